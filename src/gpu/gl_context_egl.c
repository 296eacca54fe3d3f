/* gl_context_egl.c — headless OpenGL 4.5 core through EGL (gl_context.h).
 *
 * Display: EGL_MESA_platform_surfaceless through eglGetPlatformDisplayEXT (Mesa:
 * llvmpipe, or the GPU's driver where there is one), else the first device of
 * EGL_EXT_platform_device that initializes (NVIDIA's headless path). Context:
 * desktop OpenGL 4.5 core, no surface at all (EGL_KHR_surfaceless_context): the
 * sampler renders into framebuffer objects only.
 *
 * The display is initialized and never terminated. An EGLDisplay is one object
 * per process for a platform and device, EGL 1.4/1.5 displays are not
 * reference-counted (EGL_KHR_display_reference is not in Mesa 22), and
 * eglTerminate ends every context on the display — also those of other code in
 * the process (a second sampler, the renderer). eglInitialize on a display
 * already initialized is a no-op, so no bookkeeping is needed. The cost is the
 * driver staying loaded until exit (it also lets LeakSanitizer name Mesa's own
 * leaks, tests/lsan.supp; an unloaded driver shows up as "<unknown module>").
 */
#define EGL_NO_X11 1 /* keep Xlib out of eglplatform.h: we never open a window here */
#include <EGL/egl.h>
#include <EGL/eglext.h>
#include <stdlib.h>
#include <string.h>

#include "src/gpu/gl_context_internal.h"

typedef struct egl_plat {
    EGLDisplay dpy;
    EGLContext ctx;
    const char *how; /* "surfaceless" or "device" */
} egl_plat;

static int has_ext(const char *list, const char *name)
{
    if (!list) return 0;
    size_t n = strlen(name);
    for (const char *p = list; (p = strstr(p, name)) != NULL; p += n)
        if ((p == list || p[-1] == ' ') && (p[n] == ' ' || p[n] == '\0')) return 1;
    return 0;
}

static const char *egl_error_name(EGLint e)
{
    switch (e) {
    case EGL_SUCCESS: return "EGL_SUCCESS";
    case EGL_NOT_INITIALIZED: return "EGL_NOT_INITIALIZED";
    case EGL_BAD_ACCESS: return "EGL_BAD_ACCESS";
    case EGL_BAD_ALLOC: return "EGL_BAD_ALLOC";
    case EGL_BAD_ATTRIBUTE: return "EGL_BAD_ATTRIBUTE";
    case EGL_BAD_CONFIG: return "EGL_BAD_CONFIG";
    case EGL_BAD_CONTEXT: return "EGL_BAD_CONTEXT";
    case EGL_BAD_DISPLAY: return "EGL_BAD_DISPLAY";
    case EGL_BAD_MATCH: return "EGL_BAD_MATCH";
    case EGL_BAD_PARAMETER: return "EGL_BAD_PARAMETER";
    default: return "EGL error";
    }
}

static int display_init(EGLDisplay dpy)
{
    EGLint major = 0, minor = 0;
    return eglInitialize(dpy, &major, &minor) == EGL_TRUE;
}

/* A display that initializes, on the surfaceless platform or else on a device. */
static EGLDisplay open_display(const char **how, lm_error *err)
{
    const char *client = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
    PFNEGLGETPLATFORMDISPLAYEXTPROC get_platform_display =
        (PFNEGLGETPLATFORMDISPLAYEXTPROC)eglGetProcAddress("eglGetPlatformDisplayEXT");
    if (!client || !has_ext(client, "EGL_EXT_platform_base") || !get_platform_display) {
        lm_fail(err, LM_ERR_UNSUPPORTED,
                "EGL: no EGL_EXT_platform_base, so no headless display (install libegl-mesa0, or try --gl osmesa)");
        return EGL_NO_DISPLAY;
    }
    if (has_ext(client, "EGL_MESA_platform_surfaceless")) {
        EGLDisplay dpy = get_platform_display(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, NULL);
        if (dpy != EGL_NO_DISPLAY && display_init(dpy)) {
            *how = "surfaceless";
            return dpy;
        }
    }
    if (has_ext(client, "EGL_EXT_platform_device")) {
        PFNEGLQUERYDEVICESEXTPROC query_devices = (PFNEGLQUERYDEVICESEXTPROC)eglGetProcAddress("eglQueryDevicesEXT");
        EGLDeviceEXT devices[16];
        EGLint count = 0;
        if (query_devices && query_devices(16, devices, &count))
            for (EGLint i = 0; i < count; ++i) {
                EGLDisplay dpy = get_platform_display(EGL_PLATFORM_DEVICE_EXT, devices[i], NULL);
                if (dpy != EGL_NO_DISPLAY && display_init(dpy)) {
                    *how = "device";
                    return dpy;
                }
            }
    }
    lm_fail(err, LM_ERR_UNSUPPORTED,
            "EGL: no surfaceless or device platform that initializes (%s; install libegl-mesa0, or try --gl osmesa)",
            egl_error_name(eglGetError()));
    return EGL_NO_DISPLAY;
}

static lm_result egl_make_current(void *p, lm_error *err)
{
    egl_plat *e = p;
    if (!eglMakeCurrent(e->dpy, EGL_NO_SURFACE, EGL_NO_SURFACE, e->ctx))
        return lm_fail(err, LM_ERR_RUNTIME, "EGL: eglMakeCurrent failed (%s)", egl_error_name(eglGetError()));
    return LM_OK;
}

static void egl_release(void *p)
{
    egl_plat *e = p;
    eglMakeCurrent(e->dpy, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
}

static GLADapiproc egl_get_proc(void *p, const char *name)
{
    (void)p;
    /* EGL 1.5 (and Mesa's EGL_KHR_get_all_proc_addresses) returns core GL
     * functions too, so libGL is never linked. */
    return (GLADapiproc)eglGetProcAddress(name);
}

static void egl_destroy(void *p)
{
    egl_plat *e = p;
    if (!e) return;
    if (e->ctx != EGL_NO_CONTEXT) {
        if (eglGetCurrentContext() == e->ctx) egl_release(e);
        eglDestroyContext(e->dpy, e->ctx);
    }
    /* Frees EGL's per-thread state; only when no other context is bound here,
     * because it would unbind that one too. */
    if (eglGetCurrentContext() == EGL_NO_CONTEXT) eglReleaseThread();
    free(e);
}

static const glctx_platform_ops egl_ops = {
    .name = "gl-egl",
    .make_current = egl_make_current,
    .release = egl_release,
    .get_proc = egl_get_proc,
    .destroy = egl_destroy,
};

lm_result glctx_egl_open(int debug, const glctx_platform_ops **ops, void **plat, lm_error *err)
{
    egl_plat *e = calloc(1, sizeof *e);
    if (!e) return lm_fail(err, LM_ERR_NO_MEMORY, "EGL: out of memory");
    e->ctx = EGL_NO_CONTEXT;
    e->dpy = open_display(&e->how, err);
    if (e->dpy == EGL_NO_DISPLAY) {
        free(e);
        return LM_ERR_UNSUPPORTED;
    }
    const char *dext = eglQueryString(e->dpy, EGL_EXTENSIONS);
    lm_result r = LM_OK;
    EGLConfig config = EGL_NO_CONFIG_KHR;
    if (!has_ext(dext, "EGL_KHR_surfaceless_context")) {
        r = lm_fail(err, LM_ERR_UNSUPPORTED,
                    "EGL: the %s display lacks EGL_KHR_surfaceless_context (update Mesa, or try --gl osmesa)", e->how);
    } else if (!eglBindAPI(EGL_OPENGL_API)) {
        r = lm_fail(err, LM_ERR_UNSUPPORTED,
                    "EGL: desktop OpenGL is not available on the %s display (install libgl1-mesa-dri, or try --gl osmesa)",
                    e->how);
    } else if (!has_ext(dext, "EGL_KHR_no_config_context")) {
        /* Any config that renders OpenGL; no surface type needed. */
        const EGLint want[] = {EGL_RENDERABLE_TYPE, EGL_OPENGL_BIT, EGL_SURFACE_TYPE, 0, EGL_NONE};
        EGLint n = 0;
        if (!eglChooseConfig(e->dpy, want, &config, 1, &n) || n < 1)
            r = lm_fail(err, LM_ERR_UNSUPPORTED, "EGL: no OpenGL config on the %s display (try --gl osmesa)", e->how);
    }
    if (r == LM_OK) {
        const EGLint attrs[] = {EGL_CONTEXT_MAJOR_VERSION, 4,
                                EGL_CONTEXT_MINOR_VERSION, 5,
                                EGL_CONTEXT_OPENGL_PROFILE_MASK, EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT,
                                EGL_CONTEXT_OPENGL_DEBUG, debug ? EGL_TRUE : EGL_FALSE,
                                EGL_NONE};
        e->ctx = eglCreateContext(e->dpy, config, EGL_NO_CONTEXT, attrs);
        if (e->ctx == EGL_NO_CONTEXT)
            r = lm_fail(err, LM_ERR_UNSUPPORTED,
                        "EGL: cannot create an OpenGL 4.5 core context on the %s display (%s; update Mesa, or try "
                        "--gl osmesa)",
                        e->how, egl_error_name(eglGetError()));
    }
    if (r == LM_OK) r = egl_make_current(e, err);
    if (r != LM_OK) {
        egl_destroy(e);
        return r;
    }
    *ops = &egl_ops;
    *plat = e;
    return LM_OK;
}
