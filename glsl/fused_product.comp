#version 450
// Passes 1 and 2 in one, for a block-sparse [C1 | C2] whose proxies each read the columns of at
// most one key (GpuModel::new checks: the joint-blend models, where proxy e reads key e and its
// parent bone): sparse_product.comp's T with the entries of B = [d; q] computed where they are
// used, key l's D_l(q) by predictor.glsl (as pass 1 does) and a bone's from the input, so B is
// neither written nor read and pass 1 does not run. One invocation per (character, proxy); the
// invocations of a workgroup share the proxy, hence its predictor and its column loop; rows
// e >= P of workgroups copy bone e - P into the skinning palette [t; q].
layout(local_size_x = 64) in;

#include "predictor_types.glsl"

layout(std430, set = 0, binding = 0) readonly buffer ProductOffsets { uint offsets[]; };  // P + 1
layout(std430, set = 0, binding = 1) readonly buffer ProductColumns { uint columns[]; };  // stored
layout(std430, set = 0, binding = 2) readonly buffer ProductValues { vec4 vals[]; };      // stored
layout(std430, set = 0, binding = 3) readonly buffer Bones { Affine bones[]; };         // chars x J
layout(std430, set = 0, binding = 4) readonly buffer Parents { int parents[]; };        // J
layout(std430, set = 0, binding = 5) readonly buffer Predictors { Predictor preds[]; }; // P
layout(std430, set = 0, binding = 6) buffer Palette { vec4 proxies[]; };  // chars x (P + J) x 3 rows

layout(push_constant) uniform Push { uint P; uint J; uint chars; } pc;

#include "predictor.glsl"

void main() {
    uint ch = gl_GlobalInvocationID.x;
    uint e = gl_WorkGroupID.y;
    if (ch >= pc.chars) { return; }
    uint base = ch * pc.J;
    uint out_at = (ch * (pc.P + pc.J) + e) * 3u;
    if (e >= pc.P) {
        Affine t = bones[base + e - pc.P];
        proxies[out_at] = t.r0;
        proxies[out_at + 1u] = t.r1;
        proxies[out_at + 2u] = t.r2;
        return;
    }
    uint keys = 3u * pc.P;
    uint begin = offsets[e];
    uint end = offsets[e + 1u];
    // Columns ascend, so the key's (k < 3P, all of key k / 3) come first.
    mat3 d = mat3(0.0);
    if (begin < end && columns[begin] < keys) {
        d = key_gradient(columns[begin] / 3u, base);
    }
    vec4 acc0 = vec4(0.0);
    vec4 acc1 = vec4(0.0);
    vec4 acc2 = vec4(0.0);
    for (uint i = begin; i < end; i++) {
        uint k = columns[i];
        vec3 b;   // B[k][3 ch + c] for c = x, y, z
        if (k < keys) {
            b = d[k % 3u];   // B[3l + j] = D_l[c][j]: column j of D_l
        } else {
            uint j = (k - keys) % 4u;
            Affine t = bones[base + (k - keys) / 4u];
            b = vec3(t.r0[j], t.r1[j], t.r2[j]);
        }
        vec4 v = vals[i];
        acc0 += v * b.x;
        acc1 += v * b.y;
        acc2 += v * b.z;
    }
    proxies[out_at] = acc0;
    proxies[out_at + 1u] = acc1;
    proxies[out_at + 2u] = acc2;
}
