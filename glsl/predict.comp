#version 450
// Pass 1: key gradients D_l(q) of every kind (key.glsl), written with the bone transforms into
// B = [d; q], the right-hand side of pass 2's product:
// B[(3l + j), 3ch + c] = D_l[c][j] and B[3P + 4b + j, 3ch + c] = Q_b[c][j], row-major.
// One invocation per (l = x < P + J, character = y): l < P evaluates key l, otherwise
// copies bone l - P, into B and into the skinning palette [t; q] (Palette, entry P + b). Models whose product evaluates its keys itself
// (fused_product.comp) do not run this pass.
layout(local_size_x = 64) in;

#include "affine.glsl"

layout(std430, set = 0, binding = 0) readonly buffer Bones { Affine bones[]; };           // chars x J
layout(std430, set = 0, binding = 1) readonly buffer Parents { int parents[]; };          // J
layout(std430, set = 0, binding = 2) readonly buffer Keys { uint keys[]; };               // key_words
layout(std430, set = 0, binding = 3) buffer Rhs { float bmat[]; };      // (3P + 4J) x 3 chars
layout(std430, set = 0, binding = 4) buffer Palette { Affine palette[]; };   // chars x (P + J)

layout(push_constant) uniform Push { uint P; uint J; uint chars; } pc;

#include "polar.glsl"
#include "key.glsl"

void main() {
    uint l = gl_GlobalInvocationID.x;
    uint ch = gl_GlobalInvocationID.y;
    if (l >= pc.P + pc.J || ch >= pc.chars) {
        return;
    }
    uint n_cols = 3u * pc.chars;
    uint base = ch * pc.J;
    if (l >= pc.P) {
        uint b = l - pc.P;
        Affine t = bones[base + b];
        palette[ch * (pc.P + pc.J) + l] = t;
        uint row = 3u * pc.P + 4u * b;
        for (uint j = 0u; j < 4u; j++) {
            uint o = (row + j) * n_cols + 3u * ch;
            bmat[o] = t.r0[j];
            bmat[o + 1u] = t.r1[j];
            bmat[o + 2u] = t.r2[j];
        }
        return;
    }
    mat3 dmat = key_gradient(l, base);
    for (uint j = 0u; j < 3u; j++) {
        uint o = (3u * l + j) * n_cols + 3u * ch;
        bmat[o] = dmat[j][0];       // D[0][j]: GLSL indexes [column][row]
        bmat[o + 1u] = dmat[j][1];
        bmat[o + 2u] = dmat[j][2];
    }
}
