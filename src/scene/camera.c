/* camera.c — the shared pinhole camera (camera.h). */
#include "src/scene/camera.h"

#include <math.h>

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
    double n = 1e-5 * e;
    return n > 1e-30 ? (float)n : 1e-30f;
}
