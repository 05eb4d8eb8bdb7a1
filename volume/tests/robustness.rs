//! Malformed input never panics, never hangs and never allocates from an unchecked header
//! field: truncated copies of every fixture at many offsets, flipped header bytes, header
//! dimensions that disagree with the data, broken gzip/zlib streams and absurd dimensions.

use std::path::{Path, PathBuf};
use test_support::fixtures;
use volume::Volume;

/// Fixture files (main file, companion data file if detached).
fn cases() -> Vec<(PathBuf, Option<PathBuf>)> {
    let mut v = Vec::new();
    for entry in std::fs::read_dir(fixtures()).unwrap() {
        let p = entry.unwrap().path();
        let name = p.file_name().unwrap().to_string_lossy().to_string();
        if p.is_dir() || name.ends_with(".json") || name.ends_with(".py") || name.ends_with(".raw")
        {
            continue;
        }
        let companion = match p.extension().and_then(|e| e.to_str()) {
            Some("nhdr") | Some("mhd") => Some(p.with_extension("raw")),
            _ => None,
        };
        v.push((p, companion));
    }
    v.sort();
    assert!(v.len() >= 25);
    v
}

/// Loads `bytes` written under `name` (companion copied beside it) without letting a panic
/// escape: returns Err(message) for a panic.
fn try_load(
    dir: &Path,
    name: &str,
    bytes: &[u8],
    companion: Option<(&str, &[u8])>,
) -> Result<volume::Result<Volume>, String> {
    let p = dir.join(name);
    std::fs::write(&p, bytes).unwrap();
    if let Some((cn, cb)) = companion {
        std::fs::write(dir.join(cn), cb).unwrap();
    }
    std::panic::catch_unwind(|| volume::load(&p)).map_err(|e| {
        e.downcast_ref::<String>()
            .cloned()
            .or_else(|| e.downcast_ref::<&str>().map(|s| s.to_string()))
            .unwrap_or_default()
    })
}

/// What a cut can leave readable in formats without an end marker (VTK legacy and ASCII data):
/// the first arrays of the original, equal but possibly for the very last sample read (a
/// truncated ASCII number is still a number, and a legacy file may end after any array).
fn readable_prefix(cut: &Volume, full: &Volume) -> bool {
    if cut.dims != full.dims || cut.fields.is_empty() || cut.fields.len() > full.fields.len() {
        return false;
    }
    let n = cut.fields.len();
    cut.fields
        .iter()
        .zip(&full.fields)
        .enumerate()
        .all(|(i, (x, y))| {
            let len = x.data.len();
            x.name == y.name
                && len == y.data.len()
                && x.data.iter().zip(&y.data).enumerate().all(|(j, (p, q))| {
                    p.to_bits() == q.to_bits()
                        || (p.is_nan() && q.is_nan())
                        || (i + 1 == n && j + 1 == len)
                })
        })
}

fn offsets(len: usize) -> Vec<usize> {
    if len <= 2500 {
        (0..len).collect()
    } else {
        let mut v: Vec<usize> = (0..600.min(len)).collect();
        v.extend((600..len).step_by((len / 400).max(1)));
        v.push(len - 1);
        v
    }
}

#[test]
fn truncated_files_give_errors() {
    let dir = tempfile::tempdir().unwrap();
    for (path, companion) in cases() {
        let name = path.file_name().unwrap().to_str().unwrap();
        let bytes = std::fs::read(&path).unwrap();
        let comp = companion.as_ref().map(|c| {
            (
                c.file_name().unwrap().to_str().unwrap().to_string(),
                std::fs::read(c).unwrap(),
            )
        });
        let original = volume::load(&path).unwrap();
        // Truncate the main file.
        for cut in offsets(bytes.len()) {
            let r = try_load(
                dir.path(),
                name,
                &bytes[..cut],
                comp.as_ref().map(|(n, b)| (n.as_str(), b.as_slice())),
            );
            match r {
                Err(panic) => panic!("{name} cut at {cut}: panic: {panic}"),
                Ok(Ok(v)) => {
                    let tail_blank = bytes[cut..].iter().all(|b| b.is_ascii_whitespace());
                    let legacy_or_ascii = name.ends_with(".vtk") || name.contains("ascii");
                    assert!(
                        tail_blank || (legacy_or_ascii && readable_prefix(&v, &original)),
                        "{name} cut at {cut} of {} read without error",
                        bytes.len()
                    );
                }
                Ok(Err(e)) => assert!(
                    e.to_string().contains(name),
                    "{name}: error does not name the file: {e}"
                ),
            }
        }
        // Truncate the companion data file.
        if let Some((cname, cbytes)) = &comp {
            for cut in offsets(cbytes.len()) {
                let r = try_load(dir.path(), name, &bytes, Some((cname, &cbytes[..cut])));
                match r {
                    Err(panic) => panic!("{cname} cut at {cut}: panic: {panic}"),
                    Ok(Ok(_)) => panic!("{name} with {cname} cut at {cut} read without error"),
                    Ok(Err(e)) => assert!(
                        e.to_string().contains(cname.as_str()),
                        "error does not name the data file: {e}"
                    ),
                }
            }
        }
    }
}

#[test]
fn flipped_header_bytes_never_panic() {
    let dir = tempfile::tempdir().unwrap();
    for (path, companion) in cases() {
        let name = path.file_name().unwrap().to_str().unwrap();
        let bytes = std::fs::read(&path).unwrap();
        let comp = companion.as_ref().map(|c| {
            (
                c.file_name().unwrap().to_str().unwrap().to_string(),
                std::fs::read(c).unwrap(),
            )
        });
        let head = bytes.len().min(700);
        for pos in 0..head {
            for mask in [0xffu8, 0x01, 0x40] {
                let mut b = bytes.clone();
                b[pos] ^= mask;
                match try_load(
                    dir.path(),
                    name,
                    &b,
                    comp.as_ref().map(|(n, b)| (n.as_str(), b.as_slice())),
                ) {
                    Err(panic) => panic!("{name} byte {pos} ^ {mask:#x}: panic: {panic}"),
                    Ok(Ok(v)) => v.validate().unwrap(),
                    Ok(Err(_)) => {}
                }
            }
        }
    }
}

fn replace_once(bytes: &[u8], from: &str, to: &str) -> Vec<u8> {
    let pos = bytes
        .windows(from.len())
        .position(|w| w == from.as_bytes())
        .unwrap_or_else(|| panic!("'{from}' not found"));
    let mut out = bytes[..pos].to_vec();
    out.extend_from_slice(to.as_bytes());
    out.extend_from_slice(&bytes[pos + from.len()..]);
    out
}

fn expect_error(
    dir: &Path,
    name: &str,
    bytes: &[u8],
    companion: Option<(&str, &[u8])>,
    what: &str,
) -> String {
    match try_load(dir, name, bytes, companion) {
        Err(p) => panic!("{name} ({what}): panic: {p}"),
        Ok(Ok(_)) => panic!("{name} ({what}): read without error"),
        Ok(Err(e)) => e.to_string(),
    }
}

#[test]
fn dimensions_that_disagree_with_the_data_are_errors() {
    let dir = tempfile::tempdir().unwrap();
    let f = fixtures();
    let read = |n: &str| std::fs::read(f.join(n)).unwrap();
    // Text headers: one dimension larger and one smaller than the data.
    let text_cases: &[(&str, &str, &[&str])] = &[
        (
            "ras_vec_raw.nrrd",
            "sizes: 3 5 4 3",
            &["sizes: 3 5 4 4", "sizes: 3 5 4 2"],
        ),
        (
            "spacings_ascii.nrrd",
            "sizes: 5 4 3",
            &["sizes: 5 4 4", "sizes: 5 4 2"],
        ),
        (
            "lps_i16_gzip_be.nrrd",
            "sizes: 5 4 3",
            &["sizes: 5 4 4", "sizes: 5 4 2"],
        ),
        (
            "image_binary.vtk",
            "DIMENSIONS 5 4 3",
            &["DIMENSIONS 5 4 4", "DIMENSIONS 5 4 2"],
        ),
        (
            "image_ascii.vtk",
            "DIMENSIONS 5 4 3",
            &["DIMENSIONS 5 4 4", "DIMENSIONS 5 4 2"],
        ),
        (
            "oblique_i16.mha",
            "DimSize = 5 4 3",
            &["DimSize = 5 4 4", "DimSize = 5 4 2"],
        ),
        ("ramp_raw.slc", "5 4 3 8", &["5 4 4 8", "5 4 2 8"]),
        ("ramp_rle.slc", "5 4 3 8", &["5 4 4 8", "5 4 2 8"]),
    ];
    for (name, from, tos) in text_cases {
        for to in *tos {
            let b = replace_once(&read(name), from, to);
            let e = expect_error(dir.path(), name, &b, None, to);
            assert!(e.contains(name), "{e}");
        }
    }
    for name in [
        "image_binary.vti",
        "image_appended_raw.vti",
        "image_binary_zlib.vti",
        "image_ascii.vti",
    ] {
        let b = replace_once(
            &read(name),
            "WholeExtent=\"0 4 0 3 0 2\"",
            "WholeExtent=\"0 4 0 3 0 3\"",
        );
        let b = replace_once(&b, "Extent=\"0 4 0 3 0 2\"", "Extent=\"0 4 0 3 0 3\"");
        expect_error(dir.path(), name, &b, None, "larger extent");
    }
    let mhd = read("vector_f32.mhd");
    let raw = read("vector_f32.raw");
    for to in ["DimSize = 5 4 4", "DimSize = 5 4 2"] {
        let b = replace_once(&mhd, "DimSize = 5 4 3", to);
        expect_error(
            dir.path(),
            "vector_f32.mhd",
            &b,
            Some(("vector_f32.raw", &raw)),
            to,
        );
    }
    // NIfTI: dim[3] (offset 46, int16, this file is big-endian) one larger and one smaller.
    let nii = read("n1_be_i16_flipx.nii");
    for nz in [4i16, 2] {
        let mut b = nii.clone();
        b[46..48].copy_from_slice(&nz.to_be_bytes());
        let e = expect_error(dir.path(), "n1_be_i16_flipx.nii", &b, None, "dim[3]");
        assert!(e.contains("data"), "{e}");
    }
}

#[test]
fn broken_compressed_streams_are_errors() {
    let dir = tempfile::tempdir().unwrap();
    let f = fixtures();
    for name in [
        "n1_qform_u16.nii.gz",
        "n1_i32.nii.gz",
        "lps_i16_gzip_be.nrrd",
        "oblique_i16.mha",
        "image_binary_zlib.vti",
        "image_appended_raw_zlib_u64_be.vti",
    ] {
        let bytes = std::fs::read(f.join(name)).unwrap();
        // Corrupt a run of bytes in the last third (inside the compressed data).
        let start = bytes.len() * 2 / 3;
        for (k, pos) in (start..bytes.len().min(start + 24)).enumerate() {
            let mut b = bytes.clone();
            b[pos] = b[pos].wrapping_add(37 + k as u8);
            if name.ends_with(".vti") && !b[pos].is_ascii_graphic() && bytes[pos].is_ascii_graphic()
            {
                continue;
            }
            match try_load(dir.path(), name, &b, None) {
                Err(p) => panic!("{name} byte {pos}: panic: {p}"),
                Ok(Ok(v)) => {
                    // A changed byte that zlib accepts (a literal) changes data, not structure.
                    v.validate().unwrap();
                }
                Ok(Err(_)) => {}
            }
        }
        // A stream cut in half is always an error.
        let half = &bytes[..bytes.len() * 3 / 4];
        expect_error(dir.path(), name, half, None, "cut stream");
    }
}

#[test]
fn absurd_dimensions_are_refused_without_allocating() {
    let dir = tempfile::tempdir().unwrap();
    let f = fixtures();
    let read = |n: &str| std::fs::read(f.join(n)).unwrap();
    // 2^31 voxels and more, with a few bytes of data.
    let cases: Vec<(&str, Vec<u8>)> = vec![
        (
            "spacings_ascii.nrrd",
            replace_once(
                &read("spacings_ascii.nrrd"),
                "sizes: 5 4 3",
                "sizes: 2048 1024 1024",
            ),
        ),
        (
            "lps_i16_gzip_be.nrrd",
            replace_once(
                &read("lps_i16_gzip_be.nrrd"),
                "sizes: 5 4 3",
                "sizes: 2048 1024 1024",
            ),
        ),
        (
            "ras_vec_raw.nrrd",
            replace_once(
                &read("ras_vec_raw.nrrd"),
                "sizes: 3 5 4 3",
                "sizes: 3 99999999 99999999 99999999",
            ),
        ),
        (
            "image_binary.vtk",
            replace_once(
                &replace_once(
                    &read("image_binary.vtk"),
                    "DIMENSIONS 5 4 3",
                    "DIMENSIONS 2048 1024 1024",
                ),
                "POINT_DATA 60",
                "POINT_DATA 2147483648",
            ),
        ),
        (
            "image_ascii.vtk",
            replace_once(
                &replace_once(
                    &read("image_ascii.vtk"),
                    "DIMENSIONS 5 4 3",
                    "DIMENSIONS 2048 1024 1024",
                ),
                "POINT_DATA 60",
                "POINT_DATA 2147483648",
            ),
        ),
        (
            "oblique_i16.mha",
            replace_once(
                &read("oblique_i16.mha"),
                "DimSize = 5 4 3",
                "DimSize = 2048 1024 1024",
            ),
        ),
        (
            "ramp_rle.slc",
            replace_once(&read("ramp_rle.slc"), "5 4 3 8", "2048 1024 1024 8"),
        ),
        (
            "image_appended_raw.vti",
            replace_once(
                &replace_once(
                    &read("image_appended_raw.vti"),
                    "WholeExtent=\"0 4 0 3 0 2\"",
                    "WholeExtent=\"0 2047 0 1023 0 1023\"",
                ),
                "Extent=\"0 4 0 3 0 2\"",
                "Extent=\"0 2047 0 1023 0 1023\"",
            ),
        ),
    ];
    for (name, b) in cases {
        expect_error(dir.path(), name, &b, None, "absurd dims");
    }
    for (name, off, be) in [
        ("n1_be_i16_flipx.nii", 42usize, true),
        ("n1_u32.nii", 42, false),
    ] {
        let mut b = read(name);
        for (k, d) in [2048i16, 1024, 1024].iter().enumerate() {
            let bytes = if be { d.to_be_bytes() } else { d.to_le_bytes() };
            b[off + 2 * k..off + 2 * k + 2].copy_from_slice(&bytes);
        }
        expect_error(dir.path(), name, &b, None, "absurd dims");
    }
    // NIfTI-2 with 2^62 voxels.
    let mut b = read("n2_f64_nan.nii");
    for k in 0..3 {
        b[24 + 8 * k..32 + 8 * k].copy_from_slice(&(1i64 << 21).to_le_bytes());
    }
    let e = expect_error(dir.path(), "n2_f64_nan.nii", &b, None, "2^63 voxels");
    assert!(e.contains("refusing") || e.contains("too large"), "{e}");
}

#[test]
fn empty_and_garbage_files_are_errors() {
    let dir = tempfile::tempdir().unwrap();
    for name in [
        "a.nii",
        "a.nii.gz",
        "a.nrrd",
        "a.nhdr",
        "a.vtk",
        "a.vti",
        "a.mhd",
        "a.mha",
        "a.slc",
        "a.unknown",
    ] {
        expect_error(dir.path(), name, b"", None, "empty");
        expect_error(
            dir.path(),
            name,
            b"\x00\x01garbage\xff\xfe not a volume at all",
            None,
            "garbage",
        );
    }
    let missing = volume::load(&dir.path().join("missing.nii"))
        .unwrap_err()
        .to_string();
    assert!(missing.contains("missing.nii"), "{missing}");
}
