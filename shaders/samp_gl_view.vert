#version 450 core
// samp_gl_view.vert — one vertex of the scene seen in one view of the GL
// sampler's atlas (sampling/samp_gl.c). The view is chosen per instance
// (attributes with divisor 1, so a draw's baseInstance selects it): its matrix
// maps the view's image region to [-1,1]², the four clip distances cut at the
// region's borders, and the result is squeezed into the view's atlas rectangle.

layout(location = 0) in vec3 a_pos;      // scene units
layout(location = 1) in vec3 a_attr;     // direct: light index or -1; indirect: RGB radiance
layout(location = 2) in vec4 i_pv0;      // world -> clip, column-major
layout(location = 3) in vec4 i_pv1;
layout(location = 4) in vec4 i_pv2;
layout(location = 5) in vec4 i_pv3;
layout(location = 6) in vec4 i_rect;     // atlas x0, y0, w, h (pixels)
layout(location = 7) in vec4 i_extra;    // direct: eye-space receiver normal
layout(location = 8) in vec4 i_region;   // image region at unit distance: l, r, b, t

uniform vec2 u_atlas;                    // atlas width, height (pixels)

out gl_PerVertex {
    vec4 gl_Position;
    float gl_ClipDistance[4];
};
flat out vec4 v_rect;
flat out vec4 v_extra;
flat out vec4 v_region;
flat out float v_light;
out vec3 v_radiance;

void main()
{
    vec4 c = mat4(i_pv0, i_pv1, i_pv2, i_pv3) * vec4(a_pos, 1.0);
    // The region's borders: -w <= x <= w, -w <= y <= w before the remap.
    gl_ClipDistance[0] = c.w + c.x;
    gl_ClipDistance[1] = c.w - c.x;
    gl_ClipDistance[2] = c.w + c.y;
    gl_ClipDistance[3] = c.w - c.y;
    vec2 scale = i_rect.zw / u_atlas;
    vec2 offset = (2.0 * i_rect.xy + i_rect.zw) / u_atlas - 1.0;
    gl_Position = vec4(c.xy * scale + c.w * offset, c.z, c.w);
    v_rect = i_rect;
    v_extra = i_extra;
    v_region = i_region;
    v_light = a_attr.x;
    v_radiance = a_attr;
}
