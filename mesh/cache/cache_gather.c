/* cache_gather.c — the displayed indirect values' gathers (cache.h, eq. 7),
 * split from cache_source.c (it had grown past 1,100 lines): the pilot each
 * gather traces (where its light comes from, its noise, whether it goes toward
 * the source), the gathers at their ray counts (the plain count, or finer ones
 * for noise, each finer one guided by a pilot of its own), and the values'
 * standard errors and levels. Writes cache_source_state's pilot, sigma,
 * gather level and drift entries of the values it gathers (cache_internal.h);
 * the source itself is built by cache_source.c (cache_update_radiance_source).
 * Worker thread, like the rest of the cache. */
#include "mesh/cache/cache_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "mesh/geomesh.h"
#include "sampling/samp.h"
#include "src/base/vecmath.h"

/* ---- gathers ----------------------------------------------------------------------
 *
 * A displayed indirect value knows its noise. A pilot of CACHE_IMPORTANCE_RAYS
 * rays (samp_indirect_sources, a stream of its own; the same trace records
 * importance) says which source triangles the point sees and how much of its
 * hemisphere each fills; with their mean radiance that gives the variance of one
 * ray's radiance, hence the standard error σ(N) = π·√(var/N) of an N-ray gather.
 * The point is gathered with the plain rays (or the level its caller asks for:
 * a midpoint as precise as its edge's ends, a value taken again), and
 * cache_regather_finer takes it again with GATHER_SCALE times the rays, up to
 * GATHER_FINER_LEVELS, where the cache's error estimate says its noise is still
 * seen (cache_estimate.c). Choosing the first count up front instead (the fewest
 * rays for which E ± σ could not be told from E through the tone map, up to 16×)
 * spent the first seconds on precise values where the picture's structure was
 * not there yet: the Veach door measured relMSE 0.54 / 0.28 at 2.3 / 3.5 s against
 * 0.28 / 0.11 with the plain count first (docs/cache.md, "Guided gathers").
 * Chosen from the gather's own estimate, a count biased the values low: a gather
 * whose rays all missed a gap has E = σ = 0 and was never taken again, while
 * lucky ones were pulled back (docs/cache.md, cause 5); the estimate's noise
 * comes from the pilot, independent of the value. The σ kept per value is the
 * pilot's prediction for the rays taken (the gather's own sample variance is as
 * blind as its mean to a gap all its rays missed). */
/* A point whose pilot says its light comes through a gap is gathered toward the
 * source (samp_point.toward_source): when the variance of one pilot ray's π·L is
 * more than GATHER_GAP_RATIO times E² (light uniform over a fraction p of the
 * cosine-weighted hemisphere gives (1 − p)/p: a fifth of it or less), or the
 * pilot found no light at all. Elsewhere the stratified cosine rays are better. */
#define GATHER_GAP_RATIO 4.0
enum { GATHER_SCALE = 4, GATHER_FINER_LEVELS = 4 };
/* A gather finer than the plain count that goes toward the source is guided by a
 * pilot of its own with as many rays as it (k × k strata, k a power of two, at
 * most GUIDE_K_MAX), not by the 16 × 16 one every gather traces: a slit fills
 * a handful of the coarse strata, and only in part (samp_guide_mass dilates
 * each by its neighbours), so most guided rays met the wall beside it. The
 * slot's receivers, 32 gathers each, variance summed against the coarse guide,
 * and rays a value counting the pilot (docs/cache.md, "Finer gathers, finer
 * guides"): 1,024-ray gathers 0.31 (k = 32) and 0.12 (k = 64); 4,096-ray 0.32
 * and 0.14; 16,384-ray 0.35 and 0.16, so the pilot's rays pay for themselves
 * 2-5 times over. Not at the plain count: there it would double the rays of the
 * first regathers, whose time decides the Veach door's 2 s picture. */
enum { CACHE_PILOT_K = 16, GUIDE_K_MAX = 64, GUIDE_RAYS_MAX = GUIDE_K_MAX * GUIDE_K_MAX, GUIDE_BATCH = 64 };
_Static_assert(CACHE_IMPORTANCE_RAYS == CACHE_PILOT_K * CACHE_PILOT_K, "the pilot's strata: k × k rays");

void cache_indirect_likely_sigma(const cache *c, uint32_t vid, float out[3])
{
    if (vid < c->src.drift_cap && c->src.sigma_likely) {
        memcpy(out, c->src.sigma_likely + 3 * (size_t)vid, 3 * sizeof *out);
        return;
    }
    out[0] = out[1] = out[2] = 0.0f;
}

void cache_indirect_sigma(const cache *c, uint32_t vid, float out[3])
{
    if (vid < c->src.drift_cap && c->src.sigma) {
        memcpy(out, c->src.sigma + 3 * (size_t)vid, 3 * sizeof *out);
        return;
    }
    out[0] = out[1] = out[2] = 0.0f;
}

/* The pilot trace of n ≤ CACHE_PILOT_CHUNK points into c->src.pilot_* (kept for
 * cache_record_importance).
 *
 * In chunks, because a pilot holds CACHE_IMPORTANCE_RAYS hits a point (2 KB):
 * traced whole, the first gather at every root vertex of the 116k-triangle box
 * (bench/scenes/cornell-bunny-dragon.json) held 200 MB, most of the process's peak
 * (docs/memory.md), for a pilot nobody reads: cache_record_importance reads only
 * the pilot of a refine round's gather, at most 3·ROUND_LEAVES (192) points, one
 * chunk. The rays are keyed by the point (samp_sources.c), so chunks trace the
 * same rays as one call. */
static lm_result trace_pilot(cache *c, const uint32_t *vids, const samp_point *pts, uint32_t n, lm_error *err)
{
    cache_source_state *st = &c->src;
    enum { RAYS = CACHE_IMPORTANCE_RAYS };
    if (n > st->pilot_cap) {
        size_t cap = n;
        if (!lm_realloc_array(&st->pilot_vid, st->pilot_cap, cap, sizeof *st->pilot_vid) ||
            !lm_realloc_array(&st->pilot_count, st->pilot_cap, cap, sizeof *st->pilot_count) ||
            !lm_realloc_array(&st->pilot_tri, st->pilot_cap, cap, RAYS * sizeof *st->pilot_tri) ||
            !lm_realloc_array(&st->pilot_weight, st->pilot_cap, cap, RAYS * sizeof *st->pilot_weight) ||
            !lm_realloc_array(&st->pilot_strat, st->pilot_cap, cap, 3 * sizeof *st->pilot_strat) ||
            !lm_realloc_array(&st->pilot_stratum, st->pilot_cap, cap, RAYS * sizeof *st->pilot_stratum))
            return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory tracing indirect light");
        st->pilot_cap = cap;
    }
    st->pilot_n = 0;
    lm_result r = samp_indirect_sources(
        c->sp, &st->rmesh, pts, n,
        &(samp_source_hits){.rays = RAYS, .count = st->pilot_count, .tri = st->pilot_tri, .weight = st->pilot_weight,
                            .strat_var = st->pilot_strat, .stratum = st->pilot_stratum},
        err);
    c->effort += (uint64_t)n * RAYS;
    if (r != LM_OK) return r;
    memcpy(st->pilot_vid, vids, n * sizeof *vids);
    st->pilot_n = n;
    return LM_OK;
}

/* From point i's pilot: E (RGB) and the variance of one ray's π·L (RGB), each
 * source triangle taken at the mean of its corners' radiance; strat: what a
 * stratified gather of at least CACHE_IMPORTANCE_RAYS rays behaves as instead
 * (samp_source_hits.strat_var: from neighbouring strata, the radiance
 * interpolated), never more than var. */
static void pilot_moments(const cache *c, uint32_t i, float e[3], double var[3], double strat[3])
{
    const cache_source_state *st = &c->src;
    double m1[3] = {0, 0, 0}, m2[3] = {0, 0, 0};
    for (uint32_t h = 0; h < st->pilot_count[i]; ++h) {
        size_t at = (size_t)i * CACHE_IMPORTANCE_RAYS + h;
        const float *rad = st->rmesh.radiance + 9 * (size_t)st->pilot_tri[at];
        double w = st->pilot_weight[at];
        for (int k = 0; k < 3; ++k) {
            double L = M_PI * (rad[k] + rad[3 + k] + rad[6 + k]) / 3.0;
            m1[k] += w * L;
            m2[k] += w * L * L;
        }
    }
    for (int k = 0; k < 3; ++k) {
        e[k] = (float)m1[k];
        var[k] = fmax(m2[k] - m1[k] * m1[k], 0.0);
        strat[k] = fmin((double)st->pilot_strat[3 * (size_t)i + (size_t)k], var[k]);
    }
}

/* The likely standard error of an N-ray stratified gather from the pilot's
 * moments: at N ≥ the pilot's rays its strata are finer than the pilot's, and its
 * variance falls at least as 1/N from there; coarser, only the plain variance
 * bounds it. What the error estimate uses (cache_estimate.c). Not for the edge
 * test or the ray count: the collapsed-strata estimate is itself noisy where the
 * light comes through a thin gap, and trusted there it let the slot test's
 * near room gather too few rays (its worst E_i 14% -> 37% off). Those take the
 * plain variance, which errs high. */
static float gather_sigma(double var, double strat, double N)
{
    return N > 0.0 ? (float)sqrt((N >= CACHE_IMPORTANCE_RAYS ? strat : var) / N) : 0.0f;
}

/* From point i's pilot: the variance of one ray of a gather guided by it
 * (samp_embree.c's indirect_one with a samp_guide: a fraction f_c ≈ ¼ of the rays
 * cosine-weighted, f_g ≈ ⅜ to the pilot's strata in proportion to the brightest
 * each or a neighbour saw, the rest toward the source by power; balance
 * heuristic), RGB; 0 when the pilot saw no light. With q = Σ_j f_j·p_j the
 * estimate's variance is Σ_j f_j·Var_j(f/q) / N, and in stratum s p_g/p_c is its
 * share of the guide × k², r_s, so the cosine and guided moments come from the
 * pilot's rays, one a stratum; the picks by power are left out of q (their pdf
 * is not in the pilot), which errs high, and out of the sum, which errs low.
 * Light uniform over a fraction p of the hemisphere, found exactly: about 8p·E²
 * against the cosine rays' (1 − p)/p·E². Its rays are the strata's only
 * samples, so where light fills part of a stratum it errs low: the value kept is
 * never below the gather's own sample error (gather_chunk_levels). Mirrors
 * samp_embree.c's guide_picks_make. */
static void pilot_guided_var(const cache *c, const float *y, int k, const float e[3], double var[3])
{
    const int RAYS = k * k;
    double mass[GUIDE_RAYS_MAX], total = 0.0;
    for (int b = 0; b < k; ++b)
        for (int a = 0; a < k; ++a) {
            mass[b * k + a] = samp_guide_mass(y, k, a, b);
            total += mass[b * k + a];
        }
    var[0] = var[1] = var[2] = 0.0;
    if (!(total > 0.0)) return;
    /* The pilot's RGB in each stratum is not kept: the channels scale with the
     * pilot's mean colour (e, pilot_moments'), the luminance-like mean the strata hold. */
    const double emean = ((double)e[0] + e[1] + e[2]) / 3.0;
    /* The split of the plain count (finer counts split as the shares say). */
    const uint32_t rays = samp_indirect_rays(c->sp);
    int kc, ng, npw;
    samp_toward_split(rays ? (int)lround(sqrt((double)rays)) : CACHE_PILOT_K, 1, 1, &kc, &ng, &npw);
    const double all = (double)kc * kc + ng + npw, fc = kc * kc / all, fg = ng / all;
    double m1c = 0, m2c = 0, m1g = 0, m2g = 0;
    for (int q = 0; q < RAYS; ++q) {
        const double r = mass[q] / total * RAYS, yq = y[q] / (fc + fg * r); /* f/q over p_c: π·L·p_c/q */
        m1c += yq / RAYS;
        m2c += yq * yq / RAYS;
        m1g += r * yq / RAYS;
        m2g += r * yq * yq / RAYS;
    }
    const double v = fc * fmax(m2c - m1c * m1c, 0.0) + fg * fmax(m2g - m1g * m1g, 0.0);
    for (int ch = 0; ch < 3; ++ch) var[ch] = emean > 0.0 ? v * ((double)e[ch] / emean) * ((double)e[ch] / emean) : v;
}

/* One chunk of gather_displayed: its points, what the pilot chose for them, and
 * scratch for the batches (cn points each). */
typedef struct gather_chunk {
    const uint32_t *vids;
    const samp_point *pts;
    uint32_t m0;
    uint8_t *level, *toward;
    float *predicted, *likely; /* RGB a point */
    float *mean;               /* RGB a point: the pilot's E (pilot_moments) */
    uint32_t *pick;
    samp_point *lpts;
    float *lE, *lsig;
    /* A finer gather's own guide (GUIDE_BATCH points of GUIDE_RAYS_MAX rays;
     * allocated when first needed): the pilot's hits, strata and rows. */
    uint32_t *gcount, *gtri, *grow;
    float *gweight, *gstratum;
} gather_chunk;

/* The guide's strata per side for a gather of N rays at level lv: the coarse
 * pilot's at the plain count, else the largest power of two whose square is at
 * most N, up to GUIDE_K_MAX. */
static int guide_k(int lv, double N)
{
    int k = CACHE_PILOT_K;
    while (lv > 0 && k < GUIDE_K_MAX && (double)(2 * k) * (2 * k) <= N) k *= 2;
    return k;
}

/* Points [j0, j1) of a level's picks (g->lpts, g->pick) gathered with N rays,
 * those toward the source guided by a pilot of k × k rays of their own, whose
 * prediction of their noise replaces the coarse pilot's (g->predicted, g->likely). */
static lm_result guide_finer(cache *c, gather_chunk *g, uint32_t j0, uint32_t j1, int k, double N, uint32_t scale,
                             lm_error *err)
{
    const uint32_t rays = (uint32_t)(k * k);
    if (!g->gstratum) {
        g->gcount = malloc(GUIDE_BATCH * sizeof *g->gcount);
        g->grow = malloc(GUIDE_BATCH * sizeof *g->grow);
        g->gtri = malloc((size_t)GUIDE_BATCH * GUIDE_RAYS_MAX * sizeof *g->gtri);
        g->gweight = malloc((size_t)GUIDE_BATCH * GUIDE_RAYS_MAX * sizeof *g->gweight);
        g->gstratum = malloc((size_t)GUIDE_BATCH * GUIDE_RAYS_MAX * sizeof *g->gstratum);
        if (!g->gcount || !g->grow || !g->gtri || !g->gweight || !g->gstratum)
            return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory guiding indirect gathers");
    }
    samp_point pts[GUIDE_BATCH];
    uint32_t t = 0;
    for (uint32_t j = j0; j < j1; ++j) {
        g->grow[j - j0] = 0;
        if (!g->lpts[j].toward_source) continue;
        g->grow[j - j0] = t;
        pts[t++] = g->lpts[j];
    }
    lm_result r = t ? samp_indirect_sources(c->sp, &c->src.rmesh, pts, t,
                                            &(samp_source_hits){.rays = rays, .count = g->gcount, .tri = g->gtri,
                                                                .weight = g->gweight, .stratum = g->gstratum},
                                            err)
                    : LM_OK;
    c->effort += (uint64_t)t * rays;
    for (uint32_t j = j0; r == LM_OK && j < j1; ++j) {
        if (!g->lpts[j].toward_source) continue;
        const uint32_t i = g->pick[j];
        double var[3];
        pilot_guided_var(c, g->gstratum + (size_t)g->grow[j - j0] * rays, k, g->mean + 3 * (size_t)i, var);
        if (!(var[0] + var[1] + var[2] > 0.0)) continue; /* the pilot saw nothing: the coarse prediction stays */
        for (int ch = 0; ch < 3; ++ch)
            g->predicted[3 * (size_t)i + (size_t)ch] = g->likely[3 * (size_t)i + (size_t)ch] = (float)sqrt(var[ch] / N);
    }
    const samp_guide guide = {.rays = rays, .stratum = g->gstratum, .index = g->grow};
    if (r == LM_OK)
        r = samp_indirect_guided(c->sp, &c->src.rmesh, g->lpts + j0, j1 - j0, 0, scale, &guide, g->lE + 3 * (size_t)j0,
                                 g->lsig + 3 * (size_t)j0, err);
    return r;
}

/* Gathers the chunk's points at their levels, guided by the chunk's pilot;
 * stores E, σ and the level. */
static lm_result gather_chunk_levels(cache *c, gather_chunk *g, float *E, lm_error *err)
{
    const uint32_t rays = samp_indirect_rays(c->sp);
    const samp_guide guide = {.rays = CACHE_IMPORTANCE_RAYS, .stratum = c->src.pilot_stratum, .index = g->pick};
    lm_result r = LM_OK;
    for (int lv = 0; r == LM_OK && lv < GATHER_FINER_LEVELS; ++lv) {
        uint32_t m = 0;
        for (uint32_t i = 0; i < g->m0; ++i)
            if (g->level[i] == lv) {
                g->pick[m] = i;
                g->lpts[m] = g->pts[i];
                g->lpts[m++].toward_source = g->toward[i];
            }
        if (m == 0) continue;
        const uint32_t scale = (uint32_t)pow(GATHER_SCALE, lv);
        const int k = rays ? guide_k(lv, (double)rays * scale) : CACHE_PILOT_K;
        if (k == CACHE_PILOT_K)
            r = samp_indirect_guided(c->sp, &c->src.rmesh, g->lpts, m, 0, scale, &guide, g->lE, g->lsig, err);
        for (uint32_t j0 = 0; k != CACHE_PILOT_K && r == LM_OK && j0 < m; j0 += GUIDE_BATCH)
            r = guide_finer(c, g, j0, j0 + GUIDE_BATCH < m ? j0 + GUIDE_BATCH : m, k, (double)rays * scale, scale, err);
        c->effort += (uint64_t)m * (rays ? rays : CACHE_GL_GATHER_RAYS) * (uint64_t)pow(GATHER_SCALE, lv);
        for (uint32_t j = 0; r == LM_OK && j < m; ++j) {
            const uint32_t i = g->pick[j], vid = g->vids[i];
            memcpy(E + 3 * (size_t)i, g->lE + 3 * (size_t)j, 3 * sizeof *E);
            if (vid >= c->src.drift_cap) continue;
            float *sg = c->src.sigma + 3 * (size_t)vid;
            float *sl = c->src.sigma_likely + 3 * (size_t)vid;
            /* Cosine rays: the pilot's prediction (the gather's own σ is as blind
             * as its mean to a gap all its rays missed). Guided toward the
             * source: the guided prediction, never below the gather's own
             * (pilot_guided_var errs low where the light fills part of a stratum). */
            for (int k = 0; k < 3; ++k) {
                const float own = g->toward[i] ? g->lsig[3 * (size_t)j + (size_t)k] : 0.0f;
                sg[k] = fmaxf(g->predicted[3 * (size_t)i + (size_t)k], own);
                sl[k] = fmaxf(g->likely[3 * (size_t)i + (size_t)k], own);
            }
            c->src.gather_level[vid] = (uint8_t)lv;
            c->src.toward_gathers += g->toward[i];
        }
    }
    return r;
}

/* The displayed indirect at the points, each with GATHER_SCALE^min_level[i] times
 * the plain count (min_level NULL: the plain count). A chunk at a time: the pilot
 * of CACHE_PILOT_CHUNK points (why: trace_pilot) predicts their noise, says which
 * go toward the source and guides those. */
static lm_result gather_displayed(cache *c, const uint32_t *vids, const samp_point *pts, uint32_t n,
                                  const uint8_t *min_level, float *E, lm_error *err)
{
    lm_result r = cache_grow_drift(&c->src, mesh_vtable_id_limit(c->vt), err);
    if (r != LM_OK) return r;
    const uint32_t rays = samp_indirect_rays(c->sp);
    const uint32_t cn = n < CACHE_PILOT_CHUNK ? (n ? n : 1) : CACHE_PILOT_CHUNK;
    gather_chunk g = {.level = calloc(cn, 1), .toward = calloc(cn, 1),
                      .predicted = malloc(3 * (size_t)cn * sizeof(float)), .likely = malloc(3 * (size_t)cn * sizeof(float)),
                      .mean = malloc(3 * (size_t)cn * sizeof(float)), .pick = malloc(cn * sizeof(uint32_t)),
                      .lpts = malloc(cn * sizeof(samp_point)), .lE = malloc(3 * (size_t)cn * sizeof(float)),
                      .lsig = malloc(3 * (size_t)cn * sizeof(float))};
    if (!g.level || !g.toward || !g.predicted || !g.likely || !g.mean || !g.pick || !g.lpts || !g.lE || !g.lsig)
        r = lm_fail(err, LM_ERR_NO_MEMORY, "out of memory sampling indirect light");
    for (uint32_t at = 0; r == LM_OK && at < n; at += CACHE_PILOT_CHUNK) {
        g.m0 = n - at < CACHE_PILOT_CHUNK ? n - at : CACHE_PILOT_CHUNK;
        g.vids = vids + at;
        g.pts = pts + at;
        r = trace_pilot(c, g.vids, g.pts, g.m0, err);
        /* Toward the source or not, the count asked for, and the noise predicted. */
        for (uint32_t i = 0; r == LM_OK && i < g.m0; ++i) {
            float e[3];
            double var[3], strat[3];
            pilot_moments(c, i, e, var, strat);
            memcpy(g.mean + 3 * (size_t)i, e, sizeof e);
            const double esum = (double)e[0] + e[1] + e[2], vsum = var[0] + var[1] + var[2];
            g.toward[i] = !(esum > 0.0) || vsum > GATHER_GAP_RATIO * esum * esum;
            if (g.toward[i] && esum > 0.0) { /* guided: its own variance, for every count */
                pilot_guided_var(c, c->src.pilot_stratum + (size_t)i * CACHE_IMPORTANCE_RAYS, CACHE_PILOT_K, e, var);
                memcpy(strat, var, sizeof strat);
            }
            const int asked = min_level ? min_level[at + i] : 0;
            const uint8_t lv = (uint8_t)(asked < GATHER_FINER_LEVELS ? asked : GATHER_FINER_LEVELS - 1);
            const double N = (double)rays * pow(GATHER_SCALE, lv);
            for (int k = 0; k < 3; ++k) {
                g.predicted[3 * (size_t)i + (size_t)k] = (float)sqrt(var[k] / N);
                g.likely[3 * (size_t)i + (size_t)k] = gather_sigma(var[k], strat[k], N);
            }
            g.level[i] = lv;
        }
        if (r == LM_OK) r = gather_chunk_levels(c, &g, E + 3 * (size_t)at, err);
    }
    /* Kept only whole: a pilot of several chunks holds the last one's points. */
    if (n > CACHE_PILOT_CHUNK) c->src.pilot_n = 0;
    free(g.level);
    free(g.toward);
    free(g.predicted);
    free(g.likely);
    free(g.mean);
    free(g.pick);
    free(g.lpts);
    free(g.gcount);
    free(g.grow);
    free(g.gtri);
    free(g.gweight);
    free(g.gstratum);
    free(g.lE);
    free(g.lsig);
    return r;
}

/* Is vertex vid on an edge of its triangle that no triangle continues (a mesh
 * boundary)? A displayed value there is gathered where the triangle's inside can
 * be seen from (samp_point_pull_inside): a floor that ends under the next room's
 * wall would otherwise gather that room at its edge, and interpolation carry it
 * in (docs/cache.md, cause 4). Nowhere else: a floor point under a box standing
 * on it is hidden, not in another room, and pulled out past the box it made
 * CornellBox-Original worse (mean ΔE 0.53 -> 0.94, and 0.57 for points on the
 * floor's inner diagonal alone). The further bounces' coarse vertices are
 * pulled in the same way (cache_bounces.c). */
int cache_vertex_on_open_edge(const cache *c, uint32_t vid)
{
    const mesh_vertex *mv = mesh_vtable_vertex(c->vt, vid);
    if (!c->s->topology) return 0;
    for (int e = 0; e < 3; ++e) /* edge e runs from corner e to e + 1: corner e + 2 weighs 0 on it */
        if (mv->bary.w[(e + 2) % 3] == 0 && mesh_geo_edge_kind(c->s->topology, mv->tri, e) == MESH_EDGE_BOUNDARY)
            return 1;
    return 0;
}

samp_point cache_gather_point(const cache *c, uint32_t vid)
{
    samp_point p = cache_vertex_point(c, vid);
    if (cache_vertex_on_open_edge(c, vid)) samp_point_pull_inside(c->sp, &p);
    return p;
}

static lm_result gather(cache *c, const uint32_t *vids, uint32_t n, const uint8_t *min_level, float *E, lm_error *err)
{
    if (n == 0) return LM_OK;
    lm_result r = cache_update_radiance_source(c, 0, err);
    if (r != LM_OK) return r;
    samp_point *pts = malloc(n * sizeof *pts);
    if (!pts) return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory sampling indirect light");
    for (uint32_t i = 0; i < n; ++i) pts[i] = cache_gather_point(c, vids[i]);
    r = c->desc.single_mesh ? samp_indirect(c->sp, &c->src.rmesh, pts, n, E, err)
                            : gather_displayed(c, vids, pts, n, min_level, E, err);
    if (c->desc.single_mesh) /* gather_displayed counts its own */
        c->effort += (uint64_t)n * (samp_indirect_rays(c->sp) ? samp_indirect_rays(c->sp) : CACHE_GL_GATHER_RAYS);
    free(pts);
    if (r == LM_OK) c->src.indirect_stats.samples += n;
    /* A value gathered from the current source has not drifted, and is not borrowed. */
    if (r == LM_OK && c->src.drift)
        for (uint32_t i = 0; i < n; ++i)
            if (vids[i] < c->src.drift_cap) {
                memset(c->src.drift + 3 * (size_t)vids[i], 0, 3 * sizeof *c->src.drift);
                c->src.outdated[vids[i]] = 0;
                c->src.borrowed[vids[i]] = 0.0f;
                c->src.stale_n -= c->src.unseen_stale[vids[i]];
                c->src.unseen_stale[vids[i]] = 0;
            }
    return r;
}

lm_result cache_sample_indirect(cache *c, const uint32_t *vids, uint32_t n, float *E, lm_error *err)
{
    return gather(c, vids, n, NULL, E, err);
}

lm_result cache_sample_indirect_like(cache *c, const uint32_t *vids, const uint32_t *like, uint32_t n, float *E,
                                     lm_error *err)
{
    if (n == 0) return LM_OK;
    uint8_t *lv = malloc(n);
    if (!lv) return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory sampling indirect light");
    for (uint32_t i = 0; i < n; ++i) lv[i] = (uint8_t)cache_gather_level(c, like[i]);
    lm_result r = gather(c, vids, n, lv, E, err);
    free(lv);
    return r;
}

int cache_gather_level(const cache *c, uint32_t vid)
{
    return vid < c->src.drift_cap ? c->src.gather_level[vid] : 0;
}

uint64_t cache_gather_cost(const cache *c, uint32_t vid)
{
    uint64_t cost = 1;
    for (int lv = cache_gather_level(c, vid); lv > 0; --lv) cost *= GATHER_SCALE;
    return cost;
}

uint64_t cache_gather_finer_cost(const cache *c, uint32_t vid)
{
    return GATHER_SCALE * cache_gather_cost(c, vid);
}

int cache_gather_can_refine(const cache *c, uint32_t vid)
{
    if (c->desc.single_mesh || !samp_indirect_rays(c->sp)) return 0; /* no σ to reduce (GL: exact) */
    return vid < c->src.drift_cap && c->src.gather_level[vid] + 1 < GATHER_FINER_LEVELS;
}

lm_result cache_regather_finer(cache *c, const uint32_t *vids, uint32_t n, float *E, lm_error *err)
{
    if (n == 0) return LM_OK;
    uint8_t *lv = malloc(n);
    if (!lv) return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory sampling indirect light");
    for (uint32_t i = 0; i < n; ++i) {
        uint8_t now = vids[i] < c->src.drift_cap ? c->src.gather_level[vids[i]] : 0;
        lv[i] = (uint8_t)(now + 1 < GATHER_FINER_LEVELS ? now + 1 : GATHER_FINER_LEVELS - 1);
    }
    lm_result r = gather(c, vids, n, lv, E, err);
    free(lv);
    return r;
}
