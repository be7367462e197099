//! Records the four passes of any number of crowds into ONE command buffer, pass-major, so a
//! frame has four barriers whatever the number of crowds and chunks:
//!
//! ```text
//! ts0 | barrier(prev. frame's reads/writes → compute) | predict (all crowds with P > 0)
//! ts1 | barrier | blend GEMM (all crowds with P > 0)
//! ts2 | barrier | skin (all crowds)
//! ts3 | barrier | normals (all crowds)
//! ts4 | barrier(compute writes → vertex input, transfer, compute reads)
//! ```
//! ts0..ts4 are GPU timestamps; [`Batch::timings`] turns them into per-pass milliseconds.

use super::buffer::memory_barrier;
use super::context::{Context, Shared};
use super::crowd::{Chunk, Crowd};
use super::gpu_model::Inner;
use super::pipelines::PassPipeline;
use super::{blend_gemm, normals, predict, skin};
use crate::error::{Error, Result};
use ash::vk;
use std::sync::Arc;

const TIMESTAMPS: u32 = 5;

/// GPU time per pass of the last recorded frame, in milliseconds.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct PassTimings {
    pub predict_ms: f64,
    pub blend_ms: f64,
    pub skin_ms: f64,
    pub normals_ms: f64,
}

impl PassTimings {
    pub fn total_ms(&self) -> f64 {
        self.predict_ms + self.blend_ms + self.skin_ms + self.normals_ms
    }

    /// The median of each pass over `samples`, and the median frame total (None if empty).
    pub fn median(samples: &[PassTimings]) -> Option<(PassTimings, f64)> {
        let median = |f: fn(&PassTimings) -> f64| {
            let mut v: Vec<f64> = samples.iter().map(f).collect();
            v.sort_by(f64::total_cmp);
            v.get(v.len() / 2).copied()
        };
        let passes = PassTimings {
            predict_ms: median(|t| t.predict_ms)?,
            blend_ms: median(|t| t.blend_ms)?,
            skin_ms: median(|t| t.skin_ms)?,
            normals_ms: median(|t| t.normals_ms)?,
        };
        Some((passes, median(PassTimings::total_ms)?))
    }
}

/// Owns a timestamp query pool and, for the headless path, a command buffer and its pool.
pub struct Batch {
    shared: Arc<Shared>,
    queries: Option<vk::QueryPool>,
    pool: vk::CommandPool,
    cmd: vk::CommandBuffer,
    /// Signalled by `run`'s submission; reused every frame (the per-frame path allocates nothing).
    fence: vk::Fence,
    /// Whether queries were recorded (asking for unrecorded ones is a validation error).
    recorded: bool,
}

impl Batch {
    pub fn new(context: &Context) -> Result<Batch> {
        let shared = context.shared.clone();
        let device = &shared.device;
        let info = vk::CommandPoolCreateInfo::default()
            .queue_family_index(shared.queue_family_index)
            .flags(vk::CommandPoolCreateFlags::RESET_COMMAND_BUFFER);
        // SAFETY: valid device and create info.
        let pool = unsafe { device.create_command_pool(&info, None) }
            .map_err(Error::vk("vkCreateCommandPool"))?;
        let mut batch = Batch {
            shared: shared.clone(),
            queries: None,
            pool,
            cmd: vk::CommandBuffer::null(),
            fence: vk::Fence::null(),
            recorded: false,
        };
        // SAFETY: valid device.
        batch.fence = unsafe { device.create_fence(&vk::FenceCreateInfo::default(), None) }
            .map_err(Error::vk("vkCreateFence"))?;
        let info = vk::CommandBufferAllocateInfo::default()
            .command_pool(pool)
            .level(vk::CommandBufferLevel::PRIMARY)
            .command_buffer_count(1);
        // SAFETY: our pool.
        batch.cmd = unsafe { device.allocate_command_buffers(&info) }
            .map_err(Error::vk("vkAllocateCommandBuffers"))?[0];
        if shared.limits.timestamp_period_ns.is_some() {
            let info = vk::QueryPoolCreateInfo::default()
                .query_type(vk::QueryType::TIMESTAMP)
                .query_count(TIMESTAMPS);
            // SAFETY: valid device and create info.
            batch.queries = Some(
                unsafe { device.create_query_pool(&info, None) }
                    .map_err(Error::vk("vkCreateQueryPool"))?,
            );
        }
        Ok(batch)
    }

    /// Records the passes of `crowds` into the caller's command buffer (engine path). `cmd` must
    /// be recording, outside a render pass, on a queue of the context's queue family.
    pub fn record(&mut self, cmd: vk::CommandBuffer, crowds: &[&Crowd]) -> Result<()> {
        for crowd in crowds {
            if !Arc::ptr_eq(crowd.shared(), &self.shared) {
                return Err(Error::Mismatch {
                    what: "a crowd of another context",
                });
            }
        }
        let s = &*self.shared;
        let device = &s.device;
        let compute = vk::PipelineStageFlags::COMPUTE_SHADER;
        let (mut readers, mut reads) = (
            compute | vk::PipelineStageFlags::TRANSFER,
            vk::AccessFlags::SHADER_READ | vk::AccessFlags::TRANSFER_READ,
        );
        if s.queue_has_graphics {
            readers |= vk::PipelineStageFlags::VERTEX_INPUT;
            reads |= vk::AccessFlags::VERTEX_ATTRIBUTE_READ;
        }
        let to_compute = (
            compute,
            vk::AccessFlags::SHADER_READ | vk::AccessFlags::SHADER_WRITE,
        );
        let after_compute = (compute, vk::AccessFlags::SHADER_WRITE);
        // Crowds of reduced models (P > 0) run passes 1–2; plain LBS crowds only 3–4.
        let reduced = || crowds.iter().filter(|c| c.model.proxy_count() > 0);
        let any_reduced = reduced().next().is_some();
        let p = &s.pipelines;
        // SAFETY: cmd is recording (caller's contract); every handle belongs to this device and
        // lives as long as the crowds.
        unsafe {
            if let Some(q) = self.queries {
                device.cmd_reset_query_pool(cmd, q, 0, TIMESTAMPS);
            }
            self.timestamp(cmd, 0);
            // WAR against last frame's readers (vertex fetch, copies) and WAW against its writes.
            memory_barrier(
                device,
                cmd,
                (readers, vk::AccessFlags::SHADER_WRITE),
                to_compute,
            );
            for crowd in reduced() {
                dispatch_chunks(
                    device,
                    cmd,
                    &p.predict,
                    crowd,
                    |c| c.predict,
                    predict::push,
                    predict::groups,
                );
            }
            self.timestamp(cmd, 1);
            if any_reduced {
                memory_barrier(device, cmd, after_compute, to_compute);
            }
            for crowd in reduced() {
                dispatch_chunks(
                    device,
                    cmd,
                    &p.blend_gemm,
                    crowd,
                    |c| c.blend_gemm,
                    blend_gemm::push,
                    blend_gemm::groups,
                );
            }
            self.timestamp(cmd, 2);
            if any_reduced {
                memory_barrier(device, cmd, after_compute, to_compute);
            }
            for crowd in crowds {
                let pass = p.skin(crowd.model.inner.influences);
                dispatch_chunks(
                    device,
                    cmd,
                    pass,
                    crowd,
                    |c| c.skin,
                    skin::push,
                    skin::groups,
                );
            }
            self.timestamp(cmd, 3);
            memory_barrier(device, cmd, after_compute, to_compute);
            for crowd in crowds {
                dispatch_chunks(
                    device,
                    cmd,
                    &p.normals,
                    crowd,
                    |c| c.normals,
                    normals::push,
                    normals::groups,
                );
            }
            self.timestamp(cmd, 4);
            memory_barrier(device, cmd, after_compute, (readers, reads));
        }
        self.recorded = true;
        Ok(())
    }

    /// Records the passes into the batch's own command buffer, submits and waits (headless path).
    pub fn run(&mut self, crowds: &[&Crowd]) -> Result<()> {
        let shared = self.shared.clone();
        let device = &shared.device;
        let cmd = self.cmd;
        // SAFETY: our command buffer is not pending (every run waits for completion).
        unsafe {
            device
                .reset_command_buffer(cmd, vk::CommandBufferResetFlags::empty())
                .map_err(Error::vk("vkResetCommandBuffer"))?;
            let begin = vk::CommandBufferBeginInfo::default()
                .flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT);
            device
                .begin_command_buffer(cmd, &begin)
                .map_err(Error::vk("vkBeginCommandBuffer"))?;
        }
        let recorded = self.record(cmd, crowds);
        // SAFETY: cmd is recording.
        let ended =
            unsafe { device.end_command_buffer(cmd) }.map_err(Error::vk("vkEndCommandBuffer"));
        recorded?;
        ended?;
        shared.submit_wait(cmd, self.fence)
    }

    /// Per-pass GPU time of the last recorded frame. After `record`, call it only once the
    /// engine's command buffer has completed; `NotReady` if the results are not there yet.
    pub fn timings(&self) -> Result<PassTimings> {
        let (Some(q), Some(period)) = (self.queries, self.shared.limits.timestamp_period_ns) else {
            return Err(Error::NotReady {
                what: "timestamps (the queue has no timestamp support)",
            });
        };
        if !self.recorded {
            return Err(Error::NotReady {
                what: "timestamps (nothing recorded yet)",
            });
        }
        let mut ticks = [0u64; TIMESTAMPS as usize];
        // SAFETY: our query pool; the queries were reset and written by recorded work.
        unsafe {
            self.shared.device.get_query_pool_results(
                q,
                0,
                &mut ticks,
                vk::QueryResultFlags::TYPE_64,
            )
        }
        .map_err(|result| match result {
            vk::Result::NOT_READY => Error::NotReady { what: "timestamps" },
            result => Error::Vulkan {
                call: "vkGetQueryPoolResults",
                result,
            },
        })?;
        let ms = |i: usize| ticks[i + 1].wrapping_sub(ticks[i]) as f64 * period * 1e-6;
        Ok(PassTimings {
            predict_ms: ms(0),
            blend_ms: ms(1),
            skin_ms: ms(2),
            normals_ms: ms(3),
        })
    }

    /// # Safety
    /// `cmd` must be recording.
    unsafe fn timestamp(&self, cmd: vk::CommandBuffer, index: u32) {
        if let Some(q) = self.queries {
            // SAFETY: see the function's contract; the query was reset in this command buffer.
            unsafe {
                self.shared.device.cmd_write_timestamp(
                    cmd,
                    vk::PipelineStageFlags::COMPUTE_SHADER,
                    q,
                    index,
                )
            };
        }
    }
}

impl Drop for Batch {
    fn drop(&mut self) {
        // SAFETY: `run` waits for its own submissions; after `record`, the caller guarantees the
        // engine's command buffer completed (crate contract).
        unsafe {
            if let Some(q) = self.queries {
                self.shared.device.destroy_query_pool(q, None);
            }
            self.shared.device.destroy_command_pool(self.pool, None);
            self.shared.device.destroy_fence(self.fence, None);
        }
    }
}

/// Binds `pass` and dispatches it once per chunk of `crowd`.
///
/// # Safety
/// `cmd` must be recording; the crowd's sets were written for `pass`.
unsafe fn dispatch_chunks<P: bytemuck::Pod>(
    device: &ash::Device,
    cmd: vk::CommandBuffer,
    pass: &PassPipeline,
    crowd: &Crowd,
    set_of: impl Fn(&Chunk) -> vk::DescriptorSet,
    push: impl Fn(&Inner, u32) -> P,
    groups: impl Fn(&Inner, u32) -> [u32; 3],
) {
    let m = &*crowd.model.inner;
    // SAFETY: see the function's contract.
    unsafe {
        device.cmd_bind_pipeline(cmd, vk::PipelineBindPoint::COMPUTE, pass.pipeline);
        for chunk in &crowd.chunks {
            device.cmd_bind_descriptor_sets(
                cmd,
                vk::PipelineBindPoint::COMPUTE,
                pass.layout,
                0,
                &[set_of(chunk)],
                &[],
            );
            let constants = push(m, chunk.characters);
            device.cmd_push_constants(
                cmd,
                pass.layout,
                vk::ShaderStageFlags::COMPUTE,
                0,
                bytemuck::bytes_of(&constants),
            );
            let [x, y, z] = groups(m, chunk.characters);
            device.cmd_dispatch(cmd, x, y, z);
        }
    }
}
