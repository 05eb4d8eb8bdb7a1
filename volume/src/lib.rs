//! umbra's volume model: regular grids of scalar or vector samples in a world frame, the readers
//! and writers of the common scientific volume formats, and the synthetic scenes that tests and
//! benchmarks of the later stages use.
//!
//! Data flows one way: a reader turns a file into a [`Volume`]; nothing in this crate knows about
//! tubes or rendering.
//!
//! # Conventions
//! * Samples are stored as `f32` whatever the file stores (the stored type is kept in
//!   [`Field::stored`] and reported by `umbra info`). Integer data up to 2^24 and all 8/16-bit data
//!   convert exactly; 32/64-bit integers beyond 2^24 and `f64` data are rounded to the nearest
//!   `f32`. NIfTI `scl_slope`/`scl_inter` are applied at load. The renderers' loader,
//!   [`load_scalar`], is the exception: a scalar field of 8 or 16-bit integers (NIfTI, NRRD,
//!   MetaImage) stays in its stored type ([`samples::Samples`], the layout the GPU binds).
//! * Index order: x fastest, then y, then z; a vector field interleaves its three components
//!   per voxel (`data[3 * voxel + c]`).
//! * [`Volume::affine`] maps voxel indices `(i, j, k, 1)` to world coordinates. The world frame is
//!   RAS+ millimetres ([`Space::Ras`]) whenever the file declares an anatomical space: NIfTI as
//!   nibabel reads it, NRRD and MetaImage in LPS with x and y negated. Otherwise it is the
//!   file's own frame ([`Space::File`]).
//! * Vector components are world directions (see each reader for the conversion it makes).
//! * A time-varying field is a [`VolumeSeries`]: frames on one grid at equal time steps, linear in
//!   time between them, periodic or clamped at the ends ([`series`]); NIfTI holds one as a 5-D
//!   image, and [`load_series`] reads any other volume as a steady series of one frame.

pub mod cfd_grid;
pub mod closest_point;
pub mod colormap;
pub mod distance_sweep;
pub mod error;
pub(crate) mod io_util;
pub use io_util::degenerate_axes;
pub mod labels;
pub(crate) mod lanes;
pub mod memory;
pub mod metaimage;
pub mod nifti;
pub mod nrrd;
pub mod occlusion_shading;
pub mod occlusion_sweep;
pub mod plot3d;
pub mod quantile;
pub mod regrid;
pub mod samples;
pub mod series;
pub mod slc;
pub mod synthetic;
pub mod vti;
pub(crate) mod vtk_common;
pub mod vtk_legacy;

pub use error::{Result, VolumeError};
use glam::{DMat4, DVec3, DVec4};
pub use io_util::{
    check_distinct, check_not_input, check_not_read, check_output, check_outputs, clip_text,
    folder_of, forget_input, guard_inputs, gzip_bytes, note_read, open_regular, read_regular,
    read_text, remove_stale_temps, remove_temps_being_written, show_number, temp_name, temp_path,
    write_atomic, write_atomic_with, write_pair, writing, Bytes, MAX_FILE_BYTES,
};
pub use series::VolumeSeries;
use std::path::Path;

/// The sample type a file stores.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ScalarType {
    U8,
    I8,
    U16,
    I16,
    U32,
    I32,
    U64,
    I64,
    F32,
    F64,
}

impl ScalarType {
    /// Bytes per sample.
    pub fn size(self) -> usize {
        match self {
            ScalarType::U8 | ScalarType::I8 => 1,
            ScalarType::U16 | ScalarType::I16 => 2,
            ScalarType::U32 | ScalarType::I32 | ScalarType::F32 => 4,
            ScalarType::U64 | ScalarType::I64 | ScalarType::F64 => 8,
        }
    }

    /// The name `umbra info` prints (`uint8`, `int16`, `float32`, ...).
    pub fn name(self) -> &'static str {
        match self {
            ScalarType::U8 => "uint8",
            ScalarType::I8 => "int8",
            ScalarType::U16 => "uint16",
            ScalarType::I16 => "int16",
            ScalarType::U32 => "uint32",
            ScalarType::I32 => "int32",
            ScalarType::U64 => "uint64",
            ScalarType::I64 => "int64",
            ScalarType::F32 => "float32",
            ScalarType::F64 => "float64",
        }
    }

    pub fn is_integer(self) -> bool {
        !matches!(self, ScalarType::F32 | ScalarType::F64)
    }

    /// The closed range of values the type holds (integers only; floats give +-inf).
    pub fn value_range(self) -> (f64, f64) {
        match self {
            ScalarType::U8 => (0.0, u8::MAX as f64),
            ScalarType::I8 => (i8::MIN as f64, i8::MAX as f64),
            ScalarType::U16 => (0.0, u16::MAX as f64),
            ScalarType::I16 => (i16::MIN as f64, i16::MAX as f64),
            ScalarType::U32 => (0.0, u32::MAX as f64),
            ScalarType::I32 => (i32::MIN as f64, i32::MAX as f64),
            ScalarType::U64 => (0.0, u64::MAX as f64),
            ScalarType::I64 => (i64::MIN as f64, i64::MAX as f64),
            ScalarType::F32 | ScalarType::F64 => (f64::NEG_INFINITY, f64::INFINITY),
        }
    }

    /// Whether every sample of `data` is stored exactly by this type (used by the writers to
    /// keep the file's type where the values allow it).
    pub fn holds_all(self, data: &[f32]) -> bool {
        if !self.is_integer() {
            return true;
        }
        let (lo, hi) = self.value_range();
        data.iter().all(|&v| {
            let v = v as f64;
            v.is_finite() && v.fract() == 0.0 && v >= lo && v <= hi
        })
    }
}

/// The world frame of a volume.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Space {
    /// RAS+ millimetres (x to the right, y anterior, z superior).
    Ras,
    /// The file's own frame: nothing anatomical is declared.
    File,
}

impl Space {
    pub fn name(self) -> &'static str {
        match self {
            Space::Ras => "RAS",
            Space::File => "file",
        }
    }
}

/// One named array of samples on the grid.
#[derive(Clone, Debug, PartialEq)]
pub struct Field {
    pub name: String,
    /// 1 (scalar) or 3 (vector, interleaved per voxel).
    pub components: usize,
    /// The type the file stored before conversion to `f32`.
    pub stored: ScalarType,
    pub data: Vec<f32>,
}

/// Minimum, maximum and count of voxels with a NaN or infinite component.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FieldStats {
    /// Finite minimum over all components (NaN when no sample is finite).
    pub min: f64,
    pub max: f64,
    /// Voxels with at least one NaN or infinite component.
    pub nonfinite: usize,
}

impl Field {
    /// Number of voxels this field covers.
    pub fn voxels(&self) -> usize {
        self.data.len() / self.components.max(1)
    }

    pub fn stats(&self) -> FieldStats {
        let mut min = f64::INFINITY;
        let mut max = f64::NEG_INFINITY;
        let mut nonfinite = 0;
        for voxel in self.data.chunks(self.components.max(1)) {
            let mut bad = false;
            for &v in voxel {
                if v.is_finite() {
                    min = min.min(v as f64);
                    max = max.max(v as f64);
                } else {
                    bad = true;
                }
            }
            nonfinite += bad as usize;
        }
        if min > max {
            min = f64::NAN;
            max = f64::NAN;
        }
        FieldStats {
            min,
            max,
            nonfinite,
        }
    }
}

/// How a caller names a single field: `NAME`, `NAME:magnitude` (a vector's length) or
/// `NAME:0|1|2` / `NAME:x|y|z` (one component of a vector).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FieldSelector {
    pub name: String,
    pub part: FieldPart,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FieldPart {
    Whole,
    Magnitude,
    Component(usize),
}

impl std::str::FromStr for FieldSelector {
    type Err = VolumeError;

    fn from_str(s: &str) -> Result<Self> {
        let (name, part) = match s.rsplit_once(':') {
            None => (s, FieldPart::Whole),
            Some((name, suffix)) => {
                let part = match suffix.to_ascii_lowercase().as_str() {
                    "magnitude" | "mag" | "norm" => FieldPart::Magnitude,
                    "0" | "x" => FieldPart::Component(0),
                    "1" | "y" => FieldPart::Component(1),
                    "2" | "z" => FieldPart::Component(2),
                    other => {
                        return Err(VolumeError::Invalid(format!(
                            "field {s}: unknown suffix ':{other}' (use :magnitude, :x, :y or :z)"
                        )))
                    }
                };
                (name, part)
            }
        };
        if name.is_empty() {
            return Err(VolumeError::Invalid(format!("field {s}: empty field name")));
        }
        Ok(FieldSelector {
            name: name.to_string(),
            part,
        })
    }
}

/// A regular grid of samples with an index-to-world affine.
#[derive(Clone, Debug, PartialEq)]
pub struct Volume {
    /// The format the volume was read from (`nifti1`, `nrrd`, `vtk-legacy`, ...).
    pub format: String,
    /// Samples along i, j, k.
    pub dims: [usize; 3],
    /// Index (i, j, k, 1) to world.
    pub affine: DMat4,
    pub space: Space,
    /// All arrays of the file, by name; never empty.
    pub fields: Vec<Field>,
    /// The field used when none is named (the file's active scalars, or the first array).
    pub default_field: usize,
    /// What the reader accepted but a user should know (repaired data, ignored parts).
    pub warnings: Vec<String>,
}

impl Volume {
    /// A volume with one field; `data.len()` must equal `dims` product times `components`.
    pub fn new(
        dims: [usize; 3],
        affine: DMat4,
        space: Space,
        field: Field,
    ) -> std::result::Result<Self, VolumeError> {
        let v = Volume {
            format: "memory".into(),
            dims,
            affine,
            space,
            fields: vec![field],
            default_field: 0,
            warnings: vec![],
        };
        v.validate()?;
        Ok(v)
    }

    /// Checks the invariants every reader guarantees: a positive grid of at most
    /// [`MAX_SAMPLES`] values, every field the grid's size, and a world frame that is usable in
    /// `f32` (see [`check_frame`]).
    pub fn validate(&self) -> Result<()> {
        if self.fields.is_empty() {
            return Err(VolumeError::Invalid("volume has no data arrays".into()));
        }
        let n = checked_voxels(self.dims)?;
        for f in &self.fields {
            if f.components != 1 && f.components != 3 {
                return Err(VolumeError::Invalid(format!(
                    "field '{}' has {} components (1 or 3 supported)",
                    f.name, f.components
                )));
            }
            if f.data.len() != n * f.components {
                return Err(VolumeError::Invalid(format!(
                    "field '{}' has {} values, the grid needs {}",
                    f.name,
                    f.data.len(),
                    n * f.components
                )));
            }
        }
        if self.default_field >= self.fields.len() {
            return Err(VolumeError::Invalid("default field out of range".into()));
        }
        check_frame(self.dims, self.affine)
    }

    /// Voxels of the grid (saturating: a validated volume never gets near `usize::MAX`).
    pub fn voxel_count(&self) -> usize {
        self.dims[0]
            .saturating_mul(self.dims[1])
            .saturating_mul(self.dims[2])
    }

    /// Linear index of voxel (i, j, k).
    pub fn index(&self, i: usize, j: usize, k: usize) -> usize {
        i + self.dims[0] * (j + self.dims[1] * k)
    }

    /// The field used when none is named.
    pub fn default(&self) -> &Field {
        &self.fields[self.default_field]
    }

    pub fn field_names(&self) -> Vec<String> {
        self.fields.iter().map(|f| f.name.clone()).collect()
    }

    /// [`Volume::select`] that leaves the volume a grid: the selected field's samples are
    /// moved out (not copied) and every field's samples are dropped, so that a large volume
    /// is held once.
    pub fn take_field(&mut self, selector: Option<&FieldSelector>) -> Result<Field> {
        let whole = match selector {
            None => Some(self.default_field),
            Some(sel) if sel.part == FieldPart::Whole => {
                self.fields.iter().position(|f| f.name == sel.name)
            }
            Some(_) => None,
        };
        let field = match whole {
            Some(i) if i < self.fields.len() => {
                let f = &mut self.fields[i];
                Field {
                    name: f.name.clone(),
                    components: f.components,
                    stored: f.stored,
                    data: std::mem::take(&mut f.data),
                }
            }
            _ => self.select(selector)?,
        };
        for f in &mut self.fields {
            f.data = Vec::new();
        }
        Ok(field)
    }

    /// Selects a field (or a derived scalar of a vector field); `None` gives the default field.
    pub fn select(&self, selector: Option<&FieldSelector>) -> Result<Field> {
        let Some(sel) = selector else {
            return Ok(self.default().clone());
        };
        let field = self
            .fields
            .iter()
            .find(|f| f.name == sel.name)
            .ok_or_else(|| {
                VolumeError::Invalid(format!(
                    "field {}: no such field; this file has: {}",
                    sel.name,
                    self.field_names().join(", ")
                ))
            })?;
        match sel.part {
            FieldPart::Whole => Ok(field.clone()),
            FieldPart::Magnitude | FieldPart::Component(_) if field.components != 3 => {
                Err(VolumeError::Invalid(format!(
                    "field {}: ':magnitude' and components need a 3-component field, '{}' has {}",
                    sel.name, field.name, field.components
                )))
            }
            FieldPart::Magnitude => Ok(Field {
                name: format!("{}:magnitude", field.name),
                components: 1,
                stored: ScalarType::F32,
                data: field
                    .data
                    .chunks_exact(3)
                    .map(|v| {
                        ((v[0] as f64).powi(2) + (v[1] as f64).powi(2) + (v[2] as f64).powi(2))
                            .sqrt() as f32
                    })
                    .collect(),
            }),
            FieldPart::Component(c) => Ok(Field {
                name: format!("{}:{}", field.name, ["x", "y", "z"][c]),
                components: 1,
                stored: field.stored,
                data: field.data.chunks_exact(3).map(|v| v[c]).collect(),
            }),
        }
    }

    /// Lengths of the three axis vectors of the affine (the voxel spacing in world units).
    pub fn spacing(&self) -> [f64; 3] {
        [
            self.affine.x_axis.truncate().length(),
            self.affine.y_axis.truncate().length(),
            self.affine.z_axis.truncate().length(),
        ]
    }

    /// World position of voxel centre (i, j, k) (fractional indices allowed).
    pub fn index_to_world(&self, ijk: DVec3) -> DVec3 {
        (self.affine * DVec4::new(ijk.x, ijk.y, ijk.z, 1.0)).truncate()
    }

    /// Axis-aligned world bounding box of the voxel centres: `[min, max]`.
    pub fn bounds(&self) -> [DVec3; 2] {
        grid_bounds(self.dims, self.affine)
    }
}

/// The most samples (values, all components) one array may hold: 2^32.
pub const MAX_SAMPLES: u64 = io_util::MAX_SAMPLES;

/// The smallest and largest voxel spacing (world units) a volume may have, and the largest
/// absolute world coordinate of its grid. Outside them a frame is refused: a spacing that
/// underflows `f32` (a denormal such as 1e-320 reads as 0) or bounds that overflow it
/// (1e308 x 256) would give the renderer null or infinite boxes.
pub const MIN_SPACING: f64 = 1e-12;
pub const MAX_SPACING: f64 = 1e12;
pub const MAX_COORDINATE: f64 = 1e15;

/// The grid's voxel count, with every dimension at least 1 and the product checked (no
/// wrapping) against [`MAX_SAMPLES`].
pub fn checked_voxels(dims: [usize; 3]) -> Result<usize> {
    let mut n: u64 = 1;
    for &d in &dims {
        if d == 0 {
            return Err(VolumeError::Invalid(format!(
                "grid {} x {} x {} has an empty axis",
                dims[0], dims[1], dims[2]
            )));
        }
        n = n
            .checked_mul(d as u64)
            .filter(|&n| n <= MAX_SAMPLES)
            .ok_or_else(|| {
                VolumeError::Invalid(format!(
                    "grid {} x {} x {} has more than {MAX_SAMPLES} voxels",
                    dims[0], dims[1], dims[2]
                ))
            })?;
    }
    Ok(n as usize)
}

/// Checks an index-to-world affine of a `dims` grid: finite entries, a last row of
/// `(0, 0, 0, 1)`, each axis's spacing within [`MIN_SPACING`, `MAX_SPACING`], independent
/// axes (the 3 x 3 part invertible, not merely nonzero), and every grid corner within
/// [`MAX_COORDINATE`] of the origin.
pub fn check_frame(dims: [usize; 3], affine: DMat4) -> Result<()> {
    let bad = |msg: String| Err(VolumeError::Invalid(msg));
    if let Some(v) = affine.to_cols_array().iter().find(|v| !v.is_finite()) {
        return bad(format!("the affine has a non-finite entry ({v})"));
    }
    let row3 = affine.row(3);
    if row3 != DVec4::new(0.0, 0.0, 0.0, 1.0) {
        return bad(format!(
            "the affine's last row is {row3:?}, not (0, 0, 0, 1) (no projective frames)"
        ));
    }
    let axes = [affine.x_axis, affine.y_axis, affine.z_axis].map(|a| a.truncate());
    for (a, name) in axes.iter().zip(["i", "j", "k"]) {
        let s = a.length();
        if !(MIN_SPACING..=MAX_SPACING).contains(&s) {
            return bad(format!(
                "the spacing along {name} is {s:e} (world units per voxel); umbra reads \
                 {MIN_SPACING:e} to {MAX_SPACING:e}"
            ));
        }
    }
    // Independence: the volume of the unit cell against the product of its edge lengths
    // (1 for orthogonal axes, 0 for parallel ones).
    let cell = axes[0].cross(axes[1]).dot(axes[2]).abs();
    let edges = axes[0].length() * axes[1].length() * axes[2].length();
    if cell.is_nan() || cell <= 1e-6 * edges {
        return bad(format!(
            "the affine's axes are (nearly) linearly dependent (cell volume {cell:e}, edges' \
             product {edges:e}): the grid has no 3-D world frame"
        ));
    }
    let [lo, hi] = grid_bounds(dims, affine);
    let far = lo.abs().max(hi.abs()).max_element();
    if far.is_nan() || far > MAX_COORDINATE {
        return bad(format!(
            "the grid reaches world coordinate {far:e}; umbra reads coordinates up to \
             {MAX_COORDINATE:e}"
        ));
    }
    Ok(())
}

/// Axis-aligned world bounding box of the node positions of a `dims` grid whose index-to-world
/// map is `affine`: the box of its eight corner nodes.
pub fn grid_bounds(dims: [usize; 3], affine: DMat4) -> [DVec3; 2] {
    let mut lo = DVec3::splat(f64::INFINITY);
    let mut hi = DVec3::splat(f64::NEG_INFINITY);
    for c in 0..8 {
        let corner = |bit: usize, a: usize| {
            if c & bit != 0 {
                dims[a].saturating_sub(1) as f64
            } else {
                0.0
            }
        };
        let p = (affine * DVec4::new(corner(1, 0), corner(2, 1), corner(4, 2), 1.0)).truncate();
        lo = lo.min(p);
        hi = hi.max(p);
    }
    [lo, hi]
}

/// A file name's extension in lower case, after a `.gz` (`a.NII.gz` gives `nii`; none: "").
fn extension(path: &Path) -> String {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    let stem = name.strip_suffix(".gz").unwrap_or(&name);
    stem.rsplit_once('.')
        .map(|(_, e)| e)
        .unwrap_or("")
        .to_string()
}

/// The header of an Analyze-style NIfTI pair when `path` names its image (`x.img`, `x.img.gz`):
/// the `x.hdr` or `x.hdr.gz` beside it, when there is one; else `path`. Suffixes in any case
/// (`X.IMG` finds `X.HDR`, `nifti::pair_partners`).
fn nifti_pair_header(path: &Path) -> std::borrow::Cow<'_, Path> {
    nifti::pair_partners(path, "img", "hdr")
        .into_iter()
        .find(|h| h.is_file())
        .map_or(path.into(), Into::into)
}

/// Whether a file's name is one of the volume formats' (`.nii`, `.nii.gz`, `.hdr`, `.nrrd`,
/// `.nhdr`, `.vti`, `.mhd`, `.mha`, `.slc`): such a file is read by its reader or refused, never
/// guessed at as a PLOT3D grid (which has no signature).
pub fn has_volume_extension(path: &Path) -> bool {
    let ext = extension(path);
    let ext = ext.as_str();
    matches!(
        ext,
        "nii" | "hdr" | "img" | "nrrd" | "nhdr" | "vti" | "mhd" | "mha" | "raw" | "slc"
    )
}

/// Reads a volume, choosing the reader by file name (and by content where the name says nothing).
///
/// Supported: NIfTI-1/2 (`.nii`, `.nii.gz`, `.hdr`+`.img`), NRRD (`.nrrd`, `.nhdr`), VTK legacy
/// STRUCTURED_POINTS (`.vtk`), VTK XML ImageData (`.vti`), MetaImage (`.mhd`, `.mha`), SLC (`.slc`).
pub fn load(path: &Path) -> Result<Volume> {
    let path = &nifti_pair_header(path);
    let ext = extension(path);
    let ext = ext.as_str();
    let vol = match ext {
        "nii" | "hdr" => nifti::read(path)?,
        "nrrd" | "nhdr" => nrrd::read(path)?,
        "vtk" => vtk_legacy::read(path)?,
        "vti" => vti::read(path)?,
        "mhd" | "mha" => metaimage::read(path)?,
        "slc" => slc::read(path)?,
        _ => sniff(path)?,
    };
    vol.validate()
        .map_err(|e| VolumeError::format(path, "data", e.to_string()))?;
    Ok(vol)
}

/// A volume's scalar field as the renderers take it: the grid (`volume`, every field's
/// samples dropped), the field's name and stored type, and its samples - in their stored type
/// when they are 8 or 16-bit integers read from NIfTI, NRRD or MetaImage (never converted to
/// `f32`: a 16-bit volume is held in 2 bytes a voxel), else `f32`.
#[derive(Debug)]
pub struct ScalarField {
    pub volume: Volume,
    pub name: String,
    pub stored: ScalarType,
    pub samples: samples::Samples,
}

/// Loads the scalar field `selector` (`None`: the default field) of the volume at `path` for
/// rendering ([`ScalarField`]): a scalar field of 8 or 16-bit integers in NIfTI (steady, not
/// scaled), NRRD or MetaImage is read in its stored type; every other field as [`load`]
/// reads it, moved out of the volume (no copy). Errors for a vector field (select
/// `NAME:magnitude` or a component).
pub fn load_scalar(path: &Path, selector: Option<&FieldSelector>) -> Result<ScalarField> {
    let path = &nifti_pair_header(path);
    let (mut vol, stored) = match extension(path).as_str() {
        "nii" | "hdr" => nifti::read_stored(path)?,
        "nrrd" | "nhdr" => nrrd::read_stored(path)?,
        "mhd" | "mha" => metaimage::read_stored(path)?,
        _ => (load(path)?, None),
    };
    let default = selector.is_none_or(|s| {
        s.part == FieldPart::Whole
            && vol
                .fields
                .get(vol.default_field)
                .is_some_and(|f| f.name == s.name)
    });
    if let (Some(samples), true) = (stored, default) {
        // The stored samples are the default field's; the rest of the volume is checked as
        // `load` checks it.
        let f = &vol.fields[vol.default_field];
        let n = checked_voxels(vol.dims)
            .and_then(|n| check_frame(vol.dims, vol.affine).map(|_| n))
            .map_err(|e| VolumeError::format(path, "data", e.to_string()))?;
        if samples.len() != n {
            return Err(VolumeError::format(
                path,
                "data",
                format!("{} samples for {n} voxels", samples.len()),
            ));
        }
        let (name, stored) = (f.name.clone(), f.stored);
        return Ok(ScalarField {
            volume: vol,
            name,
            stored,
            samples,
        });
    }
    if vol.fields.iter().any(|f| f.data.is_empty()) {
        // A field read in its stored type but another selected: read again as f32.
        vol = load(path)?;
    } else {
        vol.validate()
            .map_err(|e| VolumeError::format(path, "data", e.to_string()))?;
    }
    let field = vol.take_field(selector)?;
    if field.components != 1 {
        return Err(VolumeError::Invalid(format!(
            "'{}' has {} components; choose NAME:magnitude or NAME:x|y|z",
            field.name, field.components
        )));
    }
    Ok(ScalarField {
        volume: vol,
        name: field.name,
        stored: field.stored,
        samples: samples::Samples::f32(field.data),
    })
}

/// Reads a volume as a time series: a NIfTI file with a time axis (5-D, intent VECTOR, `dim[4]`
/// frames; see [`nifti::read_series`]) gives all its frames, any other volume a steady series
/// of one frame ([`VolumeSeries::steady`]).
pub fn load_series(path: &Path) -> Result<VolumeSeries> {
    let path = &nifti_pair_header(path);
    let ext = extension(path);
    let ext = ext.as_str();
    if matches!(ext, "nii" | "hdr") {
        let s = nifti::read_series(path)?;
        s.validate()
            .map_err(|e| VolumeError::format(path, "data", e.to_string()))?;
        return Ok(s);
    }
    load(path).map(VolumeSeries::steady)
}

/// Whether a file is a CFD grid rather than a volume: `.vtr`, `.vts`, `.vtu`, or a legacy
/// `.vtk` whose dataset is STRUCTURED_GRID or RECTILINEAR_GRID. (PLOT3D files have no
/// signature; callers try them when a file is no volume.)
pub fn is_grid(path: &Path) -> bool {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    let ext = name.rsplit_once('.').map(|(_, e)| e).unwrap_or("");
    match ext {
        "vtr" | "vts" | "vtu" => true,
        "vtk" => io_util::read_head(path, 512)
            .map(|h| {
                let h = String::from_utf8_lossy(&h).to_ascii_uppercase();
                h.contains("STRUCTURED_GRID") || h.contains("RECTILINEAR_GRID")
            })
            .unwrap_or(false),
        _ => false,
    }
}

/// Reads a CFD grid for resampling: VTK XML `.vtr`, `.vts`, `.vtu`, VTK legacy `.vtk`
/// (STRUCTURED_GRID, RECTILINEAR_GRID, STRUCTURED_POINTS), or a PLOT3D grid (any other name;
/// `q` is its solution file). Returns the grid and reader warnings.
pub fn load_grid(path: &Path, q: Option<&Path>) -> Result<(cfd_grid::CfdGrid, Vec<String>)> {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    let ext = name.rsplit_once('.').map(|(_, e)| e).unwrap_or("");
    if q.is_some() && matches!(ext, "vtr" | "vts" | "vtu" | "vtk") {
        return Err(VolumeError::Invalid(format!(
            "{}: a PLOT3D solution file is for PLOT3D grids; VTK files carry their own arrays",
            path.display()
        )));
    }
    match ext {
        "vtr" | "vts" | "vtu" => Ok((vti::read_grid(path)?, vec![])),
        "vtk" => Ok((vtk_legacy::read_grid(path)?, vec![])),
        _ if has_volume_extension(path) => Err(VolumeError::format(
            path,
            "file name",
            "a volume format, not a CFD grid (.vtr, .vts, .vtu, .vtk or PLOT3D): it is already \
             a regular grid",
        )),
        _ => plot3d::read(path, q),
    }
}

fn sniff(path: &Path) -> Result<Volume> {
    let ext = extension(path);
    if matches!(ext.as_str(), "trk" | "tck" | "trx" | "tt") {
        return Err(VolumeError::format(
            path,
            "file name",
            "a tractogram, not a volume (a grid of samples)",
        ));
    }
    if matches!(ext.as_str(), "vtr" | "vts" | "vtu") {
        return Err(VolumeError::format(
            path,
            "file name",
            "a CFD grid (VTK XML rectilinear, structured or unstructured), not a regular volume; \
             resample it onto a regular grid first",
        ));
    }
    let head = io_util::read_head(path, 600)?;
    let starts = |m: &[u8]| head.starts_with(m);
    // NIfTI's first field, sizeof_hdr: 348 (NIfTI-1) or 540 (NIfTI-2), in either byte order.
    let nifti_header = head.len() >= 348 && {
        let b = [head[0], head[1], head[2], head[3]];
        [i32::from_le_bytes(b), i32::from_be_bytes(b)]
            .iter()
            .any(|&n| n == 348 || n == 540)
    };
    if starts(b"NRRD") {
        nrrd::read(path)
    } else if starts(b"# vtk DataFile") {
        vtk_legacy::read(path)
    } else if starts(b"<?xml") || starts(b"<VTKFile") {
        vti::read(path)
    } else if starts(b"11111") {
        slc::read(path)
    } else if starts(&[0x1f, 0x8b]) || nifti_header {
        nifti::read(path)
    } else {
        Err(VolumeError::format(
            path,
            "file name",
            "unknown volume format: neither its name nor its first bytes are a volume's \
             (expected .nii, .nii.gz, .nrrd, .nhdr, .vtk, .vti, .mhd, .mha or .slc; CFD grids - \
             .vtr, .vts, .vtu, PLOT3D - and tractograms are not volumes)",
        ))
    }
}
