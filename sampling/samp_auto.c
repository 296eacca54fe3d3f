/* samp_auto.c — SAMP_BACKEND_AUTO: pick the back end by measurement, never by
 * assumption (issue "Irradiance sampling", item 7).
 *
 * A short calibration on the scene itself: up to CAL_POINTS receivers drawn on
 * its triangles (by area, facing the first area light), a reference G from
 * Embree with CAL_REF_RAYS rays, then
 *   - the GL back end at the asked resolution: its cost per sample (second run,
 *     after warm-up) and its mean relative error against the reference;
 *   - Embree at growing ray counts until its error is at most GL's: its cost there.
 * The cheaper at equal error wins; Embree keeps the ray count it needed. The
 * numbers go into samp_stats.choice. The choice is made on direct samples, which
 * are most of the work (the paper: 26,000 direct against 9,000 indirect).
 * When GL cannot be created here, or the scene has no area light to measure on,
 * Embree is used and the reason is recorded.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "ref_shading.h"
#include "samp_internal.h"
#include "vecmath.h"

enum { CAL_POINTS = 48, CAL_TRIES = 4096, CAL_REF_RAYS = 4096 };

static const int embree_ladder[] = {16, 36, 64, 144, 256, 576, 1024, 2304, 4096};

/* Receivers on the scene's triangles, by area, with the first area light above
 * their horizon. Returns how many were found. */
static uint32_t calibration_points(const scene *s, samp_point *pts)
{
    double total = 0.0;
    for (uint32_t t = 0; t < s->tri_count; ++t) total += s->tri_areas[t];
    ref_rng g;
    ref_rng_seed(&g, 0x5eed, 0, 0);
    uint32_t n = 0;
    for (int tries = 0; tries < CAL_TRIES && n < CAL_POINTS; ++tries) {
        double pick = ref_rng_float(&g) * total, acc = 0.0;
        uint32_t t = 0;
        for (; t + 1 < s->tri_count; ++t) {
            acc += s->tri_areas[t];
            if (acc > pick) break;
        }
        if (s->tris[t].light >= 0) continue;
        float u = ref_rng_float(&g), v = ref_rng_float(&g);
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
        if (samp_area_light_unoccluded(s, 0, x.p, x.n) > 0.0) pts[n++] = x;
    }
    return n;
}

/* Cost (seconds per sample, second of two runs) and mean relative error. */
static lm_result measure(const samp_backend_ops *ops, void *impl, const samp_point *pts, uint32_t n,
                         const float *ref, double *cost, double *error, lm_error *err)
{
    float G[CAL_POINTS];
    lm_result r = ops->direct(impl, 0, pts, n, G, err);
    if (r != LM_OK) return r;
    double t0 = lm_now_seconds();
    r = ops->direct(impl, 0, pts, n, G, err);
    if (r != LM_OK) return r;
    *cost = (lm_now_seconds() - t0) / n;
    double num = 0.0, den = 0.0;
    for (uint32_t i = 0; i < n; ++i) {
        num += fabs((double)G[i] - ref[i]);
        den += ref[i];
    }
    *error = den > 0.0 ? num / den : 0.0;
    return LM_OK;
}

lm_result samp_auto_choose(const samp_desc *desc, const rt_scene *rt, const samp_backend_ops **ops, void **impl,
                           samp_stats *stats, lm_error *err)
{
    const scene *s = desc->scene;
    lm_error gl_err = {{0}};
    const samp_backend_ops *gl_ops = NULL;
    void *gl_impl = NULL;
    if (samp_gl_create(desc, rt, &gl_ops, &gl_impl, &gl_err) != LM_OK) {
        snprintf(stats->choice, sizeof stats->choice, "auto: embree, GL unavailable (%.200s)", gl_err.msg);
        return samp_embree_create(desc, rt, ops, impl, err);
    }
    samp_point pts[CAL_POINTS];
    uint32_t n = s->area_light_count ? calibration_points(s, pts) : 0;
    if (n < 8) {
        gl_ops->destroy(gl_impl);
        snprintf(stats->choice, sizeof stats->choice, "auto: embree, no receivers of an area light to calibrate on");
        return samp_embree_create(desc, rt, ops, impl, err);
    }

    /* Reference values. */
    float ref[CAL_POINTS];
    samp_desc rd = *desc;
    rd.direct_rays = CAL_REF_RAYS;
    const samp_backend_ops *e_ops;
    void *e_impl;
    lm_result r = samp_embree_create(&rd, rt, &e_ops, &e_impl, err);
    if (r == LM_OK) {
        r = e_ops->direct(e_impl, 0, pts, n, ref, err);
        e_ops->destroy(e_impl);
    }
    double gl_cost = 0.0, gl_error = 0.0;
    if (r == LM_OK) r = measure(gl_ops, gl_impl, pts, n, ref, &gl_cost, &gl_error, err);
    if (r != LM_OK) {
        gl_ops->destroy(gl_impl);
        return r;
    }

    /* Embree up the ladder until it is as accurate as GL. */
    int rays = embree_ladder[0];
    double e_cost = INFINITY, e_error = INFINITY;
    for (size_t i = 0; i < sizeof embree_ladder / sizeof *embree_ladder; ++i) {
        rd.direct_rays = embree_ladder[i];
        if ((r = samp_embree_create(&rd, rt, &e_ops, &e_impl, err)) != LM_OK) break;
        r = measure(e_ops, e_impl, pts, n, ref, &e_cost, &e_error, err);
        e_ops->destroy(e_impl);
        if (r != LM_OK) break;
        rays = embree_ladder[i];
        if (e_error <= gl_error) break;
    }
    if (r != LM_OK) {
        gl_ops->destroy(gl_impl);
        return r;
    }
    int gl_wins = gl_cost < e_cost || e_error > gl_error;
    snprintf(stats->choice, sizeof stats->choice,
             "auto: %s; direct sample on %u points: %s %dx%d %.1f us at %.2g%% error, embree %d rays %.1f us at "
             "%.2g%% error",
             gl_wins ? gl_ops->name : "embree", n, gl_ops->name, desc->direct_res, desc->direct_res, gl_cost * 1e6,
             100.0 * gl_error, rays, e_cost * 1e6, 100.0 * e_error);
    if (gl_wins) {
        *ops = gl_ops;
        *impl = gl_impl;
        return LM_OK;
    }
    gl_ops->destroy(gl_impl);
    rd.direct_rays = rays;
    return samp_embree_create(&rd, rt, ops, impl, err);
}
