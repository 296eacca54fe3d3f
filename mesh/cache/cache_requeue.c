/* cache_requeue.c — values that changed under the refinement's feet, and the
 * leaves around them tested again: radiance values inside a light leaf that
 * answered as uniform and proved not to be (cache_light.c), indirect values a
 * rebuilt source moved (cache_source.c), glossy parts a rebuilt source or a new
 * eye left stale (cache_glossy.c), the first image's borrowed values
 * (cache_borrow.c), and indirect values gathered again with more rays where
 * their noise is seen (cache_regather_finer).
 *
 * Called by the scheduler's loop (cache_refine.c, cache_sched_refine) between
 * rounds, on the worker thread. What it does NOT do: decide what is outdated
 * (the modules above do) or test a leaf (cache_refine.c).
 */
#include <stdlib.h>
#include <string.h>

#include "mesh/cache/cache_internal.h"

typedef struct requeue_ctx {
    cache *c;
    cache_kind kind;
    const uint32_t *pixels;
    const uint32_t *vids; /* changed, sorted */
    uint32_t n;
} requeue_ctx;

static int cmp_u32(const void *a, const void *b)
{
    uint32_t x = *(const uint32_t *)a, y = *(const uint32_t *)b;
    return (x > y) - (x < y);
}

/* A leaf with a changed corner is tested again (also one found done before: what
 * it was compared with has changed). */
static lm_result requeue_visit(const mesh_qmesh *m, uint32_t node, const mesh_qnode *n, void *user, lm_error *err)
{
    requeue_ctx *q = user;
    if (n->child != MESH_QMESH_NONE) return LM_OK;
    int hit = 0;
    for (int k = 0; k < 3 && !hit; ++k) hit = bsearch(&n->v[k], q->vids, q->n, sizeof *q->vids, cmp_u32) != NULL;
    if (!hit || (q->pixels && q->pixels[n->tri] == 0 && !cache_unseen_leaf(q->pixels, q->kind, n))) return LM_OK;
    return cache_sched_add(q->c, q->kind, node, cache_leaf_priority(q->c, m, q->kind, node, n, q->pixels), err);
}

/* The triangles around each scene vertex (cache_sched.vt_first, vt_tris), and a
 * stamp per triangle; 0 when memory runs out (the caller walks every tree). */
static int around_ready(cache *c, lm_error *err)
{
    (void)err;
    cache_sched *st = &c->sched;
    if (st->vt_first) return 1;
    const scene *s = c->s;
    uint32_t *first = calloc((size_t)s->vertex_count + 1, sizeof *first);
    uint32_t *tris = malloc(3 * (size_t)(s->tri_count ? s->tri_count : 1) * sizeof *tris);
    uint32_t *fill = calloc((size_t)s->vertex_count + 1, sizeof *fill);
    uint32_t *stamp = calloc(s->tri_count ? s->tri_count : 1, sizeof *stamp);
    if (!first || !tris || !fill || !stamp) {
        free(first);
        free(tris);
        free(fill);
        free(stamp);
        return 0;
    }
    for (uint32_t t = 0; t < s->tri_count; ++t)
        for (int k = 0; k < 3; ++k) first[s->tris[t].v[k] + 1]++;
    for (uint32_t v = 0; v < s->vertex_count; ++v) first[v + 1] += first[v];
    for (uint32_t t = 0; t < s->tri_count; ++t)
        for (int k = 0; k < 3; ++k) {
            uint32_t v = s->tris[t].v[k];
            tris[first[v] + fill[v]++] = t;
        }
    free(fill);
    st->vt_first = first;
    st->vt_tris = tris;
    st->tri_stamp = stamp;
    st->stamp = 0;
    return 1;
}

/* regions NULL: anywhere in the mesh. The single-mesh ablation schedules the
 * combined (direct) mesh only. */
static lm_result requeue_changed(cache *c, cache_kind kind, const cache_region *regions, uint32_t region_count,
                                 const uint32_t *vids, uint32_t n, void *user, lm_error *err)
{
    if (kind == CACHE_KIND_INDIRECT && c->desc.single_mesh) kind = CACHE_KIND_DIRECT;
    requeue_ctx q = {c, kind, user, vids, n};
    const mesh_qmesh *m = cache_kind_mesh(c, kind);
    lm_result r = LM_OK;
    for (uint32_t i = 0; r == LM_OK && i < region_count; ++i) r = cache_region_walk(m, &regions[i], requeue_visit, &q, err);
    if (!regions && (uint64_t)n * 32 < c->s->tri_count && around_ready(c, err)) {
        /* Few changed: only the trees of the triangles around their triangles'
         * corners (a cache vertex lies inside its triangle, on one of its edges or
         * at one of its corners), not every tree of a big scene for each batch of
         * regathered values. */
        cache_sched *st = &c->sched;
        if (++st->stamp == 0) {
            memset(st->tri_stamp, 0, c->s->tri_count * sizeof *st->tri_stamp);
            st->stamp = 1;
        }
        for (uint32_t i = 0; r == LM_OK && i < n; ++i) {
            const uint32_t *corner = c->s->tris[mesh_vtable_vertex(c->vt, vids[i])->tri].v;
            for (int k = 0; r == LM_OK && k < 3; ++k)
                for (uint32_t j = st->vt_first[corner[k]]; r == LM_OK && j < st->vt_first[corner[k] + 1]; ++j) {
                    uint32_t t = st->vt_tris[j];
                    if (st->tri_stamp[t] == st->stamp) continue;
                    st->tri_stamp[t] = st->stamp;
                    if (mesh_qmesh_root(m, t) == MESH_QMESH_NONE || !cache_tri_active(c, t)) continue;
                    const cache_region whole = {.tri = t, .w1 = {0, 1, 0}, .w2 = {0, 0, 1}};
                    r = cache_region_walk(m, &whole, requeue_visit, &q, err);
                }
        }
        return r;
    }
    for (uint32_t t = 0; r == LM_OK && !regions && t < c->s->tri_count; ++t) {
        if (mesh_qmesh_root(m, t) == MESH_QMESH_NONE || !cache_tri_active(c, t)) continue;
        const cache_region whole = {.tri = t, .w1 = {0, 1, 0}, .w2 = {0, 0, 1}};
        r = cache_region_walk(m, &whole, requeue_visit, &q, err);
    }
    return r;
}

/* What changed under the refinement's feet: values inside falsified light leaves
 * (cache_light.c) and indirect values the source has moved (cache_source.c); their leaves are tested
 * again. */

lm_result cache_requeue_revise(cache *c, const uint32_t *pixels, uint64_t *allowance, uint64_t *glossy_allowance,
                               lm_error *err)
{
    lm_result r = cache_revise_falsified(c, requeue_changed, (void *)pixels, err);
    /* Indirect values wait while the first image's borrowed light is recomputed:
     * the source moves under them until it is (a million-triangle scene's first
     * rebuilds, bounded value by value, took 8 s each and flagged most values). */
    if (c->vis.borrowed_released && cache_borrowed_waiting(c)) return r;
    /* And the first image's, while the direct leaves move the source (cache_sched.owed_wait). */
    if (c->sched.owed_wait && c->sched.waiting[CACHE_KIND_DIRECT] + c->sched.waiting[CACHE_KIND_SPECULAR] > 0) return r;
    c->sched.owed_wait = 0;
    if (r == LM_OK) r = cache_regather_outdated(c, requeue_changed, (void *)pixels, allowance, err);
    /* Glossy parts a rebuilt source (or a new eye) left stale (cache_glossy.c). */
    if (r == LM_OK) r = cache_glossy_refresh(c, requeue_changed, (void *)pixels, glossy_allowance, err);
    /* The first image's borrowed values, tested once their donors are up to date. */
    if (r == LM_OK && !c->src.outdated_n) r = cache_borrow_test(c, pixels, requeue_changed, (void *)pixels, allowance, err);
    return r;
}

/* Plain gathers' worth of finer regathers a call takes per leaf of its budget:
 * the first level (4× the rays) goes as many values as leaves, as it did when
 * values were counted; deeper levels fewer (a worker's step of 512 leaves: 32
 * values at 64×, 2 million rays with Embree's 1,024, not 134 million at 256×). */
enum { FINER_COST_PER_LEAF = 4 };

/* The share of a leaf's noise ΔE that 4 times the rays at its corners are
 * credited with removing. Halved standard errors would remove half, but at 0.5
 * the regathers came before leaf tests that still mattered (the Veach door's 5 s
 * relMSE 0.018 twice against 0.004-0.005); 0.125 kept the early rows
 * (docs/cache.md, "Quieter values by their rate"). */
#define FINER_REMOVES 0.125

/* Gathers again with more rays (cache_regather_finer) the indirect values whose
 * noise keeps a visible leaf above the JND (cache_noisy_vertices), as many as
 * FINER_COST_PER_LEAF × `budget` plain gathers pay for, and queues their leaves
 * to be tested again: when the worst leaf's noise removed per ray (its pixels ×
 * noise ΔE × FINER_REMOVES, over its corners' rays at their next level and a
 * test of the leaf) is at least min_rate. */
lm_result cache_requeue_noisy(cache *c, const uint32_t *pixels, uint32_t budget, double min_rate, uint32_t *done,
                              lm_error *err)
{
    if (!c->indirect || c->desc.single_mesh) return LM_OK;
    uint32_t *vids, n;
    cache_noisy_top top;
    lm_result r = cache_noisy_vertices(c, pixels, (uint64_t)FINER_COST_PER_LEAF * budget, &vids, &n, &top, err);
    const double rays = (double)top.cost * samp_indirect_rays(c->sp) + c->sched.leaf_rays[CACHE_KIND_INDIRECT];
    const double rate = rays > 0.0 ? FINER_REMOVES * top.priority / rays : 0.0;
    if (r != LM_OK || n == 0 || rate < min_rate) {
        free(vids);
        return r;
    }
    float *E = malloc(3 * (size_t)n * sizeof *E);
    r = E ? cache_regather_finer(c, vids, n, E, err) : lm_fail(err, LM_ERR_NO_MEMORY, "out of memory refining");
    for (uint32_t i = 0; r == LM_OK && i < n; ++i) r = mesh_qmesh_set_value(c->indirect, vids[i], E + 3 * (size_t)i, err);
    /* (vids is sorted: requeue_changed looks them up.) */
    if (r == LM_OK) r = requeue_changed(c, CACHE_KIND_INDIRECT, NULL, 0, vids, n, (void *)pixels, err);
    if (r == LM_OK) *done += n;
    free(E);
    free(vids);
    return r;
}
