/* base_test.c — the foundation layer's helpers: growing arrays (lm_grow_capacity,
 * lm_realloc_array, LM_GROW and their _raw forms), lm_sleep_seconds and the random number generator
 * (lm_rng). */
#include "src/base/rng.h"
#include "src/base/util.h"
#include "tests/test_util.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>

static void test_grow_capacity(void)
{
    CHECK(lm_grow_capacity(0, 1, 0, SIZE_MAX) == 16);   /* first 0 = 16 */
    CHECK(lm_grow_capacity(0, 1, 64, SIZE_MAX) == 64);
    CHECK(lm_grow_capacity(0, 100, 64, SIZE_MAX) == 128);
    CHECK(lm_grow_capacity(128, 100, 64, SIZE_MAX) == 128); /* already holds it */
    CHECK(lm_grow_capacity(128, 129, 64, SIZE_MAX) == 256);
    CHECK(lm_grow_capacity(16, 17, 16, 20) == 20);           /* capped at max */
    CHECK(lm_grow_capacity(16, 21, 16, 20) == 0);            /* beyond max */
    CHECK(lm_grow_capacity((size_t)UINT32_MAX - 3, UINT32_MAX, 16, UINT32_MAX) == UINT32_MAX);
}

/* LM_GROW and lm_realloc_array (zero: 1), or their raw forms (0), which grow
 * alike and keep what was written without zeroing the new room (what it holds
 * is not looked at: reading it is undefined). */
static void test_grow_array(int zero)
{
    int (*grow)(void *, size_t *, size_t, size_t) = zero ? lm_grow_array : lm_grow_array_raw;
    int (*resize)(void *, size_t, size_t, size_t) = zero ? lm_realloc_array : lm_realloc_array_raw;
    uint32_t *v = NULL;
    size_t cap = 0, n = 0, reallocs = 0;
    for (uint32_t i = 0; i < 10000; ++i) {
        size_t before = cap;
        CHECK(grow(&v, &cap, n + 1, sizeof *v));
        reallocs += cap != before;
        CHECK(cap >= n + 1);
        if (zero) CHECK(v[n] == 0); /* new space is zeroed */
        v[n++] = i * 3u;
    }
    CHECK(reallocs == 11 && cap == 16384); /* 16 · 2^10 = 16384 ≥ 10000: doubling, not one step per element */
    int all = 1;
    for (uint32_t i = 0; i < 10000; ++i) all &= v[i] == i * 3u;
    CHECK(all);
    /* A size that overflows fails and leaves the array as it was. */
    uint32_t *keep = v;
    CHECK(!grow(&v, &cap, SIZE_MAX / 2, sizeof *v));
    CHECK(v == keep && cap == 16384);
    CHECK(!resize(&v, cap, SIZE_MAX / 2, sizeof *v));
    CHECK(v == keep);
    /* Shrinking keeps the prefix, and so does growing again. */
    CHECK(resize(&v, cap, 8, sizeof *v));
    CHECK(v[7] == 21u);
    CHECK(resize(&v, 8, 1 << 20, sizeof *v));
    all = 1;
    for (uint32_t i = 0; i < 8; ++i) all &= v[i] == i * 3u;
    CHECK(all);
    if (zero) CHECK(v[8] == 0 && v[(1 << 20) - 1] == 0);
    free(v);
}

static void test_rng(void)
{
    lm_rng a, b, c;
    lm_rng_seed(&a, 7, 100, 3);
    lm_rng_seed(&b, 7, 100, 3);
    lm_rng_seed(&c, 7, 101, 3);
    int same = 1, differ = 0;
    double sum = 0.0;
    for (int i = 0; i < 100000; ++i) {
        float x = lm_rng_float(&a), y = lm_rng_float(&b), z = lm_rng_float(&c);
        same &= x == y;
        differ += x != z;
        CHECK(x >= 0.0f && x < 1.0f);
        sum += x;
    }
    CHECK(same);               /* a stream depends only on (seed, pixel, sample) */
    CHECK(differ > 99000);     /* another pixel, another stream */
    CHECK_NEAR(sum / 100000.0, 0.5, 0.005); /* 5 standard errors of a uniform mean (0.0009) */
}

static void test_sleep(void)
{
    double t0 = lm_now_seconds();
    lm_sleep_seconds(0.02);
    double slept = lm_now_seconds() - t0;
    CHECK_MSG(slept >= 0.0199, "slept %.4f s", slept); /* never less than asked (no signal here) */
    t0 = lm_now_seconds();
    lm_sleep_seconds(-1.0);
    lm_sleep_seconds(NAN);
    CHECK(lm_now_seconds() - t0 < 0.5); /* nothing to wait for: returns at once */
}

int main(void)
{
    test_sleep();
    test_grow_capacity();
    test_grow_array(1);
    test_grow_array(0);
    test_rng();
    return test_finish("base_test");
}
