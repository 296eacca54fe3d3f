/* rend_id_test — the ID pass against Embree primary rays through the same pixel
 * centres (src/scene/camera.h), on CornellBox-Original and CornellBox-Water:
 *   - the id image names the triangle the ray hits in ≥ 99.5% of pixels (the
 *     rest lie on triangle edges, where rasterisation rules and ray tests may
 *     pick either side) and never a triangle the ray does not see nearby;
 *   - GPU counting and read-back counting give identical pixels per triangle;
 *   - the counts sum to the covered pixels, the visible list is exactly the
 *     triangles with pixels;
 *   - a camera looking away from everything sees nothing;
 *   - camera_triangle_pixels (no GL, no occlusion) guesses at least the counts;
 *   - rend_id_count_rays (no GL: what render counts by) gives each triangle
 *     the GL count but for edge pixels: the counts differ in at most 1% of the
 *     pixels, their sums by at most 0.5%.
 * Prints the time of both counting modes at 640×480.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "sampling/rt_scene.h"
#include "src/base/vecmath.h"
#include "src/gpu/gl_context.h"
#include "src/render/rend_id.h"
#include "src/scene/camera.h"
#include "tests/test_util.h"

enum { W = 160, H = 120 };

/* The triangle the primary ray through point (px + fx, py + fy) of the image
 * hits, + 1 (fx = fy = 0.5: the pixel centre). */
static uint32_t embree_id_at(const rt_scene *rt, const scene_camera *cam, int w, int h, double px, double py)
{
    lm_dvec3 pos = dv3_load(cam->position);
    lm_dvec3 fwd = dv3_normalize(dv3_sub(dv3_load(cam->target), pos));
    lm_dvec3 right = dv3_normalize(dv3_cross(fwd, dv3_load(cam->up)));
    lm_dvec3 up = dv3_cross(right, fwd);
    double ty = tan(0.5 * cam->fov_y_deg * M_PI / 180.0), tx = ty * w / h;
    double sx = 2.0 * px / w - 1.0, sy = 1.0 - 2.0 * py / h;
    lm_dvec3 d = dv3_normalize(dv3_add(fwd, dv3_add(dv3_scale(right, sx * tx), dv3_scale(up, sy * ty))));
    float o[3] = {cam->position[0], cam->position[1], cam->position[2]}, df[3] = {(float)d.x, (float)d.y, (float)d.z};
    rt_hit hit;
    return rt_intersect(rt, o, df, 0.0f, INFINITY, &hit) ? hit.tri + 1 : 0;
}

static uint32_t embree_id(const rt_scene *rt, const scene_camera *cam, int w, int h, int px, int py)
{
    return embree_id_at(rt, cam, w, h, px + 0.5, py + 0.5);
}

static void check_scene(const GladGLContext *gl, const char *name)
{
    char path[1024];
    snprintf(path, sizeof path, "%s/cornell-box/%s", LUMESH_SCENES, name);
    scene_load_desc ld = {.path = path};
    scene *s = NULL;
    lm_error err;
    lm_result r = scene_load(&ld, &s, &err);
    CHECK_MSG(r == LM_OK, "%s", err.msg);
    if (!s) return;
    rt_scene *rt = NULL;
    CHECK(rt_scene_create(&(rt_scene_desc){.scene = s}, &rt, &err) == LM_OK);
    rend_id *gpu = NULL, *cpu = NULL;
    CHECK(rend_id_create(gl, &(rend_id_desc){.scene = s, .width = W, .height = H, .count = REND_ID_COUNT_GPU}, &gpu,
                         &err) == LM_OK);
    CHECK(rend_id_create(gl, &(rend_id_desc){.scene = s, .width = W, .height = H}, &cpu, &err) == LM_OK);
    if (!rt || !gpu || !cpu) return;
    const scene_camera *cam = &s->cameras[0];
    rend_id_result rg, rc;
    CHECK(rend_id_render(gpu, cam, &rg, &err) == LM_OK);
    uint32_t *gpu_pixels = malloc(s->tri_count * sizeof *gpu_pixels);
    memcpy(gpu_pixels, rg.pixels, s->tri_count * sizeof *gpu_pixels);
    CHECK(rend_id_render(cpu, cam, &rc, &err) == LM_OK);
    CHECK_MSG(memcmp(gpu_pixels, rc.pixels, s->tri_count * sizeof *gpu_pixels) == 0,
              "%s: GPU and read-back counts differ", name);
    CHECK(rg.visible_count == rc.visible_count && rg.covered == rc.covered);

    static uint32_t ids[W * H];
    CHECK(rend_id_read_image(gpu, ids, &err) == LM_OK);
    int same = 0, far_off = 0;
    uint64_t sum = 0;
    for (uint32_t t = 0; t < s->tri_count; ++t) sum += rc.pixels[t];
    uint32_t nvis = 0;
    for (uint32_t t = 0; t < s->tri_count; ++t) nvis += rc.pixels[t] > 0;
    for (int py = 0; py < H; ++py)
        for (int px = 0; px < W; ++px) {
            uint32_t want = embree_id(rt, cam, W, H, px, py), got = ids[py * W + px];
            if (got == want) {
                same++;
                continue;
            }
            /* A mismatch must be an edge: some ray within a pixel of this one's
             * centre sees the GL triangle (9×9 rays over the 3×3 pixels; Water's
             * triangles can be smaller than a pixel). */
            int near = 0;
            for (int j = 0; j < 9 && !near; ++j)
                for (int i = 0; i < 9 && !near; ++i)
                    near = embree_id_at(rt, cam, W, H, px - 0.5 + 2.0 * (i + 0.5) / 9.0,
                                        py - 0.5 + 2.0 * (j + 0.5) / 9.0) == got;
            far_off += !near;
        }
    double agree = (double)same / (W * H);
    printf("%s: %u triangles, %u visible, %llu of %d pixels covered; GL ids = Embree ids in %.3f%% of pixels, %d "
           "mismatches not at an edge\n",
           name, s->tri_count, rc.visible_count, (unsigned long long)rc.covered, W * H, 100.0 * agree, far_off);
    CHECK_MSG(agree >= 0.995, "%s: only %.3f%% of pixels agree", name, 100.0 * agree);
    CHECK(far_off == 0);
    CHECK(sum == rc.covered && nvis == rc.visible_count);
    for (uint32_t i = 0; i + 1 < rc.visible_count; ++i) CHECK(rc.visible[i] < rc.visible[i + 1]);

    /* The guess without GL (camera_triangle_pixels: projected areas, no
     * occlusion) is at least each triangle's count, up to the rasterizer's
     * rounding along its edges, and the triangles nothing hides get their count. */
    uint32_t *guess = malloc(s->tri_count * sizeof *guess);
    CHECK(guess != NULL);
    uint64_t guessed = 0;
    int below = 0, matched = 0, whole = 0;
    for (uint32_t t = 0; guess && t < s->tri_count; ++t) {
        if (t == 0) camera_triangle_pixels(s, cam, W, H, guess);
        guessed += guess[t];
        double slack = 2.0 * sqrt((double)guess[t]) + 4.0;
        below += rc.pixels[t] > guess[t] + slack;
        if (rc.pixels[t] > 100 && fabs((double)rc.pixels[t] - guess[t]) <= slack) matched++;
        whole += rc.pixels[t] > 100;
    }
    printf("  guessed pixels: %llu over all triangles (%llu covered); %d triangles above their guess, %d of %d "
           "large ones match it\n",
           (unsigned long long)guessed, (unsigned long long)rc.covered, below, matched, whole);
    CHECK(below == 0 && guessed >= rc.covered);
    CHECK(matched > 0);

    /* The counts by rays, against the read-back counts: each pixel whose GL id
     * and ray id differ moves one count from one triangle to another (or to or
     * from no triangle), so |difference| summed over triangles is at most twice
     * the mismatched pixels (below 0.5% of them, above). */
    uint32_t *by_rays = malloc(s->tri_count * sizeof *by_rays);
    CHECK(by_rays != NULL);
    if (by_rays) {
        CHECK(rend_id_count_rays(s, NULL, cam, W, H, by_rays, &err) == LM_OK);
        uint64_t moved = 0, rays_covered = 0;
        for (uint32_t t = 0; t < s->tri_count; ++t) {
            moved += by_rays[t] > rc.pixels[t] ? by_rays[t] - rc.pixels[t] : rc.pixels[t] - by_rays[t];
            rays_covered += by_rays[t];
        }
        const double covered_diff = fabs((double)rays_covered - (double)rc.covered);
        printf("  counted by rays: %llu pixels covered (GL %llu), %llu counts differ from GL's (%.3f%% of the "
               "pixels)\n",
               (unsigned long long)rays_covered, (unsigned long long)rc.covered, (unsigned long long)moved,
               100.0 * (double)moved / (W * H));
        CHECK_MSG((double)moved <= 0.01 * W * H, "%s: the ray counts differ in %llu pixels", name,
                  (unsigned long long)moved);
        CHECK_MSG(covered_diff <= 0.005 * W * H, "%s: %llu covered by rays, %llu by GL", name,
                  (unsigned long long)rays_covered, (unsigned long long)rc.covered);
        CHECK(rend_id_count_rays(NULL, NULL, cam, W, H, by_rays, &err) == LM_ERR_INVALID_ARG);
        /* In an Embree scene given (render's, which its worker then samples): the same counts. */
        uint32_t *again = malloc(s->tri_count * sizeof *again);
        CHECK(again && rend_id_count_rays(s, rt, cam, W, H, again, &err) == LM_OK);
        if (again) CHECK(memcmp(again, by_rays, s->tri_count * sizeof *again) == 0);
        free(again);
        free(by_rays);
    }

    /* Looking away from the box into the void. */
    scene_camera away = *cam;
    for (int k = 0; k < 3; ++k) away.target[k] = 2.0f * cam->position[k] - cam->target[k];
    away.position[2] += 10.0f;
    away.target[2] += 10.0f;
    rend_id_result ra;
    CHECK(rend_id_render(gpu, &away, &ra, &err) == LM_OK);
    CHECK_MSG(ra.covered == 0 && ra.visible_count == 0, "looking away: %llu pixels covered",
              (unsigned long long)ra.covered);
    guessed = 0;
    if (guess) camera_triangle_pixels(s, &away, W, H, guess);
    for (uint32_t t = 0; guess && t < s->tri_count; ++t) guessed += guess[t];
    CHECK_MSG(guessed == 0, "looking away: %llu pixels guessed", (unsigned long long)guessed);
    free(guess);

    /* Speed of both counting modes at 640×480 (printed, not asserted). */
    rend_id *big[2] = {NULL, NULL};
    double best[2] = {INFINITY, INFINITY};
    for (int m = 0; m < 2; ++m) {
        rend_id_desc d = {.scene = s, .width = 640, .height = 480,
                          .count = m == 0 ? REND_ID_COUNT_GPU : REND_ID_COUNT_READBACK};
        if (rend_id_create(gl, &d, &big[m], &err) != LM_OK) continue;
        for (int rep = 0; rep < 6; ++rep) {
            rend_id_result rr;
            rend_id_render(big[m], cam, &rr, &err);
            if (rep > 0 && rr.seconds < best[m]) best[m] = rr.seconds;
        }
        rend_id_destroy(big[m]);
    }
    printf("  640x480 ID pass: %.2f ms with GPU counting, %.2f ms with read-back counting (best of 5)\n",
           best[0] * 1e3, best[1] * 1e3);
    free(gpu_pixels);
    rend_id_destroy(gpu);
    rend_id_destroy(cpu);
    rt_scene_destroy(rt);
    scene_destroy(s);
}

int main(void)
{
    glctx *ctx = NULL;
    lm_error err;
    if (glctx_create(&(glctx_desc){.platform = GLCTX_EGL}, &ctx, &err) != LM_OK) return test_no_gl(err.msg);
    const GladGLContext *gl = glctx_gl(ctx);
    check_scene(gl, "CornellBox-Original.obj");
    check_scene(gl, "CornellBox-Water.obj");
    rend_id *bad = NULL;
    CHECK(rend_id_create(gl, &(rend_id_desc){.scene = NULL, .width = 4, .height = 4}, &bad, &err) ==
              LM_ERR_INVALID_ARG &&
          bad == NULL);
    glctx_destroy(ctx);
    return test_finish("rend_id_test");
}
