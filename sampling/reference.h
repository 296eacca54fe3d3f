/* reference.h — the ground-truth renderer: a progressive, multi-threaded Embree
 * path tracer with two transports.
 *
 * REF_TRANSPORT_MODEL computes exactly the light transport of docs/architecture.md (what the
 * previewer caches), without its approximations:
 *     pixel = Le + kd·(L_dd + L_id) + ks·L_ds
 *   L_dd  direct diffuse radiance, (1/π)·Σ_ℓ E_ℓ, with visibility, area and point lights;
 *   L_ds  direct specular radiance, the EXACT integral of the modified Phong lobe
 *         (n+2)/(2π)·cosⁿα over each light (paper eq. 5, not the point approximation
 *         of eq. 6), light sampling and lobe sampling combined with MIS;
 *   L_id  K diffuse bounces (default 1): (1/π)·∫ kd(x')·L_dd(x') cosθ dω, and for
 *         K = 2 the source is kd(x')·(L_dd(x') + L_id(x')). Emission and specular
 *         radiance of the surfaces a bounce hits are not sources (paper eq. 7).
 *   L_is  (with ks·: added to L_ds) the glossy reflection of the same source: one
 *         ray by the lobe, ks·∫ (n+2)/(2π)·cosⁿα·kd(x')·(L_dd(x') + L_id(x'))·cosθ dω,
 *         L_id(x') of K − 1 bounces (the source of x's own gathers); not with
 *         REF_GLOSSY_DIRECT or without bounces (docs/cache.md, "Glossy reflection
 *         of the room").
 * REF_TRANSPORT_FULL is unbiased path tracing of all bounces with the same BRDF:
 * next-event estimation and BRDF sampling combined with MIS (power heuristic),
 * Russian roulette after three bounces.
 * REF_ESTIMATOR_VPL estimates either transport by instant radiosity instead
 * (ref_vpl.h): a peer of the previewer in `converge --methods`, not a reference.
 *
 * Surfaces reflect on both sides (the shading frame turns to face the incoming
 * ray); lights emit from their front only (docs/scene-model.md).
 *
 * Every pass adds one sample to every pixel. Sample k of pixel p draws its random
 * numbers from a generator seeded by (seed, p, k) alone, so the same seed and
 * sample count give the same image whatever the thread count or scheduling.
 *
 * Threads: one ref_renderer belongs to the thread that created it; ref_render_pass
 * starts its own workers and joins them before it returns. `cancel` may be set by
 * any thread or a signal handler.
 * Does NOT do: textures, transparency, refraction, depth of field, motion blur.
 */
#ifndef LUMESH_REFERENCE_H
#define LUMESH_REFERENCE_H

#include <signal.h>
#include <stdint.h>

#include "src/base/util.h"
#include "src/gpu/gl_platform.h"
#include "src/scene/scene.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum ref_transport {
    REF_TRANSPORT_MODEL = 0, /* default: exactly the previewer's transport */
    REF_TRANSPORT_FULL,      /* all bounces, unbiased */
    REF_TRANSPORT_COUNT
} ref_transport;

enum { REF_BOUNCES_NONE = -1 }; /* direct light only (model transport) */

/* What glossy materials reflect in the model transport (ref_desc.glossy). */
typedef enum ref_glossy {
    REF_GLOSSY_INDIRECT = 0, /* default: the lights (L_ds) and the bounces' source (L_is) */
    REF_GLOSSY_DIRECT,       /* the lights only: the paper's model (references made before it) */
    REF_GLOSSY_COUNT
} ref_glossy;

/* How the VPL estimators see whether a VPL lights a point (ref_desc.vpl_visibility). */
typedef enum ref_vpl_visibility {
    REF_VPL_VISIBILITY_RAYS = 0, /* default: an Embree shadow ray a join (exact) */
    REF_VPL_VISIBILITY_ISM,      /* imperfect shadow maps made on the GL back end each pass
                                    (sampling/ref_ism.h; biased: leaks and over-shadows, docs/peers.md);
                                    BDIR's importance tests stay rays (candidates have no maps) */
    REF_VPL_VISIBILITY_COUNT
} ref_vpl_visibility;

/* How the renderer estimates the transport (ref_desc.estimator). */
typedef enum ref_estimator {
    REF_ESTIMATOR_PATHS = 0, /* default: path tracing (above) */
    REF_ESTIMATOR_VPL,       /* instant radiosity: the direct light as above, the indirect from virtual
                                point lights traced from the lights each pass (ref_vpl.h), biased by
                                its clamp unless vpl_clamp is REF_VPL_NO_CLAMP */
    REF_ESTIMATOR_BDIR,      /* bidirectional instant radiosity (Segovia et al. 2006): REF_BDIR_CANDIDATES
                                times vpl_paths light paths each pass, vpl_paths VPLs of them kept, drawn
                                by their contribution to points the camera sees (ref_vpl_resample) */
    REF_ESTIMATOR_COUNT
} ref_estimator;

enum { REF_VPL_PATHS_DEFAULT = 1024, REF_VPL_PER_SAMPLE_DEFAULT = 16,
       REF_BDIR_CANDIDATES = 8 /* BDIR: light paths traced for each VPL kept */ };
#define REF_VPL_CLAMP_DEFAULT 0.03f /* of the scene's bounding-box diagonal */
#define REF_VPL_NO_CLAMP (-1.0f)

typedef struct ref_desc {
    const scene *scene;       /* must outlive the renderer */
    int camera;               /* index into scene->cameras */
    const scene_camera *view; /* non-NULL: this camera instead (copied; a viewer's moved one) */
    int width, height;        /* pixels; 0 = the camera's */
    ref_transport transport;
    int bounces;              /* model transport: diffuse bounces; 0 = 1; REF_BOUNCES_NONE = 0 */
    ref_glossy glossy;        /* model transport: what glossy materials reflect (the full one: all) */
    uint32_t seed;
    int threads;              /* 0 = every core */
    ref_estimator estimator;
    int vpl_paths;            /* VPL: light paths traced at each pass's start (BDIR: VPLs kept of
                                 REF_BDIR_CANDIDATES times as many); 0 = REF_VPL_PATHS_DEFAULT */
    int vpl_per_sample;       /* VPL: VPLs a pixel sample joins by a shadow ray; 0 = REF_VPL_PER_SAMPLE_DEFAULT */
    int vpl_keep;             /* VPL, BDIR: non-zero: a restart keeps the VPLs (pass k after it traces the
                                 same light paths as pass k before; only a light edit changes them):
                                 a moving view does not flicker (the instant radiosity thesis's
                                 temporal reuse); 0: a restart is an independent estimate */
    float vpl_clamp;          /* VPL: distances below this fraction of the scene's bounding-box diagonal
                                 count as this (the geometry term's clamp); 0 = REF_VPL_CLAMP_DEFAULT,
                                 REF_VPL_NO_CLAMP: none (unbiased, spiky) */
    ref_vpl_visibility vpl_visibility; /* VPL, BDIR: how a join's visibility is found (default: rays) */
    glctx_platform gl_platform; /* VPL, BDIR with REF_VPL_VISIBILITY_ISM: the maps' GL (default: EGL) */
    int background;           /* non-zero: passes run on threads of the lowest priority (Linux
                                 SCHED_IDLE), which take only the cycles other threads leave
                                 (the cache's worker, a viewer's drawing); the caller waits */
} ref_desc;

typedef struct ref_renderer ref_renderer;

lm_result ref_create(const ref_desc *desc, ref_renderer **out, lm_error *err);
void ref_destroy(ref_renderer *r); /* NULL is a no-op */

/* Adds one sample to every pixel (of the mask: ref_set_mask). The pass stops
 * early, after the tiles under way, when *cancel (may be NULL) becomes non-zero or
 * the clock passes `deadline` (an lm_now_seconds() value; 0 = none): those pixels
 * keep their extra sample, the rest do not, so every pixel's estimate is made of
 * complete samples, and the next call goes on with the pass where this one
 * stopped (short calls still sample every pixel in turn). Returns 1 when the pass
 * is complete, 0 when it stopped early. */
int ref_render_pass(ref_renderer *r, volatile sig_atomic_t *cancel, double deadline);

/* Forgets every sample and looks from view (NULL: the same camera) from now on;
 * the size, transport and BVH stay. Samples after it draw new random numbers
 * (the seed's generation moves on), so a restart at the same view is an
 * independent estimate. */
void ref_restart(ref_renderer *r, const scene_camera *view);

/* Light `light` (the scene's area lights, then its point lights) emits `value`
 * from the next pass on: radiance, or a point light's intensity (a viewer's light
 * edit; cache_worker_set_light). Lights are still chosen by the scene's power,
 * so the estimate stays unbiased. Samples taken before are not changed:
 * ref_restart after an edit. */
lm_result ref_set_light(ref_renderer *r, uint32_t light, const float value[3], lm_error *err);

/* Passes from now on add a sample only to the pixels whose mask byte is non-zero
 * (width·height bytes, copied); NULL: every pixel again. Set it between complete
 * passes: a pass that goes on after a change uses the new mask for its tiles left. For a caller that spends
 * samples where they are worth most (rend_residual.h). Stats and images are
 * unchanged in meaning: each pixel is the mean of its own samples. */
lm_result ref_set_mask(ref_renderer *r, const uint8_t *mask, lm_error *err);

typedef struct ref_stats {
    uint32_t min_samples, max_samples; /* per pixel */
    uint64_t rays;                     /* all rays traced so far */
    double seconds;                    /* wall time spent in passes */
    double mean_rel_stderr;            /* mean over pixels of SE(Y)/sqrt(Y²+0.01), Y luminance */
    uint64_t bad_samples;              /* non-finite samples, dropped (should stay 0) */
    uint64_t vpls;                     /* VPL: virtual point lights made so far (all passes) */
    uint64_t vpl_passes;               /* VPL: sets made (one a pass) */
    double vpl_seconds;                /* VPL: wall time making them (part of seconds) */
    uint64_t ism_maps;                 /* VPL with ISM visibility: imperfect shadow maps made (all passes) */
    double ism_seconds;                /* ...wall time making them, GL and read-back (part of seconds) */
} ref_stats;

void ref_get_stats(const ref_renderer *r, ref_stats *out);

/* Writes width*height pixels: mean RGB, standard error of the mean per channel
 * (INFINITY below two samples), and sample counts. Any pointer may be NULL. */
void ref_get_image(const ref_renderer *r, float *rgb, float *stderr_rgb, float *samples);
/* The same for the rows y0 .. y0+rows−1 only (clipped to the image), their
 * width·rows values from the start of each array: a caller that reads the image
 * a band at a time keeps no copy of it (rend_residual). */
void ref_get_rows(const ref_renderer *r, int y0, int rows, float *rgb, float *stderr_rgb, float *samples);
void ref_get_size(const ref_renderer *r, int *width, int *height);

#ifdef __cplusplus
}
#endif
#endif
