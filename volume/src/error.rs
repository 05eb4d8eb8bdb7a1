//! Errors of the volume readers and writers.
//!
//! Every error names the file, the field of the format that is wrong (a header key, a byte
//! range, an XML attribute) and the problem, so that a user can fix the file or report it.

use std::path::{Path, PathBuf};

/// An error from reading, writing or selecting volume data.
#[derive(Debug, thiserror::Error)]
pub enum VolumeError {
    /// The operating system refused a file operation.
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// The file is malformed or unsupported: `field` names the header key or region.
    #[error("{path}: {field}: {problem}")]
    Format {
        path: PathBuf,
        field: String,
        problem: String,
    },
    /// A request that does not fit the data (unknown field name, iso value outside the range, ...).
    #[error("{0}")]
    Invalid(String),
}

impl VolumeError {
    pub fn io(path: &Path, source: std::io::Error) -> Self {
        VolumeError::Io {
            path: path.to_path_buf(),
            source,
        }
    }

    pub fn format(path: &Path, field: impl Into<String>, problem: impl Into<String>) -> Self {
        VolumeError::Format {
            path: path.to_path_buf(),
            field: crate::io_util::clip_text(&field.into(), 120),
            problem: crate::io_util::clip_text(&problem.into(), 400),
        }
    }
}

pub type Result<T> = std::result::Result<T, VolumeError>;
