// Key predictor D_l(q) = R(q) S(q) (paper §3, Eq. 3-4; docs/method.md §2-3), shared by predict.comp
// and fused_product.comp. Mirrors src/predict.rs in f32 with the same branch thresholds, so CPU
// and GPU agree away from the log's branch cut at pi. Reads the including shader's `bones`
// (chars x J Affine), `parents` (J int, then the delta-mush keys, read by mush()), `preds`
// (P Predictor) and `pc.J`. Built with MUSH for models with delta-mush keys (then it needs
// polar.glsl): without it, a model's predictors carry neither the keys' branch nor the rotation
// fit's registers.

const float NEAR_PI_SIN = 1e-2;
const float SMALL_ANGLE = 1e-4;

mat3 rotation_of(uint i) {
    Affine t = bones[i];
    return transpose(mat3(t.r0.xyz, t.r1.xyz, t.r2.xyz));
}

vec3 log_rotation(mat3 r) {
    vec3 v = vec3(r[1][2] - r[2][1], r[2][0] - r[0][2], r[0][1] - r[1][0]);
    float s = 0.5 * length(v);
    float c = 0.5 * (r[0][0] + r[1][1] + r[2][2] - 1.0);
    float angle = atan(s, c);
    if (angle < SMALL_ANGLE) {
        return v * (0.5 * (1.0 + angle * angle / 6.0));
    }
    if (s < NEAR_PI_SIN && c < 0.0) {
        // (R + R^T)/2 - cos(theta) I = (1 - cos(theta)) a a^T
        mat3 sym = 0.5 * (r + transpose(r)) - mat3(c);
        vec3 b0 = sym[0];
        vec3 b1 = sym[1];
        vec3 b2 = sym[2];
        vec3 axis = b2;
        if (b0.x >= b1.y && b0.x >= b2.z) {
            axis = b0;
        } else if (b1.y >= b2.z) {
            axis = b1;
        }
        axis = normalize(axis);
        if (dot(axis, v) < 0.0) {
            axis = -axis;
        }
        return axis * angle;
    }
    return v * (angle / (2.0 * s));
}

mat3 exp_rotation(vec3 w) {
    float a2 = dot(w, w);
    float a = sqrt(a2);
    float s;
    float c;
    if (a < SMALL_ANGLE) {
        s = 1.0 - a2 / 6.0;
        c = 0.5 - a2 / 24.0;
    } else {
        s = sin(a) / a;
        c = (1.0 - cos(a)) / a2;
    }
    mat3 k = mat3(vec3(0.0, w.z, -w.y), vec3(-w.z, 0.0, w.x), vec3(w.y, -w.x, 0.0));
    return mat3(1.0) + k * s + (k * k) * c;
}

// theta~_b = log(Q_parent^T Q_b), log(Q_b) for a root.
vec3 joint_rotation(uint base, uint b) {
    mat3 q = rotation_of(base + b);
    int p = parents[b];
    if (p >= 0) {
        return log_rotation(transpose(rotation_of(base + uint(p))) * q);
    }
    return log_rotation(q);
}

// W and W2 of predictor l (row-major in the buffer). naga cannot pass buffer arrays by value.
mat3 w_of(uint l) {
    return transpose(mat3(preds[l].w[0], preds[l].w[1], preds[l].w[2], preds[l].w[3],
        preds[l].w[4], preds[l].w[5], preds[l].w[6], preds[l].w[7], preds[l].w[8]));
}

mat3 w2_of(uint l) {
    return transpose(mat3(preds[l].w2[0], preds[l].w2[1], preds[l].w2[2], preds[l].w2[3],
        preds[l].w2[4], preds[l].w2[5], preds[l].w2[6], preds[l].w2[7], preds[l].w2[8]));
}

// S = rows of H x, x = [theta_b; theta_p; 1] (paper Eq. 4).
mat3 scale_shear(uint l, vec3 theta_b, vec3 theta_p) {
    float s[9];
    for (uint i = 0u; i < 9u; i++) {
        uint o = 7u * i;
        s[i] = preds[l].h[o] * theta_b.x + preds[l].h[o + 1u] * theta_b.y + preds[l].h[o + 2u] * theta_b.z
            + preds[l].h[o + 3u] * theta_p.x + preds[l].h[o + 4u] * theta_p.y + preds[l].h[o + 5u] * theta_p.z
            + preds[l].h[o + 6u];
    }
    return transpose(mat3(s[0], s[1], s[2], s[3], s[4], s[5], s[6], s[7], s[8]));
}

#ifdef MUSH
// Word i of the delta-mush keys after the J parents (src/vk/gpu_model.rs): P + 1 offsets into
// these words, key l's terms being words mush(l)..mush(l + 1) (none for a predictor's key),
// then the terms, 13 words each: the bone, then its 4x3 row-major Omega as float bits.
uint mush(uint i) {
    return uint(parents[pc.J + i]);
}

// Delta-mush key l's D = fit(sum_i [Q_i | d_i] Omega_i) (src/model/mod.rs, MushKeys), its
// terms being words first..end of mush().
mat3 mush_gradient(uint first, uint end, uint base) {
    float a[9];
    for (uint i = 0u; i < 9u; i++) {
        a[i] = 0.0;
    }
    for (uint o = first; o < end; o += 13u) {
        Affine m = bones[base + mush(o)];
        for (uint c = 0u; c < 3u; c++) {
            vec4 omega = vec4(uintBitsToFloat(mush(o + 1u + c)), uintBitsToFloat(mush(o + 4u + c)),
                uintBitsToFloat(mush(o + 7u + c)), uintBitsToFloat(mush(o + 10u + c)));
            a[c] += dot(m.r0, omega);
            a[3u + c] += dot(m.r1, omega);
            a[6u + c] += dot(m.r2, omega);
        }
    }
    float r[9];
    nearest_rotation(a, r);
    return transpose(mat3(r[0], r[1], r[2], r[3], r[4], r[5], r[6], r[7], r[8]));
}
#endif

// D_l(q) of the character whose bones start at `base`.
mat3 key_gradient(uint l, uint base) {
#ifdef MUSH
    uint first = mush(l);
    uint end = mush(l + 1u);
    if (first < end) {
        return mush_gradient(first, end, base);
    }
#endif
    uint bone = preds[l].bone;
    uint second = preds[l].second;
    vec3 theta_b = joint_rotation(base, bone);
    int p = parents[bone];
    mat3 q_parent = mat3(1.0);
    vec3 theta_p = vec3(0.0);
    if (p >= 0) {
        q_parent = rotation_of(base + uint(p));
        theta_p = joint_rotation(base, uint(p));
    }
    mat3 r = q_parent * exp_rotation(w_of(l) * theta_b * preds[l].u);
    if (second != 0xFFFFFFFFu) {
        r = r * exp_rotation(w2_of(l) * joint_rotation(base, second) * preds[l].u2);
    }
    return r * scale_shear(l, theta_b, theta_p);
}
