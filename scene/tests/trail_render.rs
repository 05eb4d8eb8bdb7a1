//! Trails animated in one process (`umbra render --trail-range`): a line with a time per
//! point, read from a .trk scalar, drawn frame by frame with the trail's time advancing; the
//! frames are written with their times and the trail moves along the line.

use scene::render::{run, Cameras, RenderArgs, TrailRange};

/// The mean image column of the pixels darker than the white background.
fn centroid_x(path: &std::path::Path) -> f64 {
    let img = image::open(path).unwrap().to_rgb8();
    let (mut sum, mut n) = (0.0, 0.0);
    for (x, _, p) in img.enumerate_pixels() {
        if p.0.iter().map(|&c| c as u32).sum::<u32>() < 700 {
            sum += x as f64;
            n += 1.0;
        }
    }
    assert!(n > 10.0, "{}: {n} line pixels", path.display());
    sum / n
}

#[test]
fn a_trail_range_writes_a_frame_per_time_and_the_trail_moves() {
    let dir = tempfile::tempdir().unwrap();
    // One line along x from -10 to 10 (41 points), time 0 to 20 along it.
    let trk = dir.path().join("line.trk");
    std::fs::copy(test_support::fixtures().join("tracts/timed_line.trk"), &trk).unwrap();
    let scene = dir.path().join("trail.toml");
    std::fs::write(
        &scene,
        "background = [1.0, 1.0, 1.0]\n[camera]\nprojection = \"orthographic\"\n\
         eye = [0.0, 0.0, 40.0]\ntarget = [0.0, 0.0, 0.0]\nup = [0.0, 1.0, 0.0]\nheight = 24.0\n\
         [[lines]]\npath = \"line.trk\"\ncolor = \"#202020\"\nwidth = 6.0\ntime = \"scalar:time\"\n\
         trail = { now = 0.0, back = 2.0, forward = 2.0 }\n\
         [render]\nmethod = \"illuminated\"\nwidth = 96\nheight = 48\nfxaa = false\nmsaa = 1\n",
    )
    .unwrap();
    let args = RenderArgs {
        scene: scene.clone(),
        output: dir.path().join("f_##.png"),
        frames: 1,
        cameras: Cameras::Single,
        trail_range: Some(TrailRange::parse("4:16:3").unwrap()),
        ..Default::default()
    };
    let r = run(&args, &mut |_| {}).unwrap();
    let nows: Vec<f64> = r.sequence.iter().map(|f| f.now.unwrap()).collect();
    assert_eq!(nows, [4.0, 10.0, 16.0]);
    let xs: Vec<f64> = r.sequence.iter().map(|f| centroid_x(&f.path)).collect();
    // The trail's centre is at x = now - 10 world units; 24 units over 48 pixels, so 2 pixels
    // a unit from the centre column 48: 36, 48, 60.
    for (x, want) in xs.iter().zip([36.0, 48.0, 60.0]) {
        assert!((x - want).abs() < 3.0, "trail centres {xs:?}");
    }
    // A scene without trails is refused; so are a bad range and a mismatched orbit.
    let plain = dir.path().join("plain.toml");
    std::fs::write(&plain, "[[lines]]\npath = \"line.trk\"\n").unwrap();
    let e = run(
        &RenderArgs {
            scene: plain,
            ..args.clone()
        },
        &mut |_| {},
    )
    .unwrap_err();
    assert!(e.contains("trail"), "{e}");
    assert!(TrailRange::parse("0:1").is_err());
    assert!(TrailRange::parse("0:1:0").is_err());
    assert!(TrailRange::parse("0:nan:3").is_err());
    let e = run(
        &RenderArgs {
            cameras: Cameras::Orbit(4),
            ..args
        },
        &mut |_| {},
    )
    .unwrap_err();
    assert!(e.contains("same count"), "{e}");
}
