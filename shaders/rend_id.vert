#version 450 core
// ID pass (paper §6, first pass): scene triangles, unwelded, in scene order, so
// gl_VertexID / 3 is the scene triangle id.
layout(location = 0) in vec3 pos;
uniform mat4 u_viewproj;
flat out uint v_id;
void main()
{
    v_id = uint(gl_VertexID) / 3u;
    gl_Position = u_viewproj * vec4(pos, 1.0);
}
