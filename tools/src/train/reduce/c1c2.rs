//! The reduced reconstruction (paper §4.3, Eq. 5–6; docs/method.md §8) and the runtime model file.
//!
//! Per coordinate c the residual of every edge row e = (k, j) is
//! `G t_c + K q_c − B d_c − L q_c` with
//!
//! | matrix | shape   | row e                                                            |
//! |--------|---------|------------------------------------------------------------------|
//! | G      | 2T x 4P | φ_kj − φ_k1 over free endpoints, φ_a = α_ab ŷh_a in block b       |
//! | K      | 2T x 4J | ψ_kj − ψ_k1 over fixed endpoints, ψ_a = w_ab ŷh_a (SSD) in block b |
//! | B      | 2T x 3P | a_k β_kℓ v̂_kj in block ℓ (a_k: the triangle's regression weight)  |
//! | L      | 2T x 4J | (1 − a_k)(ψ_kj − ψ_k1) over all endpoints: SSD's edge            |
//!
//! so `t_c = C1 d_c + C2 q_c` with `C1 = (GᵀG + μI)⁻¹ GᵀB` (4P x 3P) and
//! `C2 = (GᵀG + μI)⁻¹ (Gᵀ(L − K) + μE)` (4P x 4J). The weak rows μ |t_b − q_bone(b)|² pull each
//! proxy toward its best-matching bone, which keeps proxies touching only fixed vertices
//! determined while staying linear in q.

use crate::linalg::DenseCholesky;
use crate::set::{Affine, ExampleSet, Pose};
use crate::skinning::lbs::Skinning;
use crate::train::reduce::delta_mush_keys::Keys;
use crate::train::reduce::predictor::{KeySequences, TrainedPredictor};
use crate::train::reduce::vertex::Proxies;
use crate::train::rotreg::PoseFeatures;
use faer::prelude::*;
use faer::{Mat, Side};
use glam::{DMat3, DVec3, DVec4};

/// The reduced model in f64, as trained: what the runtime model stores in f32.
#[derive(Clone)]
pub struct Reduced {
    pub proxies: usize,
    pub bones: usize,
    /// 4P x 3P, row-major.
    pub c1: Vec<f64>,
    /// 4P x 4J, row-major.
    pub c2: Vec<f64>,
    /// The keys (P in all): the predictors' (paper §3), then the delta-mush keys'
    /// (docs/method.md §23), Direct Delta DeltaMushReport's fits of their groups; the runtime model holds
    /// them as one list of [`rrskin::Key`]s ([`Reduced::to_runtime`]).
    pub predictors: Vec<TrainedPredictor>,
    pub delta_mush: Option<Keys>,
    /// Per vertex: (palette entry, weight); entries < P are proxies, P + b bone b.
    pub skin: Vec<Vec<(usize, f64)>>,
    /// Per vertex: SSD's (bone, weight), the baseline the runtime model carries.
    pub baseline: Vec<Vec<(usize, f64)>>,
}

/// Relative strength of the rows pulling each proxy toward its bone.
const PROXY_PULL: f64 = 1e-6;

/// Assembles C1 and C2 from the reductions. `blend`: per triangle, the regression's weight a_k.
pub fn assemble(
    set: &ExampleSet,
    ssd: &Skinning,
    fixed: &[bool],
    blend: &[f64],
    proxies: &Proxies,
    keys: &KeySequences,
    predictors: Vec<TrainedPredictor>,
) -> Reduced {
    let (p, j) = (proxies.count(), set.bone_count());
    let (n4p, n3p, n4j) = (4 * p, 3 * p, 4 * j);
    let (mut gtg, gtb, mut gtlk) = normal_equations(set, ssd, fixed, blend, proxies, keys);
    add_proxy_pull(set, ssd, proxies, &mut gtg, &mut gtlk);
    let factor = DenseCholesky::new(&gtg, n4p);
    let (mut c1, mut c2) = (gtb, gtlk);
    factor.solve_columns(&mut c1, n3p);
    factor.solve_columns(&mut c2, n4j);
    let skin = (0..set.vertex_count())
        .map(|a| match fixed[a] {
            true => ssd.influences[a].iter().map(|&(b, w)| (p + b, w)).collect(),
            false => proxies.weights[a].clone(),
        })
        .collect();
    Reduced {
        proxies: p,
        bones: j,
        c1,
        c2,
        predictors,
        delta_mush: None,
        skin,
        baseline: ssd.influences.clone(),
    }
}

/// GᵀG, GᵀB and Gᵀ(L − K) (row-major), summed over every edge row e = (k, j) with a free
/// endpoint (rows of fixed vertices only are all zero in G and add nothing).
fn normal_equations(
    set: &ExampleSet,
    ssd: &Skinning,
    fixed: &[bool],
    blend: &[f64],
    proxies: &Proxies,
    keys: &KeySequences,
) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    let (p, j) = (proxies.count(), set.bone_count());
    let (n4p, n3p, n4j) = (4 * p, 3 * p, 4 * j);
    let h = |a: usize| DVec4::from((set.rest[a], 1.0)).to_array();
    // Sparse rows of φ (free), ψ (fixed) and ψ over all vertices.
    let phi = |a: usize| -> Vec<(usize, f64)> {
        if fixed[a] {
            return Vec::new();
        }
        proxies.weights[a]
            .iter()
            .flat_map(|&(b, w)| (0..4).map(move |r| (4 * b + r, w * h(a)[r])))
            .collect()
    };
    let psi_all = |a: usize| -> Vec<(usize, f64)> {
        ssd.influences[a]
            .iter()
            .flat_map(|&(b, w)| (0..4).map(move |r| (4 * b + r, w * h(a)[r])))
            .collect()
    };
    let psi = |a: usize| if fixed[a] { psi_all(a) } else { Vec::new() };
    let mut gtg = vec![0.0; n4p * n4p];
    let mut gtb = vec![0.0; n4p * n3p];
    let mut gtlk = vec![0.0; n4p * n4j];
    for (k, &[k1, k2, k3]) in set.faces.iter().enumerate() {
        for kj in [k2, k3] {
            let edge = set.rest[kj] - set.rest[k1];
            let g_row = combine(&phi(kj), &phi(k1));
            if g_row.is_empty() {
                continue;
            }
            let mut b_row = Vec::new();
            for &(l, beta) in &keys.beta[k] {
                for r in 0..3 {
                    b_row.push((3 * l + r, blend[k] * beta * edge[r]));
                }
            }
            let mut lk_row: Vec<(usize, f64)> = combine(&psi_all(kj), &psi_all(k1))
                .into_iter()
                .map(|(c, v)| (c, (1.0 - blend[k]) * v))
                .collect();
            lk_row.extend(
                combine(&psi(kj), &psi(k1))
                    .into_iter()
                    .map(|(c, v)| (c, -v)),
            );
            for &(r, gv) in &g_row {
                for &(c, v) in &g_row {
                    gtg[r * n4p + c] += gv * v;
                }
                for &(c, v) in &b_row {
                    gtb[r * n3p + c] += gv * v;
                }
                for &(c, v) in &lk_row {
                    gtlk[r * n4j + c] += gv * v;
                }
            }
        }
    }
    (gtg, gtb, gtlk)
}

/// The weak rows μ |t_b − q_bone(b)|² pulling each proxy toward its best-matching bone, added
/// to GᵀG and Gᵀ(L − K); μ is [`PROXY_PULL`] times GᵀG's mean diagonal (at least 1e-12).
fn add_proxy_pull(
    set: &ExampleSet,
    ssd: &Skinning,
    proxies: &Proxies,
    gtg: &mut [f64],
    gtlk: &mut [f64],
) {
    let (n4p, n4j) = (4 * proxies.count(), 4 * set.bone_count());
    let mu = PROXY_PULL * (0..n4p).map(|d| gtg[d * n4p + d]).sum::<f64>() / n4p.max(1) as f64;
    let mu = mu.max(1e-12);
    for (b, bone) in proxy_bones(set, ssd, proxies).into_iter().enumerate() {
        for r in 0..4 {
            gtg[(4 * b + r) * n4p + 4 * b + r] += mu;
            gtlk[(4 * b + r) * n4j + 4 * bone + r] += mu;
        }
    }
}

/// Sparse row difference x − y.
fn combine(x: &[(usize, f64)], y: &[(usize, f64)]) -> Vec<(usize, f64)> {
    let mut out: Vec<(usize, f64)> = x.to_vec();
    for &(c, v) in y {
        match out.iter_mut().find(|(d, _)| *d == c) {
            Some(slot) => slot.1 -= v,
            None => out.push((c, -v)),
        }
    }
    out
}

/// Each proxy's best-matching bone: the largest total SSD weight over its vertices.
fn proxy_bones(set: &ExampleSet, ssd: &Skinning, proxies: &Proxies) -> Vec<usize> {
    let mut score = vec![vec![0.0; set.bone_count()]; proxies.count()];
    for (k, tri) in set.faces.iter().enumerate() {
        for &a in tri {
            for &(b, w) in &ssd.influences[a] {
                score[proxies.triangle_group[k]][b] += w;
            }
        }
    }
    score
        .iter()
        .map(|s| {
            (0..s.len())
                .max_by(|&x, &y| s[x].total_cmp(&s[y]))
                .unwrap_or(0)
        })
        .collect()
}

impl Reduced {
    /// The proxy share of vertex a: its (proxy, weight) entries.
    fn proxy_share(&self, a: usize) -> impl Iterator<Item = &(usize, f64)> {
        self.skin[a].iter().filter(move |x| x.0 < self.proxies)
    }

    /// `A = ΦᵀΦ` (4P x 4P, row-major) over every vertex's proxy share: the normal matrix of
    /// fitting the proxy transforms to vertex positions with these weights.
    pub fn proxy_normal_matrix(&self, set: &ExampleSet) -> Vec<f64> {
        let n4p = 4 * self.proxies;
        let mut a_mat = vec![0.0; n4p * n4p];
        for a in 0..set.vertex_count() {
            let h = DVec4::from((set.rest[a], 1.0)).to_array();
            for &(e1, w1) in self.proxy_share(a) {
                for &(e2, w2) in self.proxy_share(a) {
                    for r in 0..4 {
                        for c in 0..4 {
                            a_mat[(4 * e1 + r) * n4p + 4 * e2 + c] += w1 * w2 * h[r] * h[c];
                        }
                    }
                }
            }
        }
        a_mat
    }

    /// For one pose, with r_a = the vertex less its bones' share: `Φᵀ r_c` (4P rows, c = x, y,
    /// z) and `Σ |r|²` over the vertices with a proxy share.
    pub fn proxy_targets(&self, set: &ExampleSet, pose: &Pose) -> (Vec<[f64; 3]>, f64) {
        let p = self.proxies;
        let (mut rhs, mut s) = (vec![[0.0; 3]; 4 * p], 0.0);
        for a in 0..set.vertex_count() {
            if self.proxy_share(a).next().is_none() {
                continue;
            }
            let on_bones: DVec3 = self.skin[a]
                .iter()
                .filter(|x| x.0 >= p)
                .map(|&(e, w)| pose.bones[e - p].apply(set.rest[a]) * w)
                .sum();
            let r = pose.vertices[a] - on_bones;
            s += r.length_squared();
            let h = DVec4::from((set.rest[a], 1.0)).to_array();
            for &(e, w) in self.proxy_share(a) {
                for k in 0..4 {
                    for c in 0..3 {
                        rhs[4 * e + k][c] += w * h[k] * r[c];
                    }
                }
            }
        }
        (rhs, s)
    }

    /// The mesh in one pose, in f64: predictors, t = C1 d + C2 q, palette skinning.
    pub fn predict(&self, set: &ExampleSet, f: &PoseFeatures, bones: &[Affine]) -> Vec<DVec3> {
        self.skin_with(set, &self.predict_proxies(set, f, bones), bones)
    }

    /// The proxies' transforms in one pose, in f64: predictors, t = C1 d + C2 q.
    pub fn predict_proxies(
        &self,
        set: &ExampleSet,
        f: &PoseFeatures,
        bones: &[Affine],
    ) -> Vec<Affine> {
        let mut d: Vec<DMat3> = (self.predictors.iter())
            .map(|k| k.predict(f, &set.parents))
            .collect();
        if let Some(delta_mush) = &self.delta_mush {
            d.extend(delta_mush.motions(bones).into_iter().map(|m| m.q));
        }
        self.proxy_transforms(&d, bones)
    }

    /// Per pose of `poses`, the P proxy transforms that fit the vertices best with the trained
    /// weights (the bones' share of each vertex is known), by least squares: the ceiling of the
    /// runtime form (docs/method.md §19) and the targets of the proxy correctives.
    ///
    /// `anchor`: per pose (in `poses` order) P transforms and a strength μ: a ridge of μ times
    /// the normal matrix's mean diagonal pulls the solution toward them, so that what the
    /// vertices leave undetermined (proxies that share their vertices) stays at the anchor
    /// instead of taking the least-squares noise. None: toward zero, with a weak ridge that only
    /// keeps proxies without free vertices determined (at zero: they move nothing).
    pub fn best_transforms(
        &self,
        set: &ExampleSet,
        poses: &[usize],
        anchor: Option<(&[Vec<Affine>], f64)>,
    ) -> Vec<Vec<Affine>> {
        let p = self.proxies;
        let n4p = 4 * p;
        let normal = self.proxy_normal_matrix(set);
        let mut gram = Mat::<f64>::from_fn(n4p, n4p, |r, c| normal[r * n4p + c]);
        let trace = (0..n4p).map(|d| gram[(d, d)]).sum::<f64>() / n4p.max(1) as f64;
        let ridge = anchor.map_or(1e-9, |a| a.1.max(1e-9)) * trace.max(1e-300);
        for d in 0..n4p {
            gram[(d, d)] += ridge;
        }
        let zero = Affine {
            q: DMat3::ZERO,
            d: DVec3::ZERO,
        };
        let Ok(llt) = gram.llt(Side::Lower) else {
            return poses.iter().map(|_| vec![zero; p]).collect();
        };
        poses
            .iter()
            .enumerate()
            .map(|(k, &i)| {
                let (targets, _) = self.proxy_targets(set, &set.poses[i]);
                // Row 4e + x of the unknowns is column x of [M_e | t_e] (x = 3: t_e).
                let prior = |r: usize, c: usize| match anchor {
                    None => 0.0,
                    Some((a, _)) => match r % 4 {
                        3 => ridge * a[k][r / 4].d[c],
                        x => ridge * a[k][r / 4].q.col(x)[c],
                    },
                };
                let rhs = Mat::<f64>::from_fn(n4p, 3, |r, c| targets[r][c] + prior(r, c));
                let t = llt.solve(&rhs);
                (0..p)
                    .map(|e| Affine {
                        q: DMat3::from_cols_array(&std::array::from_fn(|k| {
                            t[(4 * e + k / 3, k % 3)]
                        })),
                        d: DVec3::from_array(std::array::from_fn(|c| t[(4 * e + 3, c)])),
                    })
                    .collect()
            })
            .collect()
    }

    /// The proxies' transforms for key gradients `d` (P) and bones: t = C1 d + C2 q (§4.3).
    pub fn proxy_transforms(&self, d: &[DMat3], bones: &[Affine]) -> Vec<Affine> {
        let (p, j) = (self.proxies, self.bones);
        let mut t = vec![[[0.0; 4]; 3]; p];
        for c in 0..3 {
            for r in 0..4 * p {
                let mut v = 0.0;
                for (l, dl) in d.iter().enumerate() {
                    let row = dl.row(c);
                    for x in 0..3 {
                        v += self.c1[r * 3 * p + 3 * l + x] * row[x];
                    }
                }
                for (b, bone) in bones.iter().enumerate() {
                    let q = bone.row(c);
                    for x in 0..4 {
                        v += self.c2[r * 4 * j + 4 * b + x] * q[x];
                    }
                }
                t[r / 4][c][r % 4] = v;
            }
        }
        t.iter()
            .map(|m| Affine {
                q: DMat3::from_cols_array(&[
                    m[0][0], m[1][0], m[2][0], m[0][1], m[1][1], m[2][1], m[0][2], m[1][2], m[2][2],
                ]),
                d: DVec3::new(m[0][3], m[1][3], m[2][3]),
            })
            .collect()
    }

    /// The mesh for key gradients `d` (P) and bones: t = C1 d + C2 q, palette skinning.
    pub fn predict_with_keys(&self, set: &ExampleSet, d: &[DMat3], bones: &[Affine]) -> Vec<DVec3> {
        self.skin_with(set, &self.proxy_transforms(d, bones), bones)
    }

    /// The mesh for the proxies' transforms `palette` (P) and bones: palette skinning.
    pub fn skin_with(&self, set: &ExampleSet, palette: &[Affine], bones: &[Affine]) -> Vec<DVec3> {
        let p = self.proxies;
        set.rest
            .iter()
            .zip(&self.skin)
            .map(|(&y, inf)| {
                inf.iter()
                    .map(|&(e, w)| match e < p {
                        true => palette[e].apply(y) * w,
                        false => bones[e - p].apply(y) * w,
                    })
                    .sum()
            })
            .collect()
    }

    /// The runtime model (f32), validated by `rrskin::Model::new`.
    pub fn to_runtime(&self, set: &ExampleSet, influences: usize) -> rrskin::Result<rrskin::Model> {
        let root = set.parents.iter().position(|p| p.is_none()).unwrap_or(0);
        let rows = |m: DMat3| m.transpose().to_cols_array().map(|x| x as f32);
        let predictors = (self.predictors.iter())
            .map(|k| match &k.rotation {
                Some(r) => rrskin::KeyPredictor {
                    bone: r.first.bone as u32,
                    u: r.first.u as f32,
                    w: rows(r.first.w),
                    second: r.second.map(|s| rrskin::SecondBone {
                        bone: s.bone as u32,
                        u: s.u as f32,
                        w: rows(s.w),
                    }),
                    h: k.stretch.map(|x| x as f32),
                },
                // No moving bone: R = I from a root with u = 0, and S = H₀.
                None => rrskin::KeyPredictor {
                    bone: root as u32,
                    u: 0.0,
                    w: rows(DMat3::IDENTITY),
                    second: None,
                    h: crate::train::scale_shear::identity().map(|x| x as f32),
                },
            })
            .map(|k| (rrskin::Key::Predictor(k), None));
        // Each key beside the frame C1 turns its fit out of (the delta-mush keys' only).
        let delta_mush = (self.delta_mush.iter())
            .flat_map(|k| k.runtime.iter().zip(k.frames()))
            .map(|(key, frame)| (rrskin::Key::DeltaMush(key.clone()), Some(*frame)));
        let (keys, frames): (Vec<_>, Vec<_>) = predictors.chain(delta_mush).unzip();
        let mut c1: Vec<f32> = self.c1.iter().map(|&x| x as f32).collect();
        rrskin::model::c1_in_key_frames(&mut c1, &frames);
        rrskin::Model::new(rrskin::ModelParts {
            keys,
            c1,
            c2: self.c2.iter().map(|&x| x as f32).collect(),
            ..runtime_parts(set, influences, &self.skin, &self.baseline)
        })
    }
}

/// The parts of a runtime model of `set` every kind shares, K = `influences`: the mesh, the
/// bones, the skin (`skin`: per vertex (palette entry, weight)) and the SSD baseline
/// (`baseline`), with the set's animation; no keys (predictors, C1 and C2 empty), no
/// correctives.
pub fn runtime_parts(
    set: &ExampleSet,
    influences: usize,
    skin: &[Vec<(usize, f64)>],
    baseline: &[Vec<(usize, f64)>],
) -> rrskin::ModelParts {
    let (skin_indices, skin_weights) = padded(skin, influences);
    let (baseline_indices, baseline_weights) = padded(baseline, influences);
    rrskin::ModelParts {
        rest_positions: set.rest.iter().map(|p| p.as_vec3().to_array()).collect(),
        triangles: set.faces.iter().map(|t| t.map(|a| a as u32)).collect(),
        bone_parents: (set.parents.iter())
            .map(|p| p.map_or(-1, |p| p as i32))
            .collect(),
        influences: influences as u32,
        skin_indices,
        skin_weights,
        keys: Vec::new(),
        c1: Vec::new(),
        c2: Vec::new(),
        normal_groups: Vec::new(),
        baseline_indices,
        baseline_weights,
        animation: set_animation(set),
        rest_tangents: Vec::new(),
        correctives: None,
        proxy_correctives: None,
    }
}

/// The poses a model is shown with: the held-out poses (a sequence, like CesiumMan's walk) if
/// there are any, else the training poses.
fn set_animation(set: &ExampleSet) -> Vec<rrskin::predict::Affine> {
    let poses = if set.test().is_empty() {
        set.train()
    } else {
        set.test()
    };
    poses
        .iter()
        .flat_map(|&i| set.poses[i].bones.iter().map(Affine::to_runtime))
        .collect()
}

/// Per-vertex (index, weight) lists as V x K arrays, normalised, padded with (0, 0).
fn padded(lists: &[Vec<(usize, f64)>], k: usize) -> (Vec<u32>, Vec<f32>) {
    let mut indices = Vec::with_capacity(lists.len() * k);
    let mut weights = Vec::with_capacity(lists.len() * k);
    for inf in lists {
        let total: f64 = inf.iter().map(|&(_, w)| w).sum();
        for s in 0..k {
            let (e, w) = inf.get(s).copied().unwrap_or((0, 0.0));
            indices.push(e as u32);
            weights.push((w / total) as f32);
        }
    }
    (indices, weights)
}
