/* gl_context_osmesa.c — headless OpenGL 4.5 core through OSMesa, Mesa's
 * off-screen renderer (gl_context.h). The fallback when EGL has no headless
 * display: it needs no driver, no device and no display server.
 *
 * OSMesa insists on a client colour buffer for OSMesaMakeCurrent; the sampler
 * renders into framebuffer objects, so a 4×4 dummy buffer owned by the
 * context is enough. Entry points come from OSMesaGetProcAddress (never libGL).
 */
#include <glad/gl.h> /* first: it stands in for GL/gl.h, which osmesa.h includes */

#include <GL/osmesa.h>
#include <stdlib.h>

#include "src/gpu/gl_context_internal.h"

enum { OSMESA_DUMMY_SIZE = 4 };

typedef struct osmesa_plat {
    OSMesaContext ctx;
    unsigned char buffer[OSMESA_DUMMY_SIZE * OSMESA_DUMMY_SIZE * 4]; /* RGBA8, never read */
} osmesa_plat;

static lm_result osmesa_make_current(void *p, lm_error *err)
{
    osmesa_plat *o = p;
    if (!OSMesaMakeCurrent(o->ctx, o->buffer, GL_UNSIGNED_BYTE, OSMESA_DUMMY_SIZE, OSMESA_DUMMY_SIZE))
        return lm_fail(err, LM_ERR_RUNTIME, "OSMesa: OSMesaMakeCurrent failed");
    return LM_OK;
}

static void osmesa_release(void *p)
{
    (void)p;
    OSMesaMakeCurrent(NULL, NULL, GL_UNSIGNED_BYTE, 0, 0); /* Mesa: unbinds the current context */
}

static GLADapiproc osmesa_get_proc(void *p, const char *name)
{
    (void)p;
    return (GLADapiproc)OSMesaGetProcAddress(name);
}

static void osmesa_destroy(void *p)
{
    osmesa_plat *o = p;
    if (!o) return;
    if (o->ctx) {
        if (OSMesaGetCurrentContext() == o->ctx) osmesa_release(o);
        OSMesaDestroyContext(o->ctx);
    }
    free(o);
}

static const glctx_platform_ops osmesa_ops = {
    .name = "gl-osmesa",
    .make_current = osmesa_make_current,
    .release = osmesa_release,
    .get_proc = osmesa_get_proc,
    .destroy = osmesa_destroy,
};

lm_result glctx_osmesa_open(int debug, const glctx_platform_ops **ops, void **plat, lm_error *err)
{
    (void)debug; /* OSMesa has no debug-context flag; KHR_debug output is enabled regardless */
    osmesa_plat *o = calloc(1, sizeof *o);
    if (!o) return lm_fail(err, LM_ERR_NO_MEMORY, "OSMesa: out of memory");
    const int attrs[] = {OSMESA_FORMAT, OSMESA_RGBA,
                         OSMESA_DEPTH_BITS, 0,
                         OSMESA_PROFILE, OSMESA_CORE_PROFILE,
                         OSMESA_CONTEXT_MAJOR_VERSION, 4,
                         OSMESA_CONTEXT_MINOR_VERSION, 5,
                         0};
    o->ctx = OSMesaCreateContextAttribs(attrs, NULL);
    if (!o->ctx) {
        free(o);
        return lm_fail(err, LM_ERR_UNSUPPORTED,
                       "OSMesa: cannot create an OpenGL 4.5 core context (install libosmesa6 from Mesa 20 or later, "
                       "or try --gl egl)");
    }
    lm_result r = osmesa_make_current(o, err);
    if (r != LM_OK) {
        osmesa_destroy(o);
        return r;
    }
    *ops = &osmesa_ops;
    *plat = o;
    return LM_OK;
}
