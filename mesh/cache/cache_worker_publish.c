/* cache_worker_publish.c — the refinement worker's snapshots: each mesh's leaf
 * triangles published indexed, a piece at a time, into the worker's back slot,
 * then committed by a pointer swap (cache_worker_internal.h; cache_snapshot.h
 * says what a snapshot holds).
 *
 * Threads: everything here runs on the worker thread but cache_publish_commit's
 * swap (under the worker's lock) and cache_publish_store_free (the display's,
 * once the thread is joined). What it does NOT do: decide when to publish
 * (cache_worker.c, worker_main) or draw (src/render/).
 */
#define _POSIX_C_SOURCE 200809L
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>

#include "mesh/cache/cache_worker_internal.h"

/* Debug data of the triangles buf[0..count): vertex ids, sampled flags, and which
 * edges lie on their leaf's boundary. mesh_qmesh_leaf_triangles emits each leaf's
 * triangles consecutively; an edge inside the leaf (a fan diagonal) is shared,
 * reversed, by two of them, a boundary edge by none. */
static void fill_corners(cache_snapshot_corner *out, const mesh_qmesh *m, const mesh_qmesh_tri *buf, size_t count)
{
    for (size_t i = 0; i < 3 * count; ++i) {
        uint32_t id = buf[i / 3].v[i % 3];
        out[i] = (cache_snapshot_corner){.vertex = id, .flags = CACHE_CORNER_LEAF_EDGE};
        float scratch[MESH_QMESH_CHANNELS_MAX];
        if (mesh_qmesh_get_value(m, id, scratch) == 1) out[i].flags |= CACHE_CORNER_SAMPLED;
    }
    for (size_t g = 0, e; g < count; g = e) {
        for (e = g + 1; e < count && buf[e].leaf == buf[g].leaf;) ++e;
        for (size_t i = g; i < e; ++i)
            for (size_t j = i + 1; j < e; ++j)
                for (int a = 0; a < 3; ++a)
                    for (int b = 0; b < 3; ++b)
                        if (buf[i].v[a] == buf[j].v[(b + 1) % 3] && buf[i].v[(a + 1) % 3] == buf[j].v[b]) {
                            out[3 * i + (size_t)a].flags &= ~(uint32_t)CACHE_CORNER_LEAF_EDGE;
                            out[3 * j + (size_t)b].flags &= ~(uint32_t)CACHE_CORNER_LEAF_EDGE;
                        }
    }
}

/* Appends the piece ps->buf[0..got) to ms as triangles count.. and vertices
 * *nv..: each vertex the first time a triangle uses it. */
static lm_result append_piece(mesh_store *ms, fill_scratch *ps, int debug, const cache *c, const mesh_qmesh *m,
                              size_t count, size_t got, uint32_t *nv, lm_error *err)
{
    const size_t most = (size_t)*nv + 3 * got;
    /* Written before read, each up to its count: not zeroed (a vertex's room is
     * reserved for three a triangle, several times what is used). */
    if (!LM_GROW_RAW(ms->index, ms->index_cap, 3 * (count + got)) ||
        !LM_GROW_RAW(ms->tris, ms->tris_cap, count + got) ||
        (debug && !LM_GROW_RAW(ms->corners, ms->corners_cap, 3 * (count + got))) ||
        !LM_GROW_RAW(ms->verts, ms->verts_cap, most) || !LM_GROW_RAW(ps->ids, ps->ids_cap, most))
        return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory publishing the cache");
    const mesh_vtable *vt = cache_vtable(c);
    const int pad = mesh_qmesh_channels(m) < 3; /* a light mesh: V, then zeros */
    const uint32_t first_new = *nv;
    for (size_t i = 0; i < 3 * got; ++i) {
        uint32_t id = ps->buf[i / 3].v[i % 3];
        if (ps->local[id] == UINT32_MAX) {
            cache_snapshot_vertex *out = &ms->verts[*nv];
            memcpy(out->position, mesh_vtable_vertex(vt, id)->position, sizeof out->position);
            if (pad) memset(out->value, 0, sizeof out->value);
            if (mesh_qmesh_get_value(m, id, out->value) < 0) memset(out->value, 0, sizeof out->value);
            ps->ids[*nv] = id;
            ps->local[id] = (*nv)++;
        }
        ms->index[3 * count + i] = ps->local[id];
    }
    /* The specular mesh's lobes, for the vertices this piece added: grown to
     * those, not to the piece's worst case as the arrays above are (32 bytes a
     * vertex, three corners a triangle of a 65,536-triangle piece: 6 MB
     * reserved a fill; heaptrack put 8 MB of Water's heap peak there). */
    if (m == cache_specular_mesh(c) && *nv > first_new) {
        if (!LM_GROW_RAW(ms->lobes, ms->lobes_cap, *nv))
            return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory publishing the cache");
        for (uint32_t v = first_new; v < *nv; ++v) cache_get_lobe(c, ps->ids[v], &ms->lobes[v]);
    }
    for (size_t i = 0; i < got; ++i) ms->tris[count + i] = ps->buf[i].tri;
    if (debug) fill_corners(ms->corners + 3 * count, m, ps->buf, got);
    return LM_OK;
}

/* Shrinks *p (capacity *cap elements of elem bytes) to `used` when more than an
 * eighth of it is spare; left as it is when realloc fails (it still holds all). */
static void fit_array(void **p, size_t *cap, size_t used, size_t elem)
{
    if (!used || *cap - used <= used / 8) return;
    void *q = realloc(*p, used * elem);
    if (!q) return;
    *p = q;
    *cap = used;
}

/* Publishes mesh m (NULL: empty) into ms and *sm, indexed: each vertex once, in
 * the order the leaf triangles first use it (they come in node order, so a
 * triangle's corners are mostly near each other in the array too), a piece of
 * PUBLISH_PIECE triangles at a time. Without debug it does exactly what the
 * renderer needs: positions, values, scene triangles. */
/* Whether m's whole roots are better published apart (cache_worker_desc.whole_roots):
 * a whole root listed costs its index, its scene triangle and about half of a
 * vertex shared with its neighbours (12 + 4 + 12 bytes), apart a twelfth of
 * the values by id, which are one array over every id: apart when the roots
 * that are leaves would cost more listed (a big scene's first images). Late in
 * a refinement few roots are whole, and the values by id would cost more than
 * listing them (Water after 20 s: a few MB a slot). */
static int whole_pays(const mesh_qmesh *m)
{
    uint32_t ids = 0;
    mesh_qmesh_values(m, &ids);
    return 28.0 * mesh_qmesh_unsplit_roots(m) >= 12.0 * ids && mesh_qmesh_unsplit_roots(m) > 0;
}

static lm_result fill_mesh(mesh_store *ms, cache_snapshot_mesh *sm, int debug, int whole, const cache *c,
                           const mesh_qmesh *m, fill_scratch *ps, lm_error *err)
{
    whole = whole && !debug && m && mesh_qmesh_channels(m) == 3 && whole_pays(m);
    /* This slot already holds the mesh as it is (a slot is filled every third
     * publication, and one mesh often rests meanwhile: the indirect one while the
     * first image's light is recomputed, the direct one while values are gathered
     * again): *sm still describes its arrays. */
    const mesh_qmesh_version now = mesh_qmesh_get_version(m);
    if (m && ms->filled.serial == now.serial && ms->filled.changes == now.changes && ms->filled_debug == debug &&
        ms->filled_whole == whole && sm->vertices == ms->verts)
        return LM_OK;
    ms->filled = (mesh_qmesh_version){0, 0};
    *sm = (cache_snapshot_mesh){0};
    if (!m) return LM_OK;
    const size_t ids = mesh_vtable_id_limit(cache_vtable(c));
    if (ids > ps->local_cap) {
        uint32_t *l = realloc(ps->local, ids * sizeof *l);
        if (!l) return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory publishing the cache");
        memset(l + ps->local_cap, 0xff, (ids - ps->local_cap) * sizeof *l);
        ps->local = l;
        ps->local_cap = ids;
    }
    /* Whole roots apart: their bits, and every value by id (one copy, in id
     * order, instead of a vertex and an index per corner). */
    const size_t words = ((size_t)mesh_vtable_scene(cache_vtable(c))->tri_count + 31) / 32;
    uint32_t whole_count = 0, value_count = 0;
    const float *values = whole ? mesh_qmesh_values(m, &value_count) : NULL;
    if (!whole && ms->values) { /* listed from now on (whole_pays): the arrays go */
        free(ms->whole);
        free(ms->values);
        ms->whole = NULL, ms->values = NULL, ms->whole_cap = ms->values_cap = 0;
    }
    if (whole) {
        if (!LM_GROW_RAW(ms->whole, ms->whole_cap, words ? words : 1) ||
            !LM_GROW_RAW(ms->values, ms->values_cap, 3 * (size_t)(value_count ? value_count : 1)))
            return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory publishing the cache");
        memset(ms->whole, 0, words * sizeof *ms->whole);
        if (value_count) memcpy(ms->values, values, 3 * (size_t)value_count * sizeof *ms->values);
    }
    size_t count = 0;
    uint32_t nv = 0, next = 0;
    lm_result r = LM_OK;
    while (r == LM_OK && next != UINT32_MAX) {
        size_t got = 0;
        r = mesh_qmesh_split_leaf_triangles_from(m, &next, PUBLISH_PIECE, whole ? ms->whole : NULL, &whole_count,
                                                 &ps->buf, &ps->buf_cap, &got, err);
        if (r == LM_OK && count + got > UINT32_MAX)
            r = lm_fail(err, LM_ERR_NO_MEMORY, "publishing the cache: more than 2^32 triangles in a mesh");
        if (r == LM_OK && got) r = append_piece(ms, ps, debug, c, m, count, got, &nv, err);
        count += got;
    }
    for (uint32_t i = 0; i < nv; ++i) ps->local[ps->ids[i]] = UINT32_MAX;
    if (r != LM_OK) return r;
    /* Grown by doubling piece by piece: down to what is used, so that three slots
     * of a big mesh do not each keep up to twice their size (Water after 20 s:
     * 41 MB of slots at the peak; a shrink or a later growth is an mremap). */
    fit_array((void **)&ms->index, &ms->index_cap, 3 * count, sizeof *ms->index);
    fit_array((void **)&ms->tris, &ms->tris_cap, count, sizeof *ms->tris);
    if (debug) fit_array((void **)&ms->corners, &ms->corners_cap, 3 * count, sizeof *ms->corners);
    fit_array((void **)&ms->verts, &ms->verts_cap, nv, sizeof *ms->verts);
    const int lobes = m == cache_specular_mesh(c) && nv;
    if (lobes) fit_array((void **)&ms->lobes, &ms->lobes_cap, nv, sizeof *ms->lobes);
    *sm = (cache_snapshot_mesh){.vertices = ms->verts, .index = ms->index, .tri = ms->tris,
                                .corners = debug && count ? ms->corners : NULL,
                                .lobes = lobes ? ms->lobes : NULL,
                                .triangle_count = (uint32_t)count, .vertex_count = nv,
                                .whole = whole_count ? ms->whole : NULL, .values = whole_count ? ms->values : NULL,
                                .whole_count = whole_count, .value_count = whole_count ? value_count : 0};
    ms->filled = now;
    ms->filled_debug = debug;
    ms->filled_whole = whole;
    return LM_OK;
}

/* A mesh filled on a helper thread beside the worker's: the fills only read the
 * cache (nothing writes it while a snapshot is made), and each writes its own
 * slot arrays and scratch. A million-triangle scene's first snapshot, direct
 * and indirect meshes of a million leaf triangles each, took 0.23 s on one core. */
typedef struct fill_job {
    mesh_store *ms;           /* written by the helper only */
    cache_snapshot_mesh *sm;  /* written by the helper only */
    int debug, whole;
    const cache *c;           /* read by both threads */
    const mesh_qmesh *m;
    fill_scratch *ps;         /* the helper's (publish_scratch.fill[1]) */
    lm_result r;              /* the helper's result, read after the join */
    lm_error err;
} fill_job;

static void *fill_main(void *arg)
{
    fill_job *job = arg;
    job->r = fill_mesh(job->ms, job->sm, job->debug, job->whole, job->c, job->m, job->ps, &job->err);
    return NULL;
}

void cache_publish_scratch_free(publish_scratch *ps)
{
    for (int k = 0; k < 2; ++k) {
        free(ps->fill[k].buf);
        free(ps->fill[k].local);
        free(ps->fill[k].ids);
    }
    memset(ps, 0, sizeof *ps);
}

/* publish_debug: every light's visibility mesh into snap.lights. */
static lm_result fill_light_meshes(snapshot_store *st, const cache *c, uint32_t light_count, publish_scratch *ps,
                                   lm_error *err)
{
    if (light_count > st->light_mesh_cap) {
        mesh_store *m = realloc(st->light_mesh, light_count * sizeof *m);
        if (m) st->light_mesh = m;
        cache_snapshot_mesh *sm = m ? realloc(st->light_snap, light_count * sizeof *sm) : NULL;
        if (sm) st->light_snap = sm;
        if (!m || !sm) return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory publishing the cache");
        memset(st->light_mesh + st->light_mesh_cap, 0, (light_count - st->light_mesh_cap) * sizeof *m);
        st->light_mesh_cap = light_count;
    }
    for (uint32_t l = 0; l < light_count; ++l) {
        lm_result r =
            fill_mesh(&st->light_mesh[l], &st->light_snap[l], 1, 0, c, cache_light_mesh(c, l), &ps->fill[0], err);
        if (r != LM_OK) return r;
    }
    st->snap.lights = st->light_snap;
    st->snap.light_mesh_count = light_count;
    return LM_OK;
}

/* Each scene corner's vertex-table id, once for the worker's life: a root's
 * corners are these (mesh_qmesh_add_roots), and the cache holds a reference on
 * each, so they never change. */
static lm_result make_corner_ids(cache_worker *w, cache *c, lm_error *err)
{
    static _Atomic uint64_t next_serial;
    if (w->corner_ids) return LM_OK;
    uint32_t *ids = cache_take_corner_ids(c); /* made beside the first roots (cache_desc.corner_ids) */
    if (!ids) ids = cache_make_corner_ids(c);
    if (!ids) return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory publishing the cache");
    w->corner_ids = ids;
    w->corner_ids_serial = atomic_fetch_add(&next_serial, 1) + 1;
    return LM_OK;
}

lm_result cache_publish_snapshot(cache_worker *w, cache *c, const cache_estimate *estimate, int debug,
                                 uint64_t generation, uint64_t tested, int converged, publish_scratch *ps,
                                 lm_error *err)
{
    snapshot_store *st = w->back;
    st->snap.first_rounds_seconds = w->first_rounds_seconds;
    st->snap.first_publish_seconds = w->first_publish_seconds;
    const int whole = w->desc.whole_roots && !debug;
    lm_result r = whole ? make_corner_ids(w, c, err) : LM_OK;
    if (r != LM_OK) return r;
    st->snap.corner_ids = whole ? w->corner_ids : NULL;
    st->snap.corner_ids_serial = whole ? w->corner_ids_serial : 0;
    /* The direct mesh on a helper thread, the others on this one. The specular
     * mesh's leaves are all triangles: its highlights need each vertex's lobe. */
    fill_job job = {.ms = &st->mesh[0], .sm = &st->snap.direct, .debug = debug, .whole = whole, .c = c,
                    .m = cache_direct_mesh(c), .ps = &ps->fill[1], .r = LM_OK};
    pthread_t helper;
    const int helped = pthread_create(&helper, NULL, fill_main, &job) == 0;
    if (!helped) fill_main(&job);
    r = fill_mesh(&st->mesh[1], &st->snap.indirect, debug, whole, c, cache_indirect_mesh(c), &ps->fill[0], err);
    if (r == LM_OK && cache_specular_mesh(c))
        r = fill_mesh(&st->mesh[2], &st->snap.specular, debug, 0, c, cache_specular_mesh(c), &ps->fill[0], err);
    if (!cache_specular_mesh(c)) st->snap.specular = (cache_snapshot_mesh){0};
    if (helped) pthread_join(helper, NULL);
    if (r == LM_OK && job.r != LM_OK) {
        *err = job.err;
        r = job.r;
    }
    if (r != LM_OK) return r;
    cache_get_stats(c, &st->snap.stats);
    st->snap.estimate = *estimate;
    if (debug) r = fill_light_meshes(st, c, st->snap.stats.light_count, ps, err);
    if (r != LM_OK) return r;
    if (st->snap.stats.light_count > st->lights_cap) {
        cache_mesh_stats *l = realloc(st->lights, st->snap.stats.light_count * sizeof *l);
        if (l) st->lights = l;
        float *le = l ? realloc(st->light_radiance, 3 * sizeof *le * st->snap.stats.light_count) : NULL;
        if (le) st->light_radiance = le;
        if (!l || !le) return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory publishing the cache");
        st->lights_cap = st->snap.stats.light_count;
    }
    for (uint32_t l = 0; l < st->snap.stats.light_count; ++l) cache_get_light_radiance(c, l, st->light_radiance + 3 * (size_t)l);
    st->snap.light_radiance = st->light_radiance;
    if (st->snap.stats.light_count)
        memcpy(st->lights, st->snap.stats.lights, st->snap.stats.light_count * sizeof *st->lights);
    st->snap.stats.lights = st->lights;
    st->snap.generation = generation;
    st->snap.tested = tested;
    st->snap.converged = converged;
    st->snap.jnd = cache_get_jnd(c);
    st->snap.failed = 0;
    st->snap.error[0] = 0;
    return LM_OK;
}

/* Commits the worker's snapshot: a pointer swap under the lock. */
void cache_publish_commit(cache_worker *w)
{
    w->back->snap.published_at = lm_now_seconds();
    pthread_mutex_lock(&w->lock);
    snapshot_store *t = w->ready;
    w->ready = w->back;
    w->back = t;
    w->ready_new = 1;
    pthread_cond_broadcast(&w->cond);
    pthread_mutex_unlock(&w->lock);
}

void cache_publish_failure(cache_worker *w, uint64_t generation, const char *msg)
{
    w->back->snap.generation = generation;
    w->back->snap.failed = 1;
    lm_strlcpy(w->back->snap.error, msg, sizeof w->back->snap.error);
    cache_publish_commit(w);
}


void cache_publish_store_free(snapshot_store *st)
{
    if (!st) return;
    for (uint32_t k = 0; k < 3 + st->light_mesh_cap; ++k) {
        mesh_store *ms = k < 3 ? &st->mesh[k] : &st->light_mesh[k - 3];
        free(ms->verts);
        free(ms->index);
        free(ms->tris);
        free(ms->corners);
        free(ms->lobes);
        free(ms->whole);
        free(ms->values);
    }
    free(st->light_mesh);
    free(st->light_snap);
    free(st->lights);
    free(st->light_radiance);
    free(st);
}
