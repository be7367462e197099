//! What each way of making normals costs in quality (issue 37): per method and normal mode, the
//! angle between its unit normal and the rig's own mesh's on the held-out poses, mean and 95th
//! percentile in degrees (Tarini, Panozzo and Sorkine-Hornung 2014 measure lighting error so).
//!
//! The rig's normal of a vertex is the area-weighted sum over the triangles around it of its own
//! deformed mesh, shared across welded seams as the runtime model's normal groups say (the
//! identity without a model), as `rrskin::normals` computes every method's recomputed normals:
//! - *recomputed*: the same sum over the method's deformed mesh;
//! - *transformed*: the rest normal through the method's own normal map: the cofactor of the
//!   blended 3x3 for SSD and the runtime model (`rrskin::normals::cofactor_times`), the blended
//!   dual quaternion's rotation for DQS.
//!
//! A vertex whose normal (the rig's or the method's) vanishes has no direction and is left out.

use super::dqs;
use crate::set::ExampleSet;
use crate::skinning::lbs::Skinning;
use glam::DVec3;
use rrskin::normals::{area_weighted_grouped, cofactor_times};
use rrskin::NormalMode;

/// The mean and 95th percentile of the angles, in degrees.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AngularError {
    pub mean_deg: f64,
    pub p95_deg: f64,
}

/// Per method (its JSON key: `ssd`, `dqs`, `rr_reduced`) and mode, the held-out angular error.
pub type NormalErrors = Vec<(&'static str, NormalMode, AngularError)>;

/// The JSON key of a mode.
pub fn mode_name(mode: NormalMode) -> &'static str {
    match mode {
        NormalMode::Recomputed => "recomputed",
        NormalMode::Transformed => "transformed",
    }
}

/// `{method: {mode: {"mean_deg", "p95_deg"}}}` (an empty object without test poses).
pub fn to_json(errors: &NormalErrors) -> serde_json::Value {
    let mut methods = serde_json::Map::new();
    for (method, mode, e) in errors {
        let modes = (methods.entry(*method)).or_insert_with(|| serde_json::json!({}));
        modes[mode_name(*mode)] = serde_json::json!({"mean_deg": e.mean_deg, "p95_deg": e.p95_deg});
    }
    methods.into()
}

/// The text table's lines: one a method and mode (none without test poses).
pub fn lines(errors: &NormalErrors) -> String {
    if errors.is_empty() {
        return String::new();
    }
    let mut s = format!(
        "{:<34} {:>10} {:>10}\n",
        "normals vs the rig's, test (deg)", "mean", "p95"
    );
    for (method, mode, e) in errors {
        let label = format!("  {method}, {}", mode_name(*mode));
        s += &format!("{label:<34} {:>10.2} {:>10.2}\n", e.mean_deg, e.p95_deg);
    }
    s
}

/// The angles between `truth` and `normals` (per pose, per vertex), where neither vanishes;
/// None where no vertex has both.
pub fn angular_error(truth: &[Vec<DVec3>], normals: &[Vec<DVec3>]) -> Option<AngularError> {
    let mut angles: Vec<f64> = (truth.iter().flatten().zip(normals.iter().flatten()))
        .filter(|(t, n)| t.length() > 0.0 && n.length() > 0.0)
        .map(|(t, n)| {
            (t.normalize().dot(n.normalize()))
                .clamp(-1.0, 1.0)
                .acos()
                .to_degrees()
        })
        .collect();
    if angles.is_empty() {
        return None;
    }
    angles.sort_by(f64::total_cmp);
    let mean_deg = angles.iter().sum::<f64>() / angles.len() as f64;
    let at = (0.95 * angles.len() as f64).ceil() as usize;
    Some(AngularError {
        mean_deg,
        p95_deg: angles[at.clamp(1, angles.len()) - 1],
    })
}

/// SSD's and DQS's (with SSD's weights) and the runtime model's angular errors in both modes
/// on the `test` poses; empty without test poses.
pub fn held_out(
    set: &ExampleSet,
    ssd: &Skinning,
    runtime: Option<&rrskin::Model>,
    test: &[usize],
) -> rrskin::Result<NormalErrors> {
    if test.is_empty() {
        return Ok(Vec::new());
    }
    let group = |v: usize| runtime.map_or(v, |m| m.normal_group(v));
    let area = |p: &[DVec3]| area_weighted_grouped(p, set.faces.iter().copied(), group);
    let truth: Vec<Vec<DVec3>> = test.iter().map(|&i| area(&set.poses[i].vertices)).collect();
    let rest_normals = area(&set.rest);
    let of_poses = |f: &dyn Fn(usize) -> Vec<DVec3>| -> Vec<Vec<DVec3>> {
        test.iter().map(|&i| f(i)).collect()
    };
    let mut candidates: Vec<(&'static str, NormalMode, Vec<Vec<DVec3>>)> = vec![
        (
            "ssd",
            NormalMode::Recomputed,
            of_poses(&|i| area(&ssd.deform(&set.rest, &set.poses[i].bones))),
        ),
        (
            "ssd",
            NormalMode::Transformed,
            of_poses(&|i| cofactor_normals(set, ssd, &rest_normals, i)),
        ),
        (
            "dqs",
            NormalMode::Recomputed,
            of_poses(&|i| {
                area(&dqs::deform(
                    &set.rest,
                    &ssd.influences,
                    &set.poses[i].bones,
                ))
            }),
        ),
        (
            "dqs",
            NormalMode::Transformed,
            of_poses(&|i| dqs::rotate(&rest_normals, &ssd.influences, &set.poses[i].bones)),
        ),
    ];
    if let Some(model) = runtime {
        for mode in [NormalMode::Recomputed, NormalMode::Transformed] {
            candidates.push(("rr_reduced", mode, runtime_normals(set, model, mode, test)?));
        }
    }
    Ok(candidates
        .into_iter()
        .filter_map(|(method, mode, normals)| {
            angular_error(&truth, &normals).map(|e| (method, mode, e))
        })
        .collect())
}

/// Pose `i`'s rest normals through the cofactor of each vertex's SSD-blended 3x3.
fn cofactor_normals(set: &ExampleSet, ssd: &Skinning, rest: &[DVec3], i: usize) -> Vec<DVec3> {
    let bones: Vec<[f64; 12]> = (set.poses[i].bones.iter())
        .map(|b| b.to_runtime().map(f64::from))
        .collect();
    (ssd.influences.iter().zip(rest))
        .map(|(inf, &n)| {
            let mut m = [0.0; 12];
            for &(b, w) in inf {
                m.iter_mut().zip(&bones[b]).for_each(|(x, e)| *x += w * e);
            }
            cofactor_times(&m, n).normalize_or_zero()
        })
        .collect()
}

/// The runtime model's normals in `mode` on the `test` poses, by the CPU reference.
fn runtime_normals(
    set: &ExampleSet,
    model: &rrskin::Model,
    mode: NormalMode,
    test: &[usize],
) -> rrskin::Result<Vec<Vec<DVec3>>> {
    let mut evaluator = rrskin::cpu::CpuEvaluator::with_normals(model, mode);
    let v = set.vertex_count();
    let (mut positions, mut normals) = (vec![[0.0f32; 3]; v], vec![[0.0f32; 3]; v]);
    test.iter()
        .map(|&i| {
            let bones: Vec<rrskin::predict::Affine> =
                set.poses[i].bones.iter().map(|b| b.to_runtime()).collect();
            evaluator.evaluate(&bones, &mut positions, &mut normals)?;
            Ok(normals
                .iter()
                .map(|n| DVec3::from(n.map(f64::from)))
                .collect())
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn angles_are_in_degrees_and_vanishing_normals_are_left_out() {
        let truth = vec![vec![DVec3::Z, DVec3::Z, DVec3::ZERO, DVec3::X]];
        let tilted = DVec3::new(0.0, 1.0, 1.0);
        let normals = vec![vec![DVec3::Z, tilted, DVec3::Y, DVec3::ZERO]];
        let e = angular_error(&truth, &normals).expect("two vertices have both");
        assert!((e.mean_deg - 22.5).abs() < 1e-9, "{e:?}");
        assert!((e.p95_deg - 45.0).abs() < 1e-9, "{e:?}");
        assert!(angular_error(&[vec![DVec3::ZERO]], &[vec![DVec3::X]]).is_none());
    }
}
