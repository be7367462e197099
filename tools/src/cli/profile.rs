//! `rrskin profile MODEL.rrs`: per-pass GPU time of a crowd.

use super::device::RunArgs;
use super::{count, Outcome};

/// `rrskin profile`: per-pass GPU time of a crowd.
pub fn run(args: &RunArgs) -> Outcome {
    let (m, choice) = args.load()?;
    let (characters, frames, json) = (args.characters, args.frames, args.json);
    let p = rrskin_tools::run::profile::run(&m, characters, frames, choice, json)?;
    if json {
        out!("{}", p.to_json());
        return Ok(());
    }
    let t = &p.median;
    out!(
        "{}: {} x {} vertices (J = {}, P = {}, K = {}), median of {}",
        p.device,
        count(p.characters, "character"),
        p.vertices,
        p.bones,
        p.proxies,
        p.influences,
        count(p.frames, "frame")
    );
    for (name, ms) in [
        ("predictors", t.predict_ms),
        ("C1/C2 prod.", t.product_ms),
        ("proxy corr.", t.proxy_correctives_ms),
        ("skinning", t.skin_ms),
        ("normals", t.normals_ms),
        ("tangents", t.tangents_ms),
    ] {
        out!(
            "  {name:<11} {ms:>9.3} ms  {:>5.1} %",
            100.0 * ms / t.total_ms()
        );
    }
    out!("  {:<11} {:>9.3} ms", "frame", p.total_ms);
    out!(
        "  skinning alone {:.1} M vertices/s, whole pipeline {:.1} M vertices/s",
        p.skin_mverts_per_s(),
        p.pipeline_mverts_per_s()
    );
    Ok(())
}
