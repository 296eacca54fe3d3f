/* cache_worker.c — the refinement worker (cache_worker.h): its thread, and the
 * display's calls; filling and committing its snapshots: cache_worker_publish.c. */
#define _POSIX_C_SOURCE 200809L /* pthread_cond_timedwait, clock_gettime */
#include "mesh/cache/cache_worker.h"

#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "mesh/cache/cache_worker_internal.h"
#include "sampling/rt_scene.h"
#include "sampling/samp_record.h"

/* The error estimate walks every visible leaf (25 ms on CornellBox-Water, 110 ms
 * at 70k triangles): made again at most every ESTIMATE_SECONDS while refining, and
 * always when refinement stops (then it is the one cache_refine made for its
 * convergence claim, cache_refine_result.estimate, not made twice). */
#define ESTIMATE_SECONDS 0.5
/* Publish while refining once the time since the last snapshot is this many
 * times what it cost (worker_main): snapshots take at most a tenth of its time. */
#define PUBLISH_SHARE 9.0

/* ---- the worker thread ---------------------------------------------------------- */

/* The first snapshot as early as possible: the coarse cache is made with a quick
 * Embree sampler (no calibration, few gather rays), refined by first_budget
 * leaves, published, and only then is the sampler the client asked for made and
 * the coarse indirect gathered again with it. AUTO starts with Embree at its
 * defaults and calibrates after the first convergence (calibrate_now), so no
 * refinement waits for a calibration (issue 14; docs/renderer.md). */
static lm_result start_cache(cache_worker *w, samp_sampler **sp, cache **c, uint64_t *generation, publish_scratch *ps,
                             lm_error *err)
{
    samp_desc sd = w->desc.sampler;
    sd.scene = w->s;
    /* One Embree scene for every sampler this worker makes: each built its own
     * (the 116k box: 0.13-0.18 s and its memory again for the sampler after the
     * first image, and again for a calibration). */
    lm_result r = LM_OK;
    if (!sd.rt) r = rt_scene_create(&(rt_scene_desc){.scene = w->s}, &w->rt, err);
    if (!sd.rt) sd.rt = w->rt;
    samp_desc quick = {.scene = w->s, .backend = SAMP_BACKEND_EMBREE, .indirect_rays = CACHE_WORKER_QUICK_RAYS,
                       .threads = sd.threads, .seed = sd.seed, .rt = sd.rt};
    if (sd.backend == SAMP_BACKEND_EMBREE) { /* the same direct estimate: light samples are kept */
        quick.direct_rays = sd.direct_rays;
        quick.direct_control_variate = sd.direct_control_variate;
    }
    /* The sampler (and a GL context, if any) is made here: it belongs to this thread. */
    samp_sampler *first = NULL;
    if (r == LM_OK) r = samp_create(w->desc.no_quick_start ? &sd : &quick, &first, err);
    /* Bounces beyond the first come after the first image (with the sampler that
     * refines): their transport and the direct mesh they need cost CornellBox-
     * Original's first image 50 ms (0.075 -> 0.125 s; docs/cache.md "Bounces"). */
    const int later_bounces = !w->desc.no_quick_start && w->desc.cache.bounces != 0 && w->desc.cache.bounces != 1;
    if (r == LM_OK) {
        cache_desc cd = w->desc.cache;
        cd.scene = w->s;
        cd.sampler = first;
        cd.corner_ids = w->desc.whole_roots; /* made beside the first roots (make_corner_ids takes them) */
        if (later_bounces) cd.bounces = 1;
        /* The first image from a fixed budget of gathers; every value is gathered
         * right after it (cache_regather_indirect or cache_set_bounces, below). */
        if (!w->desc.no_quick_start) {
            cd.coarse_gathers = CACHE_WORKER_FIRST_GATHERS;
            cd.coarse_lights = CACHE_WORKER_FIRST_LIGHT_CORNERS;
        }
        r = cache_create(&cd, c, err);
    }
    /* Only what the camera sees and what gathers from it reach (issue 16). */
    if (r == LM_OK) r = cache_init_seen(*c, w->pixels, err);
    /* A few rounds before the first image, by the pixel counts given at creation
     * (measured in docs/renderer.md, "The first image"). */
    double t = lm_now_seconds();
    if (r == LM_OK && w->desc.first_budget && w->pixels) {
        cache_refine_result res;
        r = cache_refine(*c,
                         &(cache_refine_desc){.pixels = w->pixels, .budget = w->desc.first_budget, .seen_only = 1,
                                              .first_image = 1},
                         &res, err);
        if (r == LM_OK) w->first_tested = res.tested;
    }
    w->first_rounds_seconds = lm_now_seconds() - t;
    t = lm_now_seconds();
    pthread_mutex_lock(&w->lock);
    int debug = w->debug_wanted;
    pthread_mutex_unlock(&w->lock);
    /* No estimate in the first snapshot: its leaves are untested (the estimate
     * says little until they are: cache_estimate.untested), and making it came
     * before the first image (Water: 8 ms of its ~100). The next step makes it
     * (estimate_at 0: ESTIMATE_SECONDS have passed). */
    if (r == LM_OK)
        w->estimate = (cache_estimate){.untested = 1.0, .jnd = cache_get_jnd(*c), .exposure = cache_get_exposure(*c)};
    w->estimate_at = 0.0;
    if (r == LM_OK)
        r = cache_publish_snapshot(w, *c, &w->estimate, debug, ++*generation, w->first_tested, 0, ps, err);
    if (r == LM_OK) samp_get_stats(first, &w->back->snap.sampler);
    w->back->snap.owed = w->desc.no_quick_start ? 0 : 1; /* every value is gathered again next */
    w->first_publish_seconds = lm_now_seconds() - t;
    if (r == LM_OK) cache_publish_commit(w);
    /* A client that paused before it (the viewer, until it has drawn it) has the
     * cores while it draws the first image: what follows (the refining sampler,
     * a calibration, the first regathers) waits, as any step waits for a pause. */
    pthread_mutex_lock(&w->lock);
    while (r == LM_OK && w->paused && !w->cancel) {
        w->parked = 1;
        pthread_cond_broadcast(&w->cond);
        pthread_cond_wait(&w->cond, &w->lock);
    }
    w->parked = 0;
    pthread_mutex_unlock(&w->lock);
    if (r == LM_OK && !w->desc.no_quick_start) samp_get_stats(first, &w->quick_stats);
    if (w->desc.no_quick_start) {
        *sp = first;
        return r;
    }
    /* AUTO: refinement starts at once with Embree at its default ray counts (it
     * needs no calibration); the calibration comes once the cache has converged
     * (calibrate_later, below), so no refinement waits for it. */
    samp_desc start = sd;
    if (sd.backend == SAMP_BACKEND_AUTO) {
        start.backend = SAMP_BACKEND_EMBREE;
        w->calibrate_later = 1;
        /* Fewer rays a gather until the first convergence: the first image's
         * values are all gathered again now, and with Embree's 1,024 rays the
         * Veach door's picture stayed the quick start's until after 2 s in three
         * runs of five (docs/cache.md, "The refining sampler's plain count"). */
        if (!start.indirect_rays) {
            start.indirect_rays = CACHE_WORKER_START_RAYS;
            w->start_count = 1;
        }
        if (w->start_count)
            snprintf(w->start_phrase, sizeof w->start_phrase, "Embree with %d gather rays",
                     (int)CACHE_WORKER_START_RAYS);
        else
            snprintf(w->start_phrase, sizeof w->start_phrase, "Embree at its defaults");
        snprintf(w->calibration_note, sizeof w->calibration_note,
                 "auto: %s until the first convergence, then at its defaults, calibrated then", w->start_phrase);
    }
    if (r == LM_OK) r = samp_create(&start, sp, err);
    if (r == LM_OK) cache_set_sampler(*c, *sp);
    /* Every indirect value gathered again with it (the further bounces' source
     * with them, if they were put off). */
    if (r == LM_OK) r = later_bounces ? cache_set_bounces(*c, w->desc.cache.bounces, err) : cache_regather_indirect(*c, err);
    if (*c && r != LM_OK) cache_set_sampler(*c, NULL);
    samp_destroy(first);
    return r;
}

/* Takes the pixels set_pixels or set_view left, if any: the priorities follow
 * them, and the specular mesh the eye. */
static lm_result take_pixels(cache_worker *w, cache *c, int *taken, lm_error *err)
{
    pthread_mutex_lock(&w->lock);
    uint32_t *p = w->new_pixels;
    float eye[3];
    int eye_set = w->new_eye_set;
    memcpy(eye, w->new_eye, sizeof eye);
    w->new_pixels = NULL;
    w->new_eye_set = 0;
    pthread_mutex_unlock(&w->lock);
    *taken = p != NULL;
    if (!p) return LM_OK;
    free(w->pixels);
    w->pixels = p;
    lm_result r = eye_set ? cache_set_camera(c, eye, err) : LM_OK;
    return r == LM_OK ? cache_requeue(c, err) : r;
}

enum { CHECK_DIRECT_POINTS = 256, CHECK_INDIRECT_POINTS = 64 }; /* what the calibrated sampler serves before its check */
#define CHECK_SLOWER 1.5 /* slower than the fallback by more than this: back to the fallback */

static double cost_per_point(double seconds, uint64_t points) { return points ? seconds / (double)points : 0.0; }

/* GL's cheapest cost a point on this machine (samp_record.h; < 0: never
 * measured) against Embree's here (0: no such point sampled yet, nothing to win
 * there): GL cannot win when it is slower by CHECK_SLOWER, the margin by which
 * a calibrated choice is taken back (calibrated_check). */
static int gl_cannot_win(double gl_us, double embree_us)
{
    if (!(embree_us > 0.0)) return 1;
    return gl_us >= 0.0 && gl_us > CHECK_SLOWER * embree_us;
}

/* Adds a sampler's stats to a list: to the entry with the same back ends, else
 * as a new one (at most CACHE_SNAPSHOT_RETIRED: the worker replaces two). */
static void add_served(samp_stats *list, uint32_t *count, const samp_stats *st)
{
    for (uint32_t i = 0; i < *count; ++i) {
        samp_stats *r = &list[i];
        if (r->backend != st->backend || r->gl_platform != st->gl_platform ||
            r->indirect_backend != st->indirect_backend || r->indirect_gl_platform != st->indirect_gl_platform)
            continue;
        r->direct_samples += st->direct_samples, r->indirect_samples += st->indirect_samples;
        r->glossy_samples += st->glossy_samples;
        r->direct_seconds += st->direct_seconds, r->indirect_seconds += st->indirect_seconds;
        return;
    }
    if (*count < CACHE_SNAPSHOT_RETIRED) list[(*count)++] = *st;
}

/* Keeps what a refining sampler served before it is destroyed: the snapshots
 * report every sampler's points and seconds, not only the running one's (a
 * long run of the Veach door's --stats said 1,136 gathers, counted since the
 * first convergence). */
static void retire_sampler(cache_worker *w, const samp_sampler *sp)
{
    samp_stats st;
    samp_get_stats(sp, &st);
    add_served(w->retired, &w->retired_count, &st);
}

/* The snapshot's retired samplers: those replaced, and the Embree sampler on
 * hold while a calibrated one is on trial (calibrated_check), which served
 * until then (counted in w->retired when it is dropped). */
static void snap_retired(const cache_worker *w, cache_snapshot *snap)
{
    memcpy(snap->retired, w->retired, sizeof w->retired);
    snap->retired_count = w->retired_count;
    if (!w->fallback) return;
    samp_stats st;
    samp_get_stats(w->fallback, &st);
    add_served(snap->retired, &snap->retired_count, &st);
}

/* At the first convergence (AUTO, refining on past it): the start's plain count
 * gives way to Embree's default, which the deferred calibration then judges as
 * before; worker_main has the values gathered with the start's count gathered
 * again where the sampler kept takes more rays (Original's relMSE at 10 s was
 * 20% higher without). */
static lm_result leave_start_count(cache_worker *w, cache *c, samp_sampler **sp, lm_error *err)
{
    w->start_count = 0;
    samp_desc d = w->desc.sampler;
    d.scene = w->s;
    if (!d.rt) d.rt = w->rt;
    d.backend = SAMP_BACKEND_EMBREE;
    samp_sampler *next = NULL;
    lm_result r = samp_create(&d, &next, err);
    if (r != LM_OK) return r;
    cache_set_sampler(c, next);
    retire_sampler(w, *sp);
    samp_destroy(*sp);
    *sp = next;
    return LM_OK;
}

/* The deferred calibration (AUTO, at the first convergence): a calibrated sampler
 * that picks what the running Embree sampler is (both back ends Embree, the same
 * gather rays) is dropped; another replaces it, the Embree one kept as fallback.
 * None is made where GL's cheapest cost kept on this machine cannot beat what
 * Embree costs here (samp_record.h): no GL context, no calibration time. */
static void calibrate_now(cache_worker *w, cache *c, samp_sampler **sp)
{
    w->calibrate_later = 0;
    samp_desc sd = w->desc.sampler;
    sd.scene = w->s;
    if (!sd.rt) sd.rt = w->rt;
    samp_stats running;
    samp_get_stats(*sp, &running);
    const double embree_us[2] = {1e6 * cost_per_point(running.direct_seconds, running.direct_samples),
                                 1e6 * cost_per_point(running.indirect_seconds, running.indirect_samples)};
    samp_record kept;
    if (samp_record_get(&sd, &kept) && gl_cannot_win(kept.direct_us, embree_us[0]) &&
        gl_cannot_win(kept.indirect_us, embree_us[1])) {
        char path[512];
        samp_record_path(path, sizeof path);
        snprintf(w->calibration_note, sizeof w->calibration_note,
                 "auto: %.60s until the first convergence, then at its defaults, not calibrated: GL's cheapest on "
                 "this machine (%.1f / %.1f us a direct / indirect point, kept in %.200s) is over %.1fx Embree's here "
                 "(%.1f / %.1f): kept",
                 w->start_phrase, kept.direct_us, kept.indirect_us, path, CHECK_SLOWER, embree_us[0], embree_us[1]);
        return;
    }
    samp_sampler *cal = NULL;
    lm_error why;
    if (samp_create(&sd, &cal, &why) != LM_OK) { /* refinement goes on with what it has */
        snprintf(w->calibration_note, sizeof w->calibration_note,
                 "auto: %.60s until the first convergence, then at its defaults; the calibration failed (%.300s): kept",
                 w->start_phrase, why.msg);
        return;
    }
    samp_stats cs, run;
    samp_get_stats(cal, &cs);
    samp_get_stats(*sp, &run);
    if (cs.backend == SAMP_BACKEND_EMBREE && cs.indirect_backend == SAMP_BACKEND_EMBREE &&
        samp_indirect_rays(cal) == samp_indirect_rays(*sp)) {
        snprintf(w->calibration_note, sizeof w->calibration_note,
                 "auto: %.60s until the first convergence; then %.300s: the same, kept", w->start_phrase, cs.choice);
        samp_destroy(cal);
        return;
    }
    w->fallback = *sp;
    w->fallback_cost[0] = cost_per_point(run.direct_seconds, run.direct_samples);
    w->fallback_cost[1] = cost_per_point(run.indirect_seconds, run.indirect_samples);
    *sp = cal;
    cache_set_sampler(c, cal);
    snprintf(w->calibrated_choice, sizeof w->calibrated_choice, "%s", cs.choice);
    snprintf(w->calibration_note, sizeof w->calibration_note,
             "auto: %.60s until the first convergence; then %.300s: in use, on trial", w->start_phrase, cs.choice);
}

/* The calibrated sampler's cost on the cache's own samples against the Embree
 * sampler it replaced: a calibration timed under load may have picked a slower
 * back end (issue 14). Slower by CHECK_SLOWER: back to Embree. */
static void calibrated_check(cache_worker *w, cache *c, samp_sampler **sp)
{
    samp_stats st;
    samp_get_stats(*sp, &st);
    if (st.direct_samples < CHECK_DIRECT_POINTS && st.indirect_samples < CHECK_INDIRECT_POINTS) return;
    double now[2] = {cost_per_point(st.direct_seconds, st.direct_samples),
                     cost_per_point(st.indirect_seconds, st.indirect_samples)};
    int slower = 0;
    for (int k = 0; k < 2; ++k)
        slower |= now[k] > 0.0 && w->fallback_cost[k] > 0.0 && now[k] > CHECK_SLOWER * w->fallback_cost[k];
    snprintf(w->calibration_note, sizeof w->calibration_note,
             "auto: %.60s until the first convergence; then %.280s; on the cache's samples %.1f / "
             "%.1f us a direct / indirect point against Embree's %.1f / %.1f: %s",
             w->start_phrase, w->calibrated_choice, 1e6 * now[0], 1e6 * now[1], 1e6 * w->fallback_cost[0],
             1e6 * w->fallback_cost[1], slower ? "slower, back to Embree" : "kept");
    if (slower) {
        cache_set_sampler(c, w->fallback);
        retire_sampler(w, *sp);
        samp_destroy(*sp);
        *sp = w->fallback;
    } else {
        retire_sampler(w, w->fallback);
        samp_destroy(w->fallback);
    }
    w->fallback = NULL;
}

static void *worker_main(void *arg)
{
    cache_worker *w = arg;
    lm_error err = {{0}};
    samp_sampler *sp = NULL;
    cache *c = NULL;
    publish_scratch ps = {0};
    uint64_t generation = 0;
    lm_result r = start_cache(w, &sp, &c, &generation, &ps, &err);
    uint64_t tested = w->first_tested;
    uint32_t owed = 1; /* outdated indirect values left by the last refinement (unknown before it) */
    int idle = 0; /* converged or max_tested reached: wait for an edit */
    /* Never plateau (desc.jnd_floor): the cache's own JND, and whether it has
     * converged there since the last edit or view. */
    const float base_jnd = c ? cache_get_jnd(c) : 0.0f;
    int reached = 0;
    double reached_at = 0; /* when it first did (published with the snapshots) */
    while (r == LM_OK) {
        light_edit edits[MAX_EDITS];
        uint32_t nedit = 0;
        pthread_mutex_lock(&w->lock);
        for (;;) {
            if (w->cancel) break;
            nedit = w->edit_count;
            /* pixels_later: refinement waits for the first set_pixels (the coarse cache does not). */
            int no_pixels = w->desc.pixels_later && !w->pixels && !w->new_pixels;
            /* Paused or idle, an edit, a new view or a change of the debug data still
             * wakes the worker: it is applied and published without a refinement
             * step (a paused viewer shows it); idle, refinement then goes on for it. */
            if (((w->paused || idle) && nedit == 0 && !w->new_bounces && !w->new_exposure_set && !w->new_pixels &&
                 !w->republish) ||
                no_pixels) {
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
        int cancel = w->cancel, paused = w->paused, debug = w->debug_wanted, bounces = w->new_bounces;
        const int exposure_set = w->new_exposure_set;
        const float exposure = w->new_exposure;
        w->republish = 0;
        w->new_bounces = 0;
        w->new_exposure_set = 0;
        if (!cancel && nedit) {
            memcpy(edits, w->edits, nedit * sizeof *edits);
            w->edit_count = 0;
        }
        pthread_mutex_unlock(&w->lock);
        if (cancel) break;
        /* An edit sets a light's value outright: of several queued for one light only
         * the last counts (each costs a gather of the indirect mesh). */
        for (uint32_t i = 0; r == LM_OK && i < nedit; ++i) {
            int later = 0;
            for (uint32_t j = i + 1; j < nedit && !later; ++j) later = edits[j].light == edits[i].light;
            if (!later) r = cache_set_light(c, edits[i].light, edits[i].value, &err);
        }
        if (r == LM_OK && bounces) r = cache_set_bounces(c, bounces, &err);
        if (bounces) nedit++; /* an edit like a light's */
        /* A new exposure: the tests judge the colours shown from now on; like an
         * edit, refined to the cache's JND first (no sample is taken by it). */
        if (exposure_set && cache_get_exposure(c) != exposure) {
            if (r == LM_OK) r = cache_set_exposure(c, exposure, &err);
            nedit++;
        }
        int new_view = 0;
        if (r == LM_OK) r = take_pixels(w, c, &new_view, &err);
        if (r != LM_OK) break;
        if (nedit || new_view) {
            idle = reached = 0;
            /* What changed is refined to the cache's JND first, then tightened again. */
            if (r == LM_OK && cache_get_jnd(c) != base_jnd) r = cache_set_jnd(c, base_jnd, &err);
            if (r != LM_OK) break;
        }
        cache_refine_result res = {0};
        const uint32_t step = w->desc.step_budget ? w->desc.step_budget : 512;
        uint32_t budget = step;
        /* max_tested counts leaf tests; the values the first image borrowed are
         * owed to the coarse cache whatever it says (a budget of one while they
         * are: no leaf is tested until they are gathered). */
        if (w->desc.max_tested && tested + budget > w->desc.max_tested)
            budget = tested < w->desc.max_tested ? (uint32_t)(w->desc.max_tested - tested) : owed != 0;
        if (paused) budget = 0; /* an edit while paused: applied and published, nothing refined */
        if (budget)
            r = cache_refine(c,
                             &(cache_refine_desc){.pixels = w->pixels, .budget = budget,
                                                  .regather = CACHE_REGATHER_PER_LEAF * step, .stop = &w->interrupt},
                             &res, &err);
        if (r != LM_OK || atomic_load(&w->stop_now)) break; /* cancelled: no snapshot of a cut-short step */
        if (budget) owed = res.outdated;
        tested += res.tested;
        /* Converged: the cache's estimate says so (cache_estimate_converged); nothing
         * left to do without converging (stuck) idles too, and says so. After an edit
         * while paused nothing was tested: every leaf is queued again (not converged). */
        int converged_now = !paused && budget && res.converged;
        if (converged_now && !reached) reached_at = lm_now_seconds();
        reached |= converged_now;
        idle = (!paused && budget && (res.converged || res.stuck)) ||
               (w->desc.max_tested && tested >= w->desc.max_tested && !owed);
        /* Converged above the floor: half the JND, and on (the estimate and the
         * snapshot below are still the converged ones; the next step requeues). */
        float jnd = cache_get_jnd(c);
        int tighten = converged_now && !(w->desc.max_tested && tested >= w->desc.max_tested) &&
                      w->desc.jnd_floor > 0.0f && jnd > w->desc.jnd_floor;
        double now = lm_now_seconds();
        if (r == LM_OK && budget && res.estimated) { /* cache_refine made it for its claim: the same */
            w->estimate = res.estimate;
            w->estimate_at = now;
        } else if (r == LM_OK && (idle || nedit || new_view || now - w->estimate_at >= ESTIMATE_SECONDS)) {
            r = cache_estimate_error(c, w->pixels, &w->estimate, &err);
            w->estimate_at = now;
        }
        if (r == LM_OK && w->fallback) calibrated_check(w, c, &sp);
        /* A snapshot copies every mesh's leaves: on a 116k-triangle scene 0.1-0.2 s,
         * which after every step of cheap leaf tests was a fifth of the worker's
         * time. Between the snapshots that say something new (a stop, an edit, a
         * view, a convergence, debug data asked for) it publishes only once the
         * time since the last one is PUBLISH_SHARE times what that one cost:
         * every step on the Cornell boxes, about once a second there. A client
         * that paused meanwhile gets the step's snapshot (the viewer shows it). */
        pthread_mutex_lock(&w->lock);
        const int pausing = w->paused; /* a paused client shows the last step: it is published */
        pthread_mutex_unlock(&w->lock);
        const int publish = idle || tighten || converged_now || nedit || new_view || debug || pausing ||
                            generation < 2 || now - w->published_end >= PUBLISH_SHARE * w->publish_cost;
        if (r == LM_OK && publish) {
            const double t0 = lm_now_seconds();
            r = cache_publish_snapshot(w, c, &w->estimate, debug, ++generation, tested, reached, &ps, &err);
            w->back->snap.finished = idle && !tighten;
            w->back->snap.owed = owed;
            w->back->snap.converged_at = reached ? reached_at : 0;
            if (r == LM_OK) samp_get_stats(sp, &w->back->snap.sampler);
            if (r == LM_OK && w->calibration_note[0]) { /* AUTO, deferred: what happened, not "asked for" */
                samp_stats *ss = &w->back->snap.sampler;
                snprintf(ss->choice, sizeof ss->choice, "%s", w->calibration_note);
            }
            w->back->snap.quick_sampler = w->quick_stats;
            snap_retired(w, &w->back->snap);
            if (r == LM_OK) cache_publish_commit(w);
            w->published_end = lm_now_seconds();
            w->publish_cost = w->published_end - t0;
        } else if (r == LM_OK) {
            /* Not published: a pause that comes before the next step still gets it. */
            pthread_mutex_lock(&w->lock);
            w->republish = 1;
            pthread_mutex_unlock(&w->lock);
        }
        if (r == LM_OK && tighten) {
            r = cache_set_jnd(c, fmaxf(0.5f * jnd, w->desc.jnd_floor), &err);
            idle = 0;
        }
        /* After the snapshot of the first convergence, when refinement goes on past
         * it (tighten): AUTO's deferred calibration. A worker that stops there
         * never calibrates: the Embree sampler did the whole job. */
        if (r == LM_OK && w->calibrate_later && tighten) {
            const int from_start = w->start_count;
            if (from_start) r = leave_start_count(w, c, &sp, &err);
            if (r == LM_OK) calibrate_now(w, c, &sp);
            /* The values of the start's count gathered again where the sampler
             * now refining takes more rays (the calibration may pick fewer: Water's
             * 144, and those values are then the better ones). */
            if (r == LM_OK && from_start && samp_indirect_rays(sp) > CACHE_WORKER_START_RAYS)
                r = cache_outdate_plain(c, &err);
        }
    }
    if (r != LM_OK) cache_publish_failure(w, ++generation, err.msg);
    cache_publish_scratch_free(&ps);
    cache_destroy(c);
    samp_destroy(sp);
    samp_destroy(w->fallback);
    rt_scene_destroy(w->rt); /* after every sampler that used it */
    w->rt = NULL;
    pthread_mutex_lock(&w->lock);
    w->finished = 1;
    pthread_cond_broadcast(&w->cond);
    pthread_mutex_unlock(&w->lock);
    return NULL;
}

/* ---- display side ------------------------------------------------------------------ */

/* Cancels the refinement and joins the thread (once). */
static void stop_thread(cache_worker *w)
{
    if (!w->started || w->joined) return;
    atomic_store(&w->stop_now, 1);
    atomic_store(&w->interrupt, 1); /* the step in flight returns after its batch */
    pthread_mutex_lock(&w->lock);
    w->cancel = 1;
    pthread_cond_broadcast(&w->cond);
    pthread_mutex_unlock(&w->lock);
    pthread_join(w->thread, NULL);
    w->joined = 1;
}

void cache_worker_retire(cache_worker *w)
{
    if (!w) return;
    stop_thread(w);
    /* The slot the worker wrote into is never handed over now. */
    cache_publish_store_free(w->back);
    w->back = NULL;
}

void cache_worker_destroy(cache_worker *w)
{
    if (!w) return;
    if (w->started) {
        stop_thread(w);
        pthread_mutex_destroy(&w->lock);
        pthread_cond_destroy(&w->cond);
    }
    cache_publish_store_free(w->front);
    cache_publish_store_free(w->ready);
    cache_publish_store_free(w->back);
    free(w->pixels);
    free(w->new_pixels);
    free(w->corner_ids);
    free(w);
}

lm_result cache_worker_create(const cache_worker_desc *desc, cache_worker **out, lm_error *err)
{
    *out = NULL;
    if (!desc || !desc->scene) return lm_fail(err, LM_ERR_INVALID_ARG, "cache_worker: needs a scene");
    if (!(desc->jnd_floor >= 0.0f) || !isfinite(desc->jnd_floor))
        return lm_fail(err, LM_ERR_INVALID_ARG, "cache_worker: the JND floor must be a finite ΔE >= 0, not %g",
                       (double)desc->jnd_floor);
    cache_worker *w = calloc(1, sizeof *w);
    if (!w) return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory creating the refinement worker");
    w->desc = *desc;
    atomic_init(&w->stop_now, 0);
    atomic_init(&w->interrupt, 0);
    w->debug_wanted = desc->publish_debug != 0;
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
    atomic_store(&w->interrupt, 1); /* the step in flight ends after its batch or round, and is published */
    pthread_cond_broadcast(&w->cond);
    while (!w->parked && !w->finished) pthread_cond_wait(&w->cond, &w->lock);
    pthread_mutex_unlock(&w->lock);
}

void cache_worker_set_publish_debug(cache_worker *w, int on)
{
    pthread_mutex_lock(&w->lock);
    if (w->debug_wanted != (on != 0)) {
        w->debug_wanted = on != 0;
        w->republish = 1;
        pthread_cond_broadcast(&w->cond);
    }
    pthread_mutex_unlock(&w->lock);
}

void cache_worker_request_pause(cache_worker *w)
{
    pthread_mutex_lock(&w->lock);
    w->paused = 1;
    atomic_store(&w->interrupt, 1);
    pthread_cond_broadcast(&w->cond);
    pthread_mutex_unlock(&w->lock);
}

void cache_worker_resume(cache_worker *w)
{
    pthread_mutex_lock(&w->lock);
    w->paused = 0;
    if (!atomic_load(&w->stop_now)) atomic_store(&w->interrupt, 0);
    pthread_cond_broadcast(&w->cond);
    pthread_mutex_unlock(&w->lock);
}

lm_result cache_worker_set_light(cache_worker *w, uint32_t light, const float value[3], lm_error *err)
{
    if (light >= scene_light_count(w->s))
        return lm_fail(err, LM_ERR_INVALID_ARG, "cache_worker_set_light: light %u does not exist", light);
    pthread_mutex_lock(&w->lock);
    lm_result r = LM_OK;
    uint32_t pending = 0; /* a waiting edit of the same light is replaced (held keys, slow steps) */
    while (pending < w->edit_count && w->edits[pending].light != light) ++pending;
    if (pending < w->edit_count) {
        memcpy(w->edits[pending].value, value, sizeof w->edits[0].value);
        pthread_cond_broadcast(&w->cond);
    } else if (w->edit_count == MAX_EDITS) {
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

lm_result cache_worker_set_bounces(cache_worker *w, int bounces, lm_error *err)
{
    if (bounces != CACHE_BOUNCES_AUTO && (bounces < 1 || bounces > CACHE_BOUNCES_MAX))
        return lm_fail(err, LM_ERR_INVALID_ARG, "cache_worker_set_bounces: 1..%d or auto, not %d", CACHE_BOUNCES_MAX,
                       bounces);
    pthread_mutex_lock(&w->lock);
    w->new_bounces = bounces;
    pthread_cond_broadcast(&w->cond);
    pthread_mutex_unlock(&w->lock);
    return LM_OK;
}

lm_result cache_worker_set_exposure(cache_worker *w, float exposure, lm_error *err)
{
    if (!isfinite(exposure) || fabsf(exposure) > 64.0f)
        return lm_fail(err, LM_ERR_INVALID_ARG, "cache_worker_set_exposure: stops in [-64, 64], not %g",
                       (double)exposure);
    pthread_mutex_lock(&w->lock);
    w->new_exposure = exposure;
    w->new_exposure_set = 1;
    pthread_cond_broadcast(&w->cond);
    pthread_mutex_unlock(&w->lock);
    return LM_OK;
}

lm_result cache_worker_set_pixels(cache_worker *w, const uint32_t *pixels, lm_error *err)
{
    return cache_worker_set_view(w, pixels, NULL, err);
}

lm_result cache_worker_set_view(cache_worker *w, const uint32_t *pixels, const float eye[3], lm_error *err)
{
    if (eye && (!isfinite(eye[0]) || !isfinite(eye[1]) || !isfinite(eye[2])))
        return lm_fail(err, LM_ERR_INVALID_ARG, "cache_worker_set_view: the eye must be a finite point");
    uint32_t *p = malloc((w->s->tri_count ? w->s->tri_count : 1) * sizeof *p);
    if (!p) return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory for the pixel counts");
    memcpy(p, pixels, w->s->tri_count * sizeof *p);
    pthread_mutex_lock(&w->lock);
    free(w->new_pixels); /* a newer view replaces one the worker has not taken */
    w->new_pixels = p;
    if (eye) { /* an eye not taken yet stays when pixels alone follow */
        memcpy(w->new_eye, eye, sizeof w->new_eye);
        w->new_eye_set = 1;
    }
    pthread_cond_broadcast(&w->cond);
    pthread_mutex_unlock(&w->lock);
    return LM_OK;
}
