//! Illustrative line rendering for print: `render.method = "illustrative"` draws line cores
//! in `render.illustrative.line` and halos in `render.illustrative.halo` whatever the lines'
//! colour, and `render.bits = 1` writes a PNG with exactly two values.

use glam::Vec3;
use scene::render::{run, RenderArgs};

#[test]
fn illustrative_halos_in_one_bit_print() {
    let dir = tempfile::tempdir().unwrap();
    // Two crossing lines, the one along y 3 units behind the one along x.
    let mut s = tubes::Streamlines::new();
    s.push(&[Vec3::new(-10.0, 0.0, 3.0), Vec3::new(10.0, 0.0, 3.0)]);
    s.push(&[Vec3::new(0.0, -10.0, 0.0), Vec3::new(0.0, 10.0, 0.0)]);
    tubes::save(&dir.path().join("x.tck"), &s).unwrap();
    let scene = dir.path().join("print.toml");
    std::fs::write(
        &scene,
        "background = [1.0, 1.0, 1.0]\n[camera]\nprojection = \"orthographic\"\n\
         eye = [0.0, 0.0, 40.0]\ntarget = [0.0, 0.0, 0.0]\nup = [0.0, 1.0, 0.0]\nheight = 24.0\n\
         [[lines]]\npath = \"x.tck\"\ncolor = \"#ff0000\"\nwidth = 3.0\n\
         halo = { width = 6.0, d_max = 0.02 }\n\
         [render]\nmethod = \"illustrative\"\nwidth = 80\nheight = 80\nbits = 1\n\
         [render.illustrative]\nline = [0.0, 0.0, 0.0]\nhalo = [1.0, 1.0, 1.0]\n",
    )
    .unwrap();
    let out = dir.path().join("print.png");
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
    let img = image::open(&out).unwrap().to_luma8();
    let values: std::collections::BTreeSet<u8> = img.pixels().map(|p| p.0[0]).collect();
    assert_eq!(values, [0u8, 255].into_iter().collect());
    // Black cores on white: the red colour is not used; the back line is cut by the front
    // line's halo beside the crossing (its column is white just off the front line's core).
    let black = img.pixels().filter(|p| p.0[0] == 0).count();
    assert!(black > 200 && black < 1200, "{black} black pixels");
    let (cx, cy) = (40u32, 40u32);
    assert_eq!(img.get_pixel(cx, cy).0[0], 0, "the front core");
    assert_eq!(
        img.get_pixel(cx, cy + 5).0[0],
        255,
        "the halo cuts the back line"
    );
    assert_eq!(
        img.get_pixel(cx, cy + 20).0[0],
        0,
        "the back line away from the crossing"
    );
    // An EXR with bits = 1 is refused.
    let e = run(
        &RenderArgs {
            scene,
            output: dir.path().join("print.exr"),
            frames: 1,
            ..Default::default()
        },
        &mut |_| {},
    )
    .unwrap_err();
    assert!(e.contains("render.bits"), "{e}");
}
