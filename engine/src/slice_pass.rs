//! View-aligned slices through the volume and the tubes: the volumetric occlusion buffer
//! (Schott et al., Algorithm 3), the eye buffer (Algorithm 2) and the partial occlusion of the
//! surfaces (Algorithm 4, eq. 1-3), as compute dispatches. Shader: `shaders/slice_pass.wgsl`;
//! the slices' placement is [`EaView`]'s.
//!
//! The model, its errata and the cone-following variant are stated in `occlusion::combined`
//! (the paper's equation index); this module is the GPU side of Algorithms 2-4.

use crate::gbuffer::GBuffer;
use crate::gpu::{Gpu, GpuError, Slot, Uniform};
use occlusion::combined::{auto_cell, blur_stencil};
use occlusion::emission_absorption::{occupancy, EaView, Transfer, BRICK, MAX_CLIP};
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
    /// The layer of the surface terms the partial occlusion goes to (`march`), if any.
    pub partial_layer: Option<u32>,
}

/// A volume as the pass reads it.
pub struct VolumeInput<'a> {
    pub vol: &'a Volume,
    /// As `ea_pass::prepare` returns it (NaN as -3e38).
    pub data: &'a [f32],
    pub tf: &'a Transfer,
}

/// Bytes of one slice's record (`struct Slice` of the shader).
const SLICE_BYTES: u64 = 80;

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
        terms: &wgpu::Buffer,
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
            occlusion::camera::Projection::Perspective { .. }
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
        .u32x4([cells.0, cells.1, cell, vol.tf_rows])
        .u32x4([s.partial_layer.unwrap_or(u32::MAX), 0, 0, 0]);
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
                terms.as_entire_binding(),
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
