//! A point cache as a folder of per-frame meshes: `walk_0001.obj`, `walk_0002.obj`, … (or
//! `.ply`), as DCCs and simulators write a sequence and as other skinning-decomposition tools
//! take one. Each file is one frame, numbered by the digits that end its name; its vertices are
//! the cache's points of that frame, in an order every frame shares (the rig's, or one the
//! vertex map finds, as for any cache).
//!
//! OBJ is read by `tobj`, which orders a mesh's vertices by their first use in its faces
//! (every frame alike, since the faces do not change), the objects of a file one after the
//! other; a vertex no face uses is left out. PLY is read by `ply-rs-bw`: the `vertex`
//! element's x, y, z, in file order.

use glam::DVec3;
use rayon::prelude::*;
use std::path::{Path, PathBuf};

/// The per-frame meshes' extensions read.
const EXTENSIONS: [&str; 2] = ["obj", "ply"];

/// The frames (from the file names, ascending) and each frame's points of the sequence in
/// folder `dir`.
pub fn read(dir: &Path) -> Result<(Vec<f64>, Vec<Vec<DVec3>>), String> {
    let files = frame_files(dir)?;
    let positions = (files.par_iter())
        .map(|(_, path)| read_mesh(path))
        .collect::<Result<Vec<_>, _>>()?;
    Ok((files.iter().map(|f| f.0).collect(), positions))
}

/// The folder's meshes with their frame numbers, in frame order: one extension, every name
/// ending in digits, no frame twice.
fn frame_files(dir: &Path) -> Result<Vec<(f64, PathBuf)>, String> {
    let entries = std::fs::read_dir(dir).map_err(|e| format!("cannot read the folder: {e}"))?;
    let mut files: Vec<(f64, PathBuf)> = Vec::new();
    let mut extensions: Vec<String> = Vec::new();
    for entry in entries {
        let path = entry
            .map_err(|e| format!("cannot read the folder: {e}"))?
            .path();
        let Some(ext) = (path.extension().and_then(|e| e.to_str())).map(str::to_ascii_lowercase)
        else {
            continue;
        };
        if !EXTENSIONS.contains(&ext.as_str()) {
            continue;
        }
        if !extensions.contains(&ext) {
            extensions.push(ext);
        }
        files.push((frame_number(&path)?, path));
    }
    match extensions.len() {
        0 => return Err("holds no .obj or .ply meshes: a mesh sequence is one file a frame (walk_0001.obj, walk_0002.obj, …)".into()),
        1 => {}
        _ => return Err(format!("holds both .obj and .ply meshes: a sequence is of one format ({})", extensions.join(", "))),
    }
    files.sort_by(|a, b| a.0.total_cmp(&b.0));
    if let Some(w) = files.windows(2).find(|w| w[0].0 == w[1].0) {
        return Err(format!(
            "{} and {} are both frame {}",
            name(&w[0].1),
            name(&w[1].1),
            w[0].0
        ));
    }
    Ok(files)
}

/// The frame number a file's name ends in (`walk_0012.obj`: 12).
fn frame_number(path: &Path) -> Result<f64, String> {
    let stem = path.file_stem().and_then(|s| s.to_str()).unwrap_or("");
    let digits = stem.len() - stem.trim_end_matches(|c: char| c.is_ascii_digit()).len();
    stem[stem.len() - digits..]
        .parse::<u64>()
        .map(|n| n as f64)
        .map_err(|_| {
            format!(
                "{}: a frame's mesh is named with its frame number last (walk_0012.obj)",
                name(path)
            )
        })
}

fn name(path: &Path) -> String {
    path.file_name()
        .map_or_else(String::new, |n| n.to_string_lossy().into_owned())
}

/// The points of one frame's mesh.
fn read_mesh(path: &Path) -> Result<Vec<DVec3>, String> {
    let ext = (path.extension().and_then(|e| e.to_str())).map(str::to_ascii_lowercase);
    let points = match ext.as_deref() {
        Some("ply") => read_ply(path),
        _ => read_obj(path),
    }
    .map_err(|e| format!("{}: {e}", name(path)))?;
    match points.is_empty() {
        true => Err(format!("{}: no vertices", name(path))),
        false => Ok(points),
    }
}

fn read_obj(path: &Path) -> Result<Vec<DVec3>, String> {
    let options = tobj::LoadOptions {
        single_index: false,
        triangulate: false,
        ignore_points: true,
        ignore_lines: true,
    };
    // Materials are not read: a missing .mtl is no error.
    let (models, _) = tobj::load_obj(path, &options).map_err(|e| e.to_string())?;
    Ok((models.iter())
        .flat_map(|m| m.mesh.positions.chunks_exact(3))
        .map(|p| DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64))
        .collect())
}

fn read_ply(path: &Path) -> Result<Vec<DVec3>, String> {
    use ply_rs_bw::{parser::Parser, ply::DefaultElement, ply::Property};
    let file = std::fs::File::open(path).map_err(|e| format!("cannot read: {e}"))?;
    let mut reader = std::io::BufReader::new(file);
    let ply = Parser::<DefaultElement>::new()
        .read_ply(&mut reader)
        .map_err(|e| e.to_string())?;
    let vertices = ply.payload.get("vertex").ok_or("no 'vertex' element")?;
    let coordinate = |v: &DefaultElement, axis: &str| match v.get(axis) {
        Some(Property::Float(x)) => Ok(*x as f64),
        Some(Property::Double(x)) => Ok(*x),
        _ => Err(format!("a vertex without a float '{axis}'")),
    };
    (vertices.iter())
        .map(|v| {
            Ok(DVec3::new(
                coordinate(v, "x")?,
                coordinate(v, "y")?,
                coordinate(v, "z")?,
            ))
        })
        .collect()
}
