//! `rrskin demo`: the main job on the bundled example. Trains every method, prints the error
//! table and the training time, writes the runtime model, and renders two images with the
//! Vulkan runtime: the held-out pose where SSD errs most, as ground truth | SSD | rotational
//! regression coloured by per-vertex error, and a crowd of 256 characters playing the model's
//! animation.

use crate::eval::{self, Report};
use crate::import::example_set::ExampleSet;
use crate::run::image::write_png;
use rrskin::vk::{Batch, Context, ContextDesc, Crowd, GpuModel};
use rrskin::Model;
use rrskin_render::{grid_scene, phased_poses, Camera, HostMesh, Renderer, CROWD_BACKGROUND};
use std::path::{Path, PathBuf};

/// Errors at or above this fraction of the mesh's height show as full red.
pub const ERROR_SCALE: f32 = 0.02;
pub const CROWD: usize = 256;

pub struct Outputs {
    pub report: Report,
    pub model: PathBuf,
    pub comparison: PathBuf,
    pub crowd: PathBuf,
    /// The pose shown in the comparison and the RMS errors there (SSD, RR), in mesh units.
    pub pose: usize,
    pub rms: (f64, f64),
}

pub fn run(set_dir: &Path, out: &Path, quiet: bool) -> Result<Outputs, Box<dyn std::error::Error>> {
    let set = ExampleSet::load(set_dir)?;
    let options = eval::Options {
        train: crate::train::TrainOptions {
            quiet,
            ..Default::default()
        },
        model: None,
        loocv: false,
        diagnose: false,
    };
    let report = eval::run(&set, &options)?;
    let model = report.model.clone().ok_or("training produced no model")?;
    std::fs::create_dir_all(out).map_err(|e| format!("{}: {e}", out.display()))?;
    let model_path = out.join("model.rrs");
    model.save(&model_path)?;

    let ctx = Context::new(&ContextDesc::default())?;
    let baseline = model
        .baseline()
        .ok_or("the trained model has no SSD baseline")?;
    let pose = worst_pose_for_ssd(&set, &baseline)?;
    let bones: Vec<rrskin::predict::Affine> = set.poses[pose]
        .bones
        .iter()
        .map(|b| b.to_affine())
        .collect();
    let (rr, ssd) = (
        deform(&ctx, &model, &bones)?,
        deform(&ctx, &baseline, &bones)?,
    );
    let truth: Vec<[f32; 3]> = set.poses[pose]
        .vertices
        .iter()
        .map(|p| p.as_vec3().to_array())
        .collect();
    let triangles: Vec<[u32; 3]> = set.faces.iter().map(|t| t.map(|a| a as u32)).collect();
    let height = set.rest.iter().map(|p| p.y).fold(f64::MIN, f64::max)
        - set.rest.iter().map(|p| p.y).fold(f64::MAX, f64::min);
    let errors = |p: &[[f32; 3]]| -> Vec<f32> {
        p.iter().zip(&truth).map(|(a, b)| distance(a, b)).collect()
    };
    let (e_ssd, e_rr) = (errors(&ssd.0), errors(&rr.0));
    let rms =
        |e: &[f32]| (e.iter().map(|x| (*x as f64).powi(2)).sum::<f64>() / e.len() as f64).sqrt();
    let scale = ERROR_SCALE * height as f32;
    let gray = vec![[0.8f32, 0.8, 0.8]; truth.len()];
    let (c_ssd, c_rr) = (heat(&e_ssd, scale), heat(&e_rr, scale));
    let truth_normals = vertex_normals(&truth, &triangles);
    let width = set.rest.iter().map(|p| p.x).fold(f64::MIN, f64::max)
        - set.rest.iter().map(|p| p.x).fold(f64::MAX, f64::min);
    let step = 1.15 * width as f32;
    let meshes = [
        HostMesh {
            positions: &truth,
            normals: &truth_normals,
            colors: &gray,
            triangles: &triangles,
            offset: [-step, 0.0, 0.0],
        },
        HostMesh {
            positions: &ssd.0,
            normals: &ssd.1,
            colors: &c_ssd,
            triangles: &triangles,
            offset: [0.0, 0.0, 0.0],
        },
        HostMesh {
            positions: &rr.0,
            normals: &rr.1,
            colors: &c_rr,
            triangles: &triangles,
            offset: [step, 0.0, 0.0],
        },
    ];
    let (w, h) = (1200, 600);
    let mut renderer = Renderer::new(&ctx, w, h)?;
    let center = glam::Vec3::new(0.0, 0.5 * height as f32, 0.0);
    let eye = center + glam::Vec3::new(0.0, 0.1 * height as f32, 2.2 * step);
    let camera = Camera::looking_at(eye, center, 0.9, w as f32 / h as f32, 0.01, 100.0);
    let image = renderer.render(&camera, &[], &meshes, [1.0, 1.0, 1.0])?;
    let comparison = out.join("comparison.png");
    write_png(&comparison, w, h, &image)?;

    let crowd_path = out.join("crowd.png");
    render_crowd(&ctx, &model, &crowd_path)?;
    Ok(Outputs {
        report,
        model: model_path,
        comparison,
        crowd: crowd_path,
        pose,
        rms: (rms(&e_ssd), rms(&e_rr)),
    })
}

/// The held-out pose (or, without any, the training pose) where SSD's total error is largest.
fn worst_pose_for_ssd(
    set: &ExampleSet,
    baseline: &Model,
) -> Result<usize, Box<dyn std::error::Error>> {
    let poses = if set.test().is_empty() {
        set.train()
    } else {
        set.test()
    };
    let mut evaluator = rrskin::cpu::CpuEvaluator::new(baseline);
    let v = set.vertex_count();
    let (mut p, mut n) = (vec![[0.0f32; 3]; v], vec![[0.0f32; 3]; v]);
    let mut worst = (f64::MIN, poses[0]);
    for &i in &poses {
        let bones: Vec<rrskin::predict::Affine> =
            set.poses[i].bones.iter().map(|b| b.to_affine()).collect();
        evaluator.evaluate(&bones, &mut p, &mut n)?;
        let e: f64 = p
            .iter()
            .zip(&set.poses[i].vertices)
            .map(|(a, b)| (glam::DVec3::from(a.map(f64::from)) - *b).length_squared())
            .sum();
        if e > worst.0 {
            worst = (e, i);
        }
    }
    Ok(worst.1)
}

/// One character of `model` posed by `bones` on the GPU: positions and normals.
#[allow(clippy::type_complexity)]
fn deform(
    ctx: &Context,
    model: &Model,
    bones: &[rrskin::predict::Affine],
) -> rrskin::Result<(Vec<[f32; 3]>, Vec<[f32; 3]>)> {
    let mut crowd = Crowd::new(&GpuModel::new(ctx, model)?, 1)?;
    crowd.set_bones(0, bones)?;
    Batch::new(ctx)?.run(0, &[&crowd])?;
    let out = crowd.read_back()?;
    Ok((out.positions, out.normals))
}

fn render_crowd(
    ctx: &Context,
    model: &Model,
    path: &Path,
) -> Result<(), Box<dyn std::error::Error>> {
    if model.animation().next().is_none() {
        return Err("the trained model carries no animation".into());
    }
    let mut crowd = Crowd::new(&GpuModel::new(ctx, model)?, CROWD)?;
    crowd.set_bones(0, &phased_poses(model, CROWD, 0))?;
    Batch::new(ctx)?.run(0, &[&crowd])?;
    let (w, h) = (1280, 720);
    let scene = grid_scene(model, CROWD, w as f32 / h as f32);
    let draws = scene.draws(&crowd);
    let image = Renderer::new(ctx, w, h)?.render(&scene.camera, &draws, &[], CROWD_BACKGROUND)?;
    write_png(path, w, h, &image)
}

fn distance(a: &[f32; 3], b: &[f32; 3]) -> f32 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

/// Blue (no error) → green → yellow → red (≥ `scale`).
fn heat(errors: &[f32], scale: f32) -> Vec<[f32; 3]> {
    errors
        .iter()
        .map(|&e| {
            let t = (e / scale).clamp(0.0, 1.0) * 3.0;
            match t {
                t if t < 1.0 => [0.2, 0.35 + 0.45 * t, 0.9 - 0.3 * t],
                t if t < 2.0 => [0.2 + 0.75 * (t - 1.0), 0.8, 0.6 - 0.5 * (t - 1.0)],
                t => [0.95, 0.8 - 0.65 * (t - 2.0), 0.1],
            }
        })
        .collect()
}

/// Area-weighted vertex normals of a host mesh (for the ground truth, which no crowd computed).
fn vertex_normals(positions: &[[f32; 3]], triangles: &[[u32; 3]]) -> Vec<[f32; 3]> {
    let mut sum = vec![glam::Vec3::ZERO; positions.len()];
    for t in triangles {
        let [a, b, c] = t.map(|i| glam::Vec3::from(positions[i as usize]));
        let n = (b - a).cross(c - a);
        t.iter().for_each(|&i| sum[i as usize] += n);
    }
    sum.iter()
        .map(|n| n.normalize_or_zero().to_array())
        .collect()
}
