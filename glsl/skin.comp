#version 450
// Pass 3: matrix-palette skinning, K influences (built with K = 4 and K = 8).
// One invocation per (vertex = x, character = y), over the palette of palette.glsl.
layout(local_size_x = 64) in;

struct Affine { vec4 r0; vec4 r1; vec4 r2; };   // 3x4 row-major

layout(std430, set = 0, binding = 0) readonly buffer Rest { float rest[]; };          // V x 3
layout(std430, set = 0, binding = 1) readonly buffer SkinIndex { uint skin_index[]; };   // V x K
layout(std430, set = 0, binding = 2) readonly buffer SkinWeight { float skin_weight[]; }; // V x K
layout(std430, set = 0, binding = 3) readonly buffer Palette { Affine proxies[]; };   // chars x (P + J)
layout(std430, set = 0, binding = 4) readonly buffer Bones { Affine bones[]; };       // chars x J
layout(std430, set = 0, binding = 5) buffer Positions { float pos[]; };               // chars x V x 3

layout(push_constant) uniform Push { uint V; uint P; uint J; uint chars; } pc;

#include "palette.glsl"

void main() {
    uint a = gl_GlobalInvocationID.x;
    uint ch = gl_GlobalInvocationID.y;
    if (a >= pc.V || ch >= pc.chars) {
        return;
    }
    Affine m = blended(a, ch);
    vec4 y = vec4(rest[3u * a], rest[3u * a + 1u], rest[3u * a + 2u], 1.0);
    uint o = (ch * pc.V + a) * 3u;
    pos[o] = dot(m.r0, y);
    pos[o + 1u] = dot(m.r1, y);
    pos[o + 2u] = dot(m.r2, y);
}
