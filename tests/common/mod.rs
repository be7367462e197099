//! Test support: a validated Vulkan context and the comparison of GPU outputs with the CPU reference evaluator.
#![allow(dead_code)] // each test binary uses a different subset

pub mod abi;
pub mod artifacts;
pub mod engine;
pub mod scratch;

#[allow(unused_imports)] // each test binary uses a different subset
pub use artifacts::suite_artifacts;
use glam::DVec3;
use rrskin::vk::{Context, ContextDesc};
use rrskin::Model;
#[allow(unused_imports)] // each test binary uses a different subset
pub use rrskin_render::synthetic::with_delta_mush_keys;
pub use rrskin_render::synthetic::{random_poses, Spec};

pub fn random_model(spec: Spec, seed: u64) -> Model {
    rrskin_render::synthetic::random_model(spec, seed).expect("the generator makes valid models")
}

/// Row-major 3x4 `[Q | d]`, the layout of a bone transform.
pub fn affine(q: [[f64; 3]; 3], d: [f64; 3]) -> rrskin::predict::Affine {
    let mut t = [0.0f32; 12];
    for r in 0..3 {
        for c in 0..3 {
            t[4 * r + c] = q[r][c] as f32;
        }
        t[4 * r + 3] = d[r] as f32;
    }
    t
}

/// Positions and normals of the characters posed by `bones` (J transforms each), by the CPU
/// reference evaluator.
pub fn cpu_reference(
    model: &Model,
    bones: &[rrskin::predict::Affine],
) -> (Vec<[f32; 3]>, Vec<[f32; 3]>) {
    let n = bones.len() / model.bone_count() * model.vertex_count();
    let (mut p, mut nrm) = (vec![[0.0; 3]; n], vec![[0.0; 3]; n]);
    rrskin::cpu::CpuEvaluator::new(model)
        .evaluate(bones, &mut p, &mut nrm)
        .expect("CPU evaluation");
    (p, nrm)
}

/// For a model term with a map (correctives, proxy correctives): `zero`, the model with that map
/// zeroed, poses exactly as `plain` (the model without the term) does, and `corrected` (the map
/// as it is) moves some vertex by more than 1e-3, so that the first comparison is not vacuous.
pub fn assert_a_zero_map_changes_nothing(
    plain: &Model,
    zero: &Model,
    corrected: &Model,
    bones: &[rrskin::predict::Affine],
    what: &str,
) {
    let still = cpu_reference(plain, bones);
    assert_eq!(cpu_reference(zero, bones), still, "{what}");
    let (moved, _) = cpu_reference(corrected, bones);
    let largest = (moved.iter().zip(&still.0))
        .map(|(a, b)| (0..3).map(|i| (a[i] - b[i]).abs()).fold(0.0, f32::max))
        .fold(0.0, f32::max);
    assert!(largest > 1e-3, "{what}: the map moved {largest}");
}

/// A headless context on the default device with validation + synchronization validation.
pub fn validated_context() -> Context {
    Context::new(&ContextDesc {
        validation: true,
        ..Default::default()
    })
    .expect("a Vulkan device with the validation layer (lavapipe in CI)")
}

pub fn assert_no_validation_messages(ctx: &Context) {
    let messages = ctx.validation_messages();
    assert!(
        messages.is_empty(),
        "{} validation messages:\n{}",
        messages.len(),
        messages.join("\n")
    );
}

/// Tolerances of GPU (f32) against the CPU reference (f64): positions within
/// `POSITION_TOLERANCE * max(1, |p|)`; unit normals within `NORMAL_TOLERANCE`, at vertices whose
/// unnormalised normal is not near zero (there the direction is ill-conditioned in f32).
pub const POSITION_TOLERANCE: f32 = 2e-4;
pub const NORMAL_TOLERANCE: f32 = 2e-3;
/// Unit tangents (xyz) within this, at the vertices whose normal is compared; w exactly.
pub const TANGENT_TOLERANCE: f32 = 2e-3;

pub fn compare(model: &Model, cpu: (&[[f32; 3]], &[[f32; 3]]), gpu: (&[[f32; 3]], &[[f32; 3]])) {
    assert_eq!(cpu.0.len(), gpu.0.len());
    assert_eq!(cpu.1.len(), gpu.1.len());
    let errors = cpu
        .0
        .iter()
        .zip(gpu.0)
        .map(|(c, g)| dist(c, g) / norm(c).max(1.0));
    let (i, err) = worst(errors.enumerate());
    assert!(
        err <= POSITION_TOLERANCE,
        "position {i} differs by {err} (relative): cpu {:?} gpu {:?}",
        cpu.0[i],
        gpu.0[i]
    );
    let mut skipped = 0usize;
    let errors = cpu
        .1
        .iter()
        .zip(gpu.1)
        .enumerate()
        .filter_map(|(i, (c, g))| {
            if !well_conditioned(model, cpu.0, i) {
                skipped += 1;
                return None;
            }
            Some((i, dist(c, g)))
        });
    let (i, err) = worst(errors);
    assert!(
        err <= NORMAL_TOLERANCE,
        "normal {i} differs by {err}: cpu {:?} gpu {:?}",
        cpu.1[i],
        gpu.1[i]
    );
    assert!(
        skipped * 100 <= cpu.1.len(),
        "{skipped} of {} normals ill-conditioned",
        cpu.1.len()
    );
}

/// Flat xyz floats (as the C ABI reads them back) as points.
pub fn triples(floats: &[f32]) -> Vec<[f32; 3]> {
    floats.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect()
}

/// Bones (C x J), and the CPU reference's positions and normals (C x V) of them.
pub type CheckablePose = (Vec<rrskin::predict::Affine>, Vec<[f32; 3]>, Vec<[f32; 3]>);

/// `count` sets of random poses of `characters` characters whose CPU normals `compare` can
/// check (at most 1 % ill-conditioned: tiny random meshes fold in some poses), with the CPU
/// reference's positions and normals of each.
pub fn checkable_poses(model: &Model, characters: usize, count: usize) -> Vec<CheckablePose> {
    let n = characters * model.vertex_count();
    let mut cpu = rrskin::cpu::CpuEvaluator::new(model);
    (0..)
        .map(|seed| {
            let poses = random_poses(model, characters, seed);
            let (mut p, mut nrm) = (vec![[0.0; 3]; n], vec![[0.0; 3]; n]);
            cpu.evaluate(&poses, &mut p, &mut nrm)
                .expect("CPU reference");
            (poses, p, nrm)
        })
        .filter(|(_, p, _)| (0..n).filter(|&i| !well_conditioned(model, p, i)).count() * 100 <= n)
        .take(count)
        .collect()
}

/// Whether vertex `i` (of C x V `positions`) has a normal f32 can compute like f64: its
/// triangles' normals do not nearly cancel.
fn well_conditioned(model: &Model, positions: &[[f32; 3]], i: usize) -> bool {
    let v = model.vertex_count();
    let (offsets, incident) = model.incidence();
    let tris = &model.parts().triangles;
    let (base, a) = (i / v * v, i % v);
    let p = |x: u32| DVec3::from(positions[base + x as usize].map(f64::from));
    let (mut sum, mut area) = (DVec3::ZERO, 0.0);
    for &t in &incident[offsets[a] as usize..offsets[a + 1] as usize] {
        let [x, y, z] = tris[t as usize];
        let cross = (p(y) - p(x)).cross(p(z) - p(x));
        sum += cross;
        area += cross.length();
    }
    sum.length() >= 0.05 * area
}

/// GPU tangents against the CPU's (C x V, `cpu_positions` the CPU's positions), where the
/// normal is well-conditioned: xyz within [`TANGENT_TOLERANCE`], unit, orthogonal to the GPU
/// normal; w exactly the CPU's.
pub fn compare_tangents(
    model: &Model,
    cpu_positions: &[[f32; 3]],
    cpu: &[[f32; 4]],
    gpu: (&[[f32; 4]], &[[f32; 3]]),
) {
    let (tangents, normals) = gpu;
    assert_eq!(cpu.len(), tangents.len());
    let mut compared = 0usize;
    for (i, (c, g)) in cpu.iter().zip(tangents).enumerate() {
        assert_eq!(c[3], g[3], "tangent {i}: handedness, cpu {c:?} gpu {g:?}");
        if !well_conditioned(model, cpu_positions, i) {
            continue;
        }
        compared += 1;
        let xyz = |t: &[f32; 4]| [t[0], t[1], t[2]];
        let err = dist(&xyz(c), &xyz(g));
        assert!(
            err <= TANGENT_TOLERANCE,
            "tangent {i} differs by {err}: cpu {c:?} gpu {g:?}"
        );
        let n = normals[i];
        let along = g[0] * n[0] + g[1] * n[1] + g[2] * n[2];
        assert!(
            (norm(&xyz(g)) - 1.0).abs() <= TANGENT_TOLERANCE && along.abs() <= TANGENT_TOLERANCE,
            "tangent {i} {g:?}: not unit or not orthogonal to the normal {n:?}"
        );
    }
    assert!(
        compared * 100 >= 99 * cpu.len(),
        "{compared} of {} tangents compared",
        cpu.len()
    );
}

/// The largest error and its index; NaN counts as worst.
fn worst(errors: impl Iterator<Item = (usize, f32)>) -> (usize, f32) {
    errors.fold(
        (0, 0.0),
        |w, (i, e)| if e > w.1 || e.is_nan() { (i, e) } else { w },
    )
}

fn dist(a: &[f32; 3], b: &[f32; 3]) -> f32 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

fn norm(a: &[f32; 3]) -> f32 {
    (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt()
}

/// `model` with [C1 | C2] cut to the pattern of a joint-blend proxy: proxy e's rows keep the 3
/// columns of C1 of `keys` keys (its own, e, and the next ones mod P; joint-blend proxies read
/// one) and two bones' 4 columns of C2 (e mod J and 2e + 1 mod J).
pub fn joint_blend_pattern(model: &Model, keys: usize) -> Model {
    let (p, j) = (model.proxy_count(), model.bone_count());
    let mut parts = model.parts().clone();
    for r in 0..4 * p {
        let e = r / 4;
        for k in 0..3 * p {
            if (k / 3 + p - e) % p >= keys {
                parts.c1[r * 3 * p + k] = 0.0;
            }
        }
        for k in 0..4 * j {
            if k / 4 != e % j && k / 4 != (2 * e + 1) % j {
                parts.c2[r * 4 * j + k] = 0.0;
            }
        }
    }
    Model::new(parts).expect("the same model with fewer non-zeros")
}

/// `model` with `n` pose-space correctives (paper §8) driven by its first (up to) three bones
/// with a parent: a map with three non-zero entries per target (|m| ≤ 0.5) and smooth
/// rest-space targets of a few hundredths (the synthetic grid is the unit square), seeded.
pub fn with_correctives(model: &Model, n: usize, seed: u64) -> Model {
    let mut state = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
    let mut next = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    let drivers: Vec<u32> = (0..model.bone_count())
        .filter(|&b| model.parent(b).is_some())
        .take(3)
        .map(|b| b as u32)
        .collect();
    let width = 9 * drivers.len();
    let mut map = vec![0.0f32; n * width];
    for t in 0..n {
        for _ in 0..3 {
            let e = (next() * width as f64) as usize;
            map[t * width + e] = (next() - 0.5) as f32;
        }
    }
    let rest = &model.parts().rest_positions;
    let mut targets = Vec::with_capacity(n * rest.len());
    for t in 0..n {
        let (amplitude, phase) = (0.02 + 0.04 * next(), 6.0 * next());
        targets.extend(rest.iter().map(|p| {
            let [x, y, _] = p.map(f64::from);
            [
                amplitude * (3.0 * x + phase).sin(),
                amplitude * (2.0 * y + phase + t as f64).cos(),
                amplitude * (x + y + phase).sin(),
            ]
            .map(|c| c as f32)
        }));
    }
    let parts = rrskin::ModelParts {
        correctives: Some(rrskin::model::Correctives {
            drivers,
            map,
            targets,
        }),
        ..model.parts().clone()
    };
    Model::new(parts).expect("a model with valid correctives")
}

/// `model` (P > 0) with proxy correctives (docs/method.md §21): the proxies e with e % 3 != 1
/// corrected, proxy e by (e + 1) % 4 drivers (so some by none) among the bones with a parent,
/// from the e-th on; `linear` features or not, and `kernels` kernel centres per joint at the φ
/// of random poses (width w_b = 8 for every joint: |φ|² reaches about 6); map entries |g| ≤
/// 0.02 of the linear features and ≤ 0.1 of the kernels (a few percent of the proxies' scale
/// over the tests' random poses); every joint's feature range within ±0.15 to ±0.9, seeded.
pub fn with_proxy_correctives(model: &Model, linear: bool, kernels: usize, seed: u64) -> Model {
    with_proxy_correctives_seeing(model, linear, None, kernels, seed)
}

/// [`with_proxy_correctives`] whose features also see gravity where `up` (the model's up) is
/// given: 3 more features γ_b per driver after the linear ones.
pub fn with_proxy_correctives_seeing(
    model: &Model,
    linear: bool,
    up: Option<[f32; 3]>,
    kernels: usize,
    seed: u64,
) -> Model {
    let mut state = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
    let mut next = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    let (p, j) = (model.proxy_count(), model.bone_count());
    let children: Vec<u32> = (0..j as u32)
        .filter(|&b| model.parent(b as usize).is_some())
        .collect();
    let proxies: Vec<u32> = (0..p as u32).filter(|e| e % 3 != 1).collect();
    let (mut driver_offsets, mut drivers) = (vec![0u32], Vec::new());
    for &e in &proxies {
        let count = ((e as usize + 1) % 4).min(children.len());
        drivers.extend((0..count).map(|k| children[(e as usize + k) % children.len()]));
        driver_offsets.push(drivers.len() as u32);
    }
    let mut centres = Vec::with_capacity(kernels * j);
    for c in 0..kernels {
        let pose = random_poses(model, 1, seed.wrapping_add(1000 + c as u64));
        centres.extend((0..j).map(|b| {
            let parent = model.parent(b).unwrap_or(b);
            rrskin::predict::rotation_features(&pose, b, parent).map(|x| x as f32)
        }));
    }
    let widths = if kernels > 0 {
        vec![8.0; j]
    } else {
        Vec::new()
    };
    let head = 9 * usize::from(linear) + 3 * usize::from(up.is_some());
    let features = head + kernels;
    // Kernel features are smaller than the linear and gravity ones (differences of two
    // exponentials).
    let maps = (0..features * drivers.len())
        .flat_map(|row| {
            let scale = if row % features < head { 0.04 } else { 0.2 };
            (0..12)
                .map(|_| (scale * (next() - 0.5)) as f32)
                .collect::<Vec<_>>()
        })
        .collect();
    // Feature ranges narrower than the random poses' features (|entries| up to about 2), so
    // that most poses are clamped on some entry.
    let ranges = (0..j)
        .map(|_| rrskin::FeatureRange {
            lower: std::array::from_fn(|_| -(0.15 + 0.75 * next()) as f32),
            upper: std::array::from_fn(|_| (0.15 + 0.75 * next()) as f32),
        })
        .collect();
    let parts = rrskin::ModelParts {
        proxy_correctives: Some(rrskin::ProxyCorrectives {
            linear,
            up,
            centres,
            widths,
            ranges,
            proxies,
            driver_offsets,
            drivers,
            maps,
        }),
        ..model.parts().clone()
    };
    Model::new(parts).expect("a model with valid proxy correctives")
}

/// `model` (with proxy correctives) with every joint's feature range replaced by `range` (None:
/// no ranges, as files before version 6 hold them).
pub fn with_ranges(model: &Model, range: Option<rrskin::FeatureRange>) -> Model {
    let mut parts = model.parts().clone();
    let c = parts.proxy_correctives.as_mut().expect("proxy correctives");
    c.ranges = range.map_or_else(Vec::new, |r| vec![r; model.bone_count()]);
    Model::new(parts).expect("valid")
}

/// The first pass of a frame whose GPU buffer disagrees with the CPU reference's intermediates,
/// in pass order: the key predictors (B's rows of D, where pass 1 ran: `fused` false), the
/// product (the palette's proxies; with proxy correctives, as they corrected them), the palette's
/// bone entries; then [`compare`]'s positions and normals. `bones`: C x J. Panics naming the
/// pass, the character and the entry, so that a failing GPU test says where the frame went wrong.
pub fn compare_passes(
    model: &Model,
    bones: &[rrskin::predict::Affine],
    fused: bool,
    gpu: &rrskin::vk::HostIntermediates,
) {
    let (p, j) = (model.proxy_count(), model.bone_count());
    if p == 0 {
        return;
    }
    let mut cpu = rrskin::cpu::CpuEvaluator::new(model);
    let product = if model.proxy_correctives().is_some() {
        "product and proxy correctives (the palette's proxies)"
    } else {
        "product (the palette's proxies)"
    };
    for ch in 0..bones.len() / j {
        let (gradients, palette) = (cpu.intermediates(&bones[ch * j..(ch + 1) * j]))
            .expect("the CPU reference's intermediates");
        if !fused {
            for (l, d) in gradients.iter().enumerate() {
                // B[3l + k][3ch + r] = D_l[r][k]
                let gpu_d =
                    |r: usize, k: usize| gpu.rhs[(ch * (3 * p + 4 * j) + 3 * l + k) * 3 + r];
                let err = (0..9)
                    .map(|i| (gpu_d(i / 3, i % 3) as f64 - d.row(i / 3)[i % 3]).abs())
                    .fold(0.0, f64::max);
                assert!(
                    err <= 1e-4 * d.abs().to_cols_array().iter().fold(1.0, |m, x| x.max(m)),
                    "predictors: key {l} of character {ch} differs by {err}: cpu {d:?}"
                );
            }
        }
        for (e, cpu_t) in palette.iter().enumerate() {
            let gpu_t = gpu.palette[ch * (p + j) + e];
            let scale = cpu_t.iter().fold(1.0f64, |m, x| m.max(x.abs()));
            let err = (cpu_t.iter().zip(gpu_t))
                .map(|(a, b)| (a - b as f64).abs())
                .fold(0.0, f64::max);
            let pass = if e < p {
                product
            } else {
                "palette (the bones' entries)"
            };
            assert!(
                err <= POSITION_TOLERANCE as f64 * scale,
                "{pass}: entry {e} of character {ch} differs by {err}: cpu {cpu_t:?} gpu {gpu_t:?}"
            );
        }
    }
}
