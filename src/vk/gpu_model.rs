//! A model uploaded once into device-local, read-only storage buffers, shared by every crowd
//! of that model.

use super::buffer::{upload, Buffer};
use super::context::Context;
use super::memory::{model_buffer_bytes, ModelSizes};
use super::pass::{Dims, ModelBuffer};
use super::passes::Pass;
use crate::error::Result;
use crate::model::{key_words, BlockSparse, FeatureRange, Model};
use crate::normals::{Fans, NormalMode, FAN_PIVOT};
use ash::vk;
use std::sync::Arc;

/// Cheap to clone; the buffers are freed when the last clone and the last crowd using it drop.
#[derive(Clone)]
pub struct GpuModel {
    pub(crate) inner: Arc<Inner>,
}

pub(crate) struct Inner {
    pub context: Context,
    pub dims: Dims,
    /// What `memory.rs` sized the buffers by.
    pub sizes: ModelSizes,
    /// The model's up where its proxy correctives see gravity ([`Model::up`]).
    pub up: Option<[f32; 3]>,
    /// Indexed by [`ModelBuffer`].
    buffers: [Buffer; ModelBuffer::COUNT],
}

/// What `GpuModel::new` uploads, borrowed from or computed from the model once.
struct UploadData<'m> {
    model: &'m Model,
    /// The P keys' records ([`key_words`]).
    keys: Vec<u32>,
    /// [C1 | C2] row-major where the model stays dense, else empty.
    dense: Vec<f32>,
    /// The rest positions, the corrective targets, then the rest normals: (2 + N) x V x 3.
    rest: Vec<f32>,
    /// The 1-ring fans of the normals pass.
    fans: Fans,
    /// The proxy correctives' corrected proxies, driver offsets and drivers, one after the
    /// other, then each proxy's index among the corrected (`u32::MAX` where uncorrected).
    proxy_topology: Vec<u32>,
    /// The proxy correctives' kernel centres (C x J x 9), their widths (J), the model's up, the
    /// feature ranges ([`proxy_kernels`]).
    proxy_kernels: Vec<f32>,
    blocks: BlockSparse,
}

impl UploadData<'_> {
    /// The debug name and the bytes of buffer `b`.
    fn of(&self, b: ModelBuffer) -> (&'static str, &[u8]) {
        let parts = self.model.parts();
        let floats = bytemuck::cast_slice::<f32, u8>;
        match b {
            ModelBuffer::Rest => (
                "rest positions, corrective targets and rest normals",
                floats(&self.rest),
            ),
            ModelBuffer::SkinIndex => ("skin indices", bytemuck::cast_slice(&parts.skin_indices)),
            ModelBuffer::SkinWeight => ("skin weights", floats(&parts.skin_weights)),
            ModelBuffer::Parents => ("bone parents", bytemuck::cast_slice(&parts.bone_parents)),
            ModelBuffer::Keys => ("keys", bytemuck::cast_slice(&self.keys)),
            ModelBuffer::ProductMatrix => ("C1|C2", floats(&self.dense)),
            ModelBuffer::ProductOffsets => {
                ("C1|C2 offsets", bytemuck::cast_slice(&self.blocks.offsets))
            }
            ModelBuffer::ProductColumns => {
                ("C1|C2 columns", bytemuck::cast_slice(&self.blocks.columns))
            }
            ModelBuffer::ProductValues => {
                ("C1|C2 values", floats(self.blocks.values.as_flattened()))
            }
            ModelBuffer::FanOffsets => (
                "normal fan offsets",
                bytemuck::cast_slice(&self.fans.offsets),
            ),
            ModelBuffer::Fans => ("normal fans", bytemuck::cast_slice(&self.fans.entries)),
            ModelBuffer::Triangles => (
                "triangles",
                bytemuck::cast_slice(parts.triangles.as_flattened()),
            ),
            ModelBuffer::RestTangents => {
                ("rest tangents", floats(parts.rest_tangents.as_flattened()))
            }
            ModelBuffer::CorrectiveDrivers => (
                "corrective drivers",
                bytemuck::cast_slice(self.model.correctives().map_or(&[][..], |c| &c.drivers)),
            ),
            ModelBuffer::CorrectiveMap => (
                "corrective map",
                floats(self.model.correctives().map_or(&[][..], |c| &c.map)),
            ),
            ModelBuffer::ProxyTopology => (
                "proxy corrective proxies and drivers",
                bytemuck::cast_slice(&self.proxy_topology),
            ),
            ModelBuffer::ProxyKernels => ("proxy corrective kernels", floats(&self.proxy_kernels)),
            ModelBuffer::ProxyMaps => (
                "proxy corrective maps",
                floats(self.model.proxy_correctives().map_or(&[][..], |c| &c.maps)),
            ),
        }
    }
}

/// Choices the upload makes by itself, forced for testing the runtime (as
/// [`super::CrowdDebugSettings`]); not for engines (default: none).
#[derive(Debug, Clone, Copy, Default)]
pub struct GpuModelDebugSettings {
    /// Whether a fused product applies the proxy correctives itself (`None`: where the device
    /// is a GPU, not on a CPU implementation; see `Dims::correctives_in_product`).
    pub correctives_in_product: Option<bool>,
}

impl GpuModel {
    /// Uploads `model` (submits a copy on the context's queue and waits).
    pub fn new(context: &Context, model: &Model) -> Result<GpuModel> {
        Self::with_debug_settings(context, model, GpuModelDebugSettings::default())
    }

    /// [`GpuModel::new`] with the upload's own choices forced.
    pub fn with_debug_settings(
        context: &Context,
        model: &Model,
        settings: GpuModelDebugSettings,
    ) -> Result<GpuModel> {
        let sparse = BlockSparse::layout_of(model);
        let in_product = (settings.correctives_in_product).unwrap_or(!context.limits().cpu_device);
        let dims = model_dims(model, sparse.as_ref(), in_product);
        if model.vertex_count() as u64 >= u64::from(FAN_PIVOT) {
            return Err(crate::Error::DeviceLimit {
                what: "vertices (the normal fans flag a pivot in bit 31)",
                needed: model.vertex_count() as u64,
                limit: u64::from(FAN_PIVOT) - 1,
            });
        }
        let parts = model.parts();
        let targets = parts.correctives.as_ref().map_or(&[][..], |c| &c.targets);
        let rest_normals = model.rest_normals();
        let rest = (parts
            .rest_positions
            .iter()
            .chain(targets)
            .chain(&rest_normals))
        .flatten()
        .copied()
        .collect();
        let data = UploadData {
            model,
            keys: key_words(model.keys()),
            dense: match sparse {
                Some(_) => Vec::new(),
                None => model.c1_c2(),
            },
            rest,
            fans: model.normal_fans(),
            proxy_topology: proxy_topology(model),
            proxy_kernels: proxy_kernels(model),
            blocks: sparse.unwrap_or_default(),
        };
        let sizes =
            ModelSizes::with_layout(model, data.blocks.columns.len(), data.fans.entries.len());
        let items = ModelBuffer::ALL.map(|b| data.of(b));
        let limit = context.limits().max_storage_buffer_range;
        for (b, (what, bytes)) in ModelBuffer::ALL.into_iter().zip(&items) {
            // The sizes the memory query gives are the sizes uploaded.
            if bytes.len() as u64 != model_buffer_bytes(&sizes, b) {
                return Err(crate::Error::Mismatch {
                    what: "a model buffer's bytes and memory.rs's size of it",
                });
            }
            if bytes.len() as u64 > limit {
                return Err(crate::Error::DeviceLimit {
                    what,
                    needed: bytes.len() as u64,
                    limit,
                });
            }
        }
        // The dispatch sizes that do not depend on the crowd (over vertices, predictors, rows).
        for pass in Pass::of_model(&dims) {
            pass.desc()
                .check_model_groups(&dims, context.limits().max_workgroup_count)?;
        }
        let buffers = upload(
            &context.shared,
            &items,
            // The triangles double as an index buffer ([`GpuModel::triangle_buffer`]).
            vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::INDEX_BUFFER,
        )?;
        Ok(GpuModel {
            inner: Arc::new(Inner {
                context: context.clone(),
                dims,
                sizes,
                up: model.up(),
                buffers,
            }),
        })
    }

    pub fn vertex_count(&self) -> usize {
        self.inner.dims.vertices as usize
    }

    pub fn bone_count(&self) -> usize {
        self.inner.dims.bones as usize
    }

    pub fn proxy_count(&self) -> usize {
        self.inner.dims.proxies as usize
    }

    /// Whether the model carries rest tangents (crowds of it may output tangent frames).
    pub fn has_tangents(&self) -> bool {
        self.inner.sizes.tangents
    }

    /// Whether [C1 | C2] was stored block-sparse (the sparse product runs) rather than dense
    /// (the tiled GEMM runs): see `BlockSparse::layout_of`.
    pub fn is_block_sparse(&self) -> bool {
        self.inner.dims.sparse
    }

    /// Whether the product evaluates the key predictors itself (block-sparse, and every proxy
    /// reads at most one key's columns: `BlockSparse::one_key_per_proxy`), so that the
    /// predictor pass does not run.
    pub fn fuses_predictors(&self) -> bool {
        self.inner.dims.fused
    }

    /// Whether the fused product applies the proxy correctives itself, so that their pass does
    /// not run (models whose product is fused and that have them; see
    /// [`GpuModelDebugSettings`]).
    pub fn applies_correctives_in_product(&self) -> bool {
        super::passes::fused_corrects(&self.inner.dims)
    }

    /// The model's up where its proxy correctives see gravity ([`Model::up`]): what a crowd's
    /// characters' up vectors start as ([`super::Crowd::set_ups`]). None: they are not read.
    pub fn up(&self) -> Option<[f32; 3]> {
        self.inner.up
    }

    /// N, the model's pose-space corrective targets (0 without correctives).
    pub fn corrective_count(&self) -> usize {
        self.inner.dims.correctives as usize
    }

    /// E, the proxies the model's proxy correctives correct (0 without them).
    pub fn proxy_corrective_count(&self) -> usize {
        self.inner.dims.corrected_proxies as usize
    }

    /// Bytes of the model's buffers: what [`super::model_bytes`] said before the upload.
    pub fn memory_bytes(&self) -> u64 {
        ModelBuffer::ALL
            .iter()
            .map(|&b| self.inner.buffer(b).size)
            .sum()
    }
}

impl Inner {
    pub fn buffer(&self, b: ModelBuffer) -> &Buffer {
        &self.buffers[b as usize]
    }
}

impl GpuModel {
    pub fn triangle_count(&self) -> usize {
        self.inner.sizes.triangles
    }

    /// The context the model was uploaded to.
    pub fn context(&self) -> &Context {
        &self.inner.context
    }

    /// The model's triangles as an index buffer: `triangle_count() * 3` `u32` corner indices
    /// (usage `INDEX_BUFFER`), to draw a crowd's outputs with (one character's vertices start at
    /// [`super::CrowdOutput`]'s `offset + c * character_stride`). Read-only, alive as long as
    /// the model.
    pub fn triangle_buffer(&self) -> vk::Buffer {
        self.inner.buffer(ModelBuffer::Triangles).handle
    }
}

/// The sizes and choices a model's passes run with (a crowd adds its options'): `sparse` the
/// block-sparse [C1 | C2] where chosen, `in_product` whether a fused product applies the proxy
/// correctives.
fn model_dims(model: &Model, sparse: Option<&BlockSparse>, in_product: bool) -> Dims {
    Dims {
        vertices: model.vertex_count() as u32,
        proxies: model.proxy_count() as u32,
        bones: model.bone_count() as u32,
        influences: model.influences(),
        bounds: false,
        tangents: false,
        normals: NormalMode::Recomputed,
        sparse: sparse.is_some(),
        fused: sparse.is_some_and(BlockSparse::one_key_per_proxy),
        correctives_in_product: in_product,
        correctives: model.corrective_count() as u32,
        drivers: model.corrective_driver_count() as u32,
        corrected_proxies: model.proxy_corrective_count() as u32,
        kernels: (model.proxy_correctives())
            .map_or(0, |c| c.kernel_count(model.bone_count()) as u32),
        linear_features: model.proxy_correctives().is_some_and(|c| c.linear),
        gravity: model.up().is_some(),
    }
}

/// [`UploadData::proxy_kernels`] (empty without proxy correctives): the kernel centres, the
/// widths, the model's up, then per joint 12 lower and 12 upper feature bounds, which are
/// ±`f32::MAX` for a model without ranges so that the shaders clamp every model alike.
fn proxy_kernels(model: &Model) -> Vec<f32> {
    let Some(c) = model.proxy_correctives() else {
        return Vec::new();
    };
    let unbounded = FeatureRange {
        lower: [-f32::MAX; 12],
        upper: [f32::MAX; 12],
    };
    let ranges = (0..model.bone_count()).map(|b| c.ranges.get(b).unwrap_or(&unbounded));
    let data = c.centres.as_flattened().iter().chain(&c.widths);
    (data.chain(c.up.iter().flatten()).copied())
        .chain(ranges.flat_map(|r| r.lower.into_iter().chain(r.upper)))
        .collect()
}

/// [`UploadData::proxy_topology`] (empty without proxy correctives).
fn proxy_topology(model: &Model) -> Vec<u32> {
    let Some(c) = model.proxy_correctives() else {
        return Vec::new();
    };
    let mut index = vec![u32::MAX; model.proxy_count()];
    for (i, &e) in c.proxies.iter().enumerate() {
        index[e as usize] = i as u32;
    }
    [&c.proxies, &c.driver_offsets, &c.drivers, &index]
        .into_iter()
        .flatten()
        .copied()
        .collect()
}
