#version 450 core
// Whole roots (cache_snapshot_mesh.whole): a term's leaves that are a scene
// triangle with its own three corners, drawn per sample from the material
// pass's triangle instead of as triangles (docs/cache.md, "Whole roots by
// vertex id"): a million-triangle scene's first image drew 2 million such
// leaves through llvmpipe's vertex stage, 0.3 s, and uploaded them, 0.2 s.
// Where the sample's triangle is a whole root of the term, its value is the
// corners' values (by vertex-table id) at the sample's perspective-correct
// barycentric coordinates, found from the corners' clip coordinates as a
// rasterizer does (Olano & Greer 1997: homogeneous 2D edge functions), so it is
// the value the leaf pass would interpolate there. Elsewhere it leaves the
// leaf pass's value (discard): a sample whose triangle is split sees that
// triangle's leaves, which lie in its plane in front of everything else drawn.
layout(binding = 0) uniform usampler2D u_code;       // rend_material.frag: 2·(triangle + 1) | front; 0: none
layout(binding = 1) uniform usamplerBuffer u_scene;  // 3 corners a triangle: position bits, material code
layout(binding = 2) uniform usamplerBuffer u_corner; // 3 a triangle: the corner's vertex-table id
layout(binding = 3) uniform usamplerBuffer u_whole;  // bit t % 32 of word t / 32: triangle t is a whole root
layout(binding = 4) uniform samplerBuffer u_values;  // RGB per vertex-table id
uniform mat4 u_viewproj;
uniform int u_band_y0;  // the first sample row of the band drawn (rend_frame.c)
uniform vec2 u_samples; // the sample image's size
layout(location = 0) out vec4 o_value;

void main()
{
    ivec2 p = ivec2(gl_FragCoord.xy) + ivec2(0, u_band_y0);
    uint s = texelFetch(u_code, p, 0).r;
    if (s == 0u) discard;
    uint t = (s >> 1) - 1u;
    if ((texelFetch(u_whole, int(t >> 5)).r & (1u << (t & 31u))) == 0u) discard;
    vec3 q = vec3((vec2(p) + 0.5) / u_samples * 2.0 - 1.0, 1.0);
    vec3 c[3];
    for (int k = 0; k < 3; ++k) {
        vec4 clip = u_viewproj * vec4(uintBitsToFloat(texelFetch(u_scene, 3 * int(t) + k).xyz), 1.0);
        c[k] = clip.xyw;
    }
    vec3 b = vec3(dot(cross(c[1], c[2]), q), dot(cross(c[2], c[0]), q), dot(cross(c[0], c[1]), q));
    float sum = b.x + b.y + b.z;
    b = sum != 0.0 ? b / sum : vec3(1.0 / 3.0);
    vec3 v = vec3(0.0);
    for (int k = 0; k < 3; ++k) v += b[k] * texelFetch(u_values, int(texelFetch(u_corner, 3 * int(t) + k).r)).rgb;
    o_value = vec4(v, 1.0);
}
