/* view_accum.c — the viewer's resting picture (view_accum.h): GL blending with a
 * constant alpha of 1/(n+1) forms the running mean in an RGBA32F texture. */
#include "src/view/view_accum.h"

#include <stdlib.h>
#include <string.h>

#include "src/gpu/gl_program.h"

struct view_accum {
    const GladGLContext *gl;
    GLuint program, vao;
    GLuint fbo, tex; /* the mean and its framebuffer, made again when the size changes */
    int w, h;
};

lm_result view_accum_create(const GladGLContext *gl, view_accum **out, lm_error *err)
{
    *out = NULL;
    view_accum *a = calloc(1, sizeof *a);
    if (!a) return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory for the viewer's resting picture");
    a->gl = gl;
    static const char *const names[] = {"rend_composite.vert", "view_accum.frag", NULL};
    lm_result r = glprog_build(gl, "viewer accumulation", names, "", &a->program, err);
    if (r != LM_OK) {
        free(a);
        return r;
    }
    gl->CreateVertexArrays(1, &a->vao); /* core profile: a draw needs one, even with no attributes */
    if (gl->GetError() != GL_NO_ERROR) {
        view_accum_destroy(a);
        return lm_fail(err, LM_ERR_RUNTIME, "viewer: a GL error occurred creating the accumulation pass");
    }
    *out = a;
    return LM_OK;
}

void view_accum_destroy(view_accum *a)
{
    if (!a) return;
    const GladGLContext *gl = a->gl;
    gl->DeleteProgram(a->program);
    gl->DeleteVertexArrays(1, &a->vao);
    gl->DeleteFramebuffers(1, &a->fbo);
    gl->DeleteTextures(1, &a->tex);
    free(a);
}

static lm_result ensure_target(view_accum *a, int w, int h, lm_error *err)
{
    if (a->fbo && a->w == w && a->h == h) return LM_OK;
    const GladGLContext *gl = a->gl;
    gl->DeleteFramebuffers(1, &a->fbo);
    gl->DeleteTextures(1, &a->tex);
    a->fbo = a->tex = 0;
    a->w = a->h = 0;
    gl->CreateTextures(GL_TEXTURE_2D, 1, &a->tex);
    gl->TextureStorage2D(a->tex, 1, GL_RGBA32F, w, h);
    gl->CreateFramebuffers(1, &a->fbo);
    gl->NamedFramebufferTexture(a->fbo, GL_COLOR_ATTACHMENT0, a->tex, 0);
    if (gl->CheckNamedFramebufferStatus(a->fbo, GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE ||
        gl->GetError() != GL_NO_ERROR)
        return lm_fail(err, LM_ERR_RUNTIME, "viewer: cannot make a %dx%d accumulation target", w, h);
    a->w = w;
    a->h = h;
    return LM_OK;
}

lm_result view_accum_add(view_accum *a, GLuint texture, int width, int height, uint32_t n, lm_error *err)
{
    if (width <= 0 || height <= 0 || !texture)
        return lm_fail(err, LM_ERR_INVALID_ARG, "viewer: cannot accumulate a %dx%d image", width, height);
    if (a->w != width || a->h != height) n = 0; /* a new size starts again */
    lm_result r = ensure_target(a, width, height, err);
    if (r != LM_OK) return r;
    const GladGLContext *gl = a->gl;
    GLint viewport[4], draw_fbo;
    gl->GetIntegerv(GL_VIEWPORT, viewport);
    gl->GetIntegerv(GL_DRAW_FRAMEBUFFER_BINDING, &draw_fbo);
    gl->BindFramebuffer(GL_DRAW_FRAMEBUFFER, a->fbo);
    gl->Viewport(0, 0, width, height);
    if (n > 0) {
        gl->Enable(GL_BLEND);
        gl->BlendColor(0.0f, 0.0f, 0.0f, 1.0f / (float)(n + 1));
        gl->BlendFunc(GL_CONSTANT_ALPHA, GL_ONE_MINUS_CONSTANT_ALPHA);
    }
    gl->UseProgram(a->program);
    gl->BindTextureUnit(0, texture);
    gl->BindVertexArray(a->vao);
    gl->DrawArrays(GL_TRIANGLES, 0, 3);
    gl->BindVertexArray(0);
    gl->BindTextureUnit(0, 0);
    gl->UseProgram(0);
    gl->Disable(GL_BLEND);
    gl->BindFramebuffer(GL_DRAW_FRAMEBUFFER, (GLuint)draw_fbo);
    gl->Viewport(viewport[0], viewport[1], viewport[2], viewport[3]);
    if (gl->GetError() != GL_NO_ERROR) return lm_fail(err, LM_ERR_RUNTIME, "viewer: a GL error occurred accumulating");
    return LM_OK;
}

GLuint view_accum_texture(const view_accum *a) { return a ? a->tex : 0; }

lm_result view_accum_read(view_accum *a, float *rgb, lm_error *err)
{
    if (!a->tex) return lm_fail(err, LM_ERR_INVALID_ARG, "viewer: nothing accumulated to read");
    const size_t w = (size_t)a->w, h = (size_t)a->h;
    float *rgba = malloc(w * h * 4 * sizeof *rgba);
    if (!rgba) return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory reading a %dx%d picture", a->w, a->h);
    const GladGLContext *gl = a->gl;
    gl->GetTextureImage(a->tex, 0, GL_RGBA, GL_FLOAT, (GLsizei)(w * h * 4 * sizeof *rgba), rgba);
    lm_result r = gl->GetError() == GL_NO_ERROR ? LM_OK
                                                : lm_fail(err, LM_ERR_RUNTIME, "viewer: a GL error occurred reading");
    /* GL rows run from the bottom; images are written top row first. */
    for (size_t y = 0; r == LM_OK && y < h; ++y)
        for (size_t x = 0; x < w; ++x)
            memcpy(rgb + 3 * ((h - 1 - y) * w + x), rgba + 4 * (y * w + x), 3 * sizeof *rgb);
    free(rgba);
    return r;
}
