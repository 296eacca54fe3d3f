/* view_hud.h — the viewer's text overlay: lines of ASCII text over the picture,
 * stb_easy_font's strokes (libstb-dev) on a dark translucent panel, drawn with
 * the window's GL context into its default framebuffer.
 *
 * Usage (display thread, the window's context current):
 *     view_hud *hud;
 *     if (view_hud_create(gl, &hud, &err) != LM_OK) ...
 *     view_hud_draw(hud, &(view_hud_text){.text = "12 fps\nH: help", .x = 8, .y = 8, .scale = 2},
 *                   width, height, &err);
 *     view_hud_destroy(hud);
 *
 * Threads: the thread whose context is current (the display thread).
 * Does NOT do: non-ASCII text (shown as '?'), kerning, wrapping, input.
 */
#ifndef LUMESH_VIEW_HUD_H
#define LUMESH_VIEW_HUD_H

#include <glad/gl.h>
#include <stdint.h>

#include "src/base/util.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct view_hud_text {
    const char *text;   /* '\n' separates lines */
    int x, y;           /* the panel's top-left corner, window pixels from the top-left */
    float scale;        /* pixels per font unit; 0 = 2 */
} view_hud_text;

typedef struct view_hud view_hud;

lm_result view_hud_create(const GladGLContext *gl, view_hud **out, lm_error *err);
void view_hud_destroy(view_hud *h); /* NULL is a no-op */
/* Draws into the default framebuffer of width × height pixels (blending on for
 * the draw only). */
lm_result view_hud_draw(view_hud *h, const view_hud_text *t, int width, int height, lm_error *err);
/* The default framebuffer's back buffer (what the next swap shows, HUD
 * included) as 8-bit RGB, top row first: width·height·3 bytes. */
lm_result view_hud_read_window(view_hud *h, int width, int height, uint8_t *rgb, lm_error *err);

#ifdef __cplusplus
}
#endif
#endif
