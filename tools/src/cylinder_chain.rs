//! A synthetic example set of chosen size: a cylinder on a chain of bones, bent and twisted at
//! random, deformed by a black box that slerps each joint's rotation smoothly along the
//! cylinder (volume-preserving, not representable by linear blend skinning). Used to time
//! training at scale (`benches/`, `examples/cylinder_chain.rs`).

use crate::set::{Affine, ExampleSet, Pose, SetFiles, SetParts};
use glam::{DMat3, DQuat, DVec3};

/// The chain's size: `rings` x `segments` vertices along `bones` unit-length bones, `poses`
/// example poses (pose 0 the rest pose; the last fifth held out).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Chain {
    pub rings: usize,
    pub segments: usize,
    pub bones: usize,
    pub poses: usize,
}

impl Chain {
    /// The example set; `None` unless rings ≥ 2, segments ≥ 3, bones ≥ 1 and poses ≥ 2.
    pub fn build(&self) -> Option<ExampleSet> {
        let Chain {
            rings,
            segments,
            bones,
            poses,
        } = *self;
        if rings < 2 || segments < 3 || bones < 1 || poses < 2 {
            return None;
        }
        let rest = rest_cylinder(rings, segments, bones as f64);
        let faces = cylinder_faces(rings, segments);
        let mut uniform = xorshift(SEED);
        let mut examples = Vec::with_capacity(poses);
        for i in 0..poses {
            let pose_bones = chain_pose(bones, i == 0, &mut uniform);
            let vertices = rest.iter().map(|&p| black_box(&pose_bones, p)).collect();
            examples.push(Pose {
                bones: pose_bones,
                vertices,
            });
        }
        let parts = SetParts {
            rest,
            faces,
            parents: (0..bones).map(|b| b.checked_sub(1)).collect(),
            poses: examples,
            is_test: (0..poses).map(|i| i >= poses - poses / 5).collect(),
            bone_names: None,
            rig_weights: None,
        };
        // Valid by construction: rigid bones, a chain, 4 of 5 poses training poses.
        ExampleSet::new(parts, &SetFiles::one("<cylinder chain>")).ok()
    }
}

/// The rest cylinder: `rings` rings of `segments` vertices, radius 0.25, evenly spaced along
/// the x axis from 0 to `length`, ring-major.
fn rest_cylinder(rings: usize, segments: usize, length: f64) -> Vec<DVec3> {
    let mut rest = Vec::with_capacity(rings * segments);
    for r in 0..rings {
        for s in 0..segments {
            let a = std::f64::consts::TAU * s as f64 / segments as f64;
            rest.push(DVec3::new(
                length * r as f64 / (rings - 1) as f64,
                0.25 * a.cos(),
                0.25 * a.sin(),
            ));
        }
    }
    rest
}

/// The cylinder's side: two triangles between each pair of neighbouring rings per segment
/// (the ends are left open).
fn cylinder_faces(rings: usize, segments: usize) -> Vec<[usize; 3]> {
    let mut faces = Vec::with_capacity(2 * (rings - 1) * segments);
    for r in 0..rings - 1 {
        for s in 0..segments {
            let (a, b) = (r * segments + s, r * segments + (s + 1) % segments);
            faces.push([a, b, b + segments]);
            faces.push([a, b + segments, a + segments]);
        }
    }
    faces
}

/// The chain's poses' seed.
const SEED: u64 = 0x9E37_79B9_7F4A_7C15;

/// A xorshift generator of uniform numbers in [-1, 1) from `seed` (not 0): the same sequence
/// every build, for synthetic poses.
pub fn xorshift(mut seed: u64) -> impl FnMut() -> f64 {
    move || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        (seed >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    }
}

/// One pose's bones: the rest pose if `rest`, else a random bend (z, y) and twist (x) per bone,
/// drawn from `uniform`. Affine b pivots at x = b; world rotations compose the local ones.
fn chain_pose(bones: usize, rest: bool, uniform: &mut impl FnMut() -> f64) -> Vec<Affine> {
    let mut world = DMat3::IDENTITY;
    let mut origin = DVec3::ZERO;
    let mut pose_bones = Vec::with_capacity(bones);
    for b in 0..bones {
        let local = if rest {
            DMat3::IDENTITY
        } else {
            DMat3::from_rotation_z(0.5 * uniform())
                * DMat3::from_rotation_y(0.4 * uniform())
                * DMat3::from_rotation_x(0.9 * uniform())
        };
        let pivot = DVec3::new(b as f64, 0.0, 0.0);
        let parent_apply = |p: DVec3| world * p + origin;
        let moved_pivot = if b == 0 { pivot } else { parent_apply(pivot) };
        world *= local;
        origin = moved_pivot - world * pivot;
        pose_bones.push(Affine {
            q: world,
            d: origin,
        });
    }
    pose_bones
}

/// The black box: rest point `p` moved by the pose's bones, where around each joint the
/// rotation slerps from one bone's to the next over ±0.4 about the joint (like dual-quaternion
/// skinning: no collapse, not linear blending).
fn black_box(pose_bones: &[Affine], p: DVec3) -> DVec3 {
    let bones = pose_bones.len();
    let b = (p.x.floor() as usize).min(bones - 1);
    let f = p.x - b as f64;
    let (lo, hi) = if f < 0.5 && b > 0 {
        (b - 1, b)
    } else {
        (b, (b + 1).min(bones - 1))
    };
    if lo == hi {
        return pose_bones[lo].apply(p);
    }
    let t = if f < 0.5 { 0.5 + f } else { f - 0.5 };
    let s = ((t - 0.1) / 0.8).clamp(0.0, 1.0);
    let s = s * s * (3.0 - 2.0 * s);
    let joint = DVec3::new(hi as f64, 0.0, 0.0);
    let (qa, qb) = (
        DQuat::from_mat3(&pose_bones[lo].q),
        DQuat::from_mat3(&pose_bones[hi].q),
    );
    DMat3::from_quat(qa.slerp(qb, s)) * (p - joint) + pose_bones[lo].apply(joint)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Pose 0 is the rest pose, and far from every joint a vertex moves rigidly with its bone.
    #[test]
    fn the_chain_rests_at_pose_zero_and_moves_rigidly_mid_bone() {
        let chain = Chain {
            rings: 31,
            segments: 6,
            bones: 3,
            poses: 5,
        };
        let set = chain.build().expect("a valid size");
        assert_eq!((set.vertex_count(), set.faces.len()), (186, 360));
        let still = set.poses[0].vertices.iter().zip(&set.rest);
        assert!(still.map(|(y, x)| (*y - *x).length()).fold(0.0, f64::max) < 1e-12);
        let mid_bone: Vec<usize> = (0..set.vertex_count())
            .filter(|&a| (set.rest[a].x.fract() - 0.5).abs() < 0.05)
            .collect();
        assert!(!mid_bone.is_empty());
        for pose in &set.poses[1..] {
            for &a in &mid_bone {
                let bone = pose.bones[set.rest[a].x.floor() as usize];
                let d = (bone.apply(set.rest[a]) - pose.vertices[a]).length();
                assert!(d < 1e-12, "vertex {a} leaves its bone by {d}");
            }
        }
        assert!(Chain { rings: 1, ..chain }.build().is_none());
    }
}
