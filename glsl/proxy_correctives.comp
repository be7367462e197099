#version 450
// Proxy correctives (docs/method.md §21), after whichever product wrote the proxies into the
// palette and before skinning: each corrected proxy T_e = [M | t] becomes, in place,
// T'_e = T_e (I + E_e) = [M (I + A) | t + M b] with E_e = [A | b] = sum over features f of
// x_f G_ef. The features of proxy e, driver after driver (b, its parent p, in order): if L,
// phi_b = vec(R_b - I) row-major with R_b = rot(Q_p)^T rot(Q_b) (joint_features.glsl),
// with GRAVITY gamma_b = rot(Q_b)^T u_c - u (u_c the character's up, u the model's, stored after
// the kernels' data), then for each kernel centre c < C, exp(-|phi_b - z_cb|^2 / w_b) - exp(-|z_cb|^2 / w_b) with
// z_cb the 9 floats of centre c * J + b and w_b = widths[b] (both terms computed alike: exactly
// zero at the rest pose). phi_b and gamma_b are first clamped into the joint's feature range
// (stored after the up; unbounded for a model without ranges).
//
// One invocation per (FOUR characters, corrected proxy i = y): each map row G_f is loaded once
// for four characters (CPU drivers pay every buffer load per lane, and the loads, not the
// multiply-adds, are the pass's cost there), the four characters' features are the lanes of a
// vec4 x_f, and their E rows accumulate as the columns of three mat4 (E_r += outer(G_f row r,
// x_f)). A workgroup's invocations share the proxy, so loop bounds and map loads are uniform.
// Characters of an invocation are 64 apart (adjacent invocations read adjacent characters).
// Models with proxy correctives whose product is not fused (a fused product applies them itself:
// fused_product.comp with CORRECTIVES).
layout(local_size_x = 64) in;

struct Affine { vec4 r0; vec4 r1; vec4 r2; };   // 3x4 row-major

layout(std430, set = 0, binding = 0) readonly buffer Bones { Affine bones[]; };             // chars x J
layout(std430, set = 0, binding = 1) readonly buffer Parents { int parents[]; };            // J
layout(std430, set = 0, binding = 2) readonly buffer ProxyTopology { uint topology[]; };    // E, E + 1, sum D_i
layout(std430, set = 0, binding = 3) readonly buffer ProxyKernels { float kernels[]; };     // C x J x 9, J, up, J x 24
layout(std430, set = 0, binding = 4) readonly buffer ProxyMaps { vec4 maps[]; };            // sum F_i x 3 (x 4)
layout(std430, set = 0, binding = 5) buffer Palette { Affine proxies[]; };                  // chars x (P + J)
#ifdef GRAVITY
layout(std430, set = 0, binding = 6) readonly buffer Ups { vec4 ups[]; };                   // chars
#endif

layout(push_constant) uniform Push { uint P; uint J; uint chars; uint E; uint C; uint L; } pc;

#include "joint_features.glsl"
#include "proxy_correction.glsl"

// E_r += outer(G_f row r, x): map row f (its 3 vec4 from m) times the four characters' x_f.
void add(inout mat4 e0, inout mat4 e1, inout mat4 e2, uint m, vec4 x) {
    e0 += outerProduct(maps[m], x);
    e1 += outerProduct(maps[m + 1u], x);
    e2 += outerProduct(maps[m + 2u], x);
}

#ifdef GRAVITY
// gamma_b = rot(Q_b)^T u_c - u of character ch: (Q^T u_c)_j = sum_k Q[k][j] u_c[k], clamped into
// [lo, hi].
vec3 gravity(uint ch, uint b, vec3 u, vec3 lo, vec3 hi) {
    Affine q = bones[ch * pc.J + b];
    vec3 uc = ups[ch].xyz;
    return clamp(uc.x * q.r0.xyz + uc.y * q.r1.xyz + uc.z * q.r2.xyz - u, lo, hi);
}
#endif

// Character ch's proxy T becomes T (I + E), E's rows e0, e1, e2: row r of T plus M[r][0] E row
// 0 + M[r][1] E row 1 + M[r][2] E row 2 (E's bottom row is zero). Nothing past the crowd.
void correct(uint ch, uint proxy, vec4 e0, vec4 e1, vec4 e2) {
    if (ch >= pc.chars) {
        return;
    }
    uint at = ch * (pc.P + pc.J) + proxy;
    Affine t = proxies[at];
    proxies[at] = Affine(t.r0 + t.r0.x * e0 + t.r0.y * e1 + t.r0.z * e2,
                         t.r1 + t.r1.x * e0 + t.r1.y * e1 + t.r1.z * e2,
                         t.r2 + t.r2.x * e0 + t.r2.y * e1 + t.r2.z * e2);
}

void main() {
    uint first_ch = gl_WorkGroupID.x * 256u + gl_LocalInvocationID.x;
    uint i = gl_WorkGroupID.y;
    if (first_ch >= pc.chars) {
        return;
    }
    // Characters past the crowd read the last one's bones and are not written.
    uint last_ch = pc.chars - 1u;
    uvec4 ch = min(uvec4(first_ch) + uvec4(0u, 64u, 128u, 192u), uvec4(last_ch));
    // E_r: column j is row r of character ch[j]'s E.
    mat4 e0 = mat4(0.0);
    mat4 e1 = mat4(0.0);
    mat4 e2 = mat4(0.0);
    uint first = topology[pc.E + i];
    uint last = topology[pc.E + i + 1u];
    uint g = 0u;
    uint widths = 9u * pc.C * pc.J;
    uint ranges = widths + (pc.C > 0u ? pc.J : 0u);
#ifdef GRAVITY
    g = 3u;
    vec3 u = vec3_at(ranges);
    ranges += 3u;
#endif
    uint m = 3u * first * (9u * pc.L + g + pc.C);
    for (uint k = first; k < last; k++) {
        uint b = topology[2u * pc.E + 1u + k];
        // The bounds loaded once for the four characters.
        mat3 lo = phi_bound(ranges, b, 0u);
        mat3 hi = phi_bound(ranges, b, 12u);
        mat3 f0 = clamped(joint_features(ch.x, b), lo, hi);
        mat3 f1 = clamped(joint_features(ch.y, b), lo, hi);
        mat3 f2 = clamped(joint_features(ch.z, b), lo, hi);
        mat3 f3 = clamped(joint_features(ch.w, b), lo, hi);
        if (pc.L != 0u) {
            // phi_b's entries 3r + c, one map row each (written out: local matrices indexed
            // in a loop cost CPU drivers a round trip through memory per lane).
            add(e0, e1, e2, m, vec4(f0[0][0], f1[0][0], f2[0][0], f3[0][0]));
            add(e0, e1, e2, m + 3u, vec4(f0[0][1], f1[0][1], f2[0][1], f3[0][1]));
            add(e0, e1, e2, m + 6u, vec4(f0[0][2], f1[0][2], f2[0][2], f3[0][2]));
            add(e0, e1, e2, m + 9u, vec4(f0[1][0], f1[1][0], f2[1][0], f3[1][0]));
            add(e0, e1, e2, m + 12u, vec4(f0[1][1], f1[1][1], f2[1][1], f3[1][1]));
            add(e0, e1, e2, m + 15u, vec4(f0[1][2], f1[1][2], f2[1][2], f3[1][2]));
            add(e0, e1, e2, m + 18u, vec4(f0[2][0], f1[2][0], f2[2][0], f3[2][0]));
            add(e0, e1, e2, m + 21u, vec4(f0[2][1], f1[2][1], f2[2][1], f3[2][1]));
            add(e0, e1, e2, m + 24u, vec4(f0[2][2], f1[2][2], f2[2][2], f3[2][2]));
            m += 27u;
        }
#ifdef GRAVITY
        vec3 glo = vec3_at(ranges + 24u * b + 9u);
        vec3 ghi = vec3_at(ranges + 24u * b + 21u);
        vec3 g0 = gravity(ch.x, b, u, glo, ghi);
        vec3 g1 = gravity(ch.y, b, u, glo, ghi);
        vec3 g2 = gravity(ch.z, b, u, glo, ghi);
        vec3 g3 = gravity(ch.w, b, u, glo, ghi);
        add(e0, e1, e2, m, vec4(g0.x, g1.x, g2.x, g3.x));
        add(e0, e1, e2, m + 3u, vec4(g0.y, g1.y, g2.y, g3.y));
        add(e0, e1, e2, m + 6u, vec4(g0.z, g1.z, g2.z, g3.z));
        m += 9u;
#endif
        if (pc.C > 0u) {
            float w = kernels[widths + b];
            mat3 zero = mat3(0.0);
            for (uint c = 0u; c < pc.C; c++) {
                uint z = (c * pc.J + b) * 9u;
                float at_rest = exp(-distance2(zero, z) / w);
                vec4 d = vec4(distance2(f0, z), distance2(f1, z), distance2(f2, z), distance2(f3, z));
                vec4 x = exp(-d / w) - vec4(at_rest);
                add(e0, e1, e2, m, x);
                m += 3u;
            }
        }
    }
    uint proxy = topology[i];
    correct(first_ch, proxy, e0[0], e1[0], e2[0]);
    correct(first_ch + 64u, proxy, e0[1], e1[1], e2[1]);
    correct(first_ch + 128u, proxy, e0[2], e1[2], e2[2]);
    correct(first_ch + 192u, proxy, e0[3], e1[3], e2[3]);
}
