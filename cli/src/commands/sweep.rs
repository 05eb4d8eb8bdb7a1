//! `umbra sweep`: the signed distance and the eight octant occlusion fields of an isosurface
//! (`scene::fields`), written as NRRD, with a summary as text or JSON.

use crate::output::{out, out_json};
use crate::progress::Stages;
use std::path::PathBuf;
use volume::distance_sweep::{DistanceMethod, InitMethod};
use volume::FieldSelector;

#[derive(clap::Args)]
pub struct Args {
    /// Input volume (any format `umbra info` reads).
    input: PathBuf,
    /// Iso level.
    #[arg(long, allow_hyphen_values = true, value_parser = super::finite)]
    iso: f32,
    /// Output distance field: 3-D float32 NRRD, world units, negative inside.
    #[arg(short, long)]
    output: PathBuf,
    /// Output octant fields: 4-D uint8 NRRD, first axis the 8 octants in Table 1 order
    /// (default: <stem>.octants.nrrd beside the distance file).
    #[arg(long)]
    octants_out: Option<PathBuf>,
    /// Which side is inside (negative distance): values above (>=) or below (<=) the level.
    #[arg(long, value_enum, default_value = "above")]
    inside: super::Inside,
    /// Field to use: NAME, NAME:magnitude or NAME:x|y|z.
    #[arg(long, value_parser = super::field_selector)]
    field: Option<FieldSelector>,
    /// Write only the distance field.
    #[arg(long, conflicts_with_all = ["octants_out", "subsurface"])]
    sdf_only: bool,
    /// Initial distances next to the surface: gradient (default), plane, or edge (the paper).
    #[arg(
        long,
        value_enum,
        default_value = "gradient",
        hide_possible_values = true
    )]
    init: Init,
    /// How the distance reaches the grid from the voxels next to the surface: closest-point (the
    /// distance to the surface point of the nearest such voxel; one pass per axis) or sweeping
    /// (the paper's fast sweeping, rounds of eight sweeps to --tolerance).
    #[arg(long, value_enum, default_value = "closest-point")]
    distance: Distance,
    /// Convergence tolerance of the distance sweeps (--distance sweeping only), in voxels
    /// [default: 1e-3].
    #[arg(long, allow_hyphen_values = true, value_parser = super::positive32)]
    tolerance: Option<f32>,
    /// Subsurface variant: per-voxel opacity alpha in [0, 1] for the octant sweeps.
    #[arg(long, allow_hyphen_values = true, value_parser = super::unit)]
    subsurface: Option<f32>,
    /// Print the summary as one JSON object on standard output.
    #[arg(long)]
    json: bool,
}

/// `--init`.
#[derive(Clone, Copy, Debug, clap::ValueEnum)]
enum Init {
    Gradient,
    Plane,
    Edge,
}

/// `--distance`.
#[derive(Clone, Copy, Debug, clap::ValueEnum)]
enum Distance {
    ClosestPoint,
    Sweeping,
}

impl From<Distance> for DistanceMethod {
    fn from(d: Distance) -> Self {
        match d {
            Distance::ClosestPoint => DistanceMethod::ClosestPoint,
            Distance::Sweeping => DistanceMethod::Sweeping,
        }
    }
}

impl From<Init> for InitMethod {
    fn from(i: Init) -> Self {
        match i {
            Init::Gradient => InitMethod::Gradient,
            Init::Plane => InitMethod::Plane,
            Init::Edge => InitMethod::Edge,
        }
    }
}

/// Options that conflict by their values, which clap's `conflicts_with` cannot say: the
/// message for a usage error (exit status 2, as clap's conflicts), or none.
pub fn conflict(a: &Args) -> Option<&'static str> {
    (a.tolerance.is_some() && !matches!(a.distance, Distance::Sweeping)).then_some(
        "--tolerance is the convergence of --distance sweeping; closest points need none",
    )
}

pub fn run(a: Args) -> Result<(), String> {
    if let Some(c) = conflict(&a) {
        return Err(c.into());
    }
    let args = scene::fields::SweepArgs {
        input: a.input,
        iso: a.iso,
        output: a.output,
        octants_out: a.octants_out,
        inside: a.inside.into(),
        field: a.field,
        sdf_only: a.sdf_only,
        init: a.init.into(),
        method: a.distance.into(),
        tolerance: a.tolerance.unwrap_or(1e-3),
        subsurface_alpha: a.subsurface,
    };
    let progress = if a.json {
        Stages::hidden()
    } else {
        Stages::new(false)
    };
    let s = scene::fields::run(&args, &|m| progress.stage(m))?;
    drop(progress);
    for w in &s.warnings {
        eprintln!("umbra: warning: {}: {w}", args.input.display());
    }
    if a.json {
        return out_json(&s);
    }
    out(format!(
        "grid:        {} x {} x {}",
        s.dims[0], s.dims[1], s.dims[2]
    ))?;
    if s.distance_method == "sweeping" {
        out(format!(
            "iterations:  {} rounds of 8 sweeps ({})",
            s.iterations,
            if s.converged {
                "converged"
            } else {
                "not converged"
            }
        ))?;
    } else {
        out("method:      closest points of the band (no rounds)".to_string())?;
    }
    out(format!(
        "band:        {} voxels initialised next to the surface",
        s.band_voxels
    ))?;
    out(format!(
        "seconds:     read {:.3}, compute {:.3}, write {:.3}, total {:.3}",
        s.seconds.read, s.seconds.compute, s.seconds.write, s.seconds.total
    ))?;
    if let Some(p) = s.peak_bytes {
        out(format!(
            "peak memory: {:.1} MiB",
            p as f64 / (1024.0 * 1024.0)
        ))?;
    }
    out(format!("distance:    {}", s.distance.display()))?;
    if let Some(o) = &s.octants {
        out(format!("octants:     {}", o.display()))?;
    }
    Ok(())
}
