/* rng.c — PCG32 with counter-based seeding (rng.h). */
#include "src/base/rng.h"

static uint64_t mix64(uint64_t z)
{
    z += 0x9e3779b97f4a7c15ull;
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    return z ^ (z >> 31);
}

static uint32_t pcg32(lm_rng *g)
{
    uint64_t old = g->state;
    g->state = old * 6364136223846793005ull + g->inc;
    uint32_t xorshifted = (uint32_t)(((old >> 18u) ^ old) >> 27u);
    uint32_t rot = (uint32_t)(old >> 59u);
    return (xorshifted >> rot) | (xorshifted << ((-rot) & 31u));
}

void lm_rng_seed(lm_rng *g, uint64_t seed, uint64_t pixel, uint64_t sample)
{
    g->state = 0;
    g->inc = (mix64(seed ^ mix64(pixel)) << 1u) | 1u;
    pcg32(g);
    g->state += mix64(sample ^ mix64(seed + 0x632be59bd9b4e019ull));
    pcg32(g);
}

float lm_rng_float(lm_rng *g)
{
    return (float)(pcg32(g) >> 8) * (1.0f / 16777216.0f);
}
