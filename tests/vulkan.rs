//! The Vulkan runtime against the CPU reference evaluator, on random valid models, with the
//! validation layer and synchronization validation on: any validation message fails the test.
//! Tolerances: `common::POSITION_TOLERANCE`, `common::NORMAL_TOLERANCE`,
//! `common::TANGENT_TOLERANCE`.

mod common;

use common::*;
use rrskin::cpu::CpuEvaluator;
use rrskin::vk::ash::vk;
use rrskin::vk::{
    Aabb, Batch, Context, ContextDesc, Crowd, CrowdDebugSettings, CrowdOptions, GpuModel,
    GpuModelDebugSettings,
};
use rrskin::{Error, Model, NormalMode};
use rrskin_render::synthetic::renumber_bones;

/// Evaluates `characters` random poses on the CPU and in `crowds` crowds on the GPU (one batch,
/// one command buffer) and compares every vertex.
fn check(
    ctx: &Context,
    model: &Model,
    characters: usize,
    options: CrowdOptions,
    seed: u64,
) -> Crowd {
    check_poses(ctx, model, &random_poses(model, characters, seed), options)
}

/// As [`check`], for given poses (C x J transforms).
fn check_poses(
    ctx: &Context,
    model: &Model,
    poses: &[rrskin::predict::Affine],
    options: CrowdOptions,
) -> Crowd {
    let characters = poses.len() / model.bone_count();
    let v = model.vertex_count();
    let mut cpu_pos = vec![[0.0; 3]; characters * v];
    let mut cpu_nrm = vec![[0.0; 3]; characters * v];
    CpuEvaluator::with_normals(model, options.normals)
        .evaluate(poses, &mut cpu_pos, &mut cpu_nrm)
        .expect("CPU evaluation");

    let gpu_model = GpuModel::new(ctx, model).expect("upload");
    // NaN in every buffer before the frame: a pass that reads what none wrote shows here too.
    let options = CrowdOptions {
        debug_settings: CrowdDebugSettings {
            fill_nan: true,
            ..options.debug_settings
        },
        ..options
    };
    let mut crowd = Crowd::with_options(&gpu_model, characters, options).expect("crowd");
    crowd.set_bones(0, poses).expect("bones");
    let mut batch = Batch::new(ctx).expect("batch");
    batch.run(0, &[&crowd]).expect("run");
    let intermediates = crowd.read_intermediates().expect("read back");
    compare_passes(model, poses, gpu_model.fuses_predictors(), &intermediates);
    let rrskin::vk::HostOutput {
        positions: pos,
        normals: nrm,
        ..
    } = crowd.read_back().expect("read back");
    compare(model, (&cpu_pos, &cpu_nrm), (&pos, &nrm));
    assert_no_validation_messages(ctx);
    crowd
}

const LBS: Spec = Spec {
    grid: 12,
    bones: 9,
    proxies: 0,
    influences: 4,
};
const RR: Spec = Spec {
    grid: 12,
    bones: 9,
    proxies: 7,
    influences: 4,
};

/// Both K, and C = 1, 7 and 1000 characters of one model per K.
fn check_sizes(base: Spec, seeds: [u64; 2]) {
    let ctx = validated_context();
    for (k, seed) in [(4, seeds[0]), (8, seeds[1])] {
        let model = random_model(
            Spec {
                influences: k,
                ..base
            },
            seed,
        );
        for c in [1, 7, 1000] {
            check(
                &ctx,
                &model,
                c,
                CrowdOptions::default(),
                seed * 10 + c as u64,
            );
        }
    }
}

#[test]
fn plain_lbs_matches_cpu_for_1_7_and_1000_characters() {
    check_sizes(LBS, [1, 2]);
}

#[test]
fn rotational_regression_matches_cpu_for_1_7_and_1000_characters() {
    check_sizes(RR, [3, 4]);
}

#[test]
fn gemm_tiles_cover_odd_sizes() {
    // P and 3C not multiples of the 16 x 64 output tile, depth 3P + 4J not a multiple of 16.
    let ctx = validated_context();
    for (p, j, c) in [(1, 1, 1), (17, 5, 23), (33, 3, 22)] {
        let model = random_model(
            Spec {
                grid: 6,
                bones: j,
                proxies: p,
                influences: 8,
            },
            p as u64,
        );
        check(&ctx, &model, c, CrowdOptions::default(), 77);
    }
}

/// Models whose C1|C2 is sparse take the block-sparse product, dense ones the GEMM; sparse ones
/// whose proxies read one key each evaluate their predictors in the product (the fused one),
/// those reading two keys run the predictor pass and the sparse product; all match the CPU (odd
/// proxy counts, 1, 7, 65 and 1000 characters). With P = J = 1 the pattern keeps all 7
/// columns: too dense, the GEMM stays.
#[test]
fn the_sparse_product_is_chosen_for_sparse_models_and_matches_cpu() {
    let ctx = validated_context();
    let sizes = [(7, 9, 4, true), (1, 1, 8, false), (40, 12, 8, true)];
    for ((p, j, k, sparse_product), keys) in sizes.into_iter().flat_map(|s| [(s, 1), (s, 2)]) {
        let dense = random_model(
            Spec {
                grid: 8,
                bones: j,
                proxies: p,
                influences: k,
            },
            p as u64 + 100,
        );
        assert!(!GpuModel::new(&ctx, &dense)
            .expect("upload")
            .is_block_sparse());
        let sparse = joint_blend_pattern(&dense, keys);
        let gpu = GpuModel::new(&ctx, &sparse).expect("upload");
        assert_eq!(gpu.is_block_sparse(), sparse_product, "P = {p}, J = {j}");
        // With P = 1 the two keys are one.
        let one_key = keys == 1 || p == 1;
        assert_eq!(
            gpu.fuses_predictors(),
            sparse_product && one_key,
            "P = {p}, J = {j}, {keys} keys"
        );
        for c in [1, 7, 65, 1000] {
            check(&ctx, &sparse, c, CrowdOptions::default(), c as u64);
        }
    }
}

#[test]
fn crowds_split_into_chunks_when_a_binding_would_be_too_large() {
    let ctx = validated_context();
    let model = random_model(RR, 5);
    // 144 vertices x 12 bytes = 1728 bytes per character; 64 KiB bindings hold 37 characters,
    // rounded down to the offset alignment's granularity.
    let options = CrowdOptions {
        debug_settings: CrowdDebugSettings {
            max_binding_bytes: Some(64 * 1024),
            ..Default::default()
        },
        ..CrowdOptions::default()
    };
    let crowd = check(&ctx, &model, 300, options, 9);
    assert!(crowd.chunk_count() >= 8, "{} chunks", crowd.chunk_count());
}

/// A buffer past the device's maxMemoryAllocationSize or maxBufferSize is undefined behaviour,
/// not a Vulkan error: a crowd that would need one is refused before anything is made, naming
/// the buffer and the limit. Lowered by the debug settings until every buffer just fits, the
/// crowd runs, and its read-back stages the outputs in pieces of at most that size.
#[test]
fn a_buffer_past_the_devices_largest_is_refused_and_one_at_it_reads_back_in_pieces() {
    let ctx = validated_context();
    let model = random_model(RR, 7);
    let characters = 300;
    let at_most = |limit: u64| CrowdOptions {
        debug_settings: CrowdDebugSettings {
            max_buffer_bytes: Some(limit),
            ..Default::default()
        },
        ..CrowdOptions::default()
    };
    let gpu = GpuModel::new(&ctx, &model).expect("upload");
    let mut limit = 1024;
    let fits = loop {
        match Crowd::with_options(&gpu, characters, at_most(limit)) {
            Ok(_) => break limit,
            Err(
                e @ Error::BufferTooLarge {
                    needed,
                    limit: told,
                    ..
                },
            ) => {
                assert!(needed > limit && told == limit, "{e}");
                let text = e.to_string();
                assert!(
                    text.contains("maxMemoryAllocationSize") && text.contains("crowd"),
                    "{text}"
                );
                limit = needed;
            }
            Err(e) => panic!("{e}"),
        }
    };
    let positions = characters as u64 * model.vertex_count() as u64 * 12;
    assert!(fits >= positions && fits < 2 * positions, "{fits} bytes");
    check(&ctx, &model, characters, at_most(fits), 7);
    assert_no_validation_messages(&ctx);
}

/// A device's maxPerStageDescriptorStorageBuffers decides which models and modes it runs, not
/// whether the runtime starts: lowered to what a plain LBS model's passes bind with recomputed
/// normals, that crowd runs and matches the CPU, and the same model with transformed normals
/// (their skinning pass binds the normals too) is refused when its crowd is made, naming the
/// limit. No pipeline past the limit is made, which the validation layer would report.
#[test]
fn a_device_with_few_storage_buffers_runs_the_models_whose_passes_fit() {
    let capped = |n: u32| {
        Context::new(&ContextDesc {
            validation: true,
            max_storage_buffers_per_stage: Some(n),
            ..Default::default()
        })
        .expect("a Vulkan device with the validation layer")
    };
    let needs = |ctx: &Context, model: &Model, normals: NormalMode| {
        let gpu = GpuModel::new(ctx, model).expect("upload");
        let options = CrowdOptions {
            normals,
            ..CrowdOptions::default()
        };
        match Crowd::with_options(&gpu, 4, options) {
            Ok(_) => None,
            Err(e @ Error::DeviceLimit { needed, .. }) => {
                let text = e.to_string();
                assert!(
                    text.contains("maxPerStageDescriptorStorageBuffers"),
                    "{text}"
                );
                Some(needed as u32)
            }
            Err(e) => panic!("{e}"),
        }
    };
    let lbs = random_model(LBS, 3);
    let four = capped(4);
    let recomputed = needs(&four, &lbs, NormalMode::Recomputed).expect("more than 4 buffers");
    let ctx = capped(recomputed);
    assert_eq!(needs(&ctx, &lbs, NormalMode::Recomputed), None);
    check(&ctx, &lbs, 5, CrowdOptions::default(), 3);
    let transformed = needs(&ctx, &lbs, NormalMode::Transformed).expect("a wider pass");
    assert!(transformed > recomputed);
    assert!(transformed <= rrskin::vk::requirements().storage_buffers_per_stage);
    assert_no_validation_messages(&ctx);
    assert_no_validation_messages(&four);
}

#[test]
fn ten_thousand_characters_beyond_the_device_storage_range() {
    let ctx = validated_context();
    // 35 x 35 = 1225 vertices: 10,000 characters of positions are 147 MB, beyond lavapipe's
    // 128 MiB maxStorageBufferRange (on devices with a larger range this is one chunk).
    let model = random_model(
        Spec {
            grid: 35,
            bones: 6,
            proxies: 5,
            influences: 4,
        },
        6,
    );
    let crowd = check(&ctx, &model, 10_000, CrowdOptions::default(), 11);
    let bytes = 10_000 * model.vertex_count() as u64 * 12;
    if bytes > ctx.limits().max_storage_buffer_range {
        assert!(crowd.chunk_count() >= 2);
    }
}

/// A rig whose joint order lists every child before its parent (as many glTF skins do), of
/// the size of the human_heavy set (13,456 vertices, 53 bones, 60 proxies): posing walks the
/// hierarchy in a computed order, and the GPU matches the CPU reference.
#[test]
fn a_rig_listing_children_before_parents_matches_cpu() {
    let model = random_model(
        Spec {
            grid: 116,
            bones: 53,
            proxies: 60,
            influences: 4,
        },
        21,
    );
    let reversed: Vec<usize> = (0..model.bone_count()).rev().collect();
    let model = renumber_bones(&model, &reversed).expect("a permutation");
    let children_first = (0..model.bone_count())
        .filter_map(|b| model.parent(b).map(|p| p > b))
        .all(|after| after);
    assert!(children_first, "every parent comes after its children");
    check(&validated_context(), &model, 3, CrowdOptions::default(), 5);
}

/// A trained model file (e.g. one trained from human_heavy, whose joint order lists children
/// first: training it takes minutes, too long for the suite) playing its own animation, against
/// the CPU reference: `RRSKIN_MODEL=model.rrs cargo test --test vulkan -- --ignored`.
#[test]
#[ignore = "needs RRSKIN_MODEL, a trained model file"]
fn a_trained_model_file_playing_its_animation_matches_cpu() {
    let path = std::env::var_os("RRSKIN_MODEL").expect("RRSKIN_MODEL names a .rrs file");
    let model = Model::load(&path).expect("a valid model file");
    let poses = rrskin_render::phased_poses(&model, 4, 0);
    assert!(!poses.is_empty(), "the model carries no animation");
    check_poses(
        &validated_context(),
        &model,
        &poses,
        CrowdOptions::default(),
    );
}

#[test]
fn several_crowds_of_different_models_in_one_command_buffer() {
    let ctx = validated_context();
    let models = [
        random_model(LBS, 21),
        random_model(
            Spec {
                influences: 8,
                ..RR
            },
            22,
        ),
        random_model(
            Spec {
                grid: 7,
                bones: 4,
                proxies: 3,
                influences: 4,
            },
            23,
        ),
        joint_blend_pattern(&random_model(Spec { proxies: 20, ..RR }, 24), 1),
        joint_blend_pattern(&random_model(Spec { proxies: 20, ..RR }, 25), 2),
    ];
    let gpu: Vec<GpuModel> = models
        .iter()
        .map(|m| GpuModel::new(&ctx, m).expect("upload"))
        .collect();
    // Of the two block-sparse models, one fuses its predictors into the product.
    let count = |f: fn(&GpuModel) -> bool| gpu.iter().filter(|g| f(g)).count();
    assert_eq!(count(GpuModel::is_block_sparse), 2);
    assert_eq!(count(GpuModel::fuses_predictors), 1);
    let counts = [5, 9, 3, 6, 4];
    let mut crowds = Vec::new();
    let mut expected = Vec::new();
    for ((model, g), &c) in models.iter().zip(&gpu).zip(&counts) {
        let poses = random_poses(model, c, c as u64);
        let mut crowd = Crowd::new(g, c).expect("crowd");
        crowd.set_bones(0, &poses).expect("bones");
        let v = model.vertex_count();
        let (mut p, mut n) = (vec![[0.0; 3]; c * v], vec![[0.0; 3]; c * v]);
        CpuEvaluator::new(model)
            .evaluate(&poses, &mut p, &mut n)
            .expect("cpu");
        crowds.push(crowd);
        expected.push((p, n));
    }
    let mut batch = Batch::new(&ctx).expect("batch");
    let refs: Vec<&Crowd> = crowds.iter().collect();
    for _frame in 0..3 {
        batch.run(0, &refs).expect("run");
    }
    for ((model, crowd), (p, n)) in models.iter().zip(&crowds).zip(&expected) {
        let rrskin::vk::HostOutput {
            positions: gp,
            normals: gn,
            ..
        } = crowd.read_back().expect("read back");
        compare(model, (p, n), (&gp, &gn));
    }
    let t = batch.timings(0).expect("timestamps on lavapipe");
    assert!(
        t.skin_ms > 0.0 && t.normals_ms > 0.0 && t.predict_ms > 0.0 && t.product_ms > 0.0,
        "{t:?}"
    );
    assert_no_validation_messages(&ctx);
}

#[test]
fn a_new_crowd_renders_the_rest_pose() {
    let ctx = validated_context();
    let model = random_model(RR, 8);
    let crowd = Crowd::new(&GpuModel::new(&ctx, &model).expect("upload"), 2).expect("crowd");
    let mut batch = Batch::new(&ctx).expect("batch");
    batch.run(0, &[&crowd]).expect("run");
    let rrskin::vk::HostOutput {
        positions: pos,
        normals: nrm,
        ..
    } = crowd.read_back().expect("read back");
    let identity =
        vec![[1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0]; 2 * model.bone_count()];
    let v = model.vertex_count();
    let (mut p, mut n) = (vec![[0.0; 3]; 2 * v], vec![[0.0; 3]; 2 * v]);
    CpuEvaluator::new(&model)
        .evaluate(&identity, &mut p, &mut n)
        .expect("cpu");
    compare(&model, (&p, &n), (&pos, &nrm));
    assert_no_validation_messages(&ctx);
}

#[test]
fn bad_per_frame_input_is_an_error() {
    let ctx = validated_context();
    let model = random_model(LBS, 9);
    let mut crowd = Crowd::new(&GpuModel::new(&ctx, &model).expect("upload"), 3).expect("crowd");
    let j = model.bone_count();
    let mut poses = random_poses(&model, 3, 1);
    assert_eq!(
        crowd.set_bones(0, &poses[..3 * j - 1]),
        Err(Error::WrongLength {
            what: "crowd bone transforms",
            expected: 3 * j,
            actual: 3 * j - 1
        })
    );
    assert_eq!(
        crowd.set_character_bones(0, 3, &poses[..j]),
        Err(Error::OutOfRange {
            what: "character",
            index: 3,
            count: 3
        })
    );
    poses[j + 1][5] = f32::NAN;
    assert_eq!(
        crowd.set_bones(0, &poses),
        Err(Error::NonFinite {
            what: "bone transforms",
            index: 12 * (j + 1) + 5
        })
    );
    assert!(matches!(
        Crowd::new(crowd.model(), 0),
        Err(Error::OutOfRange { .. })
    ));
    assert_no_validation_messages(&ctx);
}

/// A host-visible, coherent buffer of the test's own (raw Vulkan: the runtime hands out none),
/// mapped; freed by `destroy`.
struct HostBuffer {
    buffer: vk::Buffer,
    memory: vk::DeviceMemory,
    mapped: *const f32,
}

impl HostBuffer {
    fn new(ctx: &Context, floats: usize) -> HostBuffer {
        let d = ctx.device();
        let info = vk::BufferCreateInfo::default()
            .size(floats as u64 * 4)
            .usage(vk::BufferUsageFlags::TRANSFER_DST);
        // SAFETY: the context's live device and physical device; sizes from the requirements.
        unsafe {
            let buffer = d.create_buffer(&info, None).expect("buffer");
            let needs = d.get_buffer_memory_requirements(buffer);
            let types = ctx
                .instance()
                .get_physical_device_memory_properties(ctx.physical_device());
            let host =
                vk::MemoryPropertyFlags::HOST_VISIBLE | vk::MemoryPropertyFlags::HOST_COHERENT;
            let index = (0..types.memory_type_count)
                .find(|&t| {
                    needs.memory_type_bits & (1 << t) != 0
                        && types.memory_types[t as usize].property_flags.contains(host)
                })
                .expect("host-visible coherent memory");
            let alloc = vk::MemoryAllocateInfo::default()
                .allocation_size(needs.size)
                .memory_type_index(index);
            let memory = d.allocate_memory(&alloc, None).expect("memory");
            d.bind_buffer_memory(buffer, memory, 0).expect("bind");
            let mapped = d
                .map_memory(memory, 0, vk::WHOLE_SIZE, vk::MemoryMapFlags::empty())
                .expect("map") as *const f32;
            HostBuffer {
                buffer,
                memory,
                mapped,
            }
        }
    }

    /// `count` xyz triples from float `at` (after the GPU wrote them and a fence wait).
    fn xyz(&self, at: usize, count: usize) -> Vec<[f32; 3]> {
        // SAFETY: mapped for the buffer's whole size, which the callers stay within.
        let floats = unsafe { std::slice::from_raw_parts(self.mapped.add(at), 3 * count) };
        floats.chunks_exact(3).map(|p| [p[0], p[1], p[2]]).collect()
    }

    /// `count` xyzw quadruples from float `at`.
    fn xyzw(&self, at: usize, count: usize) -> Vec<[f32; 4]> {
        // SAFETY: as in `xyz`.
        let floats = unsafe { std::slice::from_raw_parts(self.mapped.add(at), 4 * count) };
        floats
            .chunks_exact(4)
            .map(|p| [p[0], p[1], p[2], p[3]])
            .collect()
    }

    fn destroy(self, ctx: &Context) {
        // SAFETY: the GPU finished with the buffer (the caller waited for its fences).
        unsafe {
            ctx.device().destroy_buffer(self.buffer, None);
            ctx.device().free_memory(self.memory, None);
        }
    }
}

/// Each character's box of CPU positions (C x V).
fn boxes_of(positions: &[[f32; 3]], v: usize) -> Vec<Aabb> {
    positions
        .chunks_exact(v)
        .map(|c| {
            let fold = |f: fn(f32, f32) -> f32, start: f32| {
                c.iter()
                    .fold([start; 3], |b, p| std::array::from_fn(|i| f(b[i], p[i])))
            };
            Aabb {
                min: fold(f32::min, f32::INFINITY),
                max: fold(f32::max, f32::NEG_INFINITY),
            }
        })
        .collect()
}

/// F frames of a crowd for F frames in flight, all pending on the queue at once: the first
/// frame's command buffer starts by waiting on an event the host sets only after every frame was
/// posed (`set_bones(f, ..)` while the frames before it are still pending) and submitted. Each
/// frame copies its positions, normals (and previous positions) to a buffer of its own in its own
/// command buffer; its bounds stay in its frame slot. Every frame is checked against the CPU
/// reference (tolerances of `compare`; boxes within `POSITION_TOLERANCE * max(1, |x|)`), with
/// the validation layer and synchronization validation on. One bone buffer shared by the frames
/// would give every frame the last frame's pose.
fn overlapping_frames(model: &Model, characters: usize, options: CrowdOptions) {
    let ctx = validated_context();
    let f = options.frames_in_flight;
    let v = model.vertex_count();
    let n = characters * v;
    let gpu_model = GpuModel::new(&ctx, model).expect("upload");
    let mut crowd = Crowd::with_options(&gpu_model, characters, options).expect("crowd");
    let mut batch = Batch::new(&ctx).expect("batch");
    let d = ctx.device();
    // Per frame: positions, normals, previous positions (3 n floats each), tangents (4 n).
    let copies: Vec<HostBuffer> = (0..f).map(|_| HostBuffer::new(&ctx, 13 * n)).collect();
    let poses: Vec<_> = (0..f)
        .map(|frame| random_poses(model, characters, 100 + frame as u64))
        .collect();
    // SAFETY: objects of the context's live device, destroyed below after the fences.
    let (pool, cmds, fences, event) = unsafe {
        let pool = d
            .create_command_pool(
                &vk::CommandPoolCreateInfo::default().queue_family_index(ctx.queue_family_index()),
                None,
            )
            .expect("pool");
        let cmds = d
            .allocate_command_buffers(
                &vk::CommandBufferAllocateInfo::default()
                    .command_pool(pool)
                    .command_buffer_count(f as u32),
            )
            .expect("command buffers");
        let fences: Vec<vk::Fence> = (0..f)
            .map(|_| {
                d.create_fence(&vk::FenceCreateInfo::default(), None)
                    .expect("fence")
            })
            .collect();
        let event = d
            .create_event(&vk::EventCreateInfo::default(), None)
            .expect("event");
        (pool, cmds, fences, event)
    };
    for frame in 0..f {
        crowd.set_bones(frame, &poses[frame]).expect("bones");
        let cmd = cmds[frame];
        // SAFETY: a fresh command buffer of our pool; the buffers live until the fences.
        unsafe {
            d.begin_command_buffer(cmd, &vk::CommandBufferBeginInfo::default())
                .expect("begin");
            if frame == 0 {
                let host = [vk::MemoryBarrier::default()
                    .src_access_mask(vk::AccessFlags::HOST_WRITE)
                    .dst_access_mask(vk::AccessFlags::SHADER_READ)];
                d.cmd_wait_events(
                    cmd,
                    &[event],
                    vk::PipelineStageFlags::HOST,
                    vk::PipelineStageFlags::COMPUTE_SHADER,
                    &host,
                    &[],
                    &[],
                );
            }
            batch.record(cmd, frame, &[&crowd]).expect("record");
            let out = crowd.output(frame).expect("the frame's output");
            if let Some(family) = options.release_to_queue_family {
                // The engine's side of the ownership transfer, back on this queue: acquire what
                // the recording released (the copies below then read defined contents).
                let released = [
                    Some(out.positions),
                    Some(out.normals),
                    out.bounds,
                    out.tangents,
                ];
                let acquire: Vec<vk::BufferMemoryBarrier> = (released.into_iter().flatten())
                    .map(|buffer| {
                        vk::BufferMemoryBarrier::default()
                            .dst_access_mask(vk::AccessFlags::TRANSFER_READ)
                            .src_queue_family_index(family)
                            .dst_queue_family_index(ctx.queue_family_index())
                            .buffer(buffer)
                            .size(vk::WHOLE_SIZE)
                    })
                    .collect();
                d.cmd_pipeline_barrier(
                    cmd,
                    vk::PipelineStageFlags::TOP_OF_PIPE,
                    vk::PipelineStageFlags::TRANSFER,
                    vk::DependencyFlags::empty(),
                    &[],
                    &acquire,
                    &[],
                );
            }
            let bytes = n as u64 * 12;
            let sources = [
                Some(out.positions),
                Some(out.normals),
                out.previous_positions,
            ];
            for (i, src) in sources.into_iter().enumerate() {
                if let Some(src) = src {
                    let region = [vk::BufferCopy {
                        src_offset: out.offset,
                        dst_offset: i as u64 * bytes,
                        size: bytes,
                    }];
                    d.cmd_copy_buffer(cmd, src, copies[frame].buffer, &region);
                }
            }
            if let Some(src) = out.tangents {
                let region = [vk::BufferCopy {
                    src_offset: out.offset,
                    dst_offset: 3 * bytes,
                    size: n as u64 * 16,
                }];
                d.cmd_copy_buffer(cmd, src, copies[frame].buffer, &region);
            }
            let to_host = [vk::MemoryBarrier::default()
                .src_access_mask(vk::AccessFlags::TRANSFER_WRITE)
                .dst_access_mask(vk::AccessFlags::HOST_READ)];
            d.cmd_pipeline_barrier(
                cmd,
                vk::PipelineStageFlags::TRANSFER,
                vk::PipelineStageFlags::HOST,
                vk::DependencyFlags::empty(),
                &to_host,
                &[],
                &[],
            );
            d.end_command_buffer(cmd).expect("end");
            let submit = [vk::SubmitInfo::default().command_buffers(std::slice::from_ref(&cmd))];
            ctx.with_queue(|q| d.queue_submit(q, &submit, fences[frame]))
                .expect("submit");
        }
    }
    // SAFETY: the event and fences are ours; every frame was submitted.
    unsafe {
        assert_eq!(
            d.get_fence_status(fences[0]),
            Ok(false),
            "the first frame is still pending"
        );
        d.set_event(event).expect("set event");
        d.wait_for_fences(&fences, true, u64::MAX).expect("wait");
    }
    let mut cpu = CpuEvaluator::with_normals(model, options.normals);
    let mut previous: Option<Vec<[f32; 3]>> = None;
    for frame in 0..f {
        let (mut p, mut nrm) = (vec![[0.0; 3]; n], vec![[0.0; 3]; n]);
        let copy = &copies[frame];
        if options.tangents {
            let mut t = vec![[0.0; 4]; n];
            cpu.evaluate_with_tangents(&poses[frame], &mut p, &mut nrm, &mut t)
                .expect("cpu");
            compare_tangents(model, &p, &t, (&copy.xyzw(9 * n, n), &copy.xyz(3 * n, n)));
        } else {
            cpu.evaluate(&poses[frame], &mut p, &mut nrm).expect("cpu");
        }
        compare(model, (&p, &nrm), (&copy.xyz(0, n), &copy.xyz(3 * n, n)));
        if let (true, Some(before)) = (options.previous_positions, &previous) {
            let prev = copy.xyz(6 * n, n);
            compare_positions(before, &prev);
        }
        if options.bounds {
            let mut boxes = vec![Aabb::default(); characters];
            crowd.read_bounds(frame, &mut boxes).expect("bounds");
            for (want, got) in boxes_of(&p, v).iter().zip(&boxes) {
                for (w, g) in want
                    .min
                    .iter()
                    .chain(&want.max)
                    .zip(got.min.iter().chain(&got.max))
                {
                    assert!(
                        (w - g).abs() <= POSITION_TOLERANCE * w.abs().max(1.0),
                        "frame {frame}: box {got:?}, CPU {want:?}"
                    );
                }
            }
        }
        previous = Some(p);
    }
    // SAFETY: every submission completed.
    unsafe {
        for fence in fences {
            d.destroy_fence(fence, None);
        }
        d.destroy_event(event, None);
        d.destroy_command_pool(pool, None);
    }
    for copy in copies {
        copy.destroy(&ctx);
    }
    assert_no_validation_messages(&ctx);
}

/// Positions only, at the tolerance of `compare`.
fn compare_positions(cpu: &[[f32; 3]], gpu: &[[f32; 3]]) {
    for (i, (c, g)) in cpu.iter().zip(gpu).enumerate() {
        let norm = c.iter().map(|x| x * x).sum::<f32>().sqrt().max(1.0);
        let dist = c
            .iter()
            .zip(g)
            .map(|(a, b)| (a - b).powi(2))
            .sum::<f32>()
            .sqrt();
        assert!(
            dist <= POSITION_TOLERANCE * norm,
            "position {i}: cpu {c:?} gpu {g:?}"
        );
    }
}

#[test]
fn two_frames_in_flight_each_match_cpu() {
    overlapping_frames(&random_model(LBS, 31), 5, CrowdOptions::default());
}

#[test]
fn four_frames_in_flight_of_a_reduced_model_each_match_cpu() {
    let options = CrowdOptions {
        frames_in_flight: 4,
        ..CrowdOptions::default()
    };
    overlapping_frames(&random_model(RR, 32), 7, options);
}

#[test]
fn frame_slots_out_of_range_are_errors() {
    let ctx = validated_context();
    let model = random_model(LBS, 33);
    let gpu = GpuModel::new(&ctx, &model).expect("upload");
    for frames in [0, 5] {
        let options = CrowdOptions {
            frames_in_flight: frames,
            ..CrowdOptions::default()
        };
        assert!(matches!(
            Crowd::with_options(&gpu, 1, options),
            Err(Error::OutOfRange {
                what: "frames in flight (1 to 4)",
                ..
            })
        ));
    }
    let mut crowd = Crowd::new(&gpu, 2).expect("crowd");
    assert_eq!(crowd.frames_in_flight(), 2, "the default");
    let poses = random_poses(&model, 2, 1);
    let past = Err(Error::OutOfRange {
        what: "frame in flight",
        index: 2,
        count: 2,
    });
    assert_eq!(crowd.set_bones(2, &poses), past);
    assert_eq!(
        crowd.set_character_bones(2, 0, &poses[..model.bone_count()]),
        past
    );
    assert!(crowd.output(2).is_err());
    let mut batch = Batch::new(&ctx).expect("batch");
    assert_eq!(batch.run(2, &[&crowd]), past);
    assert!(matches!(
        batch.run(0, &[&crowd, &crowd]),
        Err(Error::Mismatch { .. })
    ));
    batch.run(1, &[&crowd]).expect("run frame 1");
    assert!(matches!(batch.timings(0), Err(Error::NotReady { .. })));
    assert!(batch.timings(1).is_ok());
    assert_no_validation_messages(&ctx);
}

#[test]
fn previous_positions_and_bounds_of_three_frames_in_flight_match_cpu() {
    let options = CrowdOptions {
        frames_in_flight: 3,
        previous_positions: true,
        bounds: true,
        ..CrowdOptions::default()
    };
    overlapping_frames(&random_model(RR, 34), 6, options);
}

/// Bounds and previous positions of a crowd split into chunks (descriptor ranges at chunk
/// offsets of every per-frame buffer).
#[test]
fn previous_positions_and_bounds_across_chunks_match_cpu() {
    let options = CrowdOptions {
        previous_positions: true,
        bounds: true,
        debug_settings: CrowdDebugSettings {
            max_binding_bytes: Some(64 * 1024),
            ..Default::default()
        },
        ..CrowdOptions::default()
    };
    overlapping_frames(&random_model(LBS, 35), 300, options);
}

/// Tangents with every other output of three frames in flight, K = 4 and a reduced model;
/// K = 8, block-sparse with the predictors fused in (the shipped models), across chunks; the
/// normals made as `normals` says.
fn tangents_of_overlapping_frames(normals: NormalMode) {
    let options = CrowdOptions {
        frames_in_flight: 3,
        previous_positions: true,
        bounds: true,
        tangents: true,
        normals,
        ..CrowdOptions::default()
    };
    overlapping_frames(&random_model(RR, 51), 5, options);
    let k8 = Spec {
        influences: 8,
        ..RR
    };
    let chunked = CrowdOptions {
        frames_in_flight: 2,
        tangents: true,
        normals,
        debug_settings: CrowdDebugSettings {
            max_binding_bytes: Some(64 * 1024),
            ..Default::default()
        },
        ..CrowdOptions::default()
    };
    let model = joint_blend_pattern(&random_model(k8, 52), 1);
    overlapping_frames(&model, 40, chunked);
}

#[test]
fn tangents_of_overlapping_frames_match_cpu() {
    tangents_of_overlapping_frames(NormalMode::Recomputed);
}

/// Transformed normals (the skinning pass writes normals and tangents, no normals or tangents
/// pass runs) against the CPU reference's: both K, plain LBS, dense, block-sparse and fused
/// products, with pose-space and proxy correctives, with tangents over overlapping frames and
/// across chunks.
#[test]
fn transformed_normals_and_tangents_match_cpu() {
    let ctx = validated_context();
    let transformed = CrowdOptions {
        normals: NormalMode::Transformed,
        ..CrowdOptions::default()
    };
    let k8 = Spec {
        influences: 8,
        ..RR
    };
    let models = [
        random_model(LBS, 61),
        random_model(RR, 62),
        random_model(k8, 63),
        joint_blend_pattern(&random_model(k8, 64), 1),
        joint_blend_pattern(&random_model(Spec { proxies: 20, ..RR }, 65), 2),
        with_correctives(&random_model(RR, 66), 3, 2),
        with_proxy_correctives(&random_model(RR, 67), true, 2, 3),
    ];
    for model in &models {
        check(&ctx, model, 7, transformed, 5);
    }
    // The two modes differ (so the comparison tells which one the GPU ran).
    let poses = random_poses(&models[1], 7, 5);
    let n = 7 * models[1].vertex_count();
    let normals = |mode| {
        let (mut p, mut nrm) = (vec![[0.0; 3]; n], vec![[0.0; 3]; n]);
        (CpuEvaluator::with_normals(&models[1], mode).evaluate(&poses, &mut p, &mut nrm))
            .expect("cpu");
        nrm
    };
    let (a, b) = (
        normals(NormalMode::Recomputed),
        normals(NormalMode::Transformed),
    );
    let largest = (a.iter().zip(&b))
        .map(|(x, y)| (0..3).map(|i| (x[i] - y[i]).abs()).fold(0.0, f32::max))
        .fold(0.0, f32::max);
    assert!(
        largest > 10.0 * NORMAL_TOLERANCE,
        "the modes differ by {largest}"
    );
    tangents_of_overlapping_frames(NormalMode::Transformed);
}

#[test]
fn tangents_of_a_model_without_rest_tangents_are_refused() {
    let ctx = validated_context();
    let model = random_model(LBS, 53);
    let bare = Model::new(rrskin::ModelParts {
        rest_tangents: Vec::new(),
        ..model.parts().clone()
    })
    .expect("valid without tangents");
    let gpu = GpuModel::new(&ctx, &bare).expect("upload");
    assert!(!gpu.has_tangents());
    let options = CrowdOptions {
        tangents: true,
        ..CrowdOptions::default()
    };
    assert!(matches!(
        Crowd::with_options(&gpu, 2, options),
        Err(Error::NotInModel { .. })
    ));
    let poses = random_poses(&bare, 1, 1);
    let v = bare.vertex_count();
    let (mut p, mut n, mut t) = (vec![[0.0; 3]; v], vec![[0.0; 3]; v], vec![[0.0; 4]; v]);
    assert!(matches!(
        CpuEvaluator::new(&bare).evaluate_with_tangents(&poses, &mut p, &mut n, &mut t),
        Err(Error::NotInModel { .. })
    ));
    assert_no_validation_messages(&ctx);
}

#[test]
fn optional_outputs_are_absent_unless_asked_for() {
    let ctx = validated_context();
    let model = random_model(LBS, 36);
    let gpu = GpuModel::new(&ctx, &model).expect("upload");
    let mut crowd = Crowd::new(&gpu, 2).expect("crowd");
    let out = crowd.output(0).expect("frame 0");
    assert!(out.previous_positions.is_none() && out.bounds.is_none() && out.tangents.is_none());
    assert!(!crowd.has_tangents() && crowd.read_back().expect("read back").tangents.is_empty());
    let mut boxes = [Aabb::default(); 2];
    assert!(matches!(
        crowd.read_bounds(0, &mut boxes),
        Err(Error::NotEnabled { .. })
    ));
    assert!(matches!(
        crowd.read_bounds(0, &mut boxes[..1]),
        Err(Error::WrongLength { .. })
    ));
    // With previous positions, frames write the two buffers in turn, whatever their slot.
    let options = CrowdOptions {
        frames_in_flight: 3,
        previous_positions: true,
        ..CrowdOptions::default()
    };
    let crowd = Crowd::with_options(&gpu, 2, options).expect("crowd");
    let mut batch = Batch::new(&ctx).expect("batch");
    let mut written = Vec::new();
    for frame in [0, 1, 2, 0] {
        batch.run(frame, &[&crowd]).expect("run");
        let out = crowd.output(frame).expect("output");
        assert_eq!(out.positions, crowd.latest_output().positions);
        if let Some(&last) = written.last() {
            assert_eq!(out.previous_positions, Some(last));
            assert_ne!(out.positions, last);
        }
        written.push(out.positions);
    }
    assert_no_validation_messages(&ctx);
}

/// The memory queries, made from sizes before anything exists, are the bytes of the buffers
/// then created.
#[test]
fn memory_queries_are_the_bytes_created() {
    use rrskin::vk::{crowd_bytes, crowd_largest_buffer_bytes, model_bytes, ModelSizes};
    let ctx = validated_context();
    let with_everything = CrowdOptions {
        frames_in_flight: 3,
        previous_positions: true,
        bounds: true,
        tangents: true,
        ..CrowdOptions::default()
    };
    let models = [(LBS, 41), (RR, 42)].map(|(spec, seed)| random_model(spec, seed));
    let sparse = joint_blend_pattern(&models[1], 1);
    // With correctives: the targets in the rest buffer, the map, the drivers and the weights.
    let corrected = with_correctives(&models[1], 5, 1);
    // With proxy correctives: their proxies and drivers, kernels and maps (and, where they see
    // gravity, the model's up and the characters' up vectors).
    let up = Some([1.0, 0.0, 0.0]);
    let proxy_corrected = [
        (true, None, 0),
        (false, None, 3),
        (true, None, 2),
        (false, up, 2),
    ]
    .map(|(linear, up, kernels)| with_proxy_correctives_seeing(&models[1], linear, up, kernels, 2));
    for model in (models.iter().chain([&sparse, &corrected])).chain(&proxy_corrected) {
        let sizes = ModelSizes::of(model);
        let gpu = GpuModel::new(&ctx, model).expect("upload");
        let spec = (sizes, gpu.is_block_sparse());
        assert_eq!(sizes.product_columns > 0, gpu.is_block_sparse());
        assert_eq!(gpu.is_block_sparse(), std::ptr::eq(model, &sparse));
        assert_eq!(model_bytes(&sizes), gpu.memory_bytes(), "{spec:?}");
        for options in [CrowdOptions::default(), with_everything] {
            let expected = crowd_bytes(&sizes, 9, &options).expect("query");
            let crowd = Crowd::with_options(&gpu, 9, options).expect("crowd");
            assert_eq!(expected, crowd.memory_bytes(), "{spec:?} {options:?}");
        }
    }
    // Every option costs what it says: F bone slots, a second positions buffer, F bounds slots.
    let model = random_model(RR, 43);
    let sizes = ModelSizes::of(&model);
    let bytes = |o: CrowdOptions| crowd_bytes(&sizes, 10, &o).expect("query");
    let plain = CrowdOptions {
        frames_in_flight: 1,
        ..CrowdOptions::default()
    };
    let (j, v) = (model.bone_count() as u64, model.vertex_count() as u64);
    let previous = CrowdOptions {
        previous_positions: true,
        ..plain
    };
    assert_eq!(bytes(previous) - bytes(plain), 10 * v * 12);
    let two = CrowdOptions {
        frames_in_flight: 2,
        ..plain
    };
    assert_eq!(bytes(two) - bytes(plain), 10 * j * 48);
    let bounded = CrowdOptions {
        bounds: true,
        ..two
    };
    assert_eq!(bytes(bounded) - bytes(two), 2 * 10 * 32);
    let tangents = CrowdOptions {
        tangents: true,
        ..two
    };
    assert_eq!(bytes(tangents) - bytes(two), 10 * v * 16);
    let bare = ModelSizes {
        tangents: false,
        ..sizes
    };
    assert_eq!(model_bytes(&sizes) - model_bytes(&bare), v * 16 - 16);
    // The largest buffer per character, of bones (48 J), B = [d; q] (12 (3P + 4J)), the
    // palette [t; q] (48 (P + J)), positions and normals (12 V); never more than a character's
    // whole share.
    let largest = crowd_largest_buffer_bytes(&sizes, &plain).expect("query");
    let p = model.proxy_count() as u64;
    assert_eq!(
        largest,
        [48 * j, 12 * (3 * p + 4 * j), 48 * (p + j), 12 * v]
            .into_iter()
            .max()
            .unwrap_or(0)
    );
    assert!(largest <= crowd_bytes(&sizes, 1, &plain).expect("query"));
    assert_no_validation_messages(&ctx);
}

#[test]
fn a_crowd_beyond_the_device_heap_is_refused_before_allocating() {
    let ctx = validated_context();
    let model = random_model(LBS, 44);
    let gpu = GpuModel::new(&ctx, &model).expect("upload");
    let bytes = |c: usize| {
        rrskin::vk::crowd_bytes(
            &rrskin::vk::ModelSizes::of(&model),
            c,
            &CrowdOptions::default(),
        )
        .expect("query")
    };
    // Per character (the fixed minimum sizes of unused buffers aside).
    let per_character = bytes(2) - bytes(1);
    let characters = (ctx.limits().device_local_bytes / per_character + 1) as usize;
    let made = Crowd::new(&gpu, characters).map(|_| ());
    assert!(
        matches!(&made, Err(Error::DeviceLimit { what, .. }) if what.contains("device-local heap")),
        "{made:?}"
    );
    assert_no_validation_messages(&ctx);
}

#[test]
fn requirements_are_known_before_any_device_and_met_here() {
    let r = rrskin::vk::requirements();
    assert_eq!(r.api_version, vk::API_VERSION_1_1);
    assert!(r.instance_extensions.is_empty() && r.device_extensions.is_empty());
    assert_eq!(r.queue_flags, vk::QueueFlags::COMPUTE);
    // Skinning with transformed normals and tangents binds 10 storage buffers (the fused
    // product and the tangents pass 7), beyond Vulkan's guaranteed 4.
    assert_eq!(r.storage_buffers_per_stage, 10);
    let ctx = validated_context();
    // SAFETY: the context's live instance and physical device.
    let props = unsafe {
        ctx.instance()
            .get_physical_device_properties(ctx.physical_device())
    };
    assert!(props.api_version >= r.api_version);
    assert!(props.limits.max_per_stage_descriptor_storage_buffers >= r.storage_buffers_per_stage);
}

/// Outputs released to another queue family each frame (`VK_QUEUE_FAMILY_EXTERNAL`: lavapipe has
/// one family) and acquired back by the test's own barrier before it copies them: every frame
/// still matches the CPU, and the validation layer sees matching release/acquire pairs.
#[test]
fn outputs_released_to_another_queue_family_each_frame_match_cpu() {
    let options = CrowdOptions {
        previous_positions: true,
        bounds: true,
        release_to_queue_family: Some(vk::QUEUE_FAMILY_EXTERNAL),
        ..CrowdOptions::default()
    };
    overlapping_frames(&random_model(RR, 37), 4, options);
    let ctx = validated_context();
    let gpu = GpuModel::new(&ctx, &random_model(LBS, 38)).expect("upload");
    let own = CrowdOptions {
        release_to_queue_family: Some(ctx.queue_family_index()),
        ..CrowdOptions::default()
    };
    assert!(matches!(
        Crowd::with_options(&gpu, 1, own),
        Err(Error::OutOfRange { .. })
    ));
}

/// Pose-space correctives on the GPU: models with them (plain LBS, K = 8 dense, block-sparse
/// with fused predictors; one crowd split into chunks) and a model without, in one command
/// buffer over two frame slots, each crowd's positions, normals and bounds against the CPU
/// reference (the tolerances of `compare`; boxes as in `overlapping_frames`).
#[test]
fn correctives_beside_a_plain_model_in_one_batch_match_cpu() {
    let ctx = validated_context();
    let models = [
        with_correctives(&random_model(LBS, 51), 6, 1),
        with_correctives(
            &random_model(
                Spec {
                    influences: 8,
                    ..RR
                },
                52,
            ),
            9,
            2,
        ),
        with_correctives(
            &joint_blend_pattern(&random_model(Spec { proxies: 20, ..RR }, 53), 1),
            3,
            3,
        ),
        random_model(RR, 54),
    ];
    let gpu: Vec<GpuModel> = models
        .iter()
        .map(|m| GpuModel::new(&ctx, m).expect("upload"))
        .collect();
    assert_eq!(
        gpu.iter()
            .map(GpuModel::corrective_count)
            .collect::<Vec<_>>(),
        [6, 9, 3, 0]
    );
    assert!(gpu[2].fuses_predictors());
    let counts = [9, 7, 5, 3];
    let v = models[0].vertex_count() as u64;
    let crowds: Vec<Crowd> = (gpu.iter().zip(counts).enumerate())
        .map(|(i, (g, c))| {
            let options = CrowdOptions {
                bounds: true,
                debug_settings: CrowdDebugSettings {
                    // The first crowd in chunks of 4 characters' positions.
                    max_binding_bytes: (i == 0).then_some(4 * v * 12),
                    fill_nan: true,
                    ..Default::default()
                },
                ..CrowdOptions::default()
            };
            Crowd::with_options(g, c, options).expect("crowd")
        })
        .collect();
    assert!(crowds[0].chunk_count() > 1);
    let mut crowds = crowds;
    let mut batch = Batch::new(&ctx).expect("batch");
    for frame in 0..2 {
        let mut expected = Vec::new();
        for ((model, crowd), &c) in models.iter().zip(&mut crowds).zip(&counts) {
            let (poses, p, n) = checkable_poses(model, c, frame + 1).swap_remove(frame);
            crowd.set_bones(frame, &poses).expect("bones");
            expected.push((p, n));
        }
        let refs: Vec<&Crowd> = crowds.iter().collect();
        batch.run(frame, &refs).expect("run");
        for ((model, crowd), (p, n)) in models.iter().zip(&mut crowds).zip(&expected) {
            let out = crowd.read_back().expect("read back");
            compare(model, (p, n), (&out.positions, &out.normals));
            let mut boxes = vec![Aabb::default(); crowd.character_count()];
            crowd.read_bounds(frame, &mut boxes).expect("bounds");
            for (want, got) in boxes_of(p, model.vertex_count()).iter().zip(&boxes) {
                let pairs = (want.min.iter().chain(&want.max)).zip(got.min.iter().chain(&got.max));
                for (w, g) in pairs {
                    assert!(
                        (w - g).abs() <= POSITION_TOLERANCE * w.abs().max(1.0),
                        "frame {frame}: box {got:?}, CPU {want:?}"
                    );
                }
            }
        }
    }
    // The correctives moved the mesh: without them the CPU reference differs.
    let plain = Model::new(rrskin::ModelParts {
        correctives: None,
        ..models[0].parts().clone()
    })
    .expect("valid");
    let (poses, with, _) = checkable_poses(&models[0], 4, 1).swap_remove(0);
    let mut without = vec![[0.0; 3]; with.len()];
    let mut normals = without.clone();
    CpuEvaluator::new(&plain)
        .evaluate(&poses, &mut without, &mut normals)
        .expect("cpu");
    assert!(with
        .iter()
        .zip(&without)
        .any(|(a, b)| (0..3).any(|i| (a[i] - b[i]).abs() > 1e-3)));
    assert_no_validation_messages(&ctx);
}

/// Proxy correctives (docs/method.md §21) on the GPU, after each of the three products: the
/// dense GEMM (linear features), the block-sparse product with the predictor pass (kernels
/// only) and the fused product (both, with pose-space correctives beside them, one crowd split
/// into chunks), next to a reduced and a plain model without them, in one command buffer over
/// two frame slots: each crowd's positions and normals against the CPU reference (the
/// tolerances of `compare`: positions within `POSITION_TOLERANCE` = 2e-4 of max(1, |p|),
/// normals within `NORMAL_TOLERANCE` = 2e-3), with the validation layer and synchronization
/// validation on. The corrections move the mesh (without them the CPU reference differs), and
/// at the rest pose the corrected models render the uncorrected rest mesh. `in_product`: the
/// fused product applies them itself (what GPUs run) or their own pass does (CPU devices).
/// Delta-mush keys (docs/method.md §23) in every product: beside predictors' keys in the dense
/// GEMM, and as every key in the sparse product after the predictor pass (two keys a proxy) and
/// in the fused product (one key a proxy, its rigid fit evaluated where it is used), K = 4 and
/// 8, with the rig's children listed before their parents too; 1, 7 and 300 characters.
#[test]
fn delta_mush_keys_match_cpu_in_every_product() {
    let ctx = validated_context();
    let with_delta_mush = |spec, keys, seed| {
        with_delta_mush_keys(&random_model(spec, seed), keys, seed).expect("delta-mush keys")
    };
    let wide = Spec {
        proxies: 20,
        influences: 8,
        ..RR
    };
    let fused = joint_blend_pattern(&with_delta_mush(wide, 20, 72), 1);
    let reversed: Vec<usize> = (0..fused.bone_count()).rev().collect();
    let models = [
        with_delta_mush(RR, 3, 71),
        fused.clone(),
        joint_blend_pattern(&with_delta_mush(Spec { proxies: 20, ..RR }, 20, 73), 2),
        renumber_bones(&fused, &reversed).expect("a permutation"),
    ];
    for (i, model) in models.iter().enumerate() {
        let gpu = GpuModel::new(&ctx, model).expect("upload");
        let kind = (gpu.is_block_sparse(), gpu.fuses_predictors());
        assert_eq!(
            kind,
            [(false, false), (true, true), (true, false), (true, true)][i]
        );
        for c in [1, 7, 300] {
            check(
                &ctx,
                model,
                c,
                CrowdOptions::default(),
                5 * c as u64 + i as u64,
            );
        }
    }
}

fn proxy_correctives_after_each_product(in_product: bool) {
    let ctx = validated_context();
    let k8 = Spec {
        influences: 8,
        ..RR
    };
    let sparse =
        |keys, seed| joint_blend_pattern(&random_model(Spec { proxies: 20, ..RR }, seed), keys);
    let with_delta_mush =
        with_delta_mush_keys(&random_model(Spec { proxies: 20, ..RR }, 66), 12, 66)
            .expect("delta-mush keys");
    let models = [
        with_proxy_correctives(&random_model(k8, 61), true, 0, 1),
        with_proxy_correctives(&sparse(2, 62), false, 3, 2),
        with_proxy_correctives(&with_correctives(&sparse(1, 63), 4, 3), true, 2, 3),
        random_model(RR, 64),
        random_model(LBS, 65),
        // Delta-mush keys among the predictors: the fused product of every kind, with and
        // without the correction.
        with_proxy_correctives(&joint_blend_pattern(&with_delta_mush, 1), true, 2, 3),
        // Without feature ranges (files before version 6): the shaders clamp to ±f32::MAX.
        with_ranges(
            &with_proxy_correctives(&random_model(k8, 68), true, 2, 4),
            None,
        ),
    ];
    let settings = GpuModelDebugSettings {
        correctives_in_product: Some(in_product),
    };
    let gpu: Vec<GpuModel> = models
        .iter()
        .map(|m| GpuModel::with_debug_settings(&ctx, m, settings).expect("upload"))
        .collect();
    assert_eq!(gpu[2].applies_correctives_in_product(), in_product);
    assert_eq!(gpu[5].applies_correctives_in_product(), in_product);
    assert!(!gpu[1].applies_correctives_in_product());
    let kinds: Vec<(bool, bool, usize)> = (gpu.iter())
        .map(|g| {
            (
                g.is_block_sparse(),
                g.fuses_predictors(),
                g.proxy_corrective_count(),
            )
        })
        .collect();
    // Proxies e with e % 3 != 1 are corrected: 5 of RR's 7, 13 of 20.
    assert_eq!(
        kinds,
        [
            (false, false, 5),
            (true, false, 13),
            (true, true, 13),
            (false, false, 0),
            (false, false, 0),
            (true, true, 13),
            (false, false, 5)
        ]
    );
    // 300 characters: the pass corrects four characters 64 apart an invocation, 256 a
    // workgroup, so this covers full and partial invocations of two workgroups.
    let counts = [300, 70, 5, 3, 2, 9];
    let v = models[0].vertex_count() as u64;
    let mut crowds: Vec<Crowd> = (gpu.iter().zip(counts).enumerate())
        .map(|(i, (g, c))| {
            let options = CrowdOptions {
                debug_settings: CrowdDebugSettings {
                    // The second crowd in chunks of 16 characters' positions.
                    max_binding_bytes: (i == 1).then_some(16 * v * 12),
                    fill_nan: true,
                    ..Default::default()
                },
                ..CrowdOptions::default()
            };
            Crowd::with_options(g, c, options).expect("crowd")
        })
        .collect();
    assert!(crowds[1].chunk_count() > 1);
    let mut batch = Batch::new(&ctx).expect("batch");
    for frame in 0..2 {
        let mut expected = Vec::new();
        for ((model, crowd), &c) in models.iter().zip(&mut crowds).zip(&counts) {
            let (poses, p, n) = checkable_poses(model, c, frame + 1).swap_remove(frame);
            crowd.set_bones(frame, &poses).expect("bones");
            expected.push((poses, p, n));
        }
        let refs: Vec<&Crowd> = crowds.iter().collect();
        batch.run(frame, &refs).expect("run");
        for (i, ((model, crowd), (poses, p, n))) in
            models.iter().zip(&mut crowds).zip(&expected).enumerate()
        {
            let out = crowd.read_back().expect("read back");
            compare(model, (p, n), (&out.positions, &out.normals));
            if model.proxy_correctives().is_none() {
                continue;
            }
            // The corrections moved the mesh: the uncorrected model's reference differs.
            let plain = Model::new(rrskin::ModelParts {
                proxy_correctives: None,
                ..model.parts().clone()
            })
            .expect("valid");
            let (mut without, mut normals) = (vec![[0.0; 3]; p.len()], vec![[0.0; 3]; p.len()]);
            CpuEvaluator::new(&plain)
                .evaluate(poses, &mut without, &mut normals)
                .expect("cpu");
            let moved = (out.positions.iter().zip(&without))
                .map(|(a, b)| (0..3).map(|c| (a[c] - b[c]).abs()).fold(0.0, f32::max))
                .fold(0.0, f32::max);
            assert!(
                moved > 1e-3,
                "model {i}: the GPU's correction moved {moved}"
            );
        }
    }
    // At the rest pose the corrections vanish: the corrected models render what the
    // uncorrected ones do.
    for (model, crowd) in models.iter().zip(&mut crowds).take(3) {
        let rest = vec![rrskin::palette::REST; crowd.character_count() * model.bone_count()];
        crowd.set_bones(0, &rest).expect("bones");
        let plain = Model::new(rrskin::ModelParts {
            proxy_correctives: None,
            ..model.parts().clone()
        })
        .expect("valid");
        let n = rest.len() / model.bone_count() * model.vertex_count();
        let (mut p, mut nrm) = (vec![[0.0; 3]; n], vec![[0.0; 3]; n]);
        CpuEvaluator::new(&plain)
            .evaluate(&rest, &mut p, &mut nrm)
            .expect("cpu");
        batch.run(0, &[&*crowd]).expect("run");
        let out = crowd.read_back().expect("read back");
        compare(model, (&p, &nrm), (&out.positions, &out.normals));
    }
    assert_no_validation_messages(&ctx);
}

/// Proxy correctives that see gravity (their own pass's GRAVITY build, even where a fused
/// product was asked to apply the correction) on characters each with its own up vector: the
/// GPU matches the CPU reference given the same ups, in two frame slots with different ups, and
/// after one character's up is set alone; the ups move the mesh; a new crowd starts upright (the
/// model's up: at the rest pose it renders the uncorrected model).
#[test]
fn proxy_correctives_seeing_gravity_match_cpu_for_tilted_characters() {
    let ctx = validated_context();
    let up = Some([0.0, 0.6, 0.8]);
    let sparse = joint_blend_pattern(&random_model(Spec { proxies: 20, ..RR }, 71), 1);
    let with_delta_mush =
        with_delta_mush_keys(&random_model(Spec { proxies: 20, ..RR }, 72), 12, 72)
            .expect("delta-mush keys");
    let models = [
        with_proxy_correctives_seeing(&random_model(RR, 70), true, up, 0, 1),
        with_proxy_correctives_seeing(&sparse, false, up, 2, 2),
        with_proxy_correctives_seeing(&joint_blend_pattern(&with_delta_mush, 1), true, up, 2, 3),
    ];
    let settings = GpuModelDebugSettings {
        correctives_in_product: Some(true),
    };
    let counts = [300, 9, 5];
    let mut batch = Batch::new(&ctx).expect("batch");
    for (i, (model, c)) in models.iter().zip(counts).enumerate() {
        let gpu = GpuModel::with_debug_settings(&ctx, model, settings).expect("upload");
        assert!(!gpu.applies_correctives_in_product(), "model {i}");
        assert_eq!(gpu.up(), up);
        let options = CrowdOptions {
            frames_in_flight: 2,
            debug_settings: CrowdDebugSettings {
                fill_nan: true,
                ..Default::default()
            },
            ..CrowdOptions::default()
        };
        let mut crowd = Crowd::with_options(&gpu, c, options).expect("crowd");
        let mut cpu = CpuEvaluator::new(model);
        let v = model.vertex_count();
        let (mut p, mut n) = (vec![[0.0; 3]; c * v], vec![[0.0; 3]; c * v]);
        // Upright at rest: the uncorrected model.
        let rest = vec![rrskin::palette::REST; c * model.bone_count()];
        crowd.set_bones(0, &rest).expect("bones");
        batch.run(0, &[&crowd]).expect("run");
        let plain = Model::new(rrskin::ModelParts {
            proxy_correctives: None,
            ..model.parts().clone()
        })
        .expect("valid");
        CpuEvaluator::new(&plain)
            .evaluate(&rest, &mut p, &mut n)
            .expect("cpu");
        let out = crowd.read_back().expect("read back");
        compare(model, (&p, &n), (&out.positions, &out.normals));
        for frame in 0..2 {
            let (poses, _, _) = checkable_poses(model, c, frame + 1).swap_remove(frame);
            let mut ups: Vec<[f32; 3]> = (0..c)
                .map(|k| {
                    let a = 0.05 * (k + 7 * frame) as f32;
                    [a.sin(), 0.6 * a.cos(), 0.8 * a.cos()]
                })
                .collect();
            crowd.set_bones(frame, &poses).expect("bones");
            crowd.set_ups(frame, &ups).expect("ups");
            if frame == 1 {
                ups[c - 1] = [0.0, -0.6, -0.8];
                crowd
                    .set_character_up(frame, c - 1, ups[c - 1])
                    .expect("up");
            }
            cpu.set_ups(&ups).expect("finite");
            cpu.evaluate(&poses, &mut p, &mut n).expect("cpu");
            batch.run(frame, &[&crowd]).expect("run");
            let out = crowd.read_back().expect("read back");
            compare(model, (&p, &n), (&out.positions, &out.normals));
            let (upright, _) = cpu_reference(model, &poses);
            let moved = (out.positions.iter().zip(&upright))
                .map(|(a, b)| (0..3).map(|k| (a[k] - b[k]).abs()).fold(0.0, f32::max))
                .fold(0.0, f32::max);
            assert!(moved > 1e-3, "model {i}: the ups moved {moved}");
        }
        assert!(matches!(
            crowd.set_ups(0, &[[0.0, 1.0, 0.0]]),
            Err(Error::WrongLength { .. })
        ));
        assert!(matches!(
            crowd.set_character_up(0, 0, [f32::INFINITY, 0.0, 0.0]),
            Err(Error::NonFinite { .. })
        ));
    }
    assert_no_validation_messages(&ctx);
}

#[test]
fn proxy_correctives_in_their_own_pass_after_each_product_match_cpu() {
    proxy_correctives_after_each_product(false);
}

#[test]
fn proxy_correctives_in_the_fused_product_match_cpu() {
    proxy_correctives_after_each_product(true);
}

/// A proxy-corrected model recorded into the test's own command buffers with three frames in
/// flight (the engine path of `overlapping_frames`), with bounds and tangents: every frame
/// matches the CPU reference.
#[test]
fn proxy_correctives_of_overlapping_frames_match_cpu() {
    let model = with_proxy_correctives(
        &joint_blend_pattern(&random_model(Spec { proxies: 12, ..RR }, 66), 1),
        true,
        2,
        4,
    );
    let options = CrowdOptions {
        frames_in_flight: 3,
        previous_positions: true,
        bounds: true,
        tangents: true,
        ..CrowdOptions::default()
    };
    overlapping_frames(&model, 6, options);
}

/// The debug fill reaches every buffer a frame reads or writes: before any frame, the outputs
/// and the intermediates read back as NaN (so a pass that reads what none wrote shows as NaN
/// in the comparison with the CPU reference); a frame then overwrites all of them.
#[test]
fn the_debug_fill_puts_nan_in_every_crowd_buffer_until_a_frame_writes_it() {
    let ctx = validated_context();
    let model = random_model(RR, 8);
    let gpu_model = GpuModel::new(&ctx, &model).expect("upload");
    let options = CrowdOptions {
        tangents: true,
        debug_settings: CrowdDebugSettings {
            fill_nan: true,
            ..Default::default()
        },
        ..Default::default()
    };
    let crowd = Crowd::with_options(&gpu_model, 2, options).expect("crowd");
    let out = crowd.read_back().expect("read back");
    let inter = crowd.read_intermediates().expect("read back");
    let floats = [
        out.positions.as_flattened(),
        out.normals.as_flattened(),
        out.tangents.as_flattened(),
        &inter.rhs,
        inter.palette.as_flattened(),
    ];
    for f in floats {
        assert!(!f.is_empty() && f.iter().all(|x| x.is_nan()));
    }
    check(&ctx, &model, 2, options, 3);
}
