/* gl_program.h — GLSL programs built from the shaders compiled into lumesh
 * (shaders/NAME.vert, .frag, .comp, embedded by CMake and read as builtin:/NAME), for
 * the GL sampler and the renderer.
 *
 * Usage:
 *     static const char *const names[] = {"rend_id.vert", "rend_id.frag", NULL};
 *     GLuint prog;
 *     if (glprog_build(gl, "renderer", names, "#define X 1\n", &prog, &err) != LM_OK) ...
 *
 * The stage comes from the extension (.vert, .frag, else compute). `defines` is
 * inserted after each shader's #version line. A compile or link failure gives
 * one line naming `who`, the shader and GL's log.
 * Threads: call with the context of `gl` current on this thread.
 * Does NOT do: caching, geometry or tessellation stages, hot reload.
 */
#ifndef LUMESH_GL_PROGRAM_H
#define LUMESH_GL_PROGRAM_H

#include <glad/gl.h>

#include "src/base/util.h"

#ifdef __cplusplus
extern "C" {
#endif

enum { GLPROG_MAX_STAGES = 4 };

lm_result glprog_build(const GladGLContext *gl, const char *who, const char *const *names, const char *defines,
                       GLuint *out, lm_error *err);

#ifdef __cplusplus
}
#endif
#endif
