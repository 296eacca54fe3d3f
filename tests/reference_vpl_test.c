/* reference_vpl_test — instant radiosity and its bidirectional resampling
 * (REF_ESTIMATOR_VPL, REF_ESTIMATOR_BDIR; sampling/ref_vpl.h) against the path
 * tracer, where the VPLs' contributions to what the camera sees vary.
 *
 * The closed forms (VPLs in the point-light sphere converge to the bounce sums)
 * are in reference_sphere_test. Here the same diffuse sphere (radius 2, faces
 * inward) holds a black square between the camera's view and the far cap: the
 * camera sees the near cap, VPLs on the far cap are hidden from most of it, so
 * BDIR's importance varies from zero to large and its resampling is tested where
 * it matters. No wall meets another at a corner (the sphere is smooth, the
 * square floats), so the geometry term between two lit points stays bounded and
 * the unclamped estimators have no heavy tail (in a box, VPLs by its edges make
 * one: means over seeds then fall short of the truth until a rare huge sample).
 * With the clamp off, each estimator's image mean over independent seeds must
 * agree with the path tracer's (the same model transport, two bounces; and the
 * full transport) within three standard errors of their difference: the seeds'
 * spread for the VPL methods (a pass's pixels share its VPLs, so their errors
 * are correlated), the pixels' standard errors for the path tracer
 * (independent). BDIR must also keep fewer VPLs than it traced. The same sphere
 * lit by a small quad light instead of the point light tests both with an area
 * light's sampling too (model transport).
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "sampling/reference.h"
#include "src/scene/scene.h"
#include "tests/test_util.h"

enum { W = 24, H = 18, SEEDS = 16, PASSES = 16, PT_SPP = 512 };

static const char square_text[] = "v -1.2 -1.2 -0.8\nv 1.2 -1.2 -0.8\nv 1.2 1.2 -0.8\nv -1.2 1.2 -0.8\nf 1 2 3\nf 1 3 4\n";

static const char json_text[] =
    "{\"meshes\": [{\"file\": \"vpl_sphere.obj\", \"material\": \"white\"},"
    "            {\"file\": \"vpl_square.obj\", \"material\": \"black\"}],"
    " \"materials\": {\"white\": {\"kd\": [0.6, 0.5, 0.4]}, \"black\": {\"kd\": [0, 0, 0]}},"
    " \"lights\": [{\"type\": \"point\", \"position\": [0.3, 0.9, 0.4], \"intensity\": [3, 3, 3]}],"
    " \"cameras\": [{\"position\": [0, 0, -0.2], \"target\": [0, 0, 2], \"fov_y\": 70,"
    " \"width\": 24, \"height\": 18}]}";

/* The same, lit by a small quad facing down instead (area-light sampling). */
static const char quad_json_text[] =
    "{\"meshes\": [{\"file\": \"vpl_sphere.obj\", \"material\": \"white\"},"
    "            {\"file\": \"vpl_square.obj\", \"material\": \"black\"}],"
    " \"materials\": {\"white\": {\"kd\": [0.6, 0.5, 0.4]}, \"black\": {\"kd\": [0, 0, 0]}},"
    " \"lights\": [{\"type\": \"quad\", \"corner\": [0.1, 1.2, 0.2], \"edge1\": [0.4, 0, 0],"
    " \"edge2\": [0, 0, 0.4], \"radiance\": [12, 12, 12]}],"
    " \"cameras\": [{\"position\": [0, 0, -0.2], \"target\": [0, 0, 2], \"fov_y\": 70,"
    " \"width\": 24, \"height\": 18}]}";

/* The image mean (all channels) of one render, and the standard error of that
 * mean from its pixels' standard errors (independent pixels only). */
static double render_mean(const scene *s, ref_transport tr, ref_estimator est, uint32_t seed, int passes,
                          double *se_out, ref_stats *st)
{
    ref_desc d = {.scene = s, .transport = tr, .bounces = 2, .seed = seed, .threads = 2, .estimator = est,
                  .vpl_paths = 256, .vpl_clamp = REF_VPL_NO_CLAMP};
    ref_renderer *r = NULL;
    lm_error err;
    lm_result res = ref_create(&d, &r, &err);
    CHECK_MSG(res == LM_OK, "%s", err.msg);
    if (res != LM_OK) return NAN;
    for (int i = 0; i < passes; ++i) ref_render_pass(r, NULL, 0.0);
    static float rgb[W * H * 3], se[W * H * 3];
    ref_get_image(r, rgb, se, NULL);
    ref_get_stats(r, st);
    ref_destroy(r);
    double sum = 0.0, se2 = 0.0;
    for (int i = 0; i < W * H * 3; ++i) {
        sum += rgb[i];
        se2 += (double)se[i] * se[i];
    }
    if (se_out) *se_out = sqrt(se2) / (W * H * 3);
    return sum / (W * H * 3);
}

static void check_estimator(const scene *s, ref_transport tr, ref_estimator est, const char *label, double ref_mean,
                            double ref_se)
{
    double m[SEEDS], mean = 0.0, var = 0.0;
    ref_stats st = {0};
    for (int k = 0; k < SEEDS; ++k) {
        m[k] = render_mean(s, tr, est, 10 + (uint32_t)k, PASSES, NULL, &st);
        mean += m[k];
    }
    mean /= SEEDS;
    for (int k = 0; k < SEEDS; ++k) var += (m[k] - mean) * (m[k] - mean);
    double se = sqrt(var / (SEEDS - 1) / SEEDS), tol = 3.0 * sqrt(se * se + ref_se * ref_se);
    printf("  %-22s mean %.6f ± %.6f  path tracer %.6f ± %.6f  (%+.2f%%, %.2f SE)  VPLs made %llu in %llu passes\n",
           label, mean, se, ref_mean, ref_se, 100.0 * (mean / ref_mean - 1.0),
           fabs(mean - ref_mean) / sqrt(se * se + ref_se * ref_se), (unsigned long long)st.vpls,
           (unsigned long long)st.vpl_passes);
    CHECK_MSG(fabs(mean - ref_mean) <= tol, "%s: mean %.6f vs the path tracer's %.6f (tolerance %.6f)", label, mean,
              ref_mean, tol);
    CHECK_MSG(se < 0.01 * ref_mean, "%s: the seeds' spread %.6f is too wide to test anything", label, se);
    CHECK(st.vpl_passes == PASSES && st.vpls > 0 && st.bad_samples == 0);
}

int main(void)
{
    char path[1024];
    snprintf(path, sizeof path, "%s/vpl_sphere.obj", LUMESH_TMP_DIR);
    test_write_icosphere(4, 2.0, path);
    test_write_file("vpl_square.obj", square_text, path, sizeof path);
    /* Flat facets (no computed shading normals): a light path that bends by a
     * shading normal is not the adjoint of an eye path that does (Veach 1997,
     * ch. 5), a bias of ~0.1% here that is not what this test is about. */
    char json[1024];
    test_write_file("vpl_sphere.json", json_text, json, sizeof json);
    scene *s = NULL;
    lm_error load_err;
    CHECK_MSG(scene_load(&(scene_load_desc){.path = json, .require_light = 1, .crease_angle_deg = 0.01f}, &s,
                         &load_err) == LM_OK, "%s", load_err.msg);
    if (!s) return test_finish("reference_vpl_test");
    static const struct {
        ref_transport tr;
        const char *name;
    } transports[] = {{REF_TRANSPORT_MODEL, "model, 2 bounces"}, {REF_TRANSPORT_FULL, "full"}};
    for (int t = 0; t < 2; ++t) {
        double ref_se = NAN;
        ref_stats st;
        double ref_mean = render_mean(s, transports[t].tr, REF_ESTIMATOR_PATHS, 1, PT_SPP, &ref_se, &st);
        printf("%s:\n", transports[t].name);
        check_estimator(s, transports[t].tr, REF_ESTIMATOR_VPL, "VPL", ref_mean, ref_se);
        check_estimator(s, transports[t].tr, REF_ESTIMATOR_BDIR, "BDIR (resampled)", ref_mean, ref_se);
    }

    /* BDIR keeps at most vpl_paths VPLs a pass of REF_BDIR_CANDIDATES times as
     * many paths' VPLs, and follows them where they count: the same VPLs made,
     * fewer kept. */
    ref_desc d = {.scene = s, .transport = REF_TRANSPORT_MODEL, .bounces = 2, .seed = 3, .estimator = REF_ESTIMATOR_BDIR,
                  .vpl_paths = 64};
    ref_renderer *r;
    lm_error err;
    if (ref_create(&d, &r, &err) == LM_OK) {
        ref_render_pass(r, NULL, 0.0);
        ref_stats st;
        ref_get_stats(r, &st);
        printf("BDIR, 64 kept of %d paths: %llu candidate VPLs\n", 64 * REF_BDIR_CANDIDATES,
               (unsigned long long)st.vpls);
        CHECK(st.vpls > 64);
        ref_destroy(r);
    }
    /* Bad arguments are refused. */
    ref_desc bad = {.scene = s, .estimator = REF_ESTIMATOR_COUNT};
    CHECK(ref_create(&bad, &r, &err) == LM_ERR_INVALID_ARG);
    bad = (ref_desc){.scene = s, .estimator = REF_ESTIMATOR_VPL, .vpl_clamp = 1.5f};
    CHECK(ref_create(&bad, &r, &err) == LM_ERR_INVALID_ARG);
    bad = (ref_desc){.scene = s, .estimator = REF_ESTIMATOR_VPL, .vpl_paths = -1};
    CHECK(ref_create(&bad, &r, &err) == LM_ERR_INVALID_ARG);
    scene_destroy(s);

    /* An area light: the light paths start from points on it, by area. */
    test_write_file("vpl_sphere_quad.json", quad_json_text, json, sizeof json);
    s = NULL;
    CHECK_MSG(scene_load(&(scene_load_desc){.path = json, .require_light = 1, .crease_angle_deg = 0.01f}, &s,
                         &load_err) == LM_OK, "%s", load_err.msg);
    if (s) {
        double ref_se = NAN;
        ref_stats st;
        double ref_mean = render_mean(s, REF_TRANSPORT_MODEL, REF_ESTIMATOR_PATHS, 1, PT_SPP, &ref_se, &st);
        printf("quad light, model, 2 bounces:\n");
        check_estimator(s, REF_TRANSPORT_MODEL, REF_ESTIMATOR_VPL, "VPL", ref_mean, ref_se);
        check_estimator(s, REF_TRANSPORT_MODEL, REF_ESTIMATOR_BDIR, "BDIR (resampled)", ref_mean, ref_se);
        scene_destroy(s);
    }
    return test_finish("reference_vpl_test");
}
