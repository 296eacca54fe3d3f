/* fuzz_scene_json — libFuzzer harness for the JSON scene description.
 *
 * The input is the description (scene.json); it may name the mesh files "a.obj"
 * (a lit quad, written at start-up) or anything else, relative to it. A load must
 * end in a scene or a one-line error; ASan/UBSan and libFuzzer's timeout and
 * memory limit catch the rest. Seeds: tests/badinput/json-*.json and the
 * built-in scene's description (bench/fuzz.sh).
 */
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include "tests/fuzz/fuzz_util.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static int ready;
    char path[1024];
    if (!ready) {
        if (!fuzz_write_quad()) return 0;
        ready = 1;
    }
    if (!fuzz_write("scene.json", data, size, path, sizeof path)) return 0;
    fuzz_load_scene(path);
    return 0;
}
