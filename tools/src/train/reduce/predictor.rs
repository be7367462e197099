//! Predictor reduction (paper §5.2, docs/method.md §7): P key gradient sequences D_ℓ^i and sparse
//! blend weights β (T x P) with `Σ_i Σ_k Σ_j |Σ_ℓ β_kℓ D_ℓ^i v̂_kj − v_kj^i|²` small, by
//! coordinate descent from D_ℓ^i = the 3x3 part of proxy ℓ's transforms; then a predictor
//! (rotation §3.2 + scale/shear §3.3) is trained on each key sequence.
//!
//! j runs over the two edges *and* the Sumner–Popović normal n̂ of each triangle (the frame D is
//! defined by, docs/method.md §1): the edges alone leave each D_ℓ free along the normal, and the
//! predictors are trained on the polar factors of the whole D_ℓ. With one key per triangle the
//! keys are then exactly the triangles' gradients.

use crate::linalg::{cholesky_solve, polar, DenseCholesky};
use crate::set::ExampleSet;
use crate::train::full_model::Prepared;
use crate::train::gradients::frame;
use crate::train::reduce::vertex::Proxies;
use crate::train::rotreg::{self, PoseFeatures, RotationPredictor};
use crate::train::scale_shear::{self, ScaleShear};
use glam::{DMat3, DVec3};
use rayon::prelude::*;

/// Coordinate-descent rounds (the paper converges in three or fewer).
pub const ROUNDS: usize = 3;

#[derive(Debug, Clone)]
pub struct KeySequences {
    /// Per triangle: (key ℓ, β).
    pub beta: Vec<Vec<(usize, f64)>>,
    /// \[pose (train order)\]\[key\]
    pub d: Vec<Vec<DMat3>>,
}

/// Keys a triangle may blend: its group's and those weighting its vertices.
fn candidates(set: &ExampleSet, proxies: &Proxies, k: usize) -> Vec<usize> {
    let mut c = vec![proxies.triangle_group[k]];
    for &a in &set.faces[k] {
        for &(b, _) in &proxies.weights[a] {
            if !c.contains(&b) {
                c.push(b);
            }
        }
    }
    c
}

/// The key sequences D_ℓ^i and blend weights β: [`ROUNDS`] rounds of coordinate descent (β,
/// then D) from D_ℓ^i = the 3x3 part of proxy ℓ's transforms.
pub fn reduce(
    set: &ExampleSet,
    prep: &Prepared,
    train: &[usize],
    proxies: &Proxies,
) -> KeySequences {
    let p = proxies.count();
    // Per triangle the three columns v̂2, v̂3, n̂ of its rest frame.
    let edges: Vec<[DVec3; 3]> = set
        .faces
        .iter()
        .map(|&[a, b, c]| {
            let f = frame(set.rest[a], set.rest[b], set.rest[c]);
            [f.x_axis, f.y_axis, f.z_axis]
        })
        .collect();
    let cands: Vec<Vec<usize>> = (0..set.faces.len())
        .map(|k| candidates(set, proxies, k))
        .collect();
    let targets = Targets { prep, train, edges };
    let mut d: Vec<Vec<DMat3>> = proxies
        .transforms
        .iter()
        .map(|ts| ts.iter().map(|t| t.q).collect())
        .collect();
    let mut beta: Vec<Vec<(usize, f64)>> = Vec::new();
    for _ in 0..ROUNDS {
        beta = beta_step(&targets, &cands, &d);
        d = d_step(&targets, &beta, &d, p);
    }
    KeySequences { beta, d }
}

/// What both descent steps fit to: the triangles' rest frames and, through the full model's
/// polar factors, their posed ones.
struct Targets<'a> {
    prep: &'a Prepared,
    train: &'a [usize],
    /// Per triangle the three columns v̂2, v̂3, n̂ of its rest frame.
    edges: Vec<[DVec3; 3]>,
}

impl Targets<'_> {
    /// True edges (and normal) v_kj^i = D_k^i v̂_kj, of training pose `n` (train order).
    fn target(&self, n: usize, k: usize, j: usize) -> DVec3 {
        let (r, s) = self.prep.polar[self.train[n]][k];
        r * s * self.edges[k][j]
    }
}

/// The β-step: one small least-squares problem per triangle, over its candidate keys `cands`
/// with the keys `d` fixed.
fn beta_step(t: &Targets, cands: &[Vec<usize>], d: &[Vec<DMat3>]) -> Vec<Vec<(usize, f64)>> {
    let edges = &t.edges;
    (0..cands.len())
        .into_par_iter()
        .map(|k| {
            let c = &cands[k];
            let m = c.len();
            let (mut g, mut h) = (vec![0.0; m * m], vec![0.0; m]);
            for n in 0..t.train.len() {
                for j in 0..3 {
                    let cols: Vec<DVec3> = c.iter().map(|&l| d[n][l] * edges[k][j]).collect();
                    let v = t.target(n, k, j);
                    for r in 0..m {
                        h[r] += cols[r].dot(v);
                        for s in 0..m {
                            g[r * m + s] += cols[r].dot(cols[s]);
                        }
                    }
                }
            }
            // Ridge toward following the triangle's own group key (candidate 0): where
            // several keys fit equally well (neighbours moving alike), β stays on its own.
            let ridge = 1e-9 * (0..m).map(|r| g[r * m + r]).sum::<f64>().max(1e-300);
            for r in 0..m {
                g[r * m + r] += ridge;
            }
            h[0] += ridge;
            cholesky_solve(&g, &mut h, m);
            c.iter().copied().zip(h).collect()
        })
        .collect()
}

/// The D-step: per pose and row c, the 3P unknowns (row c of every D_ℓ) share one normal
/// matrix; a weak pull toward the current keys `d` keeps unused keys determined.
fn d_step(t: &Targets, beta: &[Vec<(usize, f64)>], d: &[Vec<DMat3>], p: usize) -> Vec<Vec<DMat3>> {
    let n3 = 3 * p;
    let mut gram = d_gram(&t.edges, beta, n3);
    let ridge = 1e-6 * (0..n3).map(|x| gram[x * n3 + x]).sum::<f64>() / n3.max(1) as f64;
    (0..n3).for_each(|x| gram[x * n3 + x] += ridge.max(1e-12));
    let factor = DenseCholesky::new(&gram, n3);
    (0..t.train.len())
        .into_par_iter()
        .map(|n| {
            let mut rows = [vec![0.0; n3], vec![0.0; n3], vec![0.0; n3]];
            for (k, bk) in beta.iter().enumerate() {
                for j in 0..3 {
                    let (e, v) = (t.edges[k][j].to_array(), t.target(n, k, j));
                    for &(l, b) in bk {
                        for c in 0..3 {
                            for r in 0..3 {
                                rows[c][3 * l + r] += b * e[r] * v[c];
                            }
                        }
                    }
                }
            }
            for (l, dl) in d[n].iter().enumerate() {
                for c in 0..3 {
                    let row = dl.row(c).to_array();
                    for r in 0..3 {
                        rows[c][3 * l + r] += ridge.max(1e-12) * row[r];
                    }
                }
            }
            rows.iter_mut().for_each(|x| factor.solve(x));
            (0..p)
                .map(|l| {
                    DMat3::from_cols_array(&[
                        rows[0][3 * l],
                        rows[1][3 * l],
                        rows[2][3 * l],
                        rows[0][3 * l + 1],
                        rows[1][3 * l + 1],
                        rows[2][3 * l + 1],
                        rows[0][3 * l + 2],
                        rows[1][3 * l + 2],
                        rows[2][3 * l + 2],
                    ])
                })
                .collect()
        })
        .collect()
}

/// The D-step's normal matrix (3P x 3P, the same for every pose and row): Σ over triangles k
/// and frame columns j of the outer product of β_k ⊗ v̂_kj with itself.
fn d_gram(edges: &[[DVec3; 3]], beta: &[Vec<(usize, f64)>], n3: usize) -> Vec<f64> {
    let mut gram = vec![0.0; n3 * n3];
    for (k, bk) in beta.iter().enumerate() {
        for j in 0..3 {
            let e = edges[k][j].to_array();
            for &(l1, b1) in bk {
                for &(l2, b2) in bk {
                    for r in 0..3 {
                        for s in 0..3 {
                            gram[(3 * l1 + r) * n3 + 3 * l2 + s] += b1 * b2 * e[r] * e[s];
                        }
                    }
                }
            }
        }
    }
    gram
}

/// A key predictor as trained, in f64 (its stored form is [`rrskin::KeyPredictor`]): rotation
/// (None when no nearby bone moves: then R = I) and H.
#[derive(Debug, Clone)]
pub struct TrainedPredictor {
    pub rotation: Option<RotationPredictor>,
    pub stretch: ScaleShear,
}

impl TrainedPredictor {
    pub fn predict(&self, f: &PoseFeatures, parents: &[Option<usize>]) -> DMat3 {
        match &self.rotation {
            Some(r) => {
                let x = scale_shear::features(f, parents, r.first.bone);
                r.predict(f, parents) * scale_shear::predict(&self.stretch, &x)
            }
            None => DMat3::IDENTITY,
        }
    }
}

/// Trains a predictor on each key sequence; candidate bones are those near the key's proxy
/// (the bones skinning its group's vertices in SSD, their parents and children).
pub fn train_predictors(
    set: &ExampleSet,
    prep: &Prepared,
    train: &[usize],
    keys: &KeySequences,
    key_bones: &[Vec<usize>],
    ridge: f64,
) -> Vec<TrainedPredictor> {
    let feats: Vec<&PoseFeatures> = train.iter().map(|&i| &prep.feats[i]).collect();
    (0..key_bones.len())
        .into_par_iter()
        .map(|l| {
            let (rs, ss): (Vec<DMat3>, Vec<DMat3>) = keys.d.iter().map(|dn| polar(dn[l])).unzip();
            let rotation = rotreg::fit(&rs, &feats, &set.parents, &key_bones[l]);
            let stretch = match &rotation {
                Some(r) => {
                    let xs: Vec<[f64; 7]> = feats
                        .iter()
                        .map(|f| scale_shear::features(f, &set.parents, r.first.bone))
                        .collect();
                    scale_shear::fit(&ss, &xs, ridge)
                }
                None => scale_shear::identity(),
            };
            TrainedPredictor { rotation, stretch }
        })
        .collect()
}
