/* vtable.c — exact-address vertex table shared by the cache meshes (vtable.h).
 *
 * Paper §4.1–4.2: all radiance and irradiance meshes are quadtree forests over the
 * same scene triangles; a point made by midpoint splits sits at the same place in
 * every mesh, so one table serves them all and a sample position is computed once.
 *
 * Layout: dense arrays indexed by vertex id (public record, packed key) plus an
 * open-addressing hash map of (id, 32-bit hash) slots with linear probing, load
 * at most 0.7, power-of-two size, backward-shift deletion (no tombstones, so a
 * long-lived table with churn does not slow down). Freed ids go on a stack and
 * are handed out again first, which keeps per-mesh arrays indexed by id dense.
 *
 * Why keys are stored rather than recomputed from (tri, bary): computing a key
 * needs the normal-class table and an edge-kind query; storing 20 bytes per
 * vertex keeps a probe to one memcmp-sized compare.
 *
 * Scene vertices (two zero weights) are not hashed: each normal class has a
 * first corner (the class's smallest triangle's corner at the vertex), and
 * class_vertex, by that corner's index, holds the class's live vertex. Every
 * cache mesh's roots look their three corners up, a million-triangle scene's
 * about three million times at start-up: hashed, those probes were random
 * reads in a table of a million slots (docs/cache.md, "Scene vertices without
 * the hash map").
 */
#include "mesh/vtable.h"
#include "src/base/parallel.h"
#include "src/base/vecmath.h" /* M_PI */

#include <math.h>
#include <stdlib.h>
#include <string.h>

enum { KIND_VERTEX = 1, KIND_EDGE = 2, KIND_INTERIOR = 3 };

/* Packed address. a,b,c,d: see key_of(); kd = kind << 8 | reduced depth. */
typedef struct vkey {
    uint32_t a, b, c, d, kd;
} vkey;

typedef struct vslot {
    uint32_t id; /* MESH_VTABLE_NONE: empty */
    uint32_t h;  /* low 32 bits of the key's hash: home slot and a cheap pre-compare */
} vslot;

struct mesh_vtable {
    const scene *s;
    const mesh_geo *geo;
    /* 3 per scene triangle (corner index 3·tri + c): the first corner of the
     * corner's normal class at its vertex (its triangle is the class's smallest);
     * and, by such a first corner, the class's live vertex (MESH_VTABLE_NONE: none). */
    uint32_t *class_corner;
    uint32_t *class_vertex;

    mesh_vertex *v;  /* [cap], by id */
    vkey *keys;      /* [cap], by id */
    uint32_t *freed; /* stack of recycled ids, [cap] */
    uint32_t cap, id_limit, free_count, live;
    uint32_t hashed; /* live vertices in slots (not scene vertices) */

    vslot *slots;
    uint32_t mask; /* slots - 1 */
    uint32_t rehashes;
    uint64_t created, destroyed;
};

/* ---- dyadic helpers ---- */

int mesh_bary_valid(mesh_bary p)
{
    if (p.depth > MESH_DEPTH_MAX) return 0;
    uint64_t sum = (uint64_t)p.w[0] + p.w[1] + p.w[2];
    return sum == (uint64_t)1 << p.depth;
}

mesh_bary mesh_bary_reduce(mesh_bary p)
{
    while (p.depth > 0 && ((p.w[0] | p.w[1] | p.w[2]) & 1u) == 0) {
        p.w[0] >>= 1, p.w[1] >>= 1, p.w[2] >>= 1;
        p.depth--;
    }
    return p;
}

lm_result mesh_bary_midpoint(mesh_bary a, mesh_bary b, mesh_bary *out)
{
    uint32_t d = a.depth > b.depth ? a.depth : b.depth;
    if (d + 1 > MESH_DEPTH_MAX) return LM_ERR_UNSUPPORTED;
    /* Bring both to depth d, then (a + b) / 2^(d+1): sums stay below 2^31. */
    for (int i = 0; i < 3; ++i)
        out->w[i] = (a.w[i] << (d - a.depth)) + (b.w[i] << (d - b.depth));
    out->depth = d + 1;
    return LM_OK;
}

/* ---- hashing ---- */

static uint64_t mix64(uint64_t x)
{
    /* splitmix64 finaliser: full avalanche, so sequential addresses spread. */
    x ^= x >> 30;
    x *= 0xbf58476d1ce4e5b9ull;
    x ^= x >> 27;
    x *= 0x94d049bb133111ebull;
    x ^= x >> 31;
    return x;
}

static uint32_t key_hash(const vkey *k)
{
    uint64_t h = mix64(((uint64_t)k->a << 32 | k->b) ^ 0x9e3779b97f4a7c15ull);
    h = mix64(h ^ ((uint64_t)k->c << 32 | k->d));
    h = mix64(h ^ k->kd);
    return (uint32_t)(h ^ (h >> 32));
}

static int key_eq(const vkey *x, const vkey *y)
{
    return x->a == y->a && x->b == y->b && x->c == y->c && x->d == y->d && x->kd == y->kd;
}

/* ---- normal classes ---- */

/* Same test as geomesh (normals_agree in geomesh_openmesh.cpp): identical vectors
 * agree; otherwise both must be finite and non-zero and within the angle. */
static int normals_agree(const float *a, const float *b, double cos_tol)
{
    if (a[0] == b[0] && a[1] == b[1] && a[2] == b[2]) return 1;
    double la = sqrt((double)a[0] * a[0] + (double)a[1] * a[1] + (double)a[2] * a[2]);
    double lb = sqrt((double)b[0] * b[0] + (double)b[1] * b[1] + (double)b[2] * b[2]);
    if (!(la > 1e-20 && lb > 1e-20) || !isfinite(la) || !isfinite(lb)) return 0;
    double c = ((double)a[0] * b[0] + (double)a[1] * b[1] + (double)a[2] * b[2]) / (la * lb);
    return c >= cos_tol;
}

static uint32_t uf_find(uint32_t *parent, uint32_t i)
{
    while (parent[i] != i) i = parent[i] = parent[parent[i]];
    return i;
}

static void uf_union(uint32_t *parent, uint32_t i, uint32_t j)
{
    i = uf_find(parent, i), j = uf_find(parent, j);
    /* The smaller local index (= smaller triangle id) stays the root. */
    if (i < j) parent[j] = i;
    else if (j < i) parent[i] = j;
}

/* For every corner, the smallest triangle id of its group at that vertex. A
 * group joins corners whose normals agree with the group's first member (this
 * keeps the cost at O(degree × groups) rather than O(degree²) at a fan apex),
 * and — so that edge and vertex keys never disagree — the two corners at each
 * end of every MESH_EDGE_INTERIOR edge (geomesh found their normals agree, and
 * its tolerance may differ from ours). */
/* The classes of the n corners L[0..n) at one vertex (sorted by triangle);
 * parent and reps have room for n. */
static void vertex_classes(mesh_vtable *vt, double cos_tol, const uint32_t *L, uint32_t n, uint32_t *parent,
                           uint32_t *reps)
{
    const scene *s = vt->s;
    uint32_t nreps = 0;
    for (uint32_t i = 0; i < n; ++i) {
        parent[i] = i;
        if (!s->corner_normals) { /* no normals: one class */
            parent[i] = 0;
            continue;
        }
        const float *ni = s->corner_normals + 3 * (size_t)L[i];
        uint32_t r2 = 0;
        for (; r2 < nreps; ++r2)
            if (normals_agree(ni, s->corner_normals + 3 * (size_t)L[reps[r2]], cos_tol)) break;
        if (r2 < nreps) uf_union(parent, i, reps[r2]);
        else reps[nreps++] = i;
    }
    for (uint32_t i = 0; vt->geo && i < n; ++i) {
        const uint32_t t = L[i] / 3, c = L[i] % 3;
        const int edges[2] = {(int)c, (int)((c + 2) % 3)}; /* the two edges at corner c */
        for (int q = 0; q < 2; ++q) {
            if (mesh_geo_edge_kind(vt->geo, t, edges[q]) != MESH_EDGE_INTERIOR) continue;
            int32_t nb = mesh_geo_neighbor(vt->geo, t, edges[q]);
            if (nb < 0) continue;
            /* Binary search the neighbour among this vertex's corners (sorted by triangle). */
            uint32_t lo = 0, hi = n;
            while (lo < hi) {
                uint32_t mid = (lo + hi) / 2;
                if (L[mid] / 3 < (uint32_t)nb) lo = mid + 1;
                else hi = mid;
            }
            if (lo < n && L[lo] / 3 == (uint32_t)nb) uf_union(parent, i, lo);
        }
    }
    for (uint32_t i = 0; i < n; ++i) vt->class_corner[L[i]] = L[uf_find(parent, i)];
}

/* Vertices a chunk of classes_chunk takes. */
#define CLASS_CHUNK 2048u

typedef struct classes_job {
    mesh_vtable *vt;         /* written: class_corner of its chunk's corners only */
    double cos_tol;
    const uint32_t *start;   /* [vertex_count + 1]: each vertex's corners in `corners` */
    const uint32_t *corners;
    uint8_t *failed;         /* [chunks]: out of memory */
} classes_job;

/* The classes at vertices [chunk·CLASS_CHUNK, ...): each vertex writes its own
 * corners' entries, so chunks run on every core (a million-triangle scene's
 * table took 0.2-0.3 s on one). */
static void classes_chunk(void *user, uint32_t chunk)
{
    const classes_job *job = user;
    const uint32_t nv = job->vt->s->vertex_count, v0 = chunk * CLASS_CHUNK;
    const uint32_t v1 = nv - v0 < CLASS_CHUNK ? nv : v0 + CLASS_CHUNK;
    uint32_t most = 1;
    for (uint32_t v = v0; v < v1; ++v)
        if (job->start[v + 1] - job->start[v] > most) most = job->start[v + 1] - job->start[v];
    uint32_t *parent = malloc(2 * (size_t)most * sizeof *parent);
    if (!parent) {
        job->failed[chunk] = 1;
        return;
    }
    for (uint32_t v = v0; v < v1; ++v)
        vertex_classes(job->vt, job->cos_tol, job->corners + job->start[v], job->start[v + 1] - job->start[v], parent,
                       parent + most);
    free(parent);
}

static lm_result build_normal_classes(mesh_vtable *vt, double cos_tol, lm_error *err)
{
    const scene *s = vt->s;
    const uint32_t nt = s->tri_count, nv = s->vertex_count;
    const size_t nc = 3 * (size_t)nt;
    const uint32_t chunks = (uint32_t)(((size_t)nv + CLASS_CHUNK - 1) / CLASS_CHUNK);
    vt->class_corner = malloc((nc ? nc : 1) * sizeof *vt->class_corner);
    vt->class_vertex = malloc((nc ? nc : 1) * sizeof *vt->class_vertex);
    uint32_t *start = calloc((size_t)nv + 1, sizeof *start);
    uint32_t *corners = malloc((nc ? nc : 1) * sizeof *corners);
    uint8_t *failed = calloc(chunks ? chunks : 1, 1);
    lm_result r = LM_OK;
    if (!vt->class_corner || !vt->class_vertex || !start || !corners || !failed) {
        r = lm_fail(err, LM_ERR_NO_MEMORY, "vertex table: out of memory for %u triangles", nt);
        goto done;
    }
    /* Corners grouped by vertex (counting sort; ascending triangle id within a vertex). */
    for (size_t k = 0; k < nc; ++k) start[s->tris[k / 3].v[k % 3] + 1]++;
    for (uint32_t v = 0; v < nv; ++v) start[v + 1] += start[v];
    for (size_t k = 0; k < nc; ++k) corners[start[s->tris[k / 3].v[k % 3]]++] = (uint32_t)k;
    memset(vt->class_vertex, 0xff, nc * sizeof *vt->class_vertex); /* MESH_VTABLE_NONE */
    for (uint32_t v = nv; v > 0; --v) start[v] = start[v - 1];
    start[0] = 0;
    lm_parallel_for(lm_thread_count(0), chunks, classes_chunk,
                    &(classes_job){.vt = vt, .cos_tol = cos_tol, .start = start, .corners = corners, .failed = failed});
    for (uint32_t k = 0; k < chunks; ++k)
        if (failed[k]) r = lm_fail(err, LM_ERR_NO_MEMORY, "vertex table: out of memory for %u triangles", nt);
done:
    free(start);
    free(corners);
    free(failed);
    return r;
}

/* ---- keys ---- */

/* The key of valid point p in triangle tri; *red receives the reduced form. */
static void key_of(const mesh_vtable *vt, uint32_t tri, mesh_bary p, vkey *k, mesh_bary *red)
{
    const mesh_bary r = mesh_bary_reduce(p);
    const uint32_t *tv = vt->s->tris[tri].v;
    int zeros = (r.w[0] == 0) + (r.w[1] == 0) + (r.w[2] == 0);
    *red = r;
    if (zeros == 2) {
        int c = r.w[0] ? 0 : r.w[1] ? 1 : 2;
        k->a = tv[c];
        k->c = vt->class_corner[3 * (size_t)tri + (size_t)c]; /* the class's first corner */
        k->b = k->c / 3;                                      /* its triangle: the class */
        k->d = 0;
        k->kd = (uint32_t)KIND_VERTEX << 8;
    } else if (zeros == 1) {
        int z = r.w[0] == 0 ? 0 : r.w[1] == 0 ? 1 : 2;
        int e = (z + 1) % 3; /* the edge opposite corner z joins corners e and e+1 */
        uint32_t va = tv[e], vb = tv[(e + 1) % 3];
        uint32_t wa = r.w[e], wb = r.w[(e + 1) % 3];
        int shared = va != vb && vt->geo && mesh_geo_edge_kind(vt->geo, tri, e) == MESH_EDGE_INTERIOR;
        if (va <= vb) k->a = va, k->b = vb, k->c = wb; /* parameter from the smaller id */
        else k->a = vb, k->b = va, k->c = wa;
        k->d = shared ? MESH_VTABLE_NONE : tri;
        k->kd = (uint32_t)KIND_EDGE << 8 | r.depth;
    } else {
        k->a = tri;
        k->b = r.w[0];
        k->c = r.w[1];
        k->d = 0;
        k->kd = (uint32_t)KIND_INTERIOR << 8 | r.depth;
    }
}

/* Slot index holding `k`, or the empty slot where it would go (*found = 0). */
static uint32_t probe(const mesh_vtable *vt, const vkey *k, uint32_t h, int *found)
{
    uint32_t i = h & vt->mask;
    for (;;) {
        const vslot *sl = &vt->slots[i];
        if (sl->id == MESH_VTABLE_NONE) {
            *found = 0;
            return i;
        }
        if (sl->h == h && key_eq(&vt->keys[sl->id], k)) {
            *found = 1;
            return i;
        }
        i = (i + 1) & vt->mask;
    }
}

static lm_result grow_slots(mesh_vtable *vt, uint32_t nslots, lm_error *err)
{
    vslot *ns = malloc((size_t)nslots * sizeof *ns);
    if (!ns) return lm_fail(err, LM_ERR_NO_MEMORY, "vertex table: out of memory (%u hash slots)", nslots);
    for (uint32_t i = 0; i < nslots; ++i) ns[i].id = MESH_VTABLE_NONE, ns[i].h = 0;
    const uint32_t nmask = nslots - 1;
    if (vt->slots) {
        for (uint32_t i = 0; i <= vt->mask; ++i) {
            vslot sl = vt->slots[i];
            if (sl.id == MESH_VTABLE_NONE) continue;
            uint32_t j = sl.h & nmask;
            while (ns[j].id != MESH_VTABLE_NONE) j = (j + 1) & nmask;
            ns[j] = sl;
        }
        vt->rehashes++;
    }
    free(vt->slots);
    vt->slots = ns;
    vt->mask = nmask;
    return LM_OK;
}

static lm_result grow_records(mesh_vtable *vt, uint32_t ncap, lm_error *err)
{
    /* Three arrays share one capacity. Not zeroed: a record is written whole
     * when its id is handed out (below id_limit, or off the freed stack), and
     * none past id_limit is read; zeroed, each doubling touched its whole new
     * half at once (docs/cache.md, "The first image's fresh memory"). */
    if (!lm_realloc_array_raw(&vt->v, vt->cap, ncap, sizeof *vt->v) ||
        !lm_realloc_array_raw(&vt->keys, vt->cap, ncap, sizeof *vt->keys) ||
        !lm_realloc_array_raw(&vt->freed, vt->cap, ncap, sizeof *vt->freed))
        return lm_fail(err, LM_ERR_NO_MEMORY, "vertex table: out of memory (%u vertices)", ncap);
    vt->cap = ncap;
    return LM_OK;
}

/* ---- public ---- */

lm_result mesh_vtable_create(const mesh_vtable_desc *desc, mesh_vtable **out, lm_error *err)
{
    if (out) *out = NULL;
    if (!desc || !out || !desc->scene)
        return lm_fail(err, LM_ERR_INVALID_ARG, "vertex table: desc, desc->scene and out are required");
    const scene *s = desc->scene;
    if (s->tri_count > 0 && (!s->tris || !s->positions))
        return lm_fail(err, LM_ERR_INVALID_ARG, "vertex table: scene has triangles but no vertex data");
    for (uint32_t t = 0; t < s->tri_count; ++t)
        for (int c = 0; c < 3; ++c)
            if (s->tris[t].v[c] >= s->vertex_count)
                return lm_fail(err, LM_ERR_INVALID_ARG,
                               "vertex table: triangle %u corner %d names vertex %u of %u", t, c,
                               s->tris[t].v[c], s->vertex_count);
    float tol = desc->crease_tolerance_deg;
    if (!(tol >= 0.0f && tol <= 180.0f))
        return lm_fail(err, LM_ERR_INVALID_ARG,
                       "vertex table: crease_tolerance_deg is %g; it must be between 0 and 180",
                       (double)tol);
    if (tol == 0.0f) tol = 0.5f;
    uint32_t cap = desc->initial_capacity ? desc->initial_capacity : 1024;
    if (cap > (1u << 30)) cap = 1u << 30;

    mesh_vtable *vt = calloc(1, sizeof *vt);
    if (!vt) return lm_fail(err, LM_ERR_NO_MEMORY, "vertex table: out of memory");
    vt->s = s;
    vt->geo = desc->geo ? desc->geo : s->topology;
    uint32_t nslots = 16;
    while ((double)nslots * 0.7 < (double)cap) nslots <<= 1;
    lm_result r = build_normal_classes(vt, cos((double)tol * M_PI / 180.0), err);
    if (r == LM_OK) r = grow_records(vt, cap, err);
    if (r == LM_OK) r = grow_slots(vt, nslots, err);
    if (r != LM_OK) {
        mesh_vtable_destroy(vt);
        return r;
    }
    *out = vt;
    return LM_OK;
}

void mesh_vtable_destroy(mesh_vtable *vt)
{
    if (!vt) return;
    free(vt->class_corner);
    free(vt->class_vertex);
    free(vt->v);
    free(vt->keys);
    free(vt->freed);
    free(vt->slots);
    free(vt);
}

static lm_result check_point(const mesh_vtable *vt, uint32_t tri, mesh_bary p, lm_error *err)
{
    if (!vt) return lm_fail(err, LM_ERR_INVALID_ARG, "vertex table: NULL table");
    if (tri >= vt->s->tri_count)
        return lm_fail(err, LM_ERR_INVALID_ARG, "vertex table: triangle %u of %u", tri,
                       vt->s->tri_count);
    if (p.depth > MESH_DEPTH_MAX)
        return lm_fail(err, LM_ERR_UNSUPPORTED, "vertex table: depth %u is deeper than %d levels",
                       p.depth, MESH_DEPTH_MAX);
    if (!mesh_bary_valid(p))
        return lm_fail(err, LM_ERR_INVALID_ARG,
                       "vertex table: weights %u+%u+%u do not sum to 2^%u", p.w[0], p.w[1], p.w[2],
                       p.depth);
    return LM_OK;
}

/* Position and normal of the new vertex: double sums in corner order, one rounding.
 * For an edge point the zero-weight term adds exactly nothing and the other two
 * commute, so both triangles of a shared edge compute bit-identical positions. */
static void fill_vertex(const mesh_vtable *vt, uint32_t tri, mesh_bary r, mesh_vertex *out)
{
    const scene *s = vt->s;
    const double scale = ldexp(1.0, -(int)r.depth);
    double pos[3] = {0, 0, 0}, nrm[3] = {0, 0, 0};
    for (int c = 0; c < 3; ++c) {
        const float *P = s->positions + 3 * (size_t)s->tris[tri].v[c];
        for (int k = 0; k < 3; ++k) pos[k] += (double)r.w[c] * (double)P[k];
    }
    if (s->corner_normals) {
        for (int c = 0; c < 3; ++c) {
            const float *N = s->corner_normals + 9 * (size_t)tri + 3 * (size_t)c;
            for (int k = 0; k < 3; ++k) nrm[k] += (double)r.w[c] * (double)N[k];
        }
    } else { /* geometric normal of the triangle */
        const float *A = s->positions + 3 * (size_t)s->tris[tri].v[0];
        const float *B = s->positions + 3 * (size_t)s->tris[tri].v[1];
        const float *C = s->positions + 3 * (size_t)s->tris[tri].v[2];
        double u[3], w[3];
        for (int k = 0; k < 3; ++k) u[k] = (double)B[k] - A[k], w[k] = (double)C[k] - A[k];
        nrm[0] = u[1] * w[2] - u[2] * w[1];
        nrm[1] = u[2] * w[0] - u[0] * w[2];
        nrm[2] = u[0] * w[1] - u[1] * w[0];
    }
    double len = sqrt(nrm[0] * nrm[0] + nrm[1] * nrm[1] + nrm[2] * nrm[2]);
    for (int k = 0; k < 3; ++k) {
        out->position[k] = (float)(pos[k] * scale);
        out->normal[k] = len > 0.0 ? (float)(nrm[k] / len) : 0.0f;
    }
    out->tri = tri;
    out->bary = r;
}

lm_result mesh_vtable_acquire(mesh_vtable *vt, uint32_t tri, mesh_bary p, uint32_t *out_id,
                              lm_error *err)
{
    if (out_id) *out_id = MESH_VTABLE_NONE;
    lm_result r = check_point(vt, tri, p, err);
    if (r != LM_OK) return r;
    if (!out_id) return lm_fail(err, LM_ERR_INVALID_ARG, "vertex table: out_id is NULL");
    vkey k;
    mesh_bary red;
    key_of(vt, tri, p, &k, &red);
    const int hashed = k.kd >> 8 != KIND_VERTEX;
    const uint32_t h = hashed ? key_hash(&k) : 0;
    int found = 0;
    uint32_t i = hashed ? probe(vt, &k, h, &found) : 0;
    const uint32_t known = hashed ? (found ? vt->slots[i].id : MESH_VTABLE_NONE) : vt->class_vertex[k.c];
    if (known != MESH_VTABLE_NONE) {
        mesh_vertex *v = &vt->v[known];
        if (v->refs == UINT32_MAX)
            return lm_fail(err, LM_ERR_RUNTIME, "vertex table: vertex %u has 2^32-1 references", known);
        v->refs++;
        *out_id = known;
        return LM_OK;
    }
    /* New vertex: make room first, so a failure leaves the table untouched. */
    if (hashed && (double)(vt->hashed + 1) > 0.7 * (double)(vt->mask + 1)) {
        if (vt->mask + 1 >= (1u << 31))
            return lm_fail(err, LM_ERR_NO_MEMORY, "vertex table: hash map is at its size limit");
        r = grow_slots(vt, 2 * (vt->mask + 1), err);
        if (r != LM_OK) return r;
        i = probe(vt, &k, h, &found);
    }
    if (vt->free_count == 0 && vt->id_limit == vt->cap) {
        size_t ncap = lm_grow_capacity(vt->cap, (size_t)vt->cap + 1, 16, UINT32_MAX / 2);
        if (!ncap) return lm_fail(err, LM_ERR_NO_MEMORY, "vertex table: vertex id space exhausted");
        r = grow_records(vt, (uint32_t)ncap, err);
        if (r != LM_OK) return r;
    }
    uint32_t id = vt->free_count ? vt->freed[--vt->free_count] : vt->id_limit++;
    fill_vertex(vt, tri, red, &vt->v[id]);
    vt->v[id].refs = 1;
    vt->keys[id] = k;
    if (hashed) {
        vt->slots[i].id = id;
        vt->slots[i].h = h;
        vt->hashed++;
    } else {
        vt->class_vertex[k.c] = id;
    }
    vt->live++;
    vt->created++;
    *out_id = id;
    return LM_OK;
}

uint32_t mesh_vtable_corner_id(const mesh_vtable *vt, uint32_t tri, int corner)
{
    if (!vt || tri >= vt->s->tri_count || corner < 0 || corner > 2) return MESH_VTABLE_NONE;
    return vt->class_vertex[vt->class_corner[3 * (size_t)tri + (size_t)corner]];
}

uint32_t mesh_vtable_find(const mesh_vtable *vt, uint32_t tri, mesh_bary p)
{
    if (check_point(vt, tri, p, NULL) != LM_OK) return MESH_VTABLE_NONE;
    vkey k;
    mesh_bary red;
    key_of(vt, tri, p, &k, &red);
    if (k.kd >> 8 == KIND_VERTEX) return vt->class_vertex[k.c];
    int found;
    uint32_t i = probe(vt, &k, key_hash(&k), &found);
    return found ? vt->slots[i].id : MESH_VTABLE_NONE;
}

static int is_live(const mesh_vtable *vt, uint32_t id)
{
    return vt && id < vt->id_limit && vt->v[id].refs > 0;
}

lm_result mesh_vtable_retain(mesh_vtable *vt, uint32_t id, lm_error *err)
{
    if (!is_live(vt, id)) return lm_fail(err, LM_ERR_INVALID_ARG, "vertex table: retain of dead id %u", id);
    if (vt->v[id].refs == UINT32_MAX)
        return lm_fail(err, LM_ERR_RUNTIME, "vertex table: vertex %u has 2^32-1 references", id);
    vt->v[id].refs++;
    return LM_OK;
}

/* A freed id: its key cleared, the id stacked for reuse. */
static lm_result forget(mesh_vtable *vt, uint32_t id)
{
    memset(&vt->keys[id], 0, sizeof vt->keys[id]);
    vt->freed[vt->free_count++] = id;
    vt->live--;
    vt->destroyed++;
    return LM_OK;
}

lm_result mesh_vtable_release(mesh_vtable *vt, uint32_t id, lm_error *err)
{
    if (!is_live(vt, id)) return lm_fail(err, LM_ERR_INVALID_ARG, "vertex table: release of dead id %u", id);
    if (--vt->v[id].refs > 0) return LM_OK;
    if (vt->keys[id].kd >> 8 == KIND_VERTEX) {
        vt->class_vertex[vt->keys[id].c] = MESH_VTABLE_NONE;
        return forget(vt, id);
    }
    /* Last reference: remove the slot by backward shift, so no tombstone remains. */
    const uint32_t h = key_hash(&vt->keys[id]);
    uint32_t i = h & vt->mask;
    while (vt->slots[i].id != id) i = (i + 1) & vt->mask;
    for (uint32_t j = (i + 1) & vt->mask;; j = (j + 1) & vt->mask) {
        const vslot sl = vt->slots[j];
        if (sl.id == MESH_VTABLE_NONE) break;
        const uint32_t home = sl.h & vt->mask;
        /* sl may move back to i unless its home lies cyclically in (i, j]. */
        const int home_in = i <= j ? (home > i && home <= j) : (home > i || home <= j);
        if (home_in) continue;
        vt->slots[i] = sl;
        i = j;
    }
    vt->slots[i].id = MESH_VTABLE_NONE;
    vt->slots[i].h = 0;
    vt->hashed--;
    return forget(vt, id);
}

const mesh_vertex *mesh_vtable_vertex(const mesh_vtable *vt, uint32_t id)
{
    return is_live(vt, id) ? &vt->v[id] : NULL;
}

uint32_t mesh_vtable_id_limit(const mesh_vtable *vt) { return vt ? vt->id_limit : 0; }
const scene *mesh_vtable_scene(const mesh_vtable *vt) { return vt ? vt->s : NULL; }
const mesh_geo *mesh_vtable_geo(const mesh_vtable *vt) { return vt ? vt->geo : NULL; }

static size_t table_bytes(const mesh_vtable *vt)
{
    return sizeof *vt + (size_t)vt->cap * (sizeof *vt->v + sizeof *vt->keys + sizeof *vt->freed) +
           ((size_t)vt->mask + 1) * sizeof *vt->slots +
           3 * (size_t)vt->s->tri_count * (sizeof *vt->class_corner + sizeof *vt->class_vertex);
}

void mesh_vtable_get_stats(const mesh_vtable *vt, mesh_vtable_stats *out)
{
    if (!out) return;
    memset(out, 0, sizeof *out);
    if (!vt) return;
    out->live = vt->live;
    out->id_limit = vt->id_limit;
    out->free_ids = vt->free_count;
    out->slots = vt->mask + 1;
    out->rehashes = vt->rehashes;
    out->created = vt->created;
    out->freed = vt->destroyed;
    out->bytes = table_bytes(vt);
    for (uint32_t i = 0; i <= vt->mask; ++i) {
        if (vt->slots[i].id == MESH_VTABLE_NONE) continue;
        uint32_t d = (i - (vt->slots[i].h & vt->mask)) & vt->mask;
        if (d + 1 > out->max_probe) out->max_probe = d + 1;
    }
}

double mesh_vtable_bytes_per_vertex(const mesh_vtable *vt)
{
    if (!vt || vt->live == 0) return 0.0;
    const size_t per_triangle = 3 * (size_t)vt->s->tri_count * (sizeof *vt->class_corner + sizeof *vt->class_vertex);
    return (double)(table_bytes(vt) - per_triangle - sizeof *vt) / (double)vt->live;
}
