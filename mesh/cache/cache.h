/* cache.h — the multi-mesh cache (paper §4; docs/cache.md): per-light
 * direct irradiance meshes, the indirect irradiance mesh, the direct diffuse
 * radiance mesh and (for glossy materials) the direct specular radiance mesh over
 * one shared vertex table, and the values at their vertices.
 *
 * Meshes (quadtree forests over the scene's triangles, qmesh.h):
 *   light[ℓ]   per light, 1 channel: the VISIBLE FRACTION V_ℓ = G_ℓ / G_ℓ,unoccluded
 *              at each vertex. The cache serves G_ℓ(x) = V_ℓ(x)·G_ℓ,unocc(x), the
 *              second factor from Lambert's formula (analytic.c) at x itself. Where
 *              a light is wholly visible (V = 1) or hidden (V = 0) the cache is then
 *              exact without samples inside; only penumbra needs samples (DESIGN's
 *              control variate, carried into the mesh). Roots: the triangles that
 *              can see the light at all (not behind it, light not below them).
 *   direct     direct diffuse radiance per unit albedo, RGB: L_dd = (1/π)·Σ L_ℓ·G_ℓ
 *              (eq. 4). View-independent: kept across camera moves.
 *   indirect   indirect irradiance E_i, RGB (eq. 7), gathered from kd·L_dd (one bounce;
 *              more: kd·(L_dd + E_m/π), cache_bounce_stats) over a
 *              cut of the direct mesh (the roots and at most 8,192 more triangles,
 *              opened where its linear interpolation error × importance is worst);
 *              the back of a surface sends nothing. Each value carries its
 *              standard error; where that could be seen it is gathered again with
 *              more rays, and the edge test ignores what the noise explains;
 *              values whose noise keeps a leaf above the JND are gathered again
 *              with more rays (cache_estimate), competing with the leaf tests
 *              by the visible error removed per ray, and once nothing is left
 *              to test.
 *              Visible gathers record where they draw from (importance), and the
 *              direct mesh on triangles no pixel sees is refined by the visible
 *              change it can cause through them (docs/cache.md). When a rebuilt source may have moved a gathered value by
 *              more than the JND (a bound: the changed source triangles' largest
 *              change × their cosine-weighted solid angle), it is gathered again.
 *   specular   direct specular radiance per unit ks, RGB, over the triangles whose
 *              material has ks > 0 only (none: no mesh): eq. 5 with V_ℓ out of
 *              the integral, Σ_ℓ V_ℓ·L_ℓ·∫_{A_ℓ} (n+2)/(2π)·cosⁿα·cosθ_x·cosθ_y/r² dA
 *              (the integral exact: samp_polygon_phong; a point light's lobe·G);
 *              it depends on the eye, so cache_set_camera rebuilds it.
 *
 * A radiance vertex's value fetches V_ℓ from each light mesh (§4.3.4): read by
 * interpolation where the light mesh can do so confidently (the enclosing light
 * leaf has V uniformly 1 or uniformly 0 at its corners and is at most
 * CACHE_LIGHT_LAG levels coarser than the radiance leaf asking), else the light
 * mesh is split down to the asking vertex and sampled. It never goes deeper than
 * the radiance refinement asks. A uniform light leaf that is later split (for a
 * deeper site) and finds a midpoint that disagrees was wrong wherever it had
 * answered: the radiance values inside it are fetched again from the finer light
 * mesh and their leaves tested again (cache_stats.falsified, .revised).
 *
 * Usage (worker thread):
 *     cache *c; lm_error err;
 *     cache_create(&(cache_desc){.scene = s, .sampler = sp}, &c, &err);
 *     cache_init(c, &err);                         // coarse: every scene vertex sampled
 *     cache_refine(c, &(cache_refine_desc){.pixels = ids.pixels, .budget = 1000}, &err);
 *     float rgb[3]; cache_eval_direct(c, tri, w1, w2, rgb, &err);
 *     cache_destroy(c);
 *
 * Threads: a cache, its meshes and its sampler belong to one thread (the
 * refinement worker); nothing here is thread safe.
 * Does NOT do: publishing to the display (cache_worker.h), the exact specular
 * integral (eq. 5; the reference renderer does).
 */
#ifndef LUMESH_CACHE_H
#define LUMESH_CACHE_H

#include <stdatomic.h>
#include <stdint.h>

#include "mesh/qmesh.h"
#include "mesh/vtable.h"
#include "sampling/samp.h"
#include "src/base/util.h"
#include "src/scene/scene.h"

#ifdef __cplusplus
extern "C" {
#endif

enum {
    CACHE_LIGHT_LAG = 2, /* a light leaf may be this many levels coarser than the radiance leaf and still interpolate */
    CACHE_BOUNCES_AUTO = -1, /* cache_desc.bounces: until the rest would change what is seen by at most a
                                quarter of the JND */
    CACHE_BOUNCES_MAX = 32,  /* most diffuse bounces, asked or chosen */
    CACHE_BOUNCE_RAYS_DEFAULT = 64 /* rays per coarse vertex of the further bounces' transport */
};

typedef enum cache_scheduler {
    CACHE_SCHED_HEAP = 0,  /* default: the highest-priority leaves first, from a max-heap per mesh; each
                              round to the mesh whose top priority per ray of a test is highest */
    CACHE_SCHED_RANDOM,    /* the paper's §4.3.3: keep refining the current triangle until a random pick beats it */
    CACHE_SCHED_COUNT
} cache_scheduler;

/* What glossy materials reflect (cache_desc.glossy). */
typedef enum cache_glossy {
    CACHE_GLOSSY_INDIRECT = 0, /* default: the lights (eq. 5) and the indirect source through the lobe
                                  (docs/cache.md, "Glossy reflection of the room") */
    CACHE_GLOSSY_DIRECT,       /* the lights only: the paper's model, and references made before */
    CACHE_GLOSSY_COUNT
} cache_glossy;

typedef struct cache_desc {
    const scene *scene;       /* must outlive the cache */
    samp_sampler *sampler;    /* samples G and E_i; owned by the caller, same thread */
    float jnd;                /* CIELAB ΔE (CIE76) a viewer notices; 0 = 2.0 */
    float exposure_offset;    /* stops added to the scene's exposure for the JND test; 0 = none */
    int bounces;              /* diffuse bounces shown: 1 (0: the default), 2..CACHE_BOUNCES_MAX, or
                                 CACHE_BOUNCES_AUTO (cache_bounces.c; docs/cache.md "Bounces") */
    cache_glossy glossy;      /* what the specular mesh holds besides the lights' highlights */
    uint32_t bounce_rays;     /* bounces beyond the first: rays per coarse vertex of their transport,
                                 a square; 0 = CACHE_BOUNCE_RAYS_DEFAULT */
    float min_leaf_pixels;    /* size criterion: leaves above this many pixels split anyway; 0 = 16 */
    float sample_pixels;      /* area of one sample of the picture drawn from the cache, in pixels
                                 (1/s² for s×s samples a pixel), 0 < it ≤ 1: no leaf this small or
                                 smaller is tested, and a leaf smaller than a pixel is judged by its
                                 share of its pixel (docs/cache.md, "Leaves smaller than a pixel");
                                 0 = 1 (one sample a pixel) */
    uint32_t node_cap;        /* most nodes over all meshes; 0 = no cap */
    uint32_t coarse_lights;   /* the first image's budget of light samples: light is sampled at no
                                 more of the direct mesh's root corners than this, chosen as the
                                 gathers are (mesh/cache/cache_first.c), and the others borrow each
                                 light's visible fraction from them, until the first
                                 cache_regather_indirect or cache_set_bounces: after that the
                                 refine calls sample them and recompute their values (a bounded
                                 number a call, before any leaf is tested). 0 = every corner */
    uint32_t coarse_gathers;  /* the first image's budget (docs/cache.md "Start-up bounded by what is
                                 seen"): the coarse cache gathers indirect light at no more root
                                 corners than this, spread over the scene, and the other corners
                                 borrow from the gathered ones near them, until the first
                                 cache_regather_indirect or cache_set_bounces: that flags the
                                 gathered values, and cache_refine gathers them again and tests
                                 the borrowed ones (cache_borrow.c: kept where a gather in their
                                 run agrees), a bounded number a call, before it refines (from
                                 then on every corner is gathered at once); 0 = every corner */
    cache_scheduler scheduler;
    uint32_t seed;            /* the random scheduler's picks */
    int single_mesh;          /* ablation: one combined radiance mesh (Tole et al. 2002): no
                                 per-light meshes (every new vertex samples every light), and
                                 indirect gathered at every new vertex, split for split with
                                 direct, judged together by one edge test */
    int eye_set;              /* non-zero: eye is the specular mesh's first viewpoint; 0 = the
                                 scene's first camera (a front end rendering another camera
                                 sets it, or its highlights are refined for the wrong eye) */
    float eye[3];             /* scene units; finite */
    int corner_ids;           /* non-zero: the cache makes each scene corner's vertex-table id with its
                                 first roots, for cache_take_corner_ids (a worker publishing whole
                                 roots: cache_worker_desc.whole_roots); 0 = not made */
} cache_desc;

typedef struct cache cache;

lm_result cache_create(const cache_desc *desc, cache **out, lm_error *err);
void cache_destroy(cache *c); /* NULL is a no-op */

/* Roots on every triangle and samples at every root corner of every mesh: the
 * coarse cache (a constant ambient stands in for indirect until the coarse direct
 * mesh exists; it exists after this). */
lm_result cache_init(cache *c, lm_error *err);

/* The coarse cache over what is needed only (issue 16, docs/cache.md "Start-up
 * bounded by what is seen"): the triangles with pixels (rend_id counts, per scene
 * triangle), and those that gathers from them reach, found by tracing
 * CACHE_REACH_RAYS cosine-weighted rays from the corners of each newly taken
 * triangle until no new one is met (the reach of reach too: further bounces
 * travel it). Only those get roots in the meshes (cache_create makes them empty;
 * the vertex table has every scene corner from creation on). The others have
 * no root and send no light until cache_refine's pixels see one (a camera
 * move), which takes it and what it reaches the same way, roots included.
 * pixels NULL: cache_init. Units: none. */
enum { CACHE_REACH_RAYS = 16 };
lm_result cache_init_seen(cache *c, const uint32_t *pixels, lm_error *err);

/* The cache's estimate of its error (cache_estimate_error, below, says what each
 * figure means). */
typedef struct cache_mesh_estimate {
    double pixels;            /* pixels this mesh's visible leaves cover */
    double interpolation;     /* pixel-weighted mean ΔE */
    double noise;             /* pixel-weighted mean ΔE */
    double combined;          /* pixel-weighted mean of each leaf's √(interpolation² + noise²): the
                                 two are independent (a leaf's fixed shape, its values' noise) */
    double max;               /* the largest leaf's combined ΔE */
    double pixels_above_jnd;  /* pixels in leaves whose combined ΔE exceeds the JND */
    double pixels_untested;   /* pixels in leaves larger than a pixel that no test of their own has
                                 looked at (a root, or a child taking its parent's figure): there the
                                 estimate is a guess */
} cache_mesh_estimate;

typedef struct cache_estimate {
    cache_mesh_estimate direct, indirect, specular; /* specular: zero without a specular mesh */
    double pixels;            /* pixels that see a scene triangle (the pixel counts' sum) */
    double mean;              /* mean ΔE over those pixels: the meshes' combined errors added */
    double above_jnd;         /* fraction of those pixels in a leaf above the JND (the meshes' summed, ≤ 1) */
    double untested;          /* fraction of those pixels in a leaf not tested yet (the worst mesh's):
                                 the estimate means little until this is near 0 */
    float jnd;                /* the JND it was measured against */
    float exposure;           /* the display's exposure it was measured at (stops: cache_set_exposure) */
    int measured;             /* 1: made (cache_estimate_error); 0: none yet, the fields above are 0 but
                                 untested (1), jnd and exposure: a worker's first snapshot, published
                                 before any leaf is tested, carries none (cache_worker.h) */
} cache_estimate;

/* Indirect values a rebuilt source moved that one cache_refine call gathers
 * again, per leaf of its budget, unless cache_refine_desc.regather says. One: on
 * the Veach door a rebuild after the first image flags about 2,800 values, which
 * at 8 a leaf (4,096 a worker's step) were one call of 3 s with no snapshot, the
 * first image shown meanwhile (relMSE 15 at 3 s, 0.77 at one a leaf); the 116k
 * box converges in the same time either way (docs/cache.md, "Leaves shared by
 * cost"). */
#define CACHE_REGATHER_PER_LEAF 1

typedef struct cache_refine_desc {
    const uint32_t *pixels;   /* per scene triangle, pixels it covers (rend_id); NULL: all 1e6 */
    uint32_t budget;          /* leaves to test in this call; 0 = 256 */
    uint32_t regather;        /* at most this many gathers of the plain count of outdated indirect
                                 values gathered again first (a value gathered with 4^L times the
                                 rays counts 4^L); 0 = CACHE_REGATHER_PER_LEAF × budget. A caller that caps the leaf
                                 tests (a total to reach) keeps this at its step's size: the values
                                 are owed to the coarse cache, not leaf tests */
    int seen_only;            /* non-zero with pixels: a queue not yet made is made of the leaves of
                                 triangles with pixels only, and the next call without it makes the
                                 whole one (the first image: the 1M-triangle scene's first call
                                 spent 1 s giving a priority to 3 million leaves, most unseen) */
    const atomic_int *stop;   /* non-NULL: looked at between batches of gathers and between rounds;
                                 once non-zero the call returns after the batch or round in flight
                                 (nothing is lost: what is left stays flagged or queued and counts in
                                 remaining). A worker being cancelled: a step of the 116k box's first
                                 regather made its client wait 1.2 s (docs/cache.md) */
    int first_image;          /* non-zero: the rounds before the first image (the worker's first_budget):
                                 after the budget's leaves the source is brought up to date with the
                                 direct mesh they refined, and the seen indirect leaves of at least
                                 1/256 of the seen pixels (none a surface parts) are tested with a
                                 fifth of the budget more, gathering from it, although the
                                 first image's indirect values are still owed (they are all gathered
                                 again after it). Water's ceiling, lit only by the walls, was black
                                 in the first image and until 0.5 s without it (docs/renderer.md) */
    int wait_for_indirect;    /* non-zero: no leaf is tested while indirect values are owed (the first
                                 image's borrowed ones, or ones a rebuilt source flagged), so that
                                 they are judged against the source they were flagged by (a test of
                                 those values). 0: the direct and specular leaves are tested meanwhile
                                 (the Veach door's floor showed the lamp room's direct light for the
                                 0.6 s its first indirect values took) */
} cache_refine_desc;

typedef struct cache_refine_result {
    uint32_t tested, split, undone;  /* leaves tested; splits kept; splits undone (found nothing) */
    uint32_t remaining;              /* leaves still waiting to be tested, and outdated values */
    uint32_t outdated;               /* indirect values still waiting to be gathered again (no indirect
                                        leaf is tested until they are) */
    uint32_t regathered_finer;       /* indirect values gathered again with more rays (their noise was seen) */
    int converged;                   /* nothing left to do, and the estimate is below the JND
                                        (cache_estimate_converged) */
    int stuck;                       /* nothing left to do, yet not converged: the estimate's error is
                                        where no test or ray count reaches (reported, not claimed) */
    int estimated;                   /* non-zero: estimate holds the estimate the claim was made from
                                        (made when nothing is left to do; cache_estimate_error) */
    cache_estimate estimate;
} cache_refine_result;

/* Tests the edges of the highest-priority leaves of the direct, indirect and
 * specular meshes (§4.3; the coarse cache first if cache_init was not called): splits where the tone-mapped fresh value differs from the
 * interpolated one by more than the JND, or where a leaf covers more than
 * min_leaf_pixels; undoes splits that found nothing. When no leaf is left to
 * test, the indirect values whose noise keeps a leaf above the JND are gathered
 * again with more rays (cache_estimate_error) and their leaves tested again;
 * only when that too is done does it say whether it has converged. */
lm_result cache_refine(cache *c, const cache_refine_desc *desc, cache_refine_result *out, lm_error *err);

/* The viewpoint of the specular mesh (scene units). A new eye resets that mesh
 * to its roots and samples them again; the view-independent meshes are kept.
 * At creation the eye is the scene's first camera. */
lm_result cache_set_camera(cache *c, const float eye[3], lm_error *err);

/* Another sampler from now on (same thread; the caller owns both). The refinement
 * worker makes the coarse cache with a quick sampler and then switches. */
void cache_set_sampler(cache *c, samp_sampler *sp);
/* Gathers every vertex of the indirect mesh(es) again with the current sampler
 * (after cache_set_sampler: the coarse cache's quick gathers replaced): at once,
 * or, after a first image made with cache_desc.coarse_gathers, by the next
 * cache_refine calls, which gather the gathered values again and test the
 * borrowed ones (see coarse_gathers). */
lm_result cache_regather_indirect(cache *c, lm_error *err);
/* Flags for gathering again, by cache_refine a bounded number a call as above,
 * every indirect value gathered at the plain count of its sampler (not the
 * borrowed ones, nor those taken with more rays for their noise): after
 * cache_set_sampler to a sampler with a larger plain count (the worker's start
 * count giving way to Embree's default at the first convergence), they are the
 * values whose noise is above what the new count allows. */
lm_result cache_outdate_plain(cache *c, lm_error *err);
/* The pixel counts given to cache_refine changed (a new view): every mesh's
 * leaves are scheduled again by the new priorities at the next cache_refine. */
lm_result cache_requeue(cache *c, lm_error *err);
/* The JND refinement works to from now on (ΔE; > 0): every leaf is tested again
 * against it at the next cache_refine, and the error estimate counts pixels above
 * it. The refinement worker halves it after each convergence, down to a floor
 * (cache_worker_desc.jnd_floor: "never plateau", docs/cache.md). */
lm_result cache_set_jnd(cache *c, float jnd, lm_error *err);
float cache_get_jnd(const cache *c);
/* The exposure the picture is shown at from now on (stops, as the scene's
 * tonemap.exposure, which it is at creation; the viewer's + and −): every ΔE the
 * cache judges (the edge tests, the borrowed values' tests, auto bounces, the
 * error estimate) is of the colour at that exposure. What was clipped to white or
 * too dark to see may now be seen, and what was seen may no longer be: as after
 * cache_set_jnd every leaf is tested again, and the ΔE its last test left is
 * forgotten (it was measured at the old exposure), so the estimate does not call
 * the cache converged until the tests have looked again. No sample is taken here. */
lm_result cache_set_exposure(cache *c, float exposure, lm_error *err);
float cache_get_exposure(const cache *c);
lm_result cache_eval_specular(const cache *c, uint32_t tri, double w1, double w2, float rgb[3], lm_error *err);

/* Changes light `light`'s radiance (area light, W·m⁻²·sr⁻¹) or intensity (point
 * light, W·sr⁻¹): the direct mesh is recomputed from the G_ℓ it keeps per vertex,
 * with no new light sample (that is why G_ℓ is stored per light); the indirect
 * mesh is gathered again at its vertices from the updated source; the specular
 * mesh is rebuilt from its roots (the light meshes answer without new samples
 * where they are sure). */
lm_result cache_set_light(cache *c, uint32_t light, const float value[3], lm_error *err);

/* The diffuse bounces shown from now on (cache_desc.bounces: 1..CACHE_BOUNCES_MAX
 * or CACHE_BOUNCES_AUTO): the further bounces' transport is traced if it was not
 * (bounce rays, no light sample) or dropped (1), and every indirect value is
 * gathered again from the new source, as after a light edit. */
lm_result cache_set_bounces(cache *c, int bounces, lm_error *err);

/* Priority of a node of the direct (0), indirect (1) or specular (2) mesh under the random
 * scheduler: a leaf's own, an inner node's the maximum of its children's. */
float cache_node_priority(const cache *c, int mesh, uint32_t node);

/* Values at barycentric point (1−w1−w2, w1, w2) of scene triangle tri,
 * interpolated from the leaves: L_dd (RGB, per unit albedo), E_i (RGB), G_ℓ. */
lm_result cache_eval_direct(const cache *c, uint32_t tri, double w1, double w2, float rgb[3], lm_error *err);
lm_result cache_eval_indirect(const cache *c, uint32_t tri, double w1, double w2, float rgb[3], lm_error *err);
lm_result cache_eval_G(const cache *c, uint32_t light, uint32_t tri, double w1, double w2, double *G, lm_error *err);

typedef struct cache_mesh_stats {
    mesh_qmesh_stats mesh;
    uint64_t samples;           /* fresh samples taken for this mesh */
    uint64_t interpolated;      /* values served by interpolation instead of a sample */
    double yield;               /* direct, indirect, specular: what its leaf tests removed per unit of
                                   the priority they were picked at, lately (pixel·ΔE per pixel·ΔE;
                                   1 before its first test since its queue was last made: a new view,
                                   a light edit, a lower JND; the heap scheduler weighs the mesh by it,
                                   docs/cache.md "Meshes weighed by what their tests remove"); light
                                   meshes: 0 */
} cache_mesh_stats;

/* Bounces beyond the first (docs/cache.md "Bounces"): they enter the displayed
 * gathers through the source, kd·(L_dd + E_m/π), E_m the irradiance of bounces
 * 1..K−1 at the coarse vertices, from a transport recorded once (rays, no
 * samples after that). */
typedef struct cache_bounce_stats {
    int bounces;              /* shown now (1 with no further-bounce transport) */
    int automatic;            /* chosen by auto */
    float rest_de;            /* the largest ΔE all further bounces would add where seen (auto's test) */
    float de[CACHE_BOUNCES_MAX + 2]; /* de[k], k ≥ 2: the largest ΔE bounce k adds where it is seen */
    double seconds[CACHE_BOUNCES_MAX + 2]; /* seconds[k]: evaluating B_k on the coarse mesh, in all (k = 1:
                                              from the direct mesh; the displayed first bounce's gathers
                                              are the indirect mesh's samples) */
    double series_seconds;    /* evaluating the whole series, in all (auto's test and rest_de) */
    char why[192];            /* why this many (auto: why it stopped) */
    uint32_t vertices;        /* coarse vertices of the transport */
    uint32_t direct_vertices; /* direct-mesh vertices added to make it as fine as the coarse mesh */
    uint32_t rays;            /* rays per vertex */
    uint64_t hits;            /* hits kept */
    double trace_seconds;     /* tracing the transport (once) */
    double update_seconds;    /* re-evaluating it, in all */
    uint64_t updates;         /* times re-evaluated (source rebuilds, light edits) */
} cache_bounce_stats;

/* Where the time before the first image went (cache_create and the first
 * cache_init_seen / cache_init; wall seconds on the calling thread). */
typedef struct cache_startup_stats {
    double create_seconds;  /* cache_create: the vertex table (every scene corner) and the empty meshes */
    double reach_seconds;   /* finding what takes part (seen triangles and what they reach), and
                               their roots in every mesh */
    double light_seconds;   /* light samples at the light meshes' root corners */
    double values_seconds;  /* direct and specular root values from the light meshes */
    double source_seconds;  /* further bounces' transport and the indirect source */
    double gather_seconds;  /* the indirect mesh's root values (gathers, borrowed ones) */
    uint64_t light_samples; /* light samples taken by the first cache_init_seen */
    uint64_t gathers;       /* indirect samples taken by it */
} cache_startup_stats;

/* The first image's borrowed indirect values, tested after it (docs/cache.md,
 * "Borrowed values tested"). */
typedef struct cache_borrow_stats {
    uint64_t borrowed;          /* root corners that borrowed their first indirect value */
    uint64_t tests;             /* spans tested (a gather at the middle of each) */
    uint64_t splits;            /* ... split there (the difference seen, or too many pixels) */
    uint64_t kept;              /* corners that kept a borrowed value after their span's test (again at
                                   each test a lower JND asks for) */
} cache_borrow_stats;

typedef struct cache_stats {
    uint32_t light_count;
    cache_mesh_stats direct, indirect, specular; /* specular: all zero when there is no specular mesh */
    cache_mesh_stats *lights;   /* light_count entries, owned by the cache */
    uint64_t undone;            /* splits undone */
    uint64_t falsified;         /* light leaves that had answered as uniform and proved not to be */
    uint64_t revised;           /* radiance values recomputed inside those (cache_refine) */
    uint64_t regathered;        /* indirect values gathered again: the source had moved them (counted in
                                   indirect.samples too) */
    uint64_t drift_probed;      /* values a rebuild's occlusion-blind bound flagged that were probed first
                                   (cosine rays through both sources: the change they saw) */
    uint64_t drift_cleared;     /* of them, unmoved past the JND: not gathered again */
    uint64_t drift_probe_rays;  /* the probes' rays */
    uint64_t toward_gathers;    /* indirect values gathered with half their rays toward the source (their
                                   pilot saw the light come through a gap: samp_point.toward_source,
                                   guided by the pilot: samp_guide; counted in indirect.samples too) */
    uint64_t glossy_gathers;    /* specular values given the source's glossy reflection (64 or more
                                   lobe rays each; cache_desc.glossy) */
    uint64_t glossy_refreshed;  /* of them, taken again because the source was rebuilt or the eye moved */
    uint64_t glossy_rays;       /* their rays: 64 each, ×4 up to three times where the noise
                                   was seen */
    cache_bounce_stats bounces;
    uint32_t active_triangles;  /* scene triangles taken part (cache_init_seen); all of them after cache_init */
    uint64_t reach_rays;        /* rays traced to find what the seen triangles' gathers reach */
    cache_startup_stats startup;
    cache_borrow_stats borrow;
    size_t bytes;               /* everything: meshes, vertex table, bookkeeping */
} cache_stats;

void cache_get_stats(cache *c, cache_stats *out);

/* The cache's own estimate of the error a viewer sees, as CIELAB ΔE (CIE76)
 * after tone mapping, averaged over the pixels each mesh's leaves cover:
 *   interpolation  per leaf, its last edge test: the mean ΔE between its fresh
 *                  midpoint values and their edges' interpolation (what a linear
 *                  leaf misses over its area, for a quadratic exactly; indirect:
 *                  less what the noise explains, in quadrature); a leaf not tested yet, a
 *                  quarter of its parent's (the error of linear interpolation falls
 *                  with the square of the size), a root its corners' contrast
 *                  (a quarter of it below one pixel);
 *   noise          indirect only: the mean absolute error the gathers' standard
 *                  errors leave after interpolation (0.56 σ: a normal's mean
 *                  |x| of the interpolated σ, σ/√2 over a triangle), σ with the
 *                  gathers' strata counted (samp_source_hits.strat_var).
 * It does NOT see what no test looked at: a shadow between the midpoints of a
 * leaf that was never split, light the sampler's rays miss altogether, the Embree
 * direct estimate's penumbra noise (SAMP_EMBREE_PENUMBRA_RMS), or transport the
 * cache does not model (bounces beyond those shown). bench/indirect.sh compares
 * it with the measured error against the reference. */
/* (cache_mesh_estimate and cache_estimate are declared above cache_refine_result.) */

/* pixels: per scene triangle, pixels it covers (as cache_refine_desc.pixels);
 * NULL: every triangle 1e6 (the estimate of the whole surface). */
lm_result cache_estimate_error(const cache *c, const uint32_t *pixels, cache_estimate *out, lm_error *err);

/* "Converged" is a claim about error: the estimate is above the JND on at most
 * this fraction of the pixels (the edge test lets a leaf's interpolation come up
 * to the JND, and the gathers' noise adds to it; measured on the Cornell boxes,
 * 1-2% of the pixels of a settled cache differ from the reference by more than
 * the JND, docs/cache.md). */
#define CACHE_CONVERGED_ABOVE_JND 0.02
int cache_estimate_converged(const cache_estimate *e);

/* The area lights' outlines, for the specular integral (eq. 5: the cache's
 * values; the renderer's highlights per pixel): loop k is xyz[3·loop[k] ..
 * 3·loop[k+1]) (counter-clockwise seen from the light's front; loop_sign[k] −1
 * for a hole, stored reversed), light l (area lights first, as cache_stats.lights)
 * owns loops light_loop[l] .. light_loop[l+1]; a point light owns none. Built from
 * the scene alone (the lights' triangles welded by position); 0 when memory runs
 * out (o untouched). */
typedef struct cache_outlines {
    double *xyz;
    uint32_t *loop, *light_loop;
    int8_t *loop_sign;
    size_t bytes;
} cache_outlines;
int cache_build_outlines(cache_outlines *o, const scene *s, uint32_t light_count);
void cache_outlines_free(cache_outlines *o);

/* What a renderer needs to evaluate the lights' part of a specular vertex's value
 * per pixel (eq. 5 at the pixel's own point and view; docs/renderer.md, "Highlights
 * per pixel"): the value is direct + the glossy part, and at a point inside a leaf
 * whose corners see every light wholly the lights' part is Σ_ℓ L_ℓ·S_ℓ there, the
 * lobe integral exact (elsewhere the values are interpolated: a shadow's edge
 * is the mesh's to find). */
typedef struct cache_lobe {
    float normal[3];  /* unit shading normal */
    float exponent;   /* Phong n of the vertex's material (its first triangle's) */
    float direct[3];  /* the lights' part of the value, Σ_ℓ V_ℓ·L_ℓ·S_ℓ (RGB per unit ks) */
    float visible;    /* the smallest visible fraction V_ℓ of the lights the vertex can see at all
                         (above its horizon, facing it): 1 where each is wholly visible, the only
                         case a renderer evaluates per pixel (CACHE_HIGHLIGHT_MIN_VISIBLE); a
                         light hidden from a vertex whose lobe misses it would otherwise light
                         a pixel whose lobe does not */
} cache_lobe;
/* Where a renderer draws the lights' part per pixel (rend_value.frag) and the
 * cache's edge tests judge the same picture (cache_specular_drawn): materials
 * whose Phong exponent is at least CACHE_HIGHLIGHT_MIN_EXPONENT (a broader lobe
 * varies little across a leaf); a light further from the lobe's axis than its
 * angular radius plus CACHE_HIGHLIGHT_SKIP_CORE lobe widths (1/√n) sends nothing
 * there (cos^n below e^-8 of its peak). */
#define CACHE_HIGHLIGHT_MIN_EXPONENT 8.0
#define CACHE_HIGHLIGHT_SKIP_CORE 4.0
/* ... and only where the lights are wholly visible (cache_lobe.visible at least
 * this at every corner around): a partly hidden light's visible fraction is the
 * one its corners' lobes see, and a pixel's lobe turned to the hidden part of
 * it lit up speckles (the Veach door's metal teapot, seen through the gap). */
#define CACHE_HIGHLIGHT_MIN_VISIBLE 0.999
/* The bounding sphere the renderer and the cache test a lobe's core against
 * (CACHE_HIGHLIGHT_SKIP_CORE): the light's box's centre and half diagonal, a
 * little wider so that round-off never skips a light that sends something. */
void cache_highlight_sphere(const scene_area_light *L, double centre[3], double *radius);
/* The lobe data of specular vertex vid (a vertex of cache_specular_mesh). */
void cache_get_lobe(const cache *c, uint32_t vid, cache_lobe *out);
/* Light `light`'s radiance (area) or intensity (point) as the cache uses it now
 * (the scene's, or the last cache_set_light). */
void cache_get_light_radiance(const cache *c, uint32_t light, float out[3]);

/* The meshes themselves, read-only, for tests and the renderer. */
const mesh_qmesh *cache_direct_mesh(const cache *c);
const mesh_qmesh *cache_indirect_mesh(const cache *c);
const mesh_qmesh *cache_specular_mesh(const cache *c); /* NULL: no glossy material */
const mesh_qmesh *cache_light_mesh(const cache *c, uint32_t light);
const mesh_vtable *cache_vtable(const cache *c);
/* With cache_desc.corner_ids, once the cache has its first roots (cache_init,
 * cache_init_seen): 3 per scene triangle, each corner's vertex-table id
 * (mesh_vtable_corner_id; MESH_VTABLE_NONE where none), handed over to the
 * caller, who frees it (NULL: not made, or taken already). The ids stay those
 * of the corners while the cache lives: it holds a reference on each. */
uint32_t *cache_take_corner_ids(cache *c);
/* The same ids made now, into a new array the caller frees (NULL: out of
 * memory); reads the vertex table only. */
uint32_t *cache_make_corner_ids(const cache *c);

#ifdef __cplusplus
}
#endif
#endif
