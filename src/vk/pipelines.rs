//! One compute pipeline per pass of the table (`passes.rs`), each with an explicit descriptor
//! set layout (storage buffers only, bindings 0..n in shader order) and one push-constant range.

use super::pass::PassDesc;
use super::passes::Pass;
use crate::error::{Error, Result};
use ash::vk;

/// A pass's pipeline and the layouts it was made with.
#[derive(Default, Clone, Copy)]
pub struct PassPipeline {
    pub set_layout: vk::DescriptorSetLayout,
    pub layout: vk::PipelineLayout,
    pub pipeline: vk::Pipeline,
}

/// Indexed by [`Pass`].
#[derive(Default)]
pub struct Pipelines([PassPipeline; Pass::COUNT]);

impl Pipelines {
    /// The pipelines of every pass that binds at most `max_storage_buffers` (the device's
    /// maxPerStageDescriptorStorageBuffers); the others stay null: a layout past the limit is
    /// invalid, and a crowd that would run such a pass is refused before it records one.
    pub fn new(device: &ash::Device, max_storage_buffers: u32) -> Result<Pipelines> {
        let mut made = Pipelines::default();
        let fits = |pass: &Pass| pass.desc().bindings.len() as u32 <= max_storage_buffers;
        // Assign one by one so that `destroy` can clean up a partial set on error.
        let result = Pass::ALL.into_iter().filter(fits).try_for_each(|pass| {
            made.0[pass as usize] = PassPipeline::new(device, pass.desc())?;
            Ok(())
        });
        match result {
            Ok(()) => Ok(made),
            Err(e) => {
                // SAFETY: nothing uses the partially created pipelines.
                unsafe { made.destroy(device) };
                Err(e)
            }
        }
    }

    pub fn get(&self, pass: Pass) -> &PassPipeline {
        &self.0[pass as usize]
    }

    /// # Safety
    /// No pipeline may be in use by the GPU; null handles are skipped.
    pub unsafe fn destroy(&self, device: &ash::Device) {
        for p in &self.0 {
            // SAFETY: see the function's contract; destroying null handles is a no-op.
            unsafe {
                device.destroy_pipeline(p.pipeline, None);
                device.destroy_pipeline_layout(p.layout, None);
                device.destroy_descriptor_set_layout(p.set_layout, None);
            }
        }
    }
}

impl PassPipeline {
    fn new(device: &ash::Device, desc: &PassDesc) -> Result<Self> {
        let mut pass = PassPipeline::default();
        let layout_bindings: Vec<vk::DescriptorSetLayoutBinding> = (0..desc.bindings.len() as u32)
            .map(|b| {
                vk::DescriptorSetLayoutBinding::default()
                    .binding(b)
                    .descriptor_type(vk::DescriptorType::STORAGE_BUFFER)
                    .descriptor_count(1)
                    .stage_flags(vk::ShaderStageFlags::COMPUTE)
            })
            .collect();
        let info = vk::DescriptorSetLayoutCreateInfo::default().bindings(&layout_bindings);
        // SAFETY: valid device and create info.
        pass.set_layout = unsafe { device.create_descriptor_set_layout(&info, None) }
            .map_err(Error::vk("vkCreateDescriptorSetLayout"))?;
        let ranges = [vk::PushConstantRange::default()
            .stage_flags(vk::ShaderStageFlags::COMPUTE)
            .size(desc.push_bytes())];
        let set_layouts = [pass.set_layout];
        let info = vk::PipelineLayoutCreateInfo::default()
            .set_layouts(&set_layouts)
            .push_constant_ranges(&ranges);
        let made = (|| {
            // SAFETY: valid device and create info.
            pass.layout = unsafe { device.create_pipeline_layout(&info, None) }
                .map_err(Error::vk("vkCreatePipelineLayout"))?;
            let words: Vec<u32> = desc
                .shader
                .spirv
                .chunks_exact(4)
                .map(|w| u32::from_le_bytes([w[0], w[1], w[2], w[3]]))
                .collect();
            let module_info = vk::ShaderModuleCreateInfo::default().code(&words);
            // SAFETY: SPIR-V produced and validated by naga in build.rs.
            let module = unsafe { device.create_shader_module(&module_info, None) }
                .map_err(Error::vk("vkCreateShaderModule"))?;
            let stage = vk::PipelineShaderStageCreateInfo::default()
                .stage(vk::ShaderStageFlags::COMPUTE)
                .module(module)
                .name(c"main");
            let info = [vk::ComputePipelineCreateInfo::default()
                .stage(stage)
                .layout(pass.layout)];
            // SAFETY: valid create info; the module may be destroyed once the pipeline exists.
            let pipelines = unsafe {
                let r = device.create_compute_pipelines(vk::PipelineCache::null(), &info, None);
                device.destroy_shader_module(module, None);
                r
            };
            pass.pipeline =
                pipelines.map_err(|(_, result)| Error::vk("vkCreateComputePipelines")(result))?[0];
            Ok(())
        })();
        match made {
            Ok(()) => Ok(pass),
            Err(e) => {
                // SAFETY: nothing uses these yet; null handles are no-ops.
                unsafe {
                    device.destroy_pipeline_layout(pass.layout, None);
                    device.destroy_descriptor_set_layout(pass.set_layout, None);
                }
                Err(e)
            }
        }
    }
}
