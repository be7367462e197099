//! Rest tangents of a glTF mesh, for normal-mapped materials: the file's TANGENT where every
//! primitive has one, else MikkTSpace (what glTF asks of clients for files without TANGENT, and
//! what baked normal maps expect; the `mikktspace` crate) from the rest positions, the rest
//! normals the runtime computes (area-weighted over each welded group) and TEXCOORD_0.
//!
//! MikkTSpace gives a tangent per triangle corner. The corners of one vertex agree unless the
//! vertex sits where MikkTSpace splits the tangent space; there their sum is kept. Each
//! generated tangent is then made orthogonal to the rest normal and normalised (the runtime
//! does the same every frame); one that vanishes takes a direction orthogonal to the normal.

use glam::DVec3;

/// Where a mesh's tangents come from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Source {
    /// The file's TANGENT attribute.
    File,
    /// MikkTSpace from TEXCOORD_0.
    MikkTSpace,
}

/// Per glTF vertex, xyz unit and w = ±1 (glTF's TANGENT layout), and where they came from;
/// `None` when the mesh has neither TANGENT nor TEXCOORD_0 on every primitive (or MikkTSpace
/// fails on it). `groups[v]` is vertex v's normal group (welded seam duplicates share one).
pub fn rest_tangents(
    rest: &[DVec3],
    triangles: &[[usize; 3]],
    groups: &[usize],
    uvs: Option<&[[f32; 2]]>,
    file: Option<&[[f32; 4]]>,
) -> Option<(Vec<[f32; 4]>, Source)> {
    if let Some(file) = file {
        return Some((file.to_vec(), Source::File));
    }
    // The runtime's normals at rest, over each welded group.
    let normals =
        rrskin::normals::area_weighted_grouped(rest, triangles.iter().copied(), |v| groups[v]);
    let mut mesh = Mesh {
        rest,
        triangles,
        normals: &normals,
        uvs: uvs?,
        sums: vec![(DVec3::ZERO, 0.0); rest.len()],
    };
    if !mikktspace::generate_tangents(&mut mesh) {
        return None;
    }
    let tangents = (mesh.sums.iter().zip(&normals))
        .map(|(&(t, w), &n)| {
            let t = orthogonal_unit(t, n);
            let w = if w < 0.0 { -1.0 } else { 1.0 };
            [t.x as f32, t.y as f32, t.z as f32, w]
        })
        .collect();
    Some((tangents, Source::MikkTSpace))
}

/// `t` without its component along the unit `n`, normalised; where nothing is left, the axis
/// least aligned with `n` made orthogonal to it.
fn orthogonal_unit(t: DVec3, n: DVec3) -> DVec3 {
    let t = t - n * n.dot(t);
    if t.length() > 1e-9 {
        return t.normalize();
    }
    let a = n.abs();
    let axis = if a.x <= a.y && a.x <= a.z {
        DVec3::X
    } else if a.y <= a.z {
        DVec3::Y
    } else {
        DVec3::Z
    };
    (axis - n * n.dot(axis)).normalize()
}

/// The mesh as MikkTSpace reads it, and the per-vertex sums of what it writes.
struct Mesh<'a> {
    rest: &'a [DVec3],
    triangles: &'a [[usize; 3]],
    normals: &'a [DVec3],
    uvs: &'a [[f32; 2]],
    /// Per vertex: the sum of its corners' tangents and of their handedness.
    sums: Vec<(DVec3, f64)>,
}

impl mikktspace::Geometry for Mesh<'_> {
    fn num_faces(&self) -> usize {
        self.triangles.len()
    }

    fn num_vertices_of_face(&self, _face: usize) -> usize {
        3
    }

    fn position(&self, face: usize, vert: usize) -> [f32; 3] {
        self.rest[self.triangles[face][vert]].as_vec3().to_array()
    }

    fn normal(&self, face: usize, vert: usize) -> [f32; 3] {
        self.normals[self.triangles[face][vert]]
            .as_vec3()
            .to_array()
    }

    /// glTF puts the UV origin at the top left, MikkTSpace (and the normal maps baked with it)
    /// at the bottom left: v is flipped so that w follows glTF's convention.
    fn tex_coord(&self, face: usize, vert: usize) -> [f32; 2] {
        let [u, v] = self.uvs[self.triangles[face][vert]];
        [u, 1.0 - v]
    }

    fn set_tangent_encoded(&mut self, tangent: [f32; 4], face: usize, vert: usize) {
        let sum = &mut self.sums[self.triangles[face][vert]];
        sum.0 += DVec3::new(tangent[0] as f64, tangent[1] as f64, tangent[2] as f64);
        sum.1 += tangent[3] as f64;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A unit square in the xy plane, two triangles, UVs = (x, 1 − y) as glTF would store an
    /// unmirrored texture (v down): tangent +x, bitangent cross(n, t) = +y = up the texture,
    /// so w = +1; mirrored in u, tangent −x and w = −1.
    #[test]
    fn a_square_gets_its_texture_axes() {
        let rest = [
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(1.0, 1.0, 0.0),
            DVec3::new(0.0, 1.0, 0.0),
        ];
        let triangles = [[0, 1, 2], [0, 2, 3]];
        let groups = [0, 1, 2, 3];
        let uvs: Vec<[f32; 2]> = rest
            .iter()
            .map(|p| [p.x as f32, 1.0 - p.y as f32])
            .collect();
        let (t, source) =
            rest_tangents(&rest, &triangles, &groups, Some(&uvs), None).expect("tangents");
        assert_eq!(source, Source::MikkTSpace);
        for x in &t {
            assert!((x[0] - 1.0).abs() < 1e-5 && x[1].abs() < 1e-5 && x[2].abs() < 1e-5);
            assert_eq!(x[3], 1.0, "{t:?}");
        }
        let mirrored: Vec<[f32; 2]> = uvs.iter().map(|&[u, v]| [1.0 - u, v]).collect();
        let (t, _) =
            rest_tangents(&rest, &triangles, &groups, Some(&mirrored), None).expect("tangents");
        for x in &t {
            assert!((x[0] + 1.0).abs() < 1e-5 && x[3] == -1.0, "{t:?}");
        }
        assert!(rest_tangents(&rest, &triangles, &groups, None, None).is_none());
        let file = [[0.0, 1.0, 0.0, -1.0]; 4];
        assert_eq!(
            rest_tangents(&rest, &triangles, &groups, None, Some(&file)),
            Some((file.to_vec(), Source::File))
        );
    }

    #[test]
    fn a_vanishing_tangent_takes_a_direction_orthogonal_to_the_normal() {
        let n = DVec3::new(0.0, 0.6, 0.8);
        let t = orthogonal_unit(n * 2.0, n);
        assert!((t.length() - 1.0).abs() < 1e-12 && t.dot(n).abs() < 1e-12);
    }
}
