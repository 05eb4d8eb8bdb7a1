//! TRX tractograms (`.trx`, tee-ar-ex/trx-spec): a zip archive (stored or deflated) or a plain
//! directory of little-endian arrays.
//!
//! * `header.json`: `NB_VERTICES`, `NB_STREAMLINES`, `VOXEL_TO_RASMM` (4x4), `DIMENSIONS`.
//! * `positions.3.<dtype>`: the points, already in RAS+ mm (the affine only describes the
//!   reference grid), float16, float32 or float64.
//! * `offsets.<dtype>` (uint32/uint64, also signed): the first point of each streamline;
//!   `NB_STREAMLINES` entries (the spec) or `NB_STREAMLINES + 1` ending at `NB_VERTICES`
//!   (what trx-python 0.6 writes). Both are read.
//! * `dpv/NAME[.C].<dtype>` and `dps/NAME[.C].<dtype>`: per-point and per-streamline
//!   attributes with C components (1 when absent). Groups (`groups/`, `dpg/`) are listed in a
//!   warning and otherwise ignored.
//!
//! Every array's byte size is checked against the header counts before it is read, and a
//! member is read with a limit of the size it must have, so a header or a zip directory that
//! lies cannot make the reader allocate more than the file holds.
//!
//! [`write`] writes a zip archive (stored, not deflated): `header.json`, `positions.3.float32`,
//! `offsets.uint64` (`NB_STREAMLINES` entries, as the spec), and every attribute as
//! `dpv/NAME[.C].float32` or `dps/NAME[.C].float32`.

use crate::{Attribute, ReferenceSpace, Result, Streamlines, TubesError};
use glam::{DMat4, DVec4, Vec3};
use std::io::Read;
use std::path::Path;

/// An element type of a TRX array.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Dtype {
    I8,
    I16,
    I32,
    I64,
    U8,
    U16,
    U32,
    U64,
    F16,
    F32,
    F64,
}

impl Dtype {
    fn parse(s: &str) -> Option<Dtype> {
        Some(match s {
            "int8" => Dtype::I8,
            "int16" => Dtype::I16,
            "int32" => Dtype::I32,
            "int64" => Dtype::I64,
            "uint8" | "bit" | "bool" => Dtype::U8,
            "uint16" => Dtype::U16,
            "uint32" => Dtype::U32,
            "uint64" => Dtype::U64,
            "float16" => Dtype::F16,
            "float32" => Dtype::F32,
            "float64" => Dtype::F64,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            Dtype::I8 | Dtype::U8 => 1,
            Dtype::I16 | Dtype::U16 | Dtype::F16 => 2,
            Dtype::I32 | Dtype::U32 | Dtype::F32 => 4,
            Dtype::I64 | Dtype::U64 | Dtype::F64 => 8,
        }
    }

    /// Decodes little-endian values as f64.
    fn decode(self, b: &[u8]) -> Vec<f64> {
        b.chunks_exact(self.size()).map(|c| self.value(c)).collect()
    }

    /// One little-endian element (`c` holds exactly [`Dtype::size`] bytes).
    fn value(self, c: &[u8]) -> f64 {
        {
            match self {
                Dtype::I8 => c[0] as i8 as f64,
                Dtype::U8 => c[0] as f64,
                Dtype::I16 => i16::from_le_bytes([c[0], c[1]]) as f64,
                Dtype::U16 => u16::from_le_bytes([c[0], c[1]]) as f64,
                Dtype::F16 => f16_to_f32(u16::from_le_bytes([c[0], c[1]])) as f64,
                Dtype::I32 => i32::from_le_bytes(c.try_into().unwrap()) as f64,
                Dtype::U32 => u32::from_le_bytes(c.try_into().unwrap()) as f64,
                Dtype::F32 => f32::from_le_bytes(c.try_into().unwrap()) as f64,
                Dtype::I64 => i64::from_le_bytes(c.try_into().unwrap()) as f64,
                Dtype::U64 => u64::from_le_bytes(c.try_into().unwrap()) as f64,
                Dtype::F64 => f64::from_le_bytes(c.try_into().unwrap()),
            }
        }
    }
}

/// IEEE half to single precision (subnormals, infinities and NaN included).
pub fn f16_to_f32(h: u16) -> f32 {
    let sign = ((h >> 15) as u32) << 31;
    let exp = ((h >> 10) & 0x1f) as u32;
    let man = (h & 0x3ff) as u32;
    let bits = match (exp, man) {
        (0, 0) => sign,
        (0, m) => {
            // Subnormal: value m * 2^-24.
            let v = m as f32 * f32::powi(2.0, -24);
            return if sign != 0 { -v } else { v };
        }
        (31, 0) => sign | 0x7f80_0000,
        (31, m) => sign | 0x7fc0_0000 | (m << 13),
        (e, m) => sign | ((e + 127 - 15) << 23) | (m << 13),
    };
    f32::from_bits(bits)
}

/// A member of the archive: its path inside, and how to read it.
struct Member {
    name: String,
    /// Declared (uncompressed) size.
    size: u64,
    index: usize,
}

/// The container: a zip archive or a directory.
enum Container {
    Zip(zip::ZipArchive<std::fs::File>),
    Dir(std::path::PathBuf),
}

impl Container {
    /// Reads a member, refusing more than `limit` bytes.
    fn read(&mut self, path: &Path, m: &Member, limit: u64) -> Result<Vec<u8>> {
        // The zip directory's size is a claim: reserve no more than 64 MiB up front.
        let mut out = Vec::with_capacity(m.size.min(limit).min(1 << 26) as usize);
        let got = match self {
            Container::Zip(z) => {
                let f = z.by_index(m.index).map_err(|e| {
                    TubesError::format(path, &m.name, format!("cannot open the member: {e}"))
                })?;
                f.take(limit + 1).read_to_end(&mut out)
            }
            Container::Dir(d) => std::fs::File::open(d.join(&m.name))
                .and_then(|f| f.take(limit + 1).read_to_end(&mut out)),
        };
        got.map_err(|e| TubesError::format(path, &m.name, format!("cannot read: {e}")))?;
        if out.len() as u64 > limit {
            return Err(TubesError::format(
                path,
                &m.name,
                format!("holds more than the {limit} bytes the header allows"),
            ));
        }
        Ok(out)
    }

    /// Reads a member in pieces of about 1 MiB, handing `f` whole elements of `elem` bytes,
    /// refusing more than `limit` bytes; returns the bytes read (a partial element at the end
    /// is counted, not handed on).
    fn stream(
        &mut self,
        path: &Path,
        m: &Member,
        limit: u64,
        elem: usize,
        mut f: impl FnMut(&[u8]),
    ) -> Result<u64> {
        let mut pump = |r: &mut dyn Read| -> std::io::Result<u64> {
            let mut buf = vec![0u8; (1 << 20) / elem * elem + elem];
            let (mut have, mut total) = (0usize, 0u64);
            loop {
                let n = r.read(&mut buf[have..])?;
                if n == 0 {
                    return Ok(total);
                }
                total += n as u64;
                if total > limit {
                    return Ok(total);
                }
                have += n;
                let whole = have / elem * elem;
                f(&buf[..whole]);
                buf.copy_within(whole..have, 0);
                have -= whole;
            }
        };
        let got = match self {
            Container::Zip(z) => {
                let mut f = z.by_index(m.index).map_err(|e| {
                    TubesError::format(path, &m.name, format!("cannot open the member: {e}"))
                })?;
                pump(&mut f)
            }
            Container::Dir(d) => {
                std::fs::File::open(d.join(&m.name)).and_then(|mut f| pump(&mut f))
            }
        };
        let total =
            got.map_err(|e| TubesError::format(path, &m.name, format!("cannot read: {e}")))?;
        if total > limit {
            return Err(TubesError::format(
                path,
                &m.name,
                format!("holds more than the {limit} bytes the header allows"),
            ));
        }
        Ok(total)
    }
}

fn list(path: &Path) -> Result<(Container, Vec<Member>)> {
    if path.is_dir() {
        let mut members = Vec::new();
        let mut stack = vec![std::path::PathBuf::new()];
        while let Some(rel) = stack.pop() {
            let dir = path.join(&rel);
            let entries = std::fs::read_dir(&dir).map_err(|e| TubesError::io(&dir, e))?;
            for e in entries {
                let e = e.map_err(|e| TubesError::io(&dir, e))?;
                let r = rel.join(e.file_name());
                let meta = e.metadata().map_err(|err| TubesError::io(&e.path(), err))?;
                if meta.is_dir() {
                    if stack.len() < 1000 {
                        stack.push(r);
                    }
                } else {
                    members.push(Member {
                        name: r.to_string_lossy().replace('\\', "/"),
                        size: meta.len(),
                        index: 0,
                    });
                }
            }
        }
        return Ok((Container::Dir(path.to_path_buf()), members));
    }
    let f = std::fs::File::open(path).map_err(|e| TubesError::io(path, e))?;
    volume::note_read(path);
    let mut z = zip::ZipArchive::new(f)
        .map_err(|e| TubesError::format(path, "zip archive", e.to_string()))?;
    let mut members = Vec::new();
    for i in 0..z.len() {
        let f = z
            .by_index_raw(i)
            .map_err(|e| TubesError::format(path, "zip archive", e.to_string()))?;
        if f.is_dir() {
            continue;
        }
        let name = f
            .name()
            .map_err(|e| TubesError::format(path, "zip archive", e.to_string()))?
            .to_string();
        members.push(Member {
            name,
            size: f.size(),
            index: i,
        });
    }
    Ok((Container::Zip(z), members))
}

/// Splits `dir/NAME[.C].dtype` into (NAME, C, dtype); the name may hold dots.
fn split_name(path: &Path, full: &str) -> Result<(String, usize, Dtype)> {
    let base = full.rsplit('/').next().unwrap_or(full);
    let bad = |why: &str| TubesError::format(path, full, why.to_string());
    let (rest, dt) = base
        .rsplit_once('.')
        .ok_or_else(|| bad("no data type in the name"))?;
    let dtype = Dtype::parse(dt).ok_or_else(|| bad("unknown data type"))?;
    match rest.rsplit_once('.') {
        Some((name, c)) if !c.is_empty() && c.bytes().all(|b| b.is_ascii_digit()) => {
            let c: usize = c.parse().map_err(|_| bad("bad component count"))?;
            if !(1..=1024).contains(&c) {
                return Err(bad("component count out of 1..1024"));
            }
            Ok((name.to_string(), c, dtype))
        }
        _ => Ok((rest.to_string(), 1, dtype)),
    }
}

fn header_count(path: &Path, h: &serde_json::Value, key: &str) -> Result<usize> {
    let v = h
        .get(key)
        .ok_or_else(|| TubesError::format(path, format!("header.json {key}"), "missing"))?;
    let n = v.as_u64().ok_or_else(|| {
        TubesError::format(
            path,
            format!("header.json {key}"),
            format!("{v} is not a non-negative integer"),
        )
    })?;
    // Four bytes a point at least: a count beyond 2^40 cannot be backed by any file we read.
    if n > 1 << 40 {
        return Err(TubesError::format(
            path,
            format!("header.json {key}"),
            format!("{n} is absurd"),
        ));
    }
    Ok(n as usize)
}

/// Reads a `.trx` archive or directory.
pub fn read(path: &Path) -> Result<Streamlines> {
    let (mut c, members) = list(path)?;
    let named = |prefix: &str| -> Vec<&Member> {
        members
            .iter()
            .filter(|m| m.name == prefix || m.name.starts_with(&format!("{prefix}.")))
            .collect()
    };
    let header = members
        .iter()
        .find(|m| m.name == "header.json")
        .ok_or_else(|| TubesError::format(path, "header.json", "missing"))?;
    let h = c.read(path, header, 1 << 20)?;
    let h: serde_json::Value = serde_json::from_slice(&h)
        .map_err(|e| TubesError::format(path, "header.json", e.to_string()))?;
    let nv = header_count(path, &h, "NB_VERTICES")?;
    let ns = header_count(path, &h, "NB_STREAMLINES")?;
    let mut s = Streamlines::new();
    s.format = "trx".into();
    // Reference grid (kept for writing TrackVis back).
    if let (Some(a), Some(d)) = (h.get("VOXEL_TO_RASMM"), h.get("DIMENSIONS")) {
        let rows: Option<Vec<Vec<f64>>> = a.as_array().map(|r| {
            r.iter()
                .filter_map(|row| {
                    row.as_array()
                        .map(|x| x.iter().filter_map(|v| v.as_f64()).collect::<Vec<_>>())
                })
                .collect()
        });
        let dims: Option<Vec<usize>> = d.as_array().map(|x| {
            x.iter()
                .filter_map(|v| v.as_u64().map(|v| v as usize))
                .collect()
        });
        if let (Some(r), Some(dims)) = (rows, dims) {
            if r.len() == 4 && r.iter().all(|x| x.len() == 4) && dims.len() == 3 {
                let m = DMat4::from_cols(
                    DVec4::new(r[0][0], r[1][0], r[2][0], r[3][0]),
                    DVec4::new(r[0][1], r[1][1], r[2][1], r[3][1]),
                    DVec4::new(r[0][2], r[1][2], r[2][2], r[3][2]),
                    DVec4::new(r[0][3], r[1][3], r[2][3], r[3][3]),
                );
                let vs = [0, 1, 2].map(|i| m.col(i).truncate().length());
                if m.is_finite() && vs.iter().all(|&v| v > 0.0) {
                    s.reference = Some(ReferenceSpace {
                        dims: [dims[0], dims[1], dims[2]],
                        voxel_sizes: vs,
                        vox_to_ras: m,
                        // As the matrix says (it was always "RAS": an LPS grid read as RAS).
                        voxel_order: crate::trk::voxel_order(&glam::DMat3::from_mat4(m)),
                    });
                }
            }
        }
    }
    // Positions.
    let pos = named("positions");
    let [pm] = pos.as_slice() else {
        return Err(TubesError::format(
            path,
            "positions",
            format!("{} positions arrays (one needed)", pos.len()),
        ));
    };
    let (_, comps, dt) = split_name(path, &pm.name)?;
    if comps != 3 || !matches!(dt, Dtype::F16 | Dtype::F32 | Dtype::F64) {
        return Err(TubesError::format(
            path,
            &pm.name,
            "positions must be 3 float components",
        ));
    }
    let need = (nv as u64) * 3 * dt.size() as u64;
    let short = |got: u64| {
        TubesError::format(
            path,
            &pm.name,
            format!(
                "{got} bytes; NB_VERTICES {nv} x 3 x {} need {need}",
                dt.size()
            ),
        )
    };
    // The member's own size (a file's, or the archive's entry) bounds what the header may
    // ask for: NB_VERTICES past it is refused before anything is allocated.
    if pm.size < need {
        return Err(short(pm.size));
    }
    // Streamed into the points (reserved once, fallibly: an archive's entry may claim more
    // than it holds): the member's bytes are never held whole.
    s.points.try_reserve_exact(nv).map_err(|_| {
        TubesError::format(
            path,
            &pm.name,
            format!("NB_VERTICES {nv}: not enough memory for its points ({need} bytes)"),
        )
    })?;
    let (mut xyz, mut k, mut bad) = ([0f64; 3], 0, None);
    let points = &mut s.points;
    let got = c.stream(path, pm, need, dt.size(), |piece| {
        for e in piece.chunks_exact(dt.size()) {
            let x = dt.value(e);
            if bad.is_none() && x.is_finite() && !(x as f32).is_finite() {
                bad = Some((points.len(), x));
            }
            xyz[k] = x;
            k += 1;
            if k == 3 {
                points.push(Vec3::new(xyz[0] as f32, xyz[1] as f32, xyz[2] as f32));
                k = 0;
            }
        }
    })?;
    if got != need {
        return Err(short(got));
    }
    if let Some((i, x)) = bad {
        return Err(TubesError::format(
            path,
            &pm.name,
            format!("point {i}: {x:e} is outside f32's range"),
        ));
    }
    // Offsets.
    let offs = named("offsets");
    let [om] = offs.as_slice() else {
        return Err(TubesError::format(
            path,
            "offsets",
            format!("{} offsets arrays (one needed)", offs.len()),
        ));
    };
    let (_, oc, odt) = split_name(path, &om.name)?;
    if oc != 1 || matches!(odt, Dtype::F16 | Dtype::F32 | Dtype::F64) {
        return Err(TubesError::format(
            path,
            &om.name,
            "offsets must be one integer component",
        ));
    }
    let b = c.read(path, om, (ns as u64 + 1) * odt.size() as u64)?;
    let mut o: Vec<f64> = odt.decode(&b);
    if b.len() % odt.size() != 0 || !(o.len() == ns || o.len() == ns + 1) {
        return Err(TubesError::format(
            path,
            &om.name,
            format!(
                "{} bytes; NB_STREAMLINES {ns} needs {ns} or {} offsets",
                b.len(),
                ns + 1
            ),
        ));
    }
    if o.len() == ns {
        o.push(nv as f64);
    }
    if (ns > 0 && o[0] != 0.0)
        || o.windows(2).any(|w| w[1] < w[0])
        || o.last() != Some(&(nv as f64))
    {
        return Err(TubesError::format(
            path,
            &om.name,
            format!("offsets must start at 0, never decrease and end at NB_VERTICES {nv}"),
        ));
    }
    s.offsets = o.iter().map(|&v| v as usize).collect();
    // Attributes.
    let mut ignored = Vec::new();
    for m in &members {
        let (per_point, count) = if m.name.starts_with("dpv/") {
            (true, nv)
        } else if m.name.starts_with("dps/") {
            (false, ns)
        } else {
            if m.name.starts_with("groups/") || m.name.starts_with("dpg/") {
                ignored.push(m.name.clone());
            }
            continue;
        };
        let (name, comps, dt) = split_name(path, &m.name)?;
        let need = (count as u64) * comps as u64 * dt.size() as u64;
        let b = c.read(path, m, need)?;
        if b.len() as u64 != need {
            return Err(TubesError::format(
                path,
                &m.name,
                format!(
                    "{} bytes; {count} x {comps} x {} need {need}",
                    b.len(),
                    dt.size()
                ),
            ));
        }
        let a = Attribute {
            name,
            components: comps,
            values: dt.decode(&b).into_iter().map(|v| v as f32).collect(),
        };
        if per_point {
            s.point_attributes.push(a);
        } else {
            s.line_attributes.push(a);
        }
    }
    s.point_attributes.sort_by(|a, b| a.name.cmp(&b.name));
    s.line_attributes.sort_by(|a, b| a.name.cmp(&b.name));
    if !ignored.is_empty() {
        s.warnings
            .push(format!("groups are not read: {}", ignored.join(", ")));
    }
    Ok(s)
}

/// Whether an attribute name survives `dpv/NAME[.C].float32`: a file name (no `/`, `\\`, NUL,
/// not empty, `.` or `..`) whose last dot-separated part is not all digits (it would read as a
/// component count).
fn writable_name(name: &str) -> bool {
    !name.is_empty()
        && name != "."
        && name != ".."
        && !name.contains(['/', '\\', '\0'])
        && name
            .rsplit_once('.')
            .is_none_or(|(_, last)| last.is_empty() || !last.bytes().all(|b| b.is_ascii_digit()))
}

/// Writes a `.trx` zip archive (see the module doc). The reference grid is the tractogram's
/// (`VOXEL_TO_RASMM`, `DIMENSIONS`), else the identity and `[1, 1, 1]`.
pub fn write(path: &Path, s: &Streamlines) -> Result<()> {
    use std::io::Write;
    s.validate()
        .map_err(|e| TubesError::Invalid(format!("{}: {e}", path.display())))?;
    for a in s.point_attributes.iter().chain(&s.line_attributes) {
        if !writable_name(&a.name) {
            return Err(TubesError::Invalid(format!(
                "{}: attribute '{}': TRX stores attributes as files named NAME[.C].float32; \
                 the name must be a file name not ending in .DIGITS",
                path.display(),
                a.name
            )));
        }
    }
    let (v2r, dims) = match &s.reference {
        Some(r) => (r.vox_to_ras, r.dims),
        None => (DMat4::IDENTITY, [1, 1, 1]),
    };
    let rows: Vec<Vec<f64>> = (0..4)
        .map(|r| (0..4).map(|c| v2r.col(c)[r]).collect())
        .collect();
    let header = serde_json::json!({
        "VOXEL_TO_RASMM": rows,
        "DIMENSIONS": dims,
        "NB_VERTICES": s.points.len(),
        "NB_STREAMLINES": s.len(),
    });
    let f32s =
        |v: &mut dyn Iterator<Item = f32>| -> Vec<u8> { v.flat_map(|x| x.to_le_bytes()).collect() };
    let mut members: Vec<(String, Vec<u8>)> = vec![
        (
            "header.json".into(),
            serde_json::to_vec_pretty(&header).map_err(|e| {
                TubesError::Invalid(format!("{}: header.json: {e}", path.display()))
            })?,
        ),
        (
            "positions.3.float32".into(),
            f32s(&mut s.points.iter().flat_map(|p| [p.x, p.y, p.z])),
        ),
        (
            "offsets.uint64".into(),
            s.offsets[..s.len()]
                .iter()
                .flat_map(|&o| (o as u64).to_le_bytes())
                .collect(),
        ),
    ];
    for (dir, attrs) in [("dpv", &s.point_attributes), ("dps", &s.line_attributes)] {
        for a in attrs {
            let name = if a.components == 1 {
                format!("{dir}/{}.float32", a.name)
            } else {
                format!("{dir}/{}.{}.float32", a.name, a.components)
            };
            members.push((name, f32s(&mut a.values.iter().copied())));
        }
    }
    let mut z = zip::ZipWriter::new(std::io::Cursor::new(Vec::new()));
    let zerr =
        |e: &dyn std::fmt::Display| TubesError::Invalid(format!("{}: zip: {e}", path.display()));
    for (name, bytes) in &members {
        let options = zip::write::SimpleFileOptions::default()
            .compression_method(zip::CompressionMethod::Stored)
            .large_file(bytes.len() as u64 >= u32::MAX as u64);
        z.start_file(name.as_str(), options).map_err(|e| zerr(&e))?;
        z.write_all(bytes).map_err(|e| zerr(&e))?;
    }
    let bytes = z.finish().map_err(|e| zerr(&e))?.into_inner();
    crate::error::write_atomic(path, bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn half_floats_decode_exactly() {
        assert_eq!(f16_to_f32(0x3c00), 1.0);
        assert_eq!(f16_to_f32(0xc000), -2.0);
        assert_eq!(f16_to_f32(0x7bff), 65504.0);
        assert_eq!(f16_to_f32(0x0001), 2f32.powi(-24));
        assert_eq!(f16_to_f32(0x3555), 0.333_251_95);
        assert!(f16_to_f32(0x7c00).is_infinite());
        assert!(f16_to_f32(0x7e00).is_nan());
        assert_eq!(f16_to_f32(0x8000).to_bits(), (-0.0f32).to_bits());
    }

    #[test]
    fn names_split_into_attribute_components_and_type() {
        let p = Path::new("x.trx");
        assert_eq!(
            split_name(p, "dpv/colors.3.float32").unwrap(),
            ("colors".into(), 3, Dtype::F32)
        );
        assert_eq!(
            split_name(p, "dps/mean.fa.float16").unwrap(),
            ("mean.fa".into(), 1, Dtype::F16)
        );
        assert!(split_name(p, "dpv/x.complex64").is_err());
        assert!(split_name(p, "dpv/x.0.float32").is_err());
    }

    #[test]
    fn attribute_names_that_would_not_read_back_are_refused() {
        for ok in ["time", "speed", "mean.fa", "v2", "x.", "a.b3"] {
            assert!(writable_name(ok), "{ok}");
        }
        for bad in ["", ".", "..", "a/b", "a\\b", "fa.3", "x.12"] {
            assert!(!writable_name(bad), "{bad}");
        }
    }
}
