/* view_tonemap.h — the viewer's display pass: rend_frame's linear output texture
 * tone-mapped on the GPU (shaders/view_tonemap.frag) with exactly the function of
 * tonemap.h (exposure, clamp, sRGB), into the window or into an 8-bit image.
 *
 * Usage (GL context current):
 *     view_tm *t;
 *     view_tm_create(gl, &t, &err);
 *     view_tm_draw(t, &(view_tm_target){.width = fb_w, .height = fb_h}, out.texture, &tm, &err); // window
 *     view_tm_read(t, out.texture, out.width, out.height, &tm, rgb8, &err);  // a screenshot
 *     view_tm_destroy(t);
 *
 * Threads: the thread where gl's context is current.
 * Does NOT do: filtering when the texture and the target differ in size (nearest
 * pixel), colour management, auto exposure, text.
 */
#ifndef LUMESH_VIEW_TONEMAP_H
#define LUMESH_VIEW_TONEMAP_H

#include <stdint.h>

#include <glad/gl.h>

#include "src/base/tonemap.h"
#include "src/base/util.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct view_tm_target {
    GLuint framebuffer;   /* 0 = the window's default framebuffer */
    int width, height;    /* pixels of the viewport drawn, > 0 */
} view_tm_target;

typedef struct view_tm view_tm;

lm_result view_tm_create(const GladGLContext *gl, view_tm **out, lm_error *err);
void view_tm_destroy(view_tm *t); /* NULL is a no-op; needs gl's context current */

/* Draws `texture` (linear RGB, as rend_frame_output.texture) tone-mapped over the
 * whole target. Puts back the viewport and the draw framebuffer; leaves program,
 * vertex array and texture unit 0 at GL's defaults. Expects blending, depth and
 * scissor tests off and GL_FRAMEBUFFER_SRGB off (GL's defaults). */
lm_result view_tm_draw(view_tm *t, const view_tm_target *target, GLuint texture, const tm_desc *tm, lm_error *err);

/* Tone maps `texture` (width × height) into an 8-bit image the same size and reads
 * it: rgb, width·height·3 bytes, top row first (img_write's order). */
/* Shows an 8-bit RGB image (width·height·3 bytes, top row first: a debug
 * overlay made on the CPU) in the default framebuffer of the same size. */
lm_result view_tm_show_rgb8(view_tm *t, const uint8_t *rgb, int width, int height, lm_error *err);
lm_result view_tm_read(view_tm *t, GLuint texture, int width, int height, const tm_desc *tm, uint8_t *rgb,
                       lm_error *err);

#ifdef __cplusplus
}
#endif
#endif
