//! Contexts: created headless or on an engine's device, asked for their validation messages
//! and device memory, destroyed.

use super::guard::{guard, put, put_if_asked, Failure};
use super::handles::{context_entry, registry, ContextEntry};
use super::types::{RrskinContext, RrskinStatus};
use crate::vk::{ash::vk, Batch, Context, ContextDesc, EngineDevice};
use std::ffi::c_void;
use std::sync::{Arc, Mutex};

/// An engine's Vulkan objects, borrowed by `rrskin_context_create_from_engine` (never destroyed
/// by rrskin). Dispatchable handles are passed as pointers.
#[repr(C)]
pub struct RrskinEngineDevice {
    /// The engine's `vkGetInstanceProcAddr` (PFN_vkGetInstanceProcAddr).
    pub get_instance_proc_addr: *const c_void,
    /// VkInstance
    pub instance: *mut c_void,
    /// VkPhysicalDevice
    pub physical_device: *mut c_void,
    /// VkDevice
    pub device: *mut c_void,
    pub queue_family_index: u32,
    /// VkQueue (of `queue_family_index`; must support compute)
    pub queue: *mut c_void,
}

/// Creates a context with its own Vulkan instance and device (the best GPU, else lavapipe).
/// `validation` != 0 enables the Khronos validation layer with synchronization validation and
/// fails with RRSKIN_ERROR_MISSING_LAYER if it is not installed. Destroy with
/// `rrskin_context_destroy`.
///
/// # Safety
/// `out` is NULL or points to writable memory for one `rrskin_context`.
#[no_mangle]
pub unsafe extern "C" fn rrskin_context_create_headless(
    validation: u32,
    out: *mut RrskinContext,
) -> RrskinStatus {
    guard(|| {
        if out.is_null() {
            return Err(Failure::null("out"));
        }
        let context = Context::new(&ContextDesc {
            validation: validation != 0,
            ..Default::default()
        })?;
        // SAFETY: `out` as the function's contract requires.
        unsafe { add_context(context, out) }
    })
}

/// Creates a context on the engine's instance, device and queue. The engine keeps ownership:
/// its objects must outlive the context and every model and crowd made from it. The library
/// submits to the queue only in `rrskin_model_load_*`, `rrskin_crowds_run` and
/// `rrskin_crowd_read_back`; the engine must not use the queue concurrently with those.
///
/// # Safety
/// `device` is NULL or points to a readable `rrskin_engine_device` whose handles are valid and
/// belong together (the instance's physical device; a device made from it with a queue of
/// `queue_family_index`; `get_instance_proc_addr` is `vkGetInstanceProcAddr` for the instance)
/// and outlive the context and every model and crowd made from it. `out` is NULL or points to
/// writable memory for one `rrskin_context`.
#[no_mangle]
pub unsafe extern "C" fn rrskin_context_create_from_engine(
    device: *const RrskinEngineDevice,
    out: *mut RrskinContext,
) -> RrskinStatus {
    guard(|| {
        if device.is_null() {
            return Err(Failure::null("device"));
        }
        if out.is_null() {
            return Err(Failure::null("out"));
        }
        // SAFETY: non-null, and the caller guarantees a valid struct.
        let d = unsafe { &*device };
        for (p, what) in [
            (
                d.get_instance_proc_addr as *mut c_void,
                "device->get_instance_proc_addr",
            ),
            (d.instance, "device->instance"),
            (d.physical_device, "device->physical_device"),
            (d.device, "device->device"),
            (d.queue, "device->queue"),
        ] {
            if p.is_null() {
                return Err(Failure::null(what));
            }
        }
        // SAFETY: a non-null PFN_vkGetInstanceProcAddr, as the caller guarantees.
        let gipa: vk::PFN_vkGetInstanceProcAddr =
            unsafe { std::mem::transmute(d.get_instance_proc_addr) };
        use vk::Handle;
        let engine = EngineDevice {
            get_instance_proc_addr: gipa,
            instance: vk::Instance::from_raw(d.instance as u64),
            physical_device: vk::PhysicalDevice::from_raw(d.physical_device as u64),
            device: vk::Device::from_raw(d.device as u64),
            queue_family_index: d.queue_family_index,
            queue: vk::Queue::from_raw(d.queue as u64),
        };
        // SAFETY: the caller guarantees the handles are valid and outlive the context.
        let context = unsafe { Context::from_engine(engine) }?;
        // SAFETY: `out` as the function's contract requires.
        unsafe { add_context(context, out) }
    })
}

/// Gives `context` its batch and hands out its handle.
///
/// # Safety
/// `out` is NULL or valid for writing one `RrskinContext`.
unsafe fn add_context(context: Context, out: *mut RrskinContext) -> Result<(), Failure> {
    let batch = Mutex::new(Batch::new(&context)?);
    let id = registry()
        .contexts
        .insert(Arc::new(ContextEntry { context, batch }));
    // SAFETY: `out` as the function's contract requires.
    unsafe { put(out, RrskinContext { id }, "out") }
}

/// Destroys a context handle. Its device is released once the last model and crowd made from it
/// is destroyed too.
#[no_mangle]
pub extern "C" fn rrskin_context_destroy(context: RrskinContext) -> RrskinStatus {
    guard(|| registry().contexts.remove(context.id).map(drop))
}

/// The number of validation-layer warnings and errors a headless context created with
/// validation has collected (0 otherwise).
///
/// # Safety
/// `out` is NULL or points to writable memory for one `uint32_t`.
#[no_mangle]
pub unsafe extern "C" fn rrskin_context_validation_message_count(
    context: RrskinContext,
    out: *mut u32,
) -> RrskinStatus {
    guard(|| {
        let count = context_entry(context)?.context.validation_messages().len();
        // SAFETY: `out` as the function's contract requires.
        unsafe { put(out, count as u32, "out") }
    })
}

/// Bytes of device memory the context holds for its models and crowds: `allocated` in live
/// allocations, `reserved` in the memory blocks taken from the driver (what counts against the
/// engine's budget). Either pointer may be NULL.
///
/// # Safety
/// `allocated` and `reserved` are each NULL or point to writable memory for one `uint64_t`.
#[no_mangle]
pub unsafe extern "C" fn rrskin_context_get_device_memory(
    context: RrskinContext,
    allocated: *mut u64,
    reserved: *mut u64,
) -> RrskinStatus {
    guard(|| {
        let (in_use, blocks) = context_entry(context)?.context.device_memory_bytes();
        // SAFETY: as the function's contract requires.
        unsafe {
            put_if_asked(allocated, in_use);
            put_if_asked(reserved, blocks);
        }
        Ok(())
    })
}
