/* rend_session.c — the GL context, ID pass, worker and renderers wired once
 * (rend_session.h). */
#include "src/render/rend_session.h"

#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "sampling/rt_scene.h"
#include "src/base/fork_guard.h"
#include "src/gpu/gl_context.h"
#include "src/render/rend_id.h"
#include "src/scene/camera.h"

struct rend_session {
    rend_session_desc d;              /* defaults applied; d.camera points at cam */
    scene_camera cam;                 /* the first view (ID_FIRST) */
    glctx *ctx;                       /* NULL when d.gl is borrowed */
    rend_session_early_gl *early_gl;  /* d.early_gl until make_context takes it */
    const GladGLContext *gl;
    rend_id *ip;
    rt_scene *rt;                     /* ids_by_rays: the ray ID pass's Embree scene, then the worker's
                                         samplers' (samp_desc.rt); freed once the worker is gone */
    scene_camera id_cam;              /* the last ID pass's camera (id_done): made again after release_gl */
    int id_done;
    cache_worker *wk;
    rend_frame *frame[REND_SESSION_RENDERER_COUNT];
    rend_frame *ahead;                /* the early context's preview renderer, made before the scene
                                         (rend_frame_set_scene), until the preview takes it */
    const cache_snapshot *snap;       /* the last acquired */
    rend_session_info info;
};

void rend_session_desc_defaults(rend_session_desc *d)
{
    if (!d) return;
    if (d->sampler.direct_target_error == 0) d->sampler.direct_target_error = REND_SESSION_TARGET_ERROR_DEFAULT;
    if (d->sampler.indirect_target_error == 0) d->sampler.indirect_target_error = REND_SESSION_TARGET_ERROR_DEFAULT;
    if (d->gl_platform == GLCTX_DEFAULT) d->gl_platform = GLCTX_EGL;
    if (d->sampler.gl_platform == GLCTX_DEFAULT) d->sampler.gl_platform = d->gl_platform;
    if (d->supersample == 0) d->supersample = REND_FRAME_SUPERSAMPLE_DEFAULT;
    if (d->jnd_floor == 0) d->jnd_floor = REND_SESSION_JND_FLOOR_DEFAULT;
    if (d->camera && d->width == 0 && d->height == 0) {
        d->width = d->camera->width;
        d->height = d->camera->height;
    }
}

static lm_result check_desc(const rend_session_desc *d, lm_error *err)
{
    if (!d || !d->scene) return lm_fail(err, LM_ERR_INVALID_ARG, "rend_session_create: no scene");
    if ((unsigned)d->order >= REND_SESSION_ORDER_COUNT)
        return lm_fail(err, LM_ERR_INVALID_ARG, "rend_session_create: order %d is none of rend_session_order",
                       (int)d->order);
    if (isnan(d->jnd_floor))
        return lm_fail(err, LM_ERR_INVALID_ARG, "rend_session_create: jnd_floor is not a number");
    if (d->order == REND_SESSION_ID_FIRST && !d->camera)
        return lm_fail(err, LM_ERR_INVALID_ARG,
                       "rend_session_create: REND_SESSION_ID_FIRST needs a camera for the first ID pass");
    if (d->width < 0 || d->height < 0 || d->width > 16384 || d->height > 16384 || (d->width == 0) != (d->height == 0))
        return lm_fail(err, LM_ERR_INVALID_ARG, "rend_session_create: %dx%d is no image size (1..16384 a side)",
                       d->width, d->height);
    if (d->order == REND_SESSION_ID_FIRST && d->width == 0)
        return lm_fail(err, LM_ERR_INVALID_ARG, "rend_session_create: the first ID pass needs an image size");
    if (d->supersample < 1 || d->supersample > REND_FRAME_SUPERSAMPLE_MAX)
        return lm_fail(err, LM_ERR_INVALID_ARG, "rend_session_create: supersample %d is not 1..%d", d->supersample,
                       REND_FRAME_SUPERSAMPLE_MAX);
    return LM_OK;
}

/* Shared with the helper thread. It writes ctx, frame and r until it is
 * joined; the client's thread (start, size, the session's create, end) reads
 * them after the join only. width, height and closed are the client's, read by
 * the helper under lock. */
struct rend_session_early_gl {
    glctx_platform platform;
    pthread_t thread;
    pthread_mutex_t lock;
    pthread_cond_t cond;
    int width, height;  /* rend_session_early_gl_size; 0 = not given yet */
    int closed;         /* no size will come: the client takes the context or ends it */
    int context_tried;  /* the helper's: glctx_create has returned (start waits for it) */
    int joined;
    glctx *ctx;
    rend_frame *frame;  /* the preview renderer made ahead of the scene (rend_frame_set_scene), or NULL */
    lm_result r; /* its error is not kept: a failed start makes the session try once more, and report that */
};

/* Before the size is known the renderer is made at 3×3: llvmpipe's shader
 * variants depend on whether a texture's sides are powers of two (its sampler
 * state), not on its size, and a window or reference is rarely a power of two
 * (a size that is still works, its first draw compiles its own variants). */
enum { EARLY_STAND_IN_SIDE = 3 };

static void *early_gl_main(void *user)
{
    rend_session_early_gl *e = user;
    lm_error err;
    e->r = glctx_create(&(glctx_desc){.platform = e->platform}, &e->ctx, &err);
    pthread_mutex_lock(&e->lock); /* the client goes on (rend_session_early_gl_start) */
    e->context_tried = 1;
    pthread_cond_broadcast(&e->cond);
    pthread_mutex_unlock(&e->lock);
    /* The preview renderer made here, inside the fork guard: Mesa's and LLVM's
     * C++ statics register exit functions the first time they are used (the
     * GLSL compiler's, and LLVM's at the first shader variant compiled:
     * fork_guard.h). Its programs cost the compiler's own start (~22 ms, its
     * built-in functions) and its first draw the variants (~40 ms): both are
     * paid here, while the client loads. */
    /* Embree's device and thread pool too (rt_device_warm): 13-18 ms of
     * Water's first image otherwise, in the worker before its first ray. */
    rt_device_warm();
    if (e->r == LM_OK) {
        lm_fork_guard_enter();
        if (rend_frame_create(glctx_gl(e->ctx),
                              &(rend_frame_desc){.width = EARLY_STAND_IN_SIDE, .height = EARLY_STAND_IN_SIDE,
                                                 .supersample = 1},
                              &e->frame, &err) != LM_OK)
            e->frame = NULL; /* the session makes its own, and reports what fails then */
        lm_fork_guard_leave();
    }
    /* Its images at the size the client gives, if it gives one before it takes
     * the context: llvmpipe zeroes an image as it makes it (~40 ms for the
     * preview's at 640×480 here), outside the guard (no library is loaded). */
    pthread_mutex_lock(&e->lock);
    while (e->frame && !e->width && !e->closed) pthread_cond_wait(&e->cond, &e->lock);
    const int w = e->width, h = e->height;
    pthread_mutex_unlock(&e->lock);
    if (e->frame && w > 0 && rend_frame_resize(e->frame, w, h, &err) != LM_OK) {
        rend_frame_destroy(e->frame);
        e->frame = NULL;
    }
    if (e->r == LM_OK) glctx_release(e->ctx); /* for the session's thread to take */
    return NULL;
}

lm_result rend_session_early_gl_start(glctx_platform platform, rend_session_early_gl **out, lm_error *err)
{
    *out = NULL;
    rend_session_early_gl *e = calloc(1, sizeof *e);
    if (!e) return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory starting the GL context");
    e->platform = platform;
    e->r = LM_ERR_RUNTIME;
    pthread_mutex_init(&e->lock, NULL);
    pthread_cond_init(&e->cond, NULL);
    if (pthread_create(&e->thread, NULL, early_gl_main, e) != 0) {
        pthread_cond_destroy(&e->cond);
        pthread_mutex_destroy(&e->lock);
        free(e);
        return lm_fail(err, LM_ERR_RUNTIME, "cannot start a thread for the GL context");
    }
    /* The driver's libraries are loaded before the client goes on: a library
     * the client loads meanwhile (the image module, for a reference) would
     * hold the dynamic loader's lock for its whole load, and the context
     * would wait for it (converge: the context 0.09 s alone, 0.64-0.69 s
     * beside the reference's read). The renderer is made after this, beside
     * the client. */
    pthread_mutex_lock(&e->lock);
    while (!e->context_tried) pthread_cond_wait(&e->cond, &e->lock);
    pthread_mutex_unlock(&e->lock);
    *out = e;
    return LM_OK;
}

void rend_session_early_gl_size(rend_session_early_gl *e, int width, int height)
{
    if (!e || width < 1 || height < 1) return;
    pthread_mutex_lock(&e->lock);
    if (!e->closed) {
        e->width = width;
        e->height = height;
        pthread_cond_broadcast(&e->cond);
    }
    pthread_mutex_unlock(&e->lock);
}

static void early_gl_join(rend_session_early_gl *e)
{
    if (e->joined) return;
    pthread_mutex_lock(&e->lock);
    e->closed = 1;
    pthread_cond_broadcast(&e->cond);
    pthread_mutex_unlock(&e->lock);
    pthread_join(e->thread, NULL);
    e->joined = 1;
}

/* Waits for the helper; its context, current on this thread, or NULL; *frame
 * the renderer made ahead (NULL without a context). */
static glctx *early_gl_take(rend_session_early_gl *e, rend_frame **frame)
{
    early_gl_join(e);
    lm_error err;
    glctx *ctx = e->ctx;
    *frame = e->frame;
    e->ctx = NULL;
    e->frame = NULL;
    if (ctx && (e->r != LM_OK || glctx_make_current(ctx, &err) != LM_OK)) {
        /* The renderer goes with its context: objects of a context that is not
         * current cannot be deleted, and glctx_destroy frees them all. */
        glctx_destroy(ctx);
        ctx = NULL;
        *frame = NULL;
    }
    return ctx;
}

void rend_session_early_gl_end(rend_session_early_gl *e)
{
    if (!e) return;
    early_gl_join(e);
    if (e->frame && e->ctx && glctx_make_current(e->ctx, &(lm_error){{0}}) == LM_OK) rend_frame_destroy(e->frame);
    glctx_destroy(e->ctx);
    pthread_cond_destroy(&e->cond);
    pthread_mutex_destroy(&e->lock);
    free(e);
}

static lm_result make_context(rend_session *rs, lm_error *err)
{
    if (rs->gl) return LM_OK; /* made, or borrowed, already */
    if (rs->d.gl) {
        rs->gl = rs->d.gl;
        return LM_OK;
    }
    if (rs->early_gl) {
        rs->ctx = early_gl_take(rs->early_gl, &rs->ahead);
        rend_session_early_gl_end(rs->early_gl);
        rs->early_gl = NULL;
        if (rs->ctx) {
            rs->gl = glctx_gl(rs->ctx);
            return LM_OK;
        }
    }
    lm_result r = glctx_create(&(glctx_desc){.platform = rs->d.gl_platform}, &rs->ctx, err);
    if (r == LM_OK) rs->gl = glctx_gl(rs->ctx);
    return r;
}

float rend_session_sample_pixels(int supersample, int accumulate)
{
    const int s = supersample > 0 ? supersample : 1, k = accumulate > 0 ? accumulate : 1;
    return 1.0f / (float)(s * k * s * k);
}

static lm_result make_worker(rend_session *rs, const uint32_t *pixels, uint32_t first_budget, lm_error *err)
{
    const rend_session_desc *d = &rs->d;
    /* Leaves as small as one of the final picture's samples: a highlight's rim or
     * a strip of light narrower than a pixel is seen in its box filter. */
    cache_desc cd = {.single_mesh = d->single_mesh,
                     .bounces = d->bounces ? d->bounces : CACHE_BOUNCES_AUTO,
                     .glossy = d->glossy,
                     .sample_pixels = d->sample_pixels > 0.0f ? d->sample_pixels
                                                              : rend_session_sample_pixels(d->supersample, 1)};
    if (d->camera) { /* the specular mesh starts at this camera's eye, not the scene's first */
        cd.eye_set = 1;
        memcpy(cd.eye, d->camera->position, sizeof cd.eye);
    }
    samp_desc sampler = d->sampler;
    if (rs->rt && !sampler.rt) sampler.rt = rs->rt; /* the ray ID pass's: not built twice */
    return cache_worker_create(&(cache_worker_desc){.scene = d->scene, .sampler = sampler, .pixels = pixels,
                                                    .pixels_later = pixels == NULL, .max_tested = d->max_tested,
                                                    .first_budget = first_budget,
                                                    .publish_debug = d->publish_debug, .cache = cd,
                                                    .whole_roots = 1, /* rend_frame draws them from the scene */
                                                    .jnd_floor = d->jnd_floor > 0 ? d->jnd_floor : 0},
                               &rs->wk, err);
}

/* The ID pass at cam, made at its first use; *out valid until the next. */
static lm_result id_pass(rend_session *rs, const scene_camera *cam, rend_id_result *out, lm_error *err)
{
    if (!cam) return lm_fail(err, LM_ERR_INVALID_ARG, "rend_session: no camera for the ID pass");
    if (rs->info.width <= 0)
        return lm_fail(err, LM_ERR_INVALID_ARG, "rend_session: no image size yet (rend_session_resize)");
    lm_result r = make_context(rs, err);
    if (r == LM_OK && !rs->ip)
        r = rend_id_create(rs->gl, &(rend_id_desc){.scene = rs->d.scene, .width = rs->info.width,
                                                   .height = rs->info.height},
                           &rs->ip, err);
    if (r == LM_OK) r = rend_id_render(rs->ip, cam, out, err);
    if (r == LM_OK) {
        rs->info.id_passes++;
        rs->info.id_seconds = out->seconds;
        rs->id_cam = *cam;
        rs->id_done = 1;
    }
    return r;
}

/* The ID pass's counts by rays (desc.ids_by_rays): as id_pass records it. */
static lm_result ray_id_pass(rend_session *rs, const scene_camera *cam, uint32_t *pixels, lm_error *err)
{
    const double t0 = lm_now_seconds();
    lm_result r = rs->rt ? LM_OK : rt_scene_create(&(rt_scene_desc){.scene = rs->d.scene}, &rs->rt, err);
    if (r == LM_OK) r = rend_id_count_rays(rs->d.scene, rs->rt, cam, rs->info.width, rs->info.height, pixels, err);
    if (r == LM_OK) {
        rs->info.id_passes++;
        rs->info.id_seconds = lm_now_seconds() - t0;
        rs->id_cam = *cam;
        rs->id_done = 1; /* rend_session_read_ids makes the GL pass when asked (no rs->ip) */
    }
    return r;
}

lm_result rend_session_create(const rend_session_desc *desc, rend_session **out, lm_error *err)
{
    rend_session_early_gl *early = desc ? desc->early_gl : NULL; /* ours, whatever happens */
    if (out) *out = NULL;
    if (!out) {
        rend_session_early_gl_end(early);
        return lm_fail(err, LM_ERR_INVALID_ARG, "rend_session_create: no place for the session");
    }
    rend_session_desc d = desc ? *desc : (rend_session_desc){0};
    d.early_gl = NULL;
    rend_session_desc_defaults(&d);
    lm_result r = check_desc(&d, err);
    rend_session *rs = r == LM_OK ? calloc(1, sizeof *rs) : NULL;
    if (!rs) {
        rend_session_early_gl_end(early);
        return r != LM_OK ? r : lm_fail(err, LM_ERR_NO_MEMORY, "out of memory for a render session");
    }
    rs->d = d;
    rs->early_gl = early;
    if (d.camera) {
        rs->cam = *d.camera;
        rs->d.camera = &rs->cam;
    }
    rs->info.width = d.width;
    rs->info.height = d.height;
    if (d.order == REND_SESSION_ID_FIRST && d.ids_by_rays) {
        uint32_t *pixels = malloc((d.scene->tri_count ? d.scene->tri_count : 1) * sizeof *pixels);
        r = pixels ? ray_id_pass(rs, &rs->cam, pixels, err)
                   : lm_fail(err, LM_ERR_NO_MEMORY, "out of memory counting pixels");
        if (r == LM_OK) r = make_worker(rs, pixels, 0, err);
        free(pixels);
    } else if (d.order == REND_SESSION_ID_FIRST) {
        rend_id_result ids;
        r = make_context(rs, err);
        if (r == LM_OK) r = id_pass(rs, &rs->cam, &ids, err);
        if (r == LM_OK) r = make_worker(rs, ids.pixels, 0, err);
    } else if (d.first_budget && d.camera && d.width > 0 && d.height > 0) {
        /* No ID pass yet: the triangles' projected areas stand in for its counts,
         * so the first image already has rounds of refinement (and refinement
         * goes on before the ID pass corrects the counts). */
        uint32_t *guess = malloc((d.scene->tri_count ? d.scene->tri_count : 1) * sizeof *guess);
        if (!guess) r = lm_fail(err, LM_ERR_NO_MEMORY, "out of memory guessing the pixels per triangle");
        if (r == LM_OK) camera_triangle_pixels(d.scene, d.camera, d.width, d.height, guess);
        if (r == LM_OK) r = make_worker(rs, guess, d.first_budget, err);
        free(guess);
        if (r == LM_OK) r = make_context(rs, err);
    } else {
        r = make_worker(rs, NULL, 0, err);
        if (r == LM_OK) r = make_context(rs, err);
    }
    if (r != LM_OK) {
        rend_session_destroy(rs);
        return r;
    }
    *out = rs;
    return LM_OK;
}

static void drop_gl_objects(rend_session *rs)
{
    rend_frame_destroy(rs->ahead);
    rs->ahead = NULL;
    for (int k = 0; k < REND_SESSION_RENDERER_COUNT; ++k) {
        rend_frame_destroy(rs->frame[k]);
        rs->frame[k] = NULL;
    }
    rend_id_destroy(rs->ip);
    rs->ip = NULL;
}

void rend_session_destroy(rend_session *rs)
{
    if (!rs) return;
    cache_worker_destroy(rs->wk); /* cancels and joins: nothing refers to the snapshots after this */
    rt_scene_destroy(rs->rt);      /* after the worker's samplers */
    drop_gl_objects(rs);
    glctx_destroy(rs->ctx);
    rend_session_early_gl_end(rs->early_gl); /* never taken: the session failed before its context */
    free(rs);
}

void rend_session_release_gl(rend_session *rs)
{
    if (!rs || !rs->ctx) return; /* a borrowed context (desc.gl) is the client's */
    drop_gl_objects(rs);
    glctx_destroy(rs->ctx);
    rs->ctx = NULL;
    rs->gl = NULL;
}

void rend_session_retire_worker(rend_session *rs)
{
    if (!rs) return;
    cache_worker_retire(rs->wk);
    rt_scene_destroy(rs->rt); /* the worker's samplers are gone with it */
    rs->rt = NULL;
}

lm_result rend_session_resize(rend_session *rs, int width, int height, lm_error *err)
{
    if (!rs) return lm_fail(err, LM_ERR_INVALID_ARG, "rend_session_resize: no session");
    if (width < 1 || height < 1 || width > 16384 || height > 16384)
        return lm_fail(err, LM_ERR_INVALID_ARG, "rend_session_resize: %dx%d is no image size (1..16384 a side)",
                       width, height);
    if (width == rs->info.width && height == rs->info.height) return LM_OK;
    drop_gl_objects(rs);
    rs->id_done = 0;
    rs->info.width = width;
    rs->info.height = height;
    return LM_OK;
}

lm_result rend_session_set_view(rend_session *rs, const scene_camera *cam, lm_error *err)
{
    if (!rs) return lm_fail(err, LM_ERR_INVALID_ARG, "rend_session_set_view: no session");
    rend_id_result ids;
    lm_result r = id_pass(rs, cam, &ids, err);
    return r == LM_OK ? cache_worker_set_view(rs->wk, ids.pixels, cam->position, err) : r;
}

lm_result rend_session_set_pixels(rend_session *rs, const scene_camera *cam, lm_error *err)
{
    if (!rs) return lm_fail(err, LM_ERR_INVALID_ARG, "rend_session_set_pixels: no session");
    rend_id_result ids;
    lm_result r = id_pass(rs, cam, &ids, err);
    return r == LM_OK ? cache_worker_set_pixels(rs->wk, ids.pixels, err) : r;
}

lm_result rend_session_read_ids(rend_session *rs, uint32_t *ids, lm_error *err)
{
    if (!rs || !ids) return lm_fail(err, LM_ERR_INVALID_ARG, "rend_session_read_ids: no session or no buffer");
    if (!rs->id_done) return lm_fail(err, LM_ERR_INVALID_ARG, "rend_session_read_ids: no ID pass has run at this size");
    lm_result r = LM_OK;
    if (!rs->ip) { /* released since (rend_session_release_gl): the same pass again */
        rend_id_result again;
        const scene_camera cam = rs->id_cam;
        r = id_pass(rs, &cam, &again, err);
    }
    return r == LM_OK ? rend_id_read_image(rs->ip, ids, err) : r;
}

lm_result rend_session_acquire(rend_session *rs, const cache_snapshot **snap, lm_error *err)
{
    if (snap) *snap = NULL;
    if (!rs) return lm_fail(err, LM_ERR_INVALID_ARG, "rend_session_acquire: no session");
    const cache_snapshot *s = cache_worker_acquire(rs->wk);
    if (s) rs->snap = s;
    if (snap) *snap = rs->snap;
    if (rs->snap && rs->snap->failed) return lm_fail(err, LM_ERR_RUNTIME, "refinement failed: %s", rs->snap->error);
    return LM_OK;
}

const cache_snapshot *rend_session_snapshot(const rend_session *rs)
{
    return rs ? rs->snap : NULL;
}

lm_result rend_session_wait(rend_session *rs, const rend_session_wait_desc *w, const cache_snapshot **snap,
                            lm_error *err)
{
    if (snap) *snap = NULL;
    if (!rs || !w) return lm_fail(err, LM_ERR_INVALID_ARG, "rend_session_wait: no session or no wait_desc");
    double period = w->nap > 0 ? w->nap : 0.005;
    for (;;) {
        if (w->stop && *w->stop) break;
        const cache_snapshot *s;
        lm_result r = rend_session_acquire(rs, &s, err);
        if (snap) *snap = s;
        if (r != LM_OK) return r;
        if (w->on_look) w->on_look(w->user, s);
        if (s && (s->finished || w->first || (w->until > 0 && lm_now_seconds() >= w->until))) break;
        lm_sleep_seconds(period);
    }
    return LM_OK;
}

lm_result rend_session_renderer(rend_session *rs, rend_session_renderer_kind kind, rend_frame **out, lm_error *err)
{
    if (out) *out = NULL;
    if (!rs || (unsigned)kind >= REND_SESSION_RENDERER_COUNT)
        return lm_fail(err, LM_ERR_INVALID_ARG, "rend_session_renderer: no session or no such renderer (%d)",
                       (int)kind);
    if (rs->info.width <= 0)
        return lm_fail(err, LM_ERR_INVALID_ARG, "rend_session_renderer: no image size yet (rend_session_resize)");
    if (!rs->frame[kind]) {
        int s = kind == REND_SESSION_FINAL ? rs->d.supersample : 1;
        lm_result r = make_context(rs, err);
        if (r != LM_OK) return r;
        if (kind == REND_SESSION_PREVIEW && rs->ahead) { /* made while the scene loaded */
            rend_frame *f = rs->ahead;
            rs->ahead = NULL;
            lm_error ignored;
            if (rend_frame_resize(f, rs->info.width, rs->info.height, &ignored) == LM_OK &&
                rend_frame_set_scene(f, rs->d.scene, &ignored) == LM_OK) {
                rs->frame[kind] = f;
                if (out) *out = f;
                return LM_OK;
            }
            rend_frame_destroy(f); /* made again below, whose error is reported */
        }
        const int one = kind == REND_SESSION_FINAL && rs->d.final_one_snapshot;
        r = rend_frame_create(rs->gl, &(rend_frame_desc){.scene = rs->d.scene, .width = rs->info.width,
                                                         .height = rs->info.height, .supersample = s,
                                                         .one_snapshot = one},
                              &rs->frame[kind], err);
        if (r != LM_OK) return r;
    }
    if (out) *out = rs->frame[kind];
    return LM_OK;
}

void rend_session_drop_renderer(rend_session *rs, rend_session_renderer_kind kind)
{
    if (!rs || (unsigned)kind >= REND_SESSION_RENDERER_COUNT) return;
    rend_frame_destroy(rs->frame[kind]);
    rs->frame[kind] = NULL;
}

static lm_result session_draw(rend_session *rs, rend_session_renderer_kind kind, const scene_camera *cam, float *rgb,
                              int add, lm_error *err)
{
    if (!cam) return lm_fail(err, LM_ERR_INVALID_ARG, "rend_session_draw: no camera");
    rend_frame *f;
    lm_result r = rend_session_renderer(rs, kind, &f, err);
    if (r != LM_OK) return r;
    r = add ? rend_frame_draw_adding(f, cam, rs->snap, rgb, err) : rend_frame_draw(f, cam, rs->snap, rgb, err);
    rend_frame_get_times(f, &rs->info.times[kind]);
    rs->info.draws[kind]++;
    return r;
}

lm_result rend_session_draw(rend_session *rs, rend_session_renderer_kind kind, const scene_camera *cam, float *rgb,
                            lm_error *err)
{
    return session_draw(rs, kind, cam, rgb, 0, err);
}

lm_result rend_session_draw_accumulated(rend_session *rs, rend_session_renderer_kind kind, const scene_camera *cam,
                                        int k, float *rgb, lm_error *err)
{
    if (!rgb) return lm_fail(err, LM_ERR_INVALID_ARG, "rend_session_draw_accumulated: no image to write");
    if (k <= 1) return rend_session_draw(rs, kind, cam, rgb, err);
    if (k > REND_SESSION_ACCUMULATE_MAX) k = REND_SESSION_ACCUMULATE_MAX;
    rend_frame *f;
    lm_result r = rend_session_renderer(rs, kind, &f, err);
    if (r != LM_OK) return r;
    size_t n = (size_t)rs->info.width * (size_t)rs->info.height * 3;
    const int s = rend_frame_get_supersample(f);
    double sum_seconds = 0.0;
    for (int i = 0; r == LM_OK && i < k * k; ++i) { /* each draw added to rgb as it is read */
        float jx, jy;
        rend_frame_jitter_pattern(i, k, s, &jx, &jy);
        rend_frame_set_jitter(f, jx, jy);
        r = session_draw(rs, kind, cam, rgb, i > 0, err);
        sum_seconds += rs->info.times[kind].total;
    }
    rend_frame_set_jitter(f, 0.0f, 0.0f);
    const float scale = 1.0f / (float)(k * k);
    for (size_t j = 0; r == LM_OK && j < n; ++j) rgb[j] *= scale;
    rs->info.times[kind].total = sum_seconds;
    return r;
}

void rend_session_get_info(const rend_session *rs, rend_session_info *out)
{
    if (!out) return;
    if (!rs) {
        memset(out, 0, sizeof *out);
        return;
    }
    *out = rs->info;
}

cache_worker *rend_session_worker(rend_session *rs)
{
    return rs ? rs->wk : NULL;
}

const GladGLContext *rend_session_gl(const rend_session *rs)
{
    return rs ? rs->gl : NULL;
}
