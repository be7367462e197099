//! The GPU memory a model and a crowd will take, from their sizes alone: the query an engine
//! makes before creating either, with no device (and no model upload) needed. A model's sizes
//! include the stored columns of its block-sparse C1|C2 ([`ModelSizes::blend_columns`]: 0 for a
//! dense one), which [`ModelSizes::of`] counts as `GpuModel::new` will lay them out. `GpuModel::new`
//! and `Crowd::with_options` size their buffers with the same functions, so the figures are the
//! bytes of the buffers they create (allocator rounding and the transient staging buffer of an
//! upload aside).

use super::crowd::{bytes_per_character, CrowdOptions};
use super::pass::{CrowdBuffer, Dims, ModelBuffer};
use crate::error::{Error, Result};
use crate::model::{Model, PREDICTOR_WORDS};

/// Vulkan forbids zero-sized buffers; empty arrays (P = 0, T = 0) get this many bytes, unread.
pub(crate) const MIN_BUFFER_BYTES: u64 = 16;

/// The sizes of a model that decide its memory (those of `rrskin_model_info` in the C ABI).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ModelSizes {
    pub vertices: usize,
    pub triangles: usize,
    pub bones: usize,
    pub proxies: usize,
    pub influences: usize,
    /// Stored columns of the block-sparse [C1 | C2] (summed over proxies: the columns where
    /// any of a proxy's 4 rows is non-zero), 0 where the model keeps the dense matrix. What
    /// [`ModelSizes::of`] finds (the layout `GpuModel::new` chooses, [`super::GpuModel::is_block_sparse`]).
    pub blend_columns: usize,
    /// Whether the model carries rest tangents (uploaded, and crowds may output tangents).
    pub tangents: bool,
}

impl ModelSizes {
    pub fn of(model: &Model) -> ModelSizes {
        ModelSizes {
            vertices: model.vertex_count(),
            triangles: model.triangle_count(),
            bones: model.bone_count(),
            proxies: model.proxy_count(),
            influences: model.influences(),
            blend_columns: super::gpu_model::BlockSparse::of(model).map_or(0, |b| b.columns.len()),
            tangents: model.has_tangents(),
        }
    }

    pub(crate) fn of_gpu(model: &super::GpuModel) -> ModelSizes {
        let d = &model.inner.dims;
        ModelSizes {
            vertices: d.vertices as usize,
            triangles: model.triangle_count(),
            bones: d.bones as usize,
            proxies: d.proxies as usize,
            influences: d.influences,
            blend_columns: model.inner.blend_columns,
            tangents: model.has_tangents(),
        }
    }

    fn dims(&self, options: &CrowdOptions) -> Result<Dims> {
        let word = |what, n: usize| {
            u32::try_from(n).map_err(|_| Error::DeviceLimit {
                what,
                needed: n as u64,
                limit: u32::MAX as u64,
            })
        };
        Ok(Dims {
            vertices: word("vertices", self.vertices)?,
            proxies: word("proxies", self.proxies)?,
            bones: word("bones", self.bones)?,
            influences: self.influences,
            bounds: options.bounds,
            tangents: options.tangents,
            sparse: self.blend_columns > 0,
            // No crowd buffer's size depends on it (B stays allocated, unused, for a fused
            // model: the sizes do not tell the two apart).
            fused: false,
        })
    }
}

/// The bytes of a GPU model's buffer `b`, before rounding up to [`MIN_BUFFER_BYTES`].
pub(crate) fn model_buffer_bytes(s: &ModelSizes, b: ModelBuffer) -> u64 {
    let (v, t, j, p, k, n) = (
        s.vertices as u64,
        s.triangles as u64,
        s.bones as u64,
        s.proxies as u64,
        s.influences as u64,
        s.blend_columns as u64,
    );
    let sparse = n > 0;
    4 * match b {
        ModelBuffer::Rest => 3 * v,
        ModelBuffer::SkinIndex | ModelBuffer::SkinWeight => k * v,
        ModelBuffer::Parents => j,
        ModelBuffer::Predictors => PREDICTOR_WORDS as u64 * p,
        ModelBuffer::BlendMatrix if sparse => 0,
        ModelBuffer::BlendMatrix => 4 * p * (3 * p + 4 * j),
        ModelBuffer::BlendOffsets if sparse => p + 1,
        ModelBuffer::BlendOffsets => 0,
        ModelBuffer::BlendColumns => n,
        ModelBuffer::BlendValues => 4 * n,
        ModelBuffer::IncidentOffsets => v + 1,
        ModelBuffer::IncidentTriangles | ModelBuffer::Triangles => 3 * t,
        ModelBuffer::RestTangents if s.tangents => 4 * v,
        ModelBuffer::RestTangents => 0,
    }
}

/// Bytes of the device-local buffers of a [`super::GpuModel`] of these sizes.
pub fn model_bytes(s: &ModelSizes) -> u64 {
    ModelBuffer::ALL
        .iter()
        .map(|&b| model_buffer_bytes(s, b).max(MIN_BUFFER_BYTES))
        .sum()
}

/// How many buffers of kind `b` a crowd made with `options` has.
pub(crate) fn crowd_buffer_copies(b: CrowdBuffer, options: &CrowdOptions) -> usize {
    match b {
        CrowdBuffer::Bones => options.frames_in_flight,
        CrowdBuffer::Positions => 1 + usize::from(options.previous_positions),
        CrowdBuffer::Bounds if options.bounds => options.frames_in_flight,
        CrowdBuffer::Bounds => 0,
        CrowdBuffer::Tangents => usize::from(options.tangents),
        CrowdBuffer::Rhs | CrowdBuffer::Proxies | CrowdBuffer::Normals => 1,
    }
}

/// Bytes per character of the largest single buffer of a [`super::Crowd`] made with `options`:
/// what a device's largest allocation bounds.
pub fn crowd_largest_buffer_bytes(s: &ModelSizes, options: &CrowdOptions) -> Result<u64> {
    let dims = s.dims(options)?;
    Ok(CrowdBuffer::ALL
        .iter()
        .filter(|&&b| crowd_buffer_copies(b, options) > 0)
        .map(|&b| bytes_per_character(&dims, b))
        .max()
        .unwrap_or(0))
}

/// Bytes of the buffers of a [`super::Crowd`] of `characters` characters of a model of these
/// sizes made with `options` (the GPU model's own not included). `DeviceLimit` when the figure
/// does not fit 64 bits or a size the runtime addresses in 32.
pub fn crowd_bytes(s: &ModelSizes, characters: usize, options: &CrowdOptions) -> Result<u64> {
    let dims = s.dims(options)?;
    let too_large = || Error::DeviceLimit {
        what: "crowd bytes (64-bit)",
        needed: u64::MAX,
        limit: u64::MAX,
    };
    CrowdBuffer::ALL.iter().try_fold(0u64, |sum, &b| {
        let one = (bytes_per_character(&dims, b))
            .checked_mul(characters as u64)
            .ok_or_else(too_large)?
            .max(MIN_BUFFER_BYTES);
        let all = one
            .checked_mul(crowd_buffer_copies(b, options) as u64)
            .ok_or_else(too_large)?;
        sum.checked_add(all).ok_or_else(too_large)
    })
}
