//! Which cache point is which glTF vertex.
//!
//! A DCC's point cache holds the DCC's vertices, which the glTF exporters of Blender, Maya and
//! Houdini split into several glTF vertices along UV and normal seams: the cache has fewer
//! points than the glTF file, in another order. Split copies share their rest position and
//! skin, so they are one *group* here (welded on rest position and skinned trajectory), and
//! each group must be one cache point:
//!
//! - **By position**, when a sample holds the bind pose: the group's rest position against the
//!   cache's points in that sample (they agree to float precision).
//! - **By trajectory** otherwise: the group's trajectory under the glTF's own skin against the
//!   points' trajectories (the median over samples of the distance, so that the few extreme
//!   poses where a deformer departs most from the skin do not decide). A deformer's departure
//!   is smooth on the mesh, so after each round every prediction is refined by the residuals of
//!   its clearly matched mesh neighbours, and the points are matched again.
//!
//! Candidates are the nearest points in one sample; pairs are taken cheapest first (a greedy
//! assignment). A match is clear when every exchange with another distinct candidate (the
//! group takes it, its owner takes the group's point) costs at least 1/[`MARGIN`] as much. Every
//! match must be clear and every point used (or a copy of a used one), else the mapping is
//! refused: a wrong mapping would train on garbage.

use crate::import::weld::weld;
use crate::set::diagonal;
use glam::DVec3;
use kdtree::distance::squared_euclidean;
use kdtree::KdTree;
use rayon::prelude::*;
use std::ops::Range;

/// Nearest points (in the reference sample) considered per group.
const CANDIDATES: usize = 12;
/// A match's cost must be at most this fraction of the next distinct candidate's.
pub const MARGIN: f64 = 0.5;
/// Cache points whose trajectories agree this closely (relative to the mesh size) are the same
/// point written twice.
const SAME_POINT: f64 = 1e-5;

/// glTF vertex → cache point.
#[derive(Debug, Clone, PartialEq)]
pub struct VertexMap {
    pub point_of: Vec<usize>,
    /// How it was found, for the user; None when the cache was in the glTF's order.
    pub note: Option<String>,
}

/// The mapping of `rest` (G glTF rest positions, `skin[s][g]` their positions under the glTF's
/// own skin at each sample) onto the cache (`cache[s][m]`, M points, already in the rig's
/// world). `bind`: a sample whose pose is the bind pose.
pub fn map(
    rest: &[DVec3],
    triangles: &[[usize; 3]],
    primitives: &[Range<usize>],
    skin: &[Vec<DVec3>],
    cache: &[Vec<DVec3>],
    bind: Option<usize>,
) -> Result<VertexMap, String> {
    let reference = bind.unwrap_or_else(|| least_moving(rest, skin));
    let problem = Problem {
        rest,
        triangles,
        primitives,
        skin,
        cache,
        bind,
        reference,
        points: tree(&cache[reference]),
        size: diagonal(rest),
    };
    let (g, m) = (rest.len(), problem.points.size());
    let identity = VertexMap {
        point_of: (0..g).collect(),
        note: None,
    };
    if m == g && problem.in_gltf_order() {
        return Ok(identity);
    }
    match problem.by_matching() {
        // As many points as vertices, none matched: the glTF's order it is, and the rig's skin
        // judges it before training (with a message about the cache's space).
        Err(_) if m == g => Ok(identity),
        found => found,
    }
}

/// What a mapping is found from, and the search every step of it shares.
struct Problem<'a> {
    rest: &'a [DVec3],
    triangles: &'a [[usize; 3]],
    primitives: &'a [Range<usize>],
    skin: &'a [Vec<DVec3>],
    cache: &'a [Vec<DVec3>],
    /// The sample at the bind pose: points are then matched by position.
    bind: Option<usize>,
    /// The sample whose points are searched: the bind pose's, else the least moving one.
    reference: usize,
    /// The cache's points in the reference sample.
    points: KdTree<f64, usize, [f64; 3]>,
    size: f64,
}

impl Problem<'_> {
    /// The cost of glTF vertex `v` being cache point `p`: by position at the bind pose, else
    /// by trajectory against `predicted` (the skin, or its refinement).
    fn cost(&self, predicted: &[Vec<DVec3>], v: usize, p: usize) -> f64 {
        match self.bind {
            Some(s) => (self.cache[s][p] - self.rest[v]).length(),
            None => trajectory_distance(predicted, self.cache, v, p),
        }
    }

    /// The CANDIDATES points nearest `v`'s prediction in the reference sample, cheapest first.
    fn candidates(&self, predicted: &[Vec<DVec3>], v: usize) -> Vec<(f64, usize)> {
        let query = match self.bind {
            Some(_) => self.rest[v],
            None => predicted[self.reference][v],
        };
        let mut c: Vec<(f64, usize)> = self
            .points
            .nearest(
                &query.to_array(),
                CANDIDATES.min(self.points.size()),
                &squared_euclidean,
            )
            .map_or_else(
                |_| Vec::new(),
                |n| {
                    n.iter()
                        .map(|&(_, &p)| (self.cost(predicted, v, p), p))
                        .collect()
                },
            );
        c.sort_by(|a, b| a.0.total_cmp(&b.0));
        c
    }

    /// Whether cache points `a` and `b` are one point written twice.
    fn same_point(&self, a: usize, b: usize) -> bool {
        self.cache
            .iter()
            .all(|s| (s[a] - s[b]).length() <= SAME_POINT * self.size)
    }

    /// Whether the cache's points, as many as the vertices, are the vertices in the glTF's
    /// order: unless some other order fits far better.
    fn in_gltf_order(&self) -> bool {
        let g = self.rest.len();
        let identity: f64 = (0..g).map(|v| self.cost(self.skin, v, v).powi(2)).sum();
        let nearest: f64 = (0..g)
            .map(|v| {
                self.candidates(self.skin, v)
                    .first()
                    .map_or(f64::INFINITY, |c| c.0.powi(2))
            })
            .sum();
        identity <= 4.0 * nearest + (1e-9 * self.size).powi(2) * g as f64
    }

    /// Each cache point found among the glTF's vertices (module docs).
    fn by_matching(&self) -> Result<VertexMap, String> {
        let (rest, skin, cache, size) = (self.rest, self.skin, self.cache, self.size);
        let (g, m) = (rest.len(), self.points.size());
        let groups = Groups::of(rest, skin, self.triangles);
        let count = groups.representative.len();
        if count > m {
            return Err(format!(
                "{m} points for the rig's {g} vertices, which are {count} distinct ones (by rest position and skin): the cache has too few points for this mesh"
            ));
        }
        let way_out = "either put the bind pose on one frame of the clip and the cache (points are then matched by position), or write the cache in the glTF file's vertex order (tools/blender/export_examples.py writes examples directly)";
        // By trajectory, the skin's prediction is refined by the residual of the confident
        // matches around each vertex (a deformer's deviation from the skin is smooth on the
        // mesh).
        let mut predicted: Vec<Vec<DVec3>> = skin.to_vec();
        let mut round = 0;
        let mut matched = loop {
            let matched = assign(self, &groups.representative, &predicted);
            round += 1;
            if self.bind.is_some() || matched.ambiguous() == 0 || round == REFINEMENTS {
                break matched;
            }
            predicted = refined(self, &groups, &matched);
        };
        let placed = match (self.bind, matched.ambiguous()) {
            (None, 1..) => by_order(&mut matched, &groups.of, self.primitives, m)?,
            _ => 0,
        };
        if let Some(k) = matched.point_of_group.iter().position(|&p| p == usize::MAX) {
            return Err(format!(
                "glTF vertex {} matches none of its {CANDIDATES} nearest free cache points: the cache's points are not the rig's vertices; {way_out}",
                groups.representative[k]
            ));
        }
        let ambiguous = matched.ambiguous();
        if ambiguous > 0 {
            let (ratio, k) = matched.worst();
            return Err(format!(
                "cannot tell which of the cache's {m} points are the rig's {g} glTF vertices: {ambiguous} of {count} match a second point nearly as well (worst: glTF vertex {}, {ratio:.2} of the next point's distance; at most {MARGIN} is taken){}; {way_out}",
                groups.representative[k],
                if self.bind.is_some() { "" } else { ", matched by trajectory: the clip has no frame at the bind pose" }
            ));
        }
        let mut used = vec![false; m];
        matched.point_of_group.iter().for_each(|&p| used[p] = true);
        let copies_a_used_point = |p: usize| {
            self.points
                .nearest(
                    &cache[self.reference][p].to_array(),
                    4.min(m),
                    &squared_euclidean,
                )
                .is_ok_and(|n| n.iter().any(|&(_, &q)| used[q] && self.same_point(p, q)))
        };
        if let Some(p) = (0..m).find(|&p| !used[p] && !copies_a_used_point(p)) {
            return Err(format!(
                "cache point {p} is none of the rig's vertices (the cache has {m} points, the rig {count} distinct vertices): the cache is of another mesh, or of more of it; {way_out}"
            ));
        }
        let how = match self.bind {
            Some(s) => format!(
                "by position at the bind pose (sample {s}), largest residual {:.1e} of the mesh size",
                matched.cost.iter().copied().fold(0.0, f64::max) / size
            ),
            None => {
                let deviation: f64 = groups
                    .representative
                    .iter()
                    .zip(&matched.point_of_group)
                    .map(|(&v, &p)| trajectory_distance(skin, cache, v, p).powi(2))
                    .sum();
                let order = match placed {
                    0 => String::new(),
                    n => format!(", {n} of them placed by the exporter's vertex order, which the other matches keep"),
                };
                format!(
                    "by trajectory over {} samples against the glTF's own skin ({round} rounds{order}), RMS residual {:.2} % of the mesh size (the rig's deviation from its skin)",
                    cache.len(),
                    100.0 * (deviation / count as f64).sqrt() / size,
                )
            }
        };
        Ok(VertexMap {
            point_of: groups.of.iter().map(|&k| matched.point_of_group[k]).collect(),
            note: Some(format!(
                "cache has {m} points in its own order for the rig's {g} glTF vertices ({count} distinct: the DCC's vertices, split at seams in the glTF): mapped {how}"
            )),
        })
    }
}

/// The glTF vertices welded into groups (split copies of one DCC vertex), each group's first
/// vertex, its mesh neighbours, and a tree of the groups' rest positions.
struct Groups {
    /// Per glTF vertex, its group.
    of: Vec<usize>,
    representative: Vec<usize>,
    adjacent: Vec<Vec<usize>>,
    rest_tree: KdTree<f64, usize, [f64; 3]>,
}

impl Groups {
    fn of(rest: &[DVec3], skin: &[Vec<DVec3>], triangles: &[[usize; 3]]) -> Groups {
        let of = weld(rest, skin);
        let count = of.iter().max().map_or(0, |x| x + 1);
        let mut representative = vec![usize::MAX; count];
        for (v, &k) in of.iter().enumerate().rev() {
            representative[k] = v;
        }
        let mut adjacent = vec![Vec::new(); count];
        for t in triangles {
            for (a, b) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
                let (a, b) = (of[a], of[b]);
                if a != b {
                    adjacent[a].push(b);
                    adjacent[b].push(a);
                }
            }
        }
        adjacent.iter_mut().for_each(|a| {
            a.sort_unstable();
            a.dedup();
        });
        let rest_tree = tree(&representative.iter().map(|&v| rest[v]).collect::<Vec<_>>());
        Groups {
            of,
            representative,
            adjacent,
            rest_tree,
        }
    }
}

/// Rounds of matching by trajectory (the first against the skin alone).
const REFINEMENTS: usize = 4;
/// Confident matches around a vertex whose residuals refine its prediction.
const NEIGHBOURS: usize = 6;

/// A greedy assignment of groups to points and how clear it is.
struct Matched {
    /// Per group its point (usize::MAX: none left), the match's cost, and its largest cost
    /// ratio to an exchange with another distinct candidate.
    point_of_group: Vec<usize>,
    cost: Vec<f64>,
    ratio: Vec<f64>,
    /// Per group: whether its match is clear (by its ratio, or placed by the vertex order).
    clear: Vec<bool>,
}

impl Matched {
    /// Whether group `k` has a point but no clear match.
    fn unclear(&self, k: usize) -> bool {
        !self.clear[k] && self.point_of_group[k] != usize::MAX
    }

    /// Groups with a match that is not clear.
    fn ambiguous(&self) -> usize {
        (0..self.clear.len()).filter(|&k| self.unclear(k)).count()
    }

    /// The largest ratio of an unclear match, and its group.
    fn worst(&self) -> (f64, usize) {
        (0..self.ratio.len())
            .filter(|&k| self.unclear(k))
            .map(|k| (self.ratio[k], k))
            .fold((0.0, 0), |a, b| if b.0 > a.0 { b } else { a })
    }
}

/// Pairs (group, candidate point) taken cheapest first while both are free.
fn assign(problem: &Problem, representative: &[usize], predicted: &[Vec<DVec3>]) -> Matched {
    let m = problem.points.size();
    let candidates: Vec<Vec<(f64, usize)>> = representative
        .par_iter()
        .map(|&v| problem.candidates(predicted, v))
        .collect();
    let mut pairs: Vec<(f64, usize, usize)> = candidates
        .iter()
        .enumerate()
        .flat_map(|(k, c)| c.iter().map(move |&(d, p)| (d, k, p)))
        .collect();
    pairs.sort_by(|a, b| a.0.total_cmp(&b.0));
    let groups = representative.len();
    let (mut point_of_group, mut cost, mut owner) = (
        vec![usize::MAX; groups],
        vec![0.0; groups],
        vec![usize::MAX; m],
    );
    for &(d, k, p) in &pairs {
        if point_of_group[k] == usize::MAX && owner[p] == usize::MAX {
            point_of_group[k] = p;
            cost[k] = d;
            owner[p] = k;
        }
    }
    // Each match against every exchange with another distinct candidate q (not a copy of p):
    // k takes q and q's group, if any, takes p. The match is clear when each costs far more.
    let ratio: Vec<f64> = candidates
        .iter()
        .enumerate()
        .map(|(k, c)| {
            let (p, d) = (point_of_group[k], cost[k]);
            if p == usize::MAX {
                return f64::INFINITY;
            }
            c.iter()
                .filter(|&&(_, q)| q != p && !problem.same_point(p, q))
                .map(|&(dq, q)| match owner[q] {
                    usize::MAX => d / dq,
                    o => (d + cost[o]) / (dq + problem.cost(predicted, representative[o], p)),
                })
                .map(|r| if r.is_nan() { f64::INFINITY } else { r })
                .fold(0.0, f64::max)
        })
        .collect();
    Matched {
        clear: ratio.iter().map(|&r| r <= MARGIN).collect(),
        point_of_group,
        cost,
        ratio,
    }
}

/// Clear matches that keep the DCC's order within a primitive this often show an exporter
/// that keeps it.
const IN_ORDER: f64 = 0.999;

/// Places unclear matches by the exporter's vertex order, when the clear matches show that it
/// keeps the DCC's order within each primitive (Blender's does: a primitive's vertices are the
/// DCC's in increasing order, split copies beside their original). Between two clear matches
/// of a primitive, the unclear groups' points lie between theirs; where exactly as many
/// points are free there as groups wait, they are those points, in order. Returns how many
/// were placed.
fn by_order(
    matched: &mut Matched,
    group: &[usize],
    primitives: &[Range<usize>],
    m: usize,
) -> Result<usize, String> {
    let runs: Vec<Vec<usize>> = primitives
        .iter()
        .map(|r| {
            // Each group where it first appears (Blender writes a vertex's copies together).
            let mut seen = std::collections::HashSet::new();
            group[r.clone()]
                .iter()
                .copied()
                .filter(|&k| seen.insert(k))
                .collect()
        })
        .collect();
    let (mut rising, mut pairs) = (0usize, 0usize);
    for run in &runs {
        let anchors: Vec<usize> = run
            .iter()
            .filter(|&&k| matched.clear[k])
            .map(|&k| matched.point_of_group[k])
            .collect();
        pairs += anchors.len().saturating_sub(1);
        rising += anchors.windows(2).filter(|w| w[1] > w[0]).count();
    }
    if pairs == 0 || (rising as f64) < IN_ORDER * pairs as f64 {
        return Ok(0);
    }
    let mut taken = vec![false; m];
    for (k, &p) in matched.point_of_group.iter().enumerate() {
        if matched.clear[k] && p != usize::MAX {
            taken[p] = true;
        }
    }
    let mut placed = 0;
    for run in &runs {
        let mut i = 0;
        while i < run.len() {
            if matched.clear[run[i]] {
                i += 1;
                continue;
            }
            let start = i;
            while i < run.len() && !matched.clear[run[i]] {
                i += 1;
            }
            let lo = start
                .checked_sub(1)
                .map_or(0, |a| matched.point_of_group[run[a]] + 1);
            let hi = run.get(i).map_or(m, |&k| matched.point_of_group[k]);
            let free: Vec<usize> = (lo..hi.max(lo)).filter(|&p| !taken[p]).collect();
            if free.len() == i - start {
                for (&k, &p) in run[start..i].iter().zip(&free) {
                    matched.point_of_group[k] = p;
                    matched.clear[k] = true;
                    taken[p] = true;
                    placed += 1;
                }
            }
        }
    }
    // Every point at most once, else the order was not the DCC's after all.
    let mut owner = vec![usize::MAX; m];
    for (k, &p) in matched.point_of_group.iter().enumerate() {
        if p != usize::MAX && matched.clear[k] {
            if owner[p] != usize::MAX {
                return Err(format!(
                    "the glTF's vertex order places two vertices on cache point {p}: the cache is not in the DCC's order"
                ));
            }
            owner[p] = k;
        }
    }
    Ok(placed)
}

/// The skin's prediction plus, per sample, the mean residual (cache − skin) of the clearly
/// matched groups around each vertex: its mesh neighbours, or where fewer than two of those
/// are clear, the nearest clear groups by rest position (its own excluded).
fn refined(problem: &Problem, groups: &Groups, matched: &Matched) -> Vec<Vec<DVec3>> {
    let (rest, skin, cache) = (problem.rest, problem.skin, problem.cache);
    let Groups {
        of: group,
        representative,
        adjacent,
        rest_tree,
    } = groups;
    let groups = representative.len();
    let residual =
        |k: usize, s: usize| cache[s][matched.point_of_group[k]] - skin[s][representative[k]];
    let around: Vec<Vec<usize>> = (0..groups)
        .into_par_iter()
        .map(|k| {
            let ring: Vec<usize> = adjacent[k]
                .iter()
                .copied()
                .filter(|&j| matched.clear[j])
                .collect();
            if ring.len() >= 2 {
                return ring;
            }
            let at = rest[representative[k]].to_array();
            rest_tree.iter_nearest(&at, &squared_euclidean).map_or_else(
                |_| Vec::new(),
                |n| {
                    n.map(|(_, &j)| j)
                        .filter(|&j| j != k && matched.clear[j])
                        .take(NEIGHBOURS)
                        .collect()
                },
            )
        })
        .collect();
    skin.iter()
        .enumerate()
        .map(|(s, positions)| {
            positions
                .iter()
                .enumerate()
                .map(|(v, &p)| {
                    let near = &around[group[v]];
                    match near.is_empty() {
                        true => p,
                        false => {
                            p + near.iter().map(|&j| residual(j, s)).sum::<DVec3>()
                                / near.len() as f64
                        }
                    }
                })
                .collect()
        })
        .collect()
}

/// A kd-tree of `points`, each carrying its index.
pub fn tree(points: &[DVec3]) -> KdTree<f64, usize, [f64; 3]> {
    let mut tree = KdTree::with_capacity(3, 16);
    for (i, p) in points.iter().enumerate() {
        // Points are finite (the cache loader checks), so adding cannot fail.
        let _ = tree.add(p.to_array(), i);
    }
    tree
}

/// The median over samples of |cache[s][p] − skin[s][v]|.
fn trajectory_distance(skin: &[Vec<DVec3>], cache: &[Vec<DVec3>], v: usize, p: usize) -> f64 {
    let d = skin
        .iter()
        .zip(cache)
        .map(|(a, b)| (b[p] - a[v]).length_squared());
    // A cache has at least one sample: never infinite.
    rrskin::cpu::median(d).map_or(f64::INFINITY, f64::sqrt)
}

/// The sample in which the skinned mesh is nearest its rest pose (where a neighbour in space is
/// most likely a neighbour on the mesh).
fn least_moving(rest: &[DVec3], skin: &[Vec<DVec3>]) -> usize {
    let moved: Vec<f64> = skin
        .iter()
        .map(|s| {
            s.iter()
                .zip(rest)
                .map(|(p, r)| (*p - *r).length_squared())
                .sum()
        })
        .collect();
    (0..moved.len())
        .min_by(|&a, &b| moved[a].total_cmp(&moved[b]))
        .unwrap_or(0)
}
