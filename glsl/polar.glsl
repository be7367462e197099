// The rotation nearest to a 3x3 matrix A, the proper R maximising tr(R^T A) (Horn's quaternion
// method by cyclic Jacobi sweeps): src/polar.rs line for line in f32, same sweeps and ties.
// A and the result are row-major: a[3r + c] = A[r][c].

const uint POLAR_SWEEPS = 5u;

// One Jacobi rotation of the symmetric 4x4 n (row-major) in the (p, q) plane, zeroing n[p][q]
// (Numerical Recipes 11.1, t the smaller root), accumulated into the eigenvectors v.
void jacobi(inout float n[16], inout float v[16], uint p, uint q) {
    float apq = n[4u * p + q];
    if (apq == 0.0) {
        return;
    }
    float theta = (n[5u * q] - n[5u * p]) / (2.0 * apq);
    float t;
    if (abs(theta) > 1e15) {
        t = 0.5 / theta;
    } else {
        t = 1.0 / (abs(theta) + sqrt(theta * theta + 1.0));
        if (theta < 0.0) {
            t = -t;
        }
    }
    float c = 1.0 / sqrt(t * t + 1.0);
    float s = t * c;
    for (uint k = 0u; k < 4u; k++) {
        float kp = n[4u * k + p];
        float kq = n[4u * k + q];
        n[4u * k + p] = c * kp - s * kq;
        n[4u * k + q] = s * kp + c * kq;
    }
    for (uint k = 0u; k < 4u; k++) {
        float pk = n[4u * p + k];
        float qk = n[4u * q + k];
        n[4u * p + k] = c * pk - s * qk;
        n[4u * q + k] = s * pk + c * qk;
    }
    for (uint k = 0u; k < 4u; k++) {
        float kp = v[4u * k + p];
        float kq = v[4u * k + q];
        v[4u * k + p] = c * kp - s * kq;
        v[4u * k + q] = s * kp + c * kq;
    }
}

void nearest_rotation(float a[9], out float rot[9]) {
    float n[16];
    n[0] = a[0] + a[4] + a[8];
    n[1] = a[7] - a[5];
    n[2] = a[2] - a[6];
    n[3] = a[3] - a[1];
    n[5] = a[0] - a[4] - a[8];
    n[6] = a[3] + a[1];
    n[7] = a[2] + a[6];
    n[10] = a[4] - a[0] - a[8];
    n[11] = a[7] + a[5];
    n[15] = a[8] - a[0] - a[4];
    n[4] = n[1];
    n[8] = n[2];
    n[9] = n[6];
    n[12] = n[3];
    n[13] = n[7];
    n[14] = n[11];
    float v[16];
    for (uint i = 0u; i < 16u; i++) {
        v[i] = (i % 5u == 0u) ? 1.0 : 0.0;
    }
    // The pairs by literal indices (no loop over them): once the driver inlines jacobi(),
    // every index into n and v is a constant, so both stay in registers.
    for (uint sweep = 0u; sweep < POLAR_SWEEPS; sweep++) {
        jacobi(n, v, 0u, 1u);
        jacobi(n, v, 0u, 2u);
        jacobi(n, v, 0u, 3u);
        jacobi(n, v, 1u, 2u);
        jacobi(n, v, 1u, 3u);
        jacobi(n, v, 2u, 3u);
    }
    // The largest eigenvalue's column, ties to the first (the identity for A = 0).
    float top = n[0];
    vec4 e = vec4(v[0], v[4], v[8], v[12]);
    if (n[5] > top) {
        top = n[5];
        e = vec4(v[1], v[5], v[9], v[13]);
    }
    if (n[10] > top) {
        top = n[10];
        e = vec4(v[2], v[6], v[10], v[14]);
    }
    if (n[15] > top) {
        e = vec4(v[3], v[7], v[11], v[15]);
    }
    float w = e.x;
    float x = e.y;
    float y = e.z;
    float z = e.w;
    float s = 2.0 / (w * w + x * x + y * y + z * z);
    rot[0] = 1.0 - s * (y * y + z * z);
    rot[1] = s * (x * y - w * z);
    rot[2] = s * (x * z + w * y);
    rot[3] = s * (x * y + w * z);
    rot[4] = 1.0 - s * (x * x + z * z);
    rot[5] = s * (y * z - w * x);
    rot[6] = s * (x * z - w * y);
    rot[7] = s * (y * z + w * x);
    rot[8] = 1.0 - s * (x * x + y * y);
}
