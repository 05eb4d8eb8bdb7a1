//! TrackVis `.trk` reader and writer (versions 1 and 2, either byte order, plain or gzip).
//!
//! nibabel (`nibabel.streamlines.trk`) is the reference behaviour:
//! * byte order from `hdr_size` (1000 as stored or byte-swapped), magic `TRACK`, version 1 or 2
//!   (`vox_to_ras` is read only from version 2; when it is all zeros it is the identity, with a
//!   warning), at most 10 scalars and 10 properties, names of up to 20 bytes where `name\0N`
//!   declares `N` values under one name;
//! * points are stored in "voxmm" (voxel coordinates times voxel size, origin at the corner of
//!   the first voxel) and converted to RAS+ mm exactly as nibabel does: divide by the voxel
//!   sizes, subtract half a voxel, re-orient from the header's `voxel_order` (empty means LPS,
//!   with a warning; lower case is accepted) to the orientation of `vox_to_ras` (nibabel's
//!   `ornt_transform` and `inv_ornt_aff`, which flip an axis as `i -> dim - 1 - i`), then apply
//!   `vox_to_ras`;
//! * `n_count` 0 means "not recorded"; a count that disagrees with the data gives a warning and
//!   the data win. No allocation is sized by a header field: every streamline's size is checked
//!   against the bytes left before it is read.

use crate::error::{read_maybe_gz, write_atomic, Result, TubesError};
use crate::{Attribute, ReferenceSpace, Streamlines};
use glam::{DMat3, DMat4, DVec3, DVec4};
use std::path::Path;

const HDR: usize = 1000;

/// Axis codes (R/L, A/P, S/I) of a 3x3 orientation: for each voxel axis the world axis it runs
/// along most and its direction (nibabel's `aff2axcodes` for affines without strong shear).
pub(crate) fn axcodes(m: &DMat3) -> [(usize, i32); 3] {
    let mut out = [(0, 1); 3];
    let mut used = [false; 3];
    // Assign the strongest components first so that two voxel axes never share a world axis.
    let mut cand: Vec<(f64, usize, usize)> = Vec::new();
    for c in 0..3 {
        for r in 0..3 {
            cand.push((m.col(c)[r].abs(), c, r));
        }
    }
    cand.sort_by(|a, b| b.0.total_cmp(&a.0));
    let mut done = [false; 3];
    for (_, c, r) in cand {
        if done[c] || used[r] {
            continue;
        }
        out[c] = (r, if m.col(c)[r] >= 0.0 { 1 } else { -1 });
        done[c] = true;
        used[r] = true;
    }
    out
}

fn code_to_ornt(path: &Path, code: &[u8; 3]) -> Result<[(usize, i32); 3]> {
    let mut o = [(0usize, 1i32); 3];
    let mut seen = [false; 3];
    for (i, &c) in code.iter().enumerate() {
        let (axis, dir) = match c.to_ascii_uppercase() {
            b'R' => (0, 1),
            b'L' => (0, -1),
            b'A' => (1, 1),
            b'P' => (1, -1),
            b'S' => (2, 1),
            b'I' => (2, -1),
            _ => {
                return Err(TubesError::format(
                    path,
                    "voxel_order",
                    format!(
                        "{:?} is not three of R/L, A/P, S/I",
                        String::from_utf8_lossy(code)
                    ),
                ));
            }
        };
        if seen[axis] {
            return Err(TubesError::format(
                path,
                "voxel_order",
                format!("{:?} names an axis twice", String::from_utf8_lossy(code)),
            ));
        }
        seen[axis] = true;
        o[i] = (axis, dir);
    }
    Ok(o)
}

/// nibabel's `inv_ornt_aff(ornt_transform(start, end), shape)`.
fn reorient(start: [(usize, i32); 3], end: [(usize, i32); 3], shape: [f64; 3]) -> DMat4 {
    // ornt_transform: for each start axis, the end axis with the same world axis, and a flip.
    let mut ornt = [(0usize, 1.0f64); 3];
    for (end_in, &(end_out, end_flip)) in end.iter().enumerate() {
        for (start_in, &(start_out, start_flip)) in start.iter().enumerate() {
            if end_out == start_out {
                ornt[start_in] = (end_in, if start_flip == end_flip { 1.0 } else { -1.0 });
                break;
            }
        }
    }
    // inv_ornt_aff: undo_flip . undo_reorder, rows of the identity taken in ornt[:, 0] order.
    let mut undo_reorder = [[0.0f64; 4]; 4];
    for (row, &(axis, _)) in ornt.iter().enumerate() {
        undo_reorder[row][axis] = 1.0;
    }
    undo_reorder[3][3] = 1.0;
    let mut undo_flip = [[0.0f64; 4]; 4];
    for (i, &(_, flip)) in ornt.iter().enumerate() {
        undo_flip[i][i] = flip;
        let center = -(shape[i] - 1.0) / 2.0;
        undo_flip[i][3] = flip * center - center;
    }
    undo_flip[3][3] = 1.0;
    let to_mat = |m: [[f64; 4]; 4]| {
        DMat4::from_cols_array_2d(&[
            [m[0][0], m[1][0], m[2][0], m[3][0]],
            [m[0][1], m[1][1], m[2][1], m[3][1]],
            [m[0][2], m[1][2], m[2][2], m[3][2]],
            [m[0][3], m[1][3], m[2][3], m[3][3]],
        ])
    };
    to_mat(undo_flip) * to_mat(undo_reorder)
}

/// The affine from TrackVis voxmm to RAS+ mm for a reference space (nibabel's
/// `get_affine_trackvis_to_rasmm`).
pub fn voxmm_to_rasmm(path: &Path, r: &ReferenceSpace) -> Result<DMat4> {
    let scale = DMat4::from_scale(DVec3::new(
        1.0 / r.voxel_sizes[0],
        1.0 / r.voxel_sizes[1],
        1.0 / r.voxel_sizes[2],
    ));
    let offset = DMat4::from_translation(DVec3::splat(-0.5));
    let header_ornt = code_to_ornt(path, &r.voxel_order)?;
    let affine_ornt = axcodes(&DMat3::from_mat4(r.vox_to_ras));
    let shape = [r.dims[0] as f64, r.dims[1] as f64, r.dims[2] as f64];
    let m = reorient(header_ornt, affine_ornt, shape);
    Ok(r.vox_to_ras * m * offset * scale)
}

fn name_field(b: &[u8]) -> (String, usize) {
    let end = b.iter().position(|&c| c == 0).unwrap_or(b.len());
    let name = String::from_utf8_lossy(&b[..end]).trim().to_string();
    // nibabel encodes "name\0N" for N values under one name.
    let rest = &b[(end + 1).min(b.len())..];
    let digits: String = rest
        .iter()
        .take_while(|c| c.is_ascii_digit())
        .map(|&c| c as char)
        .collect();
    let count = digits.parse::<usize>().ok().filter(|&n| n > 0).unwrap_or(1);
    (name, count)
}

/// Splits `n` values per point (or streamline) into named attributes.
fn names(
    path: &Path,
    hdr: &volume::Bytes,
    at: usize,
    n: usize,
    field: &str,
) -> Result<Vec<(String, usize)>> {
    let mut out = Vec::new();
    let mut total = 0;
    for i in 0..10 {
        let (name, count) = name_field(&hdr.b[at + 20 * i..at + 20 * (i + 1)]);
        if name.is_empty() || total >= n {
            break;
        }
        out.push((name, count));
        total += count;
    }
    if total != n {
        // Names missing or inconsistent: one unnamed attribute per value.
        if !out.is_empty() && total > n {
            return Err(TubesError::format(
                path,
                field,
                format!("names declare {total} values, the header says {n}"),
            ));
        }
        out = (0..n)
            .map(|i| (format!("{}_{i}", field.trim_end_matches("_name")), 1))
            .collect();
    }
    Ok(out)
}

/// Reads a `.trk` or `.trk.gz` file into RAS+ mm.
pub fn read(path: &Path) -> Result<Streamlines> {
    let bytes = read_maybe_gz(path, b"TRACK", "TrackVis")?;
    if bytes.len() < HDR {
        return Err(TubesError::format(
            path,
            "header",
            format!(
                "file has {} bytes, the TrackVis header needs {HDR}",
                bytes.len()
            ),
        ));
    }
    if &bytes[0..5] != b"TRACK" {
        return Err(TubesError::format(
            path,
            "id_string",
            format!("{:?} is not 'TRACK'", String::from_utf8_lossy(&bytes[0..5])),
        ));
    }
    let le = i32::from_le_bytes(bytes[996..1000].try_into().unwrap());
    let be = i32::from_be_bytes(bytes[996..1000].try_into().unwrap());
    let big = match (le, be) {
        (1000, _) => false,
        (_, 1000) => true,
        _ => {
            return Err(TubesError::format(
                path,
                "hdr_size",
                format!("{le} is not 1000 in either byte order"),
            ))
        }
    };
    let h = volume::Bytes {
        b: &bytes,
        big_endian: big,
    };
    let mut warnings = Vec::new();
    let mut version = h.i32(992);
    if version == 3 {
        // TrackVis 3 files have the version 2 header; nibabel reads them as version 2.
        warnings.push("version 3 read as version 2 (the same header, as nibabel reads it)".into());
        version = 2;
    }
    if version != 1 && version != 2 {
        return Err(TubesError::format(
            path,
            "version",
            format!("{version} is not 1, 2 or 3"),
        ));
    }
    let dims = [h.i16(6), h.i16(8), h.i16(10)];
    let voxel_sizes = [h.f32(12) as f64, h.f32(16) as f64, h.f32(20) as f64];
    if voxel_sizes
        .iter()
        .any(|v| !(volume::MIN_SPACING..=volume::MAX_SPACING).contains(v))
    {
        return Err(TubesError::format(
            path,
            "voxel_size",
            format!(
                "{voxel_sizes:?} must be positive, from {:e} to {:e} mm",
                volume::MIN_SPACING,
                volume::MAX_SPACING
            ),
        ));
    }
    let n_scalars = h.i16(36);
    let n_props = h.i16(238);
    if !(0..=10).contains(&n_scalars) || !(0..=10).contains(&n_props) {
        return Err(TubesError::format(
            path,
            "n_scalars/n_properties",
            format!("{n_scalars} scalars and {n_props} properties: TrackVis allows 0 to 10 each"),
        ));
    }
    let (ns, np) = (n_scalars as usize, n_props as usize);
    let scalar_names = names(path, &h, 38, ns, "scalar_name")?;
    let prop_names = names(path, &h, 240, np, "property_name")?;
    let mut vox_to_ras = DMat4::ZERO;
    if version == 2 {
        let mut rows = [[0.0f64; 4]; 4];
        for (r, row) in rows.iter_mut().enumerate() {
            for (c, v) in row.iter_mut().enumerate() {
                *v = h.f32(440 + 16 * r + 4 * c) as f64;
            }
        }
        vox_to_ras = DMat4::from_cols_array_2d(&[
            [rows[0][0], rows[1][0], rows[2][0], rows[3][0]],
            [rows[0][1], rows[1][1], rows[2][1], rows[3][1]],
            [rows[0][2], rows[1][2], rows[2][2], rows[3][2]],
            [rows[0][3], rows[1][3], rows[2][3], rows[3][3]],
        ]);
    }
    if vox_to_ras.w_axis.w == 0.0 {
        if version == 2 {
            warnings
                .push("vox_to_ras was not recorded (all zeros); assuming the identity".to_string());
        }
        vox_to_ras = DMat4::IDENTITY;
    }
    // Singular by shape, not by size: voxels of 1e-7 (a micro-scale field traced by `umbra
    // trace`) give a determinant of 1e-21 and are as regular as millimetres.
    if !vox_to_ras.to_cols_array().iter().all(|v| v.is_finite())
        || volume::degenerate_axes(DMat3::from_mat4(vox_to_ras))
    {
        return Err(TubesError::format(
            path,
            "vox_to_ras",
            "singular or non-finite",
        ));
    }
    let mut order = [bytes[948], bytes[949], bytes[950]];
    if order == [0, 0, 0] {
        warnings.push("voxel_order is empty; assuming LPS (TrackVis's default)".to_string());
        order = *b"LPS";
    }
    let reference = ReferenceSpace {
        dims: [
            dims[0].max(1) as usize,
            dims[1].max(1) as usize,
            dims[2].max(1) as usize,
        ],
        voxel_sizes,
        vox_to_ras,
        voxel_order: order.map(|c| c.to_ascii_uppercase()),
    };
    let to_ras = voxmm_to_rasmm(path, &reference)?;
    let n_count = h.i32(988);
    // Streamlines.
    let mut s = Streamlines::new();
    let mut point_vals: Vec<f32> = Vec::new();
    let mut line_vals: Vec<f32> = Vec::new();
    let mut pos = HDR;
    let rd = |o: usize| h.f32(o);
    while pos < bytes.len() {
        if pos + 4 > bytes.len() {
            return Err(TubesError::format(
                path,
                format!("streamline {}", s.len()),
                "file ends inside the point count",
            ));
        }
        let n = h.i32(pos);
        pos += 4;
        let per = 3 + ns;
        let need = (n as i64) * per as i64 * 4 + np as i64 * 4;
        if n < 0 || need > (bytes.len() - pos) as i64 {
            return Err(TubesError::format(
                path,
                format!("streamline {}", s.len()),
                format!(
                    "claims {n} points ({need} bytes), {} bytes remain",
                    bytes.len() - pos
                ),
            ));
        }
        let start = s.points.len();
        for p in 0..n as usize {
            let o = pos + p * per * 4;
            let v = DVec3::new(rd(o) as f64, rd(o + 4) as f64, rd(o + 8) as f64);
            let w = (to_ras * DVec4::from((v, 1.0))).truncate();
            let q = w.as_vec3();
            if v.is_finite() && !q.is_finite() {
                // The header's frame, not the data, made the point infinite.
                return Err(TubesError::format(
                    path,
                    "voxel_size/vox_to_ras",
                    format!(
                        "streamline {} point {p}: the header's transform maps ({}, {}, {}) to \
                         a position outside f32's range",
                        s.len(),
                        v.x,
                        v.y,
                        v.z
                    ),
                ));
            }
            s.points.push(q);
            for k in 0..ns {
                point_vals.push(rd(o + 12 + 4 * k));
            }
        }
        pos += n as usize * per * 4;
        for k in 0..np {
            line_vals.push(rd(pos + 4 * k));
        }
        pos += np * 4;
        s.offsets.push(start + n as usize);
    }
    if n_count != 0 && n_count as usize != s.len() {
        warnings.push(format!(
            "header count {n_count} disagrees with the {} streamlines in the data; using the data",
            s.len()
        ));
    }
    // Split attribute columns by name.
    let split = |vals: &[f32], per: usize, groups: &[(String, usize)]| -> Vec<Attribute> {
        let mut col = 0;
        groups
            .iter()
            .map(|(name, count)| {
                let values = vals
                    .chunks_exact(per.max(1))
                    .flat_map(|row| row[col..col + count].to_vec())
                    .collect();
                col += count;
                Attribute {
                    name: name.clone(),
                    components: *count,
                    values,
                }
            })
            .collect()
    };
    s.point_attributes = split(&point_vals, ns, &scalar_names);
    s.line_attributes = split(&line_vals, np, &prop_names);
    s.reference = Some(reference);
    s.warnings = warnings;
    s.format = "trk".into();
    Ok(s)
}

/// The reference space written when a tractogram has none: 1 mm voxels, RAS, and a `vox_to_ras`
/// that cancels nibabel's half-voxel shift, so that voxmm coordinates equal RAS+ mm exactly and
/// a round trip is bit-exact.
pub fn identity_space() -> ReferenceSpace {
    ReferenceSpace {
        dims: [1, 1, 1],
        voxel_sizes: [1.0; 3],
        vox_to_ras: DMat4::from_translation(DVec3::splat(0.5)),
        voxel_order: *b"RAS",
    }
}

/// The reference space of a volume's grid (`dims` samples, `affine` from voxel centres to RAS+
/// mm): its voxel sizes (the affine's column lengths), the affine as `vox_to_ras` and the
/// voxel order it implies, as TrackVis tools (and nibabel) read a tractogram's grid. `None`
/// where the grid does not fit a header (an axis of more than 32,767 samples, a degenerate
/// axis).
pub fn grid_space(dims: [usize; 3], affine: DMat4) -> Option<ReferenceSpace> {
    let m = DMat3::from_mat4(affine);
    let sizes = [m.x_axis.length(), m.y_axis.length(), m.z_axis.length()];
    if dims.iter().any(|&d| d == 0 || d > i16::MAX as usize)
        || sizes.iter().any(|v| !(v.is_finite() && *v > 0.0))
    {
        return None;
    }
    let voxel_order = voxel_order(&m);
    Some(ReferenceSpace {
        dims,
        voxel_sizes: sizes,
        vox_to_ras: affine,
        voxel_order,
    })
}

/// The voxel order (`b"LPS"`, ...) that a grid's voxel-to-RAS+ matrix `m` implies: each voxel
/// axis's nearest world axis and its direction, as nibabel's `aff2axcodes`.
pub(crate) fn voxel_order(m: &DMat3) -> [u8; 3] {
    let letters = [[b'L', b'R'], [b'P', b'A'], [b'I', b'S']];
    axcodes(m).map(|(axis, dir)| letters[axis][usize::from(dir > 0)])
}

fn put_name(h: &mut [u8], at: usize, name: &str, count: usize) {
    let mut field = name.as_bytes().to_vec();
    if count > 1 {
        field.push(0);
        field.extend_from_slice(count.to_string().as_bytes());
    }
    field.truncate(20);
    h[at..at + field.len()].copy_from_slice(&field);
}

/// Writes a TrackVis v2 file (little endian; gzip when the name ends in `.gz`) in the
/// tractogram's reference space, or [`identity_space`].
pub fn write(path: &Path, s: &Streamlines) -> Result<()> {
    s.validate()
        .map_err(|e| TubesError::Invalid(format!("{}: {e}", path.display())))?;
    // An empty tractogram declares no attributes: with none of their values in the file,
    // nibabel cannot read the names back (it indexes the missing values).
    let empty = s.is_empty();
    let (point_attributes, line_attributes) = if empty {
        (&[][..], &[][..])
    } else {
        (&s.point_attributes[..], &s.line_attributes[..])
    };
    let ns: usize = point_attributes.iter().map(|a| a.components).sum();
    let np: usize = line_attributes.iter().map(|a| a.components).sum();
    if ns > 10
        || np > 10
        || point_attributes
            .iter()
            .chain(line_attributes)
            .any(|a| a.name.len() > 17)
    {
        return Err(TubesError::Invalid(format!(
            "{}: TrackVis holds at most 10 scalar and 10 property values, names up to 17 bytes",
            path.display()
        )));
    }
    let r = s.reference.clone().unwrap_or_else(identity_space);
    let from_ras = voxmm_to_rasmm(path, &r)?.inverse();
    let mut h = vec![0u8; HDR];
    h[0..6].copy_from_slice(b"TRACK\0");
    for (i, d) in r.dims.iter().enumerate() {
        h[6 + 2 * i..8 + 2 * i].copy_from_slice(&(*d as i16).to_le_bytes());
    }
    for (i, v) in r.voxel_sizes.iter().enumerate() {
        h[12 + 4 * i..16 + 4 * i].copy_from_slice(&(*v as f32).to_le_bytes());
    }
    h[36..38].copy_from_slice(&(ns as i16).to_le_bytes());
    let mut at = 38;
    for a in point_attributes {
        put_name(&mut h, at, &a.name, a.components);
        at += 20;
    }
    h[238..240].copy_from_slice(&(np as i16).to_le_bytes());
    let mut at = 240;
    for a in line_attributes {
        put_name(&mut h, at, &a.name, a.components);
        at += 20;
    }
    for rr in 0..4 {
        for c in 0..4 {
            h[440 + 16 * rr + 4 * c..444 + 16 * rr + 4 * c]
                .copy_from_slice(&(r.vox_to_ras.col(c)[rr] as f32).to_le_bytes());
        }
    }
    h[948..951].copy_from_slice(&r.voxel_order);
    h[988..992].copy_from_slice(&(s.len() as i32).to_le_bytes());
    h[992..996].copy_from_slice(&2i32.to_le_bytes());
    h[996..1000].copy_from_slice(&1000i32.to_le_bytes());
    let mut out = h;
    for i in 0..s.len() {
        let (a, b) = (s.offsets[i], s.offsets[i + 1]);
        out.extend_from_slice(&((b - a) as i32).to_le_bytes());
        for p in a..b {
            let w = s.points[p].as_dvec3();
            let v = (from_ras * DVec4::from((w, 1.0))).truncate();
            for x in [v.x, v.y, v.z] {
                out.extend_from_slice(&(x as f32).to_le_bytes());
            }
            for attr in &s.point_attributes {
                for k in 0..attr.components {
                    out.extend_from_slice(&attr.values[p * attr.components + k].to_le_bytes());
                }
            }
        }
        for attr in &s.line_attributes {
            for k in 0..attr.components {
                out.extend_from_slice(&attr.values[i * attr.components + k].to_le_bytes());
            }
        }
    }
    write_atomic(path, out)
}
