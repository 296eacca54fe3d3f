/* cmd_pending.c — the commands whose engines land with later work (convergence
 * runs, the viewer). They already parse and check their arguments and their
 * scene, so scripts get the final usage and bad-input behaviour today, and then
 * say plainly that the engine is not available yet (exit 3). */
#include <stdio.h>
#include <string.h>

#include "cli.h"
#include "samp.h"
#include "scene.h"

static int not_available(const app_command *cmd, const char *what)
{
    fprintf(stderr, "lumesh %s: not available yet in this build: %s\n", cmd->name, what);
    return APP_EXIT_RUNTIME;
}

/* Loads the scene (bad input -> exit 2), then reports the missing engine. */
static int check_scene(const char *path, int need_light)
{
    scene_load_desc d = {.path = path, .require_light = need_light};
    scene *s;
    lm_error err;
    lm_result r = scene_load(&d, &s, &err);
    if (r != LM_OK) return app_report(r, &err);
    scene_destroy(s);
    return APP_EXIT_OK;
}

int cmd_converge(const app_command *cmd, int argc, char **argv)
{
    const char *ref = NULL, *out = NULL, *sampler = NULL, *gl = NULL;
    double seconds = 0;
    app_opt opts[] = {
        {"--reference", NULL, APP_OPT_STRING, &ref},
        {"--seconds", NULL, APP_OPT_DOUBLE, &seconds, 0.001, 1e7},
        {"--out", NULL, APP_OPT_STRING, &out},
        {"--sampler", NULL, APP_OPT_STRING, &sampler},
        {"--gl", NULL, APP_OPT_STRING, &gl},
    };
    const char *pos[1];
    int npos, rc = app_parse_options(cmd, argc, argv, opts, 5, pos, 1, &npos);
    if (rc < 0) return APP_EXIT_OK;
    if (rc) return rc;
    if (!ref || !out || !opts[1].seen)
        return app_usage_error(cmd, "--reference, --seconds and --out are required");
    if ((rc = app_check_sampler_options(cmd, sampler, gl)) != APP_EXIT_OK) return rc;
    if ((rc = check_scene(npos ? pos[0] : NULL, 1)) != APP_EXIT_OK) return rc;
    return not_available(cmd, "the multi-mesh renderer is not built yet");
}

int cmd_view(const app_command *cmd, int argc, char **argv)
{
    const char *sampler = NULL, *gl = NULL;
    app_opt opts[] = {
        {"--sampler", NULL, APP_OPT_STRING, &sampler},
        {"--gl", NULL, APP_OPT_STRING, &gl},
    };
    const char *pos[1];
    int npos, rc = app_parse_options(cmd, argc, argv, opts, 2, pos, 1, &npos);
    if (rc < 0) return APP_EXIT_OK;
    if (rc) return rc;
    if ((rc = app_check_sampler_options(cmd, sampler, gl)) != APP_EXIT_OK) return rc;
    if ((rc = check_scene(npos ? pos[0] : NULL, 1)) != APP_EXIT_OK) return rc;
    return not_available(cmd, "the interactive viewer is not built yet");
}
