/* reference_plane_test — the reference renderer against Lambert's closed form.
 *
 * A diffuse plane (kd = 0.6, 0.4, 0.2) under a parallel, downward-facing square
 * area light of radiance Le, the camera between them looking straight down. With
 * the model transport every pixel is
 *     kd/π · Le · G(x)
 * averaged over the pixel's footprint, G from samp_polygon_G (analytic.c). The one
 * diffuse bounce adds nothing: bounce rays leave the plane upwards and can only
 * reach the light, whose kd is 0. The camera is not geometry, so nothing occludes.
 *
 * A pixel passes when it is within 3 of its reported standard errors (plus a
 * float tolerance); the test asks that almost every pixel passes, that none is
 * beyond 5, and that the image mean matches within 3 standard errors of the mean.
 * The expected values span a factor of several across the image (the footprint
 * reaches past the light's edge), so a wrong cosine or distance term cannot pass.
 * The image corners see the light more than 60° off its normal: that is where a
 * shadow ray shortened by a fixed length hit the light itself (2.4% dark at
 * 16384 spp, 5 standard errors; see rt_segment_occluded).
 */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "analytic.h"
#include "reference.h"
#include "scene.h"
#include "test_util.h"
#include "vecmath.h"

enum { W = 24, H = 24, SPP = 256, SUB = 8 };
static const double kd[3] = {0.6, 0.4, 0.2};
static const double le[3] = {5.0, 7.0, 9.0};
#define LIGHT_HEIGHT 1.0
#define LIGHT_HALF 0.5
#define CAM_HEIGHT 0.8
#define FOV_Y 100.0

/* The point of the plane y = 0 seen through screen position (sx, sy) in [-1, 1]²,
 * with the pinhole of reference.c: dir = fwd + sx·tx·right + sy·ty·up, where the
 * camera at (0, CAM_HEIGHT, 0) looks down -y with up (0, 0, -1): right = +x and
 * the screen's up = -z. */
static void footprint_point(double sx, double sy, double x[3])
{
    double ty = tan(0.5 * FOV_Y * M_PI / 180.0), tx = ty * (double)W / (double)H;
    x[0] = CAM_HEIGHT * sx * tx;
    x[1] = 0.0;
    x[2] = -CAM_HEIGHT * sy * ty;
}

/* Mean of G over the footprint of pixel (px, py): SUB×SUB midpoint rule (the
 * screen-to-plane map is linear, so jittered pixel samples are uniform on it). */
static double pixel_G(int px, int py)
{
    static const double light[4][3] = {{-LIGHT_HALF, LIGHT_HEIGHT, -LIGHT_HALF},
                                       {LIGHT_HALF, LIGHT_HEIGHT, -LIGHT_HALF},
                                       {LIGHT_HALF, LIGHT_HEIGHT, LIGHT_HALF},
                                       {-LIGHT_HALF, LIGHT_HEIGHT, LIGHT_HALF}};
    const double up[3] = {0.0, 1.0, 0.0};
    double sum = 0.0;
    for (int j = 0; j < SUB; ++j)
        for (int i = 0; i < SUB; ++i) {
            double sx = 2.0 * (px + (i + 0.5) / SUB) / W - 1.0;
            double sy = 1.0 - 2.0 * (py + (j + 0.5) / SUB) / H;
            double x[3];
            footprint_point(sx, sy, x);
            sum += samp_polygon_G(light, 4, x, up);
        }
    return sum / (SUB * SUB);
}

static scene *load_plane_scene(void)
{
    char obj[1024], json[1024], text[2048];
    test_write_file("plane.obj",
                    "v -4 0 -4\nv 4 0 -4\nv 4 0 4\nv -4 0 4\n"
                    "f 1 4 3\nf 1 3 2\n", /* counter-clockwise seen from +y */
                    obj, sizeof obj);
    /* edge1 × edge2 = (1,0,0) × (0,0,1) = (0,-1,0): the light faces the plane. */
    snprintf(text, sizeof text,
             "{\"meshes\": [{\"file\": \"plane.obj\", \"material\": \"paint\"}],"
             " \"materials\": {\"paint\": {\"kd\": [%g, %g, %g]}},"
             " \"lights\": [{\"type\": \"quad\", \"corner\": [%g, %g, %g], \"edge1\": [%g, 0, 0],"
             " \"edge2\": [0, 0, %g], \"radiance\": [%g, %g, %g]}],"
             " \"cameras\": [{\"position\": [0, %g, 0], \"target\": [0, 0, 0], \"up\": [0, 0, -1],"
             " \"fov_y\": %g, \"width\": %d, \"height\": %d}]}",
             kd[0], kd[1], kd[2], -LIGHT_HALF, LIGHT_HEIGHT, -LIGHT_HALF, 2 * LIGHT_HALF, 2 * LIGHT_HALF,
             le[0], le[1], le[2], CAM_HEIGHT, FOV_Y, W, H);
    test_write_file("plane.json", text, json, sizeof json);
    scene_load_desc d = {.path = json, .require_light = 1};
    scene *s = NULL;
    lm_error err;
    lm_result r = scene_load(&d, &s, &err);
    CHECK_MSG(r == LM_OK, "%s", err.msg);
    return s;
}

int main(void)
{
    scene *s = load_plane_scene();
    if (!s) return test_finish("reference_plane_test");
    CHECK(s->tri_count == 4 && s->area_light_count == 1);

    ref_desc d = {.scene = s, .seed = 3, .threads = 2};
    ref_renderer *r;
    lm_error err;
    lm_result res = ref_create(&d, &r, &err);
    CHECK_MSG(res == LM_OK, "%s", err.msg);
    if (res != LM_OK) {
        scene_destroy(s);
        return test_finish("reference_plane_test");
    }
    for (int i = 0; i < SPP; ++i) ref_render_pass(r, NULL, 0.0);
    static float rgb[W * H * 3], se[W * H * 3];
    ref_get_image(r, rgb, se, NULL);
    ref_stats st;
    ref_get_stats(r, &st);
    CHECK(st.bad_samples == 0 && st.min_samples == SPP);

    int outside3 = 0, outside5 = 0;
    double gmin = INFINITY, gmax = 0.0, sum_dev = 0.0, se2 = 0.0, worst = 0.0;
    for (int py = 0; py < H; ++py)
        for (int px = 0; px < W; ++px) {
            double g = pixel_G(px, py);
            gmin = fmin(gmin, g);
            gmax = fmax(gmax, g);
            double pixel_se = 0.0;
            for (int k = 0; k < 3; ++k) {
                size_t i = ((size_t)py * W + (size_t)px) * 3 + (size_t)k;
                double want = kd[k] / M_PI * le[k] * g, dev = fabs(rgb[i] - want);
                double tol = 1e-5 * want; /* float accumulation */
                outside3 += dev > 3.0 * se[i] + tol;
                outside5 += dev > 5.0 * se[i] + tol;
                worst = fmax(worst, (dev - tol) / fmax(se[i], 1e-30));
                sum_dev += rgb[i] - want;
                pixel_se += se[i];
            }
            /* The channels of a pixel come from the same samples (kd·Le scales one
             * estimate of G), so their errors add linearly, not in quadrature. */
            se2 += pixel_se * pixel_se;
        }
    double mean_dev = sum_dev / (W * H * 3), se_mean = sqrt(se2) / (W * H * 3);
    printf("plane under a square light, %dx%d, %d spp: G from %.4f to %.4f\n", W, H, SPP, gmin, gmax);
    printf("  values outside 3 SE: %d/%d, outside 5 SE: %d, worst z %.2f, mean deviation %.2e (SE %.2e)\n",
           outside3, W * H * 3, outside5, worst, mean_dev, se_mean);
    CHECK_MSG(gmax > 3.0 * gmin, "the footprint should see G vary (%.4f..%.4f)", gmin, gmax);
    CHECK_MSG(outside3 <= (W * H * 3) / 100, "%d values outside 3 SE", outside3);
    CHECK_MSG(outside5 == 0, "%d values outside 5 SE", outside5);
    CHECK_MSG(fabs(mean_dev) <= 3.0 * se_mean, "mean deviation %.3e vs SE %.3e", mean_dev, se_mean);

    ref_destroy(r);
    scene_destroy(s);
    return test_finish("reference_plane_test");
}
