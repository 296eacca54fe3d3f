/* cache_first.c — the first image from a fixed budget (issue 16; docs/cache.md,
 * "Start-up bounded by what is seen"): of the root corners that need a value
 * before the first image, only a budget are sampled — gathers (cache_desc.
 * coarse_gathers) and light samples (cache_desc.coarse_lights) — chosen along a
 * Morton order by their share of the pixels and of the area; every other corner
 * borrows from the chosen ones beside it in that order. After the first image,
 * cache_regather_indirect flags the gathered indirect values (cache_source.c
 * gathers them again), has the borrowed ones tested (cache_borrow.c: kept where a
 * gather at the middle of their run agrees with them) and releases the borrowed
 * direct and specular roots (cache_light.c, cache_release_borrowed, recomputes them from
 * light samples taken then), a bounded number per cache_refine call.
 *
 * What is borrowed: indirect irradiance (gathers), and per light the visible
 * fraction V (light samples), from which a corner's direct and specular values
 * are made with its own unoccluded G (cache_light.c): the falloff and the
 * cosines are the corner's own, only the shadow is a neighbour's.
 *
 * Also cache_root_values, the direct and specular values at root corners from
 * the light meshes, which the coarse cache uses for every corner it samples.
 *
 * Called by cache.c's coarse cache, on the worker thread like the rest. */
#include "mesh/cache/cache_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "src/base/parallel.h"
#include "src/base/vecmath.h"

/* A point's key along a Morton (Z-order) curve through the box lo + [0, span]³:
 * points close along the curve are close in space. */
static uint64_t morton_key(const float p[3], const float lo[3], double span)
{
    uint32_t q[3];
    for (int k = 0; k < 3; ++k) {
        double u = span > 0.0 ? ((double)p[k] - lo[k]) / span : 0.0;
        u = u < 0.0 ? 0.0 : u > 1.0 ? 1.0 : u;
        q[k] = (uint32_t)(u * 2097151.0); /* 21 bits an axis */
    }
    return cache_morton_key(q);
}

typedef struct keyed_vertex {
    uint64_t key;
    uint32_t index; /* into the caller's arrays */
} keyed_vertex;

/* kv[0..n) sorted by key, equal keys by index: a stable radix sort of 8-bit
 * digits, the input in index order (qsort took ~10 ms of the 116k-triangle
 * box's first image for its 59,000 corners, twice). 0 when out of memory. */
static int sort_keyed(keyed_vertex *kv, uint32_t n)
{
    if (n < 2) return 1;
    keyed_vertex *tmp = malloc((size_t)n * sizeof *tmp);
    if (!tmp) return 0;
    keyed_vertex *from = kv, *to = tmp;
    for (int shift = 0; shift < 64; shift += 8) {
        size_t count[257] = {0};
        for (uint32_t i = 0; i < n; ++i) count[(from[i].key >> shift & 0xffu) + 1]++;
        if (count[(from[0].key >> shift & 0xffu) + 1] == n) continue; /* one digit: already in order */
        for (int d = 0; d < 256; ++d) count[d + 1] += count[d];
        for (uint32_t i = 0; i < n; ++i) to[count[from[i].key >> shift & 0xffu]++] = from[i];
        keyed_vertex *t = from;
        from = to;
        to = t;
    }
    if (from != kv) memcpy(kv, from, (size_t)n * sizeof *kv);
    free(tmp);
    return 1;
}

/* Corners v[0..n) in Morton order, with their weights (corner_weights): made
 * for the light's pick and kept for the gathers' (cache_first_gathers), whose
 * corners are the same (the indirect mesh's roots are the direct mesh's:
 * cache_create); the light's pick and the gathers' differ only in their
 * budgets. Made twice, the order was ~0.1 s of a million-triangle scene's
 * first image, in fresh memory (docs/cache.md, "The first image's fresh
 * memory"). */
typedef struct cache_first_order {
    uint32_t n;
    uint32_t *v;        /* n: the corners it was made for (a copy) */
    keyed_vertex *kv;   /* n: in Morton order (index into v) */
    double *w;          /* n: weights by index into v */
    double total;       /* their sum */
    double span;        /* the corners' bounding box's largest side */
} cache_first_order;

void cache_first_order_free(cache *c)
{
    cache_first_order *o = c->first_order;
    if (!o) return;
    free(o->v);
    free(o->kv);
    free(o->w);
    free(o);
    c->first_order = NULL;
}

/* The corners v[0..n) in Morton order and the chosen ones among them. */
typedef struct first_pick {
    const keyed_vertex *kv; /* n: the corners in Morton order (index into v): c->first_order's */
    uint32_t *before;   /* n: per order position, how many chosen ones come before it */
    uint32_t *chosen;   /* nchosen: their vertex ids, in order */
    uint32_t *at;       /* nchosen: their order positions */
    uint32_t nchosen;
    double span;        /* the corners' bounding box's largest side */
} first_pick;

static void pick_free(first_pick *pk)
{
    free(pk->before);
    free(pk->chosen);
    free(pk->at);
    memset(pk, 0, sizeof *pk);
}

/* Each corner's weight: the share of the pixels (c->first_pixels, as guessed
 * for the first image; none: 0) and the share of the area of the active
 * triangles of mesh m around it, half and half. The pixels put the samples where
 * the image is; the area keeps some on what the guess got wrong (it knows no
 * occlusion) and on large triangles, whose corners are few but carry whole
 * walls. */
static lm_result corner_weights(const cache *c, const mesh_qmesh *m, const uint32_t *v, uint32_t n, double *w,
                                lm_error *err)
{
    const scene *s = c->s;
    const uint32_t limit = mesh_vtable_id_limit(c->vt);
    uint32_t *slot = calloc(limit ? limit : 1, sizeof *slot); /* vid -> index in v, plus one */
    double *pix = calloc(n ? n : 1, sizeof *pix);
    if (!slot || !pix) {
        free(slot);
        free(pix);
        return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory for the first image's budget");
    }
    for (uint32_t i = 0; i < n; ++i) slot[v[i]] = i + 1;
    for (uint32_t i = 0; i < n; ++i) w[i] = 0.0;
    double pix_total = 0.0, area_total = 0.0;
    for (uint32_t t = 0; t < s->tri_count; ++t) {
        uint32_t root = cache_tri_active(c, t) ? mesh_qmesh_root(m, t) : MESH_QMESH_NONE;
        if (root == MESH_QMESH_NONE) continue;
        const mesh_qnode *nd = mesh_qmesh_node(m, root);
        const double a = s->tri_areas[t], p = c->first_pixels ? c->first_pixels[t] : 0.0;
        for (int k = 0; k < 3; ++k) {
            uint32_t i = nd->v[k] < limit ? slot[nd->v[k]] : 0;
            if (!i) continue;
            w[i - 1] += a;
            pix[i - 1] += p;
        }
        area_total += 3.0 * a;
        pix_total += 3.0 * p;
    }
    for (uint32_t i = 0; i < n; ++i)
        w[i] = (area_total > 0.0 ? w[i] / area_total : 0.0) + (pix_total > 0.0 ? pix[i] / pix_total : 0.0);
    free(pix);
    free(slot);
    return LM_OK;
}

/* c->first_order for the corners v[0..n) of mesh m: the one kept if it was
 * made for the same corners, else made (and kept). Kept, its weights are those
 * of the mesh it was made for: the light's pick is made over the direct mesh
 * and the gathers' over the indirect one, whose roots are the same (both
 * cache_has_albedo, the indirect's copied from the direct's: cache_create). */
static lm_result corner_order(cache *c, const mesh_qmesh *m, const uint32_t *v, uint32_t n, lm_error *err)
{
    const cache_first_order *have = c->first_order;
    if (have && have->n == n && memcmp(have->v, v, (size_t)n * sizeof *v) == 0) return LM_OK;
    cache_first_order_free(c);
    cache_first_order *o = calloc(1, sizeof *o);
    if (o) {
        o->n = n;
        o->v = malloc((size_t)(n ? n : 1) * sizeof *o->v);
        o->kv = malloc((size_t)(n ? n : 1) * sizeof *o->kv);
        o->w = malloc((size_t)(n ? n : 1) * sizeof *o->w);
        c->first_order = o;
    }
    lm_result r = o && o->v && o->kv && o->w ? corner_weights(c, m, v, n, o->w, err)
                                             : lm_fail(err, LM_ERR_NO_MEMORY, "out of memory for the first image's budget");
    if (r != LM_OK) {
        cache_first_order_free(c);
        return r;
    }
    memcpy(o->v, v, (size_t)n * sizeof *v);
    float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    double total = 0.0;
    for (uint32_t i = 0; i < n; ++i) {
        const float *p = mesh_vtable_vertex(c->vt, v[i])->position;
        for (int k = 0; k < 3; ++k) lo[k] = fminf(lo[k], p[k]), hi[k] = fmaxf(hi[k], p[k]);
        total += o->w[i];
    }
    if (!(total > 0.0)) { /* nothing weighs: evenly spaced corners */
        for (uint32_t i = 0; i < n; ++i) o->w[i] = 1.0;
        total = n;
    }
    o->total = total;
    o->span = fmax(hi[0] - lo[0], fmax(hi[1] - lo[1], hi[2] - lo[2]));
    for (uint32_t i = 0; i < n; ++i)
        o->kv[i] = (keyed_vertex){morton_key(mesh_vtable_vertex(c->vt, v[i])->position, lo, o->span), i};
    if (!sort_keyed(o->kv, n)) {
        cache_first_order_free(c);
        return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory for the first image's budget");
    }
    return LM_OK;
}

/* At most `budget` of the corners v[0..n) of mesh m, chosen by systematic
 * sampling of their weights along a Morton order of their positions: the
 * corners in whose stretch of the cumulative weight one of `budget` evenly
 * spaced marks falls. A corner with a budget's share of the weight or more is
 * always chosen; a bunny's thousands of tiny corners share theirs. */
static lm_result pick_corners(cache *c, const mesh_qmesh *m, const uint32_t *v, uint32_t n, uint32_t budget,
                              first_pick *pk, lm_error *err)
{
    memset(pk, 0, sizeof *pk);
    lm_result r = corner_order(c, m, v, n, err);
    if (r != LM_OK) return r;
    const cache_first_order *o = c->first_order;
    pk->kv = o->kv;
    pk->span = o->span;
    pk->before = malloc((size_t)n * sizeof *pk->before);
    pk->chosen = malloc((size_t)budget * sizeof *pk->chosen);
    pk->at = malloc((size_t)budget * sizeof *pk->at);
    if (!pk->before || !pk->chosen || !pk->at) {
        pick_free(pk);
        return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory for the first image's budget");
    }
    const double *w = o->w;
    double total = o->total;
    /* Corners heavier than a mark's spacing are chosen outright, and the rest of
     * the budget spread over the rest, until none is (else a few wall corners
     * would swallow most marks and the budget go unspent). */
    uint8_t *sure = calloc(n, 1);
    if (!sure) {
        pick_free(pk);
        return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory for the first image's budget");
    }
    uint32_t left = budget;
    for (int more = 1; more && left > 0;) {
        more = 0;
        const double step = total / left;
        for (uint32_t i = 0; i < n && left > 0; ++i)
            if (!sure[i] && w[i] >= step) sure[i] = 1, total -= w[i], left--, more = 1;
    }
    const double step = left ? total / left : INFINITY;
    double acc = 0.0, mark = 0.5 * step;
    for (uint32_t i = 0; i < n; ++i) {
        const uint32_t k = pk->kv[i].index;
        pk->before[i] = pk->nchosen;
        int take = sure[k];
        if (!take) {
            acc += w[k];
            if (acc > mark && left > 0) {
                take = 1;
                left--;
                while (mark < acc) mark += step;
            }
        }
        if (take) {
            pk->at[pk->nchosen] = i;
            pk->chosen[pk->nchosen++] = v[k];
        }
    }
    free(sure);
    return LM_OK;
}

/* The chosen corners beside order position i: two on either side (vertex ids
 * into d, their indices in pk->chosen into j0). Returns how many. */
static int donors_of(const first_pick *pk, uint32_t i, uint32_t d[4], uint32_t j0[4])
{
    int nd = 0;
    for (int64_t j = (int64_t)pk->before[i] - 2; j < (int64_t)pk->before[i] + 2; ++j) {
        if (j < 0 || j >= pk->nchosen) continue;
        j0[nd] = (uint32_t)j;
        d[nd++] = pk->chosen[j];
    }
    return nd;
}

/* The chosen corners a corner at order position i borrows from, and their
 * weights (cache_borrow_weights). q: indices into pk->chosen. Returns how many
 * (0 only with nothing chosen). */
static int borrow_from(const cache *c, const first_pick *pk, uint32_t vid, uint32_t i, uint32_t q[4], double w[4])
{
    uint32_t d[4], j0[4];
    int k[4];
    const int nd = donors_of(pk, i, d, j0);
    int n = cache_borrow_weights(c, vid, d, nd, pk->span, k, w);
    for (int b = 0; b < n; ++b) q[b] = j0[k[b]];
    return n;
}

/* Is order position i one of the chosen? */
static int chosen_at(const first_pick *pk, uint32_t i)
{
    return pk->before[i] < pk->nchosen && pk->at[pk->before[i]] == i;
}

/* The borrowed corners' values are made over every core, in chunks of order
 * positions: each reads the chosen corners' values and writes only its own
 * corners' entries (the 116k-triangle box: 59,000 corners, 30 ms of the first
 * image's light and 12 ms of its gathers on one core). */
enum { BORROW_CHUNK = 512 };

static uint32_t borrow_chunks(uint32_t n) { return (n + BORROW_CHUNK - 1) / BORROW_CHUNK; }

typedef struct gather_borrow_job {
    const cache *c;
    const first_pick *pk;
    const uint32_t *v;
    uint32_t n;
    float *E, *sg, *sl; /* E: the caller's, by index into v; sg, sl: 3 per order position */
    uint8_t *none;      /* per order position: no donor lies near enough (all 0) */
} gather_borrow_job;

static void gather_borrow_chunk(void *user, uint32_t chunk)
{
    gather_borrow_job *job = user;
    const first_pick *pk = job->pk;
    const uint32_t end = chunk + 1 < borrow_chunks(job->n) ? (chunk + 1) * BORROW_CHUNK : job->n;
    for (uint32_t i = chunk * BORROW_CHUNK; i < end; ++i) {
        if (chosen_at(pk, i)) continue;
        const uint32_t vid = job->v[pk->kv[i].index];
        float *out = job->E + 3 * (size_t)pk->kv[i].index, *sg = job->sg + 3 * (size_t)i, *sl = job->sl + 3 * (size_t)i;
        uint32_t d[4], j0[4];
        const int nd = donors_of(pk, i, d, j0);
        job->none[i] = !cache_borrow_mean(job->c, vid, d, nd, pk->span, out, sg, sl);
    }
}

lm_result cache_first_gathers(cache *c, const uint32_t *v, uint32_t n, float *E, lm_error *err)
{
    const uint32_t budget = c->desc.coarse_gathers;
    if (!budget || n <= budget) return cache_sample_indirect(c, v, n, E, err);
    first_pick pk;
    lm_result r = pick_corners(c, c->indirect, v, n, budget, &pk, err);
    if (r != LM_OK) return r;
    float *Er = malloc(3 * (size_t)(pk.nchosen ? pk.nchosen : 1) * sizeof *Er);
    uint32_t *order = malloc((size_t)n * sizeof *order);
    r = Er && order ? cache_sample_indirect(c, pk.chosen, pk.nchosen, Er, err)
                    : lm_fail(err, LM_ERR_NO_MEMORY, "out of memory for the first image's gathers");
    /* The gathered values in the mesh first: the others borrow from them there. */
    for (uint32_t j = 0; r == LM_OK && j < pk.nchosen; ++j)
        r = mesh_qmesh_set_value(c->indirect, pk.chosen[j], Er + 3 * (size_t)j, err);
    /* Borrowed, with the standard errors of the weighted mean (tested after the
     * first image: cache_borrow.c). */
    float *sgl = r == LM_OK ? malloc(6 * (size_t)n * sizeof *sgl) : NULL;
    uint8_t *none = r == LM_OK ? calloc(n, 1) : NULL;
    if (r == LM_OK && (!sgl || !none)) r = lm_fail(err, LM_ERR_NO_MEMORY, "out of memory for the first image's gathers");
    if (r == LM_OK) {
        gather_borrow_job job = {c, &pk, v, n, E, sgl, sgl + 3 * (size_t)n, none};
        lm_parallel_for(lm_thread_count(0), borrow_chunks(n), gather_borrow_chunk, &job);
    }
    for (uint32_t i = 0, j = 0; r == LM_OK && i < n; ++i) {
        const uint32_t vid = v[pk.kv[i].index];
        float *out = E + 3 * (size_t)pk.kv[i].index, *sg = sgl + 3 * (size_t)i, *sl = sgl + 3 * ((size_t)n + i);
        order[i] = vid;
        if (j < pk.nchosen && pk.at[j] == i) { /* gathered */
            memcpy(out, Er + 3 * (size_t)j++, 3 * sizeof *out);
            continue;
        }
        if (none[i]) out[0] = out[1] = out[2] = sg[0] = sg[1] = sg[2] = sl[0] = sl[1] = sl[2] = 0.0f;
        r = cache_set_borrowed(c, vid, out, sg, sl, INFINITY, err);
    }
    free(sgl);
    free(none);
    if (r == LM_OK) {
        r = cache_borrow_start(c, order, n, pk.at, pk.nchosen, pk.span, err);
        order = NULL; /* the cache's now */
    }
    free(order);
    free(Er);
    pick_free(&pk);
    cache_first_order_free(c); /* the last pick of the first image */
    return r;
}

/* The sites of root corners vids (their scene triangle, depth 0). */
static lm_result root_sites(const cache *c, const uint32_t *vids, uint32_t n, cache_site **out, lm_error *err)
{
    cache_site *s = malloc((n ? n : 1) * sizeof *s);
    if (!s) return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory for root values");
    for (uint32_t i = 0; i < n; ++i) {
        const mesh_vertex *mv = mesh_vtable_vertex(c->vt, vids[i]);
        double scale = ldexp(1.0, -(int)mv->bary.depth);
        s[i] = (cache_site){.vid = vids[i], .tri = mv->tri, .w1 = mv->bary.w[1] * scale, .w2 = mv->bary.w[2] * scale,
                            .depth = 0};
    }
    *out = s;
    return LM_OK;
}

lm_result cache_root_values(cache *c, cache_kind kind, const uint32_t *vids, uint32_t n, lm_error *err)
{
    mesh_qmesh *m = cache_kind_mesh(c, kind);
    uint32_t *need = malloc((n ? n : 1) * sizeof *need), nn = 0;
    if (!need) return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory for root values");
    for (uint32_t i = 0; i < n; ++i)
        if (mesh_qmesh_vertex_use(m, vids[i]) && mesh_qmesh_get_value(m, vids[i], NULL) != 1) need[nn++] = vids[i];
    cache_site *sites = NULL;
    float *rgb = malloc(3 * (size_t)(nn ? nn : 1) * sizeof *rgb);
    lm_result r = rgb ? root_sites(c, need, nn, &sites, err) : lm_fail(err, LM_ERR_NO_MEMORY, "out of memory for root values");
    if (r == LM_OK) r = cache_light_values(c, kind, sites, nn, rgb, err);
    for (uint32_t i = 0; r == LM_OK && i < nn; ++i) r = mesh_qmesh_set_value(m, need[i], rgb + 3 * (size_t)i, err);
    free(sites);
    free(rgb);
    free(need);
    return r;
}

typedef struct light_borrow_job {
    cache *c;
    const first_pick *pk;
    const uint32_t *v;
    uint32_t n;
    float *direct, *specular; /* 3 per order position */
    lm_result *chunk_result;  /* per chunk: LM_OK, or LM_ERR_NO_MEMORY */
} light_borrow_job;

/* A borrowed corner's V per light (its donors' visible fractions, weighted),
 * made into its direct and specular values with its own G (their per-vertex
 * entries reserved before: cache_direct_reserve, cache_specular_reserve). */
static void light_borrow_chunk(void *user, uint32_t chunk)
{
    light_borrow_job *job = user;
    cache *c = job->c;
    const first_pick *pk = job->pk;
    const uint32_t L = c->light_count;
    float *V = malloc((size_t)(L ? L : 1) * sizeof *V);
    lm_result r = V ? LM_OK : LM_ERR_NO_MEMORY;
    lm_error err;
    const uint32_t end = chunk + 1 < borrow_chunks(job->n) ? (chunk + 1) * BORROW_CHUNK : job->n;
    for (uint32_t i = chunk * BORROW_CHUNK; r == LM_OK && i < end; ++i) {
        if (chosen_at(pk, i)) continue;
        const uint32_t vid = job->v[pk->kv[i].index];
        uint32_t q[4];
        double w[4];
        int nb = borrow_from(c, pk, vid, i, q, w);
        for (uint32_t l = 0; l < L; ++l) {
            if (!c->light[l] || !mesh_qmesh_vertex_use(c->light[l], vid)) {
                V[l] = 0.0f; /* no triangle around it can see the light (cache_fetch_visibility: 0) */
                continue;
            }
            double sum = 0.0, wsum = 0.0;
            for (int b = 0; b < nb; ++b) {
                float vb;
                if (mesh_qmesh_get_value(c->light[l], pk->chosen[q[b]], &vb) != 1) continue;
                sum += w[b] * vb;
                wsum += w[b];
            }
            V[l] = wsum > 0.0 ? (float)(sum / wsum) : 1.0f; /* no neighbour sees it: unoccluded */
        }
        r = cache_direct_from_visibility(c, vid, V, job->direct + 3 * (size_t)i, &err);
        if (r == LM_OK && c->specular && mesh_qmesh_vertex_use(c->specular, vid))
            r = cache_specular_from_visibility(c, vid, V, job->specular + 3 * (size_t)i, &err);
    }
    free(V);
    job->chunk_result[chunk] = r;
}

lm_result cache_first_light(cache *c, const uint32_t *v, uint32_t n, int *done, lm_error *err)
{
    *done = 0;
    const uint32_t budget = c->desc.coarse_lights, L = c->light_count;
    if (!budget || n <= budget || !L) return LM_OK;
    first_pick pk;
    lm_result r = pick_corners(c, c->direct, v, n, budget, &pk, err);
    if (r != LM_OK) return r;
    /* Light samples at the chosen corners only (each light where its mesh has them). */
    uint32_t *need = malloc((pk.nchosen ? pk.nchosen : 1) * sizeof *need);
    if (!need) r = lm_fail(err, LM_ERR_NO_MEMORY, "out of memory for the first image's light");
    for (uint32_t l = 0; r == LM_OK && l < L; ++l) {
        if (!c->light[l]) continue;
        uint32_t nn = 0;
        for (uint32_t j = 0; j < pk.nchosen; ++j)
            if (mesh_qmesh_vertex_use(c->light[l], pk.chosen[j]) && mesh_qmesh_get_value(c->light[l], pk.chosen[j], NULL) != 1)
                need[nn++] = pk.chosen[j];
        r = cache_sample_light(c, l, need, nn, err);
    }
    free(need);
    /* Their direct and specular values as always. */
    if (r == LM_OK) r = cache_root_values(c, CACHE_KIND_DIRECT, pk.chosen, pk.nchosen, err);
    if (r == LM_OK && c->specular) r = cache_root_values(c, CACHE_KIND_SPECULAR, pk.chosen, pk.nchosen, err);
    /* The others: V borrowed per light, made into values with their own G,
     * over every core; then stored in order. */
    const uint32_t limit = mesh_vtable_id_limit(c->vt), chunks = borrow_chunks(n);
    uint8_t *borrowed = calloc((size_t)limit + 1, 1);
    float *rgb = malloc(6 * (size_t)(n ? n : 1) * sizeof *rgb);
    lm_result *chunk_result = malloc((size_t)(chunks ? chunks : 1) * sizeof *chunk_result);
    if (r == LM_OK && (!borrowed || !rgb || !chunk_result))
        r = lm_fail(err, LM_ERR_NO_MEMORY, "out of memory for the first image's light");
    if (r == LM_OK) r = cache_direct_reserve(c, limit, err);
    if (r == LM_OK && c->specular) r = cache_specular_reserve(c, limit, err);
    if (r == LM_OK) {
        light_borrow_job job = {c, &pk, v, n, rgb, rgb + 3 * (size_t)n, chunk_result};
        lm_parallel_for(lm_thread_count(0), chunks, light_borrow_chunk, &job);
        for (uint32_t k = 0; k < chunks && r == LM_OK; ++k)
            if (chunk_result[k] != LM_OK) r = lm_fail(err, chunk_result[k], "out of memory for the first image's light");
    }
    uint64_t nborrowed = 0;
    for (uint32_t i = 0; r == LM_OK && i < n; ++i) {
        if (chosen_at(&pk, i)) continue;
        const uint32_t vid = v[pk.kv[i].index];
        r = mesh_qmesh_set_value(c->direct, vid, rgb + 3 * (size_t)i, err);
        if (r == LM_OK && c->specular && mesh_qmesh_vertex_use(c->specular, vid)) {
            r = mesh_qmesh_set_value(c->specular, vid, rgb + 3 * ((size_t)n + i), err);
            if (r == LM_OK) r = cache_glossy_forget(c, vid, err); /* its glossy part comes with the sweep */
        }
        borrowed[vid] = 1;
        nborrowed++;
    }
    free(rgb);
    free(chunk_result);
    /* The roots with a borrowed corner are recomputed after the first image. */
    for (uint32_t t = 0; r == LM_OK && nborrowed && t < c->s->tri_count; ++t) {
        if (!cache_tri_active(c, t)) continue;
        int any = 0;
        for (int kind = CACHE_KIND_DIRECT; kind < CACHE_KINDS && !any; ++kind) {
            const mesh_qmesh *m = kind == CACHE_KIND_INDIRECT ? NULL : cache_kind_mesh(c, (cache_kind)kind);
            uint32_t root = m ? mesh_qmesh_root(m, t) : MESH_QMESH_NONE;
            if (root == MESH_QMESH_NONE) continue;
            const mesh_qnode *nd = mesh_qmesh_node(m, root);
            for (int k = 0; k < 3; ++k) any |= borrowed[nd->v[k]];
        }
        if (any) r = cache_borrowed_root(c, t, err);
    }
    free(borrowed);
    pick_free(&pk);
    if (r == LM_OK) *done = 1;
    return r;
}
