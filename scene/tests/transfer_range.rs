//! `volume.transfer.range`: the values a preset's ramp spans - the field's finite range
//! (default), its robust range (2nd to 98th percentiles) or values given - on a field whose
//! full range a few outliers stretch (as the CTH pressure field's), with the note that says so.

use glam::DVec3;
use std::path::Path;

/// A 20^3 field of values 0..100 (a ramp along x plus a little along y), NaN in one voxel,
/// and five voxels of 1e6: the full range is [0, 1e6], the robust one about [0.1, 100].
fn outlier_volume(dir: &Path) -> std::path::PathBuf {
    let n = [20, 20, 20];
    let affine = volume::synthetic::cube_affine(n, 0.0, 19.0);
    let mut vol = volume::synthetic::sample_scalar(n, affine, "pressure", |p: DVec3| {
        100.0 * p.x / 19.0 + 0.01 * p.y
    });
    let data = &mut vol.fields[0].data;
    for i in [7, 1000, 2345, 5000, 7999] {
        data[i] = 1e6;
    }
    data[4321] = f32::NAN;
    write(&vol, &dir.join("p.nrrd"))
}

/// `vol`'s first field as a raw NRRD at `path`.
fn write(vol: &volume::Volume, path: &Path) -> std::path::PathBuf {
    volume::nrrd::write(path, vol, &vol.fields[0], volume::nrrd::WriteEncoding::Raw).unwrap();
    path.to_path_buf()
}

fn scene(path: &Path, range: Option<&str>) -> scene::spec::Scene {
    let mut text = format!(
        "[volume]\npath = \"{}\"\n[volume.transfer]\npreset = \"cool-warm\"\n",
        path.display()
    );
    if let Some(r) = range {
        text += &format!("range = {r}\n");
    }
    text += "[annotate]\ncolorbar = \"volume\"\n";
    scene::spec::parse(&text, "t.toml", path.parent().unwrap(), &[]).unwrap()
}

/// The values of the field's finite samples, sorted: numpy's linear quantile at `q`.
fn quantile(path: &Path, q: f64) -> f64 {
    let v = volume::load(path).unwrap();
    let mut x: Vec<f64> = v.fields[0]
        .data
        .iter()
        .filter(|v| v.is_finite())
        .map(|&v| v as f64)
        .collect();
    x.sort_by(f64::total_cmp);
    let at = q * (x.len() - 1) as f64;
    let k = at.floor() as usize;
    x[k] + (at - k as f64) * (x[k + 1] - x[k])
}

#[test]
fn a_preset_spans_the_full_range_the_robust_range_or_the_values_given() {
    let dir = tempfile::tempdir().unwrap();
    let path = outlier_volume(dir.path());
    let (p2, p98) = (quantile(&path, 0.02), quantile(&path, 0.98));
    assert!(
        (0.0..1.0).contains(&p2) && (99.0..101.0).contains(&p98),
        "{p2} {p98}"
    );
    let spans = |m: &scene::compile::Model| {
        let t = &m.volume.as_ref().unwrap().2;
        [t.points[0].0, t.points.last().unwrap().0]
    };
    // Default: the full range, with a note naming the robust range and the key.
    let m = scene::compile::model(&scene(&path, None)).unwrap();
    assert_eq!(spans(&m), [0.0, 1e6]);
    assert_eq!(m.colorbar.as_ref().unwrap().range, [0.0, 1e6]);
    let note = m
        .notes
        .iter()
        .find(|n| n.contains("volume.transfer.range"))
        .expect("a note on the outliers");
    let p98_shown = scene::annotate::format_number(p98);
    assert!(
        note.contains("p.nrrd") && note.contains(&p98_shown),
        "{note}"
    );
    // "robust": the 2nd and 98th percentiles, exactly; the colour bar follows; no note.
    let m = scene::compile::model(&scene(&path, Some("\"robust\""))).unwrap();
    let [lo, hi] = spans(&m);
    assert!(
        (lo - p2).abs() < 1e-9 && (hi - p98).abs() < 1e-9,
        "{lo} {hi}"
    );
    assert_eq!(m.colorbar.as_ref().unwrap().range, [lo, hi]);
    assert!(!m.notes.iter().any(|n| n.contains("volume.transfer.range")));
    // Values given.
    let m = scene::compile::model(&scene(&path, Some("[10.0, 60.0]"))).unwrap();
    assert_eq!(spans(&m), [10.0, 60.0]);
    // A field without outliers gets no note.
    let plain = volume::synthetic::sample_scalar(
        [12, 12, 12],
        volume::synthetic::cube_affine([12, 12, 12], 0.0, 11.0),
        "ramp",
        |p: DVec3| p.x,
    );
    let quiet = write(&plain, &dir.path().join("q.nrrd"));
    let m = scene::compile::model(&scene(&quiet, None)).unwrap();
    assert!(!m.notes.iter().any(|n| n.contains("volume.transfer.range")));
}

#[test]
fn a_bad_range_is_refused_naming_the_key() {
    let dir = tempfile::tempdir().unwrap();
    let path = outlier_volume(dir.path());
    for (range, why) in [
        ("\"wide\"", "'wide' is not"),
        ("[5.0, 5.0]", "lo below hi"),
        ("[6.0, 1.0]", "lo below hi"),
        ("[nan, 1.0]", "finite in single precision"),
        ("[1.0, inf]", "finite in single precision"),
        ("[-1e39, 1e39]", "finite in single precision"),
    ] {
        let text = format!(
            "[volume]\npath = \"{}\"\n[volume.transfer]\nrange = {range}\n",
            path.display()
        );
        let e = scene::spec::parse(&text, "t.toml", dir.path(), &[]).unwrap_err();
        assert!(
            e.contains("volume.transfer.range") && e.contains(why),
            "{range}: {e}"
        );
    }
    let text = format!(
        "[volume]\npath = \"{}\"\n[volume.transfer]\nrange = \"robust\"\npoints = [{{ value = 0.0, color = \"#000000\", extinction = 0.0 }}]\n",
        path.display()
    );
    let e = scene::spec::parse(&text, "t.toml", dir.path(), &[]).unwrap_err();
    assert!(
        e.contains("volume.transfer.range") && e.contains("points"),
        "{e}"
    );
    // Saved and loaded back, the key is kept (and the default is not written).
    let s = scene::spec::parse(
        &format!(
            "[volume]\npath = \"{}\"\n[volume.transfer]\nrange = \"robust\"\n",
            path.display()
        ),
        "t.toml",
        dir.path(),
        &[],
    )
    .unwrap();
    let text = scene::spec::to_toml(&s).unwrap();
    assert!(text.contains("range = \"robust\""), "{text}");
    let back = scene::spec::parse(&text, "t.toml", dir.path(), &[]).unwrap();
    assert_eq!(
        back.volume.unwrap().transfer.range,
        s.volume.unwrap().transfer.range
    );
    let plain = scene::spec::parse(
        &format!("[volume]\npath = \"{}\"\n", path.display()),
        "t.toml",
        dir.path(),
        &[],
    )
    .unwrap();
    assert!(!scene::spec::to_toml(&plain).unwrap().contains("range ="));
}
