/* mesh_vtable_test.c — the shared vertex table (vtable.h): one id per point whatever
 * the depth or triangle it is reached from, shared edges and smooth vertices shared,
 * crease sides and box-corner faces kept apart, reference counts and id recycling,
 * growth to a million vertices through many rehashes with no key conflated, exact
 * positions, and argument errors. */
#include "mesh/vtable.h"
#include "tests/test_util.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* A hand-built scene: only what the vertex table reads. */
typedef struct toy {
    scene s;
    scene_tri tris[16];
    float pos[3 * 16];
    float nrm[9 * 16];
} toy;

static void toy_init(toy *t, const float *pos, uint32_t nv, const uint32_t *tv, uint32_t nt,
                     const float *face_normals /* 3 per triangle, or NULL: per-vertex given */,
                     const float *vertex_normals)
{
    memset(t, 0, sizeof *t);
    memcpy(t->pos, pos, sizeof(float) * 3 * nv);
    for (uint32_t i = 0; i < nt; ++i) {
        for (int c = 0; c < 3; ++c) {
            t->tris[i].v[c] = tv[3 * i + (uint32_t)c];
            const float *n = face_normals ? face_normals + 3 * i : vertex_normals + 3 * tv[3 * i + (uint32_t)c];
            memcpy(t->nrm + 9 * i + 3 * (uint32_t)c, n, sizeof(float) * 3);
        }
        t->tris[i].light = -1;
    }
    t->s.positions = t->pos;
    t->s.vertex_count = nv;
    t->s.tris = t->tris;
    t->s.tri_count = nt;
    t->s.corner_normals = t->nrm;
    mesh_geo_desc gd = {.positions = t->pos, .vertex_count = nv, .triangles = tv,
                        .triangle_count = nt, .corner_normals = t->nrm};
    lm_error err = {{0}};
    CHECK_MSG(mesh_geo_create(&gd, &t->s.topology, &err) == LM_OK, "%s", err.msg);
}

static mesh_vtable *make_vt(const scene *s, uint32_t cap)
{
    mesh_vtable_desc d = {.scene = s, .initial_capacity = cap};
    mesh_vtable *vt = NULL;
    lm_error err = {{0}};
    CHECK_MSG(mesh_vtable_create(&d, &vt, &err) == LM_OK, "%s", err.msg);
    return vt;
}

static uint32_t get(mesh_vtable *vt, uint32_t tri, uint32_t w0, uint32_t w1, uint32_t w2, uint32_t depth)
{
    mesh_bary b = {{w0, w1, w2}, depth};
    uint32_t id = MESH_VTABLE_NONE;
    lm_error err = {{0}};
    CHECK_MSG(mesh_vtable_acquire(vt, tri, b, &id, &err) == LM_OK, "%s", err.msg);
    return id;
}

static uint32_t refs(const mesh_vtable *vt, uint32_t id)
{
    const mesh_vertex *v = mesh_vtable_vertex(vt, id);
    return v ? v->refs : 0;
}

/* Unit square in z = 0: tri 0 = (0,1,2), tri 1 = (0,2,3); diagonal 0-2 shared. */
static const float k_square[] = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0};
static const uint32_t k_square_tris[] = {0, 1, 2, 0, 2, 3};
static const float k_up2[] = {0, 0, 1, 0, 0, 1};

static void test_canonical_forms(void)
{
    toy t;
    toy_init(&t, k_square, 4, k_square_tris, 2, k_up2, NULL);
    mesh_vtable *vt = make_vt(&t.s, 0);
    if (!vt) return;
    /* Edge midpoint of edge 0 (corners 0,1) of tri 0 at depths 1, 2, 5, 30. */
    uint32_t a = get(vt, 0, 1, 1, 0, 1), b = get(vt, 0, 2, 2, 0, 2), c = get(vt, 0, 16, 16, 0, 5),
             d = get(vt, 0, 1u << 29, 1u << 29, 0, 30);
    CHECK(a != MESH_VTABLE_NONE && a == b && b == c && c == d);
    CHECK(refs(vt, a) == 4);
    /* Interior point (1,1,2)/4 reached at depths 2, 3, 30. */
    uint32_t i1 = get(vt, 0, 1, 1, 2, 2), i2 = get(vt, 0, 2, 2, 4, 3),
             i3 = get(vt, 0, 1u << 28, 1u << 28, 1u << 29, 30);
    CHECK(i1 == i2 && i2 == i3 && i1 != a);
    /* Scene vertex 0: corner 0 of both triangles, at depth 0, 1 and 30. */
    uint32_t v0 = get(vt, 0, 1, 0, 0, 0), v0b = get(vt, 1, 2, 0, 0, 1), v0c = get(vt, 1, 1u << 30, 0, 0, 30);
    CHECK(v0 == v0b && v0b == v0c);
    /* Scene vertex 2: corner 2 of tri 0, corner 1 of tri 1. */
    CHECK(get(vt, 0, 0, 0, 1, 0) == get(vt, 1, 0, 1, 0, 0));
    /* The shared diagonal 0-2: edge 2 of tri 0 (corners 2,0), edge 0 of tri 1 (corners 0,1). */
    uint32_t m0 = get(vt, 0, 1, 0, 1, 1), m1 = get(vt, 1, 1, 1, 0, 1);
    CHECK(m0 == m1 && m0 != a);
    /* Quarter point nearer vertex 0 (weights 3:1), from both sides; the 1:3 point differs. */
    uint32_t q0 = get(vt, 0, 3, 0, 1, 2), q1 = get(vt, 1, 3, 1, 0, 2), q2 = get(vt, 1, 1, 3, 0, 2);
    CHECK(q0 == q1 && q2 != q0);
    /* Same point, bit-identical position from either side, and the exact combination. */
    const mesh_vertex *vq = mesh_vtable_vertex(vt, q0);
    CHECK(vq && vq->position[0] == 0.25f && vq->position[1] == 0.25f && vq->position[2] == 0.0f);
    CHECK(vq && fabsf(vq->normal[2] - 1.0f) < 1e-7f);
    mesh_vtable_stats st;
    mesh_vtable_get_stats(vt, &st);
    CHECK_MSG(st.live == 7, "live %u", st.live); /* a, i1, v0, v2, m0, q0, q2 */
    mesh_vtable_destroy(vt);
    mesh_geo_destroy(t.s.topology);
}

/* A fan of 6 triangles round centre 6 of a flat hexagon; the centre is corner 0,
 * 1 or 2 depending on the triangle. Smooth: one vertex. */
static void test_smooth_vertex_all_corners(void)
{
    float pos[3 * 7];
    uint32_t tv[18];
    for (int k = 0; k < 6; ++k) {
        pos[3 * k] = cosf((float)k * 1.0471976f), pos[3 * k + 1] = sinf((float)k * 1.0471976f);
        pos[3 * k + 2] = 0;
    }
    pos[18] = pos[19] = pos[20] = 0;
    for (uint32_t k = 0; k < 6; ++k) {
        uint32_t a = k, b = (k + 1) % 6, c = 6, r = k % 3; /* rotate so the centre moves */
        uint32_t tri[3] = {a, b, c};
        for (uint32_t q = 0; q < 3; ++q) tv[3 * k + q] = tri[(q + r) % 3];
    }
    float up[18];
    for (int k = 0; k < 6; ++k) up[3 * k] = 0, up[3 * k + 1] = 0, up[3 * k + 2] = 1;
    toy t;
    toy_init(&t, pos, 7, tv, 6, up, NULL);
    mesh_vtable *vt = make_vt(&t.s, 0);
    if (!vt) return;
    uint32_t first = MESH_VTABLE_NONE;
    int same = 1, forms = 0;
    for (uint32_t k = 0; k < 6; ++k)
        for (int c = 0; c < 3; ++c)
            if (t.tris[k].v[c] == 6) {
                uint32_t w[3] = {0, 0, 0};
                w[c] = 1;
                forms |= 1 << c;
                uint32_t id = get(vt, k, w[0], w[1], w[2], 0);
                if (first == MESH_VTABLE_NONE) first = id;
                same &= id == first;
            }
    CHECK(forms == 7); /* the centre was corner 0, 1 and 2 */
    CHECK(same && refs(vt, first) == 6);
    mesh_vtable_destroy(vt);
    mesh_geo_destroy(t.s.topology);
}

/* The square folded by 90 degrees along its diagonal: two ids per point on the crease. */
static void test_crease(void)
{
    const float pos[] = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 1}; /* vertex 3 lifted */
    const float fn[] = {0, 0, 1, 0.70710678f, -0.70710678f, 0}; /* arbitrary, far apart */
    toy t;
    toy_init(&t, pos, 4, k_square_tris, 2, fn, NULL);
    CHECK(mesh_geo_edge_kind(t.s.topology, 0, 2) == MESH_EDGE_CREASE);
    mesh_vtable *vt = make_vt(&t.s, 0);
    if (!vt) return;
    uint32_t m0 = get(vt, 0, 1, 0, 1, 1), m1 = get(vt, 1, 1, 1, 0, 1);
    CHECK(m0 != m1);
    const mesh_vertex *a = mesh_vtable_vertex(vt, m0), *b = mesh_vtable_vertex(vt, m1);
    CHECK(a && b && memcmp(a->position, b->position, sizeof a->position) == 0);
    CHECK(a && b && a->normal[2] == 1.0f && b->normal[2] == 0.0f);
    /* The crease's end points: one per side. */
    CHECK(get(vt, 0, 1, 0, 0, 0) != get(vt, 1, 1, 0, 0, 0));
    CHECK(get(vt, 0, 0, 0, 1, 0) != get(vt, 1, 0, 1, 0, 0));
    /* Vertex 1 belongs to tri 0 only: one id. */
    CHECK(get(vt, 0, 0, 1, 0, 0) == get(vt, 0, 0, 2, 0, 1));
    mesh_vtable_destroy(vt);
    mesh_geo_destroy(t.s.topology);
}

/* A unit cube, two triangles per face, outward winding. */
static const float k_cube[] = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0, 0, 0, 1, 1, 0, 1, 1, 1, 1, 0, 1, 1};
static const uint32_t k_cube_tris[] = {
    0, 2, 1, 0, 3, 2, /* z = 0, normal -z */
    4, 5, 6, 4, 6, 7, /* z = 1 */
    0, 1, 5, 0, 5, 4, /* y = 0 */
    3, 7, 6, 3, 6, 2, /* y = 1 */
    0, 4, 7, 0, 7, 3, /* x = 0 */
    1, 2, 6, 1, 6, 5  /* x = 1 */
};

static void cube_corner_ids(int smooth, uint32_t *distinct_at_0, uint32_t *diag, uint32_t *cube_edge)
{
    float fn[36], vn[24];
    const float face[6][3] = {{0, 0, -1}, {0, 0, 1}, {0, -1, 0}, {0, 1, 0}, {-1, 0, 0}, {1, 0, 0}};
    for (int f = 0; f < 12; ++f) memcpy(fn + 3 * f, face[f / 2], sizeof face[0]);
    for (int v = 0; v < 8; ++v)
        for (int k = 0; k < 3; ++k) vn[3 * v + k] = (k_cube[3 * v + k] - 0.5f) / 0.8660254f;
    toy t;
    toy_init(&t, k_cube, 8, k_cube_tris, 12, smooth ? NULL : fn, smooth ? vn : NULL);
    mesh_vtable *vt = make_vt(&t.s, 0);
    if (!vt) return;
    uint32_t ids[12], n = 0;
    for (uint32_t k = 0; k < 12; ++k)
        for (int c = 0; c < 3; ++c)
            if (t.tris[k].v[c] == 0) {
                uint32_t w[3] = {0, 0, 0};
                w[c] = 1;
                uint32_t id = get(vt, k, w[0], w[1], w[2], 0), seen = 0;
                for (uint32_t q = 0; q < n; ++q) seen |= ids[q] == id;
                if (!seen) ids[n++] = id;
            }
    *distinct_at_0 = n;
    /* Midpoint of the bottom face's diagonal 0-2 (tri 0 edge 0, tri 1 edge 1). */
    *diag = get(vt, 0, 1, 1, 0, 1) == get(vt, 1, 1, 0, 1, 1) ? 1 : 2;
    /* Midpoint of cube edge 0-1: tri 0 edge 2 (corners 1,0) and tri 4 edge 0 (corners 0,1). */
    *cube_edge = get(vt, 0, 1, 0, 1, 1) == get(vt, 4, 1, 1, 0, 1) ? 1 : 2;
    mesh_vtable_destroy(vt);
    mesh_geo_destroy(t.s.topology);
}

static void test_box_corner(void)
{
    uint32_t n, diag, edge;
    cube_corner_ids(0, &n, &diag, &edge);
    CHECK_MSG(n == 3, "flat box corner: %u ids, want one per face (3)", n);
    CHECK(diag == 1);
    CHECK(edge == 2);
    cube_corner_ids(1, &n, &diag, &edge);
    CHECK_MSG(n == 1, "smooth box corner: %u ids, want 1", n);
    CHECK(diag == 1 && edge == 1);
}

/* The unit square's two flat triangles (0,1,2) and (0,2,3) in a table of 4 records. */
static mesh_vtable *square_table(toy *t)
{
    toy_init(t, k_square, 4, k_square_tris, 2, k_up2, NULL);
    return make_vt(&t->s, 4);
}

static void test_refcount_and_recycling(void)
{
    toy t;
    mesh_vtable *vt = square_table(&t);
    if (!vt) return;
    lm_error err = {{0}};
    uint32_t p = get(vt, 0, 1, 1, 2, 2);
    CHECK(get(vt, 0, 1, 1, 2, 2) == p && get(vt, 0, 2, 2, 4, 3) == p && refs(vt, p) == 3);
    CHECK(mesh_vtable_retain(vt, p, &err) == LM_OK && refs(vt, p) == 4);
    for (int k = 0; k < 3; ++k) CHECK(mesh_vtable_release(vt, p, &err) == LM_OK);
    CHECK(refs(vt, p) == 1 && mesh_vtable_find(vt, 0, (mesh_bary){{1, 1, 2}, 2}) == p);
    CHECK(mesh_vtable_release(vt, p, &err) == LM_OK);
    CHECK(mesh_vtable_vertex(vt, p) == NULL);
    CHECK(mesh_vtable_find(vt, 0, (mesh_bary){{1, 1, 2}, 2}) == MESH_VTABLE_NONE);
    CHECK(mesh_vtable_release(vt, p, &err) == LM_ERR_INVALID_ARG && err.msg[0]);
    CHECK(mesh_vtable_retain(vt, p, &err) == LM_ERR_INVALID_ARG);
    CHECK(mesh_vtable_release(vt, 12345, &err) == LM_ERR_INVALID_ARG);
    /* A different point now gets the recycled id. */
    uint32_t q = get(vt, 1, 1, 2, 1, 2);
    CHECK(q == p && refs(vt, q) == 1);
    const mesh_vertex *vq = mesh_vtable_vertex(vt, q);
    CHECK(vq && vq->tri == 1 && vq->bary.w[1] == 2 && vq->bary.depth == 2);
    mesh_vtable_stats st;
    mesh_vtable_get_stats(vt, &st);
    CHECK(st.live == 1 && st.id_limit == 1 && st.free_ids == 0 && st.created == 2 && st.freed == 1);

    /* Errors: depth, sums, triangles, NULLs. The table is unchanged. */
    uint32_t id = 7;
    CHECK(mesh_vtable_acquire(vt, 0, (mesh_bary){{1u << 30, 1u << 30, 0}, 31}, &id, &err) ==
          LM_ERR_UNSUPPORTED && id == MESH_VTABLE_NONE);
    CHECK(mesh_vtable_acquire(vt, 0, (mesh_bary){{1, 1, 1}, 2}, &id, &err) == LM_ERR_INVALID_ARG);
    CHECK(mesh_vtable_acquire(vt, 2, (mesh_bary){{1, 0, 0}, 0}, &id, &err) == LM_ERR_INVALID_ARG);
    CHECK(mesh_vtable_acquire(vt, 0, (mesh_bary){{UINT32_MAX, 2, 0}, 0}, &id, &err) == LM_ERR_INVALID_ARG);
    CHECK(mesh_vtable_acquire(NULL, 0, (mesh_bary){{1, 0, 0}, 0}, &id, &err) == LM_ERR_INVALID_ARG);
    CHECK(mesh_vtable_acquire(vt, 0, (mesh_bary){{1, 0, 0}, 0}, NULL, &err) == LM_ERR_INVALID_ARG);
    CHECK(mesh_vtable_find(vt, 0, (mesh_bary){{1, 1, 1}, 2}) == MESH_VTABLE_NONE);
    mesh_bary mid;
    CHECK(mesh_bary_midpoint((mesh_bary){{1u << 30, 0, 0}, 30}, (mesh_bary){{0, 1u << 30, 0}, 30}, &mid) ==
          LM_ERR_UNSUPPORTED);
    mesh_vtable_get_stats(vt, &st);
    CHECK(st.live == 1 && st.created == 2);
    mesh_vtable *bad = (mesh_vtable *)&t;
    CHECK(mesh_vtable_create(NULL, &bad, &err) == LM_ERR_INVALID_ARG && bad == NULL);
    mesh_vtable_desc d = {.scene = &t.s, .crease_tolerance_deg = -1};
    CHECK(mesh_vtable_create(&d, &bad, &err) == LM_ERR_INVALID_ARG);
    mesh_vtable_destroy(vt);
    mesh_vtable_destroy(NULL);
    mesh_geo_destroy(t.s.topology);
}

/* Scene vertices are kept by normal class, outside the hash map (vtable.c): the
 * same counting, freeing and recycling as any other point, and the hash map
 * holds none of them. */
static void test_scene_vertex_recycling(void)
{
    toy t;
    mesh_vtable *vt = square_table(&t);
    if (!vt) return;
    lm_error err = {{0}};
    /* Vertex 0: corner 0 of both triangles; vertex 2: corner 2 of the first, 1 of the second. */
    uint32_t a = get(vt, 0, 1, 0, 0, 0);
    CHECK(a != MESH_VTABLE_NONE && get(vt, 1, 1, 0, 0, 0) == a && get(vt, 0, 4, 0, 0, 2) == a && refs(vt, a) == 3);
    uint32_t c = get(vt, 0, 0, 0, 1, 0);
    CHECK(c != a && get(vt, 1, 0, 2, 0, 1) == c && refs(vt, c) == 2);
    mesh_vtable_stats st;
    mesh_vtable_get_stats(vt, &st);
    CHECK(st.live == 2 && st.max_probe == 0); /* no slot holds either */
    for (int k = 0; k < 3; ++k) CHECK(mesh_vtable_release(vt, a, &err) == LM_OK);
    CHECK(mesh_vtable_vertex(vt, a) == NULL && mesh_vtable_find(vt, 1, (mesh_bary){{1, 0, 0}, 0}) == MESH_VTABLE_NONE);
    CHECK(mesh_vtable_find(vt, 1, (mesh_bary){{0, 1, 0}, 0}) == c);
    /* Made again, from the other triangle: the recycled id, found from both. */
    uint32_t b = get(vt, 1, 1, 0, 0, 0);
    CHECK(b == a && refs(vt, b) == 1 && mesh_vtable_find(vt, 0, (mesh_bary){{2, 0, 0}, 1}) == b);
    const mesh_vertex *vb = mesh_vtable_vertex(vt, b);
    CHECK(vb && vb->tri == 1 && vb->position[0] == 0.0f && vb->position[1] == 0.0f);
    mesh_vtable_get_stats(vt, &st);
    CHECK(st.live == 2 && st.created == 3 && st.freed == 1);
    mesh_vtable_destroy(vt);
    mesh_geo_destroy(t.s.topology);
}

/* A million interior points of one triangle at depth 11: every key new, no two
 * conflated (ids 0..N-1 in order, found again), ten-odd rehashes, exact positions. */
static void test_growth(void)
{
    enum { N = 1000000, D = 11 };
    const float pos[] = {-1.25f, 0.5f, 3.0f, 7.5f, -0.125f, 2.0f, 0.3f, 9.1f, -4.7f};
    const uint32_t tv[] = {0, 1, 2};
    const float up[] = {0, 0, 1};
    toy t;
    toy_init(&t, pos, 3, tv, 1, up, NULL);
    mesh_vtable *vt = make_vt(&t.s, 0);
    uint32_t *ids = malloc(sizeof(uint32_t) * N);
    mesh_bary *pts = malloc(sizeof(mesh_bary) * N);
    CHECK(vt && ids && pts);
    if (!vt || !ids || !pts) goto done;
    uint32_t n = 0;
    const uint32_t S = 1u << D;
    for (uint32_t i = 1; i < S && n < N; ++i)
        for (uint32_t j = 1; i + j < S && n < N; ++j) {
            uint32_t l = S - i - j;
            if (((i | j | l) & 1u) == 0) continue; /* that point has a shallower form */
            pts[n++] = (mesh_bary){{i, j, l}, D};
        }
    CHECK(n == N);
    lm_error err = {{0}};
    long wrong = 0;
    double t0 = lm_now_seconds();
    for (uint32_t k = 0; k < N; ++k) {
        if (mesh_vtable_acquire(vt, 0, pts[k], &ids[k], &err) != LM_OK) {
            CHECK_MSG(0, "%s", err.msg);
            break;
        }
        wrong += ids[k] != k;
    }
    double t1 = lm_now_seconds();
    for (uint32_t k = 0; k < N; ++k) wrong += mesh_vtable_find(vt, 0, pts[k]) != ids[k];
    double t2 = lm_now_seconds();
    CHECK_MSG(wrong == 0, "%ld keys conflated or lost", wrong);
    mesh_vtable_stats st;
    mesh_vtable_get_stats(vt, &st);
    CHECK(st.live == N && st.rehashes >= 10);
    printf("vtable: %d vertices inserted in %.3f s (%.2f M/s), found in %.3f s (%.2f M/s); "
           "%u slots, %u rehashes, longest probe %u, %zu bytes = %.1f bytes/vertex\n",
           N, t1 - t0, N / (t1 - t0) * 1e-6, t2 - t1, N / (t2 - t1) * 1e-6, st.slots, st.rehashes,
           st.max_probe, st.bytes, mesh_vtable_bytes_per_vertex(vt));
    /* Exact positions: Σ w_i·P_i in double, corner order, scaled by 2^-D, rounded once. */
    long inexact = 0;
    for (uint32_t k = 0; k < N; k += 7) {
        const mesh_vertex *v = mesh_vtable_vertex(vt, ids[k]);
        for (int c = 0; c < 3; ++c) {
            double x = (double)pts[k].w[0] * pos[c] + (double)pts[k].w[1] * pos[3 + c];
            x += (double)pts[k].w[2] * pos[6 + c];
            inexact += !v || v->position[c] != (float)(x * ldexp(1.0, -D));
        }
        inexact += !v || v->tri != 0 || memcmp(&v->bary, &pts[k], sizeof v->bary) != 0;
    }
    CHECK_MSG(inexact == 0, "%ld positions or addresses differ", inexact);
    /* Release everything: the table empties; new points reuse old ids. */
    for (uint32_t k = 0; k < N; ++k) wrong += mesh_vtable_release(vt, ids[k], NULL) != LM_OK;
    mesh_vtable_get_stats(vt, &st);
    CHECK(wrong == 0 && st.live == 0 && st.free_ids == N && st.id_limit == N);
    uint32_t again = get(vt, 0, 1, 1, 0, 1);
    CHECK(again < N);
    mesh_vtable_get_stats(vt, &st);
    CHECK(st.id_limit == N && st.live == 1);
done:
    free(ids);
    free(pts);
    mesh_vtable_destroy(vt);
    mesh_geo_destroy(t.s.topology);
}

int main(void)
{
    test_canonical_forms();
    test_smooth_vertex_all_corners();
    test_crease();
    test_box_corner();
    test_refcount_and_recycling();
    test_scene_vertex_recycling();
    test_growth();
    return test_finish("mesh_vtable_test");
}
