/* ref_ism.h — imperfect shadow maps (Ritschel et al. 2008, as the instant
 * radiosity thesis in ../shared/papers describes them, §2.6.5): the visibility
 * of many VPLs at once from a point cloud of the scene, on the GL back end.
 * The reference renderer's VPL and BDIR estimators use it in place of their
 * shadow rays when ref_desc.vpl_visibility is REF_VPL_VISIBILITY_ISM. Private
 * to sampling/.
 *
 * Usage (reference.c):
 *     ref_ism *ism;
 *     ref_ism_create(&(ref_ism_desc){.s = scene}, &ism, &err);  // a GL context of its own
 *     ref_ism_build(ism, set.vpls, set.count, stream, &err);     // once a pass, after the VPLs
 *     int v = ref_ism_visible(ism, i, x, ng);                     // any thread, per join
 *     ref_ism_destroy(ism);
 *
 * What it does. At creation, `points` points are spread over the scene's
 * surfaces by area and shuffled. Each build gives VPL i a different run of
 * `points_per_map` of them (a random subset of the scene, the "imperfect"
 * geometry) and splats them (a compute shader, an atomic minimum a texel), as
 * squares sized by the area each stands for over its distance, into the VPL's
 * tile of one atlas: a paraboloid map of
 * the hemisphere around the VPL's geometric normal (Brabec et al. 2002), each
 * texel keeping the nearest point's distance. Holes between splats are filled
 * by pull-push over two coarser levels (Marroquim et al. 2007; thresholds 5%
 * of the scene's extent, times 2 a level, as the thesis quotes). The atlas is
 * read back, so the CPU threads that gather answer V(x, y) by one texel
 * lookup: visible when x is no farther from the VPL than the texel's distance
 * plus a bias for the texel's footprint on x's surface.
 *
 * What it gets wrong, by design (docs/peers.md measures it): thin or small
 * occluders fall between points (light leaks), splats make occluders a little
 * larger, and contact shadows within the bias are lost. Its cost does not
 * depend on the pixels: builds scale with VPLs × points_per_map.
 *
 * Threads: create, build and destroy on any thread, one at a time (each makes
 * the context current and releases it again, so the caller's own GL context,
 * if any, must be made current again by the caller); ref_ism_visible from any
 * number of threads between builds (read-only then).
 * Does NOT do: shading on the GPU (gathers stay on the CPU threads, with the
 * same estimator as the shadow rays'), imperfect reflective shadow maps,
 * temporal reuse of maps.
 * Units: scene units; maps hold distances from the VPL in scene units.
 */
#ifndef LUMESH_REF_ISM_H
#define LUMESH_REF_ISM_H

#include <stdint.h>

#include "sampling/ref_vpl.h"
#include "src/gpu/gl_platform.h"

typedef struct ref_ism_desc {
    const scene *s;
    glctx_platform platform; /* GLCTX_DEFAULT: EGL */
    int tile;                /* texels of a map's side, a multiple of 4; 0: REF_ISM_TILE_DEFAULT */
    int points_per_map;      /* points splatted into each map; 0: REF_ISM_POINTS_PER_MAP_DEFAULT */
    int points;              /* the cloud; 0: REF_ISM_POINTS_DEFAULT (at least points_per_map) */
    int atlas_side;          /* texels of the atlas's side (GL's largest texture at most): more maps
                                than fit are built in turns; 0: REF_ISM_ATLAS_SIDE_DEFAULT */
    uint32_t seed;
} ref_ism_desc;

enum { REF_ISM_TILE_DEFAULT = 64, REF_ISM_POINTS_PER_MAP_DEFAULT = 4096, REF_ISM_POINTS_DEFAULT = 1 << 18,
       REF_ISM_ATLAS_SIDE_DEFAULT = 4096 };

typedef struct ref_ism ref_ism;

lm_result ref_ism_create(const ref_ism_desc *desc, ref_ism **out, lm_error *err);
/* Makes the maps of count VPLs (their p and ng), replacing the last build's.
 * Which points each map gets comes from (desc.seed, stream) alone: the same
 * VPLs and stream give the same maps (the renderer passes its VPLs' stream, so a
 * restart that keeps its VPLs keeps their maps too). */
lm_result ref_ism_build(ref_ism *m, const ref_vpl *vpls, uint32_t count, uint64_t stream, lm_error *err);
/* Non-zero when the map of VPL i (of the last build) sees x, a point on a
 * surface of geometric normal ng (its side facing the VPL or not). */
int ref_ism_visible(const ref_ism *m, uint32_t i, lm_vec3 x, lm_vec3 ng);
/* Maps made and the seconds spent making them, over all builds. */
void ref_ism_totals(const ref_ism *m, uint64_t *maps, double *seconds);
void ref_ism_destroy(ref_ism *m); /* NULL is a no-op */

#endif
