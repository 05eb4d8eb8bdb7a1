//! Tractogram readers against nibabel (tests/fixtures/tracts/expected.json, written by
//! make_expected.py with nibabel 5.4), writers' round trips, and malformed input.

use glam::Vec3;
use std::path::{Path, PathBuf};
use test_support::fixtures;
use tubes::Streamlines;

fn dir() -> PathBuf {
    fixtures().join("tracts")
}

fn close3(a: Vec3, b: &serde_json::Value) -> bool {
    (0..3).all(|k| (a[k] as f64 - b[k].as_f64().unwrap()).abs() < 1e-4)
}

#[test]
fn readers_agree_with_nibabel() {
    let text = std::fs::read_to_string(dir().join("expected.json")).unwrap();
    let all: serde_json::Value = serde_json::from_str(&text).unwrap();
    let mut n = 0;
    for (rel, e) in all.as_object().unwrap() {
        let s = tubes::load(&dir().join(rel)).unwrap_or_else(|err| panic!("{rel}: {err}"));
        assert_eq!(s.len() as u64, e["streamlines"].as_u64().unwrap(), "{rel}");
        assert_eq!(
            s.points.len() as u64,
            e["points"].as_u64().unwrap(),
            "{rel}"
        );
        if s.is_empty() {
            continue;
        }
        let first = e["first"].as_array().unwrap();
        for (k, p) in first.iter().enumerate() {
            assert!(
                close3(s.line(0)[k], p),
                "{rel}: first[{k}] {:?} vs {p}",
                s.line(0)[k]
            );
        }
        assert!(
            close3(*s.points.last().unwrap(), &e["last"][0]),
            "{rel}: last"
        );
        let lens: Vec<u64> = (0..s.len().min(5))
            .map(|i| s.line(i).len() as u64)
            .collect();
        let want: Vec<u64> = e["lengths"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_u64().unwrap())
            .collect();
        assert_eq!(lens, want, "{rel}");
        let [lo, hi] = s.bounds().unwrap();
        assert!(
            close3(lo, &e["bounds"][0]) && close3(hi, &e["bounds"][1]),
            "{rel}: bounds {lo} {hi}"
        );
        for (name, comps) in e["point_attributes"].as_object().unwrap() {
            let a = s
                .point_attributes
                .iter()
                .find(|a| &a.name == name)
                .unwrap_or_else(|| panic!("{rel}: point attribute {name}"));
            assert_eq!(a.components as u64, comps.as_u64().unwrap());
        }
        for (name, comps) in e["line_attributes"].as_object().unwrap() {
            let a = s
                .line_attributes
                .iter()
                .find(|a| &a.name == name)
                .unwrap_or_else(|| panic!("{rel}: streamline attribute {name}"));
            assert_eq!(a.components as u64, comps.as_u64().unwrap());
        }
        if let Some(fa) = e.get("first_point_attribute") {
            let name = fa[0].as_str().unwrap();
            let a = s.point_attributes.iter().find(|a| a.name == name).unwrap();
            for (k, v) in fa[1].as_array().unwrap().iter().enumerate() {
                assert!(
                    (a.values[k] as f64 - v.as_f64().unwrap()).abs() < 1e-6,
                    "{rel}: {name}[{k}]"
                );
            }
        }
        n += 1;
    }
    assert!(n >= 8);
}

fn sample() -> Streamlines {
    let mut s = Streamlines::new();
    s.push(&[
        Vec3::new(1.5, -2.25, 3.0),
        Vec3::new(1.0e6, 0.1, -7.3),
        Vec3::new(0.3333, 1e-8, 2.0),
    ]);
    s.push(&[Vec3::new(-10.0, 5.0, 0.0)]);
    s.push(&[Vec3::new(4.0, 4.0, 4.0), Vec3::new(5.0, 5.0, 5.0)]);
    s.point_attributes.push(tubes::Attribute {
        name: "fa".into(),
        components: 1,
        values: vec![0.1, 0.2, 0.3, 0.4, 0.5, 0.6],
    });
    s.point_attributes.push(tubes::Attribute {
        name: "colors".into(),
        components: 3,
        values: (0..18).map(|i| i as f32).collect(),
    });
    s.line_attributes.push(tubes::Attribute {
        name: "id".into(),
        components: 1,
        values: vec![7.0, 8.0, 9.0],
    });
    s
}

#[test]
fn our_files_round_trip_exactly() {
    let d = tempfile::tempdir().unwrap();
    let s = sample();
    for name in ["a.trk", "a.trk.gz", "a.tck", "a.tck.gz"] {
        let p = d.path().join(name);
        tubes::save(&p, &s).unwrap();
        let r = tubes::load(&p).unwrap();
        assert_eq!(r.points, s.points, "{name}: points");
        assert_eq!(r.offsets, s.offsets, "{name}");
        if name.contains("trk") {
            assert_eq!(r.point_attributes, s.point_attributes, "{name}");
            assert_eq!(r.line_attributes, s.line_attributes, "{name}");
            // Written again in the space it was read in: still exact.
            let p2 = d.path().join(format!("b{name}"));
            tubes::save(&p2, &r).unwrap();
            assert_eq!(
                tubes::load(&p2).unwrap().points,
                s.points,
                "{name}: second trip"
            );
        }
    }
}

/// A grid of micrometre-scale voxels (a field traced with `umbra trace` at 1e-7 spacing) is
/// as regular as one of millimetres: its TrackVis file reads back (it was refused as
/// "singular", its determinant 1e-21); a grid whose axes are parallel is still refused.
#[test]
fn tiny_voxels_are_a_grid_and_parallel_axes_are_not() {
    let d = tempfile::tempdir().unwrap();
    let h = 1e-7;
    let mut s = Streamlines::new();
    s.push(&[
        Vec3::new(1e-7, 2e-7, 3e-7),
        Vec3::new(1.5e-6, 0.5e-6, 1.2e-6),
    ]);
    let affine = glam::DMat4::from_scale(glam::DVec3::splat(h));
    s.reference = tubes::trk::grid_space([16; 3], affine);
    assert!(s.reference.is_some());
    let p = d.path().join("micro.trk");
    tubes::save(&p, &s).unwrap();
    let r = tubes::load(&p).unwrap();
    for (a, b) in r.points.iter().zip(&s.points) {
        assert!((*a - *b).length() < 1e-12, "{a} against {b}");
    }
    // Two axes along x: singular whatever the size.
    let mut bytes = std::fs::read(&p).unwrap();
    // vox_to_ras at byte 440, row-major 4 x 4 f32: m01 = h and m11 = 0 put the voxel y axis
    // along world x, beside the voxel x axis.
    bytes[440 + 4..440 + 8].copy_from_slice(&(h as f32).to_le_bytes());
    bytes[440 + 20..440 + 24].copy_from_slice(&0f32.to_le_bytes());
    let q = d.path().join("flat.trk");
    std::fs::write(&q, &bytes).unwrap();
    let e = tubes::load(&q).unwrap_err().to_string();
    assert!(e.contains("vox_to_ras") && e.contains("singular"), "{e}");
}

#[test]
fn nibabel_files_read_write_read_equal() {
    let d = tempfile::tempdir().unwrap();
    for rel in [
        "nibabel/standard.trk",
        "nibabel/standard.LPS.trk",
        "nibabel/complex.trk",
        "nibabel/complex_big_endian.trk",
        "nibabel/standard.tck",
        "nibabel/simple_big_endian.tck",
        "dipy/tracks300.trk",
        "nibabel/empty.trk",
        "nibabel/empty.tck",
    ] {
        let a = tubes::load(&dir().join(rel)).unwrap();
        let ext = if rel.ends_with(".trk") { "trk" } else { "tck" };
        let p = d.path().join(format!("x.{ext}"));
        tubes::save(&p, &a).unwrap();
        let b = tubes::load(&p).unwrap();
        assert_eq!(a.offsets, b.offsets, "{rel}");
        for (x, y) in a.points.iter().zip(&b.points) {
            assert!(
                (*x - *y).abs().max_element() <= 1e-5 * (1.0 + x.abs().max_element()),
                "{rel}: {x} vs {y}"
            );
        }
        assert_eq!(a.point_attributes, b.point_attributes, "{rel}");
        assert_eq!(a.line_attributes, b.line_attributes, "{rel}");
    }
}

fn replace(bytes: &[u8], from: &str, to: &str) -> Vec<u8> {
    let pos = bytes
        .windows(from.len())
        .position(|w| w == from.as_bytes())
        .unwrap_or_else(|| panic!("'{from}' not found"));
    [&bytes[..pos], to.as_bytes(), &bytes[pos + from.len()..]].concat()
}

fn expect_err(d: &Path, name: &str, bytes: &[u8], what: &str) -> String {
    let p = d.join(name);
    std::fs::write(&p, bytes).unwrap();
    match std::panic::catch_unwind(|| tubes::load(&p)) {
        Err(_) => panic!("{name} ({what}): panic"),
        Ok(Ok(_)) => panic!("{name} ({what}): read without error"),
        Ok(Err(e)) => {
            let m = e.to_string();
            assert!(
                m.contains(name),
                "{what}: error does not name the file: {m}"
            );
            m
        }
    }
}

#[test]
fn malformed_tractograms_are_errors_not_panics() {
    let d = tempfile::tempdir().unwrap();
    let trk = std::fs::read(dir().join("nibabel/complex.trk")).unwrap();
    let tck = std::fs::read(dir().join("nibabel/standard.tck")).unwrap();
    // Wrong magic.
    let mut b = trk.clone();
    b[0] = b'X';
    assert!(expect_err(d.path(), "m.trk", &b, "magic").contains("TRACK"));
    let mut b = tck.clone();
    b[0] = b'X';
    expect_err(d.path(), "m.tck", &b, "magic");
    // Version 123 and hdr_size 1234 (nibabel's own rejects).
    let mut b = trk.clone();
    b[992..996].copy_from_slice(&123i32.to_le_bytes());
    assert!(expect_err(d.path(), "v.trk", &b, "version").contains("version"));
    let mut b = trk.clone();
    b[996..1000].copy_from_slice(&1234i32.to_le_bytes());
    expect_err(d.path(), "h.trk", &b, "hdr_size");
    // An absurd point count: an error, and no allocation from it.
    let mut b = trk.clone();
    b[1000..1004].copy_from_slice(&i32::MAX.to_le_bytes());
    assert!(expect_err(d.path(), "n.trk", &b, "count").contains("claims"));
    // No END, a header past the end of the file, an unsupported datatype, no end marker.
    let text = String::from_utf8_lossy(&tck[..tck.windows(4).position(|w| w == b"END\n").unwrap()])
        .to_string();
    expect_err(d.path(), "e.tck", text.as_bytes(), "no END");
    expect_err(d.path(), "t.tck", &tck[..62], "62-byte file");
    let off = replace(&tck, "file: . 67", "file: . 99999");
    expect_err(d.path(), "o.tck", &off, "offset past the end");
    let dt = replace(&tck, "Float32LE", "Int16LEXX");
    expect_err(d.path(), "d.tck", &dt, "datatype");
    assert!(expect_err(d.path(), "x.tck", &tck[..tck.len() - 12], "no end marker").contains("inf"));
    // Truncation at every offset never panics, and is an error unless only whitespace went.
    for (name, bytes) in [("c.trk", &trk), ("s.tck", &tck)] {
        for cut in 1..bytes.len() {
            let p = d.path().join(name);
            std::fs::write(&p, &bytes[..cut]).unwrap();
            let r = std::panic::catch_unwind(|| tubes::load(&p));
            assert!(r.is_ok(), "{name} cut at {cut}: panic");
        }
    }
    // Empty files are errors (nibabel cannot read their header either), not empty sets.
    for name in ["z.trk", "z.tck", "z.vtk", "z.tck.gz"] {
        let p = d.path().join(name);
        std::fs::write(&p, b"").unwrap();
        let e = tubes::load(&p).unwrap_err().to_string();
        assert!(e.contains("empty"), "{name}: {e}");
    }
}

#[test]
fn header_counts_that_disagree_warn_and_the_data_win() {
    let d = tempfile::tempdir().unwrap();
    let tck = std::fs::read(dir().join("nibabel/simple.tck")).unwrap();
    let b = replace(&tck, "count: 0000000003", "count: 0000615000");
    let p = d.path().join("c.tck");
    std::fs::write(&p, &b).unwrap();
    let s = tubes::load(&p).unwrap();
    assert_eq!(s.len(), 3);
    assert!(
        s.warnings.iter().any(|w| w.contains("615000")),
        "{:?}",
        s.warnings
    );
    // Lower-case voxel order is accepted.
    let mut trk = std::fs::read(dir().join("nibabel/standard.LPS.trk")).unwrap();
    trk[948..951].copy_from_slice(b"lps");
    let p = d.path().join("l.trk");
    std::fs::write(&p, &trk).unwrap();
    let a = tubes::load(&p).unwrap();
    let b = tubes::load(&dir().join("nibabel/standard.LPS.trk")).unwrap();
    assert_eq!(a.points, b.points);
}

#[test]
fn vtk_polylines_read_in_both_layouts_and_encodings() {
    // Written by VTK 9.7 (`vtkPolyDataWriter`): version 5.1 (OFFSETS/CONNECTIVITY) in ASCII and
    // BINARY, and the classic 4.2 layout; three lines, point arrays fa (1) and rgb (3), a cell
    // array id.
    for name in ["lines_ascii.vtk", "lines_binary.vtk", "lines_v42.vtk"] {
        let s = tubes::load(&dir().join(name)).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(s.len(), 3, "{name}");
        assert_eq!(
            s.line(0),
            &[
                Vec3::ZERO,
                Vec3::X,
                Vec3::new(2.0, 1.0, 0.0),
                Vec3::new(3.0, 1.0, 1.0)
            ],
            "{name}"
        );
        assert_eq!(
            s.line(2),
            &[Vec3::new(3.0, 1.0, 1.0), Vec3::new(2.0, 1.0, 0.0)],
            "{name}: shared points"
        );
        let fa = s.point_attributes.iter().find(|a| a.name == "fa").unwrap();
        assert_eq!(fa.values.len(), 9);
        assert!(
            (fa.values[7] - 0.3).abs() < 1e-6 && (fa.values[8] - 0.2).abs() < 1e-6,
            "{name}: fa gathered along the lines"
        );
        let rgb = s.point_attributes.iter().find(|a| a.name == "rgb").unwrap();
        assert_eq!(rgb.components, 3);
        assert_eq!(&rgb.values[3 * 4..3 * 5], &[12.0, 13.0, 14.0]);
        assert_eq!(s.line_attributes[0].values, vec![10.0, 20.0, 30.0]);
    }
    // Indices past the points and truncation are errors, never panics.
    let d = tempfile::tempdir().unwrap();
    let text = std::fs::read(dir().join("lines_v42.vtk")).unwrap();
    let bad = replace(&text, "4 0 1 2 3", "4 0 1 2 99");
    assert!(expect_err(d.path(), "b.vtk", &bad, "index").contains("99"));
    let bin = std::fs::read(dir().join("lines_binary.vtk")).unwrap();
    for cut in (1..bin.len()).step_by(7) {
        let p = d.path().join("c.vtk");
        std::fs::write(&p, &bin[..cut]).unwrap();
        assert!(
            std::panic::catch_unwind(|| tubes::load(&p)).is_ok(),
            "cut at {cut}"
        );
    }
}

fn trx_dir() -> PathBuf {
    dir().join("trx")
}

#[test]
fn trx_files_agree_with_trx_python_and_with_their_trackvis_sources() {
    let text = std::fs::read_to_string(trx_dir().join("expected.json")).unwrap();
    let exp: serde_json::Value = serde_json::from_str(&text).unwrap();
    for (name, e) in exp.as_object().unwrap() {
        let s = tubes::load(&trx_dir().join(name)).unwrap();
        assert_eq!(s.format, "trx");
        assert_eq!(s.len() as u64, e["streamlines"].as_u64().unwrap(), "{name}");
        assert_eq!(
            s.points.len() as u64,
            e["points"].as_u64().unwrap(),
            "{name}"
        );
        for (k, p) in e["first"].as_array().unwrap().iter().enumerate() {
            assert!(close3(s.line(0)[k], p), "{name}: first {k}");
        }
        let last = s.line(s.len() - 1);
        assert!(close3(last[last.len() - 1], &e["last"][0]), "{name}: last");
        for (i, l) in e["lengths"].as_array().unwrap().iter().enumerate() {
            assert_eq!(
                s.line(i).len() as u64,
                l.as_u64().unwrap(),
                "{name}: line {i}"
            );
        }
        for (attrs, key) in [(&s.point_attributes, "dpv"), (&s.line_attributes, "dps")] {
            let want = e[key].as_object().unwrap();
            assert_eq!(attrs.len(), want.len(), "{name} {key}");
            for a in attrs.iter() {
                assert_eq!(a.components as u64, want[&a.name].as_u64().unwrap());
            }
        }
    }
    // The same streamlines as the TrackVis files they were made from: exact for float32
    // positions, within half a float16 unit in the last place for float16.
    let pairs = [
        ("complex.trx", "nibabel/complex.trk", 0.0f32),
        ("tracks300_f16.trx", "dipy/tracks300.trk", 1.0 / 2048.0),
    ];
    for (trx, trk, rel) in pairs {
        let a = tubes::load(&trx_dir().join(trx)).unwrap();
        let b = tubes::load(&dir().join(trk)).unwrap();
        assert_eq!(a.offsets, b.offsets, "{trx}");
        for (p, q) in a.points.iter().zip(&b.points) {
            let tol = rel * q.abs().max_element();
            assert!((*p - *q).abs().max_element() <= tol, "{trx}: {p} vs {q}");
        }
    }
    let c = tubes::load(&trx_dir().join("complex.trx")).unwrap();
    let t = tubes::load(&dir().join("nibabel/complex.trk")).unwrap();
    let fa = |s: &Streamlines| {
        s.point_attributes
            .iter()
            .find(|a| a.name == "fa")
            .unwrap()
            .values
            .clone()
    };
    assert_eq!(fa(&c), fa(&t));
    // Groups are reported, not silently dropped.
    let g = tubes::load(&trx_dir().join("tracks300_f16.trx")).unwrap();
    assert!(
        g.warnings.iter().any(|w| w.contains("groups/first_ten")),
        "{:?}",
        g.warnings
    );
}

/// A TRX file's voxel order is its VOXEL_TO_RASMM's (it was read as "RAS" whatever the matrix:
/// `umbra info` printed RAS for an LPS grid).
#[test]
fn a_trx_files_voxel_order_is_its_matrixs() {
    let d = tempfile::tempdir().unwrap();
    let mut s = tubes::load(&dir().join("dipy/tracks300.trk")).unwrap();
    for (diag, order) in [([-1.0, -1.0, 1.0], b"LPS"), ([-2.0, 1.0, 1.0], b"LAS")] {
        let r = s.reference.as_mut().unwrap();
        r.vox_to_ras = glam::DMat4::from_scale(glam::DVec3::from(diag));
        let p = d.path().join("t.trx");
        tubes::trx::write(&p, &s).unwrap();
        let back = tubes::load(&p).unwrap();
        assert_eq!(&back.reference.unwrap().voxel_order, order);
    }
}

/// Writes an uncompressed TRX directory.
fn trx_folder(d: &Path, files: &[(&str, Vec<u8>)]) -> PathBuf {
    let root = d.join(format!("t{}.trx", files.len()));
    let _ = std::fs::remove_dir_all(&root);
    for (name, bytes) in files {
        let p = root.join(name);
        std::fs::create_dir_all(p.parent().unwrap()).unwrap();
        std::fs::write(p, bytes).unwrap();
    }
    root
}

#[test]
fn trx_directories_old_offsets_and_malformed_archives() {
    let d = tempfile::tempdir().unwrap();
    let header = |nv: u64, ns: u64| {
        format!("{{\"NB_VERTICES\": {nv}, \"NB_STREAMLINES\": {ns}, \"DIMENSIONS\": [1,1,1], \"VOXEL_TO_RASMM\": [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]}}").into_bytes()
    };
    let pos: Vec<u8> = (0..15).flat_map(|i| (i as f64).to_le_bytes()).collect();
    // The spec's older layout: NB_STREAMLINES offsets (no final NB_VERTICES), float64 points.
    let ok = trx_folder(
        d.path(),
        &[
            ("header.json", header(5, 2)),
            ("positions.3.float64", pos.clone()),
            (
                "offsets.uint64",
                [0u64, 2].iter().flat_map(|v| v.to_le_bytes()).collect(),
            ),
            (
                "dpv/w.int16",
                [1i16, -2, 3, -4, 5]
                    .iter()
                    .flat_map(|v| v.to_le_bytes())
                    .collect(),
            ),
        ],
    );
    let s = tubes::load(&ok).unwrap();
    assert_eq!(s.offsets, vec![0, 2, 5]);
    assert_eq!(s.points[4], Vec3::new(12.0, 13.0, 14.0));
    assert_eq!(
        s.point_attributes[0].values,
        vec![1.0, -2.0, 3.0, -4.0, 5.0]
    );

    let offs = |v: &[u32]| v.iter().flat_map(|v| v.to_le_bytes()).collect::<Vec<u8>>();
    type Files<'a> = Vec<(&'a str, Vec<u8>)>;
    let cases: Vec<(Files, &str)> = vec![
        (vec![("positions.3.float64", pos.clone())], "header.json"),
        (
            vec![
                ("header.json", b"{not json".to_vec()),
                ("positions.3.float64", pos.clone()),
            ],
            "header.json",
        ),
        (
            vec![
                ("header.json", header(1 << 50, 2)),
                ("positions.3.float64", pos.clone()),
            ],
            "NB_VERTICES",
        ),
        // A count below the absurd but past what the file holds: refused before the points
        // are allocated (3 TB of them aborted the process).
        (
            vec![
                ("header.json", header(1 << 38, 2)),
                ("positions.3.float64", pos.clone()),
                ("offsets.uint32", offs(&[0, 2, 5])),
            ],
            "NB_VERTICES 274877906944 x 3 x 8 need",
        ),
        (
            vec![
                ("header.json", header(6, 2)),
                ("positions.3.float64", pos.clone()),
                ("offsets.uint32", offs(&[0, 2, 6])),
            ],
            "positions.3.float64",
        ),
        (
            vec![
                ("header.json", header(5, 2)),
                ("positions.3.float64", pos.clone()),
                ("offsets.uint32", offs(&[0, 4, 2])),
            ],
            "offsets",
        ),
        (
            vec![
                ("header.json", header(5, 2)),
                ("positions.3.float64", pos.clone()),
                ("offsets.uint32", offs(&[0, 2, 5])),
                ("dps/x.3.float32", vec![0u8; 12]),
            ],
            "dps/x.3.float32",
        ),
        (
            vec![
                ("header.json", header(5, 2)),
                ("positions.3.complex64", pos.clone()),
                ("offsets.uint32", offs(&[0, 2, 5])),
            ],
            "unknown data type",
        ),
    ];
    for (files, what) in cases {
        let p = trx_folder(d.path(), &files);
        let e = tubes::load(&p).unwrap_err().to_string();
        assert!(
            e.contains(what) && e.contains(".trx"),
            "expected '{what}' in: {e}"
        );
    }
    // Not a zip at all, and a zip cut short.
    let z = d.path().join("bad.trx");
    std::fs::write(&z, b"PK\x03\x04 definitely not a zip").unwrap();
    let e = tubes::load(&z).unwrap_err().to_string();
    assert!(e.contains("bad.trx") && e.contains("zip"), "{e}");
    let full = std::fs::read(trx_dir().join("complex.trx")).unwrap();
    std::fs::write(&z, &full[..full.len() / 2]).unwrap();
    assert!(tubes::load(&z).is_err());
}

/// The forms nibabel reads that a strict reader refused (issue 17): `.tck` continuation lines
/// and repeated keys, a repeated `file` (the first offset), no `datatype` (Float32LE), `Float32`
/// without an endianness, no `file` key (the data after END), triplets with one NaN or one Inf
/// component (points: only all-NaN splits and all-Inf ends), and TrackVis version 3 (read as
/// 2). Every streamline length and point against nibabel 5.4
/// (tests/fixtures/tracts/conformance/make_conformance.py).
#[test]
fn forms_nibabel_accepts_read_as_nibabel_reads_them() {
    let root = dir().join("conformance");
    let text = std::fs::read_to_string(root.join("conformance.json")).unwrap();
    let all: serde_json::Value = serde_json::from_str(&text).unwrap();
    let value = |v: &serde_json::Value| -> f32 {
        match v {
            serde_json::Value::String(s) => s.parse().unwrap(),
            v => v.as_f64().unwrap() as f32,
        }
    };
    let mut n = 0;
    for (name, e) in all.as_object().unwrap() {
        let s = tubes::load(&root.join(name)).unwrap_or_else(|err| panic!("{name}: {err}"));
        let lengths: Vec<usize> = (0..s.len()).map(|i| s.line(i).len()).collect();
        let want: Vec<usize> = e["lengths"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_u64().unwrap() as usize)
            .collect();
        assert_eq!(lengths, want, "{name}");
        let pts = e["points"].as_array().unwrap();
        assert_eq!(pts.len(), s.points.len(), "{name}");
        for (k, (p, q)) in s.points.iter().zip(pts).enumerate() {
            for c in 0..3 {
                let (a, b) = (p[c], value(&q[c]));
                let same = (a.is_nan() && b.is_nan()) || a == b || (a - b).abs() < 1e-4;
                assert!(same, "{name}: point {k}[{c}] {a} vs nibabel {b}");
            }
        }
        n += 1;
    }
    assert_eq!(n, 10);
}

/// Non-finite points are kept (as nibabel keeps them) but never poison what is computed from
/// them: bounds come from the finite points (a NaN point restarted glam's fold and lost every
/// point before it), a tube mesh of lines with an Inf or a trailing NaN point has only finite
/// vertices, and the line renderer's segments skip them.
#[test]
fn non_finite_points_leave_bounds_and_meshes_finite() {
    let mut s = Streamlines::new();
    s.push(&[
        Vec3::new(-5.0, 0.0, 0.0),
        Vec3::new(0.0, 0.0, 0.0),
        Vec3::new(f32::NAN, 1.0, 2.0),
        Vec3::new(1.0, 1.0, 1.0),
        Vec3::new(2.0, 3.0, 1.0),
    ]);
    s.push(&[
        Vec3::new(0.0, 4.0, 0.0),
        Vec3::new(f32::INFINITY, 0.0, 0.0),
        Vec3::new(1.0, 5.0, 0.0),
        Vec3::new(2.0, 6.0, 1.0),
        Vec3::new(3.0, 7.0, f32::NAN),
    ]);
    let [lo, hi] = s.bounds().unwrap();
    assert_eq!(lo, Vec3::new(-5.0, 0.0, 0.0));
    assert_eq!(hi, Vec3::new(2.0, 6.0, 1.0));
    assert_eq!(s.nonfinite_points(), 3);
    let o = tubes::tube_mesh::TubeOptions::defaults(0.2, 8, 0.01);
    let (mesh, _) = tubes::tube_mesh::build(&s, &o);
    assert!(!mesh.indices.is_empty());
    assert!(mesh.origin.is_finite());
    assert!(mesh.positions.iter().all(|p| p.is_finite()));
    let set = tubes::lines::LineSet::new(
        &s,
        &tubes::tube_mesh::ColorMode::Direction,
        tubes::lines::LineWidth::Pixels(2.0),
        false,
    );
    assert!(set.origin.is_finite());
    for &i in &set.segments {
        let (a, b) = (s.points[i as usize], s.points[i as usize + 1]);
        assert!(a.is_finite() && b.is_finite(), "segment {i}");
    }
    assert_eq!(set.segments.len(), 3);
}

/// `.tck` marks the end of a streamline with three NaNs and the end of the data with three
/// infinities: a point with some NaN components is written and read back as a point, one that
/// is all NaN or all infinite is refused (written, it split the streamline: a TrackVis point
/// with a NaN x is all NaN once in world space), and nothing is written.
#[test]
fn tck_refuses_points_it_would_read_as_its_own_marks() {
    let d = tempfile::tempdir().unwrap();
    let out = d.path().join("o.tck");
    let mut s = Streamlines::new();
    s.push(&[
        Vec3::ZERO,
        Vec3::new(f32::NAN, 1.0, 2.0),
        Vec3::new(f32::INFINITY, f32::NAN, 0.0),
        Vec3::ONE,
    ]);
    s.push(&[Vec3::X, Vec3::Y]);
    tubes::save(&out, &s).unwrap();
    let back = tubes::load(&out).unwrap();
    assert_eq!(back.offsets, s.offsets);
    assert_eq!(back.points[1].y, 1.0);
    assert!(back.points[1].x.is_nan() && back.points[2].y.is_nan());
    std::fs::remove_file(&out).unwrap();
    for (bad, shown) in [
        (Vec3::NAN, "(NaN, NaN, NaN)"),
        (
            Vec3::new(f32::INFINITY, f32::NEG_INFINITY, f32::INFINITY),
            "(inf, -inf, inf)",
        ),
    ] {
        let mut t = Streamlines::new();
        t.push(&[Vec3::X, Vec3::Y]);
        t.push(&[Vec3::ZERO, bad, Vec3::ONE]);
        let e = tubes::save(&out, &t).unwrap_err().to_string();
        assert!(
            e.contains("o.tck") && e.contains("streamline 1 point 1") && e.contains(shown),
            "{e}"
        );
        assert!(!out.exists());
        assert_eq!(
            std::fs::read_dir(d.path()).unwrap().count(),
            0,
            "no temporary left"
        );
    }
}

/// Issue 17's hostile tractograms, one per case: header values that overflow f32 when applied
/// (TrackVis voxel_size 1e-45, vox_to_ras 3.4e38), VTK polyline indices that are not indices
/// (-1, NaN, 1.9), doubles outside f32 (1e300), a gzip bomb of zeros (refused at its first
/// bytes), devices, and a .tck header of 150,000 keys (read in linear time).
#[test]
fn hostile_tractograms_are_refused_or_read_exactly() {
    let d = tempfile::tempdir().unwrap();
    let trk = std::fs::read(dir().join("nibabel/simple.trk")).unwrap();
    let mut tiny = trk.clone();
    tiny[12..16].copy_from_slice(&1e-45f32.to_le_bytes());
    assert!(expect_err(d.path(), "v.trk", &tiny, "voxel_size 1e-45").contains("voxel_size"));
    let mut huge = trk.clone();
    huge[440..444].copy_from_slice(&3.4e38f32.to_le_bytes());
    huge[460..464].copy_from_slice(&3.4e38f32.to_le_bytes());
    huge[480..484].copy_from_slice(&3.4e38f32.to_le_bytes());
    let e = expect_err(d.path(), "r.trk", &huge, "vox_to_ras 3.4e38");
    assert!(e.contains("vox_to_ras"), "{e}");

    let vtk = std::fs::read(dir().join("lines_ascii.vtk")).unwrap();
    for (bad, what) in [("-1", "-1"), ("nan", "NaN"), ("1.9", "1.9")] {
        let b = replace(&vtk, "0 1 2 3 4 5 6 3 2", &format!("0 1 {bad} 3 4 5 6 3 2"));
        let e = expect_err(d.path(), "i.vtk", &b, what);
        assert!(
            e.contains("CONNECTIVITY") && e.contains("entry 2"),
            "{what}: {e}"
        );
        let b = replace(&vtk, "0 4 7 9", &format!("0 {bad} 7 9"));
        expect_err(d.path(), "o.vtk", &b, what);
    }
    let b = replace(
        &replace(&vtk, "POINTS 7 float", "POINTS 7 double"),
        "0 0 0 1 0 0",
        "1e300 0 0 1 0 0",
    );
    assert!(expect_err(d.path(), "f.vtk", &b, "1e300").contains("f32"));
    // An attribute of the wrong length is reported, not dropped in silence.
    let b = replace(&vtk, "id 1 3 float\n10 20 30", "id 1 2 float\n10 20");
    let p = d.path().join("a.vtk");
    std::fs::write(&p, &b).unwrap();
    let s = tubes::load(&p).unwrap();
    assert!(
        s.warnings.iter().any(|w| w.contains("'id'")),
        "{:?}",
        s.warnings
    );

    // 64 MiB of zeros as gzip: refused at the magic, without inflating the rest.
    let bomb = volume::gzip_bytes(&vec![0u8; 64 << 20]);
    for name in ["b.trk.gz", "b.tck.gz", "b.vtk.gz"] {
        assert!(expect_err(d.path(), name, &bomb, "gzip of zeros").contains("magic"));
    }
    #[cfg(unix)]
    for target in ["/dev/zero", "/dev/urandom"] {
        let link = d.path().join("dev.tck");
        let _ = std::fs::remove_file(&link);
        std::os::unix::fs::symlink(target, &link).unwrap();
        let e = tubes::load(&link).unwrap_err().to_string();
        assert!(e.contains("regular file"), "{target}: {e}");
    }

    let tck = std::fs::read(dir().join("nibabel/simple.tck")).unwrap();
    let keys: String = (0..150_000).map(|i| format!("k{i}: {i}\n")).collect();
    let head_end = tck.windows(4).position(|w| w == b"END\n").unwrap();
    let old_off = 67usize;
    let new_off = old_off + keys.len();
    let mut many = replace(
        &tck[..head_end],
        "file: . 67",
        &format!("file: . {new_off}"),
    );
    many.extend_from_slice(keys.as_bytes());
    many.extend_from_slice(&tck[head_end..]);
    // The offset line changed length by the digits of new_off against those of 67.
    let shift = format!("{new_off}").len() - 2;
    let many = replace(
        &many,
        &format!("file: . {new_off}"),
        &format!("file: . {}", new_off + shift),
    );
    let p = d.path().join("keys.tck");
    std::fs::write(&p, &many).unwrap();
    let s = tubes::load(&p).unwrap();
    assert_eq!(s.len(), 3);
}

/// `.vtk.gz` polylines are recognised through the compression (info sniffed the gzip bytes and
/// called them a volume), and a title that says POLYDATA does not make a volume a tractogram.
#[test]
fn compressed_vtk_polylines_are_recognised() {
    let d = tempfile::tempdir().unwrap();
    let vtk = std::fs::read(dir().join("lines_ascii.vtk")).unwrap();
    let p = d.path().join("l.vtk.gz");
    std::fs::write(&p, volume::gzip_bytes(&vtk)).unwrap();
    assert!(tubes::is_tractogram(&p));
    assert_eq!(tubes::load(&p).unwrap().len(), 3);
    let img = b"# vtk DataFile Version 3.0\nPOLYDATA lines\nASCII\nDATASET STRUCTURED_POINTS\n";
    let q = d.path().join("img.vtk");
    std::fs::write(&q, img).unwrap();
    assert!(!tubes::is_tractogram(&q));
}

/// A Float64 `.tck` value that is finite but beyond `f32`'s range (1e300) is an error naming
/// the point, not an infinite coordinate.
#[test]
fn float64_values_beyond_f32_are_refused() {
    let d = tempfile::tempdir().unwrap();
    let mut head = b"mrtrix tracks\ndatatype: Float64LE\ncount: 1\nfile: . 64\n".to_vec();
    head.extend_from_slice(b"END\n");
    head.resize(64, b' ');
    let mut b = head.clone();
    for v in [
        0.0f64,
        0.0,
        0.0,
        1e300,
        1.0,
        1.0,
        f64::NAN,
        f64::NAN,
        f64::NAN,
    ] {
        b.extend_from_slice(&v.to_le_bytes());
    }
    for _ in 0..3 {
        b.extend_from_slice(&f64::INFINITY.to_le_bytes());
    }
    let e = expect_err(d.path(), "big.tck", &b, "1e300");
    assert!(e.contains("point 1") && e.contains("f32"), "{e}");
}

/// An empty TrackVis file declares no scalars or properties (nibabel, which writes them so,
/// failed to read umbra's, which named two scalars with no values), and reads back empty.
#[test]
fn an_empty_trackvis_file_declares_no_attributes() {
    let dir = tempfile::tempdir().unwrap();
    let mut s = Streamlines::new();
    s.point_attributes.push(tubes::Attribute {
        name: "time".into(),
        components: 1,
        values: vec![],
    });
    s.line_attributes.push(tubes::Attribute {
        name: "id".into(),
        components: 1,
        values: vec![],
    });
    let p = dir.path().join("e.trk");
    tubes::save(&p, &s).unwrap();
    let bytes = std::fs::read(&p).unwrap();
    let i16_at = |o: usize| i16::from_le_bytes([bytes[o], bytes[o + 1]]);
    assert_eq!((i16_at(36), i16_at(238)), (0, 0));
    assert_eq!(bytes.len(), 1000);
    let back = tubes::load(&p).unwrap();
    assert!(back.is_empty() && back.point_attributes.is_empty());
}

/// Appending keeps the points and lines in order, the attributes both sets have (values
/// concatenated), and names those only one has; an empty set takes the other whole.
#[test]
fn appended_sets_keep_shared_attributes_in_order() {
    let a = sample();
    let mut b = Streamlines::new();
    b.push(&[Vec3::new(7.0, 7.0, 7.0), Vec3::new(8.0, 8.0, 8.0)]);
    b.point_attributes.push(tubes::Attribute {
        name: "fa".into(),
        components: 1,
        values: vec![0.7, 0.8],
    });
    b.line_attributes.push(tubes::Attribute {
        name: "bundle".into(),
        components: 1,
        values: vec![3.0],
    });
    let mut all = Streamlines::new();
    assert!(all.append(&a).is_empty());
    assert_eq!(all.points, a.points);
    let dropped = all.append(&b);
    assert_eq!(all.len(), a.len() + 1);
    assert_eq!(all.line(a.len()), b.line(0));
    assert_eq!(all.line(0), a.line(0));
    assert_eq!(all.point_attributes.len(), 1);
    let fa = &all.point_attributes[0];
    assert_eq!(fa.name, "fa");
    assert_eq!(fa.values.len(), all.points.len());
    assert_eq!(&fa.values[6..], &[0.7, 0.8]);
    let mut d = dropped.clone();
    d.sort();
    assert_eq!(d, ["bundle", "colors", "id"]);
    assert!(all.line_attributes.is_empty());
    assert!(all.validate().is_ok(), "{:?}", all.validate());
    // An empty set is neutral wherever it comes (an empty .trk declares no attributes).
    let mut first = Streamlines::new();
    first.append(&Streamlines::new());
    first.append(&a);
    let mut last = a.clone();
    assert!(last.append(&Streamlines::default()).is_empty());
    assert_eq!(first.point_attributes, a.point_attributes);
    assert_eq!(last.point_attributes, a.point_attributes);
    // Shared attributes in another order keep their own values.
    let mut c = a.clone();
    c.point_attributes.reverse();
    let mut ac = a.clone();
    assert!(ac.append(&c).is_empty());
    let fa = ac.point_attributes.iter().find(|x| x.name == "fa").unwrap();
    let n = a.points.len();
    assert_eq!(&fa.values[n..], &a.point_attributes[0].values[..]);
    assert!(ac.validate().is_ok(), "{:?}", ac.validate());
}
