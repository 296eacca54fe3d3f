/* cmd_info.c — `lumesh info SCENE`: what a scene holds and what loading changed. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "src/cli/cli.h"
#include "src/scene/scene.h"

/* "-Y (down)" style name of the axis closest to n. */
static const char *facing_name(const float n[3])
{
    static const char *names[6] = {"+X", "-X", "+Y (up)", "-Y (down)", "+Z", "-Z"};
    int axis = 0;
    for (int k = 1; k < 3; ++k)
        if (fabsf(n[k]) > fabsf(n[axis])) axis = k;
    return names[2 * axis + (n[axis] < 0.0f)];
}

/* Significant digits that show a position in the file's coordinates as finely as
 * %g shows one near the origin: 6, plus the decades between the local origin and
 * the scene's extent. */
static int file_digits(const scene *s)
{
    double far = 0.0, extent = 0.0;
    for (int k = 0; k < 3; ++k) {
        far = fmax(far, fabs(s->origin[k]));
        extent = fmax(extent, (double)s->bounds_max[k] - s->bounds_min[k]);
    }
    if (!(far > 0.0) || !(extent > 0.0)) return 6;
    int more = (int)ceil(log10(far / extent));
    return 6 + (more > 0 ? (more < 11 ? more : 11) : 0);
}

/* "[x, y, z]" of a local position, in the file's coordinates. */
static const char *file_point(const scene *s, const float local[3], char *buf, size_t size)
{
    double f[3];
    scene_to_file(s, local, f);
    int d = file_digits(s);
    snprintf(buf, size, "[%.*g, %.*g, %.*g]", d, f[0], d, f[1], d, f[2]);
    return buf;
}

static void print_scene(const scene *s)
{
    char p0[96], p1[96];
    const scene_report *rep = &s->report;
    printf("scene       %s\n", s->source);
    printf("loaded in   %.1f ms\n", rep->load_seconds * 1e3);
    printf("triangles   %u (%u read; %u vertices after welding)\n", s->tri_count,
           rep->input_triangles, s->vertex_count);
    printf("bounds      %s .. %s\n", file_point(s, s->bounds_min, p0, sizeof p0),
           file_point(s, s->bounds_max, p1, sizeof p1));
    if (s->origin[0] != 0.0 || s->origin[1] != 0.0 || s->origin[2] != 0.0)
        printf("origin      [%.17g, %.17g, %.17g]: positions are kept in float relative to it\n",
               s->origin[0], s->origin[1], s->origin[2]);
    printf("dropped     %u duplicate, %u degenerate, %u with NaN/Inf", rep->dropped_duplicate,
           rep->dropped_degenerate, rep->dropped_nonfinite);
    if (rep->dropped_out_of_range) printf(", %u beyond %.2g", rep->dropped_out_of_range, SCENE_COORD_MAX);
    printf("\n");
    printf("normals     %u corners from the file, %u computed (crease angle %g°); %u triangles "
           "re-wound to their normals\n",
           rep->corners_file_normals, rep->corners_computed_normals, s->crease_angle_deg,
           rep->rewound);
    mesh_geo_stats gs;
    mesh_geo_get_stats(s->topology, &gs);
    printf("topology    triangle sides: %u interior, %u boundary, %u non-manifold, %u crease\n",
           gs.sides[MESH_EDGE_INTERIOR], gs.sides[MESH_EDGE_BOUNDARY],
           gs.sides[MESH_EDGE_NONMANIFOLD], gs.sides[MESH_EDGE_CREASE]);

    printf("materials   %u", s->material_count);
    if (rep->materials_unused) printf(" (%u unused in the file, not kept)", rep->materials_unused);
    printf("\n");
    for (uint32_t i = 0; i < s->material_count; ++i) {
        const scene_material *m = &s->materials[i];
        printf("  %-14s kd %.3g %.3g %.3g  ks %.3g %.3g %.3g  n %g", m->name, m->kd[0], m->kd[1],
               m->kd[2], m->ks[0], m->ks[1], m->ks[2], m->n);
        if (m->le[0] > 0 || m->le[1] > 0 || m->le[2] > 0)
            printf("  Le %g %g %g", m->le[0], m->le[1], m->le[2]);
        if (m->notes & SCENE_MATNOTE_DEFAULT) printf("  (default: the file has no material)");
        if (m->notes & SCENE_MATNOTE_OVERRIDDEN) printf("  (set by the scene description)");
        if (m->notes & SCENE_MATNOTE_APPROXIMATED) printf("  (approximated: see notes)");
        printf("\n");
    }

    uint32_t nl = scene_light_count(s);
    printf("lights      %u (%u area, %u point)\n", nl, s->area_light_count, s->point_light_count);
    if (nl == 0)
        printf("  none: no triangle emits (Ke/Le > 0) and there is no point light; this scene "
               "cannot be rendered until it has a light\n");
    for (uint32_t i = 0; i < s->area_light_count; ++i) {
        const scene_area_light *L = &s->area_lights[i];
        printf("  area %-3u '%s': %u triangle%s, area %g, radiance (%g, %g, %g), power (%g, %g, "
               "%g), facing %s [%.3f %.3f %.3f], centre %s\n",
               i, s->materials[L->material].name, L->count, L->count == 1 ? "" : "s", L->area,
               L->le[0], L->le[1], L->le[2], L->power[0], L->power[1], L->power[2],
               facing_name(L->normal), L->normal[0], L->normal[1], L->normal[2],
               file_point(s, L->centroid, p0, sizeof p0));
    }
    for (uint32_t i = 0; i < s->point_light_count; ++i) {
        const scene_point_light *p = &s->point_lights[i];
        printf("  point %-2u at %s, intensity (%g, %g, %g) W/sr\n", i, file_point(s, p->position, p0, sizeof p0),
               p->intensity[0], p->intensity[1], p->intensity[2]);
    }
    printf("cameras     %u\n", s->camera_count);
    for (uint32_t i = 0; i < s->camera_count; ++i) {
        const scene_camera *c = &s->cameras[i];
        printf("  %-14s from %s to %s, up [%g, %g, %g], fov_y %g°, %dx%d\n", c->name,
               file_point(s, c->position, p0, sizeof p0), file_point(s, c->target, p1, sizeof p1), c->up[0],
               c->up[1], c->up[2], c->fov_y_deg, c->width, c->height);
    }
    printf("exposure    %g stops\n", s->exposure);
    if (rep->note_count) {
        printf("notes\n");
        for (uint32_t i = 0; i < rep->note_count; ++i) printf("  - %s\n", rep->notes[i]);
    }
}

int cmd_info(const app_command *cmd, int argc, char **argv)
{
    const char *pos[1];
    int npos, rc = app_parse_options(cmd, argc, argv, NULL, 0, pos, 1, &npos);
    if (rc < 0) return APP_EXIT_OK;
    if (rc) return rc;
    scene_load_desc d = {.path = npos ? pos[0] : NULL};
    scene *s;
    lm_error err;
    lm_result r = scene_load(&d, &s, &err);
    if (r != LM_OK) return app_report(r, &err);
    print_scene(s);
    scene_destroy(s);
    return APP_EXIT_OK;
}
