//! `umbra synth`: the synthetic scenes of `volume::synthetic` as files.
//!
//! Steady scenes are written as NRRD, or as NIfTI-1 when the output ends in `.nii` or
//! `.nii.gz`. `double-gyre` is a time series: the 3-D double gyre of
//! `volume::synthetic::DoubleGyre3d` (Shadden et al.'s A = 0.1, eps = 0.25, omega = 2 pi / 10,
//! plus a y-z roll of amplitude C = 0.05),
//!
//! ```text
//! a(t) = eps sin(omega t),  b(t) = 1 - 2 eps sin(omega t),  f(x, t) = a x^2 + b x
//! u = -pi A sin(pi f) cos(pi y)
//! v =  pi A cos(pi f) sin(pi y) (2 a x + b) + pi C sin(pi y) cos(pi z)
//! w = -pi C cos(pi y) sin(pi z)
//! ```
//!
//! on `[0, 2] x [0, 1] x [0, 1]` with `--n` samples across y and z (default 33) and
//! `2 (n - 1) + 1` across x, sampled at `--frames` times `k 10 / frames` (default 20, so a
//! time step of 0.5) over one period, and written as a periodic 5-D NIfTI (`.nii` or `.nii.gz`
//! only): dims `(x, y, z, t, 3)`, intent VECTOR, `pixdim[4]` the time step, `descrip`
//! `umbra time-periodic`.

use glam::DVec3;
use std::path::{Path, PathBuf};
use volume::synthetic::{
    cube_affine, double_gyre_grid, sample_series, sample_solid, sample_vector, shepp_logan,
    three_solids, validation_scene, AbcFlow, BurgersVortex, DoubleGyre3d, RigidRotation,
};
use volume::{Volume, VolumeSeries};

/// What `umbra synth --help` adds below the options.
const NOTES: &str = "\
Scenes: validation, three-solids, phantom (the 3-D Shepp-Logan head in uint16), abc, burgers, \
rotation (steady; NRRD, or NIfTI for .nii and .nii.gz), double-gyre (a time-periodic 3-D double gyre on [0,2]x[0,1]x[0,1], period 10, as a 5-D \
NIfTI time series: .nii or .nii.gz), bundles (a tractogram of --n streamlines in smooth twisted \
bundles across a brain-sized box, written streaming as .tck or .tck.gz).";

#[derive(clap::Args)]
#[command(after_help = NOTES)]
pub struct Args {
    scene: String,
    #[arg(short, long)]
    output: PathBuf,
    /// Samples per axis (double-gyre: across y and z, twice that less one across x); default
    /// 100, double-gyre 33; bundles: streamlines (default 10000).
    #[arg(long)]
    n: Option<usize>,
    /// double-gyre: time frames over its period of 10 (default 20).
    #[arg(long)]
    frames: Option<usize>,
    /// bundles: points a streamline (default 100).
    #[arg(long)]
    points: Option<usize>,
    /// bundles: how many bundles the streamlines are dealt to (default 24).
    #[arg(long)]
    bundles: Option<usize>,
    /// bundles: a bundle's cross-section radius in mm (default 6).
    #[arg(long, allow_hyphen_values = true)]
    radius: Option<f64>,
    /// bundles: the random seed (default 1).
    #[arg(long)]
    seed: Option<u64>,
}

pub fn run(a: Args) -> Result<(), String> {
    let bundle_keys = [
        ("--points", a.points.is_some()),
        ("--bundles", a.bundles.is_some()),
        ("--radius", a.radius.is_some()),
        ("--seed", a.seed.is_some()),
    ];
    if a.scene != "bundles" {
        if let Some((k, _)) = bundle_keys.iter().find(|(_, set)| *set) {
            return Err(format!("{k} is for bundles; {} is a volume", a.scene));
        }
    }
    if a.scene == "bundles" {
        if a.frames.is_some() {
            return Err("--frames is for double-gyre; bundles is a tractogram".into());
        }
        return bundles(&a);
    }
    if a.scene == "double-gyre" {
        let n = a.n.unwrap_or(33);
        if !is_nifti(&a.output) {
            return Err(format!(
                "{}: double-gyre is a time series: write it as .nii or .nii.gz (5-D NIfTI)",
                a.output.display()
            ));
        }
        volume::check_output(&a.output)?;
        let s = double_gyre(n, a.frames.unwrap_or(20))?;
        volume::nifti::write_series(&a.output, &s).map_err(|e| e.to_string())?;
        let d = s.frames[0].dims;
        eprintln!(
            "wrote {} ({} x {} x {} x {} frames, time step {}, periodic, double-gyre)",
            a.output.display(),
            d[0],
            d[1],
            d[2],
            s.len(),
            s.dt
        );
        return Ok(());
    }
    if a.frames.is_some() {
        return Err(format!(
            "--frames is for double-gyre; {} is steady",
            a.scene
        ));
    }
    let lower = a.output.to_string_lossy().to_ascii_lowercase();
    if !(is_nifti(&a.output) || lower.ends_with(".nrrd")) {
        return Err(format!(
            "{}: {} is a volume: write it as .nrrd, .nii or .nii.gz",
            a.output.display(),
            a.scene
        ));
    }
    let n = a.n.unwrap_or(100);
    volume::check_output(&a.output)?;
    let vol = scene(&a.scene, n)?;
    if is_nifti(&a.output) {
        volume::nifti::write(&a.output, &vol, &vol.fields[0])
    } else {
        volume::nrrd::write(
            &a.output,
            &vol,
            &vol.fields[0],
            volume::nrrd::WriteEncoding::Raw,
        )
    }
    .map_err(|e| e.to_string())?;
    eprintln!("wrote {} ({}^3 {})", a.output.display(), n, a.scene);
    Ok(())
}

/// `umbra synth bundles`: streamlines made and written one at a time.
fn bundles(a: &Args) -> Result<(), String> {
    let d = tubes::synthetic::Bundles::default();
    let b = tubes::synthetic::Bundles {
        count: a.n.unwrap_or(d.count),
        points: a.points.unwrap_or(d.points),
        bundles: a.bundles.unwrap_or(d.bundles),
        radius: a.radius.unwrap_or(d.radius),
        seed: a.seed.unwrap_or(d.seed),
    };
    b.validate().map_err(|e| format!("bundles: {e}"))?;
    let name = a.output.to_string_lossy().to_ascii_lowercase();
    if !(name.ends_with(".tck") || name.ends_with(".tck.gz")) {
        return Err(format!(
            "{}: bundles are written as MRtrix .tck or .tck.gz (streamed; `umbra tracts select IN.tck -o OUT.trk` converts)",
            a.output.display()
        ));
    }
    // The points must fit the u32 indices of the renderer's line sets.
    if b.total_points() > u32::MAX as u64 {
        return Err(format!(
            "--n {} --points {}: {} points; at most {} are written",
            b.count,
            b.points,
            b.total_points(),
            u32::MAX
        ));
    }
    volume::check_output(&a.output)?;
    let bar = crate::progress::Counter::new("streamlines", b.count as u64);
    tubes::tck::write_with(&a.output, b.count, |i, out| {
        if i % 4096 == 0 {
            bar.set(i as u64);
        }
        b.line(i, out)
    })
    .map_err(|e| e.to_string())?;
    bar.set(b.count as u64);
    drop(bar);
    eprintln!(
        "wrote {} ({} streamlines of {} points in {} bundles of radius {} mm)",
        a.output.display(),
        b.count,
        b.points,
        b.bundles,
        b.radius
    );
    Ok(())
}

fn is_nifti(p: &Path) -> bool {
    let name = p.to_string_lossy().to_ascii_lowercase();
    name.ends_with(".nii") || name.ends_with(".nii.gz")
}

/// Scene names `umbra synth` knows.
pub const SCENES: &[&str] = &[
    "validation",
    "three-solids",
    "phantom",
    "abc",
    "burgers",
    "rotation",
    "double-gyre",
    "bundles",
];

/// The double gyre sampled with `n` samples across y and z at `frames` times over its period
/// (periodic).
pub fn double_gyre(n: usize, frames: usize) -> Result<VolumeSeries, String> {
    if !(2..=512).contains(&n) {
        return Err(format!("--n {n}: use 2 to 512 samples across y and z"));
    }
    if !(2..=10_000).contains(&frames) {
        return Err(format!("--frames {frames}: use 2 to 10000 frames"));
    }
    let samples = (2 * (n - 1) + 1) as u64 * (n * n) as u64 * frames as u64 * 3;
    if samples > 1 << 30 {
        return Err(format!(
            "--n {n} --frames {frames}: {samples} samples ({} GiB); use fewer",
            (samples * 4) >> 30
        ));
    }
    let g = DoubleGyre3d::default();
    let (dims, affine) = double_gyre_grid(n);
    Ok(sample_series(
        &g,
        dims,
        affine,
        "velocity",
        frames,
        0.0,
        g.period() / frames as f64,
        true,
    ))
}

/// Samples a named steady scene on an `n^3` grid.
pub fn scene(name: &str, n: usize) -> Result<Volume, String> {
    if !(2..=1024).contains(&n) {
        return Err(format!("--n {n}: use 2 to 1024 samples per axis"));
    }
    let dims = [n; 3];
    Ok(match name {
        "validation" => validation_scene(n),
        "three-solids" => sample_solid(&three_solids(), dims, cube_affine(dims, 0.0, 1.0)),
        "phantom" => shepp_logan(n),
        "abc" => sample_vector(
            &AbcFlow::default(),
            dims,
            cube_affine(dims, 0.0, 2.0 * std::f64::consts::PI),
            "velocity",
        ),
        "burgers" => sample_vector(
            &BurgersVortex {
                center: DVec3::ZERO,
                strain: 0.5,
                circulation: 20.0,
                core: 1.0,
            },
            dims,
            cube_affine(dims, -5.0, 5.0),
            "velocity",
        ),
        "rotation" => sample_vector(
            &RigidRotation {
                center: DVec3::ZERO,
                axis: DVec3::Z,
                omega: 1.0,
            },
            dims,
            cube_affine(dims, -1.0, 1.0),
            "velocity",
        ),
        "double-gyre" => {
            return Err(
                "double-gyre is a time series, not one volume (umbra synth double-gyre -o X.nii)"
                    .into(),
            )
        }
        other => {
            return Err(format!(
                "unknown scene '{other}' (known: {})",
                SCENES.join(", ")
            ))
        }
    })
}
