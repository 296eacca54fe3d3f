/* view_app_internal.h — what view_app.c (the loop, input, the worker) and
 * view_app_show.c (what is shown and written: HUD text, title, mesh overlays,
 * screenshots) share. Not a public header. */
#ifndef LUMESH_VIEW_APP_INTERNAL_H
#define LUMESH_VIEW_APP_INTERNAL_H

#include <stdint.h>

#include "src/base/tonemap.h"
#include "src/render/rend_session.h"
#include "src/view/view_accum.h"
#include "src/view/view_app.h"
#include "src/view/view_glfw.h"
#include "src/view/view_hud.h"
#include "src/view/view_residual.h"
#include "src/view/view_tonemap.h"

/* The resting picture: the mean of VIEW_ACCUM_SIDE² draws on a regular grid of
 * offsets in each pixel (rend_frame_jitter_pattern), made while the camera rests
 * on a snapshot converged at its JND (docs/viewer.md, "The resting picture"). */
enum { VIEW_ACCUM_SIDE = 4 };
/* What the mean shows: it starts again when any of this changes (a snapshot
 * sharpening one converged before keeps part of it: view_app.c). */
typedef struct view_accum_key {
    scene_camera cam;               /* with the picture's size */
    unsigned components;
    double lights;                  /* a sum over the lights' scales and tints */
    uint64_t generation;            /* the snapshot's */
} view_accum_key;

/* Everything the loop owns; all of it display thread only (the worker's state is
 * behind cache_worker's API, reached through rend_session_worker). */
typedef struct view_state {
    const view_app_desc *d;
    const scene *s;                 /* d->scene, or the last one d->reload gave */
    view_window *win;
    const GladGLContext *gl;        /* the window's, lent to the session */
    rend_session *rs;               /* the ID pass, the worker and frame, on gl (rend_session.h) */
    view_tm *tm;
    view_hud *hud;
    rend_frame *frame;              /* the session's REND_SESSION_FINAL (1 sample a pixel) */
    rend_frame *motion_frame;       /* the viewer's own, half size: drawn while the camera moves */
    int fb_w, fb_h;                 /* size of the session's images and frame; 0 = not made */
    scene_camera cam;
    uint32_t camera_index;          /* the scene camera C last selected */
    int camera_moved;               /* the camera moved this frame */
    int view_pending;               /* it moved since the last ID pass (which waits for it to rest) */
    int fresh_view;                 /* the camera moved: take the next snapshot at once */
    int start_changed;              /* before the first snapshot: something drawn changed since the last frame */
    double snap_taken;              /* when the snapshot drawn was acquired */
    double last_input;              /* when the last frame's input was taken (fly speed) */
    int paused;                     /* P: the user paused refinement */
    int motion_paused;              /* the camera is moving: refinement rests (not the user's pause) */
    int start_paused;               /* refinement rests until the first snapshot is drawn (start_session) */
    double last_motion;
    float exposure;                 /* stops */
    uint32_t light_count, light;    /* the scene's lights; the one the keys edit */
    float *light_scale;             /* per light: power relative to the scene's */
    float *light_tint;              /* per light, RGB: colour multiplier of the scene's (K cycles presets) */
    uint32_t *light_preset;         /* per light: the K preset shown (0 = the scene's colour) */
    int emission_dirty;             /* the renderer's emitters differ from light_scale */
    unsigned components;            /* REND_FRAME_COMPONENT_* shown */
    int help;                       /* the help overlay is on */
    int bounces;                    /* B: the bounces asked (cache_desc.bounces; kept over reloads) */
    /* Mesh overlay (paper Fig. 4b/4c, rend_debug.h): 0 off, else 1 + the mesh
     * (0 direct, 1 indirect, 2 specular, 3 + l light l); the image made on the CPU
     * is kept until the snapshot, the camera, the size or the choice changes. */
    int overlay, overlay_points;
    uint8_t *ov_bg, *ov_rgb;
    uint32_t *ov_ids;
    int ov_w, ov_h, ov_stale;
    uint64_t ov_generation;
    /* Samples per second for the HUD: all samples at the start of the current
     * one-second window, and the rate measured over the last one. */
    double rate_t0, rate;
    uint64_t rate_samples0;
    const cache_snapshot *snap;     /* the last acquired, valid until the next acquire */
    uint64_t frames, id_passes, screenshots, reloads;
    double t_open, first_image, id_seconds;
    view_app_startup startup;       /* seconds from t_open (window: before it); < 0 until reached */
    rend_frame_times times;
    int drawn;                      /* a frame with the current sizes exists */
    view_accum *accum;              /* the resting picture (view_accum.h) */
    uint32_t accum_n;               /* draws in it by weight (VIEW_ACCUM_SIDE²: complete) */
    uint32_t accum_i;               /* draws since it started: the next offset */
    double accum_next;              /* when the next draw into it may start */
    view_accum_key accum_key;       /* what it shows */
    GLuint shown;                   /* the linear picture the last frame showed: the frame's, the mean or
                                       the residual's correction of the mean */
    /* The resting picture corrected by path-traced samples while the worker is idle
     * (view_residual.h; docs/viewer.md "The residual"). */
    view_residual *residual;
    int residual_on;                /* started for residual_key */
    view_accum_key residual_key;    /* the resting picture it corrects */
    uint64_t residual_seq;          /* the last correction taken */
    rend_residual_info residual_info;
    float *residual_rgb;            /* read-back, then the correction shown, fb_w·fb_h·3, top row first */
    float *residual_up;             /* the same bottom-up, as uploaded */
    size_t residual_cap;            /* floats each holds */
    float *residual_lights;         /* 3 per light: what the lights emit now */
    GLuint residual_tex;            /* the correction shown (RGB32F); 0 = none made */
    int residual_shown;             /* residual_tex holds a correction of residual_key (or the peer's picture) */
    int residual_current;           /* ...of residual_key's camera, not of one before it (a peer's moving view) */
    int residual_hold;              /* a script's peer-picture/peer-preview was met: the next frame keeps the
                                     * picture it was met by (its screenshot shows that one, not a newer pass) */
    ref_estimator indirect;         /* I: the cache (PATHS), or the peer shown at rest (VPL, BDIR) */
    ref_vpl_visibility indirect_visibility; /* the peer's visibility: shadow rays or imperfect shadow maps */
    int peer_on;                    /* the residual's thread renders the peer for residual_key, */
    int peer_bounces;               /* with these bounces */
    ref_estimator peer_kind;        /* and this estimator */
    ref_vpl_visibility peer_visibility; /* and this visibility */
    /* The script: the command running and when it started. */
    size_t si;
    int cmd_started;
    double cmd_t0;
    uint64_t cmd_frames0, cmd_generation0;
    int quit;
    int in_script;                  /* apply_action runs for a script command */
    char shot[VIEW_SCRIPT_PATH_MAX];/* screenshot to take after this frame's draw; "" = none */
    int shot_exr_too;               /* F12: shot is a .png, write the .exr beside it */
    char window_shot[VIEW_SCRIPT_PATH_MAX]; /* the whole window after this frame's draw; "" = none */
} view_state;

/* K's colour names, by preset ("" for the scene's own colour). */
extern const char *const view_light_preset_names[];

void view_app_report_of(const view_state *v, view_app_report *r);
/* The last frame showed the resting picture (the mean of jittered draws), or its correction. */
static inline int view_app_showing_mean(const view_state *v)
{
    return v->shown && (v->shown == view_accum_texture(v->accum) || v->shown == v->residual_tex);
}
static inline int view_app_showing_residual(const view_state *v) { return v->residual_tex && v->shown == v->residual_tex; }
/* v->shot (PNG as shown, EXR linear; with shot_exr_too the EXR beside the PNG). */
lm_result view_app_take_screenshot(view_state *v, lm_error *err);
/* The mesh overlay over the picture in the window; nothing without data. */
lm_result view_app_draw_overlay(view_state *v, int w, int h, GLuint texture, const tm_desc *tm, lm_error *err);
/* The HUD's lines. */
void view_app_hud_text(view_state *v, char *out, size_t size);
void view_app_update_title(view_state *v);

#endif
