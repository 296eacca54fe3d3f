#version 450 core
// samp_gl_reduce.comp — one work group sums one tile of the atlas (paper §5:
// "reduce on the GPU, read back little"). Each invocation of the 8×8 group
// adds every 8th pixel of every 8th row of the tile (no integer division per
// pixel), then a tree in shared memory adds the 64 partial sums (pairwise, so
// float error grows with log2 of the pixel count, not linearly). 64 invocations
// and 6 barriers, because on llvmpipe each barrier splits the shader into
// coroutines: against 256 invocations with a division per pixel this took a
// 128² hemicube from 755 to 433 µs per point and direct 128² from 124 to 111.
// Compiled twice: plain, it sums two R32F atlases (visible, total weight of the
// direct path); with INDIRECT defined, it sums RGB radiance times the weight
// texture (cosθ·dω per pixel of one tile).

layout(local_size_x = 8, local_size_y = 8) in;

layout(binding = 0) uniform sampler2D u_tex0;   // direct: visible; indirect: radiance
layout(binding = 1) uniform sampler2D u_tex1;   // direct: total; indirect: weight (one tile)
layout(std430, binding = 0) writeonly buffer Sums { float sums[]; };

uniform ivec2 u_tile;    // tile size, pixels
uniform int u_cols;      // tiles per atlas row

shared vec3 part[64];

void main()
{
    uint k = gl_WorkGroupID.x;
    uint lid = gl_LocalInvocationIndex;
    ivec2 origin = ivec2(int(k) % u_cols, int(k) / u_cols) * u_tile;
    ivec2 l = ivec2(gl_LocalInvocationID.xy);
    vec3 acc = vec3(0.0);
    for (int y = l.y; y < u_tile.y; y += 8)
        for (int x = l.x; x < u_tile.x; x += 8) {
            ivec2 q = ivec2(x, y);
#ifdef INDIRECT
            acc += texelFetch(u_tex0, origin + q, 0).rgb * texelFetch(u_tex1, q, 0).r;
#else
            acc.x += texelFetch(u_tex0, origin + q, 0).r;
            acc.y += texelFetch(u_tex1, origin + q, 0).r;
#endif
        }
    part[lid] = acc;
    memoryBarrierShared();
    barrier();
    for (uint s = 32u; s > 0u; s >>= 1) {
        if (lid < s) part[lid] += part[lid + s];
        memoryBarrierShared();
        barrier();
    }
    if (lid == 0u) {
#ifdef INDIRECT
        sums[3u * k] = part[0].x;
        sums[3u * k + 1u] = part[0].y;
        sums[3u * k + 2u] = part[0].z;
#else
        sums[2u * k] = part[0].x;
        sums[2u * k + 1u] = part[0].y;
#endif
    }
}
