/* cache_queue.c — the refinement's queues (paper §4.3.3): which leaf of a
 * radiance mesh is tested next.
 *
 * Per mesh, a max-heap of leaves by priority (pixels × (1 + the largest ΔE
 * between the corners' colours); an unseen source leaf's by its importance,
 * cache_unseen.c), or for the randomized scheduler (cache_desc.scheduler) the
 * paper's node priorities, each the maximum of its children's; per node the
 * "done" flag of a leaf whose test found nothing, and the interpolation error
 * its test (or its parent's) left, which the error estimate reads
 * (cache_estimate.c). Scheduling every leaf afresh (at the start, after a light
 * or camera change) and the part's life (cache_sched_init / free / bytes).
 *
 * What it does NOT do: test leaves, sample, or decide a split (cache_refine.c,
 * the rounds and the edge test, calls it; so do cache_requeue.c and
 * cache_unseen.c for leaves to test again).
 *
 * Threads: the refinement worker's, like the rest of the cache.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "mesh/cache/cache_internal.h"
#include "src/base/parallel.h"

/* ---- heap -------------------------------------------------------------------- */

lm_result cache_queue_push(cache_queue *q, float priority, uint32_t node, uint32_t v0, lm_error *err)
{
    if (q->n == q->cap && !LM_GROW(q->e, q->cap, q->n + 1))
        return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory growing the refinement queue");
    size_t i = q->n++;
    while (i > 0) {
        size_t p = (i - 1) / 2;
        if (q->e[p].priority >= priority) break;
        q->e[i] = q->e[p];
        i = p;
    }
    q->e[i] = (cache_queue_entry){priority, node, v0};
    return LM_OK;
}

cache_queue_entry cache_queue_pop(cache_queue *q)
{
    cache_queue_entry top = q->e[0], last = q->e[--q->n];
    size_t i = 0;
    for (;;) {
        size_t l = 2 * i + 1, r = l + 1, m = i;
        float pm = last.priority;
        if (l < q->n && q->e[l].priority > pm) {
            m = l;
            pm = q->e[l].priority;
        }
        if (r < q->n && q->e[r].priority > pm) m = r;
        if (m == i) break;
        q->e[i] = q->e[m];
        i = m;
    }
    if (q->n) q->e[i] = last;
    return top;
}

/* ---- per-node "done" flags ------------------------------------------------------ */

static lm_result set_done(uint8_t **flags, size_t *cap, uint32_t node, uint8_t v, lm_error *err)
{
    if (node >= *cap && !LM_GROW(*flags, *cap, (size_t)node + 1))
        return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory for refinement flags");
    (*flags)[node] = v;
    return LM_OK;
}

/* ---- colours ----------------------------------------------------------------- */

float cache_leaf_pixels(const uint32_t *pixels, const mesh_qnode *n)
{
    float p = pixels ? (float)pixels[n->tri] : 1e6f;
    return ldexpf(p, -2 * (int)n->depth);
}

/* A leaf no test may split: one no larger than a sample of the picture, or a
 * root smaller than a pixel, or an indirect leaf smaller than a pixel. Below a
 * pixel only a split whose test found something goes on (a highlight's rim, a
 * strip of light through a gap); a scene triangle smaller than a pixel is the
 * geometry's detail, not the light's. Indirect light has no feature finer than
 * a pixel that a gather's noise would not hide: on the 116k-triangle box its
 * leaves below a pixel took 36,000 gathers to 55,000 and the time to converge
 * from 11.6 to 15.8 s, with no gain on the Cornell boxes (docs/cache.md,
 * "Leaves smaller than a pixel"). */
int cache_leaf_below_sample(const cache *c, cache_kind kind, double px, const mesh_qnode *n)
{
    if (px <= (double)c->desc.sample_pixels) return 1;
    return px <= 1.0 && (n->depth == 0 || kind == CACHE_KIND_INDIRECT);
}

static int below_sample(const cache *c, cache_kind kind, const uint32_t *pixels, const mesh_qnode *n)
{
    return cache_leaf_below_sample(c, kind, cache_leaf_pixels(pixels, n), n);
}

/* Priority of a leaf: its pixels × (1 + the largest ΔE between its corners);
 * an unseen source leaf's, cache_unseen_priority. */
float cache_leaf_priority(const cache *c, const mesh_qmesh *m, cache_kind kind, uint32_t node, const mesh_qnode *n,
                          const uint32_t *pixels)
{
    if (cache_unseen_leaf(pixels, kind, n)) return cache_unseen_priority(c, node, n);
    return cache_leaf_pixels(pixels, n) * (1.0f + cache_leaf_contrast(c, m, kind, n));
}

/* ---- scheduling ---------------------------------------------------------------- */

lm_result cache_sched_grow_prio(cache *c, int kind, uint32_t node, lm_error *err)
{
    cache_sched *st = &c->sched;
    if (node < st->prio_cap[kind] || LM_GROW(st->prio[kind], st->prio_cap[kind], (size_t)node + 1)) return LM_OK;
    return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory for node priorities");
}

/* Sets a leaf's own priority (> 0 waiting, 0 done, < 0 being tested) and carries
 * the change up: an inner node's priority is the maximum of its four children's
 * (§4.3.3). Keeps the count of waiting leaves. */
static lm_result set_leaf_priority(cache *c, cache_kind kind, uint32_t node, float p, lm_error *err)
{
    const mesh_qmesh *m = cache_kind_mesh(c, kind);
    lm_result r = cache_sched_grow_prio(c, kind, node, err);
    if (r != LM_OK) return r;
    float *prio = c->sched.prio[kind];
    if (prio[node] > 0.0f) c->sched.waiting[kind]--;
    if (p > 0.0f) c->sched.waiting[kind]++;
    prio[node] = p;
    for (uint32_t up = mesh_qmesh_node(m, node)->parent; up != MESH_QMESH_NONE; up = mesh_qmesh_node(m, up)->parent) {
        uint32_t ch = mesh_qmesh_node(m, up)->child;
        float mx = prio[ch];
        for (uint32_t k = 1; k < 4; ++k) mx = fmaxf(mx, prio[ch + k]);
        if (prio[up] == mx) break;
        prio[up] = mx;
    }
    return LM_OK;
}

/* A new, or newly rescheduled, leaf with priority p (0: nothing to do there). */
lm_result cache_sched_add(cache *c, cache_kind kind, uint32_t node, float p, lm_error *err)
{
    lm_result r = set_done(&c->sched.done[kind], &c->sched.done_cap[kind], node, p > 0.0f ? 0 : 1, err);
    if (r != LM_OK) return r;
    if (c->desc.scheduler == CACHE_SCHED_RANDOM) return set_leaf_priority(c, kind, node, p, err);
    if (!(p > 0.0f)) return LM_OK;
    c->sched.waiting[kind]++;
    return cache_queue_push(&c->sched.q[kind], p, node, mesh_qmesh_node(cache_kind_mesh(c, kind), node)->v[0], err);
}

/* Records a leaf's interpolation error (ΔE; cache_sched.resid): from its own
 * test (tested) or its parent's. */
lm_result cache_sched_set_residual(cache *c, cache_kind kind, uint32_t node, float delta_e, int tested, lm_error *err)
{
    cache_sched *st = &c->sched;
    if (node >= st->resid_cap[kind] && !LM_GROW(st->resid[kind], st->resid_cap[kind], (size_t)node + 1))
        return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory for refinement residuals");
    st->resid[kind][node] = (tested ? 1.0f : -1.0f) * (1.0f + fmaxf(delta_e, 0.0f));
    return LM_OK;
}

void cache_sched_forget(cache_sched *st, cache_kind kind)
{
    if (st->resid[kind]) memset(st->resid[kind], 0, st->resid_cap[kind] * sizeof *st->resid[kind]);
}

/* A leaf whose test found nothing (its split undone). */
lm_result cache_sched_done(cache *c, cache_kind kind, uint32_t node, lm_error *err)
{
    lm_result r = set_done(&c->sched.done[kind], &c->sched.done_cap[kind], node, 1, err);
    if (r == LM_OK && c->desc.scheduler == CACHE_SCHED_RANDOM) r = set_leaf_priority(c, kind, node, 0.0f, err);
    return r;
}


/* The next leaf to test and the priority it was picked at; 0 when none is waiting. */
int cache_sched_pick(cache *c, cache_kind kind, const uint32_t *pixels, uint32_t *out, float *picked)
{
    const mesh_qmesh *m = cache_kind_mesh(c, kind);
    if (c->desc.scheduler != CACHE_SCHED_RANDOM) {
        cache_queue *q = &c->sched.q[kind];
        while (q->n) {
            cache_queue_entry e = cache_queue_pop(q);
            c->sched.waiting[kind]--;
            const mesh_qnode *n = mesh_qmesh_node(m, e.node);
            if (!n || n->child != MESH_QMESH_NONE || n->v[0] != e.v0) continue;
            if (e.node < c->sched.done_cap[kind] && c->sched.done[kind][e.node]) continue;
            /* A leaf of one sample never splits (an unseen source leaf: by its importance). */
            if (!cache_unseen_leaf(pixels, kind, n) && below_sample(c, kind, pixels, n)) continue;
            /* Before the first image, a leaf that a surface parts (a floor running
             * on under a wall into the next room) is set aside: split then, on
             * values gathered before the regathers, the Veach door's floor kept a
             * band of the lamp room's light along its back wall until 4 s and
             * more (docs/renderer.md, "The ceiling lit in the first image"). */
            if (c->sched.first_image_round && kind == CACHE_KIND_INDIRECT && cache_corners_parted(c, n)) {
                lm_error ignore;
                if (cache_queue_push(&c->sched.set_aside, e.priority, e.node, e.v0, &ignore) != LM_OK) return 0;
                continue;
            }
            if (e.priority < c->sched.pick_floor) { /* the rest is below it too: left queued */
                lm_error ignore;
                if (cache_queue_push(q, e.priority, e.node, e.v0, &ignore) == LM_OK) c->sched.waiting[kind]++;
                return 0;
            }
            *out = e.node;
            *picked = e.priority;
            return 1;
        }
        c->sched.waiting[kind] = 0;
        return 0;
    }
    /* Random (§4.3.3): keep to the current root while its priority beats a
     * random pick; descend to its highest-priority leaf. */
    const float *prio = c->sched.prio[kind];
    uint32_t nroots = c->sched.root_count[kind];
    lm_error ignore;
    while (c->sched.waiting[kind] > 0 && nroots > 0) {
        uint32_t cur = c->sched.cur_root[kind];
        uint32_t pick = c->sched.roots[kind][(uint32_t)(lm_rng_float(&c->sched.rng) * (float)nroots) % nroots];
        if (cur == MESH_QMESH_NONE || prio[pick] > prio[cur]) cur = pick;
        if (!(prio[cur] > 0.0f)) { /* a finished root: find one still waiting */
            cur = MESH_QMESH_NONE;
            for (uint32_t i = 0; i < nroots && cur == MESH_QMESH_NONE; ++i)
                if (prio[c->sched.roots[kind][i]] > 0.0f) cur = c->sched.roots[kind][i];
            if (cur == MESH_QMESH_NONE) {
                c->sched.waiting[kind] = 0;
                return 0;
            }
        }
        c->sched.cur_root[kind] = cur;
        uint32_t node = cur;
        for (const mesh_qnode *n = mesh_qmesh_node(m, node); n->child != MESH_QMESH_NONE;
             n = mesh_qmesh_node(m, node)) {
            uint32_t best = n->child;
            for (uint32_t k = 1; k < 4; ++k)
                if (prio[n->child + k] > prio[best]) best = n->child + k;
            node = best;
        }
        const mesh_qnode *leaf = mesh_qmesh_node(m, node);
        *picked = prio[node];
        if (set_leaf_priority(c, kind, node, -1.0f, &ignore) != LM_OK) return 0; /* being tested */
        if (below_sample(c, kind, pixels, leaf)) continue;
        *out = node;
        return 1;
    }
    return 0;
}

float cache_node_priority(const cache *c, int mesh, uint32_t node)
{
    if (mesh < 0 || mesh >= CACHE_KINDS || node >= c->sched.prio_cap[mesh]) return 0.0f;
    return c->sched.prio[mesh][node];
}


/* The priorities of a mesh's leaves to schedule, made over every core: a
 * leaf's priority reads the cache and writes nothing (the 116k-triangle box's
 * queues after the first image: 350,000 leaves, 0.1-0.17 s on the worker's
 * thread alone). Not to schedule: -1. */
typedef struct leaf_priority_job {
    const cache *c;
    const mesh_qmesh *m;
    cache_kind kind;
    const uint32_t *pixels;
    int seen_only;
    float *p; /* per node id */
} leaf_priority_job;

static void leaf_priority_one(void *user, uint32_t leaf)
{
    const leaf_priority_job *job = user;
    const mesh_qnode *n = mesh_qmesh_node(job->m, leaf);
    job->p[leaf] = -1.0f;
    if (!n || n->child != MESH_QMESH_NONE) return;
    if (!cache_tri_active(job->c, n->tri)) return; /* not taking part: nothing to test yet */
    if (job->seen_only && job->pixels && !job->pixels[n->tri]) return; /* the next call schedules it */
    /* 0: unseen, and nothing gathers from it. */
    job->p[leaf] = cache_leaf_priority(job->c, job->m, job->kind, leaf, n, job->pixels);
}

/* Schedules every leaf of one mesh afresh (at the start; after a light changed;
 * for the specular mesh after the camera moved): heap, done flags and priorities
 * are rebuilt. */
lm_result cache_sched_schedule(cache *c, cache_kind kind, const uint32_t *pixels, int seen_only, lm_error *err)
{
    mesh_qmesh *m = cache_kind_mesh(c, kind);
    c->sched.q[kind].n = 0;
    if (c->sched.done[kind]) memset(c->sched.done[kind], 0, c->sched.done_cap[kind]);
    if (c->sched.prio[kind]) memset(c->sched.prio[kind], 0, c->sched.prio_cap[kind] * sizeof *c->sched.prio[kind]);
    c->sched.waiting[kind] = 0;
    c->sched.root_count[kind] = 0;
    c->sched.cur_root[kind] = MESH_QMESH_NONE;
    c->sched.requeue[kind] = 0;
    /* A new queue: its yield is measured afresh. Kept across, a mesh whose last
     * rounds found nothing (the viewer's direct mesh converged: 1.5e-15) waited
     * after a move or a light edit until every other mesh was done. */
    c->sched.removed[kind] = c->sched.predicted[kind] = 0.0;
    if (!m || (kind == CACHE_KIND_INDIRECT && c->desc.single_mesh)) return LM_OK; /* single mesh: it follows direct */
    free(c->sched.roots[kind]);
    c->sched.roots[kind] = malloc((c->s->tri_count ? c->s->tri_count : 1) * sizeof *c->sched.roots[kind]);
    if (!c->sched.roots[kind]) return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory scheduling refinement");
    for (uint32_t t = 0; t < c->s->tri_count; ++t) {
        uint32_t root = mesh_qmesh_root(m, t);
        if (root != MESH_QMESH_NONE && (!pixels || pixels[t] > 0) && cache_tri_active(c, t))
            c->sched.roots[kind][c->sched.root_count[kind]++] = root;
    }
    /* Every live leaf, in node order (as mesh_qmesh_leaf_triangles visits them,
     * without making their triangles: 0.11 s of the 116k box's start). */
    const uint32_t limit = mesh_qmesh_node_limit(m);
    float *p = malloc((size_t)(limit ? limit : 1) * sizeof *p);
    if (!p) return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory scheduling refinement");
    leaf_priority_job job = {c, m, kind, pixels, seen_only, p};
    lm_parallel_for(lm_thread_count(0), limit, leaf_priority_one, &job);
    lm_result r = LM_OK;
    for (uint32_t leaf = 0; r == LM_OK && leaf < limit; ++leaf)
        if (!(p[leaf] < 0.0f)) r = cache_sched_add(c, kind, leaf, p[leaf], err);
    free(p);
    if (seen_only && pixels) c->sched.requeue[kind] = 1; /* the whole queue next time */
    return r;
}

/* The highest priority waiting in a mesh's heap (entries of leaves split or
 * done since are skipped when popped, so it may be one of those: a guess). */
float cache_sched_top_priority(const cache *c, int kind)
{
    const cache_queue *q = &c->sched.q[kind];
    return q->n ? q->e[0].priority : 0.0f;
}


/* ---- the part's life --------------------------------------------------------- */

void cache_sched_init(cache_sched *st, uint32_t seed)
{
    memset(st, 0, sizeof *st);
    lm_rng_seed(&st->rng, seed, 0x5c4ed, 0);
    for (int k = 0; k < CACHE_KINDS; ++k) st->cur_root[k] = MESH_QMESH_NONE;
}

void cache_sched_free(cache_sched *st)
{
    for (int k = 0; k < CACHE_KINDS; ++k) {
        free(st->q[k].e);
        free(st->done[k]);
        free(st->prio[k]);
        free(st->roots[k]);
        free(st->resid[k]);
    }
    free(st->set_aside.e);
    free(st->dark_gen);
    free(st->vt_first);
    free(st->vt_tris);
    free(st->tri_stamp);
    memset(st, 0, sizeof *st);
}

size_t cache_sched_bytes(const cache_sched *st)
{
    size_t b = 0;
    for (int k = 0; k < CACHE_KINDS; ++k)
        b += st->q[k].cap * sizeof(cache_queue_entry) + st->done_cap[k] +
             (st->prio_cap[k] + st->resid_cap[k]) * sizeof(float);
    return b + st->dark_gen_cap;
}

void cache_sched_requeue(cache_sched *st, int kind)
{
    for (int k = 0; k < CACHE_KINDS; ++k)
        if (kind == CACHE_KINDS || kind == k) st->requeue[k] = 1;
}
