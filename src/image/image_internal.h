/* image_internal.h — what the image module's files share. Private to src/image/.
 *
 * OpenImageIO lives in a module of its own, lumesh_oiio.so, opened with dlopen
 * the first time an image is read, written or compared (image_module.c). Why:
 * Debian's libOpenImageIO links about 260 libraries (GDAL, OpenVDB, OpenCV,
 * Poppler, …) whose relocation and static constructors cost 131 MB of resident
 * memory and start-up time in every process that links it, while lumesh needs
 * it only to read and write image files (docs/memory.md). The module holds
 * image_oiio.cpp, compare_oiio.cpp, image_png.c, image_write.c and its own
 * copy of src/base/util.c, all hidden but for one entry point, IMG_OIIO_ENTRY.
 * PNGs are written by the program (image_png_write.c), EXRs by the module.
 */
#ifndef LUMESH_IMAGE_INTERNAL_H
#define LUMESH_IMAGE_INTERNAL_H

#include "src/base/util.h"
#include "src/image/compare.h"
#include "src/image/image.h"

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

/* The checks of img_write's descriptor (image_write.c, in the program and the
 * module): the format (from the extension when 0), size, channels, pixels and
 * channel names; sets *fmt and *count (values in the image). */
lm_result img_write_check(const img_write_desc *d, img_format *fmt, size_t *count, lm_error *err);


/* A checked descriptor of format IMG_FORMAT_PNG8 with count values, written by
 * the program (image_png_write.c; not in the module). */
lm_result img_png_write(const img_write_desc *d, size_t count, lm_error *err);

/* The module's implementations of img_write, img_read (image_oiio.cpp) and
 * cmp_oiio_compare (compare_oiio.cpp), with the same contracts. */
lm_result img_oiio_write(const img_write_desc *desc, lm_error *err);
lm_result img_oiio_read(const char *path, img_image *out, lm_error *err);
lm_result img_oiio_compare(const char *path_a, const char *path_b, cmp_oiio_result *out, lm_error *err);

/* What the module hands the program. The sizes are of the structures the two
 * sides pass to each other: a module from another build (other headers) is
 * refused rather than called with a different layout. */
#define IMG_OIIO_API_VERSION 1u
typedef struct img_oiio_api {
    unsigned version;                            /* IMG_OIIO_API_VERSION */
    unsigned sizes[4];                           /* IMG_OIIO_API_SIZES */
    lm_result (*write)(const img_write_desc *desc, lm_error *err);
    lm_result (*read)(const char *path, img_image *out, lm_error *err);
    lm_result (*compare)(const char *path_a, const char *path_b, cmp_oiio_result *out, lm_error *err);
} img_oiio_api;
#define IMG_OIIO_API_SIZES                                                                             \
    {(unsigned)sizeof(lm_error), (unsigned)sizeof(img_write_desc), (unsigned)sizeof(img_image),          \
     (unsigned)sizeof(cmp_oiio_result)}

/* The module's one exported symbol: `const img_oiio_api *IMG_OIIO_ENTRY(void)`. */
#define IMG_OIIO_ENTRY "lumesh_oiio_api"
#define IMG_OIIO_MODULE_FILE "lumesh_oiio.so"
typedef const img_oiio_api *(*img_oiio_entry_fn)(void);

#ifdef __cplusplus
}
#endif
#endif
