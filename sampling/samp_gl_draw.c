/* samp_gl_draw.c — what the GL sampler's passes (samp_gl_direct.c,
 * samp_gl_indirect.c) draw with: growing CPU scratch and GPU buffers, the atlas
 * framebuffers, the draw state of a batch of views, view matrices and the GPU
 * reduction of each tile. Calls nothing above it in sampling/ (samp_gl.c
 * creates the sampler and calls down to here). The depth convention and
 * batching are described in samp_gl.c. Threads: the sampler's (its context
 * current). */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "sampling/samp_gl_internal.h"

/* An atlas's side, pixels: how many views one draw batches (at the default 64-pixel
 * views, 256 direct tiles or 80 indirect hemicubes). 2048 held 129 MB of GL images
 * per GL sampler (direct: two R32F and a depth, 50 MB; indirect: RGBA32F and a
 * depth, 79 MB); 1024 holds a quarter, with the same errors and no slower
 * (bench_sampling: direct 73 → 59 µs a sample on the Cornell box, indirect within
 * the runs' spread; docs/memory.md). */
enum { ATLAS_SIDE = 1024 };

lm_result samp_gl_reserve(void *ptr_to_ptr, size_t *cap, size_t need, size_t elem, lm_error *err)
{
    if (need <= *cap) return LM_OK;
    size_t n = lm_grow_capacity(*cap, need, 256, (size_t)PTRDIFF_MAX / elem);
    if (!n || !lm_realloc_array(ptr_to_ptr, *cap, n, elem))
        return lm_fail(err, LM_ERR_NO_MEMORY, "GL sampler: out of memory (%zu elements of %zu bytes of scratch)",
                       need, elem);
    *cap = n;
    return LM_OK;
}

/* Gives GL buffer `buf` (*cap bytes of storage) room for `bytes`, doubling from
 * 4 KiB; the old contents are not kept. */
static void gpu_reserve(samp_gl *g, GLuint buf, size_t *cap, size_t bytes, GLenum usage)
{
    if (bytes <= *cap) return;
    size_t n = lm_grow_capacity(*cap, bytes, 4096, (size_t)PTRDIFF_MAX);
    g->gl->NamedBufferData(buf, (GLsizeiptr)n, NULL, usage);
    *cap = n;
}

lm_result samp_gl_upload(samp_gl *g, GLuint buf, size_t *cap, const void *data, size_t bytes, lm_error *err)
{
    const GladGLContext *gl = g->gl;
    gpu_reserve(g, buf, cap, bytes, GL_STREAM_DRAW);
    if (bytes) gl->NamedBufferSubData(buf, 0, (GLsizeiptr)bytes, data);
    return glctx_check(g->ctx, "a buffer upload", err);
}

/* ---- atlas ---------------------------------------------------------------- */

lm_result samp_gl_atlas_make(samp_gl *g, samp_gl_atlas *a, int tile_w, int tile_h, GLenum format, int color_count,
                             uint32_t tiles, lm_error *err)
{
    const GladGLContext *gl = g->gl;
    /* ATLAS_SIDE² pixels, or one tile when a tile is larger, within GL's limit. */
    int side_w = tile_w > ATLAS_SIDE ? tile_w : ATLAS_SIDE, side_h = tile_h > ATLAS_SIDE ? tile_h : ATLAS_SIDE;
    if (side_w > g->max_tex) side_w = g->max_tex;
    if (side_h > g->max_tex) side_h = g->max_tex;
    if (tile_w > side_w || tile_h > side_h)
        return lm_fail(err, LM_ERR_UNSUPPORTED,
                       "%s: a %d×%d view does not fit this GL's %d-pixel textures (lower the sampler resolution)",
                       g->ops.name, tile_w, tile_h, g->max_tex);
    memset(a, 0, sizeof *a);
    a->tile_w = tile_w;
    a->tile_h = tile_h;
    a->cols = side_w / tile_w;
    a->full_rows = side_h / tile_h;
    uint32_t need = tiles ? (tiles + (uint32_t)a->cols - 1) / (uint32_t)a->cols : (uint32_t)a->full_rows;
    a->rows = need < (uint32_t)a->full_rows ? (int)need : a->full_rows;
    a->format = format;
    a->width = a->cols * tile_w;
    a->height = a->rows * tile_h;
    a->color_count = color_count;
    gl->CreateFramebuffers(1, &a->fbo);
    gl->CreateTextures(GL_TEXTURE_2D, color_count, a->color);
    GLenum bufs[2] = {GL_COLOR_ATTACHMENT0, GL_COLOR_ATTACHMENT1};
    for (int i = 0; i < color_count; ++i) {
        gl->TextureStorage2D(a->color[i], 1, format, a->width, a->height);
        gl->TextureParameteri(a->color[i], GL_TEXTURE_MIN_FILTER, GL_NEAREST);
        gl->TextureParameteri(a->color[i], GL_TEXTURE_MAG_FILTER, GL_NEAREST);
        gl->NamedFramebufferTexture(a->fbo, bufs[i], a->color[i], 0);
    }
    gl->NamedFramebufferDrawBuffers(a->fbo, color_count, bufs);
    gl->CreateRenderbuffers(1, &a->depth);
    gl->NamedRenderbufferStorage(a->depth, GL_DEPTH_COMPONENT32F, a->width, a->height);
    gl->NamedFramebufferRenderbuffer(a->fbo, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, a->depth);
    GLenum status = gl->CheckNamedFramebufferStatus(a->fbo, GL_FRAMEBUFFER);
    lm_result r = glctx_check(g->ctx, "atlas creation", err);
    if (r == LM_OK && status != GL_FRAMEBUFFER_COMPLETE)
        r = lm_fail(err, LM_ERR_UNSUPPORTED, "%s: a %d×%d float framebuffer is not supported here (status 0x%x)",
                    g->ops.name, a->width, a->height, (unsigned)status);
    if (r != LM_OK) samp_gl_atlas_free(g, a);
    return r;
}

lm_result samp_gl_atlas_fit(samp_gl *g, samp_gl_atlas *a, uint32_t n, lm_error *err)
{
    const uint32_t cols = (uint32_t)a->cols, full = cols * (uint32_t)a->full_rows;
    const uint32_t want = n < full ? n : full;
    if (want <= cols * (uint32_t)a->rows) return LM_OK;
    uint32_t rows = (uint32_t)a->rows;
    while (rows * cols < want) rows *= 2;
    const samp_gl_atlas old = *a;
    samp_gl_atlas_free(g, a);
    return samp_gl_atlas_make(g, a, old.tile_w, old.tile_h, old.format, old.color_count, rows * cols, err);
}

void samp_gl_atlas_free(samp_gl *g, samp_gl_atlas *a)
{
    const GladGLContext *gl = g->gl;
    if (a->fbo) gl->DeleteFramebuffers(1, &a->fbo);
    if (a->color_count) gl->DeleteTextures(a->color_count, a->color);
    if (a->depth) gl->DeleteRenderbuffers(1, &a->depth);
    memset(a, 0, sizeof *a);
}

void samp_gl_begin_draw(samp_gl *g, const samp_gl_atlas *a, uint32_t tiles)
{
    const GladGLContext *gl = g->gl;
    int rows = (int)((tiles + (uint32_t)a->cols - 1) / (uint32_t)a->cols);
    gl->GetIntegerv(GL_VIEWPORT, g->saved_viewport);
    gl->BindFramebuffer(GL_DRAW_FRAMEBUFFER, a->fbo);
    gl->Viewport(0, 0, a->width, a->height);
    /* Clear only the rows this batch uses. */
    gl->Enable(GL_SCISSOR_TEST);
    gl->Scissor(0, 0, a->width, rows * a->tile_h);
    const GLfloat zero[4] = {0, 0, 0, 0}, depth0 = 0.0f;
    for (int i = 0; i < a->color_count; ++i) gl->ClearNamedFramebufferfv(a->fbo, GL_COLOR, i, zero);
    gl->ClearNamedFramebufferfv(a->fbo, GL_DEPTH, 0, &depth0);
    gl->Disable(GL_SCISSOR_TEST);
    gl->ClipControl(GL_LOWER_LEFT, GL_ZERO_TO_ONE);
    gl->DepthFunc(GL_GREATER);
    for (int i = 0; i < 4; ++i) gl->Enable(GL_CLIP_DISTANCE0 + (GLenum)i);
    gl->BindVertexArray(g->vao);
}

void samp_gl_end_draw(samp_gl *g)
{
    const GladGLContext *gl = g->gl;
    for (int i = 0; i < 4; ++i) gl->Disable(GL_CLIP_DISTANCE0 + (GLenum)i);
    gl->ClipControl(GL_LOWER_LEFT, GL_NEGATIVE_ONE_TO_ONE);
    gl->DepthFunc(GL_LESS);
    gl->Disable(GL_DEPTH_TEST);
    gl->DepthMask(GL_TRUE);
    gl->ColorMask(GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);
    gl->BindVertexArray(0);
    gl->UseProgram(0);
    gl->BindBuffer(GL_DRAW_INDIRECT_BUFFER, 0);
    gl->BindFramebuffer(GL_DRAW_FRAMEBUFFER, 0);
    gl->Viewport(g->saved_viewport[0], g->saved_viewport[1], g->saved_viewport[2], g->saved_viewport[3]);
}

void samp_gl_view_make(samp_gl_view *v, const double eye[3], const double ex[3], const double ey[3],
                       const double ez[3], double l, double r, double b, double t, double near, const float rect[4])
{
    /* View: rows ex, ey, ez and translation -R·eye. Projection of the region
     * [l,r]×[b,t] on the plane at unit distance, reversed infinite Z:
     *   x_c = (2x + (r+l)z)/(r-l)... with z = -depth, z_c = near, w_c = -z. */
    const double *R[3] = {ex, ey, ez};
    double V[4][4] = {{0}};
    for (int i = 0; i < 3; ++i) {
        for (int k = 0; k < 3; ++k) V[i][k] = R[i][k];
        V[i][3] = -(R[i][0] * eye[0] + R[i][1] * eye[1] + R[i][2] * eye[2]);
    }
    V[3][3] = 1.0;
    double P[4][4] = {{0}};
    P[0][0] = 2.0 / (r - l);
    P[0][2] = (r + l) / (r - l);
    P[1][1] = 2.0 / (t - b);
    P[1][2] = (t + b) / (t - b);
    P[2][3] = near;
    P[3][2] = -1.0;
    for (int i = 0; i < 4; ++i)
        for (int j = 0; j < 4; ++j) {
            double s = 0.0;
            for (int k = 0; k < 4; ++k) s += P[i][k] * V[k][j];
            v->pv[j * 4 + i] = (float)s; /* column-major */
        }
    memcpy(v->rect, rect, sizeof v->rect);
    memset(v->extra, 0, sizeof v->extra);
    v->region[0] = (float)l;
    v->region[1] = (float)r;
    v->region[2] = (float)b;
    v->region[3] = (float)t;
}

lm_result samp_gl_reduce(samp_gl *g, const samp_gl_atlas *a, uint32_t tiles, int per_tile, lm_error *err)
{
    const GladGLContext *gl = g->gl;
    size_t bytes = (size_t)tiles * (size_t)per_tile * sizeof(float);
    gpu_reserve(g, g->sum_buf, &g->sum_cap, bytes, GL_STREAM_READ);
    lm_result r = samp_gl_reserve(&g->sums, &g->sums_cap_cpu, (size_t)tiles * (size_t)per_tile, sizeof(float),
                                  err);
    if (r != LM_OK) return r;
    GLuint prog = per_tile == 2 ? g->prog_reduce2 : g->prog_reduce3;
    gl->UseProgram(prog);
    gl->Uniform2i(gl->GetUniformLocation(prog, "u_tile"), a->tile_w, a->tile_h);
    gl->Uniform1i(gl->GetUniformLocation(prog, "u_cols"), a->cols);
    gl->BindTextureUnit(0, a->color[0]);
    gl->BindTextureUnit(1, per_tile == 2 ? a->color[1] : g->weight_tex);
    gl->BindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, g->sum_buf);
    gl->DispatchCompute(tiles, 1, 1);
    gl->MemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT);
    gl->GetNamedBufferSubData(g->sum_buf, 0, (GLsizeiptr)bytes, g->sums);
    gl->BindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, 0);
    gl->BindTextureUnit(0, 0);
    gl->BindTextureUnit(1, 0);
    gl->UseProgram(0);
    return glctx_check(g->ctx, "the reduction", err);
}
