/* fuzz_image — libFuzzer harness for the images `lumesh compare` reads.
 *
 * $LUMESH_FUZZ_EXT picks the format (exr or png; default exr). The input is
 * written as image.EXT and goes the way compare's inputs go: img_read (through
 * OpenImageIO), then the comparison of the image with itself, and OpenImageIO's
 * own comparison of the file with itself. Each must end in a result or a
 * one-line error. Seeds: the EXR and PNG files the tests write (bench/fuzz.sh).
 */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "src/image/compare.h"
#include "src/image/image.h"
#include "tests/fuzz/fuzz_util.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    char name[32], path[1024];
    snprintf(name, sizeof name, "image.%s", fuzz_ext("exr"));
    if (!fuzz_write(name, data, size, path, sizeof path)) return 0;
    img_image img = {0};
    lm_error err;
    lm_result r = img_read(path, &img, &err);
    if (r == LM_OK) {
        cmp_result res;
        float *de = malloc(((size_t)img.width * (size_t)img.height + 1) * sizeof *de);
        if (de) r = cmp_compare(&(cmp_desc){.name_a = path, .name_b = path}, &img, &img, &res, de, &err);
        free(de);
        cmp_oiio_result oi;
        if (r == LM_OK) r = cmp_oiio_compare(path, path, &oi, &err);
    }
    if (r != LM_OK && strchr(err.msg, '\n')) __builtin_trap(); /* an error is one line */
    img_free(&img);
    return 0;
}
