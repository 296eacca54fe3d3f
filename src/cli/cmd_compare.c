/* cmd_compare.c — `lumesh compare A B`: error of image A against the reference B.
 *
 * Every metric printed is computed by compare.c (R, G, B picked by name,
 * non-finite pixels left out, PSNR with peak 1.0). OpenImageIO's own
 * ImageBufAlgo::compare of the same files and channels is printed beside it
 * as an independent check of RMSE and PSNR. Nothing goes to stdout until all
 * the work (and the heat map) has succeeded, so a failure is one stderr line.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cjson/cJSON.h>

#include "src/cli/cli.h"
#include "src/image/compare.h"
#include "src/image/image.h"

static const char *const k_rgb_names[3] = {"R", "G", "B"};

/* "R,G,B" or "Y (grey)" style description of the picked channels. */
static void describe_channels(const img_image *img, char *out, size_t n)
{
    int idx[3];
    cmp_channel_rule rule = cmp_rgb_channels(img, idx);
    if (rule == CMP_CHANNELS_GREY)
        snprintf(out, n, "%s as grey", img->channel_names[idx[0]]);
    else
        snprintf(out, n, "%s,%s,%s%s", img->channel_names[idx[0]], img->channel_names[idx[1]],
                 img->channel_names[idx[2]], rule == CMP_CHANNELS_FIRST_THREE ? " (first three)" : "");
}

static void print_psnr(const char *label, double psnr, const char *note)
{
    if (isinf(psnr))
        printf("%-13s inf dB (%s; identical)\n", label, note);
    else
        printf("%-13s %.6g dB (%s)\n", label, psnr, note);
}

static void print_text(const char *pa, const char *pb, const img_image *a, const img_image *b,
                       double exposure, const cmp_result *r, const cmp_oiio_result *o,
                       const char *heatmap)
{
    char ca[128], cb[128];
    describe_channels(a, ca, sizeof ca);
    describe_channels(b, cb, sizeof cb);
    printf("image         %s (%dx%d, channels %s)\n", pa, a->width, a->height, ca);
    printf("reference     %s (%dx%d, channels %s)\n", pb, b->width, b->height, cb);
    printf("pixels        %zu compared, %zu left out as non-finite (%zu in the image, %zu in the "
           "reference)\n",
           r->pixels_compared, r->nonfinite_pixels, r->nonfinite_a, r->nonfinite_b);
    printf("RMSE          %.6g (linear)\n", r->rmse);
    printf("relMSE        %.6g (squared error / (reference² + 0.01))\n", r->relmse);
    if (r->relmse_reference_noise > 0.0)
        printf("              of which %.6g is the reference's own noise (its stderr channels); net %.6g\n",
               r->relmse_reference_noise, r->relmse - r->relmse_reference_noise);
    print_psnr("PSNR", r->psnr, "peak 1.0");
    printf("mean error    %.6g (linear, absolute)\n", r->mean_abs_error);
    printf("max error     %.6g (linear) at x %d, y %d, channel %s\n", r->max_abs_error, r->max_x,
           r->max_y, k_rgb_names[r->max_channel]);
    printf("ΔE mean       %.6g (CIE76, tone mapped at exposure %g stops)\n", r->delta_e_mean,
           exposure);
    printf("ΔE 99%%        %.6g\n", r->delta_e_p99);
    printf("ΔE > 2        %.4g%% of the pixels (the cache's JND)\n", 100.0 * r->delta_e_above_jnd);
    printf("ΔE max        %.6g\n", r->delta_e_max);
    printf("OIIO RMSE     %.6g (OpenImageIO's ImageBufAlgo::compare, same channels%s)\n",
           o->rms_error, r->nonfinite_pixels ? ", non-finite pixels kept" : "");
    print_psnr("OIIO PSNR", o->psnr, "peak max(1, largest value)");
    if (heatmap)
        printf("heat map      %s (ΔE 0 to %g on viridis; magenta: left out)\n", heatmap,
               (double)CMP_HEATMAP_MAX_DE);
}

/* cJSON writes non-finite numbers as null; an infinite PSNR is the string "inf". */
static cJSON *add_psnr(cJSON *obj, const char *key, double psnr)
{
    if (isinf(psnr) && psnr > 0) return cJSON_AddStringToObject(obj, key, "inf");
    return cJSON_AddNumberToObject(obj, key, psnr);
}

static cJSON *channel_array(const img_image *img)
{
    int idx[3];
    cmp_rgb_channels(img, idx);
    const char *names[3] = {img->channel_names[idx[0]], img->channel_names[idx[1]],
                            img->channel_names[idx[2]]};
    return cJSON_CreateStringArray(names, 3);
}

/* The JSON text (malloc'ed by cJSON), or NULL when out of memory. */
static char *make_json(const char *pa, const char *pb, const img_image *a, const img_image *b,
                       double exposure, const cmp_result *r, const cmp_oiio_result *o,
                       const char *heatmap)
{
    cJSON *root = cJSON_CreateObject();
    int ok = root != NULL;
    if (ok) {
        cJSON *ch_a = channel_array(a), *ch_b = channel_array(b);
        ok = ch_a && ch_b;
        if (ch_a) cJSON_AddItemToObject(root, "channels_image", ch_a);
        if (ch_b) cJSON_AddItemToObject(root, "channels_reference", ch_b);
        ok = ok && cJSON_AddStringToObject(root, "image", pa) &&
             cJSON_AddStringToObject(root, "reference", pb) &&
             cJSON_AddNumberToObject(root, "width", r->width) &&
             cJSON_AddNumberToObject(root, "height", r->height) &&
             cJSON_AddNumberToObject(root, "pixels_compared", (double)r->pixels_compared) &&
             cJSON_AddNumberToObject(root, "nonfinite_pixels", (double)r->nonfinite_pixels) &&
             cJSON_AddNumberToObject(root, "nonfinite_image", (double)r->nonfinite_a) &&
             cJSON_AddNumberToObject(root, "nonfinite_reference", (double)r->nonfinite_b) &&
             cJSON_AddNumberToObject(root, "rmse", r->rmse) &&
             cJSON_AddNumberToObject(root, "relmse", r->relmse) &&
             cJSON_AddNumberToObject(root, "relmse_reference_noise", r->relmse_reference_noise) &&
             add_psnr(root, "psnr_db", r->psnr) &&
             cJSON_AddNumberToObject(root, "psnr_peak", 1.0) &&
             cJSON_AddNumberToObject(root, "mean_abs_error", r->mean_abs_error) &&
             cJSON_AddNumberToObject(root, "max_abs_error", r->max_abs_error) &&
             cJSON_AddNumberToObject(root, "max_abs_error_x", r->max_x) &&
             cJSON_AddNumberToObject(root, "max_abs_error_y", r->max_y) &&
             cJSON_AddStringToObject(root, "max_abs_error_channel", k_rgb_names[r->max_channel]) &&
             cJSON_AddNumberToObject(root, "exposure", exposure) &&
             cJSON_AddNumberToObject(root, "delta_e_mean", r->delta_e_mean) &&
             cJSON_AddNumberToObject(root, "delta_e_p99", r->delta_e_p99) &&
             cJSON_AddNumberToObject(root, "delta_e_above_jnd", r->delta_e_above_jnd) &&
             cJSON_AddNumberToObject(root, "delta_e_max", r->delta_e_max);
    }
    cJSON *oi = ok ? cJSON_AddObjectToObject(root, "oiio") : NULL;
    ok = ok && oi && cJSON_AddNumberToObject(oi, "rms_error", o->rms_error) &&
         add_psnr(oi, "psnr_db", o->psnr) &&
         cJSON_AddNumberToObject(oi, "mean_error", o->mean_error) &&
         cJSON_AddNumberToObject(oi, "max_error", o->max_error);
    if (ok && heatmap) {
        ok = cJSON_AddStringToObject(root, "heatmap", heatmap) &&
             cJSON_AddNumberToObject(root, "heatmap_max_delta_e", CMP_HEATMAP_MAX_DE);
    }
    char *text = ok ? cJSON_Print(root) : NULL;
    cJSON_Delete(root);
    return text;
}

static int write_heatmap(const char *path, const float *de, int w, int h)
{
    size_t n = (size_t)w * (size_t)h;
    uint8_t *rgb = malloc(3 * n);
    lm_error err;
    if (!rgb) {
        lm_fail(&err, LM_ERR_NO_MEMORY, "%s: out of memory for the heat map", path);
        return app_report(LM_ERR_NO_MEMORY, &err);
    }
    cmp_heatmap_rgb8(de, n, rgb);
    img_write_desc d = {.path = path, .format = IMG_FORMAT_PNG8, .width = w, .height = h,
                        .channels = 3, .pixels8 = rgb};
    lm_result r = img_write(&d, &err);
    free(rgb);
    return r == LM_OK ? APP_EXIT_OK : app_report(r, &err);
}

int cmd_compare(const app_command *cmd, int argc, char **argv)
{
    int json = 0;
    const char *heatmap = NULL;
    double exposure = 0;
    app_opt opts[] = {
        {"--json", NULL, APP_OPT_FLAG, &json},
        {"--heatmap", NULL, APP_OPT_STRING, &heatmap},
        {"--exposure", NULL, APP_OPT_DOUBLE, &exposure, -64, 64},
    };
    const char *pos[2];
    int npos, rc = app_parse_options(cmd, argc, argv, opts, 3, pos, 2, &npos);
    if (rc < 0) return APP_EXIT_OK;
    if (rc) return rc;
    if (npos != 2) return app_usage_error(cmd, "give two images: the one to test, then the reference");
    if (heatmap) {
        char ext[16];
        lm_path_ext(heatmap, ext, sizeof ext);
        if (strcmp(ext, "png") != 0) return app_usage_error(cmd, "the heat map must end in .png");
    }

    img_image a = {0}, b = {0};
    cmp_result res;
    cmp_oiio_result oi;
    float *de = NULL;
    char *text = NULL;
    lm_error err = {{0}};
    lm_result r = img_read(pos[0], &a, &err);
    if (r == LM_OK) r = img_read(pos[1], &b, &err);
    if (r == LM_OK && heatmap) {
        de = malloc((size_t)a.width * (size_t)a.height * sizeof *de);
        if (!de) r = lm_fail(&err, LM_ERR_NO_MEMORY, "%s: out of memory for the heat map", heatmap);
    }
    if (r == LM_OK) {
        cmp_desc d = {.exposure = (float)exposure, .name_a = pos[0], .name_b = pos[1]};
        r = cmp_compare(&d, &a, &b, &res, de, &err);
    }
    if (r == LM_OK) r = cmp_oiio_compare(pos[0], pos[1], &oi, &err);
    if (r != LM_OK) {
        rc = app_report(r, &err);
        goto done;
    }
    if (heatmap && (rc = write_heatmap(heatmap, de, a.width, a.height)) != APP_EXIT_OK) goto done;

    if (json) {
        text = make_json(pos[0], pos[1], &a, &b, exposure, &res, &oi, heatmap);
        if (!text) {
            lm_fail(&err, LM_ERR_NO_MEMORY, "out of memory writing the JSON report");
            rc = app_report(LM_ERR_NO_MEMORY, &err);
            goto done;
        }
        printf("%s\n", text);
    } else {
        print_text(pos[0], pos[1], &a, &b, exposure, &res, &oi, heatmap);
    }
    rc = fflush(stdout) == 0 ? APP_EXIT_OK : APP_EXIT_RUNTIME;

done:
    cJSON_free(text);
    free(de);
    img_free(&a);
    img_free(&b);
    return rc;
}
