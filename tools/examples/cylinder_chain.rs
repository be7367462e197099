//! Writes a synthetic example set of chosen size: a cylinder on a chain of bones, bent and
//! twisted at random, deformed by a black box that slerps each joint's rotation smoothly along
//! the cylinder (volume-preserving, not representable by linear blend skinning). Used to time training at scale:
//!
//!     cargo run --release -p rrskin-tools --example cylinder_chain -- OUT [RINGS SEGMENTS BONES POSES]
//!     cargo run --release -p rrskin-tools -- train OUT -o chain.rrs
//!
//! The defaults (100 rings x 80 segments, 6 bones, 30 poses, the last 6 held out) give 8000
//! vertices and 15,840 triangles.

use glam::{DMat3, DQuat, DVec3};
use rrskin_tools::import::example_set::{Bone, ExampleSet, Pose};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let out = args
        .first()
        .ok_or("usage: cylinder_chain OUT [RINGS SEGMENTS BONES POSES]")?;
    let arg = |i: usize, default: usize| -> Result<usize, Box<dyn std::error::Error>> {
        Ok(args
            .get(i)
            .map(|s| s.parse())
            .transpose()?
            .unwrap_or(default))
    };
    let (rings, segments, bones, poses) = (arg(1, 100)?, arg(2, 80)?, arg(3, 6)?, arg(4, 30)?);
    if rings < 2 || segments < 3 || bones < 1 || poses < 2 {
        return Err("need RINGS >= 2, SEGMENTS >= 3, BONES >= 1, POSES >= 2".into());
    }
    let length = bones as f64;
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
    let mut faces = Vec::with_capacity(2 * (rings - 1) * segments);
    for r in 0..rings - 1 {
        for s in 0..segments {
            let (a, b) = (r * segments + s, r * segments + (s + 1) % segments);
            faces.push([a, b, b + segments]);
            faces.push([a, b + segments, a + segments]);
        }
    }
    let mut seed = 0x9E37_79B9_7F4A_7C15u64;
    let mut uniform = move || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        (seed >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    };
    let mut examples = Vec::with_capacity(poses);
    for i in 0..poses {
        // Bone b pivots at x = b; world rotations compose local bends (z, y) and twists (x).
        let mut world = DMat3::IDENTITY;
        let mut origin = DVec3::ZERO;
        let mut pose_bones = Vec::with_capacity(bones);
        for b in 0..bones {
            let local = if i == 0 {
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
            pose_bones.push(Bone {
                q: world,
                d: origin,
            });
        }
        // The black box: around each joint, the rotation slerps from one bone's to the next over
        // ±0.4 about the joint (like dual-quaternion skinning: no collapse, not linear blending).
        let vertices = rest
            .iter()
            .map(|&p| {
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
            })
            .collect();
        examples.push(Pose {
            bones: pose_bones,
            vertices,
        });
    }
    let set = ExampleSet {
        rest,
        faces,
        parents: (0..bones).map(|b| b.checked_sub(1)).collect(),
        poses: examples,
        is_test: (0..poses).map(|i| i >= poses - poses / 5).collect(),
        bone_names: None,
        rig_weights: None,
        warnings: Vec::new(),
    };
    set.save(out)?;
    eprintln!(
        "wrote {out}: {} vertices, {} triangles, {} bones, {} poses",
        set.vertex_count(),
        set.faces.len(),
        bones,
        poses
    );
    Ok(())
}
