/* image.h — image files through OpenImageIO: linear float EXR and 8-bit PNG.
 *
 * Every write goes to a temporary name beside the target and is renamed into
 * place only when complete, so a failure never leaves a partial file and never
 * clobbers an existing one.
 *
 * Pixels are row-major, top row first, channels interleaved.
 *
 * Notes:
 * - The encoded file is built in memory and written with checked writes, because
 *   OpenImageIO 2.4's PNG writer reports success on a truncated file.
 * - EXR stores channels alphabetically; img_write records the original order in a
 *   `lumesh:channelOrder` header attribute and img_read restores it (files from
 *   other tools come back in OpenImageIO's order).
 * - Channel names: 1..31 bytes, unique, no control characters. PNG ignores them
 *   and reads back as R,G,B(,A) or Y,A. Alpha is never premultiplied.
 * - Float to PNG: NaN becomes 0, values are clamped to [0,1].
 * - LM_ERR_UNSUPPORTED: no EXR/PNG writer in this OpenImageIO, or a deep image.
 *
 * Usage:
 *     img_write_desc d = {.path = "out.exr", .width = w, .height = h,
 *                         .channels = 3, .pixels = rgb};
 *     if (img_write(&d, &err) != LM_OK) fprintf(stderr, "%s\n", err.msg);
 *
 * Does NOT do: tone mapping (see tonemap.h), colour management, resizing.
 */
#ifndef LUMESH_IMAGE_H
#define LUMESH_IMAGE_H

#include <stdint.h>
#include "src/base/util.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum img_format {
    IMG_FORMAT_FROM_EXTENSION = 0, /* default: .exr -> float EXR, .png -> 8-bit PNG */
    IMG_FORMAT_EXR_FLOAT,          /* 32-bit float channels */
    IMG_FORMAT_PNG8,               /* 8-bit channels; float input is clamped to [0,1] and rounded,
                                      so tone map first */
    IMG_FORMAT_COUNT
} img_format;

typedef struct img_write_desc {
    const char *path;
    img_format format;                 /* 0: from the extension (.exr, .png) */
    int width, height;                 /* pixels, > 0 */
    int channels;                      /* 1..16 (PNG: 1..4) */
    const float *pixels;               /* width*height*channels floats; or NULL and pixels8 */
    const uint8_t *pixels8;            /* 8-bit input, PNG only */
    const char *const *channel_names;  /* NULL: R,G,B,A for 1..4 channels, else C0..Cn */
    const char *const *attributes;     /* NULL, or name, value, name, value, ..., NULL: string
                                          attributes of the EXR header (names "lumesh:...", values
                                          up to IMG_ATTRIBUTE_CAP − 1 bytes); PNG ignores them */
} img_write_desc;

lm_result img_write(const img_write_desc *desc, lm_error *err);

enum { IMG_ATTRIBUTE_CAP = 128, IMG_ATTRIBUTES_MAX = 8 };

typedef struct img_image {
    int width, height, channels;
    float *pixels;             /* width*height*channels, owned; free with img_free */
    char (*channel_names)[32]; /* channels entries, owned */
    int attribute_count;       /* the file's "lumesh:..." string attributes (img_write_desc.attributes), */
    char attributes[IMG_ATTRIBUTES_MAX][2][IMG_ATTRIBUTE_CAP]; /* name and value, cut to fit */
} img_image;

/* The value of attribute `name` of img, or NULL. */
const char *img_attribute(const img_image *img, const char *name);

/* Reads any format OpenImageIO knows, converted to float. */
lm_result img_read(const char *path, img_image *out, lm_error *err);
void img_free(img_image *img); /* zeroes *img; safe on a zeroed image */

#ifdef __cplusplus
}
#endif
#endif
