/* ref_shading.h — pieces of the reference renderer shared by its two transports:
 * the modified Phong BRDF (Lafortune & Willems
 * 1994, the paper's eq. 5), surface records and light sampling. Private to sampling/
 * (the reference renderer and the samplers' calibration). */
#ifndef LUMESH_REF_SHADING_H
#define LUMESH_REF_SHADING_H

#include <stdint.h>

#include "sampling/rt_scene.h"
#include "src/base/rng.h"
#include "src/base/vecmath.h"
#include "src/scene/scene.h"


/* Light selection tables built once per renderer; read-only afterwards. */
typedef struct ref_lights {
    const scene *s;
    float *light_cdf;  /* area lights by power: cumulative, last = 1 */
    float *light_pmf;  /* probability of choosing each area light */
    float *tri_cdf;    /* per light, its triangles by area: cumulative within the light */
} ref_lights;

lm_result ref_lights_init(ref_lights *L, const scene *s, lm_error *err);
void ref_lights_free(ref_lights *L);

/* A point on a surface, frame turned to face the direction the ray came from. */
typedef struct ref_surface {
    lm_vec3 p;        /* position */
    lm_vec3 ng, ns;   /* geometric and shading normal, on the side of wo */
    int front;        /* wo is on the triangle's front side */
    uint32_t tri;
    const scene_material *m;
} ref_surface;

void ref_surface_from_hit(const scene *s, const rt_hit *h, lm_vec3 wo, ref_surface *out);

/* A sampled point on an area light, as seen from p. */
typedef struct ref_light_sample {
    lm_vec3 wi;       /* unit direction from p to the point */
    float dist;       /* distance, scene units */
    lm_vec3 ny;       /* unit front normal of the light at the point */
    uint32_t tri;     /* the light triangle the point is on */
    float pdf;        /* solid-angle density at p of this direction (light choice included) */
    const float *le;  /* radiance of the light */
} ref_light_sample;

/* The first index whose cumulative value exceeds u (cdf of n entries, the last 1). */
uint32_t ref_pick_cdf(const float *cdf, uint32_t n, float u);

/* A point uniform by area on area light li (its triangle by area from u1, the
 * point from u2, u3), and that triangle in *tri. */
lm_vec3 ref_area_light_point(const ref_lights *L, uint32_t li, float u1, float u2, float u3, uint32_t *tri);

/* Samples one area light by power and a point on it by area. Returns 0 when the
 * point's front does not face p (no contribution). */
int ref_sample_area_light(const ref_lights *L, lm_rng *g, lm_vec3 p, ref_light_sample *out);
/* Solid-angle density with which ref_sample_area_light picks the point `y` on
 * emissive triangle `tri`, seen from a point at distance `dist` along `wi`. */
float ref_area_light_pdf(const ref_lights *L, uint32_t tri, lm_vec3 wi, float dist);

/* Modified Phong: the specular lobe value (n+2)/(2π)·cosⁿα, α between the mirror
 * direction of wi about ns and wo; and the density (n+1)/(2π)·cosⁿα of sampling it. */
float ref_phong_lobe(float n, lm_vec3 wi, lm_vec3 wo, lm_vec3 ns);
float ref_phong_pdf(float n, lm_vec3 wi, lm_vec3 wo, lm_vec3 ns);
lm_vec3 ref_sample_phong(float n, lm_vec3 wo, lm_vec3 ns, float u1, float u2);
lm_vec3 ref_sample_cosine(lm_vec3 n, float u1, float u2);
/* An orthonormal frame (t, b, n) around the unit vector n (Duff et al. 2017). */
void ref_frame(lm_vec3 n, lm_vec3 *t, lm_vec3 *b);

/* Power heuristic (β = 2). */
static inline float ref_mis(float a, float b)
{
    float a2 = a * a, b2 = b * b;
    return a2 + b2 > 0.0f ? a2 / (a2 + b2) : 0.0f;
}

static inline float ref_luminance(const float *c)
{
    return 0.2126f * c[0] + 0.7152f * c[1] + 0.0722f * c[2];
}

#endif
