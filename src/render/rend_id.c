/* rend_id.c — the ID pass (rend_id.h). */
#include "src/render/rend_id.h"

#include <stdlib.h>
#include <string.h>

#include "src/gpu/gl_program.h"
#include "src/scene/camera.h"

struct rend_id {
    rend_id_desc desc;
    const GladGLContext *gl;
    GLuint fbo, id_tex, depth_rb, vbo, vao, prog_draw, prog_count, count_buf;
    GLint loc_viewproj;
    uint32_t *pixels;        /* tri_count counters of the last render */
    uint32_t *visible;       /* visible ids of the last render */
    uint32_t *image;         /* READBACK: the id image, GL row order */
};

static const char *const draw_names[] = {"rend_id.vert", "rend_id.frag", NULL};
static const char *const count_names[] = {"rend_id_count.comp", NULL};

void rend_id_destroy(rend_id *ip)
{
    if (!ip) return;
    const GladGLContext *gl = ip->gl;
    if (gl) {
        if (ip->fbo) gl->DeleteFramebuffers(1, &ip->fbo);
        if (ip->id_tex) gl->DeleteTextures(1, &ip->id_tex);
        if (ip->depth_rb) gl->DeleteRenderbuffers(1, &ip->depth_rb);
        if (ip->vbo) gl->DeleteBuffers(1, &ip->vbo);
        if (ip->count_buf) gl->DeleteBuffers(1, &ip->count_buf);
        if (ip->vao) gl->DeleteVertexArrays(1, &ip->vao);
        if (ip->prog_draw) gl->DeleteProgram(ip->prog_draw);
        if (ip->prog_count) gl->DeleteProgram(ip->prog_count);
    }
    free(ip->pixels);
    free(ip->visible);
    free(ip->image);
    free(ip);
}

lm_result rend_id_create(const GladGLContext *gl, const rend_id_desc *desc, rend_id **out, lm_error *err)
{
    *out = NULL;
    if (!gl || !desc || !desc->scene || desc->width <= 0 || desc->height <= 0 || desc->width > 16384 ||
        desc->height > 16384 || (unsigned)desc->count >= REND_ID_COUNT_COUNT)
        return lm_fail(err, LM_ERR_INVALID_ARG, "ID pass: needs a scene and a size from 1x1 to 16384x16384");
    const scene *s = desc->scene;
    rend_id *ip = calloc(1, sizeof *ip);
    if (!ip) return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory creating the ID pass");
    ip->desc = *desc;
    ip->gl = gl;
    size_t n = (size_t)desc->width * (size_t)desc->height;
    ip->pixels = calloc(s->tri_count ? s->tri_count : 1, sizeof *ip->pixels);
    ip->visible = calloc(s->tri_count ? s->tri_count : 1, sizeof *ip->visible);
    ip->image = malloc(n * sizeof *ip->image);
    float *verts = malloc(9 * (size_t)s->tri_count * sizeof *verts);
    if (!ip->pixels || !ip->visible || !ip->image || !verts) {
        free(verts);
        rend_id_destroy(ip);
        return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory creating the ID pass");
    }
    for (uint32_t t = 0; t < s->tri_count; ++t)
        for (int c = 0; c < 3; ++c)
            memcpy(verts + 9 * (size_t)t + 3 * (size_t)c, s->positions + 3 * (size_t)s->tris[t].v[c], 3 * sizeof(float));

    lm_result r = glprog_build(gl, "ID pass", draw_names, "", &ip->prog_draw, err);
    if (r == LM_OK) r = glprog_build(gl, "ID pass", count_names, "", &ip->prog_count, err);
    if (r != LM_OK) {
        free(verts);
        rend_id_destroy(ip);
        return r;
    }
    ip->loc_viewproj = gl->GetUniformLocation(ip->prog_draw, "u_viewproj");

    gl->CreateBuffers(1, &ip->vbo);
    gl->NamedBufferStorage(ip->vbo, (GLsizeiptr)(9 * (size_t)s->tri_count * sizeof *verts), verts, 0);
    free(verts);
    gl->CreateVertexArrays(1, &ip->vao);
    gl->VertexArrayVertexBuffer(ip->vao, 0, ip->vbo, 0, 3 * sizeof(float));
    gl->EnableVertexArrayAttrib(ip->vao, 0);
    gl->VertexArrayAttribFormat(ip->vao, 0, 3, GL_FLOAT, GL_FALSE, 0);
    gl->VertexArrayAttribBinding(ip->vao, 0, 0);

    gl->CreateBuffers(1, &ip->count_buf);
    gl->NamedBufferStorage(ip->count_buf, (GLsizeiptr)((s->tri_count ? s->tri_count : 1) * sizeof(uint32_t)), NULL,
                           GL_DYNAMIC_STORAGE_BIT | GL_MAP_READ_BIT);

    gl->CreateTextures(GL_TEXTURE_2D, 1, &ip->id_tex);
    gl->TextureStorage2D(ip->id_tex, 1, GL_R32UI, desc->width, desc->height);
    gl->CreateRenderbuffers(1, &ip->depth_rb);
    gl->NamedRenderbufferStorage(ip->depth_rb, GL_DEPTH_COMPONENT32F, desc->width, desc->height);
    gl->CreateFramebuffers(1, &ip->fbo);
    gl->NamedFramebufferTexture(ip->fbo, GL_COLOR_ATTACHMENT0, ip->id_tex, 0);
    gl->NamedFramebufferRenderbuffer(ip->fbo, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, ip->depth_rb);
    if (gl->CheckNamedFramebufferStatus(ip->fbo, GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE) {
        rend_id_destroy(ip);
        return lm_fail(err, LM_ERR_RUNTIME, "ID pass: the %dx%d R32UI framebuffer is not complete on this GL",
                       desc->width, desc->height);
    }
    *out = ip;
    return LM_OK;
}

/* Draws the ids with reversed Z and puts the GL state it changed back. */
static void draw_ids(rend_id *ip, const scene_camera *cam)
{
    const GladGLContext *gl = ip->gl;
    const scene *s = ip->desc.scene;
    float vp[16];
    camera_viewproj(cam, ip->desc.width, ip->desc.height, camera_near(s), vp);
    GLint viewport[4];
    gl->GetIntegerv(GL_VIEWPORT, viewport);
    gl->BindFramebuffer(GL_FRAMEBUFFER, ip->fbo);
    gl->Viewport(0, 0, ip->desc.width, ip->desc.height);
    gl->ClipControl(GL_LOWER_LEFT, GL_ZERO_TO_ONE);
    gl->Enable(GL_DEPTH_TEST);
    gl->DepthFunc(GL_GREATER);
    const GLuint zero[4] = {0, 0, 0, 0};
    const GLfloat far_depth = 0.0f;
    gl->ClearNamedFramebufferuiv(ip->fbo, GL_COLOR, 0, zero);
    gl->ClearNamedFramebufferfv(ip->fbo, GL_DEPTH, 0, &far_depth);
    gl->UseProgram(ip->prog_draw);
    gl->UniformMatrix4fv(ip->loc_viewproj, 1, GL_FALSE, vp);
    gl->BindVertexArray(ip->vao);
    gl->DrawArrays(GL_TRIANGLES, 0, (GLsizei)(3 * s->tri_count));
    gl->BindVertexArray(0);
    gl->UseProgram(0);
    gl->DepthFunc(GL_LESS);
    gl->Disable(GL_DEPTH_TEST);
    gl->ClipControl(GL_LOWER_LEFT, GL_NEGATIVE_ONE_TO_ONE);
    gl->BindFramebuffer(GL_FRAMEBUFFER, 0);
    gl->Viewport(viewport[0], viewport[1], viewport[2], viewport[3]);
}

lm_result rend_id_render(rend_id *ip, const scene_camera *cam, rend_id_result *out, lm_error *err)
{
    if (!ip || !cam || !out) return lm_fail(err, LM_ERR_INVALID_ARG, "ID pass: missing arguments");
    const GladGLContext *gl = ip->gl;
    const scene *s = ip->desc.scene;
    double t0 = lm_now_seconds();
    draw_ids(ip, cam);
    uint32_t ntri = s->tri_count;
    if (ip->desc.count == REND_ID_COUNT_GPU) {
        const GLuint zero = 0;
        gl->ClearNamedBufferData(ip->count_buf, GL_R32UI, GL_RED_INTEGER, GL_UNSIGNED_INT, &zero);
        gl->UseProgram(ip->prog_count);
        gl->BindImageTexture(0, ip->id_tex, 0, GL_FALSE, 0, GL_READ_ONLY, GL_R32UI);
        gl->BindBufferBase(GL_SHADER_STORAGE_BUFFER, 1, ip->count_buf);
        gl->DispatchCompute((GLuint)(ip->desc.width + 15) / 16, (GLuint)(ip->desc.height + 15) / 16, 1);
        gl->MemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT);
        gl->GetNamedBufferSubData(ip->count_buf, 0, (GLsizeiptr)(ntri * sizeof *ip->pixels), ip->pixels);
        gl->BindBufferBase(GL_SHADER_STORAGE_BUFFER, 1, 0);
        gl->BindImageTexture(0, 0, 0, GL_FALSE, 0, GL_READ_ONLY, GL_R32UI);
        gl->UseProgram(0);
    } else {
        size_t n = (size_t)ip->desc.width * (size_t)ip->desc.height;
        gl->GetTextureImage(ip->id_tex, 0, GL_RED_INTEGER, GL_UNSIGNED_INT, (GLsizei)(n * sizeof *ip->image),
                            ip->image);
        memset(ip->pixels, 0, ntri * sizeof *ip->pixels);
        for (size_t i = 0; i < n; ++i)
            if (ip->image[i] && ip->image[i] <= ntri) ip->pixels[ip->image[i] - 1]++;
    }
    out->visible_count = 0;
    out->covered = 0;
    for (uint32_t t = 0; t < ntri; ++t)
        if (ip->pixels[t]) {
            ip->visible[out->visible_count++] = t;
            out->covered += ip->pixels[t];
        }
    out->pixels = ip->pixels;
    out->visible = ip->visible;
    out->seconds = lm_now_seconds() - t0;
    if (gl->GetError() != GL_NO_ERROR) return lm_fail(err, LM_ERR_RUNTIME, "ID pass: a GL error occurred");
    return LM_OK;
}

lm_result rend_id_read_image(rend_id *ip, uint32_t *ids, lm_error *err)
{
    if (!ip || !ids) return lm_fail(err, LM_ERR_INVALID_ARG, "ID pass: missing arguments");
    const GladGLContext *gl = ip->gl;
    int w = ip->desc.width, h = ip->desc.height;
    size_t n = (size_t)w * (size_t)h;
    gl->GetTextureImage(ip->id_tex, 0, GL_RED_INTEGER, GL_UNSIGNED_INT, (GLsizei)(n * sizeof *ip->image), ip->image);
    for (int row = 0; row < h; ++row) /* GL's rows run from the bottom */
        memcpy(ids + (size_t)row * (size_t)w, ip->image + (size_t)(h - 1 - row) * (size_t)w, (size_t)w * sizeof *ids);
    return gl->GetError() == GL_NO_ERROR ? LM_OK : lm_fail(err, LM_ERR_RUNTIME, "ID pass: a GL error occurred");
}
