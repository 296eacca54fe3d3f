#version 450 core
flat in vec3 v_kd, v_ks, v_le;
layout(location = 0) out vec4 o_kd;
layout(location = 1) out vec4 o_ks;
layout(location = 2) out vec4 o_le;
// Emission leaves the front side only (docs/scene-model.md).
void main()
{
    o_kd = vec4(v_kd, 1.0);
    o_ks = vec4(v_ks, 1.0);
    o_le = vec4(gl_FrontFacing ? v_le : vec3(0.0), 1.0);
}
