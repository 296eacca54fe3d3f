/* tonemap_test.c — sRGB transfer function, exposure and clamp, CIELAB and ΔE. */
#include "src/base/tonemap.h"
#include "tests/test_util.h"

#include <math.h>
#include <stdio.h>

static void test_srgb_known_values(void)
{
    CHECK(tm_srgb_encode(0.0f) == 0.0f);
    CHECK(tm_srgb_encode(1.0f) == 1.0f);
    CHECK(tm_srgb_decode(0.0f) == 0.0f);
    CHECK(tm_srgb_decode(1.0f) == 1.0f);
    CHECK_NEAR(tm_srgb_encode(0.5f), 0.7353569830524495, 1e-6);
    CHECK_NEAR(tm_srgb_decode(0.7353569830524495f), 0.5, 1e-6);
    CHECK_NEAR(tm_srgb_encode(0.18f), 0.46135612950044164, 1e-6);
    /* The linear segment. */
    CHECK_NEAR(tm_srgb_encode(0.001f), 0.01292, 1e-7);
    CHECK_NEAR(tm_srgb_decode(0.01292f), 0.001, 1e-8);
    /* Out of range input is clamped. */
    CHECK(tm_srgb_encode(-0.5f) == 0.0f);
    CHECK(tm_srgb_encode(3.0f) == 1.0f);
    CHECK(tm_srgb_decode(-0.5f) == 0.0f);
    CHECK(tm_srgb_decode(3.0f) == 1.0f);
    CHECK(tm_srgb_encode(NAN) == 0.0f);
    CHECK(tm_srgb_decode(NAN) == 0.0f);
}

static void test_srgb_boundary_continuity(void)
{
    /* Both pieces meet at 0.0031308 (encoded 0.04045). The standard's rounded
     * constants leave a step of about 3e-8 there, so only closeness is checked,
     * not strict ordering across the join. */
    const float b = 0.0031308f;
    float below = tm_srgb_encode(nextafterf(b, 0.0f));
    float at = tm_srgb_encode(b);
    float above = tm_srgb_encode(nextafterf(b, 1.0f));
    CHECK_NEAR(at, 0.04045, 1e-6);
    CHECK_NEAR(below, at, 1e-6);
    CHECK_NEAR(above, at, 1e-6);

    const float e = 0.04045f;
    float dbelow = tm_srgb_decode(nextafterf(e, 0.0f));
    float dat = tm_srgb_decode(e);
    float dabove = tm_srgb_decode(nextafterf(e, 1.0f));
    CHECK_NEAR(dat, 0.0031308, 1e-7);
    CHECK_NEAR(dbelow, dat, 1e-7);
    CHECK_NEAR(dabove, dat, 1e-7);
    CHECK(dbelow <= dat && dat <= dabove);
}

static void test_srgb_round_trip_and_monotonic(void)
{
    float prev = -1.0f;
    int monotonic = 1;
    double worst = 0.0;
    for (int i = 0; i <= 4096; ++i) {
        float x = (float)i / 4096.0f;
        float e = tm_srgb_encode(x);
        double d = fabs((double)tm_srgb_decode(e) - x);
        if (d > worst) worst = d;
        if (e < prev) monotonic = 0;
        prev = e;
    }
    CHECK_MSG(worst <= 1e-6, "worst |decode(encode(x)) - x| = %g", worst);
    CHECK(monotonic);
}

static void test_to_display(void)
{
    tm_desc none = {0};
    tm_desc plus1 = {.exposure = 1.0f};
    tm_desc minus2 = {.exposure = -2.0f};
    float out[3];

    const float lin[3] = {0.25f, 0.5f, 0.0f};
    tm_to_display(&none, lin, out);
    CHECK(out[0] == tm_srgb_encode(0.25f));
    CHECK(out[1] == tm_srgb_encode(0.5f));
    CHECK(out[2] == 0.0f);

    /* +1 stop doubles before the clamp: 0.25 -> 0.5, 0.5 -> 1.0, 0.75 -> 1.5 -> 1. */
    const float lin2[3] = {0.25f, 0.5f, 0.75f};
    tm_to_display(&plus1, lin2, out);
    CHECK(out[0] == tm_srgb_encode(0.5f));
    CHECK(out[1] == 1.0f);
    CHECK(out[2] == 1.0f);

    /* -2 stops quarters: 2.0 -> 0.5. */
    const float lin3[3] = {2.0f, 4.0f, 8.0f};
    tm_to_display(&minus2, lin3, out);
    CHECK(out[0] == tm_srgb_encode(0.5f));
    CHECK(out[1] == 1.0f);
    CHECK(out[2] == 1.0f);

    /* Emitters saturate, negatives clamp to black. */
    const float lin4[3] = {1000.0f, -3.0f, 1.0f};
    tm_to_display(&none, lin4, out);
    CHECK(out[0] == 1.0f);
    CHECK(out[1] == 0.0f);
    CHECK(out[2] == 1.0f);

    /* Non-finite input -> 0, whatever the exposure. */
    const float bad[3] = {NAN, INFINITY, -INFINITY};
    tm_to_display(&none, bad, out);
    CHECK(out[0] == 0.0f && out[1] == 0.0f && out[2] == 0.0f);
    tm_to_display(&plus1, bad, out);
    CHECK(out[0] == 0.0f && out[1] == 0.0f && out[2] == 0.0f);

    /* A NULL descriptor is exposure 0. */
    tm_to_display(NULL, lin, out);
    CHECK(out[1] == tm_srgb_encode(0.5f));
}

static void test_to_rgb8(void)
{
    tm_desc none = {0};
    tm_desc plus1 = {.exposure = 1.0f};

    /* RGBA input: alpha is skipped. Expected bytes: round(255 * sRGB(x)). */
    const float in[4 * 4] = {
        0.0f,  1.0f,  0.5f,  0.25f, /* 0, 255, 188 */
        0.18f, 0.02f, 0.001f, 1.0f, /* 118, 39, 3 */
        NAN,   INFINITY, 5.0f, 0.0f, /* 0, 0, 255 */
        -1.0f, 0.75f, 0.0031308f, 0.0f, /* 0, 225, 10 */
    };
    uint8_t out[12];
    for (int i = 0; i < 12; ++i) out[i] = 0xAA;
    tm_to_rgb8(&none, in, 4, 4, out);
    const uint8_t expect[12] = {0, 255, 188, 118, 39, 3, 0, 0, 255, 0, 225, 10};
    for (int i = 0; i < 12; ++i)
        CHECK_MSG(out[i] == expect[i], "byte %d: got %d, want %d", i, out[i], expect[i]);

    /* RGB input with +1 stop: 0.25 -> 0.5 -> 188; 0.5 -> 1 -> 255. */
    const float rgb[3] = {0.25f, 0.5f, 0.0f};
    uint8_t o3[3];
    tm_to_rgb8(&plus1, rgb, 3, 1, o3);
    CHECK(o3[0] == 188 && o3[1] == 255 && o3[2] == 0);

    /* One gray channel fills all three. */
    const float gray[2] = {0.5f, 1.0f};
    uint8_t og[6];
    tm_to_rgb8(&none, gray, 1, 2, og);
    CHECK(og[0] == 188 && og[1] == 188 && og[2] == 188);
    CHECK(og[3] == 255 && og[4] == 255 && og[5] == 255);

    /* count 0 writes nothing. */
    uint8_t untouched[3] = {7, 7, 7};
    tm_to_rgb8(&none, rgb, 3, 0, untouched);
    CHECK(untouched[0] == 7 && untouched[1] == 7 && untouched[2] == 7);
}

static void test_lab(void)
{
    float lab[3];
    const float white[3] = {1.0f, 1.0f, 1.0f};
    tm_display_to_lab(white, lab);
    CHECK_NEAR(lab[0], 100.0, 1e-3);
    CHECK_NEAR(lab[1], 0.0, 1e-3);
    CHECK_NEAR(lab[2], 0.0, 1e-3);

    const float black[3] = {0.0f, 0.0f, 0.0f};
    tm_display_to_lab(black, lab);
    CHECK_NEAR(lab[0], 0.0, 1e-4);
    CHECK_NEAR(lab[1], 0.0, 1e-4);
    CHECK_NEAR(lab[2], 0.0, 1e-4);

    /* Reference values for the sRGB primaries (D65, 2°). */
    const float red[3] = {1.0f, 0.0f, 0.0f};
    tm_display_to_lab(red, lab);
    CHECK_NEAR(lab[0], 53.24, 0.05);
    CHECK_NEAR(lab[1], 80.09, 0.05);
    CHECK_NEAR(lab[2], 67.20, 0.05);

    const float green[3] = {0.0f, 1.0f, 0.0f};
    tm_display_to_lab(green, lab);
    CHECK_NEAR(lab[0], 87.73, 0.05);
    CHECK_NEAR(lab[1], -86.18, 0.05);
    CHECK_NEAR(lab[2], 83.18, 0.05);

    const float blue[3] = {0.0f, 0.0f, 1.0f};
    tm_display_to_lab(blue, lab);
    CHECK_NEAR(lab[0], 32.30, 0.05);
    CHECK_NEAR(lab[1], 79.19, 0.05);
    CHECK_NEAR(lab[2], -107.86, 0.05);

    /* Mid gray: neutral, L* of display 0.5. */
    const float gray[3] = {0.5f, 0.5f, 0.5f};
    tm_display_to_lab(gray, lab);
    CHECK_NEAR(lab[0], 53.39, 0.05);
    CHECK_NEAR(lab[1], 0.0, 1e-3);
    CHECK_NEAR(lab[2], 0.0, 1e-3);

    /* A very dark colour: the linear segments of both the sRGB decode and the
     * Lab f(t); values from a double-precision reference computation. */
    const float dark[3] = {0.001f, 0.002f, 0.0f};
    tm_display_to_lab(dark, lab);
    CHECK_NEAR(lab[0], 0.114868, 1e-4);
    CHECK_NEAR(lab[1], -0.137601, 1e-4);
    CHECK_NEAR(lab[2], 0.169517, 1e-4);

    /* Out-of-range and NaN display values are clamped like the encoder. */
    const float wild[3] = {2.0f, NAN, -1.0f};
    float ref[3];
    const float clamped[3] = {1.0f, 0.0f, 0.0f};
    tm_display_to_lab(wild, lab);
    tm_display_to_lab(clamped, ref);
    CHECK(lab[0] == ref[0] && lab[1] == ref[1] && lab[2] == ref[2]);
}

static void test_delta_e(void)
{
    const float a[3] = {53.24f, 80.09f, 67.20f};
    const float b[3] = {50.0f, 70.0f, 60.0f};
    CHECK(tm_delta_e(a, a) == 0.0f);
    CHECK(tm_delta_e(b, b) == 0.0f);
    CHECK(tm_delta_e(a, b) == tm_delta_e(b, a));
    /* 3-4-12 -> 13 */
    const float p[3] = {10.0f, 0.0f, 0.0f};
    const float q[3] = {13.0f, 4.0f, 12.0f};
    CHECK_NEAR(tm_delta_e(p, q), 13.0, 1e-5);

    /* ΔE between displayed colours: white vs black is 100. */
    float lw[3], lb[3];
    const float white[3] = {1.0f, 1.0f, 1.0f};
    const float black[3] = {0.0f, 0.0f, 0.0f};
    tm_display_to_lab(white, lw);
    tm_display_to_lab(black, lb);
    CHECK_NEAR(tm_delta_e(lw, lb), 100.0, 1e-3);
}

/* tm_linear_to_lab's cube root (a guess and Newton steps) against libm's cbrt in
 * the same formula: every grey level from black to white and a spread of
 * colours, within 1e-5 in L*, a* and b*. */
static void test_lab_cube_root(void)
{
    static const double M[3][3] = {{0.4124564, 0.3575761, 0.1804375},
                                   {0.2126729, 0.7151522, 0.0721750},
                                   {0.0193339, 0.1191920, 0.9503041}};
    static const double white[3] = {0.95047, 1.0, 1.08883};
    const double d = 6.0 / 29.0;
    double worst = 0.0;
    for (int i = 0; i <= 20000; ++i) {
        const float lin[3] = {(float)(i % 101) / 100.0f, (float)(i % 37) / 36.0f, (float)i / 20000.0f};
        float lab[3];
        tm_linear_to_lab(&(tm_desc){0}, lin, lab);
        double f[3];
        for (int r = 0; r < 3; ++r) {
            double t = (M[r][0] * lin[0] + M[r][1] * lin[1] + M[r][2] * lin[2]) / white[r];
            f[r] = t > d * d * d ? cbrt(t) : t / (3.0 * d * d) + 4.0 / 29.0;
        }
        const double ref[3] = {116.0 * f[1] - 16.0, 500.0 * (f[0] - f[1]), 200.0 * (f[1] - f[2])};
        for (int k = 0; k < 3; ++k) worst = fmax(worst, fabs(lab[k] - ref[k]));
    }
    printf("Lab through the fast cube root: largest difference from cbrt %.3g\n", worst);
    CHECK(worst < 1e-4);
}

int main(void)
{
    test_srgb_known_values();
    test_srgb_boundary_continuity();
    test_srgb_round_trip_and_monotonic();
    test_to_display();
    test_to_rgb8();
    test_lab();
    test_lab_cube_root();
    test_delta_e();
    return test_finish("tonemap_test");
}
