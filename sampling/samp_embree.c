/* samp_embree.c — the CPU back end of the samplers (samp.h), Embree 3 rays
 * (paper §5 names ray tracing as the alternative to hardware sampling; on a
 * machine without a GPU it is the one to beat).
 *
 * Direct: k×k stratified points on the light (uniform by area over its
 * triangles), weight w = cosθ_x·cosθ_y/r², one shadow ray each. With the control
 * variate (default) the estimate is
 *     G = G_unoccluded · Σ w·V / Σ w
 * with G_unoccluded from Lambert's formula (analytic.c): exact wherever the light
 * is fully visible or fully hidden, and in penumbra the error of the visible
 * fraction only. Without it, G = A/N·Σ w·V.
 * Indirect: k×k stratified cosine-weighted directions, E = π/N·Σ L(hit); L is
 * interpolated in the coarse radiance mesh's sub-triangle that contains the hit's
 * barycentrics (found through a grid per scene triangle, built per call). A ray
 * that leaves the scene, or meets the back of a surface, brings nothing. For a
 * receiver marked toward_source (samp.h), three quarters of the rays go instead to
 * points of the mesh picked by power and, with a guide (samp_guide), to the
 * strata of the receiver's pilot that saw light, combined with the cosine rays
 * by multiple importance sampling (indirect_one).
 *
 * Random numbers: a point's stream is seeded by (seed, light, the bits of its
 * position and normal), so a value depends on the point alone, not on the batch
 * it came in or the thread that computed it.
 * Threads: a batch is split over desc.threads workers (lm_parallel_for);
 * the caller's thread waits for them.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "sampling/ref_shading.h"
#include "sampling/samp_internal.h"
#include "src/base/parallel.h"
#include "src/base/vecmath.h"


typedef struct light_table {
    double *cdf;         /* per triangle of the light, cumulative area fraction; last = 1 */
    double area;         /* scene units² */
    /* A light made of two triangles that form a parallelogram (every quad light
     * of a JSON scene, the Cornell box's lamp) is sampled as one: corner + u·e1 +
     * v·e2, so the k×k strata are parallelograms on the light and a straight
     * shadow edge crosses about k of them (through the triangle parameterisation
     * it crosses about 2k, bent). */
    int parallelogram;
    lm_dvec3 corner, e1, e2;
    uint32_t tri;        /* either triangle: the normal */
} light_table;

typedef struct embree_impl {
    samp_desc desc;
    const scene *s;
    const rt_scene *rt;
    int threads;
    int direct_k, indirect_k; /* strata per side */
    light_table *lights;      /* per area light; read-only after creation */
} embree_impl;

/* ---- random streams -------------------------------------------------------- */

static void point_rng(const embree_impl *e, uint64_t stream, const samp_point *x, lm_rng *g)
{
    lm_rng_seed(g, e->desc.seed, samp_point_hash(x), stream);
}

/* ---- direct ---------------------------------------------------------------- */

/* Point on area light `li` for the unit-square sample (u, v); returns the triangle. */
static uint32_t light_point(const embree_impl *e, uint32_t li, double u, double v, lm_vec3 *y)
{
    const scene *s = e->s;
    const light_table *lt = &e->lights[li];
    if (lt->parallelogram) {
        lm_dvec3 p = dv3_add(lt->corner, dv3_add(dv3_scale(lt->e1, u), dv3_scale(lt->e2, v)));
        *y = v3((float)p.x, (float)p.y, (float)p.z);
        return lt->tri;
    }
    const scene_area_light *L = &s->area_lights[li];
    const double *cdf = e->lights[li].cdf;
    uint32_t lo = samp_cdf_pick(cdf, L->count, u);
    double start = lo ? cdf[lo - 1] : 0.0, width = cdf[lo] - start;
    double uu = width > 0.0 ? (u - start) / width : 0.5;
    uu = fmin(fmax(uu, 0.0), 1.0);
    uint32_t tri = s->light_tris[L->first + lo];
    const uint32_t *vi = s->tris[tri].v;
    double su = sqrt(uu), b0 = 1.0 - su, b1 = v * su, b2 = 1.0 - b0 - b1;
    lm_dvec3 a = dv3_load(s->positions + 3 * (size_t)vi[0]), b = dv3_load(s->positions + 3 * (size_t)vi[1]),
             c = dv3_load(s->positions + 3 * (size_t)vi[2]);
    lm_dvec3 p = dv3_add(dv3_add(dv3_scale(a, b0), dv3_scale(b, b1)), dv3_scale(c, b2));
    *y = v3((float)p.x, (float)p.y, (float)p.z);
    return tri;
}

static float direct_one(const embree_impl *e, uint32_t li, const samp_point *x)
{
    const scene *s = e->s;
    double g0 = samp_area_light_unoccluded(s, li, x->p, x->n);
    if (!(g0 > 0.0)) return 0.0f; /* behind the light or below the horizon: exactly 0 */
    float origin[3];
    const float eps = samp_point_eps_rt(e->rt, x);
    samp_point_origin(s, x, eps, origin);
    lm_vec3 o = v3_load(origin), nx = v3_load(x->n);
    lm_rng g;
    point_rng(e, 1u + li, x, &g);
    int k = e->direct_k;
    double sum_w = 0.0, sum_vis = 0.0;
    for (int j = 0; j < k; ++j)
        for (int i = 0; i < k; ++i) {
            double u = (i + lm_rng_float(&g)) / k, v = (j + lm_rng_float(&g)) / k;
            lm_vec3 y;
            uint32_t tri = light_point(e, li, u, v, &y);
            lm_vec3 ny = v3_load(s->tri_normals + 3 * (size_t)tri);
            lm_vec3 d = v3_sub(y, o);
            float r2 = v3_dot(d, d);
            if (!(r2 > 0.0f)) continue;
            float r = sqrtf(r2);
            float cx = v3_dot(nx, d) / r, cy = -v3_dot(ny, d) / r;
            if (cx <= 0.0f || cy <= 0.0f) continue;
            double w = (double)cx * cy / r2;
            sum_w += w;
            float yf[3], nyf[3];
            v3_store(yf, y);
            v3_store(nyf, ny);
            if (!rt_segment_occluded(e->rt, origin, NULL, yf, nyf, fmaxf(eps, rt_scene_tri_epsilon(e->rt, tri))))
                sum_vis += w;
        }
    double G;
    if (e->desc.direct_control_variate == SAMP_OFF)
        G = sum_vis * e->lights[li].area / ((double)k * k);
    else
        G = sum_w > 0.0 ? g0 * (sum_vis / sum_w) : 0.0;
    return isfinite(G) && G > 0.0 ? (float)G : 0.0f;
}

/* ---- indirect -------------------------------------------------------------- */

/* Accumulates one sample Y (RGB) of a strategy: sums and sums of squares. */
static void acc(double sum[3], double sum2[3], const float L[3], double scale)
{
    for (int c = 0; c < 3; ++c) {
        const double y = scale * L[c];
        sum[c] += y;
        sum2[c] += y * y;
    }
}

/* The guided picks of one point (samp_guide): over the pilot's k × k strata, the
 * cumulative share of each (last = 1) and its share × k² (the guided pdf over
 * the cosine pdf in that stratum: both map the stratum's square alike). */
typedef struct guide_picks {
    int k;
    double *cdf;
    float *ratio;
} guide_picks;

/* 0 (nothing held) when the row saw no light or memory ran out: the power picks
 * then, as without a guide. A stratum's mass is the brightest value the pilot saw
 * in it or its eight neighbours: one ray a stratum finds a gap's strata only where
 * it happened to pass, and the dilation covers the gap's edge around them. */
static int guide_picks_make(const samp_guide *gd, uint32_t row, guide_picks *out)
{
    memset(out, 0, sizeof *out);
    const int k = (int)lround(sqrt((double)gd->rays));
    const float *y = gd->stratum + (size_t)row * gd->rays;
    double *cdf = malloc((size_t)k * k * sizeof *cdf);
    float *ratio = malloc((size_t)k * k * sizeof *ratio);
    if (!cdf || !ratio) {
        free(cdf);
        free(ratio);
        return 0;
    }
    double total = 0.0;
    for (int b = 0; b < k; ++b)
        for (int a = 0; a < k; ++a) {
            total += samp_guide_mass(y, k, a, b);
            cdf[b * k + a] = total;
        }
    if (!(total > 0.0) || !isfinite(total)) {
        free(cdf);
        free(ratio);
        return 0;
    }
    double prev = 0.0;
    for (int q = 0; q < k * k; ++q) {
        ratio[q] = (float)((cdf[q] - prev) / total * k * k);
        prev = cdf[q];
        cdf[q] /= total;
    }
    cdf[k * k - 1] = 1.0;
    *out = (guide_picks){k, cdf, ratio};
    return 1;
}

/* p_guided / p_cosine at the unit-square sample (u, v) of samp_frame_cosine. */
static double guide_ratio(const guide_picks *g, float u, float v)
{
    int a = (int)(u * (float)g->k), b = (int)(v * (float)g->k);
    a = a < 0 ? 0 : a >= g->k ? g->k - 1 : a;
    b = b < 0 ? 0 : b >= g->k ? g->k - 1 : b;
    return g->ratio[b * g->k + a];
}

/* The unit-square sample (u, v) of samp_frame_cosine that gives direction d. */
static void frame_square(const samp_frame *f, lm_vec3 d, float *u, float *v)
{
    const float lx = v3_dot(d, f->t1), ly = v3_dot(d, f->t2);
    *u = fminf(lx * lx + ly * ly, 1.0f);
    float phi = atan2f(ly, lx) / (2.0f * (float)M_PI);
    *v = phi < 0.0f ? phi + 1.0f : phi;
}

/* The rays of one gather by strategy and what each strategy's pdf is at a
 * sample, for the balance heuristic: a sample of strategy q with integrand
 * f = L·cosθ_x is worth N_q·f / Σ_j N_j·p_j, averaged over strategy q's N_q. */
typedef struct mix {
    double N[3];         /* cosine, guided, by power */
    const guide_picks *gp; /* or NULL */
    const samp_radiance_index *ix;
} mix;

/* Σ_j N_j·p_j for a direction at cos_x from the normal and at the unit-square
 * sample (u, v), meeting radiance-mesh triangle sub (UINT32_MAX: none) at
 * distance t with cos_y there. */
static double mix_density(const mix *mx, double cos_x, float u, float v, uint32_t sub, double t, double cos_y)
{
    double d = mx->N[0] * cos_x / M_PI;
    if (mx->N[1] > 0.0) d += mx->N[1] * guide_ratio(mx->gp, u, v) * cos_x / M_PI;
    if (mx->N[2] > 0.0 && sub != UINT32_MAX && cos_y > 0.0) d += mx->N[2] * (double)mx->ix->pick_density[sub] * t * t / cos_y;
    return d;
}

/* One ray of strategy q along the unit-square sample (u, v) of frame f (a
 * cosine or a guided ray: both map the square alike), its balance-heuristic
 * sample added to sum[q], sum2[q]. A miss or a back brings nothing. */
static void mix_ray(const embree_impl *e, const samp_radiance_mesh *m, const mix *mx, const samp_frame *f,
                    const float origin[3], float u, float v, int q, double sum[3], double sum2[3])
{
    const scene *s = e->s;
    const lm_vec3 d = samp_frame_cosine(f, u, v);
    float dir[3];
    v3_store(dir, d);
    rt_hit h;
    if (!rt_intersect(e->rt, origin, dir, 0.0f, INFINITY, &h)) return;
    /* The back of a surface sends nothing: the mesh holds what leaves its front. */
    const float cos_y = -v3_dot(v3_load(s->tri_normals + 3 * (size_t)h.tri), d);
    if (!(cos_y > 0.0f)) return;
    float L[3];
    const uint32_t sub = samp_radiance_at(m, mx->ix, h.tri, h.u, h.v, L);
    const double cos_x = v3_dot(d, f->n);
    if (!(cos_x > 0.0)) return;
    acc(sum, sum2, L, mx->N[q] * cos_x / mix_density(mx, cos_x, u, v, sub, h.t, cos_y));
}

void samp_toward_split(int k, int guided, int by_power, int *kc, int *ng, int *npw)
{
    int c = guided || by_power ? (int)lround(k * sqrt(SAMP_TOWARD_COSINE_SHARE)) : k;
    c = c < 1 ? 1 : c;
    const int rest = k * k - c * c;
    *kc = c;
    *ng = guided ? (by_power ? (int)lround(rest * SAMP_TOWARD_GUIDED_SHARE) : rest) : 0;
    *npw = rest - *ng;
}

/* k×k rays a point from random stream `pass` (0: the plain gather's); std_err:
 * the standard error of E per channel, from each strategy's sample variance (the
 * strata ignored, so it errs high), or NULL.
 *
 * Up to three strategies, combined by the balance heuristic (Veach 1997, §9.2):
 * cosine-weighted rays in strata (pdf cosθ_x/π); for a receiver marked
 * toward_source, three quarters of the rays go elsewhere (SAMP_TOWARD_COSINE_SHARE):
 * with a guide (samp_guide), half of those to the strata where its pilot saw
 * light (pdf r_s·cosθ_x/π, r_s the stratum's share × k²) and half toward points
 * of the source picked by power
 * (the index's pick table: area density pick_density, pdf pick_density·r²/cosθ_y
 * in solid angle); without one, all of them by power. Light that comes through a
 * gap (a door ajar, the slot test's slit) is a few per cent of the hemisphere,
 * which cosine rays find by chance. The guided rays go where the pilot saw the
 * gap and none is lost to a wall, but a thin gap fills a stratum only in part;
 * the picks by power go to the bright source behind it, and count where the gap
 * lets them through: each covers the other's weakness (the slot test). Otherwise,
 * and without a pick table (the source sends nothing, or no memory), all rays are
 * cosine-weighted, E = π/N·Σ L(hit). */
static void indirect_one(const embree_impl *e, const samp_radiance_mesh *m, const samp_radiance_index *ix,
                         const samp_point *x, const samp_guide *gd, uint32_t row, int k, uint32_t pass, float E[3],
                         float *std_err)
{
    float origin[3];
    samp_point_origin(e->s, x, samp_point_eps_rt(e->rt, x), origin);
    samp_frame f = samp_frame_make(x->n);
    lm_rng g;
    point_rng(e, pass ? 0x1000000u + pass : 0, x, &g);
    const scene *s = e->s;
    guide_picks gp = {0};
    const int guided = x->toward_source && gd && guide_picks_make(gd, row, &gp);
    const int by_power = x->toward_source && ix->pick_cdf != NULL;
    int kc, ng, npw;
    samp_toward_split(k, guided, by_power, &kc, &ng, &npw);
    const mix mx = {{(double)kc * kc, ng, npw}, guided ? &gp : NULL, ix};
    double sum[3][3] = {{0}}, sum2[3][3] = {{0}};
    for (int j = 0; j < kc; ++j)
        for (int i = 0; i < kc; ++i) {
            const float u = (i + lm_rng_float(&g)) / kc, v = (j + lm_rng_float(&g)) / kc;
            mix_ray(e, m, &mx, &f, origin, u, v, 0, sum[0], sum2[0]);
        }
    for (int j = 0; j < ng; ++j) {
        /* A stratum of the pilot's grid by the guide, a point uniform in its square. */
        const double w = (j + lm_rng_float(&g)) / ng;
        const uint32_t q = samp_cdf_pick(gp.cdf, (uint32_t)(gp.k * gp.k), w < 1.0 ? w : 0.9999999999);
        const float u = ((float)(q % (uint32_t)gp.k) + lm_rng_float(&g)) / (float)gp.k;
        const float v = ((float)(q / (uint32_t)gp.k) + lm_rng_float(&g)) / (float)gp.k;
        mix_ray(e, m, &mx, &f, origin, u, v, 1, sum[1], sum2[1]);
    }
    for (int j = 0; j < npw; ++j) {
        const double u = (j + lm_rng_float(&g)) / npw;
        const float a = lm_rng_float(&g), b = lm_rng_float(&g);
        uint32_t t;
        float w1, w2;
        const uint32_t sub = samp_radiance_pick(s, m, ix, u < 1.0 ? u : 0.9999999999, a, b, &t, &w1, &w2);
        if (sub == UINT32_MAX) continue;
        const uint32_t *tv = s->tris[t].v;
        float y[3];
        for (int c = 0; c < 3; ++c)
            y[c] = (1.0f - w1 - w2) * s->positions[3 * (size_t)tv[0] + (size_t)c] +
                   w1 * s->positions[3 * (size_t)tv[1] + (size_t)c] + w2 * s->positions[3 * (size_t)tv[2] + (size_t)c];
        lm_vec3 d = v3_sub(v3_load(y), v3_load(origin));
        const float r = v3_length(d);
        if (!(r > 0.0f)) continue;
        d = v3_scale(d, 1.0f / r);
        const double cos_x = v3_dot(d, f.n), cos_y = -v3_dot(v3_load(s->tri_normals + 3 * (size_t)t), d);
        if (!(cos_x > 0.0) || !(cos_y > 0.0)) continue;
        /* Seen from x: the first hit along the way is the picked point (its
         * triangle, at its distance up to rounding). */
        float dir[3];
        v3_store(dir, d);
        rt_hit h;
        if (!rt_intersect(e->rt, origin, dir, 0.0f, INFINITY, &h) || h.tri != t || fabsf(h.t - r) > 1e-3f * r + 1e-5f)
            continue;
        float L[3];
        samp_radiance_at(m, ix, t, w1, w2, L);
        float us = 0.0f, vs = 0.0f;
        if (guided) frame_square(&f, d, &us, &vs);
        const double D = mix_density(&mx, cos_x, us, vs, sub, r, cos_y);
        acc(sum[2], sum2[2], L, mx.N[2] * cos_x / D);
    }
    for (int c = 0; c < 3; ++c) {
        double v = 0.0, var = 0.0;
        for (int q = 0; q < 3; ++q) {
            if (!(mx.N[q] > 0.0)) continue;
            const double mean = sum[q][c] / mx.N[q];
            v += mean;
            var += fmax(sum2[q][c] / mx.N[q] - mean * mean, 0.0) / (mx.N[q] > 1.0 ? mx.N[q] - 1.0 : 1.0);
        }
        E[c] = isfinite(v) ? (float)v : 0.0f;
        if (std_err) std_err[c] = isfinite(var) ? (float)sqrt(var) : 0.0f;
    }
    free(gp.cdf);
    free(gp.ratio);
}

/* ---- batches over threads ------------------------------------------------- */

typedef struct batch {
    const embree_impl *e;
    uint32_t light;                 /* direct */
    const samp_radiance_mesh *mesh; /* indirect when non-NULL */
    const samp_radiance_index *index;    /* its point location */
    const samp_point *pts;
    uint32_t n;
    float *out;
    float *std_err;                 /* indirect: per point RGB, or NULL */
    const samp_guide *guide;        /* indirect: or NULL */
    int k;                          /* indirect: strata per side */
    uint32_t pass;                  /* indirect: random stream */
} batch;

static void batch_one(void *user, uint32_t i)
{
    const batch *b = user;
    if (b->mesh)
        indirect_one(b->e, b->mesh, b->index, &b->pts[i], b->guide, b->guide && b->guide->index ? b->guide->index[i] : i,
                     b->k, b->pass, b->out + 3 * (size_t)i,
                     b->std_err ? b->std_err + 3 * (size_t)i : NULL);
    else
        b->out[i] = direct_one(b->e, b->light, &b->pts[i]);
}

static void run_batch(const embree_impl *e, batch *b) { lm_parallel_for(e->threads, b->n, batch_one, b); }

static lm_result embree_direct(void *impl, uint32_t light, const samp_point *pts, uint32_t n, float *G,
                               lm_error *err)
{
    (void)err;
    batch b = {.e = impl, .light = light, .pts = pts, .n = n, .out = G};
    run_batch(impl, &b);
    return LM_OK;
}

static lm_result embree_indirect_noise(void *impl, const samp_radiance_mesh *mesh, const samp_point *pts, uint32_t n,
                                       uint32_t pass, uint32_t scale, const samp_guide *guide, float *E,
                                       float *std_err, lm_error *err)
{
    (void)err;
    const embree_impl *e = impl;
    samp_radiance_index ix = {0};
    if (!mesh->index) samp_radiance_index_build(e->s, mesh, &ix); /* without it (no memory): linear search */
    int k = e->indirect_k * (int)ceil(sqrt((double)(scale ? scale : 1)) - 1e-9);
    batch b = {.e = impl, .mesh = mesh, .index = mesh->index ? mesh->index : &ix, .pts = pts, .n = n, .out = E,
               .std_err = std_err, .guide = guide, .k = k, .pass = pass};
    run_batch(impl, &b);
    samp_radiance_index_free(&ix);
    return LM_OK;
}

static lm_result embree_indirect(void *impl, const samp_radiance_mesh *mesh, const samp_point *pts, uint32_t n,
                                 float *E, lm_error *err)
{
    return embree_indirect_noise(impl, mesh, pts, n, 0, 1, NULL, E, NULL, err);
}

static uint32_t embree_indirect_rays(const void *impl)
{
    const embree_impl *e = impl;
    return (uint32_t)(e->indirect_k * e->indirect_k);
}

static void embree_destroy(void *impl)
{
    embree_impl *e = impl;
    if (!e) return;
    if (e->lights)
        for (uint32_t i = 0; i < e->s->area_light_count; ++i) free(e->lights[i].cdf);
    free(e->lights);
    free(e);
}

static const samp_backend_ops embree_ops = {
    .backend = SAMP_BACKEND_EMBREE, .name = "embree", .direct = embree_direct, .indirect = embree_indirect,
    .indirect_noise = embree_indirect_noise, .indirect_rays = embree_indirect_rays, .destroy = embree_destroy};

/* Two triangles sharing an edge whose four corners satisfy a + c = b + d (to
 * float rounding): record the parallelogram. */
static void detect_parallelogram(const scene *s, const scene_area_light *L, light_table *t)
{
    if (L->count != 2) return;
    const uint32_t *ta = s->tris[s->light_tris[L->first]].v, *tb = s->tris[s->light_tris[L->first + 1]].v;
    /* the vertex of b that is not in a */
    int extra = -1, shared = 0;
    for (int i = 0; i < 3; ++i) {
        int in_a = tb[i] == ta[0] || tb[i] == ta[1] || tb[i] == ta[2];
        shared += in_a;
        if (!in_a) extra = i;
    }
    if (shared != 2 || extra < 0) return;
    /* the vertex of a opposite the shared edge */
    int opp = -1;
    for (int i = 0; i < 3; ++i)
        if (ta[i] != tb[0] && ta[i] != tb[1] && ta[i] != tb[2]) opp = i;
    if (opp < 0) return;
    lm_dvec3 o = dv3_load(s->positions + 3 * (size_t)ta[opp]);
    lm_dvec3 p1 = dv3_load(s->positions + 3 * (size_t)ta[(opp + 1) % 3]);
    lm_dvec3 p2 = dv3_load(s->positions + 3 * (size_t)ta[(opp + 2) % 3]);
    lm_dvec3 q = dv3_load(s->positions + 3 * (size_t)tb[extra]);
    lm_dvec3 e1 = dv3_sub(p1, o), e2 = dv3_sub(p2, o);
    lm_dvec3 miss = dv3_sub(q, dv3_add(o, dv3_add(e1, e2)));
    double size = dv3_length(e1) + dv3_length(e2);
    if (dv3_length(miss) > 1e-5 * size) return;
    t->parallelogram = 1;
    t->corner = o;
    t->e1 = e1;
    t->e2 = e2;
    t->tri = s->light_tris[L->first];
}

static int strata_per_side(int rays)
{
    int k = (int)ceil(sqrt((double)rays));
    return k < 1 ? 1 : k;
}

lm_result samp_embree_create(const samp_desc *desc, const rt_scene *rt, const samp_backend_ops **ops,
                             void **impl, lm_error *err)
{
    embree_impl *e = calloc(1, sizeof *e);
    if (!e) return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory creating the Embree sampler");
    e->desc = *desc;
    e->s = desc->scene;
    e->rt = rt;
    e->threads = lm_thread_count(desc->threads);
    e->direct_k = strata_per_side(desc->direct_rays);
    e->indirect_k = strata_per_side(desc->indirect_rays);
    const scene *s = e->s;
    e->lights = calloc(s->area_light_count ? s->area_light_count : 1, sizeof *e->lights);
    if (!e->lights) {
        embree_destroy(e);
        return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory creating the Embree sampler");
    }
    for (uint32_t li = 0; li < s->area_light_count; ++li) {
        const scene_area_light *L = &s->area_lights[li];
        light_table *t = &e->lights[li];
        t->cdf = malloc(L->count * sizeof *t->cdf);
        if (!t->cdf) {
            embree_destroy(e);
            return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory creating the Embree sampler");
        }
        double total = 0.0;
        for (uint32_t i = 0; i < L->count; ++i) {
            total += s->tri_areas[s->light_tris[L->first + i]];
            t->cdf[i] = total;
        }
        for (uint32_t i = 0; i < L->count; ++i) t->cdf[i] /= total;
        t->cdf[L->count - 1] = 1.0;
        t->area = total;
        detect_parallelogram(s, L, t);
    }
    *ops = &embree_ops;
    *impl = e;
    return LM_OK;
}
