/* bench_frame — the renderer's frame (rend_frame.h) from cached samples: loads a
 * scene, refines it with the cache worker (pixel counts from the ID pass at
 * 640×480) until converged or SECONDS have passed, then times draws at 640×480
 * for s = 1, 2, 3 samples per pixel side:
 *   moving     the camera moves every frame (a tiny step), the converged snapshot:
 *              material, radiance and composite redrawn — the interactive
 *              viewer's frame (no read-back); FRAMES draws;
 *   moving+rb  the same, read back to the CPU (what lumesh render does once);
 *   still      still camera, same snapshot: composite only; FRAMES draws;
 *   refining   a new worker refines from scratch while a still camera draws
 *              every new snapshot (the worker shares the CPU, as in the viewer):
 *              only what changed is redrawn; one row per run, its draws;
 *   refine-all the same with every draw redrawing everything
 *              (rend_frame_invalidate first), for comparison.
 * Prints per pass the median and 90th percentile in ms (each pass ends with
 * glFinish) and of the whole draw; 0 means the pass was reused. The first 3
 * draws of the fixed cases are not counted (llvmpipe compiles shader variants on
 * first use).
 * usage: bench_frame [SCENE (default: CornellBox-Water)] [SECONDS (60)] [FRAMES (50)] [MAX_S (3)]
 *                    [BAND_SAMPLES (0: REND_FRAME_BAND_SAMPLES)] */
#define _POSIX_C_SOURCE 200809L /* nanosleep */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "mesh/cache/cache_worker.h"
#include "src/gpu/gl_context.h"
#include "src/render/rend_frame.h"
#include "src/render/rend_id.h"

enum { W = 640, H = 480, WARMUP = 3, MAX_FRAMES = 2000, COLS = 7 };

typedef enum bench_case {
    CASE_MOVING,
    CASE_MOVING_RB,
    CASE_STILL,
    CASE_REFINING,
    CASE_REFINE_ALL,
    CASE_COUNT
} bench_case;
static const char *const case_names[CASE_COUNT] = {"moving", "moving+rb", "still", "refining", "refine-all"};

typedef struct bench {
    const scene *s;
    const uint32_t *pixels; /* per scene triangle, from the ID pass */
    float *rgb;
    double v[COLS][MAX_FRAMES]; /* material, upload, radiance, composite, read-back, total, share redrawn */
    int n;
} bench;

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

/* Median and 90th percentile (nearest rank) of n values; sorts v. */
static void med_p90(double *v, int n, double *med, double *p90)
{
    qsort(v, (size_t)n, sizeof *v, cmp_double);
    *med = n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
    int k = (int)(0.9 * n + 0.999999) - 1;
    *p90 = v[k < 0 ? 0 : k];
}

static void record(bench *b, const rend_frame *f)
{
    rend_frame_times t;
    rend_frame_get_times(f, &t);
    double v[COLS] = {t.material, t.upload, t.radiance, t.composite, t.readback, t.total, t.radiance_redrawn};
    for (int k = 0; k < COLS; ++k) b->v[k][b->n] = v[k];
    b->n++;
}

/* moving, moving+rb, still: `frames` draws of the converged snapshot. */
static int run_fixed(bench *b, rend_frame *f, const cache_snapshot *snap, bench_case c, int frames, lm_error *err)
{
    const scene_camera *cam0 = &b->s->cameras[0];
    scene_camera cam = *cam0;
    rend_frame_invalidate(f);
    b->n = 0;
    for (int i = 0; i < WARMUP + frames; ++i) {
        if (c != CASE_STILL) cam.position[0] = cam0->position[0] + (i % 2 ? 1e-4f : 0.0f); /* a new view */
        if (rend_frame_draw(f, &cam, snap, c == CASE_MOVING_RB ? b->rgb : NULL, err) != LM_OK) return 0;
        if (i >= WARMUP) record(b, f);
    }
    return 1;
}

/* refining, refine-all: a new worker, every new snapshot drawn until converged. */
static int run_refining(bench *b, rend_frame *f, bench_case c, double budget, lm_error *err)
{
    samp_desc sd = {.direct_target_error = 0.02f, .indirect_target_error = 0.02f}; /* as lumesh render */
    cache_worker *wk = NULL;
    /* whole_roots: as the render session's worker (rend_frame draws them from the scene) */
    const cache_worker_desc wd = {.scene = b->s, .sampler = sd, .pixels = b->pixels, .whole_roots = 1};
    if (cache_worker_create(&wd, &wk, err) != LM_OK)
        return 0;
    rend_frame_invalidate(f);
    b->n = 0;
    uint64_t last = 0;
    double t0 = lm_now_seconds();
    int ok = 1;
    while (b->n < MAX_FRAMES && lm_now_seconds() - t0 < budget) {
        const cache_snapshot *snap = cache_worker_acquire(wk);
        if (snap && snap->failed) {
            ok = 0;
            snprintf(err->msg, sizeof err->msg, "refinement failed: %s", snap->error);
            break;
        }
        if (!snap || snap->generation == last) {
            nanosleep(&(struct timespec){0, 1000000}, NULL);
            continue;
        }
        last = snap->generation;
        if (c == CASE_REFINE_ALL) rend_frame_invalidate(f);
        if (rend_frame_draw(f, &b->s->cameras[0], snap, NULL, err) != LM_OK) {
            ok = 0;
            break;
        }
        if (last > 1) record(b, f); /* the first draw also compiles shader variants */
        if (snap->converged) break;
    }
    cache_worker_destroy(wk);
    return ok;
}

static void print_row(bench *b, bench_case c, int ss)
{
    printf("%-10s %2d %6d", case_names[c], ss, b->n);
    double med, p90;
    for (int k = 0; k < COLS - 1; ++k) {
        med_p90(b->v[k], b->n, &med, &p90);
        printf(" %6.2f/%6.2f", med * 1e3, p90 * 1e3);
    }
    med_p90(b->v[COLS - 1], b->n, &med, &p90);
    printf(" %8.0f%%\n", med * 100.0);
    fflush(stdout);
}

int main(int argc, char **argv)
{
    char path[1024];
    if (argc > 1 && argv[1][0])
        snprintf(path, sizeof path, "%s", argv[1]);
    else
        snprintf(path, sizeof path, "%s/cornell-box/CornellBox-Water.obj", LUMESH_SCENES);
    double budget = argc > 2 ? atof(argv[2]) : 60.0;
    int frames = argc > 3 ? atoi(argv[3]) : 50, max_s = argc > 4 ? atoi(argv[4]) : 3;
    const int band = argc > 5 ? atoi(argv[5]) : 0;
    if (frames < 1 || frames > MAX_FRAMES) frames = 50;
    if (max_s < 1 || max_s > REND_FRAME_SUPERSAMPLE_MAX) max_s = 3;
    lm_error err = {{0}};
    scene *s;
    if (scene_load(&(scene_load_desc){.path = path, .require_light = 1}, &s, &err) != LM_OK) {
        fprintf(stderr, "%s\n", err.msg);
        return 1;
    }
    glctx *ctx;
    if (glctx_create(&(glctx_desc){0}, &ctx, &err) != LM_OK) {
        fprintf(stderr, "%s\n", err.msg);
        scene_destroy(s);
        return 1;
    }
    const GladGLContext *gl = glctx_gl(ctx);
    const scene_camera *cam = &s->cameras[0];
    rend_id *ip = NULL;
    rend_id_result ids;
    cache_worker *wk = NULL;
    rend_frame *f = NULL;
    bench *b = calloc(1, sizeof *b);
    float *rgb = malloc((size_t)W * H * 3 * sizeof *rgb);
    int rc = 1;
    if (!b || !rgb) {
        snprintf(err.msg, sizeof err.msg, "out of memory");
        goto done;
    }
    *b = (bench){.s = s, .rgb = rgb};
    if (rend_id_create(gl, &(rend_id_desc){.scene = s, .width = W, .height = H}, &ip, &err) != LM_OK) goto done;
    /* The ID pass as the viewer will run it every frame (the renderer does not). */
    for (int i = 0; i < WARMUP + frames; ++i) {
        if (rend_id_render(ip, cam, &ids, &err) != LM_OK) goto done;
        if (i >= WARMUP) b->v[0][i - WARMUP] = ids.seconds;
    }
    double med, p90;
    med_p90(b->v[0], frames, &med, &p90);
    b->pixels = ids.pixels;
    samp_desc sd = {.direct_target_error = 0.02f, .indirect_target_error = 0.02f}; /* as lumesh render */
    if (cache_worker_create(&(cache_worker_desc){.scene = s, .sampler = sd, .pixels = ids.pixels, .whole_roots = 1},
                            &wk, &err) != LM_OK)
        goto done;
    const cache_snapshot *snap = NULL;
    double t0 = lm_now_seconds();
    for (;;) {
        snap = cache_worker_acquire(wk);
        if (snap && snap->failed) {
            snprintf(err.msg, sizeof err.msg, "refinement failed: %s", snap->error);
            goto done;
        }
        if (snap && (snap->converged || lm_now_seconds() - t0 >= budget)) break;
        nanosleep(&(struct timespec){0, 20000000}, NULL);
    }
    cache_worker_pause(wk); /* the fixed cases have the CPU to themselves */
    snap = cache_worker_acquire(wk);
    size_t leaves = (size_t)snap->direct.triangle_count + snap->indirect.triangle_count + snap->specular.triangle_count;
    size_t verts = (size_t)snap->direct.vertex_count + snap->indirect.vertex_count + snap->specular.vertex_count;
    size_t bytes = sizeof(cache_snapshot_vertex) * verts + 3 * sizeof(uint32_t) * leaves;
    printf("%s: %u scene triangles; cache %s after %.1f s: %u direct, %u indirect, %u specular leaf triangles "
           "(%.1f MiB of vertices and indices)\n%s; %dx%d, %d frames per fixed case, first %d not counted\n",
           path, s->tri_count, snap->converged ? "converged" : "stopped", lm_now_seconds() - t0,
           snap->direct.triangle_count, snap->indirect.triangle_count, snap->specular.triangle_count,
           bytes / 1048576.0, glctx_renderer(ctx), W, H, frames, WARMUP);
    printf("ID pass (rend_id, read-back count): median %.2f ms, p90 %.2f ms\n", med * 1e3, p90 * 1e3);
    printf("ms per draw, median/p90 (0: pass reused); redrawn: median share of the radiance images redrawn\n");
    printf("%-10s %2s %6s %13s %13s %13s %13s %13s %13s %9s\n", "case", "s", "draws", "material", "upload",
           "radiance", "composite", "read-back", "total", "redrawn");
    for (int ss = 1; ss <= max_s; ++ss) {
        rend_frame_destroy(f);
        f = NULL;
        if (rend_frame_create(gl, &(rend_frame_desc){.scene = s, .width = W, .height = H, .supersample = ss, .band_samples = band}, &f,
                              &err) != LM_OK)
            goto done;
        for (int c = 0; c < CASE_COUNT; ++c) {
            int ok = c >= CASE_REFINING ? run_refining(b, f, (bench_case)c, budget, &err)
                                        : run_fixed(b, f, snap, (bench_case)c, frames, &err);
            if (!ok) goto done;
            if (b->n) print_row(b, (bench_case)c, ss);
        }
    }
    rc = 0;
done:
    if (rc) fprintf(stderr, "%s\n", err.msg);
    rend_frame_destroy(f);
    cache_worker_destroy(wk);
    rend_id_destroy(ip);
    free(rgb);
    free(b);
    glctx_destroy(ctx);
    scene_destroy(s);
    return rc;
}
