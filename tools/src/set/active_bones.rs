//! The bones training may use. A bone that the training poses never move (relative to its
//! parent: an IK pole, a foot control, an attachment slot left at rest) is, in those poses, a
//! copy of its parent, so any weight or predictor term it gets is an arbitrary share of its
//! parent's; when an engine's animation moves it, the vertices that got that share go with it
//! and the model explodes. A bone the rig's own skin gives no weight deforms nothing, whatever
//! it does. Neither gets a weight, a predictor term or a corrective driver.

use crate::set::diagonal;
use crate::set::{Affine, ExampleSet};

/// Rotation elements and translations (over the mesh size) that differ by less are the same.
const SAME: f64 = 1e-6;

impl ExampleSet {
    /// Per bone: true where training may give it weight, a predictor term or a corrective
    /// driver. A bone is active when the rig's weights give it weight somewhere (or are not
    /// known) and it moves relative to its parent (a root: at all) across the training poses,
    /// or is an ancestor of such a bone (a still hip or root carries the moving bones below it).
    /// Every bone where none is (nothing moves: nothing to leave out).
    pub fn active_bones(&self) -> Vec<bool> {
        let weighted = self.weighted_bones();
        let moving = self.moving_bones(&self.train());
        let mut active: Vec<bool> = (0..self.bone_count())
            .map(|b| weighted[b] && moving[b])
            .collect();
        for b in 0..self.bone_count() {
            if !active[b] {
                continue;
            }
            // Walk up: every weighted ancestor carries this bone (at most J steps: no cycles).
            let mut up = self.parents[b];
            for _ in 0..self.bone_count() {
                let Some(p) = up else { break };
                active[p] |= weighted[p];
                up = self.parents[p];
            }
        }
        if !active.contains(&true) {
            active.fill(true);
        }
        active
    }

    /// One line naming the bones that training leaves out ([`Self::active_bones`]) but the
    /// held-out poses move: the model gives them nothing, so what they do to the rig's mesh is
    /// not followed. None where there are none.
    pub fn inactive_bone_warning(&self) -> Option<String> {
        // A bone still in training that moves in a held-out pose moves across the first
        // training pose and the held-out ones.
        let poses: Vec<usize> = self
            .train()
            .into_iter()
            .take(1)
            .chain(self.test())
            .collect();
        let (active, weighted, moving) = (
            self.active_bones(),
            self.weighted_bones(),
            self.moving_bones(&poses),
        );
        let moved: Vec<usize> = (0..self.bone_count())
            .filter(|&b| !active[b] && moving[b])
            .collect();
        if moved.is_empty() {
            return None;
        }
        let names = |deforms: bool| -> Vec<String> {
            (moved.iter())
                .filter(|&&b| weighted[b] == deforms)
                .map(|&b| self.bone_name(b))
                .collect()
        };
        let kinds: Vec<String> = [
            (names(true), "the training poses never move"),
            (names(false), "deform nothing (no weight in the rig's skin)"),
        ]
        .into_iter()
        .filter(|(n, _)| !n.is_empty())
        .map(|(n, why)| format!("{} ({why})", n.join(", ")))
        .collect();
        Some(format!(
            "the held-out poses move bones that training gives no weight or predictor term: {}; the model ignores them: pose them in the training poses if they deform the mesh",
            kinds.join("; ")
        ))
    }

    /// Affine b's name, or "bone b".
    pub fn bone_name(&self, b: usize) -> String {
        (self.bone_names.as_ref())
            .and_then(|n| n.get(b).cloned())
            .unwrap_or_else(|| format!("bone {b}"))
    }

    /// Per bone: the rig's skin gives it weight somewhere (true for every bone when the rig's
    /// weights are not known).
    fn weighted_bones(&self) -> Vec<bool> {
        let mut weighted = vec![self.rig_weights.is_none(); self.bone_count()];
        for inf in self.rig_weights.iter().flatten() {
            for &(b, w) in inf {
                weighted[b] |= w > 0.0;
            }
        }
        weighted
    }

    /// Per bone: its transform relative to its parent's differs between two of `poses`.
    fn moving_bones(&self, poses: &[usize]) -> Vec<bool> {
        let size = self.size();
        (0..self.bone_count())
            .map(|b| {
                let Some(&first) = poses.first() else {
                    return false;
                };
                let reference = self.local(first, b);
                poses
                    .iter()
                    .any(|&i| !same(self.local(i, b), reference, size))
            })
            .collect()
    }

    /// Affine b's transform in pose i relative to its parent's (a root's own).
    fn local(&self, i: usize, b: usize) -> Affine {
        let bones = &self.poses[i].bones;
        match self.parents[b] {
            None => bones[b],
            Some(p) => {
                let inverse = bones[p].q.transpose();
                Affine {
                    q: inverse * bones[b].q,
                    d: inverse * (bones[b].d - bones[p].d),
                }
            }
        }
    }

    fn size(&self) -> f64 {
        diagonal(&self.rest).max(f64::MIN_POSITIVE)
    }
}

fn same(x: Affine, y: Affine, size: f64) -> bool {
    x.q.abs_diff_eq(y.q, SAME) && (x.d - y.d).length() <= SAME * size
}
