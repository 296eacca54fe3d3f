/* compare.c — image error metrics (compare.h): one pass over the pixels for
 * the linear metrics and ΔE, then an exact 99th percentile by selection on a
 * compact copy of the ΔE values. */
#include "src/image/compare.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "src/base/tonemap.h"

cmp_channel_rule cmp_rgb_channels(const img_image *img, int idx[3])
{
    idx[0] = idx[1] = idx[2] = 0;
    if (!img || img->channels < 1) return CMP_CHANNELS_NONE;
    if (img->channel_names) {
        static const char *const want[3] = {"R", "G", "B"};
        int found[3] = {-1, -1, -1};
        for (int k = 0; k < 3; ++k)
            for (int c = 0; c < img->channels && found[k] < 0; ++c)
                if (strcmp(img->channel_names[c], want[k]) == 0) found[k] = c;
        if (found[0] >= 0 && found[1] >= 0 && found[2] >= 0) {
            for (int k = 0; k < 3; ++k) idx[k] = found[k];
            return CMP_CHANNELS_NAMED;
        }
    }
    if (img->channels >= 3) {
        for (int k = 0; k < 3; ++k) idx[k] = k;
        return CMP_CHANNELS_FIRST_THREE;
    }
    return CMP_CHANNELS_GREY;
}

/* ---- exact quantile by selection ---- */

static int cmp_float(const void *pa, const void *pb)
{
    float a = *(const float *)pa, b = *(const float *)pb;
    return (a > b) - (a < b);
}

static void swap_f(float *a, float *b)
{
    float t = *a;
    *a = *b;
    *b = t;
}

/* Rearranges v so that v[k] is the k-th smallest, everything before it is
 * <= v[k] and everything after it >= v[k] (like std::nth_element).
 * Quickselect with a median-of-three pivot; after a budget of rounds
 * proportional to log n the remaining range is sorted, which bounds the
 * worst case at O(n log n). */
static void select_kth(float *v, size_t n, size_t k)
{
    if (n < 2) return;
    ptrdiff_t lo = 0, hi = (ptrdiff_t)n - 1, kk = (ptrdiff_t)k;
    int budget = 8;
    for (size_t m = n; m > 1; m >>= 1) budget += 2;
    while (hi > lo) {
        if (budget-- <= 0) {
            qsort(v + lo, (size_t)(hi - lo + 1), sizeof *v, cmp_float);
            return;
        }
        ptrdiff_t mid = lo + (hi - lo) / 2;
        if (v[mid] < v[lo]) swap_f(&v[mid], &v[lo]);
        if (v[hi] < v[lo]) swap_f(&v[hi], &v[lo]);
        if (v[hi] < v[mid]) swap_f(&v[hi], &v[mid]);
        const float pivot = v[mid];
        ptrdiff_t i = lo, j = hi;
        while (i <= j) {
            while (v[i] < pivot) ++i;
            while (pivot < v[j]) --j;
            if (i <= j) {
                swap_f(&v[i], &v[j]);
                ++i;
                --j;
            }
        }
        /* [lo, j] <= pivot, (j, i) == pivot, [i, hi] >= pivot */
        if (kk <= j)
            hi = j;
        else if (kk >= i)
            lo = i;
        else
            return;
    }
}

double cmp_percentile(float *values, size_t n, double q)
{
    if (!values || n == 0 || !(q >= 0.0 && q <= 1.0)) return NAN;
    double h = q * (double)(n - 1);
    size_t k = (size_t)floor(h);
    if (k >= n - 1) k = n - 1;
    select_kth(values, n, k);
    double lo = values[k];
    double frac = h - (double)k;
    if (k + 1 >= n || frac <= 0.0) return lo;
    /* After selection everything past k is >= values[k]: the next order
     * statistic is the smallest of them. */
    float next = values[k + 1];
    for (size_t i = k + 2; i < n; ++i)
        if (values[i] < next) next = values[i];
    return lo + frac * ((double)next - lo);
}

/* ---- heat map ---- */

/* viridis (matplotlib, CC0) at t = 0, 0.1, ..., 1. */
static const uint8_t k_viridis[11][3] = {
    {68, 1, 84},    {72, 36, 117},  {65, 68, 135},  {53, 95, 141},
    {42, 120, 142}, {33, 145, 140}, {34, 168, 132}, {68, 191, 112},
    {122, 209, 81}, {189, 223, 38}, {253, 231, 37},
};

void cmp_heatmap_rgb8(const float *delta_e, size_t count, uint8_t *out_rgb)
{
    if (!delta_e || !out_rgb) return;
    for (size_t p = 0; p < count; ++p) {
        uint8_t *o = out_rgb + 3 * p;
        float d = delta_e[p];
        if (isnan(d)) {
            o[0] = 255;
            o[1] = 0;
            o[2] = 255;
            continue;
        }
        double t = (double)d / (double)CMP_HEATMAP_MAX_DE;
        t = t > 0.0 ? (t < 1.0 ? t : 1.0) : 0.0;
        double x = t * 10.0;
        int i = (int)x;
        if (i > 9) i = 9;
        double f = x - (double)i;
        for (int c = 0; c < 3; ++c) {
            double v = (1.0 - f) * k_viridis[i][c] + f * k_viridis[i + 1][c];
            o[c] = (uint8_t)(v + 0.5);
        }
    }
}

/* ---- the comparison ---- */

static int rgb_finite(const float v[3])
{
    return isfinite(v[0]) && isfinite(v[1]) && isfinite(v[2]);
}

static lm_result check_image(const img_image *img, const char *name, lm_error *err)
{
    if (!img) return lm_fail(err, LM_ERR_INVALID_ARG, "cmp_compare: %s: no image", name);
    if (img->width <= 0 || img->height <= 0 || img->channels < 1 || !img->pixels)
        return lm_fail(err, LM_ERR_INVALID_ARG, "cmp_compare: %s: empty image (%dx%d, %d channels)",
                       name, img->width, img->height, img->channels);
    return LM_OK;
}

/* The channels stderr.R, stderr.G, stderr.B of img (`lumesh reference` writes
 * the standard error of each pixel's mean there): 1 and their indices, or 0. */
static int stderr_channels(const img_image *img, int out[3])
{
    static const char *const names[3] = {"stderr.R", "stderr.G", "stderr.B"};
    if (!img->channel_names) return 0;
    for (int k = 0; k < 3; ++k) {
        out[k] = -1;
        for (int c = 0; c < img->channels; ++c)
            if (strcmp(img->channel_names[c], names[k]) == 0) out[k] = c;
        if (out[k] < 0) return 0;
    }
    return 1;
}

lm_result cmp_compare(const cmp_desc *desc, const img_image *a, const img_image *b,
                      cmp_result *out, float *delta_e, lm_error *err)
{
    static const cmp_desc defaults = {0};
    if (!desc) desc = &defaults;
    const char *name_a = desc->name_a ? desc->name_a : "image A";
    const char *name_b = desc->name_b ? desc->name_b : "image B";
    if (!out) return lm_fail(err, LM_ERR_INVALID_ARG, "cmp_compare: no result");
    memset(out, 0, sizeof *out);
    lm_result r = check_image(a, name_a, err);
    if (r == LM_OK) r = check_image(b, name_b, err);
    if (r != LM_OK) return r;
    if (!isfinite(desc->exposure))
        return lm_fail(err, LM_ERR_INVALID_ARG, "cmp_compare: the exposure is not a finite number");
    if (a->width != b->width || a->height != b->height)
        return lm_fail(err, LM_ERR_BAD_INPUT, "%s is %dx%d but the reference %s is %dx%d", name_a,
                       a->width, a->height, name_b, b->width, b->height);

    int ia[3], ib[3], se[3];
    cmp_rgb_channels(a, ia);
    cmp_rgb_channels(b, ib);
    int has_se = stderr_channels(b, se);
    const size_t npix = (size_t)a->width * (size_t)a->height;
    const size_t sa = (size_t)a->channels, sb = (size_t)b->channels;

    float *de = malloc((npix ? npix : 1) * sizeof *de); /* ΔE of compared pixels, compacted */
    if (!de)
        return lm_fail(err, LM_ERR_NO_MEMORY, "%s: out of memory comparing %dx%d images", name_a,
                       a->width, a->height);

    const tm_desc tm = {.exposure = desc->exposure};
    double sum_sq = 0.0, sum_rel = 0.0, sum_abs = 0.0, sum_de = 0.0, sum_noise = 0.0;
    double max_abs = 0.0, max_de = 0.0;
    const double jnd = desc->jnd > 0.0f ? desc->jnd : 2.0;
    size_t above = 0;
    int max_x = 0, max_y = 0, max_c = 0;
    size_t n = 0, bad = 0, bad_a = 0, bad_b = 0;
    const int w = a->width;

    for (size_t p = 0; p < npix; ++p) {
        const float *pa = a->pixels + p * sa, *pb = b->pixels + p * sb;
        const float va[3] = {pa[ia[0]], pa[ia[1]], pa[ia[2]]};
        const float vb[3] = {pb[ib[0]], pb[ib[1]], pb[ib[2]]};
        int fa = rgb_finite(va), fb = rgb_finite(vb);
        if (!fa || !fb) {
            bad++;
            bad_a += !fa;
            bad_b += !fb;
            if (delta_e) delta_e[p] = NAN;
            continue;
        }
        for (int c = 0; c < 3; ++c) {
            double d = (double)va[c] - (double)vb[c];
            double ad = fabs(d);
            sum_sq += d * d;
            sum_rel += d * d / ((double)vb[c] * (double)vb[c] + 0.01);
            if (has_se) {
                double e = pb[se[c]];
                if (isfinite(e)) sum_noise += e * e / ((double)vb[c] * (double)vb[c] + 0.01);
            }
            sum_abs += ad;
            if (ad > max_abs) {
                max_abs = ad;
                max_x = (int)(p % (size_t)w);
                max_y = (int)(p / (size_t)w);
                max_c = c;
            }
        }
        float da[3], db[3], la[3], lb[3];
        tm_to_display(&tm, va, da);
        tm_to_display(&tm, vb, db);
        tm_display_to_lab(da, la);
        tm_display_to_lab(db, lb);
        float e = tm_delta_e(la, lb);
        if (delta_e) delta_e[p] = e;
        de[n++] = e;
        sum_de += e;
        above += e > jnd;
        if (e > max_de) max_de = e;
    }

    out->width = a->width;
    out->height = a->height;
    out->pixels_compared = n;
    out->nonfinite_pixels = bad;
    out->nonfinite_a = bad_a;
    out->nonfinite_b = bad_b;
    if (n == 0) {
        free(de);
        return lm_fail(err, LM_ERR_BAD_INPUT,
                       "%s: no pixel has finite R, G and B both here and in the reference %s "
                       "(%zu pixels, all NaN or infinite)",
                       name_a, name_b, npix);
    }
    const double nv = 3.0 * (double)n;
    double mse = sum_sq / nv;
    out->rmse = sqrt(mse);
    out->relmse = sum_rel / nv;
    out->relmse_reference_noise = has_se ? sum_noise / nv : 0.0;
    out->psnr = out->rmse > 0.0 ? 20.0 * log10(1.0 / out->rmse) : INFINITY;
    out->mean_abs_error = sum_abs / nv;
    out->max_abs_error = max_abs;
    out->max_x = max_x;
    out->max_y = max_y;
    out->max_channel = max_c;
    out->delta_e_mean = sum_de / (double)n;
    out->delta_e_max = max_de;
    out->delta_e_above_jnd = (double)above / (double)n;
    out->delta_e_p99 = cmp_percentile(de, n, 0.99);
    free(de);
    return LM_OK;
}
