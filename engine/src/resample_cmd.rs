//! `umbra resample`: read a CFD grid (VTK XML or legacy rectilinear, curvilinear and
//! unstructured grids, PLOT3D), interpolate one array onto a regular grid over the mesh's
//! bounding box, and write it as NRRD or NIfTI. Samples outside the mesh are NaN.

use serde::Serialize;
use std::path::Path;
use volume::VolumeError;

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

/// Regular dimensions with `longest` samples on the longest side of `bounds` and the same
/// spacing on the others.
pub fn fit_dims(bounds: [[f64; 3]; 2], longest: usize) -> [usize; 3] {
    let ext = [0, 1, 2].map(|a| (bounds[1][a] - bounds[0][a]).max(0.0));
    let m = ext.iter().cloned().fold(0.0, f64::max);
    if m <= 0.0 {
        return [1, 1, 1];
    }
    let h = m / (longest.max(2) - 1) as f64;
    ext.map(|e| ((e / h).round() as usize + 1).clamp(1, 2048))
}

/// Reads `input` (and the PLOT3D solution `q`), resamples `field` onto `dims` (or onto
/// `longest` samples along the longest side), and writes `output`. `progress` shows a spinner
/// with the current stage on standard error.
#[allow(clippy::too_many_arguments)]
pub fn resample(
    input: &Path,
    q: Option<&Path>,
    field: &str,
    dims: Option<[usize; 3]>,
    longest: usize,
    output: &Path,
    gzip: bool,
    progress: bool,
) -> Result<ResampleReport, VolumeError> {
    let bar = progress.then(|| {
        let b = indicatif::ProgressBar::new_spinner();
        b.enable_steady_tick(std::time::Duration::from_millis(120));
        b
    });
    let stage = |m: &str| {
        if let Some(b) = &bar {
            b.set_message(m.to_string());
        }
    };
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
    stage("locating samples and interpolating");
    let vol = grid.resample(field, dims)?;
    let f = vol.select(None)?;
    let comps = f.components;
    let inside = f
        .data
        .chunks(comps)
        .filter(|c| c.iter().all(|v| !v.is_nan()))
        .count() as f64
        / (f.data.len() / comps).max(1) as f64;
    stage("writing");
    crate::convert::write_field(output, &vol, &f, gzip)?;
    if let Some(b) = bar {
        b.finish_and_clear();
    }
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
