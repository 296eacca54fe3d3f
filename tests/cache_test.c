/* cache_test — the multi-mesh cache (mesh/cache/):
 *   - a lone quad light over a plane: after refinement the cached direct radiance
 *     matches Lambert's closed form everywhere within the JND (tone-mapped CIELAB
 *     ΔE), G is exact, and the light mesh samples a small fraction of the
 *     vertices (the visible fraction is 1 everywhere and interpolates; it samples
 *     only to stay within CACHE_LIGHT_LAG levels of the radiance mesh);
 *   - the same with a blocker: the cache against a 4096-ray Embree G at random
 *     points; light samples only where there is penumbra;
 *   - the display's exposure (cache_set_exposure): converged at 0, the direct mesh
 *     is off at ±3 stops (a clipped penumbra, dim outskirts) until told the
 *     exposure, then within the blocker's bounds there;
 *   - determinism: two caches, same calls, identical statistics;
 *   - the node cap: refinement stops with LM_ERR_NO_MEMORY and a usable cache;
 *   - the built-in Cornell box: the direct value at the floor vertices in front of
 *     the short box and the indirect irradiance at the bottom of its front face
 *     against independent Embree estimates (two defects, docs/cache.md);
 *   - the specular integral (samp_polygon_phong, what the specular mesh stores per
 *     light): against a brute-force quadrature over the light for n from 0 to
 *     5000, on a quad, a triangle, a 40-gon (integrated in pieces) and a concave
 *     polygon, within 0.1%, where the centroid's lobe times G (eq. 6, the old
 *     specular mesh) is wrong by far more than 0.5% for sharp lobes; and through
 *     the cache for a lamp of 24 triangles with a hole (its outline: two loops).
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "mesh/cache/cache.h"
#include "mesh/cache/cache_internal.h"
#include "sampling/analytic.h"
#include "sampling/rt_scene.h"
#include "sampling/samp.h"
#include "src/base/rng.h"
#include "src/base/tonemap.h"
#include "src/scene/camera.h"
#include "src/base/vecmath.h"
#include "tests/test_util.h"

#define KD 0.6f
#define LE 5.0f

static scene *load_lights(const char *name, int blocker, const char *lights)
{
    char obj[1024], text[2048];
    test_write_file("cache_plane.obj", "v -2 0 -2\nv 2 0 -2\nv 2 0 2\nv -2 0 2\nf 1 4 3\nf 1 3 2\n", obj, sizeof obj);
    test_write_file("cache_blocker.obj", "v -0.2 0.5 -0.2\nv 0.2 0.5 -0.2\nv 0.2 0.5 0.2\nv -0.2 0.5 0.2\nf 1 2 3\nf 1 3 4\n",
                    obj, sizeof obj);
    snprintf(text, sizeof text,
             "{\"meshes\": [{\"file\": \"cache_plane.obj\", \"material\": \"paint\"}%s],"
             " \"materials\": {\"paint\": {\"kd\": [%g, %g, %g]}}, \"lights\": [%s]}",
             blocker ? ", {\"file\": \"cache_blocker.obj\", \"material\": \"paint\"}" : "", KD, KD, KD, lights);
    return test_load_json(name, text);
}

static scene *load(const char *name, int blocker)
{
    char light[256];
    snprintf(light, sizeof light,
             "{\"type\": \"quad\", \"corner\": [-0.5, 1, -0.5], \"edge1\": [1, 0, 0], \"edge2\": [0, 0, 1],"
             " \"radiance\": [%g, %g, %g]}",
             LE, LE, LE);
    return load_lights(name, blocker, light);
}

typedef struct run {
    samp_sampler *sp;
    cache *c;
    uint32_t *pixels;
} run;

static int start_with(run *u, const scene *s, uint32_t pixels_per_tri, uint32_t node_cap, cache_scheduler sched);
static int single_mesh_next; /* the next start_with builds a single-mesh cache (ablation) */

static int start(run *u, const scene *s, uint32_t pixels_per_tri, uint32_t node_cap)
{
    return start_with(u, s, pixels_per_tri, node_cap, CACHE_SCHED_HEAP);
}

static int start_with(run *u, const scene *s, uint32_t pixels_per_tri, uint32_t node_cap, cache_scheduler sched)
{
    lm_error err;
    memset(u, 0, sizeof *u);
    lm_result r = samp_create(&(samp_desc){.scene = s, .backend = SAMP_BACKEND_EMBREE, .seed = 5}, &u->sp, &err);
    CHECK_MSG(r == LM_OK, "%s", err.msg);
    if (r != LM_OK) return 0;
    r = cache_create(&(cache_desc){.scene = s, .sampler = u->sp, .node_cap = node_cap, .scheduler = sched, .seed = 1,
                                   .single_mesh = single_mesh_next},
                     &u->c, &err);
    single_mesh_next = 0;
    CHECK_MSG(r == LM_OK, "%s", err.msg);
    u->pixels = malloc(s->tri_count * sizeof *u->pixels);
    /* Only the plane (triangles 0, 1) is seen, 40,000 pixels each. */
    for (uint32_t t = 0; t < s->tri_count; ++t) u->pixels[t] = t < 2 ? pixels_per_tri : 0;
    return r == LM_OK;
}

static void stop(run *u)
{
    cache_destroy(u->c);
    samp_destroy(u->sp);
    free(u->pixels);
}

/* Refines until nothing is left to test (or `rounds` calls). */
static lm_result converge(run *u, int rounds, cache_refine_result *total)
{
    lm_error err;
    memset(total, 0, sizeof *total);
    for (int i = 0; i < rounds; ++i) {
        cache_refine_result res;
        lm_result r = cache_refine(u->c, &(cache_refine_desc){.pixels = u->pixels, .budget = 4096}, &res, &err);
        total->tested += res.tested;
        total->split += res.split;
        total->undone += res.undone;
        total->remaining = res.remaining;
        /* The running count the indirect source is rebuilt by equals the walk. */
        cache_stats st;
        cache_get_stats(u->c, &st);
        CHECK(cache_direct_changes(u->c) ==
              (int64_t)st.direct.mesh.splits - (int64_t)st.direct.mesh.merges + (int64_t)st.revised);
        CHECK(mesh_qmesh_node_count(cache_direct_mesh(u->c)) == st.direct.mesh.nodes);
        if (r != LM_OK) {
            printf("  refinement stopped: %s\n", err.msg);
            return r;
        }
        if (res.remaining == 0) break;
    }
    return LM_OK;
}

/* CIE76 ΔE between two linear colours after the display's tone mapping. */
static double seen_delta_e(const float a[3], const float b[3])
{
    tm_desc tm = {0};
    float da[3], db[3], la[3], lb[3];
    tm_to_display(&tm, a, da);
    tm_to_display(&tm, b, db);
    tm_display_to_lab(da, la);
    tm_display_to_lab(db, lb);
    return tm_delta_e(la, lb);
}

/* The diffuse colour of the plane under `radiance` as the display shows it at
 * `exposure` stops. */
static void lab_at(float exposure, float radiance, float lab[3])
{
    tm_desc tm = {.exposure = exposure};
    float rgb[3] = {KD * radiance, KD * radiance, KD * radiance}, d[3];
    tm_to_display(&tm, rgb, d);
    tm_display_to_lab(d, lab);
}

static void lab_of(float radiance, float lab[3]) { lab_at(0.0f, radiance, lab); }

/* Random point on the plane's central 3×3 (barycentrics in its triangle). */
static void random_plane_point(lm_rng *g, const scene *s, uint32_t *tri, double *w1, double *w2, float p[3])
{
    *tri = lm_rng_float(g) < 0.5f ? 0 : 1;
    double u, v;
    do {
        u = lm_rng_float(g);
        v = lm_rng_float(g);
    } while (u + v > 1.0);
    *w1 = u;
    *w2 = v;
    const uint32_t *tv = s->tris[*tri].v;
    for (int k = 0; k < 3; ++k)
        p[k] = (float)((1 - u - v) * s->positions[3 * tv[0] + k] + u * s->positions[3 * tv[1] + k] +
                       v * s->positions[3 * tv[2] + k]);
}

static void test_lone_light(void)
{
    scene *s = load("cache_lone.json", 0);
    run u;
    if (!s || !start(&u, s, 40000, 0)) return;
    cache_refine_result tot;
    lm_error err;
    CHECK(converge(&u, 200, &tot) == LM_OK);
    cache_stats st;
    cache_get_stats(u.c, &st);
    lm_rng g;
    lm_rng_seed(&g, 3, 0, 0);
    const float up[3] = {0, 1, 0};
    double worst_de = 0.0, worst_g = 0.0;
    int n = 0;
    for (int i = 0; i < 4000; ++i) {
        uint32_t tri;
        double w1, w2;
        float p[3];
        random_plane_point(&g, s, &tri, &w1, &w2, p);
        double G0 = samp_area_light_unoccluded(s, 0, p, up), G;
        float rgb[3], a[3], b[3];
        CHECK(cache_eval_direct(u.c, tri, w1, w2, rgb, &err) == LM_OK);
        CHECK(cache_eval_G(u.c, 0, tri, w1, w2, &G, &err) == LM_OK);
        lab_of(rgb[0], a);
        lab_of((float)(LE * G0 / M_PI), b);
        worst_de = fmax(worst_de, tm_delta_e(a, b));
        if (G0 > 1e-3) worst_g = fmax(worst_g, fabs(G - G0) / G0);
        n++;
    }
    printf("lone light over a plane: %u tested, %u splits kept, %u undone; direct mesh %u leaves (depth <= ",
           tot.tested, tot.split, tot.undone, st.direct.mesh.leaves);
    int deepest = 0;
    for (int d = 0; d < MESH_QMESH_DEPTHS; ++d)
        if (st.direct.mesh.leaves_at_depth[d]) deepest = d;
    printf("%d); direct values %llu; light samples %llu, interpolated %llu\n", deepest,
           (unsigned long long)st.direct.samples, (unsigned long long)st.lights[0].samples,
           (unsigned long long)st.lights[0].interpolated);
    printf("  %d random points: worst ΔE against Lambert %.3f (JND 2), worst relative G error %.2e\n", n, worst_de,
           worst_g);
    CHECK(tot.remaining == 0);
    CHECK_MSG(worst_de <= 2.0, "ΔE %.3f above the JND", worst_de);
    CHECK_MSG(worst_g <= 1e-5, "G error %.3e", worst_g);
    /* Wholly visible: V = 1 interpolates; the light mesh samples only to stay within
     * CACHE_LIGHT_LAG levels of the radiance mesh (16 times its area per vertex). */
    CHECK_MSG(st.lights[0].samples * 16 <= st.direct.samples, "the unoccluded light took %llu samples for %llu values",
              (unsigned long long)st.lights[0].samples, (unsigned long long)st.direct.samples);
    /* Size criterion: 40,000 pixels per triangle, leaves stop at <= 16 pixels. */
    CHECK(deepest >= 6);
    stop(&u);
    scene_destroy(s);
}

/* The cache's G of light 0 (direct_mesh: the direct mesh's L_dd) against a
 * 4096-ray Embree estimate at 1000 random points of the plane, as the ΔE of the
 * diffuse colour (light 0's radiance le) shown at `exposure`: returns the sum of ΔE, *n the points, *above those beyond
 * the JND. */
static double against_embree_at(const run *u, const scene *s, float le, float exposure, int direct_mesh, int *n,
                                int *above)
{
    samp_sampler *ref = NULL;
    lm_error err;
    CHECK(samp_create(&(samp_desc){.scene = s, .backend = SAMP_BACKEND_EMBREE, .direct_rays = 4096}, &ref, &err) ==
          LM_OK);
    lm_rng g;
    lm_rng_seed(&g, 4, 0, 0);
    double sum_de = 0.0;
    *n = *above = 0;
    for (int i = 0; i < 1000 && ref; ++i) {
        uint32_t tri;
        double w1, w2, G;
        samp_point x = {.n = {0, 1, 0}};
        random_plane_point(&g, s, &tri, &w1, &w2, x.p);
        x.tri_plus_one = tri + 1;
        float Gr, a[3], b[3];
        CHECK(samp_direct(ref, 0, &x, 1, &Gr, &err) == LM_OK);
        CHECK(cache_eval_G(u->c, 0, tri, w1, w2, &G, &err) == LM_OK);
        float ldd[3];
        CHECK(cache_eval_direct(u->c, tri, w1, w2, ldd, &err) == LM_OK);
        lab_at(exposure, direct_mesh ? ldd[0] : (float)(le * G / M_PI), a);
        lab_at(exposure, (float)(le * Gr / M_PI), b);
        double de = tm_delta_e(a, b);
        sum_de += de;
        *above += de > 2.0;
        (*n)++;
    }
    samp_destroy(ref);
    return sum_de;
}

static double against_embree(const run *u, const scene *s, int *n, int *above)
{
    return against_embree_at(u, s, LE, 0.0f, 0, n, above);
}

static void test_blocker(void)
{
    scene *s = load("cache_block.json", 1);
    run u;
    if (!s || !start(&u, s, 40000, 0)) return;
    cache_refine_result tot;
    CHECK(converge(&u, 400, &tot) == LM_OK);
    cache_stats st;
    cache_get_stats(u.c, &st);
    int n = 0, above = 0;
    double sum_de = against_embree(&u, s, &n, &above);
    printf("blocker: %u tested, %u kept, %u undone; light mesh %u leaves, %llu samples, %llu interpolated\n",
           tot.tested, tot.split, tot.undone, st.lights[0].mesh.leaves, (unsigned long long)st.lights[0].samples,
           (unsigned long long)st.lights[0].interpolated);
    printf("  %d random points vs 4096-ray Embree: mean ΔE %.3f, %d above the JND\n", n, sum_de / n, above);
    CHECK(tot.remaining == 0);
    CHECK_MSG(above <= n / 50, "%d of %d points beyond the JND", above, n);
    CHECK_MSG(sum_de / n <= 0.5, "mean ΔE %.3f", sum_de / n);
    /* The light mesh samples penumbra only: far fewer vertices than the radiance mesh. */
    CHECK_MSG(st.lights[0].samples * 2 < st.direct.samples, "light samples %llu vs direct values %llu",
              (unsigned long long)st.lights[0].samples, (unsigned long long)st.direct.samples);
    stop(&u);
    scene_destroy(s);
}

/* The display's exposure (cache_set_exposure; the viewer's + and −): a cache
 * converged at the scene's exposure is judged again at another. Two cases over
 * the blocker's plane: a light bright enough that the blocker's penumbra is
 * clipped to white at exposure 0, seen 3 stops darker; and the plane's dim
 * outskirts, too dark at 0 to show their interpolation, seen 3 stops brighter.
 * The direct mesh against 4,096-ray Embree at the new exposure (mean ΔE and
 * points beyond the JND): converged at 0, the cache is off there (measured 104
 * and 60 of 1,000 points beyond the JND, mean ΔE 0.73 and 0.52; required above
 * 50, so the check can fail); once told the exposure it is tested again (right
 * after the change every leaf is untested: the estimate claims nothing) and
 * converges within the bounds test_blocker asks at exposure 0 (measured 17 and
 * 2 points, mean ΔE 0.35 and 0.30). */
static void exposure_case(float le, float exposure)
{
    char light[256], name[64];
    snprintf(light, sizeof light,
             "{\"type\": \"quad\", \"corner\": [-0.5, 1, -0.5], \"edge1\": [1, 0, 0], \"edge2\": [0, 0, 1],"
             " \"radiance\": [%g, %g, %g]}",
             le, le, le);
    snprintf(name, sizeof name, "cache_exposure_%g.json", exposure);
    scene *s = load_lights(name, 1, light);
    run u;
    /* 1,000 pixels a triangle: a small view, where the JND rather than the
     * pixels' size bounds the leaves (at 40,000 both exposures refine to the
     * pixels, and neither shows the other's error). */
    if (!s || !start(&u, s, 1000, 0)) return;
    lm_error err;
    cache_refine_result tot;
    CHECK(converge(&u, 400, &tot) == LM_OK);
    int n0 = 0, above0 = 0, n1 = 0, above1 = 0;
    const double de0 = against_embree_at(&u, s, le, exposure, 1, &n0, &above0) / fmax(n0, 1);
    cache_stats st0, st1;
    cache_get_stats(u.c, &st0);
    CHECK(cache_set_exposure(u.c, exposure, &err) == LM_OK);
    CHECK(cache_get_exposure(u.c) == exposure);
    cache_estimate est;
    CHECK(cache_estimate_error(u.c, u.pixels, &est, &err) == LM_OK);
    CHECK_MSG(est.exposure == exposure && est.untested > 0.99, "after the change: exposure %g, %.3f untested",
              (double)est.exposure, est.untested);
    cache_refine_result tot1;
    CHECK(converge(&u, 400, &tot1) == LM_OK);
    const double de1 = against_embree_at(&u, s, le, exposure, 1, &n1, &above1) / fmax(n1, 1);
    cache_get_stats(u.c, &st1);
    CHECK(cache_estimate_error(u.c, u.pixels, &est, &err) == LM_OK);
    printf("exposure %+g (light %g): converged at 0, at %+g mean ΔE %.3f, %d of %d beyond the JND (%u direct leaves); "
           "refined for it: %.3f, %d (%u leaves, %u tested again); estimate %.3f, %.3f untested\n",
           (double)exposure, (double)le, (double)exposure, de0, above0, n0, st0.direct.mesh.leaves, de1, above1,
           st1.direct.mesh.leaves, tot1.tested, est.mean, est.untested);
    CHECK_MSG(above0 > n0 / 20, "converged at 0, only %d of %d points beyond the JND at %+g: the case shows nothing",
              above0, n0, (double)exposure);
    CHECK_MSG(above1 <= n1 / 50 && de1 <= 0.5, "refined for %+g: %d of %d beyond the JND, mean ΔE %.3f",
              (double)exposure, above1, n1, de1);
    CHECK(tot1.remaining == 0 && est.untested < 0.01);
    /* Back to the exposure it has: nothing changes. */
    CHECK(cache_set_exposure(u.c, exposure, &err) == LM_OK);
    CHECK(cache_estimate_error(u.c, u.pixels, &est, &err) == LM_OK && est.untested < 0.01);
    CHECK(cache_set_exposure(u.c, NAN, &err) == LM_ERR_INVALID_ARG);
    stop(&u);
    scene_destroy(s);
}

static void test_exposure(void)
{
    exposure_case(8.0f * LE, -3.0f); /* clipped at 0 */
    exposure_case(LE, 3.0f);         /* too dark at 0 */
}

static void test_determinism_and_cap(void)
{
    scene *s = load("cache_det.json", 1);
    run a, b;
    if (!s || !start(&a, s, 40000, 0) || !start(&b, s, 40000, 0)) return;
    cache_refine_result ra, rb;
    CHECK(converge(&a, 3, &ra) == LM_OK);
    CHECK(converge(&b, 3, &rb) == LM_OK);
    cache_stats sa, sb;
    cache_get_stats(a.c, &sa);
    cache_get_stats(b.c, &sb);
    CHECK(ra.tested == rb.tested && ra.split == rb.split && ra.undone == rb.undone);
    CHECK(sa.direct.samples == sb.direct.samples && sa.lights[0].samples == sb.lights[0].samples);
    CHECK(sa.direct.mesh.nodes == sb.direct.mesh.nodes && sa.lights[0].mesh.nodes == sb.lights[0].mesh.nodes);
    CHECK(memcmp(sa.direct.mesh.leaves_at_depth, sb.direct.mesh.leaves_at_depth,
                 sizeof sa.direct.mesh.leaves_at_depth) == 0);
    stop(&a);
    stop(&b);

    run c;
    if (!start(&c, s, 40000, 300)) return;
    cache_refine_result rc;
    lm_result r = converge(&c, 50, &rc);
    cache_stats sc;
    cache_get_stats(c.c, &sc);
    printf("node cap 300: refinement ended with %s after %u splits; direct mesh %u nodes\n", lm_result_name(r),
           rc.split, sc.direct.mesh.nodes);
    CHECK(r == LM_ERR_NO_MEMORY);
    CHECK(sc.direct.mesh.nodes <= 300 && sc.indirect.mesh.nodes <= 300);
    float rgb[3];
    lm_error err;
    CHECK(cache_eval_direct(c.c, 0, 0.3, 0.3, rgb, &err) == LM_OK && isfinite(rgb[0]));
    stop(&c);
    scene_destroy(s);
}

/* Two lights of different colours over a plane with a blocker; light 1 switched
 * off at run time must give the image of a scene that never had it, with no new
 * light sample at the switch. */
static void test_light_edit(void)
{
#define RED "{\"type\": \"quad\", \"corner\": [-1.2, 1, -0.3], \"edge1\": [0.6, 0, 0], \"edge2\": [0, 0, 0.6], \"radiance\": [12, 2, 2]}"
#define BLUE "{\"type\": \"quad\", \"corner\": [0.6, 1.2, -0.3], \"edge1\": [0.6, 0, 0], \"edge2\": [0, 0, 0.6], \"radiance\": [2, 2, 12]}"
    scene *both = load_lights("cache_two.json", 1, RED ", " BLUE), *one = load_lights("cache_one.json", 1, RED);
    run a, b;
    if (!both || !one || !start(&a, both, 40000, 0) || !start(&b, one, 40000, 0)) return;
    cache_refine_result ta, tb;
    lm_error err;
    CHECK(converge(&a, 400, &ta) == LM_OK);
    CHECK(converge(&b, 400, &tb) == LM_OK);
    cache_stats before, after;
    cache_get_stats(a.c, &before);
    uint64_t s0 = before.lights[0].samples, s1 = before.lights[1].samples;
    const float off[3] = {0, 0, 0};
    double t0 = lm_now_seconds();
    CHECK(cache_set_light(a.c, 1, off, &err) == LM_OK);
    double t_edit = lm_now_seconds() - t0;
    cache_get_stats(a.c, &after);
    CHECK_MSG(after.lights[0].samples == s0 && after.lights[1].samples == s1, "the edit took light samples");
    for (int pass = 0; pass < 2; ++pass) {
        lm_rng g;
        lm_rng_seed(&g, 9, 0, 0);
        int n = 0, above = 0;
        double sum = 0.0, worst = 0.0;
        for (int i = 0; i < 2000; ++i) {
            uint32_t tri;
            double w1, w2;
            float p[3], ra[3], rb[3], ia[3], ib[3];
            random_plane_point(&g, both, &tri, &w1, &w2, p);
            CHECK(cache_eval_direct(a.c, tri, w1, w2, ra, &err) == LM_OK);
            CHECK(cache_eval_direct(b.c, tri, w1, w2, rb, &err) == LM_OK);
            CHECK(cache_eval_indirect(a.c, tri, w1, w2, ia, &err) == LM_OK);
            CHECK(cache_eval_indirect(b.c, tri, w1, w2, ib, &err) == LM_OK);
            for (int k = 0; k < 3; ++k) { /* what the viewer sees: kd·(L_dd + E_i/π) */
                ra[k] = KD * (ra[k] + ia[k] / (float)M_PI);
                rb[k] = KD * (rb[k] + ib[k] / (float)M_PI);
            }
            double de = seen_delta_e(ra, rb);
            sum += de;
            worst = fmax(worst, de);
            above += de > 2.0;
            n++;
        }
        printf("light edit, %s: mean ΔE %.3f, worst %.3f, %d of %d points above the JND against a scene without the "
               "light%s\n",
               pass == 0 ? "at once" : "after refinement resumed", sum / n, worst, above, n,
               pass == 0 ? "" : "");
        if (pass == 0) {
            printf("  the edit took %.2f ms (direct recomputed, %llu indirect vertices gathered again) and no light sample "
                   "(light samples %llu / %llu before and after)\n",
                   t_edit * 1e3, (unsigned long long)(after.indirect.samples - before.indirect.samples),
                   (unsigned long long)s0, (unsigned long long)after.lights[0].samples);
            CHECK_MSG(above <= n / 20, "at once: %d points beyond the JND", above);
            cache_refine_result tr;
            CHECK(converge(&a, 400, &tr) == LM_OK);
        } else {
            CHECK_MSG(above <= n / 100, "after refinement: %d points beyond the JND", above);
            CHECK_MSG(sum / n <= 0.3, "after refinement: mean ΔE %.3f", sum / n);
        }
    }
    stop(&a);
    stop(&b);
    scene_destroy(both);
    scene_destroy(one);
#undef RED
#undef BLUE
}

/* Every inner node's priority is the maximum of its children's. */
static int check_max_propagation(const cache *c, const mesh_qmesh *m, uint32_t node, int *inner)
{
    const mesh_qnode *n = mesh_qmesh_node(m, node);
    if (n->child == MESH_QMESH_NONE) return 1;
    uint32_t ch = n->child;
    float mx = cache_node_priority(c, 0, ch);
    int ok = 1;
    for (uint32_t k = 0; k < 4; ++k) {
        mx = fmaxf(mx, cache_node_priority(c, 0, ch + k));
        ok &= check_max_propagation(c, m, ch + k, inner);
    }
    (*inner)++;
    return ok && cache_node_priority(c, 0, node) == mx;
}

/* The paper's randomized scheduler: priorities propagate as maxima, and it
 * converges to the same quality as the heap on the blocker scene. */
static void test_random_scheduler(void)
{
    scene *s = load("cache_random.json", 1);
    run u;
    if (!s || !start_with(&u, s, 40000, 0, CACHE_SCHED_RANDOM)) return;
    cache_refine_result part, tot;
    CHECK(converge(&u, 2, &part) == LM_OK); /* part way: priorities everywhere */
    int inner = 0, ok = 1;
    const mesh_qmesh *m = cache_direct_mesh(u.c);
    for (uint32_t t = 0; t < 2; ++t) ok &= check_max_propagation(u.c, m, mesh_qmesh_root(m, t), &inner);
    printf("random scheduler, part way (%u leaves tested): %d inner nodes, priorities %s the maxima of their children\n",
           part.tested, inner, ok ? "all" : "NOT all");
    CHECK(inner > 100 && ok);
    CHECK(converge(&u, 400, &tot) == LM_OK);
    CHECK(tot.remaining == 0);
    int n = 0, above = 0;
    double sum_de = against_embree(&u, s, &n, &above);
    printf("  converged: %u tested, %u kept; mean ΔE %.3f against 4096-ray Embree, %d of %d above the JND\n",
           part.tested + tot.tested, part.split + tot.split, sum_de / n, above, n);
    CHECK(above <= n / 50 && sum_de / n <= 0.5);
    stop(&u);
    scene_destroy(s);
}

/* The single-mesh ablation converges to the same quality on the blocker scene
 * but samples every light at every radiance vertex: many more light samples. */
static void test_single_mesh(void)
{
    scene *s = load("cache_single.json", 1);
    run multi, single;
    if (!s || !start(&multi, s, 40000, 0)) return;
    single_mesh_next = 1;
    if (!start(&single, s, 40000, 0)) return;
    cache_refine_result tm, ts;
    CHECK(converge(&multi, 400, &tm) == LM_OK && tm.remaining == 0);
    CHECK(converge(&single, 400, &ts) == LM_OK && ts.remaining == 0);
    cache_stats sm, ss;
    cache_get_stats(multi.c, &sm);
    cache_get_stats(single.c, &ss);
    lm_rng g;
    lm_rng_seed(&g, 6, 0, 0);
    double worst = 0.0;
    lm_error err;
    for (int i = 0; i < 1000; ++i) {
        uint32_t tri;
        double w1, w2;
        float p[3], a[3], b[3], la[3], lb[3];
        random_plane_point(&g, s, &tri, &w1, &w2, p);
        CHECK(cache_eval_direct(multi.c, tri, w1, w2, a, &err) == LM_OK);
        CHECK(cache_eval_direct(single.c, tri, w1, w2, b, &err) == LM_OK);
        lab_of(a[0], la);
        lab_of(b[0], lb);
        worst = fmax(worst, tm_delta_e(la, lb));
    }
    printf("single-mesh ablation: %llu light + %llu indirect samples (multi-mesh %llu + %llu) for %llu / %llu radiance "
           "values; worst ΔE between the two caches %.3f\n",
           (unsigned long long)ss.lights[0].samples, (unsigned long long)ss.indirect.samples,
           (unsigned long long)sm.lights[0].samples, (unsigned long long)sm.indirect.samples,
           (unsigned long long)ss.direct.samples, (unsigned long long)sm.direct.samples, worst);
    CHECK_MSG(ss.indirect.samples > 2 * sm.indirect.samples, "the combined mesh gathers at every vertex");
    CHECK(ss.lights[0].samples >= ss.direct.samples); /* every radiance value sampled the light */
    CHECK_MSG(sm.lights[0].samples * 2 < ss.lights[0].samples, "multi-mesh should need far fewer light samples");
    CHECK_MSG(worst <= 4.0, "the two caches differ by ΔE %.3f", worst);
    stop(&multi);
    stop(&single);
    scene_destroy(s);
}

/* ∫ over triangle (a, b, c) (counter-clockwise seen from its emitting front) of
 * (n+2)/(2π)·max(0, cos α)ⁿ·max(0, cosθ_x)·max(0, cosθ_y)/r² dA, α between wo and
 * the mirror of the direction to the light point about nx — eq. 5 per unit
 * radiance, by brute force: the collapsed square y = a + u(b − a) + uv(c − b),
 * dA = 2·area·u du dv, cut into N×N cells with 3×3 Gauss–Legendre points each. */
static double phong_brute_tri(const double a[3], const double b[3], const double c[3], const double x[3],
                              const double nx[3], const double wo[3], double n, int N)
{
    static const double gx[3] = {-0.77459666924148337704, 0.0, 0.77459666924148337704};
    static const double gw[3] = {5.0 / 9.0, 8.0 / 9.0, 5.0 / 9.0};
    lm_dvec3 A = dv3(a[0], a[1], a[2]), AB = dv3_sub(dv3(b[0], b[1], b[2]), A), BC = dv3_sub(dv3(c[0], c[1], c[2]), dv3(b[0], b[1], b[2]));
    lm_dvec3 cr = dv3_cross(AB, BC), nl = dv3_normalize(cr), X = dv3(x[0], x[1], x[2]);
    lm_dvec3 N_ = dv3_normalize(dv3(nx[0], nx[1], nx[2])), W = dv3_normalize(dv3(wo[0], wo[1], wo[2]));
    double two_area = dv3_length(cr), sum = 0.0;
    for (int i = 0; i < N; ++i)
        for (int ga = 0; ga < 3; ++ga) {
            double u = (i + 0.5 + 0.5 * gx[ga]) / N, inner = 0.0;
            for (int j = 0; j < N; ++j)
                for (int gb = 0; gb < 3; ++gb) {
                    double v = (j + 0.5 + 0.5 * gx[gb]) / N;
                    lm_dvec3 y = dv3_add(A, dv3_add(dv3_scale(AB, u), dv3_scale(BC, u * v)));
                    lm_dvec3 d = dv3_sub(y, X);
                    double r2 = dv3_dot(d, d);
                    lm_dvec3 wi = dv3_scale(d, 1.0 / sqrt(r2));
                    double cx = dv3_dot(wi, N_), cy = -dv3_dot(wi, nl);
                    double ca = dv3_dot(dv3_sub(dv3_scale(N_, 2.0 * dv3_dot(N_, wi)), wi), W);
                    if (cx <= 0.0 || cy <= 0.0 || ca <= 0.0) continue;
                    inner += gw[gb] * pow(ca, n) * cx * cy / r2;
                }
            sum += gw[ga] * u * inner;
        }
    return sum * two_area * (n + 2.0) / (2.0 * M_PI) / (4.0 * N * N);
}

/* The brute force over every triangle of area light l. */
static double phong_brute_light(const scene *s, uint32_t l, const double x[3], const double nx[3], const double wo[3],
                                double n, int N)
{
    const scene_area_light *L = &s->area_lights[l];
    double sum = 0.0;
    for (uint32_t i = 0; i < L->count; ++i) {
        const uint32_t *v = s->tris[s->light_tris[L->first + i]].v;
        double t[3][3];
        for (int k = 0; k < 3; ++k)
            for (int j = 0; j < 3; ++j) t[k][j] = s->positions[3 * (size_t)v[k] + (size_t)j];
        sum += phong_brute_tri(t[0], t[1], t[2], x, nx, wo, n, N);
    }
    return sum;
}

/* Eq. 5 at plane point p (normal +y) for the scene's one light, by brute force. */
static double specular_by_hand(const scene *s, const float p[3], const float eye[3], double n_exp)
{
    const double x[3] = {p[0], p[1], p[2]}, nx[3] = {0, 1, 0};
    const double wo[3] = {eye[0] - x[0], eye[1] - x[1], eye[2] - x[2]};
    return s->area_lights[0].le[0] * phong_brute_light(s, 0, x, nx, wo, n_exp, 16);
}

/* The specular mesh: none without gloss; over the glossy triangles only; it
 * converges to eq. 5 (the lobe integrated over the light, by brute force) within
 * the JND; a camera move resets it alone. */
static void test_specular(void)
{
    scene *matte = load("cache_matte.json", 0);
    run u;
    if (!matte || !start(&u, matte, 40000, 0)) return;
    CHECK_MSG(cache_specular_mesh(u.c) == NULL, "a scene without ks > 0 must have no specular mesh");
    stop(&u);
    scene_destroy(matte);

    char obj[1024], json[1024];
    test_write_file("cache_gloss.obj", "v -2 0 -2\nv 2 0 -2\nv 2 0 2\nv -2 0 2\nf 1 4 3\nf 1 3 2\n", obj, sizeof obj);
    test_write_file("cache_gloss.json",
                    "{\"meshes\": [{\"file\": \"cache_gloss.obj\", \"material\": \"lacquer\"}],"
                    " \"materials\": {\"lacquer\": {\"kd\": [0.3, 0.3, 0.3], \"ks\": [0.3, 0.3, 0.3], \"n\": 20}},"
                    " \"lights\": [{\"type\": \"quad\", \"corner\": [-0.25, 1, -0.25], \"edge1\": [0.5, 0, 0],"
                    " \"edge2\": [0, 0, 0.5], \"radiance\": [5, 5, 5]}],"
                    " \"cameras\": [{\"position\": [1.5, 1.2, 0], \"target\": [0, 0, 0]}]}",
                    json, sizeof json);
    scene *s = NULL;
    lm_error err;
    CHECK(scene_load(&(scene_load_desc){.path = json, .require_light = 1}, &s, &err) == LM_OK);
    if (!s || !start(&u, s, 40000, 0)) return;
    CHECK(cache_specular_mesh(u.c) != NULL);
    cache_refine_result tot;
    const float eyes[2][3] = {{1.5f, 1.2f, 0.0f}, {-0.8f, 1.5f, 1.0f}};
    for (int e = 0; e < 2; ++e) {
        if (e == 1) {
            cache_stats before, after;
            cache_get_stats(u.c, &before);
            CHECK(cache_set_camera(u.c, eyes[1], &err) == LM_OK);
            cache_get_stats(u.c, &after);
            printf("camera moved: specular mesh %u -> %u nodes, direct mesh %u -> %u nodes\n", before.specular.mesh.nodes,
                   after.specular.mesh.nodes, before.direct.mesh.nodes, after.direct.mesh.nodes);
            CHECK(after.specular.mesh.nodes == after.specular.mesh.roots);
            CHECK(after.direct.mesh.nodes == before.direct.mesh.nodes);
        }
        CHECK(converge(&u, 400, &tot) == LM_OK && tot.remaining == 0);
        lm_rng g;
        lm_rng_seed(&g, 12, 0, 0);
        double worst = 0.0, sum = 0.0;
        int n = 0, above = 0;
        for (int i = 0; i < 2000; ++i) {
            uint32_t tri;
            double w1, w2;
            float p[3], ldd[3], lds[3];
            random_plane_point(&g, s, &tri, &w1, &w2, p);
            CHECK(cache_eval_direct(u.c, tri, w1, w2, ldd, &err) == LM_OK);
            CHECK(cache_eval_specular(u.c, tri, w1, w2, lds, &err) == LM_OK);
            const float up[3] = {0, 1, 0};
            double G = samp_area_light_unoccluded(s, 0, p, up);
            float want = (float)(0.3 * 5.0 * G / M_PI + 0.3 * specular_by_hand(s, p, eyes[e], 20.0));
            float g1 = 0.3f * ldd[0] + 0.3f * lds[0], got[3] = {g1, g1, g1}, ref[3] = {want, want, want};
            double de = seen_delta_e(got, ref);
            worst = fmax(worst, de);
            sum += de;
            above += de > 2.0;
            n++;
        }
        cache_stats st;
        cache_get_stats(u.c, &st);
        printf("specular, eye %d: %u leaves in the specular mesh, %llu values; against eq. 5 by hand: mean ΔE %.3f, "
               "worst %.3f, %d of %d above the JND\n",
               e, st.specular.mesh.leaves, (unsigned long long)st.specular.samples, sum / n, worst, above, n);
        CHECK_MSG(above <= n / 100, "%d points beyond the JND", above);
        CHECK_MSG(sum / n <= 0.3, "mean ΔE %.3f", sum / n);
    }
    stop(&u);
    scene_destroy(s);
}

/* The polygon of xz corners at height h, wound to face down (-y): counter-clockwise
 * seen from below. */
static int down_polygon(const double (*xz)[2], int n, double h, double (*out)[3])
{
    double ny = 0.0; /* y of the Newell normal of the corners in the given order */
    for (int i = 0; i < n; ++i) {
        const double *a = xz[i], *b = xz[(i + 1) % n];
        ny += a[1] * b[0] - a[0] * b[1];
    }
    for (int i = 0; i < n; ++i) {
        const double *c = xz[ny > 0.0 ? n - 1 - i : i];
        out[i][0] = c[0];
        out[i][1] = h;
        out[i][2] = c[1];
    }
    return n;
}

/* The case generator: x above the floor, a tilted normal, and the view chosen so
 * that the mirror direction aims at `target` (a point of the light's plane). */
static void phong_case(lm_rng *g, const double target[3], double x[3], double nx[3], double wo[3])
{
    x[0] = -0.9 + 1.8 * lm_rng_float(g);
    x[1] = 0.9 * lm_rng_float(g);
    x[2] = -0.9 + 1.8 * lm_rng_float(g);
    lm_dvec3 N = dv3_normalize(dv3(0.6 * (lm_rng_float(g) - 0.5), 1.0, 0.6 * (lm_rng_float(g) - 0.5)));
    lm_dvec3 wi = dv3_normalize(dv3(target[0] - x[0], target[1] - x[1], target[2] - x[2]));
    lm_dvec3 W = dv3_sub(dv3_scale(N, 2.0 * dv3_dot(N, wi)), wi);
    nx[0] = N.x, nx[1] = N.y, nx[2] = N.z;
    wo[0] = W.x, wo[1] = W.y, wo[2] = W.z;
}

/* Eq. 6, the old specular mesh: G times the lobe towards the light's centroid. */
static double phong_centroid(const double (*P)[3], int np, const double x[3], const double nx[3], const double wo[3],
                             double n)
{
    double G = samp_polygon_G(P, np, x, nx), c[3] = {0, 0, 0};
    for (int i = 0; i < np; ++i)
        for (int k = 0; k < 3; ++k) c[k] += P[i][k] / np; /* the centroid of the quads and triangles used */
    lm_dvec3 N = dv3_normalize(dv3(nx[0], nx[1], nx[2])), W = dv3_normalize(dv3(wo[0], wo[1], wo[2]));
    lm_dvec3 wi = dv3_normalize(dv3(c[0] - x[0], c[1] - x[1], c[2] - x[2]));
    double ca = dv3_dot(dv3_sub(dv3_scale(N, 2.0 * dv3_dot(N, wi)), wi), W);
    return ca > 0.0 ? G * (n + 2.0) / (2.0 * M_PI) * pow(ca, n) : 0.0;
}

static double now_seconds(void)
{
    struct timespec t;
    timespec_get(&t, TIME_UTC);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

/* samp_polygon_phong against brute force: within 0.1% (+1e-7 absolute) for every
 * exponent from 0 to 5000, aiming the lobe inside, across the edges and corners
 * of, and beside the light; the centroid formula fails 0.5% on sharp lobes. */
static void test_phong_integral(void)
{
    const double quad_xz[4][2] = {{-0.24, -0.22}, {0.23, -0.22}, {0.23, 0.16}, {-0.24, 0.16}}; /* the lamp's size */
    const double tri_xz[3][2] = {{-0.3, -0.2}, {0.3, -0.1}, {0.0, 0.3}};
    double quad[4][3], tri[3][3];
    down_polygon(quad_xz, 4, 1.58, quad);
    down_polygon(tri_xz, 3, 1.4, tri);
    const double exps[] = {0, 1, 10, 32, 80, 200, 1000, 5000};
    lm_rng g;
    lm_rng_seed(&g, 77, 0, 0);
    double worst = 0.0;
    for (size_t ei = 0; ei < sizeof exps / sizeof exps[0]; ++ei) {
        double n = exps[ei], worst_n = 0.0, centroid_worst = 0.0;
        int N = 16 + (int)(2.0 * sqrt(n)), centroid_fails = 0, cases = 0;
        for (int shape = 0; shape < 2; ++shape) {
            const double (*P)[3] = shape == 0 ? (const double (*)[3])quad : (const double (*)[3])tri;
            int np = shape == 0 ? 4 : 3;
            for (int i = 0; i < 10; ++i) {
                /* the target: a corner, an edge point, the inside, or beside it (± a few lobe widths) */
                int k = i % np, kind = i % 4;
                double f = lm_rng_float(&g), t[3];
                for (int j = 0; j < 3; ++j) t[j] = P[k][j] + (kind == 0 ? 0.0 : f) * (P[(k + 1) % np][j] - P[k][j]);
                if (kind == 2)
                    for (int j = 0; j < 3; ++j) t[j] = 0.6 * t[j] + 0.4 * (P[0][j] + P[1][j] + P[2][j]) / 3.0;
                double off = (kind == 3 ? 0.15 : 0.03) * (lm_rng_float(&g) - 0.5);
                t[0] += off;
                t[2] += off * (lm_rng_float(&g) - 0.5);
                double x[3], nx[3], wo[3];
                phong_case(&g, t, x, nx, wo);
                double got = samp_polygon_phong(P, np, x, nx, wo, n);
                double want = shape == 0 ? phong_brute_tri(P[0], P[1], P[2], x, nx, wo, n, N) +
                                               phong_brute_tri(P[0], P[2], P[3], x, nx, wo, n, N)
                                         : phong_brute_tri(P[0], P[1], P[2], x, nx, wo, n, N);
                double err = fabs(got - want) / (want + 1e-4);
                worst_n = fmax(worst_n, err);
                CHECK_MSG(fabs(got - want) <= 1e-3 * want + 1e-7, "n %g, shape %d, case %d: %.9g, brute force %.9g", n,
                          shape, i, got, want);
                if (n == 0.0) { /* the constant lobe 1/π: Lambert's G/π */
                    double G = samp_polygon_G(P, np, x, nx) / M_PI;
                    CHECK_MSG(fabs(got - G) <= 1e-12 * G + 1e-15, "n 0: %.15g, G/π %.15g", got, G);
                }
                double old = phong_centroid(P, np, x, nx, wo, n);
                if (want > 1e-3) {
                    centroid_worst = fmax(centroid_worst, fabs(old - want) / want);
                    centroid_fails += fabs(old - want) > 5e-3 * want;
                    cases++;
                }
            }
        }
        printf("phong integral, n %6g: worst relative error %.2e against brute force (%dx%d cells); centroid (eq. 6) "
               "off by > 0.5%% at %d of %d points, worst %.0f%%\n",
               n, worst_n, N, N, centroid_fails, cases, 100.0 * centroid_worst);
        worst = fmax(worst, worst_n);
        if (n >= 100.0) {
            CHECK_MSG(centroid_fails * 2 > cases, "the centroid formula should fail 0.5%% on most points at n %g", n);
            CHECK(centroid_worst > 0.5);
        }
    }

    /* A 40-gon (integrated in three pieces) and a concave L, n = 200. */
    double disk_xz[40][2], disk[40][3], ell[6][3];
    for (int i = 0; i < 40; ++i) {
        disk_xz[i][0] = 0.05 + 0.25 * cos(2.0 * M_PI * i / 40);
        disk_xz[i][1] = -0.02 + 0.25 * sin(2.0 * M_PI * i / 40);
    }
    down_polygon((const double (*)[2])disk_xz, 40, 1.5, disk);
    const double ell_xz[6][2] = {{-0.2, -0.2}, {0.2, -0.2}, {0.2, -0.05}, {-0.05, -0.05}, {-0.05, 0.2}, {-0.2, 0.2}};
    down_polygon(ell_xz, 6, 1.5, ell);
    int lit = 0;
    for (int i = 0; i < 16; ++i) {
        int shape = i & 1;
        double t[3] = {0, 1.5, 0}, x[3], nx[3], wo[3];
        const double *c0 = shape ? ell[i % 6] : disk[(i * 7) % 40];
        t[0] = c0[0] + 0.03 * (lm_rng_float(&g) - 0.5) - (shape ? 0.0 : 0.05 * lm_rng_float(&g));
        t[2] = c0[2] + 0.03 * (lm_rng_float(&g) - 0.5);
        phong_case(&g, t, x, nx, wo);
        double want = 0.0, got;
        if (shape == 0) {
            double ctr[3] = {0.05, 1.5, -0.02};
            for (int k = 0; k < 40; ++k) want += phong_brute_tri(ctr, disk[k], disk[(k + 1) % 40], x, nx, wo, 200.0, 24);
            got = samp_polygon_phong((const double (*)[3])disk, 40, x, nx, wo, 200.0);
        } else { /* the L as two rectangles, four triangles */
            const double r1[4][2] = {{-0.2, -0.2}, {0.2, -0.2}, {0.2, -0.05}, {-0.2, -0.05}};
            const double r2[4][2] = {{-0.2, -0.05}, {-0.05, -0.05}, {-0.05, 0.2}, {-0.2, 0.2}};
            double q1[4][3], q2[4][3];
            down_polygon(r1, 4, 1.5, q1);
            down_polygon(r2, 4, 1.5, q2);
            want = phong_brute_tri(q1[0], q1[1], q1[2], x, nx, wo, 200.0, 48) +
                   phong_brute_tri(q1[0], q1[2], q1[3], x, nx, wo, 200.0, 48) +
                   phong_brute_tri(q2[0], q2[1], q2[2], x, nx, wo, 200.0, 48) +
                   phong_brute_tri(q2[0], q2[2], q2[3], x, nx, wo, 200.0, 48);
            got = samp_polygon_phong((const double (*)[3])ell, 6, x, nx, wo, 200.0);
        }
        worst = fmax(worst, fabs(got - want) / (want + 1e-4));
        CHECK_MSG(fabs(got - want) <= 1e-3 * want + 1e-7, "%s, case %d: %.9g, brute force %.9g", shape ? "L" : "40-gon",
                  i, got, want);
        lit += want > 1e-3;
    }
    CHECK_MSG(lit >= 8, "only %d of 16 lobes aimed at the 40-gon and the L see them", lit);
    /* Behind the light, and bad input: 0. */
    const double x_above[3] = {0, 2, 0}, up[3] = {0, 1, 0}, down[3] = {0, -1, 0}, wo[3] = {0.1, 1, 0};
    CHECK(samp_polygon_phong((const double (*)[3])quad, 4, x_above, down, wo, 80.0) == 0.0);
    CHECK(samp_polygon_phong((const double (*)[3])quad, 2, up, up, wo, 80.0) == 0.0);
    CHECK(samp_polygon_phong((const double (*)[3])quad, 4, up, up, wo, -1.0) == 0.0);
    CHECK(samp_polygon_phong((const double (*)[3])quad, 4, up, up, wo, NAN) == 0.0);

    /* Cost: the lamp, lobes aimed at it or anywhere. */
    enum { M = 2048 };
    static double X[M][3], NX[M][3], WO[M][3];
    for (int aimed = 1; aimed >= 0; --aimed) {
        for (int i = 0; i < M; ++i) {
            double t[3] = {-0.5 + lm_rng_float(&g), 1.58, -0.45 + 0.9 * lm_rng_float(&g)};
            if (!aimed) t[1] = 3.0 * lm_rng_float(&g);
            phong_case(&g, t, X[i], NX[i], WO[i]);
        }
        for (size_t ei = 3; ei < sizeof exps / sizeof exps[0]; ++ei) {
            double t0 = now_seconds(), sum = 0.0;
            for (int rep = 0; rep < 4; ++rep)
                for (int i = 0; i < M; ++i)
                    sum += samp_polygon_phong((const double (*)[3])quad, 4, X[i], NX[i], WO[i], exps[ei]);
            printf("phong integral cost, n %4g, lobes %s: %.2f µs a call (sum %.3g)\n", exps[ei],
                   aimed ? "at the light" : "anywhere", (now_seconds() - t0) / (4.0 * M) * 1e6, sum);
        }
    }
    printf("phong integral: worst relative error %.2e\n", worst);
}

/* The specular value of a vertex through the cache (cache_specular_from_visibility,
 * V = 1) against brute force over every triangle of the light, for a lamp made of
 * a 4×4 grid of squares without its middle 2×2 (24 triangles: the outline is an
 * outer square and a hole, after dropping the grid's straight-through vertices),
 * with lobes aimed at the hole's and the outer edges, inside the hole and on the lit
 * part. */
static void test_specular_outline(void)
{
    char obj_text[4096], path[1024], mtl[1024];
    size_t len = 0;
    len += (size_t)snprintf(obj_text + len, sizeof obj_text - len,
                            "mtllib cache_outline.mtl\nv -1 0 -1\nv 1 0 -1\nv 1 0 1\nv -1 0 1\nusemtl floor\nf 1 4 3\nf 1 3 2\n");
    for (int j = 0; j <= 4; ++j)
        for (int i = 0; i <= 4; ++i)
            len += (size_t)snprintf(obj_text + len, sizeof obj_text - len, "v %g 1 %g\n", -0.4 + 0.2 * i, -0.4 + 0.2 * j);
    len += (size_t)snprintf(obj_text + len, sizeof obj_text - len, "usemtl lamp\n");
    for (int j = 0; j < 4; ++j)
        for (int i = 0; i < 4; ++i) {
            if ((i == 1 || i == 2) && (j == 1 || j == 2)) continue; /* the hole */
            int a = 5 + j * 5 + i, b = a + 1, c = a + 6, d = a + 5; /* OBJ ids: 4 floor vertices first */
            /* counter-clockwise seen from below (facing -y) */
            len += (size_t)snprintf(obj_text + len, sizeof obj_text - len, "f %d %d %d\nf %d %d %d\n", a, b, c, a, c, d);
        }
    test_write_file("cache_outline.mtl",
                    "newmtl floor\nKd 0.3 0.3 0.3\nKs 0.5 0.5 0.5\nNs 300\nnewmtl lamp\nKd 0 0 0\nKe 4 4 4\n", mtl,
                    sizeof mtl);
    test_write_file("cache_outline.obj", obj_text, path, sizeof path);
    scene *s = NULL;
    lm_error err;
    CHECK(scene_load(&(scene_load_desc){.path = path, .require_light = 1}, &s, &err) == LM_OK);
    if (!s) return;
    CHECK(s->area_light_count == 1 && s->area_lights[0].count == 24);
    CHECK(s->area_lights[0].normal[1] < -0.99f);
    run u;
    if (!start(&u, s, 40000, 0)) return;
    const mesh_qmesh *m = cache_specular_mesh(u.c);
    CHECK(m != NULL);
    /* two loops of four corners: the outer square and the hole, reversed */
    CHECK(u.c->outl.light_loop[0] == 0 && u.c->outl.light_loop[1] == 2);
    CHECK(u.c->outl.loop[1] == 4 && u.c->outl.loop[2] == 8);
    CHECK(u.c->outl.loop_sign[0] * u.c->outl.loop_sign[1] == -1);
    if (m) {
        /* the floor's first triangle's corners: their vertices, which the cache
         * holds from its creation (its meshes take roots at cache_init; the
         * vertex table outlives the specular mesh, which every
         * cache_set_camera below replaces) */
        const uint32_t corner[3] = {mesh_vtable_corner_id(cache_vtable(u.c), 0, 0),
                                    mesh_vtable_corner_id(cache_vtable(u.c), 0, 1),
                                    mesh_vtable_corner_id(cache_vtable(u.c), 0, 2)};
        CHECK(corner[0] != MESH_VTABLE_NONE && corner[1] != MESH_VTABLE_NONE && corner[2] != MESH_VTABLE_NONE);
        const float V1[1] = {1.0f};
        const double targets[6][2] = {{-0.2, -0.05}, {0.2, 0.1}, {0.0, 0.0}, {-0.3, 0.3}, {0.4, -0.1}, {-0.1, 0.4}};
        double worst = 0.0;
        int lit = 0;
        for (int k = 0; k < 3; ++k)
            for (int t = 0; t < 6; ++t) {
                uint32_t vid = corner[k];
                const mesh_vertex *mv = mesh_vtable_vertex(cache_vtable(u.c), vid);
                double x[3] = {mv->position[0], mv->position[1], mv->position[2]}, nx[3] = {0, 1, 0};
                /* the eye on the mirror of the ray to the target */
                lm_dvec3 wi = dv3_normalize(dv3(targets[t][0] - x[0], 1.0 - x[1], targets[t][1] - x[2]));
                float eye[3] = {(float)(x[0] - 2.0 * wi.x), (float)(x[1] + 2.0 * wi.y), (float)(x[2] - 2.0 * wi.z)};
                CHECK(cache_set_camera(u.c, eye, &err) == LM_OK);
                double wo[3] = {eye[0] - x[0], eye[1] - x[1], eye[2] - x[2]};
                float rgb[3];
                CHECK(cache_specular_from_visibility(u.c, vid, V1, rgb, &err) == LM_OK);
                double want = 4.0 * phong_brute_light(s, 0, x, nx, wo, 300.0, 48);
                worst = fmax(worst, fabs(rgb[0] - want) / (want + 1e-3));
                lit += want > 0.1;
                CHECK_MSG(fabs(rgb[0] - want) <= 1e-3 * want + 1e-5, "vertex %u, target %d: %.7g, brute force %.7g", vid,
                          t, rgb[0], want);
            }
        printf("specular through the cache, a lamp of 24 triangles with a hole: worst relative error %.2e, %d of 18 lit\n",
               worst, lit);
        CHECK(lit >= 6);
    }
    stop(&u);
    scene_destroy(s);
}

/* A triangle of s picked uniformly and a point uniform in it (barycentrics u, v). */
static void random_surface_point(lm_rng *g, const scene *s, uint32_t *tri, double *u, double *v)
{
    *tri = (uint32_t)(lm_rng_float(g) * s->tri_count) % s->tri_count;
    *u = lm_rng_float(g);
    *v = lm_rng_float(g);
    if (*u + *v > 1.0) {
        *u = 1.0 - *u;
        *v = 1.0 - *v;
    }
}

/* The closed sphere of the tests below: radius R, facing in, albedo rho, a Phong
 * coat (ks, n; ks 0: none), a point light of intensity I at its centre and the
 * camera there; *bias is the facets' relative bound (test_write_icosphere). */
static scene *load_sphere(const char *name, double R, double rho, double ks, double n, double I, double *bias)
{
    char file[64], obj[1024], json[1024], text[1024];
    snprintf(file, sizeof file, "%s.obj", name);
    snprintf(obj, sizeof obj, "%s/%s", LUMESH_TMP_DIR, file);
    *bias = test_write_icosphere(3, R, obj);
    snprintf(text, sizeof text,
             "{\"meshes\": [{\"file\": \"%s\", \"material\": \"coat\"}],"
             " \"materials\": {\"coat\": {\"kd\": [%g, %g, %g], \"ks\": [%g, %g, %g], \"n\": %g}},"
             " \"lights\": [{\"type\": \"point\", \"position\": [0, 0, 0], \"intensity\": [%g, %g, %g]}],"
             " \"cameras\": [{\"position\": [0, 0, 0], \"target\": [1, 0, 0]}]}",
             file, rho, rho, rho, ks, ks, ks, n, I, I, I);
    snprintf(file, sizeof file, "%s.json", name);
    test_write_file(file, text, json, sizeof json);
    scene *s = NULL;
    lm_error err;
    CHECK(scene_load(&(scene_load_desc){.path = json, .crease_angle_deg = 0.01f}, &s, &err) == LM_OK);
    return s;
}

/* Closed form for the indirect pipeline: a point light of intensity I at the
 * centre of a closed sphere of radius R and albedo ρ. At every point
 * L_dd = I/(πR²) per unit albedo and the one-bounce E_i = ρ·I/R², so the pixel is
 * ρ·I/(πR²)·(1 + ρ) (the reference renderer's closed form). With K bounces
 * E_i = ρ·I/R²·Σ_(k<K) ρ^k, the partial sums of the geometric series (issue 13),
 * and auto must stop within the JND of the whole sum ρ·I/R²/(1 − ρ). The
 * icosphere's flat facets move both by at most a known relative bound
 * (test_write_icosphere). */
/* Refines c by pixels (64 a triangle of s) until nothing is left, at most 50
 * calls of 4,096 leaves; the last call's result. */
static cache_refine_result refine_sphere(cache *c, const scene *s)
{
    cache_refine_result res = {0};
    lm_error err;
    uint32_t *pixels = malloc(s->tri_count * sizeof *pixels);
    for (uint32_t t = 0; pixels && t < s->tri_count; ++t) pixels[t] = 64;
    for (int i = 0; i < 50 && c && pixels; ++i) {
        CHECK(cache_refine(c, &(cache_refine_desc){.pixels = pixels, .budget = 4096}, &res, &err) == LM_OK);
        if (res.remaining == 0) break;
    }
    free(pixels);
    return res;
}

static void test_sphere_indirect(int bounces)
{
    const double R = 2.0, rho = 0.5, I = 3.0;
    double bias;
    scene *s = load_sphere("cache_sphere", R, rho, 0.0, 1.0, I, &bias);
    lm_error err;
    if (!s) return;
    samp_sampler *sp = NULL;
    cache *c = NULL;
    CHECK(samp_create(&(samp_desc){.scene = s, .backend = SAMP_BACKEND_EMBREE, .indirect_rays = 1024}, &sp, &err) ==
          LM_OK);
    CHECK(cache_create(&(cache_desc){.scene = s, .sampler = sp, .bounces = bounces, .jnd = 1.0f}, &c, &err) == LM_OK);
    cache_refine_result res = refine_sphere(c, s);
    lm_rng g;
    lm_rng_seed(&g, 8, 0, 0);
    cache_stats st;
    if (c) cache_get_stats(c, &st);
    int shown = c ? st.bounces.bounces : 1;
    double series = 0.0;
    for (int k = 0; k < shown; ++k) series += pow(rho, k);
    double ldd_want = I / (M_PI * R * R), ei_want = rho * I / (R * R) * series;
    double worst_ldd = 0.0, worst_ei = 0.0, mean_ei = 0.0;
    const int N = 2000;
    for (int i = 0; i < N && c; ++i) {
        uint32_t tri;
        double u, v;
        random_surface_point(&g, s, &tri, &u, &v);
        float ldd[3], ei[3];
        CHECK(cache_eval_direct(c, tri, u, v, ldd, &err) == LM_OK);
        CHECK(cache_eval_indirect(c, tri, u, v, ei, &err) == LM_OK);
        worst_ldd = fmax(worst_ldd, fabs(ldd[0] - ldd_want) / ldd_want);
        worst_ei = fmax(worst_ei, fabs(ei[0] - ei_want) / ei_want);
        mean_ei += ei[0] / N;
    }
    printf("sphere, point light at the centre, %s%d bounce%s (%u facets, facet bias bound %.2e): L_dd worst relative "
           "error %.2e, E_i worst %.2e, mean E_i %.5f (closed form %.5f, %+.2f%%); %llu indirect samples; %s\n",
           bounces == CACHE_BOUNCES_AUTO ? "auto: " : "", shown, shown == 1 ? "" : "s", s->tri_count, bias, worst_ldd,
           worst_ei, mean_ei, ei_want, 100.0 * (mean_ei - ei_want) / ei_want,
           c ? (unsigned long long)st.indirect.samples : 0ull, c ? st.bounces.why : "");
    CHECK(res.remaining == 0);
    CHECK(bounces == CACHE_BOUNCES_AUTO || shown == bounces);
    CHECK_MSG(worst_ldd <= bias + 1e-5, "L_dd off by %.3e", worst_ldd);
    CHECK_MSG(worst_ei <= bias + 0.02, "E_i off by %.3e", worst_ei);
    /* Each partial sum within 1% in the mean (the facets' bias is 0.91%). */
    CHECK_MSG(fabs(mean_ei - ei_want) / ei_want <= 0.01, "mean E_i %.5f vs %.5f", mean_ei, ei_want);
    if (bounces == CACHE_BOUNCES_AUTO && c) {
        /* Within the JND of the whole series, as the viewer sees it (the pixel
         * ρ·(L_dd + E_i/π) through the scene's tone mapping). */
        double whole = rho * I / (R * R) / (1.0 - rho);
        tm_desc tm = {.exposure = s->exposure};
        float a[3], b[3], da[3], db[3], la[3], lb[3];
        for (int k = 0; k < 3; ++k) {
            a[k] = (float)(rho * (ldd_want + mean_ei / M_PI));
            b[k] = (float)(rho * (ldd_want + whole / M_PI));
        }
        tm_to_display(&tm, a, da);
        tm_to_display(&tm, b, db);
        tm_display_to_lab(da, la);
        tm_display_to_lab(db, lb);
        float de = tm_delta_e(la, lb);
        printf("  auto stopped at %d bounces, ΔE %.3f from the whole series (JND 1)\n", shown, (double)de);
        CHECK_MSG(de <= 1.0f, "auto is ΔE %.3f from the whole series", (double)de);
        CHECK(shown > 2);
    }
    cache_destroy(c);
    samp_destroy(sp);
    scene_destroy(s);
}

/* A cache_changed_fn that only counts the vertices it is told of (user: a uint64_t). */
static lm_result count_changed(cache *c, cache_kind kind, const cache_region *regions, uint32_t region_count,
                               const uint32_t *vids, uint32_t n, void *user, lm_error *err)
{
    (void)c, (void)kind, (void)regions, (void)region_count, (void)vids, (void)err;
    *(uint64_t *)user += n;
    return LM_OK;
}

/* Closed form for the glossy reflection of the source (cache_glossy.c): the
 * sphere above with a Phong coat (ks κ, exponent n) and the eye at its centre,
 * where every point is seen along its normal. The source is uniform,
 * L_src = ρ·I/(πR²)·Σ_(k<K) ρ^k, and the lobe about the normal integrates to
 * ∫ (n+2)/(2π)·cosⁿθ·cosθ dω = 1, so the specular value (per unit ks) is the
 * point light's lobe (n+2)/(2π)·I/R² plus L_src; with CACHE_GLOSSY_DIRECT the
 * first alone. The glossy part is the difference of the two caches' means over
 * the same points. A camera move makes the glossy parts stale: after the eye
 * moved away and came back the values are those of the centre again. */
static double glossy_sphere_mean(const scene *s, int bounces, cache_glossy mode, int move, double want, double bias,
                                 double n)
{
    samp_sampler *sp = NULL;
    cache *c = NULL;
    lm_error err;
    CHECK(samp_create(&(samp_desc){.scene = s, .backend = SAMP_BACKEND_EMBREE, .indirect_rays = 1024}, &sp, &err) ==
          LM_OK);
    CHECK(cache_create(&(cache_desc){.scene = s, .sampler = sp, .bounces = bounces, .jnd = 1.0f, .glossy = mode}, &c,
                       &err) == LM_OK);
    uint32_t *pixels = malloc(s->tri_count * sizeof *pixels);
    for (uint32_t t = 0; t < s->tri_count; ++t) pixels[t] = 64;
    cache_refine_result res = {0};
    for (int pass = 0; pass < 1 + move && c; ++pass) {
        if (pass == 1) {
            const float away[3] = {0.5f, 0.2f, -0.3f}, centre[3] = {0, 0, 0};
            CHECK(cache_set_camera(c, away, &err) == LM_OK);
            CHECK(cache_refine(c, &(cache_refine_desc){.pixels = pixels, .budget = 512}, NULL, &err) == LM_OK);
            CHECK(cache_set_camera(c, centre, &err) == LM_OK);
        }
        for (int i = 0; i < 50; ++i) {
            CHECK(cache_refine(c, &(cache_refine_desc){.pixels = pixels, .budget = 4096}, &res, &err) == LM_OK);
            if (res.remaining == 0) break;
        }
    }
    CHECK(res.remaining == 0);
    lm_rng g;
    lm_rng_seed(&g, 9, 0, 0);
    double worst = 0.0, mean = 0.0;
    const int N = 2000;
    for (int i = 0; i < N && c; ++i) {
        uint32_t tri;
        double u, v;
        random_surface_point(&g, s, &tri, &u, &v);
        float ls[3];
        CHECK(cache_eval_specular(c, tri, u, v, ls, &err) == LM_OK);
        worst = fmax(worst, fabs(ls[0] - want) / want);
        mean += ls[0] / N;
    }
    cache_stats st = {0};
    if (c) cache_get_stats(c, &st);
    printf("glossy sphere, %d bounce%s, %s%s: L_s mean %.5f (closed form %.5f, %+.2f%%), worst %.2e; %llu glossy "
           "gathers, %llu of them taken again\n",
           bounces, bounces == 1 ? "" : "s", mode == CACHE_GLOSSY_INDIRECT ? "lights and source" : "lights only",
           move ? ", after the eye moved and came back" : "", mean, want, 100.0 * (mean - want) / want, worst,
           (unsigned long long)st.glossy_gathers, (unsigned long long)st.glossy_refreshed);
    /* The lobe's tilt on a flat facet (the eye at the centre sees it off its
     * normal by up to β, β² ≈ bias) moves cosⁿα by about 2n·bias. */
    CHECK_MSG(fabs(mean - want) / want <= 0.01 + (1.0 + 2.0 * n) * bias, "mean L_s %.5f vs %.5f", mean, want);
    CHECK_MSG(worst <= 0.03 + (1.0 + 2.0 * n) * bias, "L_s off by %.3e", worst);
    CHECK(mode == CACHE_GLOSSY_INDIRECT ? st.glossy_gathers > 0 && st.glossy_refreshed > 0 : st.glossy_gathers == 0);
    if (c && mode == CACHE_GLOSSY_INDIRECT && !move && bounces == 1) {
        /* A refresh's allowance counts gathers of up to 256 rays: a part at
         * 4,096 rays takes 16 of it. Counted one a part, a worker step of the
         * Veach door took 10.8 million glossy rays (docs/cache.md, "A step's
         * regathers counted in rays"). */
        const uint32_t limit = mesh_vtable_id_limit(c->vt);
        for (uint32_t v = 0; v < limit && v < c->gls.cap; ++v) c->gls.level[v] = 4;
        cache_glossy_outdate(c);
        const uint64_t before = c->gls.refreshed;
        uint64_t allowance = 64, moved = 0;
        CHECK(cache_glossy_refresh(c, count_changed, &moved, &allowance, &err) == LM_OK);
        const uint64_t taken = c->gls.refreshed - before;
        printf("glossy refresh under an allowance of 64 at 4,096 rays a part: %llu parts taken, %llu left\n",
               (unsigned long long)taken, (unsigned long long)allowance);
        CHECK_MSG(taken == 4 && allowance == 0, "%llu parts taken at 4,096 rays under an allowance of 64",
                  (unsigned long long)taken);
    }
    free(pixels);
    cache_destroy(c);
    samp_destroy(sp);
    return mean;
}

/* The sphere's E_i at the vertices of the indirect mesh: the rms of its error
 * against the closed form, relative. */
static double sphere_ei_rms(cache *c, const scene *s, double want)
{
    lm_rng g;
    lm_rng_seed(&g, 9, 0, 0);
    double sum = 0.0;
    const int N = 2000;
    lm_error err;
    for (int i = 0; i < N; ++i) {
        uint32_t tri;
        double u, v;
        random_surface_point(&g, s, &tri, &u, &v);
        float ei[3];
        if (cache_eval_indirect(c, tri, u, v, ei, &err) != LM_OK) return INFINITY;
        sum += (ei[0] - want) * (ei[0] - want) / (want * want);
    }
    return sqrt(sum / N);
}

/* cache_outdate_plain: the values gathered at a sampler's plain count, flagged
 * when a sampler with 16x the rays takes over (what the worker does when its
 * start count gives way to Embree's default), are all gathered again by the
 * refine calls, and the error of E_i falls. */
/* The point-lit sphere (R 2, ρ 0.5, I 3) with a cache of 64-ray gathers at JND 4,
 * refined: what test_outdate_plain and test_outdated_keep_rays start from. */
static scene *few_ray_sphere(const char *name, samp_sampler **sp, cache **c, double *bias)
{
    scene *s = load_sphere(name, 2.0, 0.5, 0.0, 1.0, 3.0, bias);
    lm_error err;
    *sp = NULL;
    *c = NULL;
    if (!s) return NULL;
    CHECK(samp_create(&(samp_desc){.scene = s, .backend = SAMP_BACKEND_EMBREE, .indirect_rays = 64, .seed = 3}, sp,
                      &err) == LM_OK);
    CHECK(*sp && cache_create(&(cache_desc){.scene = s, .sampler = *sp, .jnd = 4.0f}, c, &err) == LM_OK);
    if (*c) refine_sphere(*c, s);
    return s;
}

static void test_outdate_plain(void)
{
    const double R = 2.0, rho = 0.5, I = 3.0;
    double bias;
    samp_sampler *few = NULL, *many = NULL;
    cache *c = NULL;
    scene *s = few_ray_sphere("cache_sphere_plain", &few, &c, &bias);
    lm_error err;
    if (!s) return;
    CHECK(samp_create(&(samp_desc){.scene = s, .backend = SAMP_BACKEND_EMBREE, .indirect_rays = 1024, .seed = 4},
                      &many, &err) == LM_OK);
    cache_refine_result res = {0};
    const double want = rho * I / (R * R);
    cache_stats before, after;
    if (c) cache_get_stats(c, &before);
    const double rms_few = c ? sphere_ei_rms(c, s, want) : 0.0;
    if (c) cache_set_sampler(c, many);
    CHECK(c && cache_outdate_plain(c, &err) == LM_OK);
    res = refine_sphere(c, s);
    if (c) cache_get_stats(c, &after);
    const double rms_many = c ? sphere_ei_rms(c, s, want) : 0.0;
    const uint64_t values = c ? before.indirect.mesh.vertices_sampled : 0, again = c ? after.regathered - before.regathered : 0;
    printf("outdate plain: %llu indirect values at 64 rays, %llu gathered again at 1024; E_i rms error %.4f -> %.4f "
           "(facet bias bound %.4f)\n",
           (unsigned long long)values, (unsigned long long)again, rms_few, rms_many, bias);
    CHECK(res.remaining == 0);
    CHECK_MSG(values > 0 && again >= values && again <= values + after.indirect.mesh.vertices_sampled,
              "%llu values, %llu gathered again", (unsigned long long)values, (unsigned long long)again);
    /* The rms holds the facets' deterministic error too (a uniform source gives
     * the gathers little noise): it falls, by less than the noise's 4x. */
    CHECK_MSG(rms_many < 0.8 * rms_few, "rms %.4f after, %.4f before", rms_many, rms_few);
    cache_destroy(c);
    samp_destroy(few);
    samp_destroy(many);
    scene_destroy(s);
}

/* A value flagged by a rebuild of the source (cache_outdate_all here) is
 * gathered again with the rays it had: half the sphere's values taken once more
 * with 4x the rays (cache_regather_finer) keep that level through
 * cache_regather_outdated, the rest stay at the plain count. Gathered again at
 * the plain count, the slot's worst receiver swung between 5% and 32% while the
 * source refined (docs/cache.md, "Drifted values keep their rays"). */
static void test_outdated_keep_rays(void)
{
    double bias;
    samp_sampler *sp = NULL;
    cache *c = NULL;
    scene *s = few_ray_sphere("cache_sphere_keep", &sp, &c, &bias);
    lm_error err;
    if (!s) return;
    if (!c) {
        samp_destroy(sp);
        scene_destroy(s);
        return;
    }
    const uint32_t limit = mesh_vtable_id_limit(c->vt);
    uint32_t *vids = malloc(limit * sizeof *vids), n = 0;
    float *E = malloc(3 * (size_t)limit * sizeof *E);
    for (uint32_t v = 0; vids && v < limit; ++v)
        if (mesh_qmesh_get_value(c->indirect, v, NULL) == 1) vids[n++] = v;
    CHECK(vids && E && n > 16);
    if (vids && E && n > 16) {
        uint32_t finer = n / 2, kept = 0, plain = 0;
        CHECK(cache_regather_finer(c, vids, finer, E, &err) == LM_OK);
        for (uint32_t i = 0; i < finer; ++i) CHECK(mesh_qmesh_set_value(c->indirect, vids[i], E + 3 * (size_t)i, &err) == LM_OK);
        cache_stats before, after;
        cache_get_stats(c, &before);
        CHECK(cache_outdate_all(c, &err) == LM_OK);
        CHECK(cache_regather_outdated(c, NULL, NULL, NULL, &err) == LM_OK);
        cache_get_stats(c, &after);
        for (uint32_t i = 0; i < n; ++i) {
            kept += i < finer && cache_gather_level(c, vids[i]) == 1;
            plain += i >= finer && cache_gather_level(c, vids[i]) == 0;
        }
        printf("outdated keep their rays: %u of %u values at 4x the rays after the regather, %u of %u at the plain "
               "count; %llu gathered again\n",
               kept, finer, plain, n - finer, (unsigned long long)(after.regathered - before.regathered));
        CHECK(after.regathered - before.regathered == n);
        CHECK_MSG(kept == finer && plain == n - finer, "%u of %u kept 4x, %u of %u plain", kept, finer, plain, n - finer);
        /* An allowance counts gathers of the plain count: a value at 4x the rays
         * takes 4 of it. Counted by values, one worker step of the Veach door
         * took 3.7 s (docs/cache.md, "A step's regathers counted in rays").
         * Every value one level finer first (1 or 2: 4 or 16 of it each). */
        CHECK(cache_regather_finer(c, vids, n, E, &err) == LM_OK);
        for (uint32_t i = 0; i < n; ++i) CHECK(mesh_qmesh_set_value(c->indirect, vids[i], E + 3 * (size_t)i, &err) == LM_OK);
        CHECK(cache_outdate_all(c, &err) == LM_OK);
        uint64_t allowance = 40, cost = 0;
        uint32_t taken = 0;
        CHECK(cache_regather_outdated(c, NULL, NULL, &allowance, &err) == LM_OK);
        for (uint32_t i = 0; i < n; ++i)
            if (!c->src.outdated[vids[i]]) {
                taken++;
                cost += cache_gather_cost(c, vids[i]);
            }
        printf("outdated under an allowance of 40: %u values gathered again, %llu plain gathers' worth, %llu left\n",
               taken, (unsigned long long)cost, (unsigned long long)allowance);
        CHECK_MSG(taken > 0 && taken <= 10 && cost <= 40 && cost + allowance == 40 && allowance < 16,
                  "%u values taken for %llu of an allowance of 40, %llu left", taken, (unsigned long long)cost,
                  (unsigned long long)allowance);
        CHECK(cache_regather_outdated(c, NULL, NULL, NULL, &err) == LM_OK); /* the rest */
    }
    free(vids);
    free(E);
    cache_destroy(c);
    samp_destroy(sp);
    scene_destroy(s);
}

static void test_sphere_glossy(int bounces)
{
    const double R = 2.0, rho = 0.5, I = 3.0, ks = 0.3, n = 2.0;
    double bias;
    scene *s = load_sphere("cache_gsphere", R, rho, ks, n, I, &bias);
    if (!s) return;
    double series = 0.0;
    for (int k = 0; k < bounces; ++k) series += pow(rho, k);
    const double lobe = (n + 2.0) / (2.0 * M_PI) * I / (R * R), src = rho * I / (M_PI * R * R) * series;
    const double lights = glossy_sphere_mean(s, bounces, CACHE_GLOSSY_DIRECT, 0, lobe, bias, n);
    const double both = glossy_sphere_mean(s, bounces, CACHE_GLOSSY_INDIRECT, 0, lobe + src, bias, n);
    const double moved = glossy_sphere_mean(s, bounces, CACHE_GLOSSY_INDIRECT, 1, lobe + src, bias, n);
    const double part = both - lights, part_moved = moved - lights;
    printf("  the glossy part: %.5f, after the move %.5f (closed form %.5f: %+.2f%%, %+.2f%%)\n", part, part_moved,
           src, 100.0 * (part - src) / src, 100.0 * (part_moved - src) / src);
    /* The source itself is uniform (no facet tilt in it): within 1%, and of the
     * partial sum of the bounces shown. */
    CHECK_MSG(fabs(part - src) / src <= 0.01, "glossy part %.5f vs %.5f", part, src);
    CHECK_MSG(fabs(part_moved - src) / src <= 0.01, "glossy part after the move %.5f vs %.5f", part_moved, src);
    scene_destroy(s);
}

/* A closed cube room (side 2, walls facing in) of albedo kd, a point light
 * inside: `auto` shows one bounce with black walls and several with white ones
 * (issue 13), and a light edit changes every bounce with no light sample: the
 * indirect light of the room with the light halved is half the room's (it is
 * linear in the light, and the gathers are deterministic).
 */
static void test_room_bounces(float kd, int min_bounces, int max_bounces)
{
    static const int quad[6][4][3] = {{{-1, -1, -1}, {1, -1, -1}, {1, -1, 1}, {-1, -1, 1}}, /* floor */
                                      {{-1, 1, -1}, {1, 1, -1}, {1, 1, 1}, {-1, 1, 1}},     /* ceiling */
                                      {{-1, -1, -1}, {-1, 1, -1}, {-1, 1, 1}, {-1, -1, 1}}, /* x = -1 */
                                      {{1, -1, -1}, {1, 1, -1}, {1, 1, 1}, {1, -1, 1}},
                                      {{-1, -1, -1}, {1, -1, -1}, {1, 1, -1}, {-1, 1, -1}}, /* z = -1 */
                                      {{-1, -1, 1}, {1, -1, 1}, {1, 1, 1}, {-1, 1, 1}}};
    char obj[4096] = "", line[128], path[1024], text[1024];
    for (int f = 0; f < 6; ++f)
        for (int k = 0; k < 4; ++k) {
            snprintf(line, sizeof line, "v %d %d %d\n", quad[f][k][0], quad[f][k][1], quad[f][k][2]);
            strcat(obj, line);
        }
    for (int f = 0; f < 6; ++f) {
        /* Wind each face so that its normal points into the room (towards the origin). */
        const int *a = quad[f][0], *b = quad[f][1], *c = quad[f][2];
        double e1[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, e2[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
        double n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
        int in = n[0] * -a[0] + n[1] * -a[1] + n[2] * -a[2] > 0, v = 4 * f + 1;
        if (in)
            snprintf(line, sizeof line, "f %d %d %d\nf %d %d %d\n", v, v + 1, v + 2, v, v + 2, v + 3);
        else
            snprintf(line, sizeof line, "f %d %d %d\nf %d %d %d\n", v, v + 2, v + 1, v, v + 3, v + 2);
        strcat(obj, line);
    }
    test_write_file("cache_room.obj", obj, path, sizeof path);
    snprintf(text, sizeof text,
             "{\"meshes\": [{\"file\": \"cache_room.obj\", \"material\": \"wall\"}],"
             " \"materials\": {\"wall\": {\"kd\": [%g, %g, %g]}},"
             " \"lights\": [{\"type\": \"point\", \"position\": [0.2, 0.5, -0.1], \"intensity\": [2, 2, 2]}],"
             " \"cameras\": [{\"position\": [0, 0, 0.9], \"target\": [0, 0, -1]}]}",
             kd, kd, kd);
    scene *s = test_load_json("cache_room.json", text);
    if (!s) return;
    lm_error err;
    samp_sampler *sp = NULL;
    cache *c = NULL;
    CHECK(samp_create(&(samp_desc){.scene = s, .backend = SAMP_BACKEND_EMBREE, .seed = 3}, &sp, &err) == LM_OK);
    CHECK(cache_create(&(cache_desc){.scene = s, .sampler = sp, .bounces = CACHE_BOUNCES_AUTO}, &c, &err) == LM_OK);
    /* Pixel counts of the camera inside (the walls behind it get none). */
    uint32_t *pixels = malloc(s->tri_count * sizeof *pixels);
    camera_triangle_pixels(s, &s->cameras[0], 160, 120, pixels);
    cache_refine_result res = {0};
    for (int i = 0; i < 40 && c; ++i) {
        CHECK(cache_refine(c, &(cache_refine_desc){.pixels = pixels, .budget = 4096}, &res, &err) == LM_OK);
        if (res.remaining == 0) break;
    }
    cache_stats st;
    if (c) cache_get_stats(c, &st);
    printf("closed room, walls of albedo %.2f: auto shows %d bounce%s (%s; %u coarse vertices, %llu hits, traced in "
           "%.1f ms, %llu updates in %.1f ms)\n",
           (double)kd, st.bounces.bounces, st.bounces.bounces == 1 ? "" : "s", st.bounces.why, st.bounces.vertices,
           (unsigned long long)st.bounces.hits, st.bounces.trace_seconds * 1e3,
           (unsigned long long)st.bounces.updates, st.bounces.update_seconds * 1e3);
    CHECK_MSG(st.bounces.bounces >= min_bounces && st.bounces.bounces <= max_bounces, "auto chose %d bounces",
              st.bounces.bounces);
    /* What auto leaves out is at most a quarter of the JND (2) where seen: the
     * rest is a bias on top of the cache's own error (cache_bounces.c). */
    CHECK_MSG(st.bounces.rest_de <= 0.5f, "auto left out bounces worth dE %.2f", (double)st.bounces.rest_de);
    if (max_bounces > 1 && c) {
        /* B_1 reads L_dd at the transport's hits from the direct mesh; the walls
         * behind the camera too. Against L_dd from G sampled at the hits, summed
         * over all hits (it was 0.857 with the direct mesh left at its roots where
         * no pixel and no visible gather looks: every further bounce a fifth low). */
        const cache_bounce_state *b = &c->bnc;
        uint32_t nh = b->hit_first[b->nv];
        samp_point *pts = malloc(nh * sizeof *pts);
        float *G = malloc(nh * sizeof *G);
        double mesh_sum = 0.0, exact_sum = 0.0;
        uint32_t eval_fail = 0;
        for (uint32_t h = 0; pts && G && h < nh; ++h) {
            uint32_t t = b->hit_tri[h];
            double w1 = b->hit_bary[2 * (size_t)h], w2 = b->hit_bary[2 * (size_t)h + 1];
            const uint32_t *v = s->tris[t].v;
            for (int k = 0; k < 3; ++k)
                pts[h].p[k] = (float)((1 - w1 - w2) * s->positions[3 * (size_t)v[0] + (size_t)k] +
                                      w1 * s->positions[3 * (size_t)v[1] + (size_t)k] +
                                      w2 * s->positions[3 * (size_t)v[2] + (size_t)k]);
            memcpy(pts[h].n, s->tri_normals + 3 * (size_t)t, sizeof pts[h].n);
            pts[h].tri_plus_one = t + 1;
            float L[3] = {0, 0, 0};
            eval_fail += cache_eval_direct(c, t, w1, w2, L, &err) != LM_OK;
            mesh_sum += L[0];
        }
        CHECK(eval_fail == 0);
        CHECK(pts && G && samp_direct(sp, 0, pts, nh, G, &err) == LM_OK);
        for (uint32_t h = 0; pts && G && h < nh; ++h) exact_sum += 2.0 * G[h] / M_PI; /* L_dd = I·G/π, I = 2 */
        printf("  L_dd at the %u transport hits from the direct mesh: %.4f of its sampled value (%u direct vertices "
               "added for it)\n",
               nh, mesh_sum / exact_sum, st.bounces.direct_vertices);
        CHECK_MSG(fabs(mesh_sum / exact_sum - 1.0) <= 0.02, "L_dd at the hits off by %.3f", mesh_sum / exact_sum - 1.0);
        free(pts);
        free(G);
        /* auto would show fewer bounces with the light halved (a darker room needs
         * fewer to be within the JND): the count fixed at auto's for the check. */
        CHECK(cache_set_bounces(c, st.bounces.bounces, &err) == LM_OK);
        enum { N = 500 };
        float before[N][3];
        lm_rng g;
        lm_rng_seed(&g, 4, 0, 0);
        uint32_t tri[N];
        double w[N][2];
        for (int i = 0; i < N; ++i) {
            tri[i] = (uint32_t)(lm_rng_float(&g) * s->tri_count) % s->tri_count;
            w[i][0] = lm_rng_float(&g);
            w[i][1] = lm_rng_float(&g) * (1.0 - w[i][0]);
            CHECK(cache_eval_indirect(c, tri[i], w[i][0], w[i][1], before[i], &err) == LM_OK);
        }
        uint64_t light_samples = st.lights[0].samples;
        const float half[3] = {1, 1, 1};
        CHECK(cache_set_light(c, 0, half, &err) == LM_OK);
        cache_get_stats(c, &st);
        double worst = 0.0;
        for (int i = 0; i < N; ++i) {
            float now[3];
            CHECK(cache_eval_indirect(c, tri[i], w[i][0], w[i][1], now, &err) == LM_OK);
            for (int k = 0; k < 3; ++k) worst = fmax(worst, fabs(now[k] / (0.5 * before[i][k]) - 1.0));
        }
        printf("  light halved: indirect within %.2e of half, light samples %llu -> %llu, %d bounces\n", worst,
               (unsigned long long)light_samples, (unsigned long long)st.lights[0].samples, st.bounces.bounces);
        CHECK(st.lights[0].samples == light_samples);
        CHECK_MSG(worst <= 0.01, "indirect not halved: %.3e", worst);
    }
    free(pixels);
    cache_destroy(c);
    samp_destroy(sp);
    scene_destroy(s);
}

/* The built-in Cornell box at 256×256 (pixels per triangle from a ray-cast ID pass,
 * the renderer's camera): two defects of the converged cache measured against
 * independent Embree estimates.
 *   - Direct: every direct-mesh vertex on the floor in front of the short box (its
 *     umbra and penumbra) against a 4096-ray G. A light leaf whose three corners
 *     were lit used to answer V = 1 for vertices inside it that the box shades, and
 *     those values stayed when the light mesh later learnt better (bright dots).
 *   - Indirect: E_i at points just above the bottom edge of the short box's front
 *     face (in the box's shadow: small) against a gather whose every hit takes its
 *     direct radiance from a 256-ray G — no cache mesh involved. It used to be 30
 *     times too bright: the gathers read the floor's wrong direct values, values
 *     gathered from early sources were never revised, the source's coarse cut
 *     blurred the shadow, and a floor vertex inside the box saw the back of the
 *     box's walls lit. Checked as seen (ΔE of the face's colour with either E_i,
 *     below the JND) and as a sum (within 10%). */
enum { CB_W = 256 };

/* Pixels per triangle: primary rays through the pixel centres (src/scene/camera.h). */
static uint32_t *cornell_pixels(const scene *s, const rt_scene *rt)
{
    uint32_t *px = calloc(s->tri_count, sizeof *px);
    const scene_camera *cam = &s->cameras[0];
    lm_dvec3 pos = dv3_load(cam->position), fwd = dv3_normalize(dv3_sub(dv3_load(cam->target), pos));
    lm_dvec3 right = dv3_normalize(dv3_cross(fwd, dv3_load(cam->up))), up = dv3_cross(right, fwd);
    double ty = tan(0.5 * cam->fov_y_deg * M_PI / 180.0);
    for (int py = 0; py < CB_W && px; ++py)
        for (int x = 0; x < CB_W; ++x) {
            double sx = 2.0 * (x + 0.5) / CB_W - 1.0, sy = 1.0 - 2.0 * (py + 0.5) / CB_W;
            lm_dvec3 d = dv3_normalize(dv3_add(fwd, dv3_add(dv3_scale(right, sx * ty), dv3_scale(up, sy * ty))));
            float o[3] = {cam->position[0], cam->position[1], cam->position[2]}, df[3] = {(float)d.x, (float)d.y, (float)d.z};
            rt_hit h;
            if (rt_intersect(rt, o, df, 0.0f, INFINITY, &h)) px[h.tri]++;
        }
    return px;
}

/* E_i at x from an exact source: 4096 stratified cosine rays; at each hit on the
 * front of a surface kd·L_dd from a 256-ray G (the back sends nothing). */
static void cornell_exact_Ei(const scene *s, const rt_scene *rt, samp_sampler *dsp, const samp_point *x, double E[3])
{
    enum { K = 64 };
    float origin[3];
    samp_point_origin(s, x, samp_point_epsilon(dsp, x), origin);
    lm_vec3 n = v3_normalize(v3_load(x->n));
    float sign = copysignf(1.0f, n.z), a = -1.0f / (sign + n.z), b = n.x * n.y * a;
    lm_vec3 t1 = v3(1.0f + sign * n.x * n.x * a, sign * b, -sign * n.x), t2 = v3(b, sign + n.y * n.y * a, -n.y);
    lm_rng g;
    lm_rng_seed(&g, 99, 7, 0);
    samp_point *hits = malloc(K * K * sizeof *hits);
    uint32_t *ht = malloc(K * K * sizeof *ht), nh = 0;
    for (int j = 0; j < K && hits && ht; ++j)
        for (int i = 0; i < K; ++i) {
            float u = (i + lm_rng_float(&g)) / K, v = (j + lm_rng_float(&g)) / K, r = sqrtf(u), phi = 2.0f * (float)M_PI * v;
            lm_vec3 d = v3_add(v3_add(v3_scale(t1, r * cosf(phi)), v3_scale(t2, r * sinf(phi))),
                               v3_scale(n, sqrtf(fmaxf(0.0f, 1.0f - u))));
            float dir[3];
            v3_store(dir, d);
            rt_hit h;
            if (!rt_intersect(rt, origin, dir, 0.0f, INFINITY, &h) || s->tris[h.tri].light >= 0) continue;
            lm_vec3 ng = v3_load(s->tri_normals + 3 * (size_t)h.tri);
            if (v3_dot(ng, d) >= 0.0f) continue;
            samp_point *y = &hits[nh];
            y->tri_plus_one = h.tri + 1;
            for (int q = 0; q < 3; ++q) y->p[q] = origin[q] + h.t * dir[q];
            v3_store(y->n, ng);
            ht[nh++] = h.tri;
        }
    float *G = malloc((nh ? nh : 1) * sizeof *G);
    lm_error err;
    E[0] = E[1] = E[2] = 0.0;
    if (G && samp_direct(dsp, 0, hits, nh, G, &err) == LM_OK)
        for (uint32_t i = 0; i < nh; ++i)
            for (int q = 0; q < 3; ++q)
                E[q] += s->materials[s->tris[ht[i]].material].kd[q] * s->area_lights[0].le[q] * G[i] / M_PI;
    for (int q = 0; q < 3; ++q) E[q] *= M_PI / (K * K);
    free(hits);
    free(ht);
    free(G);
}

/* cache_desc.corner_ids: made with the first roots (beside them, on a helper
 * thread), each scene corner's vertex-table id, handed over once. */
static void test_corner_ids(void)
{
    scene *s = NULL;
    lm_error err;
    CHECK(scene_load(&(scene_load_desc){.path = NULL, .require_light = 1}, &s, &err) == LM_OK);
    samp_sampler *sp = NULL;
    cache *c = NULL, *plain = NULL;
    if (s) CHECK(samp_create(&(samp_desc){.scene = s, .backend = SAMP_BACKEND_EMBREE}, &sp, &err) == LM_OK);
    if (sp) CHECK(cache_create(&(cache_desc){.scene = s, .sampler = sp, .corner_ids = 1}, &c, &err) == LM_OK);
    if (sp) CHECK(cache_create(&(cache_desc){.scene = s, .sampler = sp}, &plain, &err) == LM_OK);
    if (!c || !plain) goto done;
    CHECK(cache_take_corner_ids(c) == NULL); /* not before the first roots */
    CHECK(cache_init(c, &err) == LM_OK && cache_init(plain, &err) == LM_OK);
    uint32_t *ids = cache_take_corner_ids(c);
    int same = ids != NULL, roots = 0;
    for (uint32_t t = 0; same && t < s->tri_count; ++t) {
        const mesh_qnode *n = mesh_qmesh_node(cache_direct_mesh(c), mesh_qmesh_root(cache_direct_mesh(c), t));
        for (int k = 0; k < 3; ++k) {
            same &= ids[3 * (size_t)t + (size_t)k] == mesh_vtable_corner_id(cache_vtable(c), t, k);
            if (n) same &= ids[3 * (size_t)t + (size_t)k] == n->v[k], roots += k == 0;
        }
    }
    printf("corner ids: made with the first roots, %s the roots' corners (%d roots), taken once: %s\n",
           same ? "equal to" : "NOT equal to", roots, cache_take_corner_ids(c) == NULL ? "yes" : "no");
    CHECK(same && roots > 0 && cache_take_corner_ids(c) == NULL && cache_take_corner_ids(plain) == NULL);
    free(ids);
done:
    cache_destroy(c);
    cache_destroy(plain);
    samp_destroy(sp);
    scene_destroy(s);
}

static void test_cornell_box(void)
{
    scene *s = NULL;
    lm_error err;
    CHECK(scene_load(&(scene_load_desc){.path = NULL, .require_light = 1}, &s, &err) == LM_OK);
    rt_scene *rt = NULL;
    if (!s || rt_scene_create(&(rt_scene_desc){.scene = s}, &rt, &err) != LM_OK) return;
    run u = {0};
    u.pixels = cornell_pixels(s, rt);
    CHECK(samp_create(&(samp_desc){.scene = s, .backend = SAMP_BACKEND_EMBREE}, &u.sp, &err) == LM_OK);
    CHECK(cache_create(&(cache_desc){.scene = s, .sampler = u.sp}, &u.c, &err) == LM_OK);
    cache_refine_result tot = {0};
    for (int i = 0; i < 400 && u.c; ++i) {
        cache_refine_result res;
        CHECK(cache_refine(u.c, &(cache_refine_desc){.pixels = u.pixels, .budget = 512}, &res, &err) == LM_OK);
        tot.tested += res.tested;
        if (res.remaining == 0) break;
    }
    cache_stats st;
    cache_get_stats(u.c, &st);
    tm_desc tm = {.exposure = s->exposure};

    /* Direct: floor vertices in front of the short box (its corners (130, 65),
     * (290, 114) on the floor; the light behind it). */
    samp_sampler *ref = NULL;
    CHECK(samp_create(&(samp_desc){.scene = s, .backend = SAMP_BACKEND_EMBREE, .direct_rays = 4096, .seed = 77}, &ref,
                      &err) == LM_OK);
    const mesh_qmesh *dm = cache_direct_mesh(u.c);
    const mesh_vtable *vt = cache_vtable(u.c);
    mesh_vtable_stats vs;
    mesh_vtable_get_stats(vt, &vs);
    const float *kd = s->materials[s->tris[0].material].kd, *le = s->area_lights[0].le;
    int nv = 0, above = 0, far_off = 0;
    double worst = 0.0;
    float worst_at[3] = {0, 0, 0};
    for (uint32_t id = 0; id < vs.id_limit && ref; ++id) {
        float L[3];
        if (mesh_qmesh_get_value(dm, id, L) != 1) continue;
        const mesh_vertex *mv = mesh_vtable_vertex(vt, id);
        if (mv->tri > 1 || mv->position[0] < 60.0f || mv->position[0] > 300.0f || mv->position[2] > 130.0f) continue;
        samp_point x = {.tri_plus_one = mv->tri + 1};
        memcpy(x.p, mv->position, sizeof x.p);
        memcpy(x.n, mv->normal, sizeof x.n);
        float G, a[3], b[3], da[3], db[3], la[3], lb[3];
        CHECK(samp_direct(ref, 0, &x, 1, &G, &err) == LM_OK);
        for (int k = 0; k < 3; ++k) {
            a[k] = kd[k] * L[k];
            b[k] = kd[k] * le[k] * G / (float)M_PI;
        }
        tm_to_display(&tm, a, da);
        tm_to_display(&tm, b, db);
        tm_display_to_lab(da, la);
        tm_display_to_lab(db, lb);
        double de = tm_delta_e(la, lb);
        if (de > worst) {
            worst = de;
            memcpy(worst_at, mv->position, sizeof worst_at);
        }
        above += de > 2.0;
        far_off += de > 10.0;
        nv++;
    }
    uint64_t light = 0;
    for (uint32_t l = 0; l < st.light_count; ++l) light += st.lights[l].samples;
    printf("Cornell box, 256x256 pixel counts: converged after %u leaves tested; %llu light samples (%llu interpolated), "
           "%llu indirect samples\n",
           tot.tested, (unsigned long long)light, (unsigned long long)st.lights[0].interpolated,
           (unsigned long long)st.indirect.samples);
    printf("  direct at %d floor vertices in front of the short box vs 4096-ray Embree: worst ΔE %.2f at (%.0f, %.0f, "
           "%.0f); %d above the JND, %d above ΔE 10\n",
           nv, worst, worst_at[0], worst_at[1], worst_at[2], above, far_off);
    CHECK(nv > 200);
    /* The cache's own penumbra samples (64 rays) are off by a few per cent of G,
     * which near the umbra is a few ΔE (dark colours are steep in CIELAB); a
     * wrongly lit vertex in the umbra is off by ΔE 30 and more. */
    CHECK_MSG(worst <= 6.0, "a floor vertex in front of the short box is off by ΔE %.2f", worst);
    CHECK_MSG(far_off == 0, "%d floor vertices in front of the short box off by more than ΔE 10", far_off);
    samp_destroy(ref);

    /* Indirect: just above the bottom edge (130, 0, 65)–(290, 0, 114) of the front face. */
    samp_sampler *dsp = NULL;
    CHECK(samp_create(&(samp_desc){.scene = s, .backend = SAMP_BACKEND_EMBREE, .direct_rays = 256, .seed = 3}, &dsp,
                      &err) == LM_OK);
    const double fs[3] = {0.15, 0.5, 0.85}, hs[6] = {0.5, 2, 5, 10, 20, 40};
    double worst_rel = 0.0, worst_seen = 0.0, sum_c = 0.0, sum_x = 0.0;
    printf("  E_i just above the bottom edge of the short box's front face, cache / exact source (RGB mean):\n");
    for (int fi = 0; fi < 3 && dsp; ++fi) {
        printf("   ");
        for (int hi = 0; hi < 6; ++hi) {
            double P[3] = {130 + fs[fi] * 160, hs[hi], 65 + fs[fi] * 49};
            uint32_t tri = 0;
            double w1 = 0, w2 = 0;
            for (uint32_t t = 22; t <= 23; ++t) { /* the face's two triangles */
                const uint32_t *v = s->tris[t].v;
                const float *A = s->positions + 3 * (size_t)v[0], *B = s->positions + 3 * (size_t)v[1],
                            *C = s->positions + 3 * (size_t)v[2];
                double e1x = B[0] - A[0], e1y = B[1] - A[1], e2x = C[0] - A[0], e2y = C[1] - A[1];
                double px = P[0] - A[0], py = P[1] - A[1], det = e1x * e2y - e2x * e1y;
                double a1 = (px * e2y - e2x * py) / det, a2 = (e1x * py - px * e1y) / det;
                if (a1 >= -1e-9 && a2 >= -1e-9 && a1 + a2 <= 1 + 1e-9) {
                    tri = t;
                    w1 = a1;
                    w2 = a2;
                    break;
                }
            }
            CHECK(tri == 22 || tri == 23);
            float Ec[3];
            CHECK(cache_eval_indirect(u.c, tri, w1, w2, Ec, &err) == LM_OK);
            samp_point x = {.p = {(float)P[0], (float)P[1], (float)P[2]}, .tri_plus_one = tri + 1};
            memcpy(x.n, s->tri_normals + 3 * (size_t)tri, sizeof x.n);
            double Ex[3];
            cornell_exact_Ei(s, rt, dsp, &x, Ex);
            double c = (Ec[0] + Ec[1] + Ec[2]) / 3.0, e = (Ex[0] + Ex[1] + Ex[2]) / 3.0;
            printf(" %.4f/%.4f", c, e);
            worst_rel = fmax(worst_rel, fabs(c - e) / (e + 5e-4));
            /* What the viewer sees of the difference: the face's colour with the
             * cache's direct light and either E_i. */
            float Ld[3], seen_c[3], seen_x[3];
            CHECK(cache_eval_direct(u.c, tri, w1, w2, Ld, &err) == LM_OK);
            const float *kd = s->materials[s->tris[tri].material].kd;
            for (int k = 0; k < 3; ++k) {
                seen_c[k] = kd[k] * (Ld[k] + Ec[k] / (float)M_PI);
                seen_x[k] = kd[k] * (Ld[k] + (float)(Ex[k] / M_PI));
            }
            worst_seen = fmax(worst_seen, test_tone_delta_e(&tm, seen_c, seen_x));
            sum_c += c;
            sum_x += e;
        }
        printf("\n");
    }
    printf("   worst |cache − exact| / (exact + 5e-4) %.2f, seen as ΔE %.2f; sums %.4f / %.4f\n", worst_rel,
           worst_seen, sum_c, sum_x);
    CHECK(sum_x > 0.0);
    /* The cache refines to the JND of what is seen: in the box's shadow, where E_i
     * is small, it may be off by more in relative terms (13% with a fifth of
     * each round's leaves to the indirect mesh, 55% at one point with rounds shared
     * by cost, both below the JND as seen); the defect was 30 times. */
    CHECK_MSG(worst_rel <= 1.0, "E_i off by %.0f%% at the bottom of the short box's front face", 100.0 * worst_rel);
    CHECK_MSG(worst_seen <= u.c->desc.jnd, "E_i's error at the bottom of the short box's front face seen as ΔE %.2f",
              worst_seen);
    CHECK_MSG(fabs(sum_c / sum_x - 1.0) <= 0.1, "E_i at the face's bottom %.3f times the exact", sum_c / sum_x);
    samp_destroy(dsp);

    /* The back of a surface sends nothing: a floor point under the short box (inside
     * it) gathers nothing from a constant source, an open one does. */
    uint32_t *first = malloc((s->tri_count + 1) * sizeof *first);
    float *bary = malloc(6 * (size_t)s->tri_count * sizeof *bary), *rad = malloc(9 * (size_t)s->tri_count * sizeof *rad);
    for (uint32_t t = 0; t <= s->tri_count && first && bary && rad; ++t) {
        first[t] = t;
        if (t == s->tri_count) break;
        const float b[6] = {0, 0, 1, 0, 0, 1};
        memcpy(bary + 6 * (size_t)t, b, sizeof b);
        for (int k = 0; k < 9; ++k) rad[9 * (size_t)t + (size_t)k] = 1.0f;
    }
    samp_radiance_mesh one = {s->tri_count, first, bary, rad};
    samp_point inside[2] = {{{200, 0, 150}, {0, 1, 0}, 1}, {{420, 0, 100}, {0, 1, 0}, 1}};
    float Ein[6];
    CHECK(first && bary && rad && samp_indirect(u.sp, &one, inside, 2, Ein, &err) == LM_OK);
    printf("  constant source: E_i %.4f under the short box (inside it), %.4f on the open floor\n", Ein[0], Ein[3]);
    CHECK(Ein[0] == 0.0f && Ein[3] > 1.0f);
    free(first);
    free(bary);
    free(rad);
    stop(&u);
    rt_scene_destroy(rt);
    scene_destroy(s);
}

/* Which side of an emitter emits: the composite adds Le only where the front of
 * the surface is seen (rend_material.frag: gl_FrontFacing; rend_composite.frag),
 * so the cache's JND tests must judge an emitter seen from the back without it.
 * A quad light with kd > 0 facing down onto the plane: its direct and indirect
 * meshes are judged with Le from below, without from above. */
static void test_emitter_side(void)
{
    char light[256];
    snprintf(light, sizeof light,
             "{\"type\": \"quad\", \"corner\": [-0.5, 1, -0.5], \"edge1\": [1, 0, 0], \"edge2\": [0, 0, 1],"
             " \"radiance\": [%g, %g, %g], \"kd\": [0.8, 0.8, 0.8]}",
             LE, LE, LE);
    scene *s = load_lights("cache_emitter_side.json", 0, light);
    CHECK(s != NULL && s->area_light_count == 1);
    if (!s) return;
    const uint32_t lt = s->light_tris[s->area_lights[0].first];
    const scene_material *m = &s->materials[s->tris[lt].material];
    uint32_t leaves[2] = {0, 0};
    for (int above = 0; above < 2; ++above) {
        run u;
        if (!start(&u, s, 40000, 0)) break;
        for (uint32_t t = 2; t < s->tri_count; ++t) u.pixels[t] = 400; /* the light is seen too */
        lm_error err;
        const float eye[3] = {0.3f, above ? 3.0f : 0.5f, 0.2f};
        CHECK(cache_set_camera(u.c, eye, &err) == LM_OK);
        CHECK(cache_sees_front(u.c, lt) == !above);
        cache_refine_result tot;
        CHECK(converge(&u, 200, &tot) == LM_OK);
        /* What the edge test compares equals the composite's formula for the side seen. */
        float ldd[3], ei[3], rgb[3], lab[3], want_lab[3], disp[3];
        CHECK(cache_eval_direct(u.c, lt, 0.3, 0.3, ldd, &err) == LM_OK);
        CHECK(cache_eval_indirect(u.c, lt, 0.3, 0.3, ei, &err) == LM_OK);
        CHECK(ei[0] > 0.0f); /* the plane below lights the light's front */
        cache_seen_lab(u.c, lt, ldd, ei, NULL, lab);
        for (int k = 0; k < 3; ++k)
            rgb[k] = (above ? 0.0f : m->le[k]) + m->kd[k] * (ldd[k] + ei[k] * 0.31830988618379067f);
        tm_to_display(&(tm_desc){.exposure = s->exposure}, rgb, disp);
        tm_display_to_lab(disp, want_lab);
        for (int k = 0; k < 3; ++k)
            CHECK_MSG(fabsf(lab[k] - want_lab[k]) < 1e-4f, "side %d: L* %g, want %g (E_i %g)", above, lab[k],
                      want_lab[k], ei[k]);
        cache_stats st;
        cache_get_stats(u.c, &st);
        leaves[above] = st.direct.mesh.leaves + st.indirect.mesh.leaves;
        stop(&u);
    }
    /* Without Le masking it, the light's own shading is judged as seen: no fewer leaves. */
    printf("  emitter side: %u leaves (direct + indirect) seen from the front, %u from the back\n", leaves[0], leaves[1]);
    CHECK(leaves[1] >= leaves[0]);
    scene_destroy(s);
}

int main(void)
{
    test_lone_light();
    test_blocker();
    test_exposure();
    test_determinism_and_cap();
    test_light_edit();
    test_random_scheduler();
    test_single_mesh();
    test_phong_integral();
    test_specular_outline();
    test_specular();
    test_sphere_indirect(1);
    test_sphere_indirect(2);
    test_sphere_indirect(3);
    test_sphere_indirect(4);
    test_sphere_indirect(CACHE_BOUNCES_AUTO);
    test_outdate_plain();
    test_outdated_keep_rays();
    test_sphere_glossy(1);
    test_sphere_glossy(2);
    test_room_bounces(0.05f, 1, 1);
    test_room_bounces(0.8f, 3, CACHE_BOUNCES_MAX);
    test_emitter_side();
    test_corner_ids();
    test_cornell_box();
    return test_finish("cache_test");
}
