/* bench_cache — the multi-mesh cache on a real scene: pixels per triangle from the
 * ID pass (640×480, the scene's first camera, EGL), then refinement until nothing
 * is left to test or the time budget is spent. Prints, per mesh, samples, values
 * served by interpolation, nodes, leaves and bytes, and the time taken.
 * usage: bench_cache [SCENE (default: CornellBox-Original)] [SECONDS (60)] [embree|gl|auto (auto)] */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cache.h"
#include "gl_context.h"
#include "rend_id.h"
#include "samp.h"

static void print_mesh(const char *name, const cache_mesh_stats *m)
{
    printf("  %-12s %9llu %12llu %9u %9u %10.1f\n", name, (unsigned long long)m->samples,
           (unsigned long long)m->interpolated, m->mesh.nodes, m->mesh.leaves, m->mesh.bytes / 1024.0);
}

int main(int argc, char **argv)
{
    char path[1024];
    if (argc > 1)
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
    cache *c;
    if (cache_create(&(cache_desc){.scene = s, .sampler = sp}, &c, &err) != LM_OK) {
        fprintf(stderr, "%s\n", err.msg);
        return 1;
    }
    double t0 = lm_now_seconds();
    lm_result r = cache_init(c, &err);
    double t_init = lm_now_seconds() - t0;
    cache_refine_result res = {0}, tot = {0};
    while (r == LM_OK && lm_now_seconds() - t0 < budget) {
        r = cache_refine(c, &(cache_refine_desc){.pixels = ids.pixels, .budget = 512}, &res, &err);
        tot.tested += res.tested;
        tot.split += res.split;
        tot.undone += res.undone;
        if (res.remaining == 0) break;
    }
    double t = lm_now_seconds() - t0;
    if (r != LM_OK) printf("refinement stopped: %s\n", err.msg);
    cache_stats st;
    cache_get_stats(c, &st);
    printf("coarse cache in %.3f s; refinement %s after %.2f s: %u leaves tested, %u splits kept, %u undone, %u left\n",
           t_init, res.remaining == 0 ? "converged" : "stopped", t, tot.tested, tot.split, tot.undone, res.remaining);
    printf("  %-12s %9s %12s %9s %9s %10s\n", "mesh", "samples", "interpolated", "nodes", "leaves", "KiB");
    print_mesh("direct", &st.direct);
    print_mesh("indirect", &st.indirect);
    for (uint32_t l = 0; l < st.light_count; ++l) {
        char name[32];
        snprintf(name, sizeof name, "light %u", l);
        print_mesh(name, &st.lights[l]);
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
