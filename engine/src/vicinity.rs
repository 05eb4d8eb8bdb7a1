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
//! counted as open, so a tube at the border is not brighter than one in the middle.

use crate::camera::{Camera, Projection};
use crate::gbuffer::GBuffer;
use crate::gpu::{Gpu, Slot, Uniform};
use crate::iso_reference::SplitMix64;

const SHADER: &str = include_str!("../../shaders/vicinity.wgsl");

/// `n` points in the unit disk by Mitchell's best-candidate algorithm (a Poisson-disk-like
/// blue-noise set; deterministic): each point is the best of `10 i + 1` uniform candidates,
/// the one furthest from the points so far.
pub fn poisson_disk(n: usize) -> Vec<[f32; 2]> {
    let mut rng = SplitMix64(0x5eed_d15c);
    let mut pts: Vec<[f64; 2]> = Vec::with_capacity(n);
    let mut uniform = || {
        let r = rng.next_f64().sqrt();
        let a = std::f64::consts::TAU * rng.next_f64();
        [r * a.cos(), r * a.sin()]
    };
    for i in 0..n {
        let mut best = ([0.0; 2], -1.0);
        for _ in 0..(10 * i + 1) {
            let c = uniform();
            let d = pts
                .iter()
                .map(|p| (p[0] - c[0]).powi(2) + (p[1] - c[1]).powi(2))
                .fold(f64::INFINITY, f64::min);
            if d > best.1 {
                best = (c, d);
            }
        }
        pts.push(best.0);
    }
    pts.iter().map(|p| [p[0] as f32, p[1] as f32]).collect()
}

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
    pub output: wgpu::Buffer,
    size: (u32, u32),
}

impl VicinityPass {
    pub fn new(
        gpu: &Gpu,
        camera: &Camera,
        width: u32,
        height: u32,
        gbuf: &GBuffer,
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
            .u32x4([width, height, 0, 0]);
        let params = gpu.buffer("vicinity params", &u.0, wgpu::BufferUsages::UNIFORM);
        let disk = poisson_disk(s.samples.max(1) as usize);
        let disk = gpu.buffer(
            "vicinity disk",
            bytemuck::cast_slice(&disk),
            wgpu::BufferUsages::STORAGE,
        );
        let output = gpu.scratch(
            "vicinity",
            width as u64 * height as u64 * 4,
            wgpu::BufferUsages::COPY_SRC,
        );
        let bind = gpu.bind(
            "vicinity",
            &layout,
            &[
                params.as_entire_binding(),
                wgpu::BindingResource::TextureView(&gbuf.front),
                disk.as_entire_binding(),
                output.as_entire_binding(),
            ],
        );
        VicinityPass {
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
    use super::*;

    #[test]
    fn poisson_disk_points_are_in_the_disk_and_spread() {
        let p = poisson_disk(64);
        assert_eq!(p.len(), 64);
        assert!(p.iter().all(|q| q[0] * q[0] + q[1] * q[1] <= 1.0));
        let mut dmin = f32::INFINITY;
        for i in 0..p.len() {
            for j in 0..i {
                dmin = dmin.min(((p[i][0] - p[j][0]).powi(2) + (p[i][1] - p[j][1]).powi(2)).sqrt());
            }
        }
        // Uniform random points would have pairs far closer; a Poisson-disk set of 64 points
        // in the unit disk keeps them about 0.2 apart (ideal hexagonal packing: 0.24).
        assert!(dmin > 0.1, "closest pair {dmin}");
        // The centroid is near the centre.
        let c = p
            .iter()
            .fold([0.0f32; 2], |a, q| [a[0] + q[0], a[1] + q[1]]);
        assert!((c[0] / 64.0).abs() < 0.1 && (c[1] / 64.0).abs() < 0.1);
    }
}
