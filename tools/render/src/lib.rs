//! # rrskin-render: around the runtime, not in it
//!
//! What the crowd sample, `rrskin demo`, `rrskin bench`/`profile`, the benches and the tests need
//! beside the runtime, and engines do not (so the shipped `rrskin` library stays the runtime):
//!
//! - [`Renderer`]: an offscreen renderer drawing crowds straight from their output buffers, and
//!   host meshes with per-vertex colours (its shaders: `glsl/shade.vert`, `glsl/shade.frag`);
//! - [`scene`]: a camera, the grid layout and clear colour of the crowd images, and the phase
//!   convention of a crowd playing its model's animation;
//! - [`synthetic`]: random valid models and poses of any size, for tests and profiling.
//!
//! It builds only on the runtime's public API ([`rrskin::vk::Context`]'s device handles and
//! queue, [`rrskin::vk::GpuModel::triangle_buffer`], [`rrskin::vk::Crowd::output`]), with a
//! GPU allocator of its own.

mod gpu;
pub mod renderer;
pub mod scene;
pub mod synthetic;

pub use renderer::{Draw, HostMesh, Renderer};
pub use scene::{grid_scene, phased_poses, Camera, GridScene, CROWD_BACKGROUND};
