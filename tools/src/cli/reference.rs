//! `rrskin reference MODEL.rrs`: the inputs and expected outputs of examples/c/crowd.c.

use super::{at_least_one, count, note, Outcome};
use rrskin::Model;
use std::path::PathBuf;

#[derive(clap::Args)]
pub struct ReferenceArgs {
    pub model: PathBuf,
    #[arg(long, default_value_t = 3, value_parser = at_least_one)]
    pub frames: usize,
    #[arg(long, default_value_t = 64, value_parser = at_least_one)]
    pub characters: usize,
    #[arg(long)]
    pub out: PathBuf,
}

/// `rrskin reference`: the inputs and expected outputs of examples/c/crowd.c.
pub fn run(args: &ReferenceArgs) -> Outcome {
    let (model, frames, characters, out) = (&args.model, args.frames, args.characters, &args.out);
    let m = Model::load(model)?;
    let written = rrskin_tools::run::reference::write(&m, frames, characters, out)?;
    let names: Vec<String> = written.iter().map(|p| p.display().to_string()).collect();
    note(format_args!(
        "wrote {} ({} x {} of {}: J = {}, V = {})",
        names.join(", "),
        count(frames, "frame"),
        count(characters, "character"),
        model.display(),
        m.bone_count(),
        m.vertex_count()
    ));
    Ok(())
}
