#version 450 core
// Writes the visible surface's code (rend_material.vert: its triangle); bit 0
// says the front side is seen, because emission leaves the front side only
// (docs/scene-model.md). 0 stays "no surface". One R32UI sample instead of kd,
// ks, Le as three RGBA32F: the composite reads them from the material table,
// exactly, through the triangle's material.
flat in uint v_code;
layout(location = 0) out uint o_code;
void main() { o_code = v_code | (gl_FrontFacing ? 1u : 0u); }
