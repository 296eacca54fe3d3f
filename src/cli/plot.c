/* plot.c — log-log line charts into an RGB8 image (plot.h). */
#include "src/cli/plot.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <stb_easy_font.h>

enum { SS = PLOT_SUPERSAMPLE, TEXT_SCALE = 2 /* output pixels per font unit */ };

typedef struct canvas {
    uint8_t *px; /* w·h·3, at SS× the output size */
    int w, h;
} canvas;

static void put(canvas *c, int x, int y, const uint8_t rgb[3])
{
    if (x < 0 || y < 0 || x >= c->w || y >= c->h) return;
    memcpy(c->px + 3 * ((size_t)y * (size_t)c->w + (size_t)x), rgb, 3);
}

static void fill_rect(canvas *c, double x0, double y0, double x1, double y1, const uint8_t rgb[3])
{
    int ax = (int)floor(x0), ay = (int)floor(y0), bx = (int)ceil(x1), by = (int)ceil(y1);
    for (int y = ay; y < by; ++y)
        for (int x = ax; x < bx; ++x) put(c, x, y, rgb);
}

/* A line of the given width (canvas pixels) as a run of filled discs; dashes
 * measured along the line so a polyline's pattern is continuous (*phase). */
static void line(canvas *c, double x0, double y0, double x1, double y1, double width, const uint8_t rgb[3],
                 int dashed, double *phase)
{
    double dx = x1 - x0, dy = y1 - y0, len = sqrt(dx * dx + dy * dy);
    double r = 0.5 * width, dash = 8.0 * SS * 2.0;
    int steps = (int)ceil(len / (0.5 * (r > 1 ? r : 1))) + 1;
    for (int i = 0; i <= steps; ++i) {
        double t = (double)i / steps, along = (phase ? *phase : 0.0) + t * len;
        if (dashed && fmod(along, dash) > 0.6 * dash) continue;
        double cx = x0 + t * dx, cy = y0 + t * dy;
        for (int y = (int)floor(cy - r); y <= (int)ceil(cy + r); ++y)
            for (int x = (int)floor(cx - r); x <= (int)ceil(cx + r); ++x)
                if ((x - cx) * (x - cx) + (y - cy) * (y - cy) <= r * r) put(c, x, y, rgb);
    }
    if (phase) *phase += len;
}

/* stb_easy_font knows ASCII 32..126 only. */
static void sanitize(const char *in, char *out, size_t n)
{
    size_t i = 0;
    for (; in && in[i] && i + 1 < n; ++i) out[i] = (in[i] >= 32 && in[i] <= 126) ? in[i] : '?';
    out[i] = 0;
}

static double text_width(const char *text)
{
    char t[256];
    sanitize(text, t, sizeof t);
    return stb_easy_font_width(t) * TEXT_SCALE * SS;
}

/* Text with its top-left corner at (x, y), canvas pixels. */
static void text(canvas *c, double x, double y, const char *s, const uint8_t rgb[3])
{
    float quads[4 * 4 * 1200]; /* x, y, z, colour per vertex; ~270 bytes a character */
    char t[256];
    sanitize(s, t, sizeof t);
    int n = stb_easy_font_print(0, 0, t, NULL, quads, sizeof quads);
    const double k = TEXT_SCALE * SS;
    for (int q = 0; q < n; ++q) {
        const float *v = quads + 16 * q; /* 4 vertices of 4 floats (the colour is the 4th) */
        double qx0 = v[0], qy0 = v[1], qx1 = v[8], qy1 = v[9];
        fill_rect(c, x + k * qx0, y + k * qy0, x + k * qx1, y + k * qy1, rgb);
    }
}

typedef struct axes {
    double x0, y0, x1, y1;    /* plot area, canvas pixels */
    double lx0, lx1, ly0, ly1; /* log10 ranges */
} axes;

static double map_x(const axes *a, double x)
{
    return a->x0 + (log10(x) - a->lx0) / (a->lx1 - a->lx0) * (a->x1 - a->x0);
}

static double map_y(const axes *a, double y)
{
    return a->y1 - (log10(y) - a->ly0) / (a->ly1 - a->ly0) * (a->y1 - a->y0);
}

static int usable(double x, double y) { return isfinite(x) && isfinite(y) && x > 0 && y > 0; }

/* Decade range covering the data (at least one decade). */
static void decades(double lo, double hi, double *a, double *b)
{
    if (!(lo <= hi)) lo = hi = 1.0;
    *a = floor(log10(lo));
    *b = ceil(log10(hi));
    if (*b <= *a) *b = *a + 1;
}

static void tick_label(double e, char *buf, size_t n)
{
    int k = (int)lround(e);
    if (k >= -2 && k <= 3)
        snprintf(buf, n, "%g", pow(10.0, k));
    else
        snprintf(buf, n, "1e%d", k);
}

static void draw_panel(canvas *c, const plot_panel *p, double ox, double oy, double pw, double ph)
{
    static const uint8_t black[3] = {0, 0, 0}, grid[3] = {225, 225, 225}, grey[3] = {110, 110, 110};
    const double u = SS; /* one output pixel */
    /* The legend gets rows of its own above the plot area: it never hides data. */
    const double legend_top = oy + 34 * u;
    axes a = {ox + 70 * u, legend_top + (20 * p->series_count + 6) * u, ox + pw - 16 * u, oy + ph - 48 * u, 0, 0, 0, 0};
    double xlo = INFINITY, xhi = -INFINITY, ylo = INFINITY, yhi = -INFINITY;
    for (int s = 0; s < p->series_count; ++s)
        for (int i = 0; i < p->series[s].count; ++i) {
            double x = p->series[s].x[i], y = p->series[s].y[i];
            if (!usable(x, y)) continue;
            xlo = fmin(xlo, x), xhi = fmax(xhi, x), ylo = fmin(ylo, y), yhi = fmax(yhi, y);
        }
    for (int k = 0; k < PLOT_MAX_HLINES; ++k)
        if (p->hlines[k].y > 0) ylo = fmin(ylo, p->hlines[k].y), yhi = fmax(yhi, p->hlines[k].y);
    decades(xlo, xhi, &a.lx0, &a.lx1);
    decades(ylo, yhi, &a.ly0, &a.ly1);

    /* Grid: decades, and 2 and 5 within them when few decades are shown. */
    char buf[64];
    for (double e = a.lx0; e <= a.lx1 + 1e-9; e += 1.0) {
        for (int m = 1; m <= 9; ++m) {
            double v = log10(m) + e;
            if (v > a.lx1 + 1e-9) break;
            if (m > 1 && a.lx1 - a.lx0 > 3) continue;
            double X = map_x(&a, pow(10.0, v));
            line(c, X, a.y0, X, a.y1, m == 1 ? u : 0.6 * u, grid, 0, NULL);
            if (m == 1 || (a.lx1 - a.lx0 <= 2 && (m == 2 || m == 5))) {
                if (m == 1)
                    tick_label(e, buf, sizeof buf);
                else
                    snprintf(buf, sizeof buf, "%g", m * pow(10.0, e));
                text(c, X - 0.5 * text_width(buf), a.y1 + 8 * u, buf, black);
            }
        }
    }
    for (double e = a.ly0; e <= a.ly1 + 1e-9; e += 1.0) {
        for (int m = 1; m <= 9; ++m) {
            double v = log10(m) + e;
            if (v > a.ly1 + 1e-9) break;
            if (m > 1 && a.ly1 - a.ly0 > 3) continue;
            double Y = map_y(&a, pow(10.0, v));
            line(c, a.x0, Y, a.x1, Y, m == 1 ? u : 0.6 * u, grid, 0, NULL);
            if (m == 1 || (a.ly1 - a.ly0 <= 2 && (m == 2 || m == 5))) {
                if (m == 1)
                    tick_label(e, buf, sizeof buf);
                else
                    snprintf(buf, sizeof buf, "%g", m * pow(10.0, e));
                text(c, a.x0 - 8 * u - text_width(buf), Y - 7 * u, buf, black);
            }
        }
    }
    for (int k = 0; k < PLOT_MAX_HLINES; ++k) {
        if (!(p->hlines[k].y > 0)) continue;
        double Y = map_y(&a, p->hlines[k].y), phase = 0;
        line(c, a.x0, Y, a.x1, Y, 1.5 * u, grey, 1, &phase);
        if (p->hlines[k].label) text(c, a.x0 + 6 * u, Y - 18 * u, p->hlines[k].label, grey);
    }
    /* Frame, titles. */
    line(c, a.x0, a.y0, a.x1, a.y0, u, black, 0, NULL);
    line(c, a.x0, a.y1, a.x1, a.y1, u, black, 0, NULL);
    line(c, a.x0, a.y0, a.x0, a.y1, u, black, 0, NULL);
    line(c, a.x1, a.y0, a.x1, a.y1, u, black, 0, NULL);
    if (p->title) text(c, a.x0, oy + 12 * u, p->title, black);
    if (p->xlabel) text(c, 0.5 * (a.x0 + a.x1) - 0.5 * text_width(p->xlabel), a.y1 + 28 * u, p->xlabel, black);
    if (p->ylabel) text(c, a.x1 - text_width(p->ylabel), oy + 12 * u, p->ylabel, grey);

    /* Series: lines with a dot at each point; the legend above the plot area. */
    for (int s = 0; s < p->series_count; ++s) {
        const plot_series *se = &p->series[s];
        double px = NAN, py = NAN, phase = 0;
        for (int i = 0; i < se->count; ++i) {
            if (!usable(se->x[i], se->y[i])) continue;
            double X = map_x(&a, se->x[i]), Y = map_y(&a, se->y[i]);
            if (isfinite(px)) line(c, px, py, X, Y, 2.5 * u, se->rgb, se->dashed, &phase);
            line(c, X, Y, X, Y, 7 * u, se->rgb, 0, NULL);
            px = X, py = Y;
        }
    }
    for (int s = 0; s < p->series_count; ++s) {
        const plot_series *se = &p->series[s];
        double ly = legend_top + 20 * s * u, lx = a.x0 + 46 * u;
        double lphase = 0;
        line(c, lx - 40 * u, ly + 6 * u, lx - 8 * u, ly + 6 * u, 2.5 * u, se->rgb, se->dashed, &lphase);
        text(c, lx, ly, se->label ? se->label : "", black);
    }
}

lm_result plot_render(const plot_desc *d, uint8_t **rgb, int *width, int *height, lm_error *err)
{
    *rgb = NULL;
    if (!d || d->panel_count < 1 || d->panel_count > 4 || !d->panels)
        return lm_fail(err, LM_ERR_INVALID_ARG, "plot: 1 to 4 panels");
    int pw = d->panel_width > 0 ? d->panel_width : 560, ph = d->panel_height > 0 ? d->panel_height : 480;
    int title_h = d->title ? 34 : 0;
    int W = pw * d->panel_count, H = ph + title_h;
    canvas c = {malloc((size_t)W * SS * (size_t)H * SS * 3), W * SS, H * SS};
    uint8_t *out = malloc((size_t)W * (size_t)H * 3);
    if (!c.px || !out) {
        free(c.px);
        free(out);
        return lm_fail(err, LM_ERR_NO_MEMORY, "plot: out of memory for a %dx%d chart", W, H);
    }
    memset(c.px, 255, (size_t)c.w * (size_t)c.h * 3);
    static const uint8_t black[3] = {0, 0, 0};
    if (d->title) text(&c, 0.5 * c.w - 0.5 * text_width(d->title), 12.0 * SS, d->title, black);
    for (int i = 0; i < d->panel_count; ++i)
        draw_panel(&c, &d->panels[i], (double)i * pw * SS, (double)title_h * SS, (double)pw * SS, (double)ph * SS);
    /* Box filter down to the output size. */
    for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x)
            for (int k = 0; k < 3; ++k) {
                unsigned sum = 0;
                for (int j = 0; j < SS; ++j)
                    for (int i = 0; i < SS; ++i)
                        sum += c.px[3 * ((size_t)(y * SS + j) * (size_t)c.w + (size_t)(x * SS + i)) + (size_t)k];
                out[3 * ((size_t)y * (size_t)W + (size_t)x) + (size_t)k] = (uint8_t)((sum + SS * SS / 2) / (SS * SS));
            }
    free(c.px);
    *rgb = out;
    *width = W;
    *height = H;
    return LM_OK;
}
