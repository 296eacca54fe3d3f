/* vtable.h — the vertex table shared by all cache meshes (paper §4.1–4.2;
 * docs/cache.md).
 *
 * Every vertex a cache mesh creates by midpoint splits lies at an exact dyadic
 * barycentric address in a scene triangle T = (A,B,C): (w0, w1, w2) / 2^depth with
 * w0 + w1 + w2 = 2^depth. The table keys vertices by that address, never by float
 * position, so every mesh — and both triangles of a shared scene edge — finds the
 * same vertex for the same point. Keys (after halving all three weights while all
 * are even, so a point has one form at any depth):
 *   - two zero weights  -> scene vertex: (vertex id, normal class). The normal class
 *     is the smallest triangle id of the group of triangles around the vertex whose
 *     corner normals there agree (0.5° by default) or that are joined by an
 *     un-creased edge; a box corner has one vertex per face, a smooth vertex one.
 *   - one zero weight   -> on a scene edge: (smaller vertex id, larger vertex id,
 *     reduced dyadic parameter measured from the smaller id), plus the triangle id
 *     when the edge is not MESH_EDGE_INTERIOR (crease, boundary, non-manifold), so
 *     each side of a crease keeps its own samples.
 *   - no zero weight    -> interior: (triangle id, reduced w0, w1, depth).
 *
 * Usage:
 *     mesh_vtable_desc d = {.scene = s};          // s->topology gives the edge kinds
 *     mesh_vtable *vt; lm_error err;
 *     if (mesh_vtable_create(&d, &vt, &err) != LM_OK) { puts(err.msg); }
 *     mesh_bary mid = {{1, 1, 0}, 1};             // midpoint of edge 0 of triangle 7
 *     uint32_t id;
 *     if (mesh_vtable_acquire(vt, 7, mid, &id, &err) == LM_OK) {
 *         const mesh_vertex *v = mesh_vtable_vertex(vt, id);  // position, normal
 *         mesh_vtable_release(vt, id, &err);      // refs 0: freed, id recycled
 *     }
 *     mesh_vtable_destroy(vt);
 *
 * Does NOT do: sample values (each mesh keeps its own, see qmesh.h), float-position
 * lookups, welding, thread safety, shrinking its arrays after mass release.
 *
 * Threads: a table belongs to one thread, the refinement worker; no call is
 * thread safe, not even the const ones against a concurrent writer. Readers on
 * other threads get published copies (not this module's job).
 *
 * Reads from the scene: positions, vertex_count, tris[].v, tri_count and
 * corner_normals (NULL: no normal classes, every scene vertex is shared), and
 * scene->topology when desc.geo is NULL. The scene and topology must outlive the table.
 */
#ifndef LUMESH_VTABLE_H
#define LUMESH_VTABLE_H

#include <stddef.h>
#include <stdint.h>
#include "src/base/util.h"
#include "src/scene/scene.h"

#ifdef __cplusplus
extern "C" {
#endif

#define MESH_VTABLE_NONE UINT32_MAX /* "no vertex" id */

enum {
    MESH_DEPTH_MAX = 30 /* deepest dyadic level: weights are numerators over 2^30 at most */
};

/* A dyadic barycentric point in a scene triangle: weights w[i] / 2^depth of the
 * triangle's corners i, with w[0] + w[1] + w[2] == 2^depth and depth <= MESH_DEPTH_MAX. */
typedef struct mesh_bary {
    uint32_t w[3];
    uint32_t depth;
} mesh_bary;

typedef struct mesh_vertex {
    float position[3]; /* scene units; (Σ w_i·corner_i) / 2^depth in double, rounded once */
    float normal[3];   /* unit shading normal: corner normals interpolated, normalised */
    uint32_t tri;      /* the scene triangle the vertex was created from */
    mesh_bary bary;    /* its address in `tri`, reduced (not all weights even) */
    uint32_t refs;     /* holders (each cache mesh using it holds one); 0 only when free */
} mesh_vertex;

typedef struct mesh_vtable_desc {
    const scene *scene;          /* required; must outlive the table */
    const mesh_geo *geo;         /* edge kinds; NULL = scene->topology (NULL too: no shared edges) */
    uint32_t initial_capacity;   /* vertices before the first growth; 0 = 1024 */
    float crease_tolerance_deg;  /* normal classes: corner normals agree within this; 0 = 0.5
                                    (the geomesh default), valid 0..180 */
} mesh_vtable_desc;

typedef struct mesh_vtable_stats {
    uint32_t live;          /* vertices with refs > 0 */
    uint32_t id_limit;      /* ids handed out so far are < id_limit (live + free list) */
    uint32_t free_ids;      /* ids waiting on the free list */
    uint32_t slots;         /* hash slots (power of two) */
    uint32_t max_probe;     /* longest probe sequence of a live key, slots */
    uint32_t rehashes;      /* growths of the hash map so far */
    uint64_t created, freed;/* vertices ever created / freed */
    size_t bytes;           /* everything the table holds on the heap, bytes */
} mesh_vtable_stats;

/* Owned by one thread, the refinement worker, together with every mesh using it. */
typedef struct mesh_vtable mesh_vtable;

lm_result mesh_vtable_create(const mesh_vtable_desc *desc, mesh_vtable **out, lm_error *err);
void mesh_vtable_destroy(mesh_vtable *vt); /* NULL is a no-op */

/* Get-or-create the vertex at `p` in scene triangle `tri` and add one reference.
 * Errors: LM_ERR_INVALID_ARG (tri out of range, weights not summing to 2^depth),
 * LM_ERR_UNSUPPORTED (depth > MESH_DEPTH_MAX), LM_ERR_NO_MEMORY. Worker thread only. */
lm_result mesh_vtable_acquire(mesh_vtable *vt, uint32_t tri, mesh_bary p, uint32_t *out_id,
                              lm_error *err);
/* The id of the vertex at `p`, or MESH_VTABLE_NONE (absent or invalid address). No
 * reference is taken. Worker thread only. */
uint32_t mesh_vtable_find(const mesh_vtable *vt, uint32_t tri, mesh_bary p);
/* mesh_vtable_find for corner `corner` (0..2) of scene triangle tri, by its
 * normal class: two array reads, not a key (the roots of a million-triangle
 * scene's meshes look up three million corners). MESH_VTABLE_NONE: no vertex
 * yet, or tri or corner out of range. */
uint32_t mesh_vtable_corner_id(const mesh_vtable *vt, uint32_t tri, int corner);
/* One more / one less reference to a live vertex. Release of the last reference
 * frees the vertex and recycles its id. LM_ERR_INVALID_ARG for a dead or bad id. */
lm_result mesh_vtable_retain(mesh_vtable *vt, uint32_t id, lm_error *err);
lm_result mesh_vtable_release(mesh_vtable *vt, uint32_t id, lm_error *err);

/* The live vertex `id`, or NULL. Valid until the next acquire (which may grow the array). */
const mesh_vertex *mesh_vtable_vertex(const mesh_vtable *vt, uint32_t id);
/* Every id ever handed out is below this; per-mesh arrays indexed by id size to it. */
uint32_t mesh_vtable_id_limit(const mesh_vtable *vt);
void mesh_vtable_get_stats(const mesh_vtable *vt, mesh_vtable_stats *out);
/* Heap bytes per live vertex, amortised (record + key + hash slots + free list). */
double mesh_vtable_bytes_per_vertex(const mesh_vtable *vt);
const scene *mesh_vtable_scene(const mesh_vtable *vt);
const mesh_geo *mesh_vtable_geo(const mesh_vtable *vt);

/* Dyadic helpers. mesh_bary_valid: weights sum to 2^depth, depth <= MESH_DEPTH_MAX.
 * mesh_bary_reduce: halves all weights while all are even (one form per point).
 * mesh_bary_midpoint: the midpoint of a and b at depth max(a,b)+1 (not reduced);
 * LM_ERR_UNSUPPORTED when that depth would exceed MESH_DEPTH_MAX. */
int mesh_bary_valid(mesh_bary p);
mesh_bary mesh_bary_reduce(mesh_bary p);
lm_result mesh_bary_midpoint(mesh_bary a, mesh_bary b, mesh_bary *out);

#ifdef __cplusplus
}
#endif
#endif
