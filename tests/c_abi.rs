//! The C ABI from C: the committed header is what cbindgen generates from src/ffi/, and the
//! C example (examples/c/crowd.c), compiled by the system C compiler against that header and
//! the static library, runs on lavapipe with the validation layer on, checks positions against
//! the Rust CPU evaluator, and checks the bad-input behaviour of the ABI.

mod common;

use common::{
    joint_blend_pattern, random_model, random_poses, with_correctives, with_delta_mush_keys,
    with_proxy_correctives_seeing, Spec,
};
use rrskin::cpu::CpuEvaluator;
use std::path::{Path, PathBuf};
use std::process::Command;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The `//!` lines atop `file` (relative to the crate root), without the marker.
fn module_doc(file: &str) -> Vec<String> {
    let text = std::fs::read_to_string(root().join(file)).expect("a source file");
    let lines = text.lines().map_while(|l| l.strip_prefix("//!"));
    lines
        .map(|l| l.strip_prefix(' ').unwrap_or(l).to_string())
        .collect()
}

/// The header's preamble: the C conventions atop src/ffi/mod.rs, then the contract of src/lib.rs
/// (its `## Contract` section), as one C comment with rustdoc's links and bold as plain text.
fn preamble() -> String {
    let contract = module_doc("src/lib.rs");
    let contract = contract.iter().skip_while(|l| *l != "## Contract");
    let ffi = module_doc("src/ffi/mod.rs");
    let blank = String::new();
    let lines = ffi.iter().chain([&blank]).chain(contract);
    let mut out = String::from("/*\n");
    for line in lines {
        let plain = (line.replace("[`", "`").replace("`]", "`")).replace("**", "");
        assert!(
            !plain.contains("*/"),
            "the preamble would end early: {line}"
        );
        out.push_str(" *");
        if !plain.is_empty() {
            out.push(' ');
            out.push_str(&plain);
        }
        out.push('\n');
    }
    out.push_str(" */");
    out
}

fn generated_header() -> String {
    let mut config =
        cbindgen::Config::from_file(root().join("cbindgen.toml")).expect("cbindgen.toml");
    config.header = Some(preamble());
    let mut out = Vec::new();
    cbindgen::Builder::new()
        .with_crate(root())
        .with_config(config)
        .generate()
        .expect("cbindgen parses src/ffi/")
        .write(&mut out);
    String::from_utf8(out).expect("UTF-8 header")
}

#[test]
fn the_committed_header_is_current() {
    let path = root().join("include/rrskin.h");
    let generated = generated_header();
    if std::env::var_os("RRSKIN_BLESS").is_some() {
        std::fs::write(&path, &generated).expect("write header");
    }
    let committed = std::fs::read_to_string(&path).unwrap_or_default();
    assert!(
        committed == generated,
        "include/rrskin.h is stale: regenerate it with `RRSKIN_BLESS=1 cargo test --test c_abi`"
    );
}

fn write_floats(path: &Path, floats: &[f32]) {
    let bytes: Vec<u8> = floats.iter().flat_map(|x| x.to_le_bytes()).collect();
    std::fs::write(path, bytes).expect("write floats");
}

/// This build's librrskin.a, as `cargo test --workspace` built it.
fn static_library() -> PathBuf {
    let lib = common::suite_artifacts().join("librrskin.a");
    assert!(lib.exists(), "{} was not built", lib.display());
    lib
}

/// Poses of `frames` x `characters` and the CPU reference's positions (and tangents) of them,
/// as the C examples read them (`rrskin reference` writes the same).
fn write_reference(dir: &Path, model: &rrskin::Model, frames: usize, characters: usize) {
    let (mut poses, mut expected, mut tangents) = (Vec::new(), Vec::new(), Vec::new());
    let v = model.vertex_count();
    for frame in 0..frames {
        let bones = random_poses(model, characters, frame as u64);
        let (mut p, mut n, mut t) = (
            vec![[0.0; 3]; characters * v],
            vec![[0.0; 3]; characters * v],
            vec![[0.0; 4]; characters * v],
        );
        CpuEvaluator::new(model)
            .evaluate_with_tangents(&bones, &mut p, &mut n, &mut t)
            .expect("CPU evaluator");
        poses.extend(bones.as_flattened());
        expected.extend(p.as_flattened());
        tangents.extend(t.as_flattened());
    }
    write_floats(&dir.join("poses.bin"), &poses);
    write_floats(&dir.join("expected.bin"), &expected);
    write_floats(&dir.join("tangents.bin"), &tangents);
}

/// Compiles `examples/c/{name}.c` against the header and the static library with the system C
/// compiler (warnings are errors), linking `libraries`.
fn compile_example(dir: &Path, name: &str, libraries: &[&str]) -> PathBuf {
    let exe = dir.join(name);
    let cc = std::env::var("CC").unwrap_or_else(|_| "cc".into());
    let build = Command::new(&cc)
        .args(["-std=c11", "-Wall", "-Wextra", "-Werror", "-o"])
        .arg(&exe)
        .arg(root().join(format!("examples/c/{name}.c")))
        .arg("-I")
        .arg(root().join("include"))
        .arg(static_library())
        .args(libraries)
        .args(["-lgcc_s", "-lutil", "-lrt", "-lpthread", "-lm", "-ldl"])
        .output()
        .expect("a C compiler");
    assert!(
        build.status.success(),
        "{cc} failed:\n{}",
        String::from_utf8_lossy(&build.stderr)
    );
    exe
}

fn assert_passes(run: std::process::Output) {
    let stdout = String::from_utf8_lossy(&run.stdout);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(
        run.status.success() && stdout.contains("passed, 0 failed"),
        "stdout:\n{stdout}\nstderr:\n{stderr}"
    );
}

#[test]
fn the_c_example_drives_the_runtime_on_the_engines_device() {
    let (frames, characters) = (3usize, 64usize);
    let dir = common::scratch::temp_dir("c-crowd");
    let model = random_model(
        Spec {
            grid: 12,
            bones: 9,
            proxies: 7,
            influences: 8,
        },
        5,
    );
    model.save(dir.join("model.rrs")).expect("save model");
    write_reference(&dir, &model, frames, characters);
    let exe = compile_example(&dir, "crowd", &["-lvulkan"]);
    let args = |frames: usize| -> [std::ffi::OsString; 6] {
        [
            dir.join("model.rrs").into(),
            dir.join("poses.bin").into(),
            dir.join("expected.bin").into(),
            frames.to_string().into(),
            characters.to_string().into(),
            dir.join("tangents.bin").into(),
        ]
    };
    // Under memcheck for one frame (every call of the engine's frame, at a fortieth of the
    // speed), suppressing only the Vulkan stack's own (tests/valgrind/vulkan.supp).
    memcheck(&exe, &args(1), true);
    let run = Command::new(&exe)
        .args(args(frames))
        .output()
        .expect("run the C example");
    assert_passes(run);
}

/// Runs `exe` under valgrind's memcheck: it must pass, with no error and nothing definitely
/// lost; `vulkan`: with the suppressions of the Vulkan loader, layer and driver.
fn memcheck(exe: &Path, args: &[impl AsRef<std::ffi::OsStr>], vulkan: bool) {
    let mut valgrind = Command::new("valgrind");
    valgrind.args([
        "--error-exitcode=9",
        "--leak-check=full",
        "--errors-for-leak-kinds=definite",
        // The layer and driver are unloaded before the leak check: keep their symbols so the
        // suppressions can name them.
        "--keep-debuginfo=yes",
    ]);
    if vulkan {
        valgrind.arg(format!(
            "--suppressions={}",
            root().join("tests/valgrind/vulkan.supp").display()
        ));
    }
    let checked = valgrind
        .arg(exe)
        .args(args)
        .output()
        .expect("valgrind on PATH: run .ci/install-deps");
    let report = String::from_utf8_lossy(&checked.stderr);
    assert!(
        checked.status.success()
            && report.contains("ERROR SUMMARY: 0 errors")
            && report.contains("definitely lost: 0 bytes"),
        "memcheck of {}:\n{report}",
        exe.display()
    );
    let stdout = String::from_utf8_lossy(&checked.stdout);
    assert!(
        stdout.contains("passed, 0 failed"),
        "under memcheck:\n{stdout}"
    );
}

/// The CPU palette from C, linked without the Vulkan loader (an engine that skins with its own
/// shaders needs no Vulkan), clean under valgrind's memcheck.
#[test]
fn the_c_palette_example_skins_without_vulkan() {
    let (frames, characters) = (3usize, 20usize);
    let dir = common::scratch::temp_dir("c-palette");
    // With pose-space correctives: the program adds the weighted targets as a shader would.
    let model = with_correctives(
        &joint_blend_pattern(
            &random_model(
                Spec {
                    grid: 12,
                    bones: 9,
                    proxies: 14,
                    influences: 8,
                },
                6,
            ),
            1,
        ),
        5,
        6,
    );
    model.save(dir.join("model.rrs")).expect("save model");
    write_reference(&dir, &model, frames, characters);
    let exe = compile_example(&dir, "palette", &[]);
    let args = [
        dir.join("model.rrs"),
        dir.join("poses.bin"),
        dir.join("expected.bin"),
        frames.to_string().into(),
        characters.to_string().into(),
    ];
    // Under valgrind's memcheck first, with no suppressions (there is no driver on this path).
    // What it may call "possibly lost" is the 48-byte handle Rust's std keeps of the calling
    // thread once threads were started.
    memcheck(&exe, &args, false);
    let run = Command::new(&exe)
        .args(&args)
        .output()
        .expect("run the C palette example");
    assert_passes(run);
}

/// The headless path through the ABI (called in-process): a context of its own with
/// validation, a model from memory, run-and-wait, read-back, compared with the CPU evaluator.
#[test]
fn the_headless_path_through_the_abi_matches_the_cpu_evaluator() {
    use rrskin::ffi::*;
    // With pose-space and proxy correctives that see gravity (rrskin_model_info reports their
    // sizes; proxies 0, 2 and 3 corrected, by 1, 3 and 0 drivers), and keys 2 and 3
    // delta-mush keys; the characters tilted by their up vectors.
    let keys = random_model(
        Spec {
            grid: 8,
            bones: 5,
            proxies: 4,
            influences: 4,
        },
        9,
    );
    let model = with_proxy_correctives_seeing(
        &with_correctives(
            &with_delta_mush_keys(&keys, 2, 9).expect("delta-mush keys"),
            4,
            2,
        ),
        true,
        Some([0.0, 1.0, 0.0]),
        2,
        3,
    );
    let bytes = model.to_bytes();
    let characters = 5u32;
    let poses = random_poses(&model, characters as usize, 3);
    let v = model.vertex_count();
    let (mut p, mut n, mut t) = (
        vec![[0.0; 3]; characters as usize * v],
        vec![[0.0; 3]; characters as usize * v],
        vec![[0.0; 4]; characters as usize * v],
    );
    let ups: Vec<[f32; 3]> = (0..characters)
        .map(|k| [(0.4 * k as f32).sin(), (0.4 * k as f32).cos(), 0.0])
        .collect();
    let mut cpu = CpuEvaluator::new(&model);
    cpu.set_ups(&ups).expect("finite ups");
    cpu.evaluate_with_tangents(&poses, &mut p, &mut n, &mut t)
        .expect("CPU evaluator");

    let ok = RrskinStatus::Ok;
    let mut ctx = RrskinContext { id: 0 };
    // SAFETY: `out` points to a live value (so in every call below that writes one).
    assert_eq!(unsafe { rrskin_context_create_headless(1, &mut ctx) }, ok);
    let mut m = RrskinModel { id: 0 };
    // SAFETY: valid pointers and lengths.
    assert_eq!(
        unsafe { rrskin_model_load_memory(ctx, bytes.as_ptr(), bytes.len(), &mut m) },
        ok
    );
    let mut crowd = RrskinCrowd { id: 0 };
    // SAFETY: `out` points to a live value.
    assert_eq!(
        unsafe { rrskin_crowd_create(m, characters, &mut crowd) },
        ok
    );
    let floats = poses.as_flattened();
    let up_floats = ups.as_flattened();
    // SAFETY: valid pointers and lengths.
    unsafe {
        assert_eq!(
            rrskin_crowd_set_bones(crowd, 0, floats.as_ptr(), floats.len()),
            ok
        );
        assert_eq!(
            rrskin_crowd_set_ups(crowd, 0, up_floats.as_ptr(), up_floats.len()),
            ok
        );
        let nan = [0.0, f32::NAN, 1.0];
        let refused = rrskin_crowd_set_character_up(crowd, 0, 1, nan.as_ptr());
        assert_eq!(refused, RrskinStatus::ErrorNonFinite);
        assert_eq!(rrskin_crowds_run(ctx, 0, &crowd, 1), ok);
    }
    let mut positions = vec![0.0f32; characters as usize * v * 3];
    // SAFETY: room for the floats; normals skipped.
    let read = unsafe {
        rrskin_crowd_read_back(
            crowd,
            positions.as_mut_ptr(),
            std::ptr::null_mut(),
            positions.len(),
        )
    };
    assert_eq!(read, ok);
    for (a, b) in positions.chunks_exact(3).zip(&p) {
        let d = ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt();
        assert!(
            d <= 2e-4 * (b[0] * b[0] + b[1] * b[1] + b[2] * b[2]).sqrt().max(1.0),
            "{a:?} vs {b:?}"
        );
    }
    let mut timings = RrskinPassTimings::default();
    // SAFETY: `out` points to a live value.
    assert_eq!(
        unsafe { rrskin_context_get_timings(ctx, 0, &mut timings) },
        ok
    );
    assert!(timings.skin_ms > 0.0);
    // A read-back buffer of the wrong size is refused, and the message says why.
    // SAFETY: the length is checked before anything is written.
    let short =
        unsafe { rrskin_crowd_read_back(crowd, positions.as_mut_ptr(), std::ptr::null_mut(), 3) };
    assert_eq!(short, RrskinStatus::ErrorWrongLength);
    // SAFETY: rrskin_last_error never returns NULL.
    let message = unsafe { std::ffi::CStr::from_ptr(rrskin_last_error()) }
        .to_string_lossy()
        .into_owned();
    assert!(message.contains("read-back floats"), "{message}");
    let mut tangents = vec![0.0f32; characters as usize * v * 4];
    // SAFETY: room for the floats; nothing is written on failure.
    let absent =
        unsafe { rrskin_crowd_read_back_tangents(crowd, tangents.as_mut_ptr(), tangents.len()) };
    assert_eq!(absent, RrskinStatus::ErrorNotEnabled);
    // Bounds and tangents through the ABI: a crowd with options, frame slot 1 of 3.
    let options = RrskinCrowdOptions {
        frames_in_flight: 3,
        previous_positions: 1,
        bounds: 1,
        tangents: 1,
        release_outputs: 0,
        release_queue_family: 0,
        normals: RRSKIN_NORMALS_RECOMPUTED,
    };
    let unknown = RrskinCrowdOptions {
        normals: 7,
        ..options
    };
    let mut bounded = RrskinCrowd { id: 0 };
    // SAFETY: live values and valid pointers.
    let refused =
        unsafe { rrskin_crowd_create_with_options(m, characters, &unknown, &mut bounded) };
    assert_eq!(refused, RrskinStatus::ErrorOutOfRange);
    let mut boxes = vec![0.0f32; characters as usize * 6];
    // SAFETY: live values and valid lengths.
    unsafe {
        assert_eq!(
            rrskin_crowd_create_with_options(m, characters, &options, &mut bounded),
            ok
        );
        assert_eq!(
            rrskin_crowd_set_bones(bounded, 1, floats.as_ptr(), floats.len()),
            ok
        );
        assert_eq!(
            rrskin_crowd_set_ups(bounded, 1, up_floats.as_ptr(), up_floats.len()),
            ok
        );
        assert_eq!(rrskin_crowds_run(ctx, 1, &bounded, 1), ok);
        assert_eq!(
            rrskin_crowd_read_bounds(bounded, 1, boxes.as_mut_ptr(), boxes.len()),
            ok
        );
        assert_eq!(
            rrskin_crowd_read_back_tangents(bounded, tangents.as_mut_ptr(), tangents.len()),
            ok
        );
        let mut out = RrskinCrowdOutput::default();
        assert_eq!(rrskin_crowd_get_output(bounded, 1, &mut out), ok);
        assert!(out.tangents != 0 && out.tangent_stride == 16);
        assert_eq!(out.tangent_character_stride, 16 * v as u64);
        assert_eq!(
            rrskin_crowd_set_bones(bounded, 3, floats.as_ptr(), floats.len()),
            RrskinStatus::ErrorOutOfRange
        );
    }
    for (c, got) in boxes.chunks_exact(6).enumerate() {
        let character = &p[c * v..(c + 1) * v];
        for axis in 0..3 {
            let lo = character
                .iter()
                .map(|x| x[axis])
                .fold(f32::INFINITY, f32::min);
            let hi = character
                .iter()
                .map(|x| x[axis])
                .fold(f32::NEG_INFINITY, f32::max);
            for (want, got) in [(lo, got[axis]), (hi, got[3 + axis])] {
                assert!(
                    (want - got).abs() <= 2e-4 * want.abs().max(1.0),
                    "{got} vs {want}"
                );
            }
        }
    }
    for (i, (got, want)) in tangents.chunks_exact(4).zip(&t).enumerate() {
        let d = (0..3)
            .map(|c| (got[c] - want[c]).powi(2))
            .sum::<f32>()
            .sqrt();
        // The synthetic grid is smooth: every normal is well-conditioned.
        assert!(
            d <= 2e-3 && got[3] == want[3],
            "tangent {i}: {got:?} vs {want:?}"
        );
    }
    // The memory query of the C ABI is the Rust one (which tests/vulkan.rs checks against the
    // buffers created).
    let info = RrskinModelInfo {
        vertices: model.vertex_count() as u32,
        triangles: model.triangle_count() as u32,
        bones: model.bone_count() as u32,
        proxies: model.proxy_count() as u32,
        influences: model.influences() as u32,
        blend_columns: rrskin::vk::ModelSizes::of(&model).product_columns as u32,
        tangents: 1,
        correctives: model.corrective_count() as u32,
        corrective_drivers: model.corrective_driver_count() as u32,
        proxy_correctives: 3,
        proxy_corrective_drivers: 4,
        proxy_corrective_kernels: 2,
        proxy_corrective_linear: 1,
        proxy_corrective_gravity: 1,
        up: [0.0, 1.0, 0.0],
        normal_fan_entries: model.normal_fans().entries.len() as u32,
        key_words: rrskin::model::key_words(model.keys()).len() as u32,
    };
    let mut reported = RrskinModelInfo::default();
    // SAFETY: `out` points to a live value.
    assert_eq!(unsafe { rrskin_model_get_info(m, &mut reported) }, ok);
    assert_eq!(
        (
            reported.blend_columns,
            reported.tangents,
            reported.correctives,
            reported.corrective_drivers
        ),
        (info.blend_columns, 1, 4, 3)
    );
    assert_eq!(reported.normal_fan_entries, info.normal_fan_entries);
    assert!(info.key_words as usize > model.proxy_count() + 1);
    assert_eq!(reported.key_words, info.key_words);
    assert_eq!(
        (
            reported.proxy_correctives,
            reported.proxy_corrective_drivers,
            reported.proxy_corrective_kernels,
            reported.proxy_corrective_linear,
            reported.proxy_corrective_gravity,
            reported.up
        ),
        (3, 4, 2, 1, 1, [0.0, 1.0, 0.0])
    );
    let (mut model_bytes, mut crowd_bytes) = (0u64, 0u64);
    // SAFETY: live values.
    assert_eq!(
        unsafe {
            rrskin_query_memory(
                &info,
                characters,
                &options,
                &mut model_bytes,
                &mut crowd_bytes,
            )
        },
        ok
    );
    let sizes = rrskin::vk::ModelSizes::of(&model);
    assert_eq!(model_bytes, rrskin::vk::model_bytes(&sizes));
    let same = rrskin::vk::CrowdOptions {
        frames_in_flight: 3,
        previous_positions: true,
        bounds: true,
        tangents: true,
        ..Default::default()
    };
    let expected = rrskin::vk::crowd_bytes(&sizes, characters as usize, &same).expect("query");
    assert_eq!(crowd_bytes, expected);
    let mut needs = std::mem::MaybeUninit::<RrskinRequirements>::uninit();
    // SAFETY: room for one value, written on success.
    assert_eq!(unsafe { rrskin_get_requirements(needs.as_mut_ptr()) }, ok);
    // SAFETY: written by the call above.
    let needs = unsafe { needs.assume_init() };
    assert_eq!(
        (
            needs.api_version,
            needs.instance_extension_count,
            needs.device_extension_count
        ),
        (rrskin::vk::ash::vk::API_VERSION_1_1, 0, 0)
    );
    assert_eq!(rrskin_crowd_destroy(bounded), ok);
    // Tangents of a model without rest tangents: a status of its own, the message says why.
    let bare = rrskin::Model::new(rrskin::ModelParts {
        rest_tangents: Vec::new(),
        ..model.parts().clone()
    })
    .expect("valid")
    .to_bytes();
    let mut untangented = RrskinModel { id: 0 };
    let mut refused = RrskinCrowd { id: 0 };
    // SAFETY: valid pointers and lengths.
    unsafe {
        assert_eq!(
            rrskin_model_load_memory(ctx, bare.as_ptr(), bare.len(), &mut untangented),
            ok
        );
        assert_eq!(
            rrskin_crowd_create_with_options(untangented, 1, &options, &mut refused),
            RrskinStatus::ErrorNotInModel
        );
    }
    // SAFETY: rrskin_last_error never returns NULL.
    let message = unsafe { std::ffi::CStr::from_ptr(rrskin_last_error()) }.to_string_lossy();
    assert!(message.contains("rest tangents"), "{message}");
    assert_eq!(rrskin_model_destroy(untangented), ok);
    let mut count = u32::MAX;
    // SAFETY: `out` points to a live value.
    assert_eq!(
        unsafe { rrskin_context_validation_message_count(ctx, &mut count) },
        ok
    );
    assert_eq!(count, 0, "validation messages");
    // A crowd of another context, and a crowd listed twice, are refused.
    let mut other = RrskinContext { id: 0 };
    // SAFETY: `out` points to a live value; valid pointers and counts.
    unsafe {
        assert_eq!(rrskin_context_create_headless(0, &mut other), ok);
        assert_eq!(
            rrskin_crowds_run(other, 0, &crowd, 1),
            RrskinStatus::ErrorMismatch
        );
        assert_eq!(
            rrskin_crowds_run(ctx, 0, [crowd, crowd].as_ptr(), 2),
            RrskinStatus::ErrorMismatch
        );
    }
    assert_eq!(rrskin_context_destroy(other), ok);
    assert_eq!(rrskin_crowd_destroy(crowd), ok);
    assert_eq!(rrskin_model_destroy(m), ok);
    assert_eq!(rrskin_context_destroy(ctx), ok);
    assert_eq!(
        rrskin_context_destroy(ctx),
        RrskinStatus::ErrorInvalidHandle
    );
}
