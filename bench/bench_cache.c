/* bench_cache — the multi-mesh cache on a real scene: pixels per triangle from the
 * ID pass (640×480, the scene's first camera, EGL), then refinement until nothing
 * is left to test or the time budget is spent. Prints, per mesh, samples, values
 * served by interpolation, nodes, leaves and bytes, and the time taken.
 * With "schedulers" last: the heap and the paper's randomized scheduler side by
 * side, the direct error against samples taken: mean ΔE of Le + kd·L_dd at 2000
 * visible points (random pixels, their primary-ray hits) against
 * (1/π)·Σ L_ℓ·G_ℓ from a 4096-ray Embree estimate there.
 * With "soak" last: refinement is kept running for SECONDS as an idle viewer would
 * (sleeping 100 ms whenever nothing is left to test), and the cache's memory is
 * printed every 10 s: it must plateau.
 * usage: bench_cache [SCENE (default: CornellBox-Original)] [SECONDS (60)] [embree|gl|auto (auto)] [schedulers|soak] */
#define _POSIX_C_SOURCE 200809L /* nanosleep */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <math.h>
#include <time.h>

#include "mesh/cache/cache.h"
#include "sampling/rt_scene.h"
#include "sampling/samp.h"
#include "src/base/rng.h"
#include "src/base/tonemap.h"
#include "src/base/vecmath.h"
#include "src/gpu/gl_context.h"
#include "src/render/rend_id.h"
#include "src/scene/camera.h"

static void print_mesh(const char *name, const cache_mesh_stats *m)
{
    printf("  %-12s %9llu %12llu %9u %9u %10.1f\n", name, (unsigned long long)m->samples,
           (unsigned long long)m->interpolated, m->mesh.nodes, m->mesh.leaves, m->mesh.bytes / 1024.0);
}

enum { PROBES = 2000 };

typedef struct probe {
    uint32_t tri;
    double w1, w2;
    float lab[3]; /* the reference colour */
} probe;

/* Random visible points: pixels of the id image, their primary-ray hits. */
static int make_probes(const scene *s, rend_id *ip, probe *pr, lm_error *err)
{
    static uint32_t ids[640 * 480];
    if (rend_id_read_image(ip, ids, err) != LM_OK) return 0;
    rt_scene *rt;
    samp_sampler *ref;
    if (rt_scene_create(&(rt_scene_desc){.scene = s}, &rt, err) != LM_OK) return 0;
    if (samp_create(&(samp_desc){.scene = s, .backend = SAMP_BACKEND_EMBREE, .direct_rays = 4096}, &ref, err) !=
        LM_OK)
        return 0;
    const scene_camera *cam = &s->cameras[0];
    lm_dvec3 pos = dv3_load(cam->position), fwd = dv3_normalize(dv3_sub(dv3_load(cam->target), pos));
    lm_dvec3 right = dv3_normalize(dv3_cross(fwd, dv3_load(cam->up))), up = dv3_cross(right, fwd);
    double ty = tan(0.5 * cam->fov_y_deg * M_PI / 180.0), tx = ty * 640.0 / 480.0;
    lm_rng g;
    lm_rng_seed(&g, 21, 0, 0);
    tm_desc tm = {.exposure = s->exposure};
    int n = 0;
    for (int tries = 0; n < PROBES && tries < 100 * PROBES; ++tries) {
        int px = (int)(lm_rng_float(&g) * 640) % 640, py = (int)(lm_rng_float(&g) * 480) % 480;
        if (!ids[py * 640 + px]) continue;
        double sx = 2.0 * (px + 0.5) / 640 - 1.0, sy = 1.0 - 2.0 * (py + 0.5) / 480;
        lm_dvec3 d = dv3_normalize(dv3_add(fwd, dv3_add(dv3_scale(right, sx * tx), dv3_scale(up, sy * ty))));
        float o[3] = {cam->position[0], cam->position[1], cam->position[2]}, df[3] = {(float)d.x, (float)d.y, (float)d.z};
        rt_hit h;
        if (!rt_intersect(rt, o, df, 0.0f, INFINITY, &h)) continue;
        const scene_material *m = &s->materials[s->tris[h.tri].material];
        if (s->tris[h.tri].light >= 0 || !(m->kd[0] + m->kd[1] + m->kd[2] > 0.0f)) continue;
        samp_point x = {.tri_plus_one = h.tri + 1};
        for (int k = 0; k < 3; ++k) {
            x.p[k] = (1 - h.u - h.v) * s->positions[3 * (size_t)s->tris[h.tri].v[0] + (size_t)k] +
                     h.u * s->positions[3 * (size_t)s->tris[h.tri].v[1] + (size_t)k] +
                     h.v * s->positions[3 * (size_t)s->tris[h.tri].v[2] + (size_t)k];
            x.n[k] = s->tri_normals[3 * (size_t)h.tri + (size_t)k];
        }
        double e[3] = {0, 0, 0};
        for (uint32_t l = 0; l < scene_light_count(s); ++l) {
            float G;
            samp_direct(ref, l, &x, 1, &G, err);
            const float *le = l < s->area_light_count ? s->area_lights[l].le
                                                      : s->point_lights[l - s->area_light_count].intensity;
            for (int k = 0; k < 3; ++k) e[k] += le[k] * G;
        }
        float rgb[3], disp[3];
        for (int k = 0; k < 3; ++k) rgb[k] = m->le[k] + m->kd[k] * (float)(e[k] / M_PI);
        tm_to_display(&tm, rgb, disp);
        pr[n] = (probe){.tri = h.tri, .w1 = h.u, .w2 = h.v};
        tm_display_to_lab(disp, pr[n].lab);
        n++;
    }
    samp_destroy(ref);
    rt_scene_destroy(rt);
    return n;
}

static double probe_error(const scene *s, const cache *c, const probe *pr, int n)
{
    tm_desc tm = {.exposure = s->exposure};
    double sum = 0.0;
    lm_error err;
    for (int i = 0; i < n; ++i) {
        float L[3], rgb[3], disp[3], lab[3];
        if (cache_eval_direct(c, pr[i].tri, pr[i].w1, pr[i].w2, L, &err) != LM_OK) continue;
        const scene_material *m = &s->materials[s->tris[pr[i].tri].material];
        for (int k = 0; k < 3; ++k) rgb[k] = m->le[k] + m->kd[k] * L[k];
        tm_to_display(&tm, rgb, disp);
        tm_display_to_lab(disp, lab);
        sum += tm_delta_e(lab, pr[i].lab);
    }
    return sum / n;
}

static void compare_schedulers(const scene *s, samp_sampler *sp, rend_id *ip, const uint32_t *pixels)
{
    static probe pr[PROBES];
    lm_error err;
    int n = make_probes(s, ip, pr, &err);
    printf("schedulers: direct error at %d visible points (mean ΔE against a 4096-ray Embree) against samples taken\n",
           n);
    printf("  %-8s %10s %12s %12s %12s %10s\n", "", "tested", "light samp.", "indir. samp.", "direct vals", "mean ΔE");
    /* heap, random, and the single-mesh ablation (heap) */
    for (int sched = 0; sched < CACHE_SCHED_COUNT + 1; ++sched) {
        cache *c;
        int single = sched == CACHE_SCHED_COUNT;
        cache_desc cd = {.scene = s, .sampler = sp, .scheduler = single ? CACHE_SCHED_HEAP : (cache_scheduler)sched,
                         .seed = 1, .single_mesh = single};
        if (cache_create(&cd, &c, &err) != LM_OK || cache_init(c, &err) != LM_OK) {
            fprintf(stderr, "%s\n", err.msg);
            return;
        }
        uint32_t tested = 0;
        printf("  %-8s %10u %12s %12s %12s %10.3f  (coarse cache)\n",
               single ? "single" : sched == CACHE_SCHED_HEAP ? "heap" : "random", 0, "", "", "", probe_error(s, c, pr, n));
        for (int step = 0; step < 40; ++step) {
            cache_refine_result res;
            if (cache_refine(c, &(cache_refine_desc){.pixels = pixels, .budget = step < 8 ? 250 : 2000}, &res, &err) !=
                LM_OK)
                break;
            tested += res.tested;
            if (step % 2 == 1 || res.remaining == 0) {
                cache_stats st;
                cache_get_stats(c, &st);
                uint64_t ls = 0;
                for (uint32_t l = 0; l < st.light_count; ++l) ls += st.lights[l].samples;
                printf("  %-8s %10u %12llu %12llu %12llu %10.3f%s\n",
                       single ? "single" : sched == CACHE_SCHED_HEAP ? "heap" : "random", tested,
                       (unsigned long long)ls, (unsigned long long)st.indirect.samples,
                       (unsigned long long)st.direct.samples, probe_error(s, c, pr, n),
                       res.remaining == 0 ? "  (converged)" : "");
            }
            if (res.remaining == 0) break;
        }
        cache_destroy(c);
    }
}

int main(int argc, char **argv)
{
    char path[1024];
    if (argc > 1 && argv[1][0])
        snprintf(path, sizeof path, "%s", argv[1]);
    else
        snprintf(path, sizeof path, "%s/cornell-box/CornellBox-Original.obj", LUMESH_SCENES);
    double budget = argc > 2 ? atof(argv[2]) : 60.0;
    samp_backend backend = SAMP_BACKEND_AUTO;
    if (argc > 3 && !samp_backend_from_name(argv[3], &backend)) {
        fprintf(stderr, "unknown sampler '%s'\n", argv[3]);
        return 1;
    }
    scene *s;
    lm_error err;
    if (scene_load(&(scene_load_desc){.path = path, .require_light = 1}, &s, &err) != LM_OK) {
        fprintf(stderr, "%s\n", err.msg);
        return 1;
    }
    samp_sampler *sp;
    /* The cache's JND (ΔE 2) tolerates about 2% in a sample; auto picks the
     * cheaper back end at that error. */
    samp_desc sd = {.scene = s, .backend = backend, .direct_target_error = 0.02f, .indirect_target_error = 0.02f};
    if (samp_create(&sd, &sp, &err) != LM_OK) {
        fprintf(stderr, "%s\n", err.msg);
        return 1;
    }
    glctx *ctx;
    if (glctx_create(&(glctx_desc){0}, &ctx, &err) != LM_OK) {
        fprintf(stderr, "%s\n", err.msg);
        return 1;
    }
    rend_id *ip;
    rend_id_result ids;
    if (rend_id_create(glctx_gl(ctx), &(rend_id_desc){.scene = s, .width = 640, .height = 480}, &ip, &err) != LM_OK ||
        rend_id_render(ip, &s->cameras[0], &ids, &err) != LM_OK) {
        fprintf(stderr, "%s\n", err.msg);
        return 1;
    }
    samp_stats ss;
    samp_get_stats(sp, &ss);
    printf("%s: %u triangles, %u visible at 640x480; sampler: direct %s, indirect %s\n  %s\n", path, s->tri_count,
           ids.visible_count, ss.backend_name, ss.indirect_backend_name, ss.choice);
    if (argc > 4 && strcmp(argv[4], "schedulers") == 0) {
        compare_schedulers(s, sp, ip, ids.pixels);
        rend_id_destroy(ip);
        glctx_destroy(ctx);
        samp_destroy(sp);
        scene_destroy(s);
        return 0;
    }
    cache *c;
    if (cache_create(&(cache_desc){.scene = s, .sampler = sp}, &c, &err) != LM_OK) {
        fprintf(stderr, "%s\n", err.msg);
        return 1;
    }
    int soak = argc > 4 && strcmp(argv[4], "soak") == 0;
    double t0 = lm_now_seconds(), next_report = 0.0;
    lm_result r = cache_init(c, &err);
    double t_init = lm_now_seconds() - t0;
    cache_refine_result res = {0}, tot = {0};
    if (soak) printf("soak: %.0f s of idle refinement, memory every 10 s\n  %8s %12s %10s %10s\n", budget, "t (s)",
                     "cache KiB", "leaves", "tested");
    while (r == LM_OK && lm_now_seconds() - t0 < budget) {
        r = cache_refine(c, &(cache_refine_desc){.pixels = ids.pixels, .budget = 512}, &res, &err);
        tot.tested += res.tested;
        tot.split += res.split;
        tot.undone += res.undone;
        if (soak && lm_now_seconds() - t0 >= next_report) {
            cache_stats st;
            cache_get_stats(c, &st);
            printf("  %8.0f %12.1f %10u %10u\n", lm_now_seconds() - t0, st.bytes / 1024.0, st.direct.mesh.leaves,
                   tot.tested);
            fflush(stdout);
            next_report += 10.0;
        }
        if (res.remaining == 0) {
            if (!soak) break;
            nanosleep(&(struct timespec){.tv_nsec = 100000000}, NULL); /* idle: nothing to test */
        }
    }
    double t = lm_now_seconds() - t0;
    if (r != LM_OK) printf("refinement stopped: %s\n", err.msg);
    cache_stats st;
    cache_get_stats(c, &st);
    printf("coarse cache in %.3f s; refinement %s after %.2f s: %u leaves tested, %u splits kept, %u undone, %u left\n",
           t_init, res.remaining == 0 ? "converged" : "stopped", t, tot.tested, tot.split, tot.undone, res.remaining);
    printf("  %-12s %9s %12s %9s %9s %10s\n", "mesh", "samples", "interpolated", "nodes", "leaves", "KiB");
    printf("  light leaves falsified %llu (radiance values revised %llu); indirect values gathered again %llu\n",
           (unsigned long long)st.falsified, (unsigned long long)st.revised, (unsigned long long)st.regathered);
    print_mesh("direct", &st.direct);
    print_mesh("indirect", &st.indirect);
    if (cache_specular_mesh(c)) print_mesh("specular", &st.specular);
    for (uint32_t l = 0; l < st.light_count; ++l) {
        char name[32];
        snprintf(name, sizeof name, "light %u", l);
        print_mesh(name, &st.lights[l]);
    }
    /* A light edit: direct from the kept G (no sample), indirect gathered again. */
    if (st.light_count) {
        const float *le = s->area_light_count ? s->area_lights[0].le : s->point_lights[0].intensity;
        const float half[3] = {0.5f * le[0], 0.5f * le[1], 0.5f * le[2]};
        uint64_t ind0 = st.indirect.samples;
        double te = lm_now_seconds();
        if (cache_set_light(c, 0, half, &err) != LM_OK) fprintf(stderr, "%s\n", err.msg);
        te = lm_now_seconds() - te;
        cache_stats after;
        cache_get_stats(c, &after);
        printf("  light 0 halved: %.1f ms (direct from the kept G; %llu indirect vertices gathered again)\n", te * 1e3,
               (unsigned long long)(after.indirect.samples - ind0));
    }
    samp_get_stats(sp, &ss);
    printf("  sampler time: direct %.2f s for %llu samples, indirect %.2f s for %llu; total cache %.1f KiB\n",
           ss.direct_seconds, (unsigned long long)ss.direct_samples, ss.indirect_seconds,
           (unsigned long long)ss.indirect_samples, st.bytes / 1024.0);
    cache_destroy(c);
    rend_id_destroy(ip);
    glctx_destroy(ctx);
    samp_destroy(sp);
    scene_destroy(s);
    return 0;
}
