/* samp.c — the sampler front end (samp.h): argument checks, point lights, call
 * statistics, and dispatch to a back end (samp_embree.c, samp_gl.c). The choice
 * SAMP_BACKEND_AUTO is made in samp_auto.c. */
#include "sampling/samp.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "sampling/analytic.h"
#include "sampling/samp_internal.h"
#include "src/base/vecmath.h"

struct samp_sampler {
    samp_desc desc;            /* defaults filled in */
    const scene *s;
    rt_scene *rt;              /* owned; shared with the back ends (read-only) */
    samp_choice be;            /* owned */
    samp_stats stats;
};

const char *samp_backend_name(samp_backend b)
{
    switch (b) {
    case SAMP_BACKEND_AUTO: return "auto";
    case SAMP_BACKEND_EMBREE: return "embree";
    case SAMP_BACKEND_GL: return "gl";
    default: return "?";
    }
}

int samp_backend_from_name(const char *name, samp_backend *out)
{
    for (int b = 0; b < SAMP_BACKEND_COUNT && name; ++b)
        if (strcmp(name, samp_backend_name((samp_backend)b)) == 0) {
            *out = (samp_backend)b;
            return 1;
        }
    return 0;
}

samp_desc samp_desc_defaults(const samp_desc *desc)
{
    samp_desc d = *desc;
    if (d.gl_platform == GLCTX_DEFAULT) d.gl_platform = GLCTX_EGL;
    if (d.direct_res <= 0) d.direct_res = 64;
    if (d.direct_rays <= 0) d.direct_rays = 64;
    if (d.indirect_res <= 0) d.indirect_res = 64;
    if (d.indirect_rays <= 0) d.indirect_rays = 1024;
    return d;
}

double samp_area_light_unoccluded(const scene *s, uint32_t light, const float p[3], const float n[3])
{
    const scene_area_light *L = &s->area_lights[light];
    const double x[3] = {p[0], p[1], p[2]}, nx[3] = {n[0], n[1], n[2]};
    double g = 0.0;
    for (uint32_t i = 0; i < L->count; ++i) {
        const uint32_t *v = s->tris[s->light_tris[L->first + i]].v;
        double tri[3][3];
        for (int c = 0; c < 3; ++c)
            for (int k = 0; k < 3; ++k) tri[c][k] = s->positions[3 * (size_t)v[c] + (size_t)k];
        g += samp_polygon_G(tri, 3, x, nx);
    }
    return g;
}

float samp_origin_epsilon(const samp_sampler *sp) { return rt_scene_epsilon(sp->rt); }

void samp_point_origin(const scene *s, const samp_point *x, float eps, float out[3])
{
    lm_vec3 p = v3_load(x->p);
    if (x->tri_plus_one > 0 && x->tri_plus_one <= s->tri_count) {
        const uint32_t *v = s->tris[x->tri_plus_one - 1].v;
        lm_vec3 c = v3_scale(v3_add(v3_add(v3_load(s->positions + 3 * (size_t)v[0]),
                                           v3_load(s->positions + 3 * (size_t)v[1])),
                                    v3_load(s->positions + 3 * (size_t)v[2])),
                             1.0f / 3.0f);
        lm_vec3 to_c = v3_sub(c, p);
        float d = v3_length(to_c);
        /* Never past the centroid: a tiny triangle keeps its point inside. */
        if (d > 0.0f) p = v3_add(p, v3_scale(to_c, fminf(eps, 0.5f * d) / d));
    }
    v3_store(out, v3_add(p, v3_scale(v3_load(x->n), eps)));
}

uint32_t samp_cdf_pick(const double *cdf, uint32_t n, double u)
{
    uint32_t lo = 0, hi = n - 1;
    while (lo < hi) {
        uint32_t mid = (lo + hi) / 2;
        if (u < cdf[mid])
            hi = mid;
        else
            lo = mid + 1;
    }
    return lo;
}

double *samp_area_cdf(const scene *s)
{
    double *cdf = malloc((s->tri_count ? s->tri_count : 1) * sizeof *cdf), total = 0.0;
    if (!cdf) return NULL;
    for (uint32_t t = 0; t < s->tri_count; ++t) cdf[t] = (total += s->tri_areas[t]);
    for (uint32_t t = 0; t < s->tri_count; ++t) cdf[t] /= total;
    if (s->tri_count) cdf[s->tri_count - 1] = 1.0;
    return cdf;
}

samp_point samp_random_receiver(const scene *s, const double *area_cdf, lm_rng *g)
{
    uint32_t t = 0;
    for (int tries = 0; tries < 1000; ++tries) { /* a scene is never only lights (scene_load) */
        t = samp_cdf_pick(area_cdf, s->tri_count, lm_rng_float(g));
        if (s->tris[t].light < 0) break;
    }
    float u = lm_rng_float(g), v = lm_rng_float(g);
    if (u + v > 1.0f) {
        u = 1.0f - u;
        v = 1.0f - v;
    }
    const uint32_t *vi = s->tris[t].v;
    samp_point x = {.tri_plus_one = t + 1};
    for (int k = 0; k < 3; ++k) {
        x.p[k] = (1.0f - u - v) * s->positions[3 * (size_t)vi[0] + (size_t)k] +
                 u * s->positions[3 * (size_t)vi[1] + (size_t)k] + v * s->positions[3 * (size_t)vi[2] + (size_t)k];
        x.n[k] = s->tri_normals[3 * (size_t)t + (size_t)k];
    }
    return x;
}

/* kd·Σ_ℓ L_ℓ·G_ℓ,unocc/π at barycentrics (w1, w2) of scene triangle t. */
static void unoccluded_radiance(const scene *s, uint32_t t, double w1, double w2, float out[3])
{
    const scene_material *m = &s->materials[s->tris[t].material];
    const float *nrm = s->tri_normals + 3 * (size_t)t;
    float p[3];
    for (int k = 0; k < 3; ++k)
        p[k] = (float)((1.0 - w1 - w2) * s->positions[3 * (size_t)s->tris[t].v[0] + (size_t)k] +
                       w1 * s->positions[3 * (size_t)s->tris[t].v[1] + (size_t)k] +
                       w2 * s->positions[3 * (size_t)s->tris[t].v[2] + (size_t)k]);
    double e[3] = {0, 0, 0};
    for (uint32_t l = 0; l < s->area_light_count; ++l) {
        double g = samp_area_light_unoccluded(s, l, p, nrm);
        for (int k = 0; k < 3; ++k) e[k] += s->area_lights[l].le[k] * g;
    }
    const double P[3] = {p[0], p[1], p[2]}, N[3] = {nrm[0], nrm[1], nrm[2]};
    for (uint32_t l = 0; l < s->point_light_count; ++l) {
        const float *q = s->point_lights[l].position;
        const double Q[3] = {q[0], q[1], q[2]};
        double g = samp_point_G(Q, P, N);
        for (int k = 0; k < 3; ++k) e[k] += s->point_lights[l].intensity[k] * g;
    }
    for (int k = 0; k < 3; ++k) {
        double v = s->tris[t].light >= 0 ? 0.0 : m->kd[k] * e[k] / M_PI; /* emission is no source (eq. 7) */
        out[k] = v < 3e38 ? (float)v : 3e38f;
    }
}

lm_result samp_coarse_mesh_build(const scene *s, uint32_t target_triangles, samp_coarse_mesh *out, lm_error *err)
{
    memset(out, 0, sizeof *out);
    /* Every scene triangle cut into the 4^k triangles of its dyadic lattice, k the
     * largest with tri_count·4^k <= target_triangles (k = 0 at least). */
    uint32_t k = 0;
    while (k < 8 && ((uint64_t)s->tri_count << (2 * (k + 1))) <= target_triangles) k++;
    uint32_t n = 1u << k, per = n * n;
    size_t total = (size_t)s->tri_count * per;
    out->first = malloc(((size_t)s->tri_count + 1) * sizeof *out->first);
    out->bary = malloc(6 * total * sizeof *out->bary);
    out->radiance = malloc(9 * total * sizeof *out->radiance);
    if (!out->first || !out->bary || !out->radiance) {
        samp_coarse_mesh_free(out);
        return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory for a coarse radiance mesh");
    }
    size_t at = 0;
    for (uint32_t t = 0; t < s->tri_count; ++t) {
        out->first[t] = (uint32_t)at;
        for (uint32_t a = 0; a < n; ++a)
            for (uint32_t b = 0; a + b < n; ++b)
                for (int down = 0; down < 2; ++down) {
                    if (down && a + b + 1 >= n) continue;
                    /* up: (a,b) (a+1,b) (a,b+1); down: (a+1,b) (a+1,b+1) (a,b+1) */
                    const uint32_t cw[3][2] = {{a + (uint32_t)down, b}, {a + 1, b + (uint32_t)down}, {a, b + 1}};
                    for (int c = 0; c < 3; ++c) {
                        double w1 = (double)cw[c][0] / n, w2 = (double)cw[c][1] / n;
                        out->bary[6 * at + 2 * (size_t)c] = (float)w1;
                        out->bary[6 * at + 2 * (size_t)c + 1] = (float)w2;
                        unoccluded_radiance(s, t, w1, w2, out->radiance + 9 * at + 3 * (size_t)c);
                    }
                    at++;
                }
    }
    out->first[s->tri_count] = (uint32_t)at;
    out->mesh = (samp_radiance_mesh){.tri_count = (uint32_t)at, .first = out->first, .bary = out->bary,
                                     .radiance = out->radiance};
    return LM_OK;
}

void samp_coarse_mesh_free(samp_coarse_mesh *m)
{
    free(m->first);
    free(m->bary);
    free(m->radiance);
    memset(m, 0, sizeof *m);
}

int samp_radiance_mesh_valid(const scene *s, const samp_radiance_mesh *m, lm_error *err)
{
    if (!m || !m->first || (m->tri_count && (!m->bary || !m->radiance))) {
        lm_fail(err, LM_ERR_INVALID_ARG, "radiance mesh: missing arrays");
        return 0;
    }
    if (m->first[0] != 0 || m->first[s->tri_count] != m->tri_count) {
        lm_fail(err, LM_ERR_INVALID_ARG, "radiance mesh: offsets must run from 0 to its %u triangles",
                m->tri_count);
        return 0;
    }
    for (uint32_t t = 0; t < s->tri_count; ++t)
        if (m->first[t + 1] < m->first[t]) {
            lm_fail(err, LM_ERR_INVALID_ARG, "radiance mesh: offsets decrease at scene triangle %u", t);
            return 0;
        }
    for (size_t i = 0; i < 6 * (size_t)m->tri_count; ++i)
        if (!isfinite(m->bary[i])) {
            lm_fail(err, LM_ERR_INVALID_ARG, "radiance mesh: non-finite barycentric coordinate");
            return 0;
        }
    for (size_t i = 0; i < 9 * (size_t)m->tri_count; ++i)
        if (!isfinite(m->radiance[i]) || m->radiance[i] < 0.0f) {
            lm_fail(err, LM_ERR_INVALID_ARG, "radiance mesh: radiance must be finite and non-negative");
            return 0;
        }
    return 1;
}

lm_result samp_create(const samp_desc *desc, samp_sampler **out, lm_error *err)
{
    *out = NULL;
    if (!desc || !desc->scene) return lm_fail(err, LM_ERR_INVALID_ARG, "samp_create: no scene");
    if ((unsigned)desc->backend >= SAMP_BACKEND_COUNT || (unsigned)desc->gl_platform >= GLCTX_PLATFORM_COUNT ||
        (unsigned)desc->indirect_mode >= SAMP_INDIRECT_MODE_COUNT)
        return lm_fail(err, LM_ERR_INVALID_ARG, "samp_create: unknown back end, GL platform or indirect mode");
    if (desc->direct_res > 4096 || desc->indirect_res > 4096 || desc->direct_rays > (1 << 24) ||
        desc->indirect_rays > (1 << 24))
        return lm_fail(err, LM_ERR_INVALID_ARG, "samp_create: resolution or ray count too large");
    if (!(desc->direct_target_error >= 0.0f && desc->direct_target_error < 1.0f) ||
        !(desc->indirect_target_error >= 0.0f && desc->indirect_target_error < 1.0f))
        return lm_fail(err, LM_ERR_INVALID_ARG, "samp_create: target errors must be in [0, 1)");
    samp_sampler *sp = calloc(1, sizeof *sp);
    if (!sp) return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory creating a sampler");
    sp->desc = samp_desc_defaults(desc);
    sp->s = desc->scene;
    lm_result r = rt_scene_create(&(rt_scene_desc){.scene = sp->s}, &sp->rt, err);
    if (r == LM_OK) {
        samp_choice *be = &sp->be;
        switch (sp->desc.backend) {
        case SAMP_BACKEND_EMBREE:
            r = samp_embree_create(&sp->desc, sp->rt, &be->direct_ops, &be->direct_impl, err);
            snprintf(sp->stats.choice, sizeof sp->stats.choice, "asked for (--sampler embree)");
            break;
        case SAMP_BACKEND_GL:
            r = samp_gl_create(&sp->desc, sp->rt, &be->direct_ops, &be->direct_impl, err);
            snprintf(sp->stats.choice, sizeof sp->stats.choice, "asked for (--sampler gl)");
            break;
        default:
            r = samp_auto_choose(&sp->desc, sp->rt, be, &sp->stats, err);
            break;
        }
        if (r == LM_OK && !be->indirect_ops) {
            be->indirect_ops = be->direct_ops;
            be->indirect_impl = be->direct_impl;
        }
    }
    if (r != LM_OK) {
        samp_destroy(sp);
        return r;
    }
    const samp_backend_ops *d = sp->be.direct_ops, *i = sp->be.indirect_ops;
    sp->stats.backend = d->backend;
    sp->stats.gl_platform = d->gl_platform;
    sp->stats.backend_name = d->name;
    sp->stats.indirect_backend = i->backend;
    sp->stats.indirect_gl_platform = i->gl_platform;
    sp->stats.indirect_backend_name = i->name;
    *out = sp;
    return LM_OK;
}

void samp_destroy(samp_sampler *sp)
{
    if (!sp) return;
    samp_choice *be = &sp->be;
    if (be->indirect_ops && be->indirect_impl && be->indirect_impl != be->direct_impl)
        be->indirect_ops->destroy(be->indirect_impl);
    if (be->direct_ops && be->direct_impl) be->direct_ops->destroy(be->direct_impl);
    rt_scene_destroy(sp->rt);
    free(sp);
}

static int points_valid(const samp_point *pts, uint32_t n)
{
    for (uint32_t i = 0; i < n; ++i)
        for (int k = 0; k < 3; ++k)
            if (!isfinite(pts[i].p[k]) || !isfinite(pts[i].n[k])) return 0;
    return 1;
}

/* Point light: G = V·max(0, cosθ)/r², one shadow ray. */
static void point_light_G(const samp_sampler *sp, const scene_point_light *pl, const samp_point *x, float *G)
{
    const double P[3] = {pl->position[0], pl->position[1], pl->position[2]};
    const double X[3] = {x->p[0], x->p[1], x->p[2]}, N[3] = {x->n[0], x->n[1], x->n[2]};
    double g = samp_point_G(P, X, N);
    if (g > 0.0) {
        float eps = rt_scene_epsilon(sp->rt), origin[3];
        samp_point_origin(sp->s, x, eps, origin);
        if (rt_segment_occluded(sp->rt, origin, NULL, pl->position, NULL, eps)) g = 0.0;
    }
    *G = g < 3.0e38 ? (float)g : 3.0e38f;
}

lm_result samp_direct(samp_sampler *sp, uint32_t light, const samp_point *pts, uint32_t n, float *G,
                      lm_error *err)
{
    if (!sp || (n && (!pts || !G))) return lm_fail(err, LM_ERR_INVALID_ARG, "samp_direct: missing arguments");
    const scene *s = sp->s;
    if (light >= scene_light_count(s))
        return lm_fail(err, LM_ERR_INVALID_ARG, "samp_direct: light %u does not exist (the scene has %u)", light,
                       scene_light_count(s));
    if (!points_valid(pts, n)) return lm_fail(err, LM_ERR_INVALID_ARG, "samp_direct: non-finite point or normal");
    if (n == 0) return LM_OK;
    double t0 = lm_now_seconds();
    lm_result r = LM_OK;
    if (light < s->area_light_count) {
        r = sp->be.direct_ops->direct(sp->be.direct_impl, light, pts, n, G, err);
    } else {
        const scene_point_light *pl = &s->point_lights[light - s->area_light_count];
        for (uint32_t i = 0; i < n; ++i) point_light_G(sp, pl, &pts[i], &G[i]);
    }
    sp->stats.direct_seconds += lm_now_seconds() - t0;
    if (r == LM_OK) sp->stats.direct_samples += n;
    return r;
}

lm_result samp_indirect(samp_sampler *sp, const samp_radiance_mesh *mesh, const samp_point *pts, uint32_t n,
                        float *E, lm_error *err)
{
    if (!sp || (n && (!pts || !E))) return lm_fail(err, LM_ERR_INVALID_ARG, "samp_indirect: missing arguments");
    if (!samp_radiance_mesh_valid(sp->s, mesh, err)) return LM_ERR_INVALID_ARG;
    if (!points_valid(pts, n)) return lm_fail(err, LM_ERR_INVALID_ARG, "samp_indirect: non-finite point or normal");
    if (n == 0) return LM_OK;
    double t0 = lm_now_seconds();
    lm_result r = sp->be.indirect_ops->indirect(sp->be.indirect_impl, mesh, pts, n, E, err);
    sp->stats.indirect_seconds += lm_now_seconds() - t0;
    if (r == LM_OK) sp->stats.indirect_samples += n;
    return r;
}

void samp_get_stats(const samp_sampler *sp, samp_stats *out) { *out = sp->stats; }
