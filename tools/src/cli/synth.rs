//! `rrskin synth`: a random, valid, untrained model for profiling.

use super::{note, Outcome};
use rrskin_render::synthetic::{random_model, renumber_bones, Spec};
use std::path::PathBuf;

/// The sizes and seed of `rrskin synth`'s model.
#[derive(clap::Args)]
pub struct SynthArgs {
    /// Vertices = grid x grid.
    #[arg(long, default_value_t = 48)]
    pub grid: usize,
    #[arg(long, default_value_t = 19)]
    pub bones: usize,
    /// Proxy bones / key predictors (0: plain linear blend skinning).
    #[arg(long, default_value_t = 60)]
    pub proxies: usize,
    /// Influences per vertex: 4 or 8.
    #[arg(long, default_value_t = 4)]
    pub influences: u32,
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// List every bone after its children (bones renumbered J−1, …, 0), as many glTF skins
    /// order their joints.
    #[arg(long)]
    pub children_first: bool,
    #[arg(short, long)]
    pub output: PathBuf,
}

/// `rrskin synth`: a random valid model of the chosen sizes.
pub fn run(args: &SynthArgs) -> Outcome {
    let spec = Spec {
        grid: args.grid,
        bones: args.bones,
        proxies: args.proxies,
        influences: args.influences,
    };
    let mut m = random_model(spec, args.seed)?;
    if args.children_first {
        let reversed: Vec<usize> = (0..m.bone_count()).rev().collect();
        m = renumber_bones(&m, &reversed)?;
    }
    m.save(&args.output)?;
    note(format_args!(
        "wrote {} ({} vertices)",
        args.output.display(),
        m.vertex_count()
    ));
    Ok(())
}
