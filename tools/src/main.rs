//! The `rrskin` command line (its contract: docs/cli.md).

use clap::{Parser, Subcommand};
use rrskin::vk::DeviceChoice;
use rrskin::Model;
use rrskin_render::synthetic::{random_model, renumber_bones, Spec};
use rrskin_tools::eval::{Options, Report};
use rrskin_tools::import::gltf::{Imported, Options as ImportOptions};
use rrskin_tools::import::tangents::Source;
use rrskin_tools::output::{check_writable, shown};
use rrskin_tools::progress::note;
use rrskin_tools::set::ExampleSet;
use rrskin_tools::train::{Method, TrainOptions};
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
    /// Write MODEL as a skinned glTF 2.0 binary (.glb) that any viewer or engine plays with its
    /// own skinning: the palette as joints, every clip baked through the model.
    Export(ExportArgs),
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
    Synth(SynthArgs),
    /// Rotational regression against plain SSD skinning of the same mesh: GPU time per frame.
    Bench(RunArgs),
    /// Per-pass GPU time (timestamp queries) of a crowd of the model's characters.
    Profile(RunArgs),
    /// Write a crowd's bone transforms and the CPU evaluator's positions for them
    /// (DIR/poses.bin, DIR/expected.bin, little-endian f32): the inputs of examples/c/crowd.c.
    Reference {
        model: PathBuf,
        #[arg(long, default_value_t = 3, value_parser = at_least_one)]
        frames: usize,
        #[arg(long, default_value_t = 64, value_parser = at_least_one)]
        characters: usize,
        #[arg(long)]
        out: PathBuf,
    },
}

/// Prints to stdout; a closed pipe (`rrskin eval … | head`) ends output quietly, not in a panic.
macro_rules! out {
    ($($arg:tt)*) => {{
        use std::io::Write;
        let _ = writeln!(std::io::stdout(), $($arg)*);
    }};
}

/// Exit 1 on every failure, a bad flag (clap's usage errors) included; 0 for --help.
fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => {
            let _ = e.print();
            return match e.use_stderr() {
                true => ExitCode::FAILURE,
                false => ExitCode::SUCCESS,
            };
        }
    };
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            note(format_args!("rrskin: {e}"));
            ExitCode::FAILURE
        }
    }
}

/// A count that must be at least 1 (`--frames 0` would measure nothing).
fn at_least_one(text: &str) -> Result<usize, String> {
    match text.parse::<usize>() {
        Ok(n) if n >= 1 => Ok(n),
        _ => Err(format!(
            "expected a whole number of at least 1, got '{text}'"
        )),
    }
}

/// "1 character", "2 characters".
fn count(n: usize, noun: &str) -> String {
    format!("{n} {noun}{}", if n == 1 { "" } else { "s" })
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
    /// How the runtime model is made: joint-blend proxies, as many as cross-validation over the
    /// training poses chooses (auto, the default: a sixth or a third of P, P, or 1.5 P),
    /// joint-blend proxies with P, or the paper's reduction of the full model.
    #[arg(long, value_enum, default_value_t = Reduction::Auto)]
    reduction: Reduction,
    /// At most this many pose-space corrective targets on the runtime model (0: none; the
    /// cross-validation over the training poses may keep none). Each costs the runtime about
    /// 3 % of palette skinning.
    #[arg(long, default_value_t = TrainOptions::default().correctives)]
    correctives: usize,
    /// No proxy correctives (each proxy corrected from the nearby joints' rotations where the
    /// cross-validation keeps them; no per-vertex cost).
    #[arg(long)]
    no_proxy_correctives: bool,
    /// Also offer the proxy correctives a kernel per training pose (pose-space RBFs; the
    /// cross-validation still decides), at a run-time cost per kernel: held out, no better than
    /// without on the rigs measured and worse on some (docs/experiments.md).
    #[arg(long)]
    proxy_kernels: bool,
    /// --reduction paper: no gentle poses meshed by the full model (see `train::augment`).
    #[arg(long)]
    no_gentle_poses: bool,
    /// One JSON object (the contract of docs/cli.md) on stdout, no progress.
    #[arg(long)]
    json: bool,
}

#[derive(Clone, Copy, clap::ValueEnum)]
enum Reduction {
    Auto,
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
            correctives: self.correctives,
            proxy_correctives: !self.no_proxy_correctives,
            proxy_kernels: self.proxy_kernels,
            method: match self.reduction {
                Reduction::Auto => Method::Auto,
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

/// The sizes and seed of `rrskin synth`'s model.
#[derive(clap::Args)]
struct SynthArgs {
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
}

/// A crowd of a model's characters run for some frames on one Vulkan device.
#[derive(clap::Args)]
struct RunArgs {
    model: PathBuf,
    #[arg(long, default_value_t = 256, value_parser = at_least_one)]
    characters: usize,
    /// Frames measured (after the warm-up).
    #[arg(long, default_value_t = 20, value_parser = at_least_one)]
    frames: usize,
    /// Use the first Vulkan device whose name contains this text.
    #[arg(long)]
    device: Option<String>,
    /// The device's peak memory bandwidth in GB/s (e.g. 4800 for an H200): `bench` then reports
    /// the fraction of the bandwidth bound each frame reaches (the least bytes a frame moves,
    /// `run::traffic`, over this, over the frame's time).
    #[arg(long)]
    bandwidth: Option<f64>,
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

/// SET: a NumPy example-set folder, or a rig (.glb/.gltf/.fbx) with a point cache.
#[derive(clap::Args)]
struct SetArgs {
    /// An example-set folder (NumPy layout) or a rig (.glb / .gltf / .fbx).
    set: PathBuf,
    /// Rig: the animation (glTF) or animation stack (FBX) that poses the rig at the cache's
    /// samples.
    #[arg(long)]
    clip: Option<String>,
    /// Rig: the point cache (.pc2, .mdd or Alembic .abc) of the black-box rig's vertices, in
    /// the rig's vertex order or the DCC's own (mapped), world or object space, Y-up or Z-up
    /// (detected).
    #[arg(long)]
    cache: Option<PathBuf>,
    /// Rig: the clip's frames per second (glTF key time x fps = the DCC's frame number;
    /// PC2 frames become times with it, MDD and Alembic times frames).
    #[arg(long, default_value_t = 24.0)]
    fps: f64,
    /// Rig: frames held out as test poses, e.g. 41..60 (inclusive; the DCC's frame
    /// numbers, after any shift of the cache onto the clip).
    #[arg(long)]
    test_frames: Option<String>,
}

impl SetArgs {
    fn is_rig(&self) -> bool {
        let ext = self
            .set
            .extension()
            .and_then(|e| e.to_str())
            .unwrap_or("")
            .to_ascii_lowercase();
        ext == "glb" || ext == "gltf" || ext == "fbx"
    }

    /// The example set, and for a glTF rig what maps it back to the file's vertices.
    fn load(&self) -> Result<(ExampleSet, Option<Imported>), Box<dyn std::error::Error>> {
        if !self.is_rig() {
            if self.clip.is_some() || self.cache.is_some() || self.test_frames.is_some() {
                return Err(format!(
                    "{}: --clip, --cache and --test-frames apply to a rig (.glb/.gltf/.fbx)",
                    self.set.display()
                )
                .into());
            }
            return Ok((ExampleSet::load(&self.set)?, None));
        }
        let (Some(clip), Some(cache)) = (&self.clip, &self.cache) else {
            return Err(format!(
                "{}: a rig needs --clip NAME and --cache FILE.pc2|FILE.mdd|FILE.abc",
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
        // Facts about the inputs, not progress: printed under --json too (on stderr).
        for (file, line) in &imported.notes {
            note(format_args!("note: {}: {line}", file.display()));
        }
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
    options: TrainOptions,
    model: Option<PathBuf>,
    loocv: bool,
    diagnose: bool,
) -> Result<(Report, Option<Imported>), Box<dyn std::error::Error>> {
    let (examples, imported) = set.load()?;
    let (poses, folds) = (examples.train().len(), options.folds);
    if poses < MIN_TRAINING_POSES {
        return Err(format!(
            "{}: {} training pose: training needs at least {MIN_TRAINING_POSES} (and {folds} to choose its settings by {folds}-fold cross-validation)",
            set.set.display(), poses
        )
        .into());
    }
    let model = match model {
        Some(path) => {
            let m = Model::load(&path)?;
            let m = match &imported {
                // Refused here, before training, with the file named.
                Some(imported) => {
                    imported
                        .collapse(&m)
                        .map_err(|_| rrskin_tools::Error::ModelMismatch {
                            model: path.clone(),
                            model_size: (m.vertex_count(), m.bone_count()),
                            set_size: (imported.rest.len(), examples.bone_count()),
                        })?
                }
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
            .for_each(|w| note(format_args!("warning: {w}")));
        if examples.test().is_empty() && !loocv {
            note(format_args!(
                "warning: {}: no test poses, so no held-out error (--loocv reports leave-one-out over the training poses)",
                set.set.display()
            ));
        }
        if poses < folds {
            note(format_args!(
                "warning: {}: {poses} training poses, fewer than the {folds} the cross-validation needs (one per fold): its settings are fixed, not chosen",
                set.set.display()
            ));
        }
        if let Some(w) = past_gain(train, &examples) {
            note(format_args!("warning: {w}"));
        }
    }
    let options = Options {
        train: options,
        model,
        loocv,
        diagnose,
    };
    Ok((rrskin_tools::eval::run(&examples, &options)?, imported))
}

/// One pose has no variation to regress on.
const MIN_TRAINING_POSES: usize = 2;

/// Proxies per bone past which the paper's reduction gained nothing measurable (README,
/// "Reduction trade-off": CesiumMan's test EE flat from P = 60, J = 19), while the model's size
/// and the C1/C2 product grow as P².
const PROXIES_PER_BONE_OF_GAIN: usize = 3;

/// A warning when `--proxies` is past the point of no gain. Joint-blend proxies need none: they
/// stop at three per moving joint whatever P asks.
fn past_gain(train: &TrainArgs, set: &ExampleSet) -> Option<String> {
    let gain = PROXIES_PER_BONE_OF_GAIN * set.bone_count();
    (matches!(train.reduction, Reduction::Paper) && train.proxies > gain && train.proxies <= set.faces.len()).then(|| {
        format!(
            "--proxies {}: past {PROXIES_PER_BONE_OF_GAIN} per bone ({gain} here) the paper's reduction measurably gains nothing, while training time, model size and the per-frame C1/C2 product grow as P²",
            train.proxies
        )
    })
}

fn print_report(report: &Report, set: &SetArgs, json: bool) {
    let set = &set.set;
    if json {
        out!("{}", report.to_json());
    } else {
        out!("{}", report.table(&set.display().to_string()));
    }
}

type Outcome = Result<(), Box<dyn std::error::Error>>;

fn run(cli: Cli) -> Outcome {
    match cli.command {
        Command::Eval {
            set,
            train,
            loocv,
            diagnose,
            model,
        } => {
            let (report, _) = evaluate(&set, &train, train.options(), model, loocv, diagnose)?;
            print_report(&report, &set, train.json);
            Ok(())
        }
        Command::Train { set, train, output } => train_model(&set, &train, &output),
        Command::Bench(args) => bench(&args),
        Command::Demo { out, set } => demo(&out, set),
        Command::Export(args) => export(&args),
        Command::Reference {
            model,
            frames,
            characters,
            out,
        } => reference(&model, frames, characters, &out),
        Command::Info { model, json } => info(&model, json),
        Command::Synth(args) => synth(&args),
        Command::Profile(args) => profile(&args),
    }
}

/// `rrskin train`: the runtime model of SET, written to `output`.
fn train_model(set: &SetArgs, train: &TrainArgs, output: &Path) -> Outcome {
    if train.proxies == 0 {
        return Err("--proxies must be at least 1 (a model of P = 0 is plain SSD)".into());
    }
    check_writable(output.parent().unwrap_or(Path::new("")))?;
    // The runtime model only: joint-blend proxies need no full model.
    let options = TrainOptions {
        full_model: false,
        ..train.options()
    };
    let (report, imported) = evaluate(set, train, options, None, false, false)?;
    let model = report.model.as_ref().ok_or("training produced no model")?;
    // A glTF rig's model is written over the file's own vertices (order and count).
    let model = match &imported {
        Some(imported) => imported.expand(model)?,
        None => model.clone(),
    };
    model.save(output)?;
    print_report(&report, set, train.json);
    if !train.json {
        let tangents = match imported.as_ref().and_then(|i| i.tangents.as_ref()) {
            Some((_, Source::File)) => "rest tangents from the file's TANGENT",
            Some((_, Source::MikkTSpace)) => "rest tangents by MikkTSpace from TEXCOORD_0",
            None => "no rest tangents (no UVs)",
        };
        note(format_args!(
            "wrote {} ({} bytes; {tangents})",
            output.display(),
            model.to_bytes().len()
        ));
    }
    Ok(())
}

/// `rrskin bench`: RR against SSD and the optional outputs' costs.
fn bench(args: &RunArgs) -> Outcome {
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

/// `rrskin demo`: train on the bundled example (or `set`), render and write the report.
fn demo(out: &Path, set: Option<PathBuf>) -> Outcome {
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

/// `rrskin reference`: the inputs and expected outputs of examples/c/crowd.c.
fn reference(model: &Path, frames: usize, characters: usize, out: &Path) -> Outcome {
    let m = Model::load(model)?;
    let written = rrskin_tools::run::reference::write(&m, frames, characters, out)?;
    let names: Vec<String> = written.iter().map(|p| p.display().to_string()).collect();
    note(format_args!(
        "wrote {} ({} x {} of {}: J = {}, V = {})",
        names.join(", "),
        count(frames, "frame"),
        count(characters, "character"),
        model.display(),
        m.bone_count(),
        m.vertex_count()
    ));
    Ok(())
}

/// `rrskin info`: a model file's dimensions.
fn info(model: &Path, json: bool) -> Outcome {
    let m = Model::load(model)?;
    if json {
        let dims = serde_json::json!({
            "vertices": m.vertex_count(), "triangles": m.triangle_count(),
            "bones": m.bone_count(), "proxies": m.proxy_count(), "influences": m.influences(),
            "tangents": m.has_tangents(), "correctives": m.corrective_count(),
            "proxy_correctives": m.proxy_corrective_count(),
        });
        out!("{dims}");
    } else {
        out!(
            "{}: V = {} vertices, T = {} triangles, J = {} bones, P = {} proxies, K = {} influences{}; {}; {} pose-space correctives; {} corrected proxies",
            model.display(),
            m.vertex_count(),
            m.triangle_count(),
            m.bone_count(),
            m.proxy_count(),
            m.influences(),
            if m.proxy_count() == 0 { " (plain linear blend skinning)" } else { "" },
            if m.has_tangents() { "rest tangents" } else { "no rest tangents" },
            m.corrective_count(),
            m.proxy_corrective_count(),
        );
    }
    Ok(())
}

/// `rrskin synth`: a random valid model of the chosen sizes.
fn synth(args: &SynthArgs) -> Outcome {
    let spec = Spec {
        grid: args.grid,
        bones: args.bones,
        proxies: args.proxies,
        influences: args.influences,
    };
    let mut m = random_model(spec, args.seed)?;
    if args.children_first {
        let reversed: Vec<usize> = (0..m.bone_count()).rev().collect();
        m = renumber_bones(&m, &reversed)?;
    }
    m.save(&args.output)?;
    note(format_args!(
        "wrote {} ({} vertices)",
        args.output.display(),
        m.vertex_count()
    ));
    Ok(())
}

/// `rrskin profile`: per-pass GPU time of a crowd.
fn profile(args: &RunArgs) -> Outcome {
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

#[derive(clap::Args)]
struct ExportArgs {
    model: PathBuf,
    /// The .glb to write.
    #[arg(short, long)]
    output: PathBuf,
    /// The glTF rig the model was trained from: its mesh, materials, joint names and clips.
    #[arg(long)]
    rig: Option<PathBuf>,
    /// A clip of the rig to bake (repeatable; default: every named clip).
    #[arg(long = "clip")]
    clips: Vec<String>,
    /// Frames a second of the model's own animation (without --rig).
    #[arg(long, default_value_t = 30.0)]
    fps: f64,
    /// Largest vertex distance allowed between the played file and the model, as a fraction
    /// of the rest mesh's bounding-box diagonal.
    #[arg(long, default_value_t = rrskin_tools::export::TOLERANCE)]
    tolerance: f64,
    /// One JSON object on stdout.
    #[arg(long)]
    json: bool,
}

/// `rrskin export`: the model as a skinned glTF.
fn export(args: &ExportArgs) -> Outcome {
    check_writable(args.output.parent().unwrap_or(Path::new("")))?;
    let e = rrskin_tools::export::run(&rrskin_tools::export::Options {
        model: args.model.clone(),
        output: args.output.clone(),
        rig: args.rig.clone(),
        clips: args.clips.clone(),
        fps: args.fps,
        tolerance: args.tolerance,
    })?;
    for line in &e.notes {
        note(format_args!("note: {}: {line}", shown(&e.output)));
    }
    if args.json {
        let clips: Vec<_> = e
            .clips
            .iter()
            .map(|c| {
                serde_json::json!({"name": c.name, "keys": c.keys, "samples": c.samples,
                    "worst_at_samples": c.worst_at_samples, "worst_between": c.worst_between})
            })
            .collect();
        out!(
            "{}",
            serde_json::json!({"output": shown(&e.output), "vertices": e.vertices,
                "joints": e.joints, "clips": clips})
        );
        return Ok(());
    }
    out!(
        "{}: {} vertices skinned by {} palette joints",
        shown(&e.output),
        e.vertices,
        e.joints
    );
    for c in &e.clips {
        out!(
            "  clip '{}': {} keys baked into {} samples; played vs the model: {:.2e} at the samples, {:.2e} between them (of the mesh's size)",
            c.name,
            c.keys,
            c.samples,
            c.worst_at_samples,
            c.worst_between
        );
    }
    Ok(())
}
