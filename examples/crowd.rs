//! The crowd sample: C characters of a trained model in a grid, each playing the model's
//! animation at its own phase, all deformed in one command buffer by the runtime and drawn
//! straight from its output buffers (no copy back to the CPU), lit with the computed normals.
//!
//!     cargo run --release --example crowd -- MODEL.rrs --headless --out crowd.png [--characters 256] [--frames 30] [--lbs]
//!
//! `--lbs` shows the model's plain linear-blend-skinning baseline instead of rotational
//! regression. Prints the median GPU time of each pass. This version renders offscreen only
//! (works on lavapipe); the window mode is not built yet.

use rrskin::vk::render::{grid_scene, Renderer};
use rrskin::vk::{Batch, Context, ContextDesc, Crowd, GpuModel, PassTimings};
use rrskin::Model;

struct Args {
    model: String,
    out: String,
    characters: usize,
    frames: usize,
    lbs: bool,
}

fn parse() -> Result<Args, String> {
    let mut it = std::env::args().skip(1);
    let (mut model, mut out, mut characters, mut frames, mut lbs, mut headless) =
        (None, None, 256, 30, false, false);
    while let Some(a) = it.next() {
        let mut value = |name: &str| it.next().ok_or(format!("{name} needs a value"));
        match a.as_str() {
            "--out" => out = Some(value("--out")?),
            "--characters" => {
                characters = value("--characters")?
                    .parse()
                    .map_err(|e| format!("--characters: {e}"))?
            }
            "--frames" => {
                frames = value("--frames")?
                    .parse()
                    .map_err(|e| format!("--frames: {e}"))?
            }
            "--lbs" => lbs = true,
            "--headless" => headless = true,
            _ if a.starts_with("--") => return Err(format!("unknown flag {a}")),
            _ => model = Some(a),
        }
    }
    if !headless {
        return Err("this version renders offscreen only: pass --headless --out FILE.png".into());
    }
    let model = model.ok_or(
        "usage: crowd MODEL.rrs --headless --out crowd.png [--characters N] [--frames F] [--lbs]",
    )?;
    if characters == 0 || frames == 0 {
        return Err("--characters and --frames must be at least 1".into());
    }
    Ok(Args {
        model,
        out: out.unwrap_or_else(|| "crowd.png".into()),
        characters,
        frames,
        lbs,
    })
}

fn main() {
    if let Err(e) = run() {
        eprintln!("crowd: {e}");
        std::process::exit(1);
    }
}

fn run() -> Result<(), Box<dyn std::error::Error>> {
    let args = parse()?;
    let trained = Model::load(&args.model)?;
    let animation: Vec<&[rrskin::predict::Affine]> = trained.animation().collect();
    if animation.is_empty() {
        return Err(format!(
            "{} carries no animation (train it with `rrskin train`)",
            args.model
        )
        .into());
    }
    let model = if args.lbs {
        trained.baseline().ok_or("the model has no SSD baseline")?
    } else {
        trained.clone()
    };
    let ctx = Context::headless(&ContextDesc::default())?;
    let mut crowd = Crowd::new(&GpuModel::new(&ctx, &model)?, args.characters)?;
    let mut batch = Batch::new(&ctx)?;
    let (width, height) = (1280, 720);
    let mut renderer = Renderer::new(&ctx, width, height)?;

    let scene = grid_scene(&model, args.characters, width as f32 / height as f32);
    let mut samples = Vec::with_capacity(args.frames);
    let mut image = Vec::new();
    for frame in 0..args.frames {
        let bones: Vec<rrskin::predict::Affine> = (0..args.characters)
            .flat_map(|c| animation[(frame + c * 7) % animation.len()].iter().copied())
            .collect();
        crowd.set_bones(&bones)?;
        batch.run(&[&crowd])?;
        samples.push(batch.timings()?);
        if frame + 1 == args.frames {
            let draws = scene.draws(&crowd);
            image = renderer.render(&scene.camera, &draws, &[], [0.09, 0.1, 0.12])?;
        }
    }
    let (median, _) = PassTimings::median(&samples).ok_or("no frames")?;
    println!(
        "{}: {} characters x {} vertices ({}), median over {} frames: predictors {:.3} ms, C1/C2 {:.3} ms, skinning {:.3} ms, normals {:.3} ms",
        ctx.device_name(),
        args.characters,
        model.vertex_count(),
        if args.lbs { "linear blend skinning" } else { "rotational regression" },
        args.frames,
        median.predict_ms,
        median.blend_ms,
        median.skin_ms,
        median.normals_ms,
    );
    let file = std::fs::File::create(&args.out).map_err(|e| format!("{}: {e}", args.out))?;
    let mut encoder = png::Encoder::new(std::io::BufWriter::new(file), width, height);
    encoder.set_color(png::ColorType::Rgba);
    encoder.set_depth(png::BitDepth::Eight);
    encoder.write_header()?.write_image_data(&image)?;
    println!("wrote {}", args.out);
    Ok(())
}
