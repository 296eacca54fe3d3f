/* samp_coarse.c — the coarse radiance mesh without visibility
 * (samp_coarse_mesh_build, samp.h): the indirect source of the calibration
 * (samp_auto.c) and of benchmarks. Calls down only (samp_geom.c, analytic.c).
 * Threads: any; the mesh is the caller's. */
#include "sampling/samp.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "sampling/analytic.h"
#include "src/base/vecmath.h"

/* kd·Σ_ℓ L_ℓ·G_ℓ,unocc/π at barycentrics (w1, w2) of scene triangle t. */
static void unoccluded_radiance(const scene *s, uint32_t t, double w1, double w2, float out[3])
{
    const scene_material *m = &s->materials[s->tris[t].material];
    const float *nrm = s->tri_normals + 3 * (size_t)t;
    float p[3];
    for (int k = 0; k < 3; ++k)
        p[k] = (float)((1.0 - w1 - w2) * s->positions[3 * (size_t)s->tris[t].v[0] + (size_t)k] +
                       w1 * s->positions[3 * (size_t)s->tris[t].v[1] + (size_t)k] +
                       w2 * s->positions[3 * (size_t)s->tris[t].v[2] + (size_t)k]);
    double e[3] = {0, 0, 0};
    for (uint32_t l = 0; l < s->area_light_count; ++l) {
        double g = samp_area_light_unoccluded(s, l, p, nrm);
        for (int k = 0; k < 3; ++k) e[k] += s->area_lights[l].le[k] * g;
    }
    const double P[3] = {p[0], p[1], p[2]}, N[3] = {nrm[0], nrm[1], nrm[2]};
    for (uint32_t l = 0; l < s->point_light_count; ++l) {
        const float *q = s->point_lights[l].position;
        const double Q[3] = {q[0], q[1], q[2]};
        double g = samp_point_G(Q, P, N);
        for (int k = 0; k < 3; ++k) e[k] += s->point_lights[l].intensity[k] * g;
    }
    for (int k = 0; k < 3; ++k) {
        double v = s->tris[t].light >= 0 ? 0.0 : m->kd[k] * e[k] / M_PI; /* emission is no source (eq. 7) */
        out[k] = v < 3e38 ? (float)v : 3e38f;
    }
}

lm_result samp_coarse_mesh_build(const scene *s, uint32_t target_triangles, samp_coarse_mesh *out, lm_error *err)
{
    memset(out, 0, sizeof *out);
    /* Every scene triangle cut into the 4^k triangles of its dyadic lattice, k the
     * largest with tri_count·4^k <= target_triangles (k = 0 at least). */
    uint32_t k = 0;
    while (k < 8 && ((uint64_t)s->tri_count << (2 * (k + 1))) <= target_triangles) k++;
    uint32_t n = 1u << k, per = n * n;
    size_t total = (size_t)s->tri_count * per;
    out->first = malloc(((size_t)s->tri_count + 1) * sizeof *out->first);
    out->bary = malloc(6 * total * sizeof *out->bary);
    out->radiance = malloc(9 * total * sizeof *out->radiance);
    if (!out->first || !out->bary || !out->radiance) {
        samp_coarse_mesh_free(out);
        return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory for a coarse radiance mesh");
    }
    size_t at = 0;
    for (uint32_t t = 0; t < s->tri_count; ++t) {
        out->first[t] = (uint32_t)at;
        for (uint32_t a = 0; a < n; ++a)
            for (uint32_t b = 0; a + b < n; ++b)
                for (int down = 0; down < 2; ++down) {
                    if (down && a + b + 1 >= n) continue;
                    /* up: (a,b) (a+1,b) (a,b+1); down: (a+1,b) (a+1,b+1) (a,b+1) */
                    const uint32_t cw[3][2] = {{a + (uint32_t)down, b}, {a + 1, b + (uint32_t)down}, {a, b + 1}};
                    for (int c = 0; c < 3; ++c) {
                        double w1 = (double)cw[c][0] / n, w2 = (double)cw[c][1] / n;
                        out->bary[6 * at + 2 * (size_t)c] = (float)w1;
                        out->bary[6 * at + 2 * (size_t)c + 1] = (float)w2;
                        unoccluded_radiance(s, t, w1, w2, out->radiance + 9 * at + 3 * (size_t)c);
                    }
                    at++;
                }
    }
    out->first[s->tri_count] = (uint32_t)at;
    out->mesh = (samp_radiance_mesh){.tri_count = (uint32_t)at, .first = out->first, .bary = out->bary,
                                     .radiance = out->radiance};
    return LM_OK;
}

void samp_coarse_mesh_free(samp_coarse_mesh *m)
{
    free(m->first);
    free(m->bary);
    free(m->radiance);
    memset(m, 0, sizeof *m);
}
