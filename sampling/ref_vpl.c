/* ref_vpl.c — instant radiosity's VPLs: traced from the lights, gathered at a
 * surface point (see ref_vpl.h for the estimator and its bias). */
#include "sampling/ref_vpl.h"

#include "sampling/ref_ism.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

enum { MAX_PATH_DEPTH = 256, RR_START_DEPTH = 3, RR_DEEP_DEPTH = 32 };
#define RR_SMALL_THROUGHPUT 0.05f
#define VPL_SEED_SALT 0x7c1e5a3bu  /* the light paths' streams apart from the pixels' */
#define BDIR_SEED_SALT 0x2b3d9e61u /* the resampling's apart from both */

static int any_positive(const float *c) { return c[0] > 0.0f || c[1] > 0.0f || c[2] > 0.0f; }
static float max3(const float *c) { return fmaxf(c[0], fmaxf(c[1], c[2])); }
static float avg3(const float *c) { return (c[0] + c[1] + c[2]) * (1.0f / 3.0f); }

/* The lights by the luminance of their power now (light edits change it):
 * area lights π·Le·area, point lights 4π·I. Returns the number of lights, 0
 * when none emits. */
static uint32_t light_table(ref_vpl_set *set, lm_error *err, lm_result *res)
{
    const scene *s = set->params.s;
    uint32_t n = s->area_light_count + s->point_light_count;
    *res = LM_OK;
    if (n > set->light_capacity) {
        float *cdf = realloc(set->light_cdf, n * sizeof *cdf);
        if (cdf) set->light_cdf = cdf;
        float *pmf = cdf ? realloc(set->light_pmf, n * sizeof *pmf) : NULL;
        if (pmf) set->light_pmf = pmf;
        if (!cdf || !pmf) {
            *res = lm_fail(err, LM_ERR_NO_MEMORY, "out of memory for the VPLs' light table");
            return 0;
        }
        set->light_capacity = n;
    }
    double total = 0.0;
    for (uint32_t i = 0; i < n; ++i) {
        const float *v = set->params.light_value + 3 * (size_t)i;
        double w = i < s->area_light_count ? M_PI * s->area_lights[i].area : 4.0 * M_PI;
        set->light_pmf[i] = (float)(w * ref_luminance(v));
        total += set->light_pmf[i];
    }
    if (!(total > 0.0)) return 0;
    double acc = 0.0;
    for (uint32_t i = 0; i < n; ++i) {
        set->light_pmf[i] = (float)(set->light_pmf[i] / total);
        acc += set->light_pmf[i];
        set->light_cdf[i] = (float)acc;
    }
    set->light_cdf[n - 1] = 1.0f;
    return n;
}

/* A light path's start: its origin, direction and flux Φ/p (W). */
static int emit(const ref_vpl_set *set, uint32_t nlights, lm_rng *g, lm_vec3 *org, lm_vec3 *dir, float beta[3])
{
    const ref_vpl_params *P = &set->params;
    const scene *s = P->s;
    float u0 = lm_rng_float(g), u1 = lm_rng_float(g), u2 = lm_rng_float(g), u3 = lm_rng_float(g),
          u4 = lm_rng_float(g), u5 = lm_rng_float(g);
    uint32_t li = ref_pick_cdf(set->light_cdf, nlights, u0);
    float p = set->light_pmf[li];
    if (!(p > 0.0f)) return 0;
    const float *v = P->light_value + 3 * (size_t)li;
    if (li < s->area_light_count) {
        const scene_area_light *A = &s->area_lights[li];
        uint32_t tri;
        lm_vec3 y = ref_area_light_point(P->lights, li, u1, u2, u3, &tri);
        lm_vec3 n = v3_load(s->tri_normals + 3 * (size_t)tri);
        *dir = ref_sample_cosine(n, u4, u5); /* a Lambertian emitter's front: pdf cosθ/π */
        *org = v3_add(y, v3_scale(n, rt_scene_tri_epsilon(P->rt, tri)));
        /* Le·cosθ / (p · 1/area · cosθ/π) */
        for (int k2 = 0; k2 < 3; ++k2) beta[k2] = v[k2] * (float)M_PI * A->area / p;
    } else {
        const scene_point_light *L = &s->point_lights[li - s->area_light_count];
        float z = 1.0f - 2.0f * u4, r = sqrtf(fmaxf(0.0f, 1.0f - z * z)), phi = 2.0f * (float)M_PI * u5;
        *dir = v3(r * cosf(phi), r * sinf(phi), z);
        *org = v3_load(L->position);
        for (int k2 = 0; k2 < 3; ++k2) beta[k2] = v[k2] * 4.0f * (float)M_PI / p; /* I / (p · 1/4π) */
    }
    return any_positive(beta);
}

static lm_result push(ref_vpl_set *set, const ref_vpl *v, lm_error *err)
{
    if (!LM_GROW(set->vpls, set->capacity, (size_t)set->count + 1))
        return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory for %u VPLs", set->count + 1);
    set->vpls[set->count++] = *v;
    return LM_OK;
}

/* Follows one light path, leaving its VPLs in the set. */
static lm_result trace_path(ref_vpl_set *set, uint32_t nlights, lm_rng *g, uint64_t *rays, lm_error *err)
{
    const ref_vpl_params *P = &set->params;
    lm_vec3 org, dir;
    float beta[3];
    if (!emit(set, nlights, g, &org, &dir, beta)) return LM_OK;
    const float beta0 = max3(beta);
    const int max_depth = P->full ? MAX_PATH_DEPTH : P->bounces;
    for (int depth = 1; depth <= max_depth; ++depth) {
        float o[3] = {org.x, org.y, org.z}, d[3] = {dir.x, dir.y, dir.z};
        rt_hit h;
        ++*rays;
        if (!rt_intersect(P->rt, o, d, 0.0f, INFINITY, &h)) break;
        lm_vec3 w_in = v3_scale(dir, -1.0f);
        ref_surface y;
        ref_surface_from_hit(P->s, &h, w_in, &y);
        const scene_material *m = y.m;
        const int diffuse = any_positive(m->kd), glossy = P->full && any_positive(m->ks);
        if (!diffuse && !glossy) break; /* black here: the light is absorbed */
        ref_vpl v = {.p = y.p, .ng = y.ng, .ns = y.ns, .w_in = w_in, .tri = y.tri, .depth = (uint32_t)depth, .m = m};
        memcpy(v.flux, beta, sizeof v.flux);
        lm_result r = push(set, &v, err);
        if (r != LM_OK) return r;
        if (depth == max_depth) break;
        /* On: by diffuse reflection (model), or by the whole BRDF (full, as the path tracer). */
        float u0 = lm_rng_float(g), u1 = lm_rng_float(g), u2 = lm_rng_float(g);
        lm_vec3 wi;
        if (!P->full) {
            wi = ref_sample_cosine(y.ns, u1, u2);
            for (int k = 0; k < 3; ++k) beta[k] *= m->kd[k]; /* (kd/π)·cosθ / (cosθ/π) */
        } else {
            float d_avg = avg3(m->kd), s_avg = avg3(m->ks), p_spec = d_avg + s_avg > 0.0f ? s_avg / (d_avg + s_avg) : 0.0f;
            wi = u0 < p_spec ? ref_sample_phong(m->n, w_in, y.ns, u1, u2) : ref_sample_cosine(y.ns, u1, u2);
            float cosi = v3_dot(y.ns, wi);
            if (!(cosi > 0.0f)) break;
            float pdf = (1.0f - p_spec) * cosi / (float)M_PI + p_spec * ref_phong_pdf(m->n, wi, w_in, y.ns);
            if (!(pdf > 0.0f)) break;
            float lobe = ref_phong_lobe(m->n, wi, w_in, y.ns);
            for (int k = 0; k < 3; ++k) beta[k] *= (m->kd[k] / (float)M_PI + m->ks[k] * lobe) * cosi / pdf;
            /* The path tracer's bounded roulette (reference.c): thinned by halves
             * once the flux is small, gently when deep. */
            float q = 1.0f;
            if (depth + 1 >= RR_START_DEPTH && max3(beta) < RR_SMALL_THROUGHPUT * beta0)
                q = 0.5f;
            else if (depth + 1 >= RR_DEEP_DEPTH)
                q = 0.95f;
            if (q < 1.0f) {
                if (lm_rng_float(g) >= q) break;
                for (int k = 0; k < 3; ++k) beta[k] /= q;
            }
        }
        if (v3_dot(y.ng, wi) <= 0.0f || v3_dot(y.ns, wi) <= 0.0f || !any_positive(beta)) break;
        org = v3_add(y.p, v3_scale(y.ng, rt_scene_tri_epsilon(P->rt, y.tri)));
        dir = wi;
    }
    return LM_OK;
}

lm_result ref_vpl_generate(ref_vpl_set *set, const ref_vpl_params *params, uint64_t pass, uint64_t *rays,
                           lm_error *err)
{
    double t0 = lm_now_seconds();
    set->params = *params;
    set->count = 0;
    lm_result r = LM_OK;
    uint32_t nlights = light_table(set, err, &r);
    if (r != LM_OK || nlights == 0 || (!params->full && params->bounces <= 0)) return r;
    uint64_t stream = ((uint64_t)params->generation << 32) | (pass & 0xffffffffu);
    for (int i = 0; i < params->paths && r == LM_OK; ++i) {
        lm_rng g;
        lm_rng_seed(&g, (uint64_t)params->seed ^ VPL_SEED_SALT, (uint64_t)i, stream);
        r = trace_path(set, nlights, &g, rays, err);
    }
    set->made += set->count;
    set->seconds += lm_now_seconds() - t0;
    return r;
}

/* The radiance VPL v sends to x and x reflects towards wo (c: RGB), with the
 * clamp; 0 when there is none (facing away, black, or hidden: the shadow ray,
 * counted in *rays, is traced only for a non-zero value). */
static int contribution(const ref_vpl_params *P, const ref_ism *ism, uint32_t vi, const ref_vpl *v,
                        const ref_surface *x, lm_vec3 wo, int lobe_x, float d_min2, float eps_x, float c[3],
                        uint64_t *rays)
{
    const scene_material *mx = x->m;
    lm_vec3 d = v3_sub(v->p, x->p);
    float d2 = v3_dot(d, d);
    if (!(d2 > 0.0f)) return 0;
    lm_vec3 w = v3_scale(d, 1.0f / sqrtf(d2));
    float cos_x = v3_dot(x->ns, w), cos_y = -v3_dot(v->ns, w);
    if (cos_x <= 0.0f || cos_y <= 0.0f || v3_dot(x->ng, w) <= 0.0f || v3_dot(v->ng, w) >= 0.0f) return 0;
    const float geometry = cos_x * cos_y / fmaxf(d2, d_min2);
    const float lx = lobe_x ? ref_phong_lobe(mx->n, w, wo, x->ns) : 0.0f;
    const int lobe_y = P->full && any_positive(v->m->ks);
    const float ly = lobe_y ? ref_phong_lobe(v->m->n, v->w_in, v3_scale(w, -1.0f), v->ns) : 0.0f;
    for (int k = 0; k < 3; ++k) {
        float fx = mx->kd[k] / (float)M_PI + (lobe_x ? mx->ks[k] * lx : 0.0f);
        float fy = v->m->kd[k] / (float)M_PI + (lobe_y ? v->m->ks[k] * ly : 0.0f);
        c[k] = fx * fy * v->flux[k] * geometry;
    }
    if (!any_positive(c)) return 0;
    if (ism) return ref_ism_visible(ism, vi, x->p, x->ng);
    float a[3], na[3], b[3], nb[3];
    v3_store(a, x->p);
    v3_store(na, x->ng);
    v3_store(b, v->p);
    v3_store(nb, v->ng);
    ++*rays;
    return !rt_segment_occluded(P->rt, a, na, b, nb, fmaxf(eps_x, rt_scene_tri_epsilon(P->rt, v->tri)));
}

void ref_vpl_gather(const ref_vpl_set *set, const ref_surface *x, lm_vec3 wo, int lobe, int max_depth, lm_rng *g,
                    float out[3], uint64_t *rays)
{
    const ref_vpl_params *P = &set->params;
    const scene_material *mx = x->m;
    out[0] = out[1] = out[2] = 0.0f;
    const int lobe_x = lobe && any_positive(mx->ks);
    const uint32_t deepest = max_depth > 0 ? (uint32_t)max_depth : UINT32_MAX;
    if (set->count == 0 || P->paths <= 0 || (!any_positive(mx->kd) && !lobe_x)) return;
    const uint32_t V = set->count, M = P->per_sample > 0 && (uint32_t)P->per_sample < V ? (uint32_t)P->per_sample : V;
    /* One VPL from each of M equal strata of the set, at an independent place in
     * each: every VPL is expected M/V times (a VPL across a strata boundary may
     * come from either), so it weighs V/M, and 1/N for the paths. Not one offset
     * for all strata: a path's VPLs lie side by side, so with a stride that is a
     * multiple of their count every pick would be of one depth. */
    const double stride = (double)V / (double)M;
    const float weight = (float)V / (float)M / (float)P->paths, d_min2 = P->d_min * P->d_min;
    const float eps_x = rt_scene_tri_epsilon(P->rt, x->tri);
    for (uint32_t j = 0; j < M; ++j) {
        uint32_t i = (uint32_t)(((double)j + (double)lm_rng_float(g)) * stride);
        if (i >= V) i = V - 1;
        const ref_vpl *v = &set->vpls[i];
        if (v->depth > deepest) continue;
        float c[3];
        if (!contribution(P, set->ism, i, v, x, wo, lobe_x, d_min2, eps_x, c, rays)) continue;
        for (int k = 0; k < 3; ++k) out[k] += weight * c[k];
    }
}

lm_result ref_vpl_resample(ref_vpl_set *set, const ref_vpl_eye *eyes, uint32_t eye_count, uint32_t keep,
                           uint64_t pass, uint64_t *rays, lm_error *err)
{
    double t0 = lm_now_seconds();
    const ref_vpl_params *P = &set->params;
    const uint32_t V = set->count;
    if (V == 0 || eye_count == 0 || keep == 0 || P->paths <= 0) return LM_OK;
    double *p = malloc(V * sizeof *p);
    uint32_t *times = calloc(V, sizeof *times);
    if (!p || !times) {
        free(p);
        free(times);
        return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory resampling %u VPLs", V);
    }
    lm_rng g;
    lm_rng_seed(&g, (uint64_t)P->seed ^ BDIR_SEED_SALT, pass, P->generation);
    /* Each candidate's importance: the luminance it sends to REF_BDIR_TESTS points
     * the camera sees, drawn at random, shadow rays included. */
    const float d_min2 = P->d_min * P->d_min;
    double total = 0.0;
    for (uint32_t i = 0; i < V; ++i) {
        double sum = 0.0;
        for (int k = 0; k < REF_BDIR_TESTS; ++k) {
            uint32_t j = (uint32_t)(lm_rng_float(&g) * (float)eye_count);
            const ref_vpl_eye *e = &eyes[j < eye_count ? j : eye_count - 1];
            float c[3];
            if (contribution(P, NULL, i, &set->vpls[i], &e->x, e->wo, e->lobe, d_min2,
                             rt_scene_tri_epsilon(P->rt, e->x.tri), c, rays))
                sum += ref_luminance(c);
        }
        p[i] = sum;
        total += sum;
    }
    /* By importance, mixed with uniform odds (REF_BDIR_DEFENSIVE): a VPL the tests
     * missed may still light a pixel, and only a candidate with odds above zero
     * keeps the estimate unbiased. */
    for (uint32_t i = 0; i < V; ++i)
        p[i] = total > 0.0 ? (1.0 - REF_BDIR_DEFENSIVE) * p[i] / total + REF_BDIR_DEFENSIVE / V : 1.0 / V;
    /* Systematic resampling: `keep` evenly spaced draws through the cumulative
     * odds, so candidate i is drawn keep·p_i times in expectation. */
    const double u0 = lm_rng_float(&g);
    double acc = 0.0;
    uint32_t i = 0;
    for (uint32_t k = 0; k < keep; ++k) {
        double target = ((double)k + u0) / keep;
        while (i + 1 < V && acc + p[i] <= target) acc += p[i++];
        times[i]++;
    }
    /* Each drawn candidate once, its flux times (draws)/(keep·p_i·N): the mean of
     * the draws' c_i/p_i over keep, for the 1/N of the N light paths. */
    uint32_t n = 0;
    for (uint32_t c = 0; c < V; ++c) {
        if (!times[c]) continue;
        ref_vpl v = set->vpls[c];
        const double w = (double)times[c] / ((double)keep * p[c] * (double)P->paths);
        for (int k = 0; k < 3; ++k) v.flux[k] = (float)(v.flux[k] * w);
        set->vpls[n++] = v;
    }
    set->count = n;
    set->params.paths = 1; /* the 1/N is in the fluxes now */
    free(p);
    free(times);
    set->seconds += lm_now_seconds() - t0;
    return LM_OK;
}

void ref_vpl_free(ref_vpl_set *set)
{
    free(set->vpls);
    free(set->light_cdf);
    free(set->light_pmf);
    memset(set, 0, sizeof *set);
}
