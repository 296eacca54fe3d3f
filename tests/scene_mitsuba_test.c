/* scene_mitsuba_test — Mitsuba XML scenes: every element the loader reads
 * (shapes, transforms, BSDFs, textures, emitters, sensors, instances, defaults),
 * each checked against the numbers it must give; malformed files refused with
 * their line; and the Veach door's scene.xml as it is, against the hand
 * conversion in bench/scenes/veach-door.json. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "src/base/tonemap.h"
#include "src/base/vecmath.h"
#include "src/image/image.h"
#include "src/scene/scene.h"
#include "tests/test_util.h"

static scene *load(const char *path, lm_error *err)
{
    scene_load_desc d = {.path = path};
    scene *s = NULL;
    memset(err, 0, sizeof *err);
    if (scene_load(&d, &s, err) != LM_OK) return NULL;
    return s;
}

static const scene_material *material(const scene *s, const char *name)
{
    for (uint32_t i = 0; i < s->material_count; ++i)
        if (strcmp(s->materials[i].name, name) == 0) return &s->materials[i];
    CHECK_MSG(0, "no material '%s'", name);
    return NULL;
}

static int has_note(const scene *s, const char *needle)
{
    for (uint32_t i = 0; i < s->report.note_count; ++i)
        if (strstr(s->report.notes[i], needle)) return 1;
    return 0;
}

/* Triangles of a part, and their total area. */
static uint32_t part_triangles(const scene *s, const char *name, double *area)
{
    uint32_t n = 0;
    *area = 0.0;
    for (uint32_t t = 0; t < s->tri_count; ++t)
        if (strcmp(s->parts[s->tris[t].part].name, name) == 0) {
            n++;
            *area += s->tri_areas[t];
        }
    return n;
}

/* Mean front normal of a part's triangles. */
static void part_normal(const scene *s, const char *name, double out[3])
{
    out[0] = out[1] = out[2] = 0.0;
    for (uint32_t t = 0; t < s->tri_count; ++t)
        if (strcmp(s->parts[s->tris[t].part].name, name) == 0)
            for (int k = 0; k < 3; ++k) out[k] += s->tri_normals[3 * t + k];
    double l = sqrt(out[0] * out[0] + out[1] * out[1] + out[2] * out[2]);
    for (int k = 0; k < 3 && l > 0; ++k) out[k] /= l;
}

static void check_rgb(const float *got, double r, double g, double b, double tol)
{
    CHECK_NEAR(got[0], r, tol);
    CHECK_NEAR(got[1], g, tol);
    CHECK_NEAR(got[2], b, tol);
}

static double fresnel0(double a, double b) { return ((a - b) / (a + b)) * ((a - b) / (a + b)); }

/* A 2x1 texture, pure red and pure blue: its mean linear colour is (0.5, 0, 0.5)
 * whatever the decoding, as long as 255 decodes to 1 and 0 to 0. */
static void write_texture(char *path, size_t n)
{
    snprintf(path, n, "%s/mitsuba_tex.png", LUMESH_TMP_DIR);
    const uint8_t px[6] = {255, 0, 0, 0, 0, 255};
    img_write_desc d = {.path = path, .width = 2, .height = 1, .channels = 3, .pixels8 = px};
    lm_error err;
    CHECK_MSG(img_write(&d, &err) == LM_OK, "%s", err.msg);
}

static const char *ELEMENTS_XML =
    "<?xml version='1.0'?>\n"
    "<scene version='0.5.0'>\n"
    "  <integrator type='path'/>\n"
    "  <default name='albedo' value='0.25'/>\n"
    "  <bsdf type='diffuse' id='grey'><spectrum name='reflectance' value='$albedo'/></bsdf>\n"
    "  <bsdf type='twosided' id='red2'><bsdf type='diffuse'><rgb name='reflectance' value='0.5, 0.1, 0.1'/></bsdf></bsdf>\n"
    "  <bsdf type='roughplastic' id='rp'><float name='alpha' value='0.5'/>\n"
    "    <srgb name='diffuse_reflectance' value='#808080'/><float name='intIOR' value='1.5'/><float name='extIOR' value='1'/></bsdf>\n"
    "  <bsdf type='conductor' id='gold'><string name='material' value='Au'/></bsdf>\n"
    "  <bsdf type='roughconductor' id='al'><string name='material' value='Al'/><float name='alpha' value='0.25'/>\n"
    "    <spectrum name='specularReflectance' value='0.5'/></bsdf>\n"
    "  <bsdf type='dielectric' id='glass'><string name='intIOR' value='bk7'/></bsdf>\n"
    "  <texture type='bitmap' id='tex'><string name='filename' value='mitsuba_tex.png'/></texture>\n"
    "  <bsdf type='bumpmap' id='bumped'><ref id='tex'/><bsdf type='diffuse'><ref name='reflectance' id='tex'/></bsdf></bsdf>\n"
    "  <bsdf type='coating' id='coat'><float name='intIOR' value='1.5'/><float name='extIOR' value='1.0'/>\n"
    "    <bsdf type='diffuse'><texture name='reflectance' type='checkerboard'/></bsdf></bsdf>\n"
    "  <bsdf type='blendbsdf' id='blend'><float name='weight' value='0.25'/>\n"
    "    <bsdf type='diffuse'><spectrum name='reflectance' value='0.8'/></bsdf>\n"
    "    <bsdf type='conductor'><string name='material' value='none'/></bsdf></bsdf>\n"
    "  <bsdf type='phong' id='ph'><spectrum name='diffuseReflectance' value='0.3'/>\n"
    "    <spectrum name='specularReflectance' value='0.2'/><float name='exponent' value='40'/></bsdf>\n"
    "  <bsdf type='hk' id='odd'/>\n"
    "  <bsdf type='mask' id='masked'><spectrum name='opacity' value='0.5'/><ref id='grey'/></bsdf>\n"
    "  <bsdf type='diffuse' id='banded'><spectrum name='reflectance' value='400:0.2, 500:0.2, 500.001:0.6, 700:0.6'/></bsdf>\n"
    /* a 4 x 6 quad light at y = 1 facing down: scale, then rotate about x by 90 degrees, then translate */
    "  <shape type='rectangle' id='lightquad'>\n"
    "    <transform name='toWorld'><scale x='2' y='3'/><rotate x='1' angle='90'/><translate y='1'/></transform>\n"
    "    <emitter type='area'><spectrum name='radiance' value='10'/></emitter>\n"
    "  </shape>\n"
    "  <shape type='rectangle' id='floor'><transform name='toWorld'><rotate x='1' angle='-90'/><scale value='5'/></transform>\n"
    "    <ref id='grey'/></shape>\n"
    "  <shape type='cube' id='box'><transform name='toWorld'><scale value='0.5'/><translate x='-2' y='0.5'/></transform>\n"
    "    <ref id='bumped'/></shape>\n"
    "  <shape type='sphere' id='ball'><point name='center' x='2' y='0.5' z='0'/><float name='radius' value='0.5'/>\n"
    "    <ref id='rp'/></shape>\n"
    "  <shape type='disk' id='plate'><boolean name='flipNormals' value='true'/>\n"
    "    <transform name='toWorld'><translate z='-3'/></transform><ref id='glass'/></shape>\n"
    "  <shape type='obj' id='tri'><string name='filename' value='mitsuba_tri.obj'/>\n"
    "    <transform name='toWorld'><matrix value='1 0 0 0  0 0 1 0  0 -1 0 0  0 0 0 1'/><translate x='3' z='3'/></transform>\n"
    "    <ref id='gold'/></shape>\n"
    "  <shape type='ply' id='sq'><string name='filename' value='mitsuba_sq.ply'/>\n"
    "    <transform name='toWorld'><translate x='-3' z='3'/></transform><ref id='al'/></shape>\n"
    "  <shape type='shapegroup' id='grp'><shape type='rectangle'><ref id='blend'/></shape></shape>\n"
    "  <shape type='instance'><ref id='grp'/><transform name='toWorld'><translate z='6'/></transform></shape>\n"
    "  <shape type='instance'><ref id='grp'/><transform name='toWorld'><translate z='9'/></transform></shape>\n"
    "  <shape type='rectangle' id='r_red'><transform name='toWorld'><translate z='12'/></transform><ref id='red2'/></shape>\n"
    "  <shape type='rectangle' id='r_coat'><transform name='toWorld'><translate z='15'/></transform><ref id='coat'/></shape>\n"
    "  <shape type='rectangle' id='r_ph'><transform name='toWorld'><translate z='18'/></transform><ref id='ph'/></shape>\n"
    "  <shape type='rectangle' id='r_odd'><transform name='toWorld'><translate z='21'/></transform><ref id='odd'/></shape>\n"
    "  <shape type='rectangle' id='r_mask'><transform name='toWorld'><translate z='24'/></transform><ref id='masked'/></shape>\n"
    "  <shape type='rectangle' id='r_band'><transform name='toWorld'><translate z='27'/></transform><ref id='banded'/></shape>\n"
    "  <shape type='rectangle' id='ghost'><bsdf type='null'/></shape>\n"
    "  <emitter type='point'><point name='position' x='1' y='2' z='3'/><spectrum name='intensity' value='5'/></emitter>\n"
    "  <emitter type='point'><transform name='toWorld'><translate x='-1' y='4'/></transform>\n"
    "    <rgb name='intensity' value='1 2 3'/></emitter>\n"
    "  <emitter type='envmap'><string name='filename' value='sky.exr'/></emitter>\n"
    "  <sensor type='perspective' id='front'><float name='fov' value='60'/><string name='fovAxis' value='x'/>\n"
    "    <transform name='toWorld'><lookat origin='0, 1, 5' target='0, 1, 0' up='0, 1, 0'/></transform>\n"
    "    <film type='hdrfilm'><integer name='width' value='400'/><integer name='height' value='200'/></film></sensor>\n"
    "  <sensor type='thinlens'><transform name='toWorld'><lookat origin='5 1 0' target='0 1 0' up='0 1 0'/></transform>\n"
    "    <film type='ldrfilm'><integer name='width' value='300'/><integer name='height' value='200'/></film></sensor>\n"
    "</scene>\n";

static void test_elements(void)
{
    char path[1024], tex[1024], obj[1024], ply[1024];
    write_texture(tex, sizeof tex);
    test_write_file("mitsuba_tri.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", obj, sizeof obj);
    test_write_file("mitsuba_sq.ply",
                    "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
                    "element face 1\nproperty list uchar int vertex_indices\nend_header\n"
                    "0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3\n",
                    ply, sizeof ply);
    test_write_file("mitsuba_elements.xml", ELEMENTS_XML, path, sizeof path);
    lm_error err;
    scene *s = load(path, &err);
    CHECK_MSG(s != NULL, "%s", err.msg);
    if (!s) return;
    double area, n[3];

    /* Shapes, with their transforms. */
    CHECK(part_triangles(s, "lightquad", &area) == 2);
    CHECK_NEAR(area, 24.0, 1e-4);
    CHECK(part_triangles(s, "floor", &area) == 2);
    CHECK_NEAR(area, 100.0, 1e-3);
    part_normal(s, "floor", n);
    CHECK_NEAR(n[1], 1.0, 1e-6); /* rotate about x by -90: +z turns to +y */
    CHECK(part_triangles(s, "box", &area) == 12);
    CHECK_NEAR(area, 6.0, 1e-5);
    CHECK(part_triangles(s, "ball", &area) == 1280);
    CHECK(area < M_PI && area > 0.98 * M_PI); /* inscribed in the sphere of radius 0.5 */
    CHECK(part_triangles(s, "plate", &area) == 64);
    CHECK_NEAR(area, 32.0 * sin(2.0 * M_PI / 64.0), 1e-5);
    part_normal(s, "plate", n);
    CHECK_NEAR(n[2], -1.0, 1e-6); /* flipNormals: the disk's +z turned to -z */
    CHECK(s->report.rewound == 0);                /* primitives wound as their normals say */
    CHECK(!has_note(s, "could not join"));        /* the cube and the sphere are closed */
    CHECK(s->tri_count == 2 + 2 + 12 + 1280 + 64 + 1 + 2 + 2 * 2 + 6 * 2);
    CHECK(has_note(s, "shape 'ghost' has a null BSDF and emits nothing: not loaded"));

    /* The OBJ: (x, y, z) -> (x, z, -y), then translate (3, 0, 3): its corner (0,1,0) lands at (3, 0, 2). */
    double bmin[3], bmax[3];
    for (int k = 0; k < 3; ++k) bmin[k] = INFINITY, bmax[k] = -INFINITY;
    uint32_t gold = (uint32_t)(material(s, "gold") - s->materials);
    for (uint32_t t = 0; t < s->tri_count; ++t) {
        if (s->tris[t].material != gold) continue;
        for (int c = 0; c < 3; ++c) {
            double p[3];
            scene_to_file(s, &s->positions[3 * s->tris[t].v[c]], p);
            for (int k = 0; k < 3; ++k) bmin[k] = fmin(bmin[k], p[k]), bmax[k] = fmax(bmax[k], p[k]);
        }
    }
    CHECK_NEAR(bmin[0], 3.0, 1e-5);
    CHECK_NEAR(bmax[0], 4.0, 1e-5);
    CHECK_NEAR(bmin[1], 0.0, 1e-5);
    CHECK_NEAR(bmax[1], 0.0, 1e-5);
    CHECK_NEAR(bmin[2], 2.0, 1e-5);
    CHECK_NEAR(bmax[2], 3.0, 1e-5);

    /* BSDFs as modified Phong. */
    const scene_material *m;
    if ((m = material(s, "grey"))) check_rgb(m->kd, 0.25, 0.25, 0.25, 1e-7); /* $albedo from <default> */
    if ((m = material(s, "red2"))) {
        check_rgb(m->kd, 0.5, 0.1, 0.1, 1e-7);
        CHECK(!(m->notes & SCENE_MATNOTE_APPROXIMATED)); /* twosided is exact */
    }
    if ((m = material(s, "rp"))) {
        double g = tm_srgb_decode(128.0f / 255.0f);
        check_rgb(m->kd, g, g, g, 1e-6);
        check_rgb(m->ks, 0.04, 0.04, 0.04, 1e-7);
        CHECK_NEAR(m->n, 6.0, 1e-5); /* 2/alpha^2 - 2 */
        CHECK(m->notes & SCENE_MATNOTE_APPROXIMATED);
    }
    if ((m = material(s, "gold"))) {
        check_rgb(m->kd, 0, 0, 0, 0);
        check_rgb(m->ks, 1.0, 0.766, 0.336, 1e-6);
        CHECK_NEAR(m->n, 1000.0, 0);
    }
    if ((m = material(s, "al"))) {
        check_rgb(m->ks, 0.5 * 0.913, 0.5 * 0.922, 0.5 * 0.924, 1e-6);
        CHECK_NEAR(m->n, 30.0, 1e-4);
    }
    if ((m = material(s, "glass"))) {
        double f = fresnel0(1.5046, 1.000277);
        check_rgb(m->kd, 0, 0, 0, 0);
        check_rgb(m->ks, f, f, f, 1e-7);
    }
    if ((m = material(s, "bumped"))) check_rgb(m->kd, 0.5, 0.0, 0.5, 1e-6);
    if ((m = material(s, "coat"))) {
        check_rgb(m->kd, 0.3, 0.3, 0.3, 1e-6); /* the checkerboard's mean, (0.4 + 0.2) / 2 */
        check_rgb(m->ks, 0.04, 0.04, 0.04, 1e-7);
        CHECK_NEAR(m->n, 1000.0, 0);
    }
    if ((m = material(s, "blend"))) {
        check_rgb(m->kd, 0.6, 0.6, 0.6, 1e-6);
        check_rgb(m->ks, 0.25, 0.25, 0.25, 1e-6);
        CHECK_NEAR(m->n, 1000.0, 0);
    }
    if ((m = material(s, "ph"))) {
        check_rgb(m->kd, 0.3, 0.3, 0.3, 1e-7);
        check_rgb(m->ks, 0.2, 0.2, 0.2, 1e-7);
        CHECK_NEAR(m->n, 40.0, 0);
        CHECK(!(m->notes & SCENE_MATNOTE_APPROXIMATED)); /* Mitsuba's phong is the model itself */
    }
    if ((m = material(s, "odd"))) check_rgb(m->kd, 0.5, 0.5, 0.5, 0);
    if ((m = material(s, "masked"))) check_rgb(m->kd, 0.25, 0.25, 0.25, 1e-7);
    if ((m = material(s, "banded"))) check_rgb(m->kd, 0.6, 0.6, 0.2, 1e-3);
    CHECK(has_note(s, "bumpmap ignored"));
    CHECK(has_note(s, "mask (opacity) ignored"));
    CHECK(has_note(s, "BSDF type 'hk' not modelled"));
    CHECK(has_note(s, "approximated by its mean colour 0.5 0 0.5"));
    CHECK(has_note(s, "averaged over 600-700"));

    /* Emitters. */
    CHECK(s->area_light_count == 1);
    if (s->area_light_count == 1) {
        const scene_area_light *L = &s->area_lights[0];
        CHECK_NEAR(L->area, 24.0, 1e-4);
        check_rgb(L->le, 10, 10, 10, 0);
        check_rgb(L->normal, 0, -1, 0, 1e-6);
        double c[3];
        scene_to_file(s, L->centroid, c);
        CHECK_NEAR(c[0], 0.0, 1e-5);
        CHECK_NEAR(c[1], 1.0, 1e-5);
        CHECK_NEAR(c[2], 0.0, 1e-5);
        CHECK(strcmp(s->materials[L->material].name, "lightquad") == 0);
        check_rgb(s->materials[L->material].kd, 0.5, 0.5, 0.5, 0); /* Mitsuba's default BSDF */
    }
    CHECK(s->point_light_count == 2);
    if (s->point_light_count == 2) {
        double p[3];
        scene_to_file(s, s->point_lights[0].position, p);
        CHECK_NEAR(p[0], 1.0, 1e-5);
        CHECK_NEAR(p[1], 2.0, 1e-5);
        CHECK_NEAR(p[2], 3.0, 1e-5);
        check_rgb(s->point_lights[0].intensity, 5, 5, 5, 0);
        scene_to_file(s, s->point_lights[1].position, p);
        CHECK_NEAR(p[0], -1.0, 1e-5);
        CHECK_NEAR(p[1], 4.0, 1e-5);
        check_rgb(s->point_lights[1].intensity, 1, 2, 3, 0);
    }
    CHECK(has_note(s, "emitter type 'envmap' is not modelled"));

    /* Sensors: fov 60 along x at 2:1 is 2 atan(tan 30 / 2) along y; a 50 mm lens
     * on 35 mm film (36 x 24) at 3:2 sees 2 atan(12/50) along y. */
    CHECK(s->camera_count == 2);
    if (s->camera_count == 2) {
        const scene_camera *c = &s->cameras[0];
        CHECK(strcmp(c->name, "front") == 0);
        CHECK(c->width == 400 && c->height == 200);
        CHECK_NEAR(c->fov_y_deg, 2.0 * atan(tan(M_PI / 6.0) / 2.0) * 180.0 / M_PI, 1e-4);
        double p[3], t[3];
        scene_to_file(s, c->position, p);
        scene_to_file(s, c->target, t);
        CHECK_NEAR(p[1], 1.0, 1e-5);
        CHECK_NEAR(p[2], 5.0, 1e-5);
        CHECK_NEAR(t[2] - p[2], -1.0 * sqrt((t[0] - p[0]) * (t[0] - p[0]) + (t[2] - p[2]) * (t[2] - p[2])), 1e-5);
        CHECK_NEAR(c->up[1], 1.0, 1e-6);
        c = &s->cameras[1];
        CHECK(c->width == 300 && c->height == 200);
        CHECK_NEAR(c->fov_y_deg, 2.0 * atan(12.0 / 50.0) * 180.0 / M_PI, 1e-4);
    }
    CHECK(has_note(s, "thinlens sensor read as a pinhole"));
    scene_destroy(s);
}

/* An emitting sphere: each flat facet one area light, all facing out. */
static void test_sphere_light(void)
{
    char path[1024];
    test_write_file("mitsuba_sphere_light.xml",
                    "<scene version='0.6.0'><shape type='sphere'><float name='radius' value='2'/>"
                    "<emitter type='area'><rgb name='radiance' value='1 2 3'/></emitter></shape></scene>",
                    path, sizeof path);
    lm_error err;
    scene *s = load(path, &err);
    CHECK_MSG(s != NULL, "%s", err.msg);
    if (!s) return;
    CHECK(s->area_light_count == 80);
    int outward = 0;
    for (uint32_t i = 0; i < s->area_light_count; ++i) {
        double c[3];
        scene_to_file(s, s->area_lights[i].centroid, c);
        const float *nn = s->area_lights[i].normal;
        outward += c[0] * nn[0] + c[1] * nn[1] + c[2] * nn[2] > 0.0;
    }
    CHECK(outward == 80);
    CHECK(has_note(s, "tessellated into 80 flat triangles (each one an area light)"));
    scene_destroy(s);
}

/* Mitsuba 3 spellings: to_world, fov_axis, value="x y z" translate, axis= rotate. */
static void test_mitsuba3_names(void)
{
    char path[1024];
    test_write_file("mitsuba3.xml",
                    "<scene version='3.0.0'>\n"
                    "<sensor type='perspective'><float name='fov' value='40'/><string name='fov_axis' value='y'/>\n"
                    "  <transform name='to_world'><lookat origin='0,0,4' target='0,0,0' up='0,1,0'/></transform></sensor>\n"
                    "<shape type='rectangle'><transform name='to_world'><rotate axis='1 0 0' angle='90'/>"
                    "<translate value='0 2 0'/></transform>\n"
                    "  <emitter type='area'><rgb name='radiance' value='4'/></emitter></shape>\n"
                    "</scene>\n",
                    path, sizeof path);
    lm_error err;
    scene *s = load(path, &err);
    CHECK_MSG(s != NULL, "%s", err.msg);
    if (!s) return;
    CHECK(s->camera_count == 1 && fabsf(s->cameras[0].fov_y_deg - 40.0f) < 1e-4f);
    CHECK(s->cameras[0].width == 768 && s->cameras[0].height == 576); /* Mitsuba's default film */
    CHECK(s->area_light_count == 1);
    if (s->area_light_count == 1) {
        double c[3];
        scene_to_file(s, s->area_lights[0].centroid, c);
        CHECK_NEAR(c[1], 2.0, 1e-5);
        check_rgb(s->area_lights[0].normal, 0, -1, 0, 1e-6);
    }
    scene_destroy(s);
}

/* Broken files: one message naming the file and line, never a crash. */
static void test_errors(void)
{
    static const struct { const char *xml, *expect; } cases[] = {
        {"<scene><shape type='cube'></scene>", ":1:"},
        {"<foo/>", "the top element must be <scene>"},
        {"<scene><integrator type='path'/></scene>", "has no <shape>"},
        {"<scene>\n<shape type='cube'><ref id='nope'/></shape></scene>", ":2: <ref>: no element has id 'nope'"},
        {"<scene>\n\n<shape type='obj'><string name='filename' value='missing.obj'/></shape></scene>",
         ":3: <shape>: "},
        {"<scene><shape type='cube'><transform name='toWorld'><scale x='0'/></transform></shape></scene>",
         "singular"},
        {"<scene><shape type='cube'><transform name='toWorld'><skew/></transform></shape></scene>",
         "unknown transform operation"},
        {"<scene><bsdf type='roughplastic' id='a'><float name='alpha' value='abc'/></bsdf>"
         "<shape type='cube'><ref id='a'/></shape></scene>",
         "'alpha' needs value"},
        {"<scene><shape type='obj'/></scene>", "needs a filename"},
        {"<scene><sensor type='perspective'><float name='fov' value='200'/></sensor><shape type='cube'/></scene>",
         "fov must be in (0, 180)"},
        {"<scene><shape type='cube'><bsdf type='dielectric'><string name='intIOR' value='unobtainium'/></bsdf>"
         "</shape></scene>",
         "unknown material 'unobtainium'"},
        {"<!DOCTYPE l [<!ENTITY a 'aaaaaaaaaa'><!ENTITY b '&a;&a;&a;&a;&a;&a;&a;&a;&a;&a;'>"
         "<!ENTITY c '&b;&b;&b;&b;&b;&b;&b;&b;&b;&b;'><!ENTITY d '&c;&c;&c;&c;&c;&c;&c;&c;&c;&c;'>"
         "<!ENTITY e '&d;&d;&d;&d;&d;&d;&d;&d;&d;&d;'><!ENTITY f '&e;&e;&e;&e;&e;&e;&e;&e;&e;&e;'>"
         "<!ENTITY g '&f;&f;&f;&f;&f;&f;&f;&f;&f;&f;'><!ENTITY h '&g;&g;&g;&g;&g;&g;&g;&g;&g;&g;'>]>"
         "<scene><shape type='cube' id='&h;'/></scene>",
         "not well-formed XML"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; ++i) {
        char name[64], path[1024];
        snprintf(name, sizeof name, "mitsuba_bad%zu.xml", i);
        test_write_file(name, cases[i].xml, path, sizeof path);
        lm_error err;
        scene *s = load(path, &err);
        CHECK_MSG(s == NULL, "case %zu loaded", i);
        scene_destroy(s);
        CHECK_MSG(strstr(err.msg, cases[i].expect) && strstr(err.msg, name), "case %zu: '%s' lacks '%s'", i,
                  err.msg, cases[i].expect);
    }
    /* Nested past the cap: refused, not a stack overflow. */
    size_t depth = 400;
    char *deep = malloc(depth * 16 + 64), path[1024];
    char *p = deep + sprintf(deep, "<scene>");
    for (size_t i = 0; i < depth; ++i) p += sprintf(p, "<a>");
    for (size_t i = 0; i < depth; ++i) p += sprintf(p, "</a>");
    sprintf(p, "</scene>");
    test_write_file("mitsuba_deep.xml", deep, path, sizeof path);
    free(deep);
    lm_error err;
    scene *s = load(path, &err);
    CHECK(s == NULL && strstr(err.msg, "nested more than 256"));
    scene_destroy(s);
}

/* The Veach door as it is: the same geometry, light and camera as the hand
 * conversion (bench/scenes/veach-door.json), its lamp facing the door. */
static void test_veach_door(void)
{
    lm_error err;
    scene *x = load(LUMESH_SCENES "/veach-door/scene.xml", &err);
    CHECK_MSG(x != NULL, "%s", err.msg);
    scene *j = load(LUMESH_TEST_DIR "/../bench/scenes/veach-door.json", &err);
    CHECK_MSG(j != NULL, "%s", err.msg);
    if (x && j) {
        CHECK(x->tri_count == 20764 && x->tri_count == j->tri_count);
        CHECK(x->area_light_count == 1 && j->area_light_count == 1);
        if (x->area_light_count == 1) {
            const scene_area_light *L = &x->area_lights[0];
            check_rgb(L->le, 1420, 1552, 1642, 0);
            check_rgb(L->normal, 0, 0, 1, 1e-6); /* towards the door, from lamp.obj's vn */
            CHECK_NEAR(L->area, j->area_lights[0].area, 1e-3);
        }
        for (int k = 0; k < 3; ++k) {
            CHECK_NEAR(x->bounds_min[k] + x->origin[k], j->bounds_min[k] + j->origin[k], 1e-3);
            CHECK_NEAR(x->bounds_max[k] + x->origin[k], j->bounds_max[k] + j->origin[k], 1e-3);
        }
        CHECK(x->camera_count == 1);
        if (x->camera_count == 1) {
            CHECK_NEAR(x->cameras[0].fov_y_deg, 32.3792, 1e-3); /* fov 54.6003 along x at 16:9 */
            CHECK(x->cameras[0].width == 1280 && x->cameras[0].height == 720);
        }
        const scene_material *m;
        if ((m = material(x, "marble"))) check_rgb(m->kd, 0.811, 0.795, 0.903, 1e-3); /* the JSON's texture means */
        if ((m = material(x, "wood2"))) check_rgb(m->kd, 0.773, 0.623, 0.411, 1e-3);
        if ((m = material(x, "picture_image"))) check_rgb(m->kd, 0.546, 0.577, 0.606, 1e-3);
        if ((m = material(x, "glass"))) CHECK(m->notes & SCENE_MATNOTE_APPROXIMATED);
        CHECK(has_note(x, "bump ignored"));
    }
    scene_destroy(x);
    scene_destroy(j);
}

int main(void)
{
    test_elements();
    test_sphere_light();
    test_mitsuba3_names();
    test_errors();
    test_veach_door();
    return test_finish("scene_mitsuba_test");
}
