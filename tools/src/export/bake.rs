//! Baking a clip through the model into glTF node channels.
//!
//! Palette entry e's affine transform `A = [M | t]` becomes two nodes: an outer one with
//! translation t, rotation U and scale Σ, and its child with rotation Vᵀ, where `M = U Σ Vᵀ` is
//! a signed SVD (U, V rotations), so that the child's world matrix is exactly A, scale and shear
//! included. Samples are placed where they are needed: between two samples a viewer lerps t and
//! Σ and slerps U and Vᵀ, and every interval is halved (up to [`MAX_DEPTH`] times) until that
//! playback stays within the tolerance of the model evaluated at the clip's own pose, at a
//! quarter, half and three quarters of the interval. A model's pose-space correctives are
//! baked the same way, as morph-target weights that a viewer lerps between samples.

use crate::linalg::{polar, svd3};
use glam::{DMat3, DQuat, DVec3};
use rrskin::palette::Palette;
use rrskin::predict::{rotation_of, Affine};

/// Intervals between keys are halved at most this often (256 samples per key interval: a
/// clip of random poses at 24 fps turns bones by up to 8° in 1/32 of an interval, which a
/// viewer's interpolation, a chord of the true arc, follows only to 2e-3 of the mesh's size).
pub const MAX_DEPTH: u32 = 8;

/// A sample keeps its entry's previous V while that V diagonalises S this well (the largest
/// off-diagonal against the largest diagonal element): the played matrix is then off by at
/// most this, relative, at the sample (a vertex by this fraction of its distance from the
/// origin), far below the between-key tolerance.
pub const KEEP_V: f64 = 1e-5;

/// One palette entry at one sample: the outer node's (t, U, Σ) and the child's rotation Vᵀ.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NodePair {
    pub translation: DVec3,
    pub rotation: DQuat,
    pub scale: DVec3,
    pub child_rotation: DQuat,
}

/// A baked clip: sample times (seconds, increasing) and per sample the P + J node pairs and
/// the N corrective weights.
#[derive(Debug, Clone)]
pub struct Baked {
    pub times: Vec<f64>,
    pub samples: Vec<Vec<NodePair>>,
    pub weights: Vec<Vec<f32>>,
    /// The largest vertex distance between the played file and the model, at the samples and
    /// between them (where it was checked), in the mesh's units.
    pub worst_at_samples: f64,
    pub worst_between: f64,
}

impl NodePair {
    /// The rest pose: both nodes at the identity.
    pub const REST: NodePair = NodePair {
        translation: DVec3::ZERO,
        rotation: DQuat::IDENTITY,
        scale: DVec3::ONE,
        child_rotation: DQuat::IDENTITY,
    };

    /// `a` split into the two nodes, continuing `previous` (the same entry's last sample).
    ///
    /// With `M = R S` (polar), any V that diagonalises S serves. Where S is nearly isotropic
    /// (a rigid bone, a proxy that barely scales) its eigenvectors are noise, and a V that jumps
    /// from sample to sample makes a viewer's separate interpolation of U and V wrong, so the
    /// previous V is kept as long as it diagonalises S to [`KEEP_V`] (Σ its diagonal). Else the
    /// signed SVD, of its 24 equivalent forms the one whose V is nearest the previous.
    pub fn of(a: &Affine, previous: Option<&NodePair>) -> NodePair {
        let m = rotation_of(a);
        let previous_v = previous.map(|p| DMat3::from_quat(p.child_rotation).transpose());
        let kept = previous_v.and_then(|v| {
            let (r, s) = polar(m);
            let d = v.transpose() * s * v;
            let diagonal = DVec3::new(d.x_axis.x, d.y_axis.y, d.z_axis.z);
            let off = [d.y_axis.x, d.z_axis.x, d.z_axis.y]
                .iter()
                .fold(0.0f64, |w, x| w.max(x.abs()));
            (off <= KEEP_V * diagonal.abs().max_element()).then(|| (r * v, diagonal, v))
        });
        let (u, sigma, v) = kept.unwrap_or_else(|| {
            let (u, sigma, v) = svd3(m);
            nearest_signed_permutation(u, sigma, v, previous_v.unwrap_or(DMat3::IDENTITY))
        });
        let mut rotation = DQuat::from_mat3(&u).normalize();
        let mut child_rotation = DQuat::from_mat3(&v.transpose()).normalize();
        if let Some(p) = previous {
            if rotation.dot(p.rotation) < 0.0 {
                rotation = -rotation;
            }
            if child_rotation.dot(p.child_rotation) < 0.0 {
                child_rotation = -child_rotation;
            }
        }
        NodePair {
            translation: DVec3::new(a[3] as f64, a[7] as f64, a[11] as f64),
            rotation,
            scale: sigma,
            child_rotation,
        }
    }

    /// What a glTF viewer plays at fraction `f` between `self` and `next`.
    pub fn lerp(&self, next: &NodePair, f: f64) -> NodePair {
        NodePair {
            translation: self.translation.lerp(next.translation, f),
            rotation: self.rotation.slerp(next.rotation, f),
            scale: self.scale.lerp(next.scale, f),
            child_rotation: self.child_rotation.slerp(next.child_rotation, f),
        }
    }

    /// The child node's world matrix (the outer node under an identity root).
    pub fn affine(&self) -> Affine {
        let m = DMat3::from_quat(self.rotation)
            * DMat3::from_diagonal(self.scale)
            * DMat3::from_quat(self.child_rotation);
        crate::set::Affine {
            q: m,
            d: self.translation,
        }
        .to_runtime()
    }
}

/// Of the 24 proper signed permutations P (U Σ Vᵀ = (UP)(PᵀΣP)(VP)ᵀ), the one that brings V
/// nearest to `previous_v`.
fn nearest_signed_permutation(
    u: DMat3,
    sigma: DVec3,
    v: DMat3,
    previous_v: DMat3,
) -> (DMat3, DVec3, DMat3) {
    const ORDERS: [[usize; 3]; 6] = [
        [0, 1, 2],
        [0, 2, 1],
        [1, 0, 2],
        [1, 2, 0],
        [2, 0, 1],
        [2, 1, 0],
    ];
    let cols = |m: DMat3| [m.x_axis, m.y_axis, m.z_axis];
    let (uc, vc, s) = (cols(u), cols(v), sigma.to_array());
    let mut best = (f64::NEG_INFINITY, u, sigma, v);
    for order in ORDERS {
        for signs in 0..8u32 {
            let sign = |i: usize| if signs >> i & 1 == 1 { -1.0 } else { 1.0 };
            let pv = DMat3::from_cols(
                vc[order[0]] * sign(0),
                vc[order[1]] * sign(1),
                vc[order[2]] * sign(2),
            );
            if pv.determinant() < 0.0 {
                continue;
            }
            let score = (previous_v.transpose() * pv)
                .to_cols_array()
                .iter()
                .step_by(4)
                .sum::<f64>();
            if score > best.0 {
                let pu = DMat3::from_cols(
                    uc[order[0]] * sign(0),
                    uc[order[1]] * sign(1),
                    uc[order[2]] * sign(2),
                );
                let ps = DVec3::new(s[order[0]], s[order[1]], s[order[2]]);
                best = (score, pu, ps, pv);
            }
        }
    }
    (best.1, best.2, best.3)
}

/// One character's palette and corrective weights: the model at a pose, or what a viewer plays.
struct Frame {
    palette: Vec<Affine>,
    weights: Vec<f32>,
}

/// Bakes one clip: `keys` its key times (at least one), `pose_at(t)` the J bone transforms at
/// any time in their range, `tolerance` the largest vertex distance allowed between samples.
/// A clip that holds each key until the next (`step`: glTF's STEP) is sampled at its keys and
/// played held, so it is exact between them as at them.
pub fn bake(
    palette: &Palette,
    keys: &[f64],
    pose_at: impl Fn(f64) -> Vec<Affine>,
    step: bool,
    tolerance: f64,
) -> rrskin::Result<Baked> {
    let entries = |t: f64| -> rrskin::Result<Frame> {
        let bones = pose_at(t);
        let mut frame = Frame {
            palette: vec![[0.0; 12]; palette.len()],
            weights: vec![0.0; palette.corrective_count()],
        };
        palette.compute(&bones, &mut frame.palette)?;
        palette.corrective_weights(&bones, &mut frame.weights)?;
        Ok(frame)
    };
    let pairs = |a: &[Affine], previous: Option<&[NodePair]>| -> Vec<NodePair> {
        a.iter()
            .enumerate()
            .map(|(e, a)| NodePair::of(a, previous.map(|p| &p[e])))
            .collect()
    };
    let v = palette.model().vertex_count();
    let (mut want, mut got) = (vec![[0.0f32; 3]; v], vec![[0.0f32; 3]; v]);
    let mut distance = |reference: &Frame, played: &Frame| -> rrskin::Result<f64> {
        palette.skin_positions(&reference.palette, &reference.weights, &mut want)?;
        palette.skin_positions(&played.palette, &played.weights, &mut got)?;
        Ok(want.iter().zip(&got).fold(0.0f64, |m, (a, b)| {
            let d = (0..3).map(|i| ((a[i] - b[i]) as f64).powi(2)).sum::<f64>();
            m.max(d.sqrt())
        }))
    };
    let first = entries(keys[0])?;
    let mut baked = Baked {
        times: vec![keys[0]],
        samples: vec![pairs(&first.palette, None)],
        weights: vec![first.weights.clone()],
        worst_at_samples: 0.0,
        worst_between: 0.0,
    };
    // What a viewer plays from node pairs and morph weights.
    let played = |s: &[NodePair], weights: &[f32]| Frame {
        palette: s.iter().map(NodePair::affine).collect(),
        weights: weights.to_vec(),
    };
    baked.worst_at_samples = distance(&first, &played(&baked.samples[0], &first.weights))?;
    for &key in &keys[1..] {
        // Targets still to reach, with how often their interval was halved.
        let mut targets = vec![(key, 0u32)];
        while let Some(&(t1, depth)) = targets.last() {
            let last = baked.times.len() - 1;
            let (t0, p0, w0) = (
                baked.times[last],
                &baked.samples[last],
                &baked.weights[last],
            );
            let a1 = entries(t1)?;
            let p1 = pairs(&a1.palette, Some(p0));
            let mut worst = 0.0f64;
            for f in [0.25, 0.5, 0.75] {
                let (between, weights): (Vec<NodePair>, Vec<f32>) = match step {
                    true => (p0.clone(), w0.clone()),
                    false => (
                        p0.iter().zip(&p1).map(|(a, b)| a.lerp(b, f)).collect(),
                        w0.iter()
                            .zip(&a1.weights)
                            .map(|(a, b)| a + f as f32 * (b - a))
                            .collect(),
                    ),
                };
                let reference = entries(t0 + f * (t1 - t0))?;
                worst = worst.max(distance(&reference, &played(&between, &weights))?);
            }
            if !step && worst > tolerance && depth < MAX_DEPTH {
                targets.push((0.5 * (t0 + t1), depth + 1));
                continue;
            }
            targets.pop();
            baked.worst_between = baked.worst_between.max(worst);
            baked.worst_at_samples = baked
                .worst_at_samples
                .max(distance(&a1, &played(&p1, &a1.weights))?);
            baked.times.push(t1);
            baked.samples.push(p1);
            baked.weights.push(a1.weights);
        }
    }
    Ok(baked)
}
