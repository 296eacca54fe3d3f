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
 *
 * Depth: reversed infinite Z (clip z = near, w = −z_eye): with a 32-bit float
 * depth buffer cleared to 0 and GL_GREATER, precision is even from near to
 * infinity (Reed, "Depth precision visualized", 2015).
 * Does NOT do: orthographic cameras, lens effects, jitter.
 */
#ifndef LUMESH_SCENE_CAMERA_H
#define LUMESH_SCENE_CAMERA_H

#include "src/scene/scene.h"

#ifdef __cplusplus
extern "C" {
#endif

/* World → clip, column-major, reversed infinite Z with near plane `near` (scene units). */
void camera_viewproj(const scene_camera *cam, int width, int height, float near, float out[16]);

/* A near plane for a scene seen from this camera: small against the scene's
 * extent (1e-5 of it), never 0. */
float camera_near(const scene *s);

#ifdef __cplusplus
}
#endif
#endif
