/* ref_vpl.h — instant radiosity (Keller 1997): virtual point lights traced from
 * the lights, gathered at a surface point with Embree shadow rays. The reference
 * renderer's second estimator (ref_desc.estimator = REF_ESTIMATOR_VPL), private
 * to sampling/.
 *
 * Usage (reference.c):
 *     ref_vpl_set set = {0};
 *     ref_vpl_generate(&set, &(ref_vpl_params){...}, pass, &rays, &err);   // once a pass
 *     ref_vpl_gather(&set, rt, &x, wo, &g, indirect, &rays);               // per pixel sample
 *     ref_vpl_free(&set);
 *
 * What it computes. A light path leaves a light chosen by power (area lights: a
 * point by area, a cosine direction; point lights: a uniform direction) carrying
 * the flux Φ/p of its light; at each surface it reaches it leaves a VPL holding
 * the flux that arrived there. The radiance that VPL i sends to a point x is
 *     f_x(ω, ω_o)·f_y(ω_in, −ω)·Φ_i·cosθ_x·cosθ_y / max(d², d_min²)·V(x, y),
 * and the estimate at x is the mean over the pass's light paths of their VPLs'
 * sums. With d_min = 0 this is unbiased for the transport it follows (the VPLs
 * are the light-tracing half of a bidirectional path, joined to the eye's first
 * hit by one shadow ray):
 *   model transport (K bounces): VPLs at light-path depths 1..K, the path goes on
 *     by diffuse reflection only (β·kd), f_y = kd/π (the source of the cache's
 *     gathers, kd·(L_dd + L_id), reference.h), f_x = kd/π plus ks times the Phong
 *     lobe when glossy materials reflect the room (L_is; a sharp lobe instead by
 *     one ray drawn from it, REF_VPL_LOBE_SAMPLED_N);
 *   full transport: VPLs at every depth, the path goes on by sampling the whole
 *     BRDF with the path tracer's bounded roulette, f_y and f_x the whole modified
 *     Phong BRDF.
 * The direct light (emission, L_dd, L_ds) is not the VPLs' job: the caller
 * computes it as the path tracer does, so VPLs carry indirect light only.
 *
 * Bias, documented (docs/peers.md): d_min clamps the geometry term near each VPL
 * (the classic bright splotches where 1/d² is large); energy is lost within d_min
 * of a VPL, mostly in corners. A glossy receiver or VPL makes spiky estimates
 * (a lobe of exponent n concentrates a VPL's light), clamped by the same d_min
 * only. Camera paths go on through sharp lobes for one surface only.
 *
 * Each pixel sample joins M of the pass's V VPLs (M = per_sample): one from each
 * of M equal strata of the set, so every VPL is expected M/V times and weighs V/M
 * (unbiased), and neighbouring pixels use different VPLs (their errors do not
 * line up into one pattern).
 *
 * Threads: ref_vpl_generate on one thread (between passes); ref_vpl_gather from
 * any number of threads at once (the set is read-only then).
 * Visibility: an Embree shadow ray a join, or a lookup in the VPL's imperfect
 * shadow map when set->ism is set (ref_ism.h; then *rays counts no rays).
 * Does NOT do: bias compensation, camera paths through more than one glossy
 * surface (BDIR's resampling by importance is ref_vpl_resample, below).
 * Units: positions in scene units; flux in W (area lights: radiance·area·π).
 */
#ifndef LUMESH_REF_VPL_H
#define LUMESH_REF_VPL_H

#include <stdint.h>

#include "sampling/ref_shading.h"
#include "sampling/rt_scene.h"

/* One virtual point light: a light path's vertex on a surface. */
typedef struct ref_vpl {
    lm_vec3 p;          /* on the surface */
    lm_vec3 ng, ns;     /* geometric and shading normal, on the side the light arrived from */
    lm_vec3 w_in;       /* unit direction back along the light path (full transport's glossy VPLs) */
    float flux[3];      /* power that arrived, W (the path's estimate, before the 1/N of the pass) */
    uint32_t tri;
    uint32_t depth;     /* its light path's bounce: 1 at the first surface the light reaches */
    const scene_material *m;
} ref_vpl;

typedef struct ref_vpl_params {
    const scene *s;
    const rt_scene *rt;
    const ref_lights *lights;  /* the area lights' triangles by area (tri_cdf) */
    const float *light_value;  /* 3 per light (area, then point): radiance or intensity now */
    int full;                  /* non-zero: the full transport; else the model's */
    int bounces;               /* model transport: VPL depths 1..bounces (0: none) */
    int glossy_indirect;       /* model transport: glossy receivers reflect the VPLs (L_is) */
    uint32_t seed, generation;
    int paths;                 /* light paths a pass */
    int per_sample;            /* VPLs a pixel sample joins */
    float d_min;               /* clamp distance, scene units (0: none) */
} ref_vpl_params;

struct ref_ism;

/* The VPLs of one pass. Owned by the renderer's thread; read-only while a pass runs. */
typedef struct ref_vpl_set {
    ref_vpl_params params;
    const struct ref_ism *ism; /* non-NULL: gathers look up its maps (built of these VPLs, in this
                                  order) instead of tracing shadow rays; the caller sets it */
    ref_vpl *vpls;
    uint32_t count;
    size_t capacity;
    float *light_cdf;          /* all lights by power now; rebuilt each pass (light edits) */
    float *light_pmf;
    uint32_t light_capacity;
    uint64_t made;             /* VPLs made over all passes (stats) */
    double seconds;            /* spent making them */
} ref_vpl_set;

/* Traces params->paths light paths for pass `pass` (its random numbers come from
 * (seed, generation, pass, path) alone) and keeps their VPLs; the rays it traced
 * are added to *rays. */
lm_result ref_vpl_generate(ref_vpl_set *set, const ref_vpl_params *params, uint64_t pass, uint64_t *rays,
                           lm_error *err);
/* The radiance the set's VPLs send to x and x reflects towards wo (out: RGB,
 * W·m⁻²·sr⁻¹), from per_sample of them: by x's kd/π, and by its Phong lobe too
 * when `lobe` is non-zero; only VPLs of depths up to max_depth (0: all). Shadow
 * rays are added to *rays. */
void ref_vpl_gather(const ref_vpl_set *set, const ref_surface *x, lm_vec3 wo, int lobe, int max_depth, lm_rng *g,
                    float out[3], uint64_t *rays);

/* Glossy receivers whose Phong exponent is at least this reflect the VPLs' light
 * through a ray drawn by their lobe and the VPLs gathered where it lands (the
 * camera path goes on one surface), not through their lobe evaluated at each
 * VPL: VPLs sample a sharp lobe badly (a few VPLs in it give bright speckles). */
#define REF_VPL_LOBE_SAMPLED_N 8.0f
/* Bidirectional instant radiosity's resampling (Segovia et al. 2006, section 4):
 * a point the camera sees, and whether its lobe is evaluated at each VPL (as
 * ref_vpl_gather's `lobe`). */
typedef struct ref_vpl_eye {
    ref_surface x;
    lm_vec3 wo;
    int lobe;
} ref_vpl_eye;

enum { REF_BDIR_TESTS = 8,       /* eye points a candidate is tested against */
       REF_BDIR_EYES = 256 };    /* eye points a pass */
#define REF_BDIR_DEFENSIVE 0.25  /* the share of uniform odds in the resampling */

/* Keeps `keep` of the set's VPLs, drawn by their estimated contribution to the
 * eye points (the luminance each sends to REF_BDIR_TESTS of them, shadow rays
 * included) mixed with uniform odds, and weighs each by the inverse of its odds:
 * for any odds above zero the estimate stays unbiased (the clamp aside), and the
 * VPLs go where the camera looks (a room lit through a door gap: the few that
 * come through). Candidates drawn more than once are kept once, their flux
 * multiplied. Call it after ref_vpl_generate; rays are added to *rays. */
lm_result ref_vpl_resample(ref_vpl_set *set, const ref_vpl_eye *eyes, uint32_t eye_count, uint32_t keep,
                           uint64_t pass, uint64_t *rays, lm_error *err);
void ref_vpl_free(ref_vpl_set *set);

#endif
