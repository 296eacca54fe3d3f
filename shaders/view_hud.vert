#version 450 core
// The HUD's text and panel: positions in window pixels, top-left origin.
layout(location = 0) in vec2 a_pixel;
uniform vec2 u_viewport; // window pixels

void main()
{
    vec2 ndc = a_pixel / u_viewport * 2.0 - 1.0;
    gl_Position = vec4(ndc.x, -ndc.y, 0.0, 1.0);
}
