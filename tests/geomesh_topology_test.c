/* geomesh_topology_test.c — edge neighbours, edge kinds and counts of mesh_geo
 * (geomesh.h): shared edges, closed and open surfaces, non-manifold and
 * inconsistently wound edges, degenerate and duplicate triangles, creases,
 * argument checking, the empty mesh and a 100,000-triangle grid. */
#include "mesh/geomesh.h"
#include "tests/test_util.h"

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

enum { B = MESH_EDGE_BOUNDARY, I = MESH_EDGE_INTERIOR, N = MESH_EDGE_NONMANIFOLD,
       C = MESH_EDGE_CREASE };

/* Topology does not depend on positions; tests that do not care use zeros. */
static const float k_zero_positions[3 * 16];

static mesh_geo *make(const float *pos, uint32_t nv, const uint32_t *tris, uint32_t nt,
                      const float *normals, float tol)
{
    mesh_geo_desc d = {.positions = pos ? pos : k_zero_positions, .vertex_count = nv,
                       .triangles = tris, .triangle_count = nt, .corner_normals = normals,
                       .crease_tolerance_deg = tol};
    mesh_geo *g = NULL;
    lm_error err = {{0}};
    lm_result r = mesh_geo_create(&d, &g, &err);
    CHECK_MSG(r == LM_OK, "mesh_geo_create: %s", err.msg);
    CHECK(r != LM_OK || g != NULL);
    return r == LM_OK ? g : NULL;
}

/* Expects exactly these kinds (3 per triangle), neighbours and neighbour edges. */
static void expect_sides(const mesh_geo *g, uint32_t nt, const int *kinds, const int *nbrs,
                         const int *nedges, const char *what)
{
    for (uint32_t t = 0; t < nt; ++t)
        for (int e = 0; e < 3; ++e) {
            int s = 3 * (int)t + e;
            CHECK_MSG((int)mesh_geo_edge_kind(g, t, e) == kinds[s], "%s: tri %u edge %d kind %d, want %d",
                      what, t, e, (int)mesh_geo_edge_kind(g, t, e), kinds[s]);
            CHECK_MSG(mesh_geo_neighbor(g, t, e) == nbrs[s], "%s: tri %u edge %d neighbour %d, want %d",
                      what, t, e, (int)mesh_geo_neighbor(g, t, e), nbrs[s]);
            CHECK_MSG(mesh_geo_neighbor_edge(g, t, e) == nedges[s],
                      "%s: tri %u edge %d neighbour edge %d, want %d", what, t, e,
                      mesh_geo_neighbor_edge(g, t, e), nedges[s]);
        }
}

static void expect_stats(const mesh_geo *g, uint32_t interior, uint32_t boundary,
                         uint32_t nonmanifold, uint32_t crease, uint32_t rejected, const char *what)
{
    mesh_geo_stats st;
    memset(&st, 0xAB, sizeof st);
    mesh_geo_get_stats(g, &st);
    CHECK_MSG(st.sides[MESH_EDGE_INTERIOR] == interior, "%s: interior %u, want %u", what,
              st.sides[MESH_EDGE_INTERIOR], interior);
    CHECK_MSG(st.sides[MESH_EDGE_BOUNDARY] == boundary, "%s: boundary %u, want %u", what,
              st.sides[MESH_EDGE_BOUNDARY], boundary);
    CHECK_MSG(st.sides[MESH_EDGE_NONMANIFOLD] == nonmanifold, "%s: nonmanifold %u, want %u", what,
              st.sides[MESH_EDGE_NONMANIFOLD], nonmanifold);
    CHECK_MSG(st.sides[MESH_EDGE_CREASE] == crease, "%s: crease %u, want %u", what,
              st.sides[MESH_EDGE_CREASE], crease);
    CHECK_MSG(st.rejected_triangles == rejected, "%s: rejected %u, want %u", what,
              st.rejected_triangles, rejected);
}

/* Every side of every triangle: a neighbour points back at us through the
 * neighbour edge, shares our two vertices in the opposite direction and is
 * INTERIOR; no neighbour means neighbour edge -1 and a non-interior kind; the
 * stats agree with the per-side kinds. One CHECK for the lot (the grid has
 * 300,000 sides); the first problem is described. */
static void check_consistent(const mesh_geo *g, const uint32_t *tris, uint32_t nt, const char *what)
{
    uint32_t count[MESH_EDGE_KIND_COUNT] = {0};
    long bad = 0;
    char first[256] = "";
    for (uint32_t t = 0; t < nt; ++t)
        for (int e = 0; e < 3; ++e) {
            int32_t n = mesh_geo_neighbor(g, t, e);
            int k = mesh_geo_neighbor_edge(g, t, e);
            mesh_edge_kind kind = mesh_geo_edge_kind(g, t, e);
            const char *why = NULL;
            if ((int)kind < 0 || kind >= MESH_EDGE_KIND_COUNT) {
                why = "kind out of range";
            } else {
                count[kind]++;
                if (n >= 0) {
                    const uint32_t *a = tris + 3 * (size_t)t, *b = tris + 3 * (size_t)n;
                    if ((uint32_t)n >= nt) why = "neighbour out of range";
                    else if (kind != MESH_EDGE_INTERIOR) why = "neighbour on a non-interior side";
                    else if (k < 0 || k > 2) why = "neighbour edge out of range";
                    else if (mesh_geo_neighbor(g, (uint32_t)n, k) != (int32_t)t) why = "not mutual";
                    else if (mesh_geo_neighbor_edge(g, (uint32_t)n, k) != e) why = "edge not mutual";
                    else if (b[k] != a[(e + 1) % 3] || b[(k + 1) % 3] != a[e]) why = "wrong vertices";
                } else if (k != -1) {
                    why = "neighbour edge without a neighbour";
                } else if (kind == MESH_EDGE_INTERIOR) {
                    why = "interior side without a neighbour";
                }
            }
            if (why && bad++ == 0)
                snprintf(first, sizeof first, "tri %u edge %d: %s (n %d, k %d, kind %d)", t, e, why,
                         (int)n, k, (int)kind);
        }
    CHECK_MSG(bad == 0, "%s: %ld inconsistent sides, first: %s", what, bad, first);
    mesh_geo_stats st;
    mesh_geo_get_stats(g, &st);
    int same = 1;
    for (int i = 0; i < MESH_EDGE_KIND_COUNT; ++i) same &= st.sides[i] == count[i];
    CHECK_MSG(same, "%s: stats disagree with the per-side kinds", what);
}

static void test_two_triangles(void)
{
    /* 0-1-2 and 2-1-3 share the edge 1-2: edge 1 of tri 0 (1->2), edge 0 of tri 1 (2->1). */
    const float pos[] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0};
    const uint32_t tris[] = {0, 1, 2, 2, 1, 3};
    mesh_geo *g = make(pos, 4, tris, 2, NULL, 0);
    if (!g) return;
    const int kinds[] = {B, I, B, I, B, B};
    const int nbrs[] = {-1, 1, -1, 0, -1, -1};
    const int nedges[] = {-1, 0, -1, 1, -1, -1};
    expect_sides(g, 2, kinds, nbrs, nedges, "two triangles");
    expect_stats(g, 2, 4, 0, 0, 0, "two triangles");
    check_consistent(g, tris, 2, "two triangles");
    mesh_geo_destroy(g);
}

static void test_tetrahedron(void)
{
    const float pos[] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1};
    /* Outward-facing, consistently wound: every edge appears once each way. */
    const uint32_t tris[] = {0, 2, 1, 0, 1, 3, 1, 2, 3, 0, 3, 2};
    mesh_geo *g = make(pos, 4, tris, 4, NULL, 0);
    if (!g) return;
    /* tri 0 (0,2,1): 0->2 is 2->0 = edge 2 of tri 3; 2->1 is 1->2 = edge 0 of tri 2;
     * 1->0 is 0->1 = edge 0 of tri 1. And so on round the other three. */
    const int kinds[] = {I, I, I, I, I, I, I, I, I, I, I, I};
    const int nbrs[] = {3, 2, 1, 0, 2, 3, 0, 3, 1, 1, 2, 0};
    const int nedges[] = {2, 0, 0, 2, 2, 0, 1, 1, 1, 2, 1, 0};
    expect_sides(g, 4, kinds, nbrs, nedges, "tetrahedron");
    expect_stats(g, 12, 0, 0, 0, 0, "tetrahedron");
    check_consistent(g, tris, 4, "tetrahedron");
    mesh_geo_destroy(g);
}

static void test_quad_strip(void)
{
    /* 5 quads in a row: bottom vertices 0..5, top vertices 6..11; quad i is
     * (i, i+1, i+7) and (i, i+7, i+6). Edges: 5 diagonals + 4 rungs interior,
     * 10 long sides + 2 ends boundary: 18 interior sides, 12 boundary sides. */
    enum { Q = 5 };
    float pos[3 * 2 * (Q + 1)];
    uint32_t tris[3 * 2 * Q];
    for (int i = 0; i <= Q; ++i) {
        float *b = pos + 3 * i, *t = pos + 3 * (Q + 1 + i);
        b[0] = (float)i, b[1] = 0, b[2] = 0;
        t[0] = (float)i, t[1] = 1, t[2] = 0;
    }
    for (uint32_t i = 0; i < Q; ++i) {
        uint32_t b0 = i, b1 = i + 1, t0 = Q + 1 + i, t1 = Q + 2 + i;
        uint32_t *q = tris + 6 * i;
        q[0] = b0, q[1] = b1, q[2] = t1;
        q[3] = b0, q[4] = t1, q[5] = t0;
    }
    mesh_geo *g = make(pos, 2 * (Q + 1), tris, 2 * Q, NULL, 0);
    if (!g) return;
    expect_stats(g, 4 * Q - 2, 2 * Q + 2, 0, 0, 0, "quad strip");
    check_consistent(g, tris, 2 * Q, "quad strip");
    /* tri 0 = (0,1,7): bottom side, rung 1->7 (edge 2 of tri 3 = (1,8,7)), diagonal 7->0
     * (edge 0 of tri 1 = (0,7,6)). tri 1 = (0,7,6): edge 2 (6->0) is the left end. */
    CHECK(mesh_geo_edge_kind(g, 0, 0) == MESH_EDGE_BOUNDARY);
    CHECK(mesh_geo_neighbor(g, 0, 1) == 3 && mesh_geo_neighbor_edge(g, 0, 1) == 2);
    CHECK(mesh_geo_neighbor(g, 0, 2) == 1 && mesh_geo_neighbor_edge(g, 0, 2) == 0);
    CHECK(mesh_geo_edge_kind(g, 1, 2) == MESH_EDGE_BOUNDARY);
    CHECK(mesh_geo_edge_kind(g, 2 * Q - 2, 1) == MESH_EDGE_BOUNDARY); /* right end */
    mesh_geo_destroy(g);
}

static void test_three_on_one_edge(void)
{
    /* Edge 0-1 carries three triangles (a "book"): 0 and 1 join, 2 cannot. */
    const uint32_t tris[] = {0, 1, 2, 1, 0, 3, 0, 1, 4};
    mesh_geo *g = make(NULL, 5, tris, 3, NULL, 0);
    if (!g) return;
    const int kinds[] = {N, B, B, N, B, B, N, B, B};
    const int nbrs[] = {-1, -1, -1, -1, -1, -1, -1, -1, -1};
    expect_sides(g, 3, kinds, nbrs, nbrs, "three on one edge");
    expect_stats(g, 0, 6, 3, 0, 1, "three on one edge");
    check_consistent(g, tris, 3, "three on one edge");
    mesh_geo_destroy(g);

    /* Four on one edge, two consistent pairs: still nobody crosses it. */
    const uint32_t four[] = {0, 1, 2, 1, 0, 3, 0, 1, 4, 1, 0, 5};
    g = make(NULL, 6, four, 4, NULL, 0);
    if (!g) return;
    for (uint32_t t = 0; t < 4; ++t) {
        CHECK(mesh_geo_neighbor(g, t, 0) == -1);
        CHECK(mesh_geo_edge_kind(g, t, 0) == MESH_EDGE_NONMANIFOLD);
    }
    expect_stats(g, 0, 8, 4, 0, 2, "four on one edge");
    check_consistent(g, four, 4, "four on one edge");
    mesh_geo_destroy(g);
}

static void test_inconsistent_winding(void)
{
    /* Both triangles run 0->1: opposite orientations across the shared edge. */
    const uint32_t tris[] = {0, 1, 2, 0, 1, 3};
    mesh_geo *g = make(NULL, 4, tris, 2, NULL, 0);
    if (!g) return;
    const int kinds[] = {N, B, B, N, B, B};
    const int nbrs[] = {-1, -1, -1, -1, -1, -1};
    expect_sides(g, 2, kinds, nbrs, nbrs, "inconsistent pair");
    expect_stats(g, 0, 4, 2, 0, 1, "inconsistent pair");
    mesh_geo_destroy(g);

    /* A strip 0-1-2, 1-3-2, 2-3-4 with its middle triangle flipped to (1,2,3):
     * it is refused, and both edges it shares (1-2 with tri 0, 2-3 with tri 2,
     * which was added after it) become non-manifold; its edge 3-1 is a boundary. */
    const uint32_t strip[] = {0, 1, 2, 1, 2, 3, 2, 3, 4};
    g = make(NULL, 5, strip, 3, NULL, 0);
    if (!g) return;
    const int skinds[] = {B, N, B, N, N, B, N, B, B};
    const int snbrs[] = {-1, -1, -1, -1, -1, -1, -1, -1, -1};
    expect_sides(g, 3, skinds, snbrs, snbrs, "flipped strip");
    expect_stats(g, 0, 5, 4, 0, 1, "flipped strip");
    check_consistent(g, strip, 3, "flipped strip");
    mesh_geo_destroy(g);

    /* The same strip wound consistently: two interior edges. */
    const uint32_t good[] = {0, 1, 2, 1, 3, 2, 2, 3, 4};
    g = make(NULL, 5, good, 3, NULL, 0);
    if (!g) return;
    expect_stats(g, 4, 5, 0, 0, 0, "consistent strip");
    CHECK(mesh_geo_neighbor(g, 0, 1) == 1 && mesh_geo_neighbor_edge(g, 0, 1) == 2);
    CHECK(mesh_geo_neighbor(g, 1, 1) == 2 && mesh_geo_neighbor_edge(g, 1, 1) == 0);
    mesh_geo_destroy(g);
}

static void test_degenerate_and_duplicate(void)
{
    /* A repeated vertex id is refused (OpenMesh cannot take it); its edge 0-1
     * exists in the main mesh, so that edge is cut off; 1-1 is a boundary. */
    const uint32_t degen[] = {0, 1, 2, 1, 0, 3, 0, 1, 1};
    mesh_geo *g = make(NULL, 4, degen, 3, NULL, 0);
    if (!g) return;
    const int kinds[] = {N, B, B, N, B, B, N, B, N};
    const int nbrs[] = {-1, -1, -1, -1, -1, -1, -1, -1, -1};
    expect_sides(g, 3, kinds, nbrs, nbrs, "degenerate");
    expect_stats(g, 0, 5, 4, 0, 1, "degenerate");
    mesh_geo_destroy(g);

    /* The same triangle twice: all three edges of both are non-manifold. */
    const uint32_t dup[] = {0, 1, 2, 0, 1, 2};
    g = make(NULL, 3, dup, 2, NULL, 0);
    if (!g) return;
    expect_stats(g, 0, 0, 6, 0, 1, "duplicate");
    check_consistent(g, dup, 2, "duplicate");
    mesh_geo_destroy(g);

    /* Unused vertices are fine. */
    const uint32_t one[] = {3, 5, 7};
    g = make(NULL, 10, one, 1, NULL, 0);
    if (!g) return;
    expect_stats(g, 0, 3, 0, 0, 0, "one triangle");
    mesh_geo_destroy(g);
}

static void set3(float *n, float x, float y, float z)
{
    n[0] = x, n[1] = y, n[2] = z;
}

static void test_crease(void)
{
    /* Tri 0 (0,1,2) lies in z = 0 (normal +z); tri 1 (1,0,3) stands up at 90
     * degrees (normal +y... or -y; only the difference matters). Shared edge 0-1
     * is edge 0 of both. */
    const float pos[] = {0, 0, 0, 1, 0, 0, 0.5f, 1, 0, 0.5f, 0, 1};
    const uint32_t tris[] = {0, 1, 2, 1, 0, 3};
    float n[18];

    /* Flat per-corner normals: a crease on both sides, no neighbour. */
    for (int c = 0; c < 3; ++c) set3(n + 3 * c, 0, 0, 1);
    for (int c = 3; c < 6; ++c) set3(n + 3 * c, 0, 1, 0);
    mesh_geo *g = make(pos, 4, tris, 2, n, 0);
    if (!g) return;
    const int kinds[] = {C, B, B, C, B, B};
    const int nbrs[] = {-1, -1, -1, -1, -1, -1};
    expect_sides(g, 2, kinds, nbrs, nbrs, "flat crease");
    expect_stats(g, 0, 4, 0, 2, 0, "flat crease");
    check_consistent(g, tris, 2, "flat crease");
    mesh_geo_destroy(g);

    /* Without normals there is no crease test: interior. */
    g = make(pos, 4, tris, 2, NULL, 0);
    if (!g) return;
    expect_stats(g, 2, 4, 0, 0, 0, "no normals");
    mesh_geo_destroy(g);

    /* Smooth: the shared vertices carry the same (averaged) normal on both
     * sides; the unshared corners may differ freely. */
    const float h = 0.70710678f;
    set3(n + 0, 0, h, h);  /* tri 0 corner 0 = vertex 0 */
    set3(n + 3, 0, h, h);  /* tri 0 corner 1 = vertex 1 */
    set3(n + 6, 0, 0, 1);  /* vertex 2 */
    set3(n + 9, 0, h, h);  /* tri 1 corner 0 = vertex 1 */
    set3(n + 12, 0, h, h); /* tri 1 corner 1 = vertex 0 */
    set3(n + 15, 0, 1, 0); /* vertex 3 */
    g = make(pos, 4, tris, 2, n, 0);
    if (!g) return;
    const int skinds[] = {I, B, B, I, B, B};
    const int snbrs[] = {1, -1, -1, 0, -1, -1};
    const int sedges[] = {0, -1, -1, 0, -1, -1};
    expect_sides(g, 2, skinds, snbrs, sedges, "smooth");
    expect_stats(g, 2, 4, 0, 0, 0, "smooth");
    mesh_geo_destroy(g);

    /* Disagreeing at one end point only is enough (vertex 1 here). */
    set3(n + 9, 0, 0, 1);
    g = make(pos, 4, tris, 2, n, 0);
    if (!g) return;
    expect_stats(g, 0, 4, 0, 2, 0, "one end");
    mesh_geo_destroy(g);
    set3(n + 9, 0, h, h);

    /* Tolerance: 0.3 degrees apart agrees under the default 0.5; 1 degree does
     * not, unless the tolerance is raised to 2 degrees. Non-unit lengths do not matter. */
    const double d03 = 0.3 * 3.14159265358979 / 180.0, d1 = 1.0 * 3.14159265358979 / 180.0;
    for (int c = 0; c < 6; ++c) set3(n + 3 * c, 0, 0, 1);
    set3(n + 12, (float)(2.0 * sin(d03)), 0, (float)(2.0 * cos(d03))); /* vertex 0 on tri 1 */
    g = make(pos, 4, tris, 2, n, 0);
    if (!g) return;
    expect_stats(g, 2, 4, 0, 0, 0, "0.3 degrees");
    mesh_geo_destroy(g);
    set3(n + 12, (float)sin(d1), 0, (float)cos(d1));
    g = make(pos, 4, tris, 2, n, 0);
    if (!g) return;
    expect_stats(g, 0, 4, 0, 2, 0, "1 degree, default tolerance");
    mesh_geo_destroy(g);
    g = make(pos, 4, tris, 2, n, 2.0f);
    if (!g) return;
    expect_stats(g, 2, 4, 0, 0, 0, "1 degree, tolerance 2");
    mesh_geo_destroy(g);

    /* A zero normal facing a real one cannot be judged: crease. Two identical
     * zero normals agree. */
    set3(n + 12, 0, 0, 0);
    g = make(pos, 4, tris, 2, n, 0);
    if (!g) return;
    expect_stats(g, 0, 4, 0, 2, 0, "zero normal");
    mesh_geo_destroy(g);
    set3(n + 3, 0, 0, 0);  /* tri 0's vertex 1 */
    set3(n + 9, 0, 0, 0);  /* tri 1's vertex 1 */
    set3(n + 0, 0, 0, 0);  /* tri 0's vertex 0, now equal to tri 1's */
    g = make(pos, 4, tris, 2, n, 0);
    if (!g) return;
    expect_stats(g, 2, 4, 0, 0, 0, "identical zero normals");
    mesh_geo_destroy(g);
}

static void test_invalid_arguments(void)
{
    const uint32_t tris[] = {0, 1, 2, 2, 1, 3};
    mesh_geo_desc d = {.positions = k_zero_positions, .vertex_count = 3, .triangles = tris,
                       .triangle_count = 2};
    mesh_geo *g = (mesh_geo *)&d; /* must be overwritten with NULL */
    lm_error err = {{0}};

    /* Vertex 3 with only 3 vertices. */
    CHECK(mesh_geo_create(&d, &g, &err) == LM_ERR_INVALID_ARG);
    CHECK(g == NULL);
    CHECK(err.msg[0] != '\0');
    CHECK_MSG(strstr(err.msg, "triangle 1") != NULL && strstr(err.msg, "vertex 3") != NULL,
              "message: %s", err.msg);
    printf("out-of-range message: %s\n", err.msg);
    CHECK(mesh_geo_create(&d, &g, NULL) == LM_ERR_INVALID_ARG); /* err may be NULL */

    mesh_geo_desc ok = d;
    ok.vertex_count = 4;
    err.msg[0] = '\0';
    CHECK(mesh_geo_create(NULL, &g, &err) == LM_ERR_INVALID_ARG && err.msg[0] != '\0');
    err.msg[0] = '\0';
    CHECK(mesh_geo_create(&ok, NULL, &err) == LM_ERR_INVALID_ARG && err.msg[0] != '\0');

    mesh_geo_desc bad = ok;
    bad.triangles = NULL;
    err.msg[0] = '\0';
    CHECK(mesh_geo_create(&bad, &g, &err) == LM_ERR_INVALID_ARG && err.msg[0] != '\0');
    bad = ok;
    bad.positions = NULL;
    err.msg[0] = '\0';
    CHECK(mesh_geo_create(&bad, &g, &err) == LM_ERR_INVALID_ARG && err.msg[0] != '\0');
    bad = ok;
    bad.crease_tolerance_deg = -1.0f;
    err.msg[0] = '\0';
    CHECK(mesh_geo_create(&bad, &g, &err) == LM_ERR_INVALID_ARG && err.msg[0] != '\0');
    bad.crease_tolerance_deg = NAN;
    CHECK(mesh_geo_create(&bad, &g, &err) == LM_ERR_INVALID_ARG);
    bad.crease_tolerance_deg = 181.0f;
    CHECK(mesh_geo_create(&bad, &g, &err) == LM_ERR_INVALID_ARG);

    /* Too many triangles is refused before any triangle is read. */
    bad = ok;
    bad.triangle_count = 400000000u;
    err.msg[0] = '\0';
    CHECK(mesh_geo_create(&bad, &g, &err) == LM_ERR_UNSUPPORTED && err.msg[0] != '\0');
    CHECK(g == NULL);

    /* And the fixed desc works. */
    CHECK(mesh_geo_create(&ok, &g, &err) == LM_OK && g != NULL);
    if (g) {
        /* Out-of-range queries answer "nothing across" instead of reading out of bounds. */
        CHECK(mesh_geo_neighbor(g, 2, 0) == -1);
        CHECK(mesh_geo_neighbor(g, 0, 3) == -1);
        CHECK(mesh_geo_neighbor(g, 0, -1) == -1);
        CHECK(mesh_geo_neighbor_edge(g, 2, 0) == -1);
        CHECK(mesh_geo_edge_kind(g, 2, 0) == MESH_EDGE_BOUNDARY);
        CHECK(mesh_geo_neighbor(NULL, 0, 0) == -1);
        mesh_geo_get_stats(g, NULL);
    }
    mesh_geo_destroy(g);
    mesh_geo_destroy(NULL);
}

static void test_empty(void)
{
    mesh_geo_desc d = {0};
    mesh_geo *g = NULL;
    lm_error err = {{0}};
    CHECK_MSG(mesh_geo_create(&d, &g, &err) == LM_OK, "%s", err.msg);
    CHECK(g != NULL);
    expect_stats(g, 0, 0, 0, 0, 0, "empty");
    CHECK(mesh_geo_neighbor(g, 0, 0) == -1);
    mesh_geo_destroy(g);

    /* Vertices but no triangles. */
    d.positions = k_zero_positions;
    d.vertex_count = 16;
    g = NULL;
    CHECK_MSG(mesh_geo_create(&d, &g, &err) == LM_OK, "%s", err.msg);
    expect_stats(g, 0, 0, 0, 0, 0, "no triangles");
    mesh_geo_destroy(g);

    mesh_geo_stats st;
    memset(&st, 0xAB, sizeof st);
    mesh_geo_get_stats(NULL, &st);
    CHECK(st.sides[MESH_EDGE_INTERIOR] == 0 && st.rejected_triangles == 0);
}

static double now_seconds(void)
{
    struct timespec ts;
    timespec_get(&ts, TIME_UTC);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* A W x H grid of unit quads, vertex (i,j) = j*(W+1)+i, quad q = j*W+i split
 * into 2q = (v00,v10,v11) and 2q+1 = (v00,v11,v01). */
enum { GW = 250, GH = 200, GT = 2 * GW * GH }; /* 100,000 triangles */

static void test_grid(void)
{
    const uint32_t nv = (GW + 1) * (GH + 1);
    float *pos = malloc(sizeof(float) * 3 * nv);
    uint32_t *tris = malloc(sizeof(uint32_t) * 3 * GT);
    float *nrm = malloc(sizeof(float) * 9 * GT);
    CHECK(pos && tris && nrm);
    if (!pos || !tris || !nrm) {
        free(pos), free(tris), free(nrm);
        return;
    }
    for (uint32_t j = 0; j <= GH; ++j)
        for (uint32_t i = 0; i <= GW; ++i)
            set3(pos + 3 * (j * (GW + 1) + i), (float)i, (float)j, 0);
    for (uint32_t j = 0; j < GH; ++j)
        for (uint32_t i = 0; i < GW; ++i) {
            uint32_t q = j * GW + i, v00 = j * (GW + 1) + i, v10 = v00 + 1, v01 = v00 + GW + 1,
                     v11 = v01 + 1;
            uint32_t *t = tris + 6 * q;
            t[0] = v00, t[1] = v10, t[2] = v11;
            t[3] = v00, t[4] = v11, t[5] = v01;
        }

    /* Edges: 201 rows of 250 + 251 columns of 200 + 50,000 diagonals = 150,450,
     * of which 2*250 + 2*200 = 900 on the border: 149,550 interior edges. */
    double t0 = now_seconds();
    mesh_geo *g = make(pos, nv, tris, GT, NULL, 0);
    double dt = now_seconds() - t0;
    /* Timing is printed, not asserted: speed targets live in bench/, and this
     * also runs under the sanitizers on a loaded machine. */
    printf("grid %dx%d (%d triangles): built in %.3f s\n", GW, GH, GT, dt);
    if (g) {
        expect_stats(g, 299100, 900, 0, 0, 0, "grid");
        check_consistent(g, tris, GT, "grid");
        /* Quad (10,20): its lower triangle's bottom, right and diagonal neighbours. */
        uint32_t q = 20 * GW + 10, lo = 2 * q;
        CHECK(mesh_geo_neighbor(g, lo, 0) == (int32_t)(2 * (q - GW) + 1));
        CHECK(mesh_geo_neighbor_edge(g, lo, 0) == 1);
        CHECK(mesh_geo_neighbor(g, lo, 1) == (int32_t)(2 * (q + 1) + 1));
        CHECK(mesh_geo_neighbor_edge(g, lo, 1) == 2);
        CHECK(mesh_geo_neighbor(g, lo, 2) == (int32_t)(lo + 1));
        CHECK(mesh_geo_neighbor_edge(g, lo, 2) == 0);
        /* Corner quad (0,0): bottom side and the upper triangle's left side are borders. */
        CHECK(mesh_geo_edge_kind(g, 0, 0) == MESH_EDGE_BOUNDARY);
        CHECK(mesh_geo_edge_kind(g, 1, 2) == MESH_EDGE_BOUNDARY);
        mesh_geo_destroy(g);
    }

    /* Smooth normals (a function of the vertex only): no creases at all. */
    for (uint32_t k = 0; k < 3 * GT; ++k) {
        const float *p = pos + 3 * tris[k];
        float x = 0.01f * p[0] - 1.0f, y = 0.01f * p[1] - 1.0f, l = sqrtf(x * x + y * y + 1.0f);
        set3(nrm + 3 * k, x / l, y / l, 1.0f / l);
    }
    g = make(pos, nv, tris, GT, nrm, 0);
    if (g) {
        expect_stats(g, 299100, 900, 0, 0, 0, "smooth grid");
        mesh_geo_destroy(g);
    }

    /* Flat normals folding by 10 degrees at x = 125: the 200 unit edges on that
     * line become creases (400 sides), nothing else changes. */
    const double a = 10.0 * 3.14159265358979 / 180.0;
    for (uint32_t t = 0; t < GT; ++t) {
        uint32_t i = (t / 2) % GW;
        for (int c = 0; c < 3; ++c) {
            if (i < GW / 2) set3(nrm + 9 * t + 3 * c, 0, 0, 1);
            else set3(nrm + 9 * t + 3 * c, (float)sin(a), 0, (float)cos(a));
        }
    }
    g = make(pos, nv, tris, GT, nrm, 0);
    if (g) {
        expect_stats(g, 299100 - 400, 900, 0, 400, 0, "folded grid");
        check_consistent(g, tris, GT, "folded grid");
        /* Quad (124, j)'s lower triangle edge 1 lies on the fold; so does quad (125, j)'s
         * upper triangle edge 2. */
        uint32_t q = 7 * GW + 124;
        CHECK(mesh_geo_edge_kind(g, 2 * q, 1) == MESH_EDGE_CREASE);
        CHECK(mesh_geo_neighbor(g, 2 * q, 1) == -1);
        CHECK(mesh_geo_edge_kind(g, 2 * (q + 1) + 1, 2) == MESH_EDGE_CREASE);
        CHECK(mesh_geo_edge_kind(g, 2 * (q - 1), 1) == MESH_EDGE_INTERIOR);
        mesh_geo_destroy(g);
    }

    /* One triangle added a second time in the middle of the grid: it is refused
     * and its three edges are cut off from the two quads' worth of neighbours. */
    uint32_t *more = malloc(sizeof(uint32_t) * 3 * (GT + 1));
    CHECK(more != NULL);
    if (more) {
        memcpy(more, tris, sizeof(uint32_t) * 3 * GT);
        uint32_t q = 100 * GW + 100;
        memcpy(more + 3 * GT, tris + 6 * q, sizeof(uint32_t) * 3);
        g = make(pos, nv, more, GT + 1, NULL, 0);
        if (g) {
            /* 3 interior edges lose both sides (6), the copy adds 3 non-manifold sides. */
            expect_stats(g, 299100 - 6, 900, 9, 0, 1, "grid with a duplicate");
            check_consistent(g, more, GT + 1, "grid with a duplicate");
            mesh_geo_destroy(g);
        }
        free(more);
    }

    free(pos);
    free(tris);
    free(nrm);
}

int main(void)
{
    test_two_triangles();
    test_tetrahedron();
    test_quad_strip();
    test_three_on_one_edge();
    test_inconsistent_winding();
    test_degenerate_and_duplicate();
    test_crease();
    test_invalid_arguments();
    test_empty();
    test_grid();
    return test_finish("geomesh_topology_test");
}
