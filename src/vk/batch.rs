//! Records the passes of any number of crowds into ONE command buffer, pass-major: the
//! [`SCHEDULE`] is a list of phases, each dispatched for every crowd whose model runs it, so a
//! frame has at most one barrier per phase whatever the number of crowds and chunks:
//!
//! ```text
//! ts0 | barrier(prev. frame's reads/writes → compute) | predict (crowds with P > 0, not fused)
//!     |         and corrective weights (crowds of models with pose-space correctives)
//! ts1 | barrier | C1/C2 product (all crowds with P > 0: the GEMM, the sparse or the fused one)
//! ts2 | barrier | proxy correctives, in the palette (crowds of models with them)
//! ts3 | barrier | skin (all crowds, the pipeline of their K)
//! ts4 | barrier | normals and bounds (all crowds; bounds where the crowd has them)
//! ts5 | barrier | tangents (crowds with tangents, the pipeline of their K)
//! ts6 | barrier(compute writes → vertex input, transfer, compute and host reads)
//! ```
//! Frame slot f of every crowd reads its own bone transforms and writes its own bounds, so
//! recording frame f while the other frames in flight execute is safe; the buffers frames
//! share (intermediates, positions, normals) are ordered by the first barrier, which waits
//! for earlier submissions' uses on the queue. Timestamps are ringed per frame slot too.
//! A barrier between phases is recorded where a phase touches a crowd buffer written (or
//! writes one read) since the last barrier, as the table's bindings say (so a frame without
//! proxy correctives records neither their phase's barrier nor any dispatch). ts0..ts5 are GPU
//! timestamps; [`Batch::timings`] turns them into per-phase milliseconds.

use super::barrier::{global_barrier, Access, PASS_ACCESSES};
use super::context::{Context, Shared};
use super::crowd::{Crowd, MAX_FRAMES_IN_FLIGHT};
use super::passes::Pass;
use crate::error::{Error, Result};
use ash::vk;
use std::sync::Arc;

/// The frame: phases in order, each a set of passes without dependencies among them (one
/// timestamp per phase, reported by [`PassTimings`]).
pub(super) const SCHEDULE: [&[Pass]; 6] = [
    &[Pass::Predict, Pass::CorrectiveWeights],
    &[
        Pass::DenseProduct,
        Pass::SparseProduct,
        Pass::FusedProduct,
        Pass::FusedCorrectedProduct,
    ],
    &[Pass::ProxyCorrectives, Pass::ProxyCorrectivesGravity],
    &[
        Pass::SkinK4,
        Pass::SkinK8,
        Pass::SkinNormalsK4,
        Pass::SkinNormalsK8,
        Pass::SkinFramesK4,
        Pass::SkinFramesK8,
    ],
    &[Pass::Normals, Pass::Bounds],
    &[Pass::TangentsK4, Pass::TangentsK8],
];

/// Everything that meets a frame's buffers outside the batch: the next frame's compute
/// writes, then the consumers of its outputs (compute reads, copies, host reads of the
/// bounds, and vertex fetch where the queue can draw).
const OUTSIDE: [Access; 5] = [
    Access::ComputeShaderWrite,
    Access::ComputeShaderReadStorage,
    Access::TransferRead,
    Access::HostRead,
    Access::VertexBuffer,
];

/// The earlier uses the first barrier waits for: host reads need none (the host reads a slot
/// before it records that slot again, and a submission orders host work before it).
const BEFORE: [Access; 4] = [OUTSIDE[0], OUTSIDE[1], OUTSIDE[2], OUTSIDE[4]];

/// Timestamps of one frame slot; the pool holds [`MAX_FRAMES_IN_FLIGHT`] slots.
const TIMESTAMPS: u32 = SCHEDULE.len() as u32 + 1;

/// GPU time per pass of a recorded frame, in milliseconds (the bounds count with the normals; a
/// fused product's predictors and proxy correctives with the product; the corrective weights
/// with the predictors; transformed normals and their tangents with the skinning).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct PassTimings {
    /// The key predictors and the pose-space corrective weights.
    pub predict_ms: f64,
    /// The C1/C2 product t = C1 d + C2 q (dense, block-sparse or fused).
    pub product_ms: f64,
    /// The proxy correctives, T_e (I + E_e) in the palette (0 where no crowd has them).
    pub proxy_correctives_ms: f64,
    pub skin_ms: f64,
    pub normals_ms: f64,
    /// 0 for crowds without tangents (the phase records no dispatch).
    pub tangents_ms: f64,
}

impl PassTimings {
    pub fn total_ms(&self) -> f64 {
        self.predict_ms
            + self.product_ms
            + self.proxy_correctives_ms
            + self.skin_ms
            + self.normals_ms
            + self.tangents_ms
    }

    /// The median of each pass over `samples`, and the median frame total (None if empty).
    pub fn median(samples: &[PassTimings]) -> Option<(PassTimings, f64)> {
        let median = |f: fn(&PassTimings) -> f64| crate::cpu::median(samples.iter().map(f));
        let passes = PassTimings {
            predict_ms: median(|t| t.predict_ms)?,
            product_ms: median(|t| t.product_ms)?,
            proxy_correctives_ms: median(|t| t.proxy_correctives_ms)?,
            skin_ms: median(|t| t.skin_ms)?,
            normals_ms: median(|t| t.normals_ms)?,
            tangents_ms: median(|t| t.tangents_ms)?,
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
    /// Which frame slots' queries were recorded (asking for unrecorded ones is a validation
    /// error).
    recorded: [bool; MAX_FRAMES_IN_FLIGHT],
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
            recorded: [false; MAX_FRAMES_IN_FLIGHT],
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
        if shared.limits.timestamps.is_some() {
            let info = vk::QueryPoolCreateInfo::default()
                .query_type(vk::QueryType::TIMESTAMP)
                .query_count(TIMESTAMPS * MAX_FRAMES_IN_FLIGHT as u32);
            // SAFETY: valid device and create info.
            batch.queries = Some(
                unsafe { device.create_query_pool(&info, None) }
                    .map_err(Error::vk("vkCreateQueryPool"))?,
            );
        }
        Ok(batch)
    }

    /// Records frame slot `frame` of `crowds` into the caller's command buffer (engine path):
    /// their bones as set by `set_bones(frame, ..)`, their bounds into slot `frame`. `cmd` must
    /// be recording, outside a render pass, on a queue of the context's queue family. Fails,
    /// recording nothing, if `frame` is not a slot of every crowd or a crowd is listed twice.
    pub fn record(
        &mut self,
        cmd: vk::CommandBuffer,
        frame: usize,
        crowds: &[&Crowd],
    ) -> Result<()> {
        for (i, crowd) in crowds.iter().enumerate() {
            if !Arc::ptr_eq(crowd.shared(), &self.shared) {
                return Err(Error::Mismatch {
                    what: "a crowd of another context",
                });
            }
            crowd.check_frame(frame)?;
            if crowds[..i].iter().any(|c| std::ptr::eq(*c, *crowd)) {
                return Err(Error::Mismatch {
                    what: "a crowd listed twice in one frame",
                });
            }
        }
        for crowd in crowds {
            crowd.begin_frame(frame);
        }
        let device = &self.shared.device;
        let graphics = usize::from(self.shared.queue_has_graphics);
        let before = &BEFORE[..3 + graphics];
        let after = &OUTSIDE[1..4 + graphics];
        let runs = |pass: Pass| crowds.iter().filter(move |c| pass.runs_for(&c.dims));
        let barriers = barriers_before(|pass| runs(pass).next().is_some());
        let first = frame as u32 * TIMESTAMPS;
        // SAFETY: cmd is recording (caller's contract); every handle belongs to this device and
        // lives as long as the crowds.
        unsafe {
            if let Some(q) = self.queries {
                device.cmd_reset_query_pool(cmd, q, first, TIMESTAMPS);
            }
            for (i, phase) in SCHEDULE.iter().enumerate() {
                self.timestamp(cmd, first + i as u32);
                if i == 0 {
                    // WAR against earlier frames' readers (vertex fetch, copies) and WAW against
                    // their writes.
                    global_barrier(device, cmd, before, &PASS_ACCESSES);
                } else if barriers[i] {
                    global_barrier(device, cmd, &[Access::ComputeShaderWrite], &PASS_ACCESSES);
                }
                for &pass in *phase {
                    for crowd in runs(pass) {
                        dispatch_chunks(device, cmd, pass, crowd, frame);
                    }
                }
            }
            self.timestamp(cmd, first + SCHEDULE.len() as u32);
            global_barrier(device, cmd, &[Access::ComputeShaderWrite], after);
            for crowd in crowds {
                crowd.release_outputs(cmd, frame);
            }
        }
        self.recorded[frame] = true;
        Ok(())
    }

    /// Records frame slot `frame` of `crowds` into the batch's own command buffer, submits and
    /// waits (headless path).
    pub fn run(&mut self, frame: usize, crowds: &[&Crowd]) -> Result<()> {
        let shared = self.shared.clone();
        let (cmd, fence) = (self.cmd, self.fence);
        // Our command buffer is not pending: every run waits for completion.
        shared.rerecord_and_submit(cmd, fence, |cmd| self.record(cmd, frame, crowds))
    }

    /// Per-pass GPU time of frame slot `frame` as last recorded. After `record`, call it only
    /// once the engine's command buffer has completed; `NotReady` if the results are not there
    /// yet.
    pub fn timings(&self, frame: usize) -> Result<PassTimings> {
        let (Some(q), Some(clock)) = (self.queries, self.shared.limits.timestamps) else {
            return Err(Error::NotReady {
                what: "timestamps (the queue has no timestamp support)",
            });
        };
        if !self.recorded.get(frame).copied().unwrap_or(false) {
            return Err(Error::NotReady {
                what: "timestamps (the frame slot was never recorded)",
            });
        }
        let mut ticks = [0u64; TIMESTAMPS as usize];
        // SAFETY: our query pool; the queries were reset and written by recorded work.
        unsafe {
            self.shared.device.get_query_pool_results(
                q,
                frame as u32 * TIMESTAMPS,
                &mut ticks,
                vk::QueryResultFlags::TYPE_64,
            )
        }
        .map_err(|result| match result {
            vk::Result::NOT_READY => Error::NotReady { what: "timestamps" },
            result => self.shared.note(Error::vk("vkGetQueryPoolResults")(result)),
        })?;
        let ms = |i: usize| clock.ms_between(ticks[i], ticks[i + 1]);
        let phases: [f64; SCHEDULE.len()] = std::array::from_fn(ms);
        // One field per phase of the schedule (a new phase needs its field here).
        let [predict_ms, product_ms, proxy_correctives_ms, skin_ms, normals_ms, tangents_ms] =
            phases;
        Ok(PassTimings {
            predict_ms,
            product_ms,
            proxy_correctives_ms,
            skin_ms,
            normals_ms,
            tangents_ms,
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

/// Whether each phase of the schedule must wait for the phases before it, given the passes
/// that `dispatch` this frame: where it reads or writes a crowd buffer written since the last
/// barrier, or writes one read since then. The first phase always waits (for the last frame).
fn barriers_before(dispatch: impl Fn(Pass) -> bool) -> [bool; SCHEDULE.len()] {
    let mut barriers = [false; SCHEDULE.len()];
    // Crowd buffers read and written since the last barrier, as `CrowdBuffer::bit` sets.
    let (mut read, mut written) = (0, 0);
    for (barrier, phase) in barriers.iter_mut().zip(SCHEDULE) {
        let (reads, writes) = (phase.iter().filter(|&&p| dispatch(p)))
            .map(|p| p.desc().crowd_accesses())
            .fold((0, 0), |(r, w), (pr, pw)| (r | pr, w | pw));
        *barrier = (reads | writes) & written != 0 || writes & read != 0;
        if *barrier {
            (read, written) = (0, 0);
        }
        read |= reads;
        written |= writes;
    }
    barriers[0] = true;
    barriers
}

/// Binds `pass` and dispatches it once per chunk of `crowd`, with the sets of frame slot
/// `frame` as begun.
///
/// # Safety
/// `cmd` must be recording; the crowd runs `pass`; `frame` is one of its slots.
unsafe fn dispatch_chunks(
    device: &ash::Device,
    cmd: vk::CommandBuffer,
    pass: Pass,
    crowd: &Crowd,
    frame: usize,
) {
    let desc = pass.desc();
    let pipeline = crowd.shared().pipelines.get(pass);
    let dims = &crowd.dims;
    let variant = crowd.variant(frame);
    // SAFETY: see the function's contract.
    unsafe {
        device.cmd_bind_pipeline(cmd, vk::PipelineBindPoint::COMPUTE, pipeline.pipeline);
        for chunk in &crowd.chunks {
            device.cmd_bind_descriptor_sets(
                cmd,
                vk::PipelineBindPoint::COMPUTE,
                pipeline.layout,
                0,
                &[chunk.sets[variant][pass as usize]],
                &[],
            );
            let words = desc.push_words(dims, chunk.characters);
            device.cmd_push_constants(
                cmd,
                pipeline.layout,
                vk::ShaderStageFlags::COMPUTE,
                0,
                bytemuck::cast_slice(&words[..desc.push.len()]),
            );
            let [x, y, z] = desc.dispatch(dims, chunk.characters);
            device.cmd_dispatch(cmd, x, y, z);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_schedule_runs_every_pass_of_the_table_once() {
        for pass in Pass::ALL {
            let places = SCHEDULE
                .iter()
                .flat_map(|phase| phase.iter())
                .filter(|&&p| p == pass);
            assert_eq!(places.count(), 1, "{pass:?}");
        }
    }

    /// Whether `b` must wait for `a` on the buffers of one crowd: it touches what `a` wrote,
    /// or writes what `a` read.
    fn depends(a: Pass, b: Pass) -> bool {
        let (ar, aw) = a.desc().crowd_accesses();
        let (br, bw) = b.desc().crowd_accesses();
        (br | bw) & aw != 0 || bw & ar != 0
    }

    /// Checked against a direct reading of the hazards, for every subset of the table
    /// dispatching: every pair of passes in different phases where the later depends on the
    /// earlier is separated by a barrier.
    #[test]
    fn a_barrier_separates_every_dependent_pair_of_passes() {
        for subset in 0u32..1 << Pass::COUNT {
            let dispatch = |p: Pass| subset & (1 << p as u32) != 0;
            let barriers = barriers_before(dispatch);
            let dispatched = |i: usize| SCHEDULE[i].iter().copied().filter(move |&p| dispatch(p));
            for j in 0..SCHEDULE.len() {
                for i in 0..j {
                    for (a, b) in dispatched(i).flat_map(|a| dispatched(j).map(move |b| (a, b))) {
                        if depends(a, b) {
                            assert!(
                                barriers[i + 1..=j].contains(&true),
                                "{b:?} after {a:?} (passes {subset:#b})"
                            );
                        }
                    }
                }
            }
        }
    }

    /// A phase has no barrier inside: no model runs two passes of one phase that depend on
    /// each other (the skinning variants, and the products, share a phase because a model
    /// runs only one of each).
    #[test]
    fn no_model_runs_dependent_passes_in_one_phase() {
        for d in super::super::passes::model_kinds() {
            for phase in SCHEDULE {
                for &a in phase.iter().filter(|p| p.runs_for(&d)) {
                    for &b in phase.iter().filter(|&&p| p != a && p.runs_for(&d)) {
                        assert!(!depends(a, b), "{a:?} and {b:?} share a phase for {d:?}");
                    }
                }
            }
        }
    }

    #[test]
    fn frames_without_reduced_models_skip_the_barriers_of_their_passes() {
        let lbs = |p: Pass| matches!(p, Pass::SkinK4 | Pass::Normals);
        assert_eq!(
            barriers_before(lbs),
            [true, false, false, false, true, false]
        );
        let bounded_lbs = |p: Pass| matches!(p, Pass::SkinK4 | Pass::Normals | Pass::Bounds);
        assert_eq!(
            barriers_before(bounded_lbs),
            [true, false, false, false, true, false]
        );
        // Reduced models without proxy correctives: no barrier for their empty phase.
        let reduced = |p: Pass| matches!(p, Pass::Predict | Pass::DenseProduct | Pass::SkinK4);
        assert_eq!(
            barriers_before(reduced),
            [true, true, false, true, false, false]
        );
        // With them: one barrier after the product, one after the correction.
        let corrected = |p: Pass| {
            matches!(
                p,
                Pass::FusedProduct | Pass::ProxyCorrectives | Pass::SkinK8 | Pass::Normals
            )
        };
        assert_eq!(
            barriers_before(corrected),
            [true, false, true, true, true, false]
        );
        assert_eq!(barriers_before(|_| true), [true; 6]);
    }
}
