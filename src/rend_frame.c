/* rend_frame.c — material, radiance and composite passes (rend_frame.h). */
#include "rend_frame.h"

#include <stddef.h>
#include <stdlib.h>
#include <string.h>

#include "gl_program.h"
#include "rend_camera.h"

enum { TERMS = 3 }; /* direct, indirect, specular */

struct rend_frame {
    rend_frame_desc desc;
    const GladGLContext *gl;
    GLuint prog_material, prog_value, prog_composite;
    GLint loc_mat_vp, loc_val_vp;
    GLuint scene_vbo, scene_vao;       /* 3 vertices per scene triangle: pos, kd, ks, le */
    GLuint value_vbo, value_vao;       /* a snapshot mesh: pos, value */
    size_t value_cap;                  /* bytes allocated in value_vbo */
    GLuint mat_fbo, mat_tex[3], mat_depth;          /* kd, ks, le */
    GLuint val_fbo, val_tex[TERMS], val_depth;      /* L_dd, E_i, L_ds */
    GLuint out_fbo, out_tex;
    GLuint empty_vao;
    float *readback;                   /* width·height·4 */
    rend_frame_times times;
};

static const char *const material_names[] = {"rend_material.vert", "rend_material.frag", NULL};
static const char *const value_names[] = {"rend_value.vert", "rend_value.frag", NULL};
static const char *const composite_names[] = {"rend_composite.vert", "rend_composite.frag", NULL};

void rend_frame_destroy(rend_frame *f)
{
    if (!f) return;
    const GladGLContext *gl = f->gl;
    if (gl) {
        GLuint progs[3] = {f->prog_material, f->prog_value, f->prog_composite};
        for (int i = 0; i < 3; ++i)
            if (progs[i]) gl->DeleteProgram(progs[i]);
        GLuint bufs[2] = {f->scene_vbo, f->value_vbo};
        gl->DeleteBuffers(2, bufs);
        GLuint vaos[3] = {f->scene_vao, f->value_vao, f->empty_vao};
        gl->DeleteVertexArrays(3, vaos);
        gl->DeleteTextures(3, f->mat_tex);
        gl->DeleteTextures(TERMS, f->val_tex);
        gl->DeleteTextures(1, &f->out_tex);
        GLuint rbs[2] = {f->mat_depth, f->val_depth};
        gl->DeleteRenderbuffers(2, rbs);
        GLuint fbos[3] = {f->mat_fbo, f->val_fbo, f->out_fbo};
        gl->DeleteFramebuffers(3, fbos);
    }
    free(f->readback);
    free(f);
}

static GLuint float_target(const GladGLContext *gl, int w, int h)
{
    GLuint t;
    gl->CreateTextures(GL_TEXTURE_2D, 1, &t);
    gl->TextureStorage2D(t, 1, GL_RGBA32F, w, h);
    return t;
}

static GLuint depth_target(const GladGLContext *gl, int w, int h)
{
    GLuint rb;
    gl->CreateRenderbuffers(1, &rb);
    gl->NamedRenderbufferStorage(rb, GL_DEPTH_COMPONENT32F, w, h);
    return rb;
}

lm_result rend_frame_create(const GladGLContext *gl, const rend_frame_desc *desc, rend_frame **out, lm_error *err)
{
    *out = NULL;
    if (!gl || !desc || !desc->scene || desc->width < 1 || desc->height < 1 || desc->width > 16384 ||
        desc->height > 16384)
        return lm_fail(err, LM_ERR_INVALID_ARG, "renderer: needs a scene and a size from 1x1 to 16384x16384");
    const scene *s = desc->scene;
    rend_frame *f = calloc(1, sizeof *f);
    if (!f) return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory creating the renderer");
    f->desc = *desc;
    f->gl = gl;
    int w = desc->width, h = desc->height;
    f->readback = malloc((size_t)w * (size_t)h * 4 * sizeof *f->readback);
    float *verts = malloc(3 * 12 * (size_t)(s->tri_count ? s->tri_count : 1) * sizeof *verts);
    lm_result r = f->readback && verts ? LM_OK : lm_fail(err, LM_ERR_NO_MEMORY, "out of memory creating the renderer");
    if (r == LM_OK) r = glprog_build(gl, "renderer", material_names, "", &f->prog_material, err);
    if (r == LM_OK) r = glprog_build(gl, "renderer", value_names, "", &f->prog_value, err);
    if (r == LM_OK) r = glprog_build(gl, "renderer", composite_names, "", &f->prog_composite, err);
    if (r != LM_OK) {
        free(verts);
        rend_frame_destroy(f);
        return r;
    }
    f->loc_mat_vp = gl->GetUniformLocation(f->prog_material, "u_viewproj");
    f->loc_val_vp = gl->GetUniformLocation(f->prog_value, "u_viewproj");

    /* Scene triangles with their material, unwelded. */
    for (uint32_t t = 0; t < s->tri_count; ++t) {
        const scene_material *m = &s->materials[s->tris[t].material];
        for (int c = 0; c < 3; ++c) {
            float *v = verts + 12 * (3 * (size_t)t + (size_t)c);
            memcpy(v, s->positions + 3 * (size_t)s->tris[t].v[c], 3 * sizeof(float));
            memcpy(v + 3, m->kd, 3 * sizeof(float));
            memcpy(v + 6, m->ks, 3 * sizeof(float));
            memcpy(v + 9, m->le, 3 * sizeof(float));
        }
    }
    gl->CreateBuffers(1, &f->scene_vbo);
    gl->NamedBufferStorage(f->scene_vbo, (GLsizeiptr)(3 * 12 * (size_t)s->tri_count * sizeof *verts), verts, 0);
    free(verts);
    gl->CreateVertexArrays(1, &f->scene_vao);
    gl->VertexArrayVertexBuffer(f->scene_vao, 0, f->scene_vbo, 0, 12 * sizeof(float));
    for (GLuint a = 0; a < 4; ++a) {
        gl->EnableVertexArrayAttrib(f->scene_vao, a);
        gl->VertexArrayAttribFormat(f->scene_vao, a, 3, GL_FLOAT, GL_FALSE, 3 * a * (GLuint)sizeof(float));
        gl->VertexArrayAttribBinding(f->scene_vao, a, 0);
    }
    gl->CreateBuffers(1, &f->value_vbo);
    gl->CreateVertexArrays(1, &f->value_vao);
    gl->CreateVertexArrays(1, &f->empty_vao);

    gl->CreateFramebuffers(1, &f->mat_fbo);
    f->mat_depth = depth_target(gl, w, h);
    for (int i = 0; i < 3; ++i) {
        f->mat_tex[i] = float_target(gl, w, h);
        gl->NamedFramebufferTexture(f->mat_fbo, GL_COLOR_ATTACHMENT0 + (GLenum)i, f->mat_tex[i], 0);
    }
    gl->NamedFramebufferRenderbuffer(f->mat_fbo, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, f->mat_depth);
    const GLenum three[3] = {GL_COLOR_ATTACHMENT0, GL_COLOR_ATTACHMENT1, GL_COLOR_ATTACHMENT2};
    gl->NamedFramebufferDrawBuffers(f->mat_fbo, 3, three);

    gl->CreateFramebuffers(1, &f->val_fbo);
    f->val_depth = depth_target(gl, w, h);
    for (int i = 0; i < TERMS; ++i) f->val_tex[i] = float_target(gl, w, h);
    gl->NamedFramebufferRenderbuffer(f->val_fbo, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, f->val_depth);

    gl->CreateFramebuffers(1, &f->out_fbo);
    f->out_tex = float_target(gl, w, h);
    gl->NamedFramebufferTexture(f->out_fbo, GL_COLOR_ATTACHMENT0, f->out_tex, 0);

    gl->NamedFramebufferTexture(f->val_fbo, GL_COLOR_ATTACHMENT0, f->val_tex[0], 0);
    GLuint fbos[3] = {f->mat_fbo, f->val_fbo, f->out_fbo};
    for (int i = 0; i < 3; ++i)
        if (gl->CheckNamedFramebufferStatus(fbos[i], GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE) {
            rend_frame_destroy(f);
            return lm_fail(err, LM_ERR_RUNTIME, "renderer: a %dx%d float framebuffer is not complete on this GL", w, h);
        }
    *out = f;
    return LM_OK;
}

/* Draws one snapshot mesh into value texture `term` with its own depth. */
static lm_result draw_values(rend_frame *f, const cache_snapshot_mesh *m, int term, lm_error *err)
{
    const GladGLContext *gl = f->gl;
    gl->NamedFramebufferTexture(f->val_fbo, GL_COLOR_ATTACHMENT0, f->val_tex[term], 0);
    const GLfloat zero[4] = {0, 0, 0, 0}, far_depth = 0.0f;
    gl->ClearNamedFramebufferfv(f->val_fbo, GL_COLOR, 0, zero);
    gl->ClearNamedFramebufferfv(f->val_fbo, GL_DEPTH, 0, &far_depth);
    if (!m || m->triangle_count == 0) return LM_OK;
    size_t bytes = 3 * (size_t)m->triangle_count * sizeof *m->vertices;
    if (bytes > f->value_cap) {
        /* Immutable storage cannot grow: a new buffer, bound to the VAO again. */
        gl->DeleteBuffers(1, &f->value_vbo);
        gl->CreateBuffers(1, &f->value_vbo);
        size_t cap = bytes + bytes / 2;
        gl->NamedBufferStorage(f->value_vbo, (GLsizeiptr)cap, NULL, GL_DYNAMIC_STORAGE_BIT);
        f->value_cap = cap;
        gl->VertexArrayVertexBuffer(f->value_vao, 0, f->value_vbo, 0, sizeof(cache_snapshot_vertex));
        for (GLuint a = 0; a < 2; ++a) {
            gl->EnableVertexArrayAttrib(f->value_vao, a);
            gl->VertexArrayAttribFormat(f->value_vao, a, 3, GL_FLOAT, GL_FALSE,
                                        a ? (GLuint)offsetof(cache_snapshot_vertex, value) : 0);
            gl->VertexArrayAttribBinding(f->value_vao, a, 0);
        }
    }
    gl->NamedBufferSubData(f->value_vbo, 0, (GLsizeiptr)bytes, m->vertices);
    gl->BindVertexArray(f->value_vao);
    gl->DrawArrays(GL_TRIANGLES, 0, (GLsizei)(3 * m->triangle_count));
    gl->BindVertexArray(0);
    (void)err;
    return LM_OK;
}

lm_result rend_frame_draw(rend_frame *f, const scene_camera *cam, const cache_snapshot *snap, float *rgb,
                          lm_error *err)
{
    if (!f || !cam || !rgb) return lm_fail(err, LM_ERR_INVALID_ARG, "renderer: missing arguments");
    const GladGLContext *gl = f->gl;
    const scene *s = f->desc.scene;
    int w = f->desc.width, h = f->desc.height;
    float vp[16];
    rend_camera_viewproj(cam, w, h, rend_camera_near(s), vp);
    GLint viewport[4];
    gl->GetIntegerv(GL_VIEWPORT, viewport);
    gl->Viewport(0, 0, w, h);
    gl->ClipControl(GL_LOWER_LEFT, GL_ZERO_TO_ONE); /* reversed Z (rend_camera.h) */
    gl->Enable(GL_DEPTH_TEST);
    gl->DepthFunc(GL_GREATER);

    double t0 = lm_now_seconds();
    const GLfloat zero[4] = {0, 0, 0, 0}, far_depth = 0.0f;
    gl->BindFramebuffer(GL_FRAMEBUFFER, f->mat_fbo);
    for (int i = 0; i < 3; ++i) gl->ClearNamedFramebufferfv(f->mat_fbo, GL_COLOR, i, zero);
    gl->ClearNamedFramebufferfv(f->mat_fbo, GL_DEPTH, 0, &far_depth);
    gl->UseProgram(f->prog_material);
    gl->UniformMatrix4fv(f->loc_mat_vp, 1, GL_FALSE, vp);
    gl->BindVertexArray(f->scene_vao);
    gl->DrawArrays(GL_TRIANGLES, 0, (GLsizei)(3 * s->tri_count));
    gl->Finish();
    double t1 = lm_now_seconds();

    gl->BindFramebuffer(GL_FRAMEBUFFER, f->val_fbo);
    gl->UseProgram(f->prog_value);
    gl->UniformMatrix4fv(f->loc_val_vp, 1, GL_FALSE, vp);
    const cache_snapshot_mesh *meshes[TERMS] = {snap ? &snap->direct : NULL, snap ? &snap->indirect : NULL,
                                                snap ? &snap->specular : NULL};
    lm_result r = LM_OK;
    for (int t = 0; r == LM_OK && t < TERMS; ++t) r = draw_values(f, meshes[t], t, err);
    gl->Finish();
    double t2 = lm_now_seconds();

    gl->Disable(GL_DEPTH_TEST);
    gl->DepthFunc(GL_LESS);
    gl->ClipControl(GL_LOWER_LEFT, GL_NEGATIVE_ONE_TO_ONE);
    gl->BindFramebuffer(GL_FRAMEBUFFER, f->out_fbo);
    gl->UseProgram(f->prog_composite);
    GLuint inputs[6] = {f->mat_tex[0], f->mat_tex[1], f->mat_tex[2], f->val_tex[0], f->val_tex[1], f->val_tex[2]};
    gl->BindTextures(0, 6, inputs);
    gl->BindVertexArray(f->empty_vao);
    gl->DrawArrays(GL_TRIANGLES, 0, 3);
    gl->BindVertexArray(0);
    gl->BindTextures(0, 6, NULL);
    gl->UseProgram(0);
    gl->Finish();
    double t3 = lm_now_seconds();

    gl->GetTextureImage(f->out_tex, 0, GL_RGBA, GL_FLOAT, (GLsizei)((size_t)w * (size_t)h * 4 * sizeof(float)),
                        f->readback);
    for (int row = 0; row < h; ++row) /* GL rows run from the bottom */
        for (int x = 0; x < w; ++x)
            memcpy(rgb + 3 * ((size_t)row * (size_t)w + (size_t)x),
                   f->readback + 4 * ((size_t)(h - 1 - row) * (size_t)w + (size_t)x), 3 * sizeof(float));
    gl->BindFramebuffer(GL_FRAMEBUFFER, 0);
    gl->Viewport(viewport[0], viewport[1], viewport[2], viewport[3]);
    f->times = (rend_frame_times){t1 - t0, t2 - t1, t3 - t2, lm_now_seconds() - t3};
    if (r == LM_OK && gl->GetError() != GL_NO_ERROR) r = lm_fail(err, LM_ERR_RUNTIME, "renderer: a GL error occurred");
    return r;
}

void rend_frame_get_times(const rend_frame *f, rend_frame_times *out) { *out = f->times; }
