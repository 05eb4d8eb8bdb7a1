//! The render worker: a thread that owns the GPU and the uploaded scene, draws the latest
//! requested state of the scene and hands the image back, so that the window never waits for
//! a frame. Requests that arrive while a frame is drawn are coalesced: only the newest is drawn
//! next.

use engine::renderer::DrawOptions;
use scene::compile::{upload, Model};
use volume::samples::Samples;

use scene::spec::Scene;
use std::sync::mpsc::{channel, Receiver, Sender};

/// How much of the scene a frame draws: a draft while the user drags (a quarter of the
/// resolution, `ea`, at most [`DRAFT_SLICES`] slices, no MSAA or FXAA), the full scene when
/// the view rests.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Level {
    Draft,
    Full,
}

/// Slices a draft draws at most.
pub const DRAFT_SLICES: u32 = 128;

/// The time a draft aims at (ms): 10 frames a second with room for the window's own frame.
pub const DRAFT_TARGET_MS: f64 = 60.0;
/// The least a draft keeps of the geometry (triangles and segments) and of the slices.
pub const DRAFT_MIN_PRIMITIVES: usize = 10_000;
pub const DRAFT_MIN_SLICES: u32 = 32;

/// What a draft draws at most: triangles and segments (a share of the geometry above it), and
/// slices. It adapts to the drafts' times: a draft slower than 1.25 x [`DRAFT_TARGET_MS`]
/// scales both down by target / time (at most 4x, at least 1.25x at once), one faster than half
/// the target scales them up by 1.5, within [`DRAFT_MIN_PRIMITIVES`]..[`DRAFT_PRIMITIVES`] and
/// [`DRAFT_MIN_SLICES`]..[`DRAFT_SLICES`]; in between it stays (no oscillation).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DraftBudget {
    pub primitives: usize,
    pub slices: u32,
}

impl Default for DraftBudget {
    fn default() -> Self {
        DraftBudget {
            primitives: DRAFT_PRIMITIVES,
            slices: DRAFT_SLICES,
        }
    }
}

impl DraftBudget {
    /// The budget after a draft that took `ms`.
    pub fn adapt(&mut self, ms: f64) {
        if !(ms.is_finite() && ms > 0.0) {
            return;
        }
        let f = if ms > 1.25 * DRAFT_TARGET_MS {
            (DRAFT_TARGET_MS / ms).clamp(0.25, 0.8)
        } else if ms < 0.5 * DRAFT_TARGET_MS {
            1.5
        } else {
            return;
        };
        self.primitives =
            ((self.primitives as f64 * f) as usize).clamp(DRAFT_MIN_PRIMITIVES, DRAFT_PRIMITIVES);
        self.slices =
            ((self.slices as f64 * f).round() as u32).clamp(DRAFT_MIN_SLICES, DRAFT_SLICES);
    }
}

/// The scene a frame of `level` draws for scene state `s` (drafts at most [`DRAFT_SLICES`]).
pub fn at_level(s: &Scene, level: Level) -> Scene {
    at_level_with(s, level, DRAFT_SLICES)
}

/// [`at_level`] with drafts of at most `slices` slices.
pub fn at_level_with(s: &Scene, level: Level, slices: u32) -> Scene {
    let mut d = s.clone();
    if level == Level::Draft {
        d.render.width = (s.render.width / 4).max(16);
        d.render.height = (s.render.height / 4).max(16);
        d.render.method = engine::method::Method::Ea;
        d.render.slices = Some(s.render.slices.unwrap_or(slices).min(slices));
        d.render.slice_distance = None;
        d.render.msaa = 1;
        d.render.fxaa = false;
        d.render.stereo = scene::spec::Stereo::None;
    }
    d
}

/// A frame to draw, and where to write it (a screenshot: PNG, or EXR with `aov` the AOV
/// channels, as `umbra render` writes them).
pub struct Request {
    pub id: u64,
    pub scene: Scene,
    pub level: Level,
    pub save: Option<(std::path::PathBuf, bool)>,
    /// Time each pass of a full image (the renderer draws it a second time pass by pass, on
    /// adapters without timestamp queries); drafts never do.
    pub pass_timings: bool,
}

/// A drawn frame: 8-bit sRGB RGBA (rows top to bottom), what it took and what the renderer
/// noted.
pub struct Image {
    pub id: u64,
    pub level: Level,
    pub size: [usize; 2],
    pub rgba: Vec<u8>,
    /// Per pixel, the linear view depth of what it shows (the `Z` AOV; 0: nothing).
    pub depth: Vec<f32>,
    pub total_ms: f64,
    pub passes: Vec<(String, f64)>,
    /// The occlusion buffer's grid where the method swept one.
    pub light: Option<engine::renderer::LightGrid>,
    pub notes: Vec<String>,
    pub device: String,
    /// The screenshot the request asked for: its path, or why it was not written.
    pub saved: Option<Result<std::path::PathBuf, String>>,
    /// Set when the frame's model was built anew (the scene's objects changed).
    pub rebuilt: Option<Rebuilt>,
}

/// The renderer's side of the viewer: the GPU, the scene's model and its upload. A frame
/// whose scene has another `[volume.transfer]` than the uploaded one rebuilds the transfer
/// function over the data's range (as `scene::compile::model` does) and uploads again.
pub struct Session {
    gpu: &'static engine::gpu::Gpu,
    model: Model,
    up: scene::compile::Uploaded<'static>,
    /// The data's finite and robust ranges (those the presets' ramps span, by
    /// `volume.transfer.range`) and the uploaded function.
    range: [f64; 2],
    robust: [f64; 2],
    /// The editor's histograms of the volume's samples (1-D, and value x gradient), taken at
    /// the first rebuild of a volume.
    histograms: Option<(Vec<u64>, crate::transfer::Histogram2d)>,
    transfer: Option<scene::spec::TransferSpec>,
    /// The transfer function the model was made with: the slice distance a narrow feature
    /// asks for and the notes on the function's range come from it, so the full image of
    /// another function models the scene anew (drafts only upload the new function).
    modelled: Option<scene::spec::TransferSpec>,
    /// The scene's data as modelled: its objects, without the transfer function.
    data: DataKey,
    /// The slices as planned in the model and its upload.
    slices: Vec<scene::spec::SliceSpec>,
    /// The uploads drafts draw when the geometry is heavy ([`DRAFT_PRIMITIVES`]), by share
    /// (1 in k), the last used first; made at the first draft of a share after the model or
    /// its transfer function changed, the volume shared with the full upload's. The last
    /// [`DRAFT_SHARES_KEPT`] are kept, so a budget that moves between two shares uploads
    /// nothing.
    draft: Vec<(usize, scene::compile::Uploaded<'static>)>,
    /// What drafts draw, adapted to their times.
    budget: DraftBudget,
}

/// Triangles and line segments above which a draft draws a share of the geometry: every
/// k-th block of [`DRAFT_BLOCK`] triangles or segments, k chosen to keep about this many.
pub const DRAFT_PRIMITIVES: usize = 150_000;
/// Draft uploads kept (by share of the geometry).
pub const DRAFT_SHARES_KEPT: usize = 2;
/// Triangles (tubes) or segments (lines) per block a draft keeps or drops whole.
pub const DRAFT_BLOCK: usize = 256;

/// The geometry's primitives: tube triangles and line segments.
pub fn primitives(m: &Model) -> usize {
    m.meshes.iter().map(|t| t.triangles()).sum::<usize>()
        + m.lines.iter().map(|l| l.segments.len()).sum::<usize>()
}

/// The share of `heavy` primitives a draft with a budget of `budget` draws: 1 in `k`, `k` the
/// largest power of two that keeps at least the budget (a budget that moves re-uploads the
/// draft's geometry only when the share halves or doubles). Rounded up to a power of two, the
/// share fell below the budget and its floor: 133,760 triangles at the floor of 10,000 kept 1
/// in 16, 8,360.
pub fn draft_share(heavy: usize, budget: usize) -> usize {
    let k = (heavy / budget.max(1)).max(1);
    1 << (usize::BITS - 1 - k.leading_zeros())
}

/// Every `k`-th block of [`DRAFT_BLOCK`] items of `v` (in `chunk`-sized items).
fn every_kth_block<T: Clone>(v: &[T], chunk: usize, k: usize) -> Vec<T> {
    v.chunks(DRAFT_BLOCK * chunk)
        .step_by(k.max(1))
        .flatten()
        .cloned()
        .collect()
}

/// What a model is built from: the volume (but its transfer function) and the objects.
type DataKey = (
    Option<scene::spec::VolumeSpec>,
    Vec<scene::spec::TubesSpec>,
    Vec<scene::spec::LinesSpec>,
    Vec<scene::spec::PointsSpec>,
    Vec<([f64; 3], f64)>,
    bool,
    Vec<scene::spec::OverlaySpec>,
    Vec<scene::spec::SliceSpec>,
);

/// What the model is made from: the objects (the volume without its transfer function, which
/// is uploaded alone), the clipping planes an isosurface's octants are swept for, whether
/// the method projects (`mip`, `minip`: the volume's colours are then `volume.colormap` over
/// `volume.window`, and its slices a voxel apart, in the model), the overlays, and the slices
/// with a slab (which crops the geometry). Other changes of the slices only re-plan them
/// ([`scene::slices::PlaneModel::replan`]).
fn data_key(s: &Scene) -> DataKey {
    let volume = s.volume.clone().map(|mut v| {
        v.transfer = Default::default();
        v
    });
    // An isosurface's octant fields are swept for the scene's clipping planes
    // (`scene::compile::model`): another cut is another model.
    let iso = s.volume.as_ref().is_some_and(|v| v.iso.is_some());
    let clip = match iso {
        true => s.clip.iter().map(|c| (c.normal, c.offset)).collect(),
        false => vec![],
    };
    let projection = matches!(
        s.render.method,
        engine::method::Method::Mip | engine::method::Method::MinIp
    );
    (
        volume,
        s.tubes.clone(),
        s.lines.clone(),
        s.points.clone(),
        clip,
        projection,
        s.overlays.clone(),
        s.slices
            .iter()
            .filter(|c| c.slab.is_some())
            .cloned()
            .collect(),
    )
}

/// The transfer-function editor of model `m` over the data's finite `range`, for a volume it
/// draws (as a rebuilt model gives it: a volume the scene does not draw, `render = false`,
/// only the slices' grid, has none).
pub fn editor_of(m: &Model, range: [f64; 2]) -> Option<crate::transfer::Editor> {
    m.volume.is_some().then(|| {
        crate::transfer::Editor::new(range, histogram(m, range, 128))
            .with_robust(robust_range(m, range))
            .with_2d(histogram2d(m, range, 128, 64))
    })
}

/// The finite range of a model's volume samples (gaps excluded), `[0, 1]` without a volume.
pub fn data_range(m: &Model) -> [f64; 2] {
    let Some((_, data, _)) = &m.volume else {
        return [0.0, 1.0];
    };
    let (lo, hi) = data
        .values()
        .filter(|v| v.is_finite() && *v > -1e30)
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(v as f64), b.max(v as f64))
        });
    if lo <= hi {
        [lo, hi]
    } else {
        [0.0, 1.0]
    }
}

/// The robust range of a model's volume samples (gaps excluded; `volume.transfer.range =
/// "robust"`, as `scene::compile::model` takes it), `full` without a volume.
pub fn robust_range(m: &Model, full: [f64; 2]) -> [f64; 2] {
    let Some((_, data, _)) = &m.volume else {
        return full;
    };
    scene::compile::robust_range(data, full, |v| v.is_finite() && v > -1e30)
}

/// `bins` counts of the model's volume samples over `range` (gaps excluded): the histogram the
/// transfer-function editor draws.
pub fn histogram(m: &Model, range: [f64; 2], bins: usize) -> Vec<u64> {
    let mut h = vec![0u64; bins.max(1)];
    if let Some((_, data, _)) = &m.volume {
        let w = (range[1] - range[0]).max(1e-30);
        for v in data.values().filter(|v| v.is_finite() && *v > -1e30) {
            let i = (((v as f64 - range[0]) / w) * bins as f64) as usize;
            h[i.min(bins - 1)] += 1;
        }
    }
    h
}

/// Counts of the model's volume samples over value (`range`, `nv` bins) and gradient magnitude
/// (`[0, gmax]`, `ng` bins, larger magnitudes in the top bin): the histogram the value x
/// gradient editor draws. Gradients as the renderer takes them for 2-D transfer functions
/// (`occlusion::emission_absorption::gradient` at voxel centres: central differences one voxel
/// apart, one-sided and halved at the border, to world units by the transposed world-to-index
/// matrix), on every `s`-th voxel along each axis with `s` chosen to visit at most about 10^6;
/// voxels next to a gap are left out. `gmax` is the 99th percentile of the magnitudes (0 when
/// there is no volume or every gradient is 0).
pub fn histogram2d(
    m: &Model,
    range: [f64; 2],
    nv: usize,
    ng: usize,
) -> crate::transfer::Histogram2d {
    match &m.volume {
        Some((vol, data, _)) => value_gradient_histogram(vol.dims, vol.affine, data, range, nv, ng),
        None => value_gradient_histogram(
            [0; 3],
            glam::DMat4::IDENTITY,
            &Samples::f32(vec![]),
            range,
            nv,
            ng,
        ),
    }
}

/// [`histogram2d`] of samples `data` (x fastest) on a grid of `dims` with the index-to-world
/// matrix `affine`.
pub fn value_gradient_histogram(
    dims: [usize; 3],
    affine: glam::DMat4,
    data: &Samples,
    range: [f64; 2],
    nv: usize,
    ng: usize,
) -> crate::transfer::Histogram2d {
    let (nv, ng) = (nv.max(1), ng.max(1));
    let mut h = crate::transfer::Histogram2d {
        bins: [nv, ng],
        counts: vec![0; nv * ng],
        gmax: 0.0,
    };
    let [nx, ny, nz] = dims;
    let det = affine.determinant();
    if nx * ny * nz != data.len() || data.is_empty() || !(det.is_finite() && det != 0.0) {
        return h;
    }
    let jt = glam::DMat3::from_mat4(affine.inverse()).transpose();
    let n = (nx * ny * nz) as f64;
    let s = ((n / 1e6).cbrt().ceil() as usize).max(1);
    let at = |i: usize, j: usize, k: usize| data.get(i + nx * (j + ny * k)) as f64;
    let good = |v: f64| v.is_finite() && v > -1e30;
    let mut samples: Vec<(f32, f32)> = Vec::with_capacity((n / (s * s * s) as f64) as usize + 8);
    for k in (0..nz).step_by(s) {
        for j in (0..ny).step_by(s) {
            for i in (0..nx).step_by(s) {
                let v = at(i, j, k);
                let d = |a: [usize; 3], b: [usize; 3]| {
                    let (p, q) = (at(a[0], a[1], a[2]), at(b[0], b[1], b[2]));
                    (good(p) && good(q)).then_some(0.5 * (p - q))
                };
                let (Some(gx), Some(gy), Some(gz)) = (
                    d([(i + 1).min(nx - 1), j, k], [i.saturating_sub(1), j, k]),
                    d([i, (j + 1).min(ny - 1), k], [i, j.saturating_sub(1), k]),
                    d([i, j, (k + 1).min(nz - 1)], [i, j, k.saturating_sub(1)]),
                ) else {
                    continue;
                };
                if !good(v) {
                    continue;
                }
                let g = (jt * glam::DVec3::new(gx, gy, gz)).length();
                samples.push((v as f32, g as f32));
            }
        }
    }
    if samples.is_empty() {
        return h;
    }
    let mut mags: Vec<f32> = samples.iter().map(|s| s.1).collect();
    let q = ((mags.len() - 1) as f64 * 0.99) as usize;
    let gmax = *mags.select_nth_unstable_by(q, f32::total_cmp).1 as f64;
    h.gmax = gmax;
    let w = (range[1] - range[0]).max(1e-30);
    for (v, g) in samples {
        let iv = (((v as f64 - range[0]) / w * nv as f64).max(0.0) as usize).min(nv - 1);
        let ig = if gmax > 0.0 {
            ((g as f64 / gmax * ng as f64) as usize).min(ng - 1)
        } else {
            0
        };
        h.counts[iv + nv * ig] += 1;
    }
    h
}

impl Session {
    /// The GPU (kept for the life of the process: the viewer's one renderer) and the upload
    /// of model `m` of scene `s`.
    pub fn new(m: Model, s: &Scene) -> Result<Session, String> {
        let transfer = s.volume.as_ref().map(|v| v.transfer.clone());
        let gpu: &'static engine::gpu::Gpu = Box::leak(Box::new(
            engine::gpu::Gpu::new().map_err(|e| format!("no GPU adapter for the renderer: {e}"))?,
        ));
        let up = upload(gpu, &m)?;
        let range = data_range(&m);
        Ok(Session {
            gpu,
            range,
            robust: robust_range(&m, range),
            histograms: None,
            model: m,
            up,
            modelled: transfer.clone(),
            transfer,
            data: data_key(s),
            slices: s.slices.clone(),
            draft: vec![],
            budget: DraftBudget::default(),
        })
    }

    /// The model as drawn.
    pub fn model(&self) -> &Model {
        &self.model
    }

    /// Whether scene `s`'s transfer function models the scene as the one the model was made
    /// with: the same slice distance (a narrow feature shortens it) and the same kind of
    /// function and range (the range's note). Then its full image needs no new model (which
    /// reads every file again: seconds for heavy geometry).
    fn models_alike(&self, s: &Scene) -> bool {
        let (Some(spec), Some(was), Some((vol, data, _))) = (
            s.volume.as_ref().map(|v| &v.transfer),
            self.modelled.as_ref(),
            &self.model.volume,
        ) else {
            return false;
        };
        if spec.points.is_empty() != was.points.is_empty()
            || spec.range.is_full() != was.range.is_full()
        {
            return false;
        }
        if s.render.slices.is_some() || s.render.slice_distance.is_some() {
            return true;
        }
        let range = scene::compile::preset_range(spec, self.range, || self.robust);
        match scene::compile::transfer(spec, range) {
            Ok(t) => 2.0 * scene::compile::slice_distance(vol, data, &t).0 == self.model.spacing,
            // (The error is the frame's: the model anew reports it.)
            Err(_) => false,
        }
    }

    /// Draws the request (re-uploading for a new transfer function) into an [`Image`], and
    /// writes its screenshot: the same frame `umbra render` writes for that scene.
    /// The GPU the session draws on.
    pub fn gpu(&self) -> &'static engine::gpu::Gpu {
        self.gpu
    }

    pub fn frame(&mut self, req: &Request) -> Result<Image, String> {
        let tf = req.scene.volume.as_ref().map(|v| v.transfer.clone());
        let key = data_key(&req.scene);
        let mut rebuilt = None;
        // While a clipping plane is dragged, the drafts keep the isosurface's octants of the
        // cut before (sweeping them anew takes a load of the volume and a sweep); while a
        // slice with a slab is moved, they keep the geometry cropped to the slab before (the
        // slice itself moves: it is planned again below). The full image at rest is made for
        // its own cut and slabs, as `umbra render` draws it.
        let cut_only = key.0 == self.data.0
            && key.1 == self.data.1
            && key.2 == self.data.2
            && key.3 == self.data.3
            && key.5 == self.data.5
            && key.6 == self.data.6;
        let slices = req.scene.slices != self.slices;
        // Slices shown where the model has no grid of slices (none were drawn) need one.
        let no_grid = slices && self.model.planes.is_none();
        // A new transfer function at rest: the slices its features ask for and its notes
        // (a volume drawn by its function, not a projection's colours).
        let tf_modelled = req.level == Level::Draft
            || tf == self.modelled
            || self.model.volume.is_none()
            || self.data.5
            || self.models_alike(&req.scene);
        if tf_modelled && req.level == Level::Full {
            self.modelled = tf.clone();
        }
        if (key != self.data && !(cut_only && req.level == Level::Draft)) || no_grid || !tf_modelled
        {
            // Other objects (opened, removed, hidden, resized, recoloured): the model anew.
            // Both made before either is kept: a failed upload leaves model and upload as
            // they were, in step (drafts take lists from the one into the other's buffers).
            let model = scene::compile::model(&req.scene)?;
            let up = upload(self.gpu, &model)?;
            let same_volume = key.0 == self.data.0;
            self.model = model;
            self.up = up;
            // The same volume (only other objects changed): its ranges and histograms are
            // those already taken (a pass or two over its samples each).
            if !same_volume || self.histograms.is_none() {
                self.range = data_range(&self.model);
                self.robust = robust_range(&self.model, self.range);
                self.histograms = Some((
                    histogram(&self.model, self.range, 128),
                    histogram2d(&self.model, self.range, 128, 64),
                ));
            }
            let (histogram, histogram2d) = self.histograms.clone().unwrap_or_default();
            self.data = key;
            self.slices = req.scene.slices.clone();
            self.transfer = tf.clone();
            self.modelled = tf.clone();
            self.draft.clear();
            rebuilt = Some(Rebuilt {
                bounds: self.model.bounds,
                range: self.range,
                robust: self.robust,
                histogram,
                histogram2d,
                volume: self.model.volume.is_some(),
                slice_grid: crate::objects::SliceGrid::of(&self.model),
                ras: self.model.is_ras(),
            });
        }
        if req.scene.slices != self.slices {
            // Slices moved, hidden or restyled: planned anew on the model's grid, the rest of
            // the model and its upload kept (the drafts' shares are made again).
            if let Some(p) = self.model.planes.as_mut() {
                let (planes, notes) = p.replan(&req.scene)?;
                self.up.set_planes(p, &planes)?;
                p.planes = planes;
                // The slices' notes are the new plan's (an outlier note goes with a window).
                self.model
                    .notes
                    .retain(|n| !scene::slices::is_slice_note(n));
                self.model.notes.extend(notes);
                // A slice's colour bar follows its window.
                if let Some(i) = req
                    .scene
                    .annotate
                    .colorbar
                    .as_deref()
                    .and_then(|c| c.strip_prefix("slices."))
                    .and_then(|n| n.parse::<usize>().ok())
                {
                    self.model.colorbar = p.slice_bar(&req.scene, i);
                }
                self.slices = req.scene.slices.clone();
                self.draft.clear();
            }
        }
        // (A projection's colours do not come from the transfer function: see `data_key`.)
        if tf != self.transfer {
            if let (Some(spec), Some(vol), false) = (&tf, &mut self.model.volume, self.data.5) {
                let range = scene::compile::preset_range(spec, self.range, || self.robust);
                vol.2 =
                    scene::compile::transfer(spec, range).map_err(|e| format!("scene key {e}"))?;
                // The volume's colour bar shows the new function.
                if let Some(bar) = self
                    .model
                    .colorbar
                    .as_mut()
                    .filter(|_| req.scene.annotate.colorbar.as_deref() == Some("volume"))
                {
                    *bar = scene::compile::volume_bar(&bar.label, bar.map.clone(), range, &vol.2);
                }
                self.up = upload(self.gpu, &self.model)?;
                self.draft.clear();
            }
            self.transfer = tf;
        }
        let heavy = primitives(&self.model);
        let budget = self.budget;
        let k = draft_share(heavy, budget.primitives);
        if req.level == Level::Draft && k > 1 {
            if let Some(i) = self.draft.iter().position(|d| d.0 == k) {
                let d = self.draft.remove(i);
                self.draft.insert(0, d);
            } else {
                // A share of the model's geometry: its triangle and segment lists only, the
                // volume, vertices and points shared with the full upload on the GPU.
                let indices: Vec<Vec<u32>> = self
                    .model
                    .meshes
                    .iter()
                    .map(|t| every_kth_block(&t.indices, 3, k))
                    .collect();
                let segments: Vec<Vec<u32>> = self
                    .model
                    .lines
                    .iter()
                    .map(|l| every_kth_block(&l.segments, 1, k))
                    .collect();
                let up = self.up.with_shares(&indices, &segments)?;
                self.draft.insert(0, (k, up));
                self.draft.truncate(DRAFT_SHARES_KEPT);
            }
            let up = &self.draft[0].1;
            let mut img = draw_with(up, &self.model, req, budget.slices)?;
            img.rebuilt = rebuilt;
            img.notes.push(format!(
                "draft: 1 block of {DRAFT_BLOCK} triangles or segments in {k} of the geometry, \
                 at most {} slices",
                budget.slices
            ));
            self.budget.adapt(img.total_ms);
            return Ok(img);
        }
        let mut img = draw_with(&self.up, &self.model, req, budget.slices)?;
        img.rebuilt = rebuilt;
        if req.level == Level::Draft {
            self.budget.adapt(img.total_ms);
        }
        Ok(img)
    }
}

/// A model built anew for a frame: the scene's bounds, and its volume's range and histogram.
#[derive(Clone, Debug)]
pub struct Rebuilt {
    pub bounds: [glam::DVec3; 2],
    pub range: [f64; 2],
    pub robust: [f64; 2],
    pub histogram: Vec<u64>,
    pub histogram2d: crate::transfer::Histogram2d,
    pub volume: bool,
    /// The grid the slices cut (none without slices or overlays).
    pub slice_grid: Option<crate::objects::SliceGrid>,
    /// Whether the scene is in RAS+ (its volume says; tractograms and meshes alone are).
    pub ras: bool,
}

/// Draws `s` (the scene state, any level already applied) with the uploaded model into an
/// [`Image`]: the same frame `umbra render` writes as PNG for that scene.
pub fn draw(up: &scene::compile::Uploaded, m: &Model, req: &Request) -> Result<Image, String> {
    draw_with(up, m, req, DRAFT_SLICES)
}

/// [`draw`] with drafts of at most `slices` slices.
pub fn draw_with(
    up: &scene::compile::Uploaded,
    m: &Model,
    req: &Request,
    slices: u32,
) -> Result<Image, String> {
    let s = at_level_with(&req.scene, req.level, slices);
    let (mut out, v) = up.draw(
        &s,
        m,
        DrawOptions {
            frames: 1,
            // Timing each pass draws it again: full images only, when asked for.
            pass_timings: req.pass_timings && req.level == Level::Full,
        },
    )?;
    // The scene's title, labels and bars, as `umbra render` draws them: on the full image
    // (a draft's smaller image would lay them out larger and cut, then be scaled up).
    if req.level == Level::Full {
        scene::render::annotate_frame(&s, m, &mut out, &v)?;
    }
    let saved = req.save.as_ref().map(|(path, aov)| {
        let exr = path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("exr"));
        scene::render::write_image(path, exr, *aov && exr, s.render.bits, &out, &v)
            .map(|()| path.clone())
    });
    let rgba = out
        .image
        .iter()
        .flat_map(|p| {
            [
                scene::image_io::srgb8(p[0]),
                scene::image_io::srgb8(p[1]),
                scene::image_io::srgb8(p[2]),
                255,
            ]
        })
        .collect();
    Ok(Image {
        id: req.id,
        level: req.level,
        size: [s.render.width as usize, s.render.height as usize],
        rgba,
        depth: out.aov.iter().map(|a| a.depth).collect(),
        total_ms: out.timings.total_ms,
        passes: out.timings.passes.into_iter().collect(),
        light: out.light,
        // As `umbra render` reports them: the model's, the upload's, then the frame's.
        notes: {
            let mut notes: Vec<String> = vec![];
            for n in m.notes.iter().chain(&up.notes).chain(&out.notes) {
                if !notes.contains(n) {
                    notes.push(n.clone());
                }
            }
            notes
        },
        device: up.renderer.gpu().report().name,
        saved,
        rebuilt: None,
    })
}

/// The worker's ends: requests in, images (or an error naming what failed) out.
pub struct Worker {
    pub requests: Sender<Request>,
    /// Each drawn request's id with its image or error (id 0: the renderer could not start).
    pub images: Receiver<(u64, Result<Image, String>)>,
}

/// Starts the worker for model `m` of scene `s`; `wake` is called after each image (the window
/// repaints).
pub fn start(m: Model, s: &Scene, wake: impl Fn() + Send + 'static) -> Worker {
    let s = s.clone();
    let (req_tx, req_rx) = channel::<Request>();
    let (img_tx, img_rx) = channel();
    std::thread::Builder::new()
        .name("umbra render".into())
        .spawn(move || {
            let mut session = match Session::new(m, &s) {
                Ok(s) => s,
                Err(e) => {
                    let _ = img_tx.send((0, Err(e)));
                    wake();
                    return;
                }
            };
            while let Ok(mut req) = req_rx.recv() {
                while let Ok(newer) = req_rx.try_recv() {
                    req = newer;
                }
                if img_tx.send((req.id, session.frame(&req))).is_err() {
                    break;
                }
                wake();
            }
        })
        .expect("spawning the render thread");
    Worker {
        requests: req_tx,
        images: img_rx,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_a_drawn_volume_has_a_transfer_function_editor() {
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .parent()
            .unwrap();
        for (render, editor) in [(true, true), (false, false)] {
            let text = format!(
                "[volume]\npath = \"{}\"\nrender = {render}\n[[slices]]\naxis = \"axial\"\n",
                root.join("datasets/vtk/headsq_64x64x93.nhdr").display()
            );
            let s = scene::spec::parse(&text, "s.toml", root, &[]).unwrap();
            let m = scene::compile::model(&s).unwrap();
            let range = data_range(&m);
            assert_eq!(editor_of(&m, range).is_some(), editor, "render = {render}");
        }
    }

    #[test]
    fn a_draft_share_keeps_at_least_its_budget() {
        for heavy in [1usize, 9_999, 10_000, 133_760, 150_001, 7_000_000] {
            for budget in [DRAFT_MIN_PRIMITIVES, 50_000, DRAFT_PRIMITIVES] {
                let k = draft_share(heavy, budget);
                assert!(k.is_power_of_two(), "{heavy} / {budget}: {k}");
                assert!(
                    heavy / k >= budget.min(heavy),
                    "{heavy} / {budget}: 1 in {k}"
                );
                // And no more than twice the budget where it shares at all.
                assert!(
                    k == 1 || heavy / k < 2 * budget,
                    "{heavy} / {budget}: 1 in {k}"
                );
            }
        }
        assert_eq!(draft_share(133_760, DRAFT_MIN_PRIMITIVES), 8);
    }

    #[test]
    fn a_draft_keeps_whole_blocks_of_whole_triangles() {
        // 1000 triangles (3000 indices): blocks of 256 triangles, every 2nd kept.
        let idx: Vec<u32> = (0..3000).collect();
        let kept = every_kth_block(&idx, 3, 2);
        assert_eq!(kept.len() % 3, 0);
        // Blocks 0 and 2 of 0..3 (256 + 256 triangles).
        assert_eq!(kept.len(), 3 * 512);
        assert_eq!(kept[..3], [0, 1, 2]);
        assert_eq!(kept[3 * 256], 3 * 512);
        // Triangles stay whole: each kept triple starts at a multiple of 3.
        assert!(kept.chunks(3).all(|t| t[0] % 3 == 0 && t[1] == t[0] + 1));
        // k = 1 keeps everything.
        assert_eq!(every_kth_block(&idx, 3, 1), idx);
        let segs: Vec<u32> = (0..1000).collect();
        assert_eq!(every_kth_block(&segs, 1, 4).len(), 256);
    }

    #[test]
    fn draft_budgets_shrink_to_the_target_and_grow_back() {
        // A draft costing 30 ms + 1 us a primitive + 1 ms a slice (lavapipe's order of
        // magnitude on the demo): the budget comes within 1.25 x the target in a few drafts.
        let cost = |b: &DraftBudget| 30.0 + 1e-3 * b.primitives as f64 + b.slices as f64;
        let mut b = DraftBudget::default();
        assert!(cost(&b) > 300.0);
        let mut n = 0;
        while cost(&b) > 1.25 * DRAFT_TARGET_MS && n < 20 {
            b.adapt(cost(&b));
            n += 1;
        }
        assert!(n <= 6, "{n} drafts");
        assert!(b.primitives >= DRAFT_MIN_PRIMITIVES && b.slices >= DRAFT_MIN_SLICES);
        // Steady within the band.
        let c = b;
        b.adapt(cost(&b));
        assert_eq!(b, c);
        // A cheap scene grows back to the defaults, never past them.
        for _ in 0..20 {
            b.adapt(5.0);
        }
        assert_eq!(b, DraftBudget::default());
        // Out of reach (a fixed cost above the target): the floor, no lower.
        for _ in 0..20 {
            b.adapt(1000.0);
        }
        assert_eq!(
            b,
            DraftBudget {
                primitives: DRAFT_MIN_PRIMITIVES,
                slices: DRAFT_MIN_SLICES
            }
        );
        b.adapt(f64::NAN);
        assert_eq!(b.slices, DRAFT_MIN_SLICES);
    }

    #[test]
    fn the_value_gradient_histogram_finds_a_linear_fields_gradient_in_world_units() {
        // f = 3 (a . world) on a rotated, anisotropic grid: |grad f| = 3 per world unit inside
        // (central differences are exact on a linear field), less on the one-sided border.
        let n = 20;
        let lin = glam::DMat3::from_rotation_z(0.5)
            * glam::DMat3::from_rotation_x(-0.3)
            * glam::DMat3::from_diagonal(glam::DVec3::new(2.0, 1.0, 0.5));
        let affine = glam::DMat4::from_mat3_translation(lin, glam::DVec3::new(5.0, -3.0, 1.0));
        let a = glam::DVec3::new(1.0, 2.0, 2.0) / 3.0;
        let mut data = vec![0f32; n * n * n];
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for k in 0..n {
            for j in 0..n {
                for i in 0..n {
                    let w = affine.transform_point3(glam::DVec3::new(i as f64, j as f64, k as f64));
                    let v = 3.0 * a.dot(w);
                    data[i + n * (j + n * k)] = v as f32;
                    lo = lo.min(v);
                    hi = hi.max(v);
                }
            }
        }
        let h = value_gradient_histogram(
            [n; 3],
            affine,
            &Samples::f32(data.clone()),
            [lo, hi],
            32,
            16,
        );
        assert!((h.gmax - 3.0).abs() < 1e-4, "gmax {}", h.gmax);
        assert_eq!(h.counts.iter().sum::<u64>(), (n * n * n) as u64);
        // Every interior voxel in the top gradient row (3 = gmax).
        let top: u64 = h.counts[32 * 15..].iter().sum();
        assert!(top >= ((n - 2) * (n - 2) * (n - 2)) as u64, "{top}");
        // A gap (-3e38) takes its neighbours out.
        let mut gap = data.clone();
        gap[10 + n * (10 + n * 10)] = -3e38;
        let h2 = value_gradient_histogram([n; 3], affine, &Samples::f32(gap), [lo, hi], 32, 16);
        assert_eq!(h2.counts.iter().sum::<u64>(), (n * n * n - 7) as u64);
        // No volume, a flat one: nothing, gradient range 0.
        let mut bad = affine;
        bad.x_axis.x = f64::NAN;
        let nan = value_gradient_histogram([n; 3], bad, &Samples::f32(data), [lo, hi], 8, 8);
        assert_eq!((nan.counts.iter().sum::<u64>(), nan.gmax), (0, 0.0));
        let none = value_gradient_histogram(
            [0; 3],
            glam::DMat4::IDENTITY,
            &Samples::f32(vec![]),
            [0.0, 1.0],
            8,
            8,
        );
        assert_eq!((none.counts.iter().sum::<u64>(), none.gmax), (0, 0.0));
        let flat = value_gradient_histogram(
            [4; 3],
            affine,
            &Samples::f32(vec![1.0; 64]),
            [0.0, 2.0],
            8,
            8,
        );
        assert_eq!((flat.counts[4], flat.gmax), (64, 0.0));
    }
}
