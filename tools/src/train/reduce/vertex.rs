//! Vertex reduction to P proxy bones (paper §5.1, docs/method.md §6).
//!
//! 1. Greedy merging: every triangle starts as a group whose transform maps it (with a
//!    normal-offset fourth point, so the affine fit is determined) from rest to each pose; the
//!    join A → B of contiguous groups with the smallest error
//!    `E_A→B = s_A − 2 Σ_i tr(T_B^i N_A^iᵀ) + Σ_i tr(T_B^i M_A T_B^iᵀ)` is performed next. All
//!    a cost needs is in per-group moments (M 4x4, N^i 3x4, s = Σ|y|²), so a join costs O(N)
//!    whatever the group sizes; a binary heap holds each group's cheapest join, per-group
//!    versions skipping the stale ones.
//! 2. Alternation (paper steps 3–4): per free vertex, NNLS weights α over the proxies of its own
//!    group and the adjacent groups (at most K, Σα = 1); then all proxy transforms by least
//!    squares, one (4P x 4P) normal matrix shared by every pose and coordinate.
//!
//! Index letters: b, g proxies (groups), i poses (in `train` order), a vertices, k triangles.

use crate::set::{Affine, ExampleSet};
use glam::{DMat3, DMat4, DVec3, DVec4};
use rayon::prelude::*;
use std::cmp::Ordering;
use std::collections::{BinaryHeap, HashMap, HashSet};

#[derive(Debug, Clone)]
pub struct Proxies {
    /// Per vertex: (proxy, α) for free vertices, empty for fixed ones.
    pub weights: Vec<Vec<(usize, f64)>>,
    /// \[pose (train order)\]\[proxy\]
    pub transforms: Vec<Vec<Affine>>,
    /// Per triangle: the proxy of its group.
    pub triangle_group: Vec<usize>,
    /// Per proxy: the contiguous proxies.
    pub adjacency: Vec<Vec<usize>>,
}

impl Proxies {
    pub fn count(&self) -> usize {
        self.adjacency.len()
    }
}

/// Moments of a group over its sample points (docs/method.md §6).
#[derive(Clone)]
struct Moments {
    m: DMat4,
    /// Per pose: Σ y ŷhᵀ as 3 rows of 4.
    n: Vec<[DVec4; 3]>,
    /// Σ |y|² over the poses.
    s: f64,
}

impl Moments {
    fn add(&mut self, other: &Moments) {
        self.m += other.m;
        for (a, b) in self.n.iter_mut().zip(&other.n) {
            for r in 0..3 {
                a[r] += b[r];
            }
        }
        self.s += other.s;
    }

    /// Best affine fit per pose: T = N M⁻¹ (rows).
    fn fit(&self) -> Vec<[DVec4; 3]> {
        let inv = self.m.inverse();
        self.n
            .iter()
            .map(|rows| rows.map(|r| inv.transpose() * r))
            .collect()
    }

    /// Error of mapping this group's samples with `fit`: `s − 2 Σ_i tr(T^i N^iᵀ) + ⟨M,
    /// Σ_i T^iᵀ T^i⟩`, the last sum the fit's [`Fit::gram`], so a cost is 12 multiply-adds a
    /// pose (with `tr(T^i M T^iᵀ)` per pose it was 60, and the merging's time). The cross
    /// term sums into 12 independent lanes (a row's entries), which vectorise; the loop is
    /// bound by loading N and the rows, not by the adds.
    fn error_with(&self, fit: &Fit) -> f64 {
        let mut lanes = [DVec4::ZERO; 3];
        for (n, rows) in self.n.iter().zip(&fit.rows) {
            for r in 0..3 {
                lanes[r] += rows[r] * n[r];
            }
        }
        let cross = (lanes[0] + lanes[1] + lanes[2]).element_sum();
        let (m, g) = (self.m.to_cols_array(), fit.gram.to_cols_array());
        let quadratic: f64 = m.iter().zip(&g).map(|(a, b)| a * b).sum();
        (self.s - 2.0 * cross + quadratic).max(0.0)
    }
}

/// A group's best affine fit per pose, as a join's target.
struct Fit {
    /// Per pose: T^i as 3 rows of 4.
    rows: Vec<[DVec4; 3]>,
    /// `Σ_i T^iᵀ T^i` (4x4).
    gram: DMat4,
}

impl Fit {
    fn of(moments: &Moments) -> Fit {
        let rows = moments.fit();
        let mut gram = DMat4::ZERO;
        for t in rows.iter().flatten() {
            gram += DMat4::from_cols(*t * t.x, *t * t.y, *t * t.z, *t * t.w);
        }
        Fit { rows, gram }
    }

    /// No fit: a group merged away.
    fn none() -> Fit {
        Fit {
            rows: Vec::new(),
            gram: DMat4::ZERO,
        }
    }
}

fn homogeneous(p: DVec3) -> DVec4 {
    p.extend(1.0)
}

/// The triangle's fourth point: its centroid plus the unit normal times sqrt(area), so the
/// affine fit of one triangle is determined and scale-consistent.
fn fourth_point(a: DVec3, b: DVec3, c: DVec3) -> DVec3 {
    let cross = (b - a).cross(c - a);
    let len = cross.length();
    let n = if len > 0.0 {
        cross / len.sqrt()
    } else {
        DVec3::ZERO
    };
    (a + b + c) / 3.0 + n
}

fn triangle_moments(set: &ExampleSet, train: &[usize], k: usize) -> Moments {
    let [a, b, c] = set.faces[k];
    let rest = [set.rest[a], set.rest[b], set.rest[c]];
    let rest4 = fourth_point(rest[0], rest[1], rest[2]);
    let points: Vec<DVec4> = rest
        .iter()
        .chain([&rest4])
        .map(|&p| homogeneous(p))
        .collect();
    let mut m = DMat4::ZERO;
    for p in &points {
        m += DMat4::from_cols(*p * p.x, *p * p.y, *p * p.z, *p * p.w);
    }
    let (mut n, mut s) = (Vec::with_capacity(train.len()), 0.0);
    for &i in train {
        let y = &set.poses[i].vertices;
        let posed = [y[a], y[b], y[c]];
        let posed4 = fourth_point(posed[0], posed[1], posed[2]);
        let mut rows = [DVec4::ZERO; 3];
        for (q, p) in posed.iter().chain([&posed4]).zip(&points) {
            for r in 0..3 {
                rows[r] += *p * q[r];
            }
            s += q.length_squared();
        }
        n.push(rows);
    }
    // A tiny ridge keeps degenerate triangles invertible.
    Moments {
        m: m + DMat4::IDENTITY * 1e-12,
        n,
        s,
    }
}

#[derive(PartialEq)]
struct Join {
    cost: f64,
    from: usize,
    into: usize,
    /// The version of `from` it was pushed at: stale once `from`'s cheapest join changed.
    version: u32,
}

impl Eq for Join {}

impl Ord for Join {
    fn cmp(&self, other: &Self) -> Ordering {
        other.cost.total_cmp(&self.cost) // min-heap
    }
}

impl PartialOrd for Join {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

/// When merging stops: at `proxies` groups, or earlier when the next join would take the RMS
/// fitting error of the groups' sample points (vertices and normal points, over the training
/// poses, in mesh units) past `epsilon` (the paper's ε, §5.1). Join costs add up to an upper
/// bound of that error.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Stop {
    pub proxies: usize,
    pub epsilon: Option<f64>,
}

/// Greedy merging of contiguous triangle groups until `stop`. Returns each triangle's group
/// (0..P) and the group adjacency.
pub fn merge_groups(set: &ExampleSet, train: &[usize], stop: Stop) -> Grouping {
    let mut groupings = merge_groups_at(set, train, &[stop.proxies], stop.epsilon);
    groupings.swap_remove(0)
}

/// Each triangle's group (0..P) and the groups' adjacency (P lists of group indices).
pub type Grouping = (Vec<usize>, Vec<Vec<usize>>);

/// One greedy merging, read off at each of `counts` groups (any order; a grouping per count,
/// in that order): a coarser grouping is the finer one merged further, as one merging to the
/// coarsest would make it, for the cost of that one merging. `epsilon` as [`Stop`]'s: past it
/// the merging stops, and the coarser counts get the grouping reached.
pub fn merge_groups_at(
    set: &ExampleSet,
    train: &[usize],
    counts: &[usize],
    epsilon: Option<f64>,
) -> Vec<Grouping> {
    let t = set.faces.len();
    let mut merging = Merging::new(set, train);
    let mut owner: Vec<usize> = (0..t).collect(); // union-find parent
    let mut groups = t;
    // ε bounds the RMS over 4 samples per triangle and pose: a budget on the summed join costs.
    let budget = epsilon.map_or(f64::INFINITY, |e| e * e * (4 * t * train.len()) as f64);
    let mut spent = 0.0;
    let mut order: Vec<usize> = (0..counts.len()).collect();
    order.sort_by_key(|&i| std::cmp::Reverse(counts[i]));
    let mut out = vec![(Vec::new(), Vec::new()); counts.len()];
    for i in order {
        while groups > counts[i].max(1) {
            let Some(join) = merging.heap.pop() else {
                break;
            };
            if !merging.is_current(&join) {
                continue; // stale
            }
            if spent + join.cost > budget {
                merging.heap.push(join); // the coarser counts stop here too
                break;
            }
            spent += join.cost;
            merging.join(join.from, join.into);
            owner[join.from] = join.into;
            groups -= 1;
        }
        out[i] = merging.grouping(&owner);
    }
    out
}

/// The greedy merging's state. Per live group g: its moments and per-pose fits, and the cost
/// of joining it into each neighbour x (`costs[g][x]`: g's samples mapped by x's fits). The heap
/// holds each group's cheapest join, pushed whenever it changes (the previous one then stale:
/// its version is behind the group's), so the global cheapest join is the heap's valid top,
/// and the heap grows by about one entry per affected group a merge, not two per neighbour.
struct Merging {
    moments: Vec<Option<Moments>>,
    fits: Vec<Fit>,
    costs: Vec<HashMap<usize, f64>>,
    /// Each group's cheapest join (into, cost) as last pushed.
    best: Vec<Option<(usize, f64)>>,
    version: Vec<u32>,
    heap: BinaryHeap<Join>,
}

impl Merging {
    /// One group per triangle of `set`, fitted on the poses `train`, each with its cheapest join.
    fn new(set: &ExampleSet, train: &[usize]) -> Merging {
        let t = set.faces.len();
        let moments: Vec<Option<Moments>> = (0..t)
            .into_par_iter()
            .map(|k| Some(triangle_moments(set, train, k)))
            .collect();
        let fits = (moments.par_iter())
            .map(|m| m.as_ref().map_or_else(Fit::none, Fit::of))
            .collect();
        let mut merging = Merging {
            moments,
            fits,
            costs: Vec::new(),
            best: vec![None; t],
            version: vec![0; t],
            heap: BinaryHeap::new(),
        };
        let adjacency = triangle_adjacency(set);
        merging.costs = (0..t)
            .into_par_iter()
            .map(|g| {
                adjacency[g]
                    .iter()
                    .map(|&x| (x, merging.cost(g, x)))
                    .collect()
            })
            .collect();
        (0..t).for_each(|g| merging.refresh(g));
        merging
    }

    /// The live groups numbered 0..P in order: each triangle's group (`owner`: the union-find
    /// parents of the joins so far) and the groups' adjacency.
    fn grouping(&self, owner: &[usize]) -> Grouping {
        let t = owner.len();
        let roots: Vec<usize> = (0..t).filter(|&g| self.moments[g].is_some()).collect();
        let mut index = vec![usize::MAX; t];
        roots.iter().enumerate().for_each(|(n, &g)| index[g] = n);
        let find = |mut x: usize| {
            while owner[x] != x {
                x = owner[x];
            }
            x
        };
        let triangle_group: Vec<usize> = (0..t).map(|k| index[find(k)]).collect();
        let adjacency = roots
            .iter()
            .map(|&g| self.costs[g].keys().map(|&x| index[x]).collect())
            .collect();
        (triangle_group, adjacency)
    }

    /// The cost of joining group `a` into group `b`.
    fn cost(&self, a: usize, b: usize) -> f64 {
        self.moments[a]
            .as_ref()
            .map_or(f64::INFINITY, |m| m.error_with(&self.fits[b]))
    }

    /// Whether `join` is still its group's cheapest, with both groups alive.
    fn is_current(&self, join: &Join) -> bool {
        let (a, b) = (join.from, join.into);
        self.moments[a].is_some() && self.moments[b].is_some() && join.version == self.version[a]
    }

    /// Group `g`'s cheapest join, pushed if it changed (ties to the lower neighbour index).
    fn refresh(&mut self, g: usize) {
        let best = (self.costs[g].iter())
            .min_by(|p, q| p.1.total_cmp(q.1).then(p.0.cmp(q.0)))
            .map(|(&x, &c)| (x, c));
        if best == self.best[g] {
            return;
        }
        self.best[g] = best;
        self.version[g] += 1;
        if let Some((into, cost)) = best {
            self.heap.push(Join {
                cost,
                from: g,
                into,
                version: self.version[g],
            });
        }
    }

    /// Group `a` joins group `b`: b's moments and fits grow, a's neighbours become b's, and
    /// every join from or into b is costed again.
    fn join(&mut self, a: usize, b: usize) {
        if let (Some(ma), Some(mb)) = (self.moments[a].take(), self.moments[b].as_mut()) {
            mb.add(&ma);
            self.fits[b] = Fit::of(mb);
        }
        self.fits[a] = Fit::none();
        self.version[a] += 1;
        for x in std::mem::take(&mut self.costs[a]).into_keys() {
            self.costs[x].remove(&a);
            if x != b {
                self.costs[x].insert(b, 0.0);
                self.costs[b].insert(x, 0.0);
            }
        }
        let mut around: Vec<usize> = self.costs[b].keys().copied().collect();
        around.sort_unstable();
        let fresh: Vec<(f64, f64)> = (around.iter())
            .map(|&x| (self.cost(b, x), self.cost(x, b)))
            .collect();
        for (&x, (bx, xb)) in around.iter().zip(fresh) {
            self.costs[b].insert(x, bx);
            self.costs[x].insert(b, xb);
        }
        for x in around {
            self.refresh(x);
        }
        self.refresh(b);
    }
}

/// Triangles sharing an edge.
fn triangle_adjacency(set: &ExampleSet) -> Vec<HashSet<usize>> {
    let mut by_edge: std::collections::HashMap<(usize, usize), Vec<usize>> = Default::default();
    for (k, &[a, b, c]) in set.faces.iter().enumerate() {
        for (x, y) in [(a, b), (b, c), (c, a)] {
            by_edge.entry((x.min(y), x.max(y))).or_default().push(k);
        }
    }
    let mut adj = vec![HashSet::new(); set.faces.len()];
    for tris in by_edge.values() {
        for &p in tris {
            for &q in tris {
                if p != q {
                    adj[p].insert(q);
                }
            }
        }
    }
    adj
}

/// Rounds of the α / transform alternation after merging.
pub const ALTERNATIONS: usize = 3;

/// The whole vertex reduction: merging, then alternating α and transforms over free vertices.
pub fn reduce(
    set: &ExampleSet,
    train: &[usize],
    fixed: &[bool],
    stop: Stop,
    influences: usize,
) -> Proxies {
    let (triangle_group, adjacency) = merge_groups(set, train, stop);
    let p = adjacency.len();
    // Initial transforms: the least-squares fit of each group's triangles.
    let mut group_moments: Vec<Option<Moments>> = vec![None; p];
    for (k, &g) in triangle_group.iter().enumerate() {
        let m = triangle_moments(set, train, k);
        match &mut group_moments[g] {
            Some(acc) => acc.add(&m),
            slot => *slot = Some(m),
        }
    }
    let mut transforms: Vec<Vec<Affine>> = vec![Vec::with_capacity(p); train.len()];
    for m in &group_moments {
        let fit = m.as_ref().map_or_else(
            || vec![[DVec4::X, DVec4::Y, DVec4::Z]; train.len()],
            |m| m.fit(),
        );
        for (i, rows) in fit.iter().enumerate() {
            transforms[i].push(affine_of_rows(rows));
        }
    }
    // Each vertex's home group: the group of an incident triangle fitting it best.
    let mut incident: Vec<Vec<usize>> = vec![Vec::new(); set.vertex_count()];
    for (k, tri) in set.faces.iter().enumerate() {
        tri.iter()
            .for_each(|&a| incident[a].push(triangle_group[k]));
    }
    let mut weights = vec![Vec::new(); set.vertex_count()];
    for _ in 0..ALTERNATIONS {
        weights = (0..set.vertex_count())
            .into_par_iter()
            .map(|a| {
                if fixed[a] || incident[a].is_empty() {
                    return Vec::new();
                }
                let error = |g: usize| -> f64 {
                    train
                        .iter()
                        .enumerate()
                        .map(|(n, &i)| {
                            (transforms[n][g].apply(set.rest[a]) - set.poses[i].vertices[a])
                                .length_squared()
                        })
                        .sum()
                };
                let home = *incident[a]
                    .iter()
                    .min_by(|&&x, &&y| error(x).total_cmp(&error(y)))
                    .unwrap_or(&incident[a][0]);
                let mut candidates: Vec<usize> = std::iter::once(home)
                    .chain(adjacency[home].iter().copied())
                    .collect();
                candidates.sort_by(|&x, &y| error(x).total_cmp(&error(y)));
                candidates.truncate(crate::train::ssd::CANDIDATES);
                let moved = |n: usize, g: usize| transforms[n][g].apply(set.rest[a]);
                crate::train::ssd::fit_weights(train.len(), &candidates, influences, moved, |n| {
                    set.poses[train[n]].vertices[a]
                })
            })
            .collect();
        transforms = fit_transforms(set, train, &weights, &transforms);
    }
    Proxies {
        weights,
        transforms,
        triangle_group,
        adjacency,
    }
}

fn affine_of_rows(rows: &[DVec4; 3]) -> Affine {
    Affine {
        q: DMat3::from_cols(
            DVec3::new(rows[0].x, rows[1].x, rows[2].x),
            DVec3::new(rows[0].y, rows[1].y, rows[2].y),
            DVec3::new(rows[0].z, rows[1].z, rows[2].z),
        ),
        d: DVec3::new(rows[0].w, rows[1].w, rows[2].w),
    }
}

/// Least-squares proxy transforms given α: per coordinate c and pose, the unknowns are row c of
/// every proxy transform (4P); the normal matrix ΦᵀΦ is shared by all. A weak pull toward the
/// current transforms keeps proxies without free vertices determined.
fn fit_transforms(
    set: &ExampleSet,
    train: &[usize],
    weights: &[Vec<(usize, f64)>],
    current: &[Vec<Affine>],
) -> Vec<Vec<Affine>> {
    let p = current.first().map_or(0, |t| t.len());
    let n4 = 4 * p;
    let mut gram = vec![0.0; n4 * n4];
    for (a, w) in weights.iter().enumerate() {
        let h = homogeneous(set.rest[a]).to_array();
        for &(b1, w1) in w {
            for &(b2, w2) in w {
                for r in 0..4 {
                    for c in 0..4 {
                        gram[(4 * b1 + r) * n4 + 4 * b2 + c] += w1 * w2 * h[r] * h[c];
                    }
                }
            }
        }
    }
    let trace = (0..n4).map(|d| gram[d * n4 + d]).sum::<f64>() / n4.max(1) as f64;
    let ridge = 1e-6 * trace.max(1e-12);
    for d in 0..n4 {
        gram[d * n4 + d] += ridge;
    }
    let factor = crate::linalg::DenseCholesky::new(&gram, n4);
    train
        .par_iter()
        .enumerate()
        .map(|(n, &i)| {
            let mut rows = [vec![0.0; n4], vec![0.0; n4], vec![0.0; n4]];
            for (a, w) in weights.iter().enumerate() {
                let h = homogeneous(set.rest[a]).to_array();
                let y = set.poses[i].vertices[a];
                for &(b, wb) in w {
                    for r in 0..4 {
                        for c in 0..3 {
                            rows[c][4 * b + r] += wb * h[r] * y[c];
                        }
                    }
                }
            }
            for (b, t) in current[n].iter().enumerate() {
                for c in 0..3 {
                    let row = t.row(c);
                    for r in 0..4 {
                        rows[c][4 * b + r] += ridge * row[r];
                    }
                }
            }
            rows.iter_mut().for_each(|rhs| factor.solve(rhs));
            (0..p)
                .map(|b| {
                    let row = |c: usize| DVec4::from_slice(&rows[c][4 * b..4 * b + 4]);
                    affine_of_rows(&[row(0), row(1), row(2)])
                })
                .collect()
        })
        .collect()
}
