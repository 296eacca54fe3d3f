/* mesh_qmesh_test.c — quadtree cache meshes (qmesh.h) over the shared vertex table:
 * split/merge undo restores the exact state (tree, vertex table, references,
 * values) after random split sequences; leaf triangles are crack-free (every
 * interior edge once in each direction), counter-clockwise and tile each scene
 * triangle; interpolation returns stored values at vertices and edge averages at
 * unused midpoints; statistics match a recount; node cap and depth limit refuse a
 * split without changing anything. Real mesh: the sphere Cornell box. */
#include "mesh/qmesh.h"
#include "tests/test_util.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static uint64_t g_rng = 0x243F6A8885A308D3ull;
static uint32_t rnd(uint32_t n)
{
    g_rng ^= g_rng << 13, g_rng ^= g_rng >> 7, g_rng ^= g_rng << 17;
    return (uint32_t)((g_rng >> 11) % n);
}

/* ---- a growable uint32 vector for dumps ---- */
typedef struct vec {
    uint32_t *d;
    size_t n, cap;
} vec;

static void push(vec *v, uint32_t x)
{
    if (v->n == v->cap) {
        size_t nc = v->cap ? 2 * v->cap : 4096;
        uint32_t *nd = realloc(v->d, nc * sizeof *nd);
        if (!nd) return;
        v->d = nd, v->cap = nc;
    }
    v->d[v->n++] = x;
}

static uint32_t fbits(float f)
{
    uint32_t u;
    memcpy(&u, &f, 4);
    return u;
}

static void dump_node(const mesh_qmesh *m, uint32_t id, vec *out)
{
    const mesh_qnode *n = mesh_qmesh_node(m, id);
    if (!n) {
        push(out, 0xDEADu);
        return;
    }
    push(out, n->tri), push(out, n->depth), push(out, n->orient), push(out, n->a0), push(out, n->a1);
    for (int c = 0; c < 3; ++c) push(out, n->v[c]);
    push(out, n->child != MESH_QMESH_NONE);
    if (n->child != MESH_QMESH_NONE)
        for (uint32_t k = 0; k < 4; ++k) {
            const mesh_qnode *c = mesh_qmesh_node(m, n->child + k);
            push(out, c && c->parent == id);
            dump_node(m, n->child + k, out);
        }
}

/* Everything observable: trees (by structure), per-mesh uses and values, and every
 * vtable id's record and reference count. */
static void dump(const mesh_qmesh *const *ms, int nm, const mesh_vtable *vt, vec *out)
{
    out->n = 0;
    const scene *s = mesh_vtable_scene(vt);
    for (int k = 0; k < nm; ++k) {
        mesh_qmesh_stats st;
        mesh_qmesh_get_stats(ms[k], &st);
        push(out, st.nodes), push(out, st.leaves), push(out, st.vertices_used);
        push(out, st.vertices_sampled);
        for (uint32_t t = 0; t < s->tri_count; ++t) {
            uint32_t r = mesh_qmesh_root(ms[k], t);
            push(out, r);
            if (r != MESH_QMESH_NONE) dump_node(ms[k], r, out);
        }
    }
    const uint32_t lim = mesh_vtable_id_limit(vt);
    for (uint32_t id = 0; id < lim; ++id) {
        const mesh_vertex *v = mesh_vtable_vertex(vt, id);
        if (!v) continue; /* freed ids: only the free list's order may differ */
        push(out, id), push(out, v->refs), push(out, v->tri);
        for (int c = 0; c < 3; ++c) push(out, v->bary.w[c]), push(out, fbits(v->position[c]));
        push(out, v->bary.depth);
        for (int k = 0; k < nm; ++k) {
            float val[3] = {0, 0, 0};
            push(out, mesh_qmesh_vertex_use(ms[k], id));
            push(out, (uint32_t)(mesh_qmesh_get_value(ms[k], id, val) + 1));
            for (int c = 0; c < 3; ++c) push(out, fbits(val[c]));
        }
    }
}

static int same(const vec *a, const vec *b)
{
    return a->n == b->n && memcmp(a->d, b->d, a->n * sizeof *a->d) == 0;
}

/* A random leaf: random root, then random children, at most max_depth deep. */
static uint32_t random_leaf(const mesh_qmesh *m, const scene *s, uint32_t max_depth)
{
    for (;;) {
        uint32_t r = mesh_qmesh_root(m, rnd(s->tri_count));
        if (r == MESH_QMESH_NONE) continue;
        const mesh_qnode *n = mesh_qmesh_node(m, r);
        while (n->child != MESH_QMESH_NONE) {
            r = n->child + rnd(4);
            n = mesh_qmesh_node(m, r);
        }
        if (n->depth < max_depth) return r;
    }
}

/* Sets a value (a smooth function of position, plus the id) at every used vertex
 * that has none yet. */
static void sample_new(mesh_qmesh *m, const mesh_vtable *vt)
{
    const uint32_t lim = mesh_vtable_id_limit(vt);
    for (uint32_t id = 0; id < lim; ++id) {
        if (mesh_qmesh_get_value(m, id, NULL) != 0) continue;
        const mesh_vertex *v = mesh_vtable_vertex(vt, id);
        float val[3] = {v->position[0] + 2 * v->position[1], v->position[2] - v->position[0],
                        (float)(id % 97) * 0.01f};
        mesh_qmesh_set_value(m, id, val, NULL);
    }
}

static scene *load_cornell(void)
{
    scene_load_desc d = {.path = LUMESH_SCENES "/cornell-box/CornellBox-Sphere.obj"};
    scene *s = NULL;
    lm_error err = {{0}};
    CHECK_MSG(scene_load(&d, &s, &err) == LM_OK, "%s", err.msg);
    return s;
}

static mesh_qmesh *make_mesh(mesh_vtable *vt, const uint32_t *roots, uint32_t nroots,
                             mesh_qmesh_root_filter f, uint32_t channels, uint32_t cap)
{
    mesh_qmesh_desc d = {.vtable = vt, .root_tris = roots, .root_count = nroots, .root_filter = f,
                         .channels = channels, .node_cap = cap};
    mesh_qmesh *m = NULL;
    lm_error err = {{0}};
    CHECK_MSG(mesh_qmesh_create(&d, &m, &err) == LM_OK, "%s", err.msg);
    return m;
}

static int has_specular(const scene *s, uint32_t tri, void *user)
{
    (void)user;
    const float *ks = s->materials[s->tris[tri].material].ks;
    return ks[0] > 0 || ks[1] > 0 || ks[2] > 0;
}

static void test_undo(scene *s, mesh_vtable *vt)
{
    mesh_qmesh *a = make_mesh(vt, NULL, 0, NULL, 3, 0);
    mesh_qmesh *b = make_mesh(vt, NULL, 0, has_specular, 1, 0);
    if (!a || !b) goto done;
    const mesh_qmesh *both[2] = {a, b};
    vec d0 = {0}, d1 = {0}, d2 = {0};
    /* A first refinement that stays; then rounds of random splits undone in reverse. */
    for (int k = 0; k < 300; ++k) mesh_qmesh_split(a, random_leaf(a, s, 8), NULL);
    sample_new(a, vt);
    sample_new(b, vt); /* else the rounds would sample b's roots for the first time */
    uint32_t *log = malloc(sizeof(uint32_t) * 2000);
    int undone_ok = 1, rounds = 0;
    for (int round = 0; round < 20 && log; ++round, ++rounds) {
        dump(both, 2, vt, &d0);
        int n = 0;
        for (int k = 0; k < 100 + (int)rnd(400); ++k) {
            mesh_qmesh *m = rnd(4) ? a : b;
            uint32_t leaf = random_leaf(m, s, 14);
            if (mesh_qmesh_split(m, leaf, NULL) == LM_OK) log[n++] = leaf | (m == b ? 1u << 31 : 0);
            if (rnd(3) == 0) sample_new(m, vt);
        }
        dump(both, 2, vt, &d1);
        CHECK(!same(&d0, &d1));
        while (n-- > 0) {
            mesh_qmesh *m = log[n] >> 31 ? b : a;
            lm_error err = {{0}};
            lm_result r = mesh_qmesh_merge(m, log[n] & 0x7fffffffu, &err);
            if (r != LM_OK) undone_ok = 0, fprintf(stderr, "merge: %s\n", err.msg);
        }
        dump(both, 2, vt, &d2);
        CHECK_MSG(same(&d0, &d2), "round %d: state after undo differs (%zu vs %zu words)", round,
                  d0.n, d2.n);
    }
    CHECK(undone_ok && rounds == 20);
    mesh_qmesh_stats st;
    mesh_qmesh_get_stats(b, &st);
    printf("undo: 20 rounds of up to 500 random splits over two meshes restored exactly; "
           "specular mesh has %u roots of %u triangles\n", st.roots, s->tri_count);
    CHECK(st.roots > 0 && st.roots < s->tri_count);
    free(log);
    free(d0.d), free(d1.d), free(d2.d);
done:
    mesh_qmesh_destroy(a);
    mesh_qmesh_destroy(b);
    mesh_vtable_stats vs;
    mesh_vtable_get_stats(vt, &vs);
    CHECK_MSG(vs.live == 0, "%u vertices still live after both meshes went", vs.live);
}

static int cmp_u64(const void *x, const void *y)
{
    uint64_t a = *(const uint64_t *)x, b = *(const uint64_t *)y;
    return a < b ? -1 : a > b;
}

static size_t count_edge(const uint64_t *e, size_t n, uint64_t key)
{
    const uint64_t *p = bsearch(&key, e, n, sizeof *e, cmp_u64);
    if (!p) return 0;
    while (p > e && p[-1] == key) --p;
    size_t c = 0;
    while (p + c < e + n && p[c] == key) ++c;
    return c;
}

/* The scene edge (0..2) both addresses lie on, or -1. */
static int on_scene_edge(mesh_bary a, mesh_bary b)
{
    for (int z = 0; z < 3; ++z)
        if (a.w[z] == 0 && b.w[z] == 0) return (z + 1) % 3;
    return -1;
}

static double bary_coord(mesh_bary b, int k) { return ldexp((double)b.w[k], -(int)b.depth); }

static void collect_leaves(const mesh_qmesh *m, uint32_t id, vec *out)
{
    const mesh_qnode *n = mesh_qmesh_node(m, id);
    if (n->child == MESH_QMESH_NONE) {
        push(out, id);
        return;
    }
    for (uint32_t k = 0; k < 4; ++k) collect_leaves(m, n->child + k, out);
}

/* Crack-free, oriented, tiling leaf triangles; interpolation. */
static void check_leaves(const scene *s, mesh_vtable *vt, mesh_qmesh *m, const char *what)
{
    mesh_qmesh_tri *tris = NULL;
    size_t cap = 0, n = 0;
    lm_error err = {{0}};
    CHECK_MSG(mesh_qmesh_leaf_triangles(m, &tris, &cap, &n, &err) == LM_OK, "%s", err.msg);
    mesh_qmesh_stats st;
    mesh_qmesh_get_stats(m, &st);
    CHECK(n >= st.leaves);
    uint64_t *edges = malloc(3 * n * sizeof *edges + 1);
    double *area = calloc(s->tri_count, sizeof *area), *area3 = calloc(s->tri_count, sizeof *area3);
    double *aread = calloc(s->tri_count, sizeof *aread);
    uint8_t *seen = calloc(mesh_vtable_id_limit(vt) + 1, 1);
    if (!edges || !area || !area3 || !aread || !seen) goto done;
    long bad_orient = 0;
    for (size_t i = 0; i < n; ++i) {
        const mesh_qmesh_tri *t = &tris[i];
        double u[3], v[3];
        for (int c = 0; c < 3; ++c) {
            edges[3 * i + (size_t)c] = (uint64_t)t->v[c] << 32 | t->v[(c + 1) % 3];
            u[c] = bary_coord(t->bary[c], 1), v[c] = bary_coord(t->bary[c], 2);
            seen[t->v[c]] = 1;
            const mesh_vertex *vx = mesh_vtable_vertex(vt, t->v[c]);
            bad_orient += !vx || mesh_qmesh_vertex_use(m, t->v[c]) == 0;
        }
        const double a = (u[1] - u[0]) * (v[2] - v[0]) - (u[2] - u[0]) * (v[1] - v[0]);
        bad_orient += !(a > 0);
        area[t->tri] += a;
        /* 3D area from exact (double) positions of the corners' addresses ... */
        {
            const scene_tri *st3 = &s->tris[t->tri];
            double P[3][3];
            for (int c = 0; c < 3; ++c)
                for (int k = 0; k < 3; ++k) {
                    P[c][k] = 0;
                    for (int q = 0; q < 3; ++q)
                        P[c][k] += bary_coord(t->bary[c], q) * s->positions[3 * st3->v[q] + (uint32_t)k];
                }
            double e1[3], e2[3];
            for (int k = 0; k < 3; ++k) e1[k] = P[1][k] - P[0][k], e2[k] = P[2][k] - P[0][k];
            double cx = e1[1] * e2[2] - e1[2] * e2[1], cy = e1[2] * e2[0] - e1[0] * e2[2],
                   cz = e1[0] * e2[1] - e1[1] * e2[0];
            aread[t->tri] += 0.5 * sqrt(cx * cx + cy * cy + cz * cz);
        }
        /* ... and from the vtable's float positions (rounded: a looser bound). */
        const mesh_vertex *p0 = mesh_vtable_vertex(vt, t->v[0]), *p1 = mesh_vtable_vertex(vt, t->v[1]),
                          *p2 = mesh_vtable_vertex(vt, t->v[2]);
        if (p0 && p1 && p2) {
            double e1[3], e2[3];
            for (int k = 0; k < 3; ++k)
                e1[k] = (double)p1->position[k] - p0->position[k], e2[k] = (double)p2->position[k] - p0->position[k];
            double cx = e1[1] * e2[2] - e1[2] * e2[1], cy = e1[2] * e2[0] - e1[0] * e2[2],
                   cz = e1[0] * e2[1] - e1[1] * e2[0];
            area3[t->tri] += 0.5 * sqrt(cx * cx + cy * cy + cz * cz);
        }
    }
    CHECK_MSG(bad_orient == 0, "%s: %ld triangles degenerate, clockwise or with foreign vertices",
              what, bad_orient);
    /* Tiling: bary-space areas sum to exactly 1 per root; 3D areas to the scene's. */
    long bad_area = 0;
    double worst3 = 0, worstd = 0;
    for (uint32_t t = 0; t < s->tri_count; ++t) {
        if (mesh_qmesh_root(m, t) == MESH_QMESH_NONE) continue;
        bad_area += fabs(area[t] - 1.0) > 1e-12;
        const float *A = s->positions + 3 * s->tris[t].v[0], *B = s->positions + 3 * s->tris[t].v[1],
                    *C = s->positions + 3 * s->tris[t].v[2];
        double e1[3], e2[3];
        for (int k = 0; k < 3; ++k) e1[k] = (double)B[k] - A[k], e2[k] = (double)C[k] - A[k];
        double cx = e1[1] * e2[2] - e1[2] * e2[1], cy = e1[2] * e2[0] - e1[0] * e2[2],
               cz = e1[0] * e2[1] - e1[1] * e2[0];
        const double full = 0.5 * sqrt(cx * cx + cy * cy + cz * cz);
        double rel = fabs(aread[t] - full) / full;
        if (rel > worstd) worstd = rel;
        rel = fabs(area3[t] - full) / full;
        if (rel > worst3) worst3 = rel;
    }
    CHECK_MSG(bad_area == 0, "%s: %ld scene triangles not tiled", what, bad_area);
    CHECK_MSG(worstd < 1e-6, "%s: 3D area off by %.3g relative", what, worstd);
    CHECK_MSG(worst3 < 1e-4, "%s: 3D area from float positions off by %.3g relative", what, worst3);
    /* Every vertex the mesh uses appears in the output. */
    long missing = 0;
    for (uint32_t id = 0; id < mesh_vtable_id_limit(vt); ++id)
        missing += mesh_qmesh_vertex_use(m, id) > 0 && !seen[id];
    CHECK_MSG(missing == 0, "%s: %ld used vertices not in any leaf triangle", what, missing);
    /* Crack-free: every directed edge once; its reverse once too unless it lies on a
     * scene edge with nothing shared across (crease, boundary) or no tree across. */
    qsort(edges, 3 * n, sizeof *edges, cmp_u64);
    long unpaired = 0, paired = 0, border = 0;
    for (size_t i = 0; i < n; ++i)
        for (int c = 0; c < 3; ++c) {
            const mesh_qmesh_tri *t = &tris[i];
            uint32_t x = t->v[c], y = t->v[(c + 1) % 3];
            int e = on_scene_edge(t->bary[c], t->bary[(c + 1) % 3]);
            int shared = 1;
            if (e >= 0) {
                int32_t nb = mesh_geo_neighbor(s->topology, t->tri, e);
                shared = mesh_geo_edge_kind(s->topology, t->tri, e) == MESH_EDGE_INTERIOR && nb >= 0 &&
                         mesh_qmesh_root(m, (uint32_t)nb) != MESH_QMESH_NONE;
            }
            size_t fwd = count_edge(edges, 3 * n, (uint64_t)x << 32 | y);
            size_t rev = count_edge(edges, 3 * n, (uint64_t)y << 32 | x);
            if (fwd != 1 || (shared && rev != 1)) {
                if (unpaired++ < 5)
                    fprintf(stderr, "%s: edge %u->%u of tri %u (scene edge %d): %zu forward, %zu back\n",
                            what, x, y, t->tri, e, fwd, rev);
            } else if (shared) {
                paired++;
            } else {
                border++;
            }
        }
    CHECK_MSG(unpaired == 0, "%s: %ld edges unpaired (T-vertices or cracks)", what, unpaired);
    printf("%s: %zu leaf triangles for %u leaves, %ld paired edge sides, %ld border sides, "
           "area sums within %.2g (double), %.2g (float positions)\n", what, n, st.leaves, paired,
           border, worstd, worst3);

    /* Interpolation: stored value at every vertex; average of the ends at the
     * midpoint of every leaf edge whose midpoint the mesh does not use. */
    long bad_vertex = 0, bad_mid = 0, mids = 0;
    float want[3], got[3];
    const uint32_t nch = mesh_qmesh_channels(m);
    for (uint32_t id = 0; id < mesh_vtable_id_limit(vt); ++id) {
        if (mesh_qmesh_get_value(m, id, want) != 1) continue;
        const mesh_vertex *v = mesh_vtable_vertex(vt, id);
        if (mesh_qmesh_interpolate(m, v->tri, bary_coord(v->bary, 1), bary_coord(v->bary, 2), got, NULL) != LM_OK) {
            bad_vertex++;
            continue;
        }
        for (uint32_t c = 0; c < nch; ++c) bad_vertex += got[c] != want[c];
    }
    vec leaves = {0};
    for (uint32_t t = 0; t < s->tri_count; ++t)
        if (mesh_qmesh_root(m, t) != MESH_QMESH_NONE) collect_leaves(m, mesh_qmesh_root(m, t), &leaves);
    CHECK(leaves.n == st.leaves);
    for (size_t li = 0; li < leaves.n; ++li) {
        const mesh_qnode *q = mesh_qmesh_node(m, leaves.d[li]);
        for (int e = 0; e < 3; ++e) {
            mesh_bary mid;
            if (mesh_bary_midpoint(mesh_qmesh_node_corner(q, e), mesh_qmesh_node_corner(q, (e + 1) % 3), &mid) != LM_OK)
                continue;
            uint32_t id = mesh_vtable_find(vt, q->tri, mid);
            if (id != MESH_VTABLE_NONE && mesh_qmesh_vertex_use(m, id) > 0) continue;
            float va[3], vb[3];
            mesh_qmesh_get_value(m, q->v[e], va);
            mesh_qmesh_get_value(m, q->v[(e + 1) % 3], vb);
            mids++;
            if (mesh_qmesh_interpolate(m, q->tri, bary_coord(mid, 1), bary_coord(mid, 2), got, NULL) != LM_OK) {
                bad_mid++;
                continue;
            }
            for (uint32_t c = 0; c < nch; ++c)
                bad_mid += fabsf(got[c] - 0.5f * (va[c] + vb[c])) > 1e-6f * (1 + fabsf(got[c]));
        }
    }
    free(leaves.d);
    CHECK_MSG(bad_vertex == 0, "%s: %ld vertex values not returned", what, bad_vertex);
    CHECK_MSG(bad_mid == 0 && mids > 0, "%s: %ld of %ld midpoints not the average", what, bad_mid, mids);
done:
    free(tris);
    free(edges);
    free(area);
    free(area3);
    free(aread);
    free(seen);
}

/* Statistics against a recount by traversal. */
static void count_tree(const mesh_qmesh *m, uint32_t id, uint32_t *nodes, uint32_t *leaves, uint32_t *hist)
{
    const mesh_qnode *n = mesh_qmesh_node(m, id);
    (*nodes)++;
    if (n->child == MESH_QMESH_NONE) {
        (*leaves)++, hist[n->depth]++;
        return;
    }
    for (uint32_t k = 0; k < 4; ++k) count_tree(m, n->child + k, nodes, leaves, hist);
}

static void check_stats(const scene *s, const mesh_vtable *vt, const mesh_qmesh *m, uint64_t splits,
                        uint64_t merges)
{
    uint32_t nodes = 0, leaves = 0, hist[MESH_QMESH_DEPTHS] = {0}, used = 0, sampled = 0;
    for (uint32_t t = 0; t < s->tri_count; ++t)
        if (mesh_qmesh_root(m, t) != MESH_QMESH_NONE) count_tree(m, mesh_qmesh_root(m, t), &nodes, &leaves, hist);
    for (uint32_t id = 0; id < mesh_vtable_id_limit(vt); ++id) {
        used += mesh_qmesh_vertex_use(m, id) > 0;
        sampled += mesh_qmesh_get_value(m, id, NULL) == 1;
    }
    mesh_qmesh_stats st;
    mesh_qmesh_get_stats(m, &st);
    CHECK(st.nodes == nodes && st.leaves == leaves && st.vertices_used == used);
    CHECK(st.vertices_sampled == sampled && st.splits == splits && st.merges == merges);
    CHECK(memcmp(st.leaves_at_depth, hist, sizeof hist) == 0);
    CHECK(st.bytes == st.bytes_nodes + st.bytes_values + st.bytes_vtable_share && st.bytes_vtable_share > 0);
    printf("stats: %u nodes, %u leaves, %u vertices; %zu bytes (%.1f per node incl. pool slack, "
           "%zu values, %zu vtable share)\n", st.nodes, st.leaves, st.vertices_used, st.bytes,
           (double)st.bytes_nodes / st.nodes, st.bytes_values, st.bytes_vtable_share);
}

static void test_refined(scene *s, mesh_vtable *vt)
{
    mesh_qmesh *m = make_mesh(vt, NULL, 0, NULL, 3, 0);
    mesh_qmesh *spec = make_mesh(vt, NULL, 0, has_specular, 3, 0);
    if (!m || !spec) goto done;
    uint64_t splits = 0, merges = 0;
    double t0 = lm_now_seconds();
    for (int k = 0; k < 20000; ++k) splits += mesh_qmesh_split(m, random_leaf(m, s, 12), NULL) == LM_OK;
    double t1 = lm_now_seconds();
    for (int k = 0; k < 3000; ++k) mesh_qmesh_split(spec, random_leaf(spec, s, 10), NULL);
    /* Some undo on top: merge random nodes whose children are all leaves. */
    for (int k = 0; k < 3000; ++k) {
        uint32_t leaf = random_leaf(m, s, 31);
        const mesh_qnode *q = mesh_qmesh_node(m, leaf);
        if (q->parent != MESH_QMESH_NONE && mesh_qmesh_merge(m, q->parent, NULL) == LM_OK) merges++;
    }
    printf("refine: %llu splits in %.3f s (%.0f splits/s)\n", (unsigned long long)splits, t1 - t0,
           (double)splits / (t1 - t0));
    sample_new(m, vt);
    sample_new(spec, vt);
    check_stats(s, vt, m, splits, merges);
    check_leaves(s, vt, m, "cornell sphere, full mesh");
    check_leaves(s, vt, spec, "cornell sphere, specular subset");
    /* Interior point: the leaf centroid interpolates the three corners' mean. */
    uint32_t leaf = random_leaf(m, s, 31);
    const mesh_qnode *q = mesh_qmesh_node(m, leaf);
    double u = 0, v = 0;
    float want[3] = {0, 0, 0}, got[3], c3[3];
    for (int c = 0; c < 3; ++c) {
        mesh_bary b = mesh_qmesh_node_corner(q, c);
        u += bary_coord(b, 1) / 3, v += bary_coord(b, 2) / 3;
        mesh_qmesh_get_value(m, q->v[c], c3);
        for (int k = 0; k < 3; ++k) want[k] += c3[k] / 3;
    }
    CHECK(mesh_qmesh_interpolate(m, q->tri, u, v, got, NULL) == LM_OK);
    for (int k = 0; k < 3; ++k) CHECK_NEAR(got[k], want[k], 1e-5 * (1 + fabs(want[k])));
    lm_error err = {{0}};
    CHECK(mesh_qmesh_interpolate(m, q->tri, 0.7, 0.7, got, &err) == LM_ERR_INVALID_ARG);
    CHECK(mesh_qmesh_interpolate(m, q->tri, NAN, 0.1, got, &err) == LM_ERR_INVALID_ARG);
    CHECK(mesh_qmesh_interpolate(m, s->tri_count, 0.1, 0.1, got, &err) == LM_ERR_INVALID_ARG);
done:
    mesh_qmesh_destroy(m);
    mesh_qmesh_destroy(spec);
}

/* Two triangles of a square: a split on one side puts a midpoint on the shared
 * diagonal; the unsplit side is emitted as a fan of two. */
static void test_fan_small(scene *s, mesh_vtable *vt)
{
    /* Any two neighbours across an interior edge of the Cornell scene do. */
    uint32_t t0 = 0;
    int e0 = -1;
    for (uint32_t t = 0; t < s->tri_count && e0 < 0; ++t)
        for (int e = 0; e < 3; ++e)
            if (mesh_geo_edge_kind(s->topology, t, e) == MESH_EDGE_INTERIOR) {
                t0 = t, e0 = e;
                break;
            }
    CHECK(e0 >= 0);
    if (e0 < 0) return;
    const uint32_t t1 = (uint32_t)mesh_geo_neighbor(s->topology, t0, e0);
    const uint32_t roots[2] = {t1, t0};
    mesh_qmesh *m = make_mesh(vt, roots, 2, NULL, 1, 0);
    if (!m) return;
    lm_error err = {{0}};
    CHECK(mesh_qmesh_split(m, mesh_qmesh_root(m, t0), &err) == LM_OK);
    mesh_qmesh_tri *tris = NULL;
    size_t cap = 0, n = 0;
    CHECK(mesh_qmesh_leaf_triangles(m, &tris, &cap, &n, &err) == LM_OK);
    CHECK_MSG(n == 6, "%zu triangles, want 4 + a fan of 2", n);
    size_t on_t1 = 0;
    for (size_t i = 0; i < n; ++i) on_t1 += tris[i].tri == t1;
    CHECK(on_t1 == 2);
    /* Split the middle child: the other side still sees just the midpoint; each
     * corner child now has a midpoint on its inner edge: a fan of two each. */
    const mesh_qnode *r = mesh_qmesh_node(m, mesh_qmesh_root(m, t0));
    uint32_t first = r->child;
    CHECK(mesh_qmesh_split(m, first + 3, &err) == LM_OK);
    CHECK(mesh_qmesh_leaf_triangles(m, &tris, &cap, &n, &err) == LM_OK);
    CHECK_MSG(n == 4 + 3 * 2 + 2, "%zu triangles, want 12", n);
    /* In pieces of at least one triangle: whole leaves each time, and together
     * the same triangles in the same order. */
    for (size_t piece = 1; piece <= 5; ++piece) {
        mesh_qmesh_tri *part = NULL;
        size_t pcap = 0, got = 0, total = 0, calls = 0;
        int same = 1;
        for (uint32_t next = 0; next != UINT32_MAX && calls < 100; ++calls) {
            CHECK(mesh_qmesh_leaf_triangles_from(m, &next, piece, &part, &pcap, &got, &err) == LM_OK);
            for (size_t i = 0; i < got; ++i)
                same &= total + i < n && memcmp(&part[i], &tris[total + i], sizeof *part) == 0;
            same &= got >= piece || next == UINT32_MAX;
            same &= got == 0 || next == UINT32_MAX || part[got - 1].leaf != next; /* whole leaves */
            total += got;
        }
        CHECK_MSG(same && total == n, "pieces of %zu: %zu triangles in %zu calls, want %zu", piece, total, calls, n);
        free(part);
    }
    /* Bad arguments and refusals leave the mesh as it was. */
    CHECK(mesh_qmesh_split(m, first + 3, &err) == LM_ERR_INVALID_ARG);
    CHECK(mesh_qmesh_merge(m, first, &err) == LM_ERR_INVALID_ARG);        /* a leaf */
    CHECK(mesh_qmesh_merge(m, mesh_qmesh_root(m, t0), &err) == LM_ERR_INVALID_ARG); /* child split */
    CHECK(mesh_qmesh_split(m, 9999, &err) == LM_ERR_INVALID_ARG);
    CHECK(mesh_qmesh_set_value(m, 123456, (float[]){1}, &err) == LM_ERR_INVALID_ARG);
    CHECK(mesh_qmesh_leaf_triangles(m, NULL, &cap, &n, &err) == LM_ERR_INVALID_ARG);
    free(tris);
    mesh_qmesh_destroy(m);
}

/* Whole roots apart (mesh_qmesh_split_leaf_triangles_from, for the renderer's
 * pass over them): every root but a split one and its neighbours (a midpoint on
 * their edge) is whole; the listed triangles are the full listing without the
 * whole roots' own, in order; a whole root's one triangle is the scene triangle
 * with the scene corners' vertices (mesh_vtable_corner_id: what the snapshot
 * publishes), and mesh_qmesh_values holds each id's value. */
static void test_whole_roots(scene *s, mesh_vtable *vt)
{
    mesh_qmesh *m = make_mesh(vt, NULL, 0, NULL, 3, 0);
    if (!m) return;
    lm_error err = {{0}};
    const uint32_t t0 = 0;
    CHECK(mesh_qmesh_split(m, mesh_qmesh_root(m, t0), &err) == LM_OK);
    for (uint32_t t = 0; t < s->tri_count; t += 3) { /* values on some vertices */
        const mesh_qnode *n = mesh_qmesh_node(m, mesh_qmesh_root(m, t));
        if (n) CHECK(mesh_qmesh_set_value(m, n->v[0], (float[]){(float)t, 1.0f, 2.0f}, &err) == LM_OK);
    }
    mesh_qmesh_tri *all = NULL, *part = NULL;
    size_t cap = 0, pcap = 0, n = 0;
    CHECK(mesh_qmesh_leaf_triangles(m, &all, &cap, &n, &err) == LM_OK);
    const size_t words = ((size_t)s->tri_count + 31) / 32;
    uint32_t *whole = calloc(words, sizeof *whole), whole_count = 0;
    if (!whole) goto done;
    size_t total = 0, at = 0;
    int in_order = 1, one_triangle = 1, corners = 1;
    for (uint32_t next = 0; next != UINT32_MAX;) {
        size_t got = 0;
        CHECK(mesh_qmesh_split_leaf_triangles_from(m, &next, 7, whole, &whole_count, &part, &pcap, &got, &err) ==
              LM_OK);
        for (size_t i = 0; i < got; ++i) {
            while (at < n && (whole[all[at].tri / 32] >> (all[at].tri % 32) & 1u)) ++at; /* a whole root's */
            in_order &= at < n && memcmp(&part[i], &all[at], sizeof *part) == 0;
            ++at;
        }
        total += got;
        if (!got && next != UINT32_MAX) break;
    }
    uint32_t expect_whole = 0;
    for (uint32_t t = 0; t < s->tri_count; ++t) {
        const int bit = whole[t / 32] >> (t % 32) & 1u;
        size_t on_t = 0, first = 0;
        for (size_t i = 0; i < n; ++i)
            if (all[i].tri == t && !on_t++) first = i;
        if (!bit) continue;
        ++expect_whole;
        one_triangle &= on_t == 1;
        for (int k = 0; k < 3 && on_t; ++k) corners &= all[first].v[k] == mesh_vtable_corner_id(vt, t, k);
    }
    CHECK_MSG(whole_count == expect_whole && whole_count > 0 && whole_count < s->tri_count - 1,
              "%u whole roots counted, %u bits set, of %u triangles", whole_count, expect_whole, s->tri_count);
    CHECK_MSG(!(whole[t0 / 32] >> (t0 % 32) & 1u), "the split root is listed as whole");
    CHECK_MSG(in_order && total + whole_count == n,
              "%zu listed and %u whole of %zu triangles, in order: %d", total, whole_count, n, in_order);
    CHECK_MSG(one_triangle && corners, "a whole root's triangle is not the scene triangle with its corner ids");
    uint32_t ids = 0;
    const float *values = mesh_qmesh_values(m, &ids);
    int same_values = values != NULL && ids > 0;
    for (uint32_t id = 0; id < ids && same_values; ++id) {
        float v[3];
        if (mesh_qmesh_get_value(m, id, v) < 0) v[0] = v[1] = v[2] = 0.0f;
        same_values &= memcmp(v, values + 3 * (size_t)id, sizeof v) == 0;
    }
    CHECK_MSG(same_values, "mesh_qmesh_values differs from mesh_qmesh_get_value");
    CHECK(mesh_qmesh_split_leaf_triangles_from(m, &(uint32_t){0}, 1, whole, NULL, &part, &pcap, &n, &err) ==
          LM_ERR_INVALID_ARG);
done:
    free(whole);
    free(all);
    free(part);
    mesh_qmesh_destroy(m);
}

static void test_limits(scene *s, mesh_vtable *vt)
{
    lm_error err = {{0}};
    const uint32_t root = 5;
    mesh_qmesh *m = make_mesh(vt, &root, 1, NULL, 1, 1 + 4 + 4);
    if (!m) return;
    const mesh_qmesh *one[1] = {m};
    vec before = {0}, after = {0};
    uint32_t r = mesh_qmesh_root(m, root);
    CHECK(mesh_qmesh_split(m, r, &err) == LM_OK);
    CHECK(mesh_qmesh_split(m, mesh_qmesh_node(m, r)->child + 2, &err) == LM_OK);
    sample_new(m, vt);
    dump(one, 1, vt, &before);
    CHECK(mesh_qmesh_split(m, mesh_qmesh_node(m, r)->child + 1, &err) == LM_ERR_NO_MEMORY);
    printf("node cap: %s\n", err.msg);
    dump(one, 1, vt, &after);
    CHECK(same(&before, &after));
    mesh_qmesh_stats st;
    mesh_qmesh_get_stats(m, &st);
    CHECK(st.nodes == 9 && st.splits == 2);
    mesh_qmesh_destroy(m);

    /* Depth: split corner child 0 down to depth 30; the 31st split is refused. */
    m = make_mesh(vt, &root, 1, NULL, 1, 0);
    if (!m) return;
    one[0] = m;
    uint32_t n = mesh_qmesh_root(m, root);
    for (int d = 0; d < MESH_DEPTH_MAX; ++d) {
        CHECK(mesh_qmesh_split(m, n, &err) == LM_OK);
        n = mesh_qmesh_node(m, n)->child + (uint32_t)(d % 4);
    }
    CHECK(mesh_qmesh_node(m, n)->depth == MESH_DEPTH_MAX);
    sample_new(m, vt);
    dump(one, 1, vt, &before);
    CHECK(mesh_qmesh_split(m, n, &err) == LM_ERR_UNSUPPORTED);
    dump(one, 1, vt, &after);
    CHECK(same(&before, &after));
    check_leaves(s, vt, m, "one triangle to depth 30");
    mesh_qmesh_destroy(m);
    free(before.d), free(after.d);

    /* Descriptor errors. */
    mesh_qmesh_desc d = {.vtable = vt, .channels = 2};
    CHECK(mesh_qmesh_create(&d, &m, &err) == LM_ERR_INVALID_ARG && m == NULL);
    const uint32_t dup[2] = {3, 3};
    d = (mesh_qmesh_desc){.vtable = vt, .root_tris = dup, .root_count = 2};
    CHECK(mesh_qmesh_create(&d, &m, &err) == LM_ERR_INVALID_ARG);
    const uint32_t far = s->tri_count;
    d = (mesh_qmesh_desc){.vtable = vt, .root_tris = &far, .root_count = 1};
    CHECK(mesh_qmesh_create(&d, &m, &err) == LM_ERR_INVALID_ARG);
    d = (mesh_qmesh_desc){.vtable = vt, .node_cap = 3};
    CHECK(mesh_qmesh_create(&d, &m, &err) == LM_ERR_INVALID_ARG);
    d = (mesh_qmesh_desc){.vtable = vt, .scene = (const scene *)&d};
    CHECK(mesh_qmesh_create(&d, &m, &err) == LM_ERR_INVALID_ARG);
    CHECK(mesh_qmesh_create(NULL, &m, &err) == LM_ERR_INVALID_ARG);
    mesh_qmesh_destroy(NULL);
    mesh_vtable_stats vs;
    mesh_vtable_get_stats(vt, &vs);
    CHECK(vs.live == 0);
}

/* mesh_qmesh_desc.roots_like: the roots' corner ids taken from another mesh are
 * the ones a look-up gives, each held once more in the vertex table, and still
 * held once that mesh is gone. */
static void test_roots_like(scene *s, mesh_vtable *vt)
{
    lm_error err = {{0}};
    mesh_vtable_stats st0, st1;
    mesh_vtable_get_stats(vt, &st0);
    mesh_qmesh *a = NULL, *b = NULL, *c = NULL;
    const uint32_t half = s->tri_count / 2; /* b's roots: all; a has only half of them */
    uint32_t *first = malloc(half * sizeof *first);
    for (uint32_t i = 0; i < half; ++i) first[i] = i;
    CHECK(mesh_qmesh_create(&(mesh_qmesh_desc){.vtable = vt, .root_tris = first, .root_count = half}, &a, &err) ==
          LM_OK);
    CHECK(mesh_qmesh_create(&(mesh_qmesh_desc){.vtable = vt, .roots_like = a}, &b, &err) == LM_OK);
    CHECK(mesh_qmesh_create(&(mesh_qmesh_desc){.vtable = vt}, &c, &err) == LM_OK);
    free(first);
    if (!a || !b || !c) return;
    mesh_vtable_get_stats(vt, &st1);
    int same = 1;
    for (uint32_t t = 0; t < s->tri_count; ++t)
        for (int k = 0; k < 3; ++k)
            same &= mesh_qmesh_node(b, mesh_qmesh_root(b, t))->v[k] == mesh_qmesh_node(c, mesh_qmesh_root(c, t))->v[k];
    CHECK(same);
    /* The same roots as c's: copied whole (clone_roots), the mesh a look-up makes,
     * node for node and count for count. Once c is split, roots_like still gives
     * the same roots (by the corner loop). */
    mesh_qmesh *d = NULL, *e = NULL;
    CHECK(mesh_qmesh_create(&(mesh_qmesh_desc){.vtable = vt, .channels = 3, .roots_like = c}, &d, &err) == LM_OK);
    CHECK(mesh_qmesh_split(c, mesh_qmesh_root(c, 0), &err) == LM_OK);
    CHECK(mesh_qmesh_create(&(mesh_qmesh_desc){.vtable = vt, .roots_like = c}, &e, &err) == LM_OK);
    if (d && e) {
        mesh_qmesh_stats sb, sd, se;
        mesh_qmesh_get_stats(b, &sb);
        mesh_qmesh_get_stats(d, &sd);
        mesh_qmesh_get_stats(e, &se);
        CHECK(sd.roots == sb.roots && sd.nodes == sb.nodes && sd.leaves == sb.leaves && sd.leaves_at_depth[0] == sb.leaves);
        CHECK(sd.vertices_used == sb.vertices_used && se.vertices_used == sb.vertices_used && se.nodes == sb.nodes);
        int nodes_same = mesh_qmesh_node_limit(d) == mesh_qmesh_node_limit(b);
        for (uint32_t t = 0; t < s->tri_count; ++t) {
            const uint32_t rb = mesh_qmesh_root(b, t), rd = mesh_qmesh_root(d, t), re = mesh_qmesh_root(e, t);
            nodes_same &= rd == rb && re == rb && memcmp(mesh_qmesh_node(d, rd), mesh_qmesh_node(b, rb), sizeof(mesh_qnode)) == 0 &&
                          memcmp(mesh_qmesh_node(e, re), mesh_qmesh_node(b, rb), sizeof(mesh_qnode)) == 0;
            for (int k = 0; k < 3; ++k) {
                const uint32_t id = mesh_qmesh_node(b, rb)->v[k];
                nodes_same &= mesh_qmesh_vertex_use(d, id) == mesh_qmesh_vertex_use(b, id) &&
                              mesh_qmesh_vertex_use(e, id) == mesh_qmesh_vertex_use(b, id);
            }
        }
        CHECK(nodes_same);
        /* It refines like any mesh, and its vertices are its own. */
        const float rgb[3] = {1, 2, 3};
        float got[3];
        const uint32_t root = mesh_qmesh_root(d, 0);
        CHECK(mesh_qmesh_split(d, root, &err) == LM_OK);
        const uint32_t mid = mesh_qmesh_node(d, mesh_qmesh_node(d, root)->child + 3)->v[0];
        CHECK(mesh_qmesh_set_value(d, mid, rgb, &err) == LM_OK);
        CHECK(mesh_qmesh_get_value(d, mid, got) == 1 && got[2] == 3.0f && mesh_qmesh_get_value(b, mid, NULL) == -1);
        CHECK(mesh_qmesh_merge(d, root, &err) == LM_OK);
    }
    mesh_qmesh_destroy(d);
    mesh_qmesh_destroy(e);
    mesh_qmesh_destroy(a);
    mesh_qmesh_destroy(c);
    int live = 1; /* b holds its own reference to every corner */
    for (uint32_t t = 0; t < s->tri_count; ++t)
        for (int k = 0; k < 3; ++k) live &= mesh_vtable_vertex(vt, mesh_qmesh_node(b, mesh_qmesh_root(b, t))->v[k]) != NULL;
    CHECK(live);
    mesh_qmesh_destroy(b);
    mesh_vtable_stats st2;
    mesh_vtable_get_stats(vt, &st2);
    CHECK(st1.live > st0.live && st2.live == st0.live); /* every reference given back */
}

/* mesh_qmesh_add_roots on a mesh made with no_roots: in ascending order once,
 * the mesh mesh_qmesh_create makes, node for node; in two sets, after a split,
 * the later roots come after every node and the mesh refines like any; a
 * triangle with a root already is left as it is; a bad triangle is refused;
 * every reference is given back. */
static void test_add_roots(scene *s, mesh_vtable *vt)
{
    lm_error err = {{0}};
    mesh_vtable_stats st0, st1;
    mesh_vtable_get_stats(vt, &st0);
    mesh_qmesh *full = NULL, *lazy = NULL, *two = NULL;
    CHECK(mesh_qmesh_create(&(mesh_qmesh_desc){.vtable = vt, .channels = 3}, &full, &err) == LM_OK);
    CHECK(mesh_qmesh_create(&(mesh_qmesh_desc){.vtable = vt, .channels = 3, .no_roots = 1}, &lazy, &err) == LM_OK);
    CHECK(mesh_qmesh_create(&(mesh_qmesh_desc){.vtable = vt, .no_roots = 1}, &two, &err) == LM_OK);
    if (!full || !lazy || !two) goto done;
    mesh_qmesh_stats sl;
    mesh_qmesh_get_stats(lazy, &sl);
    CHECK(sl.roots == 0 && sl.nodes == 0 && sl.vertices_used == 0 && mesh_qmesh_root(lazy, 0) == MESH_QMESH_NONE);
    uint32_t *all = malloc(s->tri_count * sizeof *all);
    if (!all) goto done;
    for (uint32_t t = 0; t < s->tri_count; ++t) all[t] = t;
    const mesh_qmesh_version v0 = mesh_qmesh_get_version(lazy);
    CHECK(mesh_qmesh_add_roots(lazy, all, s->tri_count, NULL, &err) == LM_OK);
    CHECK(mesh_qmesh_get_version(lazy).changes > v0.changes); /* a snapshot of it must be made again */
    int same = mesh_qmesh_node_limit(lazy) == mesh_qmesh_node_limit(full);
    for (uint32_t t = 0; t < s->tri_count; ++t) {
        const uint32_t rf = mesh_qmesh_root(full, t), rl = mesh_qmesh_root(lazy, t);
        same &= rf == rl && memcmp(mesh_qmesh_node(full, rf), mesh_qmesh_node(lazy, rl), sizeof(mesh_qnode)) == 0;
        for (int k = 0; k < 3; ++k) {
            const uint32_t id = mesh_qmesh_node(full, rf)->v[k];
            same &= mesh_qmesh_vertex_use(lazy, id) == mesh_qmesh_vertex_use(full, id);
        }
    }
    CHECK(same);
    /* Apart (the vertex table only read): the same mesh, its references taken after. */
    mesh_qmesh *apart = NULL;
    CHECK(mesh_qmesh_create(&(mesh_qmesh_desc){.vtable = vt, .channels = 3, .no_roots = 1}, &apart, &err) == LM_OK);
    const uint32_t id0 = mesh_qmesh_node(full, mesh_qmesh_root(full, 0))->v[0];
    const uint32_t refs_before = mesh_vtable_vertex(vt, id0)->refs;
    CHECK(apart && mesh_qmesh_add_roots_apart(apart, all, s->tri_count, &err) == LM_OK);
    const uint32_t refs_apart = mesh_vtable_vertex(vt, id0)->refs;
    CHECK(mesh_qmesh_take_references(apart, &err) == LM_OK);
    int same_apart = apart && mesh_qmesh_node_limit(apart) == mesh_qmesh_node_limit(full) &&
                     mesh_qmesh_get_version(apart).changes == mesh_qmesh_get_version(lazy).changes - v0.changes;
    for (uint32_t t = 0; t < s->tri_count && apart; ++t) {
        const uint32_t rf = mesh_qmesh_root(full, t), ra = mesh_qmesh_root(apart, t);
        same_apart &= rf == ra && memcmp(mesh_qmesh_node(full, rf), mesh_qmesh_node(apart, ra), sizeof(mesh_qnode)) == 0;
        for (int k = 0; k < 3; ++k) {
            const uint32_t id = mesh_qmesh_node(full, rf)->v[k];
            same_apart &= mesh_qmesh_vertex_use(apart, id) == mesh_qmesh_vertex_use(full, id);
        }
    }
    CHECK_MSG(same_apart && refs_apart == refs_before && mesh_vtable_vertex(vt, id0)->refs == refs_before + 1,
              "roots added apart: same mesh %d, references %u, %u while owed, %u after", same_apart, refs_before,
              refs_apart, mesh_vtable_vertex(vt, id0)->refs);
    CHECK(mesh_qmesh_add_roots_apart(apart, &(uint32_t){s->tri_count}, 1, &err) == LM_ERR_INVALID_ARG);
    CHECK(mesh_qmesh_add_roots_apart(NULL, all, 1, &err) == LM_ERR_INVALID_ARG);
    mesh_qmesh_destroy(apart);
    apart = NULL; /* destroyed while its references are owed: it takes them first (the end's live count) */
    CHECK(mesh_qmesh_create(&(mesh_qmesh_desc){.vtable = vt, .channels = 3, .no_roots = 1}, &apart, &err) == LM_OK);
    CHECK(apart && mesh_qmesh_add_roots_apart(apart, all, s->tri_count, &err) == LM_OK);
    mesh_qmesh_destroy(apart);
    CHECK_MSG(mesh_vtable_vertex(vt, id0)->refs == refs_before, "references %u after a mesh that owed them, want %u",
              mesh_vtable_vertex(vt, id0)->refs, refs_before);
    /* Added again: nothing changes. */
    CHECK(mesh_qmesh_add_roots(lazy, all, s->tri_count, full, &err) == LM_OK);
    mesh_qmesh_get_stats(lazy, &sl);
    CHECK(sl.roots == s->tri_count && sl.nodes == s->tri_count);
    /* In two sets, the first split between them: the second set's nodes after
     * the children, its corners copied from full (roots_like) as looked up. */
    const uint32_t half = s->tri_count / 2;
    CHECK(mesh_qmesh_add_roots(two, all + half, s->tri_count - half, NULL, &err) == LM_OK);
    CHECK(mesh_qmesh_split(two, mesh_qmesh_root(two, half), &err) == LM_OK);
    CHECK(mesh_qmesh_add_roots(two, all, half, full, &err) == LM_OK);
    mesh_qmesh_stats s2;
    mesh_qmesh_get_stats(two, &s2);
    CHECK(s2.roots == s->tri_count && s2.nodes == s->tri_count + 4 && s2.leaves == s->tri_count + 3);
    int later = 1, corners = 1;
    for (uint32_t t = 0; t < half; ++t) {
        later &= mesh_qmesh_root(two, t) >= s->tri_count - half + 4;
        for (int k = 0; k < 3; ++k)
            corners &= mesh_qmesh_node(two, mesh_qmesh_root(two, t))->v[k] ==
                       mesh_qmesh_node(full, mesh_qmesh_root(full, t))->v[k];
    }
    CHECK(later && corners);
    CHECK(mesh_qmesh_split(two, mesh_qmesh_root(two, 0), &err) == LM_OK);
    CHECK(mesh_qmesh_merge(two, mesh_qmesh_root(two, half), &err) == LM_OK);
    /* Refused: a triangle past the scene's. */
    const uint32_t far = s->tri_count;
    CHECK(mesh_qmesh_add_roots(two, &far, 1, NULL, &err) == LM_ERR_INVALID_ARG);
    CHECK(mesh_qmesh_add_roots(NULL, all, 1, NULL, &err) == LM_ERR_INVALID_ARG);
    free(all);
done:
    mesh_qmesh_destroy(full);
    mesh_qmesh_destroy(lazy);
    mesh_qmesh_destroy(two);
    mesh_vtable_get_stats(vt, &st1);
    CHECK(st1.live == st0.live); /* every reference given back */
}

/* The version: unique serials, and every split, merge and value written counted
 * (a snapshot copy is kept while the version stays); reading changes nothing. */
static void test_version(scene *s, mesh_vtable *vt)
{
    (void)s;
    lm_error err = {{0}};
    mesh_qmesh *a = make_mesh(vt, NULL, 0, NULL, 1, 0), *b = make_mesh(vt, NULL, 0, NULL, 1, 0);
    if (!a || !b) return;
    mesh_qmesh_version va = mesh_qmesh_get_version(a), vb = mesh_qmesh_get_version(b), none = mesh_qmesh_get_version(NULL);
    CHECK(va.serial != 0 && vb.serial != 0 && va.serial != vb.serial && va.changes == 0);
    CHECK(none.serial == 0 && none.changes == 0);
    const uint32_t root = mesh_qmesh_root(a, 0);
    const float one = 1.0f;
    float got;
    CHECK(mesh_qmesh_split(a, root, &err) == LM_OK);
    mesh_qmesh_version v1 = mesh_qmesh_get_version(a);
    CHECK(v1.serial == va.serial && v1.changes == va.changes + 1);
    const uint32_t corner = mesh_qmesh_node(a, mesh_qmesh_node(a, root)->child + 3)->v[0];
    CHECK(mesh_qmesh_set_value(a, corner, &one, &err) == LM_OK);
    CHECK(mesh_qmesh_get_value(a, corner, &got) == 1 && got == 1.0f);
    mesh_qmesh_version v2 = mesh_qmesh_get_version(a);
    CHECK(v2.changes == v1.changes + 1);
    CHECK(mesh_qmesh_merge(a, root, &err) == LM_OK);
    CHECK(mesh_qmesh_get_version(a).changes == v2.changes + 1);
    CHECK(mesh_qmesh_get_version(b).changes == 0); /* the other mesh: untouched */
    mesh_qmesh_destroy(a);
    mesh_qmesh *c = make_mesh(vt, NULL, 0, NULL, 1, 0); /* made after a is gone: a serial of its own */
    if (c) CHECK(mesh_qmesh_get_version(c).serial != va.serial && mesh_qmesh_get_version(c).serial != vb.serial);
    mesh_qmesh_destroy(b);
    mesh_qmesh_destroy(c);
}

int main(void)
{
    scene *s = load_cornell();
    if (!s) return test_finish("mesh_qmesh_test");
    mesh_vtable_desc vd = {.scene = s};
    mesh_vtable *vt = NULL;
    lm_error err = {{0}};
    CHECK_MSG(mesh_vtable_create(&vd, &vt, &err) == LM_OK, "%s", err.msg);
    if (vt) {
        test_undo(s, vt);
        test_refined(s, vt);
        test_fan_small(s, vt);
        test_roots_like(s, vt);
        test_add_roots(s, vt);
        test_whole_roots(s, vt);
        test_limits(s, vt);
        test_version(s, vt);
    }
    mesh_vtable_destroy(vt);
    scene_destroy(s);
    return test_finish("mesh_qmesh_test");
}
