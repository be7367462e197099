//! # rrskin: the runtime of "Real-Time Enveloping with Rotational Regression"
//!
//! (Wang, Pulli, Popović, SIGGRAPH 2007.) A trained [`Model`] turns per-frame bone transforms
//! into deformed vertex positions and normals through four passes, for many characters at once:
//!
//! 1. predictors `d(q)`: P key deformation gradients per character (paper §3, Eq. 3–4);
//! 2. proxy transforms `t = C1 d + C2 q`: one matrix product over all characters (Eq. 5);
//! 3. matrix-palette skinning over `[t (P); q (J)]` with K = 4 or 8 influences;
//! 4. normals, gathered from incident triangles.
//!
//! [`cpu::CpuEvaluator`] runs them on the CPU in `f64` (the reference); [`vk`] runs them as
//! Vulkan compute passes, recorded for all crowds into one command buffer.
//!
//! ## Contract
//!
//! **Errors.** Every fallible call returns [`Result`]. Bad input — a malformed or corrupted model
//! file, inconsistent model parts, bone arrays of the wrong length, NaN/Inf in per-frame input,
//! indices out of range, work beyond a device limit — is an [`Error`] naming what is wrong, never
//! a panic. A [`Model`] that exists is valid: every index the GPU reads is in range.
//!
//! **The caller's duties** (Vulkan makes them impossible to check cheaply):
//! - With an engine's device ([`vk::Context::from_engine`]), the engine's objects must outlive
//!   the context, and the queue must be externally synchronised as Vulkan requires. With the
//!   runtime's own device ([`vk::Context::new`], which can enable surface and swapchain
//!   extensions), submit and present inside [`vk::Context::with_queue`].
//! - A crowd's bone transforms live in host-visible memory read by the recorded commands: call
//!   [`vk::Crowd::set_bones`] only when no submitted command buffer that reads the crowd is still
//!   executing (the headless path, [`vk::Batch::run`], waits itself).
//! - Drop a crowd or a GPU model only after the GPU finished every command buffer it was recorded
//!   into. Objects are freed in `Drop`; the context is freed after every object made from it.
//! - Output buffers are written by compute shaders; the recorded commands end with a barrier that
//!   makes them visible to vertex input, transfer and compute reads on the same queue. Queue
//!   family ownership transfers are the caller's.
//!
//! **Threads.** [`vk::Context`] is `Send + Sync`; recording and running take `&mut` on what they
//! write, so Rust's borrow rules are the threading rules.
//!
//! **Units and layouts.** Bone transforms are 3x4 row-major `f32` ([`predict::Affine`]), world
//! space, relative to the rest pose (`x ↦ Q x + d` takes a rest point to the posed one). Outputs
//! are tightly packed `f32` xyz (12-byte stride), character after character.

pub mod cpu;
pub mod error;
pub mod ffi;
pub mod model;
pub mod predict;
pub mod vk;

pub use error::{Error, ModelProblem, Result};
pub use model::{KeyPredictor, Model, ModelParts, SecondBone};
