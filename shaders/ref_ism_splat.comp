#version 450 core
// ref_ism_splat.comp — imperfect shadow maps (sampling/ref_ism.h): invocation
// (k, i) splats point k of VPL i's share of the cloud into i's paraboloid map
// (Brabec et al. 2002: u = l.xy / (1 + l.z) in the VPL's frame, the hemisphere
// around its normal in the unit disk) in its tile of the atlas, as a square the
// size of the area the point stands for seen from the VPL (thesis §2.6.5: "its
// size depends on the squared distance"), each texel keeping the nearest
// distance by an atomic minimum on its bits (positive floats order as their
// bits do). Points are splatted by a compute shader, not drawn as GL points:
// on llvmpipe drawing 4M points took 0.5–1.6 s, most of a pass.

layout(local_size_x = 64) in;

struct Vpl { vec4 p; vec4 t; vec4 b; vec4 n; };   // p.w: the first point of its share
layout(std430, binding = 0) readonly buffer Points { vec4 pts[]; };
layout(std430, binding = 1) readonly buffer Vpls { Vpl vpl[]; };
layout(r32ui, binding = 0) uniform coherent uimage2D u_atlas;   // the R32F maps, as bits

uniform int u_points;    // points in the cloud
uniform int u_per_map;   // points a map
uniform int u_tile;      // texels of a map's side
uniform int u_cols;      // maps per atlas row
uniform float u_splat;   // sqrt(area a point stands for) · tile / 4: its side in texels at unit distance

// Point k of VPL i's share, splatted.
void splat(int k, int i)
{
    Vpl v = vpl[i];
    vec3 d = pts[(int(v.p.w) + k) % u_points].xyz - v.p.xyz;
    float dist = length(d);
    if (!(dist > 0.0)) return;
    vec3 l = vec3(dot(d, v.t.xyz), dot(d, v.b.xyz), dot(d, v.n.xyz)) / dist;
    if (!(l.z > 1e-3)) return;   // behind the VPL, or its own plane
    vec2 uv = l.xy / (1.0 + l.z);
    vec2 c = (uv * 0.5 + 0.5) * float(u_tile);
    // A texel spans 4·cos²(θ/2)/tile radians at the angle θ from the normal.
    int side = int(clamp(ceil(u_splat / (dist * 0.5 * (1.0 + l.z))), 1.0, 16.0));
    ivec2 lo = clamp(ivec2(floor(c - 0.5 * float(side - 1))), ivec2(0), ivec2(u_tile - 1));
    ivec2 hi = min(lo + ivec2(side), ivec2(u_tile));
    ivec2 o = ivec2(i % u_cols, i / u_cols) * u_tile;
    uint bits = floatBitsToUint(dist);
    for (int y = lo.y; y < hi.y; ++y)
        for (int x = lo.x; x < hi.x; ++x) imageAtomicMin(u_atlas, o + ivec2(x, y), bits);
}

// Each invocation splats every (groups · 64)-th point of its map from its own:
// several points an invocation (why: SPLAT_POINTS_PER_INVOCATION in ref_ism.c).
void main()
{
    int i = int(gl_GlobalInvocationID.y), stride = int(gl_NumWorkGroups.x * gl_WorkGroupSize.x);
    for (int k = int(gl_GlobalInvocationID.x); k < u_per_map; k += stride) splat(k, i);
}
