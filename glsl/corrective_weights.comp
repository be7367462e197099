#version 450
// Pose-space corrective weights (paper §8; docs/method.md §20): w = map · φ(q) per character,
// φ[9i + 3r + c] = R_i[r][c] - δ_rc with R_i = rot(Q_p)ᵀ rot(Q_d) for driver i (bone d, its
// parent p), rot the 3x3 of the bone transform (joint_features.glsl). One invocation per
// (target n = x, character = y); skin.comp adds Σ_n w_n target_n to the rest position. Models
// with correctives only.
layout(local_size_x = 64) in;

struct Affine { vec4 r0; vec4 r1; vec4 r2; };   // 3x4 row-major

layout(std430, set = 0, binding = 0) readonly buffer Bones { Affine bones[]; };           // chars x J
layout(std430, set = 0, binding = 1) readonly buffer Parents { int parents[]; };          // J
layout(std430, set = 0, binding = 2) readonly buffer Drivers { uint drivers[]; };         // D
layout(std430, set = 0, binding = 3) readonly buffer CorrectiveMap { float map[]; };      // N x 9D
layout(std430, set = 0, binding = 4) buffer CorrectiveWeights { float weights[]; };      // chars x N4

layout(push_constant) uniform Push { uint N; uint D; uint J; uint chars; } pc;

#include "joint_features.glsl"

void main() {
    uint n = gl_GlobalInvocationID.x;
    uint ch = gl_GlobalInvocationID.y;
    if (n >= pc.N || ch >= pc.chars) {
        return;
    }
    uint width = 9u * pc.D;
    float w = 0.0;
    for (uint i = 0u; i < pc.D; i++) {
        mat3 phi = joint_features(ch, drivers[i]);
        uint m = n * width + 9u * i;
        w += dot(vec3(map[m], map[m + 1u], map[m + 2u]), phi[0]);
        w += dot(vec3(map[m + 3u], map[m + 4u], map[m + 5u]), phi[1]);
        w += dot(vec3(map[m + 6u], map[m + 7u], map[m + 8u]), phi[2]);
    }
    // N4 = N rounded up to whole vec4s: each character's weights start 16-byte aligned.
    weights[ch * ((pc.N + 3u) & ~3u) + n] = w;
}
