/* rend_debug.h — debug images of the multi-mesh cache (Fournier & Péroche 2005,
 * Fig. 4b and 4c): for one published mesh, its leaf wireframe and the positions
 * of its samples, drawn over a dimmed copy of the rendered image.
 *
 * Input is only what the display side has: a published cache_snapshot_mesh (with
 * corner data: cache_worker_desc.publish_debug), the camera, the ID image
 * (rend_id_read_image) and a tone-mapped RGB8 image. Projection is the shared
 * pinhole camera (src/scene/camera.h).
 *
 * Occlusion, without depth: a wire pixel is drawn only where the ID image shows,
 * at that pixel or one of its 8 neighbours, a scene triangle the segment belongs
 * to (the neighbourhood keeps edges lying on silhouettes and on seams between
 * scene triangles); a sample point is drawn (as one dot per vertex, however many
 * leaves share it) when the ID image shows, at its pixel or a neighbour, one of
 * the triangles around it. Hidden geometry therefore shows at most one pixel past
 * the silhouette of what hides it.
 *
 * The wireframe draws leaf boundaries (CACHE_CORNER_LEAF_EDGE), not the fan
 * diagonals that make the published triangles crack-free; each segment (pair of
 * vertex ids) once.
 *
 * Usage:
 *     rend_debug_desc d = {.camera = &cam, .width = w, .height = h, .ids = ids, .background = rgb8};
 *     rend_debug_counts n;
 *     if (rend_debug_leaves(&d, &snap->lights[0], out_rgb8, &n, &err) != LM_OK) ...
 *     rend_debug_samples(&d, &snap->direct, out_rgb8, &n, &err);
 *     rend_debug_write_images(&(rend_debug_write_desc){.draw = &d, .snap = snap, .dir = "dbg"}, &err);
 *
 * Threads: no state; any thread, as long as the snapshot stays valid (the
 * display thread between two acquires).
 * Cost: CPU only; at 512×512, 5–35 ms a mesh (docs/renderer.md).
 * Does NOT do: GL, depth tests, anti-aliased lines, drawing values (the overlays
 * show where, not what).
 */
#ifndef LUMESH_REND_DEBUG_H
#define LUMESH_REND_DEBUG_H

#include <stdint.h>

#include "mesh/cache/cache_snapshot.h"
#include "src/base/util.h"
#include "src/scene/scene.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Defaults of rend_debug_desc. */
#define REND_DEBUG_DIM 0.4f                /* background brightness factor */
#define REND_DEBUG_WIRE_COLOR 0xFFD21EFFu  /* 0xRRGGBBAA: yellow, opaque */
#define REND_DEBUG_POINT_COLOR 0xFF2A2AFFu /* red, opaque */
#define REND_DEBUG_DOT_RADIUS 1            /* pixels: a 3×3 dot */

typedef struct rend_debug_desc {
    const scene_camera *camera;   /* required: the camera of ids and background */
    int width, height;            /* pixels, > 0 */
    const uint32_t *ids;          /* required: width·height, top row first; 0 = nothing, else scene triangle + 1 */
    const uint8_t *background;    /* width·height RGB8, top row first (tone-mapped); NULL = black */
    float dim;                    /* background factor in (0, 1]; 0 = REND_DEBUG_DIM */
    uint32_t wire_color;          /* 0xRRGGBBAA, alpha = opacity; 0 = REND_DEBUG_WIRE_COLOR */
    uint32_t point_color;         /* 0xRRGGBBAA; 0 = REND_DEBUG_POINT_COLOR */
    int dot_radius;               /* pixels, 0..16: pixels with dx² + dy² <= r² + r; 0 = REND_DEBUG_DOT_RADIUS */
} rend_debug_desc;

/* A copy of *d with every zero field replaced by its default. */
rend_debug_desc rend_debug_defaults(const rend_debug_desc *d);

/* What one overlay drew. */
typedef struct rend_debug_counts {
    uint32_t segments;            /* leaves: distinct leaf-boundary segments (vertex-id pairs) */
    uint32_t segments_drawn;      /* leaves: of those, with at least one pixel drawn */
    uint64_t wire_pixels;         /* leaves: pixels coloured */
    uint32_t points_drawn;        /* samples: distinct sampled vertices drawn */
    uint32_t points_hidden;       /* samples: the others (hidden, behind the camera or off the image) */
    uint64_t point_pixels;        /* samples: pixels coloured */
    double seconds;               /* wall time of the call */
} rend_debug_counts;

/* The leaf wireframe of m over the dimmed background, into out_rgb (width·height·3
 * bytes, top row first). Errors: LM_ERR_INVALID_ARG (missing or bad argument, or a
 * non-empty mesh without corner data), LM_ERR_NO_MEMORY. counts may be NULL. */
lm_result rend_debug_leaves(const rend_debug_desc *d, const cache_snapshot_mesh *m, uint8_t *out_rgb,
                            rend_debug_counts *counts, lm_error *err);

/* The sampled vertices of m (CACHE_CORNER_SAMPLED) as dots over the dimmed
 * background; each vertex once. points_drawn + points_hidden = the distinct
 * sampled vertex ids of m. Errors as rend_debug_leaves. */
lm_result rend_debug_samples(const rend_debug_desc *d, const cache_snapshot_mesh *m, uint8_t *out_rgb,
                             rend_debug_counts *counts, lm_error *err);

/* Where world point p lands: (*px, *py) in pixels from the image's top-left corner
 * (pixel (i, j) spans [i, i+1) × [j, j+1)). Returns 0 when p is not in front of
 * the camera (then *px, *py are untouched), else 1 (on the image or not). */
int rend_debug_project(const rend_debug_desc *d, const float p[3], double *px, double *py);

/* Called after each file rend_debug_write_images writes. */
typedef void (*rend_debug_written_fn)(const char *path, const rend_debug_counts *counts, void *user);

typedef struct rend_debug_write_desc {
    const rend_debug_desc *draw;  /* required */
    const cache_snapshot *snap;   /* required, with corner data (publish_debug) */
    const char *dir;              /* required; created (with its parents) if missing */
    rend_debug_written_fn written;/* NULL = none */
    void *user;
} rend_debug_write_desc;

/* Writes DIR/<mesh>-leaves.png and DIR/<mesh>-samples.png (img_write: through a
 * temporary file) for the meshes light0, light1, ..., direct, indirect and, when
 * the snapshot has one, specular. */
lm_result rend_debug_write_images(const rend_debug_write_desc *wd, lm_error *err);

#ifdef __cplusplus
}
#endif
#endif
