/* scene_mitsuba_internal.h — Mitsuba XML scenes (versions 0.4–0.6, and the same
 * elements under Mitsuba 2/3 names), private to src/scene/scene_mitsuba*.c and
 * src/scene/scene_xml.c.
 *
 * Three steps, one file each:
 *   scene_xml.c          the file -> a small element tree (expat), with line numbers;
 *   scene_mitsuba.c      the tree -> builder: shapes, transforms, emitters, sensors;
 *   scene_mitsuba_bsdf.c properties (spectra, colours, textures) and BSDFs -> the
 *                        modified Phong material of the scene model, with a note for
 *                        every approximation (listed by `lumesh info`).
 *
 * Names of properties are compared ignoring case and '_', so "toWorld" and
 * "to_world", "intIOR" and "int_ior" are the same (0.x and 2/3 spellings).
 * Units: what the file says (positions in its coordinates, radiance in its units).
 * Does NOT do: Mitsuba's `include`, `serialized` meshes, participating media,
 * textures beyond their mean colour (the scene model has none).
 */
#ifndef LUMESH_SCENE_MITSUBA_INTERNAL_H
#define LUMESH_SCENE_MITSUBA_INTERNAL_H

#include <stdint.h>
#include "src/scene/scene_internal.h"

/* ---- the element tree (scene_xml.c) ------------------------------------- */

typedef struct mts_node {
    char *tag;
    char **attrs;              /* name, value, name, value, ..., NULL */
    int line;                  /* where the element starts in the file */
    struct mts_node *parent, *child, *next;
} mts_node;

/* Parses an XML file into a tree (*out, free with mts_free). Errors name the
 * file, line and column. At most 64 MB, 256 levels deep. */
lm_result mts_parse_file(const char *path, mts_node **out, lm_error *err);
void mts_free(mts_node *root);
/* The value of an attribute, or NULL. */
const char *mts_attr(const mts_node *n, const char *name);

/* ---- loading (scene_mitsuba.c and scene_mitsuba_bsdf.c) ------------------- */

typedef struct mts_ctx {
    scene_builder *b;
    const char *path;                 /* the XML file, for messages */
    char dir[SCENE_PATH_MAX];         /* relative file names are relative to it */
    const mts_node *root;
    const mts_node **defaults;        /* <default name value>: "$name" in attributes */
    size_t default_count, default_cap;
    struct mts_material_memo { const mts_node *bsdf; uint32_t index; } *materials;
    size_t material_count, material_cap; /* one builder material per BSDF element */
    struct mts_texture_memo { char path[SCENE_PATH_MAX]; float mean[3]; } *textures;
    size_t texture_count, texture_cap;   /* each bitmap read once */
} mts_ctx;

/* An attribute with "$name" replaced by its <default>; NULL when absent. */
const char *mts_value(const mts_ctx *c, const mts_node *n, const char *attr);
/* Names equal ignoring case and '_'. */
int mts_name_eq(const char *a, const char *b);
/* The first child of n that is a property named `name` (any tag), or NULL. */
const mts_node *mts_prop(const mts_ctx *c, const mts_node *n, const char *name);
/* An element with this id anywhere in the file, or NULL. */
const mts_node *mts_find_id(const mts_ctx *c, const char *id);
/* Follows <ref id=...> to the element it names (itself otherwise; NULL if unknown). */
const mts_node *mts_deref(const mts_ctx *c, const mts_node *n);

/* Reads up to max numbers separated by spaces or commas; the count read, or -1
 * when something else is there. */
int mts_parse_numbers(const char *s, double *out, int max);
/* A float/integer property; def when absent. LM_ERR_BAD_INPUT when malformed. */
lm_result mts_get_float(const mts_ctx *c, const mts_node *n, const char *name, double def, double *out,
                        lm_error *err);
/* A string property, or def. */
const char *mts_get_string(const mts_ctx *c, const mts_node *n, const char *name, const char *def);
/* A boolean property, or def. */
int mts_get_bool(const mts_ctx *c, const mts_node *n, const char *name, int def);
/* A colour: spectrum, rgb, srgb, or a texture (its mean colour, *textured set).
 * def when absent. Out of the visible range spectra are averaged per band. */
lm_result mts_get_color(mts_ctx *c, const mts_node *n, const char *name, const float def[3], float out[3],
                        int *textured, lm_error *err);

/* The modified Phong material for a <bsdf> element (shared by every shape that
 * names it): its builder index. Approximations become notes. */
lm_result mts_material(mts_ctx *c, const mts_node *bsdf, uint32_t *out_index, lm_error *err);
/* The material for shapes without a BSDF: Mitsuba's default, diffuse 0.5. */
lm_result mts_default_material(mts_ctx *c, uint32_t *out_index, lm_error *err);

/* "file:line: " prefix for messages about element n. */
lm_result mts_error(const mts_ctx *c, const mts_node *n, lm_error *err, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 4, 5)))
#endif
    ;

#endif
