//! rrskin's offline tools, grouped by phase:
//!
//! - [`import`]: example sets (pose, deformed mesh) from NumPy folders, glTF rigs and point
//!   caches, validated;
//! - [`train`]: the training pipeline of the paper, one module per stage, and [`train::run`];
//! - [`eval`]: the enveloping error (§7.1), the baselines, the error budget, leave-one-out;
//! - [`run`]: what runs a trained model on the Vulkan runtime: bench, profile, the demo;
//! - [`export`]: a trained model as a standard skinned glTF, for any engine's own skinning;
//! - [`output`]: outputs checked before long work, and paths shown as a user types them;
//! - [`cylinder_chain`]: a synthetic example set of any size, for timing training.
//!
//! The `rrskin` binary is a thin CLI over these modules.
//!
//! Letters as everywhere in the project: V vertices, T triangles, J bones, N example poses,
//! K influences per vertex, P proxy bones; i indexes poses, a vertices, k triangles, b bones.

// The numeric kernels index several arrays in lockstep (rows, columns, poses); index loops read
// closer to the equations than zipped iterators.
#![allow(clippy::needless_range_loop)]

pub mod cylinder_chain;
pub mod error;
pub mod eval;
pub mod export;
pub mod import;
pub mod linalg;
pub mod output;
pub mod progress;
pub mod run;
pub mod train;

pub use error::{Error, Result};
