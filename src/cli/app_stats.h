/* app_stats.h — the `--stats FILE.json` of render, converge and view: per-mesh
 * sample statistics, sampler time by back end and per-frame pass timings, as one
 * JSON object. Every field is described in docs/stats.md; keep the two together.
 *
 * Usage:
 *     cJSON *j = app_stats_json(&(app_stats_desc){.command = "render", .snap = snap, ...});
 *     app_write_json(path, j, &err);   // whole file or nothing (temporary + rename)
 *     cJSON_Delete(j);
 *
 * Does NOT do: reading the statistics back, any other output format.
 */
#ifndef LUMESH_APP_STATS_H
#define LUMESH_APP_STATS_H

#include <cjson/cJSON.h>

#include "mesh/cache/cache_worker.h"
#include "src/base/util.h"
#include "src/render/rend_frame.h"
#include "src/render/rend_residual.h"

typedef struct app_stats_desc {
    const char *command;          /* "render", "converge", "view" */
    const char *scene;            /* the scene's source (path, or "built-in") */
    int width, height;            /* image pixels */
    int supersample;              /* samples per pixel edge of the final image; 0 = 1 */
    double seconds;               /* wall time from the scene loaded to the statistics */
    double first_image_seconds;   /* from the scene loaded to the first image drawn; < 0 = not measured */
    double converged_seconds;     /* from the scene loaded to the cache's first convergence claim (the
                                     snapshot's converged_at); 0 = never or not measured (null) */
    const cache_snapshot *snap;   /* the last snapshot drawn (required) */
    double id_seconds;            /* the ID pass */
    const rend_frame_times *frame;/* the last frame's passes; NULL = none drawn */
    uint64_t frames;              /* frames drawn */
    const rend_residual_info *residual; /* the path-traced residual that corrected the picture; NULL = none */
    /* Named moments before the first image ("first_image_phases": seconds from the
     * clock's start, in this order; < 0 = not reached, written as null). */
    const char *const *phase_names;
    const double *phase_seconds;
    int phase_count;
} app_stats_desc;

/* Adds j[key] = {names[i]: seconds[i]} for i < n, a negative time as null (a
 * moment not reached): the first image's phases of `view` and `converge`. */
void app_stats_add_phases(cJSON *j, const char *key, const char *const *names, const double *seconds, int n);

/* The statistics object; NULL when out of memory. The caller deletes it. */
cJSON *app_stats_json(const app_stats_desc *d);

/* Writes j, pretty-printed, to path through a temporary file renamed into place,
 * so a failure or an interruption leaves no partial file. */
lm_result app_write_json(const char *path, const cJSON *j, lm_error *err);

/* Writes text (len bytes) the same way. */
lm_result app_write_text(const char *path, const char *text, size_t len, lm_error *err);

/* Creates directory `path` (one level) unless it exists already as a directory. */
lm_result app_make_dir(const char *path, lm_error *err);

#endif
