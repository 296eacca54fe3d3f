#version 450 core
// Composite (paper §6): Le + kd·L_dd + kd·E_i/π + ks·L_ds per pixel, linear,
// added in that order at every s, so a pixel whose samples are equal gets the
// same bits at every s (rend_frame_test).
// SS = 1: the term images are the radiance images; the products are taken here.
// SS > 1: the term images arrive resolved (rend_resolve.frag: coef·L per sample,
// box-filtered over the pixel's SS×SS samples); Le is box-filtered here from the
// material codes the same way (c0 + Σ(cᵢ − c0)/SS²), because a light edit changes
// it without a redraw (rend_frame_set_emission).
layout(binding = 0) uniform usampler2D u_code;     // rend_material.frag, SS× the output's size; 0: no surface
layout(binding = 1) uniform sampler2D u_direct;    // SS = 1: L_dd; SS > 1: kd·L_dd, resolved
layout(binding = 2) uniform sampler2D u_indirect;  // SS = 1: E_i;  SS > 1: kd·E_i/π, resolved
layout(binding = 3) uniform sampler2D u_specular;  // SS = 1: L_ds; SS > 1: ks·L_ds, resolved
// The material code of a sample's code s (rend_material.frag: 2·(triangle + 1),
// bit 0 the front side; 0 no surface): 2·(material + 1) and the same bit, the
// material read from the triangle's first corner in the scene's buffer.
layout(binding = 4) uniform usamplerBuffer u_scene; // 3 corners a triangle: position bits, code
uint code_of(uint s)
{
    return s == 0u ? 0u : texelFetch(u_scene, 3 * int((s >> 1) - 1u)).w | (s & 1u);
}
struct material {
    vec4 kd, ks, le; // .rgb; le: W·m⁻²·sr⁻¹
};
layout(std430, binding = 0) readonly buffer Materials { material u_materials[]; };
uniform uint u_terms; // bit t < 3: term image t was drawn and is shown (else it is 0 and not read);
                      // bit 3: emission is shown (rend_frame_set_components)
layout(location = 0) out vec4 o_rgb;

vec3 emitted(uint code)
{
    return (code & 1u) != 0u ? u_materials[(code >> 1) - 1u].le.rgb : vec3(0.0); // front side only
}

void main()
{
    ivec2 o = ivec2(gl_FragCoord.xy);
    vec3 c = vec3(0.0);
#if SS == 1
    uint code = code_of(texelFetch(u_code, o, 0).r);
    if (code != 0u) {
        material m = u_materials[(code >> 1) - 1u];
        if ((u_terms & 8u) != 0u) c = emitted(code);
        if ((u_terms & 1u) != 0u) c += m.kd.rgb * texelFetch(u_direct, o, 0).rgb;
        if ((u_terms & 2u) != 0u) c += m.kd.rgb * (texelFetch(u_indirect, o, 0).rgb * 0.31830988618379067);
        if ((u_terms & 4u) != 0u) c += m.ks.rgb * texelFetch(u_specular, o, 0).rgb;
    }
#else
    if ((u_terms & 8u) != 0u) {
        ivec2 p = o * SS;
        c = emitted(code_of(texelFetch(u_code, p, 0).r));
        vec3 d = vec3(0.0);
        for (int j = 0; j < SS; ++j)
            for (int i = 0; i < SS; ++i)
                if (i + j > 0) d += emitted(code_of(texelFetch(u_code, p + ivec2(i, j), 0).r)) - c;
        c += d * (1.0 / float(SS * SS));
    }
    if ((u_terms & 1u) != 0u) c += texelFetch(u_direct, o, 0).rgb;
    if ((u_terms & 2u) != 0u) c += texelFetch(u_indirect, o, 0).rgb;
    if ((u_terms & 4u) != 0u) c += texelFetch(u_specular, o, 0).rgb;
#endif
    o_rgb = vec4(c, 1.0);
}
