/* cache_internal.h — what mesh/cache.c (meshes, values) and src/cache_refine.c
 * (the refinement scheduler) share. Not a public header. Everything belongs to
 * the refinement worker thread. */
#ifndef LUMESH_CACHE_INTERNAL_H
#define LUMESH_CACHE_INTERNAL_H

#include "cache.h"
#include "ref_shading.h"
#include "tonemap.h"

/* The radiance meshes the scheduler refines. */
typedef enum cache_kind {
    CACHE_KIND_DIRECT = 0,
    CACHE_KIND_INDIRECT,
    CACHE_KIND_SPECULAR,
    CACHE_KINDS
} cache_kind;

/* A point of a scene triangle where a value is wanted: its vertex in the shared
 * table, and its barycentric address in the triangle being refined (a vertex on
 * a shared edge is reached from either triangle; the asking one is named). */
typedef struct cache_site {
    uint32_t vid;      /* vtable id */
    uint32_t tri;      /* scene triangle of the asking leaf */
    double w1, w2;     /* barycentrics in tri */
    uint32_t depth;    /* depth of the asking radiance leaf */
} cache_site;

/* Max-heap of leaves to test, lazily invalidated (an entry names a node and its
 * first corner; a node reused after a merge no longer matches). */
typedef struct cache_queue_entry {
    float priority;
    uint32_t node, v0;
} cache_queue_entry;

typedef struct cache_queue {
    cache_queue_entry *e;
    size_t n, cap;
} cache_queue;

struct cache {
    cache_desc desc;           /* defaults filled in */
    const scene *s;
    samp_sampler *sp;
    tm_desc tm;
    mesh_vtable *vt;
    uint32_t light_count;      /* area lights, then point lights */
    mesh_qmesh **light;        /* per light, NULL when no triangle can see it */
    mesh_qmesh *direct, *indirect;
    mesh_qmesh *specular;      /* NULL when no material has ks > 0 */
    mesh_qmesh *indirect1;     /* bounces = 2: the first bounce E_1 at the coarse vertices (roots only),
                                  the source of the second; NULL otherwise */
    float eye[3];              /* the specular mesh's viewpoint, scene units */
    cache_mesh_stats *light_stats;
    cache_mesh_stats direct_stats, indirect_stats, specular_stats; /* .mesh filled by cache_get_stats */
    uint64_t undone;
    int initialised;
    float *light_le;           /* light_count × RGB: current radiance (area) or intensity (point) */
    /* G_ℓ at every vertex of the direct mesh (vtable id × light_count), kept so a
     * light's colour or power can change with no new sample (cache_set_light). */
    float *vertex_G;
    size_t vertex_G_cap;       /* vertex ids with room */

    /* The radiance source of indirect samples: kd·L_dd over the direct mesh's
     * leaves, rebuilt when the direct mesh has changed enough. */
    samp_radiance_mesh rmesh;
    uint32_t *rm_first;
    float *rm_bary, *rm_rad;
    size_t rm_cap;             /* triangles allocated */
    uint64_t rm_built_at;      /* direct mesh splits+merges when last built */
    int rm_stale;              /* rebuild before the next indirect sample (a light changed) */
    int rm_with_e1;            /* the source holds kd·(L_dd + E_1/π) (bounces = 2), not kd·L_dd */
    mesh_qmesh_tri *leaf_buf;
    size_t leaf_cap;

    /* Scheduler (cache_refine.c), per radiance mesh (cache_kind).
     * Heap: a max-heap of leaves, lazily invalidated, and per-node "done" flags.
     * Random (the paper's §4.3.3): per-node priorities, a leaf's own (> 0 waiting,
     * 0 done, < 0 being tested) and an inner node's the maximum of its children's;
     * the visible roots, the current root, and how many leaves are waiting. */
    cache_queue q[CACHE_KINDS];
    uint8_t *done[CACHE_KINDS];
    size_t done_cap[CACHE_KINDS];
    float *prio[CACHE_KINDS];
    size_t prio_cap[CACHE_KINDS];
    uint32_t *roots[CACHE_KINDS];
    uint32_t root_count[CACHE_KINDS], cur_root[CACHE_KINDS];
    uint64_t waiting[CACHE_KINDS];
    ref_rng rng;
    int queues_seeded;
    int requeue[CACHE_KINDS];  /* test every leaf of that mesh again (a light or the camera changed) */
};

/* G_ℓ,unoccluded at vertex vid (analytic; point lights cosθ/r²). */
double cache_unoccluded(const cache *c, uint32_t light, uint32_t vid);
/* The sampler's receiver for vertex vid. */
samp_point cache_vertex_point(const cache *c, uint32_t vid);

/* Fills V_ℓ at every site (V[i·light_count + ℓ]), sampling light meshes where
 * they cannot interpolate confidently (see cache.h). */
lm_result cache_fetch_visibility(cache *c, const cache_site *sites, uint32_t n, float *V, lm_error *err);
/* L_dd (RGB per unit albedo) at vertex vid from visible fractions V[0..light_count);
 * remembers G_ℓ there for cache_set_light. */
lm_result cache_direct_from_visibility(cache *c, uint32_t vid, const float *V, float rgb[3], lm_error *err);
/* L_ds (RGB per unit ks, eq. 6 with each light as a point at its centre) at
 * vertex vid, seen from c->eye, from visible fractions V[0..light_count). */
void cache_specular_from_visibility(const cache *c, uint32_t vid, const float *V, float rgb[3]);
/* The mesh of a kind (NULL: the scene has none). */
mesh_qmesh *cache_kind_mesh(const cache *c, cache_kind kind);

/* Samples E_i at the given vertices (batched): gathered from kd·L_dd, and with
 * bounces = 2 from kd·(L_dd + E_1/π), E_1 the first bounce (c->indirect1). */
lm_result cache_sample_indirect(cache *c, const uint32_t *vids, uint32_t n, float *E, lm_error *err);
/* Rebuilds the radiance source from the direct mesh when it is stale or holds the
 * other kind (with_e1: kd·(L_dd + E_1/π), else kd·L_dd). */
lm_result cache_update_radiance_source(cache *c, int force, int with_e1, lm_error *err);

/* Leaf lookup: the leaf of mesh m holding barycentric (w1, w2) of scene triangle tri. */
uint32_t cache_find_leaf(const mesh_qmesh *m, uint32_t tri, double w1, double w2);
/* Barycentrics (w1, w2) of corner k of a node. */
void cache_node_corner_bary(const mesh_qnode *n, int k, double *w1, double *w2);

#endif
