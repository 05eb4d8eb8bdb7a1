//! `umbra render`: a scene file rendered on the GPU (`scene::render`) to PNG or EXR: one image,
//! a turntable (`--orbit N`) or a camera path (`--camera-path FILE`), with a one-line report
//! (or `--json`) and optional timings; on clusters a shard of the frames (`--shard`, Slurm
//! job arrays), resumable (`--skip-existing`), a manifest of scenes (`--manifest`) and a
//! record of each shard (`--record`), all from `scene::batch`.

use crate::output::{out, out_json_pretty};
use crate::progress::Frames;
use scene::batch::{Shard, ShardFrom};
use scene::render::{Cameras, FrameOutcome, Progress, RenderArgs, RenderReport};
use std::cell::{Cell, RefCell};
use std::path::{Path, PathBuf};

#[derive(clap::Args)]
pub struct Args {
    /// Scene file (see `umbra scene` and the README); with --manifest, the template scene of
    /// the lines that name none.
    #[arg(required_unless_present = "manifest")]
    scene: Option<PathBuf>,
    /// Output image: .png (8-bit sRGB) or .exr (linear float RGBA).
    #[arg(short, long)]
    output: PathBuf,
    /// Image width (render.width).
    #[arg(long, allow_negative_numbers = true)]
    width: Option<u32>,
    /// Image height (render.height).
    #[arg(long, allow_negative_numbers = true)]
    height: Option<u32>,
    /// A render method (render.method): combined, dos, vicinity, ea, phong, illuminated,
    /// lineao, illustrative, mip, minip.
    #[arg(long, value_enum, hide_possible_values = true)]
    method: Option<super::Method>,
    /// Render each image this many times, every pass re-run (total_ms is the median);
    /// more than 1 also times each pass.
    #[arg(long, default_value_t = 1, allow_negative_numbers = true,
          value_parser = clap::value_parser!(u32).range(1..=100_000))]
    frames: u32,
    /// Write the timings (total_ms, passes, each frame's) as JSON to this file; also times
    /// each pass.
    #[arg(long)]
    timings_json: Option<PathBuf>,
    /// Render a turntable of N frames (1 to 100000): frame k at camera.azimuth + k 360/N (a look-at
    /// camera turns its eye about the target around up). The output name's run of #
    /// becomes k, zero-padded.
    #[arg(long, value_name = "N", conflicts_with = "camera_path", allow_negative_numbers = true,
          value_parser = clap::value_parser!(u32).range(1..=100_000))]
    orbit: Option<u32>,
    /// Render the keyframed cameras of this TOML file (see the README, "Turntables and
    /// camera paths"); the output name needs a run of # as with --orbit.
    #[arg(long, value_name = "FILE")]
    camera_path: Option<PathBuf>,
    /// Add the AOV channels to the EXR: volumetric, partial, vicinity, lineao (with its
    /// factors .v, .g_depth, .g_light, .g_align where it ran) and combined occlusion, linear
    /// depth (Z).
    #[arg(long)]
    aov: bool,
    /// Animate the lines' trails ([[lines]] trail): N frames with the trails' time `now` from
    /// T0 to T1 (inclusive), in one process; with --orbit (the same N) or --camera-path (as
    /// many frames) the camera moves too. The output name needs a run of # as with --orbit.
    #[arg(long, value_name = "T0:T1:N")]
    trail_range: Option<String>,
    /// Override a scene key by its dotted path (repeatable).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    set: Vec<String>,
    /// A title at the top (annotate.title); may begin with `-` (`--title "-log10 p"`).
    #[arg(long, value_name = "TEXT", allow_hyphen_values = true)]
    title: Option<String>,
    /// Orientation labels (L/R, A/P, S/I) at the image's edges (annotate.orientation).
    #[arg(long)]
    orientation: bool,
    /// A scale bar of this length in world units, or auto (annotate.scale_bar).
    #[arg(long, value_name = "LENGTH|auto", allow_negative_numbers = true)]
    scale_bar: Option<String>,
    /// A colour bar: volume, tubes.N, lines.N, points.N, overlays.NAME or slices.N; none for no bar (annotate.colorbar).
    #[arg(long, value_name = "SOURCE")]
    colorbar: Option<String>,
    /// Print the report as JSON.
    #[arg(long)]
    json: bool,
    /// Render shard I of N (0 <= I < N): the frames (of --orbit, --camera-path,
    /// --trail-range or --manifest) whose index k has k mod N = I. Default: a Slurm array
    /// task's (SLURM_ARRAY_TASK_ID, _MIN, _STEP, _COUNT) when set. Implies --skip-existing.
    #[arg(long, value_name = "I/N", allow_hyphen_values = true, value_parser = shard_value)]
    shard: Option<String>,
    /// Leave outputs that are already complete images of the scene's size; render the rest.
    #[arg(long)]
    skip_existing: bool,
    /// Render one scene per line of FILE: `NAME [SCENE] [KEY=VALUE ...]` (see the README);
    /// the output needs {name}.
    #[arg(long, value_name = "FILE", conflicts_with_all = ["orbit", "camera_path", "trail_range", "timings_json"])]
    manifest: Option<PathBuf>,
    /// Write a JSON record of this run: its shard, the frames done (with their times),
    /// skipped and failed (with their errors), seconds, adapter, host.
    #[arg(long, value_name = "FILE")]
    record: Option<PathBuf>,
    /// The GPU adapter: its index in `umbra info --adapters`, a PCI bus id (0000:3b:00.0, as
    /// nvidia-smi or lspci print it) or a part of its name. Default: UMBRA_ADAPTER, else the
    /// best adapter.
    #[arg(long, value_name = "CHOICE", value_parser = adapter_choice)]
    adapter: Option<engine::gpu::AdapterChoice>,
}

fn adapter_choice(text: &str) -> Result<engine::gpu::AdapterChoice, String> {
    engine::gpu::AdapterChoice::parse(text)
}

/// What `--record` writes.
#[derive(serde::Serialize)]
struct Record<'a> {
    /// Null when the run failed before its shard was known.
    shard: Option<Shard>,
    shard_from: Option<ShardFrom>,
    /// The frames (or manifest lines) of this shard.
    frames: usize,
    done: &'a [FrameOutcome],
    skipped: &'a [FrameOutcome],
    failed: &'a [FrameOutcome],
    /// What failed before any frame (the scene, its data, the GPU).
    #[serde(skip_serializing_if = "Option::is_none")]
    error: Option<&'a str>,
    seconds: f64,
    adapter: &'a str,
    host: String,
}

/// `--shard`'s value as given (checked by `Shard::resolve`), so that `--shard -1/2` is the
/// bad shard it is (exit 1, as `--shard=-1/2`) - but not another option taken as the value
/// (`--shard --orbit 3`, `--shard -o x`): that is a command line without the shard's value.
fn shard_value(v: &str) -> Result<String, String> {
    let mut c = v.chars();
    if c.next() == Some('-') && !c.next().is_some_and(|d| d.is_ascii_digit()) {
        return Err(format!(
            "'{v}' is an option, not a shard: give I/N (e.g. --shard 0/4)"
        ));
    }
    Ok(v.to_string())
}

/// This machine's name (for a record read after a job array ran on many nodes).
fn host() -> String {
    std::fs::read_to_string("/proc/sys/kernel/hostname")
        .ok()
        .or_else(|| std::env::var("HOSTNAME").ok())
        .map(|h| h.trim().to_string())
        .unwrap_or_default()
}

/// Checks that `path` can be written before the work starts ([`volume::check_output`]: its
/// folder made, not a folder, a file can be created there).
fn writable(path: &Path, what: &str) -> Result<(), String> {
    volume::check_output(path).map_err(|e| format!("{what}: {e}"))
}

/// What the error path needs to write the record: the shard once known, its frame count once
/// known, whether the record was written.
struct RecordState {
    shard: Cell<Option<(Shard, ShardFrom)>>,
    frames: Cell<Option<usize>>,
    written: Cell<bool>,
}

/// The record an interruption (SIGINT, SIGTERM) writes, kept current as the frames end: its
/// path and the record so far (a Slurm time limit sends SIGTERM; the run's record must say
/// what it did, not stay missing or keep an earlier run's).
static INTERRUPTED: std::sync::Mutex<Option<(PathBuf, serde_json::Value, std::time::Instant)>> =
    std::sync::Mutex::new(None);

/// Keeps the record an interruption would write: `record` as it stands, of a run that began
/// at `t0` (its `seconds` are counted when the signal comes).
fn on_interrupt_record(path: Option<&Path>, record: &Record, t0: std::time::Instant) {
    let (Some(path), Ok(v)) = (path, serde_json::to_value(record)) else {
        return;
    };
    if let Ok(mut g) = INTERRUPTED.lock() {
        *g = Some((path.to_path_buf(), v, t0));
    }
}

/// No record for an interruption to write (the run's own is being written).
fn no_interrupt_record() {
    if let Ok(mut g) = INTERRUPTED.lock() {
        *g = None;
    }
}

/// Writes the record of a run interrupted by signal `sig`, with the frames ended so far and
/// `error` saying so; called by the signal thread before the process ends.
pub fn record_interrupted(sig: i32) {
    let Some((path, mut v, t0)) = INTERRUPTED.lock().ok().and_then(|mut g| g.take()) else {
        return;
    };
    v["seconds"] = t0.elapsed().as_secs_f64().into();
    let name = match sig {
        2 => "SIGINT",
        15 => "SIGTERM",
        _ => "a signal",
    };
    v["error"] = format!("interrupted by {name} (status {})", 128 + sig).into();
    if let Ok(text) = serde_json::to_string_pretty(&v) {
        let _ = volume::write_atomic(&path, text.as_bytes());
    }
}

/// Whether the record may be written over `path` when the run fails: not the output, the
/// timings, an input or a file the output pattern makes (the failure may be just that).
fn record_may_be_written(a: &Args, path: &Path) -> bool {
    volume::check_distinct(&[
        Some(a.output.as_path()),
        Some(path),
        a.timings_json.as_deref(),
    ])
    .is_ok()
        && volume::check_not_input(&[a.scene.as_deref(), a.manifest.as_deref()], &[Some(path)])
            .is_ok()
        && !pattern_makes(a, path)
}

/// Whether the output pattern of a sequence or a manifest makes the file `p`.
fn pattern_makes(a: &Args, p: &Path) -> bool {
    if a.manifest.is_some() {
        scene::batch::named_output_matches(&a.output, p)
    } else {
        let sequence_out = a.orbit.is_some() || a.camera_path.is_some() || a.trail_range.is_some();
        sequence_out && scene::camera_path::frame_path_matches(&a.output, p)
    }
}

pub fn run(a: Args) -> Result<(), String> {
    let t0 = std::time::Instant::now();
    let state = RecordState {
        shard: Cell::new(None),
        frames: Cell::new(None),
        written: Cell::new(false),
    };
    let r = render(&a, t0, &state);
    no_interrupt_record();
    if let (Err(e), Some(path)) = (&r, &a.record) {
        // Never over the scene, the manifest, the output or a frame (the error may be just
        // that).
        if !state.written.get() && record_may_be_written(&a, path) {
            let known = state.shard.get();
            let rec = Record {
                shard: known.map(|k| k.0),
                shard_from: known.map(|k| k.1),
                frames: state.frames.get().unwrap_or(0),
                done: &[],
                skipped: &[],
                failed: &[],
                error: Some(e),
                seconds: t0.elapsed().as_secs_f64(),
                adapter: "",
                host: host(),
            };
            if let Err(w) = write_record(path, &rec) {
                return Err(format!("{e} (and the record could not be written: {w})"));
            }
        }
    }
    r
}

/// The record of a `umbra render` command line that did not parse (a bad option value, an
/// unknown flag): found in the raw arguments, written with the parser's `error` so that a
/// job array's records still account for the task. Returns why it could not be written.
pub fn record_unparsed(args: &[std::ffi::OsString], error: &str) -> Result<(), String> {
    if args.get(1).and_then(|a| a.to_str()) != Some("render") {
        return Ok(());
    }
    let mut path = None;
    // The values of the options that set the frames, as `render` counts them for a run that
    // fails before any frame: a manifest 0 (not read), else `--orbit N`, else a camera path 0,
    // else `--trail-range T0:T1:N`, else one image (0 where the count itself does not parse).
    let (mut orbit, mut trail, mut manifest, mut camera_path) = (None, None, false, false);
    let mut it = args.iter().skip(2).peekable();
    while let Some(a) = it.next() {
        if a == "--" {
            break;
        }
        let Some(t) = a.to_str() else { continue };
        let (flag, inline) = match t.split_once('=') {
            Some((f, v)) if f.starts_with("--") => (f, Some(v.to_string())),
            _ => (t, None),
        };
        let takes = [
            "--record",
            "--orbit",
            "--trail-range",
            "--camera-path",
            "--manifest",
        ];
        if !takes.contains(&flag) {
            continue;
        }
        // A flag after it is the parser's missing value, not a value (and is read as a flag).
        let value = inline.or_else(|| {
            it.next_if(|v| !v.to_str().is_some_and(|v| v.starts_with('-')))
                .and_then(|v| v.to_str())
                .map(str::to_string)
        });
        match flag {
            "--record" => path = value.map(PathBuf::from),
            "--orbit" => orbit = Some(value.and_then(|v| v.parse::<usize>().ok())),
            "--trail-range" => {
                trail = Some(
                    value
                        .and_then(|v| scene::render::TrailRange::parse(&v).ok())
                        .map(|r| r.n as usize),
                )
            }
            "--manifest" => manifest = true,
            _ => camera_path = true,
        }
    }
    let frames = match (manifest, orbit, camera_path, trail) {
        (true, ..) => Some(0),
        (false, Some(n), ..) => n,
        (false, None, true, _) => Some(0),
        (false, None, false, Some(n)) => n,
        (false, None, false, None) => Some(1),
    };
    let Some(path) = path else {
        return Ok(());
    };
    writable(&path, "--record")?;
    write_record(
        &path,
        &Record {
            shard: None,
            shard_from: None,
            frames: frames.unwrap_or(0),
            done: &[],
            skipped: &[],
            failed: &[],
            error: Some(error),
            seconds: 0.0,
            adapter: "",
            host: host(),
        },
    )
}

fn write_record(path: &Path, r: &Record) -> Result<(), String> {
    let text = serde_json::to_string_pretty(r).map_err(|e| e.to_string())?;
    volume::write_atomic(path, text.as_bytes()).map_err(|e| e.to_string())
}

fn render(a: &Args, t0: std::time::Instant, state: &RecordState) -> Result<(), String> {
    // The record's and the timings' folders first: a run that fails on anything else still
    // leaves its record.
    for (p, what) in [(&a.record, "--record"), (&a.timings_json, "--timings-json")] {
        if let Some(p) = p {
            writable(p, what)?;
        }
    }
    volume::check_distinct(&[
        Some(a.output.as_path()),
        a.record.as_deref(),
        a.timings_json.as_deref(),
    ])?;
    volume::check_not_input(
        &[a.scene.as_deref(), a.manifest.as_deref()],
        &[
            Some(a.output.as_path()),
            a.record.as_deref(),
            a.timings_json.as_deref(),
        ],
    )?;
    // A sequence's or a manifest's output is a pattern: the record and the timings must not be
    // a file it makes (a frame would overwrite them, or they the frame).
    for (p, what) in [(&a.record, "--record"), (&a.timings_json, "--timings-json")] {
        let Some(p) = p.as_deref() else { continue };
        if pattern_makes(a, p) {
            return Err(format!(
                "{what} {}: a file the output pattern {} also makes; the {what} and an image \
                 would overwrite each other; give it a name the pattern cannot make",
                p.display(),
                a.output.display()
            ));
        }
    }
    let cameras = match (a.orbit, &a.camera_path) {
        (Some(n), _) => Cameras::Orbit(n),
        (None, Some(p)) => Cameras::Path(p.clone()),
        (None, None) => Cameras::Single,
    };
    let trail_range = a
        .trail_range
        .as_deref()
        .map(scene::render::TrailRange::parse)
        .transpose()?;
    let sequence = cameras != Cameras::Single || trail_range.is_some();
    // One image in a Slurm array task is that task's own image (e.g. its subject's), not a
    // shard of one frame: the Slurm variables are read for sequences and manifests only;
    // --shard applies to all.
    let slurm = sequence || a.manifest.is_some();
    // The frames the command line gives (a camera path's and a manifest's are known once
    // read): a run that fails before any frame, even on its shard, still records them.
    let total = match (a.orbit, &a.camera_path, &trail_range, &a.manifest) {
        (Some(n), _, _, None) => Some(n as usize),
        (None, None, Some(t), None) => Some(t.n as usize),
        (None, None, None, None) => Some(1),
        _ => None,
    };
    state.frames.set(total);
    let interrupted = |shard: Option<(Shard, ShardFrom)>,
                       frames: Option<usize>,
                       done: &[FrameOutcome],
                       skipped: &[FrameOutcome],
                       failed: &[FrameOutcome]| {
        on_interrupt_record(
            a.record.as_deref(),
            &Record {
                shard: shard.map(|s| s.0),
                shard_from: shard.map(|s| s.1),
                frames: frames.unwrap_or(0),
                done,
                skipped,
                failed,
                error: None,
                seconds: t0.elapsed().as_secs_f64(),
                adapter: "",
                host: host(),
            },
            t0,
        )
    };
    interrupted(None, total, &[], &[], &[]);
    let (shard, from) = Shard::resolve(a.shard.as_deref(), |k| {
        slurm.then(|| std::env::var(k).ok()).flatten()
    })
    .map_err(|e| match a.shard {
        Some(_) => format!("--shard: {e}"),
        None => e,
    })?;
    state.shard.set(Some((shard, from)));
    // The shard's frames where the command line gives their count.
    state
        .frames
        .set(total.map(|n| (0..n).filter(|&k| shard.owns(k)).count()));
    interrupted(Some((shard, from)), state.frames.get(), &[], &[], &[]);
    let skip_existing = a.skip_existing || from != ShardFrom::None;
    let progress = Frames::new();
    // The frames ended so far, for the record an interruption writes.
    let ended: RefCell<[Vec<FrameOutcome>; 3]> = RefCell::default();
    let note_ended = |which: usize, o: FrameOutcome| {
        let mut e = ended.borrow_mut();
        e[which].push(o);
        interrupted(Some((shard, from)), state.frames.get(), &e[0], &e[1], &e[2]);
    };
    let mut on_progress = |p: Progress| match p {
        Progress::Done(f, n) => {
            if sequence || a.manifest.is_some() {
                progress.done(f.index, f.name.as_deref(), n, &f.path, f.total_ms);
            }
            note_ended(
                0,
                FrameOutcome {
                    index: f.index,
                    name: f.name.clone(),
                    path: f.path.clone(),
                    ms: Some(f.total_ms),
                    error: None,
                },
            );
        }
        Progress::Skipped(o) => {
            progress.skipped(o.index, o.name.as_deref(), &o.path);
            note_ended(1, o.clone());
        }
        // A single image's failure is the command's error (printed once, at the end).
        Progress::Failed(o) => {
            if sequence || a.manifest.is_some() {
                progress.failed(
                    o.index,
                    o.name.as_deref(),
                    &o.path,
                    o.error.as_deref().unwrap_or(""),
                )
            }
            note_ended(2, o.clone());
        }
        Progress::Stage(m) => progress.stage(m),
        // A camera path's or a manifest's frames, once read.
        Progress::Frames(n) => {
            state.frames.set(Some(n));
            let e = ended.borrow();
            interrupted(Some((shard, from)), Some(n), &e[0], &e[1], &e[2]);
        }
    };
    let base = RenderArgs {
        scene: a.scene.clone().unwrap_or_default(),
        output: a.output.clone(),
        overrides: size_method_overrides(a.width, a.height, a.method, annotate_overrides(a)),
        frames: a.frames,
        aov: a.aov,
        pass_timings: a.timings_json.is_some() || a.frames > 1,
        cameras,
        trail_range,
        shard,
        skip_existing,
        adapter: a.adapter.clone(),
        also_written: [&a.timings_json, &a.record]
            .into_iter()
            .flatten()
            .cloned()
            .collect(),
    };
    let record = |done: &[FrameOutcome],
                  skipped: &[FrameOutcome],
                  failed: &[FrameOutcome],
                  frames: usize,
                  adapter: &str|
     -> Result<(), String> {
        let Some(path) = &a.record else {
            return Ok(());
        };
        no_interrupt_record();
        write_record(
            path,
            &Record {
                shard: Some(shard),
                shard_from: Some(from),
                frames,
                done,
                skipped,
                failed,
                error: None,
                seconds: t0.elapsed().as_secs_f64(),
                adapter,
                host: host(),
            },
        )?;
        state.written.set(true);
        Ok(())
    };
    if let Some(m) = &a.manifest {
        let entries = scene::batch::read_manifest(m, a.scene.as_deref())?;
        let r = scene::batch::run_manifest(&entries, &a.output, &base, shard, &mut on_progress)?;
        drop(progress);
        for (n, names) in &r.notes {
            if names.len() == r.done.len() {
                eprintln!("note: {n}");
            } else {
                eprintln!("note: {}: {n}", names.join(", "));
            }
        }
        record(&r.done, &r.skipped, &r.failed, r.frames_owned, &r.adapter)?;
        if a.json {
            out_json_pretty(&r)?;
        }
        eprintln!(
            "{}",
            shard_line(
                shard,
                "scenes",
                r.frames_owned,
                &r.done,
                &r.skipped,
                &r.failed
            )
        );
        return match scene::render::failure_summary(&r.failed, r.frames_owned, "scenes") {
            Some(e) => Err(e),
            None => Ok(()),
        };
    }
    let r = scene::render::run(&base, &mut on_progress)?;
    drop(progress);
    for n in &r.notes {
        eprintln!("note: {n}");
    }
    record(&r.done, &r.skipped, &r.failed, r.frames_owned, &r.adapter)?;
    if let Some(t) = &a.timings_json {
        if r.done.is_empty() && !r.skipped.is_empty() {
            // Nothing was timed: a resubmitted shard keeps the measurements of the run that
            // rendered its frames.
            eprintln!(
                "note: every frame was complete and skipped: {} is left as it was (no frame was timed)",
                t.display()
            );
        } else {
            let text = serde_json::to_string_pretty(&timings(&r)).map_err(|e| e.to_string())?;
            volume::write_atomic(t, text.as_bytes()).map_err(|e| e.to_string())?;
        }
    }
    if a.json {
        out_json_pretty(&r)?;
    } else if !r.done.is_empty() {
        out(summary(&r))?;
    }
    match (r.sequence.first(), r.sequence.last()) {
        (Some(first), _) if r.sequence.len() == 1 => {
            eprintln!("wrote 1 frame ({})", first.path.display())
        }
        (Some(first), Some(last)) => eprintln!(
            "wrote {} frames ({} ... {})",
            r.sequence.len(),
            first.path.display(),
            last.path.display()
        ),
        _ if r.done.len() == 1 => eprintln!("wrote {}", a.output.display()),
        _ => {}
    }
    if !r.skipped.is_empty() || from != ShardFrom::None || (sequence && !r.failed.is_empty()) {
        eprintln!(
            "{}",
            shard_line(
                shard,
                "frames",
                r.frames_owned,
                &r.done,
                &r.skipped,
                &r.failed
            )
        );
    }
    match scene::render::failure_summary(&r.failed, r.frames_owned, "frames") {
        Some(e) => Err(e),
        None => Ok(()),
    }
}

/// The last line of a shard's log: `shard I/N: D of M frames rendered, S skipped (complete), F
/// failed`.
fn shard_line(
    shard: Shard,
    what: &str,
    owned: usize,
    done: &[FrameOutcome],
    skipped: &[FrameOutcome],
    failed: &[FrameOutcome],
) -> String {
    format!(
        "shard {}/{}: {} of {owned} {what} rendered, {} skipped (complete), {} failed",
        shard.index,
        shard.count,
        done.len(),
        skipped.len(),
        failed.len()
    )
}

/// What `--timings-json` writes.
fn timings(r: &RenderReport) -> serde_json::Value {
    let mut t = serde_json::json!({
        "total_ms": r.total_ms,
        "passes": r.passes,
        "pass_clock": r.pass_clock,
        "frames_ms": r.frames_ms,
        "method": r.method,
        "width": r.width,
        "height": r.height,
        "slices": r.slices,
        "slice_distance": r.slice_distance,
        "triangles": r.triangles,
        "adapter": r.adapter,
        "setup_seconds": r.setup_seconds,
        "seconds": r.seconds,
        "sequence": r.sequence.iter().map(|f| {
            let mut o = serde_json::json!({
                "index": f.index,
                "path": f.path,
                "total_ms": f.total_ms,
                "frames_ms": f.frames_ms,
                "passes": f.passes,
                "slices": f.slices,
            });
            // The trails' time of the frame (`--trail-range`).
            if let Some(now) = f.now {
                o["now"] = now.into();
            }
            o
        }).collect::<Vec<_>>(),
    });
    // The light volume the frames swept (`dos`, `combined`), as `--json` reports it.
    if let Some(l) = r.light {
        t["light"] = serde_json::to_value(l).expect("a light grid serialises");
    }
    t
}

/// `--title`, `--orientation`, `--scale-bar`, `--colorbar` as scene overrides, then the `--set`
/// ones (which may change them).
fn annotate_overrides(a: &Args) -> Vec<String> {
    // A JSON string is a TOML basic string.
    let quoted = |t: &str| serde_json::to_string(t).expect("a string serialises");
    let mut o = vec![];
    if let Some(t) = &a.title {
        o.push(format!("annotate.title={}", quoted(t)));
    }
    if a.orientation {
        o.push("annotate.orientation=true".into());
    }
    if let Some(b) = &a.scale_bar {
        match b.trim().parse::<f64>() {
            Ok(v) => o.push(format!("annotate.scale_bar={v:?}")),
            Err(_) => o.push(format!("annotate.scale_bar={}", quoted(b.trim()))),
        }
    }
    if let Some(c) = &a.colorbar {
        o.push(format!("annotate.colorbar={}", quoted(c)));
    }
    o.extend(a.set.iter().cloned());
    o
}

/// `--width`, `--height`, `--method` as scene overrides, before the `--set` ones.
pub fn size_method_overrides(
    width: Option<u32>,
    height: Option<u32>,
    method: Option<super::Method>,
    set: Vec<String>,
) -> Vec<String> {
    let mut o = vec![];
    if let Some(w) = width {
        o.push(format!("render.width={w}"));
    }
    if let Some(h) = height {
        o.push(format!("render.height={h}"));
    }
    if let Some(m) = method {
        o.push(format!("render.method=\"{}\"", m.name()));
    }
    o.extend(set);
    o
}

/// One line about a render.
pub fn summary(r: &RenderReport) -> String {
    // Per-pass times only when they were measured (--timings-json, --frames above 1).
    let passes = if r.passes.is_empty() {
        String::new()
    } else {
        let list: Vec<String> = r
            .passes
            .iter()
            .map(|(k, v)| format!("{k} {v:.1}"))
            .collect();
        format!(" ({})", list.join(", "))
    };
    // The occlusion buffer's grid where the method swept one.
    let light = match &r.light {
        Some(l) => format!(", {l}"),
        None => String::new(),
    };
    // The slices where something samples them (a volume drawn, or the light).
    let slices = match r.marched {
        true => format!("{} slices {:.4} apart", r.slices, r.slice_distance),
        false => "no volume drawn".to_string(),
    };
    format!(
        "{}: {} x {}, {slices}{light}, {} triangles, on {}: {:.1} ms per frame{passes}, {:.2} s in all",
        r.method,
        r.width,
        r.height,
        r.triangles,
        r.adapter,
        r.total_ms,
        r.seconds
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn size_and_method_flags_come_before_the_set_overrides() {
        let o = size_method_overrides(
            Some(64),
            None,
            Some(super::super::Method(scene::spec::Method::Dos)),
            vec!["render.width=32".into()],
        );
        assert_eq!(
            o,
            [
                "render.width=64",
                "render.method=\"dos\"",
                "render.width=32"
            ]
        );
    }
}
