//! What the runtime needs of a Vulkan implementation, answerable before any instance or device
//! exists (for an engine that creates its own), and the checks of an engine's device and
//! function pointers against it at context creation.

use super::context::EngineDevice;
use super::passes::Pass;
use crate::error::{Error, Result};
use ash::vk;
use std::ffi::CStr;

/// The runtime's needs: a Vulkan version, extensions (none), a queue, one device limit. It
/// enables no device feature: storage buffers, push constants and compute shaders of SPIR-V
/// 1.3 are core Vulkan 1.1.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Requirements {
    /// The lowest `VkPhysicalDeviceProperties::apiVersion` (and instance version) it runs on.
    pub api_version: u32,
    pub instance_extensions: &'static [&'static CStr],
    pub device_extensions: &'static [&'static CStr],
    /// The queue family the context is given must have these.
    pub queue_flags: vk::QueueFlags,
    /// maxPerStageDescriptorStorageBuffers that every model in every mode runs with: the widest
    /// pass (Vulkan guarantees only 4). A device with fewer runs the models whose passes fit
    /// it; a crowd checks its own, and is refused (`DeviceLimit`) where they do not.
    pub storage_buffers_per_stage: u32,
}

pub fn requirements() -> Requirements {
    Requirements {
        api_version: vk::API_VERSION_1_1,
        instance_extensions: &[],
        device_extensions: &[],
        queue_flags: vk::QueueFlags::COMPUTE,
        storage_buffers_per_stage: (Pass::ALL.iter())
            .map(|p| p.desc().bindings.len() as u32)
            .max()
            .unwrap_or(0),
    }
}

/// Fails with `NoDevice` if the device does not meet [`requirements`].
pub(crate) fn check_device(props: &vk::PhysicalDeviceProperties) -> Result<()> {
    let needs = requirements();
    if props.api_version < needs.api_version {
        return Err(Error::NoDevice {
            reason: format!(
                "the device supports Vulkan {}.{}, the runtime needs 1.1",
                vk::api_version_major(props.api_version),
                vk::api_version_minor(props.api_version)
            ),
        });
    }
    Ok(())
}

/// The instance-level functions the runtime (and its allocator) call on an engine's instance.
const INSTANCE_FUNCTIONS: &[&CStr] = &[
    c"vkGetDeviceProcAddr",
    c"vkEnumerateDeviceExtensionProperties",
    c"vkGetPhysicalDeviceProperties",
    c"vkGetPhysicalDeviceProperties2",
    c"vkGetPhysicalDeviceQueueFamilyProperties",
    c"vkGetPhysicalDeviceMemoryProperties",
];

/// The device-level functions the runtime (and its allocator) call.
const DEVICE_FUNCTIONS: &[&CStr] = &[
    c"vkAllocateCommandBuffers",
    c"vkAllocateDescriptorSets",
    c"vkAllocateMemory",
    c"vkBeginCommandBuffer",
    c"vkBindBufferMemory",
    c"vkCmdBindDescriptorSets",
    c"vkCmdBindPipeline",
    c"vkCmdCopyBuffer",
    c"vkCmdFillBuffer",
    c"vkCmdDispatch",
    c"vkCmdPipelineBarrier",
    c"vkCmdPushConstants",
    c"vkCmdResetQueryPool",
    c"vkCmdWriteTimestamp",
    c"vkCreateBuffer",
    c"vkCreateCommandPool",
    c"vkCreateComputePipelines",
    c"vkCreateDescriptorPool",
    c"vkCreateDescriptorSetLayout",
    c"vkCreateFence",
    c"vkCreatePipelineLayout",
    c"vkCreateQueryPool",
    c"vkCreateShaderModule",
    c"vkDestroyBuffer",
    c"vkDestroyCommandPool",
    c"vkDestroyDescriptorPool",
    c"vkDestroyDescriptorSetLayout",
    c"vkDestroyFence",
    c"vkDestroyPipeline",
    c"vkDestroyPipelineLayout",
    c"vkDestroyQueryPool",
    c"vkDestroyShaderModule",
    c"vkDeviceWaitIdle",
    c"vkEndCommandBuffer",
    c"vkFreeCommandBuffers",
    c"vkFreeMemory",
    c"vkGetBufferMemoryRequirements",
    c"vkGetQueryPoolResults",
    c"vkMapMemory",
    c"vkQueueSubmit",
    c"vkResetCommandBuffer",
    c"vkResetFences",
    c"vkUnmapMemory",
    c"vkUpdateDescriptorSets",
    c"vkWaitForFences",
];

/// Fails with `MissingFunction` naming the first function the engine's `vkGetInstanceProcAddr`
/// (or the `vkGetDeviceProcAddr` it gives) returns NULL for: ash would otherwise load a stub
/// that panics when called.
///
/// # Safety
/// The engine's instance and device handles are valid and `get_instance_proc_addr` is a
/// `vkGetInstanceProcAddr` for its instance (`Context::from_engine`'s contract).
pub(crate) unsafe fn check_functions(engine: &EngineDevice) -> Result<()> {
    let missing = |name: &CStr| Error::MissingFunction {
        name: name.to_string_lossy().into_owned(),
    };
    for name in INSTANCE_FUNCTIONS {
        // SAFETY: the function's contract; `name` is NUL-terminated.
        if unsafe { (engine.get_instance_proc_addr)(engine.instance, name.as_ptr()) }.is_none() {
            return Err(missing(name));
        }
    }
    let name = c"vkGetDeviceProcAddr";
    // SAFETY: as above.
    let found = unsafe { (engine.get_instance_proc_addr)(engine.instance, name.as_ptr()) };
    let found = found.ok_or_else(|| missing(name))?;
    // SAFETY: what the loader returns for this name is a PFN_vkGetDeviceProcAddr.
    let gdpa = unsafe {
        std::mem::transmute::<unsafe extern "system" fn(), vk::PFN_vkGetDeviceProcAddr>(found)
    };
    for name in DEVICE_FUNCTIONS {
        // SAFETY: the engine's device, a valid vkGetDeviceProcAddr, a NUL-terminated name.
        if unsafe { gdpa(engine.device, name.as_ptr()) }.is_none() {
            return Err(missing(name));
        }
    }
    Ok(())
}
