/* cache_worker_test — the refinement worker (mesh/cache/cache_worker.c):
 *   - determinism: a worker with a leaf budget ends with the same statistics as
 *     the same refinement done synchronously, and its last snapshot holds as many
 *     triangles as the synchronous cache's leaves give;
 *   - pause: no commit while paused; resume: refinement goes on; a pause asked
 *     before the first snapshot holds the worker right after publishing it; a
 *     pause within a step cuts it short and publishes what it did;
 *   - a light edit through the worker: new values, no new light sample;
 *   - a camera move through the worker (set_view): the specular mesh starts again
 *     for the new eye (its values there change), the direct mesh keeps every node;
 *   - debug data switched on and off on a finished worker: published at once;
 *   - a new exposure: a converged worker refines again for it, and converges there;
 *   - AUTO: refinement starts with Embree and the calibration waits for the first
 *     convergence (with a JND floor), as the snapshots' sampler choice says; it
 *     leaves GL's costs in the per-machine record, and a record where GL cannot
 *     win skips it;
 *   - destroy while refining (a bigger scene): joins cleanly (ASan: nothing leaks).
 */
#define _POSIX_C_SOURCE 200809L /* clock_gettime */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "mesh/cache/cache.h"
#include "mesh/cache/cache_worker.h"
#include "sampling/samp.h"
#include "sampling/samp_record.h"
#include "tests/test_util.h"

static void sleep_ms(int ms)
{
    struct timespec t0, t1;
    clock_gettime(CLOCK_MONOTONIC, &t0);
    do { /* busy-free enough for a test: short polls of the monotonic clock */
        for (volatile int i = 0; i < 10000; ++i) {
        }
        clock_gettime(CLOCK_MONOTONIC, &t1);
    } while ((t1.tv_sec - t0.tv_sec) * 1000.0 + (t1.tv_nsec - t0.tv_nsec) / 1e6 < ms);
}

static scene *load_json(const char *name, const char *material)
{
    char obj[1024], text[1024];
    test_write_file("worker_plane.obj",
                    "v -2 0 -2\nv 2 0 -2\nv 2 0 2\nv -2 0 2\nf 1 4 3\nf 1 3 2\n"
                    "v -0.2 0.5 -0.2\nv 0.2 0.5 -0.2\nv 0.2 0.5 0.2\nv -0.2 0.5 0.2\nf 5 6 7\nf 5 7 8\n",
                    obj, sizeof obj);
    snprintf(text, sizeof text,
             "{\"meshes\": [{\"file\": \"worker_plane.obj\", \"material\": \"paint\"}],"
             " \"materials\": {\"paint\": %s},"
             " \"lights\": [{\"type\": \"quad\", \"corner\": [-0.5, 1, -0.5], \"edge1\": [1, 0, 0],"
             " \"edge2\": [0, 0, 1], \"radiance\": [5, 5, 5]}]}",
             material);
    return test_load_json(name, text);
}

/* Waits for a snapshot newer than generation gen (at most 10 s). */
static const cache_snapshot *wait_newer(cache_worker *w, uint64_t gen)
{
    double t0 = lm_now_seconds();
    const cache_snapshot *s = cache_worker_acquire(w);
    while ((!s || s->generation <= gen) && lm_now_seconds() - t0 < 10.0) {
        sleep_ms(5);
        s = cache_worker_acquire(w);
    }
    return s;
}

/* The specular value published at a corner at position p (first found), or -1. */
static float specular_at(const cache_snapshot *s, const float p[3])
{
    for (uint32_t i = 0; i < s->specular.vertex_count; ++i)
        if (memcmp(s->specular.vertices[i].position, p, 3 * sizeof(float)) == 0) return s->specular.vertices[i].value[0];
    return -1.0f;
}

static void test_set_view(const uint32_t *pixels)
{
    scene *s = load_json("worker_glossy.json", "{\"kd\": [0.5, 0.5, 0.5], \"ks\": [0.4, 0.4, 0.4], \"n\": 40}");
    if (!s) return;
    lm_error err;
    cache_worker *w = NULL;
    samp_desc sd = {.backend = SAMP_BACKEND_EMBREE, .seed = 2, .threads = 1};
    CHECK(cache_worker_create(&(cache_worker_desc){.scene = s, .sampler = sd, .pixels = pixels, .step_budget = 256,
                                                   .max_tested = 4000},
                              &w, &err) == LM_OK);
    const cache_snapshot *a = w ? test_wait_finished(w, 60.0) : NULL;
    CHECK(a && a->finished && a->specular.triangle_count > 0);
    if (a && a->specular.triangle_count > 0) {
        uint64_t nodes = a->stats.direct.mesh.nodes, gen = a->generation;
        const float corner[3] = {2.0f, 0.0f, 2.0f}; /* a corner of the plane: every specular mesh has it */
        float before = specular_at(a, corner);
        /* The eye moves to where the corner mirrors the light towards it: its value grows. */
        const float eye[3] = {3.0f * corner[0], 2.0f, 3.0f * corner[2]};
        CHECK(cache_worker_set_view(w, pixels, eye, &err) == LM_OK);
        const cache_snapshot *b = wait_newer(w, gen);
        float after = b ? specular_at(b, corner) : -1.0f;
        printf("set_view: specular at (%.1f, %.1f, %.1f) %.6f -> %.6f, direct nodes %llu -> %llu\n", corner[0],
               corner[1], corner[2], before, after, (unsigned long long)nodes,
               (unsigned long long)(b ? b->stats.direct.mesh.nodes : 0));
        CHECK(b && b->generation > gen);
        CHECK(after >= 0.0f && fabsf(after - before) > 1e-3f * fmaxf(before, after));
        CHECK(b && b->stats.direct.mesh.nodes >= nodes);
        float bad[3] = {NAN, 0, 0};
        CHECK(cache_worker_set_view(w, pixels, bad, &err) == LM_ERR_INVALID_ARG);
        /* A cache created at that eye (cache_desc.eye_set, what a front end rendering
         * another camera than the scene's first does) has the moved eye's value at
         * the corner from the start: a root corner's value is eq. 5 at that eye. */
        cache_worker *w2 = NULL;
        cache_desc at_eye = {.eye_set = 1, .eye = {eye[0], eye[1], eye[2]}};
        CHECK(cache_worker_create(&(cache_worker_desc){.scene = s, .sampler = sd, .pixels = pixels, .step_budget = 256,
                                                       .max_tested = 4000, .cache = at_eye},
                                  &w2, &err) == LM_OK);
        const cache_snapshot *c2 = w2 ? test_wait_finished(w2, 60.0) : NULL;
        float created = c2 ? specular_at(c2, corner) : -1.0f;
        printf("cache created at the moved eye: specular at the corner %.6f (after set_view %.6f)\n", created, after);
        CHECK(created >= 0.0f && fabsf(created - after) <= 1e-5f * fmaxf(after, 1e-3f));
        cache_worker_destroy(w2);
        at_eye.eye[0] = NAN;
        CHECK(cache_worker_create(&(cache_worker_desc){.scene = s, .sampler = sd, .pixels = pixels, .cache = at_eye},
                                  &w2, &err) == LM_OK);
        const cache_snapshot *bad_eye = w2 ? test_wait_finished(w2, 60.0) : NULL;
        CHECK(bad_eye && bad_eye->failed && strstr(bad_eye->error, "eye") != NULL);
        cache_worker_destroy(w2);
        /* Debug data on, then off: each a new snapshot, with and without corners. */
        const cache_snapshot *on = NULL, *off = NULL;
        if (b) {
            uint64_t g = b->generation;
            CHECK(b->direct.corners == NULL && b->lights == NULL);
            cache_worker_set_publish_debug(w, 1);
            on = wait_newer(w, g);
            int has = on && on->generation > g && on->direct.corners != NULL && on->light_mesh_count == 1;
            g = on ? on->generation : g;
            cache_worker_set_publish_debug(w, 0);
            off = wait_newer(w, g);
            int gone = off && off->generation > g && off->direct.corners == NULL && off->lights == NULL;
            printf("publish_debug on: corners %s; off again: corners %s\n", has ? "published" : "missing",
                   gone ? "gone" : "still there");
            CHECK(has);
            CHECK(gone);
        }
    }
    cache_worker_destroy(w);
    scene_destroy(s);
}

static scene *load(void) { return load_json("worker.json", "{\"kd\": [0.6, 0.6, 0.6]}"); }

/* A worker with AUTO at the cache's 2% and a JND floor of 1 (so that it refines on
 * past its first convergence, where the deferred calibration comes). */
static cache_worker *auto_worker(const scene *s, const uint32_t *pixels)
{
    lm_error err;
    cache_worker *w = NULL;
    CHECK(cache_worker_create(&(cache_worker_desc){.scene = s, .pixels = pixels, .jnd_floor = 1.0f,
                                                   .sampler = {.backend = SAMP_BACKEND_AUTO, .seed = 2, .threads = 1,
                                                               .direct_target_error = 0.02f,
                                                               .indirect_target_error = 0.02f}},
                              &w, &err) == LM_OK);
    return w;
}

/* Points a snapshot's samplers have served: the running one's and those it
 * replaced (cache_snapshot.retired), the quick start's apart. */
static uint64_t served_points(const cache_snapshot *snap)
{
    uint64_t n = snap->sampler.direct_samples + snap->sampler.indirect_samples;
    for (uint32_t i = 0; i < snap->retired_count; ++i)
        n += snap->retired[i].direct_samples + snap->retired[i].indirect_samples;
    return n;
}

/* AUTO (samp.h) with a JND floor: refinement starts at once with Embree (no
 * snapshot waits for a calibration), the calibration comes after the first
 * convergence, and the snapshots say so in their sampler's choice. */
static void test_auto_deferred(const scene *s, const uint32_t *pixels)
{
    static const char before[] = "auto: Embree with 576 gather rays until the first convergence, then at its defaults, "
                                 "calibrated then";
    cache_worker *w = auto_worker(s, pixels);
    const cache_snapshot *snap = NULL;
    uint64_t gen = 0, refined_before = 0, served = 0;
    int wrong_before = 0, calibrated = 0, first_owed = -1, served_fell = 0;
    double t0 = lm_now_seconds();
    while (w && lm_now_seconds() - t0 < 120.0) {
        snap = wait_newer(w, gen);
        if (!snap || snap->failed) break;
        gen = snap->generation;
        if (gen == 1) first_owed = (int)snap->owed; /* the quick start's: every value is gathered again */
        if (!snap->converged && snap->tested > 0) { /* refining, not yet converged: Embree, no calibration */
            refined_before = snap->tested;
            wrong_before += snap->sampler.backend != SAMP_BACKEND_EMBREE || strcmp(snap->sampler.choice, before) != 0;
        }
        calibrated |= strstr(snap->sampler.choice, "calibrated in") != NULL;
        /* Counted over the run: the start's sampler, replaced at the first
         * convergence, and the calibration's loser keep their points. */
        served_fell += served_points(snap) < served;
        served = served_points(snap);
        if (snap->finished) break;
    }
    printf("auto, deferred: %llu leaves tested before converging, with Embree; then: %s\n",
           (unsigned long long)refined_before, snap ? snap->sampler.choice : "(no snapshot)");
    CHECK(snap && snap->finished && !snap->failed && snap->jnd == 1.0f);
    printf("auto, deferred: the first snapshot owes %d\n", first_owed);
    CHECK_MSG(first_owed == -1 || first_owed == 1, "the first snapshot owes %d", first_owed);
    CHECK_MSG(snap && snap->owed == 0, "the finished snapshot owes %u", snap ? snap->owed : 0u);
    CHECK(refined_before > 0 && wrong_before == 0);
    CHECK_MSG(calibrated, "no calibration after converging: %s", snap ? snap->sampler.choice : "");
    printf("auto, deferred: %llu points served, %u samplers replaced; the count fell %d times\n",
           (unsigned long long)served, snap ? snap->retired_count : 0u, served_fell);
    CHECK_MSG(snap && snap->retired_count >= 1 && served_fell == 0,
              "the samplers' points fell %d times (%u replaced)", served_fell, snap ? snap->retired_count : 0u);
    cache_worker_destroy(w);
}

/* GL's costs kept per machine (sampling/samp_record.h) and the deferred
 * calibration: with a record whose GL costs no Embree sampler comes near, the
 * worker converges with Embree and calibrates nothing (its note says why, and no
 * GL context is made); with none, it calibrates as test_auto_deferred, and the
 * calibration leaves GL's costs in the record. */
static int auto_worker_calibrates(const scene *s, const uint32_t *pixels, char *note, size_t size)
{
    cache_worker *w = auto_worker(s, pixels);
    const cache_snapshot *snap = w ? test_wait_finished(w, 120.0) : NULL;
    CHECK(snap && snap->finished && !snap->failed);
    snprintf(note, size, "%s", snap ? snap->sampler.choice : "");
    int calibrated = snap && strstr(snap->sampler.choice, "calibrated in") != NULL;
    cache_worker_destroy(w);
    return calibrated;
}

static void test_auto_recorded(const scene *s, const uint32_t *pixels)
{
    char dir[1024], path[1100], note[512];
    snprintf(dir, sizeof dir, "%s/cache_worker_record", LUMESH_TMP_DIR);
    snprintf(path, sizeof path, "%s/gl-costs", dir);
    remove(path);
    setenv("LUMESH_CACHE_DIR", dir, 1);
    const samp_desc key = {.backend = SAMP_BACKEND_AUTO}; /* the worker's platform and resolutions */
    samp_record rec;
    CHECK(samp_record_get(&key, &rec) == 0);
    int calibrated = auto_worker_calibrates(s, pixels, note, sizeof note);
    int kept = samp_record_get(&key, &rec);
    printf("auto, no record: %s; then the record holds %.1f / %.1f us\n", calibrated ? "calibrated" : "not calibrated",
           rec.direct_us, rec.indirect_us);
    CHECK_MSG(calibrated, "no calibration without a record: %s", note);
    CHECK(kept == 1 && rec.direct_us > 0.0 && rec.indirect_us > 0.0);
    /* GL far slower than any Embree sampler: nothing to calibrate. */
    remove(path);
    samp_record_note(&key, 1e9, 1e9);
    calibrated = auto_worker_calibrates(s, pixels, note, sizeof note);
    printf("auto, GL's cheapest 1e9 us: %s\n", note);
    CHECK_MSG(!calibrated && strstr(note, "not calibrated") != NULL, "calibrated though GL cannot win: %s", note);
    remove(path);
    setenv("LUMESH_CACHE_DIR", "", 1);
}

/* The first image's call schedules the seen leaves only (cache_refine_desc.
 * seen_only) and the next call all of them again: here, where the first call's
 * budget goes to seen leaves anyway, the refinement tests as many leaves and
 * makes the same direct mesh as with the whole queue from the start. The
 * samples may differ a little (they do by 0.3% here): the second call's queue has
 * priorities made after the first call's splits, the other's were made before. */
static void test_seen_only_first(scene *s, const uint32_t *pixels)
{
    cache_stats st[2];
    uint64_t tested[2] = {0, 0};
    for (int k = 0; k < 2; ++k) {
        lm_error err;
        samp_sampler *sp = NULL;
        cache *c = NULL;
        CHECK(samp_create(&(samp_desc){.scene = s, .backend = SAMP_BACKEND_EMBREE, .seed = 2, .threads = 1}, &sp,
                          &err) == LM_OK);
        CHECK(cache_create(&(cache_desc){.scene = s, .sampler = sp}, &c, &err) == LM_OK);
        CHECK(cache_init_seen(c, pixels, &err) == LM_OK);
        cache_refine_result res = {0};
        CHECK(cache_refine(c, &(cache_refine_desc){.pixels = pixels, .budget = 64, .seen_only = k}, &res, &err) ==
              LM_OK);
        tested[k] = res.tested;
        for (int i = 0; i < 200 && res.remaining; ++i) {
            CHECK(cache_refine(c, &(cache_refine_desc){.pixels = pixels, .budget = 256}, &res, &err) == LM_OK);
            tested[k] += res.tested;
        }
        cache_get_stats(c, &st[k]);
        cache_destroy(c);
        samp_destroy(sp);
    }
    printf("seen-only first call: %llu / %llu leaves tested, direct nodes %zu / %zu, direct samples %llu / %llu, "
           "indirect samples %llu / %llu\n",
           (unsigned long long)tested[1], (unsigned long long)tested[0], (size_t)st[1].direct.mesh.nodes,
           (size_t)st[0].direct.mesh.nodes, (unsigned long long)st[1].direct.samples,
           (unsigned long long)st[0].direct.samples, (unsigned long long)st[1].indirect.samples,
           (unsigned long long)st[0].indirect.samples);
    CHECK(tested[1] == tested[0] && tested[0] > 64);
    CHECK(st[1].direct.mesh.nodes == st[0].direct.mesh.nodes);
    CHECK(fabs((double)st[1].direct.samples - (double)st[0].direct.samples) <= 0.01 * (double)st[0].direct.samples);
    CHECK(fabs((double)st[1].indirect.samples - (double)st[0].indirect.samples) <= 0.01 * (double)st[0].indirect.samples);
}

/* A new exposure through the worker (cache_worker_set_exposure): a worker that
 * converged at the scene's exposure and idles refines again for the colours
 * shown 3 stops brighter (the plane's dim outskirts come into view: cache_test's
 * exposure cases), its next snapshots' estimate is at that exposure, and it
 * converges there with more leaves tested. */
static void test_set_exposure(const scene *s)
{
    uint32_t *pixels = calloc(s->tri_count, sizeof *pixels);
    if (!pixels) return;
    pixels[0] = pixels[1] = 1000; /* a small view: the JND bounds the leaves (cache_test.c) */
    lm_error err;
    cache_worker *w = NULL;
    samp_desc sd = {.backend = SAMP_BACKEND_EMBREE, .seed = 2, .threads = 1};
    CHECK(cache_worker_create(&(cache_worker_desc){.scene = s, .sampler = sd, .pixels = pixels, .step_budget = 256},
                              &w, &err) == LM_OK);
    const cache_snapshot *a = w ? test_wait_finished(w, 60.0) : NULL;
    CHECK(a && a->finished && a->converged && a->estimate.exposure == s->exposure);
    if (a && a->finished) {
        const uint64_t tested = a->tested, gen = a->generation;
        const uint32_t leaves = a->stats.direct.mesh.leaves;
        CHECK(cache_worker_set_exposure(w, s->exposure + 3.0f, &err) == LM_OK);
        const cache_snapshot *b = wait_newer(w, gen);
        double t0 = lm_now_seconds();
        while (b && !b->finished && lm_now_seconds() - t0 < 60.0) b = wait_newer(w, b->generation);
        printf("set_exposure +3: %llu leaves tested -> %llu, direct leaves %u -> %u, estimate at %+g: mean ΔE %.3f "
               "(%s)\n",
               (unsigned long long)tested, (unsigned long long)(b ? b->tested : 0), leaves,
               b ? b->stats.direct.mesh.leaves : 0, b ? (double)b->estimate.exposure : 0.0,
               b ? b->estimate.mean : 0.0, b && b->converged ? "converged" : "not converged");
        CHECK(b && b->finished && b->converged && b->estimate.exposure == s->exposure + 3.0f);
        CHECK(b && b->tested > tested && b->stats.direct.mesh.leaves > leaves);
        CHECK(cache_worker_set_exposure(w, NAN, &err) == LM_ERR_INVALID_ARG);
    }
    cache_worker_destroy(w);
    free(pixels);
}

int main(void)
{
    scene *s = load();
    if (!s) return test_finish("cache_worker_test");
    /* Only the plane (triangles 0 and 1) is seen, 40,000 pixels each. */
    uint32_t *pixels = calloc(s->tri_count, sizeof *pixels);
    pixels[0] = pixels[1] = 40000;
    const uint64_t budget = 3000;
    samp_desc sd = {.backend = SAMP_BACKEND_EMBREE, .seed = 2, .threads = 1};
    lm_error err;

    /* The same refinement, synchronously. */
    samp_desc sd_sync = sd;
    sd_sync.scene = s;
    samp_sampler *sp = NULL;
    cache *c = NULL;
    CHECK(samp_create(&sd_sync, &sp, &err) == LM_OK);
    CHECK(cache_create(&(cache_desc){.scene = s, .sampler = sp}, &c, &err) == LM_OK);
    CHECK(cache_init_seen(c, pixels, &err) == LM_OK); /* as the worker starts: what is seen and reached */
    uint64_t tested = 0;
    while (tested < budget) {
        cache_refine_result res;
        uint32_t b = budget - tested < 512 ? (uint32_t)(budget - tested) : 512;
        CHECK(cache_refine(c, &(cache_refine_desc){.pixels = pixels, .budget = b}, &res, &err) == LM_OK);
        tested += res.tested;
        if (res.remaining == 0) break;
    }
    cache_stats sync;
    cache_get_stats(c, &sync);
    mesh_qmesh_tri *buf = NULL;
    size_t cap = 0, count = 0;
    CHECK(mesh_qmesh_leaf_triangles(cache_direct_mesh(c), &buf, &cap, &count, &err) == LM_OK);

    cache_worker *w = NULL;
    CHECK(cache_worker_create(&(cache_worker_desc){.scene = s, .sampler = sd, .pixels = pixels, .step_budget = 512,
                                                   .max_tested = budget},
                              &w, &err) == LM_OK);
    const cache_snapshot *snap = w ? test_wait_finished(w, 60.0) : NULL;
    CHECK(snap && snap->finished && !snap->failed);
    if (snap) {
        printf("worker: generation %llu, %llu leaves tested; direct samples %llu (synchronous %llu), light samples "
               "%llu (%llu), %u triangles published (%zu)\n",
               (unsigned long long)snap->generation, (unsigned long long)snap->tested,
               (unsigned long long)snap->stats.direct.samples, (unsigned long long)sync.direct.samples,
               (unsigned long long)snap->stats.lights[0].samples, (unsigned long long)sync.lights[0].samples,
               snap->direct.triangle_count, count);
        CHECK(snap->tested == tested);
        CHECK(snap->stats.direct.samples == sync.direct.samples);
        CHECK(snap->stats.lights[0].samples == sync.lights[0].samples);
        CHECK(snap->stats.direct.mesh.nodes == sync.direct.mesh.nodes);
        CHECK(snap->stats.indirect.mesh.leaves == sync.indirect.mesh.leaves);
        CHECK(snap->direct.triangle_count == count);
        int finite = 1;
        for (uint32_t i = 0; i < snap->direct.vertex_count; ++i)
            for (int k = 0; k < 3; ++k) finite &= isfinite(snap->direct.vertices[i].value[k]);
        CHECK(finite);
        /* Indexed: every index names a vertex, every vertex is used, in the
         * order of first use, and the corners are shared. */
        {
            const cache_snapshot_mesh *m = &snap->direct;
            uint32_t next = 0, bad = 0;
            for (uint32_t i = 0; i < 3 * m->triangle_count; ++i) {
                if (m->index[i] > next || m->index[i] >= m->vertex_count) ++bad;
                if (m->index[i] == next) ++next;
            }
            printf("direct snapshot: %u triangles, %u vertices (%.2f a triangle), %u bad indices\n",
                   m->triangle_count, m->vertex_count, (double)m->vertex_count / m->triangle_count, bad);
            CHECK(bad == 0 && next == m->vertex_count);
            CHECK(m->vertex_count < 2 * m->triangle_count);
        }

        /* Light edit through the worker: values change at once, no new light sample. */
        uint64_t gen = snap->generation, light_samples = snap->stats.lights[0].samples;
        uint32_t bright = 0; /* the brightest published corner, found again by position */
        for (uint32_t i = 1; i < snap->direct.vertex_count; ++i)
            if (snap->direct.vertices[i].value[0] > snap->direct.vertices[bright].value[0]) bright = i;
        float before = snap->direct.vertices[bright].value[0], where[3];
        memcpy(where, snap->direct.vertices[bright].position, sizeof where);
        const float half[3] = {2.5f, 2.5f, 2.5f};
        CHECK(cache_worker_set_light(w, 0, half, &err) == LM_OK);
        double t0 = lm_now_seconds();
        const cache_snapshot *edited = snap;
        while (edited->generation == gen && lm_now_seconds() - t0 < 10.0) {
            sleep_ms(5);
            edited = cache_worker_acquire(w);
        }
        float after = -1.0f;
        for (uint32_t i = 0; i < edited->direct.vertex_count && after < 0.0f; ++i)
            if (memcmp(edited->direct.vertices[i].position, where, sizeof where) == 0)
                after = edited->direct.vertices[i].value[0];
        printf("light edit (radiance halved): brightest value %.5f -> %.5f, light samples %llu -> %llu\n", before,
               after, (unsigned long long)light_samples, (unsigned long long)edited->stats.lights[0].samples);
        CHECK(edited->generation > gen);
        CHECK(before > 0.1f && fabsf(after - 0.5f * before) <= 1e-5f * before);
        CHECK(edited->stats.lights[0].samples == light_samples);
    }
    cache_worker_destroy(w);

    /* Pause and resume, then destroy mid-refinement, on the unlimited worker. */
    w = NULL;
    CHECK(cache_worker_create(&(cache_worker_desc){.scene = s, .sampler = sd, .pixels = pixels, .step_budget = 64},
                              &w, &err) == LM_OK);
    if (w) {
        while (!cache_worker_acquire(w)) sleep_ms(2);
        cache_worker_pause(w);
        uint64_t g0 = cache_worker_acquire(w)->generation;
        sleep_ms(200);
        uint64_t g1 = cache_worker_acquire(w)->generation;
        cache_worker_resume(w);
        double t0 = lm_now_seconds();
        uint64_t g2 = g1;
        while (g2 == g1 && lm_now_seconds() - t0 < 10.0) {
            sleep_ms(2);
            g2 = cache_worker_acquire(w)->generation;
        }
        printf("pause: generation %llu -> %llu over 200 ms paused; %llu after resume\n", (unsigned long long)g0,
               (unsigned long long)g1, (unsigned long long)g2);
        CHECK(g1 == g0);
        CHECK(g2 > g1);
        cache_worker_destroy(w); /* mid-refinement: must cancel and join */
    }
    /* Paused before its first snapshot (the viewer, to draw it with both cores):
     * the worker publishes it, then waits; the first refinement step comes only
     * after resume. */
    w = NULL;
    CHECK(cache_worker_create(&(cache_worker_desc){.scene = s, .sampler = sd, .pixels = pixels, .step_budget = 64},
                              &w, &err) == LM_OK);
    if (w) {
        cache_worker_request_pause(w);
        const cache_snapshot *first = NULL;
        double t0 = lm_now_seconds();
        while (!(first = cache_worker_acquire(w)) && lm_now_seconds() - t0 < 30.0) sleep_ms(2);
        CHECK(first != NULL);
        cache_worker_pause(w); /* returns once the worker is parked: at the first snapshot */
        uint64_t g0 = first ? first->generation : 0, t_first = first ? first->tested : 0;
        /* The first snapshot carries no error estimate (its leaves are untested);
         * it claims no convergence either. */
        CHECK(first && !first->estimate.measured && first->estimate.untested == 1.0 &&
              first->estimate.jnd > 0.0f && !cache_estimate_converged(&first->estimate));
        sleep_ms(200);
        const cache_snapshot *still = cache_worker_acquire(w);
        uint64_t g1 = still ? still->generation : 0;
        cache_worker_resume(w);
        uint64_t g2 = g1;
        t0 = lm_now_seconds();
        while (g2 == g1 && lm_now_seconds() - t0 < 10.0) {
            sleep_ms(2);
            g2 = cache_worker_acquire(w)->generation;
        }
        printf("paused before the first snapshot: generation %llu (%llu leaves tested) held over 200 ms (%llu); "
               "%llu after resume\n",
               (unsigned long long)g0, (unsigned long long)t_first, (unsigned long long)g1, (unsigned long long)g2);
        CHECK(g0 == 1 && g1 == g0);
        CHECK(g2 > g1);
        const cache_snapshot *next = cache_worker_acquire(w); /* the next step makes one */
        CHECK(next && next->generation > 1 && next->estimate.measured && next->estimate.pixels > 0.0);
        cache_worker_destroy(w);
    }
    /* A pause within a step cuts it short: with one step of any length (a budget
     * no refinement here reaches) the pause does not wait for it to end, and
     * the part done is published, not converged; refinement then goes on. */
    w = NULL;
    CHECK(cache_worker_create(&(cache_worker_desc){.scene = s, .sampler = sd, .pixels = pixels,
                                                   .step_budget = 1u << 30},
                              &w, &err) == LM_OK);
    if (w) {
        const cache_snapshot *first = NULL;
        double t0 = lm_now_seconds();
        while (!(first = cache_worker_acquire(w)) && lm_now_seconds() - t0 < 30.0) sleep_ms(1);
        const uint64_t t_first = first ? first->tested : 0, g_first = first ? first->generation : 0;
        cache_worker_pause(w);
        const cache_snapshot *cut = cache_worker_acquire(w);
        /* A pause that arrives before the worker has begun its step (a loaded
         * machine can run this thread first) parks it with nothing new to
         * publish: that pause was not within a step, so try again later. */
        for (int attempt = 1; attempt < 20 && cut && cut->generation == g_first; attempt++) {
            cache_worker_resume(w);
            sleep_ms(attempt);
            cache_worker_pause(w);
            cut = cache_worker_acquire(w);
        }
        const uint64_t g_cut = cut ? cut->generation : 0, t_cut = cut ? cut->tested : 0;
        const int cut_converged = cut ? cut->converged : 1;
        cache_worker_resume(w);
        uint64_t t_later = t_cut;
        t0 = lm_now_seconds();
        while (t_later == t_cut && lm_now_seconds() - t0 < 10.0) {
            sleep_ms(5);
            cache_worker_request_pause(w); /* each cut step is published ... */
            cache_worker_resume(w);        /* ... and the next goes on from it */
            t_later = cache_worker_acquire(w)->tested;
        }
        printf("a pause within one unbounded step: %llu leaves tested at the first snapshot, %llu when the pause "
               "returned (generation %llu -> %llu, %s), %llu later\n",
               (unsigned long long)t_first, (unsigned long long)t_cut, (unsigned long long)g_first,
               (unsigned long long)g_cut, cut_converged ? "converged" : "not converged", (unsigned long long)t_later);
        /* The step has no leaf budget, so a step that ran to its end would have
         * converged: a pause that waited for it could not return unconverged.
         * (No bound on the leaves tested before the pause: that is timing.) */
        CHECK(g_cut > g_first && !cut_converged);
        CHECK(t_later > t_cut);
        cache_worker_destroy(w);
    }
    /* Retired mid-refinement: the snapshot held keeps its bytes (ASan would see a
     * freed one), nothing newer comes, and edits, pauses and destroy still work. */
    w = NULL;
    CHECK(cache_worker_create(&(cache_worker_desc){.scene = s, .sampler = sd, .pixels = pixels, .step_budget = 64},
                              &w, &err) == LM_OK);
    if (w) {
        const cache_snapshot *held = NULL;
        while (!(held = cache_worker_acquire(w)) || held->direct.triangle_count == 0) sleep_ms(2);
        cache_worker_retire(w);
        held = cache_worker_acquire(w); /* may hand over one committed before the retire */
        const uint64_t gen = held->generation;
        const size_t nb = (size_t)held->direct.vertex_count * sizeof *held->direct.vertices;
        void *copy = malloc(nb);
        if (copy) memcpy(copy, held->direct.vertices, nb);
        const float half[3] = {2.5f, 2.5f, 2.5f};
        CHECK(cache_worker_set_light(w, 0, half, &err) == LM_OK);
        cache_worker_pause(w);
        cache_worker_resume(w);
        sleep_ms(100);
        const cache_snapshot *later = cache_worker_acquire(w);
        printf("retired at generation %llu (%u direct triangles); after an edit and 100 ms: generation %llu\n",
               (unsigned long long)gen, held->direct.triangle_count, (unsigned long long)later->generation);
        CHECK(later == held && later->generation == gen);
        CHECK(copy && memcmp(copy, later->direct.vertices, nb) == 0);
        free(copy);
        cache_worker_retire(w); /* twice: a no-op */
        cache_worker_destroy(w);
    }
    cache_worker_retire(NULL);
    test_seen_only_first(s, pixels);
    test_set_view(pixels);
    test_auto_deferred(s, pixels);
    test_auto_recorded(s, pixels);
    test_set_exposure(s);
    free(buf);
    free(pixels);
    cache_destroy(c);
    samp_destroy(sp);
    scene_destroy(s);
    return test_finish("cache_worker_test");
}
