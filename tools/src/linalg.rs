//! Small dense linear algebra for training: 3x3 SVD / polar decomposition / Procrustes (called
//! hundreds of thousands of times, so closed-form Jacobi rather than a general solver), and
//! non-negative least squares on normal equations (Lawson–Hanson active set).

use glam::{DMat3, DVec3};

/// Eigen-decomposition of a symmetric 3x3 matrix by cyclic Jacobi rotations.
/// Returns (eigenvalues descending, eigenvectors as the columns of a rotation).
pub fn sym_eigen3(a: DMat3) -> (DVec3, DMat3) {
    let mut m = [[0.0f64; 3]; 3];
    for (c, col) in [a.x_axis, a.y_axis, a.z_axis].iter().enumerate() {
        m[0][c] = col.x;
        m[1][c] = col.y;
        m[2][c] = col.z;
    }
    let mut v = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    for _sweep in 0..32 {
        let off = m[0][1] * m[0][1] + m[0][2] * m[0][2] + m[1][2] * m[1][2];
        let diag = m[0][0] * m[0][0] + m[1][1] * m[1][1] + m[2][2] * m[2][2];
        if off <= 1e-30 * diag.max(1e-300) {
            break;
        }
        for (p, q) in [(0, 1), (0, 2), (1, 2)] {
            if m[p][q].abs() < 1e-300 {
                continue;
            }
            let theta = (m[q][q] - m[p][p]) / (2.0 * m[p][q]);
            let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
            let t = if theta == 0.0 { 1.0 } else { t };
            let c = 1.0 / (t * t + 1.0).sqrt();
            let s = t * c;
            // M ← Jᵀ M J for the Givens rotation J in the (p, q) plane.
            for row in m.iter_mut() {
                let (mkp, mkq) = (row[p], row[q]);
                row[p] = c * mkp - s * mkq;
                row[q] = s * mkp + c * mkq;
            }
            let (mp, mq) = (m[p], m[q]);
            for k in 0..3 {
                m[p][k] = c * mp[k] - s * mq[k];
                m[q][k] = s * mp[k] + c * mq[k];
            }
            for row in v.iter_mut() {
                let (vp, vq) = (row[p], row[q]);
                row[p] = c * vp - s * vq;
                row[q] = s * vp + c * vq;
            }
        }
    }
    let mut order = [0usize, 1, 2];
    order.sort_by(|&i, &j| m[j][j].total_cmp(&m[i][i]));
    let values = DVec3::new(
        m[order[0]][order[0]],
        m[order[1]][order[1]],
        m[order[2]][order[2]],
    );
    let col = |i: usize| DVec3::new(v[0][i], v[1][i], v[2][i]);
    let mut vectors = DMat3::from_cols(col(order[0]), col(order[1]), col(order[2]));
    if vectors.determinant() < 0.0 {
        vectors.z_axis = -vectors.z_axis;
    }
    (values, vectors)
}

/// SVD `a = U diag(σ) Vᵀ` with U, V rotations and σ sorted by magnitude, the last one carrying
/// the sign of det(a) (a "signed" SVD: U Vᵀ is always a proper rotation).
pub fn svd3(a: DMat3) -> (DMat3, DVec3, DMat3) {
    let (lambda, v) = sym_eigen3(a.transpose() * a);
    let sigma = lambda.max(DVec3::ZERO).to_array().map(f64::sqrt);
    let av = [a * v.x_axis, a * v.y_axis, a * v.z_axis];
    let scale = sigma[0].max(1e-300);
    // Columns of U from A v_i / σ_i where well-conditioned; complete to an orthonormal frame.
    let mut u0 = if sigma[0] > 1e-12 * scale {
        av[0] / sigma[0]
    } else {
        DVec3::X
    };
    u0 = u0.normalize_or(DVec3::X);
    let mut u1 = av[1] - u0 * u0.dot(av[1]);
    if u1.length() <= 1e-9 * scale {
        u1 = u0.any_orthonormal_vector();
    }
    u1 = u1.normalize();
    let u2 = u0.cross(u1);
    let u = DMat3::from_cols(u0, u1, u2);
    // σ₂ = u₂ · A v₂ is negative when det(A) < 0: U and V stay rotations.
    let s2 = u2.dot(av[2]);
    (u, DVec3::new(sigma[0], u1.dot(av[1]), s2), v)
}

/// Polar decomposition `d = R S`, R a proper rotation, S symmetric (docs/method.md §1).
pub fn polar(d: DMat3) -> (DMat3, DMat3) {
    let (u, sigma, v) = svd3(d);
    let r = u * v.transpose();
    let s = v * DMat3::from_diagonal(sigma) * v.transpose();
    (r, s)
}

/// The rotation nearest to `m` (orthogonal Procrustes): argmax tr(Wᵀ m) over SO(3). By
/// `newton_polar` where det m > 0 and m is not near singular (the common case: a
/// deformation's covariance), else by the signed SVD, which also settles reflections.
pub fn procrustes(m: DMat3) -> DMat3 {
    newton_polar(m).unwrap_or_else(|| {
        let (u, _, v) = svd3(m);
        u * v.transpose()
    })
}

/// Below this det m / |m|_F³, [`procrustes`] takes the SVD: Newton's iteration slows with the
/// condition number and cannot turn a reflection into a rotation.
const NEWTON_POLAR_DET: f64 = 1e-6;
/// Newton iterations before [`procrustes`] gives up on them for the SVD.
const NEWTON_POLAR_ITERATIONS: usize = 16;

/// The rotational polar factor of `m` by Higham's scaled Newton iteration X ← (γX + X⁻ᵀ/γ) / 2,
/// γ = (|X⁻¹|_F / |X|_F)^½ (Higham 1986, "Computing the polar decomposition — with
/// applications"), to the working precision: quadratic near the end, so the step after the
/// first below 1e-8 leaves an error of about 1e-16. None where det m is not clearly positive, or
/// it does not converge. It replaced the signed SVD's cyclic Jacobi sweeps (fifteen dependent
/// rotations, each with square roots and divisions), 28 % of the CPU while Direct Delta Mush's
/// smoothing choice ran beside the merging on human_heavy (the choice 3.2 → 2.2 s); the two
/// agree to 1e-12 (the tests).
fn newton_polar(m: DMat3) -> Option<DMat3> {
    let norm = |x: DMat3| x.to_cols_array().iter().map(|e| e * e).sum::<f64>().sqrt();
    let size = norm(m);
    let det = m.determinant();
    if det.is_nan() || det <= NEWTON_POLAR_DET * size * size * size {
        return None;
    }
    let mut x = m / size;
    let mut converging = false;
    for _ in 0..NEWTON_POLAR_ITERATIONS {
        let inverse_t = x.inverse().transpose();
        let gamma = match converging {
            true => 1.0,
            false => (norm(inverse_t) / norm(x)).sqrt(),
        };
        let next = (x * gamma + inverse_t / gamma) * 0.5;
        let step = norm(next - x);
        x = next;
        if converging {
            return x.is_finite().then_some(x);
        }
        converging = step < 1e-8;
    }
    None
}

/// Geodesic angle between two rotations.
pub fn rotation_angle(a: DMat3, b: DMat3) -> f64 {
    let r = a.transpose() * b;
    let c = ((r.x_axis.x + r.y_axis.y + r.z_axis.z - 1.0) * 0.5).clamp(-1.0, 1.0);
    let v = DVec3::new(
        r.y_axis.z - r.z_axis.y,
        r.z_axis.x - r.x_axis.z,
        r.x_axis.y - r.y_axis.x,
    );
    (0.5 * v.length()).atan2(c)
}

/// min |A w − b|² subject to w ≥ 0, given the normal equations G = AᵀA (n x n, row-major,
/// symmetric positive semi-definite) and h = Aᵀb. Lawson–Hanson active set; n is small (≤ 16).
pub fn nnls(g: &[f64], h: &[f64]) -> Vec<f64> {
    let n = h.len();
    assert_eq!(g.len(), n * n, "nnls: G must be n x n");
    let mut w = vec![0.0; n];
    let mut passive = vec![false; n];
    // One scratch for every iteration's gradient and passive-set solve: the solves are tiny,
    // and allocating per solve cost as much as solving.
    let mut grad = vec![0.0; n];
    let mut subset = Subset::new(n);
    for _outer in 0..3 * n + 10 {
        // Gradient of ½|Aw − b|²: −(h − G w); pick the most negative among the active set.
        for (i, grad) in grad.iter_mut().enumerate() {
            *grad = h[i] - (0..n).map(|j| g[i * n + j] * w[j]).sum::<f64>();
        }
        let Some(best) = (0..n)
            .filter(|&i| !passive[i] && grad[i] > 1e-12 * (1.0 + h[i].abs()))
            .max_by(|&a, &b| grad[a].total_cmp(&grad[b]))
        else {
            break;
        };
        passive[best] = true;
        loop {
            let z = subset.solve(g, h, &passive);
            if (0..n).all(|i| !passive[i] || z[i] > 0.0) {
                w.copy_from_slice(z);
                break;
            }
            // Step toward z until a passive variable hits zero; move it back to the active set.
            let mut alpha = 1.0f64;
            for i in 0..n {
                if passive[i] && z[i] <= 0.0 {
                    alpha = alpha.min(w[i] / (w[i] - z[i]));
                }
            }
            for i in 0..n {
                w[i] += alpha * (z[i] - w[i]);
                if passive[i] && w[i] <= 1e-14 {
                    passive[i] = false;
                    w[i] = 0.0;
                }
            }
            if !passive.iter().any(|&p| p) {
                break;
            }
        }
    }
    w
}

/// The scratch of [`nnls`]'s passive-set solves for n unknowns.
struct Subset {
    idx: Vec<usize>,
    a: Vec<f64>,
    b: Vec<f64>,
    z: Vec<f64>,
}

impl Subset {
    fn new(n: usize) -> Subset {
        Subset {
            idx: Vec::with_capacity(n),
            a: vec![0.0; n * n],
            b: vec![0.0; n],
            z: vec![0.0; n],
        }
    }

    /// Solves G_PP z_P = h_P on the passive set P (z = 0 elsewhere) by Cholesky with a tiny
    /// ridge.
    fn solve(&mut self, g: &[f64], h: &[f64], passive: &[bool]) -> &[f64] {
        let n = h.len();
        self.idx.clear();
        self.idx.extend((0..n).filter(|&i| passive[i]));
        let (idx, m) = (&self.idx, self.idx.len());
        let (a, b) = (&mut self.a[..m * m], &mut self.b[..m]);
        for (b, &i) in b.iter_mut().zip(idx) {
            *b = h[i];
        }
        let ridge = 1e-12
            * idx
                .iter()
                .map(|&i| g[i * n + i])
                .fold(0.0, f64::max)
                .max(1e-300);
        for (r, &i) in idx.iter().enumerate() {
            for (c, &j) in idx.iter().enumerate() {
                a[r * m + c] = g[i * n + j] + if r == c { ridge } else { 0.0 };
            }
        }
        factor_in_place(a, m);
        solve_factored(a, m, b, 1);
        self.z.fill(0.0);
        for (&x, &i) in b.iter().zip(idx) {
            self.z[i] = x;
        }
        &self.z
    }
}

/// A dense Cholesky factor (row-major lower triangle), factored once, solved many times.
pub struct DenseCholesky {
    l: Vec<f64>,
    n: usize,
}

impl DenseCholesky {
    /// Factors the SPD matrix `a` (n x n, row-major); pivots are clamped at 1e-300.
    pub fn new(a: &[f64], n: usize) -> DenseCholesky {
        assert_eq!(a.len(), n * n, "DenseCholesky: a must be n x n");
        let mut l = a.to_vec();
        factor_in_place(&mut l, n);
        DenseCholesky { l, n }
    }

    /// Solves A x = b in place.
    pub fn solve(&self, b: &mut [f64]) {
        assert_eq!(b.len(), self.n, "DenseCholesky: b must have n rows");
        solve_factored(&self.l, self.n, b, 1);
    }

    /// Solves A X = B in place for B of n rows and `width` columns (row-major): each column
    /// as [`DenseCholesky::solve`] would (the same operations in the same order), all columns
    /// a row at a time.
    pub fn solve_columns(&self, b: &mut [f64], width: usize) {
        assert_eq!(b.len(), self.n * width, "DenseCholesky: B must have n rows");
        solve_factored(&self.l, self.n, b, width);
    }
}

/// Overwrites the lower triangle of the SPD matrix `l` (n x n, row-major) with its Cholesky
/// factor; pivots are clamped at 1e-300. Rows as slices, so the inner products run without
/// bounds checks, in the same order as the textbook loops.
fn factor_in_place(l: &mut [f64], n: usize) {
    for j in 0..n {
        let (above, below) = l.split_at_mut((j + 1) * n);
        let row_j = &mut above[j * n..];
        let mut d = row_j[j];
        for &x in &row_j[..j] {
            d -= x * x;
        }
        let d = d.max(1e-300).sqrt();
        row_j[j] = d;
        let row_j = &row_j[..j];
        for row_i in below.chunks_exact_mut(n) {
            let mut s = row_i[j];
            for (x, y) in row_i[..j].iter().zip(row_j) {
                s -= x * y;
            }
            row_i[j] = s / d;
        }
    }
}

/// Solves L Lᵀ X = B in place, `l` (n x n) factored by [`factor_in_place`], for B of n rows
/// and `width` columns (row-major): forward then back substitution, a row of B at a time.
fn solve_factored(l: &[f64], n: usize, b: &mut [f64], width: usize) {
    // Row r -= x · row y, entry by entry.
    let subtract = |r: &mut [f64], x: f64, y: &[f64]| {
        r.iter_mut().zip(y).for_each(|(r, y)| *r -= x * y);
    };
    for i in 0..n {
        let (done, rest) = b.split_at_mut(i * width);
        let row = &mut rest[..width];
        for (k, &x) in l[i * n..i * n + i].iter().enumerate() {
            subtract(row, x, &done[k * width..][..width]);
        }
        let d = l[i * n + i];
        row.iter_mut().for_each(|b| *b /= d);
    }
    for i in (0..n).rev() {
        let (head, after) = b.split_at_mut((i + 1) * width);
        let row = &mut head[i * width..];
        for k in i + 1..n {
            subtract(row, l[k * n + i], &after[(k - i - 1) * width..][..width]);
        }
        let d = l[i * n + i];
        row.iter_mut().for_each(|b| *b /= d);
    }
}

/// Fills the strict lower triangle of the symmetric n x n matrix `g` (row-major) from its
/// upper triangle: for Gram matrices summed over the upper triangle only.
pub fn mirror_upper(g: &mut [f64], n: usize) {
    for r in 0..n {
        for c in 0..r {
            g[r * n + c] = g[c * n + r];
        }
    }
}

/// Cholesky solve of a small SPD system (a: m x m row-major; b overwritten with x).
pub fn cholesky_solve(a: &[f64], b: &mut [f64], m: usize) {
    DenseCholesky::new(a, m).solve(b);
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: DMat3, b: DMat3, tol: f64) -> bool {
        (a - b).to_cols_array().iter().all(|x| x.abs() < tol)
    }

    /// Uniform samples in [-1, 1) from an LCG of seed `s`.
    fn uniform(mut s: u64) -> impl FnMut() -> f64 {
        move || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (s >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
        }
    }

    fn sample_matrices() -> Vec<DMat3> {
        let mut out = vec![
            DMat3::IDENTITY,
            DMat3::from_diagonal(DVec3::new(2.0, -1.0, 0.5)),
            DMat3::from_cols(
                DVec3::new(1.0, 2.0, 3.0),
                DVec3::new(4.0, 5.0, 6.0),
                DVec3::new(7.0, 8.0, 10.0),
            ),
            DMat3::from_cols(
                DVec3::new(1.0, 0.0, 0.0),
                DVec3::new(0.0, 1.0, 0.0),
                DVec3::ZERO,
            ), // rank 2
        ];
        let mut next = uniform(1);
        for _ in 0..200 {
            out.push(DMat3::from_cols_array(&[(); 9].map(|_| next())));
        }
        out
    }

    #[test]
    fn polar_gives_a_proper_rotation_times_a_symmetric_matrix() {
        for d in sample_matrices() {
            let (r, s) = polar(d);
            assert!(close(r.transpose() * r, DMat3::IDENTITY, 1e-9), "{d:?}");
            assert!((r.determinant() - 1.0).abs() < 1e-9, "{d:?}");
            assert!(close(s, s.transpose(), 1e-9), "{d:?}");
            assert!(close(r * s, d, 1e-9), "R S != D for {d:?}");
        }
    }

    #[test]
    fn procrustes_by_newton_is_the_signed_svds_rotation() {
        let mut by_newton = 0;
        for m in sample_matrices() {
            let (u, _, v) = svd3(m);
            let exact = u * v.transpose();
            let r = procrustes(m);
            by_newton += newton_polar(m).is_some() as usize;
            assert!(close(r, exact, 1e-12), "{m:?}: {r:?} against {exact:?}");
            assert!(close(r.transpose() * r, DMat3::IDENTITY, 1e-14), "{m:?}");
        }
        // About half the random matrices have det > 0; the reflections go to the SVD.
        assert!(by_newton > 60, "{by_newton}");
        // Ill-conditioned, above the threshold: still Newton's, still the SVD's rotation.
        let r = rrskin::predict::exp_rotation(DVec3::new(0.7, 0.2, -1.1));
        let q = rrskin::predict::exp_rotation(DVec3::new(-0.4, 1.3, 0.5));
        let thin = r * DMat3::from_diagonal(DVec3::new(1.0, 3e-3, 1e-3)) * q;
        assert!(newton_polar(thin).is_some());
        assert!(close(procrustes(thin), r * q, 1e-12));
        let flat = DMat3::from_diagonal(DVec3::new(1.0, 1.0, 1e-9));
        assert!(newton_polar(flat).is_none());
        assert!(newton_polar(-DMat3::IDENTITY).is_none());
    }

    #[test]
    fn procrustes_returns_the_rotation_itself() {
        let r = rrskin::predict::exp_rotation(DVec3::new(0.3, -1.2, 2.0));
        assert!(close(procrustes(r * 3.0), r, 1e-12));
        assert!(rotation_angle(r, r) < 1e-7);
    }

    #[test]
    fn nnls_matches_brute_force_on_small_problems() {
        let mut next = uniform(7);
        for trial in 0..200 {
            let (rows, n) = (8, 1 + trial % 5);
            let a: Vec<f64> = (0..rows * n).map(|_| next()).collect();
            let b: Vec<f64> = (0..rows).map(|_| next()).collect();
            let mut g = vec![0.0; n * n];
            let mut h = vec![0.0; n];
            for r in 0..rows {
                for i in 0..n {
                    h[i] += a[r * n + i] * b[r];
                    for j in 0..n {
                        g[i * n + j] += a[r * n + i] * a[r * n + j];
                    }
                }
            }
            let cost = |w: &[f64]| -> f64 {
                (0..rows)
                    .map(|r| ((0..n).map(|i| a[r * n + i] * w[i]).sum::<f64>() - b[r]).powi(2))
                    .sum()
            };
            // Brute force: the unconstrained solution on every support set, kept if feasible.
            let mut best = cost(&vec![0.0; n]);
            for mask in 1u32..(1 << n) {
                let passive: Vec<bool> = (0..n).map(|i| mask & (1 << i) != 0).collect();
                let z = Subset::new(n).solve(&g, &h, &passive).to_vec();
                if z.iter().all(|&x| x >= 0.0) {
                    best = best.min(cost(&z));
                }
            }
            let w = nnls(&g, &h);
            assert!(w.iter().all(|&x| x >= 0.0));
            assert!(
                (cost(&w) - best).abs() <= 1e-9 * (1.0 + best),
                "trial {trial}: {} vs {best}",
                cost(&w)
            );
        }
    }

    /// Many right-hand sides a row at a time give each column what a solve of its own gives,
    /// to the bit, and solve the system.
    #[test]
    fn solving_columns_together_is_solving_each() {
        let mut next = uniform(11);
        let (n, width) = (9, 5);
        let m: Vec<f64> = (0..n * n).map(|_| next()).collect();
        // A = MᵀM + I: SPD.
        let a: Vec<f64> = (0..n * n)
            .map(|u| {
                let (r, c) = (u / n, u % n);
                (0..n).map(|k| m[k * n + r] * m[k * n + c]).sum::<f64>() + f64::from(r == c)
            })
            .collect();
        let b: Vec<f64> = (0..n * width).map(|_| next()).collect();
        let factor = DenseCholesky::new(&a, n);
        let mut together = b.clone();
        factor.solve_columns(&mut together, width);
        for c in 0..width {
            let mut column: Vec<f64> = (0..n).map(|r| b[r * width + c]).collect();
            factor.solve(&mut column);
            for r in 0..n {
                assert_eq!(column[r].to_bits(), together[r * width + c].to_bits());
                let ax: f64 = (0..n).map(|k| a[r * n + k] * column[k]).sum();
                assert!((ax - b[r * width + c]).abs() < 1e-9, "row {r}, column {c}");
            }
        }
    }
}
