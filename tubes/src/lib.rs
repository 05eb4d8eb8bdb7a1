//! umbra's streamline model: polylines in world coordinates with named attributes, the
//! tractogram readers and writers, and the B-spline stream-tube mesher.
//!
//! Data flows one way: a reader fills [`Streamlines`] (world coordinates, RAS+ mm for
//! tractography); the fitting, framing and meshing modules turn them into a tube mesh. Nothing
//! here knows about rendering.

pub mod bspline_fit;
pub mod error;
pub mod lines;
pub mod mesh_io;
pub mod pathline;
pub mod points;
pub mod select;
pub mod synthetic;
pub mod tck;
pub mod trace;
pub mod trk;
pub mod trx;
pub mod tube_mesh;
pub mod vtk_lines;

pub use error::{Result, TubesError};
use glam::{DMat4, DVec3, Vec3};
use std::path::Path;

/// The voxel grid a tractogram refers to (TrackVis keeps one in its header): kept so that a
/// file written back uses the same space.
#[derive(Clone, Debug, PartialEq)]
pub struct ReferenceSpace {
    pub dims: [usize; 3],
    pub voxel_sizes: [f64; 3],
    pub vox_to_ras: DMat4,
    /// Three of R/L, A/P, S/I.
    pub voxel_order: [u8; 3],
}

/// Reads a tractogram by file name: `.trk`, `.tck`, VTK polylines `.vtk` (these optionally
/// gzip-compressed, `.gz`), or TRX `.trx` (a zip archive or a directory).
pub fn load(path: &Path) -> Result<Streamlines> {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    let stem = name.strip_suffix(".gz").unwrap_or(&name);
    let s = if stem.ends_with(".trk") {
        trk::read(path)?
    } else if stem.ends_with(".tck") {
        tck::read(path)?
    } else if stem.ends_with(".vtk") {
        vtk_lines::read(path)?
    } else if name.ends_with(".trx") {
        trx::read(path)?
    } else {
        return Err(TubesError::format(
            path,
            "file name",
            "unknown tractogram format (expected .trk, .tck, VTK polylines .vtk, optionally .gz, or .trx)",
        ));
    };
    let mut s = s;
    s.validate()
        .map_err(|e| TubesError::format(path, "data", e))?;
    let bad = s.nonfinite_points();
    if bad > 0 {
        s.warnings.push(format!(
            "{bad} of {} points have a NaN or infinite coordinate; tube meshes skip them and \
             line renders break the line there",
            s.points.len()
        ));
    }
    Ok(s)
}

/// Writes a tractogram by file name: `.trk` (TrackVis v2) or `.tck`, optionally `.gz`, or a
/// `.trx` zip archive. Per-point and per-streamline attributes go to `.trk` scalars and
/// properties and to `.trx` `dpv/` and `dps/`; `.tck` holds positions only and drops them.
pub fn save(path: &Path, s: &Streamlines) -> Result<()> {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    let stem = name.strip_suffix(".gz").unwrap_or(&name);
    if stem.ends_with(".trk") {
        trk::write(path, s)
    } else if stem.ends_with(".tck") {
        tck::write(path, s)
    } else if name.ends_with(".trx") {
        trx::write(path, s)
    } else {
        Err(TubesError::Invalid(format!(
            "{}: unknown tractogram format (use .trk, .tck or .trx)",
            path.display()
        )))
    }
}

/// Whether a file looks like a tractogram this crate reads: `.trk`, `.tck`, or a `.vtk` whose
/// dataset is POLYDATA.
pub fn is_tractogram(path: &Path) -> bool {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    let stem = name.strip_suffix(".gz").unwrap_or(&name);
    if stem.ends_with(".trk") || stem.ends_with(".tck") || name.ends_with(".trx") {
        return true;
    }
    if stem.ends_with(".vtk") {
        // A VTK file is a tractogram when its dataset is POLYDATA (else a volume).
        return vtk_dataset(path).is_some_and(|d| d == "POLYDATA");
    }
    false
}

/// The dataset type of a legacy VTK file (`POLYDATA`, `STRUCTURED_POINTS`, ...), read from the
/// `DATASET` line of its first 1 KiB, through gzip when the file is compressed; `None` when
/// the file cannot be read or has no such line.
pub fn vtk_dataset(path: &Path) -> Option<String> {
    use std::io::Read;
    let (f, _) = volume::open_regular(path).ok()?;
    let mut raw = Vec::new();
    f.take(1 << 16).read_to_end(&mut raw).ok()?;
    let mut head = Vec::new();
    if raw.starts_with(&[0x1f, 0x8b]) {
        // A truncated stream still gives its first bytes.
        let _ = flate2::read::MultiGzDecoder::new(&raw[..])
            .take(1024)
            .read_to_end(&mut head);
    } else {
        raw.truncate(1024);
        head = raw;
    }
    let text = String::from_utf8_lossy(&head);
    // The dataset line is the fourth: magic, title, ASCII/BINARY, DATASET.
    text.lines().skip(2).take(4).find_map(|l| {
        let mut t = l.split_whitespace();
        t.next()
            .filter(|k| k.eq_ignore_ascii_case("DATASET"))
            .and_then(|_| t.next())
            .map(|d| d.to_ascii_uppercase())
    })
}

/// A named attribute with `components` values per point or per streamline.
#[derive(Clone, Debug, PartialEq)]
pub struct Attribute {
    pub name: String,
    pub components: usize,
    pub values: Vec<f32>,
}

/// A set of streamlines: one flat point buffer plus offsets (`offsets[i]..offsets[i + 1]` are
/// the points of streamline `i`), world coordinates (RAS+ mm for tractography).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Streamlines {
    pub points: Vec<Vec3>,
    /// `len() == count + 1`, starts at 0, non-decreasing, ends at `points.len()`.
    pub offsets: Vec<usize>,
    pub point_attributes: Vec<Attribute>,
    pub line_attributes: Vec<Attribute>,
    /// The voxel grid of the source file, when it had one (TrackVis).
    pub reference: Option<ReferenceSpace>,
    /// The format read (`trk`, `tck`), or empty.
    pub format: String,
    /// What the reader accepted but a user should know.
    pub warnings: Vec<String>,
}

impl Streamlines {
    pub fn new() -> Self {
        Streamlines {
            offsets: vec![0],
            ..Default::default()
        }
    }

    /// Number of streamlines.
    pub fn len(&self) -> usize {
        self.offsets.len().saturating_sub(1)
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Appends a streamline.
    pub fn push(&mut self, pts: &[Vec3]) {
        if self.offsets.is_empty() {
            self.offsets.push(0);
        }
        self.points.extend_from_slice(pts);
        self.offsets.push(self.points.len());
    }

    /// Appends `other`'s streamlines after these. Attributes both sets have (same name and
    /// components, per point or per streamline; the k-th of a repeated name matched with the
    /// k-th) are kept; the others are dropped, and their names returned. An empty set is
    /// neutral: appended, it changes nothing; appended to, it takes `other` whole.
    pub fn append(&mut self, other: &Streamlines) -> Vec<String> {
        if self.offsets.is_empty() {
            self.offsets.push(0);
        }
        if other.is_empty() {
            return vec![];
        }
        if self.is_empty() {
            let warnings = std::mem::take(&mut self.warnings);
            *self = Streamlines {
                reference: None,
                format: String::new(),
                warnings,
                ..other.clone()
            };
            if self.offsets.is_empty() {
                self.offsets.push(0);
            }
            return vec![];
        }
        let mut dropped = vec![];
        // The k-th attribute named `name` with `c` components among `list`.
        let nth = |list: &[Attribute], name: &str, c: usize, k: usize| -> Option<usize> {
            list.iter()
                .enumerate()
                .filter(|(_, b)| b.name == name && b.components == c)
                .nth(k)
                .map(|(j, _)| j)
        };
        let mut keep = |mine: &mut Vec<Attribute>, theirs: &[Attribute]| {
            // Which of theirs each of mine takes, by occurrence of its name.
            let pairs: Vec<Option<usize>> = (0..mine.len())
                .map(|i| {
                    let a = &mine[i];
                    let k = mine[..i]
                        .iter()
                        .filter(|b| b.name == a.name && b.components == a.components)
                        .count();
                    nth(theirs, &a.name, a.components, k)
                })
                .collect();
            let mut used = vec![false; theirs.len()];
            let mut kept = vec![];
            for (a, pair) in std::mem::take(mine).into_iter().zip(pairs) {
                match pair {
                    Some(j) => {
                        used[j] = true;
                        let mut a = a;
                        a.values.extend_from_slice(&theirs[j].values);
                        kept.push(a);
                    }
                    None => dropped.push(a.name),
                }
            }
            *mine = kept;
            for (b, u) in theirs.iter().zip(used) {
                if !u && !dropped.contains(&b.name) {
                    dropped.push(b.name.clone());
                }
            }
        };
        keep(&mut self.point_attributes, &other.point_attributes);
        keep(&mut self.line_attributes, &other.line_attributes);
        let base = self.points.len();
        self.points.extend_from_slice(&other.points);
        self.offsets
            .extend(other.offsets.iter().skip(1).map(|o| o + base));
        // A merged set has no one grid of its own.
        self.reference = None;
        dropped
    }

    /// The points of streamline `i`.
    pub fn line(&self, i: usize) -> &[Vec3] {
        &self.points[self.offsets[i]..self.offsets[i + 1]]
    }

    /// Applies a 4x4 transform to every point (computed in f64).
    pub fn transform(&mut self, m: &DMat4) {
        for p in &mut self.points {
            *p = m.transform_point3(p.as_dvec3()).as_vec3();
        }
    }

    /// Axis-aligned bounding box of the finite points, `None` when there are none. Points with
    /// a NaN or infinite coordinate are left out (glam's `min`/`max` would let one NaN point
    /// restart the fold and lose every point before it).
    pub fn bounds(&self) -> Option<[Vec3; 2]> {
        finite_bounds(&self.points)
    }

    /// Points with a NaN or infinite coordinate (kept as the file has them, as nibabel keeps
    /// them; the tube mesher and the line renderer leave them out).
    pub fn nonfinite_points(&self) -> usize {
        self.points.iter().filter(|p| !p.is_finite()).count()
    }

    /// Checks the offset and attribute invariants; returns what is wrong.
    pub fn validate(&self) -> std::result::Result<(), String> {
        if self.offsets.first() != Some(&0) {
            return Err("offsets must start at 0".into());
        }
        if self.offsets.windows(2).any(|w| w[1] < w[0]) {
            return Err("offsets decrease".into());
        }
        if self.offsets.last() != Some(&self.points.len()) {
            return Err("offsets do not end at the point count".into());
        }
        for a in &self.point_attributes {
            if a.values.len() != a.components * self.points.len() {
                return Err(format!(
                    "point attribute '{}' has {} values for {} points",
                    a.name,
                    a.values.len(),
                    self.points.len()
                ));
            }
        }
        for a in &self.line_attributes {
            if a.values.len() != a.components * self.len() {
                return Err(format!(
                    "streamline attribute '{}' has {} values for {} streamlines",
                    a.name,
                    a.values.len(),
                    self.len()
                ));
            }
        }
        Ok(())
    }

    /// Total polyline length of streamline `i` through its finite points (a point with a NaN
    /// or infinite coordinate is left out, as the tube mesher drops it).
    pub fn arc_length(&self, i: usize) -> f64 {
        let mut prev: Option<DVec3> = None;
        let mut sum = 0.0;
        for p in self.line(i).iter().filter(|p| p.is_finite()) {
            let p = p.as_dvec3();
            if let Some(q) = prev {
                sum += (p - q).length();
            }
            prev = Some(p);
        }
        sum
    }
}

/// Axis-aligned bounding box of the finite points of `points` (`None` when none is finite).
pub fn finite_bounds(points: &[Vec3]) -> Option<[Vec3; 2]> {
    let mut it = points.iter().filter(|p| p.is_finite());
    let first = *it.next()?;
    Some(it.fold([first, first], |[lo, hi], &p| [lo.min(p), hi.max(p)]))
}

/// Converts a world point to f64 for fitting code.
pub fn to_f64(p: Vec3) -> DVec3 {
    p.as_dvec3()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn push_line_bounds_and_transform() {
        let mut s = Streamlines::new();
        assert!(s.is_empty());
        assert_eq!(s.bounds(), None);
        s.push(&[Vec3::ZERO, Vec3::X, Vec3::new(1.0, 1.0, 0.0)]);
        s.push(&[Vec3::new(-2.0, 0.0, 3.0)]);
        assert_eq!(s.len(), 2);
        assert_eq!(s.line(1), &[Vec3::new(-2.0, 0.0, 3.0)]);
        assert_eq!(
            s.bounds(),
            Some([Vec3::new(-2.0, 0.0, 0.0), Vec3::new(1.0, 1.0, 3.0)])
        );
        assert!((s.arc_length(0) - 2.0).abs() < 1e-12);
        // Non-finite points are left out of the length (the line through its finite points).
        let mut s2 = Streamlines::new();
        s2.push(&[
            Vec3::ZERO,
            Vec3::new(f32::NAN, 0.0, 0.0),
            Vec3::new(3.0, 4.0, 0.0),
            Vec3::new(3.0, f32::INFINITY, 0.0),
            Vec3::new(3.0, 4.0, 1.0),
        ]);
        assert!((s2.arc_length(0) - 6.0).abs() < 1e-12);
        s.transform(&DMat4::from_translation(DVec3::new(78.0, 76.0, -50.0)));
        assert_eq!(s.line(0)[0], Vec3::new(78.0, 76.0, -50.0));
        s.validate().unwrap();
        s.offsets[1] = 5;
        assert!(s.validate().is_err());
    }
}
