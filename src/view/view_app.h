/* view_app.h — `lumesh view`'s engine: a window on the renderer while the
 * refinement worker sharpens the image (paper §6: the display shows what the
 * cache has, the worker refines it in the meantime).
 *
 * The ID pass, the worker and the renderer are a render session (rend_session.h,
 * worker first) on the window's GL context. Each frame: input (or the script's
 * next commands), the ID pass again after a camera move (its pixel counts go to the worker: cache_worker_set_pixels, the
 * view-independent caches are kept), the latest published snapshot (acquired
 * without waiting), rend_frame at one sample a pixel without read-back, and the
 * tone-mapping pass (view_tonemap.h) into the window. Frames are paced to
 * max_fps, so the display redraws steadily whatever the worker does.
 *
 * Usage (main thread):
 *     view_app_desc d = {.scene = s, .camera = 0, .session = {.sampler = sd}, .script = cmds, .script_count = n};
 *     lm_result r = view_app_run(&d, &err);
 *
 * A camera move (orbit, pan, zoom, fly, look, another named camera) runs the ID
 * pass again and hands the worker its pixel counts and the new eye together
 * (cache_worker_set_view): the specular mesh starts again for the new eye, the
 * view-independent meshes stay.
 *
 * A HUD (view_hud.h) in the top-left corner: frame rate and pass times, samples
 * per second, samples per mesh, memory, the display state; H adds the keys.
 *
 * Does NOT do: culling leaves the ID pass found hidden, mesh overlays.
 */
#ifndef LUMESH_VIEW_APP_H
#define LUMESH_VIEW_APP_H

#include <stddef.h>
#include <stdint.h>

#include "mesh/cache/cache_worker.h"
#include "src/base/util.h"
#include "src/render/rend_frame.h"
#include "sampling/reference.h"
#include "src/render/rend_session.h"
#include "src/scene/scene.h"
#include "src/view/view_script.h"

#ifdef __cplusplus
extern "C" {
#endif

enum { VIEW_APP_DEFAULT_FPS = 60 };

/* Where the time to the first image went, in seconds from the window opening
 * (each < 0 until reached): what a slow first image is looked for in. */
typedef struct view_app_startup {
    double load;           /* BEFORE the clock: the scene's reading, from the command's start to the scene
                              loaded (view_app_desc.scene_load_seconds); < 0 = not known */
    double window;         /* BEFORE the clock: from the scene loaded (view_app_desc.scene_loaded_at) to the
                              window and its GL context open; < 0 = not known */
    double session;        /* the render session made: the worker started (the renderer comes at the first frame) */
    double display;        /* the tone mapping, HUD and resting-picture objects made */
    double residual;       /* the path-traced residual made (its Embree scene); = display without one */
    double first_snapshot; /* the worker's first snapshot acquired (after the first frame's renderer is made) */
} view_app_startup;

/* What the run measured, for the caller's report and --stats. */
typedef struct view_app_report {
    const scene *scene;                /* the scene now (d->scene, or the last reload's) */
    const scene_camera *camera;        /* the camera now */
    int width, height;                 /* framebuffer pixels of the last frame */
    uint64_t frames;                   /* frames drawn */
    double seconds;                    /* from the window opening to now */
    double first_image_seconds;        /* from the window opening to the first frame with a snapshot; < 0 = none */
    view_app_startup startup;          /* the phases before it */
    double id_seconds;                 /* the last ID pass */
    uint64_t id_passes;                /* ID passes run (1 + camera moves and resizes) */
    const cache_snapshot *snap;        /* the last snapshot drawn; NULL = none yet */
    const rend_frame_times *frame;     /* the last frame's passes; NULL = none drawn */
    const char *renderer;              /* GL_RENDERER / GL_VERSION of the window */
    uint32_t rest_draws;               /* jittered draws averaged in the picture shown (0: one plain draw;
                                          the resting picture, docs/viewer.md) */
    uint32_t residual_spp;             /* the picture shown is the resting one corrected by this many path
                                          samples a pixel at least (view_residual.h); 0: not corrected */
    double residual_corrected;         /* the share of its blocks corrected */
    const char *indirect;              /* "cache", "vpl", "bdir", "vpl-ism" or "bdir-ism": what the
                                          picture at rest shows (I) */
    uint32_t peer_spp;                 /* the picture shown is a peer's (vpl, bdir) of this many samples a
                                          pixel at least; 0: the cache's */
    uint64_t peer_vpls;                /* ...and the VPLs it has made (BDIR: its candidates) */
    uint32_t peer_grid;                /* ...sampled at one pixel in peer_grid² (a new view's first pass, the
                                          rest interpolated); 1: every pixel */
    int peer_earlier;                  /* ...of the camera before: the view moved since (until the new one's) */
    double peer_seconds;               /* ...its renderer's time in passes (since made: size, bounces, light
                                          edits), and of it making VPLs (and shadow maps) */
    double peer_vpl_seconds;
    float exposure;                    /* the display's exposure (stops; + and −), which the cache judges
                                          at once its worker has taken it (snap->estimate.exposure) */
} view_app_report;

typedef struct view_app_desc {
    const scene *scene;               /* must outlive the run */
    int camera;                       /* index into scene->cameras */
    int width, height;                /* window size; 0 = 1280 × 720 */
    rend_session_desc session;        /* the worker's sampler, GL platform and limits (zero fields:
                                         rend_session_desc_defaults); scene, sizes, order, gl,
                                         supersample and publish_debug are the viewer's */
    const view_cmd *script;           /* NULL: interactive until Esc / Q / the close button */
    size_t script_count;
    double max_fps;                   /* 0 = VIEW_APP_DEFAULT_FPS; < 0 = unpaced */
    double scene_loaded_at;           /* lm_now_seconds when the scene was loaded (startup.window); 0 = not known */
    double scene_load_seconds;        /* how long reading it took (startup.load); 0 = not known */
    int no_residual;                  /* non-zero: the resting picture is not corrected by path samples
                                         (view_residual.h) */
    ref_estimator indirect;           /* what shows the picture while the camera rests (I cycles it):
                                         REF_ESTIMATOR_PATHS the cache; VPL or BDIR that peer of it,
                                         rendered on the residual's thread (docs/peers.md), the cache's
                                         picture shown until its first pass */
    ref_vpl_visibility indirect_visibility; /* the peer's: shadow rays or imperfect shadow maps (vpl-ism,
                                         bdir-ism; made on session.gl_platform's GL) */
    void *user;
    /* Called after each screenshot is written (report->snap: the snapshot in it). */
    void (*screenshot)(const char *path, const view_app_report *report, void *user);
    /* R: a new scene from the same file (the caller's; NULL: R does nothing). On
     * error the viewer prints the reason and keeps the scene it shows. */
    lm_result (*reload)(void *user, const scene **fresh, lm_error *err);
    /* A scene the viewer no longer uses (after a reload): the caller may free it. */
    void (*release)(void *user, const scene *old);
    /* Called once when the run ends without error, before the worker is destroyed. */
    lm_result (*finished)(const view_app_report *report, void *user, lm_error *err);
} view_app_desc;

lm_result view_app_run(const view_app_desc *desc, lm_error *err);

/* What shows a still view, by name ("cache", "vpl", "bdir", "vpl-ism", "bdir-ism";
 * --indirect and the I key): 1 when the name is one, else 0. */
int view_app_indirect_from_name(const char *name, ref_estimator *peer, ref_vpl_visibility *visibility);
const char *view_app_indirect_name(ref_estimator peer, ref_vpl_visibility visibility);

#ifdef __cplusplus
}
#endif
#endif
