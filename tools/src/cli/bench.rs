//! `rrskin bench MODEL.rrs`: the per-frame pipeline against plain palette skinning, or with
//! `--palette` the CPU palette.

use super::device::RunArgs;
use super::{count, Outcome};
use rrskin_tools::run::palette_bench::PaletteBench;

#[derive(clap::Args)]
pub struct BenchArgs {
    #[command(flatten)]
    pub run: RunArgs,
    /// Measure the CPU palette instead (what an engine with its own skinning runs): µs a
    /// character on one thread and on every core; no Vulkan device is used.
    #[arg(long)]
    pub palette: bool,
}

/// `rrskin bench`: RR against SSD and the optional outputs' costs, or the CPU palette.
pub fn run(args: &BenchArgs) -> Outcome {
    if args.palette {
        return palette(&args.run);
    }
    let args = &args.run;
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

/// `rrskin bench --palette`.
fn palette(args: &RunArgs) -> Outcome {
    let (m, _) = args.load()?;
    let b = PaletteBench::run(&m, args.characters, args.frames, args.json)?;
    match args.json {
        true => out!("{}", b.to_json()),
        false => out!(
            "CPU palette, {}, median of {}: {:.2} us a character on one thread, {:.2} us on {} threads",
            count(b.characters, "character"),
            count(b.frames, "run"),
            b.us,
            b.us_threads,
            b.threads
        ),
    }
    Ok(())
}
