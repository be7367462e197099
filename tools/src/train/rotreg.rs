//! Rotational regression (paper §3.2, Eq. 3; docs/method.md §2): a rotation sequence R^i is
//! predicted from one bone's joint rotation θ~_b as `R(q) = Q_p(q) · exp(u W θ~_b(q))`, with
//! p = parent(b), W ∈ SO(3), u ∈ R, optionally times `exp(u₂ W₂ θ~_b₂(q))` for a second bone.

use crate::linalg::{procrustes, rotation_angle};
use crate::set::ExampleSet;
use glam::{DMat3, DVec3};
use rrskin::predict::{exp_rotation, log_rotation};
use std::f64::consts::PI;

/// Alternating W/u rounds (docs/method.md §2: two to five suffice).
const ROUNDS: usize = 5;
/// A second bone is kept only if it cuts the training geodesic error by this fraction.
pub const SECOND_BONE_GAIN: f64 = 0.1;

/// Per pose: every bone's rotation Q_b and joint rotation θ~_b = log(Q_p(b)ᵀ Q_b).
#[derive(Debug, Clone)]
pub struct PoseFeatures {
    pub q: Vec<DMat3>,
    pub theta: Vec<DVec3>,
}

impl PoseFeatures {
    pub fn all(set: &ExampleSet) -> Vec<PoseFeatures> {
        set.poses
            .iter()
            .map(|pose| {
                let q: Vec<DMat3> = pose.bones.iter().map(|b| b.q).collect();
                let theta = (0..q.len())
                    .map(|b| match set.parents[b] {
                        Some(p) => log_rotation(q[p].transpose() * q[b]),
                        None => log_rotation(q[b]),
                    })
                    .collect();
                PoseFeatures { q, theta }
            })
            .collect()
    }

    /// Q of `b`'s parent (identity for a root).
    pub fn parent_q(&self, parents: &[Option<usize>], b: usize) -> DMat3 {
        parents[b].map_or(DMat3::IDENTITY, |p| self.q[p])
    }
}

/// One bone's term `exp(u W θ~_bone)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BoneTerm {
    pub bone: usize,
    pub u: f64,
    pub w: DMat3,
}

impl BoneTerm {
    pub fn rotation(&self, f: &PoseFeatures) -> DMat3 {
        exp_rotation(self.w * f.theta[self.bone] * self.u)
    }
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RotationPredictor {
    pub first: BoneTerm,
    pub second: Option<BoneTerm>,
}

impl RotationPredictor {
    pub fn predict(&self, f: &PoseFeatures, parents: &[Option<usize>]) -> DMat3 {
        let r = f.parent_q(parents, self.first.bone) * self.first.rotation(f);
        match &self.second {
            Some(s) => r * s.rotation(f),
            None => r,
        }
    }

    /// Σ over poses of the squared world-space geodesic angle to `targets`.
    pub fn error(
        &self,
        targets: &[DMat3],
        feats: &[&PoseFeatures],
        parents: &[Option<usize>],
    ) -> f64 {
        targets
            .iter()
            .zip(feats)
            .map(|(r, f)| rotation_angle(self.predict(f, parents), *r).powi(2))
            .sum()
    }
}

/// Fits `ρ ≈ u W θ` (targets ρ in the bone's parent frame, sources θ) from one starting sign of
/// u. Targets are unwrapped across the log's branch cut toward the current prediction, by
/// continuation: the fit starts on the third of the samples with the smallest |θ| (whose
/// targets have not wrapped) and the active set doubles until it holds every sample, so large
/// rotations are unwrapped against a model that already knows the trend.
pub fn fit_term(targets: &[DVec3], sources: &[DVec3], sign: f64) -> Option<(f64, DMat3)> {
    let n = targets.len();
    if sources.iter().map(|t| t.length_squared()).sum::<f64>() < 1e-12 {
        return None; // the bone never moves in these poses
    }
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&a, &b| {
        sources[a]
            .length_squared()
            .total_cmp(&sources[b].length_squared())
    });
    let mut count = (n / 3).max(2).min(n);
    while count < n
        && order[..count]
            .iter()
            .all(|&i| sources[i].length_squared() < 1e-12)
    {
        count += 1; // the first stage needs a sample that moves
    }
    let first = &order[..count];
    let tt: f64 = first.iter().map(|&i| sources[i].length_squared()).sum();
    let mut u = sign
        * first
            .iter()
            .map(|&i| sources[i].length() * targets[i].length())
            .sum::<f64>()
        / tt;
    let mut w = DMat3::IDENTITY;
    let mut rho = targets.to_vec();
    let mut fitted = false;
    loop {
        let active = &order[..count];
        let tt: f64 = active.iter().map(|&i| sources[i].length_squared()).sum();
        for _round in 0..ROUNDS {
            if fitted {
                for &i in active {
                    rho[i] = unwrap(targets[i], w * sources[i] * u);
                }
            }
            let m = active
                .iter()
                .fold(DMat3::ZERO, |m, &i| m + outer(rho[i], sources[i]));
            w = procrustes(m * u.signum());
            u = active
                .iter()
                .map(|&i| (w * sources[i]).dot(rho[i]))
                .sum::<f64>()
                / tt;
            fitted = true;
        }
        if count == n {
            return Some((u, w));
        }
        count = (2 * count).min(n);
    }
}

/// Of ρ and its images across the branch cut (ρ ∓ 2π ρ/|ρ|), the one nearest `prediction`.
fn unwrap(rho: DVec3, prediction: DVec3) -> DVec3 {
    let len = rho.length();
    if len < 1e-12 {
        return rho;
    }
    let axis = rho / len;
    [rho, rho - axis * (2.0 * PI), rho + axis * (2.0 * PI)]
        .into_iter()
        .min_by(|a, b| {
            (*a - prediction)
                .length_squared()
                .total_cmp(&(*b - prediction).length_squared())
        })
        .unwrap_or(rho)
}

fn outer(a: DVec3, b: DVec3) -> DMat3 {
    DMat3::from_cols(a * b.x, a * b.y, a * b.z)
}

/// Fits the best predictor of `targets` (one rotation per training pose) over `candidates` for
/// the first bone and `candidates` minus the first for the second, selecting by world geodesic
/// error (frame-independent). None if no candidate bone moves.
pub fn fit(
    targets: &[DMat3],
    feats: &[&PoseFeatures],
    parents: &[Option<usize>],
    candidates: &[usize],
) -> Option<RotationPredictor> {
    let mut best: Option<(f64, RotationPredictor)> = None;
    let sources = |b: usize| feats.iter().map(|f| f.theta[b]).collect::<Vec<DVec3>>();
    for &b in candidates {
        let local: Vec<DVec3> = targets
            .iter()
            .zip(feats)
            .map(|(r, f)| log_rotation(f.parent_q(parents, b).transpose() * *r))
            .collect();
        let theta = sources(b);
        for sign in [1.0, -1.0] {
            if let Some((u, w)) = fit_term(&local, &theta, sign) {
                let p = RotationPredictor {
                    first: BoneTerm { bone: b, u, w },
                    second: None,
                };
                let e = p.error(targets, feats, parents);
                if best.as_ref().is_none_or(|(be, _)| e < *be) {
                    best = Some((e, p));
                }
            }
        }
    }
    let (error, mut predictor) = best?;
    // Second bone: the residual R₁ᵀ R fitted to another nearby bone's joint rotation.
    let residual: Vec<DVec3> = targets
        .iter()
        .zip(feats)
        .map(|(r, f)| log_rotation(predictor.predict(f, parents).transpose() * *r))
        .collect();
    let mut best_second: Option<(f64, BoneTerm)> = None;
    for &b in candidates.iter().filter(|&&b| b != predictor.first.bone) {
        let theta = sources(b);
        for sign in [1.0, -1.0] {
            if let Some((u, w)) = fit_term(&residual, &theta, sign) {
                let term = BoneTerm { bone: b, u, w };
                let e = RotationPredictor {
                    second: Some(term),
                    ..predictor
                }
                .error(targets, feats, parents);
                if best_second.as_ref().is_none_or(|(be, _)| e < *be) {
                    best_second = Some((e, term));
                }
            }
        }
    }
    if let Some((e, term)) = best_second {
        if e < (1.0 - SECOND_BONE_GAIN) * error {
            predictor.second = Some(term);
        }
    }
    Some(predictor)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A synthetic sequence from known (u, W) is recovered, for u < 0 and angles past π.
    #[test]
    fn recovers_known_parameters_including_negative_u_and_angles_past_pi() {
        let w_true = exp_rotation(DVec3::new(0.3, -0.8, 0.5));
        let mut wrapped = 0;
        for &u_true in &[1.7, -0.8, 2.5, -1.9] {
            let sources: Vec<DVec3> = (0..12)
                .map(|i| {
                    let t = i as f64 / 11.0;
                    // Directions span 3-D: sources in a plane would let W' = W·R_π(normal) and −u
                    // fit exactly as well (W'θ = −Wθ), and (u, W) would not be identifiable.
                    DVec3::new(0.2 + t, 0.5 - 0.3 * t, 0.4 * t * t).normalize() * (0.1 + 2.0 * t)
                })
                .collect();
            // Targets through log (angles wrapped into [0, π]), as the data would give them.
            let targets: Vec<DVec3> = sources
                .iter()
                .map(|&t| log_rotation(exp_rotation(w_true * t * u_true)))
                .collect();
            // The true angle |u θ| passes π: the logs wrapped around the branch cut.
            if sources
                .iter()
                .any(|t| (t.length() * u_true).abs() > PI + 0.1)
            {
                wrapped += 1;
            }
            let fits: Vec<(f64, DMat3)> = [1.0, -1.0]
                .iter()
                .filter_map(|&s| fit_term(&targets, &sources, s))
                .collect();
            let best = fits
                .iter()
                .min_by(|a, b| {
                    let err = |(u, w): &(f64, DMat3)| -> f64 {
                        sources
                            .iter()
                            .zip(&targets)
                            .map(|(t, r)| {
                                rotation_angle(exp_rotation(*w * *t * *u), exp_rotation(*r)).powi(2)
                            })
                            .sum()
                    };
                    err(a).total_cmp(&err(b))
                })
                .expect("a fit");
            assert!((best.0 - u_true).abs() < 1e-9, "u {} vs {u_true}", best.0);
            assert!(
                (best.1 - w_true)
                    .to_cols_array()
                    .iter()
                    .all(|x| x.abs() < 1e-9),
                "W for u = {u_true}"
            );
        }
        assert!(wrapped >= 2, "only {wrapped} sequences pass π");
    }
}
