#version 450 core
// Writes the scene triangle id + 1 (0 stays "no triangle").
flat in uint v_id;
layout(location = 0) out uint o_id;
void main() { o_id = v_id + 1u; }
