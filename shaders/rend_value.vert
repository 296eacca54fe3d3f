#version 450 core
// Radiance passes: a cache mesh's leaf triangles, per-vertex values
// interpolated by the rasterizer (Gouraud, paper §6).
layout(location = 0) in vec3 pos;
layout(location = 1) in vec3 value;
uniform mat4 u_viewproj;
out vec3 v_value;
void main()
{
    v_value = value;
    gl_Position = u_viewproj * vec4(pos, 1.0);
}
