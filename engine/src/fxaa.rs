//! FXAA on the final image (T. Lottes, "FXAA", NVIDIA white paper 2009; the compact variant of
//! FXAA 3.11 for consoles) as a compute pass over the linear RGBA buffer. Shader:
//! `shaders/fxaa.wgsl`. Luma is `sqrt` of the Rec. 601 weights of linear colour (close to the
//! display encoding FXAA expects); pixels whose 2x2-diagonal luma range is below
//! `max(1/32, max/8)` are copied; elsewhere the edge direction from the diagonal luma
//! differences picks two or four bilinear taps along the edge, the wider blend rejected when
//! it leaves the local luma range.

use crate::gpu::{Gpu, Slot};
use crate::prelude::with_prelude;

const SHADER: &str = include_str!("../../shaders/fxaa.wgsl");

/// The pass's uniform. Keep in sync with `struct Params` in `shaders/fxaa.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct FxaaParams {
    pub width: u32,
    pub height: u32,
    pub pad: [u32; 2],
}

pub struct FxaaPass {
    pipe: wgpu::ComputePipeline,
    bind: wgpu::BindGroup,
    pub output: wgpu::Buffer,
    size: (u32, u32),
}

impl FxaaPass {
    pub fn new(gpu: &Gpu, width: u32, height: u32, input: &wgpu::Buffer) -> FxaaPass {
        let module = gpu.shader("fxaa.wgsl", &with_prelude(SHADER));
        let layout = gpu.layout(
            "fxaa",
            wgpu::ShaderStages::COMPUTE,
            &[Slot::Uniform, Slot::Storage, Slot::StorageRw],
        );
        let pl = gpu.pipeline_layout("fxaa", &[&layout]);
        let pipe = gpu.compute_pipeline_with(&module, "main", &pl, "fxaa");
        let params = FxaaParams {
            width,
            height,
            pad: [0; 2],
        };
        let params = gpu.buffer(
            "fxaa params",
            bytemuck::bytes_of(&params),
            wgpu::BufferUsages::UNIFORM,
        );
        let output = gpu.scratch(
            "fxaa image",
            width as u64 * height as u64 * 16,
            wgpu::BufferUsages::COPY_SRC,
        );
        let bind = gpu.bind(
            "fxaa",
            &layout,
            &[
                params.as_entire_binding(),
                input.as_entire_binding(),
                output.as_entire_binding(),
            ],
        );
        FxaaPass {
            pipe,
            bind,
            output,
            size: (width, height),
        }
    }

    pub fn record(&self, enc: &mut wgpu::CommandEncoder) {
        crate::gpu::dispatch_image(enc, &self.pipe, &self.bind, self.size);
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn the_uniform_matches_its_wgsl_struct() {
        crate::prelude::assert_layout!(
            super::SHADER,
            "Params",
            super::FxaaParams { width, height, pad }
        );
    }
}
