/* gl_context.c — the platform-independent half of the GL context layer
 * (gl_context.h): platform dispatch, loading the glad MX function table,
 * KHR_debug in debug builds, and tracking which context is current on each
 * thread so that EGL and OSMesa contexts can take turns on one thread. */
#define _GNU_SOURCE /* dl_iterate_phdr, RTLD_NODELETE, RTLD_NOLOAD: before any header */
#include "src/gpu/gl_context.h"

#include <dlfcn.h>
#include <link.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "src/base/fork_guard.h"
#include "src/gpu/gl_context_internal.h"

struct glctx {
    const glctx_platform_ops *ops;
    void *plat;                  /* the platform's own state */
    GladGLContext gl;            /* function table, loaded from the platform */
    char renderer[256];
    /* Debug builds: the first error reported by KHR_debug since the last
     * glctx_check. Written by the debug callback, which runs synchronously on
     * the thread the context is current on. */
    char debug_msg[512];
};

/* The glctx current on this thread (NULL: none of ours). Per thread because a
 * GL context binding is per thread. Lets glctx_make_current skip redundant
 * binds and release a context of the other platform before binding: EGL and
 * OSMesa both set Mesa's per-thread dispatch, and neither knows the other. */
static _Thread_local glctx *glctx_current;

#ifdef LUMESH_DEBUG
static void GLAD_API_PTR debug_callback(GLenum source, GLenum type, GLuint id, GLenum severity, GLsizei length,
                                        const GLchar *message, const void *user)
{
    (void)source;
    (void)id;
    (void)length;
    glctx *ctx = (glctx *)(uintptr_t)user;
    if (ctx->debug_msg[0]) return; /* keep the first: later ones are usually consequences */
    if (type == GL_DEBUG_TYPE_ERROR || severity == GL_DEBUG_SEVERITY_HIGH)
        snprintf(ctx->debug_msg, sizeof ctx->debug_msg, "%s", message);
}
#endif

static GLADapiproc load_proc(void *user, const char *name)
{
    glctx *ctx = user;
    return ctx->ops->get_proc(ctx->plat, name);
}

static lm_result create_context(const glctx_desc *desc, glctx **out, lm_error *err)
{
    *out = NULL;
    glctx_platform p = desc ? desc->platform : GLCTX_DEFAULT;
    int debug = 0;
#ifdef LUMESH_DEBUG
    debug = 1;
#endif
    glctx *ctx = calloc(1, sizeof *ctx);
    if (!ctx) return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory creating a GL context");
    /* Whatever is current here belongs to someone else or to a context of the
     * other platform: release ours first so the new binding is the only one. */
    if (glctx_current) {
        glctx_current->ops->release(glctx_current->plat);
        glctx_current = NULL;
    }
    lm_result r;
    switch (p) {
    case GLCTX_DEFAULT:
    case GLCTX_EGL: r = glctx_egl_open(debug, &ctx->ops, &ctx->plat, err); break;
    case GLCTX_OSMESA: r = glctx_osmesa_open(debug, &ctx->ops, &ctx->plat, err); break;
    default: r = lm_fail(err, LM_ERR_INVALID_ARG, "GL: unknown platform %d", (int)p); break;
    }
    if (r != LM_OK) {
        free(ctx);
        return r;
    }
    glctx_current = ctx;
    int version = gladLoadGLContextUserPtr(&ctx->gl, load_proc, ctx);
    if (!version || GLAD_VERSION_MAJOR(version) * 10 + GLAD_VERSION_MINOR(version) < 45) {
        lm_fail(err, LM_ERR_UNSUPPORTED,
                "%s: the context offers OpenGL %d.%d, lumesh needs 4.5 core (update Mesa, or try --sampler embree)",
                ctx->ops->name, GLAD_VERSION_MAJOR(version), GLAD_VERSION_MINOR(version));
        glctx_destroy(ctx);
        return LM_ERR_UNSUPPORTED;
    }
    const char *rend = (const char *)ctx->gl.GetString(GL_RENDERER);
    const char *ver = (const char *)ctx->gl.GetString(GL_VERSION);
    snprintf(ctx->renderer, sizeof ctx->renderer, "%s / %s", rend ? rend : "?", ver ? ver : "?");
#ifdef LUMESH_DEBUG
    if (ctx->gl.KHR_debug || ctx->gl.DebugMessageCallback) {
        ctx->gl.Enable(GL_DEBUG_OUTPUT);
        ctx->gl.Enable(GL_DEBUG_OUTPUT_SYNCHRONOUS); /* messages arrive inside the call that caused them */
        ctx->gl.DebugMessageCallback(debug_callback, ctx);
    }
#endif
    *out = ctx;
    return LM_OK;
}

/* A loaded library that is a GL driver: Mesa's DRI drivers (swrast_dri.so,
 * iris_dri.so, ...) and its gallium library where the build has one. */
static int is_gl_driver(const char *path)
{
    const char *base = strrchr(path, '/');
    base = base ? base + 1 : path;
    return strstr(base, "_dri.so") != NULL || strncmp(base, "libgallium", 10) == 0;
}

static int pin_driver(struct dl_phdr_info *info, size_t size, void *user)
{
    (void)size;
    (void)user;
    if (info->dlpi_name && info->dlpi_name[0] && is_gl_driver(info->dlpi_name)) {
        /* NOLOAD: a handle to what is there, never a load; NODELETE: never unloaded.
         * The handle is not closed: it is what holds the module. */
        (void)dlopen(info->dlpi_name, RTLD_NOW | RTLD_NOLOAD | RTLD_NODELETE);
    }
    return 0;
}

void glctx_keep_drivers_loaded(void)
{
    lm_fork_guard_enter(); /* the loader's lock, as around a context's start */
    dl_iterate_phdr(pin_driver, NULL);
    lm_fork_guard_leave();
}

/* The driver is loaded, started and (at the last context's end) unloaded inside
 * the fork guard: a child forked meanwhile would inherit the loader's locks
 * held (fork_guard.h). */
lm_result glctx_create(const glctx_desc *desc, glctx **out, lm_error *err)
{
    lm_fork_guard_enter();
    lm_result r = create_context(desc, out, err);
    lm_fork_guard_leave();
    return r;
}

void glctx_destroy(glctx *ctx)
{
    if (!ctx) return;
    if (glctx_current == ctx) glctx_current = NULL;
    lm_fork_guard_enter();
    ctx->ops->destroy(ctx->plat);
    lm_fork_guard_leave();
    free(ctx);
}

lm_result glctx_make_current(glctx *ctx, lm_error *err)
{
    if (glctx_current == ctx) return LM_OK;
    if (glctx_current) glctx_current->ops->release(glctx_current->plat);
    glctx_current = NULL;
    lm_result r = ctx->ops->make_current(ctx->plat, err);
    if (r == LM_OK) glctx_current = ctx;
    return r;
}

void glctx_release(glctx *ctx)
{
    if (!ctx || glctx_current != ctx) return;
    ctx->ops->release(ctx->plat);
    glctx_current = NULL;
}

const GladGLContext *glctx_gl(const glctx *ctx) { return &ctx->gl; }
const char *glctx_name(const glctx *ctx) { return ctx->ops->name; }
const char *glctx_renderer(const glctx *ctx) { return ctx->renderer; }

#ifdef LUMESH_DEBUG
static const char *gl_error_name(GLenum e)
{
    switch (e) {
    case GL_INVALID_ENUM: return "GL_INVALID_ENUM";
    case GL_INVALID_VALUE: return "GL_INVALID_VALUE";
    case GL_INVALID_OPERATION: return "GL_INVALID_OPERATION";
    case GL_INVALID_FRAMEBUFFER_OPERATION: return "GL_INVALID_FRAMEBUFFER_OPERATION";
    case GL_OUT_OF_MEMORY: return "GL_OUT_OF_MEMORY";
    case GL_STACK_OVERFLOW: return "GL_STACK_OVERFLOW";
    case GL_STACK_UNDERFLOW: return "GL_STACK_UNDERFLOW";
    default: return "unknown GL error";
    }
}
#endif

lm_result glctx_check(glctx *ctx, const char *what, lm_error *err)
{
#ifdef LUMESH_DEBUG
    GLenum e = ctx->gl.GetError();
    /* Drain the queue so the next check reports only its own errors. */
    for (int i = 0; i < 16 && ctx->gl.GetError() != GL_NO_ERROR; ++i) {}
    if (ctx->debug_msg[0]) {
        lm_fail(err, LM_ERR_RUNTIME, "%s: GL error during %s: %s", ctx->ops->name, what, ctx->debug_msg);
        ctx->debug_msg[0] = '\0';
        return LM_ERR_RUNTIME;
    }
    if (e != GL_NO_ERROR)
        return lm_fail(err, LM_ERR_RUNTIME, "%s: GL error during %s: %s", ctx->ops->name, what, gl_error_name(e));
    return LM_OK;
#else
    (void)ctx;
    (void)what;
    (void)err;
    return LM_OK;
#endif
}
