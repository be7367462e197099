//! Presentation on the runtime's own device: a surface, a FIFO swapchain whose images are only
//! blit destinations, and the per-frame command buffer that runs the crowd, draws it offscreen
//! and blits the picture to the acquired image.
//!
//! [`FRAMES_IN_FLIGHT`] frames are in flight: frame n records into slot n % 2 (its command
//! buffer, fence and `acquired` semaphore) once the slot's previous frame, n − 2, completed, so
//! the CPU poses frame n (the crowd's bone slot n % 2) while frame n − 1 still executes.
//! `rendered` is one semaphore per swapchain image, since presentation may still hold the
//! previous image's semaphore.

use rrskin::vk::ash::{self, vk};
use rrskin::vk::Context;

type Error = Box<dyn std::error::Error>;

/// Frame slots, and the crowd's frames in flight.
pub const FRAMES_IN_FLIGHT: usize = 2;

pub struct Presenter {
    ctx: Context,
    surface_fn: ash::khr::surface::Instance,
    swapchain_fn: ash::khr::swapchain::Device,
    surface: vk::SurfaceKHR,
    swapchain: vk::SwapchainKHR,
    images: Vec<vk::Image>,
    pub extent: vk::Extent2D,
    format: vk::Format,
    acquired: [vk::Semaphore; FRAMES_IN_FLIGHT],
    rendered: Vec<vk::Semaphore>,
    pool: vk::CommandPool,
    cmds: [vk::CommandBuffer; FRAMES_IN_FLIGHT],
    /// Signalled when the slot's last frame completed (created signalled).
    fences: [vk::Fence; FRAMES_IN_FLIGHT],
    /// Frames submitted so far.
    submitted: usize,
}

/// What `Presenter::frame` did. `stale`: the swapchain no longer matches the window (out of
/// date or suboptimal): call `Presenter::resize` before the next frame.
pub enum Frame {
    Presented {
        stale: bool,
    },
    /// Nothing was drawn: the swapchain was out of date before the frame began.
    Skipped,
}

impl Presenter {
    /// Takes ownership of `surface` (destroyed with the presenter, also on error).
    pub fn new(ctx: &Context, surface: vk::SurfaceKHR, size: [u32; 2]) -> Result<Self, Error> {
        let mut p = Presenter {
            ctx: ctx.clone(),
            surface_fn: ash::khr::surface::Instance::new(ctx.entry(), ctx.instance()),
            swapchain_fn: ash::khr::swapchain::Device::new(ctx.instance(), ctx.device()),
            surface,
            swapchain: vk::SwapchainKHR::null(),
            images: Vec::new(),
            extent: vk::Extent2D::default(),
            format: vk::Format::UNDEFINED,
            acquired: [vk::Semaphore::null(); FRAMES_IN_FLIGHT],
            rendered: Vec::new(),
            pool: vk::CommandPool::null(),
            cmds: [vk::CommandBuffer::null(); FRAMES_IN_FLIGHT],
            fences: [vk::Fence::null(); FRAMES_IN_FLIGHT],
            submitted: 0,
        };
        // SAFETY: valid physical device, queue family and surface.
        let supported = unsafe {
            p.surface_fn.get_physical_device_surface_support(
                ctx.physical_device(),
                ctx.queue_family_index(),
                surface,
            )
        }?;
        if !supported {
            return Err(format!(
                "{}: the runtime's queue family cannot present to this window",
                ctx.device_name()
            )
            .into());
        }
        let device = ctx.device();
        // SAFETY: valid device; every handle is stored at once so Drop frees a partial presenter.
        unsafe {
            for slot in 0..FRAMES_IN_FLIGHT {
                p.acquired[slot] =
                    device.create_semaphore(&vk::SemaphoreCreateInfo::default(), None)?;
                p.fences[slot] = device.create_fence(
                    &vk::FenceCreateInfo::default().flags(vk::FenceCreateFlags::SIGNALED),
                    None,
                )?;
            }
            p.pool = device.create_command_pool(
                &vk::CommandPoolCreateInfo::default()
                    .queue_family_index(ctx.queue_family_index())
                    .flags(vk::CommandPoolCreateFlags::RESET_COMMAND_BUFFER),
                None,
            )?;
            let cmds = device.allocate_command_buffers(
                &vk::CommandBufferAllocateInfo::default()
                    .command_pool(p.pool)
                    .command_buffer_count(FRAMES_IN_FLIGHT as u32),
            )?;
            p.cmds.copy_from_slice(&cmds);
        }
        p.resize(size)?;
        Ok(p)
    }

    /// (Re)creates the swapchain for a window of `size` pixels; a zero extent (minimised
    /// window) leaves none, and `frame` is then not to be called.
    pub fn resize(&mut self, size: [u32; 2]) -> Result<(), Error> {
        let device = self.ctx.device();
        let pd = self.ctx.physical_device();
        // SAFETY: after the wait nothing of ours is pending, presentation included.
        unsafe {
            device.device_wait_idle()?;
            for s in self.rendered.drain(..) {
                device.destroy_semaphore(s, None);
            }
        }
        // SAFETY: valid physical device and surface.
        let (caps, formats) = unsafe {
            (
                self.surface_fn
                    .get_physical_device_surface_capabilities(pd, self.surface)?,
                self.surface_fn
                    .get_physical_device_surface_formats(pd, self.surface)?,
            )
        };
        // Wayland leaves the extent to us (u32::MAX); otherwise it must match the window.
        self.extent = if caps.current_extent.width == u32::MAX {
            vk::Extent2D {
                width: size[0].clamp(caps.min_image_extent.width, caps.max_image_extent.width),
                height: size[1].clamp(caps.min_image_extent.height, caps.max_image_extent.height),
            }
        } else {
            caps.current_extent
        };
        let old = std::mem::replace(&mut self.swapchain, vk::SwapchainKHR::null());
        if self.extent.width == 0 || self.extent.height == 0 {
            // SAFETY: the old swapchain's images are not in use.
            unsafe { self.swapchain_fn.destroy_swapchain(old, None) };
            self.images.clear();
            return Ok(());
        }
        if !caps
            .supported_usage_flags
            .contains(vk::ImageUsageFlags::TRANSFER_DST)
        {
            return Err("the surface's images cannot be transfer destinations".into());
        }
        // UNORM, like the offscreen target, so the window shows the bytes the PNG would hold.
        let wanted = [vk::Format::B8G8R8A8_UNORM, vk::Format::R8G8B8A8_UNORM];
        let chosen = wanted
            .iter()
            .find_map(|&w| formats.iter().find(|f| f.format == w))
            .or(formats.first())
            .ok_or("the surface offers no format")?;
        // SAFETY: valid physical device.
        let features = unsafe {
            self.ctx
                .instance()
                .get_physical_device_format_properties(pd, chosen.format)
        };
        if !features
            .optimal_tiling_features
            .contains(vk::FormatFeatureFlags::BLIT_DST)
        {
            return Err(format!("surface format {:?} cannot be blitted to", chosen.format).into());
        }
        self.format = chosen.format;
        let mut count = caps.min_image_count + 1;
        if caps.max_image_count > 0 {
            count = count.min(caps.max_image_count);
        }
        let alpha = [
            vk::CompositeAlphaFlagsKHR::OPAQUE,
            vk::CompositeAlphaFlagsKHR::INHERIT,
            vk::CompositeAlphaFlagsKHR::PRE_MULTIPLIED,
            vk::CompositeAlphaFlagsKHR::POST_MULTIPLIED,
        ]
        .into_iter()
        .find(|&a| caps.supported_composite_alpha.contains(a))
        .ok_or("the surface supports no composite alpha mode")?;
        let info = vk::SwapchainCreateInfoKHR::default()
            .surface(self.surface)
            .min_image_count(count)
            .image_format(chosen.format)
            .image_color_space(chosen.color_space)
            .image_extent(self.extent)
            .image_array_layers(1)
            .image_usage(vk::ImageUsageFlags::TRANSFER_DST)
            .image_sharing_mode(vk::SharingMode::EXCLUSIVE)
            .pre_transform(caps.current_transform)
            .composite_alpha(alpha)
            .present_mode(vk::PresentModeKHR::FIFO)
            .clipped(true)
            .old_swapchain(old);
        // SAFETY: valid create info; the old swapchain is retired by the call and destroyed
        // after it, with none of its images in use.
        let created = unsafe { self.swapchain_fn.create_swapchain(&info, None) };
        // SAFETY: as above.
        unsafe { self.swapchain_fn.destroy_swapchain(old, None) };
        self.swapchain = created?;
        // SAFETY: our swapchain.
        self.images = unsafe { self.swapchain_fn.get_swapchain_images(self.swapchain) }?;
        for _ in 0..self.images.len() {
            // SAFETY: valid device.
            let s = unsafe { device.create_semaphore(&vk::SemaphoreCreateInfo::default(), None) }?;
            self.rendered.push(s);
        }
        Ok(())
    }

    /// Waits for the next frame slot's previous frame, acquires an image, records `record`
    /// (given the slot: the crowd's passes and the offscreen draw, leaving `picture` in
    /// TRANSFER_SRC_OPTIMAL with its writes visible to transfers), blits `picture`
    /// (`picture_extent`) to the image, submits and presents, without waiting for the frame.
    pub fn frame(
        &mut self,
        picture: vk::Image,
        picture_extent: vk::Extent2D,
        record: impl FnOnce(vk::CommandBuffer, usize) -> Result<(), Error>,
    ) -> Result<Frame, Error> {
        let device = self.ctx.device();
        let slot = self.submitted % FRAMES_IN_FLIGHT;
        let fence = self.fences[slot];
        // SAFETY: our fence, signalled or submitted.
        unsafe { device.wait_for_fences(&[fence], true, u64::MAX)? };
        // SAFETY: our swapchain and an unsignalled semaphore with no pending wait (the slot's
        // last submission, which waited on it, completed).
        let acquired = unsafe {
            self.swapchain_fn.acquire_next_image(
                self.swapchain,
                u64::MAX,
                self.acquired[slot],
                vk::Fence::null(),
            )
        };
        let index = match acquired {
            Ok((index, _suboptimal)) => index,
            Err(vk::Result::ERROR_OUT_OF_DATE_KHR) => return Ok(Frame::Skipped),
            Err(e) => return Err(e.into()),
        };
        let image = self.images[index as usize];
        let cmd = self.cmds[slot];
        // SAFETY: the slot's command buffer is not pending (its fence was waited for).
        unsafe {
            device.reset_fences(&[fence])?;
            device.reset_command_buffer(cmd, vk::CommandBufferResetFlags::empty())?;
            device.begin_command_buffer(
                cmd,
                &vk::CommandBufferBeginInfo::default()
                    .flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT),
            )?;
        }
        record(cmd, slot)?;
        let color = vk::ImageSubresourceRange::default()
            .aspect_mask(vk::ImageAspectFlags::COLOR)
            .level_count(1)
            .layer_count(1);
        let layers = vk::ImageSubresourceLayers::default()
            .aspect_mask(vk::ImageAspectFlags::COLOR)
            .layer_count(1);
        let corner = |e: vk::Extent2D| vk::Offset3D {
            x: e.width as i32,
            y: e.height as i32,
            z: 1,
        };
        // SAFETY: cmd is recording; the image is the acquired one; `picture` is in
        // TRANSFER_SRC_OPTIMAL (the caller's contract).
        unsafe {
            let transfer = vk::PipelineStageFlags::TRANSFER;
            let layout = |from, to, (src_stage, src_access), (dst_stage, dst_access)| {
                let barrier = vk::ImageMemoryBarrier::default()
                    .src_access_mask(src_access)
                    .dst_access_mask(dst_access)
                    .old_layout(from)
                    .new_layout(to)
                    .src_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
                    .dst_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
                    .image(image)
                    .subresource_range(color);
                device.cmd_pipeline_barrier(
                    cmd,
                    src_stage,
                    dst_stage,
                    vk::DependencyFlags::empty(),
                    &[],
                    &[],
                    &[barrier],
                );
            };
            // The acquire semaphore is waited at TRANSFER: chain the layout change to it.
            layout(
                vk::ImageLayout::UNDEFINED,
                vk::ImageLayout::TRANSFER_DST_OPTIMAL,
                (transfer, vk::AccessFlags::empty()),
                (transfer, vk::AccessFlags::TRANSFER_WRITE),
            );
            let blit = vk::ImageBlit::default()
                .src_subresource(layers)
                .src_offsets([vk::Offset3D::default(), corner(picture_extent)])
                .dst_subresource(layers)
                .dst_offsets([vk::Offset3D::default(), corner(self.extent)]);
            device.cmd_blit_image(
                cmd,
                picture,
                vk::ImageLayout::TRANSFER_SRC_OPTIMAL,
                image,
                vk::ImageLayout::TRANSFER_DST_OPTIMAL,
                &[blit],
                vk::Filter::LINEAR,
            );
            // Presentation waits on the semaphore signalled after this; no access of its own.
            layout(
                vk::ImageLayout::TRANSFER_DST_OPTIMAL,
                vk::ImageLayout::PRESENT_SRC_KHR,
                (transfer, vk::AccessFlags::TRANSFER_WRITE),
                (
                    vk::PipelineStageFlags::BOTTOM_OF_PIPE,
                    vk::AccessFlags::empty(),
                ),
            );
            device.end_command_buffer(cmd)?;
        }
        let rendered = [self.rendered[index as usize]];
        let (waits, stages, cmds) = (
            [self.acquired[slot]],
            [vk::PipelineStageFlags::TRANSFER],
            [cmd],
        );
        let submit = vk::SubmitInfo::default()
            .wait_semaphores(&waits)
            .wait_dst_stage_mask(&stages)
            .command_buffers(&cmds)
            .signal_semaphores(&rendered);
        let (swapchains, indices) = ([self.swapchain], [index]);
        let present = vk::PresentInfoKHR::default()
            .wait_semaphores(&rendered)
            .swapchains(&swapchains)
            .image_indices(&indices);
        let presented = self.ctx.with_queue(|queue| {
            // SAFETY: the queue is locked by `with_queue`; everything submitted lives until
            // the slot's fence is waited for (next use of the slot, resize or drop).
            unsafe {
                device.queue_submit(queue, &[submit], fence)?;
                Ok::<_, vk::Result>(self.swapchain_fn.queue_present(queue, &present))
            }
        })?;
        self.submitted += 1;
        match presented {
            Ok(suboptimal) => Ok(Frame::Presented { stale: suboptimal }),
            Err(vk::Result::ERROR_OUT_OF_DATE_KHR) => Ok(Frame::Presented { stale: true }),
            Err(e) => Err(e.into()),
        }
    }
}

impl Drop for Presenter {
    fn drop(&mut self) {
        let device = self.ctx.device();
        // SAFETY: wait until nothing of ours is pending; null handles are no-ops. The surface
        // goes before the context's instance (this presenter holds a clone of the context).
        unsafe {
            let _ = device.device_wait_idle();
            for &s in &self.rendered {
                device.destroy_semaphore(s, None);
            }
            for slot in 0..FRAMES_IN_FLIGHT {
                device.destroy_semaphore(self.acquired[slot], None);
                device.destroy_fence(self.fences[slot], None);
            }
            device.destroy_command_pool(self.pool, None);
            self.swapchain_fn.destroy_swapchain(self.swapchain, None);
            self.surface_fn.destroy_surface(self.surface, None);
        }
    }
}
