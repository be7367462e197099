//! The training pipeline: from example poses to the runtime model, one module per stage of
//! the paper and one entry point, [`run`].
//!
//! | stage | module | paper |
//! |---|---|---|
//! | deformation gradients and their polar factors | [`gradients`], [`full_model::Prepared`] | §3 |
//! | rigid and SSD baselines, the near-rigid set | [`ssd`], [`full_model::near_rigid`] | §4.2 |
//! | k-fold cross-validation: one split, one score, one rule | [`cross_validate`], [`pose_scale`] | beyond the paper |
//! | model selection by cross-validation | [`selection`] | beyond the paper |
//! | rotational regression | [`rotreg`] | §3.2 |
//! | scale/shear regression | [`scale_shear`] | §3.3 |
//! | Poisson reconstruction: the full model | [`poisson`], [`full_model`] | §4.1 |
//! | joint pivots from the poses | [`pivots`] | beyond the paper |
//! | gentle poses meshed by the full model | [`augment`] | beyond the paper |
//! | vertex reduction to P proxy bones | [`reduce::vertex`] | §5.1 |
//! | predictor reduction to P key predictors | [`reduce::predictor`] | §5.2 |
//! | C1/C2 and the runtime model | [`reduce::c1c2`] | §4.3 |
//! | or: joint-blend proxies, the usual runtime model | [`reduce::joint_blend`] | beyond the paper |
//! | their keys' pose-driven stretch | [`reduce::stretch`] | beyond the paper |
//! | and their local end-to-end refit of C1/C2 | [`reduce::refit`] | beyond the paper |
//! | how many joint-blend proxies: chosen per set | [`structure`] | beyond the paper |
//! | or delta-mush proxies, alone or after the joint-blend ones, where cross-validation prefers them | [`delta_mush`], [`reduce::delta_mush`] | beyond the paper |
//! | pose-space correctives on the runtime model | [`corrective`] | §8 (suggested there) |
//! | what the runtime model may cost: every choice within it | [`budget`] | beyond the paper |
//!
//! Every choice is made on the training poses; test poses are never looked at here.

pub mod augment;
pub mod budget;
pub mod corrective;
pub mod cross_validate;
pub mod delta_mush;
pub mod full_model;
pub mod gradients;
pub mod pivots;
pub mod poisson;
pub mod pose_scale;
pub mod proxy_corrective;
pub mod reduce;
pub mod rotreg;
pub mod scale_shear;
pub mod selection;
pub mod ssd;
pub mod structure;

use crate::progress::Progress;
use crate::set::ExampleSet;
use crate::skinning::lbs::Skinning;
use budget::{CostBudget, Ledger, Priced, Refused};
use cross_validate::Validated;
use full_model::{FullModel, Prepared};
use reduce::c1c2::Reduced;
use rotreg::PoseFeatures;
use selection::Selection;
use std::fmt;
use std::time::Instant;

/// How the runtime model is made.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Method {
    /// Joint-blend proxies with NNLS weights ([`reduce::joint_blend`]; beyond the paper):
    /// geometry that extrapolates as the rig's joints do.
    JointBlend,
    /// The paper's reduction of the full model (§5, §4.3), on the training poses and gentle
    /// poses meshed by the full model ([`augment`]).
    Paper,
    /// Joint-blend proxies, P chosen by cross-validation over the training poses
    /// ([`structure`]).
    Auto,
    /// Delta-mush proxies with P ([`delta_mush`]; beyond the paper), without the
    /// cross-validation against the joint-blend model (trained still, for evaluation).
    DeltaMush,
    /// Joint-blend proxies with P, then P delta-mush proxies in one palette
    /// ([`reduce::delta_mush::join`]; beyond the paper), without the cross-validation.
    Both,
}

impl Method {
    /// Every method, in `--reduction`'s order.
    pub const ALL: [Method; 5] = [
        Method::Auto,
        Method::JointBlend,
        Method::Paper,
        Method::DeltaMush,
        Method::Both,
    ];

    /// As `--reduction` (and the Python package's `reduction`) names it.
    pub fn name(self) -> &'static str {
        match self {
            Method::Auto => "auto",
            Method::JointBlend => "joint-blend",
            Method::Paper => "paper",
            Method::DeltaMush => "delta-mush",
            Method::Both => "both",
        }
    }
}

impl fmt::Display for Method {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for Method {
    type Err = String;

    fn from_str(text: &str) -> Result<Method, String> {
        let named = Method::ALL.into_iter().find(|m| m.name() == text);
        named.ok_or_else(|| {
            let names: Vec<&str> = Method::ALL.map(Method::name).into();
            format!("'{text}': expected one of {}", names.join(", "))
        })
    }
}

/// `up` as [`TrainOptions::up`] holds it, a unit vector; None where it has no direction (zero,
/// or not a number).
pub fn unit_up(up: [f64; 3]) -> Option<[f64; 3]> {
    let length = up.iter().map(|v| v * v).sum::<f64>().sqrt();
    (length.is_finite() && length >= 1e-9).then(|| up.map(|v| v / length))
}

/// Every training default, in one place.
#[derive(Debug, Clone, PartialEq)]
pub struct TrainOptions {
    /// K: influences per vertex, of SSD and of the runtime model (4 or 8).
    pub influences: usize,
    /// P: proxy bones of the runtime model (0: train the full model only); with
    /// [`Method::Auto`], the P the candidates start from.
    pub proxies: usize,
    /// The paper's reduction: stop merging proxies earlier at this RMS fitting error (mesh
    /// units; the paper's ε).
    pub epsilon: Option<f64>,
    /// Folds of the cross-validation over the training poses.
    pub folds: usize,
    pub method: Method,
    /// Joint-rotation scales of the gentle poses the paper's reduction also sees (empty: none).
    pub gentle_scales: Vec<f64>,
    /// Also train the paper's full model (eval's `rr_full`); the paper's reduction trains it
    /// regardless. `rrskin train` of joint-blend proxies leaves it out: the runtime model does
    /// not use it, and its cross-validation is most of the training time.
    pub full_model: bool,
    /// N: at most this many pose-space corrective targets on the runtime model ([`corrective`];
    /// 0: none, the default). Cross-validation may keep none. Off by default: each target costs
    /// the skinning pass about as much as 3 % of palette skinning (docs/performance.md).
    pub correctives: usize,
    /// Proxy correctives ([`proxy_corrective`]): each proxy corrected by an affine map of the
    /// nearby joints' rotations, where cross-validation finds they help. No per-vertex cost.
    pub proxy_correctives: bool,
    /// Also offer the proxy correctives a kernel per training pose and driver (docs/method.md
    /// §21): more accurate on some rigs, but they cost the runtime's proxy pass per kernel.
    pub proxy_kernels: bool,
    /// Offer the proxy correctives each driver's gravity features (docs/method.md §21) with
    /// this as the rig's up (unit, in the examples' frame: +Y for glTF, the default), taken
    /// where cross-validation finds they pay; None: not offered.
    pub up: Option<[f64; 3]>,
    /// Offer delta-mush proxies ([`delta_mush`], docs/method.md §23) against the joint-blend
    /// model, kept where cross-validation prefers them (smoothing rigs: Delta DeltaMushReport, Corrective
    /// Smooth). Off: the joint-blend model always.
    pub delta_mush: bool,
    /// What the runtime model may cost ([`budget`]): every choice the best within it.
    pub budget: CostBudget,
    /// Also price every joint-blend structure candidate (each built once more on all training
    /// poses), so that the accuracy/cost front has them (`rrskin eval`'s `pareto`).
    pub front: bool,
    /// Told of each stage, and may stop training there (the Python package's `progress`
    /// and Ctrl-C); the terminal's progress is `quiet`'s.
    pub observer: crate::progress::Observer,
    /// No progress output (for `--json`).
    pub quiet: bool,
}

impl Default for TrainOptions {
    fn default() -> TrainOptions {
        TrainOptions {
            influences: 4,
            proxies: 60,
            epsilon: None,
            folds: 4,
            method: Method::Auto,
            gentle_scales: vec![augment::GENTLE_SCALE],
            full_model: true,
            correctives: 0,
            proxy_correctives: true,
            proxy_kernels: false,
            up: Some([0.0, 1.0, 0.0]),
            delta_mush: true,
            budget: CostBudget::default(),
            front: false,
            observer: crate::progress::Observer::default(),
            quiet: false,
        }
    }
}

/// Why training stopped.
#[derive(Debug, Clone, PartialEq)]
pub enum TrainError {
    /// K is not one the runtime has shaders for.
    Influences { influences: usize },
    /// More corrective targets than a model holds.
    Correctives { correctives: usize, max: usize },
    /// Fewer training poses than training needs (one pose has no variation to regress on).
    TooFewPoses {
        poses: usize,
        min: usize,
        folds: usize,
    },
    /// More proxy bones than the paper's reduction can make (one per triangle at most).
    TooManyProxies { proxies: usize, triangles: usize },
    /// The Poisson system cannot be factored (a component without a fixed vertex).
    Poisson { problem: String },
    /// Direct Delta DeltaMushReport's smoothing could not be precomputed (its system not positive
    /// definite: a bug if it happens, the system is by construction).
    Smoothing { problem: String },
    /// The runtime refused the trained model (a bug if it happens: training makes valid models).
    Model { source: rrskin::Error },
    /// The caller's observer ([`TrainOptions::observer`]) stopped training between stages.
    Interrupted,
}

impl From<crate::progress::Interrupted> for TrainError {
    fn from(_: crate::progress::Interrupted) -> TrainError {
        TrainError::Interrupted
    }
}

impl fmt::Display for TrainError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            TrainError::Influences { influences } => {
                write!(f, "{influences} influences per vertex: the runtime supports 4 or 8")
            }
            TrainError::Correctives { correctives, max } => write!(
                f,
                "--correctives {correctives}: a model holds at most {max} pose-space corrective targets"
            ),
            TrainError::TooFewPoses { poses, min, folds } => write!(
                f,
                "{poses} training pose{}: training needs at least {min} (and {folds} to choose its settings by {folds}-fold cross-validation)",
                if *poses == 1 { "" } else { "s" }
            ),
            TrainError::TooManyProxies { proxies, triangles } => write!(
                f,
                "--proxies {proxies}: the reduction makes at most one proxy per triangle ({triangles})"
            ),
            TrainError::Poisson { problem } => write!(f, "Poisson system: {problem}"),
            TrainError::Smoothing { problem } => write!(f, "delta-mush proxies: {problem}"),
            TrainError::Model { source } => write!(f, "the trained model is invalid: {source}"),
            TrainError::Interrupted => write!(f, "training was interrupted"),
        }
    }
}

impl std::error::Error for TrainError {}

impl From<poisson::PoissonError> for TrainError {
    fn from(e: poisson::PoissonError) -> TrainError {
        TrainError::Poisson { problem: e.0 }
    }
}

impl From<rrskin::Error> for TrainError {
    fn from(source: rrskin::Error) -> TrainError {
        TrainError::Model { source }
    }
}

/// The paper's full model (§3–4) and what it was made from.
pub struct Full {
    pub prep: Prepared,
    pub selection: Selection,
    pub model: FullModel,
}

/// Everything training produced, for the runtime model and for evaluation.
pub struct Trained {
    /// Per pose: the joints' rotations.
    pub feats: Vec<PoseFeatures>,
    /// The best rigid predictor (one bone per vertex): EE's 100 %.
    pub rigid: Skinning,
    pub ssd: Skinning,
    /// The full model, when asked for ([`TrainOptions::full_model`]) or needed.
    pub full: Option<Full>,
    /// The reduced model in f64, the one that ships (joint-blend, delta-mush proxies or both;
    /// None when P = 0).
    pub reduced: Option<Reduced>,
    /// What the joint-blend model's stretch fit and refit chose (None for the paper's
    /// reduction).
    pub joint_blend: Option<structure::JointBlendFit>,
    /// The runtime model's structure and, with [`Method::Auto`], every candidate's score.
    pub structure: Option<structure::Chosen>,
    /// What the correctives' cross-validation chose (None: not asked for, or no runtime model).
    pub correctives: Option<corrective::Fit>,
    /// What the proxy corrective fit chose (None: not asked for, or no runtime model).
    pub proxy_correctives: Option<proxy_corrective::Fit>,
    /// The delta-mush proxies and their cross-validation against the joint-blend model and
    /// both in one palette (None: not asked for, or no joint-blend model to compare with).
    pub delta_mush: Option<delta_mush::Fit>,
    pub model: Option<rrskin::Model>,
    /// The runtime model's predicted cost ([`budget::Priced`]).
    pub priced: Option<Priced>,
    /// What the cost budget refused, in the order the stages met it.
    pub refused: Vec<Refused>,
    /// Every candidate scored and priced: the accuracy/cost front's points.
    pub points: Vec<budget::Point>,
    /// Wall time per stage, in order.
    pub seconds: Vec<(&'static str, f64)>,
}

/// Stage timings as they happen.
struct Clock {
    last: Instant,
    seconds: Vec<(&'static str, f64)>,
}

impl Clock {
    fn lap(&mut self, stage: &'static str) {
        self.seconds
            .push((stage, self.last.elapsed().as_secs_f64()));
        self.last = Instant::now();
    }
}

/// Fewer training poses cannot train: one pose has no variation to regress on.
pub const MIN_TRAINING_POSES: usize = 2;

/// Proxies per bone past which the paper's reduction gained nothing measurable (README,
/// "Reduction trade-off": CesiumMan's test EE flat from P = 60, J = 19), while the model's size
/// and the C1/C2 product grow as P².
const PROXIES_PER_BONE_OF_GAIN: usize = 3;

impl TrainOptions {
    /// Whether training fits delta-mush proxies ([`delta_mush`]): asked for, or offered against
    /// a joint-blend model.
    pub fn offers_delta_mush(&self) -> bool {
        match self.method {
            Method::DeltaMush | Method::Both => true,
            Method::Paper => false,
            Method::JointBlend | Method::Auto => self.delta_mush,
        }
    }

    /// Refuses what cannot train on `set`; returns warnings of what trains poorly. [`run`]
    /// checks the same, so a caller needs this only to show the warnings before training.
    pub fn check(&self, set: &ExampleSet) -> Result<Vec<String>, TrainError> {
        let k = self.influences;
        if !rrskin::model::SUPPORTED_INFLUENCES.contains(&(k as u32)) {
            return Err(TrainError::Influences { influences: k });
        }
        if self.correctives > rrskin::model::MAX_CORRECTIVES {
            return Err(TrainError::Correctives {
                correctives: self.correctives,
                max: rrskin::model::MAX_CORRECTIVES,
            });
        }
        let poses = set.train().len();
        if poses < MIN_TRAINING_POSES {
            return Err(TrainError::TooFewPoses {
                poses,
                min: MIN_TRAINING_POSES,
                folds: self.folds,
            });
        }
        let triangles = set.faces.len();
        if self.method == Method::Paper && self.proxies > triangles {
            return Err(TrainError::TooManyProxies {
                proxies: self.proxies,
                triangles,
            });
        }
        let mut warnings = Vec::new();
        if poses < self.folds {
            warnings.push(format!("{poses} training poses, fewer than the {} the cross-validation needs (one per fold): its settings are fixed, not chosen", self.folds));
        }
        // Joint-blend proxies need no such warning: they stop at three per moving joint.
        let gain = PROXIES_PER_BONE_OF_GAIN * set.bone_count();
        if self.method == Method::Paper && self.proxies > gain {
            warnings.push(format!("--proxies {}: past {PROXIES_PER_BONE_OF_GAIN} per bone ({gain} here) the paper's reduction measurably gains nothing, while training time, model size and the per-frame C1/C2 product grow as P²", self.proxies));
        }
        Ok(warnings)
    }
}

/// Trains the full model and, for P > 0, the runtime model on the training poses of `set`.
pub fn run(set: &ExampleSet, options: &TrainOptions) -> Result<Trained, TrainError> {
    options.check(set)?;
    let (k, train) = (options.influences, set.train());
    let feats = PoseFeatures::all(set);
    let pool = reduce::joint_blend::pool(set, &feats, &train);
    let with_full = options.full_model || (options.proxies > 0 && options.method == Method::Paper);
    let steps = if with_full { options.folds + 3 } else { 2 };
    let steps = steps
        + usize::from(options.method == Method::Auto)
        + usize::from(options.proxies > 0 && options.correctives > 0)
        + usize::from(options.proxies > 0 && options.proxy_correctives)
        + usize::from(options.proxies > 0 && options.offers_delta_mush());
    let progress =
        Progress::new("training", steps, options.quiet).observed(options.observer.clone());
    let mut clock = Clock {
        last: Instant::now(),
        seconds: Vec::new(),
    };

    progress.stage("SSD")?;
    let rigid_errors = crate::skinning::lbs::rigid_errors(set, &train);
    let rigid = Skinning::rigid(&crate::skinning::lbs::rigid_bones(&rigid_errors));
    let ssd = ssd::fit(set, &train, &rigid_errors, k);
    clock.lap("ssd");
    progress.step();

    let ledger = Ledger::default();
    let stages = Stages {
        set,
        train: &train,
        feats: &feats,
        rigid: &rigid,
        ssd: &ssd,
        options,
        progress: &progress,
        ledger: &ledger,
    };
    let full = match with_full {
        false => None,
        true => Some(stages.fit_full(&mut clock)?),
    };
    let runtime = match options.proxies {
        0 => Runtime::default(),
        proxies => stages.fit_runtime(full.as_ref(), proxies, pool, &mut clock)?,
    };
    progress.step();
    progress.finish();
    let (refused, points) = ledger.into_parts();
    Ok(Trained {
        feats,
        rigid,
        ssd,
        full,
        reduced: runtime.reduced,
        joint_blend: runtime.joint_blend,
        structure: runtime.structure,
        correctives: runtime.correctives,
        proxy_correctives: runtime.proxy_correctives,
        delta_mush: runtime.delta_mush,
        priced: runtime.model.as_ref().map(Priced::of),
        model: runtime.model,
        refused,
        points,
        seconds: clock.seconds,
    })
}

/// What the stages after SSD read: the set, its training poses and their features, the two
/// baselines, the options, the progress bar each stage reports to, and the ledger of what the
/// cost budget refused.
struct Stages<'a> {
    set: &'a ExampleSet,
    train: &'a [usize],
    feats: &'a [PoseFeatures],
    rigid: &'a Skinning,
    ssd: &'a Skinning,
    options: &'a TrainOptions,
    progress: &'a Progress,
    ledger: &'a Ledger,
}

/// The runtime model and what its stages chose ([`Trained`]'s fields of the same names; all
/// `None` for P = 0).
#[derive(Default)]
struct Runtime {
    reduced: Option<Reduced>,
    model: Option<rrskin::Model>,
    joint_blend: Option<structure::JointBlendFit>,
    structure: Option<structure::Chosen>,
    correctives: Option<corrective::Fit>,
    proxy_correctives: Option<proxy_corrective::Fit>,
    delta_mush: Option<delta_mush::Fit>,
}

impl Stages<'_> {
    /// The full model, in three stages: the deformation gradients, the cross-validated
    /// selection of its settings, and the Poisson fit.
    fn fit_full(&self, clock: &mut Clock) -> Result<Full, TrainError> {
        let (set, train, options, progress) = (self.set, self.train, self.options, self.progress);
        progress.stage("gradients")?;
        let prep = Prepared::new(set, self.feats.to_vec());
        clock.lap("gradients");
        progress.stage("cross-validation")?;
        let k = options.influences;
        let selection =
            selection::choose(set, &prep, train, self.rigid, k, options.folds, progress)?;
        clock.lap("cross-validation");
        progress.stage("full model")?;
        let model = full_model::fit(set, &prep, train, self.ssd, &selection)?;
        clock.lap("full model");
        progress.step();
        Ok(Full {
            prep,
            selection,
            model,
        })
    }

    /// The runtime model of P = `proxies`: its reduction and structure, then the proxy
    /// correctives and the correctives where asked for. `pool` bounds Auto's joint-blend
    /// candidates.
    fn fit_runtime(
        &self,
        full: Option<&Full>,
        proxies: usize,
        pool: usize,
        clock: &mut Clock,
    ) -> Result<Runtime, TrainError> {
        let (reduced, joint_blend, mut chosen) = self.reduce(full, proxies, pool, clock)?;
        let (mut delta_mush, shipped) = match &joint_blend {
            Some(fit) => self.fit_delta_mush(&chosen, fit, &reduced, clock)?,
            None => (None, None),
        };
        // The folds' models served the delta-mush stage; nothing after it reads them, and the
        // trained result does not keep them (a reduced model per fold and candidate).
        chosen.built = Default::default();
        let reduced = shipped.unwrap_or(reduced);
        let model = reduced.to_runtime(self.set, chosen.structure.influences)?;
        // Whatever kind ships: the correctives' own cross-validation decides (in the delta-mush
        // stage already, where it compared the kinds so).
        let searched = delta_mush.as_mut().and_then(|m| m.correctives.take());
        let (model, proxy_correctives) =
            self.add_proxy_correctives(&reduced, model, searched, clock)?;
        let (model, correctives) = self.add_correctives(model, clock)?;
        Ok(Runtime {
            reduced: Some(reduced),
            model: Some(model),
            joint_blend,
            structure: Some(chosen),
            correctives,
            proxy_correctives,
            delta_mush,
        })
    }

    /// Where [`TrainOptions::offers_delta_mush`], its stage: delta-mush proxies of the P and K
    /// asked for, cross-validated against the chosen joint-blend structure; with the reduced
    /// model that ships in place of `reduced`, the joint-blend one, where it does not.
    fn fit_delta_mush(
        &self,
        chosen: &structure::Chosen,
        joint_blend: &structure::JointBlendFit,
        reduced: &Reduced,
        clock: &mut Clock,
    ) -> Result<(Option<delta_mush::Fit>, Option<Reduced>), TrainError> {
        if !self.options.offers_delta_mush() {
            return Ok((None, None));
        }
        self.progress.stage("delta-mush proxies")?;
        let inputs = delta_mush::Inputs {
            set: self.set,
            train: self.train,
            feats: self.feats,
            rigid: self.rigid,
            ssd: self.ssd,
            chosen,
            joint_blend,
            reduced,
            ledger: self.ledger,
        };
        let (fit, shipped) = delta_mush::fit(&inputs, self.options)?;
        clock.lap("delta-mush proxies");
        self.progress.step();
        Ok((Some(fit), shipped))
    }

    /// The reduction to the runtime model's structure: the one asked for, or with
    /// [`Method::Auto`] the one its cross-validation chose (rebuilt unless it is the first
    /// candidate, which is built anyway for the ridges the candidates' folds use).
    fn reduce(
        &self,
        full: Option<&Full>,
        proxies: usize,
        pool: usize,
        clock: &mut Clock,
    ) -> Result<(Reduced, Option<structure::JointBlendFit>, structure::Chosen), TrainError> {
        let (set, feats, ssd, options, progress) =
            (self.set, self.feats, self.ssd, self.options, self.progress);
        // Auto starts from its first candidate, which also fixes the ridges its folds use.
        let first = structure::Structure {
            method: match options.method {
                Method::Auto | Method::DeltaMush | Method::Both => Method::JointBlend,
                method => method,
            },
            proxies,
            influences: options.influences,
        };
        progress.stage("reduction")?;
        let full_parts = full.map(|f| (&f.prep, &f.model));
        let (mut reduced, mut fitted) =
            structure::build(set, feats, ssd, full_parts, &first, options, None);
        clock.lap("reduction");
        let chosen = match (options.method, &fitted) {
            (Method::Auto, Some(f)) => {
                progress.stage("structure")?;
                let (candidates, ridges) = (structure::candidates(options, pool), f.ridges());
                let c = structure::choose(set, feats, self.rigid, &candidates, ridges, options);
                if c.structure != first {
                    (reduced, fitted) =
                        structure::build(set, feats, ssd, full_parts, &c.structure, options, None);
                }
                if options.front {
                    self.price_structures(&c, &reduced, ridges)?;
                }
                let built = self.within_budget(c, reduced, fitted)?;
                clock.lap("structure");
                progress.step();
                return Ok(built);
            }
            _ => structure::Chosen {
                structure: first,
                candidates: Vec::new(),
                folds: 0,
                why: structure::Why::Asked,
                relative: Vec::new(),
                built: Default::default(),
            },
        };
        Ok((reduced, fitted, chosen))
    }

    /// Notes every joint-blend structure candidate of `chosen` as a point of the front: its
    /// cross-validated EE and the price of its model fitted to all training poses (`reduced`
    /// for the chosen one; the others built with `ridges`, uncorrected as the folds scored them).
    fn price_structures(
        &self,
        chosen: &structure::Chosen,
        reduced: &Reduced,
        ridges: structure::Ridges,
    ) -> Result<(), TrainError> {
        let (set, options) = (self.set, self.options);
        for c in &chosen.candidates {
            let built = match c.structure == chosen.structure {
                true => None,
                false => Some(
                    structure::build(
                        set,
                        self.feats,
                        self.ssd,
                        None,
                        &c.structure,
                        options,
                        Some(ridges),
                    )
                    .0,
                ),
            };
            let model = built.as_ref().unwrap_or(reduced);
            self.ledger.point(budget::Point {
                stage: "structure",
                kind: "joint-blend",
                proxies: model.proxies,
                ee: budget::ee_of_score(c.score),
                priced: Priced::of(&model.to_runtime(set, c.structure.influences)?),
            });
        }
        Ok(())
    }

    /// The joint-blend structure `chosen` (built: `reduced`, `fitted`), or, where its model is
    /// over the cost budget, the cross-validation's choice among the cheaper candidates (fewer
    /// proxies), and below the cheapest half its proxies, until one is within the budget (or
    /// one proxy is left).
    fn within_budget(
        &self,
        mut chosen: structure::Chosen,
        mut reduced: Reduced,
        mut fitted: Option<structure::JointBlendFit>,
    ) -> Result<(Reduced, Option<structure::JointBlendFit>, structure::Chosen), TrainError> {
        let (set, options) = (self.set, self.options);
        let budget = &options.budget;
        let ridges = fitted.as_ref().map(structure::JointBlendFit::ridges);
        loop {
            let k = chosen.structure.influences;
            let priced = Priced::of(&reduced.to_runtime(set, k)?);
            // The proxies built, which a pool smaller than the P asked caps.
            let p = reduced.proxies.min(chosen.structure.proxies);
            if budget.admits(&priced) || p <= 1 {
                return Ok((reduced, fitted, chosen));
            }
            let at = (chosen.candidates.iter()).position(|c| c.structure == chosen.structure);
            let (next, ee) = match at {
                Some(i) if i > 0 => {
                    let among = Validated::of(chosen.relative[..i].to_vec(), structure::TOLERANCE);
                    let ee = |j: usize| budget::ee_of_score(chosen.candidates[j].score);
                    (
                        chosen.candidates[among.chosen].structure,
                        Some((ee(i), ee(among.chosen))),
                    )
                }
                _ => {
                    let fewer = structure::Structure {
                        proxies: p / 2,
                        ..chosen.structure
                    };
                    (fewer, None)
                }
            };
            let what = format!("{p} joint-blend proxies");
            self.ledger.refuse(budget, what, priced, ee);
            (reduced, fitted) =
                structure::build(set, self.feats, self.ssd, None, &next, options, ridges);
            chosen.structure = next;
            chosen.why = structure::Why::Budget;
        }
    }

    /// With `--proxy-correctives`, their stage: fitted to `reduced`'s proxies (or `searched`,
    /// their fit already made on them) and added to `model` where their cross-validation kept
    /// any.
    fn add_proxy_correctives(
        &self,
        reduced: &Reduced,
        model: rrskin::Model,
        searched: Option<proxy_corrective::Fit>,
        clock: &mut Clock,
    ) -> Result<(rrskin::Model, Option<proxy_corrective::Fit>), TrainError> {
        if !self.options.proxy_correctives {
            return Ok((model, None));
        }
        self.progress.stage("proxy correctives")?;
        let (set, feats, train) = (self.set, self.feats, self.train);
        let mut fit = searched.unwrap_or_else(|| {
            proxy_corrective::fit(
                set,
                feats,
                self.ssd,
                self.rigid,
                reduced,
                train,
                self.options,
            )
        });
        let (budget, what) = (&self.options.budget, format!("{} proxies", reduced.proxies));
        let (model, _) = fit.apply_within(model, budget, self.ledger, &what)?;
        clock.lap("proxy correctives");
        self.progress.step();
        Ok((model, Some(fit)))
    }

    /// Whether `model` is within the cost budget; if not, notes it as refused, as `what`, with
    /// its and the kept model's cross-validated EE (`ee`).
    fn admitted(&self, model: &rrskin::Model, what: String, ee: Option<(f64, f64)>) -> bool {
        let (budget, priced) = (&self.options.budget, Priced::of(model));
        let admitted = budget.admits(&priced);
        if !admitted {
            self.ledger.refuse(budget, what, priced, ee);
        }
        admitted
    }

    /// With `--correctives N`, their stage: fitted to what `model` leaves on the training poses
    /// and added to it where their cross-validation kept any.
    fn add_correctives(
        &self,
        mut model: rrskin::Model,
        clock: &mut Clock,
    ) -> Result<(rrskin::Model, Option<corrective::Fit>), TrainError> {
        let options = self.options;
        if options.correctives == 0 {
            return Ok((model, None));
        }
        self.progress.stage("correctives")?;
        let residuals = corrective::Residuals::of(self.set, self.feats, &model, self.train)?;
        let mut fit = corrective::fit(
            self.set,
            self.ssd,
            self.rigid,
            self.train,
            &residuals,
            options.correctives,
            options.folds,
        );
        if let Some(c) = &fit.correctives {
            let corrected = rrskin::Model::new(rrskin::ModelParts {
                correctives: Some(c.to_runtime()),
                ..model.parts().clone()
            })?;
            let (without, ee) = fit.ee();
            let what = format!("{} pose-space corrective targets", c.targets.len());
            match self.admitted(&corrected, what, ee.map(|ee| (ee, without))) {
                true => model = corrected,
                false => (fit.ridge, fit.correctives) = (None, None),
            }
        }
        clock.lap("correctives");
        self.progress.step();
        Ok((model, Some(fit)))
    }
}
