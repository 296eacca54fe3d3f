/* geomesh.h — the geometric mesh: topology of the scene's triangles (OpenMesh adapter).
 *
 * Holds the welded scene triangles in an OpenMesh TriMesh and answers, for every
 * triangle edge, which triangle lies across it — or none, at a boundary, at a
 * non-manifold edge (three or more triangles, or two wound inconsistently), or at
 * a crease (the two sides' shading normals disagree at an end of the edge).
 * The cache meshes (paper §4.1) use this to split the triangle across a split edge.
 *
 * Edge e of triangle t joins its corners e and (e+1)%3.
 *
 * Usage:
 *     mesh_geo_desc d = {.positions = p, .vertex_count = nv, .triangles = t,
 *                        .triangle_count = nt, .corner_normals = n};
 *     mesh_geo *g; lm_error err;
 *     if (mesh_geo_create(&d, &g, &err) != LM_OK) { puts(err.msg); }
 *     int32_t across = mesh_geo_neighbor(g, tri, 0);
 *     mesh_geo_destroy(g);
 *
 * Does NOT do: welding (vertex ids must already be shared), normal computation,
 * duplicate removal. Not thread safe to create (it mutes OpenMesh's process-wide
 * omerr() stream while building); queries are read-only and may run on any thread.
 *
 * Notes: queries on a NULL mesh, an out-of-range triangle or an edge outside 0..2
 * return -1 / -1 / MESH_EDGE_BOUNDARY. Degenerate (repeated-id) and duplicate
 * triangles are refused by OpenMesh and so counted as rejected, their edges
 * non-manifold; scene_load removes both before it builds the topology. Which
 * triangle of a non-manifold set is rejected depends on input order. More than
 * 357,913,941 triangles is LM_ERR_UNSUPPORTED (OpenMesh handles are int).
 */
#ifndef LUMESH_GEOMESH_H
#define LUMESH_GEOMESH_H

#include <stdint.h>
#include "src/base/util.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum mesh_edge_kind {
    MESH_EDGE_INTERIOR = 0,  /* exactly one other triangle across, consistently wound, same normals */
    MESH_EDGE_BOUNDARY,      /* no triangle across */
    MESH_EDGE_NONMANIFOLD,   /* three or more triangles, or two wound inconsistently */
    MESH_EDGE_CREASE,        /* one triangle across but shading normals differ at an end point */
    MESH_EDGE_KIND_COUNT
} mesh_edge_kind;

typedef struct mesh_geo_desc {
    const float *positions;       /* 3 floats per vertex (welded: shared corners share an id) */
    uint32_t vertex_count;
    const uint32_t *triangles;    /* 3 vertex ids per triangle */
    uint32_t triangle_count;
    const float *corner_normals;  /* 9 floats per triangle, unit shading normal per corner;
                                     NULL: no crease test */
    float crease_tolerance_deg;   /* corners' normals agree when within this angle; 0 = 0.5;
                                     valid 0..180. Normals need not be unit length; a zero or
                                     non-finite one agrees only with an identical vector. */
} mesh_geo_desc;

typedef struct mesh_geo_stats {
    /* Counted per triangle side: an interior edge has two sides, a boundary one. */
    uint32_t sides[MESH_EDGE_KIND_COUNT];
    uint32_t rejected_triangles;  /* triangles OpenMesh could not join to the manifold mesh */
} mesh_geo_stats;

typedef struct mesh_geo mesh_geo;

lm_result mesh_geo_create(const mesh_geo_desc *desc, mesh_geo **out, lm_error *err);
void mesh_geo_destroy(mesh_geo *g); /* NULL is a no-op */

/* The triangle across edge `edge` (0..2) of `tri`, or -1. */
int32_t mesh_geo_neighbor(const mesh_geo *g, uint32_t tri, int edge);
/* Which edge (0..2) of the neighbour is the shared one, or -1 when there is no neighbour. */
int mesh_geo_neighbor_edge(const mesh_geo *g, uint32_t tri, int edge);
mesh_edge_kind mesh_geo_edge_kind(const mesh_geo *g, uint32_t tri, int edge);
void mesh_geo_get_stats(const mesh_geo *g, mesh_geo_stats *out);

#ifdef __cplusplus
}
#endif
#endif
