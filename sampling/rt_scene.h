/* rt_scene.h — the scene's triangles in an Embree 3 BVH, for the CPU samplers and
 * the reference renderer (docs/sampling.md, docs/reference.md).
 *
 * One Embree triangle geometry holds every scene triangle in scene order, so a
 * hit's primitive id IS the scene triangle id.
 *
 * Usage:
 *     rt_scene *rt; lm_error err;
 *     if (rt_scene_create(&(rt_scene_desc){.scene = s}, &rt, &err) != LM_OK) ...
 *     rt_hit h;
 *     if (rt_intersect(rt, org, dir, 0.0f, INFINITY, &h)) { ... h.tri, h.t, h.u, h.v ... }
 *     rt_scene_destroy(rt);
 *
 * Threads: rt_scene_create may be called from any thread (builds take turns on
 * the one process-wide Embree device, rt_scene.c); destroy on the thread that
 * created it; rt_intersect / rt_occluded may be
 * called from any number of threads at once (Embree committed scenes are
 * read-only). The scene model must outlive the rt_scene.
 * Does NOT do: shading, instancing, motion.
 */
#ifndef LUMESH_RT_SCENE_H
#define LUMESH_RT_SCENE_H

#include "src/base/util.h"
#include "src/scene/scene.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct rt_scene_desc {
    const scene *scene;
} rt_scene_desc;

typedef struct rt_hit {
    uint32_t tri;   /* scene triangle id */
    float t;        /* distance along the (unit) direction, scene units */
    float u, v;     /* barycentric weights of corners 1 and 2 (corner 0: 1-u-v) */
} rt_hit;

typedef struct rt_scene rt_scene;

lm_result rt_scene_create(const rt_scene_desc *desc, rt_scene **out, lm_error *err);
/* Makes the process's Embree device and starts its thread pool (a one-triangle
 * scene built and dropped), so that the first rt_scene_create pays for neither
 * (7-10 ms and 5-8 ms here): for a helper thread while a scene loads. Inside
 * the fork guard (src/base/fork_guard.h): TBB starts threads and C++ statics
 * while the load may fork Assimp's reader. Any thread, any number of times;
 * what fails is left for rt_scene_create to say. */
void rt_device_warm(void);
void rt_scene_destroy(rt_scene *rt); /* NULL is a no-op */

/* Closest hit on (tnear, tfar); returns 1 and fills *hit, or 0 on a miss. */
int rt_intersect(const rt_scene *rt, const float org[3], const float dir[3], float tnear, float tfar,
                 rt_hit *hit);
/* 1 when anything lies on (tnear, tfar). */
int rt_occluded(const rt_scene *rt, const float org[3], const float dir[3], float tnear, float tfar);

/* 1 when anything lies between the surface point a (normal na) and the point b
 * (normal nb). A NULL normal leaves that end where it is (a point light, or an
 * origin the caller has already moved off its surface). Each end with a normal is
 * moved off its surface by `eps` along its normal, on the side that faces the
 * other end, and the segment between the moved ends is tested. Moving only the
 * origin and shortening the far end by a fixed length is wrong at grazing
 * angles: an origin raised by eps reaches b's plane eps/cosθ_b early, so a ray
 * to a light seen at more than 60° off its normal hit the light itself
 * (measured by tests/reference_plane_test.c: image corners 2.4% dark). */
int rt_segment_occluded(const rt_scene *rt, const float a[3], const float na[3], const float b[3],
                        const float nb[3], float eps);

/* Surface offsets follow the local error: a ray or shadow segment that starts on
 * triangle t starts rt_scene_tri_epsilon(rt, t) off it, RT_EPSILON_REL of the
 * largest coordinate of t's corners (local coordinates, scene.h "Coordinates").
 * rt_scene_epsilon is the largest of them, for a point on no known triangle (and
 * what rt_scene_tri_epsilon answers for an id that names no triangle). */
#define RT_EPSILON_REL 2e-5f
float rt_scene_tri_epsilon(const rt_scene *rt, uint32_t tri);
float rt_scene_epsilon(const rt_scene *rt);

#ifdef __cplusplus
}
#endif
#endif
