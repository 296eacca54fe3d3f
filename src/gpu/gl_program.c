/* gl_program.c — GLSL programs from the shaders compiled into the program
 * (shaders/, embedded by CMake; see gl_program.h). */
#include "src/gpu/gl_program.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "src/base/vfs.h"


/* Reads builtin:/name and inserts `defines` after its #version line. */
static lm_result load_source(const char *name, const char *defines, char **out, lm_error *err)
{
    char path[128], *text = NULL;
    size_t size = 0;
    snprintf(path, sizeof path, VFS_BUILTIN_PREFIX "%s", name);
    lm_result r = vfs_read(path, 1 << 20, &text, &size, err);
    if (r != LM_OK) return r;
    const char *eol = strchr(text, '\n');
    size_t head = eol ? (size_t)(eol - text) + 1 : size, dl = strlen(defines);
    char *src = malloc(size + dl + 1);
    if (!src) {
        free(text);
        return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory reading %s", path);
    }
    memcpy(src, text, head);
    memcpy(src + head, defines, dl);
    memcpy(src + head + dl, text + head, size - head + 1);
    free(text);
    *out = src;
    return LM_OK;
}

static lm_result compile(const GladGLContext *gl, const char *who, GLenum type, const char *name, const char *defines,
                         GLuint *out, lm_error *err)
{
    char *src = NULL;
    lm_result r = load_source(name, defines, &src, err);
    if (r != LM_OK) return r;
    GLuint sh = gl->CreateShader(type);
    const GLchar *s = src;
    gl->ShaderSource(sh, 1, &s, NULL);
    gl->CompileShader(sh);
    free(src);
    GLint ok = 0;
    gl->GetShaderiv(sh, GL_COMPILE_STATUS, &ok);
    if (!ok) {
        char log[700];
        gl->GetShaderInfoLog(sh, sizeof log, NULL, log);
        gl->DeleteShader(sh);
        return lm_fail(err, LM_ERR_RUNTIME, "%s: shader %s does not compile: %s", who, name, log);
    }
    *out = sh;
    return LM_OK;
}

lm_result glprog_build(const GladGLContext *gl, const char *who, const char *const *names, const char *defines,
                       GLuint *out, lm_error *err)
{
    GLuint prog = gl->CreateProgram(), sh[GLPROG_MAX_STAGES] = {0};
    int n = 0;
    lm_result r = LM_OK;
    for (; names[n] && r == LM_OK; ++n) {
        if (n == GLPROG_MAX_STAGES) {
            r = lm_fail(err, LM_ERR_INVALID_ARG, "%s: more than %d shader stages", who, GLPROG_MAX_STAGES);
            break;
        }
        const char *ext = strrchr(names[n], '.');
        GLenum type = strcmp(ext, ".vert") == 0   ? GL_VERTEX_SHADER
                      : strcmp(ext, ".frag") == 0 ? GL_FRAGMENT_SHADER
                                                  : GL_COMPUTE_SHADER;
        r = compile(gl, who, type, names[n], defines, &sh[n], err);
        if (r == LM_OK) gl->AttachShader(prog, sh[n]);
    }
    if (r == LM_OK) {
        gl->LinkProgram(prog);
        GLint ok = 0;
        gl->GetProgramiv(prog, GL_LINK_STATUS, &ok);
        if (!ok) {
            char log[700];
            gl->GetProgramInfoLog(prog, sizeof log, NULL, log);
            r = lm_fail(err, LM_ERR_RUNTIME, "%s: shaders %s + %s do not link: %s", who, names[0],
                        names[1] ? names[1] : "", log);
        }
    }
    for (int i = 0; i < n; ++i)
        if (sh[i]) gl->DeleteShader(sh[i]); /* flagged; freed with the program */
    if (r != LM_OK) {
        gl->DeleteProgram(prog);
        return r;
    }
    *out = prog;
    return LM_OK;
}
