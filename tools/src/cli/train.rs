//! `rrskin train SET -o MODEL.rrs`: the runtime model, trained and written, scored against SSD
//! without the baselines `eval` adds.

use super::train_options::{load_for_training, SetArgs, TrainArgs};
use super::{note, Outcome};
use rrskin_tools::eval::{Options, Report};
use rrskin_tools::import::tangents::Source;
use rrskin_tools::output::check_writable;
use rrskin_tools::train::TrainOptions;
use std::path::{Path, PathBuf};

#[derive(clap::Args)]
pub struct TrainCommandArgs {
    #[command(flatten)]
    pub set: SetArgs,
    #[command(flatten)]
    pub train: TrainArgs,
    #[arg(short, long)]
    pub output: PathBuf,
    /// Also report the learning curve: the runtime model's held-out error at fractions of the
    /// training poses, and whether more poses would help (k x 4 more trainings).
    #[arg(long)]
    pub learning_curve: bool,
}

pub fn run(args: &TrainCommandArgs) -> Outcome {
    let (set, train, output) = (&args.set, &args.train, &args.output);
    if train.proxies == 0 {
        return Err("--proxies must be at least 1 (a model of P = 0 is plain SSD)".into());
    }
    check_writable(output.parent().unwrap_or(Path::new("")))?;
    // The runtime model only: joint-blend proxies need no full model.
    let options = TrainOptions {
        full_model: false,
        ..train.options()
    };
    let (examples, imported) = load_for_training(set, &options, false)?;
    let options = Options {
        train: options,
        skip_baselines: true,
        learning_curve: args.learning_curve,
        ..Default::default()
    };
    let report = rrskin_tools::eval::run(&examples, &options)?;
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

/// The report as a table, or with `json` one JSON object.
pub fn print_report(report: &Report, set: &SetArgs, json: bool) {
    match json {
        true => out!("{}", report.to_json()),
        false => out!("{}", report.table(&set.set.display().to_string())),
    }
}
