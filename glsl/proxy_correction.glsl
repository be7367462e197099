// The proxy correctives' features and one character's E (docs/method.md §21), shared by
// proxy_correctives.comp (four characters an invocation, its own accumulation) and
// fused_product.comp built with CORRECTIVES (one). Reads the including shader's `topology`,
// `kernels`, `maps` (ProxyTopology, ProxyKernels, ProxyMaps), `bones`, `parents` and the push
// words J, E, C, L; needs joint_features.glsl before it.

// The 3 floats of `kernels` from `at`.
vec3 vec3_at(uint at) {
    return vec3(kernels[at], kernels[at + 1u], kernels[at + 2u]);
}

// |phi - z|^2 of one character, z the 9 floats of a kernel centre from z.
float distance2(mat3 phi, uint z) {
    vec3 d0 = phi[0] - vec3_at(z);
    vec3 d1 = phi[1] - vec3_at(z + 3u);
    vec3 d2 = phi[2] - vec3_at(z + 6u);
    return dot(d0, d0) + dot(d1, d1) + dot(d2, d2);
}

// Bone b's feature range (docs/method.md §21) from `at`: 24 floats a bone, its 12 lower bounds
// then its 12 upper (phi_b's 9, then gamma_b's 3). One bound of phi_b, laid out as
// joint_features gives phi_b, from `side` (0: lower, 12: upper).
mat3 phi_bound(uint at, uint b, uint side) {
    uint o = at + 24u * b + side;
    return mat3(vec3_at(o), vec3_at(o + 3u), vec3_at(o + 6u));
}

// f clamped into [lo, hi], entry by entry.
mat3 clamped(mat3 f, mat3 lo, mat3 hi) {
    return mat3(clamp(f[0], lo[0], hi[0]), clamp(f[1], lo[1], hi[1]), clamp(f[2], lo[2], hi[2]));
}

// E = sum_f x_f G_f of corrected proxy i for character ch: its rows e0, e1, e2 (the bottom row
// is zero). The features driver after driver: the 9 linear phi_b entries 3r + c where L, then
// the C kernels exp(-|phi_b - z_cb|^2 / w_b) - exp(-|z_cb|^2 / w_b), phi_b clamped into its
// range; each one map row (3 vec4). The model has no gravity (a fused product never sees it).
void correction(uint ch, uint i, out vec4 e0, out vec4 e1, out vec4 e2) {
    e0 = vec4(0.0);
    e1 = vec4(0.0);
    e2 = vec4(0.0);
    uint first = topology[pc.E + i];
    uint last = topology[pc.E + i + 1u];
    uint m = 3u * first * (9u * pc.L + pc.C);
    uint widths = 9u * pc.C * pc.J;
    uint ranges = widths + (pc.C > 0u ? pc.J : 0u);
    for (uint k = first; k < last; k++) {
        uint b = topology[2u * pc.E + 1u + k];
        mat3 lo = phi_bound(ranges, b, 0u);
        mat3 hi = phi_bound(ranges, b, 12u);
        mat3 f = clamped(joint_features(ch, b), lo, hi);
        if (pc.L != 0u) {
            for (uint r = 0u; r < 3u; r++) {
                for (uint c = 0u; c < 3u; c++) {
                    float x = f[r][c];
                    e0 += maps[m] * x;
                    e1 += maps[m + 1u] * x;
                    e2 += maps[m + 2u] * x;
                    m += 3u;
                }
            }
        }
        if (pc.C > 0u) {
            float w = kernels[widths + b];
            for (uint c = 0u; c < pc.C; c++) {
                uint z = (c * pc.J + b) * 9u;
                float x = exp(-distance2(f, z) / w) - exp(-distance2(mat3(0.0), z) / w);
                e0 += maps[m] * x;
                e1 += maps[m + 1u] * x;
                e2 += maps[m + 2u] * x;
                m += 3u;
            }
        }
    }
}
