/* cache_glossy.c — the glossy part of the specular values (cache_internal.h,
 * cache_glossy_state): the indirect source seen through each specular vertex's
 * modified Phong lobe about the mirror of its view direction,
 *     L_is(x, ωo) = ∫ (n+2)/(2π) cosⁿα · L_src(y(ω)) · cosθ dω     (per unit ks),
 * L_src = kd·(L_dd + E_(K−1)/π), the radiance the indirect gathers read. The
 * paper's specular mesh holds the lights' highlights only (eq. 5–6); a metal or
 * water surface then shows black wherever no light is mirrored in it, where the
 * full transport shows the room (docs/cache.md, "Glossy reflection of the room").
 *
 * A value is gathered with the source of its time; a rebuilt source, or a new
 * viewpoint, makes every glossy part stale (generation numbers), and
 * cache_glossy_refresh takes them again by a sweep over the vertex ids, a
 * bounded number a refine call, before the cache may claim convergence.
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
        !lm_realloc_array(&st->gen, st->cap, cap, sizeof *st->gen))
        return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory for the glossy reflections");
    memset(st->rgb + 3 * st->cap, 0, (cap - st->cap) * 3 * sizeof *st->rgb);
    memset(st->gen + st->cap, 0, (cap - st->cap) * sizeof *st->gen);
    st->cap = cap;
    return LM_OK;
}

/* Rays of a glossy gather at each level: CACHE_GLOSSY_RAYS, then ×4 while its
 * noise is seen. A broad lobe (the Veach door's copper, n ≈ 1) in a room lit
 * through a gap is a diffuse gather in all but name: 64 rays leave blotches. */
enum { GLOSSY_LEVELS = 4 };
/* A value's noise is seen when adding its standard error moves the pixel by more
 * than this fraction of the JND (the indirect gathers' rule, cache_estimate.c). */
#define GLOSSY_NOISE_JND 0.5f

/* Is the noise se of glossy part L, over the direct specular value d, seen at
 * vertex vid (the pixel with the other terms there, through the tone map)? */
static int noise_seen(const cache *c, uint32_t vid, const float d[3], const float L[3], const float se[3])
{
    const mesh_vertex *mv = mesh_vtable_vertex(c->vt, vid);
    const double scale = ldexp(1.0, -(int)mv->bary.depth);
    const double w1 = mv->bary.w[1] * scale, w2 = mv->bary.w[2] * scale;
    float a[3], b[3], la[3], lb[3];
    for (int k = 0; k < 3; ++k) {
        a[k] = d[k] + L[k];
        b[k] = a[k] + se[k];
    }
    cache_seen_lab_with(c, CACHE_KIND_SPECULAR, mv->tri, w1, w2, a, la);
    cache_seen_lab_with(c, CACHE_KIND_SPECULAR, mv->tri, w1, w2, b, lb);
    return tm_delta_e(la, lb) > GLOSSY_NOISE_JND * c->desc.jnd;
}

/* The glossy parts of vertices vids[0..n) from the current source, into L[3i..];
 * direct[3i..] (NULL: 0) is the rest of each specular value, for the noise test.
 * Each is gathered with more rays (GLOSSY_LEVELS) while its noise is seen. */
static lm_result gather(cache *c, const uint32_t *vids, uint32_t n, const float *direct, float *L, lm_error *err)
{
    const scene *s = c->s;
    const size_t cnt = n ? n : 1;
    /* per point, in vids' order (…0), and packed for a level's call (the others) */
    samp_point *pts0 = malloc(cnt * sizeof *pts0), *pts = malloc(cnt * sizeof *pts);
    float *wo0 = malloc(3 * cnt * sizeof *wo0), *wo = malloc(3 * cnt * sizeof *wo);
    float *ex0 = malloc(cnt * sizeof *ex0), *ex = malloc(cnt * sizeof *ex);
    float *se = malloc(3 * cnt * sizeof *se), *Lp = malloc(3 * cnt * sizeof *Lp);
    uint32_t *at = malloc(cnt * sizeof *at); /* packed j is point at[j] */
    lm_result r = pts0 && pts && wo0 && wo && ex0 && ex && se && Lp && at
                      ? LM_OK
                      : lm_fail(err, LM_ERR_NO_MEMORY, "out of memory gathering glossy reflections");
    for (uint32_t i = 0; r == LM_OK && i < n; ++i) {
        pts0[i] = cache_vertex_point(c, vids[i]);
        for (int k = 0; k < 3; ++k) wo0[3 * i + (uint32_t)k] = c->eye[k] - pts0[i].p[k];
        /* the exponent of the triangle the vertex was made from, as the direct part's */
        ex0[i] = s->materials[s->tris[mesh_vtable_vertex(c->vt, vids[i])->tri].material].n;
        at[i] = i;
    }
    static const float zero[3] = {0, 0, 0};
    uint32_t m = n, rays = CACHE_GLOSSY_RAYS;
    for (int level = 0; r == LM_OK && m > 0 && level < GLOSSY_LEVELS; ++level, rays *= 4) {
        for (uint32_t j = 0; j < m; ++j) {
            pts[j] = pts0[at[j]];
            memcpy(wo + 3 * (size_t)j, wo0 + 3 * (size_t)at[j], 3 * sizeof *wo);
            ex[j] = ex0[at[j]];
        }
        /* pass = level: each level's rays are a stream of their own */
        r = samp_lobe_gather(c->sp, &c->src.rmesh, pts, wo, ex, m, rays, (uint32_t)level, Lp, se, err);
        if (r != LM_OK) break;
        c->effort += (uint64_t)m * rays;
        c->gls.rays += (uint64_t)m * rays;
        uint32_t keep = 0; /* keep ≤ j: at[] is rewritten behind the reading */
        for (uint32_t j = 0; j < m; ++j) {
            const uint32_t i = at[j];
            memcpy(L + 3 * (size_t)i, Lp + 3 * (size_t)j, 3 * sizeof *L);
            if (level + 1 < GLOSSY_LEVELS &&
                noise_seen(c, vids[i], direct ? direct + 3 * (size_t)i : zero, Lp + 3 * (size_t)j, se + 3 * (size_t)j))
                at[keep++] = i;
        }
        m = keep;
    }
    if (r == LM_OK) c->gls.samples += n;
    free(pts0);
    free(pts);
    free(wo0);
    free(wo);
    free(ex0);
    free(ex);
    free(se);
    free(Lp);
    free(at);
    return r;
}

/* The source exists (built at least once): something to gather from. */
static int have_source(const cache *c) { return c->src.rmesh.first != NULL && c->gls.gen_now > 0; }

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
    r = L ? gather(c, vids, n, rgb, L, err) : lm_fail(err, LM_ERR_NO_MEMORY, "out of memory gathering glossy reflections");
    for (uint32_t i = 0; r == LM_OK && i < n; ++i) {
        for (int k = 0; k < 3; ++k) {
            rgb[3 * i + (uint32_t)k] += L[3 * i + (uint32_t)k];
            st->rgb[3 * (size_t)vids[i] + (size_t)k] = L[3 * i + (uint32_t)k];
        }
        st->gen[vids[i]] = st->gen_now;
    }
    free(L);
    return r;
}

lm_result cache_glossy_forget(cache *c, uint32_t vid, lm_error *err)
{
    if (!cache_glossy_on(c)) return LM_OK;
    cache_glossy_state *st = &c->gls;
    lm_result r = grow(st, vid + 1, err);
    if (r != LM_OK) return r;
    memset(st->rgb + 3 * (size_t)vid, 0, 3 * sizeof *st->rgb);
    st->gen[vid] = 0;
    if (vid < st->cursor) st->cursor = vid;
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

lm_result cache_glossy_refresh(cache *c, cache_changed_fn changed, void *user, uint64_t *allowance, lm_error *err)
{
    enum { BATCH = 1024 };
    if (!cache_glossy_on(c) || !have_source(c)) return LM_OK;
    cache_glossy_state *st = &c->gls;
    const uint32_t limit = mesh_vtable_id_limit(c->vt);
    lm_result r = grow(st, limit, err);
    uint32_t *ids = NULL;
    float *L = NULL, *D = NULL; /* D: the direct parts of the values (their noise test) */
    while (r == LM_OK && st->cursor < limit && (!allowance || *allowance > 0) && !cache_stopping(c)) {
        if (!ids) {
            ids = malloc(BATCH * sizeof *ids);
            L = malloc(3 * BATCH * sizeof *L);
            D = malloc(3 * BATCH * sizeof *D);
            if (!ids || !L || !D) {
                r = lm_fail(err, LM_ERR_NO_MEMORY, "out of memory gathering glossy reflections again");
                break;
            }
        }
        const uint32_t most = allowance && *allowance < BATCH ? (uint32_t)*allowance : BATCH;
        uint32_t n = 0;
        /* The sweep: stale values of the specular mesh, in id order (ascending,
         * as changed's look-up wants them). */
        for (; st->cursor < limit && n < most; ++st->cursor) {
            const uint32_t vid = st->cursor;
            if (st->gen[vid] == st->gen_now || !mesh_qmesh_vertex_use(c->specular, vid)) continue;
            if (mesh_qmesh_get_value(c->specular, vid, NULL) != 1) continue; /* no value yet: gathered when made */
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
        r = gather(c, ids, n, D, L, err);
        for (uint32_t i = 0; r == LM_OK && i < n; ++i) {
            float v[3];
            for (int k = 0; k < 3; ++k) {
                v[k] = D[3 * i + (uint32_t)k] + L[3 * i + (uint32_t)k];
                st->rgb[3 * (size_t)ids[i] + (size_t)k] = L[3 * i + (uint32_t)k];
            }
            st->gen[ids[i]] = st->gen_now;
            r = mesh_qmesh_set_value(c->specular, ids[i], v, err);
        }
        st->refreshed += n;
        if (allowance) *allowance = *allowance > n ? *allowance - n : 0;
        if (r == LM_OK) r = changed(c, CACHE_KIND_SPECULAR, NULL, 0, ids, n, user, err);
    }
    free(ids);
    free(L);
    free(D);
    return r;
}

void cache_glossy_free(cache_glossy_state *st)
{
    free(st->rgb);
    free(st->gen);
    memset(st, 0, sizeof *st);
}
