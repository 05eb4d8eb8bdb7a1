//! `umbra demo [mni|cfd|lines]`: the bundled scenes.
//!
//! * `mni` (default): `datasets/scenes/demo.toml` - the MNI ICBM 2009a T1 template cut open by
//!   an axial plane (z = 20) with three HCP1065 bundles rising out of the cut (registered: they
//!   lie in the white matter), by the combined method.
//! * `cfd`: the VTK carotid flow (`datasets/vtk/carotid.vtk`): streamlines traced from 20,000
//!   random seeds (RK4, both ways, `umbra trace`) and kept where the flow is faster than 1, as
//!   tubes coloured by speed inside the vessel drawn as a translucent volume, by the combined
//!   method.
//! * `lines`: `datasets/scenes/demo_lines.toml` - all ten HCP1065 bundles (7.1M points,
//!   registered as for `mni`) as lines in direction colours with LineAO (method `lineao`) over
//!   the template, its right hemisphere cut away. 800 x 600, 41 s on lavapipe with two cores
//!   (38.6 s a frame; 1024 x 768 takes 45 s a frame): rasterising the 14.2M line triangles
//!   into the G-buffer is most of a frame at any size, so a smaller image would save little and
//!   this one stays inside a minute. The bundles are not shipped (see [`find_bundle`]).
//!
//! The datasets are found at `UMBRA_DATASETS`, else the source tree's `datasets/` (where
//! `cargo run` builds from), else `./datasets`.

use super::render::{size_method_overrides, summary};
use super::trace::{trace_to_file, TraceArgs};
use crate::output::out;
use scene::render::{RenderArgs, RenderReport};
use std::path::{Path, PathBuf};

#[derive(clap::Args)]
pub struct Args {
    /// mni (the template with three bundles as tubes), cfd (carotid flow) or lines (all of
    /// HCP1065 as lines with LineAO; needs the bundles, see `UMBRA_HCP1065`).
    #[arg(default_value = "mni")]
    which: String,
    /// Output image (.png or .exr).
    #[arg(short, long, default_value = "demo.png")]
    output: PathBuf,
    #[arg(long)]
    width: Option<u32>,
    #[arg(long)]
    height: Option<u32>,
    /// A render method (render.method): combined, dos, vicinity, ea, phong, illuminated, lineao,
    /// illustrative, mip, minip.
    #[arg(long, value_enum, hide_possible_values = true)]
    method: Option<super::Method>,
    /// Frames timed; total_ms is their median.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=100_000))]
    frames: u32,
    /// Override a scene key by its dotted path (repeatable).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    set: Vec<String>,
}

pub fn run(a: Args) -> Result<(), String> {
    let overrides = size_method_overrides(a.width, a.height, a.method, a.set);
    let r = render_demo(&a.which, &a.output, &overrides, a.frames)?;
    for n in &r.notes {
        eprintln!("note: {n}");
    }
    out(summary(&r))?;
    eprintln!("wrote {}", a.output.display());
    Ok(())
}

/// The bundled datasets directory.
pub fn datasets() -> PathBuf {
    if let Ok(d) = std::env::var("UMBRA_DATASETS") {
        return PathBuf::from(d);
    }
    let built = Path::new(env!("CARGO_MANIFEST_DIR")).join("../datasets");
    if built.join("scenes/demo.toml").exists() {
        return built;
    }
    PathBuf::from("datasets")
}

/// The CFD demo's scene, with its streamlines at `tracts`.
fn cfd_scene(data: &Path, tracts: &Path) -> String {
    format!(
        r#"# umbra demo cfd: carotid bifurcation flow (VTKData): the vessel as a translucent volume, streamlines
# filling its branches, coloured by speed, with a colour bar.
background = [1.0, 1.0, 1.0]
[camera]
azimuth = 20.0
elevation = 15.0
distance = 2.4
[volume]
path = {}
field = "scalars"
[volume.transfer]
points = [
  {{ value = 150.0, color = [0.85, 0.55, 0.5], extinction = 0.0 }},
  {{ value = 260.0, color = [0.9, 0.6, 0.56], extinction = 0.15 }},
  {{ value = 580.0, color = [0.95, 0.8, 0.75], extinction = 0.25 }},
]
[[tubes]]
path = {}
radius = 0.2
color = "scalar:speed"
select = {{ min_length = 8.0 }}
[annotate]
colorbar = "tubes.0"
colorbar_label = "speed"
[render]
width = 1024
height = 768
theta = 40.0
vicinity_distance = 1.5
combine = "product"
"#,
        toml_string(&data.join("vtk/carotid.vtk")),
        toml_string(tracts)
    )
}

/// A path as a TOML basic string (a JSON string is one): quotes and backslashes in
/// `UMBRA_DATASETS` or the temporary folder do not break the scene.
fn toml_string(p: &Path) -> String {
    serde_json::to_string(&p.display().to_string()).expect("a string serialises")
}

/// The environment variable naming a folder that holds the HCP1065 bundles (`AF_R.trk.gz`, ...).
pub const HCP1065_ENV: &str = "UMBRA_HCP1065";

/// Where the lines demo's bundle `name` (a file name) lies: `$UMBRA_HCP1065/name`, else a copy
/// shipped in `datasets/tracts/hcp1065/`, else `written` - the scene's own path for it,
/// `../shared/data/tracts/hcp1065/name` beside the repository. Made absolute. A bundle found in
/// none of them is an error that names the file and every place looked.
pub fn find_bundle(data: &Path, name: &str, written: &Path) -> Result<PathBuf, String> {
    let mut places: Vec<PathBuf> = vec![];
    if let Some(d) = std::env::var_os(HCP1065_ENV) {
        places.push(PathBuf::from(d).join(name));
    }
    places.push(data.join("tracts/hcp1065").join(name));
    places.push(written.to_path_buf());
    if let Some(p) = places.iter().find(|p| p.is_file()) {
        return p
            .canonicalize()
            .map_err(|e| format!("{}: {e}", p.display()));
    }
    let looked: Vec<String> = places.iter().map(|p| p.display().to_string()).collect();
    Err(format!(
        "umbra demo lines: the HCP1065 bundle {name} is missing; looked at {} (set {HCP1065_ENV} \
         to a folder holding the ten HCP1065 .trk.gz bundles)",
        looked.join(", ")
    ))
}

/// The `--set` overrides that point each of the lines demo's line sets (`scene`, with the
/// user's `overrides`) at its bundle as [`find_bundle`] finds it.
fn bundle_overrides(
    data: &Path,
    scene: &Path,
    overrides: &[String],
) -> Result<Vec<String>, String> {
    let s = scene::spec::load(scene, overrides)?;
    let mut o = vec![];
    for (i, l) in s.lines.iter().enumerate() {
        let name = l
            .path
            .file_name()
            .ok_or_else(|| format!("{}: lines[{i}].path names no file", scene.display()))?;
        let found = find_bundle(data, &name.to_string_lossy(), &l.path)?;
        let f = found.to_string_lossy();
        // A TOML literal string where it can be one; the loader reads anything else as text.
        o.push(if f.contains('\'') || f.contains('\n') {
            format!("lines.{i}.path={f}")
        } else {
            format!("lines.{i}.path='{f}'")
        });
    }
    Ok(o)
}

/// Renders demo `which` (`mni`, `cfd` or `lines`) to `output`.
pub fn render_demo(
    which: &str,
    output: &Path,
    overrides: &[String],
    frames: u32,
) -> Result<RenderReport, String> {
    let data = datasets();
    let args = |scene: PathBuf| RenderArgs {
        scene,
        output: output.to_path_buf(),
        overrides: overrides.to_vec(),
        frames,
        aov: false,
        pass_timings: false,
        cameras: Default::default(),
        trail_range: None,
        ..Default::default()
    };
    match which {
        "mni" => {
            let scene = data.join("scenes/demo.toml");
            if !scene.exists() {
                return Err(format!(
                    "{}: the demo scene is missing (set UMBRA_DATASETS to umbra's datasets/)",
                    scene.display()
                ));
            }
            scene::render::run(&args(scene), &mut |_| {})?.failures()
        }
        "cfd" => {
            let dir = tempfile::tempdir().map_err(|e| e.to_string())?;
            let tracts = dir.path().join("carotid.trk");
            trace_carotid_demo(&data.join("vtk/carotid.vtk"), &tracts)?;
            let scene = dir.path().join("cfd.toml");
            std::fs::write(&scene, cfd_scene(&data, &tracts)).map_err(|e| e.to_string())?;
            // Errors name the demo's scene, not the temporary file it is written to.
            let named = |e: String| e.replace(&scene.display().to_string(), "the cfd demo's scene");
            scene::render::run(&args(scene.clone()), &mut |_| {})
                .map_err(named)?
                .failures()
                .map_err(named)
        }
        "lines" => {
            let scene = data.join("scenes/demo_lines.toml");
            if !scene.exists() {
                return Err(format!(
                    "{}: the lines demo's scene is missing (set UMBRA_DATASETS to umbra's datasets/)",
                    scene.display()
                ));
            }
            // The bundles first, then the user's overrides (which may move a bundle too).
            let mut o = bundle_overrides(&data, &scene, overrides)?;
            o.extend(overrides.iter().cloned());
            let mut a = args(scene);
            a.overrides = o;
            scene::render::run(&a, &mut |_| {})?.failures()
        }
        other => Err(format!("umbra demo {other}: choose lines, mni or cfd")),
    }
}

/// The carotid streamlines of `umbra demo cfd`: RK4 both ways from 20,000 random seeds in the
/// grid through `carotid` (the VTK carotid's `vectors`), kept where the flow is faster than 1
/// (the lumen: seeds in the still tissue end at once), so the lines fill every branch of the
/// bifurcation. Returns the lines and points written.
pub fn trace_carotid_demo(carotid: &Path, output: &Path) -> Result<(usize, usize), String> {
    trace_to_file(&carotid_trace(carotid, output, "random:20000"))
}

/// RK4 through the carotid's `vectors` from `seeds`, both ways, stopping below speed 1.
fn carotid_trace(carotid: &Path, output: &Path, seeds: &str) -> TraceArgs {
    TraceArgs {
        input: carotid.to_path_buf(),
        output: output.to_path_buf(),
        field: Some("vectors".into()),
        seeds: seeds.into(),
        step: None,
        integrator: tubes::trace::Integrator::Rk4,
        tolerance: 1e-3,
        max_length: None,
        min_speed: 1.0,
        mask: None,
        threshold: 0.2,
        max_angle: 60.0,
        eigen: false,
        one_way: false,
    }
}

/// The carotid streamlines of the LineAO bench (`umbra bench lineao`): RK4 from a plane of
/// 60 x 60 seeds at the inlet (z = 3) through `carotid`, written to `output` (the bench's
/// figures were measured on these). Returns the lines and points written.
pub fn trace_carotid(carotid: &Path, output: &Path) -> Result<(usize, usize), String> {
    trace_to_file(&carotid_trace(carotid, output, "plane:z=3:60"))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The demo's streamlines fill the carotid's lumen: most voxels where the flow is fast lie
    /// within a voxel of a streamline point, in every part of the vessel tree.
    #[test]
    fn the_cfd_demo_streamlines_fill_the_vessel() {
        let data = datasets();
        let carotid = data.join("vtk/carotid.vtk");
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("c.trk");
        let (lines, _) = trace_carotid_demo(&carotid, &out).unwrap();
        assert!(lines > 500, "{lines} lines");
        let v = volume::load(&carotid).unwrap();
        let f = v
            .select(Some(&"vectors:magnitude".parse().unwrap()))
            .unwrap();
        let [nx, ny, nz] = v.dims;
        let mut near = vec![false; nx * ny * nz];
        let s = tubes::load(&out).unwrap();
        let inv = v.affine.inverse();
        for p in &s.points {
            let q = inv.transform_point3(p.as_dvec3()).round();
            for dz in -1i64..=1 {
                for dy in -1i64..=1 {
                    for dx in -1i64..=1 {
                        let (x, y, z) = (q.x as i64 + dx, q.y as i64 + dy, q.z as i64 + dz);
                        if x >= 0
                            && y >= 0
                            && z >= 0
                            && (x as usize) < nx
                            && (y as usize) < ny
                            && (z as usize) < nz
                        {
                            near[x as usize + nx * (y as usize + ny * z as usize)] = true;
                        }
                    }
                }
            }
        }
        // Fast voxels (speed above 3) in each quarter of the grid along x: each mostly covered.
        for q in 0..4 {
            let (mut fast, mut hit) = (0usize, 0usize);
            for z in 0..nz {
                for y in 0..ny {
                    for x in (q * nx / 4)..((q + 1) * nx / 4) {
                        let i = x + nx * (y + ny * z);
                        if f.data[i] > 3.0 {
                            fast += 1;
                            hit += near[i] as usize;
                        }
                    }
                }
            }
            let frac = hit as f64 / fast.max(1) as f64;
            assert!(
                fast > 20 && frac > 0.8,
                "quarter {q}: {hit} of {fast} fast voxels near a line"
            );
        }
    }
}
