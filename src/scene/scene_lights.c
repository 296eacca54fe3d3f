/* scene_lights.c — area lights from emissive triangles.
 *
 * Every connected group of coplanar emissive triangles with one material is one
 * area light (docs/scene-model.md "Lights: one side, one plane"). A curved
 * emitter breaks into one light per planar patch: the region grows from a seed
 * triangle across shared edges (the topology's neighbours) only to triangles in
 * the seed's plane, so each light has one normal and one facing side, which is
 * what the per-light irradiance mesh and the light-frustum sampler (paper §5) need.
 * The walk is linear in the number of emissive triangles.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "src/base/vecmath.h"
#include "src/scene/scene_internal.h"

/* Coplanar: normals within ~0.5 degree and corners within this fraction of the
 * scene's diagonal of the seed's plane. */
#define COPLANAR_COS 0.99996f
#define COPLANAR_REL_DIST 1e-5

static int emits(const scene_material *m)
{
    return m->le[0] > 0.0f || m->le[1] > 0.0f || m->le[2] > 0.0f;
}

lm_result scene_build_lights(scene *s, lm_error *err)
{
    uint32_t nt = s->tri_count, emissive = 0;
    for (uint32_t i = 0; i < nt; ++i) emissive += emits(&s->materials[s->tris[i].material]);
    if (emissive == 0) return LM_OK;

    s->light_tris = malloc(emissive * sizeof *s->light_tris);
    s->area_lights = malloc(emissive * sizeof *s->area_lights); /* at most one per triangle */
    if (!s->light_tris || !s->area_lights)
        return lm_fail(err, LM_ERR_NO_MEMORY, "%s: out of memory building lights", s->source);

    double diag = 0.0;
    for (int k = 0; k < 3; ++k) {
        double d = (double)s->bounds_max[k] - (double)s->bounds_min[k];
        diag += d * d;
    }
    double max_dist = COPLANAR_REL_DIST * sqrt(diag);

    uint32_t filled = 0;
    for (uint32_t seed = 0; seed < nt; ++seed) {
        scene_tri *st = &s->tris[seed];
        if (st->light >= 0 || !emits(&s->materials[st->material])) continue;
        uint32_t li = s->area_light_count++;
        scene_area_light *L = &s->area_lights[li];
        memset(L, 0, sizeof *L);
        L->first = filled;
        L->material = st->material;
        lm_vec3 n0 = v3_load(s->tri_normals + 3 * (size_t)seed);
        lm_dvec3 p0 = dv3_load(s->positions + 3 * (size_t)st->v[0]);
        lm_dvec3 dn0 = dv3_from(n0);

        /* Breadth-first over light_tris itself: [first, filled) is the queue. */
        st->light = (int32_t)li;
        s->light_tris[filled++] = seed;
        for (uint32_t q = L->first; q < filled; ++q) {
            uint32_t t = s->light_tris[q];
            for (int e = 0; e < 3; ++e) {
                int32_t u = mesh_geo_neighbor(s->topology, t, e);
                if (u < 0) continue;
                scene_tri *ut = &s->tris[u];
                if (ut->light >= 0 || ut->material != L->material) continue;
                if (v3_dot(v3_load(s->tri_normals + 3 * (size_t)u), n0) < COPLANAR_COS) continue;
                int in_plane = 1;
                for (int k = 0; k < 3; ++k) {
                    lm_dvec3 p = dv3_load(s->positions + 3 * (size_t)ut->v[k]);
                    in_plane &= fabs(dv3_dot(dv3_sub(p, p0), dn0)) <= max_dist;
                }
                if (!in_plane) continue;
                ut->light = (int32_t)li;
                s->light_tris[filled++] = (uint32_t)u;
            }
        }
        L->count = filled - L->first;

        lm_dvec3 nsum = dv3(0, 0, 0), csum = dv3(0, 0, 0);
        double area = 0.0;
        for (int k = 0; k < 3; ++k) {
            L->bounds_min[k] = INFINITY;
            L->bounds_max[k] = -INFINITY;
        }
        for (uint32_t q = L->first; q < filled; ++q) {
            uint32_t t = s->light_tris[q];
            double a = s->tri_areas[t];
            area += a;
            nsum = dv3_add(nsum, dv3_scale(dv3_load(s->tri_normals + 3 * (size_t)t), a));
            lm_dvec3 c = dv3(0, 0, 0);
            for (int k = 0; k < 3; ++k) {
                const float *p = s->positions + 3 * (size_t)s->tris[t].v[k];
                c = dv3_add(c, dv3_load(p));
                for (int j = 0; j < 3; ++j) {
                    if (p[j] < L->bounds_min[j]) L->bounds_min[j] = p[j];
                    if (p[j] > L->bounds_max[j]) L->bounds_max[j] = p[j];
                }
            }
            csum = dv3_add(csum, dv3_scale(c, a / 3.0));
        }
        lm_dvec3 n = dv3_normalize(nsum);
        L->area = (float)area;
        L->normal[0] = (float)n.x;
        L->normal[1] = (float)n.y;
        L->normal[2] = (float)n.z;
        L->centroid[0] = (float)(csum.x / area);
        L->centroid[1] = (float)(csum.y / area);
        L->centroid[2] = (float)(csum.z / area);
        const scene_material *m = &s->materials[L->material];
        for (int c = 0; c < 3; ++c) {
            L->le[c] = m->le[c];
            L->power[c] = (float)(M_PI * (double)m->le[c] * area);
        }
    }
    /* Shrink to what was used. */
    scene_area_light *shrunk = realloc(s->area_lights, s->area_light_count * sizeof *shrunk);
    if (shrunk) s->area_lights = shrunk;
    return LM_OK;
}
