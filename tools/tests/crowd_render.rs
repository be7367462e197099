//! The headless crowd: 256 CesiumMan characters of a trained model, each walking at its own
//! phase (the held-out walk frames), deformed in one command buffer and drawn straight from the
//! runtime's output buffers, on lavapipe with the validation layer on.

use rrskin::vk::{Batch, Context, ContextDesc, Crowd, GpuModel};
use rrskin_render::{grid_scene, Renderer};
use rrskin_tools::eval;
use rrskin_tools::set::ExampleSet;
use rrskin_tools::train::TrainOptions;

const SIDE: usize = 16;
const BACKGROUND: [f32; 3] = [0.1, 0.12, 0.15];

#[test]
fn a_crowd_of_256_renders_and_moves() {
    let set = ExampleSet::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../data/cesiumman"))
        .expect("bundled data");
    let options = eval::Options {
        train: TrainOptions {
            proxies: 20,
            quiet: true,
            ..Default::default()
        },
        ..Default::default()
    };
    let model = eval::run(&set, &options)
        .expect("training")
        .model
        .expect("a runtime model");
    let walk = set.test();
    let ctx = Context::new(&ContextDesc {
        validation: true,
        ..Default::default()
    })
    .expect("lavapipe");
    let mut crowd =
        Crowd::new(&GpuModel::new(&ctx, &model).expect("upload"), SIDE * SIDE).expect("crowd");
    let mut batch = Batch::new(&ctx).expect("batch");
    let (w, h) = (480, 270);
    let mut renderer = Renderer::new(&ctx, w, h).expect("renderer");
    let scene = grid_scene(&model, SIDE * SIDE, w as f32 / h as f32);
    let mut frames = Vec::new();
    for frame in [0usize, 3] {
        let bones: Vec<rrskin::predict::Affine> = (0..SIDE * SIDE)
            .flat_map(|c| {
                set.poses[walk[(c * 7 + frame) % walk.len()]]
                    .bones
                    .iter()
                    .map(|b| b.to_runtime())
            })
            .collect();
        crowd.set_bones(0, &bones).expect("bones");
        batch.run(0, &[&crowd]).expect("run");
        let draws = scene.draws(&crowd);
        frames.push(
            renderer
                .render(&scene.camera, &draws, &[], BACKGROUND)
                .expect("render"),
        );
    }
    if let Some(dir) = std::env::var_os("RRSKIN_SAVE_IMAGES") {
        for (n, img) in frames.iter().enumerate() {
            let path = std::path::Path::new(&dir).join(format!("crowd{n}.png"));
            rrskin_tools::run::image::write_png(&path, w, h, img).expect("png");
        }
    }
    let background = BACKGROUND.map(|x| (x * 255.0).round() as u8);
    let covered = frames[0]
        .chunks_exact(4)
        .filter(|p| (0..3).any(|i| p[i].abs_diff(background[i]) > 2))
        .count();
    let pixels = (w * h) as usize;
    assert!(
        covered > pixels / 20,
        "only {covered} of {pixels} pixels show a character"
    );
    let changed = frames[0]
        .chunks_exact(4)
        .zip(frames[1].chunks_exact(4))
        .filter(|(a, b)| a != b)
        .count();
    assert!(
        changed > pixels / 100,
        "only {changed} pixels changed between frames"
    );
    assert!(
        ctx.validation_messages().is_empty(),
        "{:?}",
        ctx.validation_messages()
    );
}
