/* bench_sampling — cost and error of every sampler back end on this machine
 * (issue "Irradiance sampling", item 6). Prints one table.
 *
 * Receivers: points drawn by area on the triangles of CornellBox-Original and
 * CornellBox-Water that face the light. "Unoccluded" points see the whole light
 * (a 4096-ray Embree estimate equals Lambert's formula there): error against the
 * analytic value. "Occluded" points are in penumbra or umbra: error against a
 * 1,000,000-ray Embree estimate (control variate on).
 * Indirect: the coarse radiance mesh is one sub-triangle per scene triangle with
 * corner radiance kd·Le·G_unoccluded/π (a plausible first direct-diffuse mesh);
 * error against a 262,144-ray Embree estimate of the same mesh.
 * Cost: microseconds per sample, the median over BATCHES batches of BATCH points,
 * after one warm-up batch.
 *
 * usage: bench_sampling [quick]   (quick: fewer points and a 65,536-ray reference)
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "sampling/samp.h"
#include "src/base/rng.h"
#include "src/scene/scene.h"

enum { BATCH = 256, BATCHES = 5, MAX_POINTS = 64 };

typedef struct point_set {
    samp_point unocc[MAX_POINTS], occ[MAX_POINTS], timing[BATCH];
    float unocc_ref[MAX_POINTS], occ_ref[MAX_POINTS];
    uint32_t n_unocc, n_occ;
} point_set;

static samp_sampler *make(const scene *s, samp_backend b, glctx_platform pl, int res, int rays, int ind_res,
                          int ind_rays, char *why, size_t why_n)
{
    samp_desc d = {.scene = s, .backend = b, .gl_platform = pl, .direct_res = res, .direct_rays = rays,
                   .indirect_res = ind_res, .indirect_rays = ind_rays};
    samp_sampler *sp = NULL;
    lm_error err = {{0}};
    if (samp_create(&d, &sp, &err) != LM_OK) {
        lm_strlcpy(why, err.msg, why_n);
        return NULL;
    }
    return sp;
}

static void build_points(const scene *s, point_set *ps, int quick)
{
    double *cdf = samp_area_cdf(s);
    lm_rng g;
    lm_rng_seed(&g, 77, 0, 0);
    char why[256];
    samp_sampler *probe = make(s, SAMP_BACKEND_EMBREE, 0, 0, 4096, 0, 0, why, sizeof why);
    samp_sampler *ref = make(s, SAMP_BACKEND_EMBREE, 0, 0, quick ? 65536 : 1000000, 0, 0, why, sizeof why);
    uint32_t want = quick ? 16 : 32;
    ps->n_unocc = ps->n_occ = 0;
    for (int tries = 0; tries < 20000 && (ps->n_unocc < want || ps->n_occ < want); ++tries) {
        samp_point x = samp_random_receiver(s, cdf, &g);
        float G;
        lm_error err;
        samp_direct(probe, 0, &x, 1, &G, &err);
        double g0 = samp_area_light_unoccluded(s, 0, x.p, x.n);
        if (fabs(G - g0) <= 1e-6 * g0) {
            if (ps->n_unocc < want) {
                ps->unocc[ps->n_unocc] = x;
                ps->unocc_ref[ps->n_unocc++] = (float)g0;
            }
        } else if (G > 0.02 * g0 && ps->n_occ < want) {
            ps->occ[ps->n_occ++] = x; /* penumbra: the hard case */
        }
    }
    lm_error err;
    samp_direct(ref, 0, ps->occ, ps->n_occ, ps->occ_ref, &err);
    /* Timing receivers face the light (a cache samples no light where it is behind). */
    for (int i = 0; i < BATCH;) {
        ps->timing[i] = samp_random_receiver(s, cdf, &g);
        i += samp_area_light_unoccluded(s, 0, ps->timing[i].p, ps->timing[i].n) > 0.0;
    }
    samp_destroy(probe);
    samp_destroy(ref);
    free(cdf);
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static void errors(const float *got, const float *want, uint32_t n, double *mean, double *max)
{
    *mean = *max = 0.0;
    for (uint32_t i = 0; i < n; ++i) {
        double e = want[i] > 0.0f ? fabs(got[i] - want[i]) / want[i] : fabs(got[i]);
        *mean += e / n;
        if (e > *max) *max = e;
    }
}

/* Median microseconds per point of samp_direct (ind == NULL) or samp_indirect. */
static double time_per_sample(samp_sampler *sp, const samp_radiance_mesh *ind, const samp_point *pts, int batch)
{
    static float out[3 * BATCH];
    double t[BATCHES];
    lm_error err;
    for (int b = -1; b < BATCHES; ++b) {
        double t0 = lm_now_seconds();
        if (ind)
            samp_indirect(sp, ind, pts, (uint32_t)batch, out, &err);
        else
            samp_direct(sp, 0, pts, (uint32_t)batch, out, &err);
        if (b >= 0) t[b] = (lm_now_seconds() - t0) / batch * 1e6;
    }
    qsort(t, BATCHES, sizeof *t, cmp_double);
    return t[BATCHES / 2];
}

typedef struct config {
    const char *label;
    samp_backend backend;
    glctx_platform platform;
    int res, rays; /* direct: GL pixels per side, or Embree rays */
} config;

static const config direct_configs[] = {
    {"embree", SAMP_BACKEND_EMBREE, 0, 0, 16},     {"embree", SAMP_BACKEND_EMBREE, 0, 0, 64},
    {"embree", SAMP_BACKEND_EMBREE, 0, 0, 256},    {"embree", SAMP_BACKEND_EMBREE, 0, 0, 1024},
    {"embree", SAMP_BACKEND_EMBREE, 0, 0, 4096},   {"embree", SAMP_BACKEND_EMBREE, 0, 0, 16384},
    {"gl-egl", SAMP_BACKEND_GL, GLCTX_EGL, 16, 0}, {"gl-egl", SAMP_BACKEND_GL, GLCTX_EGL, 32, 0},
    {"gl-egl", SAMP_BACKEND_GL, GLCTX_EGL, 64, 0}, {"gl-egl", SAMP_BACKEND_GL, GLCTX_EGL, 128, 0},
    {"gl-osmesa", SAMP_BACKEND_GL, GLCTX_OSMESA, 16, 0}, {"gl-osmesa", SAMP_BACKEND_GL, GLCTX_OSMESA, 32, 0},
    {"gl-osmesa", SAMP_BACKEND_GL, GLCTX_OSMESA, 64, 0}, {"gl-osmesa", SAMP_BACKEND_GL, GLCTX_OSMESA, 128, 0},
};

static const config indirect_configs[] = {
    {"embree", SAMP_BACKEND_EMBREE, 0, 0, 1024},    {"embree", SAMP_BACKEND_EMBREE, 0, 0, 4096},
    {"embree", SAMP_BACKEND_EMBREE, 0, 0, 16384},   {"embree", SAMP_BACKEND_EMBREE, 0, 0, 65536},
    {"gl-egl", SAMP_BACKEND_GL, GLCTX_EGL, 64, 0},  {"gl-egl", SAMP_BACKEND_GL, GLCTX_EGL, 128, 0},
    {"gl-egl", SAMP_BACKEND_GL, GLCTX_EGL, 256, 0}, {"gl-osmesa", SAMP_BACKEND_GL, GLCTX_OSMESA, 64, 0},
    {"gl-osmesa", SAMP_BACKEND_GL, GLCTX_OSMESA, 128, 0}, {"gl-osmesa", SAMP_BACKEND_GL, GLCTX_OSMESA, 256, 0},
};

static void bench_scene(const char *name, int quick)
{
    char path[1024];
    snprintf(path, sizeof path, "%s/cornell-box/%s", LUMESH_SCENES, name);
    scene_load_desc ld = {.path = path, .require_light = 1};
    scene *s;
    lm_error err;
    if (scene_load(&ld, &s, &err) != LM_OK) {
        fprintf(stderr, "%s\n", err.msg);
        return;
    }
    static point_set ps;
    double t0 = lm_now_seconds();
    build_points(s, &ps, quick);
    printf("\n%s (%u triangles): %u unoccluded, %u occluded receivers; reference built in %.1f s\n", name,
           s->tri_count, ps.n_unocc, ps.n_occ, lm_now_seconds() - t0);
    printf("DIRECT  %-10s %-12s %10s   %-21s %-21s\n", "back end", "resolution", "us/sample", "unoccluded mean/max",
           "occluded mean/max");
    for (size_t c = 0; c < sizeof direct_configs / sizeof *direct_configs; ++c) {
        const config *cf = &direct_configs[c];
        char res[32], why[256];
        if (cf->backend == SAMP_BACKEND_GL)
            snprintf(res, sizeof res, "%dx%d", cf->res, cf->res);
        else
            snprintf(res, sizeof res, "%d rays", cf->rays);
        samp_sampler *sp = make(s, cf->backend, cf->platform, cf->res, cf->rays, 0, 0, why, sizeof why);
        if (!sp) {
            printf("        %-10s %-12s unavailable: %s\n", cf->label, res, why);
            continue;
        }
        double us = time_per_sample(sp, NULL, ps.timing, BATCH);
        float got_u[MAX_POINTS], got_o[MAX_POINTS];
        samp_direct(sp, 0, ps.unocc, ps.n_unocc, got_u, &err);
        samp_direct(sp, 0, ps.occ, ps.n_occ, got_o, &err);
        double um, ux, om, ox;
        errors(got_u, ps.unocc_ref, ps.n_unocc, &um, &ux);
        errors(got_o, ps.occ_ref, ps.n_occ, &om, &ox);
        printf("        %-10s %-12s %10.1f   %8.2e %8.2e     %8.2e %8.2e\n", cf->label, res, us, um, ux, om, ox);
        fflush(stdout);
        samp_destroy(sp);
    }

    samp_coarse_mesh cm;
    if (samp_coarse_mesh_build(s, 8192, &cm, &err) != LM_OK) {
        fprintf(stderr, "%s\n", err.msg);
        scene_destroy(s);
        return;
    }
    char why[256];
    samp_sampler *ref = make(s, SAMP_BACKEND_EMBREE, 0, 0, 0, 0, quick ? 65536 : 262144, why, sizeof why);
    uint32_t ni = ps.n_unocc < 16 ? ps.n_unocc : 16;
    float eref[3 * 16], eg[3 * 16];
    samp_indirect(ref, &cm.mesh, ps.unocc, ni, eref, &err);
    samp_destroy(ref);
    printf("INDIRECT %-9s %-12s %10s   %-21s (batch %d, %u points vs %s-ray Embree)\n", "back end", "resolution",
           "us/sample", "mean/max rel error", BATCH, ni, quick ? "65,536" : "262,144");
    for (size_t c = 0; c < sizeof indirect_configs / sizeof *indirect_configs; ++c) {
        const config *cf = &indirect_configs[c];
        char res[32];
        if (cf->backend == SAMP_BACKEND_GL)
            snprintf(res, sizeof res, "%d^2 x 3", cf->res);
        else
            snprintf(res, sizeof res, "%d rays", cf->rays);
        samp_sampler *sp = make(s, cf->backend, cf->platform, 0, 0, cf->res, cf->rays, why, sizeof why);
        if (!sp) {
            printf("        %-10s %-12s unavailable: %s\n", cf->label, res, why);
            continue;
        }
        int batch = cf->backend == SAMP_BACKEND_GL && cf->res >= 256 ? 64 : BATCH;
        double us = time_per_sample(sp, &cm.mesh, ps.timing, batch);
        samp_indirect(sp, &cm.mesh, ps.unocc, ni, eg, &err);
        double mean = 0.0, max = 0.0;
        for (uint32_t i = 0; i < ni; ++i) {
            double e = 0.0, w = 0.0;
            for (int k = 0; k < 3; ++k) {
                e += fabs(eg[3 * i + (uint32_t)k] - eref[3 * i + (uint32_t)k]);
                w += eref[3 * i + (uint32_t)k];
            }
            e = w > 0.0 ? e / w : e;
            mean += e / ni;
            if (e > max) max = e;
        }
        printf("        %-10s %-12s %10.1f   %8.2e %8.2e\n", cf->label, res, us, mean, max);
        fflush(stdout);
        samp_destroy(sp);
    }
    samp_coarse_mesh_free(&cm);
    scene_destroy(s);
}

int main(int argc, char **argv)
{
    int quick = argc > 1 && strcmp(argv[1], "quick") == 0;
    printf("bench_sampling: microseconds per sample (median of %d batches of %d points after a warm-up) and\n"
           "relative error; GL runs on Mesa llvmpipe here (no GPU), Embree on every core.\n",
           BATCHES, BATCH);
    printf("For scale, the paper (2005 hardware): 0.9 ms per 64x64 direct sample, 2.6 ms per 16x16 ray-traced\n"
           "direct sample, 9 ms per 256x256 indirect sample.\n");
    bench_scene("CornellBox-Original.obj", quick);
    bench_scene("CornellBox-Water.obj", quick);
    return 0;
}
