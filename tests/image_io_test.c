/* image_io_test.c — img_write / img_read: EXR and PNG round trips, argument
 * checking, and the guarantee that a failed write leaves neither a partial
 * file nor a temporary file and never touches an existing target. All files
 * go to a private directory under LUMESH_TMP_DIR. */
#define _XOPEN_SOURCE 700
#include "src/base/util.h"
#include "src/image/image.h"
#include "tests/test_util.h"

#include <dirent.h>
#include <errno.h>
#include <float.h>
#include <limits.h>
#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <unistd.h>

#ifndef LUMESH_TMP_DIR
#error "LUMESH_TMP_DIR must name a writable directory"
#endif

/* OpenImageIO 2.4's PNG reader creates a std::string inside its libpng read
 * callback, and libpng longjmps over it when a file is cut short, so reading
 * a truncated PNG leaks 31 bytes inside OpenImageIO. That one leak is
 * suppressed for sanitizer builds; the full-stack unwind is needed to see
 * the OpenImageIO frame (it is built without frame pointers). Both hooks are
 * inert without -fsanitize=address. */
const char *__asan_default_options(void);
const char *__lsan_default_suppressions(void);
const char *__asan_default_options(void)
{
    return "fast_unwind_on_malloc=0";
}
const char *__lsan_default_suppressions(void)
{
    return "leak:OpenImageIO_v2_4::PNGInput::PngReadCallback\n";
}

static char g_dir[PATH_MAX];

/* g_dir/name into buf. */
static const char *tmp_path(char *buf, size_t size, const char *name)
{
    int n = snprintf(buf, size, "%s/%s", g_dir, name);
    if (n < 0 || (size_t)n >= size) {
        fprintf(stderr, "path too long: %s/%s\n", g_dir, name);
        exit(2);
    }
    return buf;
}

static int file_exists(const char *path)
{
    struct stat st;
    return stat(path, &st) == 0;
}

/* Whole file into a malloc'ed buffer; NULL if it cannot be read. */
static unsigned char *slurp(const char *path, size_t *size)
{
    FILE *f = fopen(path, "rb");
    if (!f) return NULL;
    size_t cap = 0, len = 0;
    unsigned char *buf = NULL;
    for (;;) {
        if (!LM_GROW(buf, cap, len + 4096)) {
            free(buf);
            buf = NULL;
            break;
        }
        size_t got = fread(buf + len, 1, cap - len, f);
        len += got;
        if (len < cap) break;
    }
    fclose(f);
    *size = len;
    return buf;
}

static void write_bytes(const char *path, const unsigned char *data, size_t size)
{
    FILE *f = fopen(path, "wb");
    CHECK_MSG(f != NULL, "cannot create %s: %s", path, strerror(errno));
    if (!f) return;
    CHECK(fwrite(data, 1, size, f) == size);
    CHECK(fclose(f) == 0);
}

/* Deterministic pseudo-random bytes (xorshift32). */
static uint32_t g_rng = 0x12345678u;
static uint32_t rng_next(void)
{
    g_rng ^= g_rng << 13;
    g_rng ^= g_rng >> 17;
    g_rng ^= g_rng << 5;
    return g_rng;
}

/* Removes every regular file in g_dir and the test's sub-directory, so that a
 * previous run's leftovers cannot hide or fake anything. */
static void clean_dir(void)
{
    char p[PATH_MAX], q[PATH_MAX];
    tmp_path(p, sizeof p, "occupied.exr/keep.txt");
    unlink(p);
    rmdir(tmp_path(q, sizeof q, "occupied.exr"));
    DIR *d = opendir(g_dir);
    if (!d) return;
    struct dirent *e;
    while ((e = readdir(d)) != NULL) {
        if (e->d_name[0] == '.' && (e->d_name[1] == '\0' || strcmp(e->d_name, "..") == 0))
            continue;
        if (strlen(g_dir) + 1 + strlen(e->d_name) + 1 > sizeof p) continue;
        unlink(tmp_path(p, sizeof p, e->d_name));
    }
    closedir(d);
}

/* Number of entries in g_dir whose name contains ".tmp" (printed). */
static int count_temp_files(void)
{
    DIR *d = opendir(g_dir);
    CHECK_MSG(d != NULL, "cannot open %s: %s", g_dir, strerror(errno));
    if (!d) return -1;
    int n = 0;
    struct dirent *e;
    while ((e = readdir(d)) != NULL) {
        if (strstr(e->d_name, ".tmp")) {
            fprintf(stderr, "left behind: %s/%s\n", g_dir, e->d_name);
            ++n;
        }
    }
    closedir(d);
    return n;
}

static int bits_equal(float a, float b)
{
    return memcmp(&a, &b, sizeof a) == 0;
}

/* ---------------------------------------------------------------- EXR -- */

static void test_exr_round_trip(void)
{
    char path[PATH_MAX];
    tmp_path(path, sizeof path, "round.exr");
    enum { W = 7, H = 5, C = 3 };
    float px[W * H * C];
    for (int i = 0; i < W * H * C; ++i) px[i] = (float)i * 0.37f - 5.0f;
    const float special[] = {17.0f,  1e-30f,      FLT_TRUE_MIN, FLT_MIN,  -0.0f,   65504.0f,
                             1e30f,  FLT_MAX,     -3.5f,        0.1f,     1.0f / 3.0f, 1e-7f,
                             -1e-38f, 123456.789f, INFINITY,    -INFINITY};
    memcpy(px, special, sizeof special);

    img_write_desc d = {.path = path, .width = W, .height = H, .channels = C, .pixels = px};
    lm_error err = {{0}};
    lm_result r = img_write(&d, &err);
    CHECK_MSG(r == LM_OK, "%s", err.msg);

    img_image im = {0};
    r = img_read(path, &im, &err);
    CHECK_MSG(r == LM_OK, "%s", err.msg);
    if (r == LM_OK) {
        CHECK(im.width == W && im.height == H && im.channels == C);
        int mismatches = 0;
        for (int i = 0; i < W * H * C && im.channels == C; ++i)
            if (!bits_equal(im.pixels[i], px[i])) {
                if (mismatches++ < 5)
                    fprintf(stderr, "value %d: wrote %.9g, read %.9g\n", i, px[i], im.pixels[i]);
            }
        CHECK_MSG(mismatches == 0, "%d values differ", mismatches);
        CHECK(strcmp(im.channel_names[0], "R") == 0);
        CHECK(strcmp(im.channel_names[1], "G") == 0);
        CHECK(strcmp(im.channel_names[2], "B") == 0);
    }
    img_free(&im);
    CHECK(im.pixels == NULL && im.channel_names == NULL && im.width == 0 && im.height == 0 &&
          im.channels == 0);

    /* NaN survives as NaN. */
    float nanpx[4] = {NAN, 1.0f, -NAN, 2.0f};
    img_write_desc dn = {.path = path, .width = 2, .height = 1, .channels = 2, .pixels = nanpx};
    CHECK(img_write(&dn, &err) == LM_OK);
    r = img_read(path, &im, &err);
    CHECK_MSG(r == LM_OK, "%s", err.msg);
    if (r == LM_OK && im.channels == 2 && im.width == 2) {
        CHECK(isnan(im.pixels[0]) && im.pixels[1] == 1.0f);
        CHECK(isnan(im.pixels[2]) && im.pixels[3] == 2.0f);
    }
    img_free(&im);
}

static void test_exr_extension_and_format(void)
{
    char path[PATH_MAX];
    float px[4] = {0.25f, 8.0f, -1.0f, 1e-20f};
    lm_error err = {{0}};
    img_image im = {0};

    /* Upper-case extension. */
    tmp_path(path, sizeof path, "UPPER.EXR");
    img_write_desc d = {.path = path, .width = 2, .height = 2, .channels = 1, .pixels = px};
    CHECK_MSG(img_write(&d, &err) == LM_OK, "%s", err.msg);
    CHECK(img_read(path, &im, &err) == LM_OK);
    CHECK(im.channels == 1 && strcmp(im.channel_names[0], "R") == 0);
    CHECK(im.channels == 1 && bits_equal(im.pixels[3], 1e-20f));
    img_free(&im);

    /* An explicit format needs no extension; the reader goes by content. */
    tmp_path(path, sizeof path, "explicit.data");
    img_write_desc e = {.path = path, .format = IMG_FORMAT_EXR_FLOAT, .width = 4, .height = 1,
                        .channels = 1, .pixels = px};
    CHECK_MSG(img_write(&e, &err) == LM_OK, "%s", err.msg);
    lm_result r = img_read(path, &im, &err);
    CHECK_MSG(r == LM_OK, "%s", err.msg);
    CHECK(r != LM_OK || (im.width == 4 && im.height == 1 && bits_equal(im.pixels[1], 8.0f)));
    img_free(&im);
}

static void test_exr_channel_names(void)
{
    char path[PATH_MAX];
    lm_error err = {{0}};
    img_image im = {0};
    enum { W = 3, H = 2, C = 5 };
    float px[W * H * C];
    for (int i = 0; i < W * H * C; ++i) px[i] = (float)(i % C) * 10.0f + (float)(i / C);

    /* Not alphabetical, not RGBA-first: order and data must both survive. */
    const char *names[C] = {"Z", "diffuse.R", "A", "B", "x"};
    tmp_path(path, sizeof path, "named.exr");
    img_write_desc d = {.path = path, .width = W, .height = H, .channels = C, .pixels = px,
                        .channel_names = names};
    CHECK_MSG(img_write(&d, &err) == LM_OK, "%s", err.msg);
    lm_result r = img_read(path, &im, &err);
    CHECK_MSG(r == LM_OK, "%s", err.msg);
    if (r == LM_OK) {
        CHECK(im.channels == C);
        for (int c = 0; c < C && im.channels == C; ++c)
            CHECK_MSG(strcmp(im.channel_names[c], names[c]) == 0, "channel %d: %s, want %s", c,
                      im.channel_names[c], names[c]);
        int same = im.channels == C;
        for (int i = 0; i < W * H * C && same; ++i) same = bits_equal(im.pixels[i], px[i]);
        CHECK(same);
    }
    img_free(&im);

    /* Default names beyond four channels: C0..C4. */
    img_write_desc dd = {.path = path, .width = W, .height = H, .channels = C, .pixels = px};
    CHECK(img_write(&dd, &err) == LM_OK);
    r = img_read(path, &im, &err);
    CHECK(r == LM_OK && im.channels == C);
    for (int c = 0; r == LM_OK && c < C && im.channels == C; ++c) {
        char want[16];
        snprintf(want, sizeof want, "C%d", c);
        CHECK_MSG(strcmp(im.channel_names[c], want) == 0, "%s", im.channel_names[c]);
        CHECK(im.pixels[c] == px[c]);
    }
    img_free(&im);

    /* Four channels default to R,G,B,A. */
    img_write_desc d4 = {.path = path, .width = 1, .height = 1, .channels = 4, .pixels = px};
    CHECK(img_write(&d4, &err) == LM_OK);
    r = img_read(path, &im, &err);
    CHECK(r == LM_OK && im.channels == 4);
    if (r == LM_OK && im.channels == 4) {
        CHECK(strcmp(im.channel_names[0], "R") == 0 && strcmp(im.channel_names[3], "A") == 0);
        CHECK(im.pixels[0] == px[0] && im.pixels[3] == px[3]);
    }
    img_free(&im);

    /* A name of exactly 31 bytes is kept whole. */
    const char *longname = "abcdefghijklmnopqrstuvwxyz01234";
    const char *n1[1] = {longname};
    img_write_desc dl = {.path = path, .width = 1, .height = 1, .channels = 1, .pixels = px,
                         .channel_names = n1};
    CHECK_MSG(img_write(&dl, &err) == LM_OK, "%s", err.msg);
    r = img_read(path, &im, &err);
    CHECK(r == LM_OK && im.channels == 1 && strcmp(im.channel_names[0], longname) == 0);
    img_free(&im);
}

/* The temporary name is shortened when the target's name is near NAME_MAX. */
static void test_long_file_name(void)
{
    char name[256], path[PATH_MAX];
    memset(name, 'n', 251);
    memcpy(name + 251, ".exr", 5); /* 255 bytes */
    if (strlen(g_dir) + 1 + strlen(name) >= sizeof path) return;
    tmp_path(path, sizeof path, name);
    float px[3] = {1.0f, 2.0f, 3.0f};
    img_write_desc d = {.path = path, .width = 1, .height = 1, .channels = 3, .pixels = px};
    lm_error err = {{0}};
    CHECK_MSG(img_write(&d, &err) == LM_OK, "%s", err.msg);
    img_image im = {0};
    CHECK(img_read(path, &im, &err) == LM_OK && im.channels == 3 && im.pixels[2] == 3.0f);
    img_free(&im);
    unlink(path);
}

/* ---------------------------------------------------------------- PNG -- */

static void test_png_round_trip_8bit(void)
{
    char path[PATH_MAX];
    lm_error err = {{0}};
    enum { W = 16, H = 16 };
    uint8_t px[W * H * 4];
    for (int i = 0; i < W * H * 4; ++i) px[i] = (uint8_t)(i * 7 + i / 64);
    /* Alpha 0 and partial alpha must not disturb the colour (no premultiplication). */
    px[3] = 0;
    px[7] = 1;
    px[11] = 128;
    px[0] = 200;
    px[4] = 255;

    for (int c = 1; c <= 4; ++c) {
        tmp_path(path, sizeof path, c == 4 ? "rgba8.png" : c == 3 ? "rgb8.png" : "gray8.png");
        /* Build a c-channel image from the first c bytes of each pixel. */
        uint8_t in[W * H * 4];
        for (int p = 0; p < W * H; ++p)
            for (int k = 0; k < c; ++k) in[p * c + k] = px[p * 4 + k];
        img_write_desc d = {.path = path, .width = W, .height = H, .channels = c, .pixels8 = in};
        lm_result r = img_write(&d, &err);
        CHECK_MSG(r == LM_OK, "%d channels: %s", c, err.msg);
        img_image im = {0};
        r = img_read(path, &im, &err);
        CHECK_MSG(r == LM_OK, "%d channels: %s", c, err.msg);
        if (r != LM_OK) continue;
        CHECK(im.width == W && im.height == H && im.channels == c);
        int bad = 0;
        for (int i = 0; i < W * H * c && im.channels == c; ++i) {
            float v = im.pixels[i] * 255.0f;
            if (fabsf(v - (float)in[i]) > 1e-3f) {
                if (bad++ < 5) fprintf(stderr, "%d ch, value %d: wrote %d, read %.6g\n", c, i, in[i], v);
            }
        }
        CHECK_MSG(bad == 0, "%d channels: %d values differ", c, bad);
        img_free(&im);
    }
}

static void test_png_float_clamp_round(void)
{
    char path[PATH_MAX];
    lm_error err = {{0}};
    tmp_path(path, sizeof path, "float.png");
    const float in[] = {0.5f, 2.0f, -1.0f, 0.0f,  1.0f,        NAN,    0.25f, 0.998f,
                        1.0f / 255.0f, 0.001f, INFINITY, -INFINITY, 0.0019607f, 0.5019608f, 0.75f};
    const int want[] = {128, 255, 0, 0, 255, 0, 64, 254, 1, 0, 255, 0, 0, 128, 191};
    enum { N = sizeof in / sizeof in[0] };
    _Static_assert(N == sizeof want / sizeof want[0], "tables differ");
    _Static_assert(N % 3 == 0, "RGB");
    img_write_desc d = {.path = path, .width = N / 3, .height = 1, .channels = 3, .pixels = in};
    lm_result r = img_write(&d, &err);
    CHECK_MSG(r == LM_OK, "%s", err.msg);
    img_image im = {0};
    r = img_read(path, &im, &err);
    CHECK_MSG(r == LM_OK, "%s", err.msg);
    if (r == LM_OK && im.channels == 3 && im.width == N / 3) {
        for (int i = 0; i < N; ++i) {
            int got = (int)lrintf(im.pixels[i] * 255.0f);
            CHECK_MSG(got == want[i], "%.9g -> %d, want %d", in[i], got, want[i]);
        }
    }
    img_free(&im);
}

/* -------------------------------------------------------- argument errors -- */

static void expect_invalid(const img_write_desc *d, const char *what)
{
    lm_error err = {{0}};
    lm_result r = img_write(d, &err);
    CHECK_MSG(r == LM_ERR_INVALID_ARG, "%s: got %d (%s)", what, (int)r, err.msg);
    CHECK_MSG(err.msg[0] != '\0', "%s: no message", what);
    CHECK_MSG(strchr(err.msg, '\n') == NULL, "%s: message has a newline", what);
    if (d && d->path) CHECK_MSG(strstr(err.msg, d->path) != NULL, "%s: message '%s' lacks the path", what, err.msg);
    /* Also without an error record. */
    CHECK(img_write(d, NULL) == r);
}

static void test_invalid_descriptors(void)
{
    char path[PATH_MAX], png[PATH_MAX];
    tmp_path(path, sizeof path, "invalid.exr");
    tmp_path(png, sizeof png, "invalid.png");
    float px[64] = {0};
    uint8_t px8[64] = {0};
    const img_write_desc ok = {.path = path, .width = 2, .height = 2, .channels = 3, .pixels = px};
    img_write_desc d;

    expect_invalid(NULL, "NULL descriptor");
    d = ok; d.path = NULL;                 expect_invalid(&d, "NULL path");
    d = ok; d.path = "";                   expect_invalid(&d, "empty path");
    d = ok; d.width = 0;                   expect_invalid(&d, "width 0");
    d = ok; d.height = -3;                 expect_invalid(&d, "negative height");
    d = ok; d.channels = 0;                expect_invalid(&d, "0 channels");
    d = ok; d.channels = 17;               expect_invalid(&d, "17 channels");
    d = ok; d.path = png; d.channels = 5;  expect_invalid(&d, "PNG with 5 channels");
    d = ok; d.pixels = NULL;               expect_invalid(&d, "no pixels");
    d = ok; d.pixels8 = px8;               expect_invalid(&d, "both pixel arrays");
    d = ok; d.pixels = NULL; d.pixels8 = px8; expect_invalid(&d, "8-bit pixels for EXR");
    d = ok; d.format = IMG_FORMAT_COUNT;   expect_invalid(&d, "format out of range");
    d = ok; d.format = (img_format)-1;     expect_invalid(&d, "negative format");
    /* Never dereferenced: the size check comes first. */
    d = ok; d.width = INT_MAX; d.height = INT_MAX; d.channels = 16;
    expect_invalid(&d, "size overflow");
    const char *dup[3] = {"R", "G", "R"};
    d = ok; d.channel_names = dup;         expect_invalid(&d, "duplicate channel names");
    const char *empty[3] = {"R", "", "B"};
    d = ok; d.channel_names = empty;       expect_invalid(&d, "empty channel name");
    const char *null_name[3] = {"R", NULL, "B"};
    d = ok; d.channel_names = null_name;   expect_invalid(&d, "NULL channel name");
    const char *too_long[3] = {"R", "abcdefghijklmnopqrstuvwxyz012345", "B"}; /* 32 bytes */
    d = ok; d.channel_names = too_long;    expect_invalid(&d, "channel name of 32 bytes");
    const char *ctrl[3] = {"R", "G\nX", "B"};
    d = ok; d.channel_names = ctrl;        expect_invalid(&d, "control character in a name");

    CHECK(!file_exists(path));
    CHECK(!file_exists(png));
}

static void test_unsupported_extension(void)
{
    const char *names[] = {"image.tif", "image", "image.exr.bak", "image.pngx", "image.", "x.jpg"};
    float px[3] = {0};
    for (size_t i = 0; i < sizeof names / sizeof names[0]; ++i) {
        char path[PATH_MAX];
        tmp_path(path, sizeof path, names[i]);
        img_write_desc d = {.path = path, .width = 1, .height = 1, .channels = 3, .pixels = px};
        lm_error err = {{0}};
        lm_result r = img_write(&d, &err);
        CHECK_MSG(r == LM_ERR_INVALID_ARG, "%s: got %d", names[i], (int)r);
        CHECK_MSG(strstr(err.msg, path) != NULL, "message '%s' lacks the path", err.msg);
        CHECK_MSG(strstr(err.msg, ".exr") && strstr(err.msg, ".png"),
                  "message '%s' lacks the supported extensions", err.msg);
        CHECK(!file_exists(path));
    }
    /* A dot in a directory name is not an extension. */
    char path[PATH_MAX];
    tmp_path(path, sizeof path, "dir.exr/image");
    img_write_desc d = {.path = path, .width = 1, .height = 1, .channels = 3, .pixels = px};
    CHECK(img_write(&d, NULL) == LM_ERR_INVALID_ARG);
}

/* ------------------------------------------------------------ I/O errors -- */

static void test_missing_directory(void)
{
    char dir[PATH_MAX], path[PATH_MAX];
    tmp_path(dir, sizeof dir, "no-such-dir");
    tmp_path(path, sizeof path, "no-such-dir/out.exr");
    float px[3] = {1, 2, 3};
    img_write_desc d = {.path = path, .width = 1, .height = 1, .channels = 3, .pixels = px};
    lm_error err = {{0}};
    lm_result r = img_write(&d, &err);
    CHECK_MSG(r == LM_ERR_IO, "got %d: %s", (int)r, err.msg);
    CHECK_MSG(strstr(err.msg, path) != NULL, "message '%s' lacks the path", err.msg);
    CHECK(!file_exists(path));
    CHECK(!file_exists(dir));

    tmp_path(path, sizeof path, "no-such-dir/out.png");
    d.path = path;
    r = img_write(&d, &err);
    CHECK_MSG(r == LM_ERR_IO, "got %d: %s", (int)r, err.msg);
    CHECK(strstr(err.msg, path) != NULL);
    CHECK(!file_exists(path));
}

/* Writes a small valid file at path and returns its bytes. */
static unsigned char *make_old_file(const char *path, size_t *size)
{
    float px[2 * 2 * 3];
    for (int i = 0; i < 12; ++i) px[i] = (float)i / 11.0f;
    img_write_desc d = {.path = path, .width = 2, .height = 2, .channels = 3, .pixels = px};
    lm_error err = {{0}};
    CHECK_MSG(img_write(&d, &err) == LM_OK, "%s", err.msg);
    unsigned char *b = slurp(path, size);
    CHECK(b != NULL && *size > 0);
    return b;
}

static void check_unchanged(const char *path, const unsigned char *old, size_t old_size,
                            const char *what)
{
    size_t size = 0;
    unsigned char *now = slurp(path, &size);
    CHECK_MSG(now != NULL, "%s: %s is gone", what, path);
    CHECK_MSG(now && size == old_size && memcmp(now, old, size) == 0, "%s: %s was changed", what,
              path);
    free(now);
}

static void test_failed_write_keeps_old_file(void)
{
    const char *exts[2] = {"exr", "png"};
    for (int k = 0; k < 2; ++k) {
        char name[32], path[PATH_MAX];
        snprintf(name, sizeof name, "keep.%s", exts[k]);
        tmp_path(path, sizeof path, name);
        size_t old_size = 0;
        unsigned char *old = make_old_file(path, &old_size);
        if (!old) continue;

        /* 1. A descriptor rejected before anything is written. */
        float px[4] = {0};
        img_write_desc bad = {.path = path, .width = 0, .height = 1, .channels = 3, .pixels = px};
        CHECK(img_write(&bad, NULL) == LM_ERR_INVALID_ARG);
        check_unchanged(path, old, old_size, "invalid descriptor");

        /* 2. A genuine failure while the bytes go to disk: the file size
         * limit makes write() fail with EFBIG part-way through a large,
         * incompressible image. */
        enum { W = 128, H = 128, C = 4 };
        float *noise = malloc(sizeof(float) * W * H * C);
        CHECK(noise != NULL);
        if (noise) {
            for (int i = 0; i < W * H * C; ++i) noise[i] = (float)(rng_next() >> 8) / 16777216.0f;
            struct rlimit saved, small;
            CHECK(getrlimit(RLIMIT_FSIZE, &saved) == 0);
            small = saved;
            small.rlim_cur = 8192;
            void (*old_handler)(int) = signal(SIGXFSZ, SIG_IGN);
            if (saved.rlim_max == RLIM_INFINITY || saved.rlim_max >= small.rlim_cur) {
                CHECK(setrlimit(RLIMIT_FSIZE, &small) == 0);
                img_write_desc big = {.path = path, .width = W, .height = H, .channels = C,
                                      .pixels = noise};
                lm_error err = {{0}};
                lm_result r = img_write(&big, &err);
                CHECK(setrlimit(RLIMIT_FSIZE, &saved) == 0);
                CHECK_MSG(r == LM_ERR_IO, "%s over the size limit: got %d (%s)", exts[k], (int)r,
                          err.msg);
                CHECK_MSG(strstr(err.msg, path) != NULL, "message '%s' lacks the path", err.msg);
                check_unchanged(path, old, old_size, "write past the file size limit");

                /* The same write succeeds without the limit: it was the disk. */
                r = img_write(&big, &err);
                CHECK_MSG(r == LM_OK, "%s", err.msg);
                size_t now_size = 0;
                unsigned char *now = slurp(path, &now_size);
                CHECK(now && now_size > 8192);
                free(now);
            }
            signal(SIGXFSZ, old_handler);
            free(noise);
        }
        free(old);
    }

    /* 3. rename() fails after the whole temporary file was written: the
     * target name is taken by a non-empty directory. */
    char dir[PATH_MAX], inner[PATH_MAX];
    tmp_path(dir, sizeof dir, "occupied.exr");
    tmp_path(inner, sizeof inner, "occupied.exr/keep.txt");
    CHECK(mkdir(dir, 0777) == 0 || errno == EEXIST);
    const unsigned char note[] = "do not replace me";
    write_bytes(inner, note, sizeof note);
    float px[3] = {1, 2, 3};
    img_write_desc d = {.path = dir, .width = 1, .height = 1, .channels = 3, .pixels = px};
    lm_error err = {{0}};
    lm_result r = img_write(&d, &err);
    CHECK_MSG(r == LM_ERR_IO, "got %d (%s)", (int)r, err.msg);
    CHECK_MSG(strstr(err.msg, dir) != NULL, "message '%s' lacks the path", err.msg);
    check_unchanged(inner, note, sizeof note, "rename onto a directory");
    struct stat st;
    CHECK(stat(dir, &st) == 0 && S_ISDIR(st.st_mode));
}

/* ---------------------------------------------------------------- reading -- */

static void check_read_fails(const char *path, const char *what)
{
    img_image im = {.width = 99, .height = 99, .channels = 99};
    lm_error err = {{0}};
    lm_result r = img_read(path, &im, &err);
    CHECK_MSG(r == LM_ERR_IO || r == LM_ERR_BAD_INPUT, "%s: got %d (%s)", what, (int)r, err.msg);
    CHECK_MSG(strstr(err.msg, path) != NULL, "%s: message '%s' lacks the path", what, err.msg);
    CHECK_MSG(strchr(err.msg, '\n') == NULL, "%s: message has a newline", what);
    CHECK(im.pixels == NULL && im.channel_names == NULL && im.width == 0 && im.height == 0 &&
          im.channels == 0);
    img_free(&im);
    CHECK(img_read(path, &im, NULL) == r);
    img_free(&im);
}

static void test_read_errors(void)
{
    char path[PATH_MAX];
    lm_error err = {{0}};
    img_image im = {0};

    tmp_path(path, sizeof path, "missing.exr");
    CHECK(img_read(path, &im, &err) == LM_ERR_IO);
    check_read_fails(path, "missing file");

    /* Random bytes under image names. */
    unsigned char junk[4096];
    for (size_t i = 0; i < sizeof junk; ++i) junk[i] = (unsigned char)(rng_next() >> 24);
    tmp_path(path, sizeof path, "x.exr");
    write_bytes(path, junk, sizeof junk);
    check_read_fails(path, "garbage .exr");
    tmp_path(path, sizeof path, "x.png");
    write_bytes(path, junk, sizeof junk);
    check_read_fails(path, "garbage .png");

    /* The EXR magic number followed by garbage. */
    junk[0] = 0x76; junk[1] = 0x2f; junk[2] = 0x31; junk[3] = 0x01;
    junk[4] = 2; junk[5] = 0; junk[6] = 0; junk[7] = 0;
    tmp_path(path, sizeof path, "magic.exr");
    write_bytes(path, junk, sizeof junk);
    check_read_fails(path, "EXR magic then garbage");

    /* The PNG signature followed by garbage. */
    const unsigned char sig[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
    memcpy(junk, sig, sizeof sig);
    tmp_path(path, sizeof path, "magic.png");
    write_bytes(path, junk, sizeof junk);
    check_read_fails(path, "PNG signature then garbage");

    /* Empty file. */
    tmp_path(path, sizeof path, "empty.exr");
    write_bytes(path, junk, 0);
    check_read_fails(path, "empty file");

    /* Valid files cut short. */
    const char *trunc_src[2] = {"round.exr", "rgba8.png"};
    for (int k = 0; k < 2; ++k) {
        char src[PATH_MAX];
        tmp_path(src, sizeof src, trunc_src[k]);
        size_t size = 0;
        unsigned char *b = slurp(src, &size);
        CHECK(b != NULL && size > 64);
        if (!b) continue;
        tmp_path(path, sizeof path, k == 0 ? "cut.exr" : "cut.png");
        write_bytes(path, b, size / 2);
        free(b);
        /* A reader may return partial data or fail; it must not crash and a
         * failure must carry a message. */
        lm_result r = img_read(path, &im, &err);
        if (r != LM_OK)
            CHECK_MSG(strstr(err.msg, path) != NULL, "'%s' lacks the path", err.msg);
        else
            fprintf(stderr, "note: %s read without error\n", path);
        img_free(&im);
    }

    /* A directory. */
    CHECK(img_read(g_dir, &im, &err) == LM_ERR_IO);
    check_read_fails(g_dir, "directory");

    /* Arguments. */
    CHECK(img_read(NULL, &im, &err) == LM_ERR_INVALID_ARG);
    CHECK(img_read("", &im, &err) == LM_ERR_INVALID_ARG);
    CHECK(img_read(path, NULL, &err) == LM_ERR_INVALID_ARG);
    img_free(NULL);
    img_image zero = {0};
    img_free(&zero);
    img_free(&zero);
    CHECK(zero.pixels == NULL);
}

int main(void)
{
    int n = snprintf(g_dir, sizeof g_dir, "%s/image_io_test.d", LUMESH_TMP_DIR);
    if (n < 0 || (size_t)n >= sizeof g_dir) return 2;
    if (mkdir(g_dir, 0777) != 0 && errno != EEXIST) {
        fprintf(stderr, "cannot create %s: %s\n", g_dir, strerror(errno));
        return 2;
    }
    clean_dir();

    test_exr_round_trip();
    test_exr_extension_and_format();
    test_exr_channel_names();
    test_long_file_name();
    test_png_round_trip_8bit();
    test_png_float_clamp_round();
    test_invalid_descriptors();
    test_unsupported_extension();
    test_missing_directory();
    test_failed_write_keeps_old_file();
    test_read_errors();

    int left = count_temp_files();
    CHECK_MSG(left == 0, "%d temporary files left in %s", left, g_dir);
    return test_finish("image_io_test");
}
