/* geomesh_openmesh.cpp — geomesh.h on top of OpenMesh 9: which triangle lies
 * across each edge of each scene triangle.
 *
 * Why: the radiance cache meshes of Fournier & Péroche 2005 (§4.1) are quadtrees
 * over the scene triangles. When a cache mesh element is split, the split point
 * lands on an edge of the underlying triangle and the split must propagate to
 * the triangle across that edge, or the two cache meshes no longer share
 * vertices there (T-junctions, visible seams in the interpolated radiance). So
 * every triangle side needs its neighbour, and we must know where there is
 * none: at a boundary, at a non-manifold edge, or at a shading crease where the
 * radiance is not continuous anyway and a split must not cross.
 *
 * How:
 *  1. Every triangle goes into an OpenMesh TriMesh in input order, so OpenMesh
 *     face i is triangle i. Vertex i of the desc is OpenMesh vertex i.
 *  2. A triangle OpenMesh refuses (add_face fails on a complex edge, a complex
 *     vertex or a failed patch re-link: three or more triangles on an edge, two
 *     wound inconsistently, duplicates) — and a degenerate triangle (a repeated
 *     vertex id, which OpenMesh's add_face does not allow at all) — is added
 *     instead as an isolated face on three fresh duplicate vertices and counted
 *     in stats.rejected_triangles. OpenMesh's "complex edge" messages on omerr()
 *     are switched off while building (and the previous state restored).
 *  3. After all triangles are in, every edge of the main mesh that a rejected
 *     triangle would have used (find_halfedge in either direction) is marked
 *     non-manifold in an OpenMesh edge property. Doing this after all faces are
 *     in makes it independent of where the rejected triangle sits in the input.
 *     Triangles across a marked edge get no neighbour (MESH_EDGE_NONMANIFOLD).
 *     A rejected triangle's own sides are MESH_EDGE_NONMANIFOLD where the edge
 *     exists in the main mesh and MESH_EDGE_BOUNDARY otherwise; it never has a
 *     neighbour. This is deliberately conservative: a triangle refused for a
 *     complex vertex also cuts its (possibly clean) edges off.
 *  4. For an accepted triangle, the neighbour across edge e (corners e and
 *     (e+1)%3) is the face of the opposite halfedge; the neighbour's edge index
 *     is the corner of the neighbour where that opposite halfedge starts.
 *  5. Creases (only when corner_normals is given): across an interior edge the
 *     two triangles' corner normals are compared at both end points; if either
 *     pair differs by more than crease_tolerance_deg (0 means 0.5 degrees), both
 *     sides become MESH_EDGE_CREASE with no neighbour. Normals are normalised
 *     before comparing; identical vectors always agree; a zero-length or
 *     non-finite normal that is not identical to the other side's counts as
 *     disagreeing (no propagation across data we cannot judge).
 *
 * The results live in flat arrays (neighbour int32, neighbour edge int8, kind
 * uint8; three per triangle) so a query is O(1), allocation-free and safe from
 * any number of threads. The OpenMesh object is dropped after building: nothing
 * in geomesh.h reaches it, and it costs over 3x the flat arrays (about 60
 * bytes per triangle — 1.5 edges of two 16-byte halfedges, half a vertex, a
 * face — against 18), which for a 10M-triangle scene is ~600 MB held for
 * nothing.
 *
 * Limits: at most 357,913,941 triangles and vertex_count + 3 * triangle_count
 * at most 2^31-1 (OpenMesh handles are int: 6 halfedges per triangle at worst,
 * 3 fresh vertices per rejected triangle); beyond that LM_ERR_UNSUPPORTED.
 * Creation is not thread safe: omerr() is process-global, so OpenMesh error
 * output from other threads is silenced too while a mesh is built.
 *
 * Queries with a NULL mesh, tri >= triangle_count or edge outside 0..2 return
 * -1 / -1 / MESH_EDGE_BOUNDARY ("nothing across"), never read out of bounds.
 *
 * Every C++ exception stops here: std::bad_alloc -> LM_ERR_NO_MEMORY, anything
 * else -> LM_ERR_RUNTIME.
 */
#include "mesh/geomesh.h"

/* OpenMesh's PropertyT<Vec3f>::push_back() copies a default-constructed (by
 * design uninitialised) VectorT; GCC 12 at -O2 reports that through inlining
 * even from a system header. Silenced for OpenMesh's headers only. */
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif
#include <OpenMesh/Core/Mesh/TriMesh_ArrayKernelT.hh>
#include <OpenMesh/Core/System/omstream.hh>
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic pop
#endif

#include <climits>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <exception>
#include <new>
#include <vector>

struct mesh_geo {
    uint32_t triangle_count = 0;
    std::vector<int32_t> neighbor;      /* 3 per triangle; -1: none */
    std::vector<int8_t> neighbor_edge;  /* 3 per triangle; -1: none */
    std::vector<uint8_t> kind;          /* 3 per triangle; mesh_edge_kind */
    mesh_geo_stats stats = {};
};

namespace {

typedef OpenMesh::TriMesh_ArrayKernelT<> OmMesh;

const double kDefaultCreaseDeg = 0.5;
const double kPi = 3.14159265358979323846;
/* OpenMesh handles are int; 3 edges (6 halfedges) per triangle at worst. */
const uint64_t kMaxTriangles = (uint64_t)INT_MAX / 6;

/* Switches omerr() off for its lifetime and restores the previous state.
 * A pending partial line is flushed first so that it is not lost. */
class OmErrSilencer {
public:
    OmErrSilencer() : was_enabled_(::omerr().is_enabled())
    {
        if (was_enabled_) ::omerr().flush();
        ::omerr().disable();
    }
    ~OmErrSilencer()
    {
        if (was_enabled_) ::omerr().enable();
    }
    OmErrSilencer(const OmErrSilencer &) = delete;
    OmErrSilencer &operator=(const OmErrSilencer &) = delete;

private:
    bool was_enabled_;
};

/* True when the two corner normals agree within cos_tol (cosine of the
 * tolerance angle). See the file comment for zero and non-finite normals. */
bool normals_agree(const float *a, const float *b, double cos_tol)
{
    if (a[0] == b[0] && a[1] == b[1] && a[2] == b[2]) return true;
    double ax = a[0], ay = a[1], az = a[2];
    double bx = b[0], by = b[1], bz = b[2];
    double la = std::sqrt(ax * ax + ay * ay + az * az);
    double lb = std::sqrt(bx * bx + by * by + bz * bz);
    if (!(la > 1e-20 && lb > 1e-20) || !std::isfinite(la) || !std::isfinite(lb)) return false;
    double c = (ax * bx + ay * by + az * bz) / (la * lb);
    return c >= cos_tol;
}

lm_result validate(const mesh_geo_desc *d, lm_error *err)
{
    if (d->vertex_count > 0 && !d->positions)
        return lm_fail(err, LM_ERR_INVALID_ARG,
                       "geometric mesh: positions is NULL but vertex_count is %u",
                       (unsigned)d->vertex_count);
    if (d->triangle_count > 0 && !d->triangles)
        return lm_fail(err, LM_ERR_INVALID_ARG,
                       "geometric mesh: triangles is NULL but triangle_count is %u",
                       (unsigned)d->triangle_count);
    if (!(d->crease_tolerance_deg >= 0.0f && d->crease_tolerance_deg <= 180.0f))
        return lm_fail(err, LM_ERR_INVALID_ARG,
                       "geometric mesh: crease_tolerance_deg is %g; it must be between 0 and "
                       "180 degrees (0 means the default, 0.5)",
                       (double)d->crease_tolerance_deg);
    if ((uint64_t)d->triangle_count > kMaxTriangles ||
        (uint64_t)d->vertex_count + 3 * (uint64_t)d->triangle_count > (uint64_t)INT_MAX)
        return lm_fail(err, LM_ERR_UNSUPPORTED,
                       "geometric mesh: %u vertices and %u triangles is more than this build "
                       "supports (at most %llu triangles, and vertices + 3 x triangles at most %d)",
                       (unsigned)d->vertex_count, (unsigned)d->triangle_count,
                       (unsigned long long)kMaxTriangles, INT_MAX);
    const uint32_t *t = d->triangles;
    const size_t n = 3 * (size_t)d->triangle_count;
    for (size_t i = 0; i < n; ++i) {
        if (t[i] >= d->vertex_count)
            return lm_fail(err, LM_ERR_INVALID_ARG,
                           "geometric mesh: triangle %zu corner %zu uses vertex %u, but there "
                           "are only %u vertices (ids 0..%lld)",
                           i / 3, i % 3, (unsigned)t[i], (unsigned)d->vertex_count,
                           (long long)d->vertex_count - 1);
    }
    return LM_OK;
}

/* Builds g's arrays from a validated desc. Throws on allocation failure. */
lm_result build(const mesh_geo_desc *d, mesh_geo *g, lm_error *err)
{
    const uint32_t nv = d->vertex_count;
    const uint32_t nt = d->triangle_count;
    const uint32_t *tris = d->triangles;
    const size_t ns = 3 * (size_t)nt;

    g->triangle_count = nt;
    g->neighbor.assign(ns, -1);
    g->neighbor_edge.assign(ns, -1);
    g->kind.assign(ns, (uint8_t)MESH_EDGE_BOUNDARY);
    if (nt == 0) return LM_OK;

    OmMesh mesh;
    mesh.reserve(nv, ns / 2 + 3, nt);
    for (uint32_t v = 0; v < nv; ++v) {
        const float *p = d->positions + 3 * (size_t)v;
        mesh.add_vertex(OmMesh::Point(p[0], p[1], p[2]));
    }

    std::vector<uint32_t> rejected;
    {
        OmErrSilencer quiet;
        for (uint32_t t = 0; t < nt; ++t) {
            const uint32_t *c = tris + 3 * (size_t)t;
            OmMesh::FaceHandle fh;
            bool degenerate = c[0] == c[1] || c[1] == c[2] || c[2] == c[0];
            if (!degenerate)
                fh = mesh.add_face(OmMesh::VertexHandle((int)c[0]), OmMesh::VertexHandle((int)c[1]),
                                   OmMesh::VertexHandle((int)c[2]));
            if (!fh.is_valid()) {
                OmMesh::VertexHandle dup[3];
                for (int k = 0; k < 3; ++k) {
                    /* A copy: add_vertex may reallocate the points under a reference. */
                    const OmMesh::Point p = mesh.point(OmMesh::VertexHandle((int)c[k]));
                    dup[k] = mesh.add_vertex(p);
                }
                fh = mesh.add_face(dup[0], dup[1], dup[2]);
                rejected.push_back(t);
            }
            if (!fh.is_valid() || fh.idx() != (int)t)
                return lm_fail(err, LM_ERR_RUNTIME,
                               "geometric mesh: OpenMesh did not add triangle %u as face %u "
                               "(internal error)",
                               (unsigned)t, (unsigned)t);
        }
    }

    /* Mark the main-mesh edges that rejected triangles would have used. */
    OpenMesh::EPropHandleT<bool> nonmanifold;
    mesh.add_property(nonmanifold, "lumesh:nonmanifold");
    for (OmMesh::EdgeHandle eh : mesh.edges()) mesh.property(nonmanifold, eh) = false;
    for (uint32_t t : rejected) {
        const uint32_t *c = tris + 3 * (size_t)t;
        for (int e = 0; e < 3; ++e) {
            uint32_t a = c[e], b = c[(e + 1) % 3];
            mesh_edge_kind k = MESH_EDGE_BOUNDARY;
            if (a != b) {
                OmMesh::VertexHandle va((int)a), vb((int)b);
                OmMesh::HalfedgeHandle h = mesh.find_halfedge(va, vb);
                if (!h.is_valid()) h = mesh.find_halfedge(vb, va);
                if (h.is_valid()) {
                    mesh.property(nonmanifold, mesh.edge_handle(h)) = true;
                    k = MESH_EDGE_NONMANIFOLD;
                }
            }
            g->kind[3 * (size_t)t + (size_t)e] = (uint8_t)k;
        }
    }

    /* Neighbours of the accepted triangles. A rejected triangle's face sits on
     * fresh vertices, so its halfedge lookups below simply fail to match. */
    std::vector<bool> is_rejected(nt, false);
    for (uint32_t t : rejected) is_rejected[t] = true;
    for (uint32_t t = 0; t < nt; ++t) {
        if (is_rejected[t]) continue;
        const uint32_t *c = tris + 3 * (size_t)t;
        for (int e = 0; e < 3; ++e) {
            const size_t s = 3 * (size_t)t + (size_t)e;
            OmMesh::VertexHandle va((int)c[e]), vb((int)c[(e + 1) % 3]);
            OmMesh::HalfedgeHandle h = mesh.find_halfedge(va, vb);
            if (!h.is_valid() || mesh.face_handle(h).idx() != (int)t)
                return lm_fail(err, LM_ERR_RUNTIME,
                               "geometric mesh: OpenMesh lost edge %d of triangle %u "
                               "(internal error)",
                               e, (unsigned)t);
            if (mesh.property(nonmanifold, mesh.edge_handle(h))) {
                g->kind[s] = (uint8_t)MESH_EDGE_NONMANIFOLD;
                continue;
            }
            OmMesh::FaceHandle nf = mesh.face_handle(mesh.opposite_halfedge_handle(h));
            if (!nf.is_valid()) {
                g->kind[s] = (uint8_t)MESH_EDGE_BOUNDARY;
                continue;
            }
            const uint32_t n = (uint32_t)nf.idx();
            int ne = -1;
            if (n < nt && !is_rejected[n]) {
                const uint32_t *nc = tris + 3 * (size_t)n;
                for (int k = 0; k < 3; ++k)
                    if (nc[k] == c[(e + 1) % 3] && nc[(k + 1) % 3] == c[e]) ne = k;
            }
            if (ne < 0)
                return lm_fail(err, LM_ERR_RUNTIME,
                               "geometric mesh: OpenMesh put triangle %u across edge %d of "
                               "triangle %u but they share no edge (internal error)",
                               (unsigned)n, e, (unsigned)t);
            g->neighbor[s] = (int32_t)n;
            g->neighbor_edge[s] = (int8_t)ne;
            g->kind[s] = (uint8_t)MESH_EDGE_INTERIOR;
        }
    }

    /* Creases: each interior edge once, from its lower-numbered triangle. */
    if (d->corner_normals) {
        const double tol_deg =
            d->crease_tolerance_deg > 0.0f ? (double)d->crease_tolerance_deg : kDefaultCreaseDeg;
        const double cos_tol = std::cos(tol_deg * kPi / 180.0);
        const float *nrm = d->corner_normals;
        for (uint32_t t = 0; t < nt; ++t) {
            for (int e = 0; e < 3; ++e) {
                const size_t s = 3 * (size_t)t + (size_t)e;
                if (g->kind[s] != MESH_EDGE_INTERIOR || (uint32_t)g->neighbor[s] < t) continue;
                const uint32_t n = (uint32_t)g->neighbor[s];
                const int k = g->neighbor_edge[s];
                /* Corner e of t is corner (k+1)%3 of n; corner (e+1)%3 of t is corner k of n. */
                const float *ta = nrm + 9 * (size_t)t + 3 * (size_t)e;
                const float *tb = nrm + 9 * (size_t)t + 3 * (size_t)((e + 1) % 3);
                const float *na = nrm + 9 * (size_t)n + 3 * (size_t)((k + 1) % 3);
                const float *nb = nrm + 9 * (size_t)n + 3 * (size_t)k;
                if (normals_agree(ta, na, cos_tol) && normals_agree(tb, nb, cos_tol)) continue;
                const size_t o = 3 * (size_t)n + (size_t)k;
                g->kind[s] = g->kind[o] = (uint8_t)MESH_EDGE_CREASE;
                g->neighbor[s] = g->neighbor[o] = -1;
                g->neighbor_edge[s] = g->neighbor_edge[o] = -1;
            }
        }
    }

    g->stats.rejected_triangles = (uint32_t)rejected.size();
    return LM_OK;
}

bool valid_side(const mesh_geo *g, uint32_t tri, int edge)
{
    return g && tri < g->triangle_count && edge >= 0 && edge <= 2;
}

} // namespace

extern "C" lm_result mesh_geo_create(const mesh_geo_desc *desc, mesh_geo **out, lm_error *err)
{
    if (!out) return lm_fail(err, LM_ERR_INVALID_ARG, "geometric mesh: out is NULL");
    *out = nullptr;
    if (!desc) return lm_fail(err, LM_ERR_INVALID_ARG, "geometric mesh: desc is NULL");
    lm_result r = validate(desc, err);
    if (r != LM_OK) return r;
    mesh_geo *g = nullptr;
    try {
        g = new mesh_geo;
        r = build(desc, g, err);
        if (r == LM_OK) {
            for (uint8_t k : g->kind) g->stats.sides[k]++;
            *out = g;
            return LM_OK;
        }
    } catch (const std::bad_alloc &) {
        r = lm_fail(err, LM_ERR_NO_MEMORY,
                    "geometric mesh: out of memory building the topology of %u triangles",
                    (unsigned)desc->triangle_count);
    } catch (const std::exception &e) {
        r = lm_fail(err, LM_ERR_RUNTIME, "geometric mesh: OpenMesh failed: %s", e.what());
    } catch (...) {
        r = lm_fail(err, LM_ERR_RUNTIME, "geometric mesh: OpenMesh failed (unknown exception)");
    }
    delete g;
    return r;
}

extern "C" void mesh_geo_destroy(mesh_geo *g)
{
    delete g;
}

extern "C" int32_t mesh_geo_neighbor(const mesh_geo *g, uint32_t tri, int edge)
{
    if (!valid_side(g, tri, edge)) return -1;
    return g->neighbor[3 * (size_t)tri + (size_t)edge];
}

extern "C" int mesh_geo_neighbor_edge(const mesh_geo *g, uint32_t tri, int edge)
{
    if (!valid_side(g, tri, edge)) return -1;
    return g->neighbor_edge[3 * (size_t)tri + (size_t)edge];
}

extern "C" mesh_edge_kind mesh_geo_edge_kind(const mesh_geo *g, uint32_t tri, int edge)
{
    if (!valid_side(g, tri, edge)) return MESH_EDGE_BOUNDARY;
    return (mesh_edge_kind)g->kind[3 * (size_t)tri + (size_t)edge];
}

extern "C" void mesh_geo_get_stats(const mesh_geo *g, mesh_geo_stats *out)
{
    if (!out) return;
    if (!g) {
        *out = mesh_geo_stats();
        return;
    }
    *out = g->stats;
}
