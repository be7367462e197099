//! Vertex normals of a skinned mesh, in the two ways the runtime offers ([`NormalMode`]), as
//! the CPU reference computes them (the GPU passes mirror them in `f32`).
//!
//! - **Recomputed** (paper §6): per vertex a, the area-weighted sum over the triangles around a
//!   (those of its normal group: welded seams share one) of `(p_j − p_i) × (p_k − p_i)` for
//!   triangle `(i, j, k)`, normalised (zero where it vanishes). Exact for any deformation, and
//!   it reads the 1-ring's skinned positions, hence a pass of its own after skinning.
//! - **Transformed** (what engines' skinning does): the rest normal `n̂_a` (the same sum over
//!   the rest positions) through the cofactor of the vertex's blended 3x3 `M_a`,
//!   `n_a = cof(M_a) n̂_a / |cof(M_a) n̂_a|`, in the skinning pass itself. `cof(M) = det(M) M⁻ᵀ`
//!   is the exact normal transform of a linear map, proxies' scale and shear included, and keeps
//!   the orientation of a mirroring one; what it misses is the deformation's variation across
//!   the vertex's ring (Tarini, Panozzo and Sorkine-Hornung 2014), which `rrskin eval` reports as
//!   the normals' angular error.

use glam::DVec3;

/// How a crowd's normals (and so its tangents, made orthogonal to them) are made.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum NormalMode {
    /// From the skinned positions over each vertex's 1-ring (paper §6): a second pass.
    #[default]
    Recomputed,
    /// The rest normals through the cofactor of each vertex's blended matrix, in the skinning
    /// pass: one pass a frame, as engines skin.
    Transformed,
}

/// Per vertex a, into `sums[group(a)]`, the sum of `(b − a) × (c − a)` over the triangles
/// around it (`sums`: V, cleared first; its allocation is reused): the area normals of a mesh's
/// triangles, each added to the normal group of each of its corners (`group`: vertex to group,
/// a vertex index; the identity where no vertices are welded). Vertex a's unit normal is
/// `sums[group(a)]` normalised (zero where it vanishes): what the normals pass computes.
pub fn area_weighted_sums(
    positions: &[DVec3],
    triangles: impl IntoIterator<Item = [usize; 3]>,
    group: impl Fn(usize) -> usize,
    sums: &mut Vec<DVec3>,
) {
    sums.clear();
    sums.resize(positions.len(), DVec3::ZERO);
    for t in triangles {
        let [a, b, c] = t.map(|i| positions[i]);
        let area_normal = (b - a).cross(c - a);
        for v in t {
            sums[group(v)] += area_normal;
        }
    }
}

/// Unit area-weighted vertex normals of a mesh ([`area_weighted_sums`], normalised).
pub fn area_weighted_grouped(
    positions: &[DVec3],
    triangles: impl IntoIterator<Item = [usize; 3]>,
    group: impl Fn(usize) -> usize,
) -> Vec<DVec3> {
    let mut sums = Vec::new();
    area_weighted_sums(positions, triangles, &group, &mut sums);
    (0..positions.len())
        .map(|v| sums[group(v)].normalize_or_zero())
        .collect()
}

/// Marks the first entry of a fan in [`Fans::entries`]: the fan's pivot.
pub const FAN_PIVOT: u32 = 1 << 31;

/// The triangles around each vertex as fans, the compact 1-ring the GPU's recomputed-normals
/// pass reads (`glsl/normals.comp`): vertex a's entries `entries[offsets[a]..offsets[a + 1]]`
/// are fans `[pivot | FAN_PIVOT, r_0, r_1, …, r_n]`, each standing for the n triangles
/// `(pivot, r_i, r_i+1)`, whose area normals `(p_{r_i} − p_pivot) × (p_{r_i+1} − p_pivot)` sum
/// to [`area_weighted_sums`]'s (the area normal of a triangle is the same from any corner). Around an
/// interior vertex of a manifold mesh one fan of valence + 2 entries replaces the triangles'
/// ids and their 3 corners each: about 8 index and 8 position loads instead of 24 and 18.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Fans {
    /// V + 1.
    pub offsets: Vec<u32>,
    pub entries: Vec<u32>,
}

impl Fans {
    /// The fans of the CSR lists of triangles around each vertex (`offsets`, `incident`: a
    /// model's [`crate::Model::incidence`]), where vertex a's triangles are pivoted at their
    /// corner in a's normal group (`group`: vertex to group, the identity where none are
    /// welded), or at their first corner.
    pub fn new(
        triangles: &[[u32; 3]],
        offsets: &[u32],
        incident: &[u32],
        group: impl Fn(u32) -> u32,
    ) -> Fans {
        let mut fans = Fans {
            offsets: vec![0],
            entries: Vec::with_capacity(incident.len() + 2 * offsets.len()),
        };
        let mut terms = Vec::new();
        for (a, window) in offsets.windows(2).enumerate() {
            terms.clear();
            let home = group(a as u32);
            for &t in &incident[window[0] as usize..window[1] as usize] {
                let [i, j, k] = triangles[t as usize];
                let rotated = [[i, j, k], [j, k, i], [k, i, j]];
                let pivoted = rotated.into_iter().find(|c| group(c[0]) == home);
                terms.push(pivoted.unwrap_or([i, j, k]));
            }
            chain(&mut terms, &mut fans.entries);
            fans.offsets.push(fans.entries.len() as u32);
        }
        fans
    }
}

/// Appends `terms` (triangles `[pivot, b, c]`) to `out` as fans: each starts where no other
/// triangle of the same pivot ends (an open fan), else anywhere (a closed one), and goes on
/// while one starts at its last corner.
fn chain(terms: &mut Vec<[u32; 3]>, out: &mut Vec<u32>) {
    while !terms.is_empty() {
        let opens = |t: &[u32; 3]| !terms.iter().any(|u| u[0] == t[0] && u[2] == t[1]);
        let first = terms.iter().position(opens).unwrap_or(0);
        let [pivot, b, mut c] = terms.swap_remove(first);
        out.extend([pivot | FAN_PIVOT, b, c]);
        while let Some(next) = terms.iter().position(|u| u[0] == pivot && u[1] == c) {
            c = terms.swap_remove(next)[2];
            out.push(c);
        }
    }
}

/// `cof(M) n`, unnormalised, for the 3x3 of a 3x4 row-major `m`: with M's columns `c0, c1, c2`,
/// `cof(M) = [c1 × c2 | c2 × c0 | c0 × c1]`.
pub fn cofactor_times(m: &[f64; 12], n: DVec3) -> DVec3 {
    let column = |j: usize| DVec3::new(m[j], m[4 + j], m[8 + j]);
    let (c0, c1, c2) = (column(0), column(1), column(2));
    n.x * c1.cross(c2) + n.y * c2.cross(c0) + n.z * c0.cross(c1)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DMat3;

    /// Unit area-weighted normals from [`Fans`]: what the GPU's normals pass computes, in `f64`.
    fn from_fans(positions: &[DVec3], fans: &Fans) -> Vec<DVec3> {
        (fans.offsets.windows(2))
            .map(|w| {
                let (mut sum, mut pivot, mut last) = (DVec3::ZERO, DVec3::ZERO, None);
                for &e in &fans.entries[w[0] as usize..w[1] as usize] {
                    if e & FAN_PIVOT != 0 {
                        (pivot, last) = (positions[(e & !FAN_PIVOT) as usize], None);
                        continue;
                    }
                    let r = positions[e as usize] - pivot;
                    if let Some(previous) = last {
                        sum += DVec3::cross(previous, r);
                    }
                    last = Some(r);
                }
                sum.normalize_or_zero()
            })
            .collect()
    }

    /// A grid of n x n vertices, two triangles a cell, with its incidence lists.
    fn grid(n: u32) -> (Vec<DVec3>, Vec<[u32; 3]>) {
        let positions = (0..n * n)
            .map(|i| {
                let (x, y) = ((i % n) as f64, (i / n) as f64);
                DVec3::new(x, y, 0.3 * (x * 1.3).sin() * (y * 0.7).cos())
            })
            .collect();
        let mut triangles = Vec::new();
        for y in 0..n - 1 {
            for x in 0..n - 1 {
                let a = y * n + x;
                triangles.push([a, a + 1, a + n + 1]);
                triangles.push([a, a + n + 1, a + n]);
            }
        }
        (positions, triangles)
    }

    fn usize_triangles(triangles: &[[u32; 3]]) -> impl Iterator<Item = [usize; 3]> + '_ {
        triangles.iter().map(|t| t.map(|x| x as usize))
    }

    fn incidence(v: usize, triangles: &[[u32; 3]]) -> (Vec<u32>, Vec<u32>) {
        let mut lists = vec![Vec::new(); v];
        for (t, tri) in triangles.iter().enumerate() {
            for &c in tri {
                lists[c as usize].push(t as u32);
            }
        }
        let offsets = std::iter::once(0)
            .chain(lists.iter().scan(0, |n, l| {
                *n += l.len() as u32;
                Some(*n)
            }))
            .collect();
        (offsets, lists.concat())
    }

    #[test]
    fn fans_give_the_incident_triangles_normals_in_fewer_entries() {
        let (positions, mut triangles) = grid(7);
        // A non-manifold extra: a triangle hanging off one edge, and one listed twice.
        triangles.push([8, 9, 20]);
        triangles.push(triangles[5]);
        let (offsets, incident) = incidence(positions.len(), &triangles);
        let fans = Fans::new(&triangles, &offsets, &incident, |v| v);
        let expected = area_weighted_grouped(&positions, usize_triangles(&triangles), |v| v);
        for (a, (got, want)) in from_fans(&positions, &fans)
            .iter()
            .zip(&expected)
            .enumerate()
        {
            assert!(
                (*got - *want).length() < 1e-12,
                "vertex {a}: {got} vs {want}"
            );
        }
        // An interior vertex of the grid: one closed fan of its 6 triangles.
        let a = 2 * 7 + 3;
        let entries = fans.offsets[a + 1] - fans.offsets[a];
        assert_eq!(
            entries,
            8,
            "{:?}",
            &fans.entries[fans.offsets[a] as usize..]
        );
        assert!(fans.entries.len() < incident.len() * 3 / 2);
    }

    #[test]
    fn fans_pivot_at_the_welded_twin() {
        // Two triangles sharing an edge whose corners 1 and 4 are one welded vertex.
        let positions = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [1.0, 1.0, 0.2],
            [1.0, 0.0, 0.0],
        ]
        .map(DVec3::from)
        .to_vec();
        let triangles = [[0, 1, 2], [4, 3, 2]];
        let group = |v: u32| if v == 4 { 1 } else { v };
        let offsets = vec![0, 1, 3, 5, 6, 8];
        let incident = vec![0, 0, 1, 0, 1, 1, 0, 1];
        let fans = Fans::new(&triangles, &offsets, &incident, group);
        let pivots = |a: usize| {
            (fans.entries[fans.offsets[a] as usize..fans.offsets[a + 1] as usize].iter())
                .filter(|&&e| e & FAN_PIVOT != 0)
                .map(|&e| e & !FAN_PIVOT)
                .collect::<Vec<_>>()
        };
        let mut at_one = pivots(1);
        at_one.sort();
        assert_eq!(at_one, [1, 4]);
        let sums = from_fans(&positions, &fans);
        let want = area_weighted_grouped(&positions, usize_triangles(&triangles), |v| {
            group(v as u32) as usize
        });
        assert!((sums[1] - want[1]).length() < 1e-12 && (sums[4] - sums[1]).length() < 1e-12);
    }

    #[test]
    fn the_cofactor_maps_a_normal_as_the_inverse_transpose_does() {
        // A shear with scale: normals of the transformed plane are M^-T n.
        let m = DMat3::from_cols_array(&[1.2, 0.3, -0.1, 0.4, 0.9, 0.2, 0.0, -0.5, 1.5]);
        let rows = m.transpose().to_cols_array();
        let affine = [
            rows[0], rows[1], rows[2], 0.0, rows[3], rows[4], rows[5], 0.0, rows[6], rows[7],
            rows[8], 0.0,
        ];
        let (u, v) = (DVec3::new(1.0, 0.2, 0.0), DVec3::new(-0.3, 1.0, 0.4));
        let n = u.cross(v);
        let expected = (m * u).cross(m * v);
        let got = cofactor_times(&affine, n);
        assert!((got - expected).length() < 1e-12 * expected.length());
        let inverse_transpose = m.inverse().transpose() * n;
        assert!((got.normalize() - inverse_transpose.normalize()).length() < 1e-12);
    }
}
