//! The frame: the passes of Schott et al.'s combined volume and tube occlusion in order -
//! G-buffer (raster), light volume (compute, one dispatch per step; volumetric occlusion),
//! march (compute; eye buffer, partial occlusion),
//! vicinity occlusion, compositing and FXAA (compute) - with per-pass timings.
//!
//! Data flows one way: the model (a volume with its transfer function, tube meshes) and the
//! view come in; an image and its AOVs come out. Which passes a frame runs comes from the
//! method's row of [`crate::method::METHODS`]: its volume shading picks the `light`/`march`
//! variants, and each of its surface terms writes one layer of the frame's surface terms
//! (partial occlusion from `march`, the surface-AO slot from its pass), which composite folds
//! by min or product without knowing who wrote them.
//!
//! Timings: `total_ms` is the median over frames of one frame's record-to-completion time
//! (everything recorded in one command buffer, then waited for; on a CPU adapter the G-buffer
//! submits draws of more than `gpu::CPU_BATCH_TRIANGLES` triangles in batches, each waited
//! for, which bounds lavapipe's memory). Per-pass times, when asked
//! for, come from one more frame: GPU timestamps written between its passes where the adapter
//! can and is not a CPU adapter (`PassClock::Timestamps`; see `Gpu::has_pass_timestamps`),
//! else each pass submitted and waited for on its own (`PassClock::Fences`, which adds a
//! submission's overhead to each).

use crate::composite::{CompositePass, CompositeSettings};
use crate::fxaa::FxaaPass;
use crate::gbuffer::{GBuffer, GpuLines, GpuMesh};
use crate::gpu::{Gpu, GpuError};
use crate::iso_pass::{GpuIso, IsoInput, IsoPass};
use crate::method::{LineAoShading, VolumeShading, MAX_TERMS};
use crate::planes::{GpuPlane, PlaneGrid, PlaneInput};
use crate::slice_pass::{GpuVolume, SlicePass, SliceSettings, VolumeInput};
use crate::terms::{surface_ao, TermInputs, TermPass};
use occlusion::camera::Camera;
use occlusion::emission_absorption::EaView;
use std::collections::BTreeMap;
use std::time::Instant;
use tubes::lines::LineSet;
use tubes::tube_mesh::TubeMesh;

pub use crate::method::Settings;

/// Per-pixel occlusion and depth outputs.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Aov {
    pub volumetric: f32,
    pub partial: f32,
    pub vicinity: f32,
    pub combined: f32,
    /// Linear view depth; 0 where nothing is.
    pub depth: f32,
}

/// The median of `values` (the mean of the two middle ones for an even count; NaN for
/// none): what `total_ms` and the per-pass figures report over frames.
pub fn median(values: &[f64]) -> f64 {
    let mut s = values.to_vec();
    s.sort_by(f64::total_cmp);
    match s.len() {
        0 => f64::NAN,
        n if n % 2 == 1 => s[n / 2],
        n => 0.5 * (s[n / 2 - 1] + s[n / 2]),
    }
}

/// What the passes took.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct Timings {
    /// Median submit-to-completion time of one frame.
    pub total_ms: f64,
    /// Each frame's time, in order.
    pub frames_ms: Vec<f64>,
    /// Per pass, ms (empty unless asked for): see `pass_clock`.
    pub passes: BTreeMap<String, f64>,
    /// How `passes` was measured.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub pass_clock: Option<PassClock>,
}

/// How per-pass times are measured.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum PassClock {
    /// GPU timestamps written between the passes of one more whole frame (one submission).
    Timestamps,
    /// Each pass submitted alone and waited for (includes a submission's overhead each), where
    /// the adapter has no timestamps between passes.
    Fences,
}

/// One more whole frame with a GPU timestamp before each pass and after the last; each pass's
/// time is the difference of its two, ms.
fn timestamped(gpu: &Gpu, passes: &[Recorder<'_>]) -> Result<BTreeMap<String, f64>, GpuError> {
    let n = passes.len() as u32 + 1;
    let set = gpu.device.create_query_set(&wgpu::QuerySetDescriptor {
        label: Some("pass timestamps"),
        ty: wgpu::QueryType::Timestamp,
        count: n,
    });
    let bytes = n as u64 * wgpu::QUERY_SIZE as u64;
    let resolve = gpu.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("pass timestamps resolve"),
        size: bytes,
        usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
        mapped_at_creation: false,
    });
    let (_, readback) = gpu.output_buffers("pass timestamps", bytes);
    let mut enc = gpu.device.create_command_encoder(&Default::default());
    for (i, (_, p)) in passes.iter().enumerate() {
        enc.write_timestamp(&set, i as u32);
        p(&mut enc);
    }
    enc.write_timestamp(&set, n - 1);
    enc.resolve_query_set(&set, 0..n, &resolve, 0);
    enc.copy_buffer_to_buffer(&resolve, 0, &readback, 0, bytes);
    gpu.queue.submit([enc.finish()]);
    let ticks: Vec<u64> = gpu
        .read_buffer(&readback)?
        .chunks_exact(8)
        .map(|c| u64::from_le_bytes(c.try_into().unwrap()))
        .collect();
    let ns = gpu.queue.get_timestamp_period() as f64;
    Ok(passes
        .iter()
        .enumerate()
        .map(|(i, (name, _))| {
            let d = ticks[i + 1].saturating_sub(ticks[i]) as f64 * ns * 1e-6;
            (name.to_string(), d)
        })
        .collect())
}

/// A rendered frame: linear RGBA (alpha: coverage) and AOVs, rows top to bottom.
pub struct Output {
    /// What the caller should know (e.g. a lowered MSAA count).
    pub notes: Vec<String>,
    pub image: Vec<[f32; 4]>,
    pub aov: Vec<Aov>,
    /// Each surface term the frame folded, by name (`partial`, `vicinity`), with its layer
    /// (the value composite used; 1 where no tube surface is nearest).
    pub terms: Vec<(&'static str, Vec<f32>)>,
    /// The terms' further channels by their full AOV name (`occlusion.lineao.v`, ...), only for
    /// the terms the frame ran.
    pub term_channels: Vec<(String, Vec<f32>)>,
    pub timings: Timings,
    pub triangles: u64,
    /// The occlusion buffer's grid where the frame swept one (`dos`, `combined`).
    pub light: Option<LightGrid>,
}

/// The light volume a frame swept: its cells and steps as chosen by
/// `occlusion::combined::light_grid` and `light_step` (or the scene's
/// `render.occlusion_cell` and `render.occlusion_step`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub struct LightGrid {
    /// A cell's edge in pixels.
    pub cell: u32,
    /// Eye slices per step (the light blurred once a step).
    pub step: u32,
    /// Volume samples per step, a voxel apart, and the light stored at each
    /// (`occlusion::combined::light_samples`).
    pub samples: u32,
    /// Cells per image axis.
    pub cells: [u32; 2],
    /// Steps of the sweep.
    pub steps: u32,
}

/// `light 128 x 128 cells of 2 px in 82 steps of 8 slices, 4 samples a step` (the render
/// summary's and the viewer's words).
impl std::fmt::Display for LightGrid {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "light {} x {} cells of {} px in {} steps of {} slice{}, {} sample{} a step",
            self.cells[0],
            self.cells[1],
            self.cell,
            self.steps,
            self.step,
            if self.step == 1 { "" } else { "s" },
            self.samples,
            if self.samples == 1 { "" } else { "s" }
        )
    }
}

impl LightGrid {
    /// The grid of a light volume on cells of `cell` pixels in steps of `step` slices of view
    /// `v` (`occlusion::combined::light_grid` chooses both).
    pub fn new(v: &occlusion::emission_absorption::EaView, cell: u32, step: u32) -> LightGrid {
        let (cell, step) = (cell.max(1), step.max(1));
        LightGrid {
            cell,
            step,
            samples: occlusion::combined::light_samples(v, step),
            cells: [v.width.div_ceil(cell), v.height.div_ceil(cell)],
            steps: v.slices.div_ceil(step),
        }
    }

    /// The slices the light volume stores (`samples` a step).
    pub fn stored(&self) -> u32 {
        self.steps * self.samples
    }

    /// The light volume's size in bytes (f32 values).
    pub fn bytes(&self) -> u64 {
        self.cells[0] as u64 * self.cells[1] as u64 * self.stored() as u64 * 4
    }

    /// The light volume within `limit` bytes (a storage binding), or why not (naming the
    /// scene key to change).
    pub fn fits(&self, limit: u64) -> Result<(), String> {
        if self.bytes() <= limit {
            return Ok(());
        }
        Err(format!(
            "scene key render.occlusion_cell: the light volume ({} x {} cells x {} slices, {} \
             MiB) exceeds the adapter's storage binding limit ({} MiB); raise \
             render.occlusion_cell or lower the slice count",
            self.cells[0],
            self.cells[1],
            self.stored(),
            self.bytes() >> 20,
            limit >> 20
        ))
    }
}

impl Output {
    /// The AOV channels by name, in order: `occlusion.volumetric`, `occlusion.<term>` for every
    /// surface term of [`crate::method::TERM_NAMES`] (the frame's layer where its method ran
    /// the term, else 1), the channels of the terms the frame ran (`occlusion.lineao.v`,
    /// `.g_depth`, `.g_light` where LineAO ran), `occlusion.combined`, `Z` (linear depth).
    pub fn aov_channels(&self) -> Vec<(String, Vec<f32>)> {
        let mut c = vec![(
            "occlusion.volumetric".to_string(),
            self.aov.iter().map(|a| a.volumetric).collect(),
        )];
        for name in crate::method::TERM_NAMES {
            let layer = self
                .terms
                .iter()
                .find(|(t, _)| t == name)
                .map(|(_, v)| v.clone())
                .unwrap_or_else(|| vec![1.0; self.aov.len()]);
            c.push((format!("occlusion.{name}"), layer));
        }
        c.extend(self.term_channels.iter().cloned());
        c.push((
            "occlusion.combined".into(),
            self.aov.iter().map(|a| a.combined).collect(),
        ));
        c.push(("Z".into(), self.aov.iter().map(|a| a.depth).collect()));
        c
    }
}

/// A pass's recording into a command encoder, with its name.
type Recorder<'a> = (&'static str, Box<dyn Fn(&mut wgpu::CommandEncoder) + 'a>);

struct Frame {
    iso: IsoPass,
    gbuf: GBuffer,
    slices: SlicePass,
    /// The passes of the surface terms that have one, with their names.
    term_passes: Vec<(&'static str, Box<dyn TermPass>)>,
    /// The names of the frame's surface-term layers, in layer order.
    layer_names: Vec<&'static str>,
    terms: wgpu::Buffer,
    composite: CompositePass,
    fxaa: Option<FxaaPass>,
    size: (u32, u32),
}

impl Frame {
    fn passes(&self) -> Vec<Recorder<'_>> {
        let mut p: Vec<Recorder<'_>> = vec![("gbuffer", Box::new(|e| self.gbuf.record(e)))];
        if self.slices.has_light() {
            p.push(("light", Box::new(|e| self.slices.record_light(e))));
        }
        p.push(("march", Box::new(|e| self.slices.record_march(e))));
        if self.iso.active() {
            p.push(("iso", Box::new(|e| self.iso.record(e))));
        }
        for (name, t) in &self.term_passes {
            p.push((name, Box::new(move |e| t.record(e))));
        }
        p.push(("composite", Box::new(|e| self.composite.record(e))));
        if let Some(f) = &self.fxaa {
            p.push(("fxaa", Box::new(move |e| f.record(e))));
        }
        p
    }

    fn final_image(&self) -> &wgpu::Buffer {
        self.fxaa
            .as_ref()
            .map(|f| &f.output)
            .unwrap_or(&self.composite.image)
    }
}

fn submit_and_wait(gpu: &Gpu, record: &dyn Fn(&mut wgpu::CommandEncoder)) -> Result<f64, GpuError> {
    let mut enc = gpu.device.create_command_encoder(&Default::default());
    // The clock starts before recording: on a CPU adapter the G-buffer submits large draws in
    // batches while it records (`gbuffer::batches`).
    let t = Instant::now();
    record(&mut enc);
    gpu.queue.submit([enc.finish()]);
    gpu.wait()?;
    Ok(t.elapsed().as_secs_f64() * 1e3)
}

/// A scene on the GPU: the volume (samples, transfer function, brick occupancy), the tube
/// meshes and the isosurface's fields, uploaded once by [`Renderer::upload`] and drawn by
/// every [`Renderer::draw`].
pub struct GpuScene {
    volume: Option<GpuVolume>,
    meshes: Vec<GpuMesh>,
    /// Slices of volumes ([`Renderer::upload_planes`]).
    planes: Vec<GpuPlane>,
    /// The slices' grid's fields as uploaded, by field index ([`Renderer::replace_planes`]
    /// takes them again).
    plane_fields: Vec<Option<wgpu::Buffer>>,
    /// An overlay blended into the volume ([`Renderer::upload_planes`]).
    blend: Option<crate::slice_pass::GpuBlend>,
    lines: Vec<GpuLines>,
    /// Line sets uploaded (a set without segments has no part in `lines`).
    line_sets: usize,
    iso: Option<GpuIso>,
}

/// About the GPU memory of a tube mesh: positions, normals and colours per vertex (12 + 12 + 4
/// bytes), 4 bytes an index.
fn mesh_bytes(m: &TubeMesh) -> u64 {
    m.positions.len() as u64 * 28 + m.indices.len() as u64 * 4
}

/// About the GPU memory of a line set: 20 bytes a point (position, colour, times and the
/// taper/filter pair where set are less or more), 4 a segment.
fn line_bytes(l: &LineSet) -> u64 {
    l.positions.len() as u64 * 20 + l.segments.len() as u64 * 4
}

impl GpuScene {
    /// Triangles drawn per G-buffer pass (two per line segment).
    pub fn triangles(&self) -> u64 {
        self.meshes
            .iter()
            .chain(self.planes.iter().map(|p| &p.mesh))
            .map(GpuMesh::triangles)
            .sum::<u64>()
            + self.lines.iter().map(|l| 2 * l.segments()).sum::<u64>()
    }

    /// Line sets' parts on the GPU (a set larger than a storage binding is cut into several,
    /// `gbuffer::line_parts`).
    pub fn line_parts(&self) -> usize {
        self.lines.len()
    }
}

/// What a draw measures besides the image.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DrawOptions {
    /// Whole frames rendered (at least 1), every pass re-run in each; `total_ms` is their
    /// median.
    pub frames: u32,
    /// Time each pass alone once more (submitted and waited for on its own).
    pub pass_timings: bool,
}

impl Default for DrawOptions {
    fn default() -> Self {
        DrawOptions {
            frames: 1,
            pass_timings: false,
        }
    }
}

/// The long-lived renderer (re_renderer's split): pipelines are compiled once per device and
/// variant (the GPU context's pool), a scene is uploaded once ([`Renderer::upload`]), and
/// [`Renderer::draw`] records one frame of it for a view and settings, reusing the frame's
/// buffers and targets while the image size stays the same. A new camera, clipping planes or
/// settings re-run the passes only; nothing is compiled or uploaded again.
pub struct Renderer<'g> {
    gpu: &'g Gpu,
}

impl<'g> Renderer<'g> {
    pub fn new(gpu: &'g Gpu) -> Renderer<'g> {
        Renderer { gpu }
    }

    pub fn gpu(&self) -> &'g Gpu {
        self.gpu
    }

    /// Uploads a volume (as the slices read it), tube meshes, line sets and an isosurface.
    pub fn upload(
        &self,
        volume: Option<&VolumeInput>,
        meshes: &[TubeMesh],
        lines: &[LineSet],
        iso: Option<&IsoInput>,
    ) -> Result<GpuScene, GpuError> {
        let gpu = self.gpu;
        Ok(GpuScene {
            volume: volume
                .map(|v| {
                    gpu.allocating("the volume's samples", v.data.bytes() as u64, || {
                        GpuVolume::upload(gpu, v)
                    })
                })
                .transpose()?,
            meshes: meshes
                .iter()
                .enumerate()
                .filter_map(|(i, m)| {
                    gpu.allocating(&format!("tube mesh {i}"), mesh_bytes(m), || {
                        GpuMesh::upload(gpu, m)
                    })
                    .map(|g| {
                        g.map(|mut g| {
                            g.source = i;
                            g
                        })
                    })
                    .transpose()
                })
                .collect::<Result<_, _>>()?,
            lines: lines
                .iter()
                .enumerate()
                .map(|(i, l)| {
                    gpu.allocating(&format!("line set {i}"), line_bytes(l), || {
                        GpuLines::upload(gpu, l)
                    })
                })
                .collect::<Result<Vec<_>, _>>()?
                .into_iter()
                .enumerate()
                .flat_map(|(i, parts)| {
                    parts.into_iter().map(move |mut p| {
                        p.source = i;
                        p
                    })
                })
                .collect(),
            line_sets: lines.len(),
            iso: iso.map(|i| GpuIso::upload(gpu, i)),
            planes: vec![],
            plane_fields: vec![],
            blend: None,
        })
    }

    /// A scene drawing `base`'s volume, slices, overlay and isosurface and a share of its
    /// geometry, all shared with it on the GPU: per tube mesh the triangles `indices[i]`
    /// (into mesh `i`'s vertices), per line set the segments `segments[i]` (first points in
    /// set `i`, in point order). Only those lists are uploaded: a viewer's draft with a share
    /// of the geometry. An error when `base` has a mesh or set the lists do not cover.
    pub fn upload_shares(
        &self,
        base: &GpuScene,
        indices: &[Vec<u32>],
        segments: &[Vec<u32>],
    ) -> Result<GpuScene, GpuError> {
        let missing = |what: &str, i: usize| {
            GpuError::Operation(format!(
                "a share of the geometry has no list for {what} {i}"
            ))
        };
        let mut meshes = vec![];
        for m in &base.meshes {
            let ix = indices
                .get(m.source)
                .ok_or_else(|| missing("mesh", m.source))?;
            meshes.extend(m.with_indices(self.gpu, ix)?);
        }
        let mut lines = vec![];
        for l in &base.lines {
            let sg = segments
                .get(l.source)
                .ok_or_else(|| missing("line set", l.source))?;
            lines.extend(l.with_segments(self.gpu, sg)?);
        }
        Ok(GpuScene {
            volume: base.volume.clone(),
            meshes,
            planes: base.planes.clone(),
            plane_fields: base.plane_fields.clone(),
            blend: base.blend.clone(),
            lines,
            line_sets: base.line_sets,
            iso: base.iso.clone(),
        })
    }

    /// Adds line sets to an uploaded scene, freeing each set's per-point data as its parts go
    /// up ([`GpuLines::upload_freeing`]): for one-shot renders of tractograms too large to
    /// hold twice. The sets keep their settings, no points.
    pub fn upload_lines_freeing(
        &self,
        scene: &mut GpuScene,
        lines: &mut [LineSet],
    ) -> Result<(), GpuError> {
        for l in lines.iter_mut() {
            let source = scene.line_sets;
            let parts =
                self.gpu
                    .allocating(&format!("line set {source}"), line_bytes(l), || {
                        GpuLines::upload_freeing(self.gpu, l)
                    })?;
            scene.lines.extend(parts.into_iter().map(|mut p| {
                p.source = source;
                p
            }));
            scene.line_sets += 1;
        }
        Ok(())
    }

    /// Adds slices of volumes to an uploaded scene (replacing any it had): their polygons and
    /// the fields of `grid` their layers read, each field uploaded once.
    /// `blend`: a layer of `grid` blended into the volume rendering's colours.
    pub fn upload_planes(
        &self,
        scene: &mut GpuScene,
        grid: &PlaneGrid,
        planes: &[PlaneInput],
        blend: Option<&crate::planes::PlaneLayer>,
    ) -> Result<(), GpuError> {
        let mut fields = vec![];
        scene.planes = GpuPlane::upload_all(self.gpu, grid, planes, &mut fields)?;
        scene.plane_fields = fields;
        scene.blend = blend
            .map(|b| crate::slice_pass::GpuBlend::upload(self.gpu, grid, b))
            .transpose()?;
        Ok(())
    }

    /// Replaces an uploaded scene's slices with `planes` on the grid given to the last
    /// [`Renderer::upload_planes`] (the same `grid`, fields unchanged: a viewer moving,
    /// hiding or restyling slices). The fields already on the GPU are used again; only the
    /// polygons, tables and any field no slice showed before are uploaded. The overlay
    /// blended into the volume stays.
    pub fn replace_planes(
        &self,
        scene: &mut GpuScene,
        grid: &PlaneGrid,
        planes: &[PlaneInput],
    ) -> Result<(), GpuError> {
        let mut fields = scene.plane_fields.clone();
        scene.planes = GpuPlane::upload_all(self.gpu, grid, planes, &mut fields)?;
        scene.plane_fields = fields;
        Ok(())
    }

    /// Gives an uploaded scene's volume a new transfer function (`volume` is the volume as
    /// uploaded, with the new function): the samples stay on the GPU, only the function and
    /// the brick occupancy are uploaded. Does nothing for a scene without a volume; an error
    /// when `volume` is not the grid that was uploaded.
    pub fn set_transfer(&self, scene: &mut GpuScene, volume: &VolumeInput) -> Result<(), GpuError> {
        match scene.volume.as_mut() {
            Some(v) => v.set_transfer(self.gpu, volume),
            None => Ok(()),
        }
    }

    /// Renders `scene` seen through `view` (whose clipping planes cut the volume; `tube_clip`
    /// cuts the tubes) with settings `s`, and reads the last frame back.
    pub fn draw(
        &self,
        scene: &GpuScene,
        view: &EaView,
        tube_clip: &[([f64; 3], f64)],
        s: &Settings,
        opts: DrawOptions,
    ) -> Result<Output, GpuError> {
        let gpu = self.gpu;
        let (w, h) = (view.width, view.height);
        check_size(gpu, w, h)?;
        let scope = gpu.device.push_error_scope(wgpu::ErrorFilter::Validation);
        let oom = gpu.device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
        let (frame, msaa_note) = Frame::new(gpu, scene, view, tube_clip, s)?;
        let passes = frame.passes();
        let whole = |enc: &mut wgpu::CommandEncoder| {
            for (_, p) in &passes {
                p(enc);
            }
        };
        let mut frames_ms = Vec::new();
        for _ in 0..opts.frames.max(1) {
            frames_ms.push(submit_and_wait(gpu, &whole)?);
        }
        let mut per_pass = BTreeMap::new();
        let mut pass_clock = None;
        if opts.pass_timings {
            if gpu.has_pass_timestamps() {
                per_pass = timestamped(gpu, &passes)?;
                pass_clock = Some(PassClock::Timestamps);
            } else {
                for (name, p) in &passes {
                    per_pass.insert(name.to_string(), submit_and_wait(gpu, p.as_ref())?);
                }
                pass_clock = Some(PassClock::Fences);
            }
        }
        if let Some(e) = pollster::block_on(oom.pop()) {
            return Err(GpuError::Operation(format!(
                "the GPU ran out of memory rendering {w} x {h}: {e}"
            )));
        }
        if let Some(e) = pollster::block_on(scope.pop()) {
            return Err(GpuError::Operation(format!(
                "validation error in a render pass: {e}"
            )));
        }
        let (image, aov, terms, term_channels) = frame.read_back(gpu)?;
        Ok(Output {
            notes: msaa_note.into_iter().collect(),
            image,
            aov,
            terms,
            term_channels,
            timings: Timings {
                total_ms: median(&frames_ms),
                frames_ms,
                passes: per_pass,
                pass_clock,
            },
            triangles: frame.gbuf.triangles(),
            light: frame.slices.light_grid(),
        })
    }
}

/// Refuses image sizes the adapter cannot hold.
fn check_size(gpu: &Gpu, w: u32, h: u32) -> Result<(), GpuError> {
    if w == 0 || h == 0 {
        return Err(GpuError::Operation(format!(
            "the viewport is {w} x {h}; width and height must be positive"
        )));
    }
    let limits = gpu.device.limits();
    let lim = limits.max_texture_dimension_2d;
    if w > lim || h > lim {
        return Err(GpuError::Operation(format!(
            "render.width x render.height = {w} x {h} exceeds this adapter's largest 2-D texture ({lim})"
        )));
    }
    // The largest per-pixel buffers hold 32 bytes a pixel (slice state, AOVs).
    let bytes = w as u64 * h as u64 * 32;
    let most = limits
        .max_storage_buffer_binding_size
        .min(limits.max_buffer_size);
    if bytes > most {
        return Err(GpuError::Operation(format!(
            "render.width x render.height = {w} x {h} needs {} MB buffers; this adapter binds at most {} MB",
            bytes >> 20,
            most >> 20
        )));
    }
    Ok(())
}

impl Frame {
    /// One frame's passes for a scene, a view and settings (their uniforms and bind groups;
    /// pipelines, targets and scratch buffers come from the pool), and a note when the MSAA
    /// count was lowered.
    fn new(
        gpu: &Gpu,
        scene: &GpuScene,
        view: &EaView,
        tube_clip: &[([f64; 3], f64)],
        s: &Settings,
    ) -> Result<(Frame, Option<String>), GpuError> {
        let (w, h) = (view.width, view.height);
        // Tubes, lines or planes cast light: a step a slice by default, and the march reads
        // the light's parts, which hold their coverage.
        let geometry_light =
            !(scene.meshes.is_empty() && scene.lines.is_empty() && scene.planes.is_empty());
        // Nothing in the scene but an isosurface (its ambient term swept, `iso_pass`): every
        // method's volume pass draws it as `ea`'s does - the same image - without the light
        // pass, which `combined` and `dos` ran over an empty medium (563-649 of 761-861 ms a
        // frame for `docs/images/bench/iso_embryo_cut.toml` at 256^2 on lavapipe).
        let iso_only = scene.volume.is_none() && !geometry_light && scene.iso.is_some();
        let desc = match iso_only {
            true => crate::method::Method::Ea.desc(),
            false => s.method.desc(),
        };
        // Nothing in the light - no volume or isosurface, no tubes or slice planes, no lines
        // standing for tubes (`proxy_radius`; other lines cast no shadow): it is 1 everywhere,
        // so its sweep is skipped and the partial occlusion is 1, as the sweep gave (a
        // lines-only scene with `dos` or `combined`: 1.3-1.5 of 6.3 s a frame for CST_L at
        // 256^2 on lavapipe, the image the same; docs/benchmarks.md).
        // Slice planes have no inside: they cast only the paper's column (`column`), not
        // under the default rule (a slab inside a surface), so slices alone sweep none either
        // (the MNI T1's slices with `combined`: the image `vicinity` draws, 2-37x the time).
        let casts = scene.volume.is_some()
            || scene.iso.is_some()
            || !scene.meshes.is_empty()
            || (!scene.planes.is_empty() && s.column)
            || scene.lines.iter().any(|l| l.casts_light());
        let occlusion = desc.volume == VolumeShading::Occlusion && casts;
        let cam: &Camera = &view.camera;
        let (samples, msaa_note) = crate::gbuffer::sample_count(gpu, s.msaa);
        let layers = crate::terms::layers(s.method, s.surface_ao);
        let layer_names: Vec<&'static str> = layers.iter().map(|(n, _)| *n).collect();
        let needs_nd = layers
            .iter()
            .any(|(_, c)| c.is_some_and(|c| surface_ao(c).needs_nd));
        let nd_guard = needs_nd.then(|| {
            let mut widths = crate::line_ao::Widths::default();
            for l in &scene.lines {
                match l.width() {
                    tubes::lines::LineWidth::Pixels(p) => {
                        widths.pixels = widths.pixels.max(p as f32)
                    }
                    tubes::lines::LineWidth::World(x) => widths.world = widths.world.max(x as f32),
                }
            }
            for m in &scene.meshes {
                widths.world = widths.world.max(m.diameter());
            }
            crate::line_ao::guard_pixels(cam, h, widths, &s.lineao.kernel, s.lineao.guard)
        });
        let mut gbuf = GBuffer::new(
            gpu,
            cam,
            w,
            h,
            &scene.meshes,
            &scene.planes,
            &scene.lines,
            tube_clip,
            samples,
            nd_guard,
            s.trail_now,
            s.translucent_layers,
        );
        if !occlusion {
            gbuf.without_back();
        }
        let layer = |name: &str| {
            layer_names
                .iter()
                .position(|n| *n == name)
                .map(|i| i as u32)
        };
        let n = w as u64 * h as u64;
        let terms = gpu.scratch(
            "surface terms",
            n * 4 * MAX_TERMS as u64,
            wgpu::BufferUsages::COPY_SRC,
        );
        let slices = SlicePass::new(
            gpu,
            scene.volume.as_ref(),
            view,
            &gbuf,
            &terms,
            &SliceSettings {
                occlusion,
                cell: s.occlusion_cell,
                // Tubes, lines and planes in the light keep a step a slice
                // (`occlusion::combined::light_step`); the pass resolves the volume's own.
                step: if geometry_light {
                    Some(s.occlusion_step.unwrap_or(1))
                } else {
                    s.occlusion_step
                },
                cone: s.cone,
                phong: desc.volume == VolumeShading::Phong,
                projection: match desc.volume {
                    VolumeShading::Projection(e) => Some(e),
                    _ => None,
                },
                column: s.column,
                theta_deg: s.theta_deg,
                blur_samples: s.blur_samples,
                geometry_extinction: s.geometry_extinction,
                light: s.light,
                partial_layer: layer("partial"),
                geometry_light,
            },
            scene.blend.as_ref(),
        )?;
        // The passes of the surface AO terms, from the term registry.
        let term_passes: Vec<(&'static str, Box<dyn TermPass>)> = layers
            .iter()
            .enumerate()
            .filter_map(|(l, (name, c))| Some((*name, surface_ao((*c)?).build?, l as u32)))
            .map(|(name, build, l)| {
                let inputs = TermInputs {
                    gpu,
                    camera: cam,
                    size: (w, h),
                    gbuf: &gbuf,
                    layer: crate::gpu::Layer {
                        terms: &terms,
                        index: l,
                    },
                    settings: s,
                };
                build(&inputs)
                    .map(|p| (name, p))
                    .map_err(|e| GpuError::Operation(format!("{name} settings: {e}")))
            })
            .collect::<Result<_, _>>()?;
        let paper_shading =
            layer_names.contains(&"lineao") && s.lineao.shading == LineAoShading::Paper;
        let iso_pass = IsoPass::new(gpu, cam, w, h, scene.iso.as_ref(), s.light, &view.clip);
        let composite = CompositePass::new(
            gpu,
            cam,
            w,
            h,
            &gbuf,
            &slices.eye,
            &slices.state,
            &terms,
            &iso_pass,
            &CompositeSettings {
                terms: layer_names.len() as u32,
                combine: s.combine,
                light: s.light,
                background: view.background,
                paper_shading,
                illustrative: (s.method == crate::method::Method::Illustrative)
                    .then_some(s.illustrative),
                // Nothing casts light: no march writes the partial term, which is 1.
                open_layer: layer("partial").filter(|_| !occlusion),
            },
        );
        let fxaa = s
            .fxaa
            .then(|| FxaaPass::new(gpu, w, h, &composite.image, &composite.aov));
        Ok((
            Frame {
                iso: iso_pass,
                gbuf,
                slices,
                term_passes,
                layer_names,
                terms,
                composite,
                fxaa,
                size: (w, h),
            },
            msaa_note,
        ))
    }

    /// Copies the final image, the AOVs and the surface terms' layers back to the host.
    #[allow(clippy::type_complexity)]
    fn read_back(
        &self,
        gpu: &Gpu,
    ) -> Result<
        (
            Vec<[f32; 4]>,
            Vec<Aov>,
            Vec<(&'static str, Vec<f32>)>,
            Vec<(String, Vec<f32>)>,
        ),
        GpuError,
    > {
        let n = self.size.0 as u64 * self.size.1 as u64;
        let readback = |label: &str, size: u64| {
            gpu.sized(format!("readback {label}"), size, || {
                gpu.output_buffers(label, size).1
            })
        };
        let layers = self.layer_names.len() as u64;
        let image_rb = readback("image", n * 16);
        let aov_rb = readback("aov", n * 16);
        let terms_rb = readback("surface terms", (n * 4 * layers).max(16));
        let mut enc = gpu.device.create_command_encoder(&Default::default());
        enc.copy_buffer_to_buffer(self.final_image(), 0, &image_rb, 0, n * 16);
        enc.copy_buffer_to_buffer(&self.composite.aov, 0, &aov_rb, 0, n * 16);
        if layers > 0 {
            enc.copy_buffer_to_buffer(&self.terms, 0, &terms_rb, 0, n * 4 * layers);
        }
        let channels: Vec<(&str, &wgpu::Buffer, &[&str], wgpu::Buffer)> = self
            .term_passes
            .iter()
            .filter_map(|(name, p)| {
                let (buf, names) = p.channels()?;
                let bytes = n * 4 * names.len() as u64;
                let rb = readback(&format!("{name} channels"), bytes);
                enc.copy_buffer_to_buffer(buf, 0, &rb, 0, bytes);
                Some((*name, buf, names, rb))
            })
            .collect();
        gpu.queue.submit([enc.finish()]);
        let f32s = |b: Vec<u8>| -> Vec<f32> {
            b.chunks_exact(4)
                .map(|c| f32::from_le_bytes(c.try_into().unwrap()))
                .collect()
        };
        let img = f32s(gpu.read_buffer(&image_rb)?);
        let aov = f32s(gpu.read_buffer(&aov_rb)?);
        let all = f32s(gpu.read_buffer(&terms_rb)?);
        let mut term_channels = vec![];
        for (name, _, names, rb) in &channels {
            let v = f32s(gpu.read_buffer(rb)?);
            for (k, c) in names.iter().enumerate() {
                term_channels.push((
                    format!("occlusion.{name}.{c}"),
                    v[k * n as usize..(k + 1) * n as usize].to_vec(),
                ));
            }
        }
        let terms: Vec<(&'static str, Vec<f32>)> = self
            .layer_names
            .iter()
            .enumerate()
            .map(|(t, name)| (*name, all[t * n as usize..(t + 1) * n as usize].to_vec()))
            .collect();
        let layer = |name: &str, i: usize| {
            terms
                .iter()
                .find(|(t, _)| *t == name)
                .map_or(1.0, |(_, v)| v[i])
        };
        let aov = aov
            .chunks_exact(4)
            .enumerate()
            .map(|(i, c)| Aov {
                volumetric: c[0],
                partial: layer("partial", i),
                vicinity: layer("vicinity", i),
                combined: c[1],
                depth: c[2],
            })
            .collect();
        Ok((
            img.chunks_exact(4)
                .map(|c| [c[0], c[1], c[2], c[3]])
                .collect(),
            aov,
            terms,
            term_channels,
        ))
    }
}

/// Renders `frames` frames (at least 1) of the model seen through `view` (whose clipping
/// planes cut the volume; `tube_clip` cuts the tubes), with the isosurface `iso` when given,
/// and reads the last one back: [`Renderer::upload`] then [`Renderer::draw`] with per-pass
/// timings.
#[allow(clippy::too_many_arguments)]
pub fn render(
    gpu: &Gpu,
    volume: Option<&VolumeInput>,
    meshes: &[TubeMesh],
    tube_clip: &[([f64; 3], f64)],
    iso: Option<&IsoInput>,
    view: &EaView,
    s: &Settings,
    frames: u32,
) -> Result<Output, GpuError> {
    let r = Renderer::new(gpu);
    let scene = r.upload(volume, meshes, &[], iso)?;
    r.draw(
        &scene,
        view,
        tube_clip,
        s,
        DrawOptions {
            frames,
            pass_timings: true,
        },
    )
}

#[cfg(test)]
mod tests {
    use super::median;

    /// The middle value, or the mean of the two middle ones (the upper one was reported for
    /// even counts: 51.35 for frames of 51.35 and 42.57 ms).
    #[test]
    fn the_median_of_an_even_count_is_the_mean_of_the_middle_two() {
        assert_eq!(median(&[51.35, 42.57]), 0.5 * (51.35 + 42.57));
        assert_eq!(median(&[30.9, 22.3, 21.4, 21.4]), 0.5 * (21.4 + 22.3));
        assert_eq!(median(&[3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(&[7.0]), 7.0);
        assert!(median(&[]).is_nan());
    }
}
