/* view_app.c — `lumesh view`'s display loop (view_app.h). */
#include "src/view/view_app_internal.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "src/base/tonemap.h"
#include "src/image/image.h"
#include "src/render/rend_session.h"
#include "src/scene/camera.h"
#include "src/view/view_camera.h"
#include "src/view/view_glfw.h"
#include "src/view/view_hud.h"
#include "src/view/view_tonemap.h"

enum { TITLE_PERIOD_MS = 500 };
static const float k_orbit_deg_per_unit = 0.3f; /* degrees per screen unit of drag */
static const float k_zoom_per_step = 0.9f;      /* distance factor per wheel step */
static const float k_exposure_step = 0.5f;      /* stops per + / - */
static const float k_look_deg_per_unit = 0.2f;  /* degrees per screen unit of right drag */
static const float k_fly_radii_per_s = 0.5f;    /* W A S D speed: scene bounding radii per second */
/* A new snapshot is taken at most this often while the camera rests: redrawing the
 * radiance images of a refined mesh is most of a frame's cost on llvmpipe (46 of
 * 75 ms at 1280x720 on Water), and the eye does not need each of the worker's
 * ~30 commits a second to see the picture sharpen. After a move: at once. */
static const double k_snapshot_period = 0.25;
/* While the camera moves the worker rests (the paper refines while the view is
 * idle), the picture is drawn at half the resolution and the ID pass waits: a
 * moving frame on llvmpipe cost ~165 ms at 1280x720 on Water, most of it the
 * radiance images and the composite. This long after the last move, the ID pass
 * runs, the worker gets the new view and resumes, and frames are full size again. */
static const double k_motion_rest = 0.15;
static const double k_start_poll = 0.002; /* s between looks for the first snapshot (nothing is drawn meanwhile) */
/* The resting picture's jittered draws take at most this share of the time
 * (each redraws every leaf): on Water at 1280x720 one takes ~128 ms, and with
 * a draw every frame the viewer fell from 41 to 18 fps while converging. */
static const double k_rest_share = 0.4;


static cache_worker *worker(const view_state *v)
{
    return rend_session_worker(v->rs);
}

void view_app_report_of(const view_state *v, view_app_report *r)
{
    /* The picture shown is a correction of the cache's (residual), or a peer's. */
    const int residual = view_app_showing_residual(v) && !v->peer_on, peer = view_app_showing_residual(v) && v->peer_on;
    *r = (view_app_report){.scene = v->s, .camera = &v->cam, .width = v->fb_w, .height = v->fb_h, .frames = v->frames,
                           .seconds = lm_now_seconds() - v->t_open, .first_image_seconds = v->first_image,
                           .startup = v->startup,
                           .id_seconds = v->id_seconds, .id_passes = v->id_passes, .snap = v->snap,
                           .frame = v->frames ? &v->times : NULL, .renderer = view_window_renderer(v->win),
                           .rest_draws = view_app_showing_mean(v) ? v->accum_n : 0,
                           .residual_spp = residual ? v->residual_info.min_samples : 0,
                           .residual_corrected = residual ? v->residual_info.corrected : 0.0,
                           .indirect = view_app_indirect_name(v->indirect, v->indirect_visibility),
                           .peer_spp = peer ? v->residual_info.min_samples : 0,
                           .peer_vpls = peer ? v->residual_info.vpls : 0,
                           .peer_grid = peer ? v->residual_info.grid : 0,
                           .peer_earlier = peer && !v->residual_current,
                           .peer_seconds = peer ? v->residual_info.seconds : 0.0,
                           .peer_vpl_seconds = peer ? v->residual_info.vpl_seconds : 0.0,
                           .exposure = v->exposure};
}

/* K's colours: multipliers of the scene's, about equal in luminance. */
static const float k_light_presets[][3] = {
    {1.0f, 1.0f, 1.0f},    /* as the scene says */
    {1.25f, 0.95f, 0.62f}, /* warm */
    {0.78f, 0.98f, 1.35f}, /* cool */
    {2.2f, 0.55f, 0.45f},  /* red */
    {0.55f, 1.25f, 0.6f},  /* green */
};
enum { LIGHT_PRESETS = sizeof k_light_presets / sizeof k_light_presets[0] };
const char *const view_light_preset_names[LIGHT_PRESETS] = {"", " warm", " cool", " red", " green"};

/* What light l (area lights, then point lights) emits at scale × tint × the
 * scene's radiance (or intensity). */
static void light_value(const scene *s, uint32_t l, float scale, const float tint[3], float out[3])
{
    const float *base = l < s->area_light_count ? s->area_lights[l].le
                                                : s->point_lights[l - s->area_light_count].intensity;
    for (int k = 0; k < 3; ++k) out[k] = base[k] * scale * tint[k];
}

/* Light l to scale × tint × the scene's radiance (or intensity): the worker
 * recomputes the direct mesh from its stored G (no light sample), the renderer
 * shows the emitter's new Le. */
static lm_result set_light(view_state *v, uint32_t l, float scale, const float tint[3], lm_error *err)
{
    if (l >= v->light_count)
        return lm_fail(err, LM_ERR_INVALID_ARG, "light %u does not exist (the scene has %u)", l, v->light_count);
    float value[3];
    light_value(v->s, l, scale, tint, value);
    lm_result r = cache_worker_set_light(worker(v), l, value, err);
    if (r != LM_OK) return r;
    v->light_scale[l] = scale;
    memmove(v->light_tint + 3 * (size_t)l, tint, 3 * sizeof *tint); /* tint may be that very row */
    v->emission_dirty = 1;
    return LM_OK;
}

static lm_result set_light_scale(view_state *v, uint32_t l, float scale, lm_error *err)
{
    if (l >= v->light_count)
        return lm_fail(err, LM_ERR_INVALID_ARG, "light %u does not exist (the scene has %u)", l, v->light_count);
    return set_light(v, l, scale, v->light_tint + 3 * (size_t)l, err);
}

/* The emitters' Le as light_scale says, after an edit or a new renderer. */
static lm_result apply_emission(view_state *v, lm_error *err)
{
    const scene *s = v->s;
    lm_result r = LM_OK;
    for (uint32_t l = 0; r == LM_OK && l < s->area_light_count; ++l) {
        float e[3];
        light_value(s, l, v->light_scale[l], v->light_tint + 3 * (size_t)l, e);
        r = rend_frame_set_emission(v->frame, s->area_lights[l].material, e, err);
        if (r == LM_OK && v->motion_frame) r = rend_frame_set_emission(v->motion_frame, s->area_lights[l].material, e, err);
    }
    v->emission_dirty = 0;
    return r;
}

static lm_result start_session(view_state *v, lm_error *err)
{
    /* Worker first (pixels_later): the coarse cache is made while the first ID pass
     * runs; on the window's context, at the framebuffer's size (fit_size);
     * publish_debug: the snapshots carry what a mesh overlay (O) draws, only while
     * one is shown (it costs the worker about a tenth of its pace on Water). */
    rend_session_desc d = v->d->session;
    d.scene = v->s;
    if (!v->bounces) v->bounces = d.bounces ? d.bounces : CACHE_BOUNCES_AUTO;
    d.bounces = v->bounces;
    d.camera = NULL;
    d.width = d.height = 0;
    d.order = REND_SESSION_WORKER_FIRST;
    /* AUTO's calibration comes after the first convergence, as in render and
     * converge (the worker's rule): it came first here until the driver was kept
     * loaded (glctx_keep_drivers_loaded in view_glfw.c; docs/viewer.md). */
    /* The first image with shadows (rend_session_desc.first_budget): the scene's
     * camera at the framebuffer's size guesses the pixel counts until the first
     * ID pass. */
    scene_camera first = v->s->cameras[v->camera_index < v->s->camera_count ? v->camera_index : 0];
    int fw = 0, fh = 0;
    view_window_framebuffer_size(v->win, &fw, &fh);
    if (fw > 0 && fh > 0 && v->s->camera_count > 0) {
        first.width = fw;
        first.height = fh;
        d.camera = &first;
        d.width = fw;
        d.height = fh;
        d.first_budget = REND_SESSION_FIRST_BUDGET_VIEWER;
    }
    d.gl = v->gl;
    d.supersample = 1;
    /* At rest the picture is the mean of VIEW_ACCUM_SIDE² jittered draws: leaves
     * down to one of their samples are seen. */
    d.sample_pixels = rend_session_sample_pixels(1, VIEW_ACCUM_SIDE);
    d.publish_debug = v->overlay != 0;
    lm_result r = rend_session_create(&d, &v->rs, err);
    /* A reloaded scene keeps the exposure the user chose: the cache judges it. */
    if (r == LM_OK && v->exposure != v->s->exposure) r = cache_worker_set_exposure(worker(v), v->exposure, err);
    /* The first image drawn with both cores: the worker publishes it and waits
     * (cache_worker_request_pause) until frame() has drawn it. */
    if (r == LM_OK && !v->paused) {
        cache_worker_request_pause(worker(v));
        v->start_paused = 1;
    }
    return r;
}

/* Per light, power relative to the scene's: all 1 for a new scene. */
static lm_result reset_lights(view_state *v, lm_error *err)
{
    v->light_count = scene_light_count(v->s);
    v->light = 0;
    free(v->light_scale);
    free(v->light_tint);
    free(v->light_preset);
    size_t n = v->light_count ? v->light_count : 1;
    v->light_scale = malloc(n * sizeof *v->light_scale);
    v->light_tint = malloc(3 * n * sizeof *v->light_tint);
    v->light_preset = calloc(n, sizeof *v->light_preset);
    if (!v->light_scale || !v->light_tint || !v->light_preset)
        return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory for %u lights", v->light_count);
    for (uint32_t l = 0; l < v->light_count; ++l) {
        v->light_scale[l] = 1.0f;
        for (int k = 0; k < 3; ++k) v->light_tint[3 * l + (uint32_t)k] = 1.0f;
    }
    v->emission_dirty = 1;
    return LM_OK;
}

static void residual_stop(view_state *v);

/* Stops and joins the residual's thread: nothing refers to v->s from it after this. */
static void drop_residual(view_state *v)
{
    view_residual_destroy(v->residual);
    v->residual = NULL;
    v->residual_on = v->residual_shown = 0;
    free(v->residual_lights);
    v->residual_lights = NULL;
}

/* The residual's thread (view_residual.h) for v->s, with the lights' buffer. */
static lm_result make_residual(view_state *v, lm_error *err)
{
    drop_residual(v);
    v->residual_lights = calloc((size_t)v->light_count + 1, 3 * sizeof *v->residual_lights);
    if (!v->residual_lights) return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory for the viewer's residual");
    return view_residual_create(v->s, &v->residual, err);
}

/* R: the scene again from its file (it changed on disk). Everything made from the
 * old scene goes (the worker is joined), the camera stays where the user put it.
 * A file that no longer loads keeps the old scene (the reason is printed). */
static lm_result reload_scene(view_state *v, lm_error *err)
{
    const view_app_desc *d = v->d;
    if (!d->reload) return LM_OK;
    const scene *fresh = NULL;
    lm_error why = {{0}};
    if (d->reload(d->user, &fresh, &why) != LM_OK || !fresh || fresh->camera_count == 0) {
        fprintf(stderr, "lumesh view: the scene did not reload, keeping the one shown: %s\n",
                why.msg[0] ? why.msg : "it has no camera");
        if (fresh && d->release) d->release(d->user, fresh);
        return LM_OK;
    }
    if (v->paused) cache_worker_resume(worker(v));
    rend_session_destroy(v->rs); /* joins the worker first: nothing refers to the old scene after this */
    v->rs = NULL;
    v->snap = NULL;
    v->paused = v->motion_paused = 0;
    rend_frame_destroy(v->motion_frame);
    v->frame = v->motion_frame = NULL;
    v->fb_w = v->fb_h = 0;
    int had_residual = v->residual != NULL;
    drop_residual(v);
    const scene *old = v->s;
    v->s = fresh;
    if (v->camera_index >= fresh->camera_count) v->camera_index = 0;
    v->camera_moved = 1;
    v->ov_stale = 1;
    v->reloads++;
    lm_result r = reset_lights(v, err);
    /* The residual's thread and BVH are of the old scene: made again for the new. */
    if (r == LM_OK && had_residual) r = make_residual(v, err);
    if (r == LM_OK) r = start_session(v, err);
    if (d->release) d->release(d->user, old);
    return r;
}

/* The scene's camera i, at the window's size. */
static void select_camera(view_state *v, uint32_t i)
{
    const scene *s = v->s;
    if (i >= s->camera_count) return;
    int w = v->cam.width, h = v->cam.height;
    v->cam = s->cameras[i];
    v->cam.width = w;
    v->cam.height = h;
    v->camera_index = i;
    v->camera_moved = 1;
}

static lm_result apply_action(view_state *v, view_action a, lm_error *err)
{
    v->ov_stale = 1; /* whatever it changes, the overlay is made again from the picture */
    switch (a) {
    case VIEW_ACTION_QUIT: v->quit = 1; break;
    case VIEW_ACTION_PAUSE:
        /* The key does not wait for the worker's step in flight (the display never
         * blocks on it); a script does, so that what follows sees no more commits. */
        if (v->paused) cache_worker_resume(worker(v));
        else if (v->in_script) cache_worker_pause(worker(v));
        else cache_worker_request_pause(worker(v));
        v->paused = !v->paused;
        break;
    case VIEW_ACTION_EXPOSURE_UP:
    case VIEW_ACTION_EXPOSURE_DOWN:
        /* The cache refines for the colours shown: what was clipped or too dark to
         * see may be seen now (cache_set_exposure; docs/viewer.md, "Exposure"). */
        v->exposure = fmaxf(-64.0f, fminf(64.0f, v->exposure + (a == VIEW_ACTION_EXPOSURE_UP ? k_exposure_step
                                                                                             : -k_exposure_step)));
        return cache_worker_set_exposure(worker(v), v->exposure, err);
    case VIEW_ACTION_SCREENSHOT:
        snprintf(v->shot, sizeof v->shot, "lumesh-view-%llu.png", (unsigned long long)++v->screenshots);
        v->shot_exr_too = 1;
        break;
    case VIEW_ACTION_CAMERA_NEXT: select_camera(v, (v->camera_index + 1) % v->s->camera_count); break;
    case VIEW_ACTION_FRAME_ALL:
        view_camera_frame_all(&v->cam, v->s->bounds_min, v->s->bounds_max,
                              v->fb_h > 0 ? (float)v->fb_w / (float)v->fb_h : 16.0f / 9.0f);
        v->camera_moved = 1;
        break;
    case VIEW_ACTION_LIGHT_NEXT:
        if (v->light_count) v->light = (v->light + 1) % v->light_count;
        break;
    case VIEW_ACTION_LIGHT_UP:
    case VIEW_ACTION_LIGHT_DOWN:
        if (v->light_count)
            return set_light_scale(v, v->light, v->light_scale[v->light] * (a == VIEW_ACTION_LIGHT_UP ? 2.0f : 0.5f),
                                   err);
        break;
    case VIEW_ACTION_LIGHT_COLOR:
        if (v->light_count) {
            uint32_t p = v->light_preset[v->light] = (v->light_preset[v->light] + 1) % LIGHT_PRESETS;
            return set_light(v, v->light, v->light_scale[v->light], k_light_presets[p], err);
        }
        break;
    case VIEW_ACTION_TOGGLE_DIRECT: v->components ^= REND_FRAME_COMPONENT_DIRECT_DIFFUSE; break;
    case VIEW_ACTION_TOGGLE_SPECULAR: v->components ^= REND_FRAME_COMPONENT_DIRECT_SPECULAR; break;
    case VIEW_ACTION_TOGGLE_INDIRECT: v->components ^= REND_FRAME_COMPONENT_INDIRECT; break;
    case VIEW_ACTION_TOGGLE_EMISSION: v->components ^= REND_FRAME_COMPONENT_EMISSION; break;
    case VIEW_ACTION_HELP: v->help = !v->help; break;
    case VIEW_ACTION_INDIRECT:
        /* cache → vpl → bdir → vpl-ism → bdir-ism → cache */
        if (v->indirect == REF_ESTIMATOR_PATHS) {
            v->indirect = REF_ESTIMATOR_VPL;
            v->indirect_visibility = REF_VPL_VISIBILITY_RAYS;
        } else if (v->indirect == REF_ESTIMATOR_VPL) {
            v->indirect = REF_ESTIMATOR_BDIR;
        } else if (v->indirect_visibility == REF_VPL_VISIBILITY_RAYS) {
            v->indirect = REF_ESTIMATOR_VPL;
            v->indirect_visibility = REF_VPL_VISIBILITY_ISM;
        } else {
            v->indirect = REF_ESTIMATOR_PATHS;
            v->indirect_visibility = REF_VPL_VISIBILITY_RAYS;
        }
        residual_stop(v);
        break;
    case VIEW_ACTION_RELOAD: return reload_scene(v, err);
    case VIEW_ACTION_BOUNCES: {
        /* Like a light edit: every indirect value gathered again, no light sample. */
        static const int cycle[] = {CACHE_BOUNCES_AUTO, 1, 2, 3, 4, 8};
        size_t i = 0, n = sizeof cycle / sizeof cycle[0];
        while (i < n && cycle[i] != v->bounces) ++i;
        v->bounces = cycle[(i + 1) % n];
        return cache_worker_set_bounces(worker(v), v->bounces, err);
    }
    case VIEW_ACTION_OVERLAY_NEXT:
        v->overlay = (v->overlay + 1) % (int)(4 + v->light_count);
        v->ov_stale = 1;
        cache_worker_set_publish_debug(worker(v), v->overlay != 0);
        break;
    case VIEW_ACTION_OVERLAY_KIND:
        v->overlay_points = !v->overlay_points;
        v->ov_stale = 1;
        break;
    default: break;
    }
    return LM_OK;
}

/* Runs the script's commands due now: instantaneous ones all at once, up to one
 * that waits (wait, frames) or a screenshot (taken after this frame's draw). */
static lm_result run_script(view_state *v, lm_error *err)
{
    const view_app_desc *d = v->d;
    if (!d->script) return LM_OK;
    while (!v->quit && !v->shot[0] && !v->window_shot[0]) {
        if (v->si >= d->script_count) {
            v->quit = 1; /* the script ran out: done */
            return LM_OK;
        }
        const view_cmd *c = &d->script[v->si];
        if (!v->cmd_started) {
            v->cmd_started = 1;
            v->cmd_t0 = lm_now_seconds();
            v->cmd_frames0 = v->frames;
            v->cmd_generation0 = v->snap ? v->snap->generation : 0;
        }
        lm_result r = LM_OK;
        switch (c->kind) {
        case VIEW_CMD_WAIT:
            if (lm_now_seconds() - v->cmd_t0 < c->a) return LM_OK;
            break;
        case VIEW_CMD_FRAMES:
            if (v->frames - v->cmd_frames0 < (uint64_t)c->a) return LM_OK;
            break;
        case VIEW_CMD_NEXT_SNAPSHOT:
            /* Drawn already: v->snap is the one of the last frame. */
            if ((!v->snap || v->snap->generation == v->cmd_generation0) && lm_now_seconds() - v->cmd_t0 < c->a)
                return LM_OK;
            break;
        case VIEW_CMD_PEER_PICTURE:
        case VIEW_CMD_PEER_PREVIEW: {
            /* As the screenshot line counts it: the peer's picture of this view is
             * shown, from a complete pass (or, for peer-preview, its grid's). */
            view_app_report rep;
            view_app_report_of(v, &rep);
            int shown = rep.peer_spp > 0 && !rep.peer_earlier && (c->kind == VIEW_CMD_PEER_PREVIEW || rep.peer_grid == 1);
            if (!shown && lm_now_seconds() - v->cmd_t0 < c->a) return LM_OK;
            /* The report is the last frame's: were the next frame to take the
             * peer's newer pass, a screenshot after this would not show the picture
             * waited for (a preview's grid replaced by a whole pass meanwhile). */
            v->residual_hold = shown;
            break;
        }
        case VIEW_CMD_LIGHT: r = set_light_scale(v, (uint32_t)c->a, (float)c->b, err); break;
        case VIEW_CMD_LIGHT_COLOR:
            r = (uint32_t)c->a < v->light_count
                    ? set_light(v, (uint32_t)c->a, v->light_scale[(uint32_t)c->a], c->rgb, err)
                    : lm_fail(err, LM_ERR_INVALID_ARG, "light %.0f does not exist (the scene has %u)", c->a,
                              v->light_count);
            break;
        case VIEW_CMD_ORBIT:
            view_camera_orbit(&v->cam, (float)c->a, (float)c->b);
            v->camera_moved = 1;
            break;
        case VIEW_CMD_ZOOM:
            view_camera_zoom(&v->cam, (float)c->a);
            v->camera_moved = 1;
            break;
        case VIEW_CMD_PAN:
            view_camera_pan(&v->cam, (float)c->a, (float)c->b);
            v->camera_moved = 1;
            break;
        case VIEW_CMD_FLY:
            view_camera_fly(&v->cam, (float)c->a, (float)c->b, (float)c->c);
            v->camera_moved = 1;
            break;
        case VIEW_CMD_LOOK:
            view_camera_look(&v->cam, (float)c->a, (float)c->b);
            v->camera_moved = 1;
            break;
        case VIEW_CMD_CAMERA:
            if (c->a >= v->s->camera_count)
                r = lm_fail(err, LM_ERR_INVALID_ARG, "camera %.0f does not exist (the scene has %u)", c->a,
                            v->s->camera_count);
            else
                select_camera(v, (uint32_t)c->a);
            break;
        case VIEW_CMD_RESIZE: view_window_resize(v->win, (int)c->a, (int)c->b); break;
        case VIEW_CMD_MINIMISE: view_window_minimise(v->win, (int)c->a); break;
        case VIEW_CMD_WINDOW_SHOT: snprintf(v->window_shot, sizeof v->window_shot, "%s", c->path); break;
        case VIEW_CMD_SCREENSHOT:
            snprintf(v->shot, sizeof v->shot, "%s", c->path);
            v->shot_exr_too = 0;
            break;
        case VIEW_CMD_KEY:
            v->in_script = 1;
            r = apply_action(v, c->action, err);
            v->in_script = 0;
            break;
        case VIEW_CMD_QUIT: v->quit = 1; break;
        default: break;
        }
        if (r != LM_OK) {
            char why[sizeof err->msg];
            snprintf(why, sizeof why, "%s", err->msg);
            return lm_fail(err, r, "script line %d: %s", c->line, why);
        }
        v->si++;
        v->start_changed = 1; /* a command may change what is drawn */
        v->cmd_started = 0;
    }
    return LM_OK;
}

/* The session's ID pass and renderer at the framebuffer's size (made again on
 * resize; the ID pass at the next view). */
static lm_result fit_size(view_state *v, int w, int h, lm_error *err)
{
    if (v->frame && w == v->fb_w && h == v->fb_h) return LM_OK;
    rend_frame_destroy(v->motion_frame);
    v->motion_frame = NULL;
    v->frame = NULL;
    v->fb_w = v->fb_h = 0;
    v->drawn = 0;
    lm_result r = rend_session_resize(v->rs, w, h, err);
    if (r == LM_OK) r = rend_session_renderer(v->rs, REND_SESSION_FINAL, &v->frame, err);
    if (r != LM_OK) return r;
    v->fb_w = w;
    v->fb_h = h;
    v->cam.width = w;
    v->cam.height = h;
    v->camera_moved = 1; /* new pixel counts for the new size */
    v->emission_dirty = 1; /* a new renderer has the scene's Le */
    return LM_OK;
}

/* The rest after the first image (start_session) ends: refinement goes on,
 * unless the user or a move has paused it since. */
static void end_start_pause(view_state *v)
{
    if (!v->start_paused) return;
    v->start_paused = 0;
    if (!v->paused && !v->motion_paused) cache_worker_resume(worker(v));
}

/* What the resting picture would show now. */
static view_accum_key accum_key_now(const view_state *v, const scene_camera *cam)
{
    view_accum_key k = {.cam = *cam, .components = v->components, .generation = v->snap ? v->snap->generation : 0};
    for (uint32_t l = 0; l < v->light_count; ++l)
        k.lights += (double)(l + 1) * (v->light_scale[l] + 3.0 * v->light_tint[3 * l] + 5.0 * v->light_tint[3 * l + 1] +
                                       7.0 * v->light_tint[3 * l + 2]);
    return k;
}

/* The same view (camera_equal), lights and terms. */
static int accum_same_view(const view_accum_key *a, const view_accum_key *b)
{
    return camera_equal(&a->cam, &b->cam) && a->components == b->components && a->lights == b->lights;
}

static void residual_stop(view_state *v)
{
    if (v->residual_on) view_residual_stop(v->residual);
    v->residual_on = 0;
    v->residual_shown = 0;
    v->peer_on = 0;
}

/* residual_rgb and residual_up hold n floats each. */
static lm_result residual_buffers(view_state *v, size_t n, lm_error *err)
{
    if (n <= v->residual_cap) return LM_OK;
    float *p = realloc(v->residual_rgb, n * sizeof *p), *q = p ? realloc(v->residual_up, n * sizeof *q) : NULL;
    if (p) v->residual_rgb = p;
    if (q) v->residual_up = q;
    if (!p || !q) return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory for the viewer's residual");
    v->residual_cap = n;
    return LM_OK;
}

/* A picture the residual's thread handed back (a correction, or a peer's
 * picture) into residual_tex, shown from now on. */
static void upload_residual(view_state *v, const scene_camera *cam)
{
    if (v->residual_hold ||
        !view_residual_take(v->residual, v->residual_rgb, &v->residual_seq, &v->residual_info, &v->residual_current)) {
        if (v->residual_shown) v->shown = v->residual_tex;
        return;
    }
    /* Kept top row first (screenshots); uploaded bottom-up, GL's row order. */
    const GladGLContext *gl = v->gl;
    size_t row = (size_t)cam->width * 3;
    for (int y = 0; y < cam->height; ++y)
        memcpy(v->residual_up + (size_t)(cam->height - 1 - y) * row, v->residual_rgb + (size_t)y * row,
               row * sizeof *v->residual_up);
    if (!v->residual_tex) gl->GenTextures(1, &v->residual_tex);
    gl->BindTexture(GL_TEXTURE_2D, v->residual_tex);
    gl->TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
    gl->TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
    gl->TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
    gl->TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
    gl->PixelStorei(GL_UNPACK_ALIGNMENT, 4);
    gl->TexImage2D(GL_TEXTURE_2D, 0, GL_RGB32F, cam->width, cam->height, 0, GL_RGB, GL_FLOAT, v->residual_up);
    gl->BindTexture(GL_TEXTURE_2D, 0);
    v->residual_shown = 1;
    v->shown = v->residual_tex;
}

/* --indirect vpl|bdir (I): with every term shown, the peer renders the view on
 * the residual's thread (view_residual.h) and its picture is shown: a new view's
 * first at one pixel in k×k (about 0.05 s a pass), then its whole passes; before
 * the first, the cache's. A move restarts it with its VPLs kept (the thesis's
 * temporal reuse) and the picture of the view before stays until the new one's:
 * a moving view is the peer's, a pass late. A light edit, a new bounce count or
 * a resize traces new ones and shows the cache's picture until then. */
static lm_result show_peer(view_state *v, const scene_camera *cam, lm_error *err)
{
    if (v->components != REND_FRAME_COMPONENTS_ALL) {
        residual_stop(v);
        return LM_OK;
    }
    lm_result r = v->residual ? LM_OK : make_residual(v, err);
    if (r == LM_OK) r = residual_buffers(v, (size_t)cam->width * (size_t)cam->height * 3, err);
    if (r != LM_OK) return r;
    view_accum_key k = accum_key_now(v, cam);
    k.generation = 0; /* the peer does not follow the cache's snapshots */
    const int bounces = v->snap && v->snap->stats.bounces.bounces > 0 ? v->snap->stats.bounces.bounces : 1;
    const int same_peer = v->peer_on && v->peer_bounces == bounces && v->peer_kind == v->indirect &&
                          v->peer_visibility == v->indirect_visibility;
    if (!same_peer || !accum_same_view(&v->residual_key, &k)) {
        /* Only the camera moved (not its size, the lights or the terms): the
         * picture shown stays until the new view's (view_residual_start). */
        const int moved = same_peer && v->residual_key.components == k.components &&
                          v->residual_key.lights == k.lights && v->residual_key.cam.width == k.cam.width &&
                          v->residual_key.cam.height == k.cam.height;
        for (uint32_t l = 0; l < v->light_count; ++l)
            light_value(v->s, l, v->light_scale[l], v->light_tint + 3 * (size_t)l, v->residual_lights + 3 * (size_t)l);
        view_residual_view rv = {.cam = *cam, .bounces = bounces, .light_values = v->residual_lights,
                                 .peer = v->indirect, .visibility = v->indirect_visibility,
                                 .gl_platform = v->d->session.gl_platform};
        r = view_residual_start(v->residual, &rv, NULL, err);
        if (r != LM_OK) return r;
        v->residual_on = v->peer_on = 1;
        v->residual_key = k;
        v->residual_shown = moved && v->residual_shown;
        v->residual_current = 0;
        v->peer_bounces = bounces;
        v->peer_kind = v->indirect;
        v->peer_visibility = v->indirect_visibility;
    }
    upload_residual(v, cam);
    return LM_OK;
}

/* The complete resting picture, corrected by path samples while the worker has
 * nothing to do (finished, or paused by the user) and every term is shown: the
 * mean is read back once per resting picture, handed to the residual's thread,
 * and each correction it hands back is uploaded and shown instead. */
static lm_result show_residual(view_state *v, const scene_camera *cam, lm_error *err)
{
    int idle = v->snap->finished || v->paused;
    if (!v->residual || !idle || v->components != REND_FRAME_COMPONENTS_ALL) {
        residual_stop(v);
        return LM_OK;
    }
    lm_result r = residual_buffers(v, (size_t)cam->width * (size_t)cam->height * 3, err);
    if (r != LM_OK) return r;
    if (v->peer_on) residual_stop(v); /* the thread rendered a peer: a correction starts afresh */
    if (!v->residual_on || !accum_same_view(&v->residual_key, &v->accum_key) ||
        v->residual_key.generation != v->accum_key.generation) {
        r = view_accum_read(v->accum, v->residual_rgb, err);
        for (uint32_t l = 0; l < v->light_count; ++l)
            light_value(v->s, l, v->light_scale[l], v->light_tint + 3 * (size_t)l, v->residual_lights + 3 * (size_t)l);
        view_residual_view rv = {.cam = *cam, .bounces = v->snap->stats.bounces.bounces, .light_values = v->residual_lights};
        if (r == LM_OK) r = view_residual_start(v->residual, &rv, v->residual_rgb, err);
        if (r != LM_OK) return r;
        v->residual_on = 1;
        v->residual_key = v->accum_key;
        v->residual_shown = 0;
    }
    upload_residual(v, cam);
    return LM_OK;
}

/* The picture of this frame into v->shown. At rest on a snapshot converged at
 * its JND, the frame's draws go into the resting picture, each with its samples
 * moved to the next offset of a VIEW_ACCUM_SIDE² grid in the pixel, until it is
 * complete; then nothing is drawn until something changes. A new snapshot of the
 * same view that sharpens a converged one (it differs by less than the JND)
 * keeps half of the draws' weight; anything else starts again. */
static lm_result draw_picture(view_state *v, rend_frame *f, const scene_camera *cam, const rend_frame_output *o,
                              lm_error *err)
{
    const uint32_t full = VIEW_ACCUM_SIDE * VIEW_ACCUM_SIDE;
    int rest = f == v->frame && v->snap && v->snap->converged && !v->snap->failed && v->accum;
    v->shown = o->texture;
    if (v->indirect != REF_ESTIMATOR_PATHS) { /* the peer's picture (show_peer), the cache's until its first */
        v->accum_n = 0;
        v->accum_key.generation = 0;
        /* At the window's size while moving too (the cache's moving picture is
         * half that): the peer keeps one renderer, its VPLs and its picture. */
        rend_frame_output whole;
        rend_frame_get_output(v->frame, &whole);
        scene_camera at = *cam;
        at.width = whole.width;
        at.height = whole.height;
        lm_result r = show_peer(v, &at, err);
        if (r == LM_OK && !v->residual_shown) {
            r = rend_frame_draw(f, cam, v->snap, NULL, err);
            v->shown = o->texture;
        }
        return r;
    }
    if (!rest) {
        residual_stop(v);
        v->accum_n = 0;
        v->accum_key.generation = 0; /* no mean to sharpen */
        return rend_frame_draw(f, cam, v->snap, NULL, err);
    }
    view_accum_key k = accum_key_now(v, cam);
    int same_view = accum_same_view(&k, &v->accum_key);
    if (!same_view || k.generation != v->accum_key.generation) {
        int sharpening = same_view && v->accum_key.generation != 0;
        v->accum_n = sharpening && v->accum_n > full / 2 ? full / 2 : sharpening ? v->accum_n : 0;
        if (!v->accum_n) v->accum_i = 0;
        v->accum_key = k;
    }
    /* The draws after the first wait their turn: a jittered draw redraws every
     * leaf (on Water at 1280×720, 180,000 leaf triangles: 128 ms), and the
     * viewer keeps its frame rate (docs/viewer.md, "The resting picture"). */
    double now = lm_now_seconds();
    if (v->accum_n >= full) {
        v->shown = view_accum_texture(v->accum);
        return show_residual(v, cam, err);
    }
    residual_stop(v); /* the resting picture is made again */
    if (v->accum_n > 0 && now < v->accum_next) {
        v->shown = view_accum_texture(v->accum);
        return LM_OK;
    }
    float jx, jy;
    /* The offsets go round the grid whatever the weights: a sharpening snapshot
     * keeps the mean, and the next draws fill the offsets it lacks most. */
    rend_frame_jitter_pattern((int)(v->accum_i++ % full), VIEW_ACCUM_SIDE, 1, &jx, &jy);
    rend_frame_set_jitter(f, jx, jy);
    lm_result r = rend_frame_draw(f, cam, v->snap, NULL, err);
    rend_frame_set_jitter(f, 0.0f, 0.0f);
    if (r == LM_OK) r = view_accum_add(v->accum, o->texture, o->width, o->height, v->accum_n, err);
    if (r == LM_OK) {
        v->accum_n++;
        v->shown = view_accum_texture(v->accum);
        double took = lm_now_seconds() - now;
        v->accum_next = now + took / k_rest_share;
    }
    return r;
}

/* One frame: input, script, ID pass after a move, the latest snapshot, draw, present. */
static lm_result frame(view_state *v, lm_error *err)
{
    view_input in;
    view_window_poll(v->win, &in);
    if (in.close) v->quit = 1;
    lm_result r = LM_OK;
    for (int a = 0; a < VIEW_ACTION_COUNT; ++a)
        for (int k = 0; r == LM_OK && k < in.actions[a]; ++k) {
            r = apply_action(v, (view_action)a, err);
            v->start_changed = 1;
        }
    if (r != LM_OK) return r;
    if (in.drag_dx != 0 || in.drag_dy != 0) {
        /* Dragging right turns the scene right: the camera goes left. */
        view_camera_orbit(&v->cam, -(float)in.drag_dx * k_orbit_deg_per_unit,
                          (float)in.drag_dy * k_orbit_deg_per_unit);
        v->camera_moved = 1;
    }
    if (in.wheel != 0) {
        view_camera_zoom(&v->cam, powf(k_zoom_per_step, (float)in.wheel));
        v->camera_moved = 1;
    }
    if (in.pan_dx != 0 || in.pan_dy != 0) {
        /* The scene follows the cursor: the camera goes the other way. */
        double hs = in.screen_height > 0 ? in.screen_height : 720.0;
        view_camera_pan(&v->cam, -(float)(in.pan_dx / hs), (float)(in.pan_dy / hs));
        v->camera_moved = 1;
    }
    if (in.look_dx != 0 || in.look_dy != 0) {
        view_camera_look(&v->cam, (float)in.look_dx * k_look_deg_per_unit, -(float)in.look_dy * k_look_deg_per_unit);
        v->camera_moved = 1;
    }
    double now = lm_now_seconds(), dt = fmin(0.25, now - v->last_input); /* a stall does not jump */
    v->last_input = now;
    if (in.fly[0] != 0 || in.fly[1] != 0 || in.fly[2] != 0) {
        const scene *s = v->s;
        double r2 = 0;
        for (int k = 0; k < 3; ++k) r2 += 0.25 * (s->bounds_max[k] - s->bounds_min[k]) * (s->bounds_max[k] - s->bounds_min[k]);
        float step = (float)(sqrt(r2) * k_fly_radii_per_s * dt);
        view_camera_fly(&v->cam, in.fly[0] * step, in.fly[1] * step, in.fly[2] * step);
        v->camera_moved = 1;
    }
    if ((r = run_script(v, err)) != LM_OK) return r;
    if (v->quit && !v->shot[0] && !v->window_shot[0]) return LM_OK;

    int w, h;
    view_window_framebuffer_size(v->win, &w, &h);
    if (w <= 0 || h <= 0) { /* minimised: nothing to draw into; the worker goes on */
        end_start_pause(v);
        return LM_OK;
    }
    r = fit_size(v, w, h, err);
    if (r == LM_OK && v->emission_dirty) r = apply_emission(v, err);
    if (r == LM_OK) {
        rend_frame_set_components(v->frame, v->components);
        if (v->motion_frame) rend_frame_set_components(v->motion_frame, v->components);
    }
    double now_m = lm_now_seconds();
    if (v->camera_moved) {
        v->camera_moved = 0;
        v->start_changed = 1;
        v->view_pending = 1;
        v->last_motion = now_m;
        v->ov_stale = 1;
        if (!v->paused && !v->motion_paused && v->frames > 0) {
            cache_worker_request_pause(worker(v));
            v->motion_paused = 1;
        }
    }
    /* The ID pass once the camera rests (or at once for the first view and for a
     * screenshot of the picture, which must show the view refined; a window-shot
     * shows what the window shows). The first view's pass waits for the first
     * image, as in `converge`: until then the worker refines by the pixel counts
     * guessed from the camera (start_session), and the pass (65 ms at 1280×720
     * here) came before the first picture (docs/viewer.md). */
    int first_wait = v->id_passes == 0 && v->first_image < 0 && !v->shot[0];
    int at_rest = now_m - v->last_motion >= k_motion_rest || v->id_passes == 0 || v->shot[0];
    if (r == LM_OK && v->view_pending && at_rest && !first_wait) {
        r = rend_session_set_view(v->rs, &v->cam, err);
        rend_session_info in;
        rend_session_get_info(v->rs, &in);
        v->id_seconds = in.id_seconds;
        v->id_passes++;
        v->view_pending = 0;
        v->fresh_view = 1;
        v->start_changed = 1;
    }
    if (r != LM_OK) return r;
    double now_s = lm_now_seconds();
    if (v->motion_paused && (v->paused || !v->view_pending)) {
        if (!v->paused) cache_worker_resume(worker(v));
        v->motion_paused = 0;
    }
    /* An overlay waiting for the worker's debug data takes each snapshot until it comes. */
    int debug_missing = v->overlay && v->snap && !v->snap->direct.corners;
    if (!v->snap || v->fresh_view || debug_missing || v->shot[0] || v->window_shot[0] ||
        now_s - v->snap_taken >= k_snapshot_period) {
        /* The snapshot held is valid until the acquire: its generation is read before. */
        uint64_t held = v->snap ? v->snap->generation : 0;
        const cache_snapshot *s;
        r = rend_session_acquire(v->rs, &s, err); /* never waits */
        if (s) {
            if (s->generation != held) {
                v->snap_taken = now_s;
                v->fresh_view = 0;
            }
            v->snap = s;
            if (v->startup.first_snapshot < 0) v->startup.first_snapshot = lm_now_seconds() - v->t_open;
        }
        if (r != LM_OK) return r; /* refinement failed */
    }
    /* Until the first snapshot the picture is the geometry alone, which changes
     * only with the view, the window or a key: drawn once for each, and otherwise
     * left, so that the worker's start (all of it CPU-bound) has the cores (116k
     * box, `view` 640×480: first image 0.61-0.72 -> 0.49-0.65 s; docs/viewer.md). */
    if (!v->snap && v->frames > 0 && !v->start_changed && !v->shot[0] && !v->window_shot[0]) return LM_OK;
    v->start_changed = 0;
    /* Moving: the half-size renderer, its picture stretched by the tone mapping;
     * made at the first move after a resize (its shaders cost start-up time). */
    int moving = v->view_pending && !first_wait;
    if (moving && !v->motion_frame) {
        r = rend_frame_create(v->gl,
                              &(rend_frame_desc){.scene = v->s, .width = (w + 1) / 2, .height = (h + 1) / 2,
                                                 .supersample = 1},
                              &v->motion_frame, err);
        if (r == LM_OK) r = apply_emission(v, err);
        if (r == LM_OK) rend_frame_set_components(v->motion_frame, v->components);
        if (r != LM_OK) return r;
    }
    rend_frame *f = moving ? v->motion_frame : v->frame;
    scene_camera cam = v->cam;
    rend_frame_output o;
    rend_frame_get_output(f, &o);
    cam.width = o.width;
    cam.height = o.height;
    /* The first snapshot's picture with the highlights the specular mesh
     * interpolates; the next frame draws them per pixel (docs/renderer.md, "The
     * first image's highlights one draw later"). */
    if (v->first_image < 0 && v->snap) rend_frame_defer_highlights(f);
    r = draw_picture(v, f, &cam, &o, err);
    tm_desc tm = {.exposure = v->exposure};
    if (r == LM_OK) r = view_tm_draw(v->tm, &(view_tm_target){.width = w, .height = h}, v->shown, &tm, err);
    if (r == LM_OK && v->overlay && v->snap && f == v->frame) r = view_app_draw_overlay(v, w, h, v->shown, &tm, err);
    if (r == LM_OK && v->hud) {
        char text[2048];
        view_app_hud_text(v, text, sizeof text);
        r = view_hud_draw(v->hud, &(view_hud_text){.text = text, .x = 8, .y = 8, .scale = h >= 600 ? 2.0f : 1.0f},
                          w, h, err);
    }
    if (r != LM_OK) return r;
    rend_frame_get_times(f, &v->times);
    v->frames++;
    if (v->first_image < 0 && v->snap) v->first_image = lm_now_seconds() - v->t_open;
    if (v->snap) end_start_pause(v); /* drawn: refinement goes on */
    if (v->shot[0]) r = view_app_take_screenshot(v, err);
    v->residual_hold = 0; /* one frame: the one a screenshot after the wait is taken of */
    if (r == LM_OK && v->window_shot[0]) {
        uint8_t *rgb = malloc((size_t)w * (size_t)h * 3);
        r = rgb ? view_hud_read_window(v->hud, w, h, rgb, err)
                : lm_fail(err, LM_ERR_NO_MEMORY, "out of memory for a %dx%d window shot", w, h);
        if (r == LM_OK)
            r = img_write(&(img_write_desc){.path = v->window_shot, .width = w, .height = h, .channels = 3, .pixels8 = rgb},
                          err);
        free(rgb);
        v->window_shot[0] = '\0';
    }
    view_window_swap(v->win);
    return r;
}

static const struct {
    const char *name;
    ref_estimator peer;
    ref_vpl_visibility visibility;
} k_indirect[] = {{"cache", REF_ESTIMATOR_PATHS, REF_VPL_VISIBILITY_RAYS},
                  {"vpl", REF_ESTIMATOR_VPL, REF_VPL_VISIBILITY_RAYS},
                  {"bdir", REF_ESTIMATOR_BDIR, REF_VPL_VISIBILITY_RAYS},
                  {"vpl-ism", REF_ESTIMATOR_VPL, REF_VPL_VISIBILITY_ISM},
                  {"bdir-ism", REF_ESTIMATOR_BDIR, REF_VPL_VISIBILITY_ISM}};

int view_app_indirect_from_name(const char *name, ref_estimator *peer, ref_vpl_visibility *visibility)
{
    for (size_t i = 0; i < sizeof k_indirect / sizeof k_indirect[0]; ++i)
        if (strcmp(name, k_indirect[i].name) == 0) {
            *peer = k_indirect[i].peer;
            *visibility = k_indirect[i].visibility;
            return 1;
        }
    return 0;
}

const char *view_app_indirect_name(ref_estimator peer, ref_vpl_visibility visibility)
{
    for (size_t i = 0; i < sizeof k_indirect / sizeof k_indirect[0]; ++i)
        if (k_indirect[i].peer == peer && (peer == REF_ESTIMATOR_PATHS || k_indirect[i].visibility == visibility))
            return k_indirect[i].name;
    return "cache";
}

lm_result view_app_run(const view_app_desc *d, lm_error *err)
{
    if (!d || !d->scene || d->camera < 0 || (uint32_t)d->camera >= d->scene->camera_count)
        return lm_fail(err, LM_ERR_INVALID_ARG, "view_app_run: no scene or no such camera");
    view_state v = {.d = d, .s = d->scene, .cam = d->scene->cameras[d->camera], .exposure = d->scene->exposure,
                    .first_image = -1, .camera_moved = 1, .components = REND_FRAME_COMPONENTS_ALL, .indirect = d->indirect,
                    .indirect_visibility = d->indirect_visibility,
                    .startup = {-1, -1, -1, -1, -1, -1}};
    lm_result r = reset_lights(&v, err);
    if (r != LM_OK) return r;
    r = view_window_create(&(view_window_desc){.title = "lumesh view", .width = d->width,
                                                        .height = d->height},
                                     &v.win, err);
    if (r != LM_OK) {
        free(v.light_scale);
        free(v.light_tint);
        free(v.light_preset);
        return r;
    }
    v.gl = view_window_gl(v.win);
    v.t_open = v.last_input = lm_now_seconds();
    if (d->scene_loaded_at > 0) v.startup.window = v.t_open - d->scene_loaded_at;
    if (d->scene_load_seconds > 0) v.startup.load = d->scene_load_seconds;
    v.camera_index = (uint32_t)d->camera;
    r = start_session(&v, err);
    v.startup.session = lm_now_seconds() - v.t_open;
    if (r == LM_OK) r = view_tm_create(v.gl, &v.tm, err);
    if (r == LM_OK) r = view_hud_create(v.gl, &v.hud, err);
    if (r == LM_OK) r = view_accum_create(v.gl, &v.accum, err);
    v.startup.display = lm_now_seconds() - v.t_open;
    if (r == LM_OK && !d->no_residual) r = make_residual(&v, err);
    v.startup.residual = lm_now_seconds() - v.t_open;
    double period = d->max_fps < 0 ? 0 : 1.0 / (d->max_fps > 0 ? d->max_fps : VIEW_APP_DEFAULT_FPS);
    double next = lm_now_seconds(), next_title = next;
    while (r == LM_OK && !v.quit) {
        r = frame(&v, err);
        double now = lm_now_seconds();
        if (now >= next_title) {
            view_app_update_title(&v);
            next_title = now + TITLE_PERIOD_MS * 1e-3;
        }
        /* Steady pacing: aim at fixed ticks; after a slow frame start again from now
         * rather than drawing a burst to catch up. */
        next += period;
        if (next < now) next = now;
        /* Waiting for the first snapshot, nothing is drawn (frame): look again
         * within 2 ms, not at the next tick, so that it is drawn when it comes. */
        if (!v.snap && v.frames > 0 && next > now + k_start_poll) next = now + k_start_poll;
        lm_sleep_seconds(next - now);
    }
    if (r == LM_OK && d->finished) {
        view_app_report rep;
        view_app_report_of(&v, &rep);
        r = d->finished(&rep, d->user, err);
    }
    if (v.paused) cache_worker_resume(worker(&v));
    rend_session_destroy(v.rs); /* cancels the refinement and joins the thread, then its GL objects */
    view_tm_destroy(v.tm);
    view_hud_destroy(v.hud);
    view_accum_destroy(v.accum);
    drop_residual(&v);
    if (v.residual_tex) v.gl->DeleteTextures(1, &v.residual_tex);
    free(v.residual_rgb);
    free(v.residual_up);
    rend_frame_destroy(v.motion_frame);
    view_window_destroy(v.win);
    free(v.light_scale);
    free(v.light_tint);
    free(v.light_preset);
    free(v.ov_bg);
    free(v.ov_rgb);
    free(v.ov_ids);
    return r;
}
