#version 450 core
// Material pass (paper §6): each scene triangle as the code the composite looks
// up: 2·(triangle + 1), the triangle being gl_VertexID / 3 (rend_frame.c draws
// the scene's three corners a triangle from the first). Its material is read
// from the scene's buffer (code_of in rend_resolve.frag and rend_composite.frag);
// the triangle itself is what the whole roots' pass (rend_whole.frag)
// interpolates over.
layout(location = 0) in vec3 pos;
uniform mat4 u_viewproj;
flat out uint v_code;
void main()
{
    v_code = uint(gl_VertexID / 3 + 1) << 1;
    gl_Position = u_viewproj * vec4(pos, 1.0);
}
