//! `umbra synth`, `umbra sweep` and `umbra iso` as users call them, including the stability
//! cases of the sweeping issue: iso outside the range, NaN voxels, a one-voxel-thick volume,
//! surfaces touching the border, anisotropic spacing, `--inside below`.

use std::path::{Path, PathBuf};
use std::process::Command;

fn umbra() -> Command {
    Command::new(env!("CARGO_BIN_EXE_umbra"))
}

fn ok(c: &mut Command) -> String {
    let out = c.output().unwrap();
    test_support::succeeded(&out);
    String::from_utf8_lossy(&out.stdout).to_string()
}

fn synth(dir: &Path, n: usize) -> PathBuf {
    let p = dir.join("val.nrrd");
    ok(umbra()
        .args(["synth", "validation", "-o"])
        .arg(&p)
        .args(["--n", &n.to_string()]));
    p
}

#[test]
fn sweep_writes_distance_and_octants_with_a_json_summary() {
    let dir = tempfile::tempdir().unwrap();
    let input = synth(dir.path(), 40);
    let d = dir.path().join("val.sdf.nrrd");
    let out = ok(umbra()
        .arg("sweep")
        .arg(&input)
        .args(["--iso", "0", "--json", "-o"])
        .arg(&d));
    let j: serde_json::Value = serde_json::from_str(out.trim()).unwrap();
    assert_eq!(j["dims"], serde_json::json!([40, 40, 40]));
    // Closest points by default: no rounds of sweeps.
    assert_eq!(j["distance_method"], "closest-point");
    assert_eq!(j["iterations"].as_u64(), Some(0));
    assert_eq!(j["converged"], true);
    for k in ["read", "compute", "write", "total"] {
        assert!(j["seconds"][k].as_f64().unwrap() >= 0.0, "{k}");
    }
    assert!(j["peak_bytes"].as_u64().unwrap() > 0);
    let octs = dir.path().join("val.sdf.octants.nrrd");
    assert_eq!(PathBuf::from(j["octants"].as_str().unwrap()), octs);
    // Headers as specified.
    let header = |p: &Path| {
        let b = std::fs::read(p).unwrap();
        let end = b.windows(2).position(|w| w == b"\n\n").unwrap();
        String::from_utf8_lossy(&b[..end]).to_string()
    };
    let hd = header(&d);
    assert!(
        hd.contains("type: float") && hd.contains("dimension: 3") && hd.contains("sizes: 40 40 40"),
        "{hd}"
    );
    let ho = header(&octs);
    assert!(
        ho.contains("type: uint8")
            && ho.contains("sizes: 8 40 40 40")
            && ho.contains("kinds: list domain domain domain"),
        "{ho}"
    );
    // The distance keeps the input's frame and is negative inside.
    let vin = volume::load(&input).unwrap();
    let vd = volume::load(&d).unwrap();
    assert_eq!(vd.affine, vin.affine);
    for (v, dist) in vin.fields[0].data.iter().zip(&vd.fields[0].data) {
        // The sign bit: a voxel on the surface (value -1e-14 here) may be at distance 0.
        assert_eq!(
            *v >= 0.0,
            dist.is_sign_negative(),
            "value {v}, distance {dist}"
        );
    }
    let oct = scene::fields::read_octants(&octs, [40, 40, 40]).unwrap();
    assert!(oct.octants.iter().all(|o| o.len() == 64000));
    // --sdf-only writes no octants.
    let d2 = dir.path().join("only.nrrd");
    ok(umbra()
        .arg("sweep")
        .arg(&input)
        .args(["--iso", "0", "--sdf-only", "-o"])
        .arg(&d2));
    assert!(!dir.path().join("only.octants.nrrd").exists());
}

#[test]
fn iso_outside_the_range_is_a_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    let input = synth(dir.path(), 16);
    for iso in ["1e6", "-1e6"] {
        let out = umbra()
            .arg("sweep")
            .arg(&input)
            .args(["--iso", iso, "-o"])
            .arg(dir.path().join("x.nrrd"))
            .output()
            .unwrap();
        assert_eq!(out.status.code(), Some(1));
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            err.contains("outside it") && err.contains("val.nrrd"),
            "{err}"
        );
        assert!(!dir.path().join("x.nrrd").exists());
    }
    // At the end of the range where every sample is inside, the level is not called outside
    // the range (`--iso 0` on a field of 0..7 with inside at or above the level).
    let ramp = dir.path().join("ramp.nrrd");
    std::fs::write(
        &ramp,
        "NRRD0004\ntype: float\ndimension: 3\nsizes: 2 2 2\nencoding: ascii\n\n0 1 2 3 4 5 6 7\n",
    )
    .unwrap();
    for (iso, inside, want) in [
        (
            "0",
            "above",
            Some("is its minimum, and samples at or above the level are inside"),
        ),
        (
            "7",
            "below",
            Some("is its maximum, and samples at or below the level are inside"),
        ),
        ("7", "above", None),
        ("0", "below", None),
    ] {
        let out = umbra()
            .arg("sweep")
            .arg(&ramp)
            .args(["--iso", iso, "--inside", inside, "-o"])
            .arg(dir.path().join("r.nrrd"))
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        match want {
            Some(w) => {
                assert_eq!(out.status.code(), Some(1), "{iso} {inside}: {err}");
                assert!(
                    err.contains(w) && err.contains("ranges over [0, 7]"),
                    "{err}"
                );
            }
            None => assert!(out.status.success(), "{iso} {inside}: {err}"),
        }
    }
    let out = umbra()
        .arg("sweep")
        .arg(&input)
        .args(["--iso", "0", "--field", "nope", "-o"])
        .arg(dir.path().join("x.nrrd"))
        .output()
        .unwrap();
    assert!(String::from_utf8_lossy(&out.stderr).contains("no such field"));
}

fn write_volume(
    p: &Path,
    dims: [usize; 3],
    spacing: [f64; 3],
    f: impl Fn(usize, usize, usize) -> f32,
) {
    let mut data = Vec::new();
    for k in 0..dims[2] {
        for j in 0..dims[1] {
            for i in 0..dims[0] {
                data.push(f(i, j, k));
            }
        }
    }
    let affine = glam::DMat4::from_scale(glam::DVec3::from(spacing));
    let vol = volume::Volume::new(
        dims,
        affine,
        volume::Space::File,
        volume::Field {
            name: "v".into(),
            components: 1,
            stored: volume::ScalarType::F32,
            data,
        },
    )
    .unwrap();
    volume::nrrd::write(p, &vol, &vol.fields[0], volume::nrrd::WriteEncoding::Raw).unwrap();
}

#[test]
fn nan_voxels_are_outside_and_counted_in_a_warning() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("nan.nrrd");
    // A ball of radius 5 with a NaN hole at its centre and a NaN in the far corner.
    write_volume(&p, [16, 16, 16], [1.0; 3], |i, j, k| {
        if (i, j, k) == (8, 8, 8) || (i, j, k) == (0, 0, 0) {
            f32::NAN
        } else {
            5.0 - (((i as f32 - 8.0).powi(2) + (j as f32 - 8.0).powi(2) + (k as f32 - 8.0).powi(2))
                .sqrt())
        }
    });
    let d = dir.path().join("d.nrrd");
    let out = umbra()
        .arg("sweep")
        .arg(&p)
        .args(["--iso", "0", "-o"])
        .arg(&d)
        .output()
        .unwrap();
    assert!(out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("2 NaN samples were treated as outside"),
        "{err}"
    );
    let v = volume::load(&d).unwrap();
    let at = |i: usize, j: usize, k: usize| v.fields[0].data[v.index(i, j, k)];
    assert!(
        at(8, 8, 8) > 0.0,
        "the NaN centre is outside: {}",
        at(8, 8, 8)
    );
    assert!(at(8, 8, 11) < 0.0);
    assert!(v.fields[0].data.iter().all(|x| x.is_finite()));
}

#[test]
fn thin_anisotropic_and_border_touching_volumes_work() {
    let dir = tempfile::tempdir().unwrap();
    // One voxel thick: a disk of radius 4 in a 16x16x1 slice.
    let p = dir.path().join("thin.nrrd");
    write_volume(&p, [16, 16, 1], [1.0; 3], |i, j, _| {
        4.0 - ((i as f32 - 8.0).powi(2) + (j as f32 - 8.0).powi(2)).sqrt()
    });
    let d = dir.path().join("thin.sdf.nrrd");
    let j: serde_json::Value = serde_json::from_str(
        ok(umbra()
            .arg("sweep")
            .arg(&p)
            .args(["--iso", "0", "--json", "-o"])
            .arg(&d))
        .trim(),
    )
    .unwrap();
    assert_eq!(j["converged"], true);
    let v = volume::load(&d).unwrap();
    // The disk is closed above and below by the border half a voxel away.
    assert!(
        (v.fields[0].data[v.index(8, 8, 0)] + 0.5).abs() < 1e-6,
        "{}",
        v.fields[0].data[v.index(8, 8, 0)]
    );
    // In-plane, the distance to the rim of the disk is about 4 - r far from the centre.
    assert!((v.fields[0].data[v.index(15, 8, 0)] - 3.0).abs() < 0.3);
    // Anisotropic spacing (3.2, 3.2, 1.5 like headsq): a slab z < 10 mm; distance in mm.
    let a = dir.path().join("aniso.nrrd");
    write_volume(&a, [12, 12, 20], [3.2, 3.2, 1.5], |_, _, k| {
        10.0 - 1.5 * k as f32
    });
    let ad = dir.path().join("aniso.sdf.nrrd");
    ok(umbra()
        .arg("sweep")
        .arg(&a)
        .args(["--iso", "0", "-o"])
        .arg(&ad));
    let v = volume::load(&ad).unwrap();
    for k in 0..20 {
        // Inside, the nearer of the top (z = 10 mm) and the closed border below (0.75 mm under
        // the first layer); outside, the top.
        let z = 1.5 * k as f32;
        let want = if z <= 10.0 {
            -(10.0 - z).min(z + 0.75)
        } else {
            z - 10.0
        };
        let got = v.fields[0].data[v.index(6, 6, k)];
        assert!((got - want).abs() < 0.05, "k={k}: {got} vs {want}");
    }
    // --inside below flips the sign (no sample equals the level), and near the surface, where
    // the closed border is farther than the surface, the magnitude is the same.
    let b = dir.path().join("below.nrrd");
    ok(umbra()
        .arg("sweep")
        .arg(&a)
        .args(["--iso", "0.25", "--inside", "below", "--sdf-only", "-o"])
        .arg(&b));
    let c = dir.path().join("above.nrrd");
    ok(umbra()
        .arg("sweep")
        .arg(&a)
        .args(["--iso", "0.25", "--sdf-only", "-o"])
        .arg(&c));
    let (vb, vc) = (volume::load(&b).unwrap(), volume::load(&c).unwrap());
    for (x, y) in vb.fields[0].data.iter().zip(&vc.fields[0].data) {
        assert!(x.signum() == -y.signum(), "{x} vs {y}");
    }
    for k in 4..=10 {
        let id = vc.index(6, 6, k);
        assert_eq!(vb.fields[0].data[id], -vc.fields[0].data[id], "k={k}");
    }
}

#[test]
fn iso_renders_swept_and_reference_images() {
    let dir = tempfile::tempdir().unwrap();
    let input = synth(dir.path(), 32);
    let d = dir.path().join("s.nrrd");
    ok(umbra()
        .arg("sweep")
        .arg(&input)
        .args(["--iso", "0", "-o"])
        .arg(&d));
    let png = dir.path().join("a.png");
    let j: serde_json::Value = serde_json::from_str(
        ok(umbra()
            .arg("iso")
            .arg(&input)
            .args(["--iso", "0", "--fields"])
            .arg(&d)
            .args(["--width", "48", "--height", "32", "--json", "-o"])
            .arg(&png))
        .trim(),
    )
    .unwrap();
    assert!(j["hit_pixels"].as_u64().unwrap() > 100);
    let img = image::open(&png).unwrap();
    assert_eq!((img.width(), img.height()), (48, 32));
    // A sweep with --sdf-only over the same name leaves the octants of the sweep before:
    // `iso` refuses them, naming both files, and writes no image.
    ok(umbra()
        .arg("sweep")
        .arg(&input)
        .args(["--iso=-0.2", "--sdf-only", "-o"])
        .arg(&d));
    let stale = dir.path().join("stale.png");
    let out = umbra()
        .arg("iso")
        .arg(&input)
        .args(["--iso=-0.2", "--fields"])
        .arg(&d)
        .args(["--width", "48", "--height", "32", "-o"])
        .arg(&stale)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("s.octants.nrrd")
            && err.contains("another umbra sweep")
            && err.contains("s.nrrd"),
        "{err}"
    );
    assert!(!stale.exists());
    // Fields swept for another level (or side) are refused, naming the level they hold; at
    // their own level they draw.
    ok(umbra()
        .arg("sweep")
        .arg(&input)
        .args(["--iso", "0", "-o"])
        .arg(&d));
    for args in [
        ["--iso=0.5", "--inside=above"],
        ["--iso=0", "--inside=below"],
    ] {
        let out = umbra()
            .arg("iso")
            .arg(&input)
            .args(args)
            .arg("--fields")
            .arg(&d)
            .args(["--width", "48", "--height", "32", "-o"])
            .arg(&stale)
            .output()
            .unwrap();
        assert_eq!(out.status.code(), Some(1), "{args:?}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            err.contains("s.nrrd") && err.contains("swept for the level 0.0 above"),
            "{args:?}: {err}"
        );
        assert!(!stale.exists());
    }
    ok(umbra()
        .arg("iso")
        .arg(&input)
        .args(["--iso", "0", "--fields"])
        .arg(&d)
        .args(["--width", "48", "--height", "32", "-o"])
        .arg(&stale));
    // A distance output that is not named .nrrd is refused before any work.
    for name in ["x.nii", "x.png"] {
        let out = umbra()
            .arg("sweep")
            .arg(&input)
            .args(["--iso", "0", "-o"])
            .arg(dir.path().join(name))
            .output()
            .unwrap();
        assert_eq!(out.status.code(), Some(1), "{name}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(name) && err.contains(".nrrd"), "{err}");
        assert!(!dir.path().join(name).exists());
    }
    let r = dir.path().join("r.png");
    let j: serde_json::Value = serde_json::from_str(
        ok(umbra()
            .arg("iso")
            .arg(&input)
            .args([
                "--iso",
                "0",
                "--reference-ao",
                "16",
                "--width",
                "24",
                "--height",
                "24",
                "--json",
                "-o",
            ])
            .arg(&r))
        .trim(),
    )
    .unwrap();
    assert!(j["mean_stderr"].as_f64().unwrap() > 0.0);
    for bad in [["--gamma", "0"], ["--sky", "octant:9"], ["--geometry", "x"]] {
        let out = umbra()
            .arg("iso")
            .arg(&input)
            .args(["--iso", "0", "-o"])
            .arg(dir.path().join("b.png"))
            .args(bad)
            .output()
            .unwrap();
        assert_eq!(out.status.code(), Some(1), "{bad:?}");
    }
}

#[test]
fn both_distance_methods_run_and_agree_on_the_validation_scene() {
    // `--distance sweeping` (the paper's) and the default closest points: same band, same
    // octants; the distances agree within the sweeps' first-order error (about 1.5 voxels at
    // worst beside corners, docs/accuracy.md), and an unknown method is refused by name.
    let dir = tempfile::tempdir().unwrap();
    let input = synth(dir.path(), 40);
    let run = |method: &str| -> (serde_json::Value, Vec<f32>, Vec<f32>) {
        let d = dir.path().join(format!("{method}.nrrd"));
        let out = ok(umbra()
            .arg("sweep")
            .arg(&input)
            .args(["--iso", "0", "--json", "--distance", method, "-o"])
            .arg(&d));
        let j: serde_json::Value = serde_json::from_str(out.trim()).unwrap();
        let dist = volume::load(&d).unwrap().fields[0].data.clone();
        let oct = volume::load(&dir.path().join(format!("{method}.octants.nrrd")))
            .unwrap()
            .fields[0]
            .data
            .clone();
        (j, dist, oct)
    };
    let (jc, dc, oc) = run("closest-point");
    let (js, ds, os) = run("sweeping");
    assert_eq!(jc["distance_method"], "closest-point");
    assert_eq!(js["distance_method"], "sweeping");
    assert!(js["iterations"].as_u64().unwrap() >= 1);
    assert_eq!(jc["band_voxels"], js["band_voxels"]);
    // The octants come from the band alone: identical.
    assert_eq!(oc, os);
    // Spacing: the validation scene spans [0, 100] with 40 samples.
    let h = 100.0 / 39.0;
    let mut worst = 0.0f32;
    for (a, b) in dc.iter().zip(&ds) {
        assert_eq!(a.is_sign_negative(), b.is_sign_negative());
        worst = worst.max((a - b).abs() / h);
    }
    assert!(worst < 2.0, "methods differ by {worst} voxels");
    assert!(worst > 0.0, "the two methods cannot be told apart");
    let bad = umbra()
        .arg("sweep")
        .arg(&input)
        .args(["--iso", "0", "--distance", "fmm", "-o"])
        .arg(dir.path().join("x.nrrd"))
        .output()
        .unwrap();
    assert!(!bad.status.success());
    let err = String::from_utf8_lossy(&bad.stderr);
    assert!(
        err.contains("--distance") && err.contains("closest-point"),
        "{err}"
    );
}
