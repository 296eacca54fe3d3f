#version 450 core
// Composite (paper §6): Le + kd·(L_dd + E_i/π) + ks·L_ds per sample, linear,
// box-filtered over the SS×SS samples of each pixel (SS is defined by
// rend_frame.c; the material and radiance images are SS times the output's
// size). The product is taken per sample, then averaged: averaging kd and the
// radiance images separately would be wrong at every edge between materials.
// The mean is c0 + Σ(cᵢ − c0)/SS², so a pixel whose samples are equal gets
// exactly that value (the same bits as SS = 1 gives for it).
layout(binding = 0) uniform usampler2D u_code;    // rend_material.frag; 0: no surface
layout(binding = 1) uniform sampler2D u_direct;   // L_dd per unit albedo
layout(binding = 2) uniform sampler2D u_indirect; // E_i, W·m⁻²
layout(binding = 3) uniform sampler2D u_specular; // L_ds per unit ks
struct material {
    vec4 kd, ks, le; // .rgb; le: W·m⁻²·sr⁻¹
};
layout(std430, binding = 0) readonly buffer Materials { material u_materials[]; };
uniform uint u_terms; // bit t < 3: radiance image t was drawn and is shown (else it is 0 and not read);
                      // bit 3: emission is shown (rend_frame_set_components)
layout(location = 0) out vec4 o_rgb;

vec3 shade(ivec2 q)
{
    uint code = texelFetch(u_code, q, 0).r;
    if (code == 0u) return vec3(0.0);
    material m = u_materials[(code >> 1) - 1u];
    vec3 le = (code & 1u) != 0u && (u_terms & 8u) != 0u ? m.le.rgb : vec3(0.0);
    vec3 ldd = (u_terms & 1u) != 0u ? texelFetch(u_direct, q, 0).rgb : vec3(0.0);
    vec3 ei = (u_terms & 2u) != 0u ? texelFetch(u_indirect, q, 0).rgb : vec3(0.0);
    vec3 lds = (u_terms & 4u) != 0u ? texelFetch(u_specular, q, 0).rgb : vec3(0.0);
    return le + m.kd.rgb * (ldd + ei * 0.31830988618379067) + m.ks.rgb * lds;
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
