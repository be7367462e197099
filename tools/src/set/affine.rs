//! The one affine map of the tools, x ↦ q x + d: a posed bone's transform of the rest pose (q a
//! rotation, [`rotation_error`] checks it), a proxy's (q any 3x3). The runtime takes the 3x4
//! row-major `f32` form ([`Affine::to_runtime`]) at its boundary.

use glam::{DMat3, DVec3};

/// Tolerance on the rotation part of a pose transform: |QᵀQ − I|∞ and |det Q − 1|.
pub const ROTATION_TOLERANCE: f64 = 1e-3;

/// An affine map x ↦ q x + d (a bone's: relative to the rest pose).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Affine {
    pub q: DMat3,
    pub d: DVec3,
}

impl Affine {
    pub fn apply(&self, x: DVec3) -> DVec3 {
        self.q * x + self.d
    }

    /// Row c of the 3x4 transform `[Q | d]`: what C2 multiplies (docs/method.md §8, `q_c`).
    pub fn row(&self, c: usize) -> [f64; 4] {
        [
            self.q.x_axis[c],
            self.q.y_axis[c],
            self.q.z_axis[c],
            self.d[c],
        ]
    }

    /// The 3x4 row-major form the runtime takes.
    pub fn to_runtime(&self) -> rrskin::predict::Affine {
        self.to_rows().map(|x| x as f32)
    }

    /// `[Q | d]` as 3 rows of 4, row-major (the layout of `pose_transforms.npy`).
    pub fn to_rows(&self) -> [f64; 12] {
        std::array::from_fn(|i| self.row(i / 4)[i % 4])
    }
}

/// |QᵀQ − I|∞ and |det Q − 1|, whichever is larger.
pub fn rotation_error(q: DMat3) -> f64 {
    let g = q.transpose() * q - DMat3::IDENTITY;
    let worst = g.to_cols_array().iter().fold(0.0f64, |m, x| m.max(x.abs()));
    worst.max((q.determinant() - 1.0).abs())
}
