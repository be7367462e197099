#version 450
// Bounds: each character's axis-aligned box of its skinned positions, written every frame.
// One workgroup per character (x): each invocation folds a strided run of vertices, then a
// tree reduction in shared memory (no atomics: naga's GLSL front end has none).
layout(local_size_x = 64) in;

layout(std430, set = 0, binding = 0) readonly buffer Positions { float pos[]; };  // chars x V x 3
layout(std430, set = 0, binding = 1) buffer Bounds { vec4 bounds[]; };           // chars x (min, max)

layout(push_constant) uniform Push { uint V; uint chars; } pc;

shared vec4 lo[64];
shared vec4 hi[64];

void main() {
    uint ch = gl_WorkGroupID.x;
    uint t = gl_LocalInvocationID.x;
    vec3 mn = vec3(3.402823e38);
    vec3 mx = vec3(-3.402823e38);
    // The dispatch covers exactly `chars` groups, so `ch` is uniform and in range.
    for (uint a = t; a < pc.V; a += 64u) {
        uint i = (ch * pc.V + a) * 3u;
        vec3 p = vec3(pos[i], pos[i + 1u], pos[i + 2u]);
        mn = min(mn, p);
        mx = max(mx, p);
    }
    lo[t] = vec4(mn, 0.0);
    hi[t] = vec4(mx, 0.0);
    barrier();
    for (uint s = 32u; s > 0u; s >>= 1u) {
        if (t < s) {
            lo[t] = min(lo[t], lo[t + s]);
            hi[t] = max(hi[t], hi[t + s]);
        }
        barrier();
    }
    if (t == 0u && ch < pc.chars) {
        bounds[2u * ch] = lo[0];
        bounds[2u * ch + 1u] = hi[0];
    }
}
