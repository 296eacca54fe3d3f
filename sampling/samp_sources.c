/* samp_sources.c — where indirect light comes from (samp_indirect_sources,
 * samp.h): per receiver, the fraction of its cosine-weighted hemisphere that
 * each triangle of a radiance mesh fills, by Embree rays on the shared scene.
 * The cache weighs the refinement of its indirect source by these fractions
 * (importance, Smits et al. 1992; docs/cache.md), whichever back end gathers.
 *
 * The rays are the gather's own estimator (samp_embree.c): k×k strata,
 * cosine-weighted, a hit on a back or nothing counting nothing, so that the
 * fractions w_t satisfy E_i ≈ π·Σ_t w_t·L̄_t with the same rays. Random streams
 * are keyed by the point (samp_point_hash) and a stream of their own.
 * samp_surface_hits_trace records the same rays' hits themselves (triangle and
 * barycentric) for the cache's further bounces, on a stream of its own.
 * Threads: the points are spread over the sampler's threads; each writes its own
 * slots of the output only. */
#include <math.h>
#include <stdlib.h>

#include "sampling/samp_internal.h"
#include "src/base/parallel.h"

typedef struct sources_job {
    const scene *s;
    const rt_scene *rt;
    const samp_radiance_mesh *mesh;
    const samp_radiance_index *index;
    const samp_point *pts;
    const samp_source_hits *out;
    uint32_t seed;
    int k; /* strata per side: k² ≤ rays */
} sources_job;

float samp_guide_mass(const float *stratum, int k, int a, int b)
{
    float m = 0.0f;
    for (int db = -1; db <= 1; ++db)
        for (int da = -1; da <= 1; ++da) {
            const int aa = a + da, bb = b + db;
            if (aa >= 0 && aa < k && bb >= 0 && bb < k && isfinite(stratum[bb * k + aa]))
                m = fmaxf(m, stratum[bb * k + aa]);
        }
    return m;
}

static int cmp_u32(const void *a, const void *b)
{
    uint32_t x = *(const uint32_t *)a, y = *(const uint32_t *)b;
    return (x > y) - (x < y);
}

static void sources_one(void *user, uint32_t i)
{
    const sources_job *job = user;
    const samp_point *x = &job->pts[i];
    uint32_t *tri = job->out->tri + (size_t)i * job->out->rays;
    float *weight = job->out->weight + (size_t)i * job->out->rays;
    float origin[3];
    samp_point_origin(job->s, x, samp_point_eps_rt(job->rt, x), origin);
    samp_frame f = samp_frame_make(x->n);
    lm_rng g;
    lm_rng_seed(&g, job->seed, samp_point_hash(x), 0x50u);
    const int k = job->k;
    uint32_t hits = 0;
    double pair[3] = {0, 0, 0}, even[3] = {0, 0, 0}; /* collapsed strata: (L_a − L_(a+1))² summed */
    for (int b = 0; b < k; ++b)
        for (int a = 0; a < k; ++a) {
            float L[3] = {0, 0, 0};
            rt_hit h;
            if (samp_stratum_front_hit(job->s, job->rt, &f, origin, &g, a, b, k, &h)) {
                uint32_t at = samp_radiance_at(job->mesh, job->index, h.tri, h.u, h.v, L);
                if (at != UINT32_MAX) tri[hits++] = at;
                else L[0] = L[1] = L[2] = 0.0f;
            }
            if (job->out->stratum)
                job->out->stratum[(size_t)i * job->out->rays + (size_t)(b * k + a)] =
                    (float)(M_PI * ((double)L[0] + L[1] + L[2]) / 3.0);
            for (int c = 0; c < 3; ++c) {
                double piL = M_PI * (double)L[c];
                if (a % 2 == 0)
                    even[c] = piL;
                else
                    pair[c] += (piL - even[c]) * (piL - even[c]);
            }
        }
    if (job->out->strat_var) {
        /* Var of the stratified mean ≈ Σ_pairs (L_a − L_b)² / N² (an unpaired last
         * column, k odd, is left out); N times that. */
        double N = (double)(k - k % 2) * k;
        for (int c = 0; c < 3; ++c)
            job->out->strat_var[3 * (size_t)i + (size_t)c] = N > 0.0 ? (float)(pair[c] / N) : 0.0f;
    }
    /* Runs of equal source triangles become one entry each. */
    qsort(tri, hits, sizeof *tri, cmp_u32);
    uint32_t count = 0;
    const float per_ray = 1.0f / (float)(k * k);
    for (uint32_t j = 0; j < hits; ++j) {
        if (count && tri[count - 1] == tri[j]) {
            weight[count - 1] += per_ray;
            continue;
        }
        tri[count] = tri[j];
        weight[count++] = per_ray;
    }
    job->out->count[i] = count;
}

void samp_sources_trace(const scene *s, const rt_scene *rt, uint32_t seed, int threads, const samp_radiance_mesh *mesh,
                        const samp_point *pts, uint32_t n, const samp_source_hits *out)
{
    samp_radiance_index ix = {0};
    if (!mesh->index) samp_radiance_index_build(s, mesh, &ix); /* without it (no memory): linear search */
    int k = (int)floor(sqrt((double)out->rays));
    sources_job job = {.s = s, .rt = rt, .mesh = mesh, .index = mesh->index ? mesh->index : &ix, .pts = pts, .out = out, .seed = seed,
                       .k = k < 1 ? 1 : k};
    lm_parallel_for(lm_thread_count(threads), n, sources_one, &job);
    samp_radiance_index_free(&ix);
}

typedef struct hits_job {
    const scene *s;
    const rt_scene *rt;
    const samp_point *pts;
    const samp_surface_hits *out;
    uint32_t seed;
    int k;
} hits_job;

static void hits_one(void *user, uint32_t i)
{
    const hits_job *job = user;
    const samp_point *x = &job->pts[i];
    uint32_t *tri = job->out->tri + (size_t)i * job->out->rays;
    float *bary = job->out->bary + 2 * (size_t)i * job->out->rays;
    float origin[3];
    samp_point_origin(job->s, x, samp_point_eps_rt(job->rt, x), origin);
    samp_frame f = samp_frame_make(x->n);
    lm_rng g;
    lm_rng_seed(&g, job->seed, samp_point_hash(x), 0xb0u);
    const int k = job->k;
    uint32_t hits = 0;
    for (int b = 0; b < k; ++b)
        for (int a = 0; a < k; ++a) {
            rt_hit h;
            if (!samp_stratum_front_hit(job->s, job->rt, &f, origin, &g, a, b, k, &h)) continue;
            if (job->out->keep && !job->out->keep(job->s, h.tri, job->out->keep_user)) continue;
            tri[hits] = h.tri;
            bary[2 * hits] = h.u;
            bary[2 * hits + 1] = h.v;
            hits++;
        }
    job->out->count[i] = hits;
}

void samp_surface_hits_run(const scene *s, const rt_scene *rt, uint32_t seed, int threads, const samp_point *pts,
                           uint32_t n, const samp_surface_hits *out)
{
    int k = (int)floor(sqrt((double)out->rays));
    hits_job job = {.s = s, .rt = rt, .pts = pts, .out = out, .seed = seed,
                    .k = k < 1 ? 1 : k};
    lm_parallel_for(lm_thread_count(threads), n, hits_one, &job);
}
