//! Rendering a scene to image files, the library behind `umbra render`: one image, or a
//! turntable or camera path in one process (one upload, a frame per camera, each frame written
//! atomically as it is done).

use crate::batch::{complete_image, Shard};
use crate::camera_path::{frame_path, CameraPath, Sequence};
use crate::compile::{model, upload_freeing_lines};
use crate::image_io::write_exr;
use crate::spec;
use engine::gpu::{AdapterChoice, Gpu};
use engine::renderer::{self, DrawOptions, Timings};
use occlusion::emission_absorption::EaView;
use std::cell::OnceCell;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// What `render` did.
#[derive(Clone, Debug, serde::Serialize)]
pub struct RenderReport {
    pub method: String,
    pub width: u32,
    pub height: u32,
    pub slices: u32,
    pub slice_distance: f64,
    /// Whether the frames marched the slices (a volume drawn, an isosurface, or a light volume
    /// swept): a scene of lines, tubes, points or slices alone has slices nothing samples.
    #[serde(skip)]
    pub marched: bool,
    pub triangles: u64,
    /// The occlusion buffer's cells and steps (`dos`, `combined`; absent otherwise).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub light: Option<engine::renderer::LightGrid>,
    pub adapter: String,
    /// Median frame time and per-pass times (see `renderer::Timings`).
    pub total_ms: f64,
    pub passes: std::collections::BTreeMap<String, f64>,
    /// How `passes` was measured (absent when it was not).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub pass_clock: Option<renderer::PassClock>,
    pub frames_ms: Vec<f64>,
    /// Wall time of the whole command: loading, meshing, rendering, writing.
    pub seconds: f64,
    /// Wall time before the first frame: loading, meshing, opening the GPU, uploading.
    pub setup_seconds: f64,
    pub notes: Vec<String>,
    /// Each frame of a turntable or camera path (empty for one image).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub sequence: Vec<FrameReport>,
    /// The frames this run was to render (its shard's): how many, and those rendered,
    /// skipped (`skip_existing`: already complete) and failed (with their errors).
    pub frames_owned: usize,
    #[serde(skip)]
    pub done: Vec<FrameOutcome>,
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub skipped: Vec<FrameOutcome>,
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub failed: Vec<FrameOutcome>,
}

impl RenderReport {
    /// The report, or an error naming the frames that failed.
    pub fn failures(self) -> Result<RenderReport, String> {
        match failure_summary(&self.failed, self.frames_owned, "frames") {
            Some(e) => Err(e),
            None => Ok(self),
        }
    }
}

/// "2 of 10 frames failed: the first ..." when any did (`what`: "frames", "scenes"); the error
/// itself when the one frame of a single image did.
pub fn failure_summary(failed: &[FrameOutcome], of: usize, what: &str) -> Option<String> {
    let first = failed.first()?;
    if of == 1 && failed.len() == 1 {
        // A single image's failure is its error.
        return Some(first.error.clone().unwrap_or_else(|| "failed".into()));
    }
    let which = match &first.name {
        Some(n) => format!("{n} ({})", first.path.display()),
        None => format!("frame {} ({})", first.index, first.path.display()),
    };
    Some(format!(
        "{} of {of} {what} failed; the first, {which}: {}",
        failed.len(),
        first.error.as_deref().unwrap_or("failed")
    ))
}

/// What became of one frame (or one manifest line) of a batch.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct FrameOutcome {
    /// Global index: the frame's in its sequence, the line's among a manifest's entries.
    pub index: usize,
    /// The manifest entry's name.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
    pub path: PathBuf,
    /// Median frame time, ms (rendered frames).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ms: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
}

/// What [`run`] tells its caller as it goes.
pub enum Progress<'a> {
    /// A frame rendered and written, of `n` this run owns (rendered, skipped or failed).
    Done(&'a FrameReport, usize),
    /// A frame not rendered: its output is already complete.
    Skipped(&'a FrameOutcome),
    /// A frame that failed (the others go on).
    Failed(&'a FrameOutcome),
    /// A long stage has started (reading the scene's data, uploading it, drawing a frame).
    Stage(&'a str),
    /// The frames this run owns (rendered, skipped or failed), once known: before the first
    /// frame, after a camera path or a manifest is read.
    Frames(usize),
}

/// One frame of a sequence.
#[derive(Clone, Debug, serde::Serialize)]
pub struct FrameReport {
    pub index: usize,
    /// The manifest entry's name (manifest runs).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
    pub path: PathBuf,
    /// The frame's `[camera]`.
    pub camera: spec::CameraSpec,
    pub slices: u32,
    /// The trails' time (`--trail-range`), when animated.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub now: Option<f64>,
    /// Median of the frame's repeats (`--frames`), ms.
    pub total_ms: f64,
    pub frames_ms: Vec<f64>,
    pub passes: std::collections::BTreeMap<String, f64>,
}

/// Which cameras `umbra render` renders.
#[derive(Clone, Debug, Default, PartialEq)]
pub enum Cameras {
    /// The scene's camera.
    #[default]
    Single,
    /// A turntable of this many frames.
    Orbit(u32),
    /// A camera path file.
    Path(PathBuf),
}

/// What `umbra render` is asked to do.
#[derive(Clone, Debug, Default)]
pub struct RenderArgs {
    pub scene: PathBuf,
    pub output: PathBuf,
    /// `--set KEY=VALUE` overrides (`--width`, `--height` and `--method` become these too).
    pub overrides: Vec<String>,
    /// Frames timed (the median is `total_ms`); at least 1.
    pub frames: u32,
    /// Write the AOV channels (EXR output only).
    pub aov: bool,
    /// Time each pass alone once more.
    pub pass_timings: bool,
    pub cameras: Cameras,
    /// Animate the lines' trails: `n` frames with `now` from `t0` to `t1` (inclusive).
    pub trail_range: Option<TrailRange>,
    /// Render only this shard's frames (global index k with k mod N = I).
    pub shard: Shard,
    /// Leave outputs that are already complete images of the right size
    /// ([`crate::batch::complete_image`]) as they are.
    pub skip_existing: bool,
    /// The GPU adapter to open (default: `UMBRA_ADAPTER`, else the best one).
    pub adapter: Option<AdapterChoice>,
    /// The command's other outputs (`umbra render`'s timings and record): checked, with the
    /// frames', against every file the scene's data were read from before any frame is drawn
    /// ([`volume::check_not_read`]).
    pub also_written: Vec<PathBuf>,
}

impl Default for Shard {
    fn default() -> Shard {
        Shard::ALL
    }
}

/// `--trail-range T0:T1:N`: frame k of N draws every trail at `T0 + (T1 - T0) k / (N - 1)`
/// (`T0` for one frame).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TrailRange {
    pub t0: f64,
    pub t1: f64,
    pub n: u32,
}

impl TrailRange {
    /// Reads `T0:T1:N`.
    pub fn parse(text: &str) -> Result<TrailRange, String> {
        let bad = || format!("--trail-range {text}: expected T0:T1:N, e.g. 0:1:25");
        let parts: Vec<&str> = text.split(':').collect();
        let [a, b, n] = parts[..] else {
            return Err(bad());
        };
        let (t0, t1): (f64, f64) = (
            a.trim().parse().map_err(|_| bad())?,
            b.trim().parse().map_err(|_| bad())?,
        );
        let n: u32 = n.trim().parse().map_err(|_| bad())?;
        if !(t0.is_finite() && t1.is_finite()) {
            return Err(format!("--trail-range {text}: the times must be finite"));
        }
        if n == 0 || n > crate::camera_path::MAX_FRAMES {
            return Err(format!(
                "--trail-range {text}: N must be 1 to {}",
                crate::camera_path::MAX_FRAMES
            ));
        }
        Ok(TrailRange { t0, t1, n })
    }

    /// The time of frame `k`.
    pub fn time(&self, k: u32) -> f64 {
        if self.n <= 1 {
            self.t0
        } else {
            self.t0 + (self.t1 - self.t0) * k as f64 / (self.n - 1) as f64
        }
    }
}

/// Writes one frame: PNG (8-bit sRGB) or EXR (linear RGBA, with `aov` the AOV channels),
/// atomically, creating missing folders.
pub fn write_image(
    path: &Path,
    exr: bool,
    aov: bool,
    bits: u32,
    out: &renderer::Output,
    v: &EaView,
) -> Result<(), String> {
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    }
    let (w, h) = (v.width as usize, v.height as usize);
    if exr {
        let channels = if aov { out.aov_channels() } else { vec![] };
        write_exr(path, w, h, &out.image, &channels)
    } else {
        let rgb: Vec<[f32; 3]> = out.image.iter().map(|c| [c[0], c[1], c[2]]).collect();
        if bits == 1 {
            crate::image_io::write_bw_png(path, w, h, &rgb)
        } else {
            crate::image_io::write_rgb_png(path, w, h, &rgb)
        }
    }
}

/// Refuses a colour bar of a surface's colouring (`tubes.N`, `lines.N`, `points.N`) under the
/// illustrative method, which draws every surface in one ink (`render.illustrative.line`): the
/// bar would show colours the image does not have.
pub fn check_colorbar_method(s: &spec::Scene) -> Result<(), String> {
    if let Some(src) = s.annotate.colorbar.as_deref().filter(|c| {
        ["tubes.", "lines.", "points."]
            .iter()
            .any(|p| c.starts_with(p))
    }) {
        if s.render.method == spec::Method::Illustrative {
            return Err(format!(
                "scene key annotate.colorbar: '{src}' is drawn in render.illustrative.line by the \
                 illustrative method, not in its colouring: the bar would show colours the image \
                 does not have (choose another method or leave the bar out)"
            ));
        }
    }
    Ok(())
}

/// Draws the scene's `[annotate]` over a frame's image.
pub fn annotate_frame(
    s: &spec::Scene,
    m: &crate::compile::Model,
    out: &mut renderer::Output,
    v: &EaView,
) -> Result<(), String> {
    if s.annotate.is_empty() {
        return Ok(());
    }
    let camera = crate::compile::camera(s, m.bounds)?;
    // Tractograms and meshes alone are RAS+ by convention; a volume says.
    let ras = m.is_ras();
    let bg = s.background.rgb()?.map(|c| c as f32);
    let ctx = crate::annotate::Context {
        camera: &camera,
        ras,
        background: bg,
        colorbar: m.colorbar.as_ref(),
    };
    crate::annotate::draw(
        &mut out.image,
        v.width as usize,
        v.height as usize,
        &s.annotate,
        &ctx,
    )
    .map(|_| ())
}

/// Runs `umbra render`: one frame, or a turntable or camera path (one upload, a frame per
/// camera, each written as it is done; `progress` hears of each). A frame that fails is
/// recorded in the report's `failed` and the others go on; what fails before the first frame
/// (the scene, the data, the GPU) is the error.
pub fn run(a: &RenderArgs, progress: &mut dyn FnMut(Progress)) -> Result<RenderReport, String> {
    run_on(a, &OnceCell::new(), progress)
}

/// The GPU of `cell`, opened on first use.
pub(crate) fn gpu_of<'a>(
    cell: &'a OnceCell<Gpu>,
    choice: Option<&AdapterChoice>,
) -> Result<&'a Gpu, String> {
    if cell.get().is_none() {
        let g = match choice {
            Some(c) => Gpu::open(Some(c)),
            None => Gpu::new(),
        }
        .map_err(|e| e.to_string())?;
        let _ = cell.set(g);
    }
    Ok(cell.get().expect("set above"))
}

/// [`run`] on the GPU of `gpu` (opened on first use, kept for the next run).
pub(crate) fn run_on(
    a: &RenderArgs,
    gpu_cell: &OnceCell<Gpu>,
    progress: &mut dyn FnMut(Progress),
) -> Result<RenderReport, String> {
    let t0 = Instant::now();
    let path = &a.scene;
    let s = spec::load(path, &a.overrides)?;
    let ext = a
        .output
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    let exr = match ext.as_deref() {
        Some("png") => false,
        Some("exr") => true,
        _ => {
            return Err(format!(
                "{}: the output must end in .png or .exr",
                a.output.display()
            ))
        }
    };
    if s.render.bits == 1 && exr {
        return Err(format!(
            "{}: render.bits = 1 writes PNG; this output is an EXR",
            a.output.display()
        ));
    }
    if a.aov && !exr {
        return Err(format!(
            "{}: AOV channels are written to EXR only; this output is a PNG",
            a.output.display()
        ));
    }
    let sequence = match &a.cameras {
        Cameras::Single => None,
        Cameras::Orbit(0) => return Err("a turntable needs at least one frame".into()),
        Cameras::Orbit(n) if *n > crate::camera_path::MAX_FRAMES => {
            return Err(format!(
                "a turntable of {n} frames: at most {}",
                crate::camera_path::MAX_FRAMES
            ))
        }
        Cameras::Orbit(n) => Some(Sequence::Orbit(*n)),
        Cameras::Path(p) => Some(Sequence::Path(CameraPath::load(p)?)),
    };
    if let Some(t) = &a.trail_range {
        if !s.lines.iter().any(|l| l.trail.is_some()) {
            return Err(format!(
                "{}: --trail-range animates [[lines]] trails; the scene has none",
                path.display()
            ));
        }
        // An orbit or camera path runs alongside: as many cameras as times.
        if let Cameras::Orbit(n) = a.cameras {
            if n != t.n {
                return Err(format!(
                    "--orbit {n} with --trail-range of {} frames: give both the same count",
                    t.n
                ));
            }
        }
    }
    let sequence = sequence.or(a.trail_range.map(|t| Sequence::Still(t.n)));
    let n_frames = match &sequence {
        None => 1,
        Some(Sequence::Orbit(n) | Sequence::Still(n)) => *n as usize,
        Some(Sequence::Path(p)) => p.frame_times().len(),
    };
    if let (Some(Sequence::Path(_)), Some(t)) = (&sequence, &a.trail_range) {
        if n_frames != t.n as usize {
            return Err(format!(
                "the camera path has {n_frames} frames and --trail-range {}: give both the same count",
                t.n
            ));
        }
    }
    if sequence.is_some() {
        frame_path(&a.output, 0)?;
    }
    // This run's frames, their outputs, and those already done.
    let mut owned: Vec<(usize, PathBuf)> = vec![];
    for k in (0..n_frames).filter(|&k| a.shard.owns(k)) {
        let file = match &sequence {
            None => a.output.clone(),
            Some(_) => frame_path(&a.output, k)?,
        };
        owned.push((k, file));
    }
    let frames_owned = owned.len();
    progress(Progress::Frames(frames_owned));
    // A killed run's temporary files of this shard's outputs, complete ones included (no
    // other process writes them).
    let files: Vec<&Path> = owned.iter().map(|(_, f)| f.as_path()).collect();
    volume::remove_stale_temps(&files);
    let mut skipped = vec![];
    if a.skip_existing {
        owned.retain(|(k, file)| {
            // With AOVs asked for, an EXR must hold them (the depth channel is in every
            // AOV set: `renderer::Output::aov_channels`).
            let need: &[&str] = if a.aov { &["Z"] } else { &[] };
            let done = complete_image(file, s.render.width, s.render.height, need);
            if done {
                let o = FrameOutcome {
                    index: *k,
                    name: None,
                    path: file.clone(),
                    ms: None,
                    error: None,
                };
                progress(Progress::Skipped(&o));
                skipped.push(o);
            }
            !done
        });
    }
    let mut report = RenderReport {
        method: format!("{:?}", s.render.method).to_lowercase(),
        width: s.render.width,
        height: s.render.height,
        slices: 0,
        slice_distance: 0.0,
        marched: false,
        triangles: 0,
        light: None,
        adapter: String::new(),
        total_ms: 0.0,
        passes: Default::default(),
        pass_clock: None,
        frames_ms: vec![],
        seconds: 0.0,
        setup_seconds: 0.0,
        notes: vec![],
        sequence: vec![],
        frames_owned,
        done: vec![],
        skipped,
        failed: vec![],
    };
    if owned.is_empty() {
        // Nothing to render: the scene's data are not even read.
        report.setup_seconds = t0.elapsed().as_secs_f64();
        report.seconds = report.setup_seconds;
        return Ok(report);
    }
    // What every frame needs: the output folders, the model, the GPU, the upload. When it
    // fails after frames were skipped, the frames left are failed with its error, so that
    // the report (and a shard's record) keeps what was skipped.
    let mut setup = || -> Result<_, String> {
        // Each output folder made and writable before the data are read (one probe a folder).
        let mut folders = std::collections::HashSet::new();
        for (_, f) in &owned {
            if folders.insert(f.parent()) {
                volume::check_output(f)?;
            }
        }
        check_colorbar_method(&s).map_err(|e| format!("{}: {e}", path.display()))?;
        progress(Progress::Stage("reading the scene's data"));
        let mut m = model(&s).map_err(|e| format!("{}: {e}", path.display()))?;
        // No output may replace a file the scene's data came from (a volume, a tractogram,
        // a colour table), whatever its name.
        let outputs = owned.iter().map(|(_, f)| f).chain(&a.also_written);
        volume::check_not_read(&outputs.map(|f| Some(f.as_path())).collect::<Vec<_>>())?;
        let gpu = gpu_of(gpu_cell, a.adapter.as_ref())?;
        progress(Progress::Stage("uploading to the GPU"));
        // The frames read the lines from the GPU only: their points are freed as they go up.
        // A volume the CPU renderer draws stays on the CPU only (no GPU copy, full
        // resolution).
        let on_gpu = !crate::compile::drawn_on_cpu(&s, &m, gpu);
        let up = upload_freeing_lines(gpu, &mut m, on_gpu)
            .map_err(|e| format!("{}: {e}", path.display()))?;
        Ok((m, gpu, up))
    };
    let (m, gpu, up) = match setup() {
        Ok(x) => x,
        Err(e) if report.skipped.is_empty() => return Err(e),
        Err(e) => {
            for (k, file) in owned {
                let o = FrameOutcome {
                    index: k,
                    name: None,
                    path: file,
                    ms: None,
                    error: Some(e.clone()),
                };
                progress(Progress::Failed(&o));
                report.failed.push(o);
            }
            report.setup_seconds = t0.elapsed().as_secs_f64();
            report.seconds = report.setup_seconds;
            return Ok(report);
        }
    };
    let opts = DrawOptions {
        frames: a.frames.max(1),
        pass_timings: a.pass_timings,
    };
    let mut notes = m.notes.clone();
    notes.extend(up.notes.iter().cloned());
    let cameras = match &sequence {
        None => vec![s.camera.clone()],
        Some(q) => {
            let c = (m.bounds[0] + m.bounds[1]) * 0.5;
            q.cameras(&s, c.to_array())
        }
    };
    report.setup_seconds = t0.elapsed().as_secs_f64();
    report.adapter = gpu.report().name;
    let mut frames: Vec<FrameReport> = Vec::with_capacity(owned.len());
    let mut last = None;
    let n_owned = frames_owned;
    for (k, file) in owned {
        let cam = &cameras[k];
        let mut sk = s.clone();
        sk.camera = cam.clone();
        let now = a.trail_range.map(|t| t.time(k as u32));
        progress(Progress::Stage(&format!("drawing frame {k}")));
        let drawn = up
            .draw_at(&sk, &m, opts, now)
            .map_err(|e| match sequence.is_some() {
                true => format!("{}: frame {k}: {e}", path.display()),
                // A single image has no frame number to name.
                false => format!("{}: {e}", path.display()),
            })
            .and_then(|(mut out, v)| {
                annotate_frame(&sk, &m, &mut out, &v)?;
                write_image(&file, exr, a.aov, s.render.bits, &out, &v)?;
                Ok((out, v))
            });
        let (out, v) = match drawn {
            Ok(d) => d,
            Err(error) => {
                let o = FrameOutcome {
                    index: k,
                    name: None,
                    path: file,
                    ms: None,
                    error: Some(error),
                };
                progress(Progress::Failed(&o));
                report.failed.push(o);
                continue;
            }
        };
        if last.is_none() {
            notes.extend(out.notes.iter().cloned());
        }
        let f = FrameReport {
            index: k,
            name: None,
            path: file,
            camera: cam.clone(),
            slices: v.slices,
            now,
            total_ms: out.timings.total_ms,
            frames_ms: out.timings.frames_ms.clone(),
            passes: out.timings.passes.clone(),
        };
        progress(Progress::Done(&f, n_owned));
        report.done.push(FrameOutcome {
            index: k,
            name: None,
            path: f.path.clone(),
            ms: Some(f.total_ms),
            error: None,
        });
        frames.push(f);
        last = Some((out, v));
    }
    report.notes = notes;
    report.seconds = t0.elapsed().as_secs_f64();
    let Some((out, v)) = last else {
        return Ok(report);
    };
    let Timings {
        total_ms,
        frames_ms,
        passes,
        pass_clock,
    } = out.timings;
    let totals: Vec<f64> = frames.iter().map(|f| f.total_ms).collect();
    report.width = v.width;
    report.height = v.height;
    report.slices = v.slices;
    report.slice_distance = v.dz;
    report.triangles = out.triangles;
    report.light = out.light;
    report.marched = m.volume.is_some() || m.iso.is_some() || report.light.is_some();
    report.total_ms = if sequence.is_some() {
        engine::renderer::median(&totals)
    } else {
        total_ms
    };
    report.passes = passes;
    report.pass_clock = pass_clock;
    report.frames_ms = frames_ms;
    if sequence.is_some() {
        report.sequence = frames;
    }
    Ok(report)
}
