//! Point caches: per-sample vertex positions baked from a rig.
//!
//! - PC2 (`POINTCACHE2\0`, little-endian): version i32 (1), points i32, start frame f32,
//!   sample rate f32, samples i32, then samples x points x 3 f32. Sample s is at frame
//!   `start + s · rate`; its time is frame / fps.
//! - MDD (big-endian): frames i32, points i32, frames f32 times (seconds), then
//!   frames x points x 3 f32.
//! - Alembic (`.abc`, Ogawa): the one animated PolyMesh's positions in world space, at its time
//!   sampling's times in seconds ([`crate::import::alembic`]).
//! - USD (`.usd`, `.usda`, `.usdc`): the stage's one mesh with time-sampled points, in world
//!   space converted to metres and Y up, at its time codes in seconds ([`crate::import::usd`]).
//! - A folder of per-frame OBJ or PLY meshes, numbered by their names' last digits
//!   ([`crate::import::mesh_sequence`]): frames as PC2's.
//!
//! Frame numbers are the DCC's: a sample whose frame is within float32's reach of a whole
//! number is that whole frame (MDD's f32 seconds put Blender's frame 59 at 58.99999809), so a
//! `--test-frames` bound never moves a sample to the other side.

use crate::import::SetFormat;
use crate::set::InputError;
use glam::DVec3;
use std::path::Path;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    /// Frames in the header (start, rate): `--fps` gives their times.
    Pc2,
    /// Times in seconds per sample: `--fps` only numbers their frames.
    Mdd,
    /// Times in seconds per sample, as MDD.
    Alembic,
    /// Time codes per sample, over the stage's time codes per second: seconds, as MDD.
    Usd,
    /// Frames in the file names: `--fps` gives their times, as PC2's.
    Meshes,
}

#[derive(Debug, Clone, PartialEq)]
pub struct PointCache {
    pub format: Format,
    /// Per sample: its frame number (PC2) or time x fps (MDD), whole where float32 allows.
    pub frames: Vec<f64>,
    /// Per sample: the time in seconds.
    pub times: Vec<f64>,
    /// \[sample\]\[point\]
    pub positions: Vec<Vec<DVec3>>,
}

/// A frame this close to a whole number is that number: float32 seconds hold frame f to about
/// 1e-7 f, so this reaches frame 10,000 with margin.
const WHOLE_FRAME: f64 = 1e-3;

/// `frame` rounded to a whole frame when float32 could have stored that whole frame.
fn whole(frame: f64) -> f64 {
    match (frame - frame.round()).abs() <= WHOLE_FRAME {
        true => frame.round(),
        false => frame,
    }
}

const PC2_MAGIC: &[u8; 12] = b"POINTCACHE2\0";

fn bad(file: &Path, message: impl Into<String>) -> InputError {
    InputError {
        file: file.to_path_buf(),
        message: message.into(),
    }
}

impl PointCache {
    /// Reads a .pc2, .mdd, .abc or USD file (by extension; USD's as [`SetFormat`] tells them),
    /// or a folder of per-frame meshes; `fps` turns PC2 and mesh frames into seconds and MDD,
    /// Alembic and USD seconds into frames.
    pub fn load(path: &Path, fps: f64) -> Result<PointCache, InputError> {
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .unwrap_or("")
            .to_ascii_lowercase();
        let bytes = || std::fs::read(path).map_err(|e| format!("cannot read: {e}"));
        let cache = match ext.as_str() {
            _ if path.is_dir() => crate::import::mesh_sequence::read(path).map(|(frames, positions)| {
                PointCache {
                    format: Format::Meshes,
                    times: frames.iter().map(|f| f / fps).collect(),
                    frames,
                    positions,
                }
            }),
            _ if SetFormat::of(path) == SetFormat::Usd => crate::import::usd::read_cache(path)
                .map(|c| Self::from_seconds(Format::Usd, &c.times, c.positions, fps)),
            "pc2" => bytes().and_then(|b| Self::from_pc2(&b, fps)),
            "mdd" => bytes().and_then(|b| Self::from_mdd(&b, fps)),
            "abc" => crate::import::alembic::read(path)
                .map(|c| Self::from_seconds(Format::Alembic, &c.times, c.positions, fps)),
            _ => Err(format!(
                "unknown point cache extension '.{ext}' (expected .pc2, .mdd, .abc, .usd, .usda, .usdc, or a folder of per-frame .obj or .ply meshes)"
            )),
        }
        .map_err(|m| bad(path, m))?;
        if let Some(s) = (cache.positions.iter()).position(|p| p.len() != cache.point_count()) {
            return Err(bad(path, format!("sample {s} has {} points, sample 0 {}: the mesh's vertex count must not change over the cache", cache.positions[s].len(), cache.point_count())));
        }
        if let Some((s, a)) = cache
            .positions
            .iter()
            .enumerate()
            .find_map(|(s, p)| p.iter().position(|v| !v.is_finite()).map(|a| (s, a)))
        {
            return Err(bad(path, format!("sample {s}, point {a} is not finite")));
        }
        Ok(cache)
    }

    pub fn point_count(&self) -> usize {
        self.positions.first().map_or(0, |p| p.len())
    }

    /// Samples per second, from the median spacing of the samples' times (None for one sample).
    pub fn sample_rate(&self) -> Option<f64> {
        let gaps = self.times.windows(2).map(|w| w[1] - w[0]);
        rrskin::cpu::median(gaps)
            .filter(|&g| g > 0.0)
            .map(|g| 1.0 / g)
    }

    pub fn from_pc2(b: &[u8], fps: f64) -> Result<PointCache, String> {
        if b.len() < 32 || &b[..12] != PC2_MAGIC {
            return Err("not a PC2 file (missing POINTCACHE2 header)".into());
        }
        let i32_at = |at: usize| i32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]]);
        let f32_at = |at: usize| f32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]]);
        let (version, points, start, rate, samples) =
            (i32_at(12), i32_at(16), f32_at(20), f32_at(24), i32_at(28));
        if version != 1 {
            return Err(format!("PC2 version {version} is not supported (1 is)"));
        }
        let (points, samples) = counts(points, samples)?;
        // The data first: its length bounds what the header's counts may allocate.
        let positions = read_points(&b[32..], points, samples, f32::from_le_bytes)?;
        let frames: Vec<f64> = (0..samples)
            .map(|s| whole(start as f64 + s as f64 * rate as f64))
            .collect();
        Ok(PointCache {
            format: Format::Pc2,
            times: frames.iter().map(|f| f / fps).collect(),
            frames,
            positions,
        })
    }

    pub fn from_mdd(b: &[u8], fps: f64) -> Result<PointCache, String> {
        if b.len() < 8 {
            return Err("truncated MDD header".into());
        }
        let i32_at = |at: usize| i32::from_be_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]]);
        let (samples, points) = (i32_at(0), i32_at(4));
        let (points, samples) = counts(points, samples)?;
        let body = &b[8..];
        if body.len() < 4 * samples {
            return Err(format!(
                "truncated MDD: {} bytes for {samples} frame times",
                body.len()
            ));
        }
        let times: Vec<f64> = body[..4 * samples]
            .chunks_exact(4)
            .map(|c| f32::from_be_bytes([c[0], c[1], c[2], c[3]]) as f64)
            .collect();
        let positions = read_points(&body[4 * samples..], points, samples, f32::from_be_bytes)?;
        Ok(Self::from_seconds(Format::Mdd, &times, positions, fps))
    }

    /// A cache of samples at `times` (seconds), numbered in frames at `fps`.
    fn from_seconds(
        format: Format,
        times: &[f64],
        positions: Vec<Vec<DVec3>>,
        fps: f64,
    ) -> PointCache {
        let frames: Vec<f64> = times.iter().map(|t| whole(t * fps)).collect();
        PointCache {
            format,
            // A whole frame's time is exact: the f32 seconds' rounding would miss keys.
            times: frames
                .iter()
                .zip(times)
                .map(|(f, t)| if f.fract() == 0.0 { f / fps } else { *t })
                .collect(),
            frames,
            positions,
        }
    }

    /// The PC2 image of this cache (frames must be evenly spaced).
    pub fn to_pc2(&self) -> Vec<u8> {
        let start = self.frames.first().copied().unwrap_or(0.0);
        let rate = if self.frames.len() > 1 {
            self.frames[1] - self.frames[0]
        } else {
            1.0
        };
        let mut out = PC2_MAGIC.to_vec();
        for v in [1i32, self.point_count() as i32] {
            out.extend_from_slice(&v.to_le_bytes());
        }
        out.extend_from_slice(&(start as f32).to_le_bytes());
        out.extend_from_slice(&(rate as f32).to_le_bytes());
        out.extend_from_slice(&(self.positions.len() as i32).to_le_bytes());
        self.positions.iter().flatten().for_each(|p| {
            p.to_array()
                .iter()
                .for_each(|&x| out.extend_from_slice(&(x as f32).to_le_bytes()))
        });
        out
    }

    /// The MDD image of this cache.
    pub fn to_mdd(&self) -> Vec<u8> {
        let mut out = Vec::new();
        for v in [self.positions.len() as i32, self.point_count() as i32] {
            out.extend_from_slice(&v.to_be_bytes());
        }
        self.times
            .iter()
            .for_each(|t| out.extend_from_slice(&(*t as f32).to_be_bytes()));
        self.positions.iter().flatten().for_each(|p| {
            p.to_array()
                .iter()
                .for_each(|&x| out.extend_from_slice(&(x as f32).to_be_bytes()))
        });
        out
    }
}

fn counts(points: i32, samples: i32) -> Result<(usize, usize), String> {
    if points <= 0 || samples <= 0 {
        return Err(format!(
            "{points} points and {samples} samples: both must be positive"
        ));
    }
    Ok((points as usize, samples as usize))
}

fn read_points(
    b: &[u8],
    points: usize,
    samples: usize,
    f: fn([u8; 4]) -> f32,
) -> Result<Vec<Vec<DVec3>>, String> {
    let need = points.saturating_mul(samples).saturating_mul(12);
    if b.len() < need {
        return Err(format!(
            "truncated: {} bytes of positions, {samples} samples x {points} points need {need}",
            b.len()
        ));
    }
    Ok(b[..need]
        .chunks_exact(points * 12)
        .map(|s| {
            s.chunks_exact(12)
                .map(|p| {
                    let x = |i: usize| f([p[i], p[i + 1], p[i + 2], p[i + 3]]) as f64;
                    DVec3::new(x(0), x(4), x(8))
                })
                .collect()
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample_cache() -> PointCache {
        let positions: Vec<Vec<DVec3>> = (0..4)
            .map(|s| {
                (0..5)
                    .map(|a| DVec3::new(s as f64, a as f64 * 0.5, -1.25))
                    .collect()
            })
            .collect();
        PointCache {
            format: Format::Pc2,
            frames: vec![2.0, 3.0, 4.0, 5.0],
            times: vec![2.0 / 24.0, 3.0 / 24.0, 4.0 / 24.0, 5.0 / 24.0],
            positions,
        }
    }

    #[test]
    fn pc2_round_trips() {
        let c = sample_cache();
        let back = PointCache::from_pc2(&c.to_pc2(), 24.0).expect("valid");
        assert_eq!(back.positions, c.positions);
        assert_eq!(back.frames, c.frames);
        assert!(back
            .times
            .iter()
            .zip(&c.times)
            .all(|(a, b)| (a - b).abs() < 1e-9));
    }

    #[test]
    fn mdd_round_trips_big_endian() {
        let c = sample_cache();
        let bytes = c.to_mdd();
        assert_eq!(&bytes[..4], &4i32.to_be_bytes());
        let back = PointCache::from_mdd(&bytes, 24.0).expect("valid");
        assert_eq!(back.positions, c.positions);
        assert!(back
            .frames
            .iter()
            .zip(&c.frames)
            .all(|(a, b)| (a - b).abs() < 1e-4));
    }

    #[test]
    fn truncated_and_foreign_caches_are_refused() {
        let bytes = sample_cache().to_pc2();
        assert!(PointCache::from_pc2(&bytes[..bytes.len() - 1], 24.0)
            .expect_err("short")
            .contains("truncated"));
        assert!(PointCache::from_pc2(b"hello", 24.0)
            .expect_err("not pc2")
            .contains("not a PC2"));
        let mut v2 = bytes.clone();
        v2[12] = 2;
        assert!(PointCache::from_pc2(&v2, 24.0)
            .expect_err("version")
            .contains("version 2"));
        let mdd = sample_cache().to_mdd();
        assert!(PointCache::from_mdd(&mdd[..20], 24.0)
            .expect_err("short")
            .contains("truncated"));
    }
}
