/* cache_indirect_test — indirect light in the multi-mesh cache where it is hard
 * (issue: interiors lit through an opening; docs/cache.md): a slot. Two rooms
 * joined by a slit in the wall between them, the far room lit by a quad light on
 * that wall's far side (it cannot see through the slit: the near room has no
 * direct light at all). Only the near room is "seen" (pixels), so the far room's
 * direct mesh, the indirect source, is refined for what the near room's gathers
 * draw from it (importance) or not at all.
 *   - the source: gathered with 65,536 Embree rays, the cache's source after
 *     refinement gives E_i at points of the near room within 3% of the exactly
 *     lit source (the far room is convex, so its unoccluded direct light is
 *     exact, cut 64² times finer than the scene's triangles). Measured 2.0%: the
 *     source is refined to the JND, about 2.5% at these levels. The coarse
 *     cache's source is wrong there by more than 5%, so the check can fail;
 *   - the cache's own E_i (its gathers interpolated): within 25% (measured
 *     13.5-15.5% at worst from run to run, 19% since the rounds are shared by
 *     cost, 19.5% with the gathers toward the source, 23.3% with the plain count
 *     first, 17.7% with a quarter of the guided rays cosine-weighted, 19.3%
 *     with the start's count, 13.4% with finer gathers guided by pilots of their
 *     own (docs/cache.md, "Finer gathers, finer guides"); the
 *     issue's target, 5%, is not met yet: the worst receivers' leaves have
 *     corners within 5% of the exact values and midpoints 10-27% off the linear
 *     interpolation, which the gathers' noise hides: σ 17-40% at 256 rays;
 *     docs/cache.md, "Gathers toward the source" and "A quarter of the rays
 *     cosine-weighted"). Measured when the edge tests have settled, before the
 *     finer gathers (which cost 6× the samples here and do not help);
 *   - at JND 1 (a viewer who asks for ΔE 1), 150 rounds more bring every
 *     receiver within 5% (measured 4.3%; 9.7% before differences past white
 *     were judged inside the leaf: cache_midpoint_seen_de);
 *   - gathers toward the source (samp_point.toward_source, MIS with points
 *     picked by power) at the receivers: unbiased (32 gathers' mean within 4
 *     standard errors of the 65,536-ray value) and, through the slit, less noisy
 *     than the cosine rays (variance 0.23 of theirs, required below 0.5); a
 *     4,096-ray gather guided by a 4,096-ray pilot of its own, as the cache's
 *     finer gathers are, at least twice as precise a ray as one guided by the
 *     256-ray pilot, its pilot's rays counted (measured 3.7×).
 * The error estimate (cache_estimate_error) against the error: the same box's
 * floor with 4, 64 and 1024 rays a gather, against 65,536-ray gathers from the
 * cache's own source; within 2× either way (estimated/measured 5.83/3.41,
 * 1.13/0.92, 0.57/0.43; with interpolation and noise added instead of in
 * quadrature 7.34/3.41 at 4 rays), and "converged" only with the measured error
 * below the JND.
 * Noise alone does not refine: a closed box whose floor has only indirect light
 * (smooth), the floor the only thing seen, gathered with 16 rays (one gather's
 * noise moves the floor's colour by ΔE 8, measured here and required above 2),
 * ends with at most half as many indirect leaves again as with 4096 rays, + 8
 * (measured: 51 and 66, 42 and 42 before; with the edge test blind to noise,
 * CACHE_NOISE_SIGMAS 0: 522, 234 before).
 * Two meshes do not mask each other: an edge test judges its midpoint against the
 * other meshes' darkest value over the edge (cache_edge_background), so a direct
 * difference that their spread interpolation would hide (ΔE 0) shows (ΔE 100), and
 * a mesh whose leaf there has not passed its own test yet masks nothing.
 * A floor that runs on under a wall between a lit and a dark room: with noisy
 * gathers no leaf of the dark room's floor draws on a corner beyond the wall
 * (corners_parted), E_i 0 at the wall's foot (0.36 without the rule).
 * Differences hidden in white (cache_midpoint_seen_de): a midpoint's fresh value
 * and its interpolation both past the display's white are judged also on the way
 * to the leaf's darker corner, where its interpolation carries the difference
 * (the slot's wall leaf by the slit, 9% too dark inside, passed its tests
 * before: docs/cache.md).
 * And samp_point_pull_inside, which keeps a floor vertex beyond a wall from
 * gathering the next room: such a point moves to the near side of the wall; one
 * behind a skirting board, or in the open, stays; and samp_points_parted (a wall
 * or a skirting board between two floor points, or nothing).
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "mesh/cache/cache.h"
#include "mesh/cache/cache_internal.h"
#include "sampling/samp.h"
#include "src/base/tonemap.h"
#include "src/base/vecmath.h"
#include "tests/test_util.h"

/* ---- geometry ------------------------------------------------------------- */

typedef struct obj_buf {
    char text[16384];
    size_t len;
    int verts;
} obj_buf;

/* A quad c, c+e1, c+e1+e2, c+e2 facing n (wound so that it does). */
static void quad(obj_buf *o, const double c[3], const double e1[3], const double e2[3], const double n[3])
{
    double x[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
    int flip = x[0] * n[0] + x[1] * n[1] + x[2] * n[2] < 0.0;
    const double *a = flip ? e2 : e1, *b = flip ? e1 : e2;
    double p[4][3];
    for (int k = 0; k < 3; ++k) {
        p[0][k] = c[k];
        p[1][k] = c[k] + a[k];
        p[2][k] = c[k] + a[k] + b[k];
        p[3][k] = c[k] + b[k];
    }
    for (int i = 0; i < 4; ++i)
        o->len += (size_t)snprintf(o->text + o->len, sizeof o->text - o->len, "v %.9g %.9g %.9g\n", p[i][0], p[i][1],
                                   p[i][2]);
    o->len += (size_t)snprintf(o->text + o->len, sizeof o->text - o->len, "f %d %d %d %d\n", o->verts + 1,
                               o->verts + 2, o->verts + 3, o->verts + 4);
    o->verts += 4;
}

/* An axis-aligned rectangle in the plane axis = at, spanning [lo, hi] in the two
 * other axes (in order), facing sign along axis. */
static void rect(obj_buf *o, int axis, double at, const double lo[2], const double hi[2], double sign)
{
    int u = (axis + 1) % 3, v = (axis + 2) % 3;
    double c[3] = {0}, e1[3] = {0}, e2[3] = {0}, n[3] = {0};
    c[axis] = at;
    c[u] = lo[0];
    c[v] = lo[1];
    e1[u] = hi[0] - lo[0];
    e2[v] = hi[1] - lo[1];
    n[axis] = sign;
    quad(o, c, e1, e2, n);
}

/* The near room x ∈ [0, 0.98], the far room x ∈ [1, 2], both y, z ∈ [0, 1]; the
 * wall between them (0.98 to 1) has a slit y ∈ [0.45, 0.55], z ∈ [0.3, 0.7]. */
#define WALL_NEAR 0.98
#define SLIT_Y0 0.45
#define SLIT_Y1 0.55
#define SLIT_Z0 0.3
#define SLIT_Z1 0.7

static void wall_with_slit(obj_buf *o, double x, double sign)
{
    /* rect(axis 0): spans (y, z) */
    rect(o, 0, x, (double[2]){0, 0}, (double[2]){SLIT_Y0, 1}, sign);
    rect(o, 0, x, (double[2]){SLIT_Y1, 0}, (double[2]){1, 1}, sign);
    rect(o, 0, x, (double[2]){SLIT_Y0, 0}, (double[2]){SLIT_Y1, SLIT_Z0}, sign);
    rect(o, 0, x, (double[2]){SLIT_Y0, SLIT_Z1}, (double[2]){SLIT_Y1, 1}, sign);
}

static void slot_rooms(obj_buf *o)
{
    /* near room: floor, ceiling, x = 0, z = 0, z = 1 (rect axis 1 spans (z, x), axis 2 spans (x, y)) */
    rect(o, 1, 0, (double[2]){0, 0}, (double[2]){1, WALL_NEAR}, 1);
    rect(o, 1, 1, (double[2]){0, 0}, (double[2]){1, WALL_NEAR}, -1);
    rect(o, 0, 0, (double[2]){0, 0}, (double[2]){1, 1}, 1);
    rect(o, 2, 0, (double[2]){0, 0}, (double[2]){WALL_NEAR, 1}, 1);
    rect(o, 2, 1, (double[2]){0, 0}, (double[2]){WALL_NEAR, 1}, -1);
    /* far room */
    rect(o, 1, 0, (double[2]){0, 1}, (double[2]){1, 2}, 1);
    rect(o, 1, 1, (double[2]){0, 1}, (double[2]){1, 2}, -1);
    rect(o, 0, 2, (double[2]){0, 0}, (double[2]){1, 1}, -1);
    rect(o, 2, 0, (double[2]){1, 0}, (double[2]){2, 1}, 1);
    rect(o, 2, 1, (double[2]){1, 0}, (double[2]){2, 1}, -1);
    /* the wall: its two faces and the slit's four sides (facing into the slit) */
    wall_with_slit(o, WALL_NEAR, -1);
    wall_with_slit(o, 1, 1);
    rect(o, 1, SLIT_Y0, (double[2]){SLIT_Z0, WALL_NEAR}, (double[2]){SLIT_Z1, 1}, 1);
    rect(o, 1, SLIT_Y1, (double[2]){SLIT_Z0, WALL_NEAR}, (double[2]){SLIT_Z1, 1}, -1);
    rect(o, 2, SLIT_Z0, (double[2]){WALL_NEAR, SLIT_Y0}, (double[2]){1, SLIT_Y1}, 1);
    rect(o, 2, SLIT_Z1, (double[2]){WALL_NEAR, SLIT_Y0}, (double[2]){1, SLIT_Y1}, -1);
}

static scene *load(const char *name, const obj_buf *o, const char *lights)
{
    char obj_name[64], obj[1024], json[1024], text[4096];
    snprintf(obj_name, sizeof obj_name, "%s.obj", name);
    test_write_file(obj_name, o->text, obj, sizeof obj);
    snprintf(text, sizeof text,
             "{\"meshes\": [{\"file\": \"%s\", \"material\": \"white\"}],"
             " \"materials\": {\"white\": {\"kd\": [0.7, 0.7, 0.7]}}, \"lights\": [%s],"
             " \"cameras\": [{\"position\": [0.5, 0.5, 0.5], \"target\": [0, 0.5, 0.5]}]}",
             obj_name, lights);
    char json_name[64];
    snprintf(json_name, sizeof json_name, "%s.json", name);
    test_write_file(json_name, text, json, sizeof json);
    scene *s = NULL;
    lm_error err;
    lm_result r = scene_load(&(scene_load_desc){.path = json, .crease_angle_deg = 1.0f}, &s, &err);
    CHECK_MSG(r == LM_OK, "%s", err.msg);
    return s;
}

/* Centroid of scene triangle t. */
static void centroid(const scene *s, uint32_t t, float out[3])
{
    for (int k = 0; k < 3; ++k) {
        out[k] = 0.0f;
        for (int c = 0; c < 3; ++c) out[k] += s->positions[3 * (size_t)s->tris[t].v[c] + (size_t)k] / 3.0f;
    }
}

/* The two rooms joined by the slit (slot_rooms), the far one lit by a quad on the
 * wall's far face, facing +x (edge1 × edge2 = y × z). */
static scene *load_slot(const char *name)
{
    static obj_buf o;
    memset(&o, 0, sizeof o);
    slot_rooms(&o);
    return load(name, &o,
                "{\"type\": \"quad\", \"corner\": [1.001, 0.6, 0.3], \"edge1\": [0, 0.3, 0], "
                "\"edge2\": [0, 0, 0.4], \"radiance\": [5000, 5000, 5000]}");
}

/* Refines until nothing is left to do (or 2,000 rounds); returns whether it
 * said it converged. tests_only: until the first call that gathers noisy values
 * again with more rays (regathered_finer): once no leaf is left to test, or
 * before, once their visible error per ray beats the leaf tests' (docs/cache.md,
 * "Quieter values by their rate"). */
static int refine_all(cache *c, const uint32_t *pixels, int tests_only)
{
    lm_error err;
    for (int i = 0; i < 2000; ++i) {
        cache_refine_result res;
        lm_result r = cache_refine(c, &(cache_refine_desc){.pixels = pixels, .budget = 256}, &res, &err);
        CHECK_MSG(r == LM_OK, "%s", err.msg);
        if (r != LM_OK) return 0;
        CHECK(!(res.converged && res.stuck));
        if (res.converged || res.stuck) return res.converged;
        if (tests_only && res.regathered_finer) return 0;
    }
    CHECK_MSG(0, "refinement did not finish in 2000 rounds");
    return 0;
}

/* ---- the slot -------------------------------------------------------------- */

static void test_slot(void)
{
    scene *s = load_slot("slot");
    if (!s) return;
    lm_error err;
    /* Seen: the near room's triangles (x of the centroid < WALL_NEAR), 4,000 pixels each
     * (a 320×240 view of the room spreads about that over its ten triangles). */
    uint32_t *pixels = calloc(s->tri_count, sizeof *pixels);
    for (uint32_t t = 0; t < s->tri_count; ++t) {
        float ct[3];
        centroid(s, t, ct);
        if (ct[0] < WALL_NEAR - 1e-3 && s->tris[t].light < 0) pixels[t] = 4000;
    }
    samp_sampler *sp = NULL, *ref = NULL;
    CHECK(samp_create(&(samp_desc){.scene = s, .backend = SAMP_BACKEND_EMBREE, .indirect_rays = 256}, &sp, &err) ==
          LM_OK);
    CHECK(samp_create(&(samp_desc){.scene = s, .backend = SAMP_BACKEND_EMBREE, .indirect_rays = 65536, .seed = 9},
                      &ref, &err) == LM_OK);
    cache *c = NULL;
    CHECK(cache_create(&(cache_desc){.scene = s, .sampler = sp}, &c, &err) == LM_OK);
    if (!sp || !ref || !c) return;
    CHECK(cache_init(c, &err) == LM_OK);

    /* The exactly lit source: every scene triangle cut 64² times, unoccluded
     * direct (exact here: the far room is convex, the near room behind the light). */
    samp_coarse_mesh exact;
    CHECK(samp_coarse_mesh_build(s, 4096 * s->tri_count, &exact, &err) == LM_OK);
    enum { N = 12 };
    samp_point pts[N];
    uint32_t tris[N];
    double w[N][2];
    uint32_t n = 0;
    /* Receivers: points on the near room's floor, ceiling, back wall (x = 0) and sides. */
    for (uint32_t t = 0; t < s->tri_count && n < N; ++t) {
        if (!pixels[t]) continue;
        double w1 = 0.3, w2 = 0.3;
        const uint32_t *v = s->tris[t].v;
        samp_point x = {.tri_plus_one = t + 1};
        for (int k = 0; k < 3; ++k) {
            x.p[k] = (float)((1.0 - w1 - w2) * s->positions[3 * (size_t)v[0] + (size_t)k] +
                             w1 * s->positions[3 * (size_t)v[1] + (size_t)k] + w2 * s->positions[3 * (size_t)v[2] + (size_t)k]);
            x.n[k] = s->tri_normals[3 * (size_t)t + (size_t)k];
        }
        if (x.p[0] > 0.9f) continue; /* not the wall's own face: it sees the slit edge-on */
        pts[n] = x;
        tris[n] = t;
        w[n][0] = w1;
        w[n][1] = w2;
        n++;
    }
    float want[3 * N], got[3 * N];
    CHECK(samp_indirect(ref, &exact.mesh, pts, n, want, &err) == LM_OK);
    /* The coarse cache's source, gathered exactly. */
    double coarse_worst = 1.0, source_worst = 0.0, worst = 0.0;
    if (c->src.rmesh.first && samp_indirect(ref, &c->src.rmesh, pts, n, got, &err) == LM_OK) {
        coarse_worst = 0.0;
        for (uint32_t i = 0; i < n; ++i) coarse_worst = fmax(coarse_worst, fabs(got[3 * i] - want[3 * i]) / want[3 * i]);
    }
    refine_all(c, pixels, 1);
    CHECK(samp_indirect(ref, &c->src.rmesh, pts, n, got, &err) == LM_OK);
    for (uint32_t i = 0; i < n; ++i) {
        float e[3];
        CHECK(cache_eval_indirect(c, tris[i], w[i][0], w[i][1], e, &err) == LM_OK);
        double rel = fabs(e[0] - want[3 * i]) / want[3 * i], src = fabs(got[3 * i] - want[3 * i]) / want[3 * i];
        worst = fmax(worst, rel);
        source_worst = fmax(source_worst, src);
        CHECK_MSG(src <= 0.03, "receiver %u at (%.2f %.2f %.2f): from the cache's source %.5g, exact source %.5g (%.2f%%)",
                  i, pts[i].p[0], pts[i].p[1], pts[i].p[2], got[3 * i], want[3 * i], 100.0 * src);
        CHECK_MSG(rel <= 0.25, "receiver %u at (%.2f %.2f %.2f): cache %.5g, brute force %.5g (%.1f%%)", i, pts[i].p[0],
                  pts[i].p[1], pts[i].p[2], e[0], want[3 * i], 100.0 * rel);
    }
    /* Gathers toward the source (samp_point.toward_source: three quarters of the
     * rays to points of the source picked by power, combined by MIS) against
     * cosine-weighted ones: 32 gathers of 256 rays at each receiver. Unbiased
     * (their mean within 4 standard errors of the 65,536-ray value), and less
     * noisy here, where the light comes through the slit: measured variance
     * summed over the receivers 0.22-0.24 of the cosine gathers' (0.41-0.43 with
     * half the rays cosine-weighted). Guided by a pilot of the same point
     * (samp_guide: ⅜ of the rays to the strata where the pilot saw light, ⅜ by
     * power), unbiased too, and 0.13-0.14 of the cosine gathers' (0.21-0.22 with
     * half the rays cosine-weighted, 0.30 with the guided strata alone, which a
     * slit fills only in part). */
    double var_sum[3] = {0, 0, 0};
    static uint32_t pilot_count[1], pilot_tri[256];
    static float pilot_weight[256], pilot_stratum[256];
    const samp_guide guide = {.rays = 256, .stratum = pilot_stratum};
    for (uint32_t i = 0; i < n; ++i) {
        CHECK(samp_indirect_sources(sp, &c->src.rmesh, &pts[i], 1,
                                    &(samp_source_hits){.rays = 256, .count = pilot_count, .tri = pilot_tri,
                                                        .weight = pilot_weight, .stratum = pilot_stratum},
                                    &err) == LM_OK);
        for (int toward = 0; toward < 3; ++toward) {
            samp_point q = pts[i];
            q.toward_source = toward > 0;
            double m1 = 0.0, m2 = 0.0;
            enum { PASSES = 32 };
            for (uint32_t pass = 1; pass <= PASSES; ++pass) {
                float e[3], se[3];
                CHECK(samp_indirect_guided(sp, &c->src.rmesh, &q, 1, pass, 1, toward == 2 ? &guide : NULL, e, se,
                                           &err) == LM_OK);
                m1 += e[0] / PASSES;
                m2 += (double)e[0] * e[0] / PASSES;
            }
            const double var = fmax(m2 - m1 * m1, 0.0) * PASSES / (PASSES - 1);
            var_sum[toward] += var;
            CHECK_MSG(fabs(m1 - got[3 * i]) <= 4.0 * sqrt(var / PASSES) + 0.01 * got[3 * i],
                      "receiver %u, %s: mean of 32 gathers %.4g against %.4g (standard error %.3g)", i,
                      toward == 2 ? "guided" : toward ? "toward the source" : "cosine", m1, got[3 * i], sqrt(var / PASSES));
        }
    }
    printf("slot: 256-ray gathers' variance summed over the receivers: cosine %.3g, toward the source %.3g (%.2f), guided %.3g (%.2f)\n",
           var_sum[0], var_sum[1], var_sum[1] / var_sum[0], var_sum[2], var_sum[2] / var_sum[0]);
    /* A finer gather's own guide (cache_source.c, guide_finer): 4,096-ray gathers
     * guided by a pilot of 4,096 rays (64 × 64 strata) against the 256-ray one,
     * 32 each at every receiver. Unbiased against the coarse guide's gathers
     * (the 65,536-ray value is itself 1-2% off at some receivers: cosine rays
     * through the slit), and at least twice as precise a ray, the pilot's
     * counted (measured: relative variances summed 0.0030 against 0.021, 0.14×;
     * 3.7× as precise a ray with the pilot counted). */
    double fine_var[2] = {0, 0}, fine_mean[2], fine_se[2];
    static uint32_t big_count[1], big_tri[4096];
    static float big_weight[4096], big_stratum[4096];
    for (uint32_t i = 0; i < n; ++i)
        for (int fine = 0; fine < 2; ++fine) {
            const uint32_t rays = fine ? 4096 : 256;
            samp_point q = pts[i];
            CHECK(samp_indirect_sources(sp, &c->src.rmesh, &q, 1,
                                        &(samp_source_hits){.rays = rays, .count = big_count, .tri = big_tri,
                                                            .weight = big_weight, .stratum = big_stratum},
                                        &err) == LM_OK);
            const samp_guide g = {.rays = rays, .stratum = big_stratum};
            q.toward_source = 1;
            double m1 = 0.0, m2 = 0.0;
            enum { PASSES = 32 };
            for (uint32_t pass = 1; pass <= PASSES; ++pass) {
                float e[3], se[3];
                CHECK(samp_indirect_guided(sp, &c->src.rmesh, &q, 1, pass, 16, &g, e, se, &err) == LM_OK);
                m1 += e[0] / PASSES;
                m2 += (double)e[0] * e[0] / PASSES;
            }
            const double var = fmax(m2 - m1 * m1, 0.0) * PASSES / (PASSES - 1);
            fine_var[fine] += var / (got[3 * i] * got[3 * i]);
            fine_mean[fine] = m1;
            fine_se[fine] = sqrt(var / PASSES);
            /* Against the coarse guide's mean, unbiased above: the 65,536-ray value
             * is itself 1-2% off here (cosine rays through the slit). */
            if (fine)
                CHECK_MSG(fabs(fine_mean[1] - fine_mean[0]) <= 4.0 * hypot(fine_se[0], fine_se[1]) + 0.005 * fine_mean[0],
                          "receiver %u: 4,096-ray gathers' mean %.4g with the finer guide, %.4g with the coarse one "
                          "(standard errors %.3g, %.3g)",
                          i, fine_mean[1], fine_mean[0], fine_se[1], fine_se[0]);
        }
    printf("slot: 4,096-ray guided gathers' relative variance summed over the receivers: 256-ray guide %.3g, "
           "4,096-ray guide %.3g (%.2f; %.2f counting the pilot's rays)\n",
           fine_var[0], fine_var[1], fine_var[1] / fine_var[0], fine_var[1] * 8192.0 / (fine_var[0] * 4352.0));
    CHECK_MSG(fine_var[1] * 8192.0 < 0.5 * fine_var[0] * 4352.0, "the finer guide: %.3g against %.3g", fine_var[1],
              fine_var[0]);
    CHECK_MSG(var_sum[1] < 0.5 * var_sum[0], "toward the source %.3g against cosine %.3g", var_sum[1], var_sum[0]);
    CHECK_MSG(var_sum[2] < 0.2 * var_sum[0] && var_sum[2] < 0.8 * var_sum[1], "guided %.3g against cosine %.3g, by power %.3g",
              var_sum[2], var_sum[0], var_sum[1]);
    cache_stats st;
    cache_get_stats(c, &st);
    printf("slot: %u receivers; E_i from the cache's source worst %.2f%% off the exact source (coarse cache's source: "
           "%.1f%%); the cache's E_i worst %.1f%%; direct mesh %u leaves, %llu indirect samples\n",
           n, 100.0 * source_worst, 100.0 * coarse_worst, 100.0 * worst, st.direct.mesh.leaves,
           (unsigned long long)st.indirect.samples);
    CHECK(n >= 8);
    CHECK_MSG(coarse_worst > 0.05, "the coarse source is already within 5%% (%.2f%%): the test shows nothing",
              100.0 * coarse_worst);
    /* A viewer who asks for ΔE 1 (at this exposure 2-5% of the receivers'
     * luminance; ΔE 2 allows 4-9%): refined at JND 1 until nothing is left to do,
     * every receiver is within 5% of the brute-force gather (measured 3.1%).
     * Before differences past white were judged inside the leaf
     * (cache_midpoint_seen_de) the receiver on the wall by the slit stayed 9.9%
     * off for 3,300 rounds: its leaf has a corner past white, and its midpoints'
     * differences were all past white too (docs/cache.md, "Differences hidden in
     * white"). Nothing is left to do after 158 rounds at JND 1: before the
     * rebuilds' flags were probed (cache_drift.c, probe_flagged), the far room's
     * refinement flagged half the near room's values at every rebuild through
     * the wall, and 4,000 rounds (150 s) did not finish (docs/cache.md, "Drift
     * seen through the value's own rays"). It ends stuck, not converged: by the
     * wall beside the slit, which its points see edge-on, 8-9% of the pixels
     * keep a noise that no ray count reaches (values of E 0-0.2 at 64 times the
     * plain rays). */
    enum { SLOT_JND1_ROUNDS = 1000 };
    CHECK(cache_set_jnd(c, 1.0f, &err) == LM_OK);
    cache_refine_result done = {0};
    int rounds = 0;
    while (rounds < SLOT_JND1_ROUNDS && !done.converged && !done.stuck) {
        CHECK(cache_refine(c, &(cache_refine_desc){.pixels = pixels, .budget = 256}, &done, &err) == LM_OK);
        rounds++;
    }
    CHECK_MSG(done.converged || done.stuck, "JND 1: still refining after %d rounds (%u left)", rounds, done.remaining);
    double jnd1_worst = 0.0;
    for (uint32_t i = 0; i < n; ++i) {
        float e[3];
        CHECK(cache_eval_indirect(c, tris[i], w[i][0], w[i][1], e, &err) == LM_OK);
        const double rel = fabs(e[0] - want[3 * i]) / want[3 * i];
        jnd1_worst = fmax(jnd1_worst, rel);
        CHECK_MSG(rel <= 0.05, "JND 1, receiver %u at (%.2f %.2f %.2f): cache %.5g, brute force %.5g (%.1f%%)", i,
                  pts[i].p[0], pts[i].p[1], pts[i].p[2], e[0], want[3 * i], 100.0 * rel);
    }
    cache_get_stats(c, &st);
    printf("slot: at JND 1 %s after %d rounds more (%.1f%% of the pixels estimated above it): the cache's E_i worst "
           "%.1f%% off the brute-force gather; %llu values flagged by a rebuild probed, %llu of them not gathered "
           "again, %llu gathered again\n",
           done.converged ? "converged" : done.stuck ? "stuck" : "still refining", rounds,
           100.0 * done.estimate.above_jnd, 100.0 * jnd1_worst,
           (unsigned long long)st.drift_probed, (unsigned long long)st.drift_cleared,
           (unsigned long long)st.regathered);
    samp_coarse_mesh_free(&exact);
    cache_destroy(c);
    samp_destroy(sp);
    samp_destroy(ref);
    free(pixels);
    scene_destroy(s);
}

/* ---- the first image's owed work waits for the source to settle --------------------- */

/* The slot's rooms seen whole, with the quick start's budgets (cache_desc
 * coarse_gathers, coarse_lights): after cache_regather_indirect the first
 * image's values are owed. The far room's walls by the lamp are a few root
 * triangles with a hot spot, so the first window of direct leaves moves the
 * source's power by far more than the JND allows (cache_sched.owed_wait):
 * while it does, a refine call of the worker's size gathers no owed value and
 * tests direct leaves; once a window moves it less, the owed values are
 * gathered, all of them, and refinement goes on. A caller that waits for the
 * indirect values (wait_for_indirect) is not held. */
static void test_owed_waits(void)
{
    scene *s = load_slot("owed");
    if (!s) return;
    lm_error err;
    uint32_t *pixels = calloc(s->tri_count, sizeof *pixels);
    for (uint32_t t = 0; pixels && t < s->tri_count; ++t) pixels[t] = s->tris[t].light < 0 ? 2000 : 0;
    for (int waits = 0; waits < 2; ++waits) {
        samp_sampler *sp = NULL;
        cache *c = NULL;
        CHECK(samp_create(&(samp_desc){.scene = s, .backend = SAMP_BACKEND_EMBREE, .indirect_rays = 64}, &sp, &err) ==
              LM_OK);
        CHECK(cache_create(&(cache_desc){.scene = s, .sampler = sp, .coarse_gathers = 16, .coarse_lights = 16}, &c,
                           &err) == LM_OK);
        if (!sp || !c || !pixels) {
            cache_destroy(c);
            samp_destroy(sp);
            break;
        }
        CHECK(cache_init_seen(c, pixels, &err) == LM_OK);
        CHECK(cache_regather_indirect(c, &err) == LM_OK);
        cache_stats st0, st;
        cache_get_stats(c, &st0);
        cache_refine_result res = {0};
        int held = 0, calls = 0;
        uint64_t during = 0; /* indirect samples taken while held */
        do {
            cache_stats before;
            cache_get_stats(c, &before);
            CHECK(cache_refine(c, &(cache_refine_desc){.pixels = pixels, .budget = waits ? 512 : 64,
                                                       .wait_for_indirect = !waits},
                               &res, &err) == LM_OK);
            cache_get_stats(c, &st);
            if (c->sched.owed_wait) {
                held++;
                during += st.indirect.samples - before.indirect.samples;
            }
        } while (++calls < 200 && res.outdated > 0);
        printf("owed work: %s, %d refine calls held it (%llu indirect samples taken meanwhile), all owed gathered "
               "after %d calls; %llu direct leaves\n",
               waits ? "the worker's steps" : "wait_for_indirect", held, (unsigned long long)during, calls,
               (unsigned long long)st.direct.mesh.leaves);
        CHECK(res.outdated == 0);
        if (waits) {
            CHECK_MSG(held >= 2, "held for %d calls", held);
            CHECK(during == 0);
        } else {
            CHECK_MSG(held == 0, "a caller waiting for the indirect values held for %d calls", held);
        }
        cache_destroy(c);
        samp_destroy(sp);
    }
    free(pixels);
    scene_destroy(s);
}

/* ---- noise alone does not refine ------------------------------------------------------ */

/* Leaves of the indirect mesh after refining the box room's floor (the only
 * triangles seen) with `rays` a gather. */
static uint32_t floor_indirect_leaves(const scene *s, const uint32_t *pixels, int rays, double *noise_de)
{
    lm_error err;
    samp_sampler *sp = NULL;
    cache *c = NULL;
    CHECK(samp_create(&(samp_desc){.scene = s, .backend = SAMP_BACKEND_EMBREE, .indirect_rays = rays}, &sp, &err) ==
          LM_OK);
    CHECK(sp && cache_create(&(cache_desc){.scene = s, .sampler = sp}, &c, &err) == LM_OK);
    if (!c) {
        samp_destroy(sp);
        return 0;
    }
    CHECK(cache_init(c, &err) == LM_OK);
    refine_all(c, pixels, 1);
    cache_stats st;
    cache_get_stats(c, &st);
    /* How far one gather's noise moves what the viewer sees: at floor points,
     * E ± σ of a plain gather against E, tone mapped (the scene's exposure 0). */
    *noise_de = 0.0;
    int count = 0;
    for (uint32_t t = 0; t < s->tri_count; ++t) {
        if (!pixels[t]) continue;
        const uint32_t *v = s->tris[t].v;
        samp_point x = {.tri_plus_one = t + 1};
        for (int k = 0; k < 3; ++k) {
            x.p[k] = (s->positions[3 * (size_t)v[0] + (size_t)k] + s->positions[3 * (size_t)v[1] + (size_t)k] +
                      s->positions[3 * (size_t)v[2] + (size_t)k]) / 3.0f;
            x.n[k] = s->tri_normals[3 * (size_t)t + (size_t)k];
        }
        float E[3], sig[3], ldd[3];
        CHECK(samp_indirect_noise(sp, &c->src.rmesh, &x, 1, 0, 1, E, sig, &err) == LM_OK);
        CHECK(cache_eval_direct(c, t, 1.0 / 3.0, 1.0 / 3.0, ldd, &err) == LM_OK);
        const float *kd = s->materials[s->tris[t].material].kd;
        float a[3], b[3], da[3], db[3], la[3], lb[3];
        for (int k = 0; k < 3; ++k) {
            a[k] = kd[k] * (ldd[k] + E[k] / (float)M_PI);
            b[k] = kd[k] * (ldd[k] + (E[k] + sig[k]) / (float)M_PI);
        }
        tm_desc tm = {.exposure = s->exposure};
        tm_to_display(&tm, a, da);
        tm_to_display(&tm, b, db);
        tm_display_to_lab(da, la);
        tm_display_to_lab(db, lb);
        *noise_de += tm_delta_e(la, lb);
        count++;
    }
    if (count) *noise_de /= count;
    uint32_t leaves = st.indirect.mesh.leaves;
    cache_destroy(c);
    samp_destroy(sp);
    return leaves;
}

/* A closed unit box (every face towards the inside), lit by a small quad under
 * its ceiling that faces up: the floor has no direct light, and its indirect
 * light, from the lit ceiling and walls, is smooth. Seen: the floor only, 250
 * pixels a triangle (so the size criterion, 256 pixels for indirect leaves,
 * splits nothing: only the edge test can); *pixels: malloc'ed. */
static scene *floor_box(const char *name, uint32_t **pixels)
{
    static obj_buf o;
    memset(&o, 0, sizeof o);
    rect(&o, 1, 0, (double[2]){0, 0}, (double[2]){1, 1}, 1);
    rect(&o, 1, 1, (double[2]){0, 0}, (double[2]){1, 1}, -1);
    rect(&o, 0, 0, (double[2]){0, 0}, (double[2]){1, 1}, 1);
    rect(&o, 0, 1, (double[2]){0, 0}, (double[2]){1, 1}, -1);
    rect(&o, 2, 0, (double[2]){0, 0}, (double[2]){1, 1}, 1);
    rect(&o, 2, 1, (double[2]){0, 0}, (double[2]){1, 1}, -1);
    scene *s = load(name, &o,
                    "{\"type\": \"quad\", \"corner\": [0.4, 0.8, 0.4], \"edge1\": [0, 0, 0.2], "
                    "\"edge2\": [0.2, 0, 0], \"radiance\": [30, 30, 30]}");
    *pixels = NULL;
    if (!s) return NULL;
    *pixels = calloc(s->tri_count, sizeof **pixels);
    for (uint32_t t = 0; t < s->tri_count && *pixels; ++t) {
        float ct[3];
        centroid(s, t, ct);
        if (ct[1] < 1e-3f && s->tris[t].light < 0) (*pixels)[t] = 250;
    }
    return s;
}

static void test_noise_does_not_refine(void)
{
    uint32_t *pixels;
    scene *s = floor_box("box", &pixels);
    if (!s) return;
    double noise_few, noise_many;
    uint32_t few = floor_indirect_leaves(s, pixels, 16, &noise_few);
    uint32_t many = floor_indirect_leaves(s, pixels, 4096, &noise_many);
    printf("noise: indirect leaves with 16 rays a gather %u, with 4096 %u; one 16-ray gather's noise moves the "
           "floor by dE %.2f (4096: %.2f)\n", few, many, noise_few, noise_many);
    CHECK_MSG(noise_few > 2.0, "16-ray gathers are not noisy enough to test anything: dE %.2f", noise_few);
    /* Half as many again: the schedule's order moves either count by 10-25%
     * (42 and 42, 51 and 66, 54 and 42 over the sessions), while an edge test
     * blind to the noise makes eight times as many (522 against 66). */
    CHECK_MSG(few <= many + many / 2 + 8, "noise refined the mesh: %u leaves with 16 rays against %u with 4096", few,
              many);
    free(pixels);
    scene_destroy(s);
}

/* ---- the error estimate against the error ------------------------------------------- */

/* The noisy values gathered again with more rays are chosen by their rays: at
 * their next level (4^(L+1) plain gathers each), as many as the cost given pays
 * for. Counted by values, a worker's step of 512 at the fourth level was 134
 * million rays, 15 s in which the viewer's worker would not answer a move
 * (docs/cache.md, "The finer regathers counted in rays"). */
static void check_noisy_cost(const cache *c, const uint32_t *pixels)
{
    lm_error err;
    uint32_t *all = NULL, *some = NULL, na = 0, ns = 0;
    CHECK(cache_noisy_vertices(c, pixels, UINT64_MAX, &all, &na, NULL, &err) == LM_OK);
    CHECK(cache_noisy_vertices(c, pixels, 40, &some, &ns, NULL, &err) == LM_OK);
    uint64_t cost_all = 0, cost_some = 0, most = 0;
    uint32_t finer = 0;
    for (uint32_t i = 0; i < na; ++i) {
        cost_all += cache_gather_finer_cost(c, all[i]);
        finer += cache_gather_level(c, all[i]) > 0;
    }
    for (uint32_t i = 0; i < ns; ++i) {
        const uint64_t one = cache_gather_finer_cost(c, some[i]);
        cost_some += one;
        most = one > most ? one : most;
    }
    printf("noisy values: %u, %u of them already finer (%llu plain gathers' worth at their next level); for 40: %u "
           "(%llu)\n",
           na, finer, (unsigned long long)cost_all, ns, (unsigned long long)cost_some);
    CHECK_MSG(finer > 0 && cost_all > 200, "%u noisy values (%u finer), %llu plain gathers' worth: too few to test", na,
              finer, (unsigned long long)cost_all);
    /* A leaf's corners go together: the last leaf may add up to three. */
    CHECK_MSG(ns > 0 && ns < na && cost_some >= 40 && cost_some < 40 + 3 * most,
              "%u of %u values for 40 plain gathers' worth: %llu", ns, na, (unsigned long long)cost_some);
    free(all);
    free(some);
}

/* The box room's floor refined with `rays` a gather: the cache's estimate of its
 * mean ΔE (cache_estimate_error) and the ΔE measured against gathers of 65,536
 * rays from the same source at 16 points a seen triangle (pixel-weighted). */
static void floor_estimate(const scene *s, const uint32_t *pixels, int rays, cache_estimate *est, double *measured,
                           int *converged)
{
    lm_error err;
    samp_sampler *sp = NULL, *ref = NULL;
    cache *c = NULL;
    *measured = 0.0;
    *converged = 0;
    memset(est, 0, sizeof *est);
    CHECK(samp_create(&(samp_desc){.scene = s, .backend = SAMP_BACKEND_EMBREE, .indirect_rays = rays}, &sp, &err) ==
          LM_OK);
    CHECK(samp_create(&(samp_desc){.scene = s, .backend = SAMP_BACKEND_EMBREE, .indirect_rays = 65536, .seed = 5},
                      &ref, &err) == LM_OK);
    CHECK(sp && ref && cache_create(&(cache_desc){.scene = s, .sampler = sp}, &c, &err) == LM_OK);
    if (!c) {
        samp_destroy(sp);
        samp_destroy(ref);
        return;
    }
    CHECK(cache_init(c, &err) == LM_OK);
    if (rays == 4) { /* noisy values in plenty: before the first finer regathers */
        refine_all(c, pixels, 1);
        check_noisy_cost(c, pixels);
        /* They compete with the leaf tests by their rate (visible error removed
         * per ray): none at a rate no value reaches, some at any rate. */
        uint32_t none = 0, some = 0;
        CHECK(cache_requeue_noisy(c, pixels, 256, INFINITY, &none, &err) == LM_OK);
        CHECK(cache_requeue_noisy(c, pixels, 256, 0.0, &some, &err) == LM_OK);
        CHECK_MSG(none == 0 && some > 0, "quieter values at an unreachable rate: %u, at any rate: %u", none, some);
    }
    *converged = refine_all(c, pixels, 0);
    CHECK(cache_estimate_error(c, pixels, est, &err) == LM_OK);
    CHECK(*converged == cache_estimate_converged(est));
    double sum = 0.0, weight = 0.0;
    tm_desc tm = {.exposure = s->exposure};
    for (uint32_t t = 0; t < s->tri_count; ++t) {
        if (!pixels[t]) continue;
        const uint32_t *v = s->tris[t].v;
        const float *kd = s->materials[s->tris[t].material].kd;
        for (int i = 0; i < 4; ++i)
            for (int j = 0; j < 4 - i; ++j) { /* a lattice inside the triangle */
                double w1 = (i + 0.5) / 5.0, w2 = (j + 0.5) / 5.0;
                samp_point x = {.tri_plus_one = t + 1};
                for (int k = 0; k < 3; ++k) {
                    const float *p0 = s->positions + 3 * (size_t)v[0], *p1 = s->positions + 3 * (size_t)v[1],
                                *p2 = s->positions + 3 * (size_t)v[2];
                    x.p[k] = (float)((1.0 - w1 - w2) * p0[k] + w1 * p1[k] + w2 * p2[k]);
                    x.n[k] = s->tri_normals[3 * (size_t)t + (size_t)k];
                }
                float truth[3], cached[3], ldd[3], a[3], b[3], da[3], db[3], la[3], lb[3];
                CHECK(samp_indirect(ref, &c->src.rmesh, &x, 1, truth, &err) == LM_OK);
                CHECK(cache_eval_indirect(c, t, w1, w2, cached, &err) == LM_OK);
                CHECK(cache_eval_direct(c, t, w1, w2, ldd, &err) == LM_OK);
                for (int k = 0; k < 3; ++k) {
                    a[k] = kd[k] * (ldd[k] + cached[k] / (float)M_PI);
                    b[k] = kd[k] * (ldd[k] + truth[k] / (float)M_PI);
                }
                tm_to_display(&tm, a, da);
                tm_to_display(&tm, b, db);
                tm_display_to_lab(da, la);
                tm_display_to_lab(db, lb);
                sum += pixels[t] * (double)tm_delta_e(la, lb);
                weight += pixels[t];
            }
    }
    *measured = weight > 0.0 ? sum / weight : 0.0;
    cache_destroy(c);
    samp_destroy(sp);
    samp_destroy(ref);
}

static void test_estimate(void)
{
    uint32_t *pixels;
    scene *s = floor_box("estimate", &pixels);
    if (!s) return;
    static const int rays[] = {4, 64, 1024};
    for (size_t i = 0; i < sizeof rays / sizeof rays[0]; ++i) {
        cache_estimate e;
        double measured;
        int converged;
        floor_estimate(s, pixels, rays[i], &e, &measured, &converged);
        printf("estimate: %4d rays a gather: estimated dE %.3f (interpolation %.3f, noise %.3f), measured %.3f; "
               "%.1f%% estimated above the JND; %s\n",
               rays[i], e.mean, e.indirect.interpolation, e.indirect.noise, measured, 100.0 * e.above_jnd,
               converged ? "converged" : "not converged");
        /* The estimate follows the error within a factor of two either way (plus
         * 0.1 for what is too small to matter). */
        CHECK_MSG(measured <= 2.0 * e.mean + 0.1, "%d rays: the cache estimates dE %.3f, the error is %.3f", rays[i],
                  e.mean, measured);
        CHECK_MSG(e.mean <= 2.0 * measured + 0.1, "%d rays: the cache estimates dE %.3f, the error is only %.3f",
                  rays[i], e.mean, measured);
        /* Converged means right: said only with the error below the JND. */
        CHECK_MSG(!converged || measured < e.jnd, "%d rays: converged with dE %.3f", rays[i], measured);
        /* And reached, even at 4 rays: a leaf that only its values' noise keeps
         * above the JND (its test blocked by the noise, or too small to test and
         * its corners' contrast no more than their noise) gets quieter values
         * (cache_estimate.c, visit_noisy). Before, the 4-ray floor stopped "stuck"
         * at 21% of its pixels above the JND (measured dE 4.78; docs/cache.md,
         * "Leaves the noise kept whole"). */
        CHECK_MSG(converged, "%d rays: refinement stopped without converging (%.1f%% above the JND, measured dE %.3f)",
                  rays[i], 100.0 * e.above_jnd, measured);
    }
    free(pixels);
    scene_destroy(s);
}

/* ---- a floor that runs on under a wall (cause 4) ------------------------------------ */

/* The floor triangle (facing +y at y = 0) under point (x, z), + 1; 0 if none. */
static uint32_t floor_tri(const scene *s, float x, float z)
{
    for (uint32_t t = 0; t < s->tri_count; ++t) {
        if (s->tri_normals[3 * (size_t)t + 1] < 0.99f) continue;
        const float *p[3];
        for (int k = 0; k < 3; ++k) p[k] = s->positions + 3 * (size_t)s->tris[t].v[k];
        if (fabsf(p[0][1]) > 1e-6f) continue;
        int sign = 0, in = 1;
        for (int k = 0; k < 3 && in; ++k) {
            const float *a = p[k], *b = p[(k + 1) % 3];
            float cr = (b[0] - a[0]) * (z - a[2]) - (b[2] - a[2]) * (x - a[0]);
            int sg = cr > 0.0f ? 1 : cr < 0.0f ? -1 : 0;
            if (sg && sign && sg != sign) in = 0;
            if (sg) sign = sg;
        }
        if (in) return t + 1;
    }
    return 0;
}

static void test_pull_inside(void)
{
    static obj_buf o;
    memset(&o, 0, sizeof o);
    /* A floor x ∈ [0, 2] (its triangles' centroids at x < 1.4), a wall at x = 1.6
     * standing on it (a slab 1.6 to 1.65, height 1), and a skirting board 0.02
     * high at x ∈ [0.2, 0.25]. */
    rect(&o, 1, 0, (double[2]){0, 0}, (double[2]){1, 2}, 1);
    rect(&o, 0, 1.6, (double[2]){0, 0}, (double[2]){1, 1}, -1);
    rect(&o, 0, 1.65, (double[2]){0, 0}, (double[2]){1, 1}, 1);
    rect(&o, 0, 0.2, (double[2]){0, 0}, (double[2]){0.02, 1}, -1);
    rect(&o, 0, 0.25, (double[2]){0, 0}, (double[2]){0.02, 1}, 1);
    rect(&o, 1, 0.02, (double[2]){0, 0.2}, (double[2]){1, 0.25}, 1);
    scene *s = load("pull", &o,
                    "{\"type\": \"quad\", \"corner\": [0, 2, 0], \"edge1\": [1, 0, 0], "
                    "\"edge2\": [0, 0, 1], \"radiance\": [1, 1, 1]}");
    if (!s) return;
    samp_sampler *sp = NULL;
    lm_error err;
    CHECK(samp_create(&(samp_desc){.scene = s, .backend = SAMP_BACKEND_EMBREE}, &sp, &err) == LM_OK);
    if (!sp) return;
    const float xs[3] = {1.8f, 0.1f, 1.0f}; /* beyond the wall; behind the skirting; in the open */
    samp_point pt[3];
    int moved[3];
    for (int i = 0; i < 3; ++i) {
        pt[i] = (samp_point){{xs[i], 0.0f, 0.5f}, {0, 1, 0}, floor_tri(s, xs[i], 0.5f)};
        CHECK(pt[i].tri_plus_one != 0);
        moved[i] = samp_point_pull_inside(sp, &pt[i]);
    }
    printf("pull inside: beyond the wall x 1.8 -> %.4f (moved %d); behind a skirting x 0.1 -> %.4f (%d); "
           "in the open x 1.0 -> %.4f (%d)\n", pt[0].p[0], moved[0], pt[1].p[0], moved[1], pt[2].p[0], moved[2]);
    CHECK_MSG(moved[0] && pt[0].p[0] < 1.6f && pt[0].p[0] > 1.5f, "beyond the wall: x %.4f", pt[0].p[0]);
    CHECK(fabsf(pt[0].p[1]) < 1e-6f);
    CHECK_MSG(!moved[1] && pt[1].p[0] == 0.1f, "behind a skirting board: x %.4f", pt[1].p[0]);
    CHECK_MSG(!moved[2] && pt[2].p[0] == 1.0f, "in the open: x %.4f", pt[2].p[0]);
    /* Parted: beyond the wall from in front of it, behind the skirting from the
     * open; not parted: two points in the open. */
    samp_point far = {{1.8f, 0.0f, 0.5f}, {0, 1, 0}, floor_tri(s, 1.8f, 0.5f)},
               open1 = {{1.0f, 0.0f, 0.5f}, {0, 1, 0}, floor_tri(s, 1.0f, 0.5f)},
               open2 = {{1.3f, 0.0f, 0.7f}, {0, 1, 0}, floor_tri(s, 1.3f, 0.7f)},
               low = {{0.1f, 0.0f, 0.5f}, {0, 1, 0}, floor_tri(s, 0.1f, 0.5f)};
    CHECK(samp_points_parted(sp, &far, &open1));
    CHECK(samp_points_parted(sp, &low, &open1));
    CHECK(!samp_points_parted(sp, &open1, &open2));
    samp_destroy(sp);
    scene_destroy(s);
}

/* ---- the drift bound is a bound ------------------------------------------------ */

/* ΔE at origin x (normal nx) from the source changing from `was` to `now`, by
 * quadrature over every scene triangle's front (n × n sub-triangles, midpoints),
 * unoccluded: what cache_mark_outdated bounds. */
static void exact_change(const scene *s, const samp_radiance_mesh *was, const samp_radiance_index *ixw,
                         const samp_radiance_mesh *now, const samp_radiance_index *ixn, const float x[3],
                         const float nx[3], int n, double out[3])
{
    out[0] = out[1] = out[2] = 0.0;
    for (uint32_t t = 0; t < s->tri_count; ++t) {
        if (s->tris[t].light >= 0) continue;
        const float *p0 = s->positions + 3 * (size_t)s->tris[t].v[0], *p1 = s->positions + 3 * (size_t)s->tris[t].v[1],
                    *p2 = s->positions + 3 * (size_t)s->tris[t].v[2], *nt = s->tri_normals + 3 * (size_t)t;
        const double dA = s->tri_areas[t] / ((double)n * n);
        for (int i = 0; i < n; ++i)
            for (int j = 0; i + j < n; ++j)
                for (int up = 0; up < 2 && (up == 0 || i + j + 1 < n); ++up) {
                    /* the sub-triangle's centroid, in (w1, w2) */
                    double w1 = up ? (i + 2.0 / 3.0) / n : (i + 1.0 / 3.0) / n;
                    double w2 = up ? (j + 2.0 / 3.0) / n : (j + 1.0 / 3.0) / n;
                    double y[3], d[3], r2 = 0.0, cx = 0.0, cy = 0.0;
                    for (int k = 0; k < 3; ++k) {
                        y[k] = (1.0 - w1 - w2) * p0[k] + w1 * p1[k] + w2 * p2[k];
                        d[k] = y[k] - x[k];
                        r2 += d[k] * d[k];
                    }
                    for (int k = 0; k < 3; ++k) {
                        cx += d[k] * nx[k];
                        cy -= d[k] * nt[k];
                    }
                    if (cx <= 0.0 || cy <= 0.0 || r2 <= 0.0) continue;
                    float a[3], b[3];
                    samp_radiance_at(was, ixw, t, (float)w1, (float)w2, a);
                    samp_radiance_at(now, ixn, t, (float)w1, (float)w2, b);
                    const double w = cx * cy / (r2 * r2) * dA;
                    for (int k = 0; k < 3; ++k) out[k] += w * ((double)b[k] - a[k]);
                }
    }
}

/* A copy of the source's arrays (the cache rebuilds its own in place). */
typedef struct source_copy {
    samp_radiance_mesh m;
    uint32_t *first;
    float *bary, *rad;
} source_copy;

static void copy_source(const scene *s, const samp_radiance_mesh *m, source_copy *o)
{
    o->first = malloc((s->tri_count + 1) * sizeof *o->first);
    o->bary = malloc(6 * (size_t)m->tri_count * sizeof *o->bary);
    o->rad = malloc(9 * (size_t)m->tri_count * sizeof *o->rad);
    memcpy(o->first, m->first, (s->tri_count + 1) * sizeof *o->first);
    memcpy(o->bary, m->bary, 6 * (size_t)m->tri_count * sizeof *o->bary);
    memcpy(o->rad, m->radiance, 9 * (size_t)m->tri_count * sizeof *o->rad);
    o->m = (samp_radiance_mesh){.tri_count = m->tri_count, .first = o->first, .bary = o->bary, .radiance = o->rad};
}

/* cache_mark_outdated's drift is a bound (docs/cache.md, "Borrowed values
 * tested": a tree of the changed source triangles, the signed change charged at
 * far nodes): in the floor box (JND 40, so that values are not flagged and their
 * drift keeps adding up; every wall seen at 40,000 pixels, so that the meshes
 * split for size), between a copy of the source and the source after refining
 * on, every indirect value that was neither gathered again nor flagged has
 * drifted, by the cache's account, at least as far as its unoccluded irradiance
 * moved, computed by quadrature (2 × 48² points a triangle; values nearer a wall
 * than 0.1 are left out: the quadrature is poor there). Measured: 60 values, the
 * bound 3.3 times the change on average and never below 2.2 times it, so a bound
 * made three times smaller fails here (46 values, 13 and 7 times, when each round
 * gave the indirect mesh a fifth of its leaves rather than sharing them by cost). */
static void test_drift_is_a_bound(void)
{
    uint32_t *pixels = NULL;
    scene *s = floor_box("drift_box", &pixels);
    if (!s) return;
    for (uint32_t t = 0; t < s->tri_count; ++t) pixels[t] = 40000; /* every wall seen (every value bounded), and split for size */
    lm_error err;
    samp_sampler *sp = NULL;
    cache *c = NULL;
    int ok = samp_create(&(samp_desc){.scene = s, .backend = SAMP_BACKEND_EMBREE, .seed = 5, .threads = 1}, &sp, &err) ==
                 LM_OK &&
             cache_create(&(cache_desc){.scene = s, .sampler = sp, .jnd = 40.0f}, &c, &err) == LM_OK &&
             cache_init(c, &err) == LM_OK;
    CHECK_MSG(ok, "%s", err.msg);
    cache_refine_result res;
    /* Until the indirect mesh has values enough to check (the scheduler shares the
     * leaves by cost, and the direct mesh's are cheap: it takes them first). */
    for (int i = 0; ok && i < 256; ++i) {
        CHECK(cache_refine(c, &(cache_refine_desc){.pixels = pixels, .budget = 32}, &res, &err) == LM_OK);
        cache_stats st;
        cache_get_stats(c, &st);
        if (i >= 7 && st.indirect.samples >= 400) break;
    }
    if (ok && c->src.rmesh.first) {
        source_copy was;
        copy_source(s, &c->src.rmesh, &was);
        const uint32_t limit = mesh_vtable_id_limit(cache_vtable(c));
        float *E0 = calloc(3 * (size_t)limit, sizeof *E0), *D0 = calloc(3 * (size_t)limit, sizeof *D0);
        uint8_t *had = calloc(limit, 1);
        for (uint32_t v = 0; v < limit; ++v)
            if (mesh_qmesh_get_value(c->indirect, v, E0 + 3 * (size_t)v) == 1 && v < c->src.drift_cap) {
                had[v] = 1;
                memcpy(D0 + 3 * (size_t)v, c->src.drift + 3 * (size_t)v, 3 * sizeof *D0);
            }
        for (int i = 0; i < 6; ++i) CHECK(cache_refine(c, &(cache_refine_desc){.pixels = pixels, .budget = 32}, &res, &err) == LM_OK);
        CHECK(cache_settle_source(c, &err) == LM_OK);
        samp_radiance_index ixw, ixn;
        samp_radiance_index_build(s, &was.m, &ixw);
        samp_radiance_index_build(s, &c->src.rmesh, &ixn);
        int checked = 0, below = 0, n_had = 0, n_out = 0, n_moved = 0, n_wall = 0;
        double worst = 0.0, sum_bound = 0.0, sum_exact = 0.0;
        for (uint32_t v = 0; v < limit && checked < 60; ++v) {
            float e[3];
            if (!had[v] || mesh_qmesh_get_value(c->indirect, v, e) != 1) continue;
            n_had++;
            if (c->src.outdated[v] && ++n_out) continue;
            if (memcmp(e, E0 + 3 * (size_t)v, sizeof e) != 0 && ++n_moved) continue; /* gathered again */
            samp_point pt = cache_vertex_point(c, v);
            float o[3];
            samp_point_origin(s, &pt, samp_point_epsilon(sp, &pt), o);
            const float *nx = mesh_vtable_vertex(cache_vtable(c), v)->normal;
            int near_wall = 0;
            for (int k = 0; k < 3; ++k)
                if (fabsf(nx[k]) < 0.5f) near_wall |= o[k] < 0.1f || o[k] > 0.9f;
            if (near_wall && ++n_wall) continue;
            double ex[3];
            exact_change(s, &was.m, &ixw, &c->src.rmesh, &ixn, o, nx, 48, ex);
            checked++;
            for (int k = 0; k < 3; ++k) {
                const double bound = (double)c->src.drift[3 * (size_t)v + (size_t)k] - D0[3 * (size_t)v + (size_t)k];
                if (fabs(ex[k]) > 1e-6) worst = fmax(worst, fabs(ex[k]) / fmax(bound, 1e-30));
                below += fabs(ex[k]) <= bound * 1.05 + 1e-6;
                sum_bound += bound;
                sum_exact += fabs(ex[k]);
            }
        }
        printf("drift bound: %d values, %d flagged, %d gathered again, %d near a wall\n", n_had, n_out, n_moved, n_wall);
        printf("drift bound: %d values checked; the bound holds in %d of %d channels (within 5%% quadrature), "
               "exact/bound at worst %.3f; on average the bound is %.1f times the change\n",
               checked, below, 3 * checked, worst, sum_exact > 0.0 ? sum_bound / sum_exact : 0.0);
        CHECK(checked >= 10 && sum_exact > 0.0);
        CHECK(below == 3 * checked);
        samp_radiance_index_free(&ixw);
        samp_radiance_index_free(&ixn);
        free(was.first);
        free(was.bary);
        free(was.rad);
        free(E0);
        free(D0);
        free(had);
    }
    cache_destroy(c);
    samp_destroy(sp);
    free(pixels);
    scene_destroy(s);
}

/* ---- a floor that runs on under a wall ---------------------------------------------- */

/* Two rooms side by side, x ∈ [0, 1.6] and [1.65, 3] (y up to 1, z ∈ [0, 1]), the
 * wall between them closed, the far room lit by a quad on its ceiling; one floor
 * (two triangles) runs under the wall through both, as the Veach door's does. The
 * near room gets no light at all: whatever its floor shows is a leak. Gathers of 4
 * rays (64 at most), as noisy as the door's through its gap: a leaf of the floor
 * whose corner beyond the wall gathered the lit room passed its edge test as noise
 * (0 at the midpoints against E_i 1.3 ± 1.3 at that corner), and the near room's
 * floor at the wall's foot showed E_i 0.36 (a depth-4 leaf from x 1.5 to 1.69).
 * Leaves whose corners the wall parts now split (corners_parted, cache_refine.c):
 * E_i 0 there (measured 0.0000; the lit room's floor 2.8). */
static void test_wall_on_floor(void)
{
    static obj_buf o;
    memset(&o, 0, sizeof o);
    rect(&o, 1, 0, (double[2]){0, 0}, (double[2]){1, 3}, 1);                 /* the floor, both rooms */
    rect(&o, 1, 1, (double[2]){0, 0}, (double[2]){1, 1.6}, -1);              /* near ceiling */
    rect(&o, 1, 1, (double[2]){0, 1.65}, (double[2]){1, 3}, -1);             /* far ceiling */
    rect(&o, 0, 0, (double[2]){0, 0}, (double[2]){1, 1}, 1);                 /* near end wall */
    rect(&o, 0, 3, (double[2]){0, 0}, (double[2]){1, 1}, -1);                /* far end wall */
    rect(&o, 0, 1.6, (double[2]){0, 0}, (double[2]){1, 1}, -1);              /* the wall's near face */
    rect(&o, 0, 1.65, (double[2]){0, 0}, (double[2]){1, 1}, 1);              /* its far face */
    for (int room = 0; room < 2; ++room) { /* sides, room by room (only the floor runs under the wall) */
        const double x0 = room ? 1.65 : 0.0, x1 = room ? 3.0 : 1.6;
        rect(&o, 2, 0, (double[2]){x0, 0}, (double[2]){x1, 1}, 1);
        rect(&o, 2, 1, (double[2]){x0, 0}, (double[2]){x1, 1}, -1);
    }
    scene *s = load("wall", &o,
                    "{\"type\": \"quad\", \"corner\": [2.2, 0.999, 0.4], \"edge1\": [0.2, 0, 0], "
                    "\"edge2\": [0, 0, 0.2], \"radiance\": [200, 200, 200]}");
    if (!s) return;
    lm_error err;
    uint32_t *pixels = calloc(s->tri_count, sizeof *pixels);
    for (uint32_t t = 0; t < s->tri_count; ++t) {
        float ct[3];
        centroid(s, t, ct);
        if (s->tris[t].light < 0 && (ct[0] < 1.6f || fabsf(s->tri_normals[3 * (size_t)t + 1] - 1.0f) < 1e-3f))
            pixels[t] = 20000;
    }
    samp_sampler *sp = NULL;
    CHECK(samp_create(&(samp_desc){.scene = s, .backend = SAMP_BACKEND_EMBREE, .indirect_rays = 4}, &sp, &err) ==
          LM_OK);
    cache *c = NULL;
    CHECK(sp && cache_create(&(cache_desc){.scene = s, .sampler = sp}, &c, &err) == LM_OK);
    if (!c) {
        samp_destroy(sp);
        scene_destroy(s);
        free(pixels);
        return;
    }
    CHECK(cache_init(c, &err) == LM_OK);
    refine_all(c, pixels, 1);
    /* Along the wall's near foot, on the floor (y = 0). */
    double worst = 0.0, far = 0.0;
    for (int i = 0; i < 32; ++i) {
        const double z = (i + 0.5) / 32.0;
        for (int side = 0; side < 2; ++side) {
            const double x = side ? 2.4 : 1.55;
            uint32_t t = floor_tri(s, (float)x, (float)z);
            if (!t) continue;
            const uint32_t *v = s->tris[t - 1].v;
            /* barycentrics of (x, 0, z) in floor triangle t − 1 (the y = 0 plane: x, z) */
            double ax = s->positions[3 * (size_t)v[0]], az = s->positions[3 * (size_t)v[0] + 2];
            double bx = s->positions[3 * (size_t)v[1]] - ax, bz = s->positions[3 * (size_t)v[1] + 2] - az;
            double cx = s->positions[3 * (size_t)v[2]] - ax, cz = s->positions[3 * (size_t)v[2] + 2] - az;
            double px = x - ax, pz = z - az, den = bx * cz - bz * cx;
            double w1 = (px * cz - pz * cx) / den, w2 = (bx * pz - bz * px) / den;
            float e[3];
            CHECK(cache_eval_indirect(c, t - 1, w1, w2, e, &err) == LM_OK);
            if (side) far = fmax(far, e[0]);
            else worst = fmax(worst, e[0]);
        }
    }
    cache_stats st;
    cache_get_stats(c, &st);
    printf("wall on a floor: the near room's floor at the wall's foot E_i at most %.4f (nothing reaches it); the lit "
           "room's %.3f; %u indirect leaves; %llu values gathered toward the source\n",
           worst, far, st.indirect.mesh.leaves, (unsigned long long)st.toward_gathers);
    CHECK_MSG(far > 0.3, "the lit room's floor shows %.3f: the test shows nothing", far);
    CHECK_MSG(worst <= 0.01 * far, "the near room's floor shows %.4f of the lit room's light through the wall", worst);
    cache_destroy(c);
    samp_destroy(sp);
    scene_destroy(s);
    free(pixels);
}

/* ---- two meshes masking each other ------------------------------------------------- */

/* The floor box (floor_box) with an Embree sampler of `rays` a gather, a cache
 * (cache_init'ed if init) and the first seen triangle t: the set-up of the tests
 * that judge values by hand on the floor. Returns 0 (and frees what it made)
 * when a part could not be made. */
typedef struct floor_rig {
    scene *s;
    uint32_t *pixels;
    samp_sampler *sp;
    cache *c;
    uint32_t t;
} floor_rig;

static void floor_rig_free(floor_rig *r)
{
    cache_destroy(r->c);
    samp_destroy(r->sp);
    free(r->pixels);
    scene_destroy(r->s);
}

static int floor_rig_make(const char *name, uint32_t rays, int init, floor_rig *r)
{
    memset(r, 0, sizeof *r);
    r->s = floor_box(name, &r->pixels);
    if (!r->s) return 0;
    lm_error err;
    CHECK(samp_create(&(samp_desc){.scene = r->s, .backend = SAMP_BACKEND_EMBREE, .indirect_rays = rays}, &r->sp,
                      &err) == LM_OK);
    if (r->sp) CHECK(cache_create(&(cache_desc){.scene = r->s, .sampler = r->sp}, &r->c, &err) == LM_OK);
    if (r->c && init) CHECK(cache_init(r->c, &err) == LM_OK);
    while (r->t < r->s->tri_count && !r->pixels[r->t]) ++r->t;
    CHECK(r->t < r->s->tri_count);
    if (!r->c || r->t == r->s->tri_count) {
        floor_rig_free(r);
        return 0;
    }
    return 1;
}

/* ---- differences hidden in white ------------------------------------------------- */

/* cache_midpoint_seen_de: a midpoint's fresh value and its edge's
 * interpolation, both past the display's white (tonemap.h clips), show no
 * difference at the midpoint, but a leaf with a corner below white carries the
 * difference inside (the slot's wall by the slit: a leaf 9% too dark inside
 * passed its tests). On the box's white floor (kd 0.7; E_i's white is π / 0.7 at
 * exposure 0, less a direct background, over 2^exposure: cache_white_level):
 * the edge's ends 1.3 and 0.8 of white, the third corner 1.3, the midpoint 1.2
 * against 1.05 interpolated: ΔE 0 at the midpoint, above the JND toward the
 * darker end. The same leaf white all over: 0. Nothing past white: the plain
 * ΔE, bit for bit. */
static void test_below_white(void)
{
    floor_rig rig;
    if (!floor_rig_make("white", 16, 0, &rig)) return;
    const scene *s = rig.s;
    cache *c = rig.c;
    const uint32_t t = rig.t;
    lm_error err;
    const float kd = s->materials[s->tris[t].material].kd[0];
    for (int lit = 0; lit < 2; ++lit)
        for (int stops = -1; stops <= 1; stops += 2) {
            CHECK(cache_set_exposure(c, (float)stops, &err) == LM_OK);
            float bg[CACHE_KINDS][3] = {{0, 0, 0}, {0, 0, 0}, {0, 0, 0}}, wl[3];
            const float ldd = lit ? 0.1f : 0.0f;
            for (int ch = 0; ch < 3; ++ch) bg[CACHE_KIND_DIRECT][ch] = ldd;
            const float white = (float)M_PI * (exp2f(-(float)stops) / kd - ldd); /* E_i the display shows as white */
            cache_white_level(c, CACHE_KIND_INDIRECT, t, (const float(*)[3])bg, wl);
            for (int ch = 0; ch < 3; ++ch)
                CHECK_MSG(fabsf(wl[ch] - white) <= 1e-4f * white, "white level %g, want %g (exposure %+d, direct %g)",
                          wl[ch], white, stops, (double)ldd);
            struct {
                float fresh, interp, end0, opposite; /* the other end: 2·interp − end0 */
                int seen; /* 1: above the JND only below white; 0: not seen; -1: nothing clips */
            } cases[] = {
                {1.2f, 1.05f, 1.3f, 1.3f, 1},  /* both white, the edge's other end below (0.8) */
                {1.2f, 1.05f, 1.3f, 0.5f, 1},  /* the opposite corner darker still */
                {1.5f, 1.35f, 1.3f, 1.02f, 0}, /* white all over */
                {0.6f, 0.5f, 0.6f, 0.3f, -1},  /* nothing clips */
            };
            for (size_t i = 0; i < sizeof cases / sizeof cases[0]; ++i) {
                float f[3], in[3], e0[3], e1[3], op[3], at[3], lab_at[3], lf[3], li[3];
                for (int ch = 0; ch < 3; ++ch) {
                    f[ch] = cases[i].fresh * white;
                    in[ch] = cases[i].interp * white;
                    e0[ch] = cases[i].end0 * white;
                    e1[ch] = (2.0f * cases[i].interp - cases[i].end0) * white;
                    op[ch] = cases[i].opposite * white;
                }
                cache_seen_lab_over(c, CACHE_KIND_INDIRECT, t, (const float(*)[3])bg, f, lf);
                cache_seen_lab_over(c, CACHE_KIND_INDIRECT, t, (const float(*)[3])bg, in, li);
                const float plain = tm_delta_e(lf, li);
                const float judged = cache_midpoint_seen_de(c, CACHE_KIND_INDIRECT, t, (const float(*)[3])bg, f, in, e0,
                                                            e1, op, at, lab_at);
                if (cases[i].seen == 1)
                    CHECK_MSG(plain < 0.01f && judged > c->desc.jnd,
                              "case %zu (exposure %+d, direct %g): dE %.2f at the midpoint, %.2f judged", i, stops,
                              (double)ldd, plain, judged);
                else if (cases[i].seen == 0)
                    CHECK_MSG(judged == 0.0f, "case %zu: white all over, judged %.3g", i, judged);
                else
                    CHECK_MSG(judged == plain && at[0] == in[0], "case %zu: nothing clips, %.4g judged against %.4g",
                              i, judged, plain);
                if (i == 0 && lit == 0 && stops == -1)
                    printf("below white: the midpoint 1.2 against 1.05 of white, dE %.2f there, %.2f judged inside "
                           "the leaf (at %.3f of white)\n", plain, judged, at[0] / white);
            }
        }
    floor_rig_free(&rig);
}

/* What an edge test judges a midpoint against (cache_edge_background; docs/cache.md,
 * "The door's strip: two meshes masking each other"). On the Veach door a strip of
 * light crossed the floor's leaves in the direct and the indirect mesh alike; each
 * interpolated it over the dark floor in front of the door, and each mesh's test
 * saw its own error (direct 0 fresh against 7 interpolated) on the other's spread,
 * which saturated the display: ΔE 0, no split, the strip spread for good. Here a
 * settled indirect leaf of the box's floor (its test passed) gets that state by
 * hand: E_i bright at one end of an edge, 0 at the other and at the third corner.
 * Against the indirect interpolated at the midpoint (as before) the direct
 * difference is invisible; against the darkest the indirect is over the edge it is
 * plain. Where the indirect is smooth (equal at the three points) both backgrounds
 * are its value and agree. Where the indirect leaf has not been tested yet (a root
 * after cache_init, holding the first values), it masks nothing: background 0. */
static void test_edge_background(void)
{
    floor_rig rig;
    if (!floor_rig_make("mask", 64, 1, &rig)) return;
    const uint32_t *pixels = rig.pixels;
    cache *c = rig.c;
    const uint32_t t = rig.t;
    lm_error err;
    const float fresh[3] = {0, 0, 0}, interp[3] = {7, 7, 7};
    const float bright[3] = {100, 100, 100}, dark[3] = {0, 0, 0}, even[3] = {0.5f, 0.5f, 0.5f};
    for (int settled = 0; settled < 2; ++settled) {
        /* The indirect leaf: the untested root, or a leaf whose test passed. */
        uint32_t leaf = mesh_qmesh_root(c->indirect, t);
        if (settled) {
            refine_all(c, pixels, 1);
            leaf = MESH_QMESH_NONE;
            for (uint32_t nd = 0; nd < mesh_qmesh_node_limit(c->indirect) && leaf == MESH_QMESH_NONE; ++nd) {
                const mesh_qnode *n = mesh_qmesh_node(c->indirect, nd);
                if (n && n->tri == t && n->child == MESH_QMESH_NONE && nd < c->sched.done_cap[CACHE_KIND_INDIRECT] &&
                    c->sched.done[CACHE_KIND_INDIRECT][nd])
                    leaf = nd;
            }
            CHECK_MSG(leaf != MESH_QMESH_NONE, "no indirect leaf of the floor passed its test");
            if (leaf == MESH_QMESH_NONE) break;
        }
        const mesh_qnode *n = mesh_qmesh_node(c->indirect, leaf);
        double cw1[3], cw2[3];
        for (int k = 0; k < 3; ++k) cache_node_corner_bary(n, k, &cw1[k], &cw2[k]);
        const double pw1[3] = {0.5 * (cw1[0] + cw1[1]), cw1[0], cw1[1]};
        const double pw2[3] = {0.5 * (cw2[0] + cw2[1]), cw2[0], cw2[1]};
        for (int smooth = 0; smooth < 2; ++smooth) {
            CHECK(mesh_qmesh_set_value(c->indirect, n->v[0], smooth ? even : dark, &err) == LM_OK);
            CHECK(mesh_qmesh_set_value(c->indirect, n->v[1], smooth ? even : bright, &err) == LM_OK);
            CHECK(mesh_qmesh_set_value(c->indirect, n->v[2], smooth ? even : dark, &err) == LM_OK);
            float lf[3], li[3], bg[CACHE_KINDS][3];
            cache_seen_lab_with(c, CACHE_KIND_DIRECT, t, pw1[0], pw2[0], fresh, lf);
            cache_seen_lab_with(c, CACHE_KIND_DIRECT, t, pw1[0], pw2[0], interp, li);
            const float interpolated_de = tm_delta_e(lf, li);
            cache_edge_background(c, CACHE_KIND_DIRECT, t, pw1, pw2, bg);
            cache_seen_lab_over(c, CACHE_KIND_DIRECT, t, (const float(*)[3])bg, fresh, lf);
            cache_seen_lab_over(c, CACHE_KIND_DIRECT, t, (const float(*)[3])bg, interp, li);
            const float edge_de = tm_delta_e(lf, li), bgE = bg[CACHE_KIND_INDIRECT][0];
            printf("edge background (%s indirect leaf, %s): direct 0 against 7 at the midpoint, dE %.2f on the "
                   "indirect interpolated there, %.2f on the background (E_i %.3g)\n",
                   settled ? "a settled" : "an untested", smooth ? "smooth" : "a bright end", interpolated_de, edge_de,
                   bgE);
            if (!smooth)
                CHECK_MSG(interpolated_de < c->desc.jnd, "the spread indirect does not mask here (dE %.2f): the test "
                          "shows nothing", interpolated_de);
            if (!settled || !smooth) {
                CHECK_MSG(bgE == 0.0f, "background E_i %g, not 0 (%s leaf, %s)", bgE, settled ? "settled" : "untested",
                          smooth ? "smooth" : "a bright end");
                CHECK_MSG(edge_de > 10.0f * c->desc.jnd, "the direct difference is hidden: dE %.2f", edge_de);
            } else {
                CHECK_MSG(fabsf(bgE - 0.5f) < 1e-6f, "settled and smooth: background E_i %g, not 0.5", bgE);
                CHECK_MSG(fabsf(edge_de - interpolated_de) < 1e-4f, "settled and smooth: %g against %g", edge_de,
                          interpolated_de);
            }
        }
    }
    floor_rig_free(&rig);
}

int main(void)
{
    test_below_white();
    test_edge_background();
    test_wall_on_floor();
    test_drift_is_a_bound();
    test_pull_inside();
    test_noise_does_not_refine();
    test_estimate();
    test_slot();
    test_owed_waits();
    return test_finish("cache_indirect_test");
}
