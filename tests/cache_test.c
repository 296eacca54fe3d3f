/* cache_test — the multi-mesh cache (mesh/cache.c, src/cache_refine.c):
 *   - a lone quad light over a plane: after refinement the cached direct radiance
 *     matches Lambert's closed form everywhere within the JND (tone-mapped CIELAB
 *     ΔE), G is exact, and the light mesh samples a small fraction of the
 *     vertices (the visible fraction is 1 everywhere and interpolates; it samples
 *     only to stay within CACHE_LIGHT_LAG levels of the radiance mesh);
 *   - the same with a blocker: the cache against a 4096-ray Embree G at random
 *     points; light samples only where there is penumbra;
 *   - determinism: two caches, same calls, identical statistics;
 *   - the node cap: refinement stops with LM_ERR_NO_MEMORY and a usable cache.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "analytic.h"
#include "cache.h"
#include "ref_shading.h"
#include "samp.h"
#include "samp_internal.h"
#include "test_util.h"
#include "tonemap.h"
#include "vecmath.h"

#define KD 0.6f
#define LE 5.0f

static scene *load_lights(const char *name, int blocker, const char *lights)
{
    char obj[1024], json[1024], text[2048];
    test_write_file("cache_plane.obj", "v -2 0 -2\nv 2 0 -2\nv 2 0 2\nv -2 0 2\nf 1 4 3\nf 1 3 2\n", obj, sizeof obj);
    test_write_file("cache_blocker.obj", "v -0.2 0.5 -0.2\nv 0.2 0.5 -0.2\nv 0.2 0.5 0.2\nv -0.2 0.5 0.2\nf 1 2 3\nf 1 3 4\n",
                    obj, sizeof obj);
    snprintf(text, sizeof text,
             "{\"meshes\": [{\"file\": \"cache_plane.obj\", \"material\": \"paint\"}%s],"
             " \"materials\": {\"paint\": {\"kd\": [%g, %g, %g]}}, \"lights\": [%s]}",
             blocker ? ", {\"file\": \"cache_blocker.obj\", \"material\": \"paint\"}" : "", KD, KD, KD, lights);
    test_write_file(name, text, json, sizeof json);
    scene *s = NULL;
    lm_error err;
    lm_result r = scene_load(&(scene_load_desc){.path = json, .require_light = 1}, &s, &err);
    CHECK_MSG(r == LM_OK, "%s", err.msg);
    return s;
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

static void lab_of(float radiance, float lab[3])
{
    tm_desc tm = {0};
    float rgb[3] = {KD * radiance, KD * radiance, KD * radiance}, d[3];
    tm_to_display(&tm, rgb, d);
    tm_display_to_lab(d, lab);
}

/* Random point on the plane's central 3×3 (barycentrics in its triangle). */
static void random_plane_point(ref_rng *g, const scene *s, uint32_t *tri, double *w1, double *w2, float p[3])
{
    *tri = ref_rng_float(g) < 0.5f ? 0 : 1;
    double u, v;
    do {
        u = ref_rng_float(g);
        v = ref_rng_float(g);
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
    ref_rng g;
    ref_rng_seed(&g, 3, 0, 0);
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

/* The cache's G of light 0 against a 4096-ray Embree estimate at 1000 random
 * points of the plane, as the ΔE of the diffuse colour: returns the sum of ΔE,
 * *n the points, *above those beyond the JND. */
static double against_embree(const run *u, const scene *s, int *n, int *above)
{
    samp_sampler *ref = NULL;
    lm_error err;
    CHECK(samp_create(&(samp_desc){.scene = s, .backend = SAMP_BACKEND_EMBREE, .direct_rays = 4096}, &ref, &err) ==
          LM_OK);
    ref_rng g;
    ref_rng_seed(&g, 4, 0, 0);
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
        lab_of((float)(LE * G / M_PI), a);
        lab_of((float)(LE * Gr / M_PI), b);
        double de = tm_delta_e(a, b);
        sum_de += de;
        *above += de > 2.0;
        (*n)++;
    }
    samp_destroy(ref);
    return sum_de;
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
        ref_rng g;
        ref_rng_seed(&g, 9, 0, 0);
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
    ref_rng g;
    ref_rng_seed(&g, 6, 0, 0);
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

/* Eq. 6 at plane point p, by hand: Σ L·G(p)·(n+2)/(2π)·cosⁿα, α between the
 * mirror of the direction to the light's centre and the direction to the eye. */
static double specular_by_hand(const scene *s, const float p[3], const float eye[3], double n_exp)
{
    const float up[3] = {0, 1, 0};
    const scene_area_light *L = &s->area_lights[0];
    double G = samp_area_light_unoccluded(s, 0, p, up);
    lm_dvec3 x = dv3(p[0], p[1], p[2]), wi = dv3_normalize(dv3_sub(dv3_load(L->centroid), x));
    lm_dvec3 wo = dv3_normalize(dv3_sub(dv3_load(eye), x));
    lm_dvec3 mirror = dv3(-wi.x, wi.y, -wi.z); /* about the normal (0, 1, 0) */
    double cosa = dv3_dot(mirror, wo);
    return cosa > 0.0 ? L->le[0] * G * (n_exp + 2.0) / (2.0 * M_PI) * pow(cosa, n_exp) : 0.0;
}

/* The specular mesh: none without gloss; over the glossy triangles only; it
 * converges to eq. 6 within the JND; a camera move resets it alone. */
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
        ref_rng g;
        ref_rng_seed(&g, 12, 0, 0);
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
        printf("specular, eye %d: %u leaves in the specular mesh, %llu values; against eq. 6 by hand: mean ΔE %.3f, "
               "worst %.3f, %d of %d above the JND\n",
               e, st.specular.mesh.leaves, (unsigned long long)st.specular.samples, sum / n, worst, above, n);
        CHECK_MSG(above <= n / 100, "%d points beyond the JND", above);
        CHECK_MSG(sum / n <= 0.3, "mean ΔE %.3f", sum / n);
    }
    stop(&u);
    scene_destroy(s);
}

/* Closed form for the indirect pipeline: a point light of intensity I at the
 * centre of a closed sphere of radius R and albedo ρ. At every point
 * L_dd = I/(πR²) per unit albedo and the one-bounce E_i = ρ·I/R², so the pixel is
 * ρ·I/(πR²)·(1 + ρ) (the reference renderer's closed form). With two bounces
 * E_i = ρ·I/R²·(1 + ρ) and the pixel ρ·I/(πR²)·(1 + ρ + ρ²). The icosphere's flat
 * facets move both by at most a known relative bound (test_write_icosphere). */
static void test_sphere_indirect(int bounces)
{
    const double R = 2.0, rho = 0.5, I = 3.0;
    char obj[1024], json[1024], text[1024];
    snprintf(obj, sizeof obj, "%s/cache_sphere.obj", LUMESH_TMP_DIR);
    double bias = test_write_icosphere(3, R, obj);
    snprintf(text, sizeof text,
             "{\"meshes\": [{\"file\": \"cache_sphere.obj\", \"material\": \"grey\"}],"
             " \"materials\": {\"grey\": {\"kd\": [%g, %g, %g]}},"
             " \"lights\": [{\"type\": \"point\", \"position\": [0, 0, 0], \"intensity\": [%g, %g, %g]}],"
             " \"cameras\": [{\"position\": [0, 0, 0], \"target\": [1, 0, 0]}]}",
             rho, rho, rho, I, I, I);
    test_write_file("cache_sphere.json", text, json, sizeof json);
    scene *s = NULL;
    lm_error err;
    CHECK(scene_load(&(scene_load_desc){.path = json, .crease_angle_deg = 0.01f}, &s, &err) == LM_OK);
    if (!s) return;
    samp_sampler *sp = NULL;
    cache *c = NULL;
    CHECK(samp_create(&(samp_desc){.scene = s, .backend = SAMP_BACKEND_EMBREE, .indirect_rays = 1024}, &sp, &err) ==
          LM_OK);
    CHECK(cache_create(&(cache_desc){.scene = s, .sampler = sp, .bounces = bounces}, &c, &err) == LM_OK);
    uint32_t *pixels = malloc(s->tri_count * sizeof *pixels);
    for (uint32_t t = 0; t < s->tri_count; ++t) pixels[t] = 64;
    cache_refine_result res = {0};
    for (int i = 0; i < 50 && c; ++i) {
        CHECK(cache_refine(c, &(cache_refine_desc){.pixels = pixels, .budget = 4096}, &res, &err) == LM_OK);
        if (res.remaining == 0) break;
    }
    ref_rng g;
    ref_rng_seed(&g, 8, 0, 0);
    double ldd_want = I / (M_PI * R * R), ei_want = rho * I / (R * R) * (bounces == 2 ? 1.0 + rho : 1.0);
    double worst_ldd = 0.0, worst_ei = 0.0, mean_ei = 0.0;
    const int N = 2000;
    for (int i = 0; i < N && c; ++i) {
        uint32_t tri = (uint32_t)(ref_rng_float(&g) * s->tri_count) % s->tri_count;
        double u = ref_rng_float(&g), v = ref_rng_float(&g);
        if (u + v > 1.0) {
            u = 1.0 - u;
            v = 1.0 - v;
        }
        float ldd[3], ei[3];
        CHECK(cache_eval_direct(c, tri, u, v, ldd, &err) == LM_OK);
        CHECK(cache_eval_indirect(c, tri, u, v, ei, &err) == LM_OK);
        worst_ldd = fmax(worst_ldd, fabs(ldd[0] - ldd_want) / ldd_want);
        worst_ei = fmax(worst_ei, fabs(ei[0] - ei_want) / ei_want);
        mean_ei += ei[0] / N;
    }
    cache_stats st;
    if (c) cache_get_stats(c, &st);
    printf("sphere, point light at the centre, %d bounce%s (%u facets, facet bias bound %.2e): L_dd worst relative "
           "error %.2e, E_i worst %.2e, mean E_i %.5f (closed form %.5f); %llu indirect samples\n",
           bounces, bounces == 2 ? "s" : "", s->tri_count, bias, worst_ldd, worst_ei, mean_ei, ei_want,
           c ? (unsigned long long)st.indirect.samples : 0ull);
    CHECK(res.remaining == 0);
    CHECK_MSG(worst_ldd <= bias + 1e-5, "L_dd off by %.3e", worst_ldd);
    CHECK_MSG(worst_ei <= bias + 0.02, "E_i off by %.3e", worst_ei);
    CHECK_MSG(fabs(mean_ei - ei_want) / ei_want <= bias + 0.005, "mean E_i %.5f vs %.5f", mean_ei, ei_want);
    free(pixels);
    cache_destroy(c);
    samp_destroy(sp);
    scene_destroy(s);
}

int main(void)
{
    test_lone_light();
    test_blocker();
    test_determinism_and_cap();
    test_light_edit();
    test_random_scheduler();
    test_single_mesh();
    test_specular();
    test_sphere_indirect(1);
    test_sphere_indirect(2);
    return test_finish("cache_test");
}
