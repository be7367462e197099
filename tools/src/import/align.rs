//! Pre-flight alignment of a point cache with its glTF rig, before any training.
//!
//! The glTF's own skin, played at the clip's keys, predicts roughly where every vertex is; a
//! cache that does not line up with it was exported with other settings. Three things are
//! found from that prediction, each fixed with a line for the user when it is unambiguous:
//!
//! - **Frames**: the whole-frame offset o with which cache sample s holds the clip's frame
//!   `frame_s + o` (MDD's times start at 0 whatever the scene's first frame).
//! - **Space**: the cache in the rig's world, Y-up (as glTF), or Z-up (Blender's MDD), or in
//!   the mesh's object space (PC2's default), which the mesh node's world matrix (or the skin's
//!   bind matrix) takes to the world; in the rig's units, or in centimetres or metres against
//!   them (Alembic stores no units: Maya's caches are in centimetres where its FBX, converted
//!   on load, is in metres).
//! - **Vertex order**: the glTF's, or the DCC's own ([`vertex_map`]).
//!
//! The frames and the space are told apart without knowing the vertex order: each hypothesis is
//! scored by how far the skinned mesh's points are from the nearest cache point (a one-sided
//! Chamfer distance on a subsample), and the best must be at most [`MARGIN`] of the next best.
//! A hypothesis is its placement, the frame offset and the matrix that takes the cache to the
//! world: two names for one placement (object space under a mesh node scaled 0.01, and world
//! space in centimetres) are one hypothesis, described by its simplest name, so that only two
//! different placements are ever ambiguous.

use crate::import::point_cache::{Format, PointCache};
use crate::import::preflight::RigFit;
use crate::import::rig::{at_bind_pose, Rig, TIME_SLACK};
use crate::import::vertex_map::{self, tree};
use crate::set::{bounds, diagonal};
use crate::set::{Affine, InputError};
use glam::{DMat3, DMat4, DVec3};
use kdtree::distance::squared_euclidean;
use rayon::prelude::*;
use std::path::Path;

/// The best hypothesis's score must be at most this fraction of the next one's.
pub const MARGIN: f64 = 0.5;
/// Placements that take the cache's bounding box to within this fraction of the mesh size of
/// each other are one placement: far below what a score can tell apart (a rig departs from its
/// own skin by 0.1–2 % of its size), far above float32's rounding of a node's matrix.
const SAME_PLACEMENT: f64 = 1e-5;
/// Samples and skinned vertices the hypotheses are scored on.
const SCORED_SAMPLES: usize = 16;
const SCORED_VERTICES: usize = 128;

/// The cache lined up with the rig.
#[derive(Debug, Clone)]
pub struct Aligned {
    /// [sample][glTF vertex]: the cache's positions in the rig's world, in the glTF's order.
    pub positions: Vec<Vec<DVec3>>,
    /// Per sample: the clip's frame it holds (the DCC's frame number) and its time in seconds.
    pub frames: Vec<f64>,
    pub times: Vec<f64>,
    /// Per sample: every bone's transform at its time (`Rig::bones_at`).
    pub bones: Vec<Vec<Affine>>,
    /// One line per fix made.
    pub notes: Vec<String>,
}

/// The cache's up axis against the frame it is taken to.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Up {
    Same,
    /// A Z-up cache (Blender's MDD) for a Y-up frame.
    Z,
    /// A Y-up cache for a Z-up frame: a PC2 in object space converted to Y-up ("Convert to
    /// Y-up", its default) of a mesh whose FBX object frame is Blender's Z-up.
    Y,
}

/// Where the cache's coordinates are: Y-up or Z-up, in the world or in an object space (the
/// matrix that takes it to the world, and what that matrix is).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Space {
    up: Up,
    object: Option<(DMat4, &'static str)>,
    /// Cache units to the rig's: 1, or 0.01 (a cache in centimetres), or 100 (in metres against
    /// a rig in centimetres).
    units: f64,
}

/// The unit factors tried: the same units, centimetres against metres, metres against
/// centimetres.
const UNITS: [f64; 3] = [1.0, 0.01, 100.0];

impl Space {
    /// Cache coordinates to the rig's world.
    fn matrix(self) -> DMat4 {
        // Blender's Z-up to glTF's Y-up: (x, y, z) → (x, z, −y); and back.
        let z_to_y = DMat4::from_mat3(DMat3::from_cols(DVec3::X, -DVec3::Z, DVec3::Y));
        let up = match self.up {
            Up::Same => DMat4::IDENTITY,
            Up::Z => z_to_y,
            Up::Y => z_to_y.transpose(),
        };
        self.object.map_or(DMat4::IDENTITY, |o| o.0)
            * up
            * DMat4::from_scale(DVec3::splat(self.units))
    }

    fn note(self) -> Vec<String> {
        let units = match self.units {
            0.01 => {
                Some("cache is in centimetres against the rig's metres: scaled by 0.01".to_string())
            }
            100.0 => {
                Some("cache is in metres against the rig's centimetres: scaled by 100".to_string())
            }
            _ => None,
        };
        let space = match (self.up, self.object) {
            (Up::Same, None) => None,
            (Up::Z, None) => Some("cache is Z-up: converted to the glTF's Y-up".into()),
            (Up::Y, None) => Some("cache is Y-up against the rig's Z-up: converted".into()),
            (Up::Same, Some((_, by))) => Some(format!(
                "cache is in the mesh's object space: converted to world space by {by}"
            )),
            (Up::Z, Some((_, by))) => Some(format!(
                "cache is Z-up and in the mesh's object space: converted to the glTF's Y-up world space by {by}"
            )),
            (Up::Y, Some((_, by))) => Some(format!(
                "cache is in the mesh's object space, converted to Y-up against the object's Z-up: converted to world space by {by}"
            )),
        };
        space.into_iter().chain(units).collect()
    }

    /// How many conversions the space names (an object space, an up axis, a unit factor): of
    /// two names for one placement, the simpler has fewer.
    fn conversions(self) -> usize {
        usize::from(self.object.is_some())
            + usize::from(self.up != Up::Same)
            + usize::from(self.units != 1.0)
    }

    fn describe(self) -> String {
        format!(
            "{}, {}{}",
            self.object.map_or("world space".into(), |(_, by)| format!(
                "object space ({by})"
            )),
            match self.up {
                Up::Same => "the rig's up",
                Up::Z => "Z-up",
                Up::Y => "Y-up against a Z-up frame",
            },
            match self.units {
                1.0 => String::new(),
                u => format!(", scaled by {u}"),
            }
        )
    }
}

#[derive(Debug, Clone, Copy)]
struct Hypothesis {
    space: Space,
    offset: f64,
    /// Mean distance of the skinned points to the nearest cache point, over the mesh size.
    score: f64,
}

/// Lines `cache` up with animation `clip` of `rig` (at `fps`): its frames, its space and its
/// vertex order, each fixed with a note, or an error where the cache is off the clip's keys
/// or two placements fit about as well.
pub fn align(
    rig: &Rig,
    rig_path: &Path,
    cache: &PointCache,
    cache_path: &Path,
    clip: &str,
    fps: f64,
) -> Result<Aligned, InputError> {
    let bad = |message: String| InputError {
        file: cache_path.to_path_buf(),
        message,
    };
    let keys = rig.key_times();
    if keys.is_empty() {
        return Err(InputError {
            file: rig_path.to_path_buf(),
            message: format!("animation '{clip}' has no key times"),
        });
    }
    let offsets = offsets(&cache.frames, &keys, fps);
    if offsets.is_empty() {
        return Err(bad(off_the_keys(rig_path, cache, &keys, clip, fps)));
    }
    let size = diagonal(&rig.rest);
    let spaces = spaces(rig);
    let hypotheses = score(rig, cache, fps, &spaces, &offsets, size);
    let close = close_placements(distinct(hypotheses, &corners(&cache.positions[0]), size));
    if let [only] = close[..] {
        return (lined_up(rig, cache, fps, only).map(|(aligned, _)| aligned)).map_err(bad);
    }
    // The Chamfer scores cannot tell these apart (a limb turned about its own axis, a body
    // about its vertical): their points in correspondence, through each one's vertex map, can.
    // Kept: the placements the rig's skin follows, as the last check (`preflight`) asks.
    let (mut fits, mut first) = (Vec::new(), None);
    for &h in &close {
        match lined_up(rig, cache, fps, h) {
            Ok((aligned, Some(f))) if f.follows() => fits.push((h, aligned, f.residual)),
            Ok((aligned, _)) => drop(first.get_or_insert(Ok(aligned))),
            Err(e) => drop(first.get_or_insert(Err(e))),
        }
    }
    fits.sort_by(|a, b| a.2.total_cmp(&b.2));
    match &fits[..] {
        // None is followed by the rig's skin: the first, for the checks after this to refuse.
        [] => first.unwrap_or_else(|| Err(String::new())).map_err(bad),
        [(a, _, ra), (b, _, rb), ..] if *ra > MARGIN * rb => {
            Err(bad(ambiguous((*a, *ra), (*b, *rb), rig_path, cache, clip)))
        }
        _ => Ok(fits.swap_remove(0).1),
    }
}

/// At most this many placements the Chamfer scores cannot tell apart are lined up in full.
const CLOSE_PLACEMENTS: usize = 4;

/// The best-scoring placement and those the score cannot tell from it (the best more than
/// [`MARGIN`] of theirs), at most [`CLOSE_PLACEMENTS`], best first.
fn close_placements(mut placements: Vec<Hypothesis>) -> Vec<Hypothesis> {
    placements.sort_by(|a, b| a.score.total_cmp(&b.score));
    let best = placements[0].score;
    (placements.into_iter())
        .take_while(|h| best > MARGIN * h.score || h.score == best)
        .take(CLOSE_PLACEMENTS)
        .collect()
}

/// The cache lined up by `h`: its frames shifted, its points taken to the world and mapped to
/// the glTF's vertices, with the notes; and how the rig's skin follows it, over every sample
/// (None where the samples do not move).
fn lined_up(
    rig: &Rig,
    cache: &PointCache,
    fps: f64,
    h: Hypothesis,
) -> Result<(Aligned, Option<RigFit>), String> {
    let mut notes: Vec<String> = h.space.note();
    let frames: Vec<f64> = cache.frames.iter().map(|f| f + h.offset).collect();
    let times: Vec<f64> = frames.iter().map(|f| f / fps).collect();
    if h.offset != 0.0 {
        notes.push(shift_note(cache, frames[0], h.offset));
    }
    let to_world = h.space.matrix();
    let world: Vec<Vec<DVec3>> = (cache.positions.iter())
        .map(|s| s.iter().map(|&p| to_world.transform_point3(p)).collect())
        .collect();
    let bones: Vec<Vec<Affine>> = times.iter().map(|&t| rig.bones_at(t)).collect();
    let skin: Vec<Vec<DVec3>> = bones.iter().map(|b| rig.skin(b)).collect();
    let size = diagonal(&rig.rest);
    let at_bind = bones.iter().position(|b| at_bind_pose(b, size));
    let (rest, triangles, primitives) = (&rig.rest, &rig.triangles, &rig.primitives);
    let map = vertex_map::map(rest, triangles, primitives, &skin, &world, at_bind)?;
    notes.extend(map.note);
    let positions: Vec<Vec<DVec3>> = (world.iter())
        .map(|s| map.point_of.iter().map(|&p| s[p]).collect())
        .collect();
    let vertices: Vec<&[DVec3]> = positions.iter().map(Vec::as_slice).collect();
    let fit = RigFit::between(&rig.rest, &vertices, &skin);
    let aligned = Aligned {
        positions,
        frames,
        times,
        bones,
        notes,
    };
    Ok((aligned, fit))
}

/// The spaces the cache may be in: world space or each distinct object space the rig knows
/// (the mesh node's world matrix, the skin's bind matrix; none that is the identity), each
/// with every up axis and unit factor.
fn spaces(rig: &Rig) -> Vec<Space> {
    let mut objects: Vec<(DMat4, &'static str)> = Vec::new();
    for object in [
        rig.mesh_world.map(|m| (m, "the mesh node's world matrix")),
        rig.bind.map(|m| (m, "the skin's bind matrix")),
    ]
    .into_iter()
    .flatten()
    {
        let known = |m: &DMat4| m.abs_diff_eq(object.0, 1e-6 * object.0.w_axis.length().max(1.0));
        if !known(&DMat4::IDENTITY) && !objects.iter().any(|o| known(&o.0)) {
            objects.push(object);
        }
    }
    std::iter::once(None)
        .chain(objects.into_iter().map(Some))
        .flat_map(|object| [Up::Same, Up::Z, Up::Y].map(|up| (up, object)))
        .flat_map(|(up, object)| UNITS.map(|units| Space { up, object, units }))
        .collect()
}

/// The eight corners of the bounding box of `points`.
fn corners(points: &[DVec3]) -> [DVec3; 8] {
    let (lo, hi) = bounds(points);
    std::array::from_fn(|i| {
        DVec3::select(glam::BVec3::new(i & 1 != 0, i & 2 != 0, i & 4 != 0), hi, lo)
    })
}

/// One hypothesis per placement: those with one frame offset whose matrices take the cache's
/// bounding box (`corners`) to the same points, within [`SAME_PLACEMENT`] of the mesh `size`,
/// are one, scored by the best of them and named by the simplest ([`Space::conversions`]).
fn distinct(hypotheses: Vec<Hypothesis>, corners: &[DVec3], size: f64) -> Vec<Hypothesis> {
    let placed = |h: &Hypothesis| -> Vec<DVec3> {
        let m = h.space.matrix();
        corners.iter().map(|&c| m.transform_point3(c)).collect()
    };
    let mut kept: Vec<(Hypothesis, Vec<DVec3>)> = Vec::new();
    for h in hypotheses {
        let points = placed(&h);
        let same = |(k, at): &&mut (Hypothesis, Vec<DVec3>)| {
            k.offset == h.offset
                && (at.iter().zip(&points)).all(|(a, b)| a.distance(*b) <= SAME_PLACEMENT * size)
        };
        match kept.iter_mut().find(same) {
            Some((k, _)) => {
                let score = k.score.min(h.score);
                if h.space.conversions() < k.space.conversions() {
                    *k = h;
                }
                k.score = score;
            }
            None => kept.push((h, points)),
        }
    }
    kept.into_iter().map(|(h, _)| h).collect()
}

/// The message for two placements that fit about as well: `a` and `b` with their residuals
/// in correspondence (RMS over the mesh size; the better not at most [`MARGIN`] of the other).
fn ambiguous(
    (a, ra): (Hypothesis, f64),
    (b, rb): (Hypothesis, f64),
    rig_path: &Path,
    cache: &PointCache,
    clip: &str,
) -> String {
    let what = |h: &Hypothesis, residual: f64| {
        format!(
            "{} with cache frame {} as the clip's frame {} (the skin {:.2} % of the mesh size from the nearest cache points, {:.2} % from the points it maps to)",
            h.space.describe(),
            cache.frames[0],
            cache.frames[0] + h.offset,
            100.0 * h.score,
            100.0 * residual
        )
    };
    format!(
        "cannot tell how the cache lines up with animation '{clip}' of {}: as {} or as {} (the glTF's own skin against the cache's points); export the cache in world space, in the glTF's Y-up, over the clip's own frame range",
        rig_path.display(),
        what(&a, ra),
        what(&b, rb)
    )
}

/// The note for a cache shifted by `offset` frames, whose sample 0 holds the clip's frame
/// `first`.
fn shift_note(cache: &PointCache, first: f64, offset: f64) -> String {
    format!(
        "cache sample 0 holds the clip's frame {}, not frame {}{}: shifted by {} frame{}",
        first,
        cache.frames[0],
        match cache.format {
            Format::Mdd => " (MDD times start at 0, whatever the scene's first frame)",
            Format::Pc2 | Format::Alembic | Format::Usd | Format::Meshes => "",
        },
        offset,
        if offset.abs() == 1.0 { "" } else { "s" }
    )
}

/// The whole-frame offsets under which every sample lands on a key of the clip.
fn offsets(frames: &[f64], keys: &[f64], fps: f64) -> Vec<f64> {
    let on_key = |time: f64| {
        let k = keys.partition_point(|&t| t < time);
        [k.wrapping_sub(1), k]
            .iter()
            .filter_map(|&i| keys.get(i))
            .any(|&t| (t - time).abs() <= TIME_SLACK)
    };
    let mut offsets: Vec<f64> = keys
        .iter()
        .map(|&k| (k * fps - frames[0]).round())
        .collect();
    offsets.dedup();
    offsets.retain(|&o| frames.iter().all(|&f| on_key((f + o) / fps)));
    offsets
}

/// Every hypothesis scored: over a few samples, the mean distance from a subsample of the
/// skinned mesh's points to the nearest cache point, in world units over the mesh size.
fn score(
    rig: &Rig,
    cache: &PointCache,
    fps: f64,
    spaces: &[Space],
    offsets: &[f64],
    size: f64,
) -> Vec<Hypothesis> {
    let n = cache.positions.len();
    let samples: Vec<usize> = (0..SCORED_SAMPLES.min(n))
        .map(|i| i * n / SCORED_SAMPLES.min(n))
        .collect();
    let trees: Vec<_> = samples.iter().map(|&s| tree(&cache.positions[s])).collect();
    let step = rig.rest.len().div_ceil(SCORED_VERTICES).max(1);
    let probes: Vec<usize> = (0..rig.rest.len()).step_by(step).collect();
    let to_cache: Vec<(DMat4, f64)> = spaces
        .iter()
        .map(|s| {
            let m = s.matrix();
            (m.inverse(), m.determinant().abs().cbrt())
        })
        .collect();
    offsets
        .par_iter()
        .flat_map_iter(|&offset| {
            let mut sums = vec![0.0; spaces.len()];
            for (tree, &s) in trees.iter().zip(&samples) {
                let bones = rig.bones_at((cache.frames[s] + offset) / fps);
                for &v in &probes {
                    let p = rig.skin_vertex(v, &bones);
                    for (sum, (inverse, scale)) in sums.iter_mut().zip(&to_cache) {
                        let q = inverse.transform_point3(p).to_array();
                        *sum += tree
                            .nearest(&q, 1, &squared_euclidean)
                            .ok()
                            .and_then(|n| n.first().map(|x| x.0.sqrt() * scale))
                            .unwrap_or(f64::INFINITY);
                    }
                }
            }
            let count = (samples.len() * probes.len()) as f64;
            spaces
                .iter()
                .zip(sums)
                .map(move |(&space, sum)| Hypothesis {
                    space,
                    offset,
                    score: sum / count / size,
                })
                .collect::<Vec<_>>()
        })
        .collect()
}

/// Why no offset puts the samples on the clip's keys, with the likely cause.
fn off_the_keys(rig_path: &Path, cache: &PointCache, keys: &[f64], clip: &str, fps: f64) -> String {
    let key_fps = rrskin::cpu::median(keys.windows(2).map(|w| w[1] - w[0]))
        .map(|d| 1.0 / d)
        .filter(|r| (r - r.round()).abs() < 1e-3)
        .map(f64::round);
    let hint = match (cache.format, key_fps, cache.sample_rate()) {
        (Format::Mdd | Format::Alembic | Format::Usd, Some(k), Some(c)) if (c - k).abs() > 1e-3 * k => format!(
            "; the cache was sampled at {c:.3} fps (its samples are 1/{c:.3} s apart) and the clip's keys are 1/{k} s apart: bake the cache at the clip's {k} fps (MDD, Alembic and USD store seconds: --fps only numbers their frames)"
        ),
        (Format::Pc2 | Format::Meshes, Some(k), _) if k != fps => format!("; the keys are 1/{k} s apart: is it --fps {k}?"),
        _ => "; no whole-frame shift of the cache fits either: bake the cache at the clip's keys".into(),
    };
    let s = (0..cache.times.len())
        .find(|&s| {
            offsets(&cache.frames[s..=s], keys, fps)
                .iter()
                .all(|&o| o != 0.0)
        })
        .unwrap_or(0);
    let (first, last) = (keys[0], keys[keys.len() - 1]);
    format!(
        "sample {s} (frame {}, t = {:.4} s at --fps {fps}) lands on no key of animation '{clip}' in {} ({} keys, {first:.4}..{last:.4} s){hint}",
        cache.frames[s],
        cache.times[s],
        rig_path.display(),
        keys.len()
    )
}
