#version 450
// Pass 5 (recomputed normals, paper §6): vertex normals = the normalised area-weighted sum of
// the triangles around each vertex, gathered (no atomics, no second pass) from its 1-ring fans
// (src/normals.rs `Fans`): entries `pivot | FAN_PIVOT, r0, r1, ..., rn` stand for the
// triangles (pivot, r_i, r_i+1), whose area normals cross(p[r_i] - p, p[r_i+1] - p) sum to the
// incident triangles'. One invocation per (vertex = x, character = y). Per interior vertex of
// valence 6: 2 offsets, 8 fan entries and 8 positions read (about 136 bytes, mostly cache
// hits), 12 bytes written; the incident-triangle gather it replaces read 6 triangle ids, 18
// corners and 18 positions (about 320 bytes).
layout(local_size_x = 64) in;

layout(std430, set = 0, binding = 0) readonly buffer Positions { float pos[]; };      // chars x V x 3
layout(std430, set = 0, binding = 1) readonly buffer FanOffsets { uint offsets[]; };  // V + 1
layout(std430, set = 0, binding = 2) readonly buffer Fans { uint fans[]; };           // entries
layout(std430, set = 0, binding = 3) buffer Normals { float nrm[]; };                 // chars x V x 3

layout(push_constant) uniform Push { uint V; uint chars; } pc;

const uint FAN_PIVOT = 0x80000000u;

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
    vec3 pivot = vec3(0.0);
    vec3 last = vec3(0.0);
    bool open = false;   // whether `last` is a ring vertex of the current fan
    uint end = offsets[a + 1u];
    for (uint i = offsets[a]; i < end; i++) {
        uint e = fans[i];
        if ((e & FAN_PIVOT) != 0u) {
            pivot = position(base, e & ~FAN_PIVOT);
            open = false;
            continue;
        }
        vec3 r = position(base, e) - pivot;
        if (open) {
            sum += cross(last, r);
        }
        last = r;
        open = true;
    }
    float len = length(sum);
    vec3 n = len > 0.0 ? sum / len : vec3(0.0);
    uint o = (base + a) * 3u;
    nrm[o] = n.x;
    nrm[o + 1u] = n.y;
    nrm[o + 2u] = n.z;
}
