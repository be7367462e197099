//! The `rrskin` binary end to end: exit codes, JSON output, and error messages that name the
//! file and the problem.

use std::path::PathBuf;
use std::process::{Command, Output};

fn rrskin(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_rrskin"))
        .args(args)
        .output()
        .expect("the binary runs")
}

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("rrskin-cli-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    dir
}

fn json(out: &Output) -> serde_json::Value {
    assert!(
        out.status.success(),
        "stderr: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("one JSON object on stdout")
}

#[test]
fn synth_info_and_profile_agree_on_the_model() {
    let dir = temp_dir("profile");
    let model = dir.join("m.rrs");
    let m = model.to_str().expect("utf-8 path");
    let out = rrskin(&[
        "synth",
        "--grid",
        "9",
        "--bones",
        "5",
        "--proxies",
        "6",
        "--influences",
        "8",
        "-o",
        m,
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let info = json(&rrskin(&["info", m, "--json"]));
    assert_eq!(info["vertices"], 81);
    assert_eq!(info["triangles"], 128);
    assert_eq!(
        (
            info["bones"].as_u64(),
            info["proxies"].as_u64(),
            info["influences"].as_u64()
        ),
        (Some(5), Some(6), Some(8))
    );
    let p = json(&rrskin(&[
        "profile",
        m,
        "--characters",
        "5",
        "--frames",
        "3",
        "--json",
    ]));
    assert_eq!(
        (p["characters"].as_u64(), p["vertices"].as_u64()),
        (Some(5), Some(81))
    );
    for pass in [
        "predict_ms",
        "blend_ms",
        "skin_ms",
        "normals_ms",
        "total_ms",
        "skin_mverts_per_s",
    ] {
        let value = p[pass].as_f64().expect("a number");
        assert!(value > 0.0 && value.is_finite(), "{pass}: {p}");
    }
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn bad_model_files_fail_with_the_file_and_the_problem() {
    let dir = temp_dir("bad");
    let bad = dir.join("text.rrs");
    std::fs::write(&bad, "hello").expect("write");
    let out = rrskin(&["info", bad.to_str().expect("utf-8")]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("text.rrs") && err.contains("truncated"),
        "{err}"
    );
    let out = rrskin(&["profile", dir.join("absent.rrs").to_str().expect("utf-8")]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("absent.rrs"));
    let out = rrskin(&[
        "synth",
        "--influences",
        "5",
        "-o",
        dir.join("k5.rrs").to_str().expect("utf-8"),
    ]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("must be 4 or 8"));
    std::fs::remove_dir_all(&dir).ok();
}
