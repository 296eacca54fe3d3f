/* rend_id_rays.c — the ID pass's counts without GL: Embree's primary rays
 * through the pixel centres (rend_id.h, rend_id_count_rays). */
#include <math.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>

#include "sampling/rt_scene.h"
#include "src/render/rend_id.h"
#include "src/scene/camera.h"

enum { RAY_THREADS = 2 }; /* the machine's cores (docs/renderer.md); a thread that cannot start is done inline */

/* One thread's rows (every RAY_THREADS-th from `index`) and its own counts. */
typedef struct ray_rows {
    const rt_scene *rt;
    camera_basis cam;
    int width, height, index;
    uint32_t *pixels; /* tri_count counts */
} ray_rows;

static void *count_rows(void *arg)
{
    ray_rows *t = arg;
    const float org[3] = {t->cam.position.x, t->cam.position.y, t->cam.position.z};
    for (int y = t->index; y < t->height; y += RAY_THREADS)
        for (int x = 0; x < t->width; ++x) {
            lm_vec3 d = camera_ray_dir(&t->cam, (float)x + 0.5f, (float)y + 0.5f);
            const float dir[3] = {d.x, d.y, d.z};
            rt_hit h;
            if (rt_intersect(t->rt, org, dir, 0.0f, INFINITY, &h)) t->pixels[h.tri]++;
        }
    return NULL;
}

lm_result rend_id_count_rays(const scene *s, const rt_scene *given, const scene_camera *cam, int width, int height,
                             uint32_t *pixels, lm_error *err)
{
    if (!s || !cam || !pixels || width < 1 || height < 1)
        return lm_fail(err, LM_ERR_INVALID_ARG, "rend_id_count_rays: a scene, a camera, a size and counts needed");
    rt_scene *own = NULL;
    lm_result r = given ? LM_OK : rt_scene_create(&(rt_scene_desc){.scene = s}, &own, err);
    if (r != LM_OK) return r;
    const rt_scene *rt = given ? given : own;
    const size_t n = s->tri_count ? s->tri_count : 1;
    memset(pixels, 0, s->tri_count * sizeof *pixels);
    ray_rows t[RAY_THREADS];
    for (int i = 0; i < RAY_THREADS; ++i) {
        t[i] = (ray_rows){.rt = rt, .cam = camera_basis_make(cam, width, height), .width = width, .height = height,
                          .index = i, .pixels = i == 0 ? pixels : calloc(n, sizeof *pixels)};
        if (!t[i].pixels) r = lm_fail(err, LM_ERR_NO_MEMORY, "out of memory counting pixels by rays");
    }
    pthread_t tid[RAY_THREADS];
    int started[RAY_THREADS] = {0};
    for (int i = 1; r == LM_OK && i < RAY_THREADS; ++i)
        started[i] = pthread_create(&tid[i], NULL, count_rows, &t[i]) == 0;
    if (r == LM_OK) {
        count_rows(&t[0]);
        for (int i = 1; i < RAY_THREADS; ++i) {
            if (started[i]) pthread_join(tid[i], NULL);
            else count_rows(&t[i]);
            for (uint32_t k = 0; k < s->tri_count; ++k) pixels[k] += t[i].pixels[k];
        }
    }
    for (int i = 1; i < RAY_THREADS; ++i) free(t[i].pixels);
    rt_scene_destroy(own);
    return r;
}
