//! `rrskin reference`: frames of a crowd's bone transforms and the positions (and tangents, for a
//! model with rest tangents) the runtime's CPU evaluator (the oracle of every GPU test) computes
//! for them, as raw little-endian f32 files:
//! the inputs of `examples/c/crowd.c`, and what an engine's integration can be checked against.

use crate::run::profile::poses;
use rrskin::cpu::CpuEvaluator;
use rrskin::Model;
use std::path::{Path, PathBuf};

/// Writes `dir/poses.bin` (frames x characters x J x 12 floats: 3x4 row-major transforms, the
/// model's animation at each character's phase, random poses without one),
/// `dir/expected.bin` (frames x characters x V x 3 floats: positions) and, for a model with
/// rest tangents, `dir/tangents.bin` (frames x characters x V x 4: xyz, handedness w); returns
/// the paths written.
pub fn write(
    model: &Model,
    frames: usize,
    characters: usize,
    dir: &Path,
) -> Result<Vec<PathBuf>, Box<dyn std::error::Error>> {
    crate::output::check_writable(dir)?;
    let n = characters * model.vertex_count();
    let mut evaluator = CpuEvaluator::new(model);
    let (mut positions, mut normals) = (vec![[0.0f32; 3]; n], vec![[0.0f32; 3]; n]);
    let mut tangents = vec![[0.0f32; 4]; if model.has_tangents() { n } else { 0 }];
    let bytes = |floats: &[f32]| {
        floats
            .iter()
            .flat_map(|x| x.to_le_bytes())
            .collect::<Vec<_>>()
    };
    let mut files = [
        ("poses.bin", Vec::new()),
        ("expected.bin", Vec::new()),
        ("tangents.bin", Vec::new()),
    ];
    for frame in 0..frames {
        let bones = poses(model, characters, frame);
        match model.has_tangents() {
            true => evaluator.evaluate_with_tangents(
                &bones,
                &mut positions,
                &mut normals,
                &mut tangents,
            )?,
            false => evaluator.evaluate(&bones, &mut positions, &mut normals)?,
        }
        files[0].1.extend(bytes(bones.as_flattened()));
        files[1].1.extend(bytes(positions.as_flattened()));
        files[2].1.extend(bytes(tangents.as_flattened()));
    }
    let kept = if model.has_tangents() { 3 } else { 2 };
    let mut written = Vec::with_capacity(kept);
    for (name, data) in &files[..kept] {
        let path = dir.join(name);
        std::fs::write(&path, data).map_err(|e| format!("{}: {e}", path.display()))?;
        written.push(path);
    }
    Ok(written)
}
