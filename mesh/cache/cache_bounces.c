/* cache_bounces.c — diffuse bounces beyond the first (issue 13; docs/cache.md,
 * "Bounces").
 *
 * The displayed indirect mesh gathers the first bounce from kd·L_dd over the
 * source cut (cache_source.c). Bounces 2..K reach it through the same source,
 * which then holds kd·(L_dd + E_m/π) with
 *     E_m = B_1 + … + B_(K−1),
 * B_k the irradiance of bounce k at the coarse vertices, linear over the leaves
 * of a coarse mesh (c->indirect1: the roots split to about equal area,
 * CACHE_BOUNCE_LEAVES triangles). The displayed
 * gather of that source is bounces 1..K at the displayed vertices: the final
 * gather hides the coarse solution's size and noise, as in photon-map final
 * gathering; only bounce 1 needs the refined source (a shadow edge, a lamp's
 * spot), the later ones are smooth.
 *
 * The B_k come from a transport traced once (cache_bounces_init): R stratified
 * cosine-weighted rays per coarse vertex (Embree, samp_surface_hits_trace), each
 * hit on the front of a surface with albedo kept as its triangle and
 * barycentric. With no ray after that,
 *     B_1(v)     = π/R · Σ_h kd(h)·L_dd(h)     L_dd from the direct mesh as it is now
 *     B_(k+1)(v) = 1/R · Σ_h kd(h)·B_k(h)      B_k linear over h's coarse leaf
 * (the Jacobi iteration of the radiosity system on the coarse vertices, with
 * the same hits for every bounce). cache_bounces_update re-evaluates it when the
 * source is rebuilt and something it reads changed (the direct mesh, the lights,
 * the JND, what is seen). A light edit therefore takes no sample here either.
 * Two things keep B_1 right (docs/cache.md, "Bounces"): the direct mesh is split
 * to at least the coarse mesh's depth everywhere (the hits lie on surfaces no
 * pixel sees, where it would stay at its roots), and coarse vertices on an open
 * edge start their rays inside their triangle (a floor ending under a wall).
 *
 * auto (CACHE_BOUNCES_AUTO): the smallest K whose picture is within a quarter
 * of the JND (CACHE_BOUNCES_REST_SHARE) of all bounces' at every seen coarse
 * vertex: the tone-mapped colour (CIELAB ΔE,
 * the cache's own figures: L_dd from the direct mesh) with E ≈ B_1 + … + B_K
 * against E ≈ B_1 + B_2 + … (iterated until a bounce adds under 1e-3 of the
 * sum, at most CACHE_BOUNCES_MAX). Not "the next bounce is below the JND": in a
 * sphere of albedo 0.5 at JND 1 that stops at 3 bounces, ΔE 1.6 from the whole
 * series (tests/cache_test.c). A quarter, not the whole JND: the bounces left
 * out darken every seen point the same way, a bias on top of the interpolation
 * and noise that the cache's convergence weighs against the JND; with the whole
 * JND the Veach door stopped at 14 bounces, the rest ΔE 1.65 where seen, and its
 * picture was mean ΔE 3.66 from the full transport at 60 s against 3.43 with a
 * quarter (20 bounces; docs/cache.md, "Bounces within a quarter of the JND").
 * A further bounce costs one pass over the transport's hits (the door: 2 ms).
 * cache_bounce_stats.why says why it stopped. The specular term is left out of
 * that colour: it only masks, so the count errs high.
 *
 * Does NOT do: the transport's own noise and bias (R rays per vertex, fixed; the
 * linear interpolation of B_k over a coarse leaf), light from the back of a
 * surface (it sends nothing, as in the gathers; the references reflect it), or
 * glossy interreflection (the model transport is diffuse after the first bounce).
 * Units: B_k and E_m are irradiance, W·m⁻² (RGB), like E_i.
 * Threads: the cache's (one thread); the tracing uses the sampler's threads.
 */
#include "mesh/cache/cache_internal.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "src/base/tonemap.h"
#include "src/base/vecmath.h"

void cache_bounces_free(cache_bounce_state *b)
{
    free(b->vid);
    free(b->depth);
    free(b->tv_first);
    free(b->tv_index);
    free(b->tv_bary);
    free(b->hit_first);
    free(b->hit_tri);
    free(b->hit_bary);
    free(b->hit_corner);
    free(b->hit_weight);
    free(b->b);
    free(b->next);
    free(b->sum);
    free(b->shown);
    free(b->whole);
    free(b->seen);
    memset(b, 0, sizeof *b);
}

static double tri_area(const scene *s, uint32_t t)
{
    const uint32_t *v = s->tris[t].v;
    lm_dvec3 a = dv3_load(s->positions + 3 * (size_t)v[0]), b = dv3_load(s->positions + 3 * (size_t)v[1]),
             cc = dv3_load(s->positions + 3 * (size_t)v[2]);
    return 0.5 * dv3_length(dv3_cross(dv3_sub(b, a), dv3_sub(cc, a)));
}

static lm_result split_to(mesh_qmesh *m, uint32_t node, int depth, lm_error *err)
{
    if (depth <= 0) return LM_OK;
    lm_result r = mesh_qmesh_split(m, node, err);
    uint32_t child = r == LM_OK ? mesh_qmesh_node(m, node)->child : MESH_QMESH_NONE;
    for (uint32_t k = 0; r == LM_OK && k < 4; ++k) r = split_to(m, child + k, depth - 1, err);
    return r;
}

typedef struct index_ctx {
    cache *c;
    uint32_t *at;    /* per vertex id: coarse index, or UINT32_MAX */
    uint32_t *stamp; /* per vertex id: 1 + the last triangle that listed it, or 0 */
    uint32_t tri;
} index_ctx;

/* Every leaf corner of triangle ctx->tri's tree: a coarse index, and an entry of
 * the triangle's list (once per triangle). */
static lm_result index_leaf(const mesh_qmesh *m, uint32_t node, const mesh_qnode *n, void *user, lm_error *err)
{
    (void)node;
    index_ctx *x = user;
    cache_bounce_state *b = &x->c->bnc;
    if (n->child != MESH_QMESH_NONE) return LM_OK;
    for (int k = 0; k < 3; ++k) {
        uint32_t v = n->v[k];
        if (x->at[v] == UINT32_MAX) {
            x->at[v] = b->nv;
            b->vid[b->nv++] = v;
        }
        uint32_t i = x->at[v];
        if (x->stamp[v] == x->tri + 1) continue; /* listed for this triangle already */
        x->stamp[v] = x->tri + 1;
        if (b->tv_n == b->tv_cap) {
            size_t cap = lm_grow_capacity(b->tv_cap, (size_t)b->tv_n + 1, 1024, UINT32_MAX);
            if (!cap || !lm_realloc_array(&b->tv_index, b->tv_cap, cap, sizeof *b->tv_index) ||
                !lm_realloc_array(&b->tv_bary, b->tv_cap, cap, 2 * sizeof *b->tv_bary))
                return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory for the bounces' transport");
            b->tv_cap = (uint32_t)cap;
        }
        double w1, w2;
        cache_node_corner_bary(n, k, &w1, &w2);
        b->tv_index[b->tv_n] = i;
        b->tv_bary[2 * (size_t)b->tv_n] = (float)w1;
        b->tv_bary[2 * (size_t)b->tv_n + 1] = (float)w2;
        b->tv_n++;
    }
    (void)m;
    return LM_OK;
}

/* The coarse mesh: c->indirect1's roots split until its triangles have about
 * equal area, CACHE_BOUNCE_LEAVES of them over the scene (a wall of two triangles
 * gets enough vertices for the light its corners lose or gain), at most
 * CACHE_BOUNCE_DEPTH levels; its leaf corners are the coarse vertices. Per scene
 * triangle, the coarse vertices on it and where (tv_first, tv_index, tv_bary).
 * *at_out: per vertex id, its coarse index or UINT32_MAX (the caller frees it). */
static lm_result index_vertices(cache *c, uint32_t **at_out, lm_error *err)
{
    cache_bounce_state *b = &c->bnc;
    const scene *s = c->s;
    double total = 0.0;
    for (uint32_t t = 0; t < s->tri_count; ++t)
        if (cache_tri_active(c, t) && mesh_qmesh_root(c->indirect1, t) != MESH_QMESH_NONE) total += tri_area(s, t);
    const double target = total / CACHE_BOUNCE_LEAVES;
    b->depth = calloc(s->tri_count ? s->tri_count : 1, 1);
    lm_result r = b->depth ? LM_OK : lm_fail(err, LM_ERR_NO_MEMORY, "out of memory for the bounces' transport");
    for (uint32_t t = 0; r == LM_OK && t < s->tri_count; ++t) {
        uint32_t root = mesh_qmesh_root(c->indirect1, t);
        if (root == MESH_QMESH_NONE || !(target > 0.0) || !cache_tri_active(c, t)) continue;
        double ratio = tri_area(s, t) / target;
        int depth = ratio > 1.0 ? (int)ceil(0.5 * log2(ratio)) : 0;
        depth = depth < CACHE_BOUNCE_DEPTH ? depth : CACHE_BOUNCE_DEPTH;
        b->depth[t] = (uint8_t)depth;
        r = split_to(c->indirect1, root, depth, err);
    }
    if (r != LM_OK) return r;
    const uint32_t limit = mesh_vtable_id_limit(c->vt);
    index_ctx x = {.c = c};
    x.at = malloc((limit ? limit : 1) * sizeof *x.at);
    x.stamp = calloc(limit ? limit : 1, sizeof *x.stamp);
    b->vid = malloc((limit ? limit : 1) * sizeof *b->vid);
    b->tv_first = malloc(((size_t)s->tri_count + 1) * sizeof *b->tv_first);
    if (!x.at || !x.stamp || !b->vid || !b->tv_first) r = lm_fail(err, LM_ERR_NO_MEMORY, "out of memory for the bounces' transport");
    for (uint32_t i = 0; r == LM_OK && i < limit; ++i) x.at[i] = UINT32_MAX;
    b->nv = 0;
    for (uint32_t t = 0; r == LM_OK && t < s->tri_count; ++t) {
        b->tv_first[t] = b->tv_n;
        uint32_t root = mesh_qmesh_root(c->indirect1, t);
        if (root == MESH_QMESH_NONE || !cache_tri_active(c, t)) continue;
        x.tri = t;
        const cache_region whole = {.tri = t, .w1 = {0, 1, 0}, .w2 = {0, 0, 1}};
        r = cache_region_walk(c->indirect1, &whole, index_leaf, &x, err);
    }
    if (r == LM_OK) b->tv_first[s->tri_count] = b->tv_n;
    free(x.stamp);
    *at_out = x.at;
    return r;
}

typedef struct direct_split_ctx {
    cache *c;
    int depth;
    uint32_t *leaves;
    size_t n, cap;
} direct_split_ctx;

static lm_result shallow_leaf(const mesh_qmesh *m, uint32_t node, const mesh_qnode *n, void *user, lm_error *err)
{
    (void)m;
    direct_split_ctx *x = user;
    if (n->child != MESH_QMESH_NONE || (int)n->depth >= x->depth) return LM_OK;
    if (x->n == x->cap && !LM_GROW(x->leaves, x->cap, x->n + 1))
        return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory refining the direct mesh for the bounces");
    x->leaves[x->n++] = node;
    return LM_OK;
}

/* The direct mesh made at least as fine as the coarse mesh everywhere: B_1 reads
 * L_dd at the transport's hits, many on surfaces no pixel sees and no visible
 * gather draws from, where the direct mesh stays at its roots. In the closed
 * cube of tests/cache_test.c seen from inside, L_dd read from such a mesh at
 * the hits summed to 0.857 of its exact value, and every bounce beyond the
 * first came out a fifth low (docs/cache.md, "Bounces"). The new vertices' values
 * come from the light meshes, as any split's. */
static lm_result refine_direct_to_coarse(cache *c, lm_error *err)
{
    cache_bounce_state *b = &c->bnc;
    const scene *s = c->s;
    direct_split_ctx x = {.c = c};
    lm_result r = LM_OK;
    for (uint32_t t = 0; r == LM_OK && t < s->tri_count; ++t) {
        if (!b->depth[t] || mesh_qmesh_root(c->direct, t) == MESH_QMESH_NONE || !cache_tri_active(c, t)) continue;
        x.n = 0;
        x.depth = b->depth[t];
        const cache_region whole = {.tri = t, .w1 = {0, 1, 0}, .w2 = {0, 0, 1}};
        r = cache_region_walk(c->direct, &whole, shallow_leaf, &x, err);
        for (size_t i = 0; r == LM_OK && i < x.n; ++i)
            r = split_to(c->direct, x.leaves[i], x.depth - (int)mesh_qmesh_node(c->direct, x.leaves[i])->depth, err);
    }
    free(x.leaves);
    /* The vertices without a value: the new midpoints. */
    const uint32_t limit = mesh_vtable_id_limit(c->vt);
    cache_site *sites = NULL;
    size_t ns = 0, cap = 0;
    for (uint32_t id = 0; r == LM_OK && id < limit; ++id) {
        float v[3];
        if (mesh_qmesh_get_value(c->direct, id, v) != 0) continue; /* sampled, or not in the mesh */
        const mesh_vertex *mv = mesh_vtable_vertex(c->vt, id);
        if (ns == cap && !LM_GROW(sites, cap, ns + 1)) {
            r = lm_fail(err, LM_ERR_NO_MEMORY, "out of memory refining the direct mesh for the bounces");
            break;
        }
        double scale = ldexp(1.0, -(int)mv->bary.depth);
        sites[ns++] = (cache_site){.vid = id, .tri = mv->tri, .w1 = mv->bary.w[1] * scale, .w2 = mv->bary.w[2] * scale,
                                   .depth = mv->bary.depth};
    }
    float *rgb = r == LM_OK && ns ? malloc(3 * ns * sizeof *rgb) : NULL;
    if (r == LM_OK && ns && !rgb) r = lm_fail(err, LM_ERR_NO_MEMORY, "out of memory refining the direct mesh for the bounces");
    if (r == LM_OK && ns) r = cache_light_values(c, CACHE_KIND_DIRECT, sites, (uint32_t)ns, rgb, err);
    for (size_t i = 0; r == LM_OK && i < ns; ++i) r = mesh_qmesh_set_value(c->direct, sites[i].vid, rgb + 3 * i, err);
    b->stats.direct_vertices = (uint32_t)ns;
    free(rgb);
    free(sites);
    return r;
}

/* What the transport records: the fronts of active triangles with albedo
 * (cache_init_seen: the others send nothing until they take part). */
static int sends_light(const scene *s, uint32_t t, void *user)
{
    return cache_tri_active(user, t) && cache_has_albedo(s, t, NULL);
}

lm_result cache_bounces_init(cache *c, lm_error *err)
{
    cache_bounce_state *b = &c->bnc;
    if (!c->indirect1 || b->hit_first) return LM_OK;
    double t0 = lm_now_seconds();
    uint32_t *at = NULL;
    lm_result r = index_vertices(c, &at, err);
    if (r == LM_OK && !c->desc.single_mesh) r = refine_direct_to_coarse(c, err);
    const uint32_t nv = b->nv;
    /* Rays a vertex: bounce_rays, fewer (a square, at least one) where the roots
     * alone are many (a 70,000-triangle bunny in a box: 35,000 coarse vertices,
     * 2.2 million hits at 64 rays, 70 MB and seconds an evaluation). The final
     * gather averages their noise over many vertices. */
    uint32_t R = c->desc.bounce_rays;
    while (R > 1 && (uint64_t)R * nv > CACHE_BOUNCE_RAY_BUDGET) {
        uint32_t side = (uint32_t)floor(sqrt((double)R));
        R = (side - 1) * (side - 1);
    }
    if (R < 1) R = 1;
    samp_point *pts = NULL;
    uint32_t *count = NULL, *tri = NULL;
    float *bary = NULL;
    if (r == LM_OK) {
        size_t n = nv ? nv : 1;
        pts = malloc(n * sizeof *pts);
        count = malloc(n * sizeof *count);
        tri = malloc(n * R * sizeof *tri);
        bary = malloc(2 * n * R * sizeof *bary);
        b->hit_first = malloc((n + 1) * sizeof *b->hit_first);
        b->b = calloc(3 * n, sizeof *b->b);
        b->next = calloc(3 * n, sizeof *b->next);
        b->sum = calloc(3 * n, sizeof *b->sum);
        b->shown = calloc(3 * n, sizeof *b->shown);
        b->whole = calloc(3 * n, sizeof *b->whole);
        b->seen = malloc(n);
        if (!pts || !count || !tri || !bary || !b->hit_first || !b->b || !b->next || !b->sum || !b->shown ||
            !b->whole || !b->seen)
            r = lm_fail(err, LM_ERR_NO_MEMORY, "out of memory tracing the bounces' transport (%u vertices)", nv);
    }
    if (r == LM_OK) {
        memset(b->seen, 1, nv ? nv : 1);
        for (uint32_t i = 0; i < nv; ++i) pts[i] = cache_gather_point(c, b->vid[i]);
        r = samp_surface_hits_trace(c->sp, pts, nv,
                                    &(samp_surface_hits){.rays = R, .count = count, .tri = tri, .bary = bary,
                                                         .keep = sends_light, .keep_user = c},
                                    err);
        c->effort += (uint64_t)nv * R;
    }
    /* Kept compact: each vertex's hits one after the other, each with the coarse
     * leaf holding it (its corners' indices and weights). */
    uint64_t total = 0;
    for (uint32_t i = 0; r == LM_OK && i < nv; ++i) total += count[i];
    if (r == LM_OK && total >= UINT32_MAX)
        r = lm_fail(err, LM_ERR_NO_MEMORY, "the bounces' transport has too many hits (%llu)", (unsigned long long)total);
    if (r == LM_OK) {
        size_t h = total ? total : 1;
        b->hit_tri = malloc(h * sizeof *b->hit_tri);
        b->hit_bary = malloc(2 * h * sizeof *b->hit_bary);
        b->hit_corner = malloc(3 * h * sizeof *b->hit_corner);
        b->hit_weight = malloc(2 * h * sizeof *b->hit_weight);
        if (!b->hit_tri || !b->hit_bary || !b->hit_corner || !b->hit_weight)
            r = lm_fail(err, LM_ERR_NO_MEMORY, "out of memory for the bounces' transport");
    }
    uint32_t h = 0;
    for (uint32_t i = 0; r == LM_OK && i < nv; ++i) {
        b->hit_first[i] = h;
        for (uint32_t j = 0; j < count[i]; ++j) {
            size_t from = (size_t)i * R + j;
            uint32_t leaf, *cn = b->hit_corner + 3 * (size_t)h;
            double l[3];
            lm_error ignore;
            if (mesh_qmesh_locate(c->indirect1, tri[from], bary[2 * from], bary[2 * from + 1], &leaf, l, &ignore) !=
                LM_OK)
                continue;
            const mesh_qnode *nd = mesh_qmesh_node(c->indirect1, leaf);
            /* Every leaf corner is a coarse vertex (index_vertices). */
            for (int k = 0; k < 3; ++k) cn[k] = at[nd->v[k]];
            if (cn[0] == UINT32_MAX || cn[1] == UINT32_MAX || cn[2] == UINT32_MAX) continue;
            b->hit_tri[h] = tri[from];
            b->hit_bary[2 * (size_t)h] = bary[2 * from];
            b->hit_bary[2 * (size_t)h + 1] = bary[2 * from + 1];
            b->hit_weight[2 * (size_t)h] = (float)l[1];
            b->hit_weight[2 * (size_t)h + 1] = (float)l[2];
            h++;
        }
    }
    if (r == LM_OK) {
        b->hit_first[nv] = h;
        b->stats.vertices = nv;
        b->stats.rays = R;
        b->stats.hits = h;
        b->bytes = (size_t)h * (8 * sizeof(float)) + (size_t)nv * (5 * 3 * sizeof(float) + 2 * sizeof(uint32_t) + 1) +
                   (size_t)b->tv_n * 3 * sizeof(float) + ((size_t)c->s->tri_count + 1) * sizeof(uint32_t);
    }
    free(at);
    free(pts);
    free(count);
    free(tri);
    free(bary);
    b->stats.trace_seconds = lm_now_seconds() - t0;
    return r;
}

/* Which coarse vertices are seen: those on triangles with pixels. */
static void mark_seen(cache *c, const uint32_t *pixels)
{
    cache_bounce_state *b = &c->bnc;
    for (uint32_t i = 0; i < b->nv; ++i) b->seen[i] &= 1; /* bit 1: seen by these pixels */
    for (uint32_t t = 0; t < c->s->tri_count; ++t)
        if (pixels[t])
            for (uint32_t e = b->tv_first[t]; e < b->tv_first[t + 1]; ++e) b->seen[b->tv_index[e]] |= 2;
    for (uint32_t i = 0; i < b->nv; ++i) {
        uint8_t now = b->seen[i] >> 1;
        b->dirty |= now != (b->seen[i] & 1);
        b->seen[i] = now;
    }
}

/* out = what vertex i's hits see of the per-vertex field `from` (RGB), each hit
 * weighted by its albedo, summed over the hits over R: B_(k+1) from B_k. */
static void propagate(const cache *c, const float *from, float *out)
{
    const cache_bounce_state *b = &c->bnc;
    const scene *s = c->s;
    const float inv = 1.0f / (float)b->stats.rays;
    for (uint32_t i = 0; i < b->nv; ++i) {
        double acc[3] = {0, 0, 0};
        for (uint32_t h = b->hit_first[i]; h < b->hit_first[i + 1]; ++h) {
            const uint32_t *cn = b->hit_corner + 3 * (size_t)h;
            float w1 = b->hit_weight[2 * (size_t)h], w2 = b->hit_weight[2 * (size_t)h + 1], w0 = 1.0f - w1 - w2;
            const float *kd = s->materials[s->tris[b->hit_tri[h]].material].kd;
            for (int ch = 0; ch < 3; ++ch)
                acc[ch] += kd[ch] * (w0 * from[3 * (size_t)cn[0] + (size_t)ch] + w1 * from[3 * (size_t)cn[1] + (size_t)ch] +
                                     w2 * from[3 * (size_t)cn[2] + (size_t)ch]);
        }
        for (int ch = 0; ch < 3; ++ch) out[3 * (size_t)i + (size_t)ch] = (float)acc[ch] * inv;
    }
}

/* B_1 from the direct mesh as it is now. */
static void first_bounce(const cache *c, float *out)
{
    const cache_bounce_state *b = &c->bnc;
    const scene *s = c->s;
    const float scale = (float)M_PI / (float)b->stats.rays;
    for (uint32_t i = 0; i < b->nv; ++i) {
        double acc[3] = {0, 0, 0};
        for (uint32_t h = b->hit_first[i]; h < b->hit_first[i + 1]; ++h) {
            uint32_t t = b->hit_tri[h];
            if (mesh_qmesh_root(c->direct, t) == MESH_QMESH_NONE) continue;
            float L[3];
            lm_error ignore;
            if (mesh_qmesh_interpolate(c->direct, t, b->hit_bary[2 * (size_t)h], b->hit_bary[2 * (size_t)h + 1], L,
                                       &ignore) != LM_OK)
                continue;
            const float *kd = s->materials[s->tris[t].material].kd;
            for (int ch = 0; ch < 3; ++ch) acc[ch] += kd[ch] * L[ch];
        }
        for (int ch = 0; ch < 3; ++ch) out[3 * (size_t)i + (size_t)ch] = (float)acc[ch] * scale;
    }
}

/* What an evaluation compares, per seen tv entry (in tv order, the unseen
 * skipped): L_dd there and the colours with the whole series, with what is shown
 * and with what was shown one bounce before (CIELAB). Made for one evaluation
 * and freed after it: at a million triangles the tv entries are three million,
 * and a copy of these per entry held 150 MB for the cache's life. */
/* At most this many seen points judge the bounces: every seen coarse vertex of
 * every triangle up to it (the Cornell boxes, Water), evenly spread ones beyond
 * it. A million-triangle scene has a coarse vertex at every root corner, and
 * converting three million colours to CIELAB at every bounce kept its worker
 * from refining for 5 s after the first image. */
enum { BOUNCE_SEEN_POINTS = 1 << 16 };

typedef struct seen_lab {
    float *block;                      /* one allocation holding the four */
    float *ldd, *whole, *shown, *prev; /* 3 per seen point each */
    uint32_t *entry, *tri;             /* per seen point: its tv entry and triangle */
    uint32_t n;
} seen_lab;

static lm_result seen_lab_make(const cache *c, seen_lab *sl, lm_error *err)
{
    const cache_bounce_state *b = &c->bnc;
    *sl = (seen_lab){0};
    uint64_t seen = 0;
    for (uint32_t e = 0; e < b->tv_n; ++e) seen += b->seen[b->tv_index[e]] != 0;
    const uint64_t step = seen > BOUNCE_SEEN_POINTS ? (seen + BOUNCE_SEEN_POINTS - 1) / BOUNCE_SEEN_POINTS : 1;
    const uint32_t most = (uint32_t)((seen + step - 1) / step);
    const size_t n3 = 3 * (size_t)(most ? most : 1);
    sl->block = malloc(4 * n3 * sizeof *sl->block);
    sl->entry = malloc((most ? most : 1) * sizeof *sl->entry);
    sl->tri = malloc((most ? most : 1) * sizeof *sl->tri);
    if (!sl->block || !sl->entry || !sl->tri) {
        free(sl->block);
        free(sl->entry);
        free(sl->tri);
        *sl = (seen_lab){0};
        return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory comparing the bounces (%u seen points)", most);
    }
    uint64_t k = 0;
    for (uint32_t t = 0; t < c->s->tri_count; ++t)
        for (uint32_t e = b->tv_first[t]; e < b->tv_first[t + 1]; ++e) {
            if (!b->seen[b->tv_index[e]]) continue;
            if (k++ % step == 0 && sl->n < most) {
                sl->entry[sl->n] = e;
                sl->tri[sl->n++] = t;
            }
        }
    sl->ldd = sl->block;
    sl->whole = sl->block + n3;
    sl->shown = sl->block + 2 * n3;
    sl->prev = sl->block + 3 * n3;
    return LM_OK;
}

static void seen_lab_free(seen_lab *sl)
{
    free(sl->block);
    free(sl->entry);
    free(sl->tri);
}

/* L_dd from the direct mesh at the seen points (3 each). */
static void seen_direct(const cache *c, const seen_lab *sl, float *ldd)
{
    const cache_bounce_state *b = &c->bnc;
    for (uint32_t j = 0; j < sl->n; ++j) {
        const uint32_t e = sl->entry[j], t = sl->tri[j];
        float *l = ldd + 3 * (size_t)j;
        lm_error ignore;
        if (mesh_qmesh_root(c->direct, t) == MESH_QMESH_NONE ||
            mesh_qmesh_interpolate(c->direct, t, b->tv_bary[2 * (size_t)e], b->tv_bary[2 * (size_t)e + 1], l,
                                   &ignore) != LM_OK)
            l[0] = l[1] = l[2] = 0.0f;
    }
}

/* The colour at the seen points (their triangle's material, L_dd from
 * seen_direct) with indirect irradiance E at their coarse vertices, into lab. */
static void seen_colours(const cache *c, const seen_lab *sl, const float *E, float *lab)
{
    const cache_bounce_state *b = &c->bnc;
    for (uint32_t j = 0; j < sl->n; ++j)
        cache_seen_lab(c, sl->tri[j], sl->ldd + 3 * (size_t)j, E + 3 * (size_t)b->tv_index[sl->entry[j]], NULL,
                       lab + 3 * (size_t)j);
}

/* The largest ΔE between two sets of n seen colours. */
static float largest_change(uint32_t n, const float *lab0, const float *lab1)
{
    float worst = 0.0f;
    for (uint32_t j = 0; j < n; ++j) worst = fmaxf(worst, tm_delta_e(lab0 + 3 * (size_t)j, lab1 + 3 * (size_t)j));
    return worst;
}

/* The whole series at the coarse vertices, B_1 + B_2 + … into `whole` from
 * B_1 = first, until a bounce adds less than a thousandth of the sum anywhere
 * (a thousandth of a colour is far below any JND) or CACHE_BOUNCES_MAX are in;
 * returns how many are in. Uses b->b and b->next. */
static int whole_series(cache *c, const float *first, float *whole)
{
    cache_bounce_state *b = &c->bnc;
    const size_t n3 = 3 * (size_t)b->nv;
    memcpy(b->b, first, n3 * sizeof *b->b);
    memcpy(whole, first, n3 * sizeof *whole);
    int k = 1;
    while (k < CACHE_BOUNCES_MAX) {
        propagate(c, b->b, b->next);
        k++;
        float rel = 0.0f;
        for (size_t j = 0; j < n3; ++j) {
            whole[j] += b->next[j];
            if (whole[j] > 0.0f) rel = fmaxf(rel, b->next[j] / whole[j]);
        }
        float *tmp = b->b;
        b->b = b->next;
        b->next = tmp;
        if (!(rel > 1e-3f)) break;
    }
    return k;
}

lm_result cache_bounces_update(cache *c, lm_error *err)
{
    cache_bounce_state *b = &c->bnc;
    if (!c->indirect1) return LM_OK;
    lm_result r = b->hit_first ? LM_OK : cache_bounces_init(c, err);
    if (r != LM_OK) return r;
    /* Nothing it reads has changed much (the source rebuilt after a sampler
     * change, or after a few splits): the last evaluation stands. E_m is smooth
     * and global; a few splits move it a little everywhere, and every source
     * rebuild then compared every source triangle (mark_outdated): a bunny of
     * 70,000 triangles in a box spent a third of its time there. It is evaluated
     * again once the direct mesh has changed by an eighth of its nodes, and after
     * any light edit, JND or view change. */
    int64_t moved = cache_direct_changes(c) - b->direct_at;
    if (moved < 0) moved = -moved;
    int64_t enough = (int64_t)mesh_qmesh_node_count(c->direct) / 8;
    if (!b->dirty && b->stats.updates && moved <= (enough > 16 ? enough : 16) && b->jnd_at == c->desc.jnd)
        return LM_OK;
    double t0 = lm_now_seconds();
    b->dirty = 0;
    b->direct_at = cache_direct_changes(c);
    b->jnd_at = c->desc.jnd;
    const size_t n3 = 3 * (size_t)b->nv;
    const int automatic = c->desc.bounces == CACHE_BOUNCES_AUTO;
    cache_bounce_stats *st = &b->stats;
    memset(st->de, 0, sizeof st->de);
    /* The whole series first, then K = 1, 2, … until what is shown, B_1 + … +
     * B_K, is within the JND of it where it is seen (auto), or K is the count
     * asked. E_m = B_1 + … + B_(K−1) goes into the source. */
    double t1 = lm_now_seconds();
    first_bounce(c, b->shown);
    double t2 = lm_now_seconds();
    int in_whole = whole_series(c, b->shown, b->whole);
    st->seconds[1] += t2 - t1;
    st->series_seconds += lm_now_seconds() - t2;
    memcpy(b->b, b->shown, n3 * sizeof *b->b);
    memset(b->sum, 0, n3 * sizeof *b->sum);
    seen_lab sl;
    r = seen_lab_make(c, &sl, err);
    if (r != LM_OK) return r;
    seen_direct(c, &sl, sl.ldd);
    seen_colours(c, &sl, b->whole, sl.whole);
    seen_colours(c, &sl, b->shown, sl.shown);
    int K = 1;
    const float rest_bound = CACHE_BOUNCES_REST_SHARE * c->desc.jnd;
    for (;;) {
        st->rest_de = largest_change(sl.n, sl.shown, sl.whole);
        if (automatic && !(st->rest_de > rest_bound)) {
            snprintf(st->why, sizeof st->why,
                     "auto: the bounces after %d would add at most ΔE %.2f where they are seen, below a quarter of "
                     "the JND (%.2f)",
                     K, (double)st->rest_de, (double)rest_bound);
            break;
        }
        if (!automatic && K >= c->desc.bounces) {
            snprintf(st->why, sizeof st->why, "%d bounce%s, as asked (the rest would add ΔE %.2f where seen)", K,
                     K == 1 ? "" : "s", (double)st->rest_de);
            break;
        }
        if (K >= in_whole) {
            if (K >= CACHE_BOUNCES_MAX)
                snprintf(st->why, sizeof st->why, "%s%d bounces, the most there can be (the rest would add ΔE %.2f)",
                         automatic ? "auto: " : "", K, (double)st->rest_de);
            else
                snprintf(st->why, sizeof st->why,
                         "%s%d bounces, all that change anything (the rest would add ΔE %.2f where seen)",
                         automatic ? "auto: " : "", K, (double)st->rest_de);
            break;
        }
        double tk = lm_now_seconds();
        propagate(c, b->b, b->next);
        for (size_t j = 0; j < n3; ++j) {
            b->sum[j] += b->b[j];
            b->shown[j] += b->next[j];
        }
        float *tmp = b->b;
        b->b = b->next;
        b->next = tmp;
        tmp = sl.prev;
        sl.prev = sl.shown;
        sl.shown = tmp;
        seen_colours(c, &sl, b->shown, sl.shown);
        st->de[K + 1] = largest_change(sl.n, sl.prev, sl.shown);
        st->seconds[K + 1] += lm_now_seconds() - tk;
        K++;
    }
    seen_lab_free(&sl);
    st->bounces = K;
    st->automatic = automatic;
    for (uint32_t i = 0; r == LM_OK && i < b->nv; ++i)
        r = mesh_qmesh_set_value(c->indirect1, b->vid[i], b->sum + 3 * (size_t)i, err);
    st->update_seconds += lm_now_seconds() - t0;
    st->updates++;
    return r;
}

int cache_bounces_depth(const cache *c, uint32_t tri)
{
    return c->bnc.depth && tri < c->s->tri_count ? c->bnc.depth[tri] : 0;
}

void cache_bounces_touch(cache *c)
{
    c->bnc.dirty = 1;
}

void cache_bounces_see(cache *c, const uint32_t *pixels)
{
    if (c->indirect1 && c->bnc.seen && pixels) mark_seen(c, pixels);
}
