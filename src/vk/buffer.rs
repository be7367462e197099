//! A VkBuffer with its gpu-allocator allocation, freed in Drop. Holds the context alive.

use super::barrier::{global_barrier, Access};
use super::context::Shared;
use super::memory::MIN_BUFFER_BYTES;
use crate::error::{Error, Result};
use ash::vk;
use gpu_allocator::vulkan::{Allocation, AllocationCreateDesc, AllocationScheme};
use gpu_allocator::MemoryLocation;
use std::sync::Arc;

pub struct Buffer {
    shared: Arc<Shared>,
    pub handle: vk::Buffer,
    allocation: Option<Allocation>,
    pub size: u64,
}

impl Buffer {
    pub fn new(
        shared: &Arc<Shared>,
        name: &'static str,
        size: u64,
        usage: vk::BufferUsageFlags,
        location: MemoryLocation,
    ) -> Result<Buffer> {
        let size = size.max(MIN_BUFFER_BYTES);
        let (handle, requirements) = shared.create_buffer(size, usage)?;
        // Owned at once, so that Drop destroys the buffer if allocating fails.
        let mut buffer = Buffer {
            shared: shared.clone(),
            handle,
            allocation: None,
            size,
        };
        let allocation = shared
            .allocator()
            .as_mut()
            .ok_or(Error::Allocation {
                what: name,
                message: "the allocator is gone".into(),
            })?
            .allocate(&AllocationCreateDesc {
                name,
                requirements,
                location,
                linear: true,
                allocation_scheme: AllocationScheme::GpuAllocatorManaged,
            })
            .map_err(|e| Error::Allocation {
                what: name,
                message: e.to_string(),
            })?;
        // SAFETY: the buffer is unbound; the allocation was made for its requirements.
        unsafe {
            shared
                .device
                .bind_buffer_memory(handle, allocation.memory(), allocation.offset())
        }
        .map_err(Error::vk("vkBindBufferMemory"))?;
        buffer.allocation = Some(allocation);
        Ok(buffer)
    }

    /// The host-visible bytes of a buffer made with a CpuToGpu or GpuToCpu location.
    pub fn mapped(&mut self) -> Result<&mut [u8]> {
        self.allocation
            .as_mut()
            .and_then(|a| a.mapped_slice_mut())
            .ok_or(Error::Allocation {
                what: "a mapped buffer",
                message: "not host-visible".into(),
            })
    }

    pub fn descriptor(&self, offset: u64, range: u64) -> vk::DescriptorBufferInfo {
        vk::DescriptorBufferInfo {
            buffer: self.handle,
            offset,
            range,
        }
    }

    /// The whole buffer as one descriptor.
    pub fn whole(&self) -> vk::DescriptorBufferInfo {
        self.descriptor(0, vk::WHOLE_SIZE)
    }
}

impl Drop for Buffer {
    fn drop(&mut self) {
        // SAFETY: the owner guarantees the GPU no longer uses the buffer (crate contract).
        unsafe { self.shared.device.destroy_buffer(self.handle, None) };
        if let Some(allocation) = self.allocation.take() {
            if let Some(allocator) = self.shared.allocator().as_mut() {
                // Freeing only fails for an allocation of another allocator: impossible here.
                let _ = allocator.free(allocation);
            }
        }
    }
}

/// Uploads `items` (debug name, bytes) into new device-local buffers, in order (one staging
/// copy, then waits).
pub fn upload<const N: usize>(
    shared: &Arc<Shared>,
    items: &[(&'static str, &[u8]); N],
    usage: vk::BufferUsageFlags,
) -> Result<[Buffer; N]> {
    let total: u64 = items.iter().map(|(_, d)| d.len() as u64).sum();
    let mut staging = Buffer::new(
        shared,
        "staging",
        total,
        vk::BufferUsageFlags::TRANSFER_SRC,
        MemoryLocation::CpuToGpu,
    )?;
    let mut offsets = Vec::with_capacity(items.len());
    {
        let mapped = staging.mapped()?;
        let mut at = 0usize;
        for (_, data) in items {
            mapped[at..at + data.len()].copy_from_slice(data);
            offsets.push(at as u64);
            at += data.len();
        }
    }
    let buffers = items
        .iter()
        .map(|(name, data)| {
            Buffer::new(
                shared,
                name,
                data.len() as u64,
                usage | vk::BufferUsageFlags::TRANSFER_DST,
                MemoryLocation::GpuOnly,
            )
        })
        .collect::<Result<Vec<_>>>()?;
    let buffers = <[Buffer; N]>::try_from(buffers).map_err(|_| Error::Mismatch {
        what: "uploaded buffer count",
    })?;
    shared.record_and_submit(|cmd| {
        for ((dst, (_, data)), &src_offset) in buffers.iter().zip(items).zip(&offsets) {
            if data.is_empty() {
                continue;
            }
            let region = [vk::BufferCopy {
                src_offset,
                dst_offset: 0,
                size: data.len() as u64,
            }];
            // SAFETY: both buffers are alive and large enough; cmd is recording.
            unsafe {
                shared
                    .device
                    .cmd_copy_buffer(cmd, staging.handle, dst.handle, &region)
            };
        }
        // Make the copies visible to every later compute read (submit-and-wait orders the
        // submissions, but sync validation wants the memory dependency spelled out).
        // SAFETY: cmd is recording.
        unsafe {
            global_barrier(
                &shared.device,
                cmd,
                &[Access::TransferWrite],
                &[Access::ComputeShaderReadStorage],
            )
        };
        Ok(())
    })?;
    Ok(buffers)
}

/// Copies (transfer writes) before the host reads them after the fence: the read-back barrier.
///
/// # Safety
/// `cmd` must be recording.
pub(crate) unsafe fn transfer_to_host_barrier(device: &ash::Device, cmd: vk::CommandBuffer) {
    // SAFETY: see the function's contract.
    unsafe { global_barrier(device, cmd, &[Access::TransferWrite], &[Access::HostRead]) };
}
