//! Welding: vertices a glTF splits along UV and normal seams (the same rest position and the
//! same trajectory under a cache) are one training vertex, so the mesh is connected for the
//! Poisson solve.

use glam::DVec3;
use std::collections::HashMap;

/// Welding tolerances relative to the rest mesh's bounding-box diagonal.
const WELD_REST: f64 = 1e-6;
const WELD_TRAJECTORY: f64 = 1e-5;

/// Groups vertices with equal rest positions and trajectories; returns each vertex's group, the
/// groups numbered in order of first appearance.
pub fn weld(rest: &[DVec3], trajectories: &[Vec<DVec3>]) -> Vec<usize> {
    let scale = crate::set::diagonal(rest);
    let cell = WELD_REST * scale * 4.0;
    let key = |p: DVec3| ((p / cell).round().as_i64vec3()).to_array();
    let mut buckets: HashMap<[i64; 3], Vec<usize>> = HashMap::new();
    let mut group = vec![0usize; rest.len()];
    let mut groups = 0;
    for (g, &p) in rest.iter().enumerate() {
        let candidates = buckets.entry(key(p)).or_default();
        let same = candidates.iter().copied().find(|&h| {
            (rest[h] - p).length() <= WELD_REST * scale
                && trajectories
                    .iter()
                    .all(|t| (t[h] - t[g]).length() <= WELD_TRAJECTORY * scale)
        });
        group[g] = match same {
            Some(h) => group[h],
            None => {
                candidates.push(g);
                groups += 1;
                groups - 1
            }
        };
    }
    group
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A unit cube the way glTF stores it: 6 faces x 4 vertices (split along every seam).
    fn split_cube() -> Vec<DVec3> {
        let mut v = Vec::new();
        for axis in 0..3 {
            for side in [-0.5, 0.5] {
                for (a, b) in [(-0.5, -0.5), (0.5, -0.5), (0.5, 0.5), (-0.5, 0.5)] {
                    let mut p = [0.0; 3];
                    p[axis] = side;
                    p[(axis + 1) % 3] = a;
                    p[(axis + 2) % 3] = b;
                    v.push(DVec3::from(p));
                }
            }
        }
        v
    }

    #[test]
    fn a_cube_with_split_seams_welds_to_8_vertices_and_maps_back() {
        let rest = split_cube();
        assert_eq!(rest.len(), 24);
        let moved: Vec<Vec<DVec3>> = (0..3)
            .map(|i| {
                rest.iter()
                    .map(|p| *p * (1.0 + i as f64) + DVec3::X)
                    .collect()
            })
            .collect();
        let group = weld(&rest, &moved);
        assert_eq!(group.iter().max().map(|m| m + 1), Some(8));
        for (g, h) in (0..24).flat_map(|g| (0..24).map(move |h| (g, h))) {
            assert_eq!(
                group[g] == group[h],
                rest[g] == rest[h],
                "vertices {g} and {h}"
            );
        }
        // Same rest position but a different trajectory (a torn seam) stays apart.
        let mut torn = moved.clone();
        torn[2][0] += DVec3::Y;
        assert_eq!(weld(&rest, &torn).iter().max().map(|m| m + 1), Some(9));
    }
}
