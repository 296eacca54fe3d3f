/* cache_drift.c — which indirect values a rebuild of the radiance source may
 * have moved (cache_source.c rebuilds it and gathers the flagged values again):
 * the drift bound of every displayed value, and the flags. Split from
 * cache_source.c (it had grown past 1,100 lines); writes cache_source_state's
 * drift, outdated and outdated_list only. Worker thread, like the rest of the
 * cache. */
#include "mesh/cache/cache_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "sampling/analytic.h"
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
        !lm_realloc_array(&st->gather_level, st->drift_cap, cap, sizeof *st->gather_level))
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

/* The changed triangles as the far-field loop reads them (structure of arrays:
 * the loop over them runs for every indirect value and vectorises): centre,
 * front normal, 16·radius² (nearer than four radii: exact), area × change. */
typedef struct far_field {
    float *cx, *cy, *cz, *nx, *ny, *nz, *lim, *ad0, *ad1, *ad2;
    uint32_t *near;
} far_field;

/* The corners of changed triangle ct in the scene. */
static void changed_corners(const scene *s, const samp_radiance_mesh *cur, changed_tri ct, double p[3][3])
{
    const float *b = cur->bary + 6 * (size_t)ct.i;
    for (int k = 0; k < 3; ++k) bary_point(s, ct.t, b[2 * k], b[2 * k + 1], p[k]);
}

static int far_field_make(far_field *f, const scene *s, const samp_radiance_mesh *cur, const float *d,
                          const changed_tri *ch, uint32_t n)
{
    float *block = malloc((size_t)(n ? n : 1) * 10 * sizeof *block);
    f->near = malloc((n ? n : 1) * sizeof *f->near);
    if (!block || !f->near) {
        free(block);
        free(f->near);
        return 0;
    }
    float **cols[10] = {&f->cx, &f->cy, &f->cz, &f->nx, &f->ny, &f->nz, &f->lim, &f->ad0, &f->ad1, &f->ad2};
    for (int k = 0; k < 10; ++k) *cols[k] = block + (size_t)k * (n ? n : 1);
    for (uint32_t j = 0; j < n; ++j) {
        double p[3][3];
        changed_corners(s, cur, ch[j], p);
        lm_dvec3 a = dv3(p[0][0], p[0][1], p[0][2]), bb = dv3(p[1][0], p[1][1], p[1][2]), cc = dv3(p[2][0], p[2][1], p[2][2]);
        lm_dvec3 centre = dv3_scale(dv3_add(dv3_add(a, bb), cc), 1.0 / 3.0);
        double area = 0.5 * dv3_length(dv3_cross(dv3_sub(bb, a), dv3_sub(cc, a)));
        lm_dvec3 normal = dv3_load(s->tri_normals + 3 * (size_t)ch[j].t);
        double radius = fmax(dv3_length(dv3_sub(a, centre)),
                             fmax(dv3_length(dv3_sub(bb, centre)), dv3_length(dv3_sub(cc, centre))));
        const float *dj = d + 3 * (size_t)ch[j].i;
        f->cx[j] = (float)centre.x;
        f->cy[j] = (float)centre.y;
        f->cz[j] = (float)centre.z;
        f->nx[j] = (float)normal.x;
        f->ny[j] = (float)normal.y;
        f->nz[j] = (float)normal.z;
        f->lim[j] = (float)(16.0 * radius * radius);
        f->ad0[j] = (float)(area * dj[0]);
        f->ad1[j] = (float)(area * dj[1]);
        f->ad2[j] = (float)(area * dj[2]);
    }
    return 1;
}

static void far_field_free(far_field *f)
{
    free(f->cx);
    free(f->near);
}

/* Σ_j d_j·∫ over changed triangle j's front of cosθ_x dω from (x, nx), into add:
 * by area and cosines over distance² beyond four radii, exactly
 * (samp_polygon_G) nearer. */
static void drift_bound(const far_field *f, const scene *s, const samp_radiance_mesh *cur, const float *d,
                        const changed_tri *ch, uint32_t n, const double x[3], const double nx[3], double add[3])
{
    const float X = (float)x[0], Y = (float)x[1], Z = (float)x[2], NX = (float)nx[0], NY = (float)nx[1],
                NZ = (float)nx[2];
    float a0 = 0.0f, a1 = 0.0f, a2 = 0.0f;
    uint32_t nn = 0;
    for (uint32_t j = 0; j < n; ++j) {
        float dx = f->cx[j] - X, dy = f->cy[j] - Y, dz = f->cz[j] - Z;
        float r2 = dx * dx + dy * dy + dz * dz;
        float px = dx * NX + dy * NY + dz * NZ, py = -(dx * f->nx[j] + dy * f->ny[j] + dz * f->nz[j]);
        int far = r2 > f->lim[j];
        float w = far && px > 0.0f && py > 0.0f ? px * py / (r2 * r2) : 0.0f; /* A·cosθx·cosθy/r² over A */
        a0 += w * f->ad0[j];
        a1 += w * f->ad1[j];
        a2 += w * f->ad2[j];
        f->near[nn] = j;
        nn += (uint32_t)!far;
    }
    add[0] += a0;
    add[1] += a1;
    add[2] += a2;
    for (uint32_t i = 0; i < nn; ++i) {
        const changed_tri ct = ch[f->near[i]];
        double p[3][3];
        changed_corners(s, cur, ct, p);
        double w = samp_polygon_G(p, 3, x, nx);
        for (int k = 0; k < 3; ++k) add[k] += w * d[3 * (size_t)ct.i + (size_t)k];
    }
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

/* Compares the new source (c->src.rmesh) with the previous one (c->rp_*), adds the
 * bounds to the drift of every displayed indirect value and flags those that may
 * have moved by more than the JND. */
lm_result cache_mark_outdated(cache *c, lm_error *err)
{
    const scene *s = c->s;
    const samp_radiance_mesh old = {.tri_count = (uint32_t)c->src.rp_count, .first = c->src.rp_first, .bary = c->src.rp_bary,
                                    .radiance = c->src.rp_rad};
    const samp_radiance_mesh *cur = &c->src.rmesh;
    samp_radiance_index ix_old, ix_new;
    samp_radiance_index_build(s, &old, &ix_old);
    samp_radiance_index_build(s, cur, &ix_new);
    float *d = calloc(3 * (size_t)(cur->tri_count ? cur->tri_count : 1), sizeof *d);
    changed_tri *ch = NULL;
    lm_result r = d ? LM_OK : lm_fail(err, LM_ERR_NO_MEMORY, "out of memory comparing indirect sources");
    /* The change over each new triangle: at its corners, and at the old corners
     * that fall inside it. */
    for (uint32_t t = 0; r == LM_OK && t < s->tri_count; ++t)
        for (uint32_t i = cur->first[t]; i < cur->first[t + 1]; ++i)
            for (int k = 0; k < 3; ++k) {
                const float *b = cur->bary + 6 * (size_t)i, *rad = cur->radiance + 9 * (size_t)i;
                float was[3];
                samp_radiance_at(&old, &ix_old, t, b[2 * k], b[2 * k + 1], was);
                for (int chn = 0; chn < 3; ++chn)
                    d[3 * i + (uint32_t)chn] = fmaxf(d[3 * i + (uint32_t)chn], fabsf(rad[3 * k + chn] - was[chn]));
            }
    for (uint32_t t = 0; r == LM_OK && t < s->tri_count; ++t)
        for (uint32_t i = old.first[t]; i < old.first[t + 1]; ++i)
            for (int k = 0; k < 3; ++k) {
                const float *b = old.bary + 6 * (size_t)i, *rad = old.radiance + 9 * (size_t)i;
                float now[3];
                uint32_t at = samp_radiance_at(cur, &ix_new, t, b[2 * k], b[2 * k + 1], now);
                if (at == UINT32_MAX) continue;
                for (int chn = 0; chn < 3; ++chn)
                    d[3 * at + (uint32_t)chn] = fmaxf(d[3 * at + (uint32_t)chn], fabsf(rad[3 * k + chn] - now[chn]));
            }
    /* Old triangles of a scene triangle that has none now (or the reverse) sent
     * light that is gone: counted through the corners above only where both exist;
     * a scene triangle that lost its whole source cannot happen (roots stay). */
    /* Triangles whose change is under a thousandth of the largest are not looked at
     * one by one: their largest change times π (all the cosine-weighted solid angle
     * there is) is added to every value instead, which keeps the bound. A cut that
     * moved by round-off everywhere costs one pass then. */
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
            if (dm < 1e-3f * dmax) {
                for (int k = 0; k < 3; ++k) small[k] = fmaxf(small[k], di[k]);
                continue;
            }
            ch[nch++] = (changed_tri){t, i};
        }
    /* Every displayed indirect value: its drift grows by Σ d·weight. */
    const uint32_t id_limit = mesh_vtable_id_limit(c->vt);
    int any = nch || small[0] > 0.0f || small[1] > 0.0f || small[2] > 0.0f;
    if (r == LM_OK && any) r = cache_grow_drift(&c->src, id_limit, err);
    far_field ff = {0};
    if (r == LM_OK && any && !far_field_make(&ff, s, cur, d, ch, nch))
        r = lm_fail(err, LM_ERR_NO_MEMORY, "out of memory comparing indirect sources");
    for (uint32_t vid = 0; r == LM_OK && any && vid < id_limit; ++vid) {
        float e[3];
        if (c->src.outdated[vid] || mesh_qmesh_get_value(c->indirect, vid, e) != 1) continue;
        const mesh_vertex *mv = mesh_vtable_vertex(c->vt, vid);
        /* From where the gather looks (a point on a surface's plane sees none of it). */
        samp_point sp = cache_vertex_point(c, vid);
        float o[3];
        samp_point_origin(s, &sp, samp_point_epsilon(c->sp, &sp), o);
        const double x[3] = {o[0], o[1], o[2]}, nx[3] = {mv->normal[0], mv->normal[1], mv->normal[2]};
        double add[3] = {M_PI * small[0], M_PI * small[1], M_PI * small[2]};
        drift_bound(&ff, s, cur, d, ch, nch, x, nx, add);
        float *dr = c->src.drift + 3 * (size_t)vid;
        for (int k = 0; k < 3; ++k) dr[k] += (float)fmin(add[k], 3e38);
        /* Could the drift be seen? E ± drift against E, through the tone map. */
        float ldd[3], lab0[3], lab1[3], up[3], down[3];
        cache_vertex_direct(c, vid, ldd);
        /* (E cannot be negative: the bounds are clamped at 0; L_ds is left out.) */
        float e0[3];
        for (int k = 0; k < 3; ++k) {
            e0[k] = fmaxf(e[k], 0.0f);
            up[k] = fmaxf(e[k] + dr[k], 0.0f);
            down[k] = fmaxf(e[k] - dr[k], 0.0f);
        }
        cache_seen_lab(c, mv->tri, ldd, e0, NULL, lab0);
        cache_seen_lab(c, mv->tri, ldd, up, NULL, lab1);
        int seen = tm_delta_e(lab0, lab1) > c->desc.jnd;
        if (!seen) {
            cache_seen_lab(c, mv->tri, ldd, down, NULL, lab1);
            seen = tm_delta_e(lab0, lab1) > c->desc.jnd;
        }
        if (seen) r = cache_push_outdated(&c->src, vid, err);
    }
    far_field_free(&ff);
    free(ch);
    free(d);
    samp_radiance_index_free(&ix_old);
    samp_radiance_index_free(&ix_new);
    return r;
}
