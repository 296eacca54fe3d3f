/* view_camera.c — orbit, zoom and framing for the viewer (view_camera.h). In
 * double, rounded to the camera's floats once per move. */
#include "src/view/view_camera.h"

#include <math.h>

static const double k_deg = 3.14159265358979323846 / 180.0;

static double dot3(const double a[3], const double b[3]) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

static void cross3(const double a[3], const double b[3], double o[3])
{
    o[0] = a[1] * b[2] - a[2] * b[1];
    o[1] = a[2] * b[0] - a[0] * b[2];
    o[2] = a[0] * b[1] - a[1] * b[0];
}

static int normalize3(double v[3])
{
    double l = sqrt(dot3(v, v));
    if (!(l > 1e-12)) return 0;
    for (int i = 0; i < 3; ++i) v[i] /= l;
    return 1;
}

/* Rodrigues: v turned by angle (radians) about the unit axis k. */
static void rotate3(const double v[3], const double k[3], double angle, double o[3])
{
    double c = cos(angle), s = sin(angle), kv = dot3(k, v), kxv[3];
    cross3(k, v, kxv);
    for (int i = 0; i < 3; ++i) o[i] = v[i] * c + kxv[i] * s + k[i] * kv * (1.0 - c);
}

void view_camera_orbit(scene_camera *cam, float yaw_deg, float pitch_deg)
{
    double up[3] = {cam->up[0], cam->up[1], cam->up[2]}, off[3], t[3];
    for (int i = 0; i < 3; ++i) off[i] = (double)cam->position[i] - cam->target[i];
    if (!normalize3(up) || !(dot3(off, off) > 0)) return;
    /* Turning off about up by a small θ moves it by θ·(up × off) = θ·right (right =
     * fwd × up, fwd = −off): positive yaw, to the right. About right, a positive
     * angle moves it by fwd × right = −up, away from the up axis. */
    rotate3(off, up, (double)yaw_deg * k_deg, t);
    double fwd[3] = {-t[0], -t[1], -t[2]}, right[3];
    cross3(fwd, up, right);
    if (normalize3(right) && pitch_deg != 0.0f) {
        /* Clamped in the polar angle (from up): past the axis the view would turn
         * upside down. Up by pitch is the polar angle down by pitch. */
        double len = sqrt(dot3(t, t)), polar = acos(fmax(-1.0, fmin(1.0, dot3(t, up) / len))) / k_deg;
        double want = fmax(VIEW_CAMERA_MIN_POLAR_DEG, fmin(180.0 - VIEW_CAMERA_MIN_POLAR_DEG, polar - pitch_deg));
        double p[3];
        rotate3(t, right, (want - polar) * k_deg, p);
        for (int i = 0; i < 3; ++i) t[i] = p[i];
    }
    for (int i = 0; i < 3; ++i) cam->position[i] = (float)(cam->target[i] + t[i]);
}

void view_camera_zoom(scene_camera *cam, float factor)
{
    if (!(factor > 0.0f) || !isfinite(factor)) return;
    for (int i = 0; i < 3; ++i)
        cam->position[i] = (float)(cam->target[i] + ((double)cam->position[i] - cam->target[i]) * factor);
}

void view_camera_frame_all(scene_camera *cam, const float bmin[3], const float bmax[3], float aspect)
{
    double c[3], dir[3], r2 = 0;
    for (int i = 0; i < 3; ++i) {
        c[i] = 0.5 * ((double)bmin[i] + bmax[i]);
        double h = 0.5 * ((double)bmax[i] - bmin[i]);
        r2 += h * h;
        dir[i] = (double)cam->position[i] - cam->target[i];
    }
    if (!normalize3(dir)) dir[0] = 0, dir[1] = 0, dir[2] = 1;
    double radius = sqrt(r2) > 0 ? sqrt(r2) : 1.0;
    double half_y = 0.5 * cam->fov_y_deg * k_deg;
    double half_x = atan(tan(half_y) * (aspect > 0 ? aspect : 1.0));
    double half = fmin(half_y, half_x);
    double dist = radius / sin(half > 1e-3 ? half : 1e-3) * 1.02; /* 2%: the silhouette off the border */
    for (int i = 0; i < 3; ++i) {
        cam->target[i] = (float)c[i];
        cam->position[i] = (float)(c[i] + dir[i] * dist);
    }
}

/* The camera's unit forward, right (forward × up) and true up (right × forward);
 * 0 when the camera is degenerate (eye on the target, or looking along up). */
static int camera_axes(const scene_camera *cam, double fwd[3], double right[3], double up[3], double *dist)
{
    double wup[3] = {cam->up[0], cam->up[1], cam->up[2]};
    for (int i = 0; i < 3; ++i) fwd[i] = (double)cam->target[i] - cam->position[i];
    *dist = sqrt(dot3(fwd, fwd));
    if (!normalize3(fwd) || !normalize3(wup)) return 0;
    cross3(fwd, wup, right);
    if (!normalize3(right)) return 0;
    cross3(right, fwd, up);
    return 1;
}

static void move_both(scene_camera *cam, const double m[3])
{
    for (int i = 0; i < 3; ++i) {
        cam->position[i] = (float)(cam->position[i] + m[i]);
        cam->target[i] = (float)(cam->target[i] + m[i]);
    }
}

void view_camera_pan(scene_camera *cam, float right, float up)
{
    double f[3], r[3], u[3], dist;
    if (!camera_axes(cam, f, r, u, &dist) || !isfinite(right) || !isfinite(up)) return;
    double h = 2.0 * dist * tan(0.5 * cam->fov_y_deg * k_deg), m[3];
    for (int i = 0; i < 3; ++i) m[i] = (r[i] * right + u[i] * up) * h;
    move_both(cam, m);
}

void view_camera_fly(scene_camera *cam, float forward, float right, float up)
{
    double f[3], r[3], u[3], dist, wup[3] = {cam->up[0], cam->up[1], cam->up[2]}, m[3];
    if (!camera_axes(cam, f, r, u, &dist) || !normalize3(wup) || !isfinite(forward) || !isfinite(right) ||
        !isfinite(up))
        return;
    for (int i = 0; i < 3; ++i) m[i] = f[i] * forward + r[i] * right + wup[i] * up;
    move_both(cam, m);
}

void view_camera_look(scene_camera *cam, float yaw_deg, float pitch_deg)
{
    double f[3], r[3], u[3], dist, wup[3] = {cam->up[0], cam->up[1], cam->up[2]}, t[3];
    if (!camera_axes(cam, f, r, u, &dist) || !normalize3(wup)) return;
    /* About up by −yaw turns the forward direction to the right (up × fwd = −right);
     * about right by +pitch turns it up (right × fwd = up). */
    rotate3(f, wup, -(double)yaw_deg * k_deg, t);
    double right[3];
    cross3(t, wup, right);
    if (normalize3(right) && pitch_deg != 0.0f) {
        double polar = acos(fmax(-1.0, fmin(1.0, dot3(t, wup)))) / k_deg;
        double want = fmax(VIEW_CAMERA_MIN_POLAR_DEG, fmin(180.0 - VIEW_CAMERA_MIN_POLAR_DEG, polar - pitch_deg));
        double p[3];
        rotate3(t, right, (polar - want) * k_deg, p);
        for (int i = 0; i < 3; ++i) t[i] = p[i];
    }
    for (int i = 0; i < 3; ++i) cam->target[i] = (float)(cam->position[i] + t[i] * dist);
}
