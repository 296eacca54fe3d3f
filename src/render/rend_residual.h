/* rend_residual.h — the cache as a control variate (issue 14, "unbiased in the
 * limit"): path-traced samples of the true transport in every pixel of the view,
 * and the cached picture corrected by them where they show it wrong.
 *
 * The cached picture D (a snapshot drawn and box-filtered per pixel, deterministic
 * for a given snapshot) differs from the true pixel L by its bias b = L − D. The
 * path tracer's mean P̄ of N samples over the same pixel box has mean L and a
 * standard error s ~ 1/√N, so the residual R = P̄ − D estimates b without bias.
 * Added whole, D + R = P̄ is the path tracer's picture: unbiased, but as noisy as it
 * (docs/cache.md, "Never plateau"). Shrunk, D + w·R with w = b²/(b² + s²) is the
 * best mix of the two; b² is not known, so it is estimated per block of pixels by
 * positive-part James–Stein shrinkage (James & Stein 1961), the noise counted
 * REND_RESIDUAL_SHRINK = 2 times:
 *     w_B = max(0, 1 − 2·Σ_B q·s² / Σ_B q·R²),   q = 1/(D² + 0.01)
 * (sums over the block's pixels and channels; q weighs them as relMSE does). Where
 * the cache is right, R is noise, Σ q·R² ≈ Σ q·s² and w_B = 0: the cache's picture
 * is kept, not the path tracer's noise. Where the cache is wrong by more than the
 * noise, w_B → 1. As N grows s² → 0 and w_B → 1 wherever b ≠ 0: the picture tends
 * to the truth, whatever the cache converged to.
 *
 * The path tracer is sampling's reference renderer (reference.h) at the view, the
 * transport and bounce count given: samples are jittered over the pixel box, as
 * the drawn picture's s×s (×k×k) grid is.
 *
 * Usage (one thread; the passes use every core, desc.threads):
 *     rend_residual *rr;
 *     rend_residual_create(&(rend_residual_desc){.scene = s, .camera = &cam, .width = w,
 *                          .height = h}, &rr, &err);
 *     rend_residual_run(rr, NULL, lm_now_seconds() + 5);   // while the cache is idle
 *     rend_residual_apply(rr, cached_rgb, out_rgb, &info);  // out may be cached_rgb
 *     rend_residual_restart(rr, &moved_cam);               // a camera move, a light edit
 *     rend_residual_destroy(rr);
 * Threads: every call on the creating thread; run starts and joins its workers.
 * `cancel` may be set by any thread or a signal handler.
 * Units: linear radiance, pixels, lm_now_seconds seconds.
 * Does NOT do: drawing the cached picture, deciding when to run (the front ends run
 * it while the cache has nothing to do), GL.
 */
#ifndef LUMESH_REND_RESIDUAL_H
#define LUMESH_REND_RESIDUAL_H

#include <signal.h>
#include <stdint.h>

#include "sampling/reference.h"
#include "src/base/util.h"
#include "src/scene/scene.h"

#ifdef __cplusplus
extern "C" {
#endif

enum {
    REND_RESIDUAL_BLOCK_DEFAULT = 4,      /* side of the blocks shrunk together, pixels */
    REND_RESIDUAL_MIN_SAMPLES_DEFAULT = 32, /* samples every pixel of a block has before it is corrected:
                                              with fewer, the standard errors are too often too low (Water:
                                              worse than the cache alone at 20 spp; docs/cache.md) */
    REND_RESIDUAL_UNIFORM_EVERY = 4        /* one pass in this many samples every pixel; the others only
                                              the blocks being corrected */
};
/* The noise is counted this many times in w_B: a block is corrected only where its
 * residual's energy is more than twice what the noise explains (the standard error
 * of a few heavy-tailed samples is often too low; measured in docs/cache.md). */
#define REND_RESIDUAL_SHRINK 2.0
/* The noise w_B counts is the block's own or, if more, its values' at the mean
 * q·s² of the region this many blocks around it. Where rare bright paths carry
 * the light (the Veach door's, through a gap), most 4×4 blocks have not met one
 * yet after 40-80 samples: their mean is low, their standard error as low, and
 * James–Stein took that for the cache's bias (dark specks over the smooth cached
 * picture, docs/cache.md). A variance is smoother than a mean: the blocks around
 * that did meet such paths say how noisy the block really is. */
#define REND_RESIDUAL_NOISE_REGION 2

/* Zero fields mean "default" (rend_residual_desc_defaults). */
typedef struct rend_residual_desc {
    const scene *scene;        /* required; must outlive the residual */
    const scene_camera *camera; /* required: the view (copied) */
    int width, height;         /* required: the picture's pixels */
    ref_transport transport;   /* the truth it converges to; 0 = the model transport */
    int bounces;               /* as ref_desc.bounces: the model's diffuse bounces (0 = 1) */
    ref_glossy glossy;         /* as ref_desc.glossy: what the model's glossy materials reflect */
    uint32_t seed;
    int threads;               /* 0 = every core */
    int block;                 /* 0 = REND_RESIDUAL_BLOCK_DEFAULT */
    uint32_t min_samples;      /* 0 = REND_RESIDUAL_MIN_SAMPLES_DEFAULT */
    int uniform_only;          /* non-zero: every pass samples every pixel (no adaptive passes) */
    int background;            /* non-zero: the passes take only the cycles other threads leave
                                  (ref_desc.background): run beside a refining cache, they do not
                                  slow it */
} rend_residual_desc;

void rend_residual_desc_defaults(rend_residual_desc *d);

typedef struct rend_residual rend_residual;

/* Builds the path tracer (its own BVH). On failure *out is NULL and err says why. */
lm_result rend_residual_create(const rend_residual_desc *desc, rend_residual **out, lm_error *err);
void rend_residual_destroy(rend_residual *rr); /* NULL is a no-op */

/* Forgets every sample (the picture is the cache's again) and looks from cam
 * (NULL: the same view): after a camera move or a light edit. */
void rend_residual_restart(rend_residual *rr, const scene_camera *cam);

/* Path-traces passes until `deadline` (an lm_now_seconds value) or *cancel; the
 * pass under way at the deadline stops after its tiles under way
 * (ref_render_pass). One pass in REND_RESIDUAL_UNIFORM_EVERY adds a sample to
 * every pixel; once a picture has been applied, the others add one only around
 * the blocks it corrected (w_B > 0). */
void rend_residual_run(rend_residual *rr, volatile sig_atomic_t *cancel, double deadline);

/* The same for a count of complete passes, however long they take (tests,
 * reproducible runs): with desc.uniform_only, `passes` samples every pixel. */
void rend_residual_run_passes(rend_residual *rr, uint32_t passes);

typedef struct rend_residual_info {
    uint32_t min_samples, max_samples; /* path samples a pixel */
    double seconds;                    /* spent path tracing since the last restart */
    uint64_t rays;
    double mean_weight;                /* mean w_B over the blocks */
    double corrected;                  /* share of the blocks with w_B > 0 */
    double est_relmse;                 /* the corrected picture's relMSE as the samples estimate it:
                                          Σ_B w²·Σq·s² + (1−w)²·(Σq·R² − Σq·s²) over the values;
                                          NAN while a block is short of samples */
    uint64_t vpls;                     /* a peer in its place (view_residual.h, --indirect vpl|bdir):
                                          VPLs made since it was made; 0 for the residual */
    double vpl_seconds;                /* a peer's: of `seconds`, making its VPLs (and shadow maps) */
    uint32_t grid;                     /* a peer's picture of a new view (view_residual.h): one pixel in
                                          grid×grid sampled, the others interpolated; 1: every pixel;
                                          0 for the residual */
} rend_residual_info;

/* out = cached + w_B·(P̄ − cached) per block, width·height·3 floats each (out may
 * be cached). Before any block has min_samples, out is cached. info may be NULL. */
void rend_residual_apply(rend_residual *rr, const float *cached, float *out, rend_residual_info *info);

/* Light `light` emits `value` from now on (ref_set_light: a light edit, as
 * cache_worker_set_light gives the cache); restart after it. */
lm_result rend_residual_set_light(rend_residual *rr, uint32_t light, const float value[3], lm_error *err);

/* The path tracer's pixels: mean RGB and the standard error of each mean
 * (ref_get_image; INFINITY below two samples), width·height·3 floats each; either
 * may be NULL. */
void rend_residual_read(rend_residual *rr, float *mean, float *stderr_rgb);

/* The same on given path-tracer means and standard errors (INFINITY: too few
 * samples): for tests and experiments. */
void rend_residual_blend(int width, int height, int block, const float *cached, const float *mean,
                         const float *stderr_rgb, float *out, rend_residual_info *info);

#ifdef __cplusplus
}
#endif
#endif
