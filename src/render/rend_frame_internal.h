/* rend_frame_internal.h — the renderer's state, shared by its passes
 * (rend_frame.c: drawing, change detection) and its making (rend_frame_make.c:
 * programs, images, scene, the stand-in draw). Only for src/render/rend_frame*.c.
 * Threads: a renderer is used on the thread its GL context is current on. */
#ifndef LUMESH_RENDER_REND_FRAME_INTERNAL_H
#define LUMESH_RENDER_REND_FRAME_INTERNAL_H
#include "src/render/rend_frame.h"

enum { TERMS = 3 }; /* direct, indirect, specular */

/* One material in the composite's table (std430: three vec4). */
typedef struct material_entry {
    float kd[4], ks[4], le[4];
} material_entry;

/* A scene triangle's corner for the material pass. */
typedef struct material_vertex {
    float position[3];
    uint32_t code; /* 2·(material + 1); the fragment shader adds the facing bit */
} material_vertex;

/* A rectangle of the sample images, GL rows (bottom up), half-open; empty when x0 >= x1. */
typedef struct rect {
    int x0, y0, x1, y1;
} rect;

/* One radiance term: its snapshot mesh on the GPU, a CPU copy of it (to find
 * what the next snapshot changed) and its image for the composite, output-sized:
 * at s = 1 its radiance image, drawn into directly (with the shared depth); at
 * s > 1 its resolved image (coef·L box-filtered over each pixel's samples,
 * rend_resolve.frag), the radiance drawn into the shared val_tex first. */
typedef struct term_state {
    GLuint vbo, ibo, vao, fbo, tex; /* vbo: the mesh's vertices; ibo: its index */
    size_t vbo_cap, ibo_cap;       /* bytes allocated in vbo and ibo */
    cache_snapshot_mesh copy;      /* what vbo and ibo hold (vertices, index; no tri, no corners): the
                                      counts only while copy_owed */
    cache_snapshot_vertex *copy_v; /* copy's arrays, owned */
    uint32_t *copy_i;
    uint64_t *hash;                /* tri_hash of each triangle of copy, when hash_valid */
    uint32_t copy_cap, copy_vcap;  /* allocated: triangles in copy_i and hash; vertices in copy_v */
    int hash_valid;
    int copy_owed;                 /* copy's arrays not made yet: vbo, ibo (and lobe_vbo) hold them
                                      (read back by copy_from_buffers when first compared) */
    const cache_snapshot_vertex *src; /* the snapshot array it came from */
    /* The specular term's lobes (cache_snapshot_mesh.lobes), for its highlights
     * per pixel: binding 1 of vao; their CPU copy, as copy_v's. */
    GLuint lobe_vbo;
    size_t lobe_vbo_cap;
    cache_lobe *copy_lobes;
    uint32_t copy_lcap;
    int lobes;                     /* the mesh drawn came with lobes: drawn by prog_highlight */
    int highlights_owed;           /* tex drawn without them (rend_frame_defer_highlights): redrawn next */
    int drawn;                     /* tex holds the copy drawn (and resolved) with val_vp */
    /* Whole roots (cache_snapshot_mesh.whole): drawn by rend_whole.frag from the
     * scene, the mask and the values by vertex id in buffers read as textures;
     * their CPU copies (made as copy_v's, when first compared). */
    GLuint whole_buf, values_buf, whole_tex, values_tex;
    size_t whole_buf_cap, values_buf_cap; /* bytes */
    uint32_t whole_count, value_count;     /* what the buffers hold (0 whole: none) */
    const uint32_t *whole_src;     /* the snapshot array they came from */
    uint32_t *copy_whole;          /* words: (scene triangles + 31) / 32 */
    float *copy_values;            /* 3 per id */
    size_t copy_whole_cap, copy_values_cap; /* elements */
    int whole_owed;                /* the copies not made yet (read back when first compared) */
} term_state;

/* Rectangles (rend_frame.c). */
int rend_rect_empty(const rect *r);
/* Grows r by the pixels the triangle of these corners (scene units) can touch
 * in the w×h sample image seen through vp, with a margin of 2 pixels. */
void rend_rect_add_corners(rect *r, const float vp[16], const float *const corner[3], int w, int h);
void rend_rect_union(rect *a, const rect *b); /* a grown by b */
/* Makes *buf hold at least bytes (with half as much again to grow into): a new
 * immutable buffer when it must grow. Returns whether it is new (rend_frame.c). */
int rend_ensure_buffer(const GladGLContext *gl, GLuint *buf, size_t *cap, size_t bytes);

struct rend_frame {
    rend_frame_desc desc;            /* supersample resolved */
    const GladGLContext *gl;
    int sw, sh;                      /* sample images: s·width × s·height */
    GLuint prog_material, prog_value, prog_resolve, prog_composite;
    GLint loc_mat_vp, loc_val_vp, loc_res_term, loc_res_band, loc_comp_terms;
    /* Whole roots (rend_whole.frag): the program, the scene's corners read as a
     * buffer texture (scene_vbo's), and each scene corner's vertex-table id
     * (cache_snapshot.corner_ids, uploaded when its serial changes). */
    GLuint prog_whole;
    GLint loc_whole_vp, loc_whole_band, loc_whole_samples;
    GLuint scene_tex, corner_buf, corner_tex;
    uint64_t corner_serial;
    uint8_t *id_changed;             /* scratch of whole_changed_rect: per vertex id */
    size_t id_changed_cap;
    /* Highlights per pixel (rend_value.frag, HIGHLIGHT): the program, and the
     * lights' outlines (cache_build_outlines of the scene) and radiance. */
    GLuint prog_highlight;
    GLint loc_hl_vp, loc_hl_eye, loc_hl_count;
    GLuint hl_ssbo[3];               /* lights, loops, points */
    uint32_t hl_light_count;
    float *hl_radiance;              /* hl_light_count × RGB in the lights' buffer */
    GLuint scene_vbo, scene_vao;     /* 3 material_vertex per scene triangle (the material pass draws them
                                        in order: its codes are triangles, rend_material.vert) */
    GLuint material_ssbo;            /* material_entry per scene material (dynamic: rend_frame_set_emission) */
    unsigned components;             /* REND_FRAME_COMPONENT_* drawn by the composite */
    float jitter[2];                 /* rend_frame_set_jitter: output pixels, right and down */
    int defer_highlights;            /* rend_frame_defer_highlights: for the next draw only */
    int comp_valid;                  /* the output holds the composite of the current inputs ... */
    unsigned comp_terms;             /* ... drawn with these terms (u_terms) */
    /* Sample images (s·width × s·height). Only the material codes are kept
     * between draws, whole; the depth is every pass's (each clears it where it
     * draws) and, at s > 1, the radiance image each term's in turn, resolved
     * before the next term is drawn into it (docs/memory.md). At s > 1 the
     * passes draw in bands of `band` rows (the viewport moved down by the band's
     * first row, the same projection): the depth and the radiance image hold one
     * band, the material pass draws its codes into a band image and copies them
     * into the whole one: 4 bytes a sample, 24 a sample of a band and 64 a pixel
     * (were 24 a sample: a 1920×1080 render took 450 MB of images). At s = 1 a
     * resolved image would be as large as the radiance image and cost a pass:
     * each term keeps its own (56 bytes a pixel), one band. */
    int band;                        /* rows of samples a band (a multiple of s; sh at s = 1) */
    GLuint mat_fbo, mat_tex;         /* R32UI material codes (whole); s = 1: mat_fbo draws them, with depth */
    GLuint band_tex;                 /* s > 1: a band's codes, drawn by mat_fbo (with depth), copied to mat_tex */
    GLuint val_fbo, val_tex;         /* s > 1: RGBA32F radiance of a band of the term being drawn, with depth */
    GLuint depth;                    /* DEPTH_COMPONENT32F of a band, attached to all that draw */
    GLuint out_fbo, out_tex;
    GLuint empty_vao;
    term_state term[TERMS];          /* L_dd, E_i, L_ds */
    /* Change detection: a hash table of the old triangles (index + 1, 0 = empty)
     * and the new triangles' hashes. */
    uint64_t *hash_key;
    uint32_t *hash_tri;
    uint8_t *seen;
    size_t hash_cap;                 /* slots, a power of two */
    uint64_t *new_hash;
    uint32_t new_hash_cap;           /* entries allocated in new_hash */
    /* What the images hold (rend_frame_invalidate clears it). */
    int mat_valid, val_valid, snap_valid;
    int images_ok;                   /* the images above exist (make_images; a failed resize leaves none) */
    float mat_vp[16], val_vp[16];    /* camera of the material / radiance images */
    uint64_t snap_generation;        /* snapshot the copies came from, when snap_valid */
    rend_frame_times times;
};

/* ---- rend_frame_whole.c: whole roots (cache_snapshot_mesh.whole), drawn from the scene ---- */

/* The snapshot's corner ids into corner_buf, when they are not those there
 * (returns 1: the whole roots drawn before had other ids). */
int rend_whole_upload_corners(rend_frame *f, const cache_snapshot *snap);
/* Whether m's whole roots are what ts's buffers hold (their bytes; the copies read
 * back when first compared). */
lm_result rend_whole_same(rend_frame *f, term_state *ts, const cache_snapshot_mesh *m, int *same, lm_error *err);
/* The region of the sample image where m's whole roots differ from ts's: the
 * bounding rectangle of every triangle whole in one and not the other, or whole
 * in both with a corner's value changed. */
lm_result rend_whole_changed_rect(rend_frame *f, term_state *ts, const cache_snapshot_mesh *m,
                                  const uint32_t *corner_ids, const float vp[16], rect *out, lm_error *err);
/* m's whole roots into ts's buffers (none: emptied); their copies owed. */
void rend_whole_upload(rend_frame *f, term_state *ts, const cache_snapshot_mesh *m);
/* The whole roots' pass of ts into the bound framebuffer (its band from sample
 * row y0): no depth test; the caller's viewport and scissor. */
void rend_whole_draw(rend_frame *f, term_state *ts, const float vp[16], int y0);

#endif
