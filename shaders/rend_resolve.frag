#version 450 core
// Resolve (paper §6's composite, one term at a time): a radiance term's share of
// Le + kd·(L_dd + E_i/π) + ks·L_ds, i.e. coef·L per sample with coef from the
// visible material (kd for L_dd, kd/π for E_i, ks for L_ds), box-filtered over
// the SS×SS samples of each pixel into an output-sized image. The composite is
// linear in the terms, so resolving each term as soon as it is drawn lets the
// three terms share one sample-sized radiance image (rend_frame.c says why).
// Where the pixel's samples see more than one material the product is taken per
// sample, then averaged: averaging kd and L separately would be wrong at every
// edge between materials. Where they see one (most pixels) it is coef times the
// mean of L, the same value with SS² − 1 fewer material look-ups. A mean is
// c0 + Σ(cᵢ − c0)/SS², so a pixel whose samples are equal gets exactly their
// value (the same bits as SS = 1 gives for it). Compiled for SS > 1 only.
layout(binding = 0) uniform usampler2D u_code;  // rend_material.frag; 0: no surface
layout(binding = 1) uniform sampler2D u_value;  // the term's radiance image (rend_value.frag)
// The material code of a sample's code s (rend_material.frag: 2·(triangle + 1),
// bit 0 the front side; 0 no surface): 2·(material + 1) and the same bit, the
// material read from the triangle's first corner in the scene's buffer.
layout(binding = 2) uniform usamplerBuffer u_scene; // 3 corners a triangle: position bits, code
uint code_of(uint s)
{
    return s == 0u ? 0u : texelFetch(u_scene, 3 * int((s >> 1) - 1u)).w | (s & 1u);
}
struct material {
    vec4 kd, ks, le; // .rgb
};
layout(std430, binding = 0) readonly buffer Materials { material u_materials[]; };
uniform uint u_term; // 0: L_dd (× kd), 1: E_i (× kd/π), 2: L_ds (× ks)
uniform int u_band_y0; // the first sample row u_value holds (rend_frame.c draws in bands)
layout(location = 0) out vec4 o_rgb;

// coef·L at sample q of material code `code` (not 0).
vec3 shade(uint code, vec3 l)
{
    material m = u_materials[(code >> 1) - 1u];
    if (u_term == 2u) return m.ks.rgb * l;
    return m.kd.rgb * (u_term == 1u ? l * 0.31830988618379067 : l);
}

void main()
{
    ivec2 p = ivec2(gl_FragCoord.xy) * SS, pv = p - ivec2(0, u_band_y0);
    uint codes[SS * SS];
    bool one = true; // one material over the pixel (most pixels): coef once, times the mean of L
    for (int k = 0; k < SS * SS; ++k) {
        codes[k] = code_of(texelFetch(u_code, p + ivec2(k % SS, k / SS), 0).r);
        one = one && codes[k] == codes[0];
    }
    vec3 c0, d = vec3(0.0);
    if (one) {
        if (codes[0] == 0u) {
            o_rgb = vec4(0.0, 0.0, 0.0, 1.0);
            return;
        }
        c0 = texelFetch(u_value, pv, 0).rgb;
        for (int k = 1; k < SS * SS; ++k) d += texelFetch(u_value, pv + ivec2(k % SS, k / SS), 0).rgb - c0;
        c0 = shade(codes[0], c0 + d * (1.0 / float(SS * SS)));
    } else {
        c0 = codes[0] != 0u ? shade(codes[0], texelFetch(u_value, pv, 0).rgb) : vec3(0.0);
        for (int k = 1; k < SS * SS; ++k)
            if (codes[k] != 0u) d += shade(codes[k], texelFetch(u_value, pv + ivec2(k % SS, k / SS), 0).rgb) - c0;
            else d -= c0;
        c0 += d * (1.0 / float(SS * SS));
    }
    o_rgb = vec4(c0, 1.0);
}
