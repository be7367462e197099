//! Models: loaded from a file or from memory and uploaded to a context, asked for their sizes,
//! destroyed.

use super::guard::{guard, put, slice, utf8_path, Failure};
use super::handles::{context_entry, model_entry, registry, ModelEntry};
use super::types::{RrskinContext, RrskinModel, RrskinModelInfo, RrskinStatus};
use crate::model::Model;
use crate::vk::GpuModel;
use std::ffi::c_char;
use std::sync::Arc;

/// Uploads `model` to `context` and hands out its handle.
///
/// # Safety
/// `out` is NULL or valid for writing one `RrskinModel`.
unsafe fn add_model(
    context: RrskinContext,
    model: Model,
    out: *mut RrskinModel,
) -> Result<(), Failure> {
    if out.is_null() {
        return Err(Failure::null("out"));
    }
    let gpu = GpuModel::new(&context_entry(context)?.context, &model)?;
    let id = registry()
        .models
        .insert(Arc::new(ModelEntry { model, gpu }));
    // SAFETY: `out` as the function's contract requires.
    unsafe { put(out, RrskinModel { id }, "out") }
}

/// Loads and validates a `.rrs` file (UTF-8 path) and uploads it to `context`.
///
/// # Safety
/// `path` is NULL or a NUL-terminated string readable during the call; `out` is NULL or points
/// to writable memory for one `rrskin_model`.
#[no_mangle]
pub unsafe extern "C" fn rrskin_model_load_file(
    context: RrskinContext,
    path: *const c_char,
    out: *mut RrskinModel,
) -> RrskinStatus {
    guard(|| {
        // SAFETY: `path` as the function's contract requires.
        let model = Model::load(unsafe { utf8_path(path) }?)?;
        // SAFETY: `out` as the function's contract requires.
        unsafe { add_model(context, model, out) }
    })
}

/// Validates a `.rrs` image of `size` bytes and uploads it to `context` (the bytes are copied).
///
/// # Safety
/// `data` is NULL or points to `size` readable bytes; `out` is NULL or points to writable memory
/// for one `rrskin_model`.
#[no_mangle]
pub unsafe extern "C" fn rrskin_model_load_memory(
    context: RrskinContext,
    data: *const u8,
    size: usize,
    out: *mut RrskinModel,
) -> RrskinStatus {
    guard(|| {
        // SAFETY: `data` and `out` as the function's contract requires.
        unsafe { add_model(context, Model::from_bytes(slice(data, size, "data")?)?, out) }
    })
}

/// The model's sizes.
///
/// # Safety
/// `out` is NULL or points to writable memory for one `rrskin_model_info`.
#[no_mangle]
pub unsafe extern "C" fn rrskin_model_get_info(
    model: RrskinModel,
    out: *mut RrskinModelInfo,
) -> RrskinStatus {
    guard(|| {
        let entry = model_entry(model)?;
        let m = &entry.model;
        let sizes = crate::vk::ModelSizes::of(m);
        let info = RrskinModelInfo {
            vertices: m.vertex_count() as u32,
            triangles: m.triangle_count() as u32,
            bones: m.bone_count() as u32,
            proxies: m.proxy_count() as u32,
            influences: m.influences() as u32,
            blend_columns: sizes.product_columns as u32,
            tangents: u32::from(m.has_tangents()),
            correctives: m.corrective_count() as u32,
            corrective_drivers: m.corrective_driver_count() as u32,
            proxy_correctives: sizes.proxy_correctives as u32,
            proxy_corrective_drivers: sizes.proxy_corrective_drivers as u32,
            proxy_corrective_kernels: sizes.proxy_corrective_kernels as u32,
            proxy_corrective_linear: u32::from(sizes.proxy_corrective_linear),
            proxy_corrective_gravity: u32::from(sizes.proxy_corrective_gravity),
            up: m.up().unwrap_or_default(),
            normal_fan_entries: sizes.normal_fans as u32,
            key_words: sizes.key_words as u32,
        };
        // SAFETY: `out` as the function's contract requires.
        unsafe { put(out, info, "out") }
    })
}

/// Destroys a model handle; crowds made from it keep working until destroyed themselves.
#[no_mangle]
pub extern "C" fn rrskin_model_destroy(model: RrskinModel) -> RrskinStatus {
    guard(|| registry().models.remove(model.id).map(drop))
}
