//! C characters of one GPU model: per-frame bone input, the right-hand side B = [d; q] and proxy
//! transforms, and the output positions and normals the engine draws from.
//!
//! Each per-character array is ONE buffer (so the engine binds one vertex buffer and offsets by
//! character), but a storage descriptor may only cover `maxStorageBufferRange` bytes (128 MiB on
//! lavapipe). The crowd is therefore split into chunks of characters; every chunk has its own
//! descriptor sets whose ranges start at chunk offsets aligned to
//! `minStorageBufferOffsetAlignment`, and the passes dispatch once per chunk.

use super::barrier::{global_barrier, Access};
use super::buffer::{transfer_to_host_barrier, Buffer};
use super::context::Shared;
use super::gpu_model::{GpuModel, Inner};
use super::pass::{Binding, CrowdBuffer, Dims};
use super::passes::Pass;
use super::pipelines::PassPipeline;
use crate::cpu::check_finite;
use crate::error::{Error, Result};
use crate::predict::Affine;
use ash::vk;
use gpu_allocator::MemoryLocation;
use std::sync::Arc;

const AFFINE_BYTES: u64 = 48;
const XYZ_BYTES: u64 = 12;

#[derive(Debug, Clone, Copy, Default)]
pub struct CrowdOptions {
    /// Largest descriptor range to use, below the device's maxStorageBufferRange: forces smaller
    /// chunks (tests use it to exercise chunking without gigabytes of output).
    pub max_binding_bytes: Option<u64>,
}

/// Where the engine finds the outputs: character `c`, vertex `a` is at
/// `offset + c * character_stride + a * vertex_stride` in each buffer (3 x f32: x, y, z).
#[derive(Debug, Clone, Copy)]
pub struct CrowdOutput {
    pub positions: vk::Buffer,
    pub normals: vk::Buffer,
    pub offset: u64,
    pub vertex_stride: u64,
    pub character_stride: u64,
}

/// Outputs copied to the host: C x V each, character-major.
#[derive(Debug, Clone, PartialEq)]
pub struct HostOutput {
    pub positions: Vec<[f32; 3]>,
    pub normals: Vec<[f32; 3]>,
}

/// The descriptor ranges of one chunk in the crowd's per-character buffers.
type ChunkViews = [vk::DescriptorBufferInfo; CrowdBuffer::COUNT];

pub(crate) struct Chunk {
    pub characters: u32,
    /// Indexed by [`Pass`]; null for the passes the model does not run.
    pub sets: [vk::DescriptorSet; Pass::COUNT],
}

pub struct Crowd {
    pub(crate) model: GpuModel,
    characters: u32,
    /// C x J x 3x4 f32, host-visible (written by `set_bones`, read by passes 1–3).
    bones: Buffer,
    /// B = [d; q] of pass 2's product, (3P + 4J) x 3C f32 per chunk (pass 1 → pass 2)
    rhs: Buffer,
    /// C x P x 3x4 f32 (pass 2 → pass 3)
    proxies: Buffer,
    /// C x V x 3 f32 (pass 3 → pass 4, and the engine's vertex buffer)
    positions: Buffer,
    /// C x V x 3 f32
    normals: Buffer,
    pool: vk::DescriptorPool,
    pub(crate) chunks: Vec<Chunk>,
}

impl Crowd {
    /// A crowd of `characters` characters, all in the rest pose until `set_bones`.
    pub fn new(model: &GpuModel, characters: usize) -> Result<Crowd> {
        Self::with_options(model, characters, CrowdOptions::default())
    }

    pub fn with_options(
        model: &GpuModel,
        characters: usize,
        options: CrowdOptions,
    ) -> Result<Crowd> {
        let m = &model.inner;
        let shared = m.context.shared.clone();
        if characters == 0 {
            return Err(Error::OutOfRange {
                what: "crowd size",
                index: 0,
                count: 0,
            });
        }
        let c = characters as u64;
        let per_character = CrowdBuffer::ALL.map(|b| bytes_per_character(&m.dims, b));
        let size = |b: CrowdBuffer| c * per_character[b as usize];
        let chunk_characters = chunk_size(&shared, &m.dims, &per_character, c, options)?;

        let storage = vk::BufferUsageFlags::STORAGE_BUFFER;
        let output =
            storage | vk::BufferUsageFlags::VERTEX_BUFFER | vk::BufferUsageFlags::TRANSFER_SRC;
        let gpu = MemoryLocation::GpuOnly;
        let mut bones = Buffer::new(
            &shared,
            "crowd bones",
            size(CrowdBuffer::Bones),
            storage,
            MemoryLocation::CpuToGpu,
        )?;
        let rhs = Buffer::new(&shared, "crowd rhs", size(CrowdBuffer::Rhs), storage, gpu)?;
        let proxies = Buffer::new(
            &shared,
            "crowd proxies",
            size(CrowdBuffer::Proxies),
            storage,
            gpu,
        )?;
        let positions = Buffer::new(
            &shared,
            "crowd positions",
            size(CrowdBuffer::Positions),
            output,
            gpu,
        )?;
        let normals = Buffer::new(
            &shared,
            "crowd normals",
            size(CrowdBuffer::Normals),
            output,
            gpu,
        )?;
        write_rest_pose(bones.mapped()?);

        let chunk_count = characters.div_ceil(chunk_characters as usize);
        let pool = create_pool(&shared.device, &m.dims, chunk_count as u32)?;
        let mut crowd = Crowd {
            model: model.clone(),
            characters: characters as u32,
            bones,
            rhs,
            proxies,
            positions,
            normals,
            pool,
            chunks: Vec::with_capacity(chunk_count),
        };
        for first in (0..c).step_by(chunk_characters as usize) {
            let count = chunk_characters.min(c - first);
            let view = |buffer: &Buffer, per: u64| {
                if per == 0 {
                    buffer.whole() // P = 0: an unread placeholder
                } else {
                    buffer.descriptor(first * per, count * per)
                }
            };
            let views = CrowdBuffer::ALL.map(|b| view(crowd.buffer(b), per_character[b as usize]));
            let chunk = crowd.make_chunk(&shared, m, &views, count as u32)?;
            crowd.chunks.push(chunk);
        }
        Ok(crowd)
    }

    fn make_chunk(
        &self,
        shared: &Shared,
        m: &Inner,
        views: &ChunkViews,
        characters: u32,
    ) -> Result<Chunk> {
        let mut sets = [vk::DescriptorSet::null(); Pass::COUNT];
        for pass in Pass::of_model(&m.dims) {
            let buffers: Vec<vk::DescriptorBufferInfo> = (pass.desc().bindings.iter())
                .map(|&binding| match binding {
                    Binding::Model(b) => m.buffer(b).whole(),
                    Binding::Reads(b) | Binding::Writes(b) => views[b as usize],
                })
                .collect();
            let pipeline = shared.pipelines.get(pass);
            sets[pass as usize] = write_set(shared, self.pool, pipeline, &buffers)?;
        }
        Ok(Chunk { characters, sets })
    }

    fn buffer(&self, b: CrowdBuffer) -> &Buffer {
        match b {
            CrowdBuffer::Bones => &self.bones,
            CrowdBuffer::Rhs => &self.rhs,
            CrowdBuffer::Proxies => &self.proxies,
            CrowdBuffer::Positions => &self.positions,
            CrowdBuffer::Normals => &self.normals,
        }
    }

    pub fn character_count(&self) -> usize {
        self.characters as usize
    }

    pub fn model(&self) -> &GpuModel {
        &self.model
    }

    /// Number of dispatch chunks (1 unless the outputs exceed one descriptor's range).
    pub fn chunk_count(&self) -> usize {
        self.chunks.len()
    }

    /// Sets every character's bone transforms: C x J, character-major.
    /// See the crate contract: no submitted work reading this crowd may still be executing.
    pub fn set_bones(&mut self, bones: &[Affine]) -> Result<()> {
        let expected = self.characters as usize * self.model.bone_count();
        if bones.len() != expected {
            return Err(Error::WrongLength {
                what: "crowd bone transforms",
                expected,
                actual: bones.len(),
            });
        }
        check_finite(bones)?;
        self.bones.mapped()?[..expected * 48].copy_from_slice(bytemuck::cast_slice(bones));
        Ok(())
    }

    /// Sets one character's J bone transforms.
    pub fn set_character_bones(&mut self, character: usize, bones: &[Affine]) -> Result<()> {
        let j = self.model.bone_count();
        if character >= self.characters as usize {
            return Err(Error::OutOfRange {
                what: "character",
                index: character,
                count: self.characters as usize,
            });
        }
        if bones.len() != j {
            return Err(Error::WrongLength {
                what: "character bone transforms",
                expected: j,
                actual: bones.len(),
            });
        }
        check_finite(bones)?;
        let at = character * j * 48;
        self.bones.mapped()?[at..at + j * 48].copy_from_slice(bytemuck::cast_slice(bones));
        Ok(())
    }

    pub fn output(&self) -> CrowdOutput {
        CrowdOutput {
            positions: self.positions.handle,
            normals: self.normals.handle,
            offset: 0,
            vertex_stride: XYZ_BYTES,
            character_stride: self.model.vertex_count() as u64 * XYZ_BYTES,
        }
    }

    /// Copies the outputs back to the host. Submits and waits: for tools and tests, not the
    /// per-frame path.
    pub fn read_back(&self) -> Result<HostOutput> {
        let shared = &self.model.inner.context.shared;
        let size = self.positions.size;
        let mut staging = Buffer::new(
            shared,
            "read-back",
            2 * size,
            vk::BufferUsageFlags::TRANSFER_DST,
            MemoryLocation::GpuToCpu,
        )?;
        shared.submit_and_wait(|cmd| {
            let device = &shared.device;
            // SAFETY: cmd is recording; the buffers are alive.
            unsafe {
                global_barrier(
                    device,
                    cmd,
                    &[Access::ComputeShaderWrite],
                    &[Access::TransferRead],
                );
                for (src, at) in [(&self.positions, 0), (&self.normals, size)] {
                    let region = [vk::BufferCopy {
                        src_offset: 0,
                        dst_offset: at,
                        size,
                    }];
                    device.cmd_copy_buffer(cmd, src.handle, staging.handle, &region);
                }
                transfer_to_host_barrier(device, cmd);
            }
            Ok(())
        })?;
        let n = self.characters as usize * self.model.vertex_count() * 3;
        let mapped = staging.mapped()?;
        let floats: Vec<f32> = mapped[..2 * n * 4]
            .chunks_exact(4)
            .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .collect();
        let xyz = |s: &[f32]| {
            s.chunks_exact(3)
                .map(|p| [p[0], p[1], p[2]])
                .collect::<Vec<_>>()
        };
        Ok(HostOutput {
            positions: xyz(&floats[..n]),
            normals: xyz(&floats[n..]),
        })
    }

    pub(crate) fn shared(&self) -> &Arc<Shared> {
        &self.model.inner.context.shared
    }
}

impl Drop for Crowd {
    fn drop(&mut self) {
        // SAFETY: the caller guarantees no submitted work uses the crowd (crate contract); the
        // sets are freed with their pool.
        unsafe {
            self.shared()
                .device
                .destroy_descriptor_pool(self.pool, None)
        };
    }
}

/// The characters per chunk: as many as fit the binding range, a multiple of the granularity
/// that keeps every chunk offset aligned to minStorageBufferOffsetAlignment.
fn chunk_size(
    shared: &Shared,
    dims: &Dims,
    per_character: &[u64],
    characters: u64,
    options: CrowdOptions,
) -> Result<u64> {
    let limits = &shared.limits;
    let mut range = limits.max_storage_buffer_range;
    if let Some(cap) = options.max_binding_bytes {
        range = range.min(cap);
    }
    let largest = per_character.iter().copied().max().unwrap_or(0).max(1);
    if largest > range {
        return Err(Error::DeviceLimit {
            what: "one character's output (bytes) in one storage binding",
            needed: largest,
            limit: range,
        });
    }
    let max_groups = Pass::of_model(dims)
        .map(|p| p.desc().max_characters(limits.max_workgroup_count))
        .min()
        .unwrap_or(u64::MAX);
    let fit = (range / largest).min(max_groups);
    if characters <= fit {
        return Ok(characters);
    }
    let align = limits.min_storage_buffer_offset_alignment.max(1);
    let granularity = per_character
        .iter()
        .filter(|&&b| b > 0)
        .map(|&b| align / gcd(b, align))
        .max()
        .unwrap_or(1);
    let chunk = fit / granularity * granularity;
    if chunk == 0 {
        return Err(Error::DeviceLimit {
            what: "characters per aligned storage binding",
            needed: granularity,
            limit: fit,
        });
    }
    Ok(chunk)
}

fn gcd(a: u64, b: u64) -> u64 {
    if b == 0 {
        a
    } else {
        gcd(b, a % b)
    }
}

/// Identity transforms: a new crowd renders the rest pose.
fn write_rest_pose(bytes: &mut [u8]) {
    let identity: Affine = [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0];
    for slot in bytes.chunks_exact_mut(48) {
        slot.copy_from_slice(bytemuck::cast_slice(&identity));
    }
}

/// Bytes of one character in each crowd buffer; 0 where the model does not use it.
fn bytes_per_character(d: &Dims, b: CrowdBuffer) -> u64 {
    let (v, p, j) = (d.vertices as u64, d.proxies as u64, d.bones as u64);
    match b {
        CrowdBuffer::Bones => j * AFFINE_BYTES,
        // B = [d; q]: (3P + 4J) x 3 floats per character, only when P > 0.
        CrowdBuffer::Rhs if p > 0 => (3 * p + 4 * j) * XYZ_BYTES,
        CrowdBuffer::Rhs => 0,
        CrowdBuffer::Proxies => p * AFFINE_BYTES,
        CrowdBuffer::Positions | CrowdBuffer::Normals => v * XYZ_BYTES,
    }
}

fn create_pool(device: &ash::Device, dims: &Dims, chunks: u32) -> Result<vk::DescriptorPool> {
    let (sets, buffers) = Pass::descriptors_per_chunk(dims);
    let sizes = [vk::DescriptorPoolSize {
        ty: vk::DescriptorType::STORAGE_BUFFER,
        descriptor_count: chunks * buffers,
    }];
    let info = vk::DescriptorPoolCreateInfo::default()
        .max_sets(chunks * sets)
        .pool_sizes(&sizes);
    // SAFETY: valid device and create info.
    unsafe { device.create_descriptor_pool(&info, None) }
        .map_err(Error::vk("vkCreateDescriptorPool"))
}

fn write_set(
    shared: &Shared,
    pool: vk::DescriptorPool,
    pass: &PassPipeline,
    buffers: &[vk::DescriptorBufferInfo],
) -> Result<vk::DescriptorSet> {
    let layouts = [pass.set_layout];
    let info = vk::DescriptorSetAllocateInfo::default()
        .descriptor_pool(pool)
        .set_layouts(&layouts);
    // SAFETY: the pool was sized for every set of every chunk.
    let set = unsafe { shared.device.allocate_descriptor_sets(&info) }
        .map_err(Error::vk("vkAllocateDescriptorSets"))?[0];
    let writes: Vec<vk::WriteDescriptorSet> = buffers
        .iter()
        .enumerate()
        .map(|(b, info)| {
            vk::WriteDescriptorSet::default()
                .dst_set(set)
                .dst_binding(b as u32)
                .descriptor_type(vk::DescriptorType::STORAGE_BUFFER)
                .buffer_info(std::slice::from_ref(info))
        })
        .collect();
    // SAFETY: the set is not in use; the buffers are alive.
    unsafe { shared.device.update_descriptor_sets(&writes, &[]) };
    Ok(set)
}
