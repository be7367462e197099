//! How many characters of a model a Vulkan device holds, for the error of a `--characters` too
//! large: the runtime only says that an allocation failed.

use rrskin::vk::{
    crowd_bytes, crowd_largest_buffer_bytes, Context, Crowd, CrowdOptions, GpuModel, ModelSizes,
};
use rrskin::Model;

/// The bounds on a crowd of `m` on the device: characters whose largest buffer fits the largest
/// buffer it makes, and characters whose buffers fit its largest device-local heap.
fn limits(ctx: &Context, m: &Model, options: &CrowdOptions) -> String {
    let limits = ctx.limits();
    let (allocation, heap) = (limits.max_buffer_bytes, limits.device_local_bytes);
    let sizes = ModelSizes::of(m);
    let total = crowd_bytes(&sizes, 1, options).unwrap_or(u64::MAX);
    let largest = crowd_largest_buffer_bytes(&sizes, options).unwrap_or(u64::MAX);
    let gib = |b: u64| b as f64 / (1u64 << 30) as f64;
    format!(
        "{} makes buffers of at most {:.1} GiB ({} characters of this model's largest buffer) and has {:.1} GiB of device memory (about {} characters, {total} bytes each)",
        ctx.device_name(),
        gib(allocation),
        allocation / largest.max(1),
        gib(heap),
        heap / total.max(1)
    )
}

/// A crowd of `characters`; when the device cannot hold it, an error that names the flag and
/// the device's bounds.
pub fn crowd(
    ctx: &Context,
    gpu_model: &GpuModel,
    m: &Model,
    characters: usize,
    options: CrowdOptions,
) -> Result<Crowd, Box<dyn std::error::Error>> {
    match Crowd::with_options(gpu_model, characters, options) {
        Err(
            e @ (rrskin::Error::Allocation { .. }
            | rrskin::Error::DeviceLimit { .. }
            | rrskin::Error::BufferTooLarge { .. }),
        ) => Err(format!(
            "--characters {characters}: {e}: {}; lower --characters",
            limits(ctx, m, &options)
        )
        .into()),
        other => Ok(other?),
    }
}
