/* samp_gl_internal.h — what the four files of the GL sampler share
 * (samp_gl.c: creation, context, shaders; samp_gl_direct.c: area lights;
 * samp_gl_indirect.c: hemicube and 160° plane; samp_gl_draw.c: scratch, atlases,
 * views and reduction, which both passes call). Calls go samp_gl.c → the passes
 * → samp_gl_draw.c, never back. Private to sampling/. Everything here belongs to the thread that created the sampler (its
 * GL context is current there). */
#ifndef LUMESH_SAMP_GL_INTERNAL_H
#define LUMESH_SAMP_GL_INTERNAL_H

#include "sampling/samp_internal.h"
#include "src/base/vecmath.h"
#include "src/gpu/gl_context.h"

/* One instance of a draw: a view of the scene rendered into a rectangle of the
 * atlas framebuffer. Layout = the instanced vertex attributes of
 * shaders/samp_gl_view.vert (locations 2..8, divisor 1). */
typedef struct samp_gl_view {
    float pv[16];   /* world → clip of the view's region (column-major); the region maps to [-1,1]² */
    float rect[4];  /* atlas rectangle: x0, y0, width, height, pixels (origin lower left) */
    float extra[4]; /* direct: receiver normal in eye space (xyz), unused (w) */
    float region[4];/* the image region at unit distance: l, r, b, t (tangents) */
} samp_gl_view;

/* Vertex of the triangles drawn (unwelded: three per triangle, so a per-triangle
 * attribute needs no provoking-vertex games). Attribute locations 0 and 1. */
typedef struct samp_gl_vertex {
    float pos[3];   /* scene units */
    float attr[3];  /* direct: area light index of the triangle or -1; indirect: RGB radiance, W·m⁻²·sr⁻¹ */
} samp_gl_vertex;

/* glMultiDrawElementsIndirect's command layout. */
typedef struct samp_gl_draw_cmd {
    GLuint count, instance_count, first_index, base_vertex, base_instance;
} samp_gl_draw_cmd;

/* An atlas: colour attachments of `format` plus a 32-bit float depth buffer
 * (reversed Z: cleared to 0, GL_GREATER), cut into tiles of tile_w × tile_h
 * pixels, cols × rows of them. */
typedef struct samp_gl_atlas {
    GLuint fbo, color[2], depth;
    int color_count;
    int width, height;       /* pixels */
    int tile_w, tile_h;      /* pixels */
    int cols, rows;          /* tiles */
    int full_rows;           /* rows at its full size (ATLAS_SIDE² pixels) */
    GLenum format;
} samp_gl_atlas;

/* The uniform grid over the scene's triangles used to cull occluders (paper §5). */
typedef struct samp_gl_grid {
    float lo[3], cell[3];    /* origin and cell size, scene units */
    int dim[3];
    uint32_t *first;         /* dim[0]·dim[1]·dim[2] + 1 offsets into tris */
    uint32_t *tris;          /* triangle ids per cell */
} samp_gl_grid;

/* Near plane of a view: this fraction of its receiver's offset (samp_gl.c says why). */
#define SAMP_GL_NEAR_REL 1e-3

typedef struct samp_gl {
    samp_desc desc;          /* defaults filled in */
    const scene *s;
    const rt_scene *rt;
    glctx *ctx;
    const GladGLContext *gl;
    samp_backend_ops ops;    /* gl_platform from desc, display name from the context */
    int max_tex;             /* GL_MAX_TEXTURE_SIZE, pixels */
    GLint saved_viewport[4]; /* the caller's viewport, put back after each draw */

    GLuint prog_direct, prog_indirect, prog_reduce2, prog_reduce3;
    GLint loc_direct_atlas, loc_direct_light, loc_indirect_atlas;
    GLuint vao;
    GLuint scene_vbo;        /* samp_gl_vertex × 3·tri_count, built at creation */
    GLuint view_buf, index_buf, cmd_buf, sum_buf, radiance_vbo;
    size_t view_cap, index_cap, cmd_cap, sum_cap, radiance_cap; /* bytes allocated on the GPU */

    samp_gl_atlas direct_atlas;   /* R32F visible + R32F total, direct_res² tiles */
    samp_gl_atlas indirect_atlas; /* RGBA32F radiance; made at the first indirect call */
    GLuint weight_tex;            /* R32F cosθ·dω per pixel of one indirect tile, sr */

    samp_gl_grid grid;
    /* CPU scratch, reused between calls */
    uint32_t *stamp;          /* per scene triangle: last point that listed it */
    uint32_t stamp_serial;
    samp_gl_view *views;
    size_t views_cap_cpu;         /* elements */
    uint32_t *indices;
    size_t indices_cap_cpu, indices_len;
    lm_dvec3 *light_dirs;         /* 4 per triangle of the largest light: its horizon-clipped corners */
    samp_gl_draw_cmd *cmds;
    size_t cmds_cap_cpu;
    uint32_t *batch_point;        /* per tile of a batch: index of its point in the call */
    double *batch_unocc;          /* per tile: G_unoccluded of the point (control variate) */
    size_t batch_point_cap_cpu, batch_unocc_cap_cpu;
    float *sums;
    size_t sums_cap_cpu;
} samp_gl;

/* samp_gl_draw.c */
/* Grows the CPU scratch array *ptr_to_ptr (any T **; *cap elements of elem
 * bytes) to hold `need`, doubling from 256 (lm_grow_capacity). */
lm_result samp_gl_reserve(void *ptr_to_ptr, size_t *cap, size_t need, size_t elem, lm_error *err);
/* Uploads `bytes` of data to GL buffer buf, growing its storage (*cap bytes) by doubling. */
lm_result samp_gl_upload(samp_gl *g, GLuint buf, size_t *cap, const void *data, size_t bytes, lm_error *err);
/* An atlas of tile_w×tile_h views, with rows enough for `tiles` (at most its
 * full size, ATLAS_SIDE² pixels; 0: full). */
lm_result samp_gl_atlas_make(samp_gl *g, samp_gl_atlas *a, int tile_w, int tile_h, GLenum format, int color_count,
                             uint32_t tiles, lm_error *err);
/* Remade with rows doubled until it holds min(n, its full size) tiles, if it
 * holds fewer. Atlases start one row high and grow to what calls ask: a call
 * of a few points (auto's calibration: 24) does not make 32 MB of GL images
 * (docs/memory.md, "The GL sampler's atlases grown to use"). */
lm_result samp_gl_atlas_fit(samp_gl *g, samp_gl_atlas *a, uint32_t n, lm_error *err);
void samp_gl_atlas_free(samp_gl *g, samp_gl_atlas *a);
/* Binds the atlas, clears the rows holding `tiles` tiles (colour 0, depth 0) and
 * sets the state every view draw needs; samp_gl_end_draw puts the defaults back. */
void samp_gl_begin_draw(samp_gl *g, const samp_gl_atlas *a, uint32_t tiles);
void samp_gl_end_draw(samp_gl *g);
/* A view from `eye` with orthonormal basis (ex, ey, ez; the view looks along
 * -ez) of the image-plane region [l,r]×[b,t] at unit distance, reversed infinite
 * Z with near plane `near`, into atlas rectangle rect. */
void samp_gl_view_make(samp_gl_view *v, const double eye[3], const double ex[3], const double ey[3],
                       const double ez[3], double l, double r, double b, double t, double near, const float rect[4]);
/* Sums each of `tiles` tiles of the atlas on the GPU and reads back `per_tile`
 * floats per tile (2: visible, total of the direct atlas; 3: RGB of the indirect
 * atlas weighted by weight_tex) into g->sums. */
lm_result samp_gl_reduce(samp_gl *g, const samp_gl_atlas *a, uint32_t tiles, int per_tile, lm_error *err);

/* samp_gl_direct.c */
lm_result samp_gl_grid_build(samp_gl *g, lm_error *err);
void samp_gl_grid_free(samp_gl_grid *grid);
lm_result samp_gl_direct(void *impl, uint32_t area_light, const samp_point *pts, uint32_t n, float *G,
                         lm_error *err);

/* samp_gl_indirect.c */
lm_result samp_gl_indirect(void *impl, const samp_radiance_mesh *mesh, const samp_point *pts, uint32_t n, float *E,
                           lm_error *err);

#endif
