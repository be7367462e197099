//! Scale/shear regression (paper §3.3, Eq. 4; docs/method.md §3): `vec(S(q)) = H x(q)` with
//! `x = [θ~_b1; θ~_p(b1); 1] ∈ R⁷`, vec stacking the rows of S, H (9 x 7) by ridge regression
//! toward H₀ (bias column vec(I), rest 0): with fewer poses than unknowns the plain least
//! squares problem is underdetermined.

use crate::linalg::cholesky_solve;
use crate::train::rotreg::PoseFeatures;
use glam::{DMat3, DVec3};

/// H: 9 x 7, row-major.
pub type ScaleShear = [f64; 63];

/// The feature vector x for bone `b` (its parent's joint rotation is zero for a root).
pub fn features(f: &PoseFeatures, parents: &[Option<usize>], b: usize) -> [f64; 7] {
    let t = f.theta[b];
    let p = parents[b].map_or(DVec3::ZERO, |p| f.theta[p]);
    [t.x, t.y, t.z, p.x, p.y, p.z, 1.0]
}

/// H₀: S = I whatever the pose.
pub fn identity() -> ScaleShear {
    let mut h = [0.0; 63];
    for i in [0, 4, 8] {
        h[7 * i + 6] = 1.0;
    }
    h
}

/// argmin_H Σ_i |vec(S_i) − H x_i|² + λ N |H − H₀|² with the bias column pinned to vec(I):
/// at the rest pose (θ = 0) the gradient is the identity whatever the training poses were, so
/// wide training poses cannot leave an average bulge on gentle ones. λ is per pose.
pub fn fit(stretches: &[DMat3], xs: &[[f64; 7]], lambda: f64) -> ScaleShear {
    let h0 = identity();
    let n = xs.len() as f64;
    let mut gram = [0.0; 36];
    let mut rhs = [[0.0; 6]; 9];
    for (s, x) in stretches.iter().zip(xs) {
        let s_rows = (*s - DMat3::IDENTITY).transpose().to_cols_array();
        for r in 0..6 {
            for c in 0..6 {
                gram[r * 6 + c] += x[r] * x[c];
            }
        }
        for (o, row) in rhs.iter_mut().enumerate() {
            for c in 0..6 {
                row[c] += s_rows[o] * x[c];
            }
        }
    }
    for r in 0..6 {
        gram[r * 6 + r] += lambda * n + 1e-12;
    }
    let mut h = h0;
    for (o, row) in rhs.iter().enumerate() {
        let mut b = row.to_vec();
        let a = gram.to_vec();
        cholesky_solve(&a, &mut b, 6);
        h[7 * o..7 * o + 6].copy_from_slice(&b);
    }
    h
}

/// S(q) = rows of H x.
pub fn predict(h: &ScaleShear, x: &[f64; 7]) -> DMat3 {
    let mut rows = [0.0; 9];
    for (o, v) in rows.iter_mut().enumerate() {
        *v = (0..7).map(|c| h[7 * o + c] * x[c]).sum();
    }
    DMat3::from_cols_array(&rows).transpose()
}
