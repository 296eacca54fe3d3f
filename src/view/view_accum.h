/* view_accum.h — the viewer's resting picture: the running mean of jittered
 * draws of rend_frame's output, on the GPU (shaders/view_accum.frag), as
 * `render --accumulate` averages them on the CPU (rend_session_draw_accumulated).
 * While the camera and the snapshot rest, each frame draws the picture once more
 * with its samples moved inside the pixel (rend_frame_jitter_pattern) and adds it:
 * after k² draws every pixel is the box filter of a regular k×k grid.
 *
 * Usage (GL context current):
 *     view_accum *a;
 *     view_accum_create(gl, &a, &err);
 *     rend_frame_set_jitter(f, jx, jy);                // the n-th offset of the pattern
 *     rend_frame_draw(f, &cam, snap, NULL, &err);
 *     view_accum_add(a, out.texture, out.width, out.height, n, &err); // n = 0 starts again
 *     view_tm_draw(tm, &target, view_accum_texture(a), &tmd, &err);
 *     view_accum_destroy(a);
 *
 * Units: linear radiance, as rend_frame's output (RGBA32F, GL row order).
 * Threads: the thread where gl's context is current (the viewer's display thread).
 * Does NOT do: choosing the offsets or deciding when to start again (view_app.c),
 * weighting other than the plain mean, reprojection across camera moves.
 */
#ifndef LUMESH_VIEW_ACCUM_H
#define LUMESH_VIEW_ACCUM_H

#include <stdint.h>

#include <glad/gl.h>

#include "src/base/util.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct view_accum view_accum;

lm_result view_accum_create(const GladGLContext *gl, view_accum **out, lm_error *err);
void view_accum_destroy(view_accum *a); /* NULL is a no-op; needs gl's context current */

/* Adds the draw in `texture` (width × height, linear RGB) as the (n+1)-th of the
 * mean: mean = draw when n = 0 (and whenever the size changed), else
 * mean + (draw − mean)/(n+1). */
lm_result view_accum_add(view_accum *a, GLuint texture, int width, int height, uint32_t n, lm_error *err);

/* The mean (RGBA32F, the size of the last add); 0 before the first. */
GLuint view_accum_texture(const view_accum *a);

/* Reads the mean back as width·height·3 floats, top row first. */
lm_result view_accum_read(view_accum *a, float *rgb, lm_error *err);

#ifdef __cplusplus
}
#endif

#endif
