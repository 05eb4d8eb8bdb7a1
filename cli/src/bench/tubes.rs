//! `umbra bench tubes <tractogram> --tolerances T1,T2 -o <dir>`: the stream tubes' cost against
//! their accuracy over fitting tolerances.

use super::chart::{write_chart, Plot};
use crate::commands::list_item;
use crate::output::out;
use std::io::Write as _;
use std::path::{Path, PathBuf};

/// `umbra bench tubes`.
#[derive(clap::Args)]
pub struct Args {
    /// Tractogram.
    input: PathBuf,
    #[arg(
        long,
        value_delimiter = ',',
        value_parser = list_item::<f64>,
        default_value = "0.005,0.01,0.02,0.05,0.1,0.2"
    )]
    tolerances: Vec<f64>,
    #[arg(long, default_value_t = 0.5)]
    radius: f64,
    /// Meshing runs per tolerance (the median is reported).
    #[arg(long, default_value_t = 3)]
    runs: usize,
    #[arg(short, long)]
    output: PathBuf,
}

pub fn run(a: Args) -> Result<(), String> {
    if a.runs == 0 {
        return Err("--runs: must be at least 1".into());
    }
    for r in tubes(&a.input, &a.tolerances, a.radius, a.runs, &a.output)? {
        out(format!(
            "tolerance {:8}  control points {:9}  triangles {:10}  max deviation {:.5}  {:.1} ms",
            r.tolerance, r.control_points, r.triangles, r.max_deviation, r.ms
        ))?;
    }
    eprintln!(
        "wrote {0}/tubes.csv, {0}/tubes.svg, {0}/tubes.png",
        a.output.display()
    );
    Ok(())
}

/// One tolerance of `bench tubes`.
#[derive(Clone, Debug)]
pub struct TubesRow {
    pub tolerance: f64,
    pub control_points: usize,
    pub triangles: usize,
    pub max_deviation: f64,
    /// Median meshing time.
    pub ms: f64,
}

/// `umbra bench tubes <tractogram> --tolerances T1,T2 -o <dir>`: the stream tubes' cost
/// against their accuracy: for each fitting tolerance, the control points, triangles, the
/// exact largest deviation of the B-splines from the streamlines, and the meshing time
/// (median of `runs`); `<dir>/tubes.csv` and the chart `<dir>/tubes.svg|png` (deviation against
/// triangles).
pub fn tubes(
    input: &Path,
    tolerances: &[f64],
    radius: f64,
    runs: usize,
    out: &Path,
) -> Result<Vec<TubesRow>, String> {
    let s = tubes::load(input).map_err(|e| e.to_string())?;
    // A table of zeros would read as a measurement.
    if s.points.is_empty() {
        return Err(format!(
            "{}: no streamline points: nothing to mesh",
            input.display()
        ));
    }
    std::fs::create_dir_all(out).map_err(|e| format!("{}: {e}", out.display()))?;
    let mut rows = vec![];
    for &tol in tolerances {
        if !(tol > 0.0 && tol.is_finite()) {
            return Err(format!("--tolerances: {tol} is not positive"));
        }
        // As `umbra tubes` meshes by default: no caps (the scene's tubes have them), so
        // that its counts are the command's (they differed by the caps' triangles).
        let mut args = scene::tube_sets::TubesArgs::defaults(radius, 8, tol, "direction");
        args.caps = false;
        let mut times = vec![];
        let mut stats = None;
        for _ in 0..runs.max(1) {
            let t = std::time::Instant::now();
            let (_, st) = scene::tube_sets::build_mesh(&s, &args)?;
            times.push(t.elapsed().as_secs_f64() * 1e3);
            stats = Some(st);
        }
        let st = stats.unwrap();
        rows.push(TubesRow {
            tolerance: tol,
            control_points: st.control_points,
            triangles: st.triangles,
            max_deviation: st.max_deviation,
            ms: engine::renderer::median(&times),
        });
    }
    let mut csv = Vec::new();
    let _ = writeln!(csv, "tolerance,control_points,triangles,max_deviation,ms");
    for r in &rows {
        let _ = writeln!(
            csv,
            "{},{},{},{:.6},{:.2}",
            r.tolerance, r.control_points, r.triangles, r.max_deviation, r.ms
        );
    }
    volume::write_atomic(&out.join("tubes.csv"), &csv).map_err(|e| e.to_string())?;
    write_chart(
        out,
        "tubes",
        &Plot {
            title: format!(
                "{}: deviation against triangles",
                input.file_name().unwrap_or_default().to_string_lossy()
            ),
            x_label: "triangles".into(),
            y_label: "largest deviation from the streamlines (world units)".into(),
            series: vec![(
                "B-spline tubes, tolerance swept".into(),
                rows.iter()
                    .map(|r| (r.triangles as f64, r.max_deviation.max(1e-9)))
                    .collect(),
            )],
            line: None,
        },
    )?;
    Ok(rows)
}
