#version 450
// Passes 1 and 2 in one, for a block-sparse [C1 | C2] whose proxies each read the columns of at
// most one key (GpuModel::new checks: the joint-blend models, where proxy e reads key e and its
// parent bone): sparse_product.comp's T with the entries of B = [d; q] computed where they are
// used, key l's D_l(q) by key.glsl (as pass 1 does) and a bone's from the input, so B is
// neither written nor read and pass 1 does not run. One invocation per (character, proxy); the
// invocations of a workgroup share the proxy, hence its key and its column loop; rows
// e >= P of workgroups copy bone e - P into the skinning palette [t; q].
// Built with CORRECTIVES for a model with proxy correctives: a corrected proxy's invocation
// applies T (I + E) before it stores T (proxy_correction.glsl, one character), so the frame
// needs no proxy-correctives pass (one dispatch and one barrier fewer: the fixed cost of small
// crowds). The inverse of the corrected proxies' list (P entries, ~0u where uncorrected) follows
// the drivers in ProxyTopology.
layout(local_size_x = 64) in;

#include "affine.glsl"

layout(std430, set = 0, binding = 0) readonly buffer ProductOffsets { uint offsets[]; };  // P + 1
layout(std430, set = 0, binding = 1) readonly buffer ProductColumns { uint columns[]; };  // stored
layout(std430, set = 0, binding = 2) readonly buffer ProductValues { vec4 vals[]; };      // stored
layout(std430, set = 0, binding = 3) readonly buffer Bones { Affine bones[]; };         // chars x J
layout(std430, set = 0, binding = 4) readonly buffer Parents { int parents[]; };        // J
layout(std430, set = 0, binding = 5) readonly buffer Keys { uint keys[]; };             // key_words
layout(std430, set = 0, binding = 6) buffer Palette { vec4 proxies[]; };  // chars x (P + J) x 3 rows
#ifdef CORRECTIVES
layout(std430, set = 0, binding = 7) readonly buffer ProxyTopology { uint topology[]; };    // E, E + 1, sum D_i, P
layout(std430, set = 0, binding = 8) readonly buffer ProxyKernels { float kernels[]; };     // C x J x 9, J, up, J x 24
layout(std430, set = 0, binding = 9) readonly buffer ProxyMaps { vec4 maps[]; };            // sum F_i x 3 (x 4)

layout(push_constant) uniform Push { uint P; uint J; uint chars; uint E; uint C; uint L; } pc;
#endif
#ifdef PLAIN
layout(push_constant) uniform Push { uint P; uint J; uint chars; } pc;
#endif

#include "polar.glsl"
#include "key.glsl"
#ifdef CORRECTIVES
#include "joint_features.glsl"
#include "proxy_correction.glsl"
#endif

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
#ifdef CORRECTIVES
    // T' = T (I + E): row r of T plus T[r][0] E row 0 + T[r][1] E row 1 + T[r][2] E row 2.
    uint i = topology[2u * pc.E + 1u + topology[2u * pc.E] + e];
    if (i != ~0u) {
        vec4 e0;
        vec4 e1;
        vec4 e2;
        correction(ch, i, e0, e1, e2);
        acc0 += acc0.x * e0 + acc0.y * e1 + acc0.z * e2;
        acc1 += acc1.x * e0 + acc1.y * e1 + acc1.z * e2;
        acc2 += acc2.x * e0 + acc2.y * e1 + acc2.z * e2;
    }
#endif
    proxies[out_at] = acc0;
    proxies[out_at + 1u] = acc1;
    proxies[out_at + 2u] = acc2;
}
