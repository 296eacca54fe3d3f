#version 450 core
// samp_gl_direct.frag — the area light's weight per pixel of a direct frustum
// (paper §5, eq. 3): a pixel showing the emitting (front) side of light
// u_light carries max(0, cosθ_x)·dω, computed from its direction d on the
// unit-distance image plane: dω = pixel area / |d|³. Anything else carries 0
// (an occluder, or the light's back). Both outputs get the same value; the
// colour masks choose which attachment a pass writes (0: with depth test, the
// visible weight; 1: the light alone, the total weight for the control variate).

flat in vec4 v_rect;
flat in vec4 v_extra;
flat in vec4 v_region;
flat in float v_light;

uniform float u_light;

layout(location = 0) out float o_visible;
layout(location = 1) out float o_total;

void main()
{
    float value = 0.0;
    if (v_light == u_light && gl_FrontFacing) {
        // Pixel centre on the image plane at unit distance, in eye space.
        vec2 f = (gl_FragCoord.xy - v_rect.xy) / v_rect.zw;
        vec3 d = vec3(mix(v_region.xz, v_region.yw, f), -1.0);
        float len2 = dot(d, d);
        float len = sqrt(len2);
        float cos_x = max(dot(v_extra.xyz, d) / len, 0.0);
        float area = (v_region.y - v_region.x) * (v_region.w - v_region.z) / (v_rect.z * v_rect.w);
        value = cos_x * area / (len2 * len);
    }
    o_visible = value;
    o_total = value;
}
