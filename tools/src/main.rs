//! The `rrskin` command line (contract: ../shared/ARCHITECTURE.md, "Command-line contract").

use clap::{Parser, Subcommand};
use rrskin::vk::DeviceChoice;
use rrskin::Model;
use rrskin_render::synthetic::{random_model, renumber_bones, Spec};
use rrskin_tools::eval::{Options, Report};
use rrskin_tools::import::example_set::ExampleSet;
use rrskin_tools::import::gltf::{Imported, Options as ImportOptions};
use rrskin_tools::train::{Method, TrainOptions};
use std::path::PathBuf;
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
    /// The main job on the bundled example: train, print the error table, write the model and
    /// render a comparison image and a crowd image.
    Demo {
        /// Where the model and the images go.
        #[arg(long, default_value = "demo-out")]
        out: PathBuf,
        /// The example set (default: the bundled CesiumMan).
        #[arg(long)]
        set: Option<PathBuf>,
    },
    /// Train every method on the training poses of SET and report the enveloping error.
    Eval {
        #[command(flatten)]
        set: SetArgs,
        #[command(flatten)]
        train: TrainArgs,
        /// Report leave-one-out error over the training poses as the test error.
        #[arg(long)]
        loocv: bool,
        /// Also print the error budget: oracle ceilings of the full and the runtime model.
        #[arg(long)]
        diagnose: bool,
        /// Evaluate this trained model (runtime CPU evaluator) as rr_reduced.
        #[arg(long)]
        model: Option<PathBuf>,
    },
    /// Train the runtime model on the training poses of SET and write it.
    Train {
        #[command(flatten)]
        set: SetArgs,
        #[command(flatten)]
        train: TrainArgs,
        #[arg(short, long)]
        output: PathBuf,
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
        /// List every bone after its children (bones renumbered J−1, …, 0), as many glTF skins
        /// order their joints.
        #[arg(long)]
        children_first: bool,
        #[arg(short, long)]
        output: PathBuf,
    },
    /// Rotational regression against plain SSD skinning of the same mesh: GPU time per frame.
    Bench(RunArgs),
    /// Per-pass GPU time (timestamp queries) of a crowd of the model's characters.
    Profile(RunArgs),
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

/// What training is asked for (defaults: [`TrainOptions::default`]).
#[derive(clap::Args)]
struct TrainArgs {
    /// Proxy bones P (the model's size and per-frame cost grow with it; 0: no reduction).
    #[arg(long, default_value_t = TrainOptions::default().proxies)]
    proxies: usize,
    /// --reduction paper: stop merging proxy bones earlier, when the RMS fitting error of the
    /// groups (mesh units) would pass this (the paper's ε).
    #[arg(long)]
    epsilon: Option<f64>,
    /// Influences per vertex (SSD and the runtime model): 4 or 8.
    #[arg(long, default_value_t = TrainOptions::default().influences)]
    influences: usize,
    /// How the runtime model is made: joint-blend proxies (default), or the paper's reduction
    /// of the full model.
    #[arg(long, value_enum, default_value_t = Reduction::JointBlend)]
    reduction: Reduction,
    /// --reduction paper: no gentle poses meshed by the full model (see `train::augment`).
    #[arg(long)]
    no_gentle_poses: bool,
    /// One JSON object (the contract of ARCHITECTURE.md) on stdout, no progress.
    #[arg(long)]
    json: bool,
}

#[derive(Clone, Copy, clap::ValueEnum)]
enum Reduction {
    JointBlend,
    Paper,
}

impl TrainArgs {
    fn options(&self) -> TrainOptions {
        let defaults = TrainOptions::default();
        TrainOptions {
            influences: self.influences,
            proxies: self.proxies,
            epsilon: self.epsilon,
            method: match self.reduction {
                Reduction::JointBlend => Method::JointBlend,
                Reduction::Paper => Method::Paper,
            },
            gentle_scales: if self.no_gentle_poses {
                Vec::new()
            } else {
                defaults.gentle_scales
            },
            quiet: self.json,
            ..defaults
        }
    }
}

/// A crowd of a model's characters run for some frames on one Vulkan device.
#[derive(clap::Args)]
struct RunArgs {
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
}

impl RunArgs {
    /// The model, and the device to run it on.
    fn load(&self) -> Result<(Model, DeviceChoice), Box<dyn std::error::Error>> {
        let choice = self
            .device
            .clone()
            .map_or(DeviceChoice::Auto, DeviceChoice::NameContains);
        Ok((Model::load(&self.model)?, choice))
    }
}

/// SET: a NumPy example-set folder, or a glTF rig (.glb/.gltf) with a point cache.
#[derive(clap::Args)]
struct SetArgs {
    /// An example-set folder (NumPy layout) or a glTF rig (.glb / .gltf).
    set: PathBuf,
    /// glTF rig: the animation that poses the rig at the cache's samples.
    #[arg(long)]
    clip: Option<String>,
    /// glTF rig: the point cache (.pc2 or .mdd) of the black-box rig's vertices, glTF order.
    #[arg(long)]
    cache: Option<PathBuf>,
    /// glTF rig: frames per second of the cache's frame numbers.
    #[arg(long, default_value_t = 24.0)]
    fps: f64,
    /// glTF rig: cache frames held out as test poses, e.g. 41..60 (inclusive).
    #[arg(long)]
    test_frames: Option<String>,
}

impl SetArgs {
    fn is_gltf(&self) -> bool {
        let ext = self
            .set
            .extension()
            .and_then(|e| e.to_str())
            .unwrap_or("")
            .to_ascii_lowercase();
        ext == "glb" || ext == "gltf"
    }

    /// The example set, and for a glTF rig what maps it back to the file's vertices.
    fn load(&self) -> Result<(ExampleSet, Option<Imported>), Box<dyn std::error::Error>> {
        if !self.is_gltf() {
            if self.clip.is_some() || self.cache.is_some() || self.test_frames.is_some() {
                return Err(format!(
                    "{}: --clip, --cache and --test-frames apply to a glTF rig (.glb/.gltf)",
                    self.set.display()
                )
                .into());
            }
            return Ok((ExampleSet::load(&self.set)?, None));
        }
        let (Some(clip), Some(cache)) = (&self.clip, &self.cache) else {
            return Err(format!(
                "{}: a glTF rig needs --clip NAME and --cache FILE.pc2|FILE.mdd",
                self.set.display()
            )
            .into());
        };
        let test_frames = self.test_frames.as_deref().map(parse_range).transpose()?;
        let options = ImportOptions {
            clip: clip.clone(),
            cache: cache.clone(),
            fps: self.fps,
            test_frames,
        };
        let imported = rrskin_tools::import::gltf::import(&self.set, &options)?;
        Ok((imported.set.clone(), Some(imported)))
    }
}

/// "A..B" (inclusive) as a frame range.
fn parse_range(text: &str) -> Result<(f64, f64), String> {
    let (a, b) = text
        .split_once("..")
        .ok_or_else(|| format!("--test-frames {text}: expected A..B"))?;
    let parse = |x: &str| {
        x.trim()
            .parse::<f64>()
            .map_err(|_| format!("--test-frames {text}: '{x}' is not a number"))
    };
    let (a, b) = (parse(a)?, parse(b)?);
    if b < a {
        return Err(format!("--test-frames {text}: the range is empty"));
    }
    Ok((a, b))
}

fn evaluate(
    set: &SetArgs,
    train: &TrainArgs,
    model: Option<PathBuf>,
    loocv: bool,
    diagnose: bool,
) -> Result<(Report, Option<Imported>), Box<dyn std::error::Error>> {
    let (examples, imported) = set.load()?;
    let model = match model {
        Some(path) => {
            let m = Model::load(&path)?;
            let m = match &imported {
                Some(imported) => imported.collapse(&m)?,
                None => m,
            };
            Some((path, m))
        }
        None => None,
    };
    if !train.json {
        examples
            .warnings
            .iter()
            .for_each(|w| eprintln!("warning: {w}"));
        if examples.test().is_empty() && !loocv {
            eprintln!(
                "warning: {}: no test poses, so no held-out error (--loocv reports leave-one-out over the training poses)",
                set.set.display()
            );
        }
    }
    let options = Options {
        train: train.options(),
        model,
        loocv,
        diagnose,
    };
    Ok((rrskin_tools::eval::run(&examples, &options)?, imported))
}

fn print_report(report: &Report, set: &SetArgs, json: bool) {
    let set = &set.set;
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
            train,
            loocv,
            diagnose,
            model,
        } => {
            let (report, _) = evaluate(&set, &train, model, loocv, diagnose)?;
            print_report(&report, &set, train.json);
        }
        Command::Train { set, train, output } => {
            if train.proxies == 0 {
                return Err("--proxies must be at least 1 (a model of P = 0 is plain SSD)".into());
            }
            let (report, imported) = evaluate(&set, &train, None, false, false)?;
            let model = report.model.as_ref().ok_or("training produced no model")?;
            // A glTF rig's model is written over the file's own vertices (order and count).
            let model = match &imported {
                Some(imported) => imported.expand(model)?,
                None => model.clone(),
            };
            model.save(&output)?;
            print_report(&report, &set, train.json);
            if !train.json {
                eprintln!(
                    "wrote {} ({} bytes)",
                    output.display(),
                    model.to_bytes().len()
                );
            }
        }
        Command::Bench(args) => {
            let (m, choice) = args.load()?;
            let (characters, frames, json) = (args.characters, args.frames, args.json);
            let b = rrskin_tools::run::profile::Bench::run(&m, characters, frames, choice, json)?;
            if json {
                out!("{}", b.to_json());
            } else {
                out!(
                    "{}: {} characters x {} vertices, median of {} frames\n  rotational regression {:.3} ms ({:.1} M vertices/s)\n  SSD                   {:.3} ms ({:.1} M vertices/s)\n  ratio                 {:.2}\n  RR + previous positions {:.3} ms ({:.2} x RR)\n  RR + bounds             {:.3} ms ({:.2} x RR)",
                    b.rr.device, b.rr.characters, b.rr.vertices, b.rr.frames,
                    b.rr.total_ms, b.rr.pipeline_mverts_per_s(), b.ssd.total_ms, b.ssd.pipeline_mverts_per_s(),
                    b.rr.total_ms / b.ssd.total_ms,
                    b.previous_positions.total_ms, b.cost(&b.previous_positions),
                    b.bounds.total_ms, b.cost(&b.bounds)
                );
            }
        }
        Command::Demo { out, set } => {
            let set = set.unwrap_or_else(|| {
                PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../data/cesiumman"))
            });
            let start = std::time::Instant::now();
            let o = rrskin_tools::run::demo::run(&set, &out, false)?;
            out!("{}", o.report.table(&set.display().to_string()));
            out!(
                "training (all methods, including the cross-validation): {:.1} s",
                o.report.stages.iter().map(|s| s.1).sum::<f64>()
            );
            out!(
                "held-out pose {}: RMS vertex error SSD {:.4}, rotational regression {:.4} (mesh units)",
                o.pose, o.rms.0, o.rms.1
            );
            out!("wrote\n  {}  (the runtime model)\n  {}  (ground truth | SSD | rotational regression; blue = 0, red >= {:.0} % of the height)\n  {}  ({} characters on the runtime)", o.model.display(), o.comparison.display(), 100.0 * rrskin_tools::run::demo::ERROR_SCALE, o.crowd.display(), rrskin_tools::run::demo::CROWD);
            out!("demo finished in {:.1} s", start.elapsed().as_secs_f64());
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
            children_first,
            output,
        } => {
            let mut m = random_model(
                Spec {
                    grid,
                    bones,
                    proxies,
                    influences,
                },
                seed,
            )?;
            if children_first {
                let reversed: Vec<usize> = (0..m.bone_count()).rev().collect();
                m = renumber_bones(&m, &reversed)?;
            }
            m.save(&output)?;
            eprintln!("wrote {} ({} vertices)", output.display(), m.vertex_count());
        }
        Command::Profile(args) => {
            let (m, choice) = args.load()?;
            let (characters, frames, json) = (args.characters, args.frames, args.json);
            let p = rrskin_tools::run::profile::run(&m, characters, frames, choice, json)?;
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
