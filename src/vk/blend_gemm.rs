//! Pass 2, `glsl/blend_gemm.comp`: proxy transforms `T = [C1 | C2] · [d; q]` for all characters
//! of a chunk as one tiled matrix product (M = 4P rows, N = 3 x chars columns).

use super::crowd::ChunkViews;
use super::gpu_model::Inner;
use ash::vk::DescriptorBufferInfo;

/// Bindings in shader order.
pub const BINDINGS: [&str; 3] = ["C1|C2", "rhs", "proxies"];

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
pub struct Push {
    pub proxies: u32,
    pub bones: u32,
    pub chars: u32,
}

/// Output tile of one workgroup: 16 rows (4 proxies) x 128 columns (see the shader).
const TILE_ROWS: u32 = 16;
const TILE_COLUMNS: u32 = 256;

pub fn bindings(m: &Inner, v: &ChunkViews) -> [DescriptorBufferInfo; 3] {
    [m.blend_matrix.whole(), v.rhs, v.proxies]
}

pub fn push(m: &Inner, chars: u32) -> Push {
    Push {
        proxies: m.proxies,
        bones: m.bones,
        chars,
    }
}

pub fn groups(m: &Inner, chars: u32) -> [u32; 3] {
    [
        (3 * chars).div_ceil(TILE_COLUMNS),
        (4 * m.proxies).div_ceil(TILE_ROWS),
        1,
    ]
}
