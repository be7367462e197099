//! The renderer's access to the context's device: a gpu-allocator of its own (the runtime's is
//! private to the runtime), checked forms of the routine calls, and images and buffers that free
//! their memory in Drop.
//!
//! Why the routine calls here are sound, once for all: [`Gpu`] holds the [`Context`], so the
//! device (and its instance) live as long as any `Gpu`; create infos are built here from checked
//! values. What remains `unsafe` at call sites argues lifetimes and GPU progress: owners drop
//! images and buffers only after the GPU finished with them (the renderer waits for every
//! submission it makes; [`crate::Renderer::record`]'s caller waits for its own).

use ash::vk;
use gpu_allocator::vulkan::{
    Allocation, AllocationCreateDesc, AllocationScheme, Allocator, AllocatorCreateDesc,
};
use gpu_allocator::MemoryLocation;
use rrskin::vk::Context;
use rrskin::{Error, Result};
use std::sync::{Arc, Mutex, MutexGuard};

/// The context and an allocator on its device.
pub(crate) struct Gpu {
    // Declared before `context`, so that its memory is freed while the device still exists.
    allocator: Mutex<Allocator>,
    pub context: Context,
}

impl Gpu {
    pub fn new(context: &Context) -> Result<Arc<Gpu>> {
        let allocator = Allocator::new(&AllocatorCreateDesc {
            instance: context.instance().clone(),
            device: context.device().clone(),
            physical_device: context.physical_device(),
            debug_settings: Default::default(),
            buffer_device_address: false,
            allocation_sizes: Default::default(),
        })
        .map_err(|e| Error::Allocation {
            what: "the renderer's allocator",
            message: e.to_string(),
        })?;
        Ok(Arc::new(Gpu {
            allocator: Mutex::new(allocator),
            context: context.clone(),
        }))
    }

    pub fn device(&self) -> &ash::Device {
        self.context.device()
    }

    /// Whether the context's queue family can draw.
    pub fn queue_has_graphics(&self) -> bool {
        let c = &self.context;
        // SAFETY: the context's own instance and physical device (module docs).
        let families = unsafe {
            c.instance()
                .get_physical_device_queue_family_properties(c.physical_device())
        };
        families
            .get(c.queue_family_index() as usize)
            .is_some_and(|f| f.queue_flags.contains(vk::QueueFlags::GRAPHICS))
    }

    /// An unsignalled fence.
    pub fn create_fence(&self) -> Result<vk::Fence> {
        // SAFETY: the device is live (module docs); the create info is built here.
        unsafe {
            self.device()
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
            .queue_family_index(self.context.queue_family_index())
            .flags(flags);
        // SAFETY: as above, for the context's own queue family.
        unsafe { self.device().create_command_pool(&info, None) }
            .map_err(Error::vk("vkCreateCommandPool"))
    }

    /// A pipeline layout with no descriptor sets and one push-constant range of `push_bytes`
    /// for the vertex stage.
    pub fn create_pipeline_layout(&self, push_bytes: u32) -> Result<vk::PipelineLayout> {
        let ranges = [vk::PushConstantRange::default()
            .stage_flags(vk::ShaderStageFlags::VERTEX)
            .size(push_bytes)];
        let info = vk::PipelineLayoutCreateInfo::default().push_constant_ranges(&ranges);
        // SAFETY: as above.
        unsafe { self.device().create_pipeline_layout(&info, None) }
            .map_err(Error::vk("vkCreatePipelineLayout"))
    }

    /// A shader module from SPIR-V bytes, checked to be whole little-endian words that start
    /// with the SPIR-V magic number (what build.rs embeds; naga validated the module).
    pub fn create_shader_module(&self, code: &[u8]) -> Result<vk::ShaderModule> {
        let words: Vec<u32> = code
            .chunks_exact(4)
            .map(|w| u32::from_le_bytes([w[0], w[1], w[2], w[3]]))
            .collect();
        if code.len() % 4 != 0 || words.first() != Some(&0x0723_0203) {
            return Err(Error::Mismatch {
                what: "SPIR-V (not whole words with the magic number)",
            });
        }
        let info = vk::ShaderModuleCreateInfo::default().code(&words);
        // SAFETY: as above; the code is SPIR-V that naga produced and validated.
        unsafe { self.device().create_shader_module(&info, None) }
            .map_err(Error::vk("vkCreateShaderModule"))
    }

    /// A poisoned lock only means another thread panicked holding it; the allocator stays
    /// consistent.
    fn allocator(&self) -> MutexGuard<'_, Allocator> {
        self.allocator.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// Allocates memory in `location` for a resource just created on this device and binds it.
    fn bind_memory(
        &self,
        name: &'static str,
        resource: Unbound,
        location: MemoryLocation,
    ) -> Result<Allocation> {
        let device = self.device();
        // SAFETY: the resource is this device's (the caller just created it).
        let (requirements, linear) = unsafe {
            match resource {
                Unbound::Buffer(b) => (device.get_buffer_memory_requirements(b), true),
                Unbound::Image(i) => (device.get_image_memory_requirements(i), false),
            }
        };
        let allocation = self
            .allocator()
            .allocate(&AllocationCreateDesc {
                name,
                requirements,
                location,
                linear,
                allocation_scheme: AllocationScheme::GpuAllocatorManaged,
            })
            .map_err(|e| Error::Allocation {
                what: name,
                message: e.to_string(),
            })?;
        // SAFETY: the resource has no memory yet; the allocation was made for its requirements,
        // and its memory block is used only at its own offset.
        let bound = unsafe {
            let (memory, offset) = (allocation.memory(), allocation.offset());
            match resource {
                Unbound::Buffer(b) => device
                    .bind_buffer_memory(b, memory, offset)
                    .map_err(Error::vk("vkBindBufferMemory")),
                Unbound::Image(i) => device
                    .bind_image_memory(i, memory, offset)
                    .map_err(Error::vk("vkBindImageMemory")),
            }
        };
        match bound {
            Ok(()) => Ok(allocation),
            Err(e) => {
                self.free(Some(allocation));
                Err(e)
            }
        }
    }

    fn free(&self, allocation: Option<Allocation>) {
        if let Some(a) = allocation {
            // Freeing only fails for an allocation of another allocator: impossible here.
            let _ = self.allocator().free(a);
        }
    }
}

/// A buffer or image created on the device, without memory yet.
#[derive(Clone, Copy)]
enum Unbound {
    Buffer(vk::Buffer),
    Image(vk::Image),
}

/// A 2D image (one mip, one layer) in device memory, with a view of it.
pub(crate) struct Image {
    gpu: Arc<Gpu>,
    pub image: vk::Image,
    pub view: vk::ImageView,
    allocation: Option<Allocation>,
}

impl Image {
    pub fn new(
        gpu: &Arc<Gpu>,
        format: vk::Format,
        usage: vk::ImageUsageFlags,
        aspect: vk::ImageAspectFlags,
        extent: vk::Extent2D,
    ) -> Result<Image> {
        let info = vk::ImageCreateInfo::default()
            .image_type(vk::ImageType::TYPE_2D)
            .format(format)
            .extent(vk::Extent3D {
                width: extent.width,
                height: extent.height,
                depth: 1,
            })
            .mip_levels(1)
            .array_layers(1)
            .samples(vk::SampleCountFlags::TYPE_1)
            .tiling(vk::ImageTiling::OPTIMAL)
            .usage(usage)
            .initial_layout(vk::ImageLayout::UNDEFINED);
        let device = gpu.device();
        // SAFETY: the device is live (module docs); the create info is built here.
        let image =
            unsafe { device.create_image(&info, None) }.map_err(Error::vk("vkCreateImage"))?;
        // Stored at once, so that Drop frees a partial image.
        let mut target = Image {
            gpu: gpu.clone(),
            image,
            view: vk::ImageView::null(),
            allocation: None,
        };
        target.allocation = Some(gpu.bind_memory(
            "render target",
            Unbound::Image(image),
            MemoryLocation::GpuOnly,
        )?);
        let view_info = vk::ImageViewCreateInfo::default()
            .image(image)
            .view_type(vk::ImageViewType::TYPE_2D)
            .format(format)
            .subresource_range(
                vk::ImageSubresourceRange::default()
                    .aspect_mask(aspect)
                    .level_count(1)
                    .layer_count(1),
            );
        // SAFETY: the image is bound to memory; the view's format and aspect are the image's.
        target.view = unsafe { device.create_image_view(&view_info, None) }
            .map_err(Error::vk("vkCreateImageView"))?;
        Ok(target)
    }
}

impl Drop for Image {
    fn drop(&mut self) {
        // SAFETY: the GPU is done with the image (module docs); null handles are no-ops.
        unsafe {
            self.gpu.device().destroy_image_view(self.view, None);
            self.gpu.device().destroy_image(self.image, None);
        }
        self.gpu.free(self.allocation.take());
    }
}

/// A host-visible buffer (upload or read-back).
pub(crate) struct HostBuffer {
    gpu: Arc<Gpu>,
    pub handle: vk::Buffer,
    allocation: Option<Allocation>,
}

impl HostBuffer {
    /// `size` bytes (at least 16: Vulkan forbids empty buffers) in `location`, CpuToGpu or
    /// GpuToCpu.
    pub fn new(
        gpu: &Arc<Gpu>,
        name: &'static str,
        size: u64,
        usage: vk::BufferUsageFlags,
        location: MemoryLocation,
    ) -> Result<HostBuffer> {
        let info = vk::BufferCreateInfo::default()
            .size(size.max(16))
            .usage(usage)
            .sharing_mode(vk::SharingMode::EXCLUSIVE);
        let device = gpu.device();
        // SAFETY: the device is live (module docs); the create info is built here, non-empty.
        let handle =
            unsafe { device.create_buffer(&info, None) }.map_err(Error::vk("vkCreateBuffer"))?;
        let mut buffer = HostBuffer {
            gpu: gpu.clone(),
            handle,
            allocation: None,
        };
        buffer.allocation = Some(gpu.bind_memory(name, Unbound::Buffer(handle), location)?);
        Ok(buffer)
    }

    pub fn mapped(&mut self) -> Result<&mut [u8]> {
        self.allocation
            .as_mut()
            .and_then(|a| a.mapped_slice_mut())
            .ok_or(Error::Allocation {
                what: "a mapped buffer",
                message: "not host-visible".into(),
            })
    }
}

impl Drop for HostBuffer {
    fn drop(&mut self) {
        // SAFETY: the GPU is done with the buffer (module docs).
        unsafe { self.gpu.device().destroy_buffer(self.handle, None) };
        self.gpu.free(self.allocation.take());
    }
}
