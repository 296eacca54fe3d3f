#version 450 core
// Material pass (paper §6): per-vertex kd, ks, Le of the scene triangle.
layout(location = 0) in vec3 pos;
layout(location = 1) in vec3 kd;
layout(location = 2) in vec3 ks;
layout(location = 3) in vec3 le;
uniform mat4 u_viewproj;
flat out vec3 v_kd, v_ks, v_le;
void main()
{
    v_kd = kd;
    v_ks = ks;
    v_le = le;
    gl_Position = u_viewproj * vec4(pos, 1.0);
}
