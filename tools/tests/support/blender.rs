//! Running Blender headless (Debian's 3.4, and 4.5 as the `bpy` module) and the `rrskin`
//! binary, for the Blender tests (included with `#[path]`).
#![allow(dead_code)] // each test binary uses a different subset

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// The repository's root.
pub fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// `blender -b ARGS` with Python errors as exit status 1. Fails (never skips) when Blender is
/// missing: the suite needs it.
pub fn blender(args: &[&str]) -> Output {
    let out = Command::new("blender")
        .arg("-b")
        .args(args)
        .env("PYTHONDONTWRITEBYTECODE", "1")
        .output();
    match out {
        Ok(out) => out,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => panic!(
            "`blender` is not on PATH: run .ci/install-deps (it installs Debian's blender and \
             python3-numpy, which these tests run headless)"
        ),
        Err(e) => panic!("cannot run blender: {e}"),
    }
}

/// Runs `blender -b --factory-startup --python-exit-code 1 --python SCRIPT -- ARGS`, and
/// panics with its output unless it succeeds.
pub fn blender_script(script: &Path, args: &[&str]) -> Output {
    let mut all = vec![
        "--factory-startup",
        "--python-exit-code",
        "1",
        "--python",
        script.to_str().expect("utf-8 path"),
        "--",
    ];
    all.extend_from_slice(args);
    let out = blender(&all);
    assert!(
        out.status.success(),
        "blender {} failed ({}):\n{}\n{}",
        script.display(),
        out.status,
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

/// Runs `SCRIPT -- ARGS` in the Python of Blender 4.5's `bpy` module (`.ci/install-deps` puts
/// it in tools/tests/blender45/venv), and panics with its output unless it succeeds. Fails
/// (never skips) when that Python is missing.
pub fn bpy_script(script: &Path, args: &[&str]) -> Output {
    let python = repo().join("tools/tests/blender45/venv/bin/python");
    assert!(
        python.is_file(),
        "{} is missing: run .ci/install-deps (it installs Blender 4.5's bpy module from PyPI)",
        python.display()
    );
    let out = Command::new(&python)
        .arg(script)
        .arg("--")
        .args(args)
        .env("PYTHONDONTWRITEBYTECODE", "1")
        .output()
        .expect("run the bpy Python");
    assert!(
        out.status.success(),
        "{} {} failed ({}):\n{}\n{}",
        python.display(),
        script.display(),
        out.status,
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

pub fn rrskin(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_rrskin"))
        .args(args)
        .output()
        .expect("run rrskin")
}

/// Runs `SCRIPT -- --out DIR --glb CesiumMan_examples.glb` in Blender 4.5's `bpy` Python
/// ([`bpy_script`]): a scenario script of tools/tests/blender/ writing its files of the bundled
/// rig into `dir`.
pub fn bpy_scenarios(script: &str, dir: &Path) {
    let script = repo().join("tools/tests/blender").join(script);
    let glb = repo().join("data/cesiumman_gltf/CesiumMan_examples.glb");
    let (out, glb) = (dir.to_str().expect("utf-8"), glb.to_str().expect("utf-8"));
    bpy_script(&script, &["--out", out, "--glb", glb]);
}

/// The JSON object `rrskin ARGS` printed, and its stderr (the notes); panics with stderr if
/// it failed.
pub fn eval_with_notes(args: &[&str]) -> (serde_json::Value, String) {
    let out = rrskin(args);
    let stderr = String::from_utf8_lossy(&out.stderr).to_string();
    assert!(out.status.success(), "rrskin {}:\n{stderr}", args.join(" "));
    (serde_json::from_slice(&out.stdout).expect("JSON"), stderr)
}

/// Writes 40 broken copies of `source` into `dir` (`CASE-NAME`: truncated at a random length,
/// or 8 random bits flipped, alternately; the same ones for one `seed`) and `load`s each: a
/// refusal must name the copy (a load that succeeds is fine: the damage missed what is read).
pub fn refuses_broken_copies<E: std::fmt::Display>(
    source: &Path,
    dir: &Path,
    seed: u64,
    load: &dyn Fn(&Path) -> Result<(), E>,
) {
    let name = source.file_name().expect("a file").to_string_lossy();
    let bytes = std::fs::read(source).expect("the source file");
    let mut x = seed;
    let mut next = |n: usize| {
        x = x
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (x >> 33) as usize % n
    };
    for case in 0..40 {
        let mut broken = bytes.clone();
        match case % 2 {
            0 => broken.truncate(next(bytes.len())),
            _ => (0..8).for_each(|_| {
                let at = next(broken.len());
                broken[at] ^= 1 << next(8);
            }),
        }
        let path = dir.join(format!("{case}-{name}"));
        std::fs::write(&path, &broken).expect("write");
        if let Err(e) = load(&path) {
            assert!(e.to_string().contains(&format!("{case}-{name}")), "{e}");
        }
    }
}

/// The JSON object `rrskin eval ... --json` printed; panics with stderr if it failed.
pub fn eval_json(args: &[&str]) -> serde_json::Value {
    let out = rrskin(args);
    assert!(
        out.status.success(),
        "rrskin {} failed ({}):\n{}",
        args.join(" "),
        out.status,
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).unwrap_or_else(|e| {
        panic!(
            "rrskin {}: not JSON ({e}):\n{}",
            args.join(" "),
            String::from_utf8_lossy(&out.stdout)
        )
    })
}

/// `e[method][split]` (split "train" or "test") as a number.
pub fn figure(e: &serde_json::Value, method: &str, split: &str) -> f64 {
    e[method][split]
        .as_f64()
        .unwrap_or_else(|| panic!("no {method}.{split} in {e}"))
}

/// `got`'s rigid, SSD and rig-LBS EE on both splits within `tolerance` points of `want`'s
/// (`what`: the case, in the message).
pub fn assert_same_figures(
    got: &serde_json::Value,
    want: &serde_json::Value,
    tolerance: f64,
    what: &str,
) {
    for method in ["rigid", "ssd", "rig_lbs"] {
        for split in ["train", "test"] {
            let (g, w) = (figure(got, method, split), figure(want, method, split));
            assert!(
                (g - w).abs() <= tolerance,
                "{what}: {method} {split} {g:.4} against {w:.4}"
            );
        }
    }
}

pub fn count(e: &serde_json::Value, key: &str) -> u64 {
    e[key].as_u64().unwrap_or_else(|| panic!("no {key} in {e}"))
}

/// `rrskin eval RIG --clip rom --cache CACHE` on the held-out frames 23..30, without
/// reduction, gives `reference`'s counts (vertices, triangles, bones, poses of each split), its
/// rigid, SSD and rig-LBS EE within `tolerance` points, and a note containing each of `notes`.
pub fn assert_same_route(
    reference: &serde_json::Value,
    rig: &str,
    cache: &str,
    tolerance: f64,
    notes: &[&str],
) {
    let args = ["eval", rig, "--clip", "rom", "--cache", cache];
    let held_out = ["--test-frames", "23..30", "--proxies", "0", "--json"];
    let (e, stderr) = eval_with_notes(&[&args[..], &held_out].concat());
    for key in [
        "vertices",
        "triangles",
        "bones",
        "train_poses",
        "test_poses",
    ] {
        assert_eq!(count(&e, key), count(reference, key), "{rig}: {key}");
    }
    let what = format!("{rig} + {cache} against the reference route");
    assert_same_figures(&e, reference, tolerance, &what);
    for note in notes {
        assert!(
            stderr
                .lines()
                .any(|l| l.starts_with("note: ") && l.contains(note)),
            "{rig}: no note says {note:?}:\n{stderr}"
        );
    }
}
