/* rend_exact_test — the whole pipeline (ID pass, refinement worker, material,
 * radiance and composite passes) against an image known in closed form.
 *
 * A diffuse plane (kd = 0.6, 0.4, 0.2) under a parallel, downward-facing square
 * light, the camera between them looking straight down (the camera is not
 * geometry). Every sample of the image is
 *     kd/π · Le · G(x)
 * with G from Lambert's formula (samp_polygon_G): the one diffuse bounce adds
 * nothing (bounce rays leave the plane upwards and can only reach the light,
 * whose kd is 0). The renderer's samples are the centres of an s×s grid in each
 * pixel (rend_frame.h), so the exact pixel is the mean of that formula over the
 * same points. Once the cache has converged, every pixel must be within the JND
 * (tone-mapped CIE76 ΔE 2, the refinement's own criterion) of the exact one.
 *
 * The expected values span a factor of several across the image (the footprint
 * reaches past the light's edge, which is off the camera's axis), so a wrong
 * cosine, distance, albedo, mirroring or turn cannot pass; a uniform image
 * fails by far.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "mesh/cache/cache_worker.h"
#include "src/base/tonemap.h"
#include "src/base/vecmath.h"
#include "src/gpu/gl_context.h"
#include "src/render/rend_frame.h"
#include "src/render/rend_id.h"
#include "tests/test_util.h"

enum { W = 64, H = 48, SS = 3 };
#define JND 2.0f
/* The light's centre is off the camera's axis: a mirrored or turned image cannot pass. */
static const test_plane plane = {.kd = {0.6, 0.4, 0.2}, .le = {5.0, 7.0, 9.0}, .light_x = 0.3, .light_z = -0.2,
                                 .light_half = 0.5, .light_height = 1.0, .cam_height = 0.8, .fov_y = 100.0,
                                 .width = W, .height = H};

int main(void)
{
    glctx *ctx = NULL;
    lm_error err;
    if (glctx_create(&(glctx_desc){.platform = GLCTX_EGL}, &ctx, &err) != LM_OK) return test_no_gl(err.msg);
    const GladGLContext *gl = glctx_gl(ctx);
    scene *s = test_plane_load(&plane, "exact_plane");
    rend_id *ip = NULL;
    rend_frame *f = NULL;
    cache_worker *wk = NULL;
    rend_id_result ids;
    float *img = malloc((size_t)W * H * 3 * sizeof *img);
    CHECK(img != NULL);
    if (s) CHECK(rend_id_create(gl, &(rend_id_desc){.scene = s, .width = W, .height = H}, &ip, &err) == LM_OK);
    if (ip) CHECK(rend_id_render(ip, &s->cameras[0], &ids, &err) == LM_OK);
    if (ip)
        CHECK(cache_worker_create(&(cache_worker_desc){.scene = s, .sampler = {.backend = SAMP_BACKEND_EMBREE},
                                                       .pixels = ids.pixels},
                                  &wk, &err) == LM_OK);
    const cache_snapshot *snap = test_wait_finished(wk, 60.0);
    CHECK(snap && snap->converged && !snap->failed);
    if (wk)
        CHECK(rend_frame_create(gl, &(rend_frame_desc){.scene = s, .width = W, .height = H, .supersample = SS}, &f,
                                &err) == LM_OK);
    if (f && snap && img) {
        CHECK(rend_frame_draw(f, &s->cameras[0], snap, img, &err) == LM_OK);
        tm_desc tm = {.exposure = s->exposure};
        double sum_de = 0.0, max_de = 0.0, lo = INFINITY, hi = 0.0;
        int worst = 0, above = 0;
        for (int py = 0; py < H; ++py)
            for (int px = 0; px < W; ++px) {
                double G = test_plane_pixel_G(&plane, px, py, SS);
                float exact[3], d_a[3], d_b[3], lab_a[3], lab_b[3];
                for (int k = 0; k < 3; ++k) exact[k] = (float)(plane.kd[k] / M_PI * plane.le[k] * G);
                const float *got = img + 3 * ((size_t)py * W + (size_t)px);
                tm_to_display(&tm, got, d_a);
                tm_to_display(&tm, exact, d_b);
                tm_display_to_lab(d_a, lab_a);
                tm_display_to_lab(d_b, lab_b);
                double de = tm_delta_e(lab_a, lab_b);
                sum_de += de;
                if (de > max_de) max_de = de, worst = py * W + px;
                above += de > JND;
                lo = fmin(lo, exact[1]);
                hi = fmax(hi, exact[1]);
            }
        printf("exact plane %dx%d (%dx%d samples a pixel), %llu leaves tested, %u direct triangles: mean ΔE %.4f, "
               "max %.4f at pixel (%d, %d), %d pixels above the JND; exact values span %.3f..%.3f\n",
               W, H, SS, SS, (unsigned long long)snap->tested, snap->direct.triangle_count, sum_de / (W * H), max_de,
               worst % W, worst / W, above, lo, hi);
        CHECK_MSG(max_de <= JND, "worst pixel ΔE %.3f above the JND", max_de);
        CHECK(hi > 3.0 * lo); /* the image is far from uniform */
    }
    free(img);
    rend_frame_destroy(f);
    cache_worker_destroy(wk);
    rend_id_destroy(ip);
    scene_destroy(s);
    glctx_destroy(ctx);
    return test_finish("rend_exact_test");
}
