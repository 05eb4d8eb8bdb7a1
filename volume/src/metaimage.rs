//! MetaImage (`.mhd` header + data file, `.mha` with the data attached) reader.
//!
//! Keys (case-insensitive): `NDims` (2 or 3), `DimSize`, `ElementSpacing` (else `ElementSize`,
//! else 1), `Offset`/`Position`/`Origin`, `TransformMatrix`/`Rotation`/`Orientation` (as ITK
//! reads it: the i-th group of three numbers is the direction of axis i),
//! `ElementType` (`MET_UCHAR` ... `MET_DOUBLE`), `ElementNumberOfChannels` (1 or 3),
//! `ElementByteOrderMSB`/`BinaryDataByteOrderMSB`, `CompressedData` (zlib), `HeaderSize`
//! (-1: the data are the last bytes of the file), `ElementDataFile` (`LOCAL` or a file name;
//! lists and patterns are refused).
//!
//! Frame: MetaImage is ITK's format and ITK's physical space is LPS. A file that states an
//! `AnatomicalOrientation` is therefore read as LPS and converted to RAS+ (x and y negated,
//! vector components too); a file without it (VTK's writer, for one, never writes it) keeps its
//! own frame (`space: file`).

use crate::io_util::{self, checked_count, take_samples};
use crate::samples::Samples;
use crate::{Result, ScalarType, Space, Volume, VolumeError};
use glam::{DMat3, DMat4, DVec3};
use std::path::{Path, PathBuf};

fn met_type(path: &Path, s: &str) -> Result<ScalarType> {
    Ok(match s.trim().to_ascii_uppercase().as_str() {
        "MET_UCHAR" => ScalarType::U8,
        "MET_CHAR" => ScalarType::I8,
        "MET_USHORT" => ScalarType::U16,
        "MET_SHORT" => ScalarType::I16,
        "MET_UINT" | "MET_ULONG" => ScalarType::U32,
        "MET_INT" | "MET_LONG" => ScalarType::I32,
        "MET_ULONG_LONG" => ScalarType::U64,
        "MET_LONG_LONG" => ScalarType::I64,
        "MET_FLOAT" => ScalarType::F32,
        "MET_DOUBLE" => ScalarType::F64,
        other => {
            return Err(VolumeError::format(
                path,
                "ElementType",
                format!("'{other}' is not supported"),
            ))
        }
    })
}

fn boolean(path: &Path, key: &str, s: &str) -> Result<bool> {
    match s.trim().to_ascii_lowercase().as_str() {
        "true" | "1" => Ok(true),
        "false" | "0" => Ok(false),
        other => Err(VolumeError::format(
            path,
            key,
            format!("'{other}' is not True or False"),
        )),
    }
}

/// Reads a `.mhd` or `.mha` file.
pub fn read(path: &Path) -> Result<Volume> {
    read_as(path, false).map(|(v, _)| v)
}

/// [`read`] keeping a scalar image of 8 or 16-bit integers in its stored type: the samples
/// are returned beside the volume, whose field then has no `f32` data (`None`: the image is
/// not such, its samples are in the volume as `f32`).
pub(crate) fn read_stored(path: &Path) -> Result<(Volume, Option<Samples>)> {
    read_as(path, true)
}

fn read_as(path: &Path, keep_stored: bool) -> Result<(Volume, Option<Samples>)> {
    let mut raw = io_util::read_file(path)?;
    let mut cur = io_util::Cursor::new(&raw);
    let mut kv: Vec<(String, String)> = Vec::new();
    let mut data_start = None;
    while let Some(line) = cur.line() {
        let line = std::str::from_utf8(line)
            .map_err(|_| VolumeError::format(path, "header", "header line is not text"))?;
        if line.trim().is_empty() {
            continue;
        }
        let Some((k, v)) = line.split_once('=') else {
            return Err(VolumeError::format(
                path,
                "header",
                format!(
                    "line '{}' is not 'Key = Value'",
                    line.chars().take(60).collect::<String>()
                ),
            ));
        };
        let k = k.trim().to_ascii_lowercase();
        let last = k == "elementdatafile";
        kv.push((k, v.trim().to_string()));
        if last {
            data_start = Some(cur.pos);
            break;
        }
    }
    let get = |k: &str| kv.iter().find(|(key, _)| key == k).map(|(_, v)| v.as_str());
    let data_file = get("elementdatafile").ok_or_else(|| {
        VolumeError::format(
            path,
            "ElementDataFile",
            "missing (it must be the last header key)",
        )
    })?;
    let ndims: usize = get("ndims")
        .ok_or_else(|| VolumeError::format(path, "NDims", "missing"))?
        .parse()
        .map_err(|_| VolumeError::format(path, "NDims", "not an integer"))?;
    if !(2..=3).contains(&ndims) {
        return Err(VolumeError::format(
            path,
            "NDims",
            format!("{ndims}: umbra reads 2-D and 3-D images"),
        ));
    }
    let sizes = io_util::parse_sizes(
        path,
        "DimSize",
        get("dimsize").ok_or_else(|| VolumeError::format(path, "DimSize", "missing"))?,
        ndims,
    )?;
    let ty = met_type(
        path,
        get("elementtype").ok_or_else(|| VolumeError::format(path, "ElementType", "missing"))?,
    )?;
    let channels: usize = get("elementnumberofchannels")
        .map(|s| {
            s.parse()
                .map_err(|_| VolumeError::format(path, "ElementNumberOfChannels", "not an integer"))
        })
        .transpose()?
        .unwrap_or(1);
    if !(1..=64).contains(&channels) {
        return Err(VolumeError::format(
            path,
            "ElementNumberOfChannels",
            format!("{channels}"),
        ));
    }
    let big_endian = match get("elementbyteordermsb").or(get("binarydatabyteordermsb")) {
        Some(s) => boolean(path, "ElementByteOrderMSB", s)?,
        None => false,
    };
    let compressed = get("compresseddata")
        .map(|s| boolean(path, "CompressedData", s))
        .transpose()?
        .unwrap_or(false);
    let mut sp = vec![1.0; ndims];
    if let Some(s) = get("elementspacing").or(get("elementsize")) {
        sp = io_util::parse_n_floats(path, "ElementSpacing", s, ndims)?;
    }
    let mut origin = vec![0.0; ndims];
    if let Some(s) = get("offset").or(get("position")).or(get("origin")) {
        origin = io_util::parse_n_floats(path, "Offset", s, ndims)?;
    }
    let mut dirs = [DVec3::X, DVec3::Y, DVec3::Z];
    if let Some(s) = get("transformmatrix")
        .or(get("rotation"))
        .or(get("orientation"))
    {
        let m = io_util::parse_n_floats(path, "TransformMatrix", s, ndims * ndims)?;
        for (a, dir) in dirs.iter_mut().enumerate().take(ndims) {
            let mut d = DVec3::ZERO;
            for c in 0..ndims {
                d[c] = m[a * ndims + c];
            }
            *dir = d;
        }
    }
    let lps = get("anatomicalorientation").is_some();
    let flip = if lps {
        DVec3::new(-1.0, -1.0, 1.0)
    } else {
        DVec3::ONE
    };
    let cols: Vec<DVec3> = (0..3)
        .map(|a| dirs[a] * if a < ndims { sp[a] } else { 1.0 } * flip)
        .collect();
    let m3 = DMat3::from_cols(cols[0], cols[1], cols[2]);
    if crate::io_util::degenerate_axes(m3) {
        return Err(VolumeError::format(
            path,
            "ElementSpacing/TransformMatrix",
            "degenerate axes",
        ));
    }
    let o = DVec3::new(
        origin[0],
        origin[1],
        if ndims > 2 { origin[2] } else { 0.0 },
    ) * flip;
    let affine = DMat4::from_cols(
        m3.x_axis.extend(0.0),
        m3.y_axis.extend(0.0),
        m3.z_axis.extend(0.0),
        o.extend(1.0),
    );
    let mut dims = [1usize; 3];
    for a in 0..ndims {
        dims[a] = sizes[a] as usize;
    }
    let mut factors = sizes.clone();
    factors.push(channels as i64);
    let count = checked_count(path, "DimSize", &factors)?;
    let nbytes = count * ty.size();
    let (dpath, bytes): (PathBuf, Vec<u8>) = if data_file.eq_ignore_ascii_case("LOCAL") {
        // The body cut from the file's bytes in place (no second copy).
        let start = data_start.unwrap_or(raw.len());
        let mut bytes = std::mem::take(&mut raw);
        bytes.drain(..start);
        (path.to_path_buf(), bytes)
    } else {
        if data_file.starts_with("LIST") || data_file.split_whitespace().count() > 1 {
            return Err(VolumeError::format(
                path,
                "ElementDataFile",
                "lists and patterns of data files are not supported",
            ));
        }
        io_util::read_companion(path, "ElementDataFile", data_file)?
    };
    let header_size: i64 = get("headersize")
        .map(|s| {
            s.parse()
                .map_err(|_| VolumeError::format(path, "HeaderSize", "not an integer"))
        })
        .transpose()?
        .unwrap_or(0);
    let body: Vec<u8> = if compressed {
        io_util::inflate_zlib(&dpath, "compressed data", &bytes, Some(nbytes))?
    } else if header_size == -1 {
        if bytes.len() < nbytes {
            return Err(VolumeError::format(
                &dpath,
                "data",
                format!("{} bytes, {nbytes} needed", bytes.len()),
            ));
        }
        let mut bytes = bytes;
        bytes.drain(..bytes.len() - nbytes);
        bytes
    } else if header_size < 0 || header_size as usize > bytes.len() {
        return Err(VolumeError::format(
            path,
            "HeaderSize",
            format!(
                "{header_size} does not fit the data file of {} bytes",
                bytes.len()
            ),
        ));
    } else {
        let mut bytes = bytes;
        bytes.drain(..header_size as usize);
        bytes
    };
    let stored = match keep_stored && channels == 1 {
        true => io_util::take_stored(&dpath, "data", &body, count, ty, big_endian)?,
        false => None,
    };
    let mut data = match stored {
        Some(_) => Vec::new(),
        None => take_samples(&dpath, "data", &body, count, ty, big_endian, false)?,
    };
    drop(body);
    if channels == 3 && lps {
        for v in data.chunks_exact_mut(3) {
            v[0] = -v[0];
            v[1] = -v[1];
        }
    }
    let mut fields = Vec::new();
    crate::vtk_common::push_field(&mut fields, "data".into(), channels, ty, data);
    let vol = Volume {
        format: "metaimage".into(),
        dims,
        affine,
        space: if lps { Space::Ras } else { Space::File },
        fields,
        default_field: 0,
        warnings: vec![],
    };
    Ok((vol, stored))
}
