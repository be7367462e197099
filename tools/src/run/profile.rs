//! `rrskin profile`: per-pass GPU time of one model's crowd, from timestamp queries, median over
//! frames after warm-up. Each frame uploads new poses (the model's own animation, each character
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

    /// Vertices per second through the whole pipeline (all four passes), in millions.
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
            "blend_ms": self.median.blend_ms,
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
fn context(device: DeviceChoice) -> rrskin::Result<Context> {
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
struct Runner {
    crowd: rrskin::vk::Crowd,
    batch: Batch,
    /// `run::traffic::frame_bytes` of the crowd.
    bytes: u64,
}

impl Runner {
    fn new(
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
    fn frame(
        &mut self,
        bones: &[rrskin::predict::Affine],
    ) -> Result<PassTimings, Box<dyn std::error::Error>> {
        self.crowd.set_bones(0, bones)?;
        self.batch.run(0, &[&self.crowd])?;
        Ok(self.batch.timings(0)?)
    }
}

/// The medians of `samples`, frames of `runner`'s crowd of `model`.
fn profile(
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

/// `rrskin bench`: the whole per-frame pipeline of rotational regression against plain
/// matrix-palette skinning (the model's SSD baseline: same mesh, its NNLS weights), both on one
/// device in one run, from GPU timestamps; and the cost of the runtime's optional outputs,
/// previous positions, bounds and tangents, as rotational-regression frames with each. Every
/// frame runs all of them on the same poses, one after another in an order that rotates from
/// frame to frame (so that load on the machine drifts into all alike, and none is always first:
/// on lavapipe the frame right after the host's pose work runs slower); each frame gives each a
/// ratio to that frame's plain RR (RR's to SSD), and the medians of those are what is reported.
pub struct Bench {
    pub rr: Profile,
    pub ssd: Profile,
    /// RR frame time over SSD frame time, per frame.
    pub pair_ratios: Vec<f64>,
    pub previous_positions: OptionCost,
    pub bounds: OptionCost,
    /// For models with rest tangents.
    pub tangents: Option<OptionCost>,
}

/// The frames of RR with one optional output, and per frame their time over the plain RR
/// frame's on the same poses.
pub struct OptionCost {
    pub profile: Profile,
    pub ratios: Vec<f64>,
}

impl OptionCost {
    /// The median ratio to the plain RR frame.
    pub fn ratio(&self) -> f64 {
        median(&self.ratios)
    }
}

fn median(values: &[f64]) -> f64 {
    let mut v = values.to_vec();
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
}

impl Bench {
    pub fn run(
        model: &Model,
        characters: usize,
        frames: usize,
        device: DeviceChoice,
        quiet: bool,
    ) -> Result<Bench, Box<dyn std::error::Error>> {
        let baseline = model.baseline().ok_or(
            "the model has no SSD baseline to compare with (train it with `rrskin train`)",
        )?;
        let ctx = context(device)?;
        let plain = CrowdOptions::default();
        let with = |f: fn(&mut CrowdOptions)| {
            let mut o = plain;
            f(&mut o);
            o
        };
        // RR first, SSD second, then the options: the order of `Bench`'s fields.
        let mut variants = vec![
            (model, plain),
            (&baseline, plain),
            (model, with(|o| o.previous_positions = true)),
            (model, with(|o| o.bounds = true)),
        ];
        if model.has_tangents() {
            variants.push((model, with(|o| o.tangents = true)));
        }
        let mut runners = (variants.iter())
            .map(|&(m, options)| Runner::new(&ctx, m, characters, options))
            .collect::<Result<Vec<_>, _>>()?;
        let n = runners.len();
        let progress = Progress::new(
            "RR, SSD and RR with each option",
            WARM_UP_FRAMES + frames,
            quiet,
        );
        let mut samples = vec![Vec::with_capacity(frames); n];
        let mut frame_times = vec![PassTimings::default(); n];
        for frame in 0..WARM_UP_FRAMES + frames {
            let bones = poses(model, characters, frame);
            for k in 0..n {
                let i = (frame + k) % n;
                frame_times[i] = runners[i].frame(&bones)?;
            }
            if frame >= WARM_UP_FRAMES {
                samples
                    .iter_mut()
                    .zip(&frame_times)
                    .for_each(|(s, t)| s.push(*t));
            }
            progress.step();
        }
        progress.finish();
        let total = |s: &[PassTimings]| s.iter().map(PassTimings::total_ms).collect::<Vec<_>>();
        let rr_totals = total(&samples[0]);
        let over_rr = |s: &[PassTimings]| {
            (total(s).iter().zip(&rr_totals))
                .map(|(t, rr)| t / rr)
                .collect::<Vec<_>>()
        };
        let costs = (2..n)
            .map(|i| -> Result<OptionCost, Box<dyn std::error::Error>> {
                Ok(OptionCost {
                    profile: profile(&ctx, &runners[i], model, characters, &samples[i])?,
                    ratios: over_rr(&samples[i]),
                })
            })
            .collect::<Result<Vec<_>, _>>()?;
        let mut costs = costs.into_iter();
        let (Some(previous_positions), Some(bounds)) = (costs.next(), costs.next()) else {
            return Err("an optional output was not measured".into());
        };
        let tangents = costs.next();
        Ok(Bench {
            rr: profile(&ctx, &runners[0], model, characters, &samples[0])?,
            ssd: profile(&ctx, &runners[1], &baseline, characters, &samples[1])?,
            pair_ratios: (rr_totals.iter().zip(total(&samples[1])))
                .map(|(rr, ssd)| rr / ssd)
                .collect(),
            previous_positions,
            bounds,
            tangents,
        })
    }

    /// The median of the per-pair ratios RR / SSD (NaN if no pair was measured; `run`
    /// measures at least one).
    pub fn paired_ratio(&self) -> f64 {
        median(&self.pair_ratios)
    }

    /// `bandwidth_gbps`: the device's peak memory bandwidth, if known, for the fraction of the
    /// bandwidth bound each frame reaches (`run::traffic`).
    pub fn to_json(&self, bandwidth_gbps: Option<f64>) -> serde_json::Value {
        let mverts = |p: &Profile| p.pipeline_mverts_per_s();
        let fraction = |p: &Profile| bandwidth_gbps.map(|peak| p.effective_gbps() / peak);
        let passes = |p: &Profile| {
            serde_json::json!({
                "predict_ms": p.median.predict_ms,
                "blend_ms": p.median.blend_ms,
                "skin_ms": p.median.skin_ms,
                "normals_ms": p.median.normals_ms,
            })
        };
        serde_json::json!({
            "device": self.rr.device,
            "characters": self.rr.characters,
            "vertices": self.rr.vertices,
            "rr_ms": self.rr.total_ms,
            "ssd_ms": self.ssd.total_ms,
            "ratio": self.rr.total_ms / self.ssd.total_ms,
            "paired_ratio": self.paired_ratio(),
            "pairs": self.pair_ratios.len(),
            "rr_passes": passes(&self.rr),
            "ssd_passes": passes(&self.ssd),
            "rr_mverts_per_s": mverts(&self.rr),
            "ssd_mverts_per_s": mverts(&self.ssd),
            "rr_bytes_per_frame": self.rr.bytes,
            "ssd_bytes_per_frame": self.ssd.bytes,
            "rr_effective_gbps": self.rr.effective_gbps(),
            "ssd_effective_gbps": self.ssd.effective_gbps(),
            "bandwidth_gbps": bandwidth_gbps,
            "rr_bandwidth_fraction": fraction(&self.rr),
            "ssd_bandwidth_fraction": fraction(&self.ssd),
            // Medians over the frames, each frame's ratio to its own plain RR frame.
            "previous_positions_ms": self.previous_positions.profile.total_ms,
            "previous_positions_ratio": self.previous_positions.ratio(),
            "bounds_ms": self.bounds.profile.total_ms,
            "bounds_ratio": self.bounds.ratio(),
            "tangents_ms": self.tangents.as_ref().map(|t| t.profile.total_ms),
            "tangents_ratio": self.tangents.as_ref().map(OptionCost::ratio),
            // The tangents pass alone, and every pass of the frames with tangents.
            "tangents_pass_ms": self.tangents.as_ref().map(|t| t.profile.median.tangents_ms),
            "tangents_frame": self.tangents.as_ref().map(|t| t.profile.to_json()),
        })
    }
}
