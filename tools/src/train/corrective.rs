//! Pose-space correctives (paper §8; docs/method.md §20): rest-space morph targets whose weights
//! are linear in the joints' rotations, fitted to what the runtime model leaves on the training
//! poses. Letters: V vertices, J joints, D driver joints, N targets, n training poses.
//!
//! 1. **Residuals in rest space.** With M_a(q) the 3x3 of vertex a's blended palette matrix, a
//!    rest-space offset δ_a moves the runtime model's vertex y_a(q) to y_a(q) + M_a(q) δ_a, so
//!    pose i is met exactly by δ_a^i = M_a⁻¹ (y_a^i − y_a(q_i)).
//! 2. **Features** φ_b(q) = vec(R_b − I) (9, rows stacked), R_b = Q_pᵀ Q_b the rotation of joint b
//!    with parent p. Zero at rest, so the rest pose stays exact; both the sine (odd) and the
//!    1 − cosine (even) parts of a bend, which a bulge follows alike for either direction. Roots
//!    are not drivers: their "joint rotation" is the character's heading.
//! 3. **Local ridge regression.** Per vertex, δ_a(q) = G_a φ_{N(a)}(q) (G_a: 3 x 9|N(a)|), N(a) the
//!    vertex's SSD bones and their children (a muscle bulges with the joint below it): a vertex
//!    never follows a far joint that merely correlates with its own on the training poses.
//!    Ridge λ times the mean diagonal of the vertex's Gram matrix; vertices with one N(a) share
//!    one factorisation.
//! 4. **Reduced rank.** The fitted offsets of the training poses, X (3V x n), give the N leading
//!    left singular vectors U (the targets, N x V x 3) and the map A = Uᵀ G (N x 9D): at run time
//!    w(q) = A φ(q) and the vertex's rest position is ŷ_a + Σ_k w_k U_ka, before skinning. Each
//!    target is scaled (and its row of A divided) so that its weights span [−1, 1] over the
//!    training poses.
//!
//! λ is chosen by k-fold cross-validation over the training poses from [`RIDGES`] or none, with
//! the pose-relative score and one-standard-error rule of §18
//! ([`crate::train::cross_validate`]), the most regularised first: the residuals left on the
//! training poses are smaller than those on new poses, so a weak ridge fits noise that looks
//! like signal.

use crate::linalg::DenseCholesky;
use crate::set::ExampleSet;
use crate::skinning::lbs::Skinning;
use crate::train::cross_validate::{cross_validate, Folds, Score};
use crate::train::pose_scale;
use crate::train::rotreg::PoseFeatures;
use faer::{Mat, Side};
use glam::{DMat3, DVec3};
use std::collections::HashMap;

/// The ridges tried, most regularised first (after none).
pub const RIDGES: [f64; 4] = [10.0, 1.0, 0.1, 0.01];

/// Below this |det M_a| a vertex's blended matrix is taken as singular: no offset is fitted there.
const SINGULAR: f64 = 1e-6;

/// The fitted correctives in f64, ready for [`rrskin::model::Correctives`].
#[derive(Debug, Clone, PartialEq)]
pub struct Correctives {
    /// D driver joints, ascending.
    pub drivers: Vec<usize>,
    /// N x 9D, row-major: w = map φ, φ = [φ_b for b in drivers].
    pub map: Vec<f64>,
    /// N targets of V rest-space offsets.
    pub targets: Vec<Vec<DVec3>>,
}

/// What [`fit`] chose: the ridge (None: no correctives) and every candidate's score, in the order
/// considered (none first, then [`RIDGES`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Fit {
    pub ridge: Option<f64>,
    pub scores: Vec<Score>,
    pub correctives: Option<Correctives>,
}

impl Fit {
    /// EE (%) without correctives and with the ridge kept (None: none kept) over the training
    /// folds.
    pub fn ee(&self) -> (f64, Option<f64>) {
        let kept = (self.ridge)
            .and_then(|r| RIDGES.iter().position(|&x| x == r))
            .and_then(|i| self.scores.get(i + 1));
        let ee = |s: &Score| crate::train::budget::ee_of_score(s.0);
        (self.scores.first().map_or(f64::NAN, ee), kept.map(ee))
    }
}

/// The per-pose features φ_b of every joint (zeros for roots).
pub fn features(set: &ExampleSet, f: &PoseFeatures) -> Vec<[f64; 9]> {
    (0..set.bone_count())
        .map(|b| match set.parents[b] {
            None => [0.0; 9],
            Some(p) => (f.q[p].transpose() * f.q[b] - DMat3::IDENTITY)
                .transpose()
                .to_cols_array(),
        })
        .collect()
}

/// N(a) per vertex: its SSD bones and their children, roots and inactive bones
/// ([`ExampleSet::active_bones`]) left out, ascending.
pub fn drivers(set: &ExampleSet, ssd: &Skinning) -> Vec<Vec<usize>> {
    let children = set.children();
    let active = set.active_bones();
    ssd.influences
        .iter()
        .map(|inf| {
            let mut d: Vec<usize> = inf
                .iter()
                .filter(|&&(_, w)| w > 0.0)
                .flat_map(|&(b, _)| std::iter::once(b).chain(children[b].iter().copied()))
                .filter(|&b| set.parents[b].is_some() && active[b])
                .collect();
            d.sort_unstable();
            d.dedup();
            d
        })
        .collect()
}

/// The training poses as the fit sees them: per pose (in `poses` order) the model's vertices, the
/// rest-space residuals δ, the blended 3x3s M and the features.
pub struct Residuals {
    pub positions: Vec<Vec<DVec3>>,
    pub delta: Vec<Vec<DVec3>>,
    pub m: Vec<Vec<DMat3>>,
    pub phi: Vec<Vec<[f64; 9]>>,
}

impl Residuals {
    /// What `model` (without correctives) leaves on `poses`.
    pub fn of(
        set: &ExampleSet,
        feats: &[PoseFeatures],
        model: &rrskin::Model,
        poses: &[usize],
    ) -> rrskin::Result<Residuals> {
        let palette = rrskin::palette::Palette::new(model.clone())?;
        let mut evaluator = rrskin::cpu::CpuEvaluator::new(model);
        let v = set.vertex_count();
        let skin = palette.skin();
        let (mut pos, mut nrm) = (vec![[0.0f32; 3]; v], vec![[0.0f32; 3]; v]);
        let mut entries = vec![[0.0f32; 12]; palette.len()];
        let mut out = Residuals {
            positions: Vec::new(),
            delta: Vec::new(),
            m: Vec::new(),
            phi: Vec::new(),
        };
        for &i in poses {
            let bones: Vec<rrskin::predict::Affine> =
                set.poses[i].bones.iter().map(|b| b.to_runtime()).collect();
            evaluator.evaluate(&bones, &mut pos, &mut nrm)?;
            palette.compute(&bones, &mut entries)?;
            let m: Vec<DMat3> = (0..v)
                .map(|a| rrskin::predict::rotation_of(&skin.blended(a, &entries)))
                .collect();
            let positions: Vec<DVec3> = pos.iter().map(|p| DVec3::from(p.map(f64::from))).collect();
            let delta = (0..v)
                .map(|a| match m[a].determinant().abs() > SINGULAR {
                    true => m[a].inverse() * (set.poses[i].vertices[a] - positions[a]),
                    false => DVec3::ZERO,
                })
                .collect();
            out.positions.push(positions);
            out.delta.push(delta);
            out.m.push(m);
            out.phi.push(features(set, &feats[i]));
        }
        Ok(out)
    }
}

/// Per-vertex local regression (step 3): per vertex, 9|N(a)| rows of 3 coefficients.
struct Local<'d> {
    drivers: &'d [Vec<usize>],
    g: Vec<Vec<[f64; 3]>>,
}

fn gather(drivers: &[usize], phi: &[[f64; 9]], out: &mut Vec<f64>) {
    out.clear();
    out.extend(drivers.iter().flat_map(|&b| phi[b]));
}

impl<'d> Local<'d> {
    /// Fitted on the poses `fit` (indices into `r`).
    fn fit(drivers: &'d [Vec<usize>], r: &Residuals, fit: &[usize], ridge: f64) -> Local<'d> {
        let mut groups: HashMap<&[usize], Vec<usize>> = HashMap::new();
        for (a, d) in drivers.iter().enumerate() {
            groups.entry(d).or_default().push(a);
        }
        let mut g = vec![Vec::new(); drivers.len()];
        let mut x = Vec::new();
        for (d, members) in groups {
            let f = 9 * d.len();
            if f == 0 {
                continue;
            }
            let rows: Vec<Vec<f64>> = fit
                .iter()
                .map(|&i| {
                    gather(d, &r.phi[i], &mut x);
                    x.clone()
                })
                .collect();
            let mut gram = vec![0.0; f * f];
            for row in &rows {
                for p in 0..f {
                    for q in 0..f {
                        gram[p * f + q] += row[p] * row[q];
                    }
                }
            }
            let mean = (0..f).map(|p| gram[p * f + p]).sum::<f64>() / f as f64;
            for p in 0..f {
                gram[p * f + p] += ridge * mean.max(f64::MIN_POSITIVE);
            }
            let factor = DenseCholesky::new(&gram, f);
            for &a in &members {
                let mut rhs = [vec![0.0; f], vec![0.0; f], vec![0.0; f]];
                for (row, &i) in rows.iter().zip(fit) {
                    let delta = r.delta[i][a].to_array();
                    for (c, rhs) in rhs.iter_mut().enumerate() {
                        for (o, x) in rhs.iter_mut().zip(row) {
                            *o += x * delta[c];
                        }
                    }
                }
                for c in &mut rhs {
                    factor.solve(c);
                }
                g[a] = (0..f).map(|p| [rhs[0][p], rhs[1][p], rhs[2][p]]).collect();
            }
        }
        Local { drivers, g }
    }

    fn predict(&self, phi: &[[f64; 9]]) -> Vec<DVec3> {
        let mut x = Vec::new();
        self.drivers
            .iter()
            .zip(&self.g)
            .map(|(d, g)| {
                gather(d, phi, &mut x);
                x.iter().zip(g).map(|(x, g)| *x * DVec3::from(*g)).sum()
            })
            .collect()
    }

    /// Step 4: the N leading directions of the fitted offsets of the poses `fit`.
    fn reduce(&self, r: &Residuals, fit: &[usize], n: usize) -> Correctives {
        let x: Vec<Vec<DVec3>> = fit.iter().map(|&i| self.predict(&r.phi[i])).collect();
        let m = x.len();
        let gram = Mat::<f64>::from_fn(m, m, |i, j| {
            x[i].iter().zip(&x[j]).map(|(a, b)| a.dot(*b)).sum()
        });
        let mut drivers: Vec<usize> = self.drivers.iter().flatten().copied().collect();
        drivers.sort_unstable();
        drivers.dedup();
        let column: HashMap<usize, usize> =
            drivers.iter().enumerate().map(|(c, &b)| (b, c)).collect();
        let mut out = Correctives {
            map: Vec::new(),
            targets: Vec::new(),
            drivers,
        };
        let Ok(eigen) = gram.self_adjoint_eigen(Side::Lower) else {
            return out;
        };
        let (u, s) = (eigen.U(), eigen.S());
        let largest = s[m.saturating_sub(1)].max(0.0);
        for e in (0..m).rev().take(n) {
            let sigma = s[e].max(0.0).sqrt();
            if sigma * sigma <= 1e-12 * largest || sigma == 0.0 {
                break;
            }
            // Scaled so that the training poses' weights (σ u_ie) span [−1, 1], as morph
            // weights usually do (Blender's shape keys clamp theirs to ±10).
            let scale = sigma * (0..m).map(|i| u[(i, e)].abs()).fold(0.0, f64::max);
            let target: Vec<DVec3> = (0..self.g.len())
                .map(|a| (0..m).map(|i| x[i][a] * u[(i, e)]).sum::<DVec3>() * (scale / sigma))
                .collect();
            let mut row = vec![0.0; 9 * out.drivers.len()];
            for ((d, g), t) in self.drivers.iter().zip(&self.g).zip(&target) {
                for (p, g) in g.iter().enumerate() {
                    row[9 * column[&d[p / 9]] + p % 9] += t.dot(DVec3::from(*g)) / (scale * scale);
                }
            }
            out.map.extend(row);
            out.targets.push(target);
        }
        out
    }
}

impl Correctives {
    /// For the runtime model.
    pub fn to_runtime(&self) -> rrskin::model::Correctives {
        rrskin::model::Correctives {
            drivers: self.drivers.iter().map(|&b| b as u32).collect(),
            map: self.map.iter().map(|&x| x as f32).collect(),
            targets: self
                .targets
                .iter()
                .flatten()
                .map(|t| t.as_vec3().to_array())
                .collect(),
        }
    }
}

/// λ for the local model (step 3) on the training poses `train` (in `r`'s order), by
/// `folds`-fold cross-validation (module docs): the ridge kept (None: no correction) and every
/// candidate's score, none first, then [`RIDGES`].
fn choose_ridge(
    set: &ExampleSet,
    drivers: &[Vec<usize>],
    rigid: &Skinning,
    train: &[usize],
    r: &Residuals,
    folds: usize,
) -> (Option<f64>, Vec<Score>) {
    let Some(folds) = Folds::new(train.len(), folds) else {
        return (None, Vec::new());
    };
    let normaliser = pose_scale::rigid_pose_errors(set, train, rigid);
    // Pose n's squared vertex error with rest-space offsets o: Σ_a |M_a (δ_a − o_a)|².
    let error = |n: usize, offsets: &[DVec3]| -> f64 {
        (r.m[n].iter().zip(&r.delta[n]).zip(offsets))
            .map(|((m, d), o)| (*m * (*d - *o)).length_squared())
            .sum()
    };
    let zero = vec![DVec3::ZERO; set.vertex_count()];
    let candidates = 1 + RIDGES.len();
    let validated = cross_validate(&folds, &normaliser, candidates, 0.0, |fold| {
        let none = fold.held.iter().map(|&n| error(n, &zero)).collect();
        std::iter::once(none)
            .chain(RIDGES.iter().map(|&lambda| {
                let local = Local::fit(drivers, r, &fold.inner, lambda);
                (fold.held.iter())
                    .map(|&n| error(n, &local.predict(&r.phi[n])))
                    .collect()
            }))
            .collect()
    });
    let ridge = validated.chosen.checked_sub(1).map(|c| RIDGES[c]);
    (ridge, validated.scores)
}

/// Fits at most `n` targets to the residuals `r` of the training poses `train` (in `r`'s
/// order), the ridge chosen by `folds`-fold cross-validation; `rigid` normalises each held-out
/// pose's error.
pub fn fit(
    set: &ExampleSet,
    ssd: &Skinning,
    rigid: &Skinning,
    train: &[usize],
    r: &Residuals,
    n: usize,
    folds: usize,
) -> Fit {
    let drivers = drivers(set, ssd);
    let (ridge, scores) = match n {
        0 => (None, Vec::new()),
        _ => choose_ridge(set, &drivers, rigid, train, r, folds),
    };
    let all: Vec<usize> = (0..train.len()).collect();
    let correctives = ridge
        .map(|lambda| Local::fit(&drivers, r, &all, lambda).reduce(r, &all, n))
        .filter(|c| !c.targets.is_empty());
    Fit {
        ridge,
        scores,
        correctives,
    }
}

/// The error budget's pose-space ceiling (docs/method.md §10): the local model of step 3 alone,
/// unreduced, its ridge chosen as [`fit`] chooses it and fitted on all of `train` (residuals
/// `r`), then evaluated on each of `at`: per set, per pose, the rest-space offsets, zero where
/// the cross-validation keeps no correction. What the training poses support of any correction
/// linear in the nearby joints' rotations, whatever it would cost per vertex.
pub fn ceiling(
    set: &ExampleSet,
    ssd: &Skinning,
    rigid: &Skinning,
    train: &[usize],
    r: &Residuals,
    folds: usize,
    at: &[&Residuals],
) -> Vec<Vec<Vec<DVec3>>> {
    let drivers = drivers(set, ssd);
    let all: Vec<usize> = (0..train.len()).collect();
    let local = (choose_ridge(set, &drivers, rigid, train, r, folds).0)
        .map(|lambda| Local::fit(&drivers, r, &all, lambda));
    (at.iter())
        .map(|at| match &local {
            Some(local) => at.phi.iter().map(|phi| local.predict(phi)).collect(),
            None => vec![vec![DVec3::ZERO; set.vertex_count()]; at.phi.len()],
        })
        .collect()
}
