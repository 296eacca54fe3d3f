/* view_tonemap.c — the viewer's tone-mapping pass (view_tonemap.h). The shader
 * ports tm_to_display (tonemap.c); the scale 2^exposure is computed here in
 * double like tonemap.c does and handed over as one float. */
#include "src/view/view_tonemap.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "src/gpu/gl_program.h"

struct view_tm {
    const GladGLContext *gl;
    GLuint program, vao;
    GLint u_scale, u_texel_scale;
    /* The screenshot's 8-bit target, made on first use and kept while the size stays. */
    GLuint read_fbo, read_tex;
    int read_w, read_h;
    uint8_t *rgba;          /* read-back buffer, read_w·read_h·4 */
    /* view_tm_show_rgb8's texture and its framebuffer (a blit source), kept while the size stays. */
    GLuint show_fbo, show_tex;
    int show_w, show_h;
};

lm_result view_tm_create(const GladGLContext *gl, view_tm **out, lm_error *err)
{
    *out = NULL;
    view_tm *t = calloc(1, sizeof *t);
    if (!t) return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory for the viewer's tone mapping");
    t->gl = gl;
    static const char *const names[] = {"rend_composite.vert", "view_tonemap.frag", NULL};
    lm_result r = glprog_build(gl, "viewer", names, "", &t->program, err);
    if (r != LM_OK) {
        free(t);
        return r;
    }
    t->u_scale = gl->GetUniformLocation(t->program, "u_scale");
    t->u_texel_scale = gl->GetUniformLocation(t->program, "u_texel_scale");
    gl->CreateVertexArrays(1, &t->vao); /* core profile: a draw needs one, even with no attributes */
    if (gl->GetError() != GL_NO_ERROR) {
        view_tm_destroy(t);
        return lm_fail(err, LM_ERR_RUNTIME, "viewer: a GL error occurred creating the tone-mapping pass");
    }
    *out = t;
    return LM_OK;
}

void view_tm_destroy(view_tm *t)
{
    if (!t) return;
    const GladGLContext *gl = t->gl;
    gl->DeleteProgram(t->program);
    gl->DeleteVertexArrays(1, &t->vao);
    gl->DeleteFramebuffers(1, &t->read_fbo);
    gl->DeleteTextures(1, &t->read_tex);
    gl->DeleteFramebuffers(1, &t->show_fbo);
    gl->DeleteTextures(1, &t->show_tex);
    free(t->rgba);
    free(t);
}

static float exposure_scale(const tm_desc *tm)
{
    /* As tonemap.c: a missing descriptor or a non-finite exposure means no scaling. */
    if (!tm || !isfinite(tm->exposure)) return 1.0f;
    return (float)exp2((double)tm->exposure);
}

lm_result view_tm_draw(view_tm *t, const view_tm_target *target, GLuint texture, const tm_desc *tm, lm_error *err)
{
    const GladGLContext *gl = t->gl;
    if (target->width <= 0 || target->height <= 0)
        return lm_fail(err, LM_ERR_INVALID_ARG, "viewer: cannot draw into a %dx%d target", target->width,
                       target->height);
    GLint viewport[4], draw_fbo;
    gl->GetIntegerv(GL_VIEWPORT, viewport);
    gl->GetIntegerv(GL_DRAW_FRAMEBUFFER_BINDING, &draw_fbo);
    GLint tw = 0, th = 0;
    gl->GetTextureLevelParameteriv(texture, 0, GL_TEXTURE_WIDTH, &tw);
    gl->GetTextureLevelParameteriv(texture, 0, GL_TEXTURE_HEIGHT, &th);

    gl->BindFramebuffer(GL_DRAW_FRAMEBUFFER, target->framebuffer);
    gl->Viewport(0, 0, target->width, target->height);
    gl->UseProgram(t->program);
    gl->Uniform1f(t->u_scale, exposure_scale(tm));
    gl->Uniform2f(t->u_texel_scale, (float)tw / (float)target->width, (float)th / (float)target->height);
    gl->BindTextureUnit(0, texture);
    gl->BindVertexArray(t->vao);
    gl->DrawArrays(GL_TRIANGLES, 0, 3);
    gl->BindVertexArray(0);
    gl->BindTextureUnit(0, 0);
    gl->UseProgram(0);
    gl->BindFramebuffer(GL_DRAW_FRAMEBUFFER, (GLuint)draw_fbo);
    gl->Viewport(viewport[0], viewport[1], viewport[2], viewport[3]);
    /* Cheap enough per frame (one call), and what rend_frame does after its draw. */
    if (gl->GetError() != GL_NO_ERROR) return lm_fail(err, LM_ERR_RUNTIME, "viewer: a GL error occurred tone mapping");
    return LM_OK;
}

static lm_result ensure_read_target(view_tm *t, int w, int h, lm_error *err)
{
    if (t->read_fbo && t->read_w == w && t->read_h == h) return LM_OK;
    const GladGLContext *gl = t->gl;
    gl->DeleteFramebuffers(1, &t->read_fbo);
    gl->DeleteTextures(1, &t->read_tex);
    t->read_fbo = t->read_tex = 0;
    free(t->rgba);
    t->rgba = malloc((size_t)w * (size_t)h * 4);
    if (!t->rgba) return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory for a %dx%d screenshot", w, h);
    gl->CreateTextures(GL_TEXTURE_2D, 1, &t->read_tex);
    gl->TextureStorage2D(t->read_tex, 1, GL_RGBA8, w, h);
    gl->CreateFramebuffers(1, &t->read_fbo);
    gl->NamedFramebufferTexture(t->read_fbo, GL_COLOR_ATTACHMENT0, t->read_tex, 0);
    if (gl->CheckNamedFramebufferStatus(t->read_fbo, GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE ||
        gl->GetError() != GL_NO_ERROR)
        return lm_fail(err, LM_ERR_RUNTIME, "viewer: cannot make a %dx%d 8-bit framebuffer", w, h);
    t->read_w = w;
    t->read_h = h;
    return LM_OK;
}

lm_result view_tm_read(view_tm *t, GLuint texture, int width, int height, const tm_desc *tm, uint8_t *rgb,
                       lm_error *err)
{
    if (width <= 0 || height <= 0)
        return lm_fail(err, LM_ERR_INVALID_ARG, "viewer: cannot read a %dx%d image", width, height);
    lm_result r = ensure_read_target(t, width, height, err);
    if (r == LM_OK)
        r = view_tm_draw(t, &(view_tm_target){.framebuffer = t->read_fbo, .width = width, .height = height}, texture,
                         tm, err);
    if (r != LM_OK) return r;
    const GladGLContext *gl = t->gl;
    gl->PixelStorei(GL_PACK_ALIGNMENT, 1);
    gl->GetTextureImage(t->read_tex, 0, GL_RGBA, GL_UNSIGNED_BYTE, (GLsizei)((size_t)width * (size_t)height * 4),
                        t->rgba);
    gl->PixelStorei(GL_PACK_ALIGNMENT, 4);
    if (gl->GetError() != GL_NO_ERROR) return lm_fail(err, LM_ERR_RUNTIME, "viewer: a GL error occurred reading");
    /* GL rows run from the bottom; images are written top row first. */
    for (int y = 0; y < height; ++y) {
        const uint8_t *src = t->rgba + (size_t)(height - 1 - y) * (size_t)width * 4;
        uint8_t *dst = rgb + (size_t)y * (size_t)width * 3;
        for (int x = 0; x < width; ++x) memcpy(dst + 3 * x, src + 4 * x, 3);
    }
    return LM_OK;
}

lm_result view_tm_show_rgb8(view_tm *t, const uint8_t *rgb, int width, int height, lm_error *err)
{
    if (width <= 0 || height <= 0 || !rgb)
        return lm_fail(err, LM_ERR_INVALID_ARG, "viewer: cannot show a %dx%d image", width, height);
    const GladGLContext *gl = t->gl;
    if (!t->show_fbo || t->show_w != width || t->show_h != height) {
        gl->DeleteFramebuffers(1, &t->show_fbo);
        gl->DeleteTextures(1, &t->show_tex);
        gl->CreateTextures(GL_TEXTURE_2D, 1, &t->show_tex);
        gl->TextureStorage2D(t->show_tex, 1, GL_RGBA8, width, height);
        gl->CreateFramebuffers(1, &t->show_fbo);
        gl->NamedFramebufferTexture(t->show_fbo, GL_COLOR_ATTACHMENT0, t->show_tex, 0);
        if (gl->CheckNamedFramebufferStatus(t->show_fbo, GL_READ_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
            return lm_fail(err, LM_ERR_RUNTIME, "viewer: cannot make a %dx%d overlay framebuffer", width, height);
        t->show_w = width;
        t->show_h = height;
    }
    gl->PixelStorei(GL_UNPACK_ALIGNMENT, 1);
    gl->TextureSubImage2D(t->show_tex, 0, 0, 0, width, height, GL_RGB, GL_UNSIGNED_BYTE, rgb);
    gl->PixelStorei(GL_UNPACK_ALIGNMENT, 4);
    /* Rows arrive top first, GL's run from the bottom: the blit turns it over. */
    gl->BlitNamedFramebuffer(t->show_fbo, 0, 0, 0, width, height, 0, height, width, 0, GL_COLOR_BUFFER_BIT, GL_NEAREST);
    if (gl->GetError() != GL_NO_ERROR) return lm_fail(err, LM_ERR_RUNTIME, "viewer: a GL error occurred showing an overlay");
    return LM_OK;
}
