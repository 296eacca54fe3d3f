/* rend_residual.c — the cached picture corrected by path-traced samples, shrunk
 * by block (rend_residual.h: the estimator and why it is shrunk). */
#include "src/render/rend_residual.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* The sums of a block over its pixels and channels: the residual's energy Σ q·R²
 * and its noise Σ q·s² (infinite when a pixel of it has too few samples); the
 * sum of q·s² over its values with a finite s, and their count; and the noise
 * its values would have at the mean q·s² of its region (the blocks within
 * REND_RESIDUAL_NOISE_REGION of it, their values with a finite s). */
typedef struct block_sums {
    double energy, noise, finite_noise, finite_count, region_noise;
} block_sums;

/* Where the path tracer's means and standard errors are read: whole arrays
 * (rend_residual_blend), or the path tracer itself, one row of blocks at a time
 * into a band of scratch. The residual kept a read-back copy of the whole
 * picture, 28 bytes a pixel beside the path tracer's own 72 (8.6 MB at 640×480,
 * in Water's peak while `render` draws: docs/memory.md). */
typedef struct pt_picture {
    const float *mean, *se;  /* width·height·3 each, or NULL: read from pt */
    const ref_renderer *pt;
    float min_samples;       /* fewer samples: the pixel's error is unknown (infinite) */
    float *band;             /* band_floats(width, block): means, errors, counts of the band's rows */
} pt_picture;

/* Floats of a band's scratch: `block` rows of three means, three errors and a count. */
static size_t band_floats(int width, int block) { return (size_t)width * (size_t)block * 7; }

/* The rows y0 .. y0+rows−1 (rows ≤ the block): pointers to their first mean and
 * standard error, width·rows·3 values each. */
static void pt_band(const pt_picture *p, int width, int y0, int rows, const float **mean, const float **se)
{
    if (p->mean) {
        *mean = p->mean + 3 * (size_t)y0 * (size_t)width;
        *se = p->se + 3 * (size_t)y0 * (size_t)width;
        return;
    }
    size_t n = (size_t)width * (size_t)rows;
    float *m = p->band, *e = m + 3 * n, *count = e + 3 * n;
    ref_get_rows(p->pt, y0, rows, m, e, count);
    for (size_t i = 0; i < n; ++i)
        if (count[i] < p->min_samples) e[3 * i] = e[3 * i + 1] = e[3 * i + 2] = INFINITY;
    *mean = m;
    *se = e;
}

/* Blocks of `block` pixels over a width × height picture. */
static size_t block_count(int width, int height, int block)
{
    return (size_t)((width + block - 1) / block) * (size_t)((height + block - 1) / block);
}

struct rend_residual {
    rend_residual_desc desc;
    ref_renderer *pt;
    double seconds_before; /* the path tracer's seconds at the last restart */
    float *band;              /* the path tracer's read-back, one block's rows at a time (pt_picture) */
    float *cached_copy;       /* width·height·3: a copy of the last picture applied (the adaptive
                                 passes' mask is made against it); the caller may free or reuse its own.
                                 Made with mask at the first apply: `render` runs the residual beside the
                                 refining cache long before it applies anything (16 bytes a pixel less in
                                 that peak; docs/memory.md) */
    int have_cached;          /* cached_copy holds one (none since create or the last restart) */
    uint8_t *mask;            /* width·height: the pixels of the blocks being corrected, and their neighbours */
    block_sums *sums;         /* one per block: the blend's and the mask's scratch */
    int mask_live;            /* mask has a pixel set */
    uint64_t passes;          /* complete passes since the last restart */
    int in_pass;              /* the last run stopped inside a pass: the next goes on with it */
    int uniform;              /* the pass under way samples every pixel */
};

void rend_residual_desc_defaults(rend_residual_desc *d)
{
    if (d->block <= 0) d->block = REND_RESIDUAL_BLOCK_DEFAULT;
    if (d->min_samples == 0) d->min_samples = REND_RESIDUAL_MIN_SAMPLES_DEFAULT;
}

lm_result rend_residual_create(const rend_residual_desc *desc, rend_residual **out, lm_error *err)
{
    *out = NULL;
    if (!desc || !desc->scene || !desc->camera)
        return lm_fail(err, LM_ERR_INVALID_ARG, "rend_residual_create: no scene or no camera");
    if (desc->width <= 0 || desc->height <= 0)
        return lm_fail(err, LM_ERR_INVALID_ARG, "rend_residual_create: size %dx%d", desc->width, desc->height);
    rend_residual *rr = calloc(1, sizeof *rr);
    if (rr) {
        rend_residual_desc d = *desc;
        rend_residual_desc_defaults(&d);
        rr->band = malloc(band_floats(desc->width, d.block) * sizeof *rr->band);
        rr->sums = malloc(block_count(desc->width, desc->height, d.block) * sizeof *rr->sums);
    }
    if (!rr || !rr->band || !rr->sums) {
        rend_residual_destroy(rr);
        return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory for the residual of a %dx%d picture", desc->width,
                       desc->height);
    }
    rr->desc = *desc;
    rr->desc.camera = NULL; /* the path tracer keeps its copy */
    rend_residual_desc_defaults(&rr->desc);
    lm_result r = ref_create(&(ref_desc){.scene = desc->scene,
                                         .view = desc->camera,
                                         .width = desc->width,
                                         .height = desc->height,
                                         .transport = desc->transport,
                                         .bounces = desc->bounces,
                                         .glossy = desc->glossy,
                                         .seed = desc->seed,
                                         .threads = desc->threads,
                                         .background = desc->background},
                             &rr->pt, err);
    if (r != LM_OK) {
        rend_residual_destroy(rr);
        return r;
    }
    *out = rr;
    return LM_OK;
}

void rend_residual_destroy(rend_residual *rr)
{
    if (!rr) return;
    ref_destroy(rr->pt);
    free(rr->band);
    free(rr->cached_copy);
    free(rr->mask);
    free(rr->sums);
    free(rr);
}

void rend_residual_restart(rend_residual *rr, const scene_camera *cam)
{
    ref_stats st;
    ref_get_stats(rr->pt, &st);
    rr->seconds_before = st.seconds;
    ref_restart(rr->pt, cam);
    ref_set_mask(rr->pt, NULL, NULL);
    rr->have_cached = 0;
    rr->mask_live = 0;
    rr->passes = 0;
    rr->in_pass = 0;
}

/* q of a value: the weight relMSE gives its squared error (src/image/compare.c). */
static double rel_weight(float cached) { return 1.0 / ((double)cached * cached + 0.01); }


/* Every block's sums, bw × bh row by row into s (blocks of `block` pixels from the
 * top left; the last row and column may be smaller). The regions come from the
 * blocks' finite sums, so each value is read once. */
static void block_sums_all(int width, int height, int block, const float *cached, const pt_picture *pt,
                           block_sums *s)
{
    const int bw = (width + block - 1) / block, bh = (height + block - 1) / block, R = REND_RESIDUAL_NOISE_REGION;
    for (int j = 0; j < bh; ++j) {
        const int by = j * block, y1 = by + block < height ? by + block : height;
        const float *mean, *stderr_rgb; /* the band's rows, from row by */
        pt_band(pt, width, by, y1 - by, &mean, &stderr_rgb);
        for (int i = 0; i < bw; ++i) {
            block_sums b = {0.0, 0.0, 0.0, 0.0, 0.0};
            const int bx = i * block, x1 = bx + block < width ? bx + block : width;
            for (int y = by; y < y1; ++y)
                for (int x = bx; x < x1; ++x)
                    for (int k = 0; k < 3; ++k) {
                        size_t v = 3 * ((size_t)y * (size_t)width + (size_t)x) + (size_t)k;
                        size_t u = 3 * ((size_t)(y - by) * (size_t)width + (size_t)x) + (size_t)k;
                        double q = rel_weight(cached[v]), r = (double)mean[u] - cached[v];
                        double n = q * (double)stderr_rgb[u] * stderr_rgb[u];
                        b.noise += n;
                        b.energy += q * r * r;
                        if (isfinite(stderr_rgb[u])) {
                            b.finite_noise += n;
                            b.finite_count += 1.0;
                        }
                    }
            s[(size_t)j * (size_t)bw + (size_t)i] = b;
        }
    }
    for (int j = 0; j < bh; ++j)
        for (int i = 0; i < bw; ++i) {
            double sum = 0.0, n = 0.0;
            for (int jj = j - R < 0 ? 0 : j - R; jj <= j + R && jj < bh; ++jj)
                for (int ii = i - R < 0 ? 0 : i - R; ii <= i + R && ii < bw; ++ii) {
                    sum += s[(size_t)jj * (size_t)bw + (size_t)ii].finite_noise;
                    n += s[(size_t)jj * (size_t)bw + (size_t)ii].finite_count;
                }
            const int bx = i * block, by = j * block;
            const int x1 = bx + block < width ? bx + block : width, y1 = by + block < height ? by + block : height;
            s[(size_t)j * (size_t)bw + (size_t)i].region_noise =
                n > 0.0 ? sum / n * 3.0 * (double)(x1 - bx) * (double)(y1 - by) : 0.0;
        }
}

/* w_B: positive-part James–Stein with the noise counted REND_RESIDUAL_SHRINK
 * times (rend_residual.h), the block's own or its region's, whichever is more;
 * 0 for a block short of samples. */
static double block_weight(block_sums b)
{
    double noise = REND_RESIDUAL_SHRINK * fmax(b.noise, b.region_noise);
    return isfinite(noise) && b.energy > noise ? 1.0 - noise / b.energy : 0.0;
}

/* rend_residual_blend with the blocks' sums in `sums` (room for every block):
 * they are all made before out is written, since out may be cached. */
static void blend_with(int width, int height, int block, const float *cached, const pt_picture *pt, float *out,
                       rend_residual_info *info, block_sums *sums)
{
    const int bw = (width + block - 1) / block;
    block_sums_all(width, height, block, cached, pt, sums);
    double weight_sum = 0.0, est = 0.0;
    size_t blocks = 0, corrected = 0;
    int unknown = 0; /* a block short of samples: no estimate of its error */
    for (int by = 0; by < height; by += block) {
        const int y1 = by + block < height ? by + block : height;
        const float *mean, *stderr_rgb; /* the band's rows, from row by */
        pt_band(pt, width, by, y1 - by, &mean, &stderr_rgb);
        for (int bx = 0; bx < width; bx += block) {
            int x1 = bx + block < width ? bx + block : width;
            const block_sums b = sums[(size_t)(by / block) * (size_t)bw + (size_t)(bx / block)];
            double w = block_weight(b);
            for (int y = by; y < y1; ++y)
                for (int x = bx; x < x1; ++x)
                    for (int k = 0; k < 3; ++k) {
                        size_t i = 3 * ((size_t)y * (size_t)width + (size_t)x) + (size_t)k;
                        size_t u = 3 * ((size_t)(y - by) * (size_t)width + (size_t)x) + (size_t)k;
                        out[i] = (float)(cached[i] + w * ((double)mean[u] - cached[i]));
                    }
            /* The corrected block's error: w² of the noise, and (1 − w)² of the bias,
             * whose energy is what the noise does not explain: E − N, kept signed
             * (clipping each block at 0 would add the noise's upward swings and
             * not its downward ones: an estimate 3.5× too high on Water). */
            if (isfinite(b.noise)) {
                est += w * w * b.noise + (1.0 - w) * (1.0 - w) * (b.energy - b.noise);
            } else {
                unknown = 1;
            }
            weight_sum += w;
            corrected += w > 0.0;
            blocks++;
        }
    }
    if (info) {
        info->mean_weight = blocks ? weight_sum / (double)blocks : 0.0;
        info->corrected = blocks ? (double)corrected / (double)blocks : 0.0;
        info->est_relmse = unknown ? NAN : fmax(est, 0.0) / (3.0 * (double)width * (double)height);
    }
}

void rend_residual_blend(int width, int height, int block, const float *cached, const float *mean,
                         const float *stderr_rgb, float *out, rend_residual_info *info)
{
    if (block <= 0) block = REND_RESIDUAL_BLOCK_DEFAULT;
    block_sums *sums = malloc(block_count(width, height, block) * sizeof *sums);
    if (sums) {
        blend_with(width, height, block, cached, &(pt_picture){.mean = mean, .se = stderr_rgb}, out, info, sums);
        free(sums);
        return;
    }
    /* No memory for the sums: the cache's picture, uncorrected, its error unknown. */
    if (out != cached) memcpy(out, cached, (size_t)width * (size_t)height * 3 * sizeof *out);
    if (info) {
        info->mean_weight = info->corrected = 0.0;
        info->est_relmse = NAN;
    }
}

/* The path tracer as the blend reads it: a band at a time, pixels short of
 * desc.min_samples unknown (infinite error). */
static pt_picture pt_of(const rend_residual *rr)
{
    return (pt_picture){.pt = rr->pt, .min_samples = (float)rr->desc.min_samples, .band = rr->band};
}

/* The mask of the adaptive passes: every pixel of a block with w_B > 0 against
 * the last picture applied, and of the blocks around it (a wrong region seldom
 * stops at a block's edge). */
static void update_mask(rend_residual *rr)
{
    int width = rr->desc.width, height = rr->desc.height, b = rr->desc.block;
    int bw = (width + b - 1) / b, bh = (height + b - 1) / b;
    rr->mask_live = 0;
    if (!rr->have_cached) return;
    memset(rr->mask, 0, (size_t)width * (size_t)height);
    const pt_picture pt = pt_of(rr);
    block_sums_all(width, height, b, rr->cached_copy, &pt, rr->sums);
    for (int j = 0; j < bh; ++j)
        for (int i = 0; i < bw; ++i) {
            if (!(block_weight(rr->sums[(size_t)j * (size_t)bw + (size_t)i]) > 0.0)) continue;
            rr->mask_live = 1;
            int ya = (j - 1) * b < 0 ? 0 : (j - 1) * b, yb = (j + 2) * b < height ? (j + 2) * b : height;
            int xa = (i - 1) * b < 0 ? 0 : (i - 1) * b, xb = (i + 2) * b < width ? (i + 2) * b : width;
            for (int y = ya; y < yb; ++y) memset(rr->mask + (size_t)y * (size_t)width + (size_t)xa, 1, (size_t)(xb - xa));
        }
}

/* One step of the passes: a pass (or the rest of one) with the mask it was
 * started with; between complete passes the mask is chosen, and renewed after a
 * uniform pass. Returns 0 when the pass stopped early. */
static int pass_step(rend_residual *rr, volatile sig_atomic_t *cancel, double deadline)
{
    /* One pass in REND_RESIDUAL_UNIFORM_EVERY samples every pixel (so every pixel
     * converges, and a wrong region newly found is seen); the others only the
     * blocks being corrected, where a sample lowers the error most. */
    if (!rr->in_pass) {
        rr->uniform = rr->desc.uniform_only || !rr->mask_live || rr->passes % REND_RESIDUAL_UNIFORM_EVERY == 0;
        if (ref_set_mask(rr->pt, rr->uniform ? NULL : rr->mask, NULL) != LM_OK)
            rr->uniform = 1; /* no memory for the copy: every pixel */
    }
    rr->in_pass = !ref_render_pass(rr->pt, cancel, deadline);
    if (rr->in_pass) return 0;
    rr->passes++;
    if (rr->uniform && !rr->desc.uniform_only) update_mask(rr);
    return 1;
}

void rend_residual_run(rend_residual *rr, volatile sig_atomic_t *cancel, double deadline)
{
    while (!(cancel && *cancel) && lm_now_seconds() < deadline && pass_step(rr, cancel, deadline)) {
    }
}

void rend_residual_run_passes(rend_residual *rr, uint32_t passes)
{
    for (uint32_t i = 0; i < passes; ++i) pass_step(rr, NULL, 0.0);
}

lm_result rend_residual_set_light(rend_residual *rr, uint32_t light, const float value[3], lm_error *err)
{
    return ref_set_light(rr->pt, light, value, err);
}

void rend_residual_read(rend_residual *rr, float *mean, float *stderr_rgb)
{
    ref_get_image(rr->pt, mean, stderr_rgb, NULL);
}

void rend_residual_apply(rend_residual *rr, const float *cached, float *out, rend_residual_info *info)
{
    int w = rr->desc.width, h = rr->desc.height;
    size_t n = (size_t)w * (size_t)h;
    if (!rr->cached_copy) rr->cached_copy = malloc(n * 3 * sizeof *rr->cached_copy);
    if (!rr->mask) rr->mask = malloc(n);
    if (rr->cached_copy && rr->mask) { /* without them the passes stay uniform (update_mask) */
        memcpy(rr->cached_copy, cached, n * 3 * sizeof *cached);
        rr->have_cached = 1;
    }
    rend_residual_info local;
    if (!info) info = &local;
    memset(info, 0, sizeof *info);
    const pt_picture pt = pt_of(rr);
    blend_with(w, h, rr->desc.block, cached, &pt, out, info, rr->sums);
    ref_stats st;
    ref_get_stats(rr->pt, &st);
    info->min_samples = st.min_samples;
    info->max_samples = st.max_samples;
    info->seconds = st.seconds - rr->seconds_before;
    info->rays = st.rays;
}
