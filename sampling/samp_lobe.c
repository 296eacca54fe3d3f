/* samp_lobe.c — rays drawn in proportion to a modified Phong lobe: the visible
 * fraction of an area light weighted by the lobe (samp_lobe_visibility) and the
 * radiance mesh reflected by it (samp_lobe_gather, the glossy indirect term;
 * samp.h). Embree rays whichever back end serves the sampler, as
 * samp_surface_hits_run's. Calls nothing above sampling/; threads by
 * lm_parallel_for. */
#include "sampling/samp_internal.h"

#include <math.h>
#include <string.h>

#include "src/base/parallel.h"
#include "src/base/rng.h"
#include "src/base/vecmath.h"

typedef struct lobe_job {
    const scene *s;
    const rt_scene *rt;
    uint32_t light, side, seed;
    const samp_point *pts;
    const float *wo, *exponent;
    float *V;
} lobe_job;

/* Distance along (o, d) to light triangle `tri`'s front, or 0 when the ray misses
 * it (Möller–Trumbore; the light emits on its front only: scene.h). Each lobe ray
 * tries the light's triangles in turn: a quad lamp is two; a lamp of many
 * triangles costs in proportion, on the few vertices it partly hides. */
static float light_hit(const scene *s, uint32_t tri, lm_vec3 o, lm_vec3 d)
{
    const uint32_t *v = s->tris[tri].v;
    lm_vec3 a = v3_load(s->positions + 3 * (size_t)v[0]), b = v3_load(s->positions + 3 * (size_t)v[1]),
            c = v3_load(s->positions + 3 * (size_t)v[2]);
    lm_vec3 e1 = v3_sub(b, a), e2 = v3_sub(c, a), p = v3_cross(d, e2);
    float det = v3_dot(e1, p);
    /* det = −d·(e1 × e2): positive when the ray meets the front (e1 × e2 is the
     * front normal of a counter-clockwise triangle); behind or edge-on: a miss. */
    if (!(det > 0.0f)) return 0.0f;
    float inv = 1.0f / det;
    lm_vec3 t = v3_sub(o, a);
    float u = v3_dot(t, p) * inv;
    if (u < 0.0f || u > 1.0f) return 0.0f;
    lm_vec3 q = v3_cross(t, e1);
    float w = v3_dot(d, q) * inv;
    if (w < 0.0f || u + w > 1.0f) return 0.0f;
    float dist = v3_dot(e2, q) * inv;
    return dist > 0.0f ? dist : 0.0f;
}

/* The lobe about the mirror of wo at a point of normal n: its axis r and a frame
 * (t1, t2) across it. */
typedef struct lobe_frame {
    lm_vec3 r, t1, t2;
} lobe_frame;

static lobe_frame lobe_frame_make(lm_vec3 n, lm_vec3 wo)
{
    lobe_frame f;
    f.r = v3_sub(v3_scale(n, 2.0f * v3_dot(n, wo)), wo); /* the mirror direction: the lobe's axis */
    lm_vec3 t = fabsf(f.r.x) > 0.9f ? v3(0, 1, 0) : v3(1, 0, 0);
    f.t1 = v3_normalize(v3_cross(f.r, t));
    f.t2 = v3_cross(f.r, f.t1);
    return f;
}

/* A direction drawn in proportion to cosⁿ of its angle α to the axis, from the
 * unit square (u, v): cos α = u^(1/(n+1)), its pdf (n+1)/(2π)·cosⁿα. */
static lm_vec3 lobe_direction(const lobe_frame *f, double ne, double u, double v)
{
    double ca = pow(u, 1.0 / (ne + 1.0)), sa = sqrt(fmax(0.0, 1.0 - ca * ca)), phi = 2.0 * M_PI * v;
    return v3_normalize(v3_add(v3_scale(f->r, (float)ca),
                               v3_add(v3_scale(f->t1, (float)(sa * cos(phi))), v3_scale(f->t2, (float)(sa * sin(phi))))));
}

static void lobe_one(void *user, uint32_t i)
{
    const lobe_job *j = user;
    const scene *s = j->s;
    const samp_point *x = &j->pts[i];
    const scene_area_light *L = &s->area_lights[j->light];
    const float eps = samp_point_eps_rt(j->rt, x);
    float origin[3];
    samp_point_origin(s, x, eps, origin);
    lm_vec3 o = v3_load(origin), n = v3_normalize(v3_load(x->n)), wo = v3_normalize(v3_load(j->wo + 3 * (size_t)i));
    const lobe_frame f = lobe_frame_make(n, wo);
    const double ne = j->exponent[i];
    lm_rng g;
    lm_rng_seed(&g, j->seed, i, j->light);
    double sum_w = 0.0, sum_vis = 0.0;
    for (uint32_t b = 0; b < j->side; ++b)
        for (uint32_t a = 0; a < j->side; ++a) {
            /* stratified over the lobe */
            double u = (a + lm_rng_float(&g)) / j->side, v = (b + lm_rng_float(&g)) / j->side;
            lm_vec3 d = lobe_direction(&f, ne, u, v);
            float cx = v3_dot(d, n);
            if (cx <= 0.0f) continue; /* below x's horizon: the lobe is clipped there */
            float dist = 0.0f;
            for (uint32_t k = 0; k < L->count && dist == 0.0f; ++k)
                dist = light_hit(s, s->light_tris[L->first + k], o, d);
            if (!(dist > 0.0f)) continue; /* the lobe's ray misses this light */
            float org[3], dir[3];
            v3_store(org, o);
            v3_store(dir, d);
            sum_w += cx;
            if (!rt_occluded(j->rt, org, dir, 0.0f, dist * (1.0f - 1e-4f) - eps)) sum_vis += cx;
        }
    j->V[i] = sum_w > 0.0 ? (float)(sum_vis / sum_w) : -1.0f;
}

void samp_lobe_run(const scene *s, const rt_scene *rt, uint32_t light, const samp_point *pts, const float *wo,
                   const float *exponent, uint32_t n, uint32_t side, float *V)
{
    lobe_job job = {.s = s, .rt = rt, .light = light, .side = side, .seed = 0x10be5eedu, .pts = pts, .wo = wo,
                    .exponent = exponent, .V = V};
    lm_parallel_for(lm_thread_count(0), n, lobe_one, &job);
}

/* ---- the radiance mesh reflected by the lobe (samp_lobe_gather) ---------------------- */

typedef struct gather_job {
    const scene *s;
    const rt_scene *rt;
    const samp_radiance_mesh *mesh;
    const samp_radiance_index *ix;
    uint32_t side, pass;
    const samp_point *pts;
    const float *wo, *exponent;
    float *L, *std_err;
} gather_job;

/* With directions drawn by the lobe's pdf (n+1)/(2π)·cosⁿα, a ray's sample of
 * ∫ (n+2)/(2π) cosⁿα · L · cosθ dω is (n+2)/(n+1) · cosθ · L. */
static void gather_one(void *user, uint32_t i)
{
    const gather_job *j = user;
    const scene *s = j->s;
    const samp_point *x = &j->pts[i];
    float origin[3];
    samp_point_origin(s, x, samp_point_eps_rt(j->rt, x), origin);
    const lm_vec3 n = v3_normalize(v3_load(x->n)), wo = v3_normalize(v3_load(j->wo + 3 * (size_t)i));
    const lobe_frame f = lobe_frame_make(n, wo);
    const double ne = j->exponent[i], scale = (ne + 2.0) / (ne + 1.0);
    /* Seeded by the point itself, not its place in the batch: the same point gets
     * the same rays from any batch (a value taken again is the same value). */
    uint32_t bits[3];
    memcpy(bits, x->p, sizeof bits);
    lm_rng g;
    lm_rng_seed(&g, 0x6105515eu, (uint64_t)bits[0] << 32 | bits[1], (uint64_t)bits[2] << 32 | j->pass);
    double sum[3] = {0, 0, 0}, sum2[3] = {0, 0, 0};
    for (uint32_t b = 0; b < j->side; ++b)
        for (uint32_t a = 0; a < j->side; ++a) {
            double u = (a + lm_rng_float(&g)) / j->side, v = (b + lm_rng_float(&g)) / j->side;
            lm_vec3 d = lobe_direction(&f, ne, u, v);
            const float cx = v3_dot(d, n);
            if (!(cx > 0.0f)) continue; /* below x's horizon: the lobe is clipped there */
            float dir[3];
            v3_store(dir, d);
            rt_hit h;
            if (!rt_intersect(j->rt, origin, dir, 0.0f, INFINITY, &h)) continue;
            /* The back of a surface sends nothing: the mesh holds what leaves its front. */
            if (!(-v3_dot(v3_load(s->tri_normals + 3 * (size_t)h.tri), d) > 0.0f)) continue;
            float Ly[3];
            samp_radiance_at(j->mesh, j->ix, h.tri, h.u, h.v, Ly);
            for (int c = 0; c < 3; ++c) {
                const double y = scale * cx * Ly[c];
                sum[c] += y;
                sum2[c] += y * y;
            }
        }
    const double N = (double)j->side * j->side;
    for (int c = 0; c < 3; ++c) {
        const double mean = sum[c] / N, var = fmax(sum2[c] / N - mean * mean, 0.0) / (N > 1.0 ? N - 1.0 : 1.0);
        j->L[3 * (size_t)i + (size_t)c] = isfinite(mean) ? (float)mean : 0.0f;
        if (j->std_err) j->std_err[3 * (size_t)i + (size_t)c] = isfinite(var) ? (float)sqrt(var) : 0.0f;
    }
}

void samp_lobe_gather_run(const scene *s, const rt_scene *rt, const samp_radiance_mesh *mesh,
                          const samp_radiance_index *ix, const samp_point *pts, const float *wo, const float *exponent,
                          uint32_t n, uint32_t side, uint32_t pass, float *L, float *std_err)
{
    gather_job job = {.s = s, .rt = rt, .mesh = mesh, .ix = ix, .side = side, .pass = pass, .pts = pts, .wo = wo,
                      .exponent = exponent, .L = L, .std_err = std_err};
    lm_parallel_for(lm_thread_count(0), n, gather_one, &job);
}
