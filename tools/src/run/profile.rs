//! `rrskin profile`: per-pass GPU time of one model's crowd, from timestamp queries, median over
//! frames after warm-up (and the frame runner `rrskin bench` shares, `run/bench.rs`). Each frame uploads new poses (the model's own animation, each character
//! at its own phase, when it carries one; random poses otherwise), records all passes into one
//! command buffer, submits and waits.

use crate::progress::Progress;
use rrskin::vk::{Batch, Context, ContextDesc, CrowdOptions, DeviceChoice, GpuModel, PassTimings};
use rrskin::Model;
use rrskin_render::phased_poses;
use rrskin_render::synthetic::random_poses;

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
    /// The least bytes a frame moves (`run::traffic`).
    pub bytes: u64,
}

impl Profile {
    /// Skinned vertices per second counting the skinning pass alone, in millions.
    pub fn skin_mverts_per_s(&self) -> f64 {
        (self.characters * self.vertices) as f64 / self.median.skin_ms / 1e3
    }

    /// Vertices per second through the whole pipeline (all five passes), in millions.
    pub fn pipeline_mverts_per_s(&self) -> f64 {
        (self.characters * self.vertices) as f64 / self.total_ms / 1e3
    }

    /// The frame's least bytes over its median time, in GB/s: the fraction of a device's peak
    /// bandwidth the frame reaches is this over the peak.
    pub fn effective_gbps(&self) -> f64 {
        self.bytes as f64 / (self.total_ms * 1e-3) / 1e9
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
            "blend_ms": self.median.product_ms,
            "proxy_correctives_ms": self.median.proxy_correctives_ms,
            "skin_ms": self.median.skin_ms,
            "normals_ms": self.median.normals_ms,
            "tangents_ms": self.median.tangents_ms,
            "total_ms": self.total_ms,
            "skin_mverts_per_s": self.skin_mverts_per_s(),
            "pipeline_mverts_per_s": self.pipeline_mverts_per_s(),
            "bytes_per_frame": self.bytes,
            "effective_gbps": self.effective_gbps(),
        })
    }
}

pub fn run(
    model: &Model,
    characters: usize,
    frames: usize,
    device: DeviceChoice,
    quiet: bool,
) -> Result<Profile, Box<dyn std::error::Error>> {
    measure(
        &context(device)?,
        model,
        characters,
        frames,
        CrowdOptions::default(),
        "profiling",
        quiet,
    )
}

/// A headless context on the chosen device, without validation (it would distort timings).
pub(super) fn context(device: DeviceChoice) -> rrskin::Result<Context> {
    Context::new(&ContextDesc {
        device,
        ..Default::default()
    })
}

/// Runs `frames` frames (after the warm-up) of a crowd of `model` made with `options` on `ctx`.
pub fn measure(
    ctx: &Context,
    model: &Model,
    characters: usize,
    frames: usize,
    options: CrowdOptions,
    label: &'static str,
    quiet: bool,
) -> Result<Profile, Box<dyn std::error::Error>> {
    let mut runner = Runner::new(ctx, model, characters, options)?;
    let progress = Progress::new(label, WARM_UP_FRAMES + frames, quiet);
    let mut samples = Vec::with_capacity(frames);
    for frame in 0..WARM_UP_FRAMES + frames {
        let timings = runner.frame(&poses(model, characters, frame))?;
        if frame >= WARM_UP_FRAMES {
            samples.push(timings);
        }
        progress.step();
    }
    progress.finish();
    profile(ctx, &runner, model, characters, &samples)
}

/// One crowd of a model with its own batch, run one frame at a time.
pub(super) struct Runner {
    crowd: rrskin::vk::Crowd,
    batch: Batch,
    /// `run::traffic::frame_bytes` of the crowd.
    bytes: u64,
}

impl Runner {
    pub(super) fn new(
        ctx: &Context,
        model: &Model,
        characters: usize,
        options: CrowdOptions,
    ) -> Result<Runner, Box<dyn std::error::Error>> {
        let gpu_model = GpuModel::new(ctx, model)?;
        let crowd = crate::run::capacity::crowd(ctx, &gpu_model, model, characters, options)?;
        let fused = gpu_model.fuses_predictors();
        Ok(Runner {
            crowd,
            batch: Batch::new(ctx)?,
            bytes: crate::run::traffic::frame_bytes(model, characters, &options, fused),
        })
    }

    /// Uploads `bones`, records all passes into one command buffer, submits, waits, and
    /// returns the frame's GPU times.
    pub(super) fn frame(
        &mut self,
        bones: &[rrskin::predict::Affine],
    ) -> Result<PassTimings, Box<dyn std::error::Error>> {
        self.crowd.set_bones(0, bones)?;
        self.batch.run(0, &[&self.crowd])?;
        Ok(self.batch.timings(0)?)
    }
}

/// The medians of `samples`, frames of `runner`'s crowd of `model`.
pub(super) fn profile(
    ctx: &Context,
    runner: &Runner,
    model: &Model,
    characters: usize,
    samples: &[PassTimings],
) -> Result<Profile, Box<dyn std::error::Error>> {
    let (median, total_ms) = PassTimings::median(samples).ok_or(rrskin::Error::NotReady {
        what: "timestamps (no frame measured)",
    })?;
    Ok(Profile {
        device: ctx.device_name().to_string(),
        characters,
        vertices: model.vertex_count(),
        bones: model.bone_count(),
        proxies: model.proxy_count(),
        influences: model.influences(),
        frames: samples.len(),
        median,
        total_ms,
        bytes: runner.bytes,
    })
}

/// The bone transforms of frame `frame`: the model's animation if it has one (as the crowd
/// sample plays it), else random poses. Neither assumes parents come before children.
pub fn poses(model: &Model, characters: usize, frame: usize) -> Vec<rrskin::predict::Affine> {
    match phased_poses(model, characters, frame) {
        none if none.is_empty() => random_poses(model, characters, frame as u64),
        animated => animated,
    }
}
