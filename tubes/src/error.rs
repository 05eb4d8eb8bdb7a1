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

/// Writes through a temporary file and a rename; gzip when the name ends in `.gz`.
pub fn write_atomic(path: &Path, bytes: Vec<u8>) -> Result<()> {
    use std::io::Write;
    let bytes = if path.to_string_lossy().to_ascii_lowercase().ends_with(".gz") {
        let mut enc = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::new(6));
        enc.write_all(&bytes).map_err(|e| TubesError::io(path, e))?;
        enc.finish().map_err(|e| TubesError::io(path, e))?
    } else {
        bytes
    };
    let dir = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let name = path
        .file_name()
        .ok_or_else(|| TubesError::Invalid(format!("{}: not a file path", path.display())))?;
    let tmp = dir.join(format!(
        ".{}.{}.tmp",
        name.to_string_lossy(),
        std::process::id()
    ));
    let res = (|| -> std::io::Result<()> {
        let mut f = std::fs::File::create(&tmp)?;
        f.write_all(&bytes)?;
        f.sync_all()?;
        std::fs::rename(&tmp, path)
    })();
    if let Err(e) = res {
        let _ = std::fs::remove_file(&tmp);
        return Err(TubesError::io(path, e));
    }
    Ok(())
}
