//! `umbra render <scene.toml> -o image.png`: the renderer of issue 5 as far as it exists - the
//! emission-absorption baseline (`render.method = "ea"`) of the scene's volume on the GPU.
//! Clipping planes apply; other methods and tubes are refused with a message that says so.

use crate::camera::{Camera, Projection};
use crate::ea_pass::{self, EaView, Transfer};
use crate::scene::{self, Method, ProjectionKind, Scene, TransferSpec};
use glam::DVec3;
use std::path::Path;
use std::time::Instant;

/// What `render` did.
#[derive(Clone, Debug, serde::Serialize)]
pub struct RenderReport {
    pub method: String,
    pub width: u32,
    pub height: u32,
    pub slices: u32,
    pub slice_distance: f64,
    pub adapter: String,
    pub seconds: f64,
}

/// Fraction of the value range below which the presets are transparent.
pub const PRESET_CUTOFF: f64 = 0.1;

/// The transfer function of a scene for a field with value range `range`: points as given, or
/// a preset's colour ramp over the range with extinction zero below [`PRESET_CUTOFF`] of it,
/// rising linearly to `extinction` at the top.
pub fn transfer(spec: &TransferSpec, range: [f64; 2]) -> Result<Transfer, String> {
    if !spec.points.is_empty() {
        if spec.points.iter().any(|p| p.gradient.is_some()) {
            return Err(
                "volume.transfer: 2-D transfer functions (gradient) are not rendered yet".into(),
            );
        }
        let points = spec
            .points
            .iter()
            .map(|p| Ok((p.value, p.color.rgb()?, p.extinction)))
            .collect::<Result<Vec<_>, String>>()?;
        return Ok(Transfer { points });
    }
    let [lo, hi] = range;
    let at = |t: f64| lo + (hi - lo) * t;
    let ramp: &[(f64, [f64; 3])] = match spec.preset.as_str() {
        "grey" => &[(0.0, [0.0; 3]), (1.0, [1.0; 3])],
        "bone" => &[
            (0.0, [0.0; 3]),
            (0.5, [0.8, 0.62, 0.45]),
            (1.0, [1.0, 0.98, 0.92]),
        ],
        "fire" => &[
            (0.0, [0.0; 3]),
            (0.4, [0.8, 0.1, 0.0]),
            (0.75, [1.0, 0.8, 0.1]),
            (1.0, [1.0, 1.0, 0.9]),
        ],
        "cool-warm" => &[
            (0.0, [0.23, 0.3, 0.75]),
            (0.5, [0.87, 0.87, 0.87]),
            (1.0, [0.71, 0.02, 0.15]),
        ],
        other => return Err(format!("volume.transfer.preset: unknown '{other}'")),
    };
    // Colour over the whole range; extinction zero up to 10% of the range (air and noise),
    // then rising linearly to `extinction` at the top.
    let colour = |t: f64| {
        let j = ramp
            .iter()
            .position(|r| r.0 >= t)
            .unwrap_or(ramp.len() - 1)
            .max(1);
        let (a, b) = (ramp[j - 1], ramp[j]);
        let u = ((t - a.0) / (b.0 - a.0)).clamp(0.0, 1.0);
        [0, 1, 2].map(|k| a.1[k] + (b.1[k] - a.1[k]) * u)
    };
    let mut ts: Vec<f64> = ramp.iter().map(|r| r.0).chain([PRESET_CUTOFF]).collect();
    ts.sort_by(f64::total_cmp);
    ts.dedup();
    Ok(Transfer {
        points: ts
            .into_iter()
            .map(|t| {
                let e = spec.extinction * ((t - PRESET_CUTOFF) / (1.0 - PRESET_CUTOFF)).max(0.0);
                (at(t), colour(t), e)
            })
            .collect(),
    })
}

/// The scene's camera for a volume with `bounds`.
pub fn camera(s: &Scene, bounds: [DVec3; 2]) -> Result<Camera, String> {
    let c = &s.camera;
    let centre = (bounds[0] + bounds[1]) * 0.5;
    let radius = ((bounds[1] - bounds[0]) * 0.5).length();
    let mut cam = match c.eye {
        Some(eye) => {
            let projection = match c.projection {
                ProjectionKind::Perspective => Projection::Perspective { fov_y_deg: c.fov_y },
                ProjectionKind::Orthographic => Projection::Orthographic {
                    height: c.height.unwrap_or(2.1 * radius),
                },
            };
            Camera::look_at(
                DVec3::from(eye),
                c.target.map(DVec3::from).unwrap_or(centre),
                DVec3::from(c.up),
                projection,
                bounds,
            )?
        }
        None => {
            let mut cam = Camera::orbit(
                bounds,
                c.azimuth,
                c.elevation,
                c.distance,
                (c.projection == ProjectionKind::Perspective).then_some(c.fov_y),
            );
            if let (Some(h), Projection::Orthographic { .. }) = (c.height, cam.projection) {
                cam.projection = Projection::Orthographic { height: h };
            }
            cam
        }
    };
    if let Some(n) = c.near {
        cam.near = n;
    }
    if let Some(f) = c.far {
        cam.far = f;
    }
    if !(cam.near > 0.0 && cam.far > cam.near) {
        return Err(format!(
            "camera.near {} and camera.far {} (given or fitted to the scene) need 0 < near < far",
            cam.near, cam.far
        ));
    }
    Ok(cam)
}

/// Renders the scene in `path` (with `--set` overrides) to `output` (PNG, sRGB).
pub fn run(path: &Path, overrides: &[String], output: &Path) -> Result<RenderReport, String> {
    let t0 = Instant::now();
    let s = scene::load(path, overrides)?;
    if s.render.method != Method::Ea {
        return Err(format!(
            "{}: render.method = {:?} is not implemented yet (issue 5); the emission-absorption baseline renders with --set render.method=ea",
            path.display(),
            s.render.method
        )
        .to_lowercase());
    }
    if !s.tubes.is_empty() {
        return Err(format!(
            "{}: tubes are not rendered yet (issue 5); remove [[tubes]] for the ea baseline",
            path.display()
        ));
    }
    if s.clip.len() > ea_pass::MAX_CLIP {
        return Err(format!(
            "{}: {} clipping planes; at most {}",
            path.display(),
            s.clip.len(),
            ea_pass::MAX_CLIP
        ));
    }
    let vspec = s
        .volume
        .as_ref()
        .ok_or_else(|| format!("{}: the ea method needs a [volume]", path.display()))?;
    let vol = volume::load(&vspec.path).map_err(|e| e.to_string())?;
    let sel = vspec
        .field
        .as_deref()
        .map(str::parse::<volume::FieldSelector>)
        .transpose()
        .map_err(|e| e.to_string())?;
    let field = vol.select(sel.as_ref()).map_err(|e| e.to_string())?;
    if field.components != 1 {
        return Err(format!(
            "volume.field: '{}' has {} components; choose NAME:magnitude or NAME:x|y|z",
            field.name, field.components
        ));
    }
    let st = field.stats();
    if !(st.min.is_finite() && st.max.is_finite()) {
        return Err(format!(
            "{}: the field has no finite values",
            vspec.path.display()
        ));
    }
    let tf = transfer(&vspec.transfer, [st.min, st.max])?;
    let cam = camera(&s, vol.bounds())?;
    let bg = s.background.rgb()?;
    let r = &s.render;
    let mut view = EaView::new(&vol, cam, r.width, r.height, r.slices, r.slice_distance, bg)
        .map_err(|e| format!("{}: {e}", path.display()))?;
    view.clip = s.clip.iter().map(|c| (c.normal, c.offset)).collect();
    let gpu = crate::gpu::Gpu::new().map_err(|e| e.to_string())?;
    let data = ea_pass::prepare(&field.data);
    let img = ea_pass::render(&gpu, &data, &vol, &tf, &view).map_err(|e| e.to_string())?;
    let rgb: Vec<[f32; 3]> = img.iter().map(|c| [c[0], c[1], c[2]]).collect();
    crate::iso_reference::write_rgb_png(output, r.width as usize, r.height as usize, &rgb)?;
    Ok(RenderReport {
        method: "ea".into(),
        width: r.width,
        height: r.height,
        slices: view.slices,
        slice_distance: view.dz,
        adapter: gpu.report().name,
        seconds: t0.elapsed().as_secs_f64(),
    })
}
