/* view_glfw.c — the viewer's GLFW window and input (view_glfw.h). */
#include "src/view/view_glfw.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* GLFW must not pull in a GL header of its own: glad's is the only one. */
#define GLFW_INCLUDE_NONE
#include <GLFW/glfw3.h>

#include "src/gpu/gl_context.h"

struct view_window {
    GLFWwindow *window;
    GladGLContext gl;
    char renderer[256];
    /* Display thread only: filled by GLFW's callbacks during glfwPollEvents. */
    view_input pending;
    double last_x, last_y;
    int have_last;
};

static const char *glfw_error(void)
{
    const char *d = NULL;
    return glfwGetError(&d) != GLFW_NO_ERROR && d ? d : "no reason given";
}

static void key_cb(GLFWwindow *w, int key, int scancode, int action, int mods)
{
    (void)scancode;
    (void)mods;
    if (action == GLFW_RELEASE) return;
    view_window *win = glfwGetWindowUserPointer(w);
    view_action a = VIEW_ACTION_NONE;
    switch (key) {
    case GLFW_KEY_ESCAPE:
    case GLFW_KEY_Q: a = VIEW_ACTION_QUIT; break;
    case GLFW_KEY_P: a = action == GLFW_PRESS ? VIEW_ACTION_PAUSE : VIEW_ACTION_NONE; break; /* no auto-repeat toggling */
    case GLFW_KEY_EQUAL: /* '+' is shift + '=' on most layouts */
    case GLFW_KEY_KP_ADD: a = VIEW_ACTION_EXPOSURE_UP; break;
    case GLFW_KEY_MINUS:
    case GLFW_KEY_KP_SUBTRACT: a = VIEW_ACTION_EXPOSURE_DOWN; break;
    case GLFW_KEY_F12: a = action == GLFW_PRESS ? VIEW_ACTION_SCREENSHOT : VIEW_ACTION_NONE; break;
    case GLFW_KEY_F: a = VIEW_ACTION_FRAME_ALL; break;
    case GLFW_KEY_RIGHT_BRACKET: a = VIEW_ACTION_LIGHT_UP; break;
    case GLFW_KEY_LEFT_BRACKET: a = VIEW_ACTION_LIGHT_DOWN; break;
    default: break;
    }
    /* Toggles: presses only, no auto-repeat flicker. */
    switch (action == GLFW_PRESS ? key : GLFW_KEY_UNKNOWN) {
    case GLFW_KEY_L: a = VIEW_ACTION_LIGHT_NEXT; break;
    case GLFW_KEY_C: a = VIEW_ACTION_CAMERA_NEXT; break;
    case GLFW_KEY_1: a = VIEW_ACTION_TOGGLE_DIRECT; break;
    case GLFW_KEY_2: a = VIEW_ACTION_TOGGLE_SPECULAR; break;
    case GLFW_KEY_3: a = VIEW_ACTION_TOGGLE_INDIRECT; break;
    case GLFW_KEY_4: a = VIEW_ACTION_TOGGLE_EMISSION; break;
    case GLFW_KEY_H: a = VIEW_ACTION_HELP; break;
    case GLFW_KEY_O: a = VIEW_ACTION_OVERLAY_NEXT; break;
    case GLFW_KEY_V: a = VIEW_ACTION_OVERLAY_KIND; break;
    case GLFW_KEY_R: a = VIEW_ACTION_RELOAD; break;
    case GLFW_KEY_K: a = VIEW_ACTION_LIGHT_COLOR; break;
    case GLFW_KEY_B: a = VIEW_ACTION_BOUNCES; break;
    case GLFW_KEY_I: a = VIEW_ACTION_INDIRECT; break;
    default: break;
    }
    if (a != VIEW_ACTION_NONE) win->pending.actions[a]++;
}

static void cursor_cb(GLFWwindow *w, double x, double y)
{
    view_window *win = glfwGetWindowUserPointer(w);
    if (win->have_last) {
        double dx = x - win->last_x, dy = y - win->last_y;
        int left = glfwGetMouseButton(w, GLFW_MOUSE_BUTTON_LEFT) == GLFW_PRESS;
        int shift = glfwGetKey(w, GLFW_KEY_LEFT_SHIFT) == GLFW_PRESS || glfwGetKey(w, GLFW_KEY_RIGHT_SHIFT) == GLFW_PRESS;
        if (glfwGetMouseButton(w, GLFW_MOUSE_BUTTON_MIDDLE) == GLFW_PRESS || (left && shift)) {
            win->pending.pan_dx += dx;
            win->pending.pan_dy += dy;
        } else if (left) {
            win->pending.drag_dx += dx;
            win->pending.drag_dy += dy;
        }
        if (glfwGetMouseButton(w, GLFW_MOUSE_BUTTON_RIGHT) == GLFW_PRESS) {
            win->pending.look_dx += dx;
            win->pending.look_dy += dy;
        }
    }
    win->last_x = x;
    win->last_y = y;
    win->have_last = 1;
}

static void scroll_cb(GLFWwindow *w, double dx, double dy)
{
    (void)dx;
    view_window *win = glfwGetWindowUserPointer(w);
    win->pending.wheel += dy;
}

static GLADapiproc load_proc(const char *name)
{
    return (GLADapiproc)glfwGetProcAddress(name);
}

lm_result view_window_create(const view_window_desc *desc, view_window **out, lm_error *err)
{
    *out = NULL;
    view_window *win = calloc(1, sizeof *win);
    if (!win) return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory for the window");
    if (!glfwInit()) {
        lm_fail(err, LM_ERR_RUNTIME, "viewer: cannot start GLFW: %s (is DISPLAY set? headless: xvfb-run -a lumesh view)",
                glfw_error());
        free(win);
        return LM_ERR_RUNTIME;
    }
    glfwWindowHint(GLFW_CONTEXT_VERSION_MAJOR, 4);
    glfwWindowHint(GLFW_CONTEXT_VERSION_MINOR, 5);
    glfwWindowHint(GLFW_OPENGL_PROFILE, GLFW_OPENGL_CORE_PROFILE);
    glfwWindowHint(GLFW_OPENGL_FORWARD_COMPAT, GLFW_TRUE);
    glfwWindowHint(GLFW_RESIZABLE, GLFW_TRUE);
    glfwWindowHint(GLFW_DEPTH_BITS, 0); /* the renderer draws into its own framebuffers */
    glfwWindowHint(GLFW_SRGB_CAPABLE, GLFW_FALSE); /* the tone-mapping shader encodes sRGB itself */
#ifdef LUMESH_DEBUG
    glfwWindowHint(GLFW_OPENGL_DEBUG_CONTEXT, GLFW_TRUE);
#endif
    int w = desc && desc->width > 0 ? desc->width : 1280, h = desc && desc->height > 0 ? desc->height : 720;
    win->window = glfwCreateWindow(w, h, desc && desc->title ? desc->title : "lumesh", NULL, NULL);
    if (!win->window) {
        lm_fail(err, LM_ERR_UNSUPPORTED, "viewer: cannot open a %dx%d window with OpenGL 4.5 core: %s", w, h,
                glfw_error());
        view_window_destroy(win);
        return LM_ERR_UNSUPPORTED;
    }
    glfwSetWindowUserPointer(win->window, win);
    glfwMakeContextCurrent(win->window);
    /* The window's driver stays loaded to the end, as glctx's do (gl_context.h). */
    glctx_keep_drivers_loaded();
    int version = gladLoadGLContext(&win->gl, load_proc);
    if (!version || GLAD_VERSION_MAJOR(version) * 10 + GLAD_VERSION_MINOR(version) < 45) {
        lm_fail(err, LM_ERR_UNSUPPORTED, "viewer: the window's context offers OpenGL %d.%d, lumesh needs 4.5 core",
                GLAD_VERSION_MAJOR(version), GLAD_VERSION_MINOR(version));
        view_window_destroy(win);
        return LM_ERR_UNSUPPORTED;
    }
    const char *rend = (const char *)win->gl.GetString(GL_RENDERER);
    const char *ver = (const char *)win->gl.GetString(GL_VERSION);
    snprintf(win->renderer, sizeof win->renderer, "%s / %s", rend ? rend : "?", ver ? ver : "?");
    /* The loop paces itself (view_app.c); vsync where there is one keeps it from tearing. */
    glfwSwapInterval(1);
    glfwSetKeyCallback(win->window, key_cb);
    glfwSetCursorPosCallback(win->window, cursor_cb);
    glfwSetScrollCallback(win->window, scroll_cb);
    *out = win;
    return LM_OK;
}

void view_window_destroy(view_window *win)
{
    if (!win) return;
    if (win->window) glfwDestroyWindow(win->window);
    glfwTerminate();
    free(win);
}

const GladGLContext *view_window_gl(const view_window *win) { return &win->gl; }
const char *view_window_renderer(const view_window *win) { return win->renderer; }

void view_window_poll(view_window *win, view_input *out)
{
    glfwPollEvents();
    GLFWwindow *w = win->window;
    win->pending.dragging = glfwGetMouseButton(w, GLFW_MOUSE_BUTTON_LEFT) == GLFW_PRESS ||
                            glfwGetMouseButton(w, GLFW_MOUSE_BUTTON_MIDDLE) == GLFW_PRESS ||
                            glfwGetMouseButton(w, GLFW_MOUSE_BUTTON_RIGHT) == GLFW_PRESS;
#define HELD(k) (glfwGetKey(w, (k)) == GLFW_PRESS)
    win->pending.fly[0] = (float)(HELD(GLFW_KEY_W) - HELD(GLFW_KEY_S));
    win->pending.fly[1] = (float)(HELD(GLFW_KEY_D) - HELD(GLFW_KEY_A));
    win->pending.fly[2] = (float)((HELD(GLFW_KEY_SPACE) || HELD(GLFW_KEY_PAGE_UP)) -
                                  (HELD(GLFW_KEY_LEFT_CONTROL) || HELD(GLFW_KEY_PAGE_DOWN)));
#undef HELD
    int ww = 0, wh = 0;
    glfwGetWindowSize(w, &ww, &wh);
    win->pending.screen_height = wh;
    win->pending.close = glfwWindowShouldClose(win->window);
    *out = win->pending;
    memset(&win->pending, 0, sizeof win->pending);
}

void view_window_framebuffer_size(view_window *win, int *width, int *height)
{
    glfwGetFramebufferSize(win->window, width, height);
}

void view_window_swap(view_window *win) { glfwSwapBuffers(win->window); }
void view_window_set_title(view_window *win, const char *title) { glfwSetWindowTitle(win->window, title); }

void view_window_resize(view_window *win, int width, int height) { glfwSetWindowSize(win->window, width, height); }

void view_window_minimise(view_window *win, int minimised)
{
    if (minimised) glfwIconifyWindow(win->window);
    else glfwRestoreWindow(win->window);
}
