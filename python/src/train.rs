//! `rrskin.train` and `rrskin.evaluate`: `rrskin train` and `rrskin eval` in the same process,
//! with the CLI's options by name, a progress callback and Ctrl-C.

use crate::model::Model;
use crate::set::ExampleSet;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use rrskin_tools::eval::{Options, Report};
use rrskin_tools::progress::{Observer, Update};
use rrskin_tools::train::budget::is_limit;
use rrskin_tools::train::{unit_up, TrainError, TrainOptions};
use std::sync::{Arc, Mutex};

/// The option names `train` and `evaluate` take: the CLI's flags (`--palette-budget` is
/// `palette_budget`; each `--no-…` flag a boolean of the positive name).
const OPTIONS: [&str; 13] = [
    "proxies",
    "influences",
    "reduction",
    "epsilon",
    "correctives",
    "proxy_correctives",
    "proxy_kernels",
    "up",
    "delta_mush",
    "budget",
    "palette_budget",
    "folds",
    "gentle_poses",
];

/// `options` (name: value, the CLI's flags by [`OPTIONS`]) over the CLI's defaults; an
/// unknown name, or a value of the wrong kind, is refused naming it.
fn train_options(options: &Bound<'_, PyDict>) -> PyResult<TrainOptions> {
    let mut o = TrainOptions {
        quiet: true,
        ..TrainOptions::default()
    };
    for (key, value) in options.iter() {
        let name: String = key.extract()?;
        let bad = |e: PyErr| crate::error(format!("{name}: {e}"));
        let positive = |v: Option<f64>| match v {
            Some(x) if !is_limit(x) => Err(crate::error(format!(
                "{name}: {x}, expected a positive number (or None: no limit)"
            ))),
            _ => Ok(v),
        };
        match name.as_str() {
            "proxies" => o.proxies = value.extract().map_err(bad)?,
            "influences" => o.influences = value.extract().map_err(bad)?,
            "reduction" => {
                let text: String = value.extract().map_err(bad)?;
                o.method = text
                    .parse()
                    .map_err(|e| crate::error(format!("{name}: {e}")))?;
            }
            "epsilon" => o.epsilon = positive(value.extract().map_err(bad)?)?,
            "correctives" => o.correctives = value.extract().map_err(bad)?,
            "proxy_correctives" => o.proxy_correctives = value.extract().map_err(bad)?,
            "proxy_kernels" => o.proxy_kernels = value.extract().map_err(bad)?,
            "up" => o.up = unit(&name, value.extract().map_err(bad)?)?,
            "delta_mush" => o.delta_mush = value.extract().map_err(bad)?,
            "budget" => o.budget.frame = positive(value.extract().map_err(bad)?)?,
            "palette_budget" => o.budget.palette_us = positive(value.extract().map_err(bad)?)?,
            "folds" => o.folds = value.extract().map_err(bad)?,
            "gentle_poses" => {
                let gentle: bool = value.extract().map_err(bad)?;
                o.gentle_scales = match gentle {
                    true => TrainOptions::default().gentle_scales,
                    false => Vec::new(),
                };
            }
            _ => {
                return Err(crate::error(format!(
                    "{name}: not an option (the options are {})",
                    OPTIONS.join(", ")
                )))
            }
        }
    }
    Ok(o)
}

/// `up` normalised (None: no gravity); a zero or non-finite vector refused.
fn unit(name: &str, up: Option<[f64; 3]>) -> PyResult<Option<[f64; 3]>> {
    let Some(u) = up else { return Ok(None) };
    let unit = unit_up(u)
        .ok_or_else(|| crate::error(format!("{name}: {u:?}, expected a non-zero vector")))?;
    Ok(Some(unit))
}

/// The caller's `progress(label, stage, done, total)` and Ctrl-C, watching training: the first
/// exception either raises stops it at its next stage, and is kept to raise again.
struct Watch {
    stopped: Arc<Mutex<Option<PyErr>>>,
}

impl Watch {
    fn observer(progress: Option<Py<PyAny>>) -> (Watch, Observer) {
        let stopped = Arc::new(Mutex::new(None));
        let keep = Arc::clone(&stopped);
        let observer = Observer::new(move |u: Update| {
            Python::attach(|py| {
                let told = py.check_signals().and_then(|()| match &progress {
                    Some(f) => f.call1(py, (u.label, u.stage, u.done, u.total)).map(drop),
                    None => Ok(()),
                });
                let Err(e) = told else { return true };
                let mut slot = keep.lock().unwrap_or_else(|p| p.into_inner());
                slot.get_or_insert(e);
                false
            })
        });
        (Watch { stopped }, observer)
    }

    /// `result`'s error as Python's: the watcher's exception where it stopped training.
    fn raise<T>(self, result: rrskin_tools::Result<T>) -> PyResult<T> {
        result.map_err(|e| {
            let stopped = self
                .stopped
                .lock()
                .unwrap_or_else(|p| p.into_inner())
                .take();
            match (&e, stopped) {
                (
                    rrskin_tools::Error::Train {
                        source: TrainError::Interrupted,
                    },
                    Some(raised),
                ) => raised,
                _ => crate::error(e),
            }
        })
    }
}

/// Runs `rrskin eval` (or with `train_only`, what `rrskin train` runs) on `set`.
fn run(
    py: Python<'_>,
    set: &ExampleSet,
    options: &Bound<'_, PyDict>,
    progress: Option<Py<PyAny>>,
    eval: Options,
) -> PyResult<Report> {
    let mut train = train_options(options)?;
    let (watch, observer) = Watch::observer(progress);
    train.observer = observer;
    train.full_model = train.full_model && !eval.skip_baselines;
    let set = set.set();
    let warnings = train.check(set).map_err(crate::error)?;
    let warn = py.import("warnings")?;
    for w in warnings {
        warn.call_method1("warn", (w,))?;
    }
    let eval = Options { train, ..eval };
    let result = py.detach(|| rrskin_tools::eval::run(set, &eval));
    watch.raise(result)
}

/// Trains the runtime model of `example_set` on its training poses, as `rrskin train` does,
/// with the CLI's options by name: `proxies` (60), `influences` (4), `reduction` ("auto",
/// "joint-blend", "paper", "delta-mush" or "both"), `budget` (1.25: the frame as a multiple
/// of the engine's own skinning; None: no limit), `palette_budget` (µs a character; None),
/// `correctives` (0), `proxy_correctives` (True), `proxy_kernels` (False), `up` ((0, 1, 0);
/// None: no gravity), `delta_mush` (True), `folds` (4), `epsilon` (None), `gentle_poses`
/// (True); and `learning_curve` (False). `progress(label, stage, done, total)` is called at
/// each stage. The GIL is released while it trains; Ctrl-C or an exception from `progress`
/// stops it at the next stage and is raised. The model's `report` is what it measured.
#[pyfunction]
#[pyo3(signature = (example_set, *, progress=None, learning_curve=false, **options))]
pub fn train(
    py: Python<'_>,
    example_set: &Bound<'_, ExampleSet>,
    progress: Option<Py<PyAny>>,
    learning_curve: bool,
    options: Option<&Bound<'_, PyDict>>,
) -> PyResult<Model> {
    let empty = PyDict::new(py);
    let eval = Options {
        skip_baselines: true,
        learning_curve,
        ..Default::default()
    };
    let set = example_set.get();
    let report = run(py, set, options.unwrap_or(&empty), progress, eval)?;
    let json = report.to_json();
    let model = report
        .model
        .ok_or_else(|| crate::error("training produced no model"))?;
    Model::new(model, Some(json))
}

/// Trains every method on `example_set`'s training poses and scores them, as `rrskin eval`
/// does: its JSON object as a dict (the held-out error of the runtime model, SSD, DQS, CoR and
/// DDM, the accuracy/cost front, the learning curve). The options are `train`'s, and `loocv`
/// and `diagnose` are eval's flags.
#[pyfunction]
#[pyo3(signature = (example_set, *, progress=None, loocv=false, diagnose=false, learning_curve=true, **options))]
pub fn evaluate<'py>(
    py: Python<'py>,
    example_set: &Bound<'py, ExampleSet>,
    progress: Option<Py<PyAny>>,
    loocv: bool,
    diagnose: bool,
    learning_curve: bool,
    options: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyAny>> {
    let empty = PyDict::new(py);
    let eval = Options {
        loocv,
        diagnose,
        learning_curve,
        ..Default::default()
    };
    let report = run(
        py,
        example_set.get(),
        options.unwrap_or(&empty),
        progress,
        eval,
    )?;
    crate::to_python(py, &report.to_json())
}
