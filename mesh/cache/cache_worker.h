/* cache_worker.h — the refinement worker: a thread that owns a sampler and a
 * multi-mesh cache, refines continuously, and publishes what it has to the
 * display side (docs/architecture.md "Threads and who owns what"): edits are set,
 * then committed by the worker, then queried in a snapshot.
 *
 * Publication is a triple buffer of snapshots: the worker fills its own, then
 * commits it under a short lock (a pointer swap); the display acquires the latest
 * committed one under the same lock and reads it without any lock until its next
 * acquire. Neither side ever waits on the other's work.
 *
 * A snapshot (cache_snapshot.h) holds the crack-free leaf triangles of the
 * direct, indirect and specular meshes and the cache statistics when it was made;
 * with publish_debug also the light meshes and per-corner debug data.
 *
 * Usage (display thread):
 *     cache_worker *w;
 *     cache_worker_create(&(cache_worker_desc){.scene = s, .pixels = ids.pixels}, &w, &err);
 *     const cache_snapshot *snap = cache_worker_acquire(w);   // latest; NULL before the first
 *     ... draw snap->direct ...
 *     cache_worker_pause(w); cache_worker_resume(w);
 *     cache_worker_set_light(w, 0, rgb);                     // applied by the worker, no resampling
 *     cache_worker_destroy(w);                               // cancels and joins
 *
 * Threads: create, acquire, pause, resume, set_light, set_bounces, set_exposure,
 * set_pixels and destroy are for one thread (the display); the worker thread is private. A snapshot returned
 * by acquire stays valid until the next acquire or destroy, and so do all the
 * arrays it points to (lights, corners), which belong to its slot.
 * Does NOT do: GL drawing (src/render/), choosing a sampler back end (sampling/samp.h),
 * several caches per worker.
 */
#ifndef LUMESH_CACHE_WORKER_H
#define LUMESH_CACHE_WORKER_H

#include <stdint.h>

#include "mesh/cache/cache.h"
#include "mesh/cache/cache_snapshot.h"
#include "sampling/samp.h"

#ifdef __cplusplus
extern "C" {
#endif

enum {
    CACHE_WORKER_QUICK_RAYS = 64, /* gather rays per coarse vertex for the first snapshot (then gathered again) */
    CACHE_WORKER_START_RAYS = 576, /* AUTO, no count asked: the plain gather count until the first convergence,
                                      then Embree's default (1,024) and the values taken with it gathered
                                      again (docs/cache.md, "The refining sampler's plain count") */
    CACHE_WORKER_FIRST_GATHERS = 128, /* most indirect gathers before the first snapshot (cache_desc.coarse_gathers;
                                         1,024, then 512 before: docs/cache.md has each measured) */
    CACHE_WORKER_FIRST_LIGHT_CORNERS = 1024 /* most corners sampled for light before it (cache_desc.coarse_lights;
                                               8,192, then 4,096 before) */
};

typedef struct cache_worker_desc {
    const scene *scene;          /* must outlive the worker */
    samp_desc sampler;           /* the worker creates its sampler on its own thread (.scene is set) */
    cache_desc cache;            /* .scene and .sampler are set by the worker */
    const uint32_t *pixels;      /* per scene triangle; copied; NULL: every triangle 1e6 pixels */
    int pixels_later;            /* non-zero: pixels come by cache_worker_set_pixels; the coarse cache is
                                    made meanwhile, refinement waits for them */
    int no_quick_start;          /* non-zero: the coarse cache is made with the requested sampler, as a
                                    synchronous cache_init would (exact comparisons); 0: with a quick
                                    Embree sampler, published, then gathered again (cache_worker.c) */
    uint32_t step_budget;        /* leaves tested between publications; 0 = 512 */
    uint32_t first_budget;       /* leaves tested with the quick sampler before the first publication,
                                    by `pixels` (a first image with shadows and the light's falloff:
                                    docs/renderer.md, "The first image"), and up to a fifth of it more
                                    indirect leaves (cache_refine_desc.first_image); 0 = none (and
                                    without pixels) */
    uint64_t max_tested;         /* stop after this many leaves tested (deterministic runs); 0 = no limit */
    float jnd_floor;             /* ΔE; > 0: never plateau. Once the cache has converged at its JND
                                    (cache_desc.jnd), the worker halves the JND and refines on, and
                                    again at each convergence, down to this floor; only then is it
                                    finished. An edit or a new view starts again at the cache's JND.
                                    0 = stop at the JND (the paper's behaviour) */
    int whole_roots;             /* non-zero: the direct and indirect meshes' whole roots come as
                                    cache_snapshot_mesh.whole and .values (a client that draws them from
                                    the scene: rend_frame), not as triangles; not with publish_debug.
                                    0 = every leaf a triangle */
    int publish_debug;           /* non-zero: snapshots also carry the light meshes and per-corner
                                    cache_snapshot_corner data (debug overlays); 0 = off, no extra cost
                                    (on Water about 10% of the refinement); cache_worker_set_publish_debug
                                    changes it later */
} cache_worker_desc;

typedef struct cache_worker cache_worker;

lm_result cache_worker_create(const cache_worker_desc *desc, cache_worker **out, lm_error *err);
void cache_worker_destroy(cache_worker *w); /* cancels the refinement, joins the thread; NULL is a no-op */
/* Ends the refinement for good and frees what only it used — the cache, its
 * samplers (and a GL sampler's context), the Embree scene, the slot being
 * written — keeping the committed snapshots: the one acquired last stays valid,
 * and acquire may still hand over a newer one already committed. For a client
 * that has its final snapshot and only draws it (`lumesh render`: the 116k box
 * draws with 130 MB less; docs/memory.md). Edits, views and pauses after it do
 * nothing. Display thread; NULL is a no-op. */
void cache_worker_retire(cache_worker *w);

/* The latest committed snapshot, or NULL before the first commit. The first
 * carries no error estimate (cache_estimate.measured 0): every leaf of it is
 * untested; the next one does. */
const cache_snapshot *cache_worker_acquire(cache_worker *w);

/* pause returns once the worker is between steps and waiting. The step in
 * flight does not run to its end: it stops after its batch of gathers or round
 * of leaf tests (nothing is lost: the rest stays queued) and is published, so a
 * pause waits milliseconds, not a step (Water's first steps take ~0.25 s).
 * While paused it refines nothing, but a light edit (set_light) is still
 * applied and published as one new snapshot (no refinement step, not
 * converged). */
void cache_worker_pause(cache_worker *w);
/* Snapshots from now on carry the debug data or not (cache_worker_desc.publish_debug);
 * a change is published at once, even by a worker that is idle or paused. */
void cache_worker_set_publish_debug(cache_worker *w, int on);
/* The same without waiting: the step in flight, cut short as above, may still
 * commit one snapshot (a display thread that must not block uses this). */
void cache_worker_request_pause(cache_worker *w);
void cache_worker_resume(cache_worker *w);
/* Queued; the worker applies it before its next step (cache_set_light: no resampling). */
lm_result cache_worker_set_light(cache_worker *w, uint32_t light, const float value[3], lm_error *err);
/* Queued like a light edit: the diffuse bounces shown from now on (cache_set_bounces:
 * every indirect value gathered again, no light sample). */
lm_result cache_worker_set_bounces(cache_worker *w, int bounces, lm_error *err);
/* Queued like a light edit: the display's exposure from now on (stops; the
 * viewer's + and −). The worker's tests judge the colours at it (cache_set_exposure:
 * every leaf tested again, no sample taken by the change itself); an exposure
 * equal to the cache's changes nothing. */
lm_result cache_worker_set_exposure(cache_worker *w, float exposure, lm_error *err);
/* New pixel counts per scene triangle (a new ID pass: the view changed); copied.
 * The worker takes them before its next step and reorders its queues by them. */
lm_result cache_worker_set_pixels(cache_worker *w, const uint32_t *pixels, lm_error *err);
/* The same for a camera move: pixel counts and the eye (scene units). With the
 * pixels the worker also takes the eye: the specular mesh starts again from its
 * roots for the new eye (cache_set_camera), the view-independent meshes are kept. */
lm_result cache_worker_set_view(cache_worker *w, const uint32_t *pixels, const float eye[3], lm_error *err);

#ifdef __cplusplus
}
#endif
#endif
