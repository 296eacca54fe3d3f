/* cache_light.c — what the light meshes give the cache (cache.h; paper §4.3.4):
 * visible fractions V_ℓ at radiance vertices (interpolated where a light leaf can
 * answer confidently, else the light mesh split and sampled), the direct values
 * L_dd from them (eq. 4) with G_ℓ kept per vertex for light edits, the specular
 * values through cache_specular.c, and the falsified light leaves whose answers
 * are recomputed. Owns cache_light_state (cache_internal.h); calls cache_site.c
 * and cache_specular.c below it. Worker thread, like the rest of the cache. */
#include "mesh/cache/cache_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "sampling/samp.h"
#include "src/base/vecmath.h" /* M_PI */

/* V within this of 1 (or of 0) at a light leaf's corners counts as wholly visible
 * (hidden): the control-variate samplers return exactly 1 and 0 there, up to float
 * rounding of G/G_unocc. */
#define CACHE_V_EPS 1e-4f

int cache_light_state_init(cache_light_state *st, uint32_t light_count)
{
    memset(st, 0, sizeof *st);
    st->light_stats = calloc(light_count ? light_count : 1, sizeof *st->light_stats);
    return st->light_stats != NULL;
}

void cache_light_state_free(cache_light_state *st)
{
    free(st->vertex_G);
    free(st->falsified);
    free(st->borrowed);
    free(st->light_stats);
    free(st->wanted);
    memset(st, 0, sizeof *st);
}

size_t cache_light_state_bytes(const cache_light_state *st, uint32_t light_count)
{
    return st->falsified_cap * sizeof(cache_region) + st->vertex_G_cap * light_count * sizeof(float) +
           st->borrowed_cap * sizeof *st->borrowed + st->wanted_cap;
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

/* Interpolated V at site vid when leaf can answer confidently, else -1. Not
 * across a seam: if a surface stands between the site and a corner (a wall on
 * a floor that runs on under it into the lit room), the corners' agreement says
 * nothing about the site (docs/cache.md, the Veach door). */
static float confident_V(const cache *c, const mesh_qmesh *m, const mesh_qnode *leaf, uint32_t asking_depth,
                         uint32_t vid)
{
    if ((uint32_t)leaf->depth + CACHE_LIGHT_LAG < asking_depth) return -1.0f;
    int u = uniform_V(m, leaf);
    if (u < 0) return -1.0f;
    samp_point site = cache_vertex_point(c, vid);
    for (int k = 0; k < 3; ++k) {
        samp_point corner = cache_vertex_point(c, leaf->v[k]);
        if (samp_points_parted(c->sp, &site, &corner)) return -1.0f;
    }
    return (float)u;
}

/* Records light leaf n (just split, its corners uniform) as falsified. */
static lm_result push_falsified(cache *c, uint32_t l, const mesh_qnode *n, lm_error *err)
{
    cache_light_state *st = &c->vis;
    if (!LM_GROW(st->falsified, st->falsified_cap, st->falsified_n + 1))
        return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory recording a falsified light leaf");
    cache_region *rg = &st->falsified[st->falsified_n++];
    rg->light = l;
    rg->tri = n->tri;
    for (int k = 0; k < 3; ++k) cache_node_corner_bary(n, k, &rg->w1[k], &rg->w2[k]);
    st->falsified_total++;
    return LM_OK;
}

/* Samples V of light l at the given vertices of its mesh and stores them. */
lm_result cache_sample_light(cache *c, uint32_t l, const uint32_t *vids, uint32_t n, lm_error *err)
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
    if (r == LM_OK) c->vis.light_stats[l].samples += n;
    c->effort += (uint64_t)n * samp_direct_rays(c->sp);
    free(pts);
    free(G);
    return r;
}

/* Appends to *need the corners of node that light mesh m uses but has not
 * sampled, each once (st->wanted marks those in *need). */
static lm_result want_unsampled(cache_light_state *st, const mesh_qmesh *m, const mesh_qnode *n, uint32_t **need,
                                uint32_t *count, uint32_t *cap, lm_error *err)
{
    for (int k = 0; k < 3; ++k) {
        float dummy;
        const uint32_t vid = n->v[k];
        if (mesh_qmesh_get_value(m, vid, &dummy) == 1) continue;
        if (vid >= st->wanted_cap) {
            size_t wc = lm_grow_capacity(st->wanted_cap, (size_t)vid + 1, 4096, SIZE_MAX);
            if (!wc || !lm_realloc_array(&st->wanted, st->wanted_cap, wc, 1))
                return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory refining a light mesh");
            st->wanted_cap = wc;
        }
        if (st->wanted[vid]) continue;
        if (*count == *cap) { /* a uint32_t capacity */
            size_t nc = lm_grow_capacity(*cap, (size_t)*count + 1, 64, UINT32_MAX);
            if (!nc || !lm_realloc_array(need, *cap, nc, sizeof **need))
                return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory refining a light mesh");
            *cap = (uint32_t)nc;
        }
        (*need)[(*count)++] = vid;
        st->wanted[vid] = 1;
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
        if (r == LM_OK) c->vis.light_stats[l].samples += n;
        c->effort += (uint64_t)n * samp_direct_rays(c->sp);
    }
    free(pts);
    free(G);
    return r;
}

/* The shallowest dyadic level whose lattice holds the point (w1, w2). */
static int lattice_depth(double w1, double w2)
{
    for (int k = 0; k <= MESH_DEPTH_MAX; ++k) {
        double a = ldexp(w1, k), b = ldexp(w2, k);
        if (a == floor(a) && b == floor(b)) return k;
    }
    return MESH_DEPTH_MAX + 1;
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
            uint32_t splits = 0;
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
                    r = want_unsampled(&c->vis, m, ln, &need, &need_n, &need_cap, err);
                    continue;
                }
                float cv = confident_V(c, m, ln, st->depth, st->vid);
                if (cv >= 0.0f) {
                    V[(size_t)i * L + l] = cv;
                    resolved[i] = 1;
                    c->vis.light_stats[l].interpolated++;
                    continue;
                }
                if (ln->depth > st->depth) { /* cannot happen: sites lie on the lattice of depth+1 */
                    r = lm_fail(err, LM_ERR_RUNTIME,
                                "light %u's mesh leaf %u (depth %d) is deeper than its radiance site %u (depth %d, "
                                "lattice depth %d, scene triangle %u at %.17g, %.17g)",
                                l, leaf, (int)ln->depth, st->vid, (int)st->depth, lattice_depth(st->w1, st->w2),
                                st->tri, st->w1, st->w2);
                    break;
                }
                int u = uniform_V(m, ln); /* read before the split: the pool may move */
                r = mesh_qmesh_split(m, leaf, err);
                splits += r == LM_OK;
                if (r == LM_OK && u >= 0 && split_n < n) {
                    split_uniform[split_n] = leaf;
                    split_u[split_n++] = u;
                }
                if (r == LM_OK) {
                    const mesh_qnode *p = mesh_qmesh_node(m, leaf);
                    for (uint32_t k = 0; r == LM_OK && k < 4; ++k)
                        r = want_unsampled(&c->vis, m, mesh_qmesh_node(m, p->child + k), &need, &need_n, &need_cap,
                                           err);
                }
            }
            for (uint32_t j = 0; j < need_n; ++j) c->vis.wanted[need[j]] = 0;
            /* A split whose new corners all have values already (shared with a
             * neighbour that sampled them) needs no samples, but its sites are
             * not resolved yet: another round, else their V would be left unset. */
            if (r != LM_OK || (need_n == 0 && splits == 0)) break;
            if (need_n) r = cache_sample_light(c, l, need, need_n, err);
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


/* ---- values ------------------------------------------------------------------ */

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

lm_result cache_direct_reserve(cache *c, uint32_t limit, lm_error *err)
{
    const size_t L = c->light_count;
    cache_light_state *st = &c->vis;
    if (limit > st->vertex_G_cap) { /* a row of L floats per vertex id */
        size_t row = (L ? L : 1) * sizeof *st->vertex_G;
        size_t cap = lm_grow_capacity(st->vertex_G_cap, limit, 1024, SIZE_MAX / row);
        if (!cap || !lm_realloc_array(&st->vertex_G, st->vertex_G_cap, cap, row))
            return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory for the cache's G values");
        st->vertex_G_cap = cap;
    }
    return LM_OK;
}

lm_result cache_direct_from_visibility(cache *c, uint32_t vid, const float *V, float rgb[3], lm_error *err)
{
    const size_t L = c->light_count;
    cache_light_state *st = &c->vis;
    lm_result r = cache_direct_reserve(c, vid + 1, err);
    if (r != LM_OK) return r;
    float *G = st->vertex_G + (size_t)vid * L;
    for (uint32_t l = 0; l < L; ++l) {
        double g = V[l] > 0.0f ? V[l] * cache_unoccluded(c, l, vid) : 0.0;
        G[l] = g < 3e38 ? (float)g : 3e38f;
    }
    direct_from_G(c, G, rgb);
    return LM_OK;
}

/* Where an area light is partly hidden from a specular site (0 < V_ℓ < 1), the
 * visible fraction weighted by the site's lobe replaces the cosine-weighted one
 * of the light mesh: eq. 5 takes V_ℓ out of the lobe's integral, and an occluder
 * that hides the part of the light a sharp lobe sees but little of what the
 * cosine sees made a highlight on CornellBox-Water's ripples twice the
 * reference's (docs/cache.md, "Leaves smaller than a pixel"). Wholly visible or
 * hidden lights keep V_ℓ, exact there. */
static lm_result lobe_visibility(cache *c, const cache_site *sites, uint32_t n, float *V, lm_error *err)
{
    const scene *s = c->s;
    const uint32_t L = c->light_count;
    samp_point *pts = malloc((n ? n : 1) * sizeof *pts);
    float *wo = malloc((n ? n : 1) * 3 * sizeof *wo), *ex = malloc((n ? n : 1) * sizeof *ex),
          *out = malloc((n ? n : 1) * sizeof *out);
    uint32_t *at = malloc((n ? n : 1) * sizeof *at);
    lm_result r = pts && wo && ex && out && at ? LM_OK
                                               : lm_fail(err, LM_ERR_NO_MEMORY, "out of memory for lobe visibility");
    for (uint32_t l = 0; r == LM_OK && l < L && l < s->area_light_count; ++l) {
        uint32_t m = 0;
        for (uint32_t i = 0; i < n; ++i) {
            float v = V[(size_t)i * L + l];
            if (!(v > 0.0f && v < 1.0f)) continue;
            pts[m] = cache_vertex_point(c, sites[i].vid);
            for (int k = 0; k < 3; ++k) wo[3 * m + (uint32_t)k] = c->eye[k] - pts[m].p[k];
            ex[m] = s->materials[s->tris[pts[m].tri_plus_one - 1].material].n;
            at[m++] = i;
        }
        if (m) r = samp_lobe_visibility(c->sp, l, pts, wo, ex, m, CACHE_LOBE_RAYS, out, err);
        c->effort += (uint64_t)m * CACHE_LOBE_RAYS;
        for (uint32_t k = 0; r == LM_OK && k < m; ++k)
            if (out[k] >= 0.0f) V[(size_t)at[k] * L + l] = out[k];
    }
    free(pts);
    free(wo);
    free(ex);
    free(out);
    free(at);
    return r;
}

/* The direct or specular values at the sites (cache_light_values, not counted). */
static lm_result light_values(cache *c, cache_kind kind, const cache_site *sites, uint32_t n, float *rgb,
                              lm_error *err)
{
    float *V = malloc(((size_t)n * c->light_count + 1) * sizeof *V);
    lm_result r = V ? cache_fetch_visibility(c, sites, n, V, err)
                    : lm_fail(err, LM_ERR_NO_MEMORY, "out of memory fetching visibility");
    if (r == LM_OK && kind == CACHE_KIND_SPECULAR) r = lobe_visibility(c, sites, n, V, err);
    for (uint32_t i = 0; r == LM_OK && i < n; ++i) {
        const float *Vi = V + (size_t)i * c->light_count;
        if (kind == CACHE_KIND_DIRECT)
            r = cache_direct_from_visibility(c, sites[i].vid, Vi, rgb + 3 * (size_t)i, err);
        else
            r = cache_specular_from_visibility(c, sites[i].vid, Vi, rgb + 3 * (size_t)i, err);
    }
    free(V);
    if (r == LM_OK && kind == CACHE_KIND_SPECULAR && cache_glossy_on(c)) {
        /* The source seen through the lobe (cache_glossy.c), added to the lights'. */
        uint32_t *vids = malloc((n ? n : 1) * sizeof *vids);
        if (!vids) return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory for glossy reflections");
        for (uint32_t i = 0; i < n; ++i) vids[i] = sites[i].vid;
        r = cache_glossy_add(c, vids, n, rgb, err);
        free(vids);
    }
    return r;
}

lm_result cache_light_values(cache *c, cache_kind kind, const cache_site *sites, uint32_t n, float *rgb,
                             lm_error *err)
{
    lm_result r = light_values(c, kind, sites, n, rgb, err);
    if (r == LM_OK) (kind == CACHE_KIND_DIRECT ? &c->vis.direct_stats : &c->vis.specular_stats)->samples += n;
    return r;
}

lm_result cache_relight_direct(cache *c, lm_error *err)
{
    const cache_light_state *st = &c->vis;
    uint32_t limit = mesh_vtable_id_limit(c->vt);
    for (uint32_t id = 0; id < limit && id < st->vertex_G_cap; ++id) {
        float old[3], rgb[3];
        if (mesh_qmesh_get_value(c->direct, id, old) != 1) continue;
        direct_from_G(c, st->vertex_G + (size_t)id * c->light_count, rgb);
        lm_result r = mesh_qmesh_set_value(c->direct, id, rgb, err);
        if (r != LM_OK) return r;
    }
    return LM_OK;
}

/* ---- the first image's borrowed roots (cache_first.c) ---------------------------- */

lm_result cache_borrowed_root(cache *c, uint32_t t, lm_error *err)
{
    cache_light_state *st = &c->vis;
    if (!LM_GROW(st->borrowed, st->borrowed_cap, st->borrowed_n + 1))
        return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory recording the first image's borrowed values");
    st->borrowed[st->borrowed_n++] = t;
    return LM_OK;
}

void cache_release_borrowed(cache *c) { c->vis.borrowed_released = 1; }

size_t cache_borrowed_waiting(const cache *c) { return c->vis.borrowed_n - c->vis.borrowed_next; }

lm_result cache_borrowed_to_regions(cache *c, size_t most, lm_error *err)
{
    cache_light_state *st = &c->vis;
    if (!st->borrowed_released) return LM_OK;
    for (size_t k = 0; k < most && st->borrowed_next < st->borrowed_n; ++k) {
        if (!LM_GROW(st->falsified, st->falsified_cap, st->falsified_n + 1))
            return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory recomputing the first image's borrowed values");
        /* The whole triangle: every direct and specular value in its trees. */
        st->falsified[st->falsified_n++] =
            (cache_region){.light = 0, .tri = st->borrowed[st->borrowed_next++], .w1 = {0, 1, 0}, .w2 = {0, 0, 1}};
        st->borrowed_revised++;
    }
    if (st->borrowed_next == st->borrowed_n) { /* all done: the list goes */
        free(st->borrowed);
        st->borrowed = NULL;
        st->borrowed_n = st->borrowed_cap = st->borrowed_next = 0;
    }
    return LM_OK;
}

/* ---- falsified light leaves -------------------------------------------------- */

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
        if (rs->n == rs->cap) { /* a uint32_t capacity */
            size_t nc = lm_grow_capacity(rs->cap, (size_t)rs->n + 1, 256, UINT32_MAX);
            if (!nc || !lm_realloc_array(&rs->s, rs->cap, nc, sizeof *rs->s))
                return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory revising the cache");
            rs->cap = (uint32_t)nc;
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
    float *vals = NULL;
    uint32_t *ids = NULL;
    cache_light_state *st = &c->vis;
    while (r == LM_OK && st->falsified_n) {
        /* Take the list: fetching again may record more. */
        uint32_t nreg = (uint32_t)st->falsified_n;
        cache_region *regions = malloc(nreg * sizeof *regions);
        if (!regions) {
            r = lm_fail(err, LM_ERR_NO_MEMORY, "out of memory revising the cache");
            break;
        }
        memcpy(regions, st->falsified, nreg * sizeof *regions);
        st->falsified_n = 0;
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
            free(vals);
            free(ids);
            vals = malloc(3 * (size_t)ns * sizeof *vals);
            ids = malloc(ns * sizeof *ids);
            if (!vals || !ids) {
                r = lm_fail(err, LM_ERR_NO_MEMORY, "out of memory revising the cache");
                break;
            }
            r = light_values(c, (cache_kind)kind, rs.s, ns, vals, err); /* not new samples of the mesh */
            uint32_t nchanged = 0;
            for (uint32_t i = 0; r == LM_OK && i < ns; ++i) {
                float old[3];
                const float *rgb = vals + 3 * (size_t)i;
                mesh_qmesh_get_value(m, rs.s[i].vid, old);
                if (rgb[0] == old[0] && rgb[1] == old[1] && rgb[2] == old[2]) continue;
                r = mesh_qmesh_set_value(m, rs.s[i].vid, rgb, err);
                ids[nchanged++] = rs.s[i].vid;
            }
            st->revised += nchanged;
            if (r == LM_OK && nchanged && changed)
                r = changed(c, (cache_kind)kind, regions, nreg, ids, nchanged, user, err);
        }
        free(regions);
    }
    /* A big batch (the first image's borrowed roots: 65,536 regions a call,
     * 3.7 MB) leaves no capacity behind once done. */
    if (st->falsified_n == 0 && st->falsified_cap > 1024) {
        free(st->falsified);
        st->falsified = NULL;
        st->falsified_cap = 0;
    }
    free(rs.s);
    free(vals);
    free(ids);
    return r;
}
