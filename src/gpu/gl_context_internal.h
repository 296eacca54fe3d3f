/* gl_context_internal.h — what each platform file (gl_context_egl.c,
 * gl_context_osmesa.c) gives gl_context.c. Not a public header. */
#ifndef LUMESH_GL_CONTEXT_INTERNAL_H
#define LUMESH_GL_CONTEXT_INTERNAL_H

#include "src/gpu/gl_context.h"

typedef struct glctx_platform_ops {
    const char *name;                                   /* "gl-egl", "gl-osmesa" */
    lm_result (*make_current)(void *plat, lm_error *err);
    void (*release)(void *plat);                        /* unbind from the calling thread */
    GLADapiproc (*get_proc)(void *plat, const char *name);
    void (*destroy)(void *plat);                        /* releases first if current */
} glctx_platform_ops;

/* Each opens a 4.5 core context (debug flag where the platform has one) and
 * leaves it current on the calling thread. On failure the message names the
 * platform, what failed and what to install or try. */
lm_result glctx_egl_open(int debug, const glctx_platform_ops **ops, void **plat, lm_error *err);
lm_result glctx_osmesa_open(int debug, const glctx_platform_ops **ops, void **plat, lm_error *err);

#endif
