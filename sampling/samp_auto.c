/* samp_auto.c — SAMP_BACKEND_AUTO: pick the back ends by measurement, never by
 * assumption (issue "Irradiance sampling", item 7), for direct and for indirect
 * samples separately (bench_sampling on this 2-core machine without a GPU: GL
 * wins direct at equal error, Embree wins indirect by an order of magnitude).
 *
 * A short calibration on the scene itself:
 *   direct    receivers in the penumbra of the first area light (drawn by area
 *             on its triangles; fully lit points are exact for every back end with
 *             the control variate, so they cannot tell the back ends apart), a
 *             reference from Embree with CAL_DIRECT_REF_RAYS rays; cost is
 *             measured on receivers drawn without that filter (the mix a cache
 *             sees), error on the penumbra receivers;
 *   indirect  receivers on the scene, the coarse radiance mesh of
 *             samp_coarse_mesh_build, a reference from Embree with
 *             CAL_INDIRECT_REF_RAYS rays.
 * For each: GL at the asked resolution, then Embree up a ladder of ray counts
 * until its mean relative error is at most the goal: the error the client
 * tolerates (samp_desc.*_target_error) or, when it names none, GL's own (equal
 * error). The cheaper of the two that reach the goal wins, and Embree keeps the
 * ray counts it needed. The numbers go into
 * samp_stats.choice. When GL cannot be created here, Embree serves both and the
 * reason is recorded.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "sampling/ref_shading.h"
#include "sampling/samp_internal.h"
#include "sampling/samp_record.h"
#include "src/base/vecmath.h"

enum {
    CAL_POINTS = 24,
    CAL_TRIES = 20000,
    CAL_DIRECT_REF_RAYS = 65536,
    CAL_INDIRECT_POINTS = 12,
    CAL_INDIRECT_REF_RAYS = 65536,
    /* Indirect samples are calibrated on a source of the size the cache feeds
     * them (mesh/cache/cache_source.c, CACHE_RMESH_TRIANGLES): GL's cost grows with it, Embree's
     * barely. With one triangle per scene triangle GL won on the Cornell box and
     * then cost 1.4 ms per sample in the cache against Embree's 0.22 ms. */
    CAL_SOURCE_TRIANGLES = 8192
};

static const int direct_ladder[] = {16, 36, 64, 144, 256, 576, 1024, 2304, 4096, 9216, 16384};
static const int indirect_ladder[] = {64, 144, 256, 576, 1024, 2304, 4096, 9216, 16384};

typedef struct calib {
    const scene *s;
    const rt_scene *rt;
    samp_desc desc;
    samp_point pts[CAL_POINTS];      /* error is measured here */
    samp_point timing[CAL_POINTS];   /* cost is measured here */
    float ref[3 * CAL_POINTS];
    uint32_t n, n_timing;
    const samp_radiance_mesh *mesh;  /* NULL: direct */
} calib;

/* Cost (seconds per sample, on c->timing, the second of two runs) and mean
 * relative error (on c->pts against c->ref, summed over channels). */
static lm_result measure(const calib *c, const samp_backend_ops *ops, void *impl, double *cost, double *error,
                         lm_error *err)
{
    float out[3 * CAL_POINTS];
    lm_result r = LM_OK;
    double t0 = 0.0;
    for (int run = 0; run < 2 && r == LM_OK; ++run) {
        t0 = lm_now_seconds();
        r = c->mesh ? ops->indirect(impl, c->mesh, c->timing, c->n_timing, out, err)
                    : ops->direct(impl, 0, c->timing, c->n_timing, out, err);
    }
    if (r != LM_OK) return r;
    *cost = (lm_now_seconds() - t0) / c->n_timing;
    r = c->mesh ? ops->indirect(impl, c->mesh, c->pts, c->n, out, err) : ops->direct(impl, 0, c->pts, c->n, out, err);
    if (r != LM_OK) return r;
    int ch = c->mesh ? 3 : 1;
    double num = 0.0, den = 0.0;
    for (uint32_t i = 0; i < c->n * (uint32_t)ch; ++i) {
        num += fabs((double)out[i] - c->ref[i]);
        den += c->ref[i];
    }
    *error = den > 0.0 ? num / den : 0.0;
    return LM_OK;
}

/* Embree with `rays` (direct or indirect, as c says) created, run, destroyed. */
static lm_result measure_embree(const calib *c, int rays, double *cost, double *error, lm_error *err)
{
    samp_desc d = c->desc;
    if (c->mesh)
        d.indirect_rays = rays;
    else
        d.direct_rays = rays;
    const samp_backend_ops *ops;
    void *impl;
    lm_result r = samp_embree_create(&d, c->rt, &ops, &impl, err);
    if (r != LM_OK) return r;
    r = measure(c, ops, impl, cost, error, err);
    ops->destroy(impl);
    return r;
}

typedef struct verdict {
    int gl_wins;
    int rays;                 /* Embree's ray count at GL's error (or its best) */
    double gl_cost, gl_error, e_cost, e_error;
} verdict;

/* GL at the asked resolution against Embree up the ladder. The error both must
 * reach is `target` when the client named one, else GL's own (equal error).
 * Embree stops at the first rung that reaches it; the cheaper of the two that
 * reach it wins; if neither does, the more accurate. */
static lm_result compare(const calib *c, const samp_backend_ops *gl_ops, void *gl_impl, const int *ladder,
                         size_t ladder_n, float target, verdict *v, lm_error *err)
{
    lm_result r = measure(c, gl_ops, gl_impl, &v->gl_cost, &v->gl_error, err);
    if (r != LM_OK) return r;
    double goal = target > 0.0f ? target : v->gl_error;
    v->e_cost = INFINITY;
    v->e_error = INFINITY;
    for (size_t i = 0; i < ladder_n; ++i) {
        if ((r = measure_embree(c, ladder[i], &v->e_cost, &v->e_error, err)) != LM_OK) return r;
        v->rays = ladder[i];
        if (v->e_error <= goal) break;
    }
    int gl_ok = v->gl_error <= goal, e_ok = v->e_error <= goal;
    if (gl_ok && e_ok)
        v->gl_wins = v->gl_cost < v->e_cost;
    else if (gl_ok || e_ok)
        v->gl_wins = gl_ok;
    else
        v->gl_wins = v->gl_error < v->e_error;
    return LM_OK;
}

static lm_result calibrate_direct(calib *c, const double *cdf, lm_rng *g, lm_error *err)
{
    samp_desc probe_d = c->desc;
    probe_d.direct_rays = 256;
    const samp_backend_ops *ops;
    void *impl;
    lm_result r = samp_embree_create(&probe_d, c->rt, &ops, &impl, err);
    if (r != LM_OK) return r;
    c->n = c->n_timing = 0;
    for (int tries = 0; tries < CAL_TRIES && c->n < CAL_POINTS; ++tries) {
        samp_point x = samp_random_receiver(c->s, cdf, g);
        double g0 = samp_area_light_unoccluded(c->s, 0, x.p, x.n);
        if (!(g0 > 0.0)) continue;
        if (c->n_timing < CAL_POINTS) c->timing[c->n_timing++] = x;
        float G;
        if ((r = ops->direct(impl, 0, &x, 1, &G, err)) != LM_OK) break;
        if (G > 0.02 * g0 && G < 0.98 * g0) c->pts[c->n++] = x;
    }
    ops->destroy(impl);
    if (r != LM_OK) return r;
    /* A scene without penumbra: every back end is exact; calibrate on lit points. */
    for (uint32_t i = 0; c->n < 8 && i < c->n_timing; ++i) c->pts[c->n++] = c->timing[i];
    if (c->n == 0) return LM_OK;
    samp_desc rd = c->desc;
    rd.direct_rays = CAL_DIRECT_REF_RAYS;
    if ((r = samp_embree_create(&rd, c->rt, &ops, &impl, err)) != LM_OK) return r;
    r = ops->direct(impl, 0, c->pts, c->n, c->ref, err);
    ops->destroy(impl);
    return r;
}

static lm_result calibrate_indirect(calib *c, const double *cdf, lm_rng *g, lm_error *err)
{
    c->n = c->n_timing = CAL_INDIRECT_POINTS;
    for (uint32_t i = 0; i < c->n; ++i) {
        c->pts[i] = samp_random_receiver(c->s, cdf, g);
        c->timing[i] = samp_random_receiver(c->s, cdf, g);
    }
    samp_desc rd = c->desc;
    rd.indirect_rays = CAL_INDIRECT_REF_RAYS;
    const samp_backend_ops *ops;
    void *impl;
    lm_result r = samp_embree_create(&rd, c->rt, &ops, &impl, err);
    if (r != LM_OK) return r;
    r = ops->indirect(impl, c->mesh, c->pts, c->n, c->ref, err);
    ops->destroy(impl);
    return r;
}

lm_result samp_auto_choose(const samp_desc *desc, const rt_scene *rt, samp_choice *out, samp_stats *stats,
                           lm_error *err)
{
    const scene *s = desc->scene;
    memset(out, 0, sizeof *out);
    lm_error gl_err = {{0}};
    const samp_backend_ops *gl_ops = NULL;
    void *gl_impl = NULL;
    if (samp_gl_create(desc, rt, &gl_ops, &gl_impl, &gl_err) != LM_OK) {
        snprintf(stats->choice, sizeof stats->choice, "auto: embree for both, GL unavailable (%.400s)", gl_err.msg);
        return samp_embree_create(desc, rt, &out->direct_ops, &out->direct_impl, err);
    }
    double t0 = lm_now_seconds();
    calib *c = calloc(1, sizeof *c);
    double *cdf = samp_area_cdf(s);
    samp_coarse_mesh cm = {0};
    lm_result r = c && cdf ? LM_OK : lm_fail(err, LM_ERR_NO_MEMORY, "out of memory calibrating the samplers");
    verdict vd = {.gl_wins = 0, .rays = desc->direct_rays}, vi = {.gl_wins = 0, .rays = desc->indirect_rays};
    int have_direct = 0;
    if (r == LM_OK) {
        lm_rng g;
        lm_rng_seed(&g, 0x5eed, 0, 0);
        c->s = s;
        c->rt = rt;
        c->desc = *desc;
        if (s->area_light_count) {
            r = calibrate_direct(c, cdf, &g, err);
            if (r == LM_OK && c->n > 0) {
                r = compare(c, gl_ops, gl_impl, direct_ladder, sizeof direct_ladder / sizeof *direct_ladder,
                            desc->direct_target_error, &vd, err);
                have_direct = r == LM_OK;
            }
        }
        if (r == LM_OK) r = samp_coarse_mesh_build(s, CAL_SOURCE_TRIANGLES, &cm, err);
        if (r == LM_OK) {
            c->mesh = &cm.mesh;
            r = calibrate_indirect(c, cdf, &g, err);
        }
        if (r == LM_OK)
            r = compare(c, gl_ops, gl_impl, indirect_ladder, sizeof indirect_ladder / sizeof *indirect_ladder,
                        desc->indirect_target_error, &vi, err);
    }
    samp_coarse_mesh_free(&cm);
    free(cdf);
    free(c);
    if (r != LM_OK) {
        gl_ops->destroy(gl_impl);
        return r;
    }

    /* One Embree object serves whatever Embree won, with the ray counts it needed. */
    samp_desc ed = *desc;
    ed.direct_rays = have_direct ? vd.rays : desc->direct_rays;
    ed.indirect_rays = vi.rays;
    const samp_backend_ops *e_ops = NULL;
    void *e_impl = NULL;
    if ((!vd.gl_wins || !vi.gl_wins) && (r = samp_embree_create(&ed, rt, &e_ops, &e_impl, err)) != LM_OK) {
        gl_ops->destroy(gl_impl);
        return r;
    }
    out->direct_ops = vd.gl_wins ? gl_ops : e_ops;
    out->direct_impl = vd.gl_wins ? gl_impl : e_impl;
    out->indirect_ops = vi.gl_wins ? gl_ops : e_ops;
    out->indirect_impl = vi.gl_wins ? gl_impl : e_impl;

    char direct_text[200];
    if (have_direct)
        snprintf(direct_text, sizeof direct_text,
                 "direct %s for %s (%s %dx%d: %.1f us at %.2g%% error; embree %d rays: %.1f us at %.2g%%)",
                 out->direct_ops->name,
                 desc->direct_target_error > 0.0f ? "the asked error" : "equal error", gl_ops->name,
                 desc->direct_res, desc->direct_res,
                 vd.gl_cost * 1e6, 100.0 * vd.gl_error, vd.rays, vd.e_cost * 1e6, 100.0 * vd.e_error);
    else
        snprintf(direct_text, sizeof direct_text, "direct embree (no area light to calibrate on)");
    snprintf(stats->choice, sizeof stats->choice,
             "auto, calibrated in %.2f s: %s; indirect %s for %s (%s %dx%d hemicube: %.1f us at %.2g%% error; "
             "embree %d rays: %.1f us at %.2g%%)",
             lm_now_seconds() - t0, direct_text, out->indirect_ops->name,
             desc->indirect_target_error > 0.0f ? "the asked error" : "equal error", gl_ops->name,
             desc->indirect_res, desc->indirect_res, vi.gl_cost * 1e6, 100.0 * vi.gl_error, vi.rays, vi.e_cost * 1e6,
             100.0 * vi.e_error);
    /* GL's costs kept for the next runs on this machine (samp_record.h): where
     * even its cheapest cannot win, they need no GL context to find out. */
    samp_record_note(desc, have_direct ? 1e6 * vd.gl_cost : -1.0, 1e6 * vi.gl_cost);
    /* Last: gl_ops lives inside gl_impl (its name was needed above). */
    if (!vd.gl_wins && !vi.gl_wins) gl_ops->destroy(gl_impl);
    return LM_OK;
}
