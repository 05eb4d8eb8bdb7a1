//! `umbra render` with the emission-absorption baseline end to end (moved from the renderer's
//! tests: it runs the binary).

#[test]
fn umbra_render_draws_the_ea_baseline_and_refuses_bad_settings() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .unwrap();
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("s.toml");
    std::fs::write(
        &scene,
        format!(
            "background = [0.0, 0.0, 0.0]\n[volume]\npath = \"{}\"\n[volume.transfer]\npreset = \"fire\"\nextinction = 0.05\n[render]\nmethod = \"ea\"\nwidth = 64\nheight = 48\n",
            root.join("datasets/vtk/headsq_64x64x93.nhdr").display()
        ),
    )
    .unwrap();
    let png = dir.path().join("s.png");
    let run = |extra: &[&str]| {
        std::process::Command::new(env!("CARGO_BIN_EXE_umbra"))
            .arg("render")
            .arg(&scene)
            .arg("-o")
            .arg(&png)
            .args(extra)
            .output()
            .unwrap()
    };
    let out = run(&["--json"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let r: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(r["width"], 64);
    assert!(r["slices"].as_u64().unwrap() > 50);
    let img = image::open(&png).unwrap().to_rgb8();
    assert_eq!(img.dimensions(), (64, 48));
    // The head glows on black: a bright centre, black corners.
    assert_eq!(img.get_pixel(0, 0).0, [0, 0, 0]);
    let lit = img.pixels().filter(|p| p.0[0] > 60).count();
    assert!(lit > 64 * 48 / 10, "{lit} lit pixels");
    // Settings that would hang or draw nothing are refused, naming the key; no image.
    std::fs::remove_file(&png).unwrap();
    for (set, key) in [
        ("render.slice_distance=1e-9", "render.slice_distance"),
        ("render.slices=20000", "render.slices"),
        ("camera.near=1e9", "camera.near"),
    ] {
        let out = run(&["--set", set]);
        assert!(!out.status.success(), "{set}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(key), "{set}: {err}");
        assert!(!png.exists());
    }
    let out = run(&[]);
    assert!(out.status.success());
}
