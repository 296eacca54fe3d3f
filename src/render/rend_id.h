/* rend_id.h — the renderer's ID pass (paper §6, first pass; §4.3.3 uses it for
 * priorities): scene triangles drawn with their ids as colours, then counted, so
 * the cache knows which triangles are visible and how many pixels each covers.
 *
 * Counting, two ways (rend_id_desc.count):
 *   REND_ID_COUNT_READBACK  the id image is read back and counted on the CPU
 *                           (default: measured faster on llvmpipe, 640×480:
 *                           1.0 ms against 8.4 ms on CornellBox-Original, 3.1
 *                           against 23.7 ms on Water; tests/rend_id_test.c);
 *   REND_ID_COUNT_GPU       a compute pass sums each 16×16 block per id and adds
 *                           into a per-triangle buffer; only tri_count counters
 *                           are read back (for GPUs, where the read-back is the
 *                           slow part).
 * Either way the id image can be had too (rend_id_read_image), top row first,
 * 0 = no triangle, else triangle id + 1, pixel for pixel the triangle the
 * reference path tracer's primary ray hits through the pixel centre (same
 * camera, src/scene/camera.h).
 *
 * Usage:
 *     rend_id *ip;
 *     if (rend_id_create(gl, &(rend_id_desc){.scene = s, .width = 640, .height = 480}, &ip, &err)) ...
 *     rend_id_result res;
 *     rend_id_render(ip, &s->cameras[0], &res, &err);   // res.pixels[t]: pixels of triangle t
 *     rend_id_destroy(ip);
 *
 * Threads: everything on the thread where gl's context is current. The counts
 * in a result stay valid until the next rend_id_render.
 * Does NOT do: multisampling (a pixel belongs to the triangle at its centre),
 * culling, transparency.
 */
#ifndef LUMESH_REND_ID_H
#define LUMESH_REND_ID_H

#include <stdint.h>

#include <glad/gl.h>

#include "src/base/util.h"
#include "src/scene/scene.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum rend_id_count {
    REND_ID_COUNT_READBACK = 0, /* default */
    REND_ID_COUNT_GPU,
    REND_ID_COUNT_COUNT
} rend_id_count;

typedef struct rend_id_desc {
    const scene *scene;      /* must outlive the pass */
    int width, height;       /* pixels, > 0 */
    rend_id_count count;
} rend_id_desc;

typedef struct rend_id_result {
    const uint32_t *pixels;  /* tri_count entries: pixels covered by each triangle */
    const uint32_t *visible; /* ids of the triangles with pixels > 0, increasing */
    uint32_t visible_count;
    uint64_t covered;        /* pixels showing any triangle */
    double seconds;          /* wall time of the pass, draw to counts on the CPU */
} rend_id_result;

typedef struct rend_id rend_id;

lm_result rend_id_create(const GladGLContext *gl, const rend_id_desc *desc, rend_id **out, lm_error *err);
void rend_id_destroy(rend_id *ip); /* NULL is a no-op; needs gl's context current */

lm_result rend_id_render(rend_id *ip, const scene_camera *cam, rend_id_result *out, lm_error *err);

/* The id image of the last render, width·height values, top row first. */
lm_result rend_id_read_image(rend_id *ip, uint32_t *ids, lm_error *err);

/* The counts without GL: Embree's primary ray through each pixel centre (the
 * triangle the GL pass names in all but edge pixels, tests/rend_id_test.c),
 * counted into pixels (tri_count entries) on every core, in rt (an Embree scene
 * of s, rt_scene.h) or, when rt is NULL, in one it builds and destroys. For a
 * client that must not make a GL context before it draws (render:
 * docs/memory.md). */
struct rt_scene;
lm_result rend_id_count_rays(const scene *s, const struct rt_scene *rt, const scene_camera *cam, int width,
                             int height, uint32_t *pixels, lm_error *err);

#ifdef __cplusplus
}
#endif
#endif
