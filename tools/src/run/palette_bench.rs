//! `rrskin bench --palette`: the CPU palette ([`rrskin::palette::Palette`], what an engine with
//! its own skinning runs) of any model, µs a character on one thread and on every core.

use super::profile::poses;
use crate::progress::Progress;
use rrskin::palette::Palette;
use rrskin::Model;
use std::time::Instant;

/// The CPU palette's time a character: the median over `frames` samples, each of the poses
/// `rrskin bench` gives the GPU for one frame (after one warm-up sample).
pub struct PaletteBench {
    pub characters: usize,
    pub frames: usize,
    /// µs a character, one thread ([`Palette::compute_batch`]).
    pub us: f64,
    /// µs a character of the batch split over `threads` ([`Palette::compute_batch_parallel`]).
    pub us_threads: f64,
    pub threads: usize,
}

impl PaletteBench {
    pub fn run(
        model: &Model,
        characters: usize,
        frames: usize,
        quiet: bool,
    ) -> Result<PaletteBench, Box<dyn std::error::Error>> {
        let palette = Palette::new(model.clone())?;
        let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
        let mut out = vec![[0.0f32; 12]; characters * palette.len()];
        let progress = Progress::new("the CPU palette, one thread and all", 1 + frames, quiet);
        let (mut one, mut all) = (Vec::new(), Vec::new());
        for frame in 0..=frames {
            let bones = poses(model, characters, frame);
            let single = per_character(characters, || palette.compute_batch(&bones, &mut out))?;
            let parallel = per_character(characters, || {
                palette.compute_batch_parallel(&bones, &[], &mut out, threads)
            })?;
            if frame > 0 {
                one.push(single);
                all.push(parallel);
            }
            progress.step();
        }
        progress.finish();
        let median = |v: Vec<f64>| rrskin::cpu::median(v).unwrap_or(f64::NAN);
        Ok(PaletteBench {
            characters,
            frames,
            us: median(one),
            us_threads: median(all),
            threads,
        })
    }

    pub fn to_json(&self) -> serde_json::Value {
        serde_json::json!({
            "characters": self.characters, "frames": self.frames, "palette_us": self.us,
            "palette_us_threads": self.us_threads, "threads": self.threads,
        })
    }
}

/// Each sample repeats its batch for at least this long, so that neither the timer's resolution
/// nor one preemption decides it.
const SAMPLE_SECONDS: f64 = 0.02;

/// µs a character of `batch` (of `characters`), repeated for [`SAMPLE_SECONDS`].
fn per_character(
    characters: usize,
    mut batch: impl FnMut() -> rrskin::Result<()>,
) -> rrskin::Result<f64> {
    let (start, mut runs) = (Instant::now(), 0usize);
    while runs == 0 || start.elapsed().as_secs_f64() < SAMPLE_SECONDS {
        batch()?;
        runs += 1;
    }
    Ok(start.elapsed().as_secs_f64() * 1e6 / (runs * characters) as f64)
}
