/* cache_borrow.c — the first image's borrowed indirect values, tested (issue 16;
 * docs/cache.md, "Borrowed values tested").
 *
 * The first image gathers at a budget of root corners (cache_first.c) and every
 * other root corner borrows from the gathered ones beside it along a Morton
 * order. Gathering every borrowed corner again after the first image was one
 * gather per root corner whatever the picture needed: on a 116k-triangle box
 * 59,000 gathers (about 18 s) before any leaf was tested. Instead, a run of
 * borrowed corners between donors (a span) is tested the way an edge of a leaf
 * is (§4.3, the midpoint test): one corner is gathered, the one its donors
 * support least (least_supported), and compared with what it borrows, through
 * the tone map, at that corner.
 *   - The difference can be seen (ΔE above the JND) and the noise of the gather
 *     and of the donors does not explain it (CACHE_NOISE_SIGMAS), or the span
 *     covers more pixels than an indirect leaf may (CACHE_INDIRECT_SIZE_FACTOR ×
 *     min_leaf_pixels), or a corner of it has no donor within 26° of its normal
 *     (BORROW_NORMAL_COS): the span splits at the tested corner, which is a donor
 *     from then on, and each part is tested in turn.
 *   - Else its corners keep borrowed values (now also from the tested one), and the
 *     ΔE the test left (less what the noise explains, in quadrature, as the edge
 *     test's residual) is their error in the estimate (cache_estimate.c). A JND
 *     lowered below it tests the span again.
 * Without pixels every span splits to single corners: every corner is gathered,
 * as before.
 *
 * What it does NOT do: test more than one corner of a span (as the edge test, one
 * midpoint stands for the edge: on startup_test's ball 3.9% of the corners end
 * above the JND the estimate sees), or borrow again after a camera move (a leaf that
 * grows to several pixels is tested by the edge test, which compares fresh
 * gathers with the borrowed corners).
 *
 * Owns cache_borrow_state; sets borrowed values through cache_set_borrowed
 * (cache_source.c). On the cache's thread, like the rest. */
#include "mesh/cache/cache_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "src/base/vecmath.h"

int cache_borrow_weights(const cache *c, uint32_t vid, const uint32_t *d, int nd, double span, int q[4], double w[4])
{
    const mesh_vertex *mv = mesh_vtable_vertex(c->vt, vid);
    int n = 0, near_q = -1;
    double nearest = INFINITY;
    for (int j = 0; j < nd; ++j) {
        const mesh_vertex *g = mesh_vtable_vertex(c->vt, d[j]);
        lm_dvec3 dd = dv3_sub(dv3_load(mv->position), dv3_load(g->position));
        double dist = dv3_length(dd) + 1e-6 * span, cosn = dv3_dot(dv3_load(mv->normal), dv3_load(g->normal));
        if (dist < nearest) nearest = dist, near_q = j;
        if (cosn < 0.3) continue;
        q[n] = j;
        w[n++] = cosn * cosn / dist;
    }
    if (n == 0 && near_q >= 0) {
        q[0] = near_q;
        w[0] = 1.0;
        n = 1;
    }
    return n;
}

/* A span is kept when its test differs by at most this share of the JND: one
 * corner stands for the whole run (measured in startup_test: at the whole JND,
 * 7.5% of the ball's corners ended above it). */
#define BORROW_JND_SHARE 1.0f

static lm_result push_span(cache_borrow_state *b, const cache_borrow_span *s, lm_error *err)
{
    if (b->pending_n == b->pending_cap && b->head > 0) { /* reuse what was taken */
        memmove(b->pending, b->pending + b->head, (b->pending_n - b->head) * sizeof *b->pending);
        b->pending_n -= b->head;
        b->head = 0;
    }
    if (b->pending_n == b->pending_cap && !LM_GROW(b->pending, b->pending_cap, b->pending_n + 1))
        return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory testing borrowed indirect values");
    b->pending[b->pending_n++] = *s;
    b->pending_corners += s->hi - s->lo + 1;
    return LM_OK;
}

lm_result cache_borrow_start(cache *c, uint32_t *order, uint32_t n, const uint32_t *at, uint32_t nchosen,
                             double span, lm_error *err)
{
    cache_borrow_state *b = &c->brw;
    cache_borrow_free(b);
    b->order = order;
    b->n = n;
    b->span = span;
    lm_result r = LM_OK;
    /* The runs between consecutive donors (and before the first, after the last). */
    for (int64_t j = -1; r == LM_OK && j < (int64_t)nchosen; ++j) {
        const uint32_t lo = j < 0 ? 0 : at[j] + 1, hi = j + 1 < (int64_t)nchosen ? at[j + 1] : n;
        if (lo >= hi) continue;
        cache_borrow_span s = {.lo = lo, .hi = hi - 1};
        for (int k = 0; k < 2; ++k) {
            int64_t l = j - k, rr = j + 1 + k;
            s.left[k] = l >= 0 ? at[l] : CACHE_BORROW_NONE;
            s.right[k] = rr < (int64_t)nchosen ? at[rr] : CACHE_BORROW_NONE;
        }
        r = push_span(b, &s, err);
        b->stats.borrowed += s.hi - s.lo + 1;
    }
    return r;
}

void cache_borrow_release(cache *c) { c->brw.released = c->brw.head < c->brw.pending_n; }
uint64_t cache_borrow_pending(const cache *c) { return c->brw.released ? c->brw.pending_corners : 0; }

/* The span's donors (vertex ids), left then right, nearest last then first. */
static int span_donors(const cache_borrow_state *b, const uint32_t left[2], const uint32_t right[2], uint32_t d[4])
{
    int nd = 0;
    for (int k = 1; k >= 0; --k)
        if (left[k] != CACHE_BORROW_NONE) d[nd++] = b->order[left[k]];
    for (int k = 0; k < 2; ++k)
        if (right[k] != CACHE_BORROW_NONE) d[nd++] = b->order[right[k]];
    return nd;
}

int cache_borrow_mean(const cache *c, uint32_t vid, const uint32_t *d, int nd, double span, float E[3], float sg[3],
                      float sl[3])
{
    int q[4];
    double w[4], wsum = 0.0, e[3] = {0, 0, 0}, v1[3] = {0, 0, 0}, v2[3] = {0, 0, 0};
    int nb = cache_borrow_weights(c, vid, d, nd, span, q, w);
    for (int i = 0; i < nb; ++i) wsum += w[i];
    if (!(wsum > 0.0)) return 0;
    for (int i = 0; i < nb; ++i) {
        float v[3], s1[3], s2[3];
        mesh_qmesh_get_value(c->indirect, d[q[i]], v);
        cache_indirect_sigma(c, d[q[i]], s1);
        cache_indirect_likely_sigma(c, d[q[i]], s2);
        const double a = w[i] / wsum;
        for (int k = 0; k < 3; ++k) {
            e[k] += a * v[k];
            v1[k] += a * a * s1[k] * s1[k];
            v2[k] += a * a * s2[k] * s2[k];
        }
    }
    for (int k = 0; k < 3; ++k) {
        E[k] = (float)e[k];
        sg[k] = (float)sqrt(v1[k]);
        sl[k] = (float)sqrt(v2[k]);
    }
    return 1;
}

/* What vertex vid borrows from the span's donors `left` and `right` (order
 * positions, nearest first): cache_borrow_mean. */
static int borrow_value(const cache *c, uint32_t vid, const uint32_t left[2], const uint32_t right[2], float E[3],
                        float sg[3], float sl[3])
{
    uint32_t d[4];
    const int nd = span_donors(&c->brw, left, right, d);
    return cache_borrow_mean(c, vid, d, nd, c->brw.span, E, sg, sl);
}

/* What the viewer sees at vertex vid with indirect irradiance e (CIELAB). */
static void seen_at(const cache *c, uint32_t vid, const float e[3], float lab[3])
{
    float ldd[3], e0[3];
    cache_vertex_direct(c, vid, ldd);
    for (int k = 0; k < 3; ++k) e0[k] = fmaxf(e[k], 0.0f);
    cache_seen_lab(c, mesh_vtable_vertex(c->vt, vid)->tri, ldd, e0, NULL, lab);
}

/* Per vertex id, a third of the pixels of each triangle of the indirect mesh's
 * roots around it (pixels NULL: a million a triangle). */
static lm_result corner_pixels(cache *c, const uint32_t *pixels, lm_error *err)
{
    cache_borrow_state *b = &c->brw;
    const size_t limit = mesh_vtable_id_limit(c->vt);
    if (limit > b->px_cap) {
        float *p = realloc(b->px, limit * sizeof *p);
        if (!p) return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory testing borrowed indirect values");
        b->px = p;
        b->px_cap = limit;
    }
    memset(b->px, 0, limit * sizeof *b->px);
    for (uint32_t t = 0; t < c->s->tri_count; ++t) {
        const uint32_t root = cache_tri_active(c, t) ? mesh_qmesh_root(c->indirect, t) : MESH_QMESH_NONE;
        if (root == MESH_QMESH_NONE) continue;
        const mesh_qnode *nd = mesh_qmesh_node(c->indirect, root);
        const float share = (pixels ? (float)pixels[t] : 1e6f) / 3.0f;
        for (int k = 0; k < 3; ++k) b->px[nd->v[k]] += share;
    }
    return LM_OK;
}

/* A borrowed corner needs a donor whose normal is within about 26° of its own
 * (cosine at least this); a span with a corner that has none splits whatever its
 * test says: indirect irradiance turns with the normal, and on the startup_test
 * ball, borrowing across up to 72° left 7.5% of the corners above the JND. */
#define BORROW_NORMAL_COS 0.9

/* The corner of span s that its donors support least (the smallest sum of
 * borrowing weights: far from them, or turned away): where borrowing is most
 * likely wrong, so the span's test is made there. *coherent: every corner has a
 * donor within BORROW_NORMAL_COS. */
static uint32_t least_supported(const cache *c, const cache_borrow_span *s, int *coherent)
{
    const cache_borrow_state *b = &c->brw;
    uint32_t d[4], best = s->lo + (s->hi - s->lo) / 2;
    int q[4];
    const int nd = span_donors(b, s->left, s->right, d);
    double least = INFINITY;
    *coherent = 1;
    for (uint32_t p = s->lo; p <= s->hi; ++p) {
        const mesh_vertex *mv = mesh_vtable_vertex(c->vt, b->order[p]);
        double w[4], sum = 0.0, best_cos = -1.0;
        int nb = cache_borrow_weights(c, b->order[p], d, nd, b->span, q, w);
        for (int i = 0; i < nb; ++i) sum += w[i];
        for (int i = 0; i < nd; ++i)
            best_cos = fmax(best_cos, dv3_dot(dv3_load(mv->normal), dv3_load(mesh_vtable_vertex(c->vt, d[i])->normal)));
        if (best_cos < BORROW_NORMAL_COS) *coherent = 0, sum = 0.0;
        if (sum < least) least = sum, best = p;
    }
    return best;
}

typedef struct borrow_test {
    cache_borrow_span span;
    uint32_t mid;              /* order position tested */
    int coherent;              /* least_supported's */
} borrow_test;

/* The span s's corners other than its middle m borrow from its donors and m. */
static void halves(const cache_borrow_span *s, uint32_t m, cache_borrow_span out[2], int *nout)
{
    *nout = 0;
    if (m > s->lo)
        out[(*nout)++] = (cache_borrow_span){.lo = s->lo, .hi = m - 1, .left = {s->left[0], s->left[1]},
                                              .right = {m, s->right[0]}};
    if (m < s->hi)
        out[(*nout)++] = (cache_borrow_span){.lo = m + 1, .hi = s->hi, .left = {m, s->left[0]},
                                              .right = {s->right[0], s->right[1]}};
}

static int cmp_u32(const void *a, const void *b)
{
    uint32_t x = *(const uint32_t *)a, y = *(const uint32_t *)b;
    return (x > y) - (x < y);
}

/* Accepts span s (its test left ΔE de): its borrowed corners take their values
 * from its donors, recorded as changed. */
static lm_result keep_span(cache *c, cache_borrow_span *s, float de, uint32_t **moved, size_t *nm, size_t *cap,
                           lm_error *err)
{
    cache_borrow_state *b = &c->brw;
    lm_result r = LM_OK;
    s->de = de;
    for (uint32_t p = s->lo; r == LM_OK && p <= s->hi; ++p) {
        const uint32_t vid = b->order[p];
        if (cache_borrowed_de(c, vid) == 0.0f) continue; /* gathered meanwhile */
        float E[3], sg[3], sl[3];
        if (!borrow_value(c, vid, s->left, s->right, E, sg, sl)) continue;
        r = cache_set_borrowed(c, vid, E, sg, sl, de, err);
        if (r == LM_OK && *nm == *cap && !LM_GROW(*moved, *cap, *nm + 1))
            r = lm_fail(err, LM_ERR_NO_MEMORY, "out of memory testing borrowed indirect values");
        if (r == LM_OK) (*moved)[(*nm)++] = vid;
        b->stats.kept++;
    }
    if (r == LM_OK && b->accepted_n == b->accepted_cap && !LM_GROW(b->accepted, b->accepted_cap, b->accepted_n + 1))
        r = lm_fail(err, LM_ERR_NO_MEMORY, "out of memory testing borrowed indirect values");
    if (r == LM_OK) b->accepted[b->accepted_n++] = *s;
    return r;
}

/* The test of one span whose middle has its gathered value now. */
static lm_result judge(cache *c, const borrow_test *t, float min_pixels, uint32_t **moved, size_t *nm, size_t *cap,
                       lm_error *err)
{
    cache_borrow_state *b = &c->brw;
    const cache_borrow_span *s = &t->span;
    const uint32_t vid = b->order[t->mid];
    float fresh[3], sf[3], lf[3], bor[3], sb[3], lb[3];
    mesh_qmesh_get_value(c->indirect, vid, fresh);
    cache_indirect_sigma(c, vid, sf);
    cache_indirect_likely_sigma(c, vid, lf);
    cache_borrow_span half[2];
    int nh;
    halves(s, t->mid, half, &nh);
    b->stats.tests++;
    int split = !borrow_value(c, vid, s->left, s->right, bor, sb, lb);
    float de = 0.0f, dn = 0.0f;
    if (!split) {
        float lab_f[3], lab_b[3], lab_n[3], up[3];
        seen_at(c, vid, fresh, lab_f);
        seen_at(c, vid, bor, lab_b);
        de = tm_delta_e(lab_f, lab_b);
        int beyond = 0;
        for (int k = 0; k < 3; ++k) {
            beyond |= fabsf(fresh[k] - bor[k]) > CACHE_NOISE_SIGMAS * sqrtf(sf[k] * sf[k] + sb[k] * sb[k]);
            up[k] = bor[k] + sqrtf(lf[k] * lf[k] + lb[k] * lb[k]);
        }
        seen_at(c, vid, up, lab_n);
        dn = tm_delta_e(lab_b, lab_n);
        double px = 0.0;
        for (uint32_t p = s->lo; p <= s->hi; ++p) px += b->px[b->order[p]];
        split = (de > BORROW_JND_SHARE * c->desc.jnd && beyond) || px > min_pixels || !t->coherent;
    }
    if (split) {
        b->stats.splits++;
        lm_result r = LM_OK;
        for (int h = 0; h < nh && r == LM_OK; ++h) r = push_span(b, &half[h], err);
        return r;
    }
    const float resid = fmaxf(sqrtf(fmaxf(de * de - dn * dn, 0.0f)), CACHE_BORROW_DE_MIN);
    lm_result r = LM_OK;
    for (int h = 0; h < nh && r == LM_OK; ++h) r = keep_span(c, &half[h], resid, moved, nm, cap, err);
    return r;
}

lm_result cache_borrow_test(cache *c, const uint32_t *pixels, cache_changed_fn changed, void *user,
                            uint64_t *allowance, lm_error *err)
{
    enum { BATCH = 256 };
    cache_borrow_state *b = &c->brw;
    if (!b->released || b->head == b->pending_n || !c->indirect) return LM_OK;
    const float min_pixels = c->desc.min_leaf_pixels * CACHE_INDIRECT_SIZE_FACTOR;
    lm_result r = corner_pixels(c, pixels, err);
    borrow_test *tests = malloc(BATCH * sizeof *tests);
    uint32_t *need = malloc(BATCH * sizeof *need), *moved = NULL;
    float *E = malloc(3 * BATCH * sizeof *E);
    size_t nm = 0, mcap = 0;
    if (r == LM_OK && (!tests || !need || !E)) r = lm_fail(err, LM_ERR_NO_MEMORY, "out of memory testing borrowed indirect values");
    while (r == LM_OK && b->head < b->pending_n && (!allowance || *allowance > 0) && !cache_stopping(c)) {
        const uint32_t most = allowance && *allowance < BATCH ? (uint32_t)*allowance : BATCH;
        uint32_t nt = 0, nn = 0;
        while (nt < most && b->head < b->pending_n) {
            borrow_test *t = &tests[nt++];
            t->span = b->pending[b->head++];
            b->pending_corners -= t->span.hi - t->span.lo + 1;
            t->mid = least_supported(c, &t->span, &t->coherent);
            /* A middle gathered meanwhile (outdated, or noisy) is tested as it is. */
            if (cache_borrowed_de(c, b->order[t->mid]) != 0.0f) need[nn++] = b->order[t->mid];
        }
        if (b->head == b->pending_n) b->head = b->pending_n = 0;
        r = cache_sample_indirect(c, need, nn, E, err);
        if (allowance) *allowance -= nn < *allowance ? nn : *allowance;
        nm = 0;
        for (uint32_t i = 0; r == LM_OK && i < nn; ++i) {
            r = mesh_qmesh_set_value(c->indirect, need[i], E + 3 * (size_t)i, err);
            if (r == LM_OK && nm == mcap && !LM_GROW(moved, mcap, nm + 1))
                r = lm_fail(err, LM_ERR_NO_MEMORY, "out of memory testing borrowed indirect values");
            if (r == LM_OK) moved[nm++] = need[i];
        }
        for (uint32_t i = 0; r == LM_OK && i < nt; ++i) r = judge(c, &tests[i], min_pixels, &moved, &nm, &mcap, err);
        if (r == LM_OK && nm && changed) {
            qsort(moved, nm, sizeof *moved, cmp_u32);
            r = changed(c, CACHE_KIND_INDIRECT, NULL, 0, moved, (uint32_t)nm, user, err);
        }
    }
    free(tests);
    free(need);
    free(moved);
    free(E);
    return r;
}

lm_result cache_borrow_retest(cache *c, float above, lm_error *err)
{
    cache_borrow_state *b = &c->brw;
    lm_result r = LM_OK;
    for (size_t i = 0; r == LM_OK && i < b->accepted_n;) {
        if (b->accepted[i].de <= above) {
            ++i;
            continue;
        }
        r = push_span(b, &b->accepted[i], err);
        b->accepted[i] = b->accepted[--b->accepted_n];
    }
    if (b->head < b->pending_n && b->order) b->released = 1;
    return r;
}

void cache_borrow_free(cache_borrow_state *b)
{
    cache_borrow_stats keep = b->stats;
    free(b->order);
    free(b->pending);
    free(b->accepted);
    free(b->px);
    memset(b, 0, sizeof *b);
    b->stats = keep;
}

size_t cache_borrow_bytes(const cache_borrow_state *b)
{
    return (size_t)b->n * sizeof *b->order + b->pending_cap * sizeof *b->pending +
           b->accepted_cap * sizeof *b->accepted + b->px_cap * sizeof *b->px;
}
