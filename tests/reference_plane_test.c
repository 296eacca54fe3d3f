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
 * A background renderer (ref_desc.background) gives the same image bit for bit.
 */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "sampling/reference.h"
#include "src/base/vecmath.h"
#include "src/scene/scene.h"
#include "tests/test_util.h"

enum { W = 24, H = 24, SPP = 256, SUB = 8 };
static const test_plane plane = {.kd = {0.6, 0.4, 0.2}, .le = {5.0, 7.0, 9.0}, .light_half = 0.5,
                                 .light_height = 1.0, .cam_height = 0.8, .fov_y = 100.0, .width = W, .height = H};

int main(void)
{
    scene *s = test_plane_load(&plane, "plane");
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
            double g = test_plane_pixel_G(&plane, px, py, SUB); /* the pixel's box filter, midpoint rule */
            gmin = fmin(gmin, g);
            gmax = fmax(gmax, g);
            double pixel_se = 0.0;
            for (int k = 0; k < 3; ++k) {
                size_t i = ((size_t)py * W + (size_t)px) * 3 + (size_t)k;
                double want = plane.kd[k] / M_PI * plane.le[k] * g, dev = fabs(rgb[i] - want);
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

    /* In the background (threads of the lowest priority, the caller waiting) the
     * same seed gives the same samples: the image bit for bit. */
    ref_renderer *bg = NULL;
    d.background = 1;
    res = ref_create(&d, &bg, &err);
    CHECK_MSG(res == LM_OK, "%s", err.msg);
    if (res == LM_OK) {
        for (int i = 0; i < SPP; ++i) CHECK(ref_render_pass(bg, NULL, 0.0) == 1);
        static float rgb_bg[W * H * 3], se_bg[W * H * 3];
        ref_get_image(bg, rgb_bg, se_bg, NULL);
        CHECK_MSG(memcmp(rgb, rgb_bg, sizeof rgb) == 0 && memcmp(se, se_bg, sizeof se) == 0,
                  "the background renderer's image differs from the foreground one's");
        ref_destroy(bg);
    }

    ref_destroy(r);
    scene_destroy(s);
    return test_finish("reference_plane_test");
}
