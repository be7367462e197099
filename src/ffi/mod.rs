//! rrskin: the C ABI of the rrskin runtime (real-time enveloping with rotational regression).
//! `include/rrskin.h` is generated from `src/ffi/` (this module and its files, one a concern) by
//! cbindgen: do not edit it (`RRSKIN_BLESS=1 cargo test --test c_abi` regenerates it). Its
//! preamble is the conventions below followed by the crate's contract (`src/lib.rs`,
//! "## Contract"); `tests/c_abi.rs` puts them together.
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

// cbindgen writes the header's functions in the order it meets them: module by module as
// declared here (apart, so that rustfmt does not sort them), then as each file has them.
mod requirements;

mod guard;

mod context;

mod model;

mod crowd;

mod palette;

mod handles;
mod types;

pub use context::*;
pub use crowd::*;
pub use guard::*;
pub use model::*;
pub use palette::*;
pub use requirements::*;
pub use types::*;
