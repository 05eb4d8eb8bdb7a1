//! VTK legacy POLYDATA with LINES (`.vtk`, ASCII or BINARY big-endian) as streamlines.
//!
//! `POINTS n type`, then `LINES` in either layout: the classic `LINES nlines size` with
//! `count i0 i1 ...` per line, or VTK 5.1's `LINES noffsets nconn` followed by `OFFSETS` and
//! `CONNECTIVITY` arrays. Point data (`SCALARS` with 1-4 components, `VECTORS`, `NORMALS`,
//! `FIELD` arrays) become per-point attributes gathered along each line; cell data with one
//! tuple per line become per-streamline attributes (cells other than lines, such as vertices or
//! polygons, are refused). Coordinates are taken as they are (the file's own frame).
//! Indices are checked against the point count and counts against the bytes left: no
//! allocation follows an unchecked header field.

use crate::error::{read_maybe_gz, Result, TubesError};
use crate::{Attribute, Streamlines};
use glam::Vec3;
use std::path::Path;

struct Cur<'a> {
    b: &'a [u8],
    pos: usize,
    binary: bool,
}

impl<'a> Cur<'a> {
    fn token(&mut self) -> Option<&'a str> {
        while self.pos < self.b.len() && self.b[self.pos].is_ascii_whitespace() {
            self.pos += 1;
        }
        let start = self.pos;
        while self.pos < self.b.len() && !self.b[self.pos].is_ascii_whitespace() {
            self.pos += 1;
        }
        (self.pos > start).then(|| std::str::from_utf8(&self.b[start..self.pos]).unwrap_or("?"))
    }

    fn line(&mut self) -> Option<&'a str> {
        if self.pos >= self.b.len() {
            return None;
        }
        let rest = &self.b[self.pos..];
        let end = rest.iter().position(|&c| c == b'\n').unwrap_or(rest.len());
        self.pos += (end + 1).min(rest.len());
        Some(
            std::str::from_utf8(&rest[..end])
                .unwrap_or("?")
                .trim_end_matches('\r'),
        )
    }

    /// Skips to the start of the next line (binary data follow a keyword line).
    fn end_line(&mut self) {
        while self.pos < self.b.len() && self.b[self.pos] != b'\n' {
            self.pos += 1;
        }
        self.pos = (self.pos + 1).min(self.b.len());
    }

    /// `count` numbers of VTK type `ty`.
    fn values(&mut self, path: &Path, field: &str, ty: &str, count: usize) -> Result<Vec<f64>> {
        let size = match ty {
            "unsigned_char" | "char" => 1,
            "unsigned_short" | "short" => 2,
            "unsigned_int" | "int" | "float" | "vtkidtype" => 4,
            "unsigned_long" | "long" | "double" | "vtktypeint64" | "vtktypeuint64" => 8,
            other => {
                return Err(TubesError::format(
                    path,
                    field,
                    format!("data type '{other}' is not supported"),
                ))
            }
        };
        if self.binary {
            let need = count
                .checked_mul(size)
                .filter(|&n| n <= self.b.len() - self.pos.min(self.b.len()))
                .ok_or_else(|| {
                    TubesError::format(
                        path,
                        field,
                        format!(
                            "{count} values of {ty} do not fit in the {} bytes left",
                            self.b.len().saturating_sub(self.pos)
                        ),
                    )
                })?;
            let d = &self.b[self.pos..self.pos + need];
            self.pos += need;
            let out = d
                .chunks_exact(size)
                .map(|c| match (ty, size) {
                    ("unsigned_char", _) => c[0] as f64,
                    ("char", _) => c[0] as i8 as f64,
                    ("unsigned_short", _) => u16::from_be_bytes([c[0], c[1]]) as f64,
                    ("short", _) => i16::from_be_bytes([c[0], c[1]]) as f64,
                    ("unsigned_int", _) => u32::from_be_bytes(c.try_into().unwrap()) as f64,
                    ("int", _) | ("vtkidtype", _) => {
                        i32::from_be_bytes(c.try_into().unwrap()) as f64
                    }
                    ("float", _) => f32::from_be_bytes(c.try_into().unwrap()) as f64,
                    ("double", _) => f64::from_be_bytes(c.try_into().unwrap()),
                    ("unsigned_long", _) | ("vtktypeuint64", _) => {
                        u64::from_be_bytes(c.try_into().unwrap()) as f64
                    }
                    _ => i64::from_be_bytes(c.try_into().unwrap()) as f64,
                })
                .collect();
            if self.b.get(self.pos) == Some(&b'\n') {
                self.pos += 1;
            }
            Ok(out)
        } else {
            let mut out = Vec::with_capacity(count.min(self.b.len() / 2 + 1));
            for k in 0..count {
                let t = self.token().ok_or_else(|| {
                    TubesError::format(path, field, format!("data end after {k} of {count} values"))
                })?;
                out.push(t.parse::<f64>().map_err(|_| {
                    TubesError::format(path, field, format!("'{t}' is not a number"))
                })?);
            }
            Ok(out)
        }
    }
}

fn count(path: &Path, field: &str, t: Option<&str>) -> Result<usize> {
    let t = t.ok_or_else(|| TubesError::format(path, field, "file ends here"))?;
    t.parse::<usize>()
        .ok()
        .filter(|&n| n <= 1 << 31)
        .ok_or_else(|| TubesError::format(path, field, format!("'{t}' is not a count")))
}

/// An index or count of the file (a point id, an offset, a line's length): a whole number
/// from 0 to 2^31 - 1; -1, NaN and 1.9 are errors naming the entry.
fn index(path: &Path, field: &str, entry: usize, v: f64) -> Result<usize> {
    if v >= 0.0 && v.fract() == 0.0 && v < (1u64 << 31) as f64 {
        Ok(v as usize)
    } else {
        Err(TubesError::format(
            path,
            field,
            format!("entry {entry} is {v}, not an index (a whole number from 0 to 2^31 - 1)"),
        ))
    }
}

/// Reads a legacy `.vtk` POLYDATA file's lines.
pub fn read(path: &Path) -> Result<Streamlines> {
    let bytes = read_maybe_gz(path, b"# vtk DataFile", "VTK legacy")?;
    let mut c = Cur {
        b: &bytes,
        pos: 0,
        binary: false,
    };
    let first = c.line().unwrap_or("");
    if !first.starts_with("# vtk DataFile") {
        return Err(TubesError::format(
            path,
            "header",
            "first line is not '# vtk DataFile Version x.y'",
        ));
    }
    c.line()
        .ok_or_else(|| TubesError::format(path, "title", "file ends before the title"))?;
    let mode = loop {
        let l = c
            .line()
            .ok_or_else(|| TubesError::format(path, "file type", "missing"))?;
        if !l.trim().is_empty() {
            break l.trim().to_ascii_uppercase();
        }
    };
    c.binary = match mode.as_str() {
        "ASCII" => false,
        "BINARY" => true,
        other => {
            return Err(TubesError::format(
                path,
                "file type",
                format!("'{other}' is neither ASCII nor BINARY"),
            ))
        }
    };
    match (c.token(), c.token()) {
        (Some(d), Some(k))
            if d.eq_ignore_ascii_case("DATASET") && k.eq_ignore_ascii_case("POLYDATA") => {}
        (_, k) => {
            return Err(TubesError::format(
                path,
                "DATASET",
                format!("{} is not POLYDATA", k.unwrap_or("nothing")),
            ))
        }
    }
    let mut points: Vec<Vec3> = Vec::new();
    let mut lines: Vec<Vec<usize>> = Vec::new();
    let mut point_attrs: Vec<(String, usize, Vec<f64>)> = Vec::new();
    let mut cell_attrs: Vec<(String, usize, Vec<f64>)> = Vec::new();
    let mut warnings: Vec<String> = Vec::new();
    let mut section = "";
    let mut n_section = 0usize;
    while let Some(kw) = c.token() {
        match kw.to_ascii_uppercase().as_str() {
            "POINTS" => {
                let n = count(path, "POINTS", c.token())?;
                let ty = c.token().unwrap_or("float").to_ascii_lowercase();
                c.end_line();
                let v = c.values(path, "POINTS", &ty, n.saturating_mul(3))?;
                if let Some(i) = v
                    .iter()
                    .position(|&x| x.is_finite() && !(x as f32).is_finite())
                {
                    return Err(TubesError::format(
                        path,
                        "POINTS",
                        format!("point {}: {:e} is outside f32's range", i / 3, v[i]),
                    ));
                }
                points = v
                    .chunks_exact(3)
                    .map(|p| Vec3::new(p[0] as f32, p[1] as f32, p[2] as f32))
                    .collect();
            }
            "LINES" => {
                let a = count(path, "LINES", c.token())?;
                let b = count(path, "LINES", c.token())?;
                c.end_line();
                // VTK 5.1 layout: OFFSETS and CONNECTIVITY arrays follow.
                let save = c.pos;
                if c.token().is_some_and(|t| t.eq_ignore_ascii_case("OFFSETS")) {
                    let ty = c.token().unwrap_or("vtktypeint64").to_ascii_lowercase();
                    c.end_line();
                    let offsets = c.values(path, "OFFSETS", &ty, a)?;
                    if !c
                        .token()
                        .is_some_and(|t| t.eq_ignore_ascii_case("CONNECTIVITY"))
                    {
                        return Err(TubesError::format(
                            path,
                            "CONNECTIVITY",
                            "missing after OFFSETS",
                        ));
                    }
                    let ty = c.token().unwrap_or("vtktypeint64").to_ascii_lowercase();
                    c.end_line();
                    let conn = c.values(path, "CONNECTIVITY", &ty, b)?;
                    let offsets = offsets
                        .iter()
                        .enumerate()
                        .map(|(i, &o)| index(path, "OFFSETS", i, o))
                        .collect::<Result<Vec<_>>>()?;
                    if offsets.first().is_some_and(|&o| o != 0) {
                        return Err(TubesError::format(path, "OFFSETS", "must start at 0"));
                    }
                    let conn = conn
                        .iter()
                        .enumerate()
                        .map(|(i, &o)| index(path, "CONNECTIVITY", i, o))
                        .collect::<Result<Vec<_>>>()?;
                    for w in offsets.windows(2) {
                        let (s, e) = (w[0], w[1]);
                        if s > e || e > conn.len() {
                            return Err(TubesError::format(
                                path,
                                "OFFSETS",
                                format!(
                                    "offsets {s}..{e} outside the {} connectivity entries",
                                    conn.len()
                                ),
                            ));
                        }
                        lines.push(conn[s..e].to_vec());
                    }
                } else {
                    c.pos = save;
                    let v = c.values(path, "LINES", "int", b)?;
                    let v = v
                        .iter()
                        .enumerate()
                        .map(|(i, &o)| index(path, "LINES", i, o))
                        .collect::<Result<Vec<_>>>()?;
                    let mut k = 0usize;
                    for l in 0..a {
                        let n = *v.get(k).ok_or_else(|| {
                            TubesError::format(
                                path,
                                "LINES",
                                format!("line {l} runs past the {b} entries"),
                            )
                        })?;
                        // n < 2^31 and k < len: no overflow.
                        let ids = v.get(k + 1..k + 1 + n).ok_or_else(|| {
                            TubesError::format(
                                path,
                                "LINES",
                                format!("line {l} with {n} points runs past the {b} entries"),
                            )
                        })?;
                        lines.push(ids.to_vec());
                        k += 1 + n;
                    }
                }
            }
            "VERTICES" | "POLYGONS" | "TRIANGLE_STRIPS" => {
                return Err(TubesError::format(
                    path,
                    kw,
                    "only LINES cells are streamlines",
                ));
            }
            "POINT_DATA" | "CELL_DATA" => {
                n_section = count(path, kw, c.token())?;
                section = if kw.eq_ignore_ascii_case("POINT_DATA") {
                    "point"
                } else {
                    "cell"
                };
            }
            "SCALARS" | "VECTORS" | "NORMALS" => {
                let name = c.token().unwrap_or("data").to_string();
                let ty = c.token().unwrap_or("float").to_ascii_lowercase();
                let mut comps = if kw.eq_ignore_ascii_case("SCALARS") {
                    1
                } else {
                    3
                };
                if kw.eq_ignore_ascii_case("SCALARS") {
                    let rest = c.line().unwrap_or("");
                    if let Some(n) = rest.split_whitespace().next() {
                        comps =
                            n.parse()
                                .ok()
                                .filter(|n| (1..=4).contains(n))
                                .ok_or_else(|| {
                                    TubesError::format(path, "SCALARS", format!("'{n}' components"))
                                })?;
                    }
                    let save = c.pos;
                    if c.token()
                        .is_some_and(|t| t.eq_ignore_ascii_case("LOOKUP_TABLE"))
                    {
                        c.end_line();
                    } else {
                        c.pos = save;
                    }
                } else {
                    c.end_line();
                }
                let v = c.values(path, &name, &ty, n_section.saturating_mul(comps))?;
                let dest = if section == "cell" {
                    &mut cell_attrs
                } else {
                    &mut point_attrs
                };
                dest.push((name, comps, v));
            }
            "FIELD" => {
                let _ = c.token();
                let narr = count(path, "FIELD", c.token())?;
                c.end_line();
                for _ in 0..narr.min(1000) {
                    let name = c.token().unwrap_or("data").to_string();
                    let comps = count(path, "FIELD", c.token())?;
                    let tuples = count(path, "FIELD", c.token())?;
                    let ty = c.token().unwrap_or("float").to_ascii_lowercase();
                    c.end_line();
                    let v = c.values(path, &name, &ty, comps.saturating_mul(tuples))?;
                    if tuples == n_section && (1..=16).contains(&comps) {
                        let dest = if section == "cell" {
                            &mut cell_attrs
                        } else {
                            &mut point_attrs
                        };
                        dest.push((name, comps, v));
                    } else {
                        warnings.push(format!(
                            "FIELD array '{}' ({comps} components x {tuples} tuples) does not \
                             fit its {n_section}-tuple {section} data; ignored",
                            volume::clip_text(&name, 40)
                        ));
                    }
                }
            }
            "METADATA" => {
                while let Some(l) = c.line() {
                    if l.trim().is_empty() {
                        break;
                    }
                }
            }
            other => {
                return Err(TubesError::format(
                    path,
                    "keyword",
                    format!("unexpected '{other}'"),
                ))
            }
        }
    }
    let mut s = Streamlines::new();
    for (li, l) in lines.iter().enumerate() {
        if let Some(&bad) = l.iter().find(|&&i| i >= points.len()) {
            return Err(TubesError::format(
                path,
                "LINES",
                format!(
                    "line {li} refers to point {bad}, there are {}",
                    points.len()
                ),
            ));
        }
        s.push(&l.iter().map(|&i| points[i]).collect::<Vec<_>>());
    }
    for (name, comps, v) in point_attrs {
        if v.len() != comps * points.len() {
            warnings.push(format!(
                "point array '{}' has {} tuples for {} points; ignored",
                volume::clip_text(&name, 40),
                v.len() / comps.max(1),
                points.len()
            ));
            continue;
        }
        let values = lines
            .iter()
            .flat_map(|l| l.iter().flat_map(|&i| (0..comps).map(move |k| (i, k))))
            .map(|(i, k)| v[i * comps + k] as f32)
            .collect();
        s.point_attributes.push(Attribute {
            name,
            components: comps,
            values,
        });
    }
    for (name, comps, v) in cell_attrs {
        if v.len() == comps * lines.len() {
            s.line_attributes.push(Attribute {
                name,
                components: comps,
                values: v.iter().map(|&x| x as f32).collect(),
            });
        } else {
            warnings.push(format!(
                "cell array '{}' has {} tuples for {} lines; ignored",
                volume::clip_text(&name, 40),
                v.len() / comps.max(1),
                lines.len()
            ));
        }
    }
    s.warnings = warnings;
    s.format = "vtk-polydata".into();
    Ok(s)
}
