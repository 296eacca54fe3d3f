/* view_residual.h — the viewer's path-traced residual (rend_residual.h) on a
 * thread of its own: while the camera rests on a cache that has nothing left to
 * do (finished, or paused by the user), the resting picture keeps converging to
 * the truth instead of stopping where the cache stopped.
 *
 * Usage (display thread):
 *     view_residual *vr;
 *     view_residual_create(scene, &vr, &err);                  // the thread waits, idle
 *     view_residual_start(vr, &(view_residual_view){...}, mean, &err); // the resting picture read back
 *     if (view_residual_take(vr, rgb, &seq, &info)) upload(rgb);   // each frame: a newer correction?
 *     view_residual_stop(vr);                                  // the view, a light or the terms changed
 *     view_residual_destroy(vr);
 * A start with the same view (camera, size, bounces, lights) as the samples it has
 * goes on with them and corrects the new picture; any other view forgets them.
 * A start with view.peer VPL or BDIR runs that estimator of the reference
 * renderer instead (instant radiosity: docs/peers.md) and hands back its own
 * picture: the viewer's --indirect vpl|bdir. Its VPLs are kept across camera
 * moves (ref_desc.vpl_keep: the thesis's temporal reuse), not across light edits.
 * A peer's new view is first sampled at one pixel in k×k (k so that the pass
 * takes about 0.05 s) and that picture, filled in between, is handed back at
 * once; then whole passes. While the camera moves (starts that differ only in
 * the camera) the newest picture of an earlier view is still handed back and
 * stands until the new view's own: the moving view is the peer's, a pass late.
 *
 * Threads: every call on the display thread. The thread made by create owns the
 * rend_residual (its BVH, its passes: rend_residual.h's one thread); the starts
 * it is given and the pictures it hands back go through state behind one mutex,
 * never held while it builds a BVH or path-traces. The passes use every core but
 * one (the display's); the worker is idle meanwhile.
 * Units: linear RGB, width·height·3 floats, top row first (view_accum_read's).
 * Does NOT do: GL, choosing when to run (view_app.c), reprojection across moves
 * (a moving view's picture is of the camera its pass began at).
 */
#ifndef LUMESH_VIEW_RESIDUAL_H
#define LUMESH_VIEW_RESIDUAL_H

#include <stdint.h>

#include "src/base/util.h"
#include "src/render/rend_residual.h"
#include "src/scene/scene.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct view_residual view_residual;

/* What the samples are of: a start with another view forgets them. */
typedef struct view_residual_view {
    scene_camera cam;          /* with the picture's width and height */
    int bounces;               /* the model's diffuse bounces (what the cache shows) */
    const float *light_values; /* 3 per light (area, then point): radiance or intensity now */
    ref_estimator peer;        /* REF_ESTIMATOR_PATHS: correct the cached picture (the residual);
                                  VPL, BDIR: show that peer's own picture of the view instead (the
                                  viewer's --indirect, docs/peers.md): the cached picture is not
                                  used, and a picture is handed back from its first complete pass */
    ref_vpl_visibility visibility; /* a peer's: shadow rays, or imperfect shadow maps (GL, made on
                                      the residual's thread in a context of its own) */
    glctx_platform gl_platform;    /* the maps' GL (default EGL) */
} view_residual_view;

/* s must outlive the residual. The thread starts idle. */
lm_result view_residual_create(const scene *s, view_residual **out, lm_error *err);
/* Stops and joins the thread. NULL is a no-op. */
void view_residual_destroy(view_residual *vr);

/* Corrects `cached` (the resting picture, copied) seen as `view` says, from now on
 * until view_residual_stop; with a peer (view->peer), renders the view instead
 * (`cached` may be NULL). */
lm_result view_residual_start(view_residual *vr, const view_residual_view *view, const float *cached, lm_error *err);
/* The thread stops sampling at the end of its slice (at most 0.2 s) and hands
 * back nothing more until the next start. */
void view_residual_stop(view_residual *vr);

/* When the thread has a corrected picture newer than *seq, made with enough
 * samples to correct anything (rend_residual_desc.min_samples): copies it into
 * rgb (the size of the last start), its statistics into info (may be NULL),
 * into *current (may be NULL) 1 when it is of the last start's view, 0 when of
 * an earlier one it stands for (a peer's, the camera moved since), updates *seq
 * and returns 1. Else 0. Never waits for a pass. */
int view_residual_take(view_residual *vr, float *rgb, uint64_t *seq, rend_residual_info *info, int *current);

#ifdef __cplusplus
}
#endif
#endif
