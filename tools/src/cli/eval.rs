//! `rrskin eval SET`: every method trained on the training poses, and their enveloping error.

use super::train_options::{load_for_training, SetArgs, TrainArgs};
use super::Outcome;
use rrskin::Model;
use rrskin_tools::eval::Options;
use std::path::PathBuf;

#[derive(clap::Args)]
pub struct EvalArgs {
    #[command(flatten)]
    pub set: SetArgs,
    #[command(flatten)]
    pub train: TrainArgs,
    /// Report leave-one-out error over the training poses as the test error.
    #[arg(long)]
    pub loocv: bool,
    /// Also print the error budget: oracle ceilings of the full and the runtime model.
    #[arg(long)]
    pub diagnose: bool,
    /// Evaluate this trained model (runtime CPU evaluator) as rr_reduced.
    #[arg(long)]
    pub model: Option<PathBuf>,
    /// Leave out the learning curve (the runtime model retrained at fractions of the training
    /// poses in every fold: k x 4 trainings, most of eval's time on a large rig).
    #[arg(long)]
    pub no_learning_curve: bool,
}

pub fn run(args: &EvalArgs) -> Outcome {
    let options = args.train.options();
    let (examples, imported) = load_for_training(&args.set, &options, args.loocv)?;
    let model = match &args.model {
        Some(path) => {
            let m = Model::load(path)?;
            // A glTF rig's model is over the file's vertices: collapsed onto the set's, or
            // refused here with the file named.
            let m = match &imported {
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
            Some((path.clone(), m))
        }
        None => None,
    };
    let options = Options {
        train: options,
        model,
        loocv: args.loocv,
        diagnose: args.diagnose,
        skip_baselines: false,
        learning_curve: !args.no_learning_curve,
    };
    let report = rrskin_tools::eval::run(&examples, &options)?;
    super::train::print_report(&report, &args.set, args.train.json);
    Ok(())
}
