/* rend_highlight_test — a highlight whose rim is narrower than a pixel, through
 * the whole pipeline (ID pass, refinement worker, material, radiance and
 * composite passes), against the image known in closed form.
 *
 * A plane with a sharp modified Phong lobe (n = 2000, ks 0.6) and a little
 * diffuse albedo under the square light of rend_exact_test, the camera between
 * them looking down: the plane mirrors the light as a bright square whose edge
 * falls off within about a pixel. Every sample of the image is
 *     kd/π · Le · G(x) + ks · Le · S(x, ωo)
 * (samp_polygon_G, samp_polygon_phong: the specular mesh stores S exactly at its
 * vertices, the light being wholly visible), averaged over each pixel's s×s
 * sample centres as the renderer's box filter does.
 *
 * The renderer evaluates the lights' part of the specular term at each sample
 * (rend_value.frag, HIGHLIGHT: eq. 5 at the sample's point and view, the visible
 * fraction interpolated; docs/renderer.md, "Highlights per pixel"). Before it, a
 * leaf of one pixel interpolated linearly between a vertex on the plateau and
 * one off it and spread the rim over its pixel (docs/cache.md, "Leaves smaller
 * than a pixel"): 76 pixels above the JND, relMSE 1.0e-3 with leaves stopped at
 * a pixel, 9 and 6.9e-5 with leaves down to a sample. Now:
 * - the specular term alone, drawn from the coarse cache (the worker stopped
 *   after its first leaf test: the plane's two roots), is within the JND of
 *   ks·Le·S at every pixel, and its relMSE below 1e-5 (interpolated: 169 pixels
 *   above, relMSE 0.045): the rim is the renderer's, not the mesh's;
 * - refined to convergence, with leaves down to a sample (cache_desc.sample_pixels
 *   = 1/s², what a render session asks) or stopped at a pixel (the viewer's), the
 *   whole image is within the JND at all but 0.1% of the pixels, with relMSE
 *   below 1e-4 (a tenth of the interpolated rim's).
 * The specular mesh's tests judge that picture (cache_specular_drawn): its yield
 * (what its tests removed per unit of priority) is nought beside the direct
 * mesh's, and its leaves are split only by the size criterion (shadows).
 *
 * The plane is cut to about the view (half side 1.3 against a footprint of
 * 1.27 × 0.95): the cache takes a leaf's pixels as its root's count shared by
 * area, and a root mostly outside the view makes its leaves look smaller than
 * they are (docs/cache.md).
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
static const test_plane plane = {.kd = {0.5, 0.4, 0.3}, .ks = {0.5, 0.5, 0.5}, .n = 2000.0, .le = {1.2, 1.4, 1.6},
                                 .light_x = 0.3, .light_z = -0.2, .light_half = 0.5, .light_height = 1.0,
                                 .cam_height = 0.8, .fov_y = 100.0, .width = W, .height = H, .plane_half = 1.3};

typedef struct highlight_error {
    test_pixel_error px;
    test_pixel_error deferred; /* the draw before, its highlights deferred (defer set) */
    int redrawn_specular;      /* the draw after the deferred one redrew the specular term */
    unsigned long long tested, specular_leaves;
    double yield_direct, yield_specular; /* cache_mesh_stats.yield when it converged */
} highlight_error;

/* img against the closed form (only the specular term: specular_only). */
static void measure(const scene *s, const float *img, int specular_only, test_pixel_error *px)
{
    tm_desc tm = {.exposure = s->exposure};
    for (int py = 0; py < H; ++py)
        for (int px_ = 0; px_ < W; ++px_) {
            double G = test_plane_pixel_G(&plane, px_, py, SS), S = test_plane_pixel_S(&plane, px_, py, SS);
            float exact[3];
            for (int k = 0; k < 3; ++k)
                exact[k] = (float)((specular_only ? 0.0 : plane.kd[k] / M_PI * plane.le[k] * G) +
                                   plane.ks[k] * plane.le[k] * S);
            test_pixel_error_add(px, &tm, img + 3 * ((size_t)py * W + (size_t)px_), exact, py * W + px_, W * H, JND);
        }
}

/* Refines the plane with leaves down to sample_pixels, to convergence or (max_tested
 * > 0) until that many leaves are tested, draws it (only the specular term:
 * specular_only) and measures it against the closed form; with defer, first
 * drawn with its highlights deferred (rend_frame_defer_highlights) and measured
 * into e->deferred, then drawn again with the same snapshot and camera. 0 on a
 * failed step. */
static int refine_and_measure(rend_frame *f, const scene *s, const uint32_t *pixels, float sample_pixels,
                              uint64_t max_tested, int specular_only, int defer, float *img, highlight_error *e)
{
    lm_error err;
    cache_worker *wk = NULL;
    *e = (highlight_error){0};
    if (cache_worker_create(&(cache_worker_desc){.scene = s, .sampler = {.backend = SAMP_BACKEND_EMBREE},
                                                 .pixels = pixels, .max_tested = max_tested,
                                                 .cache = {.sample_pixels = sample_pixels}},
                            &wk, &err) != LM_OK) {
        CHECK_MSG(0, "worker: %s", err.msg);
        return 0;
    }
    const cache_snapshot *snap = test_wait_finished(wk, 120.0);
    int ok = snap && (snap->converged || max_tested) && !snap->failed;
    CHECK_MSG(ok, "sample_pixels %g: the worker did not converge", (double)sample_pixels);
    rend_frame_set_components(f, specular_only ? REND_FRAME_COMPONENT_DIRECT_SPECULAR : REND_FRAME_COMPONENTS_ALL);
    if (ok && defer) {
        rend_frame_defer_highlights(f);
        ok = rend_frame_draw(f, &s->cameras[0], snap, img, &err) == LM_OK;
        if (ok) measure(s, img, specular_only, &e->deferred);
    }
    if (ok) ok = rend_frame_draw(f, &s->cameras[0], snap, img, &err) == LM_OK;
    if (ok && defer) {
        rend_frame_times tt;
        rend_frame_get_times(f, &tt);
        e->redrawn_specular = tt.radiance_redrawn > 0.0;
    }
    rend_frame_set_components(f, REND_FRAME_COMPONENTS_ALL);
    if (ok) {
        e->tested = snap->tested;
        e->specular_leaves = snap->specular.triangle_count;
        e->yield_direct = snap->stats.direct.yield;
        e->yield_specular = snap->stats.specular.yield;
    }
    cache_worker_destroy(wk);
    if (!ok) return 0;
    measure(s, img, specular_only, &e->px);
    return 1;
}

int main(void)
{
    test_plane_gl t;
    int open = test_plane_gl_open(&plane, "highlight_plane", SS, &t);
    if (open == 77) return 77;
    float *img = malloc((size_t)W * H * 3 * sizeof *img);
    CHECK(img != NULL);
    highlight_error fine = {0}, pixel = {0}, coarse = {0};
    int ok = open == 0 && img && refine_and_measure(t.f, t.s, t.pixels, 1.0f, 1, 1, 1, img, &coarse) &&
             refine_and_measure(t.f, t.s, t.pixels, 1.0f / (SS * SS), 0, 0, 0, img, &fine) &&
             refine_and_measure(t.f, t.s, t.pixels, 1.0f, 0, 0, 0, img, &pixel);
    CHECK(ok);
    if (ok) {
        printf("the specular term of the coarse cache: %llu leaves tested, %llu specular leaves; mean ΔE %.4f, max "
               "%.3f at (%d, %d), %d pixels above the JND, relMSE %.3g\n",
               coarse.tested, coarse.specular_leaves, coarse.px.mean_de, coarse.px.max_de, coarse.px.worst % W,
               coarse.px.worst / W, coarse.px.above, coarse.px.relmse);
        /* Measured: max ΔE 0.002, relMSE 1.4e-12 from the plane's two roots (interpolated
         * over them, the highlight was a blur: the check fails). */
        CHECK_MSG(coarse.px.above == 0 && coarse.px.relmse <= 1e-5,
                  "the coarse cache's highlight: %d pixels above the JND, relMSE %.3g", coarse.px.above,
                  coarse.px.relmse);
        /* The draw before it, its highlights deferred (what a first image
         * shows): the specular mesh's interpolation over the two roots, a blur
         * (measured: 169 pixels above the JND, relMSE 0.045); the draw above
         * redrew the term per pixel with the same snapshot and camera. */
        printf("the same, its highlights deferred: mean ΔE %.4f, %d pixels above the JND, relMSE %.3g; the next draw "
               "redrew the term: %s\n",
               coarse.deferred.mean_de, coarse.deferred.above, coarse.deferred.relmse,
               coarse.redrawn_specular ? "yes" : "no");
        CHECK_MSG(coarse.deferred.above >= 50 && coarse.deferred.relmse >= 1e-2,
                  "deferred highlights: %d pixels above the JND, relMSE %.3g (drawn per pixel?)",
                  coarse.deferred.above, coarse.deferred.relmse);
        CHECK_MSG(coarse.redrawn_specular, "the draw after a deferred one did not redraw the specular term");
    }
    const highlight_error *r[2] = {&fine, &pixel};
    const char *what[2] = {"leaves down to a sample (1/9 pixel)", "leaves stopped at a pixel"};
    for (int i = 0; ok && i < 2; ++i)
        printf("%s: %llu leaves tested, %llu specular leaves; mean ΔE %.4f, max %.3f at (%d, %d), %d pixels above "
               "the JND, relMSE %.3g; yield direct %.3g, specular %.3g\n",
               what[i], r[i]->tested, r[i]->specular_leaves, r[i]->px.mean_de, r[i]->px.max_de, r[i]->px.worst % W,
               r[i]->px.worst / W, r[i]->px.above, r[i]->px.relmse, r[i]->yield_direct, r[i]->yield_specular);
    /* Measured: no pixel above the JND (worst ΔE 0.28) and relMSE 9.2e-6 either
     * way, against 9 and 76 pixels, 6.9e-5 and 1.0e-3 interpolated. */
    for (int i = 0; ok && i < 2; ++i) {
        CHECK_MSG(r[i]->px.above <= W * H / 1000, "%s: %d pixels above the JND", what[i], r[i]->px.above);
        CHECK_MSG(r[i]->px.max_de <= 2.0 * JND, "%s: worst pixel ΔE %.3f", what[i], r[i]->px.max_de);
        CHECK_MSG(r[i]->px.relmse <= 1e-4, "%s: relMSE %.3g", what[i], r[i]->px.relmse);
    }
    if (ok) {
        /* The yields the scheduler weighs the meshes by (cache_sched_yield): the
         * specular mesh's tests judge the picture the renderer draws, whose rim
         * is exact, so they remove nothing (before, judging the interpolation,
         * 0.64 against the direct mesh's 0.20), and the scheduler learns to
         * spend its rays on the direct mesh. Measured 6e-18 against 0.14. */
        for (int i = 0; i < 2; ++i)
            CHECK_MSG(r[i]->yield_specular <= 1e-3 * r[i]->yield_direct && r[i]->yield_direct > 0.0,
                      "%s: yield specular %.3g, direct %.3g", what[i], r[i]->yield_specular, r[i]->yield_direct);
    }
    free(img);
    test_plane_gl_close(&t);
    return test_finish("rend_highlight_test");
}
