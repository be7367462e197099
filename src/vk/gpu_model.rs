//! A model uploaded once into device-local, read-only storage buffers, shared by every crowd
//! of that model.

use super::buffer::{upload, Buffer};
use super::context::Context;
use super::pass::{Dims, ModelBuffer};
use super::passes::Pass;
use crate::error::Result;
use crate::model::{predictor_words, Model};
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
    pub triangle_count: u32,
    /// V x 3 f32
    pub rest: Buffer,
    /// V x K u32
    pub skin_index: Buffer,
    /// V x K f32
    pub skin_weight: Buffer,
    /// J i32
    pub parents: Buffer,
    /// P x 85 words (the PRED record layout)
    pub predictors: Buffer,
    /// [C1 | C2]: 4P x (3P + 4J) f32, row-major (empty where the model is block-sparse)
    pub blend_matrix: Buffer,
    /// The block-sparse [C1 | C2] ([`BlockSparse`]; empty where the model is dense)
    pub blend_offsets: Buffer,
    pub blend_column_indices: Buffer,
    pub blend_values: Buffer,
    /// Stored columns of the block-sparse layout, 0 where dense.
    pub blend_columns: usize,
    /// V + 1 u32 (CSR offsets)
    pub incident_offsets: Buffer,
    /// 3T u32 (triangle ids)
    pub incident_triangles: Buffer,
    /// T x 3 u32
    pub triangles: Buffer,
    /// V x 4 f32 rest tangents (empty for a model without them)
    pub rest_tangents: Buffer,
    pub has_tangents: bool,
}

impl GpuModel {
    /// Uploads `model` (submits a copy on the context's queue and waits).
    pub fn new(context: &Context, model: &Model) -> Result<GpuModel> {
        let parts = model.parts();
        let predictors: Vec<u32> = parts.predictors.iter().flat_map(predictor_words).collect();
        let sparse = BlockSparse::of(model);
        let dense = match sparse {
            Some(_) => Vec::new(),
            None => model.c1_c2(),
        };
        let empty = BlockSparse::default();
        let blocks = sparse.as_ref().unwrap_or(&empty);
        let (offsets, incident) = model.incidence();
        let bytes = bytemuck::cast_slice::<f32, u8>;
        let items: [(&'static str, &[u8]); 13] = [
            ("rest positions", bytes(parts.rest_positions.as_flattened())),
            ("skin indices", bytemuck::cast_slice(&parts.skin_indices)),
            ("skin weights", bytes(&parts.skin_weights)),
            ("bone parents", bytemuck::cast_slice(&parts.bone_parents)),
            ("predictors", bytemuck::cast_slice(&predictors)),
            ("C1|C2", bytes(&dense)),
            ("C1|C2 offsets", bytemuck::cast_slice(&blocks.offsets)),
            ("C1|C2 columns", bytemuck::cast_slice(&blocks.columns)),
            ("C1|C2 values", bytes(blocks.values.as_flattened())),
            ("incident offsets", bytemuck::cast_slice(offsets)),
            ("incident triangles", bytemuck::cast_slice(incident)),
            (
                "triangles",
                bytemuck::cast_slice(parts.triangles.as_flattened()),
            ),
            ("rest tangents", bytes(parts.rest_tangents.as_flattened())),
        ];
        let limit = context.limits().max_storage_buffer_range;
        for (what, data) in &items {
            if data.len() as u64 > limit {
                return Err(crate::Error::DeviceLimit {
                    what,
                    needed: data.len() as u64,
                    limit,
                });
            }
        }
        let dims = Dims {
            vertices: model.vertex_count() as u32,
            proxies: model.proxy_count() as u32,
            bones: model.bone_count() as u32,
            influences: model.influences(),
            bounds: false,
            tangents: false,
            sparse: sparse.is_some(),
            fused: sparse.as_ref().is_some_and(BlockSparse::one_key_per_proxy),
        };
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
        let [rest, skin_index, skin_weight, parents, predictors, blend_matrix, blend_offsets, blend_column_indices, blend_values, incident_offsets, incident_triangles, triangles, rest_tangents] =
            <[Buffer; 13]>::try_from(buffers).map_err(|_| crate::Error::Mismatch {
                what: "uploaded buffer count",
            })?;
        Ok(GpuModel {
            inner: Arc::new(Inner {
                context: context.clone(),
                dims,
                triangle_count: model.triangle_count() as u32,
                rest,
                skin_index,
                skin_weight,
                parents,
                predictors,
                blend_matrix,
                blend_offsets,
                blend_column_indices,
                blend_values,
                blend_columns: blocks.columns.len(),
                incident_offsets,
                incident_triangles,
                triangles,
                rest_tangents,
                has_tangents: model.has_tangents(),
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
        self.inner.has_tangents
    }

    /// Whether [C1 | C2] was stored block-sparse (the sparse product runs) rather than dense
    /// (the tiled GEMM runs): see [`BlockSparse::of`].
    pub fn is_block_sparse(&self) -> bool {
        self.inner.dims.sparse
    }

    /// Whether the product evaluates the key predictors itself (block-sparse, and every proxy
    /// reads at most one key's columns: [`BlockSparse::one_key_per_proxy`]), so that the
    /// predictor pass does not run.
    pub fn fuses_predictors(&self) -> bool {
        self.inner.dims.fused
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
        match b {
            ModelBuffer::Rest => &self.rest,
            ModelBuffer::SkinIndex => &self.skin_index,
            ModelBuffer::SkinWeight => &self.skin_weight,
            ModelBuffer::Parents => &self.parents,
            ModelBuffer::Predictors => &self.predictors,
            ModelBuffer::BlendMatrix => &self.blend_matrix,
            ModelBuffer::BlendOffsets => &self.blend_offsets,
            ModelBuffer::BlendColumns => &self.blend_column_indices,
            ModelBuffer::BlendValues => &self.blend_values,
            ModelBuffer::IncidentOffsets => &self.incident_offsets,
            ModelBuffer::IncidentTriangles => &self.incident_triangles,
            ModelBuffer::Triangles => &self.triangles,
            ModelBuffer::RestTangents => &self.rest_tangents,
        }
    }
}

impl GpuModel {
    pub fn triangle_count(&self) -> usize {
        self.inner.triangle_count as usize
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
        self.inner.triangles.handle
    }
}

/// [C1 | C2] stored per proxy: proxy e's 4 rows (4e .. 4e + 3) keep only the columns where
/// one of them is non-zero, each as its column index and the vec4 of the 4 rows' values. A
/// joint-blend proxy touches its own key's 3 columns and its 2-3 bones' 4 each (~11 of
/// 3P + 4J); the paper's reduction and synthetic models are dense.
#[derive(Debug, Default, PartialEq)]
pub(crate) struct BlockSparse {
    /// P + 1: proxy e's columns are `columns[offsets[e]..offsets[e + 1]]`.
    pub offsets: Vec<u32>,
    pub columns: Vec<u32>,
    pub values: Vec<[f32; 4]>,
}

/// The block-sparse layout is chosen when the stored columns are fewer than this fraction of
/// the P (3P + 4J) of the dense matrix (then it is also the smaller: 20 bytes a stored column
/// against 16 a dense one).
pub(crate) const MAX_SPARSE_DENSITY: f64 = 0.25;

impl BlockSparse {
    /// The layout of `model`'s [C1 | C2], or `None` where it should stay dense (no proxies,
    /// density at or above [`MAX_SPARSE_DENSITY`], or an all-zero matrix).
    pub fn of(model: &Model) -> Option<BlockSparse> {
        let (p, j) = (model.proxy_count(), model.bone_count());
        let width = 3 * p + 4 * j;
        let a = model.c1_c2();
        let mut blocks = BlockSparse {
            offsets: Vec::with_capacity(p + 1),
            ..BlockSparse::default()
        };
        blocks.offsets.push(0);
        for e in 0..p {
            for k in 0..width {
                let column = [0, 1, 2, 3].map(|i| a[(4 * e + i) * width + k]);
                if column.iter().any(|&x| x != 0.0) {
                    blocks.columns.push(k as u32);
                    blocks.values.push(column);
                }
            }
            blocks.offsets.push(blocks.columns.len() as u32);
        }
        let stored = blocks.columns.len() as f64;
        (stored > 0.0 && stored < MAX_SPARSE_DENSITY * (p * width) as f64).then_some(blocks)
    }

    /// Whether each proxy's stored columns below 3P (its key columns) are those of one key:
    /// then its invocation of the fused product evaluates that key's D_ℓ(q) and nothing else
    /// (glsl/fused_product.comp). True of joint-blend proxies (key e, its parent bone).
    pub fn one_key_per_proxy(&self) -> bool {
        let keys = 3 * (self.offsets.len().saturating_sub(1)) as u32;
        self.offsets.windows(2).all(|w| {
            let stored = self.columns.get(w[0] as usize..w[1] as usize);
            let mut key_columns = (stored.unwrap_or_default().iter())
                .filter(|&&k| k < keys)
                .map(|k| k / 3);
            key_columns
                .next()
                .is_none_or(|first| key_columns.all(|k| k == first))
        })
    }
}
