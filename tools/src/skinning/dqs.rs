//! Dual quaternion skinning (Kavan et al. 2008): the baseline an engine uses where linear blend
//! skinning collapses joints. Per vertex, the bones' unit dual quaternions are blended with the
//! skinning weights (each flipped into the hemisphere of the heaviest bone's), normalised, and
//! applied as one rigid motion.

use crate::set::Affine;
use glam::{DQuat, DVec3};

/// A rigid transform as a unit dual quaternion: real part r (rotation), dual part ½ (0, t) r.
#[derive(Debug, Clone, Copy)]
pub(super) struct DualQuat {
    pub(super) real: DQuat,
    dual: DQuat,
}

impl DualQuat {
    pub(super) fn of(bone: &Affine) -> DualQuat {
        let real = DQuat::from_mat3(&bone.q).normalize();
        let t = DQuat::from_xyzw(bone.d.x, bone.d.y, bone.d.z, 0.0);
        DualQuat {
            real,
            dual: t * real * 0.5,
        }
    }
}

/// Each vertex of `rest` moved by its (bone, weight) list under `bones`.
pub fn deform(rest: &[DVec3], influences: &[Vec<(usize, f64)>], bones: &[Affine]) -> Vec<DVec3> {
    let dq: Vec<DualQuat> = bones.iter().map(DualQuat::of).collect();
    rest.iter()
        .zip(influences)
        .map(|(&p, inf)| blend(&dq, inf, p))
        .collect()
}

/// Each of `normals` rotated by its vertex's blended dual quaternion's rotation: DQS's normal
/// transform (a rigid motion's; a vertex without weight keeps its normal).
pub fn rotate(normals: &[DVec3], influences: &[Vec<(usize, f64)>], bones: &[Affine]) -> Vec<DVec3> {
    let dq: Vec<DualQuat> = bones.iter().map(DualQuat::of).collect();
    (normals.iter().zip(influences))
        .map(|(&n, inf)| blended(&dq, inf).map_or(n, |b| b.real * n))
        .collect()
}

/// `p` moved by the normalised weighted sum of `dq` (see [`blended`]).
fn blend(dq: &[DualQuat], inf: &[(usize, f64)], p: DVec3) -> DVec3 {
    let Some(DualQuat { real, dual }) = blended(dq, inf) else {
        return p;
    };
    // The translation t = 2 dual real*; the rotation is real's.
    let t = dual * real.conjugate() * 2.0;
    real * p + DVec3::new(t.x, t.y, t.z)
}

/// The weighted sum of `dq`, each flipped into the hemisphere of the heaviest one's real part
/// (q and −q are one rotation), normalised; None without weight (or when it cancels).
/// Its real part is also the rotation of centres-of-rotation skinning ([`super::cor`]).
pub(super) fn blended(dq: &[DualQuat], inf: &[(usize, f64)]) -> Option<DualQuat> {
    let &(pivot, _) = inf.iter().max_by(|x, y| x.1.total_cmp(&y.1))?;
    let zero = DQuat::from_xyzw(0.0, 0.0, 0.0, 0.0);
    let (mut real, mut dual) = (zero, zero);
    for &(b, w) in inf {
        let s = if dq[b].real.dot(dq[pivot].real) < 0.0 {
            -w
        } else {
            w
        };
        real += dq[b].real * s;
        dual += dq[b].dual * s;
    }
    let norm = real.length();
    (norm > 0.0).then(|| DualQuat {
        real: real / norm,
        dual: dual / norm,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DMat3;

    fn bone(axis: DVec3, angle: f64, d: DVec3) -> Affine {
        Affine {
            q: DMat3::from_axis_angle(axis.normalize(), angle),
            d,
        }
    }

    #[test]
    fn one_bone_is_its_rigid_motion() {
        let b = bone(DVec3::new(1.0, 2.0, -0.5), 1.1, DVec3::new(0.3, -0.2, 0.7));
        let p = DVec3::new(0.4, -1.0, 2.0);
        let moved = deform(&[p], &[vec![(0, 1.0)]], &[b]);
        assert!((moved[0] - b.apply(p)).length() < 1e-12);
    }

    #[test]
    fn equal_blend_of_a_twist_keeps_the_radius() {
        // A point on the unit circle around the x axis; the two bones twist by 0 and 170
        // degrees: LBS pulls it toward the axis, DQS keeps it on the circle at 85 degrees.
        let x = DVec3::X;
        let bones = [
            bone(x, 0.0, DVec3::ZERO),
            bone(x, 170f64.to_radians(), DVec3::ZERO),
        ];
        let p = DVec3::Y;
        let moved = deform(&[p], &[vec![(0, 0.5), (1, 0.5)]], &bones)[0];
        assert!((moved.length() - 1.0).abs() < 1e-12, "{moved:?}");
        let angle = moved.z.atan2(moved.y).to_degrees();
        assert!((angle - 85.0).abs() < 1e-9, "{angle}");
        let lbs = (bones[0].apply(p) + bones[1].apply(p)) * 0.5;
        assert!(lbs.length() < 0.1);
    }

    #[test]
    fn antipodal_quaternions_blend_as_one_rotation() {
        // q and −q are one motion: without the hemisphere flip their blend would cancel.
        let b = bone(DVec3::new(0.0, 1.0, 1.0), 2.5, DVec3::new(1.0, -0.5, 0.25));
        let q = DualQuat::of(&b);
        let minus = DualQuat {
            real: -q.real,
            dual: -q.dual,
        };
        let p = DVec3::new(0.5, 0.25, -1.0);
        for weights in [[0.3, 0.7], [0.7, 0.3], [0.5, 0.5]] {
            let moved = blend(&[q, minus], &[(0, weights[0]), (1, weights[1])], p);
            assert!(
                (moved - b.apply(p)).length() < 1e-12,
                "{weights:?}: {moved:?}"
            );
        }
    }
}
