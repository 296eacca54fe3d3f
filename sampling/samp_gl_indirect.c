/* samp_gl_indirect.c — one-bounce indirect irradiance E_i(x) = ∫ L cosθ dω by
 * rasterizing the coarse radiance mesh around x (Fournier & Péroche 2005 §5,
 * "Indirect irradiance sampling"; docs/architecture.md, eq. 7).
 *
 * SAMP_INDIRECT_HEMICUBE (default): a hemicube on x's normal, the front face
 * res×res and four half faces res×res/2, packed in one 3res×res tile:
 *     [ front res×res | +v over −v: res×res/2 each | +u, −u: res/2×res each ]
 * (each half face is laid so that its horizon edge is a tile edge). It covers
 * the whole hemisphere.
 * SAMP_INDIRECT_PLANE160: the paper's single image plane with a 160° field of
 * view (res×res), limited to the 80° cone around the normal; it misses the
 * grazing ring: a constant radiance L gives π·L·sin²80° instead of π·L.
 *
 * Weights: cosθ·dω of each pixel is precomputed once (weight_tex, one tile) as
 * the exact integral over the pixel — Lambert's formula for the pixel's quad
 * seen from x (samp_polygon_G), not a midpoint value — so the hemicube's
 * weights add up to π to double rounding and a constant radiance gives π·L
 * to float precision. For the 160° plane the pixels cut by the cone's rim are
 * integrated over 16×16 sub-quads whose centres lie inside it.
 * The radiance is Gouraud-interpolated over each radiance-mesh triangle and
 * seen from its front only (a back face is black, as for the Embree back end's
 * rays); scene triangles without radiance-mesh triangles are
 * drawn black (they still occlude, as the Embree back end's rays see them).
 * Near plane: eps/1000 (samp_gl.c); the hemicube starts eps above the
 * surface (samp_point_origin) and its side faces stop at the horizon, so the
 * receiver's own surface and what lies behind it are not seen.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "sampling/analytic.h"
#include "sampling/samp_gl_internal.h"

#define PLANE160_HALF_DEG 80.0
enum { FACES_MAX = 5, RIM_SUB = 16 };

/* One face of a tile, in the receiver's local frame (u, v, n) = (x, y, z). */
typedef struct face {
    double ex[3], ez[3];        /* image right and (minus) view direction; ey = ez × ex */
    double l, r, b, t;          /* region on the unit-distance image plane */
    int x0, y0, w, h;           /* rectangle in the tile, in units of res/2 */
} face;

/* The faces of the mode: x0..h in half-res units. */
static int faces_of(samp_indirect_mode mode, face *f)
{
    if (mode == SAMP_INDIRECT_PLANE160) {
        double T = tan(PLANE160_HALF_DEG * M_PI / 180.0);
        f[0] = (face){{1, 0, 0}, {0, 0, -1}, -T, T, -T, T, 0, 0, 2, 2};
        return 1;
    }
    f[0] = (face){{1, 0, 0}, {0, 0, -1}, -1, 1, -1, 1, 0, 0, 2, 2};  /* along n */
    f[1] = (face){{1, 0, 0}, {0, -1, 0}, -1, 1, 0, 1, 2, 1, 2, 1};   /* along +v, up = n */
    f[2] = (face){{-1, 0, 0}, {0, 1, 0}, -1, 1, 0, 1, 2, 0, 2, 1};   /* along -v */
    f[3] = (face){{0, 0, 1}, {-1, 0, 0}, 0, 1, -1, 1, 4, 0, 1, 2};   /* along +u, right = n */
    f[4] = (face){{0, 0, 1}, {1, 0, 0}, 0, 1, -1, 1, 5, 0, 1, 2};    /* along -u */
    return 5;
}

static void cross3(const double a[3], const double b[3], double out[3])
{
    out[0] = a[1] * b[2] - a[2] * b[1];
    out[1] = a[2] * b[0] - a[0] * b[2];
    out[2] = a[0] * b[1] - a[1] * b[0];
}

/* ∫ cosθ dω over the image-plane rectangle [u0,u1]×[v0,v1] of face f, seen
 * from the origin with normal z: Lambert's formula on the quad. */
static double quad_weight(const face *f, double u0, double u1, double v0, double v1)
{
    double ey[3], q[4][3];
    cross3(f->ez, f->ex, ey);
    const double uv[4][2] = {{u0, v0}, {u1, v0}, {u1, v1}, {u0, v1}};
    for (int c = 0; c < 4; ++c)
        for (int k = 0; k < 3; ++k) q[c][k] = f->ex[k] * uv[c][0] + ey[k] * uv[c][1] - f->ez[k];
    /* The quad emits towards the origin in one of its two windings. */
    const double o[3] = {0, 0, 0}, n[3] = {0, 0, 1};
    double rev[4][3];
    for (int c = 0; c < 4; ++c) memcpy(rev[c], q[3 - c], sizeof rev[c]);
    return fmax(samp_polygon_G(q, 4, o, n), samp_polygon_G(rev, 4, o, n));
}

static lm_result make_weights(samp_gl *g, int res, samp_indirect_mode mode, int tile_w, int tile_h, lm_error *err)
{
    face f[FACES_MAX];
    int nf = faces_of(mode, f);
    float *w = calloc((size_t)tile_w * (size_t)tile_h, sizeof *w);
    if (!w) return lm_fail(err, LM_ERR_NO_MEMORY, "GL sampler: out of memory for the hemicube weights");
    double T2 = pow(tan(PLANE160_HALF_DEG * M_PI / 180.0), 2.0);
    for (int i = 0; i < nf; ++i) {
        int x0 = f[i].x0 * res / 2, y0 = f[i].y0 * res / 2, pw = f[i].w * res / 2, ph = f[i].h * res / 2;
        for (int py = 0; py < ph; ++py)
            for (int px = 0; px < pw; ++px) {
                double u0 = f[i].l + (f[i].r - f[i].l) * px / pw, u1 = f[i].l + (f[i].r - f[i].l) * (px + 1) / pw;
                double v0 = f[i].b + (f[i].t - f[i].b) * py / ph, v1 = f[i].b + (f[i].t - f[i].b) * (py + 1) / ph;
                double wt;
                if (mode != SAMP_INDIRECT_PLANE160) {
                    wt = quad_weight(&f[i], u0, u1, v0, v1);
                } else {
                    int inside = 0;
                    for (int c = 0; c < 4; ++c) {
                        double cu = c & 1 ? u1 : u0, cv = c & 2 ? v1 : v0;
                        inside += cu * cu + cv * cv <= T2;
                    }
                    if (inside == 4) {
                        wt = quad_weight(&f[i], u0, u1, v0, v1);
                    } else if (inside == 0) {
                        wt = 0.0;
                    } else { /* on the rim: the sub-quads whose centre is inside */
                        wt = 0.0;
                        for (int sy = 0; sy < RIM_SUB; ++sy)
                            for (int sx = 0; sx < RIM_SUB; ++sx) {
                                double a0 = u0 + (u1 - u0) * sx / RIM_SUB, a1 = u0 + (u1 - u0) * (sx + 1) / RIM_SUB;
                                double b0 = v0 + (v1 - v0) * sy / RIM_SUB, b1 = v0 + (v1 - v0) * (sy + 1) / RIM_SUB;
                                double cu = 0.5 * (a0 + a1), cv = 0.5 * (b0 + b1);
                                if (cu * cu + cv * cv <= T2) wt += quad_weight(&f[i], a0, a1, b0, b1);
                            }
                    }
                }
                w[(size_t)(y0 + py) * (size_t)tile_w + (size_t)(x0 + px)] = (float)wt;
            }
    }
    const GladGLContext *gl = g->gl;
    gl->CreateTextures(GL_TEXTURE_2D, 1, &g->weight_tex);
    gl->TextureStorage2D(g->weight_tex, 1, GL_R32F, tile_w, tile_h);
    gl->TextureSubImage2D(g->weight_tex, 0, 0, 0, tile_w, tile_h, GL_RED, GL_FLOAT, w);
    free(w);
    return glctx_check(g->ctx, "the weight texture", err);
}

/* The radiance mesh as unwelded vertices, plus black scene triangles where it
 * has none; returns the vertex count. */
static lm_result build_vertices(samp_gl *g, const samp_radiance_mesh *m, size_t *count, lm_error *err)
{
    const scene *s = g->s;
    size_t tris = m->tri_count;
    for (uint32_t t = 0; t < s->tri_count; ++t) tris += m->first[t] == m->first[t + 1];
    samp_gl_vertex *v = malloc((tris ? 3 * tris : 1) * sizeof *v);
    if (!v) return lm_fail(err, LM_ERR_NO_MEMORY, "GL sampler: out of memory for %zu radiance triangles", tris);
    size_t k = 0;
    for (uint32_t t = 0; t < s->tri_count; ++t) {
        const float *p[3];
        for (int c = 0; c < 3; ++c) p[c] = s->positions + 3 * (size_t)s->tris[t].v[c];
        if (m->first[t] == m->first[t + 1]) {
            for (int c = 0; c < 3; ++c, ++k) {
                memcpy(v[k].pos, p[c], sizeof v[k].pos);
                memset(v[k].attr, 0, sizeof v[k].attr);
            }
            continue;
        }
        for (uint32_t i = m->first[t]; i < m->first[t + 1]; ++i)
            for (int c = 0; c < 3; ++c, ++k) {
                float w1 = m->bary[6 * (size_t)i + 2 * (size_t)c], w2 = m->bary[6 * (size_t)i + 2 * (size_t)c + 1];
                for (int a = 0; a < 3; ++a) {
                    /* Relative to corner 0: exact at the corners, no cancellation of large coordinates. */
                    v[k].pos[a] = p[0][a] + w1 * (p[1][a] - p[0][a]) + w2 * (p[2][a] - p[0][a]);
                    v[k].attr[a] = m->radiance[9 * (size_t)i + 3 * (size_t)c + (size_t)a];
                }
            }
    }
    lm_result r = samp_gl_upload(g, g->radiance_vbo, &g->radiance_cap, v, k * sizeof *v, err);
    free(v);
    *count = k;
    return r;
}

/* Atlas and weights at the first call (a sampler used only for direct light
 * never pays for them). */
static lm_result prepare(samp_gl *g, lm_error *err)
{
    if (g->indirect_atlas.fbo) return LM_OK;
    int res = g->desc.indirect_res + (g->desc.indirect_res & 1); /* half faces need an even size */
    int hemi = g->desc.indirect_mode != SAMP_INDIRECT_PLANE160;
    int tw = hemi ? 3 * res : res, th = res;
    lm_result r = samp_gl_atlas_make(g, &g->indirect_atlas, tw, th, GL_RGBA32F, 1, 1, err);
    if (r == LM_OK) r = make_weights(g, res, g->desc.indirect_mode, tw, th, err);
    return r;
}

/* Orthonormal u, v with u × v = n. */
static void frame(const double n[3], double u[3], double v[3])
{
    double h[3] = {0, 0, 0};
    h[fabs(n[0]) < 0.6 ? 0 : 1] = 1.0;
    cross3(h, n, u);
    double l = sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2]);
    for (int k = 0; k < 3; ++k) u[k] /= l;
    cross3(n, u, v);
}

lm_result samp_gl_indirect(void *impl, const samp_radiance_mesh *mesh, const samp_point *pts, uint32_t n, float *E,
                           lm_error *err)
{
    samp_gl *g = impl;
    const GladGLContext *gl = g->gl;
    lm_result r = glctx_make_current(g->ctx, err);
    if (r == LM_OK) r = prepare(g, err);
    if (r == LM_OK) r = samp_gl_atlas_fit(g, &g->indirect_atlas, n, err);
    size_t vcount = 0;
    if (r == LM_OK) r = build_vertices(g, mesh, &vcount, err);
    const samp_gl_atlas *a = &g->indirect_atlas;
    int res = a->tile_h;
    face f[FACES_MAX];
    int nf = faces_of(g->desc.indirect_mode, f);
    uint32_t tiles = (uint32_t)a->cols * (uint32_t)a->rows;
    if (r == LM_OK)
        r = samp_gl_reserve(&g->views, &g->views_cap_cpu, (size_t)nf * tiles, sizeof *g->views, err);
    for (uint32_t first = 0; r == LM_OK && first < n; first += tiles) {
        uint32_t nb = n - first < tiles ? n - first : tiles;
        for (uint32_t b = 0; b < nb; ++b) {
            const samp_point *x = &pts[first + b];
            float of[3];
            const float eps = samp_point_eps_rt(g->rt, x);
            samp_point_origin(g->s, x, eps, of);
            double o[3] = {of[0], of[1], of[2]}, nn[3] = {x->n[0], x->n[1], x->n[2]}, u[3], v[3];
            double len = sqrt(nn[0] * nn[0] + nn[1] * nn[1] + nn[2] * nn[2]);
            for (int k = 0; k < 3; ++k) nn[k] = len > 0.0 ? nn[k] / len : (k == 2);
            frame(nn, u, v);
            int tx = (int)(b % (uint32_t)a->cols) * a->tile_w, ty = (int)(b / (uint32_t)a->cols) * a->tile_h;
            for (int i = 0; i < nf; ++i) {
                double ex[3], ez[3], ey[3];
                for (int k = 0; k < 3; ++k) {
                    ex[k] = f[i].ex[0] * u[k] + f[i].ex[1] * v[k] + f[i].ex[2] * nn[k];
                    ez[k] = f[i].ez[0] * u[k] + f[i].ez[1] * v[k] + f[i].ez[2] * nn[k];
                }
                cross3(ez, ex, ey);
                const float rect[4] = {(float)(tx + f[i].x0 * res / 2), (float)(ty + f[i].y0 * res / 2),
                                       (float)(f[i].w * res / 2), (float)(f[i].h * res / 2)};
                samp_gl_view_make(&g->views[(size_t)b * (size_t)nf + (size_t)i], o, ex, ey, ez, f[i].l, f[i].r,
                                  f[i].b, f[i].t, SAMP_GL_NEAR_REL * eps, rect);
            }
        }
        r = samp_gl_upload(g, g->view_buf, &g->view_cap, g->views, (size_t)nb * (size_t)nf * sizeof *g->views, err);
        if (r != LM_OK) break;
        samp_gl_begin_draw(g, a, nb);
        gl->UseProgram(g->prog_indirect);
        gl->Uniform2f(g->loc_indirect_atlas, (float)a->width, (float)a->height);
        gl->VertexArrayVertexBuffer(g->vao, 0, g->radiance_vbo, 0, sizeof(samp_gl_vertex));
        gl->Enable(GL_DEPTH_TEST);
        if (vcount)
            gl->DrawArraysInstancedBaseInstance(GL_TRIANGLES, 0, (GLsizei)vcount, (GLsizei)(nb * (uint32_t)nf), 0);
        samp_gl_end_draw(g);
        r = glctx_check(g->ctx, "the indirect draw", err);
        if (r == LM_OK) r = samp_gl_reduce(g, a, nb, 3, err);
        for (uint32_t b = 0; r == LM_OK && b < nb; ++b)
            for (int k = 0; k < 3; ++k) {
                float e = g->sums[3 * b + (uint32_t)k];
                E[3 * (size_t)(first + b) + (size_t)k] = isfinite(e) && e > 0.0f ? e : 0.0f;
            }
    }
    return r;
}
