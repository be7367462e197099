//! rrskin's offline tools, grouped by phase:
//!
//! - [`set`]: the example set (pose, deformed mesh), validated once by `ExampleSet::new`;
//! - [`skinning`]: skinning without learning (LBS, rigid, DQS, CoR, DDM) and the enveloping
//!   error;
//! - [`import`]: example sets from NumPy folders, glTF or FBX rigs and point caches;
//! - [`train`]: the training pipeline of the paper, one module per stage, and [`train::run`];
//! - [`eval`]: every method's enveloping error (§7.1), the error budget, leave-one-out;
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
pub mod set;
pub mod skinning;
pub mod train;

pub use error::{Error, Result};
