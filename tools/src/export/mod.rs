//! `rrskin export`: a runtime model as a standard skinned glTF 2.0 binary (.glb) that any
//! viewer or engine plays with its own skinning.
//!
//! The skin's joints are the model's palette, in its order: P proxies, then the J bones, each
//! an exact two-node form of its affine transform ([`bake()`]); the vertices' JOINTS_0/WEIGHTS_0
//! (and JOINTS_1/WEIGHTS_1 for K = 8) are the model's skin indices and weights, so a joint
//! index is a palette index. Inverse bind matrices are the identity: the palette maps rest
//! positions to posed ones. Every clip is baked through the model: the rig's clips with
//! `--rig` (all, or those named), else the model's own animation at `fps` frames a second
//! (between two of its frames the bones move as glTF would move them: slerped rotations,
//! lerped translations). With `--rig`, the mesh is the rig's own: its primitives, materials,
//! textures (embedded), UVs and joint names; without, the geometry alone. A model's pose-space
//! correctives (docs/method.md §20) are the mesh's morph targets (POSITION offsets in rest
//! space), their weights baked into every clip beside the joints; an engine that drives the
//! skeleton itself computes them per frame with the palette
//! (`rrskin::palette::Palette::corrective_weights`).

pub mod bake;
pub mod glb;

use crate::import::gltf_rig::load_buffers;
use crate::import::rig::Rig;
use crate::linalg::procrustes;
use crate::set::InputError;
use crate::{Error, Result};
use bake::{bake, Baked, NodePair};
use glam::{DMat3, DQuat, DVec3};
use glb::{Buffer, ARRAY_BUFFER};
use rrskin::palette::{Palette, Skin};
use rrskin::predict::{rotation_of, Affine};
use rrskin::Model;
use serde_json::{json, Value};
use std::path::{Path, PathBuf};

#[derive(Debug, Clone)]
pub struct Options {
    pub output: PathBuf,
    /// The glTF rig the model was trained from: its mesh, materials and clips.
    pub rig: Option<PathBuf>,
    /// Clips of the rig to bake (empty: every clip).
    pub clips: Vec<String>,
    /// Frames a second of the model's own animation (without `rig`).
    pub fps: f64,
    /// Largest vertex distance allowed between the played file and the model, relative to the
    /// rest mesh's bounding-box diagonal.
    pub tolerance: f64,
}

/// The default of [`Options::tolerance`]: 0.1 % of the character's size.
pub const TOLERANCE: f64 = 1e-3;

#[derive(Debug, Clone)]
pub struct Exported {
    pub output: PathBuf,
    pub vertices: usize,
    /// Palette entries (skin joints that vertices use): P + J.
    pub joints: usize,
    pub clips: Vec<ClipReport>,
    /// What the user should know (vertices given a stand-in normal, ...).
    pub notes: Vec<String>,
}

impl Exported {
    /// `rrskin export --json`'s object (docs/cli.md): the output as shown, the vertices,
    /// joints and each clip's report.
    pub fn to_json(&self) -> serde_json::Value {
        let clips: Vec<_> = (self.clips.iter())
            .map(|c| {
                serde_json::json!({"name": c.name, "keys": c.keys, "samples": c.samples,
                    "worst_at_samples": c.worst_at_samples, "worst_between": c.worst_between})
            })
            .collect();
        serde_json::json!({"output": crate::output::shown(&self.output),
            "vertices": self.vertices, "joints": self.joints, "clips": clips})
    }
}

#[derive(Debug, Clone)]
pub struct ClipReport {
    pub name: String,
    pub keys: usize,
    pub samples: usize,
    /// The largest vertex distance between the played file and the model at the samples and
    /// between them, relative to the rest mesh's bounding-box diagonal.
    pub worst_at_samples: f64,
    pub worst_between: f64,
}

/// One clip to bake: its key times and the bones at any time between them.
struct Clip {
    name: String,
    keys: Vec<f64>,
    /// Every key held until the next (glTF's STEP), rather than interpolated.
    step: bool,
    pose_at: Box<dyn Fn(f64) -> Vec<Affine>>,
}

/// What the mesh is drawn with: the rig's primitives and materials, or one bare primitive.
struct Geometry {
    /// Vertex range and material (an index into `materials`) of each primitive.
    primitives: Vec<(std::ops::Range<usize>, Option<usize>)>,
    uvs: Option<Vec<[f32; 2]>>,
    names: Vec<String>,
    mesh_name: String,
    /// The rig's materials, textures, samplers and images (image bytes embedded), and the
    /// extensions they use.
    materials: serde_json::Map<String, Value>,
    extensions: Vec<String>,
}

/// `model` as a skinned glTF at `options.output`, each clip baked to within the tolerance.
pub fn run(model: Model, options: &Options) -> Result<Exported> {
    let palette = Palette::new(model)?;
    let mut buffer = Buffer::default();
    let (geometry, clips) = match &options.rig {
        Some(rig) => rig_source(rig, &options.clips, palette.model(), &mut buffer)?,
        None => (
            model_geometry(palette.model()),
            model_clip(palette.model(), options.fps),
        ),
    };
    let size = diagonal(&palette.model().parts().rest_positions);
    let (mut reports, mut baked, mut notes) = (Vec::new(), Vec::new(), Vec::new());
    for clip in clips {
        let b = bake(
            &palette,
            &clip.keys,
            &clip.pose_at,
            clip.step,
            options.tolerance * size,
        )?;
        if b.worst_between > options.tolerance * size {
            notes.push(format!(
                "clip '{}' moves too fast to follow within the tolerance: up to {:.1e} of the mesh's size between samples, {} samples a key interval at most",
                clip.name,
                b.worst_between / size,
                1u32 << bake::MAX_DEPTH
            ));
        }
        reports.push(ClipReport {
            name: clip.name.clone(),
            keys: clip.keys.len(),
            samples: b.times.len(),
            worst_at_samples: b.worst_at_samples / size,
            worst_between: b.worst_between / size,
        });
        baked.push((clip.name, clip.step, b));
    }
    let document = document(&palette, &geometry, &baked, &mut buffer, &mut notes)?;
    let bytes = glb::encode(document, buffer);
    std::fs::write(&options.output, bytes).map_err(|e| Error::Output {
        path: options.output.clone(),
        problem: format!("cannot write: {e}"),
    })?;
    Ok(Exported {
        output: options.output.clone(),
        vertices: palette.model().vertex_count(),
        joints: palette.len(),
        clips: reports,
        notes,
    })
}

fn diagonal(points: &[[f32; 3]]) -> f64 {
    let (lo, hi) = points.iter().fold(
        (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
        |(lo, hi), p| {
            let p = DVec3::from(p.map(f64::from));
            (lo.min(p), hi.max(p))
        },
    );
    (hi - lo).length().max(f64::MIN_POSITIVE)
}

fn model_geometry(model: &Model) -> Geometry {
    Geometry {
        primitives: vec![(0..model.vertex_count(), None)],
        uvs: None,
        names: (0..model.bone_count())
            .map(|b| format!("bone {b}"))
            .collect(),
        mesh_name: "rrskin model".into(),
        materials: serde_json::Map::new(),
        extensions: Vec::new(),
    }
}

/// The model's own animation as one clip, `fps` frames a second (none when it has none).
fn model_clip(model: &Model, fps: f64) -> Vec<Clip> {
    let frames = model.animation().count();
    if frames == 0 {
        return Vec::new();
    }
    let model = model.clone();
    vec![Clip {
        name: "animation".into(),
        keys: (0..frames).map(|f| f as f64 / fps).collect(),
        step: false,
        pose_at: Box::new(move |t| animation_pose(&model, fps, t)),
    }]
}

/// The bones of the model's own animation at time `t` (seconds, `fps` frames a second), what
/// an export without a rig plays: between two frames each bone moves as glTF moves a node.
pub fn animation_pose(model: &Model, fps: f64, t: f64) -> Vec<Affine> {
    let last = model.animation().count().saturating_sub(1);
    let at = (t * fps).clamp(0.0, last as f64);
    let f = at.floor() as usize;
    let x = at - f as f64;
    let mut frames = model.animation().skip(f);
    let (Some(a), next) = (frames.next(), frames.next()) else {
        return Vec::new();
    };
    a.iter()
        .zip(next.unwrap_or(a))
        .map(|(a, b)| interpolate_bone(a, b, x))
        .collect()
}

/// A bone between two frames as glTF moves a node: the rotation slerped, the rest of the 3x3
/// (scale, where there is any) and the translation lerped.
fn interpolate_bone(a: &Affine, b: &Affine, x: f64) -> Affine {
    let split = |t: &Affine| {
        let m = rotation_of(t);
        let r = procrustes(m);
        (
            DQuat::from_mat3(&r),
            r.transpose() * m,
            DVec3::new(t[3] as f64, t[7] as f64, t[11] as f64),
        )
    };
    let ((ra, sa, da), (rb, sb, db)) = (split(a), split(b));
    let rb = if ra.dot(rb) < 0.0 { -rb } else { rb };
    let m = DMat3::from_quat(ra.slerp(rb, x)) * (sa * (1.0 - x) + sb * x);
    crate::set::Affine {
        q: m,
        d: da.lerp(db, x),
    }
    .to_runtime()
}

fn input(file: &Path, message: impl Into<String>) -> Error {
    Error::Input {
        source: InputError {
            file: file.to_path_buf(),
            message: message.into(),
        },
    }
}

/// The rig's mesh, materials and clips, checked against the model.
fn rig_source(
    path: &Path,
    wanted: &[String],
    model: &Model,
    buffer: &mut Buffer,
) -> Result<(Geometry, Vec<Clip>)> {
    use crate::import::SetFormat;
    if matches!(SetFormat::of(path), SetFormat::Fbx | SetFormat::Usd) {
        return Err(input(path, "--rig takes the glTF of the rig (its materials and UVs come from there; FBX and USD rigs are read for training only): export the rig as glTF from the DCC (Blender: File > Export > glTF 2.0) and train from that glb, or export without --rig (docs/export.md)"));
    }
    let bytes = std::fs::read(path).map_err(|e| input(path, format!("cannot read: {e}")))?;
    let gltf = gltf::Gltf::from_slice(&bytes)
        .map_err(|e| input(path, format!("not a valid glTF file: {e}")))?;
    let names: Vec<String> = gltf
        .document
        .animations()
        .enumerate()
        .map(|(i, a)| {
            a.name()
                .map_or_else(|| format!("animation {i}"), str::to_string)
        })
        .collect();
    if names.is_empty() {
        return Err(input(path, "the rig has no animation to bake"));
    }
    let clips: Vec<String> = if wanted.is_empty() {
        names.clone()
    } else {
        for w in wanted {
            if !names.contains(w) {
                return Err(input(
                    path,
                    format!("no animation named '{w}' (the file has {names:?})"),
                ));
            }
        }
        wanted.to_vec()
    };
    let rig = Rig::load(path, &clips[0])?;
    check_rig_matches(path, &rig, model)?;
    let mut materials_of = Vec::new();
    for node in gltf
        .document
        .nodes()
        .filter(|n| n.mesh().is_some() && n.skin().is_some())
    {
        if let Some(mesh) = node.mesh() {
            materials_of.extend(mesh.primitives().map(|p| p.material().index()));
        }
    }
    let mesh_name = gltf
        .document
        .nodes()
        .find(|n| n.mesh().is_some() && n.skin().is_some())
        .and_then(|n| n.name().map(str::to_string))
        .unwrap_or_else(|| "rrskin model".into());
    let buffers = load_buffers(path, &gltf)?;
    let (materials, extensions) = copy_materials(path, &gltf, &buffers, buffer)?;
    if materials_of.len() != rig.primitives.len() {
        return Err(input(
            path,
            format!(
                "{} skinned primitives in the file, {} in the rig read from it",
                materials_of.len(),
                rig.primitives.len()
            ),
        ));
    }
    let primitives = rig.primitives.iter().cloned().zip(materials_of).collect();
    let geometry = Geometry {
        primitives,
        uvs: rig.uvs.clone(),
        names: rig.names.clone(),
        mesh_name,
        materials,
        extensions,
    };
    let mut out = Vec::new();
    for name in clips {
        let clip_rig = Rig::load(path, &name)?;
        let keys = clip_rig.key_times();
        if keys.is_empty() {
            return Err(input(path, format!("animation '{name}' has no key times")));
        }
        let step = clip_rig.holds_keys();
        let pose_at = move |t: f64| {
            clip_rig
                .bones_at(t)
                .iter()
                .map(|b| b.to_runtime())
                .collect()
        };
        out.push(Clip {
            name,
            keys,
            step,
            pose_at: Box::new(pose_at),
        });
    }
    Ok((geometry, out))
}

/// The model must have been trained from this rig: the same vertices in the same order, the
/// same bones.
fn check_rig_matches(path: &Path, rig: &Rig, model: &Model) -> Result<()> {
    let rest = &model.parts().rest_positions;
    if rig.rest.len() != rest.len() || rig.names.len() != model.bone_count() {
        return Err(input(
            path,
            format!(
                "the rig has {} vertices and {} bones, the model {} and {}: export with the rig the model was trained from",
                rig.rest.len(),
                rig.names.len(),
                rest.len(),
                model.bone_count()
            ),
        ));
    }
    let size = diagonal(rest);
    let worst = rig
        .rest
        .iter()
        .zip(rest)
        .map(|(a, b)| (*a - DVec3::from(b.map(f64::from))).length())
        .fold(0.0f64, f64::max);
    if worst > 1e-4 * size {
        return Err(input(
            path,
            format!(
                "the rig's rest mesh is not the model's (vertices up to {:.3} % of its size apart): export with the rig the model was trained from",
                100.0 * worst / size
            ),
        ));
    }
    Ok(())
}

/// The rig's materials, textures, samplers and images as JSON, every image's bytes embedded in
/// `buffer` (the rig's buffer views are not carried over), and the extensions they use.
fn copy_materials(
    path: &Path,
    gltf: &gltf::Gltf,
    buffers: &[Vec<u8>],
    buffer: &mut Buffer,
) -> Result<(serde_json::Map<String, Value>, Vec<String>)> {
    let root = serde_json::to_value(gltf.document.clone().into_json())
        .map_err(|e| input(path, format!("cannot read its JSON: {e}")))?;
    let mut out = serde_json::Map::new();
    for key in ["materials", "textures", "samplers"] {
        if let Some(v) = root.get(key) {
            out.insert(key.into(), v.clone());
        }
    }
    let mut images = Vec::new();
    for image in gltf.document.images() {
        let (bytes, mime) = match image.source() {
            gltf::image::Source::View { view, mime_type } => {
                let data = buffers
                    .get(view.buffer().index())
                    .and_then(|b| b.get(view.offset()..view.offset() + view.length()))
                    .ok_or_else(|| {
                        input(
                            path,
                            format!("image {} lies outside its buffer", image.index()),
                        )
                    })?;
                (data.to_vec(), mime_type.to_string())
            }
            gltf::image::Source::Uri { uri, mime_type } => {
                if uri.starts_with("data:") {
                    images.push(json!({"uri": uri}));
                    continue;
                }
                let file = path.parent().unwrap_or(Path::new(".")).join(uri);
                let data = std::fs::read(&file).map_err(|e| {
                    input(
                        &file,
                        format!("image {} of {}: {e}", image.index(), path.display()),
                    )
                })?;
                let mime = mime_type.map(str::to_string).unwrap_or_else(|| {
                    if uri.to_ascii_lowercase().ends_with(".png") {
                        "image/png"
                    } else {
                        "image/jpeg"
                    }
                    .into()
                });
                (data, mime)
            }
        };
        let view = buffer.view(&bytes, None);
        let mut entry = json!({"bufferView": view, "mimeType": mime});
        if let Some(name) = image.name() {
            entry["name"] = json!(name);
        }
        images.push(entry);
    }
    if !images.is_empty() {
        out.insert("images".into(), Value::Array(images));
    }
    let text = Value::Object(out.clone()).to_string();
    let extensions = gltf
        .document
        .extensions_used()
        .filter(|e| text.contains(&format!("\"{e}\"")))
        .map(str::to_string)
        .collect();
    Ok((out, extensions))
}

/// The glTF JSON (without buffers, views and accessors, which `buffer` holds).
fn document(
    palette: &Palette,
    geometry: &Geometry,
    clips: &[(String, bool, Baked)],
    buffer: &mut Buffer,
    notes: &mut Vec<String>,
) -> Result<Value> {
    let model = palette.model();
    let (p, entries) = (model.proxy_count(), palette.len());
    if entries > u16::MAX as usize + 1 {
        return Err(Error::Output {
            path: PathBuf::from("<export>"),
            problem: format!("{entries} palette entries do not fit glTF's 16-bit joint indices"),
        });
    }
    // Nodes: 0 the mesh, 1 the palette's root, then per entry e its outer node 2 + 2e and the
    // skinning joint 3 + 2e under it.
    let name = |e: usize| {
        if e < p {
            format!("proxy {e}")
        } else {
            geometry.names[e - p].clone()
        }
    };
    let mut nodes = vec![
        json!({"name": geometry.mesh_name, "mesh": 0, "skin": 0}),
        json!({"name": "rrskin palette", "children": (0..entries).map(|e| 2 + 2 * e).collect::<Vec<_>>()}),
    ];
    for e in 0..entries {
        nodes.push(json!({"name": format!("{} (scale)", name(e)), "children": [3 + 2 * e]}));
        nodes.push(json!({"name": name(e)}));
    }
    let joints: Vec<usize> = (0..entries)
        .map(|e| 3 + 2 * e)
        .chain((0..entries).map(|e| 2 + 2 * e))
        .collect();
    let primitives = primitives(palette, geometry, buffer, notes);
    let animations: Vec<Value> = clips
        .iter()
        .map(|(name, step, baked)| animation(name, *step, baked, buffer))
        .collect();
    let mut document = json!({
        "asset": {"version": "2.0", "generator": concat!("rrskin export ", env!("CARGO_PKG_VERSION"))},
        "scene": 0,
        "scenes": [{"nodes": [0, 1]}],
        "nodes": nodes,
        "meshes": [{"name": geometry.mesh_name, "primitives": primitives}],
        "skins": [{"name": "rrskin palette", "joints": joints, "skeleton": 1}],
    });
    if palette.corrective_count() > 0 {
        document["meshes"][0]["weights"] = json!(vec![0.0; palette.corrective_count()]);
    }
    if !animations.is_empty() {
        document["animations"] = Value::Array(animations);
    }
    for (key, value) in &geometry.materials {
        document[key] = value.clone();
    }
    if !geometry.extensions.is_empty() {
        document["extensionsUsed"] = json!(geometry.extensions);
    }
    Ok(document)
}

/// The mesh's primitives: rest positions, the runtime's rest normals, rest tangents and UVs
/// where there are any, the skin as K joints and weights per vertex.
fn primitives(
    palette: &Palette,
    geometry: &Geometry,
    buffer: &mut Buffer,
    notes: &mut Vec<String>,
) -> Vec<Value> {
    let skin = palette.skin();
    let k = skin.influences;
    let (normals, tangents) = rest_frames(&skin, notes);
    let (joints, weights) = skin_sets(skin.indices, skin.weights, k);
    geometry
        .primitives
        .iter()
        .map(|(range, material)| {
            let r = range.clone();
            let flat3 = |a: &[[f32; 3]]| a[r.clone()].as_flattened().to_vec();
            let mut attributes = serde_json::Map::new();
            attributes.insert(
                "POSITION".into(),
                json!(buffer.floats(&flat3(skin.rest_positions), 3, Some(ARRAY_BUFFER))),
            );
            attributes.insert(
                "NORMAL".into(),
                json!(buffer.floats(&flat3(&normals), 3, Some(ARRAY_BUFFER))),
            );
            if !tangents.is_empty() {
                attributes.insert(
                    "TANGENT".into(),
                    json!(buffer.floats(tangents[r.clone()].as_flattened(), 4, Some(ARRAY_BUFFER))),
                );
            }
            if let Some(uvs) = &geometry.uvs {
                attributes.insert(
                    "TEXCOORD_0".into(),
                    json!(buffer.floats(uvs[r.clone()].as_flattened(), 2, Some(ARRAY_BUFFER))),
                );
            }
            for (set, (j, w)) in joints.iter().zip(&weights).enumerate() {
                attributes.insert(
                    format!("JOINTS_{set}"),
                    json!(buffer.shorts(&j[4 * r.start..4 * r.end], 4)),
                );
                attributes.insert(
                    format!("WEIGHTS_{set}"),
                    json!(buffer.floats(&w[4 * r.start..4 * r.end], 4, Some(ARRAY_BUFFER))),
                );
            }
            let indices: Vec<u32> = skin
                .triangles
                .iter()
                .filter(|t| r.contains(&(t[0] as usize)))
                .flat_map(|t| t.map(|v| v - r.start as u32))
                .collect();
            let mut primitive =
                json!({"attributes": attributes, "indices": buffer.indices(&indices)});
            if skin.correctives > 0 {
                let v = skin.rest_positions.len();
                let targets: Vec<Value> = (0..skin.correctives)
                    .map(|n| {
                        let offsets = &skin.corrective_targets[n * v..(n + 1) * v];
                        json!({"POSITION": buffer.floats(&flat3(offsets), 3, Some(ARRAY_BUFFER))})
                    })
                    .collect();
                primitive["targets"] = Value::Array(targets);
            }
            if let Some(m) = material {
                primitive["material"] = json!(m);
            }
            primitive
        })
        .collect()
}

/// The runtime's rest normals and tangents, each made usable where the runtime has none: +Y
/// for a vertex of no area, a tangent orthogonal to its normal for one without a rest tangent
/// (glTF needs unit vectors); a note says how many were filled in.
fn rest_frames(skin: &Skin, notes: &mut Vec<String>) -> (Vec<[f32; 3]>, Vec<[f32; 4]>) {
    let (mut no_normal, mut no_tangent) = (0usize, 0usize);
    let normals: Vec<[f32; 3]> = skin
        .rest_normals
        .iter()
        .map(|n| {
            if n.iter().all(|x| *x == 0.0) {
                no_normal += 1;
                [0.0, 1.0, 0.0]
            } else {
                *n
            }
        })
        .collect();
    let tangents: Vec<[f32; 4]> = skin
        .rest_tangents
        .iter()
        .zip(&normals)
        .map(|(t, n)| {
            if t[..3].iter().all(|x| *x == 0.0) {
                no_tangent += 1;
                let o = glam::Vec3::from(*n).any_orthonormal_vector();
                [o.x, o.y, o.z, 1.0]
            } else {
                *t
            }
        })
        .collect();
    if no_normal > 0 {
        notes.push(format!(
            "{no_normal} vertices of no area have the normal +Y"
        ));
    }
    if no_tangent > 0 {
        notes.push(format!(
            "{no_tangent} vertices without a rest tangent have one orthogonal to their normal"
        ));
    }
    (normals, tangents)
}

/// The skin as glTF sets of 4 (JOINTS_n, WEIGHTS_n): per vertex the K (index, weight) pairs
/// with repeated indices merged, heaviest first, zero weights on joint 0, the weights summing
/// to 1 in `f32` as exactly as it can (the last non-zero one takes the remainder).
fn skin_sets(indices: &[u32], weights: &[f32], k: usize) -> (Vec<Vec<u16>>, Vec<Vec<f32>>) {
    let sets = k / 4;
    let v = indices.len() / k;
    let mut joints = vec![Vec::with_capacity(4 * v); sets];
    let mut out = vec![Vec::with_capacity(4 * v); sets];
    for a in 0..v {
        let mut pairs: Vec<(u32, f64)> = Vec::with_capacity(k);
        for i in a * k..(a + 1) * k {
            let w = weights[i] as f64;
            if w <= 0.0 {
                continue;
            }
            match pairs.iter_mut().find(|(j, _)| *j == indices[i]) {
                Some(pair) => pair.1 += w,
                None => pairs.push((indices[i], w)),
            }
        }
        pairs.sort_by(|x, y| y.1.total_cmp(&x.1));
        let total: f64 = pairs.iter().map(|p| p.1).sum();
        let mut w: Vec<f32> = pairs.iter().map(|p| (p.1 / total) as f32).collect();
        if let Some((last, rest)) = w.split_last_mut() {
            *last = 1.0 - rest.iter().sum::<f32>();
        }
        for s in 0..k {
            let (j, x) = pairs.get(s).map_or((0, 0.0), |p| (p.0 as u16, w[s]));
            joints[s / 4].push(j);
            out[s / 4].push(x);
        }
    }
    (joints, out)
}

/// One clip's channels: per palette entry the outer node's translation, rotation and scale and
/// the joint's rotation, and the mesh's morph-target weights where it has any, sampled at the
/// baked times, LINEAR (STEP for a clip that holds keys).
fn animation(name: &str, step: bool, baked: &Baked, buffer: &mut Buffer) -> Value {
    let interpolation = if step { "STEP" } else { "LINEAR" };
    let times: Vec<f32> = baked.times.iter().map(|&t| t as f32).collect();
    let input = buffer.floats(&times, 1, None);
    let (mut samplers, mut channels) = (Vec::new(), Vec::new());
    let entries = baked.samples.first().map_or(0, Vec::len);
    for e in 0..entries {
        let column = |f: &dyn Fn(&NodePair) -> Vec<f32>| -> Vec<f32> {
            baked.samples.iter().flat_map(|s| f(&s[e])).collect()
        };
        let outputs: [(usize, &str, Vec<f32>, usize); 4] = [
            (
                2 + 2 * e,
                "translation",
                column(&|n| n.translation.as_vec3().to_array().to_vec()),
                3,
            ),
            (
                2 + 2 * e,
                "rotation",
                column(&|n| n.rotation.as_quat().to_array().to_vec()),
                4,
            ),
            (
                2 + 2 * e,
                "scale",
                column(&|n| n.scale.as_vec3().to_array().to_vec()),
                3,
            ),
            (
                3 + 2 * e,
                "rotation",
                column(&|n| n.child_rotation.as_quat().to_array().to_vec()),
                4,
            ),
        ];
        for (node, path, values, width) in outputs {
            let output = buffer.floats(&values, width, None);
            channels
                .push(json!({"sampler": samplers.len(), "target": {"node": node, "path": path}}));
            samplers
                .push(json!({"input": input, "output": output, "interpolation": interpolation}));
        }
    }
    if baked.weights.first().is_some_and(|w| !w.is_empty()) {
        let output = buffer.floats(&baked.weights.concat(), 1, None);
        channels.push(json!({"sampler": samplers.len(), "target": {"node": 0, "path": "weights"}}));
        samplers.push(json!({"input": input, "output": output, "interpolation": interpolation}));
    }
    json!({"name": name, "samplers": samplers, "channels": channels})
}
