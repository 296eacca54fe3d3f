/* camera.c — the shared pinhole camera (camera.h). */
#include "src/scene/camera.h"

#include <math.h>
#include <string.h>

#include "src/base/parallel.h"
#include "src/base/vecmath.h"

/* The one frame of the camera (camera.h): position, unit fwd, right, up, and
 * tan(fov_y/2). */
typedef struct frame {
    lm_dvec3 pos, fwd, right, up;
    double tan_half_fov;
} frame;

static frame camera_frame(const scene_camera *cam)
{
    frame f;
    f.pos = dv3_load(cam->position);
    f.fwd = dv3_normalize(dv3_sub(dv3_load(cam->target), f.pos));
    f.right = dv3_normalize(dv3_cross(f.fwd, dv3_load(cam->up)));
    f.up = dv3_cross(f.right, f.fwd);
    f.tan_half_fov = tan(0.5 * cam->fov_y_deg * M_PI / 180.0);
    return f;
}

static lm_vec3 to_float(lm_dvec3 a) { return v3((float)a.x, (float)a.y, (float)a.z); }

int camera_equal(const scene_camera *a, const scene_camera *b)
{
    for (int i = 0; i < 3; ++i)
        if (a->position[i] != b->position[i] || a->target[i] != b->target[i] || a->up[i] != b->up[i]) return 0;
    return a->fov_y_deg == b->fov_y_deg && a->width == b->width && a->height == b->height;
}

camera_basis camera_basis_make(const scene_camera *cam, int width, int height)
{
    frame c = camera_frame(cam);
    double ty = c.tan_half_fov, tx = ty * (double)width / (double)height;
    return (camera_basis){.position = to_float(c.pos),
                          .fwd = to_float(c.fwd),
                          .right = to_float(dv3_scale(c.right, tx)),
                          .up = to_float(dv3_scale(c.up, ty)),
                          .width = width,
                          .height = height};
}

lm_vec3 camera_ray_dir(const camera_basis *b, float x, float y)
{
    float sx = 2.0f * x / (float)b->width - 1.0f;
    float sy = 1.0f - 2.0f * y / (float)b->height;
    return v3_normalize(v3_add(b->fwd, v3_add(v3_scale(b->right, sx), v3_scale(b->up, sy))));
}

void camera_viewproj(const scene_camera *cam, int width, int height, float near, float out[16])
{
    frame c = camera_frame(cam);
    lm_dvec3 pos = c.pos, fwd = c.fwd, right = c.right, up = c.up;
    double f = 1.0 / c.tan_half_fov, aspect = (double)width / (double)height;
    /* rows of view·proj: x_clip = f/aspect·(right·(p−pos)), y_clip = f·(up·(p−pos)),
     * z_clip = near, w_clip = fwd·(p−pos) (distance along the view axis). */
    const double row[4][4] = {
        {f / aspect * right.x, f / aspect * right.y, f / aspect * right.z, -f / aspect * dv3_dot(right, pos)},
        {f * up.x, f * up.y, f * up.z, -f * dv3_dot(up, pos)},
        {0.0, 0.0, 0.0, near},
        {fwd.x, fwd.y, fwd.z, -dv3_dot(fwd, pos)},
    };
    for (int r = 0; r < 4; ++r)
        for (int c = 0; c < 4; ++c) out[c * 4 + r] = (float)row[r][c];
}

float camera_near(const scene *s)
{
    double e = 0.0;
    for (int k = 0; k < 3; ++k) e = fmax(e, (double)s->bounds_max[k] - s->bounds_min[k]);
    double n = 1e-8 * e;
    return n > 1e-30 ? (float)n : 1e-30f;
}

/* Sutherland–Hodgman: the part of polygon in[0..n) (2D or 3D points, `dim`
 * doubles each) where dot(coef, p) + c >= 0; at most n + 1 points out. */
static int clip_polygon(const double *in, int n, int dim, const double *coef, double c, double *out)
{
    int m = 0;
    for (int i = 0; i < n; ++i) {
        const double *a = in + dim * i, *b = in + dim * ((i + 1) % n);
        double da = c, db = c;
        for (int k = 0; k < dim; ++k) {
            da += coef[k] * a[k];
            db += coef[k] * b[k];
        }
        if (da >= 0.0) {
            for (int k = 0; k < dim; ++k) out[dim * m + k] = a[k];
            ++m;
        }
        if ((da >= 0.0) != (db >= 0.0)) {
            double t = da / (da - db);
            for (int k = 0; k < dim; ++k) out[dim * m + k] = a[k] + t * (b[k] - a[k]);
            ++m;
        }
    }
    return m;
}

/* camera_triangle_pixels over a chunk of PIXELS_CHUNK triangles (lm_parallel_for:
 * each writes its own triangles' counts; a million triangles took 0.12 s on one
 * core, before the refinement worker could start: docs/cache.md, "The first
 * roots on two threads"). */
enum { PIXELS_CHUNK = 4096 };

typedef struct pixels_job {
    const scene *s;
    frame c;
    int width, height;
    uint32_t *pixels;
} pixels_job;

static void pixels_chunk(void *user, uint32_t chunk)
{
    const pixels_job *job = user;
    const scene *s = job->s;
    const frame c = job->c;
    const int width = job->width, height = job->height;
    uint32_t *pixels = job->pixels;
    const double ty = c.tan_half_fov, tx = ty * (double)width / (double)height, near = camera_near(s);
    const double keep_front[3] = {0.0, 0.0, 1.0};
    const double edges[4][3] = {{1, 0, 0}, {-1, 0, (double)width}, {0, 1, 0}, {0, -1, (double)height}};
    const uint32_t end = s->tri_count - chunk * PIXELS_CHUNK < PIXELS_CHUNK ? s->tri_count : (chunk + 1) * PIXELS_CHUNK;
    for (uint32_t t = chunk * PIXELS_CHUNK; t < end; ++t) {
        double view[3 * 4], clipped[3 * 4], screen[2 * 8], tmp[2 * 8];
        for (int k = 0; k < 3; ++k) {
            lm_dvec3 d = dv3_sub(dv3_load(s->positions + 3 * (size_t)s->tris[t].v[k]), c.pos);
            view[3 * k] = dv3_dot(d, c.right);
            view[3 * k + 1] = dv3_dot(d, c.up);
            view[3 * k + 2] = dv3_dot(d, c.fwd);
        }
        int n = clip_polygon(view, 3, 3, keep_front, -near, clipped);
        for (int k = 0; k < n; ++k) { /* pixels from the top-left corner, as camera_ray_dir */
            screen[2 * k] = 0.5 * (clipped[3 * k] / (clipped[3 * k + 2] * tx) + 1.0) * width;
            screen[2 * k + 1] = 0.5 * (1.0 - clipped[3 * k + 1] / (clipped[3 * k + 2] * ty)) * height;
        }
        for (int e = 0; e < 4 && n > 0; ++e) {
            n = clip_polygon(screen, n, 2, edges[e], edges[e][2], tmp);
            memcpy(screen, tmp, sizeof(double) * 2 * (size_t)n);
        }
        double area = 0.0;
        for (int k = 0; k < n; ++k) {
            const double *a = screen + 2 * k, *b = screen + 2 * ((k + 1) % n);
            area += a[0] * b[1] - b[0] * a[1];
        }
        area = fabs(0.5 * area);
        pixels[t] = area >= (double)width * height ? (uint32_t)width * (uint32_t)height : (uint32_t)(area + 0.5);
    }
}

void camera_triangle_pixels(const scene *s, const scene_camera *cam, int width, int height, uint32_t *pixels)
{
    pixels_job job = {s, camera_frame(cam), width, height, pixels};
    const uint32_t chunks = s->tri_count / PIXELS_CHUNK + (s->tri_count % PIXELS_CHUNK != 0);
    lm_parallel_for(lm_thread_count(0), chunks, pixels_chunk, &job);
}

