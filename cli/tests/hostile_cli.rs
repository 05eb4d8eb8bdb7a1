//! Issue 17's hostile command lines, one test per case: every numeric option range-checked
//! (NaN and infinities refused) before any work, every output path checked before the first
//! output is written, and hostile headers that panicked the commands behind them.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn umbra() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_umbra"));
    c.env("XDG_RUNTIME_DIR", std::env::temp_dir());
    c
}

fn fixture(rel: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .unwrap()
        .join("tests/fixtures")
        .join(rel)
}

/// Runs `umbra ARGS`, expecting a clean failure (exit 1 or clap's 2, no panic, no signal)
/// whose standard error contains `needle`; returns it.
fn refused(args: &[&str], needle: &str) -> String {
    let out: Output = umbra().args(args).output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr).to_string();
    assert!(
        matches!(out.status.code(), Some(1) | Some(2)),
        "{args:?}: status {:?}\n{err}",
        out.status
    );
    assert!(!err.contains("panicked"), "{args:?}: {err}");
    assert!(
        err.contains(needle),
        "{args:?}: wanted '{needle}' in\n{err}"
    );
    err
}

/// `dir/s.toml`: a scene of the volume `path` with the `rest` of its keys.
fn volume_scene(dir: &std::path::Path, path: &std::path::Path, rest: &str) -> PathBuf {
    let scene = dir.join("s.toml");
    std::fs::write(
        &scene,
        format!("[volume]\npath = \"{}\"\n{rest}", path.display()),
    )
    .unwrap();
    scene
}

/// Runs `umbra ARGS`, expecting success.
fn succeeds(args: &[&str]) {
    let out = umbra().args(args).output().unwrap();
    assert!(
        out.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// `umbra sweep VOL --iso 50 -o DIST --octants-out OCT`.
fn sweep_to<'a>(vol: &'a Path, dist: &'a Path, oct: &'a Path) -> [&'a str; 8] {
    [
        "sweep",
        s(vol),
        "--iso",
        "50",
        "-o",
        s(dist),
        "--octants-out",
        s(oct),
    ]
}

#[test]
fn tube_settings_out_of_range_are_refused_before_reading() {
    let d = tempfile::tempdir().unwrap();
    let trk = fixture("tracts/nibabel/simple.trk");
    let out = d.path().join("t.ply");
    // --chordal 0, NaN or 1e-12 ran for seconds and allocated gigabytes; -1 gave 6.3 M
    // triangles for 8 points.
    for bad in ["0", "nan", "1e-12", "-1", "inf"] {
        refused(
            &["tubes", s(&trk), "-o", s(&out), &format!("--chordal={bad}")],
            "chordal tolerance",
        );
    }
    // --radius 1e300 gave 0 triangles; 1e6 cannot bend with curved lines (these straight
    // ones are meshed as their polylines since their fits are weighed against them: a
    // straight tube of any radius folds nowhere).
    refused(
        &["tubes", s(&trk), "-o", s(&out), "--radius", "1e300"],
        "radius 1e300",
    );
    refused(
        &[
            "tubes",
            s(&fixture("tracts/dipy/tracks300.trk")),
            "-o",
            s(&out),
            "--radius",
            "1e6",
        ],
        "no tube could be built",
    );
    assert!(!out.exists());
    // A good chordal tolerance still meshes.
    succeeds(&["tubes", s(&trk), "-o", s(&out), "--chordal", "0.01"]);
    assert!(out.exists());
}

#[test]
fn a_second_output_that_cannot_be_written_leaves_no_first_output() {
    let d = tempfile::tempdir().unwrap();
    // A path under a regular file can never be created.
    let blocker = d.path().join("file");
    std::fs::write(&blocker, b"x").unwrap();
    let bad = blocker.join("stats.json");
    let trk = fixture("tracts/nibabel/simple.trk");
    let mesh = d.path().join("t.ply");
    refused(
        &["tubes", s(&trk), "-o", s(&mesh), "--stats-json", s(&bad)],
        "cannot write",
    );
    assert!(
        !mesh.exists(),
        "the mesh was written before the stats path was checked"
    );
    let vol = fixture("spacings_ascii.nrrd");
    let dist = d.path().join("d.nrrd");
    refused(
        &sweep_to(&vol, &dist, &blocker.join("oct.nrrd")),
        "cannot write",
    );
    assert!(
        !dist.exists(),
        "the distance was written before the octants path was checked"
    );
    let scene = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .unwrap()
        .join("datasets/scenes/example.toml");
    let png = d.path().join("r.png");
    refused(
        &[
            "render",
            s(&scene),
            "-o",
            s(&png),
            "--timings-json",
            s(&bad),
        ],
        "cannot write",
    );
    assert!(!png.exists());
    // The output of convert and resample: the format before the work.
    refused(
        &["convert", s(&vol), "-o", s(&d.path().join("x.png"))],
        "output format",
    );
}

#[test]
fn sweep_trace_and_resample_values_are_range_checked() {
    let d = tempfile::tempdir().unwrap();
    let vol = fixture("spacings_ascii.nrrd");
    let o = d.path().join("d.nrrd");
    // NaN tolerance; a subsurface opacity documented 0-1 (2 was clamped in silence).
    for (flag, v, needle) in [
        ("--tolerance", "nan", "--tolerance"),
        ("--subsurface", "2", "0 to 1"),
        ("--subsurface", "nan", "0 to 1"),
    ] {
        refused(
            &["sweep", s(&vol), "--iso", "5", "-o", s(&o), flag, v],
            needle,
        );
    }
    // --tolerance with closest points: options that conflict, a usage error (status 2, as the
    // README says; it was 1).
    let out = umbra()
        .args([
            "sweep",
            s(&vol),
            "--iso",
            "5",
            "-o",
            s(&o),
            "--tolerance",
            "0.01",
        ])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("closest points need none"), "{err}");
    assert!(err.contains("umbra sweep"), "the sweep's usage: {err}");
    assert!(!o.exists());
    // A negative value is a value out of range (status 1), however it is written.
    let neg = umbra()
        .args(["sweep", s(&vol), "--iso", "5", "-o", s(&o)])
        .args(["--distance", "sweeping", "--tolerance", "-1"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&neg.stderr);
    assert_eq!(neg.status.code(), Some(1), "{err}");
    assert!(err.contains("--tolerance"), "{err}");
    let field = fixture("ras_vec_raw.nrrd");
    let trk = d.path().join("t.trk");
    // NaN lengths and tolerances gave "0 streamlines".
    for (flag, v) in [
        ("--max-length", "nan"),
        ("--tolerance", "nan"),
        ("--step", "0"),
        ("--min-speed", "-1"),
        ("--max-angle", "nan"),
        ("--max-angle", "270"),
        ("--threshold", "nan"),
    ] {
        refused(
            &["trace", s(&field), "-o", s(&trk), &format!("{flag}={v}")],
            flag,
        );
    }
    refused(
        &[
            "trace",
            s(&field),
            "-o",
            s(&trk),
            "--seeds",
            "plane:x=nan:4",
        ],
        "finite",
    );
    assert!(!trk.exists());
    let grid = fixture("grids/fire_part_42_ascii.vtk");
    // --size 0 gave a 2 x 1 x 1 volume.
    for size in ["0", "1", "5000"] {
        refused(
            &[
                "resample",
                s(&grid),
                "--field",
                "T",
                "--size",
                size,
                "-o",
                s(&o),
            ],
            "2 to 2048",
        );
    }
    refused(
        &["render", "x.toml", "-o", "x.png", "--frames", "0"],
        "--frames",
    );
}

#[test]
fn scene_values_that_cannot_be_drawn_are_refused_naming_the_key() {
    let scene = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .unwrap()
        .join("datasets/scenes/demo.toml");
    let plane = "{normal=[0,0,1],offset=0}";
    let nine = format!("clip=[{}]", [plane; 9].join(","));
    for (set, key) in [
        ("camera.distance=nan", "camera.distance"),
        ("camera.distance=inf", "camera.distance"),
        ("camera.azimuth=nan", "camera.azimuth"),
        ("camera.far=inf", "camera.far"),
        ("light.ambient=nan", "light.ambient"),
        ("light.shininess=0", "light.shininess"),
        (
            "volume.transfer.extinction=nan",
            "volume.transfer.extinction",
        ),
        ("volume.transfer.range=[1.0,nan]", "volume.transfer.range"),
        ("volume.transfer.range=\"wide\"", "volume.transfer.range"),
        ("volume.transfer.range=5", "volume.transfer.range"),
        (
            "volume.transfer.range=[-1e39,1e39]",
            "volume.transfer.range",
        ),
        ("clip=[{normal=[nan,0,1],offset=0}]", "clip[0].normal"),
        ("clip=[{normal=[0,0,1],offset=inf}]", "clip[0].offset"),
        (nine.as_str(), "at most 8"),
        ("render.slice_distance=inf", "render.slice_distance"),
        // Transfer-function values past single precision (the devices drew different images).
        (
            "volume.transfer={points=[{value=-1e39,color=[1,0,0],extinction=0.05},{value=1e39,color=[1,1,1],extinction=0.05}]}",
            "volume.transfer.points[0].value",
        ),
        (
            "volume.transfer={points=[{value=-3e38,color=[1,0,0],extinction=0.05},{value=3e38,color=[1,1,1],extinction=0.05}]}",
            "span more than single precision",
        ),
        // Figures: a scale bar or eyes farther apart than any world, what 1 bit cannot show,
        // an entry's index written otherwise than its key, text the font cannot draw.
        ("annotate.scale_bar=1e30", "annotate.scale_bar"),
        ("render.eye_separation=1e30", "render.eye_separation"),
        ("annotate.colorbar=\"tubes.00\"", "this scene's colour bars: volume"),
        ("annotate.title=\"Fibres 中文\"", "no glyph for 2"),
    ] {
        refused(&["scene", s(&scene), "--set", set], key);
    }
    // What a 1-bit image cannot hold: an anaglyph's two colours, a colour bar's.
    for (set, key) in [
        ("render.stereo=\"anaglyph\"", "render.bits"),
        ("annotate.colorbar=\"volume\"", "1-bit"),
    ] {
        refused(
            &["scene", s(&scene), "--set", set, "--set", "render.bits=1"],
            key,
        );
    }
}

#[test]
fn hostile_headers_fail_cleanly_in_every_command_that_reads_them() {
    let d = tempfile::tempdir().unwrap();
    // DimSize whose product wraps to 2 in 64 bits: sweep panicked (index out of bounds),
    // sweep --sdf-only with "capacity overflow", convert wrote a NRRD its reader refuses.
    let mha = d.path().join("wrap.mha");
    std::fs::write(
        &mha,
        b"ObjectType = Image\nNDims = 3\nDimSize = 3 6148914691236517206 1\n\
          ElementType = MET_UCHAR\nElementDataFile = LOCAL\nab",
    )
    .unwrap();
    let o = d.path().join("o.nrrd");
    refused(&["info", s(&mha)], "DimSize");
    refused(&["sweep", s(&mha), "--iso", "1", "-o", s(&o)], "DimSize");
    refused(
        &["sweep", s(&mha), "--iso", "1", "-o", s(&o), "--sdf-only"],
        "DimSize",
    );
    refused(&["convert", s(&mha), "-o", s(&o)], "DimSize");
    let vec3 = d.path().join("wrap3.mha");
    std::fs::write(
        &vec3,
        b"ObjectType = Image\nNDims = 3\nDimSize = 3 6148914691236517206 1\n\
          ElementNumberOfChannels = 3\nElementType = MET_FLOAT\nElementDataFile = LOCAL\nabcdef",
    )
    .unwrap();
    refused(
        &["trace", s(&vec3), "-o", s(&d.path().join("t.trk"))],
        "DimSize",
    );
    assert!(!o.exists());
    // A tractogram that is a device.
    #[cfg(unix)]
    {
        let link = d.path().join("zero.tck");
        std::os::unix::fs::symlink("/dev/zero", &link).unwrap();
        refused(
            &["tubes", s(&link), "-o", s(&d.path().join("t.ply"))],
            "regular file",
        );
        refused(&["info", s(&link)], "regular file");
    }
}

#[test]
fn compressed_vtk_polylines_are_described_by_info() {
    let d = tempfile::tempdir().unwrap();
    let vtk = std::fs::read(fixture("tracts/lines_ascii.vtk")).unwrap();
    let p = d.path().join("l.vtk.gz");
    std::fs::write(&p, volume::gzip_bytes(&vtk)).unwrap();
    let out = umbra().args(["info", s(&p), "--json"]).output().unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let j: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(j["streamlines"], 3, "{j}");
}

#[test]
fn a_killed_writers_temporary_is_removed_when_the_output_is_written_again() {
    let d = tempfile::tempdir().unwrap();
    let out = d.path().join("c.nrrd");
    // What a process killed mid-write leaves (its PID long gone).
    let stale = d.path().join(".c.nrrd.999999999.tmp");
    std::fs::write(&stale, b"half").unwrap();
    succeeds(&["convert", s(&fixture("spacings_ascii.nrrd")), "-o", s(&out)]);
    assert!(out.exists());
    assert!(!stale.exists(), "the stale temporary is still there");
}

#[test]
fn a_subsample_of_nothing_is_refused() {
    let d = tempfile::tempdir().unwrap();
    let trk = fixture("tracts/nibabel/simple.trk");
    let out = d.path().join("o.trk");
    refused(
        &[
            "tracts",
            "select",
            s(&trk),
            "-o",
            s(&out),
            "--subsample",
            "0",
        ],
        "subsample",
    );
    assert!(!out.exists());
}

/// A CPU frame larger than the process may allocate (an address-space limit, as `ulimit -v`
/// on a cluster node) is a clear error naming the size keys, not an abort, and no file.
#[test]
fn a_cpu_frame_past_the_memory_limit_is_refused_cleanly() {
    let dir = tempfile::tempdir().unwrap();
    let headsq = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .unwrap()
        .join("datasets/vtk/headsq_64x64x93.nhdr");
    let scene = volume_scene(
        dir.path(),
        &headsq,
        "[render]\ndevice = \"cpu\"\nmethod = \"ea\"\n",
    );
    let png = dir.path().join("huge.png");
    // 6 GB of address space: enough to start (lavapipe included), not for 16 GiB of frame.
    let out = Command::new("sh")
        .arg("-c")
        .arg(
            "ulimit -v 6000000 && exec \"$0\" render \"$1\" -o \"$2\" --width 16384 --height 16384",
        )
        .arg(env!("CARGO_BIN_EXE_umbra"))
        .arg(&scene)
        .arg(&png)
        .env("XDG_RUNTIME_DIR", std::env::temp_dir())
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains("render.width and render.height") && err.contains("16384 x 16384"),
        "{err}"
    );
    assert!(!png.exists());
}

/// Outputs whose name promises another format than the command writes are refused before
/// any work, naming the file (an `iso` PNG named .jpg, NIfTI asked to be gzip-encoded by
/// `--gzip`), and nothing is written.
#[test]
fn outputs_named_for_another_format_are_refused() {
    let d = tempfile::tempdir().unwrap();
    let input = fixture("lps_i16_gzip_be.nrrd");
    let input = input.to_str().unwrap();
    let jpg = d.path().join("q.jpg");
    let e = refused(
        &["iso", input, "--iso", "0", "-o", jpg.to_str().unwrap()],
        "q.jpg: umbra iso writes PNG images",
    );
    assert!(!jpg.exists(), "{e}");
    let nii = d.path().join("q.nii");
    refused(
        &["convert", input, "-o", nii.to_str().unwrap(), "--gzip"],
        "q.nii: --gzip encodes NRRD output",
    );
    assert!(!nii.exists());
}

/// Two outputs of one command naming one file (literally or through `..`) are refused before
/// any work: the second write replaced the first (a sweep's octants over its distance, a
/// render's timings over its record).
#[test]
fn two_outputs_naming_one_file_are_refused() {
    let d = tempfile::tempdir().unwrap();
    let vol = fixture("spacings_ascii.nrrd");
    let x = d.path().join("x.nrrd");
    std::fs::create_dir(d.path().join("sub")).unwrap();
    let via = d.path().join("sub/../x.nrrd");
    for other in [&x, &via] {
        refused(&sweep_to(&vol, &x, other), "for a second output");
        assert!(!x.exists());
    }
    let trk = fixture("tracts/nibabel/simple.trk");
    let ply = d.path().join("t.ply");
    refused(
        &["tubes", s(&trk), "-o", s(&ply), "--stats-json", s(&ply)],
        "for a second output",
    );
    assert!(!ply.exists());
    let scene = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .unwrap()
        .join("datasets/scenes/example.toml");
    let json = d.path().join("r.json");
    let png = d.path().join("r.png");
    refused(
        &[
            "render",
            s(&scene),
            "-o",
            s(&png),
            "--record",
            s(&json),
            "--timings-json",
            s(&json),
        ],
        "for a second output",
    );
    assert!(!png.exists());
    // Distinct names in one folder still run.
    succeeds(&sweep_to(&vol, &x, &d.path().join("o.nrrd")));
}

/// A volume scene of `umbra synth` named for another format is refused before it is made
/// (`-o ph.tck` wrote a NRRD under that name).
#[test]
fn a_synthetic_volume_named_for_another_format_is_refused() {
    let d = tempfile::tempdir().unwrap();
    for name in ["ph.tck", "ph.txt", "ph"] {
        let out = d.path().join(name);
        refused(
            &["synth", "phantom", "--n", "8", "-o", s(&out)],
            "phantom is a volume: write it as .nrrd, .nii or .nii.gz",
        );
        assert!(!out.exists(), "{name}");
    }
    succeeds(&[
        "synth",
        "phantom",
        "--n",
        "8",
        "-o",
        s(&d.path().join("ph.NRRD")),
    ]);
    // Each scene's output folder is made when missing, and a path under a regular file is
    // refused before the scene is made (it failed after the work, or on the folder).
    let file = d.path().join("plain");
    std::fs::write(&file, b"x").unwrap();
    for (scene, name, extra) in [
        ("phantom", "p.nrrd", vec!["--n", "8"]),
        ("bundles", "b.tck", vec!["--n", "10", "--points", "8"]),
        ("double-gyre", "g.nii", vec!["--n", "5", "--frames", "2"]),
    ] {
        let made = d.path().join("new").join(scene).join(name);
        let mut args = vec!["synth", scene, "-o", s(&made)];
        args.extend(&extra);
        succeeds(&args);
        assert!(made.is_file(), "{scene}");
        let under = file.join(name);
        let mut args = vec!["synth", scene, "-o", s(&under)];
        args.extend(&extra);
        refused(&args, "cannot write the output here");
    }
}

/// Options that would be ignored are refused: `--tolerance` without `--distance sweeping`,
/// `--octants-out` or `--subsurface` with `--sdf-only`, `--threshold` without `--mask` (each
/// accepted and ignored before); a mask that is not scalar is named.
#[test]
fn options_that_do_not_apply_are_refused() {
    let d = tempfile::tempdir().unwrap();
    let vol = fixture("spacings_ascii.nrrd");
    let o = d.path().join("d.nrrd");
    let sweep = |extra: &[&str], needle: &str| {
        let mut args = vec!["sweep", s(&vol), "--iso", "50", "-o", s(&o)];
        args.extend_from_slice(extra);
        refused(&args, needle);
        assert!(!o.exists(), "{extra:?}");
    };
    sweep(
        &["--tolerance", "0.1"],
        "--tolerance is the convergence of --distance sweeping",
    );
    let oct = d.path().join("o.nrrd");
    sweep(
        &["--sdf-only", "--octants-out", s(&oct)],
        "cannot be used with",
    );
    sweep(
        &["--sdf-only", "--subsurface", "0.5"],
        "cannot be used with",
    );
    succeeds(&[
        "sweep",
        s(&vol),
        "--iso",
        "50",
        "-o",
        s(&o),
        "--distance",
        "sweeping",
        "--tolerance",
        "0.1",
        "--sdf-only",
    ]);
    let field = fixture("ras_vec_raw.nrrd");
    let trk = d.path().join("t.trk");
    refused(
        &["trace", s(&field), "-o", s(&trk), "--threshold", "0.3"],
        "--mask",
    );
    refused(
        &["trace", s(&field), "-o", s(&trk), "--mask", s(&field)],
        "ras_vec_raw.nrrd: the mask must be a scalar volume",
    );
    assert!(!trk.exists());
    // iso: octants without the distance they belong to, a subsurface for sweeps read from a
    // file, a Monte Carlo reference without occlusion - each was ignored in silence.
    let png = d.path().join("i.png");
    let iso = |extra: &[&str], needle: &str| {
        let mut args = vec!["iso", s(&vol), "--iso", "50", "-o", s(&png)];
        args.extend_from_slice(extra);
        refused(&args, needle);
        assert!(!png.exists(), "{extra:?}");
    };
    iso(&["--octants", s(&oct)], "--fields");
    iso(
        &["--fields", s(&o), "--subsurface", "0.5"],
        "cannot be used with",
    );
    iso(&["--local", "--reference-ao", "4"], "cannot be used with");
    // A negative value written as its own word is the value, refused by its range (exit 1).
    iso(&["--gamma", "-1"], "--gamma -1: must be a positive number");
}

/// The bench commands check their options and scenes before anything is written: a refused
/// run leaves no output folder (stability wrote its scenes, accuracy its reference folder,
/// curves and ao empty folders, lineao its data, before the error).
#[test]
fn refused_bench_runs_leave_no_folder() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let scene = test_support::headsq_scene(d, "", "bone", "width = 32\nheight = 32\n");
    let sc = s(&scene);
    let out = |n: &str| d.join(n).to_str().unwrap().to_string();
    let (st, acc, cv, cv2, lq) = (out("st"), out("acc"), out("cv"), out("cv2"), out("lq"));
    refused(
        &["bench", "stability", "-o", &st, "--reference-spp", "0"],
        "at least 1",
    );
    refused(
        &["bench", "accuracy", sc, "--sweep", "nokey=1,2", "-o", &acc],
        "nokey",
    );
    // A key swept twice (under its two names) or a value given twice: refused (the rows
    // named values the renders did not use).
    refused(
        &[
            "bench", "accuracy", sc, "--sweep", "cone=30", "--sweep", "theta=40", "-o", &acc,
        ],
        "the same key",
    );
    refused(
        &[
            "bench",
            "accuracy",
            sc,
            "--sweep",
            "slices=32,32",
            "-o",
            &acc,
        ],
        "given twice",
    );
    // A slice count out of range is refused (it was left out with a note, exit 0).
    refused(
        &[
            "bench", "curves", sc, "-o", &cv, "--sizes", "32", "--frames", "1", "--slices", "0",
        ],
        "--slices: 0",
    );
    refused(
        &[
            "bench", "curves", sc, "-o", &cv, "--sizes", "0", "--frames", "1",
        ],
        "render.width",
    );
    refused(
        &[
            "bench",
            "curves",
            sc,
            "-o",
            &cv2,
            "--methods",
            "bogus",
            "--frames",
            "1",
        ],
        "bogus",
    );
    refused(
        &[
            "bench",
            "lineao",
            "-o",
            &lq,
            "--quick",
            "--set",
            "render.lineao.samples=0",
        ],
        "render.lineao.samples",
    );
    for o in [&st, &acc, &cv, &cv2, &lq] {
        assert!(!Path::new(o).exists(), "{o} was created");
    }
}

/// Line sets that come out with nothing to draw say why: streamlines of a single point (left
/// out silently before, a blank image with exit 0), a selection that kept none (the error did
/// not name it), a filter no point passes.
#[test]
fn line_sets_with_nothing_to_draw_say_why() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let mut one = tubes::Streamlines::new();
    for k in 0..4 {
        one.push(&[glam::Vec3::new(k as f32, 0.0, 0.0)]);
    }
    tubes::save(&d.join("one.tck"), &one).unwrap();
    let mut two = tubes::Streamlines::new();
    two.push(&[glam::Vec3::ZERO, glam::Vec3::X]);
    two.push(&[glam::Vec3::Y]);
    tubes::save(&d.join("two.tck"), &two).unwrap();
    let scene = |name: &str, tck: &str| {
        let p = d.join(name);
        std::fs::write(
            &p,
            format!("[[lines]]\npath = \"{tck}\"\n[render]\nmethod = \"illuminated\"\nwidth = 32\nheight = 32\n"),
        )
        .unwrap();
        p
    };
    let png = d.join("o.png");
    let one_s = scene("one.toml", "one.tck");
    let e = refused(&["render", s(&one_s), "-o", s(&png)], "with geometry");
    assert!(e.contains("4 of 4 streamlines have a single point"), "{e}");
    assert!(!png.exists());
    let two_s = scene("two.toml", "two.tck");
    let e = refused(
        &[
            "render",
            s(&two_s),
            "-o",
            s(&png),
            "--set",
            "lines.0.select={min_length=1000}",
        ],
        "with geometry",
    );
    assert!(
        e.contains("lines[0]: select kept 0 of 2 streamlines"),
        "{e}"
    );
    // A mixed set draws its lines and notes the single point.
    let out = umbra()
        .args(["render", s(&two_s), "-o", s(&png)])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(
        err.contains("1 of 2 streamlines have a single point"),
        "{err}"
    );
    // A setting the image does not use is drawn without it, and said so.
    let noted = |set: &str, note: &str| {
        let out = umbra()
            .args(["render", s(&two_s), "-o", s(&png), "--set", set])
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{set}: {err}");
        assert!(err.contains(note), "{set}: {err}");
    };
    // Stereo settings on an image that is not stereo (they were ignored silently).
    noted("render.eye_separation=5", "apply to stereo images only");
    // `camera.up` without `eye`: the orbit turns about +z (a y-up user's image was the
    // default one, silently); a zero `up` is refused.
    noted("camera.up=[0, 1, 0]", "applies to a look-at camera");
    refused(
        &[
            "render",
            s(&two_s),
            "-o",
            s(&png),
            "--set",
            "camera.up=[0, 0, 0]",
        ],
        "camera.up",
    );
}

/// An output that names the command's input is refused before anything is written (`umbra
/// tubes IN --stats-json IN` replaced the tractogram by its statistics).
#[test]
fn outputs_never_overwrite_the_input() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let mut sl = tubes::Streamlines::new();
    sl.push(&[
        glam::Vec3::ZERO,
        glam::Vec3::X,
        glam::Vec3::new(2.0, 1.0, 0.0),
    ]);
    let tck = d.join("in.tck");
    tubes::save(&tck, &sl).unwrap();
    let before = std::fs::read(&tck).unwrap();
    let ply = d.join("o.ply");
    let same = d.join(".").join("in.tck");
    refused(
        &["tubes", s(&tck), "-o", s(&ply), "--stats-json", s(&same)],
        "the same file as the input",
    );
    refused(
        &["tracts", "select", s(&tck), "-o", s(&same)],
        "the same file as the input",
    );
    assert_eq!(std::fs::read(&tck).unwrap(), before);
    assert!(!ply.exists());
    // A render's record or timings never replace its scene, even while failing.
    let scene = d.join("s.toml");
    std::fs::write(&scene, format!("[[lines]]\npath = \"{}\"\n", s(&tck))).unwrap();
    let text = std::fs::read(&scene).unwrap();
    for flag in ["--record", "--timings-json"] {
        refused(
            &[
                "render",
                s(&scene),
                "-o",
                s(&d.join("x.png")),
                flag,
                s(&scene),
            ],
            "the same file as the input",
        );
        assert_eq!(std::fs::read(&scene).unwrap(), text, "{flag}");
    }
    // Nor a file the scene's data were read from, under any name (`--timings-json` once
    // replaced a scene's volume): refused once the data are read, before any frame.
    let vol = d.join("v.nrrd");
    std::fs::copy(fixture("spacings_ascii.nrrd"), &vol).unwrap();
    let vbytes = std::fs::read(&vol).unwrap();
    let vscene = d.join("v.toml");
    std::fs::write(
        &vscene,
        "[volume]\npath = \"v.nrrd\"\n[render]\nwidth = 16\nheight = 16\nmethod = \"ea\"\ndevice = \"cpu\"\n",
    )
    .unwrap();
    let png = d.join("v.png");
    for (flag, target) in [
        ("--timings-json", d.join("sub").join("..").join("v.nrrd")),
        ("--record", d.join("v.nrrd")),
    ] {
        refused(
            &["render", s(&vscene), "-o", s(&png), flag, s(&target)],
            "the same file as the input",
        );
        assert_eq!(
            std::fs::read(&vol).unwrap(),
            vbytes,
            "{flag} {}",
            target.display()
        );
        assert!(!png.exists(), "no frame drawn");
    }
    // A symbolic link to the volume as the output: the write replaces the link, not the
    // volume, so it is no clash.
    #[cfg(unix)]
    {
        let alias = d.join("alias.json");
        std::os::unix::fs::symlink(&vol, &alias).unwrap();
        succeeds(&[
            "render",
            s(&vscene),
            "-o",
            s(&png),
            "--timings-json",
            s(&alias),
        ]);
        assert_eq!(std::fs::read(&vol).unwrap(), vbytes);
        assert!(!std::fs::symlink_metadata(&alias)
            .unwrap()
            .file_type()
            .is_symlink());
        std::fs::remove_file(&png).unwrap();
    }
    // A tractogram's colour volume is an input of `umbra tubes` too.
    refused(
        &[
            "tubes",
            s(&tck),
            "-o",
            s(&ply),
            "--color",
            &format!("volume:{}", s(&vol)),
            "--stats-json",
            s(&vol),
        ],
        "the same file as the input",
    );
    assert_eq!(std::fs::read(&vol).unwrap(), vbytes);
}

/// A command interrupted by SIGINT or SIGTERM removes the temporary file it is writing and
/// ends as the signal would (a 243 MB `.b.tck.PID.tmp` was left by `umbra synth bundles`).
#[cfg(unix)]
#[test]
fn an_interrupted_command_leaves_no_temporary_file() {
    use std::os::unix::process::ExitStatusExt;
    let dir = tempfile::tempdir().unwrap();
    let mut checked = 0;
    for (sig, code) in [("-INT", 2), ("-TERM", 15)] {
        let out = dir.path().join("b.tck");
        let mut child = umbra()
            .args(["synth", "bundles", "--n", "1000000", "-o", s(&out)])
            .stderr(std::process::Stdio::null())
            .spawn()
            .unwrap();
        // Wait for the temporary file with data in it (the output's check creates and removes
        // an empty probe of the same name first), then interrupt.
        let t0 = std::time::Instant::now();
        let temp = loop {
            let t = std::fs::read_dir(dir.path())
                .unwrap()
                .map(|e| e.unwrap().path())
                .find(|p| {
                    p.to_string_lossy().ends_with(".tmp")
                        && std::fs::metadata(p).is_ok_and(|m| m.len() > 0)
                });
            if let Some(t) = t {
                break t;
            }
            assert!(t0.elapsed().as_secs() < 30, "no temporary file appeared");
            std::thread::sleep(std::time::Duration::from_millis(5));
        };
        let killed = Command::new("kill")
            .args([sig, &child.id().to_string()])
            .status()
            .unwrap();
        assert!(killed.success());
        let status = child.wait().unwrap();
        if status.code() == Some(0) {
            // Finished before the signal arrived: nothing to check this time.
            continue;
        }
        assert_eq!(status.signal(), Some(code), "{sig}: {status:?}");
        assert!(!temp.exists(), "{sig}: {} left", temp.display());
        assert!(!out.exists(), "{sig}");
        checked += 1;
    }
    assert!(checked > 0, "every run finished before its signal");
}

/// A single image's error names no frame (it read "frame 0:").
#[test]
fn a_single_images_error_names_no_frame() {
    let dir = tempfile::tempdir().unwrap();
    let scene = volume_scene(
        dir.path(),
        &fixture("spacings_ascii.nrrd"),
        "[render]\nwidth = 16\nheight = 16\n",
    );
    let png = dir.path().join("o.png");
    let e = refused(
        &[
            "render",
            s(&scene),
            "-o",
            s(&png),
            "--set",
            "render.slice_distance=1e-6",
        ],
        "render.slice_distance",
    );
    assert!(!e.contains("frame 0"), "{e}");
}

/// `umbra tubes` says what the statistics alone hid: no tube at all, a fit that does not honour
/// the tolerance, coordinates too large for the radius to resolve; `--chordal` decides the
/// sides, so `--sides` beside it is refused.
#[test]
fn tubes_warn_where_the_mesh_is_not_what_was_asked() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let ply = d.join("o.ply");
    let run = |tck: &Path, extra: &[&str]| {
        let mut args = vec!["tubes", s(tck), "-o", s(&ply)];
        args.extend_from_slice(extra);
        let out = umbra().args(&args).output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr).into_owned();
        assert!(out.status.success(), "{args:?}: {err}");
        err
    };
    let empty = d.join("empty.tck");
    tubes::save(&empty, &tubes::Streamlines::new()).unwrap();
    assert!(run(&empty, &[]).contains("no tube was made"));
    let mut wavy = tubes::Streamlines::new();
    let pts: Vec<glam::Vec3> = (0..40)
        .map(|i| glam::Vec3::new(i as f32 * 0.5, (i as f32 * 0.9).sin(), 0.0))
        .collect();
    wavy.push(&pts);
    let w = d.join("wavy.tck");
    tubes::save(&w, &wavy).unwrap();
    assert!(run(&w, &["--fit", "none", "--tolerance", "0.01"]).contains("exceeds the tolerance"));
    assert!(!run(&w, &["--tolerance", "0.01"]).contains("exceeds the tolerance"));
    let mut huge = tubes::Streamlines::new();
    huge.push(&pts.iter().map(|p| *p * 1e30).collect::<Vec<_>>());
    let h = d.join("huge.tck");
    tubes::save(&h, &huge).unwrap();
    assert!(run(&h, &[]).contains("flattened"));
    refused(
        &[
            "tubes",
            s(&w),
            "-o",
            s(&ply),
            "--chordal",
            "0.01",
            "--sides",
            "4",
        ],
        "cannot be used with",
    );
}
