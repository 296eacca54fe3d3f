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
 * The reported standard error is checked for honesty against the spread of the
 * pixel means over independent seeds (full transport, where there is real noise).
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "reference.h"
#include "scene.h"
#include "test_util.h"
#include "vecmath.h"

enum { W = 16, H = 16 };
#define RHO 0.5
#define INTENSITY 3.0
#define RADIUS 2.0

/* Icosphere of the given subdivision level, faces wound to face the centre. */
static double write_icosphere(int level, char *path, size_t n)
{
    int cap_v = 12 * (1 << (2 * level)) * 4 + 64, cap_f = 20 * (1 << (2 * level));
    double (*v)[3] = malloc((size_t)cap_v * sizeof *v);
    int (*f)[3] = malloc((size_t)cap_f * sizeof *f), (*g)[3] = malloc((size_t)cap_f * sizeof *g);
    const double t = (1.0 + sqrt(5.0)) / 2.0;
    const double base[12][3] = {{-1, t, 0}, {1, t, 0}, {-1, -t, 0}, {1, -t, 0}, {0, -1, t}, {0, 1, t},
                                {0, -1, -t}, {0, 1, -t}, {t, 0, -1}, {t, 0, 1}, {-t, 0, -1}, {-t, 0, 1}};
    const int faces[20][3] = {{0, 11, 5}, {0, 5, 1}, {0, 1, 7}, {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
                              {11, 10, 2}, {10, 7, 6}, {7, 1, 8}, {3, 9, 4}, {3, 4, 2}, {3, 2, 6}, {3, 6, 8},
                              {3, 8, 9}, {4, 9, 5}, {2, 4, 11}, {6, 2, 10}, {8, 6, 7}, {9, 8, 1}};
    int nv = 12, nf = 20;
    for (int i = 0; i < 12; ++i) {
        double l = sqrt(base[i][0] * base[i][0] + base[i][1] * base[i][1] + base[i][2] * base[i][2]);
        for (int k = 0; k < 3; ++k) v[i][k] = base[i][k] / l;
    }
    memcpy(f, faces, sizeof faces);
    for (int lv = 0; lv < level; ++lv) {
        int ng = 0;
        for (int i = 0; i < nf; ++i) {
            int m[3];
            for (int e = 0; e < 3; ++e) {
                int a = f[i][e], b = f[i][(e + 1) % 3];
                double p[3], l = 0;
                for (int k = 0; k < 3; ++k) {
                    p[k] = v[a][k] + v[b][k];
                    l += p[k] * p[k];
                }
                l = sqrt(l);
                /* a new vertex per face edge: both faces compute the same sum,
                 * so the loader's exact welding joins them */
                if (nv >= cap_v) {
                    cap_v *= 2;
                    v = realloc(v, (size_t)cap_v * sizeof *v);
                }
                for (int k = 0; k < 3; ++k) v[nv][k] = p[k] / l;
                int found = nv++;
                m[e] = found;
            }
            int tri[4][3] = {{f[i][0], m[0], m[2]}, {f[i][1], m[1], m[0]}, {f[i][2], m[2], m[1]}, {m[0], m[1], m[2]}};
            memcpy(g[ng], tri, sizeof tri);
            ng += 4;
        }
        nf = ng;
        int(*tmp)[3] = f;
        f = g;
        g = tmp;
    }
    FILE *out = fopen(path, "w");
    double dmin = 1.0;
    if (out) {
        for (int i = 0; i < nv; ++i) fprintf(out, "v %.17g %.17g %.17g\n", RADIUS * v[i][0], RADIUS * v[i][1], RADIUS * v[i][2]);
        for (int i = 0; i < nf; ++i) {
            /* outward winding is (0,1,2): write (0,2,1) to face the centre */
            fprintf(out, "f %d %d %d\n", f[i][0] + 1, f[i][2] + 1, f[i][1] + 1);
            lm_dvec3 a = dv3(v[f[i][0]][0], v[f[i][0]][1], v[f[i][0]][2]);
            lm_dvec3 b = dv3(v[f[i][1]][0], v[f[i][1]][1], v[f[i][1]][2]);
            lm_dvec3 c = dv3(v[f[i][2]][0], v[f[i][2]][1], v[f[i][2]][2]);
            lm_dvec3 nrm = dv3_normalize(dv3_cross(dv3_sub(b, a), dv3_sub(c, a)));
            double d = fabs(dv3_dot(nrm, a));
            if (d < dmin) dmin = d;
        }
        fclose(out);
    }
    CHECK_MSG(out != NULL, "cannot write %s", path);
    (void)n;
    free(v);
    free(f);
    free(g);
    return 1.0 / (dmin * dmin) - 1.0; /* relative bias bound (R/d)² − 1 */
}

static scene *load_sphere_scene(double *bias)
{
    char obj[1024], json[1024], text[1024];
    snprintf(obj, sizeof obj, "%s/icosphere.obj", LUMESH_TMP_DIR);
    *bias = write_icosphere(5, obj, sizeof obj);
    snprintf(text, sizeof text,
             "{\"meshes\": [{\"file\": \"icosphere.obj\", \"material\": \"grey\"}],"
             " \"materials\": {\"grey\": {\"kd\": [%g, %g, %g]}},"
             " \"lights\": [{\"type\": \"point\", \"position\": [0, 0, 0], \"intensity\": [%g, %g, %g]}],"
             " \"cameras\": [{\"position\": [0, 0, 0], \"target\": [0.3, 0.2, 1], \"fov_y\": 90,"
             " \"width\": %d, \"height\": %d}]}",
             RHO, RHO, RHO, INTENSITY, INTENSITY, INTENSITY, W, H);
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

static void render(const scene *s, ref_transport tr, int bounces, uint32_t seed, int spp, run *out)
{
    ref_desc d = {.scene = s, .transport = tr, .bounces = bounces, .seed = seed, .threads = 2};
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
    CHECK_MSG(fabs(mean - expected) <= 3.0 * se_mean + bias * expected, "%s: mean %.6f vs %.6f", label, mean,
              expected);
}

int main(void)
{
    double bias;
    scene *s = load_sphere_scene(&bias);
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
