/* cache.c — the multi-mesh cache's public face (cache.h; paper §4): creation and
 * the coarse cache, light and camera edits, evaluation, statistics, and
 * cache_refine(). The top file of the cache (cache_internal.h lists the order): it
 * calls cache_light.c (visibility, direct and specular values), cache_source.c
 * (indirect light) and cache_refine.c (the scheduler), and none of them calls it.
 * Owns the core of struct cache. Worker thread, like the rest of the cache. */
#include "mesh/cache/cache_internal.h"

#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "src/base/vecmath.h"

/* ---- lights ----------------------------------------------------------------- */

static const float *light_radiance(const scene *s, uint32_t l)
{
    return l < s->area_light_count ? s->area_lights[l].le : s->point_lights[l - s->area_light_count].intensity;
}

typedef struct light_filter {
    const scene *s;
    uint32_t light;
} light_filter;

/* A triangle can receive light l at all: some light point is above its plane
 * and some corner of it is in front of the light (conservative: a triangle that
 * fails gets no mesh for this light, and G = 0 there exactly). */
static int sees_light(const scene *s, uint32_t t, void *user)
{
    const light_filter *f = user;
    uint32_t l = f->light;
    if (s->tris[t].light >= 0 && (uint32_t)s->tris[t].light == l) return 0;
    lm_dvec3 n = dv3_load(s->tri_normals + 3 * (size_t)t), p0 = dv3_load(s->positions + 3 * (size_t)s->tris[t].v[0]);
    if (l >= s->area_light_count) {
        lm_dvec3 q = dv3_load(s->point_lights[l - s->area_light_count].position);
        return dv3_dot(dv3_sub(q, p0), n) > 0.0;
    }
    const scene_area_light *L = &s->area_lights[l];
    int above = 0, in_front = 0;
    lm_dvec3 nl = dv3_load(L->normal), cl = dv3_load(L->centroid);
    for (uint32_t i = 0; i < L->count && !above; ++i) {
        const uint32_t *v = s->tris[s->light_tris[L->first + i]].v;
        for (int k = 0; k < 3 && !above; ++k)
            above = dv3_dot(dv3_sub(dv3_load(s->positions + 3 * (size_t)v[k]), p0), n) > 0.0;
    }
    for (int k = 0; k < 3 && !in_front; ++k)
        in_front = dv3_dot(dv3_sub(dv3_load(s->positions + 3 * (size_t)s->tris[t].v[k]), cl), nl) > 0.0;
    return above && in_front;
}

int cache_has_albedo(const scene *s, uint32_t t, void *user)
{
    (void)user;
    const float *kd = s->materials[s->tris[t].material].kd;
    return kd[0] > 0.0f || kd[1] > 0.0f || kd[2] > 0.0f;
}

static int has_gloss(const scene *s, uint32_t t, void *user)
{
    (void)user;
    const float *ks = s->materials[s->tris[t].material].ks;
    return s->tris[t].light < 0 && (ks[0] > 0.0f || ks[1] > 0.0f || ks[2] > 0.0f);
}

lm_result cache_set_light(cache *c, uint32_t light, const float value[3], lm_error *err)
{
    if (!c || !value || light >= c->light_count)
        return lm_fail(err, LM_ERR_INVALID_ARG, "cache_set_light: light %u does not exist", light);
    for (int k = 0; k < 3; ++k)
        if (!(value[k] >= 0.0f) || !isfinite(value[k]))
            return lm_fail(err, LM_ERR_INVALID_ARG, "cache_set_light: radiance must be finite and non-negative");
    memcpy(c->light_le + 3 * (size_t)light, value, 3 * sizeof *value);
    lm_result r = cache_relight_direct(c, err);
    cache_bounces_touch(c); /* L_dd changed everywhere, the direct mesh's shape did not */
    if (r == LM_OK && c->initialised) r = cache_regather_all(c, err);
    if (r == LM_OK && c->initialised) cache_borrow_free(&c->brw); /* every value gathered: nothing is borrowed */
    if (r != LM_OK) return r;
    /* What was below the JND may not be now (a shadow no longer masked by another
     * light): every leaf is tested again, without new light samples unless the
     * test splits it. */
    cache_sched_requeue(&c->sched, CACHE_KINDS);
    /* The specular mesh keeps no G per vertex: sample its roots again (the light
     * meshes answer without new samples where they are sure). */
    if (c->specular) return cache_set_camera(c, c->eye, err);
    return LM_OK;
}

/* ---- create, init, destroy ---------------------------------------------------- */

void cache_destroy(cache *c)
{
    if (!c) return;
    if (c->light)
        for (uint32_t l = 0; l < c->light_count; ++l) mesh_qmesh_destroy(c->light[l]);
    mesh_qmesh_destroy(c->direct);
    mesh_qmesh_destroy(c->indirect);
    mesh_qmesh_destroy(c->specular);
    mesh_qmesh_destroy(c->indirect1);
    cache_bounces_free(&c->bnc);
    mesh_vtable_destroy(c->vt);
    cache_first_order_free(c);
    free(c->corner_ids);
    free(c->light);
    free(c->light_le);
    cache_light_state_free(&c->vis);
    cache_outlines_free(&c->outl);
    cache_source_free(&c->src);
    cache_borrow_free(&c->brw);
    cache_glossy_free(&c->gls);
    free(c->spec_visible);
    cache_sched_free(&c->sched);
    free(c->active);
    free(c->reach_traced);
    free(c->part_first);
    free(c->part_tris);
    free(c);
}

/* ---- roots where triangles take part (issue 16) --------------------------------
 *
 * A mesh gets a root on a triangle when the triangle comes to take part (what a
 * pixel sees and what gathers from it reach: cache_reach.c), not when the mesh
 * is made: a triangle nothing sees and no gather reaches costs no node, value or
 * use count in any mesh (docs/cache.md, "Roots where triangles take part"). The
 * vertex table's records of every scene corner are still made with the cache
 * (hold_corners), in the order the meshes made
 * them when every triangle had roots from the start, so that vertex ids, each
 * vertex's triangle and, once roots come in ascending triangle order, the
 * meshes' nodes are what they were: a scene whose triangles all take part is
 * bit for bit the same. */

/* Scene corner k of triangle t as a root's corner (a0 1, orient 0). */
static mesh_bary root_corner(int k)
{
    const mesh_qnode root = {.a0 = 1, .depth = 0, .orient = 0};
    return mesh_qmesh_node_corner(&root, k);
}

/* The vertex records of the corners of the triangles filter accepts, in
 * ascending order, made where none is yet; the cache holds the reference each
 * acquisition takes (given back with the vertex table, in cache_destroy).
 * *accepted: how many triangles filter accepts (0: the mesh is not made). */
static lm_result hold_corners(cache *c, mesh_qmesh_root_filter filter, void *user, uint32_t *accepted, lm_error *err)
{
    *accepted = 0;
    for (uint32_t t = 0; t < c->s->tri_count; ++t) {
        if (!filter(c->s, t, user)) continue;
        ++*accepted;
        for (int k = 0; k < 3; ++k) {
            if (mesh_vtable_corner_id(c->vt, t, k) != MESH_VTABLE_NONE) continue;
            uint32_t id;
            lm_result r = mesh_vtable_acquire(c->vt, t, root_corner(k), &id, err);
            if (r != LM_OK) return r;
        }
    }
    return LM_OK;
}

/* Roots in m on the triangles that take part and that filter accepts and that
 * have none yet, in ascending order, their corners' ids from like where it has
 * roots. Nothing before the cache takes its first roots (c->rooted: a mesh made
 * at cache_create gets them with the others, add_roots_all). */
static lm_result roots_wanted(const cache *c, const mesh_qmesh *m, mesh_qmesh_root_filter filter, void *user,
                              uint32_t **list, uint32_t *n, lm_error *err)
{
    *n = 0;
    *list = malloc((c->s->tri_count ? c->s->tri_count : 1) * sizeof **list);
    if (!*list) return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory adding the cache's roots");
    for (uint32_t t = 0; t < c->s->tri_count; ++t) /* the filter last: sees_light loops over the light */
        if (cache_tri_active(c, t) && mesh_qmesh_root(m, t) == MESH_QMESH_NONE && filter(c->s, t, user))
            (*list)[(*n)++] = t;
    return LM_OK;
}

static lm_result roots_for_active(cache *c, mesh_qmesh *m, mesh_qmesh_root_filter filter, void *user,
                                  const mesh_qmesh *like, lm_error *err)
{
    if (!m || !c->rooted) return LM_OK;
    uint32_t *list = NULL, n = 0;
    lm_result r = roots_wanted(c, m, filter, user, &list, &n, err);
    if (r == LM_OK) r = mesh_qmesh_add_roots(m, list, n, like, err);
    free(list);
    return r;
}

/* One mesh's first roots, the vertex table only read (mesh_qmesh_add_roots_apart):
 * run on the worker thread and on a helper beside it (first_roots). */
typedef struct apart_job {
    const cache *c;        /* read by both threads */
    mesh_qmesh *m;         /* this job's thread's only (NULL: none) */
    mesh_qmesh_root_filter filter;
    void *user;
    uint32_t **corner_ids; /* non-NULL: then each scene corner's vertex id into it (the helper's) */
    lm_result r;           /* read after the join */
    lm_error err;
} apart_job;

static void *apart_main(void *arg)
{
    apart_job *j = arg;
    uint32_t *list = NULL, n = 0;
    j->r = j->m ? roots_wanted(j->c, j->m, j->filter, j->user, &list, &n, &j->err) : LM_OK;
    if (j->r == LM_OK && j->m) j->r = mesh_qmesh_add_roots_apart(j->m, list, n, &j->err);
    free(list);
    if (j->r == LM_OK && j->corner_ids) { /* the table only read, as the roots above */
        *j->corner_ids = cache_make_corner_ids(j->c);
        if (!*j->corner_ids) j->r = lm_fail(&j->err, LM_ERR_NO_MEMORY, "out of memory for the scene corners' vertex ids");
    }
    return NULL;
}

/* The cache's first roots (a million-triangle scene: 2.7 million roots in the
 * light, direct and indirect meshes, 0.3-0.39 s on one core, half of it the
 * first touch of their arrays): the indirect mesh's on a helper thread, the
 * light and direct meshes' on this one, the vertex table only read by both; the
 * references their new vertices owe it taken after the join. The meshes are
 * those mesh_qmesh_add_roots makes in turn (docs/cache.md, "The first roots on
 * two threads"). */
static lm_result first_roots(cache *c, lm_error *err)
{
    /* The helper also makes the corners' ids (desc.corner_ids): the indirect
     * mesh's roots alone end before the light and direct meshes' (a million
     * triangles: 3 million look-ups and 12 MB, 40-60 ms off the first image). */
    uint32_t *corner_ids = NULL;
    apart_job helper_job = {.c = c, .m = c->indirect, .filter = cache_has_albedo,
                            .corner_ids = c->desc.corner_ids ? &corner_ids : NULL, .r = LM_OK};
    pthread_t helper;
    const int wanted = c->indirect || helper_job.corner_ids;
    const int helped = wanted && pthread_create(&helper, NULL, apart_main, &helper_job) == 0;
    lm_result r = LM_OK;
    for (uint32_t l = 0; r == LM_OK && l <= c->light_count; ++l) {
        light_filter f = {c->s, l};
        apart_job job = l < c->light_count ? (apart_job){.c = c, .m = c->light[l], .filter = sees_light, .user = &f}
                                           : (apart_job){.c = c, .m = c->direct, .filter = cache_has_albedo};
        if (!job.m) continue;
        apart_main(&job);
        if ((r = job.r) != LM_OK) *err = job.err;
    }
    if (wanted && !helped) apart_main(&helper_job);
    if (helped) pthread_join(helper, NULL);
    free(c->corner_ids);
    c->corner_ids = corner_ids;
    if (r == LM_OK && helper_job.r != LM_OK) {
        *err = helper_job.err;
        r = helper_job.r;
    }
    /* Every owed reference taken, whatever failed: destroy then balances. */
    for (uint32_t l = 0; l < c->light_count; ++l) {
        lm_result rl = mesh_qmesh_take_references(c->light[l], err);
        if (r == LM_OK) r = rl;
    }
    lm_result rd = mesh_qmesh_take_references(c->direct, err), ri = mesh_qmesh_take_references(c->indirect, err);
    return r != LM_OK ? r : rd != LM_OK ? rd : ri;
}

/* The further bounces' coarse mesh (cache_bounces.c splits it). */
static lm_result make_bounce_mesh(cache *c, lm_error *err)
{
    lm_result r = mesh_qmesh_create(
        &(mesh_qmesh_desc){.vtable = c->vt, .channels = 3, .node_cap = c->desc.node_cap, .no_roots = 1}, &c->indirect1,
        err);
    return r == LM_OK ? roots_for_active(c, c->indirect1, cache_has_albedo, NULL, c->direct, err) : r;
}

/* Every mesh's roots on what takes part and has none yet, mesh by mesh in the
 * order cache_create made the meshes, each like the one its roots were copied
 * from when they were all made at once. */
static lm_result add_roots_all(cache *c, lm_error *err)
{
    const int first = !c->rooted;
    c->rooted = 1;
    const mesh_qmesh *like = NULL;
    lm_result r = first ? first_roots(c, err) : LM_OK; /* the light, direct and indirect meshes' */
    for (uint32_t l = 0; r == LM_OK && !first && l < c->light_count; ++l) {
        if (!c->light[l]) continue;
        light_filter f = {c->s, l};
        r = roots_for_active(c, c->light[l], sees_light, &f, like, err);
        if (!like) like = c->light[l];
    }
    if (r == LM_OK && !first) r = roots_for_active(c, c->direct, cache_has_albedo, NULL, like, err);
    if (r == LM_OK && !first) r = roots_for_active(c, c->indirect, cache_has_albedo, NULL, c->direct, err);
    if (r == LM_OK) r = roots_for_active(c, c->indirect1, cache_has_albedo, NULL, c->direct, err);
    if (r == LM_OK) r = roots_for_active(c, c->specular, has_gloss, NULL, c->direct, err);
    return r;
}

lm_result cache_create(const cache_desc *desc, cache **out, lm_error *err)
{
    *out = NULL;
    if (!desc || !desc->scene || !desc->sampler) return lm_fail(err, LM_ERR_INVALID_ARG, "cache: needs a scene and a sampler");
    if (desc->bounces < CACHE_BOUNCES_AUTO || desc->bounces > CACHE_BOUNCES_MAX)
        return lm_fail(err, LM_ERR_INVALID_ARG, "cache: bounces must be 1..%d or auto, not %d", CACHE_BOUNCES_MAX,
                       desc->bounces);
    uint32_t rays = desc->bounce_rays ? desc->bounce_rays : CACHE_BOUNCE_RAYS_DEFAULT;
    uint32_t side = (uint32_t)floor(sqrt((double)rays));
    if (rays > 4096 || side * side != rays)
        return lm_fail(err, LM_ERR_INVALID_ARG, "cache: bounce_rays must be a square up to 4096, not %u", rays);
    if ((unsigned)desc->glossy >= CACHE_GLOSSY_COUNT)
        return lm_fail(err, LM_ERR_INVALID_ARG, "cache: unknown glossy mode %d", (int)desc->glossy);
    if (!(desc->jnd >= 0.0f) || !(desc->min_leaf_pixels >= 0.0f) || (unsigned)desc->scheduler >= CACHE_SCHED_COUNT)
        return lm_fail(err, LM_ERR_INVALID_ARG, "cache: the JND and leaf size must be non-negative");
    if (!(desc->sample_pixels >= 0.0f && desc->sample_pixels <= 1.0f))
        return lm_fail(err, LM_ERR_INVALID_ARG, "cache: sample_pixels (a sample's area in pixels) must be 0..1, not %g",
                       (double)desc->sample_pixels);
    const double t_create = lm_now_seconds();
    cache *c = calloc(1, sizeof *c);
    if (!c) return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory creating the cache");
    c->desc = *desc;
    if (c->desc.jnd == 0.0f) c->desc.jnd = 2.0f;
    if (c->desc.bounces == 0) c->desc.bounces = 1;
    c->desc.bounce_rays = rays;
    if (c->desc.min_leaf_pixels == 0.0f) c->desc.min_leaf_pixels = 16.0f;
    if (c->desc.sample_pixels == 0.0f) c->desc.sample_pixels = 1.0f;
    c->s = desc->scene;
    c->sp = desc->sampler;
    cache_sched_init(&c->sched, desc->seed);
    c->tm.exposure = c->s->exposure + desc->exposure_offset;
    c->light_count = scene_light_count(c->s);
    lm_result r = mesh_vtable_create(&(mesh_vtable_desc){.scene = c->s}, &c->vt, err);
    c->light = calloc(c->light_count ? c->light_count : 1, sizeof *c->light);
    int vis_ok = cache_light_state_init(&c->vis, c->light_count);
    c->light_le = calloc(3 * (size_t)(c->light_count ? c->light_count : 1), sizeof *c->light_le);
    if (r == LM_OK && (!c->light || !vis_ok || !c->light_le))
        r = lm_fail(err, LM_ERR_NO_MEMORY, "out of memory creating the cache");
    for (uint32_t l = 0; r == LM_OK && l < c->light_count; ++l)
        memcpy(c->light_le + 3 * (size_t)l, light_radiance(c->s, l), 3 * sizeof(float));
    uint32_t cap = desc->node_cap;
    /* The meshes start with no roots: each triangle gets its roots when it comes
     * to take part (add_roots_all). A light nothing can see gets no mesh, a
     * scene without gloss no specular mesh. */
    const mesh_qmesh_desc empty = {.vtable = c->vt, .channels = 3, .node_cap = cap, .no_roots = 1};
    uint32_t accepted = 0;
    for (uint32_t l = 0; r == LM_OK && l < c->light_count; ++l) {
        light_filter f = {c->s, l};
        r = hold_corners(c, sees_light, &f, &accepted, err);
        if (r == LM_OK && accepted)
            r = mesh_qmesh_create(&(mesh_qmesh_desc){.vtable = c->vt, .channels = 1, .node_cap = cap, .no_roots = 1},
                                  &c->light[l], err);
    }
    if (r == LM_OK) r = hold_corners(c, cache_has_albedo, NULL, &accepted, err);
    if (r == LM_OK) r = mesh_qmesh_create(&empty, &c->direct, err);
    if (r == LM_OK) r = mesh_qmesh_create(&empty, &c->indirect, err);
    if (r == LM_OK && c->desc.bounces != 1) r = make_bounce_mesh(c, err);
    uint32_t glossy = 0;
    if (r == LM_OK) r = hold_corners(c, has_gloss, NULL, &glossy, err);
    if (r == LM_OK && glossy) r = mesh_qmesh_create(&empty, &c->specular, err); /* no gloss, no mesh */
    if (r == LM_OK && glossy && !cache_build_outlines(&c->outl, c->s, c->light_count)) r = lm_fail(err, LM_ERR_NO_MEMORY, "out of memory creating the cache");
    if (desc->eye_set && !(isfinite(desc->eye[0]) && isfinite(desc->eye[1]) && isfinite(desc->eye[2])))
        r = lm_fail(err, LM_ERR_INVALID_ARG, "cache_create: the eye must be a finite point");
    if (desc->eye_set)
        memcpy(c->eye, desc->eye, sizeof c->eye);
    else if (c->s->camera_count)
        memcpy(c->eye, c->s->cameras[0].position, sizeof c->eye);
    if (r != LM_OK) {
        cache_destroy(c);
        return r;
    }
    c->startup.create_seconds = lm_now_seconds() - t_create;
    *out = c;
    return LM_OK;
}

/* The distinct corner vertices of the roots of m over triangles tris[0..ntris)
 * (NULL: every active triangle) that have no value yet. */
static lm_result root_vertices(const cache *c, const mesh_qmesh *m, const uint32_t *tris, uint32_t ntris, uint32_t **out,
                               uint32_t *n, lm_error *err)
{
    const scene *s = c->s;
    const uint32_t count = tris ? ntris : s->tri_count;
    uint8_t *seen = NULL;
    uint32_t *v = malloc(3 * (size_t)(count ? count : 1) * sizeof *v), cnt = 0;
    const uint32_t limit = mesh_vtable_id_limit(c->vt);
    seen = calloc(limit ? limit : 1, 1);
    if (!v || !seen) {
        free(v);
        free(seen);
        return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory initialising the cache");
    }
    for (uint32_t i = 0; i < count; ++i) {
        uint32_t t = tris ? tris[i] : i;
        if (!tris && !cache_tri_active(c, t)) continue;
        uint32_t root = mesh_qmesh_root(m, t);
        if (root == MESH_QMESH_NONE) continue;
        const mesh_qnode *nd = mesh_qmesh_node(m, root);
        for (int k = 0; k < 3; ++k)
            if (nd->v[k] < limit && !seen[nd->v[k]]) {
                seen[nd->v[k]] = 1;
                if (mesh_qmesh_get_value(m, nd->v[k], NULL) != 1) v[cnt++] = nd->v[k];
            }
    }
    free(seen);
    *out = v;
    *n = cnt;
    return LM_OK;
}

/* The root corners of the direct or specular mesh over tris (NULL: every active
 * triangle), their values from the light meshes (visible fractions; samples only
 * where those cannot answer). */
static lm_result sample_roots(cache *c, cache_kind kind, const uint32_t *tris, uint32_t ntris, lm_error *err)
{
    uint32_t *v = NULL, n = 0;
    lm_result r = root_vertices(c, cache_kind_mesh(c, kind), tris, ntris, &v, &n, err);
    if (r == LM_OK) r = cache_root_values(c, kind, v, n, err);
    free(v);
    return r;
}

lm_result cache_set_camera(cache *c, const float eye[3], lm_error *err)
{
    if (!c || !eye || !isfinite(eye[0]) || !isfinite(eye[1]) || !isfinite(eye[2]))
        return lm_fail(err, LM_ERR_INVALID_ARG, "cache_set_camera: the eye must be a finite point");
    memcpy(c->eye, eye, sizeof c->eye);
    if (!c->specular) return LM_OK; /* nothing depends on the view */
    uint32_t cap = c->desc.node_cap;
    mesh_qmesh_destroy(c->specular);
    c->specular = NULL;
    lm_result r = mesh_qmesh_create(
        &(mesh_qmesh_desc){.vtable = c->vt, .channels = 3, .node_cap = cap, .no_roots = 1}, &c->specular, err);
    if (r == LM_OK) r = roots_for_active(c, c->specular, has_gloss, NULL, c->direct, err);
    /* Every glossy part was gathered for the old eye (its vertex ids live on in the
     * vertex table): stale, before the new roots get theirs. */
    if (r == LM_OK) cache_glossy_outdate(c);
    if (r == LM_OK && c->initialised) r = sample_roots(c, CACHE_KIND_SPECULAR, NULL, 0, err);
    cache_sched_requeue(&c->sched, CACHE_KIND_SPECULAR);
    cache_sched_forget(&c->sched, CACHE_KIND_SPECULAR);
    return r;
}

/* Adds the time since *t to *spent when timed; *t becomes now. */
static void lap(double *spent, int timed, double *t)
{
    double now = lm_now_seconds();
    if (timed) *spent += now - *t;
    *t = now;
}

/* The coarse cache over triangles tris[0..ntris) (NULL: every active one): the
 * root corners of the light meshes, then of the direct and specular meshes (from
 * the light meshes), the further bounces' transport over what is active, the
 * source (kd·L_dd over a cut of the direct mesh; after the first time its change
 * flags the values it moved), and gathers at the indirect mesh's root corners
 * (§5). Corners that have a value already are not sampled again. */
static lm_result sample_coarse(cache *c, const uint32_t *tris, uint32_t ntris, lm_error *err)
{
    uint32_t *v = NULL, n = 0;
    lm_result r = LM_OK;
    /* The first time, where the time goes (cache_stats.startup). */
    const int timed = !c->initialised;
    double t = lm_now_seconds();
    /* The first image from a budget of light samples (cache_first.c): the
     * direct and specular roots get values, most of them borrowed. */
    int light_done = 0;
    if (!tris && !c->initialised && c->desc.coarse_lights) {
        r = root_vertices(c, c->direct, NULL, 0, &v, &n, err);
        if (r == LM_OK) r = cache_first_light(c, v, n, &light_done, err);
        free(v);
        v = NULL;
    }
    for (uint32_t l = 0; r == LM_OK && !light_done && l < c->light_count; ++l) {
        if (!c->light[l]) continue;
        r = root_vertices(c, c->light[l], tris, ntris, &v, &n, err);
        if (r == LM_OK) r = cache_sample_light(c, l, v, n, err);
        free(v);
        v = NULL;
    }
    lap(&c->startup.light_seconds, timed, &t);
    if (r == LM_OK) r = sample_roots(c, CACHE_KIND_DIRECT, tris, ntris, err);
    if (r == LM_OK && c->specular) r = sample_roots(c, CACHE_KIND_SPECULAR, tris, ntris, err);
    lap(&c->startup.values_seconds, timed, &t);
    /* Further bounces through E_m in the source, from a transport traced here
     * (cache_bounces.c) over the triangles that take part: traced again when an
     * eighth more take part (until then the newer ones get no E_m). */
    if (r == LM_OK && c->indirect1 && c->initialised && c->active_count > c->bounce_active_at + c->bounce_active_at / 8) {
        mesh_qmesh_destroy(c->indirect1); /* traced again once an eighth more takes part */
        c->indirect1 = NULL;
        cache_bounces_free(&c->bnc);
        r = make_bounce_mesh(c, err);
    }
    if (r == LM_OK && c->indirect1 && !c->bnc.hit_first) {
        r = cache_bounces_init(c, err);
        c->bounce_active_at = c->active_count;
    }
    if (r == LM_OK) r = cache_update_radiance_source(c, 1, err);
    lap(&c->startup.source_seconds, timed, &t);
    if (r == LM_OK) r = root_vertices(c, c->indirect, tris, ntris, &v, &n, err);
    float *E = r == LM_OK ? malloc(3 * (size_t)(n ? n : 1) * sizeof *E) : NULL;
    if (r == LM_OK && !E) r = lm_fail(err, LM_ERR_NO_MEMORY, "out of memory initialising the cache");
    if (r == LM_OK) r = cache_first_gathers(c, v, n, E, err);
    for (uint32_t i = 0; r == LM_OK && i < n; ++i) r = mesh_qmesh_set_value(c->indirect, v[i], E + 3 * (size_t)i, err);
    free(E);
    free(v);
    lap(&c->startup.gather_seconds, timed, &t);
    return r;
}

lm_result cache_init(cache *c, lm_error *err) { return cache_init_seen(c, NULL, err); }

/* ---- what takes part: seen triangles and what their gathers reach ------------ */

/* The triangles with pixels that do not take part yet: taken, with what they reach. */
static lm_result take_seen(cache *c, const uint32_t *pixels, uint32_t **out, uint32_t *nout, lm_error *err)
{
    *out = NULL;
    *nout = 0;
    uint32_t *seed = NULL, ns = 0;
    size_t cap = 0;
    for (uint32_t t = 0; t < c->s->tri_count; ++t) {
        if (!pixels[t] || c->active[t]) continue;
        if (!LM_GROW(seed, cap, (size_t)ns + 1)) {
            free(seed);
            return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory finding what is seen");
        }
        seed[ns++] = t;
    }
    lm_result r = ns ? cache_reach_take(c, seed, ns, out, nout, err) : LM_OK;
    free(seed);
    return r;
}

lm_result cache_init_seen(cache *c, const uint32_t *pixels, lm_error *err)
{
    if (!c) return lm_fail(err, LM_ERR_INVALID_ARG, "cache_init_seen: no cache");
    if (c->initialised) return LM_OK;
    uint32_t *tris = NULL, n = 0;
    lm_result r = LM_OK;
    const double t0 = lm_now_seconds();
    if (pixels) {
        c->active = calloc(c->s->tri_count ? c->s->tri_count : 1, 1);
        c->active_count = 0;
        r = c->active ? take_seen(c, pixels, &tris, &n, err) : lm_fail(err, LM_ERR_NO_MEMORY, "out of memory initialising the cache");
        free(tris); /* sample_coarse takes every active triangle */
    } else {
        c->active_count = c->s->tri_count;
    }
    if (r == LM_OK) r = add_roots_all(c, err); /* what takes part gets its roots */
    c->startup.reach_seconds = lm_now_seconds() - t0;
    c->first_pixels = pixels; /* the first image's gathers follow them (gather_roots) */
    if (r == LM_OK) r = sample_coarse(c, NULL, 0, err);
    c->first_pixels = NULL;
    if (r == LM_OK) c->initialised = 1;
    for (uint32_t l = 0; l < c->light_count; ++l) c->startup.light_samples += c->vis.light_stats[l].samples;
    c->startup.gathers = c->src.indirect_stats.samples;
    return r;
}

/* Triangles that did not take part and now must: those a camera move shows
 * (pixels), and those the gathers made since the last call reach. Taken with
 * what they reach, sampled, and every mesh's leaves scheduled again. */
static lm_result take_newly_needed(cache *c, const uint32_t *pixels, lm_error *err)
{
    /* Every refine call comes here: once every triangle takes part (most
     * scenes, right away) it costs nothing, not a pass over a million pixels. */
    if (!c->active || c->active_count == c->s->tri_count) return LM_OK;
    uint32_t *tris = NULL, n = 0;
    lm_result r = pixels ? take_seen(c, pixels, &tris, &n, err) : LM_OK;
    if (r == LM_OK && !n) {
        free(tris);
        tris = NULL;
        r = cache_reach_from_gathers(c, &tris, &n, err);
    }
    if (r == LM_OK && n) {
        r = add_roots_all(c, err);
        if (r == LM_OK) r = sample_coarse(c, tris, n, err);
        cache_sched_requeue(&c->sched, CACHE_KINDS);
    }
    free(tris);
    return r;
}

/* ---- evaluation and statistics ------------------------------------------------- */

lm_result cache_eval_direct(const cache *c, uint32_t tri, double w1, double w2, float rgb[3], lm_error *err)
{
    return mesh_qmesh_interpolate(c->direct, tri, w1, w2, rgb, err);
}

lm_result cache_eval_indirect(const cache *c, uint32_t tri, double w1, double w2, float rgb[3], lm_error *err)
{
    return mesh_qmesh_interpolate(c->indirect, tri, w1, w2, rgb, err);
}

lm_result cache_eval_specular(const cache *c, uint32_t tri, double w1, double w2, float rgb[3], lm_error *err)
{
    rgb[0] = rgb[1] = rgb[2] = 0.0f;
    if (!c->specular || mesh_qmesh_root(c->specular, tri) == MESH_QMESH_NONE) return LM_OK;
    return mesh_qmesh_interpolate(c->specular, tri, w1, w2, rgb, err);
}

lm_result cache_eval_G(const cache *c, uint32_t light, uint32_t tri, double w1, double w2, double *G, lm_error *err)
{
    *G = 0.0;
    if (light >= c->light_count) return lm_fail(err, LM_ERR_INVALID_ARG, "cache: light %u does not exist", light);
    const mesh_qmesh *m = c->light[light];
    if (!m || mesh_qmesh_root(m, tri) == MESH_QMESH_NONE) return LM_OK;
    float V;
    lm_result r = mesh_qmesh_interpolate(m, tri, w1, w2, &V, err);
    if (r != LM_OK) return r;
    const scene *s = c->s;
    const uint32_t *tv = s->tris[tri].v;
    float p[3], n[3];
    for (int k = 0; k < 3; ++k) { /* (float, like a vertex of the vtable) */
        p[k] = (float)((1.0 - w1 - w2) * s->positions[3 * (size_t)tv[0] + (size_t)k] +
                       w1 * s->positions[3 * (size_t)tv[1] + (size_t)k] + w2 * s->positions[3 * (size_t)tv[2] + (size_t)k]);
        const float *cn = s->corner_normals + 9 * (size_t)tri;
        n[k] = (float)((1.0 - w1 - w2) * cn[k] + w1 * cn[3 + k] + w2 * cn[6 + k]);
    }
    lm_vec3 nn = v3_normalize(v3_load(n));
    v3_store(n, nn);
    *G = V * cache_unoccluded_at(s, light, p, n);
    return LM_OK;
}

void cache_get_stats(cache *c, cache_stats *out)
{
    memset(out, 0, sizeof *out);
    out->light_count = c->light_count;
    out->direct = c->vis.direct_stats;
    out->indirect = c->src.indirect_stats;
    out->specular = c->vis.specular_stats;
    mesh_qmesh_get_stats(c->direct, &out->direct.mesh);
    mesh_qmesh_get_stats(c->indirect, &out->indirect.mesh);
    if (c->specular) mesh_qmesh_get_stats(c->specular, &out->specular.mesh);
    out->direct.yield = cache_sched_yield(c, CACHE_KIND_DIRECT);
    out->indirect.yield = cache_sched_yield(c, CACHE_KIND_INDIRECT);
    out->specular.yield = c->specular ? cache_sched_yield(c, CACHE_KIND_SPECULAR) : 0.0;
    out->bytes = out->direct.mesh.bytes + out->indirect.mesh.bytes + out->specular.mesh.bytes;
    cache_mesh_stats *ls = c->vis.light_stats;
    for (uint32_t l = 0; l < c->light_count; ++l) {
        if (c->light[l]) mesh_qmesh_get_stats(c->light[l], &ls[l].mesh);
        out->bytes += ls[l].mesh.bytes;
    }
    out->lights = ls;
    out->undone = c->sched.undone;
    out->falsified = c->vis.falsified_total;
    out->revised = c->vis.revised;
    out->regathered = c->src.regathered;
    out->drift_probed = c->src.probed;
    out->drift_cleared = c->src.probe_cleared;
    out->drift_probe_rays = c->src.probe_rays;
    out->toward_gathers = c->src.toward_gathers;
    out->glossy_gathers = c->gls.samples;
    out->glossy_refreshed = c->gls.refreshed;
    out->glossy_rays = c->gls.rays;
    if (c->indirect1) {
        out->bounces = c->bnc.stats;
        mesh_qmesh_stats ms;
        mesh_qmesh_get_stats(c->indirect1, &ms);
        out->bytes += c->bnc.bytes + ms.bytes;
    } else {
        out->bounces.bounces = 1;
        snprintf(out->bounces.why, sizeof out->bounces.why, "1 bounce, as asked");
    }
    out->active_triangles = c->active_count;
    out->reach_rays = c->reach_rays;
    out->startup = c->startup;
    mesh_vtable_stats vs;
    mesh_vtable_get_stats(c->vt, &vs);
    out->bytes += vs.bytes + cache_light_state_bytes(&c->vis, c->light_count) + c->outl.bytes +
                  cache_source_bytes(&c->src) + cache_sched_bytes(&c->sched) + cache_borrow_bytes(&c->brw) +
                  cache_glossy_bytes(&c->gls);
    out->borrow = c->brw.stats;
}

const mesh_qmesh *cache_direct_mesh(const cache *c) { return c->direct; }
const mesh_qmesh *cache_indirect_mesh(const cache *c) { return c->indirect; }
const mesh_qmesh *cache_specular_mesh(const cache *c) { return c->specular; }

void cache_get_light_radiance(const cache *c, uint32_t light, float out[3])
{
    if (light < c->light_count) memcpy(out, c->light_le + 3 * (size_t)light, 3 * sizeof *out);
    else memset(out, 0, 3 * sizeof *out);
}
uint32_t *cache_make_corner_ids(const cache *c)
{
    const uint32_t nt = c->s->tri_count;
    uint32_t *ids = malloc(3 * (size_t)(nt ? nt : 1) * sizeof *ids);
    for (uint32_t t = 0; ids && t < nt; ++t)
        for (int k = 0; k < 3; ++k) ids[3 * (size_t)t + (size_t)k] = mesh_vtable_corner_id(c->vt, t, k);
    return ids;
}

uint32_t *cache_take_corner_ids(cache *c)
{
    uint32_t *ids = c ? c->corner_ids : NULL;
    if (c) c->corner_ids = NULL;
    return ids;
}

const mesh_vtable *cache_vtable(const cache *c) { return c->vt; }
const mesh_qmesh *cache_light_mesh(const cache *c, uint32_t light)
{
    return light < c->light_count ? c->light[light] : NULL;
}

/* ---- the worker's quick start and view changes ------------------------------------ */

void cache_set_sampler(cache *c, samp_sampler *sp) { c->sp = sp; }

/* Every indirect value gathered again: now, or, after the first image's budget
 * of gathers (coarse_gathers, the worker's quick start), by cache_refine, a
 * bounded number a call (cache_outdate_gathered): on a big scene that is
 * thousands of gathers, and the worker must stay able to stop, publish and meet
 * a time limit meanwhile. The first image's borrowed values are tested there
 * instead of gathered (cache_borrow.c). From then on every corner is gathered. */
static lm_result regather_every_value(cache *c, lm_error *err)
{
    cache_release_borrowed(c); /* the first image's borrowed direct values too (cache_first.c) */
    c->desc.coarse_lights = 0;
    if (!c->desc.coarse_gathers) {
        cache_borrow_free(&c->brw); /* every value gathered: nothing is borrowed */
        return cache_regather_all(c, err);
    }
    c->desc.coarse_gathers = 0;
    cache_borrow_release(c);
    c->sched.owed_wait = 1; /* until a window of direct leaves has shown the source settled (cache_refine.c) */
    c->sched.owed_tested = 0;
    return cache_outdate_gathered(c, err);
}

lm_result cache_regather_indirect(cache *c, lm_error *err)
{
    if (!c->initialised) return lm_fail(err, LM_ERR_INVALID_ARG, "cache_regather_indirect: cache_init first");
    lm_result r = regather_every_value(c, err);
    cache_sched_requeue(&c->sched, CACHE_KINDS);
    return r;
}

lm_result cache_set_bounces(cache *c, int bounces, lm_error *err)
{
    if (!c || bounces < CACHE_BOUNCES_AUTO || bounces > CACHE_BOUNCES_MAX || bounces == 0)
        return lm_fail(err, LM_ERR_INVALID_ARG, "cache_set_bounces: 1..%d or auto, not %d", CACHE_BOUNCES_MAX, bounces);
    if (bounces == c->desc.bounces) return LM_OK;
    c->desc.bounces = bounces;
    lm_result r = LM_OK;
    if (bounces == 1) {
        mesh_qmesh_destroy(c->indirect1);
        c->indirect1 = NULL;
        cache_bounces_free(&c->bnc);
    } else if (!c->indirect1) {
        r = make_bounce_mesh(c, err);
        if (r == LM_OK && c->initialised) r = cache_bounces_init(c, err);
    }
    cache_bounces_touch(c);
    if (r == LM_OK && c->initialised) r = regather_every_value(c, err);
    cache_sched_requeue(&c->sched, CACHE_KINDS);
    return r;
}

lm_result cache_requeue(cache *c, lm_error *err)
{
    (void)err;
    cache_sched_requeue(&c->sched, CACHE_KINDS);
    return LM_OK;
}

lm_result cache_set_jnd(cache *c, float jnd, lm_error *err)
{
    if (!c || !(jnd > 0.0f) || !isfinite(jnd))
        return lm_fail(err, LM_ERR_INVALID_ARG, "cache_set_jnd: the JND must be a positive ΔE, not %g", (double)jnd);
    if (jnd == c->desc.jnd) return LM_OK;
    c->desc.jnd = jnd;
    cache_sched_requeue(&c->sched, CACHE_KINDS);
    return cache_borrow_retest(c, c->desc.jnd, err);
}

float cache_get_jnd(const cache *c) { return c->desc.jnd; }

lm_result cache_set_exposure(cache *c, float exposure, lm_error *err)
{
    if (!c || !isfinite(exposure) || fabsf(exposure) > 64.0f)
        return lm_fail(err, LM_ERR_INVALID_ARG, "cache_set_exposure: the exposure must be stops in [-64, 64], not %g",
                       (double)exposure);
    const float tm_exposure = exposure + c->desc.exposure_offset;
    if (tm_exposure == c->tm.exposure) return LM_OK;
    c->tm.exposure = tm_exposure;
    /* The ΔE kept from earlier tests (each leaf's, each borrowed span's) were of
     * the old colours: forgotten, and every leaf and span tested again. The
     * importance of the source's nodes (ΔE per unit radiance, recorded by the
     * gathers) is kept as a guide: the next gathers record it anew. */
    for (int k = 0; k < CACHE_KINDS; ++k) cache_sched_forget(&c->sched, (cache_kind)k);
    cache_sched_requeue(&c->sched, CACHE_KINDS);
    cache_bounces_touch(c); /* auto: the bounce count is judged at the new exposure */
    return cache_borrow_retest(c, -1.0f, err);
}

float cache_get_exposure(const cache *c) { return c->tm.exposure - c->desc.exposure_offset; }

/* ---- refinement (cache_refine.c) ------------------------------------------------ */

lm_result cache_refine(cache *c, const cache_refine_desc *desc, cache_refine_result *out, lm_error *err)
{
    if (!c || !desc) return lm_fail(err, LM_ERR_INVALID_ARG, "cache_refine: missing arguments");
    /* The coarse cache first, here: the scheduler is below this file and cannot ask for it. */
    lm_result r = c->initialised ? take_newly_needed(c, desc->pixels, err) : cache_init_seen(c, desc->pixels, err);
    if (r == LM_OK) cache_bounces_see(c, desc->pixels);
    if (r == LM_OK) {
        c->stop = desc->stop;
        c->pixels = desc->pixels;
        r = cache_sched_refine(c, desc, out, err);
        c->stop = NULL;
        c->pixels = NULL;
        return r;
    }
    if (out) *out = (cache_refine_result){0};
    return r;
}
