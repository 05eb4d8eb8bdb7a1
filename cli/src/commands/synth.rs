//! `umbra synth`: the synthetic scenes of `volume::synthetic` as files.

use glam::DVec3;
use std::path::PathBuf;
use volume::synthetic::{
    cube_affine, sample_solid, sample_vector, three_solids, validation_scene, AbcFlow,
    BurgersVortex, RigidRotation,
};
use volume::Volume;

#[derive(clap::Args)]
pub struct Args {
    scene: String,
    #[arg(short, long)]
    output: PathBuf,
    /// Samples per axis.
    #[arg(long, default_value_t = 100)]
    n: usize,
}

pub fn run(a: Args) -> Result<(), String> {
    let vol = scene(&a.scene, a.n)?;
    volume::nrrd::write(
        &a.output,
        &vol,
        &vol.fields[0],
        volume::nrrd::WriteEncoding::Raw,
    )
    .map_err(|e| e.to_string())?;
    eprintln!("wrote {} ({}^3 {})", a.output.display(), a.n, a.scene);
    Ok(())
}

/// Scene names `umbra synth` knows.
pub const SCENES: &[&str] = &["validation", "three-solids", "abc", "burgers", "rotation"];

/// Samples a named scene on an `n^3` grid.
pub fn scene(name: &str, n: usize) -> Result<Volume, String> {
    if !(2..=1024).contains(&n) {
        return Err(format!("--n {n}: use 2 to 1024 samples per axis"));
    }
    let dims = [n; 3];
    Ok(match name {
        "validation" => validation_scene(n),
        "three-solids" => sample_solid(&three_solids(), dims, cube_affine(dims, 0.0, 1.0)),
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
        other => {
            return Err(format!(
                "unknown scene '{other}' (known: {})",
                SCENES.join(", ")
            ))
        }
    })
}
