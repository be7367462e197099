//! The C types more than one concern uses: the status every function returns, the handles of
//! contexts, models and crowds, a model's sizes (`rrskin_model_get_info`, `rrskin_query_memory`)
//! and a crowd's options with the constants of its normals (`rrskin_crowd_create_with_options`,
//! `rrskin_query_memory`). A type of one concern only stands in that concern's file.

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
    /// Nonzero: they have the 3 gravity features per driver too, and crowds read each
    /// character's up vector (`rrskin_crowd_set_ups`; the model's `up` by default).
    pub proxy_corrective_gravity: u32,
    /// The model's up (unit, in its bones' frame) where `proxy_corrective_gravity`, else zeros.
    pub up: [f32; 3],
    /// Entries of the 1-ring fans the recomputed-normals pass reads (about 3 x triangles +
    /// 2 x vertices for a closed mesh): what `rrskin_model_get_info` reports, needed for
    /// `rrskin_query_memory`'s model bytes.
    pub normal_fan_entries: u32,
    /// The words of the P keys' records, all keys together: what `rrskin_model_get_info`
    /// reports, needed for `rrskin_query_memory`'s model bytes.
    pub key_words: u32,
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
