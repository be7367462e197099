//! One compute pipeline per pass, each with an explicit descriptor set layout (storage buffers
//! only, bindings 0..n in shader order) and one push-constant range. SPIR-V comes from build.rs.

use crate::error::{Error, Result};
use ash::vk;

macro_rules! spirv {
    ($name:literal) => {
        include_bytes!(concat!(env!("OUT_DIR"), "/", $name, ".spv"))
    };
}

/// A pass's pipeline and the layouts it was made with.
#[derive(Default, Clone, Copy)]
pub struct PassPipeline {
    pub set_layout: vk::DescriptorSetLayout,
    pub layout: vk::PipelineLayout,
    pub pipeline: vk::Pipeline,
    pub bindings: u32,
}

#[derive(Default)]
pub struct Pipelines {
    pub predict: PassPipeline,
    pub blend_gemm: PassPipeline,
    pub skin_k4: PassPipeline,
    pub skin_k8: PassPipeline,
    pub normals: PassPipeline,
}

impl Pipelines {
    pub fn new(device: &ash::Device) -> Result<Pipelines> {
        let mut made = Pipelines::default();
        // Assign one by one so that `destroy` can clean up a partial set on error.
        let result = (|| {
            made.predict = PassPipeline::new(
                device,
                spirv!("predict"),
                super::predict::BINDINGS.len(),
                size_of::<super::predict::Push>(),
            )?;
            made.blend_gemm = PassPipeline::new(
                device,
                spirv!("blend_gemm"),
                super::blend_gemm::BINDINGS.len(),
                size_of::<super::blend_gemm::Push>(),
            )?;
            let skin = |code: &[u8]| {
                PassPipeline::new(
                    device,
                    code,
                    super::skin::BINDINGS.len(),
                    size_of::<super::skin::Push>(),
                )
            };
            made.skin_k4 = skin(spirv!("skin_k4"))?;
            made.skin_k8 = skin(spirv!("skin_k8"))?;
            made.normals = PassPipeline::new(
                device,
                spirv!("normals"),
                super::normals::BINDINGS.len(),
                size_of::<super::normals::Push>(),
            )?;
            Ok(())
        })();
        match result {
            Ok(()) => Ok(made),
            Err(e) => {
                // SAFETY: nothing uses the partially created pipelines.
                unsafe { made.destroy(device) };
                Err(e)
            }
        }
    }

    /// The skinning pipeline for K influences (a model guarantees K is 4 or 8).
    pub fn skin(&self, influences: usize) -> &PassPipeline {
        if influences == 8 {
            &self.skin_k8
        } else {
            &self.skin_k4
        }
    }

    /// # Safety
    /// No pipeline may be in use by the GPU; null handles are skipped.
    pub unsafe fn destroy(&self, device: &ash::Device) {
        for p in [
            &self.predict,
            &self.blend_gemm,
            &self.skin_k4,
            &self.skin_k8,
            &self.normals,
        ] {
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
    fn new(device: &ash::Device, code: &[u8], bindings: usize, push_bytes: usize) -> Result<Self> {
        let mut pass = PassPipeline {
            bindings: bindings as u32,
            ..Default::default()
        };
        let layout_bindings: Vec<vk::DescriptorSetLayoutBinding> = (0..bindings as u32)
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
            .size(push_bytes as u32)];
        let set_layouts = [pass.set_layout];
        let info = vk::PipelineLayoutCreateInfo::default()
            .set_layouts(&set_layouts)
            .push_constant_ranges(&ranges);
        let made = (|| {
            // SAFETY: valid device and create info.
            pass.layout = unsafe { device.create_pipeline_layout(&info, None) }
                .map_err(Error::vk("vkCreatePipelineLayout"))?;
            let words: Vec<u32> = code
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
            pass.pipeline = pipelines.map_err(|(_, result)| Error::Vulkan {
                call: "vkCreateComputePipelines",
                result,
            })?[0];
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
