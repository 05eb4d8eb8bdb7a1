//! The tubes' G-buffer (Schott et al., section 3.2.1), the one rasterised pass of the
//! renderer. Shader: `shaders/gbuffer.wgsl`.
//!
//! Targets (all `width x height`, cleared to zero): surface colour (`rgba16float`, alpha 1 where
//! a surface is), world-space normal facing the viewer (`rgba16float`), linear view depth of
//! the nearest surface (`r32float`, the distance along the viewing direction, the same measure
//! as the slices' depth; 0 where no surface is), and in a second pass the linear depth of the
//! nearest back-facing surface, so that "inside a tube" is `front <= z <= back` (issue 5: the
//! paper, with the front depth only, shadows an endless column behind every surface).
//! Back faces are told by the interpolated vertex normal, not by the mesh's winding.
//! Vertices are drawn camera-relative (`position + origin - eye` in f32 through
//! `projection * view * translate(eye)`), which keeps precision for tubes far from the origin.
//! Clipping planes discard fragments, as they remove volume samples.
//!
//! Multisampling (`render.msaa`, lowered to what the adapter supports for all three formats,
//! with a note): colour and normal are rendered multisampled, so that compositing shades each
//! sample with its own normal (a specular highlight on a thin tube is not averaged away before
//! it is lit) and averages; the linear depths stay single-sampled (a third pass writes the
//! nearest surface's), as the slices and the vicinity term need one precise depth per pixel.

use crate::gpu::{Gpu, GpuError, Slot};
use crate::prelude::{clip_planes, mat4, vec4, with_prelude};
use glam::{DMat4, DVec3};
use occlusion::camera::Camera;
use tubes::lines::{LineSet, LineWidth};
use tubes::tube_mesh::TubeMesh;

pub(crate) const SHADER: &str = include_str!("../../shaders/gbuffer.wgsl");

/// Surface colour: linear, so in 16-bit floats (8-bit linear steps band dark tones of slices
/// once encoded as sRGB: the first step above black is sRGB 13/255).
pub const COLOR: wgpu::TextureFormat = wgpu::TextureFormat::Rgba16Float;
pub const NORMAL: wgpu::TextureFormat = wgpu::TextureFormat::Rgba16Float;
pub const DEPTH: wgpu::TextureFormat = wgpu::TextureFormat::R32Float;
/// Peeled translucent layers: straight colour and opacity; normal and linear depth.
pub const PEEL_COLOR: wgpu::TextureFormat = wgpu::TextureFormat::Rgba16Float;
pub const PEEL_ND: wgpu::TextureFormat = wgpu::TextureFormat::Rgba32Float;

/// Bytes per vertex: position (3 f32), normal (3 f32), colour (4 unorm8).
const STRIDE: u64 = 28;

/// A mesh's uniform. Keep in sync with `struct Params` in `shaders/gbuffer.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct GBufferParams {
    /// `projection * view * translate(eye)`: camera-relative position to clip space.
    pub view_proj_rel: [[f32; 4]; 4],
    /// The mesh's origin - eye (xyz, 0).
    pub offset: [f32; 4],
    pub forward: [f32; 4],
    pub eye: [f32; 4],
    pub clip: [[f32; 4]; 8],
    pub n_clip: u32,
    /// LineAO's width code of the mesh's pixels: minus the tubes' diameter, 0 when unknown.
    pub width_code: f32,
    /// A translucent mesh's opacity (1 for opaque meshes).
    pub opacity: f32,
    pub pad2: u32,
}

/// A tube mesh on the GPU: vertices (position, normal, colour; [`STRIDE`] bytes each) and
/// triangle indices, uploaded once and drawn in every frame.
#[derive(Clone)]
pub struct GpuMesh {
    vertices: wgpu::Buffer,
    indices: wgpu::Buffer,
    count: u32,
    /// The mesh's f64 origin (its positions are f32 relative to it).
    origin: DVec3,
    /// The tubes' nominal diameter, world units (0: unknown).
    diameter: f32,
    /// Below 1: translucent (drawn by the peel passes, not the opaque ones).
    opacity: f32,
    /// The mesh's index in the list it was uploaded from ([`crate::renderer::Renderer::upload`]).
    pub(crate) source: usize,
}

impl GpuMesh {
    /// Uploads `m` (`None` when it has no triangles); an error naming the buffer when the mesh
    /// is larger than the adapter's buffers.
    pub fn upload(gpu: &Gpu, m: &TubeMesh) -> Result<Option<GpuMesh>, GpuError> {
        if m.indices.is_empty() {
            return Ok(None);
        }
        let vertex_bytes = m.positions.len() as u64 * STRIDE;
        gpu.check_buffer("tube vertices", vertex_bytes, wgpu::BufferUsages::VERTEX)?;
        gpu.check_buffer(
            "tube indices",
            m.indices.len() as u64 * 4,
            wgpu::BufferUsages::INDEX,
        )?;
        let mut v = Vec::with_capacity(m.positions.len() * STRIDE as usize);
        for i in 0..m.positions.len() {
            let n = m.normals.get(i).copied().unwrap_or(glam::Vec3::Z);
            let c = m.colors.get(i).copied().unwrap_or([200, 200, 200]);
            for x in m.positions[i].to_array().into_iter().chain(n.to_array()) {
                v.extend(x.to_le_bytes());
            }
            v.extend([c[0], c[1], c[2], 255]);
        }
        Ok(Some(GpuMesh {
            vertices: gpu.buffer("tube vertices", &v, wgpu::BufferUsages::VERTEX),
            indices: gpu.buffer(
                "tube indices",
                bytemuck::cast_slice(&m.indices),
                wgpu::BufferUsages::INDEX,
            ),
            count: m.indices.len() as u32,
            origin: m.origin,
            source: 0,
            diameter: (2.0 * m.radius.max(0.0)) as f32,
            opacity: m.opacity.map_or(1.0, |o| {
                if o.is_finite() {
                    o.clamp(0.0, 1.0)
                } else {
                    1.0
                }
            }),
        }))
    }

    /// This mesh's vertices (shared on the GPU, not uploaded again) with other triangles:
    /// `indices` into the same vertices (a share of the mesh's). `None` when there are none.
    pub fn with_indices(&self, gpu: &Gpu, indices: &[u32]) -> Result<Option<GpuMesh>, GpuError> {
        if indices.is_empty() {
            return Ok(None);
        }
        gpu.check_buffer(
            "tube indices",
            indices.len() as u64 * 4,
            wgpu::BufferUsages::INDEX,
        )?;
        Ok(Some(GpuMesh {
            indices: gpu.buffer(
                "tube indices",
                bytemuck::cast_slice(indices),
                wgpu::BufferUsages::INDEX,
            ),
            count: indices.len() as u32,
            ..self.clone()
        }))
    }

    /// Triangles of the mesh.
    pub fn triangles(&self) -> u64 {
        self.count as u64 / 3
    }

    /// The tubes' nominal diameter, world units (0: unknown).
    pub fn diameter(&self) -> f32 {
        self.diameter
    }

    /// Whether the mesh is translucent (opacity below 1).
    pub fn translucent(&self) -> bool {
        self.opacity < 1.0
    }
}

/// A line set on the GPU: positions (xyz f32 relative to the origin), RGBA8 colours and the
/// first point of each segment - 16 bytes a point and 4 a segment; the strips are built in
/// the vertex shader (`gbuffer.wgsl::vs_line`; haloed lines `vs_line_h`, interpolated per
/// sample).
#[derive(Clone)]
pub struct GpuLines {
    points: wgpu::Buffer,
    colors: wgpu::Buffer,
    segments: wgpu::Buffer,
    count: u32,
    origin: DVec3,
    width: LineWidth,
    cylinder: bool,
    proxy_radius: f32,
    /// The points' times (one zero when the set has none).
    times: wgpu::Buffer,
    trail: Option<tubes::lines::Trail>,
    halo: Option<tubes::lines::Halo>,
    /// Per point (taper u, filter attribute); one zero pair when neither is set.
    aux: wgpu::Buffer,
    taper_t: f32,
    filter: Option<(f32, f32)>,
    /// A point cloud: each segment entry is a point.
    cloud: bool,
    /// The set's index in the list it was uploaded from, and the segments (first points, in
    /// the whole set) this part draws: `first <= s < end`; its points start at `first`.
    pub(crate) source: usize,
    first: u32,
    end: u32,
}

/// Where a line set of `points` points is cut into parts of at most `per_part` points that fit
/// the storage bindings: part `k` holds the points `[b[k], min(b[k + 1] + 1, points))` - next
/// parts share a point, so that a segment (joining points `s` and `s + 1`) or a point of a
/// cloud (`s` alone) lies whole in the part with `b[k] <= s < b[k + 1]`.
pub fn line_parts(points: usize, per_part: usize) -> Vec<usize> {
    let step = per_part.max(2) - 1;
    let mut b: Vec<usize> = (0..points).step_by(step).collect();
    b.push(points);
    b
}

impl GpuLines {
    /// Whether the set stands for tubes in the volume's shadow (`proxy_radius` > 0): it casts
    /// light then; other lines cast none.
    pub fn casts_light(&self) -> bool {
        self.proxy_radius > 0.0
    }

    /// Uploads `l` (no part when it has no segment) in as many parts as the adapter's storage
    /// bindings need (see [`line_parts`]; each part a draw of its own with the set's
    /// settings), every buffer filled through bounded staging copies.
    pub fn upload(gpu: &Gpu, l: &LineSet) -> Result<Vec<GpuLines>, GpuError> {
        if l.segments.is_empty() {
            return Ok(vec![]);
        }
        let n = l.positions.len();
        // Positions are the widest per-point buffer (12 bytes; aux 8, the rest 4).
        let per_part = (gpu.storage_limit() / 12).min(u32::MAX as u64) as usize;
        let bounds = line_parts(n, per_part);
        let mut parts = Vec::with_capacity(bounds.len() - 1);
        // Segments are ordered by their first point: each part's are one run of them.
        let mut seg = 0;
        for w in bounds.windows(2) {
            let (lo, hi) = (w[0], w[1]);
            let first = seg;
            while seg < l.segments.len() && (l.segments[seg] as usize) < hi {
                seg += 1;
            }
            let segments: Vec<u32> = l.segments[first..seg]
                .iter()
                .map(|&s| s - lo as u32)
                .collect();
            if segments.is_empty() {
                continue;
            }
            parts.push(GpuLines::upload_part(
                gpu,
                l,
                lo..(hi + 1).min(n),
                hi,
                &segments,
            )?);
        }
        if seg != l.segments.len() {
            return Err(GpuError::Operation(format!(
                "line segments: {} of {} are not in point order",
                l.segments.len() - seg,
                l.segments.len()
            )));
        }
        Ok(parts)
    }

    /// [`GpuLines::upload`], freeing `l`'s per-point data as its parts go up (the last part
    /// first, `l`'s vectors truncated behind it): the set is never held whole twice. `l` keeps
    /// its settings and no points.
    pub fn upload_freeing(gpu: &Gpu, l: &mut LineSet) -> Result<Vec<GpuLines>, GpuError> {
        if l.segments.is_empty() {
            return Ok(vec![]);
        }
        let n = l.positions.len();
        let per_part = (gpu.storage_limit() / 12).min(u32::MAX as u64) as usize;
        let bounds = line_parts(n, per_part);
        if l.segments.windows(2).any(|w| w[1] < w[0]) {
            return Err(GpuError::Operation(
                "line segments: not in point order".to_string(),
            ));
        }
        let mut parts = Vec::with_capacity(bounds.len() - 1);
        for w in bounds.windows(2).rev() {
            let (lo, hi) = (w[0], w[1]);
            let first = l.segments.partition_point(|&s| (s as usize) < lo);
            let segments: Vec<u32> = l.segments[first..].iter().map(|&s| s - lo as u32).collect();
            if !segments.is_empty() {
                parts.push(GpuLines::upload_part(
                    gpu,
                    l,
                    lo..(hi + 1).min(n),
                    hi,
                    &segments,
                )?);
            }
            // What this part took: only the point it shares with the part before stays.
            let keep = (lo + 1).min(n);
            let held = l.positions.len();
            l.segments.truncate(first);
            for v in [&mut l.times, &mut l.taper_u, &mut l.filter] {
                if v.len() == held {
                    v.truncate(keep);
                    v.shrink_to_fit();
                }
            }
            l.positions.truncate(keep);
            l.colors.truncate(keep);
            l.segments.shrink_to_fit();
            l.positions.shrink_to_fit();
            l.colors.shrink_to_fit();
        }
        parts.reverse();
        for v in [&mut l.times, &mut l.taper_u, &mut l.filter] {
            *v = Vec::new();
        }
        l.positions = Vec::new();
        l.colors = Vec::new();
        l.segments = Vec::new();
        Ok(parts)
    }

    /// Uploads points `range` of `l` with `segments` (relative to the range's start; the
    /// part's segments are those from `range.start` to `end`, excluded).
    fn upload_part(
        gpu: &Gpu,
        l: &LineSet,
        range: std::ops::Range<usize>,
        end: usize,
        segments: &[u32],
    ) -> Result<GpuLines, GpuError> {
        let storage = wgpu::BufferUsages::STORAGE;
        let n = range.len();
        let positions = &l.positions[range.clone()];
        gpu.check_buffer("line points", n as u64 * 12, storage)?;
        gpu.check_buffer("line segments", segments.len() as u64 * 4, storage)?;
        let staged = |label: &str, bytes: &[u8]| gpu.buffer_staged(label, bytes, storage);
        Ok(GpuLines {
            points: staged("line points", bytemuck::cast_slice(positions))?,
            colors: staged(
                "line colours",
                bytemuck::cast_slice(&l.colors[range.clone()]),
            )?,
            segments: staged("line segments", bytemuck::cast_slice(segments))?,
            count: segments.len() as u32,
            origin: l.origin,
            width: l.width,
            cylinder: l.cylinder,
            proxy_radius: l.proxy_radius.max(0.0),
            times: if l.times.len() == l.positions.len() {
                staged("line times", bytemuck::cast_slice(&l.times[range.clone()]))?
            } else {
                gpu.buffer("line times", &[0; 16], storage)
            },
            // Points have no trails, tapers or filters.
            trail: l
                .trail
                .filter(|_| l.times.len() == l.positions.len() && !l.points),
            halo: l.halo,
            aux: {
                let total = l.positions.len();
                let (tu, fl) = (l.taper_u.len() == total, l.filter.len() == total);
                if tu || fl {
                    let v: Vec<f32> = range
                        .clone()
                        .flat_map(|i| {
                            [
                                if tu { l.taper_u[i] } else { 0.5 },
                                if fl { l.filter[i] } else { 0.0 },
                            ]
                        })
                        .collect();
                    gpu.check_buffer("line aux", v.len() as u64 * 4, storage)?;
                    staged("line aux", bytemuck::cast_slice(&v))?
                } else {
                    gpu.buffer("line aux", &[0; 16], storage)
                }
            },
            taper_t: if l.taper_u.len() == l.positions.len() && !l.points {
                l.taper_t.max(0.0)
            } else {
                0.0
            },
            filter: (l.filter.len() == l.positions.len() && !l.filter.is_empty() && !l.points)
                .then_some((l.filter_min, l.filter_taper.max(0.0))),
            cloud: l.points,
            source: 0,
            first: range.start as u32,
            end: end as u32,
        })
    }

    /// This part's points (shared on the GPU, not uploaded again) with other segments: those
    /// of `segments` (first points in the whole set, in point order: a share of the set's) that
    /// fall in this part. `None` when none does.
    pub fn with_segments(&self, gpu: &Gpu, segments: &[u32]) -> Result<Option<GpuLines>, GpuError> {
        let a = segments.partition_point(|&s| s < self.first);
        let b = segments.partition_point(|&s| s < self.end);
        if a >= b {
            return Ok(None);
        }
        let local: Vec<u32> = segments[a..b].iter().map(|&s| s - self.first).collect();
        let storage = wgpu::BufferUsages::STORAGE;
        gpu.check_buffer("line segments", local.len() as u64 * 4, storage)?;
        Ok(Some(GpuLines {
            segments: gpu.buffer_staged("line segments", bytemuck::cast_slice(&local), storage)?,
            count: local.len() as u32,
            ..self.clone()
        }))
    }

    /// Segments drawn per pass.
    pub fn segments(&self) -> u64 {
        self.count as u64
    }

    /// The set's line width.
    pub fn width(&self) -> LineWidth {
        self.width
    }
}

/// A line set's per-view uniform. Keep in sync with `struct LineParams` in
/// `shaders/gbuffer.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct LineParams {
    /// Half the line's width: pixels, or world units when `world` is 1.
    pub half_width: f32,
    pub world: u32,
    pub cylinder: u32,
    /// The projection's P11.
    pub p11: f32,
    /// Width and height in pixels.
    pub viewport: [f32; 2],
    /// 1: perspective, 0: orthographic.
    pub perspective: u32,
    /// The nearest clip-space w a strip's end may have: segments are cut there.
    pub min_w: f32,
    /// The world radius the lines stand for in the volume's shadow (0: none).
    pub proxy_radius: f32,
    /// 1: draw the tapered trail `[now - back, now + forward]` of each line
    /// (`tubes::lines::Trail`), by the points' times.
    pub trail: u32,
    pub now: f32,
    pub back: f32,
    pub forward: f32,
    pub start: f32,
    pub min_width: f32,
    /// 1: a point cloud (each segment entry a point, drawn as a disc).
    pub points: u32,
    /// Halos (`tubes::lines::Halo`): 0 none, 1 uniform, 2 depth-dependent.
    pub halo: u32,
    pub halo_outline: u32,
    /// The strip's width over the line's.
    pub halo_width: f32,
    /// `d_max` in linear view depth, world units.
    pub halo_depth: f32,
    /// 0 linear, 1 sqrt, 2 square.
    pub displacement: u32,
    pub depth_cue: f32,
    pub near: f32,
    pub far: f32,
    /// The end taper's extent in u (0: none).
    pub taper_t: f32,
    /// 1: the attribute filter is on.
    pub filter_on: u32,
    pub filter_min: f32,
    pub filter_taper: f32,
}

/// A line set's draw in one frame: the bind groups of its view (group 0, as a mesh's) and of
/// its data with its line uniform (group 1).
struct LineDraw {
    view: wgpu::BindGroup,
    data: wgpu::BindGroup,
    segments: u32,
    halo: bool,
    /// The set stands for tubes in the volume's shadow: drawn in the back-depth pass too.
    proxy: bool,
}

/// A mesh's draw in one frame: its buffers and the bind group of its per-view uniform; a
/// slice's (`planes`) also the bind group of its layers, which its colour pass reads.
struct MeshDraw {
    mesh: GpuMesh,
    bind: wgpu::BindGroup,
    plane: Option<wgpu::BindGroup>,
}

/// LineAO's normal-depth map (Eichelbaum et al. §3.2): the nearest surface's linear view depth
/// (`r32float`, 0: none) and its world normal facing the viewer with the width code in alpha
/// (`rgba16float`: a width in pixels > 0, minus a world diameter < 0, 0 unknown), single
/// sampled, rendered `guard` pixels beyond the viewport on every side (§3.4's guard band):
/// viewport pixel (x, y) is texel (x + guard, y + guard). The band is drawn with the view's
/// projection widened to the larger image at the same pixel scale (clip x and y scaled by
/// `W / (W + 2g)` and `H / (H + 2g)`), so the interior is the viewport's raster; the G-buffer's
/// front depth is then copied from it, so the slices, the terms and the composite see one
/// depth.
pub struct NdMap {
    pub depth: wgpu::TextureView,
    pub normal: wgpu::TextureView,
    /// Lines' screen tangents `(cos 2θ, sin 2θ, |t.x|, 1)` (`rgba16float`; zero elsewhere).
    pub tangent: wgpu::TextureView,
    pub guard: u32,
    /// The map's size: the viewport plus twice the band.
    pub size: (u32, u32),
    depth_tex: wgpu::Texture,
    z: wgpu::TextureView,
    meshes: Vec<wgpu::BindGroup>,
    lines: Vec<(wgpu::BindGroup, wgpu::BindGroup)>,
}

/// Translucent meshes and slices, peeled into depth-sorted layers (`fs_peel`): pass k keeps, per
/// pixel, the nearest translucent fragment behind layer k - 1 and in front of the opaque
/// surfaces, and is copied into layer k of two array textures, which the march pass reads to
/// composite the layers into the volume in depth order (exact for up to `layers` translucent
/// fragments on a pixel's ray; farther ones are left out).
pub struct Peel {
    /// Layers peeled (0: the frame has no translucent geometry).
    pub layers: u32,
    /// Layer k's straight colour and opacity (`PEEL_COLOR`), as an array view.
    pub color: wgpu::TextureView,
    /// Layer k's world normal facing the viewer and linear view depth (w; 0: none).
    pub nd: wgpu::TextureView,
    color_tex: wgpu::Texture,
    nd_tex: wgpu::Texture,
    /// The two targets passes alternate between (colour, normal-depth), each copied into its
    /// layer after its pass.
    targets: [(
        wgpu::Texture,
        wgpu::TextureView,
        wgpu::Texture,
        wgpu::TextureView,
    ); 2],
    z: wgpu::TextureView,
    /// Per layer: the previous layer's normal-depth target and the opaque front depth.
    binds: Vec<wgpu::BindGroup>,
    draws: Vec<MeshDraw>,
}

/// A 2-D array texture of `layers` layers (copy destination, read by `textureLoad`), pooled by
/// label, and its array view.
fn target_array(
    gpu: &Gpu,
    label: &str,
    format: wgpu::TextureFormat,
    w: u32,
    h: u32,
    layers: u32,
) -> (wgpu::Texture, wgpu::TextureView) {
    let key = format!("target array {label} {format:?}");
    gpu.sized_entry(key, (w, h, layers), || {
        let t = gpu.device.create_texture(&wgpu::TextureDescriptor {
            label: Some(label),
            size: wgpu::Extent3d {
                width: w,
                height: h,
                depth_or_array_layers: layers,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format,
            usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
            view_formats: &[],
        });
        let v = t.create_view(&wgpu::TextureViewDescriptor {
            dimension: Some(wgpu::TextureViewDimension::D2Array),
            ..Default::default()
        });
        (t, v)
    })
}

/// The G-buffer's textures and the recorded draw of every mesh.
pub struct GBuffer {
    /// Colour and normal: `samples` samples each.
    pub color: wgpu::TextureView,
    pub normal: wgpu::TextureView,
    pub front: wgpu::TextureView,
    pub back: wgpu::TextureView,
    pub samples: u32,
    /// LineAO's normal-depth map, when a frame's terms need it.
    pub nd: Option<NdMap>,
    front_tex: wgpu::Texture,
    size: (u32, u32),
    depth_front: wgpu::TextureView,
    depth_back: wgpu::TextureView,
    depth_ms: Option<wgpu::TextureView>,
    pipes: Pipelines,
    meshes: Vec<MeshDraw>,
    lines: Vec<LineDraw>,
    /// Translucent meshes and slices (no layers when there are none).
    pub peel: Peel,
    /// At most this many triangles a submission (see [`Gpu::batch_triangles`]), with the
    /// device and queue that submit and wait for each batch.
    batch: Option<(u64, wgpu::Device, wgpu::Queue)>,
    /// Whether the back-depth pass draws (only the light volume reads the back depth).
    draw_back: bool,
}

/// The least triangles a batch of [`batch_for`] holds (2^16).
pub const MIN_BATCH_TRIANGLES: u64 = 1 << 16;

/// The batch size of a pass drawing `total` triangles on an adapter that takes at most `budget`
/// a submission: `total / 16`, within [`MIN_BATCH_TRIANGLES`]..`budget`. Lavapipe queues about
/// 550 bytes a triangle of a batch while it draws, so a batch in proportion to the scene keeps
/// that queue at most about 35 bytes a triangle drawn (issue 18's bound of 64 bytes a point, a
/// line segment being 2 triangles, holds the lines' 20 bytes on the GPU, their staging and this)
/// wherever the batch is above the floor; scenes of more than 4.2 M triangles get the full
/// budget (docs/benchmarks.md, "Whole-brain tractograms").
pub fn batch_for(total: u64, budget: u64) -> u64 {
    (total / 16).clamp(MIN_BATCH_TRIANGLES.min(budget), budget)
}

/// Segments an instance of a line draw holds (`gbuffer.wgsl::SEGMENTS_PER_INSTANCE`). Mesa's
/// draw module (lavapipe, llvmpipe) runs a draw in chunks: an instance of a non-instanced draw
/// of 6 vertices a segment in chunks of 4,095 vertices, and a chunk with one vertex outside
/// the viewport (a line leaving the image) goes through its clipping path, which clears the
/// ids of all the chunk's vertices each time its small output buffer fills (a few dozen of our
/// vertices): on a line set reaching out of the image, a third of the frame (`perf`, 3 M
/// triangles of CST_L). Instances of 32 segments make chunks of 192 vertices
/// (docs/benchmarks.md, "Lines leaving the image on lavapipe").
pub const SEGMENTS_PER_INSTANCE: u32 = 32;

/// Draws segments `s0..s1` of the bound line set (`vs_line`): whole instances of
/// [`SEGMENTS_PER_INSTANCE`], the segments before the first and after the last as instance 0.
fn draw_segments(pass: &mut wgpu::RenderPass<'_>, s0: u32, s1: u32) {
    let k = SEGMENTS_PER_INSTANCE;
    let a = s0.div_ceil(k).saturating_mul(k).min(s1);
    let b = (s1 / k * k).max(a);
    if a > s0 {
        pass.draw(6 * s0..6 * a, 0..1);
    }
    if b > a {
        pass.draw(0..6 * k, a / k..b / k);
    }
    if s1 > b {
        pass.draw(6 * b..6 * s1, 0..1);
    }
}

/// The draws of a pass cut into batches of at most `budget` triangles (`None`: one batch):
/// `sizes[i]` is draw `i`'s triangle count; each batch lists `(draw, first, end)` triangle
/// ranges, in order, every triangle in exactly one. At least one batch (empty when nothing
/// is drawn: the pass still clears its targets).
pub fn batches(sizes: &[u64], budget: Option<u64>) -> Vec<Vec<(usize, u64, u64)>> {
    let budget = budget.unwrap_or(u64::MAX).max(1);
    let mut out = vec![vec![]];
    let mut room = budget;
    for (i, &n) in sizes.iter().enumerate() {
        let mut at = 0;
        while at < n {
            if room == 0 {
                out.push(vec![]);
                room = budget;
            }
            let take = (n - at).min(room);
            out.last_mut().unwrap().push((i, at, at + take));
            at += take;
            room -= take;
        }
    }
    out
}

/// A pass's pipeline for meshes and for lines.
#[derive(Clone)]
struct PipelinePair {
    mesh: wgpu::RenderPipeline,
    line: wgpu::RenderPipeline,
    /// Haloed lines (the fragment entry point with `_h`, which writes the depth attachment
    /// itself, after `vs_line_h`: per-sample shading, each sample core or rim).
    line_halo: wgpu::RenderPipeline,
}

/// The G-buffer's pipelines for one sample count, made once per device.
#[derive(Clone)]
struct Pipelines {
    layout: wgpu::BindGroupLayout,
    line_layout: wgpu::BindGroupLayout,
    /// Slices' layers (group 2 of `front_plane`).
    plane_layout: wgpu::BindGroupLayout,
    /// Single sample: colour, normal and depth; multisampled: colour and normal.
    front: PipelinePair,
    /// The colour pass of slices (`fs_front_p` or `fs_surface_p`): meshes whose colour is
    /// sampled from their layers.
    front_plane: wgpu::RenderPipeline,
    /// Depth peeling of translucent meshes and slices (group 3: `peel_layout`).
    peel_layout: wgpu::BindGroupLayout,
    peel_mesh: wgpu::RenderPipeline,
    peel_plane: wgpu::RenderPipeline,
    /// Multisampled only: the single-sample depth.
    depth: Option<PipelinePair>,
    /// LineAO's normal-depth map (single sample).
    nd: PipelinePair,
    back: PipelinePair,
}

impl Pipelines {
    fn new(gpu: &Gpu, samples: u32) -> Pipelines {
        let device = &gpu.device;
        let ms = samples > 1;
        let module = gpu.shader("gbuffer.wgsl", &with_prelude(SHADER));
        let layout = gpu.layout(
            "gbuffer",
            wgpu::ShaderStages::VERTEX_FRAGMENT,
            &[Slot::Uniform],
        );
        let line_layout = gpu.layout(
            "gbuffer lines",
            // The halo entries read the line uniform in the fragment stage.
            wgpu::ShaderStages::VERTEX_FRAGMENT,
            &[
                Slot::Uniform,
                Slot::Storage,
                Slot::Storage,
                Slot::Storage,
                Slot::Storage,
                Slot::Storage,
            ],
        );
        let plane_layout = gpu.layout(
            "gbuffer planes",
            wgpu::ShaderStages::FRAGMENT,
            &[
                Slot::Uniform,
                Slot::Storage,
                Slot::Storage,
                Slot::Storage,
                Slot::Storage,
                Slot::Storage,
            ],
        );
        let pl = gpu.pipeline_layout("gbuffer", &[&layout]);
        let pl_lines = gpu.pipeline_layout("gbuffer lines", &[&layout, &line_layout]);
        // Slices bind group 2 (group 1 is the lines'; the slice entries do not use it).
        let pl_planes = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("gbuffer planes"),
            bind_group_layouts: &[Some(&layout), None, Some(&plane_layout)],
            immediate_size: 0,
        });
        let peel_layout = gpu.layout(
            "gbuffer peel",
            wgpu::ShaderStages::FRAGMENT,
            &[Slot::UnfilterableTexture, Slot::UnfilterableTexture],
        );
        let pl_peel = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("gbuffer peel"),
            bind_group_layouts: &[Some(&layout), None, None, Some(&peel_layout)],
            immediate_size: 0,
        });
        let pl_peel_planes = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("gbuffer peel planes"),
            bind_group_layouts: &[Some(&layout), None, Some(&plane_layout), Some(&peel_layout)],
            immediate_size: 0,
        });
        let attributes = wgpu::vertex_attr_array![0 => Float32x3, 1 => Float32x3, 2 => Unorm8x4];
        let vbl = [Some(wgpu::VertexBufferLayout {
            array_stride: STRIDE,
            step_mode: wgpu::VertexStepMode::Vertex,
            attributes: &attributes,
        })];
        let pipeline_in = |layout: &wgpu::PipelineLayout,
                           vertex: &str,
                           entry: &str,
                           targets: &[Option<wgpu::ColorTargetState>],
                           count: u32| {
            device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                label: Some(entry),
                layout: Some(layout),
                vertex: wgpu::VertexState {
                    module: &module,
                    entry_point: Some(vertex),
                    compilation_options: Default::default(),
                    buffers: if vertex == "vs" { &vbl } else { &[] },
                },
                primitive: wgpu::PrimitiveState::default(),
                depth_stencil: Some(wgpu::DepthStencilState {
                    format: wgpu::TextureFormat::Depth32Float,
                    depth_write_enabled: Some(true),
                    depth_compare: Some(wgpu::CompareFunction::Less),
                    stencil: Default::default(),
                    bias: Default::default(),
                }),
                multisample: wgpu::MultisampleState {
                    count,
                    ..Default::default()
                },
                fragment: Some(wgpu::FragmentState {
                    module: &module,
                    entry_point: Some(entry),
                    compilation_options: Default::default(),
                    targets,
                }),
                multiview_mask: None,
                cache: None,
            })
        };
        // Meshes ("vs"), lines ("vs_line") and haloed lines ("vs_line_h": interpolated per
        // sample, so that a multisampled target resolves the core's edge sample by sample).
        let pipeline =
            |vertex: &str, entry: &str, targets: &[Option<wgpu::ColorTargetState>], count: u32| {
                pipeline_in(
                    if vertex == "vs" { &pl } else { &pl_lines },
                    vertex,
                    entry,
                    targets,
                    count,
                )
            };
        let pair =
            |entry: &str, targets: &[Option<wgpu::ColorTargetState>], count: u32| PipelinePair {
                mesh: pipeline("vs", entry, targets, count),
                line: pipeline("vs_line", entry, targets, count),
                line_halo: pipeline("vs_line_h", &format!("{entry}_h"), targets, count),
            };
        let t = |f| Some(wgpu::ColorTargetState::from(f));
        let front = if ms {
            pair("fs_surface", &[t(COLOR), t(NORMAL)], samples)
        } else {
            pair("fs_front", &[t(COLOR), t(NORMAL), t(DEPTH)], 1)
        };
        let front_plane = if ms {
            pipeline_in(
                &pl_planes,
                "vs",
                "fs_surface_p",
                &[t(COLOR), t(NORMAL)],
                samples,
            )
        } else {
            pipeline_in(
                &pl_planes,
                "vs",
                "fs_front_p",
                &[t(COLOR), t(NORMAL), t(DEPTH)],
                1,
            )
        };
        let peel_targets = [t(PEEL_COLOR), t(PEEL_ND)];
        Pipelines {
            front,
            front_plane,
            peel_mesh: pipeline_in(&pl_peel, "vs", "fs_peel", &peel_targets, 1),
            peel_plane: pipeline_in(&pl_peel_planes, "vs", "fs_peel_p", &peel_targets, 1),
            peel_layout,
            plane_layout,
            depth: ms.then(|| pair("fs_depth", &[t(DEPTH)], 1)),
            nd: pair("fs_nd", &[t(DEPTH), t(NORMAL), t(NORMAL)], 1),
            back: pair("fs_back", &[t(DEPTH)], 1),
            layout,
            line_layout,
        }
    }
}

/// The sample count for `requested` that colour, normal and depth targets all support, and a
/// note when it had to be lowered.
pub fn sample_count(gpu: &Gpu, requested: u32) -> (u32, Option<String>) {
    let counts = |f| crate::gpu::supported_sample_counts(&gpu.adapter, f);
    let (a, b, c) = (
        counts(COLOR),
        counts(NORMAL),
        counts(wgpu::TextureFormat::Depth32Float),
    );
    let n = [1u32, 2, 4, 8, 16]
        .into_iter()
        .filter(|n| *n <= requested.max(1) && a.contains(n) && b.contains(n) && c.contains(n))
        .max()
        .unwrap_or(1);
    let note = (n != requested.max(1)).then(|| {
        format!(
            "render.msaa = {requested}: this adapter renders the G-buffer with {a:?} samples for colour, {b:?} for normals, {c:?} for depth; using {n}"
        )
    });
    (n, note)
}

fn target(
    gpu: &Gpu,
    label: &str,
    format: wgpu::TextureFormat,
    w: u32,
    h: u32,
) -> (wgpu::Texture, wgpu::TextureView) {
    target_ms(gpu, label, format, w, h, 1)
}

fn target_ms(
    gpu: &Gpu,
    label: &str,
    format: wgpu::TextureFormat,
    w: u32,
    h: u32,
    samples: u32,
) -> (wgpu::Texture, wgpu::TextureView) {
    // One target per label and format, replaced when the size or the sample count changes.
    let key = format!("target {label} {format:?}");
    gpu.sized_entry(key, (w, h, samples), || {
        let mut usage =
            wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING;
        if samples == 1 {
            // The front depth is copied from LineAO's guard-banded map.
            usage |= wgpu::TextureUsages::COPY_SRC | wgpu::TextureUsages::COPY_DST;
        }
        let t = gpu.device.create_texture(&wgpu::TextureDescriptor {
            label: Some(label),
            size: wgpu::Extent3d {
                width: w,
                height: h,
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: samples,
            dimension: wgpu::TextureDimension::D2,
            format,
            usage,
            view_formats: &[],
        });
        let v = t.create_view(&Default::default());
        (t, v)
    })
}

/// `clip` scaled so that a `w x h` viewport becomes the interior of a `(w + 2g) x (h + 2g)`
/// image at the same pixel scale: pixel (x, y) moves to (x + g, y + g).
pub fn guard_band(clip: DMat4, w: u32, h: u32, g: u32) -> DMat4 {
    let sx = w as f64 / (w + 2 * g) as f64;
    let sy = h as f64 / (h + 2 * g) as f64;
    DMat4::from_scale(DVec3::new(sx, sy, 1.0)) * clip
}

impl GBuffer {
    /// Leaves the back depth cleared (0: no back face) instead of drawing it: only the light
    /// volume of `dos` and `combined` reads it (a tube's inside between its faces), and the
    /// pass draws all the tubes again (a third of the G-buffer's geometry with MSAA).
    pub fn without_back(&mut self) {
        self.draw_back = false;
    }

    /// Prepares the passes drawing `meshes` and `lines` (uploaded) for `camera` at `width x
    /// height` with `samples` samples per pixel (a count [`sample_count`] returned), and
    /// LineAO's normal-depth map with a band of `nd_guard` pixels when given; `trail_now`
    /// moves every line set's trail to that time. The targets are
    /// pooled per size (every pass clears what it draws into), the pipelines made once per
    /// sample count.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        gpu: &Gpu,
        camera: &Camera,
        width: u32,
        height: u32,
        meshes: &[GpuMesh],
        planes: &[crate::planes::GpuPlane],
        lines: &[GpuLines],
        clip: &[([f64; 3], f64)],
        samples: u32,
        nd_guard: Option<u32>,
        trail_now: Option<f32>,
        peel_layers: u32,
    ) -> GBuffer {
        let ms = samples > 1;
        let pipes = gpu.cached(format!("gbuffer pipelines {samples}"), || {
            Pipelines::new(gpu, samples)
        });
        let layout = pipes.layout.clone();
        let aspect = width as f64 / height.max(1) as f64;
        let vp_rel = camera.view_projection(aspect) * DMat4::from_translation(camera.eye);
        let f = camera.forward();
        let e = camera.eye;
        // The view of a set whose positions are relative to `origin`, through `vp`.
        let view = |vp: DMat4, origin: DVec3, width_code: f32, opacity: f32| {
            let offset: DVec3 = origin - e;
            let params = GBufferParams {
                view_proj_rel: mat4(vp),
                offset: vec4([offset.x, offset.y, offset.z, 0.0]),
                forward: vec4([f.x, f.y, f.z, 0.0]),
                eye: vec4([e.x, e.y, e.z, 1.0]),
                clip: clip_planes(clip),
                n_clip: clip.len().min(8) as u32,
                width_code,
                opacity,
                pad2: 0,
            };
            let params = gpu.buffer(
                "gbuffer params",
                bytemuck::bytes_of(&params),
                wgpu::BufferUsages::UNIFORM,
            );
            gpu.bind("gbuffer", &layout, &[params.as_entire_binding()])
        };
        let code = |m: &GpuMesh| -m.diameter;
        let p11 = camera.projection_matrix(aspect).y_axis.y as f32;
        let persp = matches!(
            camera.projection,
            occlusion::camera::Projection::Perspective { .. }
        );
        // Clip-space w is the view depth under perspective (1 under orthographic projection):
        // strips end no nearer than half the near plane.
        let min_w = if persp { 0.5 * camera.near as f32 } else { 0.0 };
        // A line set's data for a viewport of `vw x vh` whose P11 is `p11`.
        let line_data = |l: &GpuLines, p11: f32, vw: u32, vh: u32| {
            let (half_width, world) = match l.width {
                LineWidth::Pixels(w) => (0.5 * w as f32, 0),
                LineWidth::World(w) => (0.5 * w as f32, 1),
            };
            let trail = l.trail.map(|mut t| {
                if let Some(now) = trail_now {
                    t.now = now;
                }
                t
            });
            let t = trail.unwrap_or(tubes::lines::Trail {
                now: 0.0,
                back: 0.0,
                forward: 0.0,
                start: 0.0,
                min_width: 1.0,
            });
            let params = LineParams {
                half_width,
                world,
                cylinder: l.cylinder as u32,
                p11,
                viewport: [vw as f32, vh as f32],
                perspective: persp as u32,
                min_w,
                proxy_radius: l.proxy_radius,
                trail: trail.is_some() as u32,
                now: t.now,
                back: t.back,
                forward: t.forward,
                start: t.start,
                min_width: t.min_width,
                points: l.cloud as u32,
                halo: l.halo.map_or(0, |h| if h.uniform { 1 } else { 2 }),
                halo_outline: l.halo.is_some_and(|h| h.outline) as u32,
                halo_width: l.halo.map_or(1.0, |h| h.width.max(1.0)),
                halo_depth: l
                    .halo
                    .map_or(0.0, |h| h.d_max * (camera.far - camera.near) as f32),
                displacement: match l.halo.map(|h| h.displacement) {
                    Some(tubes::lines::Displacement::Sqrt) => 1,
                    Some(tubes::lines::Displacement::Square) => 2,
                    _ => 0,
                },
                depth_cue: l.halo.map_or(0.0, |h| h.depth_cue),
                near: camera.near as f32,
                far: camera.far as f32,
                taper_t: l.taper_t,
                filter_on: l.filter.is_some() as u32,
                filter_min: l.filter.map_or(0.0, |f| f.0),
                filter_taper: l.filter.map_or(0.0, |f| f.1),
            };
            let params = gpu.buffer(
                "line params",
                bytemuck::bytes_of(&params),
                wgpu::BufferUsages::UNIFORM,
            );
            gpu.bind(
                "gbuffer lines",
                &pipes.line_layout,
                &[
                    params.as_entire_binding(),
                    l.points.as_entire_binding(),
                    l.colors.as_entire_binding(),
                    l.segments.as_entire_binding(),
                    l.times.as_entire_binding(),
                    l.aux.as_entire_binding(),
                ],
            )
        };
        // A slice's layers for this view: their uniform and buffers (group 2).
        let plane_data = |p: &crate::planes::GpuPlane| {
            let params = gpu.buffer(
                "plane params",
                bytemuck::bytes_of(&p.params(e)),
                wgpu::BufferUsages::UNIFORM,
            );
            let mut r = vec![params.as_entire_binding(), p.lut.as_entire_binding()];
            r.extend(p.fields.iter().map(|f| f.as_entire_binding()));
            gpu.bind("gbuffer planes", &pipes.plane_layout, &r)
        };
        // Slices are meshes (their polygons) with a colour of their own; translucent ones are
        // peeled, not drawn in the opaque passes.
        let (meshes, translucent): (Vec<_>, Vec<_>) = meshes
            .iter()
            .map(|m| (m, None))
            .chain(planes.iter().map(|p| (&p.mesh, Some(p))))
            .partition(|(m, _): &(&GpuMesh, Option<&crate::planes::GpuPlane>)| !m.translucent());
        let draw = |(m, p): &(&GpuMesh, Option<&crate::planes::GpuPlane>)| MeshDraw {
            mesh: (*m).clone(),
            bind: view(vp_rel, m.origin, code(m), m.opacity),
            plane: p.map(plane_data),
        };
        let mesh_draws = meshes.iter().map(draw).collect();
        let peel_draws: Vec<MeshDraw> = translucent.iter().map(draw).collect();
        let line_draws = lines
            .iter()
            .map(|l| LineDraw {
                view: view(vp_rel, l.origin, 0.0, 1.0),
                data: line_data(l, p11, width, height),
                segments: l.count,
                halo: l.halo.is_some(),
                proxy: l.proxy_radius > 0.0,
            })
            .collect();
        let nd = nd_guard.map(|g| {
            let (nw, nh) = (width + 2 * g, height + 2 * g);
            let vp = guard_band(vp_rel, width, height, g);
            let p11g = p11 * height as f32 / nh as f32;
            let (depth_tex, depth) = target(gpu, "lineao nd depth", DEPTH, nw, nh);
            NdMap {
                depth,
                depth_tex,
                normal: target(gpu, "lineao nd normal", NORMAL, nw, nh).1,
                tangent: target(gpu, "lineao nd tangent", NORMAL, nw, nh).1,
                guard: g,
                size: (nw, nh),
                z: target(
                    gpu,
                    "lineao nd z",
                    wgpu::TextureFormat::Depth32Float,
                    nw,
                    nh,
                )
                .1,
                meshes: meshes
                    .iter()
                    .map(|(m, _)| view(vp, m.origin, code(m), 1.0))
                    .collect(),
                lines: lines
                    .iter()
                    .map(|l| (view(vp, l.origin, 0.0, 1.0), line_data(l, p11g, nw, nh)))
                    .collect(),
            }
        });
        let depth = |l| target(gpu, l, wgpu::TextureFormat::Depth32Float, width, height).1;
        let (front_tex, front) = target(gpu, "gbuffer front depth", DEPTH, width, height);
        let layers = if peel_draws.is_empty() {
            0
        } else {
            peel_layers.clamp(1, MAX_PEEL_LAYERS)
        };
        let (pw, ph, pl) = if layers > 0 {
            (width, height, layers)
        } else {
            (1, 1, 1)
        };
        let (color_tex, color) = target_array(gpu, "peel colour", PEEL_COLOR, pw, ph, pl);
        let (nd_tex, nd_view) = target_array(gpu, "peel nd", PEEL_ND, pw, ph, pl);
        let pair = |k: usize| {
            let (ct, cv) = target(gpu, &format!("peel colour {k}"), PEEL_COLOR, pw, ph);
            let (nt, nv) = target(gpu, &format!("peel nd {k}"), PEEL_ND, pw, ph);
            (ct, cv, nt, nv)
        };
        let targets = [pair(0), pair(1)];
        // Never written: the first layer's "previous" depth, 0 everywhere.
        let none = target(gpu, "peel none", PEEL_ND, pw, ph).1;
        let binds = (0..layers as usize)
            .map(|k| {
                let prev = if k == 0 {
                    &none
                } else {
                    &targets[(k + 1) % 2].3
                };
                gpu.bind(
                    "gbuffer peel",
                    &pipes.peel_layout,
                    &[
                        wgpu::BindingResource::TextureView(prev),
                        wgpu::BindingResource::TextureView(&front),
                    ],
                )
            })
            .collect();
        let peel = Peel {
            layers,
            color,
            nd: nd_view,
            color_tex,
            nd_tex,
            z: target(gpu, "peel z", wgpu::TextureFormat::Depth32Float, pw, ph).1,
            targets,
            binds,
            draws: peel_draws,
        };
        let batch = gpu
            .batch_triangles()
            .map(|n| (n, gpu.device.clone(), gpu.queue.clone()));
        GBuffer {
            batch,
            draw_back: true,
            color: target_ms(gpu, "gbuffer colour", COLOR, width, height, samples).1,
            normal: target_ms(gpu, "gbuffer normal", NORMAL, width, height, samples).1,
            samples,
            depth_ms: ms.then(|| {
                target_ms(
                    gpu,
                    "gbuffer z ms",
                    wgpu::TextureFormat::Depth32Float,
                    width,
                    height,
                    samples,
                )
                .1
            }),
            front,
            front_tex,
            size: (width, height),
            back: target(gpu, "gbuffer back depth", DEPTH, width, height).1,
            depth_front: depth("gbuffer z front"),
            depth_back: depth("gbuffer z back"),
            nd,
            pipes,
            meshes: mesh_draws,
            lines: line_draws,
            peel,
        }
    }

    /// Triangles drawn per pass (two per line segment; translucent meshes once).
    pub fn triangles(&self) -> u64 {
        self.meshes
            .iter()
            .chain(&self.peel.draws)
            .map(|m| m.mesh.triangles())
            .sum::<u64>()
            + self
                .lines
                .iter()
                .map(|l| 2 * l.segments as u64)
                .sum::<u64>()
    }

    /// Records the passes (they also clear the targets when there is nothing to draw): the
    /// surfaces' colour and normal (with their depth when single-sampled), the single-sample
    /// depth (LineAO's guard-banded normal-depth map instead when there is one, its interior
    /// then copied to the front depth), and the back depth.
    pub fn record(&self, enc: &mut wgpu::CommandEncoder) {
        let clear = |view| {
            Some(wgpu::RenderPassColorAttachment {
                view,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT),
                    store: wgpu::StoreOp::Store,
                },
            })
        };
        let p = &self.pipes;
        #[derive(PartialEq)]
        enum Kind {
            /// The colour pass (slices take their own pipeline here).
            Color,
            Surface,
            Nd,
            Back,
        }
        let mut passes: Vec<(Kind, &PipelinePair, Vec<_>, &wgpu::TextureView)> = vec![];
        match (&p.depth, &self.depth_ms) {
            (Some(dp), Some(dms)) => {
                passes.push((
                    Kind::Color,
                    &p.front,
                    vec![clear(&self.color), clear(&self.normal)],
                    dms,
                ));
                if self.nd.is_none() {
                    passes.push((
                        Kind::Surface,
                        dp,
                        vec![clear(&self.front)],
                        &self.depth_front,
                    ));
                }
            }
            _ => passes.push((
                Kind::Color,
                &p.front,
                vec![clear(&self.color), clear(&self.normal), clear(&self.front)],
                &self.depth_front,
            )),
        }
        if let Some(nd) = &self.nd {
            passes.push((
                Kind::Nd,
                &p.nd,
                vec![clear(&nd.depth), clear(&nd.normal), clear(&nd.tangent)],
                &nd.z,
            ));
        }
        passes.push((
            Kind::Back,
            &p.back,
            vec![clear(&self.back)],
            &self.depth_back,
        ));
        for (kind, pipe, targets, depth) in passes {
            let nd = self.nd.as_ref().filter(|_| kind == Kind::Nd);
            // Lines have no back faces: the back-depth pass draws only those that stand for
            // tubes in the volume's shadow.
            // Without a light volume, nothing reads the back depth: the pass only clears.
            let skipped = kind == Kind::Back && !self.draw_back;
            let lines: Vec<(usize, &LineDraw)> = self
                .lines
                .iter()
                .enumerate()
                .filter(|(_, l)| kind != Kind::Back || (l.proxy && !skipped))
                .collect();
            let sizes: Vec<u64> = self
                .meshes
                .iter()
                .map(|m| if skipped { 0 } else { m.mesh.count as u64 / 3 })
                .chain(lines.iter().map(|(_, l)| 2 * l.segments as u64))
                .collect();
            let total = sizes.iter().sum();
            let batches = batches(&sizes, self.batch.as_ref().map(|b| batch_for(total, b.0)));
            for (b, batch) in batches.iter().enumerate() {
                let (first, last) = (b == 0, b + 1 == batches.len());
                // Later batches draw over what the earlier ones left.
                let targets: Vec<_> = targets
                    .iter()
                    .map(|t| {
                        t.clone().map(|mut a| {
                            if !first {
                                a.ops.load = wgpu::LoadOp::Load;
                            }
                            a
                        })
                    })
                    .collect();
                {
                    let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
                        label: Some("gbuffer"),
                        color_attachments: &targets,
                        depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                            view: depth,
                            depth_ops: Some(wgpu::Operations {
                                load: if first {
                                    wgpu::LoadOp::Clear(1.0)
                                } else {
                                    wgpu::LoadOp::Load
                                },
                                store: if last {
                                    wgpu::StoreOp::Discard
                                } else {
                                    wgpu::StoreOp::Store
                                },
                            }),
                            stencil_ops: None,
                        }),
                        timestamp_writes: None,
                        occlusion_query_set: None,
                        multiview_mask: None,
                    });
                    for &(i, t0, t1) in batch {
                        if let Some(MeshDraw {
                            mesh: m,
                            bind,
                            plane,
                        }) = self.meshes.get(i)
                        {
                            match (plane, kind == Kind::Color) {
                                (Some(g), true) => {
                                    pass.set_pipeline(&p.front_plane);
                                    pass.set_bind_group(2, g, &[]);
                                }
                                _ => pass.set_pipeline(&pipe.mesh),
                            }
                            pass.set_bind_group(0, nd.map_or(bind, |n| &n.meshes[i]), &[]);
                            pass.set_vertex_buffer(0, m.vertices.slice(..));
                            pass.set_index_buffer(m.indices.slice(..), wgpu::IndexFormat::Uint32);
                            pass.draw_indexed(3 * t0 as u32..3 * t1 as u32, 0, 0..1);
                        } else {
                            let (k, l) = lines[i - self.meshes.len()];
                            pass.set_pipeline(if l.halo { &pipe.line_halo } else { &pipe.line });
                            let (v, d) =
                                nd.map_or((&l.view, &l.data), |n| (&n.lines[k].0, &n.lines[k].1));
                            pass.set_bind_group(0, v, &[]);
                            pass.set_bind_group(1, d, &[]);
                            // Two triangles a segment.
                            draw_segments(&mut pass, t0 as u32 / 2, t1 as u32 / 2);
                        }
                    }
                }
                if !last {
                    self.flush(enc);
                }
            }
            if let (Kind::Nd, Some(nd)) = (&kind, &self.nd) {
                enc.copy_texture_to_texture(
                    wgpu::TexelCopyTextureInfo {
                        texture: &nd.depth_tex,
                        mip_level: 0,
                        origin: wgpu::Origin3d {
                            x: nd.guard,
                            y: nd.guard,
                            z: 0,
                        },
                        aspect: wgpu::TextureAspect::All,
                    },
                    wgpu::TexelCopyTextureInfo {
                        texture: &self.front_tex,
                        mip_level: 0,
                        origin: wgpu::Origin3d::ZERO,
                        aspect: wgpu::TextureAspect::All,
                    },
                    wgpu::Extent3d {
                        width: self.size.0,
                        height: self.size.1,
                        depth_or_array_layers: 1,
                    },
                );
            }
        }
        self.record_peel(enc);
    }

    /// Submits what `enc` holds and waits for it, continuing in a fresh encoder (between
    /// batches; see [`batches`]).
    fn flush(&self, enc: &mut wgpu::CommandEncoder) {
        if let Some((_, device, queue)) = &self.batch {
            let done = std::mem::replace(enc, device.create_command_encoder(&Default::default()));
            queue.submit([done.finish()]);
            // A failure shows in the frame's own wait (`Gpu::wait`).
            let _ = device.poll(wgpu::PollType::wait_indefinitely());
        }
    }

    /// The peel passes: layer k into the targets `k % 2`, then copied into layer k.
    fn record_peel(&self, enc: &mut wgpu::CommandEncoder) {
        let pl = &self.peel;
        let p = &self.pipes;
        for k in 0..pl.layers as usize {
            let (ct, cv, nt, nv) = &pl.targets[k % 2];
            let clear = |view| {
                Some(wgpu::RenderPassColorAttachment {
                    view,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT),
                        store: wgpu::StoreOp::Store,
                    },
                })
            };
            {
                let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
                    label: Some("gbuffer peel"),
                    color_attachments: &[clear(cv), clear(nv)],
                    depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                        view: &pl.z,
                        depth_ops: Some(wgpu::Operations {
                            load: wgpu::LoadOp::Clear(1.0),
                            store: wgpu::StoreOp::Discard,
                        }),
                        stencil_ops: None,
                    }),
                    timestamp_writes: None,
                    occlusion_query_set: None,
                    multiview_mask: None,
                });
                for MeshDraw {
                    mesh: m,
                    bind,
                    plane,
                } in &pl.draws
                {
                    match plane {
                        Some(g) => {
                            pass.set_pipeline(&p.peel_plane);
                            pass.set_bind_group(2, g, &[]);
                        }
                        None => pass.set_pipeline(&p.peel_mesh),
                    }
                    pass.set_bind_group(0, bind, &[]);
                    pass.set_bind_group(3, &pl.binds[k], &[]);
                    pass.set_vertex_buffer(0, m.vertices.slice(..));
                    pass.set_index_buffer(m.indices.slice(..), wgpu::IndexFormat::Uint32);
                    pass.draw_indexed(0..m.count, 0, 0..1);
                }
            }
            for (src, dst) in [(ct, &pl.color_tex), (nt, &pl.nd_tex)] {
                enc.copy_texture_to_texture(
                    wgpu::TexelCopyTextureInfo {
                        texture: src,
                        mip_level: 0,
                        origin: wgpu::Origin3d::ZERO,
                        aspect: wgpu::TextureAspect::All,
                    },
                    wgpu::TexelCopyTextureInfo {
                        texture: dst,
                        mip_level: 0,
                        origin: wgpu::Origin3d {
                            x: 0,
                            y: 0,
                            z: k as u32,
                        },
                        aspect: wgpu::TextureAspect::All,
                    },
                    wgpu::Extent3d {
                        width: self.size.0,
                        height: self.size.1,
                        depth_or_array_layers: 1,
                    },
                );
            }
        }
    }
}

/// The most translucent layers a frame peels (`render.translucent_layers`).
pub const MAX_PEEL_LAYERS: u32 = 8;

#[cfg(test)]
mod tests {
    #[test]
    fn batches_hold_every_triangle_once_within_the_budget() {
        let sizes = [5u64, 0, 12, 3, 7];
        for budget in [None, Some(1), Some(4), Some(7), Some(27), Some(100)] {
            let b = super::batches(&sizes, budget);
            let cap = budget.unwrap_or(u64::MAX);
            let mut seen = vec![0u64; sizes.len()];
            let mut next = (0usize, 0u64);
            for batch in &b {
                let total: u64 = batch.iter().map(|(_, a, e)| e - a).sum();
                assert!(total <= cap && total > 0, "{budget:?}: {b:?}");
                for &(i, a, e) in batch {
                    // In order, contiguous, no overlap.
                    assert!(a < e && (i, a) >= next, "{budget:?}: {b:?}");
                    let joined = if i == next.0 { a == next.1 } else { a == 0 };
                    assert!(joined, "{budget:?}: gap before draw {i} at {a}");
                    next = (i, e);
                    seen[i] += e - a;
                }
            }
            assert_eq!(seen, sizes, "{budget:?}: {b:?}");
            // Full batches but the last: as few as the budget allows.
            let want = 27u64.div_ceil(cap.min(27));
            assert_eq!(b.len() as u64, want, "{budget:?}: {b:?}");
        }
        assert_eq!(super::batches(&[], Some(4)), vec![vec![]]);
    }

    #[test]
    fn batches_follow_the_scene_between_the_floor_and_the_budget() {
        use super::{batch_for, MIN_BATCH_TRIANGLES as MIN};
        let budget = crate::gpu::CPU_BATCH_TRIANGLES;
        // Small scenes: the floor (a few batches at most).
        assert_eq!(batch_for(0, budget), MIN);
        assert_eq!(batch_for(100_000, budget), MIN);
        // 10^6 line points (2 x 10^6 triangles): an eighth of the scene, queue <= 35 B/tri.
        let b = batch_for(2_000_000, budget);
        assert_eq!(b, 125_000);
        assert!(550 * b <= 35 * 2_000_000);
        // Large scenes: the adapter's budget, never more.
        assert_eq!(batch_for(16 * budget, budget), budget);
        assert_eq!(batch_for(u64::MAX, budget), budget);
        // A budget below the floor (tests set tiny ones) is kept.
        assert_eq!(batch_for(1_000_000, 5), 5);
    }

    #[test]
    fn line_parts_cover_every_segment_once_within_the_part_size() {
        for (n, per) in [
            (1, 5),
            (2, 2),
            (7, 3),
            (1240, 100),
            (100, 100),
            (101, 100),
            (5, 1000),
        ] {
            let b = super::line_parts(n, per);
            assert_eq!((b[0], *b.last().unwrap()), (0, n), "{n} {per}: {b:?}");
            for w in b.windows(2) {
                // Points [lo, min(hi + 1, n)): at most `per`, at least one.
                let len = (w[1] + 1).min(n) - w[0];
                assert!(w[0] < w[1] && len <= per.max(2), "{n} {per}: {b:?}");
            }
            // A segment s (points s, s + 1) lies in exactly one part, whole.
            for s in 0..n {
                let k: Vec<usize> = (0..b.len() - 1)
                    .filter(|&k| b[k] <= s && s < b[k + 1])
                    .collect();
                assert_eq!(k.len(), 1, "{n} {per}: point {s}");
                if s + 1 < n {
                    assert!(
                        s + 1 < (b[k[0] + 1] + 1).min(n),
                        "{n} {per}: segment {s} cut"
                    );
                }
            }
        }
        assert_eq!(super::line_parts(1240, 100).len() - 1, 13);
    }

    #[test]
    fn the_uniforms_match_their_wgsl_structs() {
        crate::prelude::assert_layout!(
            super::SHADER,
            "LineParams",
            super::LineParams {
                half_width,
                world,
                cylinder,
                p11,
                viewport,
                perspective,
                min_w,
                proxy_radius,
                trail,
                now,
                back,
                forward,
                start,
                min_width,
                points,
                halo,
                halo_outline,
                halo_width,
                halo_depth,
                displacement,
                depth_cue,
                near,
                far,
                taper_t,
                filter_on,
                filter_min,
                filter_taper,
            }
        );
        crate::prelude::assert_layout!(
            super::SHADER,
            "Params",
            super::GBufferParams {
                view_proj_rel,
                offset,
                forward,
                eye,
                clip,
                n_clip,
                width_code,
                opacity,
                pad2,
            }
        );
    }
}
