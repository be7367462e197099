//! The rotation of a delta-mush key's rigid fit ([`crate::model::DeltaMushKey`]): for a 3x3 matrix
//! A, the proper rotation R maximising tr(Rᵀ A), the rotational part of A's polar decomposition
//! where det A > 0. [`nearest_rotation`] is the function every evaluator ships (the `f64`
//! reference; [`nearest_rotation_f32`] the palette's; `glsl/polar.glsl`) and training fits the model to.
//!
//! **Newton's method on the rotation group from a warm start**, a fixed amount of work with no
//! data-dependent loop:
//! 1. the guess G, the Gram-Schmidt frame of A's first two columns (the identity where they are
//!    zero or nearly parallel);
//! 2. [`NEWTON_STEPS`] Newton steps on f(ω) = tr((G exp(\[ω\]×))ᵀ A): with M = Gᵀ A, the gradient
//!    is g = (M₂₁ − M₁₂, M₀₂ − M₂₀, M₁₀ − M₀₁) and the Hessian −H, H = tr(M) I − sym(M), so
//!    ω = H⁻¹ g, and G ← G R(ω) with R(ω) the rotation of the unit quaternion ∝ (1, ω/2).
//!
//! H is positive definite near the optimum (its eigenvalues are sums of two of sym(M)'s, the
//! stretch's), and is damped by `DAMPING` tr(M) so that a rank-1 A, whose rotation about its
//! line is free, takes no step about it. Where H is not positive definite (a guess more than a
//! right angle off) the step is skipped: the result is then the guess, still a rotation.
//!
//! **Why the guess is good: the key's principal frame.** Training stores each key's terms Ω in
//! the frame of its rest covariance ([`principal_frame`]), so that A at rest is diagonal,
//! largest first. For any rigid motion of the key's vertices A is then R times a diagonal, the
//! guess is R exactly, and the steps only correct what the motion bends and shears. Measured
//! over the keys of CesiumMan (60) and a Corrective Smooth rig (240) on their poses, the angle
//! to the exact polar rotation after 2 steps is 5e-9 and 5e-6 rad on average (1 step: 8e-5 and
//! 2e-4); from the guess of unrotated terms it was 0.05 and 0.3 rad (the steps cannot make up a
//! guess tens of degrees off, where H is far from its value at the optimum). It replaced 4
//! cyclic Jacobi sweeps of Horn's quaternion matrix: 24 dependent Jacobi rotations, 72 % of a
//! 60-key model's CPU palette.

/// Newton steps from the guess: 2 take the guess's error e to about e⁴ (see the module docs).
pub const NEWTON_STEPS: usize = 2;

/// Below this sine of the angle between A's first two columns (or with either zero), the guess
/// is the identity: the cross product's direction is then too uncertain to make a rotation of.
const GUESS_SINE: f64 = 1e-4;

/// H is damped by this times tr(M): negligible beside a rank-2 or rank-3 stretch's Hessian,
/// and what keeps a rank-1 A's free axis at rest.
const DAMPING: f64 = 1e-3;

/// The nearest rotations of L matrices at once, in one body for `f64` (the CPU reference,
/// training) and `f32` (the CPU palette), with the order of operations of `glsl/polar.glsl`.
///
/// L of them side by side (every value an array over the lanes) make each step one loop over
/// the lanes, with no branch on values (selects), which the compiler makes vector
/// instructions: a lane's result is what it would be alone. The scalar forms are one lane.
macro_rules! nearest_rotations {
    ($lanes:ident, $one:ident, $f:ty) => {
        /// The rotation of a key's fit for each of `a`'s L matrices (row-major 3x3),
        /// row-major: the guess and [`NEWTON_STEPS`] Newton steps toward the proper rotation R
        /// maximising tr(Rᵀ a) (module docs); the identity for a = 0.
        pub fn $lanes<const L: usize>(a: &[[[$f; 3]; 3]; L]) -> [[[$f; 3]; 3]; L] {
            let mut r: [[[$f; 3]; 3]; L] = std::array::from_fn(|i| guess!(a[i], $f));
            for _ in 0..NEWTON_STEPS {
                for i in 0..L {
                    r[i] = newton_step!(r[i], a[i], $f);
                }
            }
            r
        }

        /// The rotation of a key's fit for `a` (row-major 3x3), row-major; the identity for
        /// a = 0.
        pub fn $one(a: [[$f; 3]; 3]) -> [[$f; 3]; 3] {
            let [r] = $lanes(&[a]);
            r
        }
    };
}

/// The guess G (row-major 3x3) for `a` of float type `$f`: columns g0 = a0 / |a0|, g2 = (a0 x
/// a1) / |a0 x a1|, g1 = g2 x g0; the identity below [`GUESS_SINE`].
macro_rules! guess {
    ($a:expr, $f:ty) => {{
        let a = $a;
        let (c0, c1) = ([a[0][0], a[1][0], a[2][0]], [a[0][1], a[1][1], a[2][1]]);
        let x = cross!(c0, c1);
        let length = |u: [$f; 3]| (u[0] * u[0] + u[1] * u[1] + u[2] * u[2]).sqrt();
        let (l0, l1, lx) = (length(c0), length(c1), length(x));
        match lx > GUESS_SINE as $f * l0 * l1 {
            true => {
                let g0 = c0.map(|e| e / l0);
                let g2 = x.map(|e| e / lx);
                let g1 = cross!(g2, g0);
                [
                    [g0[0], g1[0], g2[0]],
                    [g0[1], g1[1], g2[1]],
                    [g0[2], g1[2], g2[2]],
                ]
            }
            false => [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
        }
    }};
}

macro_rules! cross {
    ($u:expr, $v:expr) => {{
        let (u, v) = ($u, $v);
        [
            u[1] * v[2] - u[2] * v[1],
            u[2] * v[0] - u[0] * v[2],
            u[0] * v[1] - u[1] * v[0],
        ]
    }};
}

/// One Newton step (module docs) from the rotation `$r` toward the fit of `$a`, both row-major,
/// of float type `$f`: `$r R(ω)`, or `$r` where the damped H is not positive definite.
macro_rules! newton_step {
    ($r:expr, $a:expr, $f:ty) => {{
        let (r, a) = (&$r, &$a);
        // M = Rᵀ A.
        let m: [[$f; 3]; 3] = std::array::from_fn(|i| {
            std::array::from_fn(|c| r[0][i] * a[0][c] + r[1][i] * a[1][c] + r[2][i] * a[2][c])
        });
        let g = [m[2][1] - m[1][2], m[0][2] - m[2][0], m[1][0] - m[0][1]];
        let t = m[0][0] + m[1][1] + m[2][2];
        // H = tr(M) I − sym(M) + DAMPING tr(M) I, symmetric; its adjugate and determinant.
        let d = t * (1.0 + DAMPING as $f);
        let (h00, h11, h22) = (d - m[0][0], d - m[1][1], d - m[2][2]);
        let h01 = -0.5 * (m[0][1] + m[1][0]);
        let h02 = -0.5 * (m[0][2] + m[2][0]);
        let h12 = -0.5 * (m[1][2] + m[2][1]);
        let (j00, j11, j22) = (
            h11 * h22 - h12 * h12,
            h00 * h22 - h02 * h02,
            h00 * h11 - h01 * h01,
        );
        let (j01, j02, j12) = (
            h02 * h12 - h01 * h22,
            h01 * h12 - h02 * h11,
            h01 * h02 - h00 * h12,
        );
        let det = h00 * j00 + h01 * j01 + h02 * j02;
        // Positive definite: a positive leading entry, 2x2 minor and determinant.
        let definite = h00 > 0.0 && j22 > 0.0 && det > 0.0;
        let half = if definite { 0.5 / det } else { 0.0 };
        // The quaternion (1, ω/2), ω = adj(H) g / det.
        let x = half * (j00 * g[0] + j01 * g[1] + j02 * g[2]);
        let y = half * (j01 * g[0] + j11 * g[1] + j12 * g[2]);
        let z = half * (j02 * g[0] + j12 * g[1] + j22 * g[2]);
        let s = 2.0 / (1.0 + x * x + y * y + z * z);
        let q = [
            [1.0 - s * (y * y + z * z), s * (x * y - z), s * (x * z + y)],
            [s * (x * y + z), 1.0 - s * (x * x + z * z), s * (y * z - x)],
            [s * (x * z - y), s * (y * z + x), 1.0 - s * (x * x + y * y)],
        ];
        // R Q.
        let out: [[$f; 3]; 3] = std::array::from_fn(|i| {
            std::array::from_fn(|c| r[i][0] * q[0][c] + r[i][1] * q[1][c] + r[i][2] * q[2][c])
        });
        out
    }};
}

nearest_rotations!(nearest_rotations, nearest_rotation, f64);
nearest_rotations!(nearest_rotations_f32, nearest_rotation_f32, f32);

/// A key's principal frame: for its rest covariance C (symmetric 3x3, row-major; A at rest),
/// the proper rotation P (row-major) whose columns are C's eigenvectors by decreasing
/// eigenvalue, and that largest eigenvalue λ₁ (1 where C has none above 0). Training stores a
/// key's terms as Ω P / λ₁: A at rest is then diag(1, λ₂/λ₁, λ₃/λ₁), where the fit's guess is
/// exact for a rigid motion (module docs), and the key's rotation is the fit's times Pᵀ.
///
/// By cyclic Jacobi rotations (Numerical Recipes §11.1) until the off-diagonal is below 1e-15
/// of the diagonal. Any C gives a rotation P (of its symmetric part).
pub fn principal_frame(c: [[f64; 3]; 3]) -> ([[f64; 3]; 3], f64) {
    // Symmetric by construction in training; symmetrised for any other terms, whose frame
    // only needs to be a rotation.
    let mut a: [[f64; 3]; 3] =
        std::array::from_fn(|r| std::array::from_fn(|k| 0.5 * (c[r][k] + c[k][r])));
    let mut v = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    let scale = (0..3).map(|k| a[k][k].abs()).fold(0.0, f64::max);
    for _ in 0..16 {
        let off = a[0][1].abs() + a[0][2].abs() + a[1][2].abs();
        if off.is_nan() || off <= 1e-15 * scale {
            break;
        }
        for (p, q) in [(0, 1), (0, 2), (1, 2)] {
            if a[p][q] == 0.0 {
                continue;
            }
            let theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
            let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
            let (c, s) = (1.0 / (t * t + 1.0).sqrt(), t / (t * t + 1.0).sqrt());
            // A ← Jᵀ A J, V ← V J, J the rotation by (c, s) in the (p, q) plane.
            for row in a.iter_mut().chain(v.iter_mut()) {
                let (x, y) = (row[p], row[q]);
                (row[p], row[q]) = (c * x - s * y, s * x + c * y);
            }
            let (x, y) = (a[p], a[q]);
            a[p] = std::array::from_fn(|k| c * x[k] - s * y[k]);
            a[q] = std::array::from_fn(|k| s * x[k] + c * y[k]);
        }
    }
    let mut order = [0, 1, 2];
    order.sort_by(|&x, &y| a[y][y].total_cmp(&a[x][x]));
    let mut p: [[f64; 3]; 3] = std::array::from_fn(|r| order.map(|k| v[r][k]));
    let det = p[0][0] * (p[1][1] * p[2][2] - p[1][2] * p[2][1])
        - p[0][1] * (p[1][0] * p[2][2] - p[1][2] * p[2][0])
        + p[0][2] * (p[1][0] * p[2][1] - p[1][1] * p[2][0]);
    if det < 0.0 {
        p.iter_mut().for_each(|row| row[2] = -row[2]);
    }
    let top = a[order[0]][order[0]];
    (p, if top > 0.0 { top } else { 1.0 })
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::{DMat3, DQuat, DVec3};

    fn rows(m: DMat3) -> [[f64; 3]; 3] {
        let t = m.transpose();
        [
            t.x_axis.to_array(),
            t.y_axis.to_array(),
            t.z_axis.to_array(),
        ]
    }

    fn distance(a: [[f64; 3]; 3], b: [[f64; 3]; 3]) -> f64 {
        (0..9)
            .map(|k| (a[k / 3][k % 3] - b[k / 3][k % 3]).abs())
            .fold(0.0, f64::max)
    }

    /// Rotations of every size, axis and sign of the quaternion's scalar.
    fn rotations() -> impl Iterator<Item = DMat3> {
        (0..40).map(|i| {
            let f = i as f64;
            let axis = DVec3::new((f * 1.3).sin(), (f * 0.7).cos(), (f * 2.1).sin() + 0.3);
            DMat3::from_quat(DQuat::from_axis_angle(axis.normalize(), 0.08 * f))
        })
    }

    /// A stretch with no axis along a coordinate axis.
    fn stretch() -> DMat3 {
        DMat3::from_cols(
            DVec3::new(2.0, 0.3, 0.1),
            DVec3::new(0.3, 1.0, -0.2),
            DVec3::new(0.1, -0.2, 0.5),
        )
    }

    #[test]
    fn a_rigid_motion_in_the_principal_frame_is_exact() {
        // The terms as training stores them: A = R C P / λ₁, C P = P Λ.
        let (p, top) = principal_frame(rows(stretch()));
        let p = DMat3::from_cols_array_2d(&p).transpose();
        for r in rotations() {
            let got = nearest_rotation(rows(r * stretch() * p / top));
            assert!(distance(got, rows(r * p)) < 1e-12, "{r:?}: {got:?}");
        }
    }

    #[test]
    fn a_stretch_off_its_frame_still_converges() {
        // The guess is off by the Gram-Schmidt frame of the stretch's columns (0.15 rad here):
        // two steps take it to about its fourth power.
        for r in rotations() {
            let got = nearest_rotation(rows(r * stretch()));
            assert!(distance(got, rows(r)) < 1e-4, "{r:?}: {got:?}");
        }
    }

    /// The exact polar rotation of `a` (det > 0) by Newton's iteration on matrices, R ← (R +
    /// R⁻ᵀ) / 2 (Higham 1986), run to convergence.
    fn polar_by_higham(a: DMat3) -> DMat3 {
        (0..60).fold(a, |r, _| (r + r.inverse().transpose()) * 0.5)
    }

    #[test]
    fn a_bent_key_is_near_its_polar_rotation() {
        // A key over a joint, in its principal frame: part of its mass turned by up to a right
        // angle about an axis off the frame's. The guess is off by up to tens of degrees; two
        // steps land within 1e-6 of the exact polar rotation.
        let rest = DMat3::from_diagonal(DVec3::new(1.0, 0.5, 0.2));
        let mut worst: f64 = 0.0;
        for (i, r) in rotations().enumerate() {
            let share = 0.2 + 0.6 * (i as f64 * 0.37).fract();
            let bend =
                DMat3::from_axis_angle(DVec3::new(0.3, 1.0, 0.5).normalize(), 0.04 * i as f64);
            let a = r * (rest * (1.0 - share) + bend * rest * share);
            let exact = rows(polar_by_higham(a));
            worst = worst.max(distance(nearest_rotation(rows(a)), exact));
        }
        assert!(worst < 1e-6, "{worst}");
    }

    #[test]
    fn a_flat_group_still_has_its_one_best_rotation() {
        // Rank 2: a group of vertices in one plane.
        for r in rotations() {
            let flat = DMat3::from_diagonal(DVec3::new(1.0, 0.4, 0.0));
            assert!(distance(nearest_rotation(rows(r * flat)), rows(r)) < 1e-10);
        }
    }

    #[test]
    fn a_reflection_gives_the_best_proper_rotation() {
        // diag(1, 1, -1): the best rotation keeps the two positive axes, tr = 1 + 1 - 1.
        let got = nearest_rotation(rows(DMat3::from_diagonal(DVec3::new(3.0, 2.0, -1.0))));
        assert!(distance(got, rows(DMat3::IDENTITY)) < 1e-12, "{got:?}");
        let flip = DMat3::from_diagonal(DVec3::new(-3.0, -2.0, 1.0));
        let got = nearest_rotation(rows(flip));
        let half_turn = DMat3::from_diagonal(DVec3::new(-1.0, -1.0, 1.0));
        assert!(distance(got, rows(half_turn)) < 1e-12, "{got:?}");
    }

    #[test]
    fn zero_and_a_line_stay_rotations() {
        assert_eq!(nearest_rotation([[0.0; 3]; 3]), rows(DMat3::IDENTITY));
        assert_eq!(
            nearest_rotation_f32([[0.0; 3]; 3]),
            rows(DMat3::IDENTITY).map(|r| r.map(|x| x as f32))
        );
        // Rank 1 (no group of triangles is): a proper rotation still, if not a fitted one.
        for r in rotations() {
            let line = DMat3::from_diagonal(DVec3::new(1.0, 0.0, 0.0));
            let got = DMat3::from_cols_array_2d(&nearest_rotation(rows(r * line))).transpose();
            assert!(distance(rows(got.transpose() * got), rows(DMat3::IDENTITY)) < 1e-12);
            assert!((got.determinant() - 1.0).abs() < 1e-12);
        }
    }

    #[test]
    fn each_lane_is_its_matrix_alone() {
        // Near-rotations, stretches, a reflection, rank 2, rank 1 and zero side by side.
        let mut mats: Vec<[[f32; 3]; 3]> = vec![
            [[3.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, -1.0]],
            [[1.0, 0.2, 0.0], [0.3, 0.4, 0.0], [0.0, 0.0, 0.0]],
            [[1.0, 2.0, 3.0], [2.0, 4.0, 6.0], [0.5, 1.0, 1.5]],
            [[0.0; 3]; 3],
        ];
        mats.extend(
            rotations()
                .take(36)
                .map(|r| rows(r * stretch()))
                .map(|m| m.map(|r| r.map(|x| x as f32))),
        );
        for chunk in mats.chunks(8) {
            let lanes: [[[f32; 3]; 3]; 8] = chunk.try_into().expect("8 matrices");
            for (got, a) in nearest_rotations_f32(&lanes).iter().zip(chunk) {
                assert_eq!(*got, nearest_rotation_f32(*a), "{a:?}");
            }
        }
    }

    #[test]
    fn single_precision_agrees() {
        for r in rotations() {
            let a = rows(r * DMat3::from_diagonal(DVec3::new(1.5, 1.0, 0.7)));
            let got = nearest_rotation_f32(a.map(|r| r.map(|x| x as f32)));
            let got = got.map(|r| r.map(f64::from));
            assert!(distance(got, rows(r)) < 2e-6, "{got:?}");
        }
    }

    #[test]
    fn the_principal_frame_diagonalises() {
        for c in [
            rows(stretch()),
            rows(DMat3::from_diagonal(DVec3::new(1.0, 3.0, 2.0))),
            rows(DMat3::from_diagonal(DVec3::new(2.0, 2.0, 0.0))),
            [[0.0; 3]; 3],
        ] {
            let (p, top) = principal_frame(c);
            let (p, c) = (
                DMat3::from_cols_array_2d(&p).transpose(),
                DMat3::from_cols_array_2d(&c).transpose(),
            );
            assert!((p.determinant() - 1.0).abs() < 1e-12);
            let d = p.transpose() * c * p;
            let diag = [d.x_axis.x, d.y_axis.y, d.z_axis.z];
            let off = d - DMat3::from_diagonal(DVec3::from(diag));
            assert!(distance(rows(off), [[0.0; 3]; 3]) < 1e-12, "{d:?}");
            assert!(diag[0] >= diag[1] && diag[1] >= diag[2], "{diag:?}");
            assert!((top - if diag[0] > 0.0 { diag[0] } else { 1.0 }).abs() < 1e-12 * top);
        }
    }
}
