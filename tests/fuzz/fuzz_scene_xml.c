/* fuzz_scene_xml — libFuzzer harness for Mitsuba XML scenes (scene_mitsuba.c).
 *
 * The input is the scene (scene.xml); it may name the mesh file "a.obj" (a lit
 * quad) and the texture "t.png" (2x1 pixels), both written at start-up, or
 * anything else, relative to it. A load must end in a scene or a one-line error;
 * ASan/UBSan and libFuzzer's timeout and memory limit catch the rest. Seeds:
 * tests/badinput/mitsuba-*.xml, the .xml files of tests/fuzz/seeds and the Veach door's
 * scene.xml (bench/fuzz.sh).
 */
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include "src/image/image.h"
#include "tests/fuzz/fuzz_util.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static int ready;
    char path[1024];
    if (!ready) {
        if (!fuzz_write_quad()) return 0;
        snprintf(path, sizeof path, "%s/t.png", fuzz_dir());
        static const uint8_t px[6] = {255, 0, 0, 0, 0, 255};
        img_write_desc d = {.path = path, .width = 2, .height = 1, .channels = 3, .pixels8 = px};
        lm_error err;
        if (img_write(&d, &err) != LM_OK) return 0;
        ready = 1;
    }
    if (!fuzz_write("scene.xml", data, size, path, sizeof path)) return 0;
    fuzz_load_scene(path);
    return 0;
}
