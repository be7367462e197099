#version 450
// Pass 5: tangent frames in glTF's TANGENT layout (xyz unit, w = ±1 handedness), K influences
// (built with K = 4 and K = 8). One invocation per (vertex = x, character = y): the rest tangent
// times the 3x3 of the vertex's blended palette matrix (palette.glsl, as skinning blends it; a
// tangent is a surface direction, so it takes the matrix itself, shear and scale included), made
// orthogonal to the pass-4 normal (one Gram-Schmidt step) and normalised; w is the rest
// tangent's. Zero where it vanishes.
layout(local_size_x = 64) in;

struct Affine { vec4 r0; vec4 r1; vec4 r2; };   // 3x4 row-major

layout(std430, set = 0, binding = 0) readonly buffer SkinIndex { uint skin_index[]; };   // V x K
layout(std430, set = 0, binding = 1) readonly buffer SkinWeight { float skin_weight[]; }; // V x K
layout(std430, set = 0, binding = 2) readonly buffer RestTangents { vec4 rest_tangents[]; }; // V
layout(std430, set = 0, binding = 3) readonly buffer Palette { Affine proxies[]; };   // chars x (P + J)
layout(std430, set = 0, binding = 4) readonly buffer Bones { Affine bones[]; };       // chars x J
layout(std430, set = 0, binding = 5) readonly buffer Normals { float nrm[]; };        // chars x V x 3
layout(std430, set = 0, binding = 6) buffer Tangents { vec4 tangents[]; };            // chars x V

layout(push_constant) uniform Push { uint V; uint P; uint J; uint chars; } pc;

#include "palette.glsl"

void main() {
    uint a = gl_GlobalInvocationID.x;
    uint ch = gl_GlobalInvocationID.y;
    if (a >= pc.V || ch >= pc.chars) {
        return;
    }
    Affine m = blended(a, ch);
    vec4 rest = rest_tangents[a];
    vec3 t = vec3(dot(m.r0.xyz, rest.xyz), dot(m.r1.xyz, rest.xyz), dot(m.r2.xyz, rest.xyz));
    uint o = (ch * pc.V + a) * 3u;
    vec3 n = vec3(nrm[o], nrm[o + 1u], nrm[o + 2u]);
    t -= n * dot(n, t);
    float len = length(t);
    tangents[ch * pc.V + a] = vec4(len > 0.0 ? t / len : vec3(0.0), rest.w);
}
