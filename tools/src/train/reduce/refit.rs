//! A local end-to-end refit of the runtime form to the vertices (beyond the paper;
//! docs/method.md §12). With the skinning weights fixed, a vertex moves by
//! `y_a,c = Σ_e α_ae ŷh_aᵀ (C x_c)_e + (its bones' share)`, `x_c = [d_c(q); q_c]` (F = 3P + 4J,
//! the predicted key gradients, then the bones), so the training vertex error is quadratic in
//! C = [C1 C2] (4P x F):
//!
//! ```text
//! min_v  Σ_i Σ_c |Φ (C0 + S v) x_c^i − r_c^i|² + λ |v|²
//!   ⇔   Sᵀ(A (S v) B) + λ v = Sᵀ(E − A C0 B),   A = ΦᵀΦ (4P x 4P), B = Σ x xᵀ, E = Σ Φᵀ r xᵀ
//! ```
//!
//! (r: the vertices less their bones' share), solved by conjugate gradients. Δ = S v is local:
//! proxy e sees its own key and the bones its geometry already uses (one key per proxy: the
//! runtime then evaluates that key inside the product, `glsl/fused_product.comp`; also seeing
//! the other keys of its joint gained 0.15 / 0.06 EE points and would lose that), so a fit on wide random
//! poses cannot learn that one elbow bulges the other (STAR's lesson; a dense Δ measured worse
//! on held-out animation). And Δ is invariant to rigid motion: a column of Δ multiplies one
//! entry of one frame's matrix, and within each row the entries that multiply the same entry
//! k of different frames sum to zero, so when all the frames a proxy sees move together by any
//! rigid motion (the rest pose, a global turn or step, a stiff spine) Δ adds nothing and the
//! proxy follows them exactly. Δ only corrects *relative* motion, which is what the training
//! poses sample. Without that constraint the fit traded the near-rest spine of a walk for the
//! wide training poses (human_heavy spine vertices: 5x SSD's held-out error). λ is chosen by
//! k-fold cross-validation over the training poses ([`crate::train::cross_validate`]: every
//! held-out pose by its error relative to the rigid predictor's; the most regularised within
//! one standard error of the best, None, C0 kept, first).

use crate::set::ExampleSet;
use crate::train::cross_validate::{cross_validate, Folds};
use crate::train::pose_scale;
use crate::train::reduce::c1c2::Reduced;
use crate::train::rotreg::PoseFeatures;

/// Ridge strengths tried, relative to mean(diag A)·mean(diag B), the most regularised first
/// (`None`: C0 kept). (The cross-validation picked the weakest of 1e-6..1 on both public sets,
/// so the grid reaches further down; conjugate gradients' fixed iteration count bounds the fit
/// as well.)
pub const RIDGES: [Option<f64>; 10] = [
    None,
    Some(1.0),
    Some(1e-1),
    Some(1e-2),
    Some(1e-3),
    Some(1e-4),
    Some(1e-5),
    Some(1e-6),
    Some(1e-7),
    Some(1e-8),
];
const CG_ITERATIONS: usize = 100;

/// What the refit chose: the relative ridge (None: C0 kept) and every candidate's held-out
/// score ([`crate::train::cross_validate::Score`]'s mean), in `RIDGES` order (empty where
/// nothing was cross-validated).
#[derive(Debug, Clone, PartialEq)]
pub struct Refit {
    pub ridge: Option<f64>,
    pub held_out: Vec<f64>,
}

/// One training pose's sufficient statistics.
struct PoseTerms {
    /// F x 3, row-major: x_c for c = x, y, z.
    x: Vec<[f64; 3]>,
    /// 4P x 3: Φᵀ r_c.
    b: Vec<[f64; 3]>,
    /// Σ_c |r_c|².
    s: f64,
}

/// One column of S: +1 on entry (row, col) of Δ, −1 on (row, reference), the entry of the
/// row's first frame that multiplies the same matrix entry.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Free {
    row: usize,
    col: usize,
    reference: usize,
}

/// The fit's matrices. A is sparse: two proxies meet only where a vertex weights both.
struct Problem {
    n4p: usize,
    f: usize,
    /// A = ΦᵀΦ (4P x 4P): per row, its non-zeros (column, value).
    a: Vec<Vec<(usize, f64)>>,
    /// C0, 4P x F, row-major.
    c0: Vec<f64>,
    /// The columns of S.
    free: Vec<Free>,
    /// Per row of Δ, its entries of `free`.
    free_of_row: Vec<Vec<usize>>,
    /// Per row r, the columns where (A Δ)[r, ·] can be non-zero.
    pattern: Vec<Vec<usize>>,
    terms: Vec<PoseTerms>,
}

/// Refits `reduced`'s C1/C2 on the frames each proxy sees: its key, the bones its geometry
/// uses and the bone its key turns; the ridge chosen by `folds`-fold cross-validation.
pub fn refit(
    set: &ExampleSet,
    feats: &[PoseFeatures],
    train: &[usize],
    folds: usize,
    reduced: &mut Reduced,
) -> Refit {
    let problem = Problem::new(set, feats, train, reduced);
    let folds = Folds::new(train.len(), folds).filter(|_| !problem.free.is_empty());
    let Some(folds) = folds else {
        return Refit {
            ridge: None,
            held_out: Vec::new(),
        };
    };
    let normaliser = pose_scale::own_rigid_pose_errors(set, train);
    let validated = cross_validate(&folds, &normaliser, RIDGES.len(), 0.0, |fold| {
        (problem.solve(&fold.inner, &RIDGES).iter())
            .map(|v| fold.held.iter().map(|&n| problem.error(v, n)).collect())
            .collect()
    });
    let ridge = RIDGES[validated.chosen];
    problem.apply(ridge, train.len(), reduced);
    Refit {
        ridge,
        held_out: validated.scores.iter().map(|s| s.0).collect(),
    }
}

/// [`refit`] with the ridge given (None: C0 kept) instead of chosen; `held_out` is empty.
pub fn refit_with(
    set: &ExampleSet,
    feats: &[PoseFeatures],
    train: &[usize],
    ridge: Option<f64>,
    reduced: &mut Reduced,
) -> Refit {
    if ridge.is_some() {
        Problem::new(set, feats, train, reduced).apply(ridge, train.len(), reduced);
    }
    Refit {
        ridge,
        held_out: Vec::new(),
    }
}

impl Problem {
    /// Solves on all `poses` training poses with `ridge` and adds Δ to `reduced`'s C.
    fn apply(&self, ridge: Option<f64>, poses: usize, reduced: &mut Reduced) {
        let all: Vec<usize> = (0..poses).collect();
        if let Some(v) = ridge.and_then(|r| self.solve(&all, &[Some(r)]).pop()) {
            let (p, j) = (reduced.proxies, reduced.bones);
            for (r, c, x) in self.entries(&v) {
                match c < 3 * p {
                    true => reduced.c1[r * 3 * p + c] += x,
                    false => reduced.c2[r * 4 * j + c - 3 * p] += x,
                }
            }
        }
    }

    fn new(
        set: &ExampleSet,
        feats: &[PoseFeatures],
        train: &[usize],
        reduced: &Reduced,
    ) -> Problem {
        let (p, j) = (reduced.proxies, reduced.bones);
        let (n4p, f) = (4 * p, 3 * p + 4 * j);
        let c0: Vec<f64> = (0..n4p)
            .flat_map(|r| {
                (0..f).map(move |c| match c < 3 * p {
                    true => reduced.c1[r * 3 * p + c],
                    false => reduced.c2[r * 4 * j + c - 3 * p],
                })
            })
            .collect();
        let free = Self::free_columns(reduced, &c0);
        let dense = reduced.proxy_normal_matrix(set);
        let a: Vec<Vec<(usize, f64)>> = dense
            .chunks(n4p)
            .map(|row| {
                row.iter()
                    .enumerate()
                    .filter(|x| *x.1 != 0.0)
                    .map(|(q, &v)| (q, v))
                    .collect()
            })
            .collect();
        let mut free_of_row = vec![Vec::new(); n4p];
        for (idx, s) in free.iter().enumerate() {
            free_of_row[s.row].push(idx);
        }
        let pattern = Self::pattern(&a, &free, &free_of_row);
        let terms = Self::pose_terms(set, feats, train, reduced);
        Problem {
            n4p,
            f,
            a,
            c0,
            free,
            free_of_row,
            pattern,
            terms,
        }
    }

    /// The columns of S: per row of Δ and entry k, every frame the row sees (key e, then the
    /// bones its geometry uses or its key turns) that has an entry k, less the first such.
    fn free_columns(reduced: &Reduced, c0: &[f64]) -> Vec<Free> {
        let (p, j) = (reduced.proxies, reduced.bones);
        let (n4p, f) = (4 * p, 3 * p + 4 * j);
        // Per row, the frames it sees (key e, then bones), each as the
        // column of its entry 0 and its entry count.
        let mut free = Vec::new();
        for r in 0..n4p {
            let e = r / 4;
            let turned = reduced.predictors[e].rotation.map(|t| t.first.bone);
            let uses = |b: usize| (0..4).any(|k| c0[(4 * e + 3) * f + 3 * p + 4 * b + k] != 0.0);
            let frames: Vec<(usize, usize)> = std::iter::once((3 * e, 3))
                .chain(
                    (0..j)
                        .filter(|&b| Some(b) == turned || uses(b))
                        .map(|b| (3 * p + 4 * b, 4)),
                )
                .collect();
            for k in 0..4 {
                let mut seeing = frames.iter().filter(|f| k < f.1).map(|f| f.0 + k);
                if let Some(reference) = seeing.next() {
                    free.extend(seeing.map(|col| Free {
                        row: r,
                        col,
                        reference,
                    }));
                }
            }
        }
        free
    }

    /// Per row r of A, the columns where (A Δ)[r, ·] can be non-zero: those of the free
    /// entries (and their references) of the rows A couples r to.
    fn pattern(
        a: &[Vec<(usize, f64)>],
        free: &[Free],
        free_of_row: &[Vec<usize>],
    ) -> Vec<Vec<usize>> {
        a.iter()
            .map(|row| {
                let mut cols: Vec<usize> = row
                    .iter()
                    .flat_map(|&(q, _)| free_of_row[q].iter())
                    .flat_map(|&idx| [free[idx].col, free[idx].reference])
                    .collect();
                cols.sort_unstable();
                cols.dedup();
                cols
            })
            .collect()
    }

    /// Each training pose's sufficient statistics: x_c (the predicted key gradients, then the
    /// bones' rows), Φᵀ r_c and Σ_c |r_c|².
    fn pose_terms(
        set: &ExampleSet,
        feats: &[PoseFeatures],
        train: &[usize],
        reduced: &Reduced,
    ) -> Vec<PoseTerms> {
        let (p, j) = (reduced.proxies, reduced.bones);
        let f = 3 * p + 4 * j;
        train
            .iter()
            .map(|&i| {
                let pose = &set.poses[i];
                let mut x = vec![[0.0; 3]; f];
                for (l, key) in reduced.predictors.iter().enumerate() {
                    let d = key.predict(&feats[i], &set.parents);
                    for c in 0..3 {
                        for k in 0..3 {
                            x[3 * l + k][c] = d.row(c)[k];
                        }
                    }
                }
                for (b, bone) in pose.bones.iter().enumerate() {
                    for c in 0..3 {
                        let q = bone.row(c);
                        for k in 0..4 {
                            x[3 * p + 4 * b + k][c] = q[k];
                        }
                    }
                }
                let (bm, s) = reduced.proxy_targets(set, pose);
                PoseTerms { x, b: bm, s }
            })
            .collect()
    }

    /// The non-zeros (row, column, value) of Δ = S v.
    fn entries<'a>(&'a self, v: &'a [f64]) -> impl Iterator<Item = (usize, usize, f64)> + 'a {
        self.free
            .iter()
            .zip(v)
            .flat_map(|(s, &x)| [(s.row, s.col, x), (s.row, s.reference, -x)])
    }

    /// t = (C0 + Δ) x for pose n: 4P x 3.
    fn transforms(&self, delta: &[f64], n: usize) -> Vec<[f64; 3]> {
        let t = &self.terms[n];
        let mut out = vec![[0.0; 3]; self.n4p];
        for (r, row) in out.iter_mut().enumerate() {
            for (c, x) in t.x.iter().enumerate() {
                let v = self.c0[r * self.f + c];
                if v != 0.0 {
                    (0..3).for_each(|k| row[k] += v * x[k]);
                }
            }
        }
        for (r, c, v) in self.entries(delta) {
            (0..3).for_each(|k| out[r][k] += v * t.x[c][k]);
        }
        out
    }

    /// Σ_c |Φ t_c − r_c|² for pose n.
    fn error(&self, delta: &[f64], n: usize) -> f64 {
        let t = self.transforms(delta, n);
        let mut e = self.terms[n].s;
        for (r, row) in self.a.iter().enumerate() {
            for k in 0..3 {
                let at: f64 = row.iter().map(|&(q, a)| a * t[q][k]).sum();
                e += t[r][k] * (at - 2.0 * self.terms[n].b[r][k]);
            }
        }
        e
    }

    /// v for each ridge, fitted on `poses` (warm-started from the stronger ridge).
    fn solve(&self, poses: &[usize], ridges: &[Option<f64>]) -> Vec<Vec<f64>> {
        let (n4p, f, m) = (self.n4p, self.f, self.free.len());
        let b = self.pose_gram(poses);
        let rhs = self.rhs(poses);
        let mean_a = (0..n4p).map(|r| self.diag_a(r)).sum::<f64>() / n4p.max(1) as f64;
        let mean_b = (0..f).map(|d| b[d * f + d]).sum::<f64>() / f.max(1) as f64;
        let mut h = vec![0.0; n4p * f];
        let mut order: Vec<usize> = (0..ridges.len()).collect();
        order.sort_by(|&x, &y| {
            ridges[y]
                .unwrap_or(f64::INFINITY)
                .total_cmp(&ridges[x].unwrap_or(f64::INFINITY))
        });
        let mut out = vec![vec![0.0; m]; ridges.len()];
        let mut delta = vec![0.0; m];
        for idx in order {
            let Some(rho) = ridges[idx] else { continue };
            let lambda = rho * mean_a * mean_b;
            self.conjugate_gradients(&b, &rhs, lambda, &mut h, &mut delta);
            out[idx] = delta.clone();
        }
        out
    }

    /// B = Σ x xᵀ over `poses` and coordinates (F x F).
    fn pose_gram(&self, poses: &[usize]) -> Vec<f64> {
        let f = self.f;
        let mut b = vec![0.0; f * f];
        for &n in poses {
            let x = &self.terms[n].x;
            for r in 0..f {
                for c in 0..f {
                    b[r * f + c] += (0..3).map(|k| x[r][k] * x[c][k]).sum::<f64>();
                }
            }
        }
        b
    }

    /// The right-hand side over `poses`: Sᵀ Σ (Φᵀ r − A C0 x) xᵀ.
    fn rhs(&self, poses: &[usize]) -> Vec<f64> {
        let (n4p, m) = (self.n4p, self.free.len());
        let mut rhs = vec![0.0; m];
        for &n in poses {
            let t = &self.terms[n];
            let c0x = self.transforms(&vec![0.0; m], n);
            let residual: Vec<[f64; 3]> = (0..n4p)
                .map(|r| {
                    let mut v = t.b[r];
                    for &(q, a) in &self.a[r] {
                        (0..3).for_each(|k| v[k] -= a * c0x[q][k]);
                    }
                    v
                })
                .collect();
            let at = |r: usize, c: usize| (0..3).map(|k| residual[r][k] * t.x[c][k]).sum::<f64>();
            for (slot, s) in rhs.iter_mut().zip(&self.free) {
                *slot += at(s.row, s.col) - at(s.row, s.reference);
            }
        }
        rhs
    }

    /// A's diagonal entry r (0 where the row is empty).
    fn diag_a(&self, r: usize) -> f64 {
        self.a[r].iter().find(|x| x.0 == r).map_or(0.0, |x| x.1)
    }

    /// Sᵀ(A (S v) B) + λ v, through H = A Δ (4P x F, sparse rows: `pattern`; `h` holds it
    /// between calls, only its pattern entries are ever written or read); B is symmetric.
    fn normal_product(&self, b: &[f64], h: &mut [f64], v: &[f64], lambda: f64) -> Vec<f64> {
        let f = self.f;
        for (r, row) in self.a.iter().enumerate() {
            let hr = &mut h[r * f..(r + 1) * f];
            self.pattern[r].iter().for_each(|&c| hr[c] = 0.0);
            for &(q, a) in row {
                for &idx in &self.free_of_row[q] {
                    let s = self.free[idx];
                    hr[s.col] += a * v[idx];
                    hr[s.reference] -= a * v[idx];
                }
            }
        }
        self.free
            .iter()
            .zip(v)
            .map(|(s, &x)| {
                let (hr, bc, bo) = (&h[s.row * f..], &b[s.col * f..], &b[s.reference * f..]);
                let hb: f64 = self.pattern[s.row]
                    .iter()
                    .map(|&c| hr[c] * (bc[c] - bo[c]))
                    .sum();
                hb + lambda * x
            })
            .collect()
    }

    /// Solves (Sᵀ(A (S ·) B) + λ) v = `rhs` by conjugate gradients preconditioned with the
    /// diagonal, from `delta` (the stronger ridge's v) and into it: [`CG_ITERATIONS`] at most,
    /// stopping early once the residual is negligible.
    fn conjugate_gradients(
        &self,
        b: &[f64],
        rhs: &[f64],
        lambda: f64,
        h: &mut [f64],
        delta: &mut [f64],
    ) {
        let f = self.f;
        let diag: Vec<f64> = self
            .free
            .iter()
            .map(|s| {
                let (c, o) = (s.col, s.reference);
                let bb = b[c * f + c] - 2.0 * b[c * f + o] + b[o * f + o];
                self.diag_a(s.row) * bb + lambda
            })
            .collect();
        let applied = self.normal_product(b, h, delta, lambda);
        let mut res: Vec<f64> = rhs.iter().zip(&applied).map(|(x, y)| x - y).collect();
        let mut z: Vec<f64> = res.iter().zip(&diag).map(|(x, d)| x / d).collect();
        let mut dir = z.clone();
        let mut rz = dot(&res, &z);
        let floor = 1e-20 * dot(rhs, rhs).max(1e-300);
        for _ in 0..CG_ITERATIONS {
            if dot(&res, &res) < floor {
                break;
            }
            let ad = self.normal_product(b, h, &dir, lambda);
            let step = rz / dot(&dir, &ad).max(1e-300);
            delta.iter_mut().zip(&dir).for_each(|(x, d)| *x += step * d);
            res.iter_mut().zip(&ad).for_each(|(x, d)| *x -= step * d);
            z = res.iter().zip(&diag).map(|(x, d)| x / d).collect();
            let rz_next = dot(&res, &z);
            dir = z
                .iter()
                .zip(&dir)
                .map(|(x, d)| x + d * (rz_next / rz))
                .collect();
            rz = rz_next;
        }
    }
}

/// The dot product of two vectors, summed in order.
fn dot(x: &[f64], y: &[f64]) -> f64 {
    x.iter().zip(y).map(|(p, q)| p * q).sum::<f64>()
}
