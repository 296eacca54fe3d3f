/* cmd_converge.c — `lumesh converge`: a scripted convergence run that reports
 * speed against error.
 *
 * The previewer runs as a user would see it: the clock starts when the scene is
 * loaded; the GL context, the ID pass, the sampler's calibration and the coarse
 * cache all count. At each snapshot time the latest published snapshot is drawn,
 * written (EXR, linear, and PNG, tone-mapped) and compared with the reference by
 * cmp_compare (every metric of `lumesh compare`). The refinement worker keeps
 * refining on its own thread meanwhile, so measuring costs it nothing but a
 * share of the machine. Once the cache has converged at the scene's JND it
 * refines on to lower ones (rend_session_desc.jnd_floor: state "below-jnd"); once
 * it has converged at the lowest, or has finished without (nothing left it can
 * do), the path-traced residual (rend_residual.h: the reference's transport) uses
 * the machine until each later snapshot, and the cached picture is corrected by it
 * (state "converged" or "finished", the residual's samples in spp_min/spp_max);
 * with --residual off those snapshots show the same image and are recorded at
 * their times without waiting. Before that the residual already runs beside the
 * refining cache, on threads of the lowest priority that take only the cycles
 * the worker leaves (rend_residual_desc.background; docs/cache.md, "The residual
 * beside the refining cache"), and corrects every snapshot.
 *
 * --methods adds peers, the reference renderer's estimators of the same
 * transport: its progressive path tracer and instant radiosity (ref_vpl.h). Each
 * then runs alone for the same times with every core, counted the same way (from
 * its creation, BVH build included), its clock paused while it is measured.
 * --vs-path-tracer is short for --methods cache,path-tracer.
 *
 * Output, all through temporary files renamed into place, so an interruption
 * (Ctrl-C: stops at once and still writes what was measured) leaves no partial
 * file: DIR/convergence.csv, DIR/convergence.json, DIR/convergence.png, the
 * snapshot images, and --stats.
 */
#define _POSIX_C_SOURCE 200809L
#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "mesh/cache/cache.h"
#include "sampling/reference.h"
#include "src/base/tonemap.h"
#include "src/cli/app_stats.h"
#include "src/cli/cli.h"
#include "src/cli/converge_internal.h"
#include "src/image/compare.h"
#include "src/image/image.h"
#include "src/render/rend_residual.h"
#include "src/render/rend_session.h"
#include "src/scene/scene.h"

/* Written by the SIGINT handler, read by the measuring loops and the path tracer. */
static volatile sig_atomic_t interrupted = 0;

static void on_sigint(int sig)
{
    (void)sig;
    if (interrupted) _exit(130); /* a second Ctrl-C: leave at once */
    interrupted = 1;
}

/* "0.1,0.2,1" into increasing positive times ≤ limit (limit itself added last). */
static int parse_times(const char *list, double limit, double *out, int *count)
{
    static const double defaults[] = {0.1, 0.2, 0.5, 1, 2, 5, 10, 20, 50, 100, 200, 500, 1000, 2000, 5000, 10000};
    int n = 0;
    if (list) {
        const char *p = list;
        while (*p) {
            char *end;
            double v = strtod(p, &end);
            if (end == p || !isfinite(v) || v <= 0 || (n && v <= out[n - 1]) || n >= MAX_SNAPSHOTS - 1) return 0;
            if (v <= limit + 1e-9) out[n++] = v;
            p = end;
            if (*p == ',') ++p;
            else if (*p) return 0;
        }
    } else {
        for (size_t i = 0; i < sizeof defaults / sizeof defaults[0]; ++i)
            if (defaults[i] < limit - 1e-9) out[n++] = defaults[i];
    }
    if (!n || out[n - 1] < limit - 1e-9) out[n++] = limit;
    *count = n;
    return 1;
}

static void progress(const conv_ctx *c, const char *method, double t, const conv_row *last, int final)
{
    if (!c->tty) return;
    char bar[APP_PROGRESS_WIDTH + 1];
    app_progress_bar(t / c->seconds, bar);
    fprintf(stderr, "\r%-12s [%s] %6.2f/%.2f s", method, bar, t, c->seconds);
    if (last) fprintf(stderr, "  dE %.3f  relMSE %.3g   ", last->m.delta_e_mean, last->m.relmse);
    if (final) fputc('\n', stderr);
    fflush(stderr);
}

/* Writes the image (EXR and PNG) into DIR and compares it with the reference. */
static lm_result measure(conv_ctx *c, const char *prefix, const float *rgb, conv_row *row, lm_error *err)
{
    size_t n = (size_t)c->w * (size_t)c->h;
    snprintf(row->image, sizeof row->image, "%s-%09.3fs.exr", prefix, row->target);
    char path[SCENE_PATH_MAX + 80];
    snprintf(path, sizeof path, "%s/%s", c->dir, row->image);
    lm_result r = img_write(&(img_write_desc){.path = path, .width = c->w, .height = c->h, .channels = 3,
                                              .pixels = rgb},
                            err);
    uint8_t *png = r == LM_OK ? malloc(n * 3) : NULL;
    if (r == LM_OK && !png) r = lm_fail(err, LM_ERR_NO_MEMORY, "out of memory for a %dx%d image", c->w, c->h);
    if (r == LM_OK) {
        tm_to_rgb8(&(tm_desc){.exposure = c->exposure}, rgb, 3, n, png);
        size_t len = strlen(path);
        memcpy(path + len - 3, "png", 3);
        r = img_write(&(img_write_desc){.path = path, .width = c->w, .height = c->h, .channels = 3, .pixels8 = png},
                      err);
    }
    free(png);
    if (r != LM_OK) return r;
    img_image a = {.width = c->w, .height = c->h, .channels = 3, .pixels = (float *)rgb};
    return cmp_compare(&(cmp_desc){.exposure = c->exposure, .name_a = row->image, .name_b = "the reference"}, &a,
                       &c->ref, &row->m, NULL, err);
}

static void snapshot_samples(const conv_ctx *c, const cache_snapshot *snap, conv_row *row)
{
    const cache_stats *st = &snap->stats;
    for (uint32_t l = 0; l < c->light_count; ++l) row->samples[l] = st->lights[l].samples;
    row->samples[c->light_count] = st->direct.samples;
    row->samples[c->light_count + 1] = st->indirect.samples;
    row->samples[c->light_count + 2] = st->specular.samples;
    row->tested = snap->tested;
    /* The estimate is a mean over the pixels that see a triangle; the background is exact. */
    double seen = (double)c->w * (double)c->h;
    double share = seen > 0.0 && snap->estimate.pixels < seen ? snap->estimate.pixels / seen : 1.0;
    row->est_delta_e = snap->estimate.mean * share;
    row->est_above_jnd = snap->estimate.above_jnd * share;
    row->est_untested = snap->estimate.untested * share;
    row->est_measured = snap->estimate.measured;
    row->jnd = snap->jnd;
}

/* published: the snapshot's publication on the previewer's clock. */
static void keep_final(conv_ctx *c, const cache_snapshot *snap, double published)
{
    c->final_seconds = published;
    c->final = *snap;
    memcpy(c->final_lights, snap->stats.lights, c->light_count * sizeof *c->final_lights);
    c->final.stats.lights = c->final_lights;
    /* The leaf arrays belong to the worker's buffers: only their counts are kept
     * (listed and whole: cache_snapshot_leaf_count). */
    c->final.direct = (cache_snapshot_mesh){.triangle_count = snap->direct.triangle_count,
                                                .whole_count = snap->direct.whole_count};
    c->final.indirect = (cache_snapshot_mesh){.triangle_count = snap->indirect.triangle_count,
                                                .whole_count = snap->indirect.whole_count};
    c->final.specular = (cache_snapshot_mesh){.triangle_count = snap->specular.triangle_count,
                                                .whole_count = snap->specular.whole_count};
    c->final.lights = NULL;
    c->final.light_mesh_count = 0;
    c->have_final = 1;
}

/* The previewer's clock: seconds since the scene was loaded, less the time it
 * stood still (measuring_begin .. measuring_end). */
static double clock_of(const conv_ctx *c, double t0) { return lm_now_seconds() - t0 - c->stopped; }

/* A snapshot's image drawn and measured with the clock standing still and the
 * refinement paused, as the peers' clock is paused while theirs are (run_peer):
 * the measurement's draws (s×s samples a pixel, k jittered draws once converged,
 * on llvmpipe's threads) and files are the protocol's cost, not the previewer's.
 * Running beside the worker they took its cores: Water's cache at 2 s had tested
 * 26,432 leaves (relMSE 5.3e-4) after snapshots at 0.1, 0.25, 0.5 and 1 s, and
 * 41,792 (1.3e-4) with none before (docs/cache.md, "Water's first seconds"). */
static double measuring_begin(rend_session *rs)
{
    cache_worker_pause(rend_session_worker(rs));
    return lm_now_seconds();
}

static void measuring_end(conv_ctx *c, rend_session *rs, double begun)
{
    c->stopped += lm_now_seconds() - begun;
    cache_worker_resume(rend_session_worker(rs));
}

/* The first image, as a viewer shows it: the session's preview renderer (one
 * sample a pixel), made while the worker makes the coarse cache, draws it as soon
 * as the worker publishes it. The ID pass and every measurement come after, so
 * they cannot delay it. (Compiling the shaders beforehand on a stand-in triangle
 * measured no faster: the worker and the compiler then share the 2 cores.) */
static lm_result first_image(conv_ctx *c, rend_session *rs, double t0, float *rgb, lm_error *err)
{
    const scene_camera *cam = &c->s->cameras[c->cam];
    /* As the viewer does: the worker publishes the first snapshot and rests until
     * it is drawn, so the draw has both cores (docs/viewer.md). */
    cache_worker_request_pause(rend_session_worker(rs));
    rend_frame *preview = NULL;
    lm_result r = rend_session_renderer(rs, REND_SESSION_PREVIEW, &preview, err);
    /* The geometry alone first, as the viewer shows it until the first snapshot
     * (view_app.c): its material image depends on the camera and the scene only,
     * and the draw with the snapshot keeps it. On the 116k box that pass is 26-48
     * ms of the first draw; drawn meanwhile, the first image came 40-70 ms sooner
     * (docs/renderer.md, "The geometry drawn while the worker starts"). */
    if (r == LM_OK) r = rend_session_draw(rs, REND_SESSION_PREVIEW, cam, NULL, err);
    c->phase[1] = lm_now_seconds() - t0;
    const cache_snapshot *snap = NULL;
    if (r == LM_OK)
        r = rend_session_wait(rs, &(rend_session_wait_desc){.first = 1, .stop = &interrupted, .nap = 0.001}, &snap,
                              err);
    c->phase[2] = lm_now_seconds() - t0;
    /* As the viewer draws it: the highlights per pixel one draw later
     * (rend_frame_defer_highlights; docs/renderer.md, "The first image's
     * highlights one draw later"). */
    if (r == LM_OK && snap) {
        rend_frame_defer_highlights(preview);
        r = rend_session_draw(rs, REND_SESSION_PREVIEW, cam, NULL, err); /* a viewer shows it from the GPU */
        c->first_image = lm_now_seconds() - t0;
        c->frames++;
    }
    if (r == LM_OK && snap) {
        /* Kept as DIR/first-image.exr: what the user saw first. Read back and
         * written with the worker still resting and the clock standing still:
         * the protocol's cost (74 ms on Water at 640×480, on the clock and
         * beside the worker until the nineteenth session), not the previewer's. */
        const double begun = lm_now_seconds();
        char path[SCENE_PATH_MAX + 32];
        snprintf(path, sizeof path, "%s/first-image.exr", c->dir);
        rend_frame_defer_highlights(preview); /* read back as it was shown, not drawn again */
        r = rend_session_draw(rs, REND_SESSION_PREVIEW, cam, rgb, err);
        if (r == LM_OK)
            r = img_write(&(img_write_desc){.path = path, .width = c->w, .height = c->h, .channels = 3, .pixels = rgb},
                          err);
        /* The measurement's renderer (s×s samples a pixel, like the
         * reference's box filter; 60 ms on llvmpipe), made here too: a viewer
         * never makes it. Made later, it waited on the clock for the worker's
         * step to end (a pause waits for that), so the first rows were measured
         * late: Water's 0.1 and 0.25 s rows at 0.39 s, against the path tracer
         * at 0.1 and 0.25 s (docs/renderer.md, "The first rows on time"). */
        if (r == LM_OK) r = rend_session_renderer(rs, REND_SESSION_FINAL, NULL, err);
        c->stopped += lm_now_seconds() - begun;
    }
    cache_worker_resume(rend_session_worker(rs)); /* drawn, or none came: refinement goes on */
    rend_session_drop_renderer(rs, REND_SESSION_PREVIEW);
    return r;
}

static lm_result residual_make(conv_ctx *c, rend_residual **res, lm_error *err)
{
    return rend_residual_create(&(rend_residual_desc){.scene = c->s, .camera = &c->s->cameras[c->cam], .width = c->w,
                                                      .height = c->h, .transport = c->transport,
                                                      .bounces = c->ref_bounces, .glossy = c->glossy,
                                                      .seed = c->residual_seed,
                                                      .background = 1},
                                res, err);
}

/* A snapshot's picture corrected by the path-traced residual as it stands (run
 * by the caller): the cached picture drawn (k jittered draws accumulated) once
 * per snapshot generation. */
static lm_result residual_image(conv_ctx *c, rend_session *rs, const cache_snapshot *snap, int k, rend_residual *res,
                                float **cached, uint64_t *cached_generation, float *rgb, conv_row *row, lm_error *err)
{
    const scene_camera *cam = &c->s->cameras[c->cam];
    size_t n = (size_t)c->w * (size_t)c->h;
    lm_result r = LM_OK;
    if (!*cached && !(*cached = malloc(n * 3 * sizeof **cached)))
        return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory for a %dx%d image", c->w, c->h);
    if (*cached_generation != snap->generation) {
        r = rend_session_draw_accumulated(rs, REND_SESSION_FINAL, cam, k, *cached, err);
        if (r != LM_OK) return r;
        *cached_generation = snap->generation;
    }
    rend_residual_info info;
    rend_residual_apply(res, *cached, rgb, &info);
    row->spp_min = info.min_samples;
    row->spp_max = info.max_samples;
    row->rays = info.rays;
    row->residual_weight = info.mean_weight;
    row->residual_corrected = info.corrected;
    row->residual_est = info.est_relmse;
    return LM_OK;
}

/* The previewer: a render session (worker first, then the GL context, the first
 * image, the ID pass, the offline renderer); snapshots at c->times. */
static lm_result run_lumesh(conv_ctx *c, const rend_session_desc *sd, double t0, conv_run *run, lm_error *err)
{
    rend_session *rs = NULL;
    float *rgb = malloc((size_t)c->w * (size_t)c->h * 3 * sizeof *rgb);
    lm_result r = rgb ? LM_OK : lm_fail(err, LM_ERR_NO_MEMORY, "out of memory for a %dx%d image", c->w, c->h);
    const scene_camera *cam = &c->s->cameras[c->cam];
    /* The worker starts first: it makes the coarse cache while this thread makes the
     * GL context and the renderer; the ID pass, whose pixel counts the worker needs
     * only to refine, follows the first image. */
    if (r == LM_OK) r = rend_session_create(sd, &rs, err);
    else rend_session_early_gl_end(sd->early_gl); /* no session to take it */
    c->phase[0] = lm_now_seconds() - t0;
    if (r == LM_OK) r = first_image(c, rs, t0, rgb, err);
    if (r == LM_OK) r = rend_session_set_pixels(rs, cam, err);
    rend_session_info in;
    rend_session_get_info(rs, &in);
    c->id_seconds = in.id_seconds;
    /* The measured images: the offline renderer, made with the first image
     * (first_image); when no snapshot came, here, with the clock standing still. */
    if (r == LM_OK && c->first_image < 0) {
        const double begun = measuring_begin(rs);
        r = rend_session_renderer(rs, REND_SESSION_FINAL, NULL, err);
        measuring_end(c, rs, begun);
    }
    const cache_snapshot *snap = NULL;
    /* The path-traced residual (rend_residual.h) runs until each snapshot's
     * time: beside the refining worker on the cycles it leaves, and with the
     * whole machine once the cache has nothing left to do. The cached picture,
     * drawn once per snapshot generation, is corrected by it. */
    rend_residual *res = NULL;
    float *cached = NULL;
    uint64_t cached_generation = 0;
    for (int i = 0; r == LM_OK && i < c->time_count && !interrupted; ++i) {
        conv_row *row = &run->rows[run->count];
        memset(row, 0, sizeof *row);
        row->target = c->times[i];
        /* Wait for the time, unless the cache has nothing more to do. */
        lm_result ar;
        for (;;) {
            ar = rend_session_acquire(rs, &snap, err);
            if (interrupted || ar != LM_OK || (snap && snap->finished)) break;
            double now = clock_of(c, t0);
            if (now >= row->target) break;
            if (snap && c->residual && (res || !snap->owed)) {
                /* Beside the refining worker, in the background, until the
                 * snapshot's time; then the latest snapshot is taken. Not
                 * before the first image's values are gathered again: until then
                 * the picture is the quick start's, which its first samples cannot
                 * correct yet, and the worker's regathers decide when it changes
                 * (the Veach door's 2 s row: docs/cache.md, "The refining sampler's
                 * plain count"). */
                if (!res && (ar = residual_make(c, &res, err)) != LM_OK) break;
                rend_residual_run(res, &interrupted, t0 + c->stopped + row->target);
                continue;
            }
            progress(c, run->method, now, run->count ? &run->rows[run->count - 1] : NULL, 0);
            lm_sleep_seconds(now + 0.02 < row->target ? 0.010 : 0.001);
        }
        if (interrupted) break;
        if (ar != LM_OK) {
            r = ar;
            break;
        }
        /* On the clock: a paused worker publishes nothing, so a snapshot (and a
         * convergence) came after every stop so far; the one acquired again
         * (finished) keeps the time it was first given. */
        const double published = !snap ? 0.0
                                 : c->have_final && snap->generation == c->final.generation
                                     ? c->final_seconds
                                     : snap->published_at - t0 - c->stopped;
        if (c->converged_at < 0 && snap && snap->converged) c->converged_at = snap->converged_at - t0 - c->stopped;
        if (snap && snap->finished) {
            /* Converged at the JND it refined to last, or stopped above it: the
             * machine is the residual's until the snapshot's time, on the clock. */
            row->state = snap->converged && cache_estimate_converged(&snap->estimate) ? ROW_CONVERGED : ROW_FINISHED;
            if (c->residual && !res) r = residual_make(c, &res, err);
            if (r != LM_OK) break;
            if (res) rend_residual_run(res, &interrupted, t0 + c->stopped + row->target);
            if (interrupted) break;
            row->seconds = fmax(row->target, clock_of(c, t0));
        } else {
            row->state = !snap ? ROW_NO_SNAPSHOT : snap->converged ? ROW_BELOW_JND : ROW_REFINING;
            row->seconds = clock_of(c, t0);
        }
        if (snap) snapshot_samples(c, snap, row);
        /* A converged cache changes slowly: a resting view accumulates jittered
         * frames of it (rend_session_draw_accumulated). While refining, one draw. */
        int k = snap && snap->converged ? c->accumulate : 1;
        const double begun = measuring_begin(rs);
        if (snap && res) {
            r = residual_image(c, rs, snap, k, res, &cached, &cached_generation, rgb, row, err);
        } else {
            r = rend_session_draw_accumulated(rs, REND_SESSION_FINAL, cam, k, rgb, err);
        }
        c->frames++;
        rend_session_get_info(rs, &in);
        if (r == LM_OK) c->frame_times = in.times[REND_SESSION_FINAL];
        if (r == LM_OK) r = measure(c, run->method, rgb, row, err);
        measuring_end(c, rs, begun);
        if (r == LM_OK) {
            run->count++;
            if (snap) keep_final(c, snap, published);
            progress(c, run->method, row->seconds, row, 0);
        }
    }
    progress(c, run->method, run->count ? run->rows[run->count - 1].seconds : 0, NULL, 1);
    rend_residual_destroy(res);
    free(cached);
    rend_session_destroy(rs);
    free(rgb);
    return r;
}

/* A peer (the path tracer, instant radiosity: the reference renderer's
 * estimators of the same transport) for the same times, every core, its clock
 * paused while measured. */
static lm_result run_peer(conv_ctx *c, uint32_t seed, conv_run *run, lm_error *err)
{
    double t0 = lm_now_seconds();
    ref_renderer *pt = NULL;
    float *rgb = malloc((size_t)c->w * (size_t)c->h * 3 * sizeof *rgb);
    lm_result r = rgb ? LM_OK : lm_fail(err, LM_ERR_NO_MEMORY, "out of memory for a %dx%d image", c->w, c->h);
    if (r == LM_OK)
        r = ref_create(&(ref_desc){.scene = c->s, .camera = c->cam, .width = c->w, .height = c->h,
                                   .transport = c->transport, .bounces = c->ref_bounces, .glossy = c->glossy,
                                   .seed = seed, .estimator = run->estimator, .vpl_paths = c->vpl_paths,
                                   .vpl_per_sample = c->vpl_per_sample, .vpl_clamp = c->vpl_clamp,
                                   .vpl_visibility = run->visibility, .gl_platform = c->gl_platform},
                       &pt, err);
    double setup = lm_now_seconds() - t0;
    ref_stats st = {0};
    for (int i = 0; r == LM_OK && i < c->time_count && !interrupted; ++i) {
        conv_row *row = &run->rows[run->count];
        memset(row, 0, sizeof *row);
        row->target = c->times[i];
        for (;;) {
            ref_get_stats(pt, &st);
            double spent = setup + st.seconds;
            if (spent >= row->target || interrupted) break;
            ref_render_pass(pt, &interrupted, lm_now_seconds() + (row->target - spent));
            progress(c, run->method, setup + st.seconds, run->count ? &run->rows[run->count - 1] : NULL, 0);
        }
        if (interrupted) break;
        ref_get_stats(pt, &st);
        row->seconds = setup + st.seconds;
        row->spp_min = st.min_samples;
        row->spp_max = st.max_samples;
        row->rays = st.rays;
        row->vpls = st.vpls;
        row->vpl_seconds = st.vpl_seconds;
        row->ism_maps = st.ism_maps;
        row->ism_seconds = st.ism_seconds;
        ref_get_image(pt, rgb, NULL, NULL);
        r = measure(c, run->method, rgb, row, err);
        if (r == LM_OK) {
            run->count++;
            progress(c, run->method, row->seconds, row, 0);
        }
    }
    progress(c, run->method, run->count ? run->rows[run->count - 1].seconds : 0, NULL, 1);
    ref_destroy(pt);
    free(rgb);
    return r;
}

/* ---- the command ------------------------------------------------------------------- */

/* The transport to measure against, from the reference's header (lumesh
 * reference writes lumesh:transport and lumesh:bounces): the path tracer
 * follows it, and unless --bounces was given the previewer shows as many
 * bounces (model K), or chooses them (full: auto). A reference that does not
 * say is taken as the model transport's default, one bounce; --transport
 * (`given`, NULL: not given) says otherwise (model: one bounce unless the file
 * says how many). */
static int reference_transport(conv_ctx *c, const char *ref_path, const char *given, int bounces_given,
                               rend_session_desc *sd)
{
    const char *tr = img_attribute(&c->ref, "lumesh:transport"), *nb = img_attribute(&c->ref, "lumesh:bounces");
    if (given) { /* --transport: the file does not say, or says wrong */
        if (strcmp(given, "model") != 0 && strcmp(given, "full") != 0)
            return app_usage_error(c->cmd, "--transport is 'model' or 'full', not '%s'", given);
        if (tr && strcmp(tr, given) != 0)
            fprintf(stderr, "lumesh: %s says it is of the %s transport; measuring against it as --transport %s\n",
                    ref_path, tr, given);
        tr = given;
        if (strcmp(given, "model") == 0 && !nb) nb = "1";
    }
    c->transport = REF_TRANSPORT_MODEL;
    c->ref_bounces = 1;
    if (tr && strcmp(tr, "full") == 0) {
        c->transport = REF_TRANSPORT_FULL;
        c->ref_bounces = 0;
    } else if (tr && strcmp(tr, "model") == 0 && nb) {
        char *end = NULL;
        long k = strtol(nb, &end, 10);
        if (end == nb || *end || k < 0 || k > 64) {
            fprintf(stderr, "lumesh: %s: lumesh:bounces is '%s', not a bounce count 0..64\n", ref_path, nb);
            return APP_EXIT_BAD_INPUT;
        }
        c->ref_bounces = k == 0 ? REF_BOUNCES_NONE : (int)k;
    } else if (tr) {
        fprintf(stderr, "lumesh: %s: lumesh:transport is '%s', not 'model' or 'full'\n", ref_path, tr);
        return APP_EXIT_BAD_INPUT;
    }
    /* What glossy materials reflect: the full transport everything; the model
     * transport the room too, unless the file is older than that (no
     * lumesh:glossy) or says otherwise. The previewer models the same. */
    const char *gl = img_attribute(&c->ref, "lumesh:glossy");
    c->glossy = REF_GLOSSY_INDIRECT;
    if (gl && strcmp(gl, "direct") != 0 && strcmp(gl, "indirect") != 0) {
        fprintf(stderr, "lumesh: %s: lumesh:glossy is '%s', not 'direct' or 'indirect'\n", ref_path, gl);
        return APP_EXIT_BAD_INPUT;
    }
    if (c->transport == REF_TRANSPORT_MODEL && (!gl || strcmp(gl, "direct") == 0)) c->glossy = REF_GLOSSY_DIRECT;
    sd->glossy = c->glossy == REF_GLOSSY_DIRECT ? CACHE_GLOSSY_DIRECT : CACHE_GLOSSY_INDIRECT;
    int model_k = c->ref_bounces == REF_BOUNCES_NONE ? 0 : c->ref_bounces;
    if (!bounces_given)
        sd->bounces = c->transport == REF_TRANSPORT_FULL ? CACHE_BOUNCES_AUTO : model_k < 1 ? 1 : model_k;
    c->bounces = sd->bounces ? sd->bounces : CACHE_BOUNCES_AUTO;
    char mine[32];
    if (c->bounces == CACHE_BOUNCES_AUTO)
        snprintf(mine, sizeof mine, "auto");
    else
        snprintf(mine, sizeof mine, "%d", c->bounces);
    if (c->transport == REF_TRANSPORT_FULL)
        snprintf(c->transport_note, sizeof c->transport_note,
                 "reference: full transport; path tracer: full transport; previewer: %s bounces%s", mine,
                 bounces_given ? " (--bounces)" : "");
    else
        snprintf(c->transport_note, sizeof c->transport_note,
                 "reference: model transport, %d bounce%s%s, glossy materials reflect %s%s; path tracer: the same; "
                 "previewer: %s bounces%s",
                 model_k, model_k == 1 ? "" : "s", tr ? "" : " (the file does not say: the default)",
                 c->glossy == REF_GLOSSY_DIRECT ? "the lights only" : "the lights and the room",
                 gl ? "" : " (the file does not say: made before the room was)", mine, bounces_given ? " (--bounces)" : "");
    return APP_EXIT_OK;
}

/* --methods: "cache,vpl,bdir,path-tracer" into runs, the cache first (it is timed
 * with the machine to itself, as are the others after it), each at most once.
 * Returns the number of runs, or 0 after a usage error (*rc set). */
static int parse_methods(const app_command *cmd, const char *list, int single, conv_run *runs, int *rc)
{
    static const struct {
        const char *name, *column;
        int peer;
        ref_estimator estimator;
        ref_vpl_visibility visibility;
    } known[] = {{"cache", "lumesh", 0, REF_ESTIMATOR_PATHS, REF_VPL_VISIBILITY_RAYS},
                 {"vpl", "vpl", 1, REF_ESTIMATOR_VPL, REF_VPL_VISIBILITY_RAYS},
                 {"bdir", "bdir", 1, REF_ESTIMATOR_BDIR, REF_VPL_VISIBILITY_RAYS},
                 {"vpl-ism", "vpl-ism", 1, REF_ESTIMATOR_VPL, REF_VPL_VISIBILITY_ISM},
                 {"bdir-ism", "bdir-ism", 1, REF_ESTIMATOR_BDIR, REF_VPL_VISIBILITY_ISM},
                 {"path-tracer", "path-tracer", 1, REF_ESTIMATOR_PATHS, REF_VPL_VISIBILITY_RAYS}};
    enum { KNOWN = sizeof known / sizeof known[0] };
    int want[KNOWN] = {0}, n = 0;
    for (const char *p = list; *p;) {
        size_t len = strcspn(p, ",");
        int k = 0;
        while (k < KNOWN && !(strlen(known[k].name) == len && strncmp(p, known[k].name, len) == 0)) ++k;
        if (k == KNOWN || want[k]) {
            *rc = app_usage_error(cmd,
                                  "--methods takes each of cache, vpl, bdir, vpl-ism, bdir-ism, path-tracer at most "
                                  "once, separated by commas ('%.*s' %s)", (int)len, p, k == KNOWN ? "is not one" : "is repeated");
            return 0;
        }
        want[k] = 1;
        p += len + (p[len] == ',');
    }
    for (int k = 0; k < KNOWN; ++k)
        if (want[k]) {
            runs[n].method = k == 0 && single ? "lumesh-single-mesh" : known[k].column;
            runs[n].peer = known[k].peer;
            runs[n].estimator = known[k].estimator;
            runs[n].visibility = known[k].visibility;
            n++;
        }
    if (n == 0) *rc = app_usage_error(cmd, "--methods names no method");
    return n;
}

int cmd_converge(const app_command *cmd, int argc, char **argv)
{
    const char *ref_path = NULL, *dir = NULL, *sampler = NULL, *gl_name = NULL, *list = NULL, *camera = NULL,
               *stats_path = NULL, *bounces = NULL, *transport = NULL, *residual = "on", *methods = NULL,
               *vpl_clamp = NULL;
    long vpl_paths = 0, vpl_per_sample = 0;
    double seconds = 0, exposure = NAN;
    long supersample = REND_FRAME_SUPERSAMPLE_DEFAULT, accumulate = REND_SESSION_ACCUMULATE_DEFAULT;
    long seed = 1; /* not lumesh reference's default 0: the same seed would correlate the two images */
    int vs_pt = 0, single = 0;
    app_opt opts[] = {
        {"--reference", NULL, APP_OPT_STRING, &ref_path},
        {"--seconds", NULL, APP_OPT_DOUBLE, &seconds, 0.001, 1e5},
        {"--out", NULL, APP_OPT_STRING, &dir},
        {"--exposure", NULL, APP_OPT_DOUBLE, &exposure, -64, 64},
        {"--snapshots", NULL, APP_OPT_STRING, &list},
        {"--vs-path-tracer", NULL, APP_OPT_FLAG, &vs_pt},
        {"--single-mesh", NULL, APP_OPT_FLAG, &single},
        {"--camera", NULL, APP_OPT_STRING, &camera},
        {"--stats", NULL, APP_OPT_STRING, &stats_path},
        {"--seed", NULL, APP_OPT_INT, &seed, 0, 4294967295.0},
        {"--supersample", NULL, APP_OPT_INT, &supersample, 1, REND_FRAME_SUPERSAMPLE_MAX},
        {"--accumulate", NULL, APP_OPT_INT, &accumulate, 1, REND_SESSION_ACCUMULATE_MAX},
        {"--sampler", NULL, APP_OPT_STRING, &sampler},
        {"--gl", NULL, APP_OPT_STRING, &gl_name},
        {"--bounces", NULL, APP_OPT_STRING, &bounces},
        {"--transport", NULL, APP_OPT_STRING, &transport},
        {"--residual", NULL, APP_OPT_STRING, &residual},
        {"--methods", NULL, APP_OPT_STRING, &methods},
        {"--vpl-paths", NULL, APP_OPT_INT, &vpl_paths, 1, 1 << 22},
        {"--vpl-per-sample", NULL, APP_OPT_INT, &vpl_per_sample, 1, 1 << 16},
        {"--vpl-clamp", NULL, APP_OPT_STRING, &vpl_clamp},
    };
    const char *pos[1];
    int npos, rc = app_parse_options(cmd, argc, argv, opts, (int)(sizeof opts / sizeof opts[0]), pos, 1, &npos);
    if (rc < 0) return APP_EXIT_OK;
    if (rc) return rc;
    if (!ref_path || !dir || !opts[1].seen)
        return app_usage_error(cmd, "--reference, --seconds and --out are required");
    rend_session_desc sd = {.order = REND_SESSION_WORKER_FIRST, .single_mesh = single,
                            .supersample = (int)supersample, .first_budget = REND_SESSION_FIRST_BUDGET_VIEWER,
                            .sample_pixels = rend_session_sample_pixels((int)supersample, (int)accumulate)};
    if ((rc = app_session_options(cmd, sampler, gl_name, bounces, &sd)) != APP_EXIT_OK) return rc;
    static conv_ctx c; /* large (rows, statistics): not on the stack */
    static conv_run runs[MAX_METHODS];
    memset(&c, 0, sizeof c);
    memset(runs, 0, sizeof runs);
    if (methods && vs_pt) return app_usage_error(cmd, "--vs-path-tracer is short for --methods cache,path-tracer: give one");
    const int nmethods = parse_methods(cmd, methods ? methods : vs_pt ? "cache,path-tracer" : "cache", single, runs, &rc);
    if (nmethods == 0) return rc;
    c.vpl_paths = (int)vpl_paths;
    c.gl_platform = sd.gl_platform;
    c.vpl_per_sample = (int)vpl_per_sample;
    if (vpl_clamp) {
        char *end = NULL;
        double v = strcmp(vpl_clamp, "none") == 0 ? REF_VPL_NO_CLAMP : strtod(vpl_clamp, &end);
        if ((end && (end == vpl_clamp || *end)) || !(v == REF_VPL_NO_CLAMP || (v > 0.0 && v < 1.0)))
            return app_usage_error(cmd, "--vpl-clamp takes a fraction of the scene's size in (0, 1), or none");
        c.vpl_clamp = (float)v;
    }
    c.cmd = cmd;
    c.dir = dir;
    c.seconds = seconds;
    c.supersample = (int)supersample;
    c.accumulate = (int)accumulate;
    c.residual = strcmp(residual, "on") == 0;
    if (!c.residual && strcmp(residual, "off") != 0) return app_usage_error(cmd, "--residual takes on or off");
    c.residual_seed = (uint32_t)seed ^ 0x5eed0001u; /* not the path tracer's: independent of it */
    c.first_image = c.converged_at = -1;
    c.phase[0] = c.phase[1] = c.phase[2] = -1;
    if (!parse_times(list, seconds, c.times, &c.time_count))
        return app_usage_error(cmd, "--snapshots takes increasing positive seconds separated by commas, "
                                    "e.g. 0.1,0.5,1,5");

    lm_error err = {{0}};
    /* The GL context is made while the reference is read and the scene loads
     * (rend_session_early_gl: the driver's start then costs the first image
     * nothing); without the thread, the session makes it as before. */
    const double t_start = lm_now_seconds();
    rend_session_early_gl *early = NULL;
    if (rend_session_early_gl_start(sd.gl_platform, &early, &err) != LM_OK) early = NULL;
    lm_result r = img_read(ref_path, &c.ref, &err);
    c.load[0] = lm_now_seconds() - t_start;
    if (r == LM_OK) rend_session_early_gl_size(early, c.ref.width, c.ref.height); /* the first image's size */
    if (r != LM_OK) {
        rend_session_early_gl_end(early);
        return app_report(r, &err);
    }
    if ((rc = reference_transport(&c, ref_path, transport, bounces != NULL, &sd)) != APP_EXIT_OK) {
        rend_session_early_gl_end(early);
        img_free(&c.ref);
        return rc;
    }
    r = scene_load(&(scene_load_desc){.path = npos ? pos[0] : NULL, .require_light = 1}, &c.s, &err);
    double t0 = lm_now_seconds(); /* the clock starts with the scene loaded */
    c.load[1] = t0 - t_start;
    if (r != LM_OK) {
        rend_session_early_gl_end(early);
        img_free(&c.ref);
        return app_report(r, &err);
    }
    /* The exposure shown and measured at (the cache's tests judge the colours at it). */
    if (isfinite(exposure)) c.s->exposure = (float)exposure;
    sd.early_gl = early; /* the session's now (a wait for it counts: it is after t0) */
    c.cam = scene_find_camera(c.s, camera);
    c.w = c.ref.width;
    c.h = c.ref.height;
    c.exposure = c.s->exposure;
    c.light_count = scene_light_count(c.s);
    if (c.cam < 0)
        r = lm_fail(&err, LM_ERR_BAD_INPUT, "%s: no camera named '%s'", c.s->source, camera);
    else if (c.light_count + 3 > MAX_MESHES)
        r = lm_fail(&err, LM_ERR_UNSUPPORTED, "%s: converge reports at most %d lights", c.s->source, MAX_MESHES - 3);
    if (r == LM_OK) r = app_make_dir(dir, &err);
    sd.scene = c.s;
    if (c.cam >= 0) sd.camera = &c.s->cameras[c.cam]; /* the specular mesh's eye */
    sd.width = c.w;
    sd.height = c.h;
    c.tty = isatty(STDERR_FILENO);

    struct sigaction sa, old;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_sigint;
    sigemptyset(&sa.sa_mask);
    sigaction(SIGINT, &sa, &old);
    int nrun = 0;
    if (r == LM_OK && !runs[0].peer) {
        r = run_lumesh(&c, &sd, t0, &runs[0], &err);
        nrun++;
    } else {
        rend_session_early_gl_end(early); /* no session took it */
    }
    for (; r == LM_OK && nrun < nmethods && !interrupted; ++nrun) r = run_peer(&c, (uint32_t)seed, &runs[nrun], &err);
    int measured = 0;
    for (int k = 0; k < nrun; ++k) measured += runs[k].count;
    /* Whatever was measured is written, also after Ctrl-C. */
    cJSON *stats = NULL;
    if (c.have_final)
        stats = app_stats_json(&(app_stats_desc){.command = "converge", .scene = c.s->source, .width = c.w,
                                                 .height = c.h, .supersample = c.supersample,
                                                 .seconds = c.final_seconds,
                                                 .first_image_seconds = c.first_image,
                                                 .converged_seconds = c.converged_at > 0 ? c.converged_at : 0,
                                                 .snap = &c.final,
                                                 .id_seconds = c.id_seconds, .frame = &c.frame_times,
                                                 .frames = c.frames});
    c.interrupted = interrupted != 0;
    if (r == LM_OK && measured) r = conv_write_csv(&c, runs, nrun, &err);
    if (r == LM_OK && measured) r = conv_write_json(&c, ref_path, runs, nrun, stats, &err);
    if (r == LM_OK && measured) r = conv_write_plot(&c, runs, nrun, &err);
    if (r == LM_OK && stats_path && stats) r = app_write_json(stats_path, stats, &err);
    cJSON_Delete(stats);
    sigaction(SIGINT, &old, NULL);
    if (r == LM_OK) {
        printf("%s\n", c.transport_note);
        if (!runs[0].peer) {
            printf("%s: first image %.3f s; ", c.s->source, c.first_image);
            if (c.converged_at >= 0)
                printf("converged at %.2f s\n", c.converged_at);
            else
                printf("not converged in %.2f s\n", seconds);
        }
        for (int k = 0; k < nrun; ++k) {
            for (int i = 0; i < runs[k].count; ++i) {
                const conv_row *w = &runs[k].rows[i];
                printf("  %-18s %8.3f s  relMSE %-10.4g dE mean %-8.4f p99 %-8.4f PSNR %.2f dB", runs[k].method,
                       w->seconds, w->m.relmse, w->m.delta_e_mean, w->m.delta_e_p99, w->m.psnr);
                if (w->m.relmse_reference_noise > 0.0)
                    printf("  (net of the reference's noise: relMSE %.4g)", w->m.relmse - w->m.relmse_reference_noise);
                printf("\n");
            }
        }
        printf("wrote %s/convergence.csv, convergence.json, convergence.png%s\n", dir,
               interrupted ? " (interrupted: what was measured)" : "");
    }
    img_free(&c.ref);
    scene_destroy(c.s);
    return r == LM_OK ? APP_EXIT_OK : app_report(r, &err);
}
