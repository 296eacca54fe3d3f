#version 450 core
// Le + kd·(L_dd + E_i/π) + ks·L_ds (DESIGN.md), linear.
layout(binding = 0) uniform sampler2D u_kd;
layout(binding = 1) uniform sampler2D u_ks;
layout(binding = 2) uniform sampler2D u_le;
layout(binding = 3) uniform sampler2D u_direct;
layout(binding = 4) uniform sampler2D u_indirect;
layout(binding = 5) uniform sampler2D u_specular;
layout(location = 0) out vec4 o_rgb;
void main()
{
    ivec2 p = ivec2(gl_FragCoord.xy);
    vec3 kd = texelFetch(u_kd, p, 0).rgb, ks = texelFetch(u_ks, p, 0).rgb, le = texelFetch(u_le, p, 0).rgb;
    vec3 ldd = texelFetch(u_direct, p, 0).rgb, ei = texelFetch(u_indirect, p, 0).rgb;
    vec3 lds = texelFetch(u_specular, p, 0).rgb;
    o_rgb = vec4(le + kd * (ldd + ei * 0.31830988618379067) + ks * lds, 1.0);
}
