// Key gradients D_l(q) (paper §3, Eq. 3-4; docs/method.md §2-3, §23), shared by predict.comp
// and fused_product.comp: key_gradient() dispatches once on the key's kind, as
// src/predict.rs's key_gradient does, and mirrors it in f32 with the same branch thresholds, so
// CPU and GPU agree away from the log's branch cut at pi. Reads the including shader's `bones`
// (chars x J Affine), `parents` (J int), `keys` (the keys' words: src/model/key.rs, key_words)
// and `pc.J`, and needs polar.glsl (the delta-mush keys' rotation fit) included before it.

// A key's kind: the first word of its record (src/model/key.rs, KeyKind).
const uint KEY_PREDICTOR = 0u;
const uint KEY_DELTA_MUSH = 1u;

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

float key_float(uint i) {
    return uintBitsToFloat(keys[i]);
}

// The row-major 3x3 at words i..i + 9 (a predictor's W or W2).
mat3 key_rows(uint i) {
    return transpose(mat3(key_float(i), key_float(i + 1u), key_float(i + 2u), key_float(i + 3u),
        key_float(i + 4u), key_float(i + 5u), key_float(i + 6u), key_float(i + 7u),
        key_float(i + 8u)));
}

// S = rows of H x, x = [theta_b; theta_p; 1] (paper Eq. 4), H (9 x 7) at words h..h + 63.
mat3 scale_shear(uint h, vec3 theta_b, vec3 theta_p) {
    float s[9];
    for (uint i = 0u; i < 9u; i++) {
        uint o = h + 7u * i;
        s[i] = key_float(o) * theta_b.x + key_float(o + 1u) * theta_b.y + key_float(o + 2u) * theta_b.z
            + key_float(o + 3u) * theta_p.x + key_float(o + 4u) * theta_p.y + key_float(o + 5u) * theta_p.z
            + key_float(o + 6u);
    }
    return transpose(mat3(s[0], s[1], s[2], s[3], s[4], s[5], s[6], s[7], s[8]));
}

// A predictor's D = R S, its words from `at`: bone, second bone (0xFFFFFFFF: none), u, u2,
// W (9), W2 (9), H (63).
mat3 predictor_gradient(uint at, uint base) {
    uint bone = keys[at];
    uint second = keys[at + 1u];
    vec3 theta_b = joint_rotation(base, bone);
    int p = parents[bone];
    mat3 q_parent = mat3(1.0);
    vec3 theta_p = vec3(0.0);
    if (p >= 0) {
        q_parent = rotation_of(base + uint(p));
        theta_p = joint_rotation(base, uint(p));
    }
    mat3 r = q_parent * exp_rotation(key_rows(at + 4u) * theta_b * key_float(at + 2u));
    if (second != 0xFFFFFFFFu) {
        r = r * exp_rotation(key_rows(at + 13u) * joint_rotation(base, second) * key_float(at + 3u));
    }
    return r * scale_shear(at + 22u, theta_b, theta_p);
}

// A delta-mush key's D = fit(sum_i [Q_i | d_i] Omega_i), its terms in words first..end, 13
// each: the bone, then its 4x3 row-major Omega.
mat3 delta_mush_gradient(uint first, uint end, uint base) {
    float a[9];
    for (uint i = 0u; i < 9u; i++) {
        a[i] = 0.0;
    }
    for (uint o = first; o < end; o += 13u) {
        Affine m = bones[base + keys[o]];
        for (uint c = 0u; c < 3u; c++) {
            vec4 omega = vec4(key_float(o + 1u + c), key_float(o + 4u + c), key_float(o + 7u + c),
                key_float(o + 10u + c));
            a[c] += dot(m.r0, omega);
            a[3u + c] += dot(m.r1, omega);
            a[6u + c] += dot(m.r2, omega);
        }
    }
    float r[9];
    nearest_rotation(a, r);
    return transpose(mat3(r[0], r[1], r[2], r[3], r[4], r[5], r[6], r[7], r[8]));
}

// D_l(q) of the character whose bones start at `base`: key l's record is words
// keys[l]..keys[l + 1], its kind first.
mat3 key_gradient(uint l, uint base) {
    uint at = keys[l];
    uint end = keys[l + 1u];
    if (keys[at] == KEY_DELTA_MUSH) {
        return delta_mush_gradient(at + 1u, end, base);
    }
    return predictor_gradient(at + 1u, base);
}
