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
    let warnings =
        convert(&a.input, &a.output, a.field.as_ref(), a.gzip).map_err(|e| e.to_string())?;
    for w in &warnings {
        eprintln!("umbra: warning: {}: {w}", a.input.display());
    }
    eprintln!("wrote {}", a.output.display());
    Ok(())
}

/// Reads `input`, selects a field, and writes it to `output` (`.nrrd`, `.nii`, `.nii.gz`).
/// `gzip` picks gzip encoding for NRRD (NIfTI follows the `.gz` suffix). Returns what the
/// user should know: the reader's warnings (a time series written as its frame 0), values
/// the 32-bit float samples could not hold exactly, an anatomical frame NIfTI adds.
pub fn convert(
    input: &Path,
    output: &Path,
    field: Option<&FieldSelector>,
    gzip: bool,
) -> Result<Vec<String>, VolumeError> {
    check_volume_output(output)?;
    let vol = volume::load(input)?;
    let f = vol
        .select(field)
        .map_err(|e| VolumeError::Invalid(format!("{}: {e}", input.display())))?;
    if volume::check_not_input(&[Some(input)], &[Some(output)]).is_err() {
        // In place, on purpose (through a temporary file): the one input a command rewrites.
        volume::forget_input(input);
    }
    write_field(output, &vol, &f, gzip)?;
    let mut warnings = vol.warnings.clone();
    warnings.extend(precision_warning(&f));
    warnings.extend(frame_warning(&vol, output));
    Ok(warnings)
}

/// A volume in its file's own frame written as NIfTI, which declares RAS+: the warning that
/// says so (a CFD field in metres would get R/L labels and "mm" bars).
pub fn frame_warning(vol: &volume::Volume, output: &Path) -> Option<String> {
    let nifti = output.to_string_lossy().to_ascii_lowercase();
    (vol.space == volume::Space::File && (nifti.ends_with(".nii") || nifti.ends_with(".nii.gz")))
        .then(|| {
            "its frame is its own (no anatomical orientation declared), and NIfTI declares \
             RAS+ (sform and qform code 1): readers of the output, umbra included, label its \
             axes R/L, A/P, S/I; write .nrrd to keep the file's own frame"
                .into()
        })
}

/// What the `f32` samples could not hold of a wider stored type: float64 rounded to single
/// precision, integers past 2^24 in magnitude rounded; the output keeps the stored type, so the
/// values it holds are the rounded ones.
fn precision_warning(f: &volume::Field) -> Option<String> {
    use volume::ScalarType as T;
    let wide_int = matches!(f.stored, T::I32 | T::U32 | T::I64 | T::U64);
    let beyond = f
        .data
        .iter()
        .filter(|v| v.is_finite() && v.abs() >= 16_777_216.0)
        .count();
    match f.stored {
        T::F64 => Some(format!(
            "field {}: float64 samples are held as 32-bit floats (about 7 significant digits; \
             magnitudes past 3.4e38 become infinite) and written as float64 of those values",
            f.name
        )),
        _ if wide_int && beyond > 0 => Some(format!(
            "field {}: {beyond} samples are at or past 2^24 = 16777216 in magnitude, where 32-bit \
             floats hold only some integers: they are rounded to the nearest they hold",
            f.name
        )),
        _ => None,
    }
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
