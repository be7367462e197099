//! `rrskin profile`: per-pass GPU time of one model's crowd, from timestamp queries, median over
//! frames after warm-up. Each frame uploads new poses, records all passes into one command
//! buffer, submits and waits.

use crate::progress::Progress;
use rrskin::synthetic::random_poses;
use rrskin::vk::{Batch, Context, ContextDesc, Crowd, DeviceChoice, GpuModel, PassTimings};
use rrskin::Model;

/// Frames run (and discarded) before measuring: the first dispatch pays lavapipe's JIT.
pub const WARM_UP_FRAMES: usize = 3;

#[derive(Debug, Clone)]
pub struct Profile {
    pub device: String,
    pub characters: usize,
    pub vertices: usize,
    pub bones: usize,
    pub proxies: usize,
    pub influences: usize,
    pub frames: usize,
    /// Median per pass over the measured frames.
    pub median: PassTimings,
    /// Median of the per-frame totals.
    pub total_ms: f64,
}

impl Profile {
    /// Skinned vertices per second counting the skinning pass alone, in millions.
    pub fn skin_mverts_per_s(&self) -> f64 {
        (self.characters * self.vertices) as f64 / self.median.skin_ms / 1e3
    }

    /// Vertices per second through the whole pipeline (all four passes), in millions.
    pub fn pipeline_mverts_per_s(&self) -> f64 {
        (self.characters * self.vertices) as f64 / self.total_ms / 1e3
    }

    pub fn to_json(&self) -> serde_json::Value {
        serde_json::json!({
            "device": self.device,
            "characters": self.characters,
            "vertices": self.vertices,
            "bones": self.bones,
            "proxies": self.proxies,
            "influences": self.influences,
            "frames": self.frames,
            "predict_ms": self.median.predict_ms,
            "blend_ms": self.median.blend_ms,
            "skin_ms": self.median.skin_ms,
            "normals_ms": self.median.normals_ms,
            "total_ms": self.total_ms,
            "skin_mverts_per_s": self.skin_mverts_per_s(),
            "pipeline_mverts_per_s": self.pipeline_mverts_per_s(),
        })
    }
}

pub fn run(
    model: &Model,
    characters: usize,
    frames: usize,
    device: DeviceChoice,
    quiet: bool,
) -> rrskin::Result<Profile> {
    let ctx = Context::headless(&ContextDesc {
        device,
        validation: false,
    })?;
    let gpu_model = GpuModel::new(&ctx, model)?;
    let mut crowd = Crowd::new(&gpu_model, characters)?;
    let mut batch = Batch::new(&ctx)?;
    let progress = Progress::new("profiling", WARM_UP_FRAMES + frames, quiet);
    let mut samples = Vec::with_capacity(frames);
    for frame in 0..WARM_UP_FRAMES + frames {
        crowd.set_bones(&random_poses(model, characters, frame as u64))?;
        batch.run(&[&crowd])?;
        if frame >= WARM_UP_FRAMES {
            samples.push(batch.timings()?);
        }
        progress.set(frame + 1);
    }
    progress.finish();
    let median = |f: fn(&PassTimings) -> f64| {
        let mut v: Vec<f64> = samples.iter().map(f).collect();
        v.sort_by(f64::total_cmp);
        v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
    };
    Ok(Profile {
        device: ctx.device_name().to_string(),
        characters,
        vertices: model.vertex_count(),
        bones: model.bone_count(),
        proxies: model.proxy_count(),
        influences: model.influences(),
        frames,
        median: PassTimings {
            predict_ms: median(|t| t.predict_ms),
            blend_ms: median(|t| t.blend_ms),
            skin_ms: median(|t| t.skin_ms),
            normals_ms: median(|t| t.normals_ms),
        },
        total_ms: median(PassTimings::total_ms),
    })
}
