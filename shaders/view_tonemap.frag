#version 450 core
// The viewer's tone mapping: tm_to_display of src/tonemap.c on the GPU, per channel
//     display = sRGB_OETF(clamp(2^exposure * linear, 0, 1)),  non-finite -> 0,
// written to an 8-bit target (the window, or the screenshot's framebuffer) with
// GL_FRAMEBUFFER_SRGB off, so the encoded value is stored as it is.
// tests/view_tonemap_test.c holds it to tm_to_display within 1/255.
layout(binding = 0) uniform sampler2D u_linear; // rend_frame's output: linear RGB, GL row order
uniform float u_scale;      // 2^exposure (computed on the CPU, as tonemap.c does)
uniform vec2 u_texel_scale; // texture pixels per target pixel (1, 1 when the sizes agree)
layout(location = 0) out vec4 o_display;

float encode(float v)
{
    if (isnan(v) || isinf(v)) return 0.0;
    float x = clamp(u_scale * v, 0.0, 1.0);
    return x <= 0.0031308 ? 12.92 * x : 1.055 * pow(x, 1.0 / 2.4) - 0.055;
}

void main()
{
    ivec2 size = textureSize(u_linear, 0);
    ivec2 q = min(ivec2(floor(gl_FragCoord.xy * u_texel_scale)), size - 1);
    vec3 c = texelFetch(u_linear, q, 0).rgb;
    o_display = vec4(encode(c.r), encode(c.g), encode(c.b), 1.0);
}
