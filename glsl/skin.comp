#version 450
// Pass 3: matrix-palette skinning, K influences (built with K = 4 and K = 8).
// One invocation per (vertex = x, character = y), over the palette of palette.glsl. With
// pose-space correctives (N > 0) the skinned point is the rest position plus the targets
// weighted by corrective_weights.comp's w; N = 0 reads neither.
layout(local_size_x = 64) in;

struct Affine { vec4 r0; vec4 r1; vec4 r2; };   // 3x4 row-major

layout(std430, set = 0, binding = 0) readonly buffer Rest { float rest[]; };          // (1 + N) x V x 3
layout(std430, set = 0, binding = 1) readonly buffer SkinIndex { uint skin_index[]; };   // V x K
layout(std430, set = 0, binding = 2) readonly buffer SkinWeight { float skin_weight[]; }; // V x K
layout(std430, set = 0, binding = 3) readonly buffer Palette { Affine proxies[]; };   // chars x (P + J)
layout(std430, set = 0, binding = 4) readonly buffer Bones { Affine bones[]; };       // chars x J
layout(std430, set = 0, binding = 5) buffer Positions { float pos[]; };               // chars x V x 3
layout(std430, set = 0, binding = 6) readonly buffer CorrectiveWeights { float weights[]; }; // chars x N4

layout(push_constant) uniform Push { uint V; uint P; uint J; uint chars; uint N; } pc;

#include "palette.glsl"

void main() {
    uint a = gl_GlobalInvocationID.x;
    uint ch = gl_GlobalInvocationID.y;
    if (a >= pc.V || ch >= pc.chars) {
        return;
    }
    Affine m = blended(a, ch);
    vec3 x = vec3(rest[3u * a], rest[3u * a + 1u], rest[3u * a + 2u]);
    if (pc.N > 0u) {
        // Target n's delta of vertex a follows the rest positions: (1 + n) V + a.
        // N4 = N rounded up to whole vec4s (corrective_weights.comp).
        uint first = ch * ((pc.N + 3u) & ~3u);
        for (uint n = 0u; n < pc.N; n++) {
            float w = weights[first + n];
            uint t = ((n + 1u) * pc.V + a) * 3u;
            x += w * vec3(rest[t], rest[t + 1u], rest[t + 2u]);
        }
    }
    vec4 y = vec4(x, 1.0);
    uint o = (ch * pc.V + a) * 3u;
    pos[o] = dot(m.r0, y);
    pos[o + 1u] = dot(m.r1, y);
    pos[o + 2u] = dot(m.r2, y);
}
