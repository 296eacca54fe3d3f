/* gl_context_osmesa.c — headless OpenGL 4.5 core through OSMesa, Mesa's
 * off-screen renderer (gl_context.h). The fallback when EGL has no headless
 * display: it needs no driver, no device and no display server.
 *
 * OSMesa insists on a client colour buffer for OSMesaMakeCurrent; the sampler
 * renders into framebuffer objects, so a 4×4 dummy buffer owned by the
 * context is enough. Entry points come from OSMesaGetProcAddress (never libGL).
 *
 * libOSMesa is opened with dlopen on first use, not linked: it links LLVM, and a
 * library the program names is loaded and relocated at every start, OSMesa or
 * not. That was 51 MB of resident memory in every command, `info` included
 * (docs/memory.md); EGL loads Mesa's driver (and LLVM) only when a context is made.
 */
#include <glad/gl.h> /* first: it stands in for GL/gl.h, which osmesa.h includes */

#include <GL/osmesa.h>
#include <dlfcn.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>

#include "src/gpu/gl_context_internal.h"

enum { OSMESA_DUMMY_SIZE = 4 };

/* The entry points we use, resolved once under osm_once and then only read;
 * the library stays loaded for the rest of the process (Mesa does not unload). */
static struct {
    OSMesaContext (*create)(const int *attrs, OSMesaContext share);
    GLboolean (*make_current)(OSMesaContext ctx, void *buffer, GLenum type, GLsizei w, GLsizei h);
    OSMESAproc (*get_proc)(const char *name);
    OSMesaContext (*get_current)(void);
    void (*destroy)(OSMesaContext ctx);
    char error[160]; /* dlerror()'s message when the library or a symbol is missing */
} osm;
static pthread_once_t osm_once = PTHREAD_ONCE_INIT;

static void osm_load(void)
{
    static const char *const names[] = {"libOSMesa.so.8", "libOSMesa.so"};
    void *lib = NULL;
    for (size_t i = 0; !lib && i < sizeof names / sizeof *names; ++i) lib = dlopen(names[i], RTLD_NOW | RTLD_LOCAL);
    /* POSIX dlsym returns void *; the casts through a union keep -Wpedantic quiet. */
    union { void *p; OSMesaContext (*f)(const int *, OSMesaContext); } c = {lib ? dlsym(lib, "OSMesaCreateContextAttribs") : NULL};
    union { void *p; GLboolean (*f)(OSMesaContext, void *, GLenum, GLsizei, GLsizei); } m = {lib ? dlsym(lib, "OSMesaMakeCurrent") : NULL};
    union { void *p; OSMESAproc (*f)(const char *); } g = {lib ? dlsym(lib, "OSMesaGetProcAddress") : NULL};
    union { void *p; OSMesaContext (*f)(void); } cur = {lib ? dlsym(lib, "OSMesaGetCurrentContext") : NULL};
    union { void *p; void (*f)(OSMesaContext); } d = {lib ? dlsym(lib, "OSMesaDestroyContext") : NULL};
    if (!c.p || !m.p || !g.p || !cur.p || !d.p) {
        const char *e = dlerror();
        snprintf(osm.error, sizeof osm.error, "%s", e ? e : "libOSMesa.so.8: not found");
        return;
    }
    osm.create = c.f;
    osm.make_current = m.f;
    osm.get_proc = g.f;
    osm.get_current = cur.f;
    osm.destroy = d.f;
}

typedef struct osmesa_plat {
    OSMesaContext ctx;
    unsigned char buffer[OSMESA_DUMMY_SIZE * OSMESA_DUMMY_SIZE * 4]; /* RGBA8, never read */
} osmesa_plat;

static lm_result osmesa_make_current(void *p, lm_error *err)
{
    osmesa_plat *o = p;
    if (!osm.make_current(o->ctx, o->buffer, GL_UNSIGNED_BYTE, OSMESA_DUMMY_SIZE, OSMESA_DUMMY_SIZE))
        return lm_fail(err, LM_ERR_RUNTIME, "OSMesa: OSMesaMakeCurrent failed");
    return LM_OK;
}

static void osmesa_release(void *p)
{
    (void)p;
    osm.make_current(NULL, NULL, GL_UNSIGNED_BYTE, 0, 0); /* Mesa: unbinds the current context */
}

static GLADapiproc osmesa_get_proc(void *p, const char *name)
{
    (void)p;
    return (GLADapiproc)osm.get_proc(name);
}

static void osmesa_destroy(void *p)
{
    osmesa_plat *o = p;
    if (!o) return;
    if (o->ctx) {
        if (osm.get_current() == o->ctx) osmesa_release(o);
        osm.destroy(o->ctx);
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
    pthread_once(&osm_once, osm_load);
    if (!osm.create)
        return lm_fail(err, LM_ERR_UNSUPPORTED, "OSMesa: cannot load the library (%s); install libosmesa6, or try --gl egl",
                       osm.error);
    osmesa_plat *o = calloc(1, sizeof *o);
    if (!o) return lm_fail(err, LM_ERR_NO_MEMORY, "OSMesa: out of memory");
    const int attrs[] = {OSMESA_FORMAT, OSMESA_RGBA,
                         OSMESA_DEPTH_BITS, 0,
                         OSMESA_PROFILE, OSMESA_CORE_PROFILE,
                         OSMESA_CONTEXT_MAJOR_VERSION, 4,
                         OSMESA_CONTEXT_MINOR_VERSION, 5,
                         0};
    o->ctx = osm.create(attrs, NULL);
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
