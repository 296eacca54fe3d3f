/* rend_frame_whole.c — whole roots (cache_snapshot_mesh.whole): a term's leaves
 * that are a scene triangle with its own three corners, drawn per sample from
 * the material pass's triangle (shaders/rend_whole.frag) instead of as
 * triangles. What the GPU holds for them is a bit a scene triangle and a value
 * a vertex-table id, and each scene corner's id once for the scene; what is
 * drawn costs per sample, not per triangle. A million-triangle scene's first
 * image had 2 million such leaves: 0.2 s to upload and 0.3 s through llvmpipe's
 * vertex stage (docs/cache.md, "Whole roots by vertex id"). The rest of the
 * passes are rend_frame.c's; the leaves that are not whole are drawn there as
 * before, and this pass then writes over the samples whose triangle is whole.
 * Threads: the renderer's (its GL context's). */
#include "src/render/rend_frame_internal.h"

#include <stdlib.h>
#include <string.h>

/* rend_ensure_buffer, with the buffer's texture view tex of format fmt made
 * again when the buffer is new. */
static void ensure_texture_buffer(const GladGLContext *gl, GLuint *buf, GLuint *tex, size_t *cap, size_t bytes,
                                  GLenum fmt)
{
    if (!rend_ensure_buffer(gl, buf, cap, bytes ? bytes : 16)) return;
    gl->DeleteTextures(1, tex);
    gl->CreateTextures(GL_TEXTURE_BUFFER, 1, tex);
    gl->TextureBuffer(*tex, fmt, *buf);
}

static size_t mask_words(const rend_frame *f) { return ((size_t)f->desc.scene->tri_count + 31) / 32; }

int rend_whole_upload_corners(rend_frame *f, const cache_snapshot *snap)
{
    if (!snap || !snap->corner_ids || snap->corner_ids_serial == f->corner_serial) return 0;
    const GladGLContext *gl = f->gl;
    const size_t bytes = 3 * (size_t)f->desc.scene->tri_count * sizeof *snap->corner_ids;
    gl->DeleteBuffers(1, &f->corner_buf);
    gl->DeleteTextures(1, &f->corner_tex);
    gl->CreateBuffers(1, &f->corner_buf);
    gl->NamedBufferStorage(f->corner_buf, (GLsizeiptr)(bytes ? bytes : 16), bytes ? snap->corner_ids : NULL, 0);
    gl->CreateTextures(GL_TEXTURE_BUFFER, 1, &f->corner_tex);
    gl->TextureBuffer(f->corner_tex, GL_R32UI, f->corner_buf);
    f->corner_serial = snap->corner_ids_serial;
    return 1;
}

void rend_whole_upload(rend_frame *f, term_state *ts, const cache_snapshot_mesh *m)
{
    const GladGLContext *gl = f->gl;
    ts->whole_src = m ? m->whole : NULL;
    ts->whole_owed = 0;
    ts->whole_count = ts->value_count = 0;
    if (!m || !m->whole_count || !m->whole) return;
    const size_t wbytes = mask_words(f) * sizeof *m->whole, vbytes = 3 * (size_t)m->value_count * sizeof *m->values;
    ensure_texture_buffer(gl, &ts->whole_buf, &ts->whole_tex, &ts->whole_buf_cap, wbytes, GL_R32UI);
    ensure_texture_buffer(gl, &ts->values_buf, &ts->values_tex, &ts->values_buf_cap, vbytes, GL_RGB32F);
    gl->NamedBufferSubData(ts->whole_buf, 0, (GLsizeiptr)wbytes, m->whole);
    if (vbytes) gl->NamedBufferSubData(ts->values_buf, 0, (GLsizeiptr)vbytes, m->values);
    ts->whole_count = m->whole_count;
    ts->value_count = m->value_count;
    ts->whole_owed = !f->desc.one_snapshot;
}

/* The CPU copies of what ts's whole buffers hold, read back the first time they
 * are compared (as copy_from_buffers does for the leaves). */
static lm_result copies_from_buffers(rend_frame *f, term_state *ts, lm_error *err)
{
    if (!ts->whole_owed) return LM_OK;
    const size_t words = mask_words(f), floats = 3 * (size_t)ts->value_count;
    if (words > ts->copy_whole_cap) {
        uint32_t *w = realloc(ts->copy_whole, words * sizeof *w);
        if (!w) return lm_fail(err, LM_ERR_NO_MEMORY, "renderer: out of memory comparing snapshots");
        ts->copy_whole = w;
        ts->copy_whole_cap = words;
    }
    if (floats > ts->copy_values_cap) {
        float *v = realloc(ts->copy_values, floats * sizeof *v);
        if (!v) return lm_fail(err, LM_ERR_NO_MEMORY, "renderer: out of memory comparing snapshots");
        ts->copy_values = v;
        ts->copy_values_cap = floats;
    }
    const GladGLContext *gl = f->gl;
    gl->GetNamedBufferSubData(ts->whole_buf, 0, (GLsizeiptr)(words * sizeof *ts->copy_whole), ts->copy_whole);
    if (floats) gl->GetNamedBufferSubData(ts->values_buf, 0, (GLsizeiptr)(floats * sizeof *ts->copy_values), ts->copy_values);
    ts->whole_owed = 0;
    return LM_OK;
}

lm_result rend_whole_same(rend_frame *f, term_state *ts, const cache_snapshot_mesh *m, int *same, lm_error *err)
{
    const uint32_t nw = m && m->whole ? m->whole_count : 0;
    *same = nw == ts->whole_count;
    if (!*same || !nw) return LM_OK;
    *same = m->value_count == ts->value_count;
    if (!*same) return LM_OK;
    lm_result r = copies_from_buffers(f, ts, err);
    if (r != LM_OK) return r;
    *same = memcmp(m->whole, ts->copy_whole, mask_words(f) * sizeof *m->whole) == 0 &&
            memcmp(m->values, ts->copy_values, 3 * (size_t)m->value_count * sizeof *m->values) == 0;
    return LM_OK;
}

/* Value of id in an array of n ids (RGB), zero past its end. */
static void value_at(const float *values, uint32_t n, uint32_t id, float out[3])
{
    if (id < n)
        memcpy(out, values + 3 * (size_t)id, 3 * sizeof *out);
    else
        out[0] = out[1] = out[2] = 0.0f;
}

lm_result rend_whole_changed_rect(rend_frame *f, term_state *ts, const cache_snapshot_mesh *m,
                                  const uint32_t *corner_ids, const float vp[16], rect *out, lm_error *err)
{
    *out = (rect){0, 0, 0, 0};
    const uint32_t nw = m && m->whole ? m->whole_count : 0;
    if (!nw && !ts->whole_count) return LM_OK;
    lm_result r = copies_from_buffers(f, ts, err);
    if (r != LM_OK) return r;
    /* Which ids' values changed, over both arrays (a missing value is zero). */
    const uint32_t old_n = ts->whole_count ? ts->value_count : 0, new_n = nw ? m->value_count : 0;
    const uint32_t ids = old_n > new_n ? old_n : new_n;
    if (ids > f->id_changed_cap) {
        uint8_t *c = realloc(f->id_changed, ids);
        if (!c) return lm_fail(err, LM_ERR_NO_MEMORY, "renderer: out of memory comparing snapshots");
        f->id_changed = c;
        f->id_changed_cap = ids;
    }
    for (uint32_t id = 0; id < ids; ++id) {
        float a[3], b[3];
        value_at(ts->copy_values, old_n, id, a);
        value_at(nw ? m->values : NULL, new_n, id, b);
        f->id_changed[id] = memcmp(a, b, sizeof a) != 0;
    }
    const scene *s = f->desc.scene;
    const size_t words = mask_words(f);
    const rect full = {0, 0, f->sw, f->sh};
    for (size_t w = 0; w < words; ++w) {
        const uint32_t was = ts->whole_count ? ts->copy_whole[w] : 0u, is = nw ? m->whole[w] : 0u;
        if (!(was | is)) continue;
        for (uint32_t bits = was | is; bits; bits &= bits - 1u) {
            const uint32_t t = (uint32_t)(w * 32) + (uint32_t)__builtin_ctz(bits);
            const uint32_t bit = 1u << (t & 31u);
            int changed = (was & bit) != (is & bit);
            if (!changed && corner_ids)
                for (int k = 0; k < 3 && !changed; ++k) {
                    const uint32_t id = corner_ids[3 * (size_t)t + (size_t)k];
                    changed = id < ids && f->id_changed[id];
                }
            if (!changed) continue;
            const float *const p[3] = {s->positions + 3 * (size_t)s->tris[t].v[0],
                                       s->positions + 3 * (size_t)s->tris[t].v[1],
                                       s->positions + 3 * (size_t)s->tris[t].v[2]};
            rend_rect_add_corners(out, vp, p, f->sw, f->sh);
            if (memcmp(out, &full, sizeof full) == 0) return LM_OK;
        }
    }
    return LM_OK;
}

void rend_whole_draw(rend_frame *f, term_state *ts, const float vp[16], int y0)
{
    const GladGLContext *gl = f->gl;
    gl->Disable(GL_DEPTH_TEST);
    gl->UseProgram(f->prog_whole);
    gl->UniformMatrix4fv(f->loc_whole_vp, 1, GL_FALSE, vp);
    gl->Uniform1i(f->loc_whole_band, y0);
    gl->Uniform2f(f->loc_whole_samples, (float)f->sw, (float)f->sh);
    GLuint inputs[5] = {f->mat_tex, f->scene_tex, f->corner_tex, ts->whole_tex, ts->values_tex};
    gl->BindTextures(0, 5, inputs);
    gl->BindVertexArray(f->empty_vao);
    gl->DrawArrays(GL_TRIANGLES, 0, 3);
    gl->BindTextures(0, 5, NULL);
    gl->Enable(GL_DEPTH_TEST);
}
