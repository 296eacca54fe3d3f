/* view_residual.c — the residual's thread (view_residual.h). */
#include "src/view/view_residual.h"

#include "src/scene/camera.h"

#include <pthread.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

/* Seconds of path tracing between two corrected pictures handed back: the
 * picture follows the samples about five times a second, and applying (a
 * read-back and a blend of the picture) costs a few percent of it. It is also
 * the longest a stop waits to take effect: a pass is not cancelled from the
 * display thread (a flag read by the pass's workers would be a data race), it
 * runs to the end of its slice, with the display's core left to the display. */
#define VIEW_RESIDUAL_SLICE 0.2

struct view_residual {
    const scene *s;
    uint32_t lights;
    pthread_t thread;
    int started;                 /* the thread exists */

    /* Shared between the display thread and the residual's, under lock. */
    pthread_mutex_t lock;
    pthread_cond_t wake;
    int quit, active;            /* written by the display thread */
    int pending;                 /* a start the thread has not taken yet */
    view_residual_view view;     /* of the pending start; light_values points at pending_lights */
    float *pending_lights;       /* 3 per light */
    float *pending_cached;       /* w·h·3, the picture of the pending start */
    size_t pending_cap;          /* floats it holds */
    float *published;            /* w·h·3: the newest corrected picture */
    size_t published_cap;
    int published_w, published_h;
    uint64_t published_seq;      /* 0: none */
    rend_residual_info published_info;
};

static int same_view(const view_residual_view *a, const view_residual_view *b, uint32_t lights)
{
    if (!camera_equal(&a->cam, &b->cam) || a->bounces != b->bounces || a->peer != b->peer) return 0;
    return memcmp(a->light_values, b->light_values, 3 * (size_t)lights * sizeof *a->light_values) == 0;
}

/* The thread's own state: the residual, the view its samples are of, and the
 * picture it corrects. Touched by this thread only. */
typedef struct residual_thread {
    rend_residual *rr;
    ref_renderer *peer;             /* instead of rr with a peer (view_residual_view.peer) */
    view_residual_view view;
    float *lights, *cached, *out;
    size_t cap;
} residual_thread;

/* What a pending start asks of the residual. */
typedef enum start_kind { START_SAME = 0, START_RESTART, START_MAKE } start_kind;

/* Takes the pending start's picture, view and lights (under the lock: a copy,
 * nothing slow). 0 when out of memory. */
static int take_start(view_residual *vr, residual_thread *t, start_kind *kind)
{
    const view_residual_view *v = &vr->view;
    size_t n = (size_t)v->cam.width * (size_t)v->cam.height * 3;
    if (n > t->cap) {
        float *c = realloc(t->cached, n * sizeof *c), *o = c ? realloc(t->out, n * sizeof *o) : NULL;
        if (c) t->cached = c;
        if (o) t->out = o;
        if (!c || !o) return 0;
        t->cap = n;
    }
    if (v->peer == REF_ESTIMATOR_PATHS) memcpy(t->cached, vr->pending_cached, n * sizeof *t->cached);
    const int made = v->peer == REF_ESTIMATOR_PATHS ? t->rr != NULL : t->peer != NULL;
    *kind = made && same_view(v, &t->view, vr->lights) ? START_SAME
            : !made || v->cam.width != t->view.cam.width || v->cam.height != t->view.cam.height ||
                    v->bounces != t->view.bounces || v->peer != t->view.peer || v->visibility != t->view.visibility
                ? START_MAKE
                : START_RESTART;
    memcpy(t->lights, vr->pending_lights, 3 * (size_t)vr->lights * sizeof *t->lights);
    t->view = *v;
    t->view.light_values = t->lights;
    return 1;
}

/* Frees what the thread renders with (before making another). */
static void drop_renderers(residual_thread *t)
{
    rend_residual_destroy(t->rr);
    t->rr = NULL;
    ref_destroy(t->peer);
    t->peer = NULL;
}

/* Every core but the display's. */
static int pass_threads(void)
{
    long ncpu = sysconf(_SC_NPROCESSORS_ONLN);
    return ncpu > 2 ? (int)ncpu - 1 : 1;
}

/* begin_start for a peer: its renderer made (its own BVH) or restarted at the
 * view, with the lights now. */
static int begin_peer(view_residual *vr, residual_thread *t, start_kind kind)
{
    const view_residual_view *v = &t->view;
    if (kind == START_SAME) return 1;
    if (kind == START_MAKE) {
        drop_renderers(t);
        lm_error err;
        if (ref_create(&(ref_desc){.scene = vr->s, .view = &v->cam, .width = v->cam.width, .height = v->cam.height,
                                   .bounces = v->bounces, .estimator = v->peer, .vpl_keep = 1,
                                   .vpl_visibility = v->visibility, .gl_platform = v->gl_platform,
                                   .threads = pass_threads()},
                       &t->peer, &err) != LM_OK)
            return 0;
    }
    for (uint32_t l = 0; l < vr->lights; ++l) (void)ref_set_light(t->peer, l, t->lights + 3 * (size_t)l, NULL);
    ref_restart(t->peer, &v->cam);
    return 1;
}

/* Acts on a start taken (without the lock: making the residual builds its BVH):
 * the samples go on for the same view, else the residual is made again (a new
 * size or bounce count) or restarted. 0 when it cannot be made. */
static int begin_start(view_residual *vr, residual_thread *t, start_kind kind)
{
    const view_residual_view *v = &t->view;
    if (v->peer != REF_ESTIMATOR_PATHS) return begin_peer(vr, t, kind);
    if (kind == START_SAME) return 1;
    if (kind == START_MAKE) {
        drop_renderers(t);
        lm_error err;
        if (rend_residual_create(&(rend_residual_desc){.scene = vr->s, .camera = &v->cam, .width = v->cam.width,
                                                       .height = v->cam.height, .bounces = v->bounces,
                                                       .threads = pass_threads()},
                                 &t->rr, &err) != LM_OK)
            return 0;
    }
    for (uint32_t l = 0; l < vr->lights; ++l) rend_residual_set_light(t->rr, l, t->lights + 3 * (size_t)l, NULL);
    rend_residual_restart(t->rr, &v->cam); /* the new view's and lights' samples start together */
    rend_residual_apply(t->rr, t->cached, t->out, NULL); /* the picture its adaptive passes start from */
    return 1;
}

static void *thread_main(void *arg)
{
    view_residual *vr = arg;
    residual_thread t = {0};
    t.lights = calloc((size_t)vr->lights + 1, 3 * sizeof *t.lights);
    pthread_mutex_lock(&vr->lock);
    while (!vr->quit) {
        if (!vr->active) {
            pthread_cond_wait(&vr->wake, &vr->lock);
            continue;
        }
        start_kind kind = START_SAME;
        if (vr->pending) {
            vr->pending = 0;
            if (!t.lights || !take_start(vr, &t, &kind)) { /* out of memory: nothing until the next start */
                vr->active = 0;
                continue;
            }
        }
        pthread_mutex_unlock(&vr->lock);
        if (!begin_start(vr, &t, kind)) { /* no BVH: nothing to correct until the next start */
            drop_renderers(&t);
            pthread_mutex_lock(&vr->lock);
            if (!vr->pending) vr->active = 0; /* a start since then is tried again */
            continue;
        }
        rend_residual_info info = {0};
        const double deadline = lm_now_seconds() + VIEW_RESIDUAL_SLICE;
        if (t.peer) { /* passes to the slice's end; its picture as it stands */
            while (lm_now_seconds() < deadline) ref_render_pass(t.peer, NULL, deadline);
            ref_stats st;
            ref_get_stats(t.peer, &st);
            ref_get_image(t.peer, t.out, NULL, NULL);
            info.min_samples = st.min_samples;
            info.max_samples = st.max_samples;
            info.rays = st.rays;
            info.vpls = st.vpls;
        } else {
            rend_residual_run(t.rr, NULL, deadline);
            rend_residual_apply(t.rr, t.cached, t.out, &info);
        }
        const uint32_t needed = t.peer ? 1u : REND_RESIDUAL_MIN_SAMPLES_DEFAULT;
        pthread_mutex_lock(&vr->lock);
        size_t n = (size_t)t.view.cam.width * (size_t)t.view.cam.height * 3;
        /* Handed back only while this view is still wanted, and once it can correct. */
        if (vr->active && !vr->pending && info.min_samples >= needed) {
            if (n > vr->published_cap) {
                float *p = realloc(vr->published, n * sizeof *p);
                if (p) {
                    vr->published = p;
                    vr->published_cap = n;
                }
            }
            if (n <= vr->published_cap) {
                memcpy(vr->published, t.out, n * sizeof *t.out);
                vr->published_w = t.view.cam.width;
                vr->published_h = t.view.cam.height;
                vr->published_info = info;
                vr->published_seq++;
            }
        }
    }
    pthread_mutex_unlock(&vr->lock);
    rend_residual_destroy(t.rr);
    ref_destroy(t.peer);
    free(t.lights);
    free(t.cached);
    free(t.out);
    return NULL;
}

lm_result view_residual_create(const scene *s, view_residual **out, lm_error *err)
{
    *out = NULL;
    view_residual *vr = calloc(1, sizeof *vr);
    if (!vr) return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory for the viewer's residual");
    vr->s = s;
    vr->lights = s->area_light_count + s->point_light_count;
    vr->pending_lights = calloc((size_t)vr->lights + 1, 3 * sizeof *vr->pending_lights);
    pthread_mutex_init(&vr->lock, NULL);
    pthread_cond_init(&vr->wake, NULL);
    if (!vr->pending_lights) {
        view_residual_destroy(vr);
        return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory for the viewer's residual");
    }
    if (pthread_create(&vr->thread, NULL, thread_main, vr) != 0) {
        view_residual_destroy(vr);
        return lm_fail(err, LM_ERR_RUNTIME, "could not start the viewer's residual thread");
    }
    vr->started = 1;
    *out = vr;
    return LM_OK;
}

void view_residual_destroy(view_residual *vr)
{
    if (!vr) return;
    if (vr->started) {
        pthread_mutex_lock(&vr->lock);
        vr->quit = 1;
        pthread_cond_signal(&vr->wake);
        pthread_mutex_unlock(&vr->lock);
        pthread_join(vr->thread, NULL);
    }
    pthread_mutex_destroy(&vr->lock);
    pthread_cond_destroy(&vr->wake);
    free(vr->pending_lights);
    free(vr->pending_cached);
    free(vr->published);
    free(vr);
}

lm_result view_residual_start(view_residual *vr, const view_residual_view *view, const float *cached, lm_error *err)
{
    size_t n = (size_t)view->cam.width * (size_t)view->cam.height * 3;
    pthread_mutex_lock(&vr->lock);
    if (n > vr->pending_cap) {
        float *p = realloc(vr->pending_cached, n * sizeof *p);
        if (!p) {
            pthread_mutex_unlock(&vr->lock);
            return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory for the viewer's residual");
        }
        vr->pending_cached = p;
        vr->pending_cap = n;
    }
    if (cached) memcpy(vr->pending_cached, cached, n * sizeof *cached);
    memcpy(vr->pending_lights, view->light_values, 3 * (size_t)vr->lights * sizeof *vr->pending_lights);
    vr->view = *view;
    vr->view.light_values = vr->pending_lights;
    vr->pending = 1;
    vr->active = 1;
    vr->published_seq++; /* a picture of the new start only: the old one is not handed back */
    vr->published_w = 0;
    pthread_cond_signal(&vr->wake);
    pthread_mutex_unlock(&vr->lock);
    return LM_OK;
}

void view_residual_stop(view_residual *vr)
{
    pthread_mutex_lock(&vr->lock);
    vr->active = 0;
    pthread_mutex_unlock(&vr->lock);
}

int view_residual_take(view_residual *vr, float *rgb, uint64_t *seq, rend_residual_info *info)
{
    int got = 0;
    pthread_mutex_lock(&vr->lock);
    if (vr->active && vr->published_w && vr->published_seq != *seq) {
        memcpy(rgb, vr->published, (size_t)vr->published_w * (size_t)vr->published_h * 3 * sizeof *rgb);
        if (info) *info = vr->published_info;
        *seq = vr->published_seq;
        got = 1;
    }
    pthread_mutex_unlock(&vr->lock);
    return got;
}
