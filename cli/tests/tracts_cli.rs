//! `umbra tracts select` end to end: ROI selection of a real tractogram against a brute-force
//! selection written here from the rule in the README, attributes carried through, a label
//! mask, the scene key `select` keeping what the command keeps, and clear refusals.

use glam::{DMat4, DVec3, Vec3};
use std::path::{Path, PathBuf};
use std::process::Command;

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .unwrap()
        .to_path_buf()
}

fn umbra() -> Command {
    Command::new(env!("CARGO_BIN_EXE_umbra"))
}

use test_support::succeeded as ok;

fn cst() -> PathBuf {
    root().join("datasets/tracts/CST_L_demo.trk.gz")
}

fn in_sphere(p: Vec3, c: [f64; 4]) -> bool {
    let d = p.as_dvec3() - DVec3::new(c[0], c[1], c[2]);
    d.length() <= c[3]
}

fn in_box(p: Vec3, b: [f64; 6]) -> bool {
    let p = p.as_dvec3().to_array();
    (0..3).all(|k| p[k] >= b[k].min(b[k + 3]) && p[k] <= b[k].max(b[k + 3]))
}

fn length(line: &[Vec3]) -> f64 {
    line.windows(2)
        .map(|w| (w[1].as_dvec3() - w[0].as_dvec3()).length())
        .sum()
}

#[test]
fn rois_select_what_a_brute_force_selection_selects_on_a_real_tractogram() {
    let dir = tempfile::tempdir().unwrap();
    let s = tubes::load(&cst()).unwrap();
    let [lo, hi] = s.bounds().unwrap();
    let c = (lo + hi) * 0.5;
    // A sphere at the bundle's middle, a box over its most lateral quarter, a length floor.
    let sphere = [c.x as f64, c.y as f64, c.z as f64, 10.0];
    let bx = [
        lo.x as f64 - 1.0,
        lo.y as f64 - 1.0,
        lo.z as f64 - 1.0,
        (lo.x + (hi.x - lo.x) * 0.25) as f64,
        hi.y as f64 + 1.0,
        hi.z as f64 + 1.0,
    ];
    // The 30th percentile of the lengths.
    let mut lens: Vec<f64> = (0..s.len()).map(|i| length(s.line(i))).collect();
    lens.sort_by(f64::total_cmp);
    let min_len = lens[lens.len() * 3 / 10];
    let want: Vec<usize> = (0..s.len())
        .filter(|&i| {
            let l = s.line(i);
            l.iter().any(|&p| in_sphere(p, sphere))
                && !l.iter().any(|&p| in_box(p, bx))
                && length(l) >= min_len
        })
        .collect();
    // Each test drops streamlines of its own: a selection that can fail.
    let lines = || (0..s.len()).map(|i| s.line(i));
    assert!(lines().any(|l| !l.iter().any(|&p| in_sphere(p, sphere))));
    assert!(lines().any(|l| l.iter().any(|&p| in_box(p, bx))));
    assert!(lines().any(|l| length(l) < min_len));
    assert!(
        want.len() >= 5 && want.len() < s.len(),
        "{} of {}",
        want.len(),
        s.len()
    );
    let out = dir.path().join("sel.tck");
    let j = |v: &[f64]| {
        v.iter()
            .map(|x| x.to_string())
            .collect::<Vec<_>>()
            .join(",")
    };
    let o = umbra()
        .args(["tracts", "select"])
        .arg(cst())
        .arg("-o")
        .arg(&out)
        .arg(format!("--include-sphere={}", j(&sphere)))
        .arg(format!("--exclude-box={}", j(&bx)))
        .args(["--min-length", &min_len.to_string(), "--json"])
        .output()
        .unwrap();
    let err = ok(&o);
    assert!(
        err.contains(&format!("kept {} of {} streamlines", want.len(), s.len())),
        "{err}"
    );
    let sum: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(sum["kept"], want.len());
    let got = tubes::load(&out).unwrap();
    assert_eq!(got.len(), want.len());
    for (k, &i) in want.iter().enumerate() {
        let (a, b) = (got.line(k), s.line(i));
        assert_eq!(a.len(), b.len());
        assert!(a
            .iter()
            .zip(b)
            .all(|(p, q)| (*p - *q).abs().max_element() < 1e-3));
    }
}

/// `umbra tracts select INPUT -o OUT ARGS...`, expected to succeed; its standard error.
fn select(input: &Path, out: &Path, args: &[String]) -> String {
    ok(&umbra()
        .args(["tracts", "select"])
        .arg(input)
        .arg("-o")
        .arg(out)
        .args(args)
        .output()
        .unwrap())
}

/// A tractogram of 40 straight lines along x at y = k, with a per-point and a per-line
/// attribute, in a .trk.
fn ladder(dir: &Path) -> PathBuf {
    let mut s = tubes::Streamlines::new();
    let (mut pv, mut lv) = (vec![], vec![]);
    for k in 0..40 {
        let pts: Vec<Vec3> = (0..11)
            .map(|x| Vec3::new(x as f32, k as f32, 0.0))
            .collect();
        pv.extend(pts.iter().map(|p| p.x * 0.1));
        s.push(&pts);
        lv.push(k as f32);
    }
    s.point_attributes.push(tubes::Attribute {
        name: "fa".into(),
        components: 1,
        values: pv,
    });
    s.line_attributes.push(tubes::Attribute {
        name: "rank".into(),
        components: 1,
        values: lv,
    });
    let p = dir.join("ladder.trk");
    tubes::save(&p, &s).unwrap();
    p
}

#[test]
fn attributes_masks_and_subsamples_select_and_travel_with_the_streamlines() {
    let dir = tempfile::tempdir().unwrap();
    let input = ladder(dir.path());
    let out = dir.path().join("a.trk");
    ok(&umbra()
        .args(["tracts", "select"])
        .arg(&input)
        .arg("-o")
        .arg(&out)
        .args(["--attribute", "rank", "--min", "10", "--max", "19.5"])
        .output()
        .unwrap());
    let got = tubes::load(&out).unwrap();
    assert_eq!(got.len(), 10);
    let rank = &got
        .line_attributes
        .iter()
        .find(|a| a.name == "rank")
        .unwrap()
        .values;
    assert_eq!(rank, &(10..20).map(|k| k as f32).collect::<Vec<_>>());
    let fa = &got
        .point_attributes
        .iter()
        .find(|a| a.name == "fa")
        .unwrap()
        .values;
    assert_eq!(fa.len(), got.points.len());
    assert!((fa[3] - 0.3).abs() < 1e-6);
    assert_eq!(got.line(0)[0].y, 10.0);
    // A label mask: a 1 mm grid where label 7 covers y in [4.5, 7.5) at x = 5 only.
    let mut data = vec![0.0f32; 12 * 42 * 3];
    for y in 5..=7 {
        data[5 + 12 * (y + 42)] = 7.0;
    }
    data[2 + 12 * (30 + 42)] = 2.0;
    let v = volume::Volume::new(
        [12, 42, 3],
        DMat4::from_translation(DVec3::new(0.0, 0.0, -1.0)),
        volume::Space::Ras,
        volume::Field {
            name: "labels".into(),
            components: 1,
            stored: volume::ScalarType::F32,
            data,
        },
    )
    .unwrap();
    let mask = dir.path().join("atlas.nii");
    volume::nifti::write(&mask, &v, &v.select(None).unwrap()).unwrap();
    let out = dir.path().join("m.tck");
    let err = select(
        &input,
        &out,
        &[format!("--include-mask={}:7", mask.display())],
    );
    let got = tubes::load(&out).unwrap();
    let ys: Vec<f32> = (0..got.len()).map(|i| got.line(i)[0].y).collect();
    assert_eq!(ys, [5.0, 6.0, 7.0], "{err}");
    // A .tck drops the attributes, and a note names them.
    assert!(
        err.contains(".tck holds positions only") && err.contains("the attributes"),
        "{err}"
    );
    // Any nonzero voxel, and excluding label 7: line 30 alone is kept.
    let err = select(
        &input,
        &out,
        &[
            format!("--include-mask={}", mask.display()),
            format!("--exclude-mask={}:7", mask.display()),
        ],
    );
    assert!(err.contains("kept 1 of 40"), "{err}");
    // --transform moves the points before the selection (an atlas bundle into the mask's
    // space): shifted by +1 in y, lines 4, 5 and 6 lie in label 7, written where they moved.
    let shift = |dy: f64| format!("--transform=1,0,0,0,0,1,0,{dy},0,0,1,0,0,0,0,1");
    let err = select(
        &input,
        &out,
        &[format!("--include-mask={}:7", mask.display()), shift(1.0)],
    );
    let got = tubes::load(&out).unwrap();
    let ys: Vec<f32> = (0..got.len()).map(|i| got.line(i)[0].y).collect();
    assert_eq!(ys, [5.0, 6.0, 7.0], "{err}");
    // Moved off the mask: nothing kept, and the warning says where the points are.
    let err = select(
        &input,
        &out,
        &[format!("--include-mask={}:7", mask.display()), shift(100.0)],
    );
    assert!(
        err.contains("kept no streamline (its points span (0.0, 100.0, 0.0) to (10.0, 139.0, 0.0) after --transform"),
        "{err}"
    );
    // A subsample: 7 of the 40, the same for the same seed.
    let sub = |seed: &str, name: &str| {
        let p = dir.path().join(name);
        ok(&umbra()
            .args(["tracts", "select"])
            .arg(&input)
            .arg("-o")
            .arg(&p)
            .args(["--subsample", "7", "--seed", seed])
            .output()
            .unwrap());
        let s = tubes::load(&p).unwrap();
        (0..s.len()).map(|i| s.line(i)[0].y).collect::<Vec<f32>>()
    };
    let (a, b, c) = (sub("1", "s1.trk"), sub("1", "s1b.trk"), sub("2", "s2.trk"));
    assert_eq!(a.len(), 7);
    assert_eq!(a, b);
    assert_ne!(a, c);
}

#[test]
fn bad_selections_are_refused_naming_the_flag_or_key() {
    let dir = tempfile::tempdir().unwrap();
    let input = ladder(dir.path());
    let run = |args: &[&str]| {
        let o = umbra()
            .args(["tracts", "select"])
            .arg(&input)
            .arg("-o")
            .arg(dir.path().join("x.trk"))
            .args(args)
            .output()
            .unwrap();
        assert_eq!(o.status.code(), Some(1), "{args:?}");
        String::from_utf8_lossy(&o.stderr).into_owned()
    };
    assert!(run(&["--include-sphere=1,2,3"]).contains("expected 4 comma-separated numbers"));
    assert!(run(&["--include-sphere=0,0,0,-1"]).contains("--include-sphere"));
    assert!(run(&["--include-box=0,0,0,1,nan,1"]).contains("finite"));
    assert!(run(&["--min-length", "5", "--max-length", "2"]).contains("above max_length"));
    assert!(run(&["--attribute", "nope", "--min", "1"]).contains("the tractogram has fa, rank"));
    assert!(run(&["--include-mask", "/no/such.nii:3"]).contains("--include-mask: /no/such.nii"));
    assert!(!dir.path().join("x.trk").exists());
    // In a scene: the key is named.
    let scene = dir.path().join("s.toml");
    std::fs::write(
        &scene,
        format!(
            "[[lines]]\npath = \"{}\"\nselect = {{ include_spheres = [[0.0, 0.0, 0.0, -2.0]] }}\n",
            input.display()
        ),
    )
    .unwrap();
    let o = umbra().arg("scene").arg(&scene).output().unwrap();
    assert_eq!(o.status.code(), Some(1));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("lines[0].select.include_spheres"), "{err}");
    std::fs::write(
        &scene,
        format!(
            "[[lines]]\npath = \"{}\"\nselect = {{ include_sphere = [[0.0, 0.0, 0.0, 2.0]] }}\n",
            input.display()
        ),
    )
    .unwrap();
    let err = String::from_utf8_lossy(&umbra().arg("scene").arg(&scene).output().unwrap().stderr)
        .into_owned();
    assert!(
        err.contains("include_sphere") && err.contains("unknown field"),
        "{err}"
    );
}

#[test]
fn a_scene_select_keeps_what_the_command_keeps() {
    let dir = tempfile::tempdir().unwrap();
    let input = ladder(dir.path());
    let scene = dir.path().join("s.toml");
    let write = |path: &str, select: &str| {
        std::fs::write(
            &scene,
            format!(
                "background = [1.0, 1.0, 1.0]\n[camera]\nazimuth = 0.0\nelevation = 90.0\n\
                 [[lines]]\npath = \"{path}\"\ncolor = \"#000000\"\nwidth = 2.0\n{select}\
                 [render]\nmethod = \"illuminated\"\nwidth = 96\nheight = 96\nmsaa = 1\nfxaa = false\n"
            ),
        )
        .unwrap();
    };
    let render = |name: &str| -> (String, Vec<u8>) {
        let png = dir.path().join(name);
        let o = umbra()
            .arg("render")
            .arg(&scene)
            .arg("-o")
            .arg(&png)
            .output()
            .unwrap();
        let err = ok(&o);
        (err, image::open(&png).unwrap().to_luma8().into_raw())
    };
    // Lines 10..=19 by a box in the scene's world (the path relative to the scene).
    write(
        "ladder.trk",
        "select = { include_boxes = [[-1.0, 9.5, -1.0, 11.0, 19.5, 1.0]] }\n",
    );
    let (err, in_scene) = render("scene.png");
    assert!(
        err.contains("lines[0]: select kept 10 of 40 streamlines"),
        "{err}"
    );
    // The same lines selected by the command, drawn without a select: the same image.
    let cut = dir.path().join("cut.trk");
    select(
        &input,
        &cut,
        &["--include-box=-1,9.5,-1,11,19.5,1".to_string()],
    );
    write("cut.trk", "");
    let (_, by_command) = render("command.png");
    assert!(by_command.iter().any(|&v| v < 128), "lines are drawn");
    assert_eq!(in_scene, by_command);
}

fn got_attrs(p: &Path) -> Vec<String> {
    let s = tubes::load(p).unwrap();
    s.point_attributes
        .iter()
        .chain(&s.line_attributes)
        .map(|a| a.name.clone())
        .collect()
}

/// `umbra tracts merge`: the inputs' streamlines in order, moved by --transform, the
/// attributes they share kept; an output over an input refused.
#[test]
fn merged_tractograms_keep_their_order_and_move_together() {
    let dir = tempfile::tempdir().unwrap();
    let a = ladder(dir.path());
    let b = dir.path().join("b.trk");
    let mut s = tubes::Streamlines::new();
    s.push(&[Vec3::new(0.0, 100.0, 0.0), Vec3::new(5.0, 100.0, 0.0)]);
    tubes::save(&b, &s).unwrap();
    let out = dir.path().join("all.trk");
    let err = ok(&umbra()
        .args(["tracts", "merge"])
        .arg(&a)
        .arg(&b)
        .arg("-o")
        .arg(&out)
        .arg("--transform=1,0,0,0,0,1,0,0,0,0,1,2,0,0,0,1")
        .output()
        .unwrap());
    assert!(
        err.contains("merged 2 tractograms: 41 streamlines"),
        "{err}"
    );
    assert!(
        err.contains("attributes not in every input were left out: fa"),
        "{err}"
    );
    assert!(got_attrs(&out).is_empty());
    let got = tubes::load(&out).unwrap();
    let first = tubes::load(&a).unwrap();
    assert_eq!(got.len(), 41);
    assert_eq!(got.line(0)[3], first.line(0)[3] + Vec3::new(0.0, 0.0, 2.0));
    assert_eq!(got.line(40)[1], Vec3::new(5.0, 100.0, 2.0));
    let o = umbra()
        .args(["tracts", "merge"])
        .arg(&a)
        .arg(&b)
        .arg("-o")
        .arg(&b)
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(1));
    assert_eq!(tubes::load(&b).unwrap().len(), 1, "the input is kept");
}
