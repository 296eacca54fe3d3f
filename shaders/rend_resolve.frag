#version 450 core
// Resolve (paper §6's composite, one term at a time): a radiance term's share of
// Le + kd·(L_dd + E_i/π) + ks·L_ds, i.e. coef·L per sample with coef from the
// visible material (kd for L_dd, kd/π for E_i, ks for L_ds), box-filtered over
// the SS×SS samples of each pixel into an output-sized image. The composite is
// linear in the terms, so resolving each term as soon as it is drawn lets the
// three terms share one sample-sized radiance image (rend_frame.c says why).
// The product is taken per sample, then averaged: averaging kd and L separately
// would be wrong at every edge between materials. The mean is
// c0 + Σ(cᵢ − c0)/SS², so a pixel whose samples are equal gets exactly that
// value (the same bits as SS = 1 gives for it).
layout(binding = 0) uniform usampler2D u_code;  // rend_material.frag; 0: no surface
layout(binding = 1) uniform sampler2D u_value;  // the term's radiance image (rend_value.frag)
struct material {
    vec4 kd, ks, le; // .rgb
};
layout(std430, binding = 0) readonly buffer Materials { material u_materials[]; };
uniform uint u_term; // 0: L_dd (× kd), 1: E_i (× kd/π), 2: L_ds (× ks)
layout(location = 0) out vec4 o_rgb;

vec3 shade(ivec2 q)
{
    uint code = texelFetch(u_code, q, 0).r;
    if (code == 0u) return vec3(0.0);
    material m = u_materials[(code >> 1) - 1u];
    vec3 l = texelFetch(u_value, q, 0).rgb;
    if (u_term == 2u) return m.ks.rgb * l;
    return m.kd.rgb * (u_term == 1u ? l * 0.31830988618379067 : l);
}

void main()
{
    ivec2 p = ivec2(gl_FragCoord.xy) * SS;
    vec3 c0 = shade(p);
#if SS > 1
    vec3 d = vec3(0.0);
    for (int j = 0; j < SS; ++j)
        for (int i = 0; i < SS; ++i)
            if (i + j > 0) d += shade(p + ivec2(i, j)) - c0;
    c0 += d * (1.0 / float(SS * SS));
#endif
    o_rgb = vec4(c0, 1.0);
}
