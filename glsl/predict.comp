#version 450
// Pass 1: key predictors D_l(q) = R(q) S(q) (paper §3, Eq. 3-4; METHOD.md §2-3), written with
// the bone transforms into B = [d; q], the right-hand side of pass 2's product:
// B[(3l + j), 3ch + c] = D_l[c][j] and B[3P + 4b + j, 3ch + c] = Q_b[c][j], row-major.
// One invocation per (l = x < P + J, character = y): l < P evaluates predictor l, otherwise
// copies bone l - P. Mirrors src/predict.rs in f32 with the same branch thresholds, so CPU and
// GPU agree away from the log's branch cut at pi.
layout(local_size_x = 64) in;

struct Affine { vec4 r0; vec4 r1; vec4 r2; };   // 3x4 row-major bone transform

// Same word layout as a PRED record of the .rrs file (src/model/file.rs).
struct Predictor {
    uint bone; uint second;      // second = 0xFFFFFFFF: none
    float u; float u2;
    float w[9]; float w2[9];     // row-major 3x3 rotations
    float h[63];                 // H: 9 x 7 row-major
};

layout(std430, set = 0, binding = 0) readonly buffer Bones { Affine bones[]; };           // chars x J
layout(std430, set = 0, binding = 1) readonly buffer Parents { int parents[]; };          // J
layout(std430, set = 0, binding = 2) readonly buffer Predictors { Predictor preds[]; };   // P
layout(std430, set = 0, binding = 3) buffer Rhs { float bmat[]; };      // (3P + 4J) x 3 chars

layout(push_constant) uniform Push { uint P; uint J; uint chars; } pc;

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
        uint row = 3u * pc.P + 4u * b;
        for (uint j = 0u; j < 4u; j++) {
            uint o = (row + j) * n_cols + 3u * ch;
            bmat[o] = t.r0[j];
            bmat[o + 1u] = t.r1[j];
            bmat[o + 2u] = t.r2[j];
        }
        return;
    }
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
    mat3 dmat = r * scale_shear(l, theta_b, theta_p);
    for (uint j = 0u; j < 3u; j++) {
        uint o = (3u * l + j) * n_cols + 3u * ch;
        bmat[o] = dmat[j][0];       // D[0][j]: GLSL indexes [column][row]
        bmat[o + 1u] = dmat[j][1];
        bmat[o + 2u] = dmat[j][2];
    }
}
