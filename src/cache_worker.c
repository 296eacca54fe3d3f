/* cache_worker.c — the refinement worker and its publication (cache_worker.h). */
#define _POSIX_C_SOURCE 200809L /* pthread_cond_timedwait, clock_gettime */
#include "cache_worker.h"

#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

enum { MAX_EDITS = 64 };

typedef struct light_edit {
    uint32_t light;
    float value[3];
} light_edit;

/* Buffers behind one snapshot; owned by whichever side holds the slot. */
typedef struct snapshot_store {
    cache_snapshot snap;
    cache_snapshot_vertex *verts[3];  /* direct, indirect, specular */
    uint32_t *tris[3];
    size_t cap[3];                    /* triangles */
    cache_mesh_stats *lights;
    size_t lights_cap;
} snapshot_store;

struct cache_worker {
    cache_worker_desc desc;           /* immutable after create */
    const scene *s;
    uint32_t *pixels;                 /* owned copy; read by the worker only */
    pthread_t thread;
    int started;

    pthread_mutex_t lock;             /* guards every field below */
    pthread_cond_t cond;              /* signalled on any change of them */
    int cancel, paused, parked, finished;
    snapshot_store *front, *ready, *back; /* display's / latest committed / worker's own */
    int ready_new;
    light_edit edits[MAX_EDITS];
    uint32_t edit_count;
};

/* ---- snapshots (worker side) ---------------------------------------------------- */

static lm_result fill_mesh(snapshot_store *st, int which, const cache *c, const mesh_qmesh *m,
                           mesh_qmesh_tri **buf, size_t *buf_cap, lm_error *err)
{
    size_t count = 0;
    lm_result r = mesh_qmesh_leaf_triangles(m, buf, buf_cap, &count, err);
    if (r != LM_OK) return r;
    if (count > st->cap[which]) {
        cache_snapshot_vertex *v = realloc(st->verts[which], 3 * count * sizeof *v);
        uint32_t *t = v ? realloc(st->tris[which], count * sizeof *t) : NULL;
        if (v) st->verts[which] = v;
        if (t) st->tris[which] = t;
        if (!v || !t) return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory publishing the cache");
        st->cap[which] = count;
    }
    const mesh_vtable *vt = cache_vtable(c);
    for (size_t i = 0; i < count; ++i) {
        st->tris[which][i] = (*buf)[i].tri;
        for (int k = 0; k < 3; ++k) {
            cache_snapshot_vertex *out = &st->verts[which][3 * i + (size_t)k];
            memcpy(out->position, mesh_vtable_vertex(vt, (*buf)[i].v[k])->position, sizeof out->position);
            if (mesh_qmesh_get_value(m, (*buf)[i].v[k], out->value) < 0) memset(out->value, 0, sizeof out->value);
        }
    }
    cache_snapshot_mesh *sm = which == 0 ? &st->snap.direct : which == 1 ? &st->snap.indirect : &st->snap.specular;
    *sm = (cache_snapshot_mesh){.vertices = st->verts[which], .tri = st->tris[which], .triangle_count = (uint32_t)count};
    return LM_OK;
}

static lm_result fill_snapshot(snapshot_store *st, cache *c, uint64_t generation, uint64_t tested, int converged,
                               mesh_qmesh_tri **buf, size_t *buf_cap, lm_error *err)
{
    lm_result r = fill_mesh(st, 0, c, cache_direct_mesh(c), buf, buf_cap, err);
    if (r == LM_OK) r = fill_mesh(st, 1, c, cache_indirect_mesh(c), buf, buf_cap, err);
    if (r == LM_OK && cache_specular_mesh(c)) r = fill_mesh(st, 2, c, cache_specular_mesh(c), buf, buf_cap, err);
    if (!cache_specular_mesh(c)) st->snap.specular = (cache_snapshot_mesh){0};
    if (r != LM_OK) return r;
    cache_get_stats(c, &st->snap.stats);
    if (st->snap.stats.light_count > st->lights_cap) {
        cache_mesh_stats *l = realloc(st->lights, st->snap.stats.light_count * sizeof *l);
        if (!l) return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory publishing the cache");
        st->lights = l;
        st->lights_cap = st->snap.stats.light_count;
    }
    if (st->snap.stats.light_count)
        memcpy(st->lights, st->snap.stats.lights, st->snap.stats.light_count * sizeof *st->lights);
    st->snap.stats.lights = st->lights;
    st->snap.generation = generation;
    st->snap.tested = tested;
    st->snap.converged = converged;
    st->snap.failed = 0;
    st->snap.error[0] = 0;
    return LM_OK;
}

/* Commits the worker's snapshot: a pointer swap under the lock. */
static void commit(cache_worker *w)
{
    pthread_mutex_lock(&w->lock);
    snapshot_store *t = w->ready;
    w->ready = w->back;
    w->back = t;
    w->ready_new = 1;
    pthread_cond_broadcast(&w->cond);
    pthread_mutex_unlock(&w->lock);
}

static void publish_failure(cache_worker *w, uint64_t generation, const char *msg)
{
    w->back->snap.generation = generation;
    w->back->snap.failed = 1;
    lm_strlcpy(w->back->snap.error, msg, sizeof w->back->snap.error);
    commit(w);
}

/* ---- the worker thread ---------------------------------------------------------- */

static void *worker_main(void *arg)
{
    cache_worker *w = arg;
    lm_error err = {{0}};
    samp_sampler *sp = NULL;
    cache *c = NULL;
    mesh_qmesh_tri *buf = NULL;
    size_t buf_cap = 0;
    uint64_t generation = 0, tested = 0;
    samp_desc sd = w->desc.sampler;
    sd.scene = w->s;
    /* The sampler (and a GL context, if any) is made here: it belongs to this thread. */
    lm_result r = samp_create(&sd, &sp, &err);
    if (r == LM_OK) {
        cache_desc cd = w->desc.cache;
        cd.scene = w->s;
        cd.sampler = sp;
        r = cache_create(&cd, &c, &err);
    }
    if (r == LM_OK) r = cache_init(c, &err);
    if (r == LM_OK) r = fill_snapshot(w->back, c, ++generation, 0, 0, &buf, &buf_cap, &err);
    if (r == LM_OK) commit(w);
    int converged = 0;
    while (r == LM_OK) {
        light_edit edits[MAX_EDITS];
        uint32_t nedit = 0;
        pthread_mutex_lock(&w->lock);
        for (;;) {
            if (w->cancel) break;
            nedit = w->edit_count;
            if (w->paused || (converged && nedit == 0)) {
                w->parked = 1;
                pthread_cond_broadcast(&w->cond);
                if (w->paused) {
                    pthread_cond_wait(&w->cond, &w->lock);
                } else { /* idle: wake now and then; edits and cancel signal too */
                    struct timespec until;
                    clock_gettime(CLOCK_REALTIME, &until);
                    until.tv_nsec += 50000000;
                    if (until.tv_nsec >= 1000000000) {
                        until.tv_sec++;
                        until.tv_nsec -= 1000000000;
                    }
                    pthread_cond_timedwait(&w->cond, &w->lock, &until);
                }
                w->parked = 0;
                continue;
            }
            break;
        }
        int cancel = w->cancel;
        if (!cancel && nedit) {
            memcpy(edits, w->edits, nedit * sizeof *edits);
            w->edit_count = 0;
        }
        pthread_mutex_unlock(&w->lock);
        if (cancel) break;
        for (uint32_t i = 0; r == LM_OK && i < nedit; ++i) r = cache_set_light(c, edits[i].light, edits[i].value, &err);
        if (r != LM_OK) break;
        if (nedit) converged = 0;
        cache_refine_result res = {0};
        uint32_t budget = w->desc.step_budget ? w->desc.step_budget : 512;
        if (w->desc.max_tested && tested + budget > w->desc.max_tested) budget = (uint32_t)(w->desc.max_tested - tested);
        if (budget) r = cache_refine(c, &(cache_refine_desc){.pixels = w->pixels, .budget = budget}, &res, &err);
        if (r != LM_OK) break;
        tested += res.tested;
        converged = res.remaining == 0 || (w->desc.max_tested && tested >= w->desc.max_tested);
        r = fill_snapshot(w->back, c, ++generation, tested, converged, &buf, &buf_cap, &err);
        if (r == LM_OK) commit(w);
    }
    if (r != LM_OK) publish_failure(w, ++generation, err.msg);
    free(buf);
    cache_destroy(c);
    samp_destroy(sp);
    pthread_mutex_lock(&w->lock);
    w->finished = 1;
    pthread_cond_broadcast(&w->cond);
    pthread_mutex_unlock(&w->lock);
    return NULL;
}

/* ---- display side ------------------------------------------------------------------ */

static void store_free(snapshot_store *st)
{
    if (!st) return;
    for (int k = 0; k < 3; ++k) {
        free(st->verts[k]);
        free(st->tris[k]);
    }
    free(st->lights);
    free(st);
}

void cache_worker_destroy(cache_worker *w)
{
    if (!w) return;
    if (w->started) {
        pthread_mutex_lock(&w->lock);
        w->cancel = 1;
        pthread_cond_broadcast(&w->cond);
        pthread_mutex_unlock(&w->lock);
        pthread_join(w->thread, NULL);
        pthread_mutex_destroy(&w->lock);
        pthread_cond_destroy(&w->cond);
    }
    store_free(w->front);
    store_free(w->ready);
    store_free(w->back);
    free(w->pixels);
    free(w);
}

lm_result cache_worker_create(const cache_worker_desc *desc, cache_worker **out, lm_error *err)
{
    *out = NULL;
    if (!desc || !desc->scene) return lm_fail(err, LM_ERR_INVALID_ARG, "cache_worker: needs a scene");
    cache_worker *w = calloc(1, sizeof *w);
    if (!w) return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory creating the refinement worker");
    w->desc = *desc;
    w->s = desc->scene;
    w->front = calloc(1, sizeof *w->front);
    w->ready = calloc(1, sizeof *w->ready);
    w->back = calloc(1, sizeof *w->back);
    if (desc->pixels) {
        w->pixels = malloc(w->s->tri_count * sizeof *w->pixels);
        if (w->pixels) memcpy(w->pixels, desc->pixels, w->s->tri_count * sizeof *w->pixels);
    }
    if (!w->front || !w->ready || !w->back || (desc->pixels && !w->pixels)) {
        cache_worker_destroy(w);
        return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory creating the refinement worker");
    }
    pthread_mutex_init(&w->lock, NULL);
    pthread_cond_init(&w->cond, NULL);
    if (pthread_create(&w->thread, NULL, worker_main, w) != 0) {
        pthread_mutex_destroy(&w->lock);
        pthread_cond_destroy(&w->cond);
        cache_worker_destroy(w);
        return lm_fail(err, LM_ERR_RUNTIME, "cannot start the refinement worker thread");
    }
    w->started = 1;
    *out = w;
    return LM_OK;
}

const cache_snapshot *cache_worker_acquire(cache_worker *w)
{
    pthread_mutex_lock(&w->lock);
    if (w->ready_new) {
        snapshot_store *t = w->front;
        w->front = w->ready;
        w->ready = t;
        w->ready_new = 0;
    }
    const cache_snapshot *s = w->front->snap.generation ? &w->front->snap : NULL;
    pthread_mutex_unlock(&w->lock);
    return s;
}

void cache_worker_pause(cache_worker *w)
{
    pthread_mutex_lock(&w->lock);
    w->paused = 1;
    pthread_cond_broadcast(&w->cond);
    while (!w->parked && !w->finished) pthread_cond_wait(&w->cond, &w->lock);
    pthread_mutex_unlock(&w->lock);
}

void cache_worker_resume(cache_worker *w)
{
    pthread_mutex_lock(&w->lock);
    w->paused = 0;
    pthread_cond_broadcast(&w->cond);
    pthread_mutex_unlock(&w->lock);
}

lm_result cache_worker_set_light(cache_worker *w, uint32_t light, const float value[3], lm_error *err)
{
    if (light >= scene_light_count(w->s))
        return lm_fail(err, LM_ERR_INVALID_ARG, "cache_worker_set_light: light %u does not exist", light);
    pthread_mutex_lock(&w->lock);
    lm_result r = LM_OK;
    if (w->edit_count == MAX_EDITS) {
        r = lm_fail(err, LM_ERR_RUNTIME, "cache_worker_set_light: %d edits are waiting already", MAX_EDITS);
    } else {
        w->edits[w->edit_count].light = light;
        memcpy(w->edits[w->edit_count].value, value, sizeof w->edits[0].value);
        w->edit_count++;
        pthread_cond_broadcast(&w->cond);
    }
    pthread_mutex_unlock(&w->lock);
    return r;
}
