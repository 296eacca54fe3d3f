/* samp_gl_direct.c — G of an area light at a batch of points by rasterization
 * (Fournier & Péroche 2005 §5, "Area light sources sampling").
 *
 * Per point x: a frustum from x (lifted off its surface, samp_point_origin)
 * whose axis points at the light and that just contains the part of the light
 * above x's horizon, direct_res² pixels. Its image is the off-axis rectangle
 * around the light's projection (make_frustum: tighter than the paper's square,
 * so the light fills the pixels; raw error at 64² fell from 13.7% worst / 0.58%
 * mean to 0.53% / 0.11% on tests/samp_gl_test.c). The light's front-facing pixels carry
 * max(0,cosθ_x)·dω (shaders/samp_gl_direct.frag); the depth test against the
 * candidate occluders gives visibility; the GPU sums each tile.
 *   raw:              G = Σ visible weights
 *   control variate:  G = G_unoccluded · Σ visible / Σ total, where "total" is
 *                     the light drawn alone into a second attachment first.
 *                     Exact wherever the light is fully visible, and the
 *                     discretisation error of the raw sum cancels in the ratio.
 * Culling: a uniform grid over the scene's triangles; a cell is a candidate when
 * its bounding sphere meets the frustum's bounding cone (paper: the cell centre
 * inside the cone widened by the cell's radius) and it is not beyond the light;
 * the candidate cells' triangles, deduplicated, are that point's index list.
 * Batching: one tile of the atlas per point, one glMultiDrawElementsIndirect per
 * batch (a command per point, baseInstance = its view), one dispatch, one read-back.
 *
 * Limits: a light reaching more than FRUSTUM_MAX_DEG off the frustum's axis (a
 * receiver almost touching a large light) is cut there: the raw estimate loses
 * that grazing part; with the control variate only the visibility ratio is
 * taken from the part seen.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "sampling/samp_gl_internal.h"
#include "src/base/vecmath.h"

#define FRUSTUM_MAX_DEG 85.0
enum {
    GRID_MAX_DIM = 128,
    BATCH_MAX_INDICES = 1 << 23 /* 32 MiB of indices per batch; a point's list always fits a batch */
};

/* ---- grid ----------------------------------------------------------------- */

static void cell_range(const samp_gl_grid *gr, const float lo[3], const float hi[3], int a[3], int b[3])
{
    for (int k = 0; k < 3; ++k) {
        int i0 = (int)floorf((lo[k] - gr->lo[k]) / gr->cell[k]), i1 = (int)floorf((hi[k] - gr->lo[k]) / gr->cell[k]);
        a[k] = i0 < 0 ? 0 : i0 >= gr->dim[k] ? gr->dim[k] - 1 : i0;
        b[k] = i1 < 0 ? 0 : i1 >= gr->dim[k] ? gr->dim[k] - 1 : i1;
    }
}

static void tri_bounds(const scene *s, uint32_t t, float lo[3], float hi[3])
{
    for (int k = 0; k < 3; ++k) {
        lo[k] = INFINITY;
        hi[k] = -INFINITY;
    }
    for (int c = 0; c < 3; ++c)
        for (int k = 0; k < 3; ++k) {
            float x = s->positions[3 * (size_t)s->tris[t].v[c] + (size_t)k];
            lo[k] = fminf(lo[k], x);
            hi[k] = fmaxf(hi[k], x);
        }
}

lm_result samp_gl_grid_build(samp_gl *g, lm_error *err)
{
    const scene *s = g->s;
    samp_gl_grid *gr = &g->grid;
    float ext[3], vol = 1.0f;
    for (int k = 0; k < 3; ++k) {
        ext[k] = fmaxf(s->bounds_max[k] - s->bounds_min[k], 1e-6f * (1.0f + fabsf(s->bounds_max[k])));
        vol *= ext[k];
    }
    /* About two triangles per cell, cells roughly cubic. */
    double cell = cbrt((double)vol / fmax(1.0, 0.5 * s->tri_count));
    size_t cells = 1;
    for (int k = 0; k < 3; ++k) {
        int d = (int)ceil(ext[k] / cell);
        gr->dim[k] = d < 1 ? 1 : d > GRID_MAX_DIM ? GRID_MAX_DIM : d;
        gr->cell[k] = ext[k] / (float)gr->dim[k] * (1.0f + 1e-6f);
        gr->lo[k] = s->bounds_min[k];
        cells *= (size_t)gr->dim[k];
    }
    gr->first = calloc(cells + 1, sizeof *gr->first);
    if (!gr->first) return lm_fail(err, LM_ERR_NO_MEMORY, "GL sampler: out of memory for the culling grid");
    /* Two passes: count, then fill (CSR). A triangle goes into every cell its
     * bounding box overlaps: conservative, never misses an occluder. */
    for (int pass = 0; pass < 2; ++pass) {
        for (uint32_t t = 0; t < s->tri_count; ++t) {
            float lo[3], hi[3];
            int a[3], b[3];
            tri_bounds(s, t, lo, hi);
            cell_range(gr, lo, hi, a, b);
            for (int z = a[2]; z <= b[2]; ++z)
                for (int y = a[1]; y <= b[1]; ++y)
                    for (int x = a[0]; x <= b[0]; ++x) {
                        size_t c = ((size_t)z * (size_t)gr->dim[1] + (size_t)y) * (size_t)gr->dim[0] + (size_t)x;
                        if (pass == 0)
                            gr->first[c + 1]++;
                        else
                            gr->tris[gr->first[c]++] = t;
                    }
        }
        if (pass == 0) {
            for (size_t c = 0; c < cells; ++c) gr->first[c + 1] += gr->first[c];
            gr->tris = malloc((gr->first[cells] ? gr->first[cells] : 1) * sizeof *gr->tris);
            if (!gr->tris) return lm_fail(err, LM_ERR_NO_MEMORY, "GL sampler: out of memory for the culling grid");
        } else {
            /* The fill advanced each start to the next cell's: shift back. */
            memmove(gr->first + 1, gr->first, cells * sizeof *gr->first);
            gr->first[0] = 0;
        }
    }
    return LM_OK;
}

void samp_gl_grid_free(samp_gl_grid *gr)
{
    free(gr->first);
    free(gr->tris);
    memset(gr, 0, sizeof *gr);
}

/* ---- one point's frustum -------------------------------------------------- */

typedef struct frustum {
    double o[3];                /* apex, scene units */
    double ex[3], ey[3], ez[3]; /* eye basis; the frustum looks along -ez (towards the light) */
    double l, r, b, t;          /* image region at unit distance (tangents), off-axis allowed */
    double depth_max;           /* farthest light point along the axis, scene units */
    double near;                /* near plane: a thousandth of the receiver's offset (samp_gl.c says why) */
} frustum;

/* Corners of triangle tri clipped to the half-space dot(p - o, n) >= 0 (x's
 * horizon: the light below it carries no weight) into out; returns how many. */
static int clip_to_horizon(const double tri[3][3], const double o[3], const double n[3], double out[][3])
{
    int m = 0;
    for (int i = 0; i < 3; ++i) {
        const double *a = tri[i], *b = tri[(i + 1) % 3];
        double da = (a[0] - o[0]) * n[0] + (a[1] - o[1]) * n[1] + (a[2] - o[2]) * n[2];
        double db = (b[0] - o[0]) * n[0] + (b[1] - o[1]) * n[1] + (b[2] - o[2]) * n[2];
        if (da >= 0.0) memcpy(out[m++], a, sizeof out[0]);
        if ((da >= 0.0) != (db >= 0.0)) {
            double t = da / (da - db);
            for (int k = 0; k < 3; ++k) out[m][k] = a[k] + t * (b[k] - a[k]);
            ++m;
        }
    }
    return m;
}

/* Fits the region of frustum f (axis -f->ez, basis aligned with `edge` where
 * possible) around the directions d[0..m); returns its area on the unit plane,
 * or INFINITY when a direction is not well in front. */
static double fit_region(frustum *f, lm_dvec3 axis, lm_dvec3 edge, const lm_dvec3 *d, int m)
{
    lm_dvec3 ez = dv3_scale(axis, -1.0);
    lm_dvec3 ex = dv3_sub(edge, dv3_scale(ez, dv3_dot(edge, ez)));
    if (dv3_length(ex) < 1e-6 * dv3_length(edge)) ex = fabs(ez.x) < 0.9 ? dv3(1, 0, 0) : dv3(0, 1, 0);
    ex = dv3_normalize(dv3_sub(ex, dv3_scale(ez, dv3_dot(ex, ez))));
    lm_dvec3 ey = dv3_cross(ez, ex);
    double l = INFINITY, r = -INFINITY, b = INFINITY, t = -INFINITY, dmax = 0.0;
    for (int i = 0; i < m; ++i) {
        double z = -dv3_dot(d[i], ez);
        if (!(z > 1e-6 * dv3_length(d[i]))) return INFINITY;
        double u = dv3_dot(d[i], ex) / z, v = dv3_dot(d[i], ey) / z;
        l = fmin(l, u);
        r = fmax(r, u);
        b = fmin(b, v);
        t = fmax(t, v);
        dmax = fmax(dmax, z);
    }
    /* Wider than FRUSTUM_MAX_DEG off the axis: cut there (file comment). */
    double cap = tan(FRUSTUM_MAX_DEG * M_PI / 180.0);
    l = fmax(l, -cap);
    b = fmax(b, -cap);
    r = fmin(r, cap);
    t = fmin(t, cap);
    /* "Just contains": a hair wider, so the outermost corner is not on the border,
     * and never empty. */
    double pad = 1e-4 * fmax(fmax(r - l, t - b), 1e-6);
    f->l = l - pad;
    f->r = fmax(r, l) + pad;
    f->b = b - pad;
    f->t = fmax(t, b) + pad;
    f->depth_max = dmax;
    memcpy(f->ex, &ex, sizeof f->ex);
    memcpy(f->ey, &ey, sizeof f->ey);
    memcpy(f->ez, &ez, sizeof f->ez);
    return (f->r - f->l) * (f->t - f->b);
}

/* The frustum of point x for light L; 0 when no part of the light is above
 * x's horizon (then G = 0 anyway).
 * The image is res×res pixels over an off-axis rectangle fitted tightly around
 * the light (a square frustum would leave most of its pixels empty for a light
 * seen obliquely). Several axes are tried and the smallest region kept: head-on
 * to the light (its plane parallel to the image, its edges along pixel rows: a
 * rectangular light then fills the image and the raw estimate has no edge
 * error), the receiver's normal, the light's centroid, and the mean direction. */
static int make_frustum(const samp_gl *g, const scene_area_light *L, const samp_point *x, frustum *f, lm_dvec3 *dirs)
{
    const scene *s = g->s;
    float of[3];
    const float eps = samp_point_eps_rt(g->rt, x);
    samp_point_origin(s, x, eps, of);
    lm_dvec3 o = dv3(of[0], of[1], of[2]), n = dv3_normalize(dv3_load(x->n));
    memcpy(f->o, &o, sizeof f->o);
    f->near = SAMP_GL_NEAR_REL * eps;
    int m = 0;
    lm_dvec3 mean = dv3(0, 0, 0), edge = dv3(1, 0, 0);
    for (uint32_t i = 0; i < L->count; ++i) { /* dirs holds 4 per light triangle */
        const uint32_t *v = s->tris[s->light_tris[L->first + i]].v;
        double tri[3][3], poly[4][3];
        for (int c = 0; c < 3; ++c)
            for (int k = 0; k < 3; ++k) tri[c][k] = s->positions[3 * (size_t)v[c] + (size_t)k];
        if (i == 0) edge = dv3(tri[1][0] - tri[0][0], tri[1][1] - tri[0][1], tri[1][2] - tri[0][2]);
        int c = clip_to_horizon(tri, f->o, (const double *)&n, poly);
        for (int j = 0; j < c; ++j) {
            lm_dvec3 d = dv3_sub(dv3(poly[j][0], poly[j][1], poly[j][2]), o);
            double len = dv3_length(d);
            if (!(len > 0.0)) continue;
            dirs[m++] = d;
            mean = dv3_add(mean, dv3_scale(d, 1.0 / len));
        }
    }
    if (m == 0) return 0;
    lm_dvec3 centroid = dv3_sub(dv3_load(L->centroid), o);
    lm_dvec3 axes[4] = {dv3_scale(dv3_load(L->normal), -1.0), n, dv3_normalize(centroid), dv3_normalize(mean)};
    double best = INFINITY;
    frustum trial = *f;
    for (int k = 0; k < 4; ++k) {
        if (!(dv3_length(axes[k]) > 0.5)) continue;
        double area = fit_region(&trial, axes[k], edge, dirs, m);
        if (area < best) {
            best = area;
            *f = trial;
        }
    }
    return best < INFINITY;
}

/* Appends the index list of point x (its candidate occluders and the light) to
 * g->indices; returns the number of indices, or 0 on allocation failure (*r set). */
static size_t list_candidates(samp_gl *g, const scene_area_light *L, const frustum *f, lm_result *r, lm_error *err)
{
    const scene *s = g->s;
    const samp_gl_grid *gr = &g->grid;
    size_t start = g->indices_len;
    if (++g->stamp_serial == 0) { /* wrapped: forget every old stamp */
        memset(g->stamp, 0, s->tri_count * sizeof *g->stamp);
        g->stamp_serial = 1;
    }
    uint32_t serial = g->stamp_serial;
    /* Everything that can block a segment from x to the light lies in the convex
     * hull of x and the light, so its bounding box bounds the cells to test. */
    float lo[3], hi[3];
    for (int k = 0; k < 3; ++k) {
        lo[k] = fminf((float)f->o[k], L->bounds_min[k]);
        hi[k] = fmaxf((float)f->o[k], L->bounds_max[k]);
    }
    int a[3], b[3];
    cell_range(gr, lo, hi, a, b);
    /* The cone around the frustum: its axis, through the farthest region corner. */
    double ru = fmax(fabs(f->l), fabs(f->r)), rv = fmax(fabs(f->b), fabs(f->t));
    double half = atan(sqrt(ru * ru + rv * rv));
    double sin_h = sin(half), cos_h = cos(half);
    double radius = 0.5 * sqrt((double)gr->cell[0] * gr->cell[0] + (double)gr->cell[1] * gr->cell[1] +
                               (double)gr->cell[2] * gr->cell[2]);
    /* Light triangles first: they must be drawn whatever the grid says, and
     * drawn first, so that with GL_GREATER a surface coplanar with the light (a
     * ceiling the light is set into) does not hide it at equal depth. */
    size_t need = start + 3 * (size_t)L->count;
    *r = samp_gl_reserve(&g->indices, &g->indices_cap_cpu, need, sizeof *g->indices, err);
    if (*r != LM_OK) return 0;
    for (uint32_t i = 0; i < L->count; ++i) {
        uint32_t t = s->light_tris[L->first + i];
        g->stamp[t] = serial;
        for (uint32_t c = 0; c < 3; ++c) g->indices[g->indices_len++] = 3 * t + c;
    }
    for (int z = a[2]; z <= b[2]; ++z)
        for (int y = a[1]; y <= b[1]; ++y)
            for (int x = a[0]; x <= b[0]; ++x) {
                size_t c = ((size_t)z * (size_t)gr->dim[1] + (size_t)y) * (size_t)gr->dim[0] + (size_t)x;
                if (gr->first[c] == gr->first[c + 1]) continue;
                double cc[3] = {gr->lo[0] + (x + 0.5) * gr->cell[0], gr->lo[1] + (y + 0.5) * gr->cell[1],
                                gr->lo[2] + (z + 0.5) * gr->cell[2]};
                double v[3] = {cc[0] - f->o[0], cc[1] - f->o[1], cc[2] - f->o[2]};
                double h = -(v[0] * f->ez[0] + v[1] * f->ez[1] + v[2] * f->ez[2]); /* along the axis */
                double q2 = v[0] * v[0] + v[1] * v[1] + v[2] * v[2] - h * h;
                double q = sqrt(fmax(q2, 0.0));
                if (h - radius > f->depth_max) continue; /* wholly beyond the light */
                /* Sphere meets cone: centre within `radius` of the cone. Outside
                 * the cone, its distance to the cone is q·cos − h·sin while the
                 * nearest point is on the lateral surface, else |v| (the apex). */
                double dist = h * cos_h + q * sin_h < 0.0 ? sqrt(q2 + h * h) : q * cos_h - h * sin_h;
                if (dist > radius) continue;
                for (uint32_t i = gr->first[c]; i < gr->first[c + 1]; ++i) {
                    uint32_t t = gr->tris[i];
                    if (g->stamp[t] == serial) continue;
                    g->stamp[t] = serial;
                    *r = samp_gl_reserve(&g->indices, &g->indices_cap_cpu, g->indices_len + 3,
                                         sizeof *g->indices, err);
                    if (*r != LM_OK) return 0;
                    for (uint32_t k = 0; k < 3; ++k) g->indices[g->indices_len++] = 3 * t + k;
                }
            }
    return g->indices_len - start;
}

/* ---- a batch -------------------------------------------------------------- */

static lm_result draw_and_sum(samp_gl *g, const scene_area_light *L, uint32_t light, uint32_t nb, int cv,
                              lm_error *err)
{
    const GladGLContext *gl = g->gl;
    const samp_gl_atlas *a = &g->direct_atlas;
    lm_result r = samp_gl_upload(g, g->view_buf, &g->view_cap, g->views, nb * sizeof *g->views, err);
    if (r == LM_OK)
        r = samp_gl_upload(g, g->index_buf, &g->index_cap, g->indices, g->indices_len * sizeof *g->indices, err);
    if (r == LM_OK) r = samp_gl_upload(g, g->cmd_buf, &g->cmd_cap, g->cmds, nb * sizeof *g->cmds, err);
    if (r != LM_OK) return r;
    samp_gl_begin_draw(g, a, nb);
    gl->UseProgram(g->prog_direct);
    gl->Uniform2f(g->loc_direct_atlas, (float)a->width, (float)a->height);
    gl->Uniform1f(g->loc_direct_light, (float)light);
    gl->VertexArrayVertexBuffer(g->vao, 0, g->scene_vbo, 0, sizeof(samp_gl_vertex));
    gl->VertexArrayElementBuffer(g->vao, g->index_buf);
    if (cv) {
        /* Pass 1: the light alone, no depth test, into attachment 1 (total).
         * Its indices open the index buffer; instance b draws into tile b. */
        gl->Disable(GL_DEPTH_TEST);
        gl->ColorMaski(0, GL_FALSE, GL_FALSE, GL_FALSE, GL_FALSE);
        gl->ColorMaski(1, GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);
        gl->DrawElementsInstancedBaseInstance(GL_TRIANGLES, (GLsizei)(3 * L->count), GL_UNSIGNED_INT, NULL,
                                              (GLsizei)nb, 0);
    }
    /* Pass 2: light and candidate occluders with the depth test, attachment 0. */
    gl->Enable(GL_DEPTH_TEST);
    gl->ColorMaski(0, GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);
    gl->ColorMaski(1, GL_FALSE, GL_FALSE, GL_FALSE, GL_FALSE);
    gl->BindBuffer(GL_DRAW_INDIRECT_BUFFER, g->cmd_buf);
    gl->MultiDrawElementsIndirect(GL_TRIANGLES, GL_UNSIGNED_INT, NULL, (GLsizei)nb, sizeof(samp_gl_draw_cmd));
    gl->VertexArrayElementBuffer(g->vao, 0);
    samp_gl_end_draw(g);
    r = glctx_check(g->ctx, "the direct draw", err);
    if (r == LM_OK) r = samp_gl_reduce(g, a, nb, 2, err);
    return r;
}

lm_result samp_gl_direct(void *impl, uint32_t light, const samp_point *pts, uint32_t n, float *G, lm_error *err)
{
    samp_gl *g = impl;
    const scene *s = g->s;
    const scene_area_light *L = &s->area_lights[light];
    const samp_gl_atlas *a = &g->direct_atlas;
    const int cv = g->desc.direct_control_variate != SAMP_OFF;
    lm_result r = glctx_make_current(g->ctx, err);
    if (r == LM_OK) r = samp_gl_atlas_fit(g, &g->direct_atlas, n, err);
    if (r != LM_OK) return r;
    const uint32_t tiles = (uint32_t)a->cols * (uint32_t)a->rows;
    if (r == LM_OK) r = samp_gl_reserve(&g->views, &g->views_cap_cpu, tiles, sizeof *g->views, err);
    if (r == LM_OK) r = samp_gl_reserve(&g->cmds, &g->cmds_cap_cpu, tiles, sizeof *g->cmds, err);
    if (r == LM_OK)
        r = samp_gl_reserve(&g->batch_point, &g->batch_point_cap_cpu, tiles, sizeof *g->batch_point, err);
    if (r == LM_OK)
        r = samp_gl_reserve(&g->batch_unocc, &g->batch_unocc_cap_cpu, tiles, sizeof *g->batch_unocc, err);
    if (r != LM_OK) return r;

    uint32_t i = 0;
    while (i < n && r == LM_OK) {
        uint32_t nb = 0;
        g->indices_len = 0;
        r = samp_gl_reserve(&g->indices, &g->indices_cap_cpu, 3 * (size_t)L->count, sizeof *g->indices,
                            err);
        for (uint32_t k = 0; r == LM_OK && k < L->count; ++k)
            for (uint32_t c = 0; c < 3; ++c) g->indices[g->indices_len++] = 3 * s->light_tris[L->first + k] + c;
        while (r == LM_OK && i < n && nb < tiles) {
            const samp_point *x = &pts[i];
            double unocc = samp_area_light_unoccluded(s, light, x->p, x->n);
            frustum f;
            /* Behind the light or the light below the horizon: exactly 0, no tile. */
            if (!(unocc > 0.0) || !make_frustum(g, L, x, &f, g->light_dirs)) {
                G[i++] = 0.0f;
                continue;
            }
            size_t before = g->indices_len;
            size_t count = list_candidates(g, L, &f, &r, err);
            if (r != LM_OK) break;
            if (g->indices_len > BATCH_MAX_INDICES && nb > 0) {
                g->indices_len = before; /* full: this point opens the next batch */
                break;
            }
            float rect[4] = {(float)((nb % (uint32_t)a->cols) * (uint32_t)a->tile_w),
                             (float)((nb / (uint32_t)a->cols) * (uint32_t)a->tile_h), (float)a->tile_w,
                             (float)a->tile_h};
            samp_gl_view *v = &g->views[nb];
            samp_gl_view_make(v, f.o, f.ex, f.ey, f.ez, f.l, f.r, f.b, f.t, f.near, rect);
            lm_dvec3 nx = dv3_normalize(dv3_load(x->n));
            v->extra[0] = (float)(nx.x * f.ex[0] + nx.y * f.ex[1] + nx.z * f.ex[2]);
            v->extra[1] = (float)(nx.x * f.ey[0] + nx.y * f.ey[1] + nx.z * f.ey[2]);
            v->extra[2] = (float)(nx.x * f.ez[0] + nx.y * f.ez[1] + nx.z * f.ez[2]);
            v->extra[3] = 0.0f;
            g->cmds[nb] = (samp_gl_draw_cmd){(GLuint)count, 1, (GLuint)before, 0, nb};
            g->batch_point[nb] = i;
            g->batch_unocc[nb] = unocc;
            ++nb;
            ++i;
        }
        if (r != LM_OK || nb == 0) break;
        r = draw_and_sum(g, L, light, nb, cv, err);
        for (uint32_t b = 0; r == LM_OK && b < nb; ++b) {
            double vis = g->sums[2 * b], total = g->sums[2 * b + 1], value;
            if (!cv)
                value = vis;
            else
                value = total > 0.0 ? g->batch_unocc[b] * fmin(vis / total, 1.0) : 0.0;
            G[g->batch_point[b]] = isfinite(value) && value > 0.0 ? (float)value : 0.0f;
        }
    }
    return r;
}
