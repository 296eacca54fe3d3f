#version 450 core
// The viewer's resting picture (view_accum.c): one jittered draw of rend_frame's
// output, copied texel for texel into the running mean, which GL's blending
// forms: mean = (1 - a)·mean + a·draw with a = 1/(n+1) as the constant alpha.
layout(binding = 0) uniform sampler2D u_draw; // rend_frame's output, the mean's size
layout(location = 0) out vec4 o_mean;

void main()
{
    o_mean = vec4(texelFetch(u_draw, ivec2(gl_FragCoord.xy), 0).rgb, 1.0);
}
