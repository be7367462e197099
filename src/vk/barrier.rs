//! Barriers from named accesses (after kajiya's `vulkan/barrier.rs`): each [`Access`] maps to
//! its (stage, access) pair once, and a barrier is "these accesses before → those after".

use ash::vk;

/// How a command touches memory, on either side of a barrier.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Access {
    /// A compute shader reads a storage buffer.
    ComputeShaderReadStorage,
    /// A compute shader writes a storage buffer.
    ComputeShaderWrite,
    /// Vertex fetch from a vertex buffer (the engine drawing the outputs).
    VertexBuffer,
    TransferRead,
    TransferWrite,
    HostRead,
}

impl Access {
    const fn stage_access(self) -> (vk::PipelineStageFlags, vk::AccessFlags) {
        use vk::{AccessFlags as A, PipelineStageFlags as S};
        match self {
            Access::ComputeShaderReadStorage => (S::COMPUTE_SHADER, A::SHADER_READ),
            Access::ComputeShaderWrite => (S::COMPUTE_SHADER, A::SHADER_WRITE),
            Access::VertexBuffer => (S::VERTEX_INPUT, A::VERTEX_ATTRIBUTE_READ),
            Access::TransferRead => (S::TRANSFER, A::TRANSFER_READ),
            Access::TransferWrite => (S::TRANSFER, A::TRANSFER_WRITE),
            Access::HostRead => (S::HOST, A::HOST_READ),
        }
    }

    const fn is_write(self) -> bool {
        matches!(self, Access::ComputeShaderWrite | Access::TransferWrite)
    }
}

/// What a pass does to its storage buffers.
pub(super) const PASS_ACCESSES: [Access; 2] =
    [Access::ComputeShaderReadStorage, Access::ComputeShaderWrite];

/// The stage and access masks of a global barrier between `previous` and `next`: waits for
/// every previous stage; only writes need making available, and only after a write must the
/// next accesses be made visible (a read after a read, or a write after a read, needs no
/// memory dependency, only the execution dependency).
fn masks(
    previous: &[Access],
    next: &[Access],
) -> (
    vk::PipelineStageFlags,
    vk::PipelineStageFlags,
    vk::MemoryBarrier<'static>,
) {
    let (mut src_stage, mut src_access) =
        (vk::PipelineStageFlags::empty(), vk::AccessFlags::empty());
    for &a in previous {
        let (stage, access) = a.stage_access();
        src_stage |= stage;
        if a.is_write() {
            src_access |= access;
        }
    }
    let (mut dst_stage, mut dst_access) =
        (vk::PipelineStageFlags::empty(), vk::AccessFlags::empty());
    for &a in next {
        let (stage, access) = a.stage_access();
        dst_stage |= stage;
        if !src_access.is_empty() {
            dst_access |= access;
        }
    }
    let barrier = vk::MemoryBarrier::default()
        .src_access_mask(src_access)
        .dst_access_mask(dst_access);
    (src_stage, dst_stage, barrier)
}

/// Records a global memory barrier: the `previous` accesses happen before the `next` ones.
///
/// # Safety
/// `cmd` must be recording.
pub(crate) unsafe fn global_barrier(
    device: &ash::Device,
    cmd: vk::CommandBuffer,
    previous: &[Access],
    next: &[Access],
) {
    let (src_stage, dst_stage, barrier) = masks(previous, next);
    // SAFETY: see the function's contract.
    unsafe {
        device.cmd_pipeline_barrier(
            cmd,
            src_stage,
            dst_stage,
            vk::DependencyFlags::empty(),
            &[barrier],
            &[],
            &[],
        )
    };
}

#[cfg(test)]
mod tests {
    use super::*;
    use vk::{AccessFlags as A, PipelineStageFlags as S};

    fn pair(previous: &[Access], next: &[Access]) -> [(S, A); 2] {
        let (src, dst, b) = masks(previous, next);
        [(src, b.src_access_mask), (dst, b.dst_access_mask)]
    }

    #[test]
    fn write_then_reads_makes_the_write_visible_to_each_reader() {
        use Access::*;
        assert_eq!(
            pair(
                &[ComputeShaderWrite],
                &[ComputeShaderReadStorage, VertexBuffer, TransferRead]
            ),
            [
                (S::COMPUTE_SHADER, A::SHADER_WRITE),
                (
                    S::COMPUTE_SHADER | S::VERTEX_INPUT | S::TRANSFER,
                    A::SHADER_READ | A::VERTEX_ATTRIBUTE_READ | A::TRANSFER_READ
                ),
            ]
        );
    }

    #[test]
    fn reads_before_need_only_an_execution_dependency() {
        use Access::*;
        assert_eq!(
            pair(&[VertexBuffer, TransferRead], &[ComputeShaderWrite]),
            [
                (S::VERTEX_INPUT | S::TRANSFER, A::empty()),
                (S::COMPUTE_SHADER, A::empty()),
            ]
        );
    }
}
