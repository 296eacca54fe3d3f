/* rt_scene.c — Embree 3 BVH over the scene triangles. */
#include "rt_scene.h"

#include <embree3/rtcore.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

struct rt_scene {
    RTCDevice device;
    RTCScene scene;
    float epsilon;
};

/* Embree reports device errors through a callback; keep the first one. */
static void on_embree_error(void *user, enum RTCError code, const char *str)
{
    lm_error *e = user;
    if (e && !e->msg[0]) lm_fail(e, LM_ERR_RUNTIME, "Embree error %d: %s", (int)code, str ? str : "");
}

lm_result rt_scene_create(const rt_scene_desc *desc, rt_scene **out, lm_error *err)
{
    *out = NULL;
    if (!desc || !desc->scene) return lm_fail(err, LM_ERR_INVALID_ARG, "rt_scene_create: no scene");
    const scene *s = desc->scene;
    rt_scene *rt = calloc(1, sizeof *rt);
    if (!rt) return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory creating the ray tracing scene");
    lm_error embree_err;
    memset(&embree_err, 0, sizeof embree_err);
    rt->device = rtcNewDevice(NULL);
    if (!rt->device) {
        free(rt);
        return lm_fail(err, LM_ERR_RUNTIME, "Embree could not create a device (error %d)",
                       (int)rtcGetDeviceError(NULL));
    }
    rtcSetDeviceErrorFunction(rt->device, on_embree_error, &embree_err);
    rt->scene = rtcNewScene(rt->device);
    rtcSetSceneBuildQuality(rt->scene, RTC_BUILD_QUALITY_HIGH);
    RTCGeometry geom = rtcNewGeometry(rt->device, RTC_GEOMETRY_TYPE_TRIANGLE);
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
    if (embree_err.msg[0] || !vb || !ib) {
        rt_scene_destroy(rt);
        return lm_fail(err, LM_ERR_RUNTIME, "%s: building the Embree scene failed: %s", s->source,
                       embree_err.msg[0] ? embree_err.msg : "no buffer");
    }
    rtcSetDeviceErrorFunction(rt->device, NULL, NULL);
    float extent = 0.0f;
    for (int k = 0; k < 3; ++k) {
        extent = fmaxf(extent, fabsf(s->bounds_min[k]));
        extent = fmaxf(extent, fabsf(s->bounds_max[k]));
    }
    /* A few hundred ulps at the largest coordinate: above round-off of the
     * intersection, far below any feature size a scene models. */
    rt->epsilon = fmaxf(extent, 1e-6f) * 2e-5f;
    *out = rt;
    return LM_OK;
}

void rt_scene_destroy(rt_scene *rt)
{
    if (!rt) return;
    if (rt->scene) rtcReleaseScene(rt->scene);
    if (rt->device) rtcReleaseDevice(rt->device);
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
