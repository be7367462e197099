//! The rotation nearest to a 3x3 matrix A: the proper rotation R maximising tr(Rᵀ A), the
//! rotational part of its polar decomposition where det A > 0 (what a delta-mush key's rigid fit
//! needs, [`crate::model::MushKeys`]).
//!
//! Horn's quaternion method (Horn 1987, "Closed-form solution of absolute orientation using unit
//! quaternions", §4): `tr(R(q)ᵀ A) = qᵀ N q` for a unit quaternion q = (w, x, y, z) and the
//! symmetric 4x4 N below, so R is the rotation of N's eigenvector of largest eigenvalue. The
//! eigenvectors come from [`SWEEPS`] cyclic Jacobi sweeps, a fixed amount of work with no
//! data-dependent loop, which `glsl/polar.glsl` mirrors line for line in `f32`: CPU and GPU then
//! agree wherever the largest eigenvalue is simple (A of rank 2 or more). Unlike an SVD this
//! never needs a reflection fixed, and it degrades gracefully: rank 2 still gives the one best
//! rotation, and A = 0 gives the identity.
//!
//! The sweeps start from a guess: G, the Gram-Schmidt frame of A's first two columns (the
//! identity where they are zero or nearly parallel). The best R is G times the best rotation
//! for A' = Gᵀ A, whatever G is, and A' is nearly symmetric wherever A is nearly a rotation
//! times a stretch (a rigid fit's covariance), so N' is nearly diagonal and the sweeps start
//! near their end.

/// Cyclic Jacobi sweeps over N's 6 off-diagonal pairs. Jacobi converges quadratically; from the
/// guess, the largest error to the exact polar rotation over 2000 random 3x3s (det > 0) is
/// 2e-3 after three sweeps and 2e-9 after four (without the guess: 5e-3 and 2e-7, and five
/// were needed), and near a rotation 9e-8 after three (a NumPy replay of this code). A sweep is
/// about a sixth of a delta-mush key's cost on lavapipe.
pub const SWEEPS: usize = 4;

/// Below this sine of the angle between A's first two columns (or with either zero), the guess
/// is the identity: the cross product's direction is then too uncertain to make a rotation of.
const GUESS_SINE: f64 = 1e-4;

/// The nearest rotations of L matrices at once, in one body for `f64` (the CPU reference,
/// training) and `f32` (the CPU palette), lane by lane with the order of operations of
/// `glsl/polar.glsl`.
///
/// A matrix alone costs the latency of 24 dependent Jacobi rotations. L of them side by side
/// (every value an array over the lanes, `[[[f; L]; 4]; 4]`) pay it once: each step is one
/// operation over the lanes, which the compiler makes vector instructions. Branches on values
/// are selects, so a lane's result is what it would be alone. The scalar forms are one lane.
macro_rules! nearest_rotations {
    ($lanes:ident, $one:ident, $f:ty) => {
        /// The rotation nearest to each of `a`'s L matrices (row-major 3x3), row-major: the
        /// proper rotation R maximising tr(Rᵀ a); the identity for a = 0.
        pub fn $lanes<const L: usize>(a: &[[[$f; 3]; 3]; L]) -> [[[$f; 3]; 3]; L] {
            /// Per lane, of the Jacobi rotation that zeroes apq: t = tan of its angle (the
            /// smaller root; 0 where apq = 0), s = sin and τ = s / (1 + c). Selects of t alone,
            /// in a function of its own: inlined into the sweep, or with selects of c or s, the
            /// compiler split the lanes into scalars.
            #[inline(never)]
            fn angle<const L: usize>(app: &[$f; L], aqq: &[$f; L], apq: &[$f; L]) -> [[$f; L]; 3] {
                let mut out = [[0.0 as $f; L]; 3];
                for i in 0..L {
                    let theta = (aqq[i] - app[i]) / (2.0 * apq[i]);
                    let root = 1.0 / (theta.abs() + (theta * theta + 1.0).sqrt());
                    let root = if theta < 0.0 { -root } else { root };
                    let t = if theta.abs() > 1e15 {
                        0.5 / theta
                    } else {
                        root
                    };
                    let t = if apq[i] == 0.0 { 0.0 } else { t };
                    let c = 1.0 / (t * t + 1.0).sqrt();
                    let s = t * c;
                    [out[0][i], out[1][i], out[2][i]] = [t, s, s / (1.0 + c)];
                }
                out
            }

            /// The Jacobi rotation in the (P, Q) plane that zeroes n[P][Q] (Numerical Recipes
            /// §11.1, eq. 11.1.14–11.1.18), on every lane: N's diagonal moves by t apq, the
            /// pair's entry becomes 0, and the other rows' entries turn by (s, τ), mirrored
            /// to keep N symmetric; the rotation is accumulated into V.
            #[inline(always)]
            fn rotate<const P: usize, const Q: usize, const L: usize>(
                n: &mut [[[$f; L]; 4]; 4],
                v: &mut [[[$f; L]; 4]; 4],
            ) {
                let [t, s, tau] = angle(&n[P][P], &n[Q][Q], &n[P][Q]);
                for i in 0..L {
                    let h = t[i] * n[P][Q][i];
                    n[P][P][i] -= h;
                    n[Q][Q][i] += h;
                    (n[P][Q][i], n[Q][P][i]) = (0.0, 0.0);
                }
                for k in (0..4).filter(|&k| k != P && k != Q) {
                    for i in 0..L {
                        let (g, h) = (n[k][P][i], n[k][Q][i]);
                        let kp = g - s[i] * (h + g * tau[i]);
                        let kq = h + s[i] * (g - h * tau[i]);
                        (n[k][P][i], n[P][k][i]) = (kp, kp);
                        (n[k][Q][i], n[Q][k][i]) = (kq, kq);
                    }
                }
                for k in 0..4 {
                    for i in 0..L {
                        let (g, h) = (v[k][P][i], v[k][Q][i]);
                        v[k][P][i] = g - s[i] * (h + g * tau[i]);
                        v[k][Q][i] = h + s[i] * (g - h * tau[i]);
                    }
                }
            }

            let g: [[[$f; 3]; 3]; L] = std::array::from_fn(|i| guess!(a[i], $f));
            let mut n = [[[0.0 as $f; L]; 4]; 4];
            for i in 0..L {
                // A' = Gᵀ A.
                let (g, a) = (&g[i], &a[i]);
                let a: [[$f; 3]; 3] = std::array::from_fn(|r| {
                    std::array::from_fn(|c| {
                        g[0][r] * a[0][c] + g[1][r] * a[1][c] + g[2][r] * a[2][c]
                    })
                });
                let upper = [
                    [
                        a[0][0] + a[1][1] + a[2][2],
                        a[2][1] - a[1][2],
                        a[0][2] - a[2][0],
                        a[1][0] - a[0][1],
                    ],
                    [
                        0.0,
                        a[0][0] - a[1][1] - a[2][2],
                        a[1][0] + a[0][1],
                        a[0][2] + a[2][0],
                    ],
                    [0.0, 0.0, a[1][1] - a[0][0] - a[2][2], a[2][1] + a[1][2]],
                    [0.0, 0.0, 0.0, a[2][2] - a[0][0] - a[1][1]],
                ];
                for r in 0..4 {
                    for c in r..4 {
                        (n[r][c][i], n[c][r][i]) = (upper[r][c], upper[r][c]);
                    }
                }
            }
            let mut v = [[[0.0 as $f; L]; 4]; 4];
            (0..4).for_each(|k| v[k][k] = [1.0; L]);
            for _ in 0..SWEEPS {
                // The pairs by literal indices, as glsl/polar.glsl names them: every index a
                // constant, so one lane's n and v stay in registers (a loop over the pairs kept
                // them in memory, and cost the one-lane palette about twice as much).
                rotate::<0, 1, L>(&mut n, &mut v);
                rotate::<0, 2, L>(&mut n, &mut v);
                rotate::<0, 3, L>(&mut n, &mut v);
                rotate::<1, 2, L>(&mut n, &mut v);
                rotate::<1, 3, L>(&mut n, &mut v);
                rotate::<2, 3, L>(&mut n, &mut v);
            }
            std::array::from_fn(|i| {
                // The largest eigenvalue's column; ties go to the first (the identity for a = 0).
                let mut best = 0;
                for k in 1..4 {
                    if n[k][k][i] > n[best][best][i] {
                        best = k;
                    }
                }
                let [w, x, y, z] = [0, 1, 2, 3].map(|k| v[k][best][i]);
                let s = 2.0 / (w * w + x * x + y * y + z * z);
                let r = [
                    [
                        1.0 - s * (y * y + z * z),
                        s * (x * y - w * z),
                        s * (x * z + w * y),
                    ],
                    [
                        s * (x * y + w * z),
                        1.0 - s * (x * x + z * z),
                        s * (y * z - w * x),
                    ],
                    [
                        s * (x * z - w * y),
                        s * (y * z + w * x),
                        1.0 - s * (x * x + y * y),
                    ],
                ];
                // R = G R'.
                let g = &g[i];
                std::array::from_fn(|i| {
                    std::array::from_fn(|c| {
                        g[i][0] * r[0][c] + g[i][1] * r[1][c] + g[i][2] * r[2][c]
                    })
                })
            })
        }

        /// The rotation nearest to `a` (row-major 3x3), row-major: the proper rotation R
        /// maximising tr(Rᵀ a); the identity for a = 0.
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
        let cross = |u: [$f; 3], v: [$f; 3]| {
            [
                u[1] * v[2] - u[2] * v[1],
                u[2] * v[0] - u[0] * v[2],
                u[0] * v[1] - u[1] * v[0],
            ]
        };
        let length = |u: [$f; 3]| (u[0] * u[0] + u[1] * u[1] + u[2] * u[2]).sqrt();
        let x = cross(c0, c1);
        let (l0, l1, lx) = (length(c0), length(c1), length(x));
        match lx > GUESS_SINE as $f * l0 * l1 {
            true => {
                let g0 = c0.map(|e| e / l0);
                let g2 = x.map(|e| e / lx);
                let g1 = cross(g2, g0);
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

nearest_rotations!(nearest_rotations, nearest_rotation, f64);
nearest_rotations!(nearest_rotations_f32, nearest_rotation_f32, f32);

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

    #[test]
    fn the_rotation_of_a_rotated_stretch_is_the_rotation() {
        for r in rotations() {
            let stretch = DMat3::from_cols(
                DVec3::new(2.0, 0.3, 0.1),
                DVec3::new(0.3, 1.0, -0.2),
                DVec3::new(0.1, -0.2, 0.5),
            );
            let got = nearest_rotation(rows(r * stretch));
            assert!(distance(got, rows(r)) < 1e-12, "{r:?}: {got:?}");
        }
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
    fn zero_gives_the_identity() {
        assert_eq!(nearest_rotation([[0.0; 3]; 3]), rows(DMat3::IDENTITY));
        assert_eq!(
            nearest_rotation_f32([[0.0; 3]; 3]),
            rows(DMat3::IDENTITY).map(|r| r.map(|x| x as f32))
        );
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
                .map(|r| rows(r * DMat3::from_diagonal(DVec3::new(1.5, 1.0, 0.7))))
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
}
