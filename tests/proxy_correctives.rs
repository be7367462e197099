//! Proxy correctives (docs/method.md §21) in the CPU reference evaluator: a hand-computed case
//! (one vertex on one proxy, one driver, a linear and a kernel feature) matches the formula in
//! the reference and the palette, the reference's correction is an independent reading of the
//! form (features gathered into a vector, `T (I + E)` as 4x4 matrices), for characters of any
//! up where the features see gravity, a zero map changes nothing while the non-zero one does,
//! the correction is exact at the rest pose of an upright character and not of a tilted one, the
//! palette agrees with the reference for tilted characters, and features past a joint's range
//! are clamped into it (a joint whose range is 0 corrects nothing, ranges wider than any pose
//! change nothing).

mod common;

use common::{
    affine, assert_a_zero_map_changes_nothing, cpu_reference, joint_blend_pattern, random_model,
    random_poses, with_proxy_correctives_seeing, with_ranges, Spec,
};
use glam::{DMat4, DVec4};
use rrskin::palette::{Palette, REST};
use rrskin::predict::{apply_proxy_correctives, kernel_feature, rotation_features};
use rrskin::{Error, FeatureRange, Key, KeyPredictor, Model, ModelParts, ProxyCorrectives};

const SPEC: Spec = Spec {
    grid: 8,
    bones: 6,
    proxies: 5,
    influences: 4,
};

fn without(model: &Model) -> Model {
    Model::new(ModelParts {
        proxy_correctives: None,
        ..model.parts().clone()
    })
    .expect("valid")
}

/// The model's up of the models that see gravity: not an axis, so that every component counts.
const UP: [f32; 3] = [0.48, 0.8, 0.36];

/// The three feature kinds, with and without gravity, on a dense and a joint-blend (fused) model,
/// each with feature ranges narrower than the poses'; and one without ranges.
fn models() -> Vec<(String, Model)> {
    let dense = random_model(SPEC, 3);
    let fused = joint_blend_pattern(&random_model(Spec { proxies: 9, ..SPEC }, 4), 1);
    let mut out = Vec::new();
    for (what, base) in [("dense", &dense), ("joint-blend", &fused)] {
        let kinds = [
            (true, None, 0),
            (false, None, 3),
            (true, None, 2),
            (true, Some(UP), 0),
            (false, Some(UP), 2),
        ];
        for (linear, up, kernels) in kinds {
            let seed = 7 + kernels as u64;
            let model = with_proxy_correctives_seeing(base, linear, up, kernels, seed);
            out.push((
                format!("{what}, linear {linear}, up {up:?}, C = {kernels}"),
                model,
            ));
        }
    }
    let unclamped = with_ranges(&out[3].1, None);
    out.push(("dense, gravity, without ranges".into(), unclamped));
    out
}

/// A tilted character's up: the model's up turned by 0.7 rad about x, and 0.9 g.
fn tilted(up: [f32; 3]) -> [f32; 3] {
    let (c, s) = (0.7f32.cos(), 0.7f32.sin());
    [up[0], c * up[1] - s * up[2], s * up[1] + c * up[2]].map(|x| 0.9 * x)
}

/// One vertex on proxy 0, which follows the root (C2 copies bone 0); bone 1 (a child of the
/// root) drives it with its linear features and one kernel. The map's row 1 (φ_1 = R[0][1])
/// is the translation b = (g1, 0, 0), its row 9 (the kernel) A00 = gk: y = Q_0 (x + A x + b) +
/// d_0, worked out by hand.
#[test]
fn one_vertex_one_proxy_and_one_driver_match_the_formula() {
    let (g1, gk) = (0.25f32, -0.5f32);
    let mut maps = vec![0.0f32; 10 * 12];
    maps[12 + 3] = g1;
    maps[9 * 12] = gk;
    let z = [-0.8f32, 0.9, -0.2, -1.0, -0.9, 0.0, 0.0, 0.4, -0.1];
    let mut c2 = vec![0.0f32; 4 * 8];
    for r in 0..4 {
        c2[r * 8 + r] = 1.0;
    }
    let parts = ModelParts {
        rest_positions: vec![[1.0, 2.0, 3.0]],
        triangles: Vec::new(),
        bone_parents: vec![-1, 0],
        influences: 4,
        skin_indices: vec![0, 0, 0, 0],
        skin_weights: vec![1.0, 0.0, 0.0, 0.0],
        keys: vec![Key::Predictor(KeyPredictor {
            bone: 0,
            u: 0.0,
            w: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
            second: None,
            h: [0.0; 63],
        })],
        c1: vec![0.0; 4 * 3],
        c2,
        normal_groups: Vec::new(),
        baseline_indices: Vec::new(),
        baseline_weights: Vec::new(),
        animation: Vec::new(),
        rest_tangents: Vec::new(),
        correctives: None,
        proxy_correctives: Some(ProxyCorrectives {
            linear: true,
            up: None,
            centres: vec![[0.0; 9], z],
            widths: vec![1.0, 0.5],
            ranges: Vec::new(),
            proxies: vec![0],
            driver_offsets: vec![0, 1],
            drivers: vec![1],
            maps,
        }),
    };
    let model = Model::new(parts).expect("valid");
    assert_eq!(model.proxy_corrective_count(), 1);
    // Q_0: 90° about z, d_0 = (1, 0, 0); Q_1 (world): α about x.
    let alpha = 0.3f64;
    let (c, s) = (alpha.cos(), alpha.sin());
    let q0 = [[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]];
    let q1 = [[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]];
    let bones = [affine(q0, [1.0, 0.0, 0.0]), affine(q1, [0.0, 0.5, 0.0])];
    // R = Q_0ᵀ Q_1 has rows (0, c, −s), (−1, 0, 0), (0, s, c).
    let phi = [-1.0, c, -s, -1.0, -1.0, 0.0, 0.0, s, c - 1.0];
    let (d2, r2): (f64, f64) = phi.iter().zip(&z).fold((0.0, 0.0), |(d, r), (&f, &z)| {
        let z = z as f64;
        (d + (f - z) * (f - z), r + z * z)
    });
    let k = (-d2 / 0.5).exp() - (-r2 / 0.5).exp();
    assert!(k.abs() > 0.05, "the kernel is not negligible here: {k}");
    // x + A x + b = (1 + gk k + g1 c, 2, 3); Q_0 u + d_0 = (−u_y + 1, u_x, u_z).
    let want = [-1.0, 1.0 + gk as f64 * k + g1 as f64 * c, 3.0];
    let (p, _) = cpu_reference(&model, &bones);
    let palette = Palette::new(model.clone()).expect("palette");
    let mut entries = [[0.0f32; 12]; 3];
    palette.compute(&bones, &mut entries).expect("palette");
    let mut skinned = [[0.0f32; 3]];
    palette
        .skin_positions(&entries, &[], &mut skinned)
        .expect("skin");
    for (what, got) in [("reference", p[0]), ("palette", skinned[0])] {
        for i in 0..3 {
            assert!(
                (got[i] as f64 - want[i]).abs() < 1e-5,
                "{what}: {got:?} vs {want:?}"
            );
        }
    }
}

/// The reference's correction against the form read independently: the feature vector x of
/// each corrected proxy gathered in order (per driver 9 φ if linear, 3 γ = Q_bᵀ u_c − u if the
/// model has an up, then C kernels, φ and γ clamped into the joint's range first), E = Σ_f x_f
/// G_f as a 4x4 with a zero bottom row, T' = T (I + E) as 4x4 products; the characters upright
/// and tilted.
#[test]
fn the_reference_correction_is_the_stated_form() {
    for (what, model) in models() {
        let c = model.proxy_correctives().expect("proxy correctives");
        let (p, j) = (model.proxy_count(), model.bone_count());
        let kernels = c.centres.len() / j;
        let poses = random_poses(&model, 4, 5);
        for (k, bones) in poses.chunks_exact(j).enumerate() {
            let up = c.up.map(|u| if k % 2 == 1 { tilted(u) } else { u });
            // Any proxies will do: the rows of random 3x4 matrices.
            let t: Vec<[f64; 12]> = (0..p)
                .map(|e| std::array::from_fn(|i| ((e * 12 + i) as f64 * 0.37).sin()))
                .collect();
            let mut corrected = t.clone();
            apply_proxy_correctives(&model, bones, up, &mut corrected).expect("correct");
            for e in 0..p {
                let Some(i) = c.proxies.iter().position(|&x| x as usize == e) else {
                    assert_eq!(corrected[e], t[e], "{what}: proxy {e} is not corrected");
                    continue;
                };
                let mut x = Vec::new();
                for &b in &c.drivers[c.driver_offsets[i] as usize..c.driver_offsets[i + 1] as usize]
                {
                    let b = b as usize;
                    let into_range = |x: f64, k: usize| match c.ranges.get(b) {
                        Some(r) => x.max(r.lower[k].into()).min(r.upper[k].into()),
                        None => x,
                    };
                    let phi = rotation_features(bones, b, model.parent(b).expect("a parent"));
                    let phi: [f64; 9] = std::array::from_fn(|k| into_range(phi[k], k));
                    if c.linear {
                        x.extend(phi);
                    }
                    if let (Some(u), Some(uc)) = (c.up, up) {
                        // (Q_bᵀ u_c)_i = Σ_r Q_b[r][i] u_c[r], Q_b row-major in the transform.
                        let q = &bones[b];
                        x.extend((0..3).map(|i| {
                            let turned: f64 = (0..3)
                                .map(|r| f64::from(q[4 * r + i]) * f64::from(uc[r]))
                                .sum();
                            into_range(turned - f64::from(u[i]), 9 + i)
                        }));
                    }
                    for k in 0..kernels {
                        let z = c.centres[k * j + b].map(f64::from);
                        let w = c.widths[b] as f64;
                        let d2: f64 = (0..9).map(|m| (phi[m] - z[m]).powi(2)).sum();
                        let r2: f64 = z.iter().map(|z| z * z).sum();
                        x.push((-d2 / w).exp() - (-r2 / w).exp());
                        let lib = kernel_feature(&phi, &c.centres[k * j + b], w);
                        assert!((lib - x[x.len() - 1]).abs() < 1e-12, "{what}");
                    }
                }
                let per_driver = 12 * c.features_per_driver(j);
                let map = &c.maps[per_driver * c.driver_offsets[i] as usize..][..12 * x.len()];
                let mut e4 = DMat4::ZERO;
                for (f, &xf) in x.iter().enumerate() {
                    let g = &map[12 * f..12 * f + 12];
                    for r in 0..3 {
                        let row = DVec4::new(
                            g[4 * r] as f64,
                            g[4 * r + 1] as f64,
                            g[4 * r + 2] as f64,
                            g[4 * r + 3] as f64,
                        );
                        // glam is column-major: element (r, col) is col(col)[r].
                        for col in 0..4 {
                            e4.col_mut(col)[r] += xf * row[col];
                        }
                    }
                }
                let mut t4 = DMat4::IDENTITY;
                for r in 0..3 {
                    for col in 0..4 {
                        t4.col_mut(col)[r] = t[e][4 * r + col];
                    }
                }
                let want = t4 * (DMat4::IDENTITY + e4);
                for r in 0..3 {
                    for col in 0..4 {
                        let (a, b) = (corrected[e][4 * r + col], want.col(col)[r]);
                        assert!(
                            (a - b).abs() < 1e-12,
                            "{what}: proxy {e} ({r}, {col}): {a} vs {b}"
                        );
                    }
                    assert!(want.col(3)[3] == 1.0 && want.col(r)[3] == 0.0);
                }
            }
        }
    }
}

#[test]
fn a_zero_map_changes_nothing_and_the_map_does() {
    for (what, corrected) in models() {
        let plain = without(&corrected);
        let mut parts = corrected.parts().clone();
        let c = parts.proxy_correctives.as_mut().expect("proxy correctives");
        c.maps.iter_mut().for_each(|g| *g = 0.0);
        let zero = Model::new(parts).expect("valid");
        let bones = random_poses(&plain, 6, 2);
        assert_a_zero_map_changes_nothing(&plain, &zero, &corrected, &bones, &what);
    }
}

/// At the rest pose of an upright character every feature is zero (φ = 0, γ = 0, and both terms
/// of a kernel are equal), so the corrected proxies are the uncorrected ones exactly, in the
/// reference (f64) and the palette (f32) alike; a tilted character at rest is corrected where
/// the model sees gravity.
#[test]
fn the_correction_is_exact_at_the_rest_pose() {
    for (what, corrected) in models() {
        let plain = without(&corrected);
        let rest = vec![REST; corrected.bone_count()];
        assert_eq!(
            cpu_reference(&corrected, &rest),
            cpu_reference(&plain, &rest),
            "{what}"
        );
        let n = corrected.proxy_count() + corrected.bone_count();
        let (mut a, mut b) = (vec![[0.0; 12]; n], vec![[0.0; 12]; n]);
        Palette::new(corrected.clone())
            .expect("palette")
            .compute(&rest, &mut a)
            .expect("palette");
        Palette::new(plain)
            .expect("palette")
            .compute(&rest, &mut b)
            .expect("palette");
        assert_eq!(a, b, "{what}");
        let c = corrected.proxy_correctives().expect("proxy correctives");
        if let Some(u) = c.up {
            let palette = Palette::new(corrected.clone()).expect("palette");
            palette
                .compute_batch_with_ups(&rest, &[tilted(u)], &mut a)
                .expect("palette");
            assert_ne!(a, b, "{what}: a tilted character at rest");
        }
        let j = corrected.bone_count();
        for b in 0..j {
            let phi = rotation_features(&rest, b, corrected.parent(b).unwrap_or(b));
            assert_eq!(phi, [0.0; 9]);
            for z in c.centres.iter().skip(b).step_by(j) {
                assert_eq!(kernel_feature(&phi, z, 2.0), 0.0, "{what}");
            }
        }
    }
}

#[test]
fn wrong_lengths_are_errors() {
    let (_, model) = models().swap_remove(0);
    let bones = random_poses(&model, 1, 1);
    let mut proxies = vec![[0.0f64; 12]; model.proxy_count()];
    apply_proxy_correctives(&model, &bones, None, &mut proxies).expect("the right lengths");
    let mut short = vec![[0.0f64; 12]; model.proxy_count() - 1];
    assert!(matches!(
        apply_proxy_correctives(&model, &bones, None, &mut short),
        Err(Error::WrongLength {
            what: "proxy transforms",
            ..
        })
    ));
    assert!(matches!(
        apply_proxy_correctives(&model, &bones[1..], None, &mut proxies),
        Err(Error::WrongLength {
            what: "bone transforms",
            ..
        })
    ));
}

/// Tilted characters: the palette (f32, `compute_batch_with_ups`, and threaded) skins as the
/// reference (f64, `CpuEvaluator::set_ups`) does, the ups change the mesh of a model that sees
/// gravity and nothing of one that does not; ups of the wrong count or not finite are errors.
#[test]
fn the_palette_and_the_reference_agree_on_tilted_characters() {
    for (what, model) in models() {
        let (j, v, n) = (
            model.bone_count(),
            model.vertex_count(),
            model.proxy_count(),
        );
        let bones = random_poses(&model, 3, 11);
        let up = model.up().unwrap_or([0.0, 1.0, 0.0]);
        let ups = [up, tilted(up), [0.0; 3]];
        let mut cpu = rrskin::cpu::CpuEvaluator::new(&model);
        cpu.set_ups(&ups).expect("finite");
        let (mut want, mut normals) = (vec![[0.0f32; 3]; 3 * v], vec![[0.0f32; 3]; 3 * v]);
        cpu.evaluate(&bones, &mut want, &mut normals)
            .expect("reference");
        let palette = Palette::new(model.clone()).expect("palette");
        let mut entries = vec![[0.0f32; 12]; 3 * (n + j)];
        let mut threaded = entries.clone();
        palette
            .compute_batch_with_ups(&bones, &ups, &mut entries)
            .expect("palette");
        palette
            .compute_batch_parallel(&bones, &ups, &mut threaded, 3)
            .expect("palette");
        assert_eq!(entries, threaded, "{what}");
        let mut got = vec![[0.0f32; 3]; v];
        for (ch, palette_entries) in entries.chunks_exact(n + j).enumerate() {
            palette
                .skin_positions(palette_entries, &[], &mut got)
                .expect("skin");
            for (a, b) in got.iter().zip(&want[ch * v..(ch + 1) * v]) {
                let d = (0..3).map(|i| (a[i] - b[i]).abs()).fold(0.0, f32::max);
                assert!(d < 1e-4, "{what}, character {ch}: {a:?} vs {b:?}");
            }
        }
        let (upright, _) = cpu_reference(&model, &bones);
        let moved = (upright.iter().zip(&want))
            .skip(v)
            .map(|(a, b)| (0..3).map(|i| (a[i] - b[i]).abs()).fold(0.0, f32::max))
            .fold(0.0, f32::max);
        match model.up() {
            Some(_) => assert!(moved > 1e-4, "{what}: tilting moved {moved}"),
            None => assert_eq!(moved, 0.0, "{what}"),
        }
        assert!(matches!(
            palette.compute_batch_with_ups(&bones, &ups[..2], &mut entries),
            Err(Error::WrongLength { .. })
        ));
        assert!(matches!(
            cpu.set_ups(&[[0.0, f32::NAN, 1.0]]),
            Err(Error::NonFinite { index: 1, .. })
        ));
    }
}

/// Clamping: ranges of 0 (a joint that never moved in the training poses) correct nothing in any
/// pose; ranges wider than any pose correct as no ranges do; the models' narrow ranges change
/// the correction of random poses. In the reference and the palette alike.
#[test]
fn features_past_their_range_are_clamped_into_it() {
    let zero = FeatureRange {
        lower: [0.0; 12],
        upper: [0.0; 12],
    };
    let wide = FeatureRange {
        lower: [-1e30; 12],
        upper: [1e30; 12],
    };
    let meshes = |model: &Model, bones: &[rrskin::predict::Affine]| {
        let (p, j, v) = (
            model.proxy_count(),
            model.bone_count(),
            model.vertex_count(),
        );
        let palette = Palette::new(model.clone()).expect("palette");
        let mut entries = vec![[0.0f32; 12]; p + j];
        let mut skinned = vec![[0.0f32; 3]; v];
        let mut out: Vec<[f32; 3]> = Vec::new();
        for q in bones.chunks_exact(j) {
            palette.compute(q, &mut entries).expect("palette");
            palette
                .skin_positions(&entries, &[], &mut skinned)
                .expect("skin");
            out.extend(&skinned);
        }
        (cpu_reference(model, bones).0, out)
    };
    for (what, model) in models() {
        let bones = random_poses(&model, 4, 9);
        let plain = meshes(&without(&model), &bones);
        let unclamped = meshes(&with_ranges(&model, None), &bones);
        assert_eq!(
            meshes(&with_ranges(&model, Some(zero)), &bones),
            plain,
            "{what}"
        );
        assert_eq!(
            meshes(&with_ranges(&model, Some(wide)), &bones),
            unclamped,
            "{what}"
        );
        if !model
            .proxy_correctives()
            .expect("correctives")
            .ranges
            .is_empty()
        {
            assert_ne!(
                meshes(&model, &bones),
                unclamped,
                "{what}: the ranges clamp"
            );
        }
    }
}
