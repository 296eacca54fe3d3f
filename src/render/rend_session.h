/* rend_session.h — one progressive render as the front ends run it: the GL
 * context, the ID pass, the refinement worker and the renderers, wired once
 * (`lumesh render`, `lumesh converge` and `lumesh view` are built on it).
 *
 * What it owns, and in which order it makes it:
 *   - the GL context: made headless on desc.gl_platform (gl_context.h), or the
 *     caller's (desc.gl: the viewer's window), borrowed, never destroyed;
 *   - the ID pass (rend_id.h) at width × height, made at the first view; with
 *     desc.ids_by_rays the first one by Embree's rays, in an Embree scene that
 *     the worker's samplers then use, freed once the worker is retired;
 *   - the refinement worker (cache_worker.h) with desc's sampler and limits;
 *   - two renderers (rend_frame.h) at width × height, each made at its first use:
 *     REND_SESSION_FINAL with desc.supersample samples a pixel (the offline
 *     image), REND_SESSION_PREVIEW with one (a first image as a viewer shows it).
 * desc.order says what comes first:
 *   REND_SESSION_ID_FIRST      the context, the ID pass at *desc.camera, then the
 *                              worker with its pixel counts: refinement follows
 *                              the view from its first step (render, by rays:
 *                              no context until the first draw);
 *   REND_SESSION_WORKER_FIRST  the worker first (cache_worker_desc.pixels_later):
 *                              it makes the coarse cache while this thread makes
 *                              the context and a renderer; the ID pass waits for
 *                              rend_session_set_view / _set_pixels, so it cannot
 *                              delay the first image (converge, view).
 *
 * Usage (one thread, the display's):
 *     rend_session_desc d = {.scene = s, .camera = &cam, .max_tested = 5000};
 *     rend_session_desc_defaults(&d);         // optional: create applies it to its copy
 *     rend_session *rs;
 *     if (rend_session_create(&d, &rs, &err) != LM_OK) ...;   // err says what to try
 *     const cache_snapshot *snap;
 *     rend_session_wait(rs, &(rend_session_wait_desc){.until = lm_now_seconds() + 10}, &snap, &err);
 *     rend_session_draw(rs, REND_SESSION_FINAL, &cam, rgb, &err);  // rgb: w·h·3 floats, or NULL
 *     rend_session_destroy(rs);
 * A viewer: .gl = its window's table, .order = REND_SESSION_WORKER_FIRST; on a
 * resize rend_session_resize; after a camera move rend_session_set_view; each
 * frame rend_session_acquire and a draw without read-back, the picture taken
 * from rend_session_renderer's rend_frame_get_output.
 *
 * Threads: every call on the thread that created the session, where the GL
 * context is current (a made one is current there from create on; a borrowed
 * one must be). The worker's thread is private to it (cache_worker.h); the
 * caller may pause, resume, edit lights and switch the debug data through
 * rend_session_worker's cache_worker API, but not destroy the worker.
 * Lifetimes: the snapshot of rend_session_acquire / _snapshot / _wait stays valid
 * until the next acquire or wait (cache_worker_acquire); a rend_frame of
 * rend_session_renderer until rend_session_resize, _drop_renderer or _destroy.
 * Units: pixels for sizes, seconds of lm_now_seconds for times.
 *
 * Does NOT do: windows, tone mapping, writing images, the viewer's half-size
 * renderer for moves, pacing or measuring (the front ends'); several scenes (a
 * reload is a new session); sharing one worker between sessions.
 */
#ifndef LUMESH_REND_SESSION_H
#define LUMESH_REND_SESSION_H

#include <signal.h>
#include <stdint.h>

#include <glad/gl.h>

#include "mesh/cache/cache_worker.h"
#include "sampling/samp.h"
#include "src/base/util.h"
#include "src/gpu/gl_platform.h"
#include "src/render/rend_frame.h"
#include "src/scene/scene.h"

#ifdef __cplusplus
extern "C" {
#endif

/* The sampler's defaults for a preview (rend_session_desc_defaults): the mean
 * relative error tolerated in penumbra and in indirect samples, the cache's 2%. */
#define REND_SESSION_TARGET_ERROR_DEFAULT 0.02f
/* The worker's JND floor (cache_worker_desc.jnd_floor) by default: after converging
 * at the cache's JND (ΔE 2) it halves it twice, so a still view keeps sharpening
 * (docs/cache.md "Never plateau"); past that the front ends path-trace the
 * residual (rend_residual.h), which lowers the error faster than refining on to
 * 0.25 or 0.125 did (docs/cache.md, "The cache as a control variate"). */
#define REND_SESSION_JND_FLOOR_DEFAULT 0.5f
/* What converge and view ask for as rend_session_desc.first_budget: leaves tested
 * before the first image (docs/renderer.md, "The first image": on
 * CornellBox-Original at 640×480 mean ΔE 13.6 → 1.3 for 5–10 ms more). */
#define REND_SESSION_FIRST_BUDGET_VIEWER 320u

typedef enum rend_session_order {
    REND_SESSION_ID_FIRST = 0,  /* default; needs desc.camera */
    REND_SESSION_WORKER_FIRST,
    REND_SESSION_ORDER_COUNT
} rend_session_order;

typedef enum rend_session_renderer_kind {
    REND_SESSION_FINAL = 0,     /* desc.supersample samples a pixel */
    REND_SESSION_PREVIEW,       /* 1 sample a pixel */
    REND_SESSION_RENDERER_COUNT
} rend_session_renderer_kind;

/* A GL context being made on a helper thread, for a client that loads its scene
 * meanwhile (as a viewer opens its window while it loads), with the session's
 * preview renderer made ahead of the scene (rend_frame_set_scene): the driver's
 * start (about 80 ms of llvmpipe's on a 2-core machine), the GLSL compiler's
 * (~22 ms), the renderer's shader variants (~40 ms) and, once the client gives
 * the size, its images (~40 ms at 640×480) then overlap the loading instead of
 * delaying the first image (docs/renderer.md, "The renderer made ahead").
 * Started before the load;
 * handed to rend_session_create (rend_session_desc.early_gl), which waits for it,
 * makes it current on its own thread and owns it from then on, as a context of
 * its own; a client that makes no session ends it (rend_session_early_gl_end).
 * If it fails, the session makes its context as without it (and reports that
 * attempt's error). Threads: start, end and the session's create on one thread. */
typedef struct rend_session_early_gl rend_session_early_gl;
lm_result rend_session_early_gl_start(glctx_platform platform, rend_session_early_gl **out, lm_error *err);
void rend_session_early_gl_end(rend_session_early_gl *e); /* NULL is a no-op */
/* The size the session's preview renderer (REND_SESSION_PREVIEW) will have, as
 * soon as the client knows it: the helper makes that renderer's images at it
 * while the client loads. Without it they are made at the first draw. */
void rend_session_early_gl_size(rend_session_early_gl *e, int width, int height);

/* Zero fields mean "default" (rend_session_desc_defaults says which). */
typedef struct rend_session_desc {
    const scene *scene;            /* required; must outlive the session */
    const scene_camera *camera;    /* the first view (REND_SESSION_ID_FIRST: required); copied */
    int width, height;             /* pixels of the ID pass and the renderers; 0 = the camera's
                                      (WORKER_FIRST without a camera: 0 until rend_session_resize) */
    rend_session_order order;
    const GladGLContext *gl;       /* a context current on this thread, borrowed; NULL = make one */
    rend_session_early_gl *early_gl; /* or NULL: taken over by rend_session_create (not with gl), whatever
                                      it returns */
    glctx_platform gl_platform;    /* the context made, and the GL sampler's when sampler.gl_platform
                                      is 0; 0 = GLCTX_EGL */
    samp_desc sampler;             /* the worker's sampler (.scene is set); target errors 0 =
                                      REND_SESSION_TARGET_ERROR_DEFAULT, backend 0 = auto */
    int supersample;               /* REND_SESSION_FINAL's s (rend_frame_desc); 0 =
                                      REND_FRAME_SUPERSAMPLE_DEFAULT */
    float sample_pixels;           /* the area of one sample of the pictures drawn, in pixels: the
                                      smallest leaf the cache tests (cache_desc.sample_pixels);
                                      0 = 1/supersample²; drawn accumulated k×k, 1/(k·supersample)² */
    uint64_t max_tested;           /* the worker stops after this many leaf tests; 0 = no limit */
    int ids_by_rays;               /* ID_FIRST: the first ID pass by Embree's primary rays through the
                                      pixel centres (the triangles the GL pass finds, rend_id.h), so no
                                      GL context is made before the first draw: a client that draws only
                                      at the end (render) refines without the GL driver resident (LLVM
                                      and llvmpipe, ~60 MB; docs/memory.md) */
    int final_one_snapshot;        /* REND_SESSION_FINAL draws one snapshot (render): its renderer keeps no
                                      CPU copy of the meshes and no image per term
                                      (rend_frame_desc.one_snapshot) */
    int publish_debug;             /* snapshots carry the debug data (cache_worker_desc.publish_debug) */
    int single_mesh;               /* cache_desc.single_mesh: one mesh for all terms */
    uint32_t first_budget;         /* WORKER_FIRST with a camera and a size: leaves the worker tests before
                                      its first snapshot (and up to a fifth more indirect ones:
                                      cache_worker_desc.first_budget), by pixel counts guessed from the camera
                                      (camera_triangle_pixels), and it refines on by them until the ID
                                      pass: a first image with shadows (docs/renderer.md); 0 = none */
    int bounces;                   /* diffuse bounces (cache_desc.bounces): 1..CACHE_BOUNCES_MAX or
                                      CACHE_BOUNCES_AUTO; 0 = auto */
    cache_glossy glossy;           /* cache_desc.glossy: what glossy materials reflect; 0 = the lights
                                      and the room (CACHE_GLOSSY_INDIRECT) */
    float jnd_floor;               /* ΔE: after converging, the worker refines on to this JND
                                      (cache_worker_desc.jnd_floor); 0 = REND_SESSION_JND_FLOOR_DEFAULT;
                                      < 0: it stops at the cache's JND */
} rend_session_desc;

/* Fills d's zero fields with the defaults above (idempotent). */
void rend_session_desc_defaults(rend_session_desc *d);

/* The area in pixels of one sample of a picture drawn k×k times (jittered,
 * averaged) with s×s samples a pixel: 1/(k·s)², rend_session_desc.sample_pixels
 * for a front end that accumulates. */
float rend_session_sample_pixels(int supersample, int accumulate);

typedef struct rend_session rend_session;

/* Makes what desc.order says, in that order. On failure nothing is left (out is
 * NULL) and err names the part that failed: a GL context that cannot be made
 * says which platform to try instead. */
lm_result rend_session_create(const rend_session_desc *desc, rend_session **out, lm_error *err);
/* Cancels and joins the worker, then frees the GL objects and a made context.
 * NULL is a no-op. */
void rend_session_destroy(rend_session *rs);
/* Ends the refinement and frees the cache (cache_worker_retire): the snapshot
 * held (rend_session_snapshot) stays valid and drawable; acquire, views and edits
 * bring nothing new after it. For a client done refining that only draws. */
void rend_session_retire_worker(rend_session *rs);
/* Frees the session's GL objects and the context it made (a borrowed one,
 * desc.gl, is left as it is) until a call needs GL again (an ID pass, a renderer,
 * read_ids), which makes them anew. For a client that waits long between draws:
 * `render` refining holds no llvmpipe context (~40 MB on the 116k box;
 * docs/memory.md). Renderers configured before (components, jitter) are made
 * again with their defaults. */
void rend_session_release_gl(rend_session *rs);

/* A new size for the ID pass and the renderers (a window resized): both are made
 * again at their next use; the worker keeps the counts of the last view until
 * the next rend_session_set_view. Same size: nothing happens. */
lm_result rend_session_resize(rend_session *rs, int width, int height, lm_error *err);

/* The ID pass at cam (the image is the session's width × height, whatever cam's);
 * its pixel counts and the eye go to the worker together (cache_worker_set_view:
 * the specular mesh starts again for the eye). */
lm_result rend_session_set_view(rend_session *rs, const scene_camera *cam, lm_error *err);
/* The same with the pixel counts only (cache_worker_set_pixels): the cache keeps
 * its eye (at first the scene's first camera). */
lm_result rend_session_set_pixels(rend_session *rs, const scene_camera *cam, lm_error *err);
/* The id image of the last view, width·height values (rend_id_read_image). */
lm_result rend_session_read_ids(rend_session *rs, uint32_t *ids, lm_error *err);

/* The latest published snapshot into *snap (NULL before the first; never waits).
 * A snapshot that says refinement failed is returned and LM_ERR_RUNTIME with its
 * error. */
lm_result rend_session_acquire(rend_session *rs, const cache_snapshot **snap, lm_error *err);
/* The snapshot of the last acquire (NULL: none yet). */
const cache_snapshot *rend_session_snapshot(const rend_session *rs);

typedef struct rend_session_wait_desc {
    double until;                     /* lm_now_seconds time to stop at, once a snapshot exists; <= 0: none */
    int first;                        /* non-zero: stop at the first snapshot */
    volatile sig_atomic_t *stop;      /* non-NULL: stop when it becomes non-zero (a SIGINT handler's) */
    double nap;                       /* seconds between looks; 0 = 0.005 */
    void (*on_look)(void *user, const cache_snapshot *snap); /* non-NULL: called after each look with the
                                                                snapshot acquired (NULL before the first),
                                                                on this thread: a progress display */
    void *user;                       /* on_look's */
} rend_session_wait_desc;

/* Acquires until a snapshot is finished, or (with one) `until` has come or
 * `first` is set, or *stop is set; *snap is the last one (NULL when stopped
 * before the first). Refinement failing ends it as rend_session_acquire does. */
lm_result rend_session_wait(rend_session *rs, const rend_session_wait_desc *w, const cache_snapshot **snap,
                            lm_error *err);

/* The renderer `kind`, made now if it was not: for rend_frame_get_output, its
 * components and emission. Owned by the session. out may be NULL (just make it). */
lm_result rend_session_renderer(rend_session *rs, rend_session_renderer_kind kind, rend_frame **out, lm_error *err);
/* Frees renderer `kind` (its GL images); made again at its next use. */
void rend_session_drop_renderer(rend_session *rs, rend_session_renderer_kind kind);
/* Draws the last acquired snapshot (none: emission only) seen from cam (at the
 * session's width × height) with renderer `kind`, read back into rgb (width·height·3
 * floats, linear, top row first) unless rgb is NULL (rend_frame_draw). */
lm_result rend_session_draw(rend_session *rs, rend_session_renderer_kind kind, const scene_camera *cam, float *rgb,
                            lm_error *err);

/* The last acquired snapshot drawn k×k times by renderer `kind`, each with the
 * sample grid moved by one of k×k offsets that stratify a cell of the s×s grid
 * (rend_frame_set_jitter), averaged into rgb (width·height·3 floats, required):
 * a (k·s)×(k·s) box filter per pixel, the anti-aliasing of a still view without
 * the memory of a larger s (docs/renderer.md). k ≤ 1 is rend_session_draw;
 * k is at most REND_SESSION_ACCUMULATE_MAX. Costs k² draws, each a full redraw;
 * info.times[kind].total is their sum. */
enum {
    REND_SESSION_ACCUMULATE_MAX = 8,
    REND_SESSION_ACCUMULATE_DEFAULT = 3 /* render's and converge's k: with s = 3 a 9×9 box filter (docs/renderer.md) */
};
lm_result rend_session_draw_accumulated(rend_session *rs, rend_session_renderer_kind kind, const scene_camera *cam,
                                        int k, float *rgb, lm_error *err);

typedef struct rend_session_info {
    int width, height;              /* pixels of the ID pass and the renderers */
    uint64_t id_passes;             /* ID passes run */
    double id_seconds;              /* the last one's wall time; 0 before the first */
    rend_frame_times times[REND_SESSION_RENDERER_COUNT]; /* each renderer's last draw (zeros: none) */
    uint64_t draws[REND_SESSION_RENDERER_COUNT];          /* draws by each renderer */
} rend_session_info;

void rend_session_get_info(const rend_session *rs, rend_session_info *out);

/* The worker, for pause / resume / set_light / set_publish_debug (not destroy). */
cache_worker *rend_session_worker(rend_session *rs);
/* The GL table every GL object of the session uses (the made or borrowed one). */
const GladGLContext *rend_session_gl(const rend_session *rs);

#ifdef __cplusplus
}
#endif
#endif
