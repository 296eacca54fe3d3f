/* cache_estimate.c — the cache's own estimate of the error the viewer sees
 * (cache.h: cache_estimate_error; docs/cache.md, "Converged means right").
 *
 * Per visible leaf of each radiance mesh: its interpolation error from its edge
 * test (cache_sched.resid, written by cache_refine.c) and, for the indirect mesh,
 * the noise its gathers' standard errors leave (cache_source.c's σ per vertex),
 * both as CIELAB ΔE of what the viewer sees, weighted by the pixels the leaf
 * covers. Read-only: it walks the trees and changes nothing.
 *
 * It also names the vertices whose noise keeps a leaf above the JND
 * (cache_noisy_vertices), for the scheduler to gather again with more rays.
 *
 * Sits above cache_source.c (reads σ), below cache_refine.c (whose part's
 * residuals it reads, as cache_internal.h allows) and cache.c.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "mesh/cache/cache_internal.h"

/* The mean |x| of a normal is 0.80 σ, and interpolation between three
 * independent corner errors leaves σ·√(Σw²), whose square averages to σ²/2 over
 * a triangle (E[w²] = 1/6 per corner under uniform barycentrics). */
#define NOISE_MEAN_ABS 0.56f

typedef struct est_walk {
    const cache *c;
    cache_kind kind;
    const mesh_qmesh *m;
    float jnd;
    cache_mesh_estimate *out;
} est_walk;

/* ΔE of ± d about e (the mean of the two), over background bg. */
static float noise_de_at(const est_walk *w, uint32_t tri, const float bg[CACHE_KINDS][3], const float e[3],
                         const float d[3])
{
    float up[3], down[3], lab0[3], lab1[3], lab2[3];
    for (int ch = 0; ch < 3; ++ch) {
        up[ch] = e[ch] + d[ch];
        down[ch] = fmaxf(e[ch] - d[ch], 0.0f);
    }
    cache_seen_lab_over(w->c, w->kind, tri, bg, e, lab0);
    cache_seen_lab_over(w->c, w->kind, tri, bg, up, lab1);
    cache_seen_lab_over(w->c, w->kind, tri, bg, down, lab2);
    return 0.5f * (tm_delta_e(lab0, lab1) + tm_delta_e(lab0, lab2));
}

/* The noise a leaf's interpolated E_i carries, as ΔE at its centroid; where that
 * is past the display's white and the leaf's darkest corner is not, also on the
 * way to that corner, where the corners' noise shows (docs/cache.md,
 * "Differences hidden in white"), the largest counting. */
static float leaf_noise(const est_walk *w, const mesh_qnode *n)
{
    float e[3] = {0, 0, 0}, s2[3] = {0, 0, 0}, dark[3] = {0, 0, 0};
    float dark_sum = INFINITY;
    double cw1 = 0.0, cw2 = 0.0;
    for (int k = 0; k < 3; ++k) {
        float v[3], sg[3];
        double w1, w2;
        mesh_qmesh_get_value(w->m, n->v[k], v);
        cache_indirect_likely_sigma(w->c, n->v[k], sg);
        cache_node_corner_bary(n, k, &w1, &w2);
        cw1 += w1 / 3.0;
        cw2 += w2 / 3.0;
        for (int ch = 0; ch < 3; ++ch) {
            e[ch] += v[ch] / 3.0f;
            s2[ch] += sg[ch] * sg[ch] / 3.0f;
        }
        if (v[0] + v[1] + v[2] < dark_sum) {
            dark_sum = v[0] + v[1] + v[2];
            memcpy(dark, v, sizeof dark);
        }
    }
    if (!(s2[0] > 0.0f || s2[1] > 0.0f || s2[2] > 0.0f)) return 0.0f;
    float d[3], bg[CACHE_KINDS][3], white[3];
    for (int ch = 0; ch < 3; ++ch) {
        d[ch] = NOISE_MEAN_ABS * sqrtf(s2[ch]);
        e[ch] = fmaxf(e[ch], 0.0f);
    }
    cache_other_terms_at(w->c, w->kind, n->tri, cw1, cw2, bg);
    float best = noise_de_at(w, n->tri, (const float(*)[3])bg, e, d);
    cache_white_level(w->c, w->kind, n->tri, (const float(*)[3])bg, white);
    int past = 0, below = 0;
    for (int ch = 0; ch < 3; ++ch) {
        past |= e[ch] + d[ch] > white[ch];
        below |= dark[ch] < white[ch];
    }
    for (int q = 1; past && below && q < 3; ++q) { /* a third and two thirds of the way */
        const float t = (float)q / 3.0f;
        float v[3];
        for (int ch = 0; ch < 3; ++ch) v[ch] = (1.0f - t) * e[ch] + t * fmaxf(dark[ch], 0.0f);
        best = fmaxf(best, noise_de_at(w, n->tri, (const float(*)[3])bg, v, d));
    }
    return best;
}

float cache_sched_residual(const cache_sched *st, cache_kind kind, uint32_t node, int *tested)
{
    float v = node < st->resid_cap[kind] ? st->resid[kind][node] : 0.0f;
    if (tested) *tested = v > 0.0f;
    return fabsf(v) - 1.0f;
}

/* A leaf's interpolation and noise estimates (ΔE; a leaf smaller than a pixel
 * by its share of the pixel, as its test judges it: cache_refine.c); returns
 * whether the leaf's own test gave the interpolation (a leaf no test may split,
 * cache_leaf_below_sample, counts as tested). */
static int leaf_estimate(const est_walk *w, uint32_t node, const mesh_qnode *n, double px, float *interp_out,
                         float *noise_out)
{
    int tested, untested_borrowed = 0;
    const int one_sample = cache_leaf_below_sample(w->c, w->kind, px, n);
    const float share = cache_pixel_share(px);
    float interp = cache_sched_residual(&w->c->sched, w->kind, node, &tested);
    if (interp < 0.0f) { /* never tested: what its corners' contrast allows */
        interp = share * cache_leaf_contrast(w->c, w->m, w->kind, n);
        if (one_sample) interp *= 0.25f;
    }
    if (w->kind == CACHE_KIND_INDIRECT && w->c->desc.single_mesh) interp = 0.0f; /* judged with direct */
    if (w->kind == CACHE_KIND_INDIRECT) {
        /* Borrowed corners (cache_borrow.c): the ΔE their span's test left adds to
         * the leaf's own, in quadrature; one not tested yet leaves the leaf untested. */
        float b = 0.0f;
        for (int k = 0; k < 3; ++k) {
            float d = cache_borrowed_de(w->c, n->v[k]);
            if (isinf(d)) untested_borrowed = 1;
            else b += d / 3.0f;
        }
        interp = sqrtf(interp * interp + b * b);
    }
    *interp_out = interp;
    *noise_out = w->kind == CACHE_KIND_INDIRECT ? share * leaf_noise(w, n) : 0.0f;
    return (tested || one_sample) && !untested_borrowed;
}

/* A leaf's error from its two parts: in quadrature, since its interpolation
 * error (the function's shape between its corners, fixed) and its noise (its
 * values' random error, mean zero) are independent: E[(a + b)²] = a² + σ². Added,
 * they overstated the error where both are there: the floor box of
 * cache_indirect_test at 4 rays a gather, 7.3 estimated against 3.4 measured
 * (docs/cache.md, "Converged means right"). */
static float leaf_combined(float interp, float noise) { return sqrtf(interp * interp + noise * noise); }

static void visit_leaf(const est_walk *w, uint32_t node, const mesh_qnode *n, double px)
{
    float interp, noise;
    int tested = leaf_estimate(w, node, n, px, &interp, &noise);
    cache_mesh_estimate *o = w->out;
    const float total = leaf_combined(interp, noise);
    o->pixels += px;
    if (!tested) o->pixels_untested += px;
    o->interpolation += px * interp;
    o->noise += px * noise;
    o->combined += px * total;
    if (total > o->max) o->max = total;
    if (total > w->jnd) o->pixels_above_jnd += px;
}

typedef void (*leaf_fn)(const est_walk *w, uint32_t node, const mesh_qnode *n, double px);

static void walk_tree(const est_walk *w, uint32_t root, double root_pixels, leaf_fn visit)
{
    uint32_t stack[4 * MESH_QMESH_DEPTHS + 4];
    uint32_t top = 0;
    stack[top++] = root;
    while (top) {
        uint32_t node = stack[--top];
        const mesh_qnode *n = mesh_qmesh_node(w->m, node);
        if (n->child == MESH_QMESH_NONE) {
            visit(w, node, n, ldexp(root_pixels, -2 * (int)n->depth));
            continue;
        }
        for (uint32_t k = 0; k < 4; ++k) stack[top++] = n->child + k;
    }
}

static void finish(cache_mesh_estimate *o)
{
    if (o->pixels > 0.0) {
        o->interpolation /= o->pixels;
        o->noise /= o->pixels;
        o->combined /= o->pixels;
    }
}

lm_result cache_estimate_error(const cache *c, const uint32_t *pixels, cache_estimate *out, lm_error *err)
{
    if (!c || !out) return lm_fail(err, LM_ERR_INVALID_ARG, "cache_estimate_error: no cache or no result");
    memset(out, 0, sizeof *out);
    out->jnd = c->desc.jnd;
    out->exposure = cache_get_exposure(c);
    out->measured = 1;
    cache_mesh_estimate *per[CACHE_KINDS] = {&out->direct, &out->indirect, &out->specular};
    double sum = 0.0, above = 0.0, untested = 0.0;
    for (uint32_t t = 0; t < c->s->tri_count; ++t) out->pixels += pixels ? (double)pixels[t] : 1e6;
    for (int k = 0; k < CACHE_KINDS; ++k) {
        est_walk w = {c, (cache_kind)k, cache_kind_mesh(c, (cache_kind)k), c->desc.jnd, per[k]};
        if (!w.m) continue;
        for (uint32_t t = 0; t < c->s->tri_count; ++t) {
            uint32_t root = mesh_qmesh_root(w.m, t);
            double px = pixels ? (double)pixels[t] : 1e6;
            if (root != MESH_QMESH_NONE && px > 0.0 && cache_tri_active(c, t)) walk_tree(&w, root, px, visit_leaf);
        }
        sum += per[k]->combined;
        above += per[k]->pixels_above_jnd;
        untested = fmax(untested, per[k]->pixels_untested);
        finish(per[k]);
    }
    if (out->pixels > 0.0) {
        out->mean = sum / out->pixels;
        out->above_jnd = fmin(above / out->pixels, 1.0);
        out->untested = fmin(untested / out->pixels, 1.0);
    }
    return LM_OK;
}

int cache_estimate_converged(const cache_estimate *e)
{
    return e->measured && e->above_jnd <= CACHE_CONVERGED_ABOVE_JND;
}

/* ---- where more rays would help ---------------------------------------------------- */

#define NOISY_MIN_JND 0.05f /* noise below this share of the JND is not worth a gather */

typedef struct noisy_leaf {
    float priority; /* pixels × noise ΔE */
    uint32_t v[3];
} noisy_leaf;

typedef struct noisy_walk {
    est_walk w;
    noisy_leaf *leaves;
    size_t n, cap;
    int failed;
} noisy_walk;

static void visit_noisy(const est_walk *w, uint32_t node, const mesh_qnode *n, double px)
{
    noisy_walk *nw = (noisy_walk *)w; /* w is its first member */
    float interp, noise;
    leaf_estimate(w, node, n, px, &interp, &noise);
    /* Worth rays only where the noise is what keeps the leaf above the JND: with
     * its interpolation error alone above it, the leaf needs a split (its next
     * test), not a quieter value. Unless no test will split it (docs/cache.md,
     * "Leaves the noise kept whole"): its own test ran and kept it whole, a
     * midpoint ΔE above the JND that the noise explained (cache_refine.c,
     * beyond_noise), or it is too small to test and its corners' contrast (its
     * interpolation's guess) is no more than their noise. Left out, such leaves
     * stayed above the JND with nothing left to do: the 116k box "stuck" at
     * 2.05% of its pixels, and a 5σ value of a 4-ray gather on a leaf of one
     * pixel kept for good. Quieter values let the next test tell, or lower the
     * contrast. */
    int tested = 0;
    cache_sched_residual(&w->c->sched, w->kind, node, &tested);
    const int blocked = tested || (cache_leaf_below_sample(w->c, w->kind, px, n) && noise >= interp);
    if (!(leaf_combined(interp, noise) > w->jnd) || !(interp < w->jnd || blocked) || !(noise > NOISY_MIN_JND * w->jnd))
        return;
    int any = 0;
    for (int k = 0; k < 3; ++k) any |= cache_gather_can_refine(w->c, n->v[k]);
    if (!any) return;
    if (!LM_GROW(nw->leaves, nw->cap, nw->n + 1)) {
        nw->failed = 1;
        return;
    }
    nw->leaves[nw->n++] = (noisy_leaf){(float)px * noise, {n->v[0], n->v[1], n->v[2]}};
}

static int cmp_noisy(const void *a, const void *b)
{
    float x = ((const noisy_leaf *)a)->priority, y = ((const noisy_leaf *)b)->priority;
    return (x < y) - (x > y);
}

static int cmp_u32(const void *a, const void *b)
{
    uint32_t x = *(const uint32_t *)a, y = *(const uint32_t *)b;
    return (x > y) - (x < y);
}

lm_result cache_noisy_vertices(const cache *c, const uint32_t *pixels, uint64_t max_cost, uint32_t **out, uint32_t *count,
                               cache_noisy_top *top, lm_error *err)
{
    *out = NULL;
    *count = 0;
    if (top) *top = (cache_noisy_top){0.0f, 0};
    noisy_walk nw = {{c, CACHE_KIND_INDIRECT, c->indirect, c->desc.jnd, NULL}, NULL, 0, 0, 0};
    for (uint32_t t = 0; t < c->s->tri_count && !nw.failed; ++t) {
        uint32_t root = mesh_qmesh_root(c->indirect, t);
        double px = pixels ? (double)pixels[t] : 1e6;
        if (root != MESH_QMESH_NONE && px > 0.0 && cache_tri_active(c, t)) walk_tree(&nw.w, root, px, visit_noisy);
    }
    if (nw.failed) {
        free(nw.leaves);
        return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory choosing values to gather again");
    }
    if (nw.n) qsort(nw.leaves, nw.n, sizeof *nw.leaves, cmp_noisy); /* (qsort of NULL: undefined) */
    if (top && nw.n) {
        top->priority = nw.leaves[0].priority;
        for (int k = 0; k < 3; ++k)
            if (cache_gather_can_refine(c, nw.leaves[0].v[k])) top->cost += cache_gather_finer_cost(c, nw.leaves[0].v[k]);
    }
    uint32_t *v = malloc(3 * (nw.n ? nw.n : 1) * sizeof *v), m = 0;
    if (!v) {
        free(nw.leaves);
        return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory choosing values to gather again");
    }
    /* The worst leaves' corners, until their rays at the next level are max_cost
     * plain gathers' worth (a corner is shared by up to six leaves: duplicates
     * are dropped, and the cost counted again, as the list grows). Counted in
     * rays, not values: 512 values at the fourth level are 134 million rays,
     * 15 s in which the viewer's worker would not answer a move. */
    uint64_t cost = 0;
    for (size_t i = 0; i < nw.n && cost < max_cost; ++i) {
        for (int k = 0; k < 3; ++k)
            if (cache_gather_can_refine(c, nw.leaves[i].v[k])) {
                v[m++] = nw.leaves[i].v[k];
                cost += cache_gather_finer_cost(c, nw.leaves[i].v[k]);
            }
        if (cost >= max_cost || i + 1 == nw.n || (i & 63) == 63) {
            qsort(v, m, sizeof *v, cmp_u32);
            uint32_t u = 0;
            cost = 0;
            for (uint32_t j = 0; j < m; ++j)
                if (u == 0 || v[u - 1] != v[j]) {
                    v[u++] = v[j];
                    cost += cache_gather_finer_cost(c, v[j]);
                }
            m = u;
        }
    }
    free(nw.leaves);
    *out = v;
    *count = m;
    return LM_OK;
}
