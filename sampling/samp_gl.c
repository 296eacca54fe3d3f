/* samp_gl.c — the GL rasterization sampler ("hardware sampling", Fournier &
 * Péroche 2005 §5; DESIGN.md "Sampling"): creation, shaders, the atlas
 * framebuffers, view matrices and the GPU reduction shared by
 * samp_gl_direct.c (area lights through a small frustum per point) and
 * samp_gl_indirect.c (the coarse radiance mesh through a hemicube or the
 * paper's 160° plane).
 *
 * Batching: a call renders many points at once. Every point (direct) or point
 * and face (indirect) is a view: one instance of the draw, its matrix and atlas
 * rectangle read from instanced attributes, its pixels confined to its
 * rectangle by clip distances. One compute dispatch then sums every tile and
 * only the sums are read back.
 *
 * Depth: reversed Z with a 32-bit float depth buffer (glClipControl zero-to-one,
 * cleared to 0, GL_GREATER) and an infinite far plane, so depth precision is
 * relative (2⁻²⁴ of the distance) at every distance and the near plane can sit
 * at a thousandth of the receiver offset eps without starving the far field.
 * It must be that close: at a corner the adjacent wall is about eps from the
 * lifted origin, and seen 80° off the view axis (the 160° plane, a wide direct
 * frustum) its depth is eps·cos80°; a near plane at eps/2 cut it away and the
 * empty space behind it showed through (measured: 17% of E missing).
 *
 * Threads and context: samp_gl_create creates the GL context (EGL or OSMesa,
 * desc.gl_platform) and makes it current on the CALLING thread; the sampler must
 * then be used and destroyed on that thread only (samp.h: a sampler belongs to
 * the thread that created it). Each call makes the context current again first,
 * so several GL samplers (even of both platforms) may take turns on one thread.
 * Each call leaves the GL state it changed as it found it (defaults).
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "src/gpu/gl_program.h"
#include "sampling/samp_gl_internal.h"
#include "src/base/vfs.h"

enum { ATLAS_SIDE = 2048 };

lm_result samp_gl_reserve(void **buf, size_t *cap, size_t need, size_t elem, lm_error *err)
{
    if (need <= *cap) return LM_OK;
    size_t n = *cap ? *cap : 256;
    while (n < need) n *= 2;
    void *p = realloc(*buf, n * elem);
    if (!p) return lm_fail(err, LM_ERR_NO_MEMORY, "GL sampler: out of memory (%zu bytes of scratch)", n * elem);
    *buf = p;
    *cap = n;
    return LM_OK;
}

lm_result samp_gl_upload(samp_gl *g, GLuint buf, size_t *cap, const void *data, size_t bytes, lm_error *err)
{
    const GladGLContext *gl = g->gl;
    if (bytes > *cap) {
        size_t n = *cap ? *cap : 4096;
        while (n < bytes) n *= 2;
        gl->NamedBufferData(buf, (GLsizeiptr)n, NULL, GL_STREAM_DRAW);
        *cap = n;
    }
    if (bytes) gl->NamedBufferSubData(buf, 0, (GLsizeiptr)bytes, data);
    return glctx_check(g->ctx, "a buffer upload", err);
}

/* ---- atlas ---------------------------------------------------------------- */

lm_result samp_gl_atlas_make(samp_gl *g, samp_gl_atlas *a, int tile_w, int tile_h, GLenum format, int color_count,
                             lm_error *err)
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
    a->rows = side_h / tile_h;
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
    if (bytes > g->sum_cap) {
        size_t n = g->sum_cap ? g->sum_cap : 4096;
        while (n < bytes) n *= 2;
        gl->NamedBufferData(g->sum_buf, (GLsizeiptr)n, NULL, GL_STREAM_READ);
        g->sum_cap = n;
    }
    lm_result r = samp_gl_reserve((void **)&g->sums, &g->sums_cap_cpu, (size_t)tiles * (size_t)per_tile, sizeof(float),
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

/* ---- creation ------------------------------------------------------------- */

/* The programs' shaders, built-in files (shaders/, embedded by CMake). */
static const char *const direct_names[] = {"samp_gl_view.vert", "samp_gl_direct.frag", NULL};
static const char *const indirect_names[] = {"samp_gl_view.vert", "samp_gl_indirect.frag", NULL};
static const char *const reduce_names[] = {"samp_gl_reduce.comp", NULL};

static void samp_gl_destroy(void *impl)
{
    samp_gl *g = impl;
    if (!g) return;
    if (g->ctx && glctx_make_current(g->ctx, NULL) == LM_OK) {
        const GladGLContext *gl = g->gl;
        samp_gl_atlas_free(g, &g->direct_atlas);
        samp_gl_atlas_free(g, &g->indirect_atlas);
        GLuint bufs[] = {g->scene_vbo, g->view_buf, g->index_buf, g->cmd_buf, g->sum_buf, g->radiance_vbo};
        gl->DeleteBuffers((GLsizei)(sizeof bufs / sizeof bufs[0]), bufs);
        if (g->weight_tex) gl->DeleteTextures(1, &g->weight_tex);
        if (g->vao) gl->DeleteVertexArrays(1, &g->vao);
        GLuint progs[] = {g->prog_direct, g->prog_indirect, g->prog_reduce2, g->prog_reduce3};
        for (size_t i = 0; i < sizeof progs / sizeof progs[0]; ++i)
            if (progs[i]) gl->DeleteProgram(progs[i]);
    }
    glctx_destroy(g->ctx);
    samp_gl_grid_free(&g->grid);
    free(g->stamp);
    free(g->views);
    free(g->indices);
    free(g->cmds);
    free(g->light_dirs);
    free(g->batch_point);
    free(g->batch_unocc);
    free(g->sums);
    free(g);
}

/* The scene's triangles, unwelded, each vertex tagged with its area light. */
static lm_result upload_scene(samp_gl *g, lm_error *err)
{
    const scene *s = g->s;
    size_t nv = 3 * (size_t)s->tri_count;
    samp_gl_vertex *v = calloc(nv ? nv : 1, sizeof *v);
    if (!v) return lm_fail(err, LM_ERR_NO_MEMORY, "GL sampler: out of memory for %u triangles", s->tri_count);
    for (uint32_t t = 0; t < s->tri_count; ++t)
        for (int c = 0; c < 3; ++c) {
            samp_gl_vertex *o = &v[3 * (size_t)t + (size_t)c];
            memcpy(o->pos, s->positions + 3 * (size_t)s->tris[t].v[c], sizeof o->pos);
            o->attr[0] = (float)s->tris[t].light;
            o->attr[1] = o->attr[2] = 0.0f;
        }
    /* GL refuses empty storage: a scene without triangles gets one unused vertex. */
    g->gl->NamedBufferStorage(g->scene_vbo, (GLsizeiptr)((nv ? nv : 1) * sizeof *v), v, 0);
    free(v);
    return glctx_check(g->ctx, "the scene upload", err);
}

static void setup_vao(samp_gl *g)
{
    const GladGLContext *gl = g->gl;
    GLuint vao = g->vao;
    /* binding 0: vertices (samp_gl_vertex); binding 1: views, one per instance */
    gl->VertexArrayAttribFormat(vao, 0, 3, GL_FLOAT, GL_FALSE, (GLuint)offsetof(samp_gl_vertex, pos));
    gl->VertexArrayAttribFormat(vao, 1, 3, GL_FLOAT, GL_FALSE, (GLuint)offsetof(samp_gl_vertex, attr));
    for (GLuint a = 0; a < 2; ++a) {
        gl->VertexArrayAttribBinding(vao, a, 0);
        gl->EnableVertexArrayAttrib(vao, a);
    }
    for (GLuint a = 0; a < 7; ++a) {
        gl->VertexArrayAttribFormat(vao, 2 + a, 4, GL_FLOAT, GL_FALSE, (GLuint)(a * 4 * sizeof(float)));
        gl->VertexArrayAttribBinding(vao, 2 + a, 1);
        gl->EnableVertexArrayAttrib(vao, 2 + a);
    }
    gl->VertexArrayBindingDivisor(vao, 1, 1);
    gl->VertexArrayVertexBuffer(vao, 1, g->view_buf, 0, sizeof(samp_gl_view));
}

lm_result samp_gl_create(const samp_desc *desc, const rt_scene *rt, const samp_backend_ops **ops, void **impl,
                         lm_error *err)
{
    *ops = NULL;
    *impl = NULL;
    samp_gl *g = calloc(1, sizeof *g);
    if (!g) return lm_fail(err, LM_ERR_NO_MEMORY, "GL sampler: out of memory");
    g->desc = samp_desc_defaults(desc);
    g->s = desc->scene;
    g->rt = rt;
    g->eps = rt_scene_epsilon(rt);
    g->near = 1e-3 * g->eps;
    lm_result r = glctx_create(&(glctx_desc){.platform = g->desc.gl_platform}, &g->ctx, err);
    if (r != LM_OK) {
        free(g);
        return r;
    }
    g->gl = glctx_gl(g->ctx);
    const GladGLContext *gl = g->gl;
    g->ops = (samp_backend_ops){.backend = SAMP_BACKEND_GL,
                                .gl_platform = g->desc.gl_platform,
                                .name = glctx_name(g->ctx),
                                .direct = samp_gl_direct,
                                .indirect = samp_gl_indirect,
                                .destroy = samp_gl_destroy};
    gl->GetIntegerv(GL_MAX_TEXTURE_SIZE, &g->max_tex);

    r = glprog_build(g->gl, g->ops.name, direct_names, "", &g->prog_direct, err);
    if (r == LM_OK) r = glprog_build(g->gl, g->ops.name, indirect_names, "", &g->prog_indirect, err);
    if (r == LM_OK) r = glprog_build(g->gl, g->ops.name, reduce_names, "", &g->prog_reduce2, err);
    if (r == LM_OK) r = glprog_build(g->gl, g->ops.name, reduce_names, "#define INDIRECT 1\n", &g->prog_reduce3, err);
    if (r == LM_OK) {
        g->loc_direct_atlas = gl->GetUniformLocation(g->prog_direct, "u_atlas");
        g->loc_direct_light = gl->GetUniformLocation(g->prog_direct, "u_light");
        g->loc_indirect_atlas = gl->GetUniformLocation(g->prog_indirect, "u_atlas");
        gl->CreateVertexArrays(1, &g->vao);
        GLuint bufs[6];
        gl->CreateBuffers(6, bufs);
        g->scene_vbo = bufs[0];
        g->view_buf = bufs[1];
        g->index_buf = bufs[2];
        g->cmd_buf = bufs[3];
        g->sum_buf = bufs[4];
        g->radiance_vbo = bufs[5];
        /* Buffers made by glCreateBuffers have no storage yet: give the
         * growable ones a small one so the VAO may reference them. */
        gl->NamedBufferData(g->view_buf, 4096, NULL, GL_STREAM_DRAW);
        g->view_cap = 4096;
        setup_vao(g);
        r = upload_scene(g, err);
    }
    if (r == LM_OK)
        r = samp_gl_atlas_make(g, &g->direct_atlas, g->desc.direct_res, g->desc.direct_res, GL_R32F, 2, err);
    if (r == LM_OK) r = samp_gl_grid_build(g, err);
    if (r == LM_OK) {
        uint32_t most = 1;
        for (uint32_t i = 0; i < g->s->area_light_count; ++i)
            if (g->s->area_lights[i].count > most) most = g->s->area_lights[i].count;
        g->stamp = calloc(g->s->tri_count ? g->s->tri_count : 1, sizeof *g->stamp);
        g->light_dirs = malloc(4 * (size_t)most * sizeof *g->light_dirs);
        if (!g->stamp || !g->light_dirs) r = lm_fail(err, LM_ERR_NO_MEMORY, "GL sampler: out of memory");
    }
    if (r == LM_OK) r = glctx_check(g->ctx, "sampler creation", err);
    if (r != LM_OK) {
        samp_gl_destroy(g);
        return r;
    }
    *ops = &g->ops;
    *impl = g;
    return LM_OK;
}
