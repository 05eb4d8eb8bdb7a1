//! NIfTI-1 and NIfTI-2 reader and NIfTI-1 writer.
//!
//! Reading follows nibabel, the reference behaviour for neuroimaging users:
//! * byte order from `sizeof_hdr` (348 or 540, as stored or byte-swapped);
//! * the affine is the sform when `sform_code > 0`, else the qform when `qform_code > 0`
//!   (quaternion b, c, d with a = sqrt(1 - b^2 - c^2 - d^2), `qfac = pixdim[0]`, which is taken as
//!   1 unless it is exactly -1, as nibabel fixes it), else nibabel's fall-back
//!   `diag(-dx, dy, dz)` centred on the grid. Space is RAS whenever a code is set, `file` otherwise;
//!   units in `xyzt_units` are reported, never rescaled (nibabel does not either);
//! * `scl_slope`/`scl_inter` apply when the slope is finite and non-zero;
//! * a vector field is a 4-D image whose 4th axis has 3 entries, or a 5-D image with
//!   `intent_code` VECTOR (1007), `dim[4] == 1` and `dim[5] == 3`;
//! * a time series of vector fields is a 5-D VECTOR image with `dim[4] > 1` frames: `pixdim[4]`
//!   is the time step, `toffset` the first time, and `descrip` holding `periodic` makes it
//!   periodic ([`read_series`], [`write_series`], [`crate::series`]); [`read`] gives its first
//!   frame with a warning.
//!
//! # The frame of vector components
//! FSL's `dtifit` (the common producer of `V1` images) writes eigenvectors along the voxel axes
//! in FSL's "radiological" voxel convention: when the voxel-to-world matrix has a positive
//! determinant (neurological storage), FSL flips the first voxel axis, so the stored x component
//! is negated relative to the i axis. We convert to world directions as
//! `w = R diag(f, 1, 1) v` with `R` the affine's 3x3 part with unit columns and `f = -1` when
//! `det(A) > 0`, else `f = 1`. The writer applies the inverse, so a round trip keeps the world
//! directions (to f32 rounding). The same convention applies to `intent VECTOR` files.

use crate::io_util::{self, checked_count, take_samples};
use crate::samples::Samples;
use crate::{Field, Result, ScalarType, Space, Volume, VolumeError, VolumeSeries};
use glam::{DMat3, DMat4, DQuat, DVec3, DVec4};
use std::path::{Path, PathBuf};

const INTENT_VECTOR: i32 = 1007;

/// Everything of a NIfTI header the reader uses, in one type for both versions.
#[derive(Clone, Debug)]
struct Header {
    version: u8,
    big_endian: bool,
    dim: [i64; 8],
    datatype: i32,
    pixdim: [f64; 8],
    vox_offset: f64,
    scl_slope: f64,
    scl_inter: f64,
    qform_code: i32,
    sform_code: i32,
    quatern: [f64; 3],
    qoffset: [f64; 3],
    srow: [[f64; 4]; 3],
    intent_code: i32,
    magic: [u8; 4],
    toffset: f64,
    /// The `descrip` text up to its first NUL.
    descrip: String,
}

fn parse_header(path: &Path, b: &[u8]) -> Result<Header> {
    if b.len() < 4 {
        return Err(VolumeError::format(
            path,
            "sizeof_hdr",
            "file ends before the header",
        ));
    }
    let le = i32::from_le_bytes(b[0..4].try_into().unwrap());
    let be = i32::from_be_bytes(b[0..4].try_into().unwrap());
    let (version, big_endian) = match (le, be) {
        (348, _) => (1, false),
        (_, 348) => (1, true),
        (540, _) => (2, false),
        (_, 540) => (2, true),
        _ => {
            return Err(VolumeError::format(
                path,
                "sizeof_hdr",
                format!("{le} is neither 348 (NIfTI-1) nor 540 (NIfTI-2) in either byte order"),
            ))
        }
    };
    let size = if version == 1 { 348 } else { 540 };
    if b.len() < size {
        return Err(VolumeError::format(
            path,
            "header",
            format!(
                "file has {} bytes, the NIfTI-{version} header needs {size}",
                b.len()
            ),
        ));
    }
    let r = io_util::Bytes { b, big_endian };
    let mut h = Header {
        version,
        big_endian,
        dim: [0; 8],
        datatype: 0,
        pixdim: [0.0; 8],
        vox_offset: 0.0,
        scl_slope: 0.0,
        scl_inter: 0.0,
        qform_code: 0,
        sform_code: 0,
        quatern: [0.0; 3],
        qoffset: [0.0; 3],
        srow: [[0.0; 4]; 3],
        intent_code: 0,
        magic: [0; 4],
        toffset: 0.0,
        descrip: String::new(),
    };
    let text = |b: &[u8]| {
        let end = b.iter().position(|&c| c == 0).unwrap_or(b.len());
        String::from_utf8_lossy(&b[..end]).trim().to_string()
    };
    if version == 1 {
        for i in 0..8 {
            h.dim[i] = r.i16(40 + 2 * i) as i64;
            h.pixdim[i] = r.f32(76 + 4 * i) as f64;
        }
        h.intent_code = r.i16(68) as i32;
        h.datatype = r.i16(70) as i32;
        h.vox_offset = r.f32(108) as f64;
        h.scl_slope = r.f32(112) as f64;
        h.scl_inter = r.f32(116) as f64;
        h.toffset = r.f32(136) as f64;
        h.descrip = text(&b[148..228]);
        h.qform_code = r.i16(252) as i32;
        h.sform_code = r.i16(254) as i32;
        for i in 0..3 {
            h.quatern[i] = r.f32(256 + 4 * i) as f64;
            h.qoffset[i] = r.f32(268 + 4 * i) as f64;
            for j in 0..4 {
                h.srow[i][j] = r.f32(280 + 16 * i + 4 * j) as f64;
            }
        }
        h.magic.copy_from_slice(&b[344..348]);
        if &h.magic != b"n+1\0" && &h.magic != b"ni1\0" {
            return Err(VolumeError::format(
                path,
                "magic",
                format!(
                    "{:?} is not 'n+1' or 'ni1'",
                    String::from_utf8_lossy(&h.magic[..3])
                ),
            ));
        }
    } else {
        let magic = &b[4..12];
        if &magic[..3] != b"n+2" && &magic[..3] != b"ni2" {
            return Err(VolumeError::format(
                path,
                "magic",
                format!(
                    "{:?} is not 'n+2' or 'ni2'",
                    String::from_utf8_lossy(&magic[..3])
                ),
            ));
        }
        h.magic.copy_from_slice(&magic[..4]);
        h.datatype = r.i16(12) as i32;
        for i in 0..8 {
            h.dim[i] = r.i64(16 + 8 * i);
            h.pixdim[i] = r.f64(104 + 8 * i);
        }
        h.vox_offset = r.i64(168) as f64;
        h.scl_slope = r.f64(176);
        h.scl_inter = r.f64(184);
        h.toffset = r.f64(216);
        h.descrip = text(&b[240..320]);
        h.qform_code = r.i32(344);
        h.sform_code = r.i32(348);
        for i in 0..3 {
            h.quatern[i] = r.f64(352 + 8 * i);
            h.qoffset[i] = r.f64(376 + 8 * i);
            for j in 0..4 {
                h.srow[i][j] = r.f64(400 + 32 * i + 8 * j);
            }
        }
        h.intent_code = r.i32(504);
    }
    Ok(h)
}

fn datatype(path: &Path, code: i32) -> Result<ScalarType> {
    Ok(match code {
        2 => ScalarType::U8,
        4 => ScalarType::I16,
        8 => ScalarType::I32,
        16 => ScalarType::F32,
        64 => ScalarType::F64,
        256 => ScalarType::I8,
        512 => ScalarType::U16,
        768 => ScalarType::U32,
        1024 => ScalarType::I64,
        1280 => ScalarType::U64,
        other => {
            return Err(VolumeError::format(
                path,
                "datatype",
                format!(
                    "code {other} is not supported (u8, i8, i16, u16, i32, u32, i64, u64, f32, f64 are; \
                     complex and RGB are not)"
                ),
            ))
        }
    })
}

fn datatype_code(t: ScalarType) -> i16 {
    match t {
        ScalarType::U8 => 2,
        ScalarType::I16 => 4,
        ScalarType::I32 => 8,
        ScalarType::F32 => 16,
        ScalarType::F64 => 64,
        ScalarType::I8 => 256,
        ScalarType::U16 => 512,
        ScalarType::U32 => 768,
        ScalarType::I64 => 1024,
        ScalarType::U64 => 1280,
    }
}

/// nibabel's quaternion-to-matrix (`quat2mat` of (a, b, c, d)).
fn quat_to_mat(path: &Path, q: [f64; 3]) -> Result<DMat3> {
    let [b, c, d] = q;
    let w2 = 1.0 - (b * b + c * c + d * d);
    let a = if w2 < 0.0 {
        if w2 < -1e-5 {
            return Err(VolumeError::format(
                path,
                "quatern_b/c/d",
                format!(
                    "b^2 + c^2 + d^2 = {} exceeds 1: not a unit quaternion",
                    1.0 - w2
                ),
            ));
        }
        0.0
    } else {
        w2.sqrt()
    };
    let n = a * a + b * b + c * c + d * d;
    if n < 1e-12 {
        return Ok(DMat3::IDENTITY);
    }
    let s = 2.0 / n;
    let (x, y, z, w) = (b, c, d, a);
    let (xs, ys, zs) = (x * s, y * s, z * s);
    let (wx, wy, wz) = (w * xs, w * ys, w * zs);
    let (xx, xy, xz) = (x * xs, x * ys, x * zs);
    let (yy, yz, zz) = (y * ys, y * zs, z * zs);
    // Rows of nibabel's matrix, stored here by columns.
    Ok(DMat3::from_cols(
        DVec3::new(1.0 - (yy + zz), xy + wz, xz - wy),
        DVec3::new(xy - wz, 1.0 - (xx + zz), yz + wx),
        DVec3::new(xz + wy, yz - wx, 1.0 - (xx + yy)),
    ))
}

/// A warning when the frame comes from `pixdim` (no sform) and a voxel size there is zero,
/// negative or not finite: nibabel takes 1 for it, and so does umbra, but the user should know.
fn pixdim_warnings(h: &Header) -> Vec<String> {
    if h.sform_code > 0 {
        return vec![];
    }
    let bad: Vec<String> = (1..=3)
        .filter(|&i| !(h.pixdim[i].is_finite() && h.pixdim[i] != 0.0))
        .map(|i| format!("pixdim[{i}] = {}", h.pixdim[i]))
        .collect();
    if bad.is_empty() {
        vec![]
    } else {
        vec![format!(
            "{} read as 1 (the voxel size is unknown)",
            bad.join(", ")
        )]
    }
}

fn affine_of(path: &Path, h: &Header, dims: [usize; 3]) -> Result<(DMat4, Space)> {
    if h.sform_code > 0 {
        let s = h.srow;
        let m = DMat4::from_cols(
            DVec4::new(s[0][0], s[1][0], s[2][0], 0.0),
            DVec4::new(s[0][1], s[1][1], s[2][1], 0.0),
            DVec4::new(s[0][2], s[1][2], s[2][2], 0.0),
            DVec4::new(s[0][3], s[1][3], s[2][3], 1.0),
        );
        if !m.to_cols_array().iter().all(|v| v.is_finite()) {
            return Err(VolumeError::format(
                path,
                "srow_x/y/z",
                "non-finite entries in the sform",
            ));
        }
        if crate::io_util::degenerate_axes(glam::DMat3::from_mat4(m)) {
            return Err(VolumeError::format(
                path,
                "srow_x/y/z",
                "the sform is singular",
            ));
        }
        return Ok((m, Space::Ras));
    }
    let zooms = [h.pixdim[1].abs(), h.pixdim[2].abs(), h.pixdim[3].abs()];
    let zooms = zooms.map(|z| if z.is_finite() && z > 0.0 { z } else { 1.0 });
    if h.qform_code > 0 {
        if !h
            .quatern
            .iter()
            .chain(h.qoffset.iter())
            .all(|v| v.is_finite())
        {
            return Err(VolumeError::format(
                path,
                "quatern/qoffset",
                "non-finite qform parameters",
            ));
        }
        let r = quat_to_mat(path, h.quatern)?;
        let qfac = if h.pixdim[0] == -1.0 { -1.0 } else { 1.0 };
        let m3 = r * DMat3::from_diagonal(DVec3::new(zooms[0], zooms[1], zooms[2] * qfac));
        let m = DMat4::from_cols(
            m3.x_axis.extend(0.0),
            m3.y_axis.extend(0.0),
            m3.z_axis.extend(0.0),
            DVec4::new(h.qoffset[0], h.qoffset[1], h.qoffset[2], 1.0),
        );
        return Ok((m, Space::Ras));
    }
    // nibabel's get_base_affine: x flipped, origin at the grid centre.
    let c = |n: usize, z: f64| (n as f64 - 1.0) / 2.0 * z;
    let m = DMat4::from_cols(
        DVec4::new(-zooms[0], 0.0, 0.0, 0.0),
        DVec4::new(0.0, zooms[1], 0.0, 0.0),
        DVec4::new(0.0, 0.0, zooms[2], 0.0),
        DVec4::new(
            c(dims[0], zooms[0]),
            -c(dims[1], zooms[1]),
            -c(dims[2], zooms[2]),
            1.0,
        ),
    );
    Ok((m, Space::File))
}

/// The matrix taking FSL voxel-frame vector components to world directions (see the module doc).
pub fn vector_to_world(affine: &DMat4) -> DMat3 {
    let m = DMat3::from_mat4(*affine);
    let unit = |v: DVec3| {
        let l = v.length();
        if l > 0.0 {
            v / l
        } else {
            v
        }
    };
    let r = DMat3::from_cols(unit(m.x_axis), unit(m.y_axis), unit(m.z_axis));
    let f = if m.determinant() > 0.0 { -1.0 } else { 1.0 };
    r * DMat3::from_diagonal(DVec3::new(f, 1.0, 1.0))
}

fn transform_vectors(data: &mut [f32], m: DMat3) {
    for v in data.chunks_exact_mut(3) {
        if v.iter().all(|x| x.is_finite()) {
            let w = m * DVec3::new(v[0] as f64, v[1] as f64, v[2] as f64);
            v[0] = w.x as f32;
            v[1] = w.y as f32;
            v[2] = w.z as f32;
        }
    }
}

/// Reads a `.nii`, `.nii.gz` or `.hdr`/`.img` pair. A time series of vector fields (5-D,
/// `dim[4] > 1`: [`read_series`]) gives its first frame, with a warning.
pub fn read(path: &Path) -> Result<Volume> {
    read_series(path).map(first_frame)
}

/// A series' first frame, with a warning when there are more.
fn first_frame(mut s: VolumeSeries) -> Volume {
    let n = s.frames.len();
    let mut v = s.frames.swap_remove(0);
    if n > 1 {
        v.warnings.push(format!(
            "a time series of {n} vector fields (time step {}, first time {}{}): this is frame 0 \
             only; `umbra trace --pathlines` reads them all",
            s.dt,
            s.t0,
            if s.periodic { ", periodic" } else { "" }
        ));
    }
    v
}

/// Reads a NIfTI file as a time series ([`VolumeSeries`]).
///
/// A 5-D image with intent VECTOR (1007) and `dim[5] == 3` holds `dim[4]` vector fields:
/// sample `(i, j, k, t, c)` at index `i + nx (j + ny (k + nz (t + nt c)))`, so each component
/// is a block of frames. Frame `t` is at time `toffset + t pixdim[4]`; with `dim[4] > 1`
/// `pixdim[4]` must be positive. The series is periodic (period `dim[4] pixdim[4]`) when the
/// header's `descrip` holds the word `periodic` (any case), as umbra writes it
/// ([`write_series`]), else clamped at its ends (see [`crate::series`]). Every other image
/// (3-D scalar, 4-D with 3 components, 5-D VECTOR with `dim[4] == 1`) is a steady series of one
/// frame.
pub fn read_series(path: &Path) -> Result<VolumeSeries> {
    read_series_as(path, false).map(|(s, _)| s)
}

/// [`read`] keeping a steady scalar image of 8 or 16-bit integers without scaling
/// (`scl_slope` 0 or 1, `scl_inter` 0) in its stored type: the samples are returned beside
/// the volume, whose field then has no `f32` data (`None`: the image is not such, its samples
/// are in the volume as `f32`).
pub(crate) fn read_stored(path: &Path) -> Result<(Volume, Option<Samples>)> {
    let (s, stored) = read_series_as(path, true)?;
    Ok((first_frame(s), stored))
}

fn read_series_as(path: &Path, keep_stored: bool) -> Result<(VolumeSeries, Option<Samples>)> {
    let raw = io_util::read_file(path)?;
    let gz = raw.starts_with(&[0x1f, 0x8b]);
    // Decode just enough of a gzip stream to see the header first.
    let head = if gz {
        let mut head = Vec::new();
        use std::io::Read;
        let mut dec = flate2::read::MultiGzDecoder::new(&raw[..]);
        if let Err(e) = dec.by_ref().take(540).read_to_end(&mut head) {
            return Err(VolumeError::format(
                path,
                "gzip",
                format!("broken gzip stream: {e}"),
            ));
        }
        head
    } else {
        raw[..raw.len().min(540)].to_vec()
    };
    let h = parse_header(path, &head)?;
    let ty = datatype(path, h.datatype)?;
    let ndim = h.dim[0];
    if !(1..=7).contains(&ndim) {
        return Err(VolumeError::format(
            path,
            "dim[0]",
            format!("{ndim} is not in 1..7"),
        ));
    }
    let nd = ndim as usize;
    let mut d = [1i64; 7];
    for (i, di) in d.iter_mut().enumerate().take(nd) {
        *di = h.dim[i + 1];
        if *di < 1 {
            return Err(VolumeError::format(
                path,
                format!("dim[{}]", i + 1),
                format!("{di} is not positive"),
            ));
        }
    }
    // Components and frames: 3-D scalar, 4-D with dim4 == 3 (or 1), 5-D VECTOR with dim5 == 3
    // and dim4 frames (1: steady).
    let extra: Vec<i64> = d[3..].to_vec();
    let (components, frames) = match extra.as_slice() {
        [1, 1, 1, 1] => (1, 1),
        [3, 1, 1, 1] => (3, 1),
        [t, 3, 1, 1] if h.intent_code == INTENT_VECTOR => (3, *t as usize),
        _ => {
            return Err(VolumeError::format(
                path,
                "dim",
                format!(
                    "{}-D image with dims {:?}: only 3-D scalars, 4-D with 3 components and 5-D VECTOR \
                     (dim[5] = 3; dim[4] = 1, or the number of time frames) are volumes umbra reads",
                    ndim,
                    &d[..nd]
                ),
            ))
        }
    };
    let dt = h.pixdim[4];
    if frames > 1 && !(dt.is_finite() && dt > 0.0) {
        return Err(VolumeError::format(
            path,
            "pixdim[4]",
            format!("{dt} is not a positive time step, and dim[4] = {frames} time frames need one"),
        ));
    }
    let t0 = if h.toffset.is_finite() {
        h.toffset
    } else {
        0.0
    };
    let count = checked_count(path, "dim", &d[..3])?;
    let total = count
        .checked_mul(components)
        .and_then(|n| n.checked_mul(frames))
        .filter(|&n| n as u64 <= io_util::MAX_SAMPLES)
        .ok_or_else(|| {
            VolumeError::format(
                path,
                "dim",
                format!(
                    "{} x {} x {} voxels x {components} components x {frames} frames give more \
                     than {} samples",
                    d[0],
                    d[1],
                    d[2],
                    io_util::MAX_SAMPLES
                ),
            )
        })?;
    let nbytes = total * ty.size();
    let hdr_size = if h.version == 1 { 348 } else { 540 };
    let single = h.magic[1] == b'+';
    let (data_bytes, data_field): (Vec<u8>, String) = if single {
        let off = h.vox_offset;
        if !off.is_finite() || off < hdr_size as f64 || off > u32::MAX as f64 {
            return Err(VolumeError::format(
                path,
                "vox_offset",
                format!("{off} is not a valid data offset (at least {hdr_size})"),
            ));
        }
        let off = off as usize;
        let mut all = if gz {
            let all = io_util::gunzip(path, "gzip data", &raw, Some(off + nbytes))?;
            drop(raw);
            all
        } else {
            raw
        };
        if all.len() < off + nbytes {
            return Err(VolumeError::format(
                path,
                "data",
                format!(
                    "file holds {} bytes after vox_offset {off}, dims {:?} x {} need {nbytes}",
                    all.len().saturating_sub(off),
                    &d[..nd],
                    ty.name()
                ),
            ));
        }
        if all.len() > off + nbytes {
            return Err(VolumeError::format(
                path,
                "data",
                format!(
                    "file has {} bytes after the image data that the header's dims {:?} do not account for",
                    all.len() - off - nbytes,
                    &d[..nd]
                ),
            ));
        }
        // The header's bytes removed in place (no second copy of the image).
        all.drain(..off);
        (all, "data".into())
    } else {
        let img = pair_image(path)?;
        let ibytes = io_util::read_file(&img)?;
        let ibytes = if ibytes.starts_with(&[0x1f, 0x8b]) {
            io_util::gunzip(&img, "gzip data", &ibytes, Some(nbytes))?
        } else {
            ibytes
        };
        (ibytes, format!("image file {}", img.display()))
    };
    let slope = h.scl_slope;
    let inter = if h.scl_inter.is_finite() {
        h.scl_inter
    } else {
        0.0
    };
    let scaled = slope.is_finite() && slope != 0.0 && (slope != 1.0 || inter != 0.0);
    let stored = match keep_stored && components == 1 && frames == 1 && !scaled {
        true => io_util::take_stored(path, &data_field, &data_bytes, total, ty, h.big_endian)?,
        false => None,
    };
    let mut data = match stored {
        Some(_) => Vec::new(),
        None => take_samples(
            path,
            &data_field,
            &data_bytes,
            total,
            ty,
            h.big_endian,
            false,
        )?,
    };
    drop(data_bytes);
    if scaled {
        for v in &mut data {
            *v = (*v as f64 * slope + inter) as f32;
        }
    }
    let dims = [d[0] as usize, d[1] as usize, d[2] as usize];
    let (affine, space) = affine_of(path, &h, dims)?;
    let to_world = vector_to_world(&affine);
    let frame = |data: Vec<f32>| Volume {
        format: format!("nifti{}", h.version),
        dims,
        affine,
        space,
        fields: vec![Field {
            name: "data".into(),
            components,
            stored: ty,
            data,
        }],
        default_field: 0,
        warnings: pixdim_warnings(&h),
    };
    let volumes = if components == 3 {
        // Component blocks (each of `frames` planes) follow each other; interleave the
        // components per voxel, frame by frame.
        (0..frames)
            .map(|t| {
                let mut inter_data = vec![0f32; 3 * count];
                for c in 0..3 {
                    let at = (c * frames + t) * count;
                    for (i, &v) in data[at..at + count].iter().enumerate() {
                        inter_data[3 * i + c] = v;
                    }
                }
                transform_vectors(&mut inter_data, to_world);
                frame(inter_data)
            })
            .collect()
    } else {
        vec![frame(std::mem::take(&mut data))]
    };
    let periodic = frames > 1
        && h.descrip
            .split(|c: char| !c.is_ascii_alphanumeric() && c != '-')
            .any(|w| w.eq_ignore_ascii_case("periodic") || w.eq_ignore_ascii_case("time-periodic"));
    let series = VolumeSeries {
        frames: volumes,
        t0,
        dt: if frames > 1 { dt } else { 1.0 },
        periodic,
        warnings: vec![],
    };
    Ok((series, stored))
}

fn pair_image(path: &Path) -> Result<PathBuf> {
    pair_partners(path, "hdr", "img")
        .into_iter()
        .find(|p| p.exists())
        .ok_or_else(|| {
            VolumeError::format(
                path,
                "magic",
                "'ni1' header (separate image file) but no matching .img file",
            )
        })
}

/// The names the other file of a NIfTI pair may have: for `x.hdr` (`from` = "hdr", `to` =
/// "img") `x.img` and `x.img.gz`, the gzipped one first when the given file is gzipped. The
/// suffixes are matched in any case (`X.HDR`), and the partner is looked for in the case of
/// the given suffix first (`X.IMG`, `X.IMG.GZ`, `X.IMG.gz`), then in the other. Empty when the
/// name does not end in `.from` or `.from.gz`.
pub(crate) fn pair_partners(path: &Path, from: &str, to: &str) -> Vec<PathBuf> {
    let Some(name) = path.file_name().and_then(|n| n.to_str()) else {
        return Vec::new();
    };
    let lower = name.to_ascii_lowercase();
    let gz = lower.ends_with(&format!(".{from}.gz"));
    if !gz && !lower.ends_with(&format!(".{from}")) {
        return Vec::new();
    }
    // ASCII lower-casing keeps every byte where it is, and the suffix is ASCII.
    let stem_len = name.len() - from.len() - 1 - if gz { 3 } else { 0 };
    let (stem, suffix) = name.split_at(stem_len);
    let upper = suffix[1..].starts_with(|c: char| c.is_ascii_uppercase());
    let cases = if upper {
        [to.to_ascii_uppercase(), to.to_string()]
    } else {
        [to.to_string(), to.to_ascii_uppercase()]
    };
    let mut out = Vec::new();
    for ext in cases {
        let up = ext.starts_with(|c: char| c.is_ascii_uppercase());
        let plain = format!("{stem}.{ext}");
        let zipped = [
            format!("{plain}.{}", if up { "GZ" } else { "gz" }),
            format!("{plain}.gz"),
        ];
        let mut names = vec![plain.clone()];
        for z in zipped {
            if !names.contains(&z) {
                names.push(z);
            }
        }
        if gz {
            names.rotate_left(1);
        }
        out.extend(names.into_iter().map(|n| path.with_file_name(n)));
    }
    out
}

/// Decomposes an affine into NIfTI qform parameters (quaternion b, c, d, qfac, zooms), as
/// nibabel's `set_qform` does; `None` when the 3x3 part has shear.
fn qform_params(m: &DMat4) -> Option<([f64; 3], f64, [f64; 3])> {
    let m3 = DMat3::from_mat4(*m);
    let zooms = [m3.x_axis.length(), m3.y_axis.length(), m3.z_axis.length()];
    if zooms.iter().any(|&z| z <= 0.0) {
        return None;
    }
    let mut r = DMat3::from_cols(
        m3.x_axis / zooms[0],
        m3.y_axis / zooms[1],
        m3.z_axis / zooms[2],
    );
    let ortho = (r.transpose() * r - DMat3::IDENTITY)
        .to_cols_array()
        .iter()
        .all(|v| v.abs() < 1e-6);
    if !ortho {
        return None;
    }
    let mut qfac = 1.0;
    if r.determinant() < 0.0 {
        qfac = -1.0;
        r.z_axis = -r.z_axis;
    }
    let mut q = DQuat::from_mat3(&r).normalize();
    if q.w < 0.0 {
        q = -q;
    }
    Some(([q.x, q.y, q.z], qfac, zooms))
}

/// Writes `field` of `vol` as a NIfTI-1 single file (`.nii`, or gzip-compressed when the path
/// ends in `.gz`). The stored type is kept where every value fits it, else float32. Vector
/// fields are written as 5-D with intent VECTOR, components in FSL's voxel frame.
pub fn write(path: &Path, vol: &Volume, field: &Field) -> Result<()> {
    if field.components != 1 && field.components != 3 {
        return Err(VolumeError::Invalid(format!(
            "{}: field '{}' has {} components; NIfTI output takes 1 or 3",
            path.display(),
            field.name,
            field.components
        )));
    }
    write_frames(path, vol, &[field], None)
}

/// Writes a time series of vector fields as one NIfTI-1 file (`.nii`, `.nii.gz`): a 5-D image
/// `(nx, ny, nz, T, 3)` with intent VECTOR, float32, `pixdim[4]` the time step, `toffset` the
/// first time, `xyzt_units` millimetres and seconds, and `descrip` `umbra time-periodic` for a
/// periodic series (what [`read_series`] reads back). The field written is each frame's
/// default field, which must have 3 components. A series of one frame is written as [`write()`]
/// writes a steady vector field.
pub fn write_series(path: &Path, s: &VolumeSeries) -> Result<()> {
    s.validate()
        .map_err(|e| VolumeError::Invalid(format!("{}: {e}", path.display())))?;
    let fields: Vec<&Field> = s.frames.iter().map(|v| v.default()).collect();
    if fields[0].components != 3 {
        return Err(VolumeError::Invalid(format!(
            "{}: field '{}' has {} components; a NIfTI time series holds 3-component vector fields",
            path.display(),
            fields[0].name,
            fields[0].components
        )));
    }
    if fields.len() > i16::MAX as usize {
        return Err(VolumeError::Invalid(format!(
            "{}: {} time frames exceed NIfTI-1's limit of 32767",
            path.display(),
            fields.len()
        )));
    }
    let time = (fields.len() > 1).then_some(TimeAxis {
        t0: s.t0,
        dt: s.dt,
        periodic: s.periodic,
    });
    write_frames(path, &s.frames[0], &fields, time)
}

/// The time axis of a series being written.
struct TimeAxis {
    t0: f64,
    dt: f64,
    periodic: bool,
}

/// Writes one scalar or vector field (`fields.len() == 1`) or a time series of vector fields
/// on `vol`'s grid.
fn write_frames(
    path: &Path,
    vol: &Volume,
    fields: &[&Field],
    time: Option<TimeAxis>,
) -> Result<()> {
    let field = fields[0];
    for (i, &d) in vol.dims.iter().enumerate() {
        if d > i16::MAX as usize {
            return Err(VolumeError::Invalid(format!(
                "{}: dim {i} = {d} exceeds NIfTI-1's limit of 32767",
                path.display()
            )));
        }
    }
    let ty = if field.stored.holds_all(&field.data) {
        field.stored
    } else {
        ScalarType::F32
    };
    let mut h = vec![0u8; 352];
    let put_i16 = |h: &mut Vec<u8>, o: usize, v: i16| h[o..o + 2].copy_from_slice(&v.to_le_bytes());
    let put_f32 =
        |h: &mut Vec<u8>, o: usize, v: f64| h[o..o + 4].copy_from_slice(&(v as f32).to_le_bytes());
    h[0..4].copy_from_slice(&348i32.to_le_bytes());
    h[38] = b'r';
    let dims: Vec<i16> = if field.components == 3 {
        vec![
            5,
            vol.dims[0] as i16,
            vol.dims[1] as i16,
            vol.dims[2] as i16,
            fields.len() as i16,
            3,
            1,
            1,
        ]
    } else {
        vec![
            3,
            vol.dims[0] as i16,
            vol.dims[1] as i16,
            vol.dims[2] as i16,
            1,
            1,
            1,
            1,
        ]
    };
    for (i, d) in dims.iter().enumerate() {
        put_i16(&mut h, 40 + 2 * i, *d);
    }
    if field.components == 3 {
        put_i16(&mut h, 68, INTENT_VECTOR as i16);
    }
    put_i16(&mut h, 70, datatype_code(ty));
    put_i16(&mut h, 72, (ty.size() * 8) as i16);
    let sp = vol.spacing();
    let q = qform_params(&vol.affine);
    let qfac = q.map(|q| q.1).unwrap_or(1.0);
    let dt = time.as_ref().map_or(1.0, |t| t.dt);
    let pix = [qfac, sp[0], sp[1], sp[2], dt, 1.0, 1.0, 1.0];
    for (i, p) in pix.iter().enumerate() {
        put_f32(&mut h, 76 + 4 * i, *p);
    }
    put_f32(&mut h, 108, 352.0);
    put_f32(&mut h, 112, 1.0);
    put_f32(&mut h, 116, 0.0);
    // xyzt_units: millimetres, and seconds for a time series.
    h[123] = if time.is_some() { 2 | 8 } else { 2 };
    if let Some(t) = &time {
        put_f32(&mut h, 136, t.t0);
    }
    let descrip: &[u8] = match &time {
        Some(t) if t.periodic => b"umbra time-periodic",
        _ => b"umbra",
    };
    h[148..148 + descrip.len()].copy_from_slice(descrip);
    // sform: exact affine (code 2 = aligned anatomical; code 1 = scanner for file frames).
    let code: i16 = if vol.space == Space::Ras { 2 } else { 1 };
    put_i16(&mut h, 254, code);
    let a = vol.affine;
    for row in 0..3 {
        for col in 0..4 {
            put_f32(&mut h, 280 + 16 * row + 4 * col, a.col(col)[row]);
        }
    }
    if let Some((quat, _, _)) = q {
        put_i16(&mut h, 252, code);
        for (i, q) in quat.iter().enumerate() {
            put_f32(&mut h, 256 + 4 * i, *q);
        }
        let t = a.w_axis;
        put_f32(&mut h, 268, t.x);
        put_f32(&mut h, 272, t.y);
        put_f32(&mut h, 276, t.z);
    }
    h[344..348].copy_from_slice(b"n+1\0");
    // Data: planes per component, each a block of frames.
    let n = vol.voxel_count();
    let planar: Vec<f32> = if field.components == 3 {
        let inv = vector_to_world(&vol.affine).inverse();
        let frames = fields.len();
        let mut out = vec![0f32; 3 * n * frames];
        for (t, f) in fields.iter().enumerate() {
            for (i, v) in f.data.chunks_exact(3).enumerate() {
                let w = if v.iter().all(|x| x.is_finite()) {
                    let w = inv * DVec3::new(v[0] as f64, v[1] as f64, v[2] as f64);
                    [w.x as f32, w.y as f32, w.z as f32]
                } else {
                    [v[0], v[1], v[2]]
                };
                for c in 0..3 {
                    out[(c * frames + t) * n + i] = w[c];
                }
            }
        }
        out
    } else {
        field.data.clone()
    };
    let ty = if field.components == 3 {
        ScalarType::F32
    } else {
        ty
    };
    if field.components == 3 {
        put_i16(&mut h, 70, datatype_code(ty));
        put_i16(&mut h, 72, 32);
    }
    h.extend_from_slice(&io_util::encode_samples(&planar, ty, false));
    let gz = path.to_string_lossy().to_ascii_lowercase().ends_with(".gz");
    let bytes = if gz { io_util::gzip_bytes(&h) } else { h };
    io_util::write_atomic(path, &bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pair_partners_in_the_given_case_first() {
        let names = |p: &str, from, to| -> Vec<String> {
            pair_partners(Path::new(p), from, to)
                .iter()
                .map(|p| p.to_string_lossy().into_owned())
                .collect()
        };
        assert_eq!(
            names("d/x.hdr", "hdr", "img"),
            [
                "d/x.img",
                "d/x.img.gz",
                "d/x.IMG",
                "d/x.IMG.GZ",
                "d/x.IMG.gz"
            ]
        );
        assert_eq!(
            names("d/X.HDR.GZ", "hdr", "img"),
            [
                "d/X.IMG.GZ",
                "d/X.IMG.gz",
                "d/X.IMG",
                "d/X.img.gz",
                "d/X.img"
            ]
        );
        assert_eq!(names("ü.Img", "img", "hdr")[0], "ü.HDR");
        assert!(names("x.nii", "hdr", "img").is_empty());
        assert!(names("hdr", "hdr", "img").is_empty());
    }
}
