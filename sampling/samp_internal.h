/* samp_internal.h — what a sampler back end implements (samp_embree.c, samp_gl.c)
 * and what samp.c gives every back end. Not a public header.
 *
 * samp.c owns the sampler: it validates arguments, serves point lights with
 * Embree shadow rays, counts and times the calls, and forwards area lights and
 * indirect batches to the back end through samp_backend_ops.
 */
#ifndef LUMESH_SAMP_INTERNAL_H
#define LUMESH_SAMP_INTERNAL_H

#include "ref_shading.h"
#include "rt_scene.h"
#include "samp.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct samp_backend_ops {
    const char *name;  /* "embree", "gl-egl", "gl-osmesa" */
    /* G of area light `area_light` (index into scene.area_lights) at n points. */
    lm_result (*direct)(void *impl, uint32_t area_light, const samp_point *pts, uint32_t n, float *G,
                        lm_error *err);
    lm_result (*indirect)(void *impl, const samp_radiance_mesh *mesh, const samp_point *pts, uint32_t n,
                          float *E, lm_error *err);
    void (*destroy)(void *impl);
} samp_backend_ops;

/* Every back end is created from the user's descriptor with defaults filled in
 * (samp_desc_defaults) and the shared Embree scene (owned by samp.c; it outlives
 * the back end). */
lm_result samp_embree_create(const samp_desc *desc, const rt_scene *rt, const samp_backend_ops **ops,
                             void **impl, lm_error *err);
lm_result samp_gl_create(const samp_desc *desc, const rt_scene *rt, const samp_backend_ops **ops, void **impl,
                         lm_error *err);

/* The back ends behind one sampler: one serves direct samples, one indirect
 * samples; they are the same object unless AUTO measured that they should differ
 * (then destroy both). */
typedef struct samp_choice {
    const samp_backend_ops *direct_ops, *indirect_ops;
    void *direct_impl, *indirect_impl;
} samp_choice;

/* SAMP_BACKEND_AUTO (samp_auto.c): creates the back ends that can be made here,
 * measures each at equal error, for direct and for indirect samples, keeps the
 * cheaper of each, and writes the numbers behind the choice into stats->choice. */
lm_result samp_auto_choose(const samp_desc *desc, const rt_scene *rt, samp_choice *out, samp_stats *stats,
                           lm_error *err);

/* Index i with cdf[i-1] <= u < cdf[i] (cdf non-decreasing, cdf[n-1] = 1). */
uint32_t samp_cdf_pick(const double *cdf, uint32_t n, double u);
/* Cumulative area fractions of the scene's triangles (malloc'd; NULL: no memory). */
double *samp_area_cdf(const scene *s);
/* A receiver drawn by area on the scene's non-emitting triangles: a uniform point,
 * the triangle's front normal, tri_plus_one set. For calibration, tests, benches. */
samp_point samp_random_receiver(const scene *s, const double *area_cdf, ref_rng *g);

/* A coarse radiance mesh with no visibility, corner radiance
 * kd·Σ_ℓ L_ℓ·G_ℓ,unoccluded/π: every scene triangle cut into the same number of
 * dyadic sub-triangles, as many as keep the total at or under target_triangles
 * (one each at least). Shaped like the cache's indirect source, for calibration
 * and benchmarks. */
typedef struct samp_coarse_mesh {
    uint32_t *first;
    float *bary, *radiance;
    samp_radiance_mesh mesh;
} samp_coarse_mesh;

lm_result samp_coarse_mesh_build(const scene *s, uint32_t target_triangles, samp_coarse_mesh *out, lm_error *err);
void samp_coarse_mesh_free(samp_coarse_mesh *m);

/* The descriptor with every zero field replaced by its default. */
samp_desc samp_desc_defaults(const samp_desc *desc);

/* Unoccluded G of area light `light` at (p, n): the sum over its triangles of
 * samp_polygon_G (double precision inside). */
double samp_area_light_unoccluded(const scene *s, uint32_t light, const float p[3], const float n[3]);

/* Where rays and frusta for receiver x start: x moved `eps` towards the centroid
 * of its triangle (when x->tri_plus_one names one), then `eps` along x->n. Every
 * back end uses this, so they see the same thing from the same point. */
void samp_point_origin(const scene *s, const samp_point *x, float eps, float out[3]);

/* The epsilon every back end of sp lifts receivers by (samp_point_origin). */
float samp_origin_epsilon(const samp_sampler *sp);

/* True when the radiance mesh is well formed for scene s: offsets non-decreasing,
 * first[tri_count] == mesh->tri_count, barycentrics and radiance finite. */
int samp_radiance_mesh_valid(const scene *s, const samp_radiance_mesh *mesh, lm_error *err);

/* Point location in a radiance mesh. A scene triangle with more than 16
 * sub-triangles gets a res×res grid over its barycentric square (w1, w2) ∈ [0,1]²,
 * res = ⌈√count⌉, each cell listing the sub-triangles whose bounding box meets it;
 * others are searched linearly. Built in time linear in the mesh; valid while the
 * mesh is unchanged. Pure data: any thread may read a built index. */
typedef struct samp_radiance_index {
    uint32_t *res;        /* per scene triangle: grid cells per side, 0 = no grid */
    uint32_t *base;       /* per scene triangle: its first cell */
    uint32_t *cell_first; /* per cell, + 1: offsets into items */
    uint32_t *items;      /* radiance-mesh triangle ids */
} samp_radiance_index;

/* 0 and an empty index (linear search everywhere) when memory runs out. */
int samp_radiance_index_build(const scene *s, const samp_radiance_mesh *m, samp_radiance_index *ix);
void samp_radiance_index_free(samp_radiance_index *ix);
/* RGB radiance of mesh m at barycentrics (w1, w2) of scene triangle t: the
 * sub-triangle that contains the point (or, for a point on none by rounding, the
 * one it is least outside of), linearly interpolated. Returns that sub-triangle,
 * UINT32_MAX (and black) when t has none. */
uint32_t samp_radiance_at(const samp_radiance_mesh *m, const samp_radiance_index *ix, uint32_t t, float w1, float w2,
                          float out[3]);

#ifdef __cplusplus
}
#endif
#endif
