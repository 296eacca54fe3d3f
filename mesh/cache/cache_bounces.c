/* cache_bounces.c — diffuse bounces beyond the first (issue 13; docs/cache.md,
 * "Bounces").
 *
 * The displayed indirect mesh gathers the first bounce from kd·L_dd over the
 * source cut (cache_source.c). Bounces 2..K reach it through the same source,
 * which then holds kd·(L_dd + E_m/π) with
 *     E_m = B_1 + … + B_(K−1),
 * B_k the irradiance of bounce k at the coarse vertices (the corners of the
 * indirect roots), linear over each scene triangle (c->indirect1). The displayed
 * gather of that source is bounces 1..K at the displayed vertices: the final
 * gather hides the coarse solution's size and noise, as in photon-map final
 * gathering; only bounce 1 needs the refined source (a shadow edge, a lamp's
 * spot), the later ones are smooth.
 *
 * The B_k come from a transport traced once (cache_bounces_init): R stratified
 * cosine-weighted rays per coarse vertex (Embree, samp_surface_hits_trace), each
 * hit on the front of a surface with albedo kept as its triangle and
 * barycentric. With no ray after that,
 *     B_1(v)     = π/R · Σ_h kd(h)·L_dd(h)     L_dd from the direct mesh as it is now
 *     B_(k+1)(v) = 1/R · Σ_h kd(h)·B_k(h)      B_k linear over h's scene triangle
 * (the Jacobi iteration of the radiosity system on the coarse vertices, with
 * the same hits for every bounce). cache_bounces_update re-evaluates it whenever
 * the source is rebuilt: refinement of the direct mesh, a light edit, a sampler
 * change. A light edit therefore takes no sample here either.
 *
 * auto (CACHE_BOUNCES_AUTO): the smallest K whose picture is within the JND of
 * all bounces' at every seen coarse vertex: the tone-mapped colour (CIELAB ΔE,
 * the cache's own figures: L_dd from the direct mesh) with E ≈ B_1 + … + B_K
 * against E ≈ B_1 + B_2 + … (iterated until a bounce adds under 1e-4 of the
 * sum, at most CACHE_BOUNCES_MAX). Not "the next bounce is below the JND": in a
 * sphere of albedo 0.5 at JND 1 that stops at 3 bounces, ΔE 1.6 from the whole
 * series (tests/cache_test.c). cache_bounce_stats.why says why it stopped. The
 * specular term is left out of that colour: it only masks, so the count errs high.
 *
 * Does NOT do: the transport's own noise and bias (R rays per vertex, fixed; the
 * barycentric interpolation of B_k over a whole scene triangle), or glossy
 * interreflection (the model transport is diffuse after the first bounce).
 * Threads: the cache's (one thread); the tracing uses the sampler's threads.
 */
#include "mesh/cache/cache_internal.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "src/base/tonemap.h"
#include "src/base/vecmath.h"

void cache_bounces_free(cache_bounce_state *b)
{
    free(b->vid);
    free(b->corner);
    free(b->hit_first);
    free(b->hit_tri);
    free(b->hit_bary);
    free(b->b);
    free(b->next);
    free(b->sum);
    free(b->shown);
    free(b->whole);
    free(b->rest);
    free(b->seen);
    memset(b, 0, sizeof *b);
}

static int keeps_light(const scene *s, uint32_t t, void *user)
{
    (void)user;
    const float *kd = s->materials[s->tris[t].material].kd;
    return kd[0] > 0.0f || kd[1] > 0.0f || kd[2] > 0.0f;
}

/* The coarse vertices: the root corners of c->indirect1, and per scene
 * triangle the coarse index of each of its corners in the triangle's own order. */
static lm_result index_vertices(cache *c, lm_error *err)
{
    cache_bounce_state *b = &c->bnc;
    const scene *s = c->s;
    const uint32_t limit = mesh_vtable_id_limit(c->vt);
    uint32_t *at = malloc((limit ? limit : 1) * sizeof *at);
    b->corner = malloc(3 * (size_t)(s->tri_count ? s->tri_count : 1) * sizeof *b->corner);
    b->vid = malloc(3 * (size_t)(s->tri_count ? s->tri_count : 1) * sizeof *b->vid);
    if (!at || !b->corner || !b->vid) {
        free(at);
        return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory for the bounces' transport");
    }
    for (uint32_t i = 0; i < limit; ++i) at[i] = UINT32_MAX;
    b->nv = 0;
    for (uint32_t t = 0; t < s->tri_count; ++t) {
        uint32_t root = mesh_qmesh_root(c->indirect1, t);
        for (int k = 0; k < 3; ++k) b->corner[3 * (size_t)t + (size_t)k] = UINT32_MAX;
        if (root == MESH_QMESH_NONE) continue;
        const mesh_qnode *nd = mesh_qmesh_node(c->indirect1, root);
        for (int k = 0; k < 3; ++k) {
            double w1, w2;
            cache_node_corner_bary(nd, k, &w1, &w2);
            int scene_corner = w1 > 0.5 ? 1 : w2 > 0.5 ? 2 : 0;
            uint32_t v = nd->v[k];
            if (v >= limit) continue;
            if (at[v] == UINT32_MAX) {
                at[v] = b->nv;
                b->vid[b->nv++] = v;
            }
            b->corner[3 * (size_t)t + (size_t)scene_corner] = at[v];
        }
    }
    free(at);
    return LM_OK;
}

lm_result cache_bounces_init(cache *c, lm_error *err)
{
    cache_bounce_state *b = &c->bnc;
    if (!c->indirect1 || b->hit_first) return LM_OK;
    double t0 = lm_now_seconds();
    const uint32_t R = c->desc.bounce_rays;
    lm_result r = index_vertices(c, err);
    const uint32_t nv = b->nv;
    samp_point *pts = NULL;
    uint32_t *count = NULL, *tri = NULL;
    float *bary = NULL;
    if (r == LM_OK) {
        size_t n = nv ? nv : 1;
        pts = malloc(n * sizeof *pts);
        count = malloc(n * sizeof *count);
        tri = malloc(n * R * sizeof *tri);
        bary = malloc(2 * n * R * sizeof *bary);
        b->hit_first = malloc((n + 1) * sizeof *b->hit_first);
        b->b = calloc(3 * n, sizeof *b->b);
        b->next = calloc(3 * n, sizeof *b->next);
        b->sum = calloc(3 * n, sizeof *b->sum);
        b->shown = calloc(3 * n, sizeof *b->shown);
        b->whole = calloc(3 * n, sizeof *b->whole);
        b->rest = calloc(3 * n, sizeof *b->rest);
        b->seen = malloc(n);
        if (!pts || !count || !tri || !bary || !b->hit_first || !b->b || !b->next || !b->sum || !b->shown ||
            !b->whole || !b->rest || !b->seen)
            r = lm_fail(err, LM_ERR_NO_MEMORY, "out of memory tracing the bounces' transport (%u vertices)", nv);
    }
    if (r == LM_OK) {
        memset(b->seen, 1, nv ? nv : 1);
        for (uint32_t i = 0; i < nv; ++i) pts[i] = cache_vertex_point(c, b->vid[i]);
        r = samp_surface_hits_trace(c->sp, pts, nv,
                                    &(samp_surface_hits){.rays = R, .count = count, .tri = tri, .bary = bary,
                                                         .keep = keeps_light},
                                    err);
    }
    /* Kept compact: each vertex's hits one after the other. */
    uint64_t total = 0;
    for (uint32_t i = 0; r == LM_OK && i < nv; ++i) total += count[i];
    if (r == LM_OK && total >= UINT32_MAX)
        r = lm_fail(err, LM_ERR_NO_MEMORY, "the bounces' transport has too many hits (%llu)", (unsigned long long)total);
    if (r == LM_OK) {
        b->hit_tri = malloc((total ? total : 1) * sizeof *b->hit_tri);
        b->hit_bary = malloc(2 * (total ? total : 1) * sizeof *b->hit_bary);
        if (!b->hit_tri || !b->hit_bary) r = lm_fail(err, LM_ERR_NO_MEMORY, "out of memory for the bounces' transport");
    }
    if (r == LM_OK) {
        uint32_t h = 0;
        for (uint32_t i = 0; i < nv; ++i) {
            b->hit_first[i] = h;
            memcpy(b->hit_tri + h, tri + (size_t)i * R, count[i] * sizeof *tri);
            memcpy(b->hit_bary + 2 * (size_t)h, bary + 2 * (size_t)i * R, 2 * count[i] * sizeof *bary);
            h += count[i];
        }
        b->hit_first[nv] = h;
        b->stats.vertices = nv;
        b->stats.rays = R;
        b->stats.hits = total;
        b->bytes = (size_t)total * 3 * sizeof(float) + (size_t)nv * (6 * 3 * sizeof(float) + 2 * sizeof(uint32_t) + 1) +
                   3 * (size_t)c->s->tri_count * sizeof(uint32_t);
    }
    free(pts);
    free(count);
    free(tri);
    free(bary);
    b->stats.trace_seconds = lm_now_seconds() - t0;
    return r;
}

/* Which coarse vertices are seen: the corners of triangles with pixels. */
static void mark_seen(cache *c, const uint32_t *pixels)
{
    cache_bounce_state *b = &c->bnc;
    memset(b->seen, 0, b->nv ? b->nv : 1);
    for (uint32_t t = 0; t < c->s->tri_count; ++t)
        if (pixels[t])
            for (int k = 0; k < 3; ++k) {
                uint32_t i = b->corner[3 * (size_t)t + (size_t)k];
                if (i != UINT32_MAX) b->seen[i] = 1;
            }
}

/* out = what vertex i's hits see of the per-vertex field `from` (RGB), each hit
 * weighted by its albedo, summed over the hits over R: B_(k+1) from B_k. */
static void propagate(const cache *c, const float *from, float *out)
{
    const cache_bounce_state *b = &c->bnc;
    const scene *s = c->s;
    const float inv = 1.0f / (float)b->stats.rays;
    for (uint32_t i = 0; i < b->nv; ++i) {
        double acc[3] = {0, 0, 0};
        for (uint32_t h = b->hit_first[i]; h < b->hit_first[i + 1]; ++h) {
            uint32_t t = b->hit_tri[h];
            const uint32_t *cn = b->corner + 3 * (size_t)t;
            if (cn[0] == UINT32_MAX || cn[1] == UINT32_MAX || cn[2] == UINT32_MAX) continue;
            float w1 = b->hit_bary[2 * (size_t)h], w2 = b->hit_bary[2 * (size_t)h + 1], w0 = 1.0f - w1 - w2;
            const float *kd = s->materials[s->tris[t].material].kd;
            for (int ch = 0; ch < 3; ++ch)
                acc[ch] += kd[ch] * (w0 * from[3 * (size_t)cn[0] + (size_t)ch] + w1 * from[3 * (size_t)cn[1] + (size_t)ch] +
                                     w2 * from[3 * (size_t)cn[2] + (size_t)ch]);
        }
        for (int ch = 0; ch < 3; ++ch) out[3 * (size_t)i + (size_t)ch] = (float)acc[ch] * inv;
    }
}

/* B_1 from the direct mesh as it is now. */
static void first_bounce(const cache *c, float *out)
{
    const cache_bounce_state *b = &c->bnc;
    const scene *s = c->s;
    const float scale = (float)M_PI / (float)b->stats.rays;
    for (uint32_t i = 0; i < b->nv; ++i) {
        double acc[3] = {0, 0, 0};
        for (uint32_t h = b->hit_first[i]; h < b->hit_first[i + 1]; ++h) {
            uint32_t t = b->hit_tri[h];
            if (mesh_qmesh_root(c->direct, t) == MESH_QMESH_NONE) continue;
            float L[3];
            lm_error ignore;
            if (mesh_qmesh_interpolate(c->direct, t, b->hit_bary[2 * (size_t)h], b->hit_bary[2 * (size_t)h + 1], L,
                                       &ignore) != LM_OK)
                continue;
            const float *kd = s->materials[s->tris[t].material].kd;
            for (int ch = 0; ch < 3; ++ch) acc[ch] += kd[ch] * L[ch];
        }
        for (int ch = 0; ch < 3; ++ch) out[3 * (size_t)i + (size_t)ch] = (float)acc[ch] * scale;
    }
}

/* The largest ΔE, over the seen corners of every triangle, between the colour
 * with indirect irradiance `shown` and with `shown + more`. */
static float largest_change(const cache *c, const float *shown, const float *more)
{
    const cache_bounce_state *b = &c->bnc;
    const scene *s = c->s;
    float worst = 0.0f;
    for (uint32_t t = 0; t < s->tri_count; ++t)
        for (int k = 0; k < 3; ++k) {
            uint32_t i = b->corner[3 * (size_t)t + (size_t)k];
            if (i == UINT32_MAX || !b->seen[i]) continue;
            float ldd[3] = {0, 0, 0}, e0[3], e1[3], lab0[3], lab1[3];
            lm_error ignore;
            if (mesh_qmesh_root(c->direct, t) != MESH_QMESH_NONE &&
                mesh_qmesh_interpolate(c->direct, t, k == 1, k == 2, ldd, &ignore) != LM_OK)
                ldd[0] = ldd[1] = ldd[2] = 0.0f;
            for (int ch = 0; ch < 3; ++ch) {
                e0[ch] = shown[3 * (size_t)i + (size_t)ch];
                e1[ch] = e0[ch] + more[3 * (size_t)i + (size_t)ch];
            }
            cache_seen_lab(c, t, ldd, e0, NULL, lab0);
            cache_seen_lab(c, t, ldd, e1, NULL, lab1);
            worst = fmaxf(worst, tm_delta_e(lab0, lab1));
        }
    return worst;
}

/* The whole series at the coarse vertices, B_1 + B_2 + … into `whole`, until a
 * bounce adds less than a ten-thousandth anywhere or CACHE_BOUNCES_MAX are in;
 * returns how many are in. Uses b->b and b->next. */
static int whole_series(cache *c, float *whole)
{
    cache_bounce_state *b = &c->bnc;
    const size_t n3 = 3 * (size_t)b->nv;
    first_bounce(c, b->b);
    memcpy(whole, b->b, n3 * sizeof *whole);
    int k = 1;
    while (k < CACHE_BOUNCES_MAX) {
        propagate(c, b->b, b->next);
        k++;
        float rel = 0.0f;
        for (size_t j = 0; j < n3; ++j) {
            whole[j] += b->next[j];
            if (whole[j] > 0.0f) rel = fmaxf(rel, b->next[j] / whole[j]);
        }
        float *tmp = b->b;
        b->b = b->next;
        b->next = tmp;
        if (!(rel > 1e-4f)) break;
    }
    return k;
}

lm_result cache_bounces_update(cache *c, const uint32_t *pixels, lm_error *err)
{
    cache_bounce_state *b = &c->bnc;
    if (!c->indirect1) return LM_OK;
    lm_result r = b->hit_first ? LM_OK : cache_bounces_init(c, err);
    if (r != LM_OK) return r;
    double t0 = lm_now_seconds();
    if (pixels) mark_seen(c, pixels);
    const size_t n3 = 3 * (size_t)b->nv;
    const int automatic = c->desc.bounces == CACHE_BOUNCES_AUTO;
    cache_bounce_stats *st = &b->stats;
    memset(st->de, 0, sizeof st->de);
    /* The whole series first (no colour needed), then K = 1, 2, … until what is
     * shown, B_1 + … + B_K, is within the JND of it where it is seen (auto), or
     * K is the count asked. E_m = B_1 + … + B_(K−1) goes into the source. */
    int in_whole = whole_series(c, b->whole);
    for (size_t j = 0; j < n3; ++j) b->rest[j] = b->whole[j];
    first_bounce(c, b->b);
    memcpy(b->shown, b->b, n3 * sizeof *b->shown);
    memset(b->sum, 0, n3 * sizeof *b->sum);
    int K = 1;
    for (;;) {
        for (size_t j = 0; j < n3; ++j) b->rest[j] = b->whole[j] - b->shown[j];
        st->rest_de = largest_change(c, b->shown, b->rest);
        if (automatic && !(st->rest_de > c->desc.jnd)) {
            snprintf(st->why, sizeof st->why,
                     "auto: the bounces after %d would add at most ΔE %.2f where they are seen, below the JND %.2f", K,
                     (double)st->rest_de, (double)c->desc.jnd);
            break;
        }
        if (!automatic && K >= c->desc.bounces) {
            snprintf(st->why, sizeof st->why, "%d bounce%s, as asked (the rest would add ΔE %.2f where seen)", K,
                     K == 1 ? "" : "s", (double)st->rest_de);
            break;
        }
        if (K >= in_whole) {
            snprintf(st->why, sizeof st->why,
                     "%s%d bounces, all that change anything (the rest would add ΔE %.2f where seen)",
                     automatic ? "auto: " : "", K, (double)st->rest_de);
            if (K >= CACHE_BOUNCES_MAX)
                snprintf(st->why, sizeof st->why, "%s%d bounces, the most there can be (the rest would add ΔE %.2f)",
                         automatic ? "auto: " : "", K, (double)st->rest_de);
            break;
        }
        propagate(c, b->b, b->next);
        st->de[K + 1] = largest_change(c, b->shown, b->next);
        for (size_t j = 0; j < n3; ++j) {
            b->sum[j] += b->b[j];
            b->shown[j] += b->next[j];
        }
        float *tmp = b->b;
        b->b = b->next;
        b->next = tmp;
        K++;
    }
    st->bounces = K;
    st->automatic = automatic;
    for (uint32_t i = 0; r == LM_OK && i < b->nv; ++i)
        r = mesh_qmesh_set_value(c->indirect1, b->vid[i], b->sum + 3 * (size_t)i, err);
    st->update_seconds += lm_now_seconds() - t0;
    st->updates++;
    return r;
}

lm_result cache_bounces_see(cache *c, const uint32_t *pixels, lm_error *err)
{
    (void)err;
    if (c->indirect1 && c->bnc.seen && pixels) mark_seen(c, pixels);
    return LM_OK;
}
