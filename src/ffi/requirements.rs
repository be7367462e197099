//! What an engine asks before it creates anything: the runtime's Vulkan requirements
//! (`rrskin_get_requirements`) and the device memory a model and a crowd will take
//! (`rrskin_query_memory`).

use super::crowd::crowd_options;
use super::guard::{guard, put, put_if_asked, Failure};
use super::types::{RrskinCrowdOptions, RrskinModelInfo, RrskinStatus};
use crate::vk::CrowdOptions;
use std::ffi::c_char;

/// What the runtime needs of a Vulkan implementation (`rrskin_get_requirements`): no device
/// feature beyond core Vulkan 1.1 is enabled or used.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct RrskinRequirements {
    /// The lowest VkPhysicalDeviceProperties::apiVersion (VK_MAKE_API_VERSION) it runs on.
    pub api_version: u32,
    /// VkQueueFlags the context's queue family must have.
    pub queue_flags: u32,
    /// The maxPerStageDescriptorStorageBuffers every model runs with in every mode (Vulkan
    /// guarantees only 4); a device with fewer runs the models whose passes fit
    /// (`rrskin_crowd_create` fails with RRSKIN_ERROR_DEVICE_LIMIT for the others).
    pub storage_buffers_per_stage: u32,
    pub instance_extension_count: u32,
    /// `instance_extension_count` extension names to enable on the instance (NULL when 0);
    /// static strings.
    pub instance_extensions: *const *const c_char,
    pub device_extension_count: u32,
    /// `device_extension_count` extension names to enable on the device (NULL when 0).
    pub device_extensions: *const *const c_char,
}

/// What the runtime needs of the engine's instance, device and queue, before any exists: fill
/// `VkInstanceCreateInfo` / `VkDeviceCreateInfo` from it. `rrskin_context_create_from_engine`
/// checks the same (RRSKIN_STATUS_ERROR_NO_DEVICE, _DEVICE_LIMIT or _MISSING_FUNCTION).
///
/// # Safety
/// `out` is NULL or points to writable memory for one `rrskin_requirements`.
#[no_mangle]
pub unsafe extern "C" fn rrskin_get_requirements(out: *mut RrskinRequirements) -> RrskinStatus {
    guard(|| {
        let r = crate::vk::requirements();
        // The name lists as C arrays, made once (the names are static).
        struct Names(Vec<*const c_char>);
        // SAFETY: pointers to static, immutable strings.
        unsafe impl Send for Names {}
        // SAFETY: as above.
        unsafe impl Sync for Names {}
        static LISTS: std::sync::OnceLock<[Names; 2]> = std::sync::OnceLock::new();
        let lists = LISTS.get_or_init(|| {
            [r.instance_extensions, r.device_extensions]
                .map(|names| Names(names.iter().map(|n| n.as_ptr()).collect()))
        });
        let array = |n: &Names| {
            if n.0.is_empty() {
                std::ptr::null()
            } else {
                n.0.as_ptr()
            }
        };
        let requirements = RrskinRequirements {
            api_version: r.api_version,
            queue_flags: r.queue_flags.as_raw(),
            storage_buffers_per_stage: r.storage_buffers_per_stage,
            instance_extension_count: lists[0].0.len() as u32,
            instance_extensions: array(&lists[0]),
            device_extension_count: lists[1].0.len() as u32,
            device_extensions: array(&lists[1]),
        };
        // SAFETY: `out` as the function's contract requires.
        unsafe { put(out, requirements, "out") }
    })
}

/// The bytes of GPU memory a model of `sizes` and a crowd of `characters` of it made with
/// `options` (NULL: those of `rrskin_crowd_create`) will take, before either is created (no
/// context needed): the sizes of the buffers they create. Either out pointer may be NULL.
/// A crowd beyond the largest device-local heap is refused at creation
/// (RRSKIN_STATUS_ERROR_DEVICE_LIMIT).
///
/// # Safety
/// `sizes` is NULL or points to a readable `rrskin_model_info`; `options` is NULL or points to
/// a readable `rrskin_crowd_options`; `model_bytes` and `crowd_bytes` are each NULL or point to
/// writable memory for one `uint64_t`.
#[no_mangle]
pub unsafe extern "C" fn rrskin_query_memory(
    sizes: *const RrskinModelInfo,
    characters: u32,
    options: *const RrskinCrowdOptions,
    model_bytes: *mut u64,
    crowd_bytes: *mut u64,
) -> RrskinStatus {
    guard(|| {
        if sizes.is_null() {
            return Err(Failure::null("sizes"));
        }
        // SAFETY: non-null and readable (the function's contract).
        let i = unsafe { &*sizes };
        let sizes = crate::vk::ModelSizes {
            vertices: i.vertices as usize,
            triangles: i.triangles as usize,
            bones: i.bones as usize,
            proxies: i.proxies as usize,
            influences: i.influences as usize,
            product_columns: i.blend_columns as usize,
            tangents: i.tangents != 0,
            correctives: i.correctives as usize,
            corrective_drivers: i.corrective_drivers as usize,
            proxy_correctives: i.proxy_correctives as usize,
            proxy_corrective_drivers: i.proxy_corrective_drivers as usize,
            proxy_corrective_kernels: i.proxy_corrective_kernels as usize,
            proxy_corrective_linear: i.proxy_corrective_linear != 0,
            proxy_corrective_gravity: i.proxy_corrective_gravity != 0,
            normal_fans: i.normal_fan_entries as usize,
            key_words: i.key_words as usize,
        };
        let options = if options.is_null() {
            CrowdOptions::default()
        } else {
            // SAFETY: non-null and readable (the function's contract).
            crowd_options(unsafe { &*options })?
        };
        let crowd = crate::vk::crowd_bytes(&sizes, characters as usize, &options)?;
        // SAFETY: as the function's contract requires.
        unsafe {
            put_if_asked(model_bytes, crate::vk::model_bytes(&sizes));
            put_if_asked(crowd_bytes, crowd);
        }
        Ok(())
    })
}
