//! The `rrskin` command line (contract: ../shared/ARCHITECTURE.md, "Command-line contract").

use clap::{Parser, Subcommand};
use rrskin::synthetic::{random_model, Spec};
use rrskin::vk::DeviceChoice;
use rrskin::Model;
use rrskin_tools::eval::{Options, Report};
use rrskin_tools::example_set::ExampleSet;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

#[derive(Parser)]
#[command(
    name = "rrskin",
    version,
    about = "Real-time enveloping with rotational regression"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Train every method on the training poses of SET and report the enveloping error.
    Eval {
        /// An example-set folder (NumPy layout).
        set: PathBuf,
        /// One JSON object on stdout (the contract of ARCHITECTURE.md), no progress.
        #[arg(long)]
        json: bool,
        /// Report leave-one-out error over the training poses as the test error.
        #[arg(long)]
        loocv: bool,
        /// Influences per vertex (SSD and the runtime model): 4 or 8.
        #[arg(long, default_value_t = 4)]
        influences: usize,
        /// Proxy bones of the reduced model (0: no reduction).
        #[arg(long, default_value_t = DEFAULT_PROXIES)]
        proxies: usize,
        /// Stop merging proxy bones earlier at this RMS fitting error (mesh units).
        #[arg(long)]
        epsilon: Option<f64>,
        /// Evaluate this trained model (runtime CPU evaluator) as rr_reduced.
        #[arg(long)]
        model: Option<PathBuf>,
    },
    /// Train the runtime model on the training poses of SET and write it.
    Train {
        /// An example-set folder (NumPy layout).
        set: PathBuf,
        #[arg(short, long)]
        output: PathBuf,
        /// Proxy bones P (the model's size and per-frame cost grow with it).
        #[arg(long, default_value_t = DEFAULT_PROXIES)]
        proxies: usize,
        /// Stop merging proxy bones earlier, when the RMS fitting error of the groups (mesh
        /// units) would pass this (the paper's ε).
        #[arg(long)]
        epsilon: Option<f64>,
        /// Influences per vertex: 4 or 8.
        #[arg(long, default_value_t = 4)]
        influences: usize,
        /// One JSON object (the eval contract) on stdout, no progress.
        #[arg(long)]
        json: bool,
    },
    /// Print a model file's dimensions (validates it fully).
    Info {
        model: PathBuf,
        #[arg(long)]
        json: bool,
    },
    /// Write a synthetic model (random, valid, untrained) of chosen size, for profiling.
    Synth {
        /// Vertices = grid x grid.
        #[arg(long, default_value_t = 48)]
        grid: usize,
        #[arg(long, default_value_t = 19)]
        bones: usize,
        /// Proxy bones / key predictors (0: plain linear blend skinning).
        #[arg(long, default_value_t = 60)]
        proxies: usize,
        /// Influences per vertex: 4 or 8.
        #[arg(long, default_value_t = 4)]
        influences: u32,
        #[arg(long, default_value_t = 1)]
        seed: u64,
        #[arg(short, long)]
        output: PathBuf,
    },
    /// Per-pass GPU time (timestamp queries) of a crowd of the model's characters.
    Profile {
        model: PathBuf,
        #[arg(long, default_value_t = 256)]
        characters: usize,
        #[arg(long, default_value_t = 20)]
        frames: usize,
        /// Use the first Vulkan device whose name contains this text.
        #[arg(long)]
        device: Option<String>,
        #[arg(long)]
        json: bool,
    },
}

/// Prints to stdout; a closed pipe (`rrskin eval … | head`) ends output quietly, not in a panic.
macro_rules! out {
    ($($arg:tt)*) => {{
        use std::io::Write;
        let _ = writeln!(std::io::stdout(), $($arg)*);
    }};
}

fn main() -> ExitCode {
    match run(Cli::parse()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("rrskin: {e}");
            ExitCode::FAILURE
        }
    }
}

const DEFAULT_PROXIES: usize = 60;

fn evaluate(
    set: &Path,
    json: bool,
    options: Options,
) -> Result<Report, Box<dyn std::error::Error>> {
    if !matches!(options.influences, 4 | 8) {
        return Err(format!(
            "--influences {}: the runtime supports 4 or 8",
            options.influences
        )
        .into());
    }
    let examples = ExampleSet::load(set)?;
    if !json {
        examples
            .warnings
            .iter()
            .for_each(|w| eprintln!("warning: {w}"));
    }
    rrskin_tools::eval::run(&examples, &options)
}

fn print_report(report: &Report, set: &Path, json: bool) {
    if json {
        out!("{}", report.to_json());
    } else {
        out!("{}", report.table(&set.display().to_string()));
    }
}

fn run(cli: Cli) -> Result<(), Box<dyn std::error::Error>> {
    match cli.command {
        Command::Eval {
            set,
            json,
            loocv,
            influences,
            proxies,
            epsilon,
            model,
        } => {
            let model = model.map(Model::load).transpose()?;
            let report = evaluate(
                &set,
                json,
                Options {
                    influences,
                    proxies,
                    epsilon,
                    model,
                    loocv,
                    quiet: json,
                },
            )?;
            print_report(&report, &set, json);
        }
        Command::Train {
            set,
            output,
            proxies,
            epsilon,
            influences,
            json,
        } => {
            if proxies == 0 {
                return Err("--proxies must be at least 1 (a model of P = 0 is plain SSD)".into());
            }
            let report = evaluate(
                &set,
                json,
                Options {
                    influences,
                    proxies,
                    epsilon,
                    model: None,
                    loocv: false,
                    quiet: json,
                },
            )?;
            let model = report.model.as_ref().ok_or("training produced no model")?;
            model.save(&output)?;
            print_report(&report, &set, json);
            if !json {
                eprintln!(
                    "wrote {} ({} bytes)",
                    output.display(),
                    model.to_bytes().len()
                );
            }
        }
        Command::Info { model, json } => {
            let m = Model::load(&model)?;
            let dims = serde_json::json!({
                "vertices": m.vertex_count(), "triangles": m.triangle_count(),
                "bones": m.bone_count(), "proxies": m.proxy_count(), "influences": m.influences(),
            });
            if json {
                out!("{dims}");
            } else {
                out!(
                    "{}: V = {} vertices, T = {} triangles, J = {} bones, P = {} proxies, K = {} influences{}",
                    model.display(),
                    m.vertex_count(),
                    m.triangle_count(),
                    m.bone_count(),
                    m.proxy_count(),
                    m.influences(),
                    if m.proxy_count() == 0 { " (plain linear blend skinning)" } else { "" }
                );
            }
        }
        Command::Synth {
            grid,
            bones,
            proxies,
            influences,
            seed,
            output,
        } => {
            let m = random_model(
                Spec {
                    grid,
                    bones,
                    proxies,
                    influences,
                },
                seed,
            )?;
            m.save(&output)?;
            eprintln!("wrote {} ({} vertices)", output.display(), m.vertex_count());
        }
        Command::Profile {
            model,
            characters,
            frames,
            device,
            json,
        } => {
            let m = Model::load(&model)?;
            let choice = device.map_or(DeviceChoice::Auto, DeviceChoice::NameContains);
            let p = rrskin_tools::profile::run(&m, characters, frames.max(1), choice, json)?;
            if json {
                out!("{}", p.to_json());
            } else {
                let t = &p.median;
                out!(
                    "{}: {} characters x {} vertices (J = {}, P = {}, K = {}), median of {} frames",
                    p.device,
                    p.characters,
                    p.vertices,
                    p.bones,
                    p.proxies,
                    p.influences,
                    p.frames
                );
                for (name, ms) in [
                    ("predictors", t.predict_ms),
                    ("C1/C2 GEMM", t.blend_ms),
                    ("skinning", t.skin_ms),
                    ("normals", t.normals_ms),
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
            }
        }
    }
    Ok(())
}
