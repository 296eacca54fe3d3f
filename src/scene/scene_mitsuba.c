/* scene_mitsuba.c — Mitsuba XML scenes (0.4–0.6; Mitsuba 2/3 spellings too)
 * into the builder: shapes with their transforms and BSDFs, area and point
 * emitters, perspective sensors. The research scenes (Bitterli's collection,
 * the Veach door in ../shared/scenes/veach-door) come in this format.
 *
 * What is read (docs/scene-format.md, "Mitsuba XML", says it for users):
 *   shapes     obj, ply (through the Assimp importer, in its child process),
 *              rectangle, cube, sphere, disk (tessellated here), shapegroup and
 *              instance; flipNormals, faceNormals;
 *   transforms translate, scale, rotate, matrix, lookat, applied in file order;
 *   emitters   area (on a shape: emits from the side of the shape's normals,
 *              as Mitsuba does; the builder re-winds triangles to the file's
 *              normals), point;
 *   sensors    perspective (thinlens without depth of field), its film's size;
 *   BSDFs      scene_mitsuba_bsdf.c.
 * What is not (integrators, samplers, media, other emitters, include,
 * serialized meshes) is a note, never silence.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "src/base/vecmath.h"
#include "src/scene/scene_mitsuba_internal.h"

enum {
    SPHERE_LEVEL = 3,          /* icosphere subdivisions: 1,280 triangles */
    SPHERE_LIGHT_LEVEL = 1,    /* 80: every flat facet of an emitter is one area light */
    DISK_SEGMENTS = 64,
    INSTANCE_DEPTH_MAX = 8,
    FILM_MAX = 32768
};

static const double IDENTITY[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};

/* ---- transforms ------------------------------------------------------------ */

/* Three numbers from x/y/z attributes (missing ones def) or from value="x y z"
 * (one number: all three when `uniform`, else x). */
static lm_result get_xyz(const mts_ctx *c, const mts_node *n, double def, int uniform, double out[3],
                         lm_error *err)
{
    out[0] = out[1] = out[2] = def;
    const char *v = mts_value(c, n, "value");
    if (v) {
        double d[3];
        int k = mts_parse_numbers(v, d, 3);
        if (k == 3) {
            memcpy(out, d, sizeof d);
        } else if (k == 1 && uniform) {
            out[0] = out[1] = out[2] = d[0];
        } else {
            return mts_error(c, n, err, "value must be three numbers%s", uniform ? " or one" : "");
        }
        return LM_OK;
    }
    static const char *const axes[3] = {"x", "y", "z"};
    for (int k = 0; k < 3; ++k) {
        const char *a = mts_value(c, n, axes[k]);
        if (a && mts_parse_numbers(a, &out[k], 1) != 1)
            return mts_error(c, n, err, "%s must be a number", axes[k]);
    }
    return LM_OK;
}

/* A point given as three numbers in one attribute ("x, y, z" or "x y z"). */
static lm_result get_triple(const mts_ctx *c, const mts_node *n, const char *attr, double out[3], lm_error *err)
{
    const char *v = mts_value(c, n, attr);
    if (!v || mts_parse_numbers(v, out, 3) != 3) return mts_error(c, n, err, "%s must be three numbers", attr);
    return LM_OK;
}

static lm_result lookat_matrix(const mts_ctx *c, const mts_node *n, double m[16], lm_error *err)
{
    double o[3], t[3], u[3] = {0, 1, 0};
    lm_result r;
    if ((r = get_triple(c, n, "origin", o, err)) != LM_OK) return r;
    if ((r = get_triple(c, n, "target", t, err)) != LM_OK) return r;
    if (mts_attr(n, "up") && (r = get_triple(c, n, "up", u, err)) != LM_OK) return r;
    lm_dvec3 dir = dv3_normalize(dv3_sub(dv3_load_d(t), dv3_load_d(o)));
    lm_dvec3 left = dv3_cross(dv3_load_d(u), dir);
    if (!(dv3_length(dir) > 0.0) || !(dv3_length(left) > 1e-9 * dv3_length(dv3_load_d(u))))
        return mts_error(c, n, err, "origin equals target, or up is parallel to the view direction");
    left = dv3_normalize(left);
    lm_dvec3 up = dv3_cross(dir, left);
    /* Mitsuba's camera frame: columns left, up, direction, origin. */
    double cols[4][3] = {{left.x, left.y, left.z}, {up.x, up.y, up.z}, {dir.x, dir.y, dir.z}, {o[0], o[1], o[2]}};
    memcpy(m, IDENTITY, sizeof IDENTITY);
    for (int col = 0; col < 4; ++col)
        for (int row = 0; row < 3; ++row) m[4 * row + col] = cols[col][row];
    return LM_OK;
}

/* One operation of a <transform> as a matrix (row-major, p' = M·p). */
static lm_result transform_op(const mts_ctx *c, const mts_node *op, double m[16], lm_error *err)
{
    memcpy(m, IDENTITY, sizeof IDENTITY);
    double v[3];
    lm_result r;
    if (strcmp(op->tag, "translate") == 0) {
        if ((r = get_xyz(c, op, 0.0, 0, v, err)) != LM_OK) return r;
        m[3] = v[0];
        m[7] = v[1];
        m[11] = v[2];
        return LM_OK;
    }
    if (strcmp(op->tag, "scale") == 0) {
        if ((r = get_xyz(c, op, 1.0, 1, v, err)) != LM_OK) return r;
        m[0] = v[0];
        m[5] = v[1];
        m[10] = v[2];
        return LM_OK;
    }
    if (strcmp(op->tag, "rotate") == 0) { /* about an axis through the origin (Rodrigues) */
        double angle;
        const char *a = mts_value(c, op, "angle");
        if (!a || mts_parse_numbers(a, &angle, 1) != 1) return mts_error(c, op, err, "rotate needs angle=\"degrees\"");
        if (mts_attr(op, "axis")) {
            if ((r = get_triple(c, op, "axis", v, err)) != LM_OK) return r;
        } else if ((r = get_xyz(c, op, 0.0, 0, v, err)) != LM_OK) {
            return r;
        }
        lm_dvec3 k = dv3_normalize(dv3_load_d(v));
        if (!(dv3_length(k) > 0.0)) return mts_error(c, op, err, "rotate needs a non-zero axis");
        double th = angle * M_PI / 180.0, cs = cos(th), sn = sin(th), t = 1.0 - cs;
        double R[9] = {t * k.x * k.x + cs,       t * k.x * k.y - sn * k.z, t * k.x * k.z + sn * k.y,
                       t * k.x * k.y + sn * k.z, t * k.y * k.y + cs,       t * k.y * k.z - sn * k.x,
                       t * k.x * k.z - sn * k.y, t * k.y * k.z + sn * k.x, t * k.z * k.z + cs};
        for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j) m[4 * i + j] = R[3 * i + j];
        return LM_OK;
    }
    if (strcmp(op->tag, "matrix") == 0) {
        double d[16];
        const char *s = mts_value(c, op, "value");
        int k = s ? mts_parse_numbers(s, d, 16) : -1;
        if (k == 16) {
            memcpy(m, d, sizeof d);
        } else if (k == 9) {
            for (int i = 0; i < 3; ++i)
                for (int j = 0; j < 3; ++j) m[4 * i + j] = d[3 * i + j];
        } else {
            return mts_error(c, op, err, "matrix needs value= with 16 numbers (row-major 4x4) or 9");
        }
        if (m[12] != 0.0 || m[13] != 0.0 || m[14] != 0.0 || m[15] != 1.0)
            return mts_error(c, op, err, "a projective matrix (last row not 0 0 0 1) is not supported");
        return LM_OK;
    }
    if (strcmp(op->tag, "lookat") == 0 || strcmp(op->tag, "lookAt") == 0) return lookat_matrix(c, op, m, err);
    return mts_error(c, op, err, "unknown transform operation");
}

/* The node's transform property `name` (toWorld), identity when absent.
 * Mitsuba applies the operations in file order: each one left-multiplies. */
static lm_result get_transform(const mts_ctx *c, const mts_node *n, const char *name, double m[16], lm_error *err)
{
    memcpy(m, IDENTITY, sizeof IDENTITY);
    const mts_node *t = mts_prop(c, n, name);
    if (!t) return LM_OK;
    if (strcmp(t->tag, "transform") != 0) return mts_error(c, t, err, "'%s' must be a <transform>", name);
    for (const mts_node *op = t->child; op; op = op->next) {
        double o[16];
        lm_result r = transform_op(c, op, o, err);
        if (r != LM_OK) return r;
        scene_mat4_mul(o, m, m);
    }
    for (int i = 0; i < 16; ++i)
        if (!isfinite(m[i])) return mts_error(c, t, err, "the transform is not finite");
    return LM_OK;
}

/* ---- shapes ---------------------------------------------------------------- */

typedef struct shape_out {
    const double *m;           /* toWorld */
    uint32_t material, part;
    int flip;                  /* flipNormals */
} shape_out;

/* One triangle of a primitive in its local frame, with its local normals. */
static lm_result emit_local(mts_ctx *c, const shape_out *s, const double p[9], const double n[9], lm_error *err)
{
    double cof[9], q[9];
    double det = scene_mat4_normal_matrix(s->m, cof);
    int swap = (det < 0.0) != (s->flip != 0);
    double sign = (det < 0.0 ? -1.0 : 1.0) * (s->flip ? -1.0 : 1.0);
    float fn[9];
    for (int k = 0; k < 3; ++k) {
        int src = swap && k ? 3 - k : k;
        scene_mat4_point(s->m, p + 3 * src, q + 3 * k);
        lm_dvec3 v = dv3_load_d(n + 3 * src);
        lm_dvec3 w = dv3_normalize(dv3(cof[0] * v.x + cof[1] * v.y + cof[2] * v.z,
                                       cof[3] * v.x + cof[4] * v.y + cof[5] * v.z,
                                       cof[6] * v.x + cof[7] * v.y + cof[8] * v.z));
        fn[3 * k] = (float)(sign * w.x);
        fn[3 * k + 1] = (float)(sign * w.y);
        fn[3 * k + 2] = (float)(sign * w.z);
    }
    return scene_builder_add_triangle(c->b, q, fn, s->material, s->part, err);
}

/* A planar quad a, b, cc, d (counter-clockwise seen from normal nz). */
static lm_result emit_quad(mts_ctx *c, const shape_out *s, const double a[3], const double b[3], const double cc[3],
                           const double d[3], const double nrm[3], lm_error *err)
{
    double t0[9], t1[9], n[9];
    for (int k = 0; k < 3; ++k) {
        t0[k] = a[k], t0[3 + k] = b[k], t0[6 + k] = cc[k];
        t1[k] = a[k], t1[3 + k] = cc[k], t1[6 + k] = d[k];
        n[k] = n[3 + k] = n[6 + k] = nrm[k];
    }
    lm_result r = emit_local(c, s, t0, n, err);
    return r != LM_OK ? r : emit_local(c, s, t1, n, err);
}

static lm_result emit_cube(mts_ctx *c, const shape_out *s, lm_error *err)
{
    for (int axis = 0; axis < 3; ++axis)
        for (int side = -1; side <= 1; side += 2) {
            int u = (axis + 1) % 3, v = (axis + 2) % 3; /* u × v = axis */
            double q[4][3], n[3] = {0, 0, 0};
            static const double uv[4][2] = {{-1, -1}, {1, -1}, {1, 1}, {-1, 1}};
            n[axis] = side;
            for (int i = 0; i < 4; ++i) {
                q[i][axis] = side;
                q[i][u] = uv[i][0];
                q[i][v] = uv[i][1] * side; /* mirrored on the negative side: still outward */
            }
            lm_result r = emit_quad(c, s, q[0], q[1], q[2], q[3], n, err);
            if (r != LM_OK) return r;
        }
    return LM_OK;
}

static lm_result emit_disk(mts_ctx *c, const shape_out *s, lm_error *err)
{
    for (int i = 0; i < DISK_SEGMENTS; ++i) {
        double a0 = 2.0 * M_PI * i / DISK_SEGMENTS, a1 = 2.0 * M_PI * (i + 1) / DISK_SEGMENTS;
        double p[9] = {0, 0, 0, cos(a0), sin(a0), 0, cos(a1), sin(a1), 0};
        double n[9] = {0, 0, 1, 0, 0, 1, 0, 0, 1};
        lm_result r = emit_local(c, s, p, n, err);
        if (r != LM_OK) return r;
    }
    return LM_OK;
}

static lm_result sphere_face(mts_ctx *c, const shape_out *s, lm_dvec3 a, lm_dvec3 b, lm_dvec3 d, int level,
                             lm_error *err)
{
    if (level == 0) {
        double p[9] = {a.x, a.y, a.z, b.x, b.y, b.z, d.x, d.y, d.z}; /* unit sphere: normal = position */
        return emit_local(c, s, p, p, err);
    }
    lm_dvec3 ab = dv3_normalize(dv3_add(a, b)), bd = dv3_normalize(dv3_add(b, d)), da = dv3_normalize(dv3_add(d, a));
    lm_result r;
    if ((r = sphere_face(c, s, a, ab, da, level - 1, err)) != LM_OK) return r;
    if ((r = sphere_face(c, s, ab, b, bd, level - 1, err)) != LM_OK) return r;
    if ((r = sphere_face(c, s, da, bd, d, level - 1, err)) != LM_OK) return r;
    return sphere_face(c, s, ab, bd, da, level - 1, err);
}

static lm_result emit_sphere(mts_ctx *c, const shape_out *s, int level, lm_error *err)
{
    const double g = (1.0 + sqrt(5.0)) / 2.0; /* the icosahedron's 12 corners */
    double v[12][3] = {{-1, g, 0}, {1, g, 0}, {-1, -g, 0}, {1, -g, 0}, {0, -1, g}, {0, 1, g},
                       {0, -1, -g}, {0, 1, -g}, {g, 0, -1}, {g, 0, 1}, {-g, 0, -1}, {-g, 0, 1}};
    static const int f[20][3] = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11},
                                 {1, 5, 9},  {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
                                 {3, 9, 4},  {3, 4, 2},  {3, 2, 6},   {3, 6, 8},  {3, 8, 9},
                                 {4, 9, 5},  {2, 4, 11}, {6, 2, 10},  {8, 6, 7},  {9, 8, 1}};
    for (int i = 0; i < 20; ++i) {
        lm_result r = sphere_face(c, s, dv3_normalize(dv3_load_d(v[f[i][0]])), dv3_normalize(dv3_load_d(v[f[i][1]])),
                                  dv3_normalize(dv3_load_d(v[f[i][2]])), level, err);
        if (r != LM_OK) return r;
    }
    return LM_OK;
}

/* The shape's name for parts and light materials: its id, the file's stem, or type@line. */
static void shape_name(const mts_ctx *c, const mts_node *shape, char *out, size_t size)
{
    const char *id = mts_attr(shape, "id");
    const char *file = mts_get_string(c, shape, "filename", NULL);
    if (id) {
        lm_strlcpy(out, id, size);
    } else if (file) {
        const char *base = strrchr(file, '/');
        lm_strlcpy(out, base ? base + 1 : file, size);
        char *dot = strrchr(out, '.');
        if (dot && dot != out) *dot = '\0';
    } else {
        snprintf(out, size, "%s@%d", mts_value(c, shape, "type"), shape->line);
    }
}

/* The shape's BSDF element (inline or by reference), or NULL. */
static const mts_node *shape_bsdf(const mts_ctx *c, const mts_node *shape)
{
    for (const mts_node *ch = shape->child; ch; ch = ch->next) {
        const mts_node *t = mts_deref(c, ch);
        if (t && strcmp(t->tag, "bsdf") == 0) return t;
    }
    return NULL;
}

/* Builder material of a shape: its BSDF's, or a copy with the area emitter's radiance. */
static lm_result shape_material(mts_ctx *c, const mts_node *shape, const char *name, uint32_t *out, int *skip,
                                lm_error *err)
{
    *skip = 0;
    const mts_node *bsdf = shape_bsdf(c, shape);
    for (const mts_node *ch = shape->child; ch; ch = ch->next)
        if (strcmp(ch->tag, "ref") == 0 && !mts_deref(c, ch))
            return mts_error(c, ch, err, "no element has id '%s'", mts_value(c, ch, "id") ? mts_value(c, ch, "id") : "");
    const mts_node *emitter = NULL;
    for (const mts_node *ch = shape->child; ch; ch = ch->next) {
        const mts_node *t = mts_deref(c, ch);
        if (t && strcmp(t->tag, "emitter") == 0) emitter = t;
    }
    const char *bsdf_type = bsdf ? mts_value(c, bsdf, "type") : NULL;
    if (!emitter && bsdf_type && strcmp(bsdf_type, "null") == 0) {
        scene_builder_note(c->b, "%s:%d: shape '%s' has a null BSDF and emits nothing: not loaded", c->path,
                           shape->line, name);
        *skip = 1;
        return LM_OK;
    }
    lm_result r = bsdf ? mts_material(c, bsdf, out, err) : mts_default_material(c, out, err);
    if (r != LM_OK || !emitter) return r;
    const char *etype = mts_value(c, emitter, "type");
    if (!etype || strcmp(etype, "area") != 0) {
        scene_builder_note(c->b, "%s:%d: emitter type '%s' on a shape is not modelled: the shape does not emit",
                           c->path, emitter->line, etype ? etype : "?");
        return LM_OK;
    }
    scene_material m = c->b->mats[*out];
    static const float unit[3] = {1, 1, 1};
    if ((r = mts_get_color(c, emitter, "radiance", unit, m.le, NULL, err)) != LM_OK) return r;
    double scale;
    if ((r = mts_get_float(c, emitter, "scale", 1.0, &scale, err)) != LM_OK) return r;
    for (int k = 0; k < 3; ++k) m.le[k] *= (float)scale;
    lm_strlcpy(m.name, name, sizeof m.name);
    return scene_builder_add_material(c->b, &m, out, err);
}

/* flipNormals and faceNormals on the triangles an importer just added. */
static void adjust_imported(scene_builder *b, size_t first, int flip, int face_normals)
{
    for (size_t t = first; t < b->count; ++t) {
        float *n = b->nrm + 9 * t;
        if (face_normals) memset(n, 0, 9 * sizeof *n);
        if (!flip) continue;
        double *p = b->pos + 9 * t;
        for (int k = 0; k < 3; ++k) {
            double tmp = p[3 + k];
            p[3 + k] = p[6 + k];
            p[6 + k] = tmp;
            float tn = n[3 + k];
            n[3 + k] = n[6 + k];
            n[6 + k] = tn;
        }
        for (int k = 0; k < 9; ++k) n[k] = -n[k];
    }
}

static lm_result load_shape(mts_ctx *c, const mts_node *shape, const double *parent, int depth, lm_error *err);

static lm_result load_instance(mts_ctx *c, const mts_node *shape, const double *m, int depth, lm_error *err)
{
    const mts_node *group = NULL;
    for (const mts_node *ch = shape->child; ch && !group; ch = ch->next) {
        const mts_node *t = mts_deref(c, ch);
        if (t && strcmp(t->tag, "shape") == 0) group = t;
    }
    const char *gt = group ? mts_value(c, group, "type") : NULL;
    if (!gt || strcmp(gt, "shapegroup") != 0) return mts_error(c, shape, err, "an instance needs a <ref> to a shapegroup");
    if (depth >= INSTANCE_DEPTH_MAX) return mts_error(c, shape, err, "instances nested more than %d deep", INSTANCE_DEPTH_MAX);
    for (const mts_node *ch = group->child; ch; ch = ch->next)
        if (strcmp(ch->tag, "shape") == 0) {
            lm_result r = load_shape(c, ch, m, depth + 1, err);
            if (r != LM_OK) return r;
        }
    return LM_OK;
}

static lm_result load_shape(mts_ctx *c, const mts_node *shape, const double *parent, int depth, lm_error *err)
{
    const char *type = mts_value(c, shape, "type");
    if (!type) return mts_error(c, shape, err, "a shape needs a type");
    if (strcmp(type, "shapegroup") == 0) return LM_OK; /* drawn only through instances */
    double local[16], m[16];
    lm_result r = get_transform(c, shape, "toWorld", local, err);
    if (r != LM_OK) return r;
    scene_mat4_mul(parent, local, m);
    if (strcmp(type, "instance") == 0) return load_instance(c, shape, m, depth, err);
    double cof[9];
    double det = scene_mat4_normal_matrix(m, cof);
    if (det == 0.0 || !isfinite(det)) return mts_error(c, shape, err, "the shape's transform is singular");

    char name[SCENE_NAME_MAX];
    shape_name(c, shape, name, sizeof name);
    shape_out s = {m, 0, 0, mts_get_bool(c, shape, "flipNormals", 0)};
    int skip;
    if ((r = shape_material(c, shape, name, &s.material, &skip, err)) != LM_OK) return r;
    if (skip) return LM_OK;
    int emits = c->b->mats[s.material].le[0] > 0 || c->b->mats[s.material].le[1] > 0 ||
                c->b->mats[s.material].le[2] > 0;

    if (strcmp(type, "obj") == 0 || strcmp(type, "ply") == 0) {
        const char *file = mts_get_string(c, shape, "filename", NULL);
        if (!file || !file[0]) return mts_error(c, shape, err, "shape type '%s' needs a filename", type);
        char full[SCENE_PATH_MAX];
        if (!lm_path_join(c->dir, file, full, sizeof full)) return mts_error(c, shape, err, "file path too long");
        size_t first = c->b->count;
        r = scene_import_mesh_file(c->b, full, m, (int32_t)s.material, err);
        if (r != LM_OK && err) {
            char inner[sizeof err->msg];
            memcpy(inner, err->msg, sizeof inner);
            return mts_error(c, shape, err, "%s", inner);
        }
        if (r != LM_OK) return r;
        adjust_imported(c->b, first, s.flip, mts_get_bool(c, shape, "faceNormals", 0));
        return LM_OK;
    }
    if ((r = scene_builder_add_part(c->b, name, c->path, &s.part, err)) != LM_OK) return r;
    if (strcmp(type, "rectangle") == 0) {
        static const double a[3] = {-1, -1, 0}, b[3] = {1, -1, 0}, cc[3] = {1, 1, 0}, d[3] = {-1, 1, 0},
                            n[3] = {0, 0, 1};
        return emit_quad(c, &s, a, b, cc, d, n, err);
    }
    if (strcmp(type, "cube") == 0) return emit_cube(c, &s, err);
    if (strcmp(type, "disk") == 0) return emit_disk(c, &s, err);
    if (strcmp(type, "sphere") == 0) {
        double centre[3] = {0, 0, 0}, radius, sm[16], total[16];
        const mts_node *cn = mts_prop(c, shape, "center");
        if (cn && (r = get_xyz(c, cn, 0.0, 0, centre, err)) != LM_OK) return r;
        if ((r = mts_get_float(c, shape, "radius", 1.0, &radius, err)) != LM_OK) return r;
        if (!(radius > 0.0)) return mts_error(c, shape, err, "a sphere needs a positive radius");
        memcpy(sm, IDENTITY, sizeof sm);
        sm[0] = sm[5] = sm[10] = radius;
        sm[3] = centre[0], sm[7] = centre[1], sm[11] = centre[2];
        scene_mat4_mul(m, sm, total);
        s.m = total;
        int level = emits ? SPHERE_LIGHT_LEVEL : SPHERE_LEVEL;
        scene_builder_note(c->b, "%s:%d: sphere '%s' tessellated into %d flat triangles%s", c->path, shape->line,
                           name, 20 << (2 * level), emits ? " (each one an area light)" : "");
        return emit_sphere(c, &s, level, err);
    }
    scene_builder_note(c->b, "%s:%d: shape type '%s' is not read (lumesh reads obj, ply, rectangle, cube, sphere, "
                             "disk, shapegroup and instance): skipped",
                       c->path, shape->line, type);
    return LM_OK;
}

/* ---- emitters and sensors ---------------------------------------------------- */

static lm_result load_emitter(mts_ctx *c, const mts_node *e, lm_error *err)
{
    const char *type = mts_value(c, e, "type");
    if (!type || strcmp(type, "point") != 0) {
        scene_builder_note(c->b, "%s:%d: emitter type '%s' is not modelled (lumesh has area and point lights): "
                                 "ignored",
                           c->path, e->line, type ? type : "?");
        return LM_OK;
    }
    double m[16], pos[3] = {0, 0, 0}, scale;
    lm_result r = get_transform(c, e, "toWorld", m, err);
    if (r != LM_OK) return r;
    const mts_node *pn = mts_prop(c, e, "position");
    if (pn && (r = get_xyz(c, pn, 0.0, 0, pos, err)) != LM_OK) return r;
    scene_builder_point_light p;
    scene_mat4_point(m, pos, p.position);
    static const float unit[3] = {1, 1, 1};
    if ((r = mts_get_color(c, e, "intensity", unit, p.intensity, NULL, err)) != LM_OK) return r;
    if ((r = mts_get_float(c, e, "scale", 1.0, &scale, err)) != LM_OK) return r;
    for (int k = 0; k < 3; ++k) p.intensity[k] *= (float)scale;
    return scene_builder_add_point_light(c->b, &p, err);
}

/* Mitsuba's field of view along x from fov/fovAxis or focalLength (35 mm film
 * equivalent, measured along the diagonal). aspect = width / height. */
static lm_result sensor_fov_x(const mts_ctx *c, const mts_node *s, double aspect, double *fov_x, lm_error *err)
{
    double fov;
    const char *axis = mts_get_string(c, s, "fovAxis", "x");
    lm_result r = mts_get_float(c, s, "fov", 0.0, &fov, err);
    if (r != LM_OK) return r;
    if (!mts_prop(c, s, "fov")) {
        const char *f = mts_get_string(c, s, "focalLength", "50mm");
        double mm;
        if (sscanf(f, "%lf", &mm) != 1 || !(mm > 0.0))
            return mts_error(c, s, err, "focalLength must be like \"50mm\"");
        fov = 2.0 * atan(sqrt(36.0 * 36.0 + 24.0 * 24.0) / (2.0 * mm)) * 180.0 / M_PI;
        axis = "diagonal";
    }
    if (!(fov > 0.0 && fov < 180.0)) return mts_error(c, s, err, "fov must be in (0, 180) degrees");
    double t = tan(0.5 * fov * M_PI / 180.0);
    if (strcmp(axis, "smaller") == 0) axis = aspect > 1.0 ? "y" : "x";
    if (strcmp(axis, "larger") == 0) axis = aspect > 1.0 ? "x" : "y";
    if (strcmp(axis, "x") == 0) {
        *fov_x = fov;
    } else if (strcmp(axis, "y") == 0) {
        *fov_x = 2.0 * atan(t * aspect) * 180.0 / M_PI;
    } else if (strcmp(axis, "diagonal") == 0) {
        *fov_x = 2.0 * atan(t / sqrt(1.0 + 1.0 / (aspect * aspect))) * 180.0 / M_PI;
    } else {
        return mts_error(c, s, err, "fovAxis must be x, y, diagonal, smaller or larger");
    }
    return LM_OK;
}

static lm_result film_size(const mts_ctx *c, const mts_node *s, int *w, int *h, lm_error *err)
{
    *w = 768, *h = 576; /* Mitsuba's defaults */
    const mts_node *film = NULL;
    for (const mts_node *ch = s->child; ch; ch = ch->next)
        if (strcmp(ch->tag, "film") == 0) film = ch;
    if (!film) return LM_OK;
    double dw, dh;
    lm_result r;
    if ((r = mts_get_float(c, film, "width", 768, &dw, err)) != LM_OK) return r;
    if ((r = mts_get_float(c, film, "height", 576, &dh, err)) != LM_OK) return r;
    if (!(dw >= 1 && dw <= FILM_MAX && dh >= 1 && dh <= FILM_MAX) || dw != floor(dw) || dh != floor(dh))
        return mts_error(c, film, err, "width and height must be whole numbers from 1 to %d", FILM_MAX);
    *w = (int)dw, *h = (int)dh;
    return LM_OK;
}

static lm_result load_sensor(mts_ctx *c, const mts_node *s, lm_error *err)
{
    const char *type = mts_value(c, s, "type");
    if (!type || (strcmp(type, "perspective") != 0 && strcmp(type, "thinlens") != 0)) {
        scene_builder_note(c->b, "%s:%d: sensor type '%s' is not read (lumesh has perspective cameras): ignored",
                           c->path, s->line, type ? type : "?");
        return LM_OK;
    }
    if (strcmp(type, "thinlens") == 0)
        scene_builder_note(c->b, "%s:%d: thinlens sensor read as a pinhole: no depth of field", c->path, s->line);
    double m[16], fov_x = 0.0;
    scene_builder_camera bc;
    memset(&bc, 0, sizeof bc);
    lm_result r = get_transform(c, s, "toWorld", m, err);
    if (r == LM_OK) r = film_size(c, s, &bc.cam.width, &bc.cam.height, err);
    if (r == LM_OK) r = sensor_fov_x(c, s, (double)bc.cam.width / bc.cam.height, &fov_x, err);
    if (r != LM_OK) return r;
    double aspect = (double)bc.cam.width / bc.cam.height;
    bc.cam.fov_y_deg = (float)(2.0 * atan(tan(0.5 * fov_x * M_PI / 180.0) / aspect) * 180.0 / M_PI);
    /* The camera looks along its local +z with +y up (Mitsuba's frame). */
    static const double origin[3] = {0, 0, 0};
    scene_mat4_point(m, origin, bc.position);
    lm_dvec3 dir = dv3(m[2], m[6], m[10]), up = dv3(m[1], m[5], m[9]);
    if (!(dv3_length(dir) > 0.0) || !(dv3_length(dv3_cross(dv3_normalize(dir), dv3_normalize(up))) > 1e-6))
        return mts_error(c, s, err, "the sensor's transform has no view direction or no up");
    dir = dv3_normalize(dir);
    for (int k = 0; k < 3; ++k) bc.target[k] = bc.position[k] + (&dir.x)[k];
    lm_dvec3 upn = dv3_normalize(up);
    bc.cam.up[0] = (float)upn.x, bc.cam.up[1] = (float)upn.y, bc.cam.up[2] = (float)upn.z;
    double cof[9];
    if (scene_mat4_normal_matrix(m, cof) < 0.0)
        scene_builder_note(c->b, "%s:%d: the sensor's transform mirrors the image; lumesh shows it unmirrored",
                           c->path, s->line);
    const char *id = mts_attr(s, "id");
    if (id)
        lm_strlcpy(bc.cam.name, id, sizeof bc.cam.name);
    else
        snprintf(bc.cam.name, sizeof bc.cam.name, c->b->cam_count ? "sensor%u" : "sensor", c->b->cam_count);
    return scene_builder_add_camera(c->b, &bc, err);
}

/* ---- the file -------------------------------------------------------------- */

static lm_result import_scene(mts_ctx *c, lm_error *err)
{
    const mts_node *root = c->root;
    if (strcmp(root->tag, "scene") != 0)
        return mts_error(c, root, err, "the top element must be <scene> (is this a Mitsuba scene?)");
    for (const mts_node *ch = root->child; ch; ch = ch->next)
        if (strcmp(ch->tag, "default") == 0 && LM_GROW(c->defaults, c->default_cap, c->default_count + 1))
            c->defaults[c->default_count++] = ch;
    lm_result r = LM_OK;
    uint32_t shapes = 0;
    for (const mts_node *ch = root->child; ch && r == LM_OK; ch = ch->next) {
        if (strcmp(ch->tag, "shape") == 0) {
            shapes++;
            r = load_shape(c, ch, IDENTITY, 0, err);
        } else if (strcmp(ch->tag, "emitter") == 0) {
            r = load_emitter(c, ch, err);
        } else if (strcmp(ch->tag, "sensor") == 0) {
            r = load_sensor(c, ch, err);
        } else if (strcmp(ch->tag, "include") == 0 || strcmp(ch->tag, "medium") == 0) {
            scene_builder_note(c->b, "%s:%d: <%s> is not read", c->path, ch->line, ch->tag);
        } else if (strcmp(ch->tag, "bsdf") != 0 && strcmp(ch->tag, "texture") != 0 &&
                   strcmp(ch->tag, "integrator") != 0 && strcmp(ch->tag, "default") != 0 &&
                   strcmp(ch->tag, "sampler") != 0 && strcmp(ch->tag, "film") != 0) {
            scene_builder_note(c->b, "%s:%d: unknown element <%s> ignored", c->path, ch->line, ch->tag);
        }
    }
    if (r == LM_OK && shapes == 0)
        return mts_error(c, root, err, "the scene has no <shape>: nothing to render");
    return r;
}

lm_result scene_import_mitsuba(scene_builder *b, const char *path, lm_error *err)
{
    mts_node *root = NULL;
    lm_result r = mts_parse_file(path, &root, err);
    if (r != LM_OK) return r;
    mts_ctx c;
    memset(&c, 0, sizeof c);
    c.b = b;
    c.path = path;
    c.root = root;
    lm_path_dir(path, c.dir, sizeof c.dir);
    r = import_scene(&c, err);
    free(c.defaults);
    free(c.materials);
    free(c.textures);
    mts_free(root);
    return r;
}
