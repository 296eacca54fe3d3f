/* rend_frame.c — material, radiance and composite passes (rend_frame.h). */
#include "src/render/rend_frame.h"

#include <math.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "src/render/rend_frame_internal.h"
#include "src/scene/camera.h"

/* ---- Change detection ---------------------------------------------------- */

/* A triangle is what the radiance pass draws of it: its three corners'
 * positions and values, and their lobes when the mesh has them, whatever their
 * indices. */
typedef struct corner_data {
    cache_snapshot_vertex v;
    cache_lobe lobe; /* zero without lobes */
} corner_data;

static void tri_corners(const cache_snapshot_mesh *m, uint32_t t, corner_data out[3])
{
    memset(out, 0, 3 * sizeof *out);
    for (int k = 0; k < 3; ++k) {
        out[k].v = *cache_snapshot_corner_vertex(m, t, k);
        if (m->lobes) out[k].lobe = m->lobes[m->index[3 * (size_t)t + (size_t)k]];
    }
}

static uint64_t tri_hash(const corner_data v[3])
{
    uint32_t w[3 * sizeof *v / sizeof(uint32_t)];
    memcpy(w, v, sizeof w);
    uint64_t h = 0x9E3779B97F4A7C15u;
    for (size_t i = 0; i < sizeof w / sizeof *w; ++i) {
        h = (h ^ w[i]) * 0xBF58476D1CE4E5B9u;
        h ^= h >> 29;
    }
    return h;
}

int rend_rect_empty(const rect *r) { return r->x0 >= r->x1 || r->y0 >= r->y1; }

/* Grows r by the pixels the triangle of corners p[0..2] can touch in the w×h
 * sample image seen through vp, with a margin of 2 pixels; a corner behind the
 * camera makes it the whole image. */
void rend_rect_add_corners(rect *r, const float vp[16], const float *const corner[3], int w, int h)
{
    float x0 = 0, y0 = 0, x1 = 0, y1 = 0;
    for (int c = 0; c < 3; ++c) {
        const float *p = corner[c];
        float clip[4];
        for (int k = 0; k < 4; ++k) clip[k] = vp[k] * p[0] + vp[4 + k] * p[1] + vp[8 + k] * p[2] + vp[12 + k];
        if (!(clip[3] > 0.0f)) {
            *r = (rect){0, 0, w, h};
            return;
        }
        float x = (clip[0] / clip[3] * 0.5f + 0.5f) * (float)w, y = (clip[1] / clip[3] * 0.5f + 0.5f) * (float)h;
        if (c == 0 || x < x0) x0 = x;
        if (c == 0 || x > x1) x1 = x;
        if (c == 0 || y < y0) y0 = y;
        if (c == 0 || y > y1) y1 = y;
    }
    if (!(x1 >= -2.0f && y1 >= -2.0f && x0 <= (float)w + 2.0f && y0 <= (float)h + 2.0f)) return; /* off screen or NaN */
    int ix0 = x0 < 2.0f ? 0 : (int)x0 - 2, iy0 = y0 < 2.0f ? 0 : (int)y0 - 2;
    int ix1 = x1 > (float)(w - 3) ? w : (int)x1 + 3, iy1 = y1 > (float)(h - 3) ? h : (int)y1 + 3;
    if (rend_rect_empty(r)) {
        *r = (rect){ix0, iy0, ix1, iy1};
        return;
    }
    if (ix0 < r->x0) r->x0 = ix0;
    if (iy0 < r->y0) r->y0 = iy0;
    if (ix1 > r->x1) r->x1 = ix1;
    if (iy1 > r->y1) r->y1 = iy1;
}

/* rect_add_corners for triangle t of m. */
static void rect_add_tri(rect *r, const float vp[16], const cache_snapshot_mesh *m, uint32_t t, int w, int h)
{
    const float *const p[3] = {cache_snapshot_corner_vertex(m, t, 0)->position,
                               cache_snapshot_corner_vertex(m, t, 1)->position,
                               cache_snapshot_corner_vertex(m, t, 2)->position};
    rend_rect_add_corners(r, vp, p, w, h);
}

/* a grown by b. */
void rend_rect_union(rect *a, const rect *b)
{
    if (rend_rect_empty(b)) return;
    if (rend_rect_empty(a)) {
        *a = *b;
        return;
    }
    if (b->x0 < a->x0) a->x0 = b->x0;
    if (b->y0 < a->y0) a->y0 = b->y0;
    if (b->x1 > a->x1) a->x1 = b->x1;
    if (b->y1 > a->y1) a->y1 = b->y1;
}

/* The region of the sample image where the old triangles (the term's copy) and
 * the new ones (m) differ: the bounding rectangle of every triangle in one set
 * and not in the other, compared byte for byte. Outside it the same triangles
 * cover every pixel, so the old image is what a full redraw would give there
 * (depth ties between two of them go to the one drawn first: the worker lists
 * leaves in node order, so triangles that did not change keep their order).
 * Leaves the new triangles' hashes in f->new_hash and sets *hashed when they
 * are all there (the search stops once the rectangle is the whole image). */
static lm_result changed_rect(rend_frame *f, term_state *ts, const cache_snapshot_mesh *m, const float vp[16],
                              rect *out, int *hashed, lm_error *err)
{
    *out = (rect){0, 0, 0, 0};
    *hashed = 0;
    const rect full = {0, 0, f->sw, f->sh};
    const uint32_t old_n = ts->copy.triangle_count;
    /* Three arrays of one capacity: a power of two (doubled from 16), at least 16 and
     * twice the triangles. */
    size_t want = 2 * (size_t)old_n < 16 ? 16 : 2 * (size_t)old_n;
    size_t need = lm_grow_capacity(f->hash_cap, want, 16, (SIZE_MAX / 2 + 1) / sizeof *f->hash_key);
    if (!need) return lm_fail(err, LM_ERR_NO_MEMORY, "renderer: %u triangles are too many to compare", old_n);
    if (need > f->hash_cap) {
        if (!lm_realloc_array(&f->hash_key, f->hash_cap, need, sizeof *f->hash_key) ||
            !lm_realloc_array(&f->hash_tri, f->hash_cap, need, sizeof *f->hash_tri) ||
            !lm_realloc_array(&f->seen, f->hash_cap, need, sizeof *f->seen))
            return lm_fail(err, LM_ERR_NO_MEMORY, "renderer: out of memory comparing snapshots");
        f->hash_cap = need;
    }
    if (m->triangle_count > f->new_hash_cap) {
        uint64_t *nh = realloc(f->new_hash, (size_t)m->triangle_count * sizeof *nh);
        if (!nh) return lm_fail(err, LM_ERR_NO_MEMORY, "renderer: out of memory comparing snapshots");
        f->new_hash = nh;
        f->new_hash_cap = m->triangle_count;
    }
    if (!ts->hash_valid)
        for (uint32_t i = 0; i < old_n; ++i) {
            corner_data v[3];
            tri_corners(&ts->copy, i, v);
            ts->hash[i] = tri_hash(v);
        }
    ts->hash_valid = 1;
    size_t mask = f->hash_cap - 1;
    memset(f->hash_tri, 0, f->hash_cap * sizeof *f->hash_tri);
    memset(f->seen, 0, old_n ? old_n : 1);
    for (uint32_t i = 0; i < old_n; ++i) {
        size_t j = (size_t)ts->hash[i] & mask;
        while (f->hash_tri[j]) j = (j + 1) & mask;
        f->hash_key[j] = ts->hash[i];
        f->hash_tri[j] = i + 1;
    }
    for (uint32_t i = 0; i < m->triangle_count; ++i) {
        corner_data v[3], o_v[3];
        tri_corners(m, i, v);
        uint64_t hk = f->new_hash[i] = tri_hash(v);
        int found = 0;
        for (size_t j = (size_t)hk & mask; f->hash_tri[j]; j = (j + 1) & mask) {
            uint32_t o = f->hash_tri[j] - 1;
            if (f->hash_key[j] != hk || f->seen[o]) continue;
            tri_corners(&ts->copy, o, o_v);
            if (memcmp(o_v, v, sizeof v) == 0) {
                f->seen[o] = 1;
                found = 1;
                break;
            }
        }
        if (!found) rect_add_tri(out, vp, m, i, f->sw, f->sh);
        if (memcmp(out, &full, sizeof full) == 0) return LM_OK;
    }
    *hashed = 1;
    for (uint32_t i = 0; i < old_n; ++i)
        if (!f->seen[i]) {
            rect_add_tri(out, vp, &ts->copy, i, f->sw, f->sh);
            if (memcmp(out, &full, sizeof full) == 0) return LM_OK;
        }
    return LM_OK;
}

/* Makes *buf hold at least bytes (with half as much again to grow into);
 * immutable storage cannot grow, so a new buffer replaces it. Returns whether
 * it is a new buffer (to be bound to the VAO again). */
int rend_ensure_buffer(const GladGLContext *gl, GLuint *buf, size_t *cap, size_t bytes)
{
    if (bytes <= *cap) return 0;
    if (*buf) gl->DeleteBuffers(1, buf);
    gl->CreateBuffers(1, buf);
    *cap = bytes + bytes / 2;
    gl->NamedBufferStorage(*buf, (GLsizeiptr)*cap, NULL, GL_DYNAMIC_STORAGE_BIT);
    return 1;
}

/* Whether meshes a and b hold the same vertices and index (byte for byte). */
static int same_mesh(const cache_snapshot_mesh *a, const cache_snapshot_mesh *b)
{
    return a->triangle_count == b->triangle_count && a->vertex_count == b->vertex_count &&
           !a->lobes == !b->lobes &&
           (!a->triangle_count || (memcmp(a->index, b->index, 3 * (size_t)a->triangle_count * sizeof *a->index) == 0 &&
                                   memcmp(a->vertices, b->vertices, (size_t)a->vertex_count * sizeof *a->vertices) == 0 &&
                                   (!a->lobes || memcmp(a->lobes, b->lobes, (size_t)a->vertex_count * sizeof *a->lobes) == 0)));
}

/* Makes room for the CPU copy of a mesh of n triangles and nv vertices (lobes:
 * with its lobes). */
static lm_result copy_room(term_state *ts, uint32_t n, uint32_t nv, int lobes, lm_error *err)
{
    if (n > ts->copy_cap) {
        uint32_t *x = realloc(ts->copy_i, 3 * (size_t)n * sizeof *x);
        if (x) ts->copy_i = x;
        uint64_t *h = realloc(ts->hash, (size_t)n * sizeof *h);
        if (h) ts->hash = h;
        if (!x || !h) return lm_fail(err, LM_ERR_NO_MEMORY, "renderer: out of memory for %u triangles", n);
        ts->copy_cap = n;
    }
    if (nv > ts->copy_vcap) {
        cache_snapshot_vertex *v = realloc(ts->copy_v, (size_t)nv * sizeof *v);
        if (!v) return lm_fail(err, LM_ERR_NO_MEMORY, "renderer: out of memory for %u vertices", nv);
        ts->copy_v = v;
        ts->copy_vcap = nv;
    }
    if (lobes && nv > ts->copy_lcap) {
        cache_lobe *l = realloc(ts->copy_lobes, (size_t)nv * sizeof *l);
        if (!l) return lm_fail(err, LM_ERR_NO_MEMORY, "renderer: out of memory for %u vertices", nv);
        ts->copy_lobes = l;
        ts->copy_lcap = nv;
    }
    return LM_OK;
}

/* The CPU copy of what the term's buffers hold, read back from them the first
 * time it is compared with a new snapshot (update_snapshot, changed_rect). Made
 * at the upload, it was a copy of every snapshot drawn, the first included: on
 * a million-triangle scene 75 MB written for the first time, 0.15 s of the
 * first image's draw (docs/cache.md, "The first image's fresh memory"). A
 * renderer dropped after one draw (converge's preview) never makes it. */
static lm_result copy_from_buffers(rend_frame *f, term_state *ts, lm_error *err)
{
    if (!ts->copy_owed) return LM_OK;
    const uint32_t n = ts->copy.triangle_count, nv = ts->copy.vertex_count;
    const int lobes = ts->lobes;
    lm_result r = copy_room(ts, n, nv, lobes, err);
    if (r != LM_OK) {
        rend_frame_invalidate(f);
        return r;
    }
    const GladGLContext *gl = f->gl;
    gl->GetNamedBufferSubData(ts->vbo, 0, (GLsizeiptr)((size_t)nv * sizeof *ts->copy_v), ts->copy_v);
    gl->GetNamedBufferSubData(ts->ibo, 0, (GLsizeiptr)(3 * (size_t)n * sizeof *ts->copy_i), ts->copy_i);
    if (lobes) gl->GetNamedBufferSubData(ts->lobe_vbo, 0, (GLsizeiptr)((size_t)nv * sizeof *ts->copy_lobes), ts->copy_lobes);
    ts->copy = (cache_snapshot_mesh){.vertices = ts->copy_v, .index = ts->copy_i,
                                     .lobes = lobes ? ts->copy_lobes : NULL, .triangle_count = n,
                                     .vertex_count = nv};
    ts->copy_owed = 0;
    return LM_OK;
}

/* Copies snapshot mesh m to the term's buffers (grown when needed); its CPU
 * copy (not with desc.one_snapshot) is owed (copy_from_buffers). */
static void upload_mesh(rend_frame *f, term_state *ts, const cache_snapshot_mesh *m)
{
    const GladGLContext *gl = f->gl;
    uint32_t n = m ? m->triangle_count : 0, nv = m && n ? m->vertex_count : 0;
    ts->src = m ? m->vertices : NULL;
    ts->copy = (cache_snapshot_mesh){0};
    ts->copy_owed = 0;
    ts->hash_valid = 0;
    if (!n) return;
    ts->lobes = m->lobes != NULL;
    if (m->lobes) {
        /* Binding 1: normal and exponent, the lights' part and their visible
         * fraction (rend_value.vert, HIGHLIGHT). */
        size_t lbytes = (size_t)nv * sizeof *m->lobes;
        if (rend_ensure_buffer(gl, &ts->lobe_vbo, &ts->lobe_vbo_cap, lbytes)) {
            gl->VertexArrayVertexBuffer(ts->vao, 1, ts->lobe_vbo, 0, sizeof(cache_lobe));
            for (GLuint a = 2; a < 4; ++a) {
                gl->EnableVertexArrayAttrib(ts->vao, a);
                gl->VertexArrayAttribFormat(ts->vao, a, 4, GL_FLOAT, GL_FALSE,
                                            a == 2 ? (GLuint)offsetof(cache_lobe, normal) : (GLuint)offsetof(cache_lobe, direct));
                gl->VertexArrayAttribBinding(ts->vao, a, 1);
            }
        }
        gl->NamedBufferSubData(ts->lobe_vbo, 0, (GLsizeiptr)lbytes, m->lobes);
    }
    size_t vbytes = (size_t)nv * sizeof *m->vertices, ibytes = 3 * (size_t)n * sizeof *m->index;
    if (rend_ensure_buffer(gl, &ts->vbo, &ts->vbo_cap, vbytes)) {
        gl->VertexArrayVertexBuffer(ts->vao, 0, ts->vbo, 0, sizeof(cache_snapshot_vertex));
        for (GLuint a = 0; a < 2; ++a) {
            gl->EnableVertexArrayAttrib(ts->vao, a);
            gl->VertexArrayAttribFormat(ts->vao, a, 3, GL_FLOAT, GL_FALSE,
                                        a ? (GLuint)offsetof(cache_snapshot_vertex, value) : 0);
            gl->VertexArrayAttribBinding(ts->vao, a, 0);
        }
    }
    if (rend_ensure_buffer(gl, &ts->ibo, &ts->ibo_cap, ibytes)) gl->VertexArrayElementBuffer(ts->vao, ts->ibo);
    gl->NamedBufferSubData(ts->vbo, 0, (GLsizeiptr)vbytes, m->vertices);
    gl->NamedBufferSubData(ts->ibo, 0, (GLsizeiptr)ibytes, m->index);
    ts->copy = (cache_snapshot_mesh){.triangle_count = n, .vertex_count = nv}; /* the counts: what is drawn */
    ts->copy_owed = !f->desc.one_snapshot;
}

/* glFinish, then the seconds since *t0 (and *t0 moves on): per-pass wall time. */
static double lap(const GladGLContext *gl, double *t0)
{
    gl->Finish();
    double t = lm_now_seconds(), d = t - *t0;
    *t0 = t;
    return d;
}

/* Brings the snapshot in: per term, whether it changed since the last draw and
 * where (dirty[t], empty: nothing to redraw), and the changed meshes uploaded. */
static lm_result update_snapshot(rend_frame *f, const cache_snapshot *snap, const float vp[16], int same_camera,
                                 rect dirty[TERMS], int *uploads, lm_error *err)
{
    *uploads = 0;
    const cache_snapshot_mesh *meshes[TERMS] = {snap ? &snap->direct : NULL, snap ? &snap->indirect : NULL,
                                                snap ? &snap->specular : NULL};
    const rect full = {0, 0, f->sw, f->sh};
    uint64_t generation = snap ? snap->generation : 0;
    /* The lights' radiance the highlights are drawn with: the snapshot's (a light
     * edit reaches the specular values and the highlights together). */
    int relit = 0;
    if (snap && snap->light_radiance && snap->stats.light_count == f->hl_light_count && f->hl_light_count &&
        memcmp(snap->light_radiance, f->hl_radiance, 3 * sizeof(float) * f->hl_light_count) != 0) {
        memcpy(f->hl_radiance, snap->light_radiance, 3 * sizeof(float) * f->hl_light_count);
        for (uint32_t l = 0; l < f->hl_light_count; ++l)
            f->gl->NamedBufferSubData(f->hl_ssbo[0], (GLintptr)(l * 12 * sizeof(float)), 3 * sizeof(float),
                                      f->hl_radiance + 3 * (size_t)l);
        relit = 1;
    }
    /* Whole roots' corner ids: new ones (another worker) change every whole root. */
    const int new_corners = rend_whole_upload_corners(f, snap);
    for (int t = 0; t < TERMS; ++t) {
        term_state *ts = &f->term[t];
        const cache_snapshot_mesh *m = meshes[t];
        uint32_t n = m ? m->triangle_count : 0;
        int reusable = same_camera && ts->drawn;
        /* Unchanged: the same snapshot arrays as last time (generations are
         * per worker: rend_frame.h), else the same bytes; the listed leaves
         * and the whole roots apart. */
        const int same_slot = f->snap_valid && generation == f->snap_generation && !new_corners;
        int same = same_slot && (m ? m->vertices : NULL) == ts->src && n == ts->copy.triangle_count;
        if (!same && n == ts->copy.triangle_count && !f->desc.one_snapshot && n) {
            lm_result r = copy_from_buffers(f, ts, err);
            if (r != LM_OK) return r;
            same = same_mesh(&ts->copy, m);
        }
        same |= n == 0 && ts->copy.triangle_count == 0 && !f->desc.one_snapshot;
        int same_whole = same_slot && (m ? m->whole : NULL) == ts->whole_src &&
                         (m && m->whole ? m->whole_count : 0) == ts->whole_count;
        if (!same_whole && !new_corners && !f->desc.one_snapshot) {
            lm_result r = rend_whole_same(f, ts, m, &same_whole, err);
            if (r != LM_OK) return r;
        }
        if (same && same_whole) {
            ts->src = m ? m->vertices : NULL;
            ts->whole_src = m ? m->whole : NULL;
            dirty[t] = reusable && !(relit && ts->lobes) ? (rect){0, 0, 0, 0} : full;
            continue;
        }
        dirty[t] = full;
        lm_result r = LM_OK;
        int hashed = 0;
        /* New radiance changes every highlight, not only the changed triangles'. */
        if (reusable && !f->desc.one_snapshot && (!m || !m->lobes == !ts->lobes) && !(relit && m && m->lobes) &&
            !new_corners) {
            rect listed = {0, 0, 0, 0}, whole = {0, 0, 0, 0};
            if (!same && n) r = copy_from_buffers(f, ts, err);
            if (r == LM_OK && !same && n) r = changed_rect(f, ts, m, vp, &listed, &hashed, err);
            if (r == LM_OK && !same && !n) listed = ts->copy.triangle_count ? full : listed; /* all gone */
            if (r == LM_OK && !same_whole)
                r = rend_whole_changed_rect(f, ts, m, snap ? snap->corner_ids : NULL, vp, &whole, err);
            if (r == LM_OK) {
                dirty[t] = listed;
                rend_rect_union(&dirty[t], &whole);
            }
        }
        if (r == LM_OK && !same_whole) rend_whole_upload(f, ts, m);
        if (r == LM_OK && same) ts->src = m ? m->vertices : NULL;
        if (r == LM_OK && !same) upload_mesh(f, ts, m);
        if (r == LM_OK && hashed) r = copy_room(ts, n, 0, 0, err); /* room for n hashes */
        if (r == LM_OK && hashed) { /* the new triangles' hashes serve the next comparison */
            memcpy(ts->hash, f->new_hash, (size_t)n * sizeof *ts->hash);
            ts->hash_valid = 1;
        }
        ++*uploads;
        if (r != LM_OK) {
            rend_frame_invalidate(f);
            return r;
        }
    }
    f->snap_generation = generation;
    f->snap_valid = 1;
    return LM_OK;
}

/* The output texture into rgb (top row first), or added to it: a band of rows
 * at a time through a small buffer, not a second output-sized image (an
 * RGBA copy of the output was 16 bytes a pixel, and render's accumulated draws
 * a third image: docs/memory.md, "Twenty-first session"). */
static lm_result read_output(rend_frame *f, float *rgb, int add, lm_error *err)
{
    enum { READ_ROWS = 32 };
    const GladGLContext *gl = f->gl;
    const int w = f->desc.width, h = f->desc.height;
    const size_t row = (size_t)w * 3;
    float *band = malloc(row * READ_ROWS * sizeof *band);
    if (!band) return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory reading a %dx%d picture", w, h);
    GLint pack = 4;
    gl->GetIntegerv(GL_PACK_ALIGNMENT, &pack);
    gl->PixelStorei(GL_PACK_ALIGNMENT, 4); /* rows of floats: never padded */
    for (int y0 = 0; y0 < h; y0 += READ_ROWS) { /* GL rows run from the bottom */
        const int rows = h - y0 < READ_ROWS ? h - y0 : READ_ROWS;
        gl->GetTextureSubImage(f->out_tex, 0, 0, y0, 0, w, rows, 1, GL_RGB, GL_FLOAT,
                               (GLsizei)(row * (size_t)rows * sizeof *band), band);
        for (int j = 0; j < rows; ++j) {
            float *dst = rgb + (size_t)(h - 1 - (y0 + j)) * row;
            const float *src = band + (size_t)j * row;
            if (add)
                for (size_t i = 0; i < row; ++i) dst[i] += src[i];
            else
                memcpy(dst, src, row * sizeof *dst);
        }
    }
    gl->PixelStorei(GL_PACK_ALIGNMENT, pack);
    free(band);
    return LM_OK;
}

/* Whether a term has anything to draw: listed leaves or whole roots. */
static int term_drawn(const term_state *ts) { return ts->copy.triangle_count || ts->whole_count; }

/* The terms are resolved straight into the output (rend_frame_desc.one_snapshot). */
static int summed(const rend_frame *f) { return f->desc.one_snapshot && f->desc.supersample > 1; }

/* The composite pass into the output, full screen (the caller's state: no depth
 * test, the output's viewport). comp_terms: bits 0..2 the term images drawn and
 * shown (none when summed: they are added after it), bit 3 emission shown. */
static void composite(rend_frame *f, unsigned comp_terms)
{
    const GladGLContext *gl = f->gl;
    gl->BindFramebuffer(GL_DRAW_FRAMEBUFFER, f->out_fbo);
    gl->UseProgram(f->prog_composite);
    gl->Uniform1ui(f->loc_comp_terms, comp_terms);
    GLuint inputs[2 + TERMS] = {f->mat_tex, f->term[0].tex, f->term[1].tex, f->term[2].tex, f->scene_tex};
    gl->BindTextures(0, 2 + TERMS, inputs);
    gl->BindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, f->material_ssbo);
    gl->BindVertexArray(f->empty_vao);
    gl->DrawArrays(GL_TRIANGLES, 0, 3);
    gl->BindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, 0);
    gl->BindTextures(0, 2 + TERMS, NULL);
}

static lm_result draw(rend_frame *f, const scene_camera *cam, const cache_snapshot *snap, float *rgb, int add,
                      lm_error *err)
{
    if (!f || !cam) return lm_fail(err, LM_ERR_INVALID_ARG, "renderer: missing arguments");
    if (!f->desc.scene) return lm_fail(err, LM_ERR_INVALID_ARG, "renderer: no scene to draw (rend_frame_set_scene)");
    if (!f->images_ok)
        return lm_fail(err, LM_ERR_RUNTIME, "renderer: its %dx%d images could not be made (rend_frame_resize)",
                       f->desc.width, f->desc.height);
    const int defer = f->defer_highlights; /* for this draw only */
    f->defer_highlights = 0;
    const GladGLContext *gl = f->gl;
    const scene *s = f->desc.scene;
    int w = f->desc.width, h = f->desc.height;
    rend_frame_times *tt = &f->times;
    *tt = (rend_frame_times){.supersample = f->desc.supersample};
    double start = lm_now_seconds(), t0 = start;
    float vp[16];
    camera_viewproj(cam, f->sw, f->sh, camera_near(s), vp);
    /* A jitter moves the samples by (jx, jy) pixels over the image, i.e. the image
     * the other way under the sample grid: NDC x by −2·jx/width, y by +2·jy/height
     * (image rows go down, NDC y up), row 3 (w_clip) added to rows 0 and 1.
     * tests/rend_exact_test.c: a jitter of one pixel is the image shifted by one. */
    if (f->jitter[0] != 0.0f || f->jitter[1] != 0.0f) {
        float ax = -2.0f * f->jitter[0] / (float)w, ay = 2.0f * f->jitter[1] / (float)h;
        for (int c = 0; c < 4; ++c) {
            vp[c * 4 + 0] += ax * vp[c * 4 + 3];
            vp[c * 4 + 1] += ay * vp[c * 4 + 3];
        }
    }
    GLint viewport[4], scissor_box[4], draw_fbo = 0;
    gl->GetIntegerv(GL_VIEWPORT, viewport);
    gl->GetIntegerv(GL_SCISSOR_BOX, scissor_box);
    gl->GetIntegerv(GL_DRAW_FRAMEBUFFER_BINDING, &draw_fbo);
    GLboolean scissor_on = gl->IsEnabled(GL_SCISSOR_TEST);
    gl->Disable(GL_SCISSOR_TEST);
    gl->Viewport(0, 0, f->sw, f->sh);
    gl->ClipControl(GL_LOWER_LEFT, GL_ZERO_TO_ONE); /* reversed Z (src/scene/camera.h) */
    gl->Enable(GL_DEPTH_TEST);
    gl->DepthFunc(GL_GREATER);
    const GLfloat zero[4] = {0, 0, 0, 0}, far_depth = 0.0f;

    /* Material: only when the camera moved. */
    tt->material_reused = f->mat_valid && memcmp(vp, f->mat_vp, sizeof vp) == 0;
    if (!tt->material_reused) {
        const GLuint no_surface[4] = {0, 0, 0, 0};
        gl->BindFramebuffer(GL_DRAW_FRAMEBUFFER, f->mat_fbo);
        gl->UseProgram(f->prog_material);
        gl->UniformMatrix4fv(f->loc_mat_vp, 1, GL_FALSE, vp);
        gl->BindVertexArray(f->scene_vao);
        for (int y0 = 0; y0 < f->sh; y0 += f->band) {
            gl->ClearNamedFramebufferuiv(f->mat_fbo, GL_COLOR, 0, no_surface);
            gl->ClearNamedFramebufferfv(f->mat_fbo, GL_DEPTH, 0, &far_depth);
            gl->Viewport(0, -y0, f->sw, f->sh);
            gl->DrawArrays(GL_TRIANGLES, 0, (GLsizei)(3 * s->tri_count));
            if (f->band_tex) {
                const int rows = f->sh - y0 < f->band ? f->sh - y0 : f->band;
                gl->CopyImageSubData(f->band_tex, GL_TEXTURE_2D, 0, 0, 0, 0, f->mat_tex, GL_TEXTURE_2D, 0, 0, y0, 0,
                                     f->sw, rows, 1);
            }
        }
        memcpy(f->mat_vp, vp, sizeof vp);
        f->mat_valid = 1;
        tt->material = lap(gl, &t0);
    }

    /* Snapshot: what changed, and where. The resolved terms hold the material
     * codes of the images they were drawn with: a new material image redraws them. */
    int same_camera = tt->material_reused && f->val_valid && memcmp(vp, f->val_vp, sizeof vp) == 0;
    rect dirty[TERMS];
    int uploads = 0;
    lm_result r = update_snapshot(f, snap, vp, same_camera, dirty, &uploads, err);
    for (int t = 0; t < TERMS; ++t) /* drawn without its highlights last time: whole again, with them */
        if (f->term[t].highlights_owed && !defer) dirty[t] = (rect){0, 0, f->sw, f->sh};
    tt->upload_reused = uploads == 0;
    tt->upload = lap(gl, &t0);

    /* Radiance: each term where it changed (all of it when the camera moved),
     * cleared and redrawn with every triangle of its mesh inside the dirty
     * rectangle, so the image equals a full redraw there; at s > 1 then
     * resolved into the term's output-sized image over the same pixels (the
     * rectangle is widened to whole pixels), before the next term draws into
     * the shared radiance image. An empty mesh is neither cleared nor drawn:
     * the composite takes its term as 0. */
    unsigned terms = 0;
    double redrawn = 0.0, present = 0.0;
    int drew = 0;
    const int ss = f->desc.supersample;
    /* Summed into the output (one_snapshot at s > 1): the output first gets the
     * emission, then each shown term whole, added as it is resolved, in the
     * composite's order (Le, L_dd, E_i, L_ds: the same bits). So any change
     * redraws them all, and a hidden term is not drawn. */
    const int sum = summed(f);
    unsigned comp_terms = REND_FRAME_COMPONENT_EMISSION & f->components;
    for (int t = 0; t < TERMS; ++t)
        if (term_drawn(&f->term[t])) comp_terms |= (1u << t) & f->components;
    if (sum && r == LM_OK) {
        int redraw = !f->comp_valid || !tt->material_reused || comp_terms != f->comp_terms;
        for (int t = 0; t < TERMS; ++t) redraw |= (comp_terms >> t & 1u) && !rend_rect_empty(&dirty[t]);
        for (int t = 0; t < TERMS; ++t)
            dirty[t] = redraw && (comp_terms >> t & 1u) ? (rect){0, 0, f->sw, f->sh} : (rect){0, 0, 0, 0};
        if (redraw) {
            gl->Disable(GL_DEPTH_TEST); /* each band enables it again */
            gl->Viewport(0, 0, w, h);
            composite(f, comp_terms & REND_FRAME_COMPONENT_EMISSION);
        }
        tt->composite_reused = !redraw;
    }
    for (int t = 0; r == LM_OK && t < TERMS; ++t) {
        term_state *ts = &f->term[t];
        if (!term_drawn(ts) || (sum && !(comp_terms >> t & 1u))) {
            ts->drawn = 0;
            continue;
        }
        terms |= 1u << t;
        present += 1.0;
        if (rend_rect_empty(&dirty[t])) continue;
        rect d = dirty[t]; /* in samples, widened to whole pixels (f->sw = s·width) */
        d.x0 -= d.x0 % ss;
        d.y0 -= d.y0 % ss;
        d.x1 += (ss - d.x1 % ss) % ss;
        d.y1 += (ss - d.y1 % ss) % ss;
        redrawn += (double)(d.x1 - d.x0) * (double)(d.y1 - d.y0) / ((double)f->sw * (double)f->sh);
        ts->drawn = 1;
        drew = 1;
        /* Deferred (rend_frame_defer_highlights): the lobes' mesh through the
         * plain program, which reads its positions and values only. */
        const int per_pixel = ts->lobes && !defer;
        ts->highlights_owed = ts->lobes && defer;
        GLuint target = f->val_fbo ? f->val_fbo : ts->fbo;
        for (int y0 = 0; y0 < f->sh; y0 += f->band) {
            /* The dirty rows of this band, in its own rows (whole pixels: the
             * band and the rectangle start on multiples of s). */
            const int rows = f->sh - y0 < f->band ? f->sh - y0 : f->band;
            const int b0 = (d.y0 > y0 ? d.y0 : y0) - y0, b1 = (d.y1 < y0 + rows ? d.y1 : y0 + rows) - y0;
            if (b0 >= b1) continue;
            const int part = d.x0 > 0 || d.x1 < f->sw || b0 > 0 || b1 < rows;
            gl->Enable(GL_DEPTH_TEST);
            gl->Viewport(0, -y0, f->sw, f->sh);
            if (part) {
                gl->Enable(GL_SCISSOR_TEST);
                gl->Scissor(d.x0, b0, d.x1 - d.x0, b1 - b0);
            }
            gl->ClearNamedFramebufferfv(target, GL_COLOR, 0, zero);
            gl->ClearNamedFramebufferfv(target, GL_DEPTH, 0, &far_depth);
            gl->BindFramebuffer(GL_DRAW_FRAMEBUFFER, target);
            if (per_pixel) {
                gl->UseProgram(f->prog_highlight);
                gl->UniformMatrix4fv(f->loc_hl_vp, 1, GL_FALSE, vp);
                gl->Uniform3fv(f->loc_hl_eye, 1, cam->position);
                gl->Uniform1ui(f->loc_hl_count, f->hl_light_count);
                for (GLuint b = 0; b < 3; ++b) gl->BindBufferBase(GL_SHADER_STORAGE_BUFFER, 1 + b, f->hl_ssbo[b]);
            } else {
                gl->UseProgram(f->prog_value);
                gl->UniformMatrix4fv(f->loc_val_vp, 1, GL_FALSE, vp);
            }
            gl->BindVertexArray(ts->vao);
            if (ts->copy.triangle_count)
                gl->DrawElements(GL_TRIANGLES, (GLsizei)(3 * ts->copy.triangle_count), GL_UNSIGNED_INT, NULL);
            if (per_pixel)
                for (GLuint b = 0; b < 3; ++b) gl->BindBufferBase(GL_SHADER_STORAGE_BUFFER, 1 + b, 0);
            if (ts->whole_count) rend_whole_draw(f, ts, vp, y0); /* over the leaves, where the triangle is whole */
            if (!f->val_fbo) {
                if (part) gl->Disable(GL_SCISSOR_TEST);
                continue;
            }
            /* Resolve: one full-screen triangle over the band's pixels of the output. */
            gl->Disable(GL_DEPTH_TEST);
            gl->Viewport(0, 0, w, h);
            gl->Enable(GL_SCISSOR_TEST);
            gl->Scissor(d.x0 / ss, (y0 + b0) / ss, (d.x1 - d.x0) / ss, (b1 - b0) / ss);
            gl->BindFramebuffer(GL_DRAW_FRAMEBUFFER, sum ? f->out_fbo : ts->fbo);
            if (sum) { /* out = out + resolved: float32 blending adds exactly, as the composite does */
                gl->Enable(GL_BLEND);
                gl->BlendEquation(GL_FUNC_ADD);
                gl->BlendFunc(GL_ONE, GL_ONE);
            }
            gl->UseProgram(f->prog_resolve);
            gl->Uniform1ui(f->loc_res_term, (GLuint)t);
            gl->Uniform1i(f->loc_res_band, y0);
            GLuint inputs[3] = {f->mat_tex, f->val_tex, f->scene_tex};
            gl->BindTextures(0, 3, inputs);
            gl->BindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, f->material_ssbo);
            gl->BindVertexArray(f->empty_vao);
            gl->DrawArrays(GL_TRIANGLES, 0, 3);
            gl->BindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, 0);
            gl->BindTextures(0, 3, NULL);
            gl->Disable(GL_SCISSOR_TEST);
            if (sum) gl->Disable(GL_BLEND);
        }
    }
    if (r == LM_OK) {
        memcpy(f->val_vp, vp, sizeof vp);
        f->val_valid = 1;
    }
    tt->radiance_redrawn = present > 0.0 ? redrawn / present : 0.0;
    tt->radiance_reused = !drew;
    if (drew) tt->radiance = lap(gl, &t0);

    /* Composite: unless its inputs are those of the output already (same camera,
     * no radiance redrawn, same terms, no emission edit): a resting viewer's frame
     * is then the tone mapping alone. */
    gl->Disable(GL_DEPTH_TEST);
    gl->DepthFunc(GL_LESS);
    gl->ClipControl(GL_LOWER_LEFT, GL_NEGATIVE_ONE_TO_ONE);
    gl->Viewport(0, 0, w, h);
    if (!sum) {
        comp_terms = (terms | REND_FRAME_COMPONENT_EMISSION) & f->components;
        tt->composite_reused = r == LM_OK && f->comp_valid && tt->material_reused && tt->radiance_reused &&
                               comp_terms == f->comp_terms;
        if (r == LM_OK && !tt->composite_reused) composite(f, comp_terms);
    }
    if (r == LM_OK) {
        f->comp_valid = 1;
        f->comp_terms = comp_terms;
    }
    gl->BindVertexArray(0);
    gl->UseProgram(0);
    gl->BindFramebuffer(GL_DRAW_FRAMEBUFFER, (GLuint)draw_fbo);
    gl->Viewport(viewport[0], viewport[1], viewport[2], viewport[3]);
    gl->Scissor(scissor_box[0], scissor_box[1], scissor_box[2], scissor_box[3]);
    if (scissor_on) gl->Enable(GL_SCISSOR_TEST);
    if (r != LM_OK) return r;
    tt->composite = lap(gl, &t0);

    if (rgb) {
        r = read_output(f, rgb, add, err);
        if (r != LM_OK) return r;
        tt->readback = lm_now_seconds() - t0;
    }
    tt->total = lm_now_seconds() - start;
    if (gl->GetError() != GL_NO_ERROR) {
        rend_frame_invalidate(f);
        return lm_fail(err, LM_ERR_RUNTIME, "renderer: a GL error occurred");
    }
    return LM_OK;
}

lm_result rend_frame_draw(rend_frame *f, const scene_camera *cam, const cache_snapshot *snap, float *rgb,
                          lm_error *err)
{
    return draw(f, cam, snap, rgb, 0, err);
}

lm_result rend_frame_draw_adding(rend_frame *f, const scene_camera *cam, const cache_snapshot *snap, float *rgb,
                                 lm_error *err)
{
    if (!rgb) return lm_fail(err, LM_ERR_INVALID_ARG, "renderer: no picture to add to");
    return draw(f, cam, snap, rgb, 1, err);
}

void rend_frame_get_times(const rend_frame *f, rend_frame_times *out) { *out = f->times; }

void rend_frame_set_components(rend_frame *f, unsigned components)
{
    f->components = components & REND_FRAME_COMPONENTS_ALL;
}

unsigned rend_frame_get_components(const rend_frame *f) { return f->components; }

int rend_frame_get_supersample(const rend_frame *f) { return f->desc.supersample; }

void rend_frame_jitter_pattern(int i, int k, int s, float *jx, float *jy)
{
    const float cell = 1.0f / (float)s;
    *jx = (((float)(i % k) + 0.5f) / (float)k - 0.5f) * cell;
    *jy = (((float)(i / k) + 0.5f) / (float)k - 0.5f) * cell;
}

void rend_frame_defer_highlights(rend_frame *f) { f->defer_highlights = 1; }

void rend_frame_set_jitter(rend_frame *f, float jx, float jy)
{
    f->jitter[0] = isfinite(jx) ? jx : 0.0f;
    f->jitter[1] = isfinite(jy) ? jy : 0.0f;
}

lm_result rend_frame_set_emission(rend_frame *f, uint32_t material, const float le[3], lm_error *err)
{
    if (!f->desc.scene || material >= f->desc.scene->material_count)
        return lm_fail(err, LM_ERR_INVALID_ARG, "rend_frame_set_emission: material %u does not exist", material);
    for (int k = 0; k < 3; ++k)
        if (!(le[k] >= 0.0f) || !isfinite(le[k]))
            return lm_fail(err, LM_ERR_INVALID_ARG, "rend_frame_set_emission: radiance must be finite and non-negative");
    float v[4] = {le[0], le[1], le[2], 0.0f};
    GLintptr at = (GLintptr)(material * sizeof(material_entry) + offsetof(material_entry, le));
    f->gl->NamedBufferSubData(f->material_ssbo, at, sizeof v, v);
    f->comp_valid = 0;
    return LM_OK;
}

void rend_frame_get_output(const rend_frame *f, rend_frame_output *out)
{
    *out = (rend_frame_output){f->out_tex, f->out_fbo, f->desc.width, f->desc.height};
}
