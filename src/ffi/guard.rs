//! Errors on their way to C: `Failure` (a status and a message, from any crate `Error`), the
//! guard every function's body runs under (panics caught, the thread's last error kept for
//! `rrskin_last_error`), and the checks of the caller's pointers (`put`, `put_if_asked`,
//! `utf8_path`, `slice`).

use super::types::RrskinStatus;
use crate::error::Error;
use std::cell::RefCell;
use std::ffi::{c_char, CStr, CString};
use std::panic::{catch_unwind, AssertUnwindSafe};

thread_local! {
    /// The calling thread's last failure; `None` after a success (so that a successful call
    /// allocates nothing: the CPU palette is called per character per frame).
    static LAST_ERROR: RefCell<Option<CString>> = const { RefCell::new(None) };
}

/// An error on its way to C: status and message.
pub(super) struct Failure {
    status: RrskinStatus,
    message: String,
}

impl Failure {
    pub(super) fn new(status: RrskinStatus, message: impl Into<String>) -> Failure {
        Failure {
            status,
            message: message.into(),
        }
    }

    pub(super) fn invalid_handle() -> Failure {
        Failure::new(
            RrskinStatus::ErrorInvalidHandle,
            "invalid handle (never created, already destroyed, or of another kind)",
        )
    }

    pub(super) fn null(what: &str) -> Failure {
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
            Error::DeviceLimit { .. } | Error::BufferTooLarge { .. } => S::ErrorDeviceLimit,
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
pub(super) fn guard(body: impl FnOnce() -> Result<(), Failure>) -> RrskinStatus {
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

/// The calling thread's message for the last failed call ("" after a success). Valid until the
/// next rrskin call on this thread; never NULL.
#[no_mangle]
pub extern "C" fn rrskin_last_error() -> *const c_char {
    LAST_ERROR.with(|slot| slot.borrow().as_deref().unwrap_or(c"").as_ptr())
}

/// Writes through an out-pointer the caller gave (NULL: an error, nothing written).
///
/// # Safety
/// `out` is NULL or valid for writing one aligned `T`.
pub(super) unsafe fn put<T>(out: *mut T, value: T, what: &str) -> Result<(), Failure> {
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
pub(super) unsafe fn put_if_asked<T>(out: *mut T, value: T) {
    if !out.is_null() {
        // SAFETY: non-null, and valid for the write by the function's contract.
        unsafe { out.write(value) };
    }
}

/// A caller's path argument as UTF-8.
///
/// # Safety
/// `path` is NULL or a NUL-terminated string readable during `'a`.
pub(super) unsafe fn utf8_path<'a>(path: *const c_char) -> Result<&'a str, Failure> {
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
pub(super) unsafe fn slice<'a, T>(
    data: *const T,
    count: usize,
    what: &str,
) -> Result<&'a [T], Failure> {
    if count == 0 {
        return Ok(&[]);
    }
    if data.is_null() {
        return Err(Failure::null(what));
    }
    // SAFETY: non-null, and `count` readable elements by the function's contract.
    Ok(unsafe { std::slice::from_raw_parts(data, count) })
}

/// `floats` floats at `data` as 3-vectors (an up vector each): NULL with 0 is none.
///
/// # Safety
/// `data` is NULL or points to `floats` readable floats.
pub(super) unsafe fn vectors3<'a>(
    data: *const f32,
    floats: usize,
) -> Result<&'a [[f32; 3]], Failure> {
    if floats % 3 != 0 {
        return Err(crate::Error::WrongLength {
            what: "up vector floats (3 a vector)",
            expected: floats.div_ceil(3) * 3,
            actual: floats,
        }
        .into());
    }
    // SAFETY: `data` points to `floats` floats, 3 to a vector (`[f32; 3]` has the alignment of
    // `f32`), as the caller guarantees.
    unsafe { slice(data.cast::<[f32; 3]>(), floats / 3, "ups") }
}
