//! Writers round-trip what the readers read: every fixture and shared volume, every field,
//! through NRRD (raw and gzip) and NIfTI-1 (.nii and .nii.gz), read back with identical voxels
//! and affine (NIfTI stores the affine as float32, so there the affine agrees to f32 rounding,
//! and vector components, rotated into FSL's voxel frame by the f64 affine and back by its f32
//! copy, to 1e-5 relative).

use glam::{DMat4, DVec4};
use std::path::Path;
use test_support::{close, fixtures, shared_data};
use volume::{nifti, nrrd, synthetic, Field, ScalarType, Space, Volume};

fn same_bits(a: &[f32], b: &[f32]) -> bool {
    a.len() == b.len()
        && a.iter()
            .zip(b)
            .all(|(x, y)| x.to_bits() == y.to_bits() || (x.is_nan() && y.is_nan()))
}

fn check_roundtrip(label: &str, vol: &Volume, dir: &Path) {
    for (fi, field) in vol.fields.iter().enumerate() {
        let base = dir.join(format!("f{fi}"));
        // NRRD: exact.
        for (enc, ext) in [
            (nrrd::WriteEncoding::Raw, "raw.nrrd"),
            (nrrd::WriteEncoding::Gzip, "gz.nrrd"),
        ] {
            let p = base.with_extension(ext);
            nrrd::write(&p, vol, field, enc).unwrap_or_else(|e| panic!("{label}: {e}"));
            let back = volume::load(&p).unwrap_or_else(|e| panic!("{label} {ext}: {e}"));
            let f = back.default();
            assert_eq!(back.dims, vol.dims, "{label} {ext}");
            assert_eq!(back.affine, vol.affine, "{label} {ext}: affine");
            assert_eq!(back.space, vol.space, "{label} {ext}: space");
            assert_eq!(f.components, field.components, "{label} {ext}");
            if field.stored.holds_all(&field.data) {
                assert_eq!(f.stored, field.stored, "{label} {ext}: stored type");
            } else {
                assert_eq!(
                    f.stored,
                    ScalarType::F32,
                    "{label} {ext}: scaled data are written as float"
                );
            }
            assert!(
                same_bits(&f.data, &field.data),
                "{label} {ext}: voxels differ"
            );
        }
        // NIfTI-1.
        for ext in ["nii", "nii.gz"] {
            let p = base.with_extension(ext);
            nifti::write(&p, vol, field).unwrap_or_else(|e| panic!("{label}: {e}"));
            let back = volume::load(&p).unwrap_or_else(|e| panic!("{label} {ext}: {e}"));
            let f = back.default();
            assert_eq!(back.dims, vol.dims, "{label} {ext}");
            assert_eq!(
                back.space,
                Space::Ras,
                "{label} {ext}: NIfTI with an sform is RAS"
            );
            for c in 0..4 {
                for r in 0..4 {
                    let (a, b) = (back.affine.col(c)[r], vol.affine.col(c)[r]);
                    assert!(
                        close(a, b, 1e-6, 1e-6),
                        "{label} {ext}: affine[{r}][{c}] {a} vs {b}"
                    );
                }
            }
            assert_eq!(f.components, field.components, "{label} {ext}");
            if field.components == 1 {
                assert!(
                    same_bits(&f.data, &field.data),
                    "{label} {ext}: voxels differ"
                );
                if field.stored.holds_all(&field.data) {
                    assert_eq!(f.stored, field.stored, "{label} {ext}: stored type");
                }
            } else {
                for (a, b) in f.data.iter().zip(&field.data) {
                    assert!(
                        (a - b).abs() <= 1e-5 * b.abs().max(1.0) || (a.is_nan() && b.is_nan()),
                        "{label} {ext}: vector {a} vs {b}"
                    );
                }
            }
        }
    }
}

#[test]
fn fixtures_round_trip_through_both_writers() {
    let dir = tempfile::tempdir().unwrap();
    let mut n = 0;
    for entry in std::fs::read_dir(fixtures()).unwrap() {
        let p = entry.unwrap().path();
        let name = p.file_name().unwrap().to_string_lossy().to_string();
        if p.is_dir() || name.ends_with(".json") || name.ends_with(".py") || name.ends_with(".raw")
        {
            continue;
        }
        let vol = volume::load(&p).unwrap_or_else(|e| panic!("{e}"));
        check_roundtrip(&name, &vol, dir.path());
        n += 1;
    }
    assert!(n >= 25, "only {n} fixtures");
}

#[test]
fn shared_volumes_round_trip() {
    let Some(data) = shared_data() else {
        eprintln!("SKIP shared_volumes_round_trip: ../shared/data is absent");
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    for f in [
        "mri/headsq_64x64x93.nhdr",
        "mri/HeadMRVolume.mhd",
        "volumes/ironProt.vtk",
        "volumes/hydrogen.vti",
        "volumes/neghip.slc",
        "cfd/heart.vti",
        "cfd/carotid.vtk",
        "dti/V1.nii.gz",
        "dti/FA.nii.gz",
        "mri/mni_icbm152_t1_tal_nlin_sym_09a.nii.gz",
    ] {
        let vol = volume::load(&data.join(f)).unwrap();
        check_roundtrip(f, &vol, dir.path());
    }
}

#[test]
fn synthetic_types_and_oblique_affines_round_trip() {
    let dir = tempfile::tempdir().unwrap();
    let (c, s) = (0.6f64.cos(), 0.6f64.sin());
    let affine = DMat4::from_cols(
        DVec4::new(0.75 * c, 0.75 * s, 0.0, 0.0),
        DVec4::new(-1.25 * s, 1.25 * c, 0.0, 0.0),
        DVec4::new(0.0, 0.0, -2.5, 0.0),
        DVec4::new(-12.5, 40.25, 3.0, 1.0),
    );
    let dims = [7, 5, 4];
    let n = 7 * 5 * 4;
    for ty in [
        ScalarType::U8,
        ScalarType::I8,
        ScalarType::U16,
        ScalarType::I16,
        ScalarType::U32,
        ScalarType::I32,
        ScalarType::U64,
        ScalarType::I64,
        ScalarType::F32,
        ScalarType::F64,
    ] {
        let (lo, _) = ty.value_range();
        let data: Vec<f32> = (0..n)
            .map(|i| {
                if lo < 0.0 {
                    i as f32 - 60.0
                } else {
                    i as f32 * 1.5f32.floor()
                }
            })
            .collect();
        let mut data = data;
        if !ty.is_integer() {
            data[3] = f32::NAN;
            data[4] = f32::NEG_INFINITY;
            data[5] = 1.0e-30;
        }
        for space in [Space::Ras, Space::File] {
            let vol = Volume::new(
                dims,
                affine,
                space,
                Field {
                    name: "v".into(),
                    components: 1,
                    stored: ty,
                    data: data.clone(),
                },
            )
            .unwrap();
            check_roundtrip(&format!("{ty:?} {space:?}"), &vol, dir.path());
        }
    }
    let abc = synthetic::sample_vector(&synthetic::AbcFlow::default(), dims, affine, "abc");
    check_roundtrip("abc vectors", &abc, dir.path());
    let mut lps_like = abc.clone();
    lps_like.affine = DMat4::from_diagonal(DVec4::new(2.0, 2.0, 2.0, 1.0)); // det > 0: FSL flip path
    check_roundtrip("abc vectors, det > 0", &lps_like, dir.path());
}

#[test]
fn values_that_do_not_fit_the_stored_type_are_written_as_float() {
    let dir = tempfile::tempdir().unwrap();
    let vol = Volume::new(
        [2, 2, 1],
        DMat4::IDENTITY,
        Space::File,
        Field {
            name: "x".into(),
            components: 1,
            stored: ScalarType::U8,
            data: vec![0.5, 300.0, -1.0, 2.0],
        },
    )
    .unwrap();
    for ext in ["a.nrrd", "a.nii"] {
        let p = dir.path().join(ext);
        if ext.ends_with("nrrd") {
            nrrd::write(&p, &vol, &vol.fields[0], nrrd::WriteEncoding::Raw).unwrap();
        } else {
            nifti::write(&p, &vol, &vol.fields[0]).unwrap();
        }
        let back = volume::load(&p).unwrap();
        assert_eq!(back.default().stored, ScalarType::F32);
        assert_eq!(back.default().data, vec![0.5, 300.0, -1.0, 2.0]);
    }
}
