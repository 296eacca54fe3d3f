/* converge_output.c — `lumesh converge`'s files: convergence.csv, .json and .png
 * (docs/stats.md has every column and field; cmd_converge.c measures). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "src/cli/app_stats.h"
#include "src/cli/converge_internal.h"
#include "src/cli/plot.h"

const char *const conv_state_names[] = {"refining", "converged", "no-snapshot", "finished", "below-jnd"};


static const char *mesh_column(const conv_ctx *c, uint32_t k, char *buf, size_t n)
{
    if (k < c->light_count)
        snprintf(buf, n, "light%u", k);
    else
        snprintf(buf, n, "%s", k == c->light_count ? "direct" : k == c->light_count + 1 ? "indirect" : "specular");
    return buf;
}

lm_result conv_write_csv(const conv_ctx *c, const conv_run *runs, int nrun, lm_error *err)
{
    size_t rows = 0;
    for (int k = 0; k < nrun; ++k) rows += (size_t)runs[k].count;
    size_t cap = 4096 + rows * (640 + 24 * MAX_MESHES), len = 0;
    char *t = malloc(cap), name[32];
    if (!t) return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory writing convergence.csv");
#define OUT(...) len += (size_t)snprintf(t + len, cap - len, __VA_ARGS__)
    OUT("method,target_seconds,seconds,state,leaves_tested");
    for (uint32_t k = 0; k < c->light_count + 3; ++k) OUT(",samples_%s", mesh_column(c, k, name, sizeof name));
    OUT(",spp_min,spp_max,rays,rmse,relmse,relmse_reference_noise,psnr,mean_abs_error,max_abs_error,delta_e_mean,delta_e_p99,delta_e_max,"
        "delta_e_above_jnd,estimated_delta_e_mean,estimated_fraction_above_jnd,estimated_fraction_untested,jnd,"
        "residual_weight,residual_corrected,residual_estimated_relmse,vpls,image\n");
    for (int k = 0; k < nrun; ++k)
        for (int i = 0; i < runs[k].count; ++i) {
            const conv_row *w = &runs[k].rows[i];
            int pt = runs[k].peer;
            OUT("%s,%.3f,%.4f,%s,", runs[k].method, w->target, w->seconds, pt ? "" : conv_state_names[w->state]);
            if (!pt) OUT("%llu", (unsigned long long)w->tested);
            for (uint32_t m = 0; m < c->light_count + 3; ++m)
                if (pt)
                    OUT(",");
                else
                    OUT(",%llu", (unsigned long long)w->samples[m]);
            if (pt || w->spp_max)
                OUT(",%u,%u,%llu", w->spp_min, w->spp_max, (unsigned long long)w->rays);
            else
                OUT(",,,");
            OUT(",%.6g,%.6g,%.6g,%.4f,%.6g,%.6g,%.4f,%.4f,%.4f,", w->m.rmse, w->m.relmse, w->m.relmse_reference_noise,
                w->m.psnr, w->m.mean_abs_error,
                w->m.max_abs_error, w->m.delta_e_mean, w->m.delta_e_p99, w->m.delta_e_max);
            OUT("%.5f,", w->m.delta_e_above_jnd);
            if (!pt && w->est_measured)
                OUT("%.4f,%.5f,%.5f,%.4g", w->est_delta_e, w->est_above_jnd, w->est_untested, w->jnd);
            else if (!pt)
                OUT(",,,%.4g", w->jnd);
            else OUT(",,,");
            if (!pt && w->spp_max) OUT(",%.4f,%.4f,%.4g", w->residual_weight, w->residual_corrected, w->residual_est);
            else OUT(",,,");
            if (runs[k].peer && runs[k].estimator != REF_ESTIMATOR_PATHS) OUT(",%llu", (unsigned long long)w->vpls);
            else OUT(",");
            OUT(",%s\n", w->image);
        }
#undef OUT
    char path[SCENE_PATH_MAX + 32];
    snprintf(path, sizeof path, "%s/convergence.csv", c->dir);
    lm_result r = app_write_text(path, t, len, err);
    free(t);
    return r;
}

static double rounded(double v, double unit) { return isfinite(v) ? round(v / unit) * unit : v; }

static cJSON *row_json(const conv_ctx *c, const conv_run *run, const conv_row *w)
{
    int pt = run->peer;
    cJSON *o = cJSON_CreateObject(), *m;
    char name[32];
    if (!o) return NULL;
    cJSON_AddNumberToObject(o, "target_seconds", w->target);
    cJSON_AddNumberToObject(o, "seconds", rounded(w->seconds, 1e-4));
    if (pt) {
        cJSON_AddNumberToObject(o, "spp_min", w->spp_min);
        cJSON_AddNumberToObject(o, "spp_max", w->spp_max);
        cJSON_AddNumberToObject(o, "rays", (double)w->rays);
        if (run->estimator != REF_ESTIMATOR_PATHS) {
            cJSON_AddNumberToObject(o, "vpls", (double)w->vpls);
            cJSON_AddNumberToObject(o, "vpl_seconds", rounded(w->vpl_seconds, 1e-4));
            if (run->visibility == REF_VPL_VISIBILITY_ISM) {
                cJSON_AddNumberToObject(o, "ism_maps", (double)w->ism_maps);
                cJSON_AddNumberToObject(o, "ism_seconds", rounded(w->ism_seconds, 1e-4));
            }
        }
    } else {
        cJSON_AddStringToObject(o, "state", conv_state_names[w->state]);
        cJSON_AddNumberToObject(o, "leaves_tested", (double)w->tested);
        if (!w->est_measured) {
            cJSON_AddNullToObject(o, "estimated_error"); /* the first snapshot's: none made */
        } else if ((m = cJSON_AddObjectToObject(o, "estimated_error"))) {
            cJSON_AddNumberToObject(m, "delta_e_mean", rounded(w->est_delta_e, 1e-5));
            cJSON_AddNumberToObject(m, "fraction_above_jnd", rounded(w->est_above_jnd, 1e-6));
            cJSON_AddNumberToObject(m, "fraction_untested", rounded(w->est_untested, 1e-6));
            cJSON_AddNumberToObject(m, "jnd", rounded(w->jnd, 1e-5));
        }
        if ((m = cJSON_AddObjectToObject(o, "samples")))
            for (uint32_t k = 0; k < c->light_count + 3; ++k)
                cJSON_AddNumberToObject(m, mesh_column(c, k, name, sizeof name), (double)w->samples[k]);
        if (w->spp_max && (m = cJSON_AddObjectToObject(o, "residual"))) {
            cJSON_AddNumberToObject(m, "spp_min", w->spp_min);
            cJSON_AddNumberToObject(m, "spp_max", w->spp_max);
            cJSON_AddNumberToObject(m, "rays", (double)w->rays);
            cJSON_AddNumberToObject(m, "mean_weight", rounded(w->residual_weight, 1e-5));
            cJSON_AddNumberToObject(m, "fraction_corrected", rounded(w->residual_corrected, 1e-5));
            if (isfinite(w->residual_est)) cJSON_AddNumberToObject(m, "estimated_relmse", w->residual_est);
        }
    }
    if ((m = cJSON_AddObjectToObject(o, "error"))) {
        cJSON_AddNumberToObject(m, "rmse", w->m.rmse);
        cJSON_AddNumberToObject(m, "relmse", w->m.relmse);
        cJSON_AddNumberToObject(m, "relmse_reference_noise", w->m.relmse_reference_noise);
        if (isfinite(w->m.psnr))
            cJSON_AddNumberToObject(m, "psnr", rounded(w->m.psnr, 1e-4));
        else
            cJSON_AddStringToObject(m, "psnr", "inf");
        cJSON_AddNumberToObject(m, "mean_abs_error", w->m.mean_abs_error);
        cJSON_AddNumberToObject(m, "max_abs_error", w->m.max_abs_error);
        cJSON_AddNumberToObject(m, "delta_e_mean", rounded(w->m.delta_e_mean, 1e-5));
        cJSON_AddNumberToObject(m, "delta_e_p99", rounded(w->m.delta_e_p99, 1e-5));
        cJSON_AddNumberToObject(m, "delta_e_max", rounded(w->m.delta_e_max, 1e-5));
        cJSON_AddNumberToObject(m, "delta_e_above_jnd", rounded(w->m.delta_e_above_jnd, 1e-6));
        cJSON_AddNumberToObject(m, "pixels_compared", (double)w->m.pixels_compared);
    }
    cJSON_AddStringToObject(o, "image", w->image);
    return o;
}

lm_result conv_write_json(const conv_ctx *c, const char *ref_path, const conv_run *runs, int nrun,
                          const cJSON *stats, lm_error *err)
{
    cJSON *j = cJSON_CreateObject();
    if (!j) return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory writing convergence.json");
    cJSON_AddStringToObject(j, "scene", c->s->source);
    cJSON_AddStringToObject(j, "reference", ref_path);
    cJSON_AddStringToObject(j, "transport", c->transport == REF_TRANSPORT_FULL ? "full" : "model");
    if (c->bounces == CACHE_BOUNCES_AUTO)
        cJSON_AddStringToObject(j, "bounces", "auto");
    else
        cJSON_AddNumberToObject(j, "bounces", c->bounces);
    cJSON_AddStringToObject(j, "glossy", c->glossy == REF_GLOSSY_DIRECT ? "direct" : "indirect");
    cJSON_AddStringToObject(j, "transport_note", c->transport_note);
    cJSON_AddNumberToObject(j, "width", c->w);
    cJSON_AddNumberToObject(j, "height", c->h);
    cJSON_AddNumberToObject(j, "exposure", c->exposure);
    cJSON_AddNumberToObject(j, "seconds", c->seconds);
    cJSON_AddNumberToObject(j, "supersample", c->supersample);
    cJSON_AddNumberToObject(j, "accumulate", c->accumulate);
    cJSON_AddBoolToObject(j, "interrupted", c->interrupted != 0);
    if (c->first_image >= 0)
        cJSON_AddNumberToObject(j, "first_image_seconds", rounded(c->first_image, 1e-5));
    else
        cJSON_AddNullToObject(j, "first_image_seconds");
    static const char *const phase_names[] = {"session", "renderer", "first_snapshot"};
    static const char *const load_names[] = {"reference", "scene"};
    const double phases[] = {rounded(c->phase[0], 1e-5), rounded(c->phase[1], 1e-5), rounded(c->phase[2], 1e-5)};
    const double loads[] = {rounded(c->load[0], 1e-5), rounded(c->load[1], 1e-5)};
    app_stats_add_phases(j, "first_image_phases", phase_names, phases, 3);
    app_stats_add_phases(j, "load_phases", load_names, loads, 2);
    if (c->converged_at >= 0)
        cJSON_AddNumberToObject(j, "converged_seconds", rounded(c->converged_at, 1e-4));
    else
        cJSON_AddNullToObject(j, "converged_seconds");
    cJSON *methods = cJSON_AddObjectToObject(j, "methods");
    for (int k = 0; methods && k < nrun; ++k) {
        cJSON *arr = cJSON_AddArrayToObject(methods, runs[k].method);
        for (int i = 0; arr && i < runs[k].count; ++i)
            cJSON_AddItemToArray(arr, row_json(c, &runs[k], &runs[k].rows[i]));
    }
    if (stats) cJSON_AddItemToObject(j, "stats", cJSON_Duplicate(stats, 1));
    char path[SCENE_PATH_MAX + 32];
    snprintf(path, sizeof path, "%s/convergence.json", c->dir);
    lm_result r = app_write_json(path, j, err);
    cJSON_Delete(j);
    return r;
}

lm_result conv_write_plot(const conv_ctx *c, const conv_run *runs, int nrun, lm_error *err)
{
    static const uint8_t colours[MAX_METHODS][3] = {{214, 39, 40},   {31, 119, 180}, {44, 160, 44},
                                                    {148, 103, 189}, {255, 127, 14}, {140, 86, 75}};
    double *buf = malloc((size_t)MAX_SNAPSHOTS * 3 * MAX_METHODS * sizeof *buf);
    if (!buf) return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory plotting");
    plot_series rel[MAX_METHODS], de[MAX_METHODS];
    char labels[MAX_METHODS][64];
    for (int k = 0; k < nrun; ++k) {
        double *x = buf + (size_t)k * 3 * MAX_SNAPSHOTS, *y1 = x + MAX_SNAPSHOTS, *y2 = y1 + MAX_SNAPSHOTS;
        for (int i = 0; i < runs[k].count; ++i) {
            x[i] = runs[k].rows[i].seconds;
            y1[i] = runs[k].rows[i].m.relmse;
            y2[i] = runs[k].rows[i].m.delta_e_mean;
        }
        int pt = runs[k].peer && runs[k].estimator == REF_ESTIMATOR_PATHS;
        const int ism = runs[k].visibility == REF_VPL_VISIBILITY_ISM; /* shorter: the legend's width is the panel's */
        snprintf(labels[k], sizeof labels[k], "%s%s",
                 pt                ? "path tracer (Embree, same transport)"
                 : runs[k].peer && runs[k].estimator == REF_ESTIMATOR_VPL ? (ism ? "VPLs" : "VPLs (instant radiosity")
                 : runs[k].peer    ? (ism ? "BDIR" : "BDIR (VPLs resampled")
                                   : runs[k].method,
                 pt || !runs[k].peer ? "" : ism ? " (imperfect shadow maps)" : ", same transport)");
        rel[k] = (plot_series){.label = labels[k], .x = x, .y = y1, .count = runs[k].count, .dashed = pt};
        de[k] = rel[k];
        de[k].y = y2;
        memcpy(rel[k].rgb, colours[k], 3);
        memcpy(de[k].rgb, colours[k], 3);
    }
    plot_panel panels[2] = {
        {.title = "relMSE against the reference", .xlabel = "seconds since the scene was loaded",
         .ylabel = "log-log", .series = rel, .series_count = nrun},
        {.title = "mean dE (CIE76, tone-mapped)", .xlabel = "seconds since the scene was loaded",
         .ylabel = "log-log", .series = de, .series_count = nrun,
         .hlines = {{2.0, "JND (dE 2)"}, {1.0, "dE 1"}}},
    };
    char title[SCENE_PATH_MAX + 64];
    const char *base = strrchr(c->s->source, '/');
    snprintf(title, sizeof title, "%s, %dx%d: error against time", base ? base + 1 : c->s->source, c->w, c->h);
    uint8_t *rgb = NULL;
    int pw, ph;
    lm_result r = plot_render(&(plot_desc){.title = title, .panels = panels, .panel_count = 2}, &rgb, &pw, &ph, err);
    free(buf);
    if (r != LM_OK) return r;
    char path[SCENE_PATH_MAX + 32];
    snprintf(path, sizeof path, "%s/convergence.png", c->dir);
    r = img_write(&(img_write_desc){.path = path, .width = pw, .height = ph, .channels = 3, .pixels8 = rgb}, err);
    free(rgb);
    return r;
}
