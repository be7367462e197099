//! The model invariants, checked on every construction (from parts or from a file).
//! After `check` succeeds, every index the GPU passes read is in range and every number is finite.

use super::{
    Correctives, DeltaMushKey, FeatureRange, Key, KeyPredictor, Mat3Rows, ModelParts,
    ProxyCorrectives, MAX_CORRECTIVES, MAX_DELTA_MUSH_BONES, MAX_PROXY_DRIVERS, MAX_PROXY_KERNELS,
    SUPPORTED_INFLUENCES,
};
use crate::error::ModelProblem;

/// Largest vertex, triangle or bone count: indices and offsets must fit the shaders' u32/i32.
const MAX_COUNT: usize = i32::MAX as usize / 8;
/// Tolerance on |Σ w − 1| per vertex and on rotation matrices (orthonormality, determinant).
pub const WEIGHT_SUM_TOLERANCE: f32 = 1e-3;
pub const ROTATION_TOLERANCE: f32 = 1e-3;
/// Tolerance on |length − 1| of a rest tangent's xyz.
pub const TANGENT_LENGTH_TOLERANCE: f32 = 1e-3;

type Check = Result<(), ModelProblem>;

pub fn check(m: &ModelParts) -> Check {
    sizes(m)?;
    let v = m.rest_positions.len();
    let j = m.bone_parents.len();
    let p = m.key_count();
    let k = m.influences as usize;
    finite("rest positions", m.rest_positions.iter().flatten())?;
    finite("skin weights", m.skin_weights.iter())?;
    finite("C1", m.c1.iter())?;
    finite("C2", m.c2.iter())?;
    indices(m, v, j, p)?;
    weights(&m.skin_weights, k)?;
    for (l, key) in m.keys.iter().enumerate() {
        match key {
            Key::Predictor(k) => predictor(l, k, j)?,
            Key::DeltaMush(k) => delta_mush_key(l, k, j)?,
        }
    }
    if !m.baseline_indices.is_empty() || !m.baseline_weights.is_empty() {
        baseline(m, v, j, k)?;
    }
    animation(&m.animation, j)?;
    if !m.normal_groups.is_empty() {
        normal_groups(&m.normal_groups, v)?;
    }
    if !m.rest_tangents.is_empty() {
        rest_tangents(&m.rest_tangents, v)?;
    }
    if let Some(c) = &m.correctives {
        correctives(c, &m.bone_parents, v)?;
    }
    if let Some(c) = &m.proxy_correctives {
        proxy_correctives(c, &m.bone_parents, p)?;
    }
    Ok(())
}

/// V, J, T, P and K in range, and the lengths they give the skin, C1 and C2.
fn sizes(m: &ModelParts) -> Check {
    let v = m.rest_positions.len();
    let j = m.bone_parents.len();
    let p = m.key_count();
    let k = m.influences as usize;
    dimension("vertex count", v, 1)?;
    dimension("bone count", j, 1)?;
    dimension("triangle count", m.triangles.len(), 0)?;
    dimension("key count", p, 0)?;
    if !SUPPORTED_INFLUENCES.contains(&m.influences) {
        return Err(ModelProblem::Dimension {
            what: "influences per vertex (K)",
            value: k as u64,
            reason: "must be 4 or 8",
        });
    }
    length("skin indices", v * k, m.skin_indices.len())?;
    length("skin weights", v * k, m.skin_weights.len())?;
    length("C1", 4 * p * 3 * p, m.c1.len())?;
    length("C2", 4 * p * 4 * j, m.c2.len())?;
    Ok(())
}

/// The bone parents (a forest), the triangles' vertices and the skin's palette indices in
/// range.
fn indices(m: &ModelParts, v: usize, j: usize, p: usize) -> Check {
    for (i, &parent) in m.bone_parents.iter().enumerate() {
        if parent < -1 || parent >= j as i32 {
            return Err(out_of_range("bone parents", i, parent as i64, j));
        }
    }
    acyclic(&m.bone_parents)?;
    for (t, tri) in m.triangles.iter().enumerate() {
        for &c in tri {
            if c as usize >= v {
                return Err(out_of_range("triangles", 3 * t, c as i64, v));
            }
        }
    }
    for (i, &idx) in m.skin_indices.iter().enumerate() {
        if idx as usize >= p + j {
            return Err(out_of_range("skin indices", i, idx as i64, p + j));
        }
    }
    Ok(())
}

/// Every vertex's `k` weights non-negative, summing to 1.
fn weights(weights: &[f32], k: usize) -> Check {
    for (a, w) in weights.chunks_exact(k).enumerate() {
        let sum: f32 = w.iter().sum();
        if w.iter().any(|&x| x < 0.0) || (sum - 1.0).abs() > WEIGHT_SUM_TOLERANCE {
            return Err(ModelProblem::BadWeights { vertex: a, sum });
        }
    }
    Ok(())
}

/// The SSD baseline skin: V x K bones in range and weights.
fn baseline(m: &ModelParts, v: usize, j: usize, k: usize) -> Check {
    length("baseline indices", v * k, m.baseline_indices.len())?;
    length("baseline weights", v * k, m.baseline_weights.len())?;
    finite("baseline weights", m.baseline_weights.iter())?;
    if let Some(i) = m.baseline_indices.iter().position(|&b| b as usize >= j) {
        return Err(out_of_range(
            "baseline indices",
            i,
            m.baseline_indices[i] as i64,
            j,
        ));
    }
    weights(&m.baseline_weights, k)
}

/// Whole frames of J transforms, finite, with proper rotations.
fn animation(animation: &[[f32; 12]], j: usize) -> Check {
    if animation.len() % j != 0 {
        return Err(ModelProblem::Length {
            what: "animation (frames x bones)",
            expected: animation.len().div_ceil(j) * j,
            actual: animation.len(),
        });
    }
    finite("animation", animation.as_flattened().iter())?;
    for (i, t) in animation.iter().enumerate() {
        rotation(
            "animation rotation",
            i,
            &[t[0], t[1], t[2], t[4], t[5], t[6], t[8], t[9], t[10]],
        )?;
    }
    Ok(())
}

/// V normal groups, each a vertex.
fn normal_groups(groups: &[u32], v: usize) -> Check {
    length("normal groups", v, groups.len())?;
    if let Some(i) = groups.iter().position(|&g| g as usize >= v) {
        return Err(out_of_range("normal groups", i, groups[i] as i64, v));
    }
    Ok(())
}

/// V rest tangents, finite, of unit xyz and handedness ±1.
fn rest_tangents(tangents: &[[f32; 4]], v: usize) -> Check {
    length("rest tangents", v, tangents.len())?;
    finite("rest tangents", tangents.iter().flatten())?;
    for (a, t) in tangents.iter().enumerate() {
        let length = (t[0] * t[0] + t[1] * t[1] + t[2] * t[2]).sqrt();
        if (length - 1.0).abs() > TANGENT_LENGTH_TOLERANCE || t[3].abs() != 1.0 {
            return Err(ModelProblem::BadTangent {
                vertex: a,
                length,
                handedness: t[3],
            });
        }
    }
    Ok(())
}

/// E in 1..=P corrected proxies, ascending and distinct; CSR driver offsets from 0 giving each
/// at most MAX_PROXY_DRIVERS drivers (none leaves the proxy as it is), bones with a parent, distinct within the proxy; C x J centres
/// (C ≤ MAX_PROXY_KERNELS), J widths when C > 0 (> 0 for every driver), at least one feature
/// per driver; the maps Σ 12 F_i; every number finite.
fn proxy_correctives(c: &ProxyCorrectives, parents: &[i32], p: usize) -> Check {
    corrected_proxies(&c.proxies, p)?;
    driver_offsets(c)?;
    proxy_drivers(c, parents)?;
    proxy_kernels(c, parents.len())?;
    proxy_up(c.up)?;
    proxy_ranges(&c.ranges, parents.len())?;
    let features = c.features_per_driver(parents.len());
    length(
        "proxy corrective maps (12 x features, summed over the proxies)",
        12 * features * c.drivers.len(),
        c.maps.len(),
    )?;
    finite("proxy corrective maps", c.maps.iter())?;
    Ok(())
}

/// The model's up, where the features see gravity: finite and of unit length (to 1e-4, what
/// f32 keeps of a normalised vector), since γ_b = 0 at rest needs u_c = u exactly.
fn proxy_up(up: Option<[f32; 3]>) -> Check {
    let Some(u) = up else { return Ok(()) };
    finite("proxy corrective up", u.iter())?;
    let length = u.iter().map(|x| x * x).sum::<f32>().sqrt();
    if (length - 1.0).abs() > 1e-4 {
        return Err(ModelProblem::BadProxyCorrective {
            what: "up",
            index: 0,
            reason: "is not of unit length",
        });
    }
    Ok(())
}

/// J feature ranges or none, finite, each entry's lower bound ≤ 0 ≤ its upper bound (the rest
/// pose's features, 0, are within them).
fn proxy_ranges(ranges: &[FeatureRange], j: usize) -> Check {
    if !ranges.is_empty() {
        length(
            "proxy corrective feature ranges (J or none)",
            j,
            ranges.len(),
        )?;
    }
    let bounds = ranges.iter().flat_map(|r| r.lower.iter().chain(&r.upper));
    finite("proxy corrective feature ranges", bounds)?;
    let index = ranges
        .iter()
        .position(|r| (r.lower.iter().zip(&r.upper)).any(|(&lo, &hi)| lo > 0.0 || hi < 0.0));
    match index {
        Some(index) => Err(ModelProblem::BadProxyCorrective {
            what: "ranges",
            index,
            reason: "do not contain 0 (the rest pose's features)",
        }),
        None => Ok(()),
    }
}

/// E in 1..=P proxies, ascending and distinct.
fn corrected_proxies(proxies: &[u32], p: usize) -> Check {
    let e = proxies.len();
    if e == 0 || e > p {
        return Err(ModelProblem::Dimension {
            what: "corrected proxy count (E)",
            value: e as u64,
            reason: "must be 1 to P (the model's proxies)",
        });
    }
    for (i, &proxy) in proxies.iter().enumerate() {
        if proxy as usize >= p {
            return Err(out_of_range("proxy corrective proxies", i, proxy as i64, p));
        }
        if i > 0 && proxy <= proxies[i - 1] {
            return Err(ModelProblem::BadProxyCorrective {
                what: "proxies",
                index: i,
                reason: "is not above the one before (ascending, distinct)",
            });
        }
    }
    Ok(())
}

/// E + 1 CSR offsets from 0, non-decreasing, at most MAX_PROXY_DRIVERS apart.
fn driver_offsets(c: &ProxyCorrectives) -> Check {
    length(
        "proxy corrective driver offsets (E + 1)",
        c.proxies.len() + 1,
        c.driver_offsets.len(),
    )?;
    if c.driver_offsets[0] != 0 {
        return Err(ModelProblem::BadProxyCorrective {
            what: "driver offsets",
            index: 0,
            reason: "is not 0",
        });
    }
    for (i, w) in c.driver_offsets.windows(2).enumerate() {
        if w[1] < w[0] {
            return Err(ModelProblem::BadProxyCorrective {
                what: "driver offsets",
                index: i + 1,
                reason: "is below the one before (offsets are non-decreasing)",
            });
        }
        if (w[1] - w[0]) as usize > MAX_PROXY_DRIVERS {
            return Err(ModelProblem::BadProxyCorrective {
                what: "driver offsets",
                index: i + 1,
                reason: "gives its proxy more than 32 drivers (MAX_PROXY_DRIVERS)",
            });
        }
    }
    Ok(())
}

/// As many drivers as the last offset says; each proxy's bones with a parent, each once.
fn proxy_drivers(c: &ProxyCorrectives, parents: &[i32]) -> Check {
    let (e, j) = (c.proxies.len(), parents.len());
    length(
        "proxy corrective drivers (the last driver offset)",
        c.driver_offsets[e] as usize,
        c.drivers.len(),
    )?;
    for i in 0..e {
        let first = c.driver_offsets[i] as usize;
        let drivers = c.drivers_of(i);
        for (k, &b) in drivers.iter().enumerate() {
            if b as usize >= j {
                return Err(out_of_range(
                    "proxy corrective drivers",
                    first + k,
                    b as i64,
                    j,
                ));
            }
            let bad = |reason| ModelProblem::BadProxyDriver {
                proxy: c.proxies[i],
                index: k,
                bone: b,
                reason,
            };
            if parents[b as usize] < 0 {
                return Err(bad(
                    "is a root (a driver's rotation is relative to its parent)",
                ));
            }
            if drivers[..k].contains(&b) {
                return Err(bad("is listed twice"));
            }
        }
    }
    Ok(())
}

/// C, the kernels per joint: C x J finite centres (C ≤ MAX_PROXY_KERNELS), J finite widths
/// when C > 0, > 0 for every driver; the linear features, kernels or both.
fn proxy_kernels(c: &ProxyCorrectives, j: usize) -> Result<usize, ModelProblem> {
    if c.centres.len() % j != 0 {
        return Err(ModelProblem::Length {
            what: "proxy corrective kernel centres (C x J)",
            expected: c.centres.len().div_ceil(j) * j,
            actual: c.centres.len(),
        });
    }
    let kernels = c.centres.len() / j;
    if kernels > MAX_PROXY_KERNELS {
        return Err(ModelProblem::Dimension {
            what: "proxy corrective kernels per joint (C)",
            value: kernels as u64,
            reason: "must be at most 256 (MAX_PROXY_KERNELS)",
        });
    }
    if !c.linear && c.up.is_none() && kernels == 0 {
        return Err(ModelProblem::Dimension {
            what: "proxy corrective features per driver (9 linear + 3 gravity + C)",
            value: 0,
            reason: "needs the linear features, gravity, kernels or some of them",
        });
    }
    length(
        "proxy corrective kernel widths (J, none without kernels)",
        if kernels > 0 { j } else { 0 },
        c.widths.len(),
    )?;
    finite(
        "proxy corrective kernel centres",
        c.centres.iter().flatten(),
    )?;
    finite("proxy corrective kernel widths", c.widths.iter())?;
    if kernels > 0 {
        if let Some(&b) = (c.drivers.iter()).find(|&&b| c.widths[b as usize] <= 0.0) {
            return Err(ModelProblem::BadProxyCorrective {
                what: "widths",
                index: b as usize,
                reason: "is not > 0 (the bone drives a proxy)",
            });
        }
    }
    Ok(kernels)
}

/// N = targets / V in 1..=MAX_CORRECTIVES, the map N x 9D, every number finite, the drivers
/// bones with a parent, each once.
fn correctives(c: &Correctives, parents: &[i32], v: usize) -> Check {
    let j = parents.len();
    let n = c.targets.len() / v;
    if c.targets.len() % v != 0 {
        return Err(ModelProblem::Length {
            what: "corrective targets (targets x vertices)",
            expected: c.targets.len().div_ceil(v) * v,
            actual: c.targets.len(),
        });
    }
    if n == 0 || n > MAX_CORRECTIVES {
        return Err(ModelProblem::Dimension {
            what: "corrective target count (N)",
            value: n as u64,
            reason: "must be 1 to 64 (MAX_CORRECTIVES)",
        });
    }
    dimension("corrective driver count (D)", c.drivers.len(), 1)?;
    if c.drivers.len() >= j {
        return Err(ModelProblem::Dimension {
            what: "corrective driver count (D)",
            value: c.drivers.len() as u64,
            reason: "more drivers than bones with a parent",
        });
    }
    length(
        "corrective map (N x 9D)",
        n * 9 * c.drivers.len(),
        c.map.len(),
    )?;
    finite("corrective map", c.map.iter())?;
    finite("corrective targets", c.targets.iter().flatten())?;
    for (i, &d) in c.drivers.iter().enumerate() {
        if d as usize >= j {
            return Err(out_of_range("corrective drivers", i, d as i64, j));
        }
        if parents[d as usize] < 0 {
            return Err(ModelProblem::BadDriver {
                index: i,
                bone: d,
                reason: "is a root (a driver's rotation is relative to its parent)",
            });
        }
        if c.drivers[..i].contains(&d) {
            return Err(ModelProblem::BadDriver {
                index: i,
                bone: d,
                reason: "is listed twice",
            });
        }
    }
    Ok(())
}

fn predictor(l: usize, pred: &KeyPredictor, j: usize) -> Check {
    if pred.bone as usize >= j {
        return Err(out_of_range("predictor bone", l, pred.bone as i64, j));
    }
    finite("predictor u", [pred.u].iter()).map_err(|_| nonfinite("predictor u", l))?;
    finite("predictor H", pred.h.iter()).map_err(|_| nonfinite("predictor H", l))?;
    rotation("predictor W", l, &pred.w)?;
    if let Some(second) = &pred.second {
        if second.bone as usize >= j {
            return Err(out_of_range(
                "predictor second bone",
                l,
                second.bone as i64,
                j,
            ));
        }
        finite("predictor u2", [second.u].iter()).map_err(|_| nonfinite("predictor u2", l))?;
        rotation("predictor W2", l, &second.w)?;
    }
    Ok(())
}

/// Key l, a delta-mush key: 1 to MAX_DELTA_MUSH_BONES terms of distinct bones, in range,
/// finite.
fn delta_mush_key(l: usize, key: &DeltaMushKey, j: usize) -> Check {
    let bad = |reason: &'static str| ModelProblem::BadKey { key: l, reason };
    let bones: Vec<u32> = key.terms.iter().map(|t| t.bone).collect();
    if bones.is_empty() {
        return Err(bad("is a delta-mush key without a bone"));
    }
    if bones.len() > MAX_DELTA_MUSH_BONES {
        return Err(bad("has more than 256 bones (MAX_DELTA_MUSH_BONES)"));
    }
    if let Some(&b) = bones.iter().find(|&&b| b as usize >= j) {
        return Err(out_of_range("delta-mush key bone", l, b as i64, j));
    }
    if (1..bones.len()).any(|i| bones[..i].contains(&bones[i])) {
        return Err(bad("lists a bone twice"));
    }
    finite("delta-mush terms", key.terms.iter().flat_map(|t| &t.omega))
        .map_err(|_| nonfinite("delta-mush key terms", l))
}

fn dimension(what: &'static str, value: usize, min: usize) -> Check {
    if value < min {
        return Err(ModelProblem::Dimension {
            what,
            value: value as u64,
            reason: "too small",
        });
    }
    if value > MAX_COUNT {
        return Err(ModelProblem::Dimension {
            what,
            value: value as u64,
            reason: "too large",
        });
    }
    Ok(())
}

fn length(what: &'static str, expected: usize, actual: usize) -> Check {
    if expected != actual {
        return Err(ModelProblem::Length {
            what,
            expected,
            actual,
        });
    }
    Ok(())
}

fn finite<'a>(what: &'static str, values: impl Iterator<Item = &'a f32>) -> Check {
    for (index, x) in values.enumerate() {
        if !x.is_finite() {
            return Err(nonfinite(what, index));
        }
    }
    Ok(())
}

fn nonfinite(what: &'static str, index: usize) -> ModelProblem {
    ModelProblem::NonFinite { what, index }
}

fn out_of_range(what: &'static str, index: usize, value: i64, bound: usize) -> ModelProblem {
    ModelProblem::IndexOutOfRange {
        what,
        index,
        value,
        bound,
    }
}

/// Max deviation of `w` from a proper rotation: |WᵀW − I|∞ and |det W − 1|.
pub fn rotation_error(w: &Mat3Rows) -> f32 {
    let m = glam::Mat3::from_cols_array(w).transpose();
    let gram = m.transpose() * m;
    let mut err = (m.determinant() - 1.0).abs();
    for c in 0..3 {
        for r in 0..3 {
            let target = if r == c { 1.0 } else { 0.0 };
            err = err.max((gram.col(c)[r] - target).abs());
        }
    }
    if err.is_finite() {
        err
    } else {
        f32::INFINITY
    }
}

fn rotation(what: &'static str, index: usize, w: &Mat3Rows) -> Check {
    let error = rotation_error(w);
    if error > ROTATION_TOLERANCE {
        return Err(ModelProblem::NotRotation { what, index, error });
    }
    Ok(())
}

/// Every chain of parents must end at a root within J steps.
fn acyclic(parents: &[i32]) -> Check {
    for start in 0..parents.len() {
        let mut b = start;
        for _ in 0..=parents.len() {
            match usize::try_from(parents[b]) {
                Ok(p) => b = p,
                Err(_) => break,
            }
        }
        if parents[b] >= 0 {
            return Err(ModelProblem::ParentCycle { bone: start });
        }
    }
    Ok(())
}
