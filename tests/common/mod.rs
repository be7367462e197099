//! Test support: random valid models and poses (deterministic), a validated Vulkan context,
//! and the comparison of GPU outputs with the CPU reference evaluator.
#![allow(dead_code)] // each test binary uses a different subset

use glam::{DMat3, DVec3};
use rrskin::predict::{exp_rotation, Affine};
use rrskin::vk::{Context, ContextDesc};
use rrskin::{KeyPredictor, Model, ModelParts, SecondBone};

/// xorshift64*: deterministic, no dependency.
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Rng {
        Rng(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1)
    }
    pub fn next_u64(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
    /// Uniform in [0, 1).
    pub fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.unit()
    }
    pub fn below(&mut self, n: usize) -> usize {
        (self.next_u64() % n as u64) as usize
    }
    pub fn vec3(&mut self, scale: f64) -> DVec3 {
        DVec3::new(self.range(-scale, scale), self.range(-scale, scale), self.range(-scale, scale))
    }
    /// A rotation of angle at most `max_angle`.
    pub fn rotation(&mut self, max_angle: f64) -> DMat3 {
        let axis = loop {
            let v = self.vec3(1.0);
            if v.length() > 0.1 {
                break v.normalize();
            }
        };
        exp_rotation(axis * self.range(0.0, max_angle))
    }
}

pub fn rows(m: DMat3) -> [f32; 9] {
    m.transpose().to_cols_array().map(|x| x as f32)
}

/// What to generate.
#[derive(Clone, Copy)]
pub struct Spec {
    pub grid: usize, // vertices = grid x grid
    pub bones: usize,
    pub proxies: usize,
    pub influences: u32,
}

/// A random valid model: a bumpy grid mesh, a random bone tree, spatially smooth skinning
/// weights (so the deformed mesh stays well-conditioned and its normals comparable), proxies
/// that follow a bone (C2) plus a small key-gradient correction (C1), and predictors with
/// random bones, scales, rotations, second bones and scale/shear matrices.
pub fn random_model(spec: Spec, seed: u64) -> Model {
    let mut rng = Rng::new(seed);
    let (n, j, p) = (spec.grid, spec.bones, spec.proxies);
    let k = spec.influences as usize;
    let mut rest = Vec::with_capacity(n * n);
    for y in 0..n {
        for x in 0..n {
            let (u, v) = (x as f64 / (n - 1) as f64, y as f64 / (n - 1) as f64);
            rest.push([u as f32, v as f32, (0.1 * (6.0 * u).sin() * (4.0 * v).cos()) as f32]);
        }
    }
    let mut triangles = Vec::new();
    for y in 0..n - 1 {
        for x in 0..n - 1 {
            let a = (y * n + x) as u32;
            let (b, c, d) = (a + 1, a + n as u32, a + n as u32 + 1);
            triangles.push([a, b, d]);
            triangles.push([a, d, c]);
        }
    }
    let bone_parents: Vec<i32> =
        (0..j).map(|b| if b == 0 { -1 } else { rng.below(b) as i32 }).collect();
    // Palette entries live at random centres; weights fall off with distance.
    let entries = p + j;
    let centres: Vec<[f64; 2]> = (0..entries).map(|_| [rng.unit(), rng.unit()]).collect();
    let mut skin_indices = Vec::with_capacity(n * n * k);
    let mut skin_weights = Vec::with_capacity(n * n * k);
    for r in &rest {
        let mut by_distance: Vec<(f64, usize)> = centres
            .iter()
            .enumerate()
            .map(|(i, c)| ((c[0] - r[0] as f64).powi(2) + (c[1] - r[1] as f64).powi(2), i))
            .collect();
        by_distance.sort_by(|a, b| a.0.total_cmp(&b.0));
        let used = k.min(entries);
        let raw: Vec<f64> = by_distance[..used].iter().map(|(d2, _)| 1.0 / (d2 + 0.02)).collect();
        let total: f64 = raw.iter().sum();
        for i in 0..k {
            if i < used {
                skin_indices.push(by_distance[i].1 as u32);
                skin_weights.push((raw[i] / total) as f32);
            } else {
                skin_indices.push(0);
                skin_weights.push(0.0);
            }
        }
    }
    let predictors: Vec<KeyPredictor> = (0..p)
        .map(|_| {
            let mut h = [0.0f32; 63];
            for (i, x) in h.iter_mut().enumerate() {
                *x = rng.range(-0.1, 0.1) as f32;
                if i % 7 == 6 && [0, 4, 8].contains(&(i / 7)) {
                    *x += 1.0; // bias column ≈ vec(I)
                }
            }
            let second = (rng.unit() < 0.5).then(|| SecondBone {
                bone: rng.below(j) as u32,
                u: rng.range(-1.0, 1.0) as f32,
                w: rows(rng.rotation(3.0)),
            });
            KeyPredictor {
                bone: rng.below(j) as u32,
                u: rng.range(-1.5, 1.5) as f32,
                w: rows(rng.rotation(3.0)),
                second,
                h,
            }
        })
        .collect();
    let mut c1 = vec![0.0f32; 4 * p * 3 * p];
    for x in c1.iter_mut() {
        *x = rng.range(-0.05, 0.05) as f32;
    }
    let mut c2 = vec![0.0f32; 4 * p * 4 * j];
    for b in 0..p {
        let follow = rng.below(j);
        for r in 0..4 {
            c2[(4 * b + r) * 4 * j + 4 * follow + r] = 1.0;
        }
    }
    let parts = ModelParts {
        rest_positions: rest,
        triangles,
        bone_parents,
        influences: spec.influences,
        skin_indices,
        skin_weights,
        predictors,
        c1,
        c2,
    };
    Model::new(parts).expect("the generator makes valid models")
}

/// C random poses: per bone a local rotation of at most 2 rad (joint rotations stay away from
/// the log's branch cut at π) composed down the hierarchy, and a random translation.
pub fn random_poses(model: &Model, characters: usize, seed: u64) -> Vec<Affine> {
    let mut rng = Rng::new(seed ^ 0xB0E5);
    let j = model.bone_count();
    let mut out = Vec::with_capacity(characters * j);
    for _ in 0..characters {
        let mut world: Vec<DMat3> = Vec::with_capacity(j);
        for b in 0..j {
            let local = rng.rotation(2.0);
            // The generator's parents precede their children.
            let q = match model.parent(b) {
                Some(p) => world[p] * local,
                None => local,
            };
            world.push(q);
            let d = rng.vec3(0.5);
            let r = rows(q);
            out.push([
                r[0], r[1], r[2], d.x as f32, r[3], r[4], r[5], d.y as f32, r[6], r[7], r[8], d.z as f32,
            ]);
        }
    }
    out
}

/// A headless context on the default device with validation + synchronization validation.
pub fn validated_context() -> Context {
    Context::headless(&ContextDesc { validation: true, ..Default::default() })
        .expect("a Vulkan device with the validation layer (lavapipe in CI)")
}

pub fn assert_no_validation_messages(ctx: &Context) {
    let messages = ctx.validation_messages();
    assert!(messages.is_empty(), "{} validation messages:\n{}", messages.len(), messages.join("\n"));
}

/// Tolerances of GPU (f32) against the CPU reference (f64): positions within
/// `POSITION_TOLERANCE * max(1, |p|)`; unit normals within `NORMAL_TOLERANCE`, at vertices whose
/// unnormalised normal is not near zero (there the direction is ill-conditioned in f32).
pub const POSITION_TOLERANCE: f32 = 2e-4;
pub const NORMAL_TOLERANCE: f32 = 2e-3;

pub fn compare(
    model: &Model,
    cpu: (&[[f32; 3]], &[[f32; 3]]),
    gpu: (&[[f32; 3]], &[[f32; 3]]),
) {
    assert_eq!(cpu.0.len(), gpu.0.len());
    assert_eq!(cpu.1.len(), gpu.1.len());
    let mut worst = (0.0f32, 0usize);
    for (i, (c, g)) in cpu.0.iter().zip(gpu.0).enumerate() {
        let err = dist(c, g) / norm(c).max(1.0);
        if err > worst.0 || err.is_nan() {
            worst = (err, i);
        }
    }
    assert!(
        worst.0 <= POSITION_TOLERANCE,
        "position {} differs by {} (relative): cpu {:?} gpu {:?}",
        worst.1,
        worst.0,
        cpu.0[worst.1],
        gpu.0[worst.1]
    );
    let v = model.vertex_count();
    let (offsets, incident) = model.incidence();
    let tris = &model.parts().triangles;
    let (mut skipped, mut worst) = (0usize, (0.0f32, 0usize));
    for (i, (c, g)) in cpu.1.iter().zip(gpu.1).enumerate() {
        let (base, a) = (i / v * v, i % v);
        let p = |x: u32| DVec3::from(cpu.0[base + x as usize].map(f64::from));
        let mut sum = DVec3::ZERO;
        let mut area = 0.0;
        for &t in &incident[offsets[a] as usize..offsets[a + 1] as usize] {
            let [x, y, z] = tris[t as usize];
            let cross = (p(y) - p(x)).cross(p(z) - p(x));
            sum += cross;
            area += cross.length();
        }
        if sum.length() < 0.05 * area {
            skipped += 1;
            continue;
        }
        let err = dist(c, g);
        if err > worst.0 || err.is_nan() {
            worst = (err, i);
        }
    }
    assert!(
        worst.0 <= NORMAL_TOLERANCE,
        "normal {} differs by {}: cpu {:?} gpu {:?}",
        worst.1,
        worst.0,
        cpu.1[worst.1],
        gpu.1[worst.1]
    );
    assert!(skipped * 100 <= cpu.1.len(), "{skipped} of {} normals ill-conditioned", cpu.1.len());
}

fn dist(a: &[f32; 3], b: &[f32; 3]) -> f32 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

fn norm(a: &[f32; 3]) -> f32 {
    (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt()
}
