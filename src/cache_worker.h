/* cache_worker.h — the refinement worker: a thread that owns a sampler and a
 * multi-mesh cache, refines continuously, and publishes what it has to the
 * display side (DESIGN.md "Contexts and threads"; CONVENTIONS: set → commit →
 * query).
 *
 * Publication is a triple buffer of snapshots: the worker fills its own, then
 * commits it under a short lock (a pointer swap); the display acquires the latest
 * committed one under the same lock and reads it without any lock until its next
 * acquire. Neither side ever waits on the other's work.
 *
 * A snapshot holds the crack-free leaf triangles of the direct and indirect
 * meshes with, per corner, its position, scene triangle and value — what the
 * renderer's radiance passes draw — and the cache statistics when it was made.
 * With publish_debug it also holds each light's visibility mesh and, for every
 * mesh, per-corner vertex ids and flags (sampled vertex, leaf-boundary edge): what
 * the debug overlays draw (rend_debug.h). Off, nothing of that is made or copied.
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
 * Threads: create, acquire, pause, resume, set_light, set_pixels and destroy are
 * for one thread (the display); the worker thread is private. A snapshot returned
 * by acquire stays valid until the next acquire or destroy, and so do all the
 * arrays it points to (lights, corners), which belong to its slot.
 * Does NOT do: GL drawing, camera moves of the specular mesh (no specular mesh yet).
 */
#ifndef LUMESH_CACHE_WORKER_H
#define LUMESH_CACHE_WORKER_H

#include <stdint.h>

#include "cache.h"
#include "samp.h"

#ifdef __cplusplus
extern "C" {
#endif

enum {
    CACHE_WORKER_QUICK_RAYS = 64 /* gather rays per coarse vertex for the first snapshot (then gathered again) */
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
    uint64_t max_tested;         /* stop after this many leaves tested (deterministic runs); 0 = no limit */
    int publish_debug;           /* non-zero: snapshots also carry the light meshes and per-corner
                                    cache_snapshot_corner data (debug overlays); 0 = off, no extra cost
                                    (on Water about 10% of the refinement); cache_worker_set_publish_debug
                                    changes it later */
} cache_worker_desc;

/* One corner of a published triangle. */
typedef struct cache_snapshot_vertex {
    float position[3];           /* scene units */
    float value[3];              /* direct: L_dd per unit albedo; indirect: E_i (W·m⁻²); specular: L_ds per unit ks */
} cache_snapshot_vertex;

/* Per-corner flags of cache_snapshot_corner. */
enum {
    CACHE_CORNER_SAMPLED = 1u << 0,  /* the vertex's value was set in this mesh (mesh_qmesh_get_value
                                        returned 1): a light mesh's are sampler calls, all of them */
    CACHE_CORNER_LEAF_EDGE = 1u << 1 /* the edge from this corner to the next (k -> k+1 mod 3) lies on
                                        its leaf's boundary; clear: a diagonal of the fan tiling the leaf */
};

/* One corner's debug data (cache_worker_desc.publish_debug), parallel to vertices. */
typedef struct cache_snapshot_corner {
    uint32_t vertex;             /* vertex-table id: corners with the same id are one vertex of the mesh */
    uint32_t flags;              /* CACHE_CORNER_* */
} cache_snapshot_corner;

typedef struct cache_snapshot_mesh {
    const cache_snapshot_vertex *vertices; /* 3 per triangle */
    const uint32_t *tri;         /* scene triangle of each triangle (its material) */
    const cache_snapshot_corner *corners;  /* 3 per triangle with publish_debug; else NULL */
    uint32_t triangle_count;
} cache_snapshot_mesh;

typedef struct cache_snapshot {
    uint64_t generation;         /* 1, 2, ... per commit */
    cache_snapshot_mesh direct, indirect, specular; /* specular: empty without glossy materials */
    const cache_snapshot_mesh *lights; /* publish_debug: light_mesh_count visibility meshes, value[0] = V_ℓ
                                          (visible fraction), value[1] = value[2] = 0; else NULL */
    uint32_t light_mesh_count;   /* publish_debug: the scene's lights (a light nothing can see: an
                                    empty mesh); else 0 */
    cache_stats stats;           /* stats.lights points into the snapshot */
    samp_stats sampler;          /* the worker's sampler when it was made: back ends, samples, seconds */
    samp_stats quick_sampler;    /* the quick start's sampler (the coarse cache); zero without one */
    double published_at;         /* lm_now_seconds() when it was committed */
    uint64_t tested;             /* leaves tested so far */
    int converged;               /* nothing was left to test when it was made */
    int finished;                /* converged, or max_tested reached: no newer snapshot without an edit */
    int failed;                  /* the worker stopped on an error (message in error) */
    char error[256];
} cache_snapshot;

typedef struct cache_worker cache_worker;

lm_result cache_worker_create(const cache_worker_desc *desc, cache_worker **out, lm_error *err);
void cache_worker_destroy(cache_worker *w); /* cancels the refinement, joins the thread; NULL is a no-op */

/* The latest committed snapshot, or NULL before the first commit. */
const cache_snapshot *cache_worker_acquire(cache_worker *w);

/* pause returns once the worker is between steps and waiting. While paused it
 * refines nothing, but a light edit (set_light) is still applied and published
 * as one new snapshot (no refinement step, not converged). */
void cache_worker_pause(cache_worker *w);
/* Snapshots from now on carry the debug data or not (cache_worker_desc.publish_debug);
 * a change is published at once, even by a worker that is idle or paused. */
void cache_worker_set_publish_debug(cache_worker *w, int on);
/* The same without waiting: the step in flight may still commit one snapshot (a
 * display thread that must not block uses this). */
void cache_worker_request_pause(cache_worker *w);
void cache_worker_resume(cache_worker *w);
/* Queued; the worker applies it before its next step (cache_set_light: no resampling). */
lm_result cache_worker_set_light(cache_worker *w, uint32_t light, const float value[3], lm_error *err);
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
