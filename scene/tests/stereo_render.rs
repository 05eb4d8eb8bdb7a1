//! Anaglyph stereo and point clouds through the scene (`umbra render`): `[[points]]` read from
//! CSV drawn as discs, `render.stereo = "anaglyph"` with the off-axis eyes of
//! `occlusion::camera` (red = left eye), its disparity against the formula.

use scene::render::{run, RenderArgs};

/// The x centroid of the pixels of `img` (RGB8) where channel `c` is dark, within rows
/// `rows` and columns `cols`.
fn dark_x(
    img: &image::RgbImage,
    c: usize,
    rows: std::ops::Range<u32>,
    cols: std::ops::Range<u32>,
) -> f64 {
    let (mut sum, mut n) = (0.0, 0.0);
    for y in rows {
        for x in cols.clone() {
            if img.get_pixel(x, y).0[c] < 128 {
                sum += x as f64 + 0.5;
                n += 1.0;
            }
        }
    }
    assert!(n > 3.0, "channel {c}: {n} dark pixels");
    sum / n
}

#[test]
fn an_anaglyph_shows_the_off_axis_disparity_of_points_at_known_depths() {
    let dir = tempfile::tempdir().unwrap();
    // Three black points on white, the camera on +z looking at the origin from 40: one on
    // the convergence plane (z = 0), one nearer (z = 10, view distance 30), one farther
    // (z = -15, distance 55), apart in y so that their discs do not meet.
    std::fs::write(dir.path().join("p.csv"), "x,y,z\n0,6,0\n0,0,10\n0,-6,-15\n").unwrap();
    let scene = dir.path().join("stereo.toml");
    let (w, h, fov, e, c) = (240u32, 240u32, 40.0f64, 2.0f64, 40.0f64);
    std::fs::write(
        &scene,
        format!(
            "background = [1.0, 1.0, 1.0]\n[camera]\nprojection = \"perspective\"\nfov_y = {fov}\n\
             eye = [0.0, 0.0, 40.0]\ntarget = [0.0, 0.0, 0.0]\nup = [0.0, 1.0, 0.0]\n\
             near = 5.0\nfar = 80.0\n\
             [[points]]\npath = \"p.csv\"\nsize = 1.2\n\
             [render]\nmethod = \"illustrative\"\nwidth = {w}\nheight = {h}\n\
             stereo = \"anaglyph\"\neye_separation = {e}\nconvergence = {c}\n"
        ),
    )
    .unwrap();
    let out = dir.path().join("stereo.png");
    run(
        &RenderArgs {
            scene: scene.clone(),
            output: out.clone(),
            frames: 1,
            ..Default::default()
        },
        &mut |_| {},
    )
    .unwrap();
    let img = image::open(&out).unwrap().to_rgb8();
    // Pixels per unit of NDC, P00 = cot(fov / 2) (square image).
    let p00 = 1.0 / (0.5 * fov.to_radians()).tan();
    let half = 0.5 * w as f64;
    // Row bands of the three points (y = 6, 0, -6 at distances 40, 30, 55).
    let row = |y: f64, d: f64| (0.5 - 0.5 * p00 * y / d) * h as f64;
    for (y, d) in [(6.0, 40.0), (0.0, 30.0), (-6.0, 55.0)] {
        let r = row(y, d);
        let rows = (r - 8.0).max(0.0) as u32..((r + 8.0) as u32).min(h);
        // The left eye's black is where red is dark, the right eye's where green is.
        let xl = dark_x(&img, 0, rows.clone(), 0..w);
        let xr = dark_x(&img, 1, rows, 0..w);
        let want = p00 * e * (1.0 / c - 1.0 / d) * half;
        assert!(
            (xr - xl - want).abs() <= 0.75,
            "distance {d}: disparity {} pixels, the formula {want}",
            xr - xl
        );
    }
    // Without stereo one image: no channel differs.
    let mono = dir.path().join("mono.png");
    run(
        &RenderArgs {
            scene,
            output: mono.clone(),
            frames: 1,
            overrides: vec!["render.stereo=\"none\"".into()],
            ..Default::default()
        },
        &mut |_| {},
    )
    .unwrap();
    let img = image::open(&mono).unwrap().to_rgb8();
    assert!(img.pixels().all(|p| p.0[0] == p.0[1] && p.0[1] == p.0[2]));
    assert!(img.pixels().filter(|p| p.0[0] < 128).count() > 30);
}

/// A point cloud coloured by a column gives the colour bar `points.N`: the column's name
/// and its finite range; a point cloud without a scalar colouring is refused as a source.
#[test]
fn a_point_cloud_coloured_by_a_column_has_a_colour_bar() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("p.csv"),
        "x,y,z,temp\n0,0,0,2.5\n1,0,0,nan\n0,1,0,7.0\n0,0,1,4.0\n",
    )
    .unwrap();
    let scene = |color: &str| {
        format!(
            "[[points]]\npath = \"p.csv\"\ncolor = \"{color}\"\n[annotate]\ncolorbar = \"points.0\"\n"
        )
    };
    let s = scene::spec::parse(&scene("scalar:temp"), "s.toml", dir.path(), &[]).unwrap();
    let m = scene::compile::model(&s).unwrap();
    let bar = m.colorbar.expect("a colour bar");
    assert_eq!(bar.label, "temp");
    assert_eq!(bar.range, [2.5, 7.0]);
    // The scene's bounds hold the discs whole (diameter 1 by default), so the fitted camera
    // does not cut the ones at the edge.
    assert_eq!(
        m.bounds,
        [glam::DVec3::splat(-0.5), glam::DVec3::splat(1.5)]
    );
    let e = scene::spec::parse(&scene("#ff0000"), "s.toml", dir.path(), &[]).unwrap_err();
    assert!(
        e.contains("colorbar") && e.contains("this scene's colour bars: none"),
        "{e}"
    );
    // The error says what keeps the source from having a bar.
    assert!(e.contains("points.0 is coloured '#ff0000'"), "{e}");
    let other = |src: &str| {
        let text = scene("scalar:temp").replace("\"points.0\"", &format!("\"{src}\""));
        scene::spec::parse(&text, "s.toml", dir.path(), &[]).unwrap_err()
    };
    let e = other("points.1");
    assert!(
        e.contains("the scene has one [[points]] entry (points.0)"),
        "{e}"
    );
    let e = other("tubes.0");
    assert!(e.contains("the scene has no [[tubes]] entry"), "{e}");
    // It offers the sources the scene has.
    assert!(e.contains("this scene's colour bars: points.0"), "{e}");
    assert!(other("points.x").contains("'x' is not an index of [[points]]"));
    assert!(other("volume").contains("the scene has no volume"));
    assert!(other("overlays.fa").contains("no overlay is named 'fa' (overlays: none)"));
    assert!(other("frames").contains("not a source of a colour bar"));
    // The illustrative method draws the points in its one ink: their bar is refused there, the
    // other methods keep it.
    scene::render::check_colorbar_method(&s).unwrap();
    let ink = scene::spec::parse(
        &scene("scalar:temp"),
        "s.toml",
        dir.path(),
        &["render.method=\"illustrative\"".into()],
    )
    .unwrap();
    let e = scene::render::check_colorbar_method(&ink).unwrap_err();
    assert!(
        e.contains("annotate.colorbar") && e.contains("render.illustrative.line"),
        "{e}"
    );
}
