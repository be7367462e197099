//! Proxy correctives (docs/method.md §21): each proxy's transform is corrected, in its own rest
//! frame, by an affine map of the rotations of the joints near its vertices,
//! `T'_e(q) = T_e(q) (I + E_e(q))` with `E_e = Σ_f x_f(q) G_ef` (G_ef: 3 x 4). The palette stays
//! P + J matrices and the skinning is unchanged: what a muscle bulge or a sag needs beyond the
//! key predictors (each sees one joint and its parent) is paid once per proxy and character, not
//! per vertex. Letters: P proxies, J joints, D_e drivers of proxy e, C kernel centres, n poses.
//!
//! 1. **Targets.** Per training pose, the proxy transforms T* that fit the mesh best with the
//!    trained weights ([`Reduced::best_transforms`]) and the predicted T: the correction that
//!    makes T exact is `E* = T⁻¹ T* − I`, in T's rest frame, so it does not follow the heading.
//!    Optionally T* is anchored to T (a ridge μ toward it): where proxies share vertices, the
//!    plain least squares leaves directions the mesh barely determines, and fills them with
//!    per-pose noise that no function of the pose fits.
//! 2. **Features** of driver b, zero at rest (so the rest pose stays exact): φ_b = vec(R_b − I)
//!    (as [`corrective::features`]), and with kernels, per training pose c,
//!    `exp(−|φ_b − φ_b(q_c)|² / w_b) − exp(−|φ_b(q_c)|² / w_b)` (pose-space RBFs as in Lewis et
//!    al.'s PSD, per joint, w_b twice the mean |φ_b|² over the training poses): a corrective driven by a
//!    clamped ramp of an angle is not linear in the rotation. Offered gravity (an up u,
//!    `TrainOptions::up`), also `γ_b = rot(Q_b)ᵀ u − u` ([`rrskin::predict::gravity_features`]):
//!    a joint rotation is relative to its parent and cannot tell sagging from not sagging,
//!    which depends on the whole chain above the bone. The drivers of proxy e are the
//!    bones carrying at least [`SHARE`] of its vertices' SSD weight, and their children (a muscle
//!    bulges with the joint below it).
//! 3. **Ridge regression per proxy**, 12 outputs from F_e features, λ times the proxy's mean
//!    Gram diagonal. The anchor μ ([`ANCHORS`]), the basis (linear, or linear and kernels),
//!    gravity and λ are chosen together by k-fold cross-validation on the training poses,
//!    scored by the pose-relative vertex error of §18 and its one-standard-error rule
//!    ([`crate::train::cross_validate`]), in the order without gravity first (so that it is
//!    taken only where it wins clearly), unanchored first, the simpler basis and the stronger
//!    ridge first.
//! 4. **Ranges.** Past the poses it was fitted on, a linear map extrapolates: right for a
//!    deformer that keeps deforming (a smoothing), wrong for one that saturates (a corrective
//!    shape driven by a clamped ramp of an angle, which rigs are full of), and an animation
//!    reaches past the range-of-motion poses in a few joints at a time. The fit may clamp each
//!    driver's φ_b and γ_b into their box over the fitted poses (and 0) before its features are
//!    computed: a second cross-validation, of the chosen fit against it clamped, decides, in
//!    that order, on the held-out poses that fall past a fold's ranges.

use crate::linalg::{mirror_upper, DenseCholesky};
use crate::set::{Affine, ExampleSet};
use crate::skinning::lbs::Skinning;
use crate::train::budget::{ee_of_score, CostBudget, Ledger, Priced};
use crate::train::corrective;
use crate::train::cross_validate::{cross_validate, Fold, Folds, Score, Validated};
use crate::train::pose_scale;
use crate::train::reduce::c1c2::Reduced;
use crate::train::rotreg::PoseFeatures;
use crate::train::TrainOptions;
use glam::{DMat3, DVec3};
use rrskin::FeatureRange;

/// The ridges tried per basis, most regularised first.
pub const RIDGES: [f64; 8] = [1000.0, 100.0, 10.0, 1.0, 0.1, 0.01, 1e-3, 1e-4];

/// A bone drives a proxy when it carries this share of the proxy's vertices' SSD weight.
pub const SHARE: f64 = 0.1;

/// The anchors tried for the targets (μ of [`Reduced::best_transforms`], relative to its
/// normal matrix's mean diagonal), unanchored first.
pub const ANCHORS: [f64; 3] = [0.0, 1e-3, 1e-2];

/// Below this |det M| a predicted proxy transform is taken as singular: no target there.
const SINGULAR: f64 = 1e-9;

/// The features every proxy draws from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Basis {
    /// φ_b of each driver.
    Linear,
    /// φ_b and one kernel per training pose.
    Kernels,
}

/// The fitted corrections, in f64, ready for [`rrskin::model::ProxyCorrectives`].
#[derive(Debug, Clone, PartialEq)]
pub struct ProxyCorrectives {
    /// The model's up u where each driver's features include γ_b.
    pub up: Option<DVec3>,
    /// C x J kernel centres φ_b(q_c) (empty for [`Basis::Linear`]).
    pub centres: Vec<Vec<[f64; 9]>>,
    /// J kernel widths w_b (empty for [`Basis::Linear`]).
    pub widths: Vec<f64>,
    /// J feature ranges: the box of the fitted poses' φ_b and γ_b (and 0), which a pose's are
    /// clamped into; empty: not clamped.
    pub ranges: Vec<FeatureRange>,
    pub proxies: Vec<Corrected>,
}

/// One corrected proxy.
#[derive(Debug, Clone, PartialEq)]
pub struct Corrected {
    pub proxy: usize,
    /// D_e driver joints, ascending.
    pub drivers: Vec<usize>,
    /// F_e x 12, row-major: feature f's G_ef as the rows of [A | b].
    pub map: Vec<f64>,
}

/// One setting the cross-validation of [`fit`] scores.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Candidate {
    /// μ of the targets' anchor to the predicted proxies ([`ANCHORS`]; 0: unanchored).
    pub anchor: f64,
    pub basis: Basis,
    /// Whether each driver's features include its gravity features γ_b.
    pub gravity: bool,
    /// λ ([`RIDGES`]).
    pub ridge: f64,
    /// Whether each driver's φ_b and γ_b are clamped into their range over the poses fitted.
    pub clamped: bool,
}

/// What [`fit`] chose: the score (mean, standard error) of the uncorrected proxies, every
/// candidate's score in the order considered (the grid's, then the chosen one clamped, scored
/// against it), and the one kept (None where nothing beats no correction).
#[derive(Debug, Clone, PartialEq)]
pub struct Fit {
    pub uncorrected: Score,
    pub candidates: Vec<(Candidate, Score)>,
    pub chosen: Option<Candidate>,
    pub correctives: Option<ProxyCorrectives>,
}

impl Fit {
    /// EE (%) of the uncorrected model and of the chosen candidate (None: none chosen) over the
    /// training folds.
    pub fn ee(&self) -> (f64, Option<f64>) {
        let chosen = (self.candidates.iter())
            .find(|(c, _)| Some(*c) == self.chosen)
            .map(|(_, (score, _))| ee_of_score(*score));
        (ee_of_score(self.uncorrected.0), chosen)
    }

    /// `model` (whose proxies are `what`, as the report names them) with these correctives,
    /// and its price, where the cost budget admits it; else `model` as it is and its price, the
    /// correctives noted as refused in `ledger` and cleared from the fit.
    pub fn apply_within(
        &mut self,
        model: rrskin::Model,
        budget: &CostBudget,
        ledger: &Ledger,
        what: &str,
    ) -> rrskin::Result<(rrskin::Model, Priced)> {
        if let Some(c) = &self.correctives {
            let corrected = rrskin::Model::new(rrskin::ModelParts {
                proxy_correctives: Some(c.to_runtime()),
                ..model.parts().clone()
            })?;
            let priced = Priced::of(&corrected);
            if budget.admits(&priced) {
                return Ok((corrected, priced));
            }
            let (uncorrected, ee) = self.ee();
            let ee = ee.map(|ee| (ee, uncorrected));
            ledger.refuse(budget, format!("proxy correctives on {what}"), priced, ee);
            (self.chosen, self.correctives) = (None, None);
        }
        let priced = Priced::of(&model);
        Ok((model, priced))
    }
}

impl ProxyCorrectives {
    /// The basis over the poses `centres` (indices into `poses`), with γ_b where `up` is given,
    /// clamped into the poses' ranges if `clamped`.
    fn basis(
        basis: Basis,
        up: Option<DVec3>,
        clamped: bool,
        poses: &[JointFeatures],
        centres: &[usize],
    ) -> ProxyCorrectives {
        let fitted_ranges = match clamped {
            true => ranges(poses, centres, up.is_some()),
            false => Vec::new(),
        };
        let phi = |i: usize| &poses[i].phi;
        let (centres, widths) = match basis {
            Basis::Linear => (Vec::new(), Vec::new()),
            Basis::Kernels => {
                // One centre per pose, at most MAX_PROXY_KERNELS of them evenly spaced.
                let count = centres.len().min(rrskin::model::MAX_PROXY_KERNELS);
                let c: Vec<Vec<[f64; 9]>> = (0..count)
                    .map(|k| phi(centres[k * centres.len() / count]).clone())
                    .collect();
                let joints = poses.first().map_or(0, |x| x.phi.len());
                let widths = (0..joints)
                    .map(|b| {
                        let m = centres.iter().map(|&i| squared(&phi(i)[b])).sum::<f64>()
                            / centres.len() as f64;
                        2.0 * m.max(1e-12)
                    })
                    .collect();
                (c, widths)
            }
        };
        ProxyCorrectives {
            ranges: fitted_ranges,
            up,
            centres,
            widths,
            proxies: Vec::new(),
        }
    }

    /// The features of one driver: 9 φ_b, 3 γ_b where the model has an up, C kernels.
    fn features_per_driver(&self) -> usize {
        9 + 3 * usize::from(self.up.is_some()) + self.centres.len()
    }

    /// The features of `drivers` in the pose `x` (its φ_b and γ_b, clamped into their ranges
    /// where there are ranges).
    fn features(&self, drivers: &[usize], x: &JointFeatures, out: &mut Vec<f64>) {
        out.clear();
        for &b in drivers {
            let (mut phi, mut gamma) = (x.phi[b], x.gamma.get(b).copied().unwrap_or_default());
            if let Some(r) = self.ranges.get(b) {
                r.clamp(&mut phi, 0);
                r.clamp(&mut gamma, 9);
            }
            out.extend(phi);
            if self.up.is_some() {
                out.extend(gamma);
            }
            for z in &self.centres {
                out.push(rrskin::predict::kernel_feature(&phi, &z[b], self.widths[b]));
            }
        }
    }

    /// Applies the corrections to `palette`, the P predicted proxies of the pose `bones` whose
    /// joints' φ_b are `phi` ([`corrective::features`]).
    pub fn correct(&self, palette: &mut [Affine], phi: &[[f64; 9]], bones: &[Affine]) {
        let gamma = self.up.map_or_else(Vec::new, |up| gravity(bones, up));
        let x = JointFeatures {
            phi: phi.to_vec(),
            gamma,
        };
        self.correct_with(palette, &x);
    }

    /// [`ProxyCorrectives::correct`] of a pose with features `x`.
    fn correct_with(&self, palette: &mut [Affine], x: &JointFeatures) {
        let mut f = Vec::new();
        for c in &self.proxies {
            self.features(&c.drivers, x, &mut f);
            let x = &f;
            let mut e = [0.0; 12];
            for (x, g) in x.iter().zip(c.map.chunks_exact(12)) {
                for (e, g) in e.iter_mut().zip(g) {
                    *e += x * g;
                }
            }
            palette[c.proxy] = corrected(&palette[c.proxy], &e);
        }
    }

    /// For the runtime model.
    pub fn to_runtime(&self) -> rrskin::model::ProxyCorrectives {
        let f32s = |x: &[f64; 9]| x.map(|v| v as f32);
        let mut offsets = vec![0u32];
        for c in &self.proxies {
            offsets.push(offsets[offsets.len() - 1] + c.drivers.len() as u32);
        }
        rrskin::model::ProxyCorrectives {
            linear: true,
            up: self.up.map(|u| u.as_vec3().to_array()),
            centres: self.centres.iter().flatten().map(f32s).collect(),
            widths: self.widths.iter().map(|&w| w as f32).collect(),
            ranges: self.ranges.clone(),
            proxies: self.proxies.iter().map(|c| c.proxy as u32).collect(),
            driver_offsets: offsets,
            drivers: (self.proxies.iter())
                .flat_map(|c| c.drivers.iter().map(|&b| b as u32))
                .collect(),
            maps: (self.proxies.iter())
                .flat_map(|c| c.map.iter().map(|&g| g as f32))
                .collect(),
        }
    }
}

/// The range of each joint's φ_b and γ_b (zero without `gravity`) over the poses `fitted`, and
/// 0 (the rest pose), widened to f32 so that every fitted pose lies within it as stored.
fn ranges(poses: &[JointFeatures], fitted: &[usize], gravity: bool) -> Vec<FeatureRange> {
    let joints = poses.first().map_or(0, |x| x.phi.len());
    (0..joints)
        .map(|b| {
            let mut r = FeatureRange {
                lower: [0.0; 12],
                upper: [0.0; 12],
            };
            for &i in fitted {
                let gamma = if gravity { poses[i].gamma[b] } else { [0.0; 3] };
                for (k, &x) in poses[i].phi[b].iter().chain(&gamma).enumerate() {
                    r.lower[k] = r.lower[k].min(f32_below(x));
                    r.upper[k] = r.upper[k].max(f32_above(x));
                }
            }
            r
        })
        .collect()
}

/// An f32 at most x (x rounded, less an ulp where rounding went up).
fn f32_below(x: f64) -> f32 {
    let y = x as f32;
    match f64::from(y) > x {
        true => y - (y.abs() * f32::EPSILON).max(f32::MIN_POSITIVE),
        false => y,
    }
}

/// An f32 at least x.
fn f32_above(x: f64) -> f32 {
    -f32_below(-x)
}

fn squared(x: &[f64; 9]) -> f64 {
    x.iter().map(|v| v * v).sum()
}

/// `T (I + E)`, E as the rows of [A | b]: `[M (I + A) | t + M b]`.
fn corrected(t: &Affine, e: &[f64; 12]) -> Affine {
    let a = DMat3::from_cols_array(&[e[0], e[4], e[8], e[1], e[5], e[9], e[2], e[6], e[10]]);
    Affine {
        q: t.q * (DMat3::IDENTITY + a),
        d: t.d + t.q * DVec3::new(e[3], e[7], e[11]),
    }
}

/// `T⁻¹ T* − I` as the rows of [A | b], None where T is singular.
fn target(t: &Affine, best: &Affine) -> Option<[f64; 12]> {
    if t.q.determinant().abs() <= SINGULAR {
        return None;
    }
    let inv = t.q.inverse();
    let a = inv * best.q - DMat3::IDENTITY;
    let b = inv * (best.d - t.d);
    Some(std::array::from_fn(|k| match k % 4 {
        3 => b[k / 4],
        c => a.row(k / 4)[c],
    }))
}

/// The drivers of each proxy (module docs, step 2).
pub fn drivers(set: &ExampleSet, ssd: &Skinning, reduced: &Reduced) -> Vec<Vec<usize>> {
    let children = set.children();
    let active = set.active_bones();
    let mut mass = vec![vec![0.0; set.bone_count()]; reduced.proxies];
    for (a, inf) in reduced.skin.iter().enumerate() {
        for &(e, w) in inf.iter().filter(|x| x.0 < reduced.proxies) {
            for &(b, v) in &ssd.influences[a] {
                mass[e][b] += w * v;
            }
        }
    }
    mass.iter()
        .map(|m| {
            let total: f64 = m.iter().sum();
            let mut d: Vec<usize> = (0..m.len())
                .filter(|&b| total > 0.0 && m[b] >= SHARE * total)
                .flat_map(|b| std::iter::once(b).chain(children[b].iter().copied()))
                .filter(|&b| set.parents[b].is_some() && active[b])
                .collect();
            d.sort_unstable();
            d.dedup();
            d
        })
        .collect()
}

/// One pose's features per joint.
struct JointFeatures {
    phi: Vec<[f64; 9]>,
    /// γ_b (zero where gravity is not offered).
    gamma: Vec<[f64; 3]>,
}

/// The training poses as the fit sees them (in `train` order).
struct Poses {
    predicted: Vec<Vec<Affine>>,
    /// Per anchor ([`ANCHORS`]), pose and proxy: E*.
    targets: Vec<Vec<Vec<Option<[f64; 12]>>>>,
    features: Vec<JointFeatures>,
}

impl Poses {
    /// The poses `train` as the fit of `reduced`'s correctives sees them: the predicted
    /// proxies, the targets per anchor of `anchors`, the features with γ_b about `up`.
    fn of(
        set: &ExampleSet,
        feats: &[PoseFeatures],
        reduced: &Reduced,
        train: &[usize],
        anchors: &[f64],
        up: DVec3,
    ) -> Poses {
        let predicted: Vec<Vec<Affine>> = (train.iter())
            .map(|&i| reduced.predict_proxies(set, &feats[i], &set.poses[i].bones))
            .collect();
        let targets = (anchors.iter())
            .map(|&mu| {
                let anchor = (mu > 0.0).then_some((predicted.as_slice(), mu));
                let best = reduced.best_transforms(set, train, anchor);
                (predicted.iter().zip(&best))
                    .map(|(p, best)| p.iter().zip(best).map(|(t, b)| target(t, b)).collect())
                    .collect()
            })
            .collect();
        let features = (train.iter())
            .map(|&i| {
                let phi = corrective::features(set, &feats[i]);
                let gamma = gravity(&set.poses[i].bones, up);
                JointFeatures { phi, gamma }
            })
            .collect();
        Poses {
            predicted,
            targets,
            features,
        }
    }
}

/// γ_b = rot(Q_b)ᵀ u − u of every joint of `bones` (the rig upright in its frame).
fn gravity(bones: &[Affine], up: DVec3) -> Vec<[f64; 3]> {
    (bones.iter())
        .map(|t| (t.q.transpose() * up - up).to_array())
        .collect()
}

/// Ridge regression of E* (the targets of `targets`, an index into [`ANCHORS`]) per proxy over
/// the poses `fit` (indices into `poses`).
fn regress(
    targets: usize,
    candidate: &Candidate,
    up: DVec3,
    drivers: &[Vec<usize>],
    poses: &Poses,
    fit: &[usize],
) -> ProxyCorrectives {
    Normal::of(&[targets], candidate, up, drivers, poses, fit).solve(0, candidate.ridge)
}

/// The normal equations of [`regress`] before the ridge, which is all a candidate's ridge and
/// anchor change: one Gram matrix per corrected proxy for the basis, and the right-hand side
/// of each set of targets. A search builds them once per basis and gravity, and solves them
/// per ridge and anchor (8 x 3 solves of one accumulation over the poses).
struct Normal {
    /// The basis, with no proxy yet.
    basis: ProxyCorrectives,
    /// Per proxy with drivers.
    proxies: Vec<ProxyNormal>,
}

/// One corrected proxy's normal equations.
struct ProxyNormal {
    proxy: usize,
    drivers: Vec<usize>,
    /// F: its drivers' features.
    features: usize,
    /// F x F, row-major.
    gram: Vec<f64>,
    /// Per set of targets, F x 12.
    rhs: Vec<Vec<f64>>,
}

impl Normal {
    /// The normal equations of the targets `targets` (indices into [`ANCHORS`]) with
    /// `candidate`'s basis, gravity and clamping, over the poses `fit`.
    fn of(
        targets: &[usize],
        candidate: &Candidate,
        up: DVec3,
        drivers: &[Vec<usize>],
        poses: &Poses,
        fit: &[usize],
    ) -> Normal {
        let up = candidate.gravity.then_some(up);
        let basis =
            ProxyCorrectives::basis(candidate.basis, up, candidate.clamped, &poses.features, fit);
        let mut x = Vec::new();
        let proxies = (drivers.iter().enumerate())
            .filter(|(_, d)| !d.is_empty())
            .map(|(e, d)| {
                let f = d.len() * basis.features_per_driver();
                let mut gram = vec![0.0; f * f];
                let mut rhs = vec![vec![0.0; f * 12]; targets.len()];
                for &i in fit {
                    // Every anchor's targets exist where the unanchored ones do.
                    if poses.targets[targets[0]][i][e].is_none() {
                        continue;
                    }
                    basis.features(d, &poses.features[i], &mut x);
                    // The upper triangle; the lower mirrors it below.
                    for p in 0..f {
                        for q in p..f {
                            gram[p * f + q] += x[p] * x[q];
                        }
                    }
                    for (t, rhs) in targets.iter().zip(&mut rhs) {
                        let Some(target) = poses.targets[*t][i][e] else {
                            continue;
                        };
                        for p in 0..f {
                            for c in 0..12 {
                                rhs[p * 12 + c] += x[p] * target[c];
                            }
                        }
                    }
                }
                mirror_upper(&mut gram, f);
                ProxyNormal {
                    proxy: e,
                    drivers: d.clone(),
                    features: f,
                    gram,
                    rhs,
                }
            })
            .collect();
        Normal { basis, proxies }
    }

    /// The correctives of the `t`-th set of targets with ridge λ = `ridge` (times the Gram
    /// matrix's mean diagonal).
    fn solve(&self, t: usize, ridge: f64) -> ProxyCorrectives {
        self.solve_factored(t, &self.factors(ridge))
    }

    /// Per proxy, the Cholesky factor of its Gram matrix with ridge λ = `ridge` (times its mean
    /// diagonal): what the sets of targets of one ridge share.
    fn factors(&self, ridge: f64) -> Vec<DenseCholesky> {
        (self.proxies.iter())
            .map(|n| {
                let f = n.features;
                let mean = (0..f).map(|p| n.gram[p * f + p]).sum::<f64>() / f as f64;
                let mut gram = n.gram.clone();
                for p in 0..f {
                    gram[p * f + p] += ridge * mean.max(f64::MIN_POSITIVE);
                }
                DenseCholesky::new(&gram, f)
            })
            .collect()
    }

    /// The correctives of the `t`-th set of targets, each proxy's equations factored
    /// ([`Normal::factors`]).
    fn solve_factored(&self, t: usize, factors: &[DenseCholesky]) -> ProxyCorrectives {
        let mut out = self.basis.clone();
        for (n, factor) in self.proxies.iter().zip(factors) {
            let mut map = n.rhs[t].clone();
            factor.solve_columns(&mut map, 12);
            out.proxies.push(Corrected {
                proxy: n.proxy,
                drivers: n.drivers.clone(),
                map,
            });
        }
        out
    }
}

/// Fits the proxy correctives of `reduced` on the training poses `train`, anchor, basis (the
/// kernels only with `options.proxy_kernels`), gravity (only with `options.up`) and ridge
/// chosen by `options.folds`-fold cross-validation, then whether the features are clamped into
/// their ranges by a second one between the chosen fit as it is and clamped (the fit is the
/// same; only held-out poses past a fold's ranges differ); `rigid` normalises each held-out
/// pose's error. None is chosen where no candidate beats the uncorrected proxies.
pub fn fit(
    set: &ExampleSet,
    feats: &[PoseFeatures],
    ssd: &Skinning,
    rigid: &Skinning,
    reduced: &Reduced,
    train: &[usize],
    options: &TrainOptions,
) -> Fit {
    let Some(folds) = Folds::new(train.len(), options.folds) else {
        return Fit {
            uncorrected: (0.0, 0.0),
            candidates: Vec::new(),
            chosen: None,
            correctives: None,
        };
    };
    let drivers = drivers(set, ssd, reduced);
    let up = options.up.map_or(DVec3::ZERO, DVec3::from);
    let poses = Poses::of(set, feats, reduced, train, &ANCHORS, up);
    let normaliser = pose_scale::rigid_pose_errors(set, train, rigid);
    let grid = grid(options.proxy_kernels, options.up.is_some());
    // Held-out errors of candidate `c` with targets `a`, fitted on the fold's other poses.
    let corrected = |&(a, c): &(usize, Candidate), fold: &Fold| -> Vec<f64> {
        let fitted = regress(a, &c, up, &drivers, &poses, &fold.inner);
        (fold.held.iter())
            .map(|&k| held_error(set, train, reduced, &poses, k, Some(&fitted)))
            .collect()
    };
    let anchors: Vec<usize> = (0..ANCHORS.len()).collect();
    let validated = cross_validate(&folds, &normaliser, 1 + grid.len(), 0.0, |fold| {
        let uncorrected = (fold.held.iter())
            .map(|&k| held_error(set, train, reduced, &poses, k, None))
            .collect();
        let mut rows = vec![uncorrected];
        // One set of normal equations per basis and gravity, factored per ridge and solved
        // per anchor.
        let mut normals: Vec<((Basis, bool), Normal)> = Vec::new();
        let mut factored: Vec<((usize, u64), Vec<DenseCholesky>)> = Vec::new();
        for &(a, c) in &grid {
            let key = (c.basis, c.gravity);
            let at = match normals.iter().position(|(k, _)| *k == key) {
                Some(at) => at,
                None => {
                    let built = Normal::of(&anchors, &c, up, &drivers, &poses, &fold.inner);
                    normals.push((key, built));
                    normals.len() - 1
                }
            };
            let key = (at, c.ridge.to_bits());
            let f = match factored.iter().position(|(k, _)| *k == key) {
                Some(f) => f,
                None => {
                    factored.push((key, normals[at].1.factors(c.ridge)));
                    factored.len() - 1
                }
            };
            let fitted = normals[at].1.solve_factored(a, &factored[f].1);
            rows.push(
                (fold.held.iter())
                    .map(|&k| held_error(set, train, reduced, &poses, k, Some(&fitted)))
                    .collect(),
            );
        }
        rows
    });
    let mut candidates: Vec<(Candidate, Score)> = grid
        .iter()
        .zip(&validated.scores[1..])
        .map(|(&(_, c), &s)| (c, s))
        .collect();
    let mut chosen = validated.chosen.checked_sub(1).map(|c| grid[c]);
    // How the chosen fit extrapolates: clamped into the fitted poses' ranges only where the
    // held-out poses past a fold's ranges say so clearly. Only the clamped fit's errors are
    // new; the uncorrected proxies' and the chosen fit's are the search's.
    if let Some((a, c)) = chosen {
        let clamped = (a, Candidate { clamped: true, ..c });
        let mut held = cross_validate(&folds, &normaliser, 1, 0.0, |fold| {
            vec![corrected(&clamped, fold)]
        });
        let relative = &validated.relative;
        let rows = vec![
            relative[0].clone(),
            relative[validated.chosen].clone(),
            held.relative.swap_remove(0),
        ];
        let extrapolation = Validated::of(rows, 0.0);
        candidates.push((clamped.1, extrapolation.scores[2]));
        if extrapolation.chosen == 2 {
            chosen = Some(clamped);
        }
    }
    let all: Vec<usize> = (0..train.len()).collect();
    Fit {
        uncorrected: validated.scores[0],
        candidates,
        chosen: chosen.map(|(_, c)| c),
        correctives: chosen
            .map(|(a, c)| regress(a, &c, up, &drivers, &poses, &all))
            .filter(|c| !c.proxies.is_empty()),
    }
}

/// The proxy correctives of `reduced` fitted on the poses `fit` with `candidate` (its features
/// seeing gravity about `up`), without a search: how a cross-validation of the kinds of model
/// corrects each fold's model with the candidate [`fit`] chose for that kind on all training
/// poses, so that it compares them as they ship (docs/method.md §23). None where no proxy has
/// drivers.
pub fn fit_candidate(
    set: &ExampleSet,
    feats: &[PoseFeatures],
    ssd: &Skinning,
    reduced: &Reduced,
    fit: &[usize],
    candidate: &Candidate,
    up: Option<[f64; 3]>,
) -> Option<ProxyCorrectives> {
    let drivers = drivers(set, ssd, reduced);
    let up = up.map_or(DVec3::ZERO, DVec3::from);
    let poses = Poses::of(set, feats, reduced, fit, &[candidate.anchor], up);
    let all: Vec<usize> = (0..fit.len()).collect();
    let fitted = regress(0, candidate, up, &drivers, &poses, &all);
    (!fitted.proxies.is_empty()).then_some(fitted)
}

/// The candidates after the uncorrected proxies, in the order considered: without gravity, then
/// with it (only with `gravity`), each per anchor (an index into [`ANCHORS`], unanchored first),
/// per basis (the kernels only with `kernels`), per ridge.
fn grid(kernels: bool, gravity: bool) -> Vec<(usize, Candidate)> {
    let bases: &[Basis] = match kernels {
        true => &[Basis::Linear, Basis::Kernels],
        false => &[Basis::Linear],
    };
    let gravities: &[bool] = match gravity {
        true => &[false, true],
        false => &[false],
    };
    let per_anchor = |gravity: bool| {
        (ANCHORS.iter().enumerate()).flat_map(move |(a, &anchor)| {
            (bases.iter()).flat_map(move |&basis| {
                RIDGES.map(|ridge| {
                    let c = Candidate {
                        anchor,
                        basis,
                        gravity,
                        ridge,
                        clamped: false,
                    };
                    (a, c)
                })
            })
        })
    };
    gravities.iter().flat_map(|&g| per_anchor(g)).collect()
}

/// Training pose k's (a position in `train`) squared vertex error with the proxies predicted
/// and, given `c`, corrected.
fn held_error(
    set: &ExampleSet,
    train: &[usize],
    reduced: &Reduced,
    poses: &Poses,
    k: usize,
    c: Option<&ProxyCorrectives>,
) -> f64 {
    let pose = &set.poses[train[k]];
    let mut palette = poses.predicted[k].clone();
    if let Some(c) = c {
        c.correct_with(&mut palette, &poses.features[k]);
    }
    let y = reduced.skin_with(set, &palette, &pose.bones);
    (y.iter().zip(&pose.vertices))
        .map(|(a, b)| (*a - *b).length_squared())
        .sum()
}
