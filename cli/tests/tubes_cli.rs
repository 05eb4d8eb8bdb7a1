//! `umbra tubes` as users call it: PLY/OBJ output, statistics JSON, errors.

use std::path::PathBuf;
use std::process::Command;

fn umbra() -> Command {
    Command::new(env!("CARGO_BIN_EXE_umbra"))
}

/// Asserts that a run succeeded, printing its standard error where it did not.
fn succeeded(out: &std::process::Output) {
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

fn fixture(rel: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .unwrap()
        .join("tests/fixtures/tracts")
        .join(rel)
}

#[test]
fn tubes_writes_ply_and_obj_with_statistics() {
    let dir = tempfile::tempdir().unwrap();
    let ply = dir.path().join("t.ply");
    let stats = dir.path().join("s.json");
    let out = umbra()
        .arg("tubes")
        .arg(fixture("dipy/tracks300.trk"))
        .arg("-o")
        .arg(&ply)
        .args([
            "--radius",
            "0.3",
            "--sides",
            "6",
            "--tolerance",
            "0.1",
            "--caps",
            "--stats-json",
        ])
        .arg(&stats)
        .output()
        .unwrap();
    succeeded(&out);
    let j: serde_json::Value = serde_json::from_slice(&std::fs::read(&stats).unwrap()).unwrap();
    for k in [
        "streamlines_in",
        "streamlines_out",
        "points_in",
        "control_points",
        "triangles",
        "max_deviation",
        "max_twist_deg",
        "min_section_ratio",
        "radius_clamps",
        "splits",
    ] {
        assert!(j.get(k).is_some(), "missing {k}");
    }
    for k in ["read", "compute", "write", "total"] {
        assert!(j["seconds"][k].as_f64().unwrap() >= 0.0);
    }
    assert_eq!(j["streamlines_in"], 300);
    assert!(j["max_deviation"].as_f64().unwrap() <= 0.1 + 1e-9);
    assert!(j["control_points"].as_u64().unwrap() < j["points_in"].as_u64().unwrap());
    // Most of these lines are meshed as polylines at this tolerance (their fits placed more
    // rings than their polylines need): a polyline's frames twist more between its rings than
    // a fitted curve's (2.94 degrees here; 1.32 when 14 of the 300 were polylines).
    assert!(j["max_twist_deg"].as_f64().unwrap() <= 3.5);
    assert!(j["polyline_pieces"].as_u64().unwrap() > 150);
    assert!(j["min_section_ratio"].as_f64().unwrap() >= 0.5);
    // The PLY header lists what the issue asks for, and the body has the announced size.
    let bytes = std::fs::read(&ply).unwrap();
    let end = bytes
        .windows(11)
        .position(|w| w == b"end_header\n")
        .unwrap()
        + 11;
    let header = String::from_utf8_lossy(&bytes[..end]).to_string();
    for p in [
        "property float x",
        "property float nx",
        "property uchar red",
        "property list uchar int vertex_indices",
    ] {
        assert!(header.contains(p), "{header}");
    }
    let nv: usize = header
        .lines()
        .find(|l| l.starts_with("element vertex"))
        .unwrap()
        .split_whitespace()
        .nth(2)
        .unwrap()
        .parse()
        .unwrap();
    let nf: usize = header
        .lines()
        .find(|l| l.starts_with("element face"))
        .unwrap()
        .split_whitespace()
        .nth(2)
        .unwrap()
        .parse()
        .unwrap();
    assert_eq!(nf as u64, j["triangles"].as_u64().unwrap());
    assert_eq!(bytes.len() - end, nv * 27 + nf * 13);
    // OBJ as well.
    let obj = dir.path().join("t.obj");
    let st = umbra()
        .arg("tubes")
        .arg(fixture("nibabel/complex.trk"))
        .arg("-o")
        .arg(&obj)
        .args(["--color", "scalar:fa"])
        .status()
        .unwrap();
    assert!(st.success());
    let text = std::fs::read_to_string(&obj).unwrap();
    assert!(text.lines().any(|l| l.starts_with("v ")) && text.lines().any(|l| l.starts_with("f ")));
}

#[test]
fn tubes_errors_are_clear() {
    let dir = tempfile::tempdir().unwrap();
    let cases: &[(&[&str], &str)] = &[
        (&["--radius", "0"], "--radius"),
        (&["--color", "scalar:nope"], "nope"),
        (&["--color", "#12"], "#rrggbb"),
        (&["--fit", "magic"], "--fit"),
        (&["--transform", "1,2,3"], "--transform"),
        // A negative number is the option's value, refused by its range (it was clap's
        // "unexpected argument '-1'", exit 2).
        (&["--radius", "-1"], "--radius"),
        (&["--tolerance", "-0.1"], "--tolerance"),
        // Points are moved as points: a projective bottom row is refused, not dropped.
        (
            &["--transform", "1,0,0,0,0,1,0,0,0,0,1,0,0,0,0,2"],
            "bottom row",
        ),
    ];
    for (args, want) in cases {
        let out = umbra()
            .arg("tubes")
            .arg(fixture("nibabel/complex.trk"))
            .arg("-o")
            .arg(dir.path().join("x.ply"))
            .args(*args)
            .output()
            .unwrap();
        assert_eq!(out.status.code(), Some(1), "{args:?}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            err.contains(want) && !err.contains("unexpected"),
            "{args:?}: {err}"
        );
    }
    assert!(!dir.path().join("x.ply").exists());
    let out = umbra()
        .arg("tubes")
        .arg(dir.path().join("missing.trk"))
        .arg("-o")
        .arg(dir.path().join("y.ply"))
        .output()
        .unwrap();
    assert!(String::from_utf8_lossy(&out.stderr).contains("missing.trk"));
}

#[test]
fn trace_follows_a_synthetic_field_into_a_tractogram() {
    let dir = tempfile::tempdir().unwrap();
    let field = dir.path().join("rot.nrrd");
    assert!(umbra()
        .args(["synth", "rotation", "--n", "21", "-o"])
        .arg(&field)
        .status()
        .unwrap()
        .success());
    let csv = dir.path().join("seeds.csv");
    std::fs::write(&csv, "x,y,z\n0.5,0,0\n0.25,0,0.1\n").unwrap();
    let out = dir.path().join("t.tck");
    let o = umbra()
        .arg("trace")
        .arg(&field)
        .arg("-o")
        .arg(&out)
        .args(["--seeds"])
        .arg(&csv)
        .args(["--step", "0.02", "--max-length", "3.0", "--one-way"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // The field is in its own frame (a NRRD without a space): the tractogram's RAS+ mm is noted.
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("the field's frame is its own, not RAS+ mm") && err.contains("annotate.units"),
        "{err}"
    );
    let s = tubes::load(&out).unwrap();
    assert_eq!(s.len(), 2);
    // Circles about the z axis: the radius stays put.
    for (i, r0) in [(0usize, 0.5f32), (1, 0.25)] {
        for p in s.line(i) {
            assert!((p.x.hypot(p.y) - r0).abs() < 1e-3, "{p}");
        }
    }
    for bad in [
        ["--seeds", "grid:0"],
        ["--integrator", "magic"],
        ["--seeds", "plane:w=1:3"],
    ] {
        let o = umbra()
            .arg("trace")
            .arg(&field)
            .arg("-o")
            .arg(dir.path().join("x.tck"))
            .args(bad)
            .output()
            .unwrap();
        assert_eq!(o.status.code(), Some(1), "{bad:?}");
    }
    // Seeds that give no line: an empty tractogram, and a warning that says why.
    let far = dir.path().join("far.csv");
    std::fs::write(&far, "x,y,z\n100,100,100\n").unwrap();
    let empty = dir.path().join("empty.tck");
    let o = umbra()
        .arg("trace")
        .arg(&field)
        .arg("-o")
        .arg(&empty)
        .arg("--seeds")
        .arg(&far)
        .output()
        .unwrap();
    assert!(o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("warning: no seed gave a line"), "{err}");
    assert_eq!(tubes::load(&empty).unwrap().len(), 0);
    // Fields nothing can be traced in are errors naming the file, and nothing is written: a
    // field of NaN vectors, one of zeros, and a grid of one sample (its default length was
    // "max length 0: must be a positive number").
    let vectors = |name: &str, n: usize, v: f32| {
        let p = dir.path().join(name);
        let mut b = format!(
            "NRRD0004\ntype: float\ndimension: 4\nsizes: 3 {n} {n} {n}\n\
             kinds: 3-vector domain domain domain\nencoding: raw\nendian: little\n\n"
        )
        .into_bytes();
        for _ in 0..3 * n * n * n {
            b.extend_from_slice(&v.to_le_bytes());
        }
        std::fs::write(&p, b).unwrap();
        p
    };
    for (f, want) in [
        (
            vectors("nan.nrrd", 4, f32::NAN),
            "zero or not finite everywhere",
        ),
        (
            vectors("zero.nrrd", 4, 0.0),
            "zero or not finite everywhere",
        ),
        (vectors("one.nrrd", 1, 1.0), "a grid of one sample"),
    ] {
        let out = dir.path().join("none.trk");
        let o = umbra()
            .arg("trace")
            .arg(&f)
            .arg("-o")
            .arg(&out)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{err}");
        assert!(
            err.contains(want) && err.contains(&*f.to_string_lossy()),
            "{err}"
        );
        assert!(!out.exists());
    }
}

/// A negative bundle radius reaches the generator's check (not clap's "unexpected argument"),
/// which names the key and the value, and nothing is written.
#[test]
fn a_negative_bundle_radius_is_refused_by_name() {
    let dir = tempfile::tempdir().unwrap();
    let tck = dir.path().join("b.tck");
    let out = umbra()
        .args(["synth", "bundles", "--n", "10", "--radius", "-1", "-o"])
        .arg(&tck)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        err.contains("radius -1") && err.contains(">= 0") && !err.contains("unexpected"),
        "{err}"
    );
    assert!(!tck.exists());
}

/// `umbra synth bundles --n 30000 --points 20` into `dir`: the memory tests' tractogram.
fn bundles_30k(dir: &std::path::Path) -> std::path::PathBuf {
    let tck = dir.join("bundles.tck");
    let out = umbra()
        .args(["synth", "bundles", "--n", "30000", "--points", "20", "-o"])
        .arg(&tck)
        .output()
        .unwrap();
    succeeded(&out);
    tck
}

/// `umbra tubes TCK -o OUT --sides SIDES --radius 0.2` under an address-space limit of `limit`
/// bytes (`prlimit --as`, as a cluster job would set it), with two threads (the address space
/// of threads and their malloc arenas grows with the cores).
fn tubes_limited(
    limit: u64,
    tck: &std::path::Path,
    out: &std::path::Path,
    sides: u32,
) -> std::process::Output {
    Command::new("prlimit")
        .arg(format!("--as={limit}"))
        .arg(env!("CARGO_BIN_EXE_umbra"))
        .arg("tubes")
        .arg(tck)
        .arg("-o")
        .arg(out)
        .args(["--sides", &sides.to_string(), "--radius", "0.2"])
        .env("RAYON_NUM_THREADS", "2")
        .env("MALLOC_ARENA_MAX", "2")
        .output()
        .expect("prlimit (util-linux) runs umbra under an address-space limit")
}

/// Issue 18: a tractogram whose tube mesh would not fit is refused before meshing, with the
/// memory it would need (estimated from a mesh of 1000 of its streamlines): 30,000 synthetic
/// streamlines with 64-sided tubes need about 2 GB as an OBJ, whose mesh is held whole (the
/// estimate at 30 bytes a triangle); under a 1 GB address-space limit (`prlimit --as`, as a
/// cluster job would set it) `umbra tubes` stops at once, writing nothing. A PLY of the same
/// tubes is written part by part (`tube_mesh::build_streamed`) and is not refused.
#[test]
fn tubes_that_would_not_fit_are_refused_with_the_memory_they_need() {
    let dir = tempfile::tempdir().unwrap();
    let tck = bundles_30k(dir.path());
    let obj = dir.path().join("t.obj");
    let out = tubes_limited(1_000_000_000, &tck, &obj, 64);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains("bundles.tck")
            && err.contains("would need about")
            && err.contains("address-space limit")
            && err.contains("lines"),
        "{err}"
    );
    // The estimate: 1.5 to 3 GB (the mesh's vertices, triangles and rings,
    // `tube_sets::mesh_memory_estimate`).
    let gb: f64 = err
        .split("would need about ")
        .nth(1)
        .and_then(|r| r.split(" GB").next())
        .and_then(|v| v.parse().ok())
        .unwrap();
    assert!((1.5..3.0).contains(&gb), "{gb} GB: {err}");
    assert!(!obj.exists());
}

/// The estimate counts what an OBJ's meshing holds: the mesh's vertices (27 bytes) and
/// triangles (12) and every tube's rings, scaled from the sample. 300,000 random walks of three
/// points (short tubes: many vertices and rings a triangle) under address-space limits of
/// 400-600 MB are refused or written, never aborted: at 30 bytes a triangle (the estimate
/// before) the mesh was guessed at 0.3 GB, passed under 500 MB and the allocation failed
/// (exit 134, "memory allocation of ... failed"; a new user's 10^6 lines under `ulimit -v`).
#[test]
fn short_tubes_near_the_memory_limit_are_refused_or_written_never_aborted() {
    let dir = tempfile::tempdir().unwrap();
    let tck = dir.path().join("walks.tck");
    let mut s = tubes::Streamlines::new();
    let mut state = 12345u64;
    let mut rnd = || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((state >> 11) as f64 / (1u64 << 53) as f64) as f32 - 0.5
    };
    for _ in 0..300_000 {
        let mut p = glam::Vec3::new(rnd(), rnd(), rnd()) * 100.0;
        let line: Vec<glam::Vec3> = (0..3)
            .map(|_| {
                p += glam::Vec3::new(rnd(), rnd(), rnd()) * 3.0;
                p
            })
            .collect();
        s.push(&line);
    }
    tubes::tck::write(&tck, &s).unwrap();
    let obj = dir.path().join("w.obj");
    for mb in [400u64, 450, 500, 550, 600] {
        let out = tubes_limited(mb * 1_000_000, &tck, &obj, 8);
        let err = String::from_utf8_lossy(&out.stderr);
        match out.status.code() {
            Some(0) => assert!(obj.exists(), "{mb} MB: no OBJ"),
            Some(1) => assert!(err.contains("would need about"), "{mb} MB: {err}"),
            c => panic!("{mb} MB: exit {c:?}: {err}"),
        }
        let _ = std::fs::remove_file(&obj);
    }
}

/// Issue 18: a PLY is meshed and written part by part (`tube_mesh::build_streamed`), so
/// `umbra tubes` holds the points, the rings and one part, not the mesh: 30,000 streamlines
/// as 18-sided tubes (16.6 M triangles, a 455 MB file; held whole, the mesh alone takes 30
/// bytes a triangle, 0.5 GB) are written under a 500 MB address-space limit, in which the
/// same tubes as an OBJ (whose mesh is held whole) are refused.
#[test]
fn a_ply_larger_than_the_memory_limit_is_written_part_by_part() {
    let dir = tempfile::tempdir().unwrap();
    let tck = bundles_30k(dir.path());
    let run = |path: &std::path::Path| tubes_limited(500_000_000, &tck, path, 18);
    let ply = dir.path().join("t.ply");
    let out = run(&ply);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    let m = tubes::mesh_io::read(&ply).unwrap();
    assert!(m.triangles() > 16_000_000, "{} triangles", m.triangles());
    let n = m.positions.len() as u32;
    assert!(
        m.indices.iter().all(|&i| i < n),
        "an index past the {n} vertices"
    );
    let obj = dir.path().join("t.obj");
    let out = run(&obj);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("would need about"),
        "{err}"
    );
    assert!(!obj.exists());
}

/// A looser tolerance costs fewer triangles on HCP1065's bundles. TR_S_R: 785,248 at
/// tolerance 0.1 against 430,896 at 0.05 while a fitted line could take more rings than its
/// polyline (its lines rough enough at 0.05 to be polylines, smooth enough at 0.1 to be fitted,
/// their fits wiggling within the tolerance); 422,848 when the fits were weighed against their
/// polylines but lines with a sharp turn kept theirs; 351,424 now, and 286,960 at 0.2. SCP and
/// MCP cost 17% and 14% more at 0.2 than at 0.1 while lines with a tracker's hook at an end (a
/// sharp turn, which keeps a line from being meshed as its polyline) kept fits with more rings
/// than their polylines needed; with kinks within the tolerance dropped and the other hooks
/// split off (`tubes::tube_mesh::drop_kinks`, `split_rings`), 0.05 > 0.1 > 0.2 on all ten bundles
/// (docs/benchmarks.md, "A fit weighed against its polyline's rings"). No caps: `bench tubes`
/// counts as `umbra tubes` meshes by default. Skipped without `../shared/data`.
#[test]
fn a_looser_tolerance_does_not_cost_more_triangles_on_hcp1065() {
    let Some(shared) = test_support::shared_or_skip("a_looser_tolerance") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let mut tri = vec![];
    for bundle in ["TR_S_R", "SCP", "MCP"] {
        let out = umbra()
            .args(["bench", "tubes"])
            .arg(shared.join(format!("tracts/hcp1065/{bundle}.trk.gz")))
            .arg("-o")
            .arg(dir.path())
            .args(["--tolerances", "0.05,0.1,0.2", "--runs", "1"])
            .output()
            .unwrap();
        succeeded(&out);
        let csv = std::fs::read_to_string(dir.path().join("tubes.csv")).unwrap();
        tri = csv
            .lines()
            .skip(1)
            .map(|l| l.split(',').nth(2).unwrap().parse().unwrap())
            .collect::<Vec<f64>>();
        assert_eq!(tri.len(), 3, "{csv}");
        eprintln!("{bundle}: {tri:?} triangles at 0.05, 0.1, 0.2");
        assert!(tri[1] < tri[0] && tri[2] < tri[1], "{bundle}: {tri:?}");
    }
    // The command's own count at 0.05 (no caps), on the last bundle.
    let stats = dir.path().join("s.json");
    let out = umbra()
        .arg("tubes")
        .arg(shared.join("tracts/hcp1065/MCP.trk.gz"))
        .arg("-o")
        .arg(dir.path().join("t.ply"))
        .args(["--tolerance", "0.05", "--stats-json"])
        .arg(&stats)
        .output()
        .unwrap();
    succeeded(&out);
    let j: serde_json::Value = serde_json::from_slice(&std::fs::read(&stats).unwrap()).unwrap();
    assert_eq!(
        j["triangles"].as_f64(),
        Some(tri[0]),
        "bench tubes counts as umbra tubes"
    );
}

/// A bad `--color` names the flag and the problem; a vector volume to colour by says how many
/// components it has (it said only "needs a scalar volume").
#[test]
fn a_bad_tube_colour_names_the_flag() {
    let dir = tempfile::tempdir().unwrap();
    let tracts = test_support::root().join("datasets/tracts/CST_L_demo.trk.gz");
    let run = |color: &str| {
        let o = umbra()
            .arg("tubes")
            .arg(&tracts)
            .arg("-o")
            .arg(dir.path().join("t.ply"))
            .args(["--color", color])
            .output()
            .unwrap();
        assert_eq!(o.status.code(), Some(1), "{color}");
        String::from_utf8_lossy(&o.stderr).into_owned()
    };
    let e = run("#12345");
    assert!(
        e.contains("--color: colour #12345: expected #rrggbb"),
        "{e}"
    );
    let field = dir.path().join("rot.nrrd");
    assert!(umbra()
        .args(["synth", "rotation", "--n", "5", "-o"])
        .arg(&field)
        .status()
        .unwrap()
        .success());
    let e = run(&format!("volume:{}", field.display()));
    assert!(
        e.contains("--color: colour volume:") && e.contains("has 3 components"),
        "{e}"
    );
}

/// Dropped points are counted apart: NaN points and points repeating the one before (a clean
/// whole-brain file's 11,169 repeats read as NaNs).
#[test]
fn dropped_nan_and_repeated_points_are_told_apart() {
    use glam::Vec3;
    let dir = tempfile::tempdir().unwrap();
    let line = |y: f32| -> Vec<Vec3> { (0..20).map(|k| Vec3::new(k as f32, y, 0.0)).collect() };
    let mut clean = tubes::Streamlines::new();
    let mut a = line(0.0);
    a.insert(5, a[5]);
    clean.push(&a);
    clean.push(&line(3.0));
    let mut dirty = clean.clone();
    let mut b = line(6.0);
    b[9] = Vec3::new(f32::NAN, 6.0, 0.0);
    dirty.push(&b);
    let run = |s: &tubes::Streamlines, name: &str| {
        let p = dir.path().join(name);
        tubes::save(&p, s).unwrap();
        let o = umbra()
            .arg("tubes")
            .arg(&p)
            .arg("-o")
            .arg(dir.path().join("t.ply"))
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        String::from_utf8_lossy(&o.stderr).into_owned()
    };
    let e = run(&clean, "clean.trk");
    assert!(
        e.contains("1 repeated points (each equal to the point before it) were dropped")
            && !e.contains("NaN"),
        "{e}"
    );
    let e = run(&dirty, "dirty.trk");
    assert!(
        e.contains("1 non-finite (NaN or infinite) points and 1 repeated points"),
        "{e}"
    );
}
