/* app_stats.c — the statistics JSON (app_stats.h; fields in docs/stats.md). */
#define _POSIX_C_SOURCE 200809L
#include "src/cli/app_stats.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "src/scene/scene.h"

/* The cache's error estimate (cache.h: cache_estimate) of one mesh. */
static cJSON *estimate_json(const cache_mesh_estimate *e)
{
    cJSON *o = cJSON_CreateObject();
    if (!o) return NULL;
    cJSON_AddNumberToObject(o, "pixels", e->pixels);
    cJSON_AddNumberToObject(o, "mean_delta_e", e->combined);
    cJSON_AddNumberToObject(o, "interpolation_delta_e", e->interpolation);
    cJSON_AddNumberToObject(o, "noise_delta_e", e->noise);
    cJSON_AddNumberToObject(o, "max_delta_e", e->max);
    cJSON_AddNumberToObject(o, "pixels_above_jnd", e->pixels_above_jnd);
    cJSON_AddNumberToObject(o, "pixels_untested", e->pixels_untested);
    return o;
}

static cJSON *mesh_json(const char *name, const char *kind, int light, const cache_mesh_stats *m,
                        const cache_mesh_estimate *est)
{
    cJSON *o = cJSON_CreateObject();
    if (!o) return NULL;
    cJSON_AddStringToObject(o, "mesh", name);
    cJSON_AddStringToObject(o, "kind", kind);
    if (light >= 0) cJSON_AddNumberToObject(o, "light", light);
    cJSON_AddNumberToObject(o, "samples", (double)m->samples);
    cJSON_AddNumberToObject(o, "interpolated", (double)m->interpolated);
    cJSON_AddNumberToObject(o, "vertices", m->mesh.vertices_used);
    cJSON_AddNumberToObject(o, "vertices_sampled", m->mesh.vertices_sampled);
    cJSON_AddNumberToObject(o, "roots", m->mesh.roots);
    cJSON_AddNumberToObject(o, "nodes", m->mesh.nodes);
    cJSON_AddNumberToObject(o, "leaves", m->mesh.leaves);
    cJSON_AddNumberToObject(o, "splits", (double)m->mesh.splits);
    cJSON_AddNumberToObject(o, "undone_splits", (double)m->mesh.merges);
    cJSON_AddNumberToObject(o, "bytes", (double)m->mesh.bytes);
    if (light < 0) cJSON_AddNumberToObject(o, "yield", m->yield);
    int last = -1;
    for (int d = 0; d < MESH_QMESH_DEPTHS; ++d)
        if (m->mesh.leaves_at_depth[d]) last = d;
    cJSON *hist = cJSON_AddArrayToObject(o, "leaves_at_depth");
    for (int d = 0; hist && d <= last; ++d) cJSON_AddItemToArray(hist, cJSON_CreateNumber(m->mesh.leaves_at_depth[d]));
    if (est) cJSON_AddItemToObject(o, "estimated_error", estimate_json(est));
    return o;
}

static cJSON *sampler_side(const char *backend, uint64_t points, double seconds)
{
    cJSON *o = cJSON_CreateObject();
    if (!o) return NULL;
    cJSON_AddStringToObject(o, "backend", backend ? backend : "none");
    cJSON_AddNumberToObject(o, "points", (double)points);
    cJSON_AddNumberToObject(o, "seconds", seconds);
    cJSON_AddNumberToObject(o, "us_per_point", points ? seconds * 1e6 / (double)points : 0.0);
    return o;
}

/* The sampler running when the snapshot was made, and with it what the
 * refining samplers it replaced served (cache_snapshot.retired): points and
 * seconds of a quantity summed over those with its back end. */
static cJSON *sampler_json(const cache_snapshot *snap)
{
    const samp_stats *st = &snap->sampler, *quick = &snap->quick_sampler;
    cJSON *o = cJSON_CreateObject();
    if (!o) return NULL;
    uint64_t points[2] = {st->direct_samples, st->indirect_samples};
    double seconds[2] = {st->direct_seconds, st->indirect_seconds};
    for (uint32_t i = 0; i < snap->retired_count && i < CACHE_SNAPSHOT_RETIRED; ++i) {
        const samp_stats *r = &snap->retired[i];
        if (r->backend == st->backend && r->gl_platform == st->gl_platform)
            points[0] += r->direct_samples, seconds[0] += r->direct_seconds;
        if (r->indirect_backend == st->indirect_backend && r->indirect_gl_platform == st->indirect_gl_platform)
            points[1] += r->indirect_samples, seconds[1] += r->indirect_seconds;
    }
    cJSON_AddItemToObject(o, "direct", sampler_side(st->backend_name, points[0], seconds[0]));
    cJSON_AddItemToObject(o, "indirect", sampler_side(st->indirect_backend_name, points[1], seconds[1]));
    if (quick->backend != SAMP_BACKEND_AUTO) { /* zeroed: no quick start */
        cJSON *q = cJSON_AddObjectToObject(o, "quick_start");
        if (q) {
            cJSON_AddItemToObject(q, "direct", sampler_side(quick->backend_name, quick->direct_samples,
                                                            quick->direct_seconds));
            cJSON_AddItemToObject(q, "indirect", sampler_side(quick->indirect_backend_name, quick->indirect_samples,
                                                              quick->indirect_seconds));
        }
    }
    /* Seconds per back end, whichever quantity they served, the quick start's
     * and the replaced samplers' included. */
    cJSON *by = cJSON_AddObjectToObject(o, "seconds_by_backend");
    enum { SIDES = 2 * (2 + CACHE_SNAPSHOT_RETIRED) };
    samp_backend kinds[SIDES] = {st->backend, st->indirect_backend, quick->backend, quick->indirect_backend};
    const char *names[SIDES] = {st->backend_name, st->indirect_backend_name, quick->backend_name,
                                quick->indirect_backend_name};
    double secs[SIDES] = {st->direct_seconds, st->indirect_seconds, quick->direct_seconds, quick->indirect_seconds};
    int sides = 4;
    for (uint32_t i = 0; i < snap->retired_count && i < CACHE_SNAPSHOT_RETIRED; ++i) {
        const samp_stats *r = &snap->retired[i];
        kinds[sides] = r->backend, names[sides] = r->backend_name, secs[sides++] = r->direct_seconds;
        kinds[sides] = r->indirect_backend, names[sides] = r->indirect_backend_name, secs[sides++] = r->indirect_seconds;
    }
    for (int k = 0; by && k < sides; ++k) {
        if (kinds[k] == SAMP_BACKEND_AUTO || !names[k]) continue; /* no such sampler */
        cJSON *have = cJSON_GetObjectItemCaseSensitive(by, names[k]);
        if (have)
            cJSON_SetNumberValue(have, have->valuedouble + secs[k]);
        else
            cJSON_AddNumberToObject(by, names[k], secs[k]);
    }
    cJSON_AddStringToObject(o, "choice", st->choice);
    return o;
}

void app_stats_add_phases(cJSON *j, const char *key, const char *const *names, const double *seconds, int n)
{
    cJSON *ph = cJSON_AddObjectToObject(j, key);
    for (int i = 0; ph && i < n; ++i) {
        if (seconds[i] >= 0) cJSON_AddNumberToObject(ph, names[i], seconds[i]);
        else cJSON_AddNullToObject(ph, names[i]);
    }
}

cJSON *app_stats_json(const app_stats_desc *d)
{
    const cache_snapshot *snap = d->snap;
    const cache_stats *st = &snap->stats;
    cJSON *j = cJSON_CreateObject();
    if (!j) return NULL;
    cJSON_AddStringToObject(j, "lumesh", LUMESH_VERSION_STRING);
    cJSON_AddStringToObject(j, "command", d->command ? d->command : "");
    cJSON_AddStringToObject(j, "scene", d->scene ? d->scene : "");
    cJSON_AddNumberToObject(j, "width", d->width);
    cJSON_AddNumberToObject(j, "height", d->height);
    cJSON_AddNumberToObject(j, "supersample", d->supersample > 0 ? d->supersample : 1);
    cJSON_AddNumberToObject(j, "seconds", d->seconds);
    if (d->first_image_seconds >= 0)
        cJSON_AddNumberToObject(j, "first_image_seconds", d->first_image_seconds);
    else
        cJSON_AddNullToObject(j, "first_image_seconds");
    if (d->converged_seconds > 0)
        cJSON_AddNumberToObject(j, "converged_seconds", d->converged_seconds);
    else
        cJSON_AddNullToObject(j, "converged_seconds");
    if (d->phase_count > 0)
        app_stats_add_phases(j, "first_image_phases", d->phase_names, d->phase_seconds, d->phase_count);
    cJSON_AddNumberToObject(j, "leaves_tested", (double)snap->tested);
    cJSON_AddBoolToObject(j, "converged", snap->converged);
    cJSON *est = snap->estimate.measured ? cJSON_AddObjectToObject(j, "estimated_error") : NULL;
    if (!snap->estimate.measured) cJSON_AddNullToObject(j, "estimated_error"); /* a first snapshot's: none */
    if (est) {
        const cache_estimate *e = &snap->estimate;
        cJSON_AddNumberToObject(est, "jnd", e->jnd);
        cJSON_AddNumberToObject(est, "exposure", e->exposure);
        cJSON_AddNumberToObject(est, "pixels", e->pixels);
        cJSON_AddNumberToObject(est, "mean_delta_e", e->mean);
        cJSON_AddNumberToObject(est, "fraction_above_jnd", e->above_jnd);
        cJSON_AddNumberToObject(est, "fraction_untested", e->untested);
    }
    cJSON_AddNumberToObject(j, "snapshot", (double)snap->generation);
    cJSON_AddNumberToObject(j, "undone_splits", (double)st->undone);
    cJSON_AddNumberToObject(j, "toward_source_gathers", (double)st->toward_gathers);
    cJSON *dr = cJSON_AddObjectToObject(j, "drift");
    if (dr) { /* indirect values a rebuilt source may have moved (docs/stats.md) */
        cJSON_AddNumberToObject(dr, "regathered", (double)st->regathered);
        cJSON_AddNumberToObject(dr, "probed", (double)st->drift_probed);
        cJSON_AddNumberToObject(dr, "cleared", (double)st->drift_cleared);
        cJSON_AddNumberToObject(dr, "probe_rays", (double)st->drift_probe_rays);
    }
    cJSON_AddNumberToObject(j, "glossy_gathers", (double)st->glossy_gathers);
    cJSON_AddNumberToObject(j, "glossy_refreshed", (double)st->glossy_refreshed);
    cJSON_AddNumberToObject(j, "glossy_rays", (double)st->glossy_rays);
    cJSON_AddNumberToObject(j, "active_triangles", (double)st->active_triangles);
    cJSON_AddNumberToObject(j, "reach_rays", (double)st->reach_rays);
    cJSON *su = cJSON_AddObjectToObject(j, "startup");
    if (su) { /* where the time before the first image went (docs/stats.md) */
        const cache_startup_stats *u = &st->startup;
        cJSON_AddNumberToObject(su, "create_seconds", u->create_seconds);
        cJSON_AddNumberToObject(su, "reach_seconds", u->reach_seconds);
        cJSON_AddNumberToObject(su, "light_seconds", u->light_seconds);
        cJSON_AddNumberToObject(su, "values_seconds", u->values_seconds);
        cJSON_AddNumberToObject(su, "source_seconds", u->source_seconds);
        cJSON_AddNumberToObject(su, "gather_seconds", u->gather_seconds);
        cJSON_AddNumberToObject(su, "first_rounds_seconds", snap->first_rounds_seconds);
        cJSON_AddNumberToObject(su, "first_publish_seconds", snap->first_publish_seconds);
        cJSON_AddNumberToObject(su, "light_samples", (double)u->light_samples);
        cJSON_AddNumberToObject(su, "gathers", (double)u->gathers);
    }
    cJSON *bw = cJSON_AddObjectToObject(j, "borrowed");
    if (bw) { /* the first image's borrowed indirect values, tested after it (docs/stats.md) */
        cJSON_AddNumberToObject(bw, "corners", (double)st->borrow.borrowed);
        cJSON_AddNumberToObject(bw, "tests", (double)st->borrow.tests);
        cJSON_AddNumberToObject(bw, "splits", (double)st->borrow.splits);
        cJSON_AddNumberToObject(bw, "kept", (double)st->borrow.kept);
    }
    cJSON_AddNumberToObject(j, "bytes", (double)st->bytes);
    cJSON_AddItemToObject(j, "sampler", sampler_json(snap));
    cJSON *bn = cJSON_AddObjectToObject(j, "bounces");
    if (bn) {
        const cache_bounce_stats *b = &st->bounces;
        cJSON_AddNumberToObject(bn, "shown", b->bounces);
        cJSON_AddBoolToObject(bn, "auto", b->automatic);
        cJSON_AddStringToObject(bn, "why", b->why);
        cJSON_AddNumberToObject(bn, "rest_delta_e", b->rest_de);
        cJSON *de = cJSON_AddArrayToObject(bn, "delta_e");
        for (int k = 2; de && k <= b->bounces && k <= CACHE_BOUNCES_MAX; ++k)
            cJSON_AddItemToArray(de, cJSON_CreateNumber(b->de[k]));
        cJSON_AddNumberToObject(bn, "vertices", b->vertices);
        cJSON_AddNumberToObject(bn, "rays_per_vertex", b->rays);
        cJSON_AddNumberToObject(bn, "hits", (double)b->hits);
        cJSON_AddNumberToObject(bn, "trace_seconds", b->trace_seconds);
        cJSON_AddNumberToObject(bn, "update_seconds", b->update_seconds);
        cJSON *sec = cJSON_AddArrayToObject(bn, "seconds_per_bounce");
        for (int k = 1; sec && b->vertices && k <= b->bounces && k <= CACHE_BOUNCES_MAX; ++k)
            cJSON_AddItemToArray(sec, cJSON_CreateNumber(b->seconds[k]));
        cJSON_AddNumberToObject(bn, "series_seconds", b->series_seconds);
        cJSON_AddNumberToObject(bn, "updates", (double)b->updates);
    }

    cJSON *fr = cJSON_AddObjectToObject(j, "frame");
    if (fr) {
        cJSON_AddNumberToObject(fr, "frames", (double)d->frames);
        cJSON *ms = cJSON_AddObjectToObject(fr, "passes_ms");
        if (ms) {
            cJSON_AddNumberToObject(ms, "id", d->id_seconds * 1e3);
            const rend_frame_times *t = d->frame;
            cJSON_AddNumberToObject(ms, "material", t ? t->material * 1e3 : 0.0);
            cJSON_AddNumberToObject(ms, "radiance", t ? t->radiance * 1e3 : 0.0);
            cJSON_AddNumberToObject(ms, "composite", t ? t->composite * 1e3 : 0.0);
            cJSON_AddNumberToObject(ms, "readback", t ? t->readback * 1e3 : 0.0);
        }
        cJSON *tris = cJSON_AddObjectToObject(fr, "leaf_triangles");
        if (tris) {
            cJSON_AddNumberToObject(tris, "direct", (double)cache_snapshot_leaf_count(&snap->direct));
            cJSON_AddNumberToObject(tris, "indirect", (double)cache_snapshot_leaf_count(&snap->indirect));
            cJSON_AddNumberToObject(tris, "specular", (double)cache_snapshot_leaf_count(&snap->specular));
        }
    }

    const rend_residual_info *ri = d->residual;
    cJSON *res = ri ? cJSON_AddObjectToObject(j, "residual") : NULL;
    if (res) {
        cJSON_AddNumberToObject(res, "spp_min", ri->min_samples);
        cJSON_AddNumberToObject(res, "spp_max", ri->max_samples);
        cJSON_AddNumberToObject(res, "seconds", ri->seconds);
        cJSON_AddNumberToObject(res, "rays", (double)ri->rays);
        cJSON_AddNumberToObject(res, "mean_weight", ri->mean_weight);
        cJSON_AddNumberToObject(res, "fraction_corrected", ri->corrected);
        if (isfinite(ri->est_relmse)) cJSON_AddNumberToObject(res, "estimated_relmse", ri->est_relmse);
    }

    cJSON *meshes = cJSON_AddArrayToObject(j, "meshes");
    for (uint32_t l = 0; meshes && l < st->light_count; ++l) {
        char name[32];
        snprintf(name, sizeof name, "light%u", l);
        cJSON_AddItemToArray(meshes, mesh_json(name, "light", (int)l, &st->lights[l], NULL));
    }
    if (meshes) {
        cJSON_AddItemToArray(meshes, mesh_json("direct", "direct", -1, &st->direct, &snap->estimate.direct));
        cJSON_AddItemToArray(meshes, mesh_json("indirect", "indirect", -1, &st->indirect, &snap->estimate.indirect));
        if (st->specular.mesh.roots) cJSON_AddItemToArray(meshes, mesh_json("specular", "specular", -1, &st->specular, &snap->estimate.specular));
    }
    return j;
}

lm_result app_write_text(const char *path, const char *text, size_t len, lm_error *err)
{
    char ext[16];
    lm_path_ext(path, ext, sizeof ext);
    return lm_write_file(path, ext[0] ? ext : "tmp", text, len, err);
}

lm_result app_write_json(const char *path, const cJSON *j, lm_error *err)
{
    char *text = j ? cJSON_Print(j) : NULL;
    if (!text) return lm_fail(err, LM_ERR_NO_MEMORY, "%s: out of memory formatting the JSON", path);
    size_t len = strlen(text);
    /* cJSON_Print ends without a newline; text files end with one. */
    char *nl = realloc(text, len + 2);
    if (!nl) {
        cJSON_free(text);
        return lm_fail(err, LM_ERR_NO_MEMORY, "%s: out of memory formatting the JSON", path);
    }
    nl[len] = '\n';
    nl[len + 1] = 0;
    lm_result r = app_write_text(path, nl, len + 1, err);
    free(nl);
    return r;
}

lm_result app_make_dir(const char *path, lm_error *err)
{
    struct stat st;
    if (mkdir(path, 0777) == 0) return LM_OK;
    if (errno == EEXIST && stat(path, &st) == 0 && S_ISDIR(st.st_mode)) return LM_OK;
    return lm_fail(err, LM_ERR_IO, "%s: cannot create the directory (%s)", path, strerror(errno));
}
