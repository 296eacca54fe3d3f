#version 450 core
// ref_ism_pullpush.comp — the imperfect shadow maps' hole filling (thesis
// §2.6.5, after Marroquim et al. 2007). Pull (default): a coarser texel is the
// mean of its four finer texels that hold a distance within u_threshold of the
// nearest of them (outliers behind a nearer surface do not count). Push
// (PUSH defined): a finer texel with no distance takes its coarser texel's.
// Texels with no distance hold EMPTY. Tiles are multiples of 4 texels, so no
// 2×2 block of the two levels used crosses from one VPL's map to another's.

layout(local_size_x = 8, local_size_y = 8) in;
layout(r32f, binding = 0) uniform image2D u_fine;
layout(r32f, binding = 1) uniform image2D u_coarse;
uniform float u_threshold;   // scene units

const float EMPTY = 1e30;

// Texel p of the level written (push: the finer, pull: the coarser).
void filter_texel(ivec2 p)
{
#ifdef PUSH
    if (any(greaterThanEqual(p, imageSize(u_fine)))) return;
    if (imageLoad(u_fine, p).r < 0.5 * EMPTY) return;
    imageStore(u_fine, p, imageLoad(u_coarse, p / 2));
#else
    if (any(greaterThanEqual(p, imageSize(u_coarse)))) return;
    float v[4] = float[4](imageLoad(u_fine, 2 * p).r, imageLoad(u_fine, 2 * p + ivec2(1, 0)).r,
                          imageLoad(u_fine, 2 * p + ivec2(0, 1)).r, imageLoad(u_fine, 2 * p + ivec2(1, 1)).r);
    float nearest = min(min(v[0], v[1]), min(v[2], v[3]));
    float sum = 0.0, n = 0.0;
    for (int k = 0; k < 4; ++k)
        if (v[k] < 0.5 * EMPTY && v[k] <= nearest + u_threshold) {
            sum += v[k];
            n += 1.0;
        }
    imageStore(u_coarse, p, vec4(n > 0.0 ? sum / n : EMPTY));
#endif
}

// Each invocation does a u_block×u_block block of texels (why: PULLPUSH_BLOCK
// in ref_ism.c).
uniform int u_block;

void main()
{
    ivec2 base = ivec2(gl_GlobalInvocationID.xy) * u_block;
    for (int y = 0; y < u_block; ++y)
        for (int x = 0; x < u_block; ++x) filter_texel(base + ivec2(x, y));
}
