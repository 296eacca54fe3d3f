/* scene_internal.h — the scene builder that loaders fill and scene_build.c turns
 * into a clean scene. Private to src/scene*.c.
 *
 * Loaders only append raw triangles (world-space corners and optional file
 * normals), materials, parts, point lights and cameras; every cleaning rule
 * (finite, degenerate, duplicate, welding, normals, lights) lives in one place,
 * scene_build.c, so all formats get the same treatment.
 */
#ifndef LUMESH_SCENE_INTERNAL_H
#define LUMESH_SCENE_INTERNAL_H

#include <stddef.h>
#include "src/scene/scene.h"

/* A camera as the file gives it: where it stands and looks in the file's
 * coordinates, kept in double until scene_build knows the local origin. */
typedef struct scene_builder_camera {
    scene_camera cam;         /* name, up, fov, size; cam.position/target unused */
    double position[3], target[3];
} scene_builder_camera;

typedef struct scene_builder_point_light {
    float intensity[3];       /* W·sr⁻¹ */
    double position[3];       /* file coordinates */
} scene_builder_point_light;

typedef struct scene_builder {
    const char *source;       /* top-level path, for messages */

    /* Corners in the file's coordinates, in double: scene_build subtracts the
     * local origin before anything is rounded to float (docs/scene-model.md,
     * "Coordinates"). */
    double *pos;              /* 9 doubles per raw triangle: 3 corners, world space */
    float *nrm;               /* 9 floats per raw triangle: file normals, (0,0,0) where none */
    uint32_t *mat;            /* material per raw triangle */
    uint32_t *part;           /* part per raw triangle */
    size_t count, cap;

    scene_material *mats;
    uint32_t mat_count, mat_cap;
    scene_part *parts;
    uint32_t part_count, part_cap;
    scene_builder_point_light *points;
    uint32_t point_count, point_cap;
    scene_builder_camera *cams;
    uint32_t cam_count, cam_cap;
    char **notes;
    uint32_t note_count, note_cap;

    float exposure;
    uint32_t numbers_too_large;  /* over all files: numbers beyond float range or SCENE_COORD_MAX */
} scene_builder;

void scene_builder_free(scene_builder *b);

/* n may be NULL (no file normals). Corners are world space (the file's coordinates). */
lm_result scene_builder_add_triangle(scene_builder *b, const double p[9], const float *n,
                                     uint32_t material, uint32_t part, lm_error *err);
lm_result scene_builder_add_material(scene_builder *b, const scene_material *m, uint32_t *out_index,
                                     lm_error *err);
lm_result scene_builder_add_part(scene_builder *b, const char *name, const char *source,
                                 uint32_t *out_index, lm_error *err);
lm_result scene_builder_add_point_light(scene_builder *b, const scene_builder_point_light *p, lm_error *err);
lm_result scene_builder_add_camera(scene_builder *b, const scene_builder_camera *c, lm_error *err);
/* Adds one line to the load report (identical lines are kept once). */
void scene_builder_note(scene_builder *b, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 2, 3)))
#endif
    ;

/* A material with the loader defaults: grey kd 0.7, no ks, n 1, no emission. */
scene_material scene_material_default(const char *name);

/* Fills builder b (empty in a child process) from user's source; material
 * override as scene_import_mesh_file's (a builder material index, or -1). */
typedef lm_result (*scene_fill_fn)(scene_builder *b, void *user, int32_t material_override, lm_error *err);

/* Runs fill in a forked child and appends what it built to b (scene_isolate.c):
 * a crash, hang or leak of a third-party reader stays in the child and comes
 * back as one line about `what` (the file). */
lm_result scene_isolate(scene_builder *b, const char *what, int32_t material_override, scene_fill_fn fill,
                        void *user, lm_error *err);

/* Imports a mesh file through Assimp into the builder, in a child process
 * (scene_isolate).
 * transform: 16 doubles row-major (p' = M·p), or NULL for identity.
 * material_override: a builder material index given to every triangle, or -1 to
 * use the file's own materials. */
lm_result scene_import_mesh_file(scene_builder *b, const char *path, const double *transform,
                                 int32_t material_override, lm_error *err);

/* ---- guards in front of Assimp's parsers (scene_guard.c) ---- */

/* Numbers in a text mesh file that a float cannot hold. */
typedef struct scene_number_scan {
    uint32_t overflow;      /* beyond float's range: rewritten "inf" (their triangles are dropped) */
    uint32_t underflow;     /* non-zero, below float's normal range: rewritten "0" */
    uint32_t out_of_range;  /* a float, but beyond SCENE_COORD_MAX (scene_build drops their triangles) */
} scene_number_scan;

/* Checks the coordinate tokens of a text mesh file (ext "obj", "ply", "off", "stl";
 * others are left alone) and rewrites those a float cannot hold, in place and
 * token for token. data is NUL-terminated at data[size]. */
void scene_guard_numbers(const char *ext, char *data, size_t size, scene_number_scan *out);
/* Comments out the texture statements of an MTL file before its first newmtl; their count. */
uint32_t scene_guard_mtl(char *data, size_t size);
/* NULL when a PLY header is well formed, else what is wrong (*line: where). */
const char *scene_guard_ply(const char *data, size_t size, int *line);
/* NULL when a glTF (JSON or GLB) file's base64 data URIs are well formed. */
const char *scene_guard_gltf(const char *data, size_t size);

/* Reads a Mitsuba XML scene (scene_mitsuba.c; docs/scene-format.md) into the builder. */
lm_result scene_import_mitsuba(scene_builder *b, const char *path, lm_error *err);

/* ---- affine transforms of the loaders: row-major 4x4, p' = M·p ---- */
void scene_mat4_mul(const double *a, const double *b, double *out); /* out = a·b; out may alias */
void scene_mat4_point(const double *m, const double p[3], double out[3]);
/* c = the cofactor matrix of m's 3x3 part (det·M^-T: normals transform with it);
 * returns the determinant. */
double scene_mat4_normal_matrix(const double *m, double c[9]);

/* Reads a JSON scene description (see docs/scene-format.md) into the builder. */
lm_result scene_import_json(scene_builder *b, const char *path, lm_error *err);

/* Cleans, welds, orients, computes normals, topology and lights: builder -> scene.
 * Consumes nothing; the caller still frees the builder. */
lm_result scene_build(scene_builder *b, const scene_load_desc *desc, scene **out, lm_error *err);

/* Groups emissive triangles into planar area lights (scene_lights.c). */
lm_result scene_build_lights(scene *s, lm_error *err);

#endif
