//! The Vulkan runtime (ash + gpu-allocator): six compute passes per frame for many characters
//! (the third, proxy correctives, for models with them; the sixth, tangents, for crowds that
//! ask for them).
//!
//! - [`Context`]: headless (own instance/device) or wrapping an engine's objects.
//! - [`GpuModel`]: a [`crate::Model`] uploaded once (device-local, read-only).
//! - [`Crowd`]: C characters of one GPU model: bone input, palette, output positions/normals
//!   (and optionally previous positions, bounds, tangents).
//! - [`Batch`]: records the passes of any number of crowds into ONE command buffer, pass-major
//!   (all predictors and corrective weights, barrier, all C1/C2 products, barrier, all proxy
//!   correctives `T_e (I + E_e)` in the palettes, barrier, all skinning, barrier, all normals,
//!   barrier, all tangents), with GPU timestamps per pass; `run`
//!   submits and waits, `record` writes into the caller's buffer.
//!
//! Each pass is described once in `passes.rs` (its shader from `glsl/shaders.txt`, its bindings
//! in the order of its shader in `glsl/`, push words, workgroups; the types are in `pass.rs`);
//! pipelines, layouts, descriptor pools, limit checks and dispatches are derived from that
//! table, and `batch.rs` orders the passes into a schedule with barriers from named accesses
//! (`barrier.rs`). The buffers the bindings name are the enums of `pass.rs`, sized in
//! `memory.rs` and held in arrays indexed by them (`gpu_model.rs`, `crowd.rs`).

mod barrier;
mod batch;
mod buffer;
mod context;
#[cfg(test)]
mod contract;
mod crowd;
mod device_ext;
mod gpu_model;
mod memory;
mod pass;
mod passes;
mod pipelines;
mod requirements;

pub use ash;
pub use batch::{Batch, PassTimings};
pub use context::{Context, ContextDesc, DeviceChoice, EngineDevice, Limits, TimestampClock};
pub use crowd::{
    Aabb, Crowd, CrowdDebugSettings, CrowdOptions, CrowdOutput, HostIntermediates, HostOutput,
    BOUNDS_STRIDE, MAX_FRAMES_IN_FLIGHT, TANGENT_STRIDE,
};
pub use gpu_model::{GpuModel, GpuModelDebugSettings};
pub use memory::{crowd_bytes, crowd_largest_buffer_bytes, model_bytes, ModelSizes};
pub use requirements::{requirements, Requirements};
