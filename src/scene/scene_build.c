/* scene_build.c — turns the raw triangles every loader produces into a clean scene.
 *
 * One place for every cleaning rule, so all formats are treated alike:
 *  1. triangles with a NaN/Inf corner, or one beyond SCENE_COORD_MAX, are dropped
 *     and counted; the rest are taken relative to the local origin (in double) and
 *     rounded to float;
 *  2. corners are welded by exact position (bitwise, -0 == +0): cache vertices are
 *     keyed by scene vertex ids (docs/cache.md, mesh/vtable.h), so shared corners must share ids;
 *  3. zero-area triangles (repeated or collinear corners) are dropped and counted;
 *  4. duplicate triangles (same three corners, either winding) are dropped and
 *     counted: coincident surfaces z-fight and self-shadow in every renderer;
 *  5. a triangle whose file normals all point against its winding is re-wound;
 *  6. corners without a usable file normal get an angle-weighted normal of the
 *     faces around the vertex within the crease angle;
 *  7. topology (OpenMesh), area lights, unused materials, bounds, a framing camera.
 */
#include <float.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "src/base/vecmath.h"
#include "src/scene/scene_internal.h"

enum { DEFAULT_WIDTH = 640, DEFAULT_HEIGHT = 480 };
#define DEFAULT_CREASE_DEG 30.0f
#define DEFAULT_FOV_DEG 40.0f
/* A triangle is degenerate when twice its area is below this fraction of its
 * longest edge squared: its height is at float round-off of its size. */
#define DEGENERATE_REL 1e-7

static uint32_t hash_u32(uint32_t h)
{
    h ^= h >> 16;
    h *= 0x7feb352du;
    h ^= h >> 15;
    h *= 0x846ca68bu;
    h ^= h >> 16;
    return h;
}

static uint32_t float_key(float f)
{
    if (f == 0.0f) f = 0.0f; /* -0 and +0 are one position */
    uint32_t u;
    memcpy(&u, &f, sizeof u);
    return u;
}

static size_t table_size_for(size_t n)
{
    size_t cap = 64;
    while (cap < 2 * n) cap *= 2;
    return cap;
}

/* ---- welding ------------------------------------------------------------ */

typedef struct weld_table {
    uint32_t *slots; /* vertex id + 1, 0 = empty */
    size_t mask;
    float *positions; /* 3 per vertex */
    uint32_t count, cap;
} weld_table;

static uint32_t weld_hash(const float *p)
{
    uint32_t h = hash_u32(float_key(p[0]));
    h = hash_u32(h ^ float_key(p[1]) * 0x9e3779b1u);
    return hash_u32(h ^ float_key(p[2]) * 0x85ebca77u);
}

static int same_position(const float *a, const float *b)
{
    return float_key(a[0]) == float_key(b[0]) && float_key(a[1]) == float_key(b[1]) &&
           float_key(a[2]) == float_key(b[2]);
}

/* Returns the vertex id of p, adding it when new; UINT32_MAX when out of memory. */
static uint32_t weld(weld_table *w, const float *p)
{
    size_t i = weld_hash(p) & w->mask;
    for (;; i = (i + 1) & w->mask) {
        uint32_t s = w->slots[i];
        if (s == 0) break;
        if (same_position(w->positions + 3 * (size_t)(s - 1), p)) return s - 1;
    }
    if (w->count == w->cap) return UINT32_MAX; /* sized up front; cannot happen */
    uint32_t id = w->count++;
    memcpy(w->positions + 3 * (size_t)id, p, 3 * sizeof(float));
    w->slots[i] = id + 1;
    return id;
}

/* ---- duplicates --------------------------------------------------------- */

static void sort3(const uint32_t *v, uint32_t out[3])
{
    uint32_t a = v[0], b = v[1], c = v[2], t;
    if (a > b) { t = a; a = b; b = t; }
    if (b > c) { t = b; b = c; c = t; }
    if (a > b) { t = a; a = b; b = t; }
    out[0] = a; out[1] = b; out[2] = c;
}

/* ---- normals ------------------------------------------------------------ */

static int usable_normal(const float *n)
{
    lm_vec3 v = v3_load(n);
    return v3_isfinite(v) && v3_dot(v, v) > 1e-20f;
}

/* Angle of triangle (a,b,c) at a, radians. */
static double corner_angle(lm_dvec3 a, lm_dvec3 b, lm_dvec3 c)
{
    lm_dvec3 u = dv3_sub(b, a), v = dv3_sub(c, a);
    double cr = dv3_length(dv3_cross(u, v));
    return atan2(cr, dv3_dot(u, v));
}

/* Smoothing groups around a vertex: two of its faces are in one group when they
 * share an edge through the vertex whose dihedral angle is within the crease angle
 * (transitively). Every corner of a group gets the same angle-weighted normal, so
 * smooth neighbours agree exactly and only real creases separate cache samples. */
static uint32_t group_root(uint32_t *parent, uint32_t i)
{
    while (parent[i] != i) i = parent[i] = parent[parent[i]];
    return i;
}

static int share_edge_through(const scene_tri *a, const scene_tri *b, uint32_t v)
{
    for (int i = 0; i < 3; ++i) {
        if (a->v[i] == v) continue;
        for (int j = 0; j < 3; ++j)
            if (b->v[j] == a->v[i]) return 1;
    }
    return 0;
}

static void smooth_vertex(scene *s, const unsigned char *has_file_normal, const uint32_t *corners,
                          uint32_t count, double cos_crease, uint32_t *parent, lm_dvec3 *acc)
{
    uint32_t v = s->tris[corners[0] / 3u].v[corners[0] % 3u];
    for (uint32_t i = 0; i < count; ++i) parent[i] = i;
    for (uint32_t i = 0; i < count; ++i) {
        uint32_t ti = corners[i] / 3u;
        lm_dvec3 ni = dv3_load(s->tri_normals + 3 * (size_t)ti);
        for (uint32_t j = i + 1; j < count; ++j) {
            uint32_t tj = corners[j] / 3u;
            if (group_root(parent, i) == group_root(parent, j)) continue;
            if (dv3_dot(ni, dv3_load(s->tri_normals + 3 * (size_t)tj)) < cos_crease) continue;
            if (!share_edge_through(&s->tris[ti], &s->tris[tj], v)) continue;
            parent[group_root(parent, j)] = group_root(parent, i);
        }
    }
    for (uint32_t i = 0; i < count; ++i) acc[i] = dv3(0, 0, 0);
    for (uint32_t i = 0; i < count; ++i) {
        uint32_t t = corners[i] / 3u, k = corners[i] % 3u;
        const uint32_t *tv = s->tris[t].v;
        double w = corner_angle(dv3_load(s->positions + 3 * (size_t)tv[k]),
                                dv3_load(s->positions + 3 * (size_t)tv[(k + 1) % 3]),
                                dv3_load(s->positions + 3 * (size_t)tv[(k + 2) % 3]));
        uint32_t r = group_root(parent, i);
        acc[r] = dv3_add(acc[r], dv3_scale(dv3_load(s->tri_normals + 3 * (size_t)t), w));
    }
    for (uint32_t i = 0; i < count; ++i) {
        if (has_file_normal[corners[i]]) continue;
        lm_dvec3 n = dv3_normalize(acc[group_root(parent, i)]);
        if (dv3_dot(n, n) == 0.0) n = dv3_load(s->tri_normals + 3 * (size_t)(corners[i] / 3u));
        float *out = s->corner_normals + 3 * (size_t)corners[i];
        out[0] = (float)n.x;
        out[1] = (float)n.y;
        out[2] = (float)n.z;
    }
}

static lm_result compute_missing_normals(scene *s, const unsigned char *has_file_normal,
                                         lm_error *err)
{
    uint32_t nv = s->vertex_count, nt = s->tri_count;
    uint32_t *start = calloc((size_t)nv + 2, sizeof *start);
    uint32_t *inc = malloc((size_t)nt * 3 * sizeof *inc);
    if (!start || !inc) {
        free(start);
        free(inc);
        return lm_fail(err, LM_ERR_NO_MEMORY, "%s: out of memory computing normals", s->source);
    }
    /* Corners by vertex (counting sort). */
    for (uint32_t t = 0; t < nt; ++t)
        for (int k = 0; k < 3; ++k) start[s->tris[t].v[k] + 2]++;
    for (uint32_t v = 0; v < nv; ++v) start[v + 2] += start[v + 1];
    for (uint32_t t = 0; t < nt; ++t)
        for (int k = 0; k < 3; ++k) inc[start[s->tris[t].v[k] + 1]++] = t * 3u + (uint32_t)k;
    uint32_t max_valence = 0;
    for (uint32_t v = 0; v < nv; ++v)
        if (start[v + 1] - start[v] > max_valence) max_valence = start[v + 1] - start[v];
    uint32_t *parent = malloc((size_t)max_valence * sizeof *parent);
    lm_dvec3 *acc = malloc((size_t)max_valence * sizeof *acc);
    if (!parent || !acc) {
        free(start);
        free(inc);
        free(parent);
        free(acc);
        return lm_fail(err, LM_ERR_NO_MEMORY, "%s: out of memory computing normals", s->source);
    }
    double cos_crease = cos((double)s->crease_angle_deg * M_PI / 180.0);
    for (uint32_t v = 0; v < nv; ++v)
        if (start[v + 1] > start[v])
            smooth_vertex(s, has_file_normal, inc + start[v], start[v + 1] - start[v], cos_crease,
                          parent, acc);
    free(start);
    free(inc);
    free(parent);
    free(acc);
    return LM_OK;
}

/* ---- materials ----------------------------------------------------------- */

static void sanitize_material(scene_builder *b, scene_material *m)
{
    float *fields[3] = {m->kd, m->ks, m->le};
    static const char *names[3] = {"kd", "ks", "Le"};
    for (int f = 0; f < 3; ++f) {
        int bad = 0;
        for (int c = 0; c < 3; ++c)
            if (!isfinite(fields[f][c]) || fields[f][c] < 0.0f) {
                fields[f][c] = 0.0f;
                bad = 1;
            }
        if (bad)
            scene_builder_note(b, "material '%s': negative or non-finite %s set to 0", m->name,
                               names[f]);
    }
    if (!isfinite(m->n) || m->n < 0.0f) {
        if (m->ks[0] > 0 || m->ks[1] > 0 || m->ks[2] > 0)
            scene_builder_note(b, "material '%s': invalid Phong exponent set to 0", m->name);
        m->n = 0.0f;
    }
    for (int c = 0; c < 3; ++c)
        if (m->kd[c] + m->ks[c] > 1.0f + 1e-6f) m->notes |= SCENE_MATNOTE_GAINS_ENERGY;
}

static void describe_material_notes(scene_builder *b, const scene_material *m)
{
    if (m->notes & SCENE_MATNOTE_REFRACTION_AS_PHONG)
        scene_builder_note(b,
                           "material '%s': refraction (OBJ illum 4-9) approximated as opaque "
                           "modified Phong (kd %.3g %.3g %.3g, ks %.3g %.3g %.3g, n %g)",
                           m->name, m->kd[0], m->kd[1], m->kd[2], m->ks[0], m->ks[1], m->ks[2],
                           m->n);
    if (m->notes & SCENE_MATNOTE_TRANSPARENCY_IGNORED)
        scene_builder_note(b, "material '%s': transparency (opacity < 1) ignored; modelled opaque",
                           m->name);
    if (m->notes & SCENE_MATNOTE_GAINS_ENERGY)
        scene_builder_note(b, "material '%s': kd + ks > 1 in some channel: it reflects more "
                              "light than it receives",
                           m->name);
}

/* ---- framing camera ------------------------------------------------------ */

static void framing_camera(const scene *s, int width, int height, scene_camera *c)
{
    memset(c, 0, sizeof *c);
    lm_strlcpy(c->name, "default", sizeof c->name);
    c->fov_y_deg = DEFAULT_FOV_DEG;
    c->width = width;
    c->height = height;
    float half[3], center[3];
    for (int i = 0; i < 3; ++i) {
        center[i] = 0.5f * (s->bounds_min[i] + s->bounds_max[i]);
        half[i] = 0.5f * (s->bounds_max[i] - s->bounds_min[i]);
    }
    /* Look down -Z at the bounds, far enough that the x and y extents fit. */
    double t = tan(0.5 * (double)c->fov_y_deg * M_PI / 180.0);
    double aspect = (double)width / (double)height;
    double dist = fmax(half[1] / t, half[0] / (aspect * t)) * 1.05 + half[2];
    if (!(dist > 0.0)) dist = 1.0;
    memcpy(c->target, center, sizeof center);
    c->position[0] = center[0];
    c->position[1] = center[1];
    c->position[2] = center[2] + (float)dist;
    c->up[1] = 1.0f;
}

/* ---- the local origin ---------------------------------------------------- */

/* Where the scene's float coordinates are measured from (scene.origin; docs/
 * scene-model.md, "Coordinates"). Floats carry 24 bits: a room 10^5 units from
 * the file's origin keeps only millimetres, and offsets scaled by the largest
 * coordinate step over its features. So the corners (in double until here) are
 * taken relative to the middle of the finite geometry: the bounds' centre,
 * rounded to a multiple of q = 2^-16 of the power of two at or above the extent
 * (so every local coordinate is within extent/2 + q of zero, and a scene moved by
 * a round offset keeps exactly its floats). A scene whose bounds already hold the
 * file's origin keeps origin 0: its coordinates are within its extent of zero,
 * and its floats stay bit for bit what they were before recentring existed. */
static void choose_local_origin(const scene_builder *b, double origin[3])
{
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (size_t i = 0; i < 9 * b->count; ++i) {
        double x = b->pos[i];
        if (!(fabs(x) <= SCENE_COORD_MAX)) continue; /* NaN, Inf and absurd values are dropped later */
        int k = (int)(i % 3);
        lo[k] = fmin(lo[k], x);
        hi[k] = fmax(hi[k], x);
    }
    origin[0] = origin[1] = origin[2] = 0.0;
    if (!(lo[0] <= hi[0] && lo[1] <= hi[1] && lo[2] <= hi[2])) return;
    if (lo[0] <= 0.0 && hi[0] >= 0.0 && lo[1] <= 0.0 && hi[1] >= 0.0 && lo[2] <= 0.0 && hi[2] >= 0.0) return;
    double extent = 0.0;
    for (int k = 0; k < 3; ++k) extent = fmax(extent, hi[k] - lo[k]);
    double q = extent > 0.0 ? exp2(ceil(log2(extent)) - 16.0) : 1.0;
    for (int k = 0; k < 3; ++k) origin[k] = q * nearbyint(0.5 * (lo[k] + hi[k]) / q);
}

/* Warns when the float coordinates cannot hold the scene's smallest feature:
 * its shortest edge spans fewer than PRECISION_STEPS float steps at the scene's
 * largest local coordinate, so corners are rounded by more than 1/128 of it. */
#define PRECISION_STEPS 64.0
static void note_precision(scene_builder *b, const scene *s)
{
    double largest = 0.0, shortest = INFINITY;
    for (int k = 0; k < 3; ++k)
        largest = fmax(largest, fmax(fabs((double)s->bounds_min[k]), fabs((double)s->bounds_max[k])));
    for (uint32_t t = 0; t < s->tri_count; ++t)
        for (int e = 0; e < 3; ++e) {
            lm_dvec3 a = dv3_load(s->positions + 3 * (size_t)s->tris[t].v[e]);
            lm_dvec3 c = dv3_load(s->positions + 3 * (size_t)s->tris[t].v[(e + 1) % 3]);
            shortest = fmin(shortest, dv3_length(dv3_sub(c, a)));
        }
    if (!(largest > 0.0) || !isfinite(shortest)) return;
    int exponent;
    frexp(largest, &exponent);
    double step = ldexp(1.0, exponent - 24); /* float spacing at `largest` */
    if (shortest < PRECISION_STEPS * step)
        scene_builder_note(b, "the shortest edge (%.3g) is only %.0f float steps long at the scene's extent "
                              "(%.3g from its local origin): corners are rounded by up to %.2g, so its small "
                              "features are distorted; split the scene or model it in smaller units",
                           shortest, shortest / step, largest, 0.5 * step);
}

/* ---- the build ----------------------------------------------------------- */

typedef struct build_tmp {
    uint32_t *tri_v;            /* 3 per raw triangle */
    unsigned char *keep;        /* per raw triangle */
    uint32_t *dup_slots;
    uint32_t *part_dups;        /* per material, then reused per part */
    unsigned char *has_file_n;  /* 3 per kept triangle */
    uint32_t *mat_remap;
    weld_table weld;
    uint32_t denormals;         /* local coordinates below float's normal range, set to 0 */
} build_tmp;

static void build_tmp_free(build_tmp *t)
{
    free(t->tri_v);
    free(t->keep);
    free(t->dup_slots);
    free(t->part_dups);
    free(t->has_file_n);
    free(t->mat_remap);
    free(t->weld.slots);
    free(t->weld.positions);
}

static lm_result fail_build(build_tmp *t, scene *s, lm_result r)
{
    build_tmp_free(t);
    scene_destroy(s);
    return r;
}

lm_result scene_build(scene_builder *b, const scene_load_desc *desc, scene **out, lm_error *err)
{
    build_tmp t;
    memset(&t, 0, sizeof t);
    *out = NULL;
    scene *s = calloc(1, sizeof *s);
    if (!s) return lm_fail(err, LM_ERR_NO_MEMORY, "%s: out of memory", b->source);
    lm_strlcpy(s->source, b->source, sizeof s->source);
    s->crease_angle_deg = desc->crease_angle_deg > 0.0f ? desc->crease_angle_deg : DEFAULT_CREASE_DEG;
    s->report.input_triangles = (uint32_t)b->count;
    size_t n = b->count;

    if (n == 0)
        return fail_build(&t, s, lm_fail(err, LM_ERR_BAD_INPUT,
                                         "%s: no triangles in the file (is it truncated, or only "
                                         "points and lines?)",
                                         b->source));

    /* 1-2: finite check and welding */
    t.tri_v = malloc(n * 3 * sizeof *t.tri_v);
    t.keep = calloc(n, 1);
    t.weld.mask = table_size_for(3 * n) - 1;
    t.weld.slots = calloc(t.weld.mask + 1, sizeof *t.weld.slots);
    t.weld.cap = (uint32_t)(3 * n);
    t.weld.positions = malloc(3 * n * 3 * sizeof(float));
    /* per material (dropped duplicates) and later per part (re-wound): sized for both */
    t.part_dups = calloc((b->part_count > b->mat_count ? b->part_count : b->mat_count) + 1,
                         sizeof *t.part_dups);
    if (!t.tri_v || !t.keep || !t.weld.slots || !t.weld.positions || !t.part_dups)
        return fail_build(&t, s, lm_fail(err, LM_ERR_NO_MEMORY, "%s: out of memory", b->source));
    choose_local_origin(b, s->origin);
    for (size_t i = 0; i < n; ++i) {
        const double *p = b->pos + 9 * i;
        int finite = 1, in_range = 1;
        for (int k = 0; k < 9; ++k) {
            finite &= isfinite(p[k]) != 0;
            in_range &= fabs(p[k]) <= SCENE_COORD_MAX;
        }
        if (!finite || !in_range) {
            if (!finite)
                s->report.dropped_nonfinite++;
            else
                s->report.dropped_out_of_range++;
            continue;
        }
        float local[9];
        for (int k = 0; k < 9; ++k) {
            local[k] = (float)(p[k] - s->origin[k % 3]);
            if (local[k] != 0.0f && fabsf(local[k]) < FLT_MIN) { /* a denormal (binary files carry them) */
                local[k] = 0.0f;
                t.denormals++;
            }
        }
        for (int k = 0; k < 3; ++k) t.tri_v[3 * i + (size_t)k] = weld(&t.weld, local + 3 * k);
        t.keep[i] = 1;
    }

    /* 3: degenerate */
    for (size_t i = 0; i < n; ++i) {
        if (!t.keep[i]) continue;
        const uint32_t *v = t.tri_v + 3 * i;
        int bad = v[0] == v[1] || v[1] == v[2] || v[0] == v[2];
        if (!bad) {
            lm_dvec3 a = dv3_load(t.weld.positions + 3 * (size_t)v[0]);
            lm_dvec3 bb = dv3_load(t.weld.positions + 3 * (size_t)v[1]);
            lm_dvec3 c = dv3_load(t.weld.positions + 3 * (size_t)v[2]);
            lm_dvec3 e0 = dv3_sub(bb, a), e1 = dv3_sub(c, bb), e2 = dv3_sub(a, c);
            double emax2 = fmax(dv3_dot(e0, e0), fmax(dv3_dot(e1, e1), dv3_dot(e2, e2)));
            double twice_area = dv3_length(dv3_cross(e0, dv3_sub(c, a)));
            bad = !(twice_area > DEGENERATE_REL * emax2) || !isfinite(twice_area);
        }
        if (bad) {
            t.keep[i] = 0;
            s->report.dropped_degenerate++;
        }
    }

    /* 4: duplicates */
    size_t dmask = table_size_for(n) - 1;
    t.dup_slots = calloc(dmask + 1, sizeof *t.dup_slots);
    if (!t.dup_slots)
        return fail_build(&t, s, lm_fail(err, LM_ERR_NO_MEMORY, "%s: out of memory", b->source));
    for (size_t i = 0; i < n; ++i) {
        if (!t.keep[i]) continue;
        uint32_t key[3];
        sort3(t.tri_v + 3 * i, key);
        size_t h = hash_u32(hash_u32(hash_u32(key[0]) ^ key[1]) ^ key[2]) & dmask;
        for (;; h = (h + 1) & dmask) {
            uint32_t slot = t.dup_slots[h];
            if (slot == 0) {
                t.dup_slots[h] = (uint32_t)i + 1;
                break;
            }
            uint32_t other[3];
            sort3(t.tri_v + 3 * (size_t)(slot - 1), other);
            if (other[0] == key[0] && other[1] == key[1] && other[2] == key[2]) {
                t.keep[i] = 0;
                s->report.dropped_duplicate++;
                t.part_dups[b->mat[i] < b->mat_count ? b->mat[i] : b->mat_count]++;
                break;
            }
        }
    }
    /* Named by material: OBJ groups are often not where their faces are (the Cornell
     * files put `g shortBox` after the short box's faces), materials are. */
    for (uint32_t m = 0; m < b->mat_count; ++m)
        if (t.part_dups[m])
            scene_builder_note(b, "dropped %u duplicate triangle%s of material '%s': coincident "
                                  "with triangles already in the scene",
                               t.part_dups[m], t.part_dups[m] == 1 ? "" : "s", b->mats[m].name);
    if (s->report.dropped_nonfinite)
        scene_builder_note(b, "dropped %u triangle%s with NaN/Inf coordinates",
                           s->report.dropped_nonfinite, s->report.dropped_nonfinite == 1 ? "" : "s");
    if (t.denormals)
        scene_builder_note(b, "%s: %u coordinate%s below float's smallest normal value (1.2e-38) set to 0",
                           b->source, t.denormals, t.denormals == 1 ? "" : "s");
    if (s->report.dropped_out_of_range)
        scene_builder_note(b, "dropped %u triangle%s with a coordinate beyond %.2g (too large to compute with "
                              "in float)",
                           s->report.dropped_out_of_range, s->report.dropped_out_of_range == 1 ? "" : "s",
                           SCENE_COORD_MAX);
    if (s->report.dropped_degenerate)
        scene_builder_note(b, "dropped %u degenerate (zero-area) triangle%s",
                           s->report.dropped_degenerate,
                           s->report.dropped_degenerate == 1 ? "" : "s");

    size_t kept = 0;
    for (size_t i = 0; i < n; ++i) kept += t.keep[i];
    if (kept == 0)
        return fail_build(
            &t, s,
            lm_fail(err, LM_ERR_BAD_INPUT,
                    "%s: no triangles left after cleaning (%zu read: %u with NaN/Inf, %u out of range, %u "
                    "degenerate, %u duplicate%s)",
                    b->source, n, s->report.dropped_nonfinite, s->report.dropped_out_of_range,
                    s->report.dropped_degenerate,
                    s->report.dropped_duplicate,
                    b->numbers_too_large ? "; the file spells numbers too large for a float" : ""));

    /* Materials used by kept triangles, renumbered densely. */
    t.mat_remap = malloc(((size_t)b->mat_count + 1) * sizeof *t.mat_remap);
    if (!t.mat_remap)
        return fail_build(&t, s, lm_fail(err, LM_ERR_NO_MEMORY, "%s: out of memory", b->source));
    for (uint32_t m = 0; m <= b->mat_count; ++m) t.mat_remap[m] = UINT32_MAX;
    for (size_t i = 0; i < n; ++i)
        if (t.keep[i] && b->mat[i] < b->mat_count) t.mat_remap[b->mat[i]] = 0;
    s->materials = malloc(((size_t)b->mat_count + 1) * sizeof *s->materials);
    if (!s->materials)
        return fail_build(&t, s, lm_fail(err, LM_ERR_NO_MEMORY, "%s: out of memory", b->source));
    for (uint32_t m = 0; m < b->mat_count; ++m) {
        if (t.mat_remap[m] == UINT32_MAX) {
            /* Assimp's own stand-in is not the user's material: not worth a mention. */
            if (!(b->mats[m].notes & SCENE_MATNOTE_DEFAULT)) s->report.materials_unused++;
            continue;
        }
        scene_material mat = b->mats[m];
        sanitize_material(b, &mat);
        describe_material_notes(b, &mat);
        t.mat_remap[m] = s->material_count;
        s->materials[s->material_count++] = mat;
    }
    int need_default = 0;
    for (size_t i = 0; i < n; ++i) need_default |= t.keep[i] && b->mat[i] >= b->mat_count;
    if (need_default) { /* a loader bug would land here; keep the triangles visible */
        t.mat_remap[b->mat_count] = s->material_count;
        s->materials[s->material_count++] = scene_material_default("default");
    }

    /* Compact vertices to the ones kept triangles use. */
    uint32_t *vmap = malloc((size_t)t.weld.count * sizeof *vmap);
    if (!vmap)
        return fail_build(&t, s, lm_fail(err, LM_ERR_NO_MEMORY, "%s: out of memory", b->source));
    for (uint32_t v = 0; v < t.weld.count; ++v) vmap[v] = UINT32_MAX;
    s->positions = malloc((size_t)t.weld.count * 3 * sizeof(float));
    s->tris = malloc(kept * sizeof *s->tris);
    s->corner_normals = malloc(kept * 9 * sizeof(float));
    s->tri_normals = malloc(kept * 3 * sizeof(float));
    s->tri_areas = malloc(kept * sizeof(float));
    t.has_file_n = calloc(kept * 3, 1);
    if (!s->positions || !s->tris || !s->corner_normals || !s->tri_normals || !s->tri_areas ||
        !t.has_file_n) {
        free(vmap);
        return fail_build(&t, s, lm_fail(err, LM_ERR_NO_MEMORY, "%s: out of memory", b->source));
    }

    /* 5: orientation from file normals; geometric normals and areas */
    uint32_t *part_rewound = t.part_dups; /* reuse: duplicates are already reported */
    memset(part_rewound, 0,
           ((b->part_count > b->mat_count ? b->part_count : b->mat_count) + 1) * sizeof *part_rewound);
    for (size_t i = 0; i < n; ++i) {
        if (!t.keep[i]) continue;
        uint32_t ti = s->tri_count++;
        scene_tri *tri = &s->tris[ti];
        float nrm[9];
        memcpy(nrm, b->nrm + 9 * i, sizeof nrm);
        for (int k = 0; k < 3; ++k) {
            uint32_t v = t.tri_v[3 * i + (size_t)k];
            if (vmap[v] == UINT32_MAX) {
                vmap[v] = s->vertex_count++;
                memcpy(s->positions + 3 * (size_t)vmap[v], t.weld.positions + 3 * (size_t)v,
                       3 * sizeof(float));
            }
            tri->v[k] = vmap[v];
        }
        tri->material = t.mat_remap[b->mat[i] < b->mat_count ? b->mat[i] : b->mat_count];
        tri->light = -1;
        tri->part = b->part[i];
        lm_dvec3 p0 = dv3_load(s->positions + 3 * (size_t)tri->v[0]);
        lm_dvec3 p1 = dv3_load(s->positions + 3 * (size_t)tri->v[1]);
        lm_dvec3 p2 = dv3_load(s->positions + 3 * (size_t)tri->v[2]);
        lm_dvec3 cr = dv3_cross(dv3_sub(p1, p0), dv3_sub(p2, p0));
        int all_file = 1;
        lm_dvec3 nsum = dv3(0, 0, 0);
        for (int k = 0; k < 3; ++k) {
            int ok = usable_normal(nrm + 3 * k);
            t.has_file_n[3 * (size_t)ti + (size_t)k] = (unsigned char)ok;
            all_file &= ok;
            if (ok) {
                lm_vec3 u = v3_normalize(v3_load(nrm + 3 * k));
                v3_store(nrm + 3 * k, u);
                nsum = dv3_add(nsum, dv3_from(u));
            }
        }
        if (all_file && dv3_dot(nsum, cr) < 0.0) {
            uint32_t tv = tri->v[1];
            tri->v[1] = tri->v[2];
            tri->v[2] = tv;
            float tmp[3];
            memcpy(tmp, nrm + 3, sizeof tmp);
            memcpy(nrm + 3, nrm + 6, sizeof tmp);
            memcpy(nrm + 6, tmp, sizeof tmp);
            cr = dv3_scale(cr, -1.0);
            s->report.rewound++;
            part_rewound[tri->part < b->part_count ? tri->part : b->part_count]++;
        }
        memcpy(s->corner_normals + 9 * (size_t)ti, nrm, sizeof nrm);
        lm_dvec3 gn = dv3_normalize(cr);
        s->tri_normals[3 * (size_t)ti + 0] = (float)gn.x;
        s->tri_normals[3 * (size_t)ti + 1] = (float)gn.y;
        s->tri_normals[3 * (size_t)ti + 2] = (float)gn.z;
        s->tri_areas[ti] = (float)(0.5 * dv3_length(cr));
    }
    free(vmap);
    for (uint32_t p = 0; p < b->part_count; ++p)
        if (part_rewound[p])
            scene_builder_note(b, "re-wound %u triangle%s in '%s' (%s): their vertex normals point "
                                  "against their winding; the normals decide the front",
                               part_rewound[p], part_rewound[p] == 1 ? "" : "s", b->parts[p].name,
                               b->parts[p].source);

    /* 6: normals */
    for (size_t c = 0; c < 3 * (size_t)s->tri_count; ++c) {
        if (t.has_file_n[c])
            s->report.corners_file_normals++;
        else
            s->report.corners_computed_normals++;
    }
    lm_result r = compute_missing_normals(s, t.has_file_n, err);
    if (r != LM_OK) return fail_build(&t, s, r);

    /* Bounds */
    for (int k = 0; k < 3; ++k) {
        s->bounds_min[k] = INFINITY;
        s->bounds_max[k] = -INFINITY;
    }
    for (uint32_t v = 0; v < s->vertex_count; ++v)
        for (int k = 0; k < 3; ++k) {
            float x = s->positions[3 * (size_t)v + (size_t)k];
            if (x < s->bounds_min[k]) s->bounds_min[k] = x;
            if (x > s->bounds_max[k]) s->bounds_max[k] = x;
        }

    note_precision(b, s);

    /* 7: topology */
    mesh_geo_desc gd = {.positions = s->positions,
                        .vertex_count = s->vertex_count,
                        .triangles = &s->tris[0].v[0],
                        .triangle_count = s->tri_count,
                        .corner_normals = s->corner_normals};
    /* scene_tri is not a packed uint32 triple: pass a packed copy */
    uint32_t *packed = malloc((size_t)s->tri_count * 3 * sizeof *packed);
    if (!packed)
        return fail_build(&t, s, lm_fail(err, LM_ERR_NO_MEMORY, "%s: out of memory", b->source));
    for (uint32_t i = 0; i < s->tri_count; ++i) memcpy(packed + 3 * (size_t)i, s->tris[i].v, 12);
    gd.triangles = packed;
    r = mesh_geo_create(&gd, &s->topology, err);
    free(packed);
    if (r != LM_OK) return fail_build(&t, s, r);
    {
        mesh_geo_stats gs;
        mesh_geo_get_stats(s->topology, &gs);
        if (gs.rejected_triangles)
            scene_builder_note(b,
                               "%u triangle%s could not join the manifold mesh (non-manifold or "
                               "inconsistently wound edges): no neighbours across those edges",
                               gs.rejected_triangles, gs.rejected_triangles == 1 ? "" : "s");
    }

    r = scene_build_lights(s, err);
    if (r != LM_OK) return fail_build(&t, s, r);

    /* Point lights, cameras, parts, tone mapping */
    if (b->point_count) {
        s->point_lights = malloc(b->point_count * sizeof *s->point_lights);
        if (!s->point_lights)
            return fail_build(&t, s, lm_fail(err, LM_ERR_NO_MEMORY, "%s: out of memory", b->source));
        for (uint32_t i = 0; i < b->point_count; ++i) {
            scene_point_light *p = &s->point_lights[i];
            memcpy(p->intensity, b->points[i].intensity, sizeof p->intensity);
            for (int k = 0; k < 3; ++k) p->position[k] = (float)(b->points[i].position[k] - s->origin[k]);
        }
        s->point_light_count = b->point_count;
    }
    int width = desc->default_width > 0 ? desc->default_width : DEFAULT_WIDTH;
    int height = desc->default_height > 0 ? desc->default_height : DEFAULT_HEIGHT;
    s->camera_count = b->cam_count ? b->cam_count : 1;
    s->cameras = malloc(s->camera_count * sizeof *s->cameras);
    if (!s->cameras)
        return fail_build(&t, s, lm_fail(err, LM_ERR_NO_MEMORY, "%s: out of memory", b->source));
    if (b->cam_count) {
        for (uint32_t i = 0; i < s->camera_count; ++i) {
            s->cameras[i] = b->cams[i].cam;
            for (int k = 0; k < 3; ++k) {
                s->cameras[i].position[k] = (float)(b->cams[i].position[k] - s->origin[k]);
                s->cameras[i].target[k] = (float)(b->cams[i].target[k] - s->origin[k]);
            }
            if (s->cameras[i].width <= 0) s->cameras[i].width = width;
            if (s->cameras[i].height <= 0) s->cameras[i].height = height;
            if (!(s->cameras[i].fov_y_deg > 0.0f)) s->cameras[i].fov_y_deg = DEFAULT_FOV_DEG;
        }
    } else {
        framing_camera(s, width, height, &s->cameras[0]);
    }
    s->part_count = b->part_count;
    if (b->part_count) {
        s->parts = malloc(b->part_count * sizeof *s->parts);
        if (!s->parts)
            return fail_build(&t, s, lm_fail(err, LM_ERR_NO_MEMORY, "%s: out of memory", b->source));
        memcpy(s->parts, b->parts, b->part_count * sizeof *s->parts);
    }
    s->exposure = b->exposure;

    if (desc->require_light && scene_light_count(s) == 0)
        return fail_build(&t, s,
                          lm_fail(err, LM_ERR_BAD_INPUT,
                                  "%s: the scene has no light: no triangle emits (Ke/Le > 0) and "
                                  "there is no point light; give a material emission or add a "
                                  "light in a .json scene description",
                                  b->source));

    /* Hand the notes over to the scene's report. */
    s->report.notes = b->notes;
    s->report.note_count = b->note_count;
    b->notes = NULL;
    b->note_count = b->note_cap = 0;
    build_tmp_free(&t);
    *out = s;
    return LM_OK;
}
