/* samp_gl.c — the GL rasterization sampler ("hardware sampling", Fournier &
 * Péroche 2005 §5; docs/sampling.md): creation and destruction (context,
 * shaders, the scene's vertices). Calls go down from here: to samp_gl_direct.c
 * (area lights through a small frustum per point), samp_gl_indirect.c (the
 * coarse radiance mesh through a hemicube or the paper's 160° plane) and
 * samp_gl_draw.c (what both draw with: the atlas framebuffers, view matrices,
 * the GPU reduction).
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
 * at a thousandth of the receiver's offset eps (SAMP_GL_NEAR_REL; each view its
 * own, as eps follows the receiver's triangle) without starving the far field.
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
#include <stddef.h>
#include <stdlib.h>
#include <string.h>

#include "sampling/samp_gl_internal.h"
#include "src/gpu/gl_program.h"

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
    g->desc = *desc; /* defaults filled in (samp_internal.h) */
    g->s = desc->scene;
    g->rt = rt;
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
        r = samp_gl_atlas_make(g, &g->direct_atlas, g->desc.direct_res, g->desc.direct_res, GL_R32F, 2, 1, err);
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
