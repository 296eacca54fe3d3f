/* rend_frame.h — the renderer's passes after the ID pass (paper §6): a material
 * pass (which material, and which side, is seen at each sample), radiance passes
 * that draw the cache's leaf triangles with per-vertex values interpolated by the
 * rasterizer (direct diffuse, indirect, direct specular), and a full-screen
 * composite
 *     Le + kd·(L_dd + E_i/π) + ks·L_ds
 * per sample, box-filtered over the s×s samples of each pixel, into a linear RGB
 * image (tone mapping is the caller's: tonemap.h, the same function the
 * refinement criterion uses).
 *
 * Each radiance pass keeps its own depth: where a mesh's nearest surface is not
 * the visible one (a surface with kd = 0 or ks = 0 in front), the material's
 * coefficient for that term is 0 there, so the composite is still right.
 *
 * Anti-aliasing (desc.supersample = s): the material and radiance images are s
 * times the output's size, so their samples are the centres of an s×s grid in
 * each pixel; the composite is evaluated per sample and averaged (the reference
 * path tracer box-filters each pixel too). s = 1 samples the pixel centres.
 * The composite is linear in its terms, so at s > 1 each radiance term is
 * resolved (its product with the material, box-filtered) into an output-sized
 * image as soon as it is drawn, and the three terms take turns in one
 * sample-sized radiance image (docs/memory.md).
 *
 * What is redrawn: the material image depends only on the camera, so a draw
 * with the same camera as the last one keeps it. Each radiance image depends on
 * the camera and its mesh: with the same camera, a mesh whose triangles are the
 * same bytes as last time is neither uploaded nor drawn, and a changed one is
 * redrawn only inside the bounding rectangle of the triangles that changed
 * (widened to whole pixels, cleared there, drawn with all its triangles and
 * resolved there, so the image is bit for bit what a full redraw gives:
 * tests/rend_frame_test.c). A camera move redraws
 * everything. So a still camera under a refining cache costs what changed, a
 * still camera on a converged cache only the composite (rend_frame_times says
 * what was reused). A snapshot with the generation and arrays of the one drawn
 * before is taken as unchanged without comparing: after drawing snapshots of
 * another worker (generations restart), call rend_frame_invalidate.
 *
 * Usage (display thread, GL context current):
 *     rend_frame *f;
 *     rend_frame_create(gl, &(rend_frame_desc){.scene = s, .width = 640, .height = 480}, &f, &err);
 *     const cache_snapshot *snap = cache_worker_acquire(w);
 *     rend_frame_draw(f, &s->cameras[0], snap, rgb, &err);   // rgb: width·height·3, top row first
 *     rend_frame_times t;
 *     rend_frame_get_times(f, &t);                           // seconds per pass of that draw
 *     rend_frame_destroy(f);
 * An interactive viewer draws without read-back and shows the output texture:
 *     rend_frame_create(gl, &(rend_frame_desc){.scene = s, .width = w, .height = h, .supersample = 1}, &f, &err);
 *     rend_frame_draw(f, &cam, cache_worker_acquire(w), NULL, &err);
 *     rend_frame_output o;
 *     rend_frame_get_output(f, &o);
 *     // sample o.texture in a tone-mapping pass drawn to the window (linear values are
 *     // not displayable as they are), or blit o.framebuffer for a debug view
 *
 * Memory: GL images of 24 bytes per sample (s²·width·height samples: material
 * code, depth, the radiance image) and 64 per pixel (three resolved terms, the
 * output) at s > 1; 72 per pixel at s = 1 (code, depth, three radiance images,
 * output); a CPU copy of the snapshot's meshes (24 bytes per triangle corner).
 * Threads: everything on the thread where gl's context is current.
 * Viewer controls (cheap: only the composite uses them, it runs every draw):
 *     rend_frame_set_components(f, REND_FRAME_COMPONENTS_ALL & ~REND_FRAME_COMPONENT_INDIRECT);
 *     rend_frame_set_emission(f, s->area_lights[l].material, le, &err);  // a light edit shown on its emitter
 *
 * Does NOT do: the ID pass (rend_id.h), tone mapping, windows, culling leaves
 * that cannot be seen (docs/renderer.md), emission per light (Le is per material:
 * two lights of one material show the same edited Le).
 */
#ifndef LUMESH_REND_FRAME_H
#define LUMESH_REND_FRAME_H

#include <glad/gl.h>

#include "mesh/cache/cache_snapshot.h"
#include "src/base/util.h"
#include "src/scene/scene.h"

#ifdef __cplusplus
extern "C" {
#endif

/* The composite's terms, for rend_frame_set_components. */
enum {
    REND_FRAME_COMPONENT_DIRECT_DIFFUSE = 1u << 0,  /* kd·L_dd */
    REND_FRAME_COMPONENT_INDIRECT = 1u << 1,        /* kd·E_i/π */
    REND_FRAME_COMPONENT_DIRECT_SPECULAR = 1u << 2, /* ks·L_ds */
    REND_FRAME_COMPONENT_EMISSION = 1u << 3,        /* Le */
    REND_FRAME_COMPONENTS_ALL = 15u
};

enum {
    REND_FRAME_SUPERSAMPLE_DEFAULT = 3,         /* s for desc.supersample = 0 (offline renders:
                                                   docs/renderer.md has the error and cost per s) */
    REND_FRAME_DEFAULT_SAMPLES_MAX = 1 << 23,   /* ...lowered until s²·width·height is at most this
                                                   (24 bytes of GL images per sample: 200 MB) */
    REND_FRAME_SUPERSAMPLE_MAX = 8,
    REND_FRAME_BAND_SAMPLES = 1 << 19 /* rend_frame_desc.band_samples' default: 10 MB of band images
                                         (docs/renderer.md, "Bands": 2^20 before, 2^19 no slower) */
};

typedef struct rend_frame_desc {
    const scene *scene;   /* must outlive the renderer (or its rend_frame_set_scene); NULL: the renderer
                             is made ahead of its scene (below) */
    int width, height;    /* output pixels, 1..16384; s·width and s·height at most 16384 and GL's limit */
    int supersample;      /* s: s×s samples per pixel on a regular grid (the centres of s×s sub-pixels),
                             box-filtered, 1..REND_FRAME_SUPERSAMPLE_MAX; 1 = pixel centres only (the
                             interactive viewer); 0 = REND_FRAME_SUPERSAMPLE_DEFAULT, or less for large
                             images (REND_FRAME_DEFAULT_SAMPLES_MAX); rend_frame_times says which */
    int band_samples;     /* s > 1: the passes draw bands of whole pixel rows of at most this many samples
                             (at least one row), so the depth and radiance images hold a band, not the
                             image; 0 = REND_FRAME_BAND_SAMPLES (tests ask for small bands) */
    int one_snapshot;     /* a renderer of one snapshot (render's final picture): it keeps no CPU copy
                             of the meshes drawn (~32 bytes a leaf triangle) and, at s > 1, no image per
                             term: the terms are resolved straight into the output, added to the
                             emission drawn there first (48 bytes a pixel less; docs/memory.md). So a
                             snapshot other than the last drawn (another array or generation), a new
                             camera, component set or emission redraws every term whole, not only
                             the parts that changed; the pictures are the same, bit for bit */
} rend_frame_desc;

/* Wall-clock seconds of the last rend_frame_draw, each pass finished (glFinish)
 * before the next starts (measured: no slower than one glFinish at the end on
 * llvmpipe). A pass skipped because its result was still valid counts 0. The
 * ID pass is timed by rend_id (rend_id_result.seconds). */
typedef struct rend_frame_times {
    double material;         /* material image (s·width × s·height) */
    double upload;           /* the snapshot: comparing each mesh with the one drawn before, finding
                                where it changed, copying changed meshes to GL */
    double radiance;         /* drawing the radiance images (s·width × s·height) and, at s > 1, resolving
                                them, changed parts only */
    double composite;        /* the terms and the box-filtered emission into the output (width × height) */
    double readback;         /* output to rgb on the CPU; 0 for a draw with rgb = NULL */
    double total;            /* the whole call: the above plus state changes */
    double radiance_redrawn; /* share of the (non-empty) radiance images' pixels redrawn: 1 after a
                                camera move, 0 when nothing changed, between for a partial update */
    int material_reused;     /* same camera as the draw before: material pass skipped */
    int upload_reused;       /* no mesh changed since the draw before: nothing uploaded */
    int radiance_reused;     /* same camera, no mesh changed: radiance passes skipped */
    int composite_reused;    /* and same terms, no emission edit: the output is already the composite */
    int supersample;         /* s of this renderer */
} rend_frame_times;

/* Where a draw leaves its result: owned by the renderer, overwritten by each
 * draw, valid until rend_frame_destroy. */
typedef struct rend_frame_output {
    GLuint texture;      /* RGBA32F, width × height, linear RGB (alpha 1), GL row order (bottom row first) */
    GLuint framebuffer;  /* texture as colour attachment 0: a source for glBlitNamedFramebuffer */
    int width, height;   /* pixels */
} rend_frame_output;

typedef struct rend_frame rend_frame;

lm_result rend_frame_create(const GladGLContext *gl, const rend_frame_desc *desc, rend_frame **out, lm_error *err);
void rend_frame_destroy(rend_frame *f); /* NULL is a no-op; needs gl's context current */

/* A renderer made ahead of its scene (desc.scene NULL), e.g. while the scene
 * loads, by a thread that has the context before the client's
 * (rend_session_early_gl): its programs and images are made, and a stand-in is
 * drawn through every pass so that the driver compiles its shader variants
 * then (llvmpipe compiles them at a program's first draw); it draws nothing
 * until rend_frame_set_scene gives it its scene. rend_frame_set_scene also
 * replaces the scene of any renderer (the images and mesh copies are
 * forgotten: the next draw is whole). On failure the renderer has no scene.
 * Needs gl's context current. */
lm_result rend_frame_set_scene(rend_frame *f, const scene *s, lm_error *err);

/* New images for width × height output pixels (the same s), as made at
 * creation; what they held is forgotten. A size out of range leaves the images
 * as they were; a GL failure leaves none (every draw then fails until a resize
 * succeeds). Needs gl's context current. */
lm_result rend_frame_resize(rend_frame *f, int width, int height, lm_error *err);

/* Draws the snapshot seen from cam into the output texture and, when rgb is not
 * NULL, reads it into rgb (width·height·3 floats, linear, top row first). A NULL
 * snapshot draws emission only. Put back as they were: viewport, scissor, draw
 * framebuffer; left at GL's defaults: program, vertex array, texture units 0..3,
 * shader storage binding 0, depth test and function, clip control. Expects
 * blending off and all colour and depth writes on (GL's defaults). */
lm_result rend_frame_draw(rend_frame *f, const scene_camera *cam, const cache_snapshot *snap, float *rgb,
                          lm_error *err);
/* As rend_frame_draw, but the picture is added to rgb (which must not be NULL):
 * jittered draws are summed without an image of their own. */
lm_result rend_frame_draw_adding(rend_frame *f, const scene_camera *cam, const cache_snapshot *snap, float *rgb,
                                 lm_error *err);
void rend_frame_get_times(const rend_frame *f, rend_frame_times *out);
void rend_frame_get_output(const rend_frame *f, rend_frame_output *out);

/* Which terms the composite adds (REND_FRAME_COMPONENT_* bits; default all).
 * Applied at the next draw; the terms' images are kept. */
void rend_frame_set_components(rend_frame *f, unsigned components);
unsigned rend_frame_get_components(const rend_frame *f);
/* Moves every sample of the next draws by (jx, jy) output pixels (right, down)
 * from the s×s grid's centres: a sequence of jitters averaged over draws is a
 * finer box filter (rend_session_draw_accumulated). The material and radiance
 * images follow it like a camera move (drawn again when it changes). 0, 0 by
 * default; values that are not finite are taken as 0. */
void rend_frame_set_jitter(rend_frame *f, float jx, float jy);
/* Jitter i of the k×k pattern that stratifies one cell of an s×s grid (output
 * pixels, centred: k = 1 gives 0, 0): with the grid's own points, k×k draws at
 * these jitters sample a regular (k·s)×(k·s) grid in every pixel. i < k². */
void rend_frame_jitter_pattern(int i, int k, int s, float *jx, float *jy);
/* s of this renderer (desc.supersample resolved). */
int rend_frame_get_supersample(const rend_frame *f);
/* The emitted radiance the composite shows for `material` from the next draw on
 * (a light edit: the cache's direct values change through cache_set_light, the
 * emitter's own Le here). Needs gl's context current. */
lm_result rend_frame_set_emission(rend_frame *f, uint32_t material, const float le[3], lm_error *err);

/* Forgets what the images hold: the next draw does every pass and uploads the
 * snapshot again. */
void rend_frame_invalidate(rend_frame *f);
/* The next draw shows the specular term's lights' part as the specular mesh
 * interpolates it, not per pixel (rend_value.frag, HIGHLIGHT), and the draw
 * after it redraws that term per pixel, even with the same snapshot and camera:
 * for a first image that has to come soon. On CornellBox-Water at 640×480 the
 * per-pixel pass is 20-25 ms of a first draw of 35-40 ms on llvmpipe, and the
 * interpolated highlights' image has mean ΔE 1.98 against 1.84
 * (docs/renderer.md, "The first image's highlights one draw later"). */
void rend_frame_defer_highlights(rend_frame *f);

#ifdef __cplusplus
}
#endif
#endif
