/* view_camera.h — the viewer's camera moves on a scene_camera: orbit about the
 * target, zoom (distance to the target), frame the whole scene. Pure arithmetic,
 * no GL, no window.
 *
 * Usage:
 *     scene_camera cam = s->cameras[0];
 *     view_camera_orbit(&cam, 10.0f, 0.0f);                        // 10° about the up axis
 *     view_camera_zoom(&cam, 0.9f);                                // 10% closer
 *     view_camera_frame_all(&cam, s->bounds_min, s->bounds_max, 16.0f / 9.0f);
 *     view_camera_pan(&cam, 0.1f, 0.0f);                           // a tenth of the view to the right
 *     view_camera_fly(&cam, 0.5f, 0.0f, 0.0f);                     // half a unit forward
 *     view_camera_look(&cam, 5.0f, 0.0f);                          // turn 5° to the right
 *
 * Does NOT do: roll, collision with the scene, animation.
 */
#ifndef LUMESH_VIEW_CAMERA_H
#define LUMESH_VIEW_CAMERA_H

#include "src/scene/scene.h"

#ifdef __cplusplus
extern "C" {
#endif

enum { VIEW_CAMERA_MIN_POLAR_DEG = 1 }; /* degrees: orbit stops this close to the up axis (the view flips there) */

/* Turns the position about the target: yaw_deg about cam->up (positive: the
 * camera moves to its right), pitch_deg about the camera's right axis (positive:
 * it moves up), the angle from the up axis clamped to
 * [VIEW_CAMERA_MIN_POLAR_DEG, 180 − VIEW_CAMERA_MIN_POLAR_DEG]. */
void view_camera_orbit(scene_camera *cam, float yaw_deg, float pitch_deg);

/* Multiplies the distance to the target by factor (> 0; < 1 comes closer). */
void view_camera_zoom(scene_camera *cam, float factor);

/* Aims at the centre of the box and backs off along the current view direction
 * until the box's bounding sphere fits both fields of view (aspect = width/height). */
void view_camera_frame_all(scene_camera *cam, const float bmin[3], const float bmax[3], float aspect);
/* Moves position and target together along the camera's right and up axes, by
 * `right` and `up` times the height the view shows at the target's distance (a
 * drag over the window's whole height moves the target's plane by one view). */
void view_camera_pan(scene_camera *cam, float right, float up);
/* Moves position and target together, scene units: forward along the view
 * direction, right along the camera's right axis, up along cam->up. */
void view_camera_fly(scene_camera *cam, float forward, float right, float up);
/* Turns the view about the eye (first person; the target moves, at the same
 * distance): yaw_deg about cam->up (positive: to the right), pitch_deg about the
 * right axis (positive: up), clamped like view_camera_orbit. */
void view_camera_look(scene_camera *cam, float yaw_deg, float pitch_deg);

#ifdef __cplusplus
}
#endif
#endif
