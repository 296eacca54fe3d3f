/* cache_drift.c — which indirect values a rebuild of the radiance source may
 * have moved (cache_source.c rebuilds it and gathers the flagged values again):
 * the drift bound of every displayed value, the probes that check a flag
 * through the value's own rays (probe_flagged: traces rays, Embree), and the
 * flags. Split from cache_source.c (it had grown past 1,100 lines); writes
 * cache_source_state's drift, outdated, outdated_list and probe counts only.
 * Worker thread, like the rest of the cache. */
#include "mesh/cache/cache_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "sampling/analytic.h"
#include "src/base/parallel.h"
#include "src/base/tonemap.h"
#include "src/base/vecmath.h"

/* ---- outdated indirect values -------------------------------------------------
 *
 * A gather is only as good as the source of its time. Each rebuild of the source
 * the displayed indirect gathers from adds to every indirect value's drift a bound
 * on how far the rebuild moved it: over the source triangles that changed, their
 * largest change (at the corners of either source, which are nested cuts of one
 * tree: the difference is linear between them) times the cosine-weighted solid
 * angle of their front from the value's vertex (occlusion ignored: a bound). A
 * value whose drift could change what the viewer sees there by more than the JND
 * is flagged, and cache_regather_outdated gathers it again. */

lm_result cache_grow_drift(cache_source_state *st, uint32_t limit, lm_error *err)
{
    if (limit <= st->drift_cap) return LM_OK;
    /* drift (RGB per id) and outdated share one capacity in vertex ids */
    size_t cap = lm_grow_capacity(st->drift_cap, limit, 1024, SIZE_MAX / (3 * sizeof *st->drift));
    if (!cap || !lm_realloc_array(&st->drift, st->drift_cap, cap, 3 * sizeof *st->drift) ||
        !lm_realloc_array(&st->outdated, st->drift_cap, cap, sizeof *st->outdated) ||
        !lm_realloc_array(&st->sigma, st->drift_cap, cap, 3 * sizeof *st->sigma) ||
        !lm_realloc_array(&st->sigma_likely, st->drift_cap, cap, 3 * sizeof *st->sigma_likely) ||
        !lm_realloc_array(&st->gather_level, st->drift_cap, cap, sizeof *st->gather_level) ||
        !lm_realloc_array(&st->borrowed, st->drift_cap, cap, sizeof *st->borrowed) ||
        !lm_realloc_array(&st->unseen_stale, st->drift_cap, cap, sizeof *st->unseen_stale))
        return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory tracking indirect values");
    st->drift_cap = cap;
    return LM_OK;
}

lm_result cache_push_outdated(cache_source_state *st, uint32_t vid, lm_error *err)
{
    if (st->outdated[vid]) return LM_OK;
    if (st->outdated_n == st->outdated_cap && !LM_GROW(st->outdated_list, st->outdated_cap, st->outdated_n + 1))
        return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory tracking indirect values");
    st->outdated_list[st->outdated_n++] = vid;
    st->outdated[vid] = 1;
    return LM_OK;
}

/* A source triangle that changed: its scene triangle and its index in the new
 * source (its change is d[3i..3i+2]). Eight bytes: a million-triangle scene's
 * first regather changes nearly all of them, and the corners, centre, normal
 * and change kept here before (152 bytes) held 160 MB at the peak; the corners
 * are made again for the few that are near a point (changed_corners). */
typedef struct changed_tri {
    uint32_t t, i;
} changed_tri;

static void bary_point(const scene *s, uint32_t t, double w1, double w2, double out[3])
{
    const uint32_t *v = s->tris[t].v;
    for (int k = 0; k < 3; ++k)
        out[k] = (1.0 - w1 - w2) * s->positions[3 * (size_t)v[0] + (size_t)k] + w1 * s->positions[3 * (size_t)v[1] + (size_t)k] +
                 w2 * s->positions[3 * (size_t)v[2] + (size_t)k];
}

/* The changed triangles in a bounding-volume tree, so that a value's drift bound
 * visits O(log n) nodes instead of every changed triangle: a million-triangle
 * scene's first rebuild changes tens of thousands of source triangles, and the
 * loop over all of them for every one of the 60,000 values of the 116k box took
 * 7 s a rebuild (59% of its refinement time; docs/cache.md, "Borrowed values
 * tested"). A node far from the value (beyond DRIFT_OPEN of its radius) adds a
 * bound of its triangles' Σ area × change: their cosines at the value and at
 * themselves bounded through the node's bounding sphere and its normals' cone,
 * the distance by the sphere's nearest point. Nearer, its triangles are looked
 * at one by one as before: by area and cosines over distance² beyond four radii,
 * exactly (samp_polygon_G) nearer. */
enum { DRIFT_LEAF = 8 };
#define DRIFT_OPEN 4.0f

typedef struct drift_item {
    float c[3], n[3], lim;     /* centre, front normal, 16·radius² */
    float r;                   /* radius */
    float ad[3];               /* area × largest |change| (a bound of ∫|change| dA) */
    float as[3];               /* ∫ change dA (signed) where the old source is linear over the
                                  triangle; 0 where it is not (ad then counts whole) */
    uint8_t linear;
    uint32_t j;                /* index into the changed triangles */
    uint64_t key;
} drift_item;

/* Σ over a node of ∫ change·w dA, with w = cosθx·cosθy/r² within [w_min, w_max]
 * over the node, is at most |S|·(w_max + w_min)/2 + U·(w_max − w_min)/2 +
 * V·w_max (S = Σ ∫ change over triangles where it is known, U = Σ ∫|change|
 * there, V = Σ ∫|change| over the rest): a refinement of the source that moves
 * its radiance up here and down there moves a far value by much less than the
 * sum of the moves, and only that difference is charged. */
typedef struct drift_node {
    float c[3], R;             /* bounding sphere of its triangles */
    float N[3], cos_cone;      /* their normals within the cone around N (cos_cone ≤ -1: any) */
    float S[3], U[3], V[3];    /* as above, area-weighted, per channel */
    uint32_t first, count;     /* its items: first .. first + count */
    uint32_t child;            /* the first of its two children (0: a leaf) */
} drift_node;

typedef struct drift_tree {
    drift_item *item;
    drift_node *node;
    uint32_t nodes;
} drift_tree;

/* The corners of changed triangle ct in the scene. */
static void changed_corners(const scene *s, const samp_radiance_mesh *cur, changed_tri ct, double p[3][3])
{
    const float *b = cur->bary + 6 * (size_t)ct.i;
    for (int k = 0; k < 3; ++k) bary_point(s, ct.t, b[2 * k], b[2 * k + 1], p[k]);
}

static int cmp_item(const void *a, const void *b)
{
    const drift_item *x = a, *y = b;
    return (x->key > y->key) - (x->key < y->key);
}

/* Node k over items [first, first + count): its sphere, cone and sums. */
static void drift_fill(drift_tree *t, uint32_t k)
{
    drift_node *nd = &t->node[k];
    const drift_item *it = t->item + nd->first;
    float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    double N[3] = {0, 0, 0}, S[3] = {0, 0, 0}, U[3] = {0, 0, 0}, V[3] = {0, 0, 0};
    for (uint32_t i = 0; i < nd->count; ++i)
        for (int a = 0; a < 3; ++a) {
            lo[a] = fminf(lo[a], it[i].c[a] - it[i].r);
            hi[a] = fmaxf(hi[a], it[i].c[a] + it[i].r);
            N[a] += (double)it[i].n[a] * (it[i].ad[0] + it[i].ad[1] + it[i].ad[2] + 1e-30);
            S[a] += it[i].as[a];
            (it[i].linear ? U : V)[a] += it[i].ad[a];
        }
    double len = sqrt(N[0] * N[0] + N[1] * N[1] + N[2] * N[2]), r2 = 0.0;
    for (int a = 0; a < 3; ++a) {
        nd->c[a] = 0.5f * (lo[a] + hi[a]);
        r2 += 0.25 * (double)(hi[a] - lo[a]) * (hi[a] - lo[a]);
        nd->N[a] = len > 0.0 ? (float)(N[a] / len) : 0.0f;
        nd->S[a] = (float)S[a];
        nd->U[a] = (float)U[a];
        nd->V[a] = (float)V[a];
    }
    nd->R = (float)sqrt(r2) * 1.0001f;
    float cone = len > 0.0 ? 1.0f : -2.0f;
    for (uint32_t i = 0; i < nd->count && len > 0.0; ++i)
        cone = fminf(cone, nd->N[0] * it[i].n[0] + nd->N[1] * it[i].n[1] + nd->N[2] * it[i].n[2]);
    nd->cos_cone = cone - 1e-4f; /* round-off */
}

static int drift_tree_make(drift_tree *t, const scene *s, const samp_radiance_mesh *cur, const float *d,
                           const float *sd, const uint8_t *nonlinear, const changed_tri *ch, uint32_t n)
{
    memset(t, 0, sizeof *t);
    t->item = malloc((size_t)(n ? n : 1) * sizeof *t->item);
    t->node = malloc((size_t)(2 * (n ? n : 1)) * sizeof *t->node); /* a binary tree of ≤ n leaves */
    if (!t->item || !t->node) return 0;
    float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (uint32_t j = 0; j < n; ++j) {
        double p[3][3];
        changed_corners(s, cur, ch[j], p);
        lm_dvec3 a = dv3(p[0][0], p[0][1], p[0][2]), bb = dv3(p[1][0], p[1][1], p[1][2]), cc = dv3(p[2][0], p[2][1], p[2][2]);
        lm_dvec3 centre = dv3_scale(dv3_add(dv3_add(a, bb), cc), 1.0 / 3.0);
        double area = 0.5 * dv3_length(dv3_cross(dv3_sub(bb, a), dv3_sub(cc, a)));
        const float *nn = s->tri_normals + 3 * (size_t)ch[j].t;
        double radius = fmax(dv3_length(dv3_sub(a, centre)),
                             fmax(dv3_length(dv3_sub(bb, centre)), dv3_length(dv3_sub(cc, centre))));
        const float *dj = d + 3 * (size_t)ch[j].i, *sj = sd + 3 * (size_t)ch[j].i;
        const int linear = !nonlinear[ch[j].i];
        drift_item *it = &t->item[j];
        *it = (drift_item){.c = {(float)centre.x, (float)centre.y, (float)centre.z}, .n = {nn[0], nn[1], nn[2]},
                           .lim = (float)(16.0 * radius * radius), .r = (float)radius,
                           .ad = {(float)(area * dj[0]), (float)(area * dj[1]), (float)(area * dj[2])},
                           .as = {(float)(linear * area * sj[0]), (float)(linear * area * sj[1]),
                                  (float)(linear * area * sj[2])},
                           .linear = (uint8_t)linear, .j = j};
        for (int k = 0; k < 3; ++k) lo[k] = fminf(lo[k], it->c[k]), hi[k] = fmaxf(hi[k], it->c[k]);
    }
    const float span = fmaxf(hi[0] - lo[0], fmaxf(hi[1] - lo[1], hi[2] - lo[2]));
    for (uint32_t j = 0; j < n; ++j) {
        uint32_t q[3];
        for (int k = 0; k < 3; ++k) {
            float u = span > 0.0f ? (t->item[j].c[k] - lo[k]) / span : 0.0f;
            q[k] = (uint32_t)(fminf(fmaxf(u, 0.0f), 1.0f) * 2097151.0f);
        }
        t->item[j].key = cache_morton_key(q);
    }
    qsort(t->item, n, sizeof *t->item, cmp_item);
    /* Nodes in breadth order: node k's children are made when it is reached. */
    t->node[0] = (drift_node){.first = 0, .count = n};
    t->nodes = 1;
    for (uint32_t k = 0; k < t->nodes; ++k) {
        drift_fill(t, k);
        drift_node *nd = &t->node[k];
        nd->child = 0;
        if (nd->count <= DRIFT_LEAF) continue;
        const uint32_t half = nd->count / 2;
        nd->child = t->nodes;
        t->node[t->nodes++] = (drift_node){.first = nd->first, .count = half};
        t->node[t->nodes++] = (drift_node){.first = nd->first + half, .count = nd->count - half};
    }
    return 1;
}

static void drift_tree_free(drift_tree *t)
{
    free(t->item);
    free(t->node);
    memset(t, 0, sizeof *t);
}

/* cos(max(θ − γ, 0)) for cos θ = ct, and γ given by its cosine and sine (γ in [0, π]). */
static float cos_less(float ct, float cg, float sg)
{
    ct = fminf(fmaxf(ct, -1.0f), 1.0f);
    if (ct >= cg) return 1.0f; /* θ ≤ γ */
    const float st = sqrtf(fmaxf(1.0f - ct * ct, 0.0f));
    return ct * cg + st * sg; /* cos(θ − γ) */
}

/* max(cos(θ + γ), 0) for θ + γ up to π/2, else 0 (cos θ = ct; γ as cos_less's). */
static float cos_more(float ct, float cg, float sg)
{
    ct = fminf(fmaxf(ct, -1.0f), 1.0f);
    if (ct <= 0.0f || cg <= 0.0f) return 0.0f; /* θ or γ at least π/2 */
    const float st = sqrtf(fmaxf(1.0f - ct * ct, 0.0f));
    return fmaxf(ct * cg - st * sg, 0.0f); /* both below π/2: θ + γ < π, and cos < 0 past π/2 */
}

/* A glossy part's kernel (drift_bound with a lobe): the modified Phong lobe of
 * exponent n about the mirror axis of the view direction wo. */
typedef struct drift_lobe {
    double wo[3], n;   /* towards the viewer (any length); the exponent */
    float axis[3];     /* the unit mirror direction */
    float peak;        /* (n+2)/(2π): the lobe's largest value */
} drift_lobe;

/* The lobe's largest value over a cone of half-angle β (sin sb, cos cb) about the
 * unit direction (dx, dy, dz)/dist: at the cone's nearest approach to the axis. */
static float lobe_over_cone(const drift_lobe *lb, float dx, float dy, float dz, float dist, float sb, float cb)
{
    const float ca = fminf(fmaxf((dx * lb->axis[0] + dy * lb->axis[1] + dz * lb->axis[2]) / dist, -1.0f), 1.0f);
    const float c = cos_less(ca, cb, sb); /* cos(max(0, α − β)) */
    return c <= 0.0f ? 0.0f : lb->peak * powf(c, (float)lb->n);
}

/* Σ_j d_j·∫ over changed triangle j's front of cosθ_x dω from (x, nx), bounded,
 * into add; with a lobe, of lobe·cosθ_x dω. */
static void drift_bound(const drift_tree *t, const scene *s, const samp_radiance_mesh *cur, const float *d,
                        const changed_tri *ch, const double x[3], const double nx[3], const drift_lobe *lb,
                        double add[3])
{
    if (!t->nodes || !t->item) return;
    const float X[3] = {(float)x[0], (float)x[1], (float)x[2]}, NX[3] = {(float)nx[0], (float)nx[1], (float)nx[2]};
    uint32_t stack[128];
    uint32_t top = 0;
    stack[top++] = 0;
    float a[3] = {0, 0, 0};
    while (top) {
        const drift_node *nd = &t->node[stack[--top]];
        const float dx = nd->c[0] - X[0], dy = nd->c[1] - X[1], dz = nd->c[2] - X[2];
        const float dist = sqrtf(dx * dx + dy * dy + dz * dz);
        if (dist > DRIFT_OPEN * nd->R) {
            /* The sphere is seen within β of its centre's direction. */
            const float sb = nd->R / dist, cb = sqrtf(fmaxf(1.0f - sb * sb, 0.0f));
            const float ctx = (dx * NX[0] + dy * NX[1] + dz * NX[2]) / dist;
            const float cx = cos_less(ctx, cb, sb);
            if (cx <= 0.0f) continue; /* all behind the value's plane */
            float cy = 1.0f, cy_min = 0.0f;
            if (nd->cos_cone > -1.0f) { /* the normals' cone: γ = α + β */
                const float ca = fminf(nd->cos_cone, 1.0f), sa = sqrtf(fmaxf(1.0f - ca * ca, 0.0f));
                const float cg = ca * cb - sa * sb, sg = sa * cb + ca * sb;
                const float cty = -(dx * nd->N[0] + dy * nd->N[1] + dz * nd->N[2]) / dist;
                cy = sg < 0.0f ? 1.0f : cos_less(cty, cg, sg);
                if (cy <= 0.0f) continue; /* the value is behind them all */
                cy_min = sg < 0.0f ? 0.0f : cos_more(cty, cg, sg);
            }
            const float rmin = dist - nd->R, rmax = dist + nd->R;
            float w_max = cx * cy / (rmin * rmin), w_min = cos_more(ctx, cb, sb) * cy_min / (rmax * rmax);
            if (lb) { /* the lobe at most its largest over the sphere, at least 0 */
                w_max *= lobe_over_cone(lb, dx, dy, dz, dist, sb, cb);
                w_min = 0.0f;
                if (!(w_max > 0.0f)) continue;
            }
            for (int k = 0; k < 3; ++k)
                a[k] += fabsf(nd->S[k]) * 0.5f * (w_max + w_min) + nd->U[k] * 0.5f * (w_max - w_min) + nd->V[k] * w_max;
            continue;
        }
        if (nd->child) {
            stack[top++] = nd->child;
            stack[top++] = nd->child + 1;
            continue;
        }
        for (uint32_t i = nd->first; i < nd->first + nd->count; ++i) {
            const drift_item *it = &t->item[i];
            float ex = it->c[0] - X[0], ey = it->c[1] - X[1], ez = it->c[2] - X[2];
            float r2 = ex * ex + ey * ey + ez * ez;
            if (r2 > it->lim) {
                float px = ex * NX[0] + ey * NX[1] + ez * NX[2], py = -(ex * it->n[0] + ey * it->n[1] + ez * it->n[2]);
                float w = px > 0.0f && py > 0.0f ? px * py / (r2 * r2) : 0.0f; /* A·cosθx·cosθy/r² over A */
                if (lb && w > 0.0f) {
                    const float dist = sqrtf(r2), sb = fminf(it->r / dist, 1.0f), cb = sqrtf(fmaxf(1.0f - sb * sb, 0.0f));
                    w *= lobe_over_cone(lb, ex, ey, ez, dist, sb, cb);
                }
                for (int k = 0; k < 3; ++k) a[k] += w * it->ad[k];
                continue;
            }
            const changed_tri ct = ch[it->j];
            double p[3][3];
            changed_corners(s, cur, ct, p);
            /* exactly: ∫ cosθx dω, or ∫ lobe·cosθx dω, over the triangle */
            double w = lb ? samp_polygon_phong(p, 3, x, nx, lb->wo, lb->n) : samp_polygon_G(p, 3, x, nx);
            for (int k = 0; k < 3; ++k) add[k] += w * d[3 * (size_t)ct.i + (size_t)k];
        }
    }
    for (int k = 0; k < 3; ++k) add[k] += a[k];
}

/* L_dd at vertex vid: its own value in the direct mesh, else interpolated there. */
void cache_vertex_direct(const cache *c, uint32_t vid, float ldd[3])
{
    const mesh_vertex *mv = mesh_vtable_vertex(c->vt, vid);
    if (mesh_qmesh_get_value(c->direct, vid, ldd) == 1) return;
    double scale = ldexp(1.0, -(int)mv->bary.depth);
    lm_error ignore;
    if (mesh_qmesh_interpolate(c->direct, mv->tri, mv->bary.w[1] * scale, mv->bary.w[2] * scale, ldd, &ignore) != LM_OK)
        ldd[0] = ldd[1] = ldd[2] = 0.0f;
}

/* Per vertex id (calloc'd, id limit bytes): a corner of a leaf of the indirect
 * mesh over a triangle a pixel sees. NULL when out of memory. */
static uint8_t *seen_vertices(const cache *c, const uint32_t *pixels)
{
    uint8_t *seen = calloc(mesh_vtable_id_limit(c->vt) + 1, 1);
    if (!seen) return NULL;
    for (uint32_t t = 0; t < c->s->tri_count; ++t) {
        const uint32_t root = pixels[t] && cache_tri_active(c, t) ? mesh_qmesh_root(c->indirect, t) : MESH_QMESH_NONE;
        if (root == MESH_QMESH_NONE) continue;
        uint32_t stack[4 * MESH_QMESH_DEPTHS + 4], top = 0;
        stack[top++] = root;
        while (top) {
            const mesh_qnode *n = mesh_qmesh_node(c->indirect, stack[--top]);
            if (n->child == MESH_QMESH_NONE) {
                for (int k = 0; k < 3; ++k) seen[n->v[k]] = 1;
                continue;
            }
            for (uint32_t k = 0; k < 4; ++k) stack[top++] = n->child + k;
        }
    }
    return seen;
}

lm_result cache_refresh_stale(cache *c, const uint32_t *pixels, lm_error *err)
{
    if (!c->src.stale_n || !pixels || !c->indirect) return LM_OK;
    uint8_t *seen = seen_vertices(c, pixels);
    if (!seen) return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory finding the seen indirect values");
    lm_result r = LM_OK;
    const uint32_t limit = mesh_vtable_id_limit(c->vt);
    for (uint32_t vid = 0; r == LM_OK && vid < limit && vid < c->src.drift_cap; ++vid) {
        if (!c->src.unseen_stale[vid] || !seen[vid]) continue;
        c->src.unseen_stale[vid] = 0;
        c->src.stale_n--;
        if (mesh_qmesh_get_value(c->indirect, vid, NULL) == 1) r = cache_push_outdated(&c->src, vid, err);
    }
    free(seen);
    return r;
}

/* The values' bounds (cache_mark_outdated, over threads: bound_one,
 * glossy_bound_one): made by the worker thread, read by lm_parallel_for's
 * threads, each of which writes only its own candidates' flag and bound. */
typedef struct bound_job {
    cache *c;
    const drift_tree *tree;
    const samp_radiance_mesh *cur;
    const float *d, *small;
    const changed_tri *ch;
    const uint32_t *cand;
    uint8_t *flag;  /* indirect values (bound_one): may its drift be seen */
    float *bound;   /* this rebuild's bound, 3 per candidate (indirect values: added to their
                       drift after probe_flagged; glossy parts: given to cache_glossy_drift) */
} bound_job;

/* Where vertex vid's gathers look from (a point on a surface's plane sees none
 * of it), and its normal. */
static void bound_origin(const cache *c, uint32_t vid, double x[3], double nx[3])
{
    const mesh_vertex *mv = mesh_vtable_vertex(c->vt, vid);
    samp_point sp = cache_vertex_point(c, vid);
    float o[3];
    samp_point_origin(c->s, &sp, samp_point_epsilon(c->sp, &sp), o);
    for (int k = 0; k < 3; ++k) {
        x[k] = o[k];
        nx[k] = mv->normal[k];
    }
}

/* Could vertex vid's displayed E, moved by ± dr, be told from E through the tone
 * map? */
static int drift_seen(const cache *c, uint32_t vid, const float dr[3])
{
    const mesh_vertex *mv = mesh_vtable_vertex(c->vt, vid);
    float e[3], ldd[3], lab0[3], lab1[3], up[3], down[3], e0[3];
    mesh_qmesh_get_value(c->indirect, vid, e);
    cache_vertex_direct(c, vid, ldd);
    /* (E cannot be negative: the bounds are clamped at 0; L_ds is left out.) */
    for (int k = 0; k < 3; ++k) {
        e0[k] = fmaxf(e[k], 0.0f);
        up[k] = fmaxf(e[k] + dr[k], 0.0f);
        down[k] = fmaxf(e[k] - dr[k], 0.0f);
    }
    cache_seen_lab(c, mv->tri, ldd, e0, NULL, lab0);
    cache_seen_lab(c, mv->tri, ldd, up, NULL, lab1);
    if (tm_delta_e(lab0, lab1) > c->desc.jnd) return 1;
    cache_seen_lab(c, mv->tri, ldd, down, NULL, lab1);
    return tm_delta_e(lab0, lab1) > c->desc.jnd;
}

/* One value's bound (cache_mark_outdated, over threads): this rebuild's
 * Σ d·weight (+ π·small) into bound[j], and flag[j]: whether E ± (drift + bound)
 * can be told from E. Reads the cache; writes only bound[j] and flag[j]. */
static void bound_one(void *user, uint32_t j)
{
    const bound_job *b = user;
    const cache *c = b->c;
    const uint32_t vid = b->cand[j];
    double x[3], nx[3];
    bound_origin(c, vid, x, nx);
    double add[3] = {M_PI * b->small[0], M_PI * b->small[1], M_PI * b->small[2]};
    drift_bound(b->tree, c->s, b->cur, b->d, b->ch, x, nx, NULL, add);
    const float *dr = c->src.drift + 3 * (size_t)vid;
    float *bd = b->bound + 3 * (size_t)j, sum[3];
    for (int k = 0; k < 3; ++k) {
        bd[k] = (float)fmin(add[k], 3e38);
        sum[k] = fminf(dr[k] + bd[k], 3e38f);
    }
    b->flag[j] = (uint8_t)drift_seen(c, vid, sum);
}

/* ---- the bound checked through the value's own hemisphere ----------------------
 *
 * The bound above ignores occlusion: a value in a room lit through a slit is
 * charged with every change of the lit room behind the wall, as if the wall were
 * not there. Measured on cache_indirect_test's slot at JND 1 (a scratch count in
 * cache_regather_outdated): of 28,000 values it flagged and gathered again, 4%
 * moved by more than the JND and half did not move at all (the same rays, as
 * every gather of a point draws them, met no changed triangle); most were
 * gathers of 64 times the plain rays (docs/cache.md, "Drift seen through the
 * value's own rays"). So a flagged value is first probed where a quarter of its
 * gather's rays (PROBE_SHARE) makes a probe of PROBE_MIN_RAYS or more:
 * that many cosine-weighted rays, PROBE_RAYS at most, from where its gathers
 * start (samp_surface_hits_trace), each hit's change L_new − L_old read from
 * both sources. Their mean estimates the change the value saw (the same hits
 * for both: no noise of the source's own); the mean plus PROBE_Z standard
 * errors, where less than the occlusion-blind bound, takes its place, and the
 * flag is judged again. A change behind a wall, or on a surface none of the
 * rays meets, adds nothing. What the probe cannot see (a change on a part of
 * the hemisphere so small that no ray meets it) is the statistical bet every
 * gather makes; with fewer rays it loses: probes of 64 rays (the slot's plain
 * gathers at a quarter) left a receiver there 10.1% off. */
enum { PROBE_RAYS = 1024, PROBE_MIN_RAYS = 256, PROBE_BATCH = 256, PROBE_MAX_COST = 64 };
#define PROBE_SHARE 0.25
#define PROBE_Z 3.0f

/* The probes' reading of their hits (probe_one over threads): made by the
 * worker thread, read by lm_parallel_for's threads, each of which writes only
 * its own points' est. */
typedef struct probe_job {
    const samp_radiance_mesh *old, *cur;
    const samp_radiance_index *ix_old, *ix_new;
    const samp_surface_hits *hits;
    float *est; /* 3 per point: |mean change| + PROBE_Z standard errors of E */
} probe_job;

static void probe_one(void *user, uint32_t i)
{
    const probe_job *p = user;
    const samp_surface_hits *h = p->hits;
    double m1[3] = {0, 0, 0}, m2[3] = {0, 0, 0};
    for (uint32_t j = 0; j < h->count[i]; ++j) {
        const size_t at = (size_t)i * h->rays + j;
        float now[3], was[3];
        samp_radiance_at(p->cur, p->ix_new, h->tri[at], h->bary[2 * at], h->bary[2 * at + 1], now);
        samp_radiance_at(p->old, p->ix_old, h->tri[at], h->bary[2 * at], h->bary[2 * at + 1], was);
        for (int k = 0; k < 3; ++k) {
            const double dl = (double)now[k] - was[k];
            m1[k] += dl;
            m2[k] += dl * dl;
        }
    }
    const double R = h->rays; /* a miss or a back is a ray that saw no change */
    for (int k = 0; k < 3; ++k) {
        const double mean = m1[k] / R, var = fmax(m2[k] / R - mean * mean, 0.0) * R / (R - 1.0);
        /* E ≈ π/R·Σ L(hit) (samp_surface_hits) */
        p->est[3 * (size_t)i + (size_t)k] = (float)(M_PI * (fabs(mean) + PROBE_Z * sqrt(var / R)));
    }
}

/* The rays of a probe for a value whose gather costs `cost` plain gathers of
 * `plain` rays: the largest square within PROBE_SHARE of them, PROBE_RAYS at
 * most; 0 (no probe) below PROBE_MIN_RAYS. */
static uint32_t probe_rays_for(uint64_t cost, uint32_t plain)
{
    const double budget = fmin((double)cost * plain * PROBE_SHARE, PROBE_RAYS);
    const uint32_t k = (uint32_t)floor(sqrt(budget));
    return k * k >= PROBE_MIN_RAYS ? k * k : 0;
}

/* The flagged candidates worth a probe: their bounds tightened and their flags
 * judged again. In batches of one ray count (the values of one gather level). */
static lm_result probe_flagged(cache *c, const samp_radiance_mesh *old, const samp_radiance_index *ix_old,
                               const uint32_t *cand, uint32_t nc, uint8_t *flag, float *bound, lm_error *err)
{
    const uint32_t plain = samp_indirect_rays(c->sp);
    if (!plain) return LM_OK; /* no ray count to save (GL) */
    uint32_t worth = 0; /* most rebuilds flag nothing worth a probe: nothing allocated then */
    for (uint32_t j = 0; j < nc && !worth; ++j) worth = flag[j] && probe_rays_for(cache_gather_cost(c, cand[j]), plain);
    if (!worth) return LM_OK;
    uint32_t *which = malloc(PROBE_BATCH * sizeof *which), *count = malloc(PROBE_BATCH * sizeof *count);
    uint32_t *tri = malloc((size_t)PROBE_BATCH * PROBE_RAYS * sizeof *tri);
    float *bary = malloc(2 * (size_t)PROBE_BATCH * PROBE_RAYS * sizeof *bary), *est = malloc(3 * PROBE_BATCH * sizeof *est);
    samp_point *pts = malloc(PROBE_BATCH * sizeof *pts);
    lm_result r = which && count && tri && bary && est && pts ? LM_OK
                                                            : lm_fail(err, LM_ERR_NO_MEMORY, "out of memory probing indirect values");
    for (uint64_t cost = 1; r == LM_OK && cost <= PROBE_MAX_COST; cost *= 4) {
        const uint32_t rays = probe_rays_for(cost, plain);
        if (!rays) continue;
        const samp_surface_hits hits = {.rays = rays, .count = count, .tri = tri, .bary = bary};
        const probe_job job = {.old = old, .cur = &c->src.rmesh, .ix_old = ix_old, .ix_new = &c->src.rm_index,
                               .hits = &hits, .est = est};
        for (uint32_t j0 = 0; r == LM_OK && j0 < nc;) {
            uint32_t n = 0;
            for (; j0 < nc && n < PROBE_BATCH; ++j0) {
                const uint64_t own = cache_gather_cost(c, cand[j0]);
                if (flag[j0] && (own == cost || (cost == PROBE_MAX_COST && own > cost))) {
                    which[n] = j0;
                    pts[n++] = cache_gather_point(c, cand[j0]);
                }
            }
            if (!n) break;
            r = samp_surface_hits_trace(c->sp, pts, n, &hits, err);
            if (r != LM_OK) break;
            c->src.probe_rays += (uint64_t)n * rays;
            lm_parallel_for(lm_thread_count(0), n, probe_one, (void *)&job);
            for (uint32_t i = 0; i < n; ++i) {
                const uint32_t j = which[i];
                float *bd = bound + 3 * (size_t)j, sum[3];
                const float *dr = c->src.drift + 3 * (size_t)cand[j];
                for (int k = 0; k < 3; ++k) {
                    bd[k] = fminf(bd[k], est[3 * (size_t)i + (size_t)k]);
                    sum[k] = fminf(dr[k] + bd[k], 3e38f);
                }
                flag[j] = (uint8_t)drift_seen(c, cand[j], sum);
                c->src.probed++;
                c->src.probe_cleared += !flag[j];
            }
        }
    }
    free(which);
    free(count);
    free(tri);
    free(bary);
    free(est);
    free(pts);
    return r;
}

/* The glossy parts (cache_glossy.c) are bounded by the same tree with the lobe
 * in the kernel: a far node's bound times the lobe's largest value over its
 * bounding sphere (a sharp lobe aimed elsewhere adds nothing), a near changed
 * triangle's exact lobe integral (samp_polygon_phong). Stale at every rebuild
 * instead, the Veach door's glossy parts were taken again 183,000 times in 60 s
 * (10,600 values): the specular leaves' tests refined the light mesh, whose
 * revised values rebuilt the source, whose sweep tested the specular leaves
 * again (docs/cache.md, "Glossy reflection of the room"). */

static void glossy_bound_one(void *user, uint32_t j)
{
    const bound_job *b = user;
    const cache *c = b->c;
    const scene *s = c->s;
    const uint32_t vid = b->cand[j];
    const mesh_vertex *mv = mesh_vtable_vertex(c->vt, vid);
    double x[3], nx[3];
    bound_origin(c, vid, x, nx);
    const double n = s->materials[s->tris[mv->tri].material].n;
    drift_lobe lb = {.wo = {c->eye[0] - x[0], c->eye[1] - x[1], c->eye[2] - x[2]}, .n = n,
                     .peak = (float)((n + 2.0) / (2.0 * M_PI))};
    const lm_dvec3 N = dv3_normalize(dv3(nx[0], nx[1], nx[2])), W = dv3_normalize(dv3(lb.wo[0], lb.wo[1], lb.wo[2]));
    const lm_dvec3 A = dv3_sub(dv3_scale(N, 2.0 * dv3_dot(N, W)), W);
    lb.axis[0] = (float)A.x, lb.axis[1] = (float)A.y, lb.axis[2] = (float)A.z;
    /* the changes too small to look at: at most their largest times the lobe's
     * (n+2)/(n+1), the most a lobe-weighted average can carry */
    const double avg = (n + 2.0) / (n + 1.0);
    double add[3] = {avg * b->small[0], avg * b->small[1], avg * b->small[2]};
    drift_bound(b->tree, s, b->cur, b->d, b->ch, x, nx, &lb, add);
    for (int k = 0; k < 3; ++k) b->bound[3 * (size_t)j + (size_t)k] = (float)fmin(add[k], 3e38);
}

static lm_result glossy_drift(cache *c, const drift_tree *tree, const samp_radiance_mesh *cur, const float *d,
                              const float *small, const changed_tri *ch, lm_error *err)
{
    const uint32_t limit = mesh_vtable_id_limit(c->vt);
    uint32_t *cand = malloc((limit ? limit : 1) * sizeof *cand), nc = 0;
    if (!cand) return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory bounding glossy reflections");
    for (uint32_t vid = 0; vid < limit; ++vid) {
        if (!cache_glossy_fresh(c, vid)) continue;
        if (c->pixels && !c->pixels[mesh_vtable_vertex(c->vt, vid)->tri]) continue; /* swept as unseen */
        cand[nc++] = vid;
    }
    float *bound = malloc(3 * (size_t)(nc ? nc : 1) * sizeof *bound);
    lm_result r = bound ? LM_OK : lm_fail(err, LM_ERR_NO_MEMORY, "out of memory bounding glossy reflections");
    if (r == LM_OK && nc) {
        bound_job job = {.c = c, .tree = tree, .cur = cur, .d = d, .small = small, .ch = ch, .cand = cand,
                         .bound = bound};
        lm_parallel_for(lm_thread_count(0), nc, glossy_bound_one, &job);
    }
    for (uint32_t j = 0; r == LM_OK && j < nc; ++j) cache_glossy_drift(c, cand[j], bound + 3 * (size_t)j);
    free(cand);
    free(bound);
    return r;
}

/* Compares the new source (c->src.rmesh) with the previous one (c->rp_*), adds the
 * bounds to the drift of every displayed indirect value and flags those that may
 * have moved by more than the JND. */
lm_result cache_mark_outdated(cache *c, lm_error *err)
{
    const scene *s = c->s;
    const samp_radiance_mesh old = {.tri_count = (uint32_t)c->src.rp_count, .first = c->src.rp_first, .bary = c->src.rp_bary,
                                    .radiance = c->src.rp_rad, .index = &c->src.rp_index};
    const samp_radiance_mesh *cur = &c->src.rmesh;
    const samp_radiance_index *ix_old = &c->src.rp_index, *ix_new = &c->src.rm_index;
    float *d = calloc(3 * (size_t)(cur->tri_count ? cur->tri_count : 1), sizeof *d);
    /* The mean change at each new triangle's corners (its ∫ change dA over its
     * area where the old source is linear over it), and whether it is not: an old
     * corner inside it (the cut was coarser there before, or chosen otherwise). */
    float *sd = calloc(3 * (size_t)(cur->tri_count ? cur->tri_count : 1), sizeof *sd);
    uint8_t *nonlinear = calloc(cur->tri_count ? cur->tri_count : 1, 1);
    changed_tri *ch = NULL;
    lm_result r = d && sd && nonlinear ? LM_OK : lm_fail(err, LM_ERR_NO_MEMORY, "out of memory comparing indirect sources");
    /* The change over each new triangle: at its corners, and at the old corners
     * that fall inside it. */
    for (uint32_t t = 0; r == LM_OK && t < s->tri_count; ++t)
        for (uint32_t i = cur->first[t]; i < cur->first[t + 1]; ++i)
            for (int k = 0; k < 3; ++k) {
                const float *b = cur->bary + 6 * (size_t)i, *rad = cur->radiance + 9 * (size_t)i;
                float was[3];
                samp_radiance_at(&old, ix_old, t, b[2 * k], b[2 * k + 1], was);
                for (int chn = 0; chn < 3; ++chn) {
                    d[3 * i + (uint32_t)chn] = fmaxf(d[3 * i + (uint32_t)chn], fabsf(rad[3 * k + chn] - was[chn]));
                    sd[3 * i + (uint32_t)chn] += (rad[3 * k + chn] - was[chn]) / 3.0f;
                }
            }
    for (uint32_t t = 0; r == LM_OK && t < s->tri_count; ++t)
        for (uint32_t i = old.first[t]; i < old.first[t + 1]; ++i)
            for (int k = 0; k < 3; ++k) {
                const float *b = old.bary + 6 * (size_t)i, *rad = old.radiance + 9 * (size_t)i;
                float now[3];
                uint32_t at = samp_radiance_at(cur, ix_new, t, b[2 * k], b[2 * k + 1], now);
                if (at == UINT32_MAX) continue;
                const float *nb = cur->bary + 6 * (size_t)at;
                int corner = 0;
                for (int q = 0; q < 3 && !corner; ++q)
                    corner = fabsf(nb[2 * q] - b[2 * k]) < 1e-6f && fabsf(nb[2 * q + 1] - b[2 * k + 1]) < 1e-6f;
                if (!corner) nonlinear[at] = 1;
                for (int chn = 0; chn < 3; ++chn)
                    d[3 * at + (uint32_t)chn] = fmaxf(d[3 * at + (uint32_t)chn], fabsf(rad[3 * k + chn] - now[chn]));
            }
    /* Old triangles of a scene triangle that has none now (or the reverse) sent
     * light that is gone: counted through the corners above only where both exist;
     * a scene triangle that lost its whole source cannot happen (roots stay). */
    /* Triangles whose change is under 10⁻⁵ of the largest are not looked at one by
     * one: their largest change times π (all the cosine-weighted solid angle there
     * is) is added to every value instead, which keeps the bound. A cut that moved
     * by round-off everywhere costs one pass then. (10⁻³ before: in the Veach door,
     * whose lamp room is 10⁴ times brighter than the room seen, that charged every
     * dim glossy part 0.065 a rebuild, and most were taken again at each; 10⁻⁵:
     * glossy parts taken again in 60 s 112,000 → 65,000, indirect gathers 271,000
     * → 242,000, the boxes' times the same.) */
    float dmax = 0.0f, small[3] = {0, 0, 0};
    for (uint32_t i = 0; r == LM_OK && i < cur->tri_count; ++i)
        dmax = fmaxf(dmax, fmaxf(d[3 * i], fmaxf(d[3 * i + 1], d[3 * i + 2])));
    uint32_t nch = 0;
    if (r == LM_OK) {
        ch = malloc((cur->tri_count ? cur->tri_count : 1) * sizeof *ch);
        if (!ch) r = lm_fail(err, LM_ERR_NO_MEMORY, "out of memory comparing indirect sources");
    }
    for (uint32_t t = 0; r == LM_OK && t < s->tri_count; ++t)
        for (uint32_t i = cur->first[t]; i < cur->first[t + 1]; ++i) {
            const float *di = d + 3 * (size_t)i;
            float dm = fmaxf(di[0], fmaxf(di[1], di[2]));
            if (!(dm > 0.0f)) continue;
            if (dm < 1e-5f * dmax) {
                for (int k = 0; k < 3; ++k) small[k] = fmaxf(small[k], di[k]);
                continue;
            }
            ch[nch++] = (changed_tri){t, i};
        }
    /* Every displayed indirect value: its drift grows by Σ d·weight. */
    const uint32_t id_limit = mesh_vtable_id_limit(c->vt);
    int any = nch || small[0] > 0.0f || small[1] > 0.0f || small[2] > 0.0f;
    if (r == LM_OK && any) r = cache_grow_drift(&c->src, id_limit, err);
    drift_tree tree = {0};
    if (r == LM_OK && any && !drift_tree_make(&tree, s, cur, d, sd, nonlinear, ch, nch))
        r = lm_fail(err, LM_ERR_NO_MEMORY, "out of memory comparing indirect sources");
    /* Values no pixel sees are not bounded (half of a big scene's, and the bound
     * is most of a rebuild's time there): they are gathered again when a pixel
     * sees them (cache_refresh_stale). Without pixels, every value is. */
    uint8_t *seen = r == LM_OK && any && c->pixels ? seen_vertices(c, c->pixels) : NULL;
    if (r == LM_OK && any && c->pixels && !seen) r = lm_fail(err, LM_ERR_NO_MEMORY, "out of memory finding the seen indirect values");
    /* The values to bound, then their bounds over every core (each reads the
     * tree and the cache and writes its own drift: 0.6 s of the 116k box's run
     * in the worker alone, while the other core waited), then the flags. */
    uint32_t *cand = NULL, nc = 0;
    uint8_t *flag = NULL;
    if (r == LM_OK && any) {
        cand = malloc((id_limit ? id_limit : 1) * sizeof *cand);
        if (!cand) r = lm_fail(err, LM_ERR_NO_MEMORY, "out of memory comparing indirect sources");
    }
    for (uint32_t vid = 0; r == LM_OK && any && vid < id_limit; ++vid) {
        if (c->src.outdated[vid] || mesh_qmesh_get_value(c->indirect, vid, NULL) != 1) continue;
        if (isinf(c->src.borrowed[vid])) continue; /* borrowed, not tested yet: its test judges it */
        if (seen && !seen[vid]) {
            c->src.stale_n += !c->src.unseen_stale[vid];
            c->src.unseen_stale[vid] = 1;
            continue;
        }
        cand[nc++] = vid;
    }
    float *bound = NULL;
    if (r == LM_OK && nc) {
        flag = malloc(nc);
        bound = malloc(3 * (size_t)nc * sizeof *bound);
        if (!flag || !bound) r = lm_fail(err, LM_ERR_NO_MEMORY, "out of memory comparing indirect sources");
    }
    if (r == LM_OK && nc) {
        bound_job job = {.c = c, .tree = &tree, .cur = cur, .d = d, .ch = ch, .small = small, .cand = cand, .flag = flag,
                         .bound = bound};
        lm_parallel_for(lm_thread_count(0), nc, bound_one, &job);
        r = probe_flagged(c, &old, ix_old, cand, nc, flag, bound, err);
    }
    for (uint32_t j = 0; r == LM_OK && j < nc; ++j) {
        float *dr = c->src.drift + 3 * (size_t)cand[j];
        for (int k = 0; k < 3; ++k) dr[k] = fminf(dr[k] + bound[3 * (size_t)j + (size_t)k], 3e38f);
        if (flag[j]) r = cache_push_outdated(&c->src, cand[j], err);
    }
    if (r == LM_OK && any && cache_glossy_on(c)) r = glossy_drift(c, &tree, cur, d, small, ch, err);
    free(cand);
    free(flag);
    free(bound);
    free(seen);
    drift_tree_free(&tree);
    free(ch);
    free(d);
    free(sd);
    free(nonlinear);
    return r;
}
