/* compare_test.c — cmp_compare and its OpenImageIO cross-check: identical
 * images, a hand-computed pair, agreement with ImageBufAlgo::compare on
 * random pairs, ΔE of known colours, the 99th percentile, size mismatch,
 * channels picked by name, NaN/Inf handling and the heat-map ramp.
 *
 * `compare_test --write-cli-images DIR` only writes the images the CLI tests
 * of compare_cli.cmake use (DIR/a.exr, DIR/b.exr: 4x3 RGB; DIR/small.exr:
 * 2x2) and exits; it is the ctest fixture those tests require. */
#define _POSIX_C_SOURCE 200809L
#include "src/base/tonemap.h"
#include "src/image/compare.h"
#include "src/image/image.h"
#include "tests/test_util.h"

#include <errno.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#ifndef LUMESH_TMP_DIR
#error "LUMESH_TMP_DIR must name a writable directory"
#endif

/* ---- helpers ---- */

static uint64_t g_rng = 0x9E3779B97F4A7C15ull;

/* Uniform in [0,1), deterministic (xorshift64*). */
static float rnd(void)
{
    g_rng ^= g_rng >> 12;
    g_rng ^= g_rng << 25;
    g_rng ^= g_rng >> 27;
    uint64_t x = g_rng * 0x2545F4914F6CDD1Dull;
    return (float)((double)(x >> 40) / (double)(1ull << 24));
}

/* A w x h image of ch channels, zeroed; names NULL: R,G,B,A / C0.. like img_write. */
static img_image make_image(int w, int h, int ch, const char *const *names)
{
    img_image img = {w, h, ch, NULL, NULL};
    img.pixels = calloc((size_t)w * (size_t)h * (size_t)ch, sizeof(float));
    img.channel_names = calloc((size_t)ch, sizeof img.channel_names[0]);
    if (!img.pixels || !img.channel_names) {
        fprintf(stderr, "out of memory\n");
        exit(2);
    }
    static const char *const rgba[4] = {"R", "G", "B", "A"};
    for (int c = 0; c < ch; ++c) {
        if (names)
            snprintf(img.channel_names[c], sizeof img.channel_names[c], "%s", names[c]);
        else if (ch <= 4)
            snprintf(img.channel_names[c], sizeof img.channel_names[c], "%s", rgba[c]);
        else
            snprintf(img.channel_names[c], sizeof img.channel_names[c], "C%d", c);
    }
    return img;
}

static float *px(img_image *img, int x, int y)
{
    return img->pixels + ((size_t)y * (size_t)img->width + (size_t)x) * (size_t)img->channels;
}

static void set_rgb(img_image *img, int x, int y, float r, float g, float b)
{
    float *p = px(img, x, y);
    p[0] = r;
    p[1] = g;
    p[2] = b;
}

static void tmp_path(const char *name, char *out, size_t n)
{
    int k = snprintf(out, n, "%s/%s", LUMESH_TMP_DIR, name);
    if (k < 0 || (size_t)k >= n) {
        fprintf(stderr, "path too long: %s/%s\n", LUMESH_TMP_DIR, name);
        exit(2);
    }
}

/* Writes img as a float EXR (with its channel names) to path. */
static int write_exr(const char *path, const img_image *img)
{
    const char *names[16];
    for (int c = 0; c < img->channels && c < 16; ++c) names[c] = img->channel_names[c];
    img_write_desc d = {.path = path, .format = IMG_FORMAT_EXR_FLOAT, .width = img->width,
                        .height = img->height, .channels = img->channels, .pixels = img->pixels,
                        .channel_names = names};
    lm_error err;
    lm_result r = img_write(&d, &err);
    CHECK_MSG(r == LM_OK, "writing %s: %s", path, err.msg);
    return r == LM_OK;
}

static double rel_diff(double a, double b)
{
    double m = fabs(a) > fabs(b) ? fabs(a) : fabs(b);
    return m == 0.0 ? 0.0 : fabs(a - b) / m;
}

/* Compares the two files both ways: img_read + cmp_compare, and OpenImageIO. */
static int compare_files(const char *pa, const char *pb, cmp_result *ours, cmp_oiio_result *oiio)
{
    img_image a = {0}, b = {0};
    lm_error err;
    int ok = 1;
    lm_result r = img_read(pa, &a, &err);
    CHECK_MSG(r == LM_OK, "%s", err.msg);
    if (r == LM_OK) r = img_read(pb, &b, &err);
    CHECK_MSG(r == LM_OK, "%s", err.msg);
    if (r == LM_OK) {
        cmp_desc d = {.name_a = pa, .name_b = pb};
        r = cmp_compare(&d, &a, &b, ours, NULL, &err);
        CHECK_MSG(r == LM_OK, "cmp_compare: %s", err.msg);
    }
    ok = r == LM_OK;
    r = cmp_oiio_compare(pa, pb, oiio, &err);
    CHECK_MSG(r == LM_OK, "cmp_oiio_compare: %s", err.msg);
    img_free(&a);
    img_free(&b);
    return ok && r == LM_OK;
}

/* ---- tests ---- */

static void test_identical(void)
{
    img_image a = make_image(16, 9, 3, NULL);
    for (size_t i = 0; i < 16 * 9 * 3; ++i) a.pixels[i] = 2.0f * rnd(); /* some above 1 */
    char pa[1024], pb[1024];
    tmp_path("compare_same_1.exr", pa, sizeof pa);
    tmp_path("compare_same_2.exr", pb, sizeof pb);
    write_exr(pa, &a);
    write_exr(pb, &a);

    cmp_result r;
    float de[16 * 9];
    lm_error err;
    CHECK(cmp_compare(NULL, &a, &a, &r, de, &err) == LM_OK);
    CHECK(r.rmse == 0.0 && r.relmse == 0.0 && r.mean_abs_error == 0.0 && r.max_abs_error == 0.0);
    CHECK(r.delta_e_mean == 0.0 && r.delta_e_p99 == 0.0 && r.delta_e_max == 0.0);
    CHECK(isinf(r.psnr) && r.psnr > 0);
    CHECK(r.pixels_compared == 16 * 9 && r.nonfinite_pixels == 0);
    CHECK(r.max_x == 0 && r.max_y == 0 && r.max_channel == 0);
    int all_zero = 1;
    for (int i = 0; i < 16 * 9; ++i) all_zero = all_zero && de[i] == 0.0f;
    CHECK(all_zero);

    /* Two files with the same pixels, each read by both readers. */
    cmp_oiio_result o;
    if (compare_files(pa, pb, &r, &o)) {
        CHECK(r.rmse == 0.0 && r.relmse == 0.0 && r.max_abs_error == 0.0);
        CHECK(r.delta_e_mean == 0.0 && r.delta_e_p99 == 0.0);
        CHECK(isinf(r.psnr) && r.psnr > 0);
        CHECK(o.rms_error == 0.0 && o.max_error == 0.0 && o.mean_error == 0.0);
        CHECK(isinf(o.psnr) && o.psnr > 0);
        CHECK(o.width == 16 && o.height == 9);
    }
    img_free(&a);
}

/* 2x2, reference grey 0.5; the image differs by +0.125 R at (1,0), -0.25 G
 * at (0,1), +0.375 B at (1,1) — all exact in binary. Over 4 pixels x 3
 * channels: Σd² = 0.21875, Σ|d| = 0.75. */
static void test_hand_pair(void)
{
    img_image a = make_image(2, 2, 3, NULL), b = make_image(2, 2, 3, NULL);
    for (int i = 0; i < 12; ++i) a.pixels[i] = b.pixels[i] = 0.5f;
    px(&a, 1, 0)[0] = 0.625f;
    px(&a, 0, 1)[1] = 0.25f;
    px(&a, 1, 1)[2] = 0.875f;
    cmp_result r;
    lm_error err;
    CHECK(cmp_compare(NULL, &a, &b, &r, NULL, &err) == LM_OK);
    const double mse = 0.21875 / 12.0;
    CHECK_NEAR(r.rmse, sqrt(mse), 1e-15);
    CHECK_NEAR(r.rmse, 0.13501543121683043, 1e-15);
    CHECK_NEAR(r.relmse, 0.21875 / 0.26 / 12.0, 1e-15); /* b² + 0.01 = 0.26 */
    CHECK_NEAR(r.psnr, 20.0 * log10(1.0 / sqrt(mse)), 1e-12);
    CHECK_NEAR(r.psnr, 17.39233184353274, 1e-12);
    CHECK(r.mean_abs_error == 0.0625);
    CHECK(r.max_abs_error == 0.375);
    CHECK(r.max_x == 1 && r.max_y == 1 && r.max_channel == 2);
    CHECK(r.width == 2 && r.height == 2 && r.pixels_compared == 4);

    /* relMSE uses the reference: swapping A and B changes it. */
    cmp_result s;
    CHECK(cmp_compare(NULL, &b, &a, &s, NULL, &err) == LM_OK);
    CHECK(s.rmse == r.rmse && s.max_abs_error == r.max_abs_error);
    double expect = (0.015625 / (0.625 * 0.625 + 0.01) + 0.0625 / (0.25 * 0.25 + 0.01) +
                     0.140625 / (0.875 * 0.875 + 0.01)) / 12.0;
    CHECK_NEAR(s.relmse, expect, 1e-15);

    /* A tie for the maximum: the first in row-major order, R before G before B. */
    px(&a, 1, 0)[2] = 0.875f; /* (1,0) B now also 0.375 off, before (1,1) */
    CHECK(cmp_compare(NULL, &a, &b, &r, NULL, &err) == LM_OK);
    CHECK(r.max_x == 1 && r.max_y == 0 && r.max_channel == 2);
    px(&a, 1, 0)[0] = 0.875f; /* R at (1,0) too: R comes first */
    CHECK(cmp_compare(NULL, &a, &b, &r, NULL, &err) == LM_OK);
    CHECK(r.max_x == 1 && r.max_y == 0 && r.max_channel == 0);
    img_free(&a);
    img_free(&b);
}

/* The acceptance check: RMSE and PSNR equal to OpenImageIO's on different images. */
static void test_oiio_agreement(void)
{
    const int w = 37, h = 23;
    char pa[1024], pb[1024];
    cmp_result r;
    cmp_oiio_result o;

    /* Values in [0,1]: the two PSNR conventions coincide. */
    img_image a = make_image(w, h, 3, NULL), b = make_image(w, h, 3, NULL);
    for (size_t i = 0; i < (size_t)w * h * 3; ++i) {
        b.pixels[i] = rnd();
        float v = b.pixels[i] + 0.2f * (rnd() - 0.5f);
        a.pixels[i] = v < 0.0f ? 0.0f : (v > 1.0f ? 1.0f : v);
    }
    tmp_path("compare_rand_a.exr", pa, sizeof pa);
    tmp_path("compare_rand_b.exr", pb, sizeof pb);
    if (write_exr(pa, &a) && write_exr(pb, &b) && compare_files(pa, pb, &r, &o)) {
        CHECK(r.rmse > 0.01);
        CHECK_MSG(rel_diff(r.rmse, o.rms_error) <= 1e-6, "RMSE ours %.9g, OIIO %.9g", r.rmse,
                  o.rms_error);
        CHECK_MSG(rel_diff(r.psnr, o.psnr) <= 1e-6, "PSNR ours %.9g, OIIO %.9g", r.psnr, o.psnr);
        CHECK(rel_diff(r.mean_abs_error, o.mean_error) <= 1e-6);
        CHECK(rel_diff(r.max_abs_error, o.max_error) <= 1e-6);
        CHECK(r.max_x == o.max_x && r.max_y == o.max_y && r.max_channel == o.max_channel);
        printf("random pair: RMSE %.9g (OIIO %.9g), PSNR %.9g dB (OIIO %.9g)\n", r.rmse,
               o.rms_error, r.psnr, o.psnr);
    }

    /* HDR values: RMSE still agrees; OpenImageIO's PSNR peak is the largest value. */
    float maxval = 1.0f;
    for (size_t i = 0; i < (size_t)w * h * 3; ++i) {
        b.pixels[i] = 4.0f * rnd();
        a.pixels[i] = b.pixels[i] * (0.9f + 0.2f * rnd());
        if (a.pixels[i] > maxval) maxval = a.pixels[i];
        if (b.pixels[i] > maxval) maxval = b.pixels[i];
    }
    tmp_path("compare_hdr_a.exr", pa, sizeof pa);
    tmp_path("compare_hdr_b.exr", pb, sizeof pb);
    if (write_exr(pa, &a) && write_exr(pb, &b) && compare_files(pa, pb, &r, &o)) {
        CHECK(rel_diff(r.rmse, o.rms_error) <= 1e-6);
        CHECK_NEAR(o.psnr - r.psnr, 20.0 * log10((double)maxval), 1e-5);
    }
    img_free(&a);

    /* Extra channels in another order: both sides pick R, G, B by name. */
    static const char *const odd[5] = {"stderr.R", "B", "samples", "G", "R"};
    a = make_image(w, h, 5, odd);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            const float *q = px(&b, x, y);
            float *p = px(&a, x, y);
            p[4] = q[0] * 0.5f;  /* R */
            p[3] = q[1];         /* G */
            p[1] = q[2] + 0.25f; /* B */
            p[0] = 100.0f;       /* stderr.R: would dominate if compared */
            p[2] = 1e6f;         /* samples */
        }
    tmp_path("compare_extra_a.exr", pa, sizeof pa);
    if (write_exr(pa, &a) && compare_files(pa, pb, &r, &o)) {
        CHECK(r.max_abs_error < 10.0);
        CHECK(rel_diff(r.rmse, o.rms_error) <= 1e-6);
        CHECK(rel_diff(r.max_abs_error, o.max_error) <= 1e-6);
    }
    img_free(&a);

    /* A grey image against an RGB one: the grey value on all three channels. */
    a = make_image(w, h, 1, (const char *const[]){"Y"});
    for (size_t i = 0; i < (size_t)w * h; ++i) a.pixels[i] = 2.0f * rnd();
    tmp_path("compare_grey_a.exr", pa, sizeof pa);
    if (write_exr(pa, &a) && compare_files(pa, pb, &r, &o)) {
        CHECK(rel_diff(r.rmse, o.rms_error) <= 1e-6);
        CHECK(rel_diff(r.mean_abs_error, o.mean_error) <= 1e-6);
    }
    img_free(&a);
    img_free(&b);
}

static double delta_e_1px(float ra, float ga, float ba, float rb, float gb, float bb, float exposure,
                          double *rmse)
{
    img_image a = make_image(1, 1, 3, NULL), b = make_image(1, 1, 3, NULL);
    set_rgb(&a, 0, 0, ra, ga, ba);
    set_rgb(&b, 0, 0, rb, gb, bb);
    cmp_desc d = {.exposure = exposure};
    cmp_result r;
    lm_error err;
    float de = -1.0f;
    CHECK(cmp_compare(&d, &a, &b, &r, &de, &err) == LM_OK);
    CHECK(r.delta_e_mean == de && r.delta_e_p99 == de && r.delta_e_max == de);
    if (rmse) *rmse = r.rmse;
    img_free(&a);
    img_free(&b);
    return de;
}

static void test_delta_e_known(void)
{
    /* sRGB red (L 53.24, a 80.09, b 67.20) against green (87.73, -86.18, 83.18). */
    CHECK_NEAR(delta_e_1px(1, 0, 0, 0, 1, 0, 0, NULL), 170.56, 0.05);
    /* 18% grey against black: L* = 116·0.18^(1/3) − 16. */
    CHECK_NEAR(delta_e_1px(0.18f, 0.18f, 0.18f, 0, 0, 0, 0, NULL), 49.4961, 0.01);
    /* Linear 0.5 against white: 100 − L*(0.5). */
    double rmse = 0;
    CHECK_NEAR(delta_e_1px(0.5f, 0.5f, 0.5f, 1, 1, 1, 0, &rmse), 23.9307, 0.01);
    CHECK_NEAR(rmse, 0.5, 1e-12);
    /* One stop up both saturate to white: no visible difference, same RMSE. */
    CHECK_NEAR(delta_e_1px(0.5f, 0.5f, 0.5f, 1, 1, 1, 1.0f, &rmse), 0.0, 1e-4);
    CHECK_NEAR(rmse, 0.5, 1e-12);
    /* One stop down, 0.25 against 0.5: L*(0.5) − L*(0.25). */
    double l50 = 116.0 * cbrt(0.5) - 16.0, l25 = 116.0 * cbrt(0.25) - 16.0;
    CHECK_NEAR(delta_e_1px(0.5f, 0.5f, 0.5f, 1, 1, 1, -1.0f, NULL), l50 - l25, 0.01);
    /* The same path as tonemap.h, by hand. */
    float la[3], lb[3], da[3], db[3];
    const float ca[3] = {0.3f, 0.6f, 0.1f}, cb[3] = {0.2f, 0.5f, 0.4f};
    tm_desc tm = {.exposure = 0.5f};
    tm_to_display(&tm, ca, da);
    tm_to_display(&tm, cb, db);
    tm_display_to_lab(da, la);
    tm_display_to_lab(db, lb);
    CHECK(delta_e_1px(0.3f, 0.6f, 0.1f, 0.2f, 0.5f, 0.4f, 0.5f, NULL) == tm_delta_e(la, lb));
}

static int cmp_floats(const void *pa, const void *pb)
{
    float a = *(const float *)pa, b = *(const float *)pb;
    return (a > b) - (a < b);
}

/* Type-7 quantile of sorted v, the definition in compare.h. */
static double quantile_sorted(const float *v, size_t n, double q)
{
    double h = q * (double)(n - 1);
    size_t k = (size_t)floor(h);
    if (k + 1 >= n) return v[n - 1];
    return v[k] + (h - (double)k) * ((double)v[k + 1] - v[k]);
}

static void shuffle(float *v, size_t n)
{
    for (size_t i = n; i > 1; --i) {
        size_t j = (size_t)(rnd() * (float)i);
        if (j >= i) j = i - 1;
        float t = v[i - 1];
        v[i - 1] = v[j];
        v[j] = t;
    }
}

static void test_percentile(void)
{
    float v[1000];
    /* 1..1000: h = 0.99·999 = 989.01, so 990 + 0.01·(991 − 990). */
    for (int i = 0; i < 1000; ++i) v[i] = (float)(i + 1);
    shuffle(v, 1000);
    CHECK_NEAR(cmp_percentile(v, 1000, 0.99), 990.01, 1e-9);
    /* 0..100: h = 99 exactly. */
    for (int i = 0; i <= 100; ++i) v[i] = (float)i;
    shuffle(v, 101);
    CHECK(cmp_percentile(v, 101, 0.99) == 99.0);
    CHECK(cmp_percentile(v, 101, 0.0) == 0.0);
    CHECK(cmp_percentile(v, 101, 1.0) == 100.0);
    CHECK(cmp_percentile(v, 101, 0.5) == 50.0);
    v[0] = 7.0f;
    CHECK(cmp_percentile(v, 1, 0.99) == 7.0);
    CHECK(isnan(cmp_percentile(v, 0, 0.99)));
    CHECK(isnan(cmp_percentile(v, 5, 1.5)));
    CHECK(isnan(cmp_percentile(v, 5, NAN)));
    /* Two values: 0.99 of the way. */
    v[0] = 10.0f;
    v[1] = 0.0f;
    CHECK_NEAR(cmp_percentile(v, 2, 0.99), 9.9, 1e-6);

    /* Selection against a full sort, with many ties and sorted/reversed input. */
    static float big[20011], ref[20011];
    const size_t sizes[] = {3, 17, 100, 1001, 4096, 20011};
    for (size_t s = 0; s < sizeof sizes / sizeof sizes[0]; ++s) {
        size_t n = sizes[s];
        for (int kind = 0; kind < 4; ++kind) {
            for (size_t i = 0; i < n; ++i) {
                if (kind == 0) big[i] = rnd();
                if (kind == 1) big[i] = (float)(int)(rnd() * 5.0f); /* 5 distinct values */
                if (kind == 2) big[i] = (float)i;
                if (kind == 3) big[i] = (float)(n - i);
            }
            memcpy(ref, big, n * sizeof *big);
            qsort(ref, n, sizeof *ref, cmp_floats);
            const double qs[] = {0.0, 0.25, 0.5, 0.9, 0.99, 1.0};
            for (size_t k = 0; k < sizeof qs / sizeof qs[0]; ++k) {
                double got = cmp_percentile(big, n, qs[k]);
                double want = quantile_sorted(ref, n, qs[k]);
                CHECK_MSG(got == want, "n %zu kind %d q %g: %.9g, want %.9g", n, kind, qs[k], got,
                          want);
            }
        }
    }

    /* Through cmp_compare: 100 pixels, one differs by ΔE d: h = 98.01 -> 0.01·d. */
    img_image a = make_image(10, 10, 3, NULL), b = make_image(10, 10, 3, NULL);
    for (int i = 0; i < 300; ++i) a.pixels[i] = b.pixels[i] = 0.2f;
    set_rgb(&a, 3, 7, 0.8f, 0.2f, 0.2f);
    cmp_result r;
    lm_error err;
    float de[100];
    CHECK(cmp_compare(NULL, &a, &b, &r, de, &err) == LM_OK);
    double d = de[7 * 10 + 3];
    CHECK(d > 10.0);
    CHECK_NEAR(r.delta_e_p99, 0.01 * d, 1e-9 * d);
    CHECK_NEAR(r.delta_e_mean, d / 100.0, 1e-9 * d);
    CHECK(r.delta_e_max == d);
    /* Two such pixels: sorted, v[98] = v[99] = d, so the 99th percentile is d. */
    set_rgb(&a, 0, 0, 0.8f, 0.2f, 0.2f);
    CHECK(cmp_compare(NULL, &a, &b, &r, de, &err) == LM_OK);
    CHECK_NEAR(r.delta_e_p99, d, 1e-9 * d);
    img_free(&a);
    img_free(&b);
}

static void test_size_mismatch(void)
{
    img_image a = make_image(4, 3, 3, NULL), b = make_image(2, 2, 3, NULL);
    cmp_desc d = {.name_a = "a.exr", .name_b = "b.exr"};
    cmp_result r;
    lm_error err;
    CHECK(cmp_compare(&d, &a, &b, &r, NULL, &err) == LM_ERR_BAD_INPUT);
    CHECK_MSG(strcmp(err.msg, "a.exr is 4x3 but the reference b.exr is 2x2") == 0, "%s", err.msg);
    CHECK(cmp_compare(NULL, &a, &b, &r, NULL, &err) == LM_ERR_BAD_INPUT);
    CHECK_MSG(strcmp(err.msg, "image A is 4x3 but the reference image B is 2x2") == 0, "%s",
              err.msg);

    char pa[1024], pb[1024];
    tmp_path("compare_size_a.exr", pa, sizeof pa);
    tmp_path("compare_size_b.exr", pb, sizeof pb);
    cmp_oiio_result o;
    if (write_exr(pa, &a) && write_exr(pb, &b)) {
        CHECK(cmp_oiio_compare(pa, pb, &o, &err) == LM_ERR_BAD_INPUT);
        CHECK_MSG(strstr(err.msg, "compare_size_a.exr is 4x3 but the reference") &&
                      strstr(err.msg, "compare_size_b.exr is 2x2"),
                  "%s", err.msg);
    }
    tmp_path("compare_no_such_file.exr", pb, sizeof pb);
    CHECK(cmp_oiio_compare(pa, pb, &o, &err) == LM_ERR_IO);
    CHECK(strstr(err.msg, "compare_no_such_file.exr: cannot open") != NULL);
    img_free(&a);
    img_free(&b);
}

static void test_channels_by_name(void)
{
    int idx[3];
    static const char *const odd[6] = {"samples", "stderr.R", "B", "stderr.G", "G", "R"};
    img_image a = make_image(3, 2, 6, odd);
    CHECK(cmp_rgb_channels(&a, idx) == CMP_CHANNELS_NAMED);
    CHECK(idx[0] == 5 && idx[1] == 4 && idx[2] == 2);
    static const char *const xyz[4] = {"X", "Y", "Z", "W"};
    img_image n = make_image(1, 1, 4, xyz);
    CHECK(cmp_rgb_channels(&n, idx) == CMP_CHANNELS_FIRST_THREE);
    CHECK(idx[0] == 0 && idx[1] == 1 && idx[2] == 2);
    img_free(&n);
    n = make_image(1, 1, 1, (const char *const[]){"Y"});
    CHECK(cmp_rgb_channels(&n, idx) == CMP_CHANNELS_GREY);
    CHECK(idx[0] == 0 && idx[1] == 0 && idx[2] == 0);
    img_free(&n);
    n = make_image(1, 1, 2, (const char *const[]){"Y", "A"});
    CHECK(cmp_rgb_channels(&n, idx) == CMP_CHANNELS_GREY);
    img_free(&n);
    n = make_image(1, 1, 3, (const char *const[]){"R", "G", "b"}); /* names are case-sensitive */
    CHECK(cmp_rgb_channels(&n, idx) == CMP_CHANNELS_FIRST_THREE);
    img_free(&n);
    CHECK(cmp_rgb_channels(NULL, idx) == CMP_CHANNELS_NONE);

    /* The reference renderer's layout against a plain RGB image: only R, G, B count. */
    img_image b = make_image(3, 2, 3, NULL);
    for (int y = 0; y < 2; ++y)
        for (int x = 0; x < 3; ++x) {
            float r = rnd(), g = rnd(), bl = rnd();
            set_rgb(&b, x, y, r, g, bl);
            float *p = px(&a, x, y);
            p[5] = r;
            p[4] = g;
            p[2] = bl;
            p[0] = 1000.0f; /* samples */
            p[1] = p[3] = NAN; /* stderr: not compared, so not "non-finite" either */
        }
    cmp_result r;
    lm_error err;
    CHECK(cmp_compare(NULL, &a, &b, &r, NULL, &err) == LM_OK);
    CHECK(r.rmse == 0.0 && r.nonfinite_pixels == 0 && r.pixels_compared == 6);
    /* Moved through an EXR file (which stores channels alphabetically). */
    char pa[1024], pb[1024];
    tmp_path("compare_named_a.exr", pa, sizeof pa);
    tmp_path("compare_named_b.exr", pb, sizeof pb);
    cmp_oiio_result o;
    px(&a, 2, 1)[4] += 0.5f; /* G at (2,1) */
    if (write_exr(pa, &a) && write_exr(pb, &b) && compare_files(pa, pb, &r, &o)) {
        CHECK(r.max_abs_error == 0.5 && r.max_x == 2 && r.max_y == 1 && r.max_channel == 1);
        CHECK(o.max_error == 0.5 && o.max_x == 2 && o.max_y == 1 && o.max_channel == 1);
        CHECK(rel_diff(r.rmse, o.rms_error) <= 1e-6);
    }
    img_free(&a);
    img_free(&b);
}

/* 5x1, reference 0.5 grey. Pixel 0: the image is +0.25 in R. Pixel 1: NaN in
 * the image. Pixel 2: +Inf in the reference. Pixel 3: both (−Inf, NaN).
 * Pixel 4: equal. Compared: pixels 0 and 4, 6 values. */
static void test_nonfinite(void)
{
    img_image a = make_image(5, 1, 3, NULL), b = make_image(5, 1, 3, NULL);
    for (int i = 0; i < 15; ++i) a.pixels[i] = b.pixels[i] = 0.5f;
    px(&a, 0, 0)[0] = 0.75f;
    px(&a, 1, 0)[1] = NAN;
    px(&b, 2, 0)[2] = INFINITY;
    px(&a, 3, 0)[0] = -INFINITY;
    px(&b, 3, 0)[1] = NAN;
    px(&a, 2, 0)[0] = 1000.0f; /* would be the maximum if pixel 2 counted */
    cmp_result r;
    lm_error err;
    float de[5];
    CHECK(cmp_compare(NULL, &a, &b, &r, de, &err) == LM_OK);
    CHECK(r.pixels_compared == 2 && r.nonfinite_pixels == 3);
    CHECK(r.nonfinite_a == 2 && r.nonfinite_b == 2);
    CHECK_NEAR(r.rmse, sqrt(0.0625 / 6.0), 1e-15);
    CHECK_NEAR(r.relmse, 0.0625 / 0.26 / 6.0, 1e-15);
    CHECK(r.max_abs_error == 0.25 && r.max_x == 0 && r.max_channel == 0);
    CHECK(isfinite(r.psnr) && isfinite(r.delta_e_mean) && isfinite(r.delta_e_p99));
    CHECK(de[0] > 0.0f && de[4] == 0.0f);
    CHECK(isnan(de[1]) && isnan(de[2]) && isnan(de[3]));
    CHECK_NEAR(r.delta_e_mean, de[0] / 2.0, 1e-6);

    /* Nothing left to compare. */
    for (int i = 0; i < 15; ++i) a.pixels[i] = NAN;
    CHECK(cmp_compare(NULL, &a, &b, &r, NULL, &err) == LM_ERR_BAD_INPUT);
    CHECK(strstr(err.msg, "no pixel has finite R, G and B") != NULL);
    CHECK(r.nonfinite_pixels == 5 && r.pixels_compared == 0);
    img_free(&a);
    img_free(&b);
}

static double luma(const uint8_t *c)
{
    return 0.2126 * tm_srgb_decode(c[0] / 255.0f) + 0.7152 * tm_srgb_decode(c[1] / 255.0f) +
           0.0722 * tm_srgb_decode(c[2] / 255.0f);
}

static void test_heatmap(void)
{
    float de[6] = {0.0f, -1.0f, 10.0f, 55.0f, NAN, INFINITY};
    uint8_t rgb[18];
    cmp_heatmap_rgb8(de, 6, rgb);
    CHECK(rgb[0] == 68 && rgb[1] == 1 && rgb[2] == 84);      /* viridis start */
    CHECK(memcmp(rgb + 3, rgb, 3) == 0);                      /* below 0: clamped */
    CHECK(rgb[6] == 253 && rgb[7] == 231 && rgb[8] == 37);   /* ΔE 10: viridis end */
    CHECK(memcmp(rgb + 9, rgb + 6, 3) == 0);                  /* above: clamped */
    CHECK(rgb[12] == 255 && rgb[13] == 0 && rgb[14] == 255); /* left out: magenta */
    CHECK(memcmp(rgb + 15, rgb + 6, 3) == 0);
    /* Perceptually ordered: luminance rises with ΔE over the scale. */
    float ramp[101];
    uint8_t out[303];
    for (int i = 0; i <= 100; ++i) ramp[i] = 0.1f * (float)i;
    cmp_heatmap_rgb8(ramp, 101, out);
    int rising = 1;
    for (int i = 1; i <= 100; ++i) rising = rising && luma(out + 3 * i) >= luma(out + 3 * (i - 1));
    CHECK(rising);
    CHECK(luma(out + 300) > 10.0 * luma(out));
}

static void test_invalid(void)
{
    img_image a = make_image(2, 2, 3, NULL), empty = {0};
    cmp_result r;
    lm_error err;
    CHECK(cmp_compare(NULL, &a, &a, NULL, NULL, &err) == LM_ERR_INVALID_ARG);
    CHECK(cmp_compare(NULL, NULL, &a, &r, NULL, &err) == LM_ERR_INVALID_ARG);
    CHECK(cmp_compare(NULL, &a, &empty, &r, NULL, &err) == LM_ERR_INVALID_ARG);
    cmp_desc d = {.exposure = NAN};
    CHECK(cmp_compare(&d, &a, &a, &r, NULL, &err) == LM_ERR_INVALID_ARG);
    CHECK(cmp_compare(NULL, &a, &a, &r, NULL, NULL) == LM_OK); /* err is optional */
    cmp_oiio_result o;
    CHECK(cmp_oiio_compare(NULL, "x.exr", &o, &err) == LM_ERR_INVALID_ARG);
    CHECK(cmp_oiio_compare("x.exr", "y.exr", NULL, &err) == LM_ERR_INVALID_ARG);
    /* Not an image. */
    char bad[1024];
    test_write_file("compare_not_an_image.exr", "this is not an EXR file\n", bad, sizeof bad);
    CHECK(cmp_oiio_compare(bad, bad, &o, &err) == LM_ERR_BAD_INPUT);
    CHECK(strstr(err.msg, "compare_not_an_image.exr") != NULL);
    img_free(&a);
}

/* ---- the CLI tests' images ---- */

static int write_cli_images(const char *dir)
{
    if (mkdir(dir, 0777) != 0 && errno != EEXIST) {
        fprintf(stderr, "compare_test: cannot create %s: %s\n", dir, strerror(errno));
        return 1;
    }
    img_image a = make_image(4, 3, 3, NULL), b = make_image(4, 3, 3, NULL),
              s = make_image(2, 2, 3, NULL);
    for (int i = 0; i < 36; ++i) {
        b.pixels[i] = 0.05f * (float)i;   /* 0 .. 1.75 */
        a.pixels[i] = b.pixels[i] + 0.01f; /* everywhere a little brighter */
    }
    px(&a, 2, 1)[1] += 0.5f;
    for (int i = 0; i < 12; ++i) s.pixels[i] = 0.5f;
    const struct { const char *name; img_image *img; } files[] = {
        {"a.exr", &a}, {"b.exr", &b}, {"small.exr", &s}};
    int rc = 0;
    for (int k = 0; k < 3; ++k) {
        char path[4096];
        snprintf(path, sizeof path, "%s/%s", dir, files[k].name);
        img_write_desc d = {.path = path, .width = files[k].img->width,
                            .height = files[k].img->height, .channels = 3,
                            .pixels = files[k].img->pixels};
        lm_error err;
        if (img_write(&d, &err) != LM_OK) {
            fprintf(stderr, "compare_test: %s\n", err.msg);
            rc = 1;
        }
    }
    img_free(&a);
    img_free(&b);
    img_free(&s);
    if (rc == 0) printf("compare_test: wrote a.exr, b.exr, small.exr in %s\n", dir);
    return rc;
}

int main(int argc, char **argv)
{
    if (argc == 3 && strcmp(argv[1], "--write-cli-images") == 0) return write_cli_images(argv[2]);
    if (argc != 1) {
        fprintf(stderr, "usage: compare_test [--write-cli-images DIR]\n");
        return 2;
    }
    test_identical();
    test_hand_pair();
    test_oiio_agreement();
    test_delta_e_known();
    test_percentile();
    test_size_mismatch();
    test_channels_by_name();
    test_nonfinite();
    test_heatmap();
    test_invalid();
    return test_finish("compare_test");
}
