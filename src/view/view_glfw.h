/* view_glfw.h — the viewer's window: GLFW, an OpenGL 4.5 core context with its
 * glad MX function table loaded from glfwGetProcAddress, and the input gathered
 * between two polls (drag, wheel, keys as view_action). The only file that
 * includes GLFW: the platform stays in one file, so the rest of the viewer
 * (and its tests) never sees a window system.
 *
 * Usage:
 *     view_window *win;
 *     if (view_window_create(&(view_window_desc){.title = "lumesh", .width = 1280, .height = 720}, &win, &err)) ...
 *     const GladGLContext *gl = view_window_gl(win);      // current on this thread
 *     view_input in;
 *     while (view_window_poll(win, &in), !in.close) { ...draw...; view_window_swap(win); }
 *     view_window_destroy(win);
 *
 * Threads: the main thread only (GLFW's rule), one window per process.
 * Does NOT do: several windows, full screen, high-DPI scaling of input (cursor
 * motion is in screen coordinates, which is what the orbit speed wants).
 */
#ifndef LUMESH_VIEW_GLFW_H
#define LUMESH_VIEW_GLFW_H

#include <glad/gl.h>

#include "src/base/util.h"
#include "src/view/view_script.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct view_window_desc {
    const char *title;   /* NULL: "lumesh" */
    int width, height;   /* screen coordinates; 0: 1280 × 720 */
} view_window_desc;

/* What happened since the last poll. */
typedef struct view_input {
    double drag_dx, drag_dy;           /* cursor motion with the left button held (screen units, y down) */
    double pan_dx, pan_dy;             /* ... with the middle button, or the left one and shift */
    double look_dx, look_dy;           /* ... with the right button */
    int dragging;                      /* a mouse button held now */
    float fly[3];                      /* keys held now: forward W − S, right D − A, up (Space, Page Up) −
                                          (Ctrl, Page Down); each −1, 0 or 1 */
    double screen_height;              /* the window's height in screen units (cursor motion's) */
    double wheel;                      /* vertical scroll steps (positive: away from the user) */
    int actions[VIEW_ACTION_COUNT];    /* key presses per action (repeats count) */
    int close;                         /* the window's close button */
} view_input;

typedef struct view_window view_window;

lm_result view_window_create(const view_window_desc *desc, view_window **out, lm_error *err);
void view_window_destroy(view_window *win); /* NULL is a no-op; ends GLFW */

const GladGLContext *view_window_gl(const view_window *win);
/* GL_RENDERER / GL_VERSION, for the report. */
const char *view_window_renderer(const view_window *win);

/* Processes pending events (never waits) and returns what they were. */
void view_window_poll(view_window *win, view_input *out);
/* Framebuffer pixels; 0 × 0 while minimised. */
void view_window_framebuffer_size(view_window *win, int *width, int *height);
void view_window_swap(view_window *win);
void view_window_set_title(view_window *win, const char *title);
/* Asks for a new size (screen coordinates) or for the window to be minimised (0 × 0)
 * or restored, as a user would; the framebuffer follows at the window system's pace. */
void view_window_resize(view_window *win, int width, int height);
void view_window_minimise(view_window *win, int minimised);

#ifdef __cplusplus
}
#endif
#endif
