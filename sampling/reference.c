/* reference.c — the progressive reference path tracer (see reference.h for the
 * two transports and the determinism rule). */
#define _GNU_SOURCE /* SCHED_IDLE */
#include "sampling/reference.h"

#include <math.h>
#include <pthread.h>
#include <sched.h>
#include <sys/resource.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "sampling/ref_shading.h"
#include "sampling/ref_ism.h"
#include "sampling/ref_vpl.h"
#include "sampling/rt_scene.h"
#include "src/scene/camera.h"

enum { TILE = 16, MAX_THREADS = 256, MAX_FULL_DEPTH = 256, RR_START_DEPTH = 3, RR_DEEP_DEPTH = 32 };
#define RR_SMALL_THROUGHPUT 0.05f

/* Per-pixel accumulators. Owned by the renderer; during a pass each pixel is
 * written by exactly one worker (the one that took its tile), never read. */
typedef struct ref_pixel {
    double sum[3], sum2[3]; /* sums of samples and of their squares, per channel */
    double sum_y2;          /* the sum of the luminances' squares (theirs is the luminance of sum:
                               ref_luminance is linear), 64 bytes a pixel instead of 72 */
    uint32_t count;
} ref_pixel;

struct ref_renderer {
    ref_desc desc;
    const scene *s;
    rt_scene *rt;
    ref_lights lights;
    int width, height, threads;
    camera_basis cam;       /* the primary rays (src/scene/camera.h) */
    uint32_t generation;    /* restarts so far: part of every sample's seed */
    float *light_value;     /* 3 per light (area lights, then point lights): radiance or intensity now
                               (ref_set_light); the scene's at creation */
    ref_pixel *pixels;
    uint8_t *mask;          /* NULL: every pixel; else a pass samples only non-zero ones */
    uint64_t rays;          /* main thread; summed from workers after each pass */
    double seconds;

    /* pass state: set before workers start, read-only while they run */
    volatile sig_atomic_t *cancel;
    double deadline;
    atomic_uint next_tile;
    unsigned resume_tile;   /* tiles of an unfinished pass done (all below it): the next call goes on there */
    atomic_ullong pass_rays;
    atomic_ullong bad_samples;

    /* VPL, BDIR: the pass's VPLs, made on the calling thread when a pass starts, read-only while its workers run */
    ref_vpl_set vpl;
    int vpl_ready;          /* the set belongs to the pass under way */
    uint64_t passes;        /* complete passes since the last restart: the VPL sets' stream */
    uint32_t light_edits;   /* ref_set_light calls that changed a value: the kept VPLs' stream (vpl_keep) */
    float vpl_d_min;        /* the clamp, scene units */
    ref_ism *ism;           /* REF_VPL_VISIBILITY_ISM: the pass's maps, built with its VPLs on the calling thread */
};

/* ---- tracing helpers ------------------------------------------------------ */

typedef struct ctx {
    ref_renderer *r;          /* workers touch only the pass counters and their own tiles */
    lm_rng g;
    uint64_t rays;
} ctx;

static lm_vec3 offset(const ctx *c, const ref_surface *x, lm_vec3 dir)
{
    lm_vec3 n = v3_dot(dir, x->ng) >= 0.0f ? x->ng : v3_scale(x->ng, -1.0f);
    return v3_add(x->p, v3_scale(n, rt_scene_tri_epsilon(c->r->rt, x->tri)));
}

static int trace(ctx *c, lm_vec3 org, lm_vec3 dir, rt_hit *h)
{
    float o[3] = {org.x, org.y, org.z}, d[3] = {dir.x, dir.y, dir.z};
    c->rays++;
    return rt_intersect(c->r->rt, o, d, 0.0f, INFINITY, h);
}

/* Nothing between the surface point x and the point x + dist·wi, on triangle
 * y_tri with surface normal ny (NULL for a point light: y_tri unused). Both ends
 * move by the larger of their triangles' offsets. */
static int visible(ctx *c, const ref_surface *x, lm_vec3 wi, float dist, const lm_vec3 *ny, uint32_t y_tri)
{
    float eps = rt_scene_tri_epsilon(c->r->rt, x->tri);
    if (ny) eps = fmaxf(eps, rt_scene_tri_epsilon(c->r->rt, y_tri));
    float a[3], na[3], b[3], nb[3];
    v3_store(a, x->p);
    v3_store(na, x->ng);
    v3_store(b, v3_add(x->p, v3_scale(wi, dist)));
    if (ny) v3_store(nb, *ny);
    c->rays++;
    return !rt_segment_occluded(c->r->rt, a, na, b, ny ? nb : NULL, eps);
}

static int emits_towards(const scene *s, uint32_t tri, lm_vec3 wi)
{
    return s->tris[tri].light >= 0 && v3_dot(v3_load(s->tri_normals + 3 * (size_t)tri), wi) < 0.0f;
}

/* The radiance of the area light triangle `tri` belongs to, as ref_set_light set it. */
static const float *area_le(const ref_renderer *r, uint32_t tri)
{
    return r->light_value + 3 * (size_t)r->s->tris[tri].light;
}

static int has_specular(const scene_material *m)
{
    return m->ks[0] > 0.0f || m->ks[1] > 0.0f || m->ks[2] > 0.0f;
}

static float avg3(const float *c) { return (c[0] + c[1] + c[2]) * (1.0f / 3.0f); }

/* ---- direct light --------------------------------------------------------- */

/* Direct light at x seen from wo, split into the diffuse radiance per unit
 * albedo, (1/π)·Σ E_ℓ (multiply by kd), and the specular radiance already
 * multiplied by ks. `spec_mis_pdf` chooses how the specular part of the light
 * sample is weighted against BRDF sampling: the model transport samples the
 * Phong lobe alone (weight against the lobe pdf), the full transport samples the
 * whole BRDF (weight against the mixture pdf, and the diffuse part too). */
typedef enum mis_mode { MIS_LOBE_ONLY = 0, MIS_FULL_BRDF } mis_mode;

static float brdf_pdf(const scene_material *m, lm_vec3 wi, lm_vec3 wo, lm_vec3 ns, float p_spec)
{
    float cosi = v3_dot(ns, wi);
    if (cosi <= 0.0f) return 0.0f;
    return (1.0f - p_spec) * cosi / (float)M_PI + p_spec * ref_phong_pdf(m->n, wi, wo, ns);
}

static float spec_probability(const scene_material *m)
{
    float d = avg3(m->kd), s = avg3(m->ks);
    return d + s > 0.0f ? s / (d + s) : 0.0f;
}

static void direct_light(ctx *c, const ref_surface *x, lm_vec3 wo, int want_specular, mis_mode mode,
                         float diffuse[3], float specular[3])
{
    const scene *s = c->r->s;
    const scene_material *m = x->m;
    int spec = want_specular && has_specular(m);
    float p_spec = spec_probability(m);
    for (int k = 0; k < 3; ++k) diffuse[k] = specular[k] = 0.0f;

    if (s->area_light_count) {
        ref_light_sample ls;
        if (ref_sample_area_light(&c->r->lights, &c->g, x->p, &ls)) {
            float cosx = v3_dot(x->ns, ls.wi);
            if (cosx > 0.0f && v3_dot(x->ng, ls.wi) > 0.0f && visible(c, x, ls.wi, ls.dist, &ls.ny, ls.tri)) {
                float e = cosx / ls.pdf; /* E per unit radiance */
                float wd = 1.0f, ws = 1.0f;
                if (mode == MIS_FULL_BRDF) {
                    wd = ws = ref_mis(ls.pdf, brdf_pdf(m, ls.wi, wo, x->ns, p_spec));
                } else if (spec) {
                    ws = ref_mis(ls.pdf, ref_phong_pdf(m->n, ls.wi, wo, x->ns));
                }
                float lobe = spec ? ref_phong_lobe(m->n, ls.wi, wo, x->ns) : 0.0f;
                const float *le = area_le(c->r, ls.tri);
                for (int k = 0; k < 3; ++k) {
                    diffuse[k] += wd * le[k] * e / (float)M_PI;
                    specular[k] += ws * m->ks[k] * lobe * le[k] * e;
                }
            }
        }
        /* Lobe sampling for the specular integral (model transport only: the full
         * transport's BRDF sample does this as part of the path). */
        if (spec && mode == MIS_LOBE_ONLY) {
            float u1 = lm_rng_float(&c->g), u2 = lm_rng_float(&c->g);
            lm_vec3 wi = ref_sample_phong(m->n, wo, x->ns, u1, u2);
            float cosx = v3_dot(x->ns, wi);
            rt_hit h;
            if (cosx > 0.0f && v3_dot(x->ng, wi) > 0.0f && trace(c, offset(c, x, wi), wi, &h) &&
                emits_towards(s, h.tri, wi)) {
                float pb = ref_phong_pdf(m->n, wi, wo, x->ns);
                float pl = ref_area_light_pdf(&c->r->lights, h.tri, wi, h.t);
                float w = ref_mis(pb, pl) * ref_phong_lobe(m->n, wi, wo, x->ns) * cosx / pb;
                const float *le = area_le(c->r, h.tri);
                for (int k = 0; k < 3; ++k) specular[k] += w * m->ks[k] * le[k];
            }
        }
    }
    for (uint32_t i = 0; i < s->point_light_count; ++i) {
        const scene_point_light *pl = &s->point_lights[i];
        const float *intensity = c->r->light_value + 3 * ((size_t)s->area_light_count + i);
        lm_vec3 d = v3_sub(v3_load(pl->position), x->p);
        float dist = v3_length(d);
        if (!(dist > 0.0f)) continue;
        lm_vec3 wi = v3_scale(d, 1.0f / dist);
        float cosx = v3_dot(x->ns, wi);
        if (cosx <= 0.0f || v3_dot(x->ng, wi) <= 0.0f || !visible(c, x, wi, dist, NULL, 0)) continue;
        float e = cosx / (dist * dist);
        float lobe = spec ? ref_phong_lobe(m->n, wi, wo, x->ns) : 0.0f;
        for (int k = 0; k < 3; ++k) {
            diffuse[k] += intensity[k] * e / (float)M_PI;
            specular[k] += m->ks[k] * lobe * intensity[k] * e;
        }
    }
}

/* ---- model transport ------------------------------------------------------ */

static void gather(ctx *c, const ref_surface *x, int bounces_left, float out[3]);

/* What the surface hit from x along wi sends back to x: kd(x')·L_dd(x') (+
 * kd(x')·L_id(x') while bounces remain), the source of x's gathers. */
static void source_along(ctx *c, const ref_surface *x, lm_vec3 wi, int bounces_left, float out[3])
{
    out[0] = out[1] = out[2] = 0.0f;
    if (v3_dot(wi, x->ng) <= 0.0f) return;
    rt_hit h;
    if (!trace(c, offset(c, x, wi), wi, &h)) return;
    ref_surface y;
    ref_surface_from_hit(c->r->s, &h, v3_scale(wi, -1.0f), &y);
    const float *kd = y.m->kd;
    if (kd[0] <= 0.0f && kd[1] <= 0.0f && kd[2] <= 0.0f) return;
    float dd[3], unused[3], more[3] = {0, 0, 0};
    direct_light(c, &y, v3_scale(wi, -1.0f), 0, MIS_LOBE_ONLY, dd, unused);
    if (bounces_left > 1) gather(c, &y, bounces_left - 1, more);
    for (int k = 0; k < 3; ++k) out[k] = kd[k] * (dd[k] + more[k]);
}

/* Radiance a diffuse bounce from x brings back (source_along). Estimates
 * L_id(x) = E_i(x)/π with one cosine sample. */
static void gather(ctx *c, const ref_surface *x, int bounces_left, float out[3])
{
    float u1 = lm_rng_float(&c->g), u2 = lm_rng_float(&c->g);
    source_along(c, x, ref_sample_cosine(x->ns, u1, u2), bounces_left, out);
}

/* The glossy reflection of the gathers' source at x seen from wo, per unit ks:
 * one direction drawn by the lobe (pdf (n+1)/(2π)·cosⁿα), so the sample is
 * (n+2)/(n+1)·cosθ·L (cache_glossy.c gathers the same integral from its source). */
static void glossy_source(ctx *c, const ref_surface *x, lm_vec3 wo, int bounces, float out[3])
{
    float u1 = lm_rng_float(&c->g), u2 = lm_rng_float(&c->g);
    const float n = x->m->n;
    lm_vec3 wi = ref_sample_phong(n, wo, x->ns, u1, u2);
    const float cosi = v3_dot(wi, x->ns);
    out[0] = out[1] = out[2] = 0.0f;
    if (!(cosi > 0.0f)) return; /* below the horizon: the lobe is clipped there */
    source_along(c, x, wi, bounces, out);
    const float w = (n + 2.0f) / (n + 1.0f) * cosi;
    for (int k = 0; k < 3; ++k) out[k] *= w;
}

/* The surface x a camera ray meets, and L set to what it emits towards the camera
 * (front side only); 0 with L zero on a miss. */
static int camera_hit(ctx *c, lm_vec3 org, lm_vec3 dir, ref_surface *x, float L[3])
{
    const ref_renderer *r = c->r;
    L[0] = L[1] = L[2] = 0.0f;
    rt_hit h;
    if (!trace(c, org, dir, &h)) return 0;
    ref_surface_from_hit(r->s, &h, v3_scale(dir, -1.0f), x);
    if (x->front) {
        const float *le = r->s->tris[h.tri].light >= 0 ? area_le(r, h.tri) : x->m->le;
        for (int k = 0; k < 3; ++k) L[k] += le[k];
    }
    return 1;
}

static void radiance_model(ctx *c, lm_vec3 org, lm_vec3 dir, float L[3])
{
    const ref_renderer *r = c->r;
    lm_vec3 wo = v3_scale(dir, -1.0f);
    ref_surface x;
    if (!camera_hit(c, org, dir, &x, L)) return;
    float dd[3], ds[3];
    direct_light(c, &x, wo, 1, MIS_LOBE_ONLY, dd, ds);
    int bounces = r->desc.bounces == REF_BOUNCES_NONE ? 0 : r->desc.bounces == 0 ? 1 : r->desc.bounces;
    float id[3] = {0, 0, 0};
    if (bounces > 0 && (x.m->kd[0] > 0.0f || x.m->kd[1] > 0.0f || x.m->kd[2] > 0.0f))
        gather(c, &x, bounces, id);
    float is[3] = {0, 0, 0};
    if (bounces > 0 && r->desc.glossy == REF_GLOSSY_INDIRECT && has_specular(x.m)) glossy_source(c, &x, wo, bounces, is);
    for (int k = 0; k < 3; ++k) L[k] += x.m->kd[k] * (dd[k] + id[k]) + ds[k] + x.m->ks[k] * is[k];
}

/* ---- instant radiosity (ref_vpl.h) ------------------------------------------ */

static int model_bounces(const ref_desc *d)
{
    return d->bounces == REF_BOUNCES_NONE ? 0 : d->bounces == 0 ? 1 : d->bounces;
}

/* A sharp lobe's reflection of the VPLs' light at x (per unit ks), by one ray
 * drawn from the lobe (pdf (n+1)/(2π)·cosⁿα, so the weight is (n+2)/(n+1)·cosθ,
 * as glossy_source): what the surface y it reaches sends back, less the lights
 * (x's direct light has them, lobe samples included). Model transport: y's
 * source kd·(L_dd + L_id), L_id from VPLs of depths up to K − 1 (x's own
 * gathers' source); full: y's direct light with its specular part, and every
 * VPL by y's whole BRDF. */
static void vpl_glossy(ctx *c, const ref_surface *x, lm_vec3 wo, float out[3])
{
    const ref_renderer *r = c->r;
    const int full = r->desc.transport == REF_TRANSPORT_FULL, bounces = model_bounces(&r->desc);
    out[0] = out[1] = out[2] = 0.0f;
    float u1 = lm_rng_float(&c->g), u2 = lm_rng_float(&c->g);
    const float n = x->m->n;
    lm_vec3 wi = ref_sample_phong(n, wo, x->ns, u1, u2);
    const float cosi = v3_dot(wi, x->ns);
    rt_hit h;
    if (!(cosi > 0.0f) || v3_dot(wi, x->ng) <= 0.0f || !trace(c, offset(c, x, wi), wi, &h)) return;
    lm_vec3 back = v3_scale(wi, -1.0f);
    ref_surface y;
    ref_surface_from_hit(r->s, &h, back, &y);
    float dd[3], ds[3], ind[3] = {0, 0, 0};
    if (full) {
        direct_light(c, &y, back, 1, MIS_LOBE_ONLY, dd, ds);
        ref_vpl_gather(&r->vpl, &y, back, 1, 0, &c->g, ind, &c->rays);
    } else {
        if (!(y.m->kd[0] > 0.0f || y.m->kd[1] > 0.0f || y.m->kd[2] > 0.0f)) return;
        direct_light(c, &y, back, 0, MIS_LOBE_ONLY, dd, ds);
        ds[0] = ds[1] = ds[2] = 0.0f;
        if (bounces > 1) ref_vpl_gather(&r->vpl, &y, back, 0, bounces - 1, &c->g, ind, &c->rays);
    }
    const float w = (n + 2.0f) / (n + 1.0f) * cosi;
    for (int k = 0; k < 3; ++k) out[k] = w * (y.m->kd[k] * dd[k] + ds[k] + ind[k]);
}

/* How a material's glossy part reflects the VPLs' light: through its lobe
 * evaluated at each VPL (returns 1), or by a ray drawn from a sharp lobe
 * (*by_ray), or not at all (the model transport's lights-only gloss, no bounces). */
static int vpl_lobe(const ref_renderer *r, const scene_material *m, int *by_ray)
{
    const int glossy = has_specular(m) && (r->desc.transport == REF_TRANSPORT_FULL ||
                                           (r->desc.glossy == REF_GLOSSY_INDIRECT && model_bounces(&r->desc) > 0));
    *by_ray = glossy && m->n >= REF_VPL_LOBE_SAMPLED_N;
    return glossy && !*by_ray;
}

/* The direct light as the model transport's (light sampling, the lobe by MIS),
 * which is also the full transport's direct part; the indirect from the pass's VPLs. */
static void radiance_vpl(ctx *c, lm_vec3 org, lm_vec3 dir, float L[3])
{
    const ref_renderer *r = c->r;
    lm_vec3 wo = v3_scale(dir, -1.0f);
    ref_surface x;
    if (!camera_hit(c, org, dir, &x, L)) return;
    float dd[3], ds[3], ind[3], is[3] = {0, 0, 0};
    direct_light(c, &x, wo, 1, MIS_LOBE_ONLY, dd, ds);
    int by_ray;
    const int lobe = vpl_lobe(r, x.m, &by_ray);
    ref_vpl_gather(&r->vpl, &x, wo, lobe, 0, &c->g, ind, &c->rays);
    if (by_ray) vpl_glossy(c, &x, wo, is);
    for (int k = 0; k < 3; ++k) L[k] += x.m->kd[k] * dd[k] + ds[k] + ind[k] + x.m->ks[k] * is[k];
}

/* BDIR's eye points for this pass: REF_BDIR_EYES pixels at random, where their
 * first ray lands (fewer where rays leave the scene). */
static lm_result bdir_eyes(ref_renderer *r, ref_vpl_eye **out, uint32_t *count, lm_error *err)
{
    ref_vpl_eye *e = malloc(REF_BDIR_EYES * sizeof *e);
    if (!e) return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory for BDIR's eye points");
    ctx c = {.r = r};
    lm_rng_seed(&c.g, (uint64_t)r->desc.seed ^ 0x3e7e5u, r->passes, r->generation);
    uint32_t n = 0;
    for (int k = 0; k < REF_BDIR_EYES; ++k) {
        float px = lm_rng_float(&c.g) * (float)r->width, py = lm_rng_float(&c.g) * (float)r->height;
        lm_vec3 dir = camera_ray_dir(&r->cam, px, py);
        rt_hit h;
        if (!trace(&c, r->cam.position, dir, &h)) continue;
        e[n].wo = v3_scale(dir, -1.0f);
        ref_surface_from_hit(r->s, &h, e[n].wo, &e[n].x);
        int by_ray;
        e[n].lobe = vpl_lobe(r, e[n].x.m, &by_ray);
        n++;
    }
    r->rays += c.rays;
    *out = e;
    *count = n;
    return LM_OK;
}

/* The VPLs of the pass about to start (BDIR: candidates, then resampled by
 * what the camera sees). */
static lm_result make_vpls(ref_renderer *r, lm_error *err)
{
    const ref_desc *d = &r->desc;
    int bounces = model_bounces(d);
    const int keep = d->vpl_paths > 0 ? d->vpl_paths : REF_VPL_PATHS_DEFAULT;
    const int bdir = d->estimator == REF_ESTIMATOR_BDIR;
    ref_vpl_params p = {.s = r->s, .rt = r->rt, .lights = &r->lights, .light_value = r->light_value,
                        .full = d->transport == REF_TRANSPORT_FULL, .bounces = bounces,
                        .glossy_indirect = d->glossy == REF_GLOSSY_INDIRECT, .seed = d->seed,
                        .generation = d->vpl_keep ? r->light_edits : r->generation,
                        .paths = bdir ? keep * REF_BDIR_CANDIDATES : keep,
                        .per_sample = d->vpl_per_sample > 0 ? d->vpl_per_sample : REF_VPL_PER_SAMPLE_DEFAULT,
                        .d_min = r->vpl_d_min};
    uint64_t rays = 0;
    lm_result res = ref_vpl_generate(&r->vpl, &p, r->passes, &rays, err);
    if (res == LM_OK && bdir) {
        ref_vpl_eye *eyes = NULL;
        uint32_t n = 0;
        res = bdir_eyes(r, &eyes, &n, err);
        if (res == LM_OK) res = ref_vpl_resample(&r->vpl, eyes, n, (uint32_t)keep, r->passes, &rays, err);
        free(eyes);
    }
    r->rays += rays;
    if (res == LM_OK && r->ism)
        res = ref_ism_build(r->ism, r->vpl.vpls, r->vpl.count, ((uint64_t)p.generation << 32) | (r->passes & 0xffffffffu),
                            err);
    r->vpl.ism = r->ism;
    return res;
}

/* ---- full transport -------------------------------------------------------- */

static void radiance_full(ctx *c, lm_vec3 org, lm_vec3 dir, float L[3])
{
    const ref_renderer *r = c->r;
    const scene *s = r->s;
    float beta[3] = {1, 1, 1};
    float prev_pdf = 0.0f; /* BRDF density of the direction that led here; 0 at the camera */
    L[0] = L[1] = L[2] = 0.0f;
    ref_surface x;
    for (int depth = 0; depth < MAX_FULL_DEPTH; ++depth) {
        rt_hit h;
        if (!trace(c, org, dir, &h)) break;
        lm_vec3 wo = v3_scale(dir, -1.0f);
        ref_surface_from_hit(s, &h, wo, &x);
        if (x.front && s->tris[h.tri].light >= 0) {
            /* Emission found by BRDF sampling, weighted against light sampling. */
            float w = depth == 0 ? 1.0f : ref_mis(prev_pdf, ref_area_light_pdf(&r->lights, h.tri, dir, h.t));
            const float *le = area_le(r, h.tri);
            for (int k = 0; k < 3; ++k) L[k] += beta[k] * w * le[k];
        }
        const scene_material *m = x.m;
        float dd[3], ds[3];
        direct_light(c, &x, wo, 1, MIS_FULL_BRDF, dd, ds);
        for (int k = 0; k < 3; ++k) L[k] += beta[k] * (m->kd[k] * dd[k] + ds[k]);

        /* Continue by sampling the BRDF. */
        float p_spec = spec_probability(m);
        if (avg3(m->kd) + avg3(m->ks) <= 0.0f) break;
        float u0 = lm_rng_float(&c->g), u1 = lm_rng_float(&c->g), u2 = lm_rng_float(&c->g);
        lm_vec3 wi = u0 < p_spec ? ref_sample_phong(m->n, wo, x.ns, u1, u2) : ref_sample_cosine(x.ns, u1, u2);
        float cosi = v3_dot(x.ns, wi);
        if (cosi <= 0.0f || v3_dot(x.ng, wi) <= 0.0f) break;
        float pdf = brdf_pdf(m, wi, wo, x.ns, p_spec);
        if (!(pdf > 0.0f)) break;
        float lobe = ref_phong_lobe(m->n, wi, wo, x.ns);
        for (int k = 0; k < 3; ++k) beta[k] *= (m->kd[k] / (float)M_PI + m->ks[k] * lobe) * cosi / pdf;
        /* Russian roulette with bounded weights: a path is thinned only once its
         * throughput is small, and then by halves, so a survivor weighs at most
         * twice its neighbours. The textbook q = throughput makes survivors jump
         * by 1/throughput (x32 at the fifth bounce of an albedo-0.5 room): unbiased,
         * but so heavy-tailed that a pixel's own error estimate is often too low
         * (measured in tests/reference_sphere_test.c). Deep paths in bright rooms
         * (albedo near 1) are thinned gently from RR_DEEP_DEPTH on. */
        float bmax = fmaxf(beta[0], fmaxf(beta[1], beta[2]));
        float q = 1.0f;
        if (depth + 1 >= RR_START_DEPTH && bmax < RR_SMALL_THROUGHPUT)
            q = 0.5f;
        else if (depth + 1 >= RR_DEEP_DEPTH)
            q = 0.95f;
        if (q < 1.0f) {
            if (lm_rng_float(&c->g) >= q) break;
            for (int k = 0; k < 3; ++k) beta[k] /= q;
        }
        prev_pdf = pdf;
        org = offset(c, &x, wi);
        dir = wi;
    }
}

/* ---- passes ---------------------------------------------------------------- */

static void render_pixel(ctx *c, int px, int py)
{
    const ref_renderer *r = c->r;
    ref_pixel *pix = &r->pixels[(size_t)py * (size_t)r->width + (size_t)px];
    uint64_t pixel = (uint64_t)py * (uint64_t)r->width + (uint64_t)px;
    lm_rng_seed(&c->g, r->desc.seed, pixel, ((uint64_t)r->generation << 32) | pix->count);
    float jx = lm_rng_float(&c->g), jy = lm_rng_float(&c->g);
    lm_vec3 dir = camera_ray_dir(&r->cam, (float)px + jx, (float)py + jy);
    float L[3];
    if (r->desc.estimator != REF_ESTIMATOR_PATHS)
        radiance_vpl(c, r->cam.position, dir, L);
    else if (r->desc.transport == REF_TRANSPORT_FULL)
        radiance_full(c, r->cam.position, dir, L);
    else
        radiance_model(c, r->cam.position, dir, L);
    if (!isfinite(L[0]) || !isfinite(L[1]) || !isfinite(L[2])) {
        /* Counted, not accumulated: one NaN would poison the pixel for good. */
        atomic_fetch_add(&c->r->bad_samples, 1);
        L[0] = L[1] = L[2] = 0.0f;
    }
    float y = ref_luminance(L);
    for (int k = 0; k < 3; ++k) {
        pix->sum[k] += L[k];
        pix->sum2[k] += (double)L[k] * L[k];
    }
    pix->sum_y2 += (double)y * y;
    pix->count++;
}

static void *worker(void *arg)
{
    ref_renderer *r = arg;
    ctx c = {.r = r};
    int tiles_x = (r->width + TILE - 1) / TILE, tiles_y = (r->height + TILE - 1) / TILE;
    unsigned ntiles = (unsigned)(tiles_x * tiles_y);
    for (;;) {
        if (r->cancel && *r->cancel) break;
        if (r->deadline > 0.0 && lm_now_seconds() > r->deadline) break;
        unsigned t = atomic_fetch_add(&r->next_tile, 1u);
        if (t >= ntiles) break;
        int x0 = (int)(t % (unsigned)tiles_x) * TILE, y0 = (int)(t / (unsigned)tiles_x) * TILE;
        for (int y = y0; y < y0 + TILE && y < r->height; ++y)
            for (int x = x0; x < x0 + TILE && x < r->width; ++x)
                if (!r->mask || r->mask[(size_t)y * (size_t)r->width + (size_t)x]) render_pixel(&c, x, y);
    }
    atomic_fetch_add(&r->pass_rays, c.rays);
    return NULL;
}

/* A worker of a background renderer (ref_desc.background): the lowest priority
 * the system has for this thread, so it takes only the cycles the others leave.
 * Linux: SCHED_IDLE; elsewhere, or where that is refused, nice 19 (on Linux
 * setpriority with 0 is this thread). A thread cannot raise itself back, which is
 * why these are threads of their own, never the caller. */
static void *background_worker(void *arg)
{
#ifdef SCHED_IDLE
    struct sched_param none = {0};
    if (pthread_setschedparam(pthread_self(), SCHED_IDLE, &none) != 0)
#endif
        (void)setpriority(PRIO_PROCESS, 0, 19);
    return worker(arg);
}

int ref_render_pass(ref_renderer *r, volatile sig_atomic_t *cancel, double deadline)
{
    double t0 = lm_now_seconds();
    if (r->desc.estimator != REF_ESTIMATOR_PATHS && !r->vpl_ready) { /* a pass starts: its VPLs */
        lm_error err;
        if (make_vpls(r, &err) != LM_OK) r->vpl.count = 0; /* out of memory, or GL failed: this pass without indirect light */
        r->vpl_ready = 1;
    }
    r->cancel = cancel;
    r->deadline = deadline;
    atomic_store(&r->next_tile, r->resume_tile);
    atomic_store(&r->pass_rays, 0ull);
    pthread_t tids[MAX_THREADS];
    int started = 0;
    /* In the background every worker is a thread of its own at the lowest
     * priority, and the caller waits; else the calling thread works too. */
    const int background = r->desc.background != 0;
    for (int i = background ? 0 : 1; i < r->threads; ++i) {
        if (pthread_create(&tids[started], NULL, background ? background_worker : worker, r) != 0) break;
        started++;
    }
    if (!background || started == 0) worker(r); /* no thread could be made: the caller does the pass */
    for (int i = 0; i < started; ++i) pthread_join(tids[i], NULL);
    r->rays += atomic_load(&r->pass_rays);
    r->seconds += lm_now_seconds() - t0;
    r->cancel = NULL;
    /* A worker takes a tile only before the deadline and then finishes it, so the
     * tiles below next_tile are done; past the last one the pass is complete. */
    unsigned tiles = (unsigned)(((r->width + TILE - 1) / TILE) * ((r->height + TILE - 1) / TILE));
    unsigned done = atomic_load(&r->next_tile);
    r->resume_tile = done >= tiles ? 0u : done;
    if (done >= tiles) {
        r->passes++;
        r->vpl_ready = 0;
    }
    return done >= tiles;
}

/* ---- creation and results --------------------------------------------------- */

lm_result ref_create(const ref_desc *desc, ref_renderer **out, lm_error *err)
{
    *out = NULL;
    if (!desc || !desc->scene) return lm_fail(err, LM_ERR_INVALID_ARG, "ref_create: no scene");
    const scene *s = desc->scene;
    if (!desc->view && (desc->camera < 0 || (uint32_t)desc->camera >= s->camera_count))
        return lm_fail(err, LM_ERR_INVALID_ARG, "ref_create: camera %d does not exist", desc->camera);
    if ((unsigned)desc->transport >= REF_TRANSPORT_COUNT)
        return lm_fail(err, LM_ERR_INVALID_ARG, "ref_create: unknown transport %d", (int)desc->transport);
    if ((unsigned)desc->glossy >= REF_GLOSSY_COUNT) return lm_fail(err, LM_ERR_INVALID_ARG, "ref_create: unknown glossy mode");
    if (desc->bounces < REF_BOUNCES_NONE || desc->bounces > 64)
        return lm_fail(err, LM_ERR_INVALID_ARG, "ref_create: bounces must be 0..64");
    if ((unsigned)desc->estimator >= REF_ESTIMATOR_COUNT)
        return lm_fail(err, LM_ERR_INVALID_ARG, "ref_create: unknown estimator %d", (int)desc->estimator);
    if (desc->vpl_paths < 0 || desc->vpl_per_sample < 0 ||
        !(desc->vpl_clamp >= 0.0f || desc->vpl_clamp == REF_VPL_NO_CLAMP) || !(desc->vpl_clamp < 1.0f))
        return lm_fail(err, LM_ERR_INVALID_ARG,
                       "ref_create: VPL paths and VPLs a sample are not negative, the clamp is in [0, 1) or none");
    if ((unsigned)desc->vpl_visibility >= REF_VPL_VISIBILITY_COUNT)
        return lm_fail(err, LM_ERR_INVALID_ARG, "ref_create: unknown VPL visibility %d", (int)desc->vpl_visibility);
    const scene_camera *cam = desc->view ? desc->view : &s->cameras[desc->camera];
    ref_renderer *r = calloc(1, sizeof *r);
    if (!r) return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory creating the renderer");
    r->desc = *desc;
    r->desc.view = NULL; /* not kept: the caller's may not outlive this */
    r->s = s;
    r->width = desc->width > 0 ? desc->width : cam->width;
    r->height = desc->height > 0 ? desc->height : cam->height;
    long ncpu = sysconf(_SC_NPROCESSORS_ONLN);
    r->threads = desc->threads > 0 ? desc->threads : (ncpu > 0 ? (int)ncpu : 1);
    if (r->threads > MAX_THREADS) r->threads = MAX_THREADS;
    r->pixels = calloc((size_t)r->width * (size_t)r->height, sizeof *r->pixels);
    if (!r->pixels) {
        int w = r->width, h = r->height;
        ref_destroy(r);
        return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory for a %dx%d image", w, h);
    }
    uint32_t lights = s->area_light_count + s->point_light_count;
    r->light_value = malloc(((size_t)lights + 1) * 3 * sizeof *r->light_value);
    if (!r->light_value) {
        ref_destroy(r);
        return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory creating the renderer");
    }
    for (uint32_t l = 0; l < lights; ++l)
        memcpy(r->light_value + 3 * (size_t)l,
               l < s->area_light_count ? s->area_lights[l].le : s->point_lights[l - s->area_light_count].intensity,
               3 * sizeof *r->light_value);
    lm_result res = rt_scene_create(&(rt_scene_desc){.scene = s}, &r->rt, err);
    if (res == LM_OK) res = ref_lights_init(&r->lights, s, err);
    if (res != LM_OK) {
        ref_destroy(r);
        return res;
    }
    if (desc->estimator != REF_ESTIMATOR_PATHS && desc->vpl_visibility == REF_VPL_VISIBILITY_ISM) {
        res = ref_ism_create(&(ref_ism_desc){.s = s, .platform = desc->gl_platform, .seed = desc->seed}, &r->ism, err);
        if (res != LM_OK) {
            ref_destroy(r);
            return res;
        }
    }
    r->cam = camera_basis_make(cam, r->width, r->height);
    if (desc->vpl_clamp != REF_VPL_NO_CLAMP) {
        lm_vec3 diag = v3_sub(v3_load(s->bounds_max), v3_load(s->bounds_min));
        r->vpl_d_min = (desc->vpl_clamp > 0.0f ? desc->vpl_clamp : REF_VPL_CLAMP_DEFAULT) * v3_length(diag);
    }
    *out = r;
    return LM_OK;
}

void ref_restart(ref_renderer *r, const scene_camera *view)
{
    memset(r->pixels, 0, (size_t)r->width * (size_t)r->height * sizeof *r->pixels);
    r->generation++;
    r->resume_tile = 0;
    r->passes = 0;
    r->vpl_ready = 0;
    if (view) r->cam = camera_basis_make(view, r->width, r->height);
}

lm_result ref_set_light(ref_renderer *r, uint32_t light, const float value[3], lm_error *err)
{
    const scene *s = r->s;
    if (light >= s->area_light_count + s->point_light_count)
        return lm_fail(err, LM_ERR_INVALID_ARG, "light %u does not exist (the scene has %u)", light,
                       s->area_light_count + s->point_light_count);
    for (int k = 0; k < 3; ++k)
        if (!isfinite(value[k]) || value[k] < 0.0f)
            return lm_fail(err, LM_ERR_INVALID_ARG, "light %u: a value must be finite and not negative", light);
    if (memcmp(r->light_value + 3 * (size_t)light, value, 3 * sizeof *value) != 0) r->light_edits++;
    memcpy(r->light_value + 3 * (size_t)light, value, 3 * sizeof *value);
    return LM_OK;
}

lm_result ref_set_mask(ref_renderer *r, const uint8_t *mask, lm_error *err)
{
    size_t n = (size_t)r->width * (size_t)r->height;
    if (!mask) {
        free(r->mask);
        r->mask = NULL;
        return LM_OK;
    }
    if (!r->mask && !(r->mask = malloc(n))) return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory for a pixel mask");
    memcpy(r->mask, mask, n);
    return LM_OK;
}

void ref_destroy(ref_renderer *r)
{
    if (!r) return;
    free(r->mask);
    free(r->light_value);
    ref_vpl_free(&r->vpl);
    ref_ism_destroy(r->ism);
    rt_scene_destroy(r->rt);
    ref_lights_free(&r->lights);
    free(r->pixels);
    free(r);
}

static double stderr_of_mean(double sum, double sum2, uint32_t n)
{
    if (n < 2) return INFINITY;
    double mean = sum / n;
    double var = (sum2 - sum * mean) / (n - 1);
    return var > 0.0 ? sqrt(var / n) : 0.0;
}

void ref_get_stats(const ref_renderer *r, ref_stats *out)
{
    memset(out, 0, sizeof *out);
    size_t n = (size_t)r->width * (size_t)r->height;
    out->min_samples = UINT32_MAX;
    double rel = 0.0;
    size_t counted = 0;
    for (size_t i = 0; i < n; ++i) {
        const ref_pixel *p = &r->pixels[i];
        if (p->count < out->min_samples) out->min_samples = p->count;
        if (p->count > out->max_samples) out->max_samples = p->count;
        if (p->count < 2) continue;
        /* ref_luminance's weights, in double: the variance is a difference of sums */
        double sum_y = 0.2126f * p->sum[0] + 0.7152f * p->sum[1] + 0.0722f * p->sum[2], y = sum_y / p->count;
        rel += stderr_of_mean(sum_y, p->sum_y2, p->count) / sqrt(y * y + 0.01);
        counted++;
    }
    out->mean_rel_stderr = counted ? rel / (double)counted : INFINITY;
    out->rays = r->rays;
    out->seconds = r->seconds;
    out->bad_samples = atomic_load(&((ref_renderer *)r)->bad_samples);
    out->vpls = r->vpl.made;
    if (r->desc.estimator != REF_ESTIMATOR_PATHS) out->vpl_passes = r->passes + (uint64_t)r->vpl_ready;
    out->vpl_seconds = r->vpl.seconds;
    ref_ism_totals(r->ism, &out->ism_maps, &out->ism_seconds);
}

void ref_get_image(const ref_renderer *r, float *rgb, float *stderr_rgb, float *samples)
{
    ref_get_rows(r, 0, r->height, rgb, stderr_rgb, samples);
}

void ref_get_rows(const ref_renderer *r, int y0, int rows, float *rgb, float *stderr_rgb, float *samples)
{
    if (y0 < 0) {
        rows += y0;
        y0 = 0;
    }
    if (rows > r->height - y0) rows = r->height - y0;
    if (rows <= 0) return;
    size_t n = (size_t)r->width * (size_t)rows;
    const ref_pixel *first = r->pixels + (size_t)y0 * (size_t)r->width;
    for (size_t i = 0; i < n; ++i) {
        const ref_pixel *p = &first[i];
        for (int k = 0; k < 3; ++k) {
            if (rgb) rgb[3 * i + (size_t)k] = p->count ? (float)(p->sum[k] / p->count) : 0.0f;
            if (stderr_rgb) stderr_rgb[3 * i + (size_t)k] = (float)stderr_of_mean(p->sum[k], p->sum2[k], p->count);
        }
        if (samples) samples[i] = (float)p->count;
    }
}

void ref_get_size(const ref_renderer *r, int *width, int *height)
{
    *width = r->width;
    *height = r->height;
}
