#version 450
// Pass 3: matrix-palette skinning, K influences (built with K = 4 and K = 8).
// One invocation per (vertex = x, character = y), over the palette of palette.glsl. With
// pose-space correctives (N > 0) the skinned point is the rest position plus the targets
// weighted by corrective_weights.comp's w; N = 0 reads neither.
// Built with NORMALS for transformed normals (src/normals.rs): the rest normal, after the
// positions and targets in Rest, through the cofactor of the blended 3x3, so the frame needs no
// normals pass; with TANGENTS too, the rest tangent through the 3x3 made orthogonal to that
// normal (as tangents.comp does). Per vertex then: 12 bytes of rest normal and 12 of normal
// (16 + 16 of tangents) beside skinning's K x 8 of influences, 12 of rest position and 12 of
// position; no neighbour is read.
layout(local_size_x = 64) in;

struct Affine { vec4 r0; vec4 r1; vec4 r2; };   // 3x4 row-major

layout(std430, set = 0, binding = 0) readonly buffer Rest { float rest[]; };          // (2 + N) x V x 3
layout(std430, set = 0, binding = 1) readonly buffer SkinIndex { uint skin_index[]; };   // V x K
layout(std430, set = 0, binding = 2) readonly buffer SkinWeight { float skin_weight[]; }; // V x K
layout(std430, set = 0, binding = 3) readonly buffer Palette { Affine proxies[]; };   // chars x (P + J)
layout(std430, set = 0, binding = 4) readonly buffer Bones { Affine bones[]; };       // chars x J
layout(std430, set = 0, binding = 5) buffer Positions { float pos[]; };               // chars x V x 3
layout(std430, set = 0, binding = 6) readonly buffer CorrectiveWeights { float weights[]; }; // chars x N4
#ifdef NORMALS
layout(std430, set = 0, binding = 7) buffer Normals { float nrm[]; };                 // chars x V x 3
#endif
#ifdef TANGENTS
layout(std430, set = 0, binding = 8) readonly buffer RestTangents { vec4 rest_tangents[]; }; // V
layout(std430, set = 0, binding = 9) buffer Tangents { vec4 tangents[]; };            // chars x V
#endif

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
#ifdef NORMALS
    // cof(M) n = n.x (c1 x c2) + n.y (c2 x c0) + n.z (c0 x c1), c_j the columns of M's 3x3.
    uint rn = ((1u + pc.N) * pc.V + a) * 3u;
    vec3 rest_n = vec3(rest[rn], rest[rn + 1u], rest[rn + 2u]);
    vec3 c0 = vec3(m.r0.x, m.r1.x, m.r2.x);
    vec3 c1 = vec3(m.r0.y, m.r1.y, m.r2.y);
    vec3 c2 = vec3(m.r0.z, m.r1.z, m.r2.z);
    vec3 n = rest_n.x * cross(c1, c2) + rest_n.y * cross(c2, c0) + rest_n.z * cross(c0, c1);
    float n_len = length(n);
    n = n_len > 0.0 ? n / n_len : vec3(0.0);
    nrm[o] = n.x;
    nrm[o + 1u] = n.y;
    nrm[o + 2u] = n.z;
#endif
#ifdef TANGENTS
    vec4 rest_t = rest_tangents[a];
    vec3 t = vec3(dot(m.r0.xyz, rest_t.xyz), dot(m.r1.xyz, rest_t.xyz), dot(m.r2.xyz, rest_t.xyz));
    t -= n * dot(n, t);
    float t_len = length(t);
    tangents[ch * pc.V + a] = vec4(t_len > 0.0 ? t / t_len : vec3(0.0), rest_t.w);
#endif
}
