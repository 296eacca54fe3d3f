/* camera.c — the shared pinhole camera (camera.h). */
#include "src/scene/camera.h"

#include <math.h>

#include "src/base/vecmath.h"

void camera_viewproj(const scene_camera *cam, int width, int height, float near, float out[16])
{
    lm_dvec3 pos = dv3_load(cam->position);
    lm_dvec3 fwd = dv3_normalize(dv3_sub(dv3_load(cam->target), pos));
    lm_dvec3 right = dv3_normalize(dv3_cross(fwd, dv3_load(cam->up)));
    lm_dvec3 up = dv3_cross(right, fwd);
    double f = 1.0 / tan(0.5 * cam->fov_y_deg * M_PI / 180.0), aspect = (double)width / (double)height;
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
