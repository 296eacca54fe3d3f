/* rend_frame_test — the renderer's passes end to end against the reference path
 * tracer (model transport, same camera, box-filtered pixels), and the renderer's
 * exact properties:
 *   - a plane under a quad light with a blocker, and CornellBox-Original (with
 *     ../shared/scenes): the cache (refined by the worker with pixel counts from
 *     the ID pass) drawn by material, radiance and composite passes with s×s
 *     samples per pixel, s = 1..4, against the reference (mean ΔE, the method of
 *     `lumesh compare`); a table per scene, with the reference's own noise (a
 *     second reference, another seed) and the draw times. Bounds: s = 1 within
 *     1.5 / 2.0 (measured 1.08 / 1.69: silhouettes sampled at the pixel centre
 *     against the reference's box filter dominate), the default s within 1.1 /
 *     1.45 (measured 0.98 / 1.33);
 *   - while the worker refines, every new snapshot drawn incrementally (only
 *     where its meshes changed) gives the same image, bit for bit, as a full
 *     redraw; so does a renderer that keeps no CPU copy of the snapshot
 *     (one_snapshot, render's final one), which reuses a snapshot drawn
 *     again; a picture added to itself as read (rend_frame_draw_adding) is
 *     exactly twice it;
 *   - the composite averages per-sample values exactly: on a flat-coloured view
 *     (a plane facing the camera, constant values) every s gives the s = 1 image
 *     bit for bit;
 *   - a draw without read-back leaves the same image in the output texture;
 *   - components: indirect hidden equals a snapshot without indirect triangles;
 *     rend_frame_set_emission adds the edited Le, hidden emission removes it;
 *   - a renderer made ahead of its scene (rend_frame_set_scene, rend_frame_resize)
 *     draws what one made with them draws, bit for bit;
 *   - with no snapshot only emission is drawn; bad arguments are refused.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "mesh/cache/cache_worker.h"
#include "sampling/reference.h"
#include "src/gpu/gl_context.h"
#include "src/image/compare.h"
#include "src/image/image.h"
#include "src/render/rend_frame.h"
#include "src/render/rend_id.h"
#include "tests/test_util.h"

enum { MAX_S = 4 };

static int same_floats(const float *a, const float *b, size_t n)
{
    return memcmp(a, b, n * sizeof *a) == 0;
}

static double mean_delta_e(const scene *s, int w, int h, float *img, float *ref, double *p99)
{
    char names[3][32] = {"R", "G", "B"};
    img_image a = {w, h, 3, img, names}, b = {w, h, 3, ref, names};
    cmp_result cr;
    lm_error err;
    if (cmp_compare(&(cmp_desc){.exposure = s->exposure}, &a, &b, &cr, NULL, &err) != LM_OK) return INFINITY;
    if (p99) *p99 = cr.delta_e_p99;
    return cr.delta_e_mean;
}

static void render_reference(const scene *s, int w, int h, int spp, uint32_t seed, float *out)
{
    lm_error err;
    ref_renderer *rr = NULL;
    CHECK(ref_create(&(ref_desc){.scene = s, .width = w, .height = h, .seed = seed}, &rr, &err) == LM_OK);
    for (int i = 0; rr && i < spp; ++i) ref_render_pass(rr, NULL, 0.0);
    if (rr) ref_get_image(rr, out, NULL, NULL);
    ref_destroy(rr);
}

/* Refines until converged; every new snapshot on the way is drawn incrementally
 * by `inc` and in full by `full` (invalidated first), and the images must agree
 * bit for bit. */
/* A renderer made ahead of its scene (as rend_session_early_gl makes the
 * preview's: at 3×3, a stand-in drawn) and then given its size and scene draws
 * what a renderer made with them draws, bit for bit; so does one whose scene is
 * given again after drawing, and one resized away and back. */
static void made_ahead(const GladGLContext *gl, const scene *s, const cache_snapshot *snap, int w, int h)
{
    lm_error err;
    rend_frame *ahead = NULL, *plain = NULL;
    CHECK(rend_frame_create(gl, &(rend_frame_desc){.width = 3, .height = 3, .supersample = 1}, &ahead, &err) ==
          LM_OK);
    CHECK(rend_frame_create(gl, &(rend_frame_desc){.scene = s, .width = w, .height = h, .supersample = 1}, &plain,
                            &err) == LM_OK);
    float *a = malloc((size_t)w * h * 3 * sizeof *a), *b = malloc((size_t)w * h * 3 * sizeof *b);
    if (!ahead || !plain || !a || !b) goto done;
    CHECK(rend_frame_draw(ahead, &s->cameras[0], snap, NULL, &err) == LM_ERR_INVALID_ARG); /* no scene yet */
    CHECK(rend_frame_resize(ahead, 0, h, &err) == LM_ERR_INVALID_ARG);
    CHECK(rend_frame_resize(ahead, w, h, &err) == LM_OK);
    CHECK(rend_frame_set_scene(ahead, s, &err) == LM_OK);
    CHECK(rend_frame_draw(plain, &s->cameras[0], snap, b, &err) == LM_OK);
    CHECK(rend_frame_draw(ahead, &s->cameras[0], snap, a, &err) == LM_OK);
    const size_t n = (size_t)w * h * 3;
    const int same_made_ahead = same_floats(a, b, n);
    CHECK(rend_frame_set_scene(ahead, s, &err) == LM_OK); /* forgets what it drew: drawn whole again */
    CHECK(rend_frame_draw(ahead, &s->cameras[0], snap, a, &err) == LM_OK);
    rend_frame_times t;
    rend_frame_get_times(ahead, &t);
    const int same_scene_again = same_floats(a, b, n) && !t.material_reused && t.radiance_redrawn == 1.0;
    CHECK(rend_frame_resize(ahead, w / 2 + 1, h + 3, &err) == LM_OK);
    CHECK(rend_frame_draw(ahead, &s->cameras[0], snap, NULL, &err) == LM_OK);
    CHECK(rend_frame_resize(ahead, w, h, &err) == LM_OK);
    CHECK(rend_frame_draw(ahead, &s->cameras[0], snap, a, &err) == LM_OK);
    const int same_resized = same_floats(a, b, n);
    printf("  made ahead of its scene at 3x3, then sized and given it: the same picture %s; its scene given again: "
           "%s; resized away and back: %s\n",
           same_made_ahead ? "yes" : "no", same_scene_again ? "yes" : "no", same_resized ? "yes" : "no");
    CHECK(same_made_ahead && same_scene_again && same_resized);
done:
    free(a);
    free(b);
    rend_frame_destroy(ahead);
    rend_frame_destroy(plain);
}

/* m with its whole roots listed as triangles (cache_snapshot_mesh.whole): each
 * the scene triangle, its corners' values by vertex id. The arrays are *keep's,
 * freed by the caller. */
typedef struct listed_mesh {
    cache_snapshot_vertex *v;
    uint32_t *index, *tri;
} listed_mesh;

static cache_snapshot_mesh list_whole(const scene *s, const cache_snapshot *snap, const cache_snapshot_mesh *m,
                                      listed_mesh *keep)
{
    cache_snapshot_mesh out = *m;
    memset(keep, 0, sizeof *keep);
    if (!m->whole_count) return out;
    const size_t n = m->triangle_count + (size_t)m->whole_count, nv = m->vertex_count + 3 * (size_t)m->whole_count;
    keep->v = malloc(nv * sizeof *keep->v);
    keep->index = malloc(3 * n * sizeof *keep->index);
    keep->tri = malloc(n * sizeof *keep->tri);
    if (!keep->v || !keep->index || !keep->tri) return out;
    if (m->triangle_count) { /* none listed: every root whole, and the arrays NULL */
        memcpy(keep->v, m->vertices, m->vertex_count * sizeof *keep->v);
        memcpy(keep->index, m->index, 3 * (size_t)m->triangle_count * sizeof *keep->index);
        memcpy(keep->tri, m->tri, m->triangle_count * sizeof *keep->tri);
    }
    size_t at = m->triangle_count, vat = m->vertex_count;
    for (uint32_t t = 0; t < s->tri_count; ++t) {
        if (!(m->whole[t / 32] >> (t % 32) & 1u)) continue;
        for (int k = 0; k < 3; ++k) {
            cache_snapshot_vertex *v = &keep->v[vat];
            memcpy(v->position, s->positions + 3 * (size_t)s->tris[t].v[k], sizeof v->position);
            const uint32_t id = snap->corner_ids[3 * (size_t)t + (size_t)k];
            CHECK(id < m->value_count);
            memcpy(v->value, m->values + 3 * (size_t)(id < m->value_count ? id : 0), sizeof v->value);
            keep->index[3 * at + (size_t)k] = (uint32_t)vat++;
        }
        keep->tri[at++] = t;
    }
    CHECK(at == n);
    out = (cache_snapshot_mesh){.vertices = keep->v, .index = keep->index, .tri = keep->tri,
                                .triangle_count = (uint32_t)n, .vertex_count = (uint32_t)nv};
    return out;
}

/* Pixels of a and b (n pixels, RGB) that differ by more than 1e-4 of the
 * largest value: the whole roots' pass interpolates in its own arithmetic. */
static size_t pixels_apart(const float *a, const float *b, size_t n)
{
    float top = 0.0f;
    for (size_t i = 0; i < 3 * n; ++i) top = fmaxf(top, fabsf(b[i]));
    size_t off = 0;
    for (size_t i = 0; i < n; ++i) {
        int px = 0;
        for (int c = 0; c < 3; ++c) px |= fabsf(a[3 * i + c] - b[3 * i + c]) > 1e-4f * top;
        off += px;
    }
    return off;
}

static void refine_and_compare(const GladGLContext *gl, const scene *s, const uint32_t *pixels, int w, int h,
                               uint64_t max_tested, int whole_roots)
{
    lm_error err;
    cache_worker *wk = NULL; /* small steps: many snapshots, each changing a little */
    CHECK(cache_worker_create(&(cache_worker_desc){.scene = s, .sampler = {.backend = SAMP_BACKEND_EMBREE},
                                                   .pixels = pixels, .step_budget = 32, .max_tested = max_tested,
                                                   .whole_roots = whole_roots},
                              &wk, &err) == LM_OK);
    if (wk) cache_worker_pause(wk);
    /* In bands of three pixel rows (rend_frame_desc.band_samples): a partial
     * redraw's rectangle crosses several; `whole` draws the image as one band. */
    rend_frame *inc = NULL, *full = NULL, *whole = NULL, *nocopy = NULL;
    const rend_frame_desc banded = {.scene = s, .width = w, .height = h, .supersample = 2, .band_samples = 2 * w * 6};
    CHECK(rend_frame_create(gl, &banded, &inc, &err) == LM_OK);
    CHECK(rend_frame_create(gl, &banded, &full, &err) == LM_OK);
    rend_frame_desc one = banded;
    one.one_snapshot = 1; /* render's final renderer: each new snapshot drawn whole */
    CHECK(rend_frame_create(gl, &one, &nocopy, &err) == LM_OK);
    CHECK(rend_frame_create(gl, &(rend_frame_desc){.scene = s, .width = w, .height = h, .supersample = 2}, &whole,
                            &err) == LM_OK);
    float *a = malloc((size_t)w * h * 3 * sizeof *a), *b = malloc((size_t)w * h * 3 * sizeof *b);
    float *c = malloc((size_t)w * h * 3 * sizeof *c);
    const cache_snapshot *snap = NULL;
    uint64_t last = 0;
    int draws = 0, partial = 0, skipped = 0, differ = 0, nocopy_differ = 0, nocopy_again = 0;
    int with_whole = 0, listed_apart = 0; /* whole_roots: snapshots with some; drawn listed, not as close */
    double t0 = lm_now_seconds();
    while (wk && inc && full && lm_now_seconds() - t0 < 60.0) {
        snap = cache_worker_acquire(wk);
        if (snap && snap->failed) break;
        if (snap && snap->generation != last) {
            last = snap->generation;
            CHECK(rend_frame_draw(inc, &s->cameras[0], snap, a, &err) == LM_OK);
            rend_frame_times t;
            rend_frame_get_times(inc, &t);
            rend_frame_invalidate(full);
            CHECK(rend_frame_draw(full, &s->cameras[0], snap, b, &err) == LM_OK);
            draws++;
            partial += t.radiance_redrawn > 0.0 && t.radiance_redrawn < 1.0;
            skipped += t.radiance_reused;
            differ += !same_floats(a, b, (size_t)w * h * 3);
            if (snap->direct.whole_count || snap->indirect.whole_count) {
                /* The same leaves listed as triangles: what the leaf pass draws. */
                ++with_whole;
                listed_mesh kd, ki;
                cache_snapshot listed = *snap;
                listed.direct = list_whole(s, snap, &snap->direct, &kd);
                listed.indirect = list_whole(s, snap, &snap->indirect, &ki);
                listed.corner_ids = NULL;
                listed.generation = 0;
                if (c && nocopy) {
                    rend_frame_invalidate(full);
                    CHECK(rend_frame_draw(full, &s->cameras[0], &listed, c, &err) == LM_OK);
                    listed_apart += pixels_apart(c, b, (size_t)w * h) > 0;
                    rend_frame_invalidate(full);
                }
                free(kd.v), free(kd.index), free(kd.tri), free(ki.v), free(ki.index), free(ki.tri);
            }
            if (nocopy && c) {
                CHECK(rend_frame_draw(nocopy, &s->cameras[0], snap, c, &err) == LM_OK);
                nocopy_differ += !same_floats(c, b, (size_t)w * h * 3);
                /* The same snapshot again: nothing redrawn, the same picture. */
                CHECK(rend_frame_draw(nocopy, &s->cameras[0], snap, c, &err) == LM_OK);
                rend_frame_get_times(nocopy, &t);
                nocopy_again += t.radiance_reused && same_floats(c, b, (size_t)w * h * 3);
            }
        }
        if (snap && (snap->converged || snap->finished || snap->failed)) break;
        /* A step or so at a time: paused, the worker publishes its last step, so
         * every turn of this loop meets a new snapshot however fast the machine
         * (waiting on the clock instead, a worker that converged in two steps
         * under load was seen once, and nothing was compared). */
        cache_worker_resume(wk);
        cache_worker_pause(wk);
    }
    printf("  incremental against full redraws (s = 2, bands of 3 rows): %d snapshots, %d partly redrawn, %d not "
           "redrawn, %d differ\n",
           draws, partial, skipped, differ);
    CHECK(draws > 1);
    CHECK_MSG(differ == 0, "%d of %d incremental draws differ from a full redraw", differ, draws);
    printf("  without the snapshot's CPU copy: %d of %d draws differ from a full redraw, %d redraws of the same "
           "snapshot reused\n",
           nocopy_differ, draws, nocopy_again);
    CHECK(nocopy_differ == 0 && nocopy_again == draws);
    if (whole_roots) {
        printf("  whole roots: %d of %d snapshots had some; drawn as listed triangles instead, %d differ by more "
               "than 1e-4 of the brightest\n",
               with_whole, draws, listed_apart);
        CHECK(listed_apart == 0);
        /* Published apart only where it pays (cache_worker_publish.c, whole_pays):
         * a scene of a few roots lists them. */
        CHECK_MSG(with_whole > 0 || s->tri_count < 64, "%u triangles, no snapshot with whole roots", s->tri_count);
    }
    /* Added as read (rend_frame_draw_adding, render's accumulated draws): the
     * picture plus itself, exactly twice it. */
    if (snap && nocopy && c) {
        CHECK(rend_frame_draw(nocopy, &s->cameras[0], snap, c, &err) == LM_OK);
        memcpy(b, c, (size_t)w * h * 3 * sizeof *b);
        CHECK(rend_frame_draw_adding(nocopy, &s->cameras[0], snap, c, &err) == LM_OK);
        int doubled = 1;
        for (size_t i = 0; i < 3 * (size_t)w * h; ++i) doubled &= c[i] == 2.0f * b[i];
        CHECK_MSG(doubled, "a picture added to itself is not twice it");
        CHECK(rend_frame_draw_adding(nocopy, &s->cameras[0], snap, NULL, &err) == LM_ERR_INVALID_ARG);
    }
    /* Bands against one band: the same projection with the viewport moved by
     * whole rows; only rounding in the viewport transform may differ. */
    if (snap && whole) {
        CHECK(rend_frame_draw(full, &s->cameras[0], snap, a, &err) == LM_OK);
        CHECK(rend_frame_draw(whole, &s->cameras[0], snap, b, &err) == LM_OK);
        double diff = 0.0, sum = 0.0;
        for (size_t i = 0; i < 3 * (size_t)w * h; ++i) {
            diff += fabs((double)a[i] - b[i]);
            sum += fabs((double)b[i]);
        }
        /* Float rounding changes the last bits of many pixels; a sample that
         * changed surface (a coverage difference) changes its pixel by about a
         * quarter of its value at s = 2: counted above 1e-3 of the mean. */
        const double mean = sum / (3.0 * w * h);
        size_t off = 0;
        for (size_t i = 0; i < (size_t)w * h; ++i) {
            int px = 0;
            for (int c = 0; c < 3; ++c) px |= fabs((double)a[3 * i + c] - b[3 * i + c]) > 1e-3 * mean;
            off += px;
        }
        printf("  bands of 3 rows against one band: mean difference %.2g of the mean; %zu of %d pixels off by more "
               "than 1e-3 of it\n",
               sum > 0.0 ? diff / sum : 0.0, off, w * h);
        CHECK(sum > 0.0 && diff / sum < 1e-5 && off <= (size_t)(w * h) / 200);
    }
    if (snap) made_ahead(gl, s, snap, w, h);
    free(a);
    free(b);
    free(c);
    rend_frame_destroy(inc);
    rend_frame_destroy(full);
    rend_frame_destroy(whole);
    rend_frame_destroy(nocopy);
    cache_worker_destroy(wk);
}

/* The scene against the reference for s = 1..MAX_S; returns mean ΔE per s in de[1..MAX_S]. */
static void run_scene(const GladGLContext *gl, const scene *s, int w, int h, int spp, const char *label,
                      double de[MAX_S + 1])
{
    lm_error err;
    for (int k = 0; k <= MAX_S; ++k) de[k] = INFINITY;
    rend_id *ip = NULL;
    rend_id_result ids;
    CHECK(rend_id_create(gl, &(rend_id_desc){.scene = s, .width = w, .height = h}, &ip, &err) == LM_OK);
    if (!ip) return;
    CHECK(rend_id_render(ip, &s->cameras[0], &ids, &err) == LM_OK);
    cache_worker *wk = NULL;
    CHECK(cache_worker_create(&(cache_worker_desc){.scene = s, .sampler = {.backend = SAMP_BACKEND_EMBREE},
                                                   .pixels = ids.pixels, .whole_roots = 1},
                              &wk, &err) == LM_OK);
    printf("%s, %dx%d:\n", label, w, h);
    refine_and_compare(gl, s, ids.pixels, w, h, 0, 1);
    const cache_snapshot *snap = NULL;
    double t0 = lm_now_seconds();
    while (wk && lm_now_seconds() - t0 < 60.0) {
        snap = cache_worker_acquire(wk);
        if (snap && (snap->finished || snap->failed)) break;
        for (volatile int i = 0; i < 200000; ++i) {
        }
    }
    /* Finished: nothing left the cache can do. Converged or not is the estimate's
     * claim (at these sizes a pixel spans a shadow's whole penumbra, and it may
     * rightly say no): printed, and judged by the reference below. */
    CHECK(snap && snap->finished && !snap->failed);
    if (snap)
        printf("  %s; estimated mean ΔE %.3f, %.1f%% of the pixels above the JND\n",
               snap->converged ? "converged" : "finished without converging", snap->estimate.mean,
               100.0 * snap->estimate.above_jnd);
    size_t n = (size_t)w * h * 3;
    float *img = malloc(n * sizeof *img), *ref = malloc(n * sizeof *ref), *ref2 = malloc(n * sizeof *ref2);
    if (snap && snap->finished) {
        render_reference(s, w, h, spp, 4, ref);
        render_reference(s, w, h, spp, 5, ref2);
        printf("  %u direct, %u indirect, %u specular triangles; against the reference (%d spp; another seed: "
               "mean ΔE %.3f):\n",
               snap->direct.triangle_count, snap->indirect.triangle_count, snap->specular.triangle_count, spp,
               mean_delta_e(s, w, h, ref2, ref, NULL));
        printf("  %2s %9s %8s %13s %13s %13s\n", "s", "mean ΔE", "99%", "material ms", "radiance ms", "composite ms");
        for (int ss = 1; ss <= MAX_S; ++ss) {
            rend_frame *f = NULL;
            CHECK(rend_frame_create(gl, &(rend_frame_desc){.scene = s, .width = w, .height = h, .supersample = ss},
                                    &f, &err) == LM_OK);
            if (!f) continue;
            rend_frame_times tt;
            /* The first draw compiles llvmpipe's shader variants: time the third. */
            scene_camera cam = s->cameras[0];
            for (int i = 0; i < 3; ++i) {
                cam.position[0] = s->cameras[0].position[0] + (i == 1 ? 1e-4f : 0.0f);
                CHECK(rend_frame_draw(f, &cam, snap, img, &err) == LM_OK);
            }
            rend_frame_get_times(f, &tt);
            double p99;
            de[ss] = mean_delta_e(s, w, h, img, ref, &p99);
            printf("  %2d %9.3f %8.3f %13.2f %13.2f %13.2f\n", ss, de[ss], p99, tt.material * 1e3, tt.radiance * 1e3,
                   tt.composite * 1e3);

            if (ss == 1) {
                /* A still camera reuses material and radiance; without read-back the output
                 * texture holds the same image (GL rows bottom up). */
                CHECK(rend_frame_draw(f, &cam, snap, NULL, &err) == LM_OK);
                rend_frame_get_times(f, &tt);
                CHECK(tt.material_reused && tt.upload_reused && tt.radiance_reused && tt.readback == 0.0);
                rend_frame_output o;
                rend_frame_get_output(f, &o);
                CHECK(o.width == w && o.height == h && o.texture && o.framebuffer);
                float *tex = malloc((size_t)w * h * 4 * sizeof *tex);
                gl->GetTextureImage(o.texture, 0, GL_RGBA, GL_FLOAT, (GLsizei)((size_t)w * h * 4 * sizeof *tex), tex);
                int same = 1;
                for (int y = 0; y < h; ++y)
                    for (int x = 0; x < w; ++x)
                        for (int c = 0; c < 3; ++c)
                            same &= tex[4 * ((size_t)(h - 1 - y) * w + x) + c] == img[3 * ((size_t)y * w + x) + c];
                CHECK(same);
                free(tex);
                /* Without a snapshot: emission only (the lamp), everything else black. */
                CHECK(rend_frame_draw(f, &s->cameras[0], NULL, img, &err) == LM_OK);
                int other = 0;
                for (int i = 0; i < w * h; ++i) other += !(img[3 * i] > 0.0f);
                CHECK(other > 0);
            }
            rend_frame_destroy(f);
        }
    }
    free(img);
    free(ref);
    free(ref2);
    cache_worker_destroy(wk);
    rend_id_destroy(ip);
}

/* A renderer of one snapshot (the terms summed into its output: one_snapshot at
 * s > 1) against renderer f at the same s, through component and emission
 * edits, bit for bit; the same draw again redraws nothing. f is left showing
 * everything, with its scene's emission. */
static void one_snapshot_edits(const GladGLContext *gl, const scene *s, const cache_snapshot *snap, rend_frame *f,
                               int ss)
{
    enum { W = 37, H = 23 };
    static float a[W * H * 3], b[W * H * 3];
    lm_error err;
    rend_frame *o = NULL;
    CHECK(rend_frame_create(gl, &(rend_frame_desc){.scene = s, .width = W, .height = H, .supersample = ss,
                                                   .one_snapshot = 1},
                            &o, &err) == LM_OK);
    if (!o) return;
    const float le[3] = {1.0f, 2.0f, 3.0f}, dark[3] = {0.0f, 0.0f, 0.0f};
    const unsigned shown[] = {REND_FRAME_COMPONENTS_ALL, REND_FRAME_COMPONENTS_ALL & ~REND_FRAME_COMPONENT_INDIRECT,
                              REND_FRAME_COMPONENT_EMISSION, REND_FRAME_COMPONENT_DIRECT_SPECULAR,
                              REND_FRAME_COMPONENTS_ALL & ~REND_FRAME_COMPONENT_EMISSION, REND_FRAME_COMPONENTS_ALL};
    int differ = 0, reused = 0;
    for (int e = 0; e < 2; ++e) {
        CHECK(rend_frame_set_emission(f, 0, e ? le : dark, &err) == LM_OK);
        CHECK(rend_frame_set_emission(o, 0, e ? le : dark, &err) == LM_OK);
        for (size_t k = 0; k < sizeof shown / sizeof *shown; ++k) {
            rend_frame_set_components(f, shown[k]);
            rend_frame_set_components(o, shown[k]);
            CHECK(rend_frame_draw(f, &s->cameras[0], snap, a, &err) == LM_OK);
            CHECK(rend_frame_draw(o, &s->cameras[0], snap, b, &err) == LM_OK);
            differ += !same_floats(a, b, W * H * 3);
            CHECK(rend_frame_draw(o, &s->cameras[0], snap, b, &err) == LM_OK);
            rend_frame_times t;
            rend_frame_get_times(o, &t);
            reused += t.radiance_reused && t.composite_reused && same_floats(a, b, W * H * 3);
        }
    }
    CHECK(rend_frame_set_emission(f, 0, s->materials[0].le, &err) == LM_OK);
    printf("  s = %d, the terms summed into the output: %d of %d component and emission edits differ from "
           "separate term images; %d drawn again redrew nothing\n",
           ss, differ, (int)(2 * sizeof shown / sizeof *shown), reused);
    CHECK(differ == 0 && reused == (int)(2 * sizeof shown / sizeof *shown));
    rend_frame_destroy(o);
}

/* A plane facing the camera, constant values: every sample of every pixel has
 * the same value, so the box filter must give the s = 1 image exactly. */
static void flat_case(const GladGLContext *gl)
{
    char obj[1024], json[1024];
    test_write_file("frame_flat.obj", "v -10 -10 0\nv 10 -10 0\nv 10 10 0\nv -10 10 0\nf 1 2 3\nf 1 3 4\n", obj,
                    sizeof obj);
    test_write_file("frame_flat.json",
                    "{\"meshes\": [{\"file\": \"frame_flat.obj\", \"material\": \"m\"}],"
                    " \"materials\": {\"m\": {\"kd\": [0.6, 0.5, 0.4], \"ks\": [0.2, 0.1, 0.05]}},"
                    " \"cameras\": [{\"position\": [0, 0, 2], \"target\": [0, 0, 0], \"fov_y\": 60}]}",
                    json, sizeof json);
    scene *s = NULL;
    lm_error err;
    CHECK(scene_load(&(scene_load_desc){.path = json}, &s, &err) == LM_OK);
    if (!s) return;
    /* The snapshot: the two scene triangles with one value per mesh. */
    cache_snapshot_vertex v[3][6];
    uint32_t tri[2] = {0, 1}, index[6] = {0, 1, 2, 3, 4, 5}; /* each corner its own vertex */
    const float values[3][3] = {{0.3f, 0.7f, 0.9f}, {2.1f, 1.3f, 0.2f}, {0.05f, 0.5f, 1.7f}};
    for (int m = 0; m < 3; ++m)
        for (int t = 0; t < 2; ++t)
            for (int c = 0; c < 3; ++c) {
                uint32_t vi = s->tris[t].v[c];
                memcpy(v[m][3 * t + c].position, s->positions + 3 * (size_t)vi, 3 * sizeof(float));
                memcpy(v[m][3 * t + c].value, values[m], 3 * sizeof(float));
            }
    cache_snapshot snap = {.generation = 1,
                           .direct = {.vertices = v[0], .index = index, .tri = tri, .triangle_count = 2, .vertex_count = 6},
                           .indirect = {.vertices = v[1], .index = index, .tri = tri, .triangle_count = 2, .vertex_count = 6},
                           .specular = {.vertices = v[2], .index = index, .tri = tri, .triangle_count = 2, .vertex_count = 6},
                           .converged = 1};
    enum { W = 37, H = 23 }; /* odd sizes: no symmetry to hide an off-by-one */
    float one[W * H * 3], img[W * H * 3];
    for (int ss = 1; ss <= MAX_S; ++ss) {
        rend_frame *f = NULL;
        CHECK(rend_frame_create(gl, &(rend_frame_desc){.scene = s, .width = W, .height = H, .supersample = ss}, &f,
                                &err) == LM_OK);
        if (!f) continue;
        CHECK(rend_frame_draw(f, &s->cameras[0], &snap, ss == 1 ? one : img, &err) == LM_OK);
        if (ss == 1) {
            int flat = 1;
            for (int i = 1; i < W * H; ++i) flat &= memcmp(one, one + 3 * i, 3 * sizeof *one) == 0;
            const scene_material *m = &s->materials[0];
            float want[3];
            for (int k = 0; k < 3; ++k)
                want[k] = m->kd[k] * (values[0][k] + values[1][k] * 0.31830988618379067f) + m->ks[k] * values[2][k];
            CHECK_MSG(flat, "the s = 1 image of the flat case is not flat");
            for (int k = 0; k < 3; ++k) CHECK_NEAR(one[k], want[k], 1e-6 * want[k]);
            /* Components: indirect hidden gives, bit for bit, the image of a snapshot
             * without indirect triangles (drawn by a renderer that shows everything). */
            static float hidden[W * H * 3], without[W * H * 3];
            CHECK(rend_frame_get_components(f) == REND_FRAME_COMPONENTS_ALL);
            rend_frame_set_components(f, REND_FRAME_COMPONENTS_ALL & ~REND_FRAME_COMPONENT_INDIRECT);
            CHECK(rend_frame_draw(f, &s->cameras[0], &snap, hidden, &err) == LM_OK);
            cache_snapshot no_ind = snap;
            no_ind.generation = 2;
            no_ind.indirect.triangle_count = 0;
            rend_frame *g = NULL;
            CHECK(rend_frame_create(gl, &(rend_frame_desc){.scene = s, .width = W, .height = H, .supersample = 1},
                                    &g, &err) == LM_OK);
            if (g) CHECK(rend_frame_draw(g, &s->cameras[0], &no_ind, without, &err) == LM_OK);
            CHECK_MSG(same_floats(hidden, without, W * H * 3), "indirect hidden differs from no indirect triangles");
            CHECK(!same_floats(hidden, one, W * H * 3));
            /* Emission (a light edit shown on the emitter): Le added where shown, not when hidden. */
            const float le[3] = {1.0f, 2.0f, 3.0f};
            rend_frame_set_components(f, REND_FRAME_COMPONENTS_ALL);
            CHECK(rend_frame_set_emission(f, 0, le, &err) == LM_OK);
            CHECK(rend_frame_draw(f, &s->cameras[0], &snap, img, &err) == LM_OK);
            for (int k = 0; k < 3; ++k) CHECK_NEAR(img[k], want[k] + le[k], 1e-5 * (want[k] + le[k]));
            rend_frame_set_components(f, REND_FRAME_COMPONENTS_ALL & ~REND_FRAME_COMPONENT_EMISSION);
            CHECK(rend_frame_draw(f, &s->cameras[0], &snap, img, &err) == LM_OK);
            CHECK(same_floats(img, one, W * H * 3));
            CHECK(rend_frame_set_emission(f, 1, le, &err) == LM_ERR_INVALID_ARG);
            CHECK(rend_frame_set_emission(f, 0, (float[3]){-1.0f, 0.0f, 0.0f}, &err) == LM_ERR_INVALID_ARG);
            rend_frame_destroy(g);
        } else {
            CHECK_MSG(same_floats(one, img, W * H * 3), "s = %d differs from s = 1 on a flat view", ss);
            one_snapshot_edits(gl, s, &snap, f, ss);
        }
        rend_frame_destroy(f);
    }
    scene_destroy(s);
}

static void bad_arguments(const GladGLContext *gl, const scene *s)
{
    lm_error err;
    rend_frame *f = NULL;
    CHECK(rend_frame_create(gl, &(rend_frame_desc){.scene = s, .width = 8, .height = 8, .supersample = -1}, &f,
                            &err) == LM_ERR_INVALID_ARG && !f);
    CHECK(rend_frame_create(gl,
                            &(rend_frame_desc){.scene = s, .width = 8, .height = 8,
                                               .supersample = REND_FRAME_SUPERSAMPLE_MAX + 1},
                            &f, &err) == LM_ERR_INVALID_ARG &&
          !f);
    CHECK(rend_frame_create(gl, &(rend_frame_desc){.scene = s, .width = 16384, .height = 8, .supersample = 2}, &f,
                            &err) == LM_ERR_INVALID_ARG &&
          !f);
    CHECK(rend_frame_create(gl, &(rend_frame_desc){.scene = s, .width = 8, .height = 8}, &f, &err) == LM_OK);
    rend_frame_times t;
    if (f) {
        CHECK(rend_frame_draw(f, &s->cameras[0], NULL, NULL, &err) == LM_OK);
        rend_frame_get_times(f, &t);
        CHECK(t.supersample == REND_FRAME_SUPERSAMPLE_DEFAULT);
        CHECK(rend_frame_draw(f, NULL, NULL, NULL, &err) == LM_ERR_INVALID_ARG);
    }
    rend_frame_destroy(f);
    rend_frame_destroy(NULL);
}

int main(void)
{
    glctx *ctx = NULL;
    lm_error err;
    if (glctx_create(&(glctx_desc){.platform = GLCTX_EGL}, &ctx, &err) != LM_OK) return test_no_gl(err.msg);
    const GladGLContext *gl = glctx_gl(ctx);

    flat_case(gl);

    char obj[1024], json[1024];
    test_write_file("frame_plane.obj",
                    "v -2 0 -2\nv 2 0 -2\nv 2 0 2\nv -2 0 2\nf 1 4 3\nf 1 3 2\n"
                    "v -0.2 0.5 -0.2\nv 0.2 0.5 -0.2\nv 0.2 0.5 0.2\nv -0.2 0.5 0.2\nf 5 6 7\nf 5 7 8\n",
                    obj, sizeof obj);
    test_write_file("frame.json",
                    "{\"meshes\": [{\"file\": \"frame_plane.obj\", \"material\": \"paint\"}],"
                    " \"materials\": {\"paint\": {\"kd\": [0.6, 0.5, 0.4]}},"
                    " \"lights\": [{\"type\": \"quad\", \"corner\": [-0.5, 1, -0.5], \"edge1\": [1, 0, 0],"
                    " \"edge2\": [0, 0, 1], \"radiance\": [5, 5, 5]}],"
                    " \"cameras\": [{\"position\": [0, 0.9, 1.4], \"target\": [0, 0, 0], \"fov_y\": 70}]}",
                    json, sizeof json);
    scene *s = NULL;
    double de[MAX_S + 1];
    const int def = REND_FRAME_SUPERSAMPLE_DEFAULT;
    CHECK(scene_load(&(scene_load_desc){.path = json, .require_light = 1}, &s, &err) == LM_OK);
    if (s) {
        bad_arguments(gl, s);
        run_scene(gl, s, 96, 72, 1024, "plane, blocker, quad light", de);
        CHECK_MSG(de[1] <= 1.5, "s = 1: mean ΔE %.3f", de[1]);
        CHECK_MSG(de[def] <= 1.1, "s = %d: mean ΔE %.3f", def, de[def]);
        scene_destroy(s);
    }
    char path[1024];
    snprintf(path, sizeof path, "%s/cornell-box/CornellBox-Original.obj", LUMESH_SCENES);
    s = NULL;
    CHECK(scene_load(&(scene_load_desc){.path = path, .require_light = 1}, &s, &err) == LM_OK);
    if (s) {
        run_scene(gl, s, 80, 60, 512, "CornellBox-Original", de);
        CHECK_MSG(de[1] <= 2.0, "s = 1: mean ΔE %.3f", de[1]);
        CHECK_MSG(de[def] <= 1.45, "s = %d: mean ΔE %.3f", def, de[def]);
        scene_destroy(s);
    }
    /* Glossy materials: the specular term comes with lobes (highlights per
     * pixel, rend_value.frag), which the change detection compares too. */
    snprintf(path, sizeof path, "%s/cornell-box/CornellBox-Glossy.obj", LUMESH_SCENES);
    s = NULL;
    CHECK(scene_load(&(scene_load_desc){.path = path, .require_light = 1}, &s, &err) == LM_OK);
    rend_id *ip = NULL;
    rend_id_result ids;
    if (s) CHECK(rend_id_create(gl, &(rend_id_desc){.scene = s, .width = 80, .height = 60}, &ip, &err) == LM_OK);
    if (ip && rend_id_render(ip, &s->cameras[0], &ids, &err) == LM_OK) {
        printf("CornellBox-Glossy, 80x60:\n");
        refine_and_compare(gl, s, ids.pixels, 80, 60, 2048, 0); /* the first 64 snapshots */
        refine_and_compare(gl, s, ids.pixels, 80, 60, 2048, 1); /* the same, whole roots apart */
    }
    rend_id_destroy(ip);
    scene_destroy(s);
    glctx_destroy(ctx);
    return test_finish("rend_frame_test");
}
