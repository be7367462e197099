//! The C ABI under an engine's threads: N crowds driven from N threads at once (bones set, the
//! frame run, the outputs read back and checked against the CPU reference every frame), while
//! another thread loads and destroys models on the same context, with the validation layer on
//! (its thread-safety checks report two threads in one externally synchronised Vulkan object).

mod common;

use common::abi::load;
use common::*;
use rrskin::ffi::*;
use rrskin::Model;

const THREADS: usize = 4;
/// Frames per thread: 4000 frames in all.
const FRAMES: usize = 1000;
const CHARACTERS: usize = 2;

const OK: RrskinStatus = RrskinStatus::Ok;

/// One thread's crowd of `model`, for two frames in flight, checked every frame.
fn drive(ctx: RrskinContext, model: &Model, handle: RrskinModel, seed: usize) {
    let mut crowd = RrskinCrowd { id: 0 };
    // SAFETY: `out` points to a live value.
    let created = unsafe { rrskin_crowd_create(handle, CHARACTERS as u32, &mut crowd) };
    assert_eq!(created, OK);
    let poses = checkable_poses(model, CHARACTERS, 8);
    let floats = CHARACTERS * model.vertex_count() * 3;
    let (mut gp, mut gn) = (vec![0.0f32; floats], vec![0.0f32; floats]);
    for frame in 0..FRAMES {
        let (bones, p, n) = &poses[(frame * 3 + seed) % poses.len()];
        let bones = bones.as_flattened();
        let slot = (frame % 2) as u32;
        // SAFETY: valid pointers and lengths.
        unsafe {
            assert_eq!(
                rrskin_crowd_set_bones(crowd, slot, bones.as_ptr(), bones.len()),
                OK
            );
            assert_eq!(rrskin_crowds_run(ctx, slot, &crowd, 1), OK);
            assert_eq!(
                rrskin_crowd_read_back(crowd, gp.as_mut_ptr(), gn.as_mut_ptr(), floats),
                OK
            );
        }
        compare(model, (p, n), (&triples(&gp), &triples(&gn)));
    }
    assert_eq!(rrskin_crowd_destroy(crowd), OK);
}

#[test]
fn crowds_driven_from_many_threads_match_the_cpu_reference_every_frame() {
    let models = [
        random_model(
            Spec {
                grid: 6,
                bones: 5,
                proxies: 3,
                influences: 4,
            },
            71,
        ),
        random_model(
            Spec {
                grid: 5,
                bones: 6,
                proxies: 0,
                influences: 8,
            },
            72,
        ),
    ];
    let mut ctx = RrskinContext { id: 0 };
    // SAFETY: `out` points to a live value.
    assert_eq!(unsafe { rrskin_context_create_headless(1, &mut ctx) }, OK);
    let bytes = models.each_ref().map(|m| m.to_bytes());
    let handles = bytes.each_ref().map(|b| load(ctx, b).expect("model"));
    let done = std::sync::atomic::AtomicBool::new(false);
    let churned = std::thread::scope(|s| {
        let drivers: Vec<_> = (0..THREADS)
            .map(|t| {
                let (model, handle) = (&models[t % 2], handles[t % 2]);
                s.spawn(move || drive(ctx, model, handle, t))
            })
            .collect();
        // Model uploads submit to the queue the runs use: they must take turns with them.
        let churn = s.spawn(|| {
            let mut cycles = 0;
            while !done.load(std::sync::atomic::Ordering::Relaxed) {
                assert_eq!(
                    rrskin_model_destroy(load(ctx, &bytes[cycles % 2]).expect("model")),
                    OK
                );
                cycles += 1;
            }
            cycles
        });
        let driven: Vec<_> = drivers.into_iter().map(|d| d.join()).collect();
        done.store(true, std::sync::atomic::Ordering::Relaxed);
        let churned = churn.join();
        for d in driven {
            d.expect("a driver thread failed");
        }
        churned.expect("the model thread failed")
    });
    assert!(churned > 0);
    let mut count = u32::MAX;
    // SAFETY: `out` points to a live value.
    let status = unsafe { rrskin_context_validation_message_count(ctx, &mut count) };
    assert_eq!((status, count), (OK, 0), "validation messages");
    for h in handles {
        assert_eq!(rrskin_model_destroy(h), OK);
    }
    assert_eq!(rrskin_context_destroy(ctx), OK);
}
