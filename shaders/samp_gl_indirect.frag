#version 450 core
// samp_gl_indirect.frag — the radiance leaving the coarse radiance mesh,
// Gouraud-interpolated from its corners (W·m⁻²·sr⁻¹); the back of a triangle
// sends nothing (the views are rotations: counter-clockwise in the scene seen
// from the front stays front-facing). The cosθ·dω weight is applied per pixel
// by the reduction (samp_gl_reduce.comp), from a texture.

in vec3 v_radiance;

layout(location = 0) out vec4 o_radiance;

void main()
{
    o_radiance = gl_FrontFacing ? vec4(v_radiance, 1.0) : vec4(0.0, 0.0, 0.0, 1.0);
}
