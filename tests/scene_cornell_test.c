/* scene_cornell_test — every file of ../shared/scenes/cornell-box loads with the
 * right triangle count and its one light, despite the files' quirks (quads,
 * negative indices, CRLF, inline comments, Tr 0, illum 5/7, duplicate faces).
 * Expected counts were taken from the files themselves (faces, fan-triangulated,
 * minus coincident duplicates), not from our loader. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "src/base/vecmath.h"
#include "src/scene/scene.h"
#include "tests/test_util.h"

typedef struct expect {
    const char *file;
    uint32_t tris;        /* kept */
    uint32_t duplicates;  /* dropped */
    float le[3];
    uint32_t refraction_notes; /* materials approximated (illum 3..9) that are used */
} expect;

static const expect cases[] = {
    {"CornellBox-Original.obj", 32, 4, {17, 12, 4}, 0},
    {"CornellBox-Mirror.obj", 32, 4, {17, 12, 4}, 1},
    {"CornellBox-Empty-RG.obj", 12, 0, {17, 12, 4}, 0},
    {"CornellBox-Empty-CO.obj", 12, 0, {10, 10, 10}, 0},
    {"CornellBox-Empty-White.obj", 12, 0, {10, 10, 10}, 0},
    {"CornellBox-Empty-Squashed.obj", 12, 0, {10, 10, 10}, 0},
    {"CornellBox-Glossy.obj", 1112, 0, {10, 10, 10}, 0},
    {"CornellBox-Sphere.obj", 2188, 0, {10, 10, 10}, 2},  /* illum 5 and 7 spheres */
    {"CornellBox-Water.obj", 7088, 0, {10, 10, 10}, 3},   /* two spheres and the water */
};

static uint32_t count_notes_containing(const scene *s, const char *needle)
{
    uint32_t n = 0;
    for (uint32_t i = 0; i < s->report.note_count; ++i) n += strstr(s->report.notes[i], needle) != NULL;
    return n;
}

static void check_case(const expect *e)
{
    char path[1024];
    snprintf(path, sizeof path, "%s/cornell-box/%s", LUMESH_SCENES, e->file);
    scene_load_desc d = {.path = path, .require_light = 1};
    scene *s = NULL;
    lm_error err = {{0}};
    lm_result r = scene_load(&d, &s, &err);
    CHECK_MSG(r == LM_OK, "%s: %s", e->file, err.msg);
    if (r != LM_OK) return;
    CHECK_MSG(s->tri_count == e->tris, "%s: %u triangles, expected %u", e->file, s->tri_count, e->tris);
    CHECK_MSG(s->report.dropped_duplicate == e->duplicates, "%s: %u duplicates", e->file,
              s->report.dropped_duplicate);
    CHECK_MSG(s->report.dropped_degenerate == 0 && s->report.dropped_nonfinite == 0,
              "%s: dropped %u degenerate %u nonfinite", e->file, s->report.dropped_degenerate,
              s->report.dropped_nonfinite);
    CHECK_MSG(s->area_light_count == 1 && s->point_light_count == 0, "%s: %u area lights", e->file,
              s->area_light_count);
    if (s->area_light_count == 1) {
        const scene_area_light *L = &s->area_lights[0];
        CHECK(L->count == 2);
        for (int c = 0; c < 3; ++c) CHECK_NEAR(L->le[c], e->le[c], 1e-6);
        CHECK_NEAR(L->area, 0.1786, 1e-5);
        CHECK_MSG(L->normal[1] < -0.9999f, "%s: light faces %g %g %g, expected down", e->file,
                  L->normal[0], L->normal[1], L->normal[2]);
        for (int c = 0; c < 3; ++c) CHECK_NEAR(L->power[c], M_PI * e->le[c] * 0.1786, 1e-3 * e->le[c]);
    }
    /* Duplicate faces are reported in a note naming where they were. */
    CHECK(count_notes_containing(s, "duplicate") == (e->duplicates ? 2u : 0u));
    CHECK_MSG(count_notes_containing(s, "refraction") == e->refraction_notes,
              "%s: %u refraction notes", e->file, count_notes_containing(s, "refraction"));
    /* Tr 0 is not opacity: nothing was reported as transparent. */
    CHECK(count_notes_containing(s, "transparen") == 0);
    /* Every material keeps its real albedo (not Tr-as-opacity, not a default). */
    for (uint32_t m = 0; m < s->material_count; ++m) CHECK(!(s->materials[m].notes & SCENE_MATNOTE_DEFAULT));
    /* Shading normals are unit length everywhere. */
    int unit = 1;
    for (uint32_t i = 0; i < 3 * s->tri_count; ++i) {
        const float *n = s->corner_normals + 3 * (size_t)i;
        unit &= fabsf(n[0] * n[0] + n[1] * n[1] + n[2] * n[2] - 1.0f) < 1e-4f;
    }
    CHECK(unit);
    scene_destroy(s);
}

int main(void)
{
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; ++i) check_case(&cases[i]);

    /* The duplicates of Original are in the two boxes, named in the notes. */
    {
        char path[1024];
        snprintf(path, sizeof path, "%s/cornell-box/CornellBox-Original.obj", LUMESH_SCENES);
        scene_load_desc d = {.path = path};
        scene *s;
        lm_error err;
        CHECK(scene_load(&d, &s, &err) == LM_OK);
        CHECK(count_notes_containing(s, "duplicate triangles of material 'shortBox'") == 1);
        CHECK(count_notes_containing(s, "duplicate triangles of material 'tallBox'") == 1);
        /* Faces are welded: the floor's two triangles share an interior edge. */
        mesh_geo_stats gs;
        mesh_geo_get_stats(s->topology, &gs);
        CHECK(gs.sides[MESH_EDGE_INTERIOR] > 0);
        scene_destroy(s);
    }
    /* water.obj names a missing water.mtl and has no light: it loads, says so. */
    {
        char path[1024];
        snprintf(path, sizeof path, "%s/cornell-box/water.obj", LUMESH_SCENES);
        scene_load_desc d = {.path = path};
        scene *s;
        lm_error err;
        lm_result r = scene_load(&d, &s, &err);
        CHECK_MSG(r == LM_OK, "%s", err.msg);
        if (r == LM_OK) {
            CHECK(s->tri_count == 4900);
            CHECK(scene_light_count(s) == 0);
            CHECK(count_notes_containing(s, "water.mtl") >= 1);
            scene_destroy(s);
        }
        d.require_light = 1;
        r = scene_load(&d, &s, &err);
        CHECK(r == LM_ERR_BAD_INPUT);
        CHECK(strstr(err.msg, "water.obj") != NULL && strstr(err.msg, "no light") != NULL);
    }
    return test_finish("scene_cornell_test");
}
