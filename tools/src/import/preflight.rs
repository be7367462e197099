//! The last check before training: the examples must be the rig's own motion. A cache in other
//! units or axes, another space, another vertex order, out of step with the poses, or of another
//! rig's motion is what the rig's own skin cannot follow; training on it makes a model of
//! garbage.
//!
//! The test is relative, so that a right cache passes whatever the rig: the rig's skin (linear
//! blend skinning with its own weights) of pose i must be much nearer pose i's vertices than the
//! skins of the other poses are. How good the rig's LBS is does not enter: a low-poly body
//! under DQS and a smoothing pass may be no better than rigid bones, and its cache is still
//! right. Every distance is an RMS over the training poses and the vertices, in mesh units (over
//! the rest mesh's bounding-box diagonal).

use crate::set::diagonal;
use crate::set::{ExampleSet, InputError};
use crate::skinning::lbs::Skinning;
use glam::DVec3;
use rayon::prelude::*;
use std::path::Path;

/// The rig's skin of each pose must be nearer its vertices than this fraction of the other poses'
/// skins (RMS). Right sets measured 0.004–0.14 (the bundled sets, the black boxes and a limb
/// whose own LBS is at 90 % of the rigid error); misaligned ones (scaled 1.5x, rolled by a
/// pose, in reverse order, another rig's poses) 0.53–1.07.
pub const PAIRING_LIMIT: f64 = 0.3;
/// Poses whose vertices are nearer the skin of their neighbour (the next or the previous
/// training pose) than this fraction of the distance from their own are out of step: a
/// warning, not a refusal, since a deformer that lags (a simulation) does the same. Measured:
/// random poses 7 or more, an animation in step 1.7, the same a frame late 0.57.
pub const STEP_LIMIT: f64 = 0.75;

/// What every loader checks last: that the set is its rig's motion (`check_rig_motion`,
/// naming `motion_file` and `fix`), then a warning naming `bones_file` where the held-out poses
/// move bones training leaves out ([`ExampleSet::inactive_bone_warning`]).
pub fn check(
    set: &mut ExampleSet,
    motion_file: &Path,
    fix: &str,
    bones_file: &Path,
) -> Result<(), InputError> {
    check_rig_motion(set, motion_file, fix)?;
    let bones = set.inactive_bone_warning();
    set.warnings
        .extend(bones.map(|w| format!("{}: {w}", bones_file.display())));
    Ok(())
}

/// Refuses a set whose vertices are not its rig's motion ([`RigFit::refusal`]), naming `file`
/// and, after why, `fix`: what to export differently. Adds a warning where the poses are out of
/// step ([`RigFit::warning`]).
fn check_rig_motion(set: &mut ExampleSet, file: &Path, fix: &str) -> Result<(), InputError> {
    let Some(fit) = RigFit::of(set) else {
        return Ok(());
    };
    if let Some(why) = fit.refusal() {
        return Err(InputError {
            file: file.to_path_buf(),
            message: format!("{why}: {fix}"),
        });
    }
    set.warnings
        .extend(fit.warning().map(|w| format!("{}: {w}", file.display())));
    Ok(())
}

/// How the rig's own skin follows the training poses' vertices (mesh units).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RigFit {
    /// From each pose's vertices to the rig's skin of the same pose: the aligned residual.
    pub residual: f64,
    /// From each pose's vertices to the skins of the other training poses.
    pub unpaired: f64,
    /// From each pose's vertices to the skin of the next training pose (`+1`) or the previous
    /// one (`-1`), whichever is nearer: of an animation, the skins a frame early or late.
    pub step: (i8, f64),
}

impl RigFit {
    /// Measures the fit over the training poses: None when the set has no rig weights, fewer
    /// than two training poses, or poses that do not move (no pairing to tell apart).
    pub fn of(set: &ExampleSet) -> Option<RigFit> {
        let weights = set.rig_weights.as_ref()?;
        let train = set.train();
        let skin = Skinning {
            influences: weights.clone(),
        };
        let skins: Vec<Vec<DVec3>> = (train.par_iter())
            .map(|&i| skin.deform(&set.rest, &set.poses[i].bones))
            .collect();
        let vertices: Vec<&[DVec3]> = (train.iter())
            .map(|&i| set.poses[i].vertices.as_slice())
            .collect();
        RigFit::between(&set.rest, &vertices, &skins)
    }

    /// The fit of poses' vertices (`vertices[k]`: pose k's, over the `rest` mesh) to the rig's
    /// skin of each pose (`skins[k]`): None for fewer than two poses, or poses that do not move.
    pub fn between(rest: &[DVec3], vertices: &[&[DVec3]], skins: &[Vec<DVec3>]) -> Option<RigFit> {
        let n = vertices.len();
        if n < 2 {
            return None;
        }
        let sums = (0..rest.len())
            .into_par_iter()
            .map(|a| vertex_sums(rest[a], vertices, skins, a))
            .reduce(|| [0.0; 4], |x, y| std::array::from_fn(|k| x[k] + y[k]));
        let [paired, all_pairs, next, previous] = sums;
        let size = diagonal(rest);
        let rms =
            |sum: f64, pairs: usize| (sum.max(0.0) / (pairs * rest.len()) as f64).sqrt() / size;
        let unpaired = rms(all_pairs - paired, n * (n - 1));
        if unpaired <= 1e-9 {
            return None;
        }
        let step = match next <= previous {
            true => (1, rms(next, n - 1)),
            false => (-1, rms(previous, n - 1)),
        };
        Some(RigFit {
            residual: rms(paired, n),
            unpaired,
            step,
        })
    }

    /// The residual as a fraction of the unpaired distance.
    pub fn pairing(&self) -> f64 {
        self.residual / self.unpaired
    }

    /// Whether the rig's skin follows each pose much better than the others: the examples are
    /// the rig's motion.
    pub fn follows(&self) -> bool {
        self.pairing() <= PAIRING_LIMIT
    }

    /// Why the examples are not the rig's motion, or None where they are.
    pub fn refusal(&self) -> Option<String> {
        (!self.follows()).then(|| {
            format!(
                "the rig's own skin follows each pose no better than it follows the others (each pose's vertices are {:.2} % of the mesh size from the rig's skin of that pose, {:.2} % from its skin of the other poses; a rig's own motion is below {:.0} % of the second): the vertices are not this rig's motion",
                100.0 * self.residual,
                100.0 * self.unpaired,
                100.0 * PAIRING_LIMIT
            )
        })
    }

    /// A line for the user where the poses' vertices follow the skin of their neighbours
    /// better than their own: a cache a frame early or late, or a deformer with a lag.
    pub fn warning(&self) -> Option<String> {
        let (shift, to_neighbour) = self.step;
        (to_neighbour < STEP_LIMIT * self.residual).then(|| {
            format!(
                "each training pose's vertices are {:.2} % of the mesh size from the rig's skin of the {} training pose and {:.2} % from their own: is the cache a frame {}?",
                100.0 * to_neighbour,
                if shift > 0 { "next" } else { "previous" },
                100.0 * self.residual,
                if shift > 0 { "early" } else { "late" },
            )
        })
    }
}

/// Per vertex `a` (at `rest`), with y_i its position in pose i and s_i the rig's skin of it:
/// `[Σ_i |y_i − s_i|², Σ_{i,j} |y_i − s_j|², Σ_{i<n−1} |y_i − s_{i+1}|², Σ_{i>0} |y_i − s_{i−1}|²]`. The
/// sum over all pairs is `n Σ|y_i|² + n Σ|s_j|² − 2 Σy_i · Σs_j`, about the rest position (so
/// that nothing large cancels): O(n), not O(n²).
fn vertex_sums(rest: DVec3, vertices: &[&[DVec3]], skins: &[Vec<DVec3>], a: usize) -> [f64; 4] {
    let n = vertices.len();
    let y = |k: usize| vertices[k][a] - rest;
    let s = |k: usize| skins[k][a] - rest;
    let (mut paired, mut next, mut previous) = (0.0, 0.0, 0.0);
    let (mut y2, mut s2, mut y_sum, mut s_sum) = (0.0, 0.0, DVec3::ZERO, DVec3::ZERO);
    for k in 0..n {
        let (yk, sk) = (y(k), s(k));
        paired += (yk - sk).length_squared();
        if k + 1 < n {
            next += (yk - s(k + 1)).length_squared();
        }
        if k > 0 {
            previous += (yk - s(k - 1)).length_squared();
        }
        y2 += yk.length_squared();
        s2 += sk.length_squared();
        y_sum += yk;
        s_sum += sk;
    }
    let all_pairs = n as f64 * (y2 + s2) - 2.0 * y_sum.dot(s_sum);
    [paired, all_pairs, next, previous]
}
