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

use crate::cfd_grid::{Cell, CfdGrid, Geometry, GridArray};
use crate::io_util::{self, checked_count};
use crate::vtk_common;
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
    section: Section,
    piece: usize,
    extent: Option<[i64; 6]>,
    /// Tuples the array must hold, when the piece says (None: as many as the data hold).
    tuples: Option<usize>,
    name: String,
    ty: ScalarType,
    comps: usize,
    format: String,
    offset: Option<usize>,
    text: Vec<u8>,
}

/// Where a DataArray sits in a VTK XML file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Section {
    PointData,
    CellData,
    Points,
    Coordinates,
    Cells,
}

/// A decoded DataArray.
#[derive(Clone, Debug)]
pub struct XmlArray {
    pub section: Section,
    pub piece: usize,
    /// The piece's extent (structured kinds).
    pub extent: Option<[i64; 6]>,
    pub name: String,
    pub ty: ScalarType,
    pub comps: usize,
    pub values: Vec<f32>,
}

/// A parsed VTK XML file.
#[derive(Clone, Debug)]
pub struct XmlDoc {
    /// `ImageData`, `RectilinearGrid`, `StructuredGrid` or `UnstructuredGrid`.
    pub kind: String,
    /// Attributes of the dataset element (WholeExtent, Origin, Spacing, ...).
    pub dataset: Vec<(String, String)>,
    /// Attributes of each Piece.
    pub pieces: Vec<Vec<(String, String)>>,
    pub arrays: Vec<XmlArray>,
    /// The `Scalars` attribute of PointData.
    pub scalars: Option<String>,
}

impl XmlDoc {
    pub fn attr(&self, k: &str) -> Option<&str> {
        get(&self.dataset, k)
    }
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

    /// Decodes one binary array (header + data, compressed or not) from `bytes`; with
    /// `expected`, the size the header states must be that.
    fn block(&self, field: &str, bytes: &[u8], expected: Option<usize>) -> Result<Vec<u8>> {
        let hs = self.header_size;
        let err = |m: String| VolumeError::format(self.path, field, m);
        if !self.compressed {
            if bytes.len() < hs {
                return Err(err("data ends inside the size header".into()));
            }
            let n = self.word(bytes);
            if let Some(nbytes) = expected {
                if n != nbytes as u64 {
                    return Err(err(format!(
                        "size header says {n} bytes, the extent and type need {nbytes}"
                    )));
                }
            }
            let n = usize::try_from(n).map_err(|_| err("absurd size".into()))?;
            return bytes
                .get(hs..hs.saturating_add(n))
                .map(|b| b.to_vec())
                .ok_or_else(|| err(format!("{} data bytes, {n} needed", bytes.len() - hs)));
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
            block
                .saturating_mul(nblocks as u64 - 1)
                .saturating_add(if last == 0 { block } else { last })
        };
        if let Some(nbytes) = expected {
            if total != nbytes as u64 {
                return Err(err(format!(
                    "compressed blocks hold {total} bytes, the extent and type need {nbytes}"
                )));
            }
        }
        let head = (3 + nblocks) * hs;
        if bytes.len() < head {
            return Err(err("data ends inside the block size table".into()));
        }
        let mut out = Vec::with_capacity((total as usize).min(bytes.len().saturating_mul(8)));
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
    let mut v: Vec<(String, String)> = Vec::new();
    // quick-xml's duplicate check is quadratic in the attribute count; VTK elements have a
    // handful, so more than 64 is refused and duplicates are found here.
    for a in e.attributes().with_checks(false) {
        if v.len() == 64 {
            return Err(VolumeError::format(
                path,
                "XML",
                "an element with more than 64 attributes (VTK's have a dozen at most)",
            ));
        }
        let a =
            a.map_err(|err| VolumeError::format(path, "XML", format!("bad attribute: {err}")))?;
        let k = String::from_utf8_lossy(a.key.as_ref()).to_string();
        let val = a
            .unescape_value()
            .map_err(|err| VolumeError::format(path, "XML", format!("bad attribute value: {err}")))?
            .to_string();
        if v.iter().any(|(key, _)| *key == k) {
            return Err(VolumeError::format(
                path,
                "XML",
                format!("attribute '{}' repeated", io_util::clip_text(&k, 40)),
            ));
        }
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

/// Parses a VTK XML file of one of `kinds` and decodes all its DataArrays (point and cell
/// data, points, coordinates and cells), checking each against the size its piece implies.
pub fn parse_xml(path: &Path, kinds: &[&str]) -> Result<XmlDoc> {
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
    let mut kind = String::new();
    let mut dataset: Option<Vec<(String, String)>> = None;
    let mut pieces: Vec<Vec<(String, String)>> = Vec::new();
    let mut piece_extent: Option<[i64; 6]> = None;
    let mut section: Option<Section> = None;
    let mut coordinate = 0usize;
    let mut scalars_name: Option<String> = None;
    let mut arrays: Vec<RawArray> = Vec::new();
    let mut current: Option<RawArray> = None;
    // Depth of elements nested inside the current DataArray (VTK writes <InformationKey>
    // children with range values there; their text is not array data).
    let mut nested = 0usize;
    let count_attr = |attrs: &[(String, String)], k: &str| -> Result<Option<usize>> {
        get(attrs, k)
            .map(|v| {
                v.trim()
                    .parse::<usize>()
                    .ok()
                    .filter(|&n| n as u64 <= io_util::MAX_SAMPLES)
                    .ok_or_else(|| {
                        VolumeError::format(
                            path,
                            format!("Piece {k}"),
                            format!("'{v}' is not a count"),
                        )
                    })
            })
            .transpose()
    };
    loop {
        let ev = match reader.read_event_into(&mut buf) {
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
            Event::Start(_) if current.is_some() && !empty => nested += 1,
            Event::Start(_) if current.is_some() => {}
            Event::Start(e) => {
                let name = e.name().as_ref().to_vec();
                let attrs = attr_map(path, &e)?;
                match name.as_slice() {
                    b"VTKFile" => {
                        let t = get(&attrs, "type").unwrap_or("missing").to_string();
                        if !kinds.contains(&t.as_str()) {
                            return Err(VolumeError::format(
                                path,
                                "VTKFile type",
                                format!("{t:?} is not {}", kinds.join(" or ")),
                            ));
                        }
                        kind = t;
                        file_attrs = Some(attrs);
                    }
                    n if n == kind.as_bytes() && !kind.is_empty() => dataset = Some(attrs),
                    b"Piece" => {
                        piece_extent = get(&attrs, "Extent")
                            .map(|x| extent(path, "Piece Extent", x))
                            .transpose()?;
                        pieces.push(attrs);
                    }
                    b"PointData" => {
                        section = Some(Section::PointData);
                        scalars_name = scalars_name.or(get(&attrs, "Scalars").map(str::to_string));
                    }
                    b"CellData" => section = Some(Section::CellData),
                    b"Points" => section = Some(Section::Points),
                    b"Coordinates" => {
                        section = Some(Section::Coordinates);
                        coordinate = 0;
                    }
                    b"Cells" => section = Some(Section::Cells),
                    b"DataArray" if section.is_some() && !pieces.is_empty() => {
                        let sec = section.unwrap();
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
                        let piece = pieces.len() - 1;
                        let pattrs = &pieces[piece];
                        // Tuples implied by the piece.
                        let span = |e: [i64; 6], a: usize| {
                            e[2 * a + 1].saturating_sub(e[2 * a]).saturating_add(1)
                        };
                        let tuples = match (sec, piece_extent) {
                            (Section::PointData | Section::Points, Some(e)) => {
                                Some(io_util::checked_count(
                                    path,
                                    "Piece Extent",
                                    &[0, 1, 2].map(|a| span(e, a)),
                                )?)
                            }
                            (Section::CellData, Some(e)) => Some(io_util::checked_count(
                                path,
                                "Piece Extent",
                                &[0, 1, 2].map(|a| (span(e, a) - 1).max(1)),
                            )?),
                            (Section::Coordinates, Some(e)) => {
                                coordinate += 1;
                                Some(io_util::checked_count(
                                    path,
                                    "Piece Extent",
                                    &[span(e, (coordinate - 1).min(2))],
                                )?)
                            }
                            (Section::PointData | Section::Points, None) => {
                                count_attr(pattrs, "NumberOfPoints")?
                            }
                            (Section::CellData, None) => count_attr(pattrs, "NumberOfCells")?,
                            _ => None,
                        };
                        let arr = RawArray {
                            section: sec,
                            piece,
                            extent: piece_extent,
                            tuples,
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
                b"PointData" | b"CellData" | b"Points" | b"Coordinates" | b"Cells" => {
                    section = None
                }
                _ => {}
            },
            _ => {}
        }
        buf.clear();
    }
    let file_attrs =
        file_attrs.ok_or_else(|| VolumeError::format(path, "VTKFile", "no VTKFile element"))?;
    let dataset =
        dataset.ok_or_else(|| VolumeError::format(path, &kind, format!("no {kind} element")))?;
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
    let mut out = Vec::with_capacity(arrays.len());
    for a in arrays {
        let field = format!("DataArray {}", a.name);
        let count = a
            .tuples
            .map(|t| {
                t.checked_mul(a.comps)
                    .filter(|&n| n as u64 <= io_util::MAX_SAMPLES)
                    .ok_or_else(|| VolumeError::format(path, &field, "too large"))
            })
            .transpose()?;
        let nbytes = count.map(|c| c * a.ty.size());
        let values = match a.format.as_str() {
            "ascii" => match count {
                Some(count) => {
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
                None => {
                    let n = a
                        .text
                        .split(|b| b.is_ascii_whitespace())
                        .filter(|t| !t.is_empty())
                        .count();
                    io_util::parse_ascii(path, &field, &a.text, n)?.0
                }
            },
            "binary" => {
                let bytes =
                    base64_lenient(&a.text).map_err(|m| VolumeError::format(path, &field, m))?;
                let data = ctx.block(&field, &bytes, nbytes)?;
                io_util::decode_samples(
                    path,
                    &field,
                    &data[..data.len() / a.ty.size() * a.ty.size()],
                    a.ty,
                    big_endian,
                )?
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
                io_util::decode_samples(
                    path,
                    &field,
                    &data[..data.len() / a.ty.size() * a.ty.size()],
                    a.ty,
                    big_endian,
                )?
            }
            other => {
                return Err(VolumeError::format(
                    path,
                    &field,
                    format!("format '{other}' is not ascii, binary or appended"),
                ))
            }
        };
        if values.len() % a.comps != 0 {
            return Err(VolumeError::format(
                path,
                &field,
                format!(
                    "{} values are not whole {}-component tuples",
                    values.len(),
                    a.comps
                ),
            ));
        }
        out.push(XmlArray {
            section: a.section,
            piece: a.piece,
            extent: a.extent,
            name: a.name,
            ty: a.ty,
            comps: a.comps,
            values,
        });
    }
    Ok(XmlDoc {
        kind,
        dataset,
        pieces,
        arrays: out,
        scalars: scalars_name,
    })
}

/// Reads a `.vti` file.
pub fn read(path: &Path) -> Result<Volume> {
    let doc = parse_xml(path, &["ImageData"])?;
    let image = &doc.dataset;
    let whole = extent(
        path,
        "WholeExtent",
        get(image, "WholeExtent")
            .ok_or_else(|| VolumeError::format(path, "WholeExtent", "missing"))?,
    )?;
    let origin = match get(image, "Origin") {
        Some(s) => io_util::parse_n_floats(path, "Origin", s, 3)?,
        None => vec![0.0; 3],
    };
    let spacing = match get(image, "Spacing") {
        Some(s) => io_util::parse_n_floats(path, "Spacing", s, 3)?,
        None => vec![1.0; 3],
    };
    if spacing.contains(&0.0) {
        return Err(VolumeError::format(path, "Spacing", "a spacing of 0"));
    }
    let dir = match get(image, "Direction") {
        Some(s) => io_util::parse_n_floats(path, "Direction", s, 9)?,
        None => vec![1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
    };
    let d = DMat3::from_cols(
        DVec3::new(dir[0], dir[3], dir[6]),
        DVec3::new(dir[1], dir[4], dir[7]),
        DVec3::new(dir[2], dir[5], dir[8]),
    );
    let m3 = d * DMat3::from_diagonal(DVec3::new(spacing[0], spacing[1], spacing[2]));
    if crate::io_util::degenerate_axes(m3) {
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
    let decoded: Vec<&XmlArray> = doc
        .arrays
        .iter()
        .filter(|a| a.section == Section::PointData)
        .collect();
    for a in &decoded {
        let e = a
            .extent
            .ok_or_else(|| VolumeError::format(path, "Piece Extent", "missing"))?;
        for ax in 0..3 {
            if e[2 * ax] < whole[2 * ax] || e[2 * ax + 1] > whole[2 * ax + 1] {
                return Err(VolumeError::format(
                    path,
                    "Piece Extent",
                    "piece lies outside WholeExtent",
                ));
            }
        }
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
    for a in &decoded {
        if !names.contains(&a.name) {
            names.push(a.name.clone());
        }
    }
    let mut fields = Vec::new();
    let mut default_field = 0;
    for name in names {
        let parts: Vec<&&XmlArray> = decoded.iter().filter(|a| a.name == name).collect();
        let comps = parts[0].comps;
        let ty = parts[0].ty;
        let have: usize = parts.iter().map(|a| a.values.len()).sum();
        if parts.iter().any(|a| a.comps != comps) || have < wcount * comps {
            return Err(VolumeError::format(
                path,
                format!("DataArray {name}"),
                "pieces do not cover WholeExtent consistently",
            ));
        }
        let data = if parts.len() == 1 {
            parts[0].values.clone()
        } else {
            let mut out = vec![f32::NAN; wcount * comps];
            // Pieces share their boundary points; a point no piece covers is a gap (a piece
            // overlapping another more than that can hide one from the value count).
            let mut covered = vec![false; wcount];
            for a in &parts {
                let e = a.extent.unwrap();
                let (px, py) = ((e[1] - e[0] + 1) as usize, (e[3] - e[2] + 1) as usize);
                for (n, chunk) in a.values.chunks_exact(comps).enumerate() {
                    let (i, j, k) = (n % px, (n / px) % py, n / (px * py));
                    let gi = (e[0] - whole[0]) as usize + i;
                    let gj = (e[2] - whole[2]) as usize + j;
                    let gk = (e[4] - whole[4]) as usize + k;
                    let g = gi + wd[0] as usize * (gj + wd[1] as usize * gk);
                    out[g * comps..(g + 1) * comps].copy_from_slice(chunk);
                    covered[g] = true;
                }
            }
            let gaps = covered.iter().filter(|&&c| !c).count();
            if gaps > 0 {
                return Err(VolumeError::format(
                    path,
                    format!("DataArray {name}"),
                    format!(
                        "the pieces leave {gaps} of the WholeExtent's {wcount} points uncovered"
                    ),
                ));
            }
            out
        };
        if Some(&name) == doc.scalars.as_ref() {
            default_field = fields.len();
        }
        vtk_common::push_field(&mut fields, name, comps, ty, data);
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

/// Reads a VTK XML grid: `.vtr` (RectilinearGrid), `.vts` (StructuredGrid) or `.vtu`
/// (UnstructuredGrid), one piece. Unstructured cells: tetrahedra (VTK type 10), hexahedra (12),
/// voxels (11, reordered to hexahedra), wedges (13, split into 3 tetrahedra), pyramids (14,
/// split into 2), and the quadratic tetrahedron and hexahedron (24, 25; their corner nodes).
/// Split cells repeat their cell data. Other cell types (2D cells, polyhedra) are refused.
pub fn read_grid(path: &Path) -> Result<CfdGrid> {
    let doc = parse_xml(
        path,
        &["RectilinearGrid", "StructuredGrid", "UnstructuredGrid"],
    )?;
    if doc.pieces.len() != 1 {
        return Err(VolumeError::format(
            path,
            "Piece",
            format!(
                "{} pieces; umbra reads single-piece grids",
                doc.pieces.len()
            ),
        ));
    }
    let section = |s: Section| doc.arrays.iter().filter(move |a| a.section == s);
    let piece_dims = || -> Result<[usize; 3]> {
        let e = doc
            .arrays
            .iter()
            .find_map(|a| a.extent)
            .or_else(|| get(&doc.pieces[0], "Extent").and_then(|s| extent(path, "Extent", s).ok()))
            .ok_or_else(|| VolumeError::format(path, "Piece Extent", "missing"))?;
        Ok([0, 1, 2].map(|a| (e[2 * a + 1] - e[2 * a] + 1).max(1) as usize))
    };
    let (geometry, cell_origin) = match doc.kind.as_str() {
        "RectilinearGrid" => {
            let c: Vec<&XmlArray> = section(Section::Coordinates).collect();
            if c.len() != 3 || c.iter().any(|a| a.comps != 1) {
                return Err(VolumeError::format(
                    path,
                    "Coordinates",
                    format!("{} arrays; three 1-component arrays needed", c.len()),
                ));
            }
            let dims = piece_dims()?;
            for (a, arr) in c.iter().enumerate() {
                if arr.values.len() != dims[a] {
                    return Err(VolumeError::format(
                        path,
                        "Coordinates",
                        format!(
                            "axis {a}: {} values, the extent gives {}",
                            arr.values.len(),
                            dims[a]
                        ),
                    ));
                }
            }
            let axis = |a: usize| c[a].values.iter().map(|&v| v as f64).collect();
            (
                Geometry::Rectilinear {
                    x: axis(0),
                    y: axis(1),
                    z: axis(2),
                },
                None,
            )
        }
        kind => {
            let p = section(Section::Points)
                .next()
                .ok_or_else(|| VolumeError::format(path, "Points", "missing"))?;
            if p.comps != 3 {
                return Err(VolumeError::format(
                    path,
                    "Points",
                    format!("{} components, 3 needed", p.comps),
                ));
            }
            let points: Vec<DVec3> = p
                .values
                .chunks_exact(3)
                .map(|c| DVec3::new(c[0] as f64, c[1] as f64, c[2] as f64))
                .collect();
            if kind == "StructuredGrid" {
                (
                    Geometry::Structured {
                        dims: piece_dims()?,
                        points,
                    },
                    None,
                )
            } else {
                let (cells, origin) = unstructured_cells(path, &doc, points.len())?;
                (Geometry::Unstructured { points, cells }, Some(origin))
            }
        }
    };
    let mut arrays = Vec::new();
    for a in doc.arrays.iter() {
        let on_cells = match a.section {
            Section::PointData => false,
            Section::CellData => true,
            _ => continue,
        };
        let data = match (&cell_origin, on_cells) {
            (Some(origin), true) => {
                let n = a.values.len() / a.comps.max(1);
                let mut d = Vec::with_capacity(origin.len() * a.comps);
                for &o in origin {
                    if o >= n {
                        return Err(VolumeError::format(
                            path,
                            format!("CellData {}", a.name),
                            format!("{n} tuples for more cells"),
                        ));
                    }
                    d.extend_from_slice(&a.values[o * a.comps..(o + 1) * a.comps]);
                }
                d
            }
            _ => a.values.clone(),
        };
        arrays.push(GridArray {
            name: a.name.clone(),
            components: a.comps,
            on_cells,
            data,
        });
    }
    let grid = CfdGrid {
        format: match doc.kind.as_str() {
            "RectilinearGrid" => "vtr",
            "StructuredGrid" => "vts",
            _ => "vtu",
        }
        .into(),
        geometry,
        arrays,
    };
    grid.validate(path)?;
    Ok(grid)
}

/// Converts VTU connectivity into tetrahedra and hexahedra, with each output cell's source
/// cell index.
fn unstructured_cells(
    path: &Path,
    doc: &XmlDoc,
    npoints: usize,
) -> Result<(Vec<Cell>, Vec<usize>)> {
    // Ids pass through f32 in XmlArray; they are exact below 2^24.
    if npoints > 1 << 24 {
        return Err(VolumeError::format(
            path,
            "Points",
            format!("{npoints} points; umbra reads unstructured grids up to 2^24 points"),
        ));
    }
    let get_cells = |name: &str| {
        doc.arrays
            .iter()
            .find(|a| a.section == Section::Cells && a.name == name)
            .map(|a| &a.values)
            .ok_or_else(|| VolumeError::format(path, format!("Cells {name}"), "missing"))
    };
    let conn = get_cells("connectivity")?;
    let offsets = get_cells("offsets")?;
    let types = get_cells("types")?;
    vtk_common::cells_from_vtk(path, conn, offsets, types)
}
