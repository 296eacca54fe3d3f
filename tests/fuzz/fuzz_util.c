/* fuzz_util.c — see fuzz_util.h. */
#define _POSIX_C_SOURCE 200809L /* mkdtemp */
#include "tests/fuzz/fuzz_util.h"

#include "src/scene/scene.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

const char *fuzz_dir(void)
{
    static char dir[512];
    if (!dir[0]) {
        const char *tmp = getenv("TMPDIR");
        snprintf(dir, sizeof dir, "%s/lumesh-fuzz-XXXXXX", tmp && tmp[0] ? tmp : "/tmp");
        if (!mkdtemp(dir)) {
            perror("mkdtemp");
            abort();
        }
    }
    return dir;
}

int fuzz_write(const char *name, const uint8_t *data, size_t size, char *out, size_t out_size)
{
    int n = snprintf(out, out_size, "%s/%s", fuzz_dir(), name);
    if (n < 0 || (size_t)n >= out_size) return 0;
    FILE *f = fopen(out, "wb");
    if (!f) return 0;
    int ok = fwrite(data, 1, size, f) == size;
    return fclose(f) == 0 && ok;
}

int fuzz_write_quad(void)
{
    static const char quad[] = "v 0 0 0\nv 1 0 0\nv 1 0 1\nv 0 0 1\nf 1 4 3\nf 1 3 2\n";
    char path[1024];
    return fuzz_write("a.obj", (const uint8_t *)quad, sizeof quad - 1, path, sizeof path);
}

const char *fuzz_ext(const char *fallback)
{
    const char *e = getenv("LUMESH_FUZZ_EXT");
    return e && e[0] ? e : fallback;
}

void fuzz_load_scene(const char *path)
{
    /* A sanitizer report on our code in the reader's child process is a finding
     * (scene_isolate.c); the reader's own crashes are handled errors. */
    setenv("LUMESH_READER_STRICT", "1", 0);
    scene *s = NULL;
    lm_error err;
    if (scene_load(&(scene_load_desc){.path = path}, &s, &err) == LM_OK)
        scene_destroy(s);
    else if (strchr(err.msg, '\n'))
        __builtin_trap(); /* an error is one line */
}
