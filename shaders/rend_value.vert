#version 450 core
// Radiance passes: a cache mesh's leaf triangles, per-vertex values
// interpolated by the rasterizer (Gouraud, paper §6). HIGHLIGHT (the specular
// mesh): with each vertex its lobe (cache_lobe), for the lights' part per pixel
// (rend_value.frag).
layout(location = 0) in vec3 pos;
layout(location = 1) in vec3 value;
uniform mat4 u_viewproj;
out vec3 v_value;
#ifdef HIGHLIGHT
layout(location = 2) in vec4 normal_exponent; // unit shading normal, Phong n
layout(location = 3) in vec4 direct_visible;  // the lights' part of value, their visible fraction
out vec3 v_pos;
out vec3 v_normal;
out vec3 v_direct;
out float v_visible;
flat out float v_exponent;
#endif
void main()
{
    v_value = value;
#ifdef HIGHLIGHT
    v_pos = pos;
    v_normal = normal_exponent.xyz;
    v_exponent = normal_exponent.w;
    v_direct = direct_visible.xyz;
    v_visible = direct_visible.w;
#endif
    gl_Position = u_viewproj * vec4(pos, 1.0);
}
