//! The CPU palette through the C ABI ([`crate::palette`]): for an engine that skins with its
//! own shaders. No Vulkan. A palette model is a generational handle like the runtime's (a
//! destroyed or never-made one gives `RRSKIN_STATUS_ERROR_INVALID_HANDLE`); its registry is a
//! reader-writer lock held only to find the model, so threads run palettes of one model (or
//! many) in parallel, and a model destroyed while a call runs lives until that call returns.

use super::guard::{guard, put, slice, utf8_path, vectors3, Failure};
use super::handles::Slots;
use super::types::RrskinStatus;
use crate::model::Model;
use crate::palette::Palette;
use crate::predict::Affine;
use std::ffi::c_char;
use std::sync::{Arc, RwLock};

/// A model loaded for CPU palette evaluation. Immutable: every call may run on one from many
/// threads at once.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RrskinPaletteModel {
    pub id: u64,
}

static PALETTES: RwLock<Slots<Arc<Palette>>> = RwLock::new(Slots::new(4));

/// The palette behind a handle, found under the registry's read lock and used after it.
fn palette_of(model: RrskinPaletteModel) -> Result<Arc<Palette>, Failure> {
    let slots = PALETTES
        .read()
        .unwrap_or_else(|poisoned| poisoned.into_inner());
    slots.get(model.id).cloned()
}

/// What an engine skins with, borrowed from a palette model (valid until it is destroyed).
/// Vertex a's position is `M_a * (x_a, 1)`: the blend of 3x4 row-major palette entries
/// `M_a = sum over k < influences of weights[a*K + k] * palette[joints[a*K + k]]`, and the
/// corrected rest position
/// `x_a = rest_positions[a] + sum over n < correctives of w[n] * corrective_targets[n*V + a]`,
/// w the character's corrective weights (`rrskin_palette_compute_corrective_weights`; no sum
/// without correctives).
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct RrskinPaletteSkin {
    /// V.
    pub vertices: u32,
    pub triangles: u32,
    /// J: bone transforms in.
    pub bones: u32,
    /// P: proxies at the front of the palette (0 for a plain linear-blend-skinning model).
    pub proxies: u32,
    /// P + J: palette entries out.
    pub palette_entries: u32,
    /// K, 4 or 8.
    pub influences: u32,
    /// V x K palette indices (< P a proxy, P + b bone b).
    pub joints: *const u32,
    /// V x K weights, >= 0, summing to 1 per vertex.
    pub weights: *const f32,
    /// V x 3.
    pub rest_positions: *const f32,
    /// V x 3 unit normals of the rest mesh (area-weighted, welded seams shared): the shader
    /// takes each through the cofactor of the vertex's blended 3x3, `n.x (c1 x c2) + n.y (c2 x
    /// c0) + n.z (c0 x c1)` for its columns c, normalised (the runtime's transformed normals).
    pub rest_normals: *const f32,
    /// V x 4 (xyz unit, w = +-1 as glTF's TANGENT), or NULL for a model without rest tangents.
    pub rest_tangents: *const f32,
    /// T x 3 vertex indices.
    pub triangle_indices: *const u32,
    /// N, the pose-space corrective targets (0 without correctives; at most 64).
    pub correctives: u32,
    /// N x V x 3 rest-space deltas, target-major (as glTF morph targets), or NULL without
    /// correctives.
    pub corrective_targets: *const f32,
}

/// Loads and validates a `.rrs` file (UTF-8 path) for CPU palette evaluation. Destroy with
/// `rrskin_palette_model_destroy`.
///
/// # Safety
/// `path` is NULL or a NUL-terminated string readable during the call; `out` is NULL or points
/// to writable memory for one `rrskin_palette_model`.
#[no_mangle]
pub unsafe extern "C" fn rrskin_palette_model_load_file(
    path: *const c_char,
    out: *mut RrskinPaletteModel,
) -> RrskinStatus {
    guard(|| {
        // SAFETY: `path` and `out` as the function's contract requires.
        unsafe { give(Model::load(utf8_path(path)?)?, out) }
    })
}

/// Validates a `.rrs` image of `size` bytes for CPU palette evaluation (the bytes are copied).
///
/// # Safety
/// `data` is NULL or points to `size` readable bytes; `out` is NULL or points to writable memory
/// for one `rrskin_palette_model`.
#[no_mangle]
pub unsafe extern "C" fn rrskin_palette_model_load_memory(
    data: *const u8,
    size: usize,
    out: *mut RrskinPaletteModel,
) -> RrskinStatus {
    // SAFETY: `data` and `out` as the function's contract requires.
    guard(|| unsafe { give(Model::from_bytes(slice(data, size, "data")?)?, out) })
}

/// # Safety
/// `out` is NULL or valid for writing one `rrskin_palette_model`.
unsafe fn give(model: Model, out: *mut RrskinPaletteModel) -> Result<(), Failure> {
    if out.is_null() {
        return Err(Failure::null("out"));
    }
    let palette = Arc::new(Palette::new(model)?);
    let mut slots = PALETTES
        .write()
        .unwrap_or_else(|poisoned| poisoned.into_inner());
    let model = RrskinPaletteModel {
        id: slots.insert(palette),
    };
    // SAFETY: non-null, and valid for the write by the function's contract.
    unsafe { put(out, model, "out") }
}

/// The model's sizes and skin.
///
/// # Safety
/// `out` is NULL or points to writable memory for one
/// `rrskin_palette_skin`.
#[no_mangle]
pub unsafe extern "C" fn rrskin_palette_model_get_skin(
    model: RrskinPaletteModel,
    out: *mut RrskinPaletteSkin,
) -> RrskinStatus {
    guard(|| {
        let palette = palette_of(model)?;
        let (m, skin) = (palette.model(), palette.skin());
        let info = RrskinPaletteSkin {
            vertices: m.vertex_count() as u32,
            triangles: m.triangle_count() as u32,
            bones: m.bone_count() as u32,
            proxies: m.proxy_count() as u32,
            palette_entries: palette.len() as u32,
            influences: skin.influences as u32,
            joints: skin.indices.as_ptr(),
            weights: skin.weights.as_ptr(),
            rest_positions: skin.rest_positions.as_flattened().as_ptr(),
            rest_normals: skin.rest_normals.as_flattened().as_ptr(),
            rest_tangents: match skin.rest_tangents {
                [] => std::ptr::null(),
                t => t.as_flattened().as_ptr(),
            },
            triangle_indices: skin.triangles.as_flattened().as_ptr(),
            correctives: skin.correctives as u32,
            corrective_targets: match skin.corrective_targets {
                [] => std::ptr::null(),
                t => t.as_flattened().as_ptr(),
            },
        };
        // SAFETY: `out` as the function's contract requires.
        unsafe { put(out, info, "out") }
    })
}

/// N, the pose-space corrective weights of a character (0 for a model without correctives):
/// the floats per character `rrskin_palette_compute_corrective_weights` writes.
///
/// # Safety
/// `out` is NULL or points to writable memory for one
/// `uint32_t`.
#[no_mangle]
pub unsafe extern "C" fn rrskin_palette_model_get_corrective_count(
    model: RrskinPaletteModel,
    out: *mut u32,
) -> RrskinStatus {
    guard(|| {
        let palette = palette_of(model)?;
        // SAFETY: `out` as the function's contract requires.
        unsafe { put(out, palette.corrective_count() as u32, "out") }
    })
}

/// The model's up (3 floats, unit, in its bones' frame) where its proxy correctives see gravity,
/// so that `rrskin_palette_compute_with_ups` reads up vectors; zeros where they do not.
///
/// # Safety
/// `out` is NULL or points to 3 writable floats.
#[no_mangle]
pub unsafe extern "C" fn rrskin_palette_model_get_up(
    model: RrskinPaletteModel,
    out: *mut f32,
) -> RrskinStatus {
    guard(|| {
        let up = palette_of(model)?.model().up().unwrap_or_default();
        // SAFETY: `out` as the function's contract requires (`[f32; 3]` has the alignment of
        // `f32`).
        unsafe { put(out.cast::<[f32; 3]>(), up, "out") }
    })
}

/// The pose-space corrective weights of `characters` characters on the calling thread: `bones`
/// as `rrskin_palette_compute`'s (`bone_floats` = characters * J * 12), `out` characters x N
/// floats (`out_floats`; N from `rrskin_palette_model_get_corrective_count`), each character's
/// N weights of the skin's `corrective_targets`. For a model without correctives N = 0 and
/// `out_floats` must be 0 (`out` may then be NULL). Allocates nothing; takes only the handle
/// registry's read lock, to find the model.
///
/// # Safety
/// `bones` is NULL or points to `bone_floats`
/// readable floats; `out` is NULL or points to `out_floats` writable floats; the two do not
/// overlap.
#[no_mangle]
pub unsafe extern "C" fn rrskin_palette_compute_corrective_weights(
    model: RrskinPaletteModel,
    bones: *const f32,
    bone_floats: usize,
    out: *mut f32,
    out_floats: usize,
) -> RrskinStatus {
    guard(|| {
        let palette = palette_of(model)?;
        let count = transforms(bone_floats, "bone floats")?;
        // SAFETY: `bones` points to `bone_floats` floats, as the caller guarantees.
        let bones = unsafe { slice(bones.cast::<Affine>(), count, "bones") }?;
        let out = match (out.is_null(), out_floats) {
            (_, 0) => &mut [][..],
            (true, _) => return Err(Failure::null("out")),
            // SAFETY: non-null, `out_floats` writable floats not overlapping `bones`, as the
            // caller guarantees.
            (false, n) => unsafe { std::slice::from_raw_parts_mut(out, n) },
        };
        Ok(palette.corrective_weights_batch(bones, out)?)
    })
}

/// The palette of `characters` characters on the calling thread: `bones` is characters x J
/// transforms (`bone_floats` = characters * J * 12 floats, 3x4 row-major, world space, relative
/// to the rest pose), `out` characters x (P + J) palette matrices (`out_floats` floats, same
/// layout), proxies first (corrected by the model's proxy correctives where it has them:
/// nothing more to apply). Allocates nothing (after a thread's first call for a model of that
/// size) and takes only the handle registry's read lock, to find the model: call it from an
/// engine's worker threads on disjoint characters.
///
/// # Safety
/// `bones` is NULL or points to `bone_floats`
/// readable floats; `out` is NULL or points to `out_floats` writable floats; the two do not
/// overlap.
#[no_mangle]
pub unsafe extern "C" fn rrskin_palette_compute(
    model: RrskinPaletteModel,
    bones: *const f32,
    bone_floats: usize,
    out: *mut f32,
    out_floats: usize,
) -> RrskinStatus {
    let upright = (std::ptr::null(), 0);
    // SAFETY: the pointers as the function's contract requires.
    guard(|| unsafe { compute(model, (bones, bone_floats), upright, (out, out_floats), 1) })
}

/// `rrskin_palette_compute` split over `threads` threads it starts and joins (0: one per
/// core), for an engine without a job system of its own. Starting threads allocates.
///
/// # Safety
/// As `rrskin_palette_compute`.
#[no_mangle]
pub unsafe extern "C" fn rrskin_palette_compute_parallel(
    model: RrskinPaletteModel,
    bones: *const f32,
    bone_floats: usize,
    out: *mut f32,
    out_floats: usize,
    threads: u32,
) -> RrskinStatus {
    let (upright, threads) = ((std::ptr::null(), 0), threads as usize);
    // SAFETY: the pointers as the function's contract requires.
    guard(|| unsafe {
        compute(
            model,
            (bones, bone_floats),
            upright,
            (out, out_floats),
            threads,
        )
    })
}

/// `rrskin_palette_compute_parallel` with each character's up vector in its bones' frame:
/// `ups` characters x 3 floats (`up_floats`), the direction opposite to gravity, its length
/// gravity's strength against the training poses' (for a character tilted by its object
/// transform rather than its root bone). NULL with `up_floats` = 0: the model's up
/// (`rrskin_palette_model_get_up`). Only a model whose proxy correctives see gravity reads them;
/// `threads` = 1 runs on the calling thread.
///
/// # Safety
/// As `rrskin_palette_compute`; `ups` is NULL or points to `up_floats` readable floats.
#[no_mangle]
pub unsafe extern "C" fn rrskin_palette_compute_with_ups(
    model: RrskinPaletteModel,
    bones: *const f32,
    bone_floats: usize,
    ups: *const f32,
    up_floats: usize,
    out: *mut f32,
    out_floats: usize,
    threads: u32,
) -> RrskinStatus {
    let (bones, ups, out) = ((bones, bone_floats), (ups, up_floats), (out, out_floats));
    // SAFETY: the pointers as the function's contract requires.
    guard(|| unsafe { compute(model, bones, ups, out, threads as usize) })
}

/// # Safety
/// As `rrskin_palette_compute_with_ups`: each pointer NULL or to its count of floats.
unsafe fn compute(
    model: RrskinPaletteModel,
    (bones, bone_floats): (*const f32, usize),
    (ups, up_floats): (*const f32, usize),
    (out, out_floats): (*mut f32, usize),
    threads: usize,
) -> Result<(), Failure> {
    let palette = palette_of(model)?;
    // SAFETY: `ups` as the caller guarantees.
    let ups = unsafe { vectors3(ups, up_floats) }?;
    let (count, entries) = (
        transforms(bone_floats, "bone floats")?,
        transforms(out_floats, "palette floats")?,
    );
    // SAFETY: `bones` points to `bone_floats` floats, 12 to a transform (`[f32; 12]` has the
    // alignment of `f32`), as the caller guarantees.
    let bones = unsafe { slice(bones.cast::<Affine>(), count, "bones") }?;
    if out.is_null() {
        return Err(Failure::null("out"));
    }
    // SAFETY: non-null, `out_floats` writable floats not overlapping `bones`, as the caller
    // guarantees.
    let out = unsafe { std::slice::from_raw_parts_mut(out.cast::<Affine>(), entries) };
    Ok(palette.compute_batch_parallel(bones, ups, out, threads)?)
}

/// Transforms in `floats` floats: whole 3x4 matrices only.
fn transforms(floats: usize, what: &'static str) -> Result<usize, Failure> {
    if floats % 12 != 0 {
        return Err(crate::Error::WrongLength {
            what,
            expected: floats.div_ceil(12) * 12,
            actual: floats,
        }
        .into());
    }
    Ok(floats / 12)
}

/// Destroys a palette model handle; a call running on it on another thread finishes first (it
/// holds the model), and the skin that `rrskin_palette_model_get_skin` lent is invalid after.
#[no_mangle]
pub extern "C" fn rrskin_palette_model_destroy(model: RrskinPaletteModel) -> RrskinStatus {
    guard(|| {
        let mut slots = PALETTES
            .write()
            .unwrap_or_else(|poisoned| poisoned.into_inner());
        slots.remove(model.id).map(drop)
    })
}
