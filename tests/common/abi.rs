//! The C ABI as the tests call it: statuses as `Result`s.

use rrskin::ffi::*;

pub fn status(s: RrskinStatus) -> Result<(), RrskinStatus> {
    if s == RrskinStatus::Ok {
        Ok(())
    } else {
        Err(s)
    }
}

/// A model from its `.rrs` bytes.
pub fn load(ctx: RrskinContext, bytes: &[u8]) -> Result<RrskinModel, RrskinStatus> {
    let mut m = RrskinModel { id: 0 };
    // SAFETY: valid pointers and lengths.
    status(unsafe { rrskin_model_load_memory(ctx, bytes.as_ptr(), bytes.len(), &mut m) })
        .map(|()| m)
}
