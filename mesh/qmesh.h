/* qmesh.h — one cache mesh: a forest of triangle quadtrees over scene triangles
 * (paper §4.1–4.3: "the mesh can be seen as a set of quad-trees, each quad-tree
 * being built over a triangle of the geometrical mesh").
 *
 * Each root is a scene triangle; a split cuts a leaf into four at its edge
 * midpoints, whose vertices come from the shared vertex table (vtable.h), so every
 * mesh over the same scene agrees on where its vertices are. A merge undoes a
 * split whose four children are leaves and gives the midpoints back. The mesh keeps
 * `channels` floats per vertex it uses (1: a light's G_ℓ; 3: RGB radiance or
 * irradiance) and a "sampled" flag. mesh_qmesh_leaf_triangles turns the leaves into
 * triangles without T-vertices: a leaf whose edge carries vertices of a finer
 * neighbour (across a shared scene edge or inside the same scene triangle) is
 * emitted as a fan through them.
 *
 * Usage:
 *     mesh_qmesh_desc d = {.vtable = vt, .channels = 3};   // roots: every triangle
 *     mesh_qmesh *m; lm_error err;
 *     if (mesh_qmesh_create(&d, &m, &err) != LM_OK) { puts(err.msg); }
 *     uint32_t root = mesh_qmesh_root(m, tri);
 *     if (mesh_qmesh_split(m, root, &err) == LM_OK) {
 *         const mesh_qnode *n = mesh_qmesh_node(m, root);  // n->child .. n->child+3
 *         float rgb[3] = {1, 0.5f, 0.25f};
 *         mesh_qmesh_set_value(m, mesh_qmesh_node(m, n->child)->v[1], rgb, &err);
 *         mesh_qmesh_interpolate(m, tri, 0.25, 0.25, rgb, &err);
 *         mesh_qmesh_merge(m, root, &err);
 *     }
 *     mesh_qmesh_destroy(m);                               // before the vtable
 *     // or roots only where needed: {.no_roots = 1}, then mesh_qmesh_add_roots(m, tris, n, NULL, &err)
 *
 * Does NOT do: deciding where to split (criteria, priorities: the scheduler),
 * sampling, publishing to the display thread, T-vertex repair across crease or
 * boundary edges (each side keeps its own vertices there; positions are still
 * bit-identical, see vtable.c fill_vertex), shrinking its pools.
 *
 * Threads: a mesh, like its vtable, belongs to one thread — the refinement worker.
 * No call is thread safe. The display reads published copies (made elsewhere).
 */
#ifndef LUMESH_QMESH_H
#define LUMESH_QMESH_H

#include <stddef.h>
#include <stdint.h>
#include "mesh/vtable.h"
#include "src/base/util.h"
#include "src/scene/scene.h"

#ifdef __cplusplus
extern "C" {
#endif

#define MESH_QMESH_NONE UINT32_MAX /* "no node" */

enum {
    MESH_QMESH_DEPTHS = MESH_DEPTH_MAX + 1, /* entries of the depth histogram (0..30) */
    MESH_QMESH_CHANNELS_MAX = 3
};

/* Node flags. */
enum {
    MESH_QNODE_LIVE = 1u << 0 /* in use (clear: on the free list) */
};

/* A quadtree node. Children are wound counter-clockwise like the parent:
 * (c0, m01, m20), (m01, c1, m12), (m20, m12, c2), (m01, m12, m20). */
typedef struct mesh_qnode {
    uint32_t parent;  /* MESH_QMESH_NONE for a root */
    uint32_t child;   /* first of four consecutive nodes; MESH_QMESH_NONE for a leaf */
    uint32_t v[3];    /* corner vertex ids in the vtable */
    uint32_t tri;     /* scene triangle of its tree */
    uint32_t a0, a1;  /* corner 0's weights w[0], w[1] over 2^depth in `tri` (w[2] implied) */
    uint8_t depth;    /* 0 at a root; at most MESH_DEPTH_MAX */
    uint8_t orient;   /* 0..5: which of the lattice's six triangle shapes (see qmesh.c) */
    uint8_t flags;    /* MESH_QNODE_* */
    uint8_t pad;
} mesh_qnode;

/* Non-zero when scene triangle `tri` gets a tree (e.g. only materials with ks > 0). */
typedef int (*mesh_qmesh_root_filter)(const scene *s, uint32_t tri, void *user);

typedef struct mesh_qmesh_desc {
    mesh_vtable *vtable;          /* required; shared with other meshes; must outlive the mesh */
    const scene *scene;           /* NULL = the vtable's; if set it must be the vtable's */
    const mesh_geo *geo;          /* NULL = the vtable's; if set it must be the vtable's */
    mesh_qmesh_root_filter root_filter; /* roots: triangles it accepts ... */
    void *root_filter_user;
    const uint32_t *root_tris;    /* ... or exactly these (no duplicates); neither: all triangles */
    uint32_t root_count;
    uint32_t channels;            /* floats per vertex value: 1 or 3; 0 = 1 */
    uint32_t node_cap;            /* most nodes alive at once (roots included); 0 = no cap */
    const struct mesh_qmesh *roots_like; /* a mesh over the same vtable: where it has a root on a triangle
                                     this one takes, the root's corner ids are taken from it (no
                                     vertex table look-up: a million-triangle scene's meshes made
                                     15 million); NULL: looked up */
    int no_roots;                 /* non-zero: no roots now (filter and root_tris ignored); they come
                                     as triangles need them (mesh_qmesh_add_roots) */
} mesh_qmesh_desc;

/* One output triangle of mesh_qmesh_leaf_triangles. */
typedef struct mesh_qmesh_tri {
    uint32_t tri;        /* scene triangle */
    uint32_t leaf;       /* the leaf node it tiles */
    uint32_t v[3];       /* vtable ids, counter-clockwise like the scene triangle */
    mesh_bary bary[3];   /* each corner's address in `tri` (not necessarily reduced) */
} mesh_qmesh_tri;

typedef struct mesh_qmesh_stats {
    uint32_t roots, nodes, leaves;
    uint32_t vertices_used;       /* distinct vtable vertices this mesh references */
    uint32_t vertices_sampled;    /* of those, with a value set */
    uint32_t leaves_at_depth[MESH_QMESH_DEPTHS];
    uint64_t splits, merges;      /* since creation */
    size_t bytes_nodes;           /* node pool and root index, bytes */
    size_t bytes_values;          /* per-vertex values, flags and use counts, bytes */
    size_t bytes_vtable_share;    /* Σ over used vertices of vtable bytes/vertex ÷ holders */
    size_t bytes;                 /* the three above */
} mesh_qmesh_stats;

/* Owned by one thread, the refinement worker (the owner of its vtable too). */
typedef struct mesh_qmesh mesh_qmesh;

lm_result mesh_qmesh_create(const mesh_qmesh_desc *desc, mesh_qmesh **out, lm_error *err);
/* Roots on scene triangles tris[0..n) that have none yet, in that order (their
 * nodes after every node there is), each a leaf with its three corners; like
 * (or NULL): as desc.roots_like. The roots of a mesh made with no_roots, added
 * as triangles come to take part (the cache: what is seen and reached, issue
 * 16): in ascending order once, they are the nodes, corner ids and use counts
 * that mesh_qmesh_create makes over the same triangles. On failure the roots
 * added so far stay. */
lm_result mesh_qmesh_add_roots(mesh_qmesh *m, const uint32_t *tris, uint32_t n, const struct mesh_qmesh *like,
                               lm_error *err);
/* mesh_qmesh_add_roots on a thread of its own while another thread works on
 * another mesh of the same vertex table (the cache's first roots: the indirect
 * mesh's beside the light and direct meshes', docs/cache.md): the table is only
 * read. Every corner must have its vertex already (mesh_vtable_corner_id; else
 * LM_ERR_INVALID_ARG, the mesh unchanged by that root), and the references
 * the vertices new to this mesh owe the table are taken by
 * mesh_qmesh_take_references, on the table's thread, once the other thread is
 * done and before anything else uses the mesh (mesh_qmesh_destroy takes them
 * too). The mesh is then what mesh_qmesh_add_roots(m, tris, n, NULL) makes. */
lm_result mesh_qmesh_add_roots_apart(mesh_qmesh *m, const uint32_t *tris, uint32_t n, lm_error *err);
lm_result mesh_qmesh_take_references(mesh_qmesh *m, lm_error *err);
/* Releases the mesh's vertex references. NULL is a no-op. Worker thread only. */
void mesh_qmesh_destroy(mesh_qmesh *m);

/* Root node of scene triangle `tri`, or MESH_QMESH_NONE if it has no tree. */
uint32_t mesh_qmesh_root(const mesh_qmesh *m, uint32_t tri);
/* A live node, or NULL. Valid until the next split (the pool may move). */
const mesh_qnode *mesh_qmesh_node(const mesh_qmesh *m, uint32_t node);
/* One more than the largest node id ever handed out: per-node side arrays of this
 * many entries cover every live node. */
uint32_t mesh_qmesh_node_limit(const mesh_qmesh *m);
/* Corner c's address in the node's scene triangle, at the node's depth. */
mesh_bary mesh_qmesh_node_corner(const mesh_qnode *n, int c);

/* Splits leaf `node` into four. Errors (the mesh is unchanged): LM_ERR_INVALID_ARG
 * (not a live leaf), LM_ERR_UNSUPPORTED (depth MESH_DEPTH_MAX), LM_ERR_NO_MEMORY
 * (node cap reached, or allocation). Worker thread only. */
lm_result mesh_qmesh_split(mesh_qmesh *m, uint32_t node, lm_error *err);
/* Undoes the split of `node`, whose four children must be leaves; midpoints no other
 * node of this mesh uses lose their values and this mesh's vtable reference. */
lm_result mesh_qmesh_merge(mesh_qmesh *m, uint32_t node, lm_error *err);

/* Number of nodes of this mesh with vertex `id` as a corner (0: not used). */
uint32_t mesh_qmesh_vertex_use(const mesh_qmesh *m, uint32_t id);
/* Sets the value (`channels` floats) of a vertex this mesh uses; marks it sampled. */
lm_result mesh_qmesh_set_value(mesh_qmesh *m, uint32_t id, const float *value, lm_error *err);
/* Copies the value into out (zeros if unsampled); returns 1 if sampled, 0 if not,
 * -1 if the mesh does not use the vertex. */
int mesh_qmesh_get_value(const mesh_qmesh *m, uint32_t id, float *out);
uint32_t mesh_qmesh_channels(const mesh_qmesh *m);

/* The value at barycentric point (1-w1-w2, w1, w2) of scene triangle `tri`: descends to
 * the leaf holding it and interpolates linearly from the leaf's corners — the value a
 * fresh sample there is compared with. On a leaf edge it interpolates between the
 * nearest sampled vertices this mesh has on that edge, so it is continuous across
 * leaves of different depth and returns a vertex's own value at the vertex.
 * Unsampled corners count as zero. LM_ERR_INVALID_ARG: no tree at `tri`, or the point
 * is outside the triangle by more than 1e-6 or not finite. */
lm_result mesh_qmesh_interpolate(const mesh_qmesh *m, uint32_t tri, double w1, double w2,
                                 float *out, lm_error *err);

/* The leaf of scene triangle `tri` holding barycentric point (1-w1-w2, w1, w2),
 * and the point's barycentrics l[3] in that leaf (weights of its corners v[0..2]):
 * the descent of mesh_qmesh_interpolate, without its walk along a leaf edge.
 * Errors as mesh_qmesh_interpolate's. */
lm_result mesh_qmesh_locate(const mesh_qmesh *m, uint32_t tri, double w1, double w2, uint32_t *leaf,
                            double l[3], lm_error *err);

/* Triangles tiling every leaf without T-vertices (see the file comment), appended to
 * *buf (realloc'd as needed; the caller frees it; *buf may start NULL with *cap 0).
 * *count is set to the number written. Worker thread only. */
lm_result mesh_qmesh_leaf_triangles(const mesh_qmesh *m, mesh_qmesh_tri **buf, size_t *cap,
                                    size_t *count, lm_error *err);
/* The same in pieces, to bound the buffer: the triangles of whole leaves from
 * node *next_node on, stopping after the leaf that brings *count to max_tris or
 * more (a leaf gives at most a few dozen). *next_node is set to the node to go on
 * from, UINT32_MAX when every leaf is done (0 starts). Pieces put together are
 * mesh_qmesh_leaf_triangles' output, in its order. */
lm_result mesh_qmesh_leaf_triangles_from(const mesh_qmesh *m, uint32_t *next_node, size_t max_tris,
                                         mesh_qmesh_tri **buf, size_t *cap, size_t *count, lm_error *err);
/* The same, but a whole root (a root that is a leaf with no vertex on its edges:
 * its one triangle is the scene triangle with its three corner vertices) is not
 * emitted: bit t % 32 of whole[t / 32] is set for it instead, and *whole_count
 * counts it (the caller zeroes both first). For a client that draws such
 * triangles from the scene and the values by vertex id (mesh_qmesh_values):
 * most of a big scene's leaves at its first image (docs/cache.md, "Whole roots
 * by vertex id"). */
lm_result mesh_qmesh_split_leaf_triangles_from(const mesh_qmesh *m, uint32_t *next_node, size_t max_tris,
                                               uint32_t *whole, uint32_t *whole_count, mesh_qmesh_tri **buf,
                                               size_t *cap, size_t *count, lm_error *err);
/* The values by vertex-table id, channels per id for ids below *count (what
 * mesh_qmesh_get_value writes; 0 where the mesh uses no such vertex). Valid
 * until the mesh changes. */
const float *mesh_qmesh_values(const mesh_qmesh *m, uint32_t *count);
/* Roots that are leaves (stats.leaves_at_depth[0], O(1)): the whole roots and
 * those with a vertex on an edge, an upper bound of the first. */
uint32_t mesh_qmesh_unsplit_roots(const mesh_qmesh *m);

/* Walks every vertex (for bytes_vtable_share): statistics, not for hot paths. */
void mesh_qmesh_get_stats(const mesh_qmesh *m, mesh_qmesh_stats *out);
/* Running counts kept on every split and merge, O(1): the live nodes (stats.nodes)
 * and splits − merges since creation (stats.splits − stats.merges). */
uint32_t mesh_qmesh_node_count(const mesh_qmesh *m);
int64_t mesh_qmesh_net_splits(const mesh_qmesh *m);

/* Which mesh, and how far it has changed: serial is unique among the meshes made
 * in this process (never 0), changes counts every split, merge and value written
 * (a value written again the same counts too). Equal versions: the same leaves
 * and values, so a copy made at the first still holds (the worker's snapshots
 * skip a mesh that has not changed). NULL: {0, 0}. */
typedef struct mesh_qmesh_version {
    uint64_t serial, changes;
} mesh_qmesh_version;
mesh_qmesh_version mesh_qmesh_get_version(const mesh_qmesh *m);

#ifdef __cplusplus
}
#endif
#endif
