//! MRtrix `.tck` reader and writer (plain or gzip).
//!
//! Header: the line `mrtrix tracks`, then `key: value` lines (a key may repeat: its values are
//! joined with newlines, as MRtrix and nibabel do for multi-line fields), then `END`. The
//! `file: . <offset>` key gives where the data start; `datatype` is `Float32LE`, `Float32BE`,
//! `Float64LE` or `Float64BE`. Data: point triplets in RAS+ mm, a NaN triplet between
//! streamlines and an Inf triplet at the end (any non-standard NaN or Inf bit pattern counts).
//! As nibabel: no magic, no `END`, a header running past the end of the file, an unsupported
//! datatype or data without the final Inf triplet are errors; a `count` that disagrees with the
//! data gives a warning and the data win.

use crate::error::{open_maybe_gz, Result, TubesError};
use crate::Streamlines;
use glam::Vec3;
use std::path::Path;

/// The longest header read before its `END` (MRtrix's command histories are kilobytes).
const MAX_HEADER: usize = 64 << 20;

/// Bytes read from the file at a time.
const CHUNK: usize = 1 << 20;

/// Reads a `.tck` or `.tck.gz` file, streamed: the file is read in chunks of 1 MiB, never
/// whole, so reading needs the points (12 bytes each) and the offsets (8 bytes a streamline).
pub fn read(path: &Path) -> Result<Streamlines> {
    use std::io::Read;
    let mut src = open_maybe_gz(path, b"mrtrix tracks", "MRtrix .tck")?;
    // Reads up to CHUNK more bytes onto `buf`; false at the end of the file.
    let more = |src: &mut crate::error::Source, buf: &mut Vec<u8>| -> Result<bool> {
        let start = buf.len();
        buf.resize(start + CHUNK, 0);
        let mut got = 0;
        let res = loop {
            match src.reader.read(&mut buf[start + got..]) {
                Ok(0) => break Ok(()),
                Ok(n) => {
                    got += n;
                    if got == CHUNK {
                        break Ok(());
                    }
                }
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                Err(e) => break Err(e),
            }
        };
        buf.truncate(start + got);
        res.map_err(|e| src.error(path, e))?;
        Ok(got > 0)
    };
    let mut bytes: Vec<u8> = Vec::new();
    let mut eof = !more(&mut src, &mut bytes)?;
    // Header lines up to END, read as nibabel reads them: lines are trimmed, blank ones
    // skipped, a line without ':' continues the last key's value, and a repeated key's values
    // are joined by newlines (MRtrix repeats command_history). Keys are indexed by a map, so
    // the header's cost is linear in its length.
    let mut pos = 0;
    let mut keys: Vec<(String, String)> = Vec::new();
    let mut index: std::collections::HashMap<String, usize> = Default::default();
    let mut last: Option<usize> = None;
    let mut ended = false;
    let mut first = true;
    let mut searched = 0;
    loop {
        if bytes.len() > MAX_HEADER {
            return Err(TubesError::format(
                path,
                "END",
                format!(
                    "no END line in the first {} MiB of the header",
                    MAX_HEADER >> 20
                ),
            ));
        }
        let end = bytes[pos + searched..]
            .iter()
            .position(|&b| b == b'\n')
            .map(|e| pos + searched + e);
        let Some(end) = end else {
            if eof {
                break;
            }
            searched = bytes.len() - pos;
            eof = !more(&mut src, &mut bytes)?;
            continue;
        };
        searched = 0;
        let line = String::from_utf8_lossy(&bytes[pos..end]).trim().to_string();
        pos = end + 1;
        if first {
            first = false;
            continue;
        }
        if line == "END" {
            ended = true;
            break;
        }
        if line.is_empty() {
            continue;
        }
        let slot = match line.split_once(':') {
            Some((k, v)) => {
                let k = k.trim().to_string();
                let v = v.trim().to_string();
                match index.get(&k) {
                    Some(&i) => {
                        keys[i].1.push('\n');
                        keys[i].1.push_str(&v);
                        i
                    }
                    None => {
                        index.insert(k.clone(), keys.len());
                        keys.push((k, v));
                        keys.len() - 1
                    }
                }
            }
            None => {
                let Some(i) = last else {
                    return Err(TubesError::format(
                        path,
                        "header",
                        format!(
                            "line '{}' is not 'key: value' and follows no key",
                            volume::clip_text(&line, 60)
                        ),
                    ));
                };
                keys[i].1.push('\n');
                keys[i].1.push_str(&line);
                i
            }
        };
        last = Some(slot);
    }
    if !ended {
        return Err(TubesError::format(
            path,
            "END",
            "the header has no END line (truncated file?)",
        ));
    }
    let get = |k: &str| index.get(k).map(|&i| keys[i].1.as_str());
    let mut warnings = Vec::new();
    // A missing `file` is guessed as nibabel guesses it: the data follow the header.
    let guessed = format!(". {pos}");
    let file = get("file").unwrap_or_else(|| {
        warnings.push(format!(
            "no 'file' key; the data are read from byte {pos}, after END"
        ));
        &guessed
    });
    // A repeated key's first value counts (nibabel takes the first offset of a repeated
    // `file`).
    let first_value = |v: &str| v.split('\n').next().unwrap_or("").trim().to_string();
    let file1 = first_value(file);
    let offset: usize = match file1.split_whitespace().collect::<Vec<_>>().as_slice() {
        [".", off] => off.parse().map_err(|_| {
            TubesError::format(
                path,
                "file",
                format!(
                    "'{}': offset is not a number",
                    volume::clip_text(&file1, 60)
                ),
            )
        })?,
        _ => {
            return Err(TubesError::format(
                path,
                "file",
                format!(
                    "'{}': only '. <offset>' (data in this file) is supported",
                    volume::clip_text(&file1, 60)
                ),
            ))
        }
    };
    // The bytes before the data are dropped as they are read.
    let mut skipped = 0;
    while skipped + bytes.len() < offset && !eof {
        skipped += bytes.len();
        bytes.clear();
        eof = !more(&mut src, &mut bytes)?;
    }
    if offset < pos || offset > skipped + bytes.len() {
        return Err(TubesError::format(
            path,
            "file",
            format!(
                "data offset {offset} is outside the file ({} bytes, header ends at {pos})",
                src.len.unwrap_or((skipped + bytes.len()) as u64)
            ),
        ));
    }
    bytes.drain(..offset - skipped);
    // nibabel's rules: no datatype is Float32LE (with a warning), a datatype without BE is
    // little endian. Float64 is read too (nibabel refuses it).
    let datatype = get("datatype").map(first_value);
    let (size, big) = match datatype.as_deref() {
        Some("Float32LE") | Some("Float32") => (4, false),
        Some("Float32BE") => (4, true),
        Some("Float64LE") | Some("Float64") => (8, false),
        Some("Float64BE") => (8, true),
        Some(other) => {
            return Err(TubesError::format(
                path,
                "datatype",
                format!(
                    "'{}' is not Float32LE/BE or Float64LE/BE",
                    volume::clip_text(other, 60)
                ),
            ))
        }
        None => {
            warnings.push("no 'datatype' key; Float32LE assumed (as nibabel does)".into());
            (4, false)
        }
    };
    let triplet = 3 * size;
    let value = |data: &[u8], o: usize| -> f64 {
        if size == 4 {
            let a: [u8; 4] = data[o..o + 4].try_into().unwrap();
            (if big {
                f32::from_be_bytes(a)
            } else {
                f32::from_le_bytes(a)
            }) as f64
        } else {
            let a: [u8; 8] = data[o..o + 8].try_into().unwrap();
            if big {
                f64::from_be_bytes(a)
            } else {
                f64::from_le_bytes(a)
            }
        }
    };
    let mut s = Streamlines::new();
    s.warnings = warnings;
    // A plain file's size bounds its points (a streamline's NaN triplet included): reserved
    // once, the points are never copied to a larger buffer.
    if let Some(len) = src.len {
        let n = (len as usize).saturating_sub(offset) / triplet;
        s.points.try_reserve_exact(n).map_err(|_| {
            TubesError::format(
                path,
                "data",
                format!(
                    "not enough memory for its {n} points ({} MiB)",
                    (n * std::mem::size_of::<glam::Vec3>()) >> 20
                ),
            )
        })?;
    }
    let mut terminated = false;
    let mut open = 0usize; // points since the last delimiter
    let mut consumed = 0usize; // data bytes before `bytes[0]`
    let mut o = 0;
    // A triplet of three NaNs ends a streamline, one of three infinities the data (as in
    // MRtrix and nibabel); a triplet with only some NaN or infinite components is a point
    // (non-finite: see `Streamlines::nonfinite_points`).
    'chunks: loop {
        while o + triplet <= bytes.len() {
            let (x, y, z) = (
                value(&bytes, o),
                value(&bytes, o + size),
                value(&bytes, o + 2 * size),
            );
            o += triplet;
            if x.is_nan() && y.is_nan() && z.is_nan() {
                if open > 0 {
                    s.offsets.push(s.points.len());
                }
                open = 0;
                continue;
            }
            if x.is_infinite() && y.is_infinite() && z.is_infinite() {
                if open > 0 {
                    s.offsets.push(s.points.len());
                }
                terminated = true;
                let after = match src.len {
                    // (saturating: a file that changed size while it was read)
                    Some(len) => (len as usize).saturating_sub(offset + consumed + o),
                    None => {
                        let rest = std::io::copy(&mut src.reader, &mut std::io::sink())
                            .map_err(|e| src.error(path, e))?;
                        bytes.len() - o + rest as usize
                    }
                };
                if after >= triplet {
                    s.warnings.push(format!(
                        "{after} bytes after the end marker 'inf inf inf' ignored"
                    ));
                }
                break 'chunks;
            }
            let q = Vec3::new(x as f32, y as f32, z as f32);
            if [x, y, z]
                .iter()
                .any(|v| v.is_finite() && !(*v as f32).is_finite())
            {
                // A Float64 value that is finite but beyond f32's range.
                return Err(TubesError::format(
                    path,
                    "data",
                    format!(
                        "point {}: ({x:e}, {y:e}, {z:e}) is outside f32's range",
                        s.points.len()
                    ),
                ));
            }
            s.points.push(q);
            open += 1;
        }
        // The partial triplet at the end waits for the next chunk.
        consumed += o;
        bytes.drain(..o);
        o = 0;
        if eof {
            break;
        }
        eof = !more(&mut src, &mut bytes)?;
    }
    if !terminated {
        let total = consumed + bytes.len();
        return Err(TubesError::format(
            path,
            "data",
            if !total.is_multiple_of(triplet) {
                format!("{total} data bytes are not whole {triplet}-byte triplets and no 'inf inf inf' end marker was found")
            } else {
                "expecting the end-of-file marker 'inf inf inf'".to_string()
            },
        ));
    }
    if s.points.capacity() > s.points.len() + s.points.len() / 8 + 1024 {
        s.points.shrink_to_fit();
    }
    if let Some(c) = get("count").map(first_value) {
        match c.trim().parse::<usize>() {
            Ok(n) if n != s.len() => s.warnings.push(format!(
                "header count {n} disagrees with the {} streamlines in the data; using the data",
                s.len()
            )),
            Ok(_) => {}
            Err(_) => s.warnings.push(format!(
                "header count '{}' is not a number; ignored",
                volume::clip_text(&c, 40)
            )),
        }
    }
    s.format = "tck".into();
    Ok(s)
}

/// Writes a `.tck` file (Float32LE; gzip when the name ends in `.gz`). Attributes are not part
/// of the format and are not written.
pub fn write(path: &Path, s: &Streamlines) -> Result<()> {
    s.validate()
        .map_err(|e| TubesError::Invalid(format!("{}: {e}", path.display())))?;
    write_with(path, s.len(), |i, out| out.extend_from_slice(s.line(i)))
}

/// Writes `count` streamlines made one at a time - `line(i, out)` appends streamline `i`'s
/// points to the empty `out` - as a `.tck` file (Float32LE; gzip when the name ends in
/// `.gz`), streamed through a temporary file renamed at the end: memory does not grow with the
/// tractogram.
pub fn write_with(
    path: &Path,
    count: usize,
    mut line: impl FnMut(usize, &mut Vec<Vec3>),
) -> Result<()> {
    use std::io::Write;
    let mut header =
        format!("mrtrix tracks\ndatatype: Float32LE\ncount: {count:010}\ntimestamp: 0\n");
    // `file: . OFFSET` with the offset of the data: the line's own length depends on it.
    let base = header.len() + "file: . \nEND\n".len();
    let mut digits = 1;
    while (base + digits).to_string().len() != digits {
        digits += 1;
    }
    let offset = base + digits;
    header += &format!("file: . {offset}\nEND\n");
    debug_assert_eq!(header.len(), offset);
    let gz = path.to_string_lossy().to_ascii_lowercase().ends_with(".gz");
    let mut body = |w: &mut dyn Write| -> std::io::Result<()> {
        w.write_all(header.as_bytes())?;
        let mut points = Vec::new();
        let mut bytes = Vec::new();
        // As MRtrix and nibabel: every streamline is followed by a NaN triplet.
        for i in 0..count {
            points.clear();
            line(i, &mut points);
            // A point of three NaNs or three infinities is the format's own mark (the end of
            // a streamline, of the data): written, it would split the streamline or cut the
            // file short, silently.
            if let Some(j) = points.iter().position(|p| {
                let c = [p.x, p.y, p.z];
                c.iter().all(|v| v.is_nan()) || c.iter().all(|v| v.is_infinite())
            }) {
                return Err(std::io::Error::new(
                    std::io::ErrorKind::InvalidData,
                    format!(
                        "streamline {i} point {j} is ({}, {}, {}), which .tck reads as the end of \
                         a streamline or of the data; write .trk or .trx to keep such points",
                        points[j].x, points[j].y, points[j].z
                    ),
                ));
            }
            bytes.clear();
            for p in points.iter().chain(&[Vec3::NAN]) {
                for v in [p.x, p.y, p.z] {
                    bytes.extend_from_slice(&v.to_le_bytes());
                }
            }
            w.write_all(&bytes)?;
        }
        for _ in 0..3 {
            w.write_all(&f32::INFINITY.to_le_bytes())?;
        }
        Ok(())
    };
    volume::write_atomic_with(path, |w| {
        if gz {
            let mut enc = flate2::write::GzEncoder::new(w, flate2::Compression::new(6));
            body(&mut enc)?;
            enc.finish().map(|_| ())
        } else {
            body(w)
        }
    })
    .map_err(TubesError::from)
}
