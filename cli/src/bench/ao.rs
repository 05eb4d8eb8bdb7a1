//! `umbra bench ao <scene.toml> --spp N -o <dir>`: the inputs of the cross-check of the tubes'
//! ambient occlusion against an independent renderer.

use crate::output::out;
use scene::{compile, spec};
use std::path::{Path, PathBuf};

/// `umbra bench ao`.
#[derive(clap::Args)]
pub struct Args {
    scene: PathBuf,
    #[arg(long, default_value_t = 1024)]
    spp: u32,
    /// Only tubes this near occlude (world units; default: any distance).
    #[arg(long)]
    max_distance: Option<f64>,
    #[arg(long = "set", value_name = "KEY=VALUE")]
    set: Vec<String>,
    #[arg(short, long)]
    output: PathBuf,
}

pub fn run(a: Args) -> Result<(), String> {
    let mean = ao(&a.scene, &a.set, a.spp, a.max_distance, &a.output)?;
    out(format!("mean ambient occlusion (open fraction) {mean:.5}"))?;
    eprintln!(
        "wrote {0}/ao.exr, {0}/tubes.ply, {0}/camera.json",
        a.output.display()
    );
    Ok(())
}

/// `umbra bench ao <scene.toml> --spp N -o <dir>`: the tubes' hemisphere ambient occlusion
/// (`reference_tubes::hemisphere_ao`) seen by the scene's camera, for the cross-check against
/// an independent renderer (`bench/mitsuba_ao.py`): writes `<dir>/ao.exr` (channels `Y`, the
/// mean, and `stderr`), the tubes as one world-space mesh `<dir>/tubes.ply`, and
/// `<dir>/camera.json` (eye, target, up, vertical field of view, width, height). Perspective
/// cameras only; the volume is left out.
pub fn ao(
    scene_path: &Path,
    overrides: &[String],
    spp: u32,
    max_distance: Option<f64>,
    out: &Path,
) -> Result<f64, String> {
    if max_distance.is_some_and(|d| !(d > 0.0 && d.is_finite())) {
        return Err("--max-distance: must be a positive number".into());
    }
    if spp == 0 {
        return Err("--spp: must be at least 1".into());
    }
    let mut s = spec::load(scene_path, overrides)?;
    if s.tubes.is_empty() {
        return Err(format!(
            "{}: bench ao needs [[tubes]] (the volume, lines and points are left out)",
            scene_path.display()
        ));
    }
    s.volume = None;
    let m = compile::model(&s).map_err(|e| format!("{}: {e}", scene_path.display()))?;
    if m.meshes.is_empty() {
        return Err(format!(
            "{}: bench ao needs [[tubes]]",
            scene_path.display()
        ));
    }
    let v = compile::view(&s, &m)?;
    let occlusion::camera::Projection::Perspective { fov_y_deg } = v.camera.projection else {
        return Err("bench ao: the cross-check needs a perspective camera".into());
    };
    std::fs::create_dir_all(out).map_err(|e| format!("{}: {e}", out.display()))?;
    let ts = occlusion::reference_tubes::TubeScene::new(&m.meshes, &compile::tube_clip(&s));
    let (w, h) = (v.width as usize, v.height as usize);
    let (mean, se) =
        occlusion::reference_tubes::hemisphere_ao(&ts, &v.camera, w, h, spp, 0x5eed, max_distance);
    {
        use exr::prelude::*;
        let ch = |name: &str, x: &[f64]| {
            AnyChannel::new(
                name,
                FlatSamples::F32(x.iter().map(|&v| v as f32).collect()),
            )
        };
        let mut list: SmallVec<[AnyChannel<FlatSamples>; 4]> = SmallVec::new();
        list.push(ch("Y", &mean));
        list.push(ch("stderr", &se));
        let img = Image::from_channels((w, h), AnyChannels::sort(list));
        let mut bytes = std::io::Cursor::new(Vec::new());
        img.write()
            .to_buffered(&mut bytes)
            .map_err(|e| format!("ao.exr: {e}"))?;
        volume::write_atomic(&out.join("ao.exr"), bytes.get_ref()).map_err(|e| e.to_string())?;
    }
    // One mesh in world coordinates (origin zero).
    let mut all = tubes::tube_mesh::TubeMesh::default();
    for mesh in &m.meshes {
        let base = all.positions.len() as u32;
        all.positions.extend(
            mesh.positions
                .iter()
                .map(|p| (mesh.origin + p.as_dvec3()).as_vec3()),
        );
        all.normals.extend(&mesh.normals);
        all.colors.extend(&mesh.colors);
        all.indices.extend(mesh.indices.iter().map(|i| i + base));
    }
    tubes::mesh_io::write(&out.join("tubes.ply"), &all).map_err(|e| e.to_string())?;
    let c = &v.camera;
    let cam = serde_json::json!({
        "eye": [c.eye.x, c.eye.y, c.eye.z],
        "target": [c.target.x, c.target.y, c.target.z],
        "up": [c.up.x, c.up.y, c.up.z],
        "fov_y": fov_y_deg,
        "width": w,
        "height": h,
        "spp": spp,
    });
    volume::write_atomic(&out.join("camera.json"), cam.to_string().as_bytes())
        .map_err(|e| e.to_string())?;
    Ok(mean.iter().sum::<f64>() / mean.len().max(1) as f64)
}
