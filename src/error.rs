//! One error type for the whole runtime, and its `Result` alias.
//!
//! Every variant has named fields so that a message names what is wrong and so that the C ABI
//! can map variants one-to-one onto status codes. Model-file and model-content problems are one
//! variant, [`Error::BadModel`], whose [`ModelProblem`] says exactly what failed and where.

use ash::vk;
use std::fmt;

pub type Result<T, E = Error> = std::result::Result<T, E>;

#[derive(Debug, Clone, PartialEq)]
pub enum Error {
    /// A file could not be read or written.
    Io { path: String, message: String },
    /// A model (from a file, from memory, or from parts) is malformed. `origin` is the file path,
    /// `<memory>` or `<parts>`.
    BadModel {
        origin: String,
        problem: ModelProblem,
    },
    /// The caller passed data of the wrong size (e.g. bone transforms for the wrong bone count).
    WrongLength {
        what: &'static str,
        expected: usize,
        actual: usize,
    },
    /// The caller passed an index past the end (e.g. a character index past a crowd's capacity).
    OutOfRange {
        what: &'static str,
        index: usize,
        count: usize,
    },
    /// The caller passed a non-finite number (NaN or infinity) in per-frame input.
    NonFinite { what: &'static str, index: usize },
    /// Two objects that must belong together do not (e.g. a crowd of another context).
    Mismatch { what: &'static str },
    /// The Vulkan loader could not be found or loaded.
    Loader { message: String },
    /// A Vulkan call failed.
    Vulkan {
        call: &'static str,
        result: vk::Result,
    },
    /// No usable Vulkan device (or the requested one is not there).
    NoDevice { reason: String },
    /// A requested instance layer is missing (e.g. the validation layer in tests).
    MissingLayer { name: String },
    /// GPU memory allocation failed.
    Allocation { what: &'static str, message: String },
    /// The work does not fit a device limit (e.g. one character's output beyond
    /// maxStorageBufferRange, or a crowd larger than maxMemoryAllocationSize).
    DeviceLimit {
        what: &'static str,
        needed: u64,
        limit: u64,
    },
    /// One of a crowd's buffers would be larger than the device can make and bind
    /// (`maxMemoryAllocationSize`, `maxBufferSize`): a crowd of fewer characters, or several,
    /// fits.
    BufferTooLarge {
        buffer: &'static str,
        needed: u64,
        limit: u64,
    },
    /// Results were asked for before the GPU produced them (timestamps of unfinished work).
    NotReady { what: &'static str },
    /// An optional output was asked for from an object made without it (bounds of a crowd
    /// created without bounds).
    NotEnabled { what: &'static str },
    /// A Vulkan function the runtime calls is missing from the engine's function pointers (or
    /// the device does not provide it).
    MissingFunction { name: String },
    /// An output was asked for that the model has no data for (tangents of a model without
    /// rest tangents: one trained from a mesh without UVs).
    NotInModel { what: &'static str },
    /// The device was lost (`VK_ERROR_DEVICE_LOST` from `call`). Every later call that uses the
    /// context fails with this at once; its objects can still be dropped (destroyed).
    DeviceLost { call: &'static str },
}

/// What is wrong with a model. Counts are in elements unless the name says bytes.
#[derive(Debug, Clone, PartialEq)]
pub enum ModelProblem {
    /// The data ends before `what` (needed `expected` bytes, `actual` left).
    Truncated {
        what: String,
        expected: u64,
        actual: u64,
    },
    /// The data is longer than the length its header declares.
    TrailingBytes { declared: u64, actual: u64 },
    /// The file does not start with the `.rrs` magic.
    BadMagic,
    /// The format version is not one this build reads.
    UnsupportedVersion { found: u32, supported: u32 },
    /// The stored checksum does not match the contents (corruption).
    Checksum { stored: u32, computed: u32 },
    /// A required section is absent.
    MissingSection { tag: String },
    /// A section appears twice.
    DuplicateSection { tag: String },
    /// A section's byte range leaves the file.
    SectionBounds {
        tag: String,
        offset: u64,
        length: u64,
        file_length: u64,
    },
    /// A section's length disagrees with the model's dimensions.
    SectionLength {
        tag: String,
        expected: u64,
        actual: u64,
    },
    /// A dimension is invalid (e.g. zero vertices, K not 4 or 8).
    Dimension {
        what: &'static str,
        value: u64,
        reason: &'static str,
    },
    /// Two arrays that must agree in length do not.
    Length {
        what: &'static str,
        expected: usize,
        actual: usize,
    },
    /// A NaN or infinity in `what` at element `index`.
    NonFinite { what: &'static str, index: usize },
    /// An index in `what` at element `index` is `value`, not below `bound`.
    IndexOutOfRange {
        what: &'static str,
        index: usize,
        value: i64,
        bound: usize,
    },
    /// The bone hierarchy has a cycle through `bone`.
    ParentCycle { bone: usize },
    /// A vertex's skinning weights are negative or do not sum to one.
    BadWeights { vertex: usize, sum: f32 },
    /// A matrix that must be a rotation is not (orthonormality or determinant off by `error`).
    NotRotation {
        what: &'static str,
        index: usize,
        error: f32,
    },
    /// A corrective driver (element `index` of the drivers, bone `bone`) is not usable.
    BadDriver {
        index: usize,
        bone: u32,
        reason: &'static str,
    },
    /// A proxy corrective's driver (element `index` of corrected proxy `proxy`'s drivers, bone
    /// `bone`) is not usable.
    BadProxyDriver {
        proxy: u32,
        index: usize,
        bone: u32,
        reason: &'static str,
    },
    /// Element `index` of the proxy correctives' array `what` (proxies, driver offsets, widths)
    /// breaks an invariant, which `reason` names.
    BadProxyCorrective {
        what: &'static str,
        index: usize,
        reason: &'static str,
    },
    /// Key `key` (of the P) breaks an invariant of its record or its kind, which `reason`
    /// names.
    BadKey { key: usize, reason: &'static str },
    /// A rest tangent's xyz is not a unit vector or its handedness w is not ±1.
    BadTangent {
        vertex: usize,
        length: f32,
        handedness: f32,
    },
}

impl fmt::Display for ModelProblem {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        use ModelProblem::*;
        match self {
            Truncated { what, expected, actual } => {
                write!(f, "truncated at {what}: needs {expected} bytes, only {actual} left")
            }
            TrailingBytes { declared, actual } => {
                write!(f, "{actual} bytes, but the header declares {declared}")
            }
            BadMagic => write!(f, "not an rrskin model (bad magic)"),
            UnsupportedVersion { found, supported } => {
                write!(f, "format version {found} is not supported (this build reads 1 to {supported})")
            }
            Checksum { stored, computed } => write!(
                f,
                "checksum mismatch (stored {stored:#010x}, computed {computed:#010x}): the file is corrupted"
            ),
            MissingSection { tag } => write!(f, "required section '{tag}' is missing"),
            DuplicateSection { tag } => write!(f, "section '{tag}' appears twice"),
            SectionBounds { tag, offset, length, file_length } => write!(
                f,
                "section '{tag}' (offset {offset}, {length} bytes) extends past the end of the file ({file_length} bytes)"
            ),
            SectionLength { tag, expected, actual } => {
                write!(f, "section '{tag}' has {actual} bytes, the dimensions need {expected}")
            }
            Dimension { what, value, reason } => write!(f, "{what} = {value}: {reason}"),
            Length { what, expected, actual } => {
                write!(f, "{what} has {actual} elements, expected {expected}")
            }
            NonFinite { what, index } => write!(f, "{what}[{index}] is not finite (NaN or Inf)"),
            IndexOutOfRange { what, index, value, bound } => {
                write!(f, "{what}[{index}] = {value} is out of range (must be in 0..{bound})")
            }
            ParentCycle { bone } => write!(f, "bone parents form a cycle through bone {bone}"),
            BadWeights { vertex, sum } => write!(
                f,
                "vertex {vertex}: skinning weights must be >= 0 and sum to 1 (sum is {sum})"
            ),
            NotRotation { what, index, error } => {
                write!(f, "{what}[{index}] is not a rotation matrix (error {error:.3e})")
            }
            BadDriver { index, bone, reason } => {
                write!(f, "corrective drivers[{index}] = bone {bone} {reason}")
            }
            BadProxyDriver { proxy, index, bone, reason } => write!(
                f,
                "proxy correctives: proxy {proxy}'s drivers[{index}] = bone {bone} {reason}"
            ),
            BadKey { key, reason } => write!(f, "key {key} {reason}"),
            BadProxyCorrective { what, index, reason } => {
                write!(f, "proxy correctives: {what}[{index}] {reason}")
            }
            BadTangent { vertex, length, handedness } => write!(
                f,
                "vertex {vertex}: the rest tangent must have unit xyz and w = ±1 (length {length}, w {handedness})"
            ),
        }
    }
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        use Error::*;
        match self {
            Io { path, message } => write!(f, "{path}: {message}"),
            BadModel { origin, problem } => write!(f, "model {origin}: {problem}"),
            WrongLength {
                what,
                expected,
                actual,
            } => {
                write!(f, "{what}: expected {expected} elements, got {actual}")
            }
            OutOfRange { what, index, count } => {
                write!(f, "{what} {index} is out of range (count {count})")
            }
            NonFinite { what, index } => write!(f, "{what}[{index}] is not finite (NaN or Inf)"),
            Mismatch { what } => write!(f, "mismatch: {what}"),
            Loader { message } => write!(f, "cannot load the Vulkan loader: {message}"),
            Vulkan { call, result } => write!(f, "{call} failed: {result}"),
            DeviceLost { call } => write!(
                f,
                "the Vulkan device was lost ({call} returned VK_ERROR_DEVICE_LOST): destroy \
                 everything made from this context and create a new one"
            ),
            NoDevice { reason } => write!(f, "no usable Vulkan device: {reason}"),
            MissingLayer { name } => write!(f, "Vulkan layer {name} is not installed"),
            Allocation { what, message } => write!(f, "allocating {what}: {message}"),
            DeviceLimit {
                what,
                needed,
                limit,
            } => {
                write!(f, "{what} needs {needed}, the device allows {limit}")
            }
            BufferTooLarge {
                buffer,
                needed,
                limit,
            } => write!(
                f,
                "{buffer} needs one buffer of {needed} bytes, and the device makes and binds at most {limit} (maxMemoryAllocationSize, maxBufferSize): make the crowd of fewer characters, or several crowds"
            ),
            NotReady { what } => write!(f, "{what} is not ready yet"),
            NotEnabled { what } => write!(f, "{what} was not enabled"),
            NotInModel { what } => write!(f, "the model has no {what}"),
            MissingFunction { name } => {
                write!(
                    f,
                    "the Vulkan function {name} is missing (NULL from the loader)"
                )
            }
        }
    }
}

impl std::error::Error for Error {}

impl Error {
    /// Turns a failed Vulkan call's result into [`Error::Vulkan`] naming the call, for
    /// `map_err` (public for crates that record on a runtime context, such as rrskin-render).
    /// Out-of-memory results become [`Error::Allocation`] and a lost device
    /// [`Error::DeviceLost`], so that callers can tell the three apart.
    pub fn vk(call: &'static str) -> impl FnOnce(vk::Result) -> Error {
        move |result| match result {
            vk::Result::ERROR_DEVICE_LOST => Error::DeviceLost { call },
            vk::Result::ERROR_OUT_OF_DEVICE_MEMORY | vk::Result::ERROR_OUT_OF_HOST_MEMORY => {
                Error::Allocation {
                    what: call,
                    message: result.to_string(),
                }
            }
            result => Error::Vulkan { call, result },
        }
    }
}
