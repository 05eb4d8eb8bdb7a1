//! Every reader against files written by independent reference libraries (nibabel, pynrrd,
//! VTK, SimpleITK; see tests/fixtures/make_fixtures.py): format, grid, type, world affine and
//! frame, value range, non-finite count and voxel probes must agree.

use serde_json::Value;
use test_support::{close, fixtures};
use volume::FieldSelector;

fn expected() -> serde_json::Map<String, Value> {
    let text = std::fs::read_to_string(fixtures().join("expected.json")).unwrap();
    serde_json::from_str::<Value>(&text)
        .unwrap()
        .as_object()
        .unwrap()
        .clone()
}

#[test]
fn every_fixture_matches_its_reference_reader() {
    let all = expected();
    assert!(
        all.len() >= 28,
        "expected.json lists {} fixtures",
        all.len()
    );
    let mut failures = Vec::new();
    for (name, e) in &all {
        let file = e.get("file").and_then(Value::as_str).unwrap_or(name);
        let path = fixtures().join(file);
        let vol = match volume::load(&path) {
            Ok(v) => v,
            Err(err) => {
                failures.push(format!("{name}: {err}"));
                continue;
            }
        };
        let sel: Option<FieldSelector> = e["field"].as_str().map(|f| f.parse().unwrap());
        let field = vol.select(sel.as_ref()).unwrap();
        let mut check = |what: &str, ok: bool, detail: String| {
            if !ok {
                failures.push(format!("{name}: {what}: {detail}"));
            }
        };
        check(
            "format",
            vol.format == e["format"].as_str().unwrap(),
            vol.format.clone(),
        );
        let dims: Vec<usize> = e["dims"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_u64().unwrap() as usize)
            .collect();
        check(
            "dims",
            vol.dims.to_vec() == dims,
            format!("{:?} vs {dims:?}", vol.dims),
        );
        check(
            "components",
            field.components as u64 == e["components"].as_u64().unwrap(),
            format!("{}", field.components),
        );
        check(
            "type",
            field.stored.name() == e["type"].as_str().unwrap(),
            field.stored.name().into(),
        );
        check(
            "space",
            vol.space.name() == e["space"].as_str().unwrap(),
            vol.space.name().into(),
        );
        for r in 0..4 {
            for c in 0..4 {
                let want = e["affine"][r][c].as_f64().unwrap();
                let got = vol.affine.col(c)[r];
                check(
                    "affine",
                    close(got, want, 1e-6, 1e-5),
                    format!("[{r}][{c}] = {got}, reference {want}"),
                );
            }
        }
        let st = field.stats();
        check(
            "range",
            close(st.min, e["range"][0].as_f64().unwrap(), 1e-6, 1e-6)
                && close(st.max, e["range"][1].as_f64().unwrap(), 1e-6, 1e-6),
            format!("{} .. {}", st.min, st.max),
        );
        check(
            "nonfinite",
            st.nonfinite as u64 == e["nonfinite"].as_u64().unwrap(),
            format!("{}", st.nonfinite),
        );
        if let Some(fields) = e["fields"].as_array() {
            let want: Vec<&str> = fields.iter().map(|v| v.as_str().unwrap()).collect();
            check(
                "fields",
                vol.field_names() == want,
                format!("{:?}", vol.field_names()),
            );
        }
        for p in e["probes"].as_array().unwrap() {
            let ijk: Vec<usize> = p["ijk"]
                .as_array()
                .unwrap()
                .iter()
                .map(|v| v.as_u64().unwrap() as usize)
                .collect();
            let idx = vol.index(ijk[0], ijk[1], ijk[2]);
            for (c, want) in p["value"].as_array().unwrap().iter().enumerate() {
                let got = field.data[idx * field.components + c] as f64;
                match want.as_f64() {
                    Some(w) => check(
                        "probe",
                        close(got, w, 1e-5, 1e-5),
                        format!("{ijk:?}[{c}] = {got}, reference {w}"),
                    ),
                    None => check(
                        "probe",
                        !got.is_finite(),
                        format!("{ijk:?}[{c}] = {got}, reference non-finite"),
                    ),
                }
            }
        }
    }
    assert!(
        failures.is_empty(),
        "{} mismatches:\n{}",
        failures.len(),
        failures.join("\n")
    );
}

/// A NIfTI-1 pair (`ni1`: header and image in two files), cut from a single-file fixture, reads
/// the same whether the header or the image is named, with lower- or upper-case suffixes
/// (`PAIR.HDR` + `PAIR.IMG`, as some scanners' exports name them).
#[test]
fn a_nifti_pair_reads_by_either_name() {
    let nii = std::fs::read(fixtures().join("n1_i8.nii")).unwrap();
    let offset = f32::from_le_bytes(nii[108..112].try_into().unwrap()) as usize;
    let mut hdr = nii[..348].to_vec();
    hdr[108..112].copy_from_slice(&0f32.to_le_bytes());
    hdr[344..348].copy_from_slice(b"ni1\0");
    let want = volume::load(&fixtures().join("n1_i8.nii")).unwrap();
    for (h, i) in [("pair.hdr", "pair.img"), ("PAIR.HDR", "PAIR.IMG")] {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join(h), &hdr).unwrap();
        std::fs::write(dir.path().join(i), &nii[offset..]).unwrap();
        for name in [h, i] {
            let v = volume::load(&dir.path().join(name)).unwrap();
            assert_eq!(v.dims, want.dims, "{name}");
            assert_eq!(v.affine, want.affine, "{name}");
            assert_eq!(v.default().data, want.default().data, "{name}");
        }
    }
}

/// A VTK legacy SCALARS array of two components is split into a field per component; the
/// default field is its first component, as for NRRD lists and MetaImage channels.
#[test]
fn a_two_component_vtk_scalars_array_defaults_to_its_first_component() {
    let mut text = String::from(
        "# vtk DataFile Version 3.0\nt\nASCII\nDATASET STRUCTURED_POINTS\nDIMENSIONS 2 2 2\n\
         SPACING 1 1 1\nORIGIN 0 0 0\nPOINT_DATA 8\nSCALARS two float 2\nLOOKUP_TABLE default\n",
    );
    for k in 0..8 {
        text += &format!("{} {}\n", k, 100 + k);
    }
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("two.vtk");
    std::fs::write(&p, text).unwrap();
    let v = volume::load(&p).unwrap();
    assert_eq!(v.fields.len(), 2);
    let d = v.default();
    assert_eq!(
        d.data,
        (0..8).map(|k| k as f32).collect::<Vec<_>>(),
        "{}",
        d.name
    );
}

/// NRRD as Teem reads it: with gzip encoding, `byte skip` counts bytes of the decompressed
/// data (they were skipped in the compressed file: a valid file refused as a broken gzip
/// stream); a cell-centred axis's `axis mins` is its first cell's edge, the first sample half
/// a spacing in (it was placed at the min).
#[test]
fn nrrd_byte_skip_after_gzip_and_cell_centred_axis_mins_are_teems() {
    use std::io::Write;
    let dir = tempfile::tempdir().unwrap();
    let values: Vec<i16> = (0..210).collect();
    let mut raw = b"ABCD".to_vec();
    raw.extend(values.iter().flat_map(|v| v.to_le_bytes()));
    let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
    gz.write_all(&raw).unwrap();
    std::fs::write(dir.path().join("d.gz"), gz.finish().unwrap()).unwrap();
    let header = |extra: &str| {
        format!(
            "NRRD0004\ntype: short\ndimension: 3\nsizes: 5 6 7\nencoding: gzip\nendian: little\n\
             byte skip: 4\ndata file: d.gz\n{extra}\n"
        )
    };
    let p = dir.path().join("a.nhdr");
    std::fs::write(&p, header("")).unwrap();
    let v = volume::load(&p).unwrap();
    let want: Vec<f32> = values.iter().map(|&v| v as f32).collect();
    assert_eq!(v.default().data, want);
    std::fs::write(
        &p,
        header("spacings: 2 3 4\naxis mins: 1 2 3\ncenterings: cell node cell\n"),
    )
    .unwrap();
    let v = volume::load(&p).unwrap();
    let origin = v.affine.w_axis.truncate();
    // A skip no decompressed file could hold is refused by name, not decompressed towards.
    std::fs::write(
        &p,
        header("").replace("byte skip: 4", "byte skip: 9000000000000000000"),
    )
    .unwrap();
    let e = volume::load(&p).unwrap_err().to_string();
    assert!(e.contains("byte skip") && e.contains("a.nhdr"), "{e}");
    assert_eq!(origin.to_array(), [2.0, 2.0, 5.0], "{:?}", v.affine);
}
