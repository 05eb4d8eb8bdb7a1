//! A scene compiled into the renderer's inputs: its model (the volume's field and transfer
//! function, a tube mesh per tube set, the isosurface's fields), the camera and the slices
//! fitted to the volume and the tubes together, the renderer's settings; [`upload`] puts the
//! model on the GPU once and [`Uploaded::draw`] renders a frame of it.

use crate::spec::{self, ProjectionKind, Scene, TransferSpec};
use engine::method::SurfaceAo;
use engine::renderer::{self, DrawOptions, GpuScene, Renderer, Settings};
use engine::slice_pass::{Samples, VolumeInput};
use glam::DVec3;
use occlusion::camera::{Camera, Projection};
use occlusion::emission_absorption::{self, EaView, Transfer};
use std::path::Path;
use tubes::lines::{LineSet, LineWidth};
use tubes::tube_mesh::TubeMesh;

/// Fraction of the value range below which the presets are transparent.
pub const PRESET_CUTOFF: f64 = 0.1;

/// A field whose robust range is less than this share of its full range gets a note when a
/// preset spans the full range.
pub const OUTLIER_SHARE: f64 = 0.1;

/// Samples the note of [`OUTLIER_SHARE`] estimates the robust range from, at most.
pub const NOTE_SAMPLES: usize = 1 << 20;

/// The transfer function of a scene for a field with value range `range`: points as given, or
/// a preset's colour ramp over the range with extinction zero below [`PRESET_CUTOFF`] of it,
/// rising linearly to `extinction` at the top.
pub fn transfer(spec: &TransferSpec, range: [f64; 2]) -> Result<Transfer, String> {
    if spec.points.iter().any(|p| p.gradient.is_some()) {
        // Rows of equal gradient magnitude, by increasing gradient, each by value.
        let mut pts = spec
            .points
            .iter()
            .map(|p| {
                Ok((
                    p.gradient.unwrap_or(0.0),
                    p.value,
                    p.color.rgb()?,
                    p.extinction,
                ))
            })
            .collect::<Result<Vec<_>, String>>()?;
        pts.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)));
        let mut rows: Vec<(f64, usize)> = vec![];
        for (i, p) in pts.iter().enumerate() {
            if rows.last().is_none_or(|r| r.0 != p.0) {
                rows.push((p.0, i));
            }
        }
        return Ok(Transfer {
            points: pts.into_iter().map(|p| (p.1, p.2, p.3)).collect(),
            rows,
        });
    }
    if !spec.points.is_empty() {
        let points = spec
            .points
            .iter()
            .map(|p| Ok((p.value, p.color.rgb()?, p.extinction)))
            .collect::<Result<Vec<_>, String>>()?;
        return Ok(Transfer {
            points,
            rows: vec![],
        });
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
        rows: vec![],
    })
}

/// A set's `colormap` key (checked when the scene was read; `None`: the built-in ramp).
fn named_map(c: &Option<String>) -> Option<volume::colormap::Colormap> {
    c.as_deref().and_then(|c| c.parse().ok())
}

/// The percentiles `volume.transfer.range = "robust"` spans: the 2nd and 98th of the finite
/// values (FSL's `fslstats -r`; NiiVue's and MRIcroGL's default window).
pub const ROBUST_PERCENTILES: [f64; 2] = [2.0, 98.0];

/// The robust range of `samples` (the values `keep` keeps: finite ones, and not the gaps'
/// stand-in where NaN was replaced; [`volume::quantile::of_samples`]): their
/// [`ROBUST_PERCENTILES`], or `full` where those coincide (a field that is mostly one value,
/// such as a mask or a padded background).
pub fn robust_range(
    samples: &Samples,
    full: [f64; 2],
    keep: impl Fn(f32) -> bool + Sync,
) -> [f64; 2] {
    let q = volume::quantile::of_samples(samples, &ROBUST_FRACTIONS, keep);
    robust_from(&q, full)
}

/// [`ROBUST_PERCENTILES`] as fractions, as [`volume::quantile`] takes them.
pub const ROBUST_FRACTIONS: [f64; 2] =
    [ROBUST_PERCENTILES[0] / 100.0, ROBUST_PERCENTILES[1] / 100.0];

/// The [`ROBUST_FRACTIONS`] quantiles of the finite ones of `len` values, estimated from every
/// k-th of them, at most [`NOTE_SAMPLES`] (exact below): what the outlier notes quote, so that
/// every render of a large field does not pay two passes over it for a note.
pub fn estimated_robust<I: Iterator<Item = f32>>(len: usize, values: impl Fn() -> I) -> Vec<f64> {
    let step = len.div_ceil(NOTE_SAMPLES).max(1);
    volume::quantile::quantiles(
        || values().step_by(step).filter(|v| v.is_finite()),
        &ROBUST_FRACTIONS,
    )
}

/// The robust range from the quantiles `q` at [`ROBUST_FRACTIONS`]: `full` where they coincide
/// in single precision, as the renderers map values (or there are none).
pub fn robust_from(q: &[f64], full: [f64; 2]) -> [f64; 2] {
    match (q[0] as f32) < (q[1] as f32) {
        true => [q[0], q[1]],
        false => full,
    }
}

/// The values a preset's ramp spans (`volume.transfer.range`): the field's finite range `full`,
/// its robust range (`robust`, asked for only then) or the values given.
pub fn preset_range(
    spec: &TransferSpec,
    full: [f64; 2],
    robust: impl FnOnce() -> [f64; 2],
) -> [f64; 2] {
    match &spec.range {
        spec::TransferRange::Values(v) => *v,
        spec::TransferRange::Named(n) if n == "robust" => robust(),
        spec::TransferRange::Named(_) => full,
    }
}

/// The `volume` colour bar: transfer function `tf`'s colours over `range` (the values its
/// ramp or the projection's window spans), labelled `label` and `map`.
pub fn volume_bar(
    label: &str,
    map: String,
    range: [f64; 2],
    tf: &Transfer,
) -> crate::annotate::ColorBar {
    let [lo, hi] = range;
    crate::annotate::ColorBar {
        label: label.to_string(),
        map,
        range,
        colors: (0..64)
            .map(|k| {
                let v = lo + (hi - lo) * (k as f64 + 0.5) / 64.0;
                tf.eval(v).0.map(|c| c as f32)
            })
            .collect(),
    }
}

/// The window the projections map through: `volume.window` over the field's finite range
/// `full` (its default) and robust range (asked for only for `"robust"`).
pub fn projection_window(
    v: &spec::VolumeSpec,
    full: [f64; 2],
    robust: impl FnOnce() -> [f64; 2],
) -> [f64; 2] {
    v.window.as_ref().map_or(full, |w| w.resolve(full, robust))
}

/// The transfer function the projections (`mip`, `minip`) show their value through:
/// `volume.colormap` (default grey) over the window `window` (`volume.window` resolved:
/// [`projection_window`]) as 256 points, each with extinction `volume.opacity` (default 1), which the
/// projection takes as its opacity; values up to the window's `lo` end (at or below it, or
/// at or above it when `lo > hi`) are transparent - a field's minimum, the empty space of a
/// default window, shows the background - and values past `hi` take the map's top.
pub fn projection_transfer(v: &spec::VolumeSpec, window: [f64; 2]) -> Result<Transfer, String> {
    let cm: volume::colormap::Colormap = v.colormap.as_deref().unwrap_or("grey").parse()?;
    let mut w = window;
    if w[0] == w[1] {
        w[1] = w[0] + 1.0;
    }
    let opacity = v.opacity.unwrap_or(1.0);
    // Transparent up to `lo`, the map from a millionth of the window past it; points by
    // increasing value (a reversed window reverses the table).
    let eps = 1e-6 * (w[1] - w[0]);
    let mut points: Vec<(f64, [f64; 3], f64)> = cm
        .linear_table()
        .iter()
        .enumerate()
        .map(|(k, c)| {
            let x = w[0] + (w[1] - w[0]) * k as f64 / 255.0;
            (
                if k == 0 { x + eps } else { x },
                c.map(|c| c as f64),
                opacity,
            )
        })
        .collect();
    points.push((w[0], [0.0; 3], 0.0));
    points.sort_by(|a, b| a.0.total_cmp(&b.0));
    Ok(Transfer {
        points,
        rows: vec![],
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
            // An orbit about `camera.target` where it is given: the same orbit moved there,
            // its clipping range fitted again.
            match c.target.map(DVec3::from) {
                Some(t) if (t - centre).length() > 0.0 => {
                    Camera::look_at(cam.eye + (t - centre), t, cam.up, cam.projection, bounds)?
                }
                _ => cam,
            }
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

/// An isosurface with its swept fields (isosurface mode, `[volume.iso]`).
pub struct IsoModel {
    pub dims: [usize; 3],
    pub affine: glam::DMat4,
    /// Classified samples (inside where >= 0, NaN as -1).
    pub g: Vec<f32>,
    pub sdf: Vec<f32>,
    pub octants: volume::occlusion_sweep::OctantFields,
    pub model: volume::occlusion_shading::AmbientModel,
    pub color: [f64; 3],
}

/// A scene's model on the CPU: the volume as the passes read it (or its isosurface), and the
/// tube meshes.
pub struct Model {
    /// The volume's grid (its fields' samples moved out), its selected field's samples
    /// packed in their stored type (`Samples::pack`: 8 or 16 bits where the values allow; NaN
    /// as -3e38 otherwise), shared with the CPU renderer, and its transfer function.
    pub volume: Option<(volume::Volume, std::sync::Arc<Samples>, Transfer)>,
    pub iso: Option<IsoModel>,
    pub meshes: Vec<TubeMesh>,
    /// `[[slices]]` and `[[overlays]]`: the grid, its fields and the slices' planes.
    pub planes: Option<crate::slices::PlaneModel>,
    /// One line set per `[[lines]]`.
    pub lines: Vec<LineSet>,
    pub bounds: [DVec3; 2],
    /// The colouring `[annotate] colorbar` names, when it names one.
    pub colorbar: Option<crate::annotate::ColorBar>,
    /// The frame of the scene's volume (drawn or as an isosurface), when it has one.
    pub space: Option<volume::Space>,
    /// Twice the default slice distance (`EaView::span` halves it): see [`slice_distance`].
    pub spacing: f64,
    /// `volume.downsample`: a volume past the GPU's bindings may be halved until it fits.
    pub downsample: bool,
    pub notes: Vec<String>,
}

impl Model {
    /// Whether the scene's world is RAS+ millimetres: its volume's frame, else RAS+ by the
    /// convention of tractograms and meshes (orientation labels, scale-bar units).
    pub fn is_ras(&self) -> bool {
        self.space.is_none_or(|s| s == volume::Space::Ras)
    }

    /// A 64-bit FNV-1a hash of the data the model holds: the volume's samples and grid (after
    /// the transfer function's NaN mapping) and every mesh's vertices, normals, colours and
    /// indices. Keys caches of results that depend on the data, not on file names.
    pub fn data_hash(&self) -> u64 {
        let mut h = crate::hash::Fnv1a::default();
        let mut eat = |bytes: &[u8]| h.eat(bytes);
        if let Some((v, data, _)) = &self.volume {
            eat(bytemuck::cast_slice(&v.dims.map(|d| d as u64)));
            eat(bytemuck::cast_slice(&v.affine.to_cols_array()));
            eat(format!("{:?}", data.packing()).as_bytes());
            eat(bytemuck::cast_slice(data.words()));
        }
        for l in &self.lines {
            eat(bytemuck::cast_slice(&l.origin.to_array()));
            for p in &l.positions {
                eat(bytemuck::cast_slice(&p.to_array()));
            }
            eat(l.colors.as_flattened());
            eat(bytemuck::cast_slice(&l.segments));
            eat(format!("{:?} {}", l.width, l.cylinder).as_bytes());
        }
        for m in &self.meshes {
            eat(bytemuck::cast_slice(&m.origin.to_array()));
            for p in m.positions.iter().chain(&m.normals) {
                eat(bytemuck::cast_slice(&p.to_array()));
            }
            eat(m.colors.as_flattened());
            eat(bytemuck::cast_slice(&m.indices));
        }
        h.finish()
    }
}

fn mesh_bounds(m: &TubeMesh) -> Option<[DVec3; 2]> {
    let mut lo = DVec3::splat(f64::INFINITY);
    let mut hi = DVec3::splat(f64::NEG_INFINITY);
    for p in &m.positions {
        let q = m.origin + p.as_dvec3();
        lo = lo.min(q);
        hi = hi.max(q);
    }
    (lo.x <= hi.x).then_some([lo, hi])
}

/// The default slice distance for a volume and transfer function, and why: half the smallest
/// voxel spacing (two samples per voxel, the Nyquist rate of trilinear data), made shorter
/// when the transfer function has features narrower than the data's value change per voxel -
/// so that the narrowest visible feature (the least value distance between transfer-function
/// points whose colour or extinction differ, not both transparent) spans two samples along the 95th-percentile gradient:
/// `w_min / (2 g95)` - but not below an eighth of the spacing (cost bound). Cost follows
/// content: a smooth transfer function on coarse data gets few slices.
pub fn slice_distance(vol: &volume::Volume, data: &Samples, tf: &Transfer) -> (f64, String) {
    let sp = vol.spacing();
    let h = sp.iter().cloned().fold(f64::INFINITY, f64::min).max(1e-12);
    let base = 0.5 * h;
    let p = &tf.points;
    let w_min = p
        .windows(2)
        .filter(|w| (w[1].1 != w[0].1 || w[1].2 != w[0].2) && w[0].2.max(w[1].2) > 0.0)
        .map(|w| w[1].0 - w[0].0)
        .filter(|&w| w > 0.0)
        .fold(f64::INFINITY, f64::min);
    if !w_min.is_finite() {
        return (base, "half the smallest voxel spacing".into());
    }
    // Gradient magnitudes (central differences, world units) on a sparse lattice of voxels.
    let [nx, ny, nz] = vol.dims;
    let step = ((nx * ny * nz) as f64 / 200_000.0).cbrt().max(1.0) as usize;
    let at = |i: usize, j: usize, k: usize| data.get(i + nx * (j + ny * k)) as f64;
    let mut g = vec![];
    for k in (1..nz.saturating_sub(1)).step_by(step) {
        for j in (1..ny.saturating_sub(1)).step_by(step) {
            for i in (1..nx.saturating_sub(1)).step_by(step) {
                // NaN samples are held as -3e38 (gaps): no gradient across them.
                let around = [
                    at(i + 1, j, k),
                    at(i - 1, j, k),
                    at(i, j + 1, k),
                    at(i, j - 1, k),
                    at(i, j, k + 1),
                    at(i, j, k - 1),
                ];
                if around.iter().any(|v| !(v.is_finite() && *v > -1e30)) {
                    continue;
                }
                let c = [
                    (at(i + 1, j, k) - at(i - 1, j, k)) / (2.0 * sp[0]),
                    (at(i, j + 1, k) - at(i, j - 1, k)) / (2.0 * sp[1]),
                    (at(i, j, k + 1) - at(i, j, k - 1)) / (2.0 * sp[2]),
                ];
                let m = (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt();
                if m.is_finite() && m > 0.0 {
                    g.push(m);
                }
            }
        }
    }
    if g.is_empty() {
        return (base, "half the smallest voxel spacing".into());
    }
    g.sort_by(f64::total_cmp);
    let g95 = g[g.len() * 95 / 100];
    let d_tf = w_min / (2.0 * g95);
    if d_tf >= base {
        (base, "half the smallest voxel spacing".into())
    } else {
        let d = d_tf.max(h / 8.0);
        (
            d,
            format!(
                "the transfer function's narrowest feature ({w_min:.4} in value) over twice the 95th-percentile gradient ({g95:.4} per world unit){}",
                if d > d_tf { ", bounded at an eighth of the voxel spacing" } else { "" }
            ),
        )
    }
}

/// Whether a tube set's path is a triangle mesh (`.ply`, `.obj`) rather than a tractogram.
pub fn is_mesh(p: &Path) -> bool {
    let n = p.to_string_lossy().to_ascii_lowercase();
    n.ends_with(".ply") || n.ends_with(".obj")
}

/// A mesh file as a tube set: read (`tubes::mesh_io::read`), moved by the set's transform
/// (normals by its inverse transpose), coloured by the set's colour when it is one (else the
/// file's vertex colours, else grey); radius and tolerance do not apply.
fn mesh_set(i: usize, t: &spec::TubesSpec) -> Result<TubeMesh, String> {
    let mut m = tubes::mesh_io::read(&t.path).map_err(|e| format!("tubes[{i}]: {e}"))?;
    if let Some(a) = t.transform {
        let rows = crate::tube_sets::transform_matrix(&a, &format!("tubes[{i}].transform"))?;
        let nm = glam::DMat3::from_mat4(rows).inverse().transpose();
        let origin = rows.transform_point3(m.origin);
        for p in &mut m.positions {
            *p = (rows.transform_point3(m.origin + p.as_dvec3()) - origin).as_vec3();
        }
        for n in &mut m.normals {
            *n = (nm * n.as_dvec3()).normalize_or_zero().as_vec3();
        }
        m.origin = origin;
    }
    if t.color.starts_with('#') {
        let c = spec::Color::Hex(t.color.clone())
            .rgb()
            .map_err(|e| format!("tubes[{i}].color: {e}"))?;
        let c = c.map(|v| (v * 255.0).round() as u8);
        m.colors = vec![c; m.positions.len()];
    }
    Ok(m)
}

/// Loads the scene's volume and builds its tube meshes.
pub fn model(s: &Scene) -> Result<Model, String> {
    let mut notes = vec![];
    if s.render.stereo == spec::Stereo::None
        && (s.render.eye_separation.is_some() || s.render.convergence.is_some())
    {
        notes.push(
            "render.eye_separation and render.convergence apply to stereo images only \
             (render.stereo = \"anaglyph\"); this image is not stereo"
                .into(),
        );
    }
    if s.camera.eye.is_none() && s.camera.up != [0.0, 0.0, 1.0] {
        notes.push(format!(
            "camera.up {:?} applies to a look-at camera (camera.eye given, or a camera path's \
             eye keys); the orbit (camera.azimuth, camera.elevation) turns about +z whatever up \
             is: give camera.eye and camera.target to look with another up",
            s.camera.up
        ));
    }
    let mut colorbar = None;
    let mut space = None;
    // The volume, loaded once: drawn by its transfer function, or in isosurface mode as its
    // isosurface.
    let (mut volume, mut iso, mut iso_bounds) = (None, None, None);
    // Slices and overlays; the slabs that crop geometry; the bounds of a volume not drawn.
    let (mut planes, mut slabs, mut hidden_bounds) = (None, vec![], None);
    if let Some(vspec) = &s.volume {
        let sel = vspec
            .field
            .as_deref()
            .map(str::parse::<volume::FieldSelector>)
            .transpose()
            .map_err(|e| e.to_string())?;
        if let Some(ispec) = &vspec.iso {
            let vol = volume::load(&vspec.path).map_err(|e| format!("volume.path: {e}"))?;
            notes.extend(
                vol.warnings
                    .iter()
                    .map(|w| format!("{}: {w}", vspec.path.display())),
            );
            space = Some(vol.space);
            // The field first: an unknown or vector field is `volume.field`'s fault, not the
            // level's.
            match vol.select(sel.as_ref()) {
                Err(e) => {
                    return Err(format!("volume.field: {}: {e}", vspec.path.display()));
                }
                Ok(f) if f.components != 1 => {
                    return Err(format!(
                        "volume.field: {}: field '{}' has {} components; an isosurface needs a \
                         scalar (select {}:magnitude)",
                        vspec.path.display(),
                        f.name,
                        f.components,
                        f.name
                    ));
                }
                Ok(_) => {}
            }
            let inside = if ispec.inside == spec::IsoInside::Below {
                volume::distance_sweep::Inside::Below
            } else {
                volume::distance_sweep::Inside::Above
            };
            let values = crate::fields::scalar_field(
                &vol,
                sel.as_ref(),
                ispec.value as f32,
                inside,
                &vspec.path,
            )
            .map_err(|e| format!("volume.iso.value: {e}"))?;
            // As the volume's rendering says of its gaps (`umbra sweep` warns the same way).
            let nan = values.iter().filter(|v| v.is_nan()).count();
            if nan > 0 {
                notes.push(format!(
                    "{}: {nan} NaN samples are taken as outside the isosurface",
                    vspec.path.display()
                ));
            }
            // The octants describe the solid cut by the scene's clipping planes: a cavity the
            // cut opens sees the sky through it (`volume::occlusion_sweep::open_cut`).
            let planes: Vec<([f64; 3], f64)> =
                s.clip.iter().map(|c| (c.normal, c.offset)).collect();
            let (sdf, octants) = crate::fields::iso_fields(
                &vol,
                &values,
                ispec.value as f32,
                inside,
                ispec.fields.as_deref(),
                None,
                true,
                None,
                &planes,
            )
            .map_err(|e| format!("volume.iso.fields: {e}"))?;
            let octants = octants.ok_or("volume.iso: the octant fields are missing")?;
            let surface = occlusion::isosurface::IsoSurface::new(
                vol.dims,
                vol.affine,
                &values,
                ispec.value as f32,
                inside == volume::distance_sweep::Inside::Above,
                &sdf,
            );
            let g = surface.g.clone();
            let sky: volume::occlusion_shading::Sky = ispec.sky.parse()?;
            let opts = volume::occlusion_shading::AmbientOptions {
                sky,
                gamma: ispec.gamma,
                offset: ispec.offset,
                ..Default::default()
            };
            iso_bounds = Some(vol.bounds());
            iso = Some(IsoModel {
                dims: vol.dims,
                affine: vol.affine,
                g,
                sdf,
                octants,
                model: volume::occlusion_shading::AmbientModel::new(opts, &vol.affine),
                color: ispec.color.rgb()?,
            });
        } else {
            // The field alone, in its stored type where it is 8 or 16-bit integers (a 16-bit
            // volume is held in 2 bytes a voxel, never as f32).
            let field = volume::load_scalar(&vspec.path, sel.as_ref()).map_err(|e| match e {
                volume::VolumeError::Invalid(_) => format!("volume.field: {e}"),
                e => format!("volume.path: {e}"),
            })?;
            let vol = field.volume;
            notes.extend(
                vol.warnings
                    .iter()
                    .map(|w| format!("{}: {w}", vspec.path.display())),
            );
            space = Some(vol.space);
            let st = field.samples.stats();
            if !(st.min.is_finite() && st.max.is_finite()) {
                return Err(format!(
                    "{}: the field has no finite values",
                    vspec.path.display()
                ));
            }
            let bad = st.nonfinite;
            if bad > 0 {
                notes.push(format!(
                    "{}: {bad} NaN or infinite samples are rendered as gaps",
                    vspec.path.display()
                ));
            }
            // The projections show their value through the volume's window and colour map.
            let projection = matches!(
                s.render.method.desc().volume,
                engine::method::VolumeShading::Projection(_)
            );
            let full = [st.min, st.max];
            let finite = |v: f32| v.is_finite();
            let preset = vspec.transfer.points.is_empty();
            let range = match projection {
                true => {
                    projection_window(vspec, full, || robust_range(&field.samples, full, finite))
                }
                false => preset_range(&vspec.transfer, full, || {
                    robust_range(&field.samples, full, finite)
                }),
            };
            // The same where a projection maps the full range by default (`volume.window` left
            // out).
            let stretched = match projection {
                true => vspec.window.is_none(),
                false => preset && vspec.transfer.range.is_full(),
            };
            if stretched && vspec.render {
                // A range that outliers stretch gives most of the field almost one colour and
                // opacity: say so, and what spans the rest. Estimated from every k-th sample,
                // at most NOTE_SAMPLES of them (exact below), so that every render of a
                // large f32 field does not pay two passes over it for a note.
                let q = estimated_robust(field.samples.len(), || field.samples.values());
                if q[0] < q[1] && (q[1] - q[0]) < OUTLIER_SHARE * (full[1] - full[0]) {
                    let n = crate::annotate::format_number;
                    let (spans, take, key) = match projection {
                        true => ("the window", "almost one colour", "volume.window"),
                        false => (
                            "the preset",
                            "almost one colour and opacity",
                            "volume.transfer.range",
                        ),
                    };
                    notes.push(format!(
                        "{}: the 2nd to 98th percentiles of the values, about [{}, {}], span \
                         {}% of the range [{}, {}] {spans} spans, so most values take {take}; \
                         {key} = \"robust\" spans them",
                        vspec.path.display(),
                        n(q[0]),
                        n(q[1]),
                        n(100.0 * (q[1] - q[0]) / (full[1] - full[0])),
                        n(full[0]),
                        n(full[1])
                    ));
                }
            }
            let tf = match projection {
                true => projection_transfer(vspec, range)?,
                false => transfer(&vspec.transfer, range)?,
            };
            if s.annotate.colorbar.as_deref() == Some("volume") {
                if !vspec.render {
                    return Err(
                        "scene key annotate.colorbar: 'volume' shows the volume's colours, and \
                         volume.render = false draws none (a slice's colours: \
                         \"slices.N\")"
                            .into(),
                    );
                }
                let map = match projection {
                    true => vspec.colormap.clone().unwrap_or_else(|| "grey".into()),
                    false => "transfer function".to_string(),
                };
                colorbar = Some(volume_bar(&field.name, map, range, &tf));
            }
            // Shared by the GPU upload and the CPU renderer; f32 samples with NaN as -3e38,
            // packed in place when they are integers after all.
            let data = std::sync::Arc::new(match field.samples.packing() {
                engine::slice_pass::Packing::F32 => {
                    Samples::pack(emission_absorption::prepare_owned(field.samples.into_f32()))
                }
                _ => field.samples,
            });
            planes =
                crate::slices::model(s, &vol, &field.name, &data, [st.min, st.max], &mut notes)?;
            if let (Some(name), Some(p)) = (
                s.annotate
                    .colorbar
                    .as_deref()
                    .and_then(|c| c.strip_prefix("overlays.")),
                &planes,
            ) {
                colorbar = p.color_bar(s, name);
            }
            if let (Some(i), Some(p)) = (
                s.annotate
                    .colorbar
                    .as_deref()
                    .and_then(|c| c.strip_prefix("slices."))
                    .and_then(|n| n.parse::<usize>().ok()),
                &planes,
            ) {
                colorbar = p.slice_bar(s, i);
            }
            slabs = crate::slices::slabs(s, vol.bounds());
            if vspec.render {
                volume = Some((vol, data, tf));
            } else {
                hidden_bounds = Some(vol.bounds());
            }
        }
    }
    let mut meshes = vec![];
    for (i, t) in s.tubes.iter().enumerate() {
        if is_mesh(&t.path) {
            if t.color != "direction" && !t.color.starts_with('#') {
                notes.push(format!(
                    "tubes[{i}].color {}: a mesh file keeps its own vertex colours (only \
                     #rrggbb replaces them)",
                    t.color
                ));
            }
            let mut mesh = mesh_set(i, t)?;
            mesh.opacity = (t.opacity < 1.0).then_some(t.opacity as f32);
            meshes.push(mesh);
            continue;
        }
        let mut sl = tubes::load(&t.path).map_err(|e| {
            // A tube set also takes a mesh: say so where the tractogram readers list theirs.
            let e = e.to_string().replace(
                "or .trx)",
                "or .trx; for [[tubes]] also a mesh, .ply or .obj)",
            );
            format!("tubes[{i}]: {e}")
        })?;
        if let Some(m) = t.transform {
            let key = format!("tubes[{i}].transform");
            sl.transform(&crate::tube_sets::transform_matrix(&m, &key)?);
        }
        let (sl, note) =
            crate::tube_sets::apply_selection(sl, t.select.as_ref(), &format!("tubes[{i}]"))?;
        notes.extend(note);
        let sl = crop_noted(sl, &slabs, 2, &format!("tubes[{i}]"), &mut notes);
        notes.extend(sl.warnings.iter().map(|w| format!("tubes[{i}]: {w}")));
        if s.annotate.colorbar.as_deref() == Some(&format!("tubes.{i}")) {
            colorbar = crate::tube_sets::color_bar(&sl, &t.color, named_map(&t.colormap))
                .map_err(|e| format!("tubes[{i}].color: {e}"))?;
        }
        let mut args =
            crate::tube_sets::TubesArgs::defaults(t.radius, t.sides, t.tolerance, &t.color);
        args.colormap = named_map(&t.colormap);
        let (mesh, _) = crate::tube_sets::build_mesh(&sl, &args)
            .map_err(|e| format!("tubes[{i}] ({}): {e}", t.path.display()))?;
        let mut mesh = mesh;
        // (With no point left at all, the selection's or the slabs' note says why.)
        if mesh.indices.is_empty() && !sl.points.is_empty() {
            notes.push(format!(
                "tubes[{i}] ({}): no tube to draw (no streamline of two distinct points)",
                t.path.display()
            ));
        }
        mesh.opacity = (t.opacity < 1.0).then_some(t.opacity as f32);
        meshes.push(mesh);
    }
    let mut lines = vec![];
    for (i, l) in s.lines.iter().enumerate() {
        let bar = s.annotate.colorbar.as_deref() == Some(&format!("lines.{i}"));
        let (set, b) = line_set(i, l, &mut notes, bar, &slabs)?;
        lines.push(set);
        colorbar = colorbar.or(b);
    }
    for (i, p) in s.points.iter().enumerate() {
        let bar = s.annotate.colorbar.as_deref() == Some(&format!("points.{i}"));
        let (set, b) = point_set(i, p, &mut notes, bar, &slabs)?;
        lines.push(set);
        colorbar = colorbar.or(b);
    }
    if let (Some(src), None) = (&s.annotate.colorbar, &colorbar) {
        return Err(format!(
            "scene key annotate.colorbar: '{src}' has no colouring to show (no finite values, or no streamline: the file holds none, or select or the slices' slabs kept none)"
        ));
    }
    let mut boxes: Vec<[DVec3; 2]> = meshes.iter().filter_map(mesh_bounds).collect();
    // A set with nothing to draw (single-point streamlines only) frames nothing.
    boxes.extend(
        lines
            .iter()
            .filter(|l| !l.segments.is_empty())
            .filter_map(LineSet::drawn_bounds),
    );
    if let Some((v, _, _)) = &volume {
        boxes.push(v.bounds());
    }
    if let Some(b) = iso_bounds {
        boxes.push(b);
    }
    if let Some(b) = hidden_bounds {
        boxes.push(b);
    }
    let Some(first) = boxes.first().copied() else {
        // The notes say why a set came out empty (a selection that kept nothing, ...).
        let why = match notes.is_empty() {
            true => String::new(),
            false => format!(" ({})", notes.join("; ")),
        };
        return Err(format!(
            "the scene has no [volume] and no [[tubes]], [[lines]] or [[points]] with geometry{why}"
        ));
    };
    let bounds = boxes
        .iter()
        .fold(first, |a, b| [a[0].min(b[0]), a[1].max(b[1])]);
    let spacing = match &volume {
        // The projections use no transfer function: its features ask for no shorter slices.
        Some((v, _, _))
            if matches!(
                s.render.method,
                engine::method::Method::Mip | engine::method::Method::MinIp
            ) =>
        {
            let sp = v.spacing();
            sp.iter().cloned().fold(f64::INFINITY, f64::min).max(1e-12)
        }
        Some((v, data, tf)) => {
            let (d, why) = slice_distance(v, data, tf);
            if s.render.slices.is_none()
                && s.render.slice_distance.is_none()
                && !why.starts_with("half")
            {
                notes.push(format!("default slice distance {d:.4}: {why}"));
            }
            2.0 * d
        }
        // A volume not drawn that slices cut: its grid's voxels, as when it is drawn.
        None if planes.is_some() => {
            let a = planes.as_ref().unwrap().affine;
            [a.x_axis, a.y_axis, a.z_axis]
                .iter()
                .map(|c| c.truncate().length())
                .fold(f64::INFINITY, f64::min)
                .max(1e-12)
        }
        None => (bounds[1] - bounds[0]).length().max(1e-9) / 512.0,
    };
    Ok(Model {
        volume,
        iso,
        meshes,
        planes,
        lines,
        bounds,
        spacing,
        downsample: s.volume.as_ref().is_some_and(|v| v.downsample),
        notes,
        colorbar,
        space,
    })
}

/// The line set of `[[lines]]` number `i`: the tractogram read (its reader's warnings added to
/// `notes`), transformed and coloured.
fn line_set(
    i: usize,
    l: &spec::LinesSpec,
    notes: &mut Vec<String>,
    want_bar: bool,
    slabs: &[crate::slices::Slab],
) -> Result<(LineSet, Option<crate::annotate::ColorBar>), String> {
    let mut sl = tubes::load(&l.path).map_err(|e| format!("lines[{i}]: {e}"))?;
    let file_empty = sl.is_empty();
    if let Some(m) = l.transform {
        let key = format!("lines[{i}].transform");
        sl.transform(&crate::tube_sets::transform_matrix(&m, &key)?);
    }
    let (sl, note) =
        crate::tube_sets::apply_selection(sl, l.select.as_ref(), &format!("lines[{i}]"))?;
    notes.extend(note);
    let sl = crop_noted(sl, slabs, 2, &format!("lines[{i}]"), notes);
    let bar = match want_bar {
        true => crate::tube_sets::color_bar(&sl, &l.color, named_map(&l.colormap))
            .map_err(|e| format!("lines[{i}].color: {e}"))?,
        false => None,
    };
    let width = match l.width_unit {
        spec::WidthUnit::Pixels => LineWidth::Pixels(l.width),
        spec::WidthUnit::World => LineWidth::World(l.width),
    };
    let cylinder = l.profile == spec::LineProfile::Cylinder;
    notes.extend(sl.warnings.iter().map(|w| format!("lines[{i}]: {w}")));
    // A file without streamlines says so (a scene of nothing else is refused with this why; a
    // selection or a slab that kept none has said so already).
    if file_empty {
        notes.push(format!(
            "lines[{i}] ({}): the file holds no streamlines",
            l.path.display()
        ));
    }
    // A line needs two points: streamlines of one are left out, and said so.
    let single = (0..sl.len()).filter(|&k| sl.line(k).len() < 2).count();
    if single > 0 {
        notes.push(format!(
            "lines[{i}] ({}): {single} of {} streamlines have a single point and are not drawn \
             (a line needs two; [[points]] draws points)",
            l.path.display(),
            sl.len()
        ));
    }
    let proxy_radius = l.proxy_radius() as f32;
    let times = match &l.time {
        None => vec![],
        Some(t) => {
            let name = t.strip_prefix("scalar:").unwrap_or(t);
            let a = sl
                .point_attributes
                .iter()
                .find(|a| a.name == name)
                .ok_or_else(|| {
                    let have: Vec<&str> =
                        sl.point_attributes.iter().map(|a| a.name.as_str()).collect();
                    format!(
                        "lines[{i}].time ({}): the tractogram has no per-point '{name}' (it has: {})",
                        l.path.display(),
                        if have.is_empty() { "none".into() } else { have.join(", ") }
                    )
                })?;
            a.values
                .iter()
                .step_by(a.components.max(1))
                .copied()
                .collect()
        }
    };
    // Everything that reads the streamlines comes first: the line set then takes their points
    // (a whole-brain tractogram is not copied).
    let taper_u = l.taper.as_ref().map(|t| {
        (0..sl.len())
            .flat_map(|k| tubes::lines::taper_u(sl.line(k).len(), t.vertices as usize, t.u as f32))
            .collect()
    });
    let filter = l
        .filter
        .as_ref()
        .map(|f| crate::tube_sets::point_values(&sl, f))
        .transpose()
        .map_err(|e| format!("lines[{i}].filter ({}): {e}", l.path.display()))?;
    let names: Vec<String> = sl.point_attributes.iter().map(|a| a.name.clone()).collect();
    let names: Vec<&str> = names.iter().map(String::as_str).collect();
    let mut set =
        crate::tube_sets::with_color_map_of(&names, &l.color, named_map(&l.colormap), |c| {
            LineSet::from_streamlines(sl, c, width, cylinder)
        })
        .map_err(|e| format!("lines[{i}].color ({}): {e}", l.path.display()))?;
    set.proxy_radius = proxy_radius;
    set.times = times;
    set.halo = l.halo.as_ref().and_then(|h| h.halo());
    if let (Some(t), Some(u)) = (&l.taper, taper_u) {
        set.taper_t = t.u as f32;
        set.taper_u = u;
    }
    if let Some(values) = filter {
        if !values.iter().any(|&v| v >= l.filter_min as f32) {
            notes.push(format!(
                "lines[{i}].filter_min: no point of {} reaches {}: nothing of the set is drawn",
                l.path.display(),
                l.filter_min
            ));
        }
        set.filter = values;
        set.filter_min = l.filter_min as f32;
        set.filter_taper = l.filter_taper as f32;
    }
    set.trail = l.trail.as_ref().map(|t| tubes::lines::Trail {
        now: t.now as f32,
        back: t.back as f32,
        forward: t.forward as f32,
        start: t.start as f32,
        min_width: t.min_width as f32,
    });
    Ok((set, bar))
}

/// [`crate::slices::crop`] with a note of what the slices' slabs kept (a slab placed away from
/// a tractogram removed all of it, silently).
fn crop_noted(
    sl: tubes::Streamlines,
    slabs: &[crate::slices::Slab],
    min_points: usize,
    what: &str,
    notes: &mut Vec<String>,
) -> tubes::Streamlines {
    if slabs.is_empty() {
        return sl;
    }
    let before = sl.points.len();
    let sl = crate::slices::crop(sl, slabs, min_points);
    notes.push(format!(
        "{what}: the slices' slabs keep {} of {before} points{}",
        sl.points.len(),
        if sl.points.is_empty() && before > 0 {
            " (nothing of it is drawn: move the slab, widen it, or leave it out)"
        } else {
            ""
        }
    ));
    sl
}

/// The point cloud of `[[points]]` number `i` as a line set of discs (`LineSet::points`).
fn point_set(
    i: usize,
    p: &spec::PointsSpec,
    notes: &mut Vec<String>,
    want_bar: bool,
    slabs: &[crate::slices::Slab],
) -> Result<(LineSet, Option<crate::annotate::ColorBar>), String> {
    let mut sl = tubes::points::read(&p.path).map_err(|e| format!("points[{i}]: {e}"))?;
    if let Some(m) = p.transform {
        let key = format!("points[{i}].transform");
        sl.transform(&crate::tube_sets::transform_matrix(&m, &key)?);
    }
    let sl = crop_noted(sl, slabs, 1, &format!("points[{i}]"), notes);
    notes.extend(sl.warnings.iter().map(|w| format!("points[{i}]: {w}")));
    if sl.points.is_empty() {
        notes.push(format!("points[{i}] ({}): no points", p.path.display()));
    }
    let mut set = crate::tube_sets::with_color_map(&sl, &p.color, named_map(&p.colormap), |c| {
        LineSet::points(&sl, c, LineWidth::World(p.size))
    })
    .map_err(|e| format!("points[{i}].color ({}): {e}", p.path.display()))?;
    set.halo = p.halo.as_ref().and_then(|h| h.halo());
    let bar = match want_bar {
        true => crate::tube_sets::color_bar(&sl, &p.color, named_map(&p.colormap))
            .map_err(|e| format!("points[{i}].color: {e}"))?,
        false => None,
    };
    Ok((set, bar))
}

/// The renderer's settings from a scene.
pub fn settings(s: &Scene) -> Settings {
    let r = &s.render;
    let l = &s.light;
    Settings {
        method: r.method,
        theta_deg: r.theta,
        blur_samples: r.blur_samples,
        vicinity_samples: r.vicinity_samples,
        vicinity_distance: r.vicinity_distance,
        vicinity_bias: r
            .vicinity_bias
            .unwrap_or(spec::VICINITY_BIAS * r.vicinity_distance),
        geometry_extinction: r.geometry_extinction,
        column: r.geometry_shadow == spec::GeometryShadow::Column,
        combine: r.combine,
        fxaa: fxaa_on(r),
        light: [l.ambient, l.diffuse, l.specular, l.shininess],
        occlusion_cell: r.occlusion_cell,
        occlusion_step: r.occlusion_step,
        cone: r.occlusion_model == spec::OcclusionModel::Cone,
        msaa: if r.bits == 1 { 1 } else { r.msaa },
        surface_ao: r.surface_ao,
        lineao: r
            .lineao
            .settings([l.ambient, l.diffuse, l.specular, l.shininess]),
        trail_now: None,
        illustrative: (
            r.illustrative.line.rgb().unwrap_or([0.0; 3]),
            r.illustrative.halo.rgb().unwrap_or([1.0; 3]),
        ),
        translucent_layers: r.translucent_layers,
    }
}

/// The slices and image of a scene for a model.
pub fn view(s: &Scene, m: &Model) -> Result<EaView, String> {
    view_from(s, m, camera(s, m.bounds)?)
}

/// The view of `s` through `cam` (a stereo eye of the scene's camera, say).
fn view_from(s: &Scene, m: &Model, cam: Camera) -> Result<EaView, String> {
    let r = &s.render;
    let mut v = EaView::span(
        m.bounds,
        m.spacing,
        cam,
        r.width,
        r.height,
        r.slices,
        r.slice_distance,
        s.background.rgb()?,
    )?;
    v.clip = s.clip.iter().map(|c| (c.normal, c.offset)).collect();
    Ok(v)
}

/// The clipping planes that cut the tubes.
pub fn tube_clip(s: &Scene) -> Vec<([f64; 3], f64)> {
    s.clip
        .iter()
        .filter(|c| !c.volume_only)
        .map(|c| (c.normal, c.offset))
        .collect()
}

/// Halves the grid (2x2x2 box filter, NaN samples left out of the means; odd edges keep their
/// last sample) until the field fits in `max_bytes` as f32; `None` when it already fits. The
/// new voxel centres lie at the old ones' means, so the affine is scaled by 2 and shifted by
/// half an old voxel. Returns the volume (geometry only: an empty field), its data, and a note.
pub fn fit_volume(
    vol: &volume::Volume,
    data: &Samples,
    max_bytes: u64,
) -> Option<(volume::Volume, Vec<f32>, String)> {
    if (data.len() as u64) * 4 <= max_bytes {
        return None;
    }
    // The first halving reads the samples where they are (no f32 copy of the whole volume).
    let (mut dims, mut affine) = (vol.dims, vol.affine);
    let mut d: Option<Vec<f32>> = None;
    while (d.as_ref().map_or(data.len(), Vec::len) as u64) * 4 > max_bytes
        && dims.iter().any(|&n| n > 1)
    {
        let get = |i: usize| match &d {
            Some(d) => d[i],
            None => data.get(i),
        };
        let nd = dims.map(|n| n.div_ceil(2));
        let mut out = vec![0.0f32; nd[0] * nd[1] * nd[2]];
        for k in 0..nd[2] {
            for j in 0..nd[1] {
                for i in 0..nd[0] {
                    let (mut sum, mut n) = (0.0f64, 0u32);
                    for c in 0..8 {
                        let (x, y, z) = (2 * i + (c & 1), 2 * j + (c >> 1 & 1), 2 * k + (c >> 2));
                        if x < dims[0] && y < dims[1] && z < dims[2] {
                            let v = get(x + dims[0] * (y + dims[1] * z));
                            if v > -1e30 {
                                sum += v as f64;
                                n += 1;
                            }
                        }
                    }
                    out[i + nd[0] * (j + nd[1] * k)] = if n > 0 {
                        (sum / n as f64) as f32
                    } else {
                        -3e38
                    };
                }
            }
        }
        affine = affine
            * glam::DMat4::from_translation(DVec3::splat(0.5))
            * glam::DMat4::from_scale(DVec3::splat(2.0));
        dims = nd;
        d = Some(out);
    }
    let d = d.unwrap_or_else(|| data.to_f32().into_owned());
    let note = format!(
        "the volume ({} x {} x {}, {} MB as f32) exceeds the {} MB this adapter binds in its storage bindings: downsampled by 2x2x2 box filtering to {} x {} x {}",
        vol.dims[0],
        vol.dims[1],
        vol.dims[2],
        (data.len() * 4) >> 20,
        max_bytes >> 20,
        dims[0],
        dims[1],
        dims[2]
    );
    volume::check_frame(dims, affine).ok()?;
    // The grid only (the samples are `d`).
    let v = volume::Volume {
        format: vol.format.clone(),
        dims,
        affine,
        space: vol.space,
        fields: vec![volume::Field {
            name: "downsampled".into(),
            components: 1,
            stored: volume::ScalarType::F32,
            data: vec![],
        }],
        default_field: 0,
        warnings: vec![],
    };
    Some((v, d, note))
}

/// Renders a loaded scene: the frame and the view it was seen through. A volume larger than
/// eight of the adapter's storage bindings is downsampled first when `volume.downsample` asks
/// for it ([`fit_volume`], with a note), else a GPU frame of it is an error naming the key.
pub fn render_scene(
    gpu: &engine::gpu::Gpu,
    s: &Scene,
    m: &Model,
    frames: u32,
) -> Result<(renderer::Output, EaView), String> {
    let up = upload(gpu, m)?;
    let (mut out, v) = up.draw(
        s,
        m,
        DrawOptions {
            frames,
            pass_timings: true,
        },
    )?;
    let mut notes = up.notes.clone();
    notes.append(&mut out.notes);
    out.notes = notes;
    Ok((out, v))
}

/// A scene's model on the GPU ([`upload`]): frames at any camera, settings or size cost only
/// their passes.
pub struct Uploaded<'g> {
    pub renderer: Renderer<'g>,
    pub scene: GpuScene,
    /// What the upload changed (a volume downsampled to fit the adapter).
    pub notes: Vec<String>,
    /// The volume for the native CPU renderer (`render.device`), prepared at its first frame.
    cpu: std::sync::OnceLock<Result<raycast::EaVolume, String>>,
    /// Whether the volume went to the GPU ([`upload_for`] leaves it on the CPU when the
    /// native CPU renderer draws every frame).
    volume_on_gpu: bool,
    /// Why the volume is not on the GPU when it was to be (too large for the bindings without
    /// `volume.downsample`): the error of a frame the GPU would draw.
    refused: Option<String>,
}

/// Bytes a pixel of a CPU frame takes at its peak: the march's pixels (24), the frame's
/// image, opacity and depth (24), and the output's image and AOVs (16).
pub const CPU_FRAME_BYTES_PER_PIXEL: u64 = 64;

/// Refuses a CPU frame whose buffers this process cannot allocate (an address-space limit
/// such as `ulimit -v`, or a size past the machine), naming the keys, instead of aborting in
/// the middle of the frame: the buffers are reserved, not touched, and given back.
pub fn check_cpu_frame_memory(width: u32, height: u32) -> Result<(), String> {
    let bytes = width as u64 * height as u64 * CPU_FRAME_BYTES_PER_PIXEL;
    let mut probe: Vec<u8> = Vec::new();
    usize::try_from(bytes)
        .ok()
        .and_then(|b| probe.try_reserve_exact(b).ok())
        .ok_or_else(|| {
            format!(
                "scene keys render.width and render.height: a {width} x {height} frame needs \
                 about {:.1} GiB for the CPU renderer, more than this process can allocate",
                bytes as f64 / (1u64 << 30) as f64
            )
        })
}

/// Whether the native CPU renderer draws the frames of `s` with model `m` on `gpu`
/// (`render.device`: `cpu`, or `auto` on a CPU adapter, and nothing it refuses).
pub fn drawn_on_cpu(s: &Scene, m: &Model, gpu: &engine::gpu::Gpu) -> bool {
    match (s.render.device, cpu_refusal(s, m)) {
        (spec::Device::Cpu, None) => true,
        (spec::Device::Auto, None) => gpu.is_cpu(),
        _ => false,
    }
}

/// Why the native CPU renderer cannot draw a frame of `s` with model `m` (`None`: it can):
/// it draws volume-only scenes with a 1-D transfer function, unshaded or lit by the light
/// volume (`ea`, `dos`, `combined` and the methods whose volume is `ea`'s) or projected
/// (`mip`, `minip`), whose surface terms have no channels of their own.
pub fn cpu_refusal(s: &Scene, m: &Model) -> Option<String> {
    use engine::method::VolumeShading;
    let desc = s.render.method.desc();
    if desc.volume == VolumeShading::Phong {
        return Some(format!(
            "method {} (Phong volume shading is drawn on the GPU)",
            desc.name
        ));
    }
    if m.planes.as_ref().is_some_and(|p| !p.planes.is_empty()) {
        return Some("slices (drawn on the GPU)".into());
    }
    if m.planes.as_ref().is_some_and(|p| p.blend.is_some()) {
        return Some("an overlay blended into the volume (drawn on the GPU)".into());
    }
    if m.iso.is_some() {
        return Some("an isosurface ([volume.iso])".into());
    }
    let Some((_, _, tf)) = &m.volume else {
        return Some("no volume to draw (no [volume], or volume.render = false)".into());
    };
    if !m.meshes.is_empty() || !m.lines.is_empty() {
        return Some("tubes, lines or points (geometry is drawn on the GPU)".into());
    }
    if !tf.rows.is_empty() {
        return Some("a 2-D transfer function".into());
    }
    if cpu_layers(s)
        .iter()
        .any(|(_, c)| *c == Some(SurfaceAo::LineAo))
    {
        return Some("a LineAO term (its AOV channels come from the GPU pass)".into());
    }
    None
}

/// The surface terms' layers a frame of `s` has (all 1 on a volume-only frame).
fn cpu_layers(s: &Scene) -> Vec<(&'static str, Option<SurfaceAo>)> {
    engine::terms::layers(s.render.method, s.render.surface_ao)
}

/// The light volume's settings for the CPU renderer when the method lights the volume: the
/// GPU pass's cells and steps (`occlusion::combined::light_grid` with the adapter's binding limit),
/// model, angle and taps; an error when the light volume exceeds that limit, as on the GPU.
fn cpu_light(s: &Scene, v: &EaView, limit: u64) -> Result<Option<raycast::LightSettings>, String> {
    use engine::method::VolumeShading;
    if s.render.method.desc().volume != VolumeShading::Occlusion {
        return Ok(None);
    }
    let r = &s.render;
    let (cell, step) =
        occlusion::combined::light_grid(r.occlusion_cell, r.occlusion_step, false, v, limit);
    renderer::LightGrid::new(v, cell, step).fits(limit)?;
    Ok(Some(raycast::LightSettings {
        cell,
        step,
        cone: r.occlusion_model == spec::OcclusionModel::Cone,
        theta_deg: r.theta,
        blur_samples: r.blur_samples,
    }))
}

/// [`upload`] for a one-shot render: the line sets' points are freed as they go up (the
/// frames read them from the GPU only), so a tractogram is never held twice.
/// With `volume_on_gpu` false the volume stays on the CPU (for frames the native CPU renderer
/// draws: [`drawn_on_cpu`]): no GPU copy, and no downsampling to fit the adapter.
pub fn upload_freeing_lines<'g>(
    gpu: &'g engine::gpu::Gpu,
    m: &mut Model,
    volume_on_gpu: bool,
) -> Result<Uploaded<'g>, String> {
    let mut lines = std::mem::take(&mut m.lines);
    let up = upload_for(gpu, m, volume_on_gpu);
    let up = up.and_then(|mut up| {
        up.renderer
            .upload_lines_freeing(&mut up.scene, &mut lines)
            .map_err(out_of_memory_hint)?;
        Ok(up)
    });
    m.lines = lines;
    up
}

/// A GPU error as text; running out of GPU memory adds the scene keys that need less.
fn out_of_memory_hint(e: engine::gpu::GpuError) -> String {
    match e {
        engine::gpu::GpuError::OutOfMemory { .. } => format!(
            "{e}; scene keys that need less: volume.downsample = true (a volume halved until it \
             fits), render.device = \"cpu\" (a volume-only scene drawn without the GPU), fewer \
             streamlines (select.subsample of [[tubes]] and [[lines]])"
        ),
        e => e.to_string(),
    }
}

/// Uploads a model once: the volume (split over the storage bindings the adapter has left, 20
/// on lavapipe; when even those cannot hold it, downsampled with a note if `volume.downsample`
/// asks for it, else left off the GPU), its transfer function, the tube meshes and the isosurface's fields.
pub fn upload<'g>(gpu: &'g engine::gpu::Gpu, m: &Model) -> Result<Uploaded<'g>, String> {
    upload_for(gpu, m, true)
}

/// [`upload`], the volume left on the CPU unless `volume_on_gpu` (see
/// [`upload_freeing_lines`]).
pub fn upload_for<'g>(
    gpu: &'g engine::gpu::Gpu,
    m: &Model,
    volume_on_gpu: bool,
) -> Result<Uploaded<'g>, String> {
    let limit = gpu.storage_limit();
    let capacity = |p| engine::slice_pass::max_volume_samples(gpu, p) as u64 * 4;
    // A volume is split over the storage bindings the adapter has (slice_pass::volume_parts);
    // beyond that it is halved when `volume.downsample` asks for it, else left on the CPU
    // (the CPU renderer draws it whole; a GPU frame is an error naming the key).
    let refused = m
        .volume
        .as_ref()
        .filter(|(_, data, _)| {
            volume_on_gpu && !m.downsample && data.len() as u64 * 4 > capacity(data.packing())
        })
        .map(|(vol, data, _)| {
            format!(
                "scene key volume.downsample: the volume ({} x {} x {}, {} MB) exceeds the {} MB \
                 this adapter binds in {} storage bindings; set volume.downsample = true to \
                 draw it halved until it fits (volume-only scenes draw it whole with \
                 render.device = \"cpu\")",
                vol.dims[0],
                vol.dims[1],
                vol.dims[2],
                data.bytes() >> 20,
                (engine::slice_pass::volume_parts(gpu) as u64 * gpu.storage_limit()) >> 20,
                engine::slice_pass::volume_parts(gpu)
            )
        });
    let volume_on_gpu = volume_on_gpu && refused.is_none();
    let gpu_volume = m.volume.as_ref().filter(|_| volume_on_gpu);
    let fitted = gpu_volume.and_then(|(vol, data, _)| {
        if data.len() as u64 * 4 <= capacity(data.packing()) {
            return None;
        }
        // The means of a downsampled volume are f32: fit its f32 capacity.
        let f32_capacity = capacity(engine::slice_pass::Packing::F32);
        fit_volume(vol, data, f32_capacity).map(|(v, d, note)| (v, Samples::pack(d), note))
    });
    let mut notes = vec![];
    if let Some((_, _, note)) = &fitted {
        notes.push(note.clone());
    }
    let vi = gpu_volume.map(|(vol, data, tf)| match &fitted {
        Some((fv, fd, _)) => VolumeInput {
            vol: fv,
            data: fd,
            tf,
        },
        None => VolumeInput {
            vol,
            data: data.as_ref(),
            tf,
        },
    });
    if let Some(i) = &m.iso {
        let bytes = (i.g.len() as u64) * 8;
        if bytes > limit {
            return Err(format!(
                "volume.iso: the octant fields ({} MB) exceed this adapter's storage binding limit ({} MB)",
                bytes >> 20,
                limit >> 20
            ));
        }
    }
    let iso = m.iso.as_ref().map(|i| engine::iso_pass::IsoInput {
        dims: i.dims,
        affine: i.affine,
        g: &i.g,
        sdf: &i.sdf,
        octants: &i.octants,
        model: &i.model,
        color: i.color,
    });
    let renderer = Renderer::new(gpu);
    let mut scene = renderer
        .upload(vi.as_ref(), &m.meshes, &m.lines, iso.as_ref())
        .map_err(out_of_memory_hint)?;
    if let Some(p) = &m.planes {
        renderer
            .upload_planes(&mut scene, &p.grid(), &p.planes, p.blend.as_ref())
            .map_err(|e| format!("slices: {e}"))?;
    }
    Ok(Uploaded {
        renderer,
        scene,
        notes,
        cpu: std::sync::OnceLock::new(),
        volume_on_gpu,
        refused,
    })
}

/// Whether the frame's final image goes through FXAA (`render.fxaa`; a two-valued image has no
/// use for smoothed edges), on either device.
fn fxaa_on(r: &spec::RenderSpec) -> bool {
    r.fxaa && r.bits != 1
}

/// A frame of the native CPU renderer as the renderer's output: the image, the volumetric
/// occlusion and the depth where the volume passed half opacity (as the GPU's AOVs of a
/// volume-only frame), every surface term's layer 1 (no surfaces), timed `opts.frames` times
/// (`total_ms` the median; passes `light`, `raycast` and `fxaa` when pass times are asked
/// for). With `fxaa` the image goes through the GPU pass's FXAA on the CPU
/// (`engine::fxaa::fxaa_cpu`), so that both devices draw the same image.
fn cpu_frame(
    ev: &raycast::EaVolume,
    v: &EaView,
    opts: DrawOptions,
    light: Option<&raycast::LightSettings>,
    projection: Option<occlusion::projection::Extremum>,
    layers: &[(&'static str, Option<SurfaceAo>)],
    fxaa: bool,
) -> renderer::Output {
    let mut frames_ms = vec![];
    let mut light_ms = vec![];
    let mut fxaa_ms = vec![];
    let mut raycast_ms = vec![];
    let mut frame = None;
    for _ in 0..opts.frames.max(1) {
        let t = std::time::Instant::now();
        let mut f = match projection {
            Some(which) => ev.render_projection(v, which),
            None => ev.render_frame(v, light),
        };
        let mut smoothing = 0.0;
        if fxaa {
            let t = std::time::Instant::now();
            f.image = engine::fxaa::fxaa_cpu(&f.image, v.width, v.height);
            smoothing = t.elapsed().as_secs_f64() * 1e3;
            fxaa_ms.push(smoothing);
        }
        let whole = t.elapsed().as_secs_f64() * 1e3;
        frames_ms.push(whole);
        light_ms.push(f.light_ms);
        raycast_ms.push((whole - f.light_ms - smoothing).max(0.0));
        frame = Some(f);
    }
    let frame = frame.expect("at least one frame");
    let median = renderer::median;
    let total_ms = median(&frames_ms);
    let aov = frame
        .volumetric
        .iter()
        .zip(&frame.half_depth)
        .map(|(&volumetric, &depth)| renderer::Aov {
            volumetric,
            partial: 1.0,
            vicinity: 1.0,
            combined: 1.0,
            depth,
        })
        .collect();
    let n = frame.image.len();
    let mut passes = std::collections::BTreeMap::new();
    if opts.pass_timings {
        // Each pass's median over the frames; `raycast` is the rest of each frame (the march
        // and compositing), so the three need not add up to the median frame exactly.
        if light.is_some() {
            passes.insert("light".to_string(), median(&light_ms));
        }
        passes.insert("raycast".to_string(), median(&raycast_ms));
        if fxaa {
            passes.insert("fxaa".to_string(), median(&fxaa_ms));
        }
    }
    renderer::Output {
        notes: vec!["drawn by the native CPU renderer (render.device)".into()],
        aov,
        image: frame.image,
        terms: layers
            .iter()
            .map(|(name, _)| (*name, vec![1.0; n]))
            .collect(),
        term_channels: vec![],
        timings: renderer::Timings {
            total_ms,
            frames_ms,
            passes,
            pass_clock: None,
        },
        triangles: 0,
        light: light.map(|l| renderer::LightGrid::new(v, l.cell, l.step)),
    }
}

/// A note where the scene sets the light volume's keys (`render.occlusion_cell`,
/// `render.occlusion_step`) for a method that sweeps no light: they change nothing there.
fn unused_light_keys(s: &Scene) -> Option<String> {
    let r = &s.render;
    let set: Vec<&str> = [
        ("render.occlusion_cell", r.occlusion_cell.is_some()),
        ("render.occlusion_step", r.occlusion_step.is_some()),
    ]
    .into_iter()
    .filter_map(|(k, on)| on.then_some(k))
    .collect();
    let desc = r.method.desc();
    // An isosurface alone is drawn as `ea` draws it, whatever the method (the renderer's
    // `iso_only`): no light volume.
    let iso_alone = s.volume.as_ref().is_some_and(|v| v.iso.is_some())
        && s.tubes.is_empty()
        && s.lines.is_empty()
        && s.points.is_empty()
        && s.slices.is_empty()
        && s.overlays.is_empty();
    // Nothing in the light (no volume or tubes; slices only with the paper's column, which
    // they cast; lines that stand for no tubes, as pixel-wide lines do by default): the
    // renderer sweeps none.
    let nothing_casts = s.volume.as_ref().is_none_or(|v| !v.render)
        && s.tubes.is_empty()
        && s.points.is_empty()
        && (s.slices.is_empty() || s.render.geometry_shadow != spec::GeometryShadow::Column)
        && s.lines.iter().all(|l| l.proxy_radius() == 0.0);
    let unused =
        desc.volume != engine::method::VolumeShading::Occlusion || iso_alone || nothing_casts;
    (!set.is_empty() && unused).then(|| {
        let one = set.len() == 1;
        let who = match (iso_alone, nothing_casts) {
            (true, _) => "an isosurface alone".to_string(),
            (false, true) => "a scene of slices and lines that cast no shadow (no volume or tubes; slices with render.geometry_shadow \"inside\"; lines[].proxy_radius 0)".to_string(),
            _ => format!("method {}", desc.name),
        };
        format!(
            "{} {} the light volume of dos and combined; {who} sweeps none, so {} nothing \
             here",
            set.join(" and "),
            if one { "shapes" } else { "shape" },
            if one { "it changes" } else { "they change" }
        )
    })
}

/// A note where the method projects a volume (`mip`, `minip`) and the scene draws none: its
/// surfaces are drawn as the projections draw them (head-lit, no occlusion), nothing behind.
fn projection_of_nothing(s: &Scene, m: &Model) -> Option<String> {
    let desc = s.render.method.desc();
    let projects = matches!(desc.volume, engine::method::VolumeShading::Projection(_));
    (projects && m.volume.is_none()).then(|| {
        format!(
            "method {} projects the volume, and this scene draws none (no [volume], or \
             volume.render = false): only its surfaces are drawn, head-lit",
            desc.name
        )
    })
}

/// A note where `[[slices]]` are drawn by the illustrative method, which inks every surface
/// in `render.illustrative.line`: a slice comes out one solid colour.
fn inked_slices(s: &Scene) -> Option<String> {
    (s.render.method == spec::Method::Illustrative && !s.slices.is_empty()).then(|| {
        format!(
            "method illustrative draws every surface in render.illustrative.line, the {} \
             slice(s) too: they show no data (lineao or illuminated draw slices with lines)",
            s.slices.len()
        )
    })
}

/// A note where the scene gives `camera.height` (an orthographic camera's view height, also
/// keyed by a camera path) to a perspective camera: it changes nothing there.
fn unused_camera_keys(s: &Scene) -> Option<String> {
    (s.camera.projection == spec::ProjectionKind::Perspective && s.camera.height.is_some()).then(
        || {
            "camera.height (the scene's, or a camera path's keyed height) is an orthographic \
             camera's view height; this camera is perspective (camera.projection), so it \
             changes nothing here (camera.distance and fov_y frame a perspective view)"
                .to_string()
        },
    )
}

/// A note where the scene sets `render.lineao` (any of its keys off its default) for a method
/// that draws no LineAO: it changes nothing there.
fn unused_lineao_keys(s: &Scene) -> Option<String> {
    if s.render.lineao == spec::LineAoSpec::default() {
        return None;
    }
    let desc = s.render.method.desc();
    let draws = desc.terms.iter().any(|t| match t {
        engine::method::Term::Ao(a) => *a == SurfaceAo::LineAo,
        engine::method::Term::SurfaceAo => s.render.surface_ao == SurfaceAo::LineAo,
        engine::method::Term::Partial => false,
    });
    (!draws).then(|| {
        format!(
            "render.lineao shapes LineAO (method lineao, or a method with render.surface_ao = \
             \"lineao\"); method {} draws none, so it changes nothing here",
            desc.name
        )
    })
}

impl<'g> Uploaded<'g> {
    /// This upload drawing a share of its geometry: per tube mesh of the model the triangles
    /// `indices[i]`, per line set the segments `segments[i]` (in point order). The volume,
    /// slices, isosurface, vertices and points are shared with it on the GPU; only the two
    /// lists are uploaded. Frames of it take the model it was uploaded from.
    pub fn with_shares(
        &self,
        indices: &[Vec<u32>],
        segments: &[Vec<u32>],
    ) -> Result<Uploaded<'g>, String> {
        let renderer = Renderer::new(self.renderer.gpu());
        let scene = renderer
            .upload_shares(&self.scene, indices, segments)
            .map_err(|e| e.to_string())?;
        Ok(Uploaded {
            renderer,
            scene,
            notes: self.notes.clone(),
            cpu: std::sync::OnceLock::new(),
            volume_on_gpu: self.volume_on_gpu,
            refused: self.refused.clone(),
        })
    }
}

impl Uploaded<'_> {
    /// Replaces the uploaded slices with `planes` on the grid of `p` (the model's
    /// [`crate::slices::PlaneModel`] this was uploaded from, whose `planes` the caller sets to
    /// the same list: frames take both); the grid's fields stay on the GPU, as does the rest
    /// of the upload.
    pub fn set_planes(
        &mut self,
        p: &crate::slices::PlaneModel,
        planes: &[engine::planes::PlaneInput],
    ) -> Result<(), String> {
        self.renderer
            .replace_planes(&mut self.scene, &p.grid(), planes)
            .map_err(|e| format!("slices: {e}"))
    }

    /// One frame of scene `s` (its camera, clipping planes, settings and size; its data must
    /// be the uploaded model `m`'s).
    pub fn draw(
        &self,
        s: &Scene,
        m: &Model,
        opts: DrawOptions,
    ) -> Result<(renderer::Output, EaView), String> {
        self.draw_at(s, m, opts, None)
    }

    /// [`Uploaded::draw`] with every line set's trail drawn at time `trail_now` (when given).
    pub fn draw_at(
        &self,
        s: &Scene,
        m: &Model,
        opts: DrawOptions,
        trail_now: Option<f64>,
    ) -> Result<(renderer::Output, EaView), String> {
        let v = view(s, m)?;
        let mut st = settings(s);
        st.trail_now = trail_now.map(|t| t as f32);
        let cpu = match (s.render.device, cpu_refusal(s, m)) {
            (spec::Device::Cpu, Some(why)) => {
                return Err(format!(
                    "scene key render.device: \"cpu\" cannot draw this scene: {why}"
                ))
            }
            (spec::Device::Cpu, None) => true,
            (spec::Device::Auto, None) => self.renderer.gpu().is_cpu(),
            _ => false,
        };
        if !cpu && !self.volume_on_gpu && m.volume.is_some() {
            if let Some(why) = &self.refused {
                return Err(why.clone());
            }
            return Err(
                "the volume was left on the CPU for the CPU renderer, which cannot draw this \
                 frame (render.device)"
                    .into(),
            );
        }
        let cpu = match cpu {
            true => Some(
                self.cpu
                    .get_or_init(|| {
                        let (vol, data, tf) = m.volume.as_ref().expect("checked by cpu_refusal");
                        raycast::EaVolume::shared(vol, data.clone(), tf)
                    })
                    .as_ref()
                    .map_err(|e| format!("the CPU renderer: {e}"))?,
            ),
            false => None,
        };
        if cpu.is_some() {
            check_cpu_frame_memory(v.width, v.height)?;
        }
        let limit = self
            .renderer
            .gpu()
            .device
            .limits()
            .max_storage_buffer_binding_size;
        let layers = cpu_layers(s);
        let draw_one = |v: &EaView| match cpu {
            Some(ev) => Ok(cpu_frame(
                ev,
                v,
                opts,
                cpu_light(s, v, limit)?.as_ref(),
                match s.render.method.desc().volume {
                    engine::method::VolumeShading::Projection(e) => Some(e),
                    _ => None,
                },
                &layers,
                fxaa_on(&s.render),
            )),
            None => self
                .renderer
                .draw(&self.scene, v, &tube_clip(s), &st, opts)
                .map_err(|e| e.to_string()),
        };
        let unused: Vec<String> = unused_light_keys(s)
            .into_iter()
            .chain(unused_lineao_keys(s))
            .chain(unused_camera_keys(s))
            .chain(inked_slices(s))
            .chain(projection_of_nothing(s, m))
            .collect();
        let draw = |v: &EaView| {
            let mut out = draw_one(v)?;
            out.notes.extend(unused.clone());
            Ok::<_, String>(out)
        };
        if s.render.stereo == spec::Stereo::None {
            return Ok((draw(&v)?, v));
        }
        // Anaglyph: the frame from both eyes (occlusion::stereo), mixed on the CPU; the AOVs
        // are the left eye's, the times those of both frames together.
        let cam = v.camera;
        let conv = s
            .render
            .convergence
            .unwrap_or_else(|| occlusion::stereo::default_convergence(&cam));
        let sep = s
            .render
            .eye_separation
            .unwrap_or(conv * occlusion::stereo::SEPARATION_RATIO);
        let [l, r] = occlusion::stereo::eyes(&cam, sep, conv);
        let mut left = draw(&view_from(s, m, l)?)?;
        let right = draw(&view_from(s, m, r)?)?;
        for (a, b) in left.image.iter_mut().zip(&right.image) {
            *a = occlusion::stereo::anaglyph(*a, *b);
        }
        let t = &mut left.timings;
        t.total_ms += right.timings.total_ms;
        for (a, b) in t.frames_ms.iter_mut().zip(&right.timings.frames_ms) {
            *a += b;
        }
        for (k, b) in &right.timings.passes {
            *t.passes.entry(k.clone()).or_insert(0.0) += b;
        }
        Ok((left, v))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `tubes[].sides` meshes scene tubes with that many sides a ring (it was fixed at 8), and
    /// a count outside 3-256 is refused naming the key.
    #[test]
    fn scene_tubes_take_their_sides() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/fixtures/tracts/dipy");
        let scene =
            |sides: &str| format!("[[tubes]]\npath = \"tracks300.trk\"\nradius = 0.3\n{sides}");
        let tri = |sides: &str| {
            let s = spec::parse(&scene(sides), "t.toml", &dir, &[]).unwrap();
            model(&s)
                .unwrap()
                .meshes
                .iter()
                .map(|m| m.triangles())
                .sum::<usize>()
        };
        let (eight, three, sixteen) = (tri(""), tri("sides = 3\n"), tri("sides = 16\n"));
        // Rings and caps both scale with the sides: triangles in proportion.
        assert_eq!(eight * 3, three * 8, "{eight} and {three}");
        assert_eq!(eight * 2, sixteen, "{eight} and {sixteen}");
        for bad in ["sides = 2\n", "sides = 257\n"] {
            let e = spec::parse(&scene(bad), "t.toml", &dir, &[]).unwrap_err();
            assert!(e.contains("tubes[0].sides"), "{e}");
        }
    }

    /// A scene whose only lines come from a file without streamlines is refused with the
    /// entry and the file named (it said only "the scene has no [volume] ... with geometry").
    #[test]
    fn lines_from_an_empty_file_are_named_in_the_refusal() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/fixtures/tracts/nibabel");
        let s = spec::parse("[[lines]]\npath = \"empty.tck\"\n", "e.toml", &dir, &[]).unwrap();
        let e = model(&s).err().expect("refused");
        assert!(
            e.contains("no [volume]") && e.contains("lines[0]") && e.contains("no streamlines"),
            "{e}"
        );
    }

    /// A selection that keeps no streamline leaves its colour bar nothing to show (a bar of the
    /// colouring volume's range was drawn over no line), and says so once: the file holds
    /// streamlines (the note that it held none was false).
    #[test]
    fn an_empty_selection_has_no_colour_bar_and_no_false_note() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/fixtures/tracts/dipy");
        let vol =
            Path::new(env!("CARGO_MANIFEST_DIR")).join("../datasets/vtk/headsq_64x64x93.nhdr");
        let text = |bar: &str| {
            format!(
                "[[lines]]\npath = \"tracks300.trk\"\ncolor = \"volume:{}\"\n\
                 select = {{ include_spheres = [[1000.0, 1000.0, 1000.0, 1.0]] }}\n\
                 [[lines]]\npath = \"tracks300.trk\"\n{bar}",
                vol.display()
            )
        };
        let s = spec::parse(
            &text("[annotate]\ncolorbar = \"lines.0\"\n"),
            "l.toml",
            &dir,
            &[],
        )
        .unwrap();
        let e = model(&s).err().expect("refused");
        assert!(
            e.contains("annotate.colorbar") && e.contains("select or the slices' slabs kept none"),
            "{e}"
        );
        let m = model(&spec::parse(&text(""), "l.toml", &dir, &[]).unwrap()).unwrap();
        assert!(
            m.notes.iter().any(|n| n.contains("select kept 0 of 300")),
            "{:?}",
            m.notes
        );
        assert!(
            !m.notes.iter().any(|n| n.contains("holds no streamlines")),
            "{:?}",
            m.notes
        );
    }

    /// Slices under the illustrative method are noted (they come out one solid ink); not under
    /// other methods, and not without slices.
    #[test]
    fn slices_inked_by_the_illustrative_method_are_noted() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../datasets/vtk");
        let note = |method: &str, slices: &str| {
            let text = format!(
                "[volume]\npath = \"headsq_64x64x93.nhdr\"\nrender = false\n{slices}[[lines]]\npath = \"../../tests/fixtures/tracts/dipy/tracks300.trk\"\n[render]\nmethod = \"{method}\"\n"
            );
            inked_slices(&spec::parse(&text, "s.toml", &dir, &[]).unwrap())
        };
        let sl = "[[slices]]\naxis = \"axial\"\n";
        let e = note("illustrative", sl).expect("a note");
        assert!(e.contains("the 1 slice(s) too"), "{e}");
        assert!(note("lineao", sl).is_none());
        assert!(note("illustrative", "").is_none());
    }

    /// `camera.height` on a perspective camera gets a note; not on an orthographic one, and not
    /// when left out.
    #[test]
    fn a_height_for_a_perspective_camera_is_noted() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/fixtures/tracts/dipy");
        let note = |camera: &str| {
            let text = format!("[camera]\n{camera}[[lines]]\npath = \"tracks300.trk\"\n");
            unused_camera_keys(&spec::parse(&text, "c.toml", &dir, &[]).unwrap())
        };
        let e = note("height = 50.0\n").expect("a note");
        assert!(
            e.contains("camera.height") && e.contains("perspective"),
            "{e}"
        );
        assert!(note("projection = \"orthographic\"\nheight = 50.0\n").is_none());
        assert!(note("").is_none());
    }

    /// `render.lineao` set for a method that draws no LineAO gets a note; not for `lineao`, not
    /// for `combined` with `surface_ao = "lineao"`, and not when left at its defaults.
    #[test]
    fn lineao_keys_that_change_nothing_are_noted() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/fixtures/tracts/dipy");
        let note = |render: &str| {
            let text = format!("[[lines]]\npath = \"tracks300.trk\"\n[render]\n{render}");
            unused_lineao_keys(&spec::parse(&text, "l.toml", &dir, &[]).unwrap())
        };
        let set = "[render.lineao]\nsamples = 16\n";
        let e = note(&format!("method = \"illuminated\"\n{set}")).expect("a note");
        assert!(e.contains("method illuminated draws none"), "{e}");
        assert!(note(&format!("method = \"lineao\"\n{set}")).is_none());
        assert!(note(&format!(
            "method = \"combined\"\nsurface_ao = \"lineao\"\n{set}"
        ))
        .is_none());
        assert!(note(&format!("method = \"combined\"\n{set}")).is_some());
        assert!(note("method = \"illuminated\"\n").is_none());
    }

    #[test]
    fn an_orbit_camera_orbits_its_target() {
        let bounds = [DVec3::new(0.0, 0.0, 0.0), DVec3::new(40.0, 20.0, 30.0)];
        let centre = (bounds[0] + bounds[1]) * 0.5;
        for ortho in [false, true] {
            let mut s = spec::parse("", "t", Path::new("."), &[]).unwrap();
            s.camera.azimuth = 70.0;
            s.camera.elevation = -25.0;
            if ortho {
                s.camera.projection = ProjectionKind::Orthographic;
            }
            let about_centre = camera(&s, bounds).unwrap();
            let t = DVec3::new(5.0, 15.0, 2.0);
            s.camera.target = Some(t.to_array());
            let moved = camera(&s, bounds).unwrap();
            // The same orbit, translated by target - centre: same direction, same distance.
            assert!((moved.eye - (about_centre.eye + (t - centre))).length() < 1e-9);
            assert!((moved.target - t).length() < 1e-12);
            assert!((moved.forward() - about_centre.forward()).length() < 1e-12);
            assert_eq!(moved.projection, about_centre.projection);
            assert!(moved.near > 0.0 && moved.far > moved.near);
            // The target at the centre is the plain orbit.
            s.camera.target = Some(centre.to_array());
            assert_eq!(camera(&s, bounds).unwrap().eye, about_centre.eye);
        }
    }

    #[test]
    fn the_slice_distance_follows_the_data_and_the_transfer_function() {
        // A ramp of 1 per voxel (spacing 1): a smooth transfer function keeps half a voxel;
        // a feature 0.4 wide needs 0.2; a step is bounded at an eighth of a voxel.
        let vol = volume::synthetic::sample_scalar(
            [32, 8, 8],
            volume::synthetic::cube_affine([32, 8, 8], 0.0, 31.0),
            "ramp",
            |p: DVec3| p.x,
        );
        // Packed in 8 bits (integers 0..31): the distance reads the stored type.
        let data = Samples::pack(vol.select(None).unwrap().data);
        assert_ne!(data.packing(), engine::slice_pass::Packing::F32);
        let smooth = Transfer::ramp(0.0, 31.0, [1.0; 3], 1.0);
        assert_eq!(slice_distance(&vol, &data, &smooth).0, 0.5);
        let narrow = Transfer {
            points: vec![(10.0, [1.0; 3], 0.0), (10.4, [1.0; 3], 1.0)],
            rows: vec![],
        };
        let (d, why) = slice_distance(&vol, &data, &narrow);
        assert!((d - 0.2).abs() < 1e-9, "{d} {why}");
        let step = Transfer {
            points: vec![(10.0, [1.0; 3], 0.0), (10.0001, [1.0; 3], 1.0)],
            rows: vec![],
        };
        let (d, why) = slice_distance(&vol, &data, &step);
        assert_eq!(d, 0.125);
        assert!(why.contains("eighth"), "{why}");
        // NaN samples (gaps, held as -3e38) give no gradient: a third of the ramp NaN leaves
        // the narrow feature's 0.2, where the gaps' jumps would have bounded it at 0.125.
        let mut values = vol.select(None).unwrap().data;
        for (n, v) in values.iter_mut().enumerate() {
            if n % 32 < 10 {
                *v = f32::NAN;
            }
        }
        let gaps = Samples::pack(emission_absorption::prepare_owned(values));
        let (d, why) = slice_distance(&vol, &gaps, &narrow);
        assert!((d - 0.2).abs() < 1e-9, "{d} {why}");
    }

    #[test]
    fn oversized_volumes_are_halved_until_they_fit() {
        let vol = volume::synthetic::validation_scene(33);
        let data = vol.select(None).unwrap().data;
        let samples = Samples::f32(data.clone());
        assert!(fit_volume(&vol, &samples, data.len() as u64 * 4).is_none());
        let (v, d, note) = fit_volume(&vol, &samples, 20_000).unwrap();
        assert_eq!(v.dims, [17, 17, 17]);
        assert!(d.len() * 4 <= 20_000, "{}", d.len());
        assert!(
            note.contains("downsampled") && note.contains("17 x 17 x 17"),
            "{note}"
        );
        // The same world box (up to the half voxel at the odd edge) and a box-filtered field.
        let (a, b) = (vol.bounds(), v.bounds());
        let half = 0.5 * vol.spacing()[0];
        assert!(
            (a[0] - (b[0] - DVec3::splat(half))).length() < 1e-9,
            "{a:?} {b:?}"
        );
        assert!((v.spacing()[0] - 4.0 * half).abs() < 1e-9);
        // New voxel (3, 4, 5) is the mean of old voxels (6..8, 8..10, 10..12).
        let mut sum = 0.0;
        for c in 0..8 {
            sum += data[vol.index(6 + (c & 1), 8 + (c >> 1 & 1), 10 + (c >> 2))] as f64;
        }
        assert!((d[3 + 17 * (4 + 17 * 5)] as f64 - sum / 8.0).abs() < 1e-4);
        // Integer samples are halved from their stored type as from f32, twice over when
        // once is not enough.
        let ints: Vec<f32> = data.iter().map(|v| (v * 100.0).round()).collect();
        let packed = Samples::pack(ints.clone());
        assert_ne!(packed.packing(), engine::slice_pass::Packing::F32);
        let (v1, d1, _) = fit_volume(&vol, &packed, 4_000).unwrap();
        let (v2, d2, _) = fit_volume(&vol, &Samples::f32(ints), 4_000).unwrap();
        assert_eq!((v1.dims, v2.dims), ([9, 9, 9], [9, 9, 9]));
        assert_eq!(d1, d2);
    }
}
