/* cache_site.c — the lowest file of the cache (cache_internal.h): where values are
 * asked (a vertex as the sampler's receiver, its unoccluded G), the leaves and
 * regions of the meshes in barycentric space, and what the viewer sees of a value
 * (the composite's formula, paper §6), which every JND test of the cache uses.
 * Calls nothing of the cache's other files. Worker thread, like the rest. */
#include "mesh/cache/cache_internal.h"

#include <math.h>
#include <string.h>

#include "sampling/analytic.h"
#include "src/base/vecmath.h"

mesh_qmesh *cache_kind_mesh(const cache *c, cache_kind kind)
{
    return kind == CACHE_KIND_DIRECT ? c->direct : kind == CACHE_KIND_INDIRECT ? c->indirect : c->specular;
}

samp_point cache_vertex_point(const cache *c, uint32_t vid)
{
    const mesh_vertex *v = mesh_vtable_vertex(c->vt, vid);
    samp_point p = {.tri_plus_one = v->tri + 1};
    memcpy(p.p, v->position, sizeof p.p);
    memcpy(p.n, v->normal, sizeof p.n);
    return p;
}

double cache_unoccluded_at(const scene *s, uint32_t l, const float p[3], const float n[3])
{
    if (l < s->area_light_count) return samp_area_light_unoccluded(s, l, p, n);
    const float *q = s->point_lights[l - s->area_light_count].position;
    const double Q[3] = {q[0], q[1], q[2]}, X[3] = {p[0], p[1], p[2]}, N[3] = {n[0], n[1], n[2]};
    return samp_point_G(Q, X, N);
}

double cache_unoccluded(const cache *c, uint32_t l, uint32_t vid)
{
    const mesh_vertex *v = mesh_vtable_vertex(c->vt, vid);
    return cache_unoccluded_at(c->s, l, v->position, v->normal);
}

/* ---- leaves and regions ------------------------------------------------------- */

void cache_node_corner_bary(const mesh_qnode *n, int k, double *w1, double *w2)
{
    mesh_bary b = mesh_qmesh_node_corner(n, k);
    double scale = ldexp(1.0, -(int)b.depth);
    *w1 = b.w[1] * scale;
    *w2 = b.w[2] * scale;
}

/* Is (w1, w2) inside the closed triangle (a, b, c) of barycentric space, either
 * winding? The tolerance is relative to the triangle's size: a leaf at depth 21
 * has edges of 2^-21 and cross products of 2^-42 (2.3e-13), below the absolute
 * 1e-12 this used to allow, so that every child "contained" every point and the
 * Veach door's refinement stopped on a light leaf that did not hold its site. */
static int bary_in_triangle(const double a[2], const double b[2], const double c[2], double w1, double w2)
{
    const double area2 = fabs((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]));
    const double eps = 1e-9 * area2;
    double d0 = (b[0] - a[0]) * (w2 - a[1]) - (b[1] - a[1]) * (w1 - a[0]);
    double d1 = (c[0] - b[0]) * (w2 - b[1]) - (c[1] - b[1]) * (w1 - b[0]);
    double d2 = (a[0] - c[0]) * (w2 - c[1]) - (a[1] - c[1]) * (w1 - c[0]);
    int neg = d0 < -eps || d1 < -eps || d2 < -eps, pos = d0 > eps || d1 > eps || d2 > eps;
    return !(neg && pos);
}

int cache_region_contains(const cache_region *rg, double w1, double w2)
{
    const double a[2] = {rg->w1[0], rg->w2[0]}, b[2] = {rg->w1[1], rg->w2[1]}, c[2] = {rg->w1[2], rg->w2[2]};
    return bary_in_triangle(a, b, c, w1, w2);
}

uint32_t cache_find_leaf(const mesh_qmesh *m, uint32_t tri, double w1, double w2)
{
    if (mesh_qmesh_root(m, tri) == MESH_QMESH_NONE) return MESH_QMESH_NONE;
    /* The tree's own descent (mesh_qmesh_locate: barycentrics within each node,
     * doubled at each level, exact on the dyadic lattice at any depth), on the
     * point brought inside the triangle if rounding left it outside. */
    if (!(w1 >= 0.0)) w1 = 0.0;
    if (!(w2 >= 0.0)) w2 = 0.0;
    if (w1 + w2 > 1.0) {
        const double sum = w1 + w2;
        w1 /= sum;
        w2 /= sum;
    }
    uint32_t leaf = MESH_QMESH_NONE;
    double l[3];
    lm_error ignore;
    if (mesh_qmesh_locate(m, tri, w1, w2, &leaf, l, &ignore) != LM_OK) return MESH_QMESH_NONE;
    return leaf;
}

lm_result cache_region_walk(const mesh_qmesh *m, const cache_region *rg, cache_node_fn visit, void *user, lm_error *err)
{
    uint32_t root = mesh_qmesh_root(m, rg->tri);
    if (root == MESH_QMESH_NONE) return LM_OK;
    const double eps = 1e-12;
    double lo1 = fmin(rg->w1[0], fmin(rg->w1[1], rg->w1[2])) - eps, hi1 = fmax(rg->w1[0], fmax(rg->w1[1], rg->w1[2])) + eps;
    double lo2 = fmin(rg->w2[0], fmin(rg->w2[1], rg->w2[2])) - eps, hi2 = fmax(rg->w2[0], fmax(rg->w2[1], rg->w2[2])) + eps;
    uint32_t stack[4 * (MESH_DEPTH_MAX + 2)];
    uint32_t top = 0;
    stack[top++] = root;
    lm_result r = LM_OK;
    while (r == LM_OK && top) {
        uint32_t node = stack[--top];
        const mesh_qnode *n = mesh_qmesh_node(m, node);
        double a1 = INFINITY, b1 = -INFINITY, a2 = INFINITY, b2 = -INFINITY;
        for (int k = 0; k < 3; ++k) {
            double w1, w2;
            cache_node_corner_bary(n, k, &w1, &w2);
            a1 = fmin(a1, w1);
            b1 = fmax(b1, w1);
            a2 = fmin(a2, w2);
            b2 = fmax(b2, w2);
        }
        if (b1 < lo1 || a1 > hi1 || b2 < lo2 || a2 > hi2) continue;
        r = visit(m, node, n, user, err);
        if (r == LM_OK && n->child != MESH_QMESH_NONE)
            for (uint32_t k = 0; k < 4; ++k) stack[top++] = n->child + k;
    }
    return r;
}

/* ---- what the viewer sees (paper §6) ------------------------------------------ */

void cache_seen_radiance(const scene_material *m, int front, const float ldd[3], const float ei[3],
                         const float lds[3], float rgb[3])
{
    /* The composite's order of operations, so the cache judges the colour the
     * display shows (a float added as 0 where a term is absent changes nothing). */
    for (int k = 0; k < 3; ++k) {
        float le = front ? m->le[k] : 0.0f, spec = lds ? m->ks[k] * lds[k] : 0.0f;
        rgb[k] = le + m->kd[k] * (ldd[k] + ei[k] * (float)(1.0 / M_PI)) + spec;
    }
}

int cache_sees_front(const cache *c, uint32_t tri)
{
    const scene *s = c->s;
    const float *n = s->tri_normals + 3 * (size_t)tri, *p = s->positions + 3 * (size_t)s->tris[tri].v[0];
    double d = 0.0;
    for (int k = 0; k < 3; ++k) d += ((double)c->eye[k] - p[k]) * n[k];
    return d > 0.0;
}

/* cache_seen_radiance's `front` for tri as the viewer sees it: only an
 * emitter's side matters; the others skip the plane test. */
static int seen_front(const cache *c, uint32_t tri, const scene_material *m)
{
    return m->le[0] > 0.0f || m->le[1] > 0.0f || m->le[2] > 0.0f ? cache_sees_front(c, tri) : 1;
}

void cache_seen_lab(const cache *c, uint32_t tri, const float ldd[3], const float ei[3], const float lds[3],
                    float lab[3])
{
    const scene_material *m = &c->s->materials[c->s->tris[tri].material];
    const int front = seen_front(c, tri, m);
    float rgb[3];
    cache_seen_radiance(m, front, ldd, ei, lds, rgb);
    tm_linear_to_lab(&c->tm, rgb, lab); /* the display's Lab, without the sRGB round trip */
}

/* The other kinds' values at (w1, w2) of scene triangle tri, into term (kind's
 * own is the caller's). root_vid: the vertex there when it is a corner of the
 * triangle's root (else MESH_VTABLE_NONE): where the other mesh's root shares
 * it, its interpolation is that vertex's own value (mesh_qmesh_interpolate: the
 * located leaf has it as a corner, weights 1, 0, 0), so the value is read, not
 * located: scheduling a big scene's roots made 1.2 µs a leaf of tree descents
 * (0.42 s over the 116k-triangle box). */
static void other_terms(const cache *c, cache_kind kind, uint32_t tri, double w1, double w2, uint32_t root_vid,
                        float term[CACHE_KINDS][3])
{
    lm_error ignore;
    for (int j = 0; j < CACHE_KINDS; ++j) {
        const mesh_qmesh *mk = j == (int)kind ? NULL : cache_kind_mesh(c, (cache_kind)j);
        uint32_t root = mk ? mesh_qmesh_root(mk, tri) : MESH_QMESH_NONE;
        if (root == MESH_QMESH_NONE) continue;
        if (root_vid != MESH_VTABLE_NONE) {
            const mesh_qnode *rn = mesh_qmesh_node(mk, root);
            if ((rn->v[0] == root_vid || rn->v[1] == root_vid || rn->v[2] == root_vid) &&
                mesh_qmesh_get_value(mk, root_vid, term[j]) == 1)
                continue;
        }
        mesh_qmesh_interpolate(mk, tri, w1, w2, term[j], &ignore);
    }
}

void cache_other_terms_at(const cache *c, cache_kind kind, uint32_t tri, double w1, double w2,
                          float term[CACHE_KINDS][3])
{
    memset(term, 0, CACHE_KINDS * sizeof term[0]);
    other_terms(c, kind, tri, w1, w2, MESH_VTABLE_NONE, term);
}

void cache_seen_lab_with(const cache *c, cache_kind kind, uint32_t tri, double w1, double w2, const float value[3],
                         float lab[3])
{
    float term[CACHE_KINDS][3] = {{0, 0, 0}, {0, 0, 0}, {0, 0, 0}};
    memcpy(term[kind], value, sizeof term[kind]);
    other_terms(c, kind, tri, w1, w2, MESH_VTABLE_NONE, term);
    cache_seen_lab(c, tri, term[CACHE_KIND_DIRECT], term[CACHE_KIND_INDIRECT], term[CACHE_KIND_SPECULAR], lab);
}

/* Has the leaf of mesh `kind` holding (w1, w2) of tri passed its own test (done,
 * or too small for one: cache_leaf_below_sample)? Its interpolation there is then
 * what its test accepted, not a guess waiting for one. */
static int settled_at(const cache *c, cache_kind kind, uint32_t tri, double w1, double w2)
{
    const mesh_qmesh *m = cache_kind_mesh(c, kind);
    const uint32_t leaf = cache_find_leaf(m, tri, w1, w2);
    if (leaf == MESH_QMESH_NONE) return 0;
    if (leaf < c->sched.done_cap[kind] && c->sched.done[kind][leaf]) return 1;
    const mesh_qnode *n = mesh_qmesh_node(m, leaf);
    const double px = c->pixels ? ldexp((double)c->pixels[tri], -2 * (int)n->depth) : 1e6;
    return cache_leaf_below_sample(c, kind, px, n);
}

void cache_edge_background(const cache *c, cache_kind kind, uint32_t tri, const double w1[3], const double w2[3],
                           float term[CACHE_KINDS][3])
{
    memset(term, 0, CACHE_KINDS * sizeof term[0]);
    lm_error ignore;
    for (int j = 0; j < CACHE_KINDS; ++j) {
        const mesh_qmesh *m = j == (int)kind ? NULL : cache_kind_mesh(c, (cache_kind)j);
        /* No tree there, or a leaf not yet tested: 0 (and nothing interpolated). */
        if (!m || mesh_qmesh_root(m, tri) == MESH_QMESH_NONE || !settled_at(c, (cache_kind)j, tri, w1[0], w2[0]))
            continue;
        for (int p = 0; p < 3; ++p) {
            float at[3] = {0, 0, 0};
            mesh_qmesh_interpolate(m, tri, w1[p], w2[p], at, &ignore);
            for (int ch = 0; ch < 3; ++ch) term[j][ch] = p == 0 ? at[ch] : fminf(term[j][ch], at[ch]);
        }
    }
}

void cache_seen_lab_over(const cache *c, cache_kind kind, uint32_t tri, const float background[CACHE_KINDS][3],
                         const float value[3], float lab[3])
{
    float term[CACHE_KINDS][3];
    memcpy(term, background, sizeof term);
    memcpy(term[kind], value, sizeof term[kind]);
    cache_seen_lab(c, tri, term[CACHE_KIND_DIRECT], term[CACHE_KIND_INDIRECT], term[CACHE_KIND_SPECULAR], lab);
}

void cache_white_level(const cache *c, cache_kind kind, uint32_t tri, const float background[CACHE_KINDS][3],
                       float white[3])
{
    const scene_material *m = &c->s->materials[c->s->tris[tri].material];
    const int front = seen_front(c, tri, m);
    float term[CACHE_KINDS][3], at0[3], at1[3];
    memcpy(term, background, sizeof term);
    /* The seen radiance is affine in this mesh's term: its value at 0 and its slope. */
    memset(term[kind], 0, sizeof term[kind]);
    cache_seen_radiance(m, front, term[CACHE_KIND_DIRECT], term[CACHE_KIND_INDIRECT], term[CACHE_KIND_SPECULAR], at0);
    for (int ch = 0; ch < 3; ++ch) term[kind][ch] = 1.0f;
    cache_seen_radiance(m, front, term[CACHE_KIND_DIRECT], term[CACHE_KIND_INDIRECT], term[CACHE_KIND_SPECULAR], at1);
    const float display_white = exp2f(-c->tm.exposure); /* tonemap.h: 2^exposure · radiance clips at 1 */
    for (int ch = 0; ch < 3; ++ch) {
        const float slope = at1[ch] - at0[ch];
        white[ch] = slope > 0.0f ? (display_white - at0[ch]) / slope : INFINITY;
    }
}

/* Points on the way from the midpoint to the darkest corner where the leaf's
 * picture is judged when the midpoint is past white (t = 1/4, 2/4, 3/4). */
enum { WHITE_STEPS = 4 };

float cache_midpoint_seen_de(const cache *c, cache_kind kind, uint32_t tri, const float background[CACHE_KINDS][3],
                             const float fresh[3], const float interp[3], const float end0[3], const float end1[3],
                             const float opposite[3], float at[3], float lab_at[3])
{
    float lf[3];
    cache_seen_lab_over(c, kind, tri, background, fresh, lf);
    cache_seen_lab_over(c, kind, tri, background, interp, lab_at);
    memcpy(at, interp, 3 * sizeof *at);
    float best = tm_delta_e(lf, lab_at), white[3];
    cache_white_level(c, kind, tri, background, white);
    int past = 0;
    for (int ch = 0; ch < 3; ++ch) past |= fmaxf(fresh[ch], interp[ch]) > white[ch];
    if (!past) return best;
    const float *corner[3] = {end0, end1, opposite};
    int dk = 0;
    for (int k = 1; k < 3; ++k)
        if (corner[k][0] + corner[k][1] + corner[k][2] < corner[dk][0] + corner[dk][1] + corner[dk][2]) dk = k;
    int below = 0;
    for (int ch = 0; ch < 3; ++ch) below |= corner[dk][ch] < white[ch];
    if (!below) return best; /* white all over: not seen anywhere */
    for (int q = 1; q < WHITE_STEPS; ++q) {
        const float t = (float)q / WHITE_STEPS;
        /* The midpoint's error as the leaf's quadratic carries it: 4·l_a·l_b,
         * 1 − t² toward an end of the edge, (1 − t)² toward the opposite corner. */
        const float share = dk == 2 ? (1.0f - t) * (1.0f - t) : 1.0f - t * t;
        float vi[3], vt[3], li[3], lt[3];
        for (int ch = 0; ch < 3; ++ch) {
            vi[ch] = (1.0f - t) * interp[ch] + t * corner[dk][ch];
            vt[ch] = fmaxf(vi[ch] + share * (fresh[ch] - interp[ch]), 0.0f);
        }
        cache_seen_lab_over(c, kind, tri, background, vt, lt);
        cache_seen_lab_over(c, kind, tri, background, vi, li);
        const float de = tm_delta_e(lt, li);
        if (de > best) {
            best = de;
            memcpy(at, vi, sizeof vi);
            memcpy(lab_at, li, sizeof li);
        }
    }
    return best;
}

float cache_leaf_contrast(const cache *c, const mesh_qmesh *m, cache_kind kind, const mesh_qnode *n)
{
    float lab[3][3];
    for (int k = 0; k < 3; ++k) {
        float term[CACHE_KINDS][3] = {{0, 0, 0}, {0, 0, 0}, {0, 0, 0}};
        double w1, w2;
        cache_node_corner_bary(n, k, &w1, &w2);
        mesh_qmesh_get_value(m, n->v[k], term[kind]);
        other_terms(c, kind, n->tri, w1, w2, n->depth == 0 ? n->v[k] : MESH_VTABLE_NONE, term);
        cache_seen_lab(c, n->tri, term[CACHE_KIND_DIRECT], term[CACHE_KIND_INDIRECT], term[CACHE_KIND_SPECULAR], lab[k]);
    }
    return fmaxf(tm_delta_e(lab[0], lab[1]), fmaxf(tm_delta_e(lab[1], lab[2]), tm_delta_e(lab[2], lab[0])));
}
