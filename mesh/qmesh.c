/* qmesh.c — a cache mesh as a forest of triangle quadtrees (qmesh.h; paper §4.1–4.3).
 *
 * Nodes live in one index-based pool: roots first (one per chosen scene triangle),
 * then blocks of four children, recycled through a free list of blocks; roots
 * added later (mesh_qmesh_add_roots) come after whatever nodes there are. A node
 * stores its corner-0 address (two weights over 2^depth) and an orientation rather
 * than three addresses: in the midpoint-subdivision lattice every node is one of six
 * shapes, corner1 = corner0 + D1[o], corner2 = corner0 + D2[o]. Children 0..2 keep
 * the parent's shape; the middle child 3 turns it (D1' = D2, D2' = D2 − D1), which
 * cycles through the six with period 6 (two turns of three = a half turn).
 *
 * Vertex references: the mesh holds exactly one vtable reference per vertex it uses
 * (use count > 0), so a vertex's vtable count is the number of meshes holding it —
 * which is also how the stats split a vertex's bytes between meshes. Use counts
 * count node corners over all live nodes, internal ones included.
 *
 * Crack-free output: a leaf's edge carries this mesh's vertices exactly when the
 * mesh uses the vertex at the edge's midpoint address (deeper points on the edge
 * can only exist beneath a node that made that midpoint), so the points along an
 * edge are found by recursive midpoint lookups in the vtable — with the leaf's own
 * scene triangle as the address, which shares keys with the neighbour across an
 * un-creased scene edge.
 */
#include "mesh/qmesh.h"

#include <math.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>

#include "mesh/geomesh.h"

/* D1[o], D2[o]: corner1 − corner0 and corner2 − corner0 in units of 2^-depth. */
static const int k_d1[6][3] = {{-1, 1, 0}, {-1, 0, 1}, {0, -1, 1}, {1, -1, 0}, {1, 0, -1}, {0, 1, -1}};
static const int k_d2[6][3] = {{-1, 0, 1}, {0, -1, 1}, {1, -1, 0}, {1, 0, -1}, {0, 1, -1}, {-1, 1, 0}};

struct mesh_qmesh {
    mesh_vtable *vt;
    const scene *s;
    uint32_t channels;
    uint32_t node_cap;      /* UINT32_MAX when the desc gave 0 */

    mesh_qnode *nodes;      /* [node_alloc]; roots at [0, root_count) */
    uint32_t node_hw, node_alloc;
    uint32_t *free_blocks;  /* first index of each free block of four */
    uint32_t free_count, free_alloc;
    uint32_t *root_of_tri;  /* [scene tri_count], MESH_QMESH_NONE when no tree */
    /* [scene tri_count]: vertices of depth >= 1 this mesh uses inside the triangle
     * or on its edges (an edge's vertex counts for both triangles that share it).
     * A leaf of a triangle with none has no vertex on its edges: its triangle is
     * emitted with no look-up (mesh_qmesh_leaf_triangles: most of a big scene's
     * triangles are unsplit roots, and three failed hash look-ups each made the
     * 116k box's snapshot 0.12 s). */
    uint32_t *inner_use;
    uint32_t root_count;

    /* Per vtable id, [vcap] (zeroed where no id has been; allocated: [valloc]): */
    uint32_t *use;
    float *values;          /* channels per id */
    uint8_t *sampled;
    uint32_t vcap, valloc;

    uint32_t nodes_live, leaves, used, sampled_count;
    uint32_t hist[MESH_QMESH_DEPTHS];
    uint64_t splits, merges;
    uint32_t *owed;         /* ids whose vertex-table reference is owed (mesh_qmesh_add_roots_apart) */
    uint32_t owed_count;
    size_t owed_cap;
    uint64_t serial;        /* unique among the meshes made in this process */
    uint64_t changes;       /* splits, merges and values written (mesh_qmesh_version) */
};

static _Atomic uint64_t next_serial;

mesh_bary mesh_qmesh_node_corner(const mesh_qnode *n, int c)
{
    const int64_t w[3] = {n->a0, n->a1, ((int64_t)1 << n->depth) - n->a0 - n->a1};
    mesh_bary b = {{0, 0, 0}, n->depth};
    for (int k = 0; k < 3; ++k) {
        int64_t x = w[k] + (c == 1 ? k_d1[n->orient % 6][k] : c == 2 ? k_d2[n->orient % 6][k] : 0);
        b.w[k] = (uint32_t)x;
    }
    return b;
}

/* Ids made valid (zeroed) at a time past vcap: the vertex table hands ids out
 * in order, so the arrays are touched about as far as ids are used. */
#define VCAP_STEP 4096u

static lm_result ensure_vcap(mesh_qmesh *m, uint32_t need, lm_error *err)
{
    if (need <= m->vcap) return LM_OK;
    if (need > m->valloc) {
        /* Three arrays share one uint32_t capacity (values: `channels` floats
         * per id), grown without zeroing: the doubling's new half was zeroed
         * at once, on a million-triangle scene several MB a mesh that no id
         * reached (docs/cache.md, "The first image's fresh memory"). */
        size_t ncap = lm_grow_capacity(m->valloc, need, 256, UINT32_MAX);
        if (!lm_realloc_array_raw(&m->use, m->valloc, ncap, sizeof *m->use) ||
            !lm_realloc_array_raw(&m->values, m->valloc, ncap, m->channels * sizeof *m->values) ||
            !lm_realloc_array_raw(&m->sampled, m->valloc, ncap, sizeof *m->sampled))
            return lm_fail(err, LM_ERR_NO_MEMORY, "cache mesh: out of memory for %zu vertex values", ncap);
        m->valloc = (uint32_t)ncap;
    }
    /* Zeroed from vcap up to need, rounded up by VCAP_STEP within the room. */
    const uint64_t step_up = ((uint64_t)need + VCAP_STEP - 1) / VCAP_STEP * VCAP_STEP;
    const uint32_t upto = step_up < m->valloc ? (uint32_t)step_up : m->valloc;
    const size_t from = m->vcap, count = (size_t)upto - from;
    memset(m->use + from, 0, count * sizeof *m->use);
    memset(m->values + from * m->channels, 0, count * m->channels * sizeof *m->values);
    memset(m->sampled + from, 0, count * sizeof *m->sampled);
    m->vcap = upto;
    return LM_OK;
}

/* Gets the vertex at `p` with one vtable reference held by this mesh. *fresh says
 * whether this mesh did not use it yet (then the reference is new and must be
 * released if the caller backs out); otherwise the extra reference was returned. */
static lm_result take_vertex(mesh_qmesh *m, uint32_t tri, mesh_bary p, uint32_t *id, int *fresh,
                             lm_error *err)
{
    lm_result r = mesh_vtable_acquire(m->vt, tri, p, id, err);
    if (r != LM_OK) return r;
    r = ensure_vcap(m, *id + 1, err);
    if (r != LM_OK) {
        mesh_vtable_release(m->vt, *id, NULL);
        return r;
    }
    *fresh = m->use[*id] == 0;
    if (!*fresh) mesh_vtable_release(m->vt, *id, NULL); /* we already hold one: never frees */
    return LM_OK;
}

/* Counts vertex id (newly used: +1, no longer: -1) in inner_use. */
static void inner_count(mesh_qmesh *m, uint32_t id, int d)
{
    const mesh_vertex *v = mesh_vtable_vertex(m->vt, id);
    if (!v || v->bary.depth == 0) return; /* a corner of the scene triangle */
    m->inner_use[v->tri] += (uint32_t)d;
    const int z = v->bary.w[0] == 0 ? 0 : v->bary.w[1] == 0 ? 1 : v->bary.w[2] == 0 ? 2 : -1;
    const mesh_geo *g = mesh_vtable_geo(m->vt);
    if (z < 0 || !g) return;
    const int e = (z + 1) % 3; /* the edge opposite corner z (as mesh_vtable keys it) */
    if (mesh_geo_edge_kind(g, v->tri, e) != MESH_EDGE_INTERIOR) return; /* not shared */
    const int32_t nb = mesh_geo_neighbor(g, v->tri, e);
    if (nb >= 0 && (uint32_t)nb < m->s->tri_count) m->inner_use[nb] += (uint32_t)d;
}

static void use_add(mesh_qmesh *m, uint32_t id, uint32_t n)
{
    if (m->use[id] == 0) {
        m->used++;
        inner_count(m, id, 1);
    }
    m->use[id] += n;
}

/* Drops n uses; at zero the value goes and this mesh's vtable reference with it. */
static void use_drop(mesh_qmesh *m, uint32_t id, uint32_t n)
{
    m->use[id] -= n;
    if (m->use[id] > 0) return;
    m->used--;
    inner_count(m, id, -1);
    if (m->sampled[id]) m->sampled_count--;
    m->sampled[id] = 0;
    memset(m->values + (size_t)id * m->channels, 0, m->channels * sizeof *m->values);
    mesh_vtable_release(m->vt, id, NULL);
}

static int accept_all(const scene *s, uint32_t tri, void *user)
{
    (void)s, (void)tri, (void)user;
    return 1;
}

/* Whether `like` is roots alone (never split) over exactly the triangles that m
 * chose (marked 0 in m->root_of_tri). */
static int same_roots(const mesh_qmesh *m, const mesh_qmesh *like)
{
    if (like->node_hw != like->root_count || like->nodes_live != like->root_count) return 0;
    uint32_t n = 0;
    for (uint32_t t = 0; t < m->s->tri_count; ++t) {
        const int mine = m->root_of_tri[t] != MESH_QMESH_NONE, theirs = like->root_of_tri[t] != MESH_QMESH_NONE;
        if (mine != theirs) return 0;
        n += (uint32_t)mine;
    }
    return n == like->root_count;
}

/* m's roots as like's, which are the same triangles (same_roots): the nodes, the
 * corner ids and their use counts copied, one vertex-table reference taken per
 * vertex. What the loop in mesh_qmesh_create makes, without its per-corner work
 * (on a million-triangle scene 0.04-0.05 s a mesh instead of 0.07-0.08). */
static lm_result clone_roots(mesh_qmesh *m, const mesh_qmesh *like, lm_error *err)
{
    const uint32_t n = like->root_count;
    memcpy(m->nodes, like->nodes, (size_t)n * sizeof *m->nodes);
    memcpy(m->root_of_tri, like->root_of_tri, (size_t)m->s->tri_count * sizeof *m->root_of_tri);
    memcpy(m->inner_use, like->inner_use, ((size_t)m->s->tri_count + 1) * sizeof *m->inner_use);
    uint32_t top = like->vcap;
    while (top > 0 && like->use[top - 1] == 0) --top;
    lm_result r = ensure_vcap(m, top, err);
    for (uint32_t id = 0; r == LM_OK && id < top; ++id) {
        if (!like->use[id]) continue;
        r = mesh_vtable_retain(m->vt, id, err);
        if (r != LM_OK) break; /* destroy releases the ids whose use is set */
        m->use[id] = like->use[id];
        m->used++;
    }
    if (r != LM_OK) return r;
    m->root_count = m->node_hw = m->nodes_live = m->leaves = m->hist[0] = n;
    return LM_OK;
}

/* A root on scene triangle t (which has none), as node node_hw: its corners'
 * ids from like where it has a root on t (the same corners in the same order: a
 * root is (a0 1, orient 0)), else looked up. */
/* Node node_hw written as a root on t (corners left to the caller), not yet
 * counted: count_root does that once its corners are held. */
static mesh_qnode *new_root(mesh_qmesh *m, uint32_t t)
{
    mesh_qnode *n = &m->nodes[m->node_hw];
    *n = (mesh_qnode){.parent = MESH_QMESH_NONE, .child = MESH_QMESH_NONE, .tri = t, .a0 = 1,
                      .a1 = 0, .depth = 0, .orient = 0, .flags = MESH_QNODE_LIVE};
    return n;
}

static void count_root(mesh_qmesh *m, uint32_t t)
{
    m->root_of_tri[t] = m->node_hw;
    m->root_count++, m->node_hw++, m->nodes_live++, m->leaves++, m->hist[0]++;
}

/* Room in the pool for n more roots at once: a first set of a million roots
 * grows it once, to its size, as mesh_qmesh_create does. */
static lm_result reserve_roots(mesh_qmesh *m, uint32_t n, lm_error *err)
{
    if (!n || (size_t)m->node_hw + n <= m->node_alloc) return LM_OK;
    size_t na = (size_t)m->node_hw + n;
    if (na > UINT32_MAX - 4 || !lm_realloc_array_raw(&m->nodes, m->node_alloc, na, sizeof *m->nodes))
        return lm_fail(err, LM_ERR_NO_MEMORY, "cache mesh: out of memory for %zu nodes", na);
    m->node_alloc = (uint32_t)na;
    return LM_OK;
}

static lm_result add_root(mesh_qmesh *m, uint32_t t, const mesh_qmesh *like_mesh, lm_error *err)
{
    if (m->nodes_live >= m->node_cap)
        return lm_fail(err, LM_ERR_INVALID_ARG, "cache mesh: a root past the node cap of %u", m->node_cap);
    if (m->node_hw >= m->node_alloc) { /* roots made later (mesh_qmesh_add_roots) */
        size_t na = lm_grow_capacity(m->node_alloc, (size_t)m->node_hw + 1, 16, UINT32_MAX - 4);
        if (!na || !lm_realloc_array_raw(&m->nodes, m->node_alloc, na, sizeof *m->nodes))
            return lm_fail(err, LM_ERR_NO_MEMORY, "cache mesh: out of memory for %zu nodes", na);
        m->node_alloc = (uint32_t)na;
    }
    mesh_qnode *n = new_root(m, t);
    const uint32_t like = like_mesh ? like_mesh->root_of_tri[t] : MESH_QMESH_NONE;
    for (int c = 0; c < 3; ++c) {
        int fresh;
        lm_result r;
        /* The corner's vertex, if it is there already: like's, or the scene
         * corner's by its normal class (no key); held once more. */
        n->v[c] = like != MESH_QMESH_NONE ? like_mesh->nodes[like].v[c] : mesh_vtable_corner_id(m->vt, t, c);
        if (n->v[c] != MESH_VTABLE_NONE) {
            r = ensure_vcap(m, n->v[c] + 1, err);
            fresh = r == LM_OK && m->use[n->v[c]] == 0;
            if (fresh) r = mesh_vtable_retain(m->vt, n->v[c], err);
        } else {
            r = take_vertex(m, t, mesh_qmesh_node_corner(n, c), &n->v[c], &fresh, err);
        }
        if (r != LM_OK) { /* the corners taken so far given back: no half-made root */
            for (int k = 0; k < c; ++k) use_drop(m, n->v[k], 1);
            return r;
        }
        use_add(m, n->v[c], 1);
    }
    count_root(m, t);
    return LM_OK;
}

lm_result mesh_qmesh_add_roots(mesh_qmesh *m, const uint32_t *tris, uint32_t n, const mesh_qmesh *like,
                               lm_error *err)
{
    if (!m || (n && !tris)) return lm_fail(err, LM_ERR_INVALID_ARG, "cache mesh: add_roots needs a mesh and triangles");
    const mesh_qmesh *like_mesh = like && like->vt == m->vt ? like : NULL;
    lm_result rr = reserve_roots(m, n, err);
    if (rr != LM_OK) return rr;
    /* The first roots of a mesh, exactly like's (never split): copied whole, as
     * mesh_qmesh_create does (clone_roots; the indirect mesh like the direct one). */
    if (like_mesh && m->node_hw == 0 && n && n == like_mesh->root_count && like_mesh->node_hw == n &&
        like_mesh->nodes_live == n) {
        int same = 1;
        for (uint32_t i = 0; i < n && same; ++i) same = tris[i] < m->s->tri_count && like_mesh->nodes[i].tri == tris[i];
        if (same) {
            lm_result r = clone_roots(m, like_mesh, err);
            if (r == LM_OK) m->changes += n;
            return r;
        }
    }
    for (uint32_t i = 0; i < n; ++i) {
        const uint32_t t = tris[i];
        if (t >= m->s->tri_count)
            return lm_fail(err, LM_ERR_INVALID_ARG, "cache mesh: a root on triangle %u of %u", t, m->s->tri_count);
        if (m->root_of_tri[t] != MESH_QMESH_NONE) continue;
        lm_result r = add_root(m, t, like_mesh, err);
        if (r != LM_OK) return r;
        m->changes++; /* a new leaf: what a snapshot of the mesh holds changed (mesh_qmesh_version) */
    }
    return LM_OK;
}

/* A root on t for mesh_qmesh_add_roots_apart (the pool has room): its corners
 * the scene corners' vertices, the references of those new to the mesh owed.
 * Checked before anything changes, so a failure leaves the mesh as it was. */
static lm_result add_root_apart(mesh_qmesh *m, uint32_t t, lm_error *err)
{
    if (m->nodes_live >= m->node_cap)
        return lm_fail(err, LM_ERR_INVALID_ARG, "cache mesh: a root past the node cap of %u", m->node_cap);
    uint32_t v[3], top = 0;
    for (int c = 0; c < 3; ++c) {
        v[c] = mesh_vtable_corner_id(m->vt, t, c);
        if (v[c] == MESH_VTABLE_NONE)
            return lm_fail(err, LM_ERR_INVALID_ARG, "cache mesh: corner %d of triangle %u has no vertex to share", c, t);
        if (v[c] + 1 > top) top = v[c] + 1;
    }
    lm_result r = ensure_vcap(m, top, err);
    if (r != LM_OK) return r;
    if (!LM_GROW(m->owed, m->owed_cap, (size_t)m->owed_count + 3))
        return lm_fail(err, LM_ERR_NO_MEMORY, "cache mesh: out of memory adding roots");
    mesh_qnode *n = new_root(m, t);
    for (int c = 0; c < 3; ++c) {
        n->v[c] = v[c];
        if (m->use[v[c]] == 0) m->owed[m->owed_count++] = v[c];
        use_add(m, v[c], 1);
    }
    count_root(m, t);
    m->changes++;
    return LM_OK;
}

lm_result mesh_qmesh_add_roots_apart(mesh_qmesh *m, const uint32_t *tris, uint32_t n, lm_error *err)
{
    if (!m || (n && !tris)) return lm_fail(err, LM_ERR_INVALID_ARG, "cache mesh: add_roots needs a mesh and triangles");
    lm_result rr = reserve_roots(m, n, err);
    if (rr != LM_OK) return rr;
    for (uint32_t i = 0; i < n; ++i) {
        const uint32_t t = tris[i];
        if (t >= m->s->tri_count)
            return lm_fail(err, LM_ERR_INVALID_ARG, "cache mesh: a root on triangle %u of %u", t, m->s->tri_count);
        if (m->root_of_tri[t] != MESH_QMESH_NONE) continue;
        lm_result r = add_root_apart(m, t, err);
        if (r != LM_OK) return r;
    }
    return LM_OK;
}

lm_result mesh_qmesh_take_references(mesh_qmesh *m, lm_error *err)
{
    if (!m) return LM_OK;
    lm_result r = LM_OK;
    for (uint32_t i = 0; i < m->owed_count; ++i) {
        lm_result ri = mesh_vtable_retain(m->vt, m->owed[i], err);
        if (r == LM_OK) r = ri;
    }
    m->owed_count = 0;
    return r;
}

lm_result mesh_qmesh_create(const mesh_qmesh_desc *desc, mesh_qmesh **out, lm_error *err)
{
    if (out) *out = NULL;
    if (!desc || !out || !desc->vtable)
        return lm_fail(err, LM_ERR_INVALID_ARG, "cache mesh: desc, desc->vtable and out are required");
    const scene *s = mesh_vtable_scene(desc->vtable);
    if ((desc->scene && desc->scene != s) || (desc->geo && desc->geo != mesh_vtable_geo(desc->vtable)))
        return lm_fail(err, LM_ERR_INVALID_ARG,
                       "cache mesh: scene and geometric mesh must be the vertex table's");
    uint32_t channels = desc->channels ? desc->channels : 1;
    if (channels != 1 && channels != 3)
        return lm_fail(err, LM_ERR_INVALID_ARG, "cache mesh: %u channels; 1 or 3 are supported", channels);
    if (desc->root_count && !desc->root_tris)
        return lm_fail(err, LM_ERR_INVALID_ARG, "cache mesh: root_count %u with no root_tris",
                       desc->root_count);

    mesh_qmesh *m = calloc(1, sizeof *m);
    if (!m) return lm_fail(err, LM_ERR_NO_MEMORY, "cache mesh: out of memory");
    m->serial = atomic_fetch_add(&next_serial, 1) + 1;
    m->vt = desc->vtable;
    m->s = s;
    m->channels = channels;
    m->node_cap = desc->node_cap ? desc->node_cap : UINT32_MAX;
    lm_result r = LM_OK;
    m->root_of_tri = malloc(((size_t)s->tri_count + 1) * sizeof *m->root_of_tri);
    m->inner_use = calloc((size_t)s->tri_count + 1, sizeof *m->inner_use);
    if (!m->root_of_tri || !m->inner_use) {
        r = lm_fail(err, LM_ERR_NO_MEMORY, "cache mesh: out of memory");
        goto fail;
    }
    for (uint32_t t = 0; t < s->tri_count; ++t) m->root_of_tri[t] = MESH_QMESH_NONE;

    /* Choose the roots; root_of_tri temporarily marks chosen triangles with 0. */
    uint32_t nroots = 0;
    if (desc->no_roots) {
        /* none now: mesh_qmesh_add_roots */
    } else if (desc->root_tris) {
        for (uint32_t i = 0; i < desc->root_count; ++i) {
            uint32_t t = desc->root_tris[i];
            if (t >= s->tri_count) {
                r = lm_fail(err, LM_ERR_INVALID_ARG, "cache mesh: root %u is triangle %u of %u", i, t,
                            s->tri_count);
                goto fail;
            }
            if (m->root_of_tri[t] != MESH_QMESH_NONE) {
                r = lm_fail(err, LM_ERR_INVALID_ARG, "cache mesh: triangle %u is a root twice", t);
                goto fail;
            }
            m->root_of_tri[t] = 0;
            nroots++;
        }
    } else {
        mesh_qmesh_root_filter f = desc->root_filter ? desc->root_filter : accept_all;
        for (uint32_t t = 0; t < s->tri_count; ++t)
            if (f(s, t, desc->root_filter_user)) m->root_of_tri[t] = 0, nroots++;
    }
    if (nroots > m->node_cap) {
        r = lm_fail(err, LM_ERR_INVALID_ARG, "cache mesh: %u roots exceed the node cap of %u", nroots,
                    m->node_cap);
        goto fail;
    }
    m->node_alloc = nroots > 16 ? nroots : 16;
    m->nodes = calloc(m->node_alloc, sizeof *m->nodes);
    if (!m->nodes) {
        r = lm_fail(err, LM_ERR_NO_MEMORY, "cache mesh: out of memory for %u roots", nroots);
        goto fail;
    }
    const mesh_qmesh *like_mesh =
        !desc->no_roots && desc->roots_like && desc->roots_like->vt == m->vt ? desc->roots_like : NULL;
    if (like_mesh && same_roots(m, like_mesh)) {
        r = clone_roots(m, like_mesh, err);
        if (r != LM_OK) goto fail;
        *out = m;
        return LM_OK;
    }
    /* Roots in triangle order, so node ids do not depend on root_tris order. */
    for (uint32_t t = 0; t < s->tri_count; ++t) {
        if (m->root_of_tri[t] == MESH_QMESH_NONE) continue;
        m->root_of_tri[t] = MESH_QMESH_NONE;
        r = add_root(m, t, like_mesh, err);
        if (r != LM_OK) goto fail; /* destroy releases what the roots so far hold */
    }
    *out = m;
    return LM_OK;
fail:
    mesh_qmesh_destroy(m); /* releases the vertices the roots made so far hold */
    return r;
}

void mesh_qmesh_destroy(mesh_qmesh *m)
{
    if (!m) return;
    mesh_qmesh_take_references(m, NULL); /* each use below then holds one */
    free(m->owed);
    for (uint32_t id = 0; id < m->vcap; ++id)
        if (m->use[id] > 0) mesh_vtable_release(m->vt, id, NULL);
    free(m->nodes);
    free(m->free_blocks);
    free(m->root_of_tri);
    free(m->inner_use);
    free(m->use);
    free(m->values);
    free(m->sampled);
    free(m);
}

uint32_t mesh_qmesh_root(const mesh_qmesh *m, uint32_t tri)
{
    return m && tri < m->s->tri_count ? m->root_of_tri[tri] : MESH_QMESH_NONE;
}

const mesh_qnode *mesh_qmesh_node(const mesh_qmesh *m, uint32_t node)
{
    if (!m || node >= m->node_hw || !(m->nodes[node].flags & MESH_QNODE_LIVE)) return NULL;
    return &m->nodes[node];
}

uint32_t mesh_qmesh_node_limit(const mesh_qmesh *m)
{
    return m ? m->node_hw : 0;
}

/* A block of four free nodes (the pool grows by doubling when none is free). */
static lm_result alloc_block(mesh_qmesh *m, uint32_t *first, lm_error *err)
{
    if (m->free_count) {
        *first = m->free_blocks[--m->free_count];
        return LM_OK;
    }
    if (m->node_hw > UINT32_MAX - 8)
        return lm_fail(err, LM_ERR_NO_MEMORY, "cache mesh: node id space exhausted");
    if (m->node_hw + 4 > m->node_alloc) { /* a uint32_t capacity */
        size_t na = lm_grow_capacity(m->node_alloc, (size_t)m->node_hw + 4, 16, UINT32_MAX - 4);
        /* Not zeroed: a node past node_hw is never read, and a block is written
         * whole when it is taken (mesh_qmesh_split). A million roots' first split
         * zeroed 37 MB a mesh, the first touch of pages it would not use for
         * a long time (docs/cache.md, "The first image's fresh memory"). */
        if (!na || !lm_realloc_array_raw(&m->nodes, m->node_alloc, na, sizeof *m->nodes))
            return lm_fail(err, LM_ERR_NO_MEMORY, "cache mesh: out of memory for %zu nodes", na);
        m->node_alloc = (uint32_t)na;
    }
    /* Room on the free list for every block there is, so merge never allocates. */
    const uint32_t blocks = (m->node_hw + 4 - m->root_count) / 4;
    if (blocks > m->free_alloc) {
        size_t fa = lm_grow_capacity(m->free_alloc, blocks, 64, UINT32_MAX);
        if (!lm_realloc_array_raw(&m->free_blocks, m->free_alloc, fa, sizeof *m->free_blocks)) /* a stack */
            return lm_fail(err, LM_ERR_NO_MEMORY, "cache mesh: out of memory for the free list");
        m->free_alloc = (uint32_t)fa;
    }
    *first = m->node_hw;
    m->node_hw += 4;
    return LM_OK;
}

lm_result mesh_qmesh_split(mesh_qmesh *m, uint32_t node, lm_error *err)
{
    const mesh_qnode *pn = mesh_qmesh_node(m, node);
    if (!pn) return lm_fail(err, LM_ERR_INVALID_ARG, "cache mesh: split of a dead node %u", node);
    if (pn->child != MESH_QMESH_NONE)
        return lm_fail(err, LM_ERR_INVALID_ARG, "cache mesh: split of node %u, which is not a leaf", node);
    if (pn->depth >= MESH_DEPTH_MAX)
        return lm_fail(err, LM_ERR_UNSUPPORTED, "cache mesh: node %u is at the depth limit of %d",
                       node, MESH_DEPTH_MAX);
    if ((uint64_t)m->nodes_live + 4 > m->node_cap)
        return lm_fail(err, LM_ERR_NO_MEMORY, "cache mesh: node cap of %u reached", m->node_cap);

    const mesh_qnode p = *pn; /* the pool may move below */
    mesh_bary c[3], mid[3];
    for (int k = 0; k < 3; ++k) c[k] = mesh_qmesh_node_corner(&p, k);
    uint32_t mv[3];
    int fresh[3] = {0, 0, 0}, got = 0;
    lm_result r = LM_OK;
    for (; got < 3; ++got) { /* mid[e] is the midpoint of edge e: m01, m12, m20 */
        r = mesh_bary_midpoint(c[got], c[(got + 1) % 3], &mid[got]);
        if (r == LM_OK) r = take_vertex(m, p.tri, mid[got], &mv[got], &fresh[got], err);
        if (r != LM_OK) break;
    }
    uint32_t first = 0;
    if (r == LM_OK) r = alloc_block(m, &first, err);
    if (r != LM_OK) {
        while (got-- > 0)
            if (fresh[got]) mesh_vtable_release(m->vt, mv[got], NULL);
        return r;
    }
    /* Commit. Children's corner-0 weights (over 2^(depth+1)) and orientations. */
    const mesh_bary anchor[4] = {{{2 * c[0].w[0], 2 * c[0].w[1], 2 * c[0].w[2]}, p.depth + 1u},
                                 mid[0], mid[2], mid[0]};
    const uint32_t cv[4][3] = {{p.v[0], mv[0], mv[2]}, {mv[0], p.v[1], mv[1]},
                               {mv[2], mv[1], p.v[2]}, {mv[0], mv[1], mv[2]}};
    for (int k = 0; k < 4; ++k) {
        mesh_qnode *ch = &m->nodes[first + (uint32_t)k];
        *ch = (mesh_qnode){.parent = node, .child = MESH_QMESH_NONE, .tri = p.tri,
                           .a0 = anchor[k].w[0], .a1 = anchor[k].w[1],
                           .depth = (uint8_t)(p.depth + 1),
                           .orient = (uint8_t)(k == 3 ? (p.orient + 1) % 6 : p.orient),
                           .flags = MESH_QNODE_LIVE};
        memcpy(ch->v, cv[k], sizeof ch->v);
    }
    m->nodes[node].child = first;
    for (int k = 0; k < 3; ++k) use_add(m, p.v[k], 1);
    for (int k = 0; k < 3; ++k) use_add(m, mv[k], 3);
    m->nodes_live += 4;
    m->leaves += 3;
    m->hist[p.depth]--;
    m->hist[p.depth + 1] += 4;
    m->splits++;
    m->changes++;
    return LM_OK;
}

lm_result mesh_qmesh_merge(mesh_qmesh *m, uint32_t node, lm_error *err)
{
    const mesh_qnode *pn = mesh_qmesh_node(m, node);
    if (!pn) return lm_fail(err, LM_ERR_INVALID_ARG, "cache mesh: merge of a dead node %u", node);
    if (pn->child == MESH_QMESH_NONE)
        return lm_fail(err, LM_ERR_INVALID_ARG, "cache mesh: merge of leaf %u", node);
    const uint32_t first = pn->child;
    for (uint32_t k = 0; k < 4; ++k)
        if (m->nodes[first + k].child != MESH_QMESH_NONE)
            return lm_fail(err, LM_ERR_INVALID_ARG,
                           "cache mesh: merge of node %u, whose child %u is split", node, first + k);
    const mesh_qnode *mid = &m->nodes[first + 3]; /* (m01, m12, m20) */
    const uint32_t mv[3] = {mid->v[0], mid->v[1], mid->v[2]};
    for (int k = 0; k < 3; ++k) use_drop(m, pn->v[k], 1);
    /* Reverse order of the split's acquisitions: the vtable's id stack comes back
     * exactly as it was when the split took fresh vertices off it. */
    for (int k = 2; k >= 0; --k) use_drop(m, mv[k], 3);
    for (uint32_t k = 0; k < 4; ++k) m->nodes[first + k].flags = 0;
    m->free_blocks[m->free_count++] = first; /* room reserved below, never fails */
    m->nodes[node].child = MESH_QMESH_NONE;
    m->nodes_live -= 4;
    m->leaves -= 3;
    m->hist[pn->depth + 1] -= 4;
    m->hist[pn->depth]++;
    m->merges++;
    m->changes++;
    return LM_OK;
}

uint32_t mesh_qmesh_vertex_use(const mesh_qmesh *m, uint32_t id)
{
    return m && id < m->vcap ? m->use[id] : 0;
}

uint32_t mesh_qmesh_channels(const mesh_qmesh *m) { return m ? m->channels : 0; }

lm_result mesh_qmesh_set_value(mesh_qmesh *m, uint32_t id, const float *value, lm_error *err)
{
    if (!m || !value) return lm_fail(err, LM_ERR_INVALID_ARG, "cache mesh: NULL argument");
    if (mesh_qmesh_vertex_use(m, id) == 0)
        return lm_fail(err, LM_ERR_INVALID_ARG, "cache mesh: vertex %u is not in this mesh", id);
    memcpy(m->values + (size_t)id * m->channels, value, m->channels * sizeof *value);
    if (!m->sampled[id]) m->sampled_count++;
    m->sampled[id] = 1;
    m->changes++;
    return LM_OK;
}

int mesh_qmesh_get_value(const mesh_qmesh *m, uint32_t id, float *out)
{
    if (mesh_qmesh_vertex_use(m, id) == 0) return -1;
    if (out) memcpy(out, m->values + (size_t)id * m->channels, m->channels * sizeof *out);
    return m->sampled[id];
}

/* The id of this mesh's vertex at address p of `tri`, or MESH_VTABLE_NONE. */
static uint32_t used_at(const mesh_qmesh *m, uint32_t tri, mesh_bary p)
{
    uint32_t id = mesh_vtable_find(m->vt, tri, p);
    return id != MESH_VTABLE_NONE && id < m->vcap && m->use[id] > 0 ? id : MESH_VTABLE_NONE;
}

lm_result mesh_qmesh_locate(const mesh_qmesh *m, uint32_t tri, double w1, double w2, uint32_t *leaf_out,
                            double l_out[3], lm_error *err)
{
    const uint32_t root = mesh_qmesh_root(m, tri);
    if (root == MESH_QMESH_NONE || !leaf_out || !l_out)
        return lm_fail(err, LM_ERR_INVALID_ARG, "cache mesh: no tree at triangle %u", tri);
    double l[3] = {1.0 - w1 - w2, w1, w2};
    double sum = 0.0;
    for (int k = 0; k < 3; ++k) {
        if (!isfinite(l[k]) || l[k] < -1e-6)
            return lm_fail(err, LM_ERR_INVALID_ARG,
                           "cache mesh: point (%g, %g) is outside triangle %u", w1, w2, tri);
        if (l[k] < 0.0) l[k] = 0.0;
        sum += l[k];
    }
    for (int k = 0; k < 3; ++k) l[k] /= sum;
    /* Descend, keeping l as barycentrics within the current node (see the header of
     * each branch: the child's corners expressed through the parent's). */
    uint32_t n = root;
    while (m->nodes[n].child != MESH_QMESH_NONE) {
        const uint32_t f = m->nodes[n].child;
        if (l[0] >= 0.5) { /* (c0, m01, m20) */
            l[0] = 2 * l[0] - 1, l[1] *= 2, l[2] *= 2, n = f;
        } else if (l[1] >= 0.5) { /* (m01, c1, m12) */
            l[0] *= 2, l[1] = 2 * l[1] - 1, l[2] *= 2, n = f + 1;
        } else if (l[2] >= 0.5) { /* (m20, m12, c2) */
            l[0] *= 2, l[1] *= 2, l[2] = 2 * l[2] - 1, n = f + 2;
        } else { /* (m01, m12, m20) */
            const double a = 1 - 2 * l[2], b = 1 - 2 * l[0], c = 1 - 2 * l[1];
            l[0] = a, l[1] = b, l[2] = c, n = f + 3;
        }
    }
    *leaf_out = n;
    memcpy(l_out, l, sizeof l);
    return LM_OK;
}

lm_result mesh_qmesh_interpolate(const mesh_qmesh *m, uint32_t tri, double w1, double w2,
                                 float *out, lm_error *err)
{
    uint32_t n;
    double l[3];
    if (!out) return lm_fail(err, LM_ERR_INVALID_ARG, "cache mesh: no output");
    lm_result r = mesh_qmesh_locate(m, tri, w1, w2, &n, l, err);
    if (r != LM_OK) return r;
    const mesh_qnode *leaf = &m->nodes[n];
    const uint32_t ch = m->channels;
    int zero = -1, zeros = 0;
    for (int k = 0; k < 3; ++k)
        if (l[k] <= 0.0) zero = k, zeros++;
    if (zeros == 1) {
        /* On the edge opposite corner `zero`: walk down the midpoints this mesh has
         * (and has sampled) there, to the finest segment holding the point. */
        const int ka = (zero + 1) % 3, kb = (zero + 2) % 3;
        mesh_bary A = mesh_qmesh_node_corner(leaf, ka), B = mesh_qmesh_node_corner(leaf, kb);
        uint32_t va = leaf->v[ka], vb = leaf->v[kb];
        double s = l[kb] / (l[ka] + l[kb]);
        for (;;) {
            mesh_bary mid;
            if (mesh_bary_midpoint(A, B, &mid) != LM_OK) break;
            const uint32_t id = used_at(m, tri, mid);
            if (id == MESH_VTABLE_NONE || !m->sampled[id]) break;
            if (s == 0.5) {
                memcpy(out, m->values + (size_t)id * ch, ch * sizeof *out);
                return LM_OK;
            }
            if (s < 0.5) B = mid, vb = id, s = 2 * s;
            else A = mid, va = id, s = 2 * s - 1;
        }
        for (uint32_t c = 0; c < ch; ++c)
            out[c] = (float)((1 - s) * m->values[(size_t)va * ch + c] + s * m->values[(size_t)vb * ch + c]);
        return LM_OK;
    }
    for (uint32_t c = 0; c < ch; ++c) {
        double acc = 0.0;
        for (int k = 0; k < 3; ++k) acc += l[k] * m->values[(size_t)leaf->v[k] * ch + c];
        out[c] = (float)acc;
    }
    return LM_OK;
}

/* ---- crack-free leaf triangles ---- */

typedef struct pt {
    uint32_t id;
    mesh_bary b;
} pt;

typedef struct emitter {
    const mesh_qmesh *m;
    uint32_t tri, leaf;
    mesh_qmesh_tri **buf;
    size_t *cap, count;
    pt *line; /* scratch: points along one edge */
    size_t line_len, line_cap;
    lm_result r;
    lm_error *err;
} emitter;

static void emit(emitter *e, pt a, pt b, pt c)
{
    if (e->r != LM_OK) return;
    if (e->count == *e->cap && !LM_GROW_RAW(*e->buf, *e->cap, e->count + 1)) { /* appended */
        e->r = lm_fail(e->err, LM_ERR_NO_MEMORY, "cache mesh: out of memory for %zu triangles", e->count + 1);
        return;
    }
    mesh_qmesh_tri *t = &(*e->buf)[e->count++];
    t->tri = e->tri, t->leaf = e->leaf;
    t->v[0] = a.id, t->v[1] = b.id, t->v[2] = c.id;
    t->bary[0] = a.b, t->bary[1] = b.b, t->bary[2] = c.b;
}

static void line_push(emitter *e, pt p)
{
    if (e->r != LM_OK) return;
    if (e->line_len == e->line_cap && !LM_GROW_RAW(e->line, e->line_cap, e->line_len + 1)) {
        e->r = lm_fail(e->err, LM_ERR_NO_MEMORY, "cache mesh: out of memory");
        return;
    }
    e->line[e->line_len++] = p;
}

/* The mesh's vertex at the midpoint of a-b, if any. */
static int mid_of(const emitter *e, pt a, pt b, pt *out)
{
    if (mesh_bary_midpoint(a.b, b.b, &out->b) != LM_OK) return 0;
    out->id = used_at(e->m, e->tri, out->b);
    return out->id != MESH_VTABLE_NONE;
}

/* Pushes the mesh's vertices strictly between a and b, in order from a. */
static void collect(emitter *e, pt a, pt b)
{
    pt mid;
    if (!mid_of(e, a, b, &mid)) return;
    collect(e, a, mid);
    line_push(e, mid);
    collect(e, mid, b);
}

/* Fan from apex o over the segment a->b and the vertices on it (o, a, b CCW). */
static void fan(emitter *e, pt o, pt a, pt b)
{
    e->line_len = 0;
    line_push(e, a);
    collect(e, a, b);
    line_push(e, b);
    if (e->r != LM_OK) return;
    /* emit() never touches e->line, so iterating it while emitting is safe. */
    for (size_t i = 0; i + 1 < e->line_len; ++i) emit(e, o, e->line[i], e->line[i + 1]);
}

/* Tiles lattice triangle p (CCW) whose edges may carry vertices; its interior
 * carries none. Missing midpoint on an edge = no vertex on that edge at all. */
static void fill(emitter *e, const pt p[3])
{
    pt mid[3];
    int has[3], n = 0;
    for (int k = 0; k < 3; ++k) n += has[k] = mid_of(e, p[k], p[(k + 1) % 3], &mid[k]);
    if (n == 0) {
        emit(e, p[0], p[1], p[2]);
    } else if (n == 1) {
        const int k = has[0] ? 0 : has[1] ? 1 : 2;
        fan(e, p[(k + 2) % 3], p[k], p[(k + 1) % 3]);
    } else if (n == 2) {
        /* s: the corner between the two edges with vertices (the third edge has
         * none). Its corner child is a lattice triangle again; the rest, a quad,
         * splits along mid[s]-p[s+2] into two triangles with vertices on at most
         * one edge each, fanned from the opposite corner. */
        const int s = !has[1] ? 0 : !has[2] ? 1 : 2;
        const pt ms = mid[s], mp = mid[(s + 2) % 3]; /* on edges s and s+2 */
        const pt corner[3] = {p[s], ms, mp};
        fill(e, corner);
        fan(e, p[(s + 2) % 3], ms, p[(s + 1) % 3]);
        fan(e, ms, p[(s + 2) % 3], mp);
    } else {
        const pt c0[3] = {p[0], mid[0], mid[2]}, c1[3] = {mid[0], p[1], mid[1]},
                 c2[3] = {mid[2], mid[1], p[2]};
        fill(e, c0);
        fill(e, c1);
        fill(e, c2);
        emit(e, mid[0], mid[1], mid[2]);
    }
}

lm_result mesh_qmesh_leaf_triangles_from(const mesh_qmesh *m, uint32_t *next_node, size_t max_tris,
                                         mesh_qmesh_tri **buf, size_t *cap, size_t *count, lm_error *err)
{
    return mesh_qmesh_split_leaf_triangles_from(m, next_node, max_tris, NULL, NULL, buf, cap, count, err);
}

const float *mesh_qmesh_values(const mesh_qmesh *m, uint32_t *count)
{
    *count = m ? m->vcap : 0;
    return m ? m->values : NULL;
}

uint32_t mesh_qmesh_unsplit_roots(const mesh_qmesh *m) { return m ? m->hist[0] : 0; }

lm_result mesh_qmesh_split_leaf_triangles_from(const mesh_qmesh *m, uint32_t *next_node, size_t max_tris,
                                               uint32_t *whole, uint32_t *whole_count, mesh_qmesh_tri **buf,
                                               size_t *cap, size_t *count, lm_error *err)
{
    if (count) *count = 0;
    if (whole && !whole_count) return lm_fail(err, LM_ERR_INVALID_ARG, "cache mesh: whole roots without a count");
    if (!m || !next_node || !buf || !cap || !count)
        return lm_fail(err, LM_ERR_INVALID_ARG, "cache mesh: NULL argument to leaf_triangles");
    if (!*buf) *cap = 0;
    emitter e = {.m = m, .buf = buf, .cap = cap, .r = LM_OK, .err = err};
    uint32_t i = *next_node;
    for (; i < m->node_hw && e.r == LM_OK && e.count < max_tris; ++i) {
        const mesh_qnode *n = &m->nodes[i];
        if (!(n->flags & MESH_QNODE_LIVE) || n->child != MESH_QMESH_NONE) continue;
        if (whole && n->depth == 0 && m->inner_use[n->tri] == 0) { /* a whole root: drawn from the scene */
            whole[n->tri >> 5] |= 1u << (n->tri & 31u);
            ++*whole_count;
            continue;
        }
        e.tri = n->tri, e.leaf = i;
        pt p[3];
        for (int k = 0; k < 3; ++k) p[k].id = n->v[k], p[k].b = mesh_qmesh_node_corner(n, k);
        if (m->inner_use[n->tri] == 0)
            emit(&e, p[0], p[1], p[2]); /* no vertex on its edges: fill would find none */
        else
            fill(&e, p);
    }
    free(e.line);
    *count = e.r == LM_OK ? e.count : 0;
    if (e.r == LM_OK) *next_node = i < m->node_hw ? i : UINT32_MAX;
    return e.r;
}

lm_result mesh_qmesh_leaf_triangles(const mesh_qmesh *m, mesh_qmesh_tri **buf, size_t *cap,
                                    size_t *count, lm_error *err)
{
    uint32_t next = 0;
    return mesh_qmesh_leaf_triangles_from(m, &next, SIZE_MAX, buf, cap, count, err);
}

uint32_t mesh_qmesh_node_count(const mesh_qmesh *m) { return m ? m->nodes_live : 0; }

int64_t mesh_qmesh_net_splits(const mesh_qmesh *m) { return m ? (int64_t)m->splits - (int64_t)m->merges : 0; }

mesh_qmesh_version mesh_qmesh_get_version(const mesh_qmesh *m)
{
    return m ? (mesh_qmesh_version){m->serial, m->changes} : (mesh_qmesh_version){0, 0};
}

void mesh_qmesh_get_stats(const mesh_qmesh *m, mesh_qmesh_stats *out)
{
    if (!out) return;
    memset(out, 0, sizeof *out);
    if (!m) return;
    out->roots = m->root_count;
    out->nodes = m->nodes_live;
    out->leaves = m->leaves;
    out->vertices_used = m->used;
    out->vertices_sampled = m->sampled_count;
    memcpy(out->leaves_at_depth, m->hist, sizeof m->hist);
    out->splits = m->splits;
    out->merges = m->merges;
    out->bytes_nodes = (size_t)m->node_alloc * sizeof *m->nodes +
                       (size_t)m->free_alloc * sizeof *m->free_blocks +
                       (size_t)m->s->tri_count * (sizeof *m->root_of_tri + sizeof *m->inner_use) + sizeof *m;
    out->bytes_values = (size_t)m->valloc * (sizeof *m->use + m->channels * sizeof *m->values + 1);
    const double bpv = mesh_vtable_bytes_per_vertex(m->vt);
    double share = 0.0;
    for (uint32_t id = 0; id < m->vcap; ++id) {
        if (m->use[id] == 0) continue;
        const mesh_vertex *v = mesh_vtable_vertex(m->vt, id);
        share += v && v->refs ? bpv / v->refs : 0.0;
    }
    out->bytes_vtable_share = (size_t)(share + 0.5);
    out->bytes = out->bytes_nodes + out->bytes_values + out->bytes_vtable_share;
}
