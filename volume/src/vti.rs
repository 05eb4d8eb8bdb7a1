//! VTK XML ImageData (`.vti`) reader.
//!
//! Supports `ascii`, inline `binary` (base64) and `appended` (raw or base64) data arrays,
//! `header_type` UInt32 and UInt64, both byte orders, zlib compression
//! (`vtkZLibDataCompressor`; LZ4 and LZMA are refused with an error), several pieces, and the
//! `Direction` attribute (row-major 3x3; its columns are the axis directions). Point-data arrays
//! become fields by name, the `Scalars` attribute of `PointData` picks the default; cell data is
//! skipped. The frame is the file's own.
//!
//! Base64 is decoded leniently: VTK encodes the block header and the data of a compressed array
//! as two separately padded base64 runs, so `=` padding may appear inside one text.

use crate::io_util::{self, checked_count};
use crate::{Result, ScalarType, Space, Volume, VolumeError};
use glam::{DMat3, DMat4, DVec3};
use quick_xml::events::Event;
use std::path::Path;

fn xml_type(path: &Path, field: &str, t: &str) -> Result<ScalarType> {
    Ok(match t {
        "Int8" | "Char" => ScalarType::I8,
        "UInt8" | "UChar" => ScalarType::U8,
        "Int16" => ScalarType::I16,
        "UInt16" => ScalarType::U16,
        "Int32" => ScalarType::I32,
        "UInt32" => ScalarType::U32,
        "Int64" => ScalarType::I64,
        "UInt64" => ScalarType::U64,
        "Float32" => ScalarType::F32,
        "Float64" => ScalarType::F64,
        other => {
            return Err(VolumeError::format(
                path,
                field,
                format!("type '{other}' is not supported"),
            ))
        }
    })
}

/// Decodes base64 text, ignoring whitespace and allowing padded runs to follow each other.
pub fn base64_lenient(text: &[u8]) -> std::result::Result<Vec<u8>, String> {
    fn val(c: u8) -> Option<u32> {
        Some(match c {
            b'A'..=b'Z' => c - b'A',
            b'a'..=b'z' => c - b'a' + 26,
            b'0'..=b'9' => c - b'0' + 52,
            b'+' => 62,
            b'/' => 63,
            _ => return None,
        } as u32)
    }
    let mut out = Vec::with_capacity(text.len() / 4 * 3);
    let mut quad = [0u8; 4];
    let mut n = 0;
    for (pos, &c) in text.iter().enumerate() {
        if c.is_ascii_whitespace() {
            continue;
        }
        quad[n] = c;
        n += 1;
        if n == 4 {
            n = 0;
            let pads = quad.iter().rev().take_while(|&&c| c == b'=').count();
            if pads > 2 {
                return Err(format!("bad padding at character {pos}"));
            }
            let mut acc = 0u32;
            for (i, &q) in quad.iter().enumerate() {
                let v = if i >= 4 - pads {
                    0
                } else {
                    val(q).ok_or_else(|| {
                        format!("invalid base64 character {:?} at {pos}", q as char)
                    })?
                };
                acc = (acc << 6) | v;
            }
            let bytes = [(acc >> 16) as u8, (acc >> 8) as u8, acc as u8];
            out.extend_from_slice(&bytes[..3 - pads]);
        }
    }
    if n != 0 {
        return Err(format!(
            "base64 text ends in an incomplete group of {n} characters"
        ));
    }
    Ok(out)
}

struct RawArray {
    extent: [i64; 6],
    name: String,
    ty: ScalarType,
    comps: usize,
    format: String,
    offset: Option<usize>,
    text: Vec<u8>,
}

struct Ctx<'a> {
    path: &'a Path,
    big_endian: bool,
    header_size: usize,
    compressed: bool,
}

impl Ctx<'_> {
    fn word(&self, b: &[u8]) -> u64 {
        if self.header_size == 8 {
            let a: [u8; 8] = b[..8].try_into().unwrap();
            if self.big_endian {
                u64::from_be_bytes(a)
            } else {
                u64::from_le_bytes(a)
            }
        } else {
            let a: [u8; 4] = b[..4].try_into().unwrap();
            (if self.big_endian {
                u32::from_be_bytes(a)
            } else {
                u32::from_le_bytes(a)
            }) as u64
        }
    }

    /// Decodes one binary array (header + data, compressed or not) from `bytes`.
    fn block(&self, field: &str, bytes: &[u8], nbytes: usize) -> Result<Vec<u8>> {
        let hs = self.header_size;
        let err = |m: String| VolumeError::format(self.path, field, m);
        if !self.compressed {
            if bytes.len() < hs {
                return Err(err("data ends inside the size header".into()));
            }
            let n = self.word(bytes);
            if n != nbytes as u64 {
                return Err(err(format!(
                    "size header says {n} bytes, the extent and type need {nbytes}"
                )));
            }
            return bytes
                .get(hs..hs + nbytes)
                .map(|b| b.to_vec())
                .ok_or_else(|| err(format!("{} data bytes, {nbytes} needed", bytes.len() - hs)));
        }
        if bytes.len() < 3 * hs {
            return Err(err("data ends inside the compression header".into()));
        }
        let nblocks = self.word(bytes);
        let block = self.word(&bytes[hs..]);
        let last = self.word(&bytes[2 * hs..]);
        if nblocks as usize > bytes.len() / hs {
            return Err(err(format!(
                "{nblocks} compressed blocks cannot fit in {} bytes",
                bytes.len()
            )));
        }
        let nblocks = nblocks as usize;
        let total = if nblocks == 0 {
            0
        } else {
            block * (nblocks as u64 - 1) + if last == 0 { block } else { last }
        };
        if total != nbytes as u64 {
            return Err(err(format!(
                "compressed blocks hold {total} bytes, the extent and type need {nbytes}"
            )));
        }
        let head = (3 + nblocks) * hs;
        if bytes.len() < head {
            return Err(err("data ends inside the block size table".into()));
        }
        let mut out = Vec::with_capacity(nbytes.min(bytes.len() * 8));
        let mut pos = head;
        for b in 0..nblocks {
            let csize = self.word(&bytes[(3 + b) * hs..]) as usize;
            let chunk = bytes
                .get(pos..pos.saturating_add(csize))
                .ok_or_else(|| err(format!("compressed block {b} runs past the data")))?;
            pos += csize;
            let expect = if b + 1 == nblocks && last != 0 {
                last
            } else {
                block
            } as usize;
            out.extend(io_util::inflate_zlib(
                self.path,
                field,
                chunk,
                Some(expect),
            )?);
        }
        Ok(out)
    }
}

fn attr_map(path: &Path, e: &quick_xml::events::BytesStart) -> Result<Vec<(String, String)>> {
    let mut v = Vec::new();
    for a in e.attributes() {
        let a =
            a.map_err(|err| VolumeError::format(path, "XML", format!("bad attribute: {err}")))?;
        let k = String::from_utf8_lossy(a.key.as_ref()).to_string();
        let val = a
            .unescape_value()
            .map_err(|err| VolumeError::format(path, "XML", format!("bad attribute value: {err}")))?
            .to_string();
        v.push((k, val));
    }
    Ok(v)
}

fn get<'a>(m: &'a [(String, String)], k: &str) -> Option<&'a str> {
    m.iter().find(|(key, _)| key == k).map(|(_, v)| v.as_str())
}

fn extent(path: &Path, field: &str, s: &str) -> Result<[i64; 6]> {
    let v: Vec<i64> = s
        .split_whitespace()
        .map(|t| {
            t.parse::<i64>()
                .map_err(|_| VolumeError::format(path, field, format!("'{t}' is not an integer")))
        })
        .collect::<Result<_>>()?;
    let e: [i64; 6] = v
        .try_into()
        .map_err(|_| VolumeError::format(path, field, "expected 6 integers"))?;
    for a in 0..3 {
        if e[2 * a + 1] < e[2 * a] {
            return Err(VolumeError::format(
                path,
                field,
                format!("axis {a} extent {}..{} is empty", e[2 * a], e[2 * a + 1]),
            ));
        }
        if e[2 * a].abs() > 1 << 40 || e[2 * a + 1].abs() > 1 << 40 {
            return Err(VolumeError::format(path, field, "absurd extent"));
        }
    }
    Ok(e)
}

/// Reads a `.vti` file.
pub fn read(path: &Path) -> Result<Volume> {
    let raw = io_util::read_file(path)?;
    if !raw.trim_ascii_end().ends_with(b"</VTKFile>") {
        return Err(VolumeError::format(
            path,
            "XML",
            "the file does not end with </VTKFile> (truncated?)",
        ));
    }
    let app_pos = raw.windows(13).position(|w| w == b"<AppendedData");
    let xml = &raw[..app_pos.unwrap_or(raw.len())];
    let mut reader = quick_xml::Reader::from_reader(xml);
    let mut buf = Vec::new();
    let mut file_attrs = None;
    let mut image_attrs = None;
    let mut piece_extent: Option<[i64; 6]> = None;
    let mut in_point = false;
    let mut scalars_name: Option<String> = None;
    let mut arrays: Vec<RawArray> = Vec::new();
    let mut current: Option<RawArray> = None;
    // Depth of elements nested inside the current DataArray (VTK writes <InformationKey>
    // children with range values there; their text is not array data).
    let mut nested = 0usize;
    loop {
        let ev = reader.read_event_into(&mut buf);
        let ev = match ev {
            Ok(ev) => ev,
            Err(e) => {
                if app_pos.is_some() {
                    break; // the XML part was cut at AppendedData; unclosed tags end here
                }
                return Err(VolumeError::format(
                    path,
                    "XML",
                    format!("at byte {}: {e}", reader.buffer_position()),
                ));
            }
        };
        let (ev, empty) = match ev {
            Event::Empty(e) => (Event::Start(e), true),
            other => (other, false),
        };
        match ev {
            Event::Eof => break,
            Event::Start(e) if current.is_some() => {
                if !empty {
                    nested += 1;
                }
                let _ = e;
            }
            Event::Start(e) => {
                let name = e.name().as_ref().to_vec();
                let attrs = attr_map(path, &e)?;
                match name.as_slice() {
                    b"VTKFile" => {
                        if get(&attrs, "type") != Some("ImageData") {
                            return Err(VolumeError::format(
                                path,
                                "VTKFile type",
                                format!(
                                    "{:?} is not ImageData",
                                    get(&attrs, "type").unwrap_or("missing")
                                ),
                            ));
                        }
                        file_attrs = Some(attrs);
                    }
                    b"ImageData" => image_attrs = Some(attrs),
                    b"Piece" => {
                        piece_extent = Some(extent(
                            path,
                            "Piece Extent",
                            get(&attrs, "Extent").ok_or_else(|| {
                                VolumeError::format(path, "Piece Extent", "missing")
                            })?,
                        )?);
                    }
                    b"PointData" => {
                        in_point = true;
                        scalars_name = scalars_name.or(get(&attrs, "Scalars").map(str::to_string));
                    }
                    b"CellData" => in_point = false,
                    b"DataArray" if in_point => {
                        let name = get(&attrs, "Name").unwrap_or("data").to_string();
                        let field = format!("DataArray {name}");
                        let ty = xml_type(
                            path,
                            &field,
                            get(&attrs, "type")
                                .ok_or_else(|| VolumeError::format(path, &field, "missing type"))?,
                        )?;
                        let comps: usize = get(&attrs, "NumberOfComponents")
                            .map(|s| {
                                s.parse().map_err(|_| {
                                    VolumeError::format(path, &field, "bad NumberOfComponents")
                                })
                            })
                            .transpose()?
                            .unwrap_or(1);
                        if !(1..=64).contains(&comps) {
                            return Err(VolumeError::format(
                                path,
                                &field,
                                format!("{comps} components"),
                            ));
                        }
                        let offset = get(&attrs, "offset")
                            .map(|s| {
                                s.parse::<usize>()
                                    .map_err(|_| VolumeError::format(path, &field, "bad offset"))
                            })
                            .transpose()?;
                        let ext = piece_extent.ok_or_else(|| {
                            VolumeError::format(path, &field, "DataArray outside a Piece")
                        })?;
                        let arr = RawArray {
                            extent: ext,
                            name,
                            ty,
                            comps,
                            format: get(&attrs, "format").unwrap_or("ascii").to_string(),
                            offset,
                            text: Vec::new(),
                        };
                        if empty {
                            arrays.push(arr);
                        } else {
                            current = Some(arr);
                        }
                    }
                    _ => {}
                }
            }
            Event::Text(t) if nested == 0 => {
                if let Some(c) = current.as_mut() {
                    c.text.extend_from_slice(t.as_ref());
                }
            }
            Event::End(_) if nested > 0 => nested -= 1,
            Event::End(e) => match e.name().as_ref() {
                b"DataArray" => {
                    if let Some(c) = current.take() {
                        arrays.push(c);
                    }
                }
                b"PointData" => in_point = false,
                _ => {}
            },
            _ => {}
        }
        buf.clear();
    }
    let file_attrs =
        file_attrs.ok_or_else(|| VolumeError::format(path, "VTKFile", "no VTKFile element"))?;
    let image = image_attrs
        .ok_or_else(|| VolumeError::format(path, "ImageData", "no ImageData element"))?;
    let big_endian = match get(&file_attrs, "byte_order") {
        Some("BigEndian") => true,
        Some("LittleEndian") | None => false,
        Some(o) => return Err(VolumeError::format(path, "byte_order", format!("'{o}'"))),
    };
    let header_size = match get(&file_attrs, "header_type") {
        None | Some("UInt32") => 4,
        Some("UInt64") => 8,
        Some(o) => {
            return Err(VolumeError::format(
                path,
                "header_type",
                format!("'{o}' is not UInt32 or UInt64"),
            ))
        }
    };
    let compressed = match get(&file_attrs, "compressor") {
        None | Some("") => false,
        Some("vtkZLibDataCompressor") => true,
        Some(o) => {
            return Err(VolumeError::format(
                path,
                "compressor",
                format!("'{o}' is not supported (zlib is)"),
            ))
        }
    };
    let ctx = Ctx {
        path,
        big_endian,
        header_size,
        compressed,
    };
    let whole = extent(
        path,
        "WholeExtent",
        get(&image, "WholeExtent")
            .ok_or_else(|| VolumeError::format(path, "WholeExtent", "missing"))?,
    )?;
    let origin = match get(&image, "Origin") {
        Some(s) => io_util::parse_n_floats(path, "Origin", s, 3)?,
        None => vec![0.0; 3],
    };
    let spacing = match get(&image, "Spacing") {
        Some(s) => io_util::parse_n_floats(path, "Spacing", s, 3)?,
        None => vec![1.0; 3],
    };
    if spacing.contains(&0.0) {
        return Err(VolumeError::format(path, "Spacing", "a spacing of 0"));
    }
    let dir = match get(&image, "Direction") {
        Some(s) => io_util::parse_n_floats(path, "Direction", s, 9)?,
        None => vec![1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
    };
    let d = DMat3::from_cols(
        DVec3::new(dir[0], dir[3], dir[6]),
        DVec3::new(dir[1], dir[4], dir[7]),
        DVec3::new(dir[2], dir[5], dir[8]),
    );
    let m3 = d * DMat3::from_diagonal(DVec3::new(spacing[0], spacing[1], spacing[2]));
    if m3.determinant().abs() < 1e-12 {
        return Err(VolumeError::format(
            path,
            "Direction",
            "degenerate axis directions",
        ));
    }
    let o = DVec3::new(origin[0], origin[1], origin[2])
        + m3 * DVec3::new(whole[0] as f64, whole[2] as f64, whole[4] as f64);
    let affine = DMat4::from_cols(
        m3.x_axis.extend(0.0),
        m3.y_axis.extend(0.0),
        m3.z_axis.extend(0.0),
        o.extend(1.0),
    );
    let wd = [
        whole[1] - whole[0] + 1,
        whole[3] - whole[2] + 1,
        whole[5] - whole[4] + 1,
    ];
    let wcount = checked_count(path, "WholeExtent", &wd)?;
    // Appended section.
    let appended: Option<(&[u8], bool)> = match app_pos {
        None => None,
        Some(p) => {
            let rest = &raw[p..];
            let tag_end = rest
                .iter()
                .position(|&b| b == b'>')
                .ok_or_else(|| VolumeError::format(path, "AppendedData", "unterminated tag"))?;
            let tag = String::from_utf8_lossy(&rest[..tag_end]);
            let base64 = tag.contains("\"base64\"");
            let after = &rest[tag_end + 1..];
            let us = after
                .iter()
                .position(|&b| b == b'_')
                .ok_or_else(|| VolumeError::format(path, "AppendedData", "no '_' marker"))?;
            Some((&after[us + 1..], base64))
        }
    };
    // Decode every array of every piece.
    let mut decoded: Vec<(RawArray, Vec<f32>)> = Vec::new();
    for a in arrays {
        let field = format!("DataArray {}", a.name);
        let pd = [
            a.extent[1] - a.extent[0] + 1,
            a.extent[3] - a.extent[2] + 1,
            a.extent[5] - a.extent[4] + 1,
        ];
        for ax in 0..3 {
            if a.extent[2 * ax] < whole[2 * ax] || a.extent[2 * ax + 1] > whole[2 * ax + 1] {
                return Err(VolumeError::format(
                    path,
                    "Piece Extent",
                    "piece lies outside WholeExtent",
                ));
            }
        }
        let count = checked_count(path, &field, &pd)? * a.comps;
        let nbytes = count * a.ty.size();
        let values = match a.format.as_str() {
            "ascii" => {
                let (v, used) = io_util::parse_ascii(path, &field, &a.text, count)?;
                if a.text[used..].iter().any(|b| !b.is_ascii_whitespace()) {
                    return Err(VolumeError::format(
                        path,
                        &field,
                        format!("more than {count} values"),
                    ));
                }
                v
            }
            "binary" => {
                let bytes =
                    base64_lenient(&a.text).map_err(|m| VolumeError::format(path, &field, m))?;
                let data = ctx.block(&field, &bytes, nbytes)?;
                io_util::decode_samples(&data, a.ty, big_endian)
            }
            "appended" => {
                let (app, b64) = appended.ok_or_else(|| {
                    VolumeError::format(path, &field, "format appended but no AppendedData")
                })?;
                let off = a.offset.ok_or_else(|| {
                    VolumeError::format(path, &field, "appended array without offset")
                })?;
                let start = app.get(off..).ok_or_else(|| {
                    VolumeError::format(
                        path,
                        &field,
                        format!("offset {off} is past the appended data"),
                    )
                })?;
                let bytes: std::borrow::Cow<[u8]> = if b64 {
                    let end = start.iter().position(|&b| b == b'<').unwrap_or(start.len());
                    std::borrow::Cow::Owned(
                        base64_lenient(&start[..end])
                            .map_err(|m| VolumeError::format(path, &field, m))?,
                    )
                } else {
                    std::borrow::Cow::Borrowed(start)
                };
                let data = ctx.block(&field, &bytes, nbytes)?;
                io_util::decode_samples(&data, a.ty, big_endian)
            }
            other => {
                return Err(VolumeError::format(
                    path,
                    &field,
                    format!("format '{other}' is not ascii, binary or appended"),
                ))
            }
        };
        decoded.push((a, values));
    }
    if decoded.is_empty() {
        return Err(VolumeError::format(
            path,
            "PointData",
            "no point data arrays",
        ));
    }
    // Assemble pieces into whole-extent fields.
    let mut names: Vec<String> = Vec::new();
    for (a, _) in &decoded {
        if !names.contains(&a.name) {
            names.push(a.name.clone());
        }
    }
    let mut fields = Vec::new();
    let mut default_field = 0;
    for name in names {
        let parts: Vec<&(RawArray, Vec<f32>)> =
            decoded.iter().filter(|(a, _)| a.name == name).collect();
        let comps = parts[0].0.comps;
        let ty = parts[0].0.ty;
        let have: usize = parts.iter().map(|(_, v)| v.len()).sum();
        if parts.iter().any(|(a, _)| a.comps != comps) || have < wcount * comps {
            return Err(VolumeError::format(
                path,
                format!("DataArray {name}"),
                "pieces do not cover WholeExtent consistently",
            ));
        }
        let data = if parts.len() == 1 {
            parts[0].1.clone()
        } else {
            let mut out = vec![f32::NAN; wcount * comps];
            for (a, v) in &parts {
                let e = a.extent;
                let (px, py) = ((e[1] - e[0] + 1) as usize, (e[3] - e[2] + 1) as usize);
                for (n, chunk) in v.chunks_exact(comps).enumerate() {
                    let (i, j, k) = (n % px, (n / px) % py, n / (px * py));
                    let gi = (e[0] - whole[0]) as usize + i;
                    let gj = (e[2] - whole[2]) as usize + j;
                    let gk = (e[4] - whole[4]) as usize + k;
                    let g = gi + wd[0] as usize * (gj + wd[1] as usize * gk);
                    out[g * comps..(g + 1) * comps].copy_from_slice(chunk);
                }
            }
            out
        };
        if Some(&name) == scalars_name.as_ref() {
            default_field = fields.len();
        }
        crate::vtk_legacy::push_field(&mut fields, name, comps, ty, data);
    }
    Ok(Volume {
        format: "vti".into(),
        dims: [wd[0] as usize, wd[1] as usize, wd[2] as usize],
        affine,
        space: Space::File,
        fields,
        default_field,
        warnings: vec![],
    })
}
