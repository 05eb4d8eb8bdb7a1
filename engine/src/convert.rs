//! `umbra convert`: write a volume's field as NRRD or NIfTI-1 (format from the output name).

use std::path::Path;
use volume::{nifti, nrrd, FieldSelector, VolumeError};

/// Reads `input`, selects a field, and writes it to `output` (`.nrrd`, `.nii`, `.nii.gz`).
/// `gzip` picks gzip encoding for NRRD (NIfTI follows the `.gz` suffix).
pub fn convert(
    input: &Path,
    output: &Path,
    field: Option<&FieldSelector>,
    gzip: bool,
) -> Result<(), VolumeError> {
    let vol = volume::load(input)?;
    let f = vol.select(field)?;
    write_field(output, &vol, &f, gzip)
}

/// Writes one field of a volume as `.nrrd` (optionally gzip-encoded), `.nii` or `.nii.gz`,
/// atomically (temporary file, then rename).
pub fn write_field(
    output: &Path,
    vol: &volume::Volume,
    f: &volume::Field,
    gzip: bool,
) -> Result<(), VolumeError> {
    let name = output.to_string_lossy().to_ascii_lowercase();
    if name.ends_with(".nrrd") {
        let enc = if gzip {
            nrrd::WriteEncoding::Gzip
        } else {
            nrrd::WriteEncoding::Raw
        };
        nrrd::write(output, vol, f, enc)
    } else if name.ends_with(".nii") || name.ends_with(".nii.gz") {
        nifti::write(output, vol, f)
    } else {
        Err(VolumeError::Invalid(format!(
            "{}: output format unknown; use .nrrd, .nii or .nii.gz",
            output.display()
        )))
    }
}
