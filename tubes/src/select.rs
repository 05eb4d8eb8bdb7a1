//! Streamline selection by regions of interest, the include/exclude ROIs of mrview, DSI Studio
//! and DIPY: spheres, boxes and masks in world coordinates (RAS+ mm), arc-length and attribute
//! ranges, and a seeded random subsample. Behind `umbra tracts select` and the `select` key of
//! a scene's `[[tubes]]` and `[[lines]]`.
//!
//! The rule: a streamline is kept when every include ROI contains at least one of its points
//! and no exclude ROI contains any, its arc length lies in `[min_length, max_length]`, its
//! attribute value in `[min, max]`; then `subsample` keeps `n` of those at random (each subset
//! of `n` equally likely, the same for the same seed), in their order. Containment is of the
//! points, boundaries included: a sphere holds `p` when `|p - c| <= r`, a box when
//! `lo <= p <= hi` in every coordinate, a mask when the voxel nearest to `p` (the mask's
//! affine, rounded) is inside the grid and nonzero (or equal to the label asked for). A point
//! with a NaN coordinate is in no ROI.

use crate::Streamlines;
use glam::{DMat4, DVec3};
use rayon::prelude::*;

/// A region of interest in world coordinates.
#[derive(Clone, Debug)]
pub enum Roi {
    Sphere {
        centre: DVec3,
        radius: f64,
    },
    /// Corners in any order (normalised to `lo <= hi`).
    Box {
        lo: DVec3,
        hi: DVec3,
    },
    Mask(Mask),
}

/// A voxel mask: which voxels of a grid are inside, and the grid's world-to-voxel map.
#[derive(Clone, Debug)]
pub struct Mask {
    /// What the mask was made from (`file[:label]`), for messages.
    pub name: String,
    dims: [usize; 3],
    world_to_voxel: DMat4,
    inside: Vec<bool>,
}

impl Mask {
    /// Voxels of `v`'s scalar field that are nonzero (`label` None) or equal to `label`; NaN
    /// voxels are outside.
    pub fn from_volume(v: &volume::Volume, label: Option<f64>, name: &str) -> Result<Mask, String> {
        let f = v.select(None).map_err(|e| format!("{name}: {e}"))?;
        if f.components != 1 {
            return Err(format!(
                "{name}: a mask needs a scalar volume; this one has {} components",
                f.components
            ));
        }
        let inside: Vec<bool> = f
            .data
            .iter()
            .map(|&x| match label {
                // In the stored precision: a label 0.1 matches the f32 value 0.1.
                Some(l) => x == l as f32,
                None => x != 0.0 && !x.is_nan(),
            })
            .collect();
        if !inside.iter().any(|&b| b) {
            return Err(format!(
                "{name}: the mask is empty (no voxel is {})",
                match label {
                    Some(l) => format!("equal to {l}"),
                    None => "nonzero".into(),
                }
            ));
        }
        let world_to_voxel = v.affine.inverse();
        if !world_to_voxel.is_finite() {
            return Err(format!("{name}: the mask's affine cannot be inverted"));
        }
        Ok(Mask {
            name: name.to_string(),
            dims: v.dims,
            world_to_voxel,
            inside,
        })
    }

    /// Reads `FILE` or `FILE:LABEL` (a number after the last `:`) as a mask.
    pub fn load(spec: &str) -> Result<Mask, String> {
        let (path, label) = split_mask(spec)?;
        let v = volume::load(std::path::Path::new(path)).map_err(|e| e.to_string())?;
        Mask::from_volume(&v, label, spec)
    }

    pub fn contains(&self, p: DVec3) -> bool {
        let q = self.world_to_voxel.transform_point3(p).round();
        let [nx, ny, nz] = self.dims;
        // NaN fails every comparison: outside.
        if !(q.x >= 0.0 && q.y >= 0.0 && q.z >= 0.0) {
            return false;
        }
        if !(q.x < nx as f64 && q.y < ny as f64 && q.z < nz as f64) {
            return false;
        }
        let (x, y, z) = (q.x as usize, q.y as usize, q.z as usize);
        self.inside[x + nx * (y + ny * z)]
    }
}

/// `FILE[:LABEL]` as the file and the label (a finite number after the last `:`).
pub fn split_mask(spec: &str) -> Result<(&str, Option<f64>), String> {
    match spec.rsplit_once(':') {
        Some((p, l)) if !p.is_empty() && l.trim().parse::<f64>().is_ok() => {
            let v: f64 = l.trim().parse().expect("checked");
            if !v.is_finite() {
                return Err(format!("{spec}: the label must be a finite number"));
            }
            Ok((p, Some(v)))
        }
        _ => Ok((spec, None)),
    }
}

impl Roi {
    /// A sphere; the radius must be finite and not negative, the centre finite.
    pub fn sphere(v: [f64; 4]) -> Result<Roi, String> {
        if v.iter().any(|x| !x.is_finite()) || v[3] < 0.0 {
            return Err(format!(
                "sphere {v:?}: needs a finite centre and a finite radius >= 0"
            ));
        }
        Ok(Roi::Sphere {
            centre: DVec3::new(v[0], v[1], v[2]),
            radius: v[3],
        })
    }

    /// A box from two opposite corners `[x0, y0, z0, x1, y1, z1]`, all finite.
    pub fn cuboid(v: [f64; 6]) -> Result<Roi, String> {
        if v.iter().any(|x| !x.is_finite()) {
            return Err(format!("box {v:?}: needs finite corners"));
        }
        let (a, b) = (DVec3::new(v[0], v[1], v[2]), DVec3::new(v[3], v[4], v[5]));
        Ok(Roi::Box {
            lo: a.min(b),
            hi: a.max(b),
        })
    }

    /// Whether the point is in the region (boundary included).
    pub fn contains(&self, p: DVec3) -> bool {
        match self {
            Roi::Sphere { centre, radius } => (p - *centre).length_squared() <= radius * radius,
            Roi::Box { lo, hi } => {
                p.x >= lo.x
                    && p.y >= lo.y
                    && p.z >= lo.z
                    && p.x <= hi.x
                    && p.y <= hi.y
                    && p.z <= hi.z
            }
            Roi::Mask(m) => m.contains(p),
        }
    }

    /// Whether any point of `line` is in the region.
    pub fn touches(&self, line: &[glam::Vec3]) -> bool {
        line.iter().any(|p| self.contains(p.as_dvec3()))
    }
}

/// A streamline attribute's range: a per-streamline attribute's value, or a per-point
/// attribute's mean over the streamline's points (NaN values left out), in `[min, max]`.
#[derive(Clone, Debug, PartialEq)]
pub struct AttributeRange {
    pub name: String,
    pub min: f64,
    pub max: f64,
}

/// Everything a selection asks.
#[derive(Clone, Debug, Default)]
pub struct Selection {
    pub include: Vec<Roi>,
    pub exclude: Vec<Roi>,
    pub min_length: Option<f64>,
    pub max_length: Option<f64>,
    pub attribute: Option<AttributeRange>,
    /// Keep this many of the streamlines that pass, at random with this seed.
    pub subsample: Option<(usize, u64)>,
}

/// How many streamlines each test removed, in the order they apply.
#[derive(Clone, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct SelectSummary {
    pub total: usize,
    pub kept: usize,
    pub by_include: usize,
    pub by_exclude: usize,
    pub by_length: usize,
    pub by_attribute: usize,
    pub by_subsample: usize,
}

/// Why a streamline is dropped, the first test it fails.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Verdict {
    Keep,
    Include,
    Exclude,
    Length,
    Attribute,
}

impl Selection {
    /// Whether the selection asks anything at all.
    pub fn is_empty(&self) -> bool {
        self.include.is_empty()
            && self.exclude.is_empty()
            && self.min_length.is_none()
            && self.max_length.is_none()
            && self.attribute.is_none()
            && self.subsample.is_none()
    }

    /// Checks the ranges: lengths finite and >= 0, min <= max, the attribute's bounds not NaN,
    /// a subsample of at least 1.
    pub fn check(&self) -> Result<(), String> {
        for (k, v) in [
            ("min_length", self.min_length),
            ("max_length", self.max_length),
        ] {
            if let Some(v) = v {
                if !(v.is_finite() && v >= 0.0) {
                    return Err(format!("{k} = {v}: must be a finite length >= 0"));
                }
            }
        }
        if let (Some(a), Some(b)) = (self.min_length, self.max_length) {
            if a > b {
                return Err(format!("min_length {a} is above max_length {b}"));
            }
        }
        if self.subsample.is_some_and(|(n, _)| n == 0) {
            return Err("subsample = 0: keeps no streamline; give at least 1".into());
        }
        if let Some(a) = &self.attribute {
            if a.min.is_nan() || a.max.is_nan() || a.min > a.max {
                return Err(format!(
                    "attribute '{}': the range [{}, {}] is empty or NaN",
                    a.name, a.min, a.max
                ));
            }
        }
        Ok(())
    }

    /// The value per streamline of the attribute range, or why there is none.
    fn attribute_values(&self, s: &Streamlines) -> Result<Option<Vec<f64>>, String> {
        let Some(a) = &self.attribute else {
            return Ok(None);
        };
        if let Some(at) = s.line_attributes.iter().find(|x| x.name == a.name) {
            if at.components != 1 {
                return Err(format!(
                    "attribute '{}' has {} components; a range needs one",
                    a.name, at.components
                ));
            }
            return Ok(Some(at.values.iter().map(|&v| v as f64).collect()));
        }
        if let Some(at) = s.point_attributes.iter().find(|x| x.name == a.name) {
            if at.components != 1 {
                return Err(format!(
                    "attribute '{}' has {} components; a range needs one",
                    a.name, at.components
                ));
            }
            let mean = (0..s.len())
                .map(|i| {
                    let vals = &at.values[s.offsets[i]..s.offsets[i + 1]];
                    let (sum, n) = vals
                        .iter()
                        .filter(|v| !v.is_nan())
                        .fold((0.0f64, 0usize), |(s, n), &v| (s + v as f64, n + 1));
                    if n == 0 {
                        f64::NAN
                    } else {
                        sum / n as f64
                    }
                })
                .collect();
            return Ok(Some(mean));
        }
        let mut have: Vec<&str> = s
            .line_attributes
            .iter()
            .chain(&s.point_attributes)
            .map(|x| x.name.as_str())
            .collect();
        have.sort();
        Err(format!(
            "no attribute '{}' (the tractogram has {})",
            a.name,
            if have.is_empty() {
                "none".to_string()
            } else {
                have.join(", ")
            }
        ))
    }

    /// The streamlines that pass, with their attributes, and what each test removed.
    pub fn apply(&self, s: &Streamlines) -> Result<(Streamlines, SelectSummary), String> {
        self.check()?;
        let attr = self.attribute_values(s)?;
        let verdicts: Vec<Verdict> = (0..s.len())
            .into_par_iter()
            .map(|i| {
                let line = s.line(i);
                if !self.include.iter().all(|r| r.touches(line)) {
                    return Verdict::Include;
                }
                if self.exclude.iter().any(|r| r.touches(line)) {
                    return Verdict::Exclude;
                }
                if self.min_length.is_some() || self.max_length.is_some() {
                    let l = s.arc_length(i);
                    // A NaN length (a NaN point) is in no range.
                    let within = !l.is_nan()
                        && self.min_length.is_none_or(|m| l >= m)
                        && self.max_length.is_none_or(|m| l <= m);
                    if !within {
                        return Verdict::Length;
                    }
                }
                if let (Some(a), Some(v)) = (&self.attribute, &attr) {
                    if !(v[i] >= a.min && v[i] <= a.max) {
                        return Verdict::Attribute;
                    }
                }
                Verdict::Keep
            })
            .collect();
        let count = |v: Verdict| verdicts.iter().filter(|&&x| x == v).count();
        let mut keep: Vec<usize> = (0..s.len())
            .filter(|&i| verdicts[i] == Verdict::Keep)
            .collect();
        let passed = keep.len();
        if let Some((n, seed)) = self.subsample {
            keep = subsample(&keep, n, seed);
        }
        let summary = SelectSummary {
            total: s.len(),
            kept: keep.len(),
            by_include: count(Verdict::Include),
            by_exclude: count(Verdict::Exclude),
            by_length: count(Verdict::Length),
            by_attribute: count(Verdict::Attribute),
            by_subsample: passed - keep.len(),
        };
        Ok((subset(s, &keep), summary))
    }
}

/// `n` of `items` chosen uniformly without replacement (Knuth's selection sampling,
/// Algorithm S), in their order; all of them when `n` is not smaller.
pub fn subsample(items: &[usize], n: usize, seed: u64) -> Vec<usize> {
    if n >= items.len() {
        return items.to_vec();
    }
    let mut state = seed;
    let mut next = || {
        // SplitMix64.
        state = state.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = state;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    };
    let mut out = Vec::with_capacity(n);
    let m = items.len();
    for (t, &item) in items.iter().enumerate() {
        let need = n - out.len();
        if need == 0 {
            break;
        }
        // Keep with probability need / (m - t): exactly n are kept.
        if ((m - t) as f64 * next()) < need as f64 {
            out.push(item);
        }
    }
    out
}

/// The streamlines `keep` (indices, increasing) of `s`, with their point and streamline
/// attributes, reference space and format.
pub fn subset(s: &Streamlines, keep: &[usize]) -> Streamlines {
    let parts: Vec<(usize, usize, usize)> = keep
        .iter()
        .map(|&i| (i, s.offsets[i], s.offsets[i + 1]))
        .collect();
    pieces(s, &parts)
}

/// A piece of streamline `i`: points `a..b` of the whole set, `(i, a, b)`.
pub type Piece = (usize, usize, usize);

/// Streamlines made of pieces of `s`: `(i, a, b)` is points `a..b` (indices into `s.points`,
/// within streamline `i`), in the order given, with their point attributes; each piece repeats
/// its streamline's attributes; reference space and format kept.
pub fn pieces(s: &Streamlines, parts: &[Piece]) -> Streamlines {
    let mut out = Streamlines::new();
    out.points
        .reserve(parts.iter().map(|&(_, a, b)| b - a).sum());
    for &(_, a, b) in parts {
        out.push(&s.points[a..b]);
    }
    // The values of the pieces of an attribute with `components` per item, the items of a
    // piece being `range(piece)`.
    let take = |a: &crate::Attribute, range: &dyn Fn(&Piece) -> (usize, usize)| crate::Attribute {
        name: a.name.clone(),
        components: a.components,
        values: parts
            .iter()
            .flat_map(|p| {
                let (lo, hi) = range(p);
                a.values[lo * a.components..hi * a.components]
                    .iter()
                    .copied()
            })
            .collect(),
    };
    out.point_attributes = s
        .point_attributes
        .iter()
        .map(|a| take(a, &|&(_, lo, hi)| (lo, hi)))
        .collect();
    out.line_attributes = s
        .line_attributes
        .iter()
        .map(|a| take(a, &|&(i, _, _)| (i, i + 1)))
        .collect();
    out.reference = s.reference.clone();
    out.format = s.format.clone();
    out.warnings = s.warnings.clone();
    out
}

/// The streamlines cropped to the points `keep` accepts: every other point is removed and its
/// streamline split there; pieces of fewer than `min_points` points (at least 1) are dropped
/// ([`pieces`] keeps the attributes).
pub fn crop(s: &Streamlines, keep: impl Fn(glam::Vec3) -> bool, min_points: usize) -> Streamlines {
    let mut parts = vec![];
    for i in 0..s.len() {
        let (a, b) = (s.offsets[i], s.offsets[i + 1]);
        let mut start = a;
        while start < b {
            while start < b && !keep(s.points[start]) {
                start += 1;
            }
            let mut end = start;
            while end < b && keep(s.points[end]) {
                end += 1;
            }
            if end - start >= min_points.max(1) {
                parts.push((i, start, end));
            }
            start = end;
        }
    }
    pieces(s, &parts)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    /// A deterministic cloud of random polylines in [-50, 50]^3 with a point and a line
    /// attribute.
    fn random_lines(n: usize, seed: u64) -> Streamlines {
        let mut st = seed;
        let mut r = move || {
            st ^= st << 13;
            st ^= st >> 7;
            st ^= st << 17;
            (st >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut s = Streamlines::new();
        let mut pv = vec![];
        let mut lv = vec![];
        for _ in 0..n {
            let k = 1 + (r() * 30.0) as usize;
            let mut p = Vec3::new(
                (r() * 100.0 - 50.0) as f32,
                (r() * 100.0 - 50.0) as f32,
                (r() * 100.0 - 50.0) as f32,
            );
            let mut pts = vec![];
            for _ in 0..k {
                pts.push(p);
                pv.push(r() as f32);
                p += Vec3::new(
                    (r() * 6.0 - 3.0) as f32,
                    (r() * 6.0 - 3.0) as f32,
                    (r() * 6.0 - 3.0) as f32,
                );
            }
            s.push(&pts);
            lv.push((r() * 10.0) as f32);
        }
        s.point_attributes.push(crate::Attribute {
            name: "fa".into(),
            components: 1,
            values: pv,
        });
        s.line_attributes.push(crate::Attribute {
            name: "weight".into(),
            components: 1,
            values: lv,
        });
        s
    }

    #[test]
    fn cropping_keeps_exactly_the_accepted_points_with_their_attributes() {
        let s = random_lines(50, 7);
        let keep = |p: Vec3| p.x > 0.0;
        let c = crop(&s, keep, 2);
        // Every kept point is accepted, and every run of 2 or more accepted points is kept, in
        // order, with its point attribute and its streamline's attribute.
        let mut want_pts = vec![];
        let (mut want_fa, mut want_w) = (vec![], vec![]);
        for i in 0..s.len() {
            let (a, b) = (s.offsets[i], s.offsets[i + 1]);
            let mut k = a;
            while k < b {
                let start = k;
                while k < b && keep(s.points[k]) {
                    k += 1;
                }
                if k - start >= 2 {
                    want_pts.extend_from_slice(&s.points[start..k]);
                    want_fa.extend_from_slice(&s.point_attributes[0].values[start..k]);
                    want_w.push(s.line_attributes[0].values[i]);
                }
                k = k.max(start + 1);
            }
        }
        assert!(c.len() > 20, "{} pieces", c.len());
        assert_eq!(c.points, want_pts);
        assert_eq!(c.point_attributes[0].values, want_fa);
        assert_eq!(c.line_attributes[0].values, want_w);
        c.validate().unwrap();
    }

    /// The rule of the module's doc, written out point by point without the ROI types.
    fn brute_keeps(
        s: &Streamlines,
        i: usize,
        spheres_in: &[[f64; 4]],
        boxes_out: &[[f64; 6]],
    ) -> bool {
        let pts: Vec<DVec3> = s.line(i).iter().map(|p| p.as_dvec3()).collect();
        let in_sphere = |c: &[f64; 4], p: &DVec3| {
            let d = ((p.x - c[0]).powi(2) + (p.y - c[1]).powi(2) + (p.z - c[2]).powi(2)).sqrt();
            d <= c[3]
        };
        let in_box = |b: &[f64; 6], p: &DVec3| {
            (0..3).all(|k| {
                let (a, c) = (b[k].min(b[k + 3]), b[k].max(b[k + 3]));
                let v = [p.x, p.y, p.z][k];
                v >= a && v <= c
            })
        };
        spheres_in
            .iter()
            .all(|c| pts.iter().any(|p| in_sphere(c, p)))
            && !boxes_out.iter().any(|b| pts.iter().any(|p| in_box(b, p)))
    }

    #[test]
    fn rois_keep_what_a_brute_force_selection_keeps() {
        let s = random_lines(4000, 7);
        let spheres = [[0.0, 0.0, 0.0, 20.0], [10.0, -5.0, 3.0, 25.0]];
        let boxes = [[30.0, 30.0, 30.0, 5.0, 10.0, 0.0]];
        let sel = Selection {
            include: spheres.iter().map(|&c| Roi::sphere(c).unwrap()).collect(),
            exclude: boxes.iter().map(|&b| Roi::cuboid(b).unwrap()).collect(),
            ..Default::default()
        };
        let (out, sum) = sel.apply(&s).unwrap();
        let want: Vec<usize> = (0..s.len())
            .filter(|&i| brute_keeps(&s, i, &spheres, &boxes))
            .collect();
        assert!(
            want.len() > 50 && want.len() < 3000,
            "{} kept: a test that selects",
            want.len()
        );
        assert_eq!(sum.kept, want.len());
        assert_eq!(sum.total, 4000);
        assert_eq!(sum.kept + sum.by_include + sum.by_exclude, 4000);
        assert_eq!(out.len(), want.len());
        for (j, &i) in want.iter().enumerate() {
            assert_eq!(out.line(j), s.line(i));
            assert_eq!(
                out.line_attributes[0].values[j],
                s.line_attributes[0].values[i]
            );
        }
        out.validate().unwrap();
        assert_eq!(out.point_attributes[0].values.len(), out.points.len());
    }

    #[test]
    fn boundaries_are_inside_and_nan_points_are_in_nothing() {
        let sph = Roi::sphere([0.0, 0.0, 0.0, 2.0]).unwrap();
        assert!(sph.contains(DVec3::new(2.0, 0.0, 0.0)));
        assert!(!sph.contains(DVec3::new(2.0 + 1e-9, 0.0, 0.0)));
        let b = Roi::cuboid([1.0, 1.0, 1.0, -1.0, -1.0, -1.0]).unwrap();
        assert!(b.contains(DVec3::new(1.0, -1.0, 0.0)));
        assert!(!b.contains(DVec3::new(1.0, -1.0, 1.5)));
        let nan = DVec3::new(f64::NAN, 0.0, 0.0);
        assert!(!sph.contains(nan) && !b.contains(nan));
        assert!(Roi::sphere([0.0, 0.0, 0.0, -1.0]).is_err());
        assert!(Roi::sphere([f64::NAN, 0.0, 0.0, 1.0]).is_err());
        assert!(Roi::cuboid([0.0, 0.0, 0.0, 1.0, f64::INFINITY, 1.0]).is_err());
    }

    #[test]
    fn lengths_attributes_and_subsamples_select_exactly() {
        let s = random_lines(3000, 11);
        let sel = Selection {
            min_length: Some(20.0),
            max_length: Some(60.0),
            attribute: Some(AttributeRange {
                name: "weight".into(),
                min: 2.0,
                max: 8.0,
            }),
            ..Default::default()
        };
        let (out, sum) = sel.apply(&s).unwrap();
        let want: Vec<usize> = (0..s.len())
            .filter(|&i| {
                let l = s.arc_length(i);
                let w = s.line_attributes[0].values[i] as f64;
                (20.0..=60.0).contains(&l) && (2.0..=8.0).contains(&w)
            })
            .collect();
        assert!(want.len() > 100);
        assert_eq!(out.len(), want.len());
        assert_eq!(sum.by_length + sum.by_attribute + sum.kept, 3000);
        // A per-point attribute: the streamline's mean.
        let sel = Selection {
            attribute: Some(AttributeRange {
                name: "fa".into(),
                min: 0.5,
                max: 1.0,
            }),
            ..Default::default()
        };
        let (out, _) = sel.apply(&s).unwrap();
        let want = (0..s.len())
            .filter(|&i| {
                let v = &s.point_attributes[0].values[s.offsets[i]..s.offsets[i + 1]];
                v.iter().map(|&x| x as f64).sum::<f64>() / v.len() as f64 >= 0.5
            })
            .count();
        assert_eq!(out.len(), want);
        // Subsample: exactly n, a subset in order, the same for the same seed, another for another.
        let all: Vec<usize> = (0..1000).collect();
        let a = subsample(&all, 100, 1);
        assert_eq!(a.len(), 100);
        assert!(a.windows(2).all(|w| w[0] < w[1]));
        assert_eq!(a, subsample(&all, 100, 1));
        assert_ne!(a, subsample(&all, 100, 2));
        assert_eq!(subsample(&all, 5000, 1), all);
        // Uniform: over many seeds every item is picked about n/m of the time.
        let mut hits = [0u32; 10];
        for seed in 0..20000 {
            for i in subsample(&(0..10).collect::<Vec<_>>(), 3, seed) {
                hits[i] += 1;
            }
        }
        assert!(
            hits.iter().all(|&h| (h as f64 - 6000.0).abs() < 300.0),
            "{hits:?}"
        );
        let sel = Selection {
            attribute: Some(AttributeRange {
                name: "nope".into(),
                min: 0.0,
                max: 1.0,
            }),
            ..Default::default()
        };
        assert!(sel
            .apply(&s)
            .unwrap_err()
            .contains("the tractogram has fa, weight"));
    }

    #[test]
    fn masks_hold_the_points_whose_nearest_voxel_is_set() {
        // A 4^3 grid of 2 mm voxels at origin (10, 0, 0): label 3 in voxel (1, 2, 0).
        let mut data = vec![0.0f32; 64];
        data[1 + 4 * 2] = 3.0;
        data[5] = 1.0;
        let v = volume::Volume::new(
            [4, 4, 4],
            DMat4::from_cols_array(&[
                2.0, 0.0, 0.0, 0.0, 0.0, 2.0, 0.0, 0.0, 0.0, 0.0, 2.0, 0.0, 10.0, 0.0, 0.0, 1.0,
            ]),
            volume::Space::Ras,
            volume::Field {
                name: "labels".into(),
                components: 1,
                stored: volume::ScalarType::F32,
                data,
            },
        )
        .unwrap();
        let m = Mask::from_volume(&v, Some(3.0), "m").unwrap();
        // Voxel (1, 2, 0) is centred at world (12, 4, 0) and reaches 1 mm each way.
        assert!(m.contains(DVec3::new(12.0, 4.0, 0.0)));
        assert!(m.contains(DVec3::new(12.9, 3.1, -0.9)));
        assert!(!m.contains(DVec3::new(13.1, 4.0, 0.0)));
        assert!(!m.contains(DVec3::new(f64::NAN, 4.0, 0.0)));
        assert!(!m.contains(DVec3::new(-100.0, 4.0, 0.0)));
        let any = Mask::from_volume(&v, None, "m").unwrap();
        assert!(any.contains(DVec3::new(12.0, 2.0, 0.0)));
        assert!(Mask::from_volume(&v, Some(7.0), "m")
            .unwrap_err()
            .contains("empty"));
    }
}
