//! Fitting the runtime form end to end to vertex positions (beyond the paper; METHOD.md §12).
//!
//! The shipped model moves a free vertex a by `y_a,c(q) = φ_aᵀ C x_c(q)`, with
//! `x_c = [d_c(q); q_c]` (F = 3P + 4J: row c of every predicted key gradient, then of every bone
//! transform) and `C = [C1 C2]` (4P x F). §4.3 derives C from the gradient targets; nothing makes
//! it the best C for the vertices, nor lets it absorb what the key predictors get wrong. With
//! the skinning weights fixed the vertex error over the training poses is quadratic in C:
//!
//! ```text
//! min_C  Σ_i Σ_c |Φ C x_c^i − y_c^i|² + λ |C − C0|²_F
//!   ⇔   A C B + λ C = E + λ C0,   A = ΦᵀΦ (4P x 4P),  B = Σ_i,c x_c^i x_c^iᵀ (F x F),
//!                                 E = Σ_i,c Φᵀ y_c^i x_c^iᵀ (4P x F)
//! ```
//!
//! With `A = U Λ Uᵀ` and `B = V M Vᵀ`, `(Uᵀ C V)_jk = (Uᵀ (E + λ C0) V)_jk / (Λ_j M_k + λ)`:
//! O(P³ + F³) whatever V and N. x holds the *predicted* d(q_i), so C absorbs predictor error.
//! B has rank ≤ 3N, below F on real sets: the ridge toward the §4.3 solution C0 keeps the fit
//! where the training poses say nothing. λ is chosen by k-fold cross-validation over the
//! training poses (A does not depend on the poses: one eigendecomposition serves every fold).

use crate::example_set::ExampleSet;
use crate::full_model::Prepared;
use crate::reduced::Reduced;
use faer::prelude::*;
use faer::{Mat, Side};
use glam::DVec4;

/// Relative ridge strengths tried, in units of mean(Λ)·mean(M); `None` keeps C0.
pub const RIDGES: [Option<f64>; 10] = [
    Some(1e-4),
    Some(1e-3),
    Some(1e-2),
    Some(1e-1),
    Some(1.0),
    Some(10.0),
    Some(100.0),
    Some(1e3),
    Some(1e4),
    None,
];

const CG_ITERATIONS: usize = 80;

/// One training pose's sufficient statistics.
struct PoseTerms {
    /// F x 3: x_c for c = x, y, z.
    x: Mat<f64>,
    /// 4P x 3: Φᵀ y_c.
    b: Mat<f64>,
    /// Σ_c |y_c|² over free vertices.
    s: f64,
}

/// What the fit chose: the relative ridge and the held-out vertex error (Σ squared distances
/// over the folds' held-out poses) of every candidate, in `RIDGES` order.
#[derive(Debug, Clone, PartialEq)]
pub struct Choice {
    pub ridge: Option<f64>,
    pub held_out: Vec<f64>,
}

/// Refits `reduced.c1`/`c2` to the vertices of the `train` poses; returns the choice made.
pub fn refine(set: &ExampleSet, prep: &Prepared, train: &[usize], folds: usize, reduced: &mut Reduced, mask: Option<&Mat<f64>>) -> Choice {
    let (p, j) = (reduced.proxies, reduced.bones);
    let (n4p, f) = (4 * p, 3 * p + 4 * j);
    let free: Vec<bool> = reduced.skin.iter().map(|inf| inf.iter().all(|&(e, _)| e < p)).collect();
    let phi = |a: usize| -> Vec<(usize, f64)> {
        let h = DVec4::from((set.rest[a], 1.0)).to_array();
        reduced.skin[a].iter().flat_map(|&(e, w)| (0..4).map(move |r| (4 * e + r, w * h[r]))).collect()
    };
    let mut a_mat = Mat::<f64>::zeros(n4p, n4p);
    for a in (0..set.vertex_count()).filter(|&a| free[a]) {
        let row = phi(a);
        for &(r, x) in &row {
            for &(c, y) in &row {
                a_mat[(r, c)] += x * y;
            }
        }
    }
    let terms: Vec<PoseTerms> = train
        .iter()
        .map(|&i| {
            let feats = &prep.feats[i];
            let mut x = Mat::<f64>::zeros(f, 3);
            for (l, key) in reduced.predictors.iter().enumerate() {
                let d = key.predict(feats, &set.parents);
                for c in 0..3 {
                    let row = d.row(c);
                    for k in 0..3 {
                        x[(3 * l + k, c)] = row[k];
                    }
                }
            }
            for (b, bone) in set.poses[i].bones.iter().enumerate() {
                for c in 0..3 {
                    let q = [bone.q.x_axis[c], bone.q.y_axis[c], bone.q.z_axis[c], bone.d[c]];
                    for k in 0..4 {
                        x[(3 * p + 4 * b + k, c)] = q[k];
                    }
                }
            }
            let mut bm = Mat::<f64>::zeros(n4p, 3);
            let mut s = 0.0;
            for a in (0..set.vertex_count()).filter(|&a| free[a]) {
                let y = set.poses[i].vertices[a];
                s += y.length_squared();
                for (r, v) in phi(a) {
                    for c in 0..3 {
                        bm[(r, c)] += v * y[c];
                    }
                }
            }
            // experiment: weight the rest pose
            let rest_w: f64 = std::env::var("RRSKIN_EXP_RESTW").ok().and_then(|v| v.parse().ok()).unwrap_or(1.0);
            let is_rest = set.poses[i].bones.iter().all(|b| (b.q - glam::DMat3::IDENTITY).abs_diff_eq(glam::DMat3::ZERO, 1e-9) && b.d.length() < 1e-9);
            let w = if is_rest { rest_w.sqrt() } else { 1.0 };
            PoseTerms { x: x * w, b: bm * w, s: s * w * w }
        })
        .collect();
    let c0 = Mat::<f64>::from_fn(n4p, f, |r, c| match c < 3 * p {
        true => reduced.c1[r * 3 * p + c],
        false => reduced.c2[r * 4 * j + c - 3 * p],
    });
    let Ok(a_eig) = a_mat.self_adjoint_eigen(Side::Lower) else {
        return Choice { ridge: None, held_out: Vec::new() };
    };
    let u = a_eig.U().to_owned();
    let lambda_a: Vec<f64> = (0..n4p).map(|k| a_eig.S()[k].max(0.0)).collect();
    let mean_a = lambda_a.iter().sum::<f64>() / n4p.max(1) as f64;

    // Translation equivariance: moving every bone by one rigid G must move every proxy by G,
    // i.e. each row's weights on the bones' translations sum to what C0's do (1 for a
    // translation row, 0 otherwise). The change Δ = C − C0 is fitted on features projected off
    // n = Σ_b e_(3P + 4b + 3), so Δ n = 0: poses where the root never moves cannot teach it.
    let mut n_vec = Mat::<f64>::zeros(f, 1);
    for b in 0..j {
        n_vec[(3 * p + 4 * b + 3, 0)] = 1.0 / (j as f64).sqrt();
    }
    let project = |x: &Mat<f64>| -> Mat<f64> { x - &n_vec * (n_vec.transpose() * x) };
    let projected: Vec<Mat<f64>> = terms.iter().map(|t| project(&t.x)).collect();
    // Solves for C on `poses` for every ridge in RIDGES.
    let solve = |poses: &[usize], ridges: &[Option<f64>]| -> Vec<Mat<f64>> {
        let mut bm = Mat::<f64>::zeros(f, f);
        let mut em = Mat::<f64>::zeros(n4p, f);
        for &n in poses {
            let (t, xp) = (&terms[n], &projected[n]);
            bm += xp * xp.transpose();
            // residual of C0: Φᵀ y − A C0 x
            let r = &t.b - &a_mat * (&c0 * &t.x);
            em += r * xp.transpose();
        }
        if let Some(mask) = mask {
            // Masked: conjugate gradients on P_S(A Δ B) + λ Δ = P_S(E), warm-started from the
            // previous (stronger) ridge.
            let mean_m = (0..f).map(|k| bm[(k, k)]).sum::<f64>() / f.max(1) as f64;
            let masked = |x: Mat<f64>| Mat::<f64>::from_fn(n4p, f, |r, c| x[(r, c)] * mask[(r, c)]);
            let rhs = masked(em.clone());
            let mut delta = Mat::<f64>::zeros(n4p, f);
            let mut out = vec![c0.clone(); ridges.len()];
            let mut order: Vec<usize> = (0..ridges.len()).collect();
            order.sort_by(|&x, &y| ridges[y].unwrap_or(f64::INFINITY).total_cmp(&ridges[x].unwrap_or(f64::INFINITY)));
            for idx in order {
                let Some(rho) = ridges[idx] else { continue };
                let lambda = rho * mean_a * mean_m;
                let op = |x: &Mat<f64>| -> Mat<f64> { let y = masked(&a_mat * x * &bm); y + x * lambda };
                let pre = Mat::<f64>::from_fn(n4p, f, |r, c| 1.0 / (a_mat[(r, r)] * bm[(c, c)] + lambda));
                let mut r = &rhs - op(&delta);
                let mut z = Mat::<f64>::from_fn(n4p, f, |i, k| r[(i, k)] * pre[(i, k)]);
                let mut pd = z.clone();
                let dot = |a: &Mat<f64>, b: &Mat<f64>| -> f64 { let mut s = 0.0; for c in 0..f { for i in 0..n4p { s += a[(i, c)] * b[(i, c)]; } } s };
                let mut rz = dot(&r, &z);
                let r0 = dot(&rhs, &rhs).max(1e-300);
                for _ in 0..CG_ITERATIONS {
                    let ap = op(&pd);
                    let alpha = rz / dot(&pd, &ap).max(1e-300);
                    delta += &pd * alpha;
                    r -= &ap * alpha;
                    if dot(&r, &r) < 1e-12 * r0 { break; }
                    z = Mat::<f64>::from_fn(n4p, f, |i, k| r[(i, k)] * pre[(i, k)]);
                    let rz_new = dot(&r, &z);
                    pd = &z + &pd * (rz_new / rz);
                    rz = rz_new;
                }
                out[idx] = &c0 + &delta;
            }
            return out;
        }
        let Ok(b_eig) = bm.self_adjoint_eigen(Side::Lower) else {
            return ridges.iter().map(|_| c0.clone()).collect();
        };
        let v = b_eig.U().to_owned();
        let m: Vec<f64> = (0..f).map(|k| b_eig.S()[k].max(0.0)).collect();
        let mean_m = m.iter().sum::<f64>() / f.max(1) as f64;
        let e_t = u.transpose() * &em * &v;
        ridges
            .iter()
            .map(|ridge| match ridge {
                None => c0.clone(),
                Some(rho) => {
                    let lambda = rho * mean_a * mean_m;
                    let dt = Mat::<f64>::from_fn(n4p, f, |r, c| e_t[(r, c)] / (lambda_a[r] * m[c] + lambda));
                    &c0 + &u * dt * v.transpose()
                }
            })
            .collect()
    };
    let error = |c: &Mat<f64>, n: usize| -> f64 {
        let t = &terms[n];
        let pt = c * &t.x;
        let apt = &a_mat * &pt;
        let mut e = t.s;
        for col in 0..3 {
            for r in 0..n4p {
                e += pt[(r, col)] * (apt[(r, col)] - 2.0 * t.b[(r, col)]);
            }
        }
        e
    };
    let folds = folds.min(train.len());
    let mut held_out = vec![0.0; RIDGES.len()];
    if folds >= 2 {
        for fold in 0..folds {
            let inner: Vec<usize> = (0..train.len()).filter(|n| n % folds != fold).collect();
            for (h, c) in held_out.iter_mut().zip(solve(&inner, &RIDGES)) {
                *h += (0..train.len()).filter(|n| n % folds == fold).map(|n| error(&c, n)).sum::<f64>();
            }
        }
    }
    let best = (0..RIDGES.len()).min_by(|&x, &y| held_out[x].total_cmp(&held_out[y])).unwrap_or(RIDGES.len() - 1);
    let mut ridge = if folds >= 2 { RIDGES[best] } else { None };
    if let Ok(r) = std::env::var("RRSKIN_EXP_RIDGE") { ridge = r.parse().ok(); }
    if ridge.is_some() {
        let all: Vec<usize> = (0..train.len()).collect();
        if let Some(c) = solve(&all, &[ridge]).pop() {
            for r in 0..n4p {
                for col in 0..3 * p {
                    reduced.c1[r * 3 * p + col] = c[(r, col)];
                }
                for col in 0..4 * j {
                    reduced.c2[r * 4 * j + col] = c[(r, 3 * p + col)];
                }
            }
        }
    }
    Choice { ridge, held_out }
}

/// The ceiling of the runtime form with these skinning weights: per pose, the proxy
/// transforms that fit the true vertices best (least squares over the free vertices; fixed
/// vertices follow their bones), instead of `t = C x(q)`.
pub fn oracle_meshes(set: &ExampleSet, reduced: &Reduced, poses: &[usize]) -> Vec<Vec<glam::DVec3>> {
    oracle(set, reduced, poses).into_iter().map(|(m, _)| m).collect()
}

/// Oracle meshes and 3x3 parts of the oracle proxy transforms.
pub fn oracle(set: &ExampleSet, reduced: &Reduced, poses: &[usize]) -> Vec<(Vec<glam::DVec3>, Vec<[DVec4; 3]>)> {
    let p = reduced.proxies;
    let n4p = 4 * p;
    let h = |a: usize| DVec4::from((set.rest[a], 1.0)).to_array();
    let free: Vec<bool> = reduced.skin.iter().map(|inf| inf.iter().all(|&(e, _)| e < p)).collect();
    let mut a_mat = Mat::<f64>::zeros(n4p, n4p);
    for a in (0..set.vertex_count()).filter(|&a| free[a]) {
        for &(e1, w1) in &reduced.skin[a] {
            for &(e2, w2) in &reduced.skin[a] {
                for r in 0..4 {
                    for c in 0..4 {
                        a_mat[(4 * e1 + r, 4 * e2 + c)] += w1 * w2 * h(a)[r] * h(a)[c];
                    }
                }
            }
        }
    }
    let trace = (0..n4p).map(|d| a_mat[(d, d)]).sum::<f64>() / n4p.max(1) as f64;
    for d in 0..n4p {
        a_mat[(d, d)] += 1e-9 * trace.max(1e-300);
    }
    let llt = a_mat.llt(Side::Lower);
    poses
        .iter()
        .map(|&i| {
            let y = &set.poses[i].vertices;
            let mut rhs = Mat::<f64>::zeros(n4p, 3);
            for a in (0..set.vertex_count()).filter(|&a| free[a]) {
                for &(e, w) in &reduced.skin[a] {
                    for r in 0..4 {
                        for c in 0..3 {
                            rhs[(4 * e + r, c)] += w * h(a)[r] * y[a][c];
                        }
                    }
                }
            }
            let t = match &llt {
                Ok(l) => l.solve(&rhs),
                Err(_) => rhs,
            };
            let m3: Vec<[DVec4; 3]> = (0..p).map(|e| [0, 1, 2].map(|c| DVec4::new(t[(4 * e, c)], t[(4 * e + 1, c)], t[(4 * e + 2, c)], t[(4 * e + 3, c)]))).collect();
            let mesh = (0..set.vertex_count())
                .map(|a| {
                    reduced.skin[a]
                        .iter()
                        .map(|&(e, w)| {
                            let moved = if e < p {
                                glam::DVec3::new(
                                    (0..4).map(|r| t[(4 * e + r, 0)] * h(a)[r]).sum(),
                                    (0..4).map(|r| t[(4 * e + r, 1)] * h(a)[r]).sum(),
                                    (0..4).map(|r| t[(4 * e + r, 2)] * h(a)[r]).sum(),
                                )
                            } else {
                                set.poses[i].bones[e - p].apply(set.rest[a])
                            };
                            moved * w
                        })
                        .sum()
                })
                .collect();
            (mesh, m3)
        })
        .collect()
}

pub fn m3(rows: &[DVec4; 3]) -> glam::DMat3 {
    glam::DMat3::from_cols(
        glam::DVec3::new(rows[0].x, rows[1].x, rows[2].x),
        glam::DVec3::new(rows[0].y, rows[1].y, rows[2].y),
        glam::DVec3::new(rows[0].z, rows[1].z, rows[2].z),
    )
}

/// Local C (experiment): T_e's 3x3 = D_e; its translation from the motion of the proxy's
/// centroid, regressed on the bones near it and D_e (oracle transforms of the training poses).
pub fn local(set: &ExampleSet, train: &[usize], reduced: &mut Reduced, key_bones: &[Vec<usize>], ridge: f64) {
    let (p, j) = (reduced.proxies, reduced.bones);
    let or = oracle(set, reduced, train);
    let mut centroid = vec![(glam::DVec3::ZERO, 0.0); p];
    for (a, inf) in reduced.skin.iter().enumerate() {
        for &(e, w) in inf {
            if e < p {
                centroid[e].0 += set.rest[a] * w;
                centroid[e].1 += w;
            }
        }
    }
    reduced.c1.iter_mut().for_each(|x| *x = 0.0);
    reduced.c2.iter_mut().for_each(|x| *x = 0.0);
    for e in 0..p {
        let c = centroid[e].0 / centroid[e].1.max(1e-300);
        for k in 0..3 {
            reduced.c1[(4 * e + k) * 3 * p + 3 * e + k] = 1.0;
            reduced.c1[(4 * e + 3) * 3 * p + 3 * e + k] = -c[k];
        }
        // unknowns: 4 per near bone + 3 on D_e's row
        let bones = &key_bones[e];
        let m = 4 * bones.len() + 3;
        let (mut g, mut h) = (vec![0.0; m * m], vec![0.0; m]);
        for (n, &i) in train.iter().enumerate() {
            let t = &or[n].1[e];
            for cc in 0..3 {
                let target = t[cc].dot(DVec4::from((c, 1.0)));
                let mut x = vec![0.0; m];
                for (s, &b) in bones.iter().enumerate() {
                    let bone = &set.poses[i].bones[b];
                    let q = [bone.q.x_axis[cc], bone.q.y_axis[cc], bone.q.z_axis[cc], bone.d[cc]];
                    x[4 * s..4 * s + 4].copy_from_slice(&q);
                }
                x[m - 3] = t[cc].x; x[m - 2] = t[cc].y; x[m - 1] = t[cc].z;
                for r in 0..m {
                    h[r] += x[r] * target;
                    for q in 0..m {
                        g[r * m + q] += x[r] * x[q];
                    }
                }
            }
        }
        let tr = (0..m).map(|r| g[r * m + r]).sum::<f64>() / m as f64;
        for r in 0..m { g[r * m + r] += ridge * tr + 1e-12; }
        crate::linalg::cholesky_solve(&g.clone(), &mut h, m);
        for (s, &b) in bones.iter().enumerate() {
            for k in 0..4 {
                reduced.c2[(4 * e + 3) * 4 * j + 4 * b + k] += h[4 * s + k];
            }
        }
        for k in 0..3 {
            reduced.c1[(4 * e + 3) * 3 * p + 3 * e + k] += h[m - 3 + k];
        }
    }
}
