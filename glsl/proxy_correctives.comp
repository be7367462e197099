#version 450
// Proxy correctives (docs/method.md §21), after whichever product wrote the proxies into the
// palette and before skinning: each corrected proxy T_e = [M | t] becomes, in place,
// T'_e = T_e (I + E_e) = [M (I + A) | t + M b] with E_e = [A | b] = sum over features f of
// x_f G_ef. The features of proxy e, driver after driver (b, its parent p, in order): if L,
// phi_b = vec(R_b - I) row-major with R_b = rot(Q_p)^T rot(Q_b) (as corrective_weights.comp),
// then for each kernel centre c < C, exp(-|phi_b - z_cb|^2 / w_b) - exp(-|z_cb|^2 / w_b) with
// z_cb the 9 floats of centre c * J + b and w_b = widths[b] (both terms computed alike: exactly
// zero at the rest pose). One invocation per (character = x, corrected proxy i = y): the
// invocations of a workgroup share the proxy, so loop bounds and map loads are uniform.
// Models with proxy correctives only.
layout(local_size_x = 64) in;

struct Affine { vec4 r0; vec4 r1; vec4 r2; };   // 3x4 row-major

layout(std430, set = 0, binding = 0) readonly buffer Bones { Affine bones[]; };             // chars x J
layout(std430, set = 0, binding = 1) readonly buffer Parents { int parents[]; };            // J
layout(std430, set = 0, binding = 2) readonly buffer ProxyTopology { uint topology[]; };    // E, E + 1, sum D_i
layout(std430, set = 0, binding = 3) readonly buffer ProxyKernels { float kernels[]; };     // C x J x 9, J
layout(std430, set = 0, binding = 4) readonly buffer ProxyMaps { vec4 maps[]; };            // sum F_i x 3 (x 4)
layout(std430, set = 0, binding = 5) buffer Palette { Affine proxies[]; };                  // chars x (P + J)

layout(push_constant) uniform Push { uint P; uint J; uint chars; uint E; uint C; uint L; } pc;

// e + x G_f, G_f the 12 floats of map row f (the rows of [A | b]).
Affine add(Affine e, float x, uint f) {
    uint m = 3u * f;
    return Affine(e.r0 + x * maps[m], e.r1 + x * maps[m + 1u], e.r2 + x * maps[m + 2u]);
}

void main() {
    uint ch = gl_GlobalInvocationID.x;
    uint i = gl_WorkGroupID.y;
    if (ch >= pc.chars) {
        return;
    }
    Affine e = Affine(vec4(0.0), vec4(0.0), vec4(0.0));
    uint first = topology[pc.E + i];
    uint last = topology[pc.E + i + 1u];
    uint per = 9u * pc.L + pc.C;
    uint f = first * per;
    uint base = ch * pc.J;
    uint widths = 9u * pc.C * pc.J;
    for (uint k = first; k < last; k++) {
        uint b = topology[2u * pc.E + 1u + k];
        Affine qb = bones[base + b];
        Affine qp = bones[base + uint(parents[b])];
        // Column r of Q_p (its rows' r-th entries) combines Q_b's rows into row r of R.
        vec3 pr0 = vec3(qp.r0.x, qp.r1.x, qp.r2.x);
        vec3 pr1 = vec3(qp.r0.y, qp.r1.y, qp.r2.y);
        vec3 pr2 = vec3(qp.r0.z, qp.r1.z, qp.r2.z);
        vec3 f0 = pr0.x * qb.r0.xyz + pr0.y * qb.r1.xyz + pr0.z * qb.r2.xyz - vec3(1.0, 0.0, 0.0);
        vec3 f1 = pr1.x * qb.r0.xyz + pr1.y * qb.r1.xyz + pr1.z * qb.r2.xyz - vec3(0.0, 1.0, 0.0);
        vec3 f2 = pr2.x * qb.r0.xyz + pr2.y * qb.r1.xyz + pr2.z * qb.r2.xyz - vec3(0.0, 0.0, 1.0);
        if (pc.L != 0u) {
            e = add(e, f0.x, f);
            e = add(e, f0.y, f + 1u);
            e = add(e, f0.z, f + 2u);
            e = add(e, f1.x, f + 3u);
            e = add(e, f1.y, f + 4u);
            e = add(e, f1.z, f + 5u);
            e = add(e, f2.x, f + 6u);
            e = add(e, f2.y, f + 7u);
            e = add(e, f2.z, f + 8u);
            f += 9u;
        }
        if (pc.C > 0u) {
            float w = kernels[widths + b];
            for (uint c = 0u; c < pc.C; c++) {
                uint z = (c * pc.J + b) * 9u;
                vec3 z0 = vec3(kernels[z], kernels[z + 1u], kernels[z + 2u]);
                vec3 z1 = vec3(kernels[z + 3u], kernels[z + 4u], kernels[z + 5u]);
                vec3 z2 = vec3(kernels[z + 6u], kernels[z + 7u], kernels[z + 8u]);
                vec3 d0 = f0 - z0;
                vec3 d1 = f1 - z1;
                vec3 d2 = f2 - z2;
                vec3 n0 = vec3(0.0) - z0;
                vec3 n1 = vec3(0.0) - z1;
                vec3 n2 = vec3(0.0) - z2;
                float d = dot(d0, d0) + dot(d1, d1) + dot(d2, d2);
                float r = dot(n0, n0) + dot(n1, n1) + dot(n2, n2);
                e = add(e, exp(-d / w) - exp(-r / w), f);
                f += 1u;
            }
        }
    }
    uint at = ch * (pc.P + pc.J) + topology[i];
    Affine t = proxies[at];
    // Row r of T (I + E): row r of T plus M[r][0] E row 0 + M[r][1] E row 1 + M[r][2] E row 2
    // (E's bottom row is zero).
    Affine o;
    o.r0 = t.r0 + t.r0.x * e.r0 + t.r0.y * e.r1 + t.r0.z * e.r2;
    o.r1 = t.r1 + t.r1.x * e.r0 + t.r1.y * e.r1 + t.r1.z * e.r2;
    o.r2 = t.r2 + t.r2.x * e.r0 + t.r2.y * e.r1 + t.r2.z * e.r2;
    proxies[at] = o;
}
