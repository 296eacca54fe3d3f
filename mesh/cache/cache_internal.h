/* cache_internal.h — what the files of the multi-mesh cache (mesh/cache/) share.
 * Not a public header (tests/layers.py keeps it inside mesh/cache/).
 *
 * The files, lowest first; each calls only the files below it (and the layers
 * below mesh/cache/), never up or sideways, so there is no cycle:
 *   cache_site.c      points, leaves and regions of the meshes; what the viewer
 *                     sees (cache_seen_radiance)
 *   cache_specular.c  the area lights' outlines and the specular values (eq. 5)
 *   cache_glossy.c    the glossy part of the specular values: the source seen
 *                     through the lobe, taken again when the source moves
 *   cache_light.c     visibility from the light meshes (§4.3.4), the direct values
 *                     (eq. 4), falsified light leaves
 *   cache_drift.c     the drift bound of indirect values over source rebuilds;
 *                     which are outdated
 *   cache_source.c    indirect light (eq. 7): the radiance source, gathering
 *                     outdated values again
 *   cache_gather.c    the gathers: pilots, ray counts, guides, standard errors
 *   cache_borrow.c    the first image's borrowed indirect values, tested
 *   cache_estimate.c  the cache's estimate of its error (cache_estimate_error);
 *                     the values whose noise is still seen
 *   cache_queue.c     the refinement's queues: leaf priorities, the next leaf (§4.3.3)
 *   cache_refine.c    the refinement scheduler (§4.3): rounds, the edge test, keep or undo
 *   cache_reach.c     which triangles take part: what gathers from the seen ones
 *                     reach (cache_init_seen)
 *   cache_first.c     the first image from a budget of gathers and light samples
 *                     (borrowed values); root values from the light meshes
 *   cache.c           the public face (cache.h): create, init, edits, evaluation,
 *                     statistics, cache_refine()
 * Upward calls go through function pointers only (cache_changed_fn,
 * cache_node_fn), given by the caller.
 *
 * struct cache is a shared core (the scene, the sampler, the meshes; set by
 * cache.c) and one part per file that writes it: cache_light_state
 * (cache_light.c), cache_source_state (cache_source.c; its drift and outdated flags also
 * cache_drift.c, its pilot, sigma and gather levels cache_gather.c), cache_outlines (cache_specular.c), cache_glossy_state
 * (cache_glossy.c), cache_borrow_state (cache_borrow.c), cache_sched (cache_refine.c and cache_queue.c). A part's fields are written by
 * its owner only; other files may read them where said.
 *
 * Threads: a cache and everything in it belongs to the thread that refines it
 * (the refinement worker, cache_worker.c, or a test's own thread). Nothing here
 * locks; the display reads snapshots the worker publishes (cache_snapshot.h). */
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

/* ---- the parts -------------------------------------------------------------- */

/* Visibility and direct values (written by cache_light.c). */
typedef struct cache_light_state {
    /* G_ℓ at every vertex of the direct mesh (vtable id × light_count), kept so a
     * light's colour or power can change with no new sample (cache_set_light). */
    float *vertex_G;
    size_t vertex_G_cap;       /* vertex ids with room */
    /* Falsified light leaves (cache_region) waiting for their radiance values to be
     * recomputed, and what that has done so far. */
    cache_region *falsified;
    size_t falsified_n, falsified_cap;
    uint64_t falsified_total;
    uint64_t revised;          /* values recomputed; read by cache_source.c (direct mesh changes) */
    /* Scene triangles whose direct or specular root has a corner the first image
     * borrowed (cache_first.c): made falsified regions, a bounded number per
     * refine call, once released (after the first image), from borrowed_next on. */
    uint32_t *borrowed;
    size_t borrowed_n, borrowed_cap, borrowed_next;
    int borrowed_released;
    uint64_t borrowed_revised; /* of them, made regions so far */
    cache_mesh_stats *light_stats;               /* light_count; .mesh filled by cache_get_stats */
    cache_mesh_stats direct_stats, specular_stats; /* samples (.mesh filled by cache_get_stats) */
    /* Per vertex id: 1 while in the batch of corners a visibility round samples
     * (cache_fetch_visibility), 0 again after it: the batch's duplicate check,
     * which was a scan of the batch for each corner. */
    uint8_t *wanted;
    size_t wanted_cap;
} cache_light_state;


/* The glossy reflection of the indirect source (written by cache_glossy.c). A
 * specular value is its direct part (eq. 5, the lights) plus a glossy part: the
 * source seen through the vertex's lobe (samp_lobe_gather), gathered from the
 * source of its time. Each rebuild of the source (and each new viewpoint) makes
 * every glossy part stale, as does noise that is seen (taken again with 4× the
 * rays); a sweep over the vertex ids gathers them again, a bounded number a
 * refine call, and the leaves around those that moved visibly are tested again. */
typedef struct cache_glossy_state {
    float *rgb;        /* per vertex id: the glossy part in its specular value (RGB, per unit ks) */
    uint32_t *gen;     /* per vertex id: the source (generation) it was gathered from; 0 = none, or
                          its noise was seen: to be taken again at `level` */
    uint8_t *level;    /* per vertex id: rays of its next gather, CACHE_GLOSSY_RAYS·4^level */
    float *drift;      /* per vertex id: RGB bound of how far the source's rebuilds since its gather
                          may have moved its glossy part (cache_drift.c's bound through the lobe) */
    size_t cap;        /* ids allocated in both */
    uint32_t gen_now;  /* the source's generation: its builds and the viewpoints so far (0: no source yet) */
    uint32_t cursor;   /* no vertex id below it is stale (the sweep's next id) */
    uint64_t samples;  /* lobe gathers (points) */
    uint64_t rays;     /* their rays (more where their noise was seen) */
    uint64_t refreshed;/* of them, values taken again for a newer source or viewpoint */
} cache_glossy_state;

/* Indirect light (written by cache_source.c). */
/* A triangle of the source: cut node `leaf` of the direct mesh, or, where the
 * further bounces' coarse mesh is finer than the cut, one of its subdivisions:
 * `levels` midpoint splits, child k (emit_source's order) of split j in bits
 * 2j..2j+1 of `path`. 8 bytes, not a mesh_qmesh_tri's 68: a million-triangle
 * scene's source wrote 68 MB of fresh memory before its first image
 * (docs/cache.md, "The first image's fresh memory"). */
typedef struct cache_source_piece {
    uint32_t leaf;
    uint16_t path;
    uint8_t levels;
    uint8_t pad;
} cache_source_piece;

typedef struct cache_source_state {
    /* The radiance source of indirect samples: kd·L_dd over a cut of the direct
     * mesh, rebuilt when the direct mesh has changed enough. */
    samp_radiance_mesh rmesh;  /* rmesh.index = &rm_index */
    samp_radiance_index rm_index; /* rmesh checked and indexed once a build (samp_radiance_mesh_prepare) */
    samp_radiance_index rp_index; /* the same for the previous source (rm_index of the build before) */
    uint32_t *rm_first;
    float *rm_bary, *rm_rad;
    size_t rm_cap;             /* triangles allocated */
    /* The source before the last rebuild (same layout), kept to bound how much the
     * rebuild moved each indirect value ("outdated indirect values"). */
    uint32_t *rp_first;
    float *rp_bary, *rp_rad;
    size_t rp_cap, rp_count;
    int rp_valid;
    /* Per vertex id of the indirect mesh: how far (RGB, a bound) the source has
     * moved its E_i since it was gathered, and whether it waits to be gathered again. */
    float *drift;
    uint8_t *outdated;
    float *sigma;              /* per vertex id: the standard error of its E_i (RGB; 0: GL, exact) */
    float *sigma_likely;       /* per vertex id: its likely standard error, the strata counted (RGB; the
                                  error estimate's; sigma errs high, for the edge test) */
    uint8_t *gather_level;     /* per vertex id: its gather took GATHER_SCALE^level times the plain rays */
    uint8_t *unseen_stale;     /* per vertex id: a source rebuild found it where no pixel sees it and
                                  left its drift unbounded; gathered again once it is seen
                                  (cache_refresh_stale) */
    size_t stale_n;            /* how many are */
    float *borrowed;           /* per vertex id: 0 for a gathered value (or none); else the value was
                                  borrowed from gathered neighbours (the first image's, cache_first.c;
                                  tested by cache_borrow.c): INFINITY until its span is tested, then
                                  the ΔE the test left (at least CACHE_BORROW_DE_MIN). A gather sets 0. */
    size_t drift_cap;          /* drift, outdated, sigma, sigma_likely, gather_level, unseen_stale and
                                  borrowed */
    uint32_t *outdated_list;
    size_t outdated_n, outdated_cap;
    uint64_t regathered;       /* indirect values gathered again because they were outdated */
    uint64_t probed;           /* flagged values probed for the change they saw (cache_drift.c) */
    uint64_t probe_cleared;    /* of them, found unmoved past the JND: not gathered again */
    uint64_t probe_rays;       /* the probes' rays */
    uint64_t toward_gathers;   /* indirect values gathered toward the source (samp_point.toward_source) */
    int64_t built_at;          /* direct mesh changes (net splits + revised values) when last built */
    uint32_t built_nodes;      /* direct mesh nodes when last built */
    int settle;                /* rebuild on any change (cache_settle_source) */
    struct cache_source_piece *leaf_buf; /* the cut's triangles: source triangle i is leaf_buf[i] */
    size_t leaf_cap;
    /* Choosing the cut (per direct node): error bound, opened flag, heap. */
    float *cut_err;
    uint8_t *cut_open;
    struct source_pick *cut_heap;
    size_t cut_cap;
    /* Importance (per node id of the direct mesh, recorded at the cut's nodes;
     * cache_record_importance): how much what the viewer sees depends on the
     * source's radiance over that node. imp_max: the largest, over the visible
     * gathers, of the CIELAB ΔE a unit change of the node's source radiance causes
     * there (ΔE per W·m⁻²·sr⁻¹); imp_sum: the same summed over the gathers, each
     * weighted by the pixels its vertex stands for (pixel·ΔE per unit radiance). */
    float *imp_max, *imp_sum;
    float *imp_sub;            /* imp_sum recorded at the node and all its descendants (the cut's weight) */
    size_t imp_cap;
    int imp_any;               /* some importance has been recorded */
    uint32_t *grown;           /* cache_record_importance's answer */
    size_t grown_cap;
    /* The last displayed gather's pilot (cache_source.c, gathers): its vertex ids
     * and, per point, its source hits (samp_source_hits, CACHE_IMPORTANCE_RAYS a
     * point); cache_record_importance reads them. */
    uint32_t *pilot_vid, *pilot_count, *pilot_tri;
    float *pilot_weight;
    float *pilot_strat;        /* per point RGB: samp_source_hits.strat_var */
    float *pilot_stratum;      /* per point CACHE_IMPORTANCE_RAYS: samp_source_hits.stratum (the gathers' guide) */
    size_t pilot_cap;          /* points */
    uint32_t pilot_n;
    cache_mesh_stats indirect_stats; /* samples (.mesh filled by cache_get_stats) */
} cache_source_state;

/* Borrowed indirect values tested (written by cache_borrow.c; docs/cache.md,
 * "Borrowed values tested"). The first image's root corners in a Morton order of
 * their positions, each either gathered (a donor) or borrowed from the donors
 * beside it in that order; a span is a run of borrowed corners with the two
 * nearest donors on either side. A span is tested by gathering the corner its
 * donors support least and comparing that with what it borrows: it splits there
 * (the corner becomes a donor) where the difference can be seen and the noise
 * does not explain it, while it covers more pixels than an indirect leaf may, or
 * where a corner has no donor facing its way; else its corners keep borrowed
 * values, with the ΔE the test left as their error (the estimate's). */
enum { CACHE_BORROW_NONE = UINT32_MAX };
/* Indirect leaves stop this many times larger (in pixels) than the size criterion
 * (cache_desc.min_leaf_pixels) unless their ΔE test asks for more: indirect
 * irradiance is smooth (cache_refine.c). Borrowed spans split to the same size. */
#define CACHE_INDIRECT_SIZE_FACTOR 16.0f
/* The ray equivalent of a gather of a back end that casts none (GL's hemicube):
 * the Embree back end's default count (cache.effort). */
#define CACHE_GL_GATHER_RAYS 1024u
/* A difference between an indirect value and what interpolation or borrowing
 * gives splits nothing unless it exceeds this many standard errors of the
 * difference in some channel (the noise explains it otherwise). */
#define CACHE_NOISE_SIGMAS 2.5f
#define CACHE_BORROW_DE_MIN 1e-6f
typedef struct cache_borrow_span {
    uint32_t lo, hi;           /* order positions, inclusive */
    uint32_t left[2], right[2]; /* the donors' order positions, nearest first (CACHE_BORROW_NONE: none) */
    float de;                  /* accepted: the ΔE its test left */
} cache_borrow_span;

typedef struct cache_borrow_state {
    uint32_t *order;           /* n root corners (vertex ids), in Morton order */
    uint32_t n;
    double span;               /* their bounding box's largest side */
    int released;              /* the spans are tested (after the first image's regather) */
    cache_borrow_span *pending; /* spans to test: pending[head .. pending_n) */
    size_t head, pending_n, pending_cap;
    cache_borrow_span *accepted; /* tested and kept: tested again if the JND goes below their ΔE */
    size_t accepted_n, accepted_cap;
    uint64_t pending_corners;  /* borrowed corners in pending spans: work owed (cache_refine_result.outdated) */
    float *px;                 /* per vertex id: pixels of the triangles around it / 3 (scratch) */
    size_t px_cap;
    cache_borrow_stats stats;
} cache_borrow_state;

/* Bounces beyond the first (written by cache_bounces.c). The coarse vertices are
 * the leaf corners of a coarse mesh (c->indirect1 holds E_m there); vertex i's
 * transport is its hits hit_first[i] .. hit_first[i + 1] (scene triangle and
 * barycentric), each 1/rays of its cosine-weighted hemisphere. */
enum {
    CACHE_BOUNCE_LEAVES = 2048, /* the further bounces' coarse mesh: about this many triangles of equal area */
    CACHE_BOUNCE_DEPTH = 6,     /* ... split at most this deep */
    CACHE_BOUNCE_RAY_BUDGET = 1 << 19 /* the transport's rays in all: scenes whose roots alone give more
                                         coarse vertices than this over bounce_rays get fewer a vertex */
};

/* auto's bounces: until the rest would change no seen point by more than this
 * share of the JND (cache_bounces.c). */
#define CACHE_BOUNCES_REST_SHARE 0.25f

typedef struct cache_bounce_state {
    uint32_t nv;               /* coarse vertices: the leaf corners of c->indirect1 */
    uint32_t *vid;             /* nv: their vertex ids */
    uint8_t *depth;            /* per scene triangle: the depth of its coarse leaves */
    uint32_t *tv_first;        /* scene triangle t's coarse vertices: tv_index[tv_first[t] .. tv_first[t + 1]), */
    uint32_t *tv_index;        /* at barycentric (tv_bary[2e], tv_bary[2e + 1]) in t */
    float *tv_bary;
    uint32_t tv_n, tv_cap;
    uint32_t *hit_first;       /* nv + 1 */
    uint32_t *hit_tri;         /* per hit: scene triangle, */
    float *hit_bary;           /* its barycentric (2), */
    uint32_t *hit_corner;      /* the coarse indices of the corners of the coarse leaf holding it (3) */
    float *hit_weight;         /* and its weights w1, w2 there (2; w0 = 1 − w1 − w2) */
    float *b, *next, *sum, *shown; /* nv × RGB each: B_k, B_k+1, E_m, Σ B shown */
    float *whole;              /* nv × RGB: every bounce's sum */
    int dirty;                 /* something the evaluation reads changed (lights, what is seen) */
    int64_t direct_at;         /* cache_direct_changes and the JND at the last evaluation */
    float jnd_at;
    uint8_t *seen;             /* nv: a corner of a triangle a pixel sees (all, before any pixels) */
    cache_bounce_stats stats;
    size_t bytes;
} cache_bounce_state;

/* The scheduler (written by cache_refine.c and cache_queue.c), per radiance mesh (cache_kind).
 * Heap: a max-heap of leaves, lazily invalidated, and per-node "done" flags.
 * Random (the paper's §4.3.3): per-node priorities, a leaf's own (> 0 waiting,
 * 0 done, < 0 being tested) and an inner node's the maximum of its children's;
 * the visible roots, the current root, and how many leaves are waiting. */
typedef struct cache_sched {
    cache_queue q[CACHE_KINDS];
    /* The first image's indirect leaves (cache_refine_desc.first_image): the heap
     * scheduler picks none below pick_floor (0: any), and while
     * first_image_round sets aside those a surface parts, queued again after. */
    float pick_floor;
    int first_image_round;
    cache_queue set_aside;
    /* The quieter values' turn against the leaf tests (cache_sched_refine): calls
     * left before the next look (a look walks every visible indirect leaf), and
     * the wait after one that found none worth their rays (1, then doubled each
     * time, up to NOISY_WAIT_MAX; 0 after one that gathered: the next call looks). */
    uint32_t noisy_skip, noisy_wait;
    uint8_t *done[CACHE_KINDS];
    size_t done_cap[CACHE_KINDS];
    float *prio[CACHE_KINDS];
    size_t prio_cap[CACHE_KINDS];
    uint32_t *roots[CACHE_KINDS];
    uint32_t root_count[CACHE_KINDS], cur_root[CACHE_KINDS];
    uint64_t waiting[CACHE_KINDS];
    lm_rng rng;
    int seeded;
    int requeue[CACHE_KINDS];  /* test every leaf of that mesh again (cache_sched_requeue) */
    uint64_t undone;           /* splits undone */
    /* Per node: what its edge test says of the leaf's interpolation error, CIELAB ΔE
     * stored plus one, negative when it is the parent's (0: not known). Set when a split is undone (the mean ΔE
     * between its fresh midpoints and their edges' interpolation, less what noise
     * explains) and, for the children
     * of a kept split, a quarter of the parent's (linear interpolation's error
     * falls with the square of the size) until their own test. Read by
     * cache_estimate.c (cache_sched_residual). */
    float *resid[CACHE_KINDS];
    size_t resid_cap[CACHE_KINDS];
    /* Per node of the direct mesh, unseen leaves only: how many generations of
     * its ancestors were dark at every corner and every midpoint their test
     * sampled (0: not so, or not known); the chance that a beam hides between
     * such corners shrinks with each (source_priority). */
    uint8_t *dark_gen;
    size_t dark_gen_cap;
    /* Per scene vertex, the triangles around it (vt_first[v] .. vt_first[v + 1] of
     * vt_tris; built on first use): where a changed cache vertex's leaves can be. */
    uint32_t *vt_first, *vt_tris;
    uint32_t *tri_stamp, stamp;  /* per scene triangle: visited in this pass */
    /* Per mesh: rays a leaf test took (cache.effort), smoothed over its rounds (0:
     * none yet). The heap scheduler gives the next round to the mesh whose top
     * priority (pixels × ΔE) per ray is highest (cache_sched_refine). */
    double leaf_rays[CACHE_KINDS];
    /* Per mesh: the error its leaf tests removed (the kept splits: pixels × their
     * midpoints' ΔE, or an unseen source leaf's change as the viewer sees it)
     * and the priorities the leaves were picked at, both decayed by YIELD_MEMORY
     * a round and cleared when the mesh's queue is made afresh (schedule_leaves:
     * a new view, a light edit, a lower JND); next_kind weighs each top priority
     * by their ratio (cache_refine.c). */
    double removed[CACHE_KINDS], predicted[CACHE_KINDS];
    /* The first image's owed indirect work (its values gathered again, its
     * borrowed ones tested) waits while the direct leaves move the source it
     * would draw from: owed_wait is set when that work is released (quick
     * start) and cleared once a window of direct leaf tests (owed_tested of
     * them) has moved the source's power (source_moved: Σ |ΔP| over the
     * window's kept splits, kd·L_dd × area, channels averaged) by less than the
     * JND allows a value to be off (cache_refine.c, owed_may_start). */
    int owed_wait, owed_tested;
    double source_moved;
} cache_sched;

struct cache {
    /* The core (written by cache.c: at creation, cache_set_camera, cache_set_light,
     * cache_set_sampler; read by every file). */
    cache_desc desc;           /* defaults filled in */
    const scene *s;
    samp_sampler *sp;
    tm_desc tm;
    mesh_vtable *vt;
    uint32_t light_count;      /* area lights, then point lights */
    mesh_qmesh **light;        /* per light, NULL when no triangle can see it */
    mesh_qmesh *direct, *indirect;
    mesh_qmesh *specular;      /* NULL when no material has ks > 0 */
    mesh_qmesh *indirect1;     /* bounces ≠ 1: E_m, the irradiance of bounces 1..K−1 at the coarse
                                  vertices (roots only; cache_bounces.c), in the source of the
                                  displayed gathers; NULL with one bounce */
    float eye[3];              /* the viewpoint (scene units): the specular mesh's, and the side of
                                  an emitter the viewer sees (cache_sees_front) */
    float *light_le;           /* light_count × RGB: current radiance (area) or intensity (point) */
    int initialised;
    /* Rays traced for the cache's samples (light points, lobe rays, pilots, gathers,
     * bounce traces; a GL gather counts as CACHE_GL_GATHER_RAYS): what a leaf test
     * of each mesh costs, for the scheduler (cache_sched_refine). A count, not a
     * time, so that refinement stays deterministic. */
    uint64_t effort;
    const atomic_int *stop;    /* cache_refine_desc.stop during a cache_refine call, else NULL */
    const uint32_t *pixels;    /* cache_refine_desc.pixels during a cache_refine call, else NULL (what a
                                  source rebuild bounds the drift of: cache_mark_outdated) */
    cache_startup_stats startup; /* written by cache.c, once (cache_create, the first init) */
    const uint32_t *first_pixels; /* the pixel counts cache_init_seen was given, while it runs */
    struct cache_first_order *first_order; /* cache_first.c: the light's corners in Morton order with
                                              their weights, kept for the gathers' pick (the same
                                              corners) and freed by it */
    /* Which scene triangles take part (allocated by cache.c's cache_init_seen;
     * these fields up to part_tris written by cache_reach.c, which takes
     * triangles part, bounce_active_at by cache.c; read by every file): an
     * active triangle's roots are sampled in every mesh, scheduled, and send
     * light in the indirect source and the bounces' transport; an inactive one
     * has no root in any mesh and sends nothing, until a pixel sees it or a
     * gather from an active triangle reaches it (cache.c, add_roots). NULL:
     * every triangle (cache_init). */
    uint8_t *active;
    uint32_t active_count;
    int rooted;                /* the meshes have the roots of what takes part (cache_init_seen on) */
    uint64_t reach_rays;       /* rays traced to find what gathers reach (cache_stats.reach_rays) */
    uint8_t *reach_traced;     /* per vertex id: its reach was traced (cache_reach_from_gathers) */
    size_t reach_traced_cap;
    uint64_t reach_scan_at;    /* indirect samples when the gathers were last looked at */
    double reach_unit;         /* scene area per reach point (cache_reach.c; 0: not computed yet) */
    uint32_t bounce_active_at; /* active_count when the bounces' transport was traced */
    uint32_t *part_first, *part_tris; /* per scene part its triangles (cache_reach.c; NULL until needed) */
    /* The parts. The meshes' values are written by the part that computes them
     * (light meshes, direct and specular: cache_light.c; indirect: cache_source.c)
     * and their trees by cache_refine.c (splits) and cache_light.c (light meshes). */
    cache_light_state vis;
    cache_outlines outl;
    cache_source_state src;
    uint32_t *corner_ids;      /* desc.corner_ids: made with the first roots (first_roots' helper),
                                  until cache_take_corner_ids hands them over */
    cache_sched sched;
    cache_bounce_state bnc;
    cache_borrow_state brw;
    cache_glossy_state gls;
    /* Per vertex id of the specular mesh: the lights' visible fraction, combined
     * (cache_get_lobe; written by cache_specular.c with each value). */
    float *spec_visible;
    size_t spec_visible_cap;
};

/* Does scene triangle t take part (struct cache.active)? */
static inline int cache_tri_active(const cache *c, uint32_t t) { return !c->active || c->active[t]; }
/* The client asked the refine call in flight to return (cache_refine_desc.stop). */
static inline int cache_stopping(const cache *c) { return c->stop && atomic_load(c->stop) != 0; }

/* ---- cache_site.c: points, leaves, regions, what the viewer sees ----------------- */

/* The mesh of a kind (NULL: the scene has none). */
mesh_qmesh *cache_kind_mesh(const cache *c, cache_kind kind);
/* The sampler's receiver for vertex vid. */
samp_point cache_vertex_point(const cache *c, uint32_t vid);
/* G_ℓ,unoccluded at point p with unit normal n (analytic; point lights cosθ/r²). */
double cache_unoccluded_at(const scene *s, uint32_t light, const float p[3], const float n[3]);
/* The same at vertex vid. */
double cache_unoccluded(const cache *c, uint32_t light, uint32_t vid);

/* Barycentrics (w1, w2) of corner k of a node. */
void cache_node_corner_bary(const mesh_qnode *n, int k, double *w1, double *w2);
/* Leaf lookup: the leaf of mesh m holding barycentric (w1, w2) of scene triangle tri. */
uint32_t cache_find_leaf(const mesh_qmesh *m, uint32_t tri, double w1, double w2);
/* Calls visit for every node of m's tree over rg->tri whose closed triangle can
 * touch the region's (bounding boxes in barycentric space overlap), parents first. */
typedef lm_result (*cache_node_fn)(const mesh_qmesh *m, uint32_t node, const mesh_qnode *n, void *user, lm_error *err);
lm_result cache_region_walk(const mesh_qmesh *m, const cache_region *rg, cache_node_fn visit, void *user, lm_error *err);
/* Is barycentric point (w1, w2) inside the region's closed triangle? */
int cache_region_contains(const cache_region *rg, double w1, double w2);

/* What the viewer sees of material m (RGB radiance, linear, before tone mapping):
 * Le + kd·(L_dd + E_i/π) + ks·L_ds, the composite's formula
 * (shaders/rend_composite.frag, paper §6). Emission leaves the front side only
 * (docs/scene-model.md; rend_material.frag marks the side seen): from the back
 * (front 0) Le is not seen. lds NULL: no specular term. */
void cache_seen_radiance(const scene_material *m, int front, const float ldd[3], const float ei[3],
                         const float lds[3], float rgb[3]);
/* Does the viewer (c->eye) see the front of scene triangle tri: is the eye on the
 * side its geometric normal points to (the side GL calls front: the scene's
 * triangles are counter-clockwise seen from their front, scene.h)? */
int cache_sees_front(const cache *c, uint32_t tri);
/* cache_seen_radiance on scene triangle tri, from the side the viewer sees, tone
 * mapped (the display's own function, tonemap.h) and in CIELAB: what the JND
 * tests compare. */
void cache_seen_lab(const cache *c, uint32_t tri, const float ldd[3], const float ei[3], const float lds[3],
                    float lab[3]);
/* cache_seen_lab at (tri, w1, w2) when the quantity of mesh `kind` has `value`
 * there and the other meshes' are interpolated. */
void cache_seen_lab_with(const cache *c, cache_kind kind, uint32_t tri, double w1, double w2, const float value[3],
                         float lab[3]);
/* The other kinds' terms at (w1, w2) of tri, interpolated (term[kind] is 0): the
 * background cache_seen_lab_with puts a value of `kind` over. */
void cache_other_terms_at(const cache *c, cache_kind kind, uint32_t tri, double w1, double w2,
                          float term[CACHE_KINDS][3]);
/* What an edge test judges a mesh's midpoint against: the other meshes' terms at
 * their darkest (per channel) over the midpoint (w1[0], w2[0]) and the edge's two
 * ends (w1[1..2], w2[1..2]) of scene triangle tri. Their interpolation at the
 * midpoint is no fair background: where a feature crosses the edge (the strip of
 * light under the Veach door) every mesh's interpolation spreads it, the spread
 * saturates the tone map, and each mesh's test then finds its own error invisible
 * against the others' (docs/cache.md, "The door's strip: two meshes masking each other"). The
 * darkest the others may really be there shows the most of a difference
 * (the tone map's slope falls with brightness). A mesh whose leaf at the midpoint
 * has not passed its own test yet (waiting, or the first image's values) masks
 * nothing there (its term is 0): on the door the quick start's indirect, bright
 * over the whole floor, hid the strip from direct tests that were never repeated
 * once it was gathered again. */
void cache_edge_background(const cache *c, cache_kind kind, uint32_t tri, const double w1[3], const double w2[3],
                           float term[CACHE_KINDS][3]);
/* cache_seen_lab when mesh `kind` has `value` and the others have background's terms. */
void cache_seen_lab_over(const cache *c, cache_kind kind, uint32_t tri, const float background[CACHE_KINDS][3],
                         const float value[3], float lab[3]);
/* The value of mesh `kind` that the display shows as white (tonemap.h clips
 * 2^exposure · radiance at 1), per channel, over background's other terms;
 * INFINITY in a channel the value does not brighten (kd or ks 0 there). */
void cache_white_level(const cache *c, cache_kind kind, uint32_t tri, const float background[CACHE_KINDS][3],
                       float white[3]);
/* An edge test's ΔE at a midpoint: its fresh value against the edge's
 * interpolation (the ends end0, end1; the leaf's third corner opposite), over
 * background's terms. Where both are past white the difference is not seen at
 * the midpoint, but the leaf's interpolation carries it inside, toward a darker
 * corner, down to where nothing clips: on the slot's wall by the slit a leaf
 * with a white corner passed its edge tests while its middle was 9% too dark
 * (ΔE 3.7; docs/cache.md, "Differences hidden in white"). So the difference is
 * also judged on the way to the leaf's darkest corner, as the leaf's quadratic
 * carries the midpoint's error there (4·l_a·l_b), and the largest ΔE counts.
 * Unchanged where nothing clips, or where the leaf is white all over. at and
 * lab_at: the interpolation's value and Lab where that ΔE was found. */
float cache_midpoint_seen_de(const cache *c, cache_kind kind, uint32_t tri, const float background[CACHE_KINDS][3],
                             const float fresh[3], const float interp[3], const float end0[3], const float end1[3],
                             const float opposite[3], float at[3], float lab_at[3]);
/* The largest ΔE between what the viewer sees at a node's corners (mesh m of `kind`). */
float cache_leaf_contrast(const cache *c, const mesh_qmesh *m, cache_kind kind, const mesh_qnode *n);

/* ---- cache_specular.c: outlines and specular values --------------------------------- */

/* L_ds (RGB per unit ks) at vertex vid, seen from c->eye, from visible fractions
 * V[0..light_count): Σ_ℓ V_ℓ·L_ℓ·S_ℓ, S_ℓ the Phong lobe integrated over the
 * area light (eq. 5 with V_ℓ constant over the light; samp_polygon_phong), and
 * for a point light the point's exact lobe·G. */
/* It also records the lights' combined visible fraction at vid (cache_get_lobe). */
/* What a renderer that draws the highlights per pixel (cache.h, cache_lobe)
 * shows at specular vertex mid, the midpoint of the edge a–b of a leaf: the
 * glossy parts and the visible fractions of a and b interpolated, the lights'
 * lobe integral at mid itself. Returns 0 (out untouched) where the renderer
 * interpolates the values instead: an exponent below
 * CACHE_HIGHLIGHT_MIN_EXPONENT, or a light it would have to clip (part of its
 * outline below mid's horizon or behind the lobe's hemisphere). */
int cache_specular_drawn(const cache *c, uint32_t a, uint32_t b, uint32_t mid, float out[3]);
/* Writes only vid's entry once cache_specular_reserve covers it: calls for
 * different vertices may then run on different threads (cache_first.c). */
lm_result cache_specular_from_visibility(cache *c, uint32_t vid, const float *V, float rgb[3], lm_error *err);
/* Room for the visible fractions of vertex ids below limit (c->spec_visible). */
lm_result cache_specular_reserve(cache *c, uint32_t limit, lm_error *err);

/* ---- cache_first.c: the first image from a budget of samples --------------------- */

/* Indirect values at root corners v[0..n) into E: every one gathered, or with
 * desc.coarse_gathers, that many and the others borrowed. */
lm_result cache_first_gathers(cache *c, const uint32_t *v, uint32_t n, float *E, lm_error *err);
/* Values of `kind` (direct or specular) at the root corners vids that its mesh
 * uses and has no value for yet, from the light meshes (sampled where they
 * cannot answer). */
lm_result cache_root_values(cache *c, cache_kind kind, const uint32_t *vids, uint32_t n, lm_error *err);
/* With desc.coarse_lights below n: light sampled at that many of the direct
 * mesh's root corners v[0..n), every corner's direct and specular value set
 * (borrowed V elsewhere), the borrowed roots recorded; *done = 1. Else nothing
 * (*done = 0: the caller samples every corner). */
lm_result cache_first_light(cache *c, const uint32_t *v, uint32_t n, int *done, lm_error *err);
/* Frees c->first_order (NULL is a no-op). */
void cache_first_order_free(cache *c);

/* ---- cache_light.c: visibility, direct values, falsified light leaves --------------- */

/* 0 when memory runs out. */
int cache_light_state_init(cache_light_state *st, uint32_t light_count);
void cache_light_state_free(cache_light_state *st);
/* Bookkeeping bytes (the meshes not counted). */
size_t cache_light_state_bytes(const cache_light_state *st, uint32_t light_count);
/* Samples V of light l at the given vertices of its mesh and stores them. */
lm_result cache_sample_light(cache *c, uint32_t l, const uint32_t *vids, uint32_t n, lm_error *err);
/* Fills V_ℓ at every site (V[i·light_count + ℓ]), sampling light meshes where
 * they cannot interpolate confidently (see cache.h). */
lm_result cache_fetch_visibility(cache *c, const cache_site *sites, uint32_t n, float *V, lm_error *err);
/* L_dd (RGB per unit albedo) at vertex vid from visible fractions V[0..light_count);
 * remembers G_ℓ there for cache_set_light. Writes only vid's row once
 * cache_direct_reserve covers it: calls for different vertices may then run on
 * different threads (cache_first.c). */
lm_result cache_direct_from_visibility(cache *c, uint32_t vid, const float *V, float rgb[3], lm_error *err);
/* Room for the G_ℓ rows of vertex ids below limit (cache_light_state.vertex_G). */
lm_result cache_direct_reserve(cache *c, uint32_t limit, lm_error *err);
/* The values (RGB) of the direct or the specular mesh at the sites, from the light
 * meshes (cache_fetch_visibility), counted as that mesh's samples; not stored. */
lm_result cache_light_values(cache *c, cache_kind kind, const cache_site *sites, uint32_t n, float *rgb,
                             lm_error *err);
/* The direct mesh's values again from the G_ℓ kept per vertex (c->light_le changed). */
lm_result cache_relight_direct(cache *c, lm_error *err);

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
/* Records scene triangle t's roots as borrowed (cache_first.c). */
lm_result cache_borrowed_root(cache *c, uint32_t t, lm_error *err);
/* After the first image: the borrowed roots may be recomputed from now on. */
void cache_release_borrowed(cache *c);
/* Up to `most` released borrowed roots become falsified regions (their direct and
 * specular values recomputed by cache_revise_falsified, light sampled where it
 * was borrowed). */
lm_result cache_borrowed_to_regions(cache *c, size_t most, lm_error *err);
/* Borrowed roots not yet made regions, released or not. */
size_t cache_borrowed_waiting(const cache *c);

/* ---- cache_glossy.c: the glossy reflection of the source ------------------------------ */

/* Rays of a new glossy part (a square, for the strata; cache_glossy.c): few, so
 * that a specular leaf's test is not held up by it; where its noise is seen the
 * sweep takes it again with 4× as many, up to 4,096 (docs/cache.md, "Water's
 * first seconds"). */
enum { CACHE_GLOSSY_RAYS = 16 };
/* Does the cache reflect the source in glossy materials (a specular mesh, and
 * cache_desc.glossy CACHE_GLOSSY_INDIRECT)? */
int cache_glossy_on(const cache *c);
/* Adds to rgb[3i..] (the direct specular values of vertices vids[0..n)) their
 * glossy part from the current source, and records it. Before the first source
 * the part is 0 and the values stale. */
lm_result cache_glossy_add(cache *c, const uint32_t *vids, uint32_t n, float *rgb, lm_error *err);
/* A specular value set without its glossy part (the first image's borrowed
 * values): 0 recorded, stale. */
lm_result cache_glossy_forget(cache *c, uint32_t vid, lm_error *err);
/* The source was rebuilt untracked, or the viewpoint moved: every glossy part is stale. */
void cache_glossy_outdate(cache *c);
/* Is vertex vid's glossy part up to date with the current source (a value of
 * the specular mesh)? */
int cache_glossy_fresh(const cache *c, uint32_t vid);
/* A tracked rebuild may have moved vertex vid's glossy part by up to bound
 * (RGB): added to its drift, and the value made stale where that could be seen
 * (cache_drift.c). Not thread-safe: one vertex after another. */
void cache_glossy_drift(cache *c, uint32_t vid, const float bound[3]);
/* Gathers stale glossy parts again from the sweep's cursor, at most *allowance
 * (spent: a part of up to 256 rays counts one, a dearer one its rays / 256),
 * updates their specular values and has `changed` requeue their leaves. */
lm_result cache_glossy_refresh(cache *c, cache_changed_fn changed, void *user, uint64_t *allowance, lm_error *err);
/* Vertex ids the sweep has still to look at (work left: no convergence before). */
uint32_t cache_glossy_waiting(const cache *c);
void cache_glossy_free(cache_glossy_state *st);
/* Bytes held (per vertex id 29: RGB part, drift, generation, level). */
size_t cache_glossy_bytes(const cache_glossy_state *st);

/* ---- cache_drift.c: outdated indirect values ------------------------------------------- */

/* Room for per-vertex drift, flags, noise and levels up to vertex id limit. */
lm_result cache_grow_drift(cache_source_state *st, uint32_t limit, lm_error *err);
/* The values a source rebuild left unbounded because no pixel saw them
 * (cache_source_state.unseen_stale) and that a pixel sees now: flagged outdated. */
lm_result cache_refresh_stale(cache *c, const uint32_t *pixels, lm_error *err);
/* Flags vertex vid outdated (once) for cache_regather_outdated. */
lm_result cache_push_outdated(cache_source_state *st, uint32_t vid, lm_error *err);
/* L_dd at vertex vid: its own value in the direct mesh, else interpolated there. */
void cache_vertex_direct(const cache *c, uint32_t vid, float ldd[3]);
/* Compares the new source (c->src.rmesh) with the previous one (c->src.rp_*),
 * adds the bounds to the drift of every displayed indirect value and flags those
 * that may have moved by more than the JND. */
lm_result cache_mark_outdated(cache *c, lm_error *err);

/* ---- cache_source.c: indirect light ----------------------------------------------------- */

void cache_source_free(cache_source_state *st);
/* Bookkeeping bytes (the meshes not counted). */
size_t cache_source_bytes(const cache_source_state *st);
/* Net splits of the direct mesh plus the values revised in it and the specular
 * mesh: a running count of how much the source's mesh has changed (O(1)). */
int64_t cache_direct_changes(const cache *c);
/* The standard error (RGB) of the displayed indirect value at vertex vid (0 0 0
 * when unknown or exact), as the edge test takes it: from the plain variance of
 * the pilot's rays, which errs high. cache_indirect_likely_sigma: the same with
 * the gather's strata counted (samp_source_hits.strat_var), what the error
 * estimate takes. */
void cache_indirect_sigma(const cache *c, uint32_t vid, float out[3]);
void cache_indirect_likely_sigma(const cache *c, uint32_t vid, float out[3]);
/* Samples E_i at the given vertices (batched): gathered from kd·L_dd, and with
 * further bounces from kd·(L_dd + E_m/π) (c->indirect1, cache_bounces.c). */
lm_result cache_sample_indirect(cache *c, const uint32_t *vids, uint32_t n, float *E, lm_error *err);
/* cache_sample_indirect with at least the rays vertex like[i] was last gathered
 * with (MESH_VTABLE_NONE: no floor): an edge's midpoint, compared with its ends,
 * as precise as they (refine_round). */
lm_result cache_sample_indirect_like(cache *c, const uint32_t *vids, const uint32_t *like, uint32_t n, float *E,
                                     lm_error *err);
/* Is vertex vid on an edge of its triangle that no triangle continues (a mesh
 * boundary)? Gathers there start where the triangle's inside can be seen from
 * (samp_point_pull_inside; docs/cache.md, cause 4). */
int cache_vertex_on_open_edge(const cache *c, uint32_t vid);
/* Where vertex vid's gathers look from: its receiver, pulled inside its
 * triangle on an open edge (cache_vertex_on_open_edge). */
samp_point cache_gather_point(const cache *c, uint32_t vid);
/* The level vertex vid's displayed value was last gathered at (0: the plain
 * count, or none; GATHER_SCALE times the rays a level). */
int cache_gather_level(const cache *c, uint32_t vid);
/* What gathering vertex vid again with the rays it had costs, in gathers of the
 * plain count: GATHER_SCALE^level. */
uint64_t cache_gather_cost(const cache *c, uint32_t vid);
/* Could vertex vid's displayed value be gathered with more rays (cache_regather_finer)? */
int cache_gather_can_refine(const cache *c, uint32_t vid);
/* What cache_regather_finer costs for vertex vid, in gathers of the plain count:
 * GATHER_SCALE^(level + 1). */
uint64_t cache_gather_finer_cost(const cache *c, uint32_t vid);
/* Displayed values gathered again with GATHER_SCALE times the rays they last had
 * (their noise halved): E as cache_sample_indirect. */
lm_result cache_regather_finer(cache *c, const uint32_t *vids, uint32_t n, float *E, lm_error *err);
/* Rebuilds the radiance source from the direct mesh (and E_m) when it is stale. */
lm_result cache_update_radiance_source(cache *c, int force, lm_error *err);
/* Rebuilds the displayed indirect's source if the direct mesh changed at all since
 * it was built (refinement has nothing left to test); the values it moves are
 * flagged for cache_regather_outdated. */
lm_result cache_settle_source(cache *c, lm_error *err);
/* Gathers again, in batches, the indirect values the source's rebuilds may have
 * moved by more than the JND (flagged by cache_update_radiance_source); calls
 * `changed` (regions NULL) with the vertices whose value changed. allowance
 * (NULL: none): at most that many gathers of the plain count (a value taken with
 * 4^L times the rays counts 4^L: cache_gather_cost), taken off it; what is left
 * stays flagged (c->src.outdated_n) for the next call. */
lm_result cache_regather_outdated(cache *c, cache_changed_fn changed, void *user, uint64_t *allowance,
                                  lm_error *err);
/* A borrowed value's state (cache_source_state.borrowed: 0 gathered, INFINITY
 * untested, else the ΔE its test left). */
float cache_borrowed_de(const cache *c, uint32_t vid);
/* Sets vertex vid's indirect value to one borrowed from gathered neighbours, with
 * the standard errors the borrowing carries (RGB: the edge test's and the
 * likely one, as cache_indirect_sigma) and its state de (INFINITY: untested). */
lm_result cache_set_borrowed(cache *c, uint32_t vid, const float E[3], const float sigma[3], const float likely[3],
                             float de, lm_error *err);
/* Gathers every value of the indirect mesh(es) again from rebuilt sources (a light
 * edit, a better sampler); nothing is outdated afterwards. */
lm_result cache_regather_all(cache *c, lm_error *err);
/* The same, later: the source rebuilt now, every displayed indirect value flagged
 * outdated, for cache_regather_outdated to gather a bounded number a refine call
 * (a big scene's hundreds of thousands of values are not one uninterruptible
 * call of the worker). */
lm_result cache_outdate_all(cache *c, lm_error *err);
/* The same for the gathered values only: the borrowed ones are tested instead
 * (cache_borrow.c). */
lm_result cache_outdate_gathered(cache *c, lm_error *err);

/* Importance (Smits et al. 1992, "An importance-driven radiosity algorithm"):
 * after the displayed indirect was gathered at the sites (pixels: per scene
 * triangle, what the viewer sees of it), takes the gather's pilot rays
 * (CACHE_IMPORTANCE_RAYS a site, samp_indirect_sources; nothing is recorded if
 * the last gather was not at these sites) and records at the cut's nodes how
 * much the site's tone-mapped colour depends on their radiance (cache_source_state
 * imp_max, imp_sum). The direct-mesh nodes whose imp_max grew by half or more
 * (0 to anything included) go to `grown` with their count (a buffer owned by
 * the cache, valid until the next call), so the scheduler can refine the source
 * where the viewer now depends on it. */
enum { CACHE_IMPORTANCE_RAYS = 256 };
/* Rays of the lobe-weighted visible fraction at a specular vertex whose light is
 * partly hidden (cache_light.c, samp_lobe_visibility): 16×16 strata of the lobe. */
enum { CACHE_LOBE_RAYS = 256 };
/* Gathers trace their pilot this many points at a time; only a gather of at most
 * this many keeps it for cache_record_importance (cache_source.c, trace_pilot). */
enum { CACHE_PILOT_CHUNK = 4096 };
lm_result cache_record_importance(cache *c, const cache_site *sites, uint32_t n, const uint32_t *pixels,
                                  const uint32_t **grown, uint32_t *grown_n, lm_error *err);
/* The importance of a node of the direct mesh: the largest over it and its
 * ancestors of the recorded value times the node's share of that ancestor's
 * area (hits spread by area), max and sum as in cache_source_state; 0 0 when
 * nothing above it was recorded. */
void cache_node_importance(const cache *c, uint32_t node, float *imp_max, float *imp_sum);

/* ---- cache_bounces.c: bounces beyond the first ------------------------------------- */

/* Traces the transport (once; cache_init, after the coarse direct mesh). */
lm_result cache_bounces_init(cache *c, lm_error *err);
/* E_m from the direct mesh as it is now, and with auto the bounce count, by what
 * cache_bounces_see last said is seen (before it: everything); writes
 * c->indirect1. No ray. */
lm_result cache_bounces_update(cache *c, lm_error *err);
/* The depth of the coarse mesh's leaves on scene triangle tri (0: a root, or none). */
int cache_bounces_depth(const cache *c, uint32_t tri);
/* The lights changed (L_dd without a change of the direct mesh's shape): the
 * next cache_bounces_update evaluates again. */
void cache_bounces_touch(cache *c);
/* The seen coarse vertices from now on: the corners of triangles with pixels. */
void cache_bounces_see(cache *c, const uint32_t *pixels);
/* The scene triangles with a diffuse albedo: the roots of the direct, indirect and
 * coarse meshes, and the surfaces the bounces' transport records (a mesh root filter). */
int cache_has_albedo(const scene *s, uint32_t t, void *user);
void cache_bounces_free(cache_bounce_state *b);

/* ---- cache_borrow.c: borrowed indirect values tested ------------------------------ */

/* The weights of donors d[0..nd) (vertex ids, nd ≤ 4) for vertex vid: those whose
 * normal is within 72° of its own, (n·n_g)² over the distance (span: the scale
 * that keeps the distance off 0); the nearest if none is. Writes the donors'
 * indices into q and their weights into w; returns how many (0: nd was 0). */
int cache_borrow_weights(const cache *c, uint32_t vid, const uint32_t *d, int nd, double span, int q[4], double w[4]);
/* What vertex vid borrows from donors d[0..nd) (vertex ids with indirect values
 * and σ): their mean with cache_borrow_weights, into E, and its standard errors
 * (the edge test's and the likely one, as cache_indirect_sigma) from theirs.
 * Returns 0, writing nothing, when no donor weighs. */
int cache_borrow_mean(const cache *c, uint32_t vid, const uint32_t *d, int nd, double span, float E[3], float sg[3],
                      float sl[3]);
/* Takes the first image's order (n vertex ids, Morton order; the array is the
 * cache's from now on) and its donors' positions at[0..nchosen) (ascending):
 * every other corner is borrowed (untested) and its span waits for
 * cache_borrow_release. */
lm_result cache_borrow_start(cache *c, uint32_t *order, uint32_t n, const uint32_t *at, uint32_t nchosen,
                             double span, lm_error *err);
/* From now on cache_borrow_test tests the spans (the first image's regather). */
void cache_borrow_release(cache *c);
/* Borrowed corners whose span waits for a test, once released (0 before). */
uint64_t cache_borrow_pending(const cache *c);
/* Tests pending spans, at most *allowance gathers (taken off it; NULL: all):
 * gathers their middles, splits or accepts them, and calls `changed` (regions
 * NULL) with the vertices whose value changed. pixels: per scene triangle (NULL:
 * every triangle a million: every span splits to single corners). */
lm_result cache_borrow_test(cache *c, const uint32_t *pixels, cache_changed_fn changed, void *user,
                            uint64_t *allowance, lm_error *err);
/* Accepted spans whose ΔE is above `above` are tested again: the JND changed
 * (above = the new JND), or the exposure (above < 0: every span). */
lm_result cache_borrow_retest(cache *c, float above, lm_error *err);
/* Everything gathered now (a full regather): the spans go. */
void cache_borrow_free(cache_borrow_state *b);
size_t cache_borrow_bytes(const cache_borrow_state *b);

/* ---- cache_estimate.c: the error estimate, values worth more rays ------------------ */

/* A leaf's interpolation error from its edge test (ΔE; cache_sched.resid); < 0:
 * not known. *tested: from its own test (not its parent's); may be NULL. */
float cache_sched_residual(const cache_sched *st, cache_kind kind, uint32_t node, int *tested);
/* The distinct vertices of the visible indirect leaves whose estimated error
 * exceeds the JND with noise in it, and that could be gathered with more rays,
 * the leaves with the most pixels × noise first; as many as max_cost plain
 * gathers pay for at their next level (cache_gather_finer_cost), at least one.
 * *out: malloc'ed, the caller frees it. top (may be NULL): the first leaf's
 * pixels × noise ΔE and what its corners cost at their next level, in plain
 * gathers (0, 0: none). */
typedef struct cache_noisy_top {
    float priority;
    uint64_t cost;
} cache_noisy_top;
lm_result cache_noisy_vertices(const cache *c, const uint32_t *pixels, uint64_t max_cost, uint32_t **out, uint32_t *count,
                               cache_noisy_top *top, lm_error *err);

/* ---- cache_reach.c: what takes part ------------------------------------------------------- */

/* Takes part the triangles seed[0..nseed) that do not yet, and, transitively,
 * the part (scene_part) of every triangle with albedo that CACHE_REACH_RAYS cosine-weighted rays from a
 * newly taken triangle meet: from the corners of its direct-mesh root and, on a
 * large triangle, from points spread over it (one per 1/CACHE_REACH_POINTS of
 * the scene's area, at most 256). *out (malloc'ed) lists the newly taken ones. */
enum { CACHE_REACH_POINTS = 8192 };
lm_result cache_reach_take(cache *c, const uint32_t *seed, uint32_t nseed, uint32_t **out, uint32_t *nout,
                           lm_error *err);
/* The same from the displayed indirect mesh's vertices gathered since it last
 * looked (when the indirect samples have grown by an eighth): a refined gather
 * point may see what the root corners did not. *out as cache_reach_take. */
lm_result cache_reach_from_gathers(cache *c, uint32_t **out, uint32_t *nout, lm_error *err);

/* ---- cache_queue.c and cache_refine.c: the scheduler ------------------------------------ */

void cache_sched_init(cache_sched *st, uint32_t seed);
void cache_sched_free(cache_sched *st);
size_t cache_sched_bytes(const cache_sched *st);
/* Every leaf of that mesh (kind; CACHE_KINDS: of every mesh) is scheduled afresh
 * at the next cache_sched_refine (a light or the camera changed). */
void cache_sched_requeue(cache_sched *st, int kind);
/* A mesh's yield: what its leaf tests removed per unit of the priority they
 * were picked at, lately (cache_sched.removed / predicted; 1 before its first
 * test since its queue was last made). The heap scheduler weighs the mesh's top
 * priority by it. */
double cache_sched_yield(const cache *c, cache_kind kind);
/* Forgets every residual of one mesh (its tree was made anew: cache_set_camera). */
void cache_sched_forget(cache_sched *st, cache_kind kind);
/* A leaf of `kind` covering px pixels that no test splits: no larger than a
 * sample of the picture (cache_desc.sample_pixels), or smaller than a pixel and
 * a root, or indirect (docs/cache.md, "Leaves smaller than a pixel"). */
int cache_leaf_below_sample(const cache *c, cache_kind kind, double px, const mesh_qnode *n);
/* The part of a pixel a leaf of px pixels is seen in: a leaf smaller than a
 * pixel is one of several in its box filter, and its ΔE counts by this share in
 * its test, its residual and the estimate (docs/cache.md, "Leaves smaller than a
 * pixel"). */
static inline float cache_pixel_share(double px) { return px < 1.0 ? (float)px : 1.0f; }
/* The pixels a leaf covers: its scene triangle's (pixels; NULL: 1e6) over 4^depth. */
float cache_leaf_pixels(const uint32_t *pixels, const mesh_qnode *n);
/* A mesh's heap (cache_queue.c): push, and pop the highest priority. */
lm_result cache_queue_push(cache_queue *q, float priority, uint32_t node, uint32_t v0, lm_error *err);
cache_queue_entry cache_queue_pop(cache_queue *q);
/* The next leaf of `kind` to test and the priority it was picked at (heap or
 * randomized scheduler); 0 when none is waiting. */
int cache_sched_pick(cache *c, cache_kind kind, const uint32_t *pixels, uint32_t *out, float *picked);
/* Room for node priorities up to `node` (the randomized scheduler's). */
lm_result cache_sched_grow_prio(cache *c, int kind, uint32_t node, lm_error *err);
/* Records a leaf's interpolation error (ΔE; cache_sched.resid), from its own
 * test (tested) or its parent's. */
lm_result cache_sched_set_residual(cache *c, cache_kind kind, uint32_t node, float delta_e, int tested, lm_error *err);
/* A leaf whose test found nothing (its split undone): not picked again until requeued. */
lm_result cache_sched_done(cache *c, cache_kind kind, uint32_t node, lm_error *err);
/* Schedules every leaf of one mesh afresh (seen_only: the triangles with pixels
 * now, the rest at the next call): heap, done flags and priorities rebuilt. */
lm_result cache_sched_schedule(cache *c, cache_kind kind, const uint32_t *pixels, int seen_only, lm_error *err);
/* The highest priority waiting in a mesh's heap (a guess: stale entries count). */
float cache_sched_top_priority(const cache *c, int kind);
/* A surface stands on the leaf between two of its corners (cache_refine.c): their
 * interpolation would leak light through it. */
int cache_corners_parted(const cache *c, const mesh_qnode *n);

/* The Morton (Z-order) key of three 21-bit coordinates: their bits interleaved
 * from the top, q[0]'s first (bit b of q[k] is the key's bit 3b + 2 − k). Points
 * close along the curve are close in space (cache_first.c's picks,
 * cache_drift.c's tree). */
static inline uint64_t cache_morton_spread(uint32_t x)
{
    uint64_t v = x & 0x1fffffu;
    v = (v | v << 32) & 0x1f00000000ffffULL;
    v = (v | v << 16) & 0x1f0000ff0000ffULL;
    v = (v | v << 8) & 0x100f00f00f00f00fULL;
    v = (v | v << 4) & 0x10c30c30c30c30c3ULL;
    v = (v | v << 2) & 0x1249249249249249ULL;
    return v;
}
static inline uint64_t cache_morton_key(const uint32_t q[3])
{
    return cache_morton_spread(q[0]) << 2 | cache_morton_spread(q[1]) << 1 | cache_morton_spread(q[2]);
}
/* cache_refine (cache.h) on an initialised cache. */
lm_result cache_sched_refine(cache *c, const cache_refine_desc *desc, cache_refine_result *out, lm_error *err);
/* Leaf `node` of mesh `kind` queued at priority p; a second entry of a queued
 * leaf is dropped when popped. */
lm_result cache_sched_add(cache *c, cache_kind kind, uint32_t node, float p, lm_error *err);
/* Priority of a leaf (§4.3.3): its pixels × (1 + the largest ΔE between its
 * corners); an unseen source leaf's, cache_unseen_priority. */
float cache_leaf_priority(const cache *c, const mesh_qmesh *m, cache_kind kind, uint32_t node, const mesh_qnode *n,
                          const uint32_t *pixels);

/* ---- cache_unseen.c: the direct mesh as the source where no pixel sees it ------------- */

/* A leaf of the direct mesh that no pixel sees: refined as the indirect source,
 * for what the visible gathers draw from it (importance), not for its pixels. */
int cache_unseen_leaf(const uint32_t *pixels, cache_kind kind, const mesh_qnode *n);
/* An unseen leaf's priority in pixel·ΔE, the units of cache_leaf_priority. */
float cache_unseen_priority(const cache *c, uint32_t node, const mesh_qnode *n);
/* How many generations of an unseen node's ancestors found their corners and
 * midpoints dark (cache_sched.dark_gen), and setting it. */
uint32_t cache_unseen_dark_generations(const cache *c, uint32_t node);
lm_result cache_unseen_set_dark_generations(cache *c, uint32_t node, uint32_t gen, lm_error *err);
/* Dark at its corners and at the midpoints mid its test sampled. */
int cache_unseen_all_dark(const cache *c, const mesh_qnode *n, const uint32_t mid[3]);
/* Whether the viewer could see a split of unseen leaf node (n) with midpoints
 * mid through the gathers; *seen_change: that change in pixel·ΔE. */
int cache_unseen_split_seen(const cache *c, uint32_t node, const mesh_qnode *n, const uint32_t mid[3],
                            float *seen_change);
/* After visible gathers at sites[0..n): records where they draw from and
 * schedules the unseen source leaves whose importance grew. */
lm_result cache_unseen_schedule_important(cache *c, const cache_site *sites, uint32_t n, const uint32_t *pixels,
                                          lm_error *err);

/* ---- cache_requeue.c: values changed under the refinement, their leaves again --------- */

/* Falsified light leaves, outdated indirect values (at most *allowance), stale
 * glossy parts (*glossy_allowance) and the first image's borrowed values
 * recomputed, and the leaves around them queued again. */
lm_result cache_requeue_revise(cache *c, const uint32_t *pixels, uint64_t *allowance, uint64_t *glossy_allowance,
                               lm_error *err);
/* Indirect values whose noise keeps a visible leaf above the JND gathered again
 * with more rays (as many as a few plain gathers a leaf of the budget pay for;
 * *done counts them), their leaves queued again; nothing unless the worst such
 * leaf's noise removed per ray is at least min_rate (the leaf tests' rate, in
 * the units of next_kind, cache_refine.c: pixels × ΔE per ray). */
lm_result cache_requeue_noisy(cache *c, const uint32_t *pixels, uint32_t budget, double min_rate, uint32_t *done,
                              lm_error *err);

#endif
