//! Crowds: created from a model, given their bones, asked for their outputs (buffers,
//! read-backs, bounds), destroyed; and a context's batch, which records or runs one frame of
//! several crowds and times its passes (`rrskin_context_get_timings`).

use super::guard::{guard, put, slice, vectors3, Failure};
use super::handles::{context_entry, crowd_entry, model_entry, registry, CrowdEntry};
use super::types::{
    RrskinContext, RrskinCrowd, RrskinCrowdOptions, RrskinModel, RrskinStatus,
    RRSKIN_NORMALS_RECOMPUTED, RRSKIN_NORMALS_TRANSFORMED,
};
use crate::error::Error;
use crate::normals::NormalMode;
use crate::predict::Affine;
use crate::vk::{ash::vk, Aabb, Batch, Crowd, CrowdOptions};
use std::ffi::c_void;
use std::sync::{Arc, RwLock};

/// Where the engine finds one frame slot's outputs: character c, vertex a is at
/// `offset + c * character_stride + a * vertex_stride` bytes in the positions and normals, as
/// 3 floats, and at `offset + c * tangent_character_stride + a * tangent_stride` in the
/// tangents, as 4; character c's box at `c * bounds_stride` in `bounds`.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default)]
pub struct RrskinCrowdOutput {
    /// VkBuffer of positions written by the frame (usage: vertex buffer, storage, transfer
    /// source).
    pub positions: u64,
    /// VkBuffer of the positions of the frame recorded before it (same layout and usage), or 0
    /// without previous positions. Undefined until two frames were recorded.
    pub previous_positions: u64,
    /// VkBuffer of normals.
    pub normals: u64,
    /// VkBuffer of the frame slot's boxes (storage, host-visible): per character 8 floats, min
    /// x, y, z, pad, max x, y, z, pad; 0 without bounds.
    pub bounds: u64,
    /// VkBuffer of tangents (usage as the normals'): per vertex 4 floats, xyz unit and
    /// orthogonal to the normal, w = +-1 with bitangent = cross(normal, xyz) * w (glTF's
    /// TANGENT); 0 without tangents.
    pub tangents: u64,
    pub offset: u64,
    pub vertex_stride: u64,
    pub character_stride: u64,
    pub bounds_stride: u64,
    /// 16 bytes.
    pub tangent_stride: u64,
    pub tangent_character_stride: u64,
}

/// GPU time per pass of the last recorded frame, in milliseconds.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default)]
pub struct RrskinPassTimings {
    /// The key predictors and the pose-space corrective weights.
    pub predict_ms: f64,
    /// The C1/C2 product t = C1 d + C2 q (dense, block-sparse or fused; the Rust `product_ms`).
    pub blend_ms: f64,
    /// The proxy correctives, T_e (I + E_e) in the palette (0 where no crowd has them).
    pub proxy_correctives_ms: f64,
    pub skin_ms: f64,
    pub normals_ms: f64,
    /// 0 without tangents.
    pub tangents_ms: f64,
}

/// Creates a crowd of `characters` characters of `model` for 2 frames in flight, all in the
/// rest pose.
///
/// # Safety
/// `out` is NULL or points to writable memory for one `rrskin_crowd`.
#[no_mangle]
pub unsafe extern "C" fn rrskin_crowd_create(
    model: RrskinModel,
    characters: u32,
    out: *mut RrskinCrowd,
) -> RrskinStatus {
    guard(|| {
        // SAFETY: `out` as the function's contract requires.
        unsafe { add_crowd(model, characters, CrowdOptions::default(), out) }
    })
}

/// Creates a crowd as `rrskin_crowd_create` does, with `options` (frames in flight out of 1..4:
/// RRSKIN_STATUS_ERROR_OUT_OF_RANGE).
///
/// # Safety
/// `options` is NULL or points to a readable `rrskin_crowd_options`; `out` is NULL or points to
/// writable memory for one `rrskin_crowd`.
#[no_mangle]
pub unsafe extern "C" fn rrskin_crowd_create_with_options(
    model: RrskinModel,
    characters: u32,
    options: *const RrskinCrowdOptions,
    out: *mut RrskinCrowd,
) -> RrskinStatus {
    guard(|| {
        if options.is_null() {
            return Err(Failure::null("options"));
        }
        // SAFETY: non-null, and readable by the function's contract.
        let options = crowd_options(unsafe { &*options })?;
        // SAFETY: `out` as the function's contract requires.
        unsafe { add_crowd(model, characters, options, out) }
    })
}

pub(super) fn crowd_options(o: &RrskinCrowdOptions) -> Result<CrowdOptions, Failure> {
    let normals = match o.normals {
        RRSKIN_NORMALS_RECOMPUTED => NormalMode::Recomputed,
        RRSKIN_NORMALS_TRANSFORMED => NormalMode::Transformed,
        other => {
            return Err(Failure::from(Error::OutOfRange {
                what: "options->normals (RRSKIN_NORMALS_RECOMPUTED or _TRANSFORMED)",
                index: other as usize,
                count: 2,
            }))
        }
    };
    Ok(CrowdOptions {
        frames_in_flight: o.frames_in_flight as usize,
        previous_positions: o.previous_positions != 0,
        bounds: o.bounds != 0,
        tangents: o.tangents != 0,
        normals,
        release_to_queue_family: (o.release_outputs != 0).then_some(o.release_queue_family),
        ..CrowdOptions::default()
    })
}

/// Makes a crowd of `model` and hands out its handle.
///
/// # Safety
/// `out` is NULL or valid for writing one `RrskinCrowd`.
unsafe fn add_crowd(
    model: RrskinModel,
    characters: u32,
    options: CrowdOptions,
    out: *mut RrskinCrowd,
) -> Result<(), Failure> {
    if out.is_null() {
        return Err(Failure::null("out"));
    }
    let entry = model_entry(model)?;
    let crowd = RwLock::new(Crowd::with_options(
        &entry.gpu,
        characters as usize,
        options,
    )?);
    let id = registry().crowds.insert(Arc::new(CrowdEntry {
        device: entry.gpu.context().clone(),
        crowd,
    }));
    // SAFETY: `out` as the function's contract requires.
    unsafe { put(out, RrskinCrowd { id }, "out") }
}

/// A caller's floats as 3x4 transforms.
///
/// # Safety
/// As [`slice`]: `transforms` is NULL or points to `float_count` readable floats.
unsafe fn affines<'a>(transforms: *const f32, float_count: usize) -> Result<&'a [Affine], Failure> {
    if float_count % 12 != 0 {
        return Err(Failure::new(
            RrskinStatus::ErrorWrongLength,
            format!("{float_count} floats is not a whole number of 3x4 transforms"),
        ));
    }
    // SAFETY: the function's contract.
    let floats = unsafe { slice(transforms, float_count, "transforms")? };
    Ok(bytemuck::cast_slice(floats))
}

/// Sets every character's bone transforms of frame slot `frame` (0 to F - 1): `float_count` =
/// characters x bones x 12 floats, each transform 3x4 row-major, world space, relative to the
/// rest pose. The frame slot must not be executing; the other F - 1 may be.
///
/// # Safety
/// `transforms` is NULL or points to `float_count` readable floats (4-byte aligned) that no
/// other thread writes during the call.
#[no_mangle]
pub unsafe extern "C" fn rrskin_crowd_set_bones(
    crowd: RrskinCrowd,
    frame: u32,
    transforms: *const f32,
    float_count: usize,
) -> RrskinStatus {
    guard(|| {
        // SAFETY: `transforms` as the function's contract requires.
        let bones = unsafe { affines(transforms, float_count)? };
        Ok(crowd_entry(crowd)?
            .write()
            .set_bones(frame as usize, bones)?)
    })
}

/// Sets one character's bone transforms of frame slot `frame`: `float_count` = bones x 12.
///
/// # Safety
/// `transforms` is NULL or points to `float_count` readable floats (4-byte aligned) that no
/// other thread writes during the call.
#[no_mangle]
pub unsafe extern "C" fn rrskin_crowd_set_character_bones(
    crowd: RrskinCrowd,
    frame: u32,
    character: u32,
    transforms: *const f32,
    float_count: usize,
) -> RrskinStatus {
    guard(|| {
        // SAFETY: `transforms` as the function's contract requires.
        let bones = unsafe { affines(transforms, float_count)? };
        Ok(crowd_entry(crowd)?.write().set_character_bones(
            frame as usize,
            character as usize,
            bones,
        )?)
    })
}

/// Sets every character's up vector of frame slot `frame`: `float_count` = characters x 3, each
/// in the character's bones' frame, the direction opposite to gravity (its length gravity's
/// strength against the training poses'), for characters tilted by their object transform
/// rather than their root bone. A crowd starts with the model's up
/// (`rrskin_model_info.up`); a model without `proxy_corrective_gravity` reads none.
///
/// # Safety
/// `ups` is NULL or points to `float_count` readable floats that no other thread writes during
/// the call.
#[no_mangle]
pub unsafe extern "C" fn rrskin_crowd_set_ups(
    crowd: RrskinCrowd,
    frame: u32,
    ups: *const f32,
    float_count: usize,
) -> RrskinStatus {
    guard(|| {
        // SAFETY: `ups` as the function's contract requires.
        let ups = unsafe { vectors3(ups, float_count)? };
        Ok(crowd_entry(crowd)?.write().set_ups(frame as usize, ups)?)
    })
}

/// Sets one character's up vector of frame slot `frame` (as `rrskin_crowd_set_ups`).
///
/// # Safety
/// `up` is NULL or points to 3 readable floats.
#[no_mangle]
pub unsafe extern "C" fn rrskin_crowd_set_character_up(
    crowd: RrskinCrowd,
    frame: u32,
    character: u32,
    up: *const f32,
) -> RrskinStatus {
    guard(|| {
        // SAFETY: `up` as the function's contract requires.
        let up = unsafe { vectors3(up, 3)? }[0];
        let (frame, character) = (frame as usize, character as usize);
        Ok(crowd_entry(crowd)?
            .write()
            .set_character_up(frame, character, up)?)
    })
}

/// The output buffers of frame slot `frame` as last recorded (which positions buffer it
/// writes alternates with previous positions: ask after recording the frame), to draw from.
///
/// # Safety
/// `out` is NULL or points to writable memory for one `rrskin_crowd_output`.
#[no_mangle]
pub unsafe extern "C" fn rrskin_crowd_get_output(
    crowd: RrskinCrowd,
    frame: u32,
    out: *mut RrskinCrowdOutput,
) -> RrskinStatus {
    guard(|| {
        use vk::Handle;
        let o = crowd_entry(crowd)?.read().output(frame as usize)?;
        let raw = |b: Option<vk::Buffer>| b.map_or(0, |b| b.as_raw());
        let output = RrskinCrowdOutput {
            positions: o.positions.as_raw(),
            previous_positions: raw(o.previous_positions),
            normals: o.normals.as_raw(),
            bounds: raw(o.bounds),
            tangents: raw(o.tangents),
            offset: o.offset,
            vertex_stride: o.vertex_stride,
            character_stride: o.character_stride,
            bounds_stride: crate::vk::BOUNDS_STRIDE,
            tangent_stride: crate::vk::TANGENT_STRIDE,
            tangent_character_stride: o.tangent_character_stride,
        };
        // SAFETY: `out` as the function's contract requires.
        unsafe { put(out, output, "out") }
    })
}

/// Copies the outputs to host memory: `float_count` = characters x vertices x 3 for each of
/// `positions` and `normals` (either may be NULL to skip it). Submits and waits: for tools and
/// tests, not the per-frame path.
///
/// # Safety
/// `positions` and `normals` are each NULL or point to `float_count` writable floats (4-byte
/// aligned), not overlapping each other.
#[no_mangle]
pub unsafe extern "C" fn rrskin_crowd_read_back(
    crowd: RrskinCrowd,
    positions: *mut f32,
    normals: *mut f32,
    float_count: usize,
) -> RrskinStatus {
    guard(|| {
        let entry = crowd_entry(crowd)?;
        let c = entry.read();
        let expected = c.character_count() * c.model().vertex_count() * 3;
        if float_count != expected {
            return Err(Failure::from(Error::WrongLength {
                what: "read-back floats",
                expected,
                actual: float_count,
            }));
        }
        let out = c.read_back()?;
        for (dst, src) in [(positions, &out.positions), (normals, &out.normals)] {
            if !dst.is_null() {
                // SAFETY: non-null, room for `float_count` floats (the function's contract).
                let dst = unsafe { std::slice::from_raw_parts_mut(dst, float_count) };
                dst.copy_from_slice(src.as_flattened());
            }
        }
        Ok(())
    })
}

/// Copies the tangents to host memory: `float_count` = characters x vertices x 4. Submits and
/// waits: for tools and tests. RRSKIN_STATUS_ERROR_NOT_ENABLED for a crowd created without
/// tangents.
///
/// # Safety
/// `tangents` is NULL or points to `float_count` writable floats (4-byte aligned).
#[no_mangle]
pub unsafe extern "C" fn rrskin_crowd_read_back_tangents(
    crowd: RrskinCrowd,
    tangents: *mut f32,
    float_count: usize,
) -> RrskinStatus {
    guard(|| {
        let entry = crowd_entry(crowd)?;
        let c = entry.read();
        if !c.has_tangents() {
            return Err(Failure::from(Error::NotEnabled {
                what: "tangents (create the crowd with rrskin_crowd_options.tangents)",
            }));
        }
        let expected = c.character_count() * c.model().vertex_count() * 4;
        if float_count != expected {
            return Err(Failure::from(Error::WrongLength {
                what: "read-back tangent floats",
                expected,
                actual: float_count,
            }));
        }
        if tangents.is_null() {
            return Err(Failure::null("tangents"));
        }
        let out = c.read_back()?;
        // SAFETY: non-null, room for `float_count` floats (the function's contract).
        let dst = unsafe { std::slice::from_raw_parts_mut(tangents, float_count) };
        dst.copy_from_slice(out.tangents.as_flattened());
        Ok(())
    })
}

/// Reads frame slot `frame`'s boxes from host-visible memory, once the frame's submission
/// completed: `float_count` = characters x 6 floats (min x, y, z, max x, y, z per character).
/// RRSKIN_STATUS_ERROR_NOT_ENABLED for a crowd created without bounds.
///
/// # Safety
/// `boxes` is NULL or points to `float_count` writable floats (4-byte aligned).
#[no_mangle]
pub unsafe extern "C" fn rrskin_crowd_read_bounds(
    crowd: RrskinCrowd,
    frame: u32,
    boxes: *mut f32,
    float_count: usize,
) -> RrskinStatus {
    guard(|| {
        let entry = crowd_entry(crowd)?;
        let mut c = entry.write();
        let expected = c.character_count() * 6;
        if float_count != expected {
            return Err(Failure::from(Error::WrongLength {
                what: "bounds floats",
                expected,
                actual: float_count,
            }));
        }
        if boxes.is_null() {
            return Err(Failure::null("boxes"));
        }
        // SAFETY: non-null, room for `float_count` floats (the function's contract).
        let dst = unsafe { std::slice::from_raw_parts_mut(boxes, float_count) };
        // An Aabb is 6 floats (repr(C)): the caller's array is the boxes.
        let dst: &mut [Aabb] = bytemuck::cast_slice_mut(dst);
        Ok(c.read_bounds(frame as usize, dst)?)
    })
}

#[no_mangle]
pub extern "C" fn rrskin_crowd_destroy(crowd: RrskinCrowd) -> RrskinStatus {
    guard(|| registry().crowds.remove(crowd.id).map(drop))
}

/// The crowds of a batch, each listed once: a crowd listed twice would take its lock twice
/// (the batch refuses crowds of another context itself).
fn crowds_of(handles: &[RrskinCrowd]) -> Result<Vec<Arc<CrowdEntry>>, Failure> {
    let reg = registry();
    let mut entries: Vec<Arc<CrowdEntry>> = Vec::with_capacity(handles.len());
    for handle in handles {
        let entry = reg.crowds.get(handle.id)?;
        if entries.iter().any(|e| Arc::ptr_eq(e, entry)) {
            return Err(Failure::from(Error::Mismatch {
                what: "a crowd listed twice in one frame",
            }));
        }
        entries.push(entry.clone());
    }
    Ok(entries)
}

/// Runs `f` on the context's batch with `crowds` read-locked, in the order given (the batch's
/// lock first: the only place that holds several crowd locks, so no two threads wait on each
/// other).
fn with_batch<R>(
    context: RrskinContext,
    crowds: &[RrskinCrowd],
    f: impl FnOnce(&mut Batch, &[&Crowd]) -> crate::Result<R>,
) -> Result<R, Failure> {
    let entry = context_entry(context)?;
    let entries = crowds_of(crowds)?;
    let mut batch = entry.batch();
    let guards: Vec<_> = entries.iter().map(|e| e.read()).collect();
    let list: Vec<&Crowd> = guards.iter().map(|g| &**g).collect();
    Ok(f(&mut batch, &list)?)
}

/// Records frame slot `frame` (0 to F - 1 of every crowd) of all passes of `count` crowds into
/// the engine's command buffer (VkCommandBuffer, recording, outside a render pass, on the
/// context's queue family). The recorded commands end with a barrier making the outputs visible
/// to vertex input, transfer, compute and host reads.
///
/// # Safety
/// `crowds` is NULL or points to `count` readable `rrskin_crowd` handles. `command_buffer` is
/// NULL or a VkCommandBuffer of the context's device, in the recording state, that no other
/// thread records into during the call; the engine submits it, and keeps the crowds alive and
/// the frame slot's bones unchanged until it completed.
#[no_mangle]
pub unsafe extern "C" fn rrskin_crowds_record(
    context: RrskinContext,
    command_buffer: *mut c_void,
    frame: u32,
    crowds: *const RrskinCrowd,
    count: u32,
) -> RrskinStatus {
    guard(|| {
        if command_buffer.is_null() {
            return Err(Failure::null("command_buffer"));
        }
        // SAFETY: `crowds` as the function's contract requires.
        let handles = unsafe { slice(crowds, count as usize, "crowds")? };
        use vk::Handle;
        let cmd = vk::CommandBuffer::from_raw(command_buffer as u64);
        with_batch(context, handles, |batch, list| {
            batch.record(cmd, frame as usize, list)
        })
    })
}

/// Records frame slot `frame` of all passes of `count` crowds, submits them and waits
/// (headless path).
///
/// # Safety
/// `crowds` is NULL or points to `count` readable `rrskin_crowd` handles.
#[no_mangle]
pub unsafe extern "C" fn rrskin_crowds_run(
    context: RrskinContext,
    frame: u32,
    crowds: *const RrskinCrowd,
    count: u32,
) -> RrskinStatus {
    guard(|| {
        // SAFETY: `crowds` as the function's contract requires.
        let handles = unsafe { slice(crowds, count as usize, "crowds")? };
        with_batch(context, handles, |batch, list| {
            batch.run(frame as usize, list)
        })
    })
}

/// GPU time per pass of the context's frame slot `frame` as last recorded (after
/// `rrskin_crowds_record`, only once the command buffer completed; RRSKIN_ERROR_NOT_READY
/// otherwise).
///
/// # Safety
/// `out` is NULL or points to writable memory for one `rrskin_pass_timings`.
#[no_mangle]
pub unsafe extern "C" fn rrskin_context_get_timings(
    context: RrskinContext,
    frame: u32,
    out: *mut RrskinPassTimings,
) -> RrskinStatus {
    guard(|| {
        let t = context_entry(context)?.batch().timings(frame as usize)?;
        let timings = RrskinPassTimings {
            predict_ms: t.predict_ms,
            blend_ms: t.product_ms,
            proxy_correctives_ms: t.proxy_correctives_ms,
            skin_ms: t.skin_ms,
            normals_ms: t.normals_ms,
            tangents_ms: t.tangents_ms,
        };
        // SAFETY: `out` as the function's contract requires.
        unsafe { put(out, timings, "out") }
    })
}
