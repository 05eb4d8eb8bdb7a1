//! `umbra iso`: renders an isosurface on the CPU with swept or Monte Carlo ambient occlusion
//! (see `occlusion::isosurface`).

use crate::output::out_json;
use occlusion::isosurface::{render, AmbientSource, IsoImage, IsoSurface, OrbitCamera, Shading};
use scene::fields::{iso_fields, scalar_field};
use scene::image_io::write_png;
use serde::Serialize;
use std::path::PathBuf;
use std::time::Instant;
use volume::distance_sweep::Inside;
use volume::occlusion_shading::{AmbientModel, AmbientOptions, GeometryTerm, Sky};
use volume::FieldSelector;

#[derive(clap::Args)]
pub struct Args {
    /// Input volume.
    input: PathBuf,
    /// Iso level.
    #[arg(long, allow_hyphen_values = true, value_parser = super::finite)]
    iso: f32,
    /// Distance field from `umbra sweep` (octants beside it); computed when absent.
    #[arg(long)]
    fields: Option<PathBuf>,
    /// Octant fields, when not at <stem>.octants.nrrd beside --fields.
    #[arg(long, requires = "fields")]
    octants: Option<PathBuf>,
    /// Output PNG (8-bit sRGB).
    #[arg(short, long)]
    output: PathBuf,
    #[arg(long, default_value_t = 512, allow_negative_numbers = true)]
    width: usize,
    #[arg(long, default_value_t = 512, allow_negative_numbers = true)]
    height: usize,
    /// Degrees; 0 looks along +y, 90 along +x.
    #[arg(long, default_value_t = 30.0, allow_hyphen_values = true, value_parser = super::finite64)]
    azimuth: f64,
    /// Degrees; 90 looks down from +z.
    #[arg(long, default_value_t = 30.0, allow_hyphen_values = true, value_parser = super::finite64)]
    elevation: f64,
    /// Camera distance in multiples of the bounding-sphere radius.
    #[arg(long, default_value_t = 3.0, value_parser = distance)]
    distance: f64,
    /// Shade with Monte Carlo ambient occlusion from N rays per pixel instead.
    #[arg(long, value_parser = clap::value_parser!(u64).range(1..=1_000_000))]
    reference_ao: Option<u64>,
    /// With --reference-ao: uniform-sphere visibility (the reference for --geometry none).
    #[arg(long, requires = "reference_ao")]
    uniform: bool,
    /// No occlusion at all (local illumination).
    #[arg(long, conflicts_with = "reference_ao")]
    local: bool,
    /// Geometry term: cosine (eq. 4-5), none (scalar AO) or abs (subsurface, |N.w|).
    #[arg(
        long,
        value_enum,
        default_value = "cosine",
        hide_possible_values = true
    )]
    geometry: Geometry,
    /// Octants that light the scene: uniform, overcast, or octant:1..8.
    #[arg(long, default_value = "uniform", value_parser = str::parse::<Sky>)]
    sky: Sky,
    /// Gamma applied to the ambient term (A^(1/gamma)).
    #[arg(long, default_value_t = 1.0, allow_negative_numbers = true)]
    gamma: f64,
    /// Flat-face correction: look the octants up at P + c h N.
    #[arg(long, default_value_t = volume::occlusion_shading::DEFAULT_OFFSET, value_parser = super::nonnegative, allow_negative_numbers = true)]
    offset: f64,
    /// Subsurface opacity for the octant sweeps computed in memory.
    #[arg(long, value_parser = super::unit, conflicts_with = "fields")]
    subsurface: Option<f32>,
    /// Add a Phong head light.
    #[arg(long)]
    phong: bool,
    #[arg(long, value_enum, default_value = "above")]
    inside: super::Inside,
    #[arg(long, value_parser = super::field_selector)]
    field: Option<FieldSelector>,
    /// Print statistics as JSON.
    #[arg(long)]
    json: bool,
}

/// `--geometry`: the geometry term of the swept ambient occlusion.
#[derive(Clone, Copy, Debug, clap::ValueEnum)]
pub enum Geometry {
    Cosine,
    #[value(name = "none", alias = "constant")]
    Constant,
    Abs,
}

impl From<Geometry> for GeometryTerm {
    fn from(g: Geometry) -> Self {
        match g {
            Geometry::Cosine => GeometryTerm::Cosine,
            Geometry::Constant => GeometryTerm::Constant,
            Geometry::Abs => GeometryTerm::Absolute,
        }
    }
}

pub fn run(a: Args) -> Result<(), String> {
    if !a
        .output
        .to_string_lossy()
        .to_ascii_lowercase()
        .ends_with(".png")
    {
        return Err(format!(
            "{}: umbra iso writes PNG images; name the output .png",
            a.output.display()
        ));
    }
    volume::check_output(&a.output)?;
    if !(a.gamma.is_finite() && a.gamma > 0.0) {
        return Err(format!("--gamma {}: must be a positive number", a.gamma));
    }
    let (width, height) = (a.width, a.height);
    if width == 0 || height == 0 || width.checked_mul(height).is_none_or(|n| n > 1 << 26) {
        return Err(format!(
            "--width {width} --height {height}: the image must have between 1 and 2^26 pixels"
        ));
    }
    let args = IsoArgs {
        input: a.input,
        iso: a.iso,
        inside: a.inside.into(),
        field: a.field,
        fields: a.fields,
        octants: a.octants,
        output: a.output,
        camera: OrbitCamera {
            width,
            height,
            azimuth_deg: a.azimuth,
            elevation_deg: a.elevation,
            distance: a.distance,
        },
        reference_ao: a.reference_ao.map(|n| n as usize),
        uniform: a.uniform,
        local: a.local,
        ambient: AmbientOptions {
            geometry: a.geometry.into(),
            sky: a.sky,
            gamma: a.gamma,
            offset: a.offset,
        },
        subsurface_alpha: a.subsurface,
        phong: a.phong,
    };
    let (_, stats) = render_to_file(&args)?;
    if a.json {
        return out_json(&stats);
    }
    eprintln!(
        "wrote {} ({} surface pixels, mean ambient {}, {:.2} s)",
        args.output.display(),
        stats.hit_pixels,
        stats
            .mean_ambient
            .map_or("- (no surface in view)".into(), |m| format!("{m:.3}")),
        stats.seconds
    );
    Ok(())
}

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
    /// Means over the surface's pixels; null where no pixel shows the surface.
    pub mean_ambient: Option<f64>,
    pub mean_stderr: Option<f64>,
    pub seconds: f64,
}

/// Loads or computes the fields, renders and writes the PNG; returns the image and its
/// statistics.
pub fn render_to_file(args: &IsoArgs) -> Result<(IsoImage, IsoStats), String> {
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
        &[],
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
    let n = hits.len() as f64;
    let mean =
        |v: &[f32]| (!hits.is_empty()).then(|| hits.iter().map(|&i| v[i] as f64).sum::<f64>() / n);
    let stats = IsoStats {
        width: img.width,
        height: img.height,
        hit_pixels: hits.len(),
        mean_ambient: mean(&img.ambient),
        mean_stderr: mean(&img.stderr),
        seconds: t0.elapsed().as_secs_f64(),
    };
    Ok((img, stats))
}

/// `--distance`: a camera distance of more than one bounding-sphere radius (the camera outside
/// the sphere), finite.
fn distance(s: &str) -> Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(v) if v.is_finite() && v > 1.0 => Ok(v),
        _ => Err("must be a finite number above 1 (bounding-sphere radii)".into()),
    }
}
