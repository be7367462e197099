//! Pass 1, `glsl/predict.comp`: key gradients D_ℓ(q) for every (predictor, character), written
//! with the bone transforms into B = [d; q], the right-hand side of pass 2.

use super::crowd::ChunkViews;
use super::gpu_model::Inner;
use ash::vk::DescriptorBufferInfo;

/// Bindings in shader order.
pub const BINDINGS: [&str; 4] = ["bones", "parents", "predictors", "rhs"];

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
pub struct Push {
    pub proxies: u32,
    pub bones: u32,
    pub chars: u32,
}

pub fn bindings(m: &Inner, v: &ChunkViews) -> [DescriptorBufferInfo; 4] {
    [v.bones, m.parents.whole(), m.predictors.whole(), v.rhs]
}

pub fn push(m: &Inner, chars: u32) -> Push {
    Push {
        proxies: m.proxies,
        bones: m.bones,
        chars,
    }
}

/// local_size_x = 64 over predictors then bones, one row of groups per character.
pub fn groups(m: &Inner, chars: u32) -> [u32; 3] {
    [(m.proxies + m.bones).div_ceil(64), chars, 1]
}
