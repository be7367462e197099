//! Progress of long work: a bar on a terminal (indicatif), a line per stage when stderr is a
//! log (CI, a pipe), nothing under `--json`.

use indicatif::{ProgressBar, ProgressStyle};
use std::io::{IsTerminal, Write};

/// A line on stderr. A closed pipe (`rrskin train … 2>&1 | head`) drops it instead of
/// panicking as `eprintln!` does.
pub fn note(line: impl std::fmt::Display) {
    let _ = writeln!(std::io::stderr(), "{line}");
}

pub struct Progress {
    label: &'static str,
    mode: Mode,
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
        Progress { label, mode }
    }

    /// A new stage begins.
    pub fn stage(&self, name: &str) {
        match &self.mode {
            Mode::Bar(bar) => bar.set_message(name.to_string()),
            Mode::Log => note(format_args!("{}: {name}", self.label)),
            Mode::Quiet => {}
        }
    }

    /// One step of the total is done.
    pub fn step(&self) {
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
