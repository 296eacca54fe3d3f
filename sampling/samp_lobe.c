/* samp_lobe.c — the visible fraction of an area light weighted by a modified
 * Phong lobe (samp_lobe_visibility, samp.h): Embree rays whichever back end
 * serves the sampler, as samp_surface_hits_run's. Calls nothing above
 * sampling/; threads by lm_parallel_for. */
#include "sampling/samp_internal.h"

#include <math.h>

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
    lm_vec3 r = v3_sub(v3_scale(n, 2.0f * v3_dot(n, wo)), wo); /* the mirror direction: the lobe's axis */
    lm_vec3 t1 = fabsf(r.x) > 0.9f ? v3(0, 1, 0) : v3(1, 0, 0);
    t1 = v3_normalize(v3_cross(r, t1));
    lm_vec3 t2 = v3_cross(r, t1);
    const double ne = j->exponent[i];
    lm_rng g;
    lm_rng_seed(&g, j->seed, i, j->light);
    double sum_w = 0.0, sum_vis = 0.0;
    for (uint32_t b = 0; b < j->side; ++b)
        for (uint32_t a = 0; a < j->side; ++a) {
            /* A direction drawn in proportion to cos^n of its angle α to r (the
             * lobe), stratified: cos α = u^(1/(n+1)). */
            double u = (a + lm_rng_float(&g)) / j->side, v = (b + lm_rng_float(&g)) / j->side;
            double ca = pow(u, 1.0 / (ne + 1.0)), sa = sqrt(fmax(0.0, 1.0 - ca * ca)), phi = 2.0 * M_PI * v;
            lm_vec3 d = v3_normalize(v3_add(v3_scale(r, (float)ca),
                                            v3_add(v3_scale(t1, (float)(sa * cos(phi))), v3_scale(t2, (float)(sa * sin(phi))))));
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
