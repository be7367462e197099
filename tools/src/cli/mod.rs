//! The `rrskin` commands, a file each: its arguments, one library call, and the printing of
//! what the call returns (docs/cli.md is the contract).

pub mod bench;
pub mod demo;
pub mod device;
pub mod eval;
pub mod export;
pub mod info;
pub mod profile;
pub mod reference;
pub mod synth;
pub mod train;
pub mod train_options;

pub use rrskin_tools::progress::note;

pub type Outcome = Result<(), Box<dyn std::error::Error>>;

/// A count that must be at least 1 (`--frames 0` would measure nothing).
pub fn at_least_one(text: &str) -> Result<usize, String> {
    match text.parse::<usize>() {
        Ok(n) if n >= 1 => Ok(n),
        _ => Err(format!(
            "expected a whole number of at least 1, got '{text}'"
        )),
    }
}

/// "1 character", "2 characters".
pub fn count(n: usize, noun: &str) -> String {
    format!("{n} {noun}{}", if n == 1 { "" } else { "s" })
}
