/* samp.c — the sampler front end (samp.h): argument checks, point lights, call
 * statistics, and dispatch to a back end (samp_embree.c, samp_gl.c). The choice
 * SAMP_BACKEND_AUTO is made in samp_auto.c. */
#include "samp.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "analytic.h"
#include "samp_internal.h"
#include "vecmath.h"

struct samp_sampler {
    samp_desc desc;            /* defaults filled in */
    const scene *s;
    rt_scene *rt;              /* owned; shared with the back end (read-only) */
    const samp_backend_ops *ops;
    void *impl;
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

const char *samp_gl_platform_name(samp_gl_platform p)
{
    switch (p) {
    case SAMP_GL_DEFAULT:
    case SAMP_GL_EGL: return "egl";
    case SAMP_GL_OSMESA: return "osmesa";
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

int samp_gl_platform_from_name(const char *name, samp_gl_platform *out)
{
    for (int p = SAMP_GL_EGL; p < SAMP_GL_PLATFORM_COUNT && name; ++p)
        if (strcmp(name, samp_gl_platform_name((samp_gl_platform)p)) == 0) {
            *out = (samp_gl_platform)p;
            return 1;
        }
    return 0;
}

samp_desc samp_desc_defaults(const samp_desc *desc)
{
    samp_desc d = *desc;
    if (d.gl_platform == SAMP_GL_DEFAULT) d.gl_platform = SAMP_GL_EGL;
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
    if ((unsigned)desc->backend >= SAMP_BACKEND_COUNT || (unsigned)desc->gl_platform >= SAMP_GL_PLATFORM_COUNT ||
        (unsigned)desc->indirect_mode >= SAMP_INDIRECT_MODE_COUNT)
        return lm_fail(err, LM_ERR_INVALID_ARG, "samp_create: unknown back end, GL platform or indirect mode");
    if (desc->direct_res > 4096 || desc->indirect_res > 4096 || desc->direct_rays > (1 << 24) ||
        desc->indirect_rays > (1 << 24))
        return lm_fail(err, LM_ERR_INVALID_ARG, "samp_create: resolution or ray count too large");
    samp_sampler *sp = calloc(1, sizeof *sp);
    if (!sp) return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory creating a sampler");
    sp->desc = samp_desc_defaults(desc);
    sp->s = desc->scene;
    lm_result r = rt_scene_create(&(rt_scene_desc){.scene = sp->s}, &sp->rt, err);
    if (r == LM_OK) {
        switch (sp->desc.backend) {
        case SAMP_BACKEND_EMBREE:
            r = samp_embree_create(&sp->desc, sp->rt, &sp->ops, &sp->impl, err);
            snprintf(sp->stats.choice, sizeof sp->stats.choice, "asked for (--sampler embree)");
            break;
        case SAMP_BACKEND_GL:
            r = samp_gl_create(&sp->desc, sp->rt, &sp->ops, &sp->impl, err);
            snprintf(sp->stats.choice, sizeof sp->stats.choice, "asked for (--sampler gl)");
            break;
        default:
            r = samp_auto_choose(&sp->desc, sp->rt, &sp->ops, &sp->impl, &sp->stats, err);
            break;
        }
    }
    if (r != LM_OK) {
        samp_destroy(sp);
        return r;
    }
    sp->stats.backend = strncmp(sp->ops->name, "gl", 2) == 0 ? SAMP_BACKEND_GL : SAMP_BACKEND_EMBREE;
    sp->stats.backend_name = sp->ops->name;
    *out = sp;
    return LM_OK;
}

void samp_destroy(samp_sampler *sp)
{
    if (!sp) return;
    if (sp->ops && sp->impl) sp->ops->destroy(sp->impl);
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
        r = sp->ops->direct(sp->impl, light, pts, n, G, err);
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
    lm_result r = sp->ops->indirect(sp->impl, mesh, pts, n, E, err);
    sp->stats.indirect_seconds += lm_now_seconds() - t0;
    if (r == LM_OK) sp->stats.indirect_samples += n;
    return r;
}

void samp_get_stats(const samp_sampler *sp, samp_stats *out) { *out = sp->stats; }
