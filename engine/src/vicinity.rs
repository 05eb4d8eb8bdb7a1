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
use crate::gpu::{Gpu, Layer, Slot};
use crate::method::{require, SettingError};
use crate::prelude::with_prelude;
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

impl VicinitySettings {
    /// The most samples (the Poisson disk's sets are tuned up to this many).
    pub const MAX_SAMPLES: u32 = 118;

    /// Checks the settings; an error names the field.
    pub fn check(&self) -> Result<(), SettingError> {
        require(self.samples <= Self::MAX_SAMPLES, "samples", || {
            format!("{} exceeds {}", self.samples, Self::MAX_SAMPLES)
        })?;
        require(
            self.distance > 0.0 && self.distance.is_finite(),
            "distance",
            || format!("{} is not positive", self.distance),
        )?;
        require(self.bias >= 0.0 && self.bias.is_finite(), "bias", || {
            "must be finite and >= 0".into()
        })
    }
}

/// The pass's uniform. Keep in sync with `struct Params` in `shaders/vicinity.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct VicinityParams {
    /// The projection's P00 and P11.
    pub p00: f32,
    pub p11: f32,
    /// 1: perspective, 0: orthographic.
    pub perspective: u32,
    /// `l_vicinity tan(theta)`, world units.
    pub radius: f32,
    /// The depth bias and the reach `l_vicinity`, world units.
    pub bias: f32,
    pub range: f32,
    pub samples: u32,
    /// The layer of the surface terms this pass writes.
    pub layer: u32,
    pub width: u32,
    pub height: u32,
    pub pad: [u32; 2],
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
        let module = gpu.shader("vicinity.wgsl", &with_prelude(SHADER));
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
        let params = VicinityParams {
            p00: p.x_axis.x as f32,
            p11: p.y_axis.y as f32,
            perspective: persp as u32,
            radius: r as f32,
            bias: s.bias as f32,
            range: s.distance as f32,
            samples: s.samples,
            layer: layer.index,
            width,
            height,
            pad: [0; 2],
        };
        let params = gpu.buffer(
            "vicinity params",
            bytemuck::bytes_of(&params),
            wgpu::BufferUsages::UNIFORM,
        );
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

#[cfg(test)]
mod tests {
    #[test]
    fn the_settings_check_names_the_field() {
        let ok = super::VicinitySettings {
            samples: 32,
            distance: 2.0,
            theta_deg: 25.0,
            bias: 0.1,
        };
        assert!(ok.check().is_ok());
        let field = |s: super::VicinitySettings| s.check().unwrap_err().field;
        assert_eq!(
            field(super::VicinitySettings { samples: 119, ..ok }),
            "samples"
        );
        assert_eq!(
            field(super::VicinitySettings {
                distance: f64::NAN,
                ..ok
            }),
            "distance"
        );
        assert_eq!(field(super::VicinitySettings { bias: -1.0, ..ok }), "bias");
    }

    #[test]
    fn the_uniform_matches_its_wgsl_struct() {
        crate::prelude::assert_layout!(
            super::SHADER,
            "Params",
            super::VicinityParams {
                p00,
                p11,
                perspective,
                radius,
                bias,
                range,
                samples,
                layer,
                width,
                height,
                pad,
            }
        );
    }
}
