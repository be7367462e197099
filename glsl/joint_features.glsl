// phi_b = vec(R_b - I) of bone b of character ch, R_b = rot(Q_p)^T rot(Q_b) with p its parent
// (docs/method.md §20, §21): the features of the pose-space correctives and the linear features
// of the proxy correctives, shared by corrective_weights.comp and proxy_correctives.comp;
// src/predict.rs `rotation_features` in f64. The rows of R_b - I are the columns of the mat3
// (the row-major phi_b entry 3r + c is [r][c]). Reads the including shader's `bones` (chars x J
// Affine), `parents` (J int) and `pc.J`.
mat3 joint_features(uint ch, uint b) {
    Affine qb = bones[ch * pc.J + b];
    Affine qp = bones[ch * pc.J + uint(parents[b])];
    // Column r of Q_p (its rows' r-th entries) combines Q_b's rows into row r of R.
    vec3 pr0 = vec3(qp.r0.x, qp.r1.x, qp.r2.x);
    vec3 pr1 = vec3(qp.r0.y, qp.r1.y, qp.r2.y);
    vec3 pr2 = vec3(qp.r0.z, qp.r1.z, qp.r2.z);
    return mat3(pr0.x * qb.r0.xyz + pr0.y * qb.r1.xyz + pr0.z * qb.r2.xyz - vec3(1.0, 0.0, 0.0),
                pr1.x * qb.r0.xyz + pr1.y * qb.r1.xyz + pr1.z * qb.r2.xyz - vec3(0.0, 1.0, 0.0),
                pr2.x * qb.r0.xyz + pr2.y * qb.r1.xyz + pr2.z * qb.r2.xyz - vec3(0.0, 0.0, 1.0));
}
