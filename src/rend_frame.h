/* rend_frame.h — the renderer's passes after the ID pass (paper §6): a material
 * pass (kd, ks, Le per pixel), radiance passes that draw the cache's leaf
 * triangles with per-vertex values interpolated by the rasterizer (direct
 * diffuse, indirect, direct specular), and a full-screen composite
 *     Le + kd·(L_dd + E_i/π) + ks·L_ds
 * into a linear RGB image (tone mapping is the caller's: tonemap.h, the same
 * function the refinement criterion uses).
 *
 * Each radiance pass keeps its own depth: where a mesh's nearest surface is not
 * the visible one (a surface with kd = 0 or ks = 0 in front), the material pass's
 * coefficient for that term is 0 there, so the composite is still right.
 *
 * Usage (display thread, GL context current):
 *     rend_frame *f;
 *     rend_frame_create(gl, &(rend_frame_desc){.scene = s, .width = 640, .height = 480}, &f, &err);
 *     const cache_snapshot *snap = cache_worker_acquire(w);
 *     rend_frame_draw(f, &s->cameras[0], snap, rgb, &err);   // rgb: width·height·3, top row first
 *     rend_frame_destroy(f);
 *
 * Threads: everything on the thread where gl's context is current.
 * Does NOT do: the ID pass (rend_id.h), tone mapping, windows, incremental updates
 * of the radiance images (every draw redraws the snapshot).
 */
#ifndef LUMESH_REND_FRAME_H
#define LUMESH_REND_FRAME_H

#include <glad/gl.h>

#include "cache_worker.h"
#include "scene.h"
#include "util.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct rend_frame_desc {
    const scene *scene;   /* must outlive the renderer */
    int width, height;    /* pixels, 1..16384 */
} rend_frame_desc;

typedef struct rend_frame_times {
    double material, radiance, composite, readback; /* seconds of the last draw */
} rend_frame_times;

typedef struct rend_frame rend_frame;

lm_result rend_frame_create(const GladGLContext *gl, const rend_frame_desc *desc, rend_frame **out, lm_error *err);
void rend_frame_destroy(rend_frame *f); /* NULL is a no-op; needs gl's context current */

/* Draws the snapshot seen from cam into rgb (width·height·3 floats, linear, top
 * row first). A NULL snapshot draws emission only. */
lm_result rend_frame_draw(rend_frame *f, const scene_camera *cam, const cache_snapshot *snap, float *rgb,
                          lm_error *err);
void rend_frame_get_times(const rend_frame *f, rend_frame_times *out);

#ifdef __cplusplus
}
#endif
#endif
