//! `umbra trace`: streamlines through a vector field (see `tubes::trace`), or with
//! `--pathlines` pathlines through a time-varying one (see `tubes::pathline`).
//!
//! Every point gets two attributes: `time` (the seed's time plus the integration time,
//! `∫ ds / |v|` along a streamline, the particle's time on a pathline; earlier before the seed
//! when tracing both ways) and `speed` (`|v|` there). `.trk` stores them as scalars and `.trx` as
//! `dpv/time.float32` and `dpv/speed.float32`, so `[[lines]] color = "scalar:time"` or
//! `"scalar:speed"` colours by them; `.tck` holds positions only, so they are dropped there (the
//! command says so on stderr; the file is still written).
//!
//! Seed times (`--seed-times`): `start` (default: the field's first time, `toffset` of a NIfTI
//! series, 0 for a steady field, the frame's time with `--frame`), a number, `random` (uniform
//! over the series' time span `[t0, t0 + span)`, the period of a periodic series; a steady
//! field has no span and needs `random:T0:T1`), or `random:T0:T1`. Random times and
//! `--seeds random:N` are deterministic for a `--random-seed`.
//!
//! Pathlines (`--pathlines`): RK4 (or Euler) in time through the field interpolated
//! trilinearly in space and linearly in time between the two frames around each time; a
//! periodic series (NIfTI `descrip` holding `periodic`, as `umbra synth double-gyre` writes it)
//! wraps around with period `frames x pixdim[4]`, any other is clamped (its first frame before
//! it, its last after it); `--time-boundary` overrides the file. A steady volume (any format, or
//! the 4-D NIfTI form) is one frame the same at every time, so its pathlines are its
//! streamlines. `--time-step` defaults to the smaller of span / 200 ([002]'s heartbeat / 200)
//! and the time to cross half the smallest voxel at the field's largest speed (the latter alone
//! for a steady field); `--duration` (each way) to the span, or 200 time steps for a steady
//! field. `--max-length`, `--min-speed`, `--max-angle` (between the velocities at consecutive
//! points), `--mask` and `--one-way` apply as to streamlines; `--step`, `--eigen`, `--frame`
//! and `rk45` do not and are refused, and `--tolerance` (RK45's) is ignored.
//!
//! A time series without `--pathlines` is refused unless `--frame K` picks the frame whose
//! streamlines to trace.

use glam::DVec3;
use std::path::{Path, PathBuf};
use tubes::pathline::{pathlines_within, PathIntegrator, PathlineOptions, SeriesField};
use tubes::trace::{
    grid_seeds, random_seeds, random_times, trace_at_within, GridField, GridScalar, Integrator,
    TraceOptions,
};

/// What `umbra trace --help` adds below the options.
const NOTES: &str = "\
Every point gets the attributes `time` and `speed`: .trk keeps them as scalars, .trx as dpv/ \
arrays (colour with [[lines]] color = \"scalar:time\" or \"scalar:speed\"); .tck holds \
positions only and drops them.
--pathlines: RK4 in time, linear in time between frames; periodic when the NIfTI descrip says \
periodic (as `umbra synth double-gyre` writes), else clamped at the ends. A steady volume is one \
frame, so its pathlines are its streamlines.
--seed-times: start (the field's first time), T, random (over the field's time span) or \
random:T0:T1; deterministic for a --random-seed.";

#[derive(clap::Args)]
#[command(after_help = NOTES)]
pub struct Args {
    /// Vector field: any volume with a 3-component array (NIfTI V1, VTK vectors, ...), or a
    /// 5-D NIfTI time series (x, y, z, t, 3) for --pathlines.
    input: PathBuf,
    /// Output tractogram (.trk or .trx keep time and speed; .tck drops them).
    #[arg(short, long)]
    output: PathBuf,
    /// The vector array, by name.
    #[arg(long)]
    field: Option<String>,
    /// Seeds: grid:N, random:N, plane:x=VALUE:N (also y, z), or a CSV file of x,y,z.
    #[arg(long, default_value = "grid:10")]
    seeds: String,
    /// Step in world units (default: half the smallest voxel spacing).
    #[arg(long, value_parser = super::positive)]
    step: Option<f64>,
    /// Integrator: rk4, rk45 (adaptive) or euler.
    #[arg(long, value_enum, default_value = "rk4", hide_possible_values = true)]
    integrator: IntegratorArg,
    /// RK45 local error bound (world units).
    #[arg(long, default_value_t = 1e-3, value_parser = super::positive)]
    tolerance: f64,
    /// Longest streamline, both ways together (world units; default: twice the grid's diagonal).
    #[arg(long, value_parser = super::positive)]
    max_length: Option<f64>,
    /// Stop where the field's magnitude falls below this.
    #[arg(long, default_value_t = 1e-6, value_parser = super::nonnegative)]
    min_speed: f64,
    /// Stop where this scalar volume (e.g. FA) falls below --threshold.
    #[arg(long)]
    mask: Option<PathBuf>,
    /// The mask's level (needs --mask).
    #[arg(long, default_value_t = 0.2, allow_hyphen_values = true, value_parser = super::finite64, requires = "mask")]
    threshold: f64,
    /// Stop where the direction turns by more than this many degrees in one step.
    #[arg(long, default_value_t = 60.0, value_parser = super::degrees)]
    max_angle: f64,
    /// The field is an eigenvector field (no sign): orient it along the direction of travel.
    #[arg(long)]
    eigen: bool,
    /// Trace forward only (default: both ways from each seed).
    #[arg(long)]
    one_way: bool,
    /// Trace pathlines through a time-varying field (RK4 in time; see below).
    #[arg(long)]
    pathlines: bool,
    /// Seed times: start, a number, random, or random:T0:T1.
    #[arg(long, default_value = "start")]
    seed_times: String,
    /// Random generator seed of --seeds random:N and --seed-times random.
    #[arg(long, default_value_t = 1)]
    random_seed: u64,
    /// Pathline time step (default: min(span / 200, half the smallest voxel / the largest speed)).
    #[arg(long, value_parser = super::positive, requires = "pathlines")]
    time_step: Option<f64>,
    /// How long a pathline follows its particle each way (default: the time span; steady: 200
    /// time steps).
    #[arg(long, value_parser = super::positive, requires = "pathlines")]
    duration: Option<f64>,
    /// Override the file's time boundary: periodic or clamp.
    #[arg(long, value_enum)]
    time_boundary: Option<TimeBoundary>,
    /// Streamlines of one frame of a time series (0 = the first).
    #[arg(long)]
    frame: Option<usize>,
}

/// `--time-boundary`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum TimeBoundary {
    /// Wrap around with period frames x time step.
    Periodic,
    /// Hold the first frame before the series and the last after it.
    Clamp,
}

/// `--integrator`.
#[derive(Clone, Copy, Debug, clap::ValueEnum)]
pub enum IntegratorArg {
    Rk4,
    Rk45,
    Euler,
}

impl From<IntegratorArg> for Integrator {
    fn from(i: IntegratorArg) -> Self {
        match i {
            IntegratorArg::Rk4 => Integrator::Rk4,
            IntegratorArg::Rk45 => Integrator::Rk45,
            IntegratorArg::Euler => Integrator::Euler,
        }
    }
}

pub fn run(a: Args) -> Result<(), String> {
    let args = TraceArgs {
        input: a.input,
        output: a.output,
        field: a.field,
        seeds: a.seeds,
        step: a.step,
        integrator: a.integrator.into(),
        tolerance: a.tolerance,
        max_length: a.max_length,
        min_speed: a.min_speed,
        mask: a.mask,
        threshold: a.threshold,
        max_angle: a.max_angle,
        eigen: a.eigen,
        one_way: a.one_way,
    };
    let time = TimeArgs {
        pathlines: a.pathlines,
        seed_times: a.seed_times,
        random_seed: a.random_seed,
        time_step: a.time_step,
        duration: a.duration,
        time_boundary: a.time_boundary,
        frame: a.frame,
    };
    let r = trace_to_file_with(&args, &time)?;
    for n in &r.notes {
        eprintln!("note: {n}");
    }
    if r.lines == 0 {
        eprintln!(
            "umbra: warning: no seed gave a line: each lay outside the grid or the mask, where \
             the speed is at most --min-speed, or stopped before its first step; the output \
             holds no streamline"
        );
    }
    eprintln!(
        "wrote {}: {} {}, {} points",
        args.output.display(),
        r.lines,
        if time.pathlines {
            "pathlines"
        } else {
            "streamlines"
        },
        r.points
    );
    Ok(())
}

/// The time options of `umbra trace` (the module doc says what they do).
#[derive(Clone, Debug)]
pub struct TimeArgs {
    pub pathlines: bool,
    /// `start`, a number, `random` or `random:T0:T1`.
    pub seed_times: String,
    pub random_seed: u64,
    pub time_step: Option<f64>,
    pub duration: Option<f64>,
    pub time_boundary: Option<TimeBoundary>,
    pub frame: Option<usize>,
}

impl Default for TimeArgs {
    /// Streamlines, seeds at the field's first time, random seed 1.
    fn default() -> Self {
        TimeArgs {
            pathlines: false,
            seed_times: "start".into(),
            random_seed: 1,
            time_step: None,
            duration: None,
            time_boundary: None,
            frame: None,
        }
    }
}

/// What [`trace_to_file_with`] wrote.
#[derive(Clone, Debug, PartialEq)]
pub struct TraceReport {
    pub lines: usize,
    pub points: usize,
    /// What the user should know (attributes a format dropped, reader warnings).
    pub notes: Vec<String>,
    /// The time step pathlines were traced with.
    pub time_step: Option<f64>,
    /// How long each pathline followed its particle, each way.
    pub duration: Option<f64>,
}

/// What `umbra trace` is asked to do.
#[derive(Clone, Debug)]
pub struct TraceArgs {
    pub input: PathBuf,
    pub output: PathBuf,
    pub field: Option<String>,
    pub seeds: String,
    pub step: Option<f64>,
    pub integrator: Integrator,
    pub tolerance: f64,
    pub max_length: Option<f64>,
    pub min_speed: f64,
    pub mask: Option<PathBuf>,
    pub threshold: f64,
    pub max_angle: f64,
    pub eigen: bool,
    pub one_way: bool,
}

/// Seeds from a specification: `grid:N` (N^3 lattice), `random:N` (drawn with generator seed
/// `rng`), `plane:x=V:N` (an N x N lattice on a plane of constant x, y or z), or a CSV file of
/// `x,y,z` lines.
pub fn parse_seeds(spec: &str, bounds: [DVec3; 2], rng: u64) -> Result<Vec<DVec3>, String> {
    let num = |s: &str| match s.parse::<usize>() {
        Ok(n) if (1..=10_000_000).contains(&n) => Ok(n),
        Ok(_) => Err(format!("--seeds {spec}: {s} seeds: give 1 to 10,000,000")),
        Err(_) => Err(format!("--seeds {spec}: '{s}' is not a count")),
    };
    if let Some(n) = spec.strip_prefix("grid:") {
        if n == "0" {
            return Err(format!("--seeds {spec}: give grid:1 to grid:200"));
        }
        let n = num(n)?;
        if n > 200 {
            return Err(format!(
                "--seeds {spec}: at most grid:200 (8 million seeds)"
            ));
        }
        return Ok(grid_seeds(bounds, n));
    }
    if let Some(n) = spec.strip_prefix("random:") {
        return Ok(random_seeds(bounds, num(n)?, rng));
    }
    if let Some(rest) = spec.strip_prefix("plane:") {
        let (eq, n) = rest
            .split_once(':')
            .ok_or_else(|| format!("--seeds {spec}: use plane:x=VALUE:N"))?;
        let (axis, value) = eq
            .split_once('=')
            .ok_or_else(|| format!("--seeds {spec}: use plane:x=VALUE:N"))?;
        let a = match axis {
            "x" => 0,
            "y" => 1,
            "z" => 2,
            _ => return Err(format!("--seeds {spec}: the axis is x, y or z")),
        };
        let v: f64 = value
            .parse()
            .ok()
            .filter(|v: &f64| v.is_finite())
            .ok_or_else(|| format!("--seeds {spec}: '{value}' is not a finite number"))?;
        if !(bounds[0][a]..=bounds[1][a]).contains(&v) {
            return Err(format!(
                "--seeds {spec}: the plane misses the grid, which spans {} to {} along {axis}",
                bounds[0][a], bounds[1][a]
            ));
        }
        let n = num(n)?;
        if n > 3000 {
            return Err(format!(
                "--seeds {spec}: at most {}3000 (9 million seeds)",
                spec.strip_suffix(&n.to_string())
                    .unwrap_or("plane:x=VALUE:")
            ));
        }
        let (u, w) = ((a + 1) % 3, (a + 2) % 3);
        let mut out = Vec::with_capacity(n * n);
        for i in 0..n {
            for j in 0..n {
                let mut p = DVec3::ZERO;
                p[a] = v;
                p[u] = bounds[0][u] + (bounds[1][u] - bounds[0][u]) * (i as f64 + 0.5) / n as f64;
                p[w] = bounds[0][w] + (bounds[1][w] - bounds[0][w]) * (j as f64 + 0.5) / n as f64;
                out.push(p);
            }
        }
        return Ok(out);
    }
    let path = Path::new(spec);
    let text = volume::read_text(path, volume::MAX_FILE_BYTES).map_err(|e| format!("--seeds {spec}: not grid:N, random:N or plane:x=V:N, and not a readable CSV file ({e})"))?;
    let mut out = Vec::new();
    let mut header_allowed = true;
    for (ln, line) in text.lines().enumerate() {
        let t = line.trim();
        if t.is_empty() || t.starts_with('#') {
            continue;
        }
        // x, y and z: the first three fields (further columns, a label say, are ignored).
        let v: Result<Vec<f64>, _> = t
            .split(|c: char| c == ',' || c.is_whitespace())
            .filter(|s| !s.is_empty())
            .take(3)
            .map(|s| s.parse::<f64>())
            .collect();
        // The first line that is not numbers is a header ("x,y,z"); "nan" and "inf" are
        // numbers (refused below), not a header to skip.
        let first = std::mem::replace(&mut header_allowed, false);
        let v = match v {
            Ok(v) => v,
            Err(_) if first && t.chars().next().is_some_and(|c| c.is_alphabetic()) => continue,
            Err(_) => {
                return Err(format!(
                    "{spec}: line {}: expected x,y,z (three numbers, then any further columns)",
                    ln + 1
                ))
            }
        };
        if v.len() < 3 || !v[..3].iter().all(|x| x.is_finite()) {
            return Err(format!(
                "{spec}: line {}: expected three finite numbers",
                ln + 1
            ));
        }
        out.push(DVec3::new(v[0], v[1], v[2]));
    }
    Ok(out)
}

/// Seed times from `--seed-times` for `n` seeds: `start` (`start`), a number, `random` (uniform
/// over `[start, start + span)`; refused when `span` is 0) or `random:T0:T1`.
pub fn parse_seed_times(
    spec: &str,
    n: usize,
    start: f64,
    span: f64,
    rng: u64,
) -> Result<Vec<f64>, String> {
    let number = |s: &str| {
        s.trim()
            .parse::<f64>()
            .ok()
            .filter(|v| v.is_finite())
            .ok_or_else(|| format!("--seed-times {spec}: '{s}' is not a finite number"))
    };
    if spec == "start" {
        return Ok(vec![start; n]);
    }
    if spec == "random" {
        if span <= 0.0 {
            return Err(format!(
                "--seed-times {spec}: the field is steady and has no time span; give random:T0:T1"
            ));
        }
        return Ok(random_times(start, start + span, n, rng));
    }
    if let Some(range) = spec.strip_prefix("random:") {
        let (lo, hi) = range
            .split_once(':')
            .ok_or_else(|| format!("--seed-times {spec}: use random:T0:T1"))?;
        let (lo, hi) = (number(lo)?, number(hi)?);
        if hi <= lo {
            return Err(format!("--seed-times {spec}: T1 must be greater than T0"));
        }
        return Ok(random_times(lo, hi, n, rng));
    }
    let t = number(spec)
        .map_err(|_| format!("--seed-times {spec}: use start, a number, random or random:T0:T1"))?;
    Ok(vec![t; n])
}

/// Traces the streamlines `a` asks for and writes them; returns the number of streamlines and
/// points written. Seeds start at the field's first time (see [`trace_to_file_with`]).
pub fn trace_to_file(a: &TraceArgs) -> Result<(usize, usize), String> {
    let r = trace_to_file_with(a, &TimeArgs::default())?;
    Ok((r.lines, r.points))
}

/// Traces the streamlines, or with `t.pathlines` the pathlines, that `a` and `t` ask for, with
/// the point attributes `time` and `speed`, and writes them.
pub fn trace_to_file_with(a: &TraceArgs, t: &TimeArgs) -> Result<TraceReport, String> {
    // Settings and the output first, before the field is read: the tracer's own check on the
    // values given (the step and length defaults, computed from the field, are checked again
    // below). A NaN tolerance or length gave 0 streamlines without a word.
    TraceOptions {
        integrator: a.integrator,
        step: a.step.unwrap_or(1.0),
        tolerance: a.tolerance,
        max_length: a.max_length.unwrap_or(1.0),
        min_speed: a.min_speed,
        max_angle_deg: a.max_angle,
        orient: a.eigen,
        mask: None,
        both_ways: !a.one_way,
    }
    .check()?;
    if !a.threshold.is_finite() {
        return Err(format!(
            "threshold {}: must be a finite number",
            a.threshold
        ));
    }
    volume::check_output(&a.output)?;
    volume::check_not_input(
        &[Some(a.input.as_path()), a.mask.as_deref()],
        &[Some(a.output.as_path())],
    )?;
    let mut series = volume::load_series(&a.input).map_err(|e| e.to_string())?;
    if let Some(b) = t.time_boundary {
        series.periodic = b == TimeBoundary::Periodic;
    }
    let sel: Option<volume::FieldSelector> = a
        .field
        .as_deref()
        .map(|s| s.parse().map_err(|e: volume::VolumeError| e.to_string()))
        .transpose()?;
    let mask_vol = a
        .mask
        .as_ref()
        .map(|p| volume::load(p).map_err(|e| e.to_string()))
        .transpose()?;
    let mask = mask_vol
        .as_ref()
        .map(|v| {
            GridScalar::from_volume(v).map_err(|e| {
                format!(
                    "{}: {e}",
                    a.mask.as_deref().unwrap_or(Path::new("")).display()
                )
            })
        })
        .transpose()?;
    let mut notes: Vec<String> = series
        .warnings
        .iter()
        .map(|w| format!("{}: {w}", a.input.display()))
        .collect();
    let grid = (series.frames[0].dims, series.frames[0].affine);
    if grid.0.iter().all(|&n| n == 1) {
        return Err(format!(
            "{}: a grid of one sample has no extent to trace streamlines in",
            a.input.display()
        ));
    }
    let budget = point_budget();
    let (mut s, time_step, duration) = if t.pathlines {
        if t.frame.is_some() {
            return Err(
                "--frame picks one frame for streamlines; --pathlines uses them all".into(),
            );
        }
        if a.step.is_some() {
            return Err(
                "--step is the streamlines' arc-length step; pathlines take --time-step".into(),
            );
        }
        if a.eigen {
            return Err(
                "--eigen: an eigenvector field has no direction in time to follow with --pathlines"
                    .into(),
            );
        }
        let integrator = match a.integrator {
            Integrator::Rk4 => PathIntegrator::Rk4,
            Integrator::Euler => PathIntegrator::Euler,
            Integrator::Rk45 => {
                return Err("--integrator rk45: pathlines integrate with rk4 or euler".into())
            }
        };
        let f = SeriesField::from_series(&series, sel.as_ref())
            .map_err(|e| format!("{}: {e}", a.input.display()))?;
        let span = series.span();
        let vmax = f.max_speed();
        if vmax <= 0.0 {
            return Err(format!(
                "{}: the vectors are zero or not finite everywhere, in every frame: no pathline \
                 to trace",
                a.input.display()
            ));
        }
        let time_step = match t.time_step {
            Some(h) => h,
            None => {
                let cross = 0.5 * f.min_spacing() / vmax;
                if span > 0.0 {
                    (span / 200.0).min(cross)
                } else {
                    cross
                }
            }
        };
        let duration = t
            .duration
            .unwrap_or(if span > 0.0 { span } else { 200.0 * time_step });
        let [lo, hi] = f.bounds();
        let max_length = a.max_length.unwrap_or(2.0 * (hi - lo).length());
        let seeds = parse_seeds(&a.seeds, f.bounds(), t.random_seed)?;
        let times = parse_seed_times(&t.seed_times, seeds.len(), series.t0, span, t.random_seed)?;
        let timed: Vec<(DVec3, f64)> = seeds.into_iter().zip(times).collect();
        let o = PathlineOptions {
            integrator,
            time_step,
            duration,
            max_length,
            min_speed: a.min_speed,
            max_angle_deg: a.max_angle,
            mask: mask.as_ref().map(|m| (m, a.threshold)),
            both_ways: !a.one_way,
        };
        let s = pathlines_within(&f, &timed, &o, budget.0)
            .map_err(|e| too_many(&a.input, timed.len(), e.points, budget))?;
        (s, Some(time_step), Some(duration))
    } else {
        if t.time_step.is_some() || t.duration.is_some() {
            return Err("--time-step and --duration are for --pathlines".into());
        }
        let k = match t.frame {
            Some(k) if k >= series.len() => {
                return Err(format!(
                    "--frame {k}: {} has {} frame(s)",
                    a.input.display(),
                    series.len()
                ))
            }
            Some(k) => k,
            None if series.len() > 1 => {
                return Err(format!(
                    "{}: a time series of {} vector fields: trace pathlines with --pathlines, or \
                     the streamlines of one frame with --frame K",
                    a.input.display(),
                    series.len()
                ))
            }
            None => 0,
        };
        let vol = &series.frames[k];
        let f = GridField::from_volume(vol, sel.as_ref())
            .map_err(|e| format!("{}: {e}", a.input.display()))?;
        if f.max_speed() == 0.0 {
            return Err(format!(
                "{}: the vectors are zero or not finite everywhere: no streamline to trace",
                a.input.display()
            ));
        }
        let step = a.step.unwrap_or(0.5 * f.min_spacing());
        if !(step.is_finite() && step > 0.0) {
            return Err(format!("--step {step}: must be positive"));
        }
        let [lo, hi] = f.bounds();
        let max_length = a.max_length.unwrap_or(2.0 * (hi - lo).length());
        let seeds = parse_seeds(&a.seeds, f.bounds(), t.random_seed)?;
        let times = parse_seed_times(
            &t.seed_times,
            seeds.len(),
            series.time(k),
            series.span(),
            t.random_seed,
        )?;
        let timed: Vec<(DVec3, f64)> = seeds.into_iter().zip(times).collect();
        let o = TraceOptions {
            integrator: a.integrator,
            step,
            tolerance: a.tolerance,
            max_length,
            min_speed: a.min_speed,
            max_angle_deg: a.max_angle,
            orient: a.eigen,
            mask: mask.as_ref().map(|m| (m, a.threshold)),
            both_ways: !a.one_way,
        };
        o.check()?;
        let s = trace_at_within(&f, &timed, &o, budget.0)
            .map_err(|e| too_many(&a.input, timed.len(), e.points, budget))?;
        (s, None, None)
    };
    s.format = String::new();
    // The field's grid as the tractogram's reference space (a .trk header's dimensions, voxel
    // sizes and vox_to_ras, TRX's header), as the tools that place lines by it expect.
    s.reference = tubes::trk::grid_space(grid.0, grid.1);
    notes.extend(std::mem::take(&mut s.warnings));
    notes.extend(super::tck_drops_note(&a.output, &s));
    if series.frames[0].space != volume::Space::Ras {
        // TrackVis, MRtrix and TRX files hold RAS+ millimetres; a CFD field's frame is its own.
        notes.push(format!(
            "{}: the field's frame is its own, not RAS+ mm; {} stores its points as they are, \
             in a format read as RAS+ mm: a scene of these lines alone labels lengths \
             \"mm\" (set annotate.units to the field's unit)",
            a.input.display(),
            a.output.display()
        ));
    }
    tubes::save(&a.output, &s).map_err(|e| e.to_string())?;
    Ok(TraceReport {
        lines: s.len(),
        points: s.points.len(),
        notes,
        time_step,
        duration,
    })
}

/// Bytes a traced point takes at the peak: its sample while traced (position, time and speed
/// in f64, with the growth of its line's buffer), the tractogram's point and attributes, and
/// the writer's bytes: 82 bytes a point measured, rounded up (README, `umbra trace`: 772 MB at
/// the peak for 9.43 M points of 10^5 seeds through the blunt fin's velocity at 64^3).
const BYTES_PER_POINT: u64 = 100;

/// The most points a trace may hold, and the memory that sets it (`None`: no limit known).
fn point_budget() -> (usize, Option<(u64, &'static str)>) {
    match scene::tube_sets::memory_budget() {
        Some((bytes, why)) => ((bytes / BYTES_PER_POINT) as usize, Some((bytes, why))),
        None => (usize::MAX, None),
    }
}

/// The error of a trace stopped at `points` points of `seeds` seeds' lines.
fn too_many(
    input: &Path,
    seeds: usize,
    points: usize,
    budget: (usize, Option<(u64, &'static str)>),
) -> String {
    let (bytes, why) = budget.1.unwrap_or((0, "of memory"));
    format!(
        "{}: the lines of {seeds} seeds do not fit in memory: {points} points when tracing \
         stopped, at about {BYTES_PER_POINT} bytes a point, more than the {:.1} GB {why}; \
         trace fewer seeds or shorter lines (--max-length)",
        input.display(),
        bytes as f64 / 1e9
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A seed file's first line may be a header; after it every line is three finite numbers
    /// (`nan,2,1` was skipped as a header, silently).
    #[test]
    fn seed_files_refuse_non_finite_rows_and_a_second_header() {
        let dir = tempfile::tempdir().unwrap();
        let b = [DVec3::ZERO, DVec3::ONE];
        let parse = |text: &str| {
            let p = dir.path().join("s.csv");
            std::fs::write(&p, text).unwrap();
            parse_seeds(p.to_str().unwrap(), b, 1)
        };
        let ok = parse("# seeds\nx,y,z\n0.5,0,0\n\n0.25 0 0.1\n").unwrap();
        assert_eq!(ok, [DVec3::new(0.5, 0.0, 0.0), DVec3::new(0.25, 0.0, 0.1)]);
        // Further columns are ignored, a label among them.
        let ok = parse("x,y,z,roi\n0,0.5,1,left\n1 2 3 right 7\n").unwrap();
        assert_eq!(ok, [DVec3::new(0.0, 0.5, 1.0), DVec3::new(1.0, 2.0, 3.0)]);
        for (text, line) in [
            ("x,y,z\nnan,2,1\n", 2),
            ("inf,2,1\n", 1),
            ("0,0,0\n1,-inf,0\n", 2),
            ("x,y,z\n0,0,0\nx,y,z\n", 3),
            ("0,0,0\nseed,1,2\n", 2),
        ] {
            let e = parse(text).unwrap_err();
            assert!(e.contains(&format!("line {line}:")), "{text:?}: {e}");
        }
    }

    #[test]
    fn seed_times_are_constant_or_drawn_deterministically_in_their_range() {
        assert_eq!(parse_seed_times("start", 3, 1.5, 0.0, 1).unwrap(), [1.5; 3]);
        assert_eq!(parse_seed_times("-2", 2, 1.5, 0.0, 1).unwrap(), [-2.0; 2]);
        let a = parse_seed_times("random", 500, 2.0, 10.0, 7).unwrap();
        assert_eq!(a, parse_seed_times("random", 500, 2.0, 10.0, 7).unwrap());
        assert_ne!(a, parse_seed_times("random", 500, 2.0, 10.0, 8).unwrap());
        assert!(a.iter().all(|&t| (2.0..12.0).contains(&t)));
        let mean = a.iter().sum::<f64>() / a.len() as f64;
        assert!((mean - 7.0).abs() < 0.5, "mean {mean}");
        let b = parse_seed_times("random:-1:1", 100, 0.0, 0.0, 1).unwrap();
        assert!(b.iter().all(|&t| (-1.0..1.0).contains(&t)));
        for bad in [
            "random",
            "random:1",
            "random:2:1",
            "random:0:inf",
            "soon",
            "nan",
        ] {
            assert!(parse_seed_times(bad, 1, 0.0, 0.0, 1).is_err(), "{bad}");
        }
    }

    /// Seed counts past the limits are refused with the limit, never clamped silently.
    #[test]
    fn seed_counts_past_their_limits_say_the_limit() {
        let b = [DVec3::ZERO, DVec3::ONE];
        assert_eq!(parse_seeds("plane:z=0.5:3", b, 1).unwrap().len(), 9);
        assert_eq!(parse_seeds("random:7", b, 1).unwrap().len(), 7);
        for (spec, want) in [
            ("random:16000000", "16000000 seeds: give 1 to 10,000,000"),
            ("random:0", "0 seeds: give 1 to 10,000,000"),
            ("random:many", "'many' is not a count"),
            (
                "plane:z=0.5:100000",
                "at most plane:z=0.5:3000 (9 million seeds)",
            ),
            (
                "plane:z=20:10",
                "the plane misses the grid, which spans 0 to 1 along z",
            ),
            ("grid:201", "at most grid:200"),
            ("grid:0", "give grid:1 to grid:200"),
        ] {
            let e = parse_seeds(spec, b, 1).unwrap_err();
            assert!(e.contains(want), "{spec}: {e}");
        }
    }
}
