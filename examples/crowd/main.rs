//! The crowd sample: C characters of a trained model in a grid, each playing the model's
//! animation at its own phase, all deformed in one command buffer by the runtime and drawn
//! straight from its output buffers (no copy back to the CPU), lit with the computed normals.
//!
//!     cargo run --release --example crowd -- MODEL.rrs [--characters 256] [--lbs] [--frames F] [--validate]
//!     cargo run --release --example crowd -- MODEL.rrs --headless [--out crowd.png] ...
//!
//! Without `--headless` it opens a window (X11 or Wayland, `window.rs`): the title shows the
//! per-pass GPU times, `L` switches between rotational regression and the model's plain
//! linear-blend-skinning baseline, `Space` pauses, `Esc` quits. `--headless` renders offscreen
//! (works on lavapipe without a display) and writes the last frame to `--out`. Both print the
//! median GPU time of each pass per method at the end; `--lbs` starts with the baseline;
//! `--frames` stops after that many frames (headless default 30); `--validate` turns on the
//! validation layer and fails if it reports anything.

mod swapchain;
mod window;

use rrskin::vk::{Batch, Context, ContextDesc, Crowd, CrowdOptions, GpuModel, PassTimings};
use rrskin::Model;
use rrskin_render::{phased_poses, CROWD_BACKGROUND};

type Error = Box<dyn std::error::Error>;

pub struct Args {
    model: String,
    headless: bool,
    out: String,
    characters: usize,
    frames: Option<usize>,
    lbs: bool,
    validate: bool,
}

const USAGE: &str = "usage: crowd MODEL.rrs [--headless [--out crowd.png]] [--characters N] \
                     [--frames F] [--lbs] [--validate]";

fn parse() -> Result<Args, String> {
    let mut it = std::env::args().skip(1);
    let mut args = Args {
        model: String::new(),
        headless: false,
        out: "crowd.png".into(),
        characters: 256,
        frames: None,
        lbs: false,
        validate: false,
    };
    let count = |name: &str, value: Option<String>| -> Result<usize, String> {
        let value = value.ok_or(format!("{name} needs a value"))?;
        match value.parse() {
            Ok(n) if n > 0 => Ok(n),
            _ => Err(format!(
                "{name}: expected a positive integer, got '{value}'"
            )),
        }
    };
    while let Some(a) = it.next() {
        match a.as_str() {
            "--out" => args.out = it.next().ok_or("--out needs a value")?,
            "--characters" => args.characters = count("--characters", it.next())?,
            "--frames" => args.frames = Some(count("--frames", it.next())?),
            "--lbs" => args.lbs = true,
            "--headless" => args.headless = true,
            "--validate" => args.validate = true,
            _ if a.starts_with("--") => return Err(format!("unknown flag {a}\n{USAGE}")),
            _ if args.model.is_empty() => args.model = a,
            _ => return Err(format!("unexpected argument '{a}'\n{USAGE}")),
        }
    }
    if args.model.is_empty() {
        return Err(USAGE.into());
    }
    Ok(args)
}

fn main() {
    if let Err(e) = parse().map_err(Error::from).and_then(run) {
        eprintln!("crowd: {e}");
        std::process::exit(1);
    }
}

fn run(args: Args) -> Result<(), Error> {
    let model = Model::load(&args.model)?;
    if model.animation().next().is_none() {
        return Err(format!(
            "{} carries no animation (train it with `rrskin train`)",
            args.model
        )
        .into());
    }
    if args.lbs && model.baseline().is_none() {
        return Err(format!("{} has no SSD baseline for --lbs", args.model).into());
    }
    if args.headless {
        headless(&args, &model)
    } else {
        window::run(&args, &model)
    }
}

/// The crowd of each method (rotational regression, and the model's SSD baseline as plain
/// linear blend skinning when it carries one, with the same animation) on one context, and the
/// GPU timings of every frame.
pub struct Show {
    pub ctx: Context,
    pub batch: Batch,
    pub methods: Vec<Method>,
    /// Index into `methods` of the one shown.
    pub current: usize,
    characters: usize,
    validate: bool,
}

pub struct Method {
    pub name: &'static str,
    pub model: Model,
    pub crowd: Crowd,
    pub samples: Vec<PassTimings>,
}

impl Show {
    pub fn new(ctx: Context, model: &Model, args: &Args) -> Result<Show, Error> {
        let mut methods = Vec::new();
        let candidates = [
            ("rotational regression", Some(model.clone())),
            ("linear blend skinning", model.baseline()),
        ];
        for (name, m) in candidates {
            if let Some(m) = m {
                let options = CrowdOptions {
                    frames_in_flight: swapchain::FRAMES_IN_FLIGHT,
                    ..CrowdOptions::default()
                };
                let crowd =
                    Crowd::with_options(&GpuModel::new(&ctx, &m)?, args.characters, options)?;
                methods.push(Method {
                    name,
                    model: m,
                    crowd,
                    samples: Vec::new(),
                });
            }
        }
        Ok(Show {
            batch: Batch::new(&ctx)?,
            ctx,
            current: usize::from(args.lbs),
            methods,
            characters: args.characters,
            validate: args.validate,
        })
    }

    pub fn shown(&self) -> &Method {
        &self.methods[self.current]
    }

    /// Switches to the next method (no-op when the model has no baseline).
    pub fn switch(&mut self) {
        self.current = (self.current + 1) % self.methods.len();
    }

    /// Poses frame slot `slot` of the shown crowd at animation frame `frame` (`phased_poses`:
    /// neighbours out of step).
    pub fn pose(&mut self, slot: usize, frame: usize) -> rrskin::Result<()> {
        let m = &mut self.methods[self.current];
        m.crowd
            .set_bones(slot, &phased_poses(&m.model, self.characters, frame))
    }

    /// Once the last frame recorded in frame slot `slot` has completed: keep its pass timings
    /// (none before the slot's first frame).
    pub fn sample(&mut self, slot: usize) -> rrskin::Result<()> {
        match self.batch.timings(slot) {
            Ok(t) => self.methods[self.current].samples.push(t),
            Err(rrskin::Error::NotReady { .. }) => {}
            Err(e) => return Err(e),
        }
        Ok(())
    }

    /// Prints the median pass times of every method shown, and fails if validation (when on)
    /// reported anything.
    pub fn finish(&self) -> Result<(), Error> {
        for m in &self.methods {
            if let Some((median, _)) = PassTimings::median(&m.samples) {
                println!(
                    "{}: {} characters x {} vertices ({}), median over {} frames: predictors {:.3} ms, C1/C2 {:.3} ms, skinning {:.3} ms, normals {:.3} ms, total {:.3} ms",
                    self.ctx.device_name(),
                    self.characters,
                    m.model.vertex_count(),
                    m.name,
                    m.samples.len(),
                    median.predict_ms,
                    median.product_ms,
                    median.skin_ms,
                    median.normals_ms,
                    median.total_ms(),
                );
            }
        }
        let messages = self.ctx.validation_messages();
        if self.validate && !messages.is_empty() {
            return Err(format!(
                "{} validation messages:\n{}",
                messages.len(),
                messages.join("\n")
            )
            .into());
        }
        Ok(())
    }
}

/// Offscreen: `--frames` frames (30 unless given), one animation frame each; writes the last.
fn headless(args: &Args, model: &Model) -> Result<(), Error> {
    use rrskin_render::{grid_scene, Renderer};
    let ctx = Context::new(&ContextDesc {
        validation: args.validate,
        ..Default::default()
    })?;
    let mut show = Show::new(ctx, model, args)?;
    let (width, height) = (1280, 720);
    let mut renderer = Renderer::new(&show.ctx, width, height)?;
    let scene = grid_scene(model, args.characters, width as f32 / height as f32);
    let frames = args.frames.unwrap_or(30);
    let mut image = Vec::new();
    for frame in 0..frames {
        // The frame slots of the window mode, in turn (each run waits for its frame).
        let slot = frame % swapchain::FRAMES_IN_FLIGHT;
        show.pose(slot, frame)?;
        show.batch.run(slot, &[&show.methods[show.current].crowd])?;
        show.sample(slot)?;
        if frame + 1 == frames {
            let draws = scene.draws(&show.shown().crowd);
            image = renderer.render(&scene.camera, &draws, &[], CROWD_BACKGROUND)?;
        }
    }
    show.finish()?;
    let file = std::fs::File::create(&args.out).map_err(|e| format!("{}: {e}", args.out))?;
    let mut encoder = png::Encoder::new(std::io::BufWriter::new(file), width, height);
    encoder.set_color(png::ColorType::Rgba);
    encoder.set_depth(png::BitDepth::Eight);
    encoder.write_header()?.write_image_data(&image)?;
    println!("wrote {}", args.out);
    Ok(())
}
