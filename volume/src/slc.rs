//! SLC volume reader (the format of VolVis, read by VTK's `vtkSLCReader`).
//!
//! Layout: ASCII header `magic(11111) nx ny nz bits sx sy sz unit origin modification
//! compression`, an icon `w h X` followed by three `w*h` byte planes (red, green, blue), then
//! `nz` slices of `nx*ny` bytes: raw when compression is 0, or run-length encoded when it is 1
//! (each slice preceded by `size X`; a control byte `c` with `c & 0x7f = n`, `n = 0` ends the
//! slice, high bit set: `n` literal bytes follow, else one byte repeated `n` times). Only 8-bit
//! data exist in the format. Some writers (the `embryo.slc` of VTK's data, for one) encode
//! slices one byte short; such slices (short by at most one row) are padded with 0 and a warning
//! says so; slices shorter than that are errors. The grid starts at the origin with the header's spacing, in the
//! file's own frame.

use crate::io_util::{self, checked_count, Cursor};
use crate::{Field, Result, ScalarType, Space, Volume, VolumeError};
use glam::{DMat4, DVec4};
use std::path::Path;

fn num<T: std::str::FromStr>(path: &Path, field: &str, cur: &mut Cursor) -> Result<T> {
    let t = cur
        .token()
        .ok_or_else(|| VolumeError::format(path, field, "file ends in the header"))?;
    let s = std::str::from_utf8(t).unwrap_or("?");
    s.parse()
        .map_err(|_| VolumeError::format(path, field, format!("'{s}' is not a number")))
}

/// Skips white space and the single `X` that ends a size; binary data follow at once.
fn expect_x(path: &Path, field: &str, cur: &mut Cursor) -> Result<()> {
    while cur.rest().first().is_some_and(|b| b.is_ascii_whitespace()) {
        cur.pos += 1;
    }
    if cur.rest().first() != Some(&b'X') {
        return Err(VolumeError::format(
            path,
            field,
            "expected 'X' after the size",
        ));
    }
    cur.pos += 1;
    Ok(())
}

/// Decodes one run-length encoded slice of at most `size` bytes (the caller pads short slices).
fn decode_rle(path: &Path, slice: usize, input: &[u8], size: usize) -> Result<Vec<u8>> {
    let err = |m: &str| VolumeError::format(path, format!("slice {slice}"), m.to_string());
    // A run of at most 127 bytes per input byte: the output never exceeds that.
    let mut out = Vec::with_capacity(size.min(input.len().saturating_mul(127)));
    let mut i = 0;
    loop {
        let c = *input
            .get(i)
            .ok_or_else(|| err("run-length data ends without its end marker"))?;
        i += 1;
        let n = (c & 0x7f) as usize;
        if n == 0 {
            break;
        }
        if out.len() + n > size {
            return Err(err(
                "run-length data decode to more bytes than a slice holds",
            ));
        }
        if c & 0x80 != 0 {
            let lit = input
                .get(i..i + n)
                .ok_or_else(|| err("literal run past the end of the slice data"))?;
            out.extend_from_slice(lit);
            i += n;
        } else {
            let v = *input
                .get(i)
                .ok_or_else(|| err("repeat run without its value"))?;
            i += 1;
            out.extend(std::iter::repeat_n(v, n));
        }
    }
    Ok(out)
}

/// Reads an `.slc` file.
pub fn read(path: &Path) -> Result<Volume> {
    let raw = io_util::read_file(path)?;
    let mut cur = Cursor::new(&raw);
    let magic: i64 = num(path, "magic", &mut cur)?;
    if magic != 11111 {
        return Err(VolumeError::format(
            path,
            "magic",
            format!("{magic} is not 11111"),
        ));
    }
    let d: [i64; 3] = [
        num(path, "nx", &mut cur)?,
        num(path, "ny", &mut cur)?,
        num(path, "nz", &mut cur)?,
    ];
    let count = checked_count(path, "dimensions", &d)?;
    let bits: i64 = num(path, "bits", &mut cur)?;
    if bits != 8 {
        return Err(VolumeError::format(
            path,
            "bits",
            format!("{bits}: only 8-bit SLC data exist"),
        ));
    }
    let mut sp = [0f64; 3];
    for (a, s) in sp.iter_mut().enumerate() {
        *s = num(path, ["spacing x", "spacing y", "spacing z"][a], &mut cur)?;
        if !s.is_finite() || *s == 0.0 {
            return Err(VolumeError::format(
                path,
                "spacing",
                format!("{s} is not a finite non-zero spacing"),
            ));
        }
    }
    let _unit: i64 = num(path, "unit type", &mut cur)?;
    let _origin: i64 = num(path, "data origin", &mut cur)?;
    let _modif: i64 = num(path, "data modification", &mut cur)?;
    let compression: i64 = num(path, "compression", &mut cur)?;
    let iw: i64 = num(path, "icon width", &mut cur)?;
    let ih: i64 = num(path, "icon height", &mut cur)?;
    expect_x(path, "icon", &mut cur)?;
    if !(0..=1 << 16).contains(&iw) || !(0..=1 << 16).contains(&ih) {
        return Err(VolumeError::format(
            path,
            "icon",
            format!("size {iw} x {ih}"),
        ));
    }
    cur.take(3 * (iw * ih) as usize)
        .ok_or_else(|| VolumeError::format(path, "icon", "file ends inside the icon"))?;
    let plane = (d[0] * d[1]) as usize;
    let mut data = Vec::with_capacity(count.min(raw.len() * 64));
    let mut short = 0usize;
    for z in 0..d[2] as usize {
        match compression {
            0 => {
                let s = cur.take(plane).ok_or_else(|| {
                    VolumeError::format(path, format!("slice {z}"), "file ends inside the slice")
                })?;
                data.extend(s.iter().map(|&b| b as f32));
            }
            1 => {
                let size: i64 = num(path, &format!("slice {z} size"), &mut cur)?;
                expect_x(path, &format!("slice {z}"), &mut cur)?;
                if size < 0 {
                    return Err(VolumeError::format(
                        path,
                        format!("slice {z} size"),
                        format!("{size}"),
                    ));
                }
                let comp = cur.take(size as usize).ok_or_else(|| {
                    VolumeError::format(
                        path,
                        format!("slice {z}"),
                        "file ends inside the compressed slice",
                    )
                })?;
                let dec = decode_rle(path, z, comp, plane)?;
                if dec.len() < plane {
                    // Short by a row at most (real files lose their last byte); more is a
                    // broken or hostile file, not something to pad with zeros.
                    if plane - dec.len() > d[0] as usize {
                        return Err(VolumeError::format(
                            path,
                            format!("slice {z}"),
                            format!(
                                "run-length data decode to {} bytes, the slice has {plane} (more \
                                 than a row short)",
                                dec.len()
                            ),
                        ));
                    }
                    short += 1;
                }
                data.extend(dec.iter().map(|&b| b as f32));
                data.resize(data.len() + plane - dec.len(), 0.0);
            }
            other => {
                return Err(VolumeError::format(
                    path,
                    "compression",
                    format!("{other} is not 0 (none) or 1 (run-length)"),
                ))
            }
        }
    }
    let trailing = cur
        .rest()
        .iter()
        .filter(|b| !b.is_ascii_whitespace())
        .count();
    if trailing > 0 {
        return Err(VolumeError::format(
            path,
            "nz",
            format!("{} bytes follow the last of {} slices: the header's dimensions do not match the data", cur.rest().len(), d[2]),
        ));
    }
    let affine = DMat4::from_cols(
        DVec4::new(sp[0], 0.0, 0.0, 0.0),
        DVec4::new(0.0, sp[1], 0.0, 0.0),
        DVec4::new(0.0, 0.0, sp[2], 0.0),
        DVec4::W,
    );
    Ok(Volume {
        format: "slc".into(),
        dims: [d[0] as usize, d[1] as usize, d[2] as usize],
        affine,
        space: Space::File,
        fields: vec![Field {
            name: "SLCImage".into(),
            components: 1,
            stored: ScalarType::U8,
            data,
        }],
        default_field: 0,
        warnings: if short > 0 {
            vec![format!("{short} of {} run-length slices decode to fewer than {plane} bytes; the rest of each is set to 0 (VTK's reader leaves it undefined)", d[2])]
        } else {
            vec![]
        },
    })
}
