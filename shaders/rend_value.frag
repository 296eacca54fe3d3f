#version 450 core
in vec3 v_value;
layout(location = 0) out vec4 o_value;
void main() { o_value = vec4(v_value, 1.0); }
