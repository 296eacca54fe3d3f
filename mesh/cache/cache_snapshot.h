/* cache_snapshot.h — what the refinement worker publishes (cache_worker.h) and the
 * renderer draws (src/render/): plain arrays, no cache pointers, so that the
 * display side reads a snapshot without touching the cache or taking a lock.
 *
 * A snapshot holds the crack-free leaf triangles of the direct, indirect and
 * specular meshes, indexed: each vertex of a mesh once, with its position and
 * value, and per triangle its three vertices and its scene triangle (for the
 * material) — what the radiance passes draw — and the
 * cache statistics when it was made. With cache_worker_desc.whole_roots the
 * direct and indirect meshes' whole roots (a scene triangle with its own
 * corners) come instead as a bit mask and values by vertex id, which the
 * renderer draws from the scene. With publish_debug it also holds each light's
 * visibility mesh and, for every mesh, per-corner vertex ids and flags (sampled
 * vertex, leaf-boundary edge): what the debug overlays draw (rend_debug.h). Off,
 * nothing of that is made or copied.
 *
 * Threads: written only by the worker thread into a slot the display does not
 * hold; after cache_worker_acquire returns it, read-only for the display thread
 * until its next acquire (cache_worker.h).
 * Units: positions in scene units; values as each mesh stores them (below).
 * Does NOT do: own memory (the worker's slots do), keep a cache alive.
 */
#ifndef LUMESH_CACHE_SNAPSHOT_H
#define LUMESH_CACHE_SNAPSHOT_H

#include <stdint.h>

#include "mesh/cache/cache.h"
#include "sampling/samp.h"

#ifdef __cplusplus
extern "C" {
#endif

/* One vertex of a published mesh (shared by the triangles that index it). */
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

/* Refining samplers a worker replaces at most: its start's plain count (at the
 * first convergence) and the loser of AUTO's calibration. */
enum { CACHE_SNAPSHOT_RETIRED = 4 };

/* One corner's debug data (cache_worker_desc.publish_debug), parallel to index. */
typedef struct cache_snapshot_corner {
    uint32_t vertex;             /* vertex-table id: corners with the same id are one vertex of the mesh */
    uint32_t flags;              /* CACHE_CORNER_* */
} cache_snapshot_corner;

/* A published mesh. Indexed because leaf triangles share their corners (about
 * two triangles a vertex): 28 bytes a triangle instead of 76 with a position and
 * value per corner, in each of the worker's three slots, the renderer's copy and
 * its GL buffers (docs/memory.md, "Indexed snapshots"). */
typedef struct cache_snapshot_mesh {
    const cache_snapshot_vertex *vertices; /* vertex_count, in the order the triangles first use them */
    const uint32_t *index;       /* 3 per triangle: its corners, into vertices (counter-clockwise) */
    const uint32_t *tri;         /* scene triangle of each triangle (its material) */
    const cache_snapshot_corner *corners;  /* 3 per triangle with publish_debug; else NULL */
    const cache_lobe *lobes;     /* the specular mesh: per vertex, parallel to vertices, what its
                                    highlights per pixel need (cache_get_lobe); else NULL */
    uint32_t triangle_count, vertex_count;
    /* Whole roots (cache_worker_desc.whole_roots; NULL and 0 without): the leaves
     * that are a scene triangle with its own three corners, not in the arrays
     * above. Scene triangle t is one where bit t % 32 of whole[t / 32] is set; its
     * corner k has the value values[3·id] with id = cache_snapshot.corner_ids[3·t + k].
     * A million-triangle scene's first image: 2 million such leaves, 6 MB of
     * values a mesh instead of 29 MB of triangles (docs/cache.md, "Whole roots
     * by vertex id"). */
    const uint32_t *whole;       /* (scene triangles + 31) / 32 words */
    const float *values;         /* RGB per vertex-table id below value_count, as `vertices` hold them */
    uint32_t whole_count, value_count;
} cache_snapshot_mesh;

/* Leaves of m, listed and whole. */
static inline uint64_t cache_snapshot_leaf_count(const cache_snapshot_mesh *m)
{
    return (uint64_t)m->triangle_count + m->whole_count;
}

/* Corner k (0..2) of triangle t of m. */
static inline const cache_snapshot_vertex *cache_snapshot_corner_vertex(const cache_snapshot_mesh *m, uint32_t t,
                                                                        int k)
{
    return &m->vertices[m->index[3 * (size_t)t + (size_t)k]];
}

typedef struct cache_snapshot {
    uint64_t generation;         /* 1, 2, ... per commit */
    cache_snapshot_mesh direct, indirect, specular; /* specular: empty without glossy materials */
    const uint32_t *corner_ids;  /* with whole roots: 3 per scene triangle, the vertex-table id of each
                                    corner (MESH_VTABLE_NONE: none), the same for the worker's life */
    uint64_t corner_ids_serial;  /* names corner_ids' contents among every worker's (0: none) */
    const cache_snapshot_mesh *lights; /* publish_debug: light_mesh_count visibility meshes, value[0] = V_ℓ
                                          (visible fraction), value[1] = value[2] = 0; else NULL */
    uint32_t light_mesh_count;   /* publish_debug: the scene's lights (a light nothing can see: an
                                    empty mesh); else 0 */
    cache_stats stats;           /* stats.lights points into the snapshot */
    const float *light_radiance; /* stats.light_count × RGB: each light's radiance (area) or intensity
                                    (point) as the cache uses it (cache_get_light_radiance) */
    cache_estimate estimate;     /* the cache's estimate of its error over the worker's pixel counts; none
                                    (estimate.measured 0) in a worker's first snapshot */
    samp_stats sampler;          /* the worker's sampler when it was made: back ends, samples, seconds */
    samp_stats quick_sampler;    /* the quick start's sampler (the coarse cache); zero without one */
    samp_stats retired[CACHE_SNAPSHOT_RETIRED]; /* the refining samplers `sampler` replaced, each as it was
                                                   when it was dropped (the start's plain count at the first
                                                   convergence, the calibration's loser) */
    uint32_t retired_count;
    double published_at;         /* lm_now_seconds() when it was committed */
    double first_rounds_seconds; /* the worker's refinement rounds before the first image (the cache's
                                    own start-up is stats.startup) */
    double first_publish_seconds; /* the first image's estimate and snapshot; 0 in the first snapshot
                                     itself (measured as it is made) */
    uint64_t tested;             /* leaves tested so far */
    uint32_t owed;               /* indirect values still to be gathered again when it was made (the first
                                    image's, or ones a rebuilt source moved); the quick start's first
                                    snapshot: 1 (all of them are). A client may hold back work that would
                                    share the cores until the first image's are done (`converge` and
                                    `render` start their residual then) */
    int converged;               /* nothing was left to do and the estimate was below the cache's JND
                                    (cache_desc.jnd, cache_estimate_converged) when it was made, or
                                    earlier since the last edit or view (the worker then refines on
                                    to a lower JND: cache_worker_desc.jnd_floor) */
    double converged_at;         /* converged: lm_now_seconds() of the first converged snapshot since
                                    the last edit or view */
    float jnd;                   /* the JND refinement works to now: the cache's, or lower once it
                                    has converged there (cache_worker_desc.jnd_floor) */
    int finished;                /* converged (at the floor JND when the worker tightens), nothing left
                                    the cache can do (the estimate still above the JND: see estimate),
                                    or max_tested reached: no newer snapshot without an edit */
    int failed;                  /* the worker stopped on an error (message in error) */
    char error[256];
} cache_snapshot;

#ifdef __cplusplus
}
#endif
#endif
