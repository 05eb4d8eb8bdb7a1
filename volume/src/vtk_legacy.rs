//! VTK legacy (`.vtk`) reader, ASCII and BINARY (big-endian): STRUCTURED_POINTS volumes
//! ([`read`]) and STRUCTURED_GRID / RECTILINEAR_GRID / UNSTRUCTURED_GRID CFD grids
//! ([`read_grid`], resampled by [`crate::cfd_grid`]).
//!
//! Point-data attributes `SCALARS` (1 or 3 components; others are split per component),
//! `VECTORS`, `NORMALS`, `COLOR_SCALARS` and `FIELD` arrays all become named fields;
//! `LOOKUP_TABLE` blocks and VTK 5 `METADATA` blocks are skipped. For volumes `CELL_DATA` is
//! skipped (cell data is not on the sample grid); grids keep it. Geometry: `DIMENSIONS`,
//! `SPACING` (or the old `ASPECT_RATIO`), `ORIGIN` for volumes, whose frame is the file's own
//! (`space: file`); `POINTS` (curvilinear) or `X/Y/Z_COORDINATES` (rectilinear) for grids, and
//! for unstructured grids `POINTS`, `CELLS` (classic: each cell's id count then its ids; VTK
//! 5.1: `OFFSETS` and `CONNECTIVITY` arrays) and `CELL_TYPES`, converted as `.vtu` cells are
//! (by the cell conversion the two readers share, `vtk_common`). Polydata are refused with an
//! error that says so.

use crate::cfd_grid::{CfdGrid, Geometry, GridArray};
use crate::io_util::{self, checked_count, Cursor};
use crate::vtk_common;
use crate::{Field, Result, ScalarType, Space, Volume, VolumeError};
use glam::{DMat4, DVec3, DVec4};
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
        io_util::decode_samples(path, field, bytes, ty, true)
    } else {
        let (v, used) = io_util::parse_ascii(path, field, cur.rest(), count)?;
        cur.pos += used;
        Ok(v)
    }
}

/// One data array of a legacy file.
struct LegacyArray {
    name: String,
    comps: usize,
    ty: ScalarType,
    data: Vec<f32>,
    on_cells: bool,
    /// Declared with SCALARS (the first such point array is the default field).
    scalars: bool,
}

/// Everything a legacy file holds that umbra uses.
struct Legacy {
    kind: String,
    dims: Option<[i64; 3]>,
    spacing: [f64; 3],
    origin: [f64; 3],
    points: Option<Vec<f32>>,
    coords: [Option<Vec<f32>>; 3],
    /// Unstructured cells: connectivity, end offset of each cell, VTK cell types.
    cells: Option<(Vec<f32>, Vec<f32>, Vec<f32>)>,
    arrays: Vec<LegacyArray>,
}

/// Parses any of the structured legacy kinds.
fn parse(path: &Path) -> Result<Legacy> {
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
    if !matches!(
        kind,
        "STRUCTURED_POINTS" | "STRUCTURED_GRID" | "RECTILINEAR_GRID" | "UNSTRUCTURED_GRID"
    ) {
        return Err(VolumeError::format(
            path,
            "DATASET",
            format!("{kind} is not supported; umbra reads STRUCTURED_POINTS volumes and STRUCTURED_GRID, RECTILINEAR_GRID or UNSTRUCTURED_GRID grids"),
        ));
    }
    let kind = kind.to_string();
    let mut dims: Option<[i64; 3]> = None;
    let mut spacing = [1.0f64; 3];
    let mut origin = [0.0f64; 3];
    let mut points: Option<Vec<f32>> = None;
    let mut n_points_decl: Option<usize> = None;
    let mut cell_conn: Option<Vec<f32>> = None;
    let mut cell_ends: Option<Vec<f32>> = None;
    let mut cell_types: Option<Vec<f32>> = None;
    let mut coords: [Option<Vec<f32>>; 3] = [None, None, None];
    let mut arrays: Vec<LegacyArray> = Vec::new();
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
            "POINTS" => {
                let n = int(path, "POINTS", cur.token())?;
                let ty = vtk_type(path, "POINTS", text(path, "POINTS", cur.token())?)?;
                let expect = if kind == "UNSTRUCTURED_GRID" {
                    if n < 0 || n as u64 > io_util::MAX_SAMPLES {
                        return Err(VolumeError::format(path, "POINTS", format!("{n} points")));
                    }
                    n as usize
                } else {
                    let d = dims.ok_or_else(|| {
                        VolumeError::format(path, "POINTS", "comes before DIMENSIONS")
                    })?;
                    let expect = checked_count(path, "DIMENSIONS", &d)?;
                    if n != expect as i64 {
                        return Err(VolumeError::format(
                            path,
                            "POINTS",
                            format!("{n} points, DIMENSIONS {d:?} give {expect}"),
                        ));
                    }
                    expect
                };
                n_points_decl = Some(expect);
                cur.skip_line();
                points = Some(read_values(
                    path,
                    "POINTS",
                    &mut cur,
                    binary,
                    ty,
                    expect * 3,
                )?);
            }
            "X_COORDINATES" | "Y_COORDINATES" | "Z_COORDINATES" => {
                let axis = (kw.as_bytes()[0] - b'X') as usize;
                let n = int(path, &kw, cur.token())?;
                let ty = vtk_type(path, &kw, text(path, &kw, cur.token())?)?;
                let d =
                    dims.ok_or_else(|| VolumeError::format(path, &kw, "comes before DIMENSIONS"))?;
                if n != d[axis] {
                    return Err(VolumeError::format(
                        path,
                        &kw,
                        format!("{n} values, DIMENSIONS give {}", d[axis]),
                    ));
                }
                cur.skip_line();
                coords[axis] = Some(read_values(path, &kw, &mut cur, binary, ty, n as usize)?);
            }
            "POINT_DATA" => {
                let n = int(path, "POINT_DATA", cur.token())?;
                let expect = match (dims, n_points_decl) {
                    (Some(d), _) => checked_count(path, "DIMENSIONS", &d)?,
                    (None, Some(p)) => p,
                    (None, None) => {
                        return Err(VolumeError::format(
                            path,
                            "POINT_DATA",
                            "comes before DIMENSIONS or POINTS",
                        ))
                    }
                };
                if n != expect as i64 {
                    return Err(VolumeError::format(
                        path,
                        "POINT_DATA",
                        format!("{n} points, the geometry has {expect}"),
                    ));
                }
                npoints = Some(expect);
                in_cell_data = false;
            }
            "CELLS" => {
                // Classic: CELLS n size, then per cell its id count and ids. VTK 5.1: CELLS
                // n_offsets n_connectivity, then OFFSETS and CONNECTIVITY arrays.
                let a = int(path, "CELLS", cur.token())?;
                let b = int(path, "CELLS", cur.token())?;
                if a < 0
                    || b < 0
                    || a as u64 > io_util::MAX_SAMPLES
                    || b as u64 > io_util::MAX_SAMPLES
                {
                    return Err(VolumeError::format(path, "CELLS", format!("{a} {b}")));
                }
                cur.skip_line();
                let save = cur.pos;
                if cur
                    .token()
                    .is_some_and(|t| t.eq_ignore_ascii_case(b"OFFSETS"))
                {
                    let ty = vtk_type(path, "OFFSETS", text(path, "OFFSETS", cur.token())?)?;
                    cur.skip_line();
                    let offs = read_values(path, "OFFSETS", &mut cur, binary, ty, a as usize)?;
                    let kw = text(path, "CONNECTIVITY", cur.token())?.to_ascii_uppercase();
                    if kw != "CONNECTIVITY" {
                        return Err(VolumeError::format(
                            path,
                            "CONNECTIVITY",
                            format!("expected after OFFSETS, found '{kw}'"),
                        ));
                    }
                    let ty = vtk_type(
                        path,
                        "CONNECTIVITY",
                        text(path, "CONNECTIVITY", cur.token())?,
                    )?;
                    cur.skip_line();
                    let conn = read_values(path, "CONNECTIVITY", &mut cur, binary, ty, b as usize)?;
                    if offs.first().is_some_and(|&o| o != 0.0) {
                        return Err(VolumeError::format(path, "OFFSETS", "must start at 0"));
                    }
                    cell_ends = Some(offs.get(1..).unwrap_or(&[]).to_vec());
                    cell_conn = Some(conn);
                } else {
                    cur.pos = save;
                    let list =
                        read_values(path, "CELLS", &mut cur, binary, ScalarType::I32, b as usize)?;
                    let (mut conn, mut ends) = (
                        Vec::with_capacity(list.len()),
                        // Never more cells than list entries: a header count alone
                        // allocates nothing.
                        Vec::with_capacity((a as usize).min(list.len())),
                    );
                    let mut i = 0usize;
                    for c in 0..a as usize {
                        let k = list.get(i).copied().unwrap_or(-1.0);
                        let fits = k >= 0.0
                            && k.fract() == 0.0
                            && (k as usize) < list.len().saturating_sub(i);
                        if !fits {
                            return Err(VolumeError::format(
                                path,
                                "CELLS",
                                format!("cell {c}: {k} ids do not fit the list of {b}"),
                            ));
                        }
                        conn.extend_from_slice(&list[i + 1..i + 1 + k as usize]);
                        ends.push(conn.len() as f32);
                        i += 1 + k as usize;
                    }
                    cell_ends = Some(ends);
                    cell_conn = Some(conn);
                }
            }
            "CELL_TYPES" => {
                let n = int(path, "CELL_TYPES", cur.token())?;
                if n < 0 || n as u64 > io_util::MAX_SAMPLES {
                    return Err(VolumeError::format(
                        path,
                        "CELL_TYPES",
                        format!("{n} cells"),
                    ));
                }
                cur.skip_line();
                cell_types = Some(read_values(
                    path,
                    "CELL_TYPES",
                    &mut cur,
                    binary,
                    ScalarType::I32,
                    n as usize,
                )?);
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
                let mut bit = false;
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
                        let tname = text(path, &kw, cur.token())?;
                        bit = tname.eq_ignore_ascii_case("bit");
                        let ty = if bit {
                            ScalarType::U8
                        } else {
                            vtk_type(path, &format!("{kw} {name}"), tname)?
                        };
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
                let data = if bit && binary {
                    // Packed bits, most significant first, each array padded to a byte.
                    let bytes = cur.take(count.div_ceil(8)).ok_or_else(|| {
                        VolumeError::format(path, format!("{kw} {name}"), "file ends in the bits")
                    })?;
                    (0..count)
                        .map(|i| ((bytes[i / 8] >> (7 - i % 8)) & 1) as f32)
                        .collect()
                } else {
                    read_values(path, &format!("{kw} {name}"), &mut cur, binary, ty, count)?
                };
                arrays.push(LegacyArray {
                    name,
                    comps,
                    ty,
                    data,
                    on_cells: in_cell_data,
                    scalars: kw == "SCALARS",
                });
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
                    let expect = if in_cell_data { Some(ncells) } else { npoints };
                    if Some(tuples as usize) == expect {
                        arrays.push(LegacyArray {
                            name,
                            comps: comps as usize,
                            ty,
                            data,
                            on_cells: in_cell_data,
                            scalars: false,
                        });
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
    let cells = match (cell_conn, cell_ends, cell_types) {
        (Some(c), Some(e), Some(t)) => Some((c, e, t)),
        _ => None,
    };
    Ok(Legacy {
        kind,
        dims,
        spacing,
        origin,
        points,
        coords,
        cells,
        arrays,
    })
}

/// Reads a legacy `.vtk` STRUCTURED_POINTS file.
pub fn read(path: &Path) -> Result<Volume> {
    let Legacy {
        kind,
        dims,
        spacing,
        origin,
        arrays,
        ..
    } = parse(path)?;
    if kind != "STRUCTURED_POINTS" {
        return Err(VolumeError::format(
            path,
            "DATASET",
            format!("{kind} is not a regular grid; resample it with `umbra resample` first"),
        ));
    }
    let d = dims.ok_or_else(|| VolumeError::format(path, "DIMENSIONS", "missing"))?;
    let mut fields: Vec<Field> = Vec::new();
    let mut active: Option<usize> = None;
    for a in arrays.into_iter().filter(|a| !a.on_cells) {
        // An array of 2 or more than 3 components becomes a field per component: the active
        // scalars are its first.
        let first = fields.len();
        vtk_common::push_field(&mut fields, a.name, a.comps, a.ty, a.data);
        if a.scalars && active.is_none() {
            active = Some(first);
        }
    }
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

/// Reads a legacy STRUCTURED_GRID or RECTILINEAR_GRID file as a CFD grid.
pub fn read_grid(path: &Path) -> Result<CfdGrid> {
    let lg = parse(path)?;
    let mut cell_origin: Option<Vec<usize>> = None;
    let dims = match lg.kind.as_str() {
        "UNSTRUCTURED_GRID" => [0; 3],
        _ => {
            let d = lg
                .dims
                .ok_or_else(|| VolumeError::format(path, "DIMENSIONS", "missing"))?;
            [d[0] as usize, d[1] as usize, d[2] as usize]
        }
    };
    let geometry = match lg.kind.as_str() {
        "UNSTRUCTURED_GRID" => {
            let p = lg
                .points
                .as_ref()
                .ok_or_else(|| VolumeError::format(path, "POINTS", "missing"))?;
            let (conn, ends, types) = lg
                .cells
                .as_ref()
                .ok_or_else(|| VolumeError::format(path, "CELLS", "missing (with CELL_TYPES)"))?;
            if p.len() / 3 > 1 << 24 {
                return Err(VolumeError::format(
                    path,
                    "POINTS",
                    "more than 2^24 points in an unstructured grid",
                ));
            }
            let (cells, origin) = vtk_common::cells_from_vtk(path, conn, ends, types)?;
            cell_origin = Some(origin);
            Geometry::Unstructured {
                points: p
                    .chunks_exact(3)
                    .map(|c| DVec3::new(c[0] as f64, c[1] as f64, c[2] as f64))
                    .collect(),
                cells,
            }
        }
        "STRUCTURED_GRID" => {
            let p = lg
                .points
                .ok_or_else(|| VolumeError::format(path, "POINTS", "missing"))?;
            Geometry::Structured {
                dims,
                points: p
                    .chunks_exact(3)
                    .map(|c| DVec3::new(c[0] as f64, c[1] as f64, c[2] as f64))
                    .collect(),
            }
        }
        "RECTILINEAR_GRID" => {
            let [x, y, z] = lg
                .coords
                .map(|c| c.map(|v| v.iter().map(|&f| f as f64).collect()));
            let miss = |a: &str| VolumeError::format(path, format!("{a}_COORDINATES"), "missing");
            Geometry::Rectilinear {
                x: x.ok_or_else(|| miss("X"))?,
                y: y.ok_or_else(|| miss("Y"))?,
                z: z.ok_or_else(|| miss("Z"))?,
            }
        }
        _ => {
            // Regular: expand to coordinates, once the data show the grid exists (a header's
            // DIMENSIONS alone allocates nothing).
            let n = io_util::checked_count(path, "DIMENSIONS", &dims.map(|d| d as i64))?;
            let cells = dims
                .map(|d| d.saturating_sub(1).max(1))
                .iter()
                .product::<usize>();
            let has_data = lg
                .arrays
                .iter()
                .any(|a| a.data.len() == a.comps * if a.on_cells { cells } else { n });
            if !has_data {
                return Err(VolumeError::format(
                    path,
                    "POINT_DATA",
                    format!(
                        "no array of the {} x {} x {} grid's size: a regular grid is resampled \
                         from its data",
                        dims[0], dims[1], dims[2]
                    ),
                ));
            }
            let axis = |a: usize| {
                (0..dims[a])
                    .map(|i| lg.origin[a] + lg.spacing[a] * i as f64)
                    .collect()
            };
            Geometry::Rectilinear {
                x: axis(0),
                y: axis(1),
                z: axis(2),
            }
        }
    };
    let grid = CfdGrid {
        format: format!("vtk-legacy {}", lg.kind.to_ascii_lowercase()),
        geometry,
        arrays: lg
            .arrays
            .into_iter()
            .map(|a| {
                // Split cells repeat their source cell's values.
                let data = match (&cell_origin, a.on_cells) {
                    (Some(o), true)
                        if a.data.len() >= o.iter().max().map_or(0, |m| m + 1) * a.comps =>
                    {
                        o.iter()
                            .flat_map(|&c| a.data[c * a.comps..(c + 1) * a.comps].iter().copied())
                            .collect()
                    }
                    _ => a.data,
                };
                GridArray {
                    name: a.name,
                    components: a.comps,
                    on_cells: a.on_cells,
                    data,
                }
            })
            .collect(),
    };
    grid.validate(path)?;
    Ok(grid)
}
