//! NRRD reader and writer (format version 1-5 headers, teem's definition).
//!
//! Reads attached (`.nrrd`) and detached (`.nhdr` + `data file:`) headers with raw, gzip and
//! ASCII encodings, either endian, `line skip`/`byte skip` (including `byte skip: -1`), all
//! scalar types, `sizes`, `kinds`, `space`, `space dimension`, `space directions`,
//! `space origin`, `spacings`, `axis mins` and `measurement frame`.
//!
//! Geometry: the affine's columns are the `space directions` of the three spatial axes (axes
//! whose direction is `none`, or whose kind is not a domain kind, carry components), the
//! translation is `space origin`. Without directions, `spacings` (default 1) give a diagonal
//! matrix and `axis mins` (default 0) the origin. LPS (`left-posterior-superior`) and LAS spaces
//! are converted to RAS+ by negating x and y (LPS) or x (LAS); `scanner-xyz` and `3D-*-handed`
//! spaces keep their frame (`space: file`). Vector components are taken in the measurement frame
//! when one is given (converted to the world frame by it), and get the same LPS/LAS flip.
//!
//! A 4-D array whose non-spatial axis has 3 entries (kinds `vector`, `3-vector`,
//! `covariant-vector`, `normal`, `point`, ...) is a vector field; any other non-spatial axis
//! (`list` of 8 octants, say) is split into scalar fields named `NAME[i]`.

use crate::io_util::{self, checked_count, take_samples};
use crate::samples::Samples;
use crate::{Field, Result, ScalarType, Space, Volume, VolumeError};
use glam::{DMat3, DMat4, DVec3, DVec4};
use std::path::Path;

fn scalar_type(path: &Path, s: &str) -> Result<ScalarType> {
    let t = s.trim().to_ascii_lowercase();
    Ok(match t.as_str() {
        "signed char" | "int8" | "int8_t" => ScalarType::I8,
        "uchar" | "unsigned char" | "uint8" | "uint8_t" => ScalarType::U8,
        "short" | "short int" | "signed short" | "signed short int" | "int16" | "int16_t" => {
            ScalarType::I16
        }
        "ushort" | "unsigned short" | "unsigned short int" | "uint16" | "uint16_t" => {
            ScalarType::U16
        }
        "int" | "signed int" | "int32" | "int32_t" => ScalarType::I32,
        "uint" | "unsigned int" | "uint32" | "uint32_t" => ScalarType::U32,
        "longlong"
        | "long long"
        | "long long int"
        | "signed long long"
        | "signed long long int"
        | "int64"
        | "int64_t" => ScalarType::I64,
        "ulonglong" | "unsigned long long" | "unsigned long long int" | "uint64" | "uint64_t" => {
            ScalarType::U64
        }
        "float" => ScalarType::F32,
        "double" => ScalarType::F64,
        _ => {
            return Err(VolumeError::format(
                path,
                "type",
                format!("unknown or unsupported type '{}'", s.trim()),
            ))
        }
    })
}

fn type_name(t: ScalarType) -> &'static str {
    match t {
        ScalarType::I8 => "int8",
        ScalarType::U8 => "uint8",
        ScalarType::I16 => "int16",
        ScalarType::U16 => "uint16",
        ScalarType::I32 => "int32",
        ScalarType::U32 => "uint32",
        ScalarType::I64 => "int64",
        ScalarType::U64 => "uint64",
        ScalarType::F32 => "float",
        ScalarType::F64 => "double",
    }
}

#[derive(Clone, Copy, PartialEq, Debug)]
enum Encoding {
    Raw,
    Gzip,
    Ascii,
}

/// Parses `(x,y,z) (x,y,z) none ...` into one entry per axis.
fn parse_vectors(path: &Path, field: &str, s: &str) -> Result<Vec<Option<Vec<f64>>>> {
    let mut out = Vec::new();
    let mut rest = s.trim();
    while !rest.is_empty() {
        if let Some(r) = rest.strip_prefix("none") {
            out.push(None);
            rest = r.trim_start();
        } else if rest.starts_with('(') {
            let end = rest
                .find(')')
                .ok_or_else(|| VolumeError::format(path, field, "unclosed '('"))?;
            let v = io_util::parse_floats(path, field, &rest[1..end])?;
            out.push(Some(v));
            rest = rest[end + 1..].trim_start();
        } else {
            return Err(VolumeError::format(
                path,
                field,
                format!("cannot parse '{rest}'"),
            ));
        }
    }
    Ok(out)
}

fn is_domain_kind(k: &str) -> bool {
    matches!(k, "domain" | "space" | "time" | "???" | "none")
}

/// Reads a `.nrrd` or `.nhdr` file.
pub fn read(path: &Path) -> Result<Volume> {
    read_as(path, false).map(|(v, _)| v)
}

/// [`read`] keeping a scalar field of 8 or 16-bit integers in its stored type: the samples
/// are returned beside the volume, whose field then has no `f32` data (`None`: the field is
/// not such, its samples are in the volume as `f32`).
pub(crate) fn read_stored(path: &Path) -> Result<(Volume, Option<Samples>)> {
    read_as(path, true)
}

fn read_as(path: &Path, keep_stored: bool) -> Result<(Volume, Option<Samples>)> {
    let mut raw = io_util::read_file(path)?;
    let mut cur = io_util::Cursor::new(&raw);
    let magic = cur.line().unwrap_or_default();
    if !magic.starts_with(b"NRRD000") || magic.len() != 8 || !(b'1'..=b'9').contains(&magic[7]) {
        return Err(VolumeError::format(
            path,
            "magic",
            format!(
                "first line {:?} is not NRRD000N",
                String::from_utf8_lossy(&magic[..magic.len().min(16)])
            ),
        ));
    }
    let mut fields: Vec<(String, String)> = Vec::new();
    let mut header_ended = false;
    while let Some(line) = cur.line() {
        if line.is_empty() {
            header_ended = true;
            break;
        }
        let line = std::str::from_utf8(line)
            .map_err(|_| VolumeError::format(path, "header", "header line is not UTF-8 text"))?;
        if line.starts_with('#') {
            continue;
        }
        if line.contains(":=") {
            continue; // key/value pair: no geometry in it
        }
        let Some((k, v)) = line.split_once(": ") else {
            return Err(VolumeError::format(
                path,
                "header",
                format!("line '{line}' is not 'field: value'"),
            ));
        };
        fields.push((k.trim().to_ascii_lowercase(), v.trim().to_string()));
    }
    let get = |k: &str| {
        fields
            .iter()
            .find(|(key, _)| key == k)
            .map(|(_, v)| v.as_str())
    };
    let ty = scalar_type(
        path,
        get("type").ok_or_else(|| VolumeError::format(path, "type", "missing"))?,
    )?;
    let dimension: usize = get("dimension")
        .ok_or_else(|| VolumeError::format(path, "dimension", "missing"))?
        .parse()
        .map_err(|_| VolumeError::format(path, "dimension", "not an integer"))?;
    if !(1..=4).contains(&dimension) {
        return Err(VolumeError::format(
            path,
            "dimension",
            format!("{dimension} axes: umbra reads 1 to 4"),
        ));
    }
    let sizes = io_util::parse_sizes(
        path,
        "sizes",
        get("sizes").ok_or_else(|| VolumeError::format(path, "sizes", "missing"))?,
        dimension,
    )?;
    let total = checked_count(path, "sizes", &sizes)?;
    let encoding = match get("encoding").map(|s| s.to_ascii_lowercase()) {
        Some(e) if e == "raw" => Encoding::Raw,
        Some(e) if e == "gzip" || e == "gz" => Encoding::Gzip,
        Some(e) if e == "ascii" || e == "text" || e == "txt" => Encoding::Ascii,
        Some(e) => {
            return Err(VolumeError::format(
                path,
                "encoding",
                format!("'{e}' is not supported (raw, gzip, ascii are)"),
            ))
        }
        None => return Err(VolumeError::format(path, "encoding", "missing")),
    };
    let big_endian = match get("endian").map(|s| s.to_ascii_lowercase()) {
        Some(e) if e == "little" => false,
        Some(e) if e == "big" => true,
        Some(e) => {
            return Err(VolumeError::format(
                path,
                "endian",
                format!("'{e}' is neither little nor big"),
            ))
        }
        None if ty.size() > 1 && encoding != Encoding::Ascii => {
            return Err(VolumeError::format(
                path,
                "endian",
                "missing, and the type has more than one byte",
            ))
        }
        None => false,
    };
    let kinds: Option<Vec<String>> = get("kinds").map(|s| {
        s.split_whitespace()
            .map(|k| k.to_ascii_lowercase())
            .collect()
    });
    if let Some(k) = &kinds {
        if k.len() != dimension {
            return Err(VolumeError::format(
                path,
                "kinds",
                format!("{} kinds for {dimension} axes", k.len()),
            ));
        }
    }
    let directions = get("space directions")
        .map(|s| parse_vectors(path, "space directions", s))
        .transpose()?;
    if let Some(d) = &directions {
        if d.len() != dimension {
            return Err(VolumeError::format(
                path,
                "space directions",
                format!("{} entries for {dimension} axes", d.len()),
            ));
        }
    }
    // Which axis carries components.
    let mut comp_axis: Option<usize> = None;
    if dimension == 4 {
        let by_dir = directions
            .as_ref()
            .and_then(|d| d.iter().position(|v| v.is_none()));
        let by_kind = kinds
            .as_ref()
            .and_then(|k| k.iter().position(|k| !is_domain_kind(k)));
        comp_axis = Some(by_dir.or(by_kind).unwrap_or(0));
        if comp_axis != Some(0) && comp_axis != Some(3) {
            return Err(VolumeError::format(
                path,
                "kinds",
                "the non-spatial axis must be the first or the last",
            ));
        }
    }
    let spatial: Vec<usize> = (0..dimension).filter(|&a| Some(a) != comp_axis).collect();
    let ncomp = comp_axis.map(|a| sizes[a] as usize).unwrap_or(1);
    let mut dims = [1usize; 3];
    for (i, &a) in spatial.iter().enumerate() {
        dims[i] = sizes[a] as usize;
    }
    // Space.
    let space_name = get("space").map(|s| s.to_ascii_lowercase());
    let (flip, space) = match space_name.as_deref() {
        Some("right-anterior-superior") | Some("ras") => (DVec3::ONE, Space::Ras),
        Some("left-posterior-superior") | Some("lps") => (DVec3::new(-1.0, -1.0, 1.0), Space::Ras),
        Some("left-anterior-superior") | Some("las") => (DVec3::new(-1.0, 1.0, 1.0), Space::Ras),
        Some("scanner-xyz") | Some("3d-right-handed") | Some("3d-left-handed") | None => {
            (DVec3::ONE, Space::File)
        }
        Some(other) => {
            return Err(VolumeError::format(
                path,
                "space",
                format!("'{other}' is not a 3-D space umbra reads"),
            ))
        }
    };
    if let Some(sd) = get("space dimension") {
        if sd.trim() != "3" {
            return Err(VolumeError::format(
                path,
                "space dimension",
                format!("{sd}: only 3 is supported"),
            ));
        }
    }
    let mut cols = [DVec3::X, DVec3::Y, DVec3::Z];
    let mut origin = DVec3::ZERO;
    if let Some(dirs) = &directions {
        for (i, &a) in spatial.iter().enumerate() {
            let v = dirs[a].as_ref().ok_or_else(|| {
                VolumeError::format(
                    path,
                    "space directions",
                    format!("spatial axis {a} has direction 'none'"),
                )
            })?;
            if v.len() != 3 {
                return Err(VolumeError::format(
                    path,
                    "space directions",
                    format!("axis {a} has {} coordinates, not 3", v.len()),
                ));
            }
            cols[i] = DVec3::new(v[0], v[1], v[2]);
        }
        if spatial.len() < 3 {
            // 2-D image: complete the frame with the cross product.
            let n = cols[0].cross(if spatial.len() > 1 { cols[1] } else { DVec3::Y });
            if spatial.len() < 2 {
                cols[1] = n.cross(cols[0]).normalize_or_zero();
            }
            cols[2] = cols[0].cross(cols[1]).normalize_or_zero();
        }
        if let Some(o) = get("space origin") {
            let v = parse_vectors(path, "space origin", o)?;
            match v.as_slice() {
                [Some(v)] if v.len() == 3 => origin = DVec3::new(v[0], v[1], v[2]),
                _ => {
                    return Err(VolumeError::format(
                        path,
                        "space origin",
                        format!("'{o}' is not (x,y,z)"),
                    ))
                }
            }
        }
    } else {
        if let Some(s) = get("spacings") {
            let toks: Vec<&str> = s.split_whitespace().collect();
            if toks.len() != dimension {
                return Err(VolumeError::format(
                    path,
                    "spacings",
                    format!("{} entries for {dimension} axes", toks.len()),
                ));
            }
            for (i, &a) in spatial.iter().enumerate() {
                let v: f64 = toks[a]
                    .parse()
                    .ok()
                    .filter(|v: &f64| v.is_finite() && *v != 0.0)
                    .ok_or_else(|| {
                        VolumeError::format(
                            path,
                            "spacings",
                            format!("'{}' is not a finite non-zero spacing", toks[a]),
                        )
                    })?;
                cols[i] *= v;
            }
        }
        if let Some(s) = get("axis mins") {
            let toks: Vec<&str> = s.split_whitespace().collect();
            // A cell-centred axis's min is its first cell's edge: the first sample lies half
            // a spacing in (Teem's `nrrdAxisInfoPos`).
            let centers: Vec<&str> = get("centerings")
                .or_else(|| get("centers"))
                .map(|c| c.split_whitespace().collect())
                .unwrap_or_default();
            if toks.len() == dimension {
                for (i, &a) in spatial.iter().enumerate() {
                    if let Ok(v) = toks[a].parse::<f64>() {
                        if v.is_finite() {
                            let half = match centers.get(a) {
                                Some(&"cell") => 0.5 * cols[i][i],
                                _ => 0.0,
                            };
                            origin[i] = v + half;
                        }
                    }
                }
            }
        }
    }
    let m3 = DMat3::from_cols(cols[0] * flip, cols[1] * flip, cols[2] * flip);
    if crate::io_util::degenerate_axes(m3) {
        return Err(VolumeError::format(
            path,
            "space directions",
            "the axis directions are degenerate",
        ));
    }
    let affine = DMat4::from_cols(
        m3.x_axis.extend(0.0),
        m3.y_axis.extend(0.0),
        m3.z_axis.extend(0.0),
        DVec4::from((origin * flip, 1.0)),
    );
    // Data.
    let nbytes = total * ty.size();
    let line_skip: usize = get("line skip")
        .map(|s| {
            s.parse()
                .map_err(|_| VolumeError::format(path, "line skip", "not a count"))
        })
        .transpose()?
        .unwrap_or(0);
    let byte_skip: i64 = get("byte skip")
        .map(|s| {
            s.parse()
                .map_err(|_| VolumeError::format(path, "byte skip", "not an integer"))
        })
        .transpose()?
        .unwrap_or(0);
    let (data_path, file_bytes, start) = match get("data file").or_else(|| get("datafile")) {
        Some(df) => {
            if df.starts_with("LIST") || df.split_whitespace().count() > 1 {
                return Err(VolumeError::format(
                    path,
                    "data file",
                    "lists and format patterns of data files are not supported",
                ));
            }
            let (p, b) = io_util::read_companion(path, "data file", df)?;
            (p, b, 0usize)
        }
        None => {
            if !header_ended {
                return Err(VolumeError::format(
                    path,
                    "header",
                    "no blank line ends the header and no 'data file' is named",
                ));
            }
            // The body is read where it lies in the file's bytes (no copy).
            let pos = cur.pos;
            (path.to_path_buf(), std::mem::take(&mut raw), pos)
        }
    };
    let mut dc = io_util::Cursor::new(&file_bytes);
    dc.pos = start;
    for _ in 0..line_skip {
        if dc.line().is_none() {
            return Err(VolumeError::format(
                &data_path,
                "line skip",
                "file ends while skipping lines",
            ));
        }
    }
    let body: &[u8] = if byte_skip == -1 {
        if encoding != Encoding::Raw {
            return Err(VolumeError::format(
                path,
                "byte skip",
                "-1 is only valid with raw encoding",
            ));
        }
        let rest = dc.rest();
        if rest.len() < nbytes {
            return Err(VolumeError::format(
                &data_path,
                "data",
                format!("{} bytes, {nbytes} needed", rest.len()),
            ));
        }
        &rest[rest.len() - nbytes..]
    } else if byte_skip < 0 {
        return Err(VolumeError::format(
            path,
            "byte skip",
            format!("{byte_skip} is negative"),
        ));
    } else if encoding == Encoding::Gzip {
        // Skipped in the decompressed data (Teem's gzip reader skips after inflating).
        dc.rest()
    } else {
        dc.take(byte_skip as usize).ok_or_else(|| {
            VolumeError::format(&data_path, "byte skip", "file ends while skipping bytes")
        })?;
        dc.rest()
    };
    // A scalar field of 8/16-bit integers kept in its type (`read_stored`), else f32.
    let decode = |bytes: &[u8]| -> Result<(Vec<f32>, Option<Samples>)> {
        if keep_stored && ncomp == 1 {
            if let Some(s) = io_util::take_stored(&data_path, "data", bytes, total, ty, big_endian)?
            {
                return Ok((Vec::new(), Some(s)));
            }
        }
        let v = take_samples(&data_path, "data", bytes, total, ty, big_endian, false)?;
        Ok((v, None))
    };
    let (mut data, stored) = match encoding {
        Encoding::Raw => decode(body)?,
        Encoding::Gzip => {
            // Decompressed bytes are bounded as a file's are: a skip beyond that is no file's.
            if byte_skip as u64 > io_util::MAX_FILE_BYTES {
                return Err(VolumeError::format(
                    path,
                    "byte skip",
                    format!("{byte_skip} is more than {} bytes", io_util::MAX_FILE_BYTES),
                ));
            }
            let skip = byte_skip as usize;
            let bytes = io_util::gunzip(&data_path, "gzip data", body, Some(skip + nbytes))
                .map_err(|e| match skip {
                    0 => e,
                    _ => VolumeError::format(
                        &data_path,
                        "gzip data",
                        format!("{e} (with byte skip: {skip}, skipped in the decompressed data)"),
                    ),
                })?;
            drop(file_bytes);
            decode(&bytes[skip..])?
        }
        Encoding::Ascii => {
            let (v, used) = io_util::parse_ascii(&data_path, "ascii data", body, total)?;
            if body[used..].iter().any(|b| !b.is_ascii_whitespace()) {
                return Err(VolumeError::format(
                    &data_path,
                    "ascii data",
                    format!("more values than sizes give ({total})"),
                ));
            }
            (v, None)
        }
    };
    let name = get("content").unwrap_or("data").to_string();
    let n = dims[0] * dims[1] * dims[2];
    let mut out_fields = Vec::new();
    // Bring component-last layouts into interleaved order.
    if comp_axis == Some(3) && ncomp > 1 {
        let mut inter = vec![0f32; total];
        for c in 0..ncomp {
            for i in 0..n {
                inter[i * ncomp + c] = data[c * n + i];
            }
        }
        data = inter;
    }
    let vector_kind = kinds
        .as_ref()
        .zip(comp_axis)
        .map(|(k, a)| k[a] != "list")
        .unwrap_or(true);
    if ncomp == 3 && vector_kind {
        let mut mf = DMat3::IDENTITY;
        if let Some(m) = get("measurement frame") {
            let v = parse_vectors(path, "measurement frame", m)?;
            if v.len() != 3 || v.iter().any(|c| c.as_ref().map(|c| c.len()) != Some(3)) {
                return Err(VolumeError::format(
                    path,
                    "measurement frame",
                    "expected three (x,y,z) vectors",
                ));
            }
            let c: Vec<DVec3> = v
                .into_iter()
                .map(|c| {
                    let c = c.unwrap();
                    DVec3::new(c[0], c[1], c[2])
                })
                .collect();
            mf = DMat3::from_cols(c[0], c[1], c[2]);
            // The frame the vectors were measured in: a rotation (or a reflection). A zero or
            // scaling frame would silently zero or rescale every vector.
            let gram = mf.transpose() * mf;
            let off = (gram - DMat3::IDENTITY)
                .to_cols_array()
                .iter()
                .fold(0.0f64, |a, v| a.max(v.abs()));
            if off.is_nan() || off > 1e-3 {
                return Err(VolumeError::format(
                    path,
                    "measurement frame",
                    format!(
                        "not orthonormal (its vectors' dot products differ from the identity by \
                         {off:.3e}): the frame must be a rotation"
                    ),
                ));
            }
        }
        let m = DMat3::from_diagonal(flip) * mf;
        if m != DMat3::IDENTITY {
            for v in data.chunks_exact_mut(3) {
                let w = m * DVec3::new(v[0] as f64, v[1] as f64, v[2] as f64);
                v.copy_from_slice(&[w.x as f32, w.y as f32, w.z as f32]);
            }
        }
        out_fields.push(Field {
            name,
            components: 3,
            stored: ty,
            data,
        });
    } else if ncomp == 1 {
        out_fields.push(Field {
            name,
            components: 1,
            stored: ty,
            data,
        });
    } else {
        for c in 0..ncomp {
            out_fields.push(Field {
                name: format!("{name}[{c}]"),
                components: 1,
                stored: ty,
                data: data.iter().skip(c).step_by(ncomp).copied().collect(),
            });
        }
    }
    let vol = Volume {
        format: if data_path == path {
            "nrrd".into()
        } else {
            "nrrd-detached".into()
        },
        dims,
        affine,
        space,
        fields: out_fields,
        default_field: 0,
        warnings: vec![],
    };
    Ok((vol, stored))
}

/// NRRD data encodings the writer produces.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum WriteEncoding {
    Raw,
    Gzip,
}

/// The samples of an array to write.
pub enum ArrayData<'a> {
    /// Converted to the array's stored type on writing.
    F32(&'a [f32]),
    /// Written as they are (the stored type must be `U8`).
    U8(&'a [u8]),
    /// One `u8` plane per component (each a value per voxel), interleaved on writing (the stored
    /// type must be `U8`; raw encoding streams them without an interleaved copy).
    U8Planes(&'a [Vec<u8>]),
}

impl ArrayData<'_> {
    fn len(&self) -> usize {
        match self {
            ArrayData::F32(d) => d.len(),
            ArrayData::U8(d) => d.len(),
            ArrayData::U8Planes(p) => {
                // Planes of unequal length are refused as a mismatched count.
                let n = p.first().map_or(0, |x| x.len());
                if p.iter().all(|x| x.len() == n) {
                    n * p.len()
                } else {
                    usize::MAX
                }
            }
        }
    }
}

/// An array to write: `components` interleaved values per voxel, stored as `stored`.
pub struct Array<'a> {
    pub dims: [usize; 3],
    pub affine: DMat4,
    pub space: Space,
    pub components: usize,
    /// Kind of the component axis (`vector` for 3-vectors, `list` otherwise); unused for scalars.
    pub component_kind: &'a str,
    pub stored: ScalarType,
    pub data: ArrayData<'a>,
    pub content: &'a str,
}

/// Writes one field of a volume as an attached NRRD (the stored type is kept where all values
/// fit it, else float).
pub fn write(path: &Path, vol: &Volume, field: &Field, encoding: WriteEncoding) -> Result<()> {
    let stored = if field.stored.holds_all(&field.data) {
        field.stored
    } else {
        ScalarType::F32
    };
    write_array(
        path,
        &Array {
            dims: vol.dims,
            affine: vol.affine,
            space: vol.space,
            components: field.components,
            component_kind: "vector",
            stored,
            data: ArrayData::F32(&field.data),
            content: &field.name,
        },
        encoding,
    )
}

fn vec3(v: DVec3) -> String {
    format!("({},{},{})", v.x, v.y, v.z)
}

/// Writes an array as an attached NRRD through a temporary file.
pub fn write_array(path: &Path, a: &Array, encoding: WriteEncoding) -> Result<()> {
    write_array_with(path, a, encoding, &[])
}

/// [`write_array`] with `key:=value` lines in the header (NRRD's key/value pairs, which
/// readers keep as metadata; see [`key_values`]). Keys and values may not hold a line break,
/// and keys not `:=`.
pub fn write_array_with(
    path: &Path,
    a: &Array,
    encoding: WriteEncoding,
    key_values: &[(&str, &str)],
) -> Result<()> {
    if let Some((k, v)) = key_values
        .iter()
        .find(|(k, v)| k.is_empty() || k.contains(":=") || format!("{k}{v}").contains('\n'))
    {
        return Err(VolumeError::Invalid(format!(
            "{}: the key/value pair {k:?} := {v:?} cannot be written in a NRRD header",
            path.display()
        )));
    }
    let n = a.dims[0] * a.dims[1] * a.dims[2];
    if a.data.len() != n * a.components {
        return Err(VolumeError::Invalid(format!(
            "{}: {} values for {n} voxels x {} components",
            path.display(),
            a.data.len(),
            a.components
        )));
    }
    let mut h = String::from("NRRD0005\n# written by umbra\n");
    h += &format!("type: {}\n", type_name(a.stored));
    let list = a.components > 1;
    h += &format!("dimension: {}\n", if list { 4 } else { 3 });
    if list {
        h += &format!(
            "sizes: {} {} {} {}\n",
            a.components, a.dims[0], a.dims[1], a.dims[2]
        );
    } else {
        h += &format!("sizes: {} {} {}\n", a.dims[0], a.dims[1], a.dims[2]);
    }
    match a.space {
        Space::Ras => h += "space: right-anterior-superior\n",
        Space::File => h += "space dimension: 3\n",
    }
    let cols = [
        a.affine.x_axis.truncate(),
        a.affine.y_axis.truncate(),
        a.affine.z_axis.truncate(),
    ];
    h += &format!(
        "space directions: {}{} {} {}\n",
        if list { "none " } else { "" },
        vec3(cols[0]),
        vec3(cols[1]),
        vec3(cols[2])
    );
    h += &format!(
        "kinds: {}domain domain domain\n",
        if list {
            format!("{} ", a.component_kind)
        } else {
            String::new()
        }
    );
    if !a.content.is_empty() && !a.content.contains('\n') {
        h += &format!("content: {}\n", a.content);
    }
    h += "endian: little\n";
    h += match encoding {
        WriteEncoding::Raw => "encoding: raw\n",
        WriteEncoding::Gzip => "encoding: gzip\n",
    };
    h += &format!("space origin: {}\n", vec3(a.affine.w_axis.truncate()));
    for (k, v) in key_values {
        h += &format!("{k}:={v}\n");
    }
    h += "\n";
    if matches!(a.data, ArrayData::U8(_) | ArrayData::U8Planes(_)) && a.stored != ScalarType::U8 {
        return Err(VolumeError::Invalid(format!(
            "{}: u8 data must be stored as uint8",
            path.display()
        )));
    }
    match encoding {
        // Streamed in blocks: no copy of the body is held (a 512^3 sweep writes 1.5 GB).
        WriteEncoding::Raw => io_util::write_atomic_with(path, |w| {
            std::io::Write::write_all(w, h.as_bytes())?;
            write_body(w, &a.data, a.stored)
        }),
        WriteEncoding::Gzip => {
            let mut body = Vec::new();
            write_body(&mut body, &a.data, a.stored).map_err(|e| VolumeError::io(path, e))?;
            let mut bytes = h.into_bytes();
            bytes.extend_from_slice(&io_util::gzip_bytes(&body));
            io_util::write_atomic(path, &bytes)
        }
    }
}

/// The most bytes of a header [`key_values`] reads.
pub const MAX_HEADER: usize = 1 << 20;

/// The `key:=value` pairs of a NRRD header (attached `.nrrd` or detached `.nhdr`), in order;
/// only the header is read (at most [`MAX_HEADER`] bytes of it).
pub fn key_values(path: &Path) -> Result<Vec<(String, String)>> {
    use std::io::{BufRead, Read};
    let f = std::fs::File::open(path).map_err(|e| VolumeError::io(path, e))?;
    let mut r = std::io::BufReader::new(f).take(MAX_HEADER as u64);
    let mut out = vec![];
    let mut line = Vec::new();
    loop {
        line.clear();
        let n = r
            .read_until(b'\n', &mut line)
            .map_err(|e| VolumeError::io(path, e))?;
        let text = String::from_utf8_lossy(&line);
        let text = text.trim_end_matches(['\n', '\r']);
        if n == 0 || text.is_empty() {
            return Ok(out);
        }
        if let Some((k, v)) = text.split_once(":=") {
            out.push((k.to_string(), v.to_string()));
        }
    }
}

/// Writes the samples in the stored type, block by block.
fn write_body(
    w: &mut dyn std::io::Write,
    data: &ArrayData,
    stored: ScalarType,
) -> std::io::Result<()> {
    const BLOCK: usize = 1 << 18;
    match data {
        ArrayData::F32(d) => {
            for c in d.chunks(BLOCK) {
                w.write_all(&io_util::encode_samples(c, stored, false))?;
            }
        }
        ArrayData::U8(d) => w.write_all(d)?,
        ArrayData::U8Planes(p) => {
            let n = p.first().map_or(0, |x| x.len());
            let k = p.len();
            let mut buf = vec![0u8; BLOCK * k];
            for v0 in (0..n).step_by(BLOCK) {
                let m = BLOCK.min(n - v0);
                for (v, chunk) in buf[..m * k].chunks_exact_mut(k).enumerate() {
                    for (c, plane) in chunk.iter_mut().zip(p.iter()) {
                        *c = plane[v0 + v];
                    }
                }
                w.write_all(&buf[..m * k])?;
            }
        }
    }
    Ok(())
}
