/* samp_embree_test — the Embree sampler (samp_embree.c) against closed forms,
 * and the robustness cases of the sampling issue:
 *   - unoccluded points: with the control variate G equals Lambert's formula to
 *     float precision; without it the stratified estimate is within 1%;
 *   - a blocker covering exactly half of the light gives half the value;
 *   - a light behind the receiver gives exactly 0;
 *   - a closed room (zero-thickness walls) with the light outside: nothing leaks
 *     in, at interior points, on edges and at corners of the mesh;
 *   - the same room with the light inside: corner and edge points see it whole
 *     (no self-shadowing acne), and a lamp standing on the floor (a light
 *     touching the receiver) gives the analytic value right up to its base;
 *   - indirect: constant radiance everywhere gives π·L exactly; radiance on the
 *     ceiling only gives L·G_ceiling (analytic) within the stated error;
 *   - values depend on the point alone (batch order, thread count), never NaN/Inf;
 *   - point lights: cosθ/r² when visible, 0 when not.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "sampling/analytic.h"
#include "sampling/samp.h"
#include "src/base/vecmath.h"
#include "src/scene/scene.h"
#include "tests/test_util.h"

/* A closed unit room [0,1]³, faces wound to face inwards, as OBJ text. */
static const char room_obj[] =
    "v 0 0 0\nv 1 0 0\nv 1 0 1\nv 0 0 1\nv 0 1 0\nv 1 1 0\nv 1 1 1\nv 0 1 1\n"
    "f 1 4 3\nf 1 3 2\n"  /* floor y=0, normal +y */
    "f 5 6 7\nf 5 7 8\n"  /* ceiling y=1, normal -y */
    "f 1 2 6\nf 1 6 5\n"  /* wall z=0, normal +z */
    "f 4 8 7\nf 4 7 3\n"  /* wall z=1, normal -z */
    "f 1 5 8\nf 1 8 4\n"  /* wall x=0, normal +x */
    "f 2 3 7\nf 2 7 6\n"; /* wall x=1, normal -x */

/* Every scene of this test is turned by an arbitrary rotation (0.7 rad about
 * (1, 2, 3)), so walls are not axis planes and points on them are not exact:
 * an axis-aligned room hides leaks, because a ray starting in the plane y = 1
 * hits it at exactly t = 0. Tests give positions in the room's own frame. */
static double R[3][3];

static void init_rotation(void)
{
    double a[3] = {1, 2, 3}, l = sqrt(14.0), t = 0.7, c = cos(t), s = sin(t);
    for (int k = 0; k < 3; ++k) a[k] /= l;
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) R[i][j] = (i == j ? c : 0.0) + (1 - c) * a[i] * a[j];
    R[0][1] -= s * a[2];
    R[0][2] += s * a[1];
    R[1][0] += s * a[2];
    R[1][2] -= s * a[0];
    R[2][0] -= s * a[1];
    R[2][1] += s * a[0];
}

static void rot(const double in[3], double out[3])
{
    for (int i = 0; i < 3; ++i) out[i] = R[i][0] * in[0] + R[i][1] * in[1] + R[i][2] * in[2];
}

/* A quad light in the room's frame, as scene-description JSON. */
static void quad_json(char *buf, size_t n, const double c[3], const double e1[3], const double e2[3], double le)
{
    double rc[3], r1[3], r2[3];
    rot(c, rc);
    rot(e1, r1);
    rot(e2, r2);
    snprintf(buf, n,
             "{\"type\": \"quad\", \"corner\": [%.9g, %.9g, %.9g], \"edge1\": [%.9g, %.9g, %.9g],"
             " \"edge2\": [%.9g, %.9g, %.9g], \"radiance\": [%g, %g, %g]}",
             rc[0], rc[1], rc[2], r1[0], r1[1], r1[2], r2[0], r2[1], r2[2], le, le, le);
}

static scene *load(const char *name, const char *lights_json, const char *extra_mesh)
{
    char obj[1024], json[1024], text[4096], m[400];
    test_write_file("room.obj", room_obj, obj, sizeof obj);
    snprintf(m, sizeof m, "[%.17g, %.17g, %.17g, 0, %.17g, %.17g, %.17g, 0, %.17g, %.17g, %.17g, 0, 0, 0, 0, 1]",
             R[0][0], R[0][1], R[0][2], R[1][0], R[1][1], R[1][2], R[2][0], R[2][1], R[2][2]);
    snprintf(text, sizeof text,
             "{\"meshes\": [{\"file\": \"room.obj\", \"material\": \"white\", \"transform\": %s}%s],"
             " \"materials\": {\"white\": {\"kd\": [0.5, 0.5, 0.5]}},"
             " \"lights\": [%s],"
             " \"cameras\": [{\"position\": [0.5, 0.5, 0.9], \"target\": [0.5, 0.5, 0]}]}",
             m, extra_mesh ? extra_mesh : "", lights_json);
    test_write_file(name, text, json, sizeof json);
    scene_load_desc d = {.path = json, .crease_angle_deg = 1.0f};
    scene *s = NULL;
    lm_error err;
    lm_result r = scene_load(&d, &s, &err);
    CHECK_MSG(r == LM_OK, "%s", err.msg);
    return s;
}

static samp_sampler *make(const scene *s, int rays, int cv, int threads)
{
    samp_desc d = {.scene = s, .backend = SAMP_BACKEND_EMBREE, .direct_rays = rays, .direct_control_variate = cv,
                   .threads = threads, .indirect_rays = 4096};
    samp_sampler *sp = NULL;
    lm_error err;
    lm_result r = samp_create(&d, &sp, &err);
    CHECK_MSG(r == LM_OK, "%s", err.msg);
    return sp;
}

/* A receiver given in the room's frame. */
static samp_point pt(float x, float y, float z, float nx, float ny, float nz, uint32_t tri_plus_one)
{
    const double p[3] = {x, y, z}, n[3] = {nx, ny, nz};
    double rp[3], rn[3];
    rot(p, rp);
    rot(n, rn);
    samp_point out = {{(float)rp[0], (float)rp[1], (float)rp[2]}, {(float)rn[0], (float)rn[1], (float)rn[2]},
                      tri_plus_one};
    return out;
}

static double unocc(const scene *s, uint32_t light, const samp_point *x)
{
    return samp_area_light_unoccluded(s, light, x->p, x->n);
}

/* The light at the ceiling, inside: a 0.4-wide square 0.01 below it, facing down. */
static const char *inside_light(void)
{
    static char buf[512];
    quad_json(buf, sizeof buf, (const double[3]){0.3, 0.99, 0.3}, (const double[3]){0.4, 0, 0},
              (const double[3]){0, 0, 0.4}, 10.0);
    return buf;
}

/* Points on the floor: interior, on its edges and at its corners (tri 1 or 2 = floor). */
static uint32_t floor_points(samp_point *pts)
{
    uint32_t n = 0;
    const float c[][2] = {{0.5f, 0.5f}, {0.1f, 0.7f}, {0.93f, 0.21f}, {0.0f, 0.5f}, {1.0f, 0.3f}, {0.4f, 0.0f},
                          {0.6f, 1.0f}, {0.0f, 0.0f}, {1.0f, 1.0f}, {0.0f, 1.0f}, {1.0f, 0.0f}, {0.5f, 0.5f}};
    for (size_t i = 0; i < sizeof c / sizeof *c; ++i) {
        /* floor triangle 1 is (v1,v4,v3): x <= z side; triangle 2 the other */
        uint32_t tri = c[i][0] <= c[i][1] ? 1 : 2;
        pts[n++] = pt(c[i][0], 0.0f, c[i][1], 0, 1, 0, tri);
    }
    return n;
}

static void test_unoccluded_and_acne(void)
{
    scene *s = load("room_in.json", inside_light(), NULL);
    if (!s) return;
    samp_sampler *cv = make(s, 64, 0, 2), *raw = make(s, 1024, SAMP_OFF, 2);
    samp_point pts[16];
    uint32_t n = floor_points(pts);
    /* tilted receivers in the air too */
    pts[n++] = pt(0.5f, 0.5f, 0.5f, 0.6f, 0.8f, 0.0f, 0);
    pts[n++] = pt(0.2f, 0.3f, 0.7f, 0.0f, 0.6f, -0.8f, 0);
    float g_cv[16], g_raw[16];
    lm_error err;
    CHECK(samp_direct(cv, 0, pts, n, g_cv, &err) == LM_OK);
    CHECK(samp_direct(raw, 0, pts, n, g_raw, &err) == LM_OK);
    double worst_cv = 0.0, worst_raw = 0.0;
    for (uint32_t i = 0; i < n; ++i) {
        double want = unocc(s, 0, &pts[i]);
        CHECK_MSG(want > 0.0, "point %u should see the light", i);
        worst_cv = fmax(worst_cv, fabs(g_cv[i] - want) / want);
        worst_raw = fmax(worst_raw, fabs(g_raw[i] - want) / want);
    }
    printf("unoccluded (incl. floor edges and corners): control variate max rel err %.2e, raw 1024 rays %.2e\n",
           worst_cv, worst_raw);
    CHECK_MSG(worst_cv <= 1e-6, "control variate: %.3e", worst_cv);
    CHECK_MSG(worst_raw <= 0.01, "raw: %.3e", worst_raw);
    samp_destroy(cv);
    samp_destroy(raw);
    scene_destroy(s);
}

static void test_no_leak(void)
{
    /* Above the ceiling, outside the room, 1e-4 above it, facing down. */
    char light[512];
    quad_json(light, sizeof light, (const double[3]){0.2, 1.0001, 0.2}, (const double[3]){0.6, 0, 0},
              (const double[3]){0, 0, 0.6}, 10.0);
    scene *s = load("room_out.json", light, NULL);
    if (!s) return;
    samp_sampler *sp = make(s, 256, 0, 2);
    samp_point pts[32];
    uint32_t n = floor_points(pts);
    /* points on the ceiling's underside (they face down: light behind them),
     * points on the walls right under the ceiling, and the top corners */
    pts[n++] = pt(0.5f, 1.0f, 0.5f, 0, -1, 0, 3);
    pts[n++] = pt(0.0f, 0.999f, 0.5f, 1, 0, 0, 9);
    pts[n++] = pt(0.0f, 1.0f, 0.5f, 1, 0, 0, 9);
    pts[n++] = pt(0.5f, 1.0f, 0.0f, 0, 0, 1, 5);
    pts[n++] = pt(0.0f, 1.0f, 0.0f, 1, 0, 0, 9);
    /* a receiver in the room tilted towards the ceiling */
    pts[n++] = pt(0.5f, 0.9999f, 0.5f, 0, 1, 0, 0);
    float g[32];
    lm_error err;
    CHECK(samp_direct(sp, 0, pts, n, g, &err) == LM_OK);
    int leaks = 0, seen_above = 0;
    for (uint32_t i = 0; i < n; ++i) {
        leaks += g[i] != 0.0f;
        seen_above += unocc(s, 0, &pts[i]) > 0.0;
    }
    printf("light outside the room: %d of %u points leak (%d have it above their horizon)\n", leaks, n, seen_above);
    CHECK_MSG(leaks == 0, "%d points see a light through a wall", leaks);
    CHECK(seen_above >= 10);
    samp_destroy(sp);
    scene_destroy(s);
}

static void test_behind_and_touching(void)
{
    /* A lamp standing on the floor: a vertical quad whose bottom edge lies on the
     * floor, emitting towards +x. */
    char light[512];
    quad_json(light, sizeof light, (const double[3]){0.5, 0, 0.3}, (const double[3]){0, 0.3, 0},
              (const double[3]){0, 0, 0.4}, 5.0);
    scene *s = load("room_lamp.json", light, NULL);
    if (!s) return;
    CHECK(fabs(s->area_lights[0].normal[0] - R[0][0]) < 1e-5); /* emits along the room's +x */
    samp_sampler *sp = make(s, 64, 0, 2);
    samp_point pts[8];
    uint32_t n = 0;
    pts[n++] = pt(0.5001f, 0.0f, 0.5f, 0, 1, 0, 2);  /* touching the lamp's base, in front */
    pts[n++] = pt(0.51f, 0.0f, 0.5f, 0, 1, 0, 2);
    pts[n++] = pt(0.8f, 0.0f, 0.5f, 0, 1, 0, 2);
    pts[n++] = pt(0.5f, 0.0f, 0.5f, 0, 1, 0, 2);     /* on the base line itself */
    pts[n++] = pt(0.3f, 0.0f, 0.5f, 0, 1, 0, 1);     /* behind the lamp: exactly 0 */
    pts[n++] = pt(0.9f, 0.2f, 0.5f, 1, 0, 0, 0);     /* facing away: exactly 0 */
    float g[8];
    lm_error err;
    CHECK(samp_direct(sp, 0, pts, n, g, &err) == LM_OK);
    for (uint32_t i = 0; i < n; ++i) CHECK_MSG(isfinite(g[i]) && g[i] >= 0.0f, "point %u: %g", i, g[i]);
    for (uint32_t i = 0; i < 3; ++i) {
        double want = unocc(s, 0, &pts[i]);
        CHECK_MSG(want > 0.0 && fabs(g[i] - want) <= 1e-5 * want, "touching lamp, point %u: %.7g vs %.7g", i, g[i],
                  want);
    }
    CHECK(g[4] == 0.0f);
    CHECK(g[5] == 0.0f);
    printf("lamp on the floor: G %.5f %.5f %.5f in front, %g on its base line, %g behind, %g facing away\n", g[0],
           g[1], g[2], g[3], g[4], g[5]);
    samp_destroy(sp);
    scene_destroy(s);
}

static void test_lobe_visibility(scene *s);

static void test_half_blocker(void)
{
    /* A blocker just under the light whose edge passes below the light's centre
     * at 30° to its sides (cutting the strata at no special angle). For a
     * receiver facing up on the vertical line through the centre, the integrand
     * depends only on the distance from that line, so any line through the
     * centre hides exactly half of G. */
    const double c[3] = {0.5, 0.9, 0.5}, d[3] = {cos(M_PI / 6), 0, sin(M_PI / 6)}, q[3] = {-d[2], 0, d[0]};
    double v[3][3];
    for (int k = 0; k < 3; ++k) {
        v[0][k] = c[k] - 5 * d[k];
        v[1][k] = c[k] + 5 * d[k];
        v[2][k] = c[k] + 5 * q[k];
    }
    char obj[1024], text[512], light[512];
    double w[3][3];
    for (int i = 0; i < 3; ++i) rot(v[i], w[i]);
    snprintf(text, sizeof text, "v %.9f %.9f %.9f\nv %.9f %.9f %.9f\nv %.9f %.9f %.9f\nf 1 3 2\n", w[0][0], w[0][1],
             w[0][2], w[1][0], w[1][1], w[1][2], w[2][0], w[2][1], w[2][2]);
    test_write_file("blocker.obj", text, obj, sizeof obj);
    quad_json(light, sizeof light, (const double[3]){0.3, 0.95, 0.3}, (const double[3]){0.4, 0, 0},
              (const double[3]){0, 0, 0.4}, 10.0);
    scene *s = load("room_half.json", light, ", {\"file\": \"blocker.obj\", \"material\": \"white\"}");
    if (!s) return;
    const int rays[3] = {64, 256, 1024};
    enum { NP = 8 };
    for (int r = 0; r < 3; ++r) {
        samp_sampler *sp = make(s, rays[r], 0, 2);
        samp_point pts[NP];
        for (int i = 0; i < NP; ++i) pts[i] = pt(0.5f, 0.1f * (float)i, 0.5f, 0, 1, 0, i == 0 ? 2 : 0);
        float g[NP];
        lm_error err;
        CHECK(samp_direct(sp, 0, pts, NP, g, &err) == LM_OK);
        double worst = 0.0, rms = 0.0;
        for (int i = 0; i < NP; ++i) {
            double want = 0.5 * unocc(s, 0, &pts[i]), e = fabs(g[i] - want) / want;
            worst = fmax(worst, e);
            rms += e * e / NP;
        }
        /* Stated error of a penumbra value (samp.h, SAMP_EMBREE_PENUMBRA_RMS):
         * relative rms 1.2·rays^-0.75 (the visible fraction from k×k strata, an
         * edge across the light cutting ~k of them). Measured here: unbiased
         * (65,536 rays: within 4e-4), rms 4.9% at 64 rays, 1.8% at 256, 0.7% at
         * 1024. Every point within 3 stated standard errors, the rms within 1.5. */
        double stated = SAMP_EMBREE_PENUMBRA_RMS(rays[r]);
        printf("half blocker at 30 deg, %4d rays: rms rel err %.2e, max %.2e (stated rms %.2e)\n", rays[r],
               sqrt(rms), worst, stated);
        CHECK_MSG(worst <= 3.0 * stated, "%d rays: max %.3e > 3 x %.3e", rays[r], worst, stated);
        CHECK_MSG(sqrt(rms) <= 1.5 * stated, "%d rays: rms %.3e > 1.5 x %.3e", rays[r], sqrt(rms), stated);
        samp_destroy(sp);
    }
    test_lobe_visibility(s);
    scene_destroy(s);
}

/* The half blocker's scene seen in a sharp lobe (samp_lobe_visibility): the
 * light's visible fraction weighted by the lobe, against a midpoint-rule sum over
 * 400×400 points of the light with the blocker's half-plane tested exactly (in
 * the room's own frame). The receiver faces up below the light's centre, where
 * half of G is hidden; its lobe (n = 1000) is aimed 0.1 to either side of the
 * blocker's edge and at the edge itself: the fraction the lobe sees is then
 * about 1, 0 and ½ (measured 1.0000, 0.0039, 0.5039 against 0.9999, 0.0001,
 * 0.5000), where the cosine-weighted one (samp_direct) is ½ each time. */
static double lobe_visible_exact(const double x[3], const double r[3], double n)
{
    const double c[3] = {0.5, 0.9, 0.5}, q[3] = {-sin(M_PI / 6), 0, cos(M_PI / 6)};
    double sum = 0.0, vis = 0.0;
    enum { M = 400 };
    for (int j = 0; j < M; ++j)
        for (int i = 0; i < M; ++i) {
            const double y[3] = {0.3 + 0.4 * (i + 0.5) / M, 0.95, 0.3 + 0.4 * (j + 0.5) / M};
            double d[3], len = 0.0;
            for (int k = 0; k < 3; ++k) {
                d[k] = y[k] - x[k];
                len += d[k] * d[k];
            }
            len = sqrt(len);
            for (int k = 0; k < 3; ++k) d[k] /= len;
            double ca = d[0] * r[0] + d[1] * r[1] + d[2] * r[2];
            if (ca <= 0.0 || d[1] <= 0.0) continue;
            double w = pow(ca, n) * d[1] * d[1] / (len * len); /* lobe · cos at x · cos at the light / r² */
            double t = (0.9 - x[1]) / (y[1] - x[1]), p[3];
            for (int k = 0; k < 3; ++k) p[k] = x[k] + t * (y[k] - x[k]);
            int hidden = (p[0] - c[0]) * q[0] + (p[2] - c[2]) * q[2] > 0.0;
            sum += w;
            if (!hidden) vis += w;
        }
    return sum > 0.0 ? vis / sum : -1.0;
}

static void test_lobe_visibility(scene *s)
{
    samp_sampler *sp = make(s, 1024, 1, 2);
    if (!sp) return;
    const double x[3] = {0.5, 0.1, 0.5}, q[3] = {-sin(M_PI / 6), 0, cos(M_PI / 6)}, n = 1000.0;
    enum { NP = 3 };
    samp_point pts[NP];
    float wo[3 * NP], ex[NP], V[NP], G[NP];
    double want[NP];
    for (int i = 0; i < NP; ++i) {
        /* The lobe's axis at the light's centre moved by 0.1 across the edge (−, +) or on it. */
        double off = i == 0 ? -0.1 : i == 1 ? 0.1 : 0.0, t[3] = {0.5 + off * q[0], 0.95, 0.5 + off * q[2]}, r[3], len = 0.0;
        for (int k = 0; k < 3; ++k) {
            r[k] = t[k] - x[k];
            len += r[k] * r[k];
        }
        for (int k = 0; k < 3; ++k) r[k] /= sqrt(len);
        const double w[3] = {-r[0], r[1], -r[2]}; /* its mirror about the up normal: towards the viewer */
        double rw[3];
        rot(w, rw);
        for (int k = 0; k < 3; ++k) wo[3 * i + k] = (float)rw[k];
        ex[i] = (float)n;
        pts[i] = pt((float)x[0], (float)x[1], (float)x[2], 0, 1, 0, 0);
        want[i] = lobe_visible_exact(x, r, n);
    }
    lm_error err;
    CHECK(samp_lobe_visibility(sp, 0, pts, wo, ex, NP, 256, V, &err) == LM_OK);
    CHECK(samp_direct(sp, 0, pts, NP, G, &err) == LM_OK);
    for (int i = 0; i < NP; ++i) {
        double cosine = G[i] / unocc(s, 0, &pts[i]);
        printf("lobe aimed %s the blocker's edge: lobe-weighted visible %.4f (exact %.4f), cosine-weighted %.4f\n",
               i == 0 ? "0.1 beside" : i == 1 ? "0.1 behind" : "at", V[i], want[i], cosine);
        CHECK_MSG(fabs(V[i] - want[i]) <= 0.03, "lobe %d: %.4f against %.4f", i, V[i], want[i]);
        CHECK_MSG(fabs(cosine - 0.5) <= 0.03, "cosine-weighted %.4f, not a half", cosine);
    }
    CHECK(want[0] > 0.95 && want[1] < 0.05 && fabs(want[2] - 0.5) < 0.05); /* the set-up itself */
    /* Bad input is refused, a light that is not an area light too. */
    ex[0] = -1.0f;
    CHECK(samp_lobe_visibility(sp, 0, pts, wo, ex, 1, 256, V, &err) != LM_OK);
    ex[0] = (float)n;
    CHECK(samp_lobe_visibility(sp, 0, pts, wo, ex, 1, 250, V, &err) != LM_OK);
    CHECK(samp_lobe_visibility(sp, 7, pts, wo, ex, 1, 256, V, &err) != LM_OK);
    samp_destroy(sp);
}

/* Radiance mesh over the scene's triangles: one sub-triangle each (its corners),
 * radiance `ceiling` on the ceiling (triangles 2, 3), `other` elsewhere. */
typedef struct mesh_buf {
    uint32_t first[64];
    float bary[6 * 64], rad[9 * 64];
    samp_radiance_mesh m;
} mesh_buf;

static void make_mesh(const scene *s, float ceiling, float other, mesh_buf *b)
{
    static const float corners[6] = {0, 0, 1, 0, 0, 1};
    for (uint32_t t = 0; t <= s->tri_count; ++t) b->first[t] = t;
    for (uint32_t t = 0; t < s->tri_count; ++t) {
        memcpy(b->bary + 6 * t, corners, sizeof corners);
        float L = t == 2 || t == 3 ? ceiling : other;
        if (s->tris[t].light >= 0) L = 0.0f;
        for (int k = 0; k < 9; ++k) b->rad[9 * t + (uint32_t)k] = L;
    }
    b->m = (samp_radiance_mesh){.tri_count = s->tri_count, .first = b->first, .bary = b->bary, .radiance = b->rad};
}

static void test_indirect(void)
{
    scene *s = load("room_ind.json", inside_light(), NULL);
    if (!s) return;
    CHECK(s->tri_count < 64);
    samp_sampler *sp = make(s, 64, 0, 2);
    mesh_buf *b = malloc(sizeof *b);
    samp_point pts[16];
    uint32_t n = floor_points(pts);
    pts[n++] = pt(0.5f, 0.5f, 0.5f, 0.0f, 0.6f, 0.8f, 0);
    float E[48];
    lm_error err;
    /* constant radiance 2 everywhere (the light's own triangles are 0, and a ray
     * that reaches them is the only loss): every ray that misses the light brings 2 */
    make_mesh(s, 2.0f, 2.0f, b);
    CHECK(samp_indirect(sp, &b->m, pts, n, E, &err) == LM_OK);
    double worst = 0.0;
    for (uint32_t i = 0; i < n; ++i) {
        /* E = π·2 − 2·G_light (the light hides part of the ceiling) */
        double want = M_PI * 2.0 - 2.0 * unocc(s, 0, &pts[i]);
        for (int k = 0; k < 3; ++k) worst = fmax(worst, fabs(E[3 * i + (uint32_t)k] - want) / want);
    }
    printf("indirect, constant radiance: max rel err %.2e\n", worst);
    CHECK_MSG(worst <= 0.01, "constant radiance: %.3e", worst);

    /* ceiling only: E = L·(G of the whole ceiling square − G of the light in front of it) */
    make_mesh(s, 3.0f, 0.0f, b);
    CHECK(samp_indirect(sp, &b->m, pts, n, E, &err) == LM_OK);
    const double ceil_local[4][3] = {{0, 1, 0}, {1, 1, 0}, {1, 1, 1}, {0, 1, 1}};
    double ceil_quad[4][3];
    for (int i = 0; i < 4; ++i) rot(ceil_local[i], ceil_quad[i]);
    double mean_err = 0.0;
    worst = 0.0;
    for (uint32_t i = 0; i < n; ++i) {
        const double x[3] = {pts[i].p[0], pts[i].p[1], pts[i].p[2]}, nx[3] = {pts[i].n[0], pts[i].n[1], pts[i].n[2]};
        double want = 3.0 * (samp_polygon_G(ceil_quad, 4, x, nx) - unocc(s, 0, &pts[i]));
        double e = fabs(E[3 * i] - want) / want;
        worst = fmax(worst, e);
        mean_err += e / n;
    }
    printf("indirect, ceiling only (4096 rays): mean rel err %.2e, max %.2e\n", mean_err, worst);
    CHECK_MSG(worst <= 0.03, "ceiling only: %.3e", worst);
    CHECK_MSG(mean_err <= 0.01, "ceiling only mean: %.3e", mean_err);
    free(b);
    samp_destroy(sp);
    scene_destroy(s);
}

/* The radiance mesh reflected by a Phong lobe (samp_lobe_gather): with radiance
 * L on the ceiling only, the gather is L·(S_ceiling − S_light), S the lobe's
 * integral over a polygon (samp_polygon_phong, exact; the light's triangles
 * send 0 and hide that part of the ceiling). Floor points, views from the
 * normal to grazing, exponents 1 to 100, 1,024 rays: every value within 4 of its
 * stated standard error, the stated errors not too small (the spread of the
 * errors over them), and the sum of the errors within 4 of its standard error
 * (no bias). A value with no stated noise met the ceiling with no ray: its
 * truth is below what one ray brings (3·(n+2)/(n+1)/1,024). */
static void test_lobe_gather(void)
{
    scene *s = load("room_lobe.json", inside_light(), NULL);
    if (!s) return;
    samp_sampler *sp = make(s, 64, 0, 2);
    mesh_buf *b = malloc(sizeof *b);
    make_mesh(s, 3.0f, 0.0f, b);
    samp_point pts[16];
    const uint32_t n = floor_points(pts);
    const double ceil_local[4][3] = {{0, 1, 0}, {1, 1, 0}, {1, 1, 1}, {0, 1, 1}};
    const double light_local[4][3] = {{0.3, 0.99, 0.3}, {0.7, 0.99, 0.3}, {0.7, 0.99, 0.7}, {0.3, 0.99, 0.7}};
    double ceil_quad[4][3], light_quad[4][3];
    for (int i = 0; i < 4; ++i) {
        rot(ceil_local[i], ceil_quad[i]);
        rot(light_local[i], light_quad[i]);
    }
    const double views[3][3] = {{0, 1, 0}, {0.5, 1, 0.2}, {1, 0.3, -0.4}}, expo[3] = {1, 10, 100};
    double worst = 0.0, z2 = 0.0, worst_z = 0.0, sum_d = 0.0, sum_se2 = 0.0;
    int count = 0;
    lm_error err;
    for (int v = 0; v < 3; ++v)
        for (int e = 0; e < 3; ++e) {
            float wo[3 * 16], ex[16], L[3 * 16], se[3 * 16];
            double wv[3];
            rot(views[v], wv);
            for (uint32_t i = 0; i < n; ++i) {
                for (int k = 0; k < 3; ++k) wo[3 * i + (uint32_t)k] = (float)wv[k];
                ex[i] = (float)expo[e];
            }
            CHECK(samp_lobe_gather(sp, &b->m, pts, wo, ex, n, 1024, 0, L, se, &err) == LM_OK);
            for (uint32_t i = 0; i < n; ++i) {
                const double x[3] = {pts[i].p[0], pts[i].p[1], pts[i].p[2]},
                             nx[3] = {pts[i].n[0], pts[i].n[1], pts[i].n[2]}, w[3] = {wv[0], wv[1], wv[2]};
                const double want = 3.0 * (samp_polygon_phong((const double(*)[3])ceil_quad, 4, x, nx, w, expo[e]) -
                                           samp_polygon_phong((const double(*)[3])light_quad, 4, x, nx, w, expo[e]));
                const double d = L[3 * i] - want;
                if (want > 0.05) worst = fmax(worst, fabs(d) / want);
                sum_d += d;
                sum_se2 += (double)se[3 * i] * se[3 * i];
                if (se[3 * i] > 0.0f) {
                    const double z = fabs(d) / se[3 * i];
                    worst_z = fmax(worst_z, z);
                    z2 += z * z;
                    count++;
                } else {
                    CHECK_MSG(fabs(d) <= 3.0 * 2.0 / 1024.0, "no noise stated, off by %.3e", d);
                }
            }
        }
    const double rms_z = count ? sqrt(z2 / count) : 0.0;
    const double bias_z = sum_se2 > 0.0 ? sum_d / sqrt(sum_se2) : 0.0;
    printf("lobe gather, ceiling only (1024 rays, n 1..100, views to grazing): max rel err %.2e, error / stated "
           "standard error: rms %.2f, max %.2f (%d values); summed error %.2f standard errors\n",
           worst, rms_z, worst_z, count, bias_z);
    CHECK_MSG(fabs(bias_z) <= 4.0, "summed error %.2f standard errors", bias_z);
    CHECK_MSG(worst_z <= 4.0, "an error of %.2f stated standard errors", worst_z);
    CHECK(count > 0 && rms_z <= 1.2);
    /* Bad arguments are refused, not traced. */
    float wo1[3] = {0, 1, 0}, ex1 = -1.0f, L1[3];
    CHECK(samp_lobe_gather(sp, &b->m, pts, wo1, &ex1, 1, 64, 0, L1, NULL, &err) != LM_OK);
    ex1 = 10.0f;
    CHECK(samp_lobe_gather(sp, &b->m, pts, wo1, &ex1, 1, 63, 0, L1, NULL, &err) != LM_OK);
    CHECK(samp_lobe_gather(sp, NULL, pts, wo1, &ex1, 1, 64, 0, L1, NULL, &err) != LM_OK);
    free(b);
    samp_destroy(sp);
    scene_destroy(s);
}

/* Where indirect light comes from (samp_indirect_sources): the fraction of a
 * floor point's cosine-weighted hemisphere that each source triangle fills is
 * its cosine-weighted solid angle over π, and π·Σ w_t·L_t is the gather. */
static void test_sources(void)
{
    scene *s = load("room_src.json", inside_light(), NULL);
    if (!s) return;
    samp_sampler *sp = make(s, 4096, 0, 2);
    mesh_buf *b = malloc(sizeof *b);
    samp_point pts[16];
    uint32_t n = floor_points(pts);
    enum { RAYS = 4096 };
    uint32_t *count = malloc(n * sizeof *count), *tri = malloc((size_t)n * RAYS * sizeof *tri);
    float *weight = malloc((size_t)n * RAYS * sizeof *weight), E[48];
    lm_error err;
    make_mesh(s, 3.0f, 1.0f, b);
    const samp_source_hits hits = {.rays = RAYS, .count = count, .tri = tri, .weight = weight};
    CHECK(samp_indirect_sources(sp, &b->m, pts, n, &hits, &err) == LM_OK);
    CHECK(samp_indirect(sp, &b->m, pts, n, E, &err) == LM_OK);
    const double ceil_local[4][3] = {{0, 1, 0}, {1, 1, 0}, {1, 1, 1}, {0, 1, 1}};
    double ceil_quad[4][3], worst_ceiling = 0.0, worst_total = 0.0, worst_gather = 0.0;
    for (int i = 0; i < 4; ++i) rot(ceil_local[i], ceil_quad[i]);
    for (uint32_t i = 0; i < n; ++i) {
        const double x[3] = {pts[i].p[0], pts[i].p[1], pts[i].p[2]}, nx[3] = {pts[i].n[0], pts[i].n[1], pts[i].n[2]};
        double ceiling = 0.0, total = 0.0, gather = 0.0;
        for (uint32_t j = 0; j < count[i]; ++j) {
            uint32_t t = tri[(size_t)i * RAYS + j];
            double w = weight[(size_t)i * RAYS + j];
            CHECK(t < b->m.tri_count && w > 0.0);
            if (j) CHECK(t > tri[(size_t)i * RAYS + j - 1]);
            total += w;
            if (t == 2 || t == 3) ceiling += w;
            gather += M_PI * w * b->rad[9 * t];
        }
        double want = (samp_polygon_G(ceil_quad, 4, x, nx) - unocc(s, 0, &pts[i])) / M_PI;
        worst_ceiling = fmax(worst_ceiling, fabs(ceiling - want) / want);
        worst_total = fmax(worst_total, fabs(total - 1.0));
        worst_gather = fmax(worst_gather, fabs(gather - E[3 * i]) / E[3 * i]);
    }
    printf("sources (4096 rays): ceiling fraction max rel err %.2e, closed room total %.2e, "
           "against the gather %.2e\n", worst_ceiling, worst_total, worst_gather);
    CHECK_MSG(worst_ceiling <= 0.02, "ceiling fraction: %.3e", worst_ceiling);
    /* (a ray or two in 4096 slips out where walls meet at a point's corner: 4.9e-4 measured) */
    CHECK_MSG(worst_total <= 1e-3, "a closed room's fractions sum to 1: %.3e off", worst_total);
    CHECK_MSG(worst_gather <= 0.01, "pi sum w L against the gather: %.3e", worst_gather);
    CHECK(samp_indirect_sources(sp, &b->m, pts, n, &(samp_source_hits){.rays = 0, .count = count, .tri = tri,
                                                                       .weight = weight}, &err) == LM_ERR_INVALID_ARG);
    free(count);
    free(tri);
    free(weight);
    free(b);
    samp_destroy(sp);
    scene_destroy(s);
}

/* samp_source_hits.strat_var against the spread of stratified gathers: 64
 * independent 256-ray gathers a floor point (samp_indirect_noise, other streams)
 * in the room whose ceiling is 3× as bright as its walls. The collapsed-strata
 * estimate is to err high (at least half the measured variance, summed over the
 * points) yet count the strata (below 3/4 of the rays' plain variance). Measured:
 * 0.113 predicted, 0.064 measured, 0.250 plain. */
static void test_strat_var(void)
{
    scene *s = load("room_strat.json", inside_light(), NULL);
    if (!s) return;
    samp_sampler *sp = NULL;
    lm_error err;
    CHECK(samp_create(&(samp_desc){.scene = s, .backend = SAMP_BACKEND_EMBREE, .threads = 2, .indirect_rays = 256},
                      &sp, &err) == LM_OK);
    mesh_buf *b = malloc(sizeof *b);
    samp_point pts[16];
    uint32_t n = floor_points(pts);
    enum { RAYS = 256, PASSES = 64 };
    uint32_t *count = malloc(n * sizeof *count), *tri = malloc((size_t)n * RAYS * sizeof *tri);
    float *weight = malloc((size_t)n * RAYS * sizeof *weight), strat[48], E[48], sig[48];
    double m1[16] = {0}, m2[16] = {0};
    make_mesh(s, 3.0f, 1.0f, b);
    CHECK(sp && samp_indirect_sources(sp, &b->m, pts, n,
                                      &(samp_source_hits){.rays = RAYS, .count = count, .tri = tri, .weight = weight,
                                                          .strat_var = strat},
                                      &err) == LM_OK);
    for (uint32_t p = 1; sp && p <= PASSES; ++p) {
        CHECK(samp_indirect_noise(sp, &b->m, pts, n, p, 1, E, sig, &err) == LM_OK);
        for (uint32_t i = 0; i < n; ++i) {
            m1[i] += E[3 * i] / PASSES;
            m2[i] += (double)E[3 * i] * E[3 * i] / PASSES;
        }
    }
    double predicted = 0.0, measured = 0.0, plain = 0.0;
    for (uint32_t i = 0; i < n; ++i) {
        double a = 0.0, a2 = 0.0;
        for (uint32_t j = 0; j < count[i]; ++j) {
            double w = weight[(size_t)i * RAYS + j], L = M_PI * b->rad[9 * tri[(size_t)i * RAYS + j]];
            a += w * L;
            a2 += w * L * L;
        }
        plain += (a2 - a * a) / RAYS;
        predicted += strat[3 * i] / RAYS;
        measured += (m2[i] - m1[i] * m1[i]) * PASSES / (PASSES - 1);
    }
    printf("strata: a 256-ray gather's variance summed over %u points: predicted %.3e (collapsed strata), measured "
           "%.3e over %d gathers, plain %.3e\n", n, predicted, measured, PASSES, plain);
    CHECK_MSG(predicted >= 0.5 * measured, "strat_var errs low: %.3e against %.3e measured", predicted, measured);
    CHECK_MSG(predicted < 0.75 * plain, "strat_var does not count the strata: %.3e against %.3e plain", predicted,
              plain);
    free(count);
    free(tri);
    free(weight);
    free(b);
    samp_destroy(sp);
    scene_destroy(s);
}

static void test_determinism_and_garbage(void)
{
    char lights[1024];
    double pl[3];
    rot((const double[3]){0.5, 0.5, 0.5}, pl);
    snprintf(lights, sizeof lights, "%s, {\"type\": \"point\", \"position\": [%.9g, %.9g, %.9g], \"intensity\": [1, 1, 1]}",
             inside_light(), pl[0], pl[1], pl[2]);
    scene *s = load("room_det.json", lights, NULL);
    if (!s) return;
    samp_sampler *a = make(s, 64, SAMP_OFF, 1), *b = make(s, 64, SAMP_OFF, 2);
    enum { N = 200 };
    samp_point pts[N], rev[N];
    for (int i = 0; i < N; ++i) {
        float u = (float)((i * 37) % 101) / 100.0f, v = (float)((i * 61) % 103) / 102.0f;
        pts[i] = pt(u, 0.0f, v, 0, 1, 0, 0);
        rev[N - 1 - i] = pts[i];
    }
    float ga[N], gb[N];
    lm_error err;
    CHECK(samp_direct(a, 0, pts, N, ga, &err) == LM_OK);
    CHECK(samp_direct(b, 0, rev, N, gb, &err) == LM_OK);
    int same = 0;
    for (int i = 0; i < N; ++i) same += ga[i] == gb[N - 1 - i];
    CHECK_MSG(same == N, "%d of %d values depend on the batch or thread count", N - same, N);

    /* Point light (light index 1): cosθ/r² in the open; 0 behind the receiver. */
    samp_point q[2] = {pt(0.5f, 0.0f, 0.5f, 0, 1, 0, 2), pt(0.5f, 0.2f, 0.5f, 0, -1, 0, 0)};
    float gp[2];
    CHECK(samp_direct(a, 1, q, 2, gp, &err) == LM_OK);
    CHECK_NEAR(gp[0], 1.0 / 0.25, 1e-5);
    CHECK(gp[1] == 0.0f);

    /* Garbage: zero normal, huge coordinates; errors for NaN and bad light ids. */
    samp_point junk[3] = {pt(0.5f, 0.0f, 0.5f, 0, 0, 0, 0), (samp_point){{1e30f, 1e30f, -1e30f}, {0, 1, 0}, 0},
                          pt(0.5f, 0.5f, 0.5f, 0, 1, 0, 999)};
    float gj[3];
    CHECK(samp_direct(a, 0, junk, 3, gj, &err) == LM_OK);
    for (int i = 0; i < 3; ++i) CHECK_MSG(isfinite(gj[i]) && gj[i] >= 0.0f, "junk %d: %g", i, gj[i]);
    samp_point nan = pt(NAN, 0, 0, 0, 1, 0, 0);
    CHECK(samp_direct(a, 0, &nan, 1, gj, &err) == LM_ERR_INVALID_ARG);
    CHECK(samp_direct(a, 7, q, 1, gj, &err) == LM_ERR_INVALID_ARG && strstr(err.msg, "light 7") != NULL);
    samp_destroy(a);
    samp_destroy(b);
    scene_destroy(s);
}

/* Point location in a radiance mesh (samp_radiance_at): scene triangle 0 cut into
 * the 4^5 triangles of a midpoint lattice (a grid index), radiance linear in
 * (w1, w2), so every look-up must give the linear value exactly where it is
 * (inside, on an edge, at a corner), with the index and by linear search alike.
 * And a prepared mesh (samp_radiance_mesh_prepare) gives the same gathers as one
 * checked and indexed per call; a non-finite one is refused. */
static void lattice(const float a[2], const float b[2], const float c[2], int depth, float *bary, uint32_t *n)
{
    if (depth == 0) {
        const float *v[3] = {a, b, c};
        for (int k = 0; k < 3; ++k) {
            bary[6 * *n + 2 * (uint32_t)k] = v[k][0];
            bary[6 * *n + 2 * (uint32_t)k + 1] = v[k][1];
        }
        ++*n;
        return;
    }
    const float ab[2] = {(a[0] + b[0]) / 2, (a[1] + b[1]) / 2}, bc[2] = {(b[0] + c[0]) / 2, (b[1] + c[1]) / 2},
                ca[2] = {(c[0] + a[0]) / 2, (c[1] + a[1]) / 2};
    lattice(a, ab, ca, depth - 1, bary, n);
    lattice(ab, b, bc, depth - 1, bary, n);
    lattice(ca, bc, c, depth - 1, bary, n);
    lattice(bc, ca, ab, depth - 1, bary, n); /* the middle one, turned */
}

static float linear_L(float w1, float w2, int ch) { return 1.0f + (float)(ch + 1) * w1 + 2.0f * w2; }

static void test_radiance_index(void)
{
    scene *s = load("room_ix.json", inside_light(), NULL);
    if (!s) return;
    enum { DEPTH = 5, SUBS = 1024 };
    uint32_t *first = calloc(s->tri_count + 1, sizeof *first);
    float *bary = malloc(6 * SUBS * sizeof *bary), *rad = malloc(9 * SUBS * sizeof *rad);
    uint32_t n = 0;
    lattice((const float[2]){0, 0}, (const float[2]){1, 0}, (const float[2]){0, 1}, DEPTH, bary, &n);
    CHECK(n == SUBS);
    for (uint32_t t = 1; t <= s->tri_count; ++t) first[t] = SUBS;
    for (uint32_t i = 0; i < SUBS; ++i)
        for (int k = 0; k < 3; ++k)
            for (int ch = 0; ch < 3; ++ch)
                rad[9 * i + 3 * (uint32_t)k + (uint32_t)ch] = linear_L(bary[6 * i + 2 * (uint32_t)k], bary[6 * i + 2 * (uint32_t)k + 1], ch);
    samp_radiance_mesh m = {.tri_count = SUBS, .first = first, .bary = bary, .radiance = rad};
    samp_radiance_index ix, none = {0};
    lm_error err;
    CHECK(samp_radiance_mesh_prepare(s, &m, &ix, &err) == LM_OK && ix.checked && ix.res && ix.res[0] > 0);
    lm_rng g;
    lm_rng_seed(&g, 7, 0, 0);
    double worst = 0.0, outside = 0.0;
    int differ = 0;
    for (int q = 0; q < 4000; ++q) {
        float w1, w2;
        if (q < 1000) { /* lattice points and edge midpoints at depth DEPTH + 1: on corners and edges */
            int i = q % 65, j = (q / 65) % 65;
            if (i + j > 64) continue;
            w1 = (float)i / 64.0f;
            w2 = (float)j / 64.0f;
        } else {
            w1 = lm_rng_float(&g);
            w2 = lm_rng_float(&g) * (1.0f - w1);
        }
        float a[3], b[3];
        uint32_t ta = samp_radiance_at(&m, &ix, 0, w1, w2, a), tb = samp_radiance_at(&m, &none, 0, w1, w2, b);
        CHECK(ta < SUBS && tb < SUBS);
        if (ta < SUBS) { /* the point is in the sub-triangle found (or on its edge) */
            const float *b3 = bary + 6 * ta;
            double det = (b3[2] - b3[0]) * (b3[5] - b3[1]) - (b3[4] - b3[0]) * (b3[3] - b3[1]);
            double l1 = ((w1 - b3[0]) * (b3[5] - b3[1]) - (b3[4] - b3[0]) * (w2 - b3[1])) / det;
            double l2 = ((b3[2] - b3[0]) * (w2 - b3[1]) - (w1 - b3[0]) * (b3[3] - b3[1])) / det;
            outside = fmax(outside, -fmin(1.0 - l1 - l2, fmin(l1, l2)));
        }
        for (int ch = 0; ch < 3; ++ch) {
            worst = fmax(worst, fabs(a[ch] - linear_L(w1, w2, ch)));
            worst = fmax(worst, fabs(b[ch] - linear_L(w1, w2, ch)));
            differ += fabsf(a[ch] - b[ch]) > 1e-5f;
        }
    }
    printf("radiance index: worst error of a linear field %.2e, %d values differ from the linear search\n", worst,
           differ);
    CHECK_MSG(worst < 1e-5, "point location: %.3e from the linear field", worst);
    CHECK_MSG(outside < 1e-6, "point location: a point %.3e outside the sub-triangle found", outside);
    CHECK(differ == 0);

    /* A prepared mesh gathers what an unprepared one does, ray for ray. */
    samp_sampler *sp = make(s, 64, 0, 2);
    samp_point pts[16];
    uint32_t np = floor_points(pts);
    float E0[48], E1[48];
    CHECK(samp_indirect(sp, &m, pts, np, E0, &err) == LM_OK);
    samp_radiance_mesh mp = m;
    mp.index = &ix;
    CHECK(samp_indirect(sp, &mp, pts, np, E1, &err) == LM_OK);
    CHECK(memcmp(E0, E1, 3 * np * sizeof *E0) == 0);
    samp_radiance_index_free(&ix);
    rad[5] = NAN;
    CHECK(samp_radiance_mesh_prepare(s, &m, &ix, &err) == LM_ERR_INVALID_ARG && !ix.checked);
    CHECK(strstr(err.msg, "finite") != NULL);
    samp_destroy(sp);
    free(first);
    free(bary);
    free(rad);
    scene_destroy(s);
}

int main(void)
{
    init_rotation();
    test_unoccluded_and_acne();
    test_no_leak();
    test_behind_and_touching();
    test_half_blocker();
    test_indirect();
    test_lobe_gather();
    test_sources();
    test_strat_var();
    test_determinism_and_garbage();
    test_radiance_index();
    return test_finish("samp_embree_test");
}
