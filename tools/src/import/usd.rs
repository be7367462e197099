//! USD stages (`.usd`, `.usda`, `.usdc`) through `openusd`, which parses the text and binary
//! layers and composes the stage: what a USD rig ([`crate::import::usd_rig`]) and a USD point
//! cache share, and the point cache.
//!
//! A stage's frame is its `upAxis` and `metersPerUnit` metadata: it is converted on load to the
//! rig frame of the other importers (metres, Y up, right-handed), as ufbx converts an FBX, so a
//! USD cache lines up with a glTF or FBX rig as it does with a USD one. Blender writes Z-up in
//! metres; Houdini's Solaris Y-up, in metres by default.
//!
//! The cache is the stage's one mesh whose `points` are time-sampled (Blender's USD export of
//! the evaluated mesh with armatures off; a Solaris stage of the deformed character), taken to
//! world space by the transforms above it at each sample, at the sample's time code over the
//! stage's `timeCodesPerSecond`.

use crate::import::guarded;
use glam::{DMat4, DVec3};
use openusd::schemas::geom::{Mesh, PointBased, Xformable};
use openusd::sdf::{self, Value};
use openusd::usd::{Prim, PrimPredicate, SchemaBase, SchemaKind, TimeCode};
use openusd::{gf, schemas::skel::Skeleton};
use std::path::Path;

/// An opened stage and how its frame maps to the rig's.
pub(crate) struct Stage {
    pub stage: openusd::usd::Stage,
    /// Stage coordinates to the rig frame's (metres, Y up).
    pub to_rig: DMat4,
    /// Time codes per second: a time code over this is seconds.
    pub codes_per_second: f64,
    /// What the conversion did, for the user (None where the stage is already in metres, Y up).
    pub frame_note: Option<String>,
}

/// Opens the stage at `path` (errors are messages about the file).
pub(crate) fn open(path: &Path) -> Result<Stage, String> {
    let name = path.to_str().ok_or("the path is not UTF-8")?;
    let stage =
        openusd::usd::Stage::open(name).map_err(|e| format!("not a readable USD file: {e:#}"))?;
    let metadata = |key: &str| stage.stage_metadata(key).ok().flatten();
    let up = match metadata("upAxis") {
        Some(Value::Token(t)) => t.as_str().to_string(),
        Some(Value::String(s)) => s,
        // USD's fallback when a stage says nothing.
        _ => "Y".to_string(),
    };
    let meters = match metadata("metersPerUnit") {
        Some(Value::Double(m)) => m,
        Some(Value::Float(m)) => m.into(),
        Some(Value::Int(m)) => m.into(),
        // USD's fallback when a stage says nothing: centimetres.
        _ => 0.01,
    };
    if !(meters.is_finite() && meters > 0.0) {
        return Err(format!("metersPerUnit {meters} must be positive"));
    }
    let rotation = match up.as_str() {
        "Y" => DMat4::IDENTITY,
        // Z up to Y up: (x, y, z) -> (x, z, -y).
        "Z" => DMat4::from_rotation_x(-std::f64::consts::FRAC_PI_2),
        other => return Err(format!("upAxis \"{other}\": USD allows Y or Z")),
    };
    let frame_note = (up != "Y" || meters != 1.0).then(|| {
        let units = match meters {
            1.0 => "metres".to_string(),
            0.01 => "centimetres".to_string(),
            m => format!("units of {m} m"),
        };
        format!("USD stage in {units}, {up} up: converted to metres, Y up")
    });
    let codes_per_second = stage.time_codes_per_second();
    if !(codes_per_second.is_finite() && codes_per_second > 0.0) {
        return Err(format!(
            "timeCodesPerSecond {codes_per_second} must be positive"
        ));
    }
    Ok(Stage {
        to_rig: DMat4::from_scale(DVec3::splat(meters)) * rotation,
        stage,
        codes_per_second,
        frame_note,
    })
}

/// `e`, an error of the reader, as a message (with its causes).
pub(crate) fn why(e: impl std::fmt::Display) -> String {
    format!("{e:#}")
}

/// A USD matrix (row-major, acting on row vectors) as glam's (column vectors): its transpose,
/// which reading the 16 values as columns gives.
pub(crate) fn mat4(m: &gf::Matrix4d) -> DMat4 {
    DMat4::from_cols_array(&m.0)
}

/// Any prim, read for its `xformOpOrder` (a Scope or a prim without one is the identity).
struct Transformed(Prim);

impl SchemaBase for Transformed {
    const KIND: SchemaKind = SchemaKind::ConcreteTyped;

    fn prim(&self) -> &Prim {
        &self.0
    }
}

impl openusd::schemas::geom::Imageable for Transformed {}
impl Xformable for Transformed {}

/// The prim at `path`'s local-to-world matrix at `time`, the transforms of every prim above it
/// composed (up to one that resets the transform stack).
pub(crate) fn local_to_world(
    stage: &Stage,
    path: &sdf::Path,
    time: TimeCode,
) -> Result<DMat4, String> {
    let mut world = DMat4::IDENTITY;
    let mut at = Some(path.clone());
    while let Some(p) = at.filter(|p| p.as_str() != "/") {
        let prim = Transformed(stage.stage.prim(p.clone()));
        let local = prim.local_to_parent_transform(time).map_err(why)?;
        world = mat4(&local) * world;
        if prim.resets_xform_stack().map_err(why)? {
            break;
        }
        at = p.parent();
    }
    Ok(world)
}

/// The stage's prims (the default traversal: active, loaded, defined).
pub(crate) fn prims(stage: &Stage) -> Result<Vec<sdf::Path>, String> {
    let mut paths = Vec::new();
    (stage
        .stage
        .traverse(PrimPredicate::DEFAULT, |p| paths.push(p.clone())))
    .map_err(why)?;
    Ok(paths)
}

/// A point array as authored (float or double points).
pub(crate) fn points(value: Option<Value>) -> Option<Vec<DVec3>> {
    match value? {
        Value::Vec3fVec(v) => Some(
            v.iter()
                .map(|p| DVec3::new(p.x.into(), p.y.into(), p.z.into()))
                .collect(),
        ),
        Value::Vec3dVec(v) => Some(v.iter().map(|p| DVec3::new(p.x, p.y, p.z)).collect()),
        _ => None,
    }
}

/// A cache read from a USD stage.
#[derive(Debug, Clone, PartialEq)]
pub struct Cache {
    /// Per sample: its time in seconds.
    pub times: Vec<f64>,
    /// \[sample\]\[point\], in world space, metres, Y up.
    pub positions: Vec<Vec<DVec3>>,
}

/// Reads the cache at `path`; errors are messages about the file. A fault of the reader on a
/// malformed file is an error too.
pub fn read_cache(path: &Path) -> Result<Cache, String> {
    guarded("USD", || read_stage_cache(path))
}

fn read_stage_cache(path: &Path) -> Result<Cache, String> {
    let stage = open(path)?;
    let mut animated = Vec::new();
    for p in prims(&stage)? {
        let Some(mesh) = Mesh::get(&stage.stage, p.clone()).map_err(why)? else {
            continue;
        };
        let times = mesh
            .points_attr()
            .time_sample_times()
            .map_err(|e| format!("{p}: {e:#}"))?;
        if times.len() > 1 {
            animated.push((mesh, times));
        }
    }
    let (mesh, times) = match animated.len() {
        1 => animated.remove(0),
        0 => return Err(no_animated_mesh(&stage)),
        _ => {
            let names: Vec<&str> = animated.iter().map(|(m, _)| m.path().as_str()).collect();
            return Err(format!(
                "several meshes with time-sampled points ({}): export only the deformed character",
                names.join(", ")
            ));
        }
    };
    let positions = (times.iter())
        .map(|&t| {
            let time = TimeCode::new(t);
            let name = mesh.path();
            let value = mesh
                .points_attr()
                .get_at::<Value>(time)
                .map_err(|e| format!("{name}: time {t}: {e:#}"))?;
            let points = points(value).ok_or_else(|| {
                format!("{name}: time {t}: points are not float or double vectors")
            })?;
            let to_world = stage.to_rig * local_to_world(&stage, name, time)?;
            Ok(points
                .into_iter()
                .map(|p| to_world.transform_point3(p))
                .collect())
        })
        .collect::<Result<Vec<Vec<DVec3>>, String>>()?;
    Ok(Cache {
        times: times.iter().map(|t| t / stage.codes_per_second).collect(),
        positions,
    })
}

/// Why a stage is no point cache, with what to export instead.
fn no_animated_mesh(stage: &Stage) -> String {
    let skeletal = prims(stage)
        .unwrap_or_default()
        .into_iter()
        .any(|p| Skeleton::get(&stage.stage, p).is_ok_and(|s| s.is_some()));
    let rig = match skeletal {
        true => " (this stage is a UsdSkel rig, whose mesh is posed by its skeleton: the cache is a second export)",
        false => "",
    };
    format!("no mesh with time-sampled points{rig}: export the deformed mesh's animation (Blender: File > Export > Universal Scene Description with Armatures and Shape Keys off, Animation on)")
}
