//! `umbra iso`: renders an isosurface on the CPU with swept or Monte Carlo ambient occlusion
//! (see [`crate::iso_reference`]).

use crate::iso_reference::{
    render, write_png, AmbientSource, IsoImage, IsoSurface, OrbitCamera, Shading,
};
use crate::sweep_cmd::{read_octants, scalar_field};
use serde::Serialize;
use std::path::PathBuf;
use std::time::Instant;
use volume::distance_sweep::{DistanceOptions, Inside};
use volume::occlusion_shading::{AmbientModel, AmbientOptions};
use volume::occlusion_sweep::{sweep_fields, OcclusionOptions};
use volume::FieldSelector;

/// What `umbra iso` is asked to do.
#[derive(Clone, Debug)]
pub struct IsoArgs {
    pub input: PathBuf,
    pub iso: f32,
    pub inside: Inside,
    pub field: Option<FieldSelector>,
    /// Distance field from `umbra sweep` (octants from `octants` or `<stem>.octants.nrrd`);
    /// computed in memory when absent.
    pub fields: Option<PathBuf>,
    pub octants: Option<PathBuf>,
    pub output: PathBuf,
    pub camera: OrbitCamera,
    /// Monte Carlo reference with this many rays per pixel instead of the swept term.
    pub reference_ao: Option<usize>,
    pub uniform: bool,
    /// No ambient term at all (local illumination).
    pub local: bool,
    pub ambient: AmbientOptions,
    pub subsurface_alpha: Option<f32>,
    pub phong: bool,
}

/// What `umbra iso` reports.
#[derive(Clone, Debug, Serialize)]
pub struct IsoStats {
    pub width: usize,
    pub height: usize,
    pub hit_pixels: usize,
    pub mean_ambient: f64,
    pub mean_stderr: f64,
    pub seconds: f64,
}

/// The distance field and (when `need_octants`) the eight octant visibilities of an
/// isosurface: read from `fields` (the octants from `octants` or beside it) when given, else
/// swept in memory.
#[allow(clippy::too_many_arguments)]
pub fn iso_fields(
    vol: &volume::Volume,
    values: &[f32],
    iso: f32,
    inside: Inside,
    fields: Option<&std::path::Path>,
    octants: Option<&std::path::Path>,
    need_octants: bool,
    subsurface_alpha: Option<f32>,
) -> Result<(Vec<f32>, Option<volume::occlusion_sweep::OctantFields>), String> {
    match fields {
        Some(p) => {
            let d = volume::load(p).map_err(|e| e.to_string())?;
            if d.dims != vol.dims || d.fields[0].components != 1 {
                return Err(format!(
                    "{}: distance grid {:?} does not match the volume's {:?}",
                    p.display(),
                    d.dims,
                    vol.dims
                ));
            }
            let oct = if need_octants {
                let op = octants
                    .map(|o| o.to_path_buf())
                    .unwrap_or_else(|| crate::sweep_cmd::default_octants_path(p));
                Some(read_octants(&op, vol.dims)?)
            } else {
                None
            };
            Ok((d.fields[0].data.clone(), oct))
        }
        None => {
            let sp = vol.spacing();
            let dopts = DistanceOptions {
                iso,
                inside,
                ..Default::default()
            };
            let (df, oct) = sweep_fields(
                values,
                vol.dims,
                [sp[0] as f32, sp[1] as f32, sp[2] as f32],
                &dopts,
                &OcclusionOptions { subsurface_alpha },
                true,
            );
            Ok((df.distance, oct))
        }
    }
}

/// Loads or computes the fields and renders; returns the image and its statistics.
pub fn render_cli(args: &IsoArgs) -> Result<(IsoImage, IsoStats), String> {
    let t0 = Instant::now();
    let vol = volume::load(&args.input).map_err(|e| e.to_string())?;
    let values = scalar_field(
        &vol,
        args.field.as_ref(),
        args.iso,
        args.inside,
        &args.input,
    )?;
    let need_octants = args.reference_ao.is_none() && !args.local;
    let (sdf, octants) = iso_fields(
        &vol,
        &values,
        args.iso,
        args.inside,
        args.fields.as_deref(),
        args.octants.as_deref(),
        need_octants,
        args.subsurface_alpha,
    )?;
    let surface = IsoSurface::new(
        vol.dims,
        vol.affine,
        &values,
        args.iso,
        args.inside == Inside::Above,
        &sdf,
    );
    let model = AmbientModel::new(args.ambient, &vol.affine);
    let source = if args.local {
        AmbientSource::None
    } else if let Some(n) = args.reference_ao {
        AmbientSource::Reference {
            rays: n.max(1),
            uniform: args.uniform,
        }
    } else {
        AmbientSource::Swept {
            octants: octants.as_ref().ok_or("octant fields are missing")?,
            model: &model,
        }
    };
    let img = render(
        &surface,
        vol.bounds(),
        &args.camera,
        &source,
        &Shading {
            phong: args.phong,
            ..Default::default()
        },
    );
    write_png(&args.output, &img)?;
    let hits: Vec<usize> = (0..img.ambient.len())
        .filter(|&i| img.ambient[i].is_finite())
        .collect();
    let n = hits.len().max(1) as f64;
    let stats = IsoStats {
        width: img.width,
        height: img.height,
        hit_pixels: hits.len(),
        mean_ambient: hits.iter().map(|&i| img.ambient[i] as f64).sum::<f64>() / n,
        mean_stderr: hits.iter().map(|&i| img.stderr[i] as f64).sum::<f64>() / n,
        seconds: t0.elapsed().as_secs_f64(),
    };
    Ok((img, stats))
}
