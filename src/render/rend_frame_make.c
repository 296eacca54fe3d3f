/* rend_frame_make.c — the renderer made (rend_frame.h): its programs, its images
 * (made again by rend_frame_resize), its scene (rend_frame_set_scene), and, for
 * one made ahead of its scene, the stand-in drawn so that the driver compiles
 * its shader variants then. The passes are in rend_frame.c. */
#include "src/render/rend_frame_internal.h"

#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "src/gpu/gl_program.h"

static const char *const material_names[] = {"rend_material.vert", "rend_material.frag", NULL};
static const char *const value_names[] = {"rend_value.vert", "rend_value.frag", NULL};
static const char *const resolve_names[] = {"rend_composite.vert", "rend_resolve.frag", NULL};
static const char *const composite_names[] = {"rend_composite.vert", "rend_composite.frag", NULL};
static const char *const whole_names[] = {"rend_composite.vert", "rend_whole.frag", NULL};

static void free_images(rend_frame *f);

void rend_frame_destroy(rend_frame *f)
{
    if (!f) return;
    const GladGLContext *gl = f->gl;
    if (gl) {
        free_images(f);
        GLuint progs[6] = {f->prog_material, f->prog_value,     f->prog_resolve,
                           f->prog_composite, f->prog_highlight, f->prog_whole};
        for (int i = 0; i < 6; ++i)
            if (progs[i]) gl->DeleteProgram(progs[i]);
        GLuint bufs[3] = {f->scene_vbo, f->material_ssbo, f->corner_buf}, vaos[2] = {f->scene_vao, f->empty_vao};
        gl->DeleteBuffers(3, bufs);
        GLuint texs[2] = {f->scene_tex, f->corner_tex};
        gl->DeleteTextures(2, texs);
        gl->DeleteBuffers(3, f->hl_ssbo);
        gl->DeleteVertexArrays(2, vaos);
        for (int t = 0; t < TERMS; ++t) {
            term_state *ts = &f->term[t];
            gl->DeleteBuffers(1, &ts->vbo);
            gl->DeleteBuffers(1, &ts->ibo);
            gl->DeleteBuffers(1, &ts->lobe_vbo);
            gl->DeleteVertexArrays(1, &ts->vao);
            GLuint wb[2] = {ts->whole_buf, ts->values_buf}, wt[2] = {ts->whole_tex, ts->values_tex};
            gl->DeleteBuffers(2, wb);
            gl->DeleteTextures(2, wt);
        }
    }
    free(f->hl_radiance);
    for (int t = 0; t < TERMS; ++t) {
        free(f->term[t].copy_lobes);
        free(f->term[t].copy_v);
        free(f->term[t].copy_i);
        free(f->term[t].hash);
        free(f->term[t].copy_whole);
        free(f->term[t].copy_values);
    }
    free(f->id_changed);
    free(f->new_hash);
    free(f->hash_key);
    free(f->hash_tri);
    free(f->seen);
    free(f);
}

static GLuint color_target(const GladGLContext *gl, GLenum format, int w, int h)
{
    GLuint t;
    gl->CreateTextures(GL_TEXTURE_2D, 1, &t);
    gl->TextureStorage2D(t, 1, format, w, h);
    /* Read with texelFetch only; NEAREST also keeps an integer texture complete. */
    gl->TextureParameteri(t, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
    gl->TextureParameteri(t, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
    return t;
}

static GLuint depth_target(const GladGLContext *gl, int w, int h)
{
    GLuint rb;
    gl->CreateRenderbuffers(1, &rb);
    gl->NamedRenderbufferStorage(rb, GL_DEPTH_COMPONENT32F, w, h);
    return rb;
}

/* One light of the highlights' table (rend_value.frag, hl_light; std430). */
typedef struct hl_light {
    float le[4];     /* radiance (area) or intensity (point); the snapshot's replaces it */
    float sphere[4]; /* area: bounding sphere, centre and radius; point: position */
    uint32_t loops[4]; /* first loop, loops, 1 for a point light */
} hl_light;

/* The lights' outlines (cache_build_outlines: the cache's own, so that a pixel
 * integrates what its vertices did) and radiance, for the highlights per pixel. */
static lm_result upload_lights(rend_frame *f, const scene *s, lm_error *err)
{
    const GladGLContext *gl = f->gl;
    const uint32_t nl = s->area_light_count + s->point_light_count;
    cache_outlines o = {0};
    if (nl && !cache_build_outlines(&o, s, nl)) return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory creating the renderer");
    const uint32_t loops = nl ? o.light_loop[nl] : 0, points = loops ? o.loop[loops] : 0;
    hl_light *lights = calloc(nl ? nl : 1, sizeof *lights);
    int32_t *lp = calloc(4 * (size_t)(loops ? loops : 1), sizeof *lp);
    float *pts = calloc(4 * (size_t)(points ? points : 1), sizeof *pts), *rad = calloc(3 * (size_t)(nl ? nl : 1), sizeof *rad);
    lm_result r = lights && lp && pts && rad ? LM_OK : lm_fail(err, LM_ERR_NO_MEMORY, "out of memory creating the renderer");
    for (uint32_t i = 0; r == LM_OK && i < points; ++i)
        for (int k = 0; k < 3; ++k) pts[4 * (size_t)i + (size_t)k] = (float)o.xyz[3 * (size_t)i + (size_t)k];
    for (uint32_t k = 0; r == LM_OK && k < loops; ++k) {
        lp[4 * (size_t)k] = (int32_t)o.loop[k];
        lp[4 * (size_t)k + 1] = (int32_t)(o.loop[k + 1] - o.loop[k]);
        lp[4 * (size_t)k + 2] = o.loop_sign[k];
    }
    for (uint32_t l = 0; r == LM_OK && l < nl; ++l) {
        hl_light *L = &lights[l];
        if (l < s->area_light_count) {
            const scene_area_light *a = &s->area_lights[l];
            memcpy(L->le, a->le, 3 * sizeof(float));
            double centre[3], radius;
            cache_highlight_sphere(a, centre, &radius); /* the cache's tests skip the same lights */
            for (int k = 0; k < 3; ++k) L->sphere[k] = (float)centre[k];
            L->sphere[3] = (float)radius;
            L->loops[0] = o.light_loop[l];
            L->loops[1] = o.light_loop[l + 1] - o.light_loop[l];
        } else {
            const scene_point_light *p = &s->point_lights[l - s->area_light_count];
            memcpy(L->le, p->intensity, 3 * sizeof(float));
            memcpy(L->sphere, p->position, 3 * sizeof(float));
            L->loops[2] = 1;
        }
        memcpy(rad + 3 * (size_t)l, L->le, 3 * sizeof(float));
    }
    if (r == LM_OK) {
        gl->DeleteBuffers(3, f->hl_ssbo);
        gl->CreateBuffers(3, f->hl_ssbo);
        gl->NamedBufferStorage(f->hl_ssbo[0], (GLsizeiptr)((nl ? nl : 1) * sizeof *lights), lights, GL_DYNAMIC_STORAGE_BIT);
        gl->NamedBufferStorage(f->hl_ssbo[1], (GLsizeiptr)(4 * (size_t)(loops ? loops : 1) * sizeof *lp), lp, 0);
        gl->NamedBufferStorage(f->hl_ssbo[2], (GLsizeiptr)(4 * (size_t)(points ? points : 1) * sizeof *pts), pts, 0);
        free(f->hl_radiance);
        f->hl_radiance = rad;
        rad = NULL;
        f->hl_light_count = nl;
    }
    if (nl) cache_outlines_free(&o);
    free(lights);
    free(lp);
    free(pts);
    free(rad);
    return r;
}

/* The scene's triangles (unwelded, with their material codes) and material
 * table, in buffers that replace any before them (the vertex array's format is
 * made once, in make_scene_vao). */
static lm_result upload_scene(rend_frame *f, const scene *s, lm_error *err)
{
    const GladGLContext *gl = f->gl;
    size_t nv = 3 * (size_t)s->tri_count, nm = s->material_count;
    /* The material pass's codes are 2·(triangle + 1) | 1 in 32 bits, and the
     * corners are texels of a buffer texture. */
    GLint texels = 0;
    gl->GetIntegerv(GL_MAX_TEXTURE_BUFFER_SIZE, &texels);
    if (s->tri_count >= (1u << 31) - 1u || nv > (size_t)texels)
        return lm_fail(err, LM_ERR_INVALID_ARG,
                       "renderer: %u triangles are more than this GL draws (%d corners in a buffer texture)",
                       s->tri_count, (int)texels);
    material_vertex *verts = malloc((nv ? nv : 1) * sizeof *verts);
    material_entry *mats = calloc(nm ? nm : 1, sizeof *mats);
    if (!verts || !mats) {
        free(verts);
        free(mats);
        return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory creating the renderer");
    }
    for (uint32_t t = 0; t < s->tri_count; ++t)
        for (int c = 0; c < 3; ++c) {
            material_vertex *v = verts + 3 * (size_t)t + (size_t)c;
            memcpy(v->position, s->positions + 3 * (size_t)s->tris[t].v[c], sizeof v->position);
            v->code = 2u * (s->tris[t].material + 1u);
        }
    for (size_t m = 0; m < nm; ++m) {
        memcpy(mats[m].kd, s->materials[m].kd, 3 * sizeof(float));
        memcpy(mats[m].ks, s->materials[m].ks, 3 * sizeof(float));
        memcpy(mats[m].le, s->materials[m].le, 3 * sizeof(float));
    }
    GLuint old[2] = {f->scene_vbo, f->material_ssbo};
    gl->DeleteBuffers(2, old);
    gl->CreateBuffers(1, &f->scene_vbo);
    gl->NamedBufferStorage(f->scene_vbo, (GLsizeiptr)((nv ? nv : 1) * sizeof *verts), verts, 0);
    gl->CreateBuffers(1, &f->material_ssbo);
    gl->NamedBufferStorage(f->material_ssbo, (GLsizeiptr)((nm ? nm : 1) * sizeof *mats), mats,
                           GL_DYNAMIC_STORAGE_BIT);
    free(verts);
    free(mats);
    gl->VertexArrayVertexBuffer(f->scene_vao, 0, f->scene_vbo, 0, sizeof(material_vertex));
    /* The same corners as texels (position bits, code) for the composite's
     * materials and the whole roots' pass. */
    gl->DeleteTextures(1, &f->scene_tex);
    gl->CreateTextures(GL_TEXTURE_BUFFER, 1, &f->scene_tex);
    gl->TextureBuffer(f->scene_tex, GL_RGBA32UI, f->scene_vbo);
    f->desc.scene = s;
    return upload_lights(f, s, err);
}

static void make_scene_vao(rend_frame *f)
{
    const GladGLContext *gl = f->gl;
    gl->CreateVertexArrays(1, &f->scene_vao);
    gl->EnableVertexArrayAttrib(f->scene_vao, 0);
    gl->VertexArrayAttribFormat(f->scene_vao, 0, 3, GL_FLOAT, GL_FALSE, (GLuint)offsetof(material_vertex, position));
    gl->VertexArrayAttribBinding(f->scene_vao, 0, 0);
}

/* What a renderer made ahead of its scene does instead (rend_frame_create with
 * no scene): a stand-in drawn through every pass and forgotten. llvmpipe
 * compiles a program's shader variants (per program and pipeline state: the
 * targets' formats, depth test, vertex formats) at its first draw, not at link
 * time: CornellBox-Original's first picture at 640×480 took 49-65 ms against
 * 12 ms for the next (docs/renderer.md, "The renderer made ahead"). The
 * stand-in is one triangle of one material facing the camera, its one triangle
 * in each term, drawn with the renderer's own images, vertex arrays and state,
 * so the variants made are those the first real picture uses. */
static lm_result prime(rend_frame *f, lm_error *err)
{
    float positions[9] = {-1.0f, -1.0f, 0.0f, 1.0f, -1.0f, 0.0f, 0.0f, 1.0f, 0.0f};
    scene_tri tri = {.v = {0, 1, 2}, .material = 0, .light = -1};
    scene_material mat = {.kd = {0.5f, 0.5f, 0.5f}, .ks = {0.1f, 0.1f, 0.1f}, .n = 10.0f};
    scene stand_in = {.positions = positions, .vertex_count = 3, .tris = &tri, .tri_count = 1,
                      .materials = &mat, .material_count = 1, .bounds_min = {-1.0f, -1.0f, 0.0f},
                      .bounds_max = {1.0f, 1.0f, 0.0f}};
    scene_camera cam = {.position = {0.0f, 0.0f, 3.0f}, .up = {0.0f, 1.0f, 0.0f}, .fov_y_deg = 60.0f,
                        .width = f->desc.width, .height = f->desc.height};
    cache_snapshot_vertex v[3];
    for (int k = 0; k < 3; ++k) {
        memcpy(v[k].position, positions + 3 * k, sizeof v[k].position);
        v[k].value[0] = v[k].value[1] = v[k].value[2] = 1.0f;
    }
    const uint32_t index[3] = {0, 1, 2};
    const cache_snapshot_mesh one = {.vertices = v, .index = index, .triangle_count = 1, .vertex_count = 3};
    cache_snapshot_mesh spec = one;
    const cache_lobe lobe = {.normal = {0.0f, 0.0f, 1.0f}, .exponent = 10.0f, .visible = 1.0f};
    const cache_lobe lobes[3] = {lobe, lobe, lobe};
    spec.lobes = lobes;
    /* The indirect term as a whole root: its pass is compiled too. */
    const uint32_t mask = 1u, corners[3] = {0, 1, 2};
    const float values[9] = {1.0f, 1.0f, 1.0f, 1.0f, 1.0f, 1.0f, 1.0f, 1.0f, 1.0f};
    const cache_snapshot_mesh whole = {.whole = &mask, .values = values, .whole_count = 1, .value_count = 3};
    const cache_snapshot snap = {.generation = 1, .direct = one, .indirect = whole, .specular = spec,
                                 .corner_ids = corners, .corner_ids_serial = UINT64_MAX};
    lm_result r = upload_scene(f, &stand_in, err);
    if (r == LM_OK) r = rend_frame_draw(f, &cam, &snap, NULL, err);
    f->desc.scene = NULL;
    return r;
}

/* Whether w × h pixels of s × s samples fit this GL and the limits. */
static lm_result check_size(const GladGLContext *gl, int w, int h, int ss, lm_error *err)
{
    if (w < 1 || h < 1 || ss < 1 || ss > REND_FRAME_SUPERSAMPLE_MAX || (long)w * ss > 16384 || (long)h * ss > 16384)
        return lm_fail(err, LM_ERR_INVALID_ARG,
                       "renderer: needs a size from 1x1 to 16384x16384 and 1..%d samples per pixel side, "
                       "at most 16384 samples per row and column",
                       REND_FRAME_SUPERSAMPLE_MAX);
    GLint max_size = 0, max_rb = 0;
    gl->GetIntegerv(GL_MAX_TEXTURE_SIZE, &max_size);
    gl->GetIntegerv(GL_MAX_RENDERBUFFER_SIZE, &max_rb);
    if (max_rb < max_size) max_size = max_rb;
    if ((long)w * ss > max_size || (long)h * ss > max_size)
        return lm_fail(err, LM_ERR_INVALID_ARG, "renderer: %dx%d with %dx%d samples per pixel exceeds this GL's %d", w,
                       h, ss, ss, (int)max_size);
    return LM_OK;
}

/* The images and their framebuffers (not the vertex arrays or programs). */
static void free_images(rend_frame *f)
{
    const GladGLContext *gl = f->gl;
    GLuint texs[4] = {f->mat_tex, f->band_tex, f->val_tex, f->out_tex};
    GLuint fbos[3] = {f->mat_fbo, f->val_fbo, f->out_fbo};
    gl->DeleteTextures(4, texs);
    gl->DeleteRenderbuffers(1, &f->depth);
    gl->DeleteFramebuffers(3, fbos);
    f->mat_tex = f->band_tex = f->val_tex = f->out_tex = f->depth = f->mat_fbo = f->val_fbo = f->out_fbo = 0;
    for (int t = 0; t < TERMS; ++t) {
        gl->DeleteTextures(1, &f->term[t].tex);
        gl->DeleteFramebuffers(1, &f->term[t].fbo);
        f->term[t].tex = f->term[t].fbo = 0;
    }
    f->images_ok = 0;
}

/* The images for desc.width × desc.height pixels of s × s samples (sw, sh and
 * band set here). On failure none are kept. */
static lm_result make_images(rend_frame *f, lm_error *err)
{
    const GladGLContext *gl = f->gl;
    const int ss = f->desc.supersample, w = f->desc.width, h = f->desc.height;
    f->sw = w * ss;
    f->sh = h * ss;
    f->band = f->sh;
    if (ss > 1) { /* whole pixels' rows, at least one */
        int rows = (f->desc.band_samples > 0 ? f->desc.band_samples : REND_FRAME_BAND_SAMPLES) / f->sw;
        rows -= rows % ss;
        f->band = rows < ss ? ss : rows > f->sh ? f->sh : rows;
    }
    f->depth = depth_target(gl, f->sw, f->band);
    gl->CreateFramebuffers(1, &f->mat_fbo);
    f->mat_tex = color_target(gl, GL_R32UI, f->sw, f->sh);
    if (ss > 1) f->band_tex = color_target(gl, GL_R32UI, f->sw, f->band);
    gl->NamedFramebufferTexture(f->mat_fbo, GL_COLOR_ATTACHMENT0, ss > 1 ? f->band_tex : f->mat_tex, 0);
    gl->NamedFramebufferRenderbuffer(f->mat_fbo, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, f->depth);
    /* RGBA32F: an RGBA16F image was no faster to draw on llvmpipe (the cost
     * is per triangle) and would overflow above 65504 (docs/renderer.md). */
    if (ss > 1) {
        gl->CreateFramebuffers(1, &f->val_fbo);
        f->val_tex = color_target(gl, GL_RGBA32F, f->sw, f->band);
        gl->NamedFramebufferTexture(f->val_fbo, GL_COLOR_ATTACHMENT0, f->val_tex, 0);
        gl->NamedFramebufferRenderbuffer(f->val_fbo, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, f->depth);
    }
    /* Summed into the output (one_snapshot at s > 1: rend_frame.c), no term images. */
    for (int t = 0; t < TERMS && !(f->desc.one_snapshot && ss > 1); ++t) {
        term_state *ts = &f->term[t];
        gl->CreateFramebuffers(1, &ts->fbo);
        ts->tex = color_target(gl, GL_RGBA32F, w, h);
        gl->NamedFramebufferTexture(ts->fbo, GL_COLOR_ATTACHMENT0, ts->tex, 0);
        if (ss == 1) gl->NamedFramebufferRenderbuffer(ts->fbo, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, f->depth);
    }

    gl->CreateFramebuffers(1, &f->out_fbo);
    f->out_tex = color_target(gl, GL_RGBA32F, w, h);
    gl->NamedFramebufferTexture(f->out_fbo, GL_COLOR_ATTACHMENT0, f->out_tex, 0);

    GLuint fbos[3 + TERMS] = {f->mat_fbo, f->out_fbo, f->term[0].fbo, f->term[1].fbo, f->term[2].fbo,
                              f->val_fbo};
    for (int i = 0; i < 2 + TERMS + (ss > 1); ++i)
        if (fbos[i] && gl->CheckNamedFramebufferStatus(fbos[i], GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE) {
            free_images(f);
            return lm_fail(err, LM_ERR_RUNTIME, "renderer: a %dx%d framebuffer is not complete on this GL", f->sw,
                           f->sh);
        }
    if (gl->GetError() != GL_NO_ERROR) {
        free_images(f);
        return lm_fail(err, LM_ERR_RUNTIME, "renderer: a GL error occurred creating %dx%d targets (out of memory?)",
                       f->sw, f->sh);
    }
    f->images_ok = 1;
    return LM_OK;
}

lm_result rend_frame_create(const GladGLContext *gl, const rend_frame_desc *desc, rend_frame **out, lm_error *err)
{
    *out = NULL;
    int ss = desc ? desc->supersample : 0;
    if (desc && ss == 0) { /* the default, lowered where its images would be large */
        ss = REND_FRAME_SUPERSAMPLE_DEFAULT;
        while (ss > 1 && (double)ss * ss * desc->width * desc->height > REND_FRAME_DEFAULT_SAMPLES_MAX) --ss;
    }
    if (!gl || !desc) return lm_fail(err, LM_ERR_INVALID_ARG, "renderer: no GL context or no description");
    lm_result r = check_size(gl, desc->width, desc->height, ss, err);
    if (r != LM_OK) return r;
    rend_frame *f = calloc(1, sizeof *f);
    if (!f) return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory creating the renderer");
    f->desc = *desc;
    f->desc.supersample = ss;
    f->gl = gl;
    f->components = REND_FRAME_COMPONENTS_ALL;
    char defines[64];
    snprintf(defines, sizeof defines, "#define SS %d\n", ss);
    r = glprog_build(gl, "renderer", material_names, "", &f->prog_material, err);
    if (r == LM_OK) r = glprog_build(gl, "renderer", value_names, "", &f->prog_value, err);
    if (r == LM_OK && ss > 1) r = glprog_build(gl, "renderer", resolve_names, defines, &f->prog_resolve, err);
    if (r == LM_OK) r = glprog_build(gl, "renderer", composite_names, defines, &f->prog_composite, err);
    if (r == LM_OK) r = glprog_build(gl, "renderer", whole_names, "", &f->prog_whole, err);
    /* Materials with a Phong exponent below CACHE_HIGHLIGHT_MIN_EXPONENT keep the
     * specular mesh's interpolated value: a lobe that broad varies little across a
     * leaf, and its integral would cost a pass over the light's outline in every
     * pixel of it (the door's copper, n ≈ 1). Lights partly hidden keep it too
     * (CACHE_HIGHLIGHT_MIN_VISIBLE). The cache's tests judge the same. */
    char hl_defines[192];
    snprintf(hl_defines, sizeof hl_defines,
             "#define HIGHLIGHT 1\n#define HIGHLIGHT_MIN_N %.1f\n#define SKIP_CORE %.1f\n#define MIN_VISIBLE %.4f\n",
             CACHE_HIGHLIGHT_MIN_EXPONENT, CACHE_HIGHLIGHT_SKIP_CORE, CACHE_HIGHLIGHT_MIN_VISIBLE);
    if (r == LM_OK) r = glprog_build(gl, "renderer", value_names, hl_defines, &f->prog_highlight, err);
    if (r != LM_OK) {
        rend_frame_destroy(f);
        return r;
    }
    make_scene_vao(f);
    f->loc_mat_vp = gl->GetUniformLocation(f->prog_material, "u_viewproj");
    f->loc_val_vp = gl->GetUniformLocation(f->prog_value, "u_viewproj");
    f->loc_hl_vp = gl->GetUniformLocation(f->prog_highlight, "u_viewproj");
    f->loc_hl_eye = gl->GetUniformLocation(f->prog_highlight, "u_eye");
    f->loc_hl_count = gl->GetUniformLocation(f->prog_highlight, "u_light_count");
    if (ss > 1) f->loc_res_term = gl->GetUniformLocation(f->prog_resolve, "u_term");
    if (ss > 1) f->loc_res_band = gl->GetUniformLocation(f->prog_resolve, "u_band_y0");
    f->loc_comp_terms = gl->GetUniformLocation(f->prog_composite, "u_terms");
    f->loc_whole_vp = gl->GetUniformLocation(f->prog_whole, "u_viewproj");
    f->loc_whole_band = gl->GetUniformLocation(f->prog_whole, "u_band_y0");
    f->loc_whole_samples = gl->GetUniformLocation(f->prog_whole, "u_samples");
    gl->CreateVertexArrays(1, &f->empty_vao);
    for (int t = 0; t < TERMS; ++t) gl->CreateVertexArrays(1, &f->term[t].vao);
    r = make_images(f, err);
    if (r == LM_OK) r = desc->scene ? rend_frame_set_scene(f, desc->scene, err) : prime(f, err);
    if (r != LM_OK) {
        rend_frame_destroy(f);
        return r;
    }
    *out = f;
    return LM_OK;
}

lm_result rend_frame_resize(rend_frame *f, int width, int height, lm_error *err)
{
    if (!f) return lm_fail(err, LM_ERR_INVALID_ARG, "rend_frame_resize: no renderer");
    if (f->images_ok && width == f->desc.width && height == f->desc.height) return LM_OK;
    lm_result r = check_size(f->gl, width, height, f->desc.supersample, err);
    if (r != LM_OK) return r; /* the images as they were */
    free_images(f);
    f->desc.width = width;
    f->desc.height = height;
    rend_frame_invalidate(f);
    return make_images(f, err);
}

lm_result rend_frame_set_scene(rend_frame *f, const scene *s, lm_error *err)
{
    if (!f || !s) return lm_fail(err, LM_ERR_INVALID_ARG, "rend_frame_set_scene: no renderer or no scene");
    lm_result r = upload_scene(f, s, err);
    /* Nothing drawn before is kept: not the images, nor the meshes' copies
     * (a stand-in's, or another scene's). */
    rend_frame_invalidate(f);
    for (int t = 0; t < TERMS; ++t) {
        term_state *ts = &f->term[t];
        ts->copy = (cache_snapshot_mesh){0};
        ts->src = NULL;
        ts->hash_valid = 0;
        ts->whole_count = ts->value_count = 0;
        ts->whole_src = NULL;
        ts->whole_owed = 0;
    }
    f->corner_serial = 0; /* the stand-in's corners, or another scene's */
    if (r == LM_OK && f->gl->GetError() != GL_NO_ERROR)
        r = lm_fail(err, LM_ERR_RUNTIME, "renderer: a GL error occurred uploading %u triangles (out of memory?)",
                    s->tri_count);
    if (r != LM_OK) f->desc.scene = NULL;
    return r;
}

void rend_frame_invalidate(rend_frame *f)
{
    if (!f) return;
    f->mat_valid = f->val_valid = f->snap_valid = f->comp_valid = 0;
    for (int t = 0; t < TERMS; ++t) f->term[t].drawn = f->term[t].highlights_owed = 0;
}
