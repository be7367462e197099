//! rrskin's offline tools: example sets, training (SSD, rotational regression, Poisson
//! reconstruction), evaluation, model inspection, synthetic models and runtime profiling. The
//! `rrskin` binary is a thin CLI over these modules.
//!
//! Letters as everywhere in the project: V vertices, T triangles, J bones, N example poses,
//! K influences per vertex; i indexes poses, a vertices, k triangles, b bones.

// The numeric kernels index several arrays in lockstep (rows, columns, poses); index loops read
// closer to the equations than zipped iterators.
#![allow(clippy::needless_range_loop)]

pub mod augment;
pub mod demo;
pub mod dqs;
pub mod eval;
pub mod example_set;
pub mod full_model;
pub mod gltf_rig;
pub mod gradients;
pub mod image;
pub mod import;
pub mod linalg;
pub mod npy;
pub mod point_cache;
pub mod poisson;
pub mod predictor_reduction;
pub mod profile;
pub mod progress;
pub mod reduced;
pub mod rotreg;
pub mod runtime_fit;
pub mod scale_shear;
pub mod ssd;
pub mod vertex_reduction;
