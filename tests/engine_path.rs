//! The engine path: the test plays an engine that owns its instance, device, queue, validation
//! messenger and command buffer; rrskin wraps them and records into that command buffer.

mod common;

use ash::vk;
use common::engine::{Current, Engine};
use common::*;
use rrskin::cpu::CpuEvaluator;
use rrskin::vk::{Batch, Context, Crowd, EngineDevice, GpuModel};
use std::ffi::{c_char, CStr};
use std::sync::Mutex;

#[test]
fn records_into_the_engines_command_buffer_on_the_engines_device() {
    let messages = Mutex::new(Vec::new());
    let engine = Engine::new(&messages);
    let model = random_model(
        Spec {
            grid: 10,
            bones: 7,
            proxies: 5,
            influences: 8,
        },
        31,
    );
    let characters = 64;
    {
        // SAFETY: the engine's handles are valid and outlive the context (dropped in this block).
        let ctx =
            unsafe { Context::from_engine(engine.handles()) }.expect("wrap the engine's device");
        let gpu_model = GpuModel::new(&ctx, &model).expect("upload");
        let mut crowd = Crowd::new(&gpu_model, characters).expect("crowd");
        let mut batch = Batch::new(&ctx).expect("batch");
        let d = &engine.device;
        // SAFETY: the engine's own command pool, buffer and fence, used as an engine would.
        unsafe {
            let pool = d
                .create_command_pool(
                    &vk::CommandPoolCreateInfo::default()
                        .queue_family_index(engine.family)
                        .flags(vk::CommandPoolCreateFlags::RESET_COMMAND_BUFFER),
                    None,
                )
                .expect("pool");
            let cmd = d
                .allocate_command_buffers(
                    &vk::CommandBufferAllocateInfo::default()
                        .command_pool(pool)
                        .command_buffer_count(1),
                )
                .expect("cmd")[0];
            let fence = d
                .create_fence(&vk::FenceCreateInfo::default(), None)
                .expect("fence");
            for frame in 0..3u64 {
                let poses = random_poses(&model, characters, frame);
                crowd.set_bones(0, &poses).expect("bones");
                d.begin_command_buffer(cmd, &vk::CommandBufferBeginInfo::default())
                    .expect("begin");
                batch.record(cmd, 0, &[&crowd]).expect("record");
                d.end_command_buffer(cmd).expect("end");
                let cmds = [cmd];
                d.queue_submit(
                    engine.queue,
                    &[vk::SubmitInfo::default().command_buffers(&cmds)],
                    fence,
                )
                .expect("submit");
                d.wait_for_fences(&[fence], true, u64::MAX).expect("wait");
                d.reset_fences(&[fence]).expect("reset");
                let v = model.vertex_count();
                let (mut p, mut n) = (
                    vec![[0.0; 3]; characters * v],
                    vec![[0.0; 3]; characters * v],
                );
                CpuEvaluator::new(&model)
                    .evaluate(&poses, &mut p, &mut n)
                    .expect("cpu");
                let rrskin::vk::HostOutput {
                    positions: gp,
                    normals: gn,
                    ..
                } = crowd.read_back().expect("read back");
                compare(&model, (&p, &n), (&gp, &gn));
                assert!(batch.timings(0).expect("timings").total_ms() > 0.0);
            }
            let out = crowd.output(0).expect("frame 0");
            assert_eq!(
                (out.vertex_stride, out.character_stride),
                (12, 12 * model.vertex_count() as u64)
            );
            d.destroy_fence(fence, None);
            d.destroy_command_pool(pool, None);
        }
    }
    let seen = messages.lock().expect("not poisoned").clone();
    engine.destroy();
    assert!(seen.is_empty(), "validation messages:\n{}", seen.join("\n"));
}

/// The engine's real loader entry points, behind the filtering ones below.
static REAL_GIPA: Current<vk::PFN_vkGetInstanceProcAddr> = Current::new();
static REAL_GDPA: Current<vk::PFN_vkGetDeviceProcAddr> = Current::new();
/// The function the filters hide.
static HIDDEN: Mutex<&CStr> = Mutex::new(c"");

fn hidden(name: *const c_char) -> bool {
    // SAFETY: the runtime passes NUL-terminated names.
    let name = unsafe { CStr::from_ptr(name) };
    name == *HIDDEN.lock().expect("not poisoned")
}

/// `vkGetInstanceProcAddr` of an engine whose loader lacks `HIDDEN`, instance- or device-level.
unsafe extern "system" fn filtering_gipa(
    instance: vk::Instance,
    name: *const c_char,
) -> vk::PFN_vkVoidFunction {
    if hidden(name) {
        return None;
    }
    // SAFETY: `name` is NUL-terminated.
    let asked = unsafe { CStr::from_ptr(name) };
    if asked == c"vkGetDeviceProcAddr" {
        // SAFETY: same signature.
        return Some(unsafe {
            std::mem::transmute::<vk::PFN_vkGetDeviceProcAddr, unsafe extern "system" fn()>(
                filtering_gdpa,
            )
        });
    }
    // SAFETY: the real loader's entry point, with the caller's arguments.
    unsafe { REAL_GIPA.get()(instance, name) }
}

unsafe extern "system" fn filtering_gdpa(
    device: vk::Device,
    name: *const c_char,
) -> vk::PFN_vkVoidFunction {
    if hidden(name) {
        return None;
    }
    // SAFETY: the real device entry point, with the caller's arguments.
    unsafe { REAL_GDPA.get()(device, name) }
}

#[test]
fn a_missing_engine_function_is_an_error_not_a_crash() {
    let messages = Mutex::new(Vec::new());
    let engine = Engine::new(&messages);
    let handles = engine.handles();
    REAL_GIPA.set(handles.get_instance_proc_addr);
    REAL_GDPA.set(engine.instance.fp_v1_0().get_device_proc_addr);
    let filtered = EngineDevice {
        get_instance_proc_addr: filtering_gipa,
        ..handles
    };
    for name in [
        c"vkGetDeviceProcAddr",
        c"vkGetPhysicalDeviceMemoryProperties",
        c"vkCmdDispatch",
        c"vkCreateComputePipelines",
    ] {
        *HIDDEN.lock().expect("not poisoned") = name;
        // SAFETY: valid engine handles; the filter forwards to the real loader.
        let made = unsafe { Context::from_engine(filtered) };
        assert!(
            matches!(&made, Err(rrskin::Error::MissingFunction { name: n }) if n.as_str() == name.to_str().expect("ASCII")),
            "{name:?}: {:?}",
            made.err()
        );
    }
    *HIDDEN.lock().expect("not poisoned") = c"";
    // SAFETY: as above, nothing hidden.
    drop(unsafe { Context::from_engine(filtered) }.expect("every function there"));
    let seen = messages.lock().expect("not poisoned").clone();
    engine.destroy();
    assert!(seen.is_empty(), "validation messages:\n{}", seen.join("\n"));
}
