/* reference_sphere_test — closed-form checks of the reference renderer.
 *
 * A closed sphere of radius R with inward normals, grey albedo ρ, an isotropic
 * point light of intensity I at its centre, camera inside. Every pixel is
 *     model, 1 bounce:  ρ·I/R²·(1+ρ)/π
 *     model, 2 bounces: ρ·I/R²·(1+ρ+ρ²)/π
 *     full transport:   ρ·I/R²/(π(1−ρ))
 * The sphere is an icosphere, so the irradiance I·cosθ/r² on a facet departs from
 * I/R² by at most a known factor: with d the smallest facet-plane distance to the
 * centre, I·d/R³ <= E <= I/d², a relative bias below b = (R/d)² − 1. A pixel passes
 * when |value − expected| <= 3·SE + b·expected; the test also asks that almost
 * every pixel passes (3 SE is a 99.7% band) and that the image mean passes with
 * the standard error of the mean.
 * With a Phong coat (ks κ, exponent n) every point is seen along its normal from
 * the centre, so the model transport adds κ·(n+2)/(2π)·I/R² (the light in the
 * lobe) and κ·L_src (the lobe reflecting the uniform source of the bounces,
 * ρ·I/(πR²)·Σ_(k<K) ρ^k; the lobe about the normal integrates to 1), the second
 * not with REF_GLOSSY_DIRECT. The tilt of a flat facet moves the lobe's value at
 * the light by about 2n times the bias bound.
 * The reported standard error is checked for honesty against the spread of the
 * pixel means over independent seeds (full transport, where there is real noise).
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "sampling/reference.h"
#include "src/base/vecmath.h"
#include "src/scene/scene.h"
#include "tests/test_util.h"

enum { W = 16, H = 16 };
#define RHO 0.5
#define INTENSITY 3.0
#define RADIUS 2.0

#define KS 0.3
#define PHONG_N 2.0

static scene *load_sphere_scene(double *bias, double ks, double phong_n)
{
    char obj[1024], json[1024], text[1024];
    snprintf(obj, sizeof obj, "%s/icosphere.obj", LUMESH_TMP_DIR);
    *bias = test_write_icosphere(5, RADIUS, obj);
    snprintf(text, sizeof text,
             "{\"meshes\": [{\"file\": \"icosphere.obj\", \"material\": \"grey\"}],"
             " \"materials\": {\"grey\": {\"kd\": [%g, %g, %g], \"ks\": [%g, %g, %g], \"n\": %g}},"
             " \"lights\": [{\"type\": \"point\", \"position\": [0, 0, 0], \"intensity\": [%g, %g, %g]}],"
             " \"cameras\": [{\"position\": [0, 0, 0], \"target\": [0.3, 0.2, 1], \"fov_y\": 90,"
             " \"width\": %d, \"height\": %d}]}",
             RHO, RHO, RHO, ks, ks, ks, phong_n, INTENSITY, INTENSITY, INTENSITY, W, H);
    test_write_file("sphere.json", text, json, sizeof json);
    scene_load_desc d = {.path = json, .require_light = 1, .crease_angle_deg = 0.01f};
    scene *s = NULL;
    lm_error err;
    lm_result r = scene_load(&d, &s, &err);
    CHECK_MSG(r == LM_OK, "%s", err.msg);
    return s;
}

typedef struct run {
    float rgb[W * H * 3], se[W * H * 3];
} run;

static ref_estimator estimator = REF_ESTIMATOR_PATHS; /* which estimator the renders below use */

static void render_glossy(const scene *s, ref_transport tr, int bounces, ref_glossy glossy, uint32_t seed, int spp,
                          run *out)
{
    ref_desc d = {.scene = s, .transport = tr, .bounces = bounces, .glossy = glossy, .seed = seed, .threads = 2,
                  .estimator = estimator, .vpl_clamp = REF_VPL_NO_CLAMP};
    ref_renderer *r;
    lm_error err;
    lm_result res = ref_create(&d, &r, &err);
    CHECK_MSG(res == LM_OK, "%s", err.msg);
    if (res != LM_OK) return;
    for (int i = 0; i < spp; ++i) ref_render_pass(r, NULL, 0.0);
    ref_get_image(r, out->rgb, out->se, NULL);
    ref_stats st;
    ref_get_stats(r, &st);
    CHECK(st.bad_samples == 0 && st.min_samples == (uint32_t)spp && st.max_samples == (uint32_t)spp);
    ref_destroy(r);
}

static void render(const scene *s, ref_transport tr, int bounces, uint32_t seed, int spp, run *out)
{
    render_glossy(s, tr, bounces, REF_GLOSSY_INDIRECT, seed, spp, out);
}

/* check_against's mean is within this fraction of the expected value (0: not
 * asked), and not tested against its pixels' standard errors: a VPL pass's
 * pixels share its VPLs, so their errors are correlated and the image mean's
 * error is not their standard errors added in quadrature. */
static double mean_within = 0.0;

static void check_against(const char *label, const run *res, double expected, double bias)
{
    int outside3 = 0, outside5 = 0;
    double sum = 0.0, se2 = 0.0, worst = 0.0;
    /* The mean over pixels, with the standard error of that mean: channels of a
     * grey image are one quantity, so one channel per pixel enters se2. */
    for (int i = 0; i < W * H * 3; i += 3) se2 += (double)res->se[i] * res->se[i];
    for (int i = 0; i < W * H * 3; ++i) {
        double dev = fabs(res->rgb[i] - expected), tol = bias * expected;
        outside3 += dev > 3.0 * res->se[i] + tol;
        outside5 += dev > 5.0 * res->se[i] + tol;
        double z = (dev - tol) / (res->se[i] > 0 ? res->se[i] : 1e-30);
        if (z > worst) worst = z;
        sum += res->rgb[i];
    }
    double mean = sum / (W * H * 3), se_mean = sqrt(se2) / (W * H);
    printf("  %-18s expected %.6f  mean %.6f  SE(mean) %.2e  bias bound %.2e  outside 3SE: %d/%d  worst z %.2f\n",
           label, expected, mean, se_mean, bias * expected, outside3, W * H * 3, worst);
    CHECK_MSG(outside3 <= (W * H * 3) / 100, "%s: %d values outside 3 SE", label, outside3);
    CHECK_MSG(outside5 == 0, "%s: %d values outside 5 SE", label, outside5);
    if (mean_within == 0.0)
        CHECK_MSG(fabs(mean - expected) <= 3.0 * se_mean + bias * expected, "%s: mean %.6f vs %.6f", label, mean,
                  expected);
    else
        CHECK_MSG(fabs(mean - expected) <= mean_within * expected, "%s: mean %.6f is %.2f%% from %.6f", label, mean,
                  100.0 * (mean - expected) / expected, expected);
}

/* Instant radiosity (REF_ESTIMATOR_VPL, no clamp: inside a sphere the geometry
 * term between two of its points is 1/(4R²), never large) against the same
 * closed forms, each within 1% in the mean: the VPLs' bounces are the partial
 * sums of the series, and the full transport its sum. */
static void check_vpl(const scene *s, const scene *coated, double e, double bias, double coat_bias)
{
    enum { SHARP_N = 20 }; /* above REF_VPL_LOBE_SAMPLED_N: the lobe reflects the VPLs by a ray */
    estimator = REF_ESTIMATOR_VPL;
    mean_within = 0.01;
    static run a, b, c, g;
    render(s, REF_TRANSPORT_MODEL, 0, 3, 64, &a);
    check_against("VPL, model, 1 bounce", &a, e * (1 + RHO), bias);
    render(s, REF_TRANSPORT_MODEL, 3, 3, 64, &b);
    check_against("VPL, model, 3 bounces", &b, e * (1 + RHO + RHO * RHO + RHO * RHO * RHO), bias);
    render(s, REF_TRANSPORT_FULL, 0, 3, 64, &c);
    check_against("VPL, full", &c, e / (1 - RHO), bias);
    if (coated) {
        const double e0 = INTENSITY / (RADIUS * RADIUS), lobe = KS * (PHONG_N + 2.0) / (2.0 * M_PI) * e0;
        const double src2 = RHO * e0 / M_PI * (1 + RHO), tilt = (1.0 + 2.0 * PHONG_N) * coat_bias;
        render_glossy(coated, REF_TRANSPORT_MODEL, 2, REF_GLOSSY_INDIRECT, 3, 64, &g);
        check_against("VPL, model, 2 bounces, Phong coat", &g, e * (1 + RHO + RHO * RHO) + lobe + KS * src2, tilt);
        double sb;
        scene *sharp = load_sphere_scene(&sb, KS, SHARP_N);
        if (sharp) {
            static run h;
            const double sharp_lobe = KS * (SHARP_N + 2.0) / (2.0 * M_PI) * e0;
            render_glossy(sharp, REF_TRANSPORT_MODEL, 2, REF_GLOSSY_INDIRECT, 3, 64, &h);
            check_against("VPL, model, 2 bounces, sharp coat", &h, e * (1 + RHO + RHO * RHO) + sharp_lobe + KS * src2,
                          (1.0 + 2.0 * SHARP_N) * sb);
            /* The lobe's reflection of the room alone: the same seed with the lights
             * only draws the same direct light, so the difference is KS·L_is. */
            static run hd;
            render_glossy(sharp, REF_TRANSPORT_MODEL, 2, REF_GLOSSY_DIRECT, 3, 64, &hd);
            double diff = 0.0;
            for (int i = 0; i < W * H * 3; ++i) diff += (double)h.rgb[i] - hd.rgb[i];
            diff /= W * H * 3;
            printf("  VPL, sharp coat's reflection of the room: %.6f, expected %.6f (%+.2f%%)\n", diff, KS * src2,
                   100.0 * (diff / (KS * src2) - 1.0));
            CHECK_MSG(fabs(diff - KS * src2) <= 0.01 * KS * src2, "sharp coat's L_is %.6f vs %.6f", diff, KS * src2);
            scene_destroy(sharp);
        }
    }
    estimator = REF_ESTIMATOR_PATHS;
    mean_within = 0.0;
}

int main(void)
{
    double bias;
    scene *s = load_sphere_scene(&bias, 0.0, PHONG_N);
    if (!s) return test_finish("reference_sphere_test");
    CHECK(s->tri_count == 20480);
    double e = RHO * INTENSITY / (RADIUS * RADIUS) / M_PI;
    printf("icosphere facets: relative bias bound %.2e\n", bias);

    static run a, b, c;
    render(s, REF_TRANSPORT_MODEL, 0, 1, 8, &a);
    check_against("model, 1 bounce", &a, e * (1 + RHO), bias);
    render(s, REF_TRANSPORT_MODEL, 2, 1, 8, &b);
    check_against("model, 2 bounces", &b, e * (1 + RHO + RHO * RHO), bias);
    /* A pixel's own error estimate is only as good as its sample of long paths:
     * with the textbook roulette (survival = throughput) 6% of pixels landed
     * beyond 3 SE at 64 spp; the bounded-weight roulette of reference.c has none. */
    render(s, REF_TRANSPORT_FULL, 0, 1, 128, &c);
    check_against("full", &c, e / (1 - RHO), bias);

    /* The Phong coat (see the top). */
    {
        double gb;
        scene *gs = load_sphere_scene(&gb, KS, PHONG_N);
        if (gs) {
            const double e0 = INTENSITY / (RADIUS * RADIUS), lobe = KS * (PHONG_N + 2.0) / (2.0 * M_PI) * e0;
            const double src1 = RHO * e0 / M_PI, src2 = src1 * (1 + RHO), tilt = (1.0 + 2.0 * PHONG_N) * gb;
            static run g1, g2, gd;
            render_glossy(gs, REF_TRANSPORT_MODEL, 0, REF_GLOSSY_INDIRECT, 1, 128, &g1);
            check_against("model, 1 bounce, Phong coat", &g1, e * (1 + RHO) + lobe + KS * src1, tilt);
            render_glossy(gs, REF_TRANSPORT_MODEL, 2, REF_GLOSSY_INDIRECT, 1, 128, &g2);
            check_against("model, 2 bounces, Phong coat", &g2, e * (1 + RHO + RHO * RHO) + lobe + KS * src2, tilt);
            render_glossy(gs, REF_TRANSPORT_MODEL, 0, REF_GLOSSY_DIRECT, 1, 128, &gd);
            check_against("model, 1 bounce, Phong coat, the lights only", &gd, e * (1 + RHO) + lobe, tilt);
            check_vpl(s, gs, e, bias, gb);
            scene_destroy(gs);
        }
    }

    /* Honest standard error: the spread of independent seeds' pixel means. */
    enum { SEEDS = 6 };
    static run runs[SEEDS];
    for (int k = 0; k < SEEDS; ++k) render(s, REF_TRANSPORT_FULL, 0, 100 + (uint32_t)k, 32, &runs[k]);
    double emp = 0.0, rep = 0.0;
    for (int i = 0; i < W * H * 3; ++i) {
        double m = 0.0, v = 0.0, r2 = 0.0;
        for (int k = 0; k < SEEDS; ++k) m += runs[k].rgb[i];
        m /= SEEDS;
        for (int k = 0; k < SEEDS; ++k) {
            v += (runs[k].rgb[i] - m) * (runs[k].rgb[i] - m);
            r2 += (double)runs[k].se[i] * runs[k].se[i];
        }
        emp += v / (SEEDS - 1);
        rep += r2 / SEEDS;
    }
    double ratio = sqrt(emp / rep);
    printf("  standard error honesty: spread of %d seeds / reported = %.3f\n", SEEDS, ratio);
    CHECK_MSG(ratio > 0.85 && ratio < 1.18, "spread/reported SE = %.3f", ratio);

    /* Same seed and sample count: the same image, whatever the thread count. */
    static run d1, d2;
    ref_desc dd = {.scene = s, .transport = REF_TRANSPORT_FULL, .seed = 7, .threads = 1};
    ref_renderer *r1, *r2;
    lm_error err;
    if (ref_create(&dd, &r1, &err) == LM_OK) {
        dd.threads = 2;
        if (ref_create(&dd, &r2, &err) == LM_OK) {
            for (int i = 0; i < 3; ++i) {
                ref_render_pass(r1, NULL, 0.0);
                ref_render_pass(r2, NULL, 0.0);
            }
            ref_get_image(r1, d1.rgb, d1.se, NULL);
            ref_get_image(r2, d2.rgb, d2.se, NULL);
            CHECK(memcmp(d1.rgb, d2.rgb, sizeof d1.rgb) == 0);
            ref_destroy(r2);
        }
        ref_destroy(r1);
    }
    scene_destroy(s);
    return test_finish("reference_sphere_test");
}
