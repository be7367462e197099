//! Joint pivots: for each bone, the rest-space point that it and its parent move alike in every
//! pose (`T_b c_b = T_p c_b`), by least squares over the poses. Rigs do not export their joint
//! centres in the example layout; the poses determine them (up to the joint's axis where a
//! joint only ever turns about one).

use crate::set::ExampleSet;
use glam::{DMat3, DVec3};

/// Each bone's pivot: argmin_c Σ_i |(Q_b − Q_p) c − (d_p − d_b)|² (roots: the origin).
pub fn pivots(set: &ExampleSet, poses: &[usize]) -> Vec<DVec3> {
    (0..set.bone_count())
        .map(|b| {
            let Some(p) = set.parents[b] else {
                return DVec3::ZERO;
            };
            let (mut g, mut h) = (DMat3::ZERO, DVec3::ZERO);
            for &i in poses {
                let (tb, tp) = (set.poses[i].bones[b], set.poses[i].bones[p]);
                let m = tb.q - tp.q;
                g += m.transpose() * m;
                h += m.transpose() * (tp.d - tb.d);
            }
            // A weak ridge toward the origin fixes c along the axis of a joint that only ever
            // turns about one (and where it never turns).
            let ridge = 1e-9 * (g.x_axis.x + g.y_axis.y + g.z_axis.z).max(1e-300);
            (g + DMat3::from_diagonal(DVec3::splat(ridge))).inverse() * h
        })
        .collect()
}
