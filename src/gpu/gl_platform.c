/* gl_platform.c — names of the GL platforms (gl_platform.h). */
#include "src/gpu/gl_platform.h"

#include <string.h>

const char *glctx_platform_name(glctx_platform p)
{
    switch (p) {
    case GLCTX_DEFAULT:
    case GLCTX_EGL: return "egl";
    case GLCTX_OSMESA: return "osmesa";
    default: return "?";
    }
}

int glctx_platform_from_name(const char *name, glctx_platform *out)
{
    for (int p = GLCTX_EGL; p < GLCTX_PLATFORM_COUNT && name; ++p)
        if (strcmp(name, glctx_platform_name((glctx_platform)p)) == 0) {
            *out = (glctx_platform)p;
            return 1;
        }
    return 0;
}
