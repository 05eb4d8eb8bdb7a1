//! LineAO (Eichelbaum, Hlawitschka and Scheuermann, IEEE TVCG 2013, eq. 4-16) as a surface
//! term: the lines' and tubes' ambient occlusion from the G-buffer's normal-depth map. Shader:
//! `shaders/line_ao.wgsl`. The model, where it departs from the paper and why, and the CPU twin
//! whose functions the WGSL follows one by one: `occlusion::line_ao`.
//!
//! Three compute dispatches, recorded as one pass (`lineao` in the pass timings):
//! 1. `nd_level0`: the G-buffer's guard-banded normal-depth map ([`crate::gbuffer::NdMap`]) as
//!    level 0 of the pyramid: depth normalised over the camera's clipping range, normal turned
//!    into view space.
//! 2. `nd_half`, once per further level: the 2 x 2 mean with background as far.
//! 3. `main`: the kernel at every viewport pixel, which writes the visibility `1 - LineAO` into
//!    its layer of the frame's surface terms and the factor channels `V`, `g_depth`, `g_light`
//!    (seed 002 Fig. 4) into [`LineAoPass::factors`].
//!
//! What is per pixel here and a single value in the twin: `z(P)` (from the pixel's linear depth,
//! `0.5 P11 H / z` or `0.5 P11 H` orthographic: [`occlusion::line_ao::zoom_px`]) and the width
//! `r0` follows, read from the normal-depth map's width code - a pixel width for pixel-width
//! lines (`r0 = 1.5 w`), a world diameter for tubes and world-width lines (eq. 16, `r0 = 1.5
//! z(P) t_s`), and 2 pixels where it is unknown (meshes read from files).
//!
//! The guard band ([`guard_pixels`]): the normal-depth map extends `g` pixels beyond the
//! viewport, `g` the largest disc radius any pixel can have (its widest line at the scene's
//! nearest depth, plus the outer levels' step) rounded up to a multiple of `2^(s_r - 1)` so that
//! the pyramid's blocks line up with an unguarded one's, and capped at `render.lineao.guard`.
//! Samples beyond the band - only where the cap was reached - are left out of their level's
//! mean (the renormalising rule of the twin and of the vicinity pass).

use crate::gbuffer::GBuffer;
use crate::gpu::{Gpu, Layer, Slot};
use crate::method::LineAo;
use crate::prelude::with_prelude;
use occlusion::camera::{Camera, Projection};
use occlusion::line_ao::{
    level_angle, Alignment, Falloff, LevelsCombine, LineAoSettings, Visibility, MAX_LEVELS,
};

const SHADER: &str = include_str!("../../shaders/line_ao.wgsl");

/// The factor channels' names after `occlusion.lineao.` (the AOV `occlusion.lineao.v`, ...).
pub const FACTORS: [&str; 4] = ["v", "g_depth", "g_light", "g_align"];

/// The pass's uniform. Keep in sync with `struct Params` in `shaders/line_ao.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct LineAoParams {
    pub right: [f32; 4],
    pub up: [f32; 4],
    pub back: [f32; 4],
    pub near: f32,
    pub far: f32,
    pub zoom_scale: f32,
    pub perspective: u32,
    pub width: u32,
    pub height: u32,
    pub nd_width: u32,
    pub nd_height: u32,
    pub guard: u32,
    pub levels: u32,
    pub samples: u32,
    pub layer: u32,
    pub r0_widths: f32,
    pub radius_step: f32,
    pub delta0: f32,
    pub light_intensity: f32,
    pub light_diffuse: f32,
    pub light_specular: f32,
    pub light_shininess: f32,
    pub seed: u32,
    pub constant_falloff: u32,
    pub plane: u32,
    pub anisotropic: u32,
    pub paper_alignment: u32,
    pub intensity: f32,
    pub floor: f32,
    pub mean_levels: u32,
    pub pad2: u32,
    pub level_angle: [[f32; 4]; 2],
    pub level_offset: [[u32; 4]; 2],
    pub level_size: [[u32; 4]; 4],
}

/// One halving's uniform. Keep in sync with `struct Half` in `shaders/line_ao.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct HalfParams {
    pub src: u32,
    pub pad0: u32,
    pub pad1: u32,
    pub pad2: u32,
}

/// The widths LineAO's discs are sized from: the widest pixel-width line set (pixels) and the
/// widest world width (world-width lines, tube diameters; world units).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Widths {
    pub pixels: f32,
    pub world: f32,
}

/// The guard band in pixels for a viewport `height` pixels high: the largest disc radius a
/// pixel of the scene can get - `r0` of the widest line (2 pixels at least, the kernel's width
/// where it is unknown) and the outer levels' `(s_r - 1) step z`, with `z(P)` at the camera's
/// near plane, the nearest a surface can be - plus one pixel, rounded up to a multiple of
/// `2^(s_r - 1)` (the pyramid's blocks then line up with an unguarded map's) and capped at
/// `cap` (rounded down to that multiple). 0 when `cap` is 0.
pub fn guard_pixels(
    camera: &Camera,
    height: u32,
    widths: Widths,
    s: &LineAoSettings,
    cap: u32,
) -> u32 {
    let block = 1u32 << (s.levels.clamp(1, MAX_LEVELS as u32) - 1);
    let cap = cap / block * block;
    if cap == 0 {
        return 0;
    }
    let zoom = occlusion::line_ao::zoom_px(camera, camera.near, height);
    let zoom = if zoom.is_finite() { zoom } else { f32::MAX };
    let width = widths.pixels.max(widths.world * zoom).max(2.0);
    let r = s.r0_widths * width + (s.levels.max(1) - 1) as f32 * s.radius_step * zoom + 1.0;
    // A NaN radius takes the cap too.
    if r.is_nan() || r >= cap as f32 {
        return cap;
    }
    (r.ceil() as u32).div_ceil(block) * block
}

/// The pyramid's levels: each one's first texel in the buffer and its size.
fn level_layout(size: (u32, u32), levels: u32) -> (Vec<u32>, Vec<(u32, u32)>, u32) {
    let (mut off, mut sizes, mut total) = (vec![], vec![], 0u32);
    let (mut w, mut h) = size;
    for _ in 0..levels {
        off.push(total);
        sizes.push((w, h));
        total += w * h;
        (w, h) = (w.div_ceil(2), h.div_ceil(2));
    }
    (off, sizes, total)
}

/// The LineAO pass of one frame.
pub struct LineAoPass {
    level0: wgpu::ComputePipeline,
    half: wgpu::ComputePipeline,
    kernel: wgpu::ComputePipeline,
    /// One bind group per halving (they differ in the level they read), the first also for
    /// level 0 and the kernel.
    binds: Vec<wgpu::BindGroup>,
    sizes: Vec<(u32, u32)>,
    size: (u32, u32),
    /// The factor channels [`FACTORS`], each `width * height` f32 (1 = open).
    pub factors: wgpu::Buffer,
    /// The pyramid (view normal xyz, normalised depth), level after level.
    pub pyramid: wgpu::Buffer,
}

impl LineAoPass {
    /// The pass over `gbuf`'s normal-depth map (which must exist) for `camera` at `width x
    /// height`, writing `layer`; `light` is the head light's material (ambient, diffuse,
    /// specular, shininess) for `g_light`'s BRDF.
    pub fn new(
        gpu: &Gpu,
        camera: &Camera,
        (width, height): (u32, u32),
        gbuf: &GBuffer,
        layer: Layer,
        s: &LineAo,
        light: [f64; 4],
    ) -> LineAoPass {
        let nd = gbuf
            .nd
            .as_ref()
            .expect("LineAO's pass needs the G-buffer's normal-depth map");
        let k = &s.kernel;
        let levels = k.levels.clamp(1, MAX_LEVELS as u32);
        let module = gpu.shader("line_ao.wgsl", &with_prelude(SHADER));
        let layout = gpu.layout(
            "lineao",
            wgpu::ShaderStages::COMPUTE,
            &[
                Slot::Uniform,
                Slot::UnfilterableTexture,
                Slot::UnfilterableTexture,
                Slot::StorageRw,
                Slot::Uniform,
                Slot::StorageRw,
                Slot::StorageRw,
                Slot::StorageRw,
                Slot::UnfilterableTexture,
                Slot::StorageRw,
            ],
        );
        let pl = gpu.pipeline_layout("lineao", &[&layout]);
        let pipe = |entry: &str| gpu.compute_pipeline_with(&module, entry, &pl, entry);
        let (offsets, sizes, total) = level_layout(nd.size, levels);
        let aspect = width as f64 / height.max(1) as f64;
        let p11 = camera.projection_matrix(aspect).y_axis.y;
        let perspective = matches!(camera.projection, Projection::Perspective { .. });
        let f = camera.forward();
        let right = f.cross(camera.up).normalize();
        let up = right.cross(f);
        let v4 = |v: glam::DVec3| [v.x as f32, v.y as f32, v.z as f32, 0.0];
        let mut level_angle_a = [[0.0f32; 4]; 2];
        let mut level_offset = [[0u32; 4]; 2];
        let mut level_size = [[0u32; 4]; 4];
        for j in 0..levels as usize {
            level_angle_a[j / 4][j % 4] = level_angle(j as u32);
            level_offset[j / 4][j % 4] = offsets[j];
            level_size[j / 2][2 * (j % 2)] = sizes[j].0;
            level_size[j / 2][2 * (j % 2) + 1] = sizes[j].1;
        }
        let params = LineAoParams {
            right: v4(right),
            up: v4(up),
            back: v4(-f),
            near: camera.near as f32,
            far: camera.far as f32,
            zoom_scale: (0.5 * p11 * height as f64) as f32,
            perspective: perspective as u32,
            width,
            height,
            nd_width: nd.size.0,
            nd_height: nd.size.1,
            guard: nd.guard,
            levels,
            samples: k.samples,
            layer: layer.index,
            r0_widths: k.r0_widths,
            radius_step: k.radius_step,
            delta0: k.delta0,
            light_intensity: k.light_intensity,
            light_diffuse: light[1] as f32,
            light_specular: light[2] as f32,
            light_shininess: light[3] as f32,
            seed: k.seed,
            constant_falloff: (k.falloff == Falloff::Constant) as u32,
            plane: (k.visibility == Visibility::Plane) as u32,
            anisotropic: k.anisotropic as u32,
            paper_alignment: (k.alignment == Alignment::Paper) as u32,
            intensity: k.intensity,
            floor: k.floor,
            mean_levels: (k.levels_combine == LevelsCombine::Mean) as u32,
            pad2: 0,
            level_angle: level_angle_a,
            level_offset,
            level_size,
        };
        let params = gpu.buffer(
            "lineao params",
            bytemuck::bytes_of(&params),
            wgpu::BufferUsages::UNIFORM,
        );
        let n = width as u64 * height as u64;
        let pyramid = gpu.scratch(
            "lineao pyramid",
            total as u64 * 16,
            wgpu::BufferUsages::COPY_SRC,
        );
        let cover = gpu.scratch(
            "lineao cover",
            total as u64 * 4,
            wgpu::BufferUsages::empty(),
        );
        let tangents = gpu.scratch(
            "lineao tangents",
            total as u64 * 16,
            wgpu::BufferUsages::empty(),
        );
        let factors = gpu.scratch(
            "lineao factors",
            n * 4 * FACTORS.len() as u64,
            wgpu::BufferUsages::COPY_SRC,
        );
        let binds = (0..levels.max(2) - 1)
            .map(|src| {
                let half = gpu.buffer(
                    "lineao half",
                    bytemuck::bytes_of(&HalfParams {
                        src,
                        pad0: 0,
                        pad1: 0,
                        pad2: 0,
                    }),
                    wgpu::BufferUsages::UNIFORM,
                );
                gpu.bind(
                    "lineao",
                    &layout,
                    &[
                        params.as_entire_binding(),
                        wgpu::BindingResource::TextureView(&nd.depth),
                        wgpu::BindingResource::TextureView(&nd.normal),
                        pyramid.as_entire_binding(),
                        half.as_entire_binding(),
                        layer.terms.as_entire_binding(),
                        factors.as_entire_binding(),
                        cover.as_entire_binding(),
                        wgpu::BindingResource::TextureView(&nd.tangent),
                        tangents.as_entire_binding(),
                    ],
                )
            })
            .collect();
        LineAoPass {
            level0: pipe("nd_level0"),
            half: pipe("nd_half"),
            kernel: pipe("main"),
            binds,
            sizes,
            size: (width, height),
            factors,
            pyramid,
        }
    }

    pub fn record(&self, enc: &mut wgpu::CommandEncoder) {
        use crate::gpu::dispatch_image;
        dispatch_image(enc, &self.level0, &self.binds[0], self.sizes[0]);
        for j in 1..self.sizes.len() {
            dispatch_image(enc, &self.half, &self.binds[j - 1], self.sizes[j]);
        }
        dispatch_image(enc, &self.kernel, &self.binds[0], self.size);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    #[test]
    fn the_uniforms_match_their_wgsl_structs() {
        crate::prelude::assert_layout!(
            super::SHADER,
            "Params",
            super::LineAoParams {
                right,
                up,
                back,
                near,
                far,
                zoom_scale,
                perspective,
                width,
                height,
                nd_width,
                nd_height,
                guard,
                levels,
                samples,
                layer,
                r0_widths,
                radius_step,
                delta0,
                light_intensity,
                light_diffuse,
                light_specular,
                light_shininess,
                seed,
                constant_falloff,
                plane,
                anisotropic,
                paper_alignment,
                intensity,
                floor,
                mean_levels,
                pad2,
                level_angle,
                level_offset,
                level_size,
            }
        );
        crate::prelude::assert_layout!(
            super::SHADER,
            "Half",
            super::HalfParams {
                src,
                pad0,
                pad1,
                pad2,
            }
        );
    }

    fn ortho(height: f64) -> Camera {
        Camera {
            eye: DVec3::new(0.0, 0.0, 10.0),
            target: DVec3::ZERO,
            up: DVec3::Y,
            projection: Projection::Orthographic { height },
            near: 1.0,
            far: 20.0,
            skew: 0.0,
        }
    }

    #[test]
    fn the_guard_band_covers_the_largest_disc_in_whole_blocks_up_to_its_cap() {
        // Orthographic, 100 px for 10 world units: z = 10 px per world unit. r0 = 1.5 x 2 px,
        // two outer levels of 1 world unit: 3 + 20 + 1 = 24 px, a multiple of 4 already.
        let s = LineAoSettings::default();
        let cam = ortho(10.0);
        let w = Widths {
            pixels: 2.0,
            world: 0.0,
        };
        assert_eq!(guard_pixels(&cam, 100, w, &s, 64), 24);
        // A wider line: 1.5 x 5 = 7.5 -> 28.5 -> 29 -> 32.
        let wide = Widths {
            pixels: 5.0,
            world: 0.0,
        };
        assert_eq!(guard_pixels(&cam, 100, wide, &s, 64), 32);
        // Tubes of diameter 1: r0 = 1.5 x 10 px = 15 -> 36.
        let tubes = Widths {
            pixels: 0.0,
            world: 1.0,
        };
        assert_eq!(guard_pixels(&cam, 100, tubes, &s, 64), 36);
        // The cap, rounded down to whole blocks; 0 disables.
        assert_eq!(guard_pixels(&cam, 100, tubes, &s, 30), 28);
        assert_eq!(guard_pixels(&cam, 100, tubes, &s, 0), 0);
        assert_eq!(guard_pixels(&cam, 100, tubes, &s, 3), 0);
        // One level: blocks of 1, no outer discs.
        let one = LineAoSettings { levels: 1, ..s };
        assert_eq!(guard_pixels(&cam, 100, w, &one, 64), 4);
    }

    #[test]
    fn the_levels_halve_with_ceil() {
        let (off, sizes, total) = level_layout((5, 3), 3);
        assert_eq!(sizes, vec![(5, 3), (3, 2), (2, 1)]);
        assert_eq!(off, vec![0, 15, 21]);
        assert_eq!(total, 23);
    }
}
