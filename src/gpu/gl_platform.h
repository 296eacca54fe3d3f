/* gl_platform.h — which headless OpenGL platform a context is made on, and its
 * command-line spellings. A header of its own, without GL, so that descriptors
 * above the GPU layer (the samplers', the front ends') can name a platform
 * without pulling in the GL loader.
 *
 * Usage:
 *     glctx_platform p = GLCTX_DEFAULT;
 *     if (!glctx_platform_from_name("osmesa", &p)) ...;   // "egl", "osmesa"
 *     printf("%s\n", glctx_platform_name(p));
 *
 * Does NOT do: create contexts (gl_context.h), probe what the machine has.
 */
#ifndef LUMESH_GPU_GL_PLATFORM_H
#define LUMESH_GPU_GL_PLATFORM_H

#ifdef __cplusplus
extern "C" {
#endif

typedef enum glctx_platform {
    GLCTX_DEFAULT = 0, /* EGL */
    GLCTX_EGL,         /* headless EGL: surfaceless, else device platform */
    GLCTX_OSMESA,      /* Mesa's off-screen software renderer */
    GLCTX_PLATFORM_COUNT
} glctx_platform;

/* "egl" (also for GLCTX_DEFAULT), "osmesa", "?" for anything else. */
const char *glctx_platform_name(glctx_platform p);
/* The spellings of the command line: "egl", "osmesa". Returns 0 (and leaves *out
 * alone) for anything else. */
int glctx_platform_from_name(const char *name, glctx_platform *out);

#ifdef __cplusplus
}
#endif
#endif
