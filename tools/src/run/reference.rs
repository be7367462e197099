//! `rrskin reference`: frames of a crowd's bone transforms and the positions the runtime's CPU
//! evaluator (the oracle of every GPU test) computes for them, as raw little-endian f32 files:
//! the inputs of `examples/c/crowd.c`, and what an engine's integration can be checked against.

use crate::run::profile::poses;
use rrskin::cpu::CpuEvaluator;
use rrskin::Model;
use std::path::{Path, PathBuf};

/// Writes `dir/poses.bin` (frames x characters x J x 12 floats: 3x4 row-major transforms, the
/// model's animation at each character's phase, random poses without one) and
/// `dir/expected.bin` (frames x characters x V x 3 floats: positions); returns both paths.
pub fn write(
    model: &Model,
    frames: usize,
    characters: usize,
    dir: &Path,
) -> Result<(PathBuf, PathBuf), Box<dyn std::error::Error>> {
    crate::output::check_writable(dir)?;
    let v = model.vertex_count();
    let mut evaluator = CpuEvaluator::new(model);
    let (mut positions, mut normals) = (
        vec![[0.0f32; 3]; characters * v],
        vec![[0.0f32; 3]; characters * v],
    );
    let (mut pose_bytes, mut expected_bytes) = (Vec::new(), Vec::new());
    for frame in 0..frames {
        let bones = poses(model, characters, frame);
        evaluator.evaluate(&bones, &mut positions, &mut normals)?;
        pose_bytes.extend(bones.as_flattened().iter().flat_map(|x| x.to_le_bytes()));
        expected_bytes.extend(
            positions
                .as_flattened()
                .iter()
                .flat_map(|x| x.to_le_bytes()),
        );
    }
    let (poses_path, expected_path) = (dir.join("poses.bin"), dir.join("expected.bin"));
    for (path, bytes) in [(&poses_path, pose_bytes), (&expected_path, expected_bytes)] {
        std::fs::write(path, bytes).map_err(|e| format!("{}: {e}", path.display()))?;
    }
    Ok((poses_path, expected_path))
}
