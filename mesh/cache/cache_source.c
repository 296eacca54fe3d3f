/* cache_source.c — indirect light in the cache (cache.h, eq. 7): the radiance
 * source that indirect samples gather from (a cut of the direct mesh), gathering
 * again the values the source's rebuilds have outdated (which cache_drift.c
 * finds), and gathering everything again after a light edit; the gathers
 * themselves are cache_gather.c's. Owns cache_source_state (cache_internal.h);
 * calls only cache_site.c below it (it reads the direct mesh and
 * cache_light_state.revised, and calls no file above: the scheduler is told of
 * moved values through the cache_changed_fn it passes). Worker thread, like the
 * rest of the cache. */
#include "mesh/cache/cache_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "sampling/analytic.h"
#include "sampling/samp.h"
#include "src/base/parallel.h"
#include "src/base/vecmath.h"

/* The source is a cut of the direct mesh of the roots and at most this many more
 * triangles (a scene of more triangles than this still gets a cut that follows
 * the light where gathers see it, docs/cache.md): indirect
 * irradiance is smooth, and every indirect sample draws or searches the whole
 * source (the paper gathers from a coarse direct mesh, §5). With the full leaf set
 * of the built-in Cornell box (31,000 triangles) a GL hemicube sample cost 6 ms. */
#define CACHE_RMESH_TRIANGLES 8192u
/* Rebuild the source when the direct mesh has changed, since the last build, by a
 * quarter of its nodes then (kept splits and revised values), at least 16 and at
 * most this many; always before the first indirect samples, and when refinement
 * has nothing left to test (cache_settle_source). The cap was 256: a rebuild
 * every 256 changes made the 116k box's rebuilds flag about 10,000 values each,
 * and it converged in 46.5 s against 20.6 (docs/cache.md, "Borrowed values
 * tested"); a direct mesh under 1,024 nodes rebuilds as often as before, and the
 * Cornell boxes' and the door's images at 1 to 20 s are the same or better. */
#define CACHE_RMESH_STALE 16384u

/* An entry of the cut's heap (cache_source_state.cut_heap). */
struct source_pick {
    float key;
    uint32_t node;
};

void cache_source_free(cache_source_state *st)
{
    samp_radiance_index_free(&st->rm_index);
    samp_radiance_index_free(&st->rp_index);
    free(st->rm_first);
    free(st->rm_bary);
    free(st->rm_rad);
    free(st->rp_first);
    free(st->rp_bary);
    free(st->rp_rad);
    free(st->drift);
    free(st->outdated);
    free(st->sigma);
    free(st->gather_level);
    free(st->sigma_likely);
    free(st->borrowed);
    free(st->unseen_stale);
    free(st->outdated_list);
    free(st->leaf_buf);
    free(st->cut_err);
    free(st->cut_open);
    free(st->cut_heap);
    free(st->imp_max);
    free(st->imp_sum);
    free(st->imp_sub);
    free(st->grown);
    free(st->pilot_vid);
    free(st->pilot_count);
    free(st->pilot_tri);
    free(st->pilot_weight);
    free(st->pilot_strat);
    free(st->pilot_stratum);
    memset(st, 0, sizeof *st);
}

size_t cache_source_bytes(const cache_source_state *st)
{
    return st->cut_cap * (sizeof *st->cut_err + sizeof *st->cut_open + sizeof *st->cut_heap) +
           (st->rm_cap + st->rp_cap) * (6 + 9) * sizeof(float) + st->drift_cap * (10 * sizeof(float) + 3) +
           st->outdated_cap * sizeof(uint32_t) + st->leaf_cap * sizeof *st->leaf_buf +
           st->imp_cap * 3 * sizeof(float) + st->grown_cap * sizeof(uint32_t) +
           st->pilot_cap * (2 + CACHE_IMPORTANCE_RAYS * 3) * sizeof(uint32_t);
}

/* ---- the cut ------------------------------------------------------------------
 *
 * Opened where linear interpolation over a node is worst: from the roots, the node
 * with the largest bound on |fine mesh − the node's own plane| (of kd·L_dd) times
 * its weight is replaced by its four children while the budget (the roots and
 * CACHE_RMESH_TRIANGLES more) allows. The weight is the node's importance
 * (imp_sum: what the viewer would see of the error) once any was recorded, its
 * area before. The bound is
 * built bottom-up: 0 at a leaf; at an inner node, the largest of its children's
 * plus the largest deviation of the values at its edge midpoints from the mean of
 * the edge's ends (the children's planes differ from the parent's by at most that). */


static float source_error(cache *c, uint32_t node)
{
    const mesh_qnode *n = mesh_qmesh_node(c->direct, node);
    if (n->child == MESH_QMESH_NONE) return c->src.cut_err[node] = 0.0f;
    const uint32_t child = n->child, tri = n->tri, corner[3] = {n->v[0], n->v[1], n->v[2]};
    const float *kd = c->s->materials[c->s->tris[tri].material].kd;
    float worst = 0.0f;
    for (uint32_t k = 0; k < 4; ++k) worst = fmaxf(worst, source_error(c, child + k));
    /* The centre child's corners are the midpoints of edges 01, 12, 20. */
    const mesh_qnode *centre = mesh_qmesh_node(c->direct, child + 3);
    float dev = 0.0f;
    for (int j = 0; j < 3; ++j) {
        float a[3], b[3], m[3];
        if (mesh_qmesh_get_value(c->direct, corner[j], a) != 1 || mesh_qmesh_get_value(c->direct, corner[(j + 1) % 3], b) != 1 ||
            mesh_qmesh_get_value(c->direct, centre->v[j], m) != 1)
            continue;
        for (int ch = 0; ch < 3; ++ch) dev = fmaxf(dev, kd[ch] * fabsf(m[ch] - 0.5f * (a[ch] + b[ch])));
    }
    return c->src.cut_err[node] = worst + dev;
}

static void heap_push(struct source_pick *h, uint32_t *n, struct source_pick e)
{
    uint32_t i = (*n)++;
    while (i > 0 && h[(i - 1) / 2].key < e.key) {
        h[i] = h[(i - 1) / 2];
        i = (i - 1) / 2;
    }
    h[i] = e;
}

static struct source_pick heap_pop(struct source_pick *h, uint32_t *n)
{
    struct source_pick top = h[0], last = h[--*n];
    uint32_t i = 0;
    for (;;) {
        uint32_t l = 2 * i + 1, r = l + 1, big = i;
        float kb = last.key;
        if (l < *n && h[l].key > kb) big = l, kb = h[l].key;
        if (r < *n && h[r].key > kb) big = r;
        if (big == i) break;
        h[i] = h[big];
        i = big;
    }
    if (*n) h[i] = last;
    return top;
}

/* What an error over a node weighs when the cut is chosen: its importance once
 * any is known (a node nothing visible gathers from weighs nothing beyond a
 * trace of its area, so ties still open the larger), its area before.
 * The importance of a node is what was recorded anywhere inside it (imp_sub:
 * the cut opens from the roots, and hits recorded at a fine cut are inside
 * the coarse nodes it must open first), or its area's share of an ancestor's
 * where that is more (a node nothing was recorded in yet). With the node's own
 * records only, a root whose hits were all recorded at its descendants weighed
 * what its few early gathers gave it: the cut left it closed, the gathers then
 * recorded at it and the next cut opened it again — the indirect light of
 * CornellBox-Original dipped by a quarter and back while refining
 * (docs/cache.md, "A dip of the indirect source"). */
static float cut_weight(const cache *c, uint32_t node)
{
    const mesh_qnode *n = mesh_qmesh_node(c->direct, node);
    float area = (float)(c->s->tri_areas[n->tri] * ldexp(1.0, -2 * (int)n->depth));
    if (!c->src.imp_any) return area;
    float sub = 0.0f, share = 1.0f;
    for (uint32_t a = node; a != MESH_QMESH_NONE; a = mesh_qmesh_node(c->direct, a)->parent, share *= 0.25f)
        if (a < c->src.imp_cap) sub = fmaxf(sub, c->src.imp_sub[a] * share);
    return sub + 1e-9f * area;
}

/* Marks in c->src.cut_open the nodes the cut opens. */
static lm_result choose_cut(cache *c, lm_error *err)
{
    const scene *s = c->s;
    cache_source_state *st = &c->src;
    uint32_t limit = mesh_qmesh_node_limit(c->direct);
    if (limit > st->cut_cap) { /* three arrays, one capacity: the node limit itself */
        if (!lm_realloc_array(&st->cut_err, st->cut_cap, limit, sizeof *st->cut_err) ||
            !lm_realloc_array(&st->cut_open, st->cut_cap, limit, sizeof *st->cut_open) ||
            !lm_realloc_array(&st->cut_heap, st->cut_cap, limit, sizeof *st->cut_heap))
            return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory for the indirect source");
        st->cut_cap = limit;
    }
    memset(c->src.cut_open, 0, limit);
    uint32_t hn = 0, count = 0;
    for (uint32_t t = 0; t < s->tri_count; ++t) {
        uint32_t root = mesh_qmesh_root(c->direct, t);
        if (root == MESH_QMESH_NONE || !cache_tri_active(c, t)) continue; /* inactive: sends nothing yet */
        count++;
        float e = source_error(c, root);
        if (e > 0.0f) heap_push(c->src.cut_heap, &hn, (struct source_pick){e * cut_weight(c, root), root});
    }
    const uint32_t budget = count + CACHE_RMESH_TRIANGLES;
    while (hn && count + 3 <= budget) {
        struct source_pick p = heap_pop(c->src.cut_heap, &hn);
        const mesh_qnode *n = mesh_qmesh_node(c->direct, p.node);
        c->src.cut_open[p.node] = 1;
        count += 3;
        for (uint32_t k = 0; k < 4; ++k) {
            float e = c->src.cut_err[n->child + k];
            if (e > 0.0f)
                heap_push(c->src.cut_heap, &hn, (struct source_pick){e * cut_weight(c, n->child + k), n->child + k});
        }
    }
    return LM_OK;
}

/* Appends the source triangles of cut node `leaf`, split `levels` more times:
 * where the further bounces' coarse mesh is finer than the cut, the source
 * follows it, so that E_m keeps its shape in the source (a wall lit only
 * indirectly has no direct light to open the cut; its E_m over the root's
 * corners alone lost a sixth of the door's wall light: docs/cache.md,
 * "Bounces"). Only the node and the path are kept; piece_corners makes the
 * corners again. */
static lm_result emit_source(cache *c, uint32_t leaf, uint32_t path, int levels, int depth, size_t *count,
                             lm_error *err)
{
    if (depth < levels) {
        lm_result r = LM_OK;
        for (uint32_t k = 0; r == LM_OK && k < 4; ++k)
            r = emit_source(c, leaf, path | k << (2 * depth), levels, depth + 1, count, err);
        return r;
    }
    if (*count == c->src.leaf_cap && !LM_GROW_RAW(c->src.leaf_buf, c->src.leaf_cap, *count + 1))
        return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory for the indirect source");
    c->src.leaf_buf[(*count)++] = (cache_source_piece){.leaf = leaf, .path = (uint16_t)path, .levels = (uint8_t)levels};
    return LM_OK;
}

/* Splits of a cut node a source triangle may take: a piece's path has 2 bits a split. */
#define PIECE_LEVELS_MAX 8
_Static_assert(CACHE_BOUNCE_DEPTH <= PIECE_LEVELS_MAX, "a source piece's path holds 8 splits");

/* The corners of source piece p (scene triangle, dyadic corners, vertex ids of
 * the direct mesh: MESH_VTABLE_NONE where a corner is not one). Midpoints keep
 * the corners' orientation: (c0, m01, m20), (m01, c1, m12), (m20, m12, c2),
 * (m01, m12, m20). */
static uint32_t piece_corners(const cache *c, const cache_source_piece *p, mesh_bary b[3], uint32_t v[3])
{
    const mesh_qnode *n = mesh_qmesh_node(c->direct, p->leaf);
    for (int k = 0; k < 3; ++k) {
        b[k] = mesh_qmesh_node_corner(n, k);
        v[k] = n->v[k];
    }
    for (int j = 0; j < p->levels; ++j) {
        const uint32_t child = (uint32_t)p->path >> (2 * j) & 3u, N = MESH_VTABLE_NONE;
        mesh_bary m[3]; /* m[0] = m01, m[1] = m12, m[2] = m20 */
        for (int k = 0; k < 3; ++k)
            if (mesh_bary_midpoint(b[k], b[(k + 1) % 3], &m[k]) != LM_OK)
                return n->tri; /* past MESH_DEPTH_MAX: collect_source emits no such path */
        const mesh_bary cb[4][3] = {{b[0], m[0], m[2]}, {m[0], b[1], m[1]}, {m[2], m[1], b[2]}, {m[0], m[1], m[2]}};
        const uint32_t keep = child < 3 ? v[child] : N;
        for (int k = 0; k < 3; ++k) {
            b[k] = cb[child][k];
            v[k] = (uint32_t)k == child ? keep : N;
        }
    }
    return n->tri;
}

/* Appends the cut's triangles under `node` to c->src.leaf_buf. */
static lm_result collect_source(cache *c, uint32_t node, size_t *count, lm_error *err)
{
    const mesh_qnode *n = mesh_qmesh_node(c->direct, node);
    if (n->child != MESH_QMESH_NONE && c->src.cut_open[node]) {
        uint32_t child = n->child;
        for (uint32_t k = 0; k < 4; ++k) {
            lm_result r = collect_source(c, child + k, count, err);
            if (r != LM_OK) return r;
        }
        return LM_OK;
    }
    int finer = c->indirect1 ? cache_bounces_depth(c, n->tri) - (int)n->depth : 0;
    if (finer > 0) { /* as deep as the midpoints go (mesh_bary_midpoint: MESH_DEPTH_MAX) */
        const int room = MESH_DEPTH_MAX - (int)n->depth;
        finer = finer < room ? finer : room;
    }
    return emit_source(c, node, 0, finer > 0 ? finer : 0, 0, count, err);
}

/* Room for a source of n triangles in (first, bary, rad) (the layout of
 * samp_radiance_mesh); cap counts triangles. */
static lm_result grow_source(const scene *s, uint32_t **first, float **bary, float **rad, size_t *cap, size_t n,
                             lm_error *err)
{
    if (!*first) {
        *first = calloc((size_t)s->tri_count + 1, sizeof **first);
        if (!*first) return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory for the indirect source");
    }
    if (n <= *cap) return LM_OK;
    /* filled whole for the n triangles (fill_source_chunk) */
    if (!lm_realloc_array_raw(bary, *cap, n, 6 * sizeof **bary) || !lm_realloc_array_raw(rad, *cap, n, 9 * sizeof **rad))
        return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory for the indirect source");
    *cap = n;
    return LM_OK;
}

/* ---- the source ----------------------------------------------------------------- */

int64_t cache_direct_changes(const cache *c)
{
    /* Running counts, O(1): mesh_qmesh_get_stats walks every vertex (its byte
     * share), and this is asked before every gather. */
    return mesh_qmesh_net_splits(c->direct) + (int64_t)c->vis.revised;
}

/* Exchanges the current source's arrays with the previous one's. */
static void swap_source_arrays(cache_source_state *st)
{
    uint32_t *first = st->rm_first;
    float *bary = st->rm_bary, *rad = st->rm_rad;
    size_t cap = st->rm_cap;
    st->rm_first = st->rp_first, st->rm_bary = st->rp_bary, st->rm_rad = st->rp_rad, st->rm_cap = st->rp_cap;
    st->rp_first = first, st->rp_bary = bary, st->rp_rad = rad, st->rp_cap = cap;
}

/* Source triangles a chunk of the fill (fill_source_chunk) takes. */
#define SOURCE_FILL_CHUNK 4096u

typedef struct fill_source_job {
    cache *c;     /* read: the direct and bounce meshes, leaf_buf; written: rm_bary, rm_rad */
    size_t count; /* source triangles */
} fill_source_job;

/* Corners and radiance of source triangles [chunk·SOURCE_FILL_CHUNK, ...): each
 * triangle's own entries, from meshes only read, so the chunks run on every core
 * (a million-triangle scene's source took 0.13-0.18 s on one). */
static void fill_source_chunk(void *user, uint32_t chunk)
{
    const fill_source_job *job = user;
    cache *c = job->c;
    const scene *s = c->s;
    const int with_em = c->indirect1 != NULL;
    const size_t begin = (size_t)chunk * SOURCE_FILL_CHUNK;
    const size_t end = begin + SOURCE_FILL_CHUNK < job->count ? begin + SOURCE_FILL_CHUNK : job->count;
    for (size_t i = begin; i < end; ++i) {
        mesh_bary bary[3];
        uint32_t v[3];
        const uint32_t tri = piece_corners(c, &c->src.leaf_buf[i], bary, v);
        const float *kd = s->materials[s->tris[tri].material].kd;
        for (int k = 0; k < 3; ++k) {
            double scale = ldexp(1.0, -(int)bary[k].depth), w1 = bary[k].w[1] * scale, w2 = bary[k].w[2] * scale;
            c->src.rm_bary[6 * i + 2 * (size_t)k] = (float)w1;
            c->src.rm_bary[6 * i + 2 * (size_t)k + 1] = (float)w2;
            float L[3] = {0, 0, 0}, Ei[3] = {0, 0, 0};
            lm_error ignore;
            if (v[k] != MESH_VTABLE_NONE)
                mesh_qmesh_get_value(c->direct, v[k], L);
            else if (mesh_qmesh_interpolate(c->direct, tri, w1, w2, L, &ignore) != LM_OK)
                L[0] = L[1] = L[2] = 0.0f; /* a point inside a cut leaf: the direct mesh there */
            if (with_em && mesh_qmesh_root(c->indirect1, tri) != MESH_QMESH_NONE &&
                mesh_qmesh_interpolate(c->indirect1, tri, w1, w2, Ei, &ignore) != LM_OK)
                Ei[0] = Ei[1] = Ei[2] = 0;
            for (int ch = 0; ch < 3; ++ch)
                c->src.rm_rad[9 * i + 3 * (size_t)k + (size_t)ch] = kd[ch] * (L[ch] + (float)(Ei[ch] / M_PI));
        }
    }
}

/* Builds the source: kd·L_dd, and with further bounces kd·(L_dd + E_m/π), E_m
 * first brought up to date with the direct mesh (cache_bounces_update, no ray);
 * track: compare it with the previous source and flag the values it moved. */
static lm_result build_source(cache *c, int track, lm_error *err)
{
    const scene *s = c->s;
    const int with_em = c->indirect1 != NULL;
    lm_result r = with_em ? cache_bounces_update(c, err) : LM_OK;
    if (r == LM_OK) r = choose_cut(c, err);
    size_t count = 0;
    for (uint32_t t = 0; r == LM_OK && t < s->tri_count; ++t) {
        uint32_t root = mesh_qmesh_root(c->direct, t);
        if (root != MESH_QMESH_NONE && cache_tri_active(c, t)) r = collect_source(c, root, &count, err);
    }
    if (r != LM_OK) return r;
    /* The single-mesh ablation keeps what it gathered. Before the first image
     * (cache_desc.coarse_gathers set) nothing is flagged: every value is gathered
     * again right after it. */
    const int compare = track && !c->desc.single_mesh && c->initialised && !c->desc.coarse_gathers;
    if (compare) {
        /* The source built last becomes the previous one, which the new one is
         * compared with (cache_mark_outdated): its arrays and its index move
         * there, and the new source is written over the arrays of the one before
         * (they were copied, 0.1 s for a million-triangle scene's). */
        samp_radiance_index_free(&c->src.rp_index);
        c->src.rp_index = c->src.rm_index;
        memset(&c->src.rm_index, 0, sizeof c->src.rm_index);
        swap_source_arrays(&c->src);
        c->src.rp_count = c->src.rmesh.tri_count;
        c->src.rp_valid = c->src.rp_first != NULL && c->src.rmesh.first != NULL;
    } else {
        /* Nothing compares with the source it replaces: written over it. The
         * rebuild in the first image's rounds made a second source of 64 bytes a
         * scene triangle in memory touched for the first time (a million-
         * triangle scene's: 0.1 s of page faults; docs/cache.md, "The first
         * image's fresh memory"); the first rebuild compared makes it, after the
         * first image. A previous source kept from before waits unused: the next
         * comparing rebuild replaces it with this one. */
        samp_radiance_index_free(&c->src.rm_index);
    }
    c->src.rmesh = (samp_radiance_mesh){0};
    r = grow_source(s, &c->src.rm_first, &c->src.rm_bary, &c->src.rm_rad, &c->src.rm_cap, count, err);
    if (r != LM_OK) return r;
    /* Counting sort by scene triangle (the cut is collected in scene order already,
     * so this keeps the order: leaf_buf[i] is source triangle i). */
    memset(c->src.rm_first, 0, ((size_t)s->tri_count + 1) * sizeof *c->src.rm_first);
    for (size_t i = 0; i < count; ++i) c->src.rm_first[mesh_qmesh_node(c->direct, c->src.leaf_buf[i].leaf)->tri + 1]++;
    for (uint32_t t = 0; t < s->tri_count; ++t) c->src.rm_first[t + 1] += c->src.rm_first[t];
    const uint32_t chunks = (uint32_t)((count + SOURCE_FILL_CHUNK - 1) / SOURCE_FILL_CHUNK);
    lm_parallel_for(lm_thread_count(0), chunks, fill_source_chunk, &(fill_source_job){c, count});
    c->src.rmesh = (samp_radiance_mesh){.tri_count = (uint32_t)count, .first = c->src.rm_first, .bary = c->src.rm_bary,
                                    .radiance = c->src.rm_rad};
    /* Checked and indexed once here, not by every gather batch. */
    r = samp_radiance_mesh_prepare(s, &c->src.rmesh, &c->src.rm_index, err);
    if (r != LM_OK) return r;
    c->src.rmesh.index = &c->src.rm_index;
    c->src.built_at = cache_direct_changes(c);
    c->src.built_nodes = mesh_qmesh_node_count(c->direct);
    if (compare && c->src.rp_valid)
        r = cache_mark_outdated(c, err); /* and the glossy parts it may have moved visibly */
    else
        cache_glossy_outdate(c); /* untracked: every glossy part is taken again (cache_glossy.c) */
    return r;
}

lm_result cache_update_radiance_source(cache *c, int force, lm_error *err)
{
    int64_t changed = cache_direct_changes(c) - c->src.built_at;
    if (changed < 0) changed = -changed;
    uint32_t stale = c->src.built_nodes / 4;
    stale = stale < 16 ? 16 : stale > CACHE_RMESH_STALE ? CACHE_RMESH_STALE : stale;
    int fresh = c->src.rmesh.first && (c->src.settle ? changed == 0 : changed < (int64_t)stale);
    if (!force && fresh) return LM_OK;
    return build_source(c, 1, err);
}

lm_result cache_settle_source(cache *c, lm_error *err)
{
    c->src.settle = 1;
    lm_result r = cache_update_radiance_source(c, 0, err);
    c->src.settle = 0;
    return r;
}

static int cmp_vid(const void *a, const void *b)
{
    uint32_t x = *(const uint32_t *)a, y = *(const uint32_t *)b;
    return (x > y) - (x < y);
}

lm_result cache_regather_outdated(cache *c, cache_changed_fn changed, void *user, uint64_t *allowance,
                                  lm_error *err)
{
    enum { BATCH = 1024 };
    lm_result r = LM_OK;
    uint32_t *ids = NULL, *moved = NULL;
    float *E = NULL;
    /* Gathering may rebuild the source and flag more: until none is left, or the
     * allowance is spent. */
    while (r == LM_OK && c->src.outdated_n && (!allowance || *allowance > 0) && !cache_stopping(c)) {
        uint32_t n = 0;
        if (!ids) {
            ids = malloc(BATCH * sizeof *ids);
            moved = malloc(BATCH * sizeof *moved);
            E = malloc(3 * BATCH * sizeof *E);
            if (!ids || !moved || !E) {
                r = lm_fail(err, LM_ERR_NO_MEMORY, "out of memory gathering indirect light again");
                break;
            }
        }
        /* Take up to a batch (and no more than the allowance) from the end of the
         * list (still flagged, still in the mesh). The allowance counts gathers
         * of the plain count: a value taken with 4^L times the rays costs 4^L of
         * it (at least one value a batch). Counted by values, a worker step of
         * the Veach door took 512 values at their levels, up to 64 times the
         * plain rays each: 3.7 s with no snapshot (docs/cache.md, "A step's
         * regathers counted in rays"). */
        uint64_t cost = 0;
        while (n < BATCH && c->src.outdated_n) {
            uint32_t vid = c->src.outdated_list[c->src.outdated_n - 1];
            float tmp[3];
            if (!c->src.outdated[vid]) { /* gathered meanwhile */
                c->src.outdated_n--;
                continue;
            }
            const uint64_t one = cache_gather_cost(c, vid);
            if (allowance && n > 0 && cost + one > *allowance) break;
            c->src.outdated_n--;
            c->src.outdated[vid] = 0;
            if (mesh_qmesh_get_value(c->indirect, vid, tmp) == 1) {
                ids[n++] = vid;
                cost += one;
            }
        }
        if (n == 0) continue;
        /* With the rays each had: a value taken finer for its noise and gathered
         * again at the plain count would come back with the noise the
         * estimate had it taken again for, larger than the drift it was
         * flagged for (the slot refined at JND 1: its worst receiver swung
         * between 5% and 32% as the source's rebuilds undid the finer gathers;
         * docs/cache.md, "Drifted values keep their rays"). */
        r = cache_sample_indirect_like(c, ids, ids, n, E, err);
        if (allowance) *allowance = cost < *allowance ? *allowance - cost : 0;
        uint32_t nm = 0;
        for (uint32_t i = 0; r == LM_OK && i < n; ++i) {
            float old[3];
            mesh_qmesh_get_value(c->indirect, ids[i], old);
            const float *e = E + 3 * (size_t)i;
            if (old[0] == e[0] && old[1] == e[1] && old[2] == e[2]) continue;
            r = mesh_qmesh_set_value(c->indirect, ids[i], e, err);
            moved[nm++] = ids[i];
        }
        c->src.regathered += n;
        if (r == LM_OK && nm && changed) {
            qsort(moved, nm, sizeof *moved, cmp_vid);
            r = changed(c, CACHE_KIND_INDIRECT, NULL, 0, moved, nm, user, err);
        }
    }
    free(ids);
    free(moved);
    free(E);
    return r;
}

/* ---- after a light edit or a sampler change ----------------------------------------
 *
 * Every vertex of the indirect mesh(es) gathered again from a rebuilt source, in
 * batches (one-bounce indirect is linear in each light, but a per-light indirect
 * mesh would multiply memory and samples by the number of lights for every
 * refinement, for the rare edit; docs/cache.md has the numbers). */

static lm_result regather_mesh(cache *c, mesh_qmesh *m, lm_error *err)
{
    enum { BATCH = 4096 };
    const uint32_t id_limit = mesh_vtable_id_limit(c->vt);
    lm_result r = build_source(c, 0, err);
    uint32_t *ids = malloc(BATCH * sizeof *ids);
    float *E = malloc(3 * BATCH * sizeof *E), tmp[3];
    if (r == LM_OK && (!ids || !E)) r = lm_fail(err, LM_ERR_NO_MEMORY, "out of memory re-gathering indirect light");
    uint32_t n = 0;
    for (uint32_t id = 0; r == LM_OK && id <= id_limit; ++id) {
        if (id < id_limit && mesh_qmesh_get_value(m, id, tmp) == 1) ids[n++] = id;
        if (n == BATCH || (id == id_limit && n)) {
            r = cache_sample_indirect(c, ids, n, E, err);
            for (uint32_t i = 0; r == LM_OK && i < n; ++i) r = mesh_qmesh_set_value(m, ids[i], E + 3 * (size_t)i, err);
            n = 0;
        }
    }
    free(ids);
    free(E);
    return r;
}

/* Which indirect values outdate() flags. */
typedef enum outdate_which {
    OUTDATE_ALL,      /* every value (from a rebuilt source) */
    OUTDATE_GATHERED, /* every value not borrowed (from a rebuilt source) */
    OUTDATE_PLAIN     /* values gathered at the plain count, not borrowed (the source as it is) */
} outdate_which;

static lm_result outdate(cache *c, outdate_which which, lm_error *err)
{
    const uint32_t id_limit = mesh_vtable_id_limit(c->vt);
    lm_result r = which == OUTDATE_PLAIN ? LM_OK : build_source(c, 0, err);
    if (r == LM_OK) r = cache_grow_drift(&c->src, id_limit, err);
    for (uint32_t vid = 0; r == LM_OK && vid < id_limit; ++vid) {
        if (mesh_qmesh_get_value(c->indirect, vid, NULL) != 1) continue;
        if (which != OUTDATE_ALL && c->src.borrowed[vid] != 0.0f) continue;
        if (which == OUTDATE_PLAIN && c->src.gather_level[vid] != 0) continue;
        r = cache_push_outdated(&c->src, vid, err); /* a value already flagged stays flagged once */
    }
    return r;
}

lm_result cache_outdate_all(cache *c, lm_error *err) { return outdate(c, OUTDATE_ALL, err); }

lm_result cache_outdate_plain(cache *c, lm_error *err)
{
    if (!c) return lm_fail(err, LM_ERR_INVALID_ARG, "cache_outdate_plain: no cache");
    return outdate(c, OUTDATE_PLAIN, err);
}
lm_result cache_outdate_gathered(cache *c, lm_error *err) { return outdate(c, OUTDATE_GATHERED, err); }

float cache_borrowed_de(const cache *c, uint32_t vid)
{
    return vid < c->src.drift_cap && c->src.borrowed ? c->src.borrowed[vid] : 0.0f;
}

lm_result cache_set_borrowed(cache *c, uint32_t vid, const float E[3], const float sigma[3], const float likely[3],
                             float de, lm_error *err)
{
    lm_result r = cache_grow_drift(&c->src, mesh_vtable_id_limit(c->vt), err);
    if (r == LM_OK) r = mesh_qmesh_set_value(c->indirect, vid, E, err);
    if (r != LM_OK) return r;
    memcpy(c->src.sigma + 3 * (size_t)vid, sigma, 3 * sizeof *sigma);
    memcpy(c->src.sigma_likely + 3 * (size_t)vid, likely, 3 * sizeof *likely);
    memset(c->src.drift + 3 * (size_t)vid, 0, 3 * sizeof *c->src.drift);
    c->src.gather_level[vid] = 0;
    c->src.borrowed[vid] = de;
    return LM_OK;
}

/* From a source rebuilt (with E_m re-evaluated: no ray). Nothing is outdated
 * afterwards. */
lm_result cache_regather_all(cache *c, lm_error *err)
{
    lm_result r = regather_mesh(c, c->indirect, err);
    if (r == LM_OK) {
        if (c->src.drift) {
            memset(c->src.drift, 0, 3 * c->src.drift_cap * sizeof *c->src.drift);
            memset(c->src.outdated, 0, c->src.drift_cap);
        }
        c->src.outdated_n = 0;
    }
    return r;
}

/* ---- importance ------------------------------------------------------------------- */

static lm_result grow_importance(cache_source_state *st, uint32_t limit, lm_error *err)
{
    if (limit <= st->imp_cap) return LM_OK;
    size_t cap = lm_grow_capacity(st->imp_cap, limit, 1024, SIZE_MAX / sizeof(float));
    if (!cap || !lm_realloc_array(&st->imp_max, st->imp_cap, cap, sizeof *st->imp_max) ||
        !lm_realloc_array(&st->imp_sum, st->imp_cap, cap, sizeof *st->imp_sum) ||
        !lm_realloc_array(&st->imp_sub, st->imp_cap, cap, sizeof *st->imp_sub))
        return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory for the indirect source's importance");
    memset(st->imp_max + st->imp_cap, 0, (cap - st->imp_cap) * sizeof *st->imp_max);
    memset(st->imp_sum + st->imp_cap, 0, (cap - st->imp_cap) * sizeof *st->imp_sum);
    memset(st->imp_sub + st->imp_cap, 0, (cap - st->imp_cap) * sizeof *st->imp_sub);
    st->imp_cap = cap;
    return LM_OK;
}

void cache_node_importance(const cache *c, uint32_t node, float *imp_max, float *imp_sum)
{
    float mx = 0.0f, sm = 0.0f, share = 1.0f;
    for (uint32_t a = node; a != MESH_QMESH_NONE; a = mesh_qmesh_node(c->direct, a)->parent, share *= 0.25f) {
        if (a >= c->src.imp_cap) continue;
        mx = fmaxf(mx, c->src.imp_max[a] * share);
        sm = fmaxf(sm, c->src.imp_sum[a] * share);
    }
    *imp_max = mx;
    *imp_sum = sm;
}

/* ΔE per unit change of the source radiance over the whole hemisphere of a
 * visible site: the tone-mapped colour with E_i + π·h against E_i, over h. */
static float site_sensitivity(const cache *c, const cache_site *st, const float ei[3])
{
    float ldd[3] = {0, 0, 0}, lab0[3], lab1[3], up[3];
    lm_error ignore;
    if (mesh_qmesh_interpolate(c->direct, st->tri, st->w1, st->w2, ldd, &ignore) != LM_OK) ldd[0] = ldd[1] = ldd[2] = 0;
    float level = 0.0f;
    for (int k = 0; k < 3; ++k) level = fmaxf(level, fmaxf(ei[k], 0.0f) + (float)M_PI * ldd[k]);
    float h = fmaxf(0.01f * level / (float)M_PI, 1e-6f);
    float e0[3];
    for (int k = 0; k < 3; ++k) {
        e0[k] = fmaxf(ei[k], 0.0f);
        up[k] = e0[k] + (float)M_PI * h;
    }
    cache_seen_lab(c, st->tri, ldd, e0, NULL, lab0);
    cache_seen_lab(c, st->tri, ldd, up, NULL, lab1);
    return tm_delta_e(lab0, lab1) / h;
}

lm_result cache_record_importance(cache *c, const cache_site *sites, uint32_t n, const uint32_t *pixels,
                                  const uint32_t **grown, uint32_t *grown_n, lm_error *err)
{
    cache_source_state *st = &c->src;
    *grown_n = 0;
    *grown = st->grown;
    if (!pixels || n == 0 || !st->rmesh.first) return LM_OK;
    /* The hits are the pilot of the gather just made at these sites (gather_displayed). */
    if (st->pilot_n != n) return LM_OK;
    for (uint32_t i = 0; i < n; ++i)
        if (st->pilot_vid[i] != sites[i].vid) return LM_OK;
    lm_result r = grow_importance(st, mesh_qmesh_node_limit(c->direct), err);
    for (uint32_t j = 0; r == LM_OK && j < n; ++j) {
        const cache_site *site = &sites[j];
        float ei[3];
        if (pixels[site->tri] == 0 || mesh_qmesh_get_value(c->indirect, site->vid, ei) != 1) continue;
        float g = site_sensitivity(c, site, ei);
        float px = ldexpf((float)pixels[site->tri], -2 * ((int)site->depth + 1));
        if (!(g > 0.0f) || !isfinite(g)) continue;
        for (uint32_t h = 0; r == LM_OK && h < st->pilot_count[j]; ++h) {
            size_t at = (size_t)j * CACHE_IMPORTANCE_RAYS + h;
            uint32_t node = st->leaf_buf[st->pilot_tri[at]].leaf;
            float w = st->pilot_weight[at] * g, before = st->imp_max[node];
            st->imp_sum[node] += px * w;
            for (uint32_t a = node; a != MESH_QMESH_NONE; a = mesh_qmesh_node(c->direct, a)->parent)
                st->imp_sub[a] += px * w;
            if (!(w > before)) continue;
            st->imp_max[node] = w;
            st->imp_any = 1;
            if (w < 1.5f * before) continue;
            if (*grown_n == st->grown_cap && !LM_GROW(st->grown, st->grown_cap, (size_t)*grown_n + 1))
                r = lm_fail(err, LM_ERR_NO_MEMORY, "out of memory tracing importance");
            else
                st->grown[(*grown_n)++] = node;
        }
    }
    *grown = st->grown;
    return r;
}
