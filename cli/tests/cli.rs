//! The `umbra` binary as users and scripts call it.

use std::path::PathBuf;
use std::process::Command;

fn umbra() -> Command {
    Command::new(env!("CARGO_BIN_EXE_umbra"))
}

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .unwrap()
        .to_path_buf()
}

fn fixture(name: &str) -> PathBuf {
    root().join("tests").join("fixtures").join(name)
}

#[test]
fn every_subcommand_has_help() {
    let out = umbra().arg("--help").output().unwrap();
    assert!(out.status.success());
    let text = String::from_utf8_lossy(&out.stdout).to_string();
    let subs: Vec<String> = text
        .lines()
        .skip_while(|l| !l.starts_with("Commands:"))
        .skip(1)
        .take_while(|l| l.starts_with("  "))
        .filter_map(|l| l.split_whitespace().next().map(str::to_string))
        .filter(|s| s != "help")
        .collect();
    assert!(
        subs.contains(&"info".to_string()) && subs.contains(&"convert".to_string()),
        "{subs:?}"
    );
    for s in subs {
        let out = umbra().args([s.as_str(), "--help"]).output().unwrap();
        assert!(out.status.success(), "umbra {s} --help failed");
        assert!(
            String::from_utf8_lossy(&out.stdout).contains("Usage: umbra"),
            "umbra {s} --help"
        );
    }
}

#[test]
fn info_json_has_the_documented_keys_and_values() {
    let out = umbra()
        .args(["info", "--json"])
        .arg(fixture("lps_i16_gzip_be.nrrd"))
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    for key in [
        "format",
        "dims",
        "components",
        "type",
        "spacing",
        "affine",
        "space",
        "bounds",
        "range",
        "robust",
        "nonfinite",
        "fields",
    ] {
        assert!(v.get(key).is_some(), "missing key {key}");
    }
    assert_eq!(v["dims"], serde_json::json!([5, 4, 3]));
    assert_eq!(v["space"], "RAS");
    assert_eq!(v["type"], "int16");
    // LPS -> RAS: the first axis vector (0.9, 0.1, 0) becomes (-0.9, -0.1, 0): row 0, column 0.
    assert!((v["affine"][0][0].as_f64().unwrap() + 0.9).abs() < 1e-12);
    assert!((v["affine"][1][0].as_f64().unwrap() + 0.1).abs() < 1e-12);
    assert_eq!(v["affine"][3], serde_json::json!([0.0, 0.0, 0.0, 1.0]));
    let sp = v["spacing"][0].as_f64().unwrap();
    assert!((sp - (0.81f64 + 0.01).sqrt()).abs() < 1e-12);
    assert_eq!(v["range"], serde_json::json!([-100.0, 134.0]));
    assert_eq!(v["nonfinite"], 0);
    // `robust`: the 2nd and 98th percentiles (numpy's "linear") of the values, by sorting.
    let vol = volume::load(&fixture("lps_i16_gzip_be.nrrd")).unwrap();
    let mut x: Vec<f64> = vol.fields[0].data.iter().map(|&v| v as f64).collect();
    x.sort_by(f64::total_cmp);
    let q = |p: f64| {
        let at = p * (x.len() - 1) as f64;
        let k = at.floor() as usize;
        x[k] + (at - k as f64) * (x[(k + 1).min(x.len() - 1)] - x[k])
    };
    for (i, p) in [0.02, 0.98].into_iter().enumerate() {
        let got = v["robust"][i].as_f64().unwrap();
        assert!(
            (got - q(p)).abs() < 1e-9,
            "robust[{i}] {got} against {}",
            q(p)
        );
    }
    assert!(v["robust"][0].as_f64() < v["robust"][1].as_f64());
}

#[test]
fn info_field_selection_and_nonfinite_count() {
    let out = umbra()
        .args(["info", "--json", "--field", "velocity:magnitude"])
        .arg(fixture("image_binary.vtk"))
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["components"], 1);
    assert_eq!(v["fields"], serde_json::json!(["density", "velocity"]));
    // |(r, 1, -r)| at r = 0 is 1.
    assert!((v["range"][0].as_f64().unwrap() - 1.0).abs() < 1e-6);
    let out = umbra()
        .args(["info", "--json"])
        .arg(fixture("n2_f64_nan.nii"))
        .output()
        .unwrap();
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["nonfinite"], 2);
    assert_eq!(v["format"], "nifti2");
    // The robust range leaves the NaN out and lies within the finite range.
    let (r, lo, hi) = (&v["robust"], &v["range"][0], &v["range"][1]);
    assert!(
        r[0].as_f64().unwrap() >= lo.as_f64().unwrap()
            && r[1].as_f64().unwrap() <= hi.as_f64().unwrap(),
        "{v}"
    );
    let out = umbra()
        .args(["info", "--field", "nope"])
        .arg(fixture("image_binary.vtk"))
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("nope") && err.contains("density"), "{err}");
}

#[test]
fn errors_name_the_file_and_exit_non_zero_without_panicking() {
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("broken.nrrd");
    std::fs::write(
        &bad,
        b"NRRD0004\ntype: short\ndimension: 3\nsizes: 5 4\nencoding: raw\n\n",
    )
    .unwrap();
    let out = umbra().args(["info"]).arg(&bad).output().unwrap();
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("broken.nrrd") && err.contains("sizes"),
        "{err}"
    );
    assert!(!err.contains("panicked"), "{err}");
    let out = umbra()
        .args(["info"])
        .arg(dir.path().join("absent.nii.gz"))
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&out.stderr).contains("absent.nii.gz"));
}

#[test]
fn absurd_dimensions_stay_within_a_small_address_space() {
    // Run under a 512 MiB address-space limit: a reader that allocated from the header
    // (2^31 voxels x 4 bytes) would abort; ours answers with an error.
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("huge.nrrd");
    std::fs::write(&p, b"NRRD0004\ntype: float\ndimension: 3\nsizes: 2048 1024 1024\nendian: little\nencoding: raw\n\n\x00\x00\x80\x3f").unwrap();
    let gz = dir.path().join("huge.nii.gz");
    let mut h = vec![0u8; 352];
    h[0..4].copy_from_slice(&348i32.to_le_bytes());
    for (k, d) in [3i16, 2048, 1024, 1024, 1, 1, 1, 1].iter().enumerate() {
        h[40 + 2 * k..42 + 2 * k].copy_from_slice(&d.to_le_bytes());
    }
    h[70..72].copy_from_slice(&16i16.to_le_bytes());
    h[72..74].copy_from_slice(&32i16.to_le_bytes());
    h[108..112].copy_from_slice(&352f32.to_le_bytes());
    h[344..348].copy_from_slice(b"n+1\0");
    h.extend_from_slice(&[0u8; 4096]);
    let mut enc = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
    std::io::Write::write_all(&mut enc, &h).unwrap();
    std::fs::write(&gz, enc.finish().unwrap()).unwrap();
    // Files whose bytes really are there (sparse, 1 GiB): reading them whole needs more than
    // the limit, an error rather than an abort.
    let raw = dir.path().join("raw.nii");
    let mut h = h[..352].to_vec();
    for (k, d) in [3i16, 1024, 1024, 1024, 1, 1, 1, 1].iter().enumerate() {
        h[40 + 2 * k..42 + 2 * k].copy_from_slice(&d.to_le_bytes());
    }
    h[70..72].copy_from_slice(&2i16.to_le_bytes());
    h[72..74].copy_from_slice(&8i16.to_le_bytes());
    let f = std::fs::File::create(&raw).unwrap();
    std::io::Write::write_all(&mut &f, &h).unwrap();
    f.set_len(352 + (1 << 30)).unwrap();
    let tck = dir.path().join("raw.tck");
    let f = std::fs::File::create(&tck).unwrap();
    std::io::Write::write_all(
        &mut &f,
        b"mrtrix tracks\ndatatype: Float32LE\nfile: . 100\ncount: 1\nEND\n",
    )
    .unwrap();
    f.set_len(1 << 30).unwrap();
    for f in [&p, &gz, &raw, &tck] {
        let out = Command::new("sh")
            .arg("-c")
            .arg(format!(
                "ulimit -v 524288; exec '{}' info --json '{}'",
                env!("CARGO_BIN_EXE_umbra"),
                f.display()
            ))
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{}: {err}", f.display());
        assert!(
            err.contains("umbra: error")
                && err.contains(&*f.file_name().unwrap().to_string_lossy()),
            "{err}"
        );
    }
}

#[test]
fn convert_writes_nrrd_and_nifti_that_read_back() {
    let dir = tempfile::tempdir().unwrap();
    for out_name in ["c.nrrd", "c.nii.gz"] {
        let out = dir.path().join(out_name);
        let st = umbra()
            .args(["convert"])
            .arg(fixture("oblique_i16.mha"))
            .arg("-o")
            .arg(&out)
            .arg("--gzip")
            .status()
            .unwrap();
        assert!(st.success());
        let a = volume::load(&fixture("oblique_i16.mha")).unwrap();
        let b = volume::load(&out).unwrap();
        assert_eq!(a.default().data, b.default().data);
        assert_eq!(a.dims, b.dims);
    }
    // No temporary files are left behind.
    let left: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(left.len(), 2, "{left:?}");
    let st = umbra()
        .args(["convert"])
        .arg(fixture("oblique_i16.mha"))
        .arg("-o")
        .arg(dir.path().join("x.png"))
        .output()
        .unwrap();
    assert!(!st.status.success());
}

/// What `umbra convert` cannot carry over is said: float64 rounded to 32-bit floats, a file's
/// own frame that NIfTI would declare RAS+ (not for NRRD, which keeps it).
#[test]
fn convert_warns_of_what_the_output_does_not_keep() {
    let dir = tempfile::tempdir().unwrap();
    let run = |input: PathBuf, out: &str| {
        let o = umbra()
            .arg("convert")
            .arg(input)
            .arg("-o")
            .arg(dir.path().join(out))
            .output()
            .unwrap();
        assert!(o.status.success());
        String::from_utf8_lossy(&o.stderr).into_owned()
    };
    let e = run(fixture("detached_f64.nhdr"), "f.nrrd");
    assert!(
        e.contains("float64 samples are held as 32-bit floats"),
        "{e}"
    );
    let headsq = root().join("datasets/vtk/headsq_64x64x93.nhdr");
    let e = run(headsq.clone(), "h.nii");
    assert!(e.contains("NIfTI declares RAS+"), "{e}");
    let e = run(headsq.clone(), "h.nrrd");
    assert!(!e.contains("warning"), "{e}");
    // A field the file lacks: the error names the file.
    for cmd in [&["convert", "-o", "x.nrrd"][..], &["info"]] {
        let o = umbra()
            .args(cmd)
            .arg(&headsq)
            .args(["--field", "nope"])
            .current_dir(dir.path())
            .output()
            .unwrap();
        let e = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{e}");
        assert!(
            e.contains("headsq_64x64x93.nhdr: field nope"),
            "{cmd:?}: {e}"
        );
    }
}

#[test]
fn info_describes_tractograms() {
    let p = root().join("tests/fixtures/tracts/nibabel/complex.trk");
    let out = umbra().args(["info", "--json"]).arg(&p).output().unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["format"], "trk");
    assert_eq!(v["streamlines"], 3);
    assert_eq!(v["points"], 8);
    assert_eq!(
        v["bounds"],
        serde_json::json!([[0.0, 1.0, 2.0], [12.0, 13.0, 14.0]])
    );
    assert_eq!(v["attributes"]["point"]["colors"], 3);
    assert_eq!(v["attributes"]["streamline"]["mean_torsion"], 1);
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("bad.tck");
    std::fs::write(&bad, b"mrtrix tracks\ncount: 1\n").unwrap();
    let out = umbra().args(["info"]).arg(&bad).output().unwrap();
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&out.stderr).contains("END"));
}

#[test]
fn resample_writes_a_regular_volume_from_a_curvilinear_grid() {
    let dir = tempfile::tempdir().unwrap();
    // A sheared 3x3x3 curvilinear grid carrying s = x + 2y - z.
    let mut pts = Vec::new();
    let mut s = Vec::new();
    for k in 0..3 {
        for j in 0..3 {
            for i in 0..3 {
                let (x, y, z) = (i as f64 + 0.3 * j as f64, j as f64, k as f64);
                pts.push(format!("{x} {y} {z}"));
                s.push(format!("{}", x + 2.0 * y - z));
            }
        }
    }
    let text = format!(
        "# vtk DataFile Version 3.0\nsheared\nASCII\nDATASET STRUCTURED_GRID\nDIMENSIONS 3 3 3\nPOINTS 27 double\n{}\nPOINT_DATA 27\nSCALARS s double\nLOOKUP_TABLE default\n{}\n",
        pts.join("\n"),
        s.join(" ")
    );
    let input = dir.path().join("sheared.vtk");
    std::fs::write(&input, text).unwrap();
    let output = dir.path().join("s.nrrd");
    let out = umbra()
        .arg("resample")
        .arg(&input)
        .args(["--field", "s", "--dims", "9,5,5", "--json", "-o"])
        .arg(&output)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(report["points"], 27);
    assert_eq!(report["dims"], serde_json::json!([9, 5, 5]));
    let inside = report["inside"].as_f64().unwrap();
    assert!(inside > 0.6 && inside < 1.0, "{inside}");
    let vol = volume::load(&output).unwrap();
    let f = vol.select(None).unwrap();
    let mut checked = 0;
    for (n, &v) in f.data.iter().enumerate() {
        if v.is_nan() {
            continue;
        }
        let (i, j, k) = (n % 9, (n / 9) % 5, n / 45);
        let p = vol.index_to_world(glam::DVec3::new(i as f64, j as f64, k as f64));
        assert!(
            (v as f64 - (p.x + 2.0 * p.y - p.z)).abs() < 1e-5,
            "sample {n}: {v}"
        );
        checked += 1;
    }
    assert!(checked > 100);
    // NRRD keeps the grid's own frame, silently; NIfTI would declare it RAS+ (mm, R/L labels):
    // a warning says so, as convert's does.
    assert!(!String::from_utf8_lossy(&out.stderr).contains("RAS+"));
    let nii = umbra()
        .arg("resample")
        .arg(&input)
        .args(["--field", "s", "--dims", "9,5,5", "-o"])
        .arg(dir.path().join("s.nii"))
        .output()
        .unwrap();
    assert!(nii.status.success());
    let e = String::from_utf8_lossy(&nii.stderr);
    assert!(
        e.contains("warning") && e.contains("NIfTI declares RAS+"),
        "{e}"
    );

    // `umbra info` describes the grid itself.
    let out = umbra()
        .arg("info")
        .arg(&input)
        .arg("--json")
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let j: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(j["geometry"], "structured");
    assert_eq!(j["dims"], serde_json::json!([3, 3, 3]));
    assert_eq!(j["arrays"][0]["name"], "s");
    assert_eq!(j["arrays"][0]["on"], "points");
    // s = x + 2y - z over the nodes: x in 0..2.6, y and z in 0..2.
    let r = &j["arrays"][0]["range"];
    assert_eq!(r[0], -2.0);
    assert!((r[1].as_f64().unwrap() - 6.6).abs() < 1e-6, "{r}");

    // PLOT3D without its q file: a clear error and no output.
    let p3 = dir.path().join("grid.xyz");
    let mut b = Vec::new();
    for d in [2i32, 2, 2] {
        b.extend(d.to_be_bytes());
    }
    for c in 0..3 {
        for n in 0..8 {
            b.extend((((n >> c) & 1) as f32).to_be_bytes());
        }
    }
    std::fs::write(&p3, b).unwrap();
    let o2 = dir.path().join("none.nrrd");
    let out = umbra()
        .arg("resample")
        .arg(&p3)
        .args(["--field", "density", "-o"])
        .arg(&o2)
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("grid.xyz") && err.contains("--q"), "{err}");
    assert!(!o2.exists());
    // ... but `umbra info` recognises it (no signature: tried when the file is no volume).
    let out = umbra().arg("info").arg(&p3).arg("--json").output().unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let j: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(j["format"], "plot3d");
    assert_eq!(j["points"], 8);
    // A bad --dims is refused by the parser.
    let out = umbra()
        .arg("resample")
        .arg(&input)
        .args(["--field", "s", "--dims", "9,0,5", "-o"])
        .arg(&o2)
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("NX,NY,NZ"));
    // A field the grid does not have: the error names the file (resample and info alike).
    let err = |args: &[&str]| {
        let out = umbra().args(args).output().unwrap();
        assert!(!out.status.success(), "{args:?}");
        String::from_utf8_lossy(&out.stderr).into_owned()
    };
    let sheared = input.to_str().unwrap();
    let o3 = dir.path().join("n.nrrd");
    let o3 = o3.to_str().unwrap();
    for args in [
        &["resample", sheared, "--field", "nope", "-o", o3][..],
        &["info", sheared, "--field", "nope"],
    ] {
        let e = err(args);
        assert!(
            e.contains("sheared.vtk") && e.contains("nope"),
            "{args:?}: {e}"
        );
    }
    // One sample along an axis the grid extends along cannot span it: refused.
    let e = err(&[
        "resample", sheared, "--field", "s", "--dims", "4,1,4", "-o", o3,
    ]);
    assert!(e.contains("sheared.vtk") && e.contains("along y"), "{e}");
}

#[test]
fn scene_files_resolve_with_overrides_and_unknown_keys_are_errors() {
    let example = root().join("datasets/scenes/example.toml");
    let out = umbra()
        .arg("scene")
        .arg(&example)
        .args([
            "--set",
            "render.width=640",
            "--set",
            "tubes.0.color=#ff0000",
        ])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let j: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(j["render"]["width"], 640);
    assert_eq!(j["render"]["height"], 768);
    assert_eq!(j["tubes"][0]["color"], "#ff0000");
    // Paths resolve against the scene file's folder and exist for the bundled example.
    let vol = j["volume"]["path"].as_str().unwrap();
    assert!(std::path::Path::new(vol).exists(), "{vol}");
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("bad.toml");
    std::fs::write(&bad, "[camera]\nfov_y = 30\nazimut = 10\n").unwrap();
    let out = umbra().arg("scene").arg(&bad).output().unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("bad.toml") && err.contains("azimut") && err.contains("line 3"),
        "{err}"
    );
}

#[test]
fn the_readme_first_command_renders_the_demo() {
    // The umbra part of the README's first command, run from the repository root with the
    // output redirected to a temporary file and the image made smaller (lavapipe in CI).
    let readme = std::fs::read_to_string(root().join("README.md")).unwrap();
    let block = readme.split("```sh\n").nth(1).unwrap();
    let line = block.lines().next().unwrap();
    let args = line.split("cargo run --release -- ").nth(1).unwrap();
    let mut args: Vec<String> = args.split_whitespace().map(str::to_string).collect();
    assert_eq!(args[0], "demo");
    let o = args.iter().position(|a| a == "-o").unwrap();
    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("demo.png");
    args[o + 1] = png.display().to_string();
    args.extend(["--width", "256", "--height", "192"].map(String::from));
    let out = umbra().current_dir(root()).args(&args).output().unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let img = image::open(&png).unwrap().to_rgb8();
    assert_eq!(img.dimensions(), (256, 192));
    // The brain covers a tenth of the image or more, and the tracts (orange, blue and green,
    // unlike the template's greys) are in it.
    let covered = img
        .pixels()
        .filter(|p| p.0.iter().any(|&v| v < 240))
        .count();
    assert!(covered > 256 * 192 / 10, "{covered} covered pixels");
    let tracts = img
        .pixels()
        .filter(|p| {
            let (lo, hi) = (p.0.iter().min().unwrap(), p.0.iter().max().unwrap());
            (*hi as i32 - *lo as i32) > 60
        })
        .count();
    assert!(tracts > 300, "{tracts} tract pixels");
}

#[test]
fn a_closed_pipe_on_standard_output_ends_quietly() {
    // `umbra scene example.toml | head -1`: the reader goes away before (or while) the JSON is
    // written; the writer exits cleanly instead of panicking on the broken pipe.
    let example = root().join("datasets/scenes/example.toml");
    let mut child = umbra()
        .arg("scene")
        .arg(&example)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take());
    let out = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!err.contains("panicked"), "{err}");
    assert_eq!(out.status.code(), Some(0), "{err}");
}

/// `inside` counts the samples inside the mesh whatever the array's values: a NaN at one node
/// of a tetrahedron makes its samples NaN but keeps them inside, and a warning says so.
#[test]
fn resample_counts_samples_inside_the_mesh_whatever_their_values() {
    let dir = tempfile::tempdir().unwrap();
    let vtu = |values: &str| {
        format!(
            "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"0.1\" \
             byte_order=\"LittleEndian\">\n<UnstructuredGrid><Piece NumberOfPoints=\"4\" \
             NumberOfCells=\"1\">\n<PointData Scalars=\"s\"><DataArray type=\"Float32\" \
             Name=\"s\" format=\"ascii\">{values}</DataArray></PointData>\n<Points><DataArray \
             type=\"Float32\" NumberOfComponents=\"3\" format=\"ascii\">0 0 0 1 0 0 0 1 0 0 0 \
             1</DataArray></Points>\n<Cells><DataArray type=\"Int32\" Name=\"connectivity\" \
             format=\"ascii\">0 1 2 3</DataArray>\n<DataArray type=\"Int32\" Name=\"offsets\" \
             format=\"ascii\">4</DataArray>\n<DataArray type=\"UInt8\" Name=\"types\" \
             format=\"ascii\">10</DataArray></Cells>\n</Piece></UnstructuredGrid></VTKFile>\n"
        )
    };
    let mut reports = vec![];
    for (name, values) in [("ok", "0 1 2 3"), ("nan", "0 1 2 nan")] {
        let p = dir.path().join(format!("{name}.vtu"));
        std::fs::write(&p, vtu(values)).unwrap();
        let out = umbra()
            .arg("resample")
            .arg(&p)
            .args(["--field", "s", "--size", "8", "--json", "-o"])
            .arg(dir.path().join(format!("{name}.nrrd")))
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let j: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        reports.push(j);
    }
    let (ok, nan) = (&reports[0], &reports[1]);
    let inside = ok["inside"].as_f64().unwrap();
    // A corner tetrahedron of the unit cube holds about a sixth of a regular grid's samples.
    assert!(inside > 0.1 && inside < 0.4, "{inside}");
    assert_eq!(nan["inside"].as_f64(), Some(inside));
    assert!(ok["warnings"].as_array().unwrap().is_empty());
    let w = nan["warnings"].to_string();
    assert!(
        w.contains("inside the mesh are NaN") && w.contains("'s'"),
        "{w}"
    );
}

/// An error that quotes a huge value (a 5 MB string in a scene, as a bad colour or as a value
/// of the wrong type) stays short: each quoted line is cut.
#[test]
fn errors_quoting_a_huge_value_stay_short() {
    let dir = tempfile::tempdir().unwrap();
    let big = "x".repeat(5_000_000);
    for (name, text) in [
        ("colour.toml", format!("background = \"{big}\"\n")),
        ("type.toml", format!("background = [\"{big}\"]\n")),
    ] {
        let p = dir.path().join(name);
        std::fs::write(&p, text).unwrap();
        let out = umbra().arg("scene").arg(&p).output().unwrap();
        assert_eq!(out.status.code(), Some(1));
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            err.len() < 3000 && err.contains(name),
            "{name}: {} bytes",
            err.len()
        );
    }
}

/// A broken file named like a VTK file is refused by the VTK reader, never read as a PLOT3D
/// grid (which has no signature to tell it by).
#[test]
fn info_does_not_guess_plot3d_for_a_broken_vtk_file() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("broken.vtk");
    std::fs::write(&p, [7u8; 24]).unwrap();
    let out = umbra().arg("info").arg(&p).output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains("broken.vtk") && !err.contains("plot3d"),
        "{err}"
    );
}
