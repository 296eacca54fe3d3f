/* cmd_render.c — `lumesh render`: a headless progressive render.
 *
 * A render session (rend_session.h): the ID pass gives the pixels per triangle;
 * the refinement worker refines the multi-mesh cache (its own sampler, `--sampler`, chosen at the cache's 2%
 * tolerance by default) until it has converged at its JND (or nothing is left to
 * test), or `--seconds` have passed (refining on to a lower JND meanwhile), or
 * `--samples` leaf tests are done; the renderer's passes draw the last
 * snapshot (with `--seconds` corrected by the path-traced residual, which runs in
 * the background beside the worker and then until the time is up:
 * rend_residual.h); the image is written linear (EXR) or tone-mapped (PNG),
 * through a temporary file (img_write), so a failure leaves no partial file.
 */
#define _POSIX_C_SOURCE 200809L
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "src/base/tonemap.h"
#include "src/cli/app_stats.h"
#include "src/cli/cli.h"
#include "src/image/image.h"
#include "src/render/rend_debug.h"
#include "src/render/rend_residual.h"
#include "src/render/rend_session.h"
#include "src/scene/scene.h"

enum { DEFAULT_SECONDS_LIMIT = 600 }; /* without --seconds or --samples: until converged, at most this */

/* The path-traced residual of `--seconds` (rend_residual.h): it runs beside the
 * refining worker, in the background (the cycles the worker leaves), from the
 * first snapshot on, and with the whole machine once the cache has finished.
 * The model transport with the bounces the cache shows is the truth it converges
 * to: made again, its samples dropped, if `auto` changes them. Main thread. */
typedef struct render_residual {
    const scene *s;
    const scene_camera *cam;
    int w, h;
    double until;      /* lm_now_seconds: the end of --seconds */
    rend_residual *rr; /* NULL until the first snapshot, or after a failure to make it */
    int bounces;       /* rr's */
    lm_result failed;  /* making it failed: err says why, and it is not tried again */
    lm_error err;
} render_residual;

/* The residual for the bounces `snap` shows (made, or made again). */
static rend_residual *residual_for(render_residual *res, const cache_snapshot *snap)
{
    int bounces = snap->stats.bounces.bounces > 0 ? snap->stats.bounces.bounces : 1;
    if (res->rr && res->bounces == bounces) return res->rr;
    rend_residual_destroy(res->rr);
    res->rr = NULL;
    if (res->failed != LM_OK) return NULL;
    res->failed = rend_residual_create(&(rend_residual_desc){.scene = res->s, .camera = res->cam, .width = res->w,
                                                             .height = res->h, .bounces = bounces,
                                                             .seed = 0x5eed0001u, .background = 1},
                                       &res->rr, &res->err);
    res->bounces = bounces;
    return res->rr;
}

/* The progress line on a terminal (stderr), as `lumesh reference` shows its own:
 * time against the limit, leaves tested, samples, and the cache's estimate of its
 * error against the JND it refines to. Between looks, the residual's passes. */
typedef struct render_progress {
    double t0, limit, last;
    int tty, shown;
    render_residual *residual; /* NULL: none */
} render_progress;

static void show_progress(void *user, const cache_snapshot *snap)
{
    render_progress *p = user;
    /* Not before the first image's values are gathered again (cache_snapshot.owed). */
    rend_residual *rr = p->residual && snap && !snap->failed && (p->residual->rr || !snap->owed)
                            ? residual_for(p->residual, snap)
                            : NULL;
    /* A slice of background passes: the wait looks at the worker again after it. */
    if (rr) rend_residual_run(rr, NULL, fmin(p->residual->until, lm_now_seconds() + 0.1));
    double now = lm_now_seconds();
    if (!p->tty || !snap || now - p->last < 0.1) return;
    p->last = now;
    p->shown = 1;
    double t = now - p->t0;
    char bar[APP_PROGRESS_WIDTH + 1];
    app_progress_bar(p->limit > 0 ? t / p->limit : 0, bar);
    uint64_t light = 0;
    for (uint32_t l = 0; l < snap->stats.light_count; ++l) light += snap->stats.lights[l].samples;
    char est[32] = "est. dE -"; /* the first snapshot has none (cache_worker_acquire) */
    if (snap->estimate.measured) snprintf(est, sizeof est, "est. dE %.2f", snap->estimate.mean);
    fprintf(stderr, "\rrender [%s] %.1f s  %llu leaves  %llu light + %llu indirect samples  %s (JND %.3g)%s   ",
            bar, t, (unsigned long long)snap->tested, (unsigned long long)light,
            (unsigned long long)snap->stats.indirect.samples, est, (double)snap->jnd,
            snap->converged ? " converged" : "");
    fflush(stderr);
}

/* What `--seconds` has left after the refinement goes to the residual, with its
 * samples from beside the worker: the cached picture in rgb (drawn, accumulated)
 * is corrected in place. A terminal shows its progress. */
static lm_result residual_until(render_residual *res, const cache_snapshot *snap, double t0, float *rgb,
                                rend_residual_info *info, lm_error *err)
{
    rend_residual *rr = residual_for(res, snap);
    if (!rr) {
        *err = res->err;
        return res->failed;
    }
    int w = res->w, h = res->h;
    double until = res->until;
    float *cached = malloc((size_t)w * (size_t)h * 3 * sizeof *cached);
    if (!cached) return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory for a %dx%d image", w, h);
    memcpy(cached, rgb, (size_t)w * (size_t)h * 3 * sizeof *cached);
    int tty = isatty(STDERR_FILENO);
    rend_residual_apply(rr, cached, rgb, info); /* the picture its adaptive passes start from */
    while (lm_now_seconds() < until) {
        rend_residual_run(rr, NULL, fmin(until, lm_now_seconds() + (tty ? 0.25 : until)));
        if (!tty) continue;
        rend_residual_apply(rr, cached, rgb, info);
        double t = lm_now_seconds() - t0, limit = until - t0;
        char bar[APP_PROGRESS_WIDTH + 1];
        app_progress_bar(limit > 0 ? t / limit : 1, bar);
        char est[32] = "-"; /* unknown below the samples the residual trusts */
        if (isfinite(info->est_relmse)) snprintf(est, sizeof est, "%.3g", info->est_relmse);
        fprintf(stderr, "\rresidual [%s] %.1f s  %u..%u path samples a pixel  %.1f%% of the blocks corrected  "
                        "est. relMSE %s   ",
                bar, t, info->min_samples, info->max_samples, 100.0 * info->corrected, est);
        fflush(stderr);
    }
    if (tty) fputc('\n', stderr);
    rend_residual_apply(rr, cached, rgb, info);
    free(cached);
    return LM_OK;
}

/* --components LIST: the composite's terms to draw (rend_frame_set_components),
 * a comma-separated list of direct, indirect, specular and emission; each term
 * alone is what finds which of them carries an error (docs/cache.md, the Veach
 * door's line). Returns 0 on a name it does not know. */
static unsigned parse_components(const char *list)
{
    static const struct { const char *name; unsigned bit; } names[] = {
        {"direct", REND_FRAME_COMPONENT_DIRECT_DIFFUSE}, {"indirect", REND_FRAME_COMPONENT_INDIRECT},
        {"specular", REND_FRAME_COMPONENT_DIRECT_SPECULAR}, {"emission", REND_FRAME_COMPONENT_EMISSION}};
    unsigned mask = 0;
    for (const char *p = list; *p;) {
        size_t len = strcspn(p, ",");
        unsigned bit = 0;
        for (size_t i = 0; i < sizeof names / sizeof names[0]; ++i)
            if (len == strlen(names[i].name) && strncmp(p, names[i].name, len) == 0) bit = names[i].bit;
        if (!bit) return 0;
        mask |= bit;
        p += len;
        if (*p == ',') p++;
    }
    return mask;
}

static int ext_is(const char *path, const char *want)
{
    char ext[16];
    lm_path_ext(path, ext, sizeof ext);
    return strcmp(ext, want) == 0;
}

static void print_debug_image(const char *path, const rend_debug_counts *n, void *user)
{
    (void)user;
    if (strstr(path, "-leaves.png"))
        printf("wrote %s: %u of %u leaf edges shown, %llu pixels, %.0f ms\n", path, n->segments_drawn, n->segments,
               (unsigned long long)n->wire_pixels, n->seconds * 1e3);
    else
        printf("wrote %s: %u samples shown, %u hidden, %.0f ms\n", path, n->points_drawn, n->points_hidden,
               n->seconds * 1e3);
}

/* --debug-meshes DIR: each mesh's leaves and samples over the tone-mapped image,
 * hidden parts left out by the ID image (rend_debug.h). */
static lm_result write_debug_meshes(const char *dir, const scene *s, const scene_camera *cam, int w, int h,
                                    rend_session *rs, const float *rgb, const cache_snapshot *snap, lm_error *err)
{
    const size_t n = (size_t)w * (size_t)h;
    uint32_t *ids = malloc(n * sizeof *ids);
    uint8_t *bg = malloc(3 * n);
    lm_result r = ids && bg ? LM_OK : lm_fail(err, LM_ERR_NO_MEMORY, "out of memory for a %dx%d image", w, h);
    if (r == LM_OK) r = rend_session_read_ids(rs, ids, err);
    if (r == LM_OK) {
        tm_to_rgb8(&(tm_desc){.exposure = s->exposure}, rgb, 3, n, bg);
        rend_debug_desc d = {.camera = cam, .width = w, .height = h, .ids = ids, .background = bg};
        r = rend_debug_write_images(
            &(rend_debug_write_desc){.draw = &d, .snap = snap, .dir = dir, .written = print_debug_image}, err);
    }
    free(ids);
    free(bg);
    return r;
}

int cmd_render(const app_command *cmd, int argc, char **argv)
{
    const char *out = NULL, *camera = NULL, *stats = NULL, *sampler = NULL, *gl_name = NULL, *bounces = NULL, *debug_dir = NULL,
               *components = NULL, *residual_opt = "on";
    double seconds = 0, exposure = NAN;
    long samples = 0, width = 0, height = 0, supersample = REND_FRAME_SUPERSAMPLE_DEFAULT,
         accumulate = REND_SESSION_ACCUMULATE_DEFAULT;
    int deterministic = 0;
    app_opt opts[] = {
        {"--output", "-o", APP_OPT_STRING, &out},
        {"--seconds", NULL, APP_OPT_DOUBLE, &seconds, 0.001, 1e7},
        {"--samples", NULL, APP_OPT_INT, &samples, 1, 2e9},
        {"--width", NULL, APP_OPT_INT, &width, 1, 16384},
        {"--height", NULL, APP_OPT_INT, &height, 1, 16384},
        {"--camera", NULL, APP_OPT_STRING, &camera},
        {"--stats", NULL, APP_OPT_STRING, &stats},
        {"--sampler", NULL, APP_OPT_STRING, &sampler},
        {"--bounces", NULL, APP_OPT_STRING, &bounces},
        {"--gl", NULL, APP_OPT_STRING, &gl_name},
        {"--debug-meshes", NULL, APP_OPT_STRING, &debug_dir},
        {"--deterministic", NULL, APP_OPT_FLAG, &deterministic},
        {"--supersample", NULL, APP_OPT_INT, &supersample, 1, REND_FRAME_SUPERSAMPLE_MAX},
        {"--accumulate", NULL, APP_OPT_INT, &accumulate, 1, REND_SESSION_ACCUMULATE_MAX},
        {"--components", NULL, APP_OPT_STRING, &components},
        {"--residual", NULL, APP_OPT_STRING, &residual_opt},
        {"--exposure", NULL, APP_OPT_DOUBLE, &exposure, -64, 64},
    };
    const char *pos[1];
    int npos, rc = app_parse_options(cmd, argc, argv, opts, (int)(sizeof opts / sizeof opts[0]), pos, 1, &npos);
    if (rc < 0) return APP_EXIT_OK;
    if (rc) return rc;
    if (!out) return app_usage_error(cmd, "an output image is required (-o OUT.png or OUT.exr)");
    if (!ext_is(out, "exr") && !ext_is(out, "png")) return app_usage_error(cmd, "the output must end in .png or .exr");
    if (opts[1].seen && opts[2].seen) return app_usage_error(cmd, "give --seconds or --samples, not both");
    if (opts[3].seen != opts[4].seen) return app_usage_error(cmd, "give both --width and --height");
    if (strcmp(residual_opt, "on") != 0 && strcmp(residual_opt, "off") != 0)
        return app_usage_error(cmd, "--residual takes on or off");
    unsigned mask = components ? parse_components(components) : REND_FRAME_COMPONENTS_ALL;
    if (!mask)
        return app_usage_error(cmd, "--components takes a comma-separated list of direct, indirect, specular and "
                                    "emission, not '%s'", components);
    /* With --seconds the cache keeps sharpening past its JND until the time is up
     * (rend_session_desc.jnd_floor); otherwise it stops there, as --samples does. */
    /* ids_by_rays: no GL context (nor the driver's ~60 MB) until the final draw,
     * which keeps no copy of the one snapshot it draws (docs/memory.md). */
    rend_session_desc sd = {.supersample = (int)supersample, .max_tested = (uint64_t)samples, .ids_by_rays = 1,
                            .final_one_snapshot = 1,
                            .publish_debug = debug_dir != NULL, .jnd_floor = opts[1].seen ? 0.0f : -1.0f,
                            .sample_pixels = rend_session_sample_pixels((int)supersample, (int)accumulate)};
    if ((rc = app_session_options(cmd, sampler, gl_name, bounces, &sd)) != APP_EXIT_OK) return rc;
    /* Reproducible runs: a stop counted in leaf tests, not seconds, and no timing-based
     * calibration (auto picks its back ends by measured speed). */
    if (deterministic && !opts[2].seen) return app_usage_error(cmd, "--deterministic needs --samples N");
    if (deterministic && sampler && strcmp(sampler, "auto") == 0)
        return app_usage_error(cmd, "--deterministic cannot use --sampler auto (it calibrates by timing)");

    lm_error err = {{0}};
    scene *s = NULL;
    lm_result r = scene_load(&(scene_load_desc){.path = npos ? pos[0] : NULL, .require_light = 1}, &s, &err);
    if (r != LM_OK) return app_report(r, &err);
    /* The picture's exposure: the image written and what the cache judges (its JND
     * test sees the colours at it: cache_set_exposure). */
    if (isfinite(exposure)) s->exposure = (float)exposure;
    int ci = scene_find_camera(s, camera);
    if (ci < 0) {
        lm_fail(&err, LM_ERR_BAD_INPUT, "%s: no camera named '%s'", s->source, camera);
        scene_destroy(s);
        return app_report(LM_ERR_BAD_INPUT, &err);
    }
    scene_camera cam = s->cameras[ci];
    int w = width ? (int)width : cam.width, h = height ? (int)height : cam.height;
    if (deterministic && !sampler) sd.sampler.backend = SAMP_BACKEND_EMBREE;
    sd.scene = s;
    sd.camera = &cam;
    sd.width = w;
    sd.height = h;

    double t0 = lm_now_seconds();
    rend_session *rs = NULL;
    float *rgb = NULL;
    uint8_t *png = NULL;
    const cache_snapshot *snap = NULL;
    double limit = opts[1].seen ? seconds : DEFAULT_SECONDS_LIMIT;
    r = rend_session_create(&sd, &rs, &err);
    /* Nothing is drawn until the refinement ends: the ID pass's GL context is not
     * held meanwhile (docs/memory.md, "Sixth session"). */
    if (r == LM_OK) rend_session_release_gl(rs);
    /* The whole picture (not chosen terms) with --seconds: the residual from the
     * first snapshot on. */
    render_residual residual = {.s = s, .cam = &cam, .w = w, .h = h, .until = t0 + limit};
    const int with_residual = opts[1].seen && strcmp(residual_opt, "on") == 0 && mask == REND_FRAME_COMPONENTS_ALL;
    render_progress prog = {.t0 = t0, .limit = opts[1].seen ? seconds : 0, .tty = isatty(STDERR_FILENO),
                            .residual = with_residual ? &residual : NULL};
    if (r == LM_OK)
        r = rend_session_wait(rs, &(rend_session_wait_desc){.until = t0 + limit, .on_look = show_progress, .user = &prog},
                              &snap, &err);
    if (prog.shown) fputc('\n', stderr);
    /* The final snapshot is all the drawing needs: the cache, its samplers and
     * the Embree scene are freed before the renderer's images are made (the
     * 116k-triangle box's peak: docs/memory.md, "The cache gone before the final
     * draw"). */
    rend_session_retire_worker(rs);
    app_return_freed_memory();
    rgb = r == LM_OK ? malloc((size_t)w * (size_t)h * 3 * sizeof *rgb) : NULL;
    if (r == LM_OK && !rgb) r = lm_fail(&err, LM_ERR_NO_MEMORY, "out of memory for a %dx%d image", w, h);
    if (r == LM_OK && mask != REND_FRAME_COMPONENTS_ALL) {
        rend_frame *final = NULL;
        r = rend_session_renderer(rs, REND_SESSION_FINAL, &final, &err);
        if (r == LM_OK) rend_frame_set_components(final, mask);
    }
    if (r == LM_OK) r = rend_session_draw_accumulated(rs, REND_SESSION_FINAL, &cam, (int)accumulate, rgb, &err);
    rend_residual_info res = {0};
    int corrected = r == LM_OK && with_residual && !snap->failed;
    /* The residual's passes need the drawn picture, not the context that drew it:
     * LLVM, llvmpipe's threads and the renderer's images (~50 MB on Water) are
     * freed before they run with every core (docs/memory.md). --debug draws again. */
    if (corrected && !debug_dir) {
        rend_session_release_gl(rs);
        app_return_freed_memory();
    }
    if (corrected) r = residual_until(&residual, snap, t0, rgb, &res, &err);
    rend_residual_destroy(residual.rr);
    double elapsed = lm_now_seconds() - t0;
    if (r == LM_OK && debug_dir) r = write_debug_meshes(debug_dir, s, &cam, w, h, rs, rgb, snap, &err);
    /* What the statistics and the summary need is taken from the session, which is
     * then destroyed before the image is written: the image module (OpenImageIO,
     * 131 MB) is loaded only after the cache and the GL images are gone, so it does
     * not add to the peak (docs/memory.md). */
    cJSON *json = NULL;
    /* When the cache claimed convergence, apart from `seconds`, which also counts
     * the final picture's k×k supersampled draws (3.2 s of the 116k box's 15). */
    const double converged_s = r == LM_OK && snap && snap->converged_at > 0 ? snap->converged_at - t0 : 0.0;
    if (r == LM_OK && stats) {
        rend_session_info in;
        rend_session_get_info(rs, &in);
        json = app_stats_json(&(app_stats_desc){.command = "render", .scene = s->source, .width = w, .height = h,
                                                .supersample = (int)supersample, .seconds = elapsed,
                                                .first_image_seconds = -1, .converged_seconds = converged_s,
                                                .snap = snap, .id_seconds = in.id_seconds,
                                                .frame = &in.times[REND_SESSION_FINAL], .frames = 1,
                                                .residual = corrected ? &res : NULL});
        if (!json) r = lm_fail(&err, LM_ERR_NO_MEMORY, "out of memory for the statistics");
    }
    char summary[1024] = "", converged_at_text[48] = "";
    if (converged_s > 0) snprintf(converged_at_text, sizeof converged_at_text, " (at %.2f s)", converged_s);
    if (r == LM_OK) {
        const cache_stats *st = &snap->stats;
        uint64_t light = 0;
        for (uint32_t l = 0; l < st->light_count; ++l) light += st->lights[l].samples;
        snprintf(summary, sizeof summary,
                 "%dx%d, %.2f s, %s%s after %llu leaves tested; samples: %llu light, %llu indirect; %llu direct, "
                 "%llu indirect, %llu specular triangles; estimated mean dE %.2f, %.1f%% of the pixels above the JND it "
                 "refines to (dE %.3g), %.1f%% untested%s",
                 w, h, elapsed, snap->converged ? "converged" : "stopped", converged_at_text,
                 (unsigned long long)snap->tested,
                 (unsigned long long)light, (unsigned long long)st->indirect.samples,
                 (unsigned long long)cache_snapshot_leaf_count(&snap->direct),
                 (unsigned long long)cache_snapshot_leaf_count(&snap->indirect),
                 (unsigned long long)cache_snapshot_leaf_count(&snap->specular), snap->estimate.mean,
                 100.0 * snap->estimate.above_jnd, (double)snap->jnd, 100.0 * snap->estimate.untested,
                 snap->finished && !snap->converged && !snap->failed ? " (nothing left it can improve)" : "");
        if (corrected) {
            /* The estimate is unknown while a block has fewer samples than the
             * residual trusts (rend_residual.h): said so, not printed as nan. */
            char est[96];
            if (isfinite(res.est_relmse))
                snprintf(est, sizeof est, "estimated relMSE %.3g", res.est_relmse);
            else
                snprintf(est, sizeof est, "relMSE not estimated below %d samples a pixel",
                         REND_RESIDUAL_MIN_SAMPLES_DEFAULT);
            size_t len = strlen(summary);
            snprintf(summary + len, sizeof summary - len, "; then %u..%u path samples a pixel corrected %.1f%% of its blocks (%s)",
                     res.min_samples, res.max_samples, 100.0 * res.corrected, est);
        }
    }
    rend_session_destroy(rs);
    snap = NULL;
    if (r == LM_OK) {
        img_write_desc d = {.path = out, .width = w, .height = h, .channels = 3};
        if (ext_is(out, "png")) {
            png = malloc((size_t)w * (size_t)h * 3);
            if (!png) r = lm_fail(&err, LM_ERR_NO_MEMORY, "out of memory for a %dx%d image", w, h);
            tm_desc tm = {.exposure = s->exposure};
            if (png) tm_to_rgb8(&tm, rgb, 3, (size_t)w * (size_t)h, png);
            d.pixels8 = png;
        } else {
            d.pixels = rgb;
        }
        if (r == LM_OK) r = img_write(&d, &err);
    }
    if (r == LM_OK && json) r = app_write_json(stats, json, &err);
    cJSON_Delete(json);
    if (r == LM_OK) printf("wrote %s: %s\n", out, summary);
    free(png);
    free(rgb);
    scene_destroy(s);
    return r == LM_OK ? APP_EXIT_OK : app_report(r, &err);
}
