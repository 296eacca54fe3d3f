/* cache_internal.h — what mesh/cache.c (meshes, values), mesh/cache_source.c
 * (indirect light), mesh/cache_specular.c (specular values) and src/cache_refine.c
 * (the refinement scheduler) share. Not a public header. Everything belongs to
 * the refinement worker thread. */
#ifndef LUMESH_CACHE_INTERNAL_H
#define LUMESH_CACHE_INTERNAL_H

#include "mesh/cache/cache.h"
#include "src/base/rng.h"
#include "src/base/tonemap.h"

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

/* A light leaf whose corners agreed (V all 1 or all 0), so that it answered for
 * the radiance vertices inside it by interpolation, and whose split then found a
 * corner that does not agree: those answers may be wrong. The region is the leaf's
 * triangle in the barycentric space of its scene triangle (closed: its edges
 * included). cache_fetch_visibility records it; cache_refine recomputes the
 * radiance values inside (cache_revise_falsified). */
typedef struct cache_region {
    uint32_t light, tri;
    double w1[3], w2[3];   /* the leaf's corners */
} cache_region;

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
    /* The area lights' outlines for the specular integral (only with a specular
     * mesh): loop k is spec_outline[3·spec_loop[k] .. 3·spec_loop[k+1]) (xyz,
     * counter-clockwise seen from the light's front; spec_loop_sign[k] −1 for a
     * hole, stored reversed), light l owns loops spec_light_loop[l] .. [l+1]. */
    double *spec_outline;
    uint32_t *spec_loop, *spec_light_loop;
    int8_t *spec_loop_sign;
    size_t spec_outline_bytes;
    cache_mesh_stats *light_stats;
    cache_mesh_stats direct_stats, indirect_stats, specular_stats; /* .mesh filled by cache_get_stats */
    uint64_t undone;
    /* Falsified light leaves (cache_region) waiting for their radiance values to be
     * recomputed, and what that has done so far. */
    cache_region *falsified;
    size_t falsified_n, falsified_cap;
    uint64_t falsified_total, revised;
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
    /* The source before the last rebuild (same layout), kept to bound how much the
     * rebuild moved each indirect value (cache_source.c, "outdated indirect values"). */
    uint32_t *rp_first;
    float *rp_bary, *rp_rad;
    size_t rp_cap, rp_count;
    int rp_valid, rp_with_e1;
    /* Per vertex id of the indirect mesh: how far (RGB, a bound) the source has
     * moved its E_i since it was gathered, and whether it waits to be gathered again. */
    float *drift;
    uint8_t *outdated;
    size_t drift_cap;
    uint32_t *outdated_list;
    size_t outdated_n, outdated_cap;
    uint64_t regathered;       /* indirect values gathered again because they were outdated */
    uint64_t rm_built_at;      /* direct mesh kept splits + revised values when last built */
    uint32_t rm_nodes;         /* direct mesh nodes when last built */
    int rm_settle;             /* rebuild on any change (cache_settle_source) */
    int rm_stale;              /* rebuild before the next indirect sample (a light changed) */
    int rm_with_e1;            /* the source holds kd·(L_dd + E_1/π) (bounces = 2), not kd·L_dd */
    mesh_qmesh_tri *leaf_buf;
    size_t leaf_cap;
    /* Choosing the source's cut (per direct node): error bound, opened flag, heap. */
    float *src_err;
    uint8_t *src_open;
    struct source_pick *src_heap;
    uint32_t src_cap;

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
    lm_rng rng;
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
/* L_ds (RGB per unit ks) at vertex vid, seen from c->eye, from visible fractions
 * V[0..light_count): Σ_ℓ V_ℓ·L_ℓ·S_ℓ, S_ℓ the Phong lobe integrated over the
 * area light (eq. 5 with V_ℓ constant over the light; samp_polygon_phong), and
 * for a point light the point's exact lobe·G. */
void cache_specular_from_visibility(const cache *c, uint32_t vid, const float *V, float rgb[3]);
/* The mesh of a kind (NULL: the scene has none). */
mesh_qmesh *cache_kind_mesh(const cache *c, cache_kind kind);

/* E at the given vertices (batched) from the source of the kind asked (first
 * bounce: kd·L_dd; else the displayed indirect's, cache_sample_indirect). */
lm_result cache_gather(cache *c, int first_bounce, const uint32_t *vids, uint32_t n, float *E, lm_error *err);
/* Gathers every value of the indirect mesh(es) again from rebuilt sources (a light
 * edit, a better sampler); nothing is outdated afterwards. */
lm_result cache_regather_all(cache *c, lm_error *err);
/* The area lights' boundary loops for the specular integral (c->spec_*); 0 when
 * memory runs out. */
int cache_build_outlines(cache *c);

/* Samples E_i at the given vertices (batched): gathered from kd·L_dd, and with
 * bounces = 2 from kd·(L_dd + E_1/π), E_1 the first bounce (c->indirect1). */
lm_result cache_sample_indirect(cache *c, const uint32_t *vids, uint32_t n, float *E, lm_error *err);
/* Rebuilds the radiance source from the direct mesh when it is stale or holds the
 * other kind (with_e1: kd·(L_dd + E_1/π), else kd·L_dd). */
lm_result cache_update_radiance_source(cache *c, int force, int with_e1, lm_error *err);
/* Rebuilds the displayed indirect's source if the direct mesh changed at all since
 * it was built (refinement has nothing left to test); the values it moves are
 * flagged for cache_regather_outdated. */
lm_result cache_settle_source(cache *c, lm_error *err);

/* The radiance vertices (of the direct and the specular mesh) inside the falsified
 * light leaves recorded so far get their visible fractions fetched again (the light
 * meshes now know better; this may split and sample them, and record more
 * falsified leaves, which are done in turn) and their values recomputed. For the
 * values that changed, `changed` gets the mesh kind, the regions searched and the
 * changed vertex ids (sorted), so the scheduler can test the leaves around them
 * again. */
typedef lm_result (*cache_changed_fn)(cache *c, cache_kind kind, const cache_region *regions, uint32_t region_count,
                                      const uint32_t *vids, uint32_t n, void *user, lm_error *err);
lm_result cache_revise_falsified(cache *c, cache_changed_fn changed, void *user, lm_error *err);
/* Calls visit for every node of m's tree over rg->tri whose closed triangle can
 * touch the region's (bounding boxes in barycentric space overlap), parents first. */
typedef lm_result (*cache_node_fn)(const mesh_qmesh *m, uint32_t node, const mesh_qnode *n, void *user, lm_error *err);
lm_result cache_region_walk(const mesh_qmesh *m, const cache_region *rg, cache_node_fn visit, void *user, lm_error *err);
/* Is barycentric point (w1, w2) inside the region's closed triangle? */
int cache_region_contains(const cache_region *rg, double w1, double w2);

/* Gathers again, in batches, the indirect values the source's rebuilds may have
 * moved by more than the JND (flagged by cache_update_radiance_source); calls
 * `changed` (regions NULL) with the vertices whose value changed. */
lm_result cache_regather_outdated(cache *c, cache_changed_fn changed, void *user, lm_error *err);

/* Leaf lookup: the leaf of mesh m holding barycentric (w1, w2) of scene triangle tri. */
uint32_t cache_find_leaf(const mesh_qmesh *m, uint32_t tri, double w1, double w2);
/* Barycentrics (w1, w2) of corner k of a node. */
void cache_node_corner_bary(const mesh_qnode *n, int k, double *w1, double *w2);

#endif
