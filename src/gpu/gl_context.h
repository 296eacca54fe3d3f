/* gl_context.h — a headless OpenGL 4.5 core context and its function table
 * (docs/architecture.md "Threads and who owns what"). One file per platform: gl_context_egl.c
 * (EGL surfaceless or device platform), gl_context_osmesa.c (Mesa's off-screen
 * renderer); gl_context.c holds what they share (dispatch, KHR_debug, the
 * "which context is current on this thread" bookkeeping).
 *
 * GL entry points are loaded by a glad loader generated at build time in MX
 * mode: every context has its own GladGLContext, so EGL and OSMesa contexts can
 * live in one process (each table comes from its own platform's
 * GetProcAddress, never from libGL).
 *
 * Usage:
 *     glctx *ctx; lm_error err;
 *     if (glctx_create(&(glctx_desc){.platform = GLCTX_EGL}, &ctx, &err) != LM_OK)
 *         fprintf(stderr, "%s\n", err.msg);   // says which platform failed and what to try
 *     const GladGLContext *gl = glctx_gl(ctx);   // current on this thread already
 *     gl->ClearColor(0, 0, 0, 0);
 *     glctx_destroy(ctx);
 *
 * Threads: a context is current on at most one thread. glctx_create makes the
 * new context current on the calling thread; glctx_make_current moves it (the
 * caller must make sure no other thread is using it). glctx_destroy releases
 * it from the calling thread. Switching between contexts of different
 * platforms on one thread is handled: the previous one is released first
 * (EGL and OSMesa both bind Mesa's dispatch, and neither knows the other).
 * Debug builds (LUMESH_DEBUG): KHR_debug output is on and glctx_check turns the
 * first GL error or debug message of high/medium severity into an lm_error; in
 * other builds glctx_check costs nothing and always succeeds.
 * Does NOT do: windows or surfaces (render into framebuffer objects), sharing
 * objects between contexts, GLES.
 */
#ifndef LUMESH_GL_CONTEXT_H
#define LUMESH_GL_CONTEXT_H

#include <glad/gl.h>

#include "src/base/util.h"
#include "src/gpu/gl_platform.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct glctx_desc {
    glctx_platform platform; /* GLCTX_DEFAULT = EGL */
} glctx_desc;

typedef struct glctx glctx;

/* Creates an OpenGL 4.5 core context on the platform asked for (no fallback to
 * another platform: the caller decides) and makes it current on this thread. */
lm_result glctx_create(const glctx_desc *desc, glctx **out, lm_error *err);
void glctx_destroy(glctx *ctx); /* NULL is a no-op */

/* Keeps the GL drivers loaded now (Mesa's `*_dri.so` and `libgallium*`) loaded for
 * the rest of the process (dlopen RTLD_NODELETE). For a front end whose own
 * window system unloads the driver at its end (the viewer's GLFW/GLX: at
 * glfwTerminate): Mesa keeps state reachable only from the driver's globals, and
 * once those are unmapped LeakSanitizer reports it as leaked from an "unknown
 * module" (docs/viewer.md). glctx's EGL and OSMesa contexts never unload it.
 * Any thread; cheap. */
void glctx_keep_drivers_loaded(void);

/* Makes ctx current on the calling thread (cheap when it already is). */
lm_result glctx_make_current(glctx *ctx, lm_error *err);
/* Releases ctx from the calling thread, where it is current (else a no-op), so
 * that another thread may make it current: a context made on a helper thread
 * while the main one loads the scene (`converge`). */
void glctx_release(glctx *ctx);

/* The context's function table; valid while ctx lives; call only while ctx is
 * current on the calling thread. */
const GladGLContext *glctx_gl(const glctx *ctx);

/* "gl-egl" or "gl-osmesa", for display (messages, and the GL sampler's name in
 * reports); decide by the platform asked for (glctx_desc.platform), not by this. */
const char *glctx_name(const glctx *ctx);
/* GL_RENDERER and GL_VERSION, for reports ("llvmpipe (LLVM 15.0.6, 256 bits) / 4.5 (Core Profile) Mesa 22.3.6"). */
const char *glctx_renderer(const glctx *ctx);

/* Debug builds: the first pending GL error or KHR_debug error message since the
 * last check becomes "GL error during <what>: ..." and LM_ERR_RUNTIME. Release
 * builds: returns LM_OK without touching GL. */
lm_result glctx_check(glctx *ctx, const char *what, lm_error *err);

#ifdef __cplusplus
}
#endif
#endif
