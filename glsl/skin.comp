#version 450
// Pass 3: matrix-palette skinning, K influences (built with K = 4 and K = 8).
// One invocation per (vertex = x, character = y). The palette is [t (P proxies); q (J bones)]:
// for a reduced model (P > 0) the Proxies buffer holds all of it per character (the product
// passes write t, and the bones are copied beside it), so that an influence's load does not
// branch between two buffers (on a CPU driver both sides ran for every influence); a plain LBS
// model (P = 0) reads the bones in place.
layout(local_size_x = 64) in;

struct Affine { vec4 r0; vec4 r1; vec4 r2; };   // 3x4 row-major

layout(std430, set = 0, binding = 0) readonly buffer Rest { float rest[]; };          // V x 3
layout(std430, set = 0, binding = 1) readonly buffer SkinIndex { uint skin_index[]; };   // V x K
layout(std430, set = 0, binding = 2) readonly buffer SkinWeight { float skin_weight[]; }; // V x K
layout(std430, set = 0, binding = 3) readonly buffer Proxies { Affine proxies[]; };   // chars x (P + J)
layout(std430, set = 0, binding = 4) readonly buffer Bones { Affine bones[]; };       // chars x J
layout(std430, set = 0, binding = 5) buffer Positions { float pos[]; };               // chars x V x 3

layout(push_constant) uniform Push { uint V; uint P; uint J; uint chars; } pc;

void main() {
    uint a = gl_GlobalInvocationID.x;
    uint ch = gl_GlobalInvocationID.y;
    if (a >= pc.V || ch >= pc.chars) {
        return;
    }
    vec4 r0 = vec4(0.0);
    vec4 r1 = vec4(0.0);
    vec4 r2 = vec4(0.0);
    uint palette = pc.P + pc.J;
    for (uint k = 0u; k < uint(K); k++) {
        uint i = skin_index[a * uint(K) + k];
        float w = skin_weight[a * uint(K) + k];
        Affine m;
        if (pc.P > 0u) {
            m = proxies[ch * palette + i];
        } else {
            m = bones[ch * pc.J + i];
        }
        r0 += w * m.r0;
        r1 += w * m.r1;
        r2 += w * m.r2;
    }
    vec4 y = vec4(rest[3u * a], rest[3u * a + 1u], rest[3u * a + 2u], 1.0);
    uint o = (ch * pc.V + a) * 3u;
    pos[o] = dot(r0, y);
    pos[o + 1u] = dot(r1, y);
    pos[o + 2u] = dot(r2, y);
}
