//! `rrskin info MODEL.rrs`: a model file's dimensions.

use super::Outcome;
use rrskin::Model;
use std::path::PathBuf;

#[derive(clap::Args)]
pub struct InfoArgs {
    pub model: PathBuf,
    #[arg(long)]
    pub json: bool,
}

/// `rrskin info`: a model file's dimensions.
pub fn run(args: &InfoArgs) -> Outcome {
    let (model, json) = (&args.model, args.json);
    let m = Model::load(model)?;
    let clamped = m.proxy_correctives().is_some_and(|c| !c.ranges.is_empty());
    if json {
        let dims = rrskin_tools::run::info::to_json(&m);
        out!("{dims}");
    } else {
        out!(
            "{}: V = {} vertices, T = {} triangles, J = {} bones, P = {} proxies ({} delta-mush keys), K = {} influences{}; {}; {} pose-space correctives; {} corrected proxies{}{}",
            model.display(),
            m.vertex_count(),
            m.triangle_count(),
            m.bone_count(),
            m.proxy_count(),
            m.keys_of(rrskin::KeyKind::DeltaMush),
            m.influences(),
            if m.proxy_count() == 0 { " (plain linear blend skinning)" } else { "" },
            if m.has_tangents() { "rest tangents" } else { "no rest tangents" },
            m.corrective_count(),
            m.proxy_corrective_count(),
            match m.up() {
                Some([x, y, z]) => format!(", seeing gravity (the model's up {x}, {y}, {z})"),
                None => String::new(),
            },
            if clamped { ", features clamped to the training range" } else { "" },
        );
        out!("{}", rrskin_tools::eval::cost::line(&m));
    }
    Ok(())
}
