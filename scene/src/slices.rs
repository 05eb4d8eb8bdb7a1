//! `[[slices]]` and `[[overlays]]` compiled into the renderer's slice planes
//! (`engine::planes`): overlays read and resampled into the scene volume's grid (trilinear, or
//! nearest for labels; `volume::regrid`), label tables (FreeSurfer colour tables or a colour
//! per label), each slice's polygon (its plane cut by the volume's grid box) and layers, and
//! the slabs that crop tubes, lines and points.

use crate::spec::{OverlaySpec, Scene, SliceAxis, SliceSpec, Window};
use engine::planes::{LayerMap, PlaneInput, PlaneLayer, MAX_LABELS, MAX_LAYERS};
use glam::{DMat4, DVec3, DVec4, Vec3};
use volume::colormap::Colormap;
use volume::regrid::Interp;

/// The slices' model: the grid (the scene volume's), its fields (the volume's, then each
/// overlay's resampled into the grid, in `[[overlays]]` order) and the slices.
pub struct PlaneModel {
    pub dims: [usize; 3],
    pub affine: DMat4,
    pub fields: Vec<Vec<f32>>,
    pub planes: Vec<PlaneInput>,
    /// Each overlay's colour mapping and opacity, in `[[overlays]]` order.
    pub overlays: Vec<(LayerMap, f32)>,
    /// The values of each of `fields` (the volume's, then the overlays'): their finite range
    /// (a slice's window where none is given; the file's, for an overlay) and their robust one
    /// (`"robust"` windows; of the values in the grid).
    pub ranges: Vec<FieldRange>,
    /// The scene volume's bounds (a slice's default position is their centre).
    pub bounds: [DVec3; 2],
    /// The name of the volume's field (a slice's colour bar's label).
    pub field: String,
    /// The overlay blended into the volume rendering (`volume_blend`), as a layer of the grid.
    pub blend: Option<PlaneLayer>,
}

impl PlaneModel {
    /// The colour bar of scalar overlay `name` (`annotate.colorbar = "overlays.NAME"`): its
    /// colour map over its range.
    pub fn color_bar(&self, s: &Scene, name: &str) -> Option<crate::annotate::ColorBar> {
        let k = s.overlays.iter().position(|o| o.name == name)?;
        let (LayerMap::Scalar { lo, hi, .. }, _) = self.overlays.get(k)? else {
            return None;
        };
        let cm: Colormap = s.overlays[k]
            .colormap
            .as_deref()
            .unwrap_or("red-yellow")
            .parse()
            .ok()?;
        Some(crate::annotate::ColorBar {
            label: name.to_string(),
            map: cm.name().to_string(),
            range: [*lo, *hi],
            colors: (0..64)
                .map(|i| cm.rgb((i as f64 + 0.5) / 64.0).map(|c| c as f32))
                .collect(),
        })
    }
    /// The colour bar of slice `i` (`annotate.colorbar = "slices.N"`): its colour map over
    /// its window, labelled with the volume's field name or the overlay's name it shows;
    /// `None` for a slice of a label overlay.
    pub fn slice_bar(&self, s: &Scene, i: usize) -> Option<crate::annotate::ColorBar> {
        let sl = s.slices.get(i)?;
        let LayerMap::Scalar { lo, hi, .. } = &self.planes.get(i)?.layers.first()?.map else {
            return None;
        };
        let (label, map) = match &sl.volume {
            None => (
                self.field.clone(),
                sl.colormap
                    .as_deref()
                    .or(s.volume.as_ref().and_then(|v| v.colormap.as_deref()))
                    .unwrap_or("grey"),
            ),
            Some(name) => {
                let o = s.overlays.iter().find(|o| &o.name == name)?;
                (
                    name.clone(),
                    sl.colormap
                        .as_deref()
                        .or(o.colormap.as_deref())
                        .unwrap_or("red-yellow"),
                )
            }
        };
        let cm: Colormap = map.parse().ok()?;
        Some(crate::annotate::ColorBar {
            label,
            map: cm.name().to_string(),
            range: [*lo, *hi],
            colors: (0..64)
                .map(|k| cm.rgb((k as f64 + 0.5) / 64.0).map(|c| c as f32))
                .collect(),
        })
    }

    /// The slices of `s` (another state of the scene this model was made for: the same volume
    /// and overlays) on this model's grid and fields: what moving, hiding or restyling slices
    /// changes, without reading or resampling anything. Slabs are not taken into account
    /// (they crop the geometry: a model anew).
    /// Also the notes the slices get (an outlier note: [`is_slice_note`]).
    pub fn replan(&self, s: &Scene) -> Result<(Vec<PlaneInput>, Vec<String>), String> {
        let vspec = s.volume.as_ref().ok_or("slices need a [volume]")?;
        let mut notes = vec![];
        let planes = planes_of(s, vspec, self, &mut notes)?;
        Ok((planes, notes))
    }

    /// The span `[lo, hi]` of the grid's voxel centres along unit normal `n` (where a slice
    /// normal to `n` cuts the grid).
    pub fn extent(&self, n: DVec3) -> [f64; 2] {
        extent(self.dims, self.affine, n)
    }

    /// The grid as the renderer takes it.
    pub fn grid(&self) -> engine::planes::PlaneGrid<'_> {
        engine::planes::PlaneGrid {
            dims: self.dims,
            affine: self.affine,
            fields: self.fields.iter().map(Vec::as_slice).collect(),
        }
    }
}

/// The values of one of a [`PlaneModel`]'s fields: its finite range, and its robust range
/// (the [`crate::compile::ROBUST_PERCENTILES`] of its finite values in the grid; the full range
/// where they coincide), computed when first asked for.
pub struct FieldRange {
    pub full: [f64; 2],
    robust: std::sync::OnceLock<[f64; 2]>,
}

impl FieldRange {
    /// A field whose finite range is `full` (widened where its ends coincide in single
    /// precision, as a constant field's do: [`usable`]).
    pub fn new(full: [f64; 2]) -> FieldRange {
        FieldRange {
            full: usable(full),
            robust: Default::default(),
        }
    }

    /// The robust range of `values` (this field's values in the grid; gaps held as -3e38 are
    /// left out).
    pub fn robust(&self, values: &[f32]) -> [f64; 2] {
        *self.robust.get_or_init(|| {
            let q = volume::quantile::quantiles(
                || {
                    values
                        .iter()
                        .copied()
                        .filter(|v| v.is_finite() && *v > -1e30)
                },
                &crate::compile::ROBUST_FRACTIONS,
            );
            usable(crate::compile::robust_from(&q, self.full))
        })
    }
}

/// A slab that crops geometry: the unit normal, the slice's position along it and half the
/// thickness.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Slab {
    pub normal: DVec3,
    pub position: f64,
    pub half: f64,
}

impl Slab {
    pub fn contains(&self, p: Vec3) -> bool {
        let d = self.normal.dot(tubes::to_f64(p)) - self.position;
        d.abs() <= self.half
    }
}

/// A slice's unit normal.
pub fn normal(s: &SliceSpec) -> DVec3 {
    match (s.axis, s.normal) {
        (Some(SliceAxis::Axial), _) => DVec3::Z,
        (Some(SliceAxis::Coronal), _) => DVec3::Y,
        (Some(SliceAxis::Sagittal), _) => DVec3::X,
        (None, Some(n)) => DVec3::from(n).normalize(),
        (None, None) => DVec3::Z,
    }
}

/// A slice's position along its normal: as given, or the centre of `bounds`.
pub fn position(s: &SliceSpec, bounds: [DVec3; 2]) -> f64 {
    s.position
        .unwrap_or_else(|| normal(s).dot(0.5 * (bounds[0] + bounds[1])))
}

/// The slabs of the slices that have one (`bounds`: the scene volume's).
pub fn slabs(s: &Scene, bounds: [DVec3; 2]) -> Vec<Slab> {
    s.slices
        .iter()
        .filter_map(|sl| {
            sl.slab.map(|w| Slab {
                normal: normal(sl),
                position: position(sl, bounds),
                half: 0.5 * w,
            })
        })
        .collect()
}

/// The streamlines cropped to the slabs (mrview's crop to slab): every point outside all of
/// them is removed and its streamline split there; pieces of fewer than `min_points` points
/// are dropped; attributes follow (`tubes::select::crop`).
pub fn crop(s: tubes::Streamlines, slabs: &[Slab], min_points: usize) -> tubes::Streamlines {
    if slabs.is_empty() {
        return s;
    }
    tubes::select::crop(&s, |p| slabs.iter().any(|b| b.contains(p)), min_points)
}

/// Corner `c` (0..8, bit k set: the last index along axis k) of the box of a grid's voxel
/// centres, in world.
fn corner(dims: [usize; 3], affine: DMat4, c: usize) -> DVec3 {
    let hi = dims.map(|d| d.saturating_sub(1) as f64);
    let q = DVec3::new(
        if c & 1 != 0 { hi[0] } else { 0.0 },
        if c & 2 != 0 { hi[1] } else { 0.0 },
        if c & 4 != 0 { hi[2] } else { 0.0 },
    );
    (affine * DVec4::from((q, 1.0))).truncate()
}

/// The polygon where the plane `normal . p = position` cuts the box of a grid's voxel
/// centres (`dims`, index-to-world `affine`), in order around it; `None` when it misses.
pub fn polygon(
    dims: [usize; 3],
    affine: DMat4,
    normal: DVec3,
    position: f64,
) -> Option<Vec<DVec3>> {
    let corner = |c: usize| corner(dims, affine, c);
    let mut pts: Vec<DVec3> = vec![];
    for a in 0..8usize {
        for bit in [1usize, 2, 4] {
            if a & bit != 0 {
                continue;
            }
            let (p, q) = (corner(a), corner(a | bit));
            let (fa, fb) = (normal.dot(p) - position, normal.dot(q) - position);
            let x = if fa == 0.0 {
                p
            } else if fb == 0.0 {
                q
            } else if (fa < 0.0) != (fb < 0.0) {
                p + (q - p) * (fa / (fa - fb))
            } else {
                continue;
            };
            let scale = (p - q).length().max(1e-300);
            if !pts.iter().any(|y| (*y - x).length() <= 1e-9 * scale) {
                pts.push(x);
            }
        }
    }
    if pts.len() < 3 {
        return None;
    }
    let c = pts.iter().copied().sum::<DVec3>() / pts.len() as f64;
    let u = normal.any_orthonormal_vector();
    let v = normal.cross(u);
    pts.sort_by(|a, b| {
        let (da, db) = (*a - c, *b - c);
        da.dot(v)
            .atan2(da.dot(u))
            .total_cmp(&db.dot(v).atan2(db.dot(u)))
    });
    // A plane along a face of a flat grid: no area to draw.
    let area: f64 = (1..pts.len() - 1)
        .map(|k| (pts[k] - pts[0]).cross(pts[k + 1] - pts[0]).length())
        .sum();
    (area > 0.0).then_some(pts)
}

/// The polygon as a mesh (a fan of triangles about its first corner, normal `n`).
fn polygon_mesh(pts: &[DVec3], n: DVec3) -> tubes::tube_mesh::TubeMesh {
    let origin = pts.iter().copied().sum::<DVec3>() / pts.len() as f64;
    tubes::tube_mesh::TubeMesh {
        origin,
        positions: pts.iter().map(|p| (*p - origin).as_vec3()).collect(),
        normals: vec![n.as_vec3(); pts.len()],
        colors: vec![[200, 200, 200]; pts.len()],
        indices: (1..pts.len() as u32 - 1)
            .flat_map(|k| [0, k, k + 1])
            .collect(),
        radius: 0.0,
        opacity: None,
    }
}

/// A window that can be mapped in single precision: ends too close for f32 (a constant field;
/// a width under the smallest normal f32) are widened to a relative 1e-3 or by one.
fn usable(w: [f64; 2]) -> [f64; 2] {
    // (A width below the smallest normal f32 is taken as zero where subnormals are flushed.)
    if (w[1] as f32) - (w[0] as f32) >= f32::MIN_POSITIVE {
        w
    } else {
        [w[0], w[0] + (1e-3 * w[0].abs()).max(1.0)]
    }
}

/// An overlay read and resampled, with how its values become colours.
struct Overlay {
    field: Vec<f32>,
    map: LayerMap,
    opacity: f32,
    range: FieldRange,
}

/// Reads overlay `i` and resamples it into the grid (`space`: the scene volume's frame); its
/// colour mapping.
fn overlay(
    i: usize,
    o: &OverlaySpec,
    (dims, affine, space): ([usize; 3], DMat4, volume::Space),
    notes: &mut Vec<String>,
) -> Result<Overlay, String> {
    let key = |k: &str| format!("overlays[{i}].{k}");
    let vol = volume::load(&o.path).map_err(|e| format!("{}: {e}", key("path")))?;
    if vol.space != space && o.transform.is_none() {
        // RAS+ millimetres against a file's own frame: the affines place it, but nothing says
        // the two frames are one (a head MR in its scanner's frame pasted over an MNI T1).
        let frame = |s: volume::Space| match s {
            volume::Space::Ras => "RAS+ mm",
            volume::Space::File => "its file's own frame",
        };
        notes.push(format!(
            "overlays[{i}] ({}): its grid is in {} and the scene volume's in {}; it is placed \
             by the two affines as they are (give overlays[{i}].transform where the frames differ)",
            o.path.display(),
            frame(vol.space),
            frame(space)
        ));
    }
    let sel = o
        .field
        .as_deref()
        .map(str::parse::<volume::FieldSelector>)
        .transpose()
        .map_err(|e| format!("{}: {e}", key("field")))?;
    let f = vol
        .select(sel.as_ref())
        .map_err(|e| format!("{}: {e}", key("field")))?;
    if f.components != 1 {
        return Err(format!(
            "{} ({}): '{}' has {} components; choose NAME:magnitude or NAME:x|y|z",
            key("field"),
            o.path.display(),
            f.name,
            f.components
        ));
    }
    let to_src = match &o.transform {
        Some(m) => crate::tube_sets::transform_matrix(m, &key("transform"))?.inverse(),
        None => DMat4::IDENTITY,
    };
    if o.labels {
        // The file's own voxels, so that the error can name one.
        // (Infinities are whole, and out of range below.)
        let whole = |v: f32| !v.is_finite() || (v - v.round()).abs() <= 1e-3;
        let [nx, ny, _] = vol.dims;
        let voxel = |n: usize| format!("voxel ({}, {}, {})", n % nx, n / nx % ny, n / (nx * ny));
        if let Some(n) = f.data.iter().position(|&v| !whole(v)) {
            return Err(format!(
                "overlays[{i}].labels ({}): the value {} at {} is not a whole number; a label \
                 overlay holds labels (a scalar map is an overlay without labels = true)",
                o.path.display(),
                f.data[n],
                voxel(n)
            ));
        }
        let outside = |v: f32| !v.is_nan() && !(0.0..MAX_LABELS as f32).contains(&v.round());
        if let Some(n) = f.data.iter().position(|&v| outside(v)) {
            return Err(format!(
                "overlays[{i}].labels ({}): label {} at {} is outside 0..{}",
                o.path.display(),
                f.data[n],
                voxel(n),
                MAX_LABELS - 1
            ));
        }
    }
    let interp = if o.labels {
        Interp::Nearest
    } else {
        Interp::Linear
    };
    let field =
        volume::regrid::into_grid(&f.data, vol.dims, vol.affine, to_src, dims, affine, interp)
            .map_err(|e| format!("{} ({}): {e}", key("path"), o.path.display()))?;
    if field.iter().all(|v| !v.is_finite()) {
        // Say why: the file's own values, or where it lies.
        let why = if f.data.iter().all(|v| !v.is_finite()) {
            "every value of it is NaN or infinite: nothing to draw"
        } else {
            "no voxel of it falls inside the scene volume's grid"
        };
        notes.push(format!("overlays[{i}] ({}): {why}", o.path.display()));
    }
    let st = f.stats();
    let range = FieldRange::new(match st.min.is_finite() && st.max.is_finite() {
        true => usable([st.min, st.max]),
        false => [0.0, 1.0],
    });
    let map = if o.labels {
        labels_map(i, o, &field, notes)?
    } else {
        let cm: Colormap = o.colormap.as_deref().unwrap_or("red-yellow").parse()?;
        let w = match &o.range {
            Some(Window::Values(r)) => *r,
            r => {
                if !(st.min.is_finite() && st.max.is_finite()) {
                    return Err(format!(
                        "{} ({}): the field has no finite values",
                        key("path"),
                        o.path.display()
                    ));
                }
                match r {
                    Some(w) if w.is_robust() => range.robust(&field),
                    _ => range.full,
                }
            }
        };
        LayerMap::Scalar {
            lo: w[0],
            hi: w[1],
            colors: cm.linear_table(),
        }
    };
    Ok(Overlay {
        field,
        map,
        opacity: o.opacity as f32,
        range,
    })
}

/// A label overlay's colour table: the labels of the resampled field, coloured from the
/// FreeSurfer table `lut` (labels it lacks are hidden, with a note) or a colour per label,
/// shown when listed in `show` (default: all but 0).
fn labels_map(
    i: usize,
    o: &OverlaySpec,
    field: &[f32],
    notes: &mut Vec<String>,
) -> Result<LayerMap, String> {
    let mut present = std::collections::BTreeSet::new();
    // NaN holds no label. The file's values were checked whole and in range where it was read
    // (`overlay`, naming the voxel); nearest-neighbour resampling keeps them.
    for &v in field.iter().filter(|v| !v.is_nan()) {
        let l = v.round();
        present.insert(l as i64);
    }
    let labels: Vec<i64> = present.into_iter().collect();
    let table = match &o.lut {
        Some(p) => volume::labels::read_lut(p).map_err(|e| format!("overlays[{i}].lut: {e}"))?,
        None => volume::labels::default_colors(&labels),
    };
    let shown = |l: i64| match &o.show {
        Some(s) => s.contains(&l),
        None => l != 0,
    };
    // (Labels `show` hides are hidden whatever the table holds: not noted.)
    let missing: Vec<i64> = labels
        .iter()
        .copied()
        .filter(|&l| l != 0 && shown(l) && !table.entries.contains_key(&l))
        .collect();
    if !missing.is_empty() {
        notes.push(format!(
            "overlays[{i}].lut: {} labels of {} are not in the table and are hidden (first: {:?})",
            missing.len(),
            o.path.display(),
            &missing[..missing.len().min(8)]
        ));
    }
    let top = labels.last().copied().unwrap_or(0).max(0) as usize;
    let mut colors = vec![[0.0f32; 4]; top + 1];
    for &l in &labels {
        if let (true, Some(e)) = (shown(l), table.entries.get(&l)) {
            let [r, g, b] = e
                .rgb
                .map(|c| volume::colormap::srgb_to_linear(c as f64 / 255.0) as f32);
            colors[l as usize] = [r, g, b, 1.0];
        }
    }
    Ok(LayerMap::Labels { colors })
}

/// The slices of scene `s` over the volume `vol` (its field named `field`, `data` as the model
/// holds it),
/// with the overlays read and resampled into its grid.
/// `range`: the volume field's finite range (`Field::stats`).
pub fn model(
    s: &Scene,
    vol: &volume::Volume,
    field: &str,
    data: &volume::samples::Samples,
    range: [f64; 2],
    notes: &mut Vec<String>,
) -> Result<Option<PlaneModel>, String> {
    if s.slices.is_empty() && s.overlays.is_empty() {
        return Ok(None);
    }
    let vspec = s.volume.as_ref().ok_or("slices need a [volume]")?;
    let (dims, affine) = (vol.dims, vol.affine);
    let mut fields = vec![data.to_f32().into_owned()];
    let mut overlays = vec![];
    for (i, o) in s.overlays.iter().enumerate() {
        let mut ov = overlay(i, o, (dims, affine, vol.space), notes)?;
        fields.push(std::mem::take(&mut ov.field));
        overlays.push(ov);
    }
    let mut ranges = vec![FieldRange::new(range)];
    let overlays: Vec<(LayerMap, f32)> = overlays
        .into_iter()
        .map(|o| {
            ranges.push(o.range);
            (o.map, o.opacity)
        })
        .collect();
    let mut m = PlaneModel {
        dims,
        affine,
        fields,
        planes: vec![],
        blend: s
            .overlays
            .iter()
            .position(|o| o.volume_blend)
            .map(|k| PlaneLayer {
                field: k + 1,
                map: overlays[k].0.clone(),
                opacity: overlays[k].1,
            }),
        overlays,
        ranges,
        bounds: vol.bounds(),
        field: field.to_string(),
    };
    m.planes = planes_of(s, vspec, &m, notes)?;
    Ok(Some(m))
}

/// The span of the voxel centres of a grid along unit normal `n`.
pub fn extent(dims: [usize; 3], affine: DMat4, n: DVec3) -> [f64; 2] {
    let ext = [0usize, 1, 2, 3, 4, 5, 6, 7].map(|c| n.dot(corner(dims, affine, c)));
    [
        ext.iter().copied().fold(f64::INFINITY, f64::min),
        ext.iter().copied().fold(f64::NEG_INFINITY, f64::max),
    ]
}

/// The slices of `s` on model `m`'s grid, with its fields' ranges and the overlays' mappings
/// and opacities; a note in `notes` where slices show the volume over its full range and a few
/// outliers stretch it.
fn planes_of(
    s: &Scene,
    vspec: &crate::spec::VolumeSpec,
    m: &PlaneModel,
    notes: &mut Vec<String>,
) -> Result<Vec<PlaneInput>, String> {
    let (dims, affine, bounds) = (m.dims, m.affine, m.bounds);
    let mut planes = vec![];
    let mut stretched = vec![];
    for (i, sl) in s.slices.iter().enumerate() {
        let key = |k: &str| format!("slices[{i}].{k}");
        let n = normal(sl);
        let pos = position(sl, bounds);
        let pts = polygon(dims, affine, n, pos).ok_or_else(|| {
            let [lo, hi] = extent(dims, affine, n);
            format!(
                "scene key {}: the plane at {pos} does not cut the volume (it spans {lo:.3} to {hi:.3} along the normal)",
                key("position")
            )
        })?;
        // The slice's own layer.
        let base = match &sl.volume {
            None => {
                let cm: Colormap = sl
                    .colormap
                    .as_deref()
                    .or(vspec.colormap.as_deref())
                    .unwrap_or("grey")
                    .parse()?;
                let r = &m.ranges[0];
                let full = r.full;
                let w = match sl.window.as_ref().or(vspec.window.as_ref()) {
                    Some(w) => w.resolve(full, || r.robust(&m.fields[0])),
                    None => {
                        stretched.push(key("window"));
                        full
                    }
                };
                PlaneLayer {
                    field: 0,
                    map: LayerMap::Scalar {
                        lo: w[0],
                        hi: w[1],
                        colors: cm.linear_table(),
                    },
                    opacity: 1.0,
                }
            }
            Some(name) => {
                let k = s
                    .overlays
                    .iter()
                    .position(|o| &o.name == name)
                    .ok_or_else(|| format!("scene key {}: no overlay '{name}'", key("volume")))?;
                let mut map = m.overlays[k].0.clone();
                if let LayerMap::Scalar { lo, hi, colors } = &mut map {
                    if let Some(w) = &sl.window {
                        let r = &m.ranges[k + 1];
                        [*lo, *hi] = w.resolve(r.full, || r.robust(&m.fields[k + 1]));
                    }
                    if let Some(c) = &sl.colormap {
                        *colors = c.parse::<Colormap>()?.linear_table();
                    }
                }
                PlaneLayer {
                    field: k + 1,
                    map,
                    opacity: 1.0,
                }
            }
        };
        let base_field = base.field;
        let mut layers = vec![base];
        if sl.overlays {
            for (k, (map, opacity)) in m.overlays.iter().enumerate() {
                if k + 1 == base_field {
                    continue;
                }
                layers.push(PlaneLayer {
                    field: k + 1,
                    map: map.clone(),
                    opacity: *opacity,
                });
            }
        }
        if layers.len() > MAX_LAYERS {
            return Err(format!(
                "scene key {}: {} overlays over one slice; at most {} (set overlays = false or show it as the slice's volume)",
                key("overlays"),
                layers.len() - 1,
                MAX_LAYERS - 1
            ));
        }
        planes.push(PlaneInput {
            polygon: {
                let mut m = polygon_mesh(&pts, n);
                m.opacity = (sl.opacity < 1.0).then_some(sl.opacity as f32);
                m
            },
            layers,
            lit: sl.lit,
        });
    }
    if !stretched.is_empty() {
        if let Some(note) = outlier_note(&m.fields[0], m.ranges[0].full) {
            notes.push(format!(
                "{} ({}): {note}; window = \"robust\" spans them",
                stretched.join(", "),
                vspec.path.display()
            ));
        }
    }
    Ok(planes)
}

/// Whether note `n` is one the slices' planning gives (replaced when they are planned again).
pub fn is_slice_note(n: &str) -> bool {
    n.starts_with("slices[") && n.ends_with("window = \"robust\" spans them")
}

/// A slice whose window is its field's full range `full`: the field's 2nd to 98th percentiles
/// (estimated from at most [`crate::compile::NOTE_SAMPLES`] of `values`, gaps left out) and
/// the share of the window they span, where that is under [`crate::compile::OUTLIER_SHARE`]
/// (a few outliers, as the inlet's speeds of a room's flow, leave the rest one colour).
fn outlier_note(values: &[f32], full: [f64; 2]) -> Option<String> {
    // (Gaps, held as -3e38, are no values.)
    let q = crate::compile::estimated_robust(values.len(), || {
        values
            .iter()
            .copied()
            .map(|v| if v > -1e30 { v } else { f32::NAN })
    });
    let n = crate::annotate::format_number;
    (q[0] < q[1] && (q[1] - q[0]) < crate::compile::OUTLIER_SHARE * (full[1] - full[0])).then(
        || {
            format!(
            "the 2nd to 98th percentiles of the values, about [{}, {}], span {}% of the window \
             [{}, {}] (the field's finite range), so most of the slice takes almost one colour",
            n(q[0]),
            n(q[1]),
            n(100.0 * (q[1] - q[0]) / (full[1] - full[0])),
            n(full[0]),
            n(full[1])
        )
        },
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_plane_through_a_box_is_its_cross_section() {
        // A 3 x 5 x 9 grid of unit voxels: axial planes cut a 2 x 4 rectangle.
        let (dims, affine) = ([3, 5, 9], DMat4::IDENTITY);
        let p = polygon(dims, affine, DVec3::Z, 3.5).unwrap();
        assert_eq!(p.len(), 4);
        assert!(p.iter().all(|x| (x.z - 3.5).abs() < 1e-12));
        let area: f64 = (1..p.len() - 1)
            .map(|k| 0.5 * (p[k] - p[0]).cross(p[k + 1] - p[0]).length())
            .sum();
        assert!((area - 8.0).abs() < 1e-9, "{area}");
        // An oblique plane through a cube's centre perpendicular to its diagonal cuts a regular
        // hexagon (area (3 sqrt 3 / 4) a^2 for the cube of edge a = 4: side a / sqrt 2); the
        // same plane through the elongated box cuts its four long edges only.
        let n = DVec3::ONE.normalize();
        let hex = polygon([5, 5, 5], affine, n, n.dot(DVec3::splat(2.0))).unwrap();
        assert_eq!(hex.len(), 6);
        let area: f64 = (1..hex.len() - 1)
            .map(|k| 0.5 * (hex[k] - hex[0]).cross(hex[k + 1] - hex[0]).length())
            .sum();
        assert!((area - 0.75 * 3f64.sqrt() * 16.0).abs() < 1e-9, "{area}");
        let quad = polygon(dims, affine, n, n.dot(DVec3::new(1.0, 2.0, 4.0))).unwrap();
        assert_eq!(quad.len(), 4);
        // A plane beside the box misses it.
        assert!(polygon(dims, affine, DVec3::Z, 8.5).is_none());
        assert!(polygon(dims, affine, DVec3::Z, -0.1).is_none());
    }

    #[test]
    fn cropping_removes_exactly_the_points_outside_the_slabs() {
        let mut s = tubes::Streamlines::new();
        let line: Vec<Vec3> = (0..21)
            .map(|k| Vec3::new(0.1 * k as f32, 0.0, k as f32 - 10.0))
            .collect();
        s.push(&line);
        s.point_attributes.push(tubes::Attribute {
            name: "z".into(),
            components: 1,
            values: line.iter().map(|p| p.z).collect(),
        });
        let slabs = [
            Slab {
                normal: DVec3::Z,
                position: -5.0,
                half: 2.0,
            },
            Slab {
                normal: DVec3::Z,
                position: 6.0,
                half: 1.5,
            },
        ];
        let c = crop(s.clone(), &slabs, 2);
        // z in [-7, -3] and [4.5, 7.5]: two pieces of 5 and 3 points.
        assert_eq!(c.len(), 2);
        assert_eq!(c.line(0).len(), 5);
        assert_eq!(c.line(1).len(), 3);
        let kept: Vec<f32> = c.points.iter().map(|p| p.z).collect();
        let want: Vec<f32> = line
            .iter()
            .map(|p| p.z)
            .filter(|z| (z + 5.0).abs() <= 2.0 || (z - 6.0).abs() <= 1.5)
            .collect();
        assert_eq!(kept, want);
        assert_eq!(c.point_attributes[0].values, want);
        // Single points survive only where pieces of one point are asked for.
        let thin = [Slab {
            normal: DVec3::Z,
            position: 0.0,
            half: 0.25,
        }];
        assert_eq!(crop(s.clone(), &thin, 2).len(), 0);
        assert_eq!(crop(s.clone(), &thin, 1).points, vec![line[10]]);
    }
}
