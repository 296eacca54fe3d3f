/* cache.c — the multi-mesh cache's meshes and values (cache.h; paper §4.1–4.2,
 * §4.3.4): lights, visibility, direct values, creation. Indirect light (source,
 * gathers, outdated values) is cache_source.c, the specular values
 * cache_specular.c, the refinement scheduler src/cache_refine.c. */
#include "mesh/cache/cache_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "sampling/analytic.h"
#include "sampling/samp.h"
#include "src/base/vecmath.h"

/* V within this of 1 (or of 0) at a light leaf's corners counts as wholly visible
 * (hidden): the control-variate samplers return exactly 1 and 0 there, up to float
 * rounding of G/G_unocc. */
#define CACHE_V_EPS 1e-4f

/* ---- lights ----------------------------------------------------------------- */

static const float *light_radiance(const scene *s, uint32_t l)
{
    return l < s->area_light_count ? s->area_lights[l].le : s->point_lights[l - s->area_light_count].intensity;
}

typedef struct light_filter {
    const scene *s;
    uint32_t light;
} light_filter;

/* A triangle can receive light l at all: some light point is above its plane
 * and some corner of it is in front of the light (conservative: a triangle that
 * fails gets no mesh for this light, and G = 0 there exactly). */
static int sees_light(const scene *s, uint32_t t, void *user)
{
    const light_filter *f = user;
    uint32_t l = f->light;
    if (s->tris[t].light >= 0 && (uint32_t)s->tris[t].light == l) return 0;
    lm_dvec3 n = dv3_load(s->tri_normals + 3 * (size_t)t), p0 = dv3_load(s->positions + 3 * (size_t)s->tris[t].v[0]);
    if (l >= s->area_light_count) {
        lm_dvec3 q = dv3_load(s->point_lights[l - s->area_light_count].position);
        return dv3_dot(dv3_sub(q, p0), n) > 0.0;
    }
    const scene_area_light *L = &s->area_lights[l];
    int above = 0, in_front = 0;
    lm_dvec3 nl = dv3_load(L->normal), cl = dv3_load(L->centroid);
    for (uint32_t i = 0; i < L->count && !above; ++i) {
        const uint32_t *v = s->tris[s->light_tris[L->first + i]].v;
        for (int k = 0; k < 3 && !above; ++k)
            above = dv3_dot(dv3_sub(dv3_load(s->positions + 3 * (size_t)v[k]), p0), n) > 0.0;
    }
    for (int k = 0; k < 3 && !in_front; ++k)
        in_front = dv3_dot(dv3_sub(dv3_load(s->positions + 3 * (size_t)s->tris[t].v[k]), cl), nl) > 0.0;
    return above && in_front;
}

static int has_albedo(const scene *s, uint32_t t, void *user)
{
    (void)user;
    const float *kd = s->materials[s->tris[t].material].kd;
    return kd[0] > 0.0f || kd[1] > 0.0f || kd[2] > 0.0f;
}

static int has_gloss(const scene *s, uint32_t t, void *user)
{
    (void)user;
    const float *ks = s->materials[s->tris[t].material].ks;
    return s->tris[t].light < 0 && (ks[0] > 0.0f || ks[1] > 0.0f || ks[2] > 0.0f);
}

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

double cache_unoccluded(const cache *c, uint32_t l, uint32_t vid)
{
    const mesh_vertex *v = mesh_vtable_vertex(c->vt, vid);
    if (l < c->s->area_light_count) return samp_area_light_unoccluded(c->s, l, v->position, v->normal);
    const float *q = c->s->point_lights[l - c->s->area_light_count].position;
    const double Q[3] = {q[0], q[1], q[2]}, X[3] = {v->position[0], v->position[1], v->position[2]},
                 N[3] = {v->normal[0], v->normal[1], v->normal[2]};
    return samp_point_G(Q, X, N);
}

/* ---- leaves ------------------------------------------------------------------ */

void cache_node_corner_bary(const mesh_qnode *n, int k, double *w1, double *w2)
{
    mesh_bary b = mesh_qmesh_node_corner(n, k);
    double scale = ldexp(1.0, -(int)b.depth);
    *w1 = b.w[1] * scale;
    *w2 = b.w[2] * scale;
}

/* Is (w1, w2) inside the closed triangle (a, b, c) of barycentric space, either winding? */
static int bary_in_triangle(const double a[2], const double b[2], const double c[2], double w1, double w2)
{
    const double eps = 1e-12;
    double d0 = (b[0] - a[0]) * (w2 - a[1]) - (b[1] - a[1]) * (w1 - a[0]);
    double d1 = (c[0] - b[0]) * (w2 - b[1]) - (c[1] - b[1]) * (w1 - b[0]);
    double d2 = (a[0] - c[0]) * (w2 - c[1]) - (a[1] - c[1]) * (w1 - c[0]);
    int neg = d0 < -eps || d1 < -eps || d2 < -eps, pos = d0 > eps || d1 > eps || d2 > eps;
    return !(neg && pos);
}

/* Is (w1, w2) inside the node's triangle (barycentric space of its scene triangle)? */
static int node_contains(const mesh_qnode *n, double w1, double w2)
{
    double a[2], b[2], c[2];
    cache_node_corner_bary(n, 0, &a[0], &a[1]);
    cache_node_corner_bary(n, 1, &b[0], &b[1]);
    cache_node_corner_bary(n, 2, &c[0], &c[1]);
    return bary_in_triangle(a, b, c, w1, w2);
}

int cache_region_contains(const cache_region *rg, double w1, double w2)
{
    const double a[2] = {rg->w1[0], rg->w2[0]}, b[2] = {rg->w1[1], rg->w2[1]}, c[2] = {rg->w1[2], rg->w2[2]};
    return bary_in_triangle(a, b, c, w1, w2);
}

uint32_t cache_find_leaf(const mesh_qmesh *m, uint32_t tri, double w1, double w2)
{
    uint32_t node = mesh_qmesh_root(m, tri);
    if (node == MESH_QMESH_NONE) return MESH_QMESH_NONE;
    for (;;) {
        const mesh_qnode *n = mesh_qmesh_node(m, node);
        if (n->child == MESH_QMESH_NONE) return node;
        uint32_t next = n->child + 3; /* the centre child when rounding leaves no other */
        for (uint32_t k = 0; k < 4; ++k)
            if (node_contains(mesh_qmesh_node(m, n->child + k), w1, w2)) {
                next = n->child + k;
                break;
            }
        node = next;
    }
}

/* ---- visibility (§4.3.4) ----------------------------------------------------- */

/* 1 (0) when V is uniformly 1 (0) at the leaf's three sampled corners, else -1. */
static int uniform_V(const mesh_qmesh *m, const mesh_qnode *leaf)
{
    float v[3];
    for (int k = 0; k < 3; ++k)
        if (mesh_qmesh_get_value(m, leaf->v[k], &v[k]) != 1) return -1;
    if (v[0] >= 1.0f - CACHE_V_EPS && v[1] >= 1.0f - CACHE_V_EPS && v[2] >= 1.0f - CACHE_V_EPS) return 1;
    if (v[0] <= CACHE_V_EPS && v[1] <= CACHE_V_EPS && v[2] <= CACHE_V_EPS) return 0;
    return -1;
}

/* Interpolated V at (w1, w2) when leaf can answer confidently, else -1. */
static float confident_V(const mesh_qmesh *m, const mesh_qnode *leaf, uint32_t asking_depth)
{
    if ((uint32_t)leaf->depth + CACHE_LIGHT_LAG < asking_depth) return -1.0f;
    int u = uniform_V(m, leaf);
    return u < 0 ? -1.0f : (float)u;
}

/* Records light leaf n (just split, its corners uniform) as falsified. */
static lm_result push_falsified(cache *c, uint32_t l, const mesh_qnode *n, lm_error *err)
{
    if (c->falsified_n == c->falsified_cap) {
        size_t nc = c->falsified_cap ? 2 * c->falsified_cap : 64;
        cache_region *p = realloc(c->falsified, nc * sizeof *p);
        if (!p) return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory recording a falsified light leaf");
        c->falsified = p;
        c->falsified_cap = nc;
    }
    cache_region *rg = &c->falsified[c->falsified_n++];
    rg->light = l;
    rg->tri = n->tri;
    for (int k = 0; k < 3; ++k) cache_node_corner_bary(n, k, &rg->w1[k], &rg->w2[k]);
    c->falsified_total++;
    return LM_OK;
}

/* Samples V of light l at the given vertices of its mesh and stores them. */
static lm_result sample_light(cache *c, uint32_t l, const uint32_t *vids, uint32_t n, lm_error *err)
{
    if (n == 0) return LM_OK;
    samp_point *pts = calloc(n, sizeof *pts);
    float *G = calloc(n, sizeof *G);
    lm_result r = pts && G ? LM_OK : lm_fail(err, LM_ERR_NO_MEMORY, "out of memory sampling a light");
    for (uint32_t i = 0; r == LM_OK && i < n; ++i) pts[i] = cache_vertex_point(c, vids[i]);
    if (r == LM_OK) r = samp_direct(c->sp, l, pts, n, G, err);
    for (uint32_t i = 0; r == LM_OK && i < n; ++i) {
        double g0 = cache_unoccluded(c, l, vids[i]);
        /* Where the light is below the horizon V is moot (G = V·0); 1 keeps such
         * corners from making a lit leaf look uncertain. */
        float V = g0 > 0.0 ? (float)fmin(1.0, fmax(0.0, G[i] / g0)) : 1.0f;
        r = mesh_qmesh_set_value(c->light[l], vids[i], &V, err);
    }
    if (r == LM_OK) c->light_stats[l].samples += n;
    free(pts);
    free(G);
    return r;
}

/* Appends to *need (deduplicated by a sampled check) the corners of node that
 * light mesh m uses but has not sampled. */
static lm_result want_unsampled(const mesh_qmesh *m, const mesh_qnode *n, uint32_t **need, uint32_t *count,
                                uint32_t *cap, lm_error *err)
{
    for (int k = 0; k < 3; ++k) {
        float dummy;
        if (mesh_qmesh_get_value(m, n->v[k], &dummy) == 1) continue;
        int dup = 0;
        for (uint32_t i = 0; i < *count && !dup; ++i) dup = (*need)[i] == n->v[k];
        if (dup) continue;
        if (*count == *cap) {
            uint32_t nc = *cap ? 2 * *cap : 64, *p = realloc(*need, nc * sizeof *p);
            if (!p) return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory refining a light mesh");
            *need = p;
            *cap = nc;
        }
        (*need)[(*count)++] = n->v[k];
    }
    return LM_OK;
}

/* Single-mesh ablation: V of every light sampled at every site. */
static lm_result fetch_visibility_single(cache *c, const cache_site *sites, uint32_t n, float *V, lm_error *err)
{
    const uint32_t L = c->light_count;
    samp_point *pts = calloc(n ? n : 1, sizeof *pts);
    float *G = calloc(n ? n : 1, sizeof *G);
    lm_result r = pts && G ? LM_OK : lm_fail(err, LM_ERR_NO_MEMORY, "out of memory sampling lights");
    for (uint32_t i = 0; r == LM_OK && i < n; ++i) pts[i] = cache_vertex_point(c, sites[i].vid);
    for (uint32_t l = 0; r == LM_OK && l < L; ++l) {
        r = samp_direct(c->sp, l, pts, n, G, err);
        for (uint32_t i = 0; r == LM_OK && i < n; ++i) {
            double g0 = cache_unoccluded(c, l, sites[i].vid);
            V[(size_t)i * L + l] = g0 > 0.0 ? (float)fmin(1.0, fmax(0.0, G[i] / g0)) : 1.0f;
        }
        if (r == LM_OK) c->light_stats[l].samples += n;
    }
    free(pts);
    free(G);
    return r;
}

lm_result cache_fetch_visibility(cache *c, const cache_site *sites, uint32_t n, float *V, lm_error *err)
{
    const uint32_t L = c->light_count;
    if (c->desc.single_mesh) return fetch_visibility_single(c, sites, n, V, err);
    uint8_t *resolved = calloc(n ? n : 1, 1);
    uint32_t *need = NULL, need_n = 0, need_cap = 0;
    /* Leaves split in a round whose corners were uniform (they could have answered
     * before, at a shallower site): checked once their midpoints are sampled. */
    uint32_t *split_uniform = malloc((n ? n : 1) * sizeof *split_uniform), split_n = 0;
    int *split_u = malloc((n ? n : 1) * sizeof *split_u);
    lm_result r = resolved && split_uniform && split_u
                      ? LM_OK
                      : lm_fail(err, LM_ERR_NO_MEMORY, "out of memory fetching visibility");
    for (uint32_t l = 0; r == LM_OK && l < L; ++l) {
        mesh_qmesh *m = c->light[l];
        memset(resolved, 0, n);
        /* Each round splits, once, the light leaves that hold an unresolved site
         * and cannot answer, and samples their new corners in one batch. */
        for (int round = 0; r == LM_OK && round <= MESH_DEPTH_MAX + 1; ++round) {
            need_n = 0;
            split_n = 0;
            for (uint32_t i = 0; r == LM_OK && i < n; ++i) {
                if (resolved[i]) continue;
                const cache_site *st = &sites[i];
                float v;
                /* A vertex shared with a triangle that sees the light has its value
                 * there even when the asking triangle does not. */
                if (m && mesh_qmesh_get_value(m, st->vid, &v) == 1) {
                    V[(size_t)i * L + l] = v;
                    resolved[i] = 1;
                    continue;
                }
                if (!m || mesh_qmesh_root(m, st->tri) == MESH_QMESH_NONE) {
                    V[(size_t)i * L + l] = 0.0f; /* this triangle cannot see the light */
                    resolved[i] = 1;
                    continue;
                }
                uint32_t leaf = cache_find_leaf(m, st->tri, st->w1, st->w2);
                const mesh_qnode *ln = mesh_qmesh_node(m, leaf);
                int corners_known = 1;
                for (int k = 0; k < 3; ++k) corners_known &= mesh_qmesh_get_value(m, ln->v[k], &v) == 1;
                if (!corners_known) {
                    /* Split earlier in this round: its corners are in this round's
                     * batch; ask again once they are sampled. */
                    r = want_unsampled(m, ln, &need, &need_n, &need_cap, err);
                    continue;
                }
                float cv = confident_V(m, ln, st->depth);
                if (cv >= 0.0f) {
                    V[(size_t)i * L + l] = cv;
                    resolved[i] = 1;
                    c->light_stats[l].interpolated++;
                    continue;
                }
                if (ln->depth > st->depth) { /* cannot happen: sites lie on the lattice of depth+1 */
                    r = lm_fail(err, LM_ERR_RUNTIME, "light mesh deeper than its radiance site");
                    break;
                }
                int u = uniform_V(m, ln); /* read before the split: the pool may move */
                r = mesh_qmesh_split(m, leaf, err);
                if (r == LM_OK && u >= 0 && split_n < n) {
                    split_uniform[split_n] = leaf;
                    split_u[split_n++] = u;
                }
                if (r == LM_OK) {
                    const mesh_qnode *p = mesh_qmesh_node(m, leaf);
                    for (uint32_t k = 0; r == LM_OK && k < 4; ++k)
                        r = want_unsampled(m, mesh_qmesh_node(m, p->child + k), &need, &need_n, &need_cap, err);
                }
            }
            if (r != LM_OK || need_n == 0) break;
            r = sample_light(c, l, need, need_n, err);
            /* A uniform leaf whose midpoints disagree was wrong wherever it answered. */
            for (uint32_t j = 0; r == LM_OK && j < split_n; ++j) {
                const mesh_qnode *p = mesh_qmesh_node(m, split_uniform[j]);
                if (uniform_V(m, mesh_qmesh_node(m, p->child + 3)) != split_u[j]) r = push_falsified(c, l, p, err);
            }
        }
    }
    free(split_uniform);
    free(split_u);
    free(need);
    free(resolved);
    return r;
}

/* ---- falsified light leaves -------------------------------------------------- */

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

typedef struct revise_sites {
    const cache *c;
    const cache_region *rg;
    cache_site *s;
    uint32_t n, cap;
} revise_sites;

/* The corners of a node that lie in the region and have a value in m: sites to
 * fetch again, asked at the depth that made them (a vertex of reduced depth k is
 * the midpoint of an edge of a depth k−1 leaf), so the lag allowed is the same. */
static lm_result collect_region_sites(const mesh_qmesh *m, uint32_t node, const mesh_qnode *n, void *user,
                                      lm_error *err)
{
    (void)node;
    revise_sites *rs = user;
    for (int k = 0; k < 3; ++k) {
        float tmp[3];
        double w1, w2;
        if (mesh_qmesh_get_value(m, n->v[k], tmp) != 1) continue;
        cache_node_corner_bary(n, k, &w1, &w2);
        if (!cache_region_contains(rs->rg, w1, w2)) continue;
        if (rs->n == rs->cap) {
            uint32_t nc = rs->cap ? 2 * rs->cap : 256;
            cache_site *p = realloc(rs->s, nc * sizeof *p);
            if (!p) return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory revising the cache");
            rs->s = p;
            rs->cap = nc;
        }
        uint32_t d = mesh_vtable_vertex(rs->c->vt, n->v[k])->bary.depth;
        rs->s[rs->n++] = (cache_site){.vid = n->v[k], .tri = n->tri, .w1 = w1, .w2 = w2, .depth = d ? d - 1 : 0};
    }
    return LM_OK;
}

static int site_by_vid(const void *a, const void *b)
{
    uint32_t x = ((const cache_site *)a)->vid, y = ((const cache_site *)b)->vid;
    return (x > y) - (x < y);
}

lm_result cache_revise_falsified(cache *c, cache_changed_fn changed, void *user, lm_error *err)
{
    lm_result r = LM_OK;
    revise_sites rs = {.c = c};
    float *V = NULL;
    uint32_t *ids = NULL;
    while (r == LM_OK && c->falsified_n) {
        /* Take the list: fetching again may record more. */
        uint32_t nreg = (uint32_t)c->falsified_n;
        cache_region *regions = malloc(nreg * sizeof *regions);
        if (!regions) {
            r = lm_fail(err, LM_ERR_NO_MEMORY, "out of memory revising the cache");
            break;
        }
        memcpy(regions, c->falsified, nreg * sizeof *regions);
        c->falsified_n = 0;
        for (int kind = CACHE_KIND_DIRECT; r == LM_OK && kind < CACHE_KINDS; ++kind) {
            mesh_qmesh *m = cache_kind_mesh(c, (cache_kind)kind);
            if (kind == CACHE_KIND_INDIRECT || !m) continue; /* indirect values do not come from V */
            rs.n = 0;
            for (uint32_t i = 0; r == LM_OK && i < nreg; ++i) {
                rs.rg = &regions[i];
                r = cache_region_walk(m, &regions[i], collect_region_sites, &rs, err);
            }
            if (r != LM_OK || rs.n == 0) continue;
            qsort(rs.s, rs.n, sizeof *rs.s, site_by_vid);
            uint32_t ns = 0;
            for (uint32_t i = 0; i < rs.n; ++i)
                if (ns == 0 || rs.s[ns - 1].vid != rs.s[i].vid) rs.s[ns++] = rs.s[i];
            free(V);
            free(ids);
            V = malloc(((size_t)ns * c->light_count + 1) * sizeof *V);
            ids = malloc(ns * sizeof *ids);
            if (!V || !ids) {
                r = lm_fail(err, LM_ERR_NO_MEMORY, "out of memory revising the cache");
                break;
            }
            r = cache_fetch_visibility(c, rs.s, ns, V, err);
            uint32_t nchanged = 0;
            for (uint32_t i = 0; r == LM_OK && i < ns; ++i) {
                float old[3], rgb[3];
                mesh_qmesh_get_value(m, rs.s[i].vid, old);
                const float *Vi = V + (size_t)i * c->light_count;
                if (kind == CACHE_KIND_DIRECT)
                    r = cache_direct_from_visibility(c, rs.s[i].vid, Vi, rgb, err);
                else
                    cache_specular_from_visibility(c, rs.s[i].vid, Vi, rgb);
                if (r != LM_OK || (rgb[0] == old[0] && rgb[1] == old[1] && rgb[2] == old[2])) continue;
                r = mesh_qmesh_set_value(m, rs.s[i].vid, rgb, err);
                ids[nchanged++] = rs.s[i].vid;
            }
            c->revised += nchanged;
            if (r == LM_OK && nchanged && changed)
                r = changed(c, (cache_kind)kind, regions, nreg, ids, nchanged, user, err);
        }
        free(regions);
    }
    free(rs.s);
    free(V);
    free(ids);
    return r;
}

/* L_dd = (1/π)·Σ_ℓ L_ℓ·G_ℓ from the G row of one vertex. */
static void direct_from_G(const cache *c, const float *G, float rgb[3])
{
    double e[3] = {0, 0, 0};
    for (uint32_t l = 0; l < c->light_count; ++l)
        for (int k = 0; k < 3; ++k) e[k] += (double)c->light_le[3 * l + (uint32_t)k] * G[l];
    for (int k = 0; k < 3; ++k) {
        double v = e[k] / M_PI;
        rgb[k] = v < 3e38 ? (float)v : 3e38f;
    }
}

lm_result cache_direct_from_visibility(cache *c, uint32_t vid, const float *V, float rgb[3], lm_error *err)
{
    const size_t L = c->light_count;
    if (vid >= c->vertex_G_cap) {
        size_t cap = c->vertex_G_cap ? c->vertex_G_cap : 1024;
        while (cap <= vid) cap *= 2;
        float *g = realloc(c->vertex_G, cap * (L ? L : 1) * sizeof *g);
        if (!g) return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory for the cache's G values");
        c->vertex_G = g;
        c->vertex_G_cap = cap;
    }
    float *G = c->vertex_G + (size_t)vid * L;
    for (uint32_t l = 0; l < L; ++l) {
        double g = V[l] > 0.0f ? V[l] * cache_unoccluded(c, l, vid) : 0.0;
        G[l] = g < 3e38 ? (float)g : 3e38f;
    }
    direct_from_G(c, G, rgb);
    return LM_OK;
}

lm_result cache_set_light(cache *c, uint32_t light, const float value[3], lm_error *err)
{
    if (!c || !value || light >= c->light_count)
        return lm_fail(err, LM_ERR_INVALID_ARG, "cache_set_light: light %u does not exist", light);
    for (int k = 0; k < 3; ++k)
        if (!(value[k] >= 0.0f) || !isfinite(value[k]))
            return lm_fail(err, LM_ERR_INVALID_ARG, "cache_set_light: radiance must be finite and non-negative");
    memcpy(c->light_le + 3 * (size_t)light, value, 3 * sizeof *value);
    mesh_vtable_stats vs;
    mesh_vtable_get_stats(c->vt, &vs);
    for (uint32_t id = 0; id < vs.id_limit && id < c->vertex_G_cap; ++id) {
        float old[3], rgb[3];
        if (mesh_qmesh_get_value(c->direct, id, old) != 1) continue;
        direct_from_G(c, c->vertex_G + (size_t)id * c->light_count, rgb);
        lm_result r = mesh_qmesh_set_value(c->direct, id, rgb, err);
        if (r != LM_OK) return r;
    }
    lm_result rg = c->initialised ? cache_regather_all(c, err) : LM_OK;
    if (rg != LM_OK) return rg;
    /* What was below the JND may not be now (a shadow no longer masked by another
     * light): every leaf is tested again, without new light samples unless the
     * test splits it. */
    for (int k = 0; k < CACHE_KINDS; ++k) c->requeue[k] = 1;
    /* The specular mesh keeps no G per vertex: sample its roots again (the light
     * meshes answer without new samples where they are sure). */
    if (c->specular) return cache_set_camera(c, c->eye, err);
    return LM_OK;
}

/* ---- create, init, destroy ---------------------------------------------------- */

void cache_destroy(cache *c)
{
    if (!c) return;
    if (c->light)
        for (uint32_t l = 0; l < c->light_count; ++l) mesh_qmesh_destroy(c->light[l]);
    mesh_qmesh_destroy(c->direct);
    mesh_qmesh_destroy(c->indirect);
    mesh_qmesh_destroy(c->specular);
    mesh_qmesh_destroy(c->indirect1);
    mesh_vtable_destroy(c->vt);
    free(c->light);
    free(c->light_stats);
    free(c->light_le);
    free(c->vertex_G);
    free(c->rm_first);
    free(c->rm_bary);
    free(c->rm_rad);
    free(c->leaf_buf);
    free(c->falsified);
    free(c->rp_first);
    free(c->rp_bary);
    free(c->rp_rad);
    free(c->drift);
    free(c->outdated);
    free(c->outdated_list);
    free(c->src_err);
    free(c->src_open);
    free(c->src_heap);
    free(c->spec_outline);
    free(c->spec_loop);
    free(c->spec_light_loop);
    free(c->spec_loop_sign);
    for (int k = 0; k < CACHE_KINDS; ++k) {
        free(c->q[k].e);
        free(c->done[k]);
        free(c->prio[k]);
        free(c->roots[k]);
    }
    free(c);
}

lm_result cache_create(const cache_desc *desc, cache **out, lm_error *err)
{
    *out = NULL;
    if (!desc || !desc->scene || !desc->sampler) return lm_fail(err, LM_ERR_INVALID_ARG, "cache: needs a scene and a sampler");
    if (desc->bounces < 0 || desc->bounces > 2 || !(desc->jnd >= 0.0f) || !(desc->min_leaf_pixels >= 0.0f) ||
        (unsigned)desc->scheduler >= CACHE_SCHED_COUNT)
        return lm_fail(err, LM_ERR_INVALID_ARG, "cache: bounces must be 1 or 2, the JND and leaf size non-negative");
    cache *c = calloc(1, sizeof *c);
    if (!c) return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory creating the cache");
    c->desc = *desc;
    if (c->desc.jnd == 0.0f) c->desc.jnd = 2.0f;
    if (c->desc.bounces == 0) c->desc.bounces = 1;
    if (c->desc.min_leaf_pixels == 0.0f) c->desc.min_leaf_pixels = 16.0f;
    c->s = desc->scene;
    c->sp = desc->sampler;
    lm_rng_seed(&c->rng, desc->seed, 0x5c4ed, 0);
    for (int k = 0; k < CACHE_KINDS; ++k) c->cur_root[k] = MESH_QMESH_NONE;
    c->tm.exposure = c->s->exposure + desc->exposure_offset;
    c->light_count = scene_light_count(c->s);
    lm_result r = mesh_vtable_create(&(mesh_vtable_desc){.scene = c->s}, &c->vt, err);
    c->light = calloc(c->light_count ? c->light_count : 1, sizeof *c->light);
    c->light_stats = calloc(c->light_count ? c->light_count : 1, sizeof *c->light_stats);
    c->light_le = calloc(3 * (size_t)(c->light_count ? c->light_count : 1), sizeof *c->light_le);
    if (r == LM_OK && (!c->light || !c->light_stats || !c->light_le))
        r = lm_fail(err, LM_ERR_NO_MEMORY, "out of memory creating the cache");
    for (uint32_t l = 0; r == LM_OK && l < c->light_count; ++l)
        memcpy(c->light_le + 3 * (size_t)l, light_radiance(c->s, l), 3 * sizeof(float));
    uint32_t cap = desc->node_cap;
    for (uint32_t l = 0; r == LM_OK && l < c->light_count; ++l) {
        light_filter f = {c->s, l};
        uint32_t roots = 0;
        for (uint32_t t = 0; t < c->s->tri_count; ++t) roots += sees_light(c->s, t, &f) != 0;
        if (roots == 0) continue; /* a light nothing can see gets no mesh */
        r = mesh_qmesh_create(&(mesh_qmesh_desc){.vtable = c->vt, .root_filter = sees_light, .root_filter_user = &f,
                                                 .channels = 1, .node_cap = cap},
                              &c->light[l], err);
    }
    if (r == LM_OK)
        r = mesh_qmesh_create(&(mesh_qmesh_desc){.vtable = c->vt, .root_filter = has_albedo, .channels = 3, .node_cap = cap},
                              &c->direct, err);
    if (r == LM_OK)
        r = mesh_qmesh_create(&(mesh_qmesh_desc){.vtable = c->vt, .root_filter = has_albedo, .channels = 3, .node_cap = cap},
                              &c->indirect, err);
    if (r == LM_OK && c->desc.bounces >= 2)
        r = mesh_qmesh_create(&(mesh_qmesh_desc){.vtable = c->vt, .root_filter = has_albedo, .channels = 3, .node_cap = cap},
                              &c->indirect1, err);
    uint32_t glossy = 0;
    for (uint32_t t = 0; r == LM_OK && t < c->s->tri_count; ++t) glossy += has_gloss(c->s, t, NULL) != 0;
    if (r == LM_OK && glossy) /* model only what the scene needs: no gloss, no mesh */
        r = mesh_qmesh_create(&(mesh_qmesh_desc){.vtable = c->vt, .root_filter = has_gloss, .channels = 3, .node_cap = cap},
                              &c->specular, err);
    if (r == LM_OK && glossy && !cache_build_outlines(c)) r = lm_fail(err, LM_ERR_NO_MEMORY, "out of memory creating the cache");
    if (c->s->camera_count) memcpy(c->eye, c->s->cameras[0].position, sizeof c->eye);
    if (r != LM_OK) {
        cache_destroy(c);
        return r;
    }
    *out = c;
    return LM_OK;
}

/* The distinct corner vertices of every root of m. */
static lm_result root_vertices(const cache *c, const mesh_qmesh *m, uint32_t **out, uint32_t *n, lm_error *err)
{
    const scene *s = c->s;
    uint8_t *seen = NULL;
    uint32_t *v = malloc(3 * (size_t)(s->tri_count ? s->tri_count : 1) * sizeof *v), cnt = 0, limit = 0;
    mesh_vtable_stats vs;
    mesh_vtable_get_stats(c->vt, &vs);
    limit = vs.id_limit;
    seen = calloc(limit ? limit : 1, 1);
    if (!v || !seen) {
        free(v);
        free(seen);
        return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory initialising the cache");
    }
    for (uint32_t t = 0; t < s->tri_count; ++t) {
        uint32_t root = mesh_qmesh_root(m, t);
        if (root == MESH_QMESH_NONE) continue;
        const mesh_qnode *nd = mesh_qmesh_node(m, root);
        for (int k = 0; k < 3; ++k)
            if (nd->v[k] < limit && !seen[nd->v[k]]) {
                seen[nd->v[k]] = 1;
                v[cnt++] = nd->v[k];
            }
    }
    free(seen);
    *out = v;
    *n = cnt;
    return LM_OK;
}

/* The root corners of the direct or specular mesh, their values from the light
 * meshes (visible fractions; samples only where those cannot answer). */
static lm_result sample_roots(cache *c, cache_kind kind, lm_error *err)
{
    mesh_qmesh *m = cache_kind_mesh(c, kind);
    uint32_t *v = NULL, n = 0;
    lm_result r = root_vertices(c, m, &v, &n, err);
    float *V = r == LM_OK ? malloc(((size_t)n * c->light_count + 1) * sizeof *V) : NULL;
    cache_site *sites = r == LM_OK ? malloc((n ? n : 1) * sizeof *sites) : NULL;
    if (r == LM_OK && (!V || !sites)) r = lm_fail(err, LM_ERR_NO_MEMORY, "out of memory initialising the cache");
    for (uint32_t i = 0; r == LM_OK && i < n; ++i) {
        const mesh_vertex *mv = mesh_vtable_vertex(c->vt, v[i]);
        double scale = ldexp(1.0, -(int)mv->bary.depth);
        sites[i] = (cache_site){.vid = v[i], .tri = mv->tri, .w1 = mv->bary.w[1] * scale,
                                .w2 = mv->bary.w[2] * scale, .depth = 0};
    }
    if (r == LM_OK) r = cache_fetch_visibility(c, sites, n, V, err);
    cache_mesh_stats *st = kind == CACHE_KIND_DIRECT ? &c->direct_stats : &c->specular_stats;
    for (uint32_t i = 0; r == LM_OK && i < n; ++i) {
        float rgb[3];
        if (kind == CACHE_KIND_DIRECT)
            r = cache_direct_from_visibility(c, v[i], V + (size_t)i * c->light_count, rgb, err);
        else
            cache_specular_from_visibility(c, v[i], V + (size_t)i * c->light_count, rgb);
        if (r == LM_OK) r = mesh_qmesh_set_value(m, v[i], rgb, err);
        st->samples++;
    }
    free(V);
    free(sites);
    free(v);
    return r;
}

lm_result cache_set_camera(cache *c, const float eye[3], lm_error *err)
{
    if (!c || !eye || !isfinite(eye[0]) || !isfinite(eye[1]) || !isfinite(eye[2]))
        return lm_fail(err, LM_ERR_INVALID_ARG, "cache_set_camera: the eye must be a finite point");
    memcpy(c->eye, eye, sizeof c->eye);
    if (!c->specular) return LM_OK; /* nothing depends on the view */
    uint32_t cap = c->desc.node_cap;
    mesh_qmesh_destroy(c->specular);
    c->specular = NULL;
    lm_result r = mesh_qmesh_create(
        &(mesh_qmesh_desc){.vtable = c->vt, .root_filter = has_gloss, .channels = 3, .node_cap = cap}, &c->specular, err);
    if (r == LM_OK && c->initialised) r = sample_roots(c, CACHE_KIND_SPECULAR, err);
    c->requeue[CACHE_KIND_SPECULAR] = 1;
    return r;
}

lm_result cache_init(cache *c, lm_error *err)
{
    uint32_t *v = NULL, n = 0;
    lm_result r = LM_OK;
    for (uint32_t l = 0; r == LM_OK && l < c->light_count; ++l) {
        if (!c->light[l]) continue;
        r = root_vertices(c, c->light[l], &v, &n, err);
        if (r == LM_OK) r = sample_light(c, l, v, n, err);
        free(v);
        v = NULL;
    }
    if (r == LM_OK) r = sample_roots(c, CACHE_KIND_DIRECT, err);
    if (r == LM_OK && c->specular) r = sample_roots(c, CACHE_KIND_SPECULAR, err);
    /* Indirect: gathered from the coarse direct mesh just made (§5); with two
     * bounces the first bounce at the coarse vertices first, then the second
     * from kd·(L_dd + E_1/π). */
    if (r == LM_OK && c->indirect1) {
        r = root_vertices(c, c->indirect1, &v, &n, err);
        float *E1 = r == LM_OK ? malloc(3 * (size_t)(n ? n : 1) * sizeof *E1) : NULL;
        if (r == LM_OK && !E1) r = lm_fail(err, LM_ERR_NO_MEMORY, "out of memory initialising the cache");
        if (r == LM_OK) r = cache_gather(c, 1, v, n, E1, err);
        for (uint32_t i = 0; r == LM_OK && i < n; ++i)
            r = mesh_qmesh_set_value(c->indirect1, v[i], E1 + 3 * (size_t)i, err);
        free(E1);
        free(v);
        v = NULL;
    }
    if (r == LM_OK) r = cache_update_radiance_source(c, 1, 1, err);
    if (r == LM_OK) r = root_vertices(c, c->indirect, &v, &n, err);
    float *E = r == LM_OK ? malloc(3 * (size_t)(n ? n : 1) * sizeof *E) : NULL;
    if (r == LM_OK && !E) r = lm_fail(err, LM_ERR_NO_MEMORY, "out of memory initialising the cache");
    if (r == LM_OK) r = cache_sample_indirect(c, v, n, E, err);
    for (uint32_t i = 0; r == LM_OK && i < n; ++i) r = mesh_qmesh_set_value(c->indirect, v[i], E + 3 * (size_t)i, err);
    free(E);
    free(v);
    if (r == LM_OK) c->initialised = 1;
    return r;
}

/* ---- evaluation and statistics ------------------------------------------------- */

lm_result cache_eval_direct(const cache *c, uint32_t tri, double w1, double w2, float rgb[3], lm_error *err)
{
    return mesh_qmesh_interpolate(c->direct, tri, w1, w2, rgb, err);
}

lm_result cache_eval_indirect(const cache *c, uint32_t tri, double w1, double w2, float rgb[3], lm_error *err)
{
    return mesh_qmesh_interpolate(c->indirect, tri, w1, w2, rgb, err);
}

lm_result cache_eval_specular(const cache *c, uint32_t tri, double w1, double w2, float rgb[3], lm_error *err)
{
    rgb[0] = rgb[1] = rgb[2] = 0.0f;
    if (!c->specular || mesh_qmesh_root(c->specular, tri) == MESH_QMESH_NONE) return LM_OK;
    return mesh_qmesh_interpolate(c->specular, tri, w1, w2, rgb, err);
}

lm_result cache_eval_G(const cache *c, uint32_t light, uint32_t tri, double w1, double w2, double *G, lm_error *err)
{
    *G = 0.0;
    if (light >= c->light_count) return lm_fail(err, LM_ERR_INVALID_ARG, "cache: light %u does not exist", light);
    const mesh_qmesh *m = c->light[light];
    if (!m || mesh_qmesh_root(m, tri) == MESH_QMESH_NONE) return LM_OK;
    float V;
    lm_result r = mesh_qmesh_interpolate(m, tri, w1, w2, &V, err);
    if (r != LM_OK) return r;
    const scene *s = c->s;
    const uint32_t *tv = s->tris[tri].v;
    float p[3], n[3];
    for (int k = 0; k < 3; ++k) {
        p[k] = (float)((1.0 - w1 - w2) * s->positions[3 * (size_t)tv[0] + (size_t)k] +
                       w1 * s->positions[3 * (size_t)tv[1] + (size_t)k] + w2 * s->positions[3 * (size_t)tv[2] + (size_t)k]);
        const float *cn = s->corner_normals + 9 * (size_t)tri;
        n[k] = (float)((1.0 - w1 - w2) * cn[k] + w1 * cn[3 + k] + w2 * cn[6 + k]);
    }
    lm_vec3 nn = v3_normalize(v3_load(n));
    v3_store(n, nn);
    double g0;
    if (light < s->area_light_count) {
        g0 = samp_area_light_unoccluded(s, light, p, n);
    } else {
        const float *q = s->point_lights[light - s->area_light_count].position;
        const double Q[3] = {q[0], q[1], q[2]}, X[3] = {p[0], p[1], p[2]}, N[3] = {n[0], n[1], n[2]};
        g0 = samp_point_G(Q, X, N);
    }
    *G = V * g0;
    return LM_OK;
}

void cache_get_stats(cache *c, cache_stats *out)
{
    memset(out, 0, sizeof *out);
    out->light_count = c->light_count;
    out->direct = c->direct_stats;
    out->indirect = c->indirect_stats;
    out->specular = c->specular_stats;
    mesh_qmesh_get_stats(c->direct, &out->direct.mesh);
    mesh_qmesh_get_stats(c->indirect, &out->indirect.mesh);
    if (c->specular) mesh_qmesh_get_stats(c->specular, &out->specular.mesh);
    out->bytes = out->direct.mesh.bytes + out->indirect.mesh.bytes + out->specular.mesh.bytes;
    for (uint32_t l = 0; l < c->light_count; ++l) {
        if (c->light[l]) mesh_qmesh_get_stats(c->light[l], &c->light_stats[l].mesh);
        out->bytes += c->light_stats[l].mesh.bytes;
    }
    out->lights = c->light_stats;
    out->undone = c->undone;
    out->falsified = c->falsified_total;
    out->revised = c->revised;
    out->regathered = c->regathered;
    mesh_vtable_stats vs;
    mesh_vtable_get_stats(c->vt, &vs);
    out->bytes += c->src_cap * (sizeof(float) + 1 + 2 * sizeof(uint32_t)) + c->falsified_cap * sizeof(cache_region) +
                  c->rp_cap * (6 + 9) * sizeof(float) + c->drift_cap * (3 * sizeof(float) + 1) +
                  c->outdated_cap * sizeof(uint32_t);
    out->bytes += vs.bytes + c->rm_cap * (6 + 9) * sizeof(float) + c->leaf_cap * sizeof *c->leaf_buf +
                  c->vertex_G_cap * c->light_count * sizeof(float) + c->spec_outline_bytes;
    for (int k = 0; k < CACHE_KINDS; ++k)
        out->bytes += c->q[k].cap * sizeof(cache_queue_entry) + c->done_cap[k] + c->prio_cap[k] * sizeof(float);
}

const mesh_qmesh *cache_direct_mesh(const cache *c) { return c->direct; }
const mesh_qmesh *cache_indirect_mesh(const cache *c) { return c->indirect; }
const mesh_qmesh *cache_specular_mesh(const cache *c) { return c->specular; }
const mesh_vtable *cache_vtable(const cache *c) { return c->vt; }
const mesh_qmesh *cache_light_mesh(const cache *c, uint32_t light)
{
    return light < c->light_count ? c->light[light] : NULL;
}

/* ---- the worker's quick start and view changes ------------------------------------ */

void cache_set_sampler(cache *c, samp_sampler *sp) { c->sp = sp; }

lm_result cache_regather_indirect(cache *c, lm_error *err)
{
    if (!c->initialised) return lm_fail(err, LM_ERR_INVALID_ARG, "cache_regather_indirect: cache_init first");
    lm_result r = cache_regather_all(c, err);
    for (int k = 0; k < CACHE_KINDS; ++k) c->requeue[k] = 1;
    return r;
}

lm_result cache_requeue(cache *c, lm_error *err)
{
    (void)err;
    for (int k = 0; k < CACHE_KINDS; ++k) c->requeue[k] = 1;
    return LM_OK;
}
