/* cmd_render.c — `lumesh render`: a headless progressive render.
 *
 * The ID pass gives the pixels per triangle; the refinement worker refines the
 * multi-mesh cache (its own sampler, `--sampler`, chosen at the cache's 2%
 * tolerance by default) until nothing is left to test, `--seconds` have passed,
 * or `--samples` leaf tests are done; the renderer's passes draw the last
 * snapshot; the image is written linear (EXR) or tone-mapped (PNG), through a
 * temporary file (img_write), so a failure leaves no partial file.
 */
#define _POSIX_C_SOURCE 200809L /* nanosleep */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "cache_worker.h"
#include "cli.h"
#include "gl_context.h"
#include "image.h"
#include "rend_frame.h"
#include "rend_id.h"
#include "scene.h"
#include "tonemap.h"

enum { DEFAULT_SECONDS_LIMIT = 600 }; /* without --seconds or --samples: until converged, at most this */

static int ext_is(const char *path, const char *want)
{
    char ext[16];
    lm_path_ext(path, ext, sizeof ext);
    return strcmp(ext, want) == 0;
}

static void nap(void)
{
    struct timespec t = {0, 5000000}; /* 5 ms */
    nanosleep(&t, NULL);
}

/* Per-mesh statistics as JSON (docs/cache.md names the fields). */
static int write_stats(const char *path, const cache_snapshot *snap, const rend_frame_times *tt, double seconds,
                       lm_error *err)
{
    char tmp[SCENE_PATH_MAX + 8];
    snprintf(tmp, sizeof tmp, "%s.tmp", path);
    FILE *f = fopen(tmp, "w");
    if (!f) {
        lm_fail(err, LM_ERR_IO, "%s: cannot write the statistics", path);
        return 0;
    }
    const cache_stats *st = &snap->stats;
    fprintf(f, "{\n  \"seconds\": %.6f,\n  \"leaves_tested\": %llu,\n  \"converged\": %s,\n  \"bytes\": %zu,\n", seconds,
            (unsigned long long)snap->tested, snap->converged ? "true" : "false", st->bytes);
    fprintf(f, "  \"passes_ms\": {\"material\": %.3f, \"radiance\": %.3f, \"composite\": %.3f, \"readback\": %.3f},\n",
            tt->material * 1e3, tt->radiance * 1e3, tt->composite * 1e3, tt->readback * 1e3);
    fprintf(f, "  \"meshes\": [\n");
    const char *names[3] = {"direct", "indirect", "specular"};
    const cache_mesh_stats *ms[3] = {&st->direct, &st->indirect, &st->specular};
    uint32_t total = 3 + st->light_count;
    for (uint32_t i = 0; i < total; ++i) {
        const cache_mesh_stats *m = i < 3 ? ms[i] : &st->lights[i - 3];
        char name[32];
        if (i < 3)
            snprintf(name, sizeof name, "%s", names[i]);
        else
            snprintf(name, sizeof name, "light %u", i - 3);
        fprintf(f,
                "    {\"mesh\": \"%s\", \"samples\": %llu, \"interpolated\": %llu, \"vertices\": %u, \"nodes\": %u, "
                "\"leaves\": %u, \"splits\": %llu, \"merges\": %llu, \"bytes\": %zu, \"leaves_at_depth\": [",
                name, (unsigned long long)m->samples, (unsigned long long)m->interpolated, m->mesh.vertices_used,
                m->mesh.nodes, m->mesh.leaves, (unsigned long long)m->mesh.splits,
                (unsigned long long)m->mesh.merges, m->mesh.bytes);
        int last = 0;
        for (int d = 0; d < MESH_QMESH_DEPTHS; ++d)
            if (m->mesh.leaves_at_depth[d]) last = d;
        for (int d = 0; d <= last; ++d) fprintf(f, "%s%u", d ? ", " : "", m->mesh.leaves_at_depth[d]);
        fprintf(f, "]}%s\n", i + 1 < total ? "," : "");
    }
    fprintf(f, "  ]\n}\n");
    int ok = fclose(f) == 0 && rename(tmp, path) == 0;
    if (!ok) {
        remove(tmp);
        lm_fail(err, LM_ERR_IO, "%s: cannot write the statistics", path);
    }
    return ok;
}

int cmd_render(const app_command *cmd, int argc, char **argv)
{
    const char *out = NULL, *camera = NULL, *stats = NULL, *sampler = NULL, *gl_name = NULL;
    double seconds = 0;
    long samples = 0, width = 0, height = 0;
    app_opt opts[] = {
        {"--output", "-o", APP_OPT_STRING, &out},
        {"--seconds", NULL, APP_OPT_DOUBLE, &seconds, 0.001, 1e7},
        {"--samples", NULL, APP_OPT_INT, &samples, 1, 2e9},
        {"--width", NULL, APP_OPT_INT, &width, 1, 16384},
        {"--height", NULL, APP_OPT_INT, &height, 1, 16384},
        {"--camera", NULL, APP_OPT_STRING, &camera},
        {"--stats", NULL, APP_OPT_STRING, &stats},
        {"--sampler", NULL, APP_OPT_STRING, &sampler},
        {"--gl", NULL, APP_OPT_STRING, &gl_name},
    };
    const char *pos[1];
    int npos, rc = app_parse_options(cmd, argc, argv, opts, 9, pos, 1, &npos);
    if (rc < 0) return APP_EXIT_OK;
    if (rc) return rc;
    if (!out) return app_usage_error(cmd, "an output image is required (-o OUT.png or OUT.exr)");
    if (!ext_is(out, "exr") && !ext_is(out, "png")) return app_usage_error(cmd, "the output must end in .png or .exr");
    if (opts[1].seen && opts[2].seen) return app_usage_error(cmd, "give --seconds or --samples, not both");
    if (opts[3].seen != opts[4].seen) return app_usage_error(cmd, "give both --width and --height");
    if ((rc = app_check_sampler_options(cmd, sampler, gl_name)) != APP_EXIT_OK) return rc;

    lm_error err = {{0}};
    scene *s = NULL;
    lm_result r = scene_load(&(scene_load_desc){.path = npos ? pos[0] : NULL, .require_light = 1}, &s, &err);
    if (r != LM_OK) return app_report(r, &err);
    int ci = scene_find_camera(s, camera);
    if (ci < 0) {
        lm_fail(&err, LM_ERR_BAD_INPUT, "%s: no camera named '%s'", s->source, camera);
        scene_destroy(s);
        return app_report(LM_ERR_BAD_INPUT, &err);
    }
    scene_camera cam = s->cameras[ci];
    int w = width ? (int)width : cam.width, h = height ? (int)height : cam.height;
    samp_desc sd = {.direct_target_error = 0.02f, .indirect_target_error = 0.02f};
    if (sampler) samp_backend_from_name(sampler, &sd.backend);
    samp_gl_platform platform = SAMP_GL_EGL;
    if (gl_name) samp_gl_platform_from_name(gl_name, &platform);
    sd.gl_platform = platform;

    double t0 = lm_now_seconds();
    glctx *ctx = NULL;
    rend_id *ip = NULL;
    rend_frame *frame = NULL;
    cache_worker *wk = NULL;
    float *rgb = NULL;
    uint8_t *png = NULL;
    rend_id_result ids;
    r = glctx_create(&(glctx_desc){.platform = platform}, &ctx, &err);
    if (r == LM_OK) r = rend_id_create(glctx_gl(ctx), &(rend_id_desc){.scene = s, .width = w, .height = h}, &ip, &err);
    if (r == LM_OK) r = rend_id_render(ip, &cam, &ids, &err);
    if (r == LM_OK)
        r = cache_worker_create(&(cache_worker_desc){.scene = s, .sampler = sd, .pixels = ids.pixels,
                                                     .max_tested = (uint64_t)samples},
                                &wk, &err);
    const cache_snapshot *snap = NULL;
    double limit = opts[1].seen ? seconds : DEFAULT_SECONDS_LIMIT;
    while (r == LM_OK) {
        snap = cache_worker_acquire(wk);
        if (snap && snap->failed) {
            r = lm_fail(&err, LM_ERR_RUNTIME, "refinement failed: %s", snap->error);
            break;
        }
        if (snap && (snap->converged || lm_now_seconds() - t0 >= limit)) break;
        nap();
    }
    if (r == LM_OK) r = rend_frame_create(glctx_gl(ctx), &(rend_frame_desc){.scene = s, .width = w, .height = h}, &frame, &err);
    rgb = r == LM_OK ? malloc((size_t)w * (size_t)h * 3 * sizeof *rgb) : NULL;
    if (r == LM_OK && !rgb) r = lm_fail(&err, LM_ERR_NO_MEMORY, "out of memory for a %dx%d image", w, h);
    if (r == LM_OK) r = rend_frame_draw(frame, &cam, snap, rgb, &err);
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
    double elapsed = lm_now_seconds() - t0;
    if (r == LM_OK && stats) {
        rend_frame_times tt;
        rend_frame_get_times(frame, &tt);
        if (!write_stats(stats, snap, &tt, elapsed, &err)) r = LM_ERR_IO;
    }
    if (r == LM_OK) {
        const cache_stats *st = &snap->stats;
        uint64_t light = 0;
        for (uint32_t l = 0; l < st->light_count; ++l) light += st->lights[l].samples;
        printf("wrote %s: %dx%d, %.2f s, %s after %llu leaves tested; samples: %llu light, %llu indirect; %u direct, "
               "%u indirect, %u specular triangles\n",
               out, w, h, elapsed, snap->converged ? "converged" : "stopped", (unsigned long long)snap->tested,
               (unsigned long long)light, (unsigned long long)st->indirect.samples, snap->direct.triangle_count,
               snap->indirect.triangle_count, snap->specular.triangle_count);
    }
    free(png);
    free(rgb);
    cache_worker_destroy(wk);
    rend_frame_destroy(frame);
    rend_id_destroy(ip);
    glctx_destroy(ctx);
    scene_destroy(s);
    return r == LM_OK ? APP_EXIT_OK : app_report(r, &err);
}
