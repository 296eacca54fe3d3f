/* view_app_show.c — what the viewer shows and writes besides the picture: the
 * HUD's text, the window title, the mesh overlays (rend_debug), screenshots
 * (view_app_internal.h). Display thread. */
#include "src/view/view_app_internal.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "src/image/image.h"
#include "src/render/rend_debug.h"

static int ends_with(const char *s, const char *suffix)
{
    size_t n = strlen(s), k = strlen(suffix);
    return n >= k && strcmp(s + n - k, suffix) == 0;
}

/* The linear radiance behind the picture: the resting picture read back, or the
 * same snapshot drawn again and read back (the renderer redraws only what
 * changed, i.e. nothing). */
static lm_result write_exr(view_state *v, const char *path, lm_error *err)
{
    rend_frame_output o;
    rend_frame_get_output(v->frame, &o);
    float *rgb = malloc((size_t)o.width * (size_t)o.height * 3 * sizeof *rgb);
    if (!rgb) return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory for a %dx%d screenshot", o.width, o.height);
    lm_result r = LM_OK;
    if (view_app_showing_residual(v)) /* the correction shown (view_app.c, show_residual) */
        memcpy(rgb, v->residual_rgb, (size_t)o.width * (size_t)o.height * 3 * sizeof *rgb);
    else
        r = view_app_showing_mean(v) ? view_accum_read(v->accum, rgb, err)
                                     : rend_session_draw(v->rs, REND_SESSION_FINAL, &v->cam, rgb, err);
    if (r == LM_OK)
        r = img_write(&(img_write_desc){.path = path, .width = o.width, .height = o.height, .channels = 3, .pixels = rgb},
                      err);
    free(rgb);
    return r;
}

lm_result view_app_take_screenshot(view_state *v, lm_error *err)
{
    rend_frame_output o;
    rend_frame_get_output(v->frame, &o);
    lm_result r = LM_OK;
    if (ends_with(v->shot, ".exr")) {
        r = write_exr(v, v->shot, err);
    } else {
        uint8_t *rgb = malloc((size_t)o.width * (size_t)o.height * 3);
        if (!rgb) return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory for a %dx%d screenshot", o.width, o.height);
        r = view_tm_read(v->tm, v->shown ? v->shown : o.texture, o.width, o.height, &(tm_desc){.exposure = v->exposure},
                         rgb, err);
        if (r == LM_OK)
            r = img_write(&(img_write_desc){.path = v->shot, .width = o.width, .height = o.height, .channels = 3,
                                            .pixels8 = rgb},
                          err);
        free(rgb);
    }
    if (r == LM_OK && v->shot_exr_too && ends_with(v->shot, ".png")) {
        char exr[VIEW_SCRIPT_PATH_MAX];
        snprintf(exr, sizeof exr, "%.*s.exr", (int)(strlen(v->shot) - 4), v->shot);
        r = write_exr(v, exr, err);
    }
    if (r == LM_OK && v->d->screenshot) {
        view_app_report rep;
        view_app_report_of(v, &rep);
        v->d->screenshot(v->shot, &rep, v->d->user);
    }
    v->shot[0] = '\0';
    return r;
}

/* The overlay's mesh in the snapshot, and its name; NULL when it has none. */
static const cache_snapshot_mesh *overlay_mesh(const view_state *v, char *name, size_t size)
{
    const cache_snapshot *s = v->snap;
    int k = v->overlay - 1;
    if (k < 3) snprintf(name, size, "%s", k == 0 ? "direct" : k == 1 ? "indirect" : "specular");
    else snprintf(name, size, "light%d", k - 3);
    if (!s) return NULL;
    const cache_snapshot_mesh *m = k == 0 ? &s->direct : k == 1 ? &s->indirect : k == 2 ? &s->specular
                                 : (uint32_t)(k - 3) < s->light_mesh_count ? &s->lights[k - 3] : NULL;
    return m && m->corners && m->triangle_count ? m : NULL;
}

/* Draws the overlay over the tone-mapped picture in the window (made again when
 * what it shows changed). Returns LM_OK and draws nothing without data. */
lm_result view_app_draw_overlay(view_state *v, int w, int h, GLuint texture, const tm_desc *tm, lm_error *err)
{
    char name[32];
    const cache_snapshot_mesh *m = overlay_mesh(v, name, sizeof name);
    if (!m) return LM_OK;
    size_t n = (size_t)w * (size_t)h;
    if (v->ov_w != w || v->ov_h != h) {
        free(v->ov_bg);
        free(v->ov_rgb);
        free(v->ov_ids);
        v->ov_bg = malloc(3 * n);
        v->ov_rgb = malloc(3 * n);
        v->ov_ids = malloc(n * sizeof *v->ov_ids);
        v->ov_w = v->ov_bg && v->ov_rgb && v->ov_ids ? w : 0;
        v->ov_h = h;
        if (!v->ov_w) return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory for a %dx%d overlay", w, h);
        v->ov_stale = 1;
    }
    lm_result r = LM_OK;
    if (v->ov_stale || v->ov_generation != v->snap->generation) {
        r = rend_session_read_ids(v->rs, v->ov_ids, err);
        if (r == LM_OK) r = view_tm_read(v->tm, texture, w, h, tm, v->ov_bg, err);
        rend_debug_desc d = {.camera = &v->cam, .width = w, .height = h, .ids = v->ov_ids, .background = v->ov_bg};
        if (r == LM_OK)
            r = v->overlay_points ? rend_debug_samples(&d, m, v->ov_rgb, NULL, err)
                                  : rend_debug_leaves(&d, m, v->ov_rgb, NULL, err);
        if (r != LM_OK) return r;
        v->ov_stale = 0;
        v->ov_generation = v->snap->generation;
    }
    return view_tm_show_rgb8(v->tm, v->ov_rgb, w, h, err);
}

static const char k_help[] =
    "left drag: orbit    middle / shift+left drag: pan    right drag: look    wheel: zoom\n"
    "W A S D, Space / Ctrl: fly    F: frame all    C: next camera\n"
    "1 2 3 4: direct diffuse, direct specular, indirect, emission on / off\n"
    "L: next light    ] [: its power x2 / x0.5    K: its colour (no new light samples)\n"
    "+ -: exposure    P: pause refinement    F12: screenshot (PNG + EXR)\n"
    "O: overlay the next mesh    V: wireframe / sample points\n"
    "B: bounces (auto, 1, 2, 3, 4, 8)    I: still view by cache, VPLs, BDIR (+ shadow maps)\n"
    "R: reload the scene from its file    H: this help    Esc / Q: quit";

static uint64_t all_samples(const cache_snapshot *s)
{
    uint64_t n = s->stats.direct.samples + s->stats.indirect.samples + s->stats.specular.samples;
    for (uint32_t l = 0; l < s->stats.light_count; ++l) n += s->stats.lights[l].samples;
    return n;
}

/* The HUD's lines: frame rate and passes, refinement, samples per mesh, memory,
 * the display state; the help under it when on. */
void view_app_hud_text(view_state *v, char *out, size_t size)
{
    const cache_snapshot *s = v->snap;
    double now = lm_now_seconds();
    if (s && now - v->rate_t0 >= 1.0) {
        uint64_t n = all_samples(s);
        v->rate = v->rate_t0 > 0 ? (double)(n - v->rate_samples0) / (now - v->rate_t0) : 0.0;
        v->rate_t0 = now;
        v->rate_samples0 = n;
    }
    double fps = v->frames / fmax(1e-9, now - v->t_open);
    size_t k = (size_t)snprintf(out, size, "%.1f fps  %dx%d  frame %.1f ms (material %.1f, radiance %.1f, composite %.1f)\n",
                                fps, v->fb_w, v->fb_h, 1e3 * v->times.total, 1e3 * v->times.material,
                                1e3 * v->times.radiance, 1e3 * v->times.composite);
    if (s && k < size) {
        /* Past convergence the worker sharpens on to a lower JND (rend_session_desc.jnd_floor). */
        const char *state = v->paused                     ? "paused"
                            : s->converged && s->finished ? "converged"
                            : s->converged                ? "converged, sharpening"
                            : s->finished                 ? "finished (the estimate is still above the JND)"
                                                          : "running";
        if (s->estimate.measured)
            k += (size_t)snprintf(out + k, size - k,
                                  "refinement: %s, %.0f samples/s, %.1f MB; estimated mean dE %.2f, %.1f%% above the "
                                  "JND (%.3g), %.0f%% untested\n",
                                  state, v->rate, s->stats.bytes / 1048576.0, s->estimate.mean,
                                  100.0 * s->estimate.above_jnd, (double)s->jnd, 100.0 * s->estimate.untested);
        else /* the first snapshot: none made yet (cache_worker_acquire) */
            k += (size_t)snprintf(out + k, size - k, "refinement: %s, %.1f MB; error not estimated yet (JND %.3g)\n",
                                  state, s->stats.bytes / 1048576.0, (double)s->jnd);
        view_app_report rep;
        view_app_report_of(v, &rep);
        if (rep.rest_draws && k < size) /* the resting picture (view_app.c, draw_picture) */
            k += (size_t)snprintf(out + k, size - k, "picture: %u of %d draws averaged", rep.rest_draws,
                                  VIEW_ACCUM_SIDE * VIEW_ACCUM_SIDE);
        if (rep.residual_spp && k < size) /* ... corrected by path samples (show_residual) */
            k += (size_t)snprintf(out + k, size - k, ", corrected by %u+ path samples a pixel (%.0f%% of it)",
                                  rep.residual_spp, 100.0 * rep.residual_corrected);
        if (rep.rest_draws && k < size) k += (size_t)snprintf(out + k, size - k, "\n");
        if (strcmp(rep.indirect, "cache") != 0 && k < size) { /* I: a peer renders the still view (show_peer) */
            const char *peer = strcmp(rep.indirect, "vpl") == 0       ? "instant radiosity (VPLs)"
                               : strcmp(rep.indirect, "vpl-ism") == 0 ? "instant radiosity (VPLs, shadow maps)"
                               : strcmp(rep.indirect, "bdir-ism") == 0 ? "BDIR (shadow maps)"
                                                                       : "BDIR";
            if (rep.peer_spp && rep.peer_grid > 1) /* a new view's first pass (view_residual.h) */
                k += (size_t)snprintf(out + k, size - k, "picture: %s, one pixel in %ux%u sampled%s, %llu VPLs made\n",
                                      peer, rep.peer_grid, rep.peer_grid, rep.peer_earlier ? " (the view before)" : "",
                                      (unsigned long long)rep.peer_vpls);
            else if (rep.peer_spp)
                k += (size_t)snprintf(out + k, size - k, "picture: %s, %u samples a pixel%s, %llu VPLs made\n", peer,
                                      rep.peer_spp, rep.peer_earlier ? " (the view before)" : "",
                                      (unsigned long long)rep.peer_vpls);
            else
                k += (size_t)snprintf(out + k, size - k, "picture: the cache's until the first pass of %s\n", peer);
        }
        if (k < size) k += (size_t)snprintf(out + k, size - k, "samples:");
        for (uint32_t l = 0; l < s->stats.light_count && l < 8 && k < size; ++l)
            k += (size_t)snprintf(out + k, size - k, " light%u %llu,", l, (unsigned long long)s->stats.lights[l].samples);
        if (k < size)
            k += (size_t)snprintf(out + k, size - k, " direct %llu, indirect %llu, specular %llu\n",
                                  (unsigned long long)s->stats.direct.samples,
                                  (unsigned long long)s->stats.indirect.samples,
                                  (unsigned long long)s->stats.specular.samples);
    } else if (k < size) {
        k += (size_t)snprintf(out + k, size - k, "refinement: starting\n");
    }
    if (k < size) {
        char light[64] = "";
        if (v->light_count)
            snprintf(light, sizeof light, "  light %u/%u x%.3g%s", v->light + 1, v->light_count,
                     v->light_scale[v->light], view_light_preset_names[v->light_preset[v->light]]);
        char bounces[64];
        int shown = s ? s->stats.bounces.bounces : 0;
        if (v->bounces == CACHE_BOUNCES_AUTO && shown)
            snprintf(bounces, sizeof bounces, "bounces auto (%d)", shown);
        else if (v->bounces == CACHE_BOUNCES_AUTO)
            snprintf(bounces, sizeof bounces, "bounces auto");
        else
            snprintf(bounces, sizeof bounces, "bounces %d", v->bounces);
        k += (size_t)snprintf(out + k, size - k, "exposure %+.1f%s  %s  terms %c%c%c%c  camera %u/%u%s", v->exposure, light,
                              bounces,
                              v->components & REND_FRAME_COMPONENT_DIRECT_DIFFUSE ? 'D' : '-',
                              v->components & REND_FRAME_COMPONENT_DIRECT_SPECULAR ? 'S' : '-',
                              v->components & REND_FRAME_COMPONENT_INDIRECT ? 'I' : '-',
                              v->components & REND_FRAME_COMPONENT_EMISSION ? 'E' : '-', v->camera_index + 1,
                              v->s->camera_count, v->help ? "" : "    H: help");
    }
    if (v->overlay && k < size) {
        char name[32];
        const cache_snapshot_mesh *m = overlay_mesh(v, name, sizeof name);
        k += (size_t)snprintf(out + k, size - k, "\noverlay: %s %s%s", name,
                              v->overlay_points ? "sample points" : "leaf wireframe", m ? "" : " (nothing to show)");
    }
    if (v->help && k < size) snprintf(out + k, size - k, "\n\n%s", k_help);
}

void view_app_update_title(view_state *v)
{
    const cache_snapshot *s = v->snap;
    char title[256];
    double fps = v->frames / fmax(1e-9, lm_now_seconds() - v->t_open);
    char light[64] = "";
    if (v->light_count)
        snprintf(light, sizeof light, ", light %u/%u ×%.3g", v->light + 1, v->light_count, v->light_scale[v->light]);
    snprintf(title, sizeof title,
             "lumesh view — %.0f fps, exposure %+.1f%s, terms %c%c%c%c — %s%llu direct, %llu indirect samples%s", fps,
             v->exposure, light, v->components & REND_FRAME_COMPONENT_DIRECT_DIFFUSE ? 'D' : '-',
             v->components & REND_FRAME_COMPONENT_DIRECT_SPECULAR ? 'S' : '-',
             v->components & REND_FRAME_COMPONENT_INDIRECT ? 'I' : '-',
             v->components & REND_FRAME_COMPONENT_EMISSION ? 'E' : '-', v->paused ? "paused, " : "",
             s ? (unsigned long long)s->stats.direct.samples : 0ull,
             s ? (unsigned long long)s->stats.indirect.samples : 0ull, s && s->converged ? ", converged" : "");
    view_window_set_title(v->win, title);
}

