//! Shared reading helpers: bounded decompression, sample decoding, text cursors.
//!
//! The rule all readers follow: no allocation is sized by a header field before the bytes that
//! field promises have been seen. Sample buffers are allocated only after the raw bytes are in
//! memory (their size is then bounded by the file), and decompression grows its output as data
//! arrives, stopping one byte past what the header promised.

use crate::{Result, ScalarType, VolumeError};
use std::io::Read;
use std::path::Path;

/// Hard ceiling on the number of samples of one array (16 GiB as f32): above it a header is
/// rejected before anything is read.
pub const MAX_SAMPLES: u64 = 1 << 32;

/// Fixed-offset reads from a binary header in either byte order (NIfTI, TrackVis). Offsets
/// must lie inside the slice: callers check the header's length first.
pub struct Bytes<'a> {
    pub b: &'a [u8],
    pub big_endian: bool,
}

macro_rules! bytes_getter {
    ($name:ident, $t:ty, $n:literal) => {
        pub fn $name(&self, o: usize) -> $t {
            let a: [u8; $n] = self.b[o..o + $n].try_into().unwrap();
            if self.big_endian {
                <$t>::from_be_bytes(a)
            } else {
                <$t>::from_le_bytes(a)
            }
        }
    };
}

impl Bytes<'_> {
    bytes_getter!(i16, i16, 2);
    bytes_getter!(i32, i32, 4);
    bytes_getter!(i64, i64, 8);
    bytes_getter!(f32, f32, 4);
    bytes_getter!(f64, f64, 8);
}

/// The most bytes any reader takes from one file or decodes from one compressed stream
/// (16 GiB: 2^32 samples of 4 bytes); a larger file is refused before it is read.
pub const MAX_FILE_BYTES: u64 = 1 << 34;

/// Opens a file for reading, refusing what is not a regular file (directories, devices such as
/// /dev/zero or /dev/urandom, sockets, pipes: they have no size to bound the read by) and files
/// over [`MAX_FILE_BYTES`]. Returns the file and its length.
pub fn open_regular(path: &Path) -> std::io::Result<(std::fs::File, u64)> {
    use std::io::{Error, ErrorKind};
    let meta = std::fs::metadata(path)?;
    if !meta.is_file() {
        let what = if meta.is_dir() {
            "a directory"
        } else {
            "not a regular file (a device, pipe or socket)"
        };
        return Err(Error::new(
            ErrorKind::InvalidInput,
            format!("{what}; umbra reads regular files only"),
        ));
    }
    if meta.len() > MAX_FILE_BYTES {
        return Err(Error::new(
            ErrorKind::InvalidInput,
            format!(
                "{} bytes, more than the {MAX_FILE_BYTES} umbra reads from one file",
                meta.len()
            ),
        ));
    }
    let f = std::fs::File::open(path)?;
    note_input(path, &meta);
    Ok((f, meta.len()))
}

/// A file's identity on the file system: its device and inode on Unix (so that a second
/// name for it - `./x`, a symbolic or hard link - is the same file), else its canonical path.
#[derive(Clone, Debug, PartialEq, Eq)]
enum FileId {
    #[cfg(unix)]
    Inode(u64, u64),
    #[cfg(not(unix))]
    Path(std::path::PathBuf),
}

fn file_id(path: &Path, meta: &std::fs::Metadata) -> Option<FileId> {
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        let _ = path;
        Some(FileId::Inode(meta.dev(), meta.ino()))
    }
    #[cfg(not(unix))]
    {
        let _ = meta;
        path.canonicalize().ok().map(FileId::Path)
    }
}

/// The files this process has read through [`open_regular`] (every reader's way in), once
/// [`guard_inputs`] is called: what no write of this process may replace
/// ([`write_atomic_with`], [`check_not_read`]).
static READ: std::sync::Mutex<Vec<(FileId, std::path::PathBuf)>> =
    std::sync::Mutex::new(Vec::new());

static GUARD: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

/// From now on no write of this process replaces a file it has read (a command: `umbra
/// render --timings-json` named after the scene's volume replaced the volume). Off by default:
/// a program that reads a file and later saves a new version of it on purpose (a script, a
/// test) is not refused.
pub fn guard_inputs() {
    GUARD.store(true, std::sync::atomic::Ordering::Relaxed);
}

/// Notes that `path` is read by this process (for a reader that opens it its own way: a TRX
/// archive past [`MAX_FILE_BYTES`], read member by member).
pub fn note_read(path: &Path) {
    if let Ok(meta) = std::fs::metadata(path) {
        note_input(path, &meta);
    }
}

fn note_input(path: &Path, meta: &std::fs::Metadata) {
    if !GUARD.load(std::sync::atomic::Ordering::Relaxed) {
        return;
    }
    if let Some(id) = file_id(path, meta) {
        let mut read = READ.lock().unwrap_or_else(|e| e.into_inner());
        if !read.iter().any(|(i, _)| *i == id) {
            read.push((id, path.to_path_buf()));
        }
    }
}

/// Lets this process's writes replace `path` although it was read: a command that rewrites
/// its input on purpose (`umbra convert` in place, the viewer saving the scene it opened).
pub fn forget_input(path: &Path) {
    let Some(id) = std::fs::metadata(path).ok().and_then(|m| file_id(path, &m)) else {
        return;
    };
    READ.lock()
        .unwrap_or_else(|e| e.into_inner())
        .retain(|(i, _)| *i != id);
}

/// The path under which this process read the file `path` names, if it did. A file read
/// and since removed (or replaced) is no input any more: its entry is dropped, so that a new
/// file that reuses its inode is not taken for it.
fn read_as(path: &Path) -> Option<std::path::PathBuf> {
    // The entry the output's name is (not a link's target: a write renames over the link
    // itself, and the file it points to is left as it was).
    let id = std::fs::symlink_metadata(path)
        .ok()
        .and_then(|m| file_id(path, &m))?;
    let mut read = READ.lock().unwrap_or_else(|e| e.into_inner());
    // Only the entries of that id are checked again (every write asks).
    let still = |(i, p): &(FileId, std::path::PathBuf)| {
        std::fs::metadata(p)
            .ok()
            .and_then(|m| file_id(p, &m))
            .is_some_and(|now| now == *i)
    };
    let at = read.iter().position(|e| e.0 == id)?;
    if still(&read[at]) {
        return Some(read[at].1.clone());
    }
    read.swap_remove(at);
    None
}

/// Refuses an output that names a file this process has read (a volume, a tractogram, a
/// colour table, a camera path...: whatever went through [`open_regular`]) since
/// [`guard_inputs`]: writing it would destroy an input. [`check_not_input`] compares with the inputs a command names; this one
/// with those its inputs led it to (a scene's data), once read.
pub fn check_not_read(outputs: &[Option<&Path>]) -> std::result::Result<(), String> {
    if !GUARD.load(std::sync::atomic::Ordering::Relaxed) {
        return Ok(());
    }
    for o in outputs.iter().flatten() {
        if let Some(i) = read_as(o) {
            return Err(input_clash(o, &i));
        }
    }
    Ok(())
}

fn input_clash(output: &Path, input: &Path) -> String {
    format!(
        "{}: the same file as the input {}; writing it would destroy the input",
        output.display(),
        input.display()
    )
}

/// Reads at most `limit` bytes of a regular file (all of it with `None`), never more than the
/// file's length: a file that grows while it is read is cut at the length it had when opened.
pub fn read_regular(path: &Path, limit: Option<u64>) -> std::io::Result<Vec<u8>> {
    let (f, len) = open_regular(path)?;
    let n = limit.map_or(len, |l| l.min(len));
    let mut buf = Vec::new();
    // Reserved fallibly: a file larger than the memory the process may use (an address-space
    // limit, a cgroup) is an error giving its size, not an abort.
    buf.try_reserve_exact(n as usize).map_err(|_| {
        std::io::Error::new(
            std::io::ErrorKind::OutOfMemory,
            format!("not enough memory to read its {n} bytes ({} MiB)", n >> 20),
        )
    })?;
    f.take(n).read_to_end(&mut buf)?;
    Ok(buf)
}

/// Reads a UTF-8 text file (a scene, a manifest, a seed list) of at most `max` bytes: larger
/// files, devices and invalid UTF-8 are errors.
pub fn read_text(path: &Path, max: u64) -> std::io::Result<String> {
    use std::io::{Error, ErrorKind};
    let (_, len) = open_regular(path)?;
    if len > max {
        return Err(Error::new(
            ErrorKind::InvalidData,
            format!("{len} bytes, more than the {max} a text file of this kind may have"),
        ));
    }
    let bytes = read_regular(path, Some(max))?;
    String::from_utf8(bytes).map_err(|e| {
        Error::new(
            ErrorKind::InvalidData,
            format!("not UTF-8 text (byte {})", e.utf8_error().valid_up_to()),
        )
    })
}

/// Reads a whole regular file (see [`open_regular`] for what is refused).
pub fn read_file(path: &Path) -> Result<Vec<u8>> {
    read_regular(path, None).map_err(|e| VolumeError::io(path, e))
}

/// Whether three axis vectors fail to span 3-D space: a non-finite determinant, or a cell
/// volume below 1e-6 of its edges' product (scale-free: 10 um voxels in metres are fine,
/// parallel axes are not).
pub fn degenerate_axes(m: glam::DMat3) -> bool {
    let det = m.determinant();
    let edges = m.x_axis.length() * m.y_axis.length() * m.z_axis.length();
    !(det.is_finite() && det.abs() > 1e-6 * edges && edges > 0.0)
}

/// A number as an error message shows it: plain in the range people write (1e-4 to 1e6),
/// exponent form outside it (1e300, not three hundred digits).
pub fn show_number(v: f64) -> String {
    if !v.is_finite() || v == 0.0 || (1e-4..1e6).contains(&v.abs()) {
        format!("{v}")
    } else {
        format!("{v:e}")
    }
}

/// Cuts text quoted from a file for an error message to at most `max` characters, saying how
/// long it was: a 5 MB header line gives a readable error, not a 5 MB one.
pub fn clip_text(s: &str, max: usize) -> String {
    match s.char_indices().nth(max) {
        None => s.to_string(),
        Some((cut, _)) => format!("{}... ({} bytes in all)", &s[..cut], s.len()),
    }
}

/// Reads a data file named by a header: errors name both the header and its field.
pub fn read_companion(
    header: &Path,
    field: &str,
    name: &str,
) -> Result<(std::path::PathBuf, Vec<u8>)> {
    if name.trim().is_empty() {
        return Err(VolumeError::format(header, field, "empty file name"));
    }
    let p = if Path::new(name).is_absolute() {
        std::path::PathBuf::from(name)
    } else {
        header.parent().unwrap_or(Path::new(".")).join(name)
    };
    let bytes = read_regular(&p, None).map_err(|e| {
        VolumeError::format(header, field, format!("cannot read {}: {e}", p.display()))
    })?;
    Ok((p, bytes))
}

pub fn read_head(path: &Path, n: usize) -> Result<Vec<u8>> {
    read_regular(path, Some(n as u64)).map_err(|e| VolumeError::io(path, e))
}

/// Product of dimensions with overflow and size checks. `what` names the header field.
pub fn checked_count(path: &Path, what: &str, dims: &[i64]) -> Result<usize> {
    let mut n: u64 = 1;
    for &d in dims {
        if d < 1 {
            return Err(VolumeError::format(
                path,
                what,
                format!("dimension {d} is not positive (dims {dims:?})"),
            ));
        }
        n = n
            .checked_mul(d as u64)
            .filter(|&n| n <= MAX_SAMPLES)
            .ok_or_else(|| {
                VolumeError::format(
                    path,
                    what,
                    format!("dims {dims:?} give more than {MAX_SAMPLES} samples; refusing to read"),
                )
            })?;
    }
    Ok(n as usize)
}

fn decompress_limited(
    path: &Path,
    field: &str,
    mut reader: impl Read,
    expected: Option<usize>,
    kind: &str,
) -> Result<Vec<u8>> {
    let mut out = Vec::new();
    let limit = expected.map_or(MAX_FILE_BYTES, |n| n as u64);
    let res = reader.by_ref().take(limit + 1).read_to_end(&mut out);
    if expected.is_none() && out.len() as u64 > limit {
        return Err(VolumeError::format(
            path,
            field,
            format!("{kind} data decode to more than {MAX_FILE_BYTES} bytes; refusing"),
        ));
    }
    if let Err(e) = res {
        return Err(VolumeError::format(
            path,
            field,
            format!(
                "broken {kind} stream after {} decoded bytes: {e}",
                out.len()
            ),
        ));
    }
    if let Some(n) = expected {
        if out.len() != n {
            return Err(VolumeError::format(
                path,
                field,
                format!(
                    "{kind} data decodes to {}{} bytes, the header promises {n}",
                    out.len().min(n + 1),
                    if out.len() > n { " or more" } else { "" }
                ),
            ));
        }
    }
    Ok(out)
}

/// Decodes a gzip stream (possibly several members). With `expected`, exactly that many bytes
/// must come out.
pub fn gunzip(path: &Path, field: &str, data: &[u8], expected: Option<usize>) -> Result<Vec<u8>> {
    decompress_limited(
        path,
        field,
        flate2::read::MultiGzDecoder::new(data),
        expected,
        "gzip",
    )
}

/// Decodes a zlib stream of exactly `expected` bytes (or any length with `None`).
pub fn inflate_zlib(
    path: &Path,
    field: &str,
    data: &[u8],
    expected: Option<usize>,
) -> Result<Vec<u8>> {
    decompress_limited(
        path,
        field,
        flate2::read::ZlibDecoder::new(data),
        expected,
        "zlib",
    )
}

/// Converts raw samples to `f32` (`bytes.len()` a multiple of `ty.size()`). The output is
/// reserved with `try_reserve_exact`, so a volume too large for the memory the process may use
/// (an address-space limit, a cgroup) is an error naming its size, not an abort.
pub fn decode_samples(
    path: &Path,
    field: &str,
    bytes: &[u8],
    ty: ScalarType,
    big_endian: bool,
) -> Result<Vec<f32>> {
    let n = bytes.len() / ty.size();
    let mut out: Vec<f32> = Vec::new();
    out.try_reserve_exact(n).map_err(|_| {
        VolumeError::format(
            path,
            field,
            format!(
                "not enough memory for {n} samples ({} MiB as float32)",
                (n as u64 * 4) >> 20
            ),
        )
    })?;
    macro_rules! conv {
        ($t:ty, $n:expr) => {
            out.extend(bytes.chunks_exact($n).map(|c| {
                let a: [u8; $n] = c.try_into().unwrap();
                (if big_endian {
                    <$t>::from_be_bytes(a)
                } else {
                    <$t>::from_le_bytes(a)
                }) as f32
            }))
        };
    }
    match ty {
        ScalarType::U8 => out.extend(bytes.iter().map(|&b| b as f32)),
        ScalarType::I8 => out.extend(bytes.iter().map(|&b| b as i8 as f32)),
        ScalarType::U16 => conv!(u16, 2),
        ScalarType::I16 => conv!(i16, 2),
        ScalarType::U32 => conv!(u32, 4),
        ScalarType::I32 => conv!(i32, 4),
        ScalarType::U64 => conv!(u64, 8),
        ScalarType::I64 => conv!(i64, 8),
        ScalarType::F32 => conv!(f32, 4),
        ScalarType::F64 => conv!(f64, 8),
    }
    Ok(out)
}

/// Takes exactly `count` samples of `ty` from `bytes` (which may be longer only when
/// `allow_trailing`), converting to `f32`.
pub fn take_samples(
    path: &Path,
    field: &str,
    bytes: &[u8],
    count: usize,
    ty: ScalarType,
    big_endian: bool,
    allow_trailing: bool,
) -> Result<Vec<f32>> {
    let need = data_bytes(path, field, bytes, count, ty, allow_trailing)?;
    decode_samples(path, field, &bytes[..need], ty, big_endian)
}

/// The bytes `count` samples of `ty` take, checked against `bytes` (which may be longer only
/// when `allow_trailing`): an error naming the sizes otherwise.
fn data_bytes(
    path: &Path,
    field: &str,
    bytes: &[u8],
    count: usize,
    ty: ScalarType,
    allow_trailing: bool,
) -> Result<usize> {
    let need = count
        .checked_mul(ty.size())
        .ok_or_else(|| VolumeError::format(path, field, "data size overflows"))?;
    if bytes.len() < need || (!allow_trailing && bytes.len() > need) {
        return Err(VolumeError::format(
            path,
            field,
            format!(
                "{} data bytes, the header's dims and type ({count} x {}) need {need}",
                bytes.len(),
                ty.name()
            ),
        ));
    }
    Ok(need)
}

/// [`take_samples`] for 8 and 16-bit integers, kept in their stored type
/// ([`crate::samples::Samples::from_stored`], no `f32`); `None` for other types.
pub fn take_stored(
    path: &Path,
    field: &str,
    bytes: &[u8],
    count: usize,
    ty: ScalarType,
    big_endian: bool,
) -> Result<Option<crate::samples::Samples>> {
    if !matches!(
        ty,
        ScalarType::U8 | ScalarType::I8 | ScalarType::U16 | ScalarType::I16
    ) {
        return Ok(None);
    }
    let need = data_bytes(path, field, bytes, count, ty, false)?;
    crate::samples::Samples::from_stored(bytes, ty, big_endian).map_err(|_| {
        VolumeError::format(
            path,
            field,
            format!(
                "not enough memory for {count} samples ({} MiB as {})",
                (need as u64) >> 20,
                ty.name()
            ),
        )
    })
}

/// Encodes `f32` samples as `ty` (values must be representable; floats round to nearest).
pub fn encode_samples(data: &[f32], ty: ScalarType, big_endian: bool) -> Vec<u8> {
    let mut out = Vec::with_capacity(data.len() * ty.size());
    macro_rules! enc {
        ($t:ty) => {
            for &v in data {
                let x = v as $t;
                out.extend_from_slice(&if big_endian {
                    x.to_be_bytes()
                } else {
                    x.to_le_bytes()
                });
            }
        };
    }
    match ty {
        ScalarType::U8 => enc!(u8),
        ScalarType::I8 => enc!(i8),
        ScalarType::U16 => enc!(u16),
        ScalarType::I16 => enc!(i16),
        ScalarType::U32 => enc!(u32),
        ScalarType::I32 => enc!(i32),
        ScalarType::U64 => enc!(u64),
        ScalarType::I64 => enc!(i64),
        ScalarType::F32 => enc!(f32),
        ScalarType::F64 => enc!(f64),
    }
    out
}

/// Parses one number of ASCII data (accepts `nan`, `inf`, `-inf` in any case).
pub fn parse_number(tok: &str) -> Option<f32> {
    match tok.to_ascii_lowercase().as_str() {
        "nan" | "-nan" | "+nan" => Some(f32::NAN),
        "inf" | "+inf" | "infinity" | "+infinity" => Some(f32::INFINITY),
        "-inf" | "-infinity" => Some(f32::NEG_INFINITY),
        _ => tok.parse::<f64>().ok().map(|v| v as f32),
    }
}

/// Parses `count` whitespace-separated numbers from the front of `text`; returns them and the
/// number of bytes consumed. Allocation grows with what is parsed, never with `count` alone.
pub fn parse_ascii(
    path: &Path,
    field: &str,
    text: &[u8],
    count: usize,
) -> Result<(Vec<f32>, usize)> {
    let mut out = Vec::with_capacity(count.min(text.len() / 2 + 1));
    let mut cur = Cursor::new(text);
    while out.len() < count {
        let Some(tok) = cur.token() else {
            return Err(VolumeError::format(
                path,
                field,
                format!("ASCII data ends after {} of {count} values", out.len()),
            ));
        };
        let s = std::str::from_utf8(tok).unwrap_or("?");
        let v = parse_number(s).ok_or_else(|| {
            VolumeError::format(
                path,
                field,
                format!("'{s}' is not a number (value {} of {count})", out.len() + 1),
            )
        })?;
        out.push(v);
    }
    Ok((out, cur.pos))
}

/// A byte cursor over a text-and-binary file (VTK legacy, SLC, NRRD headers).
pub struct Cursor<'a> {
    pub data: &'a [u8],
    pub pos: usize,
}

impl<'a> Cursor<'a> {
    pub fn new(data: &'a [u8]) -> Self {
        Cursor { data, pos: 0 }
    }

    pub fn at_end(&self) -> bool {
        self.pos >= self.data.len()
    }

    /// The next line without its `\n` (and `\r`), or `None` at the end.
    pub fn line(&mut self) -> Option<&'a [u8]> {
        if self.at_end() {
            return None;
        }
        let rest = &self.data[self.pos..];
        let (line, adv) = match rest.iter().position(|&b| b == b'\n') {
            Some(p) => (&rest[..p], p + 1),
            None => (rest, rest.len()),
        };
        self.pos += adv;
        Some(line.strip_suffix(b"\r").unwrap_or(line))
    }

    /// The next non-blank line, trimmed.
    pub fn nonblank_line(&mut self) -> Option<&'a [u8]> {
        loop {
            let l = self.line()?;
            let t = l.trim_ascii();
            if !t.is_empty() {
                return Some(t);
            }
        }
    }

    /// The next whitespace-separated token.
    pub fn token(&mut self) -> Option<&'a [u8]> {
        while self.pos < self.data.len() && self.data[self.pos].is_ascii_whitespace() {
            self.pos += 1;
        }
        if self.at_end() {
            return None;
        }
        let start = self.pos;
        while self.pos < self.data.len() && !self.data[self.pos].is_ascii_whitespace() {
            self.pos += 1;
        }
        Some(&self.data[start..self.pos])
    }

    /// Skips the rest of the current line including its newline.
    pub fn skip_line(&mut self) {
        let _ = self.line();
    }

    /// Takes `n` raw bytes, or `None` when fewer remain.
    pub fn take(&mut self, n: usize) -> Option<&'a [u8]> {
        let end = self.pos.checked_add(n)?;
        if end > self.data.len() {
            return None;
        }
        let s = &self.data[self.pos..end];
        self.pos = end;
        Some(s)
    }

    pub fn rest(&self) -> &'a [u8] {
        &self.data[self.pos.min(self.data.len())..]
    }
}

/// Parses a whitespace/comma separated list of numbers from a header value.
pub fn parse_floats(path: &Path, field: &str, s: &str) -> Result<Vec<f64>> {
    s.split(|c: char| c.is_whitespace() || c == ',')
        .filter(|t| !t.is_empty())
        .map(|t| {
            t.parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| {
                    VolumeError::format(path, field, format!("'{t}' is not a finite number"))
                })
        })
        .collect()
}

/// Parses exactly `n` numbers from a header value.
pub fn parse_n_floats(path: &Path, field: &str, s: &str, n: usize) -> Result<Vec<f64>> {
    let v = parse_floats(path, field, s)?;
    if v.len() != n {
        return Err(VolumeError::format(
            path,
            field,
            format!("expected {n} numbers, found {} in '{}'", v.len(), s.trim()),
        ));
    }
    Ok(v)
}

/// Parses exactly `n` positive integer sizes from a header value.
pub fn parse_sizes(path: &Path, field: &str, s: &str, n: usize) -> Result<Vec<i64>> {
    let v: Vec<i64> = s
        .split_whitespace()
        .map(|t| {
            t.parse::<i64>()
                .map_err(|_| VolumeError::format(path, field, format!("'{t}' is not an integer")))
        })
        .collect::<Result<_>>()?;
    if v.len() != n {
        return Err(VolumeError::format(
            path,
            field,
            format!("expected {n} sizes, found {}", v.len()),
        ));
    }
    if let Some(bad) = v.iter().find(|&&d| d < 1) {
        return Err(VolumeError::format(
            path,
            field,
            format!("size {bad} is not positive"),
        ));
    }
    Ok(v)
}

/// Writes `bytes` to `path` through a temporary file in the same folder and a rename, so that a
/// failure never leaves a half-written output. The temporary file is `.NAME.PID.tmp`
/// ([`temp_name`]); one a killed process left behind is what [`remove_stale_temps`] removes.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    write_atomic_with(path, |w| std::io::Write::write_all(w, bytes))
}

/// [`write_atomic`] with the contents streamed by `write` (through a buffer) instead of held.
pub fn write_atomic_with(
    path: &Path,
    write: impl FnOnce(&mut dyn std::io::Write) -> std::io::Result<()>,
) -> Result<()> {
    check_not_read(&[Some(path)]).map_err(VolumeError::Invalid)?;
    let tmp = temp_path(path)?;
    writing(&tmp, true);
    let res = (|| -> std::io::Result<()> {
        let mut f = std::io::BufWriter::with_capacity(1 << 20, std::fs::File::create(&tmp)?);
        write(&mut f)?;
        let f = f.into_inner().map_err(|e| e.into_error())?;
        f.sync_all()?;
        std::fs::rename(&tmp, path)
    })();
    if res.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    writing(&tmp, false);
    res.map_err(|e| VolumeError::io(path, e))
}

/// The temporary files this process is writing ([`write_atomic_with`], a streamed PLY).
static WRITING: std::sync::Mutex<Vec<std::path::PathBuf>> = std::sync::Mutex::new(Vec::new());

/// Notes that `tmp` is being written (`true`) or no longer is (`false`: renamed into place or
/// removed), for [`remove_temps_being_written`].
pub fn writing(tmp: &Path, on: bool) {
    let mut w = WRITING.lock().unwrap_or_else(|e| e.into_inner());
    if on {
        w.push(tmp.to_path_buf());
    } else if let Some(i) = w.iter().position(|p| p == tmp) {
        w.swap_remove(i);
    }
}

/// Removes the temporary files this process is writing: what a command interrupted by a
/// signal calls before it exits (its outputs are left as they were; the next run of the
/// command would remove them too, [`remove_stale_temps`]). Returns how many it removed.
pub fn remove_temps_being_written() -> usize {
    let w = WRITING.lock().unwrap_or_else(|e| e.into_inner());
    w.iter().filter(|p| std::fs::remove_file(p).is_ok()).count()
}

/// Writes two outputs of one command, both or neither: `write_first(staged)` writes the first
/// beside `first` (under the name of its temporary file, so that a killed run's is removed by
/// the next, [`remove_stale_temps`]), then `write_second()` writes the second (itself through a
/// temporary file), and the first is renamed into place only once the second is written. A
/// failure of either leaves `first` as it was and removes the staged file.
pub fn write_pair(
    first: &Path,
    write_first: impl FnOnce(&Path) -> std::result::Result<(), String>,
    write_second: impl FnOnce() -> std::result::Result<(), String>,
) -> std::result::Result<(), String> {
    check_not_read(&[Some(first)])?;
    let staged = temp_path(first).map_err(|e| e.to_string())?;
    writing(&staged, true);
    let done = write_first(&staged)
        .and_then(|()| write_second())
        .and_then(|()| {
            check_not_read(&[Some(first)])?;
            std::fs::rename(&staged, first).map_err(|e| format!("{}: {e}", first.display()))
        });
    if done.is_err() {
        let _ = std::fs::remove_file(&staged);
    }
    writing(&staged, false);
    done
}

/// The folder a file path lies in: its parent, or `.` for a bare name.
pub fn folder_of(path: &Path) -> &Path {
    path.parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."))
}

/// The temporary file beside `path` that this process writes it through before the rename
/// ([`temp_name`]); an error when `path` names no file.
pub fn temp_path(path: &Path) -> Result<std::path::PathBuf> {
    let dir = folder_of(path);
    let name = path
        .file_name()
        .ok_or_else(|| VolumeError::Invalid(format!("{}: not a file path", path.display())))?;
    Ok(dir.join(temp_name(&name.to_string_lossy(), std::process::id())))
}

/// The temporary file name [`write_atomic`] writes `name` through in process `pid`.
pub fn temp_name(name: &str, pid: u32) -> String {
    format!(".{name}.{pid}.tmp")
}

/// Checks, before any work, that `path` can be written: not a directory, its folder created
/// when missing, and a file can be created there (a probe named like the temporary file, then
/// removed). Also removes the temporaries a killed earlier run left for this path
/// ([`remove_stale_temps`]). The error names the path and the reason.
pub fn check_output(path: &Path) -> std::result::Result<(), String> {
    let fail = |why: String| {
        Err(format!(
            "{}: cannot write the output here: {why}",
            path.display()
        ))
    };
    let Some(name) = path.file_name() else {
        return fail("not a file path".into());
    };
    // `Path` drops a trailing separator or `.` ("out/" and "out/." name "out"); the file
    // system does not.
    let raw = path.as_os_str().as_encoded_bytes();
    if raw.ends_with(b"/") || raw.ends_with(b"/.") || raw == b"." {
        return fail("a folder's path (it ends in / or /.), not a file's".into());
    }
    if path.is_dir() {
        return fail("it is a directory".into());
    }
    let dir = folder_of(path);
    if let Err(e) = std::fs::create_dir_all(dir) {
        // A file where a folder of the path should be: name it (the system says only "File
        // exists").
        let file = dir
            .ancestors()
            .find(|a| !a.as_os_str().is_empty() && a.exists() && !a.is_dir());
        return fail(match file {
            Some(f) => format!(
                "{} is a file, not a folder, so its folder cannot be made",
                f.display()
            ),
            None => format!("cannot create its folder: {e}"),
        });
    }
    remove_stale_temps(&[path]);
    let probe = dir.join(temp_name(&name.to_string_lossy(), std::process::id()));
    match std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(&probe)
    {
        Ok(_) => {
            let _ = std::fs::remove_file(&probe);
            Ok(())
        }
        // Our own temporary from an earlier write of this process: the folder is writable.
        Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => Ok(()),
        Err(e) => fail(e.to_string()),
    }
}

/// [`check_output`] for every path given (`None`s skipped): all outputs of a command are
/// checked before it starts, so a bad second path leaves no first output written.
pub fn check_outputs(paths: &[Option<&Path>]) -> std::result::Result<(), String> {
    paths.iter().flatten().try_for_each(|p| check_output(p))?;
    check_distinct(paths)
}

/// A file's identity for comparing paths: its folder as the file system resolves it (the
/// absolute path where it does not exist yet) and its name.
fn file_key(p: &Path) -> (std::path::PathBuf, Option<std::ffi::OsString>) {
    let dir = folder_of(p);
    let dir = dir
        .canonicalize()
        .or_else(|_| std::path::absolute(dir))
        .unwrap_or_else(|_| dir.to_path_buf());
    (dir, p.file_name().map(|n| n.to_os_string()))
}

/// Refuses two outputs that name one file (`out.nrrd` and `./dir/../out.nrrd` alike: the
/// folders compared as the file system resolves them): the second write would replace the
/// first. Call it after the folders exist ([`check_output`] makes them).
pub fn check_distinct(paths: &[Option<&Path>]) -> std::result::Result<(), String> {
    let key = file_key;
    let paths: Vec<&Path> = paths.iter().flatten().copied().collect();
    for (i, a) in paths.iter().enumerate() {
        if let Some(b) = paths[..i].iter().find(|b| key(b) == key(a)) {
            return Err(format!(
                "{}: the same file as {} is given for a second output; each output needs a \
                 file of its own",
                a.display(),
                b.display()
            ));
        }
    }
    Ok(())
}

/// Refuses an output that names one of the command's inputs (as the file system resolves the
/// folders, as [`check_distinct`]): writing it would destroy what is being read (a
/// tractogram replaced by a statistics file). Commands that may rewrite their input in place
/// (`umbra convert`, through a temporary file) do not call it.
pub fn check_not_input(
    inputs: &[Option<&Path>],
    outputs: &[Option<&Path>],
) -> std::result::Result<(), String> {
    let key = file_key;
    for o in outputs.iter().flatten() {
        if let Some(i) = inputs.iter().flatten().find(|i| key(i) == key(o)) {
            return Err(input_clash(o, i));
        }
    }
    Ok(())
}

/// Whether process `pid` is alive on this machine (Linux: /proc; elsewhere assumed dead).
fn process_alive(pid: &str) -> bool {
    cfg!(target_os = "linux") && Path::new("/proc").join(pid).exists()
}

/// Removes the temporary files of `paths` that [`write_atomic`] in other processes left
/// (`.NAME.PID.tmp` beside each, PID not this process's nor, on Linux, any live process's):
/// what a killed process leaves. Call it only for outputs no other process writes. Each folder is read
/// once, however many outputs it holds. Returns how many were removed; a folder that cannot be
/// read removes none.
pub fn remove_stale_temps(paths: &[&Path]) -> usize {
    use std::collections::{BTreeMap, HashSet};
    let mut by_dir: BTreeMap<&Path, HashSet<String>> = BTreeMap::new();
    for p in paths {
        let Some(name) = p.file_name() else { continue };
        let dir = folder_of(p);
        by_dir
            .entry(dir)
            .or_default()
            .insert(name.to_string_lossy().into_owned());
    }
    let own = std::process::id().to_string();
    let mut removed = 0;
    for (dir, names) in by_dir {
        let Ok(entries) = std::fs::read_dir(dir) else {
            continue;
        };
        for e in entries.flatten() {
            let f = e.file_name();
            let f = f.to_string_lossy();
            // `.NAME.PID.tmp` with NAME one of ours and PID digits, not ours - or the temporary
            // of such a file (`write_pair` writes its first output under that name, through a
            // temporary of its own).
            let parse = |f: &str| -> Option<(String, String)> {
                let (name, pid) = f
                    .strip_prefix('.')?
                    .strip_suffix(".tmp")?
                    .rsplit_once('.')?;
                (!pid.is_empty() && pid.bytes().all(|b| b.is_ascii_digit()))
                    .then(|| (name.to_string(), pid.to_string()))
            };
            let stale = parse(&f).is_some_and(|(name, pid)| {
                let ours = names.contains(&name)
                    || parse(&name).is_some_and(|(inner, _)| names.contains(&inner));
                ours && pid != own && !process_alive(&pid)
            });
            if stale
                && e.file_type().is_ok_and(|t| t.is_file())
                && std::fs::remove_file(e.path()).is_ok()
            {
                removed += 1;
            }
        }
    }
    removed
}

pub fn gzip_bytes(bytes: &[u8]) -> Vec<u8> {
    use std::io::Write;
    let mut enc = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::new(6));
    enc.write_all(bytes).expect("writing to memory");
    enc.finish().expect("writing to memory")
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two outputs, both or neither: the second failing (a full disk) leaves the first as an
    /// earlier run wrote it (a sweep replaced its distance and then failed on its octants).
    #[test]
    fn a_pair_is_written_both_or_neither() {
        let dir = tempfile::tempdir().unwrap();
        let (a, b) = (dir.path().join("d.nrrd"), dir.path().join("o.nrrd"));
        let put = |p: &Path, s: &str| write_atomic(p, s.as_bytes()).map_err(|e| e.to_string());
        write_pair(&a, |st| put(st, "a1"), || put(&b, "b1")).unwrap();
        assert_eq!(std::fs::read(&a).unwrap(), b"a1");
        assert_eq!(std::fs::read(&b).unwrap(), b"b1");
        // The second fails: the first keeps the earlier run's bytes.
        let e = write_pair(&a, |st| put(st, "a2"), || Err("disk full".into())).unwrap_err();
        assert_eq!(e, "disk full");
        // The first fails: nothing changes.
        write_pair(&a, |_| Err("no".into()), || put(&b, "b3")).unwrap_err();
        assert_eq!(std::fs::read(&a).unwrap(), b"a1");
        assert_eq!(std::fs::read(&b).unwrap(), b"b1");
        let names: Vec<_> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(names.len(), 2, "no staged file left: {names:?}");
        write_pair(&a, |st| put(st, "a4"), || put(&b, "b4")).unwrap();
        assert_eq!(std::fs::read(&a).unwrap(), b"a4");
    }

    #[test]
    fn an_output_under_a_file_names_the_file() {
        let d = tempfile::tempdir().unwrap();
        let f = d.path().join("afile");
        std::fs::write(&f, "x").unwrap();
        for out in [f.join("x.png"), f.join("sub").join("x.png")] {
            let e = check_output(&out).unwrap_err();
            assert!(
                e.contains(&format!("{} is a file, not a folder", f.display())),
                "{e}"
            );
        }
    }

    #[test]
    fn stale_temporary_files_of_one_output_are_removed_and_nothing_else() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("f_03.png");
        let touch = |n: &str| std::fs::write(dir.path().join(n), b"x").unwrap();
        // Left by processes that are gone (PIDs above Linux's largest, 2^22): removed.
        touch(&temp_name("f_03.png", 999_999_917));
        touch(&temp_name("f_03.png", 999_994_242));
        // A staged first output's own temporary (`write_pair`), from a process that is gone.
        touch(&temp_name(&temp_name("f_03.png", 999_999_917), 999_999_917));
        // Not stale or not ours: kept; among them a live process's (our parent's).
        let own = temp_name("f_03.png", std::process::id());
        touch(&own);
        #[cfg(target_os = "linux")]
        let live = {
            let p = temp_name("f_03.png", std::os::unix::process::parent_id());
            touch(&p);
            p
        };
        for keep in [
            ".f_04.png.17.tmp",
            ".f_03.png.x1.tmp",
            ".f_03.png..tmp",
            "f_03.png.17.tmp",
        ] {
            touch(keep);
        }
        assert_eq!(remove_stale_temps(&[out.as_path()]), 3);
        let mut left: Vec<String> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        left.sort();
        let mut want = vec![
            own,
            ".f_04.png.17.tmp".to_string(),
            ".f_03.png.x1.tmp".to_string(),
            ".f_03.png..tmp".to_string(),
            "f_03.png.17.tmp".to_string(),
        ];
        #[cfg(target_os = "linux")]
        want.push(live);
        want.sort();
        assert_eq!(left, want);
        // A write goes through this process's temporary name and leaves none.
        write_atomic(&out, b"png").unwrap();
        assert_eq!(std::fs::read(&out).unwrap(), b"png");
        assert!(!dir
            .path()
            .join(temp_name("f_03.png", std::process::id()))
            .exists());
    }
}
