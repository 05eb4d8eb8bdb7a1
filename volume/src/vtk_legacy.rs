//! VTK legacy (`.vtk`) STRUCTURED_POINTS reader, ASCII and BINARY (big-endian).
//!
//! Point-data attributes `SCALARS` (1 or 3 components; others are split per component),
//! `VECTORS`, `NORMALS`, `COLOR_SCALARS` and `FIELD` arrays all become named fields;
//! `LOOKUP_TABLE` blocks and `CELL_DATA` sections are skipped (cell data is not on the sample
//! grid), as are VTK 5 `METADATA` blocks. Geometry: `DIMENSIONS`, `SPACING` (or the old
//! `ASPECT_RATIO`), `ORIGIN`; the frame is the file's own (`space: file`).
//! Curvilinear, rectilinear and unstructured datasets are not regular volumes; they are refused
//! with an error that says so.

use crate::io_util::{self, checked_count, Cursor};
use crate::{Field, Result, ScalarType, Space, Volume, VolumeError};
use glam::{DMat4, DVec4};
use std::path::Path;

fn vtk_type(path: &Path, field: &str, t: &str) -> Result<ScalarType> {
    Ok(match t.to_ascii_lowercase().as_str() {
        "unsigned_char" => ScalarType::U8,
        "char" | "signed_char" => ScalarType::I8,
        "unsigned_short" => ScalarType::U16,
        "short" => ScalarType::I16,
        "unsigned_int" => ScalarType::U32,
        "int" | "vtkidtype" => ScalarType::I32,
        "unsigned_long" | "vtktypeuint64" => ScalarType::U64,
        "long" | "vtktypeint64" => ScalarType::I64,
        "float" => ScalarType::F32,
        "double" => ScalarType::F64,
        other => {
            return Err(VolumeError::format(
                path,
                field,
                format!("data type '{other}' is not supported"),
            ))
        }
    })
}

fn text<'a>(path: &Path, field: &str, b: Option<&'a [u8]>) -> Result<&'a str> {
    let b = b.ok_or_else(|| VolumeError::format(path, field, "file ends here"))?;
    std::str::from_utf8(b).map_err(|_| VolumeError::format(path, field, "not ASCII text"))
}

fn int(path: &Path, field: &str, b: Option<&[u8]>) -> Result<i64> {
    let s = text(path, field, b)?;
    s.parse()
        .map_err(|_| VolumeError::format(path, field, format!("'{s}' is not an integer")))
}

fn float(path: &Path, field: &str, b: Option<&[u8]>) -> Result<f64> {
    let s = text(path, field, b)?;
    s.parse::<f64>()
        .ok()
        .filter(|v| v.is_finite())
        .ok_or_else(|| VolumeError::format(path, field, format!("'{s}' is not a finite number")))
}

/// Reads `count` values of `ty` at the cursor (binary: big-endian bytes after the keyword
/// line; ASCII: tokens).
fn read_values(
    path: &Path,
    field: &str,
    cur: &mut Cursor,
    binary: bool,
    ty: ScalarType,
    count: usize,
) -> Result<Vec<f32>> {
    if binary {
        let need = count
            .checked_mul(ty.size())
            .ok_or_else(|| VolumeError::format(path, field, "size overflows"))?;
        let bytes = cur.take(need).ok_or_else(|| {
            VolumeError::format(
                path,
                field,
                format!(
                    "{} bytes remain, {count} x {} need {need}",
                    cur.rest().len(),
                    ty.name()
                ),
            )
        })?;
        // The line break after binary data is optional.
        if cur.rest().first() == Some(&b'\n') {
            cur.pos += 1;
        }
        Ok(io_util::decode_samples(bytes, ty, true))
    } else {
        let (v, used) = io_util::parse_ascii(path, field, cur.rest(), count)?;
        cur.pos += used;
        Ok(v)
    }
}

/// Reads a legacy `.vtk` STRUCTURED_POINTS file.
pub fn read(path: &Path) -> Result<Volume> {
    let raw = io_util::read_file(path)?;
    let mut cur = Cursor::new(&raw);
    let first = cur.line().unwrap_or_default();
    if !first.starts_with(b"# vtk DataFile") {
        return Err(VolumeError::format(
            path,
            "header",
            "first line is not '# vtk DataFile Version x.y'",
        ));
    }
    let _title = cur
        .line()
        .ok_or_else(|| VolumeError::format(path, "title", "file ends before the title line"))?;
    let mode = text(path, "file type", cur.nonblank_line())?.to_ascii_uppercase();
    let binary = match mode.as_str() {
        "ASCII" => false,
        "BINARY" => true,
        other => {
            return Err(VolumeError::format(
                path,
                "file type",
                format!("'{other}' is neither ASCII nor BINARY"),
            ))
        }
    };
    let ds = text(path, "DATASET", cur.nonblank_line())?.to_ascii_uppercase();
    let kind = ds.strip_prefix("DATASET").map(str::trim).ok_or_else(|| {
        VolumeError::format(path, "DATASET", format!("expected DATASET, found '{ds}'"))
    })?;
    if kind != "STRUCTURED_POINTS" {
        return Err(VolumeError::format(
            path,
            "DATASET",
            format!("{kind} is not a regular grid; umbra reads STRUCTURED_POINTS volumes (curvilinear and unstructured grids need resampling)"),
        ));
    }
    let mut dims: Option<[i64; 3]> = None;
    let mut spacing = [1.0f64; 3];
    let mut origin = [0.0f64; 3];
    let mut fields: Vec<Field> = Vec::new();
    let mut active: Option<usize> = None;
    let mut npoints: Option<usize> = None;
    let mut in_cell_data = false;
    let mut ncells = 0usize;
    while let Some(tok) = cur.token() {
        let kw = text(path, "keyword", Some(tok))?.to_ascii_uppercase();
        match kw.as_str() {
            "DIMENSIONS" => {
                let mut d = [0i64; 3];
                for v in &mut d {
                    *v = int(path, "DIMENSIONS", cur.token())?;
                }
                checked_count(path, "DIMENSIONS", &d)?;
                dims = Some(d);
            }
            "SPACING" | "ASPECT_RATIO" => {
                for v in &mut spacing {
                    *v = float(path, &kw, cur.token())?;
                }
                if spacing.contains(&0.0) {
                    return Err(VolumeError::format(path, &kw, "a spacing of 0"));
                }
            }
            "ORIGIN" => {
                for v in &mut origin {
                    *v = float(path, "ORIGIN", cur.token())?;
                }
            }
            "POINT_DATA" => {
                let n = int(path, "POINT_DATA", cur.token())?;
                let d = dims.ok_or_else(|| {
                    VolumeError::format(path, "POINT_DATA", "comes before DIMENSIONS")
                })?;
                let expect = checked_count(path, "DIMENSIONS", &d)?;
                if n != expect as i64 {
                    return Err(VolumeError::format(
                        path,
                        "POINT_DATA",
                        format!("{n} points, DIMENSIONS {d:?} give {expect}"),
                    ));
                }
                npoints = Some(expect);
                in_cell_data = false;
            }
            "CELL_DATA" => {
                let n = int(path, "CELL_DATA", cur.token())?;
                if n < 0 || n as u64 > io_util::MAX_SAMPLES {
                    return Err(VolumeError::format(path, "CELL_DATA", format!("{n} cells")));
                }
                ncells = n as usize;
                in_cell_data = true;
            }
            "SCALARS" | "VECTORS" | "NORMALS" | "COLOR_SCALARS" | "TENSORS" => {
                let n = if in_cell_data {
                    ncells
                } else {
                    npoints
                        .ok_or_else(|| VolumeError::format(path, &kw, "comes before POINT_DATA"))?
                };
                let name = text(path, &kw, cur.token())?.to_string();
                let (ty, comps) = match kw.as_str() {
                    "COLOR_SCALARS" => {
                        let c = int(path, "COLOR_SCALARS", cur.token())?;
                        if !(1..=4).contains(&c) {
                            return Err(VolumeError::format(
                                path,
                                "COLOR_SCALARS",
                                format!("{c} components"),
                            ));
                        }
                        // Binary colour scalars are unsigned bytes, ASCII ones floats in [0, 1].
                        (
                            if binary {
                                ScalarType::U8
                            } else {
                                ScalarType::F32
                            },
                            c as usize,
                        )
                    }
                    _ => {
                        let ty =
                            vtk_type(path, &format!("{kw} {name}"), text(path, &kw, cur.token())?)?;
                        let comps = match kw.as_str() {
                            "SCALARS" => {
                                // Optional component count on the same line.
                                let save = cur.pos;
                                let rest_line = {
                                    let mut c2 = Cursor::new(cur.data);
                                    c2.pos = save;
                                    c2.line().unwrap_or_default()
                                };
                                let t = rest_line
                                    .split(|b| b.is_ascii_whitespace())
                                    .find(|t| !t.is_empty());
                                match t {
                                    Some(t) => {
                                        let c = int(path, "SCALARS numComp", Some(t))?;
                                        if !(1..=4).contains(&c) {
                                            return Err(VolumeError::format(
                                                path,
                                                "SCALARS numComp",
                                                format!("{c} is not in 1..4"),
                                            ));
                                        }
                                        cur.token();
                                        c as usize
                                    }
                                    None => 1,
                                }
                            }
                            "TENSORS" => 9,
                            _ => 3,
                        };
                        (ty, comps)
                    }
                };
                cur.skip_line();
                if kw == "SCALARS" {
                    // LOOKUP_TABLE line (optional in practice).
                    let save = cur.pos;
                    match cur.token() {
                        Some(t) if t.eq_ignore_ascii_case(b"LOOKUP_TABLE") => cur.skip_line(),
                        _ => cur.pos = save,
                    }
                }
                let count = n
                    .checked_mul(comps)
                    .ok_or_else(|| VolumeError::format(path, &kw, "size overflows"))?;
                let data = read_values(path, &format!("{kw} {name}"), &mut cur, binary, ty, count)?;
                if !in_cell_data {
                    push_field(&mut fields, name, comps, ty, data);
                    if kw == "SCALARS" && active.is_none() {
                        active = Some(fields.len() - 1);
                    }
                }
            }
            "LOOKUP_TABLE" => {
                let _name = cur.token();
                let size = int(path, "LOOKUP_TABLE", cur.token())?;
                if size < 0 || size as u64 > io_util::MAX_SAMPLES {
                    return Err(VolumeError::format(
                        path,
                        "LOOKUP_TABLE",
                        format!("size {size}"),
                    ));
                }
                cur.skip_line();
                let ty = if binary {
                    ScalarType::U8
                } else {
                    ScalarType::F32
                };
                read_values(
                    path,
                    "LOOKUP_TABLE",
                    &mut cur,
                    binary,
                    ty,
                    size as usize * 4,
                )?;
            }
            "FIELD" => {
                let _name = cur.token();
                let narr = int(path, "FIELD", cur.token())?;
                if !(0..=10_000).contains(&narr) {
                    return Err(VolumeError::format(path, "FIELD", format!("{narr} arrays")));
                }
                cur.skip_line();
                for _ in 0..narr {
                    let name = text(path, "FIELD array", cur.token())?.to_string();
                    let comps = int(path, &format!("FIELD array {name}"), cur.token())?;
                    let tuples = int(path, &format!("FIELD array {name}"), cur.token())?;
                    let ty = vtk_type(
                        path,
                        &format!("FIELD array {name}"),
                        text(path, "FIELD array", cur.token())?,
                    )?;
                    if !(1..=64).contains(&comps) || tuples < 0 {
                        return Err(VolumeError::format(
                            path,
                            format!("FIELD array {name}"),
                            format!("{comps} components, {tuples} tuples"),
                        ));
                    }
                    cur.skip_line();
                    let count = checked_count(
                        path,
                        &format!("FIELD array {name}"),
                        &[comps, tuples.max(1)],
                    )?;
                    let count = if tuples == 0 { 0 } else { count };
                    let data = read_values(
                        path,
                        &format!("FIELD array {name}"),
                        &mut cur,
                        binary,
                        ty,
                        count,
                    )?;
                    if !in_cell_data && Some(tuples as usize) == npoints {
                        push_field(&mut fields, name, comps as usize, ty, data);
                    }
                }
            }
            "METADATA" => {
                // Skip until a blank line.
                cur.skip_line();
                while let Some(l) = cur.line() {
                    if l.trim_ascii().is_empty() {
                        break;
                    }
                }
            }
            other => {
                return Err(VolumeError::format(
                    path,
                    "keyword",
                    format!("unexpected '{other}'"),
                ));
            }
        }
    }
    let d = dims.ok_or_else(|| VolumeError::format(path, "DIMENSIONS", "missing"))?;
    if fields.is_empty() {
        return Err(VolumeError::format(
            path,
            "POINT_DATA",
            "no point data arrays",
        ));
    }
    let affine = DMat4::from_cols(
        DVec4::new(spacing[0], 0.0, 0.0, 0.0),
        DVec4::new(0.0, spacing[1], 0.0, 0.0),
        DVec4::new(0.0, 0.0, spacing[2], 0.0),
        DVec4::new(origin[0], origin[1], origin[2], 1.0),
    );
    Ok(Volume {
        format: "vtk-legacy".into(),
        dims: [d[0] as usize, d[1] as usize, d[2] as usize],
        affine,
        space: Space::File,
        fields,
        default_field: active.unwrap_or(0),
        warnings: vec![],
    })
}

/// Adds an array as a field: 1 and 3 components as they are, others split per component.
pub(crate) fn push_field(
    fields: &mut Vec<Field>,
    name: String,
    comps: usize,
    ty: ScalarType,
    data: Vec<f32>,
) {
    if comps == 1 || comps == 3 {
        fields.push(Field {
            name,
            components: comps,
            stored: ty,
            data,
        });
    } else {
        for c in 0..comps {
            fields.push(Field {
                name: format!("{name}[{c}]"),
                components: 1,
                stored: ty,
                data: data.iter().skip(c).step_by(comps).copied().collect(),
            });
        }
    }
}
