//! `rrskin demo`: the main job on the bundled example.

use super::Outcome;
use rrskin_tools::output::shown;
use std::path::{Path, PathBuf};

#[derive(clap::Args)]
pub struct DemoArgs {
    /// Where the model and the images go.
    #[arg(long, default_value = "demo-out")]
    pub out: PathBuf,
    /// The example set (default: the bundled CesiumMan).
    #[arg(long)]
    pub set: Option<PathBuf>,
}

/// `rrskin demo`: train on the bundled example (or `set`), render and write the report.
pub fn run(args: &DemoArgs) -> Outcome {
    let (out, set) = (&args.out, args.set.clone());
    let set = set.unwrap_or_else(|| {
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .parent()
            .unwrap_or(Path::new(".."))
            .join("data/cesiumman")
    });
    let start = std::time::Instant::now();
    let o = rrskin_tools::run::demo::run(&set, out, false)?;
    out!("{}", o.report.table(&shown(&set)));
    out!(
        "training (all methods, including the cross-validation): {:.1} s",
        o.report.stages.iter().map(|s| s.1).sum::<f64>()
    );
    out!(
        "held-out pose {}: RMS vertex error SSD {:.4}, rotational regression {:.4} (mesh units)",
        o.pose,
        o.rms.0,
        o.rms.1
    );
    out!("rendered with the Vulkan runtime on {}", o.device);
    out!("wrote");
    for (path, what) in demo_files(&o) {
        out!("  {}  ({what})", shown(&path));
    }
    out!("demo finished in {:.1} s", start.elapsed().as_secs_f64());
    Ok(())
}

/// The files `rrskin demo` wrote, each with what it shows.
fn demo_files(o: &rrskin_tools::run::demo::Outputs) -> [(PathBuf, String); 6] {
    let scale = 100.0 * rrskin_tools::run::demo::ERROR_SCALE;
    let curve = (o.tradeoff.iter())
        .map(|x| format!("P = {} {:.1} %", x.proxies, x.test.unwrap_or(x.train)))
        .collect::<Vec<_>>()
        .join(", ");
    let crowd = rrskin_tools::run::demo::CROWD;
    [
        (o.model.clone(), "the runtime model".to_string()),
        (
            o.comparison.clone(),
            format!("ground truth | SSD | rotational regression; blue = 0, red >= {scale:.0} % of the height"),
        ),
        (
            o.closeup.clone(),
            "SSD | rotational regression where it gains most".to_string(),
        ),
        (o.crowd.clone(), format!("{crowd} characters on the runtime")),
        (o.tradeoff_plot.clone(), format!("EE against P: {curve}")),
        (
            o.model.with_file_name("report.html"),
            "the tables, the curve and the images".to_string(),
        ),
    ]
}
