/* cache_reach.c — which scene triangles take part (issue 16; docs/cache.md,
 * "Start-up bounded by what is seen").
 *
 * The cache samples only the triangles a pixel sees and those from which a
 * gather of theirs can draw light: a triangle nothing sees and no gather reaches
 * (inside a closed box outside the room, the far side of a building) costs no
 * sample and sends no light. What a gather reaches is found the way it would
 * find it: CACHE_REACH_RAYS stratified cosine-weighted rays (Embree,
 * samp_surface_hits_trace) from points of each newly taken triangle, every front
 * of a triangle with albedo they meet taken in turn (further bounces travel the
 * reach of the reach). A triangle met takes its whole part (a mesh or group of
 * the file) with it. The points are its root corners and, on a triangle
 * larger than 1/CACHE_REACH_POINTS of the scene's area, points spread over it
 * (a wall of two triangles has six corners; its gathers will be everywhere on
 * it); a part of more than REACH_PART_TRIANGLES triangles is traced from that
 * many of them, spread through it (a 69,000-triangle bunny, taken whole, need not
 * send 16 rays from each of its 35,000 vertices to find the walls). Gathers made later by refinement are looked at too
 * (cache_reach_from_gathers), so what the corners missed is taken when a
 * refined gather point sees it.
 *
 * Does NOT do: sampling (cache.c samples what is taken), taking a triangle out
 * again, reach through the back of a surface (a back sends nothing, as in the
 * gathers). A small triangle every ray misses stays out until a pixel or a later
 * gather finds it: until then it is an occluder that sends nothing.
 * Threads: the cache's.
 */
#include "mesh/cache/cache_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

enum { REACH_BATCH = 16384, REACH_POINTS_MAX = 256, REACH_PART_TRIANGLES = 1024 };

typedef struct reach {
    cache *c;
    samp_point *pts;
    uint32_t np;
    uint32_t *count, *hit;
    float *bary;
    uint32_t *list;        /* triangles taken by this call, in order */
    size_t n, cap;
} reach;

static int keep_unreached(const scene *s, uint32_t t, void *user)
{
    const cache *c = user;
    return !c->active[t] && cache_has_albedo(s, t, NULL);
}

static lm_result reach_open(reach *x, cache *c, lm_error *err)
{
    memset(x, 0, sizeof *x);
    x->c = c;
    x->pts = malloc(REACH_BATCH * sizeof *x->pts);
    x->count = malloc(REACH_BATCH * sizeof *x->count);
    x->hit = malloc((size_t)REACH_BATCH * CACHE_REACH_RAYS * sizeof *x->hit);
    x->bary = malloc(2 * (size_t)REACH_BATCH * CACHE_REACH_RAYS * sizeof *x->bary);
    if (x->pts && x->count && x->hit && x->bary) return LM_OK;
    return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory finding what gathers reach");
}

static void reach_close(reach *x)
{
    free(x->pts);
    free(x->count);
    free(x->hit);
    free(x->bary);
}

/* Per part, its triangles (part_first[p] .. part_first[p + 1] of part_tris). */
static lm_result part_index(cache *c, lm_error *err)
{
    if (c->part_first) return LM_OK;
    const scene *s = c->s;
    c->part_first = calloc((size_t)s->part_count + 1, sizeof *c->part_first);
    c->part_tris = malloc((s->tri_count ? s->tri_count : 1) * sizeof *c->part_tris);
    uint32_t *fill = calloc((size_t)s->part_count + 1, sizeof *fill);
    if (!c->part_first || !c->part_tris || !fill) {
        free(c->part_first);
        free(c->part_tris);
        free(fill);
        c->part_first = c->part_tris = NULL;
        return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory finding what gathers reach");
    }
    for (uint32_t t = 0; t < s->tri_count; ++t) c->part_first[s->tris[t].part + 1]++;
    for (uint32_t p = 0; p < s->part_count; ++p) c->part_first[p + 1] += c->part_first[p];
    for (uint32_t t = 0; t < s->tri_count; ++t) {
        uint32_t p = s->tris[t].part;
        c->part_tris[c->part_first[p] + fill[p]++] = t;
    }
    free(fill);
    return LM_OK;
}

/* Takes part triangle t's whole part (a mesh or group of the file): a ray that
 * meets one triangle of a tessellated surface stands for its neighbours, which
 * the rays' finite number would miss one by one (a teapot's back, seen by the
 * wall behind it, through 16 rays a point). */
static lm_result take(reach *x, uint32_t t, lm_error *err)
{
    cache *c = x->c;
    if (c->active[t]) return LM_OK;
    lm_result r = part_index(c, err);
    if (r != LM_OK) return r;
    const uint32_t p = c->s->tris[t].part;
    for (uint32_t i = c->part_first[p]; i < c->part_first[p + 1]; ++i) {
        uint32_t u = c->part_tris[i];
        if (c->active[u]) continue;
        if (!LM_GROW(x->list, x->cap, x->n + 1)) return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory finding what gathers reach");
        c->active[u] = 1;
        c->active_count++;
        x->list[x->n++] = u;
    }
    return LM_OK;
}

/* Traces the points gathered so far; what they meet is taken. */
static lm_result flush(reach *x, lm_error *err)
{
    if (!x->np) return LM_OK;
    const uint32_t R = CACHE_REACH_RAYS;
    lm_result r = samp_surface_hits_trace(x->c->sp, x->pts, x->np,
                                          &(samp_surface_hits){.rays = R, .count = x->count, .tri = x->hit,
                                                               .bary = x->bary, .keep = keep_unreached, .keep_user = x->c},
                                          err);
    x->c->reach_rays += (uint64_t)x->np * R;
    for (uint32_t p = 0; r == LM_OK && p < x->np; ++p)
        for (uint32_t j = 0; r == LM_OK && j < x->count[p]; ++j) r = take(x, x->hit[(size_t)p * R + j], err);
    x->np = 0;
    return r;
}

static lm_result add_point(reach *x, samp_point p, lm_error *err)
{
    x->pts[x->np++] = p;
    return x->np == REACH_BATCH ? flush(x, err) : LM_OK;
}

/* The scene's area per reach point (the triangles with albedo). */
static double reach_unit(cache *c)
{
    if (c->reach_unit > 0.0) return c->reach_unit;
    double total = 0.0;
    for (uint32_t t = 0; t < c->s->tri_count; ++t)
        if (cache_has_albedo(c->s, t, NULL)) total += c->s->tri_areas[t];
    c->reach_unit = total > 0.0 ? total / CACHE_REACH_POINTS : 1.0;
    return c->reach_unit;
}

/* Points of triangle t to trace from: its root corners (once per vertex id per
 * round: stamp), and points spread over it when it is large (the R2 sequence,
 * folded into the triangle). */
static lm_result add_triangle(reach *x, uint32_t t, uint32_t *stamp, uint32_t round, lm_error *err)
{
    cache *c = x->c;
    if (!cache_has_albedo(c->s, t, NULL)) return LM_OK; /* it gathers nothing */
    const uint32_t limit = mesh_vtable_id_limit(c->vt);
    lm_result r = LM_OK;
    for (int k = 0; r == LM_OK && k < 3; ++k) {
        /* Its roots come after the reach (cache.c, add_roots_all): the scene
         * corner's vertex, which the cache holds from its creation (hold_corners). */
        uint32_t vid = mesh_vtable_corner_id(c->vt, t, k);
        if (vid >= limit || stamp[vid] == round) continue;
        stamp[vid] = round;
        r = add_point(x, cache_gather_point(c, vid), err);
    }
    double want = c->s->tri_areas[t] / reach_unit(c);
    uint32_t extra = want >= REACH_POINTS_MAX ? REACH_POINTS_MAX : (uint32_t)want;
    const scene *s = c->s;
    const float *a = s->positions + 3 * (size_t)s->tris[t].v[0], *b = s->positions + 3 * (size_t)s->tris[t].v[1],
                *cc = s->positions + 3 * (size_t)s->tris[t].v[2];
    for (uint32_t i = 0; r == LM_OK && i < extra; ++i) {
        double u = fmod(0.5 + (i + 1) * 0.7548776662466927, 1.0), v = fmod(0.5 + (i + 1) * 0.5698402909980532, 1.0);
        if (u + v > 1.0) u = 1.0 - u, v = 1.0 - v;
        samp_point p = {.tri_plus_one = t + 1};
        for (int k = 0; k < 3; ++k) {
            p.p[k] = (float)((1.0 - u - v) * a[k] + u * b[k] + v * cc[k]);
            p.n[k] = s->tri_normals[3 * (size_t)t + (size_t)k];
        }
        r = add_point(x, p, err);
    }
    return r;
}

/* Breadth first from x->list[from ..]: each round traces from the triangles the
 * one before took, until a round takes none. */
static lm_result close_reach(reach *x, size_t from, lm_error *err)
{
    const uint32_t limit = mesh_vtable_id_limit(x->c->vt);
    uint32_t *stamp = calloc(limit ? limit : 1, sizeof *stamp), round = 0;
    lm_result r = stamp ? LM_OK : lm_fail(err, LM_ERR_NO_MEMORY, "out of memory finding what gathers reach");
    /* (Once every triangle takes part there is nothing left to find.) */
    while (r == LM_OK && from < x->n && x->c->active_count < x->c->s->tri_count) {
        const size_t to = x->n;
        round++;
        for (size_t i = from; r == LM_OK && i < to; ++i) {
            /* A large part is traced from every stride-th triangle: what it can
             * reach, REACH_PART_TRIANGLES of them find, and it is taken whole. */
            uint32_t t = x->list[i], p = x->c->s->tris[t].part;
            uint32_t size = x->c->part_first ? x->c->part_first[p + 1] - x->c->part_first[p] : 1;
            uint32_t stride = size > REACH_PART_TRIANGLES ? size / REACH_PART_TRIANGLES : 1;
            if (t % stride == 0) r = add_triangle(x, t, stamp, round, err);
        }
        if (r == LM_OK) r = flush(x, err);
        from = to;
    }
    free(stamp);
    return r;
}

/* Frees the tracer; hands over its list of newly taken triangles when r is LM_OK. */
static lm_result reach_finish(reach *x, lm_result r, uint32_t **out, uint32_t *nout)
{
    reach_close(x);
    if (r != LM_OK) {
        free(x->list);
        return r;
    }
    *out = x->list;
    *nout = (uint32_t)x->n;
    return LM_OK;
}

lm_result cache_reach_take(cache *c, const uint32_t *seed, uint32_t nseed, uint32_t **out, uint32_t *nout,
                           lm_error *err)
{
    *out = NULL;
    *nout = 0;
    reach x;
    lm_result r = reach_open(&x, c, err);
    for (uint32_t i = 0; r == LM_OK && i < nseed; ++i) r = take(&x, seed[i], err);
    if (r == LM_OK) r = close_reach(&x, 0, err);
    return reach_finish(&x, r, out, nout);
}

lm_result cache_reach_from_gathers(cache *c, uint32_t **out, uint32_t *nout, lm_error *err)
{
    *out = NULL;
    *nout = 0;
    const uint64_t samples = c->src.indirect_stats.samples;
    if (!c->active || c->active_count == c->s->tri_count || samples < c->reach_scan_at + c->reach_scan_at / 8 + 1)
        return LM_OK; /* everything takes part already, or too little new to look at */
    c->reach_scan_at = samples;
    const uint32_t limit = mesh_vtable_id_limit(c->vt);
    if (limit > c->reach_traced_cap) {
        if (!lm_realloc_array(&c->reach_traced, c->reach_traced_cap, limit, 1))
            return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory finding what gathers reach");
        c->reach_traced_cap = limit;
    }
    reach x;
    lm_result r = reach_open(&x, c, err);
    for (uint32_t vid = 0; r == LM_OK && vid < limit; ++vid) {
        if (c->reach_traced[vid] || mesh_qmesh_get_value(c->indirect, vid, NULL) != 1) continue;
        c->reach_traced[vid] = 1;
        r = add_point(&x, cache_gather_point(c, vid), err);
    }
    if (r == LM_OK) r = flush(&x, err);
    if (r == LM_OK) r = close_reach(&x, 0, err);
    return reach_finish(&x, r, out, nout);
}
