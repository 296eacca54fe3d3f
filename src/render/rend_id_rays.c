/* rend_id_rays.c — the ID pass's counts without GL: Embree's primary rays
 * through the pixel centres (rend_id.h, rend_id_count_rays). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "sampling/rt_scene.h"
#include "src/base/parallel.h"
#include "src/render/rend_id.h"
#include "src/scene/camera.h"

/* One row's rays: the triangle each pixel centre sees, + 1 (0: none), into its row of ids. */
typedef struct ray_rows {
    const rt_scene *rt;
    camera_basis cam;
    int width;
    uint32_t *ids; /* width·height */
} ray_rows;

static void trace_row(void *user, uint32_t y)
{
    const ray_rows *t = user;
    const float org[3] = {t->cam.position.x, t->cam.position.y, t->cam.position.z};
    uint32_t *row = t->ids + (size_t)y * (size_t)t->width;
    for (int x = 0; x < t->width; ++x) {
        lm_vec3 d = camera_ray_dir(&t->cam, (float)x + 0.5f, (float)y + 0.5f);
        const float dir[3] = {d.x, d.y, d.z};
        rt_hit h;
        row[x] = rt_intersect(t->rt, org, dir, 0.0f, INFINITY, &h) ? h.tri + 1 : 0;
    }
}

lm_result rend_id_count_rays(const scene *s, const rt_scene *given, const scene_camera *cam, int width, int height,
                             uint32_t *pixels, lm_error *err)
{
    if (!s || !cam || !pixels || width < 1 || height < 1)
        return lm_fail(err, LM_ERR_INVALID_ARG, "rend_id_count_rays: a scene, a camera, a size and counts needed");
    const size_t n = (size_t)width * (size_t)height;
    uint32_t *ids = malloc(n * sizeof *ids);
    if (!ids) return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory for a %dx%d id image", width, height);
    rt_scene *own = NULL;
    lm_result r = given ? LM_OK : rt_scene_create(&(rt_scene_desc){.scene = s}, &own, err);
    if (r == LM_OK) {
        ray_rows t = {.rt = given ? given : own, .cam = camera_basis_make(cam, width, height), .width = width,
                      .ids = ids};
        lm_parallel_for(lm_thread_count(0), (uint32_t)height, trace_row, &t);
        memset(pixels, 0, s->tri_count * sizeof *pixels);
        for (size_t i = 0; i < n; ++i)
            if (ids[i]) pixels[ids[i] - 1]++;
    }
    rt_scene_destroy(own);
    free(ids);
    return r;
}
