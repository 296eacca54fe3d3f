/* rt_scene.c — Embree 3 BVH over the scene triangles. */
#include "sampling/rt_scene.h"

#include <embree3/rtcore.h>
#include <math.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>

#include "src/base/fork_guard.h"

struct rt_scene {
    RTCScene scene;
    float epsilon;     /* the largest of tri_eps: for points on no known triangle */
    float *tri_eps;    /* per scene triangle (rt_scene_tri_epsilon) */
    uint32_t tri_count;
};

/* One Embree device per process, made by the first rt_scene_create and kept until
 * the process ends; scenes are built one at a time under device_lock. Why: two
 * threads creating devices at once (the refinement worker's sampler beside the
 * main thread's) race inside Embree and TBB — a new device writes its
 * configuration while TBB workers started for the other device read it, which
 * ThreadSanitizer reports and which no suppression of ours can name (the frames
 * are libstdc++'s). One device also means one TBB thread pool. Building a scene
 * takes milliseconds, so serialising builds costs nothing measurable. */
static pthread_mutex_t device_lock = PTHREAD_MUTEX_INITIALIZER;
static RTCDevice shared_device;   /* guarded by device_lock; never released */
static lm_error build_error;      /* the scene build in progress; guarded by device_lock */

/* Embree reports device errors through a callback; keep the first one of the
 * build in progress. */
static void on_embree_error(void *user, enum RTCError code, const char *str)
{
    (void)user;
    if (!build_error.msg[0]) lm_fail(&build_error, LM_ERR_RUNTIME, "Embree error %d: %s", (int)code, str ? str : "");
}

lm_result rt_scene_create(const rt_scene_desc *desc, rt_scene **out, lm_error *err)
{
    *out = NULL;
    if (!desc || !desc->scene) return lm_fail(err, LM_ERR_INVALID_ARG, "rt_scene_create: no scene");
    const scene *s = desc->scene;
    rt_scene *rt = calloc(1, sizeof *rt);
    if (!rt) return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory creating the ray tracing scene");
    pthread_mutex_lock(&device_lock);
    if (!shared_device) {
        shared_device = rtcNewDevice(NULL);
        if (!shared_device) {
            pthread_mutex_unlock(&device_lock);
            free(rt);
            return lm_fail(err, LM_ERR_RUNTIME, "Embree could not create a device (error %d)",
                           (int)rtcGetDeviceError(NULL));
        }
        rtcSetDeviceErrorFunction(shared_device, on_embree_error, NULL);
    }
    memset(&build_error, 0, sizeof build_error);
    rt->scene = rtcNewScene(shared_device);
    /* Embree's default (binned SAH), not HIGH (spatial splits): on the 116k-
     * triangle box the build went 0.15-0.27 s -> 0.07-0.09 s, before the first
     * image can be sampled, and tracing was no slower: the path tracer, both in
     * one run, 8.30-8.62 -> 8.63-9.25 Mrays/s there and 6.70-6.81 -> 7.18-7.36 on
     * the Veach door (docs/sampling.md, "Embree's build quality"). */
    rtcSetSceneBuildQuality(rt->scene, RTC_BUILD_QUALITY_MEDIUM);
    RTCGeometry geom = rtcNewGeometry(shared_device, RTC_GEOMETRY_TYPE_TRIANGLE);
    float *vb = rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                        3 * sizeof(float), s->vertex_count);
    unsigned *ib = rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                           3 * sizeof(unsigned), s->tri_count);
    if (vb && ib) {
        memcpy(vb, s->positions, (size_t)s->vertex_count * 3 * sizeof(float));
        for (uint32_t t = 0; t < s->tri_count; ++t)
            for (int k = 0; k < 3; ++k) ib[3 * (size_t)t + (size_t)k] = s->tris[t].v[k];
    }
    rtcCommitGeometry(geom);
    rtcAttachGeometryByID(rt->scene, geom, 0);
    rtcReleaseGeometry(geom);
    rtcCommitScene(rt->scene);
    lm_error failed = build_error;
    pthread_mutex_unlock(&device_lock);
    if (failed.msg[0] || !vb || !ib) {
        rt_scene_destroy(rt);
        return lm_fail(err, LM_ERR_RUNTIME, "%s: building the Embree scene failed: %s", s->source,
                       failed.msg[0] ? failed.msg : "no buffer");
    }
    /* A few hundred ulps (2e-5, 168) of the largest coordinate of each triangle:
     * above the round-off of a point interpolated on it and of a ray's
     * intersection with its plane (both a few ulps of its corners' magnitude),
     * and no larger, so that a feature far from the scene's largest coordinate
     * keeps offsets of its own size (docs/scene-model.md, "Coordinates"). */
    rt->tri_eps = malloc(((size_t)s->tri_count + 1) * sizeof *rt->tri_eps);
    if (!rt->tri_eps) {
        rt_scene_destroy(rt);
        return lm_fail(err, LM_ERR_NO_MEMORY, "%s: out of memory for the surface offsets", s->source);
    }
    rt->tri_count = s->tri_count;
    float extent = 0.0f;
    for (uint32_t t = 0; t < s->tri_count; ++t) {
        float m = 0.0f;
        for (int c = 0; c < 3; ++c)
            for (int k = 0; k < 3; ++k) m = fmaxf(m, fabsf(s->positions[3 * (size_t)s->tris[t].v[c] + (size_t)k]));
        rt->tri_eps[t] = fmaxf(m, 1e-6f) * RT_EPSILON_REL;
        extent = fmaxf(extent, m);
    }
    rt->epsilon = fmaxf(extent, 1e-6f) * RT_EPSILON_REL;
    *out = rt;
    return LM_OK;
}

void rt_device_warm(void)
{
    /* A stand-in scene through rt_scene_create itself: the device, its error
     * callback and a build (TBB's threads) exactly as the first real scene's. */
    float positions[9] = {0.0f, 0.0f, 0.0f, 1.0f, 0.0f, 0.0f, 0.0f, 1.0f, 0.0f};
    scene_tri tri = {.v = {0, 1, 2}, .light = -1};
    scene stand_in = {.positions = positions, .vertex_count = 3, .tris = &tri, .tri_count = 1};
    rt_scene *rt = NULL;
    lm_error ignored;
    lm_fork_guard_enter();
    if (rt_scene_create(&(rt_scene_desc){.scene = &stand_in}, &rt, &ignored) == LM_OK) rt_scene_destroy(rt);
    lm_fork_guard_leave();
}

void rt_scene_destroy(rt_scene *rt)
{
    if (!rt) return;
    if (rt->scene) rtcReleaseScene(rt->scene);
    free(rt->tri_eps);
    free(rt);
}

int rt_intersect(const rt_scene *rt, const float org[3], const float dir[3], float tnear, float tfar,
                 rt_hit *hit)
{
    struct RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    struct RTCRayHit rh;
    rh.ray.org_x = org[0];
    rh.ray.org_y = org[1];
    rh.ray.org_z = org[2];
    rh.ray.dir_x = dir[0];
    rh.ray.dir_y = dir[1];
    rh.ray.dir_z = dir[2];
    rh.ray.tnear = tnear;
    rh.ray.tfar = tfar;
    rh.ray.time = 0.0f;
    rh.ray.mask = 0xffffffffu;
    rh.ray.id = 0;
    rh.ray.flags = 0;
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    rtcIntersect1(rt->scene, &ctx, &rh);
    if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return 0;
    hit->tri = rh.hit.primID;
    hit->t = rh.ray.tfar;
    hit->u = rh.hit.u;
    hit->v = rh.hit.v;
    return 1;
}

int rt_occluded(const rt_scene *rt, const float org[3], const float dir[3], float tnear, float tfar)
{
    struct RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    struct RTCRay r;
    r.org_x = org[0];
    r.org_y = org[1];
    r.org_z = org[2];
    r.dir_x = dir[0];
    r.dir_y = dir[1];
    r.dir_z = dir[2];
    r.tnear = tnear;
    r.tfar = tfar;
    r.time = 0.0f;
    r.mask = 0xffffffffu;
    r.id = 0;
    r.flags = 0;
    rtcOccluded1(rt->scene, &ctx, &r);
    return r.tfar < 0.0f; /* Embree sets tfar to -inf when occluded */
}

/* p moved by eps along n, turned to the side of `towards`. */
static void offset_towards(const float p[3], const float n[3], const float towards[3], float eps, float out[3])
{
    float d = (towards[0] - p[0]) * n[0] + (towards[1] - p[1]) * n[1] + (towards[2] - p[2]) * n[2];
    float s = d >= 0.0f ? eps : -eps;
    for (int k = 0; k < 3; ++k) out[k] = p[k] + s * n[k];
}

int rt_segment_occluded(const rt_scene *rt, const float a[3], const float na[3], const float b[3],
                        const float nb[3], float eps)
{
    float oa[3], ob[3], d[3];
    if (na)
        offset_towards(a, na, b, eps, oa);
    else
        for (int k = 0; k < 3; ++k) oa[k] = a[k];
    if (nb)
        offset_towards(b, nb, a, eps, ob);
    else
        for (int k = 0; k < 3; ++k) ob[k] = b[k];
    for (int k = 0; k < 3; ++k) d[k] = ob[k] - oa[k];
    float len = sqrtf(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    /* Ends closer than the offsets: the surfaces touch there, nothing fits between. */
    if (!(len > eps)) return 0;
    for (int k = 0; k < 3; ++k) d[k] /= len;
    return rt_occluded(rt, oa, d, 0.0f, len);
}

float rt_scene_epsilon(const rt_scene *rt) { return rt->epsilon; }

float rt_scene_tri_epsilon(const rt_scene *rt, uint32_t tri)
{
    return tri < rt->tri_count ? rt->tri_eps[tri] : rt->epsilon; /* a garbage id gets the largest */
}
