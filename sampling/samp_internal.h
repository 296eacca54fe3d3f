/* samp_internal.h — what a sampler back end implements (samp_embree.c, samp_gl.c)
 * and what the back ends share beyond the public samp.h. Private to sampling/
 * (the cache uses samp.h).
 *
 * samp.c owns the sampler: it validates arguments, serves point lights with
 * Embree shadow rays, counts and times the calls, and forwards area lights and
 * indirect batches to the back end through samp_backend_ops.
 *
 * Calls run one way: samp.c → samp_auto.c → the back ends (samp_embree.c,
 * samp_gl.c) → the shared helpers (samp_geom.c, samp_coarse.c,
 * samp_radiance_index.c; the public ones are declared in samp.h). A back end
 * never calls samp.c.
 */
#ifndef LUMESH_SAMP_INTERNAL_H
#define LUMESH_SAMP_INTERNAL_H

#include "sampling/ref_shading.h"
#include "sampling/rt_scene.h"
#include "sampling/samp.h"
#include "src/base/vecmath.h"

#ifdef __cplusplus
extern "C" {
#endif

/* What a back end is, for deciding (backend, gl_platform), and what it is
 * called, for display only (name): never decide by the name. */
typedef struct samp_backend_ops {
    samp_backend backend;        /* SAMP_BACKEND_EMBREE or SAMP_BACKEND_GL, never AUTO */
    glctx_platform gl_platform;  /* GL: GLCTX_EGL or GLCTX_OSMESA; Embree: GLCTX_DEFAULT */
    const char *name;            /* display: "embree", "gl-egl", "gl-osmesa" */
    /* G of area light `area_light` (index into scene.area_lights) at n points. */
    lm_result (*direct)(void *impl, uint32_t area_light, const samp_point *pts, uint32_t n, float *G,
                        lm_error *err);
    lm_result (*indirect)(void *impl, const samp_radiance_mesh *mesh, const samp_point *pts, uint32_t n,
                          float *E, lm_error *err);
    /* samp_indirect_guided (guide NULL: samp_indirect_noise); NULL for a back end
     * without noise (GL's hemicube). */
    lm_result (*indirect_noise)(void *impl, const samp_radiance_mesh *mesh, const samp_point *pts, uint32_t n,
                                uint32_t pass, uint32_t scale, const samp_guide *guide, float *E, float *std_err,
                                lm_error *err);
    uint32_t (*indirect_rays)(const void *impl); /* rays of one pass at scale 1 */
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

/* samp_sources.c: samp_indirect_sources (samp.h) on the shared Embree scene, its
 * arguments checked. */
void samp_sources_trace(const scene *s, const rt_scene *rt, uint32_t seed, int threads, const samp_radiance_mesh *mesh,
                        const samp_point *pts, uint32_t n, const samp_source_hits *out);

/* samp_sources.c: samp_surface_hits_trace (samp.h), its arguments checked. */
void samp_surface_hits_run(const scene *s, const rt_scene *rt, uint32_t seed, int threads, const samp_point *pts,
                           uint32_t n, const samp_surface_hits *out);

/* samp_geom.c: index i with cdf[i-1] <= u < cdf[i] (cdf non-decreasing, cdf[n-1] = 1). */
uint32_t samp_cdf_pick(const double *cdf, uint32_t n, double u);

/* A hash of a receiver's position and normal bits: the key of its random stream,
 * so that a value depends on the point alone, not on its batch or thread. */
uint64_t samp_point_hash(const samp_point *x);

/* An orthonormal frame around a unit normal (Duff et al. 2017, "Building an
 * orthonormal basis, revisited"), and the cosine-weighted direction of the
 * unit-square sample (u, v) in it (pdf cosθ/π): what every hemisphere gather draws. */
typedef struct samp_frame {
    lm_vec3 t1, t2, n;
} samp_frame;
samp_frame samp_frame_make(const float n[3]);
lm_vec3 samp_frame_cosine(const samp_frame *f, float u, float v);
/* The hemisphere gathers' ray: stratum (a, b) of k × k of the cosine-weighted
 * hemisphere of f, jittered by two draws of g (u, then v). Returns 1 with h
 * filled when its first hit from origin is on the front of a triangle; 0 on a
 * miss or a back (the back of a surface sends nothing: samp.h). */
int samp_stratum_front_hit(const scene *s, const rt_scene *rt, const samp_frame *f, const float origin[3], lm_rng *g,
                           int a, int b, int k, rt_hit *h);

/* samp_point_epsilon from the ray tracing scene (the back ends hold no sampler). */
float samp_point_eps_rt(const rt_scene *rt, const samp_point *x);
/* samp_lobe_visibility's work (samp_lobe.c), side² rays a point. */
void samp_lobe_run(const scene *s, const rt_scene *rt, uint32_t light, const samp_point *pts, const float *wo,
                   const float *exponent, uint32_t n, uint32_t side, float *V);
/* samp_lobe_gather's work (samp_lobe.c), side² rays a point. */
void samp_lobe_gather_run(const scene *s, const rt_scene *rt, const samp_radiance_mesh *mesh,
                          const samp_radiance_index *ix, const samp_point *pts, const float *wo, const float *exponent,
                          uint32_t n, uint32_t side, uint32_t pass, float *L, float *std_err);
#ifdef __cplusplus
}
#endif
#endif
