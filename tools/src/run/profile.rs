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
            "tangents_ms": self.median.tangents_ms,
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
    profile(ctx, model, characters, &samples)
}

/// One crowd of a model with its own batch, run one frame at a time.
struct Runner {
    crowd: rrskin::vk::Crowd,
    batch: Batch,
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
        Ok(Runner {
            crowd,
            batch: Batch::new(ctx)?,
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

/// The medians of `samples`, frames of a crowd of `model`.
fn profile(
    ctx: &Context,
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
/// previous positions, bounds and tangents, as rotational-regression frames with each. RR and
/// SSD frames alternate in pairs of the same poses (RR SSD, SSD RR, RR SSD ...), so that load on
/// the machine drifts into both alike and neither is always first; each pair gives a ratio:
/// [`Bench::paired_ratio`] is their median.
pub struct Bench {
    pub rr: Profile,
    pub ssd: Profile,
    /// RR frame time over SSD frame time of each pair of consecutive frames.
    pub pair_ratios: Vec<f64>,
    pub previous_positions: Profile,
    pub bounds: Profile,
    /// For models with rest tangents.
    pub tangents: Option<Profile>,
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
        let (rr, ssd, pair_ratios) = {
            let mut rr = Runner::new(&ctx, model, characters, plain)?;
            let mut ssd = Runner::new(&ctx, &baseline, characters, plain)?;
            let progress = Progress::new(
                "rotational regression and SSD",
                WARM_UP_FRAMES + frames,
                quiet,
            );
            let (mut rr_samples, mut ssd_samples) =
                (Vec::with_capacity(frames), Vec::with_capacity(frames));
            for frame in 0..WARM_UP_FRAMES + frames {
                let bones = poses(model, characters, frame);
                // Which runs first alternates: on lavapipe the frame after the host's pose
                // work runs measurably slower than the one right after it.
                let pair = if frame % 2 == 0 {
                    (rr.frame(&bones)?, ssd.frame(&bones)?)
                } else {
                    let ssd_first = ssd.frame(&bones)?;
                    (rr.frame(&bones)?, ssd_first)
                };
                if frame >= WARM_UP_FRAMES {
                    rr_samples.push(pair.0);
                    ssd_samples.push(pair.1);
                }
                progress.step();
            }
            progress.finish();
            let ratios = (rr_samples.iter().zip(&ssd_samples))
                .map(|(r, s)| r.total_ms() / s.total_ms())
                .collect();
            (
                profile(&ctx, model, characters, &rr_samples)?,
                profile(&ctx, &baseline, characters, &ssd_samples)?,
                ratios,
            )
        };
        let run =
            |m: &Model, options, label| measure(&ctx, m, characters, frames, options, label, quiet);
        let previous = CrowdOptions {
            previous_positions: true,
            ..plain
        };
        let previous_positions = run(model, previous, "with previous positions")?;
        let bounded = CrowdOptions {
            bounds: true,
            ..plain
        };
        let bounds = run(model, bounded, "with bounds")?;
        let tangents = CrowdOptions {
            tangents: true,
            ..plain
        };
        let tangents = match model.has_tangents() {
            true => Some(run(model, tangents, "with tangents")?),
            false => None,
        };
        Ok(Bench {
            rr,
            ssd,
            pair_ratios,
            previous_positions,
            bounds,
            tangents,
        })
    }

    /// The frame time of rotational regression with `p`'s option, over the plain frame's.
    pub fn cost(&self, p: &Profile) -> f64 {
        p.total_ms / self.rr.total_ms
    }

    /// The median of the per-pair ratios RR / SSD (NaN if no pair was measured; `run`
    /// measures at least one).
    pub fn paired_ratio(&self) -> f64 {
        let mut r = self.pair_ratios.clone();
        r.sort_by(f64::total_cmp);
        r.get(r.len() / 2).copied().unwrap_or(f64::NAN)
    }

    pub fn to_json(&self) -> serde_json::Value {
        let mverts = |p: &Profile| p.pipeline_mverts_per_s();
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
            "previous_positions_ms": self.previous_positions.total_ms,
            "previous_positions_ratio": self.cost(&self.previous_positions),
            "bounds_ms": self.bounds.total_ms,
            "bounds_ratio": self.cost(&self.bounds),
            "tangents_ms": self.tangents.as_ref().map(|t| t.total_ms),
            "tangents_ratio": self.tangents.as_ref().map(|t| self.cost(t)),
            // The tangents pass alone, from the same frames (steadier than a ratio of totals),
            // and every pass of those frames.
            "tangents_pass_ms": self.tangents.as_ref().map(|t| t.median.tangents_ms),
            "tangents_frame": self.tangents.as_ref().map(Profile::to_json),
        })
    }
}
