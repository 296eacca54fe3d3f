/* scene.c — scene_load entry point, the builder's storage, and scene_destroy. */
#include "src/scene/scene.h"

#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "src/base/vfs.h"
#include "src/scene/scene_internal.h"

/* Grows the array *ptr_to_ptr (any T **; elements of size elem, capacity in a
 * uint32_t) so that index `need-1` fits: lm_grow_capacity with the uint32_t limit. */
static int grow(void *ptr_to_ptr, uint32_t *cap, size_t need, size_t elem)
{
    size_t c = lm_grow_capacity(*cap, need, 16, UINT32_MAX);
    if (!c || !lm_realloc_array(ptr_to_ptr, *cap, c, elem)) return 0;
    *cap = (uint32_t)c;
    return 1;
}

void scene_builder_free(scene_builder *b)
{
    free(b->pos);
    free(b->nrm);
    free(b->mat);
    free(b->part);
    free(b->mats);
    free(b->parts);
    free(b->points);
    free(b->cams);
    for (uint32_t i = 0; i < b->note_count; ++i) free(b->notes[i]);
    free(b->notes);
    memset(b, 0, sizeof *b);
}

lm_result scene_builder_add_triangle(scene_builder *b, const double p[9], const float *n,
                                     uint32_t material, uint32_t part, lm_error *err)
{
    if (b->count == b->cap) { /* four arrays, one capacity */
        size_t ncap = lm_grow_capacity(b->cap, b->count + 1, 1024, UINT32_MAX);
        if (!ncap) return lm_fail(err, LM_ERR_BAD_INPUT, "%s: more than 4 billion triangles", b->source);
        if (!lm_realloc_array(&b->pos, b->cap, ncap, 9 * sizeof(double)) ||
            !lm_realloc_array(&b->nrm, b->cap, ncap, 9 * sizeof(float)) ||
            !lm_realloc_array(&b->mat, b->cap, ncap, sizeof(uint32_t)) ||
            !lm_realloc_array(&b->part, b->cap, ncap, sizeof(uint32_t)))
            return lm_fail(err, LM_ERR_NO_MEMORY, "%s: out of memory at %zu triangles", b->source,
                           b->count);
        b->cap = ncap;
    }
    memcpy(b->pos + 9 * b->count, p, 9 * sizeof(double));
    if (n)
        memcpy(b->nrm + 9 * b->count, n, 9 * sizeof(float));
    else
        memset(b->nrm + 9 * b->count, 0, 9 * sizeof(float));
    b->mat[b->count] = material;
    b->part[b->count] = part;
    b->count++;
    return LM_OK;
}

lm_result scene_builder_add_material(scene_builder *b, const scene_material *m, uint32_t *out_index,
                                     lm_error *err)
{
    if (!grow(&b->mats, &b->mat_cap, (size_t)b->mat_count + 1, sizeof *b->mats))
        return lm_fail(err, LM_ERR_NO_MEMORY, "%s: out of memory (materials)", b->source);
    b->mats[b->mat_count] = *m;
    *out_index = b->mat_count++;
    return LM_OK;
}

lm_result scene_builder_add_part(scene_builder *b, const char *name, const char *source,
                                 uint32_t *out_index, lm_error *err)
{
    if (!grow(&b->parts, &b->part_cap, (size_t)b->part_count + 1, sizeof *b->parts))
        return lm_fail(err, LM_ERR_NO_MEMORY, "%s: out of memory (parts)", b->source);
    scene_part *p = &b->parts[b->part_count];
    lm_strlcpy(p->name, name, sizeof p->name);
    lm_strlcpy(p->source, source, sizeof p->source);
    *out_index = b->part_count++;
    return LM_OK;
}

lm_result scene_builder_add_point_light(scene_builder *b, const scene_builder_point_light *p, lm_error *err)
{
    if (!grow(&b->points, &b->point_cap, (size_t)b->point_count + 1, sizeof *b->points))
        return lm_fail(err, LM_ERR_NO_MEMORY, "%s: out of memory (lights)", b->source);
    b->points[b->point_count++] = *p;
    return LM_OK;
}

lm_result scene_builder_add_camera(scene_builder *b, const scene_builder_camera *c, lm_error *err)
{
    if (!grow(&b->cams, &b->cam_cap, (size_t)b->cam_count + 1, sizeof *b->cams))
        return lm_fail(err, LM_ERR_NO_MEMORY, "%s: out of memory (cameras)", b->source);
    b->cams[b->cam_count++] = *c;
    return LM_OK;
}

void scene_builder_note(scene_builder *b, const char *fmt, ...)
{
    char line[512];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(line, sizeof line, fmt, ap);
    va_end(ap);
    for (uint32_t i = 0; i < b->note_count; ++i)
        if (strcmp(b->notes[i], line) == 0) return;
    if (!grow(&b->notes, &b->note_cap, (size_t)b->note_count + 1, sizeof *b->notes)) return;
    char *copy = malloc(strlen(line) + 1);
    if (!copy) return; /* a lost note is not worth failing a load for */
    strcpy(copy, line);
    b->notes[b->note_count++] = copy;
}

scene_material scene_material_default(const char *name)
{
    scene_material m;
    memset(&m, 0, sizeof m);
    lm_strlcpy(m.name, name, sizeof m.name);
    m.kd[0] = m.kd[1] = m.kd[2] = 0.7f;
    m.n = 1.0f;
    return m;
}

lm_result scene_load(const scene_load_desc *desc, scene **out, lm_error *err)
{
    static const scene_load_desc zero_desc;
    if (!out) return lm_fail(err, LM_ERR_INVALID_ARG, "scene_load: out is NULL");
    *out = NULL;
    if (!desc) desc = &zero_desc;
    const char *path = desc->path && desc->path[0] ? desc->path : VFS_DEFAULT_SCENE;
    double t0 = lm_now_seconds();

    scene_builder b;
    memset(&b, 0, sizeof b);
    b.source = path;

    char ext[16];
    lm_path_ext(path, ext, sizeof ext);
    lm_result r = strcmp(ext, "json") == 0  ? scene_import_json(&b, path, err)
                  : strcmp(ext, "xml") == 0 ? scene_import_mitsuba(&b, path, err)
                                            : scene_import_mesh_file(&b, path, NULL, -1, err);
    if (r == LM_OK) r = scene_build(&b, desc, out, err);
    scene_builder_free(&b);
    if (r == LM_OK) (*out)->report.load_seconds = lm_now_seconds() - t0;
    return r;
}

void scene_destroy(scene *s)
{
    if (!s) return;
    free(s->positions);
    free(s->tris);
    free(s->corner_normals);
    free(s->tri_normals);
    free(s->tri_areas);
    free(s->materials);
    free(s->area_lights);
    free(s->light_tris);
    free(s->point_lights);
    free(s->cameras);
    free(s->parts);
    mesh_geo_destroy(s->topology);
    for (uint32_t i = 0; i < s->report.note_count; ++i) free(s->report.notes[i]);
    free(s->report.notes);
    free(s);
}

void scene_mat4_mul(const double *a, const double *b, double *out)
{
    double r[16];
    for (int i = 0; i < 4; ++i)
        for (int j = 0; j < 4; ++j) {
            double sum = 0.0;
            for (int k = 0; k < 4; ++k) sum += a[4 * i + k] * b[4 * k + j];
            r[4 * i + j] = sum;
        }
    memcpy(out, r, sizeof r);
}

void scene_mat4_point(const double *m, const double p[3], double out[3])
{
    double r[3];
    for (int i = 0; i < 3; ++i) r[i] = m[4 * i] * p[0] + m[4 * i + 1] * p[1] + m[4 * i + 2] * p[2] + m[4 * i + 3];
    memcpy(out, r, sizeof r);
}

double scene_mat4_normal_matrix(const double *m, double c[9])
{
#define M(i, j) m[4 * (i) + (j)]
    c[0] = M(1, 1) * M(2, 2) - M(1, 2) * M(2, 1);
    c[1] = M(1, 2) * M(2, 0) - M(1, 0) * M(2, 2);
    c[2] = M(1, 0) * M(2, 1) - M(1, 1) * M(2, 0);
    c[3] = M(0, 2) * M(2, 1) - M(0, 1) * M(2, 2);
    c[4] = M(0, 0) * M(2, 2) - M(0, 2) * M(2, 0);
    c[5] = M(0, 1) * M(2, 0) - M(0, 0) * M(2, 1);
    c[6] = M(0, 1) * M(1, 2) - M(0, 2) * M(1, 1);
    c[7] = M(0, 2) * M(1, 0) - M(0, 0) * M(1, 2);
    c[8] = M(0, 0) * M(1, 1) - M(0, 1) * M(1, 0);
#undef M
    return m[0] * c[0] + m[1] * c[1] + m[2] * c[2];
}

void scene_to_file(const scene *s, const float local[3], double out[3])
{
    for (int k = 0; k < 3; ++k) out[k] = s->origin[k] + (double)local[k];
}

int scene_find_camera(const scene *s, const char *name)
{
    if (!name || !name[0]) return s->camera_count > 0 ? 0 : -1;
    for (uint32_t i = 0; i < s->camera_count; ++i)
        if (strcmp(s->cameras[i].name, name) == 0) return (int)i;
    return -1;
}

uint32_t scene_light_count(const scene *s)
{
    return s->area_light_count + s->point_light_count;
}
