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
            field: field.into(),
            problem: problem.into(),
        }
    }
}

pub type Result<T> = std::result::Result<T, TubesError>;

/// Reads a file, decompressing gzip (by content, not name).
pub fn read_maybe_gz(path: &Path) -> Result<Vec<u8>> {
    use std::io::Read;
    let raw = std::fs::read(path).map_err(|e| TubesError::io(path, e))?;
    if raw.starts_with(&[0x1f, 0x8b]) {
        let mut out = Vec::new();
        flate2::read::MultiGzDecoder::new(&raw[..])
            .read_to_end(&mut out)
            .map_err(|e| {
                TubesError::format(
                    path,
                    "gzip",
                    format!("broken gzip stream after {} bytes: {e}", out.len()),
                )
            })?;
        Ok(out)
    } else {
        Ok(raw)
    }
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
