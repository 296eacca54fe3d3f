#version 450 core
// One colour per draw (panel, then text), blended over the picture.
uniform vec4 u_color;
layout(location = 0) out vec4 o_color;

void main()
{
    o_color = u_color;
}
