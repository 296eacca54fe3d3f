/* tonemap.c — exposure, clamp and the sRGB transfer function; sRGB -> CIELAB
 * (D65) and CIE76 ΔE. Arithmetic is done in double and rounded to float once. */
#include "src/base/tonemap.h"

#include <math.h>
#include <stdint.h>
#include <string.h>

/* Linear sRGB -> CIE XYZ (D65), IEC 61966-2-1 primaries. */
static const double k_rgb_to_xyz[3][3] = {
    {0.4124564, 0.3575761, 0.1804375},
    {0.2126729, 0.7151522, 0.0721750},
    {0.0193339, 0.1191920, 0.9503041},
};
/* D65 reference white, Y = 1. */
static const double k_white[3] = {0.95047, 1.0, 1.08883};

/* [0,1]; NaN -> 0. */
static double clamp01(double v)
{
    return v > 0.0 ? (v < 1.0 ? v : 1.0) : 0.0;
}

static double encode_d(double x)
{
    x = clamp01(x);
    return x <= 0.0031308 ? 12.92 * x : 1.055 * pow(x, 1.0 / 2.4) - 0.055;
}

static double decode_d(double e)
{
    e = clamp01(e);
    return e <= 0.04045 ? e / 12.92 : pow((e + 0.055) / 1.055, 2.4);
}

float tm_srgb_encode(float linear)
{
    return (float)encode_d(linear);
}

float tm_srgb_decode(float encoded)
{
    return (float)decode_d(encoded);
}

/* 2^exposure; a missing descriptor or a non-finite exposure means no scaling. */
static double exposure_scale(const tm_desc *desc)
{
    if (!desc || !isfinite(desc->exposure)) return 1.0;
    return exp2((double)desc->exposure);
}

static double display_channel(double scale, float linear)
{
    if (!isfinite(linear)) return 0.0;
    return encode_d(scale * (double)linear); /* encode_d clamps */
}

void tm_to_display(const tm_desc *desc, const float linear[3], float display[3])
{
    double scale = exposure_scale(desc);
    for (int i = 0; i < 3; ++i) display[i] = (float)display_channel(scale, linear[i]);
}

static uint8_t to_byte(double display)
{
    return (uint8_t)(clamp01(display) * 255.0 + 0.5);
}

void tm_to_rgb8(const tm_desc *desc, const float *in, int in_channels, size_t count, uint8_t *out_rgb)
{
    if (!in || !out_rgb || in_channels < 1) return;
    double scale = exposure_scale(desc);
    size_t stride = (size_t)in_channels;
    for (size_t p = 0; p < count; ++p) {
        const float *px = in + p * stride;
        uint8_t *o = out_rgb + 3 * p;
        if (in_channels >= 3) {
            for (int c = 0; c < 3; ++c) o[c] = to_byte(display_channel(scale, px[c]));
        } else {
            /* Gray (or gray + alpha): the first channel on all three. */
            uint8_t g = to_byte(display_channel(scale, px[0]));
            o[0] = o[1] = o[2] = g;
        }
    }
}

/* The cube root of t in ((6/29)^3, 1]: a guess from the float's bits (the
 * exponent divided by three, within 4%), then three Newton steps (relative error
 * 4e-2 -> 2e-3 -> 5e-6 -> 3e-11). libm's cbrt made the Lab conversions a tenth of
 * a million-triangle scene's start-up (cache_bounces.c compares every seen
 * colour once a bounce). */
static double cube_root(double t)
{
    float f = (float)t;
    uint32_t bits;
    memcpy(&bits, &f, sizeof bits);
    bits = bits / 3u + 709921077u;
    memcpy(&f, &bits, sizeof f);
    double y = f;
    for (int i = 0; i < 3; ++i) y = (2.0 * y + t / (y * y)) * (1.0 / 3.0);
    return y;
}

/* CIELAB companding: cube root above (6/29)^3, linear below. */
static double lab_f(double t)
{
    const double d = 6.0 / 29.0;
    return t > d * d * d ? cube_root(t) : t / (3.0 * d * d) + 4.0 / 29.0;
}

/* Linear display RGB in [0,1] -> CIELAB. */
static void lab_of_linear(const double lin[3], float lab[3])
{
    double f[3];
    for (int r = 0; r < 3; ++r) {
        double xyz = k_rgb_to_xyz[r][0] * lin[0] + k_rgb_to_xyz[r][1] * lin[1] +
                     k_rgb_to_xyz[r][2] * lin[2];
        f[r] = lab_f(xyz / k_white[r]);
    }
    lab[0] = (float)(116.0 * f[1] - 16.0);
    lab[1] = (float)(500.0 * (f[0] - f[1]));
    lab[2] = (float)(200.0 * (f[1] - f[2]));
}

void tm_display_to_lab(const float display[3], float lab[3])
{
    double lin[3];
    for (int i = 0; i < 3; ++i) lin[i] = decode_d(display[i]); /* decode_d clamps, NaN -> 0 */
    lab_of_linear(lin, lab);
}

void tm_linear_to_lab(const tm_desc *desc, const float linear[3], float lab[3])
{
    double scale = exposure_scale(desc), lin[3];
    for (int i = 0; i < 3; ++i) lin[i] = isfinite(linear[i]) ? clamp01(scale * (double)linear[i]) : 0.0;
    lab_of_linear(lin, lab);
}

float tm_delta_e(const float lab_a[3], const float lab_b[3])
{
    double dl = (double)lab_a[0] - lab_b[0];
    double da = (double)lab_a[1] - lab_b[1];
    double db = (double)lab_a[2] - lab_b[2];
    return (float)sqrt(dl * dl + da * da + db * db);
}
