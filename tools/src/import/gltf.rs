//! An example set from a rig (glTF, or FBX through `fbx_rig`, or USD through `usd_rig`) and a
//! point cache (PC2, MDD, Alembic, USD or a mesh sequence).
//!
//! glTF splits vertices along UV and normal seams. Vertices at the same rest position whose
//! cache trajectories agree are welded into one training vertex, so the mesh is connected for
//! the Poisson solve; `weld` maps every glTF vertex to its training vertex, so a trained model
//! can be expanded back to the file's own vertex order and count, with the file's rest tangents
//! (TANGENT, or MikkTSpace from TEXCOORD_0: `import::tangents`).

use crate::import::align::{align, Aligned};
use crate::import::point_cache::PointCache;
use crate::import::preflight;
use crate::import::rig::{at_bind_pose, Rig};
use crate::import::tangents::{rest_tangents, Source};
use crate::import::weld::weld;
use crate::set::{diagonal, Affine, ExampleSet, InputError, Pose, SetFiles, SetParts};
use glam::DVec3;
use std::path::{Path, PathBuf};

#[derive(Debug, Clone)]
pub struct Options {
    /// The animation whose samples pose the rig.
    pub clip: String,
    pub cache: PathBuf,
    pub fps: f64,
    /// Cache frames (inclusive range) held out as test poses.
    pub test_frames: Option<(f64, f64)>,
}

pub struct Imported {
    pub set: ExampleSet,
    /// glTF vertex → training vertex.
    pub weld: Vec<usize>,
    /// The glTF rest mesh and triangles (the file's own order and count).
    pub rest: Vec<DVec3>,
    pub triangles: Vec<[usize; 3]>,
    /// Rest tangents over the glTF vertices, and their source; `None` without TANGENT or
    /// TEXCOORD_0 (the model then has no tangents, and the set says so in its warnings).
    pub tangents: Option<(Vec<[f32; 4]>, Source)>,
    /// What was found and fixed in the inputs (morph targets, cache alignment): the file and a
    /// line each.
    pub notes: Vec<(PathBuf, String)>,
}

/// The example set of the rig at `rig_path` posed by `options`' point cache, lined up with the
/// rig's animation and welded across the glTF's seams.
pub fn import(rig_path: &Path, options: &Options) -> Result<Imported, InputError> {
    if !(options.fps.is_finite() && options.fps > 0.0) {
        return Err(InputError {
            file: options.cache.clone(),
            message: format!("--fps {} must be positive", options.fps),
        });
    }
    let mut rig = Rig::load(rig_path, &options.clip)?;
    let cache = PointCache::load(&options.cache, options.fps)?;
    let aligned = align(
        &rig,
        rig_path,
        &cache,
        &options.cache,
        &options.clip,
        options.fps,
    )?;
    check_test_frames(options, &aligned.frames)?;
    if rig.base_mesh {
        rest_at_bind_sample(&mut rig, &aligned);
    }
    let weld = weld(&rig.rest, &aligned.positions);
    let is_test: Vec<bool> = aligned
        .frames
        .iter()
        .map(|&f| options.test_frames.is_some_and(|r| in_range(f, r)))
        .collect();
    let parts = set_parts(&rig, &weld, &aligned.positions, aligned.bones, is_test);
    let groups = normal_groups(&weld);
    let tangents = rest_tangents(
        &rig.rest,
        &rig.triangles,
        &groups,
        rig.uvs.as_deref(),
        rig.tangents.as_deref(),
    );
    let files = set_files(rig_path, options, &aligned.times);
    let mut set = ExampleSet::new(parts, &files)?;
    if tangents.is_none() {
        set.warnings.push(format!(
            "{}: no per-vertex UVs or tangents (glTF: TANGENT or TEXCOORD_0 on every primitive, or MikkTSpace failed; FBX: UVs are not read): the model has no tangents",
            rig_path.display()
        ));
    }
    let fix = format!("the cache is not this rig's motion as {} exports it. Bake the cache from this rig and clip, in world space (PC2: 'Export into Worldspace'), in the glTF's Y-up or Blender's Z-up, in the rig's units, over the clip's frames", rig_path.display());
    preflight::check(&mut set, &options.cache, &fix, rig_path)?;
    let notes = (rig
        .notes
        .iter()
        .map(|n| (rig_path.to_path_buf(), n.clone())))
    .chain(
        aligned
            .notes
            .iter()
            .map(|n| (options.cache.clone(), n.clone())),
    )
    .collect();
    Ok(Imported {
        notes,
        set,
        weld,
        rest: rig.rest,
        triangles: rig.triangles,
        tangents,
    })
}

/// A rig whose rest is its base mesh ([`Rig::base_mesh`]) rests where the cache's first sample
/// at the bind pose has it: the base mesh as the DCC's deformers leave it there, what every
/// pose's motion starts from (a NumPy set's rest, from the DCC's evaluation). A note says so,
/// and how far that is from the file's mesh.
fn rest_at_bind_sample(rig: &mut Rig, aligned: &Aligned) {
    let size = diagonal(&rig.rest);
    let Some(k) = (aligned.bones.iter()).position(|b| at_bind_pose(b, size)) else {
        return;
    };
    let sample = &aligned.positions[k];
    let moved = (rig.rest.iter().zip(sample))
        .map(|(a, b)| a.distance(*b))
        .fold(0.0, f64::max);
    rig.notes.push(format!(
        "the rest mesh is the cache's sample {k} (frame {}, at the bind pose): the file's is the mesh before the DCC's deformers, up to {:.3} % of the mesh size from it",
        aligned.frames[k],
        100.0 * moved / size
    ));
    rig.rest = sample.clone();
}

/// The example set over the training vertices: each welded group of glTF vertices taken at
/// its first (rest position, cache positions, the rig's weights), the triangles the weld does
/// not collapse, one pose per cache sample (`positions`, `bones`, `is_test`).
fn set_parts(
    rig: &Rig,
    weld: &[usize],
    positions: &[Vec<DVec3>],
    bones: Vec<Vec<Affine>>,
    is_test: Vec<bool>,
) -> SetParts {
    let representative = first_duplicates(weld);
    let faces: Vec<[usize; 3]> = rig
        .triangles
        .iter()
        .map(|t| t.map(|g| weld[g]))
        .filter(|[a, b, c]| a != b && b != c && a != c)
        .collect();
    let poses: Vec<Pose> = positions
        .iter()
        .zip(bones)
        .map(|(positions, bones)| Pose {
            bones,
            vertices: representative.iter().map(|&g| positions[g]).collect(),
        })
        .collect();
    SetParts {
        rest: representative.iter().map(|&g| rig.rest[g]).collect(),
        faces,
        parents: rig.parents.clone(),
        poses,
        is_test,
        bone_names: Some(rig.names.clone()),
        rig_weights: Some(
            representative
                .iter()
                .map(|&g| rig.weights[g].clone())
                .collect(),
        ),
    }
}

/// Where the set's parts came from: the rig file, the split from the cache; each pose named by
/// its cache sample and time (`times`).
fn set_files(rig_path: &Path, options: &Options, times: &[f64]) -> SetFiles {
    SetFiles {
        split: options.cache.clone(),
        pose_labels: Some(
            times
                .iter()
                .enumerate()
                .map(|(s, t)| format!("sample {s} (t = {t:.4} s)"))
                .collect(),
        ),
        ..SetFiles::one(rig_path)
    }
}

/// `--test-frames` must select samples inside the cache (`frames`: the clip's frame of each
/// sample, the DCC's frame numbers).
fn check_test_frames(options: &Options, frames: &[f64]) -> Result<(), InputError> {
    let Some((a, b)) = options.test_frames else {
        return Ok(());
    };
    let bad = |message: String| InputError {
        file: options.cache.clone(),
        message,
    };
    let lo = frames.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = frames.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    if a < lo - FRAME_SLACK || b > hi + FRAME_SLACK {
        return Err(bad(format!(
            "--test-frames {a}..{b} reaches outside the cache, whose frames are {lo}..{hi}"
        )));
    }
    if !frames.iter().any(|&f| in_range(f, (a, b))) {
        return Err(bad(format!(
            "--test-frames {a}..{b} holds none of the cache's frames: no test poses"
        )));
    }
    Ok(())
}

/// Frame numbers are compared with this slack (f32 start and rate in PC2 headers).
const FRAME_SLACK: f64 = 1e-6;

fn in_range(frame: f64, (a, b): (f64, f64)) -> bool {
    frame >= a - FRAME_SLACK && frame <= b + FRAME_SLACK
}

impl Imported {
    /// The runtime model over the glTF file's own vertices (order and count), so an engine keeps
    /// its index buffer, UVs and materials: each vertex takes its training vertex's skinning,
    /// and welded duplicates form one normal group (they shade as one vertex across the seam).
    pub fn expand(&self, model: &rrskin::Model) -> rrskin::Result<rrskin::Model> {
        let parts = model.parts();
        let k = model.influences();
        let per_vertex = |data: &[u32]| -> Vec<u32> {
            self.weld
                .iter()
                .flat_map(|&w| data[w * k..(w + 1) * k].to_vec())
                .collect()
        };
        rrskin::Model::new(rrskin::ModelParts {
            rest_positions: self.rest.iter().map(|p| p.as_vec3().to_array()).collect(),
            triangles: self.triangles.iter().map(|t| t.map(|g| g as u32)).collect(),
            bone_parents: parts.bone_parents.clone(),
            influences: parts.influences,
            skin_indices: per_vertex(&parts.skin_indices),
            skin_weights: self
                .weld
                .iter()
                .flat_map(|&w| parts.skin_weights[w * k..(w + 1) * k].to_vec())
                .collect(),
            keys: parts.keys.clone(),
            c1: parts.c1.clone(),
            c2: parts.c2.clone(),
            normal_groups: normal_groups(&self.weld)
                .iter()
                .map(|&g| g as u32)
                .collect(),
            baseline_indices: per_vertex(&parts.baseline_indices),
            baseline_weights: self
                .weld
                .iter()
                .flat_map(|&w| parts.baseline_weights[w * k..(w + 1) * k].to_vec())
                .collect(),
            animation: parts.animation.clone(),
            rest_tangents: self.tangents.as_ref().map_or(Vec::new(), |t| t.0.clone()),
            correctives: parts
                .correctives
                .as_ref()
                .map(|c| rrskin::model::Correctives {
                    targets: per_target(&c.targets, model.vertex_count(), &self.weld),
                    ..c.clone()
                }),
            proxy_correctives: parts.proxy_correctives.clone(),
        })
    }
}

/// Per training vertex (weld group), its first glTF vertex.
fn first_duplicates(weld: &[usize]) -> Vec<usize> {
    let welded = weld.iter().max().map_or(0, |m| m + 1);
    let mut first = vec![usize::MAX; welded];
    for (g, &w) in weld.iter().enumerate() {
        if first[w] == usize::MAX {
            first[w] = g;
        }
    }
    first
}

/// Each glTF vertex's normal group: the first glTF vertex welded with it.
fn normal_groups(weld: &[usize]) -> Vec<usize> {
    let first = first_duplicates(weld);
    weld.iter().map(|&w| first[w]).collect()
}

impl Imported {
    /// The inverse of [`Imported::expand`]: a model over the glTF vertices restricted to the
    /// training vertices (each takes its first glTF duplicate), for evaluation on the set.
    pub fn collapse(&self, model: &rrskin::Model) -> rrskin::Result<rrskin::Model> {
        if model.vertex_count() != self.weld.len() {
            return Err(rrskin::Error::WrongLength {
                what: "model vertices (the glTF rig's vertex count)",
                expected: self.weld.len(),
                actual: model.vertex_count(),
            });
        }
        let parts = model.parts();
        let k = model.influences();
        let first = first_duplicates(&self.weld);
        rrskin::Model::new(rrskin::ModelParts {
            rest_positions: self
                .set
                .rest
                .iter()
                .map(|p| p.as_vec3().to_array())
                .collect(),
            triangles: self.set.faces.iter().map(|t| t.map(|a| a as u32)).collect(),
            bone_parents: parts.bone_parents.clone(),
            influences: parts.influences,
            skin_indices: first
                .iter()
                .flat_map(|&g| parts.skin_indices[g * k..(g + 1) * k].to_vec())
                .collect(),
            skin_weights: first
                .iter()
                .flat_map(|&g| parts.skin_weights[g * k..(g + 1) * k].to_vec())
                .collect(),
            keys: parts.keys.clone(),
            c1: parts.c1.clone(),
            c2: parts.c2.clone(),
            normal_groups: Vec::new(),
            baseline_indices: first
                .iter()
                .flat_map(|&g| parts.baseline_indices[g * k..(g + 1) * k].to_vec())
                .collect(),
            baseline_weights: first
                .iter()
                .flat_map(|&g| parts.baseline_weights[g * k..(g + 1) * k].to_vec())
                .collect(),
            animation: parts.animation.clone(),
            rest_tangents: Vec::new(),
            correctives: parts
                .correctives
                .as_ref()
                .map(|c| rrskin::model::Correctives {
                    targets: per_target(&c.targets, model.vertex_count(), &first),
                    ..c.clone()
                }),
            proxy_correctives: parts.proxy_correctives.clone(),
        })
    }
}

/// N targets of `v` vertices each (target-major), re-indexed: vertex g of each new target is
/// vertex `from[g]` of the old.
fn per_target(targets: &[[f32; 3]], v: usize, from: &[usize]) -> Vec<[f32; 3]> {
    targets
        .chunks_exact(v.max(1))
        .flat_map(|t| from.iter().map(|&g| t[g]))
        .collect()
}
