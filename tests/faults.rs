//! Fault injection through the device function table. The test plays an engine whose
//! `vkGetInstanceProcAddr` hands rrskin wrappers of every Vulkan function that allocates,
//! creates or submits. Armed at n, the n-th such call fails with
//! `VK_ERROR_OUT_OF_DEVICE_MEMORY`, for every n along context, model and crowd creation and
//! along a frame; or the n-th submission or fence wait loses the device. Each case must return a
//! typed status, leave no Vulkan object behind (the wrappers count what is created and
//! destroyed; the validation layer's object tracker reports leftovers when each test destroys
//! its device) and leave the context usable, or, once the device is lost, make every later call
//! on it fail at once while destroying still works.

mod common;

use ash::vk;
use common::abi::{load, status};
use common::engine::{Current, Engine};
use common::*;
use rrskin::ffi::*;
use std::ffi::{c_char, c_void, CStr};
use std::sync::atomic::{AtomicBool, AtomicI64, AtomicUsize, Ordering::SeqCst};
use std::sync::{Mutex, MutexGuard};

// ---- the wrappers' state (global: the tests take turns through `serial`) ----

/// Counted calls since the last `arm`.
static CALLS: AtomicUsize = AtomicUsize::new(0);
/// The counted call that fails (`usize::MAX`: none).
static FAIL_AT: AtomicUsize = AtomicUsize::new(usize::MAX);
/// The armed fault is a lost device (only submissions and fence waits count), not memory.
static LOSE: AtomicBool = AtomicBool::new(false);
/// The device is lost: every submission and wait fails from now on.
static LOST: AtomicBool = AtomicBool::new(false);
/// Device memory ran out: once an allocation or mapping failed, every later one fails too until
/// `disarm` (else the allocator tries another memory type, and the failure path is never
/// taken).
static EXHAUSTED: AtomicBool = AtomicBool::new(false);
/// The call that failed last (for the messages).
static INJECTED: Mutex<&CStr> = Mutex::new(c"");
/// Submissions that reached the real queue.
static SUBMITTED: AtomicUsize = AtomicUsize::new(0);
/// The live engine's loader entry point and instance (raw handle), to look up the real
/// functions with.
static REAL: Current<(vk::PFN_vkGetInstanceProcAddr, u64)> = Current::new();

/// Vulkan objects made and not yet destroyed, per kind.
#[derive(Clone, Copy, Debug)]
enum Kind {
    Buffer,
    Memory,
    DescriptorPool,
    SetLayout,
    PipelineLayout,
    ShaderModule,
    Pipeline,
    CommandPool,
    Fence,
    QueryPool,
}
const KINDS: usize = 10;
static LIVE: [AtomicI64; KINDS] = [const { AtomicI64::new(0) }; KINDS];

fn live() -> [i64; KINDS] {
    LIVE.each_ref().map(|n| n.load(SeqCst))
}

#[derive(PartialEq)]
enum Site {
    Create,
    Submit,
    Wait,
}

/// The result a wrapped call at `site` gives instead of the real one, if any.
fn inject(site: Site, name: &'static CStr) -> Option<vk::Result> {
    if LOST.load(SeqCst) && site != Site::Create {
        return Some(vk::Result::ERROR_DEVICE_LOST);
    }
    let memory = name == c"vkAllocateMemory" || name == c"vkMapMemory";
    if EXHAUSTED.load(SeqCst) && memory {
        return Some(vk::Result::ERROR_OUT_OF_DEVICE_MEMORY);
    }
    let lose = LOSE.load(SeqCst);
    let counted = if lose {
        site != Site::Create
    } else {
        site != Site::Wait
    };
    if !counted || CALLS.fetch_add(1, SeqCst) != FAIL_AT.load(SeqCst) {
        return None;
    }
    *INJECTED.lock().unwrap_or_else(|p| p.into_inner()) = name;
    if lose {
        LOST.store(true, SeqCst);
        Some(vk::Result::ERROR_DEVICE_LOST)
    } else {
        EXHAUSTED.store(memory, SeqCst);
        Some(vk::Result::ERROR_OUT_OF_DEVICE_MEMORY)
    }
}

/// The loader's function `name` (a trampoline that dispatches on its first argument).
fn real<F>(name: &CStr) -> F {
    let (gipa, instance) = REAL.get();
    use vk::Handle;
    let instance = vk::Instance::from_raw(instance);
    // SAFETY: a live instance and a NUL-terminated name.
    let f = unsafe { gipa(instance, name.as_ptr()) }.expect("the loader has every function");
    // SAFETY: `F` is the PFN type of `name` (each wrapper names its own).
    unsafe { std::mem::transmute_copy::<unsafe extern "system" fn(), F>(&f) }
}

/// A fallible call: counted, failed when armed, else forwarded; on success `live` more objects
/// of `kind` exist.
macro_rules! fallible {
    ($wrapper:ident, $name:literal, $pfn:ty, ($($arg:ident: $ty:ty),*) $(, $kind:expr, $count:expr)?) => {
        unsafe extern "system" fn $wrapper($($arg: $ty),*) -> vk::Result {
            if let Some(failure) = inject(Site::Create, $name) {
                return failure;
            }
            // SAFETY: the real function, with the caller's arguments.
            let result = unsafe { real::<$pfn>($name)($($arg),*) };
            $(if result == vk::Result::SUCCESS {
                LIVE[$kind as usize].fetch_add($count as i64, SeqCst);
            })?
            result
        }
    };
}

macro_rules! destroy {
    ($wrapper:ident, $name:literal, $pfn:ty, $handle:ty, $kind:expr) => {
        unsafe extern "system" fn $wrapper(
            device: vk::Device,
            handle: $handle,
            allocator: *const vk::AllocationCallbacks<'_>,
        ) {
            use vk::Handle;
            if !handle.is_null() {
                LIVE[$kind as usize].fetch_sub(1, SeqCst);
            }
            // SAFETY: the real function, with the caller's arguments.
            unsafe { real::<$pfn>($name)(device, handle, allocator) }
        }
    };
}

type Alloc<'a> = *const vk::AllocationCallbacks<'a>;

fallible!(create_buffer, c"vkCreateBuffer", vk::PFN_vkCreateBuffer,
    (d: vk::Device, i: *const vk::BufferCreateInfo<'_>, a: Alloc<'_>, o: *mut vk::Buffer),
    Kind::Buffer, 1);
fallible!(allocate_memory, c"vkAllocateMemory", vk::PFN_vkAllocateMemory,
    (d: vk::Device, i: *const vk::MemoryAllocateInfo<'_>, a: Alloc<'_>, o: *mut vk::DeviceMemory),
    Kind::Memory, 1);
fallible!(create_descriptor_pool, c"vkCreateDescriptorPool", vk::PFN_vkCreateDescriptorPool,
    (d: vk::Device, i: *const vk::DescriptorPoolCreateInfo<'_>, a: Alloc<'_>,
     o: *mut vk::DescriptorPool),
    Kind::DescriptorPool, 1);
fallible!(create_set_layout, c"vkCreateDescriptorSetLayout",
    vk::PFN_vkCreateDescriptorSetLayout,
    (d: vk::Device, i: *const vk::DescriptorSetLayoutCreateInfo<'_>, a: Alloc<'_>,
     o: *mut vk::DescriptorSetLayout),
    Kind::SetLayout, 1);
fallible!(create_pipeline_layout, c"vkCreatePipelineLayout", vk::PFN_vkCreatePipelineLayout,
    (d: vk::Device, i: *const vk::PipelineLayoutCreateInfo<'_>, a: Alloc<'_>,
     o: *mut vk::PipelineLayout),
    Kind::PipelineLayout, 1);
fallible!(create_shader_module, c"vkCreateShaderModule", vk::PFN_vkCreateShaderModule,
    (d: vk::Device, i: *const vk::ShaderModuleCreateInfo<'_>, a: Alloc<'_>,
     o: *mut vk::ShaderModule),
    Kind::ShaderModule, 1);
fallible!(create_compute_pipelines, c"vkCreateComputePipelines",
    vk::PFN_vkCreateComputePipelines,
    (d: vk::Device, cache: vk::PipelineCache, n: u32,
     i: *const vk::ComputePipelineCreateInfo<'_>, a: Alloc<'_>, o: *mut vk::Pipeline),
    Kind::Pipeline, n);
fallible!(create_command_pool, c"vkCreateCommandPool", vk::PFN_vkCreateCommandPool,
    (d: vk::Device, i: *const vk::CommandPoolCreateInfo<'_>, a: Alloc<'_>,
     o: *mut vk::CommandPool),
    Kind::CommandPool, 1);
fallible!(create_fence, c"vkCreateFence", vk::PFN_vkCreateFence,
    (d: vk::Device, i: *const vk::FenceCreateInfo<'_>, a: Alloc<'_>, o: *mut vk::Fence),
    Kind::Fence, 1);
fallible!(create_query_pool, c"vkCreateQueryPool", vk::PFN_vkCreateQueryPool,
    (d: vk::Device, i: *const vk::QueryPoolCreateInfo<'_>, a: Alloc<'_>,
     o: *mut vk::QueryPool),
    Kind::QueryPool, 1);
fallible!(allocate_descriptor_sets, c"vkAllocateDescriptorSets",
    vk::PFN_vkAllocateDescriptorSets,
    (d: vk::Device, i: *const vk::DescriptorSetAllocateInfo<'_>, o: *mut vk::DescriptorSet));
fallible!(allocate_command_buffers, c"vkAllocateCommandBuffers",
    vk::PFN_vkAllocateCommandBuffers,
    (d: vk::Device, i: *const vk::CommandBufferAllocateInfo<'_>, o: *mut vk::CommandBuffer));
fallible!(bind_buffer_memory, c"vkBindBufferMemory", vk::PFN_vkBindBufferMemory,
    (d: vk::Device, b: vk::Buffer, m: vk::DeviceMemory, offset: vk::DeviceSize));
fallible!(map_memory, c"vkMapMemory", vk::PFN_vkMapMemory,
    (d: vk::Device, m: vk::DeviceMemory, offset: vk::DeviceSize, size: vk::DeviceSize,
     f: vk::MemoryMapFlags, o: *mut *mut c_void));
fallible!(begin_command_buffer, c"vkBeginCommandBuffer", vk::PFN_vkBeginCommandBuffer,
    (c: vk::CommandBuffer, i: *const vk::CommandBufferBeginInfo<'_>));
fallible!(end_command_buffer, c"vkEndCommandBuffer", vk::PFN_vkEndCommandBuffer,
    (c: vk::CommandBuffer));

destroy!(
    destroy_buffer,
    c"vkDestroyBuffer",
    vk::PFN_vkDestroyBuffer,
    vk::Buffer,
    Kind::Buffer
);
destroy!(
    free_memory,
    c"vkFreeMemory",
    vk::PFN_vkFreeMemory,
    vk::DeviceMemory,
    Kind::Memory
);
destroy!(
    destroy_descriptor_pool,
    c"vkDestroyDescriptorPool",
    vk::PFN_vkDestroyDescriptorPool,
    vk::DescriptorPool,
    Kind::DescriptorPool
);
destroy!(
    destroy_set_layout,
    c"vkDestroyDescriptorSetLayout",
    vk::PFN_vkDestroyDescriptorSetLayout,
    vk::DescriptorSetLayout,
    Kind::SetLayout
);
destroy!(
    destroy_pipeline_layout,
    c"vkDestroyPipelineLayout",
    vk::PFN_vkDestroyPipelineLayout,
    vk::PipelineLayout,
    Kind::PipelineLayout
);
destroy!(
    destroy_shader_module,
    c"vkDestroyShaderModule",
    vk::PFN_vkDestroyShaderModule,
    vk::ShaderModule,
    Kind::ShaderModule
);
destroy!(
    destroy_pipeline,
    c"vkDestroyPipeline",
    vk::PFN_vkDestroyPipeline,
    vk::Pipeline,
    Kind::Pipeline
);
destroy!(
    destroy_command_pool,
    c"vkDestroyCommandPool",
    vk::PFN_vkDestroyCommandPool,
    vk::CommandPool,
    Kind::CommandPool
);
destroy!(
    destroy_fence,
    c"vkDestroyFence",
    vk::PFN_vkDestroyFence,
    vk::Fence,
    Kind::Fence
);
destroy!(
    destroy_query_pool,
    c"vkDestroyQueryPool",
    vk::PFN_vkDestroyQueryPool,
    vk::QueryPool,
    Kind::QueryPool
);

unsafe extern "system" fn queue_submit(
    queue: vk::Queue,
    count: u32,
    submits: *const vk::SubmitInfo<'_>,
    fence: vk::Fence,
) -> vk::Result {
    if let Some(failure) = inject(Site::Submit, c"vkQueueSubmit") {
        return failure;
    }
    SUBMITTED.fetch_add(1, SeqCst);
    // SAFETY: the real function, with the caller's arguments.
    unsafe { real::<vk::PFN_vkQueueSubmit>(c"vkQueueSubmit")(queue, count, submits, fence) }
}

/// Waits for real (so that nothing the GPU still reads is freed), then reports a lost device if
/// it is lost or this wait loses it.
unsafe extern "system" fn wait_for_fences(
    device: vk::Device,
    count: u32,
    fences: *const vk::Fence,
    all: vk::Bool32,
    timeout: u64,
) -> vk::Result {
    // SAFETY: the real function, with the caller's arguments.
    let result = unsafe {
        real::<vk::PFN_vkWaitForFences>(c"vkWaitForFences")(device, count, fences, all, timeout)
    };
    inject(Site::Wait, c"vkWaitForFences").unwrap_or(result)
}

/// The wrapper of `name`, if it has one.
fn wrapper(name: &CStr) -> vk::PFN_vkVoidFunction {
    macro_rules! table {
        ($($name:ident: $w:ident),* $(,)?) => {
            $(if name.to_bytes() == stringify!($name).as_bytes() {
                // SAFETY: a function pointer as the loader hands them out; the caller casts it
                // back to its PFN type.
                return Some(unsafe {
                    std::mem::transmute::<*const (), unsafe extern "system" fn()>($w as *const ())
                });
            })*
        };
    }
    table!(
        vkCreateBuffer: create_buffer,
        vkAllocateMemory: allocate_memory,
        vkCreateDescriptorPool: create_descriptor_pool,
        vkCreateDescriptorSetLayout: create_set_layout,
        vkCreatePipelineLayout: create_pipeline_layout,
        vkCreateShaderModule: create_shader_module,
        vkCreateComputePipelines: create_compute_pipelines,
        vkCreateCommandPool: create_command_pool,
        vkCreateFence: create_fence,
        vkCreateQueryPool: create_query_pool,
        vkAllocateDescriptorSets: allocate_descriptor_sets,
        vkAllocateCommandBuffers: allocate_command_buffers,
        vkBindBufferMemory: bind_buffer_memory,
        vkMapMemory: map_memory,
        vkBeginCommandBuffer: begin_command_buffer,
        vkEndCommandBuffer: end_command_buffer,
        vkDestroyBuffer: destroy_buffer,
        vkFreeMemory: free_memory,
        vkDestroyDescriptorPool: destroy_descriptor_pool,
        vkDestroyDescriptorSetLayout: destroy_set_layout,
        vkDestroyPipelineLayout: destroy_pipeline_layout,
        vkDestroyShaderModule: destroy_shader_module,
        vkDestroyPipeline: destroy_pipeline,
        vkDestroyCommandPool: destroy_command_pool,
        vkDestroyFence: destroy_fence,
        vkDestroyQueryPool: destroy_query_pool,
        vkQueueSubmit: queue_submit,
        vkWaitForFences: wait_for_fences,
    );
    None
}

unsafe extern "system" fn faulty_gipa(
    instance: vk::Instance,
    name: *const c_char,
) -> vk::PFN_vkVoidFunction {
    // SAFETY: the runtime passes NUL-terminated names.
    let asked = unsafe { CStr::from_ptr(name) };
    if asked == c"vkGetDeviceProcAddr" {
        // SAFETY: same signature.
        return Some(unsafe {
            std::mem::transmute::<vk::PFN_vkGetDeviceProcAddr, unsafe extern "system" fn()>(
                faulty_gdpa,
            )
        });
    }
    // SAFETY: the real loader's entry point, with the caller's arguments.
    wrapper(asked).or_else(|| unsafe { REAL.get().0(instance, name) })
}

unsafe extern "system" fn faulty_gdpa(
    device: vk::Device,
    name: *const c_char,
) -> vk::PFN_vkVoidFunction {
    // SAFETY: the runtime passes NUL-terminated names.
    let asked = unsafe { CStr::from_ptr(name) };
    wrapper(asked).or_else(|| {
        let gdpa = real::<vk::PFN_vkGetDeviceProcAddr>(c"vkGetDeviceProcAddr");
        // SAFETY: the real entry point, with the caller's arguments.
        unsafe { gdpa(device, name) }
    })
}

// ---- the cases ----

const OK: RrskinStatus = RrskinStatus::Ok;

/// The wrappers' state is global: one test at a time.
fn serial() -> MutexGuard<'static, ()> {
    static SERIAL: Mutex<()> = Mutex::new(());
    SERIAL.lock().unwrap_or_else(|p| p.into_inner())
}

/// An engine with validation whose functions rrskin gets through the wrappers.
struct Faulty {
    engine: Engine,
}

impl Faulty {
    fn new(messages: &Mutex<Vec<String>>) -> Faulty {
        let engine = Engine::new(messages);
        use vk::Handle;
        REAL.set((
            engine.entry.static_fn().get_instance_proc_addr,
            engine.instance.handle().as_raw(),
        ));
        disarm();
        Faulty { engine }
    }

    fn context(&self) -> Result<RrskinContext, RrskinStatus> {
        use vk::Handle;
        let e = &self.engine;
        let device = RrskinEngineDevice {
            get_instance_proc_addr: faulty_gipa as *const c_void,
            instance: e.instance.handle().as_raw() as *mut c_void,
            physical_device: e.physical.as_raw() as *mut c_void,
            device: e.device.handle().as_raw() as *mut c_void,
            queue_family_index: e.family,
            queue: e.queue.as_raw() as *mut c_void,
        };
        let mut ctx = RrskinContext { id: 0 };
        // SAFETY: the engine's live handles, which outlive every context of the test.
        status(unsafe { rrskin_context_create_from_engine(&device, &mut ctx) }).map(|()| ctx)
    }

    /// Destroys the device (the object tracker reports what is left) and checks the messages.
    fn finish(self, messages: &Mutex<Vec<String>>) {
        self.engine.destroy();
        let seen = messages.lock().unwrap_or_else(|p| p.into_inner()).clone();
        assert!(seen.is_empty(), "validation messages:\n{}", seen.join("\n"));
    }
}

fn injected() -> &'static CStr {
    *INJECTED.lock().unwrap_or_else(|p| p.into_inner())
}

fn arm(lose: bool, n: usize) {
    CALLS.store(0, SeqCst);
    LOSE.store(lose, SeqCst);
    FAIL_AT.store(n, SeqCst);
}

fn disarm() {
    FAIL_AT.store(usize::MAX, SeqCst);
    EXHAUSTED.store(false, SeqCst);
    LOST.store(false, SeqCst);
}

fn last_error() -> String {
    // SAFETY: never NULL, valid until the next call on this thread.
    unsafe { CStr::from_ptr(rrskin_last_error()) }
        .to_string_lossy()
        .into_owned()
}

fn model() -> rrskin::Model {
    random_model(
        Spec {
            grid: 6,
            bones: 4,
            proxies: 3,
            influences: 4,
        },
        5,
    )
}

const CHARACTERS: u32 = 3;

/// Every optional output, so that every kind of crowd buffer is made.
fn crowd(model: RrskinModel) -> Result<RrskinCrowd, RrskinStatus> {
    let options = RrskinCrowdOptions {
        frames_in_flight: 2,
        previous_positions: 1,
        bounds: 1,
        tangents: 1,
        ..Default::default()
    };
    let mut c = RrskinCrowd { id: 0 };
    // SAFETY: valid pointers.
    status(unsafe { rrskin_crowd_create_with_options(model, CHARACTERS, &options, &mut c) })
        .map(|()| c)
}

/// One frame as a headless engine runs it: bones, the batch, the outputs read back.
fn frame(
    ctx: RrskinContext,
    model: &rrskin::Model,
    crowd: RrskinCrowd,
) -> Result<(), RrskinStatus> {
    let poses = random_poses(model, CHARACTERS as usize, 1);
    let floats = poses.as_flattened();
    let mut positions = vec![0.0f32; CHARACTERS as usize * model.vertex_count() * 3];
    let mut boxes = vec![0.0f32; CHARACTERS as usize * 6];
    // SAFETY: valid pointers and lengths.
    unsafe {
        status(rrskin_crowd_set_bones(
            crowd,
            1,
            floats.as_ptr(),
            floats.len(),
        ))?;
        status(rrskin_crowds_run(ctx, 1, &crowd, 1))?;
        status(rrskin_crowd_read_bounds(
            crowd,
            1,
            boxes.as_mut_ptr(),
            boxes.len(),
        ))?;
        status(rrskin_crowd_read_back(
            crowd,
            positions.as_mut_ptr(),
            std::ptr::null_mut(),
            positions.len(),
        ))
    }
}

/// For n = 0, 1, ...: `setup` without faults; `attempt` with the n-th allocation, creation or
/// submission failing, which must give RRSKIN_STATUS_ERROR_ALLOCATION; `attempt` again without
/// faults, which must work (the context is still usable); then `undo` and `teardown`. After
/// each n as many Vulkan objects exist as before. Ends at the first n that `attempt` no longer
/// reaches; returns it (the number of cases).
fn sweep<S, T>(
    setup: impl Fn() -> S,
    attempt: impl Fn(&S) -> Result<T, RrskinStatus>,
    undo: impl Fn(T),
    teardown: impl Fn(S),
) -> usize {
    for n in 0.. {
        let before = live();
        let state = setup();
        arm(false, n);
        let made = attempt(&state);
        let reached = CALLS.load(SeqCst) > n;
        disarm();
        match made {
            Ok(made) => {
                assert!(
                    !reached,
                    "case {n}: the failure of {:?} was not reported",
                    injected()
                );
                undo(made);
                teardown(state);
                assert_eq!(live(), before, "objects left after the fault-free run");
                return n;
            }
            Err(s) => {
                assert!(
                    reached,
                    "case {n}: failed without a fault: {s:?} {}",
                    last_error()
                );
                assert_eq!(
                    s,
                    RrskinStatus::ErrorAllocation,
                    "case {n} ({:?}): {}",
                    injected(),
                    last_error()
                );
            }
        }
        let again = attempt(&state).unwrap_or_else(|s| {
            panic!("case {n}: unusable after the fault: {s:?} {}", last_error())
        });
        undo(again);
        teardown(state);
        assert_eq!(live(), before, "case {n}: Vulkan objects left over");
    }
    unreachable!()
}

#[test]
fn a_failed_allocation_creation_or_submission_leaks_nothing_and_leaves_the_context_usable() {
    let _serial = serial();
    let messages = Mutex::new(Vec::new());
    let faulty = Faulty::new(&messages);
    let model = model();
    let bytes = model.to_bytes();
    let context = || faulty.context().expect("context");
    let destroy_context = |ctx| assert_eq!(rrskin_context_destroy(ctx), OK);
    let with_model = || {
        let ctx = context();
        (ctx, load(ctx, &bytes).expect("model"))
    };
    let without_model = |(ctx, m)| {
        assert_eq!(rrskin_model_destroy(m), OK);
        destroy_context(ctx);
    };
    let cases = [
        (
            "context",
            sweep(|| (), |()| faulty.context(), destroy_context, |()| ()),
        ),
        (
            "model",
            sweep(
                context,
                |&ctx| load(ctx, &bytes),
                |m| assert_eq!(rrskin_model_destroy(m), OK),
                destroy_context,
            ),
        ),
        (
            "crowd",
            sweep(
                with_model,
                |&(_, m)| crowd(m),
                |c| assert_eq!(rrskin_crowd_destroy(c), OK),
                without_model,
            ),
        ),
        (
            "frame",
            sweep(
                || {
                    let (ctx, m) = with_model();
                    (ctx, m, crowd(m).expect("crowd"))
                },
                |&(ctx, _, c)| frame(ctx, &model, c),
                |()| (),
                |(ctx, m, c)| {
                    assert_eq!(rrskin_crowd_destroy(c), OK);
                    without_model((ctx, m));
                },
            ),
        ),
    ];
    println!("cases: {cases:?}");
    for (stage, n) in cases {
        assert!(n > 0, "{stage}: no fallible call was reached");
    }
    faulty.finish(&messages);
}

#[test]
fn a_lost_device_fails_every_later_call_at_once_and_everything_can_be_destroyed() {
    let _serial = serial();
    let messages = Mutex::new(Vec::new());
    let faulty = Faulty::new(&messages);
    let model = model();
    let bytes = model.to_bytes();
    let lost = RrskinStatus::ErrorDeviceLost;
    let mut cases = 0;
    for n in 0.. {
        let before = live();
        let ctx = faulty.context().expect("context");
        arm(true, n);
        // A model's life: the upload, a crowd, frames; the first failure ends it.
        let (mut m, mut c) = (None, None);
        let life: Result<(), RrskinStatus> = (|| {
            m = Some(load(ctx, &bytes)?);
            c = Some(crowd(m.expect("loaded"))?);
            for _ in 0..2 {
                frame(ctx, &model, c.expect("made"))?;
            }
            Ok(())
        })();
        let reached = CALLS.load(SeqCst) > n;
        match life {
            Ok(()) => assert!(!reached, "case {n}: the lost device was not reported"),
            Err(s) => {
                assert!(
                    reached,
                    "case {n}: failed without a fault: {}",
                    last_error()
                );
                assert_eq!(s, lost, "case {n}: {}", last_error());
                cases += 1;
                let submitted = SUBMITTED.load(SeqCst);
                // Every later call on the context, its model and its crowd.
                let m2 = m.unwrap_or(RrskinModel { id: 0 });
                let mut info = RrskinModelInfo::default();
                let mut out = RrskinCrowdOutput::default();
                let mut timings = RrskinPassTimings::default();
                let mut count = 0;
                // SAFETY: valid pointers.
                let later = unsafe {
                    [
                        load(ctx, &bytes).err(),
                        Some(rrskin_context_validation_message_count(ctx, &mut count)),
                        Some(rrskin_context_get_timings(ctx, 0, &mut timings)),
                        Some(rrskin_crowds_run(ctx, 0, std::ptr::null(), 0)),
                    ]
                };
                for (i, s) in later.into_iter().enumerate() {
                    assert_eq!(s, Some(lost), "case {n}: context call {i}");
                }
                if m.is_some() {
                    // SAFETY: valid pointer.
                    let s = unsafe { rrskin_model_get_info(m2, &mut info) };
                    assert_eq!(s, lost, "case {n}: model info");
                    assert_eq!(crowd(m2).err(), Some(lost), "case {n}: crowd creation");
                }
                if let Some(c) = c {
                    // SAFETY: valid pointer.
                    let s = unsafe { rrskin_crowd_get_output(c, 0, &mut out) };
                    assert_eq!(s, lost, "case {n}: crowd output");
                    assert_eq!(frame(ctx, &model, c), Err(lost), "case {n}: a frame");
                }
                assert_eq!(
                    SUBMITTED.load(SeqCst),
                    submitted,
                    "case {n}: submitted after loss"
                );
            }
        }
        disarm();
        for s in [
            c.map(|c| rrskin_crowd_destroy(c)),
            m.map(|m| rrskin_model_destroy(m)),
            Some(rrskin_context_destroy(ctx)),
        ]
        .into_iter()
        .flatten()
        {
            assert_eq!(s, OK, "case {n}: destroying after the loss");
        }
        assert_eq!(live(), before, "case {n}: Vulkan objects left over");
        if !reached {
            break;
        }
    }
    println!("device-lost cases: {cases}");
    assert!(cases >= 3, "the upload, a run and a read-back each submit");
    faulty.finish(&messages);
}
