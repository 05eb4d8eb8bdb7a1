//! Time series of vector fields in 5-D NIfTI: the writer's layout byte by byte, the round trip
//! (values, time step, first time, periodic flag), the steady 4-D and 5-D forms still reading
//! as one frame, and headers a series cannot have.

use glam::DVec3;
use test_support::fixtures;
use volume::synthetic::{double_gyre_grid, sample_series, DoubleGyre3d, LinearRamp, UnsteadyField};
use volume::{nifti, VolumeSeries};

fn gyre(frames: usize) -> VolumeSeries {
    let (dims, affine) = double_gyre_grid(5);
    sample_series(
        &DoubleGyre3d::default(),
        dims,
        affine,
        "velocity",
        frames,
        0.0,
        10.0 / frames as f64,
        true,
    )
}

fn f32_at(bytes: &[u8], index: usize) -> f32 {
    let o = 352 + 4 * index;
    f32::from_le_bytes(bytes[o..o + 4].try_into().unwrap())
}

#[test]
fn a_5d_series_round_trips_with_its_time_axis() {
    let dir = tempfile::tempdir().unwrap();
    for (name, periodic) in [("g.nii", true), ("g.nii.gz", false)] {
        let mut s = gyre(6);
        s.periodic = periodic;
        s.t0 = 0.25;
        let p = dir.path().join(name);
        nifti::write_series(&p, &s).unwrap();
        let r = nifti::read_series(&p).unwrap();
        assert_eq!(r.len(), 6, "{name}");
        assert_eq!(r.dt, s.dt as f32 as f64, "{name}");
        assert_eq!(r.t0, 0.25, "{name}");
        assert_eq!(r.periodic, periodic, "{name}");
        for (a, b) in r.frames.iter().zip(&s.frames) {
            assert_eq!(a.dims, b.dims);
            assert_eq!(a.affine, b.affine);
            assert_eq!(a.fields[0].components, 3);
            // The voxel-frame conversion of a diagonal affine only negates x: exact.
            assert_eq!(a.fields[0].data, b.fields[0].data, "{name}");
        }
        // The generic loader reads the series, the plain reader its first frame.
        let l = volume::load_series(&p).unwrap();
        assert_eq!(l.len(), 6);
        let v = volume::load(&p).unwrap();
        assert_eq!(v.fields[0].data, s.frames[0].fields[0].data);
        assert!(
            v.warnings.iter().any(|w| w.contains("6 vector fields")),
            "{:?}",
            v.warnings
        );
    }
}

#[test]
fn the_written_layout_is_x_y_z_t_then_component() {
    let dir = tempfile::tempdir().unwrap();
    let s = gyre(4);
    let p = dir.path().join("g.nii");
    nifti::write_series(&p, &s).unwrap();
    let b = std::fs::read(&p).unwrap();
    let i16_at = |o: usize| i16::from_le_bytes([b[o], b[o + 1]]);
    let f32h = |o: usize| f32::from_le_bytes(b[o..o + 4].try_into().unwrap());
    let [nx, ny, nz] = s.frames[0].dims;
    let dims: Vec<i16> = (0..8).map(|i| i16_at(40 + 2 * i)).collect();
    assert_eq!(dims, [5, nx as i16, ny as i16, nz as i16, 4, 3, 1, 1]);
    assert_eq!(i16_at(68), 1007, "intent VECTOR");
    assert_eq!(f32h(76 + 16), 2.5, "pixdim[4] = time step");
    assert_eq!(b[123], 2 | 8, "xyzt_units: mm and s");
    assert!(String::from_utf8_lossy(&b[148..228]).contains("periodic"));
    assert_eq!(b.len(), 352 + 4 * nx * ny * nz * 4 * 3);
    // Sample (i, j, k, t, c) at i + nx (j + ny (k + nz (t + nt c))); the stored x component is
    // negated (FSL's voxel frame for a positive-determinant affine).
    let g = DoubleGyre3d::default();
    for &(i, j, k, t) in &[(1usize, 2usize, 3usize, 0usize), (7, 1, 2, 3), (8, 4, 4, 2)] {
        let w = g.velocity(
            DVec3::new(i as f64 * 0.25, j as f64 * 0.25, k as f64 * 0.25),
            t as f64 * 2.5,
        );
        let at = |c: usize| f32_at(&b, i + nx * (j + ny * (k + nz * (t + 4 * c))));
        assert_eq!(at(0), -(w.x as f32));
        assert_eq!(at(1), w.y as f32);
        assert_eq!(at(2), w.z as f32);
    }
}

#[test]
fn steady_vector_files_still_read_as_one_frame() {
    // nibabel's 4-D (x, y, z, 3) and 5-D (x, y, z, 1, 3) vector fixtures.
    for name in ["n1_vec4d.nii.gz", "n1_vec5d.nii"] {
        let p = fixtures().join(name);
        let v = volume::load(&p).unwrap();
        assert_eq!(v.fields[0].components, 3, "{name}");
        assert!(v.warnings.is_empty(), "{name}: {:?}", v.warnings);
        let s = volume::load_series(&p).unwrap();
        assert!(s.is_steady(), "{name}");
        assert_eq!(s.frames[0], v, "{name}");
        assert_eq!(s.span(), 0.0);
    }
    // umbra's own steady vector output: unchanged, 5-D with one frame.
    let dir = tempfile::tempdir().unwrap();
    let s = gyre(1);
    let p = dir.path().join("one.nii");
    nifti::write_series(&p, &s).unwrap();
    let b = std::fs::read(&p).unwrap();
    assert_eq!(i16::from_le_bytes([b[48], b[49]]), 1, "dim[4]");
    assert!(volume::load_series(&p).unwrap().is_steady());
    // Other formats are steady series.
    let nrrd = dir.path().join("one.nrrd");
    volume::nrrd::write(
        &nrrd,
        &s.frames[0],
        &s.frames[0].fields[0],
        volume::nrrd::WriteEncoding::Raw,
    )
    .unwrap();
    assert!(volume::load_series(&nrrd).unwrap().is_steady());
}

#[test]
fn series_headers_that_cannot_be_read_are_errors() {
    let dir = tempfile::tempdir().unwrap();
    let (dims, affine) = double_gyre_grid(3);
    let ramp = LinearRamp {
        rate: 1.0,
        direction: DVec3::X,
    };
    let s = sample_series(&ramp, dims, affine, "v", 3, 0.0, 1.0, false);
    let p = dir.path().join("r.nii");
    nifti::write_series(&p, &s).unwrap();
    let good = std::fs::read(&p).unwrap();
    // A zero time step.
    let mut b = good.clone();
    b[92..96].copy_from_slice(&0f32.to_le_bytes());
    let bad = dir.path().join("dt0.nii");
    std::fs::write(&bad, &b).unwrap();
    let e = nifti::read_series(&bad).unwrap_err().to_string();
    assert!(e.contains("pixdim[4]"), "{e}");
    // Frames without the VECTOR intent.
    let mut b = good.clone();
    b[68..70].copy_from_slice(&0i16.to_le_bytes());
    let bad = dir.path().join("nointent.nii");
    std::fs::write(&bad, &b).unwrap();
    let e = volume::load(&bad).unwrap_err().to_string();
    assert!(e.contains("dim"), "{e}");
    // Truncated data.
    let bad = dir.path().join("short.nii");
    std::fs::write(&bad, &good[..good.len() - 4]).unwrap();
    assert!(nifti::read_series(&bad).is_err());
    // A scalar series cannot be written.
    let mut one = s.clone();
    for f in &mut one.frames {
        f.fields[0] = f.select(Some(&"v:x".parse().unwrap())).unwrap();
    }
    let e = nifti::write_series(&dir.path().join("x.nii"), &one)
        .unwrap_err()
        .to_string();
    assert!(e.contains("3-component"), "{e}");
}
