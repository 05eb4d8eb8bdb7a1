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

/// Files that are no volume are named for what they are, not read as a broken NIfTI header
/// (every file of 348 bytes or more once was): text, tractograms, CFD grids.
#[test]
fn files_that_are_no_volume_say_so() {
    let dir = tempfile::tempdir().unwrap();
    let text = "Permission is hereby granted, free of charge, to any person. ".repeat(20);
    for (name, bytes, want) in [
        ("LICENSE.txt", text.as_bytes(), "unknown volume format"),
        ("grid.bin", &[7u8; 4000][..], "unknown volume format"),
        ("t.trk", &[0u8; 1000][..], "a tractogram"),
        ("t.trk.gz", &[0x1f, 0x8b, 8, 0][..], "a tractogram"),
        ("t.tck", b"mrtrix tracks\n".as_slice(), "a tractogram"),
        ("g.vtu", b"<?xml version=\"1.0\"?>".as_slice(), "a CFD grid"),
    ] {
        let p = dir.path().join(name);
        std::fs::write(&p, bytes).unwrap();
        let e = volume::load(&p).unwrap_err().to_string();
        assert!(e.contains(name) && e.contains(want), "{name}: {e}");
        assert!(!e.contains("sizeof_hdr"), "{name}: {e}");
    }
    // A NIfTI header without the usual name is still read as one (big-endian too).
    let nii = test_support::fixtures().join("n1_be_i16_flipx.nii");
    let p = dir.path().join("volume.dat");
    std::fs::copy(&nii, &p).unwrap();
    assert!(volume::load(&p).is_ok());
}

/// Issue 17's hostile headers: products of header fields that overflow 64 bits are refused
/// (the MetaImage product wrapped to 2 and a 2-byte file was accepted as 3 x 6.1e18 x 1), and
/// so are piece extents whose voxel count overflows.
#[test]
fn header_products_that_overflow_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let mha = b"ObjectType = Image\nNDims = 3\nDimSize = 3 6148914691236517206 1\n\
        ElementType = MET_UCHAR\nElementDataFile = LOCAL\nab";
    let e = expect_error(dir.path(), "wrap.mha", mha, None, "DimSize product wraps");
    assert!(e.contains("DimSize"), "{e}");
    let b = std::fs::read(fixtures().join("image_appended_raw.vti")).unwrap();
    let b = replace_once(
        &replace_once(
            &b,
            "WholeExtent=\"0 4 0 3 0 2\"",
            "WholeExtent=\"0 4398046511103 0 4398046511103 0 4398046511103\"",
        ),
        "Extent=\"0 4 0 3 0 2\"",
        "Extent=\"0 4398046511103 0 4398046511103 0 4398046511103\"",
    );
    expect_error(dir.path(), "wrap.vti", &b, None, "extent product wraps");
}

/// Finite but absurd spacings (1e308: infinite bounds), denormal ones (1e-320: zero in f32)
/// and zero ones are refused by every reader, naming the spacing.
#[test]
fn spacings_outside_what_f32_can_draw_are_refused_in_every_reader() {
    let dir = tempfile::tempdir().unwrap();
    let f = fixtures();
    let read = |n: &str| std::fs::read(f.join(n)).unwrap();
    for bad in ["1e308", "1e-320", "1e-30", "1e20"] {
        let cases: Vec<(&str, Vec<u8>)> = vec![
            (
                "s.nrrd",
                replace_once(
                    &read("spacings_ascii.nrrd"),
                    "spacings: 0.5 0.25 4",
                    &format!("spacings: {bad} 0.25 4"),
                ),
            ),
            (
                "s.vtk",
                replace_once(
                    &read("image_ascii.vtk"),
                    "SPACING 0.5 1 2",
                    &format!("SPACING {bad} 1 2"),
                ),
            ),
            (
                "s.vti",
                replace_once(
                    &read("image_ascii.vti"),
                    "Spacing=\"0.5 1 2\"",
                    &format!("Spacing=\"{bad} 1 2\""),
                ),
            ),
            (
                "s.mha",
                replace_once(
                    &read("oblique_i16.mha"),
                    "ElementSpacing = 0.69999999999999996",
                    &format!("ElementSpacing = {bad}"),
                ),
            ),
            (
                "s.slc",
                replace_once(
                    &read("ramp_rle.slc"),
                    "0.5 1.0 2.0",
                    &format!("{bad} 1.0 2.0"),
                ),
            ),
        ];
        for (name, b) in cases {
            let e = expect_error(dir.path(), name, &b, None, bad);
            assert!(
                e.contains("spacing") || e.contains("degenerate") || e.contains("positive"),
                "{name} {bad}: {e}"
            );
        }
        // NIfTI-2: srow_x[0] (f64) set to the value, sform code 2 kept.
        let mut b = read("n2_f64_nan.nii");
        let v: f64 = bad.parse().unwrap();
        b[400..408].copy_from_slice(&v.to_le_bytes());
        let e = expect_error(dir.path(), "s.nii", &b, None, bad);
        assert!(
            e.contains("spacing") || e.contains("singular"),
            "nifti2 {bad}: {e}"
        );
    }
}

/// A NRRD measurement frame that is not a rotation (zero, scaling) is refused: a zero frame
/// turned every vector into (0, 0, 0).
#[test]
fn measurement_frames_that_are_not_rotations_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let b = std::fs::read(fixtures().join("ras_vec_raw.nrrd")).unwrap();
    for frame in [
        "(0,0,0) (0,0,0) (0,0,0)",
        "(2,0,0) (0,2,0) (0,0,2)",
        "(1,0,0) (1,0,0) (0,0,1)",
    ] {
        let bad = replace_once(
            &b,
            "kinds: vector domain domain domain",
            &format!("kinds: vector domain domain domain\nmeasurement frame: {frame}"),
        );
        let e = expect_error(dir.path(), "mf.nrrd", &bad, None, frame);
        assert!(e.contains("measurement frame"), "{frame}: {e}");
    }
    // A rotation is accepted.
    let ok = replace_once(
        &b,
        "kinds: vector domain domain domain",
        "kinds: vector domain domain domain\nmeasurement frame: (0,1,0) (-1,0,0) (0,0,1)",
    );
    assert!(try_load(dir.path(), "mf.nrrd", &ok, None).unwrap().is_ok());
}

/// A header that promises a huge run-length slice, a CELLS count or DIMENSIONS without the
/// data allocates nothing: the SLC slice of 65536 x 65536 in a 51-byte file, `CELLS
/// 4294967296 0` and `DIMENSIONS 4294967296 1 1` are errors at once.
#[test]
fn header_counts_without_their_data_allocate_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let slc = b"11111\n65536 65536 1 8\n1.0 1.0 1.0\n1 6 0 1\n1 1 X\0\0\0 1 X\0";
    let e = expect_error(dir.path(), "big.slc", slc, None, "65536^2 run-length slice");
    assert!(e.contains("slice 0"), "{e}");
    let cells = b"# vtk DataFile Version 3.0\nx\nASCII\nDATASET UNSTRUCTURED_GRID\n\
        POINTS 1 float\n0 0 0\nCELLS 4294967296 0\nCELL_TYPES 0\n";
    let p = dir.path().join("cells.vtk");
    std::fs::write(&p, cells).unwrap();
    assert!(volume::load_grid(&p, None).is_err());
    let dims = b"# vtk DataFile Version 3.0\nx\nASCII\nDATASET STRUCTURED_POINTS\n\
        DIMENSIONS 4294967296 1 1\nSPACING 1 1 1\nORIGIN 0 0 0\n";
    let p = dir.path().join("dims.vtk");
    std::fs::write(&p, dims).unwrap();
    let e = volume::load_grid(&p, None).unwrap_err().to_string();
    assert!(e.contains("POINT_DATA") || e.contains("DIMENSIONS"), "{e}");
}

/// Devices, directories and pipes are refused before a byte is read (a /dev/zero data file
/// was read until memory ran out); a detached data file that is a device too.
#[cfg(unix)]
#[test]
fn special_files_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let e = volume::load(Path::new("/dev/zero"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("regular file"), "{e}");
    let link = dir.path().join("zero.nii");
    std::os::unix::fs::symlink("/dev/zero", &link).unwrap();
    let e = volume::load(&link).unwrap_err().to_string();
    assert!(e.contains("regular file"), "{e}");
    let nhdr = b"NRRD0004\ntype: uint8\ndimension: 3\nsizes: 2 2 2\nencoding: raw\n\
        data file: /dev/urandom\n";
    let e = expect_error(dir.path(), "dev.nhdr", nhdr, None, "/dev/urandom data file");
    assert!(e.contains("regular file"), "{e}");
    let e = volume::load(dir.path()).unwrap_err().to_string();
    assert!(e.contains("directory") || e.contains("regular"), "{e}");
}

/// Header text quoted in an error is cut: a 5 MB header line gives a short message.
#[test]
fn errors_quote_at_most_a_few_hundred_bytes_of_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let long = "x".repeat(5 << 20);
    let nrrd = format!("NRRD0004\ntype: {long}\ndimension: 3\nsizes: 2 2 2\nencoding: raw\n\n");
    let e = expect_error(dir.path(), "long.nrrd", nrrd.as_bytes(), None, "5 MB line");
    assert!(e.len() < 1000, "{} bytes of error", e.len());
    let mha = format!("ObjectType = Image\nNDims = 3\nDimSize = {long}\n");
    let e = expect_error(dir.path(), "long.mha", mha.as_bytes(), None, "5 MB line");
    assert!(e.len() < 1000, "{} bytes of error", e.len());
}

/// A broken volume with a volume's name is reported by its reader, never read as a PLOT3D
/// grid (which has no signature).
#[test]
fn volume_names_are_never_guessed_as_plot3d_grids() {
    let dir = tempfile::tempdir().unwrap();
    // 12 bytes that parse as a PLOT3D header of 1 x 1 x 1 and then 3 floats.
    let mut b = Vec::new();
    for v in [1i32, 1, 1] {
        b.extend_from_slice(&v.to_le_bytes());
    }
    for v in [0f32, 0.0, 0.0] {
        b.extend_from_slice(&v.to_le_bytes());
    }
    let p = dir.path().join("broken.nii");
    std::fs::write(&p, &b).unwrap();
    let e = volume::load_grid(&p, None).unwrap_err().to_string();
    assert!(e.contains("volume format"), "{e}");
}

/// Pieces of a `.vti` that overlap can hide a gap from the value count (20 NaN voxels were read
/// without a word): points no piece covers are an error; pieces that share a boundary (as VTK
/// writes them) are fine.
#[test]
fn vti_pieces_that_leave_a_gap_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let doc = |pieces: &[(&str, &str)]| {
        let mut s = String::from(
            "<?xml version=\"1.0\"?>\n<VTKFile type=\"ImageData\" version=\"0.1\" \
             byte_order=\"LittleEndian\">\n<ImageData WholeExtent=\"0 4 0 0 0 0\" \
             Origin=\"0 0 0\" Spacing=\"1 1 1\">\n",
        );
        for (e, v) in pieces {
            s += &format!(
                "<Piece Extent=\"{e}\"><PointData Scalars=\"d\"><DataArray type=\"Float32\" \
                 Name=\"d\" format=\"ascii\">{v}</DataArray></PointData></Piece>\n"
            );
        }
        s + "</ImageData>\n</VTKFile>\n"
    };
    // Two pieces over points 0-2: six values for five points, points 3 and 4 uncovered.
    let gap = doc(&[("0 2 0 0 0 0", "0 1 2"), ("0 2 0 0 0 0", "0 1 2")]);
    let e = expect_error(
        dir.path(),
        "gap.vti",
        gap.as_bytes(),
        None,
        "overlap hiding a gap",
    );
    assert!(e.contains("2 of") && e.contains("uncovered"), "{e}");
    // Pieces sharing point 2, as VTK splits an extent.
    let ok = doc(&[("0 2 0 0 0 0", "0 1 2"), ("2 4 0 0 0 0", "2 3 4")]);
    let v = try_load(dir.path(), "ok.vti", ok.as_bytes(), None)
        .unwrap()
        .unwrap();
    assert_eq!(v.fields[0].data, vec![0.0, 1.0, 2.0, 3.0, 4.0]);
}

/// A zero or NaN voxel size in `pixdim`, where the frame comes from it (no sform), is read as
/// 1 (as nibabel does) with a warning, not in silence.
#[test]
fn zero_voxel_sizes_read_as_one_with_a_warning() {
    let dir = tempfile::tempdir().unwrap();
    let mut b = std::fs::read(fixtures().join("n1_nocode_f32.nii")).unwrap();
    b[80..84].copy_from_slice(&0f32.to_le_bytes());
    b[84..88].copy_from_slice(&f32::NAN.to_le_bytes());
    let v = try_load(dir.path(), "z.nii", &b, None).unwrap().unwrap();
    assert_eq!(v.spacing()[0], 1.0);
    assert_eq!(v.spacing()[1], 1.0);
    let w = v.warnings.join("; ");
    assert!(
        w.contains("pixdim[1] = 0") && w.contains("pixdim[2] = NaN"),
        "{w}"
    );
}

/// VTK XML elements with very many attributes are refused at once (quick-xml's duplicate check
/// is quadratic: 120,000 attributes took over 20 s), and a repeated attribute is an error.
#[test]
fn xml_attribute_floods_and_repeats_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let b = std::fs::read(fixtures().join("image_ascii.vti")).unwrap();
    let many: String = (0..120_000).map(|i| format!(" a{i}=\"{i}\"")).collect();
    let flood = replace_once(&b, "<ImageData ", &format!("<ImageData{many} "));
    let e = expect_error(dir.path(), "flood.vti", &flood, None, "120k attributes");
    assert!(e.contains("64 attributes"), "{e}");
    let rep = replace_once(&b, "<ImageData ", "<ImageData Origin=\"0 0 0\" ");
    let e = expect_error(dir.path(), "rep.vti", &rep, None, "repeated Origin");
    assert!(e.contains("'Origin' repeated"), "{e}");
}
