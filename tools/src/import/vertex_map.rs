//! Which cache point is which glTF vertex.
//!
//! A DCC's point cache holds the DCC's vertices, which the glTF exporters of Blender, Maya and
//! Houdini split into several glTF vertices along UV and normal seams: the cache has fewer
//! points than the glTF file, in another order. Split copies share their rest position and skin, so they are one
//! *group* here (welded on rest position and skinned trajectory), and each group must be one
//! cache point:
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

use crate::import::gltf::weld;
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
    let (g, m) = (rest.len(), cache.first().map_or(0, Vec::len));
    let identity = VertexMap {
        point_of: (0..g).collect(),
        note: None,
    };
    let mesh = Mesh {
        rest,
        triangles,
        primitives,
        skin,
    };
    if m == g && in_gltf_order(&mesh, cache, bind) {
        return Ok(identity);
    }
    match by_matching(&mesh, cache, bind) {
        // As many points as vertices, none matched: the glTF's order it is, and the rig's skin
        // judges it before training (with a message about the cache's space).
        Err(_) if m == g => Ok(identity),
        found => found,
    }
}

/// The glTF side of the mapping.
struct Mesh<'a> {
    rest: &'a [DVec3],
    triangles: &'a [[usize; 3]],
    primitives: &'a [Range<usize>],
    skin: &'a [Vec<DVec3>],
}

/// Whether the cache's points, as many as the vertices, are the vertices in the glTF's order:
/// unless some other order fits far better.
fn in_gltf_order(mesh: &Mesh, cache: &[Vec<DVec3>], bind: Option<usize>) -> bool {
    let (rest, skin) = (mesh.rest, mesh.skin);
    let g = rest.len();
    let size = diagonal(rest);
    let by_position = bind.is_some();
    let reference = bind.unwrap_or_else(|| least_moving(rest, skin));
    let points = tree(&cache[reference]);
    let near = |query: DVec3, cost: &dyn Fn(usize) -> f64| candidates(&points, query, cost);

    {
        let cost = |v: usize, p: usize| match bind {
            Some(s) => (cache[s][p] - rest[v]).length(),
            None => trajectory_distance(skin, cache, v, p),
        };
        let query = |v: usize| {
            if by_position {
                rest[v]
            } else {
                skin[reference][v]
            }
        };
        let identity: f64 = (0..g).map(|v| cost(v, v).powi(2)).sum();
        let nearest: f64 = (0..g)
            .map(|v| {
                near(query(v), &|p| cost(v, p))
                    .first()
                    .map_or(f64::INFINITY, |c| c.0.powi(2))
            })
            .sum();
        identity <= 4.0 * nearest + (1e-9 * size).powi(2) * g as f64
    }
}

/// Each cache point found among the glTF's vertices (module docs).
fn by_matching(
    mesh: &Mesh,
    cache: &[Vec<DVec3>],
    bind: Option<usize>,
) -> Result<VertexMap, String> {
    let (rest, triangles, primitives, skin) =
        (mesh.rest, mesh.triangles, mesh.primitives, mesh.skin);
    let (g, m) = (rest.len(), cache.first().map_or(0, Vec::len));
    let size = diagonal(rest);
    let by_position = bind.is_some();
    let reference = bind.unwrap_or_else(|| least_moving(rest, skin));
    let points = tree(&cache[reference]);
    let near = |query: DVec3, cost: &dyn Fn(usize) -> f64| candidates(&points, query, cost);

    let group = weld(rest, skin);
    let groups = group.iter().max().map_or(0, |x| x + 1);
    let mut representative = vec![usize::MAX; groups];
    for (v, &k) in group.iter().enumerate().rev() {
        representative[k] = v;
    }
    if groups > m {
        return Err(format!(
            "{m} points for the rig's {g} vertices, which are {groups} distinct ones (by rest position and skin): the cache has too few points for this mesh"
        ));
    }
    let same_point = |a: usize, b: usize| {
        cache
            .iter()
            .all(|s| (s[a] - s[b]).length() <= SAME_POINT * size)
    };
    let way_out = "either put the bind pose on one frame of the clip and the cache (points are then matched by position), or write the cache in the glTF file's vertex order (tools/blender/export_examples.py writes examples directly)";
    // By trajectory, the skin's prediction is refined by the residual of the confident
    // matches around each vertex (a deformer's deviation from the skin is smooth on the mesh).
    let mut predicted: Vec<Vec<DVec3>> = skin.to_vec();
    let rest_tree = tree(&representative.iter().map(|&v| rest[v]).collect::<Vec<_>>());
    let mut adjacent = vec![Vec::new(); groups];
    for t in triangles {
        for (a, b) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
            let (a, b) = (group[a], group[b]);
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
    let mut round = 0;
    let mut matched = loop {
        let matched = assign(
            &representative,
            m,
            |v| match bind {
                Some(_) => near(rest[v], &|p| (cache[reference][p] - rest[v]).length()),
                None => near(predicted[reference][v], &|p| {
                    trajectory_distance(&predicted, cache, v, p)
                }),
            },
            |v, p| match bind {
                Some(s) => (cache[s][p] - rest[v]).length(),
                None => trajectory_distance(&predicted, cache, v, p),
            },
            &same_point,
        );
        round += 1;
        if by_position || matched.ambiguous == 0 || round == REFINEMENTS {
            break matched;
        }
        predicted = refined(
            rest,
            skin,
            cache,
            &representative,
            &group,
            &adjacent,
            &matched,
            &rest_tree,
        );
    };
    let placed = match (by_position, matched.ambiguous) {
        (false, 1..) => by_order(&mut matched, &group, primitives)?,
        _ => 0,
    };
    let Matched {
        point_of_group,
        used,
        ambiguous,
        worst,
        largest,
        ..
    } = matched;
    if let Some(k) = point_of_group.iter().position(|&p| p == usize::MAX) {
        return Err(format!(
            "glTF vertex {} matches none of its {CANDIDATES} nearest free cache points: the cache's points are not the rig's vertices; {way_out}",
            representative[k]
        ));
    }
    if ambiguous > 0 {
        return Err(format!(
            "cannot tell which of the cache's {m} points are the rig's {g} glTF vertices: {ambiguous} of {groups} match a second point nearly as well (worst: glTF vertex {}, {:.2} of the next point's distance; at most {MARGIN} is taken){}; {way_out}",
            worst.1,
            worst.0,
            if by_position { "" } else { ", matched by trajectory: the clip has no frame at the bind pose" }
        ));
    }
    let copies_a_used_point = |p: usize| {
        points
            .nearest(
                &cache[reference][p].to_array(),
                4.min(m),
                &squared_euclidean,
            )
            .is_ok_and(|n| n.iter().any(|&(_, &q)| used[q] && same_point(p, q)))
    };
    if let Some(p) = (0..m).find(|&p| !used[p] && !copies_a_used_point(p)) {
        return Err(format!(
            "cache point {p} is none of the rig's vertices (the cache has {m} points, the rig {groups} distinct vertices): the cache is of another mesh, or of more of it; {way_out}"
        ));
    }
    let how = match bind {
        Some(s) => format!(
            "by position at the bind pose (sample {s}), largest residual {:.1e} of the mesh size",
            largest / size
        ),
        None => {
            let deviation: f64 = (0..groups)
                .map(|k| {
                    trajectory_distance(skin, cache, representative[k], point_of_group[k]).powi(2)
                })
                .sum();
            let order = match placed {
                0 => String::new(),
                n => format!(", {n} of them placed by the exporter's vertex order, which the other matches keep"),
            };
            format!(
                "by trajectory over {} samples against the glTF's own skin ({round} rounds{order}), RMS residual {:.2} % of the mesh size (the rig's deviation from its skin)",
                cache.len(),
                100.0 * (deviation / groups as f64).sqrt() / size,
            )
        }
    };
    Ok(VertexMap {
        point_of: group.iter().map(|&k| point_of_group[k]).collect(),
        note: Some(format!(
            "cache has {m} points in its own order for the rig's {g} glTF vertices ({groups} distinct: the DCC's vertices, split at seams in the glTF): mapped {how}"
        )),
    })
}

/// Rounds of matching by trajectory (the first against the skin alone).
const REFINEMENTS: usize = 4;
/// Confident matches around a vertex whose residuals refine its prediction.
const NEIGHBOURS: usize = 6;

/// A greedy assignment of groups to points and how clear it is.
struct Matched {
    /// Per group its point (usize::MAX: none left).
    point_of_group: Vec<usize>,
    used: Vec<bool>,
    /// Groups whose match is not clearly better than the next distinct point.
    ambiguous: usize,
    /// The largest cost ratio to the next distinct point, and its glTF vertex.
    worst: (f64, usize),
    /// The largest cost of a match.
    largest: f64,
    /// Per group: whether its match is clear.
    clear: Vec<bool>,
}

/// Pairs (group, candidate point) taken cheapest first while both are free.
fn assign(
    representative: &[usize],
    m: usize,
    candidates_of: impl Fn(usize) -> Vec<(f64, usize)> + Sync,
    cost: impl Fn(usize, usize) -> f64,
    same_point: &(dyn Fn(usize, usize) -> bool + Sync),
) -> Matched {
    let candidates: Vec<Vec<(f64, usize)>> = representative
        .par_iter()
        .map(|&v| candidates_of(v))
        .collect();
    let mut pairs: Vec<(f64, usize, usize)> = candidates
        .iter()
        .enumerate()
        .flat_map(|(k, c)| c.iter().map(move |&(d, p)| (d, k, p)))
        .collect();
    pairs.sort_by(|a, b| a.0.total_cmp(&b.0));
    let groups = representative.len();
    let (mut point_of_group, mut cost_of_group, mut used) =
        (vec![usize::MAX; groups], vec![0.0; groups], vec![false; m]);
    for &(d, k, p) in &pairs {
        if point_of_group[k] == usize::MAX && !used[p] {
            point_of_group[k] = p;
            cost_of_group[k] = d;
            used[p] = true;
        }
    }
    let mut owner = vec![usize::MAX; m];
    for (k, &p) in point_of_group.iter().enumerate() {
        if p != usize::MAX {
            owner[p] = k;
        }
    }
    let mut matched = Matched {
        point_of_group,
        used,
        ambiguous: 0,
        worst: (0.0, 0),
        largest: 0.0,
        clear: vec![false; groups],
    };
    for (k, c) in candidates.iter().enumerate() {
        let (p, d) = (matched.point_of_group[k], cost_of_group[k]);
        if p == usize::MAX {
            continue;
        }
        matched.largest = matched.largest.max(d);
        // Against every exchange with another distinct candidate q (not a copy of p): k takes
        // q and q's group, if any, takes p. The match is clear when each costs far more.
        let ratio = c
            .iter()
            .filter(|&&(_, q)| q != p && !same_point(p, q))
            .map(|&(dq, q)| match owner[q] {
                usize::MAX => d / dq,
                o => (d + cost_of_group[o]) / (dq + cost(representative[o], p)),
            })
            .map(|r| if r.is_nan() { f64::INFINITY } else { r })
            .fold(0.0, f64::max);
        matched.clear[k] = ratio <= MARGIN;
        if !matched.clear[k] {
            matched.ambiguous += 1;
        }
        if ratio > matched.worst.0 {
            matched.worst = (ratio, representative[k]);
        }
    }
    matched
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
) -> Result<usize, String> {
    let m = matched.used.len();
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
    matched.used = owner.iter().map(|&o| o != usize::MAX).collect();
    matched.ambiguous = matched.clear.iter().filter(|&&c| !c).count();
    Ok(placed)
}

/// The skin's prediction plus, per sample, the mean residual (cache − skin) of the nearest
/// clearly matched groups around each vertex (by rest position, the vertex's own excluded).
fn refined(
    rest: &[DVec3],
    skin: &[Vec<DVec3>],
    cache: &[Vec<DVec3>],
    representative: &[usize],
    group: &[usize],
    adjacent: &[Vec<usize>],
    matched: &Matched,
    rest_tree: &KdTree<f64, usize, [f64; 3]>,
) -> Vec<Vec<DVec3>> {
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

/// The CANDIDATES points of `points` nearest `query`, cheapest first by `cost`.
fn candidates(
    points: &KdTree<f64, usize, [f64; 3]>,
    query: DVec3,
    cost: &dyn Fn(usize) -> f64,
) -> Vec<(f64, usize)> {
    let mut c: Vec<(f64, usize)> = points
        .nearest(
            &query.to_array(),
            CANDIDATES.min(points.size()),
            &squared_euclidean,
        )
        .map_or_else(
            |_| Vec::new(),
            |n| n.iter().map(|&(_, &p)| (cost(p), p)).collect(),
        );
    c.sort_by(|a, b| a.0.total_cmp(&b.0));
    c
}

/// The length of the bounding box's diagonal (at least 1e-12).
pub fn diagonal(points: &[DVec3]) -> f64 {
    let (lo, hi) = points.iter().fold(
        (DVec3::splat(f64::MAX), DVec3::splat(f64::MIN)),
        |(lo, hi), p| (lo.min(*p), hi.max(*p)),
    );
    (hi - lo).length().max(1e-12)
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

/// RMS over samples of |cache[s][p] − skin[s][v]|.
fn trajectory_distance(skin: &[Vec<DVec3>], cache: &[Vec<DVec3>], v: usize, p: usize) -> f64 {
    let mut d: Vec<f64> = skin
        .iter()
        .zip(cache)
        .map(|(a, b)| (b[p] - a[v]).length_squared())
        .collect();
    d.sort_by(f64::total_cmp);
    d[d.len() / 2].sqrt()
}

/// The sample in which the skinned mesh is nearest its rest pose (where a neighbour in space is
/// most likely a neighbour on the mesh).
fn least_moving(rest: &[DVec3], skin: &[Vec<DVec3>]) -> usize {
    (0..skin.len())
        .min_by(|&a, &b| {
            let moved = |s: usize| -> f64 {
                skin[s]
                    .iter()
                    .zip(rest)
                    .map(|(p, r)| (*p - *r).length_squared())
                    .sum()
            };
            moved(a).total_cmp(&moved(b))
        })
        .unwrap_or(0)
}
