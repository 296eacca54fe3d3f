/* camera.h — the pinhole camera every image of lumesh shares: the
 * reference path tracer (reference.c) and the GL passes of the renderer map a
 * pixel to the same ray.
 *
 * Pixel (px, py), py counted from the TOP row, is the ray from the camera through
 *     fwd + sx·tan(fov_y/2)·(W/H)·right + sy·tan(fov_y/2)·up,
 *     sx = 2(px + ½)/W − 1,  sy = 1 − 2(py + ½)/H
 * with fwd = normalize(target − position), right = normalize(fwd × up_hint),
 * up = right × fwd. GL's framebuffer rows run from the bottom: GL row r is image
 * row H − 1 − r.
 *
 * Usage:
 *     float vp[16];
 *     camera_viewproj(&s->cameras[0], 640, 480, near, vp);  // column-major, for glUniformMatrix4fv
 *     camera_basis b = camera_basis_make(&s->cameras[0], 640, 480);
 *     lm_vec3 d = camera_ray_dir(&b, px + 0.5f, py + 0.5f);  // pixel (px, py)'s centre; from b.position
 *
 * Depth: reversed infinite Z (clip z = near, w = −z_eye): with a 32-bit float
 * depth buffer cleared to 0 and GL_GREATER, precision is even from near to
 * infinity (Reed, "Depth precision visualized", 2015).
 * Units: positions in scene units, pixels for image points; fov_y in degrees.
 * Threads: pure functions; any thread.
 * Does NOT do: orthographic cameras, lens effects, jitter (the caller chooses the
 * image point inside a pixel).
 */
#ifndef LUMESH_SCENE_CAMERA_H
#define LUMESH_SCENE_CAMERA_H

#include "src/base/vecmath.h"
#include "src/scene/scene.h"

#ifdef __cplusplus
extern "C" {
#endif

/* World → clip, column-major, reversed infinite Z with near plane `near` (scene units). */
void camera_viewproj(const scene_camera *cam, int width, int height, float near, float out[16]);

/* The primary rays of a width × height image in the convention above: fwd,
 * right and up come from the same double-precision frame as camera_viewproj,
 * rounded to float, right and up already scaled to the image plane at unit
 * distance (by tan(fov_y/2)·W/H and tan(fov_y/2)). */
typedef struct camera_basis {
    lm_vec3 position;   /* where every ray starts, scene units */
    lm_vec3 fwd;        /* unit, towards the target */
    lm_vec3 right, up;  /* half the image plane's width and height at unit distance */
    int width, height;  /* pixels */
} camera_basis;

camera_basis camera_basis_make(const scene_camera *cam, int width, int height);

/* The same view: position, target, up, field of view and size (field by field:
 * the name is not compared, and its padding is not read). */
int camera_equal(const scene_camera *a, const scene_camera *b);

/* Unit direction of the ray from b->position through image point (x, y), in
 * pixels from the image's top-left corner (pixel (px, py) spans [px, px+1) ×
 * [py, py+1); its centre is (px + ½, py + ½)): fwd + sx·right + sy·up normalized,
 * sx = 2x/W − 1, sy = 1 − 2y/H. */
lm_vec3 camera_ray_dir(const camera_basis *b, float x, float y);

/* Pixels each scene triangle covers in a width × height image from cam, before
 * occlusion: the triangle clipped to the near plane and the image, its projected
 * area rounded (both sides count: surfaces are seen from either). A guess of the
 * ID pass's counts without GL, to refine by before that pass has run (the first
 * image: rend_session); pixels holds s->tri_count values. */
void camera_triangle_pixels(const scene *s, const scene_camera *cam, int width, int height, uint32_t *pixels);

/* A near plane for a scene seen from this camera: small against the scene's
 * extent (1e-8 of it), never 0. Reversed float Z keeps relative precision at
 * every distance, so it can be that small: at 1e-5 a camera 0.8 units over a
 * floor in a scene 2·10^5 wide (a room in its site) lost the floor to the near
 * plane (tests/offset_test.c, "far"). */
float camera_near(const scene *s);

#ifdef __cplusplus
}
#endif
#endif
