//! `umbra tubes`: B-spline stream tubes of a tractogram (`scene::tube_sets`), written as PLY or
//! OBJ, with statistics.

use clap::builder::RangedU64ValueParser;
use std::path::{Path, PathBuf};
use tubes::bspline_fit::FitMethod;
use tubes::tube_mesh::{FrameMethod, RadiusMode};

#[derive(clap::Args)]
pub struct Args {
    /// Input tractogram.
    input: PathBuf,
    /// Output mesh: .ply (binary) or .obj.
    #[arg(short, long)]
    output: PathBuf,
    /// Tube radius (world units).
    #[arg(long, default_value_t = 0.5, value_parser = super::positive)]
    radius: f64,
    /// Sides of a ring.
    #[arg(long, default_value_t = 8, value_parser = RangedU64ValueParser::<usize>::new().range(3..=256))]
    sides: usize,
    /// Rings per B-spline span before adaptive refinement (spans are bisected until the
    /// tangent turns by at most 15 degrees between rings).
    #[arg(long, default_value_t = 1, value_parser = RangedU64ValueParser::<usize>::new().range(1..=64))]
    per_span: usize,
    /// Largest distance of an input point to the fitted curve (world units).
    #[arg(long, default_value_t = 0.05, value_parser = super::positive)]
    tolerance: f64,
    /// Error-bounded tessellation: sides and ring spacing from this chordal tolerance.
    #[arg(long, conflicts_with = "sides")]
    chordal: Option<f64>,
    /// Curve fit: iterative (the paper's), least-squares, or none.
    #[arg(
        long,
        value_enum,
        default_value = "iterative",
        hide_possible_values = true
    )]
    fit: Fit,
    /// Frames: rmf (rotation minimizing) or frenet (with flip correction).
    #[arg(long, value_enum, default_value = "rmf", hide_possible_values = true)]
    frame: Frame,
    /// Radius limit: local (per ring, below 1/curvature) or global (the paper's 1/kappa_max).
    #[arg(long, value_enum, default_value = "local", hide_possible_values = true)]
    radius_mode: Radius,
    /// Colour: direction, scalar:NAME, volume:PATH, or #rrggbb.
    #[arg(long, default_value = "direction")]
    color: String,
    /// Colour map of scalar:NAME and volume:PATH colours: grey, viridis, magma, inferno,
    /// plasma, cool-warm, hot, red-yellow, blue-lightblue (default: the built-in viridis-like
    /// ramp).
    #[arg(long)]
    colormap: Option<String>,
    /// Close the tube ends.
    #[arg(long)]
    caps: bool,
    /// Row-major 4x4 transform applied to the points, as 16 comma-separated numbers.
    #[arg(long, allow_hyphen_values = true, value_parser = parse_transform)]
    transform: Option<[f64; 16]>,
    /// Write the statistics as JSON to this file.
    #[arg(long)]
    stats_json: Option<PathBuf>,
}

/// `--fit`.
#[derive(Clone, Copy, Debug, clap::ValueEnum)]
enum Fit {
    Iterative,
    LeastSquares,
    #[value(name = "none")]
    Unfitted,
}

impl From<Fit> for FitMethod {
    fn from(f: Fit) -> Self {
        match f {
            Fit::Iterative => FitMethod::Iterative,
            Fit::LeastSquares => FitMethod::LeastSquares,
            Fit::Unfitted => FitMethod::None,
        }
    }
}

/// `--frame`.
#[derive(Clone, Copy, Debug, clap::ValueEnum)]
enum Frame {
    Rmf,
    Frenet,
}

impl From<Frame> for FrameMethod {
    fn from(f: Frame) -> Self {
        match f {
            Frame::Rmf => FrameMethod::Rmf,
            Frame::Frenet => FrameMethod::Frenet,
        }
    }
}

/// `--radius-mode`.
#[derive(Clone, Copy, Debug, clap::ValueEnum)]
enum Radius {
    Local,
    Global,
}

impl From<Radius> for RadiusMode {
    fn from(r: Radius) -> Self {
        match r {
            Radius::Local => RadiusMode::Local,
            Radius::Global => RadiusMode::Global,
        }
    }
}

/// `--transform`: 16 comma-separated numbers.
fn parse_transform(t: &str) -> Result<[f64; 16], String> {
    let v: Vec<f64> = t
        .split(',')
        .map(|x| x.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|_| "16 comma-separated numbers".to_string())?;
    <[f64; 16]>::try_from(v).map_err(|_| "16 comma-separated numbers".to_string())
}

pub fn run(a: Args) -> Result<(), String> {
    if let Some(m) = &a.transform {
        scene::tube_sets::transform_matrix(m, "--transform")?;
    }
    let args = scene::tube_sets::TubesArgs {
        input: a.input,
        output: a.output,
        radius: a.radius,
        sides: a.sides,
        per_span: a.per_span,
        tolerance: a.tolerance,
        chordal: a.chordal,
        fit: a.fit.into(),
        frame: a.frame.into(),
        radius_mode: a.radius_mode.into(),
        color: a.color,
        colormap: a
            .colormap
            .as_deref()
            .map(|c| c.parse().map_err(|e| format!("--colormap: {e}")))
            .transpose()?,
        caps: a.caps,
        transform: a.transform,
    };
    volume::check_outputs(&[Some(args.output.as_path()), a.stats_json.as_deref()])?;
    // The colour volume of `volume:PATH` is an input too.
    let colour_volume = args.color.strip_prefix("volume:").map(Path::new);
    volume::check_not_input(
        &[Some(args.input.as_path()), colour_volume],
        &[Some(args.output.as_path()), a.stats_json.as_deref()],
    )?;
    if args.colormap.is_some()
        && !(args.color.starts_with("scalar:") || args.color.starts_with("volume:"))
    {
        eprintln!(
            "umbra: note: --colormap colours scalar:NAME and volume:PATH values; with --color {} it changes nothing",
            args.color
        );
    }
    // The library names the colouring ("colour #12345: ..."); the command line names the flag.
    let s = scene::tube_sets::run(&args).map_err(|e| match e.starts_with("colour ") {
        true => format!("--color: {e}"),
        false => e,
    })?;
    for w in &s.warnings {
        eprintln!("umbra: warning: {}: {w}", args.input.display());
    }
    if let Some(p) = a.stats_json {
        let json = serde_json::to_string_pretty(&s).map_err(|e| e.to_string())?;
        volume::write_atomic(&p, json.as_bytes()).map_err(|e| e.to_string())?;
    }
    eprintln!(
        "wrote {}: {} tubes, {} triangles, {} control points for {} points, max deviation {:.4}, {:.2} s",
        args.output.display(),
        s.stats.streamlines_out,
        s.stats.triangles,
        s.stats.control_points,
        s.stats.points_in,
        s.stats.max_deviation,
        s.seconds.total
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn transforms_are_sixteen_numbers() {
        let id = "1,0,0,0, 0,1,0,0, 0,0,1,0, 0,0,0,1";
        assert_eq!(parse_transform(id).unwrap()[5], 1.0);
        for bad in ["1,2,3", "1,0,0,0,0,1,0,0,0,0,1,0,0,0,0,x"] {
            assert_eq!(
                parse_transform(bad).unwrap_err(),
                "16 comma-separated numbers"
            );
        }
    }
}
