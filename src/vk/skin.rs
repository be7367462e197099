//! Pass 3, `glsl/skin.comp`: matrix-palette skinning with K = 4 or 8 influences over the
//! palette `[proxies (P); bones (J)]` (the bones are read in place, never copied).

use super::crowd::ChunkViews;
use super::gpu_model::Inner;
use ash::vk::DescriptorBufferInfo;

/// Bindings in shader order.
pub const BINDINGS: [&str; 6] = [
    "rest positions",
    "skin indices",
    "skin weights",
    "proxies",
    "bones",
    "positions",
];

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
pub struct Push {
    pub vertices: u32,
    pub proxies: u32,
    pub bones: u32,
    pub chars: u32,
}

pub fn bindings(m: &Inner, v: &ChunkViews) -> [DescriptorBufferInfo; 6] {
    [
        m.rest.whole(),
        m.skin_index.whole(),
        m.skin_weight.whole(),
        v.proxies,
        v.bones,
        v.positions,
    ]
}

pub fn push(m: &Inner, chars: u32) -> Push {
    Push {
        vertices: m.vertices,
        proxies: m.proxies,
        bones: m.bones,
        chars,
    }
}

/// local_size_x = 64 over vertices, one row of groups per character.
pub fn groups(m: &Inner, chars: u32) -> [u32; 3] {
    [m.vertices.div_ceil(64), chars, 1]
}
