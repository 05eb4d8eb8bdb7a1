//! Errors of the tractogram readers, writers and the tube mesher.

use std::path::{Path, PathBuf};

#[derive(Debug, thiserror::Error)]
pub enum TubesError {
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// The file is malformed or unsupported: `field` names the header field or region.
    #[error("{path}: {field}: {problem}")]
    Format {
        path: PathBuf,
        field: String,
        problem: String,
    },
    #[error("{0}")]
    Invalid(String),
}

impl TubesError {
    pub fn io(path: &Path, source: std::io::Error) -> Self {
        TubesError::Io {
            path: path.to_path_buf(),
            source,
        }
    }
    pub fn format(path: &Path, field: impl Into<String>, problem: impl Into<String>) -> Self {
        TubesError::Format {
            path: path.to_path_buf(),
            field: volume::clip_text(&field.into(), 120),
            problem: volume::clip_text(&problem.into(), 400),
        }
    }
}

pub type Result<T> = std::result::Result<T, TubesError>;

/// The most bytes a compressed tractogram may decode to (2 GiB, about 180 million points of
/// a `.tck`): beyond it reading stops with an error rather than exhausting memory.
pub const MAX_GZ_DECODED: u64 = 2 << 30;

/// A tractogram file opened for streaming: its decoded bytes from the first, whether it is
/// gzip, and (plain files) its length.
pub struct Source {
    pub reader: Box<dyn std::io::Read>,
    pub gzip: bool,
    pub len: Option<u64>,
}

impl Source {
    /// The error of a failed read: gzip failures (a broken stream, the decoded limit) name the
    /// `gzip` field, others are I/O errors of the file.
    pub fn error(&self, path: &Path, e: std::io::Error) -> TubesError {
        if self.gzip {
            TubesError::format(path, "gzip", e.to_string())
        } else {
            TubesError::io(path, e)
        }
    }
}

/// A gzip decoder that stops at [`MAX_GZ_DECODED`] bytes and says how far a broken stream got.
struct GzGuard<R> {
    inner: flate2::read::MultiGzDecoder<R>,
    decoded: u64,
}

impl<R: std::io::BufRead> std::io::Read for GzGuard<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = self.inner.read(buf).map_err(|e| {
            std::io::Error::new(
                e.kind(),
                format!(
                    "broken gzip stream after {} decoded bytes: {e}",
                    self.decoded
                ),
            )
        })?;
        self.decoded += n as u64;
        if self.decoded > MAX_GZ_DECODED {
            return Err(std::io::Error::other(format!(
                "the stream decodes to more than {MAX_GZ_DECODED} bytes, the most umbra \
                 inflates; decompress it first (gunzip) to read it"
            )));
        }
        Ok(n)
    }
}

/// Opens a regular file (devices, pipes and directories are refused; see
/// `volume::open_regular`) for streaming, decompressing gzip (by content, not name) up to
/// [`MAX_GZ_DECODED`] bytes. The data (decoded) must start with `magic`, the format's
/// signature, which is checked on the first decoded bytes before the rest is inflated: a
/// gzip bomb of zeros is refused at once. An empty file is an error.
pub fn open_maybe_gz(path: &Path, magic: &[u8], format: &str) -> Result<Source> {
    use std::io::{BufRead, Read};
    let (f, len) = volume::open_regular(path).map_err(|e| TubesError::io(path, e))?;
    if len == 0 {
        return Err(TubesError::format(
            path,
            "file",
            format!("the file is empty (a {format} file starts with its header)"),
        ));
    }
    let check = |head: &[u8]| -> Result<()> {
        if head.starts_with(magic) {
            Ok(())
        } else {
            let shown: String = String::from_utf8_lossy(&head[..head.len().min(magic.len())])
                .chars()
                .map(|c| if c.is_control() { '.' } else { c })
                .collect();
            Err(TubesError::format(
                path,
                "magic",
                format!(
                    "not a {format} file: it starts with '{shown}', not '{}'",
                    String::from_utf8_lossy(magic)
                ),
            ))
        }
    };
    let mut file = std::io::BufReader::with_capacity(1 << 20, f);
    let head = file.fill_buf().map_err(|e| TubesError::io(path, e))?;
    if !head.starts_with(&[0x1f, 0x8b]) {
        check(head)?;
        return Ok(Source {
            reader: Box::new(file),
            gzip: false,
            len: Some(len),
        });
    }
    let mut dec = GzGuard {
        inner: flate2::read::MultiGzDecoder::new(file),
        decoded: 0,
    };
    let mut first = Vec::new();
    (&mut dec)
        .take(magic.len() as u64)
        .read_to_end(&mut first)
        .map_err(|e| TubesError::format(path, "gzip", e.to_string()))?;
    check(&first)?;
    Ok(Source {
        reader: Box::new(std::io::Cursor::new(first).chain(dec)),
        gzip: true,
        len: None,
    })
}

/// Reads a whole file as [`open_maybe_gz`] opens it.
pub fn read_maybe_gz(path: &Path, magic: &[u8], format: &str) -> Result<Vec<u8>> {
    use std::io::Read;
    let mut src = open_maybe_gz(path, magic, format)?;
    let mut out = Vec::new();
    let len = src.len.unwrap_or(0);
    // Reserved fallibly: a file past the memory the process may use is an error, not an abort.
    out.try_reserve_exact(len as usize).map_err(|_| {
        TubesError::format(
            path,
            "data",
            format!(
                "not enough memory to read its {len} bytes ({} MiB)",
                len >> 20
            ),
        )
    })?;
    src.reader
        .read_to_end(&mut out)
        .map_err(|e| src.error(path, e))?;
    Ok(out)
}

/// Writes through a temporary file and a rename (`volume::write_atomic`); gzip when the name
/// ends in `.gz`.
pub fn write_atomic(path: &Path, bytes: Vec<u8>) -> Result<()> {
    let bytes = if path.to_string_lossy().to_ascii_lowercase().ends_with(".gz") {
        volume::gzip_bytes(&bytes)
    } else {
        bytes
    };
    volume::write_atomic(path, &bytes).map_err(TubesError::from)
}

impl From<volume::VolumeError> for TubesError {
    fn from(e: volume::VolumeError) -> Self {
        match e {
            volume::VolumeError::Io { path, source } => TubesError::Io { path, source },
            volume::VolumeError::Format {
                path,
                field,
                problem,
            } => TubesError::Format {
                path,
                field,
                problem,
            },
            volume::VolumeError::Invalid(m) => TubesError::Invalid(m),
        }
    }
}
