/* view_residual.c — the residual's thread (view_residual.h). */
#include "src/view/view_residual.h"

#include "src/scene/camera.h"

#include <math.h>
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

/* A peer's new view first gets one pass over a grid of its pixels, one in k×k
 * with the rest interpolated, k chosen from the last such pass so that it takes
 * about this long, and that picture is handed back at once: a moving view shows
 * the peer's own light a dozen times a second, where a whole pass at 1280×720
 * takes about a second here (docs/peers.md, "The moving view"). Until the view's
 * first whole pass, the slices are a quarter of it, so that a view that moves on
 * is taken up promptly. */
#define VIEW_RESIDUAL_PREVIEW_PASS 0.05
#define VIEW_RESIDUAL_GRID_FIRST 8 /* k before any grid pass was timed */
#define VIEW_RESIDUAL_GRID_MAX 16

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
    uint64_t starts;             /* view_residual_start calls so far */
    uint64_t published_start;    /* the start whose view the published picture is of */
};

static int same_lights(const view_residual_view *a, const view_residual_view *b, uint32_t lights)
{
    return memcmp(a->light_values, b->light_values, 3 * (size_t)lights * sizeof *a->light_values) == 0;
}

static int same_view(const view_residual_view *a, const view_residual_view *b, uint32_t lights)
{
    return camera_equal(&a->cam, &b->cam) && a->bounces == b->bounces && a->peer == b->peer &&
           same_lights(a, b, lights);
}

/* Two peer views that differ at most in where the camera looks from (not in its
 * size): a picture of one stands for the other while the view moves. */
static int same_but_camera(const view_residual_view *a, const view_residual_view *b, uint32_t lights)
{
    return a->peer != REF_ESTIMATOR_PATHS && a->peer == b->peer && a->bounces == b->bounces &&
           a->visibility == b->visibility && a->cam.width == b->cam.width && a->cam.height == b->cam.height &&
           same_lights(a, b, lights);
}

/* The thread's own state: the residual, the view its samples are of, and the
 * picture it corrects. Touched by this thread only. */
typedef struct residual_thread {
    rend_residual *rr;
    ref_renderer *peer;             /* instead of rr with a peer (view_residual_view.peer) */
    view_residual_view view;
    uint64_t start;                 /* which start (view_residual.starts) view is of */
    float *lights, *cached, *out;
    size_t cap;
    /* A peer's grid passes (preview_pass). */
    int preview_due;                /* the view is new: its first pass is a grid's */
    int whole_due;                  /* no whole pass of the view handed back yet: short slices */
    uint8_t *mask;                  /* width·height: the grid's pixels */
    size_t mask_cap;
    double pixel_seconds;           /* the last grid pass's time a pixel sampled, the VPLs' aside; 0: none yet */
    double vpl_seconds;             /* ...and what making its VPLs (and maps) took */
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
    t->start = vr->starts;
    return 1;
}

/* Frees what the thread renders with (before making another). */
static void drop_renderers(residual_thread *t)
{
    rend_residual_destroy(t->rr);
    t->rr = NULL;
    ref_destroy(t->peer);
    t->peer = NULL;
    t->pixel_seconds = t->vpl_seconds = 0.0; /* another scene, size or estimator: timed again */
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
    t->preview_due = t->whole_due = 1;
    return 1;
}

/* The grid's side k for a w×h view: one sampled pixel in k×k, so that a pass
 * takes about VIEW_RESIDUAL_PREVIEW_PASS by the last grid pass's times (its
 * VPLs cost the same whatever k: they are left at least a quarter of it). */
static int preview_grid(const residual_thread *t, int w, int h)
{
    if (!(t->pixel_seconds > 0.0)) return VIEW_RESIDUAL_GRID_FIRST;
    double budget = VIEW_RESIDUAL_PREVIEW_PASS - t->vpl_seconds;
    if (budget < 0.25 * VIEW_RESIDUAL_PREVIEW_PASS) budget = 0.25 * VIEW_RESIDUAL_PREVIEW_PASS;
    const double k = ceil(sqrt((double)w * (double)h * t->pixel_seconds / budget));
    return k < 1.0 ? 1 : k > VIEW_RESIDUAL_GRID_MAX ? VIEW_RESIDUAL_GRID_MAX : (int)k;
}

/* Along one axis: the grid lines (at o + i·k, g of them) either side of pixel x,
 * and the weight of the second, clamped at the borders. */
static void grid_span(int x, int o, int k, int g, int *i0, int *i1, float *wt)
{
    *i0 = x < o ? 0 : (x - o) / k < g - 1 ? (x - o) / k : g - 1;
    *i1 = *i0 + 1 < g ? *i0 + 1 : *i0;
    const float f = (float)(x - o - *i0 * k) / (float)k;
    *wt = f < 0.0f ? 0.0f : f > 1.0f ? 1.0f : f;
}

/* The pixels between a grid's (one in k×k, at (ox + i·k, oy + j·k)), from the
 * grid's bilinearly (clamped at the borders); rgb (w·h·3) holds the grid's
 * samples, which are not written. Separably: the grid's rows first, along x,
 * then every other row between its two grid rows (a tenth of the time of a
 * per-pixel weave at 1280×720: its share of a moving view's cycle). */
static void fill_between(float *rgb, int w, int h, int k, int ox, int oy)
{
    const int gw = (w - 1 - ox) / k + 1, gh = (h - 1 - oy) / k + 1;
    const size_t row = (size_t)w * 3;
    for (int j = 0; j < gh; ++j) {
        float *r = rgb + (size_t)(oy + j * k) * row;
        for (int x = 0; x < w; ++x) {
            if (x >= ox && (x - ox) % k == 0) continue;
            int i0, i1;
            float wx;
            grid_span(x, ox, k, gw, &i0, &i1, &wx);
            const float *a = r + (size_t)(ox + i0 * k) * 3, *b = r + (size_t)(ox + i1 * k) * 3;
            for (int c = 0; c < 3; ++c) r[(size_t)x * 3 + (size_t)c] = a[c] + wx * (b[c] - a[c]);
        }
    }
    for (int y = 0; y < h; ++y) {
        if (y >= oy && (y - oy) % k == 0) continue;
        int j0, j1;
        float wy;
        grid_span(y, oy, k, gh, &j0, &j1, &wy);
        const float *a = rgb + (size_t)(oy + j0 * k) * row, *b = rgb + (size_t)(oy + j1 * k) * row;
        float *o = rgb + (size_t)y * row;
        for (size_t c = 0; c < row; ++c) o[c] = a[c] + wy * (b[c] - a[c]);
    }
}

/* A peer's first pass at a new view: one sample at each pixel of a k×k grid,
 * the picture filled in between (t->out), its statistics in info (grid: k). */
static void preview_pass(residual_thread *t, rend_residual_info *info)
{
    const int w = t->view.cam.width, h = t->view.cam.height;
    const size_t n = (size_t)w * (size_t)h;
    int k = preview_grid(t, w, h);
    if (k > 1 && n > t->mask_cap) {
        uint8_t *m = realloc(t->mask, n);
        if (m) {
            t->mask = m;
            t->mask_cap = n;
        }
    }
    if (n > t->mask_cap) k = 1; /* out of memory for the grid: a whole pass */
    const int ox = k / 2 < w ? k / 2 : w - 1, oy = k / 2 < h ? k / 2 : h - 1;
    if (k > 1) {
        memset(t->mask, 0, n);
        for (int y = oy; y < h; y += k)
            for (int x = ox; x < w; x += k) t->mask[(size_t)y * (size_t)w + (size_t)x] = 1;
        if (ref_set_mask(t->peer, t->mask, NULL) != LM_OK) k = 1;
    }
    ref_stats before, after;
    ref_get_stats(t->peer, &before);
    const double t0 = lm_now_seconds();
    ref_render_pass(t->peer, NULL, 0.0); /* whole: every grid pixel one sample */
    const double took = lm_now_seconds() - t0;
    if (k > 1) (void)ref_set_mask(t->peer, NULL, NULL);
    ref_get_stats(t->peer, &after);
    const double vpls = (after.vpl_seconds - before.vpl_seconds) + (after.ism_seconds - before.ism_seconds);
    const double sampled = (double)((w - 1 - ox) / k + 1) * (double)((h - 1 - oy) / k + 1);
    t->vpl_seconds = vpls;
    t->pixel_seconds = (took > vpls ? took - vpls : 1e-9) / sampled;
    if (k > 1) { /* the grid's rows only: the rest is filled in */
        for (int y = oy; y < h; y += k) ref_get_rows(t->peer, y, 1, t->out + (size_t)y * (size_t)w * 3, NULL, NULL);
        fill_between(t->out, w, h, k, ox, oy);
    } else {
        ref_get_image(t->peer, t->out, NULL, NULL);
    }
    info->min_samples = info->max_samples = 1;
    info->rays = after.rays;
    info->vpls = after.vpls;
    info->seconds = after.seconds;
    info->vpl_seconds = after.vpl_seconds + after.ism_seconds;
    info->grid = (uint32_t)k;
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
        const double deadline =
            lm_now_seconds() + (t.peer && t.whole_due ? 0.25 * VIEW_RESIDUAL_PREVIEW_PASS : VIEW_RESIDUAL_SLICE);
        if (t.peer && t.preview_due) {
            preview_pass(&t, &info);
            t.preview_due = 0;
        } else if (t.peer) { /* passes to the slice's end; its picture as it stands, once whole */
            while (lm_now_seconds() < deadline) ref_render_pass(t.peer, NULL, deadline);
            ref_stats st;
            ref_get_stats(t.peer, &st);
            if (st.min_samples >= 1) {
                ref_get_image(t.peer, t.out, NULL, NULL);
                t.whole_due = 0;
            }
            info.min_samples = st.min_samples;
            info.max_samples = st.max_samples;
            info.rays = st.rays;
            info.vpls = st.vpls;
            info.seconds = st.seconds;
            info.vpl_seconds = st.vpl_seconds + st.ism_seconds;
            info.grid = 1;
        } else {
            rend_residual_run(t.rr, NULL, deadline);
            rend_residual_apply(t.rr, t.cached, t.out, &info);
        }
        const uint32_t needed = t.peer ? 1u : REND_RESIDUAL_MIN_SAMPLES_DEFAULT;
        pthread_mutex_lock(&vr->lock);
        size_t n = (size_t)t.view.cam.width * (size_t)t.view.cam.height * 3;
        /* Handed back only while this view is still wanted (a peer's: or a view
         * it stands for, the camera moved on), and once it can correct. */
        if (vr->active && (!vr->pending || same_but_camera(&vr->view, &t.view, vr->lights)) &&
            info.min_samples >= needed) {
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
                vr->published_start = t.start;
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
    free(t.mask);
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
    /* A peer's picture of the view before stands for this one until its own:
     * the camera moved, nothing else. Else a picture of the new start only. */
    const int moved = vr->active && vr->published_w && same_but_camera(view, &vr->view, vr->lights);
    memcpy(vr->pending_lights, view->light_values, 3 * (size_t)vr->lights * sizeof *vr->pending_lights);
    vr->view = *view;
    vr->view.light_values = vr->pending_lights;
    vr->pending = 1;
    vr->active = 1;
    vr->starts++;
    if (!moved) {
        vr->published_seq++;
        vr->published_w = 0;
    }
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

int view_residual_take(view_residual *vr, float *rgb, uint64_t *seq, rend_residual_info *info, int *current)
{
    int got = 0;
    pthread_mutex_lock(&vr->lock);
    if (vr->active && vr->published_w && vr->published_seq != *seq) {
        memcpy(rgb, vr->published, (size_t)vr->published_w * (size_t)vr->published_h * 3 * sizeof *rgb);
        if (info) *info = vr->published_info;
        if (current) *current = vr->published_start == vr->starts;
        *seq = vr->published_seq;
        got = 1;
    }
    pthread_mutex_unlock(&vr->lock);
    return got;
}
