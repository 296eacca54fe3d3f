/* vfs.c — disk files and the files compiled into the program. */
#include "src/base/vfs.h"

#include <stdlib.h>
#include <string.h>

int vfs_is_builtin(const char *path)
{
    return strncmp(path, VFS_BUILTIN_PREFIX, strlen(VFS_BUILTIN_PREFIX)) == 0;
}

lm_result vfs_read(const char *path, size_t max_bytes, char **out_data, size_t *out_size,
                   lm_error *err)
{
    if (!vfs_is_builtin(path)) return lm_read_file(path, max_bytes, out_data, out_size, err);
    const char *name = path + strlen(VFS_BUILTIN_PREFIX);
    for (const vfs_builtin_file *f = vfs_builtin_files; f->name; ++f) {
        if (strcmp(f->name, name) != 0) continue;
        char *buf = malloc(f->size + 1);
        if (!buf) return lm_fail(err, LM_ERR_NO_MEMORY, "%s: out of memory", path);
        memcpy(buf, f->data, f->size);
        buf[f->size] = '\0';
        *out_data = buf;
        *out_size = f->size;
        return LM_OK;
    }
    *out_data = NULL;
    *out_size = 0;
    return lm_fail(err, LM_ERR_IO, "%s: no such built-in file", path);
}
