/* bench_load — scene load times for the shared third-party scenes, the built-in
 * one, and a generated curved emitter (a lat-long sphere whose every triangle
 * emits: one light per planar patch). Prints a table: best and mean of R runs
 * (default 5), triangles, lights.
 * usage: bench_load [RUNS] */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "src/base/vecmath.h"
#include "src/scene/scene.h"

/* Writes an emissive lat-long sphere (nlat x nlon) as OBJ+MTL into dir. */
static int write_emissive_sphere(const char *dir, int nlat, int nlon, char *path, size_t n)
{
    char mtl[1024];
    snprintf(mtl, sizeof mtl, "%s/bench-glow.mtl", dir);
    snprintf(path, n, "%s/bench-glow.obj", dir);
    FILE *m = fopen(mtl, "w"), *f = fopen(path, "w");
    if (!m || !f) {
        if (m) fclose(m);
        if (f) fclose(f);
        return 0;
    }
    fprintf(m, "newmtl glow\nKd 0.5 0.5 0.5\nKe 4 4 4\n");
    fclose(m);
    fprintf(f, "mtllib bench-glow.mtl\nusemtl glow\nv 0 1 0\n");
    for (int i = 1; i < nlat; ++i)
        for (int j = 0; j < nlon; ++j) {
            double th = M_PI * i / nlat, ph = 2 * M_PI * j / nlon;
            fprintf(f, "v %.9f %.9f %.9f\n", sin(th) * cos(ph), cos(th), -sin(th) * sin(ph));
        }
    fprintf(f, "v 0 -1 0\n");
    int south = 2 + (nlat - 1) * nlon;
#define RING(i, j) (2 + ((i) - 1) * nlon + ((j) % nlon))
    for (int j = 0; j < nlon; ++j) fprintf(f, "f 1 %d %d\n", RING(1, j), RING(1, j + 1));
    for (int i = 1; i < nlat - 1; ++i)
        for (int j = 0; j < nlon; ++j)
            fprintf(f, "f %d %d %d %d\n", RING(i, j), RING(i + 1, j), RING(i + 1, j + 1), RING(i, j + 1));
    for (int j = 0; j < nlon; ++j) fprintf(f, "f %d %d %d\n", RING(nlat - 1, j), south, RING(nlat - 1, j + 1));
#undef RING
    return fclose(f) == 0;
}

static const char *const scenes[] = {
    NULL, /* built-in */
    "cornell-box/CornellBox-Original.obj",
    "cornell-box/CornellBox-Sphere.obj",
    "cornell-box/CornellBox-Water.obj",
    "stanford-bunny/stanford-bunny.obj",
    "stanford-dragon/dragon_vrip_res3.ply",
    "spot/spot_triangulated.obj",
    "", /* generated emissive sphere */
};

int main(int argc, char **argv)
{
    int runs = argc > 1 ? atoi(argv[1]) : 5;
    if (runs < 1) runs = 1;
    printf("%-40s %10s %8s %10s %10s\n", "scene", "triangles", "lights", "best ms", "mean ms");
    for (size_t i = 0; i < sizeof scenes / sizeof scenes[0]; ++i) {
        char path[1024];
        const char *label = scenes[i] ? scenes[i] : "(built-in)";
        if (scenes[i] && !scenes[i][0]) {
            label = "emissive sphere 100x200 (generated)";
            if (!write_emissive_sphere(LUMESH_BENCH_TMP, 100, 200, path, sizeof path)) {
                printf("%-40s cannot write into %s\n", label, LUMESH_BENCH_TMP);
                continue;
            }
        } else if (scenes[i]) {
            snprintf(path, sizeof path, "%s/%s", LUMESH_SCENES, scenes[i]);
        }
        double best = 1e30, sum = 0.0;
        uint32_t tris = 0, lights = 0;
        int ok = 1;
        for (int r = 0; r < runs && ok; ++r) {
            scene_load_desc d = {.path = scenes[i] ? path : NULL};
            scene *s;
            lm_error err;
            double t0 = lm_now_seconds();
            if (scene_load(&d, &s, &err) != LM_OK) {
                printf("%-40s failed: %s\n", label, err.msg);
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
            printf("%-40s %10u %8u %10.1f %10.1f\n", label, tris, lights,
                   best * 1e3, sum / runs * 1e3);
    }
    return 0;
}
