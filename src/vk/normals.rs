//! Pass 4, `glsl/normals.comp`: normals gathered from each vertex's incident triangles.

use super::crowd::ChunkViews;
use super::gpu_model::Inner;
use ash::vk::DescriptorBufferInfo;

/// Bindings in shader order.
pub const BINDINGS: [&str; 5] = [
    "positions",
    "incident offsets",
    "incident triangles",
    "triangles",
    "normals",
];

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
pub struct Push {
    pub vertices: u32,
    pub chars: u32,
}

pub fn bindings(m: &Inner, v: &ChunkViews) -> [DescriptorBufferInfo; 5] {
    [
        v.positions,
        m.incident_offsets.whole(),
        m.incident_triangles.whole(),
        m.triangles.whole(),
        v.normals,
    ]
}

pub fn push(m: &Inner, chars: u32) -> Push {
    Push {
        vertices: m.vertices,
        chars,
    }
}

/// local_size_x = 64 over vertices, one row of groups per character.
pub fn groups(m: &Inner, chars: u32) -> [u32; 3] {
    [m.vertices.div_ceil(64), chars, 1]
}
