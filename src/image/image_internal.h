/* image_internal.h — what the image module's files share. Private to src/image/. */
#ifndef LUMESH_IMAGE_INTERNAL_H
#define LUMESH_IMAGE_INTERNAL_H

#include "src/base/util.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Checks a PNG's framing before libpng reads it (image_png.c): LM_OK for a file
 * that is not a PNG or whose chunks are whole (each inside the file, its CRC
 * right, IEND reached); LM_ERR_BAD_INPUT with one line naming the file and the
 * chunk otherwise. Why: libpng prints its own errors to stderr (OpenImageIO
 * leaves its default handler in place), and OpenImageIO 2.4 leaks a string on a
 * truncated file, both found by fuzzing (docs/robustness.md). */
lm_result img_check_png(const char *path, lm_error *err);

#ifdef __cplusplus
}
#endif
#endif
