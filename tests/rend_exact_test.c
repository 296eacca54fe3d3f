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
 * Then a worker that refines on past the JND (jnd_floor) must keep lowering the
 * error at least at a Monte Carlo rate in its samples.
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

/* The image of snap against the closed form: mean and largest ΔE, pixels above
 * the JND, relMSE as `lumesh compare` computes it (linear, (a−b)²/(b²+0.01) over
 * pixels and channels), and the range of the exact green values. */
typedef struct exact_error {
    test_pixel_error px;
    double lo, hi;
} exact_error;

static int measure(rend_frame *f, const scene *s, const cache_snapshot *snap, float *img, exact_error *e)
{
    lm_error err;
    if (rend_frame_draw(f, &s->cameras[0], snap, img, &err) != LM_OK) return 0;
    tm_desc tm = {.exposure = s->exposure};
    *e = (exact_error){.lo = INFINITY};
    for (int py = 0; py < H; ++py)
        for (int px = 0; px < W; ++px) {
            double G = test_plane_pixel_G(&plane, px, py, SS);
            float exact[3];
            for (int k = 0; k < 3; ++k) exact[k] = (float)(plane.kd[k] / M_PI * plane.le[k] * G);
            test_pixel_error_add(&e->px, &tm, img + 3 * ((size_t)py * W + (size_t)px), exact, py * W + px, W * H, JND);
            e->lo = fmin(e->lo, exact[1]);
            e->hi = fmax(e->hi, exact[1]);
        }
    return 1;
}

/* Light samples and gathers a snapshot's cache has taken. */
static double samples_taken(const cache_snapshot *snap)
{
    double n = (double)(snap->stats.direct.samples + snap->stats.indirect.samples);
    for (uint32_t l = 0; l < snap->stats.light_count; ++l) n += (double)snap->stats.lights[l].samples;
    return n;
}

int main(void)
{
    lm_error err;
    test_plane_gl t;
    int open = test_plane_gl_open(&plane, "exact_plane", SS, &t);
    if (open == 77) return 77;
    scene *s = t.s;
    rend_frame *f = t.f;
    cache_worker *wk = NULL;
    float *img = malloc((size_t)W * H * 3 * sizeof *img);
    CHECK(img != NULL);
    if (open == 0)
        CHECK(cache_worker_create(&(cache_worker_desc){.scene = s, .sampler = {.backend = SAMP_BACKEND_EMBREE},
                                                       .pixels = t.pixels},
                                  &wk, &err) == LM_OK);
    const cache_snapshot *snap = test_wait_finished(wk, 60.0);
    CHECK(snap && snap->converged && !snap->failed);
    exact_error e1 = {0};
    int measured = f && snap && img && measure(f, s, snap, img, &e1);
    CHECK(measured);
    if (measured) {
        printf("exact plane %dx%d (%dx%d samples a pixel), %llu leaves tested, %u direct triangles: mean ΔE %.4f, "
               "max %.4f at pixel (%d, %d), %d pixels above the JND, relMSE %.3g; exact values span %.3f..%.3f\n",
               W, H, SS, SS, (unsigned long long)snap->tested, snap->direct.triangle_count, e1.px.mean_de, e1.px.max_de,
               e1.px.worst % W, e1.px.worst / W, e1.px.above, e1.px.relmse, e1.lo, e1.hi);
        CHECK_MSG(e1.px.max_de <= JND, "worst pixel ΔE %.3f above the JND", e1.px.max_de);
        CHECK(e1.hi > 3.0 * e1.lo); /* the image is far from uniform */
    }
    /* Never plateau (cache_worker_desc.jnd_floor): converged at the JND, the
     * worker refines on to JND/8; the error must fall at least as fast in the
     * samples taken as a Monte Carlo estimate's (relMSE ∝ 1/N: after 4N
     * samples at most a third of that after N), and it must fall. */
    /* The jitter (rend_frame_set_jitter) moves the samples by whole output pixels
     * here, right and down: pixel (x, y) must show what the plain image has at
     * (x + 1, y) or (x, y + 1), value for value up to the rasterizer's rounding of
     * the moved triangles. */
    float *moved = malloc((size_t)W * H * 3 * sizeof *moved);
    CHECK(moved != NULL);
    for (int dir = 0; measured && moved && dir < 2; ++dir) {
        CHECK(rend_frame_draw(f, &s->cameras[0], snap, img, &err) == LM_OK);
        rend_frame_set_jitter(f, dir == 0 ? 1.0f : 0.0f, dir == 1 ? 1.0f : 0.0f);
        CHECK(rend_frame_draw(f, &s->cameras[0], snap, moved, &err) == LM_OK);
        rend_frame_set_jitter(f, 0.0f, 0.0f);
        double worst = 0.0;
        for (int py = 0; py + (dir == 1) < H; ++py)
            for (int px = 0; px + (dir == 0) < W; ++px)
                for (int k = 0; k < 3; ++k) {
                    float a = moved[3 * ((size_t)py * W + (size_t)px) + (size_t)k];
                    float b = img[3 * ((size_t)(py + (dir == 1)) * W + (size_t)(px + (dir == 0))) + (size_t)k];
                    worst = fmax(worst, fabs(a - b) / fmax(fabs(b), 1e-3));
                }
        printf("jitter by one pixel %s: the plain image shifted within %.2g (relative)\n", dir ? "down" : "right",
               worst);
        CHECK_MSG(worst < 1e-3, "jitter %s: %.3g from the shifted image", dir ? "down" : "right", worst);
    }
    /* Accumulated: k×k draws at rend_frame_jitter_pattern's offsets make a
     * (k·SS)² grid per pixel (rend_session_draw_accumulated's pattern): within the
     * JND of the exact mean over that grid. */
    enum { K = 2 };
    for (int i = 0; measured && moved && i < K * K; ++i) {
        float jx, jy;
        rend_frame_jitter_pattern(i, K, SS, &jx, &jy);
        rend_frame_set_jitter(f, jx, jy);
        CHECK(rend_frame_draw(f, &s->cameras[0], snap, i ? moved : img, &err) == LM_OK);
        for (size_t j = 0; i && j < (size_t)W * H * 3; ++j) img[j] += moved[j];
    }
    rend_frame_set_jitter(f, 0.0f, 0.0f);
    if (measured && moved) {
        tm_desc tm = {.exposure = s->exposure};
        double worst = 0.0;
        for (int py = 0; py < H; ++py)
            for (int px = 0; px < W; ++px) {
                double G = test_plane_pixel_G(&plane, px, py, K * SS);
                float exact[3], got[3], d_a[3], d_b[3], lab_a[3], lab_b[3];
                for (int k = 0; k < 3; ++k) {
                    exact[k] = (float)(plane.kd[k] / M_PI * plane.le[k] * G);
                    got[k] = img[3 * ((size_t)py * W + (size_t)px) + (size_t)k] / (K * K);
                }
                tm_to_display(&tm, got, d_a);
                tm_to_display(&tm, exact, d_b);
                tm_display_to_lab(d_a, lab_a);
                tm_display_to_lab(d_b, lab_b);
                worst = fmax(worst, tm_delta_e(lab_a, lab_b));
            }
        printf("%dx%d jittered draws against the exact %dx%d grid: worst ΔE %.3f\n", K, K, K * SS, K * SS, worst);
        CHECK_MSG(worst <= JND, "accumulated: worst ΔE %.3f", worst);
    }
    free(moved);
    double n1 = snap ? samples_taken(snap) : 0;
    cache_worker_destroy(wk);
    wk = NULL;
    if (open == 0)
        CHECK(cache_worker_create(&(cache_worker_desc){.scene = s, .sampler = {.backend = SAMP_BACKEND_EMBREE},
                                                       .pixels = t.pixels, .jnd_floor = JND / 8},
                                  &wk, &err) == LM_OK);
    snap = test_wait_finished(wk, 120.0);
    CHECK(snap && snap->converged && !snap->failed && snap->jnd == JND / 8);
    exact_error e2 = {0};
    measured = measured && snap && measure(f, s, snap, img, &e2);
    CHECK(measured && e1.px.relmse > 0);
    if (measured && e1.px.relmse > 0) {
        double n2 = samples_taken(snap), mc = e1.px.relmse * (n1 / n2);
        printf("refined on to ΔE %.2f: %.0f samples (%.2fx), relMSE %.3g (%.3g of the JND's; a Monte Carlo "
               "estimate's %.3g), mean ΔE %.4f, max %.4f\n",
               (double)snap->jnd, n2, n2 / n1, e2.px.relmse, e2.px.relmse / e1.px.relmse, mc, e2.px.mean_de, e2.px.max_de);
        CHECK_MSG(e2.px.relmse <= 0.5 * e1.px.relmse, "relMSE %.3g after tightening, %.3g before", e2.px.relmse, e1.px.relmse);
        CHECK_MSG(e2.px.relmse <= mc * 4.0 / 3.0, "relMSE %.3g with %.2fx the samples: slower than 1/N", e2.px.relmse,
                  n2 / n1);
        CHECK(e2.px.max_de <= e1.px.max_de);
    }
    free(img);
    cache_worker_destroy(wk);
    test_plane_gl_close(&t);
    return test_finish("rend_exact_test");
}
