/* cache_refine.c — the refinement scheduler of the multi-mesh cache (paper
 * §4.3): which leaves to test, the edge test, keep or undo.
 *
 * A round takes the highest-priority leaves of one radiance mesh (direct or
 * indirect) from a max-heap, splits each tentatively, computes the values at the
 * new edge midpoints in one batch (direct: visible fractions from the light
 * meshes, sampling them only where they cannot interpolate, cache_light.c; indirect:
 * one samp_indirect batch), and compares at every midpoint the colour the viewer
 * would see with the fresh value and with the value interpolated from the edge's
 * ends, after tone mapping (src/base/tonemap.c, the display's own function; what
 * the viewer sees is cache_seen_lab, cache_site.c), as CIELAB
 * ΔE against the JND (§4.3.1–4.3.2). A split is kept when an edge differs
 * noticeably or the leaf still covers more than min_leaf_pixels (the size
 * criterion, so small discontinuities are not missed); otherwise it is undone
 * and the leaf is marked done. A leaf no larger than one of the picture's
 * samples (cache_desc.sample_pixels) is never tested, and one smaller than a
 * pixel is judged by its share of the pixel: its ΔE times its area in pixels.
 * Priority (§4.3.3): pixels the leaf covers × (1 + the largest ΔE between its
 * corners' colours). The direct mesh on triangles no pixel sees is the indirect
 * source there: its leaves are refined for the change the viewer would see
 * through the gathers (importance, Smits et al. 1992; recorded by
 * cache_source.c), in the same heap, with a priority in the same units. An
 * indirect split is kept only on a difference beyond the gathers' noise.
 * (What an unseen source leaf is worth, and when its split is kept:
 * cache_unseen.c.) After each round, values that changed under the
 * refinement's feet — radiance values inside a light leaf that answered as
 * uniform and proved not to be, indirect values a rebuilt source moved by more
 * than the JND — are recomputed (cache_light.c, cache_source.c) and the leaves
 * around them tested again (cache_requeue.c). Two schedulers pick the leaves (cache_desc.scheduler): a max-heap of
 * leaves, or the paper's randomized rule over node priorities kept as the
 * maximum of the children's (measured against each other in
 * bench/bench_cache.c, docs/cache.md).
 *
 * Owns cache_sched (cache_internal.h), with cache_queue.c (the heaps, the
 * priorities, the next leaf), cache_unseen.c and cache_requeue.c (its dark
 * generations, its requeued leaves). Calls cache_site.c, cache_light.c
 * and cache_source.c below it; cache.c (cache_refine, the edits) calls it, never the
 * reverse (the coarse cache is made there, before cache_sched_refine).
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "mesh/cache/cache_internal.h"
#include "src/base/parallel.h"
#include "src/base/vecmath.h"

enum { ROUND_LEAVES = 64 };
/* Calls the quieter values wait at most between two looks (cache_sched.noisy_wait). */
enum { NOISY_WAIT_MAX = 16 };
/* A round's gather (3 midpoints a leaf) keeps its pilot for the importance. */
_Static_assert(3 * ROUND_LEAVES <= CACHE_PILOT_CHUNK, "a refine round's gather must fit one pilot chunk");

typedef cache_kind refine_kind;
#define KIND_DIRECT CACHE_KIND_DIRECT
#define KIND_INDIRECT CACHE_KIND_INDIRECT
#define KIND_SPECULAR CACHE_KIND_SPECULAR

/* The first image's indirect leaves (cache_refine_desc.first_image): only those
 * of at least this share of the pixels seen (priority pixels·(1 + ΔE)). */
#define FIRST_IMAGE_LEAF_SHARE (1.0 / 256.0)

/* ---- one round ---------------------------------------------------------------- */

/* Is fresh − interp (the midpoint's gather against the mean of the edge's ends)
 * more than CACHE_NOISE_SIGMAS standard errors of that difference in some channel? */
static int beyond_noise(const cache *c, uint32_t a, uint32_t b, uint32_t mid, const float fresh[3],
                        const float interp[3])
{
    float sa[3], sb[3], sm[3];
    cache_indirect_sigma(c, a, sa);
    cache_indirect_sigma(c, b, sb);
    cache_indirect_sigma(c, mid, sm);
    for (int ch = 0; ch < 3; ++ch) {
        float sd = sqrtf(sm[ch] * sm[ch] + 0.25f * (sa[ch] * sa[ch] + sb[ch] * sb[ch]));
        if (fabsf(fresh[ch] - interp[ch]) > CACHE_NOISE_SIGMAS * sd) return 1;
    }
    return 0;
}

/* The part of an indirect midpoint's ΔE that noise explains: the ΔE of the
 * difference's likely standard error (beyond_noise's, the strata counted: the
 * estimate's), on the interpolated value.
 * The leaf's interpolation error is the rest, in quadrature (E[d²] = true² + σ²),
 * so that noisy values do not count twice in the estimate (cache_estimate.c adds
 * the noise of its own). */
static float noise_delta_e(const cache *c, uint32_t tri, const float background[CACHE_KINDS][3], uint32_t a,
                           uint32_t b, uint32_t mid, const float interp[3], const float lab_interp[3])
{
    float sa[3], sb[3], sm[3], up[3], lab[3];
    cache_indirect_likely_sigma(c, a, sa);
    cache_indirect_likely_sigma(c, b, sb);
    cache_indirect_likely_sigma(c, mid, sm);
    for (int ch = 0; ch < 3; ++ch)
        up[ch] = interp[ch] + sqrtf(sm[ch] * sm[ch] + 0.25f * (sa[ch] * sa[ch] + sb[ch] * sb[ch]));
    cache_seen_lab_over(c, KIND_INDIRECT, tri, background, up, lab);
    return tm_delta_e(lab, lab_interp);
}

/* A leaf's priority (cache_leaf_priority: pixels × (1 + its corners' ΔE);
 * cache_unseen_priority) predicts what its test removes, but not equally well for
 * every mesh: an untested leaf of uniform wall is counted at one ΔE a pixel and
 * its test usually finds nothing, while a specular leaf across a highlight's
 * rim finds most of its contrast. The heap scheduler weighs each mesh's top
 * priority by what that mesh's tests have removed per unit of the priority they
 * were picked at, its yield (cache_sched_yield): a running ratio in which each round
 * counts YIELD_MEMORY less a round after (1 until the mesh's first round since
 * its queue was last made: schedule_leaves).
 * Measured on the Cornell boxes and the Veach door (docs/cache.md, "Meshes
 * weighed by what their tests remove"). */
#define YIELD_MEMORY 0.8

typedef struct round_leaf {
    uint32_t node;
    uint32_t mirror;            /* single mesh: the indirect node split along with it */
    uint32_t mid[3];            /* vtable ids of the midpoints of edges 01, 12, 20 */
    float picked;               /* the priority it was picked at (cache_sched_yield) */
    double mw1[3], mw2[3];      /* their barycentrics */
    double cw1[3], cw2[3];      /* the corners' */
} round_leaf;

/* Does a surface stand between two corners of node n (samp_points_parted)? */
int cache_corners_parted(const cache *c, const mesh_qnode *n)
{
    samp_point p[3];
    for (int k = 0; k < 3; ++k) p[k] = cache_vertex_point(c, n->v[k]);
    for (int k = 0; k < 3; ++k)
        if (samp_points_parted(c->sp, &p[k], &p[(k + 1) % 3])) return 1;
    return 0;
}

/* How much splitting direct leaf n moves the indirect source's power: the
 * source is kd·L_dd linear over the leaves, so the four children hold
 * A/12·(Σ corners + 3·Σ midpoints) against the leaf's A/3·Σ corners, a change
 * of A/4·(Σ midpoints − Σ corners) a channel (A: the leaf's area). Channels
 * averaged, as a magnitude. */
static double split_power_change(const cache *c, const mesh_qmesh *m, const mesh_qnode *n, const uint32_t corner[3],
                                 const uint32_t mid[3])
{
    const float *kd = c->s->materials[c->s->tris[n->tri].material].kd;
    const double A = c->s->tri_areas[n->tri] / (double)(1ull << (2 * n->depth));
    double sum[3] = {0, 0, 0};
    for (int k = 0; k < 3; ++k) {
        float a[3] = {0, 0, 0}, b[3] = {0, 0, 0};
        mesh_qmesh_get_value(m, mid[k], a);
        mesh_qmesh_get_value(m, corner[k], b);
        for (int ch = 0; ch < 3; ++ch) sum[ch] += (double)a[ch] - b[ch];
    }
    double d = 0.0;
    for (int ch = 0; ch < 3; ++ch) d += fabs(A / 4.0 * kd[ch] * sum[ch]) / 3.0;
    return d;
}

/* The source's power: Σ area × mean radiance over its triangles (channels and
 * corners averaged). */
static double source_power(const cache *c)
{
    const samp_radiance_mesh *sm = &c->src.rmesh;
    double P = 0.0;
    for (uint32_t t = 0; sm->first && t < c->s->tri_count; ++t)
        for (uint32_t i = sm->first[t]; i < sm->first[t + 1]; ++i) {
            const float *b = sm->bary + 6 * (size_t)i, *L = sm->radiance + 9 * (size_t)i;
            const double share = fabs((double)(b[2] - b[0]) * (b[5] - b[1]) - (double)(b[4] - b[0]) * (b[3] - b[1]));
            double mean = 0.0;
            for (int q = 0; q < 9; ++q) mean += L[q] / 9.0;
            P += c->s->tri_areas[t] * share * mean;
        }
    return P;
}

/* May the first image's owed indirect work start (cache_sched.owed_wait)? Once
 * a window of OWED_WINDOW direct leaf tests (one worker step) has moved the
 * source's power by less than the relative error the JND allows at mid-grey (a
 * relative error ε there is about 22·ε ΔE: docs/cache.md, "The slot, looked
 * at"): gathered before, the values would draw from a source about to move. On
 * the Veach door the first window after the first image moved it by 35% (the
 * strip of lamp light the door lets onto the floor, the near room's main
 * source), and values gathered before it were nearly all gathered again (2,197
 * of about 2,600); on Water 6.7-7.1%, on CornellBox-Original 3.2%
 * (docs/cache.md, "The owed work after the source settles"). Called at the
 * start of each refine call; the first window only measures. */
enum { OWED_WINDOW = 512 };
static void owed_may_start(cache *c, const cache_refine_desc *desc, uint32_t budget)
{
    cache_sched *st = &c->sched;
    if (!st->owed_wait) return;
    /* A caller that holds the leaves back until the owed values are gathered
     * (wait_for_indirect), or doles out fewer leaves than a window (a worker at
     * its max_tested: only the owed work is left), gets the owed work first. */
    if (desc->wait_for_indirect || budget < OWED_WINDOW) {
        st->owed_wait = 0;
        return;
    }
    if (st->owed_tested < OWED_WINDOW) return; /* not enough direct tests yet to say */
    {
        const double P = source_power(c);
        if (!(P > 0.0) || st->source_moved < P * (double)c->desc.jnd / 22.0) st->owed_wait = 0;
    }
    st->owed_tested = 0;
    st->source_moved = 0.0;
}

static lm_result refine_round(cache *c, refine_kind kind, const uint32_t *pixels, uint32_t max_leaves,
                              cache_refine_result *res, lm_error *err)
{
    mesh_qmesh *m = cache_kind_mesh(c, kind);
    round_leaf leaves[ROUND_LEAVES];
    uint32_t nl = 0;
    lm_result r = LM_OK;
    /* The size criterion is there to find small discontinuities (shadow edges);
     * indirect irradiance is smooth, so its leaves stop CACHE_INDIRECT_SIZE_FACTOR
     * times larger unless the ΔE test asks for more (measured on the built-in
     * Cornell box: with the same floor, indirect samples were 28% of all and took
     * 98% of the sampler time). */
    float min_pixels = c->desc.min_leaf_pixels * (kind == KIND_INDIRECT ? CACHE_INDIRECT_SIZE_FACTOR : 1.0f);

    /* Pick and split tentatively. */
    uint32_t node;
    float picked = 0.0f;
    while (nl < max_leaves && nl < ROUND_LEAVES && r == LM_OK && cache_sched_pick(c, kind, pixels, &node, &picked)) {
        const mesh_qnode *n = mesh_qmesh_node(m, node);
        double cw1[3], cw2[3];
        for (int k = 0; k < 3; ++k) cache_node_corner_bary(n, k, &cw1[k], &cw2[k]);
        r = mesh_qmesh_split(m, node, err);
        if (r == LM_ERR_NO_MEMORY || r == LM_ERR_UNSUPPORTED) {
            res->remaining = (uint32_t)(c->sched.waiting[0] + c->sched.waiting[1] + c->sched.waiting[2]);
            return r; /* cap or depth: refinement stops here, the cache stays valid */
        }
        if (r != LM_OK) break;
        n = mesh_qmesh_node(m, node);
        if (c->desc.scheduler == CACHE_SCHED_RANDOM) {
            /* Child ids are recycled: clear what earlier nodes left there, so no
             * stale priority leads a descent into this node while it is tested. */
            r = cache_sched_grow_prio(c, kind, n->child + 3, err);
            if (r != LM_OK) break;
            for (uint32_t k = 0; k < 4; ++k) c->sched.prio[kind][n->child + k] = 0.0f;
        }
        const mesh_qnode *centre = mesh_qmesh_node(m, n->child + 3); /* (m01, m12, m20) */
        round_leaf *rl = &leaves[nl++];
        rl->node = node;
        rl->picked = picked;
        rl->mirror = MESH_QMESH_NONE;
        if (kind == KIND_DIRECT && c->desc.single_mesh) {
            /* One combined mesh: the indirect mesh follows the direct one split for
             * split (same addresses, so the same vertices). */
            double cx = (cw1[0] + cw1[1] + cw1[2]) / 3.0, cy = (cw2[0] + cw2[1] + cw2[2]) / 3.0;
            uint32_t mir = cache_find_leaf(c->indirect, n->tri, cx, cy);
            if (mir != MESH_QMESH_NONE && mesh_qmesh_node(c->indirect, mir)->depth == n->depth &&
                mesh_qmesh_split(c->indirect, mir, err) == LM_OK)
                rl->mirror = mir;
        }
        for (int k = 0; k < 3; ++k) {
            rl->cw1[k] = cw1[k];
            rl->cw2[k] = cw2[k];
            rl->mid[k] = centre->v[k];
            rl->mw1[k] = 0.5 * (cw1[k] + cw1[(k + 1) % 3]);
            rl->mw2[k] = 0.5 * (cw2[k] + cw2[(k + 1) % 3]);
        }
    }
    if (r != LM_OK || nl == 0) return r;
    /* Values at the midpoints that have none yet, in one batch. */
    cache_site sites[3 * ROUND_LEAVES];
    uint32_t like[3 * ROUND_LEAVES]; /* indirect: the edge's end with the more rays */
    uint32_t ns = 0;
    for (uint32_t i = 0; i < nl; ++i) {
        const mesh_qnode *n = mesh_qmesh_node(m, leaves[i].node);
        for (int k = 0; k < 3; ++k) {
            float tmp[3];
            if (mesh_qmesh_get_value(m, leaves[i].mid[k], tmp) == 1) continue;
            int dup = 0;
            for (uint32_t j = 0; j < ns && !dup; ++j) dup = sites[j].vid == leaves[i].mid[k];
            if (dup) continue;
            const uint32_t a = n->v[k], b = n->v[(k + 1) % 3];
            like[ns] = kind == KIND_INDIRECT && cache_gather_level(c, b) > cache_gather_level(c, a) ? b : a;
            sites[ns++] = (cache_site){leaves[i].mid[k], n->tri, leaves[i].mw1[k], leaves[i].mw2[k], n->depth};
        }
    }
    float *vals = malloc(3 * (size_t)(ns ? ns : 1) * sizeof *vals);
    int from_lights = kind != KIND_INDIRECT;
    uint32_t *vids = malloc((ns ? ns : 1) * sizeof *vids);
    if (!vals || !vids) r = lm_fail(err, LM_ERR_NO_MEMORY, "out of memory refining");
    for (uint32_t i = 0; r == LM_OK && i < ns; ++i) vids[i] = sites[i].vid;
    if (r == LM_OK && from_lights) {
        r = cache_light_values(c, kind, sites, ns, vals, err);
        if (r == LM_OK && kind == KIND_DIRECT && c->desc.single_mesh) {
            /* The combined mesh gathers indirect light at every new vertex. */
            float *E = malloc(3 * (size_t)(ns ? ns : 1) * sizeof *E);
            uint32_t *need = malloc((ns ? ns : 1) * sizeof *need), nn = 0;
            float tmp[3];
            for (uint32_t i = 0; i < ns && need; ++i)
                if (mesh_qmesh_vertex_use(c->indirect, vids[i]) && mesh_qmesh_get_value(c->indirect, vids[i], tmp) != 1)
                    need[nn++] = vids[i];
            r = E && need ? cache_sample_indirect(c, need, nn, E, err)
                          : lm_fail(err, LM_ERR_NO_MEMORY, "out of memory refining");
            for (uint32_t i = 0; r == LM_OK && i < nn; ++i)
                r = mesh_qmesh_set_value(c->indirect, need[i], E + 3 * (size_t)i, err);
            free(E);
            free(need);
        }
    } else if (r == LM_OK) {
        /* A midpoint is compared with its edge's ends: gathered with at least the
         * rays of the one with more, or the edges of leaves whose corners were
         * gathered again for their noise (cache_requeue_noisy) are tested again with
         * midpoints as noisy as before, and a real difference still passes as
         * noise (the slot test, docs/cache.md "Guided gathers"). */
        r = cache_sample_indirect_like(c, vids, like, ns, vals, err);
    }
    for (uint32_t i = 0; r == LM_OK && i < ns; ++i) r = mesh_qmesh_set_value(m, vids[i], vals + 3 * (size_t)i, err);
    free(vals);
    free(vids);
    /* What the new visible gathers draw from: the source is refined there. */
    if (r == LM_OK && kind == KIND_INDIRECT) r = cache_unseen_schedule_important(c, sites, ns, pixels, err);

    /* Edge tests: keep or undo. What the kept splits removed (pixels × their
     * midpoints' ΔE; an unseen source leaf's change as the viewer sees it),
     * against the priorities the leaves were picked at (cache_sched_yield). */
    double predicted = 0.0, removed = 0.0;
    for (uint32_t i = 0; r == LM_OK && i < nl; ++i) {
        const mesh_qnode *n = mesh_qmesh_node(m, leaves[i].node);
        uint32_t tri = n->tri, corner[3] = {n->v[0], n->v[1], n->v[2]}, child = n->child;
        float px = cache_leaf_pixels(pixels, n);
        int found = 0;
        /* The leaf's interpolation error: the mean of its midpoints' ΔE (the mean
         * over a triangle of a quadratic that is 0 at the corners is the mean of
         * its three midpoint values); for indirect values in quadrature, less
         * what their noise explains (E[d²] = true² + σ²). */
        float sum_de = 0.0f, sum_de2 = 0.0f, sum_dn2 = 0.0f;
        int tested_mid = 0;
        int combined = leaves[i].mirror != MESH_QMESH_NONE;
        int unseen = cache_unseen_leaf(pixels, kind, n);
        float seen_change = 0.0f; /* unseen: what its split changes on screen */
        if (unseen) {
            found = cache_unseen_split_seen(c, leaves[i].node, n, leaves[i].mid, &seen_change);
            px = 0.0f;
        }
        for (int k = 0; k < 3 && !found && !unseen; ++k) {
            float a[3], b[3], fresh[3], interp[3], lf[3], li[3], background[CACHE_KINDS][3];
            float interp_seen[3], de_seen = 0.0f; /* where judged: cache_midpoint_seen_de */
            mesh_qmesh_get_value(m, corner[k], a);
            mesh_qmesh_get_value(m, corner[(k + 1) % 3], b);
            mesh_qmesh_get_value(m, leaves[i].mid[k], fresh);
            for (int ch = 0; ch < 3; ++ch) interp[ch] = 0.5f * (a[ch] + b[ch]);
            /* A highlight drawn per pixel: the picture at the midpoint is not the
             * ends' interpolation but the lobe's own integral there (its rim is
             * the renderer's to draw, not the leaves': docs/renderer.md). */
            if (kind == KIND_SPECULAR) cache_specular_drawn(c, corner[k], corner[(k + 1) % 3], leaves[i].mid[k], interp);
            if (combined) {
                /* One mesh holds everything: fresh direct and indirect against both
                 * interpolated from the edge's ends. */
                float ea[3], eb[3], ef[3], ei[3];
                mesh_qmesh_get_value(c->indirect, corner[k], ea);
                mesh_qmesh_get_value(c->indirect, corner[(k + 1) % 3], eb);
                mesh_qmesh_get_value(c->indirect, leaves[i].mid[k], ef);
                for (int ch = 0; ch < 3; ++ch) ei[ch] = 0.5f * (ea[ch] + eb[ch]);
                cache_seen_lab(c, tri, fresh, ef, NULL, lf); /* L_ds left out, as before */
                cache_seen_lab(c, tri, interp, ei, NULL, li);
                de_seen = tm_delta_e(lf, li);
            } else {
                const int e = (k + 1) % 3;
                const double pw1[3] = {leaves[i].mw1[k], leaves[i].cw1[k], leaves[i].cw1[e]};
                const double pw2[3] = {leaves[i].mw2[k], leaves[i].cw2[k], leaves[i].cw2[e]};
                cache_edge_background(c, kind, tri, pw1, pw2, background);
                float opposite[3];
                mesh_qmesh_get_value(m, corner[(k + 2) % 3], opposite);
                de_seen = cache_midpoint_seen_de(c, kind, tri, (const float(*)[3])background, fresh, interp, a, b,
                                                 opposite, interp_seen, li);
            }
            float de = de_seen * cache_pixel_share(px);
            found = de > c->desc.jnd;
            tested_mid++;
            sum_de += de;
            sum_de2 += de * de;
            if (kind == KIND_INDIRECT && !combined) {
                float dn = cache_pixel_share(px) * noise_delta_e(c, tri, (const float(*)[3])background, corner[k],
                                                                 corner[(k + 1) % 3], leaves[i].mid[k], interp_seen, li);
                sum_dn2 += dn * dn;
            }
            /* Indirect values are noisy estimates: a difference the noise explains
             * (within CACHE_NOISE_SIGMAS standard errors in every channel) splits nothing. */
            if (found && kind == KIND_INDIRECT && !combined)
                found = beyond_noise(c, corner[k], corner[(k + 1) % 3], leaves[i].mid[k], fresh, interp);
        }
        float interp_err = 0.0f;
        if (tested_mid)
            interp_err = kind == KIND_INDIRECT && !combined ? sqrtf(fmaxf(sum_de2 - sum_dn2, 0.0f) / (float)tested_mid)
                                                       : sum_de / (float)tested_mid;
        res->tested++;
        if (kind == KIND_DIRECT && c->sched.owed_wait) c->sched.owed_tested++;
        /* A surface standing on the leaf between two of its corners (a wall on a
         * floor that runs on under it into the next room, a box on the floor)
         * makes their interpolation a leak, whatever the midpoints say: the
         * midpoint under the wall gathers nothing, and a corner beyond it the next
         * room's light, which the noise of a gather through the gap may explain.
         * Such a leaf splits while it is bigger than the direct mesh's size floor,
         * as a shadow's edge does (the Veach door's floor: a wedge of the lamp
         * room's E_i = 87 on the near room's floor, docs/cache.md). One ray an edge. */
        if (!found && !unseen && kind == KIND_INDIRECT && !combined && px > c->desc.min_leaf_pixels &&
            cache_corners_parted(c, n))
            found = 1;
        predicted += leaves[i].picked;
        if (found || px > min_pixels) {
            if (kind == KIND_DIRECT && c->sched.owed_wait) c->sched.source_moved += split_power_change(c, m, n, corner, leaves[i].mid);
            removed += unseen ? (double)seen_change : (double)px * interp_err;
            res->split++;
            uint32_t gen = unseen && cache_unseen_all_dark(c, n, leaves[i].mid)
                               ? cache_unseen_dark_generations(c, leaves[i].node) + 1
                               : 0;
            for (uint32_t k = 0; r == LM_OK && k < 4; ++k) {
                const mesh_qnode *ch = mesh_qmesh_node(m, child + k);
                /* Every child of the direct mesh, seen or not: a node id comes back
                 * after a merge, and a leaf seen now may be unseen after a move. */
                if (kind == KIND_DIRECT) r = cache_unseen_set_dark_generations(c, child + k, gen, err);
                if (r == LM_OK) r = cache_sched_set_residual(c, kind, child + k, 0.25f * interp_err, 0, err);
                if (r == LM_OK)
                    r = cache_sched_add(c, kind, child + k, cache_leaf_priority(c, m, kind, child + k, ch, pixels), err);
            }
        } else {
            r = mesh_qmesh_merge(m, leaves[i].node, err);
            if (r == LM_OK && combined) r = mesh_qmesh_merge(c->indirect, leaves[i].mirror, err);
            if (r == LM_OK) r = cache_sched_done(c, kind, leaves[i].node, err);
            if (r == LM_OK) r = cache_sched_set_residual(c, kind, leaves[i].node, interp_err, 1, err);
            res->undone++;
            c->sched.undone++;
        }
    }
    if (r == LM_OK && predicted > 0.0) {
        cache_sched *st = &c->sched;
        st->removed[kind] = YIELD_MEMORY * st->removed[kind] + removed;
        st->predicted[kind] = YIELD_MEMORY * st->predicted[kind] + predicted;
    }
    return r;
}

/* What a leaf test costs besides its samples, in rays (cache.effort): its tree
 * descents, tone mapping and bookkeeping. Measured on the Veach door: a direct
 * leaf test took 17 µs with its light samples (64 points each), a gather of
 * 1,024 rays about 0.6 ms, so a ray is about 0.6 µs and 32 of them the order of
 * a test that samples nothing. */
#define LEAF_BASE_RAYS 32.0

/* Smoothed rays a leaf test of `kind` takes (cache_sched.leaf_rays). */
static void note_leaf_cost(cache *c, int kind, double rays)
{
    double *s = &c->sched.leaf_rays[kind];
    *s = *s > 0.0 ? 0.8 * *s + 0.2 * rays : rays;
}

double cache_sched_yield(const cache *c, cache_kind kind)
{
    const cache_sched *st = &c->sched;
    return st->predicted[kind] > 0.0 ? st->removed[kind] / st->predicted[kind] : 1.0;
}

/* A mesh's top priority times its yield per ray of its leaf tests; INFINITY
 * before its cost is known. */
static double kind_rate(const cache *c, int k)
{
    const double cost = c->sched.leaf_rays[k];
    return cost > 0.0 ? (double)cache_sched_top_priority(c, k) * cache_sched_yield(c, (cache_kind)k) / cost : INFINITY;
}

/* The mesh the heap scheduler tests next, or -1 when no leaf is waiting or the
 * budget is spent: the highest top priority (pixels × ΔE its test may remove)
 * times its mesh's yield (what its tests have removed per unit of priority:
 * cache_sched_yield, YIELD_MEMORY), per ray a leaf test of that mesh takes
 * (cache.effort). One budget of leaves a
 * call, shared by cost: on the Veach door a direct leaf (light samples) took
 * 17 µs and an indirect one (gathers of up to 4,096 rays) 2.4 ms; fixed shares of
 * the leaves (a fifth to indirect) gave the gathers 70% of the time and left the
 * door's strip of direct light waiting (docs/cache.md, "Leaves shared by cost").
 * A mesh not tested yet goes first, so that its cost is known. */
static int next_kind(const cache *c, uint32_t total_left, int indirect_too)
{
    if (!total_left) return -1;
    int best = -1;
    double best_rate = -1.0;
    for (int k = 0; k < CACHE_KINDS; ++k) {
        if (!c->sched.waiting[k] || !cache_kind_mesh(c, (cache_kind)k)) continue;
        if (k == KIND_INDIRECT && !indirect_too) continue;
        const double rate = kind_rate(c, k);
        if (rate > best_rate) best = k, best_rate = rate;
    }
    return best;
}

/* next_kind's best rate over the meshes with leaves waiting; 0: none waits. */
static double best_leaf_rate(const cache *c)
{
    double best = 0.0;
    for (int k = 0; k < CACHE_KINDS; ++k)
        if (c->sched.waiting[k] && cache_kind_mesh(c, (cache_kind)k)) best = fmax(best, kind_rate(c, k));
    return best;
}

lm_result cache_sched_refine(cache *c, const cache_refine_desc *desc, cache_refine_result *out, lm_error *err)
{
    cache_refine_result res = {0};
    lm_result r = LM_OK;
    for (int k = 0; r == LM_OK && k < CACHE_KINDS; ++k)
        if (!c->sched.seeded || c->sched.requeue[k])
            r = cache_sched_schedule(c, (refine_kind)k, desc->pixels, desc->seen_only && !c->sched.seeded, err);
    c->sched.seeded = 1;
    uint32_t budget = desc->budget ? desc->budget : 256;
    /* The random scheduler (§4.3.3): direct light first; indirect (smoother,
     * dearer samples) and specular get a fifth of the leaves each; what a missing
     * mesh would get goes to direct. The heap scheduler shares the budget by
     * cost instead (next_kind). */
    uint32_t fifth = budget / 5 ? budget / 5 : 1;
    uint32_t left[CACHE_KINDS] = {0, fifth, c->specular ? fifth : 0};
    left[KIND_DIRECT] = budget > left[1] + left[2] ? budget - left[1] - left[2] : 1;
    const int by_cost = c->desc.scheduler != CACHE_SCHED_RANDOM;
    uint32_t total_left = budget;
    /* Values a rebuilt source moved are gathered again, at most desc->regather
     * (CACHE_REGATHER_PER_LEAF per leaf of the budget) in one call: a big scene's first rebuild can flag
     * most of its hundreds of thousands of values, and one call is one step of the
     * worker (the first image waits for the first). What is left waits for the
     * next call, which does nothing else until it is done. */
    uint64_t allowance = desc->regather ? desc->regather : (uint64_t)CACHE_REGATHER_PER_LEAF * budget;
    /* Glossy parts taken again: a glossy gather is CACHE_GLOSSY_RAYS to 4,096
     * rays, counted by 256 (cache_glossy_refresh); an indirect one ~1,024. None
     * in the rounds before the first image: there they cost Water 8 ms of its
     * ~100 and changed its first image by mean ΔE 0.009 (1.893 -> 1.902 against
     * the reference; the 0.25 s snapshot the same), Glossy's by 0.11 and the
     * 116k box's by 0.004 (docs/cache.md, "The first snapshot without an
     * estimate"); the calls after it take them. */
    uint64_t glossy_allowance = desc->first_image ? 0 : 16 * allowance;
    /* The first image's borrowed direct and specular roots (cache_first.c),
     * sixteen a value gathered again (a light sample costs about a fifteenth of
     * a gather on the 116k box; at one a value, the box's leaf tests waited 30 s
     * for them): their light is sampled and the values recomputed by the
     * revision below, before the indirect values are gathered from them. */
    owed_may_start(c, desc, budget);
    if (r == LM_OK) r = cache_borrowed_to_regions(c, 16 * allowance, err);
    /* Values a rebuild left unbounded while unseen, seen now (a camera move). */
    if (r == LM_OK) r = cache_refresh_stale(c, desc->pixels, err);
    /* Changes made outside refinement (coarse cache, a camera move). */
    if (r == LM_OK) r = cache_requeue_revise(c, desc->pixels, &allowance, &glossy_allowance, err);
    int settled = 0, finer = 0;
    /* Quieter values compete with the leaf tests, once a call, by the visible
     * error they remove per ray (cache_requeue_noisy against next_kind's rate):
     * left until nothing was left to test, they never came on the Veach door,
     * whose queue the source's drift keeps filling, and its indirect noise
     * stayed (13% of the pixels above the JND at 30 s, the estimate's noise
     * 0.43 ΔE of its 0.71; docs/cache.md, "Quieter values by their rate"). */
    if (r == LM_OK && by_cost && !desc->first_image && !c->src.outdated_n && !cache_borrow_pending(c)) {
        /* The look walks every visible indirect leaf: after one that found no
         * value worth its rays the next waits 1, 2, 4, ... calls (the 116k box,
         * whose noise never wins: 10% longer to converge with a look a call). */
        if (c->sched.noisy_skip) {
            c->sched.noisy_skip--;
        } else {
            const uint32_t before = res.regathered_finer;
            r = cache_requeue_noisy(c, desc->pixels, budget, best_leaf_rate(c), &res.regathered_finer, err);
            finer = res.regathered_finer > before;
            c->sched.noisy_wait = finer ? 0 : c->sched.noisy_wait ? 2 * c->sched.noisy_wait : 1;
            if (c->sched.noisy_wait > NOISY_WAIT_MAX) c->sched.noisy_wait = NOISY_WAIT_MAX;
            c->sched.noisy_skip = c->sched.noisy_wait;
        }
    }
    /* No leaf is tested while values it would be judged by are still the first
     * image's (its borrowed direct and specular roots). Indirect values still
     * to be gathered (borrowed by the first image, or flagged by a rebuilt
     * source) hold back only the indirect leaves: the direct and specular ones
     * are judged over them as they are, and tested meanwhile. Held back too, the
     * Veach door's floor under its back wall showed the lamp room's direct light
     * (a leaf with a corner there) for the 0.6 s the first image's indirect
     * values took (docs/cache.md, "Guided gathers"). */
    const size_t borrowed = c->vis.borrowed_released ? cache_borrowed_waiting(c) : 0;
    while (r == LM_OK && !borrowed && !cache_stopping(c)) {
        const int indirect_too = !c->src.outdated_n && !cache_borrow_pending(c);
        int kind = by_cost ? next_kind(c, total_left, indirect_too) : -1;
        for (int k = 0; k < CACHE_KINDS && kind < 0 && !by_cost; ++k)
            if (left[k] && c->sched.waiting[k] && (k != KIND_INDIRECT || indirect_too)) kind = k;
        if (kind < 0 && !indirect_too) break; /* the rest waits for the regathers */
        if (!indirect_too && desc->wait_for_indirect) break;
        if (kind < 0) {
            if (c->sched.waiting[0] + c->sched.waiting[1] + c->sched.waiting[2] > 0) break; /* out of budget */
            /* Nothing left to test: bring the indirect source up to date with the
             * direct mesh (indirect values it moves are gathered again and their
             * leaves tested); then gather again, with more rays, the values whose
             * noise the estimate still sees, once per call (their leaves are tested
             * again by the next call). */
            if (!settled) {
                settled = 1;
                r = cache_settle_source(c, err);
                if (r == LM_OK) r = cache_requeue_revise(c, desc->pixels, &allowance, &glossy_allowance, err);
                continue;
            }
            if (finer) break;
            finer = 1;
            r = cache_requeue_noisy(c, desc->pixels, budget, 0.0, &res.regathered_finer, err);
            continue;
        }
        uint32_t before = res.tested;
        const uint64_t effort = c->effort;
        r = refine_round(c, (refine_kind)kind, desc->pixels, by_cost ? total_left : left[kind], &res, err);
        if (res.tested > before)
            note_leaf_cost(c, kind, (double)(c->effort - effort) / (double)(res.tested - before) + LEAF_BASE_RAYS);
        /* The round's light fetches may have found uniform light leaves that were
         * not, and its gathers a rebuilt source that moved older indirect values:
         * recompute those values (cache_light.c) and test their leaves again. */
        if (r == LM_OK) r = cache_requeue_revise(c, desc->pixels, &allowance, &glossy_allowance, err);
        uint32_t used = res.tested - before;
        left[kind] = used == 0 || used >= left[kind] ? 0 : left[kind] - used;
        total_left = used >= total_left ? 0 : total_left - used;
        if (by_cost && used == 0) c->sched.waiting[kind] = 0; /* nothing it could test: not picked again */
    }
    /* The first image's indirect leaves (cache_refine_desc.first_image): the
     * source the first gathers drew from was built before the rounds above
     * split the direct mesh where the light is (Water's walls: root corners
     * grazing the lamp or under the water, dark), and the indirect leaves wait
     * while the first image's values are owed, so a surface lit only
     * indirectly stayed dark until the regathers after the first image were
     * done (0.5 s). A fifth of the budget, as the random scheduler gives
     * indirect leaves (§4.3.3), and only to leaves of a visible share of the
     * picture (FIRST_IMAGE_LEAF_SHARE: big surfaces that a few corners
     * misrepresent; where the queue holds none, the source is not rebuilt
     * either: 33-40 ms on the 116k box, whose room's walls do qualify);
     * leaves a surface parts are set aside (pick_leaf). */
    double seen = 0.0;
    for (uint32_t t = 0; desc->first_image && desc->pixels && t < c->s->tri_count; ++t) seen += desc->pixels[t];
    const float floor_priority = (float)(seen * FIRST_IMAGE_LEAF_SHARE);
    const cache_queue *iq = &c->sched.q[KIND_INDIRECT];
    const int big_leaves = !by_cost || (iq->n && iq->e[0].priority >= floor_priority); /* the heap's top (or stale) */
    if (r == LM_OK && desc->first_image && big_leaves && !cache_stopping(c)) {
        r = cache_settle_source(c, err);
        c->sched.pick_floor = floor_priority;
        c->sched.first_image_round = 1;
        if (r == LM_OK) r = refine_round(c, KIND_INDIRECT, desc->pixels, fifth, &res, err);
        c->sched.first_image_round = 0;
        c->sched.pick_floor = 0.0f;
        /* The leaves set aside (pick_leaf) wait in the queue as before. */
        cache_queue *aside = &c->sched.set_aside;
        while (r == LM_OK && aside->n) {
            cache_queue_entry e = cache_queue_pop(aside);
            r = cache_queue_push(&c->sched.q[KIND_INDIRECT], e.priority, e.node, e.v0, err);
            if (r == LM_OK) c->sched.waiting[KIND_INDIRECT]++;
        }
        aside->n = 0;
    }
    /* Values still waiting to be gathered again count as work left. */
    res.outdated = (uint32_t)(c->src.outdated_n + (c->vis.borrowed_released ? cache_borrowed_waiting(c) : 0) +
                              cache_borrow_pending(c) + cache_glossy_waiting(c));
    res.remaining = (uint32_t)(c->sched.waiting[0] + c->sched.waiting[1] + c->sched.waiting[2] + res.outdated);
    /* Stopped (cache_refine_desc.stop): no claim, the settling may not have run. */
    if (r == LM_OK && res.remaining == 0 && res.regathered_finer == 0 && !cache_stopping(c)) {
        r = cache_estimate_error(c, desc->pixels, &res.estimate, err);
        res.estimated = r == LM_OK;
        res.converged = r == LM_OK && cache_estimate_converged(&res.estimate);
        res.stuck = r == LM_OK && !res.converged;
    }
    if (out) *out = res;
    return r;
}
