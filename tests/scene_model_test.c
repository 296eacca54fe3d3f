/* scene_model_test — the scene model's rules on small scenes written here:
 * the built-in Cornell box, welding, duplicates of either winding, degenerate and
 * non-finite triangles, re-winding to vertex normals (the Veach lamp quirk),
 * crease-angle normals, one light per planar patch of a curved emitter,
 * mirroring transforms, and the framing camera. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "src/base/vecmath.h"
#include "src/scene/scene.h"
#include "tests/test_util.h"

static scene *load(const char *path, lm_result expect)
{
    scene_load_desc d = {.path = path};
    scene *s = NULL;
    lm_error err;
    memset(&err, 0, sizeof err);
    lm_result r = scene_load(&d, &s, &err);
    CHECK_MSG(r == expect, "%s: got %s: %s", path ? path : "(builtin)", lm_result_name(r), err.msg);
    return s;
}

static void test_builtin(void)
{
    scene *s = load(NULL, LM_OK);
    if (!s) return;
    /* floor 2, ceiling ring 8, light 2, three walls 6, two blocks 5 faces each: 38 */
    CHECK(s->tri_count == 38);
    CHECK(s->area_light_count == 1 && s->point_light_count == 0);
    const scene_area_light *L = &s->area_lights[0];
    CHECK(L->count == 2);
    CHECK_NEAR(L->area, 130.0 * 105.0, 1e-2);
    CHECK_NEAR(L->normal[1], -1.0, 1e-6);
    CHECK_NEAR(L->le[0], 17, 0) ;
    CHECK_NEAR(L->le[1], 12, 0);
    CHECK_NEAR(L->le[2], 4, 0);
    CHECK_NEAR(L->centroid[0], 278.0, 1e-3);
    CHECK_NEAR(L->centroid[2], 279.5, 1e-3);
    CHECK(s->camera_count == 1 && strcmp(s->cameras[0].name, "cornell") == 0);
    CHECK(s->cameras[0].width == 512 && s->cameras[0].height == 512);
    CHECK_NEAR(s->cameras[0].fov_y_deg, 39.3077, 1e-4);
    /* The ceiling is welded to the light: the ring and the light share edges. */
    int light_has_neighbour = 0;
    for (int e = 0; e < 3; ++e) {
        int32_t u = mesh_geo_neighbor(s->topology, s->light_tris[0], e);
        light_has_neighbour |= u >= 0 && s->tris[u].light < 0;
    }
    CHECK(light_has_neighbour);
    /* Every room surface faces the inside: the middle of the room is in front. */
    const float mid[3] = {278, 274, 280};
    int inward = 1;
    for (uint32_t t = 0; t < s->tri_count; ++t) {
        const char *part = s->parts[s->tris[t].part].name;
        if (strstr(part, "block")) continue;
        const float *p = s->positions + 3 * (size_t)s->tris[t].v[0];
        lm_vec3 d = v3_sub(v3_load(mid), v3_load(p));
        inward &= v3_dot(d, v3_load(s->tri_normals + 3 * (size_t)t)) > 0.0f;
    }
    CHECK(inward);
    /* Flat faces meeting at large angles: computed normals are the face normals. */
    int flat = 1;
    for (uint32_t t = 0; t < s->tri_count; ++t)
        for (int k = 0; k < 3; ++k)
            flat &= v3_dot(v3_load(s->corner_normals + 9 * (size_t)t + 3 * (size_t)k),
                           v3_load(s->tri_normals + 3 * (size_t)t)) > 0.99999f;
    CHECK(flat);
    CHECK(s->report.note_count == 0);
    scene_destroy(s);
}

static void test_cleaning(void)
{
    char path[1024];
    /* t1: a quad; t2: the quad's first triangle again with opposite winding;
     * t3: collinear; t4: repeated corner; t5: a triangle whose first corner is
     * written as a new vertex (-0.0, -0.0, 0) equal to vertex 1. */
    test_write_file("clean.obj",
               "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"
               "v 2 0 0\nv 3 0 0\nv -0.0 -0.0 0\nv 3 1 0\n"
               "f 1 2 3 4\n"
               "f 3 2 1\n"
               "f 1 2 5\n"
               "f 1 1 3\n"
               "f 7 6 8\n",
               path, sizeof path);
    scene *s = load(path, LM_OK);
    if (!s) return;
    CHECK(s->report.input_triangles == 6);
    CHECK(s->report.dropped_duplicate == 1);
    CHECK(s->report.dropped_degenerate == 2);
    CHECK(s->tri_count == 3);
    /* (-0,-0,0) welds to (0,0,0); (2,0,0) is used only by a dropped triangle: 6 vertices. */
    CHECK(s->vertex_count == 6);
    scene_destroy(s);

    /* A corner beyond float range through a transform (1e40, finite in double) is
     * dropped and counted as out of range. */
    char obj[1024], json[1024];
    test_write_file("huge.obj", "v 0 0 0\nv 1e30 0 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 0 1 1\nf 1 2 3\nf 4 5 6\n",
               obj, sizeof obj);
    test_write_file("huge.json",
               "{\"meshes\": [{\"file\": \"huge.obj\", \"transform\": "
               "[1e10,0,0,0, 0,1e10,0,0, 0,0,1e10,0, 0,0,0,1]}]}",
               json, sizeof json);
    s = load(json, LM_OK);
    if (s) {
        CHECK(s->report.dropped_out_of_range == 1 && s->report.dropped_nonfinite == 0);
        CHECK(s->tri_count == 1);
        scene_destroy(s);
    }
}

/* ../shared's Veach lamp: winding normal +Y, vertex normals -Y (towards the door).
 * The normals decide: the triangle is re-wound and the light faces -Y. */
static void test_rewind_lamp(void)
{
    char lamp[1024], json[1024];
    snprintf(lamp, sizeof lamp, "%s/veach-door/data/lamp.obj", LUMESH_SCENES);
    char text[2048];
    snprintf(text, sizeof text,
             "{\"meshes\": [{\"file\": \"%s\", \"material\": \"lamp\"}],"
             " \"materials\": {\"lamp\": {\"kd\": [0.73, 0.73, 0.73], \"Le\": [1420, 1552, 1642]}}}",
             lamp);
    test_write_file("lamp.json", text, json, sizeof json);
    scene *s = load(json, LM_OK);
    if (!s) return;
    CHECK(s->report.rewound == s->tri_count && s->tri_count == 2);
    CHECK(s->area_light_count == 1);
    if (s->area_light_count == 1) CHECK(s->area_lights[0].normal[1] < -0.999f);
    scene_destroy(s);
}

/* A unit sphere as a latitude-longitude mesh, optionally emissive, no normals. */
static void write_sphere(const char *name, int nlat, int nlon, int emissive, char *path, size_t n)
{
    size_t cap = 1 << 20;
    char *buf = malloc(cap);
    size_t len = 0;
    if (emissive) {
        char mtl[1024];
        test_write_file("glow.mtl", "newmtl glow\nKd 0 0 0\nKe 2 2 2\n", mtl, sizeof mtl);
        len += (size_t)snprintf(buf + len, cap - len, "mtllib glow.mtl\nusemtl glow\n");
    }
    len += (size_t)snprintf(buf + len, cap - len, "v 0 1 0\n");
    for (int i = 1; i < nlat; ++i)
        for (int j = 0; j < nlon; ++j) {
            double th = M_PI * i / nlat, ph = 2 * M_PI * j / nlon;
            len += (size_t)snprintf(buf + len, cap - len, "v %.9f %.9f %.9f\n", sin(th) * cos(ph),
                                    cos(th), -sin(th) * sin(ph));
        }
    len += (size_t)snprintf(buf + len, cap - len, "v 0 -1 0\n");
    int south = 2 + (nlat - 1) * nlon;
#define RING(i, j) (2 + ((i) - 1) * nlon + ((j) % nlon))
    for (int j = 0; j < nlon; ++j)
        len += (size_t)snprintf(buf + len, cap - len, "f 1 %d %d\n", RING(1, j), RING(1, j + 1));
    for (int i = 1; i < nlat - 1; ++i)
        for (int j = 0; j < nlon; ++j)
            len += (size_t)snprintf(buf + len, cap - len, "f %d %d %d %d\n", RING(i, j), RING(i + 1, j),
                                    RING(i + 1, j + 1), RING(i, j + 1));
    for (int j = 0; j < nlon; ++j)
        len += (size_t)snprintf(buf + len, cap - len, "f %d %d %d\n", RING(nlat - 1, j), south,
                                RING(nlat - 1, j + 1));
#undef RING
    CHECK(len < cap);
    test_write_file(name, buf, path, n);
    free(buf);
}

static void test_curved_emitter_and_normals(void)
{
    char path[1024];
    write_sphere("glow-sphere.obj", 8, 16, 1, path, sizeof path);
    scene *s = load(path, LM_OK);
    if (!s) return;
    /* 16 pole triangles at each end, 6 rings of 16 planar quads */
    CHECK(s->tri_count == 2 * 16 + 6 * 16 * 2);
    CHECK_MSG(s->area_light_count == 2 * 16 + 6 * 16, "%u lights", s->area_light_count);
    uint32_t in_lights = 0;
    double area = 0.0;
    for (uint32_t i = 0; i < s->area_light_count; ++i) {
        in_lights += s->area_lights[i].count;
        area += s->area_lights[i].area;
        /* outward: the normal points away from the centre */
        CHECK(v3_dot(v3_load(s->area_lights[i].normal), v3_load(s->area_lights[i].centroid)) > 0.0f);
    }
    CHECK(in_lights == s->tri_count);
    double total = 0.0;
    for (uint32_t t = 0; t < s->tri_count; ++t) total += s->tri_areas[t];
    CHECK_NEAR(area, total, 1e-4 * total);
    scene_destroy(s);

    /* A finer sphere without normals gets smooth normals: close to radial. */
    write_sphere("smooth-sphere.obj", 32, 64, 0, path, sizeof path);
    s = load(path, LM_OK);
    if (!s) return;
    float worst = 1.0f;
    for (uint32_t t = 0; t < s->tri_count; ++t)
        for (int k = 0; k < 3; ++k) {
            lm_vec3 p = v3_normalize(v3_load(s->positions + 3 * (size_t)s->tris[t].v[k]));
            float c = v3_dot(p, v3_load(s->corner_normals + 9 * (size_t)t + 3 * (size_t)k));
            if (c < worst) worst = c;
        }
    CHECK_MSG(worst > cosf(2.0f * (float)M_PI / 180.0f), "worst normal cos %f", worst);
    CHECK(s->report.corners_computed_normals == 3 * s->tri_count);
    /* Smooth: no crease inside the sphere. */
    mesh_geo_stats gs;
    mesh_geo_get_stats(s->topology, &gs);
    CHECK(gs.sides[MESH_EDGE_CREASE] == 0 && gs.sides[MESH_EDGE_BOUNDARY] == 0);
    CHECK(gs.sides[MESH_EDGE_INTERIOR] == 3 * s->tri_count);
    scene_destroy(s);
}

static void test_light_grouping(void)
{
    char path[1024];
    /* Two coplanar quads side by side: left emits with material a, right with b;
     * a third quad of material a, coplanar but not connected. */
    test_write_file("groups.mtl", "newmtl a\nKe 1 1 1\nnewmtl b\nKe 2 2 2\n", path, sizeof path);
    test_write_file("groups.obj",
               "mtllib groups.mtl\n"
               "v 0 0 0\nv 1 0 0\nv 2 0 0\nv 0 0 -1\nv 1 0 -1\nv 2 0 -1\n"
               "v 5 0 0\nv 6 0 0\nv 6 0 -1\nv 5 0 -1\n"
               "usemtl a\nf 1 2 5 4\nf 7 8 9 10\n"
               "usemtl b\nf 2 3 6 5\n",
               path, sizeof path);
    scene *s = load(path, LM_OK);
    if (!s) return;
    CHECK(s->area_light_count == 3);
    for (uint32_t i = 0; i < s->area_light_count; ++i) {
        CHECK(s->area_lights[i].count == 2);
        CHECK_NEAR(s->area_lights[i].area, 1.0, 1e-6);
        CHECK_NEAR(s->area_lights[i].normal[1], 1.0, 1e-6);
        CHECK_NEAR(s->area_lights[i].power[0], M_PI * s->area_lights[i].le[0], 1e-5);
    }
    scene_destroy(s);

    /* A large emissive grid is one light and loads in one pass. */
    int n = 150;
    size_t cap = (size_t)n * n * 64 + 4096;
    char *buf = malloc(cap);
    size_t len = (size_t)snprintf(buf, cap, "mtllib groups.mtl\nusemtl a\n");
    for (int i = 0; i <= n; ++i)
        for (int j = 0; j <= n; ++j) len += (size_t)snprintf(buf + len, cap - len, "v %d 0 %d\n", i, -j);
    for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) {
            int a = 1 + i * (n + 1) + j;
            len += (size_t)snprintf(buf + len, cap - len, "f %d %d %d %d\n", a, a + n + 1, a + n + 2, a + 1);
        }
    test_write_file("grid.obj", buf, path, sizeof path);
    free(buf);
    s = load(path, LM_OK);
    if (!s) return;
    CHECK(s->tri_count == (uint32_t)(2 * n * n));
    CHECK(s->area_light_count == 1);
    if (s->area_light_count == 1) {
        CHECK(s->area_lights[0].count == s->tri_count);
        CHECK_NEAR(s->area_lights[0].area, (double)n * n, 1e-3 * n * n);
    }
    scene_destroy(s);
}

static void test_mirror_transform_and_camera(void)
{
    char obj[1024], json[1024];
    test_write_file("normals.obj",
               "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//1 3//1\n", obj, sizeof obj);
    test_write_file("mirror.json",
               "{\"meshes\": [{\"file\": \"normals.obj\", \"transform\": "
               "[-1,0,0,0, 0,1,0,0, 0,0,1,0, 0,0,0,1]}],"
               " \"lights\": [{\"type\": \"point\", \"position\": [0,0,1], \"intensity\": [1,1,1]}]}",
               json, sizeof json);
    scene *s = load(json, LM_OK);
    if (!s) return;
    /* Mirroring keeps the front where the normals are: +Z, no re-winding needed. */
    CHECK(s->tri_count == 1 && s->report.rewound == 0);
    CHECK_NEAR(s->tri_normals[2], 1.0, 1e-6);
    CHECK_NEAR(s->corner_normals[2], 1.0, 1e-6);
    CHECK(s->point_light_count == 1);
    scene_destroy(s);

    /* A mesh file alone gets a camera that sees all of its bounds. */
    s = load(obj, LM_OK);
    if (!s) return;
    const scene_camera *c = &s->cameras[0];
    CHECK(s->camera_count == 1 && c->width == 640 && c->height == 480);
    lm_vec3 fwd = v3_normalize(v3_sub(v3_load(c->target), v3_load(c->position)));
    lm_vec3 right = v3_normalize(v3_cross(fwd, v3_load(c->up)));
    lm_vec3 up = v3_cross(right, fwd);
    float ty = tanf(0.5f * c->fov_y_deg * (float)M_PI / 180.0f), tx = ty * 640.0f / 480.0f;
    int inside = 1;
    for (int i = 0; i < 8; ++i) {
        lm_vec3 p = v3((i & 1) ? s->bounds_max[0] : s->bounds_min[0], (i & 2) ? s->bounds_max[1] : s->bounds_min[1],
                       (i & 4) ? s->bounds_max[2] : s->bounds_min[2]);
        lm_vec3 d = v3_sub(p, v3_load(c->position));
        float z = v3_dot(d, fwd);
        inside &= z > 0 && fabsf(v3_dot(d, right)) <= tx * z && fabsf(v3_dot(d, up)) <= ty * z;
    }
    CHECK(inside);
    scene_destroy(s);
}

/* The other formats Assimp gives us: glTF 2.0 (with a node transform and an
 * emissive PBR material), OFF and ASCII STL. */
static void test_formats(void)
{
    char path[1024];
    test_write_file("tri.gltf",
               "{\"asset\": {\"version\": \"2.0\"}, \"scene\": 0, \"scenes\": [{\"nodes\": [0]}],"
               " \"nodes\": [{\"mesh\": 0, \"translation\": [5, 0, 0]}],"
               " \"meshes\": [{\"primitives\": [{\"attributes\": {\"POSITION\": 0}, \"material\": 0}]}],"
               " \"materials\": [{\"name\": \"glow\", \"emissiveFactor\": [1, 0.5, 0.25],"
               " \"pbrMetallicRoughness\": {\"baseColorFactor\": [0.2, 0.3, 0.4, 1]}}],"
               " \"buffers\": [{\"byteLength\": 36, \"uri\": \"data:application/octet-stream;base64,"
               "AAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAAAAAAAAgD8AAAAA\"}],"
               " \"bufferViews\": [{\"buffer\": 0, \"byteLength\": 36}],"
               " \"accessors\": [{\"bufferView\": 0, \"componentType\": 5126, \"count\": 3,"
               " \"type\": \"VEC3\", \"min\": [0, 0, 0], \"max\": [1, 1, 0]}]}",
               path, sizeof path);
    scene *s = load(path, LM_OK);
    if (s) {
        CHECK(s->tri_count == 1);
        CHECK_NEAR(s->bounds_min[0] + s->origin[0], 5.0, 0); /* the file's coordinates */
        CHECK_NEAR(s->bounds_max[0] + s->origin[0], 6.0, 0);
        CHECK(s->area_light_count == 1);
        if (s->area_light_count == 1) {
            CHECK_NEAR(s->area_lights[0].le[1], 0.5, 1e-6);
            CHECK_NEAR(s->area_lights[0].normal[2], 1.0, 1e-6);
        }
        CHECK_NEAR(s->materials[0].kd[2], 0.4, 1e-6);
        scene_destroy(s);
    }
    test_write_file("square.off", "OFF\n4 1 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3\n", path, sizeof path);
    s = load(path, LM_OK);
    if (s) {
        CHECK(s->tri_count == 2 && s->vertex_count == 4);
        CHECK(s->materials[0].notes & SCENE_MATNOTE_DEFAULT);
        scene_destroy(s);
    }
    test_write_file("tri.stl",
               "solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\n"
               "endloop\nendfacet\nfacet normal 0 0 1\nouter loop\nvertex 1 0 0\nvertex 1 1 0\n"
               "vertex 0 1 0\nendloop\nendfacet\nendsolid t\n",
               path, sizeof path);
    s = load(path, LM_OK);
    if (s) {
        /* STL repeats corners per facet; welding shares them: one interior edge. */
        CHECK(s->tri_count == 2 && s->vertex_count == 4);
        mesh_geo_stats gs;
        mesh_geo_get_stats(s->topology, &gs);
        CHECK(gs.sides[MESH_EDGE_INTERIOR] == 2);
        scene_destroy(s);
    }
}

int main(void)
{
    test_builtin();
    test_cleaning();
    test_rewind_lamp();
    test_curved_emitter_and_normals();
    test_light_grouping();
    test_mirror_transform_and_camera();
    test_formats();
    return test_finish("scene_model_test");
}
