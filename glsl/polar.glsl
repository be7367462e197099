// The rotation nearest to a 3x3 matrix A, the proper R maximising tr(R^T A) (Horn's quaternion
// method by cyclic Jacobi sweeps from a guess): src/polar.rs in f32, same guess, sweeps and ties.
// A and the result are row-major: a[3r + c] = A[r][c].

const uint POLAR_SWEEPS = 4u;
// Below this sine of the angle between A's first two columns (or with either zero), the guess
// is the identity.
const float GUESS_SINE = 1e-4;

// One Jacobi rotation of the symmetric 4x4 n (row-major) in the (p, q) plane, zeroing n[p][q]
// (Numerical Recipes 11.1, eq. 11.1.14-11.1.18, t the smaller root): the diagonal moves by
// t apq, the other rows' entries turn by (s, tau) and are mirrored, and the rotation is
// accumulated into the eigenvectors v.
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
    float tau = s / (1.0 + c);
    float h = t * apq;
    n[5u * p] -= h;
    n[5u * q] += h;
    n[4u * p + q] = 0.0;
    n[4u * q + p] = 0.0;
    for (uint k = 0u; k < 4u; k++) {
        if (k == p || k == q) {
            continue;
        }
        float g = n[4u * k + p];
        float hk = n[4u * k + q];
        float kp = g - s * (hk + g * tau);
        float kq = hk + s * (g - hk * tau);
        n[4u * k + p] = kp;
        n[4u * p + k] = kp;
        n[4u * k + q] = kq;
        n[4u * q + k] = kq;
    }
    for (uint k = 0u; k < 4u; k++) {
        float g = v[4u * k + p];
        float hk = v[4u * k + q];
        v[4u * k + p] = g - s * (hk + g * tau);
        v[4u * k + q] = hk + s * (g - hk * tau);
    }
}

// The guess G (row-major) of src/polar.rs: the Gram-Schmidt frame of A's first two columns,
// the identity below GUESS_SINE. The sweeps then work on A' = G^T A, nearly symmetric wherever
// A is nearly a rotation times a stretch, and the result is G R'.
void guess(float a[9], out float g[9]) {
    vec3 c0 = vec3(a[0], a[3], a[6]);
    vec3 c1 = vec3(a[1], a[4], a[7]);
    vec3 x = vec3(c0.y * c1.z - c0.z * c1.y, c0.z * c1.x - c0.x * c1.z, c0.x * c1.y - c0.y * c1.x);
    float l0 = sqrt(dot(c0, c0));
    float l1 = sqrt(dot(c1, c1));
    float lx = sqrt(dot(x, x));
    vec3 g0 = vec3(1.0, 0.0, 0.0);
    vec3 g1 = vec3(0.0, 1.0, 0.0);
    vec3 g2 = vec3(0.0, 0.0, 1.0);
    if (lx > GUESS_SINE * l0 * l1) {
        g0 = c0 / l0;
        g2 = x / lx;
        g1 = vec3(g2.y * g0.z - g2.z * g0.y, g2.z * g0.x - g2.x * g0.z, g2.x * g0.y - g2.y * g0.x);
    }
    g[0] = g0.x; g[1] = g1.x; g[2] = g2.x;
    g[3] = g0.y; g[4] = g1.y; g[5] = g2.y;
    g[6] = g0.z; g[7] = g1.z; g[8] = g2.z;
}

void nearest_rotation(float a_in[9], out float rot[9]) {
    float g[9];
    guess(a_in, g);
    // A' = G^T A, written out: a local array indexed in a loop costs CPU drivers a round trip
    // through memory per lane.
    mat3 gm = mat3(g[0], g[3], g[6], g[1], g[4], g[7], g[2], g[5], g[8]);   // columns
    mat3 am = mat3(a_in[0], a_in[3], a_in[6], a_in[1], a_in[4], a_in[7], a_in[2], a_in[5], a_in[8]);
    mat3 ap = transpose(gm) * am;
    float a[9];
    a[0] = ap[0][0]; a[1] = ap[1][0]; a[2] = ap[2][0];
    a[3] = ap[0][1]; a[4] = ap[1][1]; a[5] = ap[2][1];
    a[6] = ap[0][2]; a[7] = ap[1][2]; a[8] = ap[2][2];
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
    float r[9];
    r[0] = 1.0 - s * (y * y + z * z);
    r[1] = s * (x * y - w * z);
    r[2] = s * (x * z + w * y);
    r[3] = s * (x * y + w * z);
    r[4] = 1.0 - s * (x * x + z * z);
    r[5] = s * (y * z - w * x);
    r[6] = s * (x * z - w * y);
    r[7] = s * (y * z + w * x);
    r[8] = 1.0 - s * (x * x + y * y);
    // R = G R'
    mat3 rm = gm * mat3(r[0], r[3], r[6], r[1], r[4], r[7], r[2], r[5], r[8]);
    rot[0] = rm[0][0]; rot[1] = rm[1][0]; rot[2] = rm[2][0];
    rot[3] = rm[0][1]; rot[4] = rm[1][1]; rot[5] = rm[2][1];
    rot[6] = rm[0][2]; rot[7] = rm[1][2]; rot[8] = rm[2][2];
}
