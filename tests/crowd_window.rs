//! The crowd sample (examples/crowd) as a user runs it: in a window on a virtual X server
//! (Xvfb), presenting through a swapchain on lavapipe with the validation layer on, for both
//! methods; and headless, writing a PNG. The test reads the X server's screen back (xwd) while
//! the sample runs: the window must show characters, and they must move.
//!
//! Needs `Xvfb` and `xwd` (packages xvfb and x11-apps; `.ci/install-deps` installs them).

mod common;

use common::{random_model, random_poses, Spec};
use rrskin_render::CROWD_BACKGROUND;
use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// A synthetic model with an animation (random poses) and a baseline (its skinning, folded onto
/// the bones), so
/// the sample can play it with either method.
fn model_file(dir: &Path) -> PathBuf {
    let model = random_model(
        Spec {
            grid: 10,
            bones: 6,
            proxies: 5,
            influences: 4,
        },
        11,
    );
    let mut parts = model.parts().clone();
    parts.animation = random_poses(&model, 8, 3);
    // Skinning columns J.. are proxy bones; the baseline skins to the J bones only.
    let bones = model.bone_count() as u32;
    parts.baseline_indices = parts.skin_indices.iter().map(|i| i % bones).collect();
    parts.baseline_weights = parts.skin_weights.clone();
    let path = dir.join("animated.rrs");
    rrskin::Model::new(parts)
        .expect("valid model")
        .save(&path)
        .expect("save");
    path
}

/// An Xvfb server on a free display, killed on drop.
struct Xvfb {
    child: Child,
    display: String,
}

impl Xvfb {
    fn start() -> Xvfb {
        // -displayfd 1: the server picks a free display and writes its number to stdout.
        let mut child = Command::new("Xvfb")
            .args([
                "-displayfd",
                "1",
                "-screen",
                "0",
                "640x480x24",
                "-nolisten",
                "tcp",
                "-br",
            ])
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .expect("Xvfb (package xvfb; run .ci/install-deps)");
        let mut number = String::new();
        let mut stdout = child.stdout.take().expect("piped stdout");
        let mut byte = [0u8];
        while stdout.read(&mut byte).expect("read Xvfb's display") == 1 && byte[0] != b'\n' {
            number.push(byte[0] as char);
        }
        assert!(!number.is_empty(), "Xvfb did not report a display");
        Xvfb {
            child,
            display: format!(":{}", number.trim()),
        }
    }

    /// The screen as RGB pixels (xwd's 32-bit ZPixmap, little-endian BGRX).
    fn screenshot(&self) -> Option<Vec<[u8; 3]>> {
        let out = Command::new("xwd")
            .args(["-root", "-silent", "-display", &self.display])
            .output()
            .expect("xwd (package x11-apps; run .ci/install-deps)");
        let d = out.stdout;
        let word = |i: usize| -> Option<usize> {
            let b = d.get(4 * i..4 * i + 4)?;
            Some(u32::from_be_bytes([b[0], b[1], b[2], b[3]]) as usize)
        };
        let (header, width, height) = (word(0)?, word(4)?, word(5)?);
        let (byte_order, bits, row) = (word(7)?, word(11)?, word(12)?);
        assert_eq!((bits, byte_order), (32, 0), "unexpected xwd pixel layout");
        let start = header + word(19)? * 12; // the colour map follows the header
        let pixels = d.get(start..start + row * height)?;
        Some(
            pixels
                .chunks_exact(row)
                .flat_map(|r| r[..4 * width].chunks_exact(4).map(|p| [p[2], p[1], p[0]]))
                .collect(),
        )
    }
}

impl Drop for Xvfb {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Pixels that are neither the black root window nor the sample's clear colour.
fn character_pixels(screen: &[[u8; 3]]) -> usize {
    let background = CROWD_BACKGROUND.map(|x| (x * 255.0).round() as u8);
    let near = |p: &[u8; 3], q: [u8; 3]| (0..3).all(|i| p[i].abs_diff(q[i]) <= 6);
    screen
        .iter()
        .filter(|p| !near(p, [0; 3]) && !near(p, background))
        .count()
}

/// Runs the sample in a window until it exits, screenshotting the screen meanwhile. Returns
/// its stdout and the screenshots that show characters.
fn run_in_window(x: &Xvfb, sample: &Path, args: &[&str]) -> (String, Vec<Vec<[u8; 3]>>) {
    let mut child = Command::new(sample)
        .args(args)
        .env("DISPLAY", &x.display)
        .env_remove("WAYLAND_DISPLAY")
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("run the crowd sample");
    let (started, mut shots) = (Instant::now(), Vec::new());
    while child.try_wait().expect("wait").is_none() {
        assert!(
            started.elapsed() < Duration::from_secs(300),
            "the sample did not finish"
        );
        if let Some(screen) = x.screenshot() {
            if character_pixels(&screen) > 200 {
                shots.push(screen);
            }
        }
        std::thread::sleep(Duration::from_millis(100));
    }
    let out = child.wait_with_output().expect("sample output");
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(
        out.status.success(),
        "crowd {args:?} failed:\n{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    (stdout, shots)
}

#[test]
fn the_crowd_sample_presents_moving_characters_in_a_window_and_headless() {
    let sample = common::suite_artifacts().join("examples/crowd");
    let dir = common::scratch::temp_dir("crowd-window");
    let model = model_file(&dir);
    let model = model.to_str().expect("UTF-8 temp path");
    let x = Xvfb::start();

    for (method, extra) in [
        ("rotational regression", None),
        ("linear blend skinning", Some("--lbs")),
    ] {
        let mut args = vec![model, "--characters", "16", "--frames", "90", "--validate"];
        args.extend(extra);
        let (stdout, shots) = run_in_window(&x, &sample, &args);
        assert!(stdout.contains("presented 90 frames"), "{stdout}");
        assert!(
            stdout.contains(&format!(
                "16 characters x 100 vertices ({method}), median over 90"
            )),
            "{stdout}"
        );
        assert!(
            shots.len() >= 2,
            "{method}: {} screenshots showed characters",
            shots.len()
        );
        let moved = shots.windows(2).any(|w| w[0] != w[1]);
        assert!(
            moved,
            "{method}: the characters did not move between screenshots"
        );
    }

    let png = dir.join("crowd.png");
    let png_arg = png.to_str().expect("UTF-8 temp path");
    let out = Command::new(&sample)
        .args([model, "--headless", "--out", png_arg, "--characters", "9"])
        .args(["--frames", "3", "--validate"])
        .output()
        .expect("run the crowd sample");
    assert!(
        out.status.success(),
        "headless crowd failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let decoder = png::Decoder::new(std::io::BufReader::new(
        std::fs::File::open(&png).expect("the PNG was written"),
    ));
    let mut reader = decoder.read_info().expect("a PNG");
    let mut rgba = vec![0; reader.output_buffer_size().expect("image size")];
    let info = reader.next_frame(&mut rgba).expect("PNG pixels");
    assert_eq!((info.width, info.height), (1280, 720));
    let rgb: Vec<[u8; 3]> = rgba.chunks_exact(4).map(|p| [p[0], p[1], p[2]]).collect();
    assert!(
        character_pixels(&rgb) > 200,
        "the headless image shows no characters"
    );

    // Without a display the window mode fails with the reason and the way out, not winit's
    // source location.
    let out = Command::new(&sample)
        .args([model, "--frames", "1"])
        .env_remove("DISPLAY")
        .env_remove("WAYLAND_DISPLAY")
        .env_remove("WAYLAND_SOCKET")
        .output()
        .expect("run the crowd sample");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        out.status.code() == Some(1) && stderr.contains("--headless") && !stderr.contains(".rs:"),
        "{stderr}"
    );
}
