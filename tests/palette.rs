//! The CPU palette (`rrskin::palette`, and its C ABI in-process) against the f64 CPU reference
//! evaluator: positions skinned from the f32 palette within `PALETTE_TOLERANCE * max(1, |p|)`
//! of `CpuEvaluator`'s, on dense, block-sparse (joint-blend pattern), plain-LBS and K = 8
//! models, with and without delta-mush keys, pose-space and proxy correctives; the serial, batched and threaded
//! forms agree bit for bit; bad input is an error.

mod common;

use common::{
    joint_blend_pattern, random_model, random_poses, with_correctives, with_delta_mush_keys,
    with_proxy_correctives, Spec,
};
use rrskin::cpu::CpuEvaluator;
use rrskin::palette::{Palette, REST};
use rrskin::predict::Affine;
use rrskin::{Error, Model, NormalMode};
use rrskin_render::synthetic::{palette_error, PALETTE_TOLERANCE};

fn models() -> Vec<(&'static str, Model)> {
    let spec = |grid, bones, proxies, influences| Spec {
        grid,
        bones,
        proxies,
        influences,
    };
    vec![
        ("dense", random_model(spec(9, 6, 5, 4), 1)),
        ("dense K = 8", random_model(spec(10, 9, 7, 8), 2)),
        ("plain LBS", random_model(spec(7, 4, 0, 4), 3)),
        (
            "one key per proxy",
            joint_blend_pattern(&random_model(spec(9, 7, 12, 4), 4), 1),
        ),
        (
            "two keys per proxy",
            joint_blend_pattern(&random_model(spec(9, 7, 12, 8), 5), 2),
        ),
        (
            "delta-mush keys after predictors' keys",
            with_delta_mush(random_model(spec(9, 7, 8, 4), 6), 5),
        ),
        (
            "delta-mush keys only, one per proxy",
            joint_blend_pattern(&with_delta_mush(random_model(spec(9, 7, 12, 8), 7), 12), 1),
        ),
    ]
}

/// `model` with its last `keys` keys delta-mush keys.
fn with_delta_mush(model: Model, keys: usize) -> Model {
    with_delta_mush_keys(&model, keys, 3).expect("no more delta-mush keys than keys")
}

/// Positions skinned from the palette within the tolerance of the reference's, and the
/// palette's last J entries the bones themselves.
fn assert_matches_reference(model: &Model, bones: &[Affine], what: &str) {
    let worst = palette_error(model, bones).expect("a palette of a valid model");
    eprintln!("{what}: worst relative position error {worst:.2e}");
    assert!(
        worst <= PALETTE_TOLERANCE,
        "{what}: positions from the palette differ by {worst} (relative) from the reference"
    );
    let palette = Palette::new(model.clone()).expect("palette");
    let (j, n) = (model.bone_count(), palette.len());
    let mut out = vec![[0.0; 12]; n];
    palette.compute(&bones[..j], &mut out).expect("palette");
    assert_eq!(&out[n - j..], &bones[..j], "{what}: bones");
}

#[test]
fn positions_from_the_palette_match_the_reference() {
    for (what, model) in models() {
        assert_matches_reference(&model, &random_poses(&model, 16, 7), what);
    }
}

#[test]
fn serial_batched_and_threaded_palettes_agree_exactly() {
    let (_, model) = models().swap_remove(1);
    let palette = Palette::new(model.clone()).expect("palette");
    let (j, n, characters) = (model.bone_count(), palette.len(), 37);
    let bones = random_poses(&model, characters, 11);
    let mut one_by_one = vec![[0.0; 12]; characters * n];
    for (q, out) in bones.chunks_exact(j).zip(one_by_one.chunks_exact_mut(n)) {
        palette.compute(q, out).expect("one character");
    }
    for threads in [1, 3, 0, 64] {
        let mut batch = vec![[0.0; 12]; characters * n];
        palette
            .compute_batch_parallel(&bones, &[], &mut batch, threads)
            .expect("batch");
        assert!(batch == one_by_one, "{threads} threads");
    }
    // Threads sharing one palette, each on its own characters (an engine's job system).
    let mut shared = vec![[0.0; 12]; characters * n];
    std::thread::scope(|s| {
        for (q, out) in bones.chunks(10 * j).zip(shared.chunks_mut(10 * n)) {
            let palette = &palette;
            s.spawn(move || palette.compute_batch(q, out).expect("worker"));
        }
    });
    assert!(shared == one_by_one);
}

#[test]
fn the_rest_pose_gives_the_rest_mesh_and_the_runtimes_normals() {
    let (_, model) = models().swap_remove(0);
    let palette = Palette::new(model.clone()).expect("palette");
    let v = model.vertex_count();
    let skin = palette.skin();
    assert_eq!(skin.rest_normals, &model.rest_normals()[..]);
    assert_eq!(skin.rest_positions, &model.parts().rest_positions[..]);
    assert_eq!(
        skin.rest_tangents.len(),
        v,
        "synthetic models carry tangents"
    );
    assert_eq!(skin.indices.len(), v * skin.influences);
}

#[test]
fn bad_input_is_an_error() {
    let (_, model) = models().swap_remove(0);
    let palette = Palette::new(model.clone()).expect("palette");
    let (j, n) = (model.bone_count(), palette.len());
    let mut bones = random_poses(&model, 2, 1);
    let mut out = vec![[0.0; 12]; 2 * n];
    let short = palette.compute_batch(&bones[..j + 1], &mut out);
    assert!(matches!(short, Err(Error::WrongLength { .. })), "{short:?}");
    let small = palette.compute_batch(&bones, &mut out[..n]);
    assert!(matches!(small, Err(Error::WrongLength { .. })), "{small:?}");
    bones[j + 2][5] = f32::NAN;
    let nan = palette.compute_batch(&bones, &mut out);
    assert!(
        matches!(nan, Err(Error::NonFinite { index, .. }) if index == (j + 2) * 12 + 5),
        "{nan:?}"
    );
}

#[test]
fn the_c_abi_palette_matches_the_rust_one() {
    use rrskin::ffi::*;
    let (_, model) = models().swap_remove(3);
    let bytes = model.to_bytes();
    let palette = Palette::new(model.clone()).expect("palette");
    let (j, n, characters) = (model.bone_count(), palette.len(), 9usize);
    let bones = random_poses(&model, characters, 2);
    let mut want = vec![[0.0; 12]; characters * n];
    palette.compute_batch(&bones, &mut want).expect("palette");

    let ok = RrskinStatus::Ok;
    let mut m = RrskinPaletteModel { id: 0 };
    // SAFETY: valid pointers and lengths (so in every call below).
    unsafe {
        assert_eq!(
            rrskin_palette_model_load_memory(bytes.as_ptr(), bytes.len(), &mut m),
            ok
        );
        let mut skin = std::mem::zeroed::<RrskinPaletteSkin>();
        assert_eq!(rrskin_palette_model_get_skin(m, &mut skin), ok);
        assert_eq!(
            (
                skin.vertices,
                skin.bones,
                skin.palette_entries,
                skin.influences
            ),
            (
                model.vertex_count() as u32,
                j as u32,
                n as u32,
                model.influences() as u32
            )
        );
        let k = model.influences() * model.vertex_count();
        assert_eq!(
            std::slice::from_raw_parts(skin.joints, k),
            &model.parts().skin_indices[..]
        );
        assert!(!skin.rest_tangents.is_null());
        let floats = bones.as_flattened();
        for threads in [None, Some(2)] {
            let mut got = vec![0.0f32; characters * n * 12];
            let status = match threads {
                None => rrskin_palette_compute(
                    m,
                    floats.as_ptr(),
                    floats.len(),
                    got.as_mut_ptr(),
                    got.len(),
                ),
                Some(t) => rrskin_palette_compute_parallel(
                    m,
                    floats.as_ptr(),
                    floats.len(),
                    got.as_mut_ptr(),
                    got.len(),
                    t,
                ),
            };
            assert_eq!(status, ok);
            assert!(got == want.as_flattened(), "{threads:?} threads");
        }
        let mut got = vec![0.0f32; n * 12];
        let wrong = rrskin_palette_compute(m, floats.as_ptr(), 13, got.as_mut_ptr(), got.len());
        assert_eq!(wrong, RrskinStatus::ErrorWrongLength);
        let message = std::ffi::CStr::from_ptr(rrskin_last_error()).to_string_lossy();
        assert!(message.contains("bone floats"), "{message}");
        let never = rrskin_palette_compute(
            RrskinPaletteModel { id: 0 },
            floats.as_ptr(),
            j * 12,
            got.as_mut_ptr(),
            got.len(),
        );
        assert_eq!(never, RrskinStatus::ErrorInvalidHandle);
        assert_eq!(
            rrskin_palette_compute(m, floats.as_ptr(), j * 12, got.as_mut_ptr(), got.len()),
            ok
        );
        assert_eq!(
            std::ffi::CStr::from_ptr(rrskin_last_error()).to_bytes(),
            b"",
            "a success clears the message"
        );
        let mut bad = RrskinPaletteModel { id: 0 };
        assert_eq!(
            rrskin_palette_model_load_memory(bytes.as_ptr(), 20, &mut bad),
            RrskinStatus::ErrorBadModel
        );
        assert_eq!(bad.id, 0);
        assert_eq!(rrskin_palette_model_destroy(m), ok);
        // A stale handle is a status: destroyed twice, used after destroy.
        let stale = RrskinStatus::ErrorInvalidHandle;
        assert_eq!(rrskin_palette_model_destroy(m), stale);
        let after = rrskin_palette_compute(m, floats.as_ptr(), j * 12, got.as_mut_ptr(), got.len());
        assert_eq!(after, stale);
        assert_eq!(rrskin_palette_model_get_skin(m, &mut skin), stale);
    }
}

/// Positions skinned from the palette and the corrective weights (as an engine's shader does)
/// against the reference's, worst relative error over C characters.
fn corrected_error(model: &Model, bones: &[Affine]) -> f32 {
    let palette = Palette::new(model.clone()).expect("palette");
    let (v, j, n, c) = (
        model.vertex_count(),
        model.bone_count(),
        palette.len(),
        palette.corrective_count(),
    );
    let characters = bones.len() / j;
    let mut entries = vec![[0.0; 12]; characters * n];
    palette.compute_batch(bones, &mut entries).expect("palette");
    let mut weights = vec![0.0; characters * c];
    palette
        .corrective_weights_batch(bones, &mut weights)
        .expect("weights");
    let (mut want, mut normals) = (
        vec![[0.0; 3]; characters * v],
        vec![[0.0; 3]; characters * v],
    );
    CpuEvaluator::new(model)
        .evaluate(bones, &mut want, &mut normals)
        .expect("reference");
    let mut got = vec![[0.0; 3]; v];
    let mut worst = 0.0f32;
    for ch in 0..characters {
        palette
            .skin_positions(
                &entries[ch * n..(ch + 1) * n],
                &weights[ch * c..(ch + 1) * c],
                &mut got,
            )
            .expect("skin");
        for (g, w) in got.iter().zip(&want[ch * v..(ch + 1) * v]) {
            let d = (0..3).map(|i| (g[i] - w[i]).powi(2)).sum::<f32>().sqrt();
            let size = (0..3).map(|i| w[i] * w[i]).sum::<f32>().sqrt().max(1.0);
            worst = worst.max(d / size);
        }
    }
    worst
}

#[test]
fn correctives_through_the_palette_match_the_reference() {
    for (what, model) in models() {
        let corrected = with_correctives(&model, 6, 3);
        let bones = random_poses(&corrected, 16, 8);
        let worst = corrected_error(&corrected, &bones);
        eprintln!("{what} with correctives: worst relative position error {worst:.2e}");
        assert!(worst <= PALETTE_TOLERANCE, "{what}: {worst}");
        // The f32 weights are the f64 reference's.
        let palette = Palette::new(corrected.clone()).expect("palette");
        let j = corrected.bone_count();
        let mut w32 = vec![0.0f32; 6];
        let mut w64 = vec![0.0f64; 6];
        for q in bones.chunks_exact(j) {
            palette.corrective_weights(q, &mut w32).expect("weights");
            rrskin::predict::corrective_weights(&corrected, q, &mut w64).expect("reference");
            for (a, b) in w32.iter().zip(&w64) {
                assert!((*a as f64 - b).abs() <= 1e-5, "{what}: {a} vs {b}");
            }
        }
        // With zero weights, the skin is that of the model without correctives.
        let plain = Palette::new(model.clone()).expect("palette");
        let mut entries = vec![[0.0; 12]; palette.len()];
        palette.compute(&bones[..j], &mut entries).expect("palette");
        let v = model.vertex_count();
        let (mut a, mut b) = (vec![[0.0; 3]; v], vec![[0.0; 3]; v]);
        palette
            .skin_positions(&entries, &[0.0; 6], &mut a)
            .expect("skin");
        plain.skin_positions(&entries, &[], &mut b).expect("skin");
        assert_eq!(a, b, "{what}");
    }
}

#[test]
fn corrective_weights_batched_and_one_by_one_agree_and_check_their_input() {
    let (_, model) = models().swap_remove(0);
    let model = with_correctives(&model, 5, 4);
    let palette = Palette::new(model.clone()).expect("palette");
    let (j, n, characters) = (model.bone_count(), palette.corrective_count(), 11);
    assert_eq!(n, 5);
    let skin = palette.skin();
    assert_eq!(skin.correctives, 5);
    assert_eq!(skin.corrective_targets.len(), 5 * model.vertex_count());
    let mut bones = random_poses(&model, characters, 3);
    let mut batch = vec![0.0; characters * n];
    palette
        .corrective_weights_batch(&bones, &mut batch)
        .expect("batch");
    for (q, w) in bones.chunks_exact(j).zip(batch.chunks_exact(n)) {
        let mut one = vec![0.0; n];
        palette.corrective_weights(q, &mut one).expect("one");
        assert!(one == w);
    }
    let short = palette.corrective_weights_batch(&bones, &mut batch[1..]);
    assert!(matches!(short, Err(Error::WrongLength { .. })), "{short:?}");
    let partial = palette.corrective_weights(&bones[..j - 1], &mut batch[..n]);
    assert!(
        matches!(partial, Err(Error::WrongLength { .. })),
        "{partial:?}"
    );
    bones[j + 1][2] = f32::INFINITY;
    let inf = palette.corrective_weights_batch(&bones, &mut batch);
    assert!(matches!(inf, Err(Error::NonFinite { .. })), "{inf:?}");
    let mut entries = vec![[0.0; 12]; palette.len()];
    palette.compute(&bones[..j], &mut entries).expect("palette");
    let mut got = vec![[0.0; 3]; model.vertex_count()];
    let wrong = palette.skin_positions(&entries, &batch[..n - 1], &mut got);
    assert!(matches!(wrong, Err(Error::WrongLength { .. })), "{wrong:?}");
    // A model without correctives has none to compute.
    let (_, plain) = models().swap_remove(0);
    let plain = Palette::new(plain).expect("palette");
    assert_eq!(plain.corrective_count(), 0);
    assert!(plain.skin().corrective_targets.is_empty());
    plain
        .corrective_weights_batch(&bones[..j], &mut [])
        .expect("no weights");
}

#[test]
fn the_c_abi_gives_the_corrective_weights_and_targets() {
    use rrskin::ffi::*;
    let (_, model) = models().swap_remove(3);
    let model = with_correctives(&model, 4, 6);
    let bytes = model.to_bytes();
    let palette = Palette::new(model.clone()).expect("palette");
    let (j, characters) = (model.bone_count(), 5usize);
    let bones = random_poses(&model, characters, 9);
    let mut want = vec![0.0f32; characters * 4];
    palette
        .corrective_weights_batch(&bones, &mut want)
        .expect("weights");
    let ok = RrskinStatus::Ok;
    let floats = bones.as_flattened();
    let mut m = RrskinPaletteModel { id: 0 };
    // SAFETY: valid pointers and lengths (so in every call below).
    unsafe {
        assert_eq!(
            rrskin_palette_model_load_memory(bytes.as_ptr(), bytes.len(), &mut m),
            ok
        );
        let mut n = u32::MAX;
        assert_eq!(rrskin_palette_model_get_corrective_count(m, &mut n), ok);
        assert_eq!(n, 4);
        assert_eq!(
            rrskin_palette_model_get_corrective_count(m, std::ptr::null_mut()),
            RrskinStatus::ErrorNullPointer
        );
        let mut skin = std::mem::zeroed::<RrskinPaletteSkin>();
        assert_eq!(rrskin_palette_model_get_skin(m, &mut skin), ok);
        assert_eq!(skin.correctives, 4);
        let v = model.vertex_count();
        assert_eq!(
            std::slice::from_raw_parts(skin.corrective_targets, 4 * v * 3),
            model
                .correctives()
                .expect("correctives")
                .targets
                .as_flattened()
        );
        let mut got = vec![0.0f32; characters * 4];
        assert_eq!(
            rrskin_palette_compute_corrective_weights(
                m,
                floats.as_ptr(),
                floats.len(),
                got.as_mut_ptr(),
                got.len()
            ),
            ok
        );
        assert!(got == want);
        assert_eq!(
            rrskin_palette_compute_corrective_weights(
                m,
                floats.as_ptr(),
                floats.len(),
                got.as_mut_ptr(),
                got.len() - 1
            ),
            RrskinStatus::ErrorWrongLength
        );
        let message = std::ffi::CStr::from_ptr(rrskin_last_error()).to_string_lossy();
        assert!(message.contains("corrective weights"), "{message}");
        assert_eq!(
            rrskin_palette_compute_corrective_weights(
                m,
                floats.as_ptr(),
                floats.len(),
                std::ptr::null_mut(),
                got.len()
            ),
            RrskinStatus::ErrorNullPointer
        );
        assert_eq!(
            rrskin_palette_compute_corrective_weights(
                RrskinPaletteModel { id: 0 },
                floats.as_ptr(),
                j * 12,
                got.as_mut_ptr(),
                4
            ),
            RrskinStatus::ErrorInvalidHandle
        );
        assert_eq!(rrskin_palette_model_destroy(m), ok);
        // A model without correctives: N = 0, no targets, no floats to write.
        let plain = models().swap_remove(3).1.to_bytes();
        assert_eq!(
            rrskin_palette_model_load_memory(plain.as_ptr(), plain.len(), &mut m),
            ok
        );
        assert_eq!(rrskin_palette_model_get_corrective_count(m, &mut n), ok);
        assert_eq!(n, 0);
        assert_eq!(rrskin_palette_model_get_skin(m, &mut skin), ok);
        assert!(skin.correctives == 0 && skin.corrective_targets.is_null());
        assert_eq!(
            rrskin_palette_compute_corrective_weights(
                m,
                floats.as_ptr(),
                floats.len(),
                std::ptr::null_mut(),
                0
            ),
            ok
        );
        assert_eq!(rrskin_palette_model_destroy(m), ok);
    }
}

/// Proxy correctives (docs/method.md §21) are applied by `Palette::compute` itself: the skin of
/// the f32 palette is the f64 reference's within `PALETTE_TOLERANCE` (relative to max(1, |p|)),
/// for linear features, kernels and both, on every reduced model kind, with pose-space
/// correctives beside them on one; the corrected palette differs from the uncorrected one; the
/// batched, one-by-one and threaded forms agree bit for bit.
#[test]
fn proxy_correctives_through_the_palette_match_the_reference() {
    for (what, model) in models().into_iter().filter(|(_, m)| m.proxy_count() > 0) {
        for (linear, kernels) in [(true, 0), (false, 4), (true, 2)] {
            let corrected = with_proxy_correctives(&model, linear, kernels, 11);
            let what = format!("{what}, linear {linear}, C = {kernels}");
            let bones = random_poses(&corrected, 16, 9);
            let worst = palette_error(&corrected, &bones).expect("palette");
            eprintln!("{what}: worst relative position error {worst:.2e}");
            assert!(worst <= PALETTE_TOLERANCE, "{what}: {worst}");
            let (j, n) = (
                corrected.bone_count(),
                corrected.proxy_count() + corrected.bone_count(),
            );
            let palette = Palette::new(corrected.clone()).expect("palette");
            let plain = Palette::new(model.clone()).expect("palette");
            let (mut a, mut b) = (vec![[0.0; 12]; 16 * n], vec![[0.0; 12]; 16 * n]);
            palette.compute_batch(&bones, &mut a).expect("palette");
            plain.compute_batch(&bones, &mut b).expect("palette");
            assert_ne!(a, b, "{what}: the correction changed nothing");
            for (q, want) in bones.chunks_exact(j).zip(a.chunks_exact(n)) {
                let mut one = vec![[0.0; 12]; n];
                palette.compute(q, &mut one).expect("palette");
                assert_eq!(one, want, "{what}");
            }
            let mut threaded = vec![[0.0; 12]; 16 * n];
            palette
                .compute_batch_parallel(&bones, &[], &mut threaded, 3)
                .expect("palette");
            assert_eq!(threaded, a, "{what}");
        }
    }
    let (what, model) = models().swap_remove(1);
    let both = with_proxy_correctives(&with_correctives(&model, 5, 2), true, 3, 12);
    let worst = corrected_error(&both, &random_poses(&both, 16, 10));
    assert!(
        worst <= PALETTE_TOLERANCE,
        "{what} with both correctives: {worst}"
    );
}

/// `renumber_bones` carries both correctives' drivers and the kernels' per-bone centres and
/// widths: the renumbered model deforms as the original for the same poses renumbered.
#[test]
fn renumbered_bones_keep_both_correctives() {
    let (_, model) = models().swap_remove(1);
    let model = with_proxy_correctives(&with_correctives(&model, 5, 2), true, 3, 12);
    let j = model.bone_count();
    let reversed: Vec<usize> = (0..j).rev().collect();
    let renumbered = rrskin_render::synthetic::renumber_bones(&model, &reversed).expect("valid");
    let bones = random_poses(&model, 4, 13);
    let mut moved = bones.clone();
    for (q, old) in moved.chunks_exact_mut(j).zip(bones.chunks_exact(j)) {
        for (b, t) in old.iter().enumerate() {
            q[reversed[b]] = *t;
        }
    }
    let v = model.vertex_count();
    let (mut a, mut b) = (vec![[0.0; 3]; v], vec![[0.0; 3]; v]);
    let mut n = vec![[0.0; 3]; v];
    let (mut original, mut other) = (CpuEvaluator::new(&model), CpuEvaluator::new(&renumbered));
    for (q, r) in bones.chunks_exact(j).zip(moved.chunks_exact(j)) {
        original.evaluate(q, &mut a, &mut n).expect("evaluates");
        other.evaluate(r, &mut b, &mut n).expect("evaluates");
        let worst = (a.iter().zip(&b))
            .flat_map(|(x, y)| x.iter().zip(y).map(|(x, y)| (x - y).abs()))
            .fold(0.0f32, f32::max);
        assert!(worst <= 1e-5, "renumbered model off by {worst}");
    }
}

/// The normals the palette's documentation gives an engine (the rest normal through the
/// cofactor of the blended 3x3, normalised) are the CPU reference's transformed normals, within
/// the GPU tests' normal tolerance (2e-3), for every kind of model.
#[test]
fn cofactor_normals_from_the_palette_are_the_references_transformed_normals() {
    for (what, model) in models() {
        let palette = Palette::new(model.clone()).expect("palette");
        let (j, v) = (model.bone_count(), model.vertex_count());
        let bones = random_poses(&model, 3, 9);
        let n = 3 * v;
        let (mut p, mut expected) = (vec![[0.0; 3]; n], vec![[0.0; 3]; n]);
        CpuEvaluator::with_normals(&model, NormalMode::Transformed)
            .evaluate(&bones, &mut p, &mut expected)
            .expect("reference");
        let skin = palette.skin();
        let mut entries = vec![REST; palette.len()];
        for ch in 0..3 {
            palette
                .compute(&bones[ch * j..(ch + 1) * j], &mut entries)
                .expect("palette");
            for a in 0..v {
                let m = skin.blended(a, &entries).map(f64::from);
                let rest = glam::DVec3::from(skin.rest_normals[a].map(f64::from));
                let got = rrskin::normals::cofactor_times(&m, rest).normalize_or_zero();
                let want = glam::DVec3::from(expected[ch * v + a].map(f64::from));
                assert!(
                    (got - want).length() < 2e-3,
                    "{what}: character {ch} vertex {a}: {got} vs {want}"
                );
            }
        }
    }
}
