//! Checked forms of the routine Vulkan calls, so that their call sites need no `unsafe`: queries
//! of a physical device, device creation with its inputs checked, and objects whose create info
//! is built here. They are sound for one reason, argued once here rather than at every call:
//! the handles cannot be dangling. A [`Physical`] borrows the `ash::Instance` it came from, and
//! this crate destroys an instance only once nothing made from it is left (`Shared`'s Drop, or
//! the failure path of `Context::new` before anything was made); a [`Shared`]'s device lives as
//! long as the `Shared` (owned: destroyed in its Drop; an engine's: `Context::from_engine`'s
//! contract). The `unsafe` left elsewhere argues lifetimes of objects and GPU progress.

use super::context::Shared;
use crate::error::{Error, Result};
use ash::vk;
use std::ffi::{c_char, CStr};

/// A physical device of a live instance.
#[derive(Clone, Copy)]
pub(crate) struct Physical<'a> {
    instance: &'a ash::Instance,
    pub handle: vk::PhysicalDevice,
}

impl<'a> Physical<'a> {
    /// Every physical device of `instance`, in enumeration order.
    pub fn enumerate(instance: &'a ash::Instance) -> Result<Vec<Physical<'a>>> {
        // SAFETY: the instance is live (module docs).
        let handles = unsafe { instance.enumerate_physical_devices() }
            .map_err(Error::vk("vkEnumeratePhysicalDevices"))?;
        Ok(handles
            .into_iter()
            .map(|handle| Physical { instance, handle })
            .collect())
    }

    /// # Safety
    /// `handle` is a physical device of `instance` (the engine's pair, under
    /// `Context::from_engine`'s contract, or one [`Physical::enumerate`] gave).
    pub unsafe fn from_raw(instance: &'a ash::Instance, handle: vk::PhysicalDevice) -> Self {
        Physical { instance, handle }
    }

    pub fn properties(self) -> vk::PhysicalDeviceProperties {
        // SAFETY: a physical device of a live instance (module docs).
        unsafe { self.instance.get_physical_device_properties(self.handle) }
    }

    /// The largest buffer the device can make and bind: `maxMemoryAllocationSize` (Vulkan 1.1),
    /// and `maxBufferSize` where the device has maintenance4 (Vulkan 1.3). Past either, a
    /// buffer is undefined behaviour, not an error, so the runtime checks before it asks.
    pub fn max_buffer_bytes(self) -> u64 {
        let maintenance4 = self.has_extensions(&[ash::khr::maintenance4::NAME]);
        let mut m3 = vk::PhysicalDeviceMaintenance3Properties::default();
        let mut m4 = vk::PhysicalDeviceMaintenance4Properties::default();
        let mut props = vk::PhysicalDeviceProperties2::default().push_next(&mut m3);
        if maintenance4 {
            props = props.push_next(&mut m4);
        }
        // SAFETY: a physical device of a live instance (module docs); the chain holds core
        // 1.1 properties and maintenance4's only where the device has the extension.
        unsafe {
            self.instance
                .get_physical_device_properties2(self.handle, &mut props)
        };
        let allocation = m3.max_memory_allocation_size;
        match maintenance4 {
            true => allocation.min(m4.max_buffer_size),
            false => allocation,
        }
    }

    /// The size of the largest device-local memory heap.
    pub fn device_local_bytes(self) -> u64 {
        // SAFETY: a physical device of a live instance (module docs).
        let memory = unsafe {
            self.instance
                .get_physical_device_memory_properties(self.handle)
        };
        (memory.memory_heaps_as_slice().iter())
            .filter(|h| h.flags.contains(vk::MemoryHeapFlags::DEVICE_LOCAL))
            .map(|h| h.size)
            .max()
            .unwrap_or(0)
    }

    pub fn queue_families(self) -> Vec<vk::QueueFamilyProperties> {
        // SAFETY: as above.
        unsafe {
            self.instance
                .get_physical_device_queue_family_properties(self.handle)
        }
    }

    /// Whether the device supports every one of `extensions` (false if it cannot say).
    pub fn has_extensions(self, extensions: &[&CStr]) -> bool {
        // SAFETY: as above.
        let available = unsafe {
            self.instance
                .enumerate_device_extension_properties(self.handle)
        }
        .unwrap_or_default();
        extensions.iter().all(|&wanted| {
            available
                .iter()
                .any(|e| e.extension_name_as_c_str() == Ok(wanted))
        })
    }

    /// A device with one queue of `queue_family` and `extensions` enabled, both checked first.
    pub fn create_device(self, queue_family: u32, extensions: &[&CStr]) -> Result<ash::Device> {
        let families = self.queue_families().len();
        if queue_family as usize >= families {
            return Err(Error::OutOfRange {
                what: "queue family index",
                index: queue_family as usize,
                count: families,
            });
        }
        if !self.has_extensions(extensions) {
            return Err(Error::NoDevice {
                reason: format!("the device lacks one of {extensions:?}"),
            });
        }
        let priorities = [1.0f32];
        let queue_info = [vk::DeviceQueueCreateInfo::default()
            .queue_family_index(queue_family)
            .queue_priorities(&priorities)];
        let names: Vec<*const c_char> = extensions.iter().map(|e| e.as_ptr()).collect();
        let info = vk::DeviceCreateInfo::default()
            .queue_create_infos(&queue_info)
            .enabled_extension_names(&names);
        // SAFETY: a physical device of a live instance; the family exists and the extensions are
        // supported (checked above); `info` and what it points to live through the call.
        unsafe { self.instance.create_device(self.handle, &info, None) }
            .map_err(Error::vk("vkCreateDevice"))
    }
}

impl Shared {
    /// An unsignalled fence.
    pub fn create_fence(&self) -> Result<vk::Fence> {
        // SAFETY: the device is live (module docs); the create info is built here.
        unsafe {
            self.device
                .create_fence(&vk::FenceCreateInfo::default(), None)
        }
        .map_err(Error::vk("vkCreateFence"))
    }

    /// A command pool of the context's queue family.
    pub fn create_command_pool(
        &self,
        flags: vk::CommandPoolCreateFlags,
    ) -> Result<vk::CommandPool> {
        let info = vk::CommandPoolCreateInfo::default()
            .queue_family_index(self.queue_family_index)
            .flags(flags);
        // SAFETY: the device is live; the create info is built here, for the device's family.
        unsafe { self.device.create_command_pool(&info, None) }
            .map_err(Error::vk("vkCreateCommandPool"))
    }

    /// An exclusive buffer of `size` bytes (checked non-zero, as Vulkan requires), not yet bound
    /// to memory, and what memory it needs.
    pub fn create_buffer(
        &self,
        size: u64,
        usage: vk::BufferUsageFlags,
    ) -> Result<(vk::Buffer, vk::MemoryRequirements)> {
        if size == 0 {
            return Err(Error::OutOfRange {
                what: "buffer size",
                index: 0,
                count: 0,
            });
        }
        let info = vk::BufferCreateInfo::default()
            .size(size)
            .usage(usage)
            .sharing_mode(vk::SharingMode::EXCLUSIVE);
        // SAFETY: the device is live; the create info is built here with a non-zero size.
        let buffer = unsafe { self.device.create_buffer(&info, None) }
            .map_err(Error::vk("vkCreateBuffer"))?;
        // SAFETY: the buffer was just created on this device.
        let requirements = unsafe { self.device.get_buffer_memory_requirements(buffer) };
        Ok((buffer, requirements))
    }
}
