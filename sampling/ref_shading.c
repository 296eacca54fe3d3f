/* ref_shading.c — modified Phong, surfaces and light sampling for
 * the reference renderer. */
#include "sampling/ref_shading.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>


/* ---- lights -------------------------------------------------------------- */

lm_result ref_lights_init(ref_lights *L, const scene *s, lm_error *err)
{
    memset(L, 0, sizeof *L);
    L->s = s;
    uint32_t n = s->area_light_count;
    if (n == 0) return LM_OK;
    uint32_t ntri = s->area_lights[n - 1].first + s->area_lights[n - 1].count;
    L->light_cdf = malloc(n * sizeof *L->light_cdf);
    L->light_pmf = malloc(n * sizeof *L->light_pmf);
    L->tri_cdf = malloc(ntri * sizeof *L->tri_cdf);
    if (!L->light_cdf || !L->light_pmf || !L->tri_cdf) {
        ref_lights_free(L);
        return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory building light tables");
    }
    double total = 0.0;
    for (uint32_t i = 0; i < n; ++i) total += ref_luminance(s->area_lights[i].power);
    double acc = 0.0;
    for (uint32_t i = 0; i < n; ++i) {
        const scene_area_light *A = &s->area_lights[i];
        /* By power; lights of equal power (or a zero total) fall back to equal odds. */
        double w = total > 0.0 ? ref_luminance(A->power) / total : 1.0 / n;
        L->light_pmf[i] = (float)w;
        acc += w;
        L->light_cdf[i] = (float)acc;
        double a = 0.0;
        for (uint32_t k = 0; k < A->count; ++k) {
            a += s->tri_areas[s->light_tris[A->first + k]];
            L->tri_cdf[A->first + k] = (float)(a / A->area);
        }
        L->tri_cdf[A->first + A->count - 1] = 1.0f;
    }
    L->light_cdf[n - 1] = 1.0f;
    return LM_OK;
}

void ref_lights_free(ref_lights *L)
{
    free(L->light_cdf);
    free(L->light_pmf);
    free(L->tri_cdf);
    memset(L, 0, sizeof *L);
}

uint32_t ref_pick_cdf(const float *cdf, uint32_t n, float u)
{
    uint32_t lo = 0, hi = n - 1;
    while (lo < hi) {
        uint32_t mid = (lo + hi) / 2;
        if (cdf[mid] > u)
            hi = mid;
        else
            lo = mid + 1;
    }
    return lo;
}

lm_vec3 ref_area_light_point(const ref_lights *L, uint32_t li, float u1, float u2, float u3, uint32_t *tri)
{
    const scene *s = L->s;
    const scene_area_light *A = &s->area_lights[li];
    *tri = s->light_tris[A->first + ref_pick_cdf(L->tri_cdf + A->first, A->count, u1)];
    const uint32_t *v = s->tris[*tri].v;
    /* Uniform point on the triangle. */
    float su = sqrtf(u2), b0 = 1.0f - su, b1 = u3 * su;
    lm_vec3 a = v3_load(s->positions + 3 * (size_t)v[0]);
    lm_vec3 b = v3_load(s->positions + 3 * (size_t)v[1]);
    lm_vec3 c = v3_load(s->positions + 3 * (size_t)v[2]);
    return v3_add(v3_add(v3_scale(a, b0), v3_scale(b, b1)), v3_scale(c, 1.0f - b0 - b1));
}

int ref_sample_area_light(const ref_lights *L, lm_rng *g, lm_vec3 p, ref_light_sample *out)
{
    const scene *s = L->s;
    float u0 = lm_rng_float(g), u1 = lm_rng_float(g), u2 = lm_rng_float(g), u3 = lm_rng_float(g);
    uint32_t li = ref_pick_cdf(L->light_cdf, s->area_light_count, u0);
    const scene_area_light *A = &s->area_lights[li];
    uint32_t tri;
    lm_vec3 y = ref_area_light_point(L, li, u1, u2, u3, &tri);
    lm_vec3 d = v3_sub(y, p);
    float dist = v3_length(d);
    if (!(dist > 0.0f)) return 0;
    lm_vec3 wi = v3_scale(d, 1.0f / dist);
    lm_vec3 ny = v3_load(s->tri_normals + 3 * (size_t)tri);
    float cosy = -v3_dot(ny, wi);
    if (cosy <= 0.0f) return 0;
    out->wi = wi;
    out->dist = dist;
    out->ny = ny;
    out->tri = tri;
    out->pdf = L->light_pmf[li] / A->area * dist * dist / cosy;
    out->le = A->le;
    return 1;
}

float ref_area_light_pdf(const ref_lights *L, uint32_t tri, lm_vec3 wi, float dist)
{
    const scene *s = L->s;
    int32_t li = s->tris[tri].light;
    if (li < 0) return 0.0f;
    float cosy = -v3_dot(v3_load(s->tri_normals + 3 * (size_t)tri), wi);
    if (cosy <= 0.0f) return 0.0f;
    return L->light_pmf[li] / s->area_lights[li].area * dist * dist / cosy;
}

/* ---- surfaces ------------------------------------------------------------ */

void ref_surface_from_hit(const scene *s, const rt_hit *h, lm_vec3 wo, ref_surface *out)
{
    const scene_tri *t = &s->tris[h->tri];
    float w0 = 1.0f - h->u - h->v;
    lm_vec3 p0 = v3_load(s->positions + 3 * (size_t)t->v[0]);
    lm_vec3 p1 = v3_load(s->positions + 3 * (size_t)t->v[1]);
    lm_vec3 p2 = v3_load(s->positions + 3 * (size_t)t->v[2]);
    out->p = v3_add(v3_add(v3_scale(p0, w0), v3_scale(p1, h->u)), v3_scale(p2, h->v));
    const float *cn = s->corner_normals + 9 * (size_t)h->tri;
    lm_vec3 ns = v3_normalize(v3_add(v3_add(v3_scale(v3_load(cn), w0), v3_scale(v3_load(cn + 3), h->u)),
                                     v3_scale(v3_load(cn + 6), h->v)));
    lm_vec3 ng = v3_load(s->tri_normals + 3 * (size_t)h->tri);
    out->front = v3_dot(ng, wo) > 0.0f;
    if (!out->front) {
        ng = v3_scale(ng, -1.0f);
        ns = v3_scale(ns, -1.0f);
    }
    /* A shading normal that faces away from the viewer would make the surface
     * black from here; the geometric normal is the honest fallback. */
    if (v3_dot(ns, wo) <= 0.0f || !v3_isfinite(ns)) ns = ng;
    out->ng = ng;
    out->ns = ns;
    out->tri = h->tri;
    out->m = &s->materials[t->material];
}

/* ---- modified Phong ------------------------------------------------------ */

static lm_vec3 reflect(lm_vec3 w, lm_vec3 n)
{
    return v3_sub(v3_scale(n, 2.0f * v3_dot(n, w)), w);
}

static float cos_alpha(lm_vec3 wi, lm_vec3 wo, lm_vec3 ns)
{
    float c = v3_dot(reflect(wi, ns), wo);
    return c > 0.0f ? c : 0.0f;
}

float ref_phong_lobe(float n, lm_vec3 wi, lm_vec3 wo, lm_vec3 ns)
{
    return (n + 2.0f) / (2.0f * (float)M_PI) * powf(cos_alpha(wi, wo, ns), n);
}

float ref_phong_pdf(float n, lm_vec3 wi, lm_vec3 wo, lm_vec3 ns)
{
    return (n + 1.0f) / (2.0f * (float)M_PI) * powf(cos_alpha(wi, wo, ns), n);
}

/* An orthonormal frame around a unit vector (Duff et al. 2017). */
void ref_frame(lm_vec3 n, lm_vec3 *t, lm_vec3 *b)
{
    float sign = copysignf(1.0f, n.z);
    float a = -1.0f / (sign + n.z);
    float bb = n.x * n.y * a;
    *t = v3(1.0f + sign * n.x * n.x * a, sign * bb, -sign * n.x);
    *b = v3(bb, sign + n.y * n.y * a, -n.y);
}

static lm_vec3 around(lm_vec3 axis, float cos_t, float phi)
{
    float sin_t = sqrtf(fmaxf(0.0f, 1.0f - cos_t * cos_t));
    lm_vec3 t, b;
    ref_frame(axis, &t, &b);
    return v3_add(v3_add(v3_scale(t, sin_t * cosf(phi)), v3_scale(b, sin_t * sinf(phi))),
                  v3_scale(axis, cos_t));
}

lm_vec3 ref_sample_phong(float n, lm_vec3 wo, lm_vec3 ns, float u1, float u2)
{
    return around(reflect(wo, ns), powf(u1, 1.0f / (n + 1.0f)), 2.0f * (float)M_PI * u2);
}

lm_vec3 ref_sample_cosine(lm_vec3 n, float u1, float u2)
{
    return around(n, sqrtf(1.0f - u1), 2.0f * (float)M_PI * u2);
}
