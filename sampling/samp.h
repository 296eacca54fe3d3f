/* samp.h — irradiance samplers: one interface, several back ends (paper §5;
 * docs/sampling.md).
 *
 * Two quantities, for a batch of receiver points x with unit normals n:
 *   direct    G_ℓ(x) = ∫_ℓ V(x,y) cosθ_x cosθ_y / r² dA_y   for one light ℓ
 *             (dimensionless; irradiance E_ℓ = L_ℓ·G_ℓ). For a point light of
 *             intensity I the same call gives V·cosθ_x/r² (E = I·G), scene units⁻².
 *   indirect  E_i(x) = ∫_Ω L(x ← ω) cosθ dω, RGB, where L is read from a supplied
 *             coarse radiance mesh (radiance leaving the surface, W·m⁻²·sr⁻¹)
 *             over the scene's triangles (paper eq. 7: kd(x')·L_dd(x')).
 *
 * Back ends:
 *   SAMP_BACKEND_EMBREE  CPU rays. Direct: stratified points on the light,
 *                        shadow rays, and the analytic unoccluded value as a
 *                        control variate: G = G_unocc · (visible weight / total
 *                        weight), exact wherever the light is fully visible.
 *                        Indirect: stratified cosine-weighted rays; the hit's
 *                        scene triangle and barycentrics look the radiance up.
 *   SAMP_BACKEND_GL      Rasterization on an OpenGL 4.5 core context (EGL or
 *                        OSMesa, headless): direct by a small frustum around the
 *                        light per point, indirect by a hemicube; batched draws,
 *                        reduced on the GPU (samp_gl.c).
 *   SAMP_BACKEND_AUTO    the cheaper at equal error on this machine, by a short
 *                        calibration at creation (samp_auto.c), chosen for
 *                        direct and for indirect samples separately;
 *                        samp_get_stats says which and why.
 * Point lights are always sampled with one Embree shadow ray (exact; a frustum
 * adds nothing for a point).
 *
 * Usage:
 *     samp_sampler *sp; lm_error err;
 *     if (samp_create(&(samp_desc){.scene = s}, &sp, &err) != LM_OK) ...
 *     samp_point pts[2] = {{{0, 0, 0}, {0, 1, 0}}, {{1, 0, 0}, {0, 1, 0}}};
 *     float G[2];
 *     samp_direct(sp, 0, pts, 2, G, &err);           // light 0 of scene_light order
 *     samp_destroy(sp);
 *
 * Light order: the scene's area lights first (scene.area_lights), then its point
 * lights; scene_light_count(s) in all.
 *
 * Threads: a sampler belongs to the thread that created it (a GL back end's
 * context is current there); calls on it are not thread-safe. The Embree back
 * end spreads each batch over its own worker threads (desc.threads).
 * Does NOT do: specular (Phong-lobe) integrals (the cache integrates the lobe over
 * each light with samp_polygon_phong, analytic.h, and takes V from the light
 * meshes), visibility of emission itself, textures.
 */
#ifndef LUMESH_SAMP_H
#define LUMESH_SAMP_H

#include <math.h>
#include <stdint.h>

#include "src/base/rng.h"
#include "src/base/util.h"
#include "src/gpu/gl_platform.h"
#include "src/scene/scene.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum samp_backend {
    SAMP_BACKEND_AUTO = 0, /* default: measured at creation */
    SAMP_BACKEND_EMBREE,
    SAMP_BACKEND_GL,
    SAMP_BACKEND_COUNT
} samp_backend;

typedef enum samp_indirect_mode {
    SAMP_INDIRECT_HEMICUBE = 0, /* default: five faces, the whole hemisphere */
    SAMP_INDIRECT_PLANE160,     /* GL: the paper's single 160° plane (misses the grazing ring) */
    SAMP_INDIRECT_MODE_COUNT
} samp_indirect_mode;

typedef struct samp_desc {
    const scene *scene;           /* must outlive the sampler */
    samp_backend backend;
    glctx_platform gl_platform;
    int direct_res;               /* GL: frustum pixels per side; 0 = 64 */
    int direct_rays;              /* Embree: light points per receiver (stratified); 0 = 64 */
    int direct_control_variate;   /* 0 = on (default); SAMP_OFF = raw estimate */
    int indirect_res;             /* GL: hemicube face pixels per side; 0 = 64 */
    int indirect_rays;            /* Embree: hemisphere rays per receiver (stratified); 0 = 1024 */
    samp_indirect_mode indirect_mode;
    int threads;                  /* Embree worker threads; 0 = every core */
    float direct_target_error;    /* AUTO: mean relative error the client tolerates in penumbra;
                                     0 = as accurate as GL at direct_res (equal-error comparison) */
    float indirect_target_error;  /* AUTO: the same for indirect samples; 0 = as accurate as GL */
    uint32_t seed;                /* random numbers: the same seed and calls give the same values */
    const struct rt_scene *rt;    /* an Embree scene of `scene` to use (rt_scene.h), made by the caller
                                     and outliving the sampler: samplers made one after the other
                                     (a quick start, a calibration) need not build it again; NULL:
                                     the sampler builds its own */
} samp_desc;

enum { SAMP_OFF = -1 };

/* Stated accuracy of the Embree direct estimate with the control variate: exact
 * (to float rounding) where the light is wholly visible or wholly hidden; in
 * penumbra a relative standard deviation of about 1.2·rays^-0.75 of G (measured
 * with a straight edge across the middle of a quad light, tests/samp_embree_test.c). */
#define SAMP_EMBREE_PENUMBRA_RMS(rays) (1.2 * pow((double)(rays), -0.75))

/* A receiver: position (scene units) and unit normal of the side that receives.
 * tri_plus_one names the scene triangle the point lies on (its id + 1; 0 = not
 * given). With it, every back end moves the ray origin a few epsilons into that
 * triangle before lifting it off the surface, so a point on an edge or corner of
 * the mesh (a floor vertex where a wall stands) cannot see through the wall's
 * plane at distance 0. Without it only the lift along n is applied. */
typedef struct samp_point {
    float p[3];
    float n[3];
    uint32_t tri_plus_one;
    /* Indirect gathers of the Embree back end: 0 casts every ray cosine-weighted;
     * non-zero sends three quarters of them (SAMP_TOWARD_COSINE_SHARE) toward points
     * of the radiance mesh picked by power, combined by multiple importance
     * sampling (samp_embree.c), and with a guide half of those to the guide's
     * strata (samp_indirect_guided). For a
     * receiver whose light comes through a gap (the caller knows from a pilot):
     * the cosine rays find a gap by chance, the picks go to what shines behind it.
     * Where the light comes from most of the hemisphere the stratified cosine rays
     * alone are better (3× less noise on a ball in a lit room). Other back ends
     * and the direct samplers ignore it. */
    uint8_t toward_source;
} samp_point;

/* A coarse radiance mesh over the scene's triangles: triangles lying inside scene
 * triangles, each corner given by its barycentric coordinates (w1, w2) in the
 * scene triangle (position = (1−w1−w2)·v0 + w1·v1 + w2·v2) and the RGB radiance
 * leaving the surface there. Triangles are grouped by scene triangle:
 * first[t] .. first[t+1] are those inside scene triangle t (first has
 * scene.tri_count + 1 entries; a scene triangle may have none: it sends no light).
 * Inside one scene triangle the sub-triangles tile it without overlap (the Embree
 * back end finds the one containing a hit). Radiance is what leaves the front
 * (the side of the scene triangle's normal); the back sends nothing — inside a
 * closed object, or behind a wall, a surface's back is not lit by its front. */
typedef struct samp_radiance_index samp_radiance_index;
typedef struct samp_radiance_mesh {
    uint32_t tri_count;
    const uint32_t *first;    /* scene.tri_count + 1 offsets */
    const float *bary;        /* 6 floats per triangle: (w1, w2) of corners 0, 1, 2 */
    const float *radiance;    /* 9 floats per triangle: RGB of corners 0, 1, 2, W·m⁻²·sr⁻¹ */
    /* Optional: samp_radiance_mesh_prepare's index for exactly these arrays and
     * their contents. NULL: every call checks the mesh (samp_radiance_mesh_valid)
     * and builds its own index, both O(mesh) per call (on the 116k box, 5% of a
     * run went there: a gather batch is small, the source 124,000 triangles). */
    const samp_radiance_index *index;
} samp_radiance_mesh;

typedef struct samp_sampler samp_sampler;

lm_result samp_create(const samp_desc *desc, samp_sampler **out, lm_error *err);
void samp_destroy(samp_sampler *sp); /* NULL is a no-op */

/* G of light `light` at each of the n points, into G[0..n). Points behind a
 * one-sided light, or with the light below their horizon, get exactly 0. */
lm_result samp_direct(samp_sampler *sp, uint32_t light, const samp_point *pts, uint32_t n, float *G,
                      lm_error *err);

/* RGB indirect irradiance from `mesh` at each of the n points, into E[3·i ..]. */
lm_result samp_indirect(samp_sampler *sp, const samp_radiance_mesh *mesh, const samp_point *pts, uint32_t n,
                        float *E, lm_error *err);

/* samp_indirect with each value's standard error (RGB, std_err[3·i ..]) and more
 * rays: the Embree back end traces scale × indirect_rays rays a point (scale 1,
 * 4, 16, ...: the strata refined) from random stream `pass` (0 is
 * samp_indirect's own; passes are independent, so a caller may average them,
 * weighted by their rays). The error is the rays' sample standard deviation over
 * √rays (it ignores the strata, so it errs high). A back end without noise (GL's
 * hemicube is deterministic; its discretisation is not estimated) gives its
 * plain value and an error of 0, whatever scale. */
lm_result samp_indirect_noise(samp_sampler *sp, const samp_radiance_mesh *mesh, const samp_point *pts, uint32_t n,
                              uint32_t pass, uint32_t scale, float *E, float *std_err, lm_error *err);
/* The shares of a toward_source point's rays: SAMP_TOWARD_COSINE_SHARE of them
 * cosine-weighted in strata (the nearest square count), and of the rest
 * SAMP_TOWARD_GUIDED_SHARE to the guide's strata when there is a guide, the
 * others by power. A caller that predicts the noise mirrors them (the cache's
 * pilot_guided_var). A quarter, not a half, cosine-weighted: where a point goes
 * toward the source its pilot saw light from a fifth of the hemisphere or less,
 * which most cosine rays miss; the slot test's 256-ray variance went from 0.22
 * to 0.13 of all-cosine rays, the Veach door's relMSE at 10 s from 0.0034-0.0037
 * to 0.0019-0.0029 (docs/cache.md, "A quarter of the rays cosine-weighted"). */
#define SAMP_TOWARD_COSINE_SHARE 0.25
#define SAMP_TOWARD_GUIDED_SHARE 0.5

/* How a toward_source point of k × k rays splits them: kc × kc cosine-weighted
 * in strata, ng to the guide's strata (0 without a guide) and npw by power (0
 * without picks): the shares above, rounded as samp_indirect_guided rounds them
 * (at 4 rays 1, 2 and 1). For a caller that predicts the noise, k is the square
 * root of samp_indirect_rays (a square). */
void samp_toward_split(int k, int guided, int by_power, int *kc, int *ng, int *npw);

/* samp_indirect_noise with a guide for the points marked toward_source: what a
 * pilot of the same point saw in each stratum of its cosine-weighted hemisphere
 * (samp_source_hits.stratum). Of the three quarters of their rays that do not go
 * cosine-weighted, half go to strata of the pilot's grid picked in proportion to
 * the brightest the pilot saw in the stratum or its eight neighbours (uniform in
 * the stratum's square, mapped as the cosine rays are), and half toward points of
 * the source picked by power, as without a guide; all combined by the balance
 * heuristic, so a direction the guide leaves out is still found by the others.
 * Through a gap the guided rays go where the pilot saw the gap and none is lost to
 * a wall, as most picks on the source behind it are; a thin gap fills a stratum
 * only in part, where the picks do better (docs/cache.md, "Guided gathers").
 * Point i's row is index[i] (index NULL: row i); a row that saw no light falls
 * back to the picks by power alone. Back ends without noise ignore the guide, as
 * they ignore toward_source. */
typedef struct samp_guide {
    uint32_t rays;          /* the pilot's rays a point: k², k = 2..64 */
    const float *stratum;   /* rows × rays: samp_source_hits.stratum */
    const uint32_t *index;  /* per point: its row; or NULL */
} samp_guide;

/* The guide's mass of stratum (a, b) of a pilot's k × k strata (one row of
 * samp_source_hits.stratum): the brightest value in it or its eight neighbours,
 * non-finite as 0. What samp_indirect_guided picks strata by, for a caller that
 * predicts its noise. */
float samp_guide_mass(const float *stratum, int k, int a, int b);

lm_result samp_indirect_guided(samp_sampler *sp, const samp_radiance_mesh *mesh, const samp_point *pts, uint32_t n,
                               uint32_t pass, uint32_t scale, const samp_guide *guide, float *E, float *std_err,
                               lm_error *err);
/* Rays a point of one pass at scale 1 (0: the indirect back end casts none). */
uint32_t samp_indirect_rays(const samp_sampler *sp);
/* Light points a receiver of samp_direct (samp_desc.direct_rays, defaults filled
 * in; the GL back ends use none, and this is their ray equivalent). */
uint32_t samp_direct_rays(const samp_sampler *sp);

/* Where the indirect light of each point comes from (the cache's importance,
 * docs/cache.md): `rays` stratified cosine-weighted rays per point, traced with
 * Embree whichever back end serves samp_indirect, each hit on the front of a
 * triangle of `mesh` counted. Point i's entries are (tri[i·rays + j],
 * weight[i·rays + j]) for j < count[i], source triangles in increasing order:
 * the fraction of the point's rays that met that source triangle, an estimate of
 * ∂E_i(x)/∂L̄ / π for a change L̄ of the radiance over that triangle (E_i =
 * π·Σ_t w_t·L̄_t). The weights sum to at most 1 (the rest left the scene or met
 * the back of a surface). Deterministic per point, like samp_indirect.
 * strat_var (optional) says how noisy a stratified gather of E there is: N·Var of
 * the stratified mean of π·L over these rays, estimated from neighbouring strata
 * (each pair (a, a+1) of a row of strata adds (π·L_a − π·L_(a+1))²: collapsed
 * strata, which errs high). A stratified gather of N ≥ rays rays then has a
 * standard error of at most √(strat_var / N); for independent rays strat_var is
 * the plain variance of π·L, and where the radiance is smooth over a stratum far
 * less. */
typedef struct samp_source_hits {
    uint32_t rays;      /* per point, 1..4096 */
    uint32_t *count;    /* n */
    uint32_t *tri;      /* n × rays */
    float *weight;      /* n × rays */
    float *strat_var;   /* n × RGB, or NULL */
    /* n × rays, or NULL: per stratum (b·k + a for stratum (a, b) of k × k, k² =
     * rays, a the first of samp_frame_cosine's numbers), π × the radiance its ray
     * met averaged over the channels, 0 for a miss or a back: samp_guide's input. */
    float *stratum;
} samp_source_hits;

lm_result samp_indirect_sources(samp_sampler *sp, const samp_radiance_mesh *mesh, const samp_point *pts, uint32_t n,
                                const samp_source_hits *out, lm_error *err);

/* Where a receiver's cosine-weighted hemisphere lands (the cache's further
 * bounces, docs/cache.md "Bounces"): rays = k² stratified cosine-weighted rays
 * per point (k×k strata), traced with Embree whichever back end serves
 * samp_indirect. Each hit on the FRONT of a scene triangle that `keep` accepts
 * (NULL: every triangle) is recorded as the triangle and its barycentric (w1, w2);
 * a miss, a back or a triangle not kept records nothing. Point i's hits are
 * tri[i·rays + j] and bary[2·(i·rays + j) ..] for j < count[i]; each stands for
 * 1/rays of the point's cosine-weighted hemisphere, so for any radiance L leaving
 * the kept fronts E(x) ≈ π/rays·Σ_j L(hit j). Deterministic per point (its own
 * random stream, not samp_indirect's). */
typedef struct samp_surface_hits {
    uint32_t rays;      /* per point: a square, 1..4096 */
    uint32_t *count;    /* n */
    uint32_t *tri;      /* n × rays */
    float *bary;        /* n × rays × 2 */
    int (*keep)(const scene *s, uint32_t tri, void *user); /* or NULL */
    void *keep_user;
} samp_surface_hits;

lm_result samp_surface_hits_trace(samp_sampler *sp, const samp_point *pts, uint32_t n, const samp_surface_hits *out,
                                  lm_error *err);

/* The fraction of area light `light` visible from each point, weighted by the
 * modified Phong lobe of exponent[i] about the mirror of wo[i] (3 floats a point,
 * towards the viewer, any length) times the cosine at the point: what the
 * specular integral needs where the light is partly hidden (docs/cache.md,
 * "Leaves smaller than a pixel"; the cosine-weighted fraction of samp_direct
 * misses an occluder that hides the part of the light a sharp lobe sees).
 * rays (a square, 1..4096) directions a point, stratified in proportion to the
 * lobe, traced with Embree whichever back end serves samp_direct. V[i] = −1
 * where no ray of the lobe reaches the light (no information). Deterministic
 * per point. */
lm_result samp_lobe_visibility(samp_sampler *sp, uint32_t light, const samp_point *pts, const float *wo,
                               const float *exponent, uint32_t n, uint32_t rays, float *V, lm_error *err);

/* The radiance of `mesh` reflected by a modified Phong lobe of exponent[i] about
 * the mirror of wo[i] (3 floats a point, towards the viewer, any length), per
 * unit ks: L_is(x, ωo) = ∫ (n+2)/(2π) cosⁿα · L(y(ω)) · cosθ dω, the glossy
 * indirect term (docs/cache.md, "Glossy reflection of the room"). rays (a square,
 * 1..4096) directions a point drawn in proportion to cosⁿα, stratified, traced
 * with Embree whichever back end serves the sampler; a direction below the
 * point's horizon brings nothing (the lobe clipped there), as does a miss or the
 * back of a surface (samp_radiance_mesh: the back sends nothing). L[3·i ..] gets
 * the RGB mean, std_err[3·i ..] (NULL: not wanted) its standard error (the rays'
 * sample deviation over √rays: the strata ignored, so it errs high).
 * Deterministic per point and `pass` (a random stream). Not counted as indirect
 * samples (samp_stats.glossy_samples). */
lm_result samp_lobe_gather(samp_sampler *sp, const samp_radiance_mesh *mesh, const samp_point *pts, const float *wo,
                           const float *exponent, uint32_t n, uint32_t rays, uint32_t pass, float *L, float *std_err,
                           lm_error *err);

/* Which back ends serve a sampler. Decide by the enums (backend, gl_platform);
 * the names are for display and the statistics JSON only. A zeroed samp_stats
 * (backend AUTO, names NULL) stands for "no sampler". */
typedef struct samp_stats {
    samp_backend backend;         /* the back end of direct samples (never AUTO) */
    glctx_platform gl_platform;   /* its GL platform (GLCTX_EGL, GLCTX_OSMESA); GLCTX_DEFAULT unless GL */
    const char *backend_name;     /* display: "embree", "gl-egl", "gl-osmesa" */
    samp_backend indirect_backend;/* the back end of indirect samples */
    glctx_platform indirect_gl_platform;
    const char *indirect_backend_name;
    char choice[512];             /* why these back ends (AUTO: the calibration's numbers) */
    uint64_t direct_samples, indirect_samples;  /* points served */
    uint64_t glossy_samples;                    /* samp_lobe_gather's points (in indirect_seconds' time) */
    double direct_seconds, indirect_seconds;    /* wall time inside the calls (indirect: samp_indirect_sources too) */
} samp_stats;

void samp_get_stats(const samp_sampler *sp, samp_stats *out);

const char *samp_backend_name(samp_backend b);
/* The spellings of the command line: "auto", "embree", "gl" (the GL platforms'
 * are in src/gpu/gl_platform.h).
 * Return 0 (and leave *out alone) for anything else. */
int samp_backend_from_name(const char *name, samp_backend *out);

/* ---- for the cache, calibration, tests and benches ----------------------- */

/* Cumulative area fractions of the scene's triangles (malloc'd; NULL: no memory). */
double *samp_area_cdf(const scene *s);
/* A receiver drawn by area on the scene's non-emitting triangles: a uniform point,
 * the triangle's front normal, tri_plus_one set. For calibration, tests, benches. */
samp_point samp_random_receiver(const scene *s, const double *area_cdf, lm_rng *g);

/* A coarse radiance mesh with no visibility, corner radiance
 * kd·Σ_ℓ L_ℓ·G_ℓ,unoccluded/π: every scene triangle cut into the same number of
 * dyadic sub-triangles, as many as keep the total at or under target_triangles
 * (one each at least). Shaped like the cache's indirect source, for calibration
 * and benchmarks. */
typedef struct samp_coarse_mesh {
    uint32_t *first;
    float *bary, *radiance;
    samp_radiance_mesh mesh;
} samp_coarse_mesh;

lm_result samp_coarse_mesh_build(const scene *s, uint32_t target_triangles, samp_coarse_mesh *out, lm_error *err);
void samp_coarse_mesh_free(samp_coarse_mesh *m);

/* The descriptor with every zero field replaced by its default. */
samp_desc samp_desc_defaults(const samp_desc *desc);

/* Unoccluded G of area light `light` at (p, n): the sum over its triangles of
 * samp_polygon_G (double precision inside). */
double samp_area_light_unoccluded(const scene *s, uint32_t light, const float p[3], const float n[3]);

/* Where rays and frusta for receiver x start: x moved `eps` towards the centroid
 * of its triangle (when x->tri_plus_one names one), then `eps` along x->n. Every
 * back end uses this, so they see the same thing from the same point. */
void samp_point_origin(const scene *s, const samp_point *x, float eps, float out[3]);

/* A receiver that cannot see the middle of its own triangle — a surface crosses
 * the triangle between them, as a wall standing on a floor that runs on under it
 * into the next room — is moved along the surface towards the centroid, just past
 * every surface that blocks the way (4 eps past each, at most 8). Only a blocker
 * that also blocks the way lifted by a tenth of its length counts (a picture
 * frame on a wall does not). A value gathered at the original point would be the
 * next room's, and interpolation would carry it into this one. Returns 1 if x
 * moved. Needs x->tri_plus_one; unchanged without it. (Two Embree rays and one
 * per blocker.) The caller decides where this applies: a box standing on a
 * floor blocks the way too (the cache pulls only points on their triangle's
 * boundary, docs/cache.md). */
int samp_point_pull_inside(const samp_sampler *sp, samp_point *x);

/* Does a surface stand between two receivers on the same surface (the segment
 * between their ray origins, samp_point_origin, blocked)? Then what one sees says
 * nothing about the other: the cache does not let a light leaf whose corners
 * agree answer for a point so parted from them (a wall standing on a floor that
 * runs on into the lit room). (One Embree ray.) */
int samp_points_parted(const samp_sampler *sp, const samp_point *a, const samp_point *b);

/* The offset every back end of sp lifts receiver x by (samp_point_origin): its
 * triangle's (rt_scene_tri_epsilon), or the scene's largest without one. */
float samp_point_epsilon(const samp_sampler *sp, const samp_point *x);

/* True when the radiance mesh is well formed for scene s: offsets non-decreasing,
 * first[tri_count] == mesh->tri_count, barycentrics and radiance finite. */
int samp_radiance_mesh_valid(const scene *s, const samp_radiance_mesh *mesh, lm_error *err);

/* Point location in a radiance mesh. A scene triangle with more than 16
 * sub-triangles gets a grid over its barycentric square (w1, w2) ∈ [0,1]²: res ×
 * res squares (res the power of two at or above √count), each halved along its
 * anti-diagonal, each half listing the sub-triangles that overlap it (the halves
 * are the midpoint lattice's triangles, which the cache's sources are cut from);
 * others are searched linearly. Built in time linear in the mesh; valid while the
 * mesh is unchanged. Pure data: any thread may read a built index. */
struct samp_radiance_index {
    uint32_t *res;        /* per scene triangle: grid cells per side, 0 = no grid */
    uint32_t *base;       /* per scene triangle: its first cell */
    uint32_t *cell_first; /* per cell, + 1: offsets into items */
    uint32_t *items;      /* radiance-mesh triangle ids */
    /* Picking a point of the mesh by power (samp_radiance_pick): per radiance-mesh
     * triangle, the cumulative share of the mesh's power (area × mean radiance over
     * the channels; last = 1), and its share over its area (scene units⁻²: the area
     * density of a pick there). NULL: the mesh sends nothing, or no memory. */
    double *pick_cdf;
    float *pick_density;
    int checked;          /* made by samp_radiance_mesh_prepare: the mesh passed samp_radiance_mesh_valid */
};

/* 0 and an empty index (linear search everywhere) when memory runs out. */
int samp_radiance_index_build(const scene *s, const samp_radiance_mesh *m, samp_radiance_index *ix);
/* Checks m (samp_radiance_mesh_valid) and builds its index into *ix, once for
 * many calls: point m->index (or a copy's) at *ix, and every sampler call trusts
 * both while the arrays stay as they are (the caller's promise: build again after
 * a change). An index that did not fit in memory still counts as checked (linear
 * search). On failure *ix is empty and unchecked. */
lm_result samp_radiance_mesh_prepare(const scene *s, const samp_radiance_mesh *m, samp_radiance_index *ix,
                                     lm_error *err);
void samp_radiance_index_free(samp_radiance_index *ix);
/* RGB radiance of mesh m at barycentrics (w1, w2) of scene triangle t: the
 * sub-triangle that contains the point (or, for a point on none by rounding, the
 * one it is least outside of), linearly interpolated. Returns that sub-triangle,
 * UINT32_MAX (and black) when t has none. */
uint32_t samp_radiance_at(const samp_radiance_mesh *m, const samp_radiance_index *ix, uint32_t t, float w1, float w2,
                          float out[3]);
/* A point of mesh m picked by power from two uniform numbers (u picks the
 * triangle, v and w the point in it, uniform by area): its scene triangle *t and
 * barycentrics (*w1, *w2) there; returns the radiance-mesh triangle, or
 * UINT32_MAX when the index has no power table. The pick's area density at a
 * point of radiance-mesh triangle i is ix->pick_density[i]. */
uint32_t samp_radiance_pick(const scene *s, const samp_radiance_mesh *m, const samp_radiance_index *ix, double u,
                            float v, float w, uint32_t *t, float *w1, float *w2);

#ifdef __cplusplus
}
#endif
#endif
