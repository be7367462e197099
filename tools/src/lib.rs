//! rrskin's offline tools: model inspection, synthetic models and runtime profiling (and, as
//! the project grows, import, training and evaluation). The `rrskin` binary is a thin CLI over
//! these modules.

pub mod profile;
pub mod progress;
