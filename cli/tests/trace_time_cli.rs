//! `umbra trace` with time: the `time` and `speed` point attributes, pathlines through 5-D NIfTI
//! time series written by `umbra synth double-gyre` or by the volume crate, seed times, and the
//! refusals, as users call them.

use glam::{DVec3, Vec3};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use volume::synthetic::{
    cube_affine, sample_series, sample_vector, LinearRamp, UnsteadyField, VectorField,
};
use volume::VolumeSeries;

fn umbra() -> Command {
    Command::new(env!("CARGO_BIN_EXE_umbra"))
}

fn run(args: &[&str], paths: &[&Path]) -> Output {
    // Paths go first (the input), then `-o` and the output where there are two.
    let mut c = umbra();
    c.arg(args[0]);
    c.arg(paths[0]);
    if let Some(out) = paths.get(1) {
        c.arg("-o").arg(out);
    }
    c.args(&args[1..]);
    c.output().unwrap()
}

use test_support::succeeded as ok;

fn fails(o: &Output, what: &str) {
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.contains(what), "expected '{what}' in: {err}");
}

struct Steady(fn(DVec3) -> DVec3);

impl VectorField for Steady {
    fn velocity(&self, p: DVec3) -> DVec3 {
        (self.0)(p)
    }
}

impl UnsteadyField for Steady {
    fn velocity(&self, p: DVec3, _t: f64) -> DVec3 {
        (self.0)(p)
    }
}

fn attr<'a>(s: &'a tubes::Streamlines, name: &str) -> &'a [f32] {
    &s.point_attributes
        .iter()
        .find(|a| a.name == name)
        .unwrap_or_else(|| panic!("no '{name}' (have {:?})", s.point_attributes))
        .values
}

fn seeds(dir: &Path, pts: &[[f64; 3]]) -> PathBuf {
    let p = dir.join("seeds.csv");
    let text: String = pts
        .iter()
        .map(|q| format!("{},{},{}\n", q[0], q[1], q[2]))
        .collect();
    std::fs::write(&p, format!("x,y,z\n{text}")).unwrap();
    p
}

#[test]
fn a_uniform_field_records_its_speed_and_time_as_step_over_speed() {
    let dir = tempfile::tempdir().unwrap();
    let dims = [6, 6, 6];
    let v = 0.25;
    let vol = sample_vector(
        &Steady(|_| DVec3::new(0.0, 0.15, 0.2)),
        dims,
        cube_affine(dims, 0.0, 5.0),
        "v",
    );
    let field = dir.path().join("u.nii");
    volume::nifti::write(&field, &vol, &vol.fields[0]).unwrap();
    let csv = seeds(dir.path(), &[[2.0, 2.0, 2.0], [1.0, 3.0, 1.5]]);
    let out = dir.path().join("u.trk");
    let csv_s = csv.to_string_lossy().to_string();
    ok(&run(
        &[
            "trace",
            "--seeds",
            &csv_s,
            "--step",
            "0.1",
            "--seed-times",
            "4",
        ],
        &[&field, &out],
    ));
    let s = tubes::load(&out).unwrap();
    assert_eq!(s.len(), 2);
    let (time, speed) = (attr(&s, "time"), attr(&s, "speed"));
    for &x in speed {
        assert!((x as f64 - v).abs() < 1e-6, "speed {x}");
    }
    for i in 0..s.len() {
        let (a, b) = (s.offsets[i], s.offsets[i + 1]);
        assert!(b - a > 20);
        for k in a + 1..b {
            let d = (s.points[k] - s.points[k - 1]).length() as f64;
            let dt = (time[k] - time[k - 1]) as f64;
            assert!((dt - d / v).abs() < 1e-5, "dt {dt}, step {d}");
            assert!(
                (d - 0.1).abs() < 1e-5 || k == a + 1 || k == b - 1,
                "step {d}"
            );
        }
        // Both ways from the seed at time 4.
        assert!(time[a] < 4.0 && time[b - 1] > 4.0);
        assert!(time[a..b].contains(&4.0));
    }
    // .tck output drops them, and says so; the lines are the same.
    let tck = dir.path().join("u.tck");
    let err = ok(&run(
        &["trace", "--seeds", &csv_s, "--step", "0.1"],
        &[&field, &tck],
    ));
    assert!(err.contains(".tck holds positions only"), "{err}");
    let t = tubes::load(&tck).unwrap();
    assert!(t.point_attributes.is_empty());
    // (The .trk's points go through its grid's voxel coordinates in f32: within 1e-5.)
    assert_eq!(t.points.len(), s.points.len());
    assert!(t
        .points
        .iter()
        .zip(&s.points)
        .all(|(a, b)| (*a - *b).length() < 1e-5));
}

/// The rigid rotation on 21^3 samples as `umbra synth rotation` writes it (NRRD), in `dir`.
fn rotation(dir: &Path) -> PathBuf {
    let nrrd = dir.join("rot.nrrd");
    ok(&umbra()
        .args(["synth", "rotation", "--n", "21", "-o"])
        .arg(&nrrd)
        .output()
        .unwrap());
    nrrd
}

#[test]
fn pathlines_of_a_steady_field_equal_its_streamlines() {
    let dir = tempfile::tempdir().unwrap();
    // The rigid rotation (linear: trilinear interpolation is exact) as `umbra synth` writes it
    // (NRRD, steady) and as a 5-D NIfTI of three equal frames.
    let nrrd = rotation(dir.path());
    let dims = [21, 21, 21];
    let rot = Steady(|p| DVec3::new(-p.y, p.x, 0.0));
    let equal = sample_series(
        &rot,
        dims,
        cube_affine(dims, -1.0, 1.0),
        "v",
        3,
        0.0,
        1.0,
        false,
    );
    let nii = dir.path().join("rot5d.nii.gz");
    volume::nifti::write_series(&nii, &equal).unwrap();
    let csv = seeds(
        dir.path(),
        &[[0.5, 0.0, 0.0], [0.0, -0.7, 0.3], [0.2, 0.2, -0.5]],
    );
    let csv_s = csv.to_string_lossy().to_string();
    let stream = dir.path().join("s.trk");
    ok(&run(
        &[
            "trace",
            "--seeds",
            &csv_s,
            "--step",
            "0.001",
            "--max-length",
            "6",
        ],
        &[&nrrd, &stream],
    ));
    let s = tubes::load(&stream).unwrap();
    for input in [&nrrd, &nii] {
        let path = dir.path().join("p.trx");
        ok(&run(
            &[
                "trace",
                "--pathlines",
                "--seeds",
                &csv_s,
                "--time-step",
                "0.002",
                "--duration",
                "1.5",
            ],
            &[input, &path],
        ));
        let p = tubes::load(&path).unwrap();
        assert_eq!(p.len(), 3);
        let mut worst = 0.0f64;
        for i in 0..3 {
            let line: Vec<Vec3> = s.line(i).to_vec();
            for q in p.line(i) {
                let d = line
                    .windows(2)
                    .map(|w| {
                        let (a, b, q) = (w[0].as_dvec3(), w[1].as_dvec3(), q.as_dvec3());
                        let u = ((q - a).dot(b - a) / (b - a).length_squared()).clamp(0.0, 1.0);
                        (a + (b - a) * u - q).length()
                    })
                    .fold(f64::INFINITY, f64::min);
                worst = worst.max(d);
            }
            // Time from -1.5 to 1.5 about the seed at 0; speed = radius.
            let t = &attr(&p, "time")[p.offsets[i]..p.offsets[i + 1]];
            assert!((t[0] + 1.5).abs() < 1e-6 && (t[t.len() - 1] - 1.5).abs() < 1e-6);
            let v = &attr(&p, "speed")[p.offsets[i]..p.offsets[i + 1]];
            for (q, &sp) in p.line(i).iter().zip(v) {
                assert!((q.x.hypot(q.y) - sp).abs() < 1e-5);
            }
        }
        assert!(worst < 1e-5, "{}: {worst:.2e}", input.display());
    }
}

#[test]
fn pathlines_follow_a_flow_whose_speed_grows_linearly_in_time() {
    // u = (a t, 0, 0) in a clamped 5-D series at t = 0, 0.5, ..., 6:
    // x(t) = x0 + a (t^2 - t0^2) / 2 exactly (linear in space and time).
    let dir = tempfile::tempdir().unwrap();
    let a = 0.1;
    let dims = [11, 3, 3];
    let ramp = LinearRamp {
        rate: a,
        direction: DVec3::X,
    };
    let series = sample_series(
        &ramp,
        dims,
        cube_affine(dims, 0.0, 10.0),
        "v",
        13,
        0.0,
        0.5,
        false,
    );
    let nii = dir.path().join("ramp.nii");
    volume::nifti::write_series(&nii, &series).unwrap();
    let csv = seeds(dir.path(), &[[1.0, 5.0, 5.0], [2.5, 4.0, 6.0]]);
    let csv_s = csv.to_string_lossy().to_string();
    let out = dir.path().join("r.trk");
    let o = &[
        "trace",
        "--pathlines",
        "--seeds",
        &csv_s,
        "--seed-times",
        "1.0",
        "--time-step",
        "0.05",
        "--duration",
        "4",
        "--one-way",
    ];
    ok(&run(o, &[&nii, &out]));
    let s = tubes::load(&out).unwrap();
    assert_eq!(s.len(), 2);
    let t = attr(&s, "time");
    let mut worst = 0.0f64;
    for (i, x0) in [1.0, 2.5].iter().enumerate() {
        let (from, to) = (s.offsets[i], s.offsets[i + 1]);
        for (p, &tk) in s.points[from..to].iter().zip(&t[from..to]) {
            let tk = tk as f64;
            let x = x0 + a * (tk * tk - 1.0) / 2.0;
            worst = worst.max((p.x as f64 - x).abs());
        }
        assert!((t[s.offsets[i + 1] - 1] - 5.0).abs() < 1e-5);
    }
    assert!(worst < 2e-5, "largest error {worst:.2e}");
}

#[test]
fn the_double_gyre_traces_into_coloured_deterministic_pathlines() {
    let dir = tempfile::tempdir().unwrap();
    let dg = dir.path().join("dg.nii.gz");
    let err = ok(&umbra()
        .args(["synth", "double-gyre", "--n", "9", "--frames", "10", "-o"])
        .arg(&dg)
        .output()
        .unwrap());
    assert!(err.contains("17 x 9 x 9 x 10 frames"), "{err}");
    let series: VolumeSeries = volume::load_series(&dg).unwrap();
    assert_eq!((series.len(), series.dt, series.periodic), (10, 1.0, true));
    let trace = |out: &Path, rng: &str| {
        ok(&run(
            &[
                "trace",
                "--pathlines",
                "--seeds",
                "random:40",
                "--seed-times",
                "random",
                "--random-seed",
                rng,
            ],
            &[&dg, out],
        ))
    };
    let (a, b, c) = (
        dir.path().join("a.trx"),
        dir.path().join("b.trx"),
        dir.path().join("c.trx"),
    );
    trace(&a, "7");
    trace(&b, "7");
    trace(&c, "8");
    let (sa, sb, sc) = (
        tubes::load(&a).unwrap(),
        tubes::load(&b).unwrap(),
        tubes::load(&c).unwrap(),
    );
    assert_eq!(sa, sb, "the same --random-seed gives the same pathlines");
    assert_ne!(sa.points, sc.points);
    assert!(sa.len() >= 35, "{} pathlines of 40 seeds", sa.len());
    // Seed times spread over the period; each line spans up to a period either side.
    let t = attr(&sa, "time");
    let (lo, hi) = t
        .iter()
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(l, h), &x| {
            (l.min(x), h.max(x))
        });
    assert!(
        lo < 0.0 && hi > 10.0 && lo >= -10.0 && hi <= 20.0,
        "{lo}..{hi}"
    );
    for p in &sa.points {
        assert!(
            p.x > -0.01 && p.x < 2.01 && p.y > -0.01 && p.y < 1.01,
            "{p}"
        );
    }
    // `[[lines]] color = "scalar:time"` and `"scalar:speed"` read the attributes as they are.
    for colour in ["scalar:time", "scalar:speed"] {
        let set = scene::tube_sets::with_color_mode(&sa, colour, |c| {
            tubes::lines::LineSet::new(&sa, c, tubes::lines::LineWidth::Pixels(2.0), false)
        })
        .unwrap();
        assert_eq!(set.colors.len(), sa.points.len());
        let first = set.colors[0];
        assert!(
            set.colors.iter().any(|&c| c != first),
            "{colour}: one colour"
        );
    }
}

#[test]
fn time_options_that_do_not_apply_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let dg = dir.path().join("dg.nii");
    ok(&umbra()
        .args(["synth", "double-gyre", "--n", "5", "--frames", "4", "-o"])
        .arg(&dg)
        .output()
        .unwrap());
    let rot = dir.path().join("rot.nrrd");
    ok(&umbra()
        .args(["synth", "rotation", "--n", "5", "-o"])
        .arg(&rot)
        .output()
        .unwrap());
    let out = dir.path().join("x.trk");
    fails(&run(&["trace"], &[&dg, &out]), "--pathlines");
    ok(&run(
        &["trace", "--frame", "2", "--seeds", "grid:2"],
        &[&dg, &out],
    ));
    fails(&run(&["trace", "--frame", "4"], &[&dg, &out]), "4 frame");
    for (args, what) in [
        (
            &["trace", "--pathlines", "--integrator", "rk45"][..],
            "rk4 or euler",
        ),
        (
            &["trace", "--pathlines", "--step", "0.1"][..],
            "--time-step",
        ),
        (&["trace", "--pathlines", "--eigen"][..], "--eigen"),
        (&["trace", "--pathlines", "--frame", "1"][..], "--frame"),
        (
            &["trace", "--pathlines", "--seed-times", "random:3:1"][..],
            "T1",
        ),
        (
            &["trace", "--pathlines", "--seed-times", "soon"][..],
            "--seed-times",
        ),
        (
            &["trace", "--pathlines", "--time-step", "0"][..],
            "positive",
        ),
    ] {
        fails(&run(args, &[&dg, &out]), what);
    }
    // A pathline option without --pathlines conflicts: status 2, as the parser's conflicts.
    let o = run(&["trace", "--time-step", "0.1"], &[&dg, &out]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("--pathlines"), "{err}");
    // A steady field has no time span to draw random seed times from.
    fails(
        &run(&["trace", "--seed-times", "random"], &[&rot, &out]),
        "random:T0:T1",
    );
    ok(&run(
        &["trace", "--seed-times", "random:0:5", "--seeds", "grid:2"],
        &[&rot, &out],
    ));
    // synth: the series needs NIfTI; steady scenes take no --frames.
    let o = umbra()
        .args(["synth", "double-gyre", "--n", "5", "-o"])
        .arg(dir.path().join("dg.nrrd"))
        .output()
        .unwrap();
    fails(&o, ".nii");
    let o = umbra()
        .args(["synth", "rotation", "--frames", "3", "-o"])
        .arg(dir.path().join("r.nrrd"))
        .output()
        .unwrap();
    fails(&o, "--frames");
}

/// A time series drawn as a volume is its first frame, and the render says so (as `umbra
/// info` does).
#[test]
fn a_time_series_rendered_as_a_volume_notes_that_it_is_frame_0() {
    let dir = tempfile::tempdir().unwrap();
    let nii = dir.path().join("dg.nii");
    let o = umbra()
        .args(["synth", "double-gyre", "--n", "5", "--frames", "3", "-o"])
        .arg(&nii)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let scene = dir.path().join("s.toml");
    std::fs::write(
        &scene,
        "[volume]\npath = \"dg.nii\"\nfield = \"data:magnitude\"\n\
         [render]\ndevice = \"cpu\"\nmethod = \"ea\"\nwidth = 24\nheight = 16\n",
    )
    .unwrap();
    let o = umbra()
        .arg("render")
        .arg(&scene)
        .arg("-o")
        .arg(dir.path().join("s.png"))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(
        err.contains("dg.nii: a time series of 3 vector fields") && err.contains("frame 0 only"),
        "{err}"
    );
}

/// A `.trk` records the field's grid (dimensions, voxel sizes, affine, voxel order; f32 in the
/// header) as its reference space, with the points in the same world coordinates as a
/// `.tck`'s (the header was a 1 x 1 x 1 grid of 1 mm voxels, which tools that place lines by
/// it read as outside).
#[test]
fn a_trk_header_records_the_fields_grid() {
    let dir = tempfile::tempdir().unwrap();
    let nrrd = rotation(dir.path());
    let field = volume::load(&nrrd).unwrap();
    let (trk, tck) = (dir.path().join("r.trk"), dir.path().join("r.tck"));
    for out in [&trk, &tck] {
        ok(&run(&["trace", "--seeds", "grid:3"], &[&nrrd, out]));
    }
    let t = tubes::load(&trk).unwrap();
    let r = t.reference.as_ref().expect("a reference space");
    assert_eq!(r.dims, field.dims);
    let h = field.spacing();
    for (got, want) in r.voxel_sizes.iter().zip(h) {
        assert!((got - want).abs() < 1e-6, "{:?}", r.voxel_sizes);
    }
    assert!(
        r.vox_to_ras.abs_diff_eq(field.affine, 1e-6),
        "{}",
        r.vox_to_ras
    );
    assert_eq!(&r.voxel_order, b"RAS");
    let c = tubes::load(&tck).unwrap();
    assert_eq!(t.points.len(), c.points.len());
    let worst = t
        .points
        .iter()
        .zip(&c.points)
        .map(|(a, b)| (*a - *b).length())
        .fold(0.0f32, f32::max);
    assert!(worst < 1e-5, "points moved by {worst}");
}
