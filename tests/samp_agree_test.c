/* samp_agree_test — the back ends against each other on a real scene, and the
 * automatic choice.
 *
 * CornellBox-Original (../shared/scenes): receivers drawn on its triangles, kept
 * where the boxes shadow part of the light (penumbra) or all of it. GL (64²,
 * control variate) and Embree (4096 rays, control variate) must agree within
 * their stated errors: GL one pixel row of the light's image, G_unocc/res;
 * Embree 3 standard errors, 3·SAMP_EMBREE_PENUMBRA_RMS(rays)·G_unocc. A 65,536-ray
 * Embree value is printed beside them for scale.
 * Auto: the choice is recorded with its numbers, names a back end for each
 * quantity, and the sampler's values are exactly those of the back end it names.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "sampling/samp.h"
#include "src/base/rng.h"
#include "tests/test_util.h"

enum { N = 24, RES = 64, RAYS = 4096 };

static samp_sampler *make(const scene *s, samp_backend b, int rays)
{
    samp_desc d = {.scene = s, .backend = b, .direct_res = RES, .direct_rays = rays};
    samp_sampler *sp = NULL;
    lm_error err;
    lm_result r = samp_create(&d, &sp, &err);
    CHECK_MSG(r == LM_OK, "%s", err.msg);
    return sp;
}

/* Receivers on the box's triangles that see the light partly or not at all
 * although it is above their horizon. */
static uint32_t shadowed_points(const scene *s, samp_sampler *probe, samp_point *pts)
{
    lm_rng g;
    lm_rng_seed(&g, 11, 0, 0);
    uint32_t n = 0, umbra = 0;
    for (int tries = 0; tries < 200000 && n < N; ++tries) {
        uint32_t t = (uint32_t)(lm_rng_float(&g) * s->tri_count) % s->tri_count;
        if (s->tris[t].light >= 0) continue;
        float u = lm_rng_float(&g), v = lm_rng_float(&g);
        if (u + v > 1.0f) {
            u = 1.0f - u;
            v = 1.0f - v;
        }
        samp_point x = {.tri_plus_one = t + 1};
        for (int k = 0; k < 3; ++k) {
            x.p[k] = (1 - u - v) * s->positions[3 * (size_t)s->tris[t].v[0] + (size_t)k] +
                     u * s->positions[3 * (size_t)s->tris[t].v[1] + (size_t)k] +
                     v * s->positions[3 * (size_t)s->tris[t].v[2] + (size_t)k];
            x.n[k] = s->tri_normals[3 * (size_t)t + (size_t)k];
        }
        double g0 = samp_area_light_unoccluded(s, 0, x.p, x.n);
        if (!(g0 > 0.0)) continue;
        float G;
        lm_error err;
        samp_direct(probe, 0, &x, 1, &G, &err);
        int is_umbra = G == 0.0f, is_penumbra = G > 0.01 * g0 && G < 0.99 * g0;
        if (is_penumbra || (is_umbra && umbra < N / 4)) {
            umbra += is_umbra;
            pts[n++] = x;
        }
    }
    return n;
}

int main(void)
{
    char path[1024];
    snprintf(path, sizeof path, "%s/cornell-box/CornellBox-Original.obj", LUMESH_SCENES);
    scene_load_desc ld = {.path = path, .require_light = 1};
    scene *s = NULL;
    lm_error err;
    lm_result lr = scene_load(&ld, &s, &err);
    CHECK_MSG(lr == LM_OK, "%s", err.msg);
    if (!s) return test_finish("samp_agree_test");

    samp_sampler *emb = make(s, SAMP_BACKEND_EMBREE, RAYS), *ref = make(s, SAMP_BACKEND_EMBREE, 65536);
    samp_sampler *gl = make(s, SAMP_BACKEND_GL, 0);
    if (!emb || !ref || !gl) return test_finish("samp_agree_test");
    samp_point pts[N];
    uint32_t n = shadowed_points(s, emb, pts);
    CHECK_MSG(n == N, "found only %u shadowed receivers", n);
    float ge[N], gg[N], gr[N];
    CHECK(samp_direct(emb, 0, pts, n, ge, &err) == LM_OK);
    CHECK(samp_direct(gl, 0, pts, n, gg, &err) == LM_OK);
    CHECK(samp_direct(ref, 0, pts, n, gr, &err) == LM_OK);
    int outside = 0;
    double worst = 0.0;
    for (uint32_t i = 0; i < n; ++i) {
        double g0 = samp_area_light_unoccluded(s, 0, pts[i].p, pts[i].n);
        double bound = g0 / RES + 3.0 * SAMP_EMBREE_PENUMBRA_RMS(RAYS) * g0, diff = fabs(gg[i] - ge[i]);
        outside += diff > bound;
        worst = fmax(worst, diff / bound);
        printf("  point %2u: G_unocc %.5f  gl %.5f  embree %.5f  (65536 rays %.5f)  |diff|/bound %.2f\n", i, g0,
               gg[i], ge[i], gr[i], diff / bound);
    }
    printf("GL %dx%d vs Embree %d rays on %u shadowed Cornell box points: worst |diff|/stated bound %.2f\n", RES, RES,
           RAYS, n, worst);
    CHECK_MSG(outside == 0, "%d points disagree beyond the stated errors", outside);

    /* Auto: a recorded choice, and the values of the back end it names. */
    samp_sampler *au = make(s, SAMP_BACKEND_AUTO, 0);
    if (au) {
        samp_stats st;
        samp_get_stats(au, &st);
        printf("auto: direct %s, indirect %s\n  %s\n", st.backend_name, st.indirect_backend_name, st.choice);
        CHECK(strncmp(st.choice, "auto", 4) == 0 && strstr(st.choice, "direct ") && strstr(st.choice, "indirect "));
        CHECK(st.backend != SAMP_BACKEND_AUTO && st.indirect_backend != SAMP_BACKEND_AUTO);
        char says[64];
        snprintf(says, sizeof says, "direct %s", st.backend_name);
        CHECK_MSG(strstr(st.choice, says) != NULL, "choice text does not name %s", st.backend_name);
        float ga[N];
        CHECK(samp_direct(au, 0, pts, n, ga, &err) == LM_OK);
        if (st.backend == SAMP_BACKEND_GL)
            CHECK_MSG(memcmp(ga, gg, n * sizeof *ga) == 0, "auto (GL) differs from the GL sampler");
        for (uint32_t i = 0; i < n; ++i) CHECK(isfinite(ga[i]) && ga[i] >= 0.0f);
        samp_destroy(au);
    }
    /* Auto with a stated tolerance: the choice says so, and the chosen back end's
     * penumbra error on these points is within twice the tolerance (the
     * calibration measured it on other points of the same scene). */
    samp_desc td = {.scene = s, .direct_target_error = 0.02f, .indirect_target_error = 0.02f};
    samp_sampler *tol = NULL;
    CHECK(samp_create(&td, &tol, &err) == LM_OK);
    if (tol) {
        samp_stats st;
        samp_get_stats(tol, &st);
        printf("auto, 2%% asked: direct %s, indirect %s\n  %s\n", st.backend_name, st.indirect_backend_name, st.choice);
        CHECK(strstr(st.choice, "direct") && strstr(st.choice, "for the asked error"));
        float gt[N];
        CHECK(samp_direct(tol, 0, pts, n, gt, &err) == LM_OK);
        double num = 0.0, den = 0.0;
        for (uint32_t i = 0; i < n; ++i) {
            num += fabs(gt[i] - gr[i]);
            den += gr[i];
        }
        printf("  its mean relative error on the shadowed points: %.2f%%\n", 100.0 * num / den);
        CHECK_MSG(num / den <= 0.04, "mean relative error %.3f", num / den);
        samp_destroy(tol);
    }
    samp_destroy(emb);
    samp_destroy(ref);
    samp_destroy(gl);
    scene_destroy(s);
    return test_finish("samp_agree_test");
}
