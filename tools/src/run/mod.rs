//! Running trained models on the Vulkan runtime: `rrskin bench`, `rrskin profile`, `rrskin demo`.

pub mod capacity;
pub mod demo;
pub mod image;
pub mod profile;
