//! Criterion benches: per-frame runtime of rotational regression and of its SSD baseline at
//! C = 1, 16, 256, 1024 characters, the CPU palette per character and batched over threads, the
//! C ABI's `set_bones` from several threads, and training (benches/README.md).

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use rrskin::palette::Palette;
use rrskin::vk::{Batch, Context, ContextDesc, Crowd, GpuModel};
use rrskin_render::phased_poses;
use rrskin_tools::cylinder_chain::Chain;
use rrskin_tools::set::ExampleSet;
use rrskin_tools::train::{self, TrainOptions};
use std::time::Duration;

fn cesiumman() -> ExampleSet {
    ExampleSet::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../data/cesiumman"))
        .expect("bundled data")
}

fn options() -> TrainOptions {
    TrainOptions {
        quiet: true,
        ..Default::default()
    }
}

fn runtime(c: &mut Criterion) {
    let model = train::run(&cesiumman(), &options())
        .expect("training")
        .model
        .expect("a model");
    let baseline = model.baseline().expect("an SSD baseline");
    let ctx = Context::new(&ContextDesc::default()).expect("a Vulkan device");
    let mut group = c.benchmark_group("runtime");
    group
        .sample_size(10)
        .measurement_time(Duration::from_secs(5))
        .warm_up_time(Duration::from_secs(1));
    for (name, m) in [("rr", &model), ("ssd", &baseline)] {
        for characters in [1usize, 16, 256, 1024] {
            let mut crowd =
                Crowd::new(&GpuModel::new(&ctx, m).expect("upload"), characters).expect("crowd");
            let mut batch = Batch::new(&ctx).expect("batch");
            let bones = phased_poses(&model, characters, 0);
            group.bench_with_input(BenchmarkId::new(name, characters), &characters, |b, _| {
                b.iter(|| {
                    crowd.set_bones(0, &bones).expect("bones");
                    batch.run(0, &[&crowd]).expect("run");
                })
            });
        }
    }
    group.finish();
}

/// `rrskin train`'s work (the runtime model only) on the bundled example, on a synthetic set
/// of the human's size (13,360 vertices, 53 bones, 41 training poses) and on `human_heavy`
/// itself (`data/human_heavy`, when it loads).
fn training(c: &mut Criterion) {
    let runtime_model = TrainOptions {
        full_model: false,
        ..options()
    };
    let chain = Chain {
        rings: 167,
        segments: 80,
        bones: 53,
        poses: 51,
    };
    let human = concat!(env!("CARGO_MANIFEST_DIR"), "/../data/human_heavy");
    let mut sets = vec![
        ("cesiumman", cesiumman()),
        ("chain_13k", chain.build().expect("a valid chain")),
    ];
    if let Ok(set) = ExampleSet::load(human) {
        sets.push(("human_heavy", set));
    }
    let mut group = c.benchmark_group("training");
    group
        .sample_size(10)
        .measurement_time(Duration::from_secs(30));
    for (name, set) in &sets {
        group.bench_function(*name, |b| {
            b.iter(|| train::run(set, &runtime_model).expect("training"))
        });
    }
    group.finish();
}

/// The CPU palette (`rrskin_palette_compute`'s work) of the runtime models trained on the
/// bundled example and on `data/human_heavy` (53 bones): one character on one thread, and 1024
/// characters on 1, 2, ... up to every core's threads (the batched form).
fn palette(c: &mut Criterion) {
    let mut models = vec![("cesiumman", cesiumman())];
    let human = concat!(env!("CARGO_MANIFEST_DIR"), "/../data/human_heavy");
    if let Ok(set) = ExampleSet::load(human) {
        models.push(("human_heavy", set));
    }
    let runtime_model = TrainOptions {
        full_model: false,
        ..options()
    };
    let mut group = c.benchmark_group("palette");
    group
        .sample_size(20)
        .measurement_time(Duration::from_secs(3))
        .warm_up_time(Duration::from_secs(1));
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    for (name, set) in models {
        let model = train::run(&set, &runtime_model)
            .expect("training")
            .model
            .expect("a model");
        let palette = Palette::new(model).expect("palette");
        let characters = 1024;
        let bones = phased_poses(palette.model(), characters, 0);
        let mut out = vec![[0.0; 12]; characters * palette.len()];
        let (j, n) = (palette.model().bone_count(), palette.len());
        group.throughput(criterion::Throughput::Elements(1));
        group.bench_function(BenchmarkId::new(format!("{name}/character"), 1), |b| {
            b.iter(|| {
                palette
                    .compute(&bones[..j], &mut out[..n])
                    .expect("palette")
            })
        });
        group.throughput(criterion::Throughput::Elements(characters as u64));
        let mut threads = 1;
        while threads <= cores {
            group.bench_function(
                BenchmarkId::new(format!("{name}/1024/threads"), threads),
                |b| {
                    b.iter(|| {
                        palette
                            .compute_batch_parallel(&bones, &[], &mut out, threads)
                            .expect("palette")
                    })
                },
            );
            threads *= 2;
        }
    }
    group.finish();
}

/// `rrskin_crowd_set_bones` on 8 crowds from 1, 2, 4 and 8 threads (thread t sets crowds t,
/// t + N, ...): calls on different crowds take only their own crowd's lock. `serialised` puts
/// one lock around every call, as a single registry lock did before, for the comparison.
fn set_bones(c: &mut Criterion) {
    use rrskin::ffi::*;
    use rrskin_render::synthetic::{random_model, random_poses, Spec};
    let spec = Spec {
        grid: 8,
        bones: 53,
        proxies: 8,
        influences: 4,
    };
    let model = random_model(spec, 1).expect("a model");
    let bytes = model.to_bytes();
    let characters = 1024;
    let ok = RrskinStatus::Ok;
    let mut ctx = RrskinContext { id: 0 };
    // SAFETY: valid pointers and lengths in every call below.
    unsafe {
        assert_eq!(rrskin_context_create_headless(0, &mut ctx), ok);
    }
    let mut m = RrskinModel { id: 0 };
    // SAFETY: as above.
    let loaded = unsafe { rrskin_model_load_memory(ctx, bytes.as_ptr(), bytes.len(), &mut m) };
    assert_eq!(loaded, ok);
    let crowds: Vec<RrskinCrowd> = (0..8)
        .map(|_| {
            let mut crowd = RrskinCrowd { id: 0 };
            // SAFETY: as above.
            assert_eq!(
                unsafe { rrskin_crowd_create(m, characters, &mut crowd) },
                ok
            );
            crowd
        })
        .collect();
    let bones = random_poses(&model, characters as usize, 2);
    let floats = bones.as_flattened();
    let one_lock = std::sync::Mutex::new(());
    let mut group = c.benchmark_group("set_bones");
    group
        .sample_size(20)
        .measurement_time(Duration::from_secs(3))
        .warm_up_time(Duration::from_secs(1));
    group.throughput(criterion::Throughput::Bytes(
        (crowds.len() * std::mem::size_of_val(floats)) as u64,
    ));
    for serialised in [false, true] {
        for threads in [1, 2, 4, 8] {
            let name = if serialised {
                "serialised"
            } else {
                "per_crowd"
            };
            group.bench_function(BenchmarkId::new(format!("{name}/threads"), threads), |b| {
                b.iter(|| {
                    std::thread::scope(|s| {
                        for t in 0..threads {
                            let (crowds, one_lock) = (&crowds, &one_lock);
                            s.spawn(move || {
                                for crowd in crowds.iter().skip(t).step_by(threads) {
                                    let _serial = serialised.then(|| one_lock.lock());
                                    // SAFETY: as above.
                                    let set = unsafe {
                                        rrskin_crowd_set_bones(
                                            *crowd,
                                            0,
                                            floats.as_ptr(),
                                            floats.len(),
                                        )
                                    };
                                    assert_eq!(set, RrskinStatus::Ok);
                                }
                            });
                        }
                    })
                })
            });
        }
    }
    group.finish();
    for crowd in crowds {
        assert_eq!(rrskin_crowd_destroy(crowd), ok);
    }
    assert_eq!(rrskin_model_destroy(m), ok);
    assert_eq!(rrskin_context_destroy(ctx), ok);
}

criterion_group!(benches, runtime, palette, set_bones, training);
criterion_main!(benches);
