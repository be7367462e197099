//! Running trained models on the Vulkan runtime: `rrskin bench`, `rrskin profile`, `rrskin demo`;
//! and the CPU reference frames of `rrskin reference`.

pub mod bench;
pub mod capacity;
pub mod demo;
pub mod figure;
pub mod image;
pub mod info;
pub mod palette_bench;
pub mod profile;
pub mod reference;
pub mod report;
pub mod tradeoff;
pub mod traffic;
