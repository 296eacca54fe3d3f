/* samp_geom.c — what the sampler front end (samp.c), its back ends
 * (samp_embree.c, samp_gl*.c, samp_auto.c) and the coarse radiance mesh
 * (samp_coarse.c) share about a scene: where a receiver's rays start
 * (samp_point_origin), the unoccluded G of an area light, and receivers drawn
 * by area. The bottom of sampling/'s calls: it calls only analytic.c and
 * src/base, so calls run one way, samp.c → back ends → here (samp_internal.h).
 * Pure functions of their arguments: any thread. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "sampling/analytic.h"
#include "sampling/samp_internal.h"
#include "src/base/vecmath.h"

double samp_area_light_unoccluded(const scene *s, uint32_t light, const float p[3], const float n[3])
{
    const scene_area_light *L = &s->area_lights[light];
    const double x[3] = {p[0], p[1], p[2]}, nx[3] = {n[0], n[1], n[2]};
    double g = 0.0;
    for (uint32_t i = 0; i < L->count; ++i) {
        const uint32_t *v = s->tris[s->light_tris[L->first + i]].v;
        double tri[3][3];
        for (int c = 0; c < 3; ++c)
            for (int k = 0; k < 3; ++k) tri[c][k] = s->positions[3 * (size_t)v[c] + (size_t)k];
        g += samp_polygon_G(tri, 3, x, nx);
    }
    return g;
}

void samp_point_origin(const scene *s, const samp_point *x, float eps, float out[3])
{
    lm_vec3 p = v3_load(x->p);
    if (x->tri_plus_one > 0 && x->tri_plus_one <= s->tri_count) {
        const uint32_t *v = s->tris[x->tri_plus_one - 1].v;
        lm_vec3 c = v3_scale(v3_add(v3_add(v3_load(s->positions + 3 * (size_t)v[0]),
                                           v3_load(s->positions + 3 * (size_t)v[1])),
                                    v3_load(s->positions + 3 * (size_t)v[2])),
                             1.0f / 3.0f);
        lm_vec3 to_c = v3_sub(c, p);
        float d = v3_length(to_c);
        /* Never past the centroid: a tiny triangle keeps its point inside. */
        if (d > 0.0f) p = v3_add(p, v3_scale(to_c, fminf(eps, 0.5f * d) / d));
    }
    v3_store(out, v3_add(p, v3_scale(v3_load(x->n), eps)));
}

uint32_t samp_cdf_pick(const double *cdf, uint32_t n, double u)
{
    uint32_t lo = 0, hi = n - 1;
    while (lo < hi) {
        uint32_t mid = (lo + hi) / 2;
        if (u < cdf[mid])
            hi = mid;
        else
            lo = mid + 1;
    }
    return lo;
}

double *samp_area_cdf(const scene *s)
{
    double *cdf = malloc((s->tri_count ? s->tri_count : 1) * sizeof *cdf), total = 0.0;
    if (!cdf) return NULL;
    for (uint32_t t = 0; t < s->tri_count; ++t) cdf[t] = (total += s->tri_areas[t]);
    for (uint32_t t = 0; t < s->tri_count; ++t) cdf[t] /= total;
    if (s->tri_count) cdf[s->tri_count - 1] = 1.0;
    return cdf;
}

samp_point samp_random_receiver(const scene *s, const double *area_cdf, lm_rng *g)
{
    uint32_t t = 0;
    for (int tries = 0; tries < 1000; ++tries) { /* a scene is never only lights (scene_load) */
        t = samp_cdf_pick(area_cdf, s->tri_count, lm_rng_float(g));
        if (s->tris[t].light < 0) break;
    }
    float u = lm_rng_float(g), v = lm_rng_float(g);
    if (u + v > 1.0f) {
        u = 1.0f - u;
        v = 1.0f - v;
    }
    const uint32_t *vi = s->tris[t].v;
    samp_point x = {.tri_plus_one = t + 1};
    for (int k = 0; k < 3; ++k) {
        x.p[k] = (1.0f - u - v) * s->positions[3 * (size_t)vi[0] + (size_t)k] +
                 u * s->positions[3 * (size_t)vi[1] + (size_t)k] + v * s->positions[3 * (size_t)vi[2] + (size_t)k];
        x.n[k] = s->tri_normals[3 * (size_t)t + (size_t)k];
    }
    return x;
}

uint64_t samp_point_hash(const samp_point *x)
{
    uint64_t h = 0x84222325cbf29ce4ull;
    const float *f[2] = {x->p, x->n};
    for (int a = 0; a < 2; ++a)
        for (int k = 0; k < 3; ++k) {
            uint32_t bits;
            memcpy(&bits, &f[a][k], sizeof bits);
            h = (h ^ bits) * 0x100000001b3ull;
        }
    return h;
}

samp_frame samp_frame_make(const float normal[3])
{
    lm_vec3 n = v3_normalize(v3_load(normal));
    float sign = copysignf(1.0f, n.z), a = -1.0f / (sign + n.z), b = n.x * n.y * a;
    return (samp_frame){v3(1.0f + sign * n.x * n.x * a, sign * b, -sign * n.x), v3(b, sign + n.y * n.y * a, -n.y), n};
}

lm_vec3 samp_frame_cosine(const samp_frame *f, float u, float v)
{
    float r = sqrtf(u), phi = 2.0f * (float)M_PI * v;
    float lx = r * cosf(phi), ly = r * sinf(phi), lz = sqrtf(fmaxf(0.0f, 1.0f - u));
    return v3_add(v3_add(v3_scale(f->t1, lx), v3_scale(f->t2, ly)), v3_scale(f->n, lz));
}

int samp_stratum_front_hit(const scene *s, const rt_scene *rt, const samp_frame *f, const float origin[3], lm_rng *g,
                           int a, int b, int k, rt_hit *h)
{
    float u = (a + lm_rng_float(g)) / k, v = (b + lm_rng_float(g)) / k;
    lm_vec3 d = samp_frame_cosine(f, u, v);
    float dir[3];
    v3_store(dir, d);
    return rt_intersect(rt, origin, dir, 0.0f, INFINITY, h) &&
           v3_dot(v3_load(s->tri_normals + 3 * (size_t)h->tri), d) < 0.0f;
}

