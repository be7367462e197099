//! `rrskin bench MODEL.rrs`: the per-frame pipeline against plain palette skinning.

use super::device::RunArgs;
use super::{count, Outcome};

/// `rrskin bench`: RR against SSD and the optional outputs' costs.
pub fn run(args: &RunArgs) -> Outcome {
    let (m, choice) = args.load()?;
    let (characters, frames, json) = (args.characters, args.frames, args.json);
    let b = rrskin_tools::run::bench::Bench::run(&m, characters, frames, choice, json)?;
    if json {
        out!("{}", b.to_json(args.bandwidth));
        return Ok(());
    }
    let (rr, ssd) = (&b.rr, &b.ssd);
    out!(
        "{}: {} x {} vertices, median of {}",
        rr.device,
        count(rr.characters, "character"),
        rr.vertices,
        count(rr.frames, "frame")
    );
    for (name, p) in [("rotational regression", rr), ("SSD", ssd)] {
        let (ms, mverts) = (p.total_ms, p.pipeline_mverts_per_s());
        out!("  {name:<21} {ms:.3} ms ({mverts:.1} M vertices/s)");
    }
    out!(
        "  ratio                 {:.2} (median of the {} pairs' ratios {:.2})",
        rr.total_ms / ssd.total_ms,
        b.pair_ratios.len(),
        b.paired_ratio()
    );
    out!(
        "  transformed normals: RR {:.3} ms, engine baseline (SSD, one pass) {:.3} ms, RR / engine {:.2}",
        b.rr_transformed.profile.total_ms,
        b.engine.total_ms,
        b.rr_vs_engine()
    );
    let options = [
        ("previous positions", Some(&b.previous_positions)),
        ("bounds", Some(&b.bounds)),
        ("tangents", b.tangents.as_ref()),
    ];
    for (name, cost) in options {
        match cost {
            Some(c) => out!(
                "  RR + {name:<18} {:.3} ms ({:.2} x RR)",
                c.profile.total_ms,
                c.ratio()
            ),
            None => out!("  RR + {name:<18} - (the model has no rest tangents)"),
        }
    }
    for (name, p) in [("RR", rr), ("SSD", ssd)] {
        let bound = match args.bandwidth {
            Some(peak) => format!(
                ", {:.0} % of the bandwidth bound",
                100.0 * p.effective_gbps() / peak
            ),
            None => String::new(),
        };
        out!(
            "  {name}: {:.1} MB a frame at least, {:.1} GB/s{bound}",
            p.bytes as f64 / 1e6,
            p.effective_gbps()
        );
    }
    Ok(())
}
