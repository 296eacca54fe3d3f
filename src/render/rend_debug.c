/* rend_debug.c — leaf wireframes and sample positions over the image
 * (rend_debug.h; Fournier & Péroche 2005, Fig. 4b/4c). */
#define _POSIX_C_SOURCE 200809L /* mkdir */
#include "src/render/rend_debug.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "src/image/image.h"
#include "src/scene/camera.h"

rend_debug_desc rend_debug_defaults(const rend_debug_desc *d)
{
    rend_debug_desc o = *d;
    if (o.dim == 0.0f) o.dim = REND_DEBUG_DIM;
    if (o.wire_color == 0) o.wire_color = REND_DEBUG_WIRE_COLOR;
    if (o.point_color == 0) o.point_color = REND_DEBUG_POINT_COLOR;
    if (o.dot_radius == 0) o.dot_radius = REND_DEBUG_DOT_RADIUS;
    return o;
}

/* ---- projection: the shared camera's matrix (src/scene/camera.h) ---------------------- */

typedef struct proj {
    double m[16];   /* world -> clip, column-major */
    int w, h;
} proj;

static void proj_init(proj *p, const rend_debug_desc *d)
{
    float vp[16];
    /* Only x, y and w are used (w: distance along the view axis), so the near
     * plane, which sets z alone, does not matter. */
    camera_viewproj(d->camera, d->width, d->height, 1.0f, vp);
    for (int i = 0; i < 16; ++i) p->m[i] = vp[i];
    p->w = d->width, p->h = d->height;
}

/* Clip coordinates x, y, w of a world point. */
static void proj_clip(const proj *p, const float q[3], double c[3])
{
    const int rows[3] = {0, 1, 3};
    for (int i = 0; i < 3; ++i) {
        int r = rows[i];
        c[i] = p->m[r] * q[0] + p->m[4 + r] * q[1] + p->m[8 + r] * q[2] + p->m[12 + r];
    }
}

/* Clip coordinates -> pixel coordinates from the top-left corner. */
static void proj_pixel(const proj *p, const double c[3], double *px, double *py)
{
    *px = 0.5 * (c[0] / c[2] + 1.0) * p->w;
    *py = 0.5 * (1.0 - c[1] / c[2]) * p->h;
}

static int in_front(const double c[3]) { return c[2] > 0.0 && isfinite(c[0]) && isfinite(c[1]) && isfinite(c[2]); }

int rend_debug_project(const rend_debug_desc *d, const float q[3], double *px, double *py)
{
    if (!d || !d->camera || d->width <= 0 || d->height <= 0 || !q) return 0;
    proj p;
    proj_init(&p, d);
    double c[3];
    proj_clip(&p, q, c);
    if (!in_front(c)) return 0;
    proj_pixel(&p, c, px, py);
    return 1;
}

/* Clips segment a-b (clip space) to the view frustum, widened by two pixels on
 * every side, and in front of the eye (Liang–Barsky in homogeneous coordinates).
 * Returns 0 if nothing is left. */
static int clip_segment(const proj *p, double a[3], double b[3])
{
    const double mx = 1.0 + 4.0 / p->w, my = 1.0 + 4.0 / p->h;
    const double wmin = 1e-9 * (fabs(a[2]) + fabs(b[2])) + 1e-30;
    double fa[5] = {a[2] - wmin, mx * a[2] - a[0], mx * a[2] + a[0], my * a[2] - a[1], my * a[2] + a[1]};
    double fb[5] = {b[2] - wmin, mx * b[2] - b[0], mx * b[2] + b[0], my * b[2] - b[1], my * b[2] + b[1]};
    double t0 = 0.0, t1 = 1.0;
    for (int i = 0; i < 5; ++i) {
        if (fa[i] < 0.0 && fb[i] < 0.0) return 0;
        if (fa[i] < 0.0) t0 = fmax(t0, fa[i] / (fa[i] - fb[i]));
        else if (fb[i] < 0.0) t1 = fmin(t1, fa[i] / (fa[i] - fb[i]));
    }
    if (!(t0 <= t1)) return 0;
    double na[3], nb[3];
    for (int k = 0; k < 3; ++k) {
        na[k] = a[k] + t0 * (b[k] - a[k]);
        nb[k] = a[k] + t1 * (b[k] - a[k]);
    }
    memcpy(a, na, sizeof na);
    memcpy(b, nb, sizeof nb);
    return a[2] > 0.0 && b[2] > 0.0;
}

/* ---- occlusion ------------------------------------------------------------------------ */

/* Non-zero when the ID image shows one of tris[0..n) at (x, y) or one of its 8 neighbours. */
static int shows(const rend_debug_desc *d, int x, int y, const uint32_t *tris, size_t n)
{
    for (int dy = -1; dy <= 1; ++dy) {
        int yy = y + dy;
        if (yy < 0 || yy >= d->height) continue;
        for (int dx = -1; dx <= 1; ++dx) {
            int xx = x + dx;
            if (xx < 0 || xx >= d->width) continue;
            uint32_t id = d->ids[(size_t)yy * (size_t)d->width + (size_t)xx];
            if (id == 0) continue;
            for (size_t i = 0; i < n; ++i)
                if (id == tris[i] + 1) return 1;
        }
    }
    return 0;
}

/* ---- common ----------------------------------------------------------------------------- */

static lm_result check_args(const rend_debug_desc *d, const cache_snapshot_mesh *m, const uint8_t *out,
                            const char *what, lm_error *err)
{
    if (!d || !m || !out || !d->camera || !d->ids)
        return lm_fail(err, LM_ERR_INVALID_ARG, "%s: needs a camera, an ID image, a mesh and an output image", what);
    if (d->width <= 0 || d->height <= 0 || d->width > 65536 || d->height > 65536)
        return lm_fail(err, LM_ERR_INVALID_ARG, "%s: bad image size %dx%d", what, d->width, d->height);
    if (!(d->dim >= 0.0f && d->dim <= 1.0f))
        return lm_fail(err, LM_ERR_INVALID_ARG, "%s: dim must be in (0, 1], not %g", what, (double)d->dim);
    if (d->dot_radius < 0 || d->dot_radius > 16)
        return lm_fail(err, LM_ERR_INVALID_ARG, "%s: dot radius must be 0..16 pixels, not %d", what, d->dot_radius);
    if (m->triangle_count && (!m->vertices || !m->index || !m->tri))
        return lm_fail(err, LM_ERR_INVALID_ARG, "%s: a mesh with triangles but no vertices", what);
    if (m->triangle_count && !m->corners)
        return lm_fail(err, LM_ERR_INVALID_ARG,
                       "%s: the mesh has no corner data (create the worker with publish_debug)", what);
    return LM_OK;
}

/* out = dim·background, then colour (alpha-blended) wherever mask is set. */
static uint64_t compose(const rend_debug_desc *d, const uint8_t *mask, uint32_t color, uint8_t *out)
{
    const size_t n = (size_t)d->width * (size_t)d->height;
    const float a = (float)(color & 0xFFu) / 255.0f;
    const float c[3] = {(float)(color >> 24), (float)((color >> 16) & 0xFFu), (float)((color >> 8) & 0xFFu)};
    uint64_t set = 0;
    for (size_t i = 0; i < n; ++i) {
        for (int k = 0; k < 3; ++k) {
            float v = d->background ? d->dim * (float)d->background[3 * i + (size_t)k] : 0.0f;
            if (mask[i]) v = (1.0f - a) * v + a * c[k];
            out[3 * i + (size_t)k] = (uint8_t)(v + 0.5f);
        }
        set += mask[i] != 0;
    }
    return set;
}

/* ---- the leaf wireframe ----------------------------------------------------------------- */

typedef struct edge_rec {
    uint64_t key;      /* (smaller vertex id << 32) | larger */
    uint32_t tri;      /* scene triangle of the leaf it bounds */
    uint32_t corner;   /* index of its first corner in the mesh's corner arrays */
} edge_rec;

static int edge_cmp(const void *pa, const void *pb)
{
    const edge_rec *a = pa, *b = pb;
    if (a->key != b->key) return a->key < b->key ? -1 : 1;
    return a->tri < b->tri ? -1 : a->tri > b->tri;
}

/* Rasterizes a-b (pixel coordinates, pixel centres at +½) with a DDA: an
 * 8-connected line, one pixel per step along the major axis. Endpoints are taken
 * in a fixed order so coincident segments give identical pixels. */
static int draw_segment(const rend_debug_desc *d, double ax, double ay, double bx, double by, const uint32_t *tris,
                        size_t ntri, uint8_t *mask)
{
    if (bx < ax || (bx == ax && by < ay)) {
        double t = ax; ax = bx; bx = t;
        t = ay; ay = by; by = t;
    }
    ax -= 0.5, ay -= 0.5, bx -= 0.5, by -= 0.5;
    const double len = fmax(fabs(bx - ax), fabs(by - ay));
    const long steps = (long)ceil(len);
    int drawn = 0;
    for (long i = 0; i <= steps; ++i) {
        double t = steps ? (double)i / (double)steps : 0.0;
        long x = lround(ax + t * (bx - ax)), y = lround(ay + t * (by - ay));
        if (x < 0 || y < 0 || x >= d->width || y >= d->height) continue;
        if (!shows(d, (int)x, (int)y, tris, ntri)) continue;
        mask[(size_t)y * (size_t)d->width + (size_t)x] = 1;
        drawn = 1;
    }
    return drawn;
}

/* What both overlays start and end with: arguments checked, defaults filled, the
 * clock started, a pixel mask and per-corner scratch (records of rec_size bytes
 * and triangle ids). */
typedef struct overlay_work {
    rend_debug_desc d;
    size_t ncorner;
    uint8_t *mask;
    void *recs;
    uint32_t *tris;
    double t0;
} overlay_work;

static lm_result overlay_begin(const rend_debug_desc *din, const cache_snapshot_mesh *m, uint8_t *out_rgb,
                               rend_debug_counts *counts, size_t rec_size, const char *who, overlay_work *w,
                               lm_error *err)
{
    memset(w, 0, sizeof *w);
    w->t0 = lm_now_seconds();
    if (counts) memset(counts, 0, sizeof *counts);
    lm_result r = check_args(din, m, out_rgb, who, err);
    if (r != LM_OK) return r;
    w->d = rend_debug_defaults(din);
    w->ncorner = 3 * (size_t)m->triangle_count;
    size_t n = w->ncorner ? w->ncorner : 1;
    w->mask = calloc((size_t)w->d.width * (size_t)w->d.height, 1);
    w->recs = malloc(n * rec_size);
    w->tris = malloc(n * sizeof *w->tris);
    if (!w->mask || !w->recs || !w->tris) {
        free(w->mask), free(w->recs), free(w->tris);
        return lm_fail(err, LM_ERR_NO_MEMORY, "%s: out of memory for %zu corners", who, w->ncorner);
    }
    return LM_OK;
}

/* Frees the scratch and hands out the counts with the time taken. */
static void overlay_end(overlay_work *w, rend_debug_counts *n, rend_debug_counts *counts)
{
    free(w->mask), free(w->recs), free(w->tris);
    n->seconds = lm_now_seconds() - w->t0;
    if (counts) *counts = *n;
}

lm_result rend_debug_leaves(const rend_debug_desc *din, const cache_snapshot_mesh *m, uint8_t *out_rgb,
                            rend_debug_counts *counts, lm_error *err)
{
    overlay_work w;
    lm_result r = overlay_begin(din, m, out_rgb, counts, sizeof(edge_rec), "rend_debug_leaves", &w, err);
    if (r != LM_OK) return r;
    const rend_debug_desc d = w.d;
    const size_t ncorner = w.ncorner;
    uint8_t *mask = w.mask;
    edge_rec *e = w.recs;
    uint32_t *tris = w.tris;
    size_t ne = 0;
    for (size_t i = 0; i < ncorner; ++i) {
        if (!(m->corners[i].flags & CACHE_CORNER_LEAF_EDGE)) continue;
        uint32_t a = m->corners[i].vertex, b = m->corners[i - i % 3 + (i % 3 + 1) % 3].vertex;
        uint64_t lo = a < b ? a : b, hi = a < b ? b : a;
        e[ne++] = (edge_rec){.key = lo << 32 | hi, .tri = m->tri[i / 3], .corner = (uint32_t)i};
    }
    qsort(e, ne, sizeof *e, edge_cmp);
    proj p;
    proj_init(&p, &d);
    rend_debug_counts n = {0};
    for (size_t g = 0, end; g < ne; g = end) {
        size_t nt = 0;
        for (end = g; end < ne && e[end].key == e[g].key; ++end)
            if (nt == 0 || tris[nt - 1] != e[end].tri) tris[nt++] = e[end].tri;
        n.segments++;
        size_t i = e[g].corner, j = i - i % 3 + (i % 3 + 1) % 3;
        double a[3], b[3];
        proj_clip(&p, m->vertices[m->index[i]].position, a);
        proj_clip(&p, m->vertices[m->index[j]].position, b);
        if (!clip_segment(&p, a, b)) continue;
        double ax, ay, bx, by;
        proj_pixel(&p, a, &ax, &ay);
        proj_pixel(&p, b, &bx, &by);
        n.segments_drawn += (uint32_t)draw_segment(&d, ax, ay, bx, by, tris, nt, mask);
    }
    n.wire_pixels = compose(&d, mask, d.wire_color, out_rgb);
    overlay_end(&w, &n, counts);
    return LM_OK;
}

/* ---- the sample positions --------------------------------------------------------------- */

typedef struct vert_rec {
    uint32_t vertex, tri, corner;
} vert_rec;

static int vert_cmp(const void *pa, const void *pb)
{
    const vert_rec *a = pa, *b = pb;
    if (a->vertex != b->vertex) return a->vertex < b->vertex ? -1 : 1;
    return a->tri < b->tri ? -1 : a->tri > b->tri;
}

lm_result rend_debug_samples(const rend_debug_desc *din, const cache_snapshot_mesh *m, uint8_t *out_rgb,
                             rend_debug_counts *counts, lm_error *err)
{
    overlay_work w;
    lm_result r = overlay_begin(din, m, out_rgb, counts, sizeof(vert_rec), "rend_debug_samples", &w, err);
    if (r != LM_OK) return r;
    const rend_debug_desc d = w.d;
    const size_t ncorner = w.ncorner;
    uint8_t *mask = w.mask;
    vert_rec *v = w.recs;
    uint32_t *tris = w.tris;
    size_t nv = 0;
    for (size_t i = 0; i < ncorner; ++i)
        if (m->corners[i].flags & CACHE_CORNER_SAMPLED)
            v[nv++] = (vert_rec){.vertex = m->corners[i].vertex, .tri = m->tri[i / 3], .corner = (uint32_t)i};
    qsort(v, nv, sizeof *v, vert_cmp);
    proj p;
    proj_init(&p, &d);
    rend_debug_counts n = {0};
    const int rad = d.dot_radius;
    for (size_t g = 0, end; g < nv; g = end) {
        size_t nt = 0;
        for (end = g; end < nv && v[end].vertex == v[g].vertex; ++end)
            if (nt == 0 || tris[nt - 1] != v[end].tri) tris[nt++] = v[end].tri;
        double c[3], px, py;
        proj_clip(&p, m->vertices[m->index[v[g].corner]].position, c);
        int shown = 0;
        long x = -1, y = -1;
        if (in_front(c)) {
            proj_pixel(&p, c, &px, &py);
            if (px >= 0.0 && py >= 0.0 && px < d.width && py < d.height) {
                x = (long)px, y = (long)py;
                shown = shows(&d, (int)x, (int)y, tris, nt);
            }
        }
        if (!shown) {
            n.points_hidden++;
            continue;
        }
        n.points_drawn++;
        for (long dy = -rad; dy <= rad; ++dy)
            for (long dx = -rad; dx <= rad; ++dx) {
                long xx = x + dx, yy = y + dy;
                if (dx * dx + dy * dy > (long)rad * rad + rad || xx < 0 || yy < 0 || xx >= d.width || yy >= d.height)
                    continue;
                mask[(size_t)yy * (size_t)d.width + (size_t)xx] = 1;
            }
    }
    n.point_pixels = compose(&d, mask, d.point_color, out_rgb);
    overlay_end(&w, &n, counts);
    return LM_OK;
}

/* ---- files ------------------------------------------------------------------------------ */

/* mkdir -p: creates dir and its missing parents. */
static lm_result make_dirs(const char *dir, lm_error *err)
{
    char path[SCENE_PATH_MAX];
    size_t len = strlen(dir);
    if (len == 0 || len >= sizeof path) return lm_fail(err, LM_ERR_INVALID_ARG, "bad directory name '%s'", dir);
    memcpy(path, dir, len + 1);
    for (size_t i = 1; i <= len; ++i) {
        if (path[i] != '/' && path[i] != 0) continue;
        char keep = path[i];
        path[i] = 0;
        if (mkdir(path, 0777) != 0 && errno != EEXIST)
            return lm_fail(err, LM_ERR_IO, "%s: cannot create the directory: %s", path, strerror(errno));
        path[i] = keep;
    }
    struct stat st;
    if (stat(dir, &st) != 0 || !S_ISDIR(st.st_mode)) return lm_fail(err, LM_ERR_IO, "%s: not a directory", dir);
    return LM_OK;
}

lm_result rend_debug_write_images(const rend_debug_write_desc *wd, lm_error *err)
{
    if (!wd || !wd->draw || !wd->snap || !wd->dir)
        return lm_fail(err, LM_ERR_INVALID_ARG,
                       "rend_debug_write_images: needs drawing options, a snapshot and a directory");
    const rend_debug_desc *d = wd->draw;
    if (d->width <= 0 || d->height <= 0)
        return lm_fail(err, LM_ERR_INVALID_ARG, "rend_debug_write_images: bad image size %dx%d", d->width, d->height);
    lm_result r = make_dirs(wd->dir, err);
    if (r != LM_OK) return r;
    const cache_snapshot *s = wd->snap;
    uint8_t *img = malloc((size_t)d->width * (size_t)d->height * 3);
    if (!img) return lm_fail(err, LM_ERR_NO_MEMORY, "out of memory for a %dx%d image", d->width, d->height);
    const uint32_t total = s->light_mesh_count + 3;
    for (uint32_t i = 0; r == LM_OK && i < total; ++i) {
        const cache_snapshot_mesh *m;
        char name[32];
        if (i < s->light_mesh_count) {
            m = &s->lights[i];
            snprintf(name, sizeof name, "light%u", i);
        } else {
            const char *const names[3] = {"direct", "indirect", "specular"};
            const uint32_t k = i - s->light_mesh_count;
            m = k == 0 ? &s->direct : k == 1 ? &s->indirect : &s->specular;
            if (k == 2 && m->triangle_count == 0) continue;
            snprintf(name, sizeof name, "%s", names[k]);
        }
        for (int kind = 0; r == LM_OK && kind < 2; ++kind) {
            char path[SCENE_PATH_MAX + 64];
            snprintf(path, sizeof path, "%s/%s-%s.png", wd->dir, name, kind ? "samples" : "leaves");
            rend_debug_counts n;
            r = kind ? rend_debug_samples(d, m, img, &n, err) : rend_debug_leaves(d, m, img, &n, err);
            if (r == LM_OK)
                r = img_write(&(img_write_desc){.path = path, .width = d->width, .height = d->height, .channels = 3,
                                                .pixels8 = img},
                              err);
            if (r == LM_OK && wd->written) wd->written(path, &n, wd->user);
        }
    }
    free(img);
    return r;
}
