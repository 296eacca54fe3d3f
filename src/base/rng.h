/* rng.h — the project's random number generator: PCG32 (O'Neill 2014) with a
 * counter-based seed, so that a stream depends only on (seed, pixel, sample) and
 * never on which thread draws it. Used by the reference path tracer (one stream
 * per pixel sample), the samplers' calibration, and the cache's randomized
 * scheduler.
 *
 * Usage:
 *     lm_rng g;
 *     lm_rng_seed(&g, seed, pixel, sample);
 *     float u = lm_rng_float(&g);   // [0, 1), 24 random bits
 *
 * Threads: a generator is plain data owned by whoever holds it; no shared state.
 * Does NOT do: cryptographic randomness, jump-ahead, doubles with 53 bits.
 */
#ifndef LUMESH_BASE_RNG_H
#define LUMESH_BASE_RNG_H

#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* PCG32 (O'Neill 2014), seeded from (seed, pixel, sample) so each sample's
 * random numbers do not depend on which thread draws them. */
typedef struct lm_rng {
    uint64_t state, inc;
} lm_rng;

void lm_rng_seed(lm_rng *g, uint64_t seed, uint64_t pixel, uint64_t sample);
float lm_rng_float(lm_rng *g); /* [0, 1) */

#ifdef __cplusplus
}
#endif
#endif
