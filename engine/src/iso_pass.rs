//! Isosurface mode (issue 5 item 6; Singh, Yuksel and House, ISVC 2009, section 3): the
//! volume drawn as an isosurface, ray-marched on the GPU with the distance field of
//! `umbra sweep` for sphere tracing and the eight octant visibilities with `G_s(N)` for the
//! ambient term, in the same image as the tubes (the nearer surface wins per pixel). Shader:
//! `shaders/iso_pass.wgsl`.
//!
//! It is the GPU twin of `iso_reference` (`umbra iso`), step for step: the classified field
//! `g` (inside where `g >= 0`, the space beyond the grid outside), steps of the trilinear
//! distance shortened by one smallest spacing and at least 0.3 of it, 20 bisections, the normal
//! from central differences of the distance half a voxel apart taken to world space by
//! `A^-T`, and `A(P, N)` of `occlusion_shading::AmbientModel` with the visibilities looked up
//! at `P + c h_min N` (trilinear, open sky beyond the grid as the sweeps assume) and `G_s(N)`
//! computed exactly (the projected solid angle of the octant clipped by `N`), not tabulated.
//! The surface is shaded as the tubes are (eq. 9): `A colour (ambient + diffuse (N.L)) +
//! specular` under the head light. Tested against the CPU reference on lavapipe. Clipping
//! planes that cut the volume cut the isosurface: a ray entering a kept half-space inside the
//! solid meets the cut face (normal: the plane's; unoccluded, as it faces the removed half),
//! and the octant fields are swept for the cut solid (`scene::fields::iso_fields`), so a
//! cavity the cut opens sees the sky through the opening.

use crate::gpu::{Gpu, Slot};
use crate::prelude::{clip_planes, mat4, vec4, with_prelude, FrameUniform, LightUniform};
use bytemuck::Zeroable;
use glam::{DMat3, DMat4};
use occlusion::camera::Camera;
use volume::distance_sweep::SWEEP_DIRECTIONS;
use volume::occlusion_shading::{AmbientModel, GeometryTerm};
use volume::occlusion_sweep::OctantFields;

const SHADER: &str = include_str!("../../shaders/iso_pass.wgsl");

/// An isosurface with its fields, as the pass reads it.
pub struct IsoInput<'a> {
    pub dims: [usize; 3],
    pub affine: DMat4,
    /// Classified samples: inside where `g >= 0` (NaN as -1), as `IsoSurface::g`.
    pub g: &'a [f32],
    /// Signed distance, world units (negative inside).
    pub sdf: &'a [f32],
    pub octants: &'a OctantFields,
    pub model: &'a AmbientModel,
    pub color: [f64; 3],
}

/// An isosurface's fields on the GPU (classified samples, distance, packed octants) with what
/// the shading needs of its model, uploaded once.
#[derive(Clone)]
pub struct GpuIso {
    g: wgpu::Buffer,
    sdf: wgpu::Buffer,
    octants: wgpu::Buffer,
    dims: [usize; 3],
    affine: DMat4,
    model: AmbientModel,
    color: [f64; 3],
}

impl GpuIso {
    /// Uploads `i`'s fields (the octants packed four to a `u32`).
    pub fn upload(gpu: &Gpu, i: &IsoInput) -> GpuIso {
        let storage = wgpu::BufferUsages::STORAGE;
        let nvox = i.dims[0] * i.dims[1] * i.dims[2];
        let mut packed = vec![0u32; 2 * nvox];
        for s in 0..8 {
            for (v, &b) in i.octants.octants[s].iter().enumerate() {
                packed[2 * v + s / 4] |= (b as u32) << (8 * (s % 4));
            }
        }
        GpuIso {
            g: gpu.buffer("iso g", bytemuck::cast_slice(i.g), storage),
            sdf: gpu.buffer("iso sdf", bytemuck::cast_slice(i.sdf), storage),
            octants: gpu.buffer("iso octants", bytemuck::cast_slice(&packed), storage),
            dims: i.dims,
            affine: i.affine,
            model: i.model.clone(),
            color: i.color,
        }
    }
}

/// The pass's uniform. Keep in sync with `struct Params` in `shaders/iso_pass.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct IsoParams {
    pub frame: FrameUniform,
    pub world_to_index: [[f32; 4]; 4],
    /// World normal from an index-space gradient: `A^-T` (upper 3x3).
    pub normal_to_world: [[f32; 4]; 4],
    /// World normal to the octants' index frame: `R^T` (upper 3x3).
    pub normal_to_index: [[f32; 4]; 4],
    pub dims: [u32; 3],
    /// The geometry term: 0 cosine, 1 constant, 2 absolute.
    pub geometry: u32,
    /// The smallest spacing, the lookup offset c (in `h_min`), gamma, the normalisation.
    pub h_min: f32,
    pub offset: f32,
    pub gamma: f32,
    pub norm: f32,
    /// The octant weights, four to a row.
    pub weights: [[f32; 4]; 2],
    /// The sweep directions (xyz, 0).
    pub sweeps: [[f32; 4]; 8],
    /// The surface colour (rgb, 1).
    pub color: [f32; 4],
    pub light: LightUniform,
    pub n_clip: u32,
    pub pad0: u32,
    pub pad1: u32,
    pub pad2: u32,
    pub clip: [[f32; 4]; 8],
}

pub struct IsoPass {
    pipe: wgpu::ComputePipeline,
    bind: wgpu::BindGroup,
    /// Per pixel: shaded colour and linear depth (0: no hit).
    pub output: wgpu::Buffer,
    /// Per pixel: the ambient term (-1: no hit).
    pub ambient: wgpu::Buffer,
    size: (u32, u32),
    active: bool,
}

fn mat3(m: DMat3) -> DMat4 {
    DMat4::from_mat3(m)
}

impl IsoPass {
    /// The pass for `iso` (or, without one, empty outputs the compositing reads as no hit).
    pub fn new(
        gpu: &Gpu,
        camera: &Camera,
        width: u32,
        height: u32,
        iso: Option<&GpuIso>,
        light: [f64; 4],
        clip: &[([f64; 3], f64)],
    ) -> IsoPass {
        let n = width as u64 * height as u64;
        let copy = wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST;
        let output = gpu.zeroed("iso output", n * 16, copy);
        let ambient = gpu.zeroed("iso ambient", n * 4, copy);
        let module = gpu.shader("iso_pass.wgsl", &with_prelude(SHADER));
        let layout = gpu.layout(
            "iso",
            wgpu::ShaderStages::COMPUTE,
            &[
                Slot::Uniform,
                Slot::Storage,
                Slot::Storage,
                Slot::Storage,
                Slot::StorageRw,
                Slot::StorageRw,
            ],
        );
        let pl = gpu.pipeline_layout("iso", &[&layout]);
        let pipe = gpu.compute_pipeline_with(&module, "main", &pl, "iso");
        let storage = wgpu::BufferUsages::STORAGE;
        let (u, g, sdf, oct) = match iso {
            Some(i) => {
                let a3 = DMat3::from_mat4(i.affine);
                let h_min = a3
                    .x_axis
                    .length()
                    .min(a3.y_axis.length())
                    .min(a3.z_axis.length());
                let w = i.model.weights();
                let geometry = match i.model.options.geometry {
                    GeometryTerm::Cosine => 0,
                    GeometryTerm::Constant => 1,
                    GeometryTerm::Absolute => 2,
                };
                let c = i.color;
                let u = IsoParams {
                    frame: FrameUniform::new(camera, width, height),
                    world_to_index: mat4(i.affine.inverse()),
                    normal_to_world: mat4(mat3(a3.inverse().transpose())),
                    normal_to_index: mat4(mat3(i.model.to_index())),
                    dims: i.dims.map(|d| d as u32),
                    geometry,
                    h_min: h_min as f32,
                    offset: i.model.options.offset as f32,
                    gamma: i.model.options.gamma as f32,
                    norm: i.model.norm() as f32,
                    weights: [
                        vec4([w[0], w[1], w[2], w[3]]),
                        vec4([w[4], w[5], w[6], w[7]]),
                    ],
                    sweeps: SWEEP_DIRECTIONS.map(|d| [d[0] as f32, d[1] as f32, d[2] as f32, 0.0]),
                    color: vec4([c[0], c[1], c[2], 1.0]),
                    light: light.into(),
                    n_clip: clip.len().min(8) as u32,
                    pad0: 0,
                    pad1: 0,
                    pad2: 0,
                    clip: clip_planes(clip),
                };
                (u, i.g.clone(), i.sdf.clone(), i.octants.clone())
            }
            None => {
                let u = IsoParams::zeroed();
                let z = [0u8; 16];
                (
                    u,
                    gpu.buffer("iso g", &z, storage),
                    gpu.buffer("iso sdf", &z, storage),
                    gpu.buffer("iso octants", &z, storage),
                )
            }
        };
        let params = gpu.buffer(
            "iso params",
            bytemuck::bytes_of(&u),
            wgpu::BufferUsages::UNIFORM,
        );
        let bind = gpu.bind(
            "iso",
            &layout,
            &[
                params.as_entire_binding(),
                g.as_entire_binding(),
                sdf.as_entire_binding(),
                oct.as_entire_binding(),
                output.as_entire_binding(),
                ambient.as_entire_binding(),
            ],
        );
        IsoPass {
            pipe,
            bind,
            output,
            ambient,
            size: (width, height),
            active: iso.is_some(),
        }
    }

    /// Whether there is an isosurface to march.
    pub fn active(&self) -> bool {
        self.active
    }

    /// Records the march (without an isosurface the outputs stay as created: zero, no hit).
    pub fn record(&self, enc: &mut wgpu::CommandEncoder) {
        if !self.active {
            return;
        }
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
            super::IsoParams {
                frame,
                world_to_index,
                normal_to_world,
                normal_to_index,
                dims,
                geometry,
                h_min,
                offset,
                gamma,
                norm,
                weights,
                sweeps,
                color,
                light,
                n_clip,
                pad0,
                pad1,
                pad2,
                clip,
            }
        );
    }
}
