/* view_hud.c — the viewer's text overlay (view_hud.h). stb_easy_font turns text
 * into quads (4 vertices of x, y, z and an RGBA colour, 16 bytes); core GL has no
 * quads, so each becomes two triangles of pixel positions here. */
#include "src/view/view_hud.h"

#include <stdlib.h>
#include <string.h>

#include "src/gpu/gl_program.h"


#include <stb_easy_font.h>

enum {
    HUD_TEXT_MAX = 4096,   /* characters drawn at most */
    HUD_PAD = 4,           /* panel margin around the text, font units */
};

struct view_hud {
    const GladGLContext *gl;
    GLuint program, vao, vbo;
    GLint u_viewport, u_color;
    char *text;            /* a writable copy (stb_easy_font_print takes char *) */
    float *quads;          /* stb_easy_font's output */
    float *tris;           /* 6 vertices × 2 floats per quad, + the panel */
    size_t quad_cap;
};

lm_result view_hud_create(const GladGLContext *gl, view_hud **out, lm_error *err)
{
    *out = NULL;
    view_hud *h = calloc(1, sizeof *h);
    if (!h) return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory for the viewer's HUD");
    h->gl = gl;
    /* A character is at most a few dozen strokes; 70 quads each is stb's own bound. */
    h->quad_cap = 70 * (size_t)HUD_TEXT_MAX;
    h->text = malloc(HUD_TEXT_MAX + 1);
    h->quads = malloc(h->quad_cap * 4 * 16);
    h->tris = malloc((h->quad_cap + 1) * 12 * sizeof *h->tris);
    if (!h->text || !h->quads || !h->tris) {
        view_hud_destroy(h);
        return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory for the viewer's HUD");
    }
    static const char *const names[] = {"view_hud.vert", "view_hud.frag", NULL};
    lm_result r = glprog_build(gl, "viewer HUD", names, "", &h->program, err);
    if (r != LM_OK) {
        view_hud_destroy(h);
        return r;
    }
    h->u_viewport = gl->GetUniformLocation(h->program, "u_viewport");
    h->u_color = gl->GetUniformLocation(h->program, "u_color");
    gl->CreateBuffers(1, &h->vbo);
    gl->CreateVertexArrays(1, &h->vao);
    gl->VertexArrayVertexBuffer(h->vao, 0, h->vbo, 0, 2 * sizeof(float));
    gl->EnableVertexArrayAttrib(h->vao, 0);
    gl->VertexArrayAttribFormat(h->vao, 0, 2, GL_FLOAT, GL_FALSE, 0);
    gl->VertexArrayAttribBinding(h->vao, 0, 0);
    if (gl->GetError() != GL_NO_ERROR) {
        view_hud_destroy(h);
        return lm_fail(err, LM_ERR_RUNTIME, "viewer: a GL error occurred creating the HUD");
    }
    *out = h;
    return LM_OK;
}

void view_hud_destroy(view_hud *h)
{
    if (!h) return;
    const GladGLContext *gl = h->gl;
    if (h->program) gl->DeleteProgram(h->program);
    if (h->vao) gl->DeleteVertexArrays(1, &h->vao);
    if (h->vbo) gl->DeleteBuffers(1, &h->vbo);
    free(h->text);
    free(h->quads);
    free(h->tris);
    free(h);
}

/* The two triangles of the axis-aligned rectangle (x0, y0)–(x1, y1). */
static void rect(float *o, float x0, float y0, float x1, float y1)
{
    const float v[12] = {x0, y0, x1, y0, x1, y1, x0, y0, x1, y1, x0, y1};
    memcpy(o, v, sizeof v);
}

lm_result view_hud_draw(view_hud *h, const view_hud_text *t, int width, int height, lm_error *err)
{
    if (!t || !t->text || !t->text[0] || width <= 0 || height <= 0) return LM_OK;
    const GladGLContext *gl = h->gl;
    float scale = t->scale > 0 ? t->scale : 2.0f;
    /* ASCII 32..126 and newlines only (stb_easy_font's range). */
    size_t n = 0;
    for (const char *p = t->text; *p && n < HUD_TEXT_MAX; ++p, ++n) {
        unsigned char ch = (unsigned char)*p;
        h->text[n] = ch == '\n' || (ch >= 32 && ch < 127) ? (char)ch : '?';
    }
    h->text[n] = '\0';
    int nq = stb_easy_font_print(0, 0, h->text, NULL, h->quads, (int)(h->quad_cap * 4 * 16));
    float tw = (float)stb_easy_font_width(h->text), th = (float)stb_easy_font_height(h->text);
    float ox = (float)t->x + HUD_PAD * scale, oy = (float)t->y + HUD_PAD * scale;
    rect(h->tris, (float)t->x, (float)t->y, ox + (tw + HUD_PAD) * scale, oy + (th + HUD_PAD - 2) * scale);
    for (int q = 0; q < nq; ++q) {
        const float *v = h->quads + (size_t)q * 16; /* 4 vertices of 4 words: x, y, z, colour */
        rect(h->tris + 12 * (size_t)(q + 1), ox + v[0] * scale, oy + v[1] * scale, ox + v[8] * scale, oy + v[9] * scale);
    }
    gl->NamedBufferData(h->vbo, (GLsizeiptr)((size_t)(nq + 1) * 12 * sizeof(float)), h->tris, GL_STREAM_DRAW);
    GLint viewport[4], draw_fbo;
    gl->GetIntegerv(GL_VIEWPORT, viewport);
    gl->GetIntegerv(GL_DRAW_FRAMEBUFFER_BINDING, &draw_fbo);
    gl->BindFramebuffer(GL_DRAW_FRAMEBUFFER, 0);
    gl->Viewport(0, 0, width, height);
    gl->Enable(GL_BLEND);
    gl->BlendFunc(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA);
    gl->UseProgram(h->program);
    gl->Uniform2f(h->u_viewport, (float)width, (float)height);
    gl->BindVertexArray(h->vao);
    gl->Uniform4f(h->u_color, 0.0f, 0.0f, 0.0f, 0.55f);
    gl->DrawArrays(GL_TRIANGLES, 0, 6);
    gl->Uniform4f(h->u_color, 1.0f, 1.0f, 0.9f, 1.0f);
    if (nq > 0) gl->DrawArrays(GL_TRIANGLES, 6, 6 * nq);
    gl->BindVertexArray(0);
    gl->UseProgram(0);
    gl->Disable(GL_BLEND);
    gl->BindFramebuffer(GL_DRAW_FRAMEBUFFER, (GLuint)draw_fbo);
    gl->Viewport(viewport[0], viewport[1], viewport[2], viewport[3]);
    if (gl->GetError() != GL_NO_ERROR) return lm_fail(err, LM_ERR_RUNTIME, "viewer: a GL error occurred drawing the HUD");
    return LM_OK;
}

lm_result view_hud_read_window(view_hud *h, int width, int height, uint8_t *rgb, lm_error *err)
{
    if (width <= 0 || height <= 0) return lm_fail(err, LM_ERR_INVALID_ARG, "viewer: cannot read a %dx%d window", width, height);
    const GladGLContext *gl = h->gl;
    size_t row = (size_t)width * 3;
    uint8_t *tmp = malloc(row * (size_t)height);
    if (!tmp) return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory reading a %dx%d window", width, height);
    GLint read_fbo;
    gl->GetIntegerv(GL_READ_FRAMEBUFFER_BINDING, &read_fbo);
    gl->BindFramebuffer(GL_READ_FRAMEBUFFER, 0);
    gl->ReadBuffer(GL_BACK);
    gl->PixelStorei(GL_PACK_ALIGNMENT, 1);
    gl->ReadnPixels(0, 0, width, height, GL_RGB, GL_UNSIGNED_BYTE, (GLsizei)(row * (size_t)height), tmp);
    gl->PixelStorei(GL_PACK_ALIGNMENT, 4);
    gl->BindFramebuffer(GL_READ_FRAMEBUFFER, (GLuint)read_fbo);
    for (int y = 0; y < height; ++y) memcpy(rgb + (size_t)y * row, tmp + (size_t)(height - 1 - y) * row, row);
    free(tmp);
    if (gl->GetError() != GL_NO_ERROR) return lm_fail(err, LM_ERR_RUNTIME, "viewer: a GL error occurred reading the window");
    return LM_OK;
}
