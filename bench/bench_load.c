/* bench_load — scene load times for the shared third-party scenes and the
 * built-in one. Prints a table: best of R runs (default 5), triangles, lights.
 * usage: bench_load [RUNS] */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "scene.h"

static const char *const scenes[] = {
    NULL, /* built-in */
    "cornell-box/CornellBox-Original.obj",
    "cornell-box/CornellBox-Sphere.obj",
    "cornell-box/CornellBox-Water.obj",
    "stanford-bunny/stanford-bunny.obj",
    "stanford-dragon/dragon_vrip_res3.ply",
    "spot/spot_triangulated.obj",
};

int main(int argc, char **argv)
{
    int runs = argc > 1 ? atoi(argv[1]) : 5;
    if (runs < 1) runs = 1;
    printf("%-40s %10s %8s %10s %10s\n", "scene", "triangles", "lights", "best ms", "mean ms");
    for (size_t i = 0; i < sizeof scenes / sizeof scenes[0]; ++i) {
        char path[1024];
        if (scenes[i])
            snprintf(path, sizeof path, "%s/%s", LUMESH_SCENES, scenes[i]);
        double best = 1e30, sum = 0.0;
        uint32_t tris = 0, lights = 0;
        int ok = 1;
        for (int r = 0; r < runs && ok; ++r) {
            scene_load_desc d = {.path = scenes[i] ? path : NULL};
            scene *s;
            lm_error err;
            double t0 = lm_now_seconds();
            if (scene_load(&d, &s, &err) != LM_OK) {
                printf("%-40s failed: %s\n", scenes[i] ? scenes[i] : "(built-in)", err.msg);
                ok = 0;
                break;
            }
            double dt = lm_now_seconds() - t0;
            tris = s->tri_count;
            lights = scene_light_count(s);
            scene_destroy(s);
            if (dt < best) best = dt;
            sum += dt;
        }
        if (ok)
            printf("%-40s %10u %8u %10.1f %10.1f\n", scenes[i] ? scenes[i] : "(built-in)", tris, lights,
                   best * 1e3, sum / runs * 1e3);
    }
    return 0;
}
