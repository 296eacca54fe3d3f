/* image_png_write.c — 8-bit PNGs written by the program itself, with
 * stb_image_write (libstb-dev, header only), not by the OpenImageIO module.
 * Why: `render -o x.png` wrote its image last, after the GL session was gone but
 * with LLVM still mapped, and opening the module then (OpenImageIO and its ~260
 * libraries: OpenVDB alone 27 MB resident) set the command's peak: CornellBox-
 * Water at 640×480 215 MB, of it ~45 MB the module's libraries (docs/memory.md,
 * "PNG without the module"). EXR still goes through the module.
 * Same contract as img_write for PNG: the descriptor checked by
 * img_write_check, floats clamped to [0, 1] and rounded, the file encoded in
 * memory and then replaced atomically (lm_write_file). */
#include <stdlib.h>
#include <string.h>

#include "src/image/image_internal.h"

#if defined(__GNUC__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wconversion"
#pragma GCC diagnostic ignored "-Wsign-conversion"
#pragma GCC diagnostic ignored "-Wmissing-prototypes"
#pragma GCC diagnostic ignored "-Wmissing-declarations"
#pragma GCC diagnostic ignored "-Wcast-qual"
#pragma GCC diagnostic ignored "-Wdouble-promotion"
#pragma GCC diagnostic ignored "-Wunused-function"
#endif
#define STB_IMAGE_WRITE_IMPLEMENTATION
#define STBI_WRITE_NO_STDIO
#include <stb_image_write.h>
#if defined(__GNUC__)
#pragma GCC diagnostic pop
#endif

/* The encoded file, grown as stb hands it over; failed: out of memory. */
typedef struct png_buffer {
    unsigned char *data;
    size_t size, cap;
    int failed;
} png_buffer;

static void append(void *user, void *bytes, int n)
{
    png_buffer *b = user;
    if (b->failed || n <= 0) return;
    if (!LM_GROW(b->data, b->cap, b->size + (size_t)n)) {
        b->failed = 1;
        return;
    }
    memcpy(b->data + b->size, bytes, (size_t)n);
    b->size += (size_t)n;
}

lm_result img_png_write(const img_write_desc *d, size_t count, lm_error *err)
{
    const uint8_t *px = d->pixels8;
    uint8_t *bytes = NULL;
    if (!px) {
        bytes = malloc(count ? count : 1);
        if (!bytes) return lm_fail(err, LM_ERR_NO_MEMORY, "%s: out of memory for a %dx%d image", d->path, d->width, d->height);
        for (size_t i = 0; i < count; ++i) {
            float v = d->pixels[i];
            v = v > 0.0f ? (v < 1.0f ? v : 1.0f) : 0.0f; /* NaN fails both tests and ends at 0 */
            bytes[i] = (uint8_t)(v * 255.0f + 0.5f);
        }
        px = bytes;
    }
    png_buffer b = {0};
    /* stb takes the row stride as an int. */
    int ok = (size_t)d->width * (size_t)d->channels <= (size_t)INT32_MAX &&
             stbi_write_png_to_func(append, &b, d->width, d->height, d->channels, px, d->width * d->channels);
    free(bytes);
    lm_result r = LM_OK;
    if (b.failed)
        r = lm_fail(err, LM_ERR_NO_MEMORY, "%s: out of memory encoding PNG", d->path);
    else if (!ok || !b.size)
        r = lm_fail(err, LM_ERR_IO, "%s: cannot encode PNG (%dx%d, %d channels)", d->path, d->width, d->height,
                    d->channels);
    else
        r = lm_write_file(d->path, "png", b.data, b.size, err);
    free(b.data);
    return r;
}
