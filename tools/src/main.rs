//! The `rrskin` command line (its contract: docs/cli.md): arguments in, one library call per
//! command ([`cli`], a file each), the result printed.

use clap::{Parser, Subcommand};
use std::process::ExitCode;

/// Prints to stdout; a closed pipe (`rrskin eval … | head`) ends output quietly, not in a panic.
macro_rules! out {
    ($($arg:tt)*) => {{
        use std::io::Write;
        let _ = writeln!(std::io::stdout(), $($arg)*);
    }};
}

mod cli;

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
    Export(cli::export::ExportArgs),
    /// The main job on the bundled example: train, print the error table, write the model and
    /// render a comparison image and a crowd image.
    Demo(cli::demo::DemoArgs),
    /// Train every method on the training poses of SET and report the enveloping error.
    Eval(cli::eval::EvalArgs),
    /// Train the runtime model on the training poses of SET and write it.
    Train(cli::train::TrainCommandArgs),
    /// Print a model file's dimensions (validates it fully).
    Info(cli::info::InfoArgs),
    /// Write a synthetic model (random, valid, untrained) of chosen size, for profiling.
    Synth(cli::synth::SynthArgs),
    /// Rotational regression against plain SSD skinning of the same mesh: GPU time per frame.
    Bench(cli::bench::BenchArgs),
    /// Per-pass GPU time (timestamp queries) of a crowd of the model's characters.
    Profile(cli::device::RunArgs),
    /// Write a crowd's bone transforms and the CPU evaluator's positions for them
    /// (DIR/poses.bin, DIR/expected.bin, little-endian f32): the inputs of examples/c/crowd.c.
    Reference(cli::reference::ReferenceArgs),
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
    let outcome = match &cli.command {
        Command::Export(args) => cli::export::run(args),
        Command::Demo(args) => cli::demo::run(args),
        Command::Eval(args) => cli::eval::run(args),
        Command::Train(args) => cli::train::run(args),
        Command::Info(args) => cli::info::run(args),
        Command::Synth(args) => cli::synth::run(args),
        Command::Bench(args) => cli::bench::run(args),
        Command::Profile(args) => cli::profile::run(args),
        Command::Reference(args) => cli::reference::run(args),
    };
    match outcome {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            cli::note(format_args!("rrskin: {e}"));
            ExitCode::FAILURE
        }
    }
}
