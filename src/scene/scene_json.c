/* scene_json.c — the JSON scene description (docs/scene-format.md), through cJSON.
 *
 * Shape:
 *   {"meshes":   [{"file": "room.obj", "transform": [16 numbers, row-major], "material": "name"}],
 *    "materials": {"name": {"kd": [r,g,b], "ks": [r,g,b], "n": 20, "Le": [r,g,b]}},
 *    "lights":   [{"type": "quad", "corner": [..], "edge1": [..], "edge2": [..], "radiance": [..]},
 *                 {"type": "point", "position": [..], "intensity": [..]}],
 *    "cameras":  [{"name": "main", "position": [..], "target": [..], "up": [0,1,0],
 *                  "fov_y": 40, "width": 640, "height": 480}],
 *    "tonemap":  {"exposure": 0.0}}
 *
 * Paths are relative to the description. A "materials" entry overrides, field by
 * field, every material of that name the mesh files bring (e.g. an MTL's), and
 * is given whole to a mesh that names it in "material" (files with no materials,
 * such as PLY scans). Every shape error names the file and the JSON path.
 */
#include <cjson/cJSON.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "src/base/vecmath.h"
#include "src/base/vfs.h"
#include "src/scene/scene_internal.h"

enum { MAX_JSON_BYTES = 64 << 20 };

typedef struct json_ctx {
    scene_builder *b;
    const char *path;
    char dir[SCENE_PATH_MAX];
    const cJSON *materials;     /* the "materials" object or NULL */
} json_ctx;

static lm_result shape_error(const json_ctx *c, lm_error *err, const char *where, const char *what)
{
    return lm_fail(err, LM_ERR_BAD_INPUT, "%s: %s: %s", c->path, where, what);
}

/* Reads an array of exactly n finite numbers. Positions and transforms stay in
 * double until scene_build has subtracted the local origin (scene-model.md,
 * "Coordinates"); they must still fit a float, as everything does in the end. */
static int get_doubles(const cJSON *item, double *out, int n)
{
    if (!cJSON_IsArray(item) || cJSON_GetArraySize(item) != n) return 0;
    int i = 0;
    for (const cJSON *e = item->child; e; e = e->next, ++i) {
        if (!cJSON_IsNumber(e) || !isfinite(e->valuedouble)) return 0;
        if (!isfinite((float)e->valuedouble)) return 0; /* finite double, too large for float */
        out[i] = e->valuedouble;
    }
    return 1;
}

static int get_numbers(const cJSON *item, float *out, int n)
{
    double d[16];
    if (n > 16 || !get_doubles(item, d, n)) return 0;
    for (int i = 0; i < n; ++i) out[i] = (float)d[i];
    return 1;
}

static lm_result vec3_error(const json_ctx *c, const cJSON *item, const char *where, const char *key,
                            int required, lm_error *err)
{
    char at[160];
    snprintf(at, sizeof at, "%s.%s", where, key);
    if (!item) return required ? shape_error(c, err, at, "missing (expected [x, y, z])") : LM_OK;
    return shape_error(c, err, at, "expected an array of 3 finite numbers");
}

static lm_result get_vec3(const json_ctx *c, const cJSON *obj, const char *key, const char *where,
                          int required, int nonnegative, float out[3], lm_error *err)
{
    const cJSON *item = cJSON_GetObjectItemCaseSensitive(obj, key);
    if (!item || !get_numbers(item, out, 3)) return vec3_error(c, item, where, key, required, err);
    if (nonnegative && (out[0] < 0 || out[1] < 0 || out[2] < 0)) {
        char at[160];
        snprintf(at, sizeof at, "%s.%s", where, key);
        return shape_error(c, err, at, "values must not be negative");
    }
    return LM_OK;
}

/* A position or offset in the file's coordinates (double, see get_doubles). */
static lm_result get_point(const json_ctx *c, const cJSON *obj, const char *key, const char *where,
                           int required, double out[3], lm_error *err)
{
    const cJSON *item = cJSON_GetObjectItemCaseSensitive(obj, key);
    if (!item || !get_doubles(item, out, 3)) return vec3_error(c, item, where, key, required, err);
    return LM_OK;
}

static void note_unknown_keys(const json_ctx *c, const cJSON *obj, const char *where,
                              const char *const *known)
{
    for (const cJSON *e = obj->child; e; e = e->next) {
        int ok = 0;
        for (const char *const *k = known; *k; ++k) ok |= strcmp(e->string, *k) == 0;
        if (!ok) scene_builder_note(c->b, "%s: %s: unknown key '%s' ignored", c->path, where, e->string);
    }
}

/* ---- materials ----------------------------------------------------------- */

/* Applies the fields present in spec to m. */
static lm_result apply_material_spec(const json_ctx *c, const cJSON *spec, const char *name,
                                     scene_material *m, lm_error *err)
{
    char where[128];
    snprintf(where, sizeof where, "materials.%s", name);
    if (!cJSON_IsObject(spec)) return shape_error(c, err, where, "expected an object");
    static const char *const known[] = {"kd", "ks", "n", "Le", NULL};
    note_unknown_keys(c, spec, where, known);
    lm_result r;
    if ((r = get_vec3(c, spec, "kd", where, 0, 1, m->kd, err)) != LM_OK) return r;
    if ((r = get_vec3(c, spec, "ks", where, 0, 1, m->ks, err)) != LM_OK) return r;
    if ((r = get_vec3(c, spec, "Le", where, 0, 1, m->le, err)) != LM_OK) return r;
    const cJSON *n = cJSON_GetObjectItemCaseSensitive(spec, "n");
    if (n) {
        if (!cJSON_IsNumber(n) || !isfinite(n->valuedouble) || n->valuedouble < 0.0)
            return shape_error(c, err, where, "n must be a non-negative number");
        m->n = (float)n->valuedouble;
    }
    return LM_OK;
}

static lm_result validate_materials(const json_ctx *c, lm_error *err)
{
    if (!c->materials) return LM_OK;
    for (const cJSON *e = c->materials->child; e; e = e->next) {
        scene_material scratch = scene_material_default(e->string);
        lm_result r = apply_material_spec(c, e, e->string, &scratch, err);
        if (r != LM_OK) return r;
    }
    return LM_OK;
}

/* Overrides every builder material whose name has an entry in "materials". */
static lm_result override_file_materials(json_ctx *c, uint32_t first, lm_error *err)
{
    if (!c->materials) return LM_OK;
    for (uint32_t i = first; i < c->b->mat_count; ++i) {
        scene_material *m = &c->b->mats[i];
        const cJSON *spec = cJSON_GetObjectItemCaseSensitive(c->materials, m->name);
        if (!spec) continue;
        lm_result r = apply_material_spec(c, spec, m->name, m, err);
        if (r != LM_OK) return r;
        m->notes |= SCENE_MATNOTE_OVERRIDDEN;
        m->notes &= ~(uint32_t)SCENE_MATNOTE_DEFAULT;
    }
    return LM_OK;
}

/* ---- meshes -------------------------------------------------------------- */

static lm_result load_mesh(json_ctx *c, const cJSON *m, int index, lm_error *err)
{
    char where[64];
    snprintf(where, sizeof where, "meshes[%d]", index);
    if (!cJSON_IsObject(m)) return shape_error(c, err, where, "expected an object");
    static const char *const known[] = {"file", "transform", "material", NULL};
    note_unknown_keys(c, m, where, known);
    const cJSON *file = cJSON_GetObjectItemCaseSensitive(m, "file");
    if (!cJSON_IsString(file) || !file->valuestring[0])
        return shape_error(c, err, where, "\"file\" must be a non-empty string");
    char ext[16];
    lm_path_ext(file->valuestring, ext, sizeof ext);
    if (strcmp(ext, "json") == 0)
        return shape_error(c, err, where, "a mesh file cannot be another .json scene description");
    char full[SCENE_PATH_MAX];
    if (!lm_path_join(c->dir, file->valuestring, full, sizeof full))
        return shape_error(c, err, where, "file path too long");

    double transform[16];
    const cJSON *tf = cJSON_GetObjectItemCaseSensitive(m, "transform");
    if (tf) {
        if (!get_doubles(tf, transform, 16))
            return shape_error(c, err, where, "\"transform\" must be an array of 16 finite numbers "
                                              "(row-major 4x4)");
        double det = transform[0] * (transform[5] * transform[10] - transform[6] * transform[9]) -
                     transform[1] * (transform[4] * transform[10] - transform[6] * transform[8]) +
                     transform[2] * (transform[4] * transform[9] - transform[5] * transform[8]);
        if (det == 0.0 || !isfinite(det))
            return shape_error(c, err, where, "\"transform\" is singular (it flattens the mesh)");
    }

    int32_t override_index = -1;
    const cJSON *mat = cJSON_GetObjectItemCaseSensitive(m, "material");
    if (mat) {
        if (!cJSON_IsString(mat)) return shape_error(c, err, where, "\"material\" must be a string");
        const cJSON *spec =
            c->materials ? cJSON_GetObjectItemCaseSensitive(c->materials, mat->valuestring) : NULL;
        if (!spec)
            return lm_fail(err, LM_ERR_BAD_INPUT,
                           "%s: %s: material '%s' is not defined in \"materials\"", c->path, where,
                           mat->valuestring);
        scene_material sm = scene_material_default(mat->valuestring);
        lm_result r = apply_material_spec(c, spec, mat->valuestring, &sm, err);
        if (r != LM_OK) return r;
        uint32_t idx;
        r = scene_builder_add_material(c->b, &sm, &idx, err);
        if (r != LM_OK) return r;
        override_index = (int32_t)idx;
    }
    lm_result r = scene_import_mesh_file(c->b, full, tf ? transform : NULL, override_index, err);
    if (r != LM_OK && err) { /* say which description and entry led there */
        char inner[sizeof err->msg];
        memcpy(inner, err->msg, sizeof inner);
        lm_fail(err, r, "%s: %s: %s", c->path, where, inner);
    }
    return r;
}

/* ---- lights -------------------------------------------------------------- */

static lm_result load_light(json_ctx *c, const cJSON *l, int index, lm_error *err)
{
    char where[64];
    snprintf(where, sizeof where, "lights[%d]", index);
    if (!cJSON_IsObject(l)) return shape_error(c, err, where, "expected an object");
    const cJSON *type = cJSON_GetObjectItemCaseSensitive(l, "type");
    if (!cJSON_IsString(type)) return shape_error(c, err, where, "\"type\" must be \"quad\" or \"point\"");
    lm_result r;
    if (strcmp(type->valuestring, "point") == 0) {
        static const char *const known[] = {"type", "position", "intensity", NULL};
        note_unknown_keys(c, l, where, known);
        scene_builder_point_light p;
        if ((r = get_point(c, l, "position", where, 1, p.position, err)) != LM_OK) return r;
        if ((r = get_vec3(c, l, "intensity", where, 1, 1, p.intensity, err)) != LM_OK) return r;
        return scene_builder_add_point_light(c->b, &p, err);
    }
    if (strcmp(type->valuestring, "quad") != 0)
        return shape_error(c, err, where, "\"type\" must be \"quad\" or \"point\"");
    static const char *const known[] = {"type", "corner", "edge1", "edge2", "radiance", "kd", NULL};
    note_unknown_keys(c, l, where, known);
    double corner[3], e1[3], e2[3];
    scene_material m = scene_material_default(where);
    m.kd[0] = m.kd[1] = m.kd[2] = 0.0f; /* a black emitter unless "kd" says otherwise */
    if ((r = get_point(c, l, "corner", where, 1, corner, err)) != LM_OK) return r;
    if ((r = get_point(c, l, "edge1", where, 1, e1, err)) != LM_OK) return r;
    if ((r = get_point(c, l, "edge2", where, 1, e2, err)) != LM_OK) return r;
    if ((r = get_vec3(c, l, "radiance", where, 1, 1, m.le, err)) != LM_OK) return r;
    if ((r = get_vec3(c, l, "kd", where, 0, 1, m.kd, err)) != LM_OK) return r;
    lm_dvec3 cr = dv3_cross(dv3_load_d(e1), dv3_load_d(e2));
    if (!(dv3_length(cr) > 0.0) || !isfinite(dv3_length(cr)))
        return shape_error(c, err, where, "edge1 and edge2 are parallel or zero: the quad has no area");
    uint32_t mi, part;
    if ((r = scene_builder_add_material(c->b, &m, &mi, err)) != LM_OK) return r;
    if ((r = scene_builder_add_part(c->b, where, c->path, &part, err)) != LM_OK) return r;
    /* Emits towards edge1 x edge2: corners c, c+e1, c+e1+e2, c+e2 counter-clockwise. */
    double q[4][3];
    for (int k = 0; k < 3; ++k) {
        q[0][k] = corner[k];
        q[1][k] = corner[k] + e1[k];
        q[2][k] = corner[k] + e1[k] + e2[k];
        q[3][k] = corner[k] + e2[k];
    }
    double t0[9], t1[9];
    memcpy(t0, q[0], sizeof q[0]);
    memcpy(t0 + 3, q[1], sizeof q[0]);
    memcpy(t0 + 6, q[2], sizeof q[0]);
    memcpy(t1, q[0], sizeof q[0]);
    memcpy(t1 + 3, q[2], sizeof q[0]);
    memcpy(t1 + 6, q[3], sizeof q[0]);
    if ((r = scene_builder_add_triangle(c->b, t0, NULL, mi, part, err)) != LM_OK) return r;
    return scene_builder_add_triangle(c->b, t1, NULL, mi, part, err);
}

/* ---- cameras ------------------------------------------------------------- */

static lm_result get_positive_int(const json_ctx *c, const cJSON *obj, const char *key,
                                  const char *where, int *out, lm_error *err)
{
    const cJSON *v = cJSON_GetObjectItemCaseSensitive(obj, key);
    if (!v) return LM_OK;
    if (!cJSON_IsNumber(v) || v->valuedouble < 1 || v->valuedouble > 32768 ||
        v->valuedouble != floor(v->valuedouble)) {
        char at[96];
        snprintf(at, sizeof at, "%s.%s", where, key);
        return shape_error(c, err, at, "expected a whole number of pixels from 1 to 32768");
    }
    *out = (int)v->valuedouble;
    return LM_OK;
}

static lm_result load_camera(json_ctx *c, const cJSON *j, int index, lm_error *err)
{
    char where[64];
    snprintf(where, sizeof where, "cameras[%d]", index);
    if (!cJSON_IsObject(j)) return shape_error(c, err, where, "expected an object");
    static const char *const known[] = {"name", "position", "target", "up", "fov_y", "width", "height", NULL};
    note_unknown_keys(c, j, where, known);
    scene_builder_camera bc;
    memset(&bc, 0, sizeof bc);
    scene_camera cam = bc.cam;
    snprintf(cam.name, sizeof cam.name, "camera%d", index);
    cam.up[1] = 1.0f;
    const cJSON *name = cJSON_GetObjectItemCaseSensitive(j, "name");
    if (name) {
        if (!cJSON_IsString(name) || !name->valuestring[0])
            return shape_error(c, err, where, "\"name\" must be a non-empty string");
        lm_strlcpy(cam.name, name->valuestring, sizeof cam.name);
    }
    lm_result r;
    if ((r = get_point(c, j, "position", where, 1, bc.position, err)) != LM_OK) return r;
    if ((r = get_point(c, j, "target", where, 1, bc.target, err)) != LM_OK) return r;
    if ((r = get_vec3(c, j, "up", where, 0, 0, cam.up, err)) != LM_OK) return r;
    const cJSON *fov = cJSON_GetObjectItemCaseSensitive(j, "fov_y");
    if (fov) {
        if (!cJSON_IsNumber(fov) || !(fov->valuedouble > 0.0 && fov->valuedouble < 180.0))
            return shape_error(c, err, where, "\"fov_y\" must be a number of degrees in (0, 180)");
        cam.fov_y_deg = (float)fov->valuedouble;
    }
    if ((r = get_positive_int(c, j, "width", where, &cam.width, err)) != LM_OK) return r;
    if ((r = get_positive_int(c, j, "height", where, &cam.height, err)) != LM_OK) return r;
    lm_dvec3 dir = dv3_sub(dv3_load_d(bc.target), dv3_load_d(bc.position));
    if (!(dv3_length(dir) > 0.0)) return shape_error(c, err, where, "position and target are the same point");
    lm_dvec3 up = dv3_load(cam.up);
    if (!(dv3_length(dv3_cross(dv3_normalize(dir), dv3_normalize(up))) > 1e-4))
        return shape_error(c, err, where, "\"up\" is zero or parallel to the view direction");
    for (uint32_t i = 0; i < c->b->cam_count; ++i)
        if (strcmp(c->b->cams[i].cam.name, cam.name) == 0)
            return shape_error(c, err, where, "two cameras have the same name");
    bc.cam = cam;
    return scene_builder_add_camera(c->b, &bc, err);
}

/* ---- top level ----------------------------------------------------------- */

static lm_result parse_error(const char *path, const char *text, size_t size, lm_error *err)
{
    const char *at = cJSON_GetErrorPtr();
    if (!at || at < text || at > text + size)
        return lm_fail(err, LM_ERR_BAD_INPUT, "%s: not valid JSON", path);
    int line = 1, col = 1;
    for (const char *p = text; p < at; ++p) {
        if (*p == '\n') {
            line++;
            col = 1;
        } else {
            col++;
        }
    }
    return lm_fail(err, LM_ERR_BAD_INPUT, "%s:%d:%d: not valid JSON near here", path, line, col);
}

static lm_result import_root(json_ctx *c, const cJSON *root, lm_error *err)
{
    if (!cJSON_IsObject(root))
        return lm_fail(err, LM_ERR_BAD_INPUT, "%s: the top level must be a JSON object", c->path);
    static const char *const known[] = {"meshes", "materials", "lights", "cameras", "tonemap", NULL};
    note_unknown_keys(c, root, "top level", known);

    const cJSON *materials = cJSON_GetObjectItemCaseSensitive(root, "materials");
    if (materials && !cJSON_IsObject(materials))
        return shape_error(c, err, "materials", "expected an object of named materials");
    c->materials = materials;
    lm_result r = validate_materials(c, err);
    if (r != LM_OK) return r;

    const cJSON *meshes = cJSON_GetObjectItemCaseSensitive(root, "meshes");
    const cJSON *lights = cJSON_GetObjectItemCaseSensitive(root, "lights");
    if (meshes && !cJSON_IsArray(meshes)) return shape_error(c, err, "meshes", "expected an array");
    if (lights && !cJSON_IsArray(lights)) return shape_error(c, err, "lights", "expected an array");
    if (cJSON_GetArraySize(meshes) == 0 && cJSON_GetArraySize(lights) == 0)
        return lm_fail(err, LM_ERR_BAD_INPUT, "%s: no \"meshes\" and no \"lights\": nothing to render",
                       c->path);

    uint32_t first_material = c->b->mat_count;
    int i = 0;
    for (const cJSON *m = meshes ? meshes->child : NULL; m; m = m->next, ++i)
        if ((r = load_mesh(c, m, i, err)) != LM_OK) return r;
    if ((r = override_file_materials(c, first_material, err)) != LM_OK) return r;
    i = 0;
    for (const cJSON *l = lights ? lights->child : NULL; l; l = l->next, ++i)
        if ((r = load_light(c, l, i, err)) != LM_OK) return r;

    const cJSON *cameras = cJSON_GetObjectItemCaseSensitive(root, "cameras");
    if (cameras && !cJSON_IsArray(cameras)) return shape_error(c, err, "cameras", "expected an array");
    i = 0;
    for (const cJSON *cam = cameras ? cameras->child : NULL; cam; cam = cam->next, ++i)
        if ((r = load_camera(c, cam, i, err)) != LM_OK) return r;

    const cJSON *tonemap = cJSON_GetObjectItemCaseSensitive(root, "tonemap");
    if (tonemap) {
        if (!cJSON_IsObject(tonemap)) return shape_error(c, err, "tonemap", "expected an object");
        static const char *const tknown[] = {"exposure", NULL};
        note_unknown_keys(c, tonemap, "tonemap", tknown);
        const cJSON *e = cJSON_GetObjectItemCaseSensitive(tonemap, "exposure");
        if (e) {
            if (!cJSON_IsNumber(e) || !isfinite(e->valuedouble) || fabs(e->valuedouble) > 64.0)
                return shape_error(c, err, "tonemap.exposure", "expected a number of stops in [-64, 64]");
            c->b->exposure = (float)e->valuedouble;
        }
    }
    return LM_OK;
}

lm_result scene_import_json(scene_builder *b, const char *path, lm_error *err)
{
    char *text = NULL;
    size_t size = 0;
    lm_result r = vfs_read(path, MAX_JSON_BYTES, &text, &size, err);
    if (r != LM_OK) return r;
    if (size == 0) {
        free(text);
        return lm_fail(err, LM_ERR_BAD_INPUT, "%s: the file is empty", path);
    }
    if (memchr(text, '\0', size)) {
        free(text);
        return lm_fail(err, LM_ERR_BAD_INPUT, "%s: not a JSON text file (it contains binary data)", path);
    }
    cJSON *root = cJSON_ParseWithLength(text, size);
    if (!root) {
        r = parse_error(path, text, size, err);
        free(text);
        return r;
    }
    json_ctx c;
    memset(&c, 0, sizeof c);
    c.b = b;
    c.path = path;
    lm_path_dir(path, c.dir, sizeof c.dir);
    r = import_root(&c, root, err);
    cJSON_Delete(root);
    free(text);
    return r;
}
