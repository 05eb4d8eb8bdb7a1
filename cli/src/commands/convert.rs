//! `umbra convert`: write a volume's field as NRRD or NIfTI-1 (format from the output name).

use std::path::{Path, PathBuf};
use volume::{nifti, nrrd, FieldSelector, VolumeError};

#[derive(clap::Args)]
pub struct Args {
    /// Input volume.
    input: PathBuf,
    /// Output file; the format follows the extension.
    #[arg(short, long)]
    output: PathBuf,
    /// Field to write: NAME, NAME:magnitude or NAME:x|y|z.
    #[arg(long, value_parser = super::field_selector)]
    field: Option<FieldSelector>,
    /// Gzip-encode NRRD output.
    #[arg(long)]
    gzip: bool,
}

pub fn run(a: Args) -> Result<(), String> {
    if a.gzip
        && a.output
            .to_string_lossy()
            .to_ascii_lowercase()
            .ends_with(".nii")
    {
        return Err(format!(
            "{}: --gzip encodes NRRD output; a NIfTI file is compressed by naming it .nii.gz",
            a.output.display()
        ));
    }
    convert(&a.input, &a.output, a.field.as_ref(), a.gzip).map_err(|e| e.to_string())?;
    eprintln!("wrote {}", a.output.display());
    Ok(())
}

/// Reads `input`, selects a field, and writes it to `output` (`.nrrd`, `.nii`, `.nii.gz`).
/// `gzip` picks gzip encoding for NRRD (NIfTI follows the `.gz` suffix).
pub fn convert(
    input: &Path,
    output: &Path,
    field: Option<&FieldSelector>,
    gzip: bool,
) -> Result<(), VolumeError> {
    check_volume_output(output)?;
    let vol = volume::load(input)?;
    let f = vol.select(field)?;
    write_field(output, &vol, &f, gzip)
}

/// Checks before any work that `output` names a format [`write_field`] writes and can be
/// written ([`volume::check_output`]).
pub fn check_volume_output(output: &Path) -> Result<(), VolumeError> {
    let name = output.to_string_lossy().to_ascii_lowercase();
    if !(name.ends_with(".nrrd") || name.ends_with(".nii") || name.ends_with(".nii.gz")) {
        return Err(VolumeError::Invalid(format!(
            "{}: output format unknown; use .nrrd, .nii or .nii.gz",
            output.display()
        )));
    }
    volume::check_output(output).map_err(VolumeError::Invalid)
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
