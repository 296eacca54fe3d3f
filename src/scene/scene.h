/* scene.h — the scene model: exactly what the light transport needs
 * (docs/architecture.md "The light transport").
 *
 * Triangles over one welded vertex table, per-corner shading normals, one
 * modified-Phong material per triangle (kd, ks, n, Le), area lights (connected
 * coplanar emissive triangles of one material), point lights, cameras and the
 * tone mapping settings. Loaded from a mesh file (through Assimp), from a JSON
 * scene description, or the built-in Cornell box.
 *
 * Coordinates: every position in a scene (vertices, lights, cameras, bounds) is in
 * float, relative to scene.origin, a point near the geometry that the loader
 * chose in double; the file's coordinates are origin + local (scene_to_file).
 * What is shown to users (`info`) speaks in the file's coordinates.
 *
 * Orientation: a triangle's front is the side of its winding normal
 * (counter-clockwise corners). When the file gives vertex normals that all point
 * to the other side, the triangle is re-wound so that front agrees with them.
 * Area lights emit from the front only (docs/scene-model.md says why).
 *
 * Usage:
 *     scene_load_desc d = {.path = "box.obj"};   // .path NULL: built-in scene
 *     scene *s; lm_error err;
 *     if (scene_load(&d, &s, &err) != LM_OK) { fprintf(stderr, "%s\n", err.msg); ... }
 *     for (uint32_t i = 0; i < s->tri_count; ++i) { const scene_tri *t = &s->tris[i]; ... }
 *     scene_destroy(s);
 *
 * Ownership: a loaded scene is immutable; any number of threads may read it.
 * Does NOT do: textures, transparency, refraction (approximated as Phong and
 * reported), instancing, animation.
 */
#ifndef LUMESH_SCENE_H
#define LUMESH_SCENE_H

#include <stdint.h>
#include "mesh/geomesh.h"
#include "src/base/util.h"

#ifdef __cplusplus
extern "C" {
#endif

enum {
    SCENE_NAME_MAX = 64,
    SCENE_PATH_MAX = 1024
};

/* Corners farther than this from the file's origin are dropped and counted: a
 * squared length of such a scene overflows a float (2^62, about 4.6e18). */
#define SCENE_COORD_MAX 4.611686018427388e18

/* What a loader had to approximate in a material (bits of scene_material.notes). */
typedef enum scene_material_note {
    SCENE_MATNOTE_REFRACTION_AS_PHONG = 1u << 0,  /* OBJ illum 4..7/9: glass, modelled opaque */
    SCENE_MATNOTE_TRANSPARENCY_IGNORED = 1u << 1, /* opacity < 1 (d < 1): modelled opaque */
    SCENE_MATNOTE_GAINS_ENERGY = 1u << 2,         /* kd + ks > 1 in some channel */
    SCENE_MATNOTE_DEFAULT = 1u << 3,              /* the file gave no material: default grey */
    SCENE_MATNOTE_OVERRIDDEN = 1u << 4,           /* replaced (in part) by the scene description */
    SCENE_MATNOTE_APPROXIMATED = 1u << 5          /* a richer model (a Mitsuba BSDF) approximated: see notes */
} scene_material_note;

typedef struct scene_material {
    char name[SCENE_NAME_MAX];
    float kd[3];     /* diffuse albedo, RGB in [0,1] */
    float ks[3];     /* specular reflectance of the modified Phong lobe, RGB */
    float n;         /* Phong exponent (dimensionless) */
    float le[3];     /* emitted radiance, W·m⁻²·sr⁻¹ (scene radiance units), RGB */
    uint32_t notes;  /* scene_material_note bits */
} scene_material;

typedef struct scene_tri {
    uint32_t v[3];     /* vertex ids into scene.positions; corners counter-clockwise seen from front */
    uint32_t material; /* index into scene.materials */
    int32_t light;     /* index into scene.area_lights, -1 when the triangle does not emit */
    uint32_t part;     /* index into scene.parts (the mesh/group it came from) */
} scene_tri;

typedef struct scene_area_light {
    uint32_t first, count; /* its triangles: scene.light_tris[first .. first+count) */
    uint32_t material;
    float area;            /* scene units² */
    float normal[3];       /* unit normal of the emitting (front) side */
    float centroid[3];     /* area-weighted, scene units */
    float le[3];           /* radiance, W·m⁻²·sr⁻¹ */
    float power[3];        /* W: π·Le·area (one-sided Lambertian emitter) */
    float bounds_min[3], bounds_max[3];
} scene_area_light;

typedef struct scene_point_light {
    float position[3];
    float intensity[3];    /* W·sr⁻¹ */
} scene_point_light;

typedef struct scene_camera {
    char name[SCENE_NAME_MAX];
    float position[3], target[3], up[3];
    float fov_y_deg;       /* full vertical field of view, degrees */
    int width, height;     /* pixels */
} scene_camera;

typedef struct scene_part {
    char name[SCENE_NAME_MAX];    /* group/mesh name from the file, or the file name */
    char source[SCENE_PATH_MAX];  /* file it came from */
} scene_part;

/* What loading dropped, fixed or approximated — shown by `lumesh info`. */
typedef struct scene_report {
    uint32_t input_triangles;        /* after triangulating polygons, before cleaning */
    uint32_t dropped_nonfinite;      /* a corner had NaN/Inf coordinates */
    uint32_t dropped_out_of_range;   /* a corner beyond SCENE_COORD_MAX from the file's origin */
    uint32_t dropped_degenerate;     /* zero area: repeated or collinear corners */
    uint32_t dropped_duplicate;      /* same three corners as an earlier triangle (either winding) */
    uint32_t rewound;                /* winding flipped to agree with the file's vertex normals */
    uint32_t corners_file_normals;   /* corners whose shading normal came from the file */
    uint32_t corners_computed_normals;
    uint32_t materials_unused;       /* materials no triangle uses (pruned) */
    double load_seconds;             /* wall time of scene_load */
    char **notes;                    /* one line each: approximations, quirks met, warnings */
    uint32_t note_count;
} scene_report;

typedef struct scene {
    char source[SCENE_PATH_MAX];     /* the path given to scene_load ("builtin:/..." for the default) */

    float *positions;                /* 3 floats per welded vertex, scene units */
    uint32_t vertex_count;

    scene_tri *tris;
    uint32_t tri_count;
    float *corner_normals;           /* 9 floats per triangle: unit shading normal per corner */
    float *tri_normals;              /* 3 floats per triangle: unit geometric (front) normal */
    float *tri_areas;                /* scene units² */

    scene_material *materials;
    uint32_t material_count;

    scene_area_light *area_lights;
    uint32_t area_light_count;
    uint32_t *light_tris;            /* triangle ids grouped by light */

    scene_point_light *point_lights;
    uint32_t point_light_count;

    scene_camera *cameras;           /* at least one: a framing camera when none was given */
    uint32_t camera_count;

    scene_part *parts;
    uint32_t part_count;

    float exposure;                  /* tone mapping, stops */
    double origin[3];                /* the file's coordinates of local (0,0,0); see "Coordinates" */
    float bounds_min[3], bounds_max[3]; /* local */
    float crease_angle_deg;          /* used for computed normals */

    mesh_geo *topology;              /* edge neighbours (OpenMesh) */
    scene_report report;
} scene;

typedef struct scene_load_desc {
    const char *path;         /* mesh file (.obj .ply .off .stl .gltf .glb ...) or .json; NULL: built-in */
    float crease_angle_deg;   /* normals computed where the file has none; 0 = 30 */
    int require_light;        /* non-zero: a scene with no light is LM_ERR_BAD_INPUT */
    int default_width;        /* resolution of a framing camera; 0 = 640 */
    int default_height;       /* 0 = 480 */
} scene_load_desc;

lm_result scene_load(const scene_load_desc *desc, scene **out, lm_error *err);
void scene_destroy(scene *s); /* NULL is a no-op */

/* A local position in the file's coordinates: origin + local, in double. */
void scene_to_file(const scene *s, const float local[3], double out[3]);

/* Index of the camera named `name`, or -1. NULL or "" gives 0. */
int scene_find_camera(const scene *s, const char *name);
uint32_t scene_light_count(const scene *s); /* area + point lights */

#ifdef __cplusplus
}
#endif
#endif
