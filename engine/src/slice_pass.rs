//! View-aligned slices through the volume and the tubes: the volumetric occlusion buffer
//! (Schott et al., Algorithm 3), the eye buffer (Algorithm 2) and the partial occlusion of the
//! surfaces (Algorithm 4, eq. 1-3), as compute dispatches. Shader: `shaders/slice_pass.wgsl`;
//! the slices' placement is [`EaView`]'s.
//!
//! The model (issue 5 states the intended maths where the paper's pseudo-code errs):
//! * Slice k is the plane at view depth `z_k = z0 + (k + 1/2) d`, standing for the slab
//!   `[z0 + k d, z0 + (k + 1) d]`. The transfer function gives extinction sigma per world
//!   unit; a slab's opacity along a ray is `1 - exp(-sigma d / cos phi)`.
//! * The light is the head light: a cone of half-angle theta around the direction towards the
//!   eye. `O_k(x)`, the light arriving at slice k at x (`O_0 = 1`), is gathered from the light
//!   leaving slice k - 1, `L_{k-1} = O_{k-1} (1 - alpha_{k-1})`, averaged over the disk the
//!   cone cuts from slice k - 1: radius `d tan(theta)` in world units, projected as
//!   `0.5 (P00, P11) r / z_{k-1}` in texture units (orthographic: without the division; see
//!   `camera::texture_radius`), sampled with `n x n` taps (`blur_samples`) mapped
//!   concentrically onto the disk, bilinear ([`blur_stencil`]). This is the paper's incremental
//!   blur ("ComputeDOS", after Schott et al. 2009): each slice blurs the previous one.
//! * Geometry into volume (Alg. 3): where slice k lies inside a tube (`front <= z_k <= back`),
//!   the tube's extinction `geometry_extinction` adds to the volume's for the light leaving
//!   the slice. The paper, with the front depth only, replaces the opacity of every sample
//!   behind a surface (an endless shadow column; its test `f_depth < geom_depth` is a typo for
//!   "behind") - kept as `geometry_shadow = "column"`.
//! * Eye buffer (Alg. 2): volume colour `c alpha O_k` composited front to back (`dos`,
//!   `combined`; `ea` and `vicinity` leave `O` out, `phong` shades `c` with the gradient), the
//!   sampling distance clipped where the ray meets the nearest surface of the G-buffer.
//! * Partial occlusion (Alg. 4, eq. 1-3): a surface at depth `z_s` between `z_{k-1}` and `z_k`
//!   receives `lerp(O_{k-1}, O_k, (z_s - z_{k-1}) / d)`. Algorithm 1's order of updates with
//!   Algorithm 3's buffer swap reverses these weights if copied literally.
//!
//! The cone-following model (`render.occlusion_model = "cone"`; issue 5 item 5). The paper's
//! incremental blur is a random walk: a blur of radius `r` (uniform disk, variance `r^2 / 4`
//! per axis) per slice spreads a shadow after a distance `L` to a standard deviation of
//! `tan(theta) sqrt(L d) / 2`, where the cone it models puts it on a disk of radius
//! `L tan(theta)` (deviation `L tan(theta) / 2`); the result depends on the slice count and
//! never reaches the cone. Here each cell also carries the shadow-weighted age `D` of its
//! shadow (how far behind its occluders it lies; the buffers hold `L` and `(1 - L) D`), and
//! the step's radius is chosen so the variances add up to the cone's:
//! `r^2 = tan^2(theta) ((D + d)^2 - D^2)`, i.e. `r = d tan(theta) sqrt(1 + 2 D / d)` - the
//! paper's radius at `D = 0`; after `n` steps from a point occluder the variance is
//! `(n d tan(theta))^2 / 4`, the cone's at `L = n d`, whatever `d` is. Ages mix linearly where
//! shadows of different occluders overlap (an approximation), and the taps (`n x n`, at least
//! `blur_samples`, up to 9 per axis) grow with the radius in cells.
//!
//! Departure from the paper, for speed (issue 5, "beat the paper's design"): the occlusion
//! buffer lives on cells of `s x s` pixels (`render.occlusion_cell`), one dispatch per slice
//! (the `light` entry; the dispatch is the barrier the blur needs), and stores every slice's
//! `O_k` in a light volume (cells x slices). The eye buffer is then one dispatch (`march`): all
//! slices of a pixel in one invocation, with `O` read bilinearly from the light volume, rays
//! clipped to the grid's box and to the surface, empty 8^3 bricks skipped (exact, see
//! `ea_pass::occupancy`), early termination at opacity 0.999 - none of which the
//! slice-by-slice eye buffer can do. A cell's transmittance through the tubes is the mean over
//! its pixels (coverage), its volume sample the one on its centre ray. A surface reads its
//! partial occlusion at the nearest surface depth of the cells around it, so that a tube does
//! not shadow itself through the cell it shares with its own silhouette; occluders nearer than
//! that within a cell are left to the vicinity term. With `s = 1` the light is the paper's
//! per-pixel buffer (the tubes exactly as in the model above).

use crate::ea_pass::{occupancy, EaView, Transfer, BRICK, MAX_CLIP};
use crate::gbuffer::GBuffer;
use crate::gpu::{Gpu, GpuError, Slot, Uniform};
use volume::Volume;

const SHADER: &str = include_str!("../../shaders/slice_pass.wgsl");

/// How the slices shade.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SliceSettings {
    /// Run the occlusion buffer (one dispatch per slice) and shade the volume with it.
    pub occlusion: bool,
    /// Cell edge of the occlusion buffer in pixels (None: [`auto_cell`] from 2).
    pub cell: Option<u32>,
    /// The cone-following model instead of the paper's constant per-slice blur.
    pub cone: bool,
    /// Phong shading of the volume with on-the-fly gradients.
    pub phong: bool,
    /// The paper's endless shadow column behind surfaces instead of the tubes' thickness.
    pub column: bool,
    pub theta_deg: f64,
    pub blur_samples: u32,
    pub geometry_extinction: f64,
    /// ambient, diffuse, specular, shininess
    pub light: [f64; 4],
}

/// A volume as the pass reads it.
pub struct VolumeInput<'a> {
    pub vol: &'a Volume,
    /// As `ea_pass::prepare` returns it (NaN as -3e38).
    pub data: &'a [f32],
    pub tf: &'a Transfer,
}

/// Cell edge in pixels when the scene does not fix it: the smallest power of two (at least
/// `min`) whose light volume (`cells x slices` f32) fits in `budget` bytes.
pub fn auto_cell(width: u32, height: u32, slices: u32, min: u32, budget: u64) -> u32 {
    let mut s = min.max(1);
    while s < 64 {
        let cells = width.div_ceil(s) as u64 * height.div_ceil(s) as u64;
        if cells * slices as u64 * 4 <= budget {
            break;
        }
        s *= 2;
    }
    s
}

/// Bytes of one slice's record (`struct Slice` of the shader).
const SLICE_BYTES: u64 = 80;

/// The occlusion blur of one slice, a uniform disk of radius `rpx` cells (x, y). On a grid a
/// sub-cell blur cannot be sampled with bilinear taps without adding the interpolation's own
/// diffusion (a tap at offset `o` spreads variance `|o| (1 - |o|)`, linear in `o`, where the
/// disk adds `r^2 / 4`): repeated every slice, that diffusion would dominate and make the
/// spread depend on the cell size instead of the cone. Up to a radius of two cells the blur
/// is therefore the 3x3 stencil with the disk's variance per axis, `v = r^2 / 4`: the outer
/// product of `[v/2, 1 - v, v/2]` in x and y (rows y = -1, 0, 1), returned with `false`; the
/// same for every cell of the slice. Beyond, `true`: the shader takes `n x n` bilinear taps
/// mapped concentrically onto the disk (`n` = `blur_samples`).
pub fn blur_stencil(rpx: [f64; 2]) -> (bool, [[f64; 3]; 3]) {
    let mut w = [[0.0; 3]; 3];
    if rpx[0] > 2.0 || rpx[1] > 2.0 {
        return (true, w);
    }
    let k = |r: f64| {
        let v = r * r / 4.0;
        [v / 2.0, 1.0 - v, v / 2.0]
    };
    let (kx, ky) = (k(rpx[0]), k(rpx[1]));
    for (y, row) in w.iter_mut().enumerate() {
        for (x, c) in row.iter_mut().enumerate() {
            *c = ky[y] * kx[x];
        }
    }
    (false, w)
}

/// A volume on the GPU: its samples, its transfer function (1-D points, then the 2-D rows'
/// ranges) and the brick occupancy of [`occupancy`], uploaded once and read by every frame.
#[derive(Clone)]
pub struct GpuVolume {
    field: wgpu::Buffer,
    tf: wgpu::Buffer,
    occ: wgpu::Buffer,
    dims: [usize; 3],
    world_to_index: glam::DMat4,
    bricks: [usize; 3],
    tf_points: u32,
    tf_rows: u32,
}

impl GpuVolume {
    /// Uploads `vi`; an error when its samples exceed the adapter's storage binding limit.
    pub fn upload(gpu: &Gpu, vi: &VolumeInput) -> Result<GpuVolume, GpuError> {
        let limit = gpu.device.limits().max_storage_buffer_binding_size as usize;
        if vi.data.len() * 4 > limit {
            return Err(GpuError::Operation(format!(
                "the volume has {} samples; this adapter binds at most {} bytes ({} samples)",
                vi.data.len(),
                limit,
                limit / 4
            )));
        }
        let mut tfb: Vec<f32> = Vec::with_capacity(8 * vi.tf.points.len().max(1));
        for (val, rgb, sigma) in &vi.tf.points {
            tfb.extend([
                *val as f32,
                rgb[0] as f32,
                rgb[1] as f32,
                rgb[2] as f32,
                *sigma as f32,
                0.0,
                0.0,
                0.0,
            ]);
        }
        let rows = vi.tf.row_slices();
        let mut first = 0usize;
        for (r, p) in vi.tf.rows.iter().zip(&rows) {
            tfb.extend([r.0 as f32, first as f32, (first + p.len()) as f32, 0.0]);
            first += p.len();
        }
        let (bricks, occ) = occupancy(vi.data, vi.vol.dims, vi.tf);
        Ok(Self::make(
            gpu,
            vi.data,
            &tfb,
            &occ,
            vi.vol.dims,
            vi.vol.affine.inverse(),
            bricks,
            (vi.tf.points.len() as u32, vi.tf.rows.len() as u32),
        ))
    }

    #[allow(clippy::too_many_arguments)]
    fn make(
        gpu: &Gpu,
        field: &[f32],
        tf: &[f32],
        occ: &[u32],
        dims: [usize; 3],
        world_to_index: glam::DMat4,
        bricks: [usize; 3],
        (tf_points, tf_rows): (u32, u32),
    ) -> GpuVolume {
        let storage = wgpu::BufferUsages::STORAGE;
        GpuVolume {
            field: gpu.buffer("slice field", bytemuck::cast_slice(field), storage),
            tf: gpu.buffer("slice transfer", bytemuck::cast_slice(tf), storage),
            occ: gpu.buffer("slice occupancy", bytemuck::cast_slice(occ), storage),
            dims,
            world_to_index,
            bricks,
            tf_points,
            tf_rows,
        }
    }

    /// The stand-in the passes bind when a scene has no volume (never sampled).
    fn none(gpu: &Gpu) -> GpuVolume {
        gpu.cached("no volume".into(), || {
            Self::make(
                gpu,
                &[0.0; 8],
                &[0.0; 8],
                &[0],
                [2, 2, 2],
                glam::DMat4::IDENTITY,
                [1, 1, 1],
                (0, 0),
            )
        })
    }
}

pub struct SlicePass {
    light_pipe: wgpu::ComputePipeline,
    march_pipe: wgpu::ComputePipeline,
    group0: wgpu::BindGroup,
    /// Ping-pong: slice k uses `group1[k % 2]`.
    group1: [wgpu::BindGroup; 2],
    stride: u32,
    pub eye: wgpu::Buffer,
    pub state: wgpu::Buffer,
    pub slices: u32,
    occlusion: bool,
    size: (u32, u32),
    cells: (u32, u32),
    /// Cell edge in pixels.
    pub cell: u32,
}

impl SlicePass {
    pub fn new(
        gpu: &Gpu,
        volume: Option<&GpuVolume>,
        v: &EaView,
        gbuf: &GBuffer,
        s: &SliceSettings,
    ) -> Result<SlicePass, GpuError> {
        let device = &gpu.device;
        if v.clip.len() > MAX_CLIP {
            return Err(GpuError::Operation(format!(
                "{} clipping planes; at most {MAX_CLIP}",
                v.clip.len()
            )));
        }
        let limit = device.limits().max_storage_buffer_binding_size as usize;
        let module = gpu.shader("slice_pass.wgsl", SHADER);
        let tf2d = volume.is_some_and(|vi| vi.tf_rows > 0);
        let l0 = gpu.layout(
            "slice group 0",
            wgpu::ShaderStages::COMPUTE,
            &[
                Slot::Uniform,
                Slot::Storage,
                Slot::Storage,
                Slot::Storage,
                Slot::StorageRw,
                Slot::StorageRw,
                Slot::UnfilterableTexture,
                Slot::UnfilterableTexture,
                Slot::StorageRw,
                Slot::StorageRw,
            ],
        );
        let l1 = gpu.layout(
            "slice group 1",
            wgpu::ShaderStages::COMPUTE,
            &[Slot::StorageDynamic, Slot::Storage, Slot::StorageRw],
        );
        let pl = gpu.pipeline_layout("slice", &[&l0, &l1]);
        let light_pipe = gpu.compute_pipeline_constants(
            &module,
            "light",
            &pl,
            "light",
            &[
                ("CONE", if s.cone { 1.0 } else { 0.0 }),
                ("TF2D", if tf2d { 1.0 } else { 0.0 }),
            ],
        );
        let march_pipe = gpu.compute_pipeline_constants(
            &module,
            "march",
            &pl,
            "march",
            &[
                ("PHONG", if s.phong { 1.0 } else { 0.0 }),
                ("TF2D", if tf2d { 1.0 } else { 0.0 }),
            ],
        );

        let aspect = v.width as f64 / v.height.max(1) as f64;
        let proj = v.camera.projection_matrix(aspect);
        let persp = matches!(
            v.camera.projection,
            crate::camera::Projection::Perspective { .. }
        );
        let e = v.camera.eye;
        let f = v.camera.forward();
        let budget = (limit as u64).min(1 << 30);
        let cell = match s.cell {
            Some(c) => c.max(1),
            None => auto_cell(v.width, v.height, v.slices, 2, budget),
        };
        let cells = (v.width.div_ceil(cell), v.height.div_ceil(cell));
        let light_bytes = cells.0 as u64 * cells.1 as u64 * v.slices as u64 * 4;
        if s.occlusion && light_bytes > limit as u64 {
            return Err(GpuError::Operation(format!(
                "the light volume ({} x {} cells x {} slices, {} MB) exceeds this adapter's \
                 storage binding limit ({} MB); raise render.occlusion_cell or lower the \
                 slice count",
                cells.0,
                cells.1,
                v.slices,
                light_bytes >> 20,
                limit >> 20
            )));
        }
        let has_volume = volume.is_some();
        let vol = volume.cloned().unwrap_or_else(|| GpuVolume::none(gpu));
        let (w2i, dims, nb) = (vol.world_to_index, vol.dims, vol.bricks);
        let mut u = Uniform::default();
        u.mat(v.camera.view_projection(aspect).inverse())
            .mat(w2i)
            .vec4([e.x, e.y, e.z, 1.0])
            .vec4([f.x, f.y, f.z, 0.0])
            .u32x4([dims[0] as u32, dims[1] as u32, dims[2] as u32, 0])
            .vec4([
                v.z0,
                v.dz,
                s.theta_deg.to_radians().tan(),
                s.geometry_extinction,
            ])
            .u32x4([v.slices, vol.tf_points, v.width, v.height])
            .u32x4([nb[0] as u32, nb[1] as u32, nb[2] as u32, BRICK as u32]);
        for i in 0..MAX_CLIP {
            let (n, o) = v.clip.get(i).copied().unwrap_or(([0.0; 3], 0.0));
            u.vec4([n[0], n[1], n[2], o]);
        }
        let mode = s.occlusion as u32 | (s.phong as u32) << 1 | (s.column as u32) << 2;
        u.u32x4([
            v.clip.len() as u32,
            mode,
            has_volume as u32,
            s.blur_samples.max(1),
        ])
        .vec4([
            proj.x_axis.x,
            proj.y_axis.y,
            if persp { 1.0 } else { 0.0 },
            0.0,
        ])
        .vec4(s.light)
        .u32x4([cells.0, cells.1, cell, vol.tf_rows]);
        let params = gpu.buffer("slice params", &u.0, wgpu::BufferUsages::UNIFORM);
        let n = v.width as u64 * v.height as u64;
        let eye = gpu.scratch("eye buffer", n * 16, wgpu::BufferUsages::COPY_SRC);
        let state = gpu.scratch("slice state", n * 32, wgpu::BufferUsages::COPY_SRC);
        let ncell = cells.0 as u64 * cells.1 as u64;
        let light = gpu.scratch(
            "light volume",
            if s.occlusion { light_bytes } else { 16 },
            wgpu::BufferUsages::empty(),
        );
        let cell_state = gpu.scratch("cell state", ncell * 16, wgpu::BufferUsages::empty());
        let group0 = gpu.bind(
            "slice group 0",
            &l0,
            &[
                params.as_entire_binding(),
                vol.field.as_entire_binding(),
                vol.tf.as_entire_binding(),
                vol.occ.as_entire_binding(),
                eye.as_entire_binding(),
                state.as_entire_binding(),
                wgpu::BindingResource::TextureView(&gbuf.front),
                wgpu::BindingResource::TextureView(&gbuf.back),
                light.as_entire_binding(),
                cell_state.as_entire_binding(),
            ],
        );
        // Slice indices, one per dynamic-offset row.
        // A storage buffer, not a uniform one: lavapipe inlines uniform values into the shader
        // and recompiles it for every new offset (2.5 ms a dispatch here).
        let align = device.limits().min_storage_buffer_offset_alignment.max(16);
        let stride = (SLICE_BYTES as u32).div_ceil(align) * align;
        let rows = if s.occlusion { v.slices } else { 1 };
        let mut kb = vec![0u8; (rows * stride) as usize];
        let tan = s.theta_deg.to_radians().tan();
        for k in 0..rows {
            // The blur radius in cells at slice k - 1 (perpendicular to the view direction).
            let z = (v.z0 + (k as f64 - 0.5) * v.dz).max(1e-9);
            let r = v.dz * tan;
            let scale = if persp { 0.5 * r / z } else { 0.5 * r } / cell as f64;
            let rpx = [
                scale * proj.x_axis.x * v.width as f64,
                scale * proj.y_axis.y * v.height as f64,
            ];
            let (wide, w) = blur_stencil(rpx);
            let mut u = Uniform::default();
            u.u32x4([k, wide as u32, 0, 0])
                .vec4([rpx[0], rpx[1], 0.0, 0.0]);
            for row in w {
                u.vec4([row[0], row[1], row[2], 0.0]);
            }
            let at = (k * stride) as usize;
            kb[at..at + u.0.len()].copy_from_slice(&u.0);
        }
        let kbuf = gpu.buffer("slice index", &kb, wgpu::BufferUsages::STORAGE);
        let a = gpu.scratch("occlusion a", ncell * 8, wgpu::BufferUsages::empty());
        let b = gpu.scratch("occlusion b", ncell * 8, wgpu::BufferUsages::empty());
        let k_binding = wgpu::BindingResource::Buffer(wgpu::BufferBinding {
            buffer: &kbuf,
            offset: 0,
            size: std::num::NonZeroU64::new(SLICE_BYTES),
        });
        let g1 = |src: &wgpu::Buffer, dst: &wgpu::Buffer| {
            gpu.bind(
                "slice group 1",
                &l1,
                &[
                    k_binding.clone(),
                    src.as_entire_binding(),
                    dst.as_entire_binding(),
                ],
            )
        };
        let group1 = [g1(&a, &b), g1(&b, &a)];
        Ok(SlicePass {
            light_pipe,
            march_pipe,
            group0,
            group1,
            stride,
            eye,
            state,
            slices: v.slices,
            occlusion: s.occlusion,
            size: (v.width, v.height),
            cells,
            cell,
        })
    }

    /// Whether the light volume is computed (the `light` pass has work).
    pub fn has_light(&self) -> bool {
        self.occlusion
    }

    /// Records the light volume, slice by slice, in one compute pass.
    pub fn record_light(&self, enc: &mut wgpu::CommandEncoder) {
        if !self.occlusion {
            return;
        }
        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("light"),
            timestamp_writes: None,
        });
        pass.set_bind_group(0, &self.group0, &[]);
        let (gx, gy) = (self.cells.0.div_ceil(8), self.cells.1.div_ceil(8));
        pass.set_pipeline(&self.light_pipe);
        for k in 0..self.slices {
            pass.set_bind_group(1, &self.group1[(k % 2) as usize], &[k * self.stride]);
            pass.dispatch_workgroups(gx, gy, 1);
        }
    }

    /// Records the eye march (after the light volume).
    pub fn record_march(&self, enc: &mut wgpu::CommandEncoder) {
        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("march"),
            timestamp_writes: None,
        });
        pass.set_bind_group(0, &self.group0, &[]);
        pass.set_pipeline(&self.march_pipe);
        pass.set_bind_group(1, &self.group1[0], &[0]);
        pass.dispatch_workgroups(self.size.0.div_ceil(8), self.size.1.div_ceil(8), 1);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_blur_stencil_has_the_disks_variance_and_sums_to_one() {
        for r in [0.0, 0.3, 1.0, 1.9] {
            let (wide, w) = blur_stencil([r, 0.5 * r]);
            assert!(!wide);
            let sum: f64 = w.iter().flatten().sum();
            assert!((sum - 1.0).abs() < 1e-12);
            // Second moments: x^2 weights against r^2 / 4 (a uniform disk's, per axis).
            let vx: f64 = (0..3)
                .map(|y| {
                    (0..3)
                        .map(|x| w[y][x] * ((x as f64) - 1.0).powi(2))
                        .sum::<f64>()
                })
                .sum();
            let vy: f64 = (0..3)
                .map(|y| {
                    (0..3)
                        .map(|x| w[y][x] * ((y as f64) - 1.0).powi(2))
                        .sum::<f64>()
                })
                .sum();
            assert!((vx - r * r / 4.0).abs() < 1e-12, "{r}: {vx}");
            assert!((vy - r * r / 16.0).abs() < 1e-12, "{r}: {vy}");
            assert!(w.iter().flatten().all(|&v| v >= 0.0));
        }
        assert!(
            blur_stencil([2.5, 0.1]).0,
            "beyond two cells the shader takes taps"
        );
    }

    #[test]
    fn the_cell_size_grows_until_the_light_volume_fits() {
        // 512^2 x 512 slices of f32: 512 MB at cell 1, 128 MB at 2, 32 MB at 4.
        assert_eq!(auto_cell(512, 512, 512, 1, 1 << 30), 1);
        assert_eq!(auto_cell(512, 512, 512, 1, 128 << 20), 2);
        assert_eq!(auto_cell(512, 512, 512, 2, 100 << 20), 4);
        assert_eq!(auto_cell(512, 512, 512, 2, 1 << 30), 2);
    }
}
