#version 450 core
// Material pass (paper §6): each scene triangle's material, as a code the
// composite looks up (rend_frame.c: 2·(material + 1)).
layout(location = 0) in vec3 pos;
layout(location = 1) in uint code;
uniform mat4 u_viewproj;
flat out uint v_code;
void main()
{
    v_code = code;
    gl_Position = u_viewproj * vec4(pos, 1.0);
}
