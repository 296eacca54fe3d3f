/* rend_residual_test — the cache as a control variate (rend_residual.h), on the
 * closed-form planes of rend_exact_test and rend_highlight_test.
 *
 * 1. Where the cache is exact (its picture the closed form of a diffuse plane
 *    under a quad light), the residual P̄ − D has mean zero: over the image, its
 *    mean is within three standard errors of zero, and those errors are small
 *    enough to see a cache 0.5% too bright (the residual against D·1.005 is six
 *    or more of them from zero). The blend leaves an exact cache alone: at most
 *    1% of the blocks corrected. The converged cache itself, drawn on a 24×24 grid
 *    a pixel, is 0.6% darker than the closed form (linear interpolation between
 *    exact vertex values, below the concave G): its residual's mean must equal
 *    that true error within three standard errors, and be six or more from zero.
 * 2. Where the cache is wrong (the highlight plane converged at a JND of 100
 *    with leaves of at least 1,024 pixels: the diffuse fall-off interpolated
 *    over big leaves, relMSE 2.0e-2; the highlight itself is drawn per pixel and
 *    right, docs/renderer.md), the picture keeps improving with path samples
 *    after the cache has converged: relMSE after 4N samples a pixel at most a
 *    third of that after N (measured 9.1e-4 and 2.5e-4), against the
 *    box-filtered closed form, and below the cache's own.
 *
 * The truth the path tracer estimates is the pixel's box integral; the closed
 * form's is taken as the mean over a fine grid (24×24 points) of each pixel, the
 * drawn picture's as its 3×3 centres (what rend_frame draws).
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "mesh/cache/cache_worker.h"
#include "src/base/tonemap.h"
#include "src/base/vecmath.h"
#include "src/render/rend_frame.h"
#include "src/render/rend_residual.h"
#include "tests/test_util.h"

enum { W = 64, H = 48, SS = 3, FINE = 24, N_FIRST = 64 };
#define JND 2.0f
#define WRONG_JND 100.0f         /* ΔE: a cache converged, and wrong (part 2) ... */
#define WRONG_LEAF_PIXELS 1024.0f /* ... its leaves no smaller than this */

static const test_plane diffuse_plane = {.kd = {0.6, 0.4, 0.2}, .le = {5.0, 7.0, 9.0}, .light_x = 0.3,
                                         .light_z = -0.2, .light_half = 0.5, .light_height = 1.0,
                                         .cam_height = 0.8, .fov_y = 100.0, .width = W, .height = H};
static const test_plane highlight_plane = {.kd = {0.5, 0.4, 0.3}, .ks = {0.5, 0.5, 0.5}, .n = 2000.0,
                                           .le = {1.2, 1.4, 1.6}, .light_x = 0.3, .light_z = -0.2,
                                           .light_half = 0.5, .light_height = 1.0, .cam_height = 0.8,
                                           .fov_y = 100.0, .width = W, .height = H, .plane_half = 1.3};

/* The cache refined to convergence on t's plane (leaves down to sample_pixels),
 * drawn into img k×k times with the jitters of rend_frame_jitter_pattern and
 * averaged: a (k·s)×(k·s) grid in every pixel (k = 1: the s×s centres). 0 on a
 * failed step. */
static int converged_picture(const test_plane_gl *t, float sample_pixels, float jnd, float min_leaf_pixels, int k,
                             float *img)
{
    lm_error err;
    cache_worker *wk = NULL;
    if (cache_worker_create(&(cache_worker_desc){.scene = t->s, .sampler = {.backend = SAMP_BACKEND_EMBREE},
                                                 .pixels = t->pixels,
                                                 .cache = {.sample_pixels = sample_pixels, .jnd = jnd,
                                                           .min_leaf_pixels = min_leaf_pixels}},
                            &wk, &err) != LM_OK) {
        CHECK_MSG(0, "worker: %s", err.msg);
        return 0;
    }
    const cache_snapshot *snap = test_wait_finished(wk, 120.0);
    int ok = snap && snap->converged && !snap->failed;
    CHECK_MSG(ok, "the worker did not converge");
    size_t n = (size_t)W * H * 3;
    float *one = k > 1 ? malloc(n * sizeof *one) : NULL;
    CHECK(k <= 1 || one);
    if (k > 1 && !one) ok = 0;
    for (int d = 0; ok && d < k * k; ++d) {
        float jx = 0.0f, jy = 0.0f;
        if (k > 1) rend_frame_jitter_pattern(d, k, SS, &jx, &jy);
        rend_frame_set_jitter(t->f, jx, jy);
        ok = rend_frame_draw(t->f, &t->s->cameras[0], snap, k > 1 ? one : img, &err) == LM_OK;
        for (size_t i = 0; ok && k > 1 && i < n; ++i) img[i] = (d ? img[i] : 0.0f) + one[i] / (float)(k * k);
    }
    rend_frame_set_jitter(t->f, 0.0f, 0.0f);
    free(one);
    CHECK_MSG(ok, "draw: %s", err.msg);
    cache_worker_destroy(wk);
    return ok;
}

/* The box-filtered closed form of plane p (the fine grid's mean). */
static void exact_picture(const test_plane *p, float *out)
{
    for (int py = 0; py < H; ++py)
        for (int px = 0; px < W; ++px) {
            double G = test_plane_pixel_G(p, px, py, FINE), S = p->n > 0.0 ? test_plane_pixel_S(p, px, py, FINE) : 0.0;
            for (int k = 0; k < 3; ++k)
                out[3 * ((size_t)py * W + (size_t)px) + (size_t)k] =
                    (float)(p->kd[k] / M_PI * p->le[k] * G + p->ks[k] * p->le[k] * S);
        }
}

static double relmse(const float *img, const float *exact)
{
    double s = 0.0;
    for (size_t i = 0; i < (size_t)W * H * 3; ++i) {
        double d = (double)img[i] - exact[i];
        s += d * d / ((double)exact[i] * exact[i] + 0.01);
    }
    return s / (3.0 * W * H);
}

static rend_residual *make_residual(const test_plane_gl *t)
{
    lm_error err;
    rend_residual *rr = NULL;
    if (rend_residual_create(&(rend_residual_desc){.scene = t->s, .camera = &t->s->cameras[0], .width = W,
                                                   .height = H, .seed = 11, .uniform_only = 1},
                             &rr, &err) != LM_OK)
        CHECK_MSG(0, "residual: %s", err.msg);
    return rr;
}

/* Part 1: the residual's mean over the image against the cache's true error (the
 * closed form's mean minus the cached picture's), in its standard errors. With
 * `exact` the cached picture is the closed form itself (a cache without error):
 * the residual's mean must be zero, and almost no block corrected. Without, it is
 * the converged cache drawn on a 24×24 grid a pixel, whose linear interpolation
 * between exact vertex values lies below the concave G: the residual must see
 * that error. 77: no GL. */
static int mean_residual(const test_plane *plane, const char *name, int exact, float *cached, float *out,
                         float *truth)
{
    test_plane_gl t;
    int open = test_plane_gl_open(plane, name, SS, &t);
    if (open == 77) return 77;
    CHECK(open == 0);
    if (open != 0) return 1;
    rend_residual *rr = NULL;
    size_t n = (size_t)W * H * 3;
    float *mean = malloc(n * sizeof *mean), *se = malloc(n * sizeof *se);
    CHECK(mean && se);
    exact_picture(plane, truth);
    int drawn = exact ? 1 : converged_picture(&t, 1.0f / (SS * SS), 0.0f, 0.0f, FINE / SS, cached);
    if (exact) memcpy(cached, truth, n * sizeof *cached);
    if (mean && se && drawn && (rr = make_residual(&t))) {
        rend_residual_run_passes(rr, N_FIRST);
        rend_residual_info info;
        rend_residual_apply(rr, cached, out, &info);
        rend_residual_read(rr, mean, se);
        double sum = 0.0, sum_true = 0.0, sum_bright = 0.0, var = 0.0, level = 0.0;
        for (size_t i = 0; i < n; ++i) {
            sum += (double)mean[i] - cached[i];
            sum_true += (double)truth[i] - cached[i];
            sum_bright += (double)mean[i] - 1.005 * cached[i];
            var += (double)se[i] * se[i];
            level += cached[i];
        }
        double m = sum / (double)n, m_true = sum_true / (double)n, mb = sum_bright / (double)n;
        double sem = sqrt(var) / (double)n;
        level /= (double)n;
        printf("%s, %d samples a pixel: mean residual %.3g, the cache's true error %.3g (difference %.2f standard "
               "errors of %.3g; mean pixel %.3g); against it 0.5%% brighter %.3g (%.1f standard errors); "
               "%.2f%% of the blocks corrected, mean weight %.4f\n",
               name, N_FIRST, m, m_true, (m - m_true) / sem, sem, level, mb, mb / sem, 100.0 * info.corrected,
               info.mean_weight);
        CHECK_MSG(fabs(m - m_true) <= 3.0 * sem, "%s: mean residual %.3g, true error %.3g: %.1f standard errors apart",
                  name, m, m_true, (m - m_true) / sem);
        CHECK_MSG(info.min_samples == N_FIRST && info.max_samples == N_FIRST, "samples %u..%u", info.min_samples,
                  info.max_samples);
        if (exact) {
            CHECK_MSG(fabs(mb) >= 6.0 * sem, "%s: a cache 0.5%% too bright is not seen: %.1f standard errors", name,
                      mb / sem);
            CHECK_MSG(fabs(m) <= 3.0 * sem, "%s: mean residual %.3g is %.1f standard errors from zero", name, m,
                      m / sem);
            CHECK_MSG(info.corrected <= 0.01, "%s: %.2f%% of the blocks of an exact cache corrected", name,
                      100.0 * info.corrected);
        } else {
            CHECK_MSG(fabs(m) >= 6.0 * sem, "%s: the cache's error %.3g is not seen (%.1f standard errors)", name, m,
                      m / sem);
        }
    }
    free(mean);
    free(se);
    rend_residual_destroy(rr);
    test_plane_gl_close(&t);
    return 0;
}

/* Part 2: the picture of a wrong cache keeps improving with samples. */
static void wrong_cache(float *cached, float *out, float *exact)
{
    test_plane_gl t;
    int open = test_plane_gl_open(&highlight_plane, "residual_highlight", SS, &t);
    CHECK(open == 0);
    if (open != 0) return;
    rend_residual *rr = NULL;
    exact_picture(&highlight_plane, exact);
    /* Converged at a JND of WRONG_JND with leaves of WRONG_LEAF_PIXELS: the
     * diffuse light's fall-off interpolated over big leaves (with 64-pixel
     * leaves the cache was too nearly right, relMSE 1.5e-4, for 64 samples a
     * pixel to improve on it by more than their noise). */
    if (converged_picture(&t, 1.0f, WRONG_JND, WRONG_LEAF_PIXELS, FINE / SS, cached) && (rr = make_residual(&t))) {
        double e_cache = relmse(cached, exact), e[2];
        rend_residual_info info[2];
        uint32_t spp[2] = {N_FIRST, 4 * N_FIRST};
        for (int i = 0; i < 2; ++i) {
            rend_residual_run_passes(rr, spp[i] - (i ? spp[0] : 0));
            rend_residual_apply(rr, cached, out, &info[i]);
            e[i] = relmse(out, exact);
            printf("highlight, cache alone relMSE %.3g; corrected with %u samples a pixel: relMSE %.3g (estimated "
                   "%.3g), %.1f%% of the blocks corrected\n",
                   e_cache, info[i].min_samples, e[i], info[i].est_relmse, 100.0 * info[i].corrected);
        }
        CHECK_MSG(e[1] <= e[0] / 3.0, "relMSE %.3g after %u samples a pixel, %.3g after %u: not a third", e[1], spp[1],
                  e[0], spp[0]);
        CHECK_MSG(e[0] < e_cache, "relMSE %.3g after %u samples a pixel, the cache alone %.3g", e[0], spp[0], e_cache);
    }
    rend_residual_destroy(rr);
    test_plane_gl_close(&t);
}

int main(void)
{
    size_t n = (size_t)W * H * 3;
    float *cached = malloc(n * sizeof *cached), *out = malloc(n * sizeof *out), *exact = malloc(n * sizeof *exact);
    CHECK(cached && out && exact);
    if (cached && out && exact && mean_residual(&diffuse_plane, "residual_exact", 1, cached, out, exact) == 77) {
        free(cached);
        free(out);
        free(exact);
        return 77;
    }
    if (cached && out && exact) mean_residual(&diffuse_plane, "residual_plane", 0, cached, out, exact);
    if (cached && out && exact) wrong_cache(cached, out, exact);
    free(cached);
    free(out);
    free(exact);
    return test_finish("rend_residual_test");
}
