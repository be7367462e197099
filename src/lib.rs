//! # rrskin: the runtime of "Real-Time Enveloping with Rotational Regression"
//!
//! (Wang, Pulli, Popović, SIGGRAPH 2007.) A trained [`Model`] turns per-frame bone transforms
//! into deformed vertex positions and normals through six passes, for many characters at once:
//!
//! 1. keys `d(q)`: P key deformation gradients per character, each by its kind ([`Key`]):
//!    a key predictor (paper §3, Eq. 3–4) or a delta-mush key (docs/method.md §23), the
//!    rotation nearest to a weighted sum of a few bones' transforms; and,
//!    for a model with pose-space correctives (paper §8), their N weights `w = map · φ(q)`,
//!    linear in the driver joints' rotations relative to their parents;
//! 2. proxy transforms `t = C1 d + C2 q`: one matrix product over all characters (Eq. 5),
//!    dense, or block-sparse per proxy where `[C1 | C2]` is mostly zeros (joint-blend proxies:
//!    chosen when the model uploads, [`vk::GpuModel::is_block_sparse`]); where each proxy
//!    reads one key, the product evaluates that key's predictor itself and pass 1 does not run
//!    ([`vk::GpuModel::fuses_predictors`]);
//! 3. for a model with proxy correctives (docs/method.md §21, [`ProxyCorrectives`]), each
//!    corrected proxy `T_e ← T_e (I + E_e)`, `E_e = Σ_f x_f G_ef` from its drivers' rotations,
//!    in the palette (on a GPU a fused product applies them itself, and this pass does not
//!    run: [`vk::GpuModel::applies_correctives_in_product`]); where they see gravity
//!    ([`Model::up`]), also from each character's up vector ([`vk::Crowd::set_ups`],
//!    [`cpu::CpuEvaluator::set_ups`], [`palette::Palette::compute_batch_with_ups`]);
//! 4. matrix-palette skinning over the palette `[t (P); q (J)]` with K = 4 or 8 influences
//!    (of the rest position plus the N weighted corrective targets, where the model has them);
//! 5. normals, gathered from incident triangles;
//! 6. optionally tangent frames (models with rest tangents): each rest tangent through its
//!    vertex's blended palette matrix, made orthogonal to the normal.
//!
//! With transformed normals ([`NormalMode::Transformed`], [`vk::CrowdOptions::normals`]), pass
//! 4 also writes the normals (the rest normal through the cofactor of the blended matrix) and
//! the tangents, and passes 5 (but for the bounds) and 6 do not run: one pass a frame, as
//! engines skin.
//!
//! [`cpu::CpuEvaluator`] runs them on the CPU in `f64` (the reference); [`vk`] runs them as
//! Vulkan compute passes, recorded for all crowds into one command buffer. For an engine that
//! skins with its own shaders, [`palette::Palette`] runs steps 1–3 on the CPU in `f32`: bones in,
//! the P + J palette (and the N corrective weights) out, with no Vulkan at all. [`cost::Cost`]
//! predicts what a model costs on each, per character and against the engine's own skinning,
//! before it runs (docs/method.md §24).
//!
//! ## Contract
//!
//! This section is the contract of the Rust crate and of the C ABI alike: the C header's
//! preamble is made from it (and from the C conventions atop `src/ffi/mod.rs`) by
//! `tests/c_abi.rs`, and tests check its lists against the code. Where the C names differ they
//! are given beside the Rust ones.
//!
//! **Errors.** Every fallible call returns [`Result`] (C: an `rrskin_status`). Bad input — a
//! malformed or corrupted model file, inconsistent model parts, bone arrays of the wrong
//! length, NaN/Inf in per-frame input, indices out of range, work beyond a device limit — is an
//! [`Error`] naming what is wrong, never a panic. A [`Model`] that exists is valid: every index
//! the GPU reads is in range.
//!
//! **The caller's duties** (Vulkan makes them impossible to check cheaply):
//! - With an engine's device ([`vk::Context::from_engine`], `rrskin_context_create_from_engine`),
//!   the engine's objects must outlive the context, and the queue must be externally
//!   synchronised as Vulkan requires: the runtime submits to it only while loading a model,
//!   running a batch headless and reading outputs back (`rrskin_model_load_*`,
//!   `rrskin_crowds_run`, `rrskin_crowd_read_back`). With the runtime's own device
//!   ([`vk::Context::new`], which can enable surface and swapchain extensions), submit and
//!   present inside [`vk::Context::with_queue`].
//! - Frames in flight: a crowd is made for F of them ([`vk::CrowdOptions::frames_in_flight`],
//!   1 to 4, default 2) and keeps F slots of its per-frame inputs and host-read outputs (bone
//!   transforms, bounds). Set slot f's bones and record frame slot f ([`vk::Batch::record`])
//!   only once the GPU finished the last submission that recorded slot f; the other F − 1
//!   slots may be executing meanwhile (the headless path, [`vk::Batch::run`], waits itself).
//! - Drop (destroy) a crowd or a GPU model only after the GPU finished every command buffer it
//!   was recorded into. A model keeps its context's device alive, a crowd its model's buffers:
//!   they may be dropped in any order.
//!
//! **What a recording does** ([`vk::Batch::record`], `rrskin_crowds_record`), for an engine
//! that tracks state. Every buffer is a plain `VkBuffer` (no images, no layouts). Before: no
//! state is required — the first command is a global barrier from compute writes, compute
//! reads, transfer reads and (on a graphics queue) vertex-attribute reads of earlier
//! submissions to this recording's compute reads and writes, so last frame's draws of the
//! outputs may still be in flight on the queue. After: a global barrier makes every compute
//! write visible to compute shader reads, transfer reads, host reads and (on a graphics queue)
//! vertex attribute reads. Readers the end barrier does not cover record their own barrier
//! after the recording, from `COMPUTE_SHADER` / `SHADER_WRITE` (the runtime's last writes) to:
//! - vertex pulling (the outputs read as storage buffers in a vertex shader): `VERTEX_SHADER` /
//!   `SHADER_READ` (`SHADER_STORAGE_READ` with synchronization2);
//! - a ray-tracing BLAS built or refitted from the positions:
//!   `ACCELERATION_STRUCTURE_BUILD_KHR` / `SHADER_READ` (VK_KHR_acceleration_structure reads
//!   build inputs with that access);
//! - another stage or family: as Vulkan says for it (another family: after the acquire).
//!
//! In between, per crowd and frame slot f (pass n of the list above; the
//! bounds are written with the normals, a fused product reads the bones, and the proxy
//! correctives read the bones (and, where they see gravity, the characters' up vectors) and
//! update the palette's proxies in place):
//!
//! | buffer | access | memory |
//! |---|---|---|
//! | bone transforms, slot f | compute read (passes 1, 2, 3, 4, 6) | host-visible, written by setting the bones of slot f |
//! | up vectors, slot f | compute read (pass 3) | host-visible, written by setting the up vectors of slot f (models whose proxy correctives see gravity) |
//! | model buffers | compute read | device-local, written once at upload |
//! | B = [d; q] | compute write (pass 1), then read (pass 2) | device-local, internal |
//! | palette [t; q] | compute write (passes 1, 2, 3), then read (passes 3, 4, 6) | device-local, internal |
//! | positions (this frame's buffer) | compute write (pass 4), then read (pass 5) | device-local, vertex + storage + transfer-src |
//! | previous positions | not touched | the buffer the last recorded frame wrote |
//! | normals | compute write (passes 4, 5), then read (pass 6) | device-local, vertex + storage + transfer-src |
//! | bounds, slot f | compute write (pass 5) | host-visible, cached (read back), storage |
//! | tangents | compute write (passes 4, 6) | device-local, vertex + storage + transfer-src |
//! | corrective weights | compute write (pass 1), then read (pass 4) | device-local, internal (models with correctives) |
//!
//! It binds compute pipelines, descriptor set 0 and push constants (bytes 0..24) at
//! `VK_PIPELINE_BIND_POINT_COMPUTE`, and writes timestamps into the batch's own query pool; it
//! leaves the graphics bind point, render passes and dynamic state alone, and never begins,
//! ends or submits the command buffer. The engine re-binds its own compute state after it.
//!
//! **Queue family ownership.** Every buffer is created `VK_SHARING_MODE_EXCLUSIVE` and used on
//! the context's queue family only: outputs drawn on that family need nothing more. For an
//! engine that reads outputs on another family, [`vk::CrowdOptions::release_to_queue_family`]
//! (C: `release_outputs` and `release_queue_family`) ends each recording with the release
//! barriers of the frame's outputs (its positions, the normals, its bounds, the tangents: those
//! the crowd has; whole buffers, compute writes); the engine records the matching acquires on
//! its queue after a semaphore wait. The runtime never reads an output a previous recording
//! wrote, so nothing needs to come back: the next recording overwrites it (undefined old
//! contents are never read). The drawn outputs (positions, normals, tangents) are one buffer
//! each, shared by every frame slot (positions alternate between two with previous positions),
//! and the recording's first barrier orders only work on the context's queue: an engine that
//! reads them on another family (async compute) makes the compute submission of the next
//! recording, whatever its slot, wait on a semaphore its reading submission signals after its
//! last read (draws, copies, a BLAS build), or that recording overwrites what is still drawn.
//!
//! **Memory and requirements before creation.** [`vk::model_bytes`] and [`vk::crowd_bytes`]
//! (`rrskin_query_memory`) give the bytes a model and a crowd of C characters will take, from
//! their sizes alone ([`vk::ModelSizes::of`] a model, including the stored columns of a
//! block-sparse C1/C2); creating a crowd beyond the largest device-local heap is a
//! `DeviceLimit` error, and one with a buffer past the largest the device makes and binds
//! (`maxMemoryAllocationSize`, and `maxBufferSize` with maintenance4; per character:
//! [`vk::crowd_largest_buffer_bytes`]) a `BufferTooLarge` error naming the buffer, where
//! Vulkan would be undefined behaviour: make several crowds of fewer characters.
//! [`vk::requirements`] (`rrskin_get_requirements`) gives the Vulkan version (1.1), extensions
//! (none), features (none), queue flags and the storage buffers per stage that every model in
//! every mode runs with, before any device exists; [`vk::Context::from_engine`] checks the
//! version and that every Vulkan function the runtime calls is there (`MissingFunction`
//! otherwise, never a call through a NULL pointer). A device with fewer storage buffers per
//! stage runs the models whose passes fit: a crowd whose widest pass binds more is a
//! `DeviceLimit` error naming maxPerStageDescriptorStorageBuffers.
//!
//! **Threads.** [`vk::Context`] is `Send + Sync`; recording and running take `&mut` on what they
//! write, so Rust's borrow rules are the threading rules. C: any function from any thread; calls
//! on different objects run concurrently (a global lock covers only the lookup of a handle), and
//! calls on one object are serialised by its own lock (see the conventions).
//!
//! **Faults.** A failed creation (out of memory in any allocation or creation along a model or
//! a crowd, or a failed submission) returns its error and leaves nothing behind: the context
//! stays usable. `VK_ERROR_DEVICE_LOST` becomes [`Error::DeviceLost`], and from then on every
//! submission on the context fails with it at once ([`vk::Context::check_lost`]); objects can
//! still be dropped.
//!
//! **Units and layouts.** Bone transforms are 3x4 row-major `f32` ([`predict::Affine`]), world
//! space, relative to the rest pose (`x ↦ Q x + d` takes a rest point to the posed one). Up
//! vectors are 3 `f32` per character in the frame of its bones, the direction opposite to
//! gravity (its length gravity's strength against the training poses'); a crowd starts with the
//! model's up ([`Model::up`]). Outputs
//! are tightly packed `f32` xyz (12-byte stride), character after character; previous positions
//! likewise (undefined until a crowd recorded two frames); bounds are two std430 `vec4` per
//! character (min xyz, max xyz; [`vk::BOUNDS_STRIDE`] = 32 bytes); tangents are 4 `f32` per
//! vertex (xyz unit and orthogonal to the normal, w = ±1 with bitangent = cross(n, t) * w, as
//! glTF's TANGENT; [`vk::TANGENT_STRIDE`] = 16 bytes), zero where the skinned tangent vanishes.

pub mod cost;
pub mod cpu;
pub mod error;
pub mod ffi;
pub mod model;
pub mod normals;
pub mod palette;
pub mod polar;
pub mod predict;
pub mod vk;

pub use error::{Error, ModelProblem, Result};
pub use model::{
    Correctives, DeltaMushKey, DeltaMushTerm, FeatureRange, Key, KeyKind, KeyPredictor, Model,
    ModelParts, ProxyCorrectives, SecondBone,
};
pub use normals::NormalMode;
