/* fuzz_mesh — libFuzzer harness for mesh files through Assimp and scene_build.
 *
 * $LUMESH_FUZZ_EXT picks the format (obj, ply, gltf, glb, off, stl; default obj).
 * The input is written as mesh.EXT. For OBJ the same bytes are also mesh.mtl and
 * the file is loaded once more with "mtllib mesh.mtl" in front, so one input
 * drives both the OBJ and the MTL parser (a line one of them does not know, the
 * other skips). A load must end in a scene or a one-line error.
 * Seeds: tests/badinput and the shared scenes' small files (bench/fuzz.sh).
 */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "tests/fuzz/fuzz_util.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    const char *ext = fuzz_ext("obj");
    char name[32], path[1024];
    snprintf(name, sizeof name, "mesh.%s", ext);
    if (!fuzz_write(name, data, size, path, sizeof path)) return 0;
    fuzz_load_scene(path);
    if (strcmp(ext, "obj") == 0) {
        static const char head[] = "mtllib mesh.mtl\n";
        uint8_t *both = malloc(sizeof head - 1 + size);
        if (!both) return 0;
        memcpy(both, head, sizeof head - 1);
        memcpy(both + sizeof head - 1, data, size);
        if (fuzz_write("mesh.mtl", data, size, path, sizeof path) &&
            fuzz_write("with-mtl.obj", both, sizeof head - 1 + size, path, sizeof path))
            fuzz_load_scene(path);
        free(both);
    }
    return 0;
}
