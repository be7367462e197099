//! `rrskin demo`: the main job on the bundled example. Trains every method, prints the error
//! table and the training time, writes the runtime model, and renders with the Vulkan runtime:
//! the held-out pose where SSD errs most, as ground truth | SSD | rotational regression
//! coloured by per-vertex error (each panel from the same camera on the figure, labelled, with
//! the colour scale), a close-up of SSD and the runtime model where the runtime model gains
//! most, and a crowd of 256 characters playing the model's animation; the runtime model
//! retrained at smaller P for the accuracy/size curve; and a report page (report.html) with the
//! error table, the curve and the images.

use crate::eval::{self, Report};
use crate::run::figure::Image;
use crate::run::image::write_png;
use crate::set::ExampleSet;
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
    /// SSD | the runtime model where the runtime model gains most on SSD.
    pub closeup: PathBuf,
    pub crowd: PathBuf,
    /// The runtime model at several P (smallest first) and their curve (SVG).
    pub tradeoff: Vec<crate::run::tradeoff::Point>,
    pub tradeoff_plot: PathBuf,
    /// The Vulkan device that rendered the images.
    pub device: String,
    /// The pose shown in the comparison and the RMS errors there (SSD, RR), in mesh units.
    pub pose: usize,
    pub rms: (f64, f64),
    /// Error (mesh units) shown as full red.
    pub scale: f32,
    /// The example set, as shown to the user.
    pub set: String,
}

/// Trains, renders the three figures, sweeps P and writes the report page.
pub fn run(set_dir: &Path, out: &Path, quiet: bool) -> Result<Outputs, Box<dyn std::error::Error>> {
    let set = ExampleSet::load(set_dir)?;
    crate::output::check_writable(out)?;
    let (report, model) = train(&set, quiet)?;
    let model_path = out.join("model.rrs");
    model.save(&model_path)?;

    let ctx = Context::new(&ContextDesc::default())?;
    let held_out = HeldOut::of(&ctx, &set, &model)?;
    let comparison = out.join("comparison.png");
    held_out.write_comparison(&ctx, &comparison)?;
    let closeup = out.join("closeup.png");
    held_out.write_closeup(&ctx, &closeup)?;
    let crowd_path = out.join("crowd.png");
    render_crowd(&ctx, &model, &crowd_path)?;

    let tradeoff = crate::run::tradeoff::sweep(&set, &report, quiet)?;
    let tradeoff_plot = out.join("tradeoff.svg");
    crate::run::tradeoff::plot(&tradeoff_plot, &tradeoff, &report)?;
    let outputs = Outputs {
        report,
        model: model_path,
        comparison,
        closeup,
        crowd: crowd_path,
        tradeoff,
        tradeoff_plot,
        device: ctx.device_name().to_string(),
        pose: held_out.pose,
        rms: (rms(&held_out.e_ssd), rms(&held_out.e_rr)),
        scale: held_out.scale,
        set: crate::output::shown(set_dir),
    };
    crate::run::report::write(&out.join("report.html"), &outputs)?;
    Ok(outputs)
}

/// Every method trained on `set` (the report) and the runtime model.
fn train(set: &ExampleSet, quiet: bool) -> Result<(Report, Model), Box<dyn std::error::Error>> {
    let options = eval::Options {
        train: crate::train::TrainOptions {
            quiet,
            ..Default::default()
        },
        ..Default::default()
    };
    let report = eval::run(set, &options)?;
    let model = report.model.clone().ok_or("training produced no model")?;
    Ok((report, model))
}

/// The held-out pose where SSD errs most: ground truth, SSD and the runtime model there (as
/// the runtime deforms them), their per-vertex errors and colours.
struct HeldOut {
    pose: usize,
    truth: Vec<[f32; 3]>,
    /// The ground truth's normals, which no crowd computed.
    truth_normals: Vec<[f32; 3]>,
    /// Positions and normals.
    ssd: (Vec<[f32; 3]>, Vec<[f32; 3]>),
    rr: (Vec<[f32; 3]>, Vec<[f32; 3]>),
    e_ssd: Vec<f32>,
    e_rr: Vec<f32>,
    triangles: Vec<[u32; 3]>,
    /// The rest mesh's height, and the error shown as full red.
    height: f32,
    scale: f32,
    proxies: usize,
}

/// The RMS of per-vertex errors.
fn rms(e: &[f32]) -> f64 {
    (e.iter().map(|x| (*x as f64).powi(2)).sum::<f64>() / e.len() as f64).sqrt()
}

impl HeldOut {
    fn of(
        ctx: &Context,
        set: &ExampleSet,
        model: &Model,
    ) -> Result<HeldOut, Box<dyn std::error::Error>> {
        let baseline = model
            .baseline()
            .ok_or("the trained model has no SSD baseline")?;
        let pose = worst_pose_for_ssd(set, &baseline)?;
        let bones: Vec<rrskin::predict::Affine> = set.poses[pose]
            .bones
            .iter()
            .map(|b| b.to_runtime())
            .collect();
        let (rr, ssd) = (deform(ctx, model, &bones)?, deform(ctx, &baseline, &bones)?);
        let truth: Vec<[f32; 3]> = set.poses[pose]
            .vertices
            .iter()
            .map(|p| p.as_vec3().to_array())
            .collect();
        let height = set.rest.iter().map(|p| p.y).fold(f64::MIN, f64::max)
            - set.rest.iter().map(|p| p.y).fold(f64::MAX, f64::min);
        let errors = |p: &[[f32; 3]]| -> Vec<f32> {
            p.iter().zip(&truth).map(|(a, b)| distance(a, b)).collect()
        };
        let (e_ssd, e_rr) = (errors(&ssd.0), errors(&rr.0));
        let truth_normals = rrskin::normals::area_weighted_grouped(
            &set.poses[pose].vertices,
            set.faces.iter().copied(),
            |v| v,
        )
        .iter()
        .map(|n| n.as_vec3().to_array())
        .collect();
        Ok(HeldOut {
            pose,
            truth,
            truth_normals,
            ssd,
            rr,
            e_ssd,
            e_rr,
            triangles: set.faces.iter().map(|t| t.map(|a| a as u32)).collect(),
            height: height as f32,
            scale: ERROR_SCALE * height as f32,
            proxies: model.proxy_count(),
        })
    }

    /// Renders `panels` (positions, normals, colours, label) side by side from `camera`.
    fn render(
        &self,
        renderer: &mut Renderer,
        camera: &Camera,
        panels: &[Panel],
    ) -> rrskin::Result<Image> {
        let mut images = Vec::new();
        for (positions, normals, colors, label) in panels {
            let mut image = panel(
                renderer,
                camera,
                positions,
                normals,
                colors,
                &self.triangles,
            )?;
            tag(&mut image, label);
            images.push(image);
        }
        Ok(Image::side_by_side(&images))
    }

    /// Ground truth (grey), SSD and the runtime model (coloured by error).
    fn panels(&self) -> [Panel<'_>; 3] {
        let gray = vec![[0.8f32, 0.8, 0.8]; self.truth.len()];
        let (c_ssd, c_rr) = (heat(&self.e_ssd, self.scale), heat(&self.e_rr, self.scale));
        [
            (
                &self.truth,
                &self.truth_normals,
                gray,
                "GROUND TRUTH".to_string(),
            ),
            (&self.ssd.0, &self.ssd.1, c_ssd, "SSD (LBS)".to_string()),
            (
                &self.rr.0,
                &self.rr.1,
                c_rr,
                format!("RUNTIME MODEL, P = {}", self.proxies),
            ),
        ]
    }

    /// The three panels from one camera on the pose's own centre (the three copies are seen
    /// alike), with the colour scale.
    fn write_comparison(
        &self,
        ctx: &Context,
        path: &Path,
    ) -> Result<(), Box<dyn std::error::Error>> {
        let h = self.height;
        let (lo, hi) = self.truth.iter().fold(
            (glam::Vec3::splat(f32::MAX), glam::Vec3::splat(f32::MIN)),
            |(lo, hi), p| (lo.min((*p).into()), hi.max((*p).into())),
        );
        let center = 0.5 * (lo + hi);
        let (pw, ph) = (400, 600);
        let eye = center + glam::Vec3::new(0.0, 0.1 * h, 1.35 * h);
        let camera = Camera::looking_at(eye, center, 0.9, pw as f32 / ph as f32, 0.01, 100.0);
        let mut renderer = Renderer::new(ctx, pw, ph)?;
        let mut figure = self.render(&mut renderer, &camera, &self.panels())?;
        legend(&mut figure, pw as i64, self.scale);
        write_png(path, figure.width, figure.height, &figure.rgba)?;
        Ok(())
    }

    /// SSD and the runtime model where the runtime model gains most on SSD, seen along the
    /// surface normal there.
    fn write_closeup(&self, ctx: &Context, path: &Path) -> Result<(), Box<dyn std::error::Error>> {
        let h = self.height;
        let (e_ssd, e_rr) = (&self.e_ssd, &self.e_rr);
        let gain = (0..self.truth.len())
            .max_by(|&a, &b| (e_ssd[a] - e_rr[a]).total_cmp(&(e_ssd[b] - e_rr[b])))
            .unwrap_or(0);
        let at = glam::Vec3::from(self.truth[gain]);
        let normal = glam::Vec3::from(self.truth_normals[gain])
            .try_normalize()
            .unwrap_or(glam::Vec3::Z);
        let near_eye = at + normal * 0.35 * h + glam::Vec3::Y * 0.05 * h;
        let near = Camera::looking_at(near_eye, at, 0.9, 1.0, 0.001, 100.0);
        let mut renderer = Renderer::new(ctx, 400, 400)?;
        let [_, ssd, rr] = self.panels();
        let close_ups = [ssd, rr].map(|(p, n, c, label)| (p, n, c, format!("{label}, CLOSE-UP")));
        let close = self.render(&mut renderer, &near, &close_ups)?;
        write_png(path, close.width, close.height, &close.rgba)?;
        Ok(())
    }
}

/// A panel of a figure: positions, normals, colours, label.
type Panel<'a> = (&'a Vec<[f32; 3]>, &'a Vec<[f32; 3]>, Vec<[f32; 3]>, String);

/// Dark grey of the labels.
const INK: [u8; 3] = [40, 40, 40];

/// A panel's label, top left, on white (a close-up's mesh may fill the panel).
fn tag(image: &mut Image, text: &str) {
    image.bar(8, 8, Image::label_width(text, 2) + 8, 22, |_| [1.0; 3]);
    image.label(12, 12, 2, text, INK);
}

/// One mesh rendered alone on white.
fn panel(
    renderer: &mut Renderer,
    camera: &Camera,
    positions: &[[f32; 3]],
    normals: &[[f32; 3]],
    colors: &[[f32; 3]],
    triangles: &[[u32; 3]],
) -> rrskin::Result<Image> {
    let mesh = HostMesh {
        positions,
        normals,
        colors,
        triangles,
        offset: [0.0; 3],
    };
    let rgba = renderer.render(camera, &[], &[mesh], [1.0, 1.0, 1.0])?;
    Ok(Image {
        width: renderer.width(),
        height: renderer.height(),
        rgba,
    })
}

/// The colour scale under the two coloured panels, with its unit.
fn legend(figure: &mut Image, panel_width: i64, scale: f32) {
    let (x, w) = (panel_width + 40, 2 * panel_width - 80);
    let y = figure.height as i64 - 44;
    figure.bar(x, y, w, 12, |t| heat(&[t], 1.0)[0]);
    figure.label(x, y + 18, 2, "0", INK);
    let text = format!(">= {scale:.4} MESH UNITS (2% OF HEIGHT)");
    figure.label(x + w - Image::label_width(&text, 2), y + 18, 2, &text, INK);
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
            set.poses[i].bones.iter().map(|b| b.to_runtime()).collect();
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
