//! Proxy correctives (docs/method.md §21): each proxy's transform is corrected, in its own rest
//! frame, by an affine map linear in the rotations of the joints near its vertices:
//! `T'_e(q) = T_e(q) (I + E_e(q))`, `E_e(q) = Σ_f φ_f(q) G_ef` (G_ef: 3 x 4, bottom row 0).
//! The palette stays P + J matrices and the skinning unchanged: what a muscle bulge or a sag
//! needs beyond the key predictors (which see one joint and its parent) is paid once per proxy on
//! the CPU, not per vertex. Letters: P proxies, D_e drivers of proxy e, n training poses.
//!
//! 1. **Targets.** Per training pose, the proxy transforms that fit the mesh best with the
//!    trained weights (T*, least squares per pose), and the predicted ones T: the correction that
//!    would make them exact is `E* = T⁻¹ T* − I`, in T's rest frame so that it does not depend
//!    on the character's heading.
//! 2. **Features** φ_b = vec(R_b − I) of the drivers (as [`corrective::features`]); the drivers
//!    of proxy e are those of its vertices ([`corrective::drivers`]: their SSD bones and their
//!    children), zero at rest so that the rest pose stays exact.
//! 3. **Ridge regression per proxy**, 12 outputs from 9 D_e features; one λ for every proxy
//!    (times each proxy's mean Gram diagonal), chosen by k-fold cross-validation on the training
//!    poses with the pose-relative vertex error and the one-standard-error rule of §18.

use crate::import::example_set::{Bone, ExampleSet};
use crate::linalg::DenseCholesky;
use crate::train::corrective;
use crate::train::pose_scale;
use crate::train::reduce::c1c2::Reduced;
use crate::train::rotreg::PoseFeatures;
use crate::train::ssd::Skinning;
use glam::{DMat3, DVec3, DVec4};

/// The ridges tried, most regularised first (after none).
pub const RIDGES: [f64; 5] = [10.0, 1.0, 0.1, 0.01, 0.001];

/// Below this |det T| a proxy's predicted transform is taken as singular: no target there.
const SINGULAR: f64 = 1e-9;

/// The fitted correction of one proxy.
#[derive(Debug, Clone, PartialEq)]
pub struct ProxyCorrective {
    pub proxy: usize,
    /// D_e driver joints, ascending.
    pub drivers: Vec<usize>,
    /// 9 D_e x 12, row-major: feature f's G_ef, rows of [A | b] stacked.
    pub map: Vec<f64>,
}

/// What [`fit`] chose: the ridge (None: no correction) and every candidate's score, in the
/// order considered (none first, then [`RIDGES`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Fit {
    pub ridge: Option<f64>,
    pub scores: Vec<(f64, f64)>,
    pub correctives: Vec<ProxyCorrective>,
}

/// The training poses as the fit sees them.
struct Poses {
    /// Per pose: the predicted proxy transforms.
    predicted: Vec<Vec<Bone>>,
    /// Per pose and proxy: E* (12, rows of [A | b]), None where T is singular.
    targets: Vec<Vec<Option<[f64; 12]>>>,
    phi: Vec<Vec<[f64; 9]>>,
}

impl ProxyCorrective {
    /// E_e(φ) applied to T: `T (I + E)`.
    pub fn apply(&self, t: &Bone, phi: &[[f64; 9]]) -> Bone {
        let mut e = [0.0; 12];
        for (i, &b) in self.drivers.iter().enumerate() {
            for (k, &x) in phi[b].iter().enumerate() {
                let row = &self.map[(9 * i + k) * 12..(9 * i + k + 1) * 12];
                for (e, g) in e.iter_mut().zip(row) {
                    *e += x * g;
                }
            }
        }
        corrected(t, &e)
    }
}

/// `T (I + E)`, E as rows of [A | b].
fn corrected(t: &Bone, e: &[f64; 12]) -> Bone {
    let a = DMat3::from_cols_array(&[
        e[0], e[4], e[8], e[1], e[5], e[9], e[2], e[6], e[10],
    ]);
    let b = DVec3::new(e[3], e[7], e[11]);
    Bone {
        q: t.q * (DMat3::IDENTITY + a),
        d: t.d + t.q * b,
    }
}

/// The drivers of each proxy: the bones carrying at least [`SHARE`] of its vertices' SSD weight
/// (weighted by the proxy's own weights), and their children; roots left out.
fn proxy_drivers(set: &ExampleSet, ssd: &Skinning, reduced: &Reduced) -> Vec<Vec<usize>> {
    let share: f64 = std::env::var("PC_SHARE").ok().and_then(|s| s.parse().ok()).unwrap_or(0.1);
    let children = set.children();
    let mut mass = vec![vec![0.0; set.bone_count()]; reduced.proxies];
    for (a, inf) in reduced.skin.iter().enumerate() {
        for &(e, w) in inf {
            if e < reduced.proxies {
                for &(b, v) in &ssd.influences[a] {
                    mass[e][b] += w * v;
                }
            }
        }
    }
    mass.iter()
        .map(|m| {
            let total: f64 = m.iter().sum();
            let mut d: Vec<usize> = (0..m.len())
                .filter(|&b| m[b] > share * total && total > 0.0)
                .flat_map(|b| std::iter::once(b).chain(children[b].iter().copied()))
                .filter(|&b| set.parents[b].is_some())
                .collect();
            d.sort_unstable();
            d.dedup();
            d
        })
        .collect()
}

fn gather(drivers: &[usize], phi: &[[f64; 9]], out: &mut Vec<f64>) {
    out.clear();
    out.extend(drivers.iter().flat_map(|&b| phi[b]));
}

/// Ridge regression of E* on φ per proxy over the poses `fit` (indices into `poses`).
fn regress(
    drivers: &[Vec<usize>],
    poses: &Poses,
    fit: &[usize],
    ridge: f64,
) -> Vec<ProxyCorrective> {
    let mut x = Vec::new();
    drivers
        .iter()
        .enumerate()
        .filter(|(_, d)| !d.is_empty())
        .map(|(e, d)| {
            let f = 9 * d.len();
            let mut gram = vec![0.0; f * f];
            let mut rhs = vec![0.0; f * 12];
            for &i in fit {
                let Some(target) = poses.targets[i][e] else {
                    continue;
                };
                gather(d, &poses.phi[i], &mut x);
                for p in 0..f {
                    for q in 0..f {
                        gram[p * f + q] += x[p] * x[q];
                    }
                    for c in 0..12 {
                        rhs[p * 12 + c] += x[p] * target[c];
                    }
                }
            }
            let mean = (0..f).map(|p| gram[p * f + p]).sum::<f64>() / f as f64;
            for p in 0..f {
                gram[p * f + p] += ridge * mean.max(f64::MIN_POSITIVE);
            }
            let factor = DenseCholesky::new(&gram, f);
            let mut map = vec![0.0; f * 12];
            for c in 0..12 {
                let mut col: Vec<f64> = (0..f).map(|p| rhs[p * 12 + c]).collect();
                factor.solve(&mut col);
                for p in 0..f {
                    map[p * 12 + c] = col[p];
                }
            }
            ProxyCorrective {
                proxy: e,
                drivers: d.clone(),
                map,
            }
        })
        .collect()
}

/// The mesh of pose i (of `poses`) with the corrections applied.
fn mesh(
    set: &ExampleSet,
    reduced: &Reduced,
    bones: &[Bone],
    predicted: &[Bone],
    phi: &[[f64; 9]],
    correctives: &[ProxyCorrective],
) -> Vec<DVec3> {
    let mut palette = predicted.to_vec();
    for c in correctives {
        palette[c.proxy] = c.apply(&predicted[c.proxy], phi);
    }
    reduced.skin_with(set, &palette, bones)
}

/// The corrected palette of one pose: `predicted` (P) with `correctives` applied.
pub fn correct(predicted: &mut [Bone], phi: &[[f64; 9]], correctives: &[ProxyCorrective]) {
    for c in correctives {
        predicted[c.proxy] = c.apply(&predicted[c.proxy], phi);
    }
}

/// Fits the proxy correctives of `reduced` on the training poses `train`, the ridge chosen by
/// `folds`-fold cross-validation; `rigid` normalises each held-out pose's error.
pub fn fit(
    set: &ExampleSet,
    feats: &[PoseFeatures],
    ssd: &Skinning,
    rigid: &Skinning,
    reduced: &Reduced,
    train: &[usize],
    folds: usize,
) -> Fit {
    let drivers = proxy_drivers(set, ssd, reduced);
    let oracle = crate::eval::diagnose::oracle_transforms(set, reduced, train);
    let mut poses = Poses {
        predicted: Vec::new(),
        targets: Vec::new(),
        phi: Vec::new(),
    };
    for (&i, best) in train.iter().zip(&oracle) {
        let d: Vec<DMat3> = reduced
            .predictors
            .iter()
            .map(|k| k.predict(&feats[i], &set.parents))
            .collect();
        let predicted = reduced.proxy_transforms(&d, &set.poses[i].bones);
        let targets = predicted
            .iter()
            .zip(best)
            .map(|(t, rows)| {
                if t.q.determinant().abs() <= SINGULAR {
                    return None;
                }
                let inv = t.q.inverse();
                let m = DMat3::from_cols(rows[0].truncate(), rows[1].truncate(), rows[2].truncate())
                    .transpose();
                let a = inv * m - DMat3::IDENTITY;
                let b = inv * (DVec3::new(rows[0].w, rows[1].w, rows[2].w) - t.d);
                let r = |k: usize| [a.row(k).x, a.row(k).y, a.row(k).z, b[k]];
                let (r0, r1, r2) = (r(0), r(1), r(2));
                Some([
                    r0[0], r0[1], r0[2], r0[3], r1[0], r1[1], r1[2], r1[3], r2[0], r2[1], r2[2],
                    r2[3],
                ])
            })
            .collect();
        poses.predicted.push(predicted);
        poses.targets.push(targets);
        poses.phi.push(corrective::features(set, &feats[i]));
    }
    let all: Vec<usize> = (0..train.len()).collect();
    let folds = folds.min(train.len());
    let mut scores = Vec::new();
    let mut ridge = None;
    if folds >= 2 {
        let normaliser = pose_scale::rigid_pose_errors(set, train, rigid);
        let held_error = |k: usize, correctives: &[ProxyCorrective]| -> f64 {
            let i = train[k];
            let y = mesh(
                set,
                reduced,
                &set.poses[i].bones,
                &poses.predicted[k],
                &poses.phi[k],
                correctives,
            );
            let e: f64 = y
                .iter()
                .zip(&set.poses[i].vertices)
                .map(|(a, b)| (*a - *b).length_squared())
                .sum();
            e / normaliser[k]
        };
        let mut relative = vec![all.iter().map(|&k| held_error(k, &[])).collect::<Vec<f64>>()];
        for &lambda in &RIDGES {
            let mut per_pose = vec![0.0; all.len()];
            for fold in 0..folds {
                let (held, kept): (Vec<usize>, Vec<usize>) =
                    all.iter().partition(|&&k| k % folds == fold);
                let c = regress(&drivers, &poses, &kept, lambda);
                for k in held {
                    per_pose[k] = held_error(k, &c);
                }
            }
            relative.push(per_pose);
        }
        scores = pose_scale::scores(&relative);
        ridge = pose_scale::first_within(&scores, 0..scores.len(), 0.0)
            .and_then(|c| c.checked_sub(1))
            .map(|c| RIDGES[c]);
    }
    let correctives = ridge.map_or(Vec::new(), |lambda| regress(&drivers, &poses, &all, lambda));
    let _ = DVec4::ZERO;
    Fit {
        ridge,
        scores,
        correctives,
    }
}
