//! The training options `eval` and `train` share, and SET: the example set they load.

use super::note;
use rrskin_tools::import::gltf::Imported;
use rrskin_tools::import::{ImportOptions, Loaded};
use rrskin_tools::set::ExampleSet;
use rrskin_tools::train::budget::CostBudget;
use rrskin_tools::train::{Method, TrainOptions};
use std::path::PathBuf;

/// What training is asked for (defaults: [`TrainOptions::default`]).
#[derive(clap::Args)]
pub struct TrainArgs {
    /// Proxy bones P (the model's size and per-frame cost grow with it; 0: no reduction).
    #[arg(long, default_value_t = TrainOptions::default().proxies)]
    pub proxies: usize,
    /// --reduction paper: stop merging proxy bones earlier, when the RMS fitting error of the
    /// groups (mesh units) would pass this (the paper's ε).
    #[arg(long)]
    pub epsilon: Option<f64>,
    /// Influences per vertex (SSD and the runtime model): 4 or 8.
    #[arg(long, default_value_t = TrainOptions::default().influences)]
    pub influences: usize,
    /// How the runtime model is made: joint-blend proxies, as many as cross-validation over the
    /// training poses chooses (auto, the default: a sixth or a third of P, P, or 1.5 P; or P
    /// delta-mush proxies, alone or after the joint-blend ones, where the cross-validation
    /// prefers them), joint-blend proxies with P (or P delta-mush proxies alone where preferred),
    /// the paper's reduction of the full model, P delta-mush proxies whatever the
    /// cross-validation says, or both: joint-blend proxies with P then P delta-mush proxies.
    #[arg(long, value_name = "auto|joint-blend|paper|delta-mush|both", default_value_t = Method::Auto)]
    pub reduction: Method,
    /// At most this many pose-space corrective targets on the runtime model (0: none; the
    /// cross-validation over the training poses may keep none). Each costs the runtime about
    /// 3 % of palette skinning.
    #[arg(long, default_value_t = TrainOptions::default().correctives)]
    pub correctives: usize,
    /// No proxy correctives (each proxy corrected from the nearby joints' rotations where the
    /// cross-validation keeps them; no per-vertex cost).
    #[arg(long)]
    pub no_proxy_correctives: bool,
    /// Also offer the proxy correctives a kernel per training pose (pose-space RBFs; the
    /// cross-validation still decides), at a run-time cost per kernel: held out, no better than
    /// without on the rigs measured and worse on some (docs/experiments.md).
    #[arg(long)]
    pub proxy_kernels: bool,
    /// The rig's up in the examples' frame, as x,y,z (normalised): the proxy correctives are
    /// offered each driver's orientation to gravity (the cross-validation decides).
    #[arg(long, value_name = "X,Y,Z", default_value = "0,1,0", value_parser = parse_up, allow_hyphen_values = true)]
    pub up: [f64; 3],
    /// Do not offer the proxy correctives gravity.
    #[arg(long)]
    pub no_gravity: bool,
    /// No delta-mush proxies (offered against the joint-blend model and kept where the
    /// cross-validation over the training poses prefers them: smoothing rigs, such as Delta
    /// DeltaMushReport or Corrective Smooth; they cost training a mesh merging and a cross-validation).
    #[arg(long)]
    pub no_delta_mush: bool,
    /// What the runtime model's frame may cost, as a multiple of the engine baseline (SSD's
    /// weights, one skinning pass with transformed normals), by the cost model (`rrskin info`
    /// reports it): every choice is the best cross-validated one within it. `none`: choose by
    /// error alone.
    #[arg(long, value_name = "R|none", default_value_t = FrameBudget(TrainOptions::default().budget.frame), value_parser = parse_budget, allow_hyphen_values = true)]
    pub budget: FrameBudget,
    /// What the CPU palette may cost, µs a character on one core (engines with their own
    /// skinning; by the cost model, calibrated on this project's machines). No limit by default.
    #[arg(long, value_name = "US", value_parser = parse_positive, allow_hyphen_values = true)]
    pub palette_budget: Option<f64>,
    /// --reduction paper: no gentle poses meshed by the full model (see `train::augment`).
    #[arg(long)]
    pub no_gentle_poses: bool,
    /// One JSON object (the contract of docs/cli.md) on stdout, no progress.
    #[arg(long)]
    pub json: bool,
}

/// `--budget`: a multiple of the engine baseline, or none.
#[derive(Clone, Copy, Debug)]
pub struct FrameBudget(pub Option<f64>);

impl std::fmt::Display for FrameBudget {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self.0 {
            Some(r) => write!(f, "{r}"),
            None => write!(f, "none"),
        }
    }
}

fn parse_budget(text: &str) -> Result<FrameBudget, String> {
    match text {
        "none" => Ok(FrameBudget(None)),
        _ => parse_positive(text).map(|r| FrameBudget(Some(r))),
    }
}

fn parse_positive(text: &str) -> Result<f64, String> {
    (text.trim().parse::<f64>().ok())
        .filter(|v| rrskin_tools::train::budget::is_limit(*v))
        .ok_or_else(|| format!("'{text}': expected a positive number"))
}

impl TrainArgs {
    pub fn options(&self) -> TrainOptions {
        let defaults = TrainOptions::default();
        TrainOptions {
            influences: self.influences,
            proxies: self.proxies,
            epsilon: self.epsilon,
            correctives: self.correctives,
            proxy_correctives: !self.no_proxy_correctives,
            proxy_kernels: self.proxy_kernels,
            up: (!self.no_gravity).then_some(self.up),
            delta_mush: !self.no_delta_mush,
            method: self.reduction,
            gentle_scales: if self.no_gentle_poses {
                Vec::new()
            } else {
                defaults.gentle_scales
            },
            budget: CostBudget {
                frame: self.budget.0,
                palette_us: self.palette_budget,
            },
            quiet: self.json,
            ..defaults
        }
    }
}

/// SET: a NumPy example-set folder, or a rig (.glb/.gltf/.fbx/.usd) with a point cache.
#[derive(clap::Args)]
pub struct SetArgs {
    /// An example-set folder (NumPy layout) or a rig (.glb / .gltf / .fbx, or USD as UsdSkel:
    /// .usd / .usda / .usdc).
    pub set: PathBuf,
    /// Rig: the animation (glTF), animation stack (FBX) or SkelAnimation (USD) that poses the
    /// rig at the cache's samples.
    #[arg(long)]
    pub clip: Option<String>,
    /// Rig: the point cache (.pc2, .mdd, Alembic .abc, USD with time-sampled mesh points, or a
    /// folder of per-frame .obj or .ply meshes numbered by their names) of the black-box rig's vertices, in the rig's vertex
    /// order or the DCC's own (mapped), world or object space, Y-up or Z-up (detected).
    #[arg(long)]
    pub cache: Option<PathBuf>,
    /// Rig: the clip's frames per second (glTF key time x fps = the DCC's frame number;
    /// PC2 and mesh-sequence frames become times with it, MDD, Alembic and USD times frames).
    #[arg(long, default_value_t = 24.0)]
    pub fps: f64,
    /// Rig: frames held out as test poses, e.g. 41..60 (inclusive; the DCC's frame
    /// numbers, after any shift of the cache onto the clip).
    #[arg(long)]
    pub test_frames: Option<String>,
}

impl SetArgs {
    /// The example set, and for a rig what maps it back to the file's vertices.
    pub fn load(&self) -> Result<(ExampleSet, Option<Imported>), Box<dyn std::error::Error>> {
        let options = ImportOptions {
            clip: self.clip.clone(),
            cache: self.cache.clone(),
            fps: self.fps,
            test_frames: self.test_frames.as_deref().map(parse_range).transpose()?,
        };
        match rrskin_tools::import::load(&self.set, &options)? {
            Loaded::Folder(set) => Ok((set, None)),
            Loaded::Rig(imported) => {
                // Facts about the inputs, not progress: printed under --json too (on stderr).
                for (file, line) in &imported.notes {
                    note(format_args!("note: {}: {line}", file.display()));
                }
                Ok((imported.set.clone(), Some(*imported)))
            }
        }
    }
}

/// What `eval` and `train` start from: SET loaded, `options` checked against it (refused naming
/// SET), and unless `quiet` the set's and the options' warnings shown.
pub fn load_for_training(
    set: &SetArgs,
    options: &TrainOptions,
    loocv: bool,
) -> Result<(ExampleSet, Option<Imported>), Box<dyn std::error::Error>> {
    let (examples, imported) = set.load()?;
    let path = set.set.display();
    let warnings = options
        .check(&examples)
        .map_err(|e| format!("{path}: {e}"))?;
    if !options.quiet {
        let no_test = (examples.test().is_empty() && !loocv).then(|| format!("{path}: no test poses, so no held-out error (--loocv reports leave-one-out over the training poses)"));
        let named = warnings.iter().map(|w| format!("{path}: {w}"));
        for w in examples
            .warnings
            .iter()
            .cloned()
            .chain(no_test)
            .chain(named)
        {
            note(format_args!("warning: {w}"));
        }
    }
    Ok((examples, imported))
}

/// "X,Y,Z" as a unit up vector.
fn parse_up(text: &str) -> Result<[f64; 3], String> {
    let parts: Vec<&str> = text.split(',').collect();
    let [x, y, z] = parts[..] else {
        return Err(format!("'{text}': expected X,Y,Z"));
    };
    let mut up = [0.0; 3];
    for (out, part) in up.iter_mut().zip([x, y, z]) {
        *out = (part.trim().parse::<f64>().ok())
            .filter(|v| v.is_finite())
            .ok_or_else(|| format!("'{text}': '{part}' is not a number"))?;
    }
    rrskin_tools::train::unit_up(up).ok_or_else(|| format!("'{text}': the up vector is zero"))
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
