//! rrskin: the C ABI of the rrskin runtime (real-time enveloping with rotational regression).
//! `include/rrskin.h` is generated from `src/ffi.rs` by cbindgen: do not edit it
//! (`RRSKIN_BLESS=1 cargo test --test c_abi` regenerates it). Its preamble is the conventions
//! below followed by the crate's contract (`src/lib.rs`, "## Contract"); `tests/c_abi.rs` puts
//! them together.
//!
//! ## Conventions of every function
//!
//! - Status: it returns an `rrskin_status` (`int32_t`); `RRSKIN_STATUS_OK` is 0. After a
//!   failure, `rrskin_last_error()` returns the calling thread's message (valid until the
//!   thread's next rrskin call). It never unwinds or aborts: every body runs under
//!   `catch_unwind`, and an internal fault gives `RRSKIN_STATUS_ERROR_PANIC`.
//! - Handles: `{ uint64_t id }` values (0 is never valid). `rrskin_*_create` and
//!   `rrskin_*_load_*` give handles the caller destroys with the matching `rrskin_*_destroy`,
//!   in any order. Using a destroyed handle is the caller's error, but it is caught: slots
//!   carry a generation, so a stale handle gives `RRSKIN_STATUS_ERROR_INVALID_HANDLE` instead
//!   of touching freed memory. Borrowed Vulkan objects (engine devices, command buffers) stay
//!   the engine's.
//! - Pointers: a null one gives `RRSKIN_STATUS_ERROR_NULL_POINTER`; array lengths are passed
//!   explicitly and checked (`RRSKIN_STATUS_ERROR_WRONG_LENGTH`). Every function that takes a
//!   pointer is `unsafe`: what a non-null pointer must be is what the library cannot check,
//!   and its `# Safety` section (copied into the header) says it. Pointers are used only
//!   during the call, never kept.
//! - Threads: any function may be called from any thread, and calls on different objects run
//!   concurrently: a global lock covers only the lookup of a handle. Calls on one object are
//!   serialised by that object's own lock: on a crowd, those that change it
//!   (`rrskin_crowd_set_bones`, `rrskin_crowd_set_character_bones`, `rrskin_crowd_read_bounds`)
//!   exclude every other call on it, while reads (`rrskin_crowd_get_output`,
//!   `rrskin_crowd_read_back`) and recordings share it; on a context, recordings and runs
//!   (`rrskin_crowds_record`, `rrskin_crowds_run`, `rrskin_context_get_timings`) take turns,
//!   since they share its query pool. A model is immutable once loaded. Externally
//!   synchronised, as Vulkan says it: the engine's command buffer in `rrskin_crowds_record`
//!   (no other thread records into it during the call), and the engine's queue while the
//!   runtime submits to it (the contract's first duty). The Vulkan rules are the contract's:
//!   no submitted work reading a crowd may be executing when its bones are set or it is
//!   destroyed.
//! - Device loss: once any call sees `VK_ERROR_DEVICE_LOST`, it and every later call on that
//!   context or on a model or crowd of it returns `RRSKIN_STATUS_ERROR_DEVICE_LOST` at once,
//!   submitting nothing; the `rrskin_*_destroy` calls still work, and a new context can be
//!   created. Out-of-memory results of any Vulkan call are `RRSKIN_STATUS_ERROR_ALLOCATION`. A
//!   failed creation leaves no Vulkan object behind and the context usable.

mod palette;

pub use palette::*;

use crate::error::Error;
use crate::model::Model;
use crate::normals::NormalMode;
use crate::predict::Affine;
use crate::vk::{
    ash::vk, Aabb, Batch, Context, ContextDesc, Crowd, CrowdOptions, EngineDevice, GpuModel,
};
use std::cell::RefCell;
use std::ffi::{c_char, c_void, CStr, CString};
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::{Arc, Mutex, MutexGuard, RwLock, RwLockReadGuard, RwLockWriteGuard};

/// Status codes (fixed width: `int32_t`).
#[repr(i32)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RrskinStatus {
    Ok = 0,
    ErrorNullPointer = 1,
    ErrorInvalidHandle = 2,
    ErrorWrongLength = 3,
    ErrorOutOfRange = 4,
    ErrorNonFinite = 5,
    ErrorBadModel = 6,
    ErrorIo = 7,
    ErrorLoader = 8,
    ErrorVulkan = 9,
    ErrorNoDevice = 10,
    ErrorMissingLayer = 11,
    ErrorAllocation = 12,
    ErrorDeviceLimit = 13,
    ErrorNotReady = 14,
    ErrorMismatch = 15,
    ErrorInvalidArgument = 16,
    ErrorPanic = 17,
    /// An optional output asked for from a crowd created without it.
    ErrorNotEnabled = 18,
    /// A Vulkan function the runtime calls is NULL from the engine's `vkGetInstanceProcAddr`.
    ErrorMissingFunction = 19,
    /// The model has no data for what was asked (tangents of a model without rest tangents:
    /// trained from a mesh without UVs; the engine computes its own or draws without).
    ErrorNotInModel = 20,
    /// The Vulkan device was lost (`VK_ERROR_DEVICE_LOST`): every call on the context and its
    /// models and crowds returns this from then on; destroy them and create a new context.
    ErrorDeviceLost = 21,
}

/// A Vulkan context (headless, or wrapping an engine's device).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RrskinContext {
    pub id: u64,
}

/// A model uploaded to one context.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RrskinModel {
    pub id: u64,
}

/// C characters of one model.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RrskinCrowd {
    pub id: u64,
}

/// An engine's Vulkan objects, borrowed by `rrskin_context_create_from_engine` (never destroyed
/// by rrskin). Dispatchable handles are passed as pointers.
#[repr(C)]
pub struct RrskinEngineDevice {
    /// The engine's `vkGetInstanceProcAddr` (PFN_vkGetInstanceProcAddr).
    pub get_instance_proc_addr: *const c_void,
    /// VkInstance
    pub instance: *mut c_void,
    /// VkPhysicalDevice
    pub physical_device: *mut c_void,
    /// VkDevice
    pub device: *mut c_void,
    pub queue_family_index: u32,
    /// VkQueue (of `queue_family_index`; must support compute)
    pub queue: *mut c_void,
}

#[repr(C)]
#[derive(Debug, Clone, Copy, Default)]
pub struct RrskinModelInfo {
    pub vertices: u32,
    pub triangles: u32,
    pub bones: u32,
    /// P; 0 for a plain linear-blend-skinning model.
    pub proxies: u32,
    /// K: 4 or 8.
    pub influences: u32,
    /// Stored columns of the model's block-sparse C1|C2 (the sum over proxies of the columns
    /// any of a proxy's 4 rows touches), 0 where the runtime keeps it dense: what
    /// `rrskin_model_get_info` reports, needed for `rrskin_query_memory`'s model bytes.
    pub blend_columns: u32,
    /// Nonzero: the model carries rest tangents, so its crowds can output tangents.
    pub tangents: u32,
    /// N, the pose-space corrective targets (0 without correctives; at most 64).
    pub correctives: u32,
    /// D, the corrective driver bones (0 without correctives).
    pub corrective_drivers: u32,
    /// E, the proxies corrected by proxy correctives (0 without them; at most `proxies`).
    pub proxy_correctives: u32,
    /// The drivers of all corrected proxies together (0 without proxy correctives).
    pub proxy_corrective_drivers: u32,
    /// C, the proxy correctives' kernel centres per joint (0 without kernels; at most 256).
    pub proxy_corrective_kernels: u32,
    /// Nonzero: the proxy correctives have the 9 linear features per driver.
    pub proxy_corrective_linear: u32,
    /// Entries of the 1-ring fans the recomputed-normals pass reads (about 3 x triangles +
    /// 2 x vertices for a closed mesh): what `rrskin_model_get_info` reports, needed for
    /// `rrskin_query_memory`'s model bytes.
    pub normal_fan_entries: u32,
}

/// How a crowd is made (`rrskin_crowd_create_with_options`); `rrskin_crowd_create` uses
/// 2 frames in flight and no optional output.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default)]
pub struct RrskinCrowdOptions {
    /// F, 1 to 4: the crowd keeps F slots of its bone transforms and bounds, so that frame slot
    /// f is set and recorded while the other F - 1 frames still execute.
    pub frames_in_flight: u32,
    /// Nonzero: keep last frame's positions in a second buffer (the two alternate, no copy).
    pub previous_positions: u32,
    /// Nonzero: write each character's axis-aligned box every frame.
    pub bounds: u32,
    /// Nonzero: write a tangent per vertex every frame (for normal-mapped materials);
    /// RRSKIN_STATUS_ERROR_NOT_IN_MODEL for a model without rest tangents
    /// (`rrskin_model_info.tangents` says).
    pub tangents: u32,
    /// Nonzero: end each recording with a queue family ownership release of the frame's
    /// outputs (its positions, the normals, its bounds, the tangents; whole buffers) from the context's family
    /// to `release_queue_family` (another family of the device, or VK_QUEUE_FAMILY_EXTERNAL),
    /// for the engine to acquire there. Nothing needs to come back.
    pub release_outputs: u32,
    pub release_queue_family: u32,
    /// How normals (and tangents) are made: RRSKIN_NORMALS_RECOMPUTED (0, the default) from the
    /// skinned positions over each vertex's 1-ring by a pass of their own, or
    /// RRSKIN_NORMALS_TRANSFORMED (1) in the skinning pass, the rest normal through the
    /// cofactor of the vertex's blended matrix (one pass a frame, as engines skin); any other
    /// value is RRSKIN_STATUS_ERROR_OUT_OF_RANGE.
    pub normals: u32,
}

/// `rrskin_crowd_options.normals`: recomputed from the skinned positions (paper §6).
pub const RRSKIN_NORMALS_RECOMPUTED: u32 = 0;
/// `rrskin_crowd_options.normals`: transformed in the skinning pass.
pub const RRSKIN_NORMALS_TRANSFORMED: u32 = 1;

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

/// What the runtime needs of a Vulkan implementation (`rrskin_get_requirements`): no device
/// feature beyond core Vulkan 1.1 is enabled or used.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct RrskinRequirements {
    /// The lowest VkPhysicalDeviceProperties::apiVersion (VK_MAKE_API_VERSION) it runs on.
    pub api_version: u32,
    /// VkQueueFlags the context's queue family must have.
    pub queue_flags: u32,
    /// The maxPerStageDescriptorStorageBuffers it needs (Vulkan guarantees only 4).
    pub storage_buffers_per_stage: u32,
    pub instance_extension_count: u32,
    /// `instance_extension_count` extension names to enable on the instance (NULL when 0);
    /// static strings.
    pub instance_extensions: *const *const c_char,
    pub device_extension_count: u32,
    /// `device_extension_count` extension names to enable on the device (NULL when 0).
    pub device_extensions: *const *const c_char,
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

/// The registry's entries are shared (`Arc`) so that a call holds the global lock only to find
/// its objects, and each object's own lock (the batch's mutex, the crowd's read-write lock)
/// for the work.
struct ContextEntry {
    context: Context,
    batch: Mutex<Batch>,
}

/// Immutable once loaded.
struct ModelEntry {
    model: Model,
    gpu: GpuModel,
}

impl ContextEntry {
    fn batch(&self) -> MutexGuard<'_, Batch> {
        self.batch
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner())
    }
}

struct CrowdEntry {
    /// Its context's device, to check for a lost device without taking the crowd's lock.
    device: Context,
    crowd: RwLock<Crowd>,
}

impl CrowdEntry {
    fn read(&self) -> RwLockReadGuard<'_, Crowd> {
        self.crowd
            .read()
            .unwrap_or_else(|poisoned| poisoned.into_inner())
    }

    fn write(&self) -> RwLockWriteGuard<'_, Crowd> {
        self.crowd
            .write()
            .unwrap_or_else(|poisoned| poisoned.into_inner())
    }
}

/// A slot map. A handle is `kind << 60 | generation << 28 | (index + 1)`: 0 is never a handle,
/// a destroyed slot's old handles stop matching, and a handle of one kind (say a crowd) never
/// matches another kind's slots (a context).
struct Slots<T> {
    kind: u64,
    entries: Vec<(u32, Option<T>)>,
}

const INDEX_BITS: u32 = 28;

impl<T> Slots<T> {
    const fn new(kind: u64) -> Self {
        Slots {
            kind,
            entries: Vec::new(),
        }
    }

    fn insert(&mut self, value: T) -> u64 {
        let index = match self.entries.iter().position(|(_, v)| v.is_none()) {
            Some(i) => i,
            None => {
                self.entries.push((0, None));
                self.entries.len() - 1
            }
        };
        debug_assert!(
            index + 1 < 1 << INDEX_BITS,
            "more than 2^28 live handles of one kind"
        );
        let slot = &mut self.entries[index];
        slot.0 = slot.0.wrapping_add(1);
        slot.1 = Some(value);
        (self.kind << 60) | ((slot.0 as u64) << INDEX_BITS) | (index as u64 + 1)
    }

    fn locate(&self, id: u64) -> Option<usize> {
        if id >> 60 != self.kind {
            return None;
        }
        let index = (id & ((1 << INDEX_BITS) - 1)).checked_sub(1)? as usize;
        let generation = ((id >> INDEX_BITS) & 0xFFFF_FFFF) as u32;
        match self.entries.get(index) {
            Some((g, Some(_))) if *g == generation => Some(index),
            _ => None,
        }
    }

    fn get(&self, id: u64) -> Result<&T, Failure> {
        self.locate(id)
            .and_then(|i| self.entries[i].1.as_ref())
            .ok_or(Failure::invalid_handle())
    }

    fn remove(&mut self, id: u64) -> Result<T, Failure> {
        let i = self.locate(id).ok_or(Failure::invalid_handle())?;
        self.entries[i].1.take().ok_or(Failure::invalid_handle())
    }
}

struct Registry {
    contexts: Slots<Arc<ContextEntry>>,
    models: Slots<Arc<ModelEntry>>,
    crowds: Slots<Arc<CrowdEntry>>,
}

static REGISTRY: Mutex<Registry> = Mutex::new(Registry {
    contexts: Slots::new(1),
    models: Slots::new(2),
    crowds: Slots::new(3),
});

fn registry() -> MutexGuard<'static, Registry> {
    REGISTRY
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner())
}

/// The objects behind handles, found under the global lock and used after it is released; each
/// fails at once on a lost device.
fn context_entry(context: RrskinContext) -> Result<Arc<ContextEntry>, Failure> {
    let entry = registry().contexts.get(context.id)?.clone();
    entry.context.check_lost()?;
    Ok(entry)
}

fn model_entry(model: RrskinModel) -> Result<Arc<ModelEntry>, Failure> {
    let entry = registry().models.get(model.id)?.clone();
    entry.gpu.context().check_lost()?;
    Ok(entry)
}

fn crowd_entry(crowd: RrskinCrowd) -> Result<Arc<CrowdEntry>, Failure> {
    let entry = registry().crowds.get(crowd.id)?.clone();
    entry.device.check_lost()?;
    Ok(entry)
}

thread_local! {
    /// The calling thread's last failure; `None` after a success (so that a successful call
    /// allocates nothing: the CPU palette is called per character per frame).
    static LAST_ERROR: RefCell<Option<CString>> = const { RefCell::new(None) };
}

/// An error on its way to C: status and message.
struct Failure {
    status: RrskinStatus,
    message: String,
}

impl Failure {
    fn new(status: RrskinStatus, message: impl Into<String>) -> Failure {
        Failure {
            status,
            message: message.into(),
        }
    }

    fn invalid_handle() -> Failure {
        Failure::new(
            RrskinStatus::ErrorInvalidHandle,
            "invalid handle (never created, already destroyed, or of another kind)",
        )
    }

    fn null(what: &str) -> Failure {
        Failure::new(RrskinStatus::ErrorNullPointer, format!("{what} is NULL"))
    }
}

impl From<Error> for Failure {
    fn from(e: Error) -> Failure {
        use RrskinStatus as S;
        let status = match &e {
            Error::Io { .. } => S::ErrorIo,
            Error::BadModel { .. } => S::ErrorBadModel,
            Error::WrongLength { .. } => S::ErrorWrongLength,
            Error::OutOfRange { .. } => S::ErrorOutOfRange,
            Error::NonFinite { .. } => S::ErrorNonFinite,
            Error::Mismatch { .. } => S::ErrorMismatch,
            Error::Loader { .. } => S::ErrorLoader,
            Error::Vulkan { .. } => S::ErrorVulkan,
            Error::NoDevice { .. } => S::ErrorNoDevice,
            Error::MissingLayer { .. } => S::ErrorMissingLayer,
            Error::Allocation { .. } => S::ErrorAllocation,
            Error::DeviceLimit { .. } => S::ErrorDeviceLimit,
            Error::NotReady { .. } => S::ErrorNotReady,
            Error::NotEnabled { .. } => S::ErrorNotEnabled,
            Error::MissingFunction { .. } => S::ErrorMissingFunction,
            Error::NotInModel { .. } => S::ErrorNotInModel,
            Error::DeviceLost { .. } => S::ErrorDeviceLost,
        };
        Failure::new(status, e.to_string())
    }
}

/// Runs `body`, catching panics, recording the error message, returning the status.
fn guard(body: impl FnOnce() -> Result<(), Failure>) -> RrskinStatus {
    let outcome = catch_unwind(AssertUnwindSafe(body)).unwrap_or_else(|panic| {
        let text = panic
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| panic.downcast_ref::<String>().cloned())
            .unwrap_or_else(|| "unknown panic".into());
        Err(Failure::new(
            RrskinStatus::ErrorPanic,
            format!("internal error (panic): {text}"),
        ))
    });
    let (status, message) = match outcome {
        Ok(()) => (RrskinStatus::Ok, None),
        Err(f) => (f.status, CString::new(f.message.replace('\0', " ")).ok()),
    };
    LAST_ERROR.with(|slot| *slot.borrow_mut() = message);
    status
}

/// Writes through an out-pointer the caller gave (NULL: an error, nothing written).
///
/// # Safety
/// `out` is NULL or valid for writing one aligned `T`.
unsafe fn put<T>(out: *mut T, value: T, what: &str) -> Result<(), Failure> {
    if out.is_null() {
        return Err(Failure::null(what));
    }
    // SAFETY: non-null, and valid for the write by the function's contract.
    unsafe { out.write(value) };
    Ok(())
}

/// Writes through an optional out-pointer (NULL: not asked for).
///
/// # Safety
/// `out` is NULL or valid for writing one aligned `T`.
unsafe fn put_if_asked<T>(out: *mut T, value: T) {
    if !out.is_null() {
        // SAFETY: non-null, and valid for the write by the function's contract.
        unsafe { out.write(value) };
    }
}

/// A caller's path argument as UTF-8.
///
/// # Safety
/// `path` is NULL or a NUL-terminated string readable during `'a`.
unsafe fn utf8_path<'a>(path: *const c_char) -> Result<&'a str, Failure> {
    if path.is_null() {
        return Err(Failure::null("path"));
    }
    // SAFETY: non-null NUL-terminated string, as the caller guarantees.
    unsafe { CStr::from_ptr(path) }
        .to_str()
        .map_err(|_| Failure::new(RrskinStatus::ErrorInvalidArgument, "path is not UTF-8"))
}

/// A caller's (pointer, count) as a slice (count 0: empty, whatever the pointer).
///
/// # Safety
/// `data` is NULL or points to `count` readable, aligned `T` that nothing writes during `'a`.
unsafe fn slice<'a, T>(data: *const T, count: usize, what: &str) -> Result<&'a [T], Failure> {
    if count == 0 {
        return Ok(&[]);
    }
    if data.is_null() {
        return Err(Failure::null(what));
    }
    // SAFETY: non-null, and `count` readable elements by the function's contract.
    Ok(unsafe { std::slice::from_raw_parts(data, count) })
}

/// What the runtime needs of the engine's instance, device and queue, before any exists: fill
/// `VkInstanceCreateInfo` / `VkDeviceCreateInfo` from it. `rrskin_context_create_from_engine`
/// checks the same (RRSKIN_STATUS_ERROR_NO_DEVICE, _DEVICE_LIMIT or _MISSING_FUNCTION).
///
/// # Safety
/// `out` is NULL or points to writable memory for one `rrskin_requirements`.
#[no_mangle]
pub unsafe extern "C" fn rrskin_get_requirements(out: *mut RrskinRequirements) -> RrskinStatus {
    guard(|| {
        let r = crate::vk::requirements();
        // The name lists as C arrays, made once (the names are static).
        struct Names(Vec<*const c_char>);
        // SAFETY: pointers to static, immutable strings.
        unsafe impl Send for Names {}
        // SAFETY: as above.
        unsafe impl Sync for Names {}
        static LISTS: std::sync::OnceLock<[Names; 2]> = std::sync::OnceLock::new();
        let lists = LISTS.get_or_init(|| {
            [r.instance_extensions, r.device_extensions]
                .map(|names| Names(names.iter().map(|n| n.as_ptr()).collect()))
        });
        let array = |n: &Names| {
            if n.0.is_empty() {
                std::ptr::null()
            } else {
                n.0.as_ptr()
            }
        };
        let requirements = RrskinRequirements {
            api_version: r.api_version,
            queue_flags: r.queue_flags.as_raw(),
            storage_buffers_per_stage: r.storage_buffers_per_stage,
            instance_extension_count: lists[0].0.len() as u32,
            instance_extensions: array(&lists[0]),
            device_extension_count: lists[1].0.len() as u32,
            device_extensions: array(&lists[1]),
        };
        // SAFETY: `out` as the function's contract requires.
        unsafe { put(out, requirements, "out") }
    })
}

/// The bytes of GPU memory a model of `sizes` and a crowd of `characters` of it made with
/// `options` (NULL: those of `rrskin_crowd_create`) will take, before either is created (no
/// context needed): the sizes of the buffers they create. Either out pointer may be NULL.
/// A crowd beyond the largest device-local heap is refused at creation
/// (RRSKIN_STATUS_ERROR_DEVICE_LIMIT).
///
/// # Safety
/// `sizes` is NULL or points to a readable `rrskin_model_info`; `options` is NULL or points to
/// a readable `rrskin_crowd_options`; `model_bytes` and `crowd_bytes` are each NULL or point to
/// writable memory for one `uint64_t`.
#[no_mangle]
pub unsafe extern "C" fn rrskin_query_memory(
    sizes: *const RrskinModelInfo,
    characters: u32,
    options: *const RrskinCrowdOptions,
    model_bytes: *mut u64,
    crowd_bytes: *mut u64,
) -> RrskinStatus {
    guard(|| {
        if sizes.is_null() {
            return Err(Failure::null("sizes"));
        }
        // SAFETY: non-null and readable (the function's contract).
        let i = unsafe { &*sizes };
        let sizes = crate::vk::ModelSizes {
            vertices: i.vertices as usize,
            triangles: i.triangles as usize,
            bones: i.bones as usize,
            proxies: i.proxies as usize,
            influences: i.influences as usize,
            product_columns: i.blend_columns as usize,
            tangents: i.tangents != 0,
            correctives: i.correctives as usize,
            corrective_drivers: i.corrective_drivers as usize,
            proxy_correctives: i.proxy_correctives as usize,
            proxy_corrective_drivers: i.proxy_corrective_drivers as usize,
            proxy_corrective_kernels: i.proxy_corrective_kernels as usize,
            proxy_corrective_linear: i.proxy_corrective_linear != 0,
            normal_fans: i.normal_fan_entries as usize,
        };
        let options = if options.is_null() {
            CrowdOptions::default()
        } else {
            // SAFETY: non-null and readable (the function's contract).
            crowd_options(unsafe { &*options })?
        };
        let crowd = crate::vk::crowd_bytes(&sizes, characters as usize, &options)?;
        // SAFETY: as the function's contract requires.
        unsafe {
            put_if_asked(model_bytes, crate::vk::model_bytes(&sizes));
            put_if_asked(crowd_bytes, crowd);
        }
        Ok(())
    })
}

/// The calling thread's message for the last failed call ("" after a success). Valid until the
/// next rrskin call on this thread; never NULL.
#[no_mangle]
pub extern "C" fn rrskin_last_error() -> *const c_char {
    LAST_ERROR.with(|slot| slot.borrow().as_deref().unwrap_or(c"").as_ptr())
}

/// Creates a context with its own Vulkan instance and device (the best GPU, else lavapipe).
/// `validation` != 0 enables the Khronos validation layer with synchronization validation and
/// fails with RRSKIN_ERROR_MISSING_LAYER if it is not installed. Destroy with
/// `rrskin_context_destroy`.
///
/// # Safety
/// `out` is NULL or points to writable memory for one `rrskin_context`.
#[no_mangle]
pub unsafe extern "C" fn rrskin_context_create_headless(
    validation: u32,
    out: *mut RrskinContext,
) -> RrskinStatus {
    guard(|| {
        if out.is_null() {
            return Err(Failure::null("out"));
        }
        let context = Context::new(&ContextDesc {
            validation: validation != 0,
            ..Default::default()
        })?;
        let batch = Mutex::new(Batch::new(&context)?);
        let id = registry()
            .contexts
            .insert(Arc::new(ContextEntry { context, batch }));
        // SAFETY: `out` as the function's contract requires.
        unsafe { put(out, RrskinContext { id }, "out") }
    })
}

/// Creates a context on the engine's instance, device and queue. The engine keeps ownership:
/// its objects must outlive the context and every model and crowd made from it. The library
/// submits to the queue only in `rrskin_model_load_*`, `rrskin_crowds_run` and
/// `rrskin_crowd_read_back`; the engine must not use the queue concurrently with those.
///
/// # Safety
/// `device` is NULL or points to a readable `rrskin_engine_device` whose handles are valid and
/// belong together (the instance's physical device; a device made from it with a queue of
/// `queue_family_index`; `get_instance_proc_addr` is `vkGetInstanceProcAddr` for the instance)
/// and outlive the context and every model and crowd made from it. `out` is NULL or points to
/// writable memory for one `rrskin_context`.
#[no_mangle]
pub unsafe extern "C" fn rrskin_context_create_from_engine(
    device: *const RrskinEngineDevice,
    out: *mut RrskinContext,
) -> RrskinStatus {
    guard(|| {
        if device.is_null() {
            return Err(Failure::null("device"));
        }
        if out.is_null() {
            return Err(Failure::null("out"));
        }
        // SAFETY: non-null, and the caller guarantees a valid struct.
        let d = unsafe { &*device };
        for (p, what) in [
            (
                d.get_instance_proc_addr as *mut c_void,
                "device->get_instance_proc_addr",
            ),
            (d.instance, "device->instance"),
            (d.physical_device, "device->physical_device"),
            (d.device, "device->device"),
            (d.queue, "device->queue"),
        ] {
            if p.is_null() {
                return Err(Failure::null(what));
            }
        }
        // SAFETY: a non-null PFN_vkGetInstanceProcAddr, as the caller guarantees.
        let gipa: vk::PFN_vkGetInstanceProcAddr =
            unsafe { std::mem::transmute(d.get_instance_proc_addr) };
        use vk::Handle;
        let engine = EngineDevice {
            get_instance_proc_addr: gipa,
            instance: vk::Instance::from_raw(d.instance as u64),
            physical_device: vk::PhysicalDevice::from_raw(d.physical_device as u64),
            device: vk::Device::from_raw(d.device as u64),
            queue_family_index: d.queue_family_index,
            queue: vk::Queue::from_raw(d.queue as u64),
        };
        // SAFETY: the caller guarantees the handles are valid and outlive the context.
        let context = unsafe { Context::from_engine(engine) }?;
        let batch = Mutex::new(Batch::new(&context)?);
        let id = registry()
            .contexts
            .insert(Arc::new(ContextEntry { context, batch }));
        // SAFETY: `out` as the function's contract requires.
        unsafe { put(out, RrskinContext { id }, "out") }
    })
}

/// Destroys a context handle. Its device is released once the last model and crowd made from it
/// is destroyed too.
#[no_mangle]
pub extern "C" fn rrskin_context_destroy(context: RrskinContext) -> RrskinStatus {
    guard(|| registry().contexts.remove(context.id).map(drop))
}

/// The number of validation-layer warnings and errors a headless context created with
/// validation has collected (0 otherwise).
///
/// # Safety
/// `out` is NULL or points to writable memory for one `uint32_t`.
#[no_mangle]
pub unsafe extern "C" fn rrskin_context_validation_message_count(
    context: RrskinContext,
    out: *mut u32,
) -> RrskinStatus {
    guard(|| {
        let count = context_entry(context)?.context.validation_messages().len();
        // SAFETY: `out` as the function's contract requires.
        unsafe { put(out, count as u32, "out") }
    })
}

/// Bytes of device memory the context holds for its models and crowds: `allocated` in live
/// allocations, `reserved` in the memory blocks taken from the driver (what counts against the
/// engine's budget). Either pointer may be NULL.
///
/// # Safety
/// `allocated` and `reserved` are each NULL or point to writable memory for one `uint64_t`.
#[no_mangle]
pub unsafe extern "C" fn rrskin_context_get_device_memory(
    context: RrskinContext,
    allocated: *mut u64,
    reserved: *mut u64,
) -> RrskinStatus {
    guard(|| {
        let (in_use, blocks) = context_entry(context)?.context.device_memory_bytes();
        // SAFETY: as the function's contract requires.
        unsafe {
            put_if_asked(allocated, in_use);
            put_if_asked(reserved, blocks);
        }
        Ok(())
    })
}

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
            normal_fan_entries: sizes.normal_fans as u32,
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

fn crowd_options(o: &RrskinCrowdOptions) -> Result<CrowdOptions, Failure> {
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
