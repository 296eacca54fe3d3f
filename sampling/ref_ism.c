/* ref_ism.c — imperfect shadow maps on the GL back end (see ref_ism.h). */
#include "sampling/ref_ism.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "src/base/rng.h"
#include "src/gpu/gl_context.h"
#include "src/gpu/gl_program.h"

enum { LEVELS = 3 }; /* the map and the two coarser levels pull-push uses (as Ritschel et al.) */
#define EMPTY 1e30f              /* a texel no point reached (the shaders' EMPTY) */
#define PULL_THRESHOLD_REL 0.05f /* of the scene's extent, doubled a level (thesis §2.6.5) */
/* Work an invocation does. llvmpipe runs each invocation as a coroutine whose
 * frame it allocates: one point or texel an invocation made a build 7.6 times
 * slower under AddressSanitizer's allocator (837 maps 9.5 s against 1.25 s, so
 * the viewer's test saw no picture in 3 s); in a release build the two are
 * level within this machine's noise (0.14-0.25 ms a map either way). */
#define SPLAT_POINTS_PER_INVOCATION 16 /* the splat shader's loop */
#define PULLPUSH_BLOCK 4               /* texels on a side (the pull-push shader's u_block) */
/* The lookup: x moved off its surface by this many texels' width (normal
 * offset), then visible when no farther than the texel's distance plus
 * BIAS_ABS_REL of the scene's extent (a splat is flat and faces the VPL, so a
 * surface tilted away behind it is a little farther than its distance). Light
 * wrongly shadowed / leaked of what the exact visibility passes on
 * CornellBox-Original (reference_ism_test), and the door's camera room image
 * mean against shadow rays (64×48, 8 passes; the pairs: 64 paths, 3 bounces):
 *   a depth bias of 2 texels × the receiver's slope (tan, up to 8), 0.01: 1.6% / 0.8%, door +617%
 *   (grazing receivers in the camera room saw through the wall to the lamp's room);
 *   normal offset 1, 0.002: 7.9% / 0.6%, door +40%;  2, 0.002: 4.7% / 0.7%, +50%;
 *   2, 0.005 (kept): 4.0% / 0.7%, +60%;  3, 0.002: 3.9% / 1.1%, +71%.
 * The door's remaining excess is leaks between the points of the wall: with
 * 16,384 points a map +18%, at 2.5× the build time. */
#define NORMAL_OFFSET_TEXELS 2.0f
#define BIAS_ABS_REL 0.005f
/* A splat's side over the angle its area spans (measured with the slope-scaled
 * bias above, wrongly shadowed / leaked): 1 made near points' squares shadow what lies
 * behind their tilted surfaces (5.1% / 0.2%), 0.5 leaked (2.1% / 1.4%), 0.7
 * balanced them (1.6% / 0.8%). */
#define SPLAT_SCALE 0.7f
#define ISM_SEED_SALT 0x15a9c0deu

/* One VPL as the splat shader reads it (std430 struct Vpl). */
typedef struct ism_vpl {
    float p[4]; /* position; w: the first point of its share of the cloud */
    float t[4], b[4], n[4];
} ism_vpl;

/* Owned by the thread that calls create/build/destroy (one at a time); maps and
 * frames are read by any number of gathering threads between builds. */
struct ref_ism {
    ref_ism_desc desc; /* defaults filled in */
    glctx *ctx;
    const GladGLContext *gl;
    GLuint prog_splat, prog_pull, prog_push;
    GLint loc_points, loc_per_map, loc_tile, loc_cols, loc_splat, loc_pull_thr;
    GLuint points_buf, vpl_buf, color;
    int cols, rows; /* maps per atlas row; rows of maps the atlas holds now */
    int max_rows;   /* rows of one build chunk */
    float splat, extent;
    ism_vpl *frames; /* the last build's VPLs, as drawn (the lookup uses the same frames) */
    float *maps;     /* per chunk: the atlas's rows of maps (cols·tile wide), distances */
    size_t frames_cap, maps_cap;
    uint32_t count;
    uint64_t made;
    double seconds;
};

static const char *const splat_names[] = {"ref_ism_splat.comp", NULL};
static const char *const pullpush_names[] = {"ref_ism_pullpush.comp", NULL};

/* The cloud: desc.points points spread over the surfaces by area (stratified
 * over the cumulative area), then shuffled so that any run of them is a random
 * subset of the scene. */
static lm_result make_points(ref_ism *m, lm_error *err)
{
    const scene *s = m->desc.s;
    const size_t n = (size_t)m->desc.points;
    double *cdf = malloc((s->tri_count ? s->tri_count : 1) * sizeof *cdf);
    float *pts = malloc(4 * n * sizeof *pts);
    if (!cdf || !pts) {
        free(cdf);
        free(pts);
        return lm_fail(err, LM_ERR_NO_MEMORY, "imperfect shadow maps: out of memory for %zu points", n);
    }
    double total = 0.0;
    for (uint32_t t = 0; t < s->tri_count; ++t) cdf[t] = total += s->tri_areas[t];
    lm_rng g;
    lm_rng_seed(&g, (uint64_t)m->desc.seed ^ ISM_SEED_SALT, 0, 0);
    uint32_t tri = 0;
    for (size_t j = 0; j < n; ++j) {
        double target = ((double)j + lm_rng_float(&g)) / (double)n * total;
        while (tri + 1 < s->tri_count && cdf[tri] <= target) tri++;
        float u = lm_rng_float(&g), v = lm_rng_float(&g);
        if (u + v > 1.0f) {
            u = 1.0f - u;
            v = 1.0f - v;
        }
        const float *a = s->positions + 3 * (size_t)s->tris[tri].v[0];
        const float *b = s->positions + 3 * (size_t)s->tris[tri].v[1];
        const float *c = s->positions + 3 * (size_t)s->tris[tri].v[2];
        for (int k = 0; k < 3; ++k) pts[4 * j + (size_t)k] = a[k] + u * (b[k] - a[k]) + v * (c[k] - a[k]);
        pts[4 * j + 3] = 0.0f;
    }
    for (size_t j = n - 1; j > 0; --j) { /* Fisher-Yates */
        size_t k = (size_t)(lm_rng_float(&g) * (float)(j + 1));
        if (k > j) k = j;
        float tmp[4];
        memcpy(tmp, pts + 4 * j, sizeof tmp);
        memcpy(pts + 4 * j, pts + 4 * k, sizeof tmp);
        memcpy(pts + 4 * k, tmp, sizeof tmp);
    }
    m->gl->NamedBufferStorage(m->points_buf, (GLsizeiptr)(4 * n * sizeof *pts), pts, 0);
    /* Each map gets points_per_map of them: each stands for total/points_per_map
     * of the surface; seen at unit distance its side spans sqrt(that) radians,
     * and a texel at the map's centre 4/tile. */
    m->splat = SPLAT_SCALE * sqrtf((float)(total / m->desc.points_per_map)) * (float)m->desc.tile / 4.0f;
    free(cdf);
    free(pts);
    return LM_OK;
}

/* An atlas of `rows` rows of maps, with the pull-push levels. */
static lm_result make_atlas(ref_ism *m, int rows, lm_error *err)
{
    const GladGLContext *gl = m->gl;
    if (m->color) gl->DeleteTextures(1, &m->color);
    m->color = 0;
    gl->CreateTextures(GL_TEXTURE_2D, 1, &m->color);
    gl->TextureStorage2D(m->color, LEVELS, GL_R32F, m->cols * m->desc.tile, rows * m->desc.tile);
    m->rows = rows;
    return glctx_check(m->ctx, "the imperfect shadow maps' atlas", err);
}

void ref_ism_destroy(ref_ism *m)
{
    if (!m) return;
    if (m->ctx && glctx_make_current(m->ctx, NULL) == LM_OK) {
        const GladGLContext *gl = m->gl;
        GLuint bufs[] = {m->points_buf, m->vpl_buf};
        gl->DeleteBuffers(2, bufs);
        if (m->color) gl->DeleteTextures(1, &m->color);
        GLuint progs[] = {m->prog_splat, m->prog_pull, m->prog_push};
        for (int i = 0; i < 3; ++i)
            if (progs[i]) gl->DeleteProgram(progs[i]);
    }
    glctx_destroy(m->ctx);
    free(m->frames);
    free(m->maps);
    free(m);
}

lm_result ref_ism_create(const ref_ism_desc *desc, ref_ism **out, lm_error *err)
{
    *out = NULL;
    if (!desc || !desc->s) return lm_fail(err, LM_ERR_INVALID_ARG, "ref_ism_create: no scene");
    ref_ism_desc d = *desc;
    if (d.tile == 0) d.tile = REF_ISM_TILE_DEFAULT;
    if (d.points_per_map == 0) d.points_per_map = REF_ISM_POINTS_PER_MAP_DEFAULT;
    if (d.points == 0) d.points = REF_ISM_POINTS_DEFAULT;
    if (d.points < d.points_per_map) d.points = d.points_per_map;
    if (d.atlas_side == 0) d.atlas_side = REF_ISM_ATLAS_SIDE_DEFAULT;
    if (d.tile < 4 || d.tile % 4 != 0 || d.tile > 1024)
        return lm_fail(err, LM_ERR_INVALID_ARG, "imperfect shadow maps: a map's side must be a multiple of 4 up to "
                       "1024, not %d", d.tile);
    if (d.atlas_side < d.tile)
        return lm_fail(err, LM_ERR_INVALID_ARG, "imperfect shadow maps: an atlas of %d texels holds no map of %d",
                       d.atlas_side, d.tile);
    if (d.points_per_map < 0 || d.points > (1 << 24))
        return lm_fail(err, LM_ERR_INVALID_ARG, "imperfect shadow maps: %d points a map of %d (at most %d)",
                       d.points_per_map, d.points, 1 << 24);
    if (d.s->tri_count == 0)
        return lm_fail(err, LM_ERR_INVALID_ARG, "imperfect shadow maps: the scene has no triangles");
    ref_ism *m = calloc(1, sizeof *m);
    if (!m) return lm_fail(err, LM_ERR_NO_MEMORY, "imperfect shadow maps: out of memory");
    m->desc = d;
    const scene *s = d.s;
    m->extent = v3_length(v3_sub(v3_load(s->bounds_max), v3_load(s->bounds_min)));
    lm_result r = glctx_create(&(glctx_desc){.platform = d.platform}, &m->ctx, err);
    if (r == LM_OK) {
        m->gl = glctx_gl(m->ctx);
        r = glprog_build(m->gl, "imperfect shadow maps", splat_names, "", &m->prog_splat, err);
    }
    if (r == LM_OK) r = glprog_build(m->gl, "imperfect shadow maps", pullpush_names, "", &m->prog_pull, err);
    if (r == LM_OK)
        r = glprog_build(m->gl, "imperfect shadow maps", pullpush_names, "#define PUSH 1\n", &m->prog_push, err);
    if (r == LM_OK) {
        const GladGLContext *gl = m->gl;
        m->loc_points = gl->GetUniformLocation(m->prog_splat, "u_points");
        m->loc_per_map = gl->GetUniformLocation(m->prog_splat, "u_per_map");
        m->loc_tile = gl->GetUniformLocation(m->prog_splat, "u_tile");
        m->loc_cols = gl->GetUniformLocation(m->prog_splat, "u_cols");
        m->loc_splat = gl->GetUniformLocation(m->prog_splat, "u_splat");
        m->loc_pull_thr = gl->GetUniformLocation(m->prog_pull, "u_threshold");
        gl->ProgramUniform1i(m->prog_pull, gl->GetUniformLocation(m->prog_pull, "u_block"), PULLPUSH_BLOCK);
        gl->ProgramUniform1i(m->prog_push, gl->GetUniformLocation(m->prog_push, "u_block"), PULLPUSH_BLOCK);
        GLint max_tex = 0;
        gl->GetIntegerv(GL_MAX_TEXTURE_SIZE, &max_tex);
        const int side = max_tex < d.atlas_side ? max_tex : d.atlas_side;
        m->cols = side / d.tile;
        m->max_rows = side / d.tile;
        GLuint bufs[2];
        gl->CreateBuffers(2, bufs);
        m->points_buf = bufs[0];
        m->vpl_buf = bufs[1];
        if (m->cols < 1)
            r = lm_fail(err, LM_ERR_RUNTIME, "imperfect shadow maps: textures of %d texels are too small", max_tex);
    }
    if (r == LM_OK) r = make_points(m, err);
    if (r == LM_OK) r = glctx_check(m->ctx, "the imperfect shadow maps' creation", err);
    if (r != LM_OK) {
        ref_ism_destroy(m);
        return r;
    }
    glctx_release(m->ctx);
    *out = m;
    return LM_OK;
}

/* Pull-push over the atlas's first `rows` rows of maps (levels 0 → 1 → 2 → 1 → 0). */
static void pull_push(ref_ism *m, int rows)
{
    const GladGLContext *gl = m->gl;
    const int w = m->cols * m->desc.tile, h = rows * m->desc.tile;
    for (int pass = 0; pass < 2 * (LEVELS - 1); ++pass) {
        const int pull = pass < LEVELS - 1;
        const int fine = pull ? pass : 2 * (LEVELS - 1) - 1 - pass;
        const int fw = w >> fine, fh = h >> fine, cw = fw / 2, ch = fh / 2;
        gl->UseProgram(pull ? m->prog_pull : m->prog_push);
        if (pull) gl->Uniform1f(m->loc_pull_thr, PULL_THRESHOLD_REL * m->extent * (float)(1 << fine));
        gl->BindImageTexture(0, m->color, fine, GL_FALSE, 0, GL_READ_WRITE, GL_R32F);
        gl->BindImageTexture(1, m->color, fine + 1, GL_FALSE, 0, GL_READ_WRITE, GL_R32F);
        const int gw = pull ? cw : fw, gh = pull ? ch : fh;
        const int span = 8 * PULLPUSH_BLOCK; /* texels a work group covers on a side */
        gl->DispatchCompute((GLuint)((gw + span - 1) / span), (GLuint)((gh + span - 1) / span), 1);
        gl->MemoryBarrier(GL_SHADER_IMAGE_ACCESS_BARRIER_BIT | GL_TEXTURE_UPDATE_BARRIER_BIT);
    }
}

lm_result ref_ism_build(ref_ism *m, const ref_vpl *vpls, uint32_t count, uint64_t stream, lm_error *err)
{
    const double t0 = lm_now_seconds();
    m->count = 0;
    if (count == 0) return LM_OK;
    lm_result r = glctx_make_current(m->ctx, err);
    if (r != LM_OK) return r;
    const GladGLContext *gl = m->gl;
    const int tile = m->desc.tile, w = m->cols * tile;
    const uint32_t per_chunk = (uint32_t)(m->cols * m->max_rows);
    const uint32_t chunks = (count + per_chunk - 1) / per_chunk;
    /* Every chunk but the last is full; the last holds the rows of maps it uses. */
    const size_t chunk_floats = (size_t)w * (size_t)m->max_rows * (size_t)tile;
    const uint32_t last = count - (chunks - 1) * per_chunk;
    const size_t last_rows = (last + (uint32_t)m->cols - 1) / (uint32_t)m->cols;
    const size_t floats = (size_t)(chunks - 1) * chunk_floats + last_rows * (size_t)tile * (size_t)w;
    if (!LM_GROW(m->frames, m->frames_cap, count) || !LM_GROW(m->maps, m->maps_cap, floats)) {
        glctx_release(m->ctx);
        return lm_fail(err, LM_ERR_NO_MEMORY, "imperfect shadow maps: out of memory for %u maps", count);
    }
    lm_rng g;
    lm_rng_seed(&g, (uint64_t)m->desc.seed ^ ISM_SEED_SALT, 1, stream);
    for (uint32_t i = 0; i < count; ++i) {
        lm_vec3 t, b, n = vpls[i].ng;
        ref_frame(n, &t, &b);
        ism_vpl *f = &m->frames[i];
        v3_store(f->p, vpls[i].p);
        v3_store(f->t, t);
        v3_store(f->b, b);
        v3_store(f->n, n);
        /* A different run of the shuffled cloud for every map (exact in a float: points ≤ 2²⁴). */
        f->p[3] = floorf(lm_rng_float(&g) * (float)m->desc.points);
        f->t[3] = f->b[3] = f->n[3] = 0.0f;
    }
    const GLsizeiptr need = (GLsizeiptr)((size_t)(count < per_chunk ? count : per_chunk) * sizeof(ism_vpl));
    GLint have = 0;
    gl->GetNamedBufferParameteriv(m->vpl_buf, GL_BUFFER_SIZE, &have);
    if (have < need) gl->NamedBufferData(m->vpl_buf, need, NULL, GL_STREAM_DRAW);
    gl->BindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, m->points_buf);
    gl->BindBufferBase(GL_SHADER_STORAGE_BUFFER, 1, m->vpl_buf);
    for (uint32_t c = 0; c < chunks && r == LM_OK; ++c) {
        const uint32_t first = c * per_chunk, n = count - first < per_chunk ? count - first : per_chunk;
        const int rows = (int)((n + (uint32_t)m->cols - 1) / (uint32_t)m->cols);
        if (rows > m->rows) { /* grow by doubling: VPL counts vary from pass to pass */
            const int doubled = m->rows * 2 < m->max_rows ? m->rows * 2 : m->max_rows;
            r = make_atlas(m, rows > doubled ? rows : doubled, err);
        }
        if (r != LM_OK) break;
        gl->NamedBufferSubData(m->vpl_buf, 0, (GLsizeiptr)(n * sizeof(ism_vpl)), m->frames + first);
        const float empty = EMPTY;
        gl->ClearTexImage(m->color, 0, GL_RED, GL_FLOAT, &empty);
        gl->UseProgram(m->prog_splat);
        gl->Uniform1i(m->loc_points, m->desc.points);
        gl->Uniform1i(m->loc_per_map, m->desc.points_per_map);
        gl->Uniform1i(m->loc_tile, tile);
        gl->Uniform1i(m->loc_cols, m->cols);
        gl->Uniform1f(m->loc_splat, m->splat);
        /* The R32F level as 32-bit unsigned integers (compatible by size): atomic minimum. */
        gl->BindImageTexture(0, m->color, 0, GL_FALSE, 0, GL_READ_WRITE, GL_R32UI);
        const int per_group = 64 * SPLAT_POINTS_PER_INVOCATION;
        gl->DispatchCompute((GLuint)((m->desc.points_per_map + per_group - 1) / per_group), n, 1);
        gl->MemoryBarrier(GL_SHADER_IMAGE_ACCESS_BARRIER_BIT);
        pull_push(m, rows);
        const int h = rows * tile;
        gl->GetTextureSubImage(m->color, 0, 0, 0, 0, w, h, 1, GL_RED, GL_FLOAT,
                               (GLsizei)((size_t)w * (size_t)h * sizeof(float)), m->maps + (size_t)c * chunk_floats);
        r = glctx_check(m->ctx, "the imperfect shadow maps' build", err);
    }
    gl->UseProgram(0);
    glctx_release(m->ctx);
    if (r != LM_OK) return r;
    m->count = count;
    m->made += count;
    m->seconds += lm_now_seconds() - t0;
    return LM_OK;
}

int ref_ism_visible(const ref_ism *m, uint32_t i, lm_vec3 x, lm_vec3 ng)
{
    if (i >= m->count) return 1;
    const ism_vpl *f = &m->frames[i];
    const lm_vec3 p = v3_load(f->p), axis = v3_load(f->n);
    lm_vec3 d = v3_sub(x, p);
    float dist = v3_length(d);
    if (!(dist > 0.0f)) return 1;
    float lz = v3_dot(d, axis) / dist;
    if (!(lz > 0.0f)) return 1; /* behind the VPL: not its map's to say (it sends nothing there) */
    const int tile = m->desc.tile;
    /* Normal offset: x moved off its surface, towards the VPL's side, by
     * NORMAL_OFFSET_TEXELS texels' width there (4·cos²(θ/2)/tile radians at
     * dist), so that its own surface's points in the texel lie behind it at any
     * slope, with no depth bias that grows with the slope (which let a grazing
     * receiver see through walls: docs/peers.md). */
    const float texel = 2.0f * (1.0f + lz) / (float)tile * dist;
    const lm_vec3 side = v3_dot(ng, d) < 0.0f ? ng : v3_scale(ng, -1.0f);
    d = v3_add(d, v3_scale(side, NORMAL_OFFSET_TEXELS * texel));
    dist = v3_length(d);
    if (!(dist > 0.0f)) return 1;
    const lm_vec3 w = v3_scale(d, 1.0f / dist);
    lz = v3_dot(w, axis);
    if (!(lz > 0.0f)) return 1;
    const float u = v3_dot(w, v3_load(f->t)) / (1.0f + lz), v = v3_dot(w, v3_load(f->b)) / (1.0f + lz);
    int tx = (int)floorf((u * 0.5f + 0.5f) * (float)tile), ty = (int)floorf((v * 0.5f + 0.5f) * (float)tile);
    tx = tx < 0 ? 0 : tx >= tile ? tile - 1 : tx;
    ty = ty < 0 ? 0 : ty >= tile ? tile - 1 : ty;
    const uint32_t per_chunk = (uint32_t)(m->cols * m->max_rows), j = i % per_chunk;
    const size_t w_atlas = (size_t)m->cols * (size_t)tile;
    const size_t chunk_floats = w_atlas * (size_t)m->max_rows * (size_t)tile;
    const size_t row = j / (uint32_t)m->cols, col = j % (uint32_t)m->cols;
    const float stored = m->maps[(size_t)(i / per_chunk) * chunk_floats + (row * (size_t)tile + (size_t)ty) * w_atlas +
                                 col * (size_t)tile + (size_t)tx];
    return stored >= 0.5f * EMPTY || dist <= stored + BIAS_ABS_REL * m->extent;
}

void ref_ism_totals(const ref_ism *m, uint64_t *maps, double *seconds)
{
    *maps = m ? m->made : 0;
    *seconds = m ? m->seconds : 0.0;
}
