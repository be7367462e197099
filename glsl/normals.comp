#version 450
// Pass 4: vertex normals = normalised area-weighted sum of incident triangle normals.
// One invocation per (vertex = x, character = y). A gather over a per-vertex CSR list of
// incident triangles: no atomics (naga has none), no second pass.
layout(local_size_x = 64) in;

layout(std430, set = 0, binding = 0) readonly buffer Positions { float pos[]; };      // chars x V x 3
layout(std430, set = 0, binding = 1) readonly buffer Offsets { uint offsets[]; };     // V + 1
layout(std430, set = 0, binding = 2) readonly buffer Incident { uint incident[]; };   // 3T
layout(std430, set = 0, binding = 3) readonly buffer Triangles { uint tris[]; };      // T x 3
layout(std430, set = 0, binding = 4) buffer Normals { float nrm[]; };                 // chars x V x 3

layout(push_constant) uniform Push { uint V; uint chars; } pc;

vec3 position(uint base, uint a) {
    uint i = (base + a) * 3u;
    return vec3(pos[i], pos[i + 1u], pos[i + 2u]);
}

void main() {
    uint a = gl_GlobalInvocationID.x;
    uint ch = gl_GlobalInvocationID.y;
    if (a >= pc.V || ch >= pc.chars) {
        return;
    }
    uint base = ch * pc.V;
    vec3 sum = vec3(0.0);
    for (uint i = offsets[a]; i < offsets[a + 1u]; i++) {
        uint k = incident[i] * 3u;
        vec3 p0 = position(base, tris[k]);
        vec3 p1 = position(base, tris[k + 1u]);
        vec3 p2 = position(base, tris[k + 2u]);
        sum += cross(p1 - p0, p2 - p0);
    }
    float len = length(sum);
    vec3 n = len > 0.0 ? sum / len : vec3(0.0);
    uint o = (base + a) * 3u;
    nrm[o] = n.x;
    nrm[o + 1u] = n.y;
    nrm[o + 2u] = n.z;
}
