//! `rrskin bench`: the whole per-frame pipeline of rotational regression against plain
//! matrix-palette skinning (with recomputed normals, and as engines skin: one pass with
//! transformed normals), and the cost of the runtime's optional outputs, from GPU timestamps
//! (the frames are `run/profile.rs`'s).

use super::profile::{context, poses, profile, Profile, Runner, WARM_UP_FRAMES};
use crate::progress::Progress;
use rrskin::vk::{CrowdOptions, DeviceChoice, PassTimings};
use rrskin::{Model, NormalMode};

/// The whole per-frame pipeline of rotational regression against plain matrix-palette skinning
/// (the model's SSD baseline: same mesh, its NNLS weights), both on one device in one run, from
/// GPU timestamps; and the cost of the runtime's optional outputs,
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
    /// The engine baseline: plain palette skinning with the model's SSD weights and transformed
    /// normals, one pass a frame (what a skin cache runs: Unreal's GPU skin cache, Godot's and
    /// Unity's compute skinning).
    pub engine: Profile,
    /// RR with transformed normals, its ratio to the plain RR frame.
    pub rr_transformed: OptionCost,
    /// RR with transformed normals over the engine baseline, per frame: like for like.
    pub engine_ratios: Vec<f64>,
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
    rrskin::cpu::median(values.iter().copied()).unwrap_or(f64::NAN)
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
        let transformed = with(|o| o.normals = NormalMode::Transformed);
        // RR first, SSD second, the engine baseline, RR with transformed normals, then the
        // options: the order of `Bench`'s fields.
        let mut variants = vec![
            (model, plain),
            (&baseline, plain),
            (&baseline, transformed),
            (model, transformed),
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
            "RR, SSD, the engine baseline and RR in each mode",
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
        let costs = (3..n)
            .map(|i| -> Result<OptionCost, Box<dyn std::error::Error>> {
                Ok(OptionCost {
                    profile: profile(&ctx, &runners[i], model, characters, &samples[i])?,
                    ratios: over_rr(&samples[i]),
                })
            })
            .collect::<Result<Vec<_>, _>>()?;
        let mut costs = costs.into_iter();
        let (Some(rr_transformed), Some(previous_positions), Some(bounds)) =
            (costs.next(), costs.next(), costs.next())
        else {
            return Err("an optional output was not measured".into());
        };
        let tangents = costs.next();
        Ok(Bench {
            rr: profile(&ctx, &runners[0], model, characters, &samples[0])?,
            ssd: profile(&ctx, &runners[1], &baseline, characters, &samples[1])?,
            pair_ratios: (rr_totals.iter().zip(total(&samples[1])))
                .map(|(rr, ssd)| rr / ssd)
                .collect(),
            engine: profile(&ctx, &runners[2], &baseline, characters, &samples[2])?,
            engine_ratios: (total(&samples[3]).iter().zip(total(&samples[2])))
                .map(|(rr, engine)| rr / engine)
                .collect(),
            rr_transformed,
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

    /// The median of the per-frame ratios of RR with transformed normals to the engine
    /// baseline.
    pub fn rr_vs_engine(&self) -> f64 {
        median(&self.engine_ratios)
    }

    /// `bandwidth_gbps`: the device's peak memory bandwidth, if known, for the fraction of the
    /// bandwidth bound each frame reaches (`run::traffic`).
    pub fn to_json(&self, bandwidth_gbps: Option<f64>) -> serde_json::Value {
        let mverts = |p: &Profile| p.pipeline_mverts_per_s();
        let fraction = |p: &Profile| bandwidth_gbps.map(|peak| p.effective_gbps() / peak);
        let passes = |p: &Profile| {
            serde_json::json!({
                "predict_ms": p.median.predict_ms,
                "blend_ms": p.median.product_ms,
                "proxy_correctives_ms": p.median.proxy_correctives_ms,
                "skin_ms": p.median.skin_ms,
                "normals_ms": p.median.normals_ms,
                "tangents_ms": p.median.tangents_ms,
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
            // Plain palette skinning with SSD weights and transformed normals, one pass; RR
            // with transformed normals, and its paired ratio to that baseline.
            "engine_ms": self.engine.total_ms,
            "engine_passes": passes(&self.engine),
            "rr_transformed_ms": self.rr_transformed.profile.total_ms,
            "rr_transformed_passes": passes(&self.rr_transformed.profile),
            "rr_transformed_ratio": self.rr_transformed.ratio(),
            "rr_vs_engine": self.rr_vs_engine(),
            "engine_bytes_per_frame": self.engine.bytes,
            "rr_transformed_bytes_per_frame": self.rr_transformed.profile.bytes,
            "engine_bandwidth_fraction": fraction(&self.engine),
            "rr_transformed_bandwidth_fraction": fraction(&self.rr_transformed.profile),
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
