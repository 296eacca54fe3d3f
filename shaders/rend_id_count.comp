#version 450 core
// Pixels per triangle from the ID image without reading the image back: a
// workgroup counts its 16x16 pixels (runs of the same id are common, so an
// atomic per pixel into the global array would serialise on big triangles).
layout(local_size_x = 16, local_size_y = 16) in;
layout(binding = 0, r32ui) uniform readonly uimage2D u_ids;
layout(std430, binding = 1) buffer Counts { uint counts[]; };
shared uint s_id[256];
void main()
{
    ivec2 size = imageSize(u_ids);
    ivec2 p = ivec2(gl_GlobalInvocationID.xy);
    uint id = (p.x < size.x && p.y < size.y) ? imageLoad(u_ids, p).r : 0u;
    uint me = gl_LocalInvocationIndex;
    s_id[me] = id;
    barrier();
    // The first invocation holding an id counts how many of the group hold it.
    if (id != 0u) {
        bool first = true;
        for (uint i = 0u; i < me; ++i)
            if (s_id[i] == id) { first = false; break; }
        if (first) {
            uint n = 0u;
            for (uint i = me; i < 256u; ++i) n += s_id[i] == id ? 1u : 0u;
            atomicAdd(counts[id - 1u], n);
        }
    }
}
