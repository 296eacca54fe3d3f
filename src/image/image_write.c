/* image_write.c — what every image write does whatever encodes it: the
 * descriptor's checks (image_internal.h; the file's atomic replacement is
 * lm_write_file, src/base/util.h).
 * Compiled into the program and into the OpenImageIO module, so that both
 * encoders (PNG in the program, EXR in the module) check and write alike. */
#define _POSIX_C_SOURCE 200809L /* fsync, O_CLOEXEC, PATH_MAX and NAME_MAX through limits.h */
#include <limits.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "src/image/image_internal.h"

enum { MAX_WRITE_CHANNELS = 16, MAX_PNG_CHANNELS = 4, CHANNEL_NAME_CAP = 32 };

static const char *format_label(img_format f) { return f == IMG_FORMAT_PNG8 ? "PNG" : "EXR"; }

/* Whether path's extension (after the last '.' of its last component) is ext,
 * ignoring ASCII case. */
static int has_ext(const char *path, const char *ext)
{
    const char *slash = strrchr(path, '/'), *dot = strrchr(path, '.');
    if (!dot || (slash && dot < slash)) return 0;
    const char *p = dot + 1;
    size_t i = 0;
    for (; p[i] && ext[i]; ++i) {
        char c = p[i];
        if (c >= 'A' && c <= 'Z') c = (char)(c - 'A' + 'a');
        if (c != ext[i]) return 0;
    }
    return p[i] == '\0' && ext[i] == '\0';
}

static lm_result check_channel_names(const img_write_desc *d, lm_error *err)
{
    for (int i = 0; d->channel_names && i < d->channels; ++i) {
        const char *n = d->channel_names[i];
        if (!n || !n[0]) return lm_fail(err, LM_ERR_INVALID_ARG, "%s: channel %d has no name", d->path, i);
        if (strlen(n) >= CHANNEL_NAME_CAP)
            return lm_fail(err, LM_ERR_INVALID_ARG, "%s: channel name \"%.40s...\" is longer than %d bytes", d->path,
                           n, CHANNEL_NAME_CAP - 1);
        for (const char *q = n; *q; ++q)
            if ((unsigned char)*q < 0x20 || *q == 0x7f)
                return lm_fail(err, LM_ERR_INVALID_ARG, "%s: channel %d name contains a control character", d->path,
                               i);
        for (int j = 0; j < i; ++j)
            if (strcmp(n, d->channel_names[j]) == 0)
                return lm_fail(err, LM_ERR_INVALID_ARG, "%s: channel name \"%s\" is used twice", d->path, n);
    }
    return LM_OK;
}

lm_result img_write_check(const img_write_desc *d, img_format *fmt, size_t *count, lm_error *err)
{
    if (!d) return lm_fail(err, LM_ERR_INVALID_ARG, "img_write: no descriptor");
    if (!d->path || !d->path[0]) return lm_fail(err, LM_ERR_INVALID_ARG, "img_write: no output path");
    const char *path = d->path;
    /* A caller may store any int in the enum: look at the value before using it. */
    int fv = (int)d->format;
    if (fv < 0 || fv >= (int)IMG_FORMAT_COUNT)
        return lm_fail(err, LM_ERR_INVALID_ARG, "%s: unknown image format %d", path, fv);
    img_format f = (img_format)fv;
    if (f == IMG_FORMAT_FROM_EXTENSION) {
        if (has_ext(path, "exr"))
            f = IMG_FORMAT_EXR_FLOAT;
        else if (has_ext(path, "png"))
            f = IMG_FORMAT_PNG8;
        else
            return lm_fail(err, LM_ERR_INVALID_ARG, "%s: unsupported image file extension (supported: .exr, .png)",
                           path);
    }
    if (d->width <= 0 || d->height <= 0)
        return lm_fail(err, LM_ERR_INVALID_ARG, "%s: invalid image size %dx%d", path, d->width, d->height);
    int max_ch = f == IMG_FORMAT_PNG8 ? MAX_PNG_CHANNELS : MAX_WRITE_CHANNELS;
    if (d->channels < 1 || d->channels > max_ch)
        return lm_fail(err, LM_ERR_INVALID_ARG, "%s: %d channels; %s takes 1 to %d", path, d->channels,
                       format_label(f), max_ch);
    /* width*height*channels floats must be addressable (and fit a ptrdiff_t). */
    size_t w = (size_t)d->width, h = (size_t)d->height, c = (size_t)d->channels;
    size_t limit = (size_t)PTRDIFF_MAX / sizeof(float);
    if (w > limit / h || w * h > limit / c)
        return lm_fail(err, LM_ERR_INVALID_ARG, "%s: image of %dx%dx%d values is too large", path, d->width,
                       d->height, d->channels);
    if ((d->pixels != NULL) == (d->pixels8 != NULL))
        return lm_fail(err, LM_ERR_INVALID_ARG, "%s: exactly one of pixels (float) and pixels8 (8-bit) must be given",
                       path);
    if (d->pixels8 && f != IMG_FORMAT_PNG8)
        return lm_fail(err, LM_ERR_INVALID_ARG, "%s: 8-bit pixels can only be written as PNG", path);
    lm_result r = check_channel_names(d, err);
    if (r != LM_OK) return r;
    *fmt = f;
    *count = w * h * c;
    return LM_OK;
}
