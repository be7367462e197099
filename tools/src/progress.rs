//! Progress of long work: a bar on a terminal (indicatif), a line per stage when stderr is a
//! log (CI, a pipe), nothing under `--json`; and for a caller in the same process (the Python
//! package) an [`Observer`], told of each stage and step, that may stop the work.

use indicatif::{ProgressBar, ProgressStyle};
use std::fmt;
use std::io::{IsTerminal, Write};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;

/// Where long work stands, as an [`Observer`] is told it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Update<'a> {
    /// The work ("training").
    pub label: &'static str,
    /// Its stage now ("structure").
    pub stage: &'a str,
    /// Steps done, of `total`.
    pub done: usize,
    pub total: usize,
}

/// Watches long work from the same process: called at each stage and step; returning false
/// stops the work at its next stage ([`Interrupted`]). None: no one watches.
#[derive(Clone, Default)]
pub struct Observer(Option<Arc<Watch>>);

/// What an [`Observer`] calls: true to go on.
type Watch = dyn Fn(Update) -> bool + Send + Sync;

impl Observer {
    pub fn new(watch: impl Fn(Update) -> bool + Send + Sync + 'static) -> Observer {
        Observer(Some(Arc::new(watch)))
    }

    fn tell(&self, update: Update) -> bool {
        self.0.as_ref().is_none_or(|watch| watch(update))
    }
}

impl fmt::Debug for Observer {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(if self.0.is_some() {
            "Observer(watched)"
        } else {
            "Observer(none)"
        })
    }
}

/// Options that differ only in who watches are the same options.
impl PartialEq for Observer {
    fn eq(&self, _: &Observer) -> bool {
        true
    }
}

/// The [`Observer`] stopped the work.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Interrupted;

/// A line on stderr. A closed pipe (`rrskin train … 2>&1 | head`) drops it instead of
/// panicking as `eprintln!` does.
pub fn note(line: impl std::fmt::Display) {
    let _ = writeln!(std::io::stderr(), "{line}");
}

pub struct Progress {
    label: &'static str,
    mode: Mode,
    observer: Observer,
    total: usize,
    done: AtomicUsize,
}

enum Mode {
    Bar(ProgressBar),
    Log,
    Quiet,
}

impl Progress {
    /// `total` steps of work; `quiet` silences it whatever stderr is.
    pub fn new(label: &'static str, total: usize, quiet: bool) -> Progress {
        let mode = match (quiet, std::io::stderr().is_terminal()) {
            (true, _) => Mode::Quiet,
            (false, false) => Mode::Log,
            (false, true) => {
                let bar = ProgressBar::new(total as u64);
                if let Ok(style) = ProgressStyle::with_template(
                    "{prefix} [{bar:30}] {pos}/{len} {msg} ({elapsed})",
                ) {
                    bar.set_style(style.progress_chars("#>-"));
                }
                bar.set_prefix(label);
                Mode::Bar(bar)
            }
        };
        Progress {
            label,
            mode,
            observer: Observer::default(),
            total,
            done: AtomicUsize::new(0),
        }
    }

    /// Also tells `observer`.
    pub fn observed(self, observer: Observer) -> Progress {
        Progress { observer, ..self }
    }

    /// A new stage begins, unless the observer stops the work here.
    pub fn stage(&self, name: &str) -> Result<(), Interrupted> {
        match &self.mode {
            Mode::Bar(bar) => bar.set_message(name.to_string()),
            Mode::Log => note(format_args!("{}: {name}", self.label)),
            Mode::Quiet => {}
        }
        let update = Update {
            label: self.label,
            stage: name,
            done: self.done.load(Ordering::Relaxed),
            total: self.total,
        };
        match self.observer.tell(update) {
            true => Ok(()),
            false => Err(Interrupted),
        }
    }

    /// One step of the total is done.
    pub fn step(&self) {
        self.done.fetch_add(1, Ordering::Relaxed);
        if let Mode::Bar(bar) = &self.mode {
            bar.inc(1);
        }
    }

    pub fn finish(&self) {
        if let Mode::Bar(bar) = &self.mode {
            bar.finish_and_clear();
        }
    }
}
