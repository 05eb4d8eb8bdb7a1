//! `umbra resample`: read a CFD grid (VTK XML or legacy rectilinear, curvilinear and
//! unstructured grids, PLOT3D), interpolate one array onto a regular grid over the mesh's
//! bounding box, and write it as NRRD or NIfTI. Samples outside the mesh are NaN.

use crate::output::{out, out_json_pretty};
use crate::progress::Stages;
use serde::Serialize;
use std::path::{Path, PathBuf};
use volume::VolumeError;

#[derive(clap::Args)]
pub struct Args {
    /// Grid file; any name other than .vtr/.vts/.vtu/.vtk is read as a PLOT3D grid.
    input: PathBuf,
    /// PLOT3D solution (q) file: gives density, momentum, energy, velocity, pressure.
    #[arg(long)]
    q: Option<PathBuf>,
    /// Array: NAME, NAME:magnitude, NAME:x|y|z, or three scalars A,B,C assembled into a
    /// vector (e.g. "X Velocity,Y Velocity,Z Velocity").
    #[arg(long)]
    field: String,
    /// Output dimensions NX,NY,NZ (default: --size on the longest side, equal spacing).
    #[arg(long, value_parser = parse_dims, conflicts_with = "size")]
    dims: Option<[usize; 3]>,
    /// Samples along the longest side when --dims is not given.
    #[arg(long, default_value_t = 128)]
    size: usize,
    /// Output volume (.nrrd, .nii, .nii.gz).
    #[arg(short, long)]
    output: PathBuf,
    /// Gzip-encode NRRD output.
    #[arg(long)]
    gzip: bool,
    /// Print the report as JSON.
    #[arg(long)]
    json: bool,
}

pub fn run(a: Args) -> Result<(), String> {
    let progress = if a.json {
        Stages::hidden()
    } else {
        Stages::new(false)
    };
    let r = resample(
        &a.input,
        a.q.as_deref(),
        &a.field,
        a.dims,
        a.size,
        &a.output,
        a.gzip,
        &|m| progress.stage(m),
    )
    .map_err(|e| e.to_string())?;
    drop(progress);
    for w in &r.warnings {
        eprintln!("umbra: warning: {w}");
    }
    if a.json {
        out_json_pretty(&r)?;
    } else {
        out(format!(
            "{} grid: {} points, {} cells; arrays: {}",
            r.format,
            r.points,
            r.cells,
            r.arrays.join(", ")
        ))?;
        out(format!(
            "resampled '{}' to {}x{}x{} over [{:.4}, {:.4}, {:.4}]..[{:.4}, {:.4}, {:.4}]; {:.1}% of samples inside the mesh",
            r.field,
            r.dims[0],
            r.dims[1],
            r.dims[2],
            r.bounds[0][0],
            r.bounds[0][1],
            r.bounds[0][2],
            r.bounds[1][0],
            r.bounds[1][1],
            r.bounds[1][2],
            100.0 * r.inside
        ))?;
    }
    eprintln!("wrote {}", a.output.display());
    Ok(())
}

/// `--dims NX,NY,NZ`: three positive integers.
fn parse_dims(s: &str) -> Result<[usize; 3], String> {
    let v: Vec<usize> = s
        .split(',')
        .map(|t| t.trim().parse::<usize>())
        .collect::<Result<_, _>>()
        .map_err(|_| format!("'{s}' is not NX,NY,NZ"))?;
    match v.as_slice() {
        &[x, y, z] if x > 0 && y > 0 && z > 0 => Ok([x, y, z]),
        _ => Err(format!("'{s}' is not three positive integers NX,NY,NZ")),
    }
}

/// What `resample` did.
#[derive(Clone, Debug, Serialize)]
pub struct ResampleReport {
    pub format: String,
    pub points: usize,
    pub cells: usize,
    pub arrays: Vec<String>,
    pub field: String,
    pub dims: [usize; 3],
    pub bounds: [[f64; 3]; 2],
    /// Fraction of regular samples that fell inside the mesh.
    pub inside: f64,
    pub warnings: Vec<String>,
}

/// Regular dimensions with `longest` samples on the longest side of `bounds` and, on each
/// other side, the count whose spacing is nearest to that side's, two at least where the side
/// has any extent (each axis spans its bounds exactly, so the spacings differ by the
/// rounding); a flat side gets one.
pub fn fit_dims(bounds: [[f64; 3]; 2], longest: usize) -> [usize; 3] {
    let ext = [0, 1, 2].map(|a| (bounds[1][a] - bounds[0][a]).max(0.0));
    let m = ext.iter().cloned().fold(0.0, f64::max);
    if m <= 0.0 {
        return [1, 1, 1];
    }
    let h = m / (longest.max(2) - 1) as f64;
    // An axis with any extent gets two samples at least, so that it spans its bounds.
    ext.map(|e| {
        let lo = if e > 0.0 { 2 } else { 1 };
        ((e / h).round() as usize + 1).clamp(lo, 2048)
    })
}

/// Reads `input` (and the PLOT3D solution `q`), resamples `field` onto `dims` (or onto
/// `longest` samples along the longest side), and writes `output`; `stage` hears the name of
/// each stage as it starts.
#[allow(clippy::too_many_arguments)]
pub fn resample(
    input: &Path,
    q: Option<&Path>,
    field: &str,
    dims: Option<[usize; 3]>,
    longest: usize,
    output: &Path,
    gzip: bool,
    stage: &dyn Fn(&str),
) -> Result<ResampleReport, VolumeError> {
    if dims.is_none() && !(2..=2048).contains(&longest) {
        return Err(VolumeError::Invalid(format!(
            "size {longest}: the longest side needs 2 to 2048 samples"
        )));
    }
    super::convert::check_volume_output(output)?;
    stage("reading the grid");
    let (grid, warnings) = volume::load_grid(input, q)?;
    if grid.arrays.is_empty() {
        return Err(VolumeError::Invalid(format!(
            "{}: the grid has no data arrays{}",
            input.display(),
            if grid.format == "plot3d" {
                " (pass the PLOT3D solution with --q)"
            } else {
                ""
            }
        )));
    }
    let b = grid.bounds();
    let bounds = [b[0].to_array(), b[1].to_array()];
    let dims = dims.unwrap_or_else(|| fit_dims(bounds, longest));
    // One sample cannot span an axis the grid extends along.
    for (a, name) in ["x", "y", "z"].iter().enumerate() {
        if dims[a] < 2 && bounds[1][a] > bounds[0][a] {
            return Err(VolumeError::Invalid(format!(
                "{}: dims {}: the grid spans {} to {} along {name}, which needs 2 samples at \
                 least (1 only for a flat axis)",
                input.display(),
                dims.map(|d| d.to_string()).join(","),
                bounds[0][a],
                bounds[1][a]
            )));
        }
    }
    stage("locating samples and interpolating");
    let (vol, inside) = grid
        .resample_counted(field, dims)
        .map_err(|e| VolumeError::Invalid(format!("{}: {e}", input.display())))?;
    let f = vol.select(None)?;
    let comps = f.components;
    let samples = (f.data.len() / comps).max(1);
    let nan = f
        .data
        .chunks(comps)
        .filter(|c| c.iter().any(|v| v.is_nan()))
        .count();
    let mut warnings = warnings;
    // Samples outside the mesh are NaN; any more are the array's own NaN values.
    if nan > samples - inside {
        warnings.push(format!(
            "{} of the samples inside the mesh are NaN: the array '{field}' has NaN values in \
             the cells around them",
            nan - (samples - inside)
        ));
    }
    let inside = inside as f64 / samples as f64;
    stage("writing");
    super::convert::write_field(output, &vol, &f, gzip)?;
    warnings.extend(super::convert::frame_warning(&vol, output));
    Ok(ResampleReport {
        format: grid.format.clone(),
        points: grid.n_points(),
        cells: grid.n_cells(),
        arrays: grid.names(),
        field: field.to_string(),
        dims,
        bounds,
        inside,
        warnings,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_axis_with_extent_gets_two_samples_at_least() {
        // kitchen.vtk at --size 2 gave a z of one sample (spacing 1, a slab of nothing).
        assert_eq!(fit_dims([[0.0; 3], [10.0, 0.05, 0.0]], 2), [2, 2, 1]);
        assert_eq!(fit_dims([[0.0; 3], [10.0, 5.0, 2.5]], 5), [5, 3, 2]);
        assert_eq!(fit_dims([[0.0; 3], [0.0; 3]], 5), [1, 1, 1]);
    }

    #[test]
    fn dims_are_three_positive_integers() {
        assert_eq!(parse_dims("9, 5,5").unwrap(), [9, 5, 5]);
        for bad in ["9,0,5", "9,5", "a,b,c"] {
            assert!(parse_dims(bad).unwrap_err().contains("NX,NY,NZ"), "{bad}");
        }
    }
}
