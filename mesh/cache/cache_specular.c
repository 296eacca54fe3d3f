/* cache_specular.c — the values of the direct specular mesh (cache.h, eq. 5 of the
 * paper with V_ℓ out of the integral): the area lights' outlines (cache_outlines,
 * this file's part of the cache), built once per cache, and the Phong lobe
 * integrated over them (samp_polygon_phong). Calls no other file of the cache.
 * Worker thread, like the rest of the cache. */
#include "mesh/cache/cache_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "sampling/analytic.h"
#include "sampling/samp.h"
#include "src/base/vecmath.h"

/* ---- outlines ----------------------------------------------------------------
 *
 * A light's triangles are wound counter-clockwise seen from their front (scene.h),
 * so an edge inside the light appears once in each direction and cancels; what is
 * left is the boundary: outer loops counter-clockwise seen from the front, holes
 * clockwise. A quad light integrates four edges instead of six, and a lamp of many
 * triangles a handful. The scene model guarantees what this needs: corners welded
 * by exact position (scene_build.c), and each area light one connected group of
 * coplanar triangles facing one way (scene_lights.c), so every loop is planar. */

static lm_dvec3 dv3_of(const double *p) { return dv3(p[0], p[1], p[2]); }

typedef struct outline_edge {
    uint64_t key;  /* min << 32 | max (scene vertex ids) */
    int32_t count; /* net multiplicity, from → to positive */
} outline_edge;

/* Growing arrays of the outline being built. */
typedef struct outline_buf {
    double *xyz;
    uint32_t *loop;
    int8_t *sign;
    uint32_t *light_loop;
    size_t xyz_n, xyz_cap, loop_n, loop_cap;
} outline_buf;

static int cmp_u64(const void *a, const void *b)
{
    uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
    return (x > y) - (x < y);
}

static int cmp_edge(const void *a, const void *b) { return cmp_u64(&((const outline_edge *)a)->key, &((const outline_edge *)b)->key); }

static int push_point(outline_buf *b, const float p[3])
{
    /* xyz holds points of three doubles: one capacity in points. */
    size_t nc = lm_grow_capacity(b->xyz_cap, b->xyz_n + 1, 64, SIZE_MAX / (3 * sizeof *b->xyz));
    if (!nc || !lm_realloc_array(&b->xyz, b->xyz_cap, nc, 3 * sizeof *b->xyz)) return 0;
    b->xyz_cap = nc;
    for (int k = 0; k < 3; ++k) b->xyz[3 * b->xyz_n + (size_t)k] = p[k];
    b->xyz_n++;
    return 1;
}

/* Closes the loop that started at point `start`: drops vertices where the outline
 * goes straight on, orients it (sign −1 and reversed when it turns clockwise about
 * `front`), and records it. A loop with fewer than three corners left is dropped. */
static int close_loop(outline_buf *b, size_t start, const float front[3])
{
    size_t n = b->xyz_n - start, m = 0;
    double *P = b->xyz + 3 * start;
    /* Straight-through vertices: the cross product of the two edges is tiny
     * against their lengths. Kept in place, in order. */
    for (size_t i = 0; i < n; ++i) {
        const double *a = P + 3 * ((i + n - 1) % n), *c = P + 3 * i, *d = P + 3 * ((i + 1) % n);
        lm_dvec3 e0 = dv3_sub(dv3_of(c), dv3_of(a)), e1 = dv3_sub(dv3_of(d), dv3_of(c));
        double cr = dv3_length(dv3_cross(e0, e1)), scale = dv3_length(e0) * dv3_length(e1);
        if (cr <= 1e-9 * scale && dv3_dot(e0, e1) > 0.0) continue;
        if (m != i) memmove(P + 3 * m, c, 3 * sizeof *P);
        m++;
    }
    b->xyz_n = start + m;
    if (m < 3) {
        b->xyz_n = start;
        return 1;
    }
    /* Newell normal against the light's front. */
    lm_dvec3 nn = {0, 0, 0};
    for (size_t i = 0; i < m; ++i) {
        const double *a = P + 3 * i, *c = P + 3 * ((i + 1) % m);
        nn.x += (a[1] - c[1]) * (a[2] + c[2]);
        nn.y += (a[2] - c[2]) * (a[0] + c[0]);
        nn.z += (a[0] - c[0]) * (a[1] + c[1]);
    }
    int8_t sign = nn.x * front[0] + nn.y * front[1] + nn.z * front[2] >= 0.0 ? 1 : -1;
    if (sign < 0) /* a hole: stored counter-clockwise, subtracted */
        for (size_t i = 0; i < m / 2; ++i)
            for (int k = 0; k < 3; ++k) {
                double t = P[3 * i + (size_t)k];
                P[3 * i + (size_t)k] = P[3 * (m - 1 - i) + (size_t)k];
                P[3 * (m - 1 - i) + (size_t)k] = t;
            }
    if (b->loop_n + 2 > b->loop_cap) { /* loop and sign share one capacity */
        size_t nc = lm_grow_capacity(b->loop_cap, b->loop_n + 2, 16, SIZE_MAX / sizeof *b->loop);
        if (!nc || !lm_realloc_array(&b->loop, b->loop_cap, nc, sizeof *b->loop) ||
            !lm_realloc_array(&b->sign, b->loop_cap, nc, sizeof *b->sign))
            return 0;
        b->loop_cap = nc;
    }
    b->sign[b->loop_n] = sign;
    b->loop[++b->loop_n] = (uint32_t)b->xyz_n;
    return 1;
}

/* The boundary loops of one light. */
static int outline_light(const scene *s, const scene_area_light *L, outline_buf *b)
{
    const uint32_t nv = 3 * L->count;
    outline_edge *e = malloc((nv ? nv : 1) * sizeof *e);
    uint64_t *out = malloc((nv ? nv : 1) * sizeof *out);
    uint8_t *used = calloc(nv ? nv : 1, 1);
    int ok = e && out && used;
    /* Edges by (min, max) vertex id with a sign: +1 going up, −1 going down. */
    size_t ne = 0;
    for (uint32_t i = 0; ok && i < L->count; ++i) {
        const uint32_t *v = s->tris[s->light_tris[L->first + i]].v;
        for (uint32_t k = 0; k < 3; ++k) {
            uint32_t a = v[k], c = v[(k + 1) % 3];
            if (a == c) continue; /* degenerate */
            uint32_t lo = a < c ? a : c, hi = a < c ? c : a;
            e[ne].key = (uint64_t)lo << 32 | hi;
            e[ne++].count = a < c ? 1 : -1;
        }
    }
    if (ok) qsort(e, ne, sizeof *e, cmp_edge);
    /* Net edges, as directed keys from << 32 | to, sorted for the chaining. */
    size_t no = 0;
    for (size_t i = 0; ok && i < ne;) {
        size_t j = i;
        int32_t net = 0;
        for (; j < ne && e[j].key == e[i].key; ++j) net += e[j].count;
        uint32_t lo = (uint32_t)(e[i].key >> 32), hi = (uint32_t)e[i].key;
        for (int32_t m = 0; m < (net < 0 ? -net : net); ++m)
            out[no++] = net > 0 ? e[i].key : (uint64_t)hi << 32 | lo;
        i = j;
    }
    if (ok) qsort(out, no, sizeof *out, cmp_u64);
    /* Chain: from an unused edge, follow an unused edge leaving its end. */
    for (size_t first = 0; ok && first < no; ++first) {
        if (used[first]) continue;
        size_t start = b->xyz_n, cur = first;
        const uint32_t loop_from = (uint32_t)(out[first] >> 32);
        for (size_t steps = 0; ok && steps <= no; ++steps) {
            used[cur] = 1;
            uint32_t from = (uint32_t)(out[cur] >> 32), to = (uint32_t)out[cur];
            ok = push_point(b, s->positions + 3 * (size_t)from);
            if (to == loop_from) break; /* closed (a vertex two loops touch ends each) */
            /* the edges leaving `to` start at the lower bound of to << 32 */
            size_t lo = 0, hi = no;
            uint64_t want = (uint64_t)to << 32;
            while (lo < hi) {
                size_t mid = (lo + hi) / 2;
                if (out[mid] < want) lo = mid + 1; else hi = mid;
            }
            size_t next = no;
            for (size_t j = lo; j < no && (uint32_t)(out[j] >> 32) == to; ++j)
                if (!used[j]) {
                    next = j;
                    break;
                }
            if (next == no) break; /* an open chain (cannot happen for net edges): closed here */
            cur = next;
        }
        if (ok) ok = close_loop(b, start, L->normal);
    }
    free(e);
    free(out);
    free(used);
    return ok;
}

int cache_build_outlines(cache_outlines *o, const scene *s, uint32_t light_count)
{
    outline_buf b = {0};
    b.light_loop = calloc((size_t)light_count + 1, sizeof *b.light_loop);
    b.loop = calloc(16, sizeof *b.loop);
    b.sign = calloc(16, sizeof *b.sign);
    b.loop_cap = 16;
    int ok = b.light_loop && b.loop && b.sign;
    for (uint32_t l = 0; ok && l < light_count; ++l) {
        b.light_loop[l] = (uint32_t)b.loop_n;
        if (l < s->area_light_count) ok = outline_light(s, &s->area_lights[l], &b);
    }
    if (ok) b.light_loop[light_count] = (uint32_t)b.loop_n;
    if (!ok) {
        free(b.xyz);
        free(b.loop);
        free(b.sign);
        free(b.light_loop);
        return 0;
    }
    o->xyz = b.xyz;
    o->loop = b.loop;
    o->loop_sign = b.sign;
    o->light_loop = b.light_loop;
    o->bytes = b.xyz_cap * 3 * sizeof(double) + b.loop_cap * (sizeof(uint32_t) + 1) +
               ((size_t)light_count + 1) * sizeof(uint32_t);
    return 1;
}

void cache_outlines_free(cache_outlines *o)
{
    free(o->xyz);
    free(o->loop);
    free(o->light_loop);
    free(o->loop_sign);
    memset(o, 0, sizeof *o);
}

/* ---- values ------------------------------------------------------------------- */

/* S_ℓ(x, ωo): the lobe integrated over light l (area: its loops, holes
 * subtracted), or for a point light its lobe towards the point times G. */
static double light_phong(const cache *c, uint32_t l, const double x[3], const double nx[3], const double wo[3],
                          double n)
{
    const scene *s = c->s;
    if (l >= s->area_light_count) {
        const float *q = s->point_lights[l - s->area_light_count].position;
        const double Q[3] = {q[0], q[1], q[2]};
        double g = samp_point_G(Q, x, nx);
        if (!(g > 0.0)) return 0.0;
        lm_dvec3 ns = dv3_normalize(dv3_of(nx)), w = dv3_normalize(dv3_of(wo));
        lm_dvec3 wi = dv3_normalize(dv3_sub(dv3_of(Q), dv3_of(x)));
        lm_dvec3 mirror = dv3_sub(dv3_scale(ns, 2.0 * dv3_dot(ns, wi)), wi);
        double cosa = dv3_dot(mirror, w);
        return cosa > 0.0 ? (n + 2.0) / (2.0 * M_PI) * pow(cosa, n) * g : 0.0;
    }
    const cache_outlines *o = &c->outl;
    double sum = 0.0;
    for (uint32_t k = o->light_loop[l]; k < o->light_loop[l + 1]; ++k) {
        const double(*P)[3] = (const double(*)[3])(o->xyz + 3 * (size_t)o->loop[k]);
        int np = (int)(o->loop[k + 1] - o->loop[k]);
        sum += o->loop_sign[k] * samp_polygon_phong(P, np, x, nx, wo, n);
    }
    return sum > 0.0 ? sum : 0.0; /* a hole's round-off cannot make light negative */
}

/* Can x (normal nx) see any of light l at all: some corner of its bounding box
 * above x's horizon, and x in front of its emitting side (a point light: above
 * the horizon)? A bound, not G_ℓ's integral: it runs for every light at every
 * specular value. */
static int light_above(const scene *s, uint32_t l, const float x[3], const float nx[3])
{
    if (l >= s->area_light_count) {
        const float *p = s->point_lights[l - s->area_light_count].position;
        return (p[0] - x[0]) * nx[0] + (p[1] - x[1]) * nx[1] + (p[2] - x[2]) * nx[2] > 0.0f;
    }
    const scene_area_light *L = &s->area_lights[l];
    const float *p0 = s->positions + 3 * (size_t)s->tris[s->light_tris[L->first]].v[0];
    if (!((x[0] - p0[0]) * L->normal[0] + (x[1] - p0[1]) * L->normal[1] + (x[2] - p0[2]) * L->normal[2] > 0.0f))
        return 0;
    for (int k = 0; k < 8; ++k) {
        float d = 0.0f;
        for (int a = 0; a < 3; ++a) d += ((k >> a & 1 ? L->bounds_max[a] : L->bounds_min[a]) - x[a]) * nx[a];
        if (d > 0.0f) return 1;
    }
    return 0;
}

lm_result cache_specular_reserve(cache *c, uint32_t limit, lm_error *err)
{
    if (limit > c->spec_visible_cap) {
        size_t cap = lm_grow_capacity(c->spec_visible_cap, limit, 1024, SIZE_MAX / sizeof *c->spec_visible);
        if (!cap || !lm_realloc_array(&c->spec_visible, c->spec_visible_cap, cap, sizeof *c->spec_visible))
            return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory for the specular values");
        for (size_t i = c->spec_visible_cap; i < cap; ++i) c->spec_visible[i] = 1.0f;
        c->spec_visible_cap = cap;
    }
    return LM_OK;
}

lm_result cache_specular_from_visibility(cache *c, uint32_t vid, const float *V, float rgb[3], lm_error *err)
{
    const scene *s = c->s;
    const mesh_vertex *mv = mesh_vtable_vertex(c->vt, vid);
    /* The exponent of the triangle the vertex was made from (a vertex shared by two
     * glossy materials takes the first's; shared vertices need equal normals). */
    double n = s->materials[s->tris[mv->tri].material].n;
    const double x[3] = {mv->position[0], mv->position[1], mv->position[2]},
                 nx[3] = {mv->normal[0], mv->normal[1], mv->normal[2]},
                 wo[3] = {c->eye[0] - x[0], c->eye[1] - x[1], c->eye[2] - x[2]};
    double e[3] = {0, 0, 0}, least = 1.0;
    for (uint32_t l = 0; l < c->light_count; ++l) {
        const float *le = c->light_le + 3 * (size_t)l;
        const double v = V[l] > 0.0f ? V[l] : 0.0;
        /* The smallest visible fraction of the lights this vertex can see at
         * all (cache_lobe.visible): 1 only where each is wholly visible. */
        if (v < least && light_above(s, l, mv->position, mv->normal)) least = v;
        if (!(v > 0.0)) continue;
        double S = light_phong(c, l, x, nx, wo, n);
        if (!(S > 0.0)) continue;
        for (int k = 0; k < 3; ++k) e[k] += v * le[k] * S;
    }
    for (int k = 0; k < 3; ++k) rgb[k] = e[k] < 3e38 ? (float)e[k] : 3e38f;
    lm_result r = cache_specular_reserve(c, vid + 1, err);
    if (r == LM_OK) c->spec_visible[vid] = (float)least;
    return r;
}

/* Whether the renderer skips area light l at x for the lobe about r of exponent
 * n (rend_value.frag: the lobe's core misses the light's bounding sphere). */
void cache_highlight_sphere(const scene_area_light *L, double centre[3], double *radius)
{
    double r2 = 0.0;
    for (int k = 0; k < 3; ++k) {
        centre[k] = 0.5 * ((double)L->bounds_min[k] + L->bounds_max[k]);
        double h = 0.5 * ((double)L->bounds_max[k] - L->bounds_min[k]);
        r2 += h * h;
    }
    *radius = 1.001 * sqrt(r2);
}

static int highlight_skips(const scene_area_light *L, const double x[3], lm_dvec3 r, double n)
{
    double c[3], radius;
    cache_highlight_sphere(L, c, &radius);
    for (int k = 0; k < 3; ++k) c[k] -= x[k];
    double dist = sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]);
    if (!(dist > radius)) return 0;
    double cosr = (r.x * c[0] + r.y * c[1] + r.z * c[2]) / dist;
    double ang = acos(cosr < -1.0 ? -1.0 : cosr > 1.0 ? 1.0 : cosr);
    return ang > asin(fmin(radius / dist, 1.0)) + CACHE_HIGHLIGHT_SKIP_CORE / sqrt(n);
}

int cache_specular_drawn(const cache *c, uint32_t a, uint32_t b, uint32_t mid, float out[3])
{
    const scene *s = c->s;
    const mesh_vertex *mv = mesh_vtable_vertex(c->vt, mid);
    const double n = s->materials[s->tris[mv->tri].material].n;
    if (!(n >= CACHE_HIGHLIGHT_MIN_EXPONENT)) return 0;
    cache_lobe la, lb;
    cache_get_lobe(c, a, &la);
    cache_get_lobe(c, b, &lb);
    const double vis = 0.5 * ((double)la.visible + lb.visible);
    if (!(vis >= CACHE_HIGHLIGHT_MIN_VISIBLE)) return 0; /* partly or wholly hidden: the renderer keeps the values */
    float va[3], vb[3];
    if (mesh_qmesh_get_value(c->specular, a, va) < 0 || mesh_qmesh_get_value(c->specular, b, vb) < 0) return 0;
    const double x[3] = {mv->position[0], mv->position[1], mv->position[2]},
                 nx[3] = {mv->normal[0], mv->normal[1], mv->normal[2]},
                 wo[3] = {c->eye[0] - x[0], c->eye[1] - x[1], c->eye[2] - x[2]};
    lm_dvec3 ns = dv3_normalize(dv3_of(nx)), w = dv3_normalize(dv3_of(wo));
    lm_dvec3 r = dv3_normalize(dv3_sub(dv3_scale(ns, 2.0 * dv3_dot(ns, w)), w));
    double U[3] = {0, 0, 0};
    for (uint32_t l = 0; l < c->light_count; ++l) {
        if (l < s->area_light_count) {
            const scene_area_light *L = &s->area_lights[l];
            if (highlight_skips(L, x, r, n)) continue;
            /* Facing x, and wholly above its horizon and in the lobe's hemisphere,
             * or the renderer keeps the interpolated value. */
            const float *p0 = s->positions + 3 * (size_t)s->tris[s->light_tris[L->first]].v[0];
            double side = 0.0;
            for (int k = 0; k < 3; ++k) side += (double)L->normal[k] * (x[k] - p0[k]);
            if (side > 0.0) {
                const cache_outlines *o = &c->outl;
                for (uint32_t k = o->light_loop[l]; k < o->light_loop[l + 1]; ++k)
                    for (uint32_t i = o->loop[k]; i < o->loop[k + 1]; ++i) {
                        lm_dvec3 d = dv3_sub(dv3_of(o->xyz + 3 * (size_t)i), dv3_of(x));
                        if (dv3_dot(d, r) < 0.0 || dv3_dot(d, ns) < 0.0) return 0;
                    }
            }
        }
        double S = light_phong(c, l, x, nx, wo, n);
        if (!(S > 0.0)) continue;
        for (int k = 0; k < 3; ++k) U[k] += c->light_le[3 * (size_t)l + (size_t)k] * S;
    }
    for (int k = 0; k < 3; ++k) {
        double rest = 0.5 * ((double)va[k] - la.direct[k] + vb[k] - lb.direct[k]);
        double v = (rest > 0.0 ? rest : 0.0) + (vis > 1.0 ? 1.0 : vis) * U[k];
        out[k] = v < 3e38 ? (float)v : 3e38f;
    }
    return 1;
}

void cache_get_lobe(const cache *c, uint32_t vid, cache_lobe *out)
{
    const mesh_vertex *mv = mesh_vtable_vertex(c->vt, vid);
    memcpy(out->normal, mv->normal, sizeof out->normal);
    out->exponent = c->s->materials[c->s->tris[mv->tri].material].n;
    float v[3] = {0, 0, 0};
    if (!c->specular || mesh_qmesh_get_value(c->specular, vid, v) < 0) memset(v, 0, sizeof v);
    /* The value is the lights' part plus the glossy part (cache_glossy.c). */
    const float *g = cache_glossy_on(c) && vid < c->gls.cap ? c->gls.rgb + 3 * (size_t)vid : NULL;
    for (int k = 0; k < 3; ++k) {
        float d = g ? v[k] - g[k] : v[k];
        out->direct[k] = d > 0.0f ? d : 0.0f;
    }
    out->visible = vid < c->spec_visible_cap ? c->spec_visible[vid] : 1.0f;
}
