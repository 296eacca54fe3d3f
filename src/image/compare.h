/* compare.h — image error of a test image A against a reference B: RMSE,
 * relMSE, PSNR, maximum error, and CIELAB ΔE after the project's tone mapping.
 *
 * Channels: each image's channels named exactly "R", "G" and "B" (wherever they
 * are, so extra channels such as "stderr.R" or "samples" are ignored); an image
 * without all three names gives its first three channels; an image with one or
 * two channels (grey, or grey + alpha as PNG reads back) gives its first
 * channel on all three. A and B are picked independently (a grey A against an
 * RGB B is fine). cmp_rgb_channels() says what was picked.
 *
 * Non-finite values: a pixel whose picked R, G or B is NaN or ±Inf in A or in B
 * is left out of every metric (and is NaN in the per-pixel ΔE output); such
 * pixels are counted in cmp_result. If no pixel is left, the comparison fails
 * with LM_ERR_BAD_INPUT.
 *
 * Definitions, with n the pixels compared and sums over those pixels and the
 * three channels c, a = A's linear value, b = the reference's:
 *   mse            = Σ (a−b)² / 3n
 *   rmse           = sqrt(mse)                               (linear units)
 *   relmse         = Σ (a−b)² / (b² + 0.01) / 3n             (unitless)
 *   psnr           = 20·log10(1.0 / rmse) dB = −10·log10(mse): the peak is
 *                    fixed at 1.0 (the display white) whatever the images hold;
 *                    +INFINITY when rmse == 0 (identical images).
 *   mean_abs_error = Σ |a−b| / 3n
 *   max_abs_error  = max |a−b|; max_x, max_y (column, row from the top) and
 *                    max_channel (0 R, 1 G, 2 B) name the first place it occurs
 *                    in row-major order, channel R before G before B.
 * Differences are taken in double from the float values.
 *
 * Relation to OpenImageIO's ImageBufAlgo::compare (cmp_oiio_compare below):
 * on the same three channels of finite images, its rms_error, meanerror and
 * maxerror are these rmse, mean_abs_error and max_abs_error (up to rounding:
 * it subtracts in float). Its PSNR is 20·log10(peak / rms_error) with
 * peak = max(1.0, largest value of either image), so it equals psnr exactly
 * when no compared value exceeds 1.0 and is 20·log10(peak) dB higher otherwise.
 * With non-finite values they differ: OpenImageIO keeps those values in its
 * averages' denominator, counts NaN against NaN as no error and NaN against a
 * number as an infinite maxerror; this module leaves such pixels out instead.
 *
 * ΔE: per pixel, both RGB triples go through tm_to_display (with desc->exposure
 * stops), tm_display_to_lab and tm_delta_e (CIE76) from tonemap.h.
 * delta_e_p99 is the 99th percentile of the per-pixel ΔE by cmp_percentile.
 *
 * Usage:
 *     cmp_desc d = {.exposure = 0, .name_a = "a.exr", .name_b = "ref.exr"};
 *     cmp_result r;
 *     if (cmp_compare(&d, &a, &ref, &r, NULL, &err) != LM_OK) ...
 *
 * Does NOT do: reading files (img_read does), resampling or aligning images
 * of different sizes, alpha, perceptual metrics other than CIE76 ΔE.
 */
#ifndef LUMESH_COMPARE_H
#define LUMESH_COMPARE_H

#include <stddef.h>
#include <stdint.h>

#include "src/base/util.h"
#include "src/image/image.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct cmp_desc {
    float exposure;     /* stops, for the tone mapping used by ΔE; 0 = no scaling */
    const char *name_a; /* for messages; NULL: "image A" */
    const char *name_b; /* for messages; NULL: "image B" */
    float jnd;          /* ΔE a viewer notices, for delta_e_above_jnd; 0 = 2.0 (the cache's default) */
} cmp_desc;

typedef struct cmp_result {
    int width, height;
    size_t pixels_compared;   /* pixels with finite R, G, B in both images */
    size_t nonfinite_pixels;  /* pixels left out: a non-finite R, G or B in A or B */
    size_t nonfinite_a;       /* pixels with a non-finite R, G or B in A */
    size_t nonfinite_b;       /* ... in the reference */
    double rmse;
    double relmse;
    double relmse_reference_noise; /* the part of relmse the reference's own noise explains:
                                      mean of se²/(b² + 0.01) over the values compared, se the
                                      reference's standard error from its channels stderr.R/G/B
                                      (lumesh reference writes them); 0 without them. For an image
                                      independent of the reference, relmse − this estimates its
                                      relMSE against the truth without bias. */
    double psnr;              /* dB, peak 1.0; +INFINITY when rmse == 0 */
    double mean_abs_error;
    double max_abs_error;
    int max_x, max_y, max_channel;
    double delta_e_mean;      /* CIE76 */
    double delta_e_p99;
    double delta_e_max;
    double delta_e_above_jnd; /* fraction of the compared pixels with ΔE above cmp_desc.jnd */
} cmp_result;

/* Compares A against the reference B (same width and height, else
 * LM_ERR_BAD_INPUT "A is WxH but the reference B is WxH"). delta_e, if not
 * NULL, receives width*height ΔE values (row-major, top row first), NaN for
 * pixels left out. */
lm_result cmp_compare(const cmp_desc *desc, const img_image *a, const img_image *b,
                      cmp_result *out, float *delta_e, lm_error *err);

typedef enum cmp_channel_rule {
    CMP_CHANNELS_NAMED = 0,  /* channels named R, G, B */
    CMP_CHANNELS_FIRST_THREE,
    CMP_CHANNELS_GREY,       /* the first channel on all three */
    CMP_CHANNELS_NONE        /* not an image (no channels) */
} cmp_channel_rule;

/* Which channels of img are compared as R, G, B (the rule above). */
cmp_channel_rule cmp_rgb_channels(const img_image *img, int idx[3]);

/* The q-quantile (q in [0,1]) of n values, by linear interpolation between
 * closest ranks (Hyndman & Fan type 7, NumPy's default): with v sorted
 * ascending, h = q·(n−1), result = v[⌊h⌋] + (h−⌊h⌋)·(v[⌊h⌋+1] − v[⌊h⌋]).
 * Exact, by selection in place: reorders values. Values must not be NaN.
 * Returns NaN when n == 0 or q is outside [0,1]. */
double cmp_percentile(float *values, size_t n, double q);

/* The heat map's colour ramp: ΔE 0 to CMP_HEATMAP_MAX_DE (clamped) along
 * viridis (dark purple, blue, green, yellow: lightness increases with ΔE);
 * NaN (pixels left out) is magenta. count pixels, 3 bytes each. */
#define CMP_HEATMAP_MAX_DE 10.0f
void cmp_heatmap_rgb8(const float *delta_e, size_t count, uint8_t *out_rgb);

/* OpenImageIO's own comparison (ImageBufAlgo::compare) of two files, as an
 * independent check on cmp_compare: OpenImageIO reads both files and picks
 * R, G, B by the rule above (the first three honour the channel order
 * img_write records), then compares those three channels over the image
 * (data windows moved to the origin). Sizes must match (LM_ERR_BAD_INPUT). */
typedef struct cmp_oiio_result {
    int width, height;
    double mean_error;  /* ImageBufAlgo CompareResults::meanerror */
    double rms_error;   /* ::rms_error */
    double psnr;        /* ::PSNR, dB, peak max(1, largest value); +INFINITY if identical */
    double max_error;   /* ::maxerror */
    int max_x, max_y, max_channel;
} cmp_oiio_result;

lm_result cmp_oiio_compare(const char *path_a, const char *path_b, cmp_oiio_result *out,
                           lm_error *err);

#ifdef __cplusplus
}
#endif
#endif
