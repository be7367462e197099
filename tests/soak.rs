//! A soak through the C ABI: frames of one mixed batch (three models, K = 4 and 8, with and
//! without proxies, crowds with and without optional outputs) interleaved with create/destroy
//! cycles of models and crowds, under the validation layer. Resident host memory
//! (`/proc/self/statm`; on lavapipe device memory is host memory too) and the context's device
//! memory (`rrskin_context_get_device_memory`) are sampled along the run; the test fails if
//! either grows after the warm-up. Every so often the outputs are checked against the CPU
//! reference.
//!
//! `soak_short` runs in the suite. The full soak (100,000 frames, 1,000 cycles):
//! `cargo test --release --test soak -- --ignored soak --nocapture`.

mod common;

use common::abi::load;
use common::*;
use rrskin::ffi::*;
use rrskin::Model;

const OK: RrskinStatus = RrskinStatus::Ok;

/// Resident host memory, bytes.
fn resident_bytes() -> u64 {
    let statm = std::fs::read_to_string("/proc/self/statm").expect("/proc/self/statm");
    let pages: u64 = statm
        .split_whitespace()
        .nth(1)
        .and_then(|p| p.parse().ok())
        .expect("statm's second field");
    pages * 4096
}

fn device_memory(ctx: RrskinContext) -> (u64, u64) {
    let (mut allocated, mut reserved) = (0, 0);
    // SAFETY: valid pointers.
    let s = unsafe { rrskin_context_get_device_memory(ctx, &mut allocated, &mut reserved) };
    assert_eq!(s, OK);
    (allocated, reserved)
}

fn crowd(model: RrskinModel, characters: u32, options: RrskinCrowdOptions) -> RrskinCrowd {
    let mut c = RrskinCrowd { id: 0 };
    // SAFETY: valid pointers.
    let s = unsafe { rrskin_crowd_create_with_options(model, characters, &options, &mut c) };
    assert_eq!(s, OK);
    c
}

fn set_bones(c: RrskinCrowd, slot: u32, poses: &[rrskin::predict::Affine]) {
    let floats = poses.as_flattened();
    // SAFETY: valid pointer and length.
    let s = unsafe { rrskin_crowd_set_bones(c, slot, floats.as_ptr(), floats.len()) };
    assert_eq!(s, OK);
}

fn run(ctx: RrskinContext, slot: u32, crowds: &[RrskinCrowd]) {
    // SAFETY: valid pointer and count.
    let s = unsafe { rrskin_crowds_run(ctx, slot, crowds.as_ptr(), crowds.len() as u32) };
    assert_eq!(s, OK);
}

/// The crowd's positions and normals against the CPU reference's `p` and `n`.
fn check(model: &Model, c: RrskinCrowd, p: &[[f32; 3]], n: &[[f32; 3]]) {
    let (mut gp, mut gn) = (vec![0.0f32; p.len() * 3], vec![0.0f32; n.len() * 3]);
    // SAFETY: room for the floats.
    let s = unsafe { rrskin_crowd_read_back(c, gp.as_mut_ptr(), gn.as_mut_ptr(), gp.len()) };
    assert_eq!(s, OK);
    compare(model, (p, n), (&triples(&gp), &triples(&gn)));
}

struct Sample {
    frame: usize,
    resident: u64,
    device: (u64, u64),
}

/// `frames` frames of the batch, and a create/destroy cycle after every `frames / cycles`.
fn soak(frames: usize, cycles: usize) {
    let specs = [(5, 4, 3, 4), (6, 6, 0, 8), (4, 5, 4, 8)];
    let models: Vec<Model> = (specs.iter().enumerate())
        .map(|(i, &(grid, bones, proxies, influences))| {
            random_model(
                Spec {
                    grid,
                    bones,
                    proxies,
                    influences,
                },
                40 + i as u64,
            )
        })
        .collect();
    let bytes: Vec<Vec<u8>> = models.iter().map(|m| m.to_bytes()).collect();
    let everything = RrskinCrowdOptions {
        frames_in_flight: 2,
        previous_positions: 1,
        bounds: 1,
        tangents: 1,
        ..Default::default()
    };
    let plain = RrskinCrowdOptions {
        frames_in_flight: 2,
        ..Default::default()
    };
    let characters = [4u32, 3, 5];
    let mut ctx = RrskinContext { id: 0 };
    // SAFETY: valid pointer.
    assert_eq!(unsafe { rrskin_context_create_headless(1, &mut ctx) }, OK);
    let handles: Vec<RrskinModel> = bytes.iter().map(|b| load(ctx, b).expect("model")).collect();
    let crowds: Vec<RrskinCrowd> = (0..3)
        .map(|i| {
            let options = if i == 1 { plain } else { everything };
            crowd(handles[i], characters[i], options)
        })
        .collect();
    // The poses cycle through a fixed set (per model: bones, CPU positions, CPU normals): the
    // run measures the runtime, not the test's own allocations.
    let pose_sets: Vec<_> = (models.iter().zip(characters))
        .map(|(m, c)| checkable_poses(m, c as usize, 4))
        .collect();
    let every = (frames / cycles.max(1)).max(1);
    let samples_wanted = 20;
    let mut samples = Vec::new();
    let mut cycles_done = 0;
    let started = std::time::Instant::now();
    for frame in 0..frames {
        let slot = (frame % 2) as u32;
        let set = frame % 4;
        for (c, poses) in crowds.iter().zip(&pose_sets) {
            set_bones(*c, slot, &poses[set].0);
        }
        run(ctx, slot, &crowds);
        if frame % 1000 == 999 {
            for ((m, c), poses) in models.iter().zip(&crowds).zip(&pose_sets) {
                let (_, p, n) = &poses[set];
                check(m, *c, p, n);
            }
        }
        if frame % every == every - 1 && cycles_done < cycles {
            let i = cycles_done % models.len();
            let m = load(ctx, &bytes[i]).expect("model");
            let c = crowd(m, characters[i], everything);
            set_bones(c, 0, &pose_sets[i][0].0);
            run(ctx, 0, &[c]);
            assert_eq!(rrskin_crowd_destroy(c), OK);
            assert_eq!(rrskin_model_destroy(m), OK);
            cycles_done += 1;
        }
        if frame % (frames / samples_wanted).max(1) == 0 || frame + 1 == frames {
            samples.push(Sample {
                frame,
                resident: resident_bytes(),
                device: device_memory(ctx),
            });
        }
    }
    let elapsed = started.elapsed().as_secs_f64();
    let mut count = u32::MAX;
    // SAFETY: valid pointer.
    let status = unsafe { rrskin_context_validation_message_count(ctx, &mut count) };
    assert_eq!((status, count), (OK, 0), "validation messages");
    for c in crowds {
        assert_eq!(rrskin_crowd_destroy(c), OK);
    }
    for m in handles {
        assert_eq!(rrskin_model_destroy(m), OK);
    }
    assert_eq!(rrskin_context_destroy(ctx), OK);

    println!(
        "{frames} frames, {cycles_done} cycles in {elapsed:.1} s ({:.3} ms a frame)",
        elapsed * 1e3 / frames as f64
    );
    for s in &samples {
        println!(
            "frame {:>6}: resident {:>7.2} MiB, device memory {} allocated / {} reserved",
            s.frame,
            s.resident as f64 / (1 << 20) as f64,
            s.device.0,
            s.device.1
        );
    }
    assert_eq!(cycles_done, cycles);
    // Warm-up: the first quarter of the run (the driver's caches and the allocator's blocks
    // fill); after it nothing may grow.
    let warm = &samples[samples.len() / 4];
    let last = samples.last().expect("samples");
    for s in &samples[samples.len() / 4..] {
        assert_eq!(
            s.device, warm.device,
            "device memory changed after warm-up (frame {} against {})",
            s.frame, warm.frame
        );
    }
    // Host memory moves by the allocator's page-granular reuse; a leak of 16 bytes a frame is
    // 1.5 MB over the full soak, so the margin is below that.
    let growth = last.resident as i64 - warm.resident as i64;
    assert!(
        growth < 1 << 20,
        "resident memory grew by {growth} bytes from frame {} to {}",
        warm.frame,
        last.frame
    );
}

#[test]
fn soak_short() {
    soak(4000, 100);
}

#[test]
#[ignore = "the full soak, about N minutes: cargo test --release --test soak -- --ignored soak"]
fn soak_full() {
    soak(100_000, 1000);
}
