//! Progress on a terminal, silence otherwise (pipes, `--json`).

use std::io::{IsTerminal, Write};

pub struct Progress {
    label: &'static str,
    total: usize,
    enabled: bool,
}

impl Progress {
    /// Shows progress on stderr only if it is a terminal and `quiet` is false.
    pub fn new(label: &'static str, total: usize, quiet: bool) -> Progress {
        Progress {
            label,
            total,
            enabled: !quiet && std::io::stderr().is_terminal(),
        }
    }

    pub fn set(&self, done: usize) {
        if self.enabled {
            let width = 30;
            let filled = width * done / self.total.max(1);
            eprint!(
                "\r{} [{}{}] {done}/{}",
                self.label,
                "#".repeat(filled),
                " ".repeat(width - filled),
                self.total
            );
            let _ = std::io::stderr().flush();
        }
    }

    pub fn finish(&self) {
        if self.enabled {
            eprintln!();
        }
    }
}
