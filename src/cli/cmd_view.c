/* cmd_view.c — `lumesh view`: the interactive window (view_app.h) on a scene,
 * scriptable for tests (--script, view_script.h) and with --stats like render.
 * Prints one line per screenshot with the frames so far and the snapshot's
 * direct-diffuse and light-mesh sample counts, so a script can check refinement
 * kept going across a camera move (the view-independent caches are kept) and
 * that a light edit took no light sample. */
#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "sampling/rt_scene.h"
#include "src/cli/app_stats.h"
#include "src/cli/cli.h"
#include "src/render/rend_session.h"
#include "src/scene/scene.h"
#include "src/view/view_app.h"
#include "src/view/view_script.h"

typedef struct view_cli {
    const char *path;        /* the scene file (NULL: the built-in scene), for R */
    scene *current;          /* the scene the viewer shows; freed by cmd_view at the end */
    scene *pending;          /* the last reload, until the viewer takes it (or releases it) */
    const char *stats;
    double t_load_start; /* lm_now_seconds before the scene was read: --stats' seconds count from it */
} view_cli;

static void print_screenshot(const char *path, const view_app_report *rep, void *user)
{
    (void)user;
    const cache_snapshot *snap = rep->snap;
    unsigned long long light_samples = 0;
    for (uint32_t l = 0; snap && l < snap->stats.light_count; ++l) light_samples += snap->stats.lights[l].samples;
    printf("screenshot %s: %dx%d, frame %llu, %.2f s, direct samples %llu, light samples %llu, indirect samples %llu, "
           "generation %llu, bounces %d, converged %d, rest draws %u, residual spp %u, indirect %s, peer spp %u, peer vpls %llu, "
           "peer grid %u, peer earlier %d, exposure %g, judged at %g\n",
           path, rep->width, rep->height, (unsigned long long)rep->frames, rep->seconds,
           snap ? (unsigned long long)snap->stats.direct.samples : 0ull, light_samples,
           snap ? (unsigned long long)snap->stats.indirect.samples : 0ull,
           snap ? (unsigned long long)snap->generation : 0ull, snap ? snap->stats.bounces.bounces : 0,
           snap ? snap->converged : 0, rep->rest_draws, rep->residual_spp, rep->indirect, rep->peer_spp,
           (unsigned long long)rep->peer_vpls, rep->peer_grid, rep->peer_earlier, (double)rep->exposure, snap ? (double)snap->estimate.exposure : 0.0);
    fflush(stdout);
}

static lm_result finished(const view_app_report *rep, void *user, lm_error *err)
{
    view_cli *c = user;
    printf("view: %llu frames in %.2f s (%.1f fps) at %dx%d, %llu ID passes; %s\n", (unsigned long long)rep->frames,
           rep->seconds, rep->frames / (rep->seconds > 0 ? rep->seconds : 1), rep->width, rep->height,
           (unsigned long long)rep->id_passes, rep->renderer);
    if (!c->stats) return LM_OK;
    if (!rep->snap) return lm_fail(err, LM_ERR_RUNTIME, "%s: no snapshot was drawn, no statistics to write", c->stats);
    static const char *const phase_names[] = {"load", "window", "session", "display", "residual", "first_snapshot"};
    const double phases[] = {rep->startup.load,    rep->startup.window,   rep->startup.session,
                             rep->startup.display, rep->startup.residual, rep->startup.first_snapshot};
    cJSON *j = app_stats_json(&(app_stats_desc){.command = "view", .scene = rep->scene->source, .width = rep->width,
                                               .height = rep->height, .supersample = 1,
                                               .seconds = lm_now_seconds() - c->t_load_start,
                                               .first_image_seconds = rep->first_image_seconds,
                                               .converged_seconds = rep->snap->converged_at > 0
                                                                        ? rep->snap->converged_at - c->t_load_start -
                                                                              rep->startup.load
                                                                        : 0,
                                               .snap = rep->snap,
                                               .id_seconds = rep->id_seconds, .frame = rep->frame,
                                               .frames = rep->frames, .phase_names = phase_names,
                                               .phase_seconds = phases, .phase_count = 6});
    if (!j) return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory for the statistics");
    if (rep->peer_spp) { /* the picture shown at exit is a peer's (I, --indirect): its VPLs and times */
        cJSON *p = cJSON_AddObjectToObject(j, "peer");
        if (p) {
            cJSON_AddStringToObject(p, "indirect", rep->indirect);
            cJSON_AddNumberToObject(p, "samples_per_pixel", rep->peer_spp);
            cJSON_AddNumberToObject(p, "grid", rep->peer_grid);
            cJSON_AddBoolToObject(p, "view_before", rep->peer_earlier);
            cJSON_AddNumberToObject(p, "vpls", (double)rep->peer_vpls);
            cJSON_AddNumberToObject(p, "seconds", rep->peer_seconds);
            cJSON_AddNumberToObject(p, "vpl_seconds", rep->peer_vpl_seconds);
        }
    }
    lm_result r = app_write_json(c->stats, j, err);
    cJSON_Delete(j);
    return r;
}

/* R in the viewer: the same file loaded again. */
static lm_result reload(void *user, const scene **fresh, lm_error *err)
{
    view_cli *c = user;
    scene *s = NULL;
    lm_result r = scene_load(&(scene_load_desc){.path = c->path, .require_light = 1}, &s, err);
    if (r != LM_OK) return r;
    printf("reloaded %s: %u triangles, %u lights\n", s->source, s->tri_count, scene_light_count(s));
    fflush(stdout);
    c->pending = s;
    *fresh = s;
    return LM_OK;
}

/* The viewer let go of `old`: the scene it showed (it took the reload) or the
 * reload itself (it refused it). */
static void release(void *user, const scene *old)
{
    view_cli *c = user;
    if (old == c->current) {
        scene_destroy(c->current);
        c->current = c->pending;
    } else if (old == c->pending) {
        scene_destroy(c->pending);
    }
    c->pending = NULL;
}

/* The process's Embree device, made on a helper thread while the scene loads. */
static void *warm_embree(void *unused)
{
    (void)unused;
    rt_device_warm();
    return NULL;
}

int cmd_view(const app_command *cmd, int argc, char **argv)
{
    const char *sampler = NULL, *gl_name = NULL, *bounces = NULL, *script = NULL, *stats = NULL, *camera = NULL,
               *residual = "on", *indirect = "cache";
    long width = 0, height = 0;
    double max_fps = VIEW_APP_DEFAULT_FPS, exposure = NAN;
    enum { OPT_WIDTH = 6, OPT_HEIGHT = 7 }; /* their places below */
    app_opt opts[] = {
        {"--sampler", NULL, APP_OPT_STRING, &sampler},
        {"--bounces", NULL, APP_OPT_STRING, &bounces},
        {"--gl", NULL, APP_OPT_STRING, &gl_name},
        {"--script", NULL, APP_OPT_STRING, &script},
        {"--stats", NULL, APP_OPT_STRING, &stats},
        {"--camera", NULL, APP_OPT_STRING, &camera},
        [OPT_WIDTH] = {"--width", NULL, APP_OPT_INT, &width, 1, 16384},
        [OPT_HEIGHT] = {"--height", NULL, APP_OPT_INT, &height, 1, 16384},
        {"--max-fps", NULL, APP_OPT_DOUBLE, &max_fps, 0, 1000},
        {"--exposure", NULL, APP_OPT_DOUBLE, &exposure, -64, 64},
        {"--residual", NULL, APP_OPT_STRING, &residual},
        {"--indirect", NULL, APP_OPT_STRING, &indirect},
    };
    const char *pos[1];
    int npos, rc = app_parse_options(cmd, argc, argv, opts, (int)(sizeof opts / sizeof opts[0]), pos, 1, &npos);
    if (rc < 0) return APP_EXIT_OK;
    if (rc) return rc;
    if (opts[OPT_WIDTH].seen != opts[OPT_HEIGHT].seen) return app_usage_error(cmd, "give both --width and --height");
    if (strcmp(residual, "on") != 0 && strcmp(residual, "off") != 0)
        return app_usage_error(cmd, "--residual takes on or off");
    ref_estimator peer;
    ref_vpl_visibility visibility;
    if (!view_app_indirect_from_name(indirect, &peer, &visibility))
        return app_usage_error(cmd, "--indirect takes cache, vpl, bdir, vpl-ism or bdir-ism, not '%s'", indirect);
    /* As render: the 2% tolerance (rend_session_desc_defaults), the sampler chosen by
     * --sampler (auto by default). */
    rend_session_desc sd = {0};
    if ((rc = app_session_options(cmd, sampler, gl_name, bounces, &sd)) != APP_EXIT_OK) return rc;

    lm_error err = {{0}};
    view_cmd *cmds = NULL;
    size_t ncmds = 0;
    lm_result r = script ? view_script_load(script, &cmds, &ncmds, &err) : LM_OK;
    if (r == LM_OK && script && ncmds == 0) r = lm_fail(&err, LM_ERR_BAD_INPUT, "%s: the script has no commands", script);
    if (r != LM_OK) return app_report(r, &err);
    scene *s = NULL;
    double t_load_start = lm_now_seconds();
    /* Embree's device made beside the load, as converge's early helper does
     * (rt_device_warm): the worker's first step then pays only for its scene. */
    pthread_t warm;
    const int warming = pthread_create(&warm, NULL, warm_embree, NULL) == 0;
    r = scene_load(&(scene_load_desc){.path = npos ? pos[0] : NULL, .require_light = 1}, &s, &err);
    if (warming) pthread_join(warm, NULL);
    double t_scene = lm_now_seconds();
    if (r == LM_OK && isfinite(exposure)) s->exposure = (float)exposure; /* where + and − start */
    int ci = r == LM_OK ? scene_find_camera(s, camera) : 0;
    if (r == LM_OK && ci < 0) r = lm_fail(&err, LM_ERR_BAD_INPUT, "%s: no camera named '%s'", s->source, camera);
    if (r == LM_OK) {
        view_cli c = {.path = npos ? pos[0] : NULL, .current = s, .stats = stats, .t_load_start = t_load_start};
        r = view_app_run(&(view_app_desc){.scene = s, .camera = ci, .width = (int)width, .height = (int)height,
                                          .session = sd, .script = script ? cmds : NULL, .script_count = ncmds,
                                          .max_fps = max_fps > 0 ? max_fps : -1, .scene_loaded_at = t_scene,
                                          .scene_load_seconds = t_scene - t_load_start, .user = &c,
                                          .screenshot = print_screenshot, .finished = finished, .reload = reload,
                                          .release = release, .no_residual = strcmp(residual, "off") == 0,
                                          .indirect = peer, .indirect_visibility = visibility},
                         &err);
        s = c.current; /* the scene shown last (the first one or a reload's); the others are freed */
        scene_destroy(c.pending); /* a reload the run ended before taking (an error) */
    }
    free(cmds);
    scene_destroy(s);
    return r == LM_OK ? APP_EXIT_OK : app_report(r, &err);
}
