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
 * by acquire stays valid until the next acquire or destroy.
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

typedef struct cache_worker_desc {
    const scene *scene;          /* must outlive the worker */
    samp_desc sampler;           /* the worker creates its sampler on its own thread (.scene is set) */
    cache_desc cache;            /* .scene and .sampler are set by the worker */
    const uint32_t *pixels;      /* per scene triangle; copied; NULL: every triangle 1e6 pixels */
    uint32_t step_budget;        /* leaves tested between publications; 0 = 512 */
    uint64_t max_tested;         /* stop after this many leaves tested (deterministic runs); 0 = no limit */
} cache_worker_desc;

/* One corner of a published triangle. */
typedef struct cache_snapshot_vertex {
    float position[3];           /* scene units */
    float value[3];              /* direct: L_dd per unit albedo; indirect: E_i (W·m⁻²); specular: L_ds per unit ks */
} cache_snapshot_vertex;

typedef struct cache_snapshot_mesh {
    const cache_snapshot_vertex *vertices; /* 3 per triangle */
    const uint32_t *tri;         /* scene triangle of each triangle (its material) */
    uint32_t triangle_count;
} cache_snapshot_mesh;

typedef struct cache_snapshot {
    uint64_t generation;         /* 1, 2, ... per commit */
    cache_snapshot_mesh direct, indirect, specular; /* specular: empty without glossy materials */
    cache_stats stats;           /* stats.lights points into the snapshot */
    uint64_t tested;             /* leaves tested so far */
    int converged;               /* nothing was left to test when it was made */
    int failed;                  /* the worker stopped on an error (message in error) */
    char error[256];
} cache_snapshot;

typedef struct cache_worker cache_worker;

lm_result cache_worker_create(const cache_worker_desc *desc, cache_worker **out, lm_error *err);
void cache_worker_destroy(cache_worker *w); /* cancels the refinement, joins the thread; NULL is a no-op */

/* The latest committed snapshot, or NULL before the first commit. */
const cache_snapshot *cache_worker_acquire(cache_worker *w);

void cache_worker_pause(cache_worker *w);  /* returns once the worker is between steps and waiting */
void cache_worker_resume(cache_worker *w);
/* Queued; the worker applies it before its next step (cache_set_light: no resampling). */
lm_result cache_worker_set_light(cache_worker *w, uint32_t light, const float value[3], lm_error *err);

#ifdef __cplusplus
}
#endif
#endif
