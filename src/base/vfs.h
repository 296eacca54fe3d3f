/* vfs.h — where scene files come from: the disk, or the files compiled into the
 * program (the built-in default scene, see cmake/embed.cmake).
 *
 * A path "builtin:/NAME" names an embedded file; every other path is a disk path.
 * Relative paths inside a built-in scene resolve to other built-in files, because
 * lm_path_dir("builtin:/a.json") is "builtin:".
 */
#ifndef LUMESH_VFS_H
#define LUMESH_VFS_H

#include <stddef.h>
#include "src/base/util.h"

#ifdef __cplusplus
extern "C" {
#endif

#define VFS_BUILTIN_PREFIX "builtin:/"
#define VFS_DEFAULT_SCENE VFS_BUILTIN_PREFIX "cornell-box.json"

typedef struct vfs_builtin_file {
    const char *name;           /* file name, no directory */
    const unsigned char *data;  /* size bytes followed by a NUL */
    size_t size;
} vfs_builtin_file;

/* Generated table, terminated by an entry with name == NULL. */
extern const vfs_builtin_file vfs_builtin_files[];

int vfs_is_builtin(const char *path);

/* Reads a whole file (disk or built-in) into a malloc'd NUL-terminated buffer. */
lm_result vfs_read(const char *path, size_t max_bytes, char **out_data, size_t *out_size,
                   lm_error *err);

#ifdef __cplusplus
}
#endif
#endif
