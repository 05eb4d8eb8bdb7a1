//! Vicinity occlusion: the tubes' occlusion of each other from the G-buffer's depths (Schott
//! et al., section 3.2.5, Algorithm 5, eq. 4-6), as a compute pass. Shader:
//! `shaders/vicinity.wgsl`.
//!
//! For a pixel whose nearest surface is at linear depth `z`, `N` Poisson-disk offsets `p_i`
//! (unit disk, [`poisson_disk`]) are scaled to the texture-space radius of the world radius
//! `r = l_vicinity tan(theta)` at that depth and added to the pixel (eq. 6). Eq. 4-5 as printed
//! project `(r, r, z, 1)` through `T P`, whose 0.5 offset makes the result a position, not a
//! radius; the radius is `R_t = 0.5 (P00, P11) r / |z|` under perspective and
//! `0.5 (P00, P11) r` under orthographic projection (derivation: `camera.rs`). A neighbour at
//! depth `z_n` occludes when `z_n < z - bias` (it is closer to the eye than the biased
//! surface; Algorithm 5 adds the bias the other way, `z + bias`, which makes flat surfaces
//! occlude themselves) and `z - z_n <= l_vicinity` (the cone's reach: an occluder further than
//! the virtual slice distance lies outside the base it was sized for). The term is
//! `1 - hits / valid`: samples that fall off the screen are unknown and left out rather than
//! counted as open, so a tube at the border is not brighter than one in the middle. The term
//! is written into its layer of the frame's surface terms (see `renderer`).

use crate::gbuffer::GBuffer;
use crate::gpu::{Gpu, Layer, Slot, Uniform};
use occlusion::camera::{Camera, Projection};
use occlusion::combined::poisson_disk;

const SHADER: &str = include_str!("../../shaders/vicinity.wgsl");

/// Settings of the pass.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VicinitySettings {
    pub samples: u32,
    /// Virtual slice distance l_vicinity, world units.
    pub distance: f64,
    pub theta_deg: f64,
    /// Depth bias, world units.
    pub bias: f64,
}

pub struct VicinityPass {
    pipe: wgpu::ComputePipeline,
    bind: wgpu::BindGroup,
    size: (u32, u32),
}

impl VicinityPass {
    pub fn new(
        gpu: &Gpu,
        camera: &Camera,
        width: u32,
        height: u32,
        gbuf: &GBuffer,
        layer: Layer,
        s: &VicinitySettings,
    ) -> VicinityPass {
        let module = gpu.shader("vicinity.wgsl", SHADER);
        let layout = gpu.layout(
            "vicinity",
            wgpu::ShaderStages::COMPUTE,
            &[
                Slot::Uniform,
                Slot::UnfilterableTexture,
                Slot::Storage,
                Slot::StorageRw,
            ],
        );
        let pl = gpu.pipeline_layout("vicinity", &[&layout]);
        let pipe = gpu.compute_pipeline_with(&module, "main", &pl, "vicinity");
        let p = camera.projection_matrix(width as f64 / height.max(1) as f64);
        let persp = matches!(camera.projection, Projection::Perspective { .. });
        let r = s.distance * s.theta_deg.to_radians().tan();
        let mut u = Uniform::default();
        u.vec4([p.x_axis.x, p.y_axis.y, if persp { 1.0 } else { 0.0 }, r])
            .vec4([s.bias, s.distance, s.samples as f64, 0.0])
            .u32x4([width, height, layer.index, 0]);
        let params = gpu.buffer("vicinity params", &u.0, wgpu::BufferUsages::UNIFORM);
        let disk = poisson_disk(s.samples.max(1) as usize);
        let disk = gpu.buffer(
            "vicinity disk",
            bytemuck::cast_slice(&disk),
            wgpu::BufferUsages::STORAGE,
        );
        let bind = gpu.bind(
            "vicinity",
            &layout,
            &[
                params.as_entire_binding(),
                wgpu::BindingResource::TextureView(&gbuf.front),
                disk.as_entire_binding(),
                layer.terms.as_entire_binding(),
            ],
        );
        VicinityPass {
            pipe,
            bind,
            size: (width, height),
        }
    }

    pub fn record(&self, enc: &mut wgpu::CommandEncoder) {
        crate::gpu::dispatch_image(enc, &self.pipe, &self.bind, self.size);
    }
}
