/* samp.c — the sampler front end (samp.h): argument checks, point lights, call
 * statistics, and dispatch to a back end (samp_embree.c, samp_gl.c). The choice
 * SAMP_BACKEND_AUTO is made in samp_auto.c. The top of sampling/'s samplers:
 * it calls the back ends and they never call it (what they share is in
 * samp_geom.c). */
#include "sampling/samp.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "sampling/analytic.h"
#include "sampling/samp_internal.h"

struct samp_sampler {
    samp_desc desc;            /* defaults filled in */
    const scene *s;
    const rt_scene *rt;        /* shared with the back ends (read-only) */
    rt_scene *own_rt;          /* rt when this sampler built it (desc.rt NULL), else NULL */
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

float samp_point_eps_rt(const rt_scene *rt, const samp_point *x)
{
    return x->tri_plus_one ? rt_scene_tri_epsilon(rt, x->tri_plus_one - 1) : rt_scene_epsilon(rt);
}

float samp_point_epsilon(const samp_sampler *sp, const samp_point *x) { return samp_point_eps_rt(sp->rt, x); }

int samp_points_parted(const samp_sampler *sp, const samp_point *a, const samp_point *b)
{
    const float ea = samp_point_eps_rt(sp->rt, a), eb = samp_point_eps_rt(sp->rt, b), eps = fmaxf(ea, eb);
    float oa[3], ob[3], dir[3], len = 0.0f;
    samp_point_origin(sp->s, a, ea, oa);
    samp_point_origin(sp->s, b, eb, ob);
    for (int k = 0; k < 3; ++k) {
        dir[k] = ob[k] - oa[k];
        len += dir[k] * dir[k];
    }
    len = sqrtf(len);
    if (!(len > 2.0f * eps)) return 0;
    for (int k = 0; k < 3; ++k) dir[k] /= len;
    return rt_occluded(sp->rt, oa, dir, 0.0f, len);
}

int samp_point_pull_inside(const samp_sampler *sp, samp_point *x)
{
    const scene *s = sp->s;
    if (x->tri_plus_one == 0 || x->tri_plus_one > s->tri_count) return 0;
    const uint32_t *v = s->tris[x->tri_plus_one - 1].v;
    const float eps = samp_point_eps_rt(sp->rt, x);
    float org[3], to[3], dir[3], len = 0.0f;
    samp_point_origin(s, x, eps, org);
    for (int k = 0; k < 3; ++k) {
        float c = (s->positions[3 * (size_t)v[0] + (size_t)k] + s->positions[3 * (size_t)v[1] + (size_t)k] +
                   s->positions[3 * (size_t)v[2] + (size_t)k]) / 3.0f;
        to[k] = c + eps * x->n[k]; /* the centroid, lifted as the origin is */
        dir[k] = to[k] - org[k];
        len += dir[k] * dir[k];
    }
    len = sqrtf(len);
    if (!(len > 8.0f * eps)) return 0;
    for (int k = 0; k < 3; ++k) dir[k] /= len;
    /* Only a tall blocker is a wall between rooms: the same way lifted by a tenth
     * of its length must be blocked too (a picture frame on a wall, a skirting
     * board on a floor, is passed over). */
    {
        float o[3];
        for (int k = 0; k < 3; ++k) o[k] = org[k] + 0.1f * len * x->n[k];
        if (!rt_occluded(sp->rt, o, dir, 0.0f, len)) return 0;
    }
    /* Past every blocking surface in turn (a wall has two faces), at most 8. */
    float moved = 0.0f;
    for (int pass = 0; pass < 8; ++pass) {
        float o[3];
        for (int k = 0; k < 3; ++k) o[k] = org[k] + dir[k] * moved;
        rt_hit h;
        if (!rt_intersect(sp->rt, o, dir, 0.0f, len - moved, &h) || h.tri == x->tri_plus_one - 1) break;
        float next = moved + h.t + 4.0f * eps;
        if (next >= len) break;
        moved = next;
    }
    if (moved == 0.0f) return 0;
    for (int k = 0; k < 3; ++k) x->p[k] += dir[k] * moved;
    return 1;
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

lm_result samp_radiance_mesh_prepare(const scene *s, const samp_radiance_mesh *m, samp_radiance_index *ix,
                                     lm_error *err)
{
    memset(ix, 0, sizeof *ix);
    if (!s) return lm_fail(err, LM_ERR_INVALID_ARG, "samp_radiance_mesh_prepare: no scene");
    if (!samp_radiance_mesh_valid(s, m, err)) return LM_ERR_INVALID_ARG;
    samp_radiance_index_build(s, m, ix); /* without it (no memory): linear search */
    ix->checked = 1;
    return LM_OK;
}

/* A mesh a call may use: prepared (checked once) or checked now. */
static int mesh_ok(const samp_sampler *sp, const samp_radiance_mesh *mesh, lm_error *err)
{
    if (mesh && mesh->index && mesh->index->checked) return 1;
    return samp_radiance_mesh_valid(sp->s, mesh, err);
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
    lm_result r = LM_OK;
    if (desc->rt) {
        sp->rt = desc->rt;
    } else {
        r = rt_scene_create(&(rt_scene_desc){.scene = sp->s}, &sp->own_rt, err);
        sp->rt = sp->own_rt;
    }
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
    rt_scene_destroy(sp->own_rt);
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
        float eps = samp_point_eps_rt(sp->rt, x), origin[3];
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
    if (!mesh_ok(sp, mesh, err)) return LM_ERR_INVALID_ARG;
    if (!points_valid(pts, n)) return lm_fail(err, LM_ERR_INVALID_ARG, "samp_indirect: non-finite point or normal");
    if (n == 0) return LM_OK;
    double t0 = lm_now_seconds();
    lm_result r = sp->be.indirect_ops->indirect(sp->be.indirect_impl, mesh, pts, n, E, err);
    sp->stats.indirect_seconds += lm_now_seconds() - t0;
    if (r == LM_OK) sp->stats.indirect_samples += n;
    return r;
}

lm_result samp_indirect_guided(samp_sampler *sp, const samp_radiance_mesh *mesh, const samp_point *pts, uint32_t n,
                               uint32_t pass, uint32_t scale, const samp_guide *guide, float *E, float *std_err,
                               lm_error *err)
{
    if (!sp || (n && (!pts || !E || !std_err)))
        return lm_fail(err, LM_ERR_INVALID_ARG, "samp_indirect_noise: missing arguments");
    if (scale < 1 || scale > 256) return lm_fail(err, LM_ERR_INVALID_ARG, "samp_indirect_noise: scale %u (1..256)", scale);
    if (guide) {
        const uint32_t k = (uint32_t)lround(sqrt((double)guide->rays));
        if (!guide->stratum || k < 2 || k > 64 || k * k != guide->rays)
            return lm_fail(err, LM_ERR_INVALID_ARG, "samp_indirect_guided: a guide needs its strata, k² rays (k 2..64)");
    }
    if (!sp->be.indirect_ops->indirect_noise) {
        lm_result r = samp_indirect(sp, mesh, pts, n, E, err);
        if (r == LM_OK) memset(std_err, 0, 3 * (size_t)n * sizeof *std_err);
        return r;
    }
    if (!mesh_ok(sp, mesh, err)) return LM_ERR_INVALID_ARG;
    if (!points_valid(pts, n)) return lm_fail(err, LM_ERR_INVALID_ARG, "samp_indirect_noise: non-finite point or normal");
    if (n == 0) return LM_OK;
    double t0 = lm_now_seconds();
    lm_result r =
        sp->be.indirect_ops->indirect_noise(sp->be.indirect_impl, mesh, pts, n, pass, scale, guide, E, std_err, err);
    sp->stats.indirect_seconds += lm_now_seconds() - t0;
    if (r == LM_OK) sp->stats.indirect_samples += n;
    return r;
}

lm_result samp_indirect_noise(samp_sampler *sp, const samp_radiance_mesh *mesh, const samp_point *pts, uint32_t n,
                              uint32_t pass, uint32_t scale, float *E, float *std_err, lm_error *err)
{
    return samp_indirect_guided(sp, mesh, pts, n, pass, scale, NULL, E, std_err, err);
}

uint32_t samp_direct_rays(const samp_sampler *sp) { return (uint32_t)sp->desc.direct_rays; }

uint32_t samp_indirect_rays(const samp_sampler *sp)
{
    return sp->be.indirect_ops->indirect_rays ? sp->be.indirect_ops->indirect_rays(sp->be.indirect_impl) : 0;
}

lm_result samp_indirect_sources(samp_sampler *sp, const samp_radiance_mesh *mesh, const samp_point *pts, uint32_t n,
                                const samp_source_hits *out, lm_error *err)
{
    if (!sp || !out || (n && (!pts || !out->count || !out->tri || !out->weight)))
        return lm_fail(err, LM_ERR_INVALID_ARG, "samp_indirect_sources: missing arguments");
    if (out->rays < 1 || out->rays > 4096)
        return lm_fail(err, LM_ERR_INVALID_ARG, "samp_indirect_sources: %u rays a point (1..4096)", out->rays);
    if (!mesh_ok(sp, mesh, err)) return LM_ERR_INVALID_ARG;
    if (!points_valid(pts, n))
        return lm_fail(err, LM_ERR_INVALID_ARG, "samp_indirect_sources: non-finite point or normal");
    /* The cache's pilot rays are indirect work: timed as such (not counted as samples). */
    double t0 = lm_now_seconds();
    samp_sources_trace(sp->s, sp->rt, sp->desc.seed, sp->desc.threads, mesh, pts, n, out);
    sp->stats.indirect_seconds += lm_now_seconds() - t0;
    return LM_OK;
}

lm_result samp_surface_hits_trace(samp_sampler *sp, const samp_point *pts, uint32_t n, const samp_surface_hits *out,
                                  lm_error *err)
{
    if (!sp || !out || (n && (!pts || !out->count || !out->tri || !out->bary)))
        return lm_fail(err, LM_ERR_INVALID_ARG, "samp_surface_hits_trace: missing arguments");
    uint32_t k = (uint32_t)floor(sqrt((double)out->rays));
    if (out->rays < 1 || out->rays > 4096 || k * k != out->rays)
        return lm_fail(err, LM_ERR_INVALID_ARG, "samp_surface_hits_trace: %u rays a point (a square, 1..4096)", out->rays);
    if (!points_valid(pts, n))
        return lm_fail(err, LM_ERR_INVALID_ARG, "samp_surface_hits_trace: non-finite point or normal");
    double t0 = lm_now_seconds();
    samp_surface_hits_run(sp->s, sp->rt, sp->desc.seed, sp->desc.threads, pts, n, out);
    sp->stats.indirect_seconds += lm_now_seconds() - t0;
    return LM_OK;
}

/* The checks samp_lobe_visibility and samp_lobe_gather share; their side in *side. */
static lm_result lobe_args_ok(const char *fn, const samp_point *pts, const float *wo,
                              const float *exponent, uint32_t n, uint32_t rays, uint32_t *side, lm_error *err)
{
    *side = (uint32_t)floor(sqrt((double)rays));
    if (rays < 1 || rays > 4096 || *side * *side != rays)
        return lm_fail(err, LM_ERR_INVALID_ARG, "%s: %u rays a point (a square, 1..4096)", fn, rays);
    if (!points_valid(pts, n)) return lm_fail(err, LM_ERR_INVALID_ARG, "%s: non-finite point or normal", fn);
    for (uint32_t i = 0; i < n; ++i)
        if (!(exponent[i] >= 0.0f) || !isfinite(exponent[i]) || !isfinite(wo[3 * i]) || !isfinite(wo[3 * i + 1]) ||
            !isfinite(wo[3 * i + 2]))
            return lm_fail(err, LM_ERR_INVALID_ARG, "%s: a bad exponent or view direction", fn);
    return LM_OK;
}

lm_result samp_lobe_visibility(samp_sampler *sp, uint32_t light, const samp_point *pts, const float *wo,
                               const float *exponent, uint32_t n, uint32_t rays, float *V, lm_error *err)
{
    if (!sp || (n && (!pts || !wo || !exponent || !V)))
        return lm_fail(err, LM_ERR_INVALID_ARG, "samp_lobe_visibility: missing arguments");
    if (light >= sp->s->area_light_count)
        return lm_fail(err, LM_ERR_INVALID_ARG, "samp_lobe_visibility: %u is not an area light", light);
    uint32_t side;
    lm_result r = lobe_args_ok("samp_lobe_visibility", pts, wo, exponent, n, rays, &side, err);
    if (r != LM_OK) return r;
    double t0 = lm_now_seconds();
    samp_lobe_run(sp->s, sp->rt, light, pts, wo, exponent, n, side, V);
    sp->stats.direct_seconds += lm_now_seconds() - t0;
    return LM_OK;
}

lm_result samp_lobe_gather(samp_sampler *sp, const samp_radiance_mesh *mesh, const samp_point *pts, const float *wo,
                           const float *exponent, uint32_t n, uint32_t rays, uint32_t pass, float *L, float *std_err,
                           lm_error *err)
{
    if (!sp || (n && (!pts || !wo || !exponent || !L)))
        return lm_fail(err, LM_ERR_INVALID_ARG, "samp_lobe_gather: missing arguments");
    if (!mesh_ok(sp, mesh, err)) return LM_ERR_INVALID_ARG;
    uint32_t side;
    lm_result r = lobe_args_ok("samp_lobe_gather", pts, wo, exponent, n, rays, &side, err);
    if (r != LM_OK || n == 0) return r;
    double t0 = lm_now_seconds();
    samp_radiance_index own = {0}; /* a mesh not prepared: indexed for this call (linear search without memory) */
    const samp_radiance_index *ix = mesh->index;
    if (!ix) {
        samp_radiance_index_build(sp->s, mesh, &own);
        ix = &own;
    }
    samp_lobe_gather_run(sp->s, sp->rt, mesh, ix, pts, wo, exponent, n, side, pass, L, std_err);
    samp_radiance_index_free(&own);
    sp->stats.indirect_seconds += lm_now_seconds() - t0;
    sp->stats.glossy_samples += n;
    return LM_OK;
}

void samp_get_stats(const samp_sampler *sp, samp_stats *out) { *out = sp->stats; }
