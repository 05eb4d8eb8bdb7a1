//! View-aligned slices through the volume and the tubes: the volumetric occlusion buffer
//! (Schott et al., Algorithm 3), the eye buffer (Algorithm 2) and the partial occlusion of the
//! surfaces (Algorithm 4, eq. 1-3), as compute dispatches. Shader: `shaders/slice_pass.wgsl`;
//! the slices' placement is [`EaView`]'s.
//!
//! The model, its errata and the cone-following variant are stated in `occlusion::combined`
//! (the paper's equation index); this module is the GPU side of Algorithms 2-4.

use crate::gbuffer::GBuffer;
use crate::gpu::{Gpu, GpuError, Slot};
use crate::method::{require, SettingError};
use crate::prelude::{clip_planes, mat4, with_prelude, FrameUniform, LightUniform};
use occlusion::combined::{blur_rows, light_grid, light_view, step_theta, BlurRow};
use occlusion::emission_absorption::{occupancy_packed, EaView, Transfer, BRICK, MAX_CLIP};
use volume::Volume;

const SHADER: &str = include_str!("../../shaders/slice_pass.wgsl");

/// How the slices shade.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SliceSettings {
    /// Run the occlusion buffer (one dispatch per step of `step` slices) and shade the volume
    /// with it.
    pub occlusion: bool,
    /// Cell edge of the occlusion buffer in pixels (None: `occlusion::combined::light_grid`).
    pub cell: Option<u32>,
    /// Eye slices per step of the light volume, 1, 2, 4 or 8 (None: four voxels deep,
    /// sampled and stored a voxel apart, `occlusion::combined::data_step`; the caller passes 1
    /// where tubes or lines cast light, `occlusion::combined::light_step`).
    pub step: Option<u32>,
    /// The cone-following model instead of the paper's constant per-slice blur.
    pub cone: bool,
    /// Phong shading of the volume with on-the-fly gradients.
    pub phong: bool,
    /// A maximum or minimum intensity projection instead of emission-absorption: the
    /// extreme value of the ray's samples (slab midpoints, the whole ray inside the grid and
    /// the clipping planes) through the transfer function, colour `rgb` and opacity its
    /// extinction, drawn only where no surface is (behind them).
    pub projection: Option<crate::method::Extremum>,
    /// The paper's endless shadow column behind surfaces instead of the tubes' thickness.
    pub column: bool,
    pub theta_deg: f64,
    pub blur_samples: u32,
    pub geometry_extinction: f64,
    /// ambient, diffuse, specular, shininess
    pub light: [f64; 4],
    /// The layer of the surface terms the partial occlusion goes to (`march`), if any.
    pub partial_layer: Option<u32>,
    /// Tubes, lines or planes cast light: the march reads the light volume at every stored
    /// slice (their coverage is in the light's parts, not in the pixel's own samples), else
    /// at every step's front (`occlusion::combined::light_in_slab`).
    pub geometry_light: bool,
}

impl SliceSettings {
    /// Checks the settings; an error names the field.
    pub fn check(&self) -> Result<(), SettingError> {
        require(
            self.theta_deg > 0.0 && self.theta_deg < 90.0,
            "theta_deg",
            || format!("{} is not in (0, 90) degrees", self.theta_deg),
        )?;
        require((1..=9).contains(&self.blur_samples), "blur_samples", || {
            format!("{} is not in 1..9", self.blur_samples)
        })?;
        require(
            self.cell.is_none_or(|c| (1..=16).contains(&c)),
            "cell",
            || "must be 1 to 16 pixels".into(),
        )?;
        require(
            self.step
                .is_none_or(|m| m.is_power_of_two() && m <= occlusion::combined::MAX_LIGHT_STEP),
            "step",
            || "must be 1, 2, 4 or 8 slices".into(),
        )?;
        require(
            self.geometry_extinction >= 0.0 && self.geometry_extinction.is_finite(),
            "geometry_extinction",
            || format!("{} must be finite and >= 0", self.geometry_extinction),
        )
    }
}

/// A volume as the pass reads it.
pub struct VolumeInput<'a> {
    pub vol: &'a Volume,
    /// Packed (`Samples::pack` of the field as `emission_absorption::prepare` returns it: NaN
    /// as -3e38); uploaded as they are.
    pub data: &'a Samples,
    pub tf: &'a Transfer,
}

/// The pass's uniform. Keep in sync with `struct Params` in `shaders/slice_pass.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct SliceParams {
    pub frame: FrameUniform,
    pub world_to_index: [[f32; 4]; 4],
    /// Grid samples per axis.
    pub dims: [u32; 3],
    /// Transfer-function points (1-D).
    pub n_tf: u32,
    /// Empty-space bricks per axis.
    pub bricks: [u32; 3],
    /// A brick's edge in voxels.
    pub brick: u32,
    /// The slab's front depth and the slice spacing, world units.
    pub z0: f32,
    pub dz: f32,
    pub tan_theta: f32,
    /// The tubes' extinction per world unit.
    pub geometry_extinction: f32,
    pub clip: [[f32; 4]; 8],
    pub n_clip: u32,
    pub n_slices: u32,
    /// 1: the light volume shades the volume.
    pub occlusion: u32,
    /// 1: the paper's endless shadow column behind surfaces.
    pub column: u32,
    pub has_volume: u32,
    /// Blur taps per axis (n x n).
    pub blur_samples: u32,
    /// 2-D transfer-function rows (0: 1-D).
    pub tf_rows: u32,
    /// The layer of the surface terms the partial occlusion goes to ([`NO_LAYER`]: none).
    pub partial_layer: u32,
    pub light: LightUniform,
    /// Occlusion-buffer cells per axis.
    pub cells: [u32; 2],
    /// A cell's edge in pixels.
    pub cell: u32,
    /// Translucent layers peeled by the G-buffer (`GBuffer::peel`), composited in depth order.
    pub peel_layers: u32,
    /// An overlay blended into the volume's colour ([`GpuBlend`]): world to its grid's index.
    pub blend_to_index: [[f32; 4]; 4],
    pub blend_dims: [u32; 3],
    /// 1: a blended overlay.
    pub blend_on: u32,
    /// Its window (`t = (v - lo) / (hi - lo)`), opacity and kind (1: labels, `blend_count`
    /// entries in its table; 0: 256 colours).
    pub blend_lo: f32,
    pub blend_hi: f32,
    pub blend_opacity: f32,
    pub blend_labels: u32,
    pub blend_count: u32,
    /// 32-bit words in each part of the field (the first part is all of a volume that fits
    /// one storage binding).
    pub part_len: u32,
    /// How samples are packed in a word ([`Packing`]): 0 f32, 1 two u16, 2 four u8.
    pub packing: u32,
    /// Added to a packed integer to give the sample's value.
    pub value_offset: f32,
    /// Eye slices per stored slice of the light volume (a power of two) and the stored
    /// slices it holds.
    pub light_step: u32,
    pub light_slices: u32,
    /// Stored slices (and volume samples, a voxel apart) per step of the `light` entry
    /// (`occlusion::combined::light_samples`).
    pub light_samples: u32,
    /// The light's extinction factor, its mean path through a slab over the cone's
    /// directions (`occlusion::combined::cone_path_factor`).
    pub light_path: f32,
    /// Eye slices between the march's reads of the light volume: a step
    /// (`light_step light_samples`), or a stored slice (`light_step`) where tubes, lines or
    /// planes cast light ([`SliceSettings::geometry_light`]).
    pub light_read: u32,
    pub light_pad0: u32,
    pub light_pad1: u32,
    pub light_pad2: u32,
}

/// An overlay blended into the volume rendering (`overlays[].volume_blend`): each volume
/// sample's colour is mixed with the overlay's colour at its world point by the overlay's
/// coverage times its opacity (extinction unchanged); the mapping is the slices'
/// (`engine::planes::layer_color`).
#[derive(Clone)]
pub struct GpuBlend {
    field: wgpu::Buffer,
    lut: wgpu::Buffer,
    world_to_index: glam::DMat4,
    dims: [usize; 3],
    lo: f32,
    hi: f32,
    opacity: f32,
    labels: bool,
    count: u32,
}

impl GpuBlend {
    /// Uploads field `layer.field` of `grid` with its mapping; an error naming the buffer when
    /// it exceeds the adapter's binding limit.
    pub fn upload(
        gpu: &Gpu,
        grid: &crate::planes::PlaneGrid,
        layer: &crate::planes::PlaneLayer,
    ) -> Result<GpuBlend, GpuError> {
        use crate::planes::LayerMap;
        let storage = wgpu::BufferUsages::STORAGE;
        let f = grid.fields[layer.field];
        gpu.check_buffer("blended overlay", f.len() as u64 * 4, storage)?;
        let f = occlusion::emission_absorption::prepare(f);
        crate::planes::check_layer(grid, layer, "the blended overlay")
            .map_err(GpuError::Operation)?;
        let (lut, lo, hi, labels): (Vec<[f32; 4]>, f64, f64, bool) = match &layer.map {
            LayerMap::Scalar { lo, hi, colors } => (
                colors.iter().map(|c| [c[0], c[1], c[2], 1.0]).collect(),
                *lo,
                *hi,
                false,
            ),
            LayerMap::Labels { colors } => (colors.clone(), 0.0, 1.0, true),
        };
        Ok(GpuBlend {
            field: gpu.buffer("blended overlay", bytemuck::cast_slice(&f), storage),
            lut: gpu.buffer(
                "blended overlay colours",
                bytemuck::cast_slice(&lut),
                storage,
            ),
            world_to_index: grid.affine.inverse(),
            dims: grid.dims,
            lo: lo as f32,
            hi: hi as f32,
            opacity: layer.opacity,
            labels,
            count: lut.len() as u32,
        })
    }

    /// The stand-in the pass binds without a blended overlay (never read).
    fn none(gpu: &Gpu) -> (wgpu::Buffer, wgpu::Buffer) {
        gpu.cached("no blend".into(), || {
            let s = wgpu::BufferUsages::STORAGE;
            (
                gpu.buffer("no blend", &[0; 16], s),
                gpu.buffer("no blend colours", &[0; 16], s),
            )
        })
    }
}

/// No layer (`SliceParams::partial_layer`).
pub const NO_LAYER: u32 = u32::MAX;

/// One slice's record, at a dynamic offset. Keep in sync with `struct Slice` in
/// `shaders/slice_pass.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct SliceRow {
    /// The slice index.
    pub k: u32,
    /// 1: the blur needs the tap loop (radius above two cells).
    pub wide: u32,
    pub pad: [u32; 2],
    /// The blur radius in cells (x, y; unused, unused).
    pub rpx: [f32; 4],
    /// The blur as a 3x3 stencil, rows y = -1, 0, 1 (xyz of each).
    pub w: [[f32; 4]; 3],
}

/// Bytes of one slice's record.
const SLICE_BYTES: u64 = std::mem::size_of::<SliceRow>() as u64;

/// The most parts a volume's samples are ever split into (the shader's `field`, `field1`, ...):
/// 32 parts of lavapipe's 128 MiB bindings hold 4 GiB, 1024^3 samples in f32.
pub const MAX_VOLUME_PARTS: usize = 32;

/// The slice pass's bind groups 0 and 1 (group 2 holds the volume's further parts).
const GROUP0: [Slot; 15] = [
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
    Slot::UnfilterableTextureArray,
    Slot::UnfilterableTextureArray,
    Slot::Storage,
    Slot::Storage,
];
const GROUP1: [Slot; 3] = [Slot::StorageDynamic, Slot::Storage, Slot::StorageRw];

/// How many parts a volume's samples may be split into on `gpu`: every storage binding a
/// compute stage has left after the slice pass's own (groups 0 and 1, the first part among
/// them), at most [`MAX_VOLUME_PARTS`], at least 1. lavapipe binds 32 storage buffers a stage:
/// 20 parts of 128 MiB, 2.5 GiB (1024^3 samples in 16 bits).
pub fn volume_parts(gpu: &Gpu) -> usize {
    let storage = |s: &&Slot| matches!(s, Slot::Storage | Slot::StorageDynamic | Slot::StorageRw);
    let own = GROUP0.iter().chain(&GROUP1).filter(storage).count();
    let stage = gpu.device.limits().max_storage_buffers_per_shader_stage as usize;
    (stage + 1).saturating_sub(own).clamp(1, MAX_VOLUME_PARTS)
}

/// The WGSL of a volume split into `parts` (at least 1): the further parts' declarations
/// (group 2, `field1`.. `field{parts - 1}`) and `field_word(w)`, the volume's word `w` read
/// from its part. Written into `slice_pass.wgsl` at its `//@field-parts` line for each
/// volume's part count, so the shader declares exactly the bindings the volume has (WGSL has
/// no arrays of storage buffers without a native-only feature) and a volume in one binding
/// reads it directly. The part is found by halving `[0, parts)` with comparisons of `w` (no
/// division; lavapipe runs every case of a `switch` its SIMD lanes reach: a 20-case switch
/// doubled a two-part volume's frame).
pub fn field_parts_wgsl(parts: usize) -> String {
    fn find(lo: usize, hi: usize, indent: usize, s: &mut String) {
        let pad = " ".repeat(indent);
        if hi - lo == 1 {
            *s += &match lo {
                0 => format!("{pad}return field[w];\n"),
                _ => format!("{pad}return field{lo}[w - {lo}u * P.part_len];\n"),
            };
            return;
        }
        let mid = (lo + hi) / 2;
        *s += &format!("{pad}if (w < {mid}u * P.part_len) {{\n");
        find(lo, mid, indent + 4, s);
        *s += &format!("{pad}}} else {{\n");
        find(mid, hi, indent + 4, s);
        *s += &format!("{pad}}}\n");
    }
    let parts = parts.max(1);
    let mut s = String::new();
    for k in 1..parts {
        s += &format!(
            "@group(2) @binding({}) var<storage, read> field{k}: array<u32>;\n",
            k - 1
        );
    }
    s += "fn field_word(w: u32) -> u32 {\n";
    find(0, parts, 4, &mut s);
    s += "}\n";
    s
}

/// `slice_pass.wgsl` for a volume in at most `parts` parts (the prelude not yet prepended).
fn source(parts: usize) -> String {
    SHADER.replace("//@field-parts", &field_parts_wgsl(parts))
}

/// 32-bit words a part of a volume holds on `gpu` (its storage binding limit).
pub fn part_words(gpu: &Gpu) -> usize {
    (gpu.storage_limit() / 4).min(u32::MAX as u64) as usize
}

/// How a volume's samples are stored on the GPU (and by the model on the CPU: one layout,
/// `volume::samples`).
pub use volume::samples::{Packing, Samples};

/// The most samples a volume packed as `packing` may have on `gpu` at full resolution.
pub fn max_volume_samples(gpu: &Gpu, packing: Packing) -> usize {
    // The shader's sample index is a u32 (`voxel` in slice_pass.wgsl).
    (volume_parts(gpu) * part_words(gpu) * packing.per_word())
        .min((u32::MAX as usize).saturating_add(1))
}

/// A volume on the GPU: its samples, its transfer function (1-D points, then the 2-D rows'
/// ranges) and the brick occupancy of [`occupancy`], uploaded once and read by every frame.
#[derive(Clone)]
pub struct GpuVolume {
    /// The samples' words in parts of `part_len` (the last may be shorter), at most
    /// [`volume_parts`].
    field: Vec<wgpu::Buffer>,
    part_len: u32,
    packing: Packing,
    value_offset: f32,
    tf: wgpu::Buffer,
    occ: wgpu::Buffer,
    dims: [usize; 3],
    world_to_index: glam::DMat4,
    bricks: [usize; 3],
    tf_points: u32,
    tf_rows: u32,
}

/// A transfer function as the shader reads it: each point `(value, r, g, b, extinction, 0, 0,
/// 0)`, then per 2-D row `(gradient, first point, end point, 0)`.
fn transfer_floats(tf: &Transfer) -> Vec<f32> {
    let mut out: Vec<f32> = Vec::with_capacity(8 * tf.points.len().max(1));
    for (val, rgb, sigma) in &tf.points {
        out.extend([
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
    let rows = tf.row_slices();
    let mut first = 0usize;
    for (r, p) in tf.rows.iter().zip(&rows) {
        out.extend([r.0 as f32, first as f32, (first + p.len()) as f32, 0.0]);
        first += p.len();
    }
    out
}

impl GpuVolume {
    /// Uploads `vi`; an error when its samples exceed the adapter's storage binding limit.
    pub fn upload(gpu: &Gpu, vi: &VolumeInput) -> Result<GpuVolume, GpuError> {
        let packing = vi.data.packing();
        let most = max_volume_samples(gpu, packing);
        if vi.data.len() > most {
            return Err(GpuError::Operation(format!(
                "the volume has {} samples ({} MB as {:?}); this adapter binds at most {} in \
                 {} parts of {} MB: downsample it",
                vi.data.len(),
                vi.data.bytes() >> 20,
                packing,
                most,
                volume_parts(gpu),
                (part_words(gpu) * 4) >> 20
            )));
        }
        let tfb = transfer_floats(vi.tf);
        let (bricks, occ) = occupancy_packed(vi.data, vi.vol.dims, vi.tf, BRICK);
        Self::make(
            gpu,
            vi.data,
            &tfb,
            &occ,
            vi.vol.dims,
            vi.vol.affine.inverse(),
            bricks,
            (vi.tf.points.len() as u32, vi.tf.rows.len() as u32),
        )
    }

    /// Replaces the transfer function (and the brick occupancy, which depends on it) of an
    /// uploaded volume, keeping its samples on the GPU: `vi` is the volume as uploaded with its
    /// new transfer function.
    pub fn set_transfer(&mut self, gpu: &Gpu, vi: &VolumeInput) -> Result<(), GpuError> {
        if vi.vol.dims != self.dims || vi.data.len() != vi.vol.dims.iter().product::<usize>() {
            return Err(GpuError::Operation(format!(
                "a new transfer function for a {:?} volume; the uploaded one is {:?} (pass the \
                 volume as uploaded, after any downsampling)",
                vi.vol.dims, self.dims
            )));
        }
        let storage = wgpu::BufferUsages::STORAGE;
        let (bricks, occ) = occupancy_packed(vi.data, vi.vol.dims, vi.tf, BRICK);
        self.tf = gpu.buffer(
            "slice transfer",
            bytemuck::cast_slice(&transfer_floats(vi.tf)),
            storage,
        );
        self.occ = gpu.buffer("slice occupancy", bytemuck::cast_slice(&occ), storage);
        self.bricks = bricks;
        self.tf_points = vi.tf.points.len() as u32;
        self.tf_rows = vi.tf.rows.len() as u32;
        Ok(())
    }

    #[allow(clippy::too_many_arguments)]
    fn make(
        gpu: &Gpu,
        field: &Samples,
        tf: &[f32],
        occ: &[u32],
        dims: [usize; 3],
        world_to_index: glam::DMat4,
        bricks: [usize; 3],
        (tf_points, tf_rows): (u32, u32),
    ) -> Result<GpuVolume, GpuError> {
        let storage = wgpu::BufferUsages::STORAGE;
        let part_len = part_words(gpu).max(1);
        let packing = field.packing();
        let words = field.words();
        Ok(GpuVolume {
            // Staged in pieces of at most 16 MiB (a 128 MiB part would stage all at once).
            field: words
                .chunks(part_len)
                .map(|c| {
                    gpu.buffer_staged_by(
                        "slice field",
                        bytemuck::cast_slice(c),
                        storage,
                        crate::gpu::VOLUME_STAGING_BYTES,
                    )
                })
                .collect::<Result<_, _>>()?,
            part_len: part_len.min(u32::MAX as usize) as u32,
            packing,
            value_offset: packing.offset(),
            tf: gpu.buffer("slice transfer", bytemuck::cast_slice(tf), storage),
            occ: gpu.buffer("slice occupancy", bytemuck::cast_slice(occ), storage),
            dims,
            world_to_index,
            bricks,
            tf_points,
            tf_rows,
        })
    }

    /// The stand-in the passes bind when a scene has no volume (never sampled).
    fn none(gpu: &Gpu) -> GpuVolume {
        gpu.cached("no volume".into(), || {
            Self::make(
                gpu,
                &Samples::f32(vec![0.0; 8]),
                &[0.0; 8],
                &[0],
                [2, 2, 2],
                glam::DMat4::IDENTITY,
                [1, 1, 1],
                (0, 0),
            )
            // Eight samples are uploaded at once, without a wait that could fail.
            .expect("a 32-byte volume needs no staging")
        })
    }
}

pub struct SlicePass {
    light_pipe: wgpu::ComputePipeline,
    march_pipe: wgpu::ComputePipeline,
    group0: wgpu::BindGroup,
    /// The volume's further parts.
    group2: wgpu::BindGroup,
    /// Ping-pong: slice k uses `group1[k % 2]`.
    group1: [wgpu::BindGroup; 2],
    stride: u32,
    pub eye: wgpu::Buffer,
    pub state: wgpu::Buffer,
    pub slices: u32,
    occlusion: bool,
    /// Whether the march has anything to do: a volume, translucent layers or the light.
    /// Without any, its result is the zeroed eye buffer and state (no colour, no opacity;
    /// composite reads a volumetric AOV of 1 and no depth, and a partial term of 1).
    march: bool,
    size: (u32, u32),
    cells: (u32, u32),
    /// Cell edge in pixels.
    pub cell: u32,
    /// The light volume's cells, steps and parts.
    grid: crate::renderer::LightGrid,
}

impl SlicePass {
    pub fn new(
        gpu: &Gpu,
        volume: Option<&GpuVolume>,
        v: &EaView,
        gbuf: &GBuffer,
        terms: &wgpu::Buffer,
        s: &SliceSettings,
        blend: Option<&GpuBlend>,
    ) -> Result<SlicePass, GpuError> {
        let device = &gpu.device;
        s.check()
            .map_err(|e| GpuError::Operation(format!("slice settings: {e}")))?;
        if v.clip.len() > MAX_CLIP {
            return Err(GpuError::Operation(format!(
                "{} clipping planes; at most {MAX_CLIP}",
                v.clip.len()
            )));
        }
        let limit = device.limits().max_storage_buffer_binding_size as usize;
        // The volume's parts (the stand-in of a scene without one has one).
        let parts = volume.map_or(1, |vi| vi.field.len());
        let module = gpu.shader("slice_pass.wgsl", &with_prelude(&source(parts)));
        let tf2d = volume.is_some_and(|vi| vi.tf_rows > 0);
        // The field's packing, a pipeline constant.
        let packing = volume.map_or(0.0, |vi| vi.packing.code() as f64);
        let l0 = gpu.layout("slice group 0", wgpu::ShaderStages::COMPUTE, &GROUP0);
        let l1 = gpu.layout("slice group 1", wgpu::ShaderStages::COMPUTE, &GROUP1);
        let l2 = gpu.layout(
            "slice group 2",
            wgpu::ShaderStages::COMPUTE,
            &vec![Slot::Storage; parts - 1],
        );
        let pl = gpu.pipeline_layout("slice", &[&l0, &l1, &l2]);
        let light_pipe = gpu.compute_pipeline_constants(
            &module,
            "light",
            &pl,
            "light",
            &[
                ("CONE", if s.cone { 1.0 } else { 0.0 }),
                ("TF2D", if tf2d { 1.0 } else { 0.0 }),
                ("PACKING", packing),
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
                ("PACKING", packing),
                (
                    "PROJECTION",
                    match s.projection {
                        None => 0.0,
                        Some(crate::method::Extremum::Max) => 1.0,
                        Some(crate::method::Extremum::Min) => 2.0,
                    },
                ),
            ],
        );

        // The light's own view: cells of `cell` pixels, steps of `step` eye slices
        // (`occlusion::combined::light_grid`, `light_view`).
        let (cell, step) = light_grid(s.cell, s.step, false, v, limit as u64);
        // Each step sampled in parts a voxel deep, and the light reaching each part stored
        // (`occlusion::combined::light_samples`).
        let grid = crate::renderer::LightGrid::new(v, cell, step);
        let cells = (grid.cells[0], grid.cells[1]);
        let lv = light_view(v, step);
        let light_bytes = grid.bytes();
        if s.occlusion {
            grid.fits(limit as u64).map_err(GpuError::Settings)?;
        }
        let has_volume = volume.is_some();
        let vol = volume.cloned().unwrap_or_else(|| GpuVolume::none(gpu));
        let (w2i, dims, nb) = (vol.world_to_index, vol.dims, vol.bricks);
        let u32x3 = |d: [usize; 3]| d.map(|x| x as u32);
        let params = SliceParams {
            frame: FrameUniform::new(&v.camera, v.width, v.height),
            world_to_index: mat4(w2i),
            dims: u32x3(dims),
            n_tf: vol.tf_points,
            bricks: u32x3(nb),
            brick: BRICK as u32,
            z0: v.z0 as f32,
            dz: v.dz as f32,
            tan_theta: s.theta_deg.to_radians().tan() as f32,
            geometry_extinction: s.geometry_extinction as f32,
            clip: clip_planes(&v.clip),
            n_clip: v.clip.len() as u32,
            n_slices: v.slices,
            occlusion: s.occlusion as u32,
            column: s.column as u32,
            has_volume: has_volume as u32,
            blur_samples: s.blur_samples.max(1),
            tf_rows: vol.tf_rows,
            partial_layer: s.partial_layer.unwrap_or(NO_LAYER),
            light: s.light.into(),
            cells: [cells.0, cells.1],
            cell,
            peel_layers: gbuf.peel.layers,
            blend_to_index: mat4(blend.map_or(glam::DMat4::IDENTITY, |b| b.world_to_index)),
            blend_dims: blend.map_or([1; 3], |b| u32x3(b.dims)),
            blend_on: blend.is_some() as u32,
            blend_lo: blend.map_or(0.0, |b| b.lo),
            blend_hi: blend.map_or(1.0, |b| b.hi),
            blend_opacity: blend.map_or(0.0, |b| b.opacity),
            blend_labels: blend.is_some_and(|b| b.labels) as u32,
            blend_count: blend.map_or(0, |b| b.count),
            part_len: vol.part_len,
            packing: vol.packing.code(),
            value_offset: vol.value_offset,
            light_step: step / grid.samples,
            light_slices: grid.stored(),
            light_samples: grid.samples,
            light_path: occlusion::combined::cone_path_factor(s.theta_deg) as f32,
            light_read: if s.geometry_light {
                step / grid.samples
            } else {
                step
            },
            light_pad0: 0,
            light_pad1: 0,
            light_pad2: 0,
        };
        let (blend_field, blend_lut) = match blend {
            Some(b) => (b.field.clone(), b.lut.clone()),
            None => GpuBlend::none(gpu),
        };
        let params = gpu.buffer(
            "slice params",
            bytemuck::bytes_of(&params),
            wgpu::BufferUsages::UNIFORM,
        );
        let n = v.width as u64 * v.height as u64;
        // COPY_DST: cleared instead of marched where the march has nothing to do.
        let copy = wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST;
        let eye = gpu.scratch("eye buffer", n * 16, copy);
        let state = gpu.scratch("slice state", n * 32, copy);
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
                vol.field[0].as_entire_binding(),
                vol.tf.as_entire_binding(),
                vol.occ.as_entire_binding(),
                eye.as_entire_binding(),
                state.as_entire_binding(),
                wgpu::BindingResource::TextureView(&gbuf.front),
                wgpu::BindingResource::TextureView(&gbuf.back),
                light.as_entire_binding(),
                cell_state.as_entire_binding(),
                terms.as_entire_binding(),
                wgpu::BindingResource::TextureView(&gbuf.peel.color),
                wgpu::BindingResource::TextureView(&gbuf.peel.nd),
                blend_field.as_entire_binding(),
                blend_lut.as_entire_binding(),
            ],
        );
        // The field's further parts (unused bindings repeat the first part; never read).
        let parts: Vec<wgpu::BindingResource> = (1..parts)
            .map(|k| {
                vol.field
                    .get(k)
                    .unwrap_or(&vol.field[0])
                    .as_entire_binding()
            })
            .collect();
        let group2 = gpu.bind("slice group 2", &l2, &parts);
        // Slice indices, one per dynamic-offset row.
        // A storage buffer, not a uniform one: lavapipe inlines uniform values into the shader
        // and recompiles it for every new offset (2.5 ms a dispatch here).
        let align = device.limits().min_storage_buffer_offset_alignment.max(16);
        let stride = (SLICE_BYTES as u32).div_ceil(align) * align;
        let rows = if s.occlusion { lv.slices } else { 1 };
        let mut kb = vec![0u8; (rows * stride) as usize];
        let blur = blur_rows(&lv, cell, step_theta(s.theta_deg, step, s.cone));
        for k in 0..rows {
            let BlurRow { wide, rpx, w } = blur.get(k as usize).copied().unwrap_or(BlurRow {
                wide: false,
                rpx: [0.0; 2],
                w: [[0.0; 3]; 3],
            });
            let row = SliceRow {
                k,
                wide: wide as u32,
                pad: [0; 2],
                rpx: [rpx[0] as f32, rpx[1] as f32, 0.0, 0.0],
                w: w.map(|r| [r[0] as f32, r[1] as f32, r[2] as f32, 0.0]),
            };
            let bytes = bytemuck::bytes_of(&row);
            let at = (k * stride) as usize;
            kb[at..at + bytes.len()].copy_from_slice(bytes);
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
            group2,
            group1,
            stride,
            eye,
            state,
            slices: lv.slices,
            occlusion: s.occlusion,
            // (Without the light the partial term is 1, which composite reads in its place:
            // `CompositeSettings::open_layer`.)
            march: has_volume || s.occlusion || gbuf.peel.layers > 0,
            size: (v.width, v.height),
            cells,
            cell,
            grid,
        })
    }

    /// Whether the light volume is computed (the `light` pass has work).
    pub fn has_light(&self) -> bool {
        self.occlusion
    }

    /// The light volume's cells and steps, where the pass sweeps one.
    pub fn light_grid(&self) -> Option<crate::renderer::LightGrid> {
        self.occlusion.then_some(self.grid)
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
        pass.set_bind_group(2, &self.group2, &[]);
        let (gx, gy) = (self.cells.0.div_ceil(8), self.cells.1.div_ceil(8));
        pass.set_pipeline(&self.light_pipe);
        for k in 0..self.slices {
            pass.set_bind_group(1, &self.group1[(k % 2) as usize], &[k * self.stride]);
            pass.dispatch_workgroups(gx, gy, 1);
        }
    }

    /// Records the eye march (after the light volume), or where it has nothing to do (no
    /// volume, layers or light) the clearing of its buffers: on lavapipe the
    /// march over an empty scene cost about as much as the G-buffer of the lines in it
    /// (80-140 ms at 900 x 600).
    pub fn record_march(&self, enc: &mut wgpu::CommandEncoder) {
        if !self.march {
            enc.clear_buffer(&self.eye, 0, None);
            enc.clear_buffer(&self.state, 0, None);
            return;
        }
        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("march"),
            timestamp_writes: None,
        });
        pass.set_bind_group(0, &self.group0, &[]);
        pass.set_bind_group(2, &self.group2, &[]);
        pass.set_pipeline(&self.march_pipe);
        pass.set_bind_group(1, &self.group1[0], &[0]);
        pass.dispatch_workgroups(self.size.0.div_ceil(8), self.size.1.div_ceil(8), 1);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_shader_ends_rays_at_the_models_opacity() {
        // The WGSL literal and the Rust constant the CPU renderer and the twin use.
        let opaque = occlusion::emission_absorption::OPAQUE;
        assert!(
            SHADER.contains(&format!("if (e.a > {opaque}) {{")),
            "shaders/slice_pass.wgsl does not end rays at {opaque}"
        );
    }

    #[test]
    fn the_march_brings_the_carried_light_to_each_front_as_the_cpu() {
        // `raycast::light::front_gain`'s rule in the WGSL twin (the CPU's `GAIN_RANGE` is
        // [1e-3, 1e3]; the devices' agreement on cut faces is `cli/tests/render_cli.rs`'s):
        // a first read or a light below 1e-20 takes the front, else the ratio's roots.
        for text in [
            "if (first || !(carried > 1e-20)) {\n        return vec2<f32>(front, 1.0);",
            "var g = clamp(front / carried, 1e-3, 1e3);",
            "for (var n = P.light_read; n > 1u; n = n >> 1u) {\n        g = sqrt(g);",
            "*lrun = *lrun * (ef * lgain);",
        ] {
            assert!(
                SHADER.contains(text),
                "shaders/slice_pass.wgsl lacks `{text}`"
            );
        }
    }

    #[test]
    fn the_light_pass_stops_attenuating_at_the_models_dark_light() {
        // The WGSL literal and the Rust constant the CPU sweep uses.
        // The skip comes after a part's store (a dark cell stores its light at every part)
        // and before its samples; the CPU sweep's agreement with the GPU pass (cli/tests/ea_cli.rs)
        // is looser than DARK, so the shader's text is checked here.
        let dark = occlusion::combined::DARK;
        assert!(
            SHADER.contains(&format!("const DARK: f32 = {dark};"))
                && SHADER.contains("let lit = occl >= DARK;"),
            "shaders/slice_pass.wgsl does not stop its light at {dark}"
        );
        let at = |s: &str| {
            SHADER
                .find(s)
                .unwrap_or_else(|| panic!("no `{s}` in the shader"))
        };
        let store = at("light_volume[ci + cw * ch * (k * n + i)] = occl * t;");
        let skip = at("if (!lit) {\n            continue;\n        }");
        let sample = at("let c = volume_sample(r, 0.5 * (iv.x + iv.y), &grad);");
        assert!(
            store < skip && skip < sample,
            "the light pass's skip is not between a part's store and its sample"
        );
    }

    #[test]
    fn the_settings_check_names_the_field() {
        let ok = SliceSettings {
            occlusion: true,
            cell: None,
            step: None,
            cone: false,
            phong: false,
            projection: None,
            column: false,
            theta_deg: 25.0,
            blur_samples: 3,
            geometry_extinction: 10.0,
            light: [0.3, 0.7, 0.3, 32.0],
            partial_layer: None,
            geometry_light: false,
        };
        assert!(ok.check().is_ok());
        let field = |s: SliceSettings| s.check().unwrap_err().field;
        assert_eq!(
            field(SliceSettings {
                theta_deg: 90.0,
                ..ok
            }),
            "theta_deg"
        );
        assert_eq!(
            field(SliceSettings {
                blur_samples: 0,
                ..ok
            }),
            "blur_samples"
        );
        assert_eq!(
            field(SliceSettings {
                cell: Some(17),
                ..ok
            }),
            "cell"
        );
        for step in [0, 3, 16] {
            assert_eq!(
                field(SliceSettings {
                    step: Some(step),
                    ..ok
                }),
                "step"
            );
        }
        assert_eq!(
            field(SliceSettings {
                geometry_extinction: f64::INFINITY,
                ..ok
            }),
            "geometry_extinction"
        );
    }

    /// The shader parses and validates with the volume in one part, two and the most, and
    /// declares exactly `parts - 1` further bindings (group 2).
    #[test]
    fn the_shader_declares_the_parts_it_is_written_for() {
        for parts in [1, 2, 20, MAX_VOLUME_PARTS] {
            let wgsl = crate::prelude::with_prelude(&source(parts));
            let module = naga::front::wgsl::parse_str(&wgsl)
                .unwrap_or_else(|e| panic!("{parts} parts: {}", e.emit_to_string(&wgsl)));
            naga::valid::Validator::new(
                naga::valid::ValidationFlags::all(),
                naga::valid::Capabilities::all(),
            )
            .validate(&module)
            .unwrap_or_else(|e| panic!("{parts} parts: {e:?}"));
            let group2 = module
                .global_variables
                .iter()
                .filter(|(_, g)| g.binding.as_ref().is_some_and(|b| b.group == 2))
                .count();
            assert_eq!(group2, parts - 1, "{parts} parts");
        }
    }

    #[test]
    fn the_uniforms_match_their_wgsl_structs() {
        crate::prelude::assert_layout!(
            &source(2),
            "Params",
            SliceParams {
                frame,
                world_to_index,
                dims,
                n_tf,
                bricks,
                brick,
                z0,
                dz,
                tan_theta,
                geometry_extinction,
                clip,
                n_clip,
                n_slices,
                occlusion,
                column,
                has_volume,
                blur_samples,
                tf_rows,
                partial_layer,
                light,
                cells,
                cell,
                peel_layers,
                blend_to_index,
                blend_dims,
                blend_on,
                blend_lo,
                blend_hi,
                blend_opacity,
                blend_labels,
                blend_count,
                part_len,
                packing,
                value_offset,
                light_step,
                light_slices,
                light_samples,
                light_path,
                light_read,
                light_pad0,
                light_pad1,
                light_pad2,
            }
        );
        crate::prelude::assert_layout!(
            &source(2),
            "Slice",
            SliceRow {
                k,
                wide,
                pad,
                rpx,
                w
            }
        );
    }
}
