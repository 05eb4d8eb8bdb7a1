//! `umbra trace`: streamlines through a vector field (see `tubes::trace`).

use glam::DVec3;
use std::path::{Path, PathBuf};
use tubes::trace::{
    grid_seeds, random_seeds, trace, GridField, GridScalar, Integrator, TraceOptions,
};

#[derive(clap::Args)]
pub struct Args {
    /// Vector field: any volume with a 3-component array (NIfTI V1, VTK vectors, ...).
    input: PathBuf,
    /// Output tractogram (.tck or .trk).
    #[arg(short, long)]
    output: PathBuf,
    /// The vector array, by name.
    #[arg(long)]
    field: Option<String>,
    /// Seeds: grid:N, random:N, plane:x=VALUE:N (also y, z), or a CSV file of x,y,z.
    #[arg(long, default_value = "grid:10")]
    seeds: String,
    /// Step in world units (default: half the smallest voxel spacing).
    #[arg(long)]
    step: Option<f64>,
    /// Integrator: rk4, rk45 (adaptive) or euler.
    #[arg(long, value_enum, default_value = "rk4", hide_possible_values = true)]
    integrator: IntegratorArg,
    /// RK45 local error bound (world units).
    #[arg(long, default_value_t = 1e-3)]
    tolerance: f64,
    /// Longest streamline (world units; default: twice the grid's diagonal).
    #[arg(long)]
    max_length: Option<f64>,
    /// Stop where the field's magnitude falls below this.
    #[arg(long, default_value_t = 1e-6)]
    min_speed: f64,
    /// Stop where this scalar volume (e.g. FA) falls below --threshold.
    #[arg(long)]
    mask: Option<PathBuf>,
    #[arg(long, default_value_t = 0.2)]
    threshold: f64,
    /// Stop where the direction turns by more than this many degrees in one step.
    #[arg(long, default_value_t = 60.0)]
    max_angle: f64,
    /// The field is an eigenvector field (no sign): orient it along the direction of travel.
    #[arg(long)]
    eigen: bool,
    /// Trace forward only (default: both ways from each seed).
    #[arg(long)]
    one_way: bool,
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
    let (n, p) = trace_to_file(&args)?;
    eprintln!(
        "wrote {}: {n} streamlines, {p} points",
        args.output.display()
    );
    Ok(())
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

/// Seeds from a specification: `grid:N` (N^3 lattice), `random:N`, `plane:x=V:N` (an N x N
/// lattice on a plane of constant x, y or z), or a CSV file of `x,y,z` lines.
pub fn parse_seeds(spec: &str, bounds: [DVec3; 2]) -> Result<Vec<DVec3>, String> {
    let num = |s: &str| {
        s.parse::<usize>()
            .ok()
            .filter(|&n| (1..=10_000_000).contains(&n))
            .ok_or_else(|| format!("--seeds {spec}: '{s}' is not a count"))
    };
    if let Some(n) = spec.strip_prefix("grid:") {
        let n = num(n)?;
        if n > 200 {
            return Err(format!(
                "--seeds {spec}: at most grid:200 (8 million seeds)"
            ));
        }
        return Ok(grid_seeds(bounds, n));
    }
    if let Some(n) = spec.strip_prefix("random:") {
        return Ok(random_seeds(bounds, num(n)?, 1));
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
            .map_err(|_| format!("--seeds {spec}: '{value}' is not a number"))?;
        let n = num(n)?.min(3000);
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
    let text = std::fs::read_to_string(path).map_err(|e| format!("--seeds {spec}: not grid:N, random:N or plane:x=V:N, and not a readable CSV file ({e})"))?;
    let mut out = Vec::new();
    for (ln, line) in text.lines().enumerate() {
        let t = line.trim();
        if t.is_empty() || t.starts_with('#') || t.chars().next().is_some_and(|c| c.is_alphabetic())
        {
            continue;
        }
        let v: Vec<f64> = t
            .split(|c: char| c == ',' || c.is_whitespace())
            .filter(|s| !s.is_empty())
            .map(|s| s.parse::<f64>())
            .collect::<Result<_, _>>()
            .map_err(|_| format!("{spec}: line {}: expected x,y,z", ln + 1))?;
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

/// Traces the streamlines `a` asks for and writes them; returns the number of streamlines and
/// points written.
pub fn trace_to_file(a: &TraceArgs) -> Result<(usize, usize), String> {
    let vol = volume::load(&a.input).map_err(|e| e.to_string())?;
    let sel: Option<volume::FieldSelector> = a
        .field
        .as_deref()
        .map(|s| s.parse().map_err(|e: volume::VolumeError| e.to_string()))
        .transpose()?;
    let f = GridField::from_volume(&vol, sel.as_ref())
        .map_err(|e| format!("{}: {e}", a.input.display()))?;
    let mask_vol = a
        .mask
        .as_ref()
        .map(|p| volume::load(p).map_err(|e| e.to_string()))
        .transpose()?;
    let mask = mask_vol.as_ref().map(GridScalar::from_volume).transpose()?;
    let step = a.step.unwrap_or(0.5 * f.min_spacing());
    if !(step.is_finite() && step > 0.0) {
        return Err(format!("--step {step}: must be positive"));
    }
    let [lo, hi] = f.bounds();
    let max_length = a.max_length.unwrap_or(2.0 * (hi - lo).length());
    let seeds = parse_seeds(&a.seeds, f.bounds())?;
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
    let mut s = trace(&f, &seeds, &o);
    s.format = String::new();
    tubes::save(&a.output, &s).map_err(|e| e.to_string())?;
    Ok((s.len(), s.points.len()))
}
