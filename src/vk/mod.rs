//! The Vulkan runtime (ash + gpu-allocator): four compute passes per frame for many characters
//! (five with tangents).
//!
//! - [`Context`]: headless (own instance/device) or wrapping an engine's objects.
//! - [`GpuModel`]: a [`crate::Model`] uploaded once (device-local, read-only).
//! - [`Crowd`]: C characters of one GPU model: bone input, palette, output positions/normals
//!   (and optionally previous positions, bounds, tangents).
//! - [`Batch`]: records the passes of any number of crowds into ONE command buffer, pass-major
//!   (all predictors, barrier, all GEMMs, barrier, all skinning, barrier, all normals, barrier,
//!   all tangents), with GPU
//!   timestamps per pass; `run` submits and waits, `record` writes into the caller's buffer.
//!
//! Each pass is described once in `passes.rs` (its SPIR-V, its bindings in the order of its
//! shader in `glsl/`, push words, workgroups; the types are in `pass.rs`); pipelines, layouts,
//! descriptor pools, limit checks and dispatches are derived from that table, and `batch.rs`
//! orders the passes into a schedule with barriers from named accesses (`barrier.rs`).

mod barrier;
mod batch;
mod buffer;
mod context;
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
pub use context::{Context, ContextDesc, DeviceChoice, EngineDevice, Limits};
pub use crowd::{
    Aabb, Crowd, CrowdOptions, CrowdOutput, HostOutput, BOUNDS_STRIDE, MAX_FRAMES_IN_FLIGHT,
    TANGENT_STRIDE,
};
pub use gpu_model::GpuModel;
pub use memory::{crowd_bytes, crowd_largest_buffer_bytes, model_bytes, ModelSizes};
pub use requirements::{requirements, Requirements};
