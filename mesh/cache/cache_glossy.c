/* cache_glossy.c — the glossy part of the specular values (cache_internal.h,
 * cache_glossy_state): the indirect source seen through each specular vertex's
 * modified Phong lobe about the mirror of its view direction,
 *     L_is(x, ωo) = ∫ (n+2)/(2π) cosⁿα · L_src(y(ω)) · cosθ dω     (per unit ks),
 * L_src = kd·(L_dd + E_(K−1)/π), the radiance the indirect gathers read. The
 * paper's specular mesh holds the lights' highlights only (eq. 5–6); a metal or
 * water surface then shows black wherever no light is mirrored in it, where the
 * full transport shows the room (docs/cache.md, "Glossy reflection of the room").
 *
 * A value is gathered with the source of its time. A tracked rebuild of the
 * source bounds how far it moved each glossy part (cache_drift.c, the lobe in
 * the drift tree's kernel: cache_glossy_drift) and makes stale those whose drift
 * could be seen; an untracked rebuild or a new viewpoint makes every one stale
 * (generation numbers); a value whose noise is seen is stale one level of rays
 * up. cache_glossy_refresh takes them again by a sweep over the vertex ids, a
 * bounded number a refine call, before the cache may claim convergence.
 * Does NOT do: glossy surfaces as sources (caustics), reflections of a surface's
 * back. Units: radiance per unit ks (W·m⁻²·sr⁻¹).
 * Calls cache_site.c and the sampler only. Worker thread, like the rest of the
 * cache. */
#include "mesh/cache/cache_internal.h"

#include <stdlib.h>
#include <string.h>

#include "sampling/samp.h"
#include "src/base/tonemap.h"

int cache_glossy_on(const cache *c) { return c->specular && c->desc.glossy == CACHE_GLOSSY_INDIRECT; }

static lm_result grow(cache_glossy_state *st, uint32_t limit, lm_error *err)
{
    if (limit <= st->cap) return LM_OK;
    size_t cap = lm_grow_capacity(st->cap, limit, 1024, SIZE_MAX / (3 * sizeof *st->rgb));
    if (!cap || !lm_realloc_array(&st->rgb, st->cap, cap, 3 * sizeof *st->rgb) ||
        !lm_realloc_array(&st->gen, st->cap, cap, sizeof *st->gen) ||
        !lm_realloc_array(&st->level, st->cap, cap, sizeof *st->level) ||
        !lm_realloc_array(&st->drift, st->cap, cap, 3 * sizeof *st->drift))
        return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory for the glossy reflections");
    memset(st->rgb + 3 * st->cap, 0, (cap - st->cap) * 3 * sizeof *st->rgb);
    memset(st->gen + st->cap, 0, (cap - st->cap) * sizeof *st->gen);
    memset(st->level + st->cap, 0, (cap - st->cap) * sizeof *st->level);
    memset(st->drift + 3 * st->cap, 0, (cap - st->cap) * 3 * sizeof *st->drift);
    st->cap = cap;
    return LM_OK;
}

/* Rays of a glossy gather at each level: CACHE_GLOSSY_RAYS (16), ×4 a level, up
 * to 4,096. A broad lobe (the Veach door's copper, n ≈ 1) in a room lit through
 * a gap is a diffuse gather in all but name: 64 rays leave blotches. A value is
 * made at level 0; where its noise is seen it is marked stale one level up, and
 * the sweep takes it again there, a bounded number a refine call: escalating at
 * once (up to 4,096 rays for every new value) made the door's first snapshots
 * wait (mean ΔE 38 at 1 s against 19 without glossy gathers). Starting at 64
 * rays instead of 16 starved Water's specular mesh in its first two seconds
 * (relMSE 1.8e-2 against 5.9e-3 at 0.5 s, 6e-4 against 1.7e-4 at 1.5 s; the
 * door and the converged pictures the same). */
enum { GLOSSY_LEVELS = 5 };
/* A value's noise is seen when adding its standard error moves the pixel by more
 * than this fraction of the JND (the indirect gathers' rule, cache_estimate.c). */
#define GLOSSY_NOISE_JND 0.5f
/* A value taken again moved its pixel by more than this fraction of the JND:
 * the leaves around it are tested again. Less, and the tests that passed them
 * stand (a source rebuilt as the direct mesh refines moves most glossy parts a
 * little; testing every leaf again after each rebuild made the door's specular
 * mesh take 17× the samples). */
#define GLOSSY_MOVED_JND 0.25f

/* The pixel's CIELAB at vertex vid with specular value spec (the other terms
 * there, through the tone map). */
static void seen_lab(const cache *c, uint32_t vid, const float spec[3], float lab[3])
{
    const mesh_vertex *mv = mesh_vtable_vertex(c->vt, vid);
    const double scale = ldexp(1.0, -(int)mv->bary.depth);
    cache_seen_lab_with(c, CACHE_KIND_SPECULAR, mv->tri, mv->bary.w[1] * scale, mv->bary.w[2] * scale, spec, lab);
}

/* How far (ΔE) specular value d + L0 is seen from d + L1 at vertex vid. */
static float moved_by(const cache *c, uint32_t vid, const float d[3], const float L0[3], const float L1[3])
{
    float a[3], b[3], la[3], lb[3];
    for (int k = 0; k < 3; ++k) {
        a[k] = d[k] + L0[k];
        b[k] = d[k] + L1[k];
    }
    seen_lab(c, vid, a, la);
    seen_lab(c, vid, b, lb);
    return tm_delta_e(la, lb);
}

/* Vertex vid's glossy part is to be gathered again: the sweep comes back to it. */
static void mark_stale(cache_glossy_state *st, uint32_t vid)
{
    st->gen[vid] = 0;
    if (vid < st->cursor) st->cursor = vid;
}

/* The glossy parts of vertices vids[0..n) from the current source, into L[3i..],
 * each with CACHE_GLOSSY_RAYS·4^level[i] rays (level NULL: 0); direct[3i..] (NULL:
 * 0) is the rest of each specular value. noisy[i] (may be NULL) says whether the
 * value's noise is seen. */
static lm_result gather(cache *c, const uint32_t *vids, const uint8_t *level, uint32_t n, const float *direct,
                        float *L, uint8_t *noisy, lm_error *err)
{
    const scene *s = c->s;
    const size_t cnt = n ? n : 1;
    samp_point *pts = malloc(cnt * sizeof *pts);
    float *wo = malloc(3 * cnt * sizeof *wo), *ex = malloc(cnt * sizeof *ex);
    float *se = malloc(3 * cnt * sizeof *se), *Lp = malloc(3 * cnt * sizeof *Lp);
    uint32_t *at = malloc(cnt * sizeof *at); /* packed j is point at[j] */
    lm_result r = pts && wo && ex && se && Lp && at ? LM_OK
                                                    : lm_fail(err, LM_ERR_NO_MEMORY, "out of memory gathering glossy reflections");
    static const float zero[3] = {0, 0, 0};
    /* One call per level, of the points at that level. */
    for (int lv = 0; r == LM_OK && lv < GLOSSY_LEVELS; ++lv) {
        uint32_t m = 0;
        for (uint32_t i = 0; i < n; ++i) {
            if ((level ? level[i] : 0) != lv) continue;
            pts[m] = cache_vertex_point(c, vids[i]);
            for (int k = 0; k < 3; ++k) wo[3 * m + (uint32_t)k] = c->eye[k] - pts[m].p[k];
            /* the exponent of the triangle the vertex was made from, as the direct part's */
            ex[m] = s->materials[s->tris[mesh_vtable_vertex(c->vt, vids[i])->tri].material].n;
            at[m++] = i;
        }
        if (m == 0) continue;
        const uint32_t rays = (uint32_t)CACHE_GLOSSY_RAYS << (2 * lv);
        /* pass = level: each level's rays are a stream of their own */
        r = samp_lobe_gather(c->sp, &c->src.rmesh, pts, wo, ex, m, rays, (uint32_t)lv, Lp, se, err);
        if (r != LM_OK) break;
        c->effort += (uint64_t)m * rays;
        c->gls.rays += (uint64_t)m * rays;
        for (uint32_t j = 0; j < m; ++j) {
            const uint32_t i = at[j];
            memcpy(L + 3 * (size_t)i, Lp + 3 * (size_t)j, 3 * sizeof *L);
            if (!noisy) continue;
            const float *d = direct ? direct + 3 * (size_t)i : zero;
            float up[3];
            for (int k = 0; k < 3; ++k) up[k] = Lp[3 * j + (uint32_t)k] + se[3 * j + (uint32_t)k];
            noisy[i] = moved_by(c, vids[i], d, Lp + 3 * (size_t)j, up) > GLOSSY_NOISE_JND * c->desc.jnd;
        }
    }
    if (r == LM_OK) c->gls.samples += n;
    free(pts);
    free(wo);
    free(ex);
    free(se);
    free(Lp);
    free(at);
    return r;
}

/* The source exists (built at least once): something to gather from. */
static int have_source(const cache *c) { return c->src.rmesh.first != NULL && c->gls.gen_now > 0; }

int cache_glossy_fresh(const cache *c, uint32_t vid)
{
    const cache_glossy_state *st = &c->gls;
    return cache_glossy_on(c) && vid < st->cap && st->gen[vid] != 0 && st->gen[vid] == st->gen_now &&
           mesh_qmesh_vertex_use(c->specular, vid) && mesh_qmesh_get_value(c->specular, vid, NULL) == 1;
}

void cache_glossy_drift(cache *c, uint32_t vid, const float bound[3])
{
    cache_glossy_state *st = &c->gls;
    float *dr = st->drift + 3 * (size_t)vid, v[3], d[3], up[3], down[3];
    mesh_qmesh_get_value(c->specular, vid, v);
    const float *l = st->rgb + 3 * (size_t)vid;
    for (int k = 0; k < 3; ++k) {
        dr[k] = fminf(dr[k] + bound[k], 3e38f);
        d[k] = fmaxf(v[k] - l[k], 0.0f);
        up[k] = l[k] + dr[k];
        down[k] = fmaxf(l[k] - dr[k], 0.0f);
    }
    /* Could its drift be seen (the indirect values' rule: by more than the JND)? */
    if (moved_by(c, vid, d, l, up) > c->desc.jnd || moved_by(c, vid, d, l, down) > c->desc.jnd) {
        mark_stale(st, vid); /* at the level it has */
    }
}

/* Records vertex vid's glossy part L, gathered at `level` from the current
 * source; a noisy one is left stale one level up, for the sweep. */
static void record(cache_glossy_state *st, uint32_t vid, const float L[3], int level, int noisy)
{
    memcpy(st->rgb + 3 * (size_t)vid, L, 3 * sizeof *L);
    memset(st->drift + 3 * (size_t)vid, 0, 3 * sizeof *st->drift);
    st->level[vid] = (uint8_t)level;
    st->gen[vid] = st->gen_now;
    if (noisy && level + 1 < GLOSSY_LEVELS) {
        st->level[vid] = (uint8_t)(level + 1);
        mark_stale(st, vid);
    }
}

lm_result cache_glossy_add(cache *c, const uint32_t *vids, uint32_t n, float *rgb, lm_error *err)
{
    if (!cache_glossy_on(c) || n == 0) return LM_OK;
    cache_glossy_state *st = &c->gls;
    uint32_t top = 0;
    for (uint32_t i = 0; i < n; ++i) top = vids[i] + 1 > top ? vids[i] + 1 : top;
    lm_result r = grow(st, top, err);
    if (r != LM_OK) return r;
    if (!have_source(c)) {
        for (uint32_t i = 0; i < n; ++i) r = cache_glossy_forget(c, vids[i], err);
        return r;
    }
    float *L = malloc(3 * (size_t)n * sizeof *L);
    uint8_t *noisy = malloc(n);
    r = L && noisy ? gather(c, vids, NULL, n, rgb, L, noisy, err)
                   : lm_fail(err, LM_ERR_NO_MEMORY, "out of memory gathering glossy reflections");
    for (uint32_t i = 0; r == LM_OK && i < n; ++i) {
        for (int k = 0; k < 3; ++k) rgb[3 * i + (uint32_t)k] += L[3 * i + (uint32_t)k];
        record(st, vids[i], L + 3 * (size_t)i, 0, noisy[i]);
    }
    free(L);
    free(noisy);
    return r;
}

lm_result cache_glossy_forget(cache *c, uint32_t vid, lm_error *err)
{
    if (!cache_glossy_on(c)) return LM_OK;
    cache_glossy_state *st = &c->gls;
    lm_result r = grow(st, vid + 1, err);
    if (r != LM_OK) return r;
    memset(st->rgb + 3 * (size_t)vid, 0, 3 * sizeof *st->rgb);
    mark_stale(st, vid);
    return LM_OK;
}

void cache_glossy_outdate(cache *c)
{
    if (!cache_glossy_on(c)) return;
    if (++c->gls.gen_now == 0) { /* wrapped: every recorded generation is of some old source */
        memset(c->gls.gen, 0, c->gls.cap * sizeof *c->gls.gen);
        c->gls.gen_now = 1;
    }
    c->gls.cursor = 0;
}

uint32_t cache_glossy_waiting(const cache *c)
{
    if (!cache_glossy_on(c) || !have_source(c)) return 0;
    const uint32_t limit = mesh_vtable_id_limit(c->vt);
    return c->gls.cursor < limit ? limit - c->gls.cursor : 0;
}

/* What taking a part again at `level` costs of a refresh's allowance: one up to
 * GLOSSY_REFRESH_UNIT_RAYS rays, a dearer gather its rays over that. Counted one
 * a part, a worker step of the Veach door took 8,192 parts at up to 4,096 rays,
 * 10.8 million rays and 2.8 s with no snapshot (docs/cache.md, "A step's
 * regathers counted in rays"); the cheap parts of the first seconds count as
 * before. */
enum { GLOSSY_REFRESH_UNIT_RAYS = 256 };
static uint64_t refresh_cost(uint8_t level)
{
    const uint64_t rays = (uint64_t)CACHE_GLOSSY_RAYS << (2 * level);
    return rays > GLOSSY_REFRESH_UNIT_RAYS ? rays / GLOSSY_REFRESH_UNIT_RAYS : 1;
}

lm_result cache_glossy_refresh(cache *c, cache_changed_fn changed, void *user, uint64_t *allowance, lm_error *err)
{
    enum { BATCH = 1024 };
    if (!cache_glossy_on(c) || !have_source(c)) return LM_OK;
    cache_glossy_state *st = &c->gls;
    const uint32_t limit = mesh_vtable_id_limit(c->vt);
    lm_result r = grow(st, limit, err);
    uint32_t *ids = malloc(BATCH * sizeof *ids), *moved = malloc(BATCH * sizeof *moved);
    uint8_t *lv = malloc(BATCH), *noisy = malloc(BATCH);
    float *L = malloc(3 * BATCH * sizeof *L), *D = malloc(3 * BATCH * sizeof *D); /* D: the direct parts */
    if (r == LM_OK && (!ids || !moved || !lv || !noisy || !L || !D))
        r = lm_fail(err, LM_ERR_NO_MEMORY, "out of memory gathering glossy reflections again");
    while (r == LM_OK && st->cursor < limit && (!allowance || *allowance > 0) && !cache_stopping(c)) {
        const uint32_t most = allowance && *allowance < BATCH ? (uint32_t)*allowance : BATCH;
        uint32_t n = 0;
        /* The sweep: stale values of the specular mesh, in id order (ascending,
         * as changed's look-up wants them). A value no pixel sees is taken as it
         * is: the specular mesh is made again when the view moves. */
        uint64_t cost = 0;
        for (; st->cursor < limit && n < most; ++st->cursor) {
            const uint32_t vid = st->cursor;
            if (st->gen[vid] == st->gen_now || !mesh_qmesh_vertex_use(c->specular, vid)) continue;
            if (mesh_qmesh_get_value(c->specular, vid, NULL) != 1) continue; /* no value yet: gathered when made */
            if (c->pixels && !c->pixels[mesh_vtable_vertex(c->vt, vid)->tri]) {
                st->gen[vid] = st->gen_now;
                continue;
            }
            const uint64_t one = refresh_cost(st->level[vid]);
            if (allowance && n > 0 && cost + one > *allowance) break; /* this one waits for the next call */
            cost += one;
            lv[n] = st->level[vid];
            ids[n++] = vid;
        }
        if (n == 0) break;
        for (uint32_t i = 0; i < n; ++i) {
            mesh_qmesh_get_value(c->specular, ids[i], D + 3 * (size_t)i);
            for (int k = 0; k < 3; ++k) {
                float *d = D + 3 * (size_t)i + (size_t)k;
                *d -= st->rgb[3 * (size_t)ids[i] + (size_t)k];
                if (!(*d > 0.0f)) *d = 0.0f; /* round-off of the difference: light is not negative */
            }
        }
        r = gather(c, ids, lv, n, D, L, noisy, err);
        uint32_t nm = 0;
        for (uint32_t i = 0; r == LM_OK && i < n; ++i) {
            float v[3];
            const float *d = D + 3 * (size_t)i, *l = L + 3 * (size_t)i;
            for (int k = 0; k < 3; ++k) v[k] = d[k] + l[k];
            if (moved_by(c, ids[i], d, st->rgb + 3 * (size_t)ids[i], l) > GLOSSY_MOVED_JND * c->desc.jnd)
                moved[nm++] = ids[i];
            record(st, ids[i], l, lv[i], noisy[i]);
            r = mesh_qmesh_set_value(c->specular, ids[i], v, err);
        }
        st->refreshed += n;
        if (allowance) *allowance = *allowance > cost ? *allowance - cost : 0;
        if (r == LM_OK && nm) r = changed(c, CACHE_KIND_SPECULAR, NULL, 0, moved, nm, user, err);
    }
    free(ids);
    free(moved);
    free(lv);
    free(noisy);
    free(L);
    free(D);
    return r;
}

size_t cache_glossy_bytes(const cache_glossy_state *st)
{
    return st->cap * (6 * sizeof(float) + sizeof(uint32_t) + sizeof(uint8_t));
}

void cache_glossy_free(cache_glossy_state *st)
{
    free(st->rgb);
    free(st->gen);
    free(st->level);
    free(st->drift);
    memset(st, 0, sizeof *st);
}
