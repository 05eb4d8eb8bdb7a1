//! `umbra bench sweep -o <dir>`: occlusion sweeping against Monte Carlo ambient occlusion on the
//! sweeping paper's validation scene, and [`iso_accuracy`], the measurement `bench stability`
//! shares.

use super::chart::{write_chart, Plot};
use crate::commands::iso::Geometry;
use crate::commands::list_item;
use crate::output::out;
use std::io::Write as _;
use std::path::{Path, PathBuf};

/// `umbra bench sweep`.
#[derive(clap::Args)]
pub struct Args {
    /// Grid sizes n (the sweep's grid is n^3), comma-separated.
    #[arg(long, value_delimiter = ',', value_parser = list_item::<usize>, default_value = "32,64,128")]
    sizes: Vec<usize>,
    /// Flat-face offsets c (comma-separated).
    #[arg(long, value_delimiter = ',', value_parser = list_item::<f64>, default_value = "1.5")]
    offsets: Vec<f64>,
    /// Geometry terms: cosine (AO, against cosine-weighted rays), constant (scalar AO,
    /// against uniform-sphere visibility).
    #[arg(
        long,
        value_enum,
        value_delimiter = ',',
        default_value = "cosine",
        hide_possible_values = true
    )]
    geometry: Vec<Geometry>,
    /// Monte Carlo rays per pixel of the reference.
    #[arg(long, default_value_t = 256)]
    spp: usize,
    /// Image size (square).
    #[arg(long, default_value_t = 128)]
    size: usize,
    /// Output folder: sweep.csv, sweep.svg, sweep.png.
    #[arg(short, long)]
    output: PathBuf,
}

pub fn run(a: Args) -> Result<(), String> {
    let geometries: Vec<_> = a.geometry.into_iter().map(Into::into).collect();
    for r in sweep(&a.sizes, &a.offsets, &geometries, a.spp, a.size, &a.output)? {
        out(format!(
            "n {:4}  {:8} offset {:4}  sweep {:9.1} ms  rmse {:.5}  (reference stderr {:.5})",
            r.n, r.geometry, r.offset, r.ms, r.rmse, r.reference_stderr
        ))?;
    }
    eprintln!(
        "wrote {0}/sweep.csv, {0}/sweep.svg, {0}/sweep.png",
        a.output.display()
    );
    Ok(())
}

/// Occlusion sweeping on the isosurface 0 of `vol` (inside where positive) with each of the
/// ambient options `opts` against Monte Carlo AO (`spp` rays per pixel: cosine-weighted, or
/// uniform over the sphere for scalar AO without the geometry term; each reference traced
/// once) on a `size x size` image from azimuth `azimuth`, elevation 35, distance 1.6: the
/// sweep's milliseconds, and per option the RMSE of the ambient term and the reference's mean
/// standard error.
pub fn iso_accuracy(
    vol: &volume::Volume,
    spp: usize,
    size: usize,
    azimuth: f64,
    opts: &[volume::occlusion_shading::AmbientOptions],
) -> Result<(f64, Vec<(f64, f64)>), String> {
    use occlusion::isosurface::{render, rmse, AmbientSource, IsoSurface, OrbitCamera, Shading};
    use volume::occlusion_shading::{AmbientModel, GeometryTerm};
    let values = vol.select(None).map_err(|e| e.to_string())?.data;
    let sp = vol.spacing();
    let dopts = volume::distance_sweep::DistanceOptions {
        iso: 0.0,
        inside: volume::distance_sweep::Inside::Above,
        ..Default::default()
    };
    let t = std::time::Instant::now();
    let (df, oct) = volume::occlusion_sweep::sweep_fields(
        &values,
        vol.dims,
        [sp[0] as f32, sp[1] as f32, sp[2] as f32],
        &dopts,
        &volume::occlusion_sweep::OcclusionOptions {
            subsurface_alpha: None,
        },
        true,
    );
    let ms = t.elapsed().as_secs_f64() * 1e3;
    let oct = oct.ok_or("octant fields missing")?;
    let surface = IsoSurface::new(vol.dims, vol.affine, &values, 0.0, true, &df.distance);
    let cam = OrbitCamera {
        width: size,
        height: size,
        azimuth_deg: azimuth,
        elevation_deg: 35.0,
        distance: 1.6,
    };
    let shading = Shading::default();
    // The references, cosine-weighted and uniform, as the options need them.
    let mut refs: [Option<(occlusion::isosurface::IsoImage, f64)>; 2] = [None, None];
    let mut out = vec![];
    for o in opts {
        let uniform = o.geometry == GeometryTerm::Constant;
        if refs[uniform as usize].is_none() {
            let reference = render(
                &surface,
                vol.bounds(),
                &cam,
                &AmbientSource::Reference { rays: spp, uniform },
                &shading,
            );
            let hits: Vec<f64> = reference
                .stderr
                .iter()
                .zip(&reference.ambient)
                .filter(|(_, a)| a.is_finite())
                .map(|(s, _)| *s as f64)
                .collect();
            let se = hits.iter().sum::<f64>() / hits.len().max(1) as f64;
            refs[uniform as usize] = Some((reference, se));
        }
        let (reference, se) = refs[uniform as usize].as_ref().unwrap();
        let model = AmbientModel::new(*o, &vol.affine);
        let swept = render(
            &surface,
            vol.bounds(),
            &cam,
            &AmbientSource::Swept {
                octants: &oct,
                model: &model,
            },
            &shading,
        );
        out.push((rmse(&swept, reference), *se));
    }
    Ok((ms, out))
}

/// One configuration of `bench sweep`.
#[derive(Clone, Debug)]
pub struct SweepRow {
    pub n: usize,
    pub offset: f64,
    /// `cosine` (with the geometry term) or `constant` (scalar AO).
    pub geometry: String,
    pub ms: f64,
    pub rmse: f64,
    pub reference_stderr: f64,
}

/// `umbra bench sweep -o <dir>`: occlusion sweeping against Monte Carlo ambient occlusion on
/// the sweeping paper's validation scene at several grid sizes: sweep time (distance and eight
/// octants), and the RMSE of the swept ambient term against hemisphere AO traced on the same
/// isosurface (`spp` cosine-weighted rays per pixel, its standard error reported), on a
/// `size x size` image; `<dir>/sweep.csv` and `<dir>/sweep.svg|png` (error against time).
pub fn sweep(
    sizes: &[usize],
    offsets: &[f64],
    geometries: &[volume::occlusion_shading::GeometryTerm],
    spp: usize,
    size: usize,
    out: &Path,
) -> Result<Vec<SweepRow>, String> {
    if let Some(o) = offsets.iter().find(|o| !(o.is_finite() && **o >= 0.0)) {
        return Err(format!("--offsets: {o} is not a finite number >= 0"));
    }
    if spp == 0 || !(8..=2048).contains(&size) {
        return Err(format!(
            "--spp {spp} --size {size}: at least one ray per pixel, an image of 8 to 2048 pixels"
        ));
    }
    std::fs::create_dir_all(out).map_err(|e| format!("{}: {e}", out.display()))?;
    let mut rows = vec![];
    for &n in sizes {
        if !(8..=512).contains(&n) {
            return Err(format!("--sizes: {n} is not in 8..512"));
        }
        let vol = volume::synthetic::validation_scene(n);
        let opts: Vec<volume::occlusion_shading::AmbientOptions> = geometries
            .iter()
            .flat_map(|&geometry| {
                offsets
                    .iter()
                    .map(move |&offset| volume::occlusion_shading::AmbientOptions {
                        geometry,
                        offset,
                        ..Default::default()
                    })
            })
            .collect();
        let (ms, results) = iso_accuracy(&vol, spp, size, 35.0, &opts)?;
        for (o, (rmse, se)) in opts.iter().zip(results) {
            rows.push(SweepRow {
                n,
                offset: o.offset,
                geometry: format!("{:?}", o.geometry).to_lowercase(),
                ms,
                rmse,
                reference_stderr: se,
            });
        }
    }
    let mut csv = Vec::new();
    let _ = writeln!(csv, "n,offset,geometry,sweep_ms,rmse,reference_stderr");
    for r in &rows {
        let _ = writeln!(
            csv,
            "{},{},{},{:.2},{:.6},{:.6}",
            r.n, r.offset, r.geometry, r.ms, r.rmse, r.reference_stderr
        );
    }
    volume::write_atomic(&out.join("sweep.csv"), &csv).map_err(|e| e.to_string())?;
    write_chart(
        out,
        "sweep",
        &Plot {
            title: "occlusion sweeping: error against time (validation scene)".into(),
            x_label: "sweep time (ms; distance and eight octants)".into(),
            y_label: "RMSE of the ambient term against Monte Carlo AO".into(),
            series: {
                let name = |r: &SweepRow| format!("{}, offset {}", r.geometry, r.offset);
                let mut names: Vec<String> = rows.iter().map(name).collect();
                names.sort();
                names.dedup();
                names
                    .into_iter()
                    .map(|nm| {
                        let pts = rows
                            .iter()
                            .filter(|r| name(r) == nm)
                            .map(|r| (r.ms.max(1e-3), r.rmse.max(1e-9)))
                            .collect();
                        (nm, pts)
                    })
                    .collect()
            },
            line: None,
        },
    )?;
    Ok(rows)
}
