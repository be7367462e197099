//! An offscreen renderer for crowds (`glsl/shade.vert`, `glsl/shade.frag`): the crowd sample's
//! window and headless modes, and the demo's images. It draws straight from the crowds' output
//! buffers (positions and normals as vertex buffers, the model's triangles as the index buffer),
//! one draw per character placed by a push-constant offset, and reads the image back as RGBA8.
//!
//! Synchronisation: the batch's last barrier makes the compute outputs visible to vertex input;
//! the render pass's external dependencies order this frame's attachment writes after the last
//! frame's read-back and the read-back after the writes.

use crate::gpu::{Gpu, HostBuffer, Image};
use crate::scene::Camera;
use ash::vk;
use gpu_allocator::MemoryLocation;
use rrskin::vk::{Context, Crowd};
use rrskin::{Error, Result};
use std::sync::Arc;

const COLOR_FORMAT: vk::Format = vk::Format::R8G8B8A8_UNORM;
const DEPTH_FORMAT: vk::Format = vk::Format::D32_SFLOAT;

/// A mesh from host memory (e.g. a ground truth, or an error map), with a colour per vertex.
#[derive(Clone, Copy)]
pub struct HostMesh<'a> {
    pub positions: &'a [[f32; 3]],
    pub normals: &'a [[f32; 3]],
    pub colors: &'a [[f32; 3]],
    pub triangles: &'a [[u32; 3]],
    pub offset: [f32; 3],
}

/// One character to draw: which, where, and its tint.
#[derive(Clone, Copy)]
pub struct Draw<'a> {
    pub crowd: &'a Crowd,
    pub character: usize,
    pub offset: [f32; 3],
    pub color: [f32; 3],
}

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Push {
    view_proj: [f32; 16],
    offset: [f32; 4],
    color: [f32; 4],
}

pub struct Renderer {
    gpu: Arc<Gpu>,
    extent: vk::Extent2D,
    color: Image,
    _depth: Image,
    render_pass: vk::RenderPass,
    framebuffer: vk::Framebuffer,
    layout: vk::PipelineLayout,
    /// Crowd characters: positions and normals from the crowd's buffers.
    pipeline: vk::Pipeline,
    /// Host meshes: positions, normals and per-vertex colours.
    mesh_pipeline: vk::Pipeline,
    readback: HostBuffer,
    pool: vk::CommandPool,
    fence: vk::Fence,
}

impl Renderer {
    /// An offscreen renderer of `width` x `height` pixels. The context's queue must support
    /// graphics.
    pub fn new(context: &Context, width: u32, height: u32) -> Result<Renderer> {
        let gpu = Gpu::new(context)?;
        if !gpu.queue_has_graphics() {
            return Err(Error::NoDevice {
                reason: "the context's queue has no graphics".into(),
            });
        }
        if width == 0 || height == 0 {
            return Err(Error::OutOfRange {
                what: "image size",
                index: 0,
                count: 0,
            });
        }
        let extent = vk::Extent2D { width, height };
        let color = Image::new(
            &gpu,
            COLOR_FORMAT,
            vk::ImageUsageFlags::COLOR_ATTACHMENT | vk::ImageUsageFlags::TRANSFER_SRC,
            vk::ImageAspectFlags::COLOR,
            extent,
        )?;
        let depth = Image::new(
            &gpu,
            DEPTH_FORMAT,
            vk::ImageUsageFlags::DEPTH_STENCIL_ATTACHMENT,
            vk::ImageAspectFlags::DEPTH,
            extent,
        )?;
        let readback = HostBuffer::new(
            &gpu,
            "rendered image",
            width as u64 * height as u64 * 4,
            vk::BufferUsageFlags::TRANSFER_DST,
            MemoryLocation::GpuToCpu,
        )?;
        let mut r = Renderer {
            gpu,
            extent,
            color,
            _depth: depth,
            render_pass: vk::RenderPass::null(),
            framebuffer: vk::Framebuffer::null(),
            layout: vk::PipelineLayout::null(),
            pipeline: vk::Pipeline::null(),
            mesh_pipeline: vk::Pipeline::null(),
            readback,
            pool: vk::CommandPool::null(),
            fence: vk::Fence::null(),
        };
        // Every handle is stored as soon as it exists, so Drop frees a partial renderer.
        r.create_objects()?;
        Ok(r)
    }

    fn create_objects(&mut self) -> Result<()> {
        let device = self.gpu.device();
        let attachments = [
            vk::AttachmentDescription::default()
                .format(COLOR_FORMAT)
                .samples(vk::SampleCountFlags::TYPE_1)
                .load_op(vk::AttachmentLoadOp::CLEAR)
                .store_op(vk::AttachmentStoreOp::STORE)
                .initial_layout(vk::ImageLayout::UNDEFINED)
                .final_layout(vk::ImageLayout::TRANSFER_SRC_OPTIMAL),
            vk::AttachmentDescription::default()
                .format(DEPTH_FORMAT)
                .samples(vk::SampleCountFlags::TYPE_1)
                .load_op(vk::AttachmentLoadOp::CLEAR)
                .store_op(vk::AttachmentStoreOp::DONT_CARE)
                .initial_layout(vk::ImageLayout::UNDEFINED)
                .final_layout(vk::ImageLayout::DEPTH_STENCIL_ATTACHMENT_OPTIMAL),
        ];
        let color_ref = [vk::AttachmentReference {
            attachment: 0,
            layout: vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL,
        }];
        let depth_ref = vk::AttachmentReference {
            attachment: 1,
            layout: vk::ImageLayout::DEPTH_STENCIL_ATTACHMENT_OPTIMAL,
        };
        let subpass = [vk::SubpassDescription::default()
            .pipeline_bind_point(vk::PipelineBindPoint::GRAPHICS)
            .color_attachments(&color_ref)
            .depth_stencil_attachment(&depth_ref)];
        let attachment_stages = vk::PipelineStageFlags::COLOR_ATTACHMENT_OUTPUT
            | vk::PipelineStageFlags::EARLY_FRAGMENT_TESTS
            | vk::PipelineStageFlags::LATE_FRAGMENT_TESTS;
        let attachment_writes = vk::AccessFlags::COLOR_ATTACHMENT_WRITE
            | vk::AccessFlags::DEPTH_STENCIL_ATTACHMENT_WRITE;
        let dependencies = [
            // After the last frame's read-back and attachment writes.
            vk::SubpassDependency::default()
                .src_subpass(vk::SUBPASS_EXTERNAL)
                .dst_subpass(0)
                .src_stage_mask(vk::PipelineStageFlags::TRANSFER | attachment_stages)
                .src_access_mask(attachment_writes)
                .dst_stage_mask(attachment_stages)
                .dst_access_mask(
                    attachment_writes | vk::AccessFlags::DEPTH_STENCIL_ATTACHMENT_READ,
                ),
            // Before the read-back.
            vk::SubpassDependency::default()
                .src_subpass(0)
                .dst_subpass(vk::SUBPASS_EXTERNAL)
                .src_stage_mask(vk::PipelineStageFlags::COLOR_ATTACHMENT_OUTPUT)
                .src_access_mask(vk::AccessFlags::COLOR_ATTACHMENT_WRITE)
                .dst_stage_mask(vk::PipelineStageFlags::TRANSFER)
                .dst_access_mask(vk::AccessFlags::TRANSFER_READ),
        ];
        let info = vk::RenderPassCreateInfo::default()
            .attachments(&attachments)
            .subpasses(&subpass)
            .dependencies(&dependencies);
        // SAFETY: the device is live (crate::gpu); the attachments, subpass and dependencies the
        // info points to live through the call.
        self.render_pass = unsafe { device.create_render_pass(&info, None) }
            .map_err(Error::vk("vkCreateRenderPass"))?;
        let views = [self.color.view, self._depth.view];
        let info = vk::FramebufferCreateInfo::default()
            .render_pass(self.render_pass)
            .attachments(&views)
            .width(self.extent.width)
            .height(self.extent.height)
            .layers(1);
        // SAFETY: the views match the render pass's attachments.
        self.framebuffer = unsafe { device.create_framebuffer(&info, None) }
            .map_err(Error::vk("vkCreateFramebuffer"))?;
        self.layout = self.gpu.create_pipeline_layout(size_of::<Push>() as u32)?;
        self.pipeline = self.create_pipeline(
            include_bytes!(concat!(env!("OUT_DIR"), "/shade_vert.spv")),
            2,
        )?;
        self.mesh_pipeline = self.create_pipeline(
            include_bytes!(concat!(env!("OUT_DIR"), "/shade_colors_vert.spv")),
            3,
        )?;
        self.pool = self
            .gpu
            .create_command_pool(vk::CommandPoolCreateFlags::RESET_COMMAND_BUFFER)?;
        self.fence = self.gpu.create_fence()?;
        Ok(())
    }

    /// A pipeline with `streams` vertex bindings (positions, normals[, colours]), 12 bytes each.
    fn create_pipeline(&self, vertex_code: &[u8], streams: u32) -> Result<vk::Pipeline> {
        let device = self.gpu.device();
        let vert = self.gpu.create_shader_module(vertex_code)?;
        let fragment_code = include_bytes!(concat!(env!("OUT_DIR"), "/shade_frag.spv"));
        let frag = match self.gpu.create_shader_module(fragment_code) {
            Ok(m) => m,
            Err(e) => {
                // SAFETY: no pipeline was made from the module.
                unsafe { device.destroy_shader_module(vert, None) };
                return Err(e);
            }
        };
        let stages = [
            vk::PipelineShaderStageCreateInfo::default()
                .stage(vk::ShaderStageFlags::VERTEX)
                .module(vert)
                .name(c"main"),
            vk::PipelineShaderStageCreateInfo::default()
                .stage(vk::ShaderStageFlags::FRAGMENT)
                .module(frag)
                .name(c"main"),
        ];
        // Positions (binding 0), normals (1)[, colours (2)]: the crowd's output layout, 12 bytes.
        let bindings: Vec<vk::VertexInputBindingDescription> = (0..streams)
            .map(|b| vk::VertexInputBindingDescription {
                binding: b,
                stride: 12,
                input_rate: vk::VertexInputRate::VERTEX,
            })
            .collect();
        let attributes: Vec<vk::VertexInputAttributeDescription> = (0..streams)
            .map(|b| vk::VertexInputAttributeDescription {
                location: b,
                binding: b,
                format: vk::Format::R32G32B32_SFLOAT,
                offset: 0,
            })
            .collect();
        let vertex_input = vk::PipelineVertexInputStateCreateInfo::default()
            .vertex_binding_descriptions(&bindings)
            .vertex_attribute_descriptions(&attributes);
        let assembly = vk::PipelineInputAssemblyStateCreateInfo::default()
            .topology(vk::PrimitiveTopology::TRIANGLE_LIST);
        let viewports = [vk::Viewport {
            x: 0.0,
            y: 0.0,
            width: self.extent.width as f32,
            height: self.extent.height as f32,
            min_depth: 0.0,
            max_depth: 1.0,
        }];
        let scissors = [vk::Rect2D {
            offset: vk::Offset2D::default(),
            extent: self.extent,
        }];
        let viewport = vk::PipelineViewportStateCreateInfo::default()
            .viewports(&viewports)
            .scissors(&scissors);
        let raster = vk::PipelineRasterizationStateCreateInfo::default()
            .polygon_mode(vk::PolygonMode::FILL)
            .cull_mode(vk::CullModeFlags::NONE)
            .front_face(vk::FrontFace::COUNTER_CLOCKWISE)
            .line_width(1.0);
        let multisample = vk::PipelineMultisampleStateCreateInfo::default()
            .rasterization_samples(vk::SampleCountFlags::TYPE_1);
        let depth = vk::PipelineDepthStencilStateCreateInfo::default()
            .depth_test_enable(true)
            .depth_write_enable(true)
            .depth_compare_op(vk::CompareOp::LESS);
        let blend_attachments = [vk::PipelineColorBlendAttachmentState::default()
            .color_write_mask(vk::ColorComponentFlags::RGBA)];
        let blend =
            vk::PipelineColorBlendStateCreateInfo::default().attachments(&blend_attachments);
        let info = [vk::GraphicsPipelineCreateInfo::default()
            .stages(&stages)
            .vertex_input_state(&vertex_input)
            .input_assembly_state(&assembly)
            .viewport_state(&viewport)
            .rasterization_state(&raster)
            .multisample_state(&multisample)
            .depth_stencil_state(&depth)
            .color_blend_state(&blend)
            .layout(self.layout)
            .render_pass(self.render_pass)
            .subpass(0)];
        // SAFETY: valid create info; the modules may be destroyed once the pipeline exists.
        let result = unsafe {
            let r = device.create_graphics_pipelines(vk::PipelineCache::null(), &info, None);
            device.destroy_shader_module(vert, None);
            device.destroy_shader_module(frag, None);
            r
        };
        Ok(result.map_err(|(_, result)| Error::vk("vkCreateGraphicsPipelines")(result))?[0])
    }

    pub fn width(&self) -> u32 {
        self.extent.width
    }

    pub fn height(&self) -> u32 {
        self.extent.height
    }

    /// Draws `draws` (whose crowds were run before, e.g. by `Batch::run`) and `meshes`, and
    /// returns the image: width x height RGBA8 pixels, rows top to bottom.
    pub fn render(
        &mut self,
        camera: &Camera,
        draws: &[Draw],
        meshes: &[HostMesh],
        background: [f32; 3],
    ) -> Result<Vec<u8>> {
        self.check_draws(draws)?;
        let uploaded = self.upload_meshes(meshes)?;
        let gpu = self.gpu.clone();
        let device = gpu.device();
        let info = vk::CommandBufferAllocateInfo::default()
            .command_pool(self.pool)
            .command_buffer_count(1);
        // SAFETY: the renderer's own pool, used only under `&mut self` (externally synchronised).
        let cmd = unsafe { device.allocate_command_buffers(&info) }
            .map_err(Error::vk("vkAllocateCommandBuffers"))?[0];
        let recorded = (|| -> Result<()> {
            let begin = vk::CommandBufferBeginInfo::default()
                .flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT);
            // SAFETY: `cmd` was just allocated (initial state); every object the commands below
            // use lives until the wait returns.
            unsafe { device.begin_command_buffer(cmd, &begin) }
                .map_err(Error::vk("vkBeginCommandBuffer"))?;
            self.record_pass(cmd, camera, draws, background, |cmd| {
                self.record_meshes(cmd, camera, meshes, &uploaded)
            });
            let region = [vk::BufferImageCopy::default()
                .image_subresource(
                    vk::ImageSubresourceLayers::default()
                        .aspect_mask(vk::ImageAspectFlags::COLOR)
                        .layer_count(1),
                )
                .image_extent(vk::Extent3D {
                    width: self.extent.width,
                    height: self.extent.height,
                    depth: 1,
                })];
            // SAFETY: cmd is recording; the image is in TRANSFER_SRC_OPTIMAL after the pass.
            unsafe {
                device.cmd_copy_image_to_buffer(
                    cmd,
                    self.color.image,
                    vk::ImageLayout::TRANSFER_SRC_OPTIMAL,
                    self.readback.handle,
                    &region,
                );
                transfer_to_host_barrier(device, cmd);
                device
                    .end_command_buffer(cmd)
                    .map_err(Error::vk("vkEndCommandBuffer"))?;
            }
            submit_wait(&gpu.context, cmd, self.fence)
        })();
        // SAFETY: the command buffer finished (or never ran).
        unsafe { device.free_command_buffers(self.pool, &[cmd]) };
        recorded?;
        let n = self.extent.width as usize * self.extent.height as usize * 4;
        Ok(self.readback.mapped()?[..n].to_vec())
    }

    /// Records the drawing of `draws` into the caller's command buffer (a window's frame:
    /// `Batch::record`, then this, then a copy of [`Renderer::color_image`] to the swapchain).
    /// `cmd` must be recording, outside a render pass, on the context's queue family, after the
    /// crowds' passes. When the pass ends the colour image is in `TRANSFER_SRC_OPTIMAL` and its
    /// writes are visible to transfer reads.
    pub fn record(
        &self,
        cmd: vk::CommandBuffer,
        camera: &Camera,
        draws: &[Draw],
        background: [f32; 3],
    ) -> Result<()> {
        self.check_draws(draws)?;
        self.record_pass(cmd, camera, draws, background, |_| {});
        Ok(())
    }

    /// The colour target (`COLOR_FORMAT`, width x height), e.g. to blit to a swapchain image.
    pub fn color_image(&self) -> vk::Image {
        self.color.image
    }

    fn check_draws(&self, draws: &[Draw]) -> Result<()> {
        for d in draws {
            if d.crowd.model().context().device().handle() != self.gpu.device().handle() {
                return Err(Error::Mismatch {
                    what: "a crowd of another context",
                });
            }
            if d.character >= d.crowd.character_count() {
                return Err(Error::OutOfRange {
                    what: "character",
                    index: d.character,
                    count: d.crowd.character_count(),
                });
            }
        }
        Ok(())
    }

    /// Host meshes go to host-visible vertex and index buffers: positions, normals, colours,
    /// triangles per mesh. The caller keeps them alive until the submission completes.
    fn upload_meshes(&self, meshes: &[HostMesh]) -> Result<Vec<[HostBuffer; 4]>> {
        let mut uploaded = Vec::with_capacity(meshes.len());
        for m in meshes {
            let v = m.positions.len();
            if m.normals.len() != v || m.colors.len() != v {
                let actual = m.normals.len().min(m.colors.len());
                return Err(Error::WrongLength {
                    what: "mesh normals and colours",
                    expected: v,
                    actual,
                });
            }
            if let Some(i) = m
                .triangles
                .as_flattened()
                .iter()
                .position(|&x| x as usize >= v)
            {
                return Err(Error::OutOfRange {
                    what: "mesh triangle corner",
                    index: i,
                    count: v,
                });
            }
            let streams: [(&'static str, &[u8], vk::BufferUsageFlags); 4] = [
                (
                    "mesh positions",
                    bytemuck::cast_slice(m.positions),
                    vk::BufferUsageFlags::VERTEX_BUFFER,
                ),
                (
                    "mesh normals",
                    bytemuck::cast_slice(m.normals),
                    vk::BufferUsageFlags::VERTEX_BUFFER,
                ),
                (
                    "mesh colours",
                    bytemuck::cast_slice(m.colors),
                    vk::BufferUsageFlags::VERTEX_BUFFER,
                ),
                (
                    "mesh triangles",
                    bytemuck::cast_slice(m.triangles),
                    vk::BufferUsageFlags::INDEX_BUFFER,
                ),
            ];
            let upload = |(name, data, usage): (&'static str, &[u8], vk::BufferUsageFlags)| {
                let mut b = HostBuffer::new(
                    &self.gpu,
                    name,
                    data.len() as u64,
                    usage,
                    MemoryLocation::CpuToGpu,
                )?;
                b.mapped()?[..data.len()].copy_from_slice(data);
                Ok(b)
            };
            let [p, n, c, t] = streams;
            uploaded.push([upload(p)?, upload(n)?, upload(c)?, upload(t)?]);
        }
        Ok(uploaded)
    }

    /// The render pass: clear, the crowd characters, then whatever `extra` records.
    fn record_pass(
        &self,
        cmd: vk::CommandBuffer,
        camera: &Camera,
        draws: &[Draw],
        background: [f32; 3],
        extra: impl FnOnce(vk::CommandBuffer),
    ) {
        let device = self.gpu.device();
        let clear = [
            vk::ClearValue {
                color: vk::ClearColorValue {
                    float32: [background[0], background[1], background[2], 1.0],
                },
            },
            vk::ClearValue {
                depth_stencil: vk::ClearDepthStencilValue {
                    depth: 1.0,
                    stencil: 0,
                },
            },
        ];
        let pass = vk::RenderPassBeginInfo::default()
            .render_pass(self.render_pass)
            .framebuffer(self.framebuffer)
            .render_area(vk::Rect2D {
                offset: vk::Offset2D::default(),
                extent: self.extent,
            })
            .clear_values(&clear);
        // SAFETY: cmd is recording outside a render pass (callers' contract); the draws were
        // checked against this context and live as long as the caller's borrow.
        unsafe {
            device.cmd_begin_render_pass(cmd, &pass, vk::SubpassContents::INLINE);
            device.cmd_bind_pipeline(cmd, vk::PipelineBindPoint::GRAPHICS, self.pipeline);
            for d in draws {
                let out = d.crowd.latest_output();
                let at = out.offset + d.character as u64 * out.character_stride;
                device.cmd_bind_vertex_buffers(cmd, 0, &[out.positions, out.normals], &[at, at]);
                let model = d.crowd.model();
                device.cmd_bind_index_buffer(
                    cmd,
                    model.triangle_buffer(),
                    0,
                    vk::IndexType::UINT32,
                );
                self.push(cmd, camera, d.offset, d.color);
                device.cmd_draw_indexed(cmd, model.triangle_count() as u32 * 3, 1, 0, 0, 0);
            }
            extra(cmd);
            device.cmd_end_render_pass(cmd);
        }
    }

    fn record_meshes(
        &self,
        cmd: vk::CommandBuffer,
        camera: &Camera,
        meshes: &[HostMesh],
        uploaded: &[[HostBuffer; 4]],
    ) {
        let device = self.gpu.device();
        // SAFETY: inside the render pass of `record_pass`; the buffers outlive the submission.
        unsafe {
            device.cmd_bind_pipeline(cmd, vk::PipelineBindPoint::GRAPHICS, self.mesh_pipeline);
            for (m, [p, n, c, t]) in meshes.iter().zip(uploaded) {
                device.cmd_bind_vertex_buffers(cmd, 0, &[p.handle, n.handle, c.handle], &[0; 3]);
                device.cmd_bind_index_buffer(cmd, t.handle, 0, vk::IndexType::UINT32);
                self.push(cmd, camera, m.offset, [1.0; 3]);
                device.cmd_draw_indexed(cmd, m.triangles.len() as u32 * 3, 1, 0, 0, 0);
            }
        }
    }

    /// # Safety
    /// `cmd` is recording with one of this renderer's pipelines bound.
    unsafe fn push(
        &self,
        cmd: vk::CommandBuffer,
        camera: &Camera,
        offset: [f32; 3],
        color: [f32; 3],
    ) {
        let push = Push {
            view_proj: camera.view_proj.to_cols_array(),
            offset: [offset[0], offset[1], offset[2], 0.0],
            color: [color[0], color[1], color[2], 1.0],
        };
        // SAFETY: see the function's contract.
        unsafe {
            self.gpu.device().cmd_push_constants(
                cmd,
                self.layout,
                vk::ShaderStageFlags::VERTEX,
                0,
                bytemuck::bytes_of(&push),
            )
        };
    }
}

impl Drop for Renderer {
    fn drop(&mut self) {
        // SAFETY: `render` waits for its submission; null handles are no-ops.
        unsafe {
            let d = self.gpu.device();
            d.destroy_fence(self.fence, None);
            d.destroy_command_pool(self.pool, None);
            d.destroy_pipeline(self.pipeline, None);
            d.destroy_pipeline(self.mesh_pipeline, None);
            d.destroy_pipeline_layout(self.layout, None);
            d.destroy_framebuffer(self.framebuffer, None);
            d.destroy_render_pass(self.render_pass, None);
        }
    }
}

/// Submits `cmd` on the context's queue (taken through `with_queue`, so never racing the
/// runtime's own submissions), waits on `fence` (unsignalled) and resets it.
fn submit_wait(context: &Context, cmd: vk::CommandBuffer, fence: vk::Fence) -> Result<()> {
    let cmds = [cmd];
    let submit = [vk::SubmitInfo::default().command_buffers(&cmds)];
    let device = context.device();
    context.with_queue(|queue| {
        // SAFETY: the queue is held exclusively inside `with_queue`; `cmd` is executable and
        // every object it uses outlives the wait; the fence is this device's and unsignalled.
        unsafe {
            device
                .queue_submit(queue, &submit, fence)
                .map_err(Error::vk("vkQueueSubmit"))?;
            device
                .wait_for_fences(&[fence], true, u64::MAX)
                .map_err(Error::vk("vkWaitForFences"))?;
            device
                .reset_fences(&[fence])
                .map_err(Error::vk("vkResetFences"))
        }
    })
}

/// The copy's transfer writes made visible to the host, which reads them after the fence.
///
/// # Safety
/// `cmd` must be recording, outside a render pass.
unsafe fn transfer_to_host_barrier(device: &ash::Device, cmd: vk::CommandBuffer) {
    let barrier = [vk::MemoryBarrier::default()
        .src_access_mask(vk::AccessFlags::TRANSFER_WRITE)
        .dst_access_mask(vk::AccessFlags::HOST_READ)];
    // SAFETY: see the function's contract.
    unsafe {
        device.cmd_pipeline_barrier(
            cmd,
            vk::PipelineStageFlags::TRANSFER,
            vk::PipelineStageFlags::HOST,
            vk::DependencyFlags::empty(),
            &barrier,
            &[],
            &[],
        )
    };
}
