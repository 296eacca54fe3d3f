/* scene_json_test — the JSON scene description: material overrides of an MTL,
 * a material given to a whole PLY scan, quad and point lights, cameras, tone
 * mapping, relative paths, and unknown keys reported rather than ignored silently. */
#include <math.h>
#include <stdio.h>
#include <string.h>
#include <sys/stat.h>

#include "src/base/vecmath.h"
#include "src/scene/scene.h"
#include "tests/test_util.h"

static scene *load_ok(const char *path)
{
    scene_load_desc d = {.path = path};
    scene *s = NULL;
    lm_error err;
    memset(&err, 0, sizeof err);
    lm_result r = scene_load(&d, &s, &err);
    CHECK_MSG(r == LM_OK, "%s: %s", path, err.msg);
    return s;
}

static const scene_material *find_material(const scene *s, const char *name)
{
    for (uint32_t i = 0; i < s->material_count; ++i)
        if (strcmp(s->materials[i].name, name) == 0) return &s->materials[i];
    return NULL;
}

static int has_note(const scene *s, const char *needle)
{
    for (uint32_t i = 0; i < s->report.note_count; ++i)
        if (strstr(s->report.notes[i], needle)) return 1;
    return 0;
}

static void test_override_mtl(void)
{
    char json[1024], text[4096];
    snprintf(text, sizeof text,
             "{\"meshes\": [{\"file\": \"%s/cornell-box/CornellBox-Original.obj\"}],\n"
             " \"materials\": {\"leftWall\": {\"kd\": [0.1, 0.2, 0.3], \"ks\": [0.25, 0.25, 0.25], \"n\": 50},\n"
             "               \"light\": {\"Le\": [1, 2, 3]}},\n"
             " \"cameras\": [{\"name\": \"front\", \"position\": [0, 1, 3.5], \"target\": [0, 1, 0],"
             " \"fov_y\": 45, \"width\": 320, \"height\": 200},\n"
             "             {\"name\": \"side\", \"position\": [3, 1, 0], \"target\": [0, 1, 0]}],\n"
             " \"tonemap\": {\"exposure\": -1.5},\n"
             " \"colour\": \"typo\"}\n",
             LUMESH_SCENES);
    test_write_file("override.json", text, json, sizeof json);
    scene *s = load_ok(json);
    if (!s) return;
    const scene_material *lw = find_material(s, "leftWall");
    CHECK(lw != NULL);
    if (lw) {
        CHECK_NEAR(lw->kd[0], 0.1, 1e-7);
        CHECK_NEAR(lw->kd[2], 0.3, 1e-7);
        CHECK_NEAR(lw->ks[1], 0.25, 1e-7);
        CHECK_NEAR(lw->n, 50, 0);
        CHECK(lw->notes & SCENE_MATNOTE_OVERRIDDEN);
    }
    /* Fields not given keep the MTL's values: the right wall is untouched. */
    const scene_material *rw = find_material(s, "rightWall");
    CHECK(rw && fabsf(rw->kd[1] - 0.45f) < 1e-7f && !(rw->notes & SCENE_MATNOTE_OVERRIDDEN));
    const scene_material *light = find_material(s, "light");
    CHECK(light && light->le[2] == 3.0f && fabsf(light->kd[0] - 0.78f) < 1e-6f);
    CHECK(s->area_light_count == 1 && s->area_lights[0].le[1] == 2.0f);
    CHECK(s->camera_count == 2);
    CHECK(scene_find_camera(s, "side") == 1 && scene_find_camera(s, "nope") == -1);
    CHECK(s->cameras[0].width == 320 && s->cameras[0].height == 200);
    CHECK(s->cameras[1].width == 640 && s->cameras[1].fov_y_deg == 40.0f);
    CHECK_NEAR(s->exposure, -1.5, 0);
    CHECK(has_note(s, "unknown key 'colour'"));
    scene_destroy(s);
}

static void test_ply_with_material_and_lights(void)
{
    char json[1024], text[4096];
    snprintf(text, sizeof text,
             "{\"meshes\": [{\"file\": \"%s/stanford-dragon/dragon_vrip_res3.ply\", \"material\": \"jade\","
             "  \"transform\": [10,0,0,0, 0,10,0,0, 0,0,10,0, 0,0,0,1]}],\n"
             " \"materials\": {\"jade\": {\"kd\": [0.2, 0.6, 0.3], \"ks\": [0.2, 0.2, 0.2], \"n\": 40}},\n"
             " \"lights\": [{\"type\": \"quad\", \"corner\": [-1, 3, -1], \"edge1\": [2, 0, 0],"
             " \"edge2\": [0, 0, 2], \"radiance\": [5, 5, 5]},\n"
             "            {\"type\": \"point\", \"position\": [0, 2, 2], \"intensity\": [3, 2, 1]}]}\n",
             LUMESH_SCENES);
    test_write_file("dragon.json", text, json, sizeof json);
    scene *s = load_ok(json);
    if (!s) return;
    /* 47,794 triangles in the file, plus the quad light's 2 */
    CHECK_MSG(s->tri_count + s->report.dropped_degenerate + s->report.dropped_duplicate == 47794 + 2,
              "%u triangles, %u degenerate, %u duplicate", s->tri_count, s->report.dropped_degenerate,
              s->report.dropped_duplicate);
    const scene_material *jade = find_material(s, "jade");
    CHECK(jade && jade->ks[0] == 0.2f && jade->n == 40.0f);
    uint32_t jade_tris = 0;
    for (uint32_t t = 0; t < s->tri_count; ++t) jade_tris += s->materials[s->tris[t].material].le[0] == 0.0f;
    CHECK(jade_tris == s->tri_count - 2);
    /* The dragon's file normals are not unit length; ours are. */
    CHECK(s->report.corners_file_normals > 0);
    int unit = 1;
    for (uint32_t i = 0; i < 3 * s->tri_count; ++i) {
        const float *n = s->corner_normals + 3 * (size_t)i;
        unit &= fabsf(n[0] * n[0] + n[1] * n[1] + n[2] * n[2] - 1.0f) < 1e-4f;
    }
    CHECK(unit);
    /* The quad light emits towards edge1 x edge2 = (2,0,0)x(0,0,2) = (0,-4,0): down. */
    CHECK(s->area_light_count == 1);
    if (s->area_light_count == 1) {
        CHECK_NEAR(s->area_lights[0].normal[1], -1.0, 1e-6);
        CHECK_NEAR(s->area_lights[0].area, 4.0, 1e-5);
        CHECK_NEAR(s->area_lights[0].power[0], M_PI * 5.0 * 4.0, 1e-3);
    }
    CHECK(s->point_light_count == 1 && s->point_lights[0].intensity[2] == 1.0f);
    scene_destroy(s);
}

static void test_relative_paths(void)
{
    char dir[1024], obj[1024], json[1024];
    snprintf(dir, sizeof dir, "%s/sub", LUMESH_TMP_DIR);
    mkdir(dir, 0755);
    test_write_file("sub/tri.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", obj, sizeof obj);
    test_write_file("relative.json",
               "{\"meshes\": [{\"file\": \"sub/tri.obj\", \"material\": \"m\"}],"
               " \"materials\": {\"m\": {\"Le\": [1, 1, 1]}}}",
               json, sizeof json);
    scene *s = load_ok(json);
    if (!s) return;
    CHECK(s->tri_count == 1 && s->area_light_count == 1);
    /* A material given in the description starts from the defaults. */
    CHECK(s->materials[0].kd[0] == 0.7f && s->materials[0].ks[0] == 0.0f);
    scene_destroy(s);
}

int main(void)
{
    test_override_mtl();
    test_ply_with_material_and_lights();
    test_relative_paths();
    return test_finish("scene_json_test");
}
