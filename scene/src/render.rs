//! Rendering a scene to image files, the library behind `umbra render`: one image, or a
//! turntable or camera path in one process (one upload, a frame per camera, each frame written
//! atomically as it is done).

use crate::camera_path::{frame_path, CameraPath, Sequence};
use crate::compile::{model, upload};
use crate::image_io::write_exr;
use crate::spec;
use engine::renderer::{self, DrawOptions, Timings};
use occlusion::emission_absorption::EaView;
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
    pub triangles: u64,
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
}

/// One frame of a sequence.
#[derive(Clone, Debug, serde::Serialize)]
pub struct FrameReport {
    pub index: usize,
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

/// Runs `umbra render`: one frame, or a turntable or camera path (one upload, a frame per
/// camera, each written as it is done; `progress` hears of each).
pub fn run(
    a: &RenderArgs,
    progress: &mut dyn FnMut(&FrameReport, usize),
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
    if sequence.is_some() {
        frame_path(&a.output, 0)?;
    }
    let m = model(&s).map_err(|e| format!("{}: {e}", path.display()))?;
    let gpu = engine::gpu::Gpu::new().map_err(|e| e.to_string())?;
    let up = upload(&gpu, &m).map_err(|e| format!("{}: {e}", path.display()))?;
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
    if let Some(t) = &a.trail_range {
        if cameras.len() != t.n as usize {
            return Err(format!(
                "the camera path has {} frames and --trail-range {}: give both the same count",
                cameras.len(),
                t.n
            ));
        }
    }
    let setup_seconds = t0.elapsed().as_secs_f64();
    let mut frames: Vec<FrameReport> = Vec::with_capacity(cameras.len());
    let mut last = None;
    for (k, cam) in cameras.iter().enumerate() {
        let mut sk = s.clone();
        sk.camera = cam.clone();
        let now = a.trail_range.map(|t| t.time(k as u32));
        let (out, v) = up
            .draw_at(&sk, &m, opts, now)
            .map_err(|e| format!("{}: frame {k}: {e}", path.display()))?;
        let file = match &sequence {
            None => a.output.clone(),
            Some(_) => frame_path(&a.output, k)?,
        };
        write_image(&file, exr, a.aov, s.render.bits, &out, &v)?;
        if k == 0 {
            notes.extend(out.notes.iter().cloned());
        }
        let f = FrameReport {
            index: k,
            path: file,
            camera: cam.clone(),
            slices: v.slices,
            now,
            total_ms: out.timings.total_ms,
            frames_ms: out.timings.frames_ms.clone(),
            passes: out.timings.passes.clone(),
        };
        progress(&f, cameras.len());
        frames.push(f);
        last = Some((out, v));
    }
    let (out, v) = last.ok_or("no frame was rendered")?;
    let Timings {
        total_ms,
        frames_ms,
        passes,
        pass_clock,
    } = out.timings;
    let mut totals: Vec<f64> = frames.iter().map(|f| f.total_ms).collect();
    totals.sort_by(f64::total_cmp);
    Ok(RenderReport {
        method: format!("{:?}", s.render.method).to_lowercase(),
        width: v.width,
        height: v.height,
        slices: v.slices,
        slice_distance: v.dz,
        triangles: out.triangles,
        adapter: gpu.report().name,
        total_ms: if sequence.is_some() {
            totals[totals.len() / 2]
        } else {
            total_ms
        },
        passes,
        pass_clock,
        frames_ms,
        setup_seconds,
        seconds: t0.elapsed().as_secs_f64(),
        notes,
        sequence: if sequence.is_some() { frames } else { vec![] },
    })
}
