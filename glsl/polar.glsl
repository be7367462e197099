// The rotation of a delta-mush key's rigid fit for a 3x3 A, toward the proper R maximising
// tr(R^T A): the Gram-Schmidt guess and Newton steps on the rotation group, src/polar.rs in f32
// with the same guess, steps, damping and order of operations. A and the result are row-major:
// a[3r + c] = A[r][c].

const uint NEWTON_STEPS = 2u;
// Below this sine of the angle between A's first two columns (or with either zero), the guess
// is the identity.
const float GUESS_SINE = 1e-4;
// H is damped by this times tr(M).
const float DAMPING = 1e-3;

// The guess G (columns): g0 = a0 / |a0|, g2 = (a0 x a1) / |a0 x a1|, g1 = g2 x g0; the identity
// below GUESS_SINE.
mat3 guess(mat3 a) {
    vec3 c0 = a[0];
    vec3 c1 = a[1];
    vec3 x = vec3(c0.y * c1.z - c0.z * c1.y, c0.z * c1.x - c0.x * c1.z, c0.x * c1.y - c0.y * c1.x);
    float l0 = sqrt(dot(c0, c0));
    float l1 = sqrt(dot(c1, c1));
    float lx = sqrt(dot(x, x));
    if (lx > GUESS_SINE * l0 * l1) {
        vec3 g0 = c0 / l0;
        vec3 g2 = x / lx;
        vec3 g1 = vec3(g2.y * g0.z - g2.z * g0.y, g2.z * g0.x - g2.x * g0.z, g2.x * g0.y - g2.y * g0.x);
        return mat3(g0, g1, g2);
    }
    return mat3(1.0);
}

// One Newton step from the rotation r toward the fit of a (both by columns): r R(w), with
// M = r^T A, g its skew part's axis, H = tr(M) (1 + DAMPING) I - sym(M), w = H^-1 g, R(w) the
// rotation of the quaternion (1, w / 2); r itself where H is not positive definite.
mat3 newton_step(mat3 r, mat3 a) {
    mat3 m = transpose(r) * a;   // m[c][r] = M[r][c]
    vec3 g = vec3(m[1][2] - m[2][1], m[2][0] - m[0][2], m[0][1] - m[1][0]);
    float t = m[0][0] + m[1][1] + m[2][2];
    float d = t * (1.0 + DAMPING);
    float h00 = d - m[0][0];
    float h11 = d - m[1][1];
    float h22 = d - m[2][2];
    float h01 = -0.5 * (m[1][0] + m[0][1]);
    float h02 = -0.5 * (m[2][0] + m[0][2]);
    float h12 = -0.5 * (m[2][1] + m[1][2]);
    float j00 = h11 * h22 - h12 * h12;
    float j11 = h00 * h22 - h02 * h02;
    float j22 = h00 * h11 - h01 * h01;
    float j01 = h02 * h12 - h01 * h22;
    float j02 = h01 * h12 - h02 * h11;
    float j12 = h01 * h02 - h00 * h12;
    float det = h00 * j00 + h01 * j01 + h02 * j02;
    float half_ = (h00 > 0.0 && j22 > 0.0 && det > 0.0) ? 0.5 / det : 0.0;
    float x = half_ * (j00 * g.x + j01 * g.y + j02 * g.z);
    float y = half_ * (j01 * g.x + j11 * g.y + j12 * g.z);
    float z = half_ * (j02 * g.x + j12 * g.y + j22 * g.z);
    float s = 2.0 / (1.0 + x * x + y * y + z * z);
    mat3 q = mat3(
        1.0 - s * (y * y + z * z), s * (x * y + z), s * (x * z - y),
        s * (x * y - z), 1.0 - s * (x * x + z * z), s * (y * z + x),
        s * (x * z + y), s * (y * z - x), 1.0 - s * (x * x + y * y));
    return r * q;
}

void nearest_rotation(float a_in[9], out float rot[9]) {
    mat3 a = mat3(a_in[0], a_in[3], a_in[6], a_in[1], a_in[4], a_in[7], a_in[2], a_in[5], a_in[8]);
    mat3 r = guess(a);
    for (uint step = 0u; step < NEWTON_STEPS; step++) {
        r = newton_step(r, a);
    }
    rot[0] = r[0][0]; rot[1] = r[1][0]; rot[2] = r[2][0];
    rot[3] = r[0][1]; rot[4] = r[1][1]; rot[5] = r[2][1];
    rot[6] = r[0][2]; rot[7] = r[1][2]; rot[8] = r[2][2];
}
