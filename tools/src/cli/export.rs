//! `rrskin export MODEL.rrs -o OUT.glb`: the model as a skinned glTF.

use super::{note, Outcome};
use rrskin_tools::output::{check_writable, shown};
use std::path::{Path, PathBuf};

#[derive(clap::Args)]
pub struct ExportArgs {
    pub model: PathBuf,
    /// The .glb to write.
    #[arg(short, long)]
    pub output: PathBuf,
    /// The glTF rig the model was trained from: its mesh, materials, joint names and clips.
    #[arg(long)]
    pub rig: Option<PathBuf>,
    /// A clip of the rig to bake (repeatable; default: every named clip).
    #[arg(long = "clip")]
    pub clips: Vec<String>,
    /// Frames a second of the model's own animation (without --rig).
    #[arg(long, default_value_t = 30.0)]
    pub fps: f64,
    /// Largest vertex distance allowed between the played file and the model, as a fraction
    /// of the rest mesh's bounding-box diagonal.
    #[arg(long, default_value_t = rrskin_tools::export::TOLERANCE)]
    pub tolerance: f64,
    /// One JSON object on stdout.
    #[arg(long)]
    pub json: bool,
}

/// `rrskin export`: the model as a skinned glTF.
pub fn run(args: &ExportArgs) -> Outcome {
    check_writable(args.output.parent().unwrap_or(Path::new("")))?;
    let model = rrskin::Model::load(&args.model)?;
    let e = rrskin_tools::export::run(
        model,
        &rrskin_tools::export::Options {
            output: args.output.clone(),
            rig: args.rig.clone(),
            clips: args.clips.clone(),
            fps: args.fps,
            tolerance: args.tolerance,
        },
    )?;
    for line in &e.notes {
        note(format_args!("note: {}: {line}", shown(&e.output)));
    }
    if args.json {
        out!("{}", e.to_json());
        return Ok(());
    }
    out!(
        "{}: {} vertices skinned by {} palette joints",
        shown(&e.output),
        e.vertices,
        e.joints
    );
    for c in &e.clips {
        out!(
            "  clip '{}': {} keys baked into {} samples; played vs the model: {:.2e} at the samples, {:.2e} between them (of the mesh's size)",
            c.name,
            c.keys,
            c.samples,
            c.worst_at_samples,
            c.worst_between
        );
    }
    Ok(())
}
