//! The GPU memory a model and a crowd will take, from their sizes alone: the query an engine
//! makes before creating either, with no device (and no model upload) needed. A model's sizes
//! include the stored columns of its block-sparse C1|C2 ([`ModelSizes::product_columns`]: 0 for
//! a dense one), which [`ModelSizes::of`] counts as `GpuModel::new` will lay them out.
//! `GpuModel::new` and `Crowd::with_options` size their buffers with the same functions (the
//! model's upload fails if its data and [`model_buffer_bytes`] disagree), so the figures are the
//! bytes of the buffers they create (allocator rounding and the transient staging buffer of an
//! upload aside).

use super::crowd::{CrowdOptions, BOUNDS_STRIDE, TANGENT_STRIDE};
use super::pass::{CrowdBuffer, Dims, ModelBuffer};
use crate::error::{Error, Result};
use crate::model::Model;

/// Vulkan forbids zero-sized buffers; empty arrays (P = 0, T = 0) get this many bytes, unread.
pub(crate) const MIN_BUFFER_BYTES: u64 = 16;
/// One 3x4 f32 transform (a bone's or a palette entry).
pub(crate) const AFFINE_BYTES: u64 = 48;
/// One f32 xyz (a position, a normal, a column of B).
pub(crate) const XYZ_BYTES: u64 = 12;

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
    pub product_columns: usize,
    /// Entries of the 1-ring fans the normals pass reads ([`Model::normal_fans`]): about
    /// 3T + 2V for a closed manifold mesh, what [`ModelSizes::of`] counts.
    pub normal_fans: usize,
    /// Whether the model carries rest tangents (uploaded, and crowds may output tangents).
    pub tangents: bool,
    /// N, the pose-space corrective targets (0 without correctives).
    pub correctives: usize,
    /// D, the corrective driver bones (0 without correctives).
    pub corrective_drivers: usize,
    /// E, the proxies corrected by proxy correctives (0 without them).
    pub proxy_correctives: usize,
    /// Σ D_i, the drivers of all corrected proxies together (0 without proxy correctives).
    pub proxy_corrective_drivers: usize,
    /// C, the proxy correctives' kernel centres per joint (0 without kernels).
    pub proxy_corrective_kernels: usize,
    /// Whether the proxy correctives have the 9 linear features per driver.
    pub proxy_corrective_linear: bool,
    /// Whether they have the 3 gravity features per driver ([`Model::up`]; crowds then keep
    /// each character's up vector).
    pub proxy_corrective_gravity: bool,
    /// The words of the keys' records, all keys together ([`crate::model::key_words`]).
    pub key_words: usize,
}

impl ModelSizes {
    pub fn of(model: &Model) -> ModelSizes {
        let columns = crate::model::BlockSparse::layout_of(model).map_or(0, |b| b.columns.len());
        ModelSizes::with_layout(model, columns, model.normal_fans().entries.len())
    }

    /// The sizes of `model` once its block-sparse C1|C2 (if any) stores `columns` columns and
    /// its normal fans `fans` entries.
    pub(crate) fn with_layout(model: &Model, columns: usize, fans: usize) -> ModelSizes {
        ModelSizes {
            normal_fans: fans,
            vertices: model.vertex_count(),
            triangles: model.triangle_count(),
            bones: model.bone_count(),
            proxies: model.proxy_count(),
            influences: model.influences(),
            product_columns: columns,
            tangents: model.has_tangents(),
            correctives: model.corrective_count(),
            corrective_drivers: model.corrective_driver_count(),
            proxy_correctives: model.proxy_corrective_count(),
            proxy_corrective_drivers: model.proxy_correctives().map_or(0, |c| c.drivers.len()),
            proxy_corrective_kernels: (model.proxy_correctives())
                .map_or(0, |c| c.kernel_count(model.bone_count())),
            proxy_corrective_linear: model.proxy_correctives().is_some_and(|c| c.linear),
            proxy_corrective_gravity: model.up().is_some(),
            key_words: crate::model::key_words(model.keys()).len(),
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
            normals: options.normals,
            sparse: self.product_columns > 0,
            // No crowd buffer's size depends on it (B stays allocated, unused, for a fused
            // model: the sizes do not tell the two apart).
            fused: false,
            correctives_in_product: false,
            correctives: word("corrective targets", self.correctives)?,
            drivers: word("corrective drivers", self.corrective_drivers)?,
            corrected_proxies: word("corrected proxies", self.proxy_correctives)?,
            kernels: word("proxy corrective kernels", self.proxy_corrective_kernels)?,
            linear_features: self.proxy_corrective_linear,
            gravity: self.proxy_corrective_gravity,
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
        s.product_columns as u64,
    );
    let (corr, drivers) = (s.correctives as u64, s.corrective_drivers as u64);
    let (corrected, proxy_drivers, kernels) = (
        s.proxy_correctives as u64,
        s.proxy_corrective_drivers as u64,
        s.proxy_corrective_kernels as u64,
    );
    let gravity = 3 * u64::from(s.proxy_corrective_gravity);
    let features = 9 * u64::from(s.proxy_corrective_linear) + gravity + kernels;
    let sparse = n > 0;
    4 * match b {
        // The rest positions, the N corrective targets, then the rest normals.
        ModelBuffer::Rest => 3 * v * (2 + corr),
        ModelBuffer::SkinIndex | ModelBuffer::SkinWeight => k * v,
        ModelBuffer::Parents => j,
        ModelBuffer::Keys => s.key_words as u64,
        ModelBuffer::ProductMatrix if sparse => 0,
        ModelBuffer::ProductMatrix => 4 * p * (3 * p + 4 * j),
        ModelBuffer::ProductOffsets if sparse => p + 1,
        ModelBuffer::ProductOffsets => 0,
        ModelBuffer::ProductColumns => n,
        ModelBuffer::ProductValues => 4 * n,
        ModelBuffer::FanOffsets => v + 1,
        ModelBuffer::Fans => s.normal_fans as u64,
        ModelBuffer::Triangles => 3 * t,
        ModelBuffer::RestTangents if s.tangents => 4 * v,
        ModelBuffer::RestTangents => 0,
        ModelBuffer::CorrectiveDrivers => drivers,
        ModelBuffer::CorrectiveMap => corr * 9 * drivers,
        // The corrected proxies, their driver offsets, the drivers.
        // The corrected proxies, their driver offsets, the drivers, then each proxy's index
        // among the corrected (~0 where uncorrected: the fused product's lookup).
        ModelBuffer::ProxyTopology if corrected > 0 => 2 * corrected + 1 + proxy_drivers + p,
        ModelBuffer::ProxyTopology => 0,
        // The centres, then the widths (only with kernels), then the model's up (only with
        // gravity), then the J feature ranges (24 floats each).
        ModelBuffer::ProxyKernels if corrected > 0 => {
            kernels * j * 9 + if kernels > 0 { j } else { 0 } + gravity + 24 * j
        }
        ModelBuffer::ProxyKernels => 0,
        ModelBuffer::ProxyMaps => 12 * proxy_drivers * features,
    }
}

/// Bytes of the device-local buffers of a [`super::GpuModel`] of these sizes.
pub fn model_bytes(s: &ModelSizes) -> u64 {
    ModelBuffer::ALL
        .iter()
        .map(|&b| model_buffer_bytes(s, b).max(MIN_BUFFER_BYTES))
        .sum()
}

/// Bytes of one character in each crowd buffer; 0 where the model does not use it.
pub(crate) fn bytes_per_character(d: &Dims, b: CrowdBuffer) -> u64 {
    let (v, p, j) = (d.vertices as u64, d.proxies as u64, d.bones as u64);
    match b {
        CrowdBuffer::Bones => j * AFFINE_BYTES,
        // B = [d; q]: (3P + 4J) x 3 floats per character, only when P > 0.
        CrowdBuffer::Rhs if p > 0 => (3 * p + 4 * j) * XYZ_BYTES,
        CrowdBuffer::Rhs => 0,
        // The skinning palette [t (P); q (J)], only when P > 0.
        CrowdBuffer::Palette if p > 0 => (p + j) * AFFINE_BYTES,
        CrowdBuffer::Palette => 0,
        CrowdBuffer::Positions | CrowdBuffer::Normals => v * XYZ_BYTES,
        CrowdBuffer::Bounds if d.bounds => BOUNDS_STRIDE,
        CrowdBuffer::Bounds => 0,
        CrowdBuffer::Tangents if d.tangents => v * TANGENT_STRIDE,
        CrowdBuffer::Tangents => 0,
        // w, N floats per character rounded up to whole vec4s (so that chunk offsets align as
        // easily as the other buffers'), only with correctives.
        CrowdBuffer::CorrectiveWeights => 16 * (d.correctives as u64).div_ceil(4),
        // An up vector (xyz, w unused), only where the proxy correctives see gravity.
        CrowdBuffer::Ups if d.gravity => 16,
        CrowdBuffer::Ups => 0,
    }
}

/// How many buffers of kind `b` a crowd of a model of sizes `d` made with `options` has.
pub(crate) fn crowd_buffer_copies(b: CrowdBuffer, d: &Dims, options: &CrowdOptions) -> usize {
    match b {
        CrowdBuffer::Bones => options.frames_in_flight,
        // Only where a pass reads them: the proxy correctives that see gravity.
        CrowdBuffer::Ups if d.gravity => options.frames_in_flight,
        CrowdBuffer::Ups => 0,
        CrowdBuffer::Positions => 1 + usize::from(options.previous_positions),
        CrowdBuffer::Bounds if options.bounds => options.frames_in_flight,
        CrowdBuffer::Bounds => 0,
        CrowdBuffer::Tangents => usize::from(options.tangents),
        CrowdBuffer::Rhs
        | CrowdBuffer::Palette
        | CrowdBuffer::Normals
        | CrowdBuffer::CorrectiveWeights => 1,
    }
}

/// Bytes per character of the largest single buffer of a [`super::Crowd`] made with `options`:
/// what a device's largest allocation bounds.
pub fn crowd_largest_buffer_bytes(s: &ModelSizes, options: &CrowdOptions) -> Result<u64> {
    let dims = s.dims(options)?;
    Ok(crowd_buffers(&dims, options)
        .map(|b| bytes_per_character(&dims, b))
        .max()
        .unwrap_or(0))
}

/// The kinds of buffer a crowd of a model of sizes `d` made with `options` has (one or more
/// copies each).
pub(crate) fn crowd_buffers<'a>(
    d: &'a Dims,
    options: &'a CrowdOptions,
) -> impl Iterator<Item = CrowdBuffer> + 'a {
    (CrowdBuffer::ALL.into_iter()).filter(move |&b| crowd_buffer_copies(b, d, options) > 0)
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
            .checked_mul(crowd_buffer_copies(b, &dims, options) as u64)
            .ok_or_else(too_large)?;
        sum.checked_add(all).ok_or_else(too_large)
    })
}
