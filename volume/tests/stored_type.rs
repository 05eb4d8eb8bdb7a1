//! Issue 18: `volume::load_scalar` reads a scalar field of 8 or 16-bit integers in its stored
//! type (NIfTI, NRRD raw and gzip, MetaImage), with exactly the values `volume::load` gives
//! as f32; every other field (floats, scaled NIfTI, a field chosen by name among several, a
//! component) falls back to f32, and a vector field is refused.

use glam::DMat4;
use test_support::shared_or_skip;
use volume::samples::Packing;
use volume::{Field, FieldSelector, ScalarType, Space, Volume};

fn volume_of(ty: ScalarType, values: impl Fn(usize) -> f32) -> Volume {
    let dims = [7, 5, 3];
    let data: Vec<f32> = (0..105).map(values).collect();
    let field = Field {
        name: "v".into(),
        components: 1,
        stored: ty,
        data,
    };
    let affine = DMat4::from_scale(glam::DVec3::new(1.5, 2.0, 0.5));
    Volume::new(dims, affine, Space::Ras, field).unwrap()
}

/// The field read by `load_scalar` equals `load`'s, in the packing `want`.
fn same_as_load(path: &std::path::Path, want: Packing) {
    let whole = volume::load(path).unwrap();
    let f = volume::load_scalar(path, None).unwrap();
    assert_eq!(f.samples.packing(), want, "{}", path.display());
    assert_eq!(f.volume.dims, whole.dims);
    assert_eq!(f.volume.affine, whole.affine);
    assert_eq!(f.name, whole.default().name);
    assert_eq!(f.stored, whole.default().stored);
    assert_eq!(
        f.samples.to_f32().as_ref(),
        whole.default().data.as_slice(),
        "{}",
        path.display()
    );
    assert!(
        f.volume.fields.iter().all(|f| f.data.is_empty()),
        "the grid holds no samples"
    );
}

#[test]
fn eight_and_sixteen_bit_fields_are_read_in_their_stored_type() {
    let d = tempfile::tempdir().unwrap();
    let cases = [
        (
            ScalarType::U8,
            Packing::U8 { offset: 0.0 },
            0.0f32,
            255.0f32,
        ),
        (
            ScalarType::I8,
            Packing::U8 { offset: -128.0 },
            -128.0,
            127.0,
        ),
        (ScalarType::U16, Packing::U16 { offset: 0.0 }, 0.0, 65535.0),
        (
            ScalarType::I16,
            Packing::U16 { offset: -32768.0 },
            -32768.0,
            32767.0,
        ),
    ];
    for (ty, want, lo, hi) in cases {
        // Both ends of the type's range, and values between.
        let vol = volume_of(ty, |i| match i {
            0 => lo,
            1 => hi,
            _ => (lo + (i as f32 * 7919.0) % (hi - lo)).round(),
        });
        let name = ty.name();
        for (file, write) in [
            ("raw.nrrd", 0),
            ("gz.nrrd", 1),
            ("one.nii", 2),
            ("one.nii.gz", 2),
        ] {
            let p = d.path().join(format!("{name}_{file}"));
            match write {
                0 => volume::nrrd::write(&p, &vol, vol.default(), volume::nrrd::WriteEncoding::Raw),
                1 => {
                    volume::nrrd::write(&p, &vol, vol.default(), volume::nrrd::WriteEncoding::Gzip)
                }
                _ => volume::nifti::write(&p, &vol, vol.default()),
            }
            .unwrap();
            assert_eq!(volume::load(&p).unwrap().default().stored, ty, "{file}");
            same_as_load(&p, want);
        }
    }
}

#[test]
fn other_fields_are_read_as_f32_and_vectors_are_refused() {
    let d = tempfile::tempdir().unwrap();
    // Floats stay f32.
    let floats = volume_of(ScalarType::F32, |i| i as f32 * 0.25);
    let p = d.path().join("f.nrrd");
    volume::nrrd::write(
        &p,
        &floats,
        floats.default(),
        volume::nrrd::WriteEncoding::Raw,
    )
    .unwrap();
    same_as_load(&p, Packing::F32);
    // A named field: the default one by name is read as stored; a missing one is an error
    // naming the fields there are.
    let ints = volume_of(ScalarType::U16, |i| (i * 300) as f32);
    let p = d.path().join("u.nrrd");
    volume::nrrd::write(&p, &ints, ints.default(), volume::nrrd::WriteEncoding::Raw).unwrap();
    let by_name: FieldSelector = "v".parse().unwrap();
    let f = volume::load_scalar(&p, Some(&by_name)).unwrap();
    assert_eq!(f.samples.packing(), Packing::U16 { offset: 0.0 });
    let e = volume::load_scalar(&p, Some(&"w".parse().unwrap())).unwrap_err();
    assert!(e.to_string().contains("no such field"), "{e}");
    // A vector field: refused whole, its magnitude read as f32.
    let vectors = volume::synthetic::rotation_slab();
    let p = d.path().join("vec.nrrd");
    volume::nrrd::write(
        &p,
        &vectors,
        vectors.default(),
        volume::nrrd::WriteEncoding::Raw,
    )
    .unwrap();
    let e = volume::load_scalar(&p, None).unwrap_err();
    assert!(e.to_string().contains("3 components"), "{e}");
    let mag: FieldSelector = format!("{}:magnitude", vectors.default().name)
        .parse()
        .unwrap();
    let f = volume::load_scalar(&p, Some(&mag)).unwrap();
    assert_eq!(f.samples.packing(), Packing::F32);
    assert_eq!(
        f.samples.to_f32().as_ref(),
        volume::load(&p)
            .unwrap()
            .select(Some(&mag))
            .unwrap()
            .data
            .as_slice()
    );
}

#[test]
fn shared_scans_are_read_in_their_stored_type() {
    let Some(data) = shared_or_skip("shared_scans_are_read_in_their_stored_type") else {
        return;
    };
    // uint8 NIfTI (gzip), int16 detached NRRD, uint8 MetaImage.
    for (file, want) in [
        (
            "mri/mni_icbm152_t1_tal_nlin_sym_09a.nii.gz",
            Packing::U8 { offset: 0.0 },
        ),
        (
            "mri/headsq_64x64x93.nhdr",
            Packing::U16 { offset: -32768.0 },
        ),
        ("mri/HeadMRVolume.mhd", Packing::U8 { offset: 0.0 }),
    ] {
        same_as_load(&data.join(file), want);
    }
}
