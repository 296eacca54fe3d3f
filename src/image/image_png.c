/* image_png.c — a PNG's chunk framing, checked before libpng reads it
 * (image_internal.h says why). A PNG is an 8-byte signature, then chunks of a
 * 4-byte big-endian length, a 4-letter type, the data and a CRC-32 of type and
 * data (PNG specification, section 5.3), ending with IEND. */
#include <pthread.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "src/image/image_internal.h"

enum { PNG_MAX_BYTES = 1 << 30 };

static uint32_t crc_table[256]; /* written once under crc_once, then only read */
static pthread_once_t crc_once = PTHREAD_ONCE_INIT;

static void make_crc_table(void)
{
    for (uint32_t i = 0; i < 256; ++i) {
        uint32_t c = i;
        for (int k = 0; k < 8; ++k) c = c & 1 ? 0xedb88320u ^ (c >> 1) : c >> 1;
        crc_table[i] = c;
    }
}

static uint32_t crc32_png(const unsigned char *p, size_t n)
{
    pthread_once(&crc_once, make_crc_table);
    uint32_t c = 0xffffffffu;
    for (size_t i = 0; i < n; ++i) c = crc_table[(c ^ p[i]) & 0xff] ^ (c >> 8);
    return c ^ 0xffffffffu;
}

static uint32_t be32(const unsigned char *p)
{
    return (uint32_t)p[0] << 24 | (uint32_t)p[1] << 16 | (uint32_t)p[2] << 8 | (uint32_t)p[3];
}

lm_result img_check_png(const char *path, lm_error *err)
{
    static const unsigned char signature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
    char *data = NULL;
    size_t size = 0;
    if (lm_read_file(path, PNG_MAX_BYTES, &data, &size, NULL) != LM_OK) return LM_OK; /* the reader will say */
    const unsigned char *p = (const unsigned char *)data;
    lm_result r = LM_OK;
    if (size < 8 || memcmp(p, signature, 8) != 0) goto done; /* not a PNG: the reader judges */
    size_t at = 8;
    for (int chunk = 1;; ++chunk) {
        if (size - at < 12) {
            r = lm_fail(err, LM_ERR_BAD_INPUT, "%s: cannot read image: broken PNG: the file ends before chunk %d "
                        "(truncated, no IEND)", path, chunk);
            break;
        }
        uint32_t len = be32(p + at);
        const unsigned char *type = p + at + 4;
        char name[5] = {0};
        for (int k = 0; k < 4; ++k) name[k] = (char)((type[k] >= 'A' && type[k] <= 'Z') || (type[k] >= 'a' && type[k] <= 'z') ? type[k] : '?');
        if (len > 0x7fffffffu || len > size - at - 12) {
            r = lm_fail(err, LM_ERR_BAD_INPUT, "%s: cannot read image: broken PNG: chunk %d ('%s') runs past the end "
                        "of the file (truncated)", path, chunk, name);
            break;
        }
        if (crc32_png(type, (size_t)len + 4) != be32(type + 4 + len)) {
            r = lm_fail(err, LM_ERR_BAD_INPUT, "%s: cannot read image: broken PNG: chunk %d ('%s') fails its CRC "
                        "(corrupted)", path, chunk, name);
            break;
        }
        at += (size_t)len + 12;
        if (memcmp(type, "IEND", 4) == 0) break;
    }
done:
    free(data);
    return r;
}
