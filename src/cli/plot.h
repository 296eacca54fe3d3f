/* plot.h — log-log line charts rasterised to an RGB8 image (for
 * `lumesh converge`'s convergence.png): panels side by side, each with decade
 * grid lines, tick labels, axis titles, a legend above the plot, and optional horizontal
 * reference lines. Text is stb_easy_font's (ASCII only). Lines are drawn at
 * PLOT_SUPERSAMPLE× the output size and box-filtered down (anti-aliasing).
 *
 * Usage:
 *     plot_series s[2] = {{.label = "lumesh", .x = t, .y = e, .count = n, .rgb = {200, 40, 40}}, ...};
 *     plot_panel p = {.title = "relMSE", .xlabel = "seconds", .series = s, .series_count = 2};
 *     uint8_t *rgb; int w, h;
 *     plot_render(&(plot_desc){.title = "CornellBox-Water", .panels = &p, .panel_count = 1}, &rgb, &w, &h, &err);
 *     ... img_write ...; free(rgb);
 *
 * Points whose x or y is not finite or not > 0 are skipped (a log axis cannot
 * show them); a series left with no point is listed in the legend only.
 * Does NOT do: linear axes, non-ASCII text, vector output.
 */
#ifndef LUMESH_PLOT_H
#define LUMESH_PLOT_H

#include <stdint.h>

#include "src/base/util.h"

enum { PLOT_SUPERSAMPLE = 3, PLOT_MAX_HLINES = 4 };

typedef struct plot_series {
    const char *label;
    const double *x, *y;
    int count;
    uint8_t rgb[3];
    int dashed;            /* non-zero: dashed line */
} plot_series;

typedef struct plot_hline {
    double y;              /* > 0 */
    const char *label;
} plot_hline;

typedef struct plot_panel {
    const char *title, *xlabel, *ylabel;
    const plot_series *series;
    int series_count;
    plot_hline hlines[PLOT_MAX_HLINES]; /* y = 0 entries are unused */
} plot_panel;

typedef struct plot_desc {
    const char *title;          /* above all panels; NULL = none */
    const plot_panel *panels;
    int panel_count;            /* 1..4 */
    int panel_width, panel_height; /* output pixels per panel; 0 = 560 × 480 */
} plot_desc;

/* Renders the chart into a new RGB8 image (*rgb, malloc'd, top row first). */
lm_result plot_render(const plot_desc *d, uint8_t **rgb, int *width, int *height, lm_error *err);

#endif
