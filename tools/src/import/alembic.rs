//! Alembic geometry caches (`.abc`, the Ogawa container) through the `ogawa-rs` reader: the
//! positions of the file's one animated PolyMesh, per sample, taken to world space by the
//! transforms of the objects above it, at the sample times of its time sampling.
//!
//! `ogawa-rs` 0.4.0 parses the container, the objects, the schemas and the time samplings. Its
//! sample lookup has two faults against Alembic's reference reader (`AbcCoreOgawa`
//! `ReadUtil.cpp` and `AprImpl.cpp`), so samples are looked up here with its public chunk API:
//! - a property header without explicit changed indices means samples 1..n−1 changed (it reads
//!   0..n−1, which shifts every animated sample by one and calls the property constant);
//! - an array property stores each sample as a (data, dimensions) pair of chunks, so sample k's
//!   data is chunk 2k (it reads chunk k).

use glam::{DMat4, DVec3};
use ogawa_rs::{
    Archive, ArchiveReader, GroupChunk, MemMappedReader, ObjectReader, PodArray, PropertyHeader,
    PropertyReader, Schema, TimeSampling,
};
use std::path::Path;

/// A cache read from an Alembic file.
#[derive(Debug, Clone, PartialEq)]
pub struct Cache {
    /// Per sample: its time in seconds.
    pub times: Vec<f64>,
    /// \[sample\]\[point\], in world space.
    pub positions: Vec<Vec<DVec3>>,
}

type Found = (String, Vec<DMat4>, PolyMesh);

/// The animated PolyMesh's positions: P, its sample count and time sampling.
struct PolyMesh {
    header: PropertyHeader,
    group: GroupChunk,
}

/// Reads `path`; errors are messages about the file. A fault of the reader on a malformed file
/// (ogawa-rs panics on some, as on the allocation of a corrupt size) is an error too.
pub fn read(path: &Path) -> Result<Cache, String> {
    crate::import::guarded("Alembic", || read_file(path))
}

fn read_file(path: &Path) -> Result<Cache, String> {
    let file = std::fs::File::open(path).map_err(|e| format!("cannot read: {e}"))?;
    let mut reader = MemMappedReader::new(file).map_err(|e| format!("not an Alembic file: {e}"))?;
    let archive = Archive::new(&mut reader).map_err(|e| {
        format!("not an Alembic (Ogawa) file: {e} (HDF5 Alembic is not read: re-export as Ogawa)")
    })?;
    let root = (archive.load_root_object(&mut reader)).map_err(|e| format!("unreadable: {e}"))?;
    let mut found: Vec<Found> = Vec::new();
    walk(&root, &mut reader, &archive, &[], &mut found).map_err(|e| format!("unreadable: {e}"))?;
    found.retain(|(_, _, mesh)| mesh.header.next_sample_index > 1);
    let (mesh, xforms, poly) = match found.len() {
        1 => found.remove(0),
        0 => {
            return Err(
                "no animated PolyMesh (a mesh whose positions have more than one sample)".into(),
            )
        }
        _ => {
            let names: Vec<&str> = found.iter().map(|f| f.0.as_str()).collect();
            return Err(format!(
                "several animated meshes ({}): export only the deformed character",
                names.join(", ")
            ));
        }
    };
    let n = poly.header.next_sample_index;
    let sampling = (poly.header.time_sampling.as_deref())
        .ok_or("the mesh's positions have no time sampling")?;
    let times: Vec<f64> = (0..n).map(|i| sample_time(sampling, i)).collect();
    let positions = (0..n)
        .map(|i| {
            let to_world = xforms
                .get(i as usize)
                .or(xforms.last())
                .copied()
                .unwrap_or(DMat4::IDENTITY);
            let points = read_positions(&poly, i, &mut reader)
                .map_err(|e| format!("{mesh}: sample {i}: {e}"))?;
            Ok(points
                .into_iter()
                .map(|p| to_world.transform_point3(p))
                .collect())
        })
        .collect::<Result<Vec<Vec<DVec3>>, String>>()?;
    Ok(Cache { times, positions })
}

/// Every PolyMesh under `object`, with its world matrices per sample (`parents`: the matrices
/// of the objects above, per sample; one entry if they are constant).
fn walk(
    object: &ObjectReader,
    reader: &mut dyn ArchiveReader,
    archive: &Archive,
    parents: &[DMat4],
    found: &mut Vec<Found>,
) -> ogawa_rs::Result<()> {
    for i in 0..object.child_count() {
        let child = object.load_child(
            i,
            reader,
            &archive.indexed_meta_data,
            &archive.time_samplings,
        )?;
        let mut world = parents.to_vec();
        match Schema::parse(&child, reader, archive) {
            Ok(Schema::Xform(_)) => world = compose(parents, &xform(&child, reader, archive)?),
            Ok(Schema::PolyMesh(mesh)) => found.push((
                child.header.full_name.clone(),
                world.clone(),
                PolyMesh {
                    header: mesh.vertices.header.clone(),
                    group: mesh.vertices.group.clone(),
                },
            )),
            _ => {}
        }
        walk(&child, reader, archive, &world, found)?;
    }
    Ok(())
}

/// `parents[i] · local[i]` per sample, the shorter list held at its last entry.
fn compose(parents: &[DMat4], local: &[DMat4]) -> Vec<DMat4> {
    let n = parents.len().max(local.len()).max(1);
    let at = |m: &[DMat4], i: usize| m.get(i).or(m.last()).copied().unwrap_or(DMat4::IDENTITY);
    (0..n).map(|i| at(parents, i) * at(local, i)).collect()
}

/// An Xform object's local matrices per sample (`.xform/.vals`: a single 4x4 matrix op as DCCs
/// write it, row-vector convention, so transposed here). Empty: the identity.
fn xform(
    object: &ObjectReader,
    reader: &mut dyn ArchiveReader,
    archive: &Archive,
) -> ogawa_rs::Result<Vec<DMat4>> {
    let Some(properties) = object.properties() else {
        return Ok(Vec::new());
    };
    let PropertyReader::Compound(xform) = properties.load_sub_property(0, reader, archive)? else {
        return Ok(Vec::new());
    };
    let Some(PropertyReader::Scalar(vals)) =
        xform.load_sub_property_by_name(".vals", reader, archive)?
    else {
        return Ok(Vec::new());
    };
    let n = vals.header.next_sample_index;
    (0..n)
        .map(|i| {
            let data = vals
                .group
                .load_data(reader, stored_sample(&vals.header, i))?;
            Ok(match data.read_pod_array(&vals.header.data_type, reader)? {
                PodArray::F64(v) if v.len() == 16 => {
                    DMat4::from_cols_array(&v.try_into().unwrap_or([0.0; 16]))
                }
                _ => DMat4::IDENTITY,
            })
        })
        .collect()
}

/// Sample `i`'s positions.
fn read_positions(
    mesh: &PolyMesh,
    i: u32,
    reader: &mut dyn ArchiveReader,
) -> Result<Vec<DVec3>, String> {
    let data = (mesh
        .group
        .load_data(reader, 2 * stored_sample(&mesh.header, i)))
    .map_err(|e| e.to_string())?;
    match (data.read_pod_array(&mesh.header.data_type, reader)).map_err(|e| e.to_string())? {
        PodArray::F32(v) => Ok(v
            .chunks_exact(3)
            .map(|c| DVec3::new(c[0].into(), c[1].into(), c[2].into()))
            .collect()),
        PodArray::F64(v) => Ok(v
            .chunks_exact(3)
            .map(|c| DVec3::new(c[0], c[1], c[2]))
            .collect()),
        _ => Err("positions are not float32 or float64 vectors".into()),
    }
}

/// The stored sample that holds sample `i` (Alembic's `verifyIndex`): samples before the first
/// change are sample 0, after the last change the last stored one.
fn stored_sample(h: &PropertyHeader, i: u32) -> usize {
    let n = h.next_sample_index;
    // ogawa-rs reads "no explicit range" as 0..n−1; the format means 1..n−1.
    let (first, last) = match (h.first_changed_index, h.last_changed_index) {
        (0, l) if n > 1 && l == n - 1 => (1, n - 1),
        range => range,
    };
    let i = i.min(n.saturating_sub(1));
    if i < first || (first == 0 && last == 0) {
        0
    } else if i >= last {
        (last - first + 1) as usize
    } else {
        (i - first + 1) as usize
    }
}

/// Sample `i`'s time: a uniform or cyclic sampling repeats its cycle of `samples` every
/// `time_per_cycle`; an acyclic one (Alembic writes u32::MAX samples per cycle) lists every time.
fn sample_time(sampling: &TimeSampling, i: u32) -> f64 {
    let (per_cycle, samples) = (
        sampling.sampling_type.num_samples_per_cycle,
        &sampling.samples,
    );
    let Some(last) = samples.len().checked_sub(1) else {
        return f64::from(i) * sampling.sampling_type.time_per_cycle;
    };
    match per_cycle {
        0 | u32::MAX => samples[(i as usize).min(last)],
        n => {
            samples[((i % n) as usize).min(last)]
                + f64::from(i / n) * sampling.sampling_type.time_per_cycle
        }
    }
}
