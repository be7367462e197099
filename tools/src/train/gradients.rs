//! Deformation gradients (paper §3, docs/method.md §1): per triangle k and pose i,
//! `D = [v2 v3 n][v̂2 v̂3 n̂]⁻¹` with edges v2 = y_k2 − y_k1, v3 = y_k3 − y_k1 and the
//! Sumner–Popović fourth direction n = (v2 × v3) / sqrt|v2 × v3|.

use glam::{DMat3, DVec3};

/// The two edges and the scaled normal of a triangle, as the columns of a matrix.
pub fn frame(a: DVec3, b: DVec3, c: DVec3) -> DMat3 {
    let (v2, v3) = (b - a, c - a);
    let cross = v2.cross(v3);
    let len = cross.length();
    let n = if len > 0.0 {
        cross / len.sqrt()
    } else {
        DVec3::ZERO
    };
    DMat3::from_cols(v2, v3, n)
}

/// Per triangle: the inverse rest frame, or None for a degenerate rest triangle (whose gradient
/// is defined as the identity: it has no shape to deform).
pub fn rest_inverses(rest: &[DVec3], faces: &[[usize; 3]]) -> Vec<Option<DMat3>> {
    faces
        .iter()
        .map(|&[a, b, c]| {
            let f = frame(rest[a], rest[b], rest[c]);
            // |det| = |v2 × v3|^(3/2); relative to the edge lengths it measures flatness.
            let det = f.determinant().abs();
            let edge = f.x_axis.length().max(f.y_axis.length());
            (det > 1e-12 * edge.powi(3)).then(|| f.inverse())
        })
        .collect()
}

/// D for every triangle of one posed mesh `y`.
pub fn gradients(y: &[DVec3], faces: &[[usize; 3]], inverses: &[Option<DMat3>]) -> Vec<DMat3> {
    faces
        .iter()
        .zip(inverses)
        .map(|(&[a, b, c], inv)| match inv {
            Some(inv) => frame(y[a], y[b], y[c]) * *inv,
            None => DMat3::IDENTITY,
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_rest_pose_has_identity_gradients_and_rigid_motion_its_rotation() {
        let rest = [
            DVec3::ZERO,
            DVec3::new(1.0, 0.1, 0.0),
            DVec3::new(0.2, 0.9, 0.3),
            DVec3::new(1.0, 1.0, 1.0),
        ];
        let faces = [[0, 1, 2], [1, 3, 2]];
        let inv = rest_inverses(&rest, &faces);
        for d in gradients(&rest, &faces, &inv) {
            assert!((d - DMat3::IDENTITY)
                .to_cols_array()
                .iter()
                .all(|x| x.abs() < 1e-12));
        }
        let r = rrskin::predict::exp_rotation(DVec3::new(0.4, -0.7, 1.9));
        let moved: Vec<DVec3> = rest
            .iter()
            .map(|&p| r * p + DVec3::new(3.0, -1.0, 2.0))
            .collect();
        for d in gradients(&moved, &faces, &inv) {
            assert!((d - r).to_cols_array().iter().all(|x| x.abs() < 1e-12));
        }
    }
}
