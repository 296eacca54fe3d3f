/* cache_unseen.c — the direct mesh as the indirect source where no pixel sees
 * it (the indirect issue; docs/cache.md, "Interiors lit through an opening"):
 * which of its leaves are unseen, what refining one is worth to the viewer
 * through the gathers (importance, Smits et al. 1992, recorded by
 * cache_source.c), in the units of a visible leaf's priority so that one heap
 * weighs both, and when a split of one is kept.
 *
 * Called by the scheduler (cache_refine.c, cache_requeue.c), on the worker
 * thread like the rest of the cache. What it does NOT do: pick leaves or test
 * them (cache_refine.c), or gather (cache_source.c).
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "mesh/cache/cache_internal.h"
#include "src/base/vecmath.h"

/* ---- priority ----------------------------------------------------------------------- */

/* A leaf of the direct mesh that no pixel sees: refined as the indirect source,
 * for what the visible gathers draw from it (importance), not for its pixels. */
int cache_unseen_leaf(const uint32_t *pixels, cache_kind kind, const mesh_qnode *n)
{
    return kind == CACHE_KIND_DIRECT && pixels && pixels[n->tri] == 0;
}

/* A source leaf's radiance kd·L_dd (any channel) at its corners, lowest and
 * highest, and its bound with every light unoccluded there (kd·Σ_ℓ
 * L_ℓ·G_ℓ,unocc/π): light through a gap may fall between corners that are all
 * in shadow, and only the bound says that it could. */
typedef struct source_levels {
    float lo, hi, bound;
} source_levels;

static source_levels source_levels_of(const cache *c, const mesh_qnode *n, int with_bound)
{
    const float *kd = c->s->materials[c->s->tris[n->tri].material].kd;
    source_levels s = {INFINITY, 0.0f, 0.0f};
    for (int k = 0; k < 3; ++k) {
        float v[3] = {0, 0, 0};
        mesh_qmesh_get_value(c->direct, n->v[k], v);
        for (int ch = 0; ch < 3; ++ch) {
            s.lo = fminf(s.lo, kd[ch] * v[ch]);
            s.hi = fmaxf(s.hi, kd[ch] * v[ch]);
        }
        for (uint32_t l = 0; with_bound && l < c->light_count; ++l) { /* analytic, and dear */
            double g = cache_unoccluded(c, l, n->v[k]) / M_PI;
            for (int ch = 0; ch < 3; ++ch)
                s.bound = fmaxf(s.bound, (float)(kd[ch] * c->light_le[3 * (size_t)l + (size_t)ch] * g));
        }
    }
    return s;
}

/* The largest source radiance a node could send: its corners', or its bound. */
static float source_peak(const cache *c, const mesh_qnode *n)
{
    source_levels s = source_levels_of(c, n, 1);
    return fmaxf(s.hi, s.bound);
}

uint32_t cache_unseen_dark_generations(const cache *c, uint32_t node)
{
    return node < c->sched.dark_gen_cap ? c->sched.dark_gen[node] : 0u;
}

lm_result cache_unseen_set_dark_generations(cache *c, uint32_t node, uint32_t gen, lm_error *err)
{
    cache_sched *st = &c->sched;
    if (node >= st->dark_gen_cap) {
        size_t old = st->dark_gen_cap;
        if (!LM_GROW(st->dark_gen, st->dark_gen_cap, (size_t)node + 1))
            return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory for the source's dark generations");
        memset(st->dark_gen + old, 0, st->dark_gen_cap - old);
    }
    st->dark_gen[node] = (uint8_t)(gen < 255u ? gen : 255u);
    return LM_OK;
}

/* Priority of an unseen source leaf: pixel·ΔE the viewer would see of its
 * error, the units of cache_leaf_priority: imp_sum × the radiance it may be off by.
 * Where a corner sends light, the light meshes have looked there, and the leaf
 * may be off by about its corners' spread (linear interpolation, as the
 * on-screen contrast). Where every corner is dark (V = 0 sends exactly 0), a beam
 * through a gap may still lie between them: the bound, a quarter of it for each
 * generation of ancestors whose test found their corners and midpoints dark
 * too (a beam that escaped those samples is narrower than their spacing, so it
 * fills at most about the share of the leaf that one child is of its parent).
 * With the whole bound for every leaf, the walls the Veach door's beam lights
 * (bound 3-9 times their light) and the dark ones beside them kept ahead of
 * visible leaves at the door's base for the whole run (docs/cache.md, "The line
 * along the door's base"). */
float cache_unseen_priority(const cache *c, uint32_t node, const mesh_qnode *n)
{
    float imax, isum;
    cache_node_importance(c, node, &imax, &isum);
    if (!(isum > 0.0f)) return 0.0f; /* no gather draws from it (yet): nothing to weigh */
    source_levels s = source_levels_of(c, n, 0);
    if (s.hi > 0.0f) return isum * (s.hi - s.lo);
    s = source_levels_of(c, n, 1);
    return isum * ldexpf(s.bound, -2 * (int)cache_unseen_dark_generations(c, node));
}

/* Dark at its corners and at the midpoints its test sampled (an unseen leaf's
 * test: the children's dark generations). */
int cache_unseen_all_dark(const cache *c, const mesh_qnode *n, const uint32_t mid[3])
{
    for (int k = 0; k < 3; ++k) {
        float a[3], m[3];
        mesh_qmesh_get_value(c->direct, n->v[k], a);
        mesh_qmesh_get_value(c->direct, mid[k], m);
        for (int ch = 0; ch < 3; ++ch)
            if (a[ch] > 0.0f || m[ch] > 0.0f) return 0;
    }
    return 1;
}

/* ---- a split of an unseen leaf -------------------------------------------------------
 *
 * A split of an unseen source leaf is kept when the viewer could see it through
 * the gathers (importance, cache_source.c): the deviations δ_k of kd·L_dd at the
 * edge midpoints from the edges' means change the leaf's mean radiance by
 * (Σ δ_k)/4 (the children's planes against the parent's, integrated), which
 * changes a visible colour by at most imp_max × that; kept above
 * SOURCE_EDGE_JND of the JND. The size criterion's counterpart: a leaf whose
 * peak (source_peak: its values, and its unoccluded bound) would be seen above
 * SOURCE_SIZE_JND JNDs is split anyway (a bright spot, such as the beam through
 * a door gap, may lie between corners that do not show it). */
#define SOURCE_EDGE_JND 0.5f
#define SOURCE_SIZE_JND 8.0f

int cache_unseen_split_seen(const cache *c, uint32_t node, const mesh_qnode *n, const uint32_t mid[3],
                            float *seen_change)
{
    float imax, isum;
    cache_node_importance(c, node, &imax, &isum);
    *seen_change = 0.0f;
    if (!(imax > 0.0f)) return 0;
    const float *kd = c->s->materials[c->s->tris[n->tri].material].kd;
    float dev = 0.0f, peak = source_peak(c, n);
    for (int k = 0; k < 3; ++k) {
        float a[3], b[3], m[3], d = 0.0f;
        mesh_qmesh_get_value(c->direct, n->v[k], a);
        mesh_qmesh_get_value(c->direct, n->v[(k + 1) % 3], b);
        mesh_qmesh_get_value(c->direct, mid[k], m);
        for (int ch = 0; ch < 3; ++ch) {
            d = fmaxf(d, kd[ch] * fabsf(m[ch] - 0.5f * (a[ch] + b[ch])));
            peak = fmaxf(peak, kd[ch] * m[ch]);
        }
        dev += d;
    }
    /* The children's share of the importance is a quarter each: imp_max stays the
     * parent's bound for the change over the whole leaf. What the viewer sees of
     * the change, in cache_unseen_priority's units (pixel·ΔE): isum times it. */
    *seen_change = isum * 0.25f * dev;
    return imax * 0.25f * dev > SOURCE_EDGE_JND * c->desc.jnd || imax * peak > SOURCE_SIZE_JND * c->desc.jnd;
}

/* Schedules every unseen leaf of the direct mesh under `node`. */
static lm_result schedule_source_subtree(cache *c, uint32_t node, const uint32_t *pixels, lm_error *err)
{
    const mesh_qnode *n = mesh_qmesh_node(c->direct, node);
    if (n->child != MESH_QMESH_NONE) {
        uint32_t child = n->child;
        lm_result r = LM_OK;
        for (uint32_t k = 0; r == LM_OK && k < 4; ++k) r = schedule_source_subtree(c, child + k, pixels, err);
        return r;
    }
    if (!cache_unseen_leaf(pixels, CACHE_KIND_DIRECT, n)) return LM_OK;
    /* (It may be waiting already: the heap drops a second entry when it is popped.) */
    return cache_sched_add(c, CACHE_KIND_DIRECT, node, cache_unseen_priority(c, node, n), err);
}

/* After visible gathers: record where they draw from, and schedule the unseen
 * source leaves whose importance grew. */
lm_result cache_unseen_schedule_important(cache *c, const cache_site *sites, uint32_t n, const uint32_t *pixels,
                                          lm_error *err)
{
    if (c->desc.single_mesh || !pixels) return LM_OK;
    const uint32_t *grown;
    uint32_t gn;
    lm_result r = cache_record_importance(c, sites, n, pixels, &grown, &gn, err);
    for (uint32_t i = 0; r == LM_OK && i < gn; ++i) r = schedule_source_subtree(c, grown[i], pixels, err);
    return r;
}
