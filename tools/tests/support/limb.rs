//! A rig whose own linear blend skinning is no better than rigid bones: a low-poly limb of three
//! bones (7 rings of 6 vertices), bent and twisted widely at its two joints, deformed by DQS with
//! the rig's weights plus a muscle bulge driven by each joint's bend (as a corrective shape key
//! would). Neither LBS nor rigid bones can follow the bulge or the wide twists, so the rig's
//! LBS error is about the rigid one; the examples are still this rig's motion, and train.

use glam::{DMat3, DVec3};
use rrskin_tools::set::{Affine, ExampleSet, Pose};

const RINGS: usize = 7;
const SEGMENTS: usize = 6;
const RADIUS: f64 = 0.25;
/// The joints' positions along x (bone b spans x in [b, b + 1]).
const JOINTS: [f64; 2] = [1.0, 2.0];

/// The rig's weights: a ring at a joint is shared equally by the bones on either side.
fn weights(x: f64) -> Vec<(usize, f64)> {
    match JOINTS.iter().position(|&j| (x - j).abs() < 1e-9) {
        Some(k) => vec![(k, 0.5), (k + 1, 0.5)],
        None => vec![(x.floor().min(2.0) as usize, 1.0)],
    }
}

/// A generator of uniform numbers in [−1, 1) (an LCG: the set is the same on every machine).
struct Lcg(u64);

impl Lcg {
    fn next(&mut self) -> f64 {
        self.0 = (self.0)
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (self.0 >> 11) as f64 / (1u64 << 52) as f64 - 1.0
    }
}

/// Each joint's bend about z and twist about the bone, in radians.
type Angles = [(f64, f64); 2];

/// The limb's bones in one pose, each joint's rotation about its own rest position, after its
/// parent's motion.
fn bones_of(angles: Angles) -> Vec<Affine> {
    let mut bones = vec![Affine {
        q: DMat3::IDENTITY,
        d: DVec3::ZERO,
    }];
    for (&x, (bend, twist)) in JOINTS.iter().zip(angles) {
        let local = DMat3::from_rotation_z(bend) * DMat3::from_rotation_x(twist);
        let parent = *bones.last().expect("the root");
        let joint = DVec3::new(x, 0.0, 0.0);
        let q = parent.q * local;
        bones.push(Affine {
            q,
            d: parent.apply(joint) - q * joint,
        });
    }
    bones
}

/// `poses` training poses then `test` held-out ones, each joint bent by up to 90° and twisted
/// by up to 170° at random; pose 0 is the rest pose.
pub fn limb_set(poses: usize, test: usize) -> ExampleSet {
    let mut rng = Lcg(2007);
    let mut angle = |degrees: f64| (degrees * rng.next()).to_radians();
    let angles: Vec<Angles> = (0..poses + test)
        .map(|i| match i {
            0 => [(0.0, 0.0); 2],
            _ => [(); 2].map(|_| (angle(90.0), angle(170.0))),
        })
        .collect();
    limb_of(&angles, poses, true)
}

/// An animation of `frames` frames, 5° apart at each joint (held out: none), deformed by DQS
/// alone: each frame moves the hand by about 5 % of the limb's size, several times the rig's
/// residual.
pub fn limb_animation(frames: usize) -> ExampleSet {
    let angles: Vec<Angles> = (0..frames)
        .map(|f| {
            let t = (5.0 * f as f64).to_radians();
            [(t, 0.5 * t), (0.5 * t, -t)]
        })
        .collect();
    limb_of(&angles, frames, false)
}

/// The limb posed by `angles`, the first `train` poses for training; deformed by DQS, then, if
/// `rich`, the bulge and the smoothing pass.
fn limb_of(angles: &[Angles], train: usize, rich: bool) -> ExampleSet {
    let (rest, faces) = super::tube(RINGS, SEGMENTS, 3.0, RADIUS);
    let mut neighbours = vec![Vec::new(); rest.len()];
    for t in &faces {
        for k in 0..3 {
            neighbours[t[k]].push(t[(k + 1) % 3]);
            neighbours[t[(k + 1) % 3]].push(t[k]);
        }
    }
    let influences: Vec<Vec<(usize, f64)>> = rest.iter().map(|p| weights(p.x)).collect();
    let examples = (angles.iter())
        .map(|&angles| {
            let bones = bones_of(angles);
            let bends = angles.map(|(bend, _)| bend);
            let posed = rrskin_tools::skinning::dqs::deform(&rest, &influences, &bones);
            if !rich {
                return Pose {
                    bones,
                    vertices: posed,
                };
            }
            let moved: Vec<DVec3> = (posed.iter().zip(&rest))
                .map(|(y, p)| *y - *p + bulge(*p, &bones, bends))
                .collect();
            let vertices = (smooth(&moved, &neighbours).iter().zip(&rest))
                .map(|(d, p)| *p + *d)
                .collect();
            Pose { bones, vertices }
        })
        .collect();
    ExampleSet {
        rest,
        faces,
        parents: vec![None, Some(0), Some(1)],
        poses: examples,
        is_test: (0..angles.len()).map(|i| i >= train).collect(),
        bone_names: Some(["upper", "lower", "hand"].map(String::from).to_vec()),
        rig_weights: Some(influences),
        warnings: Vec::new(),
    }
}

/// The muscle on the top of each bone after a joint swells with that joint's bend (by the radius
/// times the bend in radians), outward along the rest radial direction, moved with the bone.
fn bulge(p: DVec3, bones: &[Affine], bends: [f64; 2]) -> DVec3 {
    let radial = DVec3::new(0.0, p.y, p.z).normalize_or_zero();
    (0..2)
        .map(|k| {
            let along = p.x - JOINTS[k];
            let profile = (1.0 - (2.0 * along - 1.0).powi(2)).max(0.0) * radial.y.max(0.0);
            bones[k + 1].q * radial * (RADIUS * profile * bends[k].abs())
        })
        .sum()
}

/// The displacements smoothed over the mesh's edges (2 steps of factor 0.5, as a smoothing
/// modifier after the armature would): a joint's kink spreads to the rings beside it.
fn smooth(moved: &[DVec3], neighbours: &[Vec<usize>]) -> Vec<DVec3> {
    let mut d = moved.to_vec();
    for _ in 0..2 {
        d = (d.iter().zip(neighbours))
            .map(|(&x, n)| {
                let mean = n.iter().map(|&k| d[k]).sum::<DVec3>() / n.len() as f64;
                x + 0.5 * (mean - x)
            })
            .collect();
    }
    d
}

/// [`limb_set`] with two bones that deform nothing, as rigs have: `IKPole` (a root) and
/// `HandSlot` (an attachment slot, a child of the hand). The training poses leave them at rest
/// (relative to their parents); the held-out poses move them if `moved`.
pub fn limb_with_controls(poses: usize, test: usize, moved: bool) -> ExampleSet {
    let mut set = limb_set(poses, test);
    set.parents.extend([None, Some(2)]);
    (set.bone_names.as_mut().expect("names")).extend(["IKPole", "HandSlot"].map(String::from));
    for (i, pose) in set.poses.iter_mut().enumerate() {
        let hand = pose.bones[2];
        let (pole, slot) = match i >= poses && moved {
            false => (DMat3::IDENTITY, DMat3::IDENTITY),
            true => (
                DMat3::from_rotation_y(0.7 + 0.1 * i as f64),
                DMat3::from_rotation_x(1.2 - 0.05 * i as f64),
            ),
        };
        let tip = DVec3::new(3.0, 0.0, 0.0);
        pose.bones.push(Affine {
            q: pole,
            d: DVec3::new(0.0, 0.5, 0.0) - pole * DVec3::new(0.0, 0.5, 0.0),
        });
        // The slot turned about the hand's tip, after the hand's motion.
        let q = hand.q * slot;
        pose.bones.push(Affine {
            q,
            d: hand.apply(tip) - q * tip,
        });
    }
    set
}
