//! C characters of one GPU model: per-frame bone input, the right-hand side B = [d; q] and proxy
//! transforms, and the output positions, normals and (optionally) tangents the engine draws
//! from.
//!
//! Each per-character array is ONE buffer (so the engine binds one vertex buffer and offsets by
//! character), but a storage descriptor may only cover `maxStorageBufferRange` bytes (128 MiB on
//! lavapipe). The crowd is therefore split into chunks of characters; every chunk has its own
//! descriptor sets whose ranges start at chunk offsets aligned to
//! `minStorageBufferOffsetAlignment`, and the passes dispatch once per chunk.

use super::barrier::{global_barrier, Access, PASS_ACCESSES};
use super::buffer::{transfer_to_host_barrier, Buffer};
use super::context::Shared;
use super::gpu_model::{GpuModel, Inner};
use super::memory::{
    bytes_per_character, crowd_buffer_copies, crowd_buffers, crowd_bytes, XYZ_BYTES,
};
use super::pass::{Binding, CrowdBuffer, Dims};
use super::passes::Pass;
use super::pipelines::PassPipeline;
use crate::cpu::check_finite;
use crate::error::{Error, Result};
use crate::normals::NormalMode;
use crate::predict::Affine;
use ash::vk;
use gpu_allocator::MemoryLocation;
use std::sync::atomic::{AtomicU8, Ordering};
use std::sync::Arc;

/// One vertex's tangent in the tangents buffer: x, y, z, handedness w (f32, glTF's TANGENT).
pub const TANGENT_STRIDE: u64 = 16;
/// One character's box in the bounds buffer: min xyz, pad, max xyz, pad (two std430 vec4).
pub const BOUNDS_STRIDE: u64 = 32;
/// The most frames in flight a crowd rings its per-frame buffers over.
pub const MAX_FRAMES_IN_FLIGHT: usize = 4;

#[derive(Debug, Clone, Copy)]
pub struct CrowdOptions {
    /// F, the frames the engine keeps in flight (1..=[`MAX_FRAMES_IN_FLIGHT`], default 2): the
    /// crowd keeps F slots of its per-frame inputs and host-read outputs (bone transforms,
    /// bounds), so that frame f's are written while the other F − 1 frames still execute.
    pub frames_in_flight: usize,
    /// Keep last frame's positions in a second buffer: each recorded frame writes the buffer the
    /// one before did not (alternating, no copy); [`CrowdOutput::previous_positions`].
    pub previous_positions: bool,
    /// Write each character's axis-aligned box every frame ([`CrowdOutput::bounds`]).
    pub bounds: bool,
    /// Write a tangent frame per vertex every frame ([`CrowdOutput::tangents`]): for
    /// normal-mapped materials. Only for models with rest tangents (`NotInModel` otherwise).
    pub tangents: bool,
    /// How normals (and tangents, orthogonal to them) are made: recomputed from the skinned
    /// positions over each vertex's 1-ring by a pass of their own (paper §6, the default), or
    /// transformed in the skinning pass by the cofactor of each vertex's blended matrix, as
    /// engines skin (one pass a frame; `rrskin eval` reports what each costs in angular error).
    pub normals: NormalMode,
    /// Release each frame's outputs (its positions, the normals, its bounds, the tangents: those
    /// the crowd has) to this queue family at the end of the recording: a queue family ownership release barrier, which the engine matches with
    /// an acquire on its queue (same buffers, whole range, families reversed); see the crate's
    /// contract, "Queue family ownership". Another family of the device, or
    /// `VK_QUEUE_FAMILY_EXTERNAL`.
    pub release_to_queue_family: Option<u32>,
    /// Knobs for testing the runtime, not for engines (default: none).
    pub debug_settings: CrowdDebugSettings,
}

/// Settings that exercise the runtime's edge cases on small inputs (as gpu-allocator keeps its
/// `AllocatorDebugSettings` apart from the allocator's options).
#[derive(Debug, Clone, Copy, Default)]
pub struct CrowdDebugSettings {
    /// Largest descriptor range to use, below the device's maxStorageBufferRange: forces smaller
    /// chunks (tests exercise chunking without gigabytes of output).
    pub max_binding_bytes: Option<u64>,
    /// Largest buffer to make, below the device's (maxMemoryAllocationSize, maxBufferSize):
    /// tests exercise the limit, and the read-back's staging in pieces, without gigabytes.
    pub max_buffer_bytes: Option<u64>,
    /// Fill every buffer the crowd allocates, but the bone input, with NaN (0x7FC00000) once
    /// at creation, before any pass writes it: a pass that reads what no pass wrote (an
    /// uninitialised read that a real GPU answers with whatever the memory held) then spreads
    /// NaN into the outputs, where a comparison with the CPU reference sees it, on any device.
    pub fill_nan: bool,
}

/// Intermediates of the frame last run, copied to the host for tests and debugging
/// ([`Crowd::read_intermediates`]): C characters each, character-major.
#[derive(Debug, Clone, PartialEq)]
pub struct HostIntermediates {
    /// B = [d; q] of pass 1 per character, C x (3P + 4J) x 3: row r of character ch's
    /// `[d_c; q_c]` for c = x, y, z at `(ch (3P + 4J) + r) 3 + c` (the GPU keeps each chunk's
    /// rows for all its characters together). Empty for a plain LBS model (P = 0); a fused
    /// product writes none of it.
    pub rhs: Vec<f32>,
    /// The skinning palette [t (P); q (J)] per character, 3x4 row-major; empty for P = 0.
    pub palette: Vec<[f32; 12]>,
}

/// The outputs a recording releases with [`CrowdOptions::release_to_queue_family`], those the
/// crowd has, in barrier order: the positions the frame wrote, the normals, the frame slot's
/// bounds, the tangents (the crate's contract lists them; a test checks it does).
pub(crate) const RELEASED_OUTPUTS: [CrowdBuffer; 4] = [
    CrowdBuffer::Positions,
    CrowdBuffer::Normals,
    CrowdBuffer::Bounds,
    CrowdBuffer::Tangents,
];

impl Default for CrowdOptions {
    fn default() -> Self {
        CrowdOptions {
            frames_in_flight: 2,
            previous_positions: false,
            bounds: false,
            tangents: false,
            normals: NormalMode::Recomputed,
            release_to_queue_family: None,
            debug_settings: CrowdDebugSettings::default(),
        }
    }
}

/// Where the engine finds one frame's outputs: character `c`, vertex `a` is at
/// `offset + c * character_stride + a * vertex_stride` in each vertex buffer (3 x f32: x, y, z);
/// character `c`'s box at `c * BOUNDS_STRIDE` in `bounds`.
#[derive(Debug, Clone, Copy)]
pub struct CrowdOutput {
    pub positions: vk::Buffer,
    /// The positions of the crowd's frame recorded before this one (same layout); undefined
    /// until two frames were recorded. With [`CrowdOptions::previous_positions`] only.
    pub previous_positions: Option<vk::Buffer>,
    pub normals: vk::Buffer,
    /// Tangents with [`CrowdOptions::tangents`]: vertex `a` of character `c` at
    /// `offset + c * tangent_character_stride + a * TANGENT_STRIDE`, 4 x f32 (xyz unit,
    /// orthogonal to the normal; w = ±1, bitangent = cross(normal, xyz) * w).
    pub tangents: Option<vk::Buffer>,
    pub tangent_character_stride: u64,
    /// Per-character boxes (f32 min x, y, z, pad, max x, y, z, pad), host-visible (cached host
    /// memory, for reading back); with
    /// [`CrowdOptions::bounds`] only.
    pub bounds: Option<vk::Buffer>,
    pub offset: u64,
    pub vertex_stride: u64,
    pub character_stride: u64,
}

/// Outputs copied to the host: C x V each, character-major.
#[derive(Debug, Clone, PartialEq)]
pub struct HostOutput {
    pub positions: Vec<[f32; 3]>,
    pub normals: Vec<[f32; 3]>,
    /// Empty for a crowd without tangents.
    pub tangents: Vec<[f32; 4]>,
}

/// A character's axis-aligned box, in the units of the positions (6 floats: the C ABI's
/// layout).
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct Aabb {
    pub min: [f32; 3],
    pub max: [f32; 3],
}

pub(crate) struct Chunk {
    pub characters: u32,
    /// Indexed by [`Crowd::variant`], then by [`Pass`]; null for the passes the crowd does not
    /// run.
    pub sets: Vec<[vk::DescriptorSet; Pass::COUNT]>,
}

pub struct Crowd {
    pub(crate) model: GpuModel,
    /// The model's sizes and this crowd's optional outputs.
    pub(crate) dims: Dims,
    characters: u32,
    /// Indexed by [`CrowdBuffer`]: its copies, as many as `crowd_buffer_copies` says (the bones
    /// and bounds one per frame slot, the positions two with previous positions, the bounds
    /// and tangents none without them), each C x `bytes_per_character`.
    buffers: [Vec<Buffer>; CrowdBuffer::COUNT],
    /// Which positions buffer the last recording of each frame slot wrote, and of any frame.
    /// Atomics: recording takes `&Crowd` (many crowds in one batch), and the crowd stays `Sync`.
    written: [AtomicU8; MAX_FRAMES_IN_FLIGHT],
    last: AtomicU8,
    last_frame: AtomicU8,
    release_to: Option<u32>,
    /// The largest buffer the crowd makes (the device's, or the debug settings' lower one).
    buffer_limit: u64,
    pool: vk::DescriptorPool,
    pub(crate) chunks: Vec<Chunk>,
}

impl Crowd {
    /// A crowd of `characters` characters for 2 frames in flight, all in the rest pose until
    /// `set_bones`.
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
        check_request(&shared, m, characters, &options)?;
        let dims = crowd_dims(m, &options);

        let c = characters as u64;
        let per_character = CrowdBuffer::ALL.map(|b| bytes_per_character(&dims, b));
        let chunk_characters = chunk_size(&shared, &dims, &per_character, c, options)?;
        let buffers = create_buffers(&shared, &dims, c, &options)?;
        let mut crowd = Crowd {
            model: model.clone(),
            dims,
            characters: characters as u32,
            buffers,
            written: Default::default(),
            last: AtomicU8::new(0),
            last_frame: AtomicU8::new(0),
            release_to: options.release_to_queue_family,
            buffer_limit: buffer_limit(&shared, &options),
            pool: vk::DescriptorPool::null(),
            chunks: Vec::new(),
        };
        for slot in &mut crowd.buffers[CrowdBuffer::Bones as usize] {
            write_rest_pose(slot.mapped()?);
        }
        if let Some(up) = m.up {
            for slot in &mut crowd.buffers[CrowdBuffer::Ups as usize] {
                write_ups(slot.mapped()?, up);
            }
        }
        crowd.make_chunks(&shared, m, &per_character, c, chunk_characters)?;
        Ok(crowd)
    }

    /// The descriptor pool and the chunks of `c` characters, `chunk_characters` each (the
    /// last one fewer), each with its descriptor sets per variant.
    fn make_chunks(
        &mut self,
        shared: &Shared,
        m: &Inner,
        per_character: &[u64; CrowdBuffer::COUNT],
        c: u64,
        chunk_characters: u64,
    ) -> Result<()> {
        let chunk_count = (c as usize).div_ceil(chunk_characters as usize);
        let variants = self.variant_count();
        self.pool = create_pool(&shared.device, &self.dims, (chunk_count * variants) as u32)?;
        self.chunks.reserve_exact(chunk_count);
        for first in (0..c).step_by(chunk_characters as usize) {
            let count = chunk_characters.min(c - first);
            let mut sets = Vec::with_capacity(variants);
            for variant in 0..variants {
                let view = |b: CrowdBuffer| {
                    let buffer = self.buffer(b, variant).ok_or(Error::Mismatch {
                        what: "a pass binds a buffer the crowd was made without",
                    })?;
                    Ok(match per_character[b as usize] {
                        0 => buffer.whole(), // P = 0 or N = 0: an unread placeholder
                        per => buffer.descriptor(first * per, count * per),
                    })
                };
                sets.push(self.make_sets(shared, m, &view)?);
            }
            self.chunks.push(Chunk {
                characters: count as u32,
                sets,
            });
        }
        Ok(())
    }

    /// One descriptor set per pass the crowd runs, over the views `view` gives.
    fn make_sets(
        &self,
        shared: &Shared,
        m: &Inner,
        view: &dyn Fn(CrowdBuffer) -> Result<vk::DescriptorBufferInfo>,
    ) -> Result<[vk::DescriptorSet; Pass::COUNT]> {
        let mut sets = [vk::DescriptorSet::null(); Pass::COUNT];
        for pass in Pass::of_model(&self.dims) {
            let buffers = (pass.desc().bindings.iter())
                .map(|&binding| match binding {
                    Binding::Model(b) => Ok(m.buffer(b).whole()),
                    Binding::Reads(b) | Binding::Writes(b) | Binding::Updates(b) => view(b),
                })
                .collect::<Result<Vec<_>>>()?;
            let pipeline = shared.pipelines.get(pass);
            sets[pass as usize] = write_set(shared, self.pool, pipeline, &buffers)?;
        }
        Ok(sets)
    }

    /// The copies of buffer `b` (empty for the bounds or tangents of a crowd without them).
    fn copies(&self, b: CrowdBuffer) -> &[Buffer] {
        &self.buffers[b as usize]
    }

    fn positions(&self) -> &[Buffer] {
        self.copies(CrowdBuffer::Positions)
    }

    /// Descriptor variants: one per (frame slot, positions buffer written).
    fn variant_count(&self) -> usize {
        self.frames_in_flight() * self.positions().len()
    }

    /// The buffer `b` of frame slot `frame` that writes positions buffer `written`: the copy of
    /// the slot for the per-frame buffers, of `written` for the positions, else the one buffer.
    fn buffer_of(&self, b: CrowdBuffer, frame: usize, written: usize) -> Option<&Buffer> {
        let copies = self.copies(b);
        match b {
            CrowdBuffer::Bones | CrowdBuffer::Ups | CrowdBuffer::Bounds => copies.get(frame),
            CrowdBuffer::Positions => copies.get(written),
            CrowdBuffer::Rhs
            | CrowdBuffer::Palette
            | CrowdBuffer::Normals
            | CrowdBuffer::Tangents
            | CrowdBuffer::CorrectiveWeights => copies.first(),
        }
    }

    /// The buffer `b` of descriptor variant `variant` (see [`Crowd::variant`]).
    fn buffer(&self, b: CrowdBuffer, variant: usize) -> Option<&Buffer> {
        let n = self.positions().len();
        self.buffer_of(b, variant / n, variant % n)
    }

    pub fn character_count(&self) -> usize {
        self.characters as usize
    }

    pub fn model(&self) -> &GpuModel {
        &self.model
    }

    /// Bytes of the crowd's buffers: what [`super::crowd_bytes`] said before creating it.
    pub fn memory_bytes(&self) -> u64 {
        self.buffers.iter().flatten().map(|b| b.size).sum()
    }

    /// Whether the crowd writes tangents ([`CrowdOptions::tangents`]).
    pub fn has_tangents(&self) -> bool {
        !self.copies(CrowdBuffer::Tangents).is_empty()
    }

    /// F, the frames in flight the crowd was made for.
    pub fn frames_in_flight(&self) -> usize {
        self.copies(CrowdBuffer::Bones).len()
    }

    /// Number of dispatch chunks (1 unless the outputs exceed one descriptor's range).
    pub fn chunk_count(&self) -> usize {
        self.chunks.len()
    }

    /// `OutOfRange` unless `frame` is one of the crowd's frame slots.
    pub(crate) fn check_frame(&self, frame: usize) -> Result<()> {
        if frame >= self.frames_in_flight() {
            return Err(Error::OutOfRange {
                what: "frame in flight",
                index: frame,
                count: self.frames_in_flight(),
            });
        }
        Ok(())
    }

    /// Starts recording frame slot `frame` (checked): picks the positions buffer it writes, the
    /// one the last recorded frame did not.
    pub(crate) fn begin_frame(&self, frame: usize) {
        let written = if self.positions().len() == 2 {
            1 - self.last.load(Ordering::Relaxed)
        } else {
            0
        };
        self.last.store(written, Ordering::Relaxed);
        self.last_frame.store(frame as u8, Ordering::Relaxed);
        self.written[frame].store(written, Ordering::Relaxed);
    }

    /// The descriptor variant of frame slot `frame` as last begun.
    pub(crate) fn variant(&self, frame: usize) -> usize {
        frame * self.positions().len() + self.written[frame].load(Ordering::Relaxed) as usize
    }

    /// Sets frame slot `frame`'s bone transforms of every character: C x J, character-major.
    /// Frame `frame` must not be executing (the other F − 1 may be).
    pub fn set_bones(&mut self, frame: usize, bones: &[Affine]) -> Result<()> {
        self.check_frame(frame)?;
        let expected = self.characters as usize * self.model.bone_count();
        if bones.len() != expected {
            return Err(Error::WrongLength {
                what: "crowd bone transforms",
                expected,
                actual: bones.len(),
            });
        }
        check_finite(bones)?;
        self.bones_mut(frame)?[..expected * 48].copy_from_slice(bytemuck::cast_slice(bones));
        Ok(())
    }

    /// Sets one character's J bone transforms in frame slot `frame`.
    pub fn set_character_bones(
        &mut self,
        frame: usize,
        character: usize,
        bones: &[Affine],
    ) -> Result<()> {
        self.check_frame(frame)?;
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
        self.bones_mut(frame)?[at..at + j * 48].copy_from_slice(bytemuck::cast_slice(bones));
        Ok(())
    }

    /// Sets frame slot `frame`'s up vector of every character (C, in its bones' frame): the
    /// direction opposite to gravity, its length gravity's strength against the training
    /// poses' ([`crate::predict::check_ups`]), for characters tilted by their object transform
    /// rather than their root bone. A crowd starts with the model's up
    /// ([`GpuModel::up`]) in every slot; a model whose proxy correctives do not see gravity
    /// reads none (they are checked, and dropped).
    pub fn set_ups(&mut self, frame: usize, ups: &[[f32; 3]]) -> Result<()> {
        self.check_frame(frame)?;
        if ups.len() != self.characters as usize {
            return Err(Error::WrongLength {
                what: "crowd up vectors",
                expected: self.characters as usize,
                actual: ups.len(),
            });
        }
        crate::predict::check_ups(ups)?;
        if self.dims.gravity {
            for (out, up) in self.ups_mut(frame)?.chunks_exact_mut(16).zip(ups) {
                write_ups(out, *up);
            }
        }
        Ok(())
    }

    /// Sets one character's up vector in frame slot `frame` (as [`Crowd::set_ups`]).
    pub fn set_character_up(&mut self, frame: usize, character: usize, up: [f32; 3]) -> Result<()> {
        self.check_frame(frame)?;
        if character >= self.characters as usize {
            return Err(Error::OutOfRange {
                what: "character",
                index: character,
                count: self.characters as usize,
            });
        }
        crate::predict::check_ups(&[up])?;
        if self.dims.gravity {
            write_ups(
                &mut self.ups_mut(frame)?[16 * character..16 * (character + 1)],
                up,
            );
        }
        Ok(())
    }

    /// The host-visible bytes of frame slot `frame`'s bone transforms (checked slot).
    fn bones_mut(&mut self, frame: usize) -> Result<&mut [u8]> {
        self.buffers[CrowdBuffer::Bones as usize][frame].mapped()
    }

    /// The host-visible bytes of frame slot `frame`'s up vectors (checked slot; a crowd of a
    /// model that sees gravity).
    fn ups_mut(&mut self, frame: usize) -> Result<&mut [u8]> {
        self.buffers[CrowdBuffer::Ups as usize][frame].mapped()
    }

    /// The buffers frame slot `frame` was last recorded with (the positions it writes, the
    /// previous frame's, its bounds).
    pub fn output(&self, frame: usize) -> Result<CrowdOutput> {
        self.check_frame(frame)?;
        Ok(self.output_of(frame, self.written[frame].load(Ordering::Relaxed)))
    }

    /// The buffers of the frame recorded last (of any slot; slot 0's before any recording),
    /// for a draw recorded right after it.
    pub fn latest_output(&self) -> CrowdOutput {
        let frame = self.last_frame.load(Ordering::Relaxed) as usize;
        self.output_of(frame, self.last.load(Ordering::Relaxed))
    }

    fn output_of(&self, frame: usize, written: u8) -> CrowdOutput {
        let written = written as usize;
        let handle = |b| self.buffer_of(b, frame, written).map(|b| b.handle);
        let positions = self.positions();
        CrowdOutput {
            positions: positions[written].handle,
            previous_positions: (positions.len() == 2).then(|| positions[1 - written].handle),
            normals: self.copies(CrowdBuffer::Normals)[0].handle,
            tangents: handle(CrowdBuffer::Tangents),
            tangent_character_stride: self.model.vertex_count() as u64 * TANGENT_STRIDE,
            bounds: handle(CrowdBuffer::Bounds),
            offset: 0,
            vertex_stride: XYZ_BYTES,
            character_stride: self.model.vertex_count() as u64 * XYZ_BYTES,
        }
    }

    /// Records the release of frame slot `frame`'s outputs (as last begun) to the family of
    /// [`CrowdOptions::release_to_queue_family`], if any.
    ///
    /// # Safety
    /// `cmd` is recording, after the frame's passes; `frame` is one of the crowd's slots.
    pub(crate) unsafe fn release_outputs(&self, cmd: vk::CommandBuffer, frame: usize) {
        let Some(family) = self.release_to else {
            return;
        };
        let written = self.written[frame].load(Ordering::Relaxed) as usize;
        let release = |b: &Buffer| {
            vk::BufferMemoryBarrier::default()
                .src_access_mask(vk::AccessFlags::SHADER_WRITE)
                .src_queue_family_index(self.shared().queue_family_index)
                .dst_queue_family_index(family)
                .buffer(b.handle)
                .offset(0)
                .size(vk::WHOLE_SIZE)
        };
        // A fixed array, no allocation: the outputs the crowd has.
        let mut barriers = [vk::BufferMemoryBarrier::default(); RELEASED_OUTPUTS.len()];
        let mut count = 0;
        for b in RELEASED_OUTPUTS {
            if let Some(buffer) = self.buffer_of(b, frame, written) {
                barriers[count] = release(buffer);
                count += 1;
            }
        }
        let used = &barriers[..count];
        // SAFETY: see the function's contract; the buffers are the crowd's, alive.
        unsafe {
            self.shared().device.cmd_pipeline_barrier(
                cmd,
                vk::PipelineStageFlags::COMPUTE_SHADER,
                vk::PipelineStageFlags::BOTTOM_OF_PIPE,
                vk::DependencyFlags::empty(),
                &[],
                used,
                &[],
            )
        };
    }

    /// Frame slot `frame`'s boxes, one per character, read from host-visible memory: call it
    /// once the frame's submission completed (no copy, no submission; allocation-free).
    pub fn read_bounds(&mut self, frame: usize, out: &mut [Aabb]) -> Result<()> {
        self.check_frame(frame)?;
        let c = self.characters as usize;
        if out.len() != c {
            return Err(Error::WrongLength {
                what: "bounds",
                expected: c,
                actual: out.len(),
            });
        }
        let slot = (self.buffers[CrowdBuffer::Bounds as usize].get_mut(frame)).ok_or(
            Error::NotEnabled {
                what: "bounds (create the crowd with CrowdOptions::bounds)",
            },
        )?;
        let floats: &[f32] = bytemuck::cast_slice(&slot.mapped()?[..c * BOUNDS_STRIDE as usize]);
        for (b, f) in out.iter_mut().zip(floats.chunks_exact(8)) {
            *b = Aabb {
                min: [f[0], f[1], f[2]],
                max: [f[4], f[5], f[6]],
            };
        }
        Ok(())
    }

    /// Copies the outputs of the last recorded frame back to the host. Submits and waits: for
    /// tools and tests, not the per-frame path.
    pub fn read_back(&self) -> Result<HostOutput> {
        let positions = &self.positions()[self.last.load(Ordering::Relaxed) as usize];
        let normals = &self.copies(CrowdBuffer::Normals)[0];
        let tangents = self.copies(CrowdBuffer::Tangents).first();
        let buffers: Vec<&Buffer> = [positions, normals].into_iter().chain(tangents).collect();
        let mut floats = self.read_floats(&buffers)?.into_iter();
        let mut next = || floats.next().unwrap_or_default();
        let (positions, normals, tangents) = (next(), next(), next());
        Ok(HostOutput {
            positions: xyz(&positions),
            normals: xyz(&normals),
            tangents: (tangents.chunks_exact(4))
                .map(|p| [p[0], p[1], p[2], p[3]])
                .collect(),
        })
    }

    /// The intermediates of the frame last run (`Batch::run`, or a recorded frame whose
    /// command buffer completed), copied to the host: for tests that name the first pass
    /// whose buffer disagrees with the CPU reference, and for debugging. Waits.
    pub fn read_intermediates(&self) -> Result<HostIntermediates> {
        if self.dims.proxies == 0 {
            return Ok(HostIntermediates {
                rhs: Vec::new(),
                palette: Vec::new(),
            });
        }
        let buffers = [CrowdBuffer::Rhs, CrowdBuffer::Palette].map(|b| &self.copies(b)[0]);
        let mut floats = self.read_floats(&buffers)?.into_iter();
        let chunked = floats.next().unwrap_or_default();
        let palette = floats.next().unwrap_or_default();
        let rows = 3 * self.dims.proxies as usize + 4 * self.dims.bones as usize;
        let mut rhs = Vec::with_capacity(chunked.len());
        let mut first = 0;
        for chunk in &self.chunks {
            // The chunk's B: `rows` rows of 3 x its characters columns, row-major.
            let cols = 3 * chunk.characters as usize;
            let b = &chunked[first * rows..][..rows * cols];
            for ch in 0..chunk.characters as usize {
                rhs.extend((0..rows).flat_map(|r| &b[r * cols + 3 * ch..][..3]));
            }
            first += cols;
        }
        Ok(HostIntermediates {
            rhs,
            palette: (palette.chunks_exact(12))
                .map(|t| std::array::from_fn(|i| t[i]))
                .collect(),
        })
    }

    /// The whole of each of `buffers` as f32 (waits): after the compute writes, through a
    /// host-visible staging buffer of at most [`READ_BACK_STAGING`] bytes (and the largest
    /// buffer the crowd makes), one submission each time it fills.
    fn read_floats(&self, buffers: &[&Buffer]) -> Result<Vec<Vec<f32>>> {
        let shared = &self.model.inner.context.shared;
        let total: u64 = buffers.iter().map(|b| b.size).sum();
        let piece = (total.min(READ_BACK_STAGING).min(self.buffer_limit) & !3).max(4);
        let mut staging = Buffer::new(
            shared,
            "read-back",
            piece,
            vk::BufferUsageFlags::TRANSFER_DST,
            MemoryLocation::GpuToCpu,
        )?;
        let mut floats: Vec<Vec<f32>> = (buffers.iter())
            .map(|b| Vec::with_capacity(b.size as usize / 4))
            .collect();
        // (buffer, offset in it, bytes) of each copy into the staging buffer, in its order.
        let mut pending: Vec<(usize, u64, u64)> = Vec::new();
        let mut filled = 0;
        for (i, src) in buffers.iter().enumerate() {
            let mut offset = 0;
            while offset < src.size {
                let size = (piece - filled).min(src.size - offset);
                pending.push((i, offset, size));
                (filled, offset) = (filled + size, offset + size);
                if filled == piece {
                    self.stage(buffers, &pending, &mut staging, &mut floats)?;
                    (filled, pending) = (0, Vec::new());
                }
            }
        }
        if !pending.is_empty() {
            self.stage(buffers, &pending, &mut staging, &mut floats)?;
        }
        Ok(floats)
    }

    /// Copies `pieces` ((buffer, offset, bytes), packed in order) of `buffers` into `staging`
    /// in one submission, waits, and appends their floats to `floats`.
    fn stage(
        &self,
        buffers: &[&Buffer],
        pieces: &[(usize, u64, u64)],
        staging: &mut Buffer,
        floats: &mut [Vec<f32>],
    ) -> Result<()> {
        let shared = &self.model.inner.context.shared;
        shared.record_and_submit(|cmd| {
            let device = &shared.device;
            // SAFETY: cmd is recording; the buffers are alive and have TRANSFER_SRC, and the
            // pieces lie within them and, packed, within the staging buffer.
            unsafe {
                global_barrier(
                    device,
                    cmd,
                    &[Access::ComputeShaderWrite],
                    &[Access::TransferRead],
                );
                let mut at = 0;
                for &(i, offset, size) in pieces {
                    let region = [vk::BufferCopy {
                        src_offset: offset,
                        dst_offset: at,
                        size,
                    }];
                    device.cmd_copy_buffer(cmd, buffers[i].handle, staging.handle, &region);
                    at += size;
                }
                transfer_to_host_barrier(device, cmd);
            }
            Ok(())
        })?;
        let mapped = staging.mapped()?;
        let mut at = 0usize;
        for &(i, _, size) in pieces {
            let bytes = &mapped[at..at + size as usize];
            at += size as usize;
            floats[i].extend(
                (bytes.chunks_exact(4)).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])),
            );
        }
        Ok(())
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

/// What `Crowd::with_options` refuses before it creates anything: no characters, frames in
/// flight out of 1..4, a release to the context's own (or no) queue family, tangents of a model
/// without rest tangents, a buffer beyond the largest the device makes, a crowd beyond the
/// largest device-local heap.
fn check_request(
    shared: &Shared,
    m: &Inner,
    characters: usize,
    options: &CrowdOptions,
) -> Result<()> {
    if characters == 0 {
        return Err(Error::OutOfRange {
            what: "crowd size",
            index: 0,
            count: 0,
        });
    }
    let frames = options.frames_in_flight;
    if !(1..=MAX_FRAMES_IN_FLIGHT).contains(&frames) {
        return Err(Error::OutOfRange {
            what: "frames in flight (1 to 4)",
            index: frames,
            count: MAX_FRAMES_IN_FLIGHT + 1,
        });
    }
    if let Some(family) = options.release_to_queue_family {
        let count = shared.limits.queue_family_count;
        let other = family != shared.queue_family_index
            && (family < count || family == vk::QUEUE_FAMILY_EXTERNAL);
        if !other {
            return Err(Error::OutOfRange {
                what: "queue family to release outputs to (another of the device's)",
                index: family as usize,
                count: count as usize,
            });
        }
    }
    if options.tangents && !m.sizes.tangents {
        return Err(Error::NotInModel {
            what: "rest tangents (train from a glTF rig with TANGENT or TEXCOORD_0) for a crowd with tangents",
        });
    }
    let dims = crowd_dims(m, options);
    let widest = (Pass::of_model(&dims).map(|p| p.desc().bindings.len() as u32)).max();
    let storage = shared.limits.max_storage_buffers_per_stage;
    if let Some(needed) = widest.filter(|&n| n > storage) {
        return Err(Error::DeviceLimit {
            what: "storage buffers per shader stage of the model's widest pass in this mode (maxPerStageDescriptorStorageBuffers)",
            needed: needed as u64,
            limit: storage as u64,
        });
    }
    let limit = buffer_limit(shared, options);
    for b in crowd_buffers(&dims, options) {
        let needed = bytes_per_character(&dims, b).saturating_mul(characters as u64);
        if needed > limit {
            return Err(Error::BufferTooLarge {
                buffer: kind(b).0,
                needed,
                limit,
            });
        }
    }
    let bytes = crowd_bytes(&m.sizes, characters, options)?;
    let heap = shared.limits.device_local_bytes;
    if bytes > heap {
        return Err(Error::DeviceLimit {
            what: "crowd bytes (vk::crowd_bytes) in the largest device-local heap",
            needed: bytes,
            limit: heap,
        });
    }
    Ok(())
}

/// The sizes of a crowd of model `m` made with `options`: the model's, with the outputs asked.
fn crowd_dims(m: &Inner, options: &CrowdOptions) -> Dims {
    Dims {
        bounds: options.bounds,
        tangents: options.tangents,
        normals: options.normals,
        ..m.dims
    }
}

/// The read-back's staging buffer at most: a crowd's outputs are gigabytes at 16k characters.
const READ_BACK_STAGING: u64 = 64 << 20;

/// The largest buffer the crowd makes: the device's, or lower where the debug settings say.
fn buffer_limit(shared: &Shared, options: &CrowdOptions) -> u64 {
    let device = shared.limits.max_buffer_bytes;
    (options.debug_settings.max_buffer_bytes).map_or(device, |cap| cap.min(device))
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
    if let Some(cap) = options.debug_settings.max_binding_bytes {
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

/// `up` (xyz, w 0) in every vec4 of `bytes`.
fn write_ups(bytes: &mut [u8], up: [f32; 3]) {
    let [x, y, z] = up;
    for slot in bytes.chunks_exact_mut(16) {
        slot.copy_from_slice(bytemuck::cast_slice(&[x, y, z, 0.0]));
    }
}

/// Every buffer of a crowd of `characters` of a model of sizes `dims` made with `options`,
/// NaN-filled where the options' debug settings ask.
fn create_buffers(
    shared: &Arc<Shared>,
    dims: &Dims,
    characters: u64,
    options: &CrowdOptions,
) -> Result<[Vec<Buffer>; CrowdBuffer::COUNT]> {
    let mut buffers: [Vec<Buffer>; CrowdBuffer::COUNT] = Default::default();
    for b in CrowdBuffer::ALL {
        let (name, usage, location) = kind(b);
        let size = characters * bytes_per_character(dims, b);
        buffers[b as usize] = (0..crowd_buffer_copies(b, dims, options))
            .map(|_| Buffer::new(shared, name, size, usage, location))
            .collect::<Result<_>>()?;
    }
    if options.debug_settings.fill_nan {
        fill_nan(shared, &mut buffers)?;
    }
    Ok(buffers)
}

/// Consecutive triples of floats.
fn xyz(floats: &[f32]) -> Vec<[f32; 3]> {
    (floats.chunks_exact(3))
        .map(|p| [p[0], p[1], p[2]])
        .collect()
}

/// NaN in every crowd buffer but the inputs, the bones and the up vectors, whose defaults a crowd
/// starts with (`CrowdDebugSettings::fill_nan`): the host-visible
/// ones through their mapping, the device-local ones by `vkCmdFillBuffer`, made visible to
/// every later pass.
fn fill_nan(shared: &Arc<Shared>, buffers: &mut [Vec<Buffer>; CrowdBuffer::COUNT]) -> Result<()> {
    const NAN: u32 = 0x7FC0_0000;
    for b in CrowdBuffer::ALL
        .into_iter()
        .filter(|&b| !matches!(b, CrowdBuffer::Bones | CrowdBuffer::Ups))
    {
        if kind(b).2 == MemoryLocation::GpuOnly {
            continue;
        }
        for buffer in &mut buffers[b as usize] {
            for word in buffer.mapped()?.chunks_exact_mut(4) {
                word.copy_from_slice(&NAN.to_le_bytes());
            }
        }
    }
    shared.record_and_submit(|cmd| {
        let device = &shared.device;
        let on_device = (CrowdBuffer::ALL.into_iter())
            .filter(|&b| kind(b).2 == MemoryLocation::GpuOnly)
            .flat_map(|b| &buffers[b as usize]);
        // SAFETY: cmd is recording; the buffers are alive, unused, and have TRANSFER_DST.
        unsafe {
            for buffer in on_device {
                device.cmd_fill_buffer(cmd, buffer.handle, 0, vk::WHOLE_SIZE, NAN);
            }
            global_barrier(device, cmd, &[Access::TransferWrite], &PASS_ACCESSES);
        }
        Ok(())
    })
}

/// The debug name, usage and memory of crowd buffer `b`. Every device-local buffer can be
/// filled (`CrowdDebugSettings::fill_nan`) and copied to the host (outputs and intermediates
/// alike: [`Crowd::read_back`], [`Crowd::read_intermediates`]).
pub(super) fn kind(b: CrowdBuffer) -> (&'static str, vk::BufferUsageFlags, MemoryLocation) {
    let storage = vk::BufferUsageFlags::STORAGE_BUFFER;
    let copies = vk::BufferUsageFlags::TRANSFER_SRC | vk::BufferUsageFlags::TRANSFER_DST;
    let output = storage | vk::BufferUsageFlags::VERTEX_BUFFER | copies;
    let gpu = MemoryLocation::GpuOnly;
    // Host-visible and coherent, so neither needs a flush or an invalidation. What the host
    // writes, it writes through: device-local where the device offers it (gpu-allocator's
    // CpuToGpu: the BAR heap of a discrete GPU, uncached on the host). What the host reads
    // back is cached host memory (GpuToCpu): a read of write-combined BAR memory crosses PCIe
    // uncached, every load (about 100k floats a frame for 16k characters' bounds).
    let host = MemoryLocation::CpuToGpu;
    let readback = MemoryLocation::GpuToCpu;
    match b {
        CrowdBuffer::Bones => ("crowd bones", storage, host),
        CrowdBuffer::Rhs => ("crowd rhs", storage | copies, gpu),
        CrowdBuffer::Palette => ("crowd palette", storage | copies, gpu),
        CrowdBuffer::Positions => ("crowd positions", output, gpu),
        CrowdBuffer::Normals => ("crowd normals", output, gpu),
        CrowdBuffer::Bounds => ("crowd bounds", storage, readback),
        CrowdBuffer::Tangents => ("crowd tangents", output, gpu),
        CrowdBuffer::CorrectiveWeights => ("crowd corrective weights", storage | copies, gpu),
        CrowdBuffer::Ups => ("crowd up vectors", storage, host),
    }
}

/// A pool for the sets of `copies` chunks (every chunk once per descriptor variant).
fn create_pool(device: &ash::Device, dims: &Dims, copies: u32) -> Result<vk::DescriptorPool> {
    let (sets, buffers) = Pass::descriptors_per_chunk(dims);
    let chunks = copies;
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
