//! The MNI demo shows the brain's structure: its median 9 x 9 local luminance spread over the
//! brain's pixels (background and tubes left out) at 512 x 384 is at least 6/255 (issue 20),
//! and the three bundles are on screen in their own colours.

use scene::compile::{model, upload};
use scene::image_io::{luminance8, median_local_spread};
use std::path::Path;

fn root() -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .unwrap()
        .to_path_buf()
}

/// The scene's image (linear RGBA) at 512 x 384.
fn draw(gpu: &engine::gpu::Gpu, s: &scene::Scene) -> Vec<[f32; 4]> {
    let m = model(s).unwrap();
    let up = upload(gpu, &m).unwrap();
    let (out, _) = up
        .draw_at(
            s,
            &m,
            engine::renderer::DrawOptions {
                frames: 1,
                pass_timings: false,
            },
            None,
        )
        .unwrap();
    out.image
}

#[test]
fn the_mni_demo_shows_gyri_sulci_and_the_bundles() {
    let path = root().join("datasets/scenes/demo.toml");
    let sets = [
        "render.width=512".to_string(),
        "render.height=384".to_string(),
    ];
    let s = scene::spec::load(&path, &sets).unwrap();
    let gpu = engine::gpu::Gpu::new().expect("a GPU adapter (lavapipe in CI)");
    let full = draw(&gpu, &s);
    // Where the brain is: the volume alone; where the tubes are: the tubes alone.
    let mut vol_only = s.clone();
    vol_only.tubes.clear();
    let brain = draw(&gpu, &vol_only);
    let mut tubes_only = s.clone();
    tubes_only.volume = None;
    tubes_only.clip.clear();
    let tubes = draw(&gpu, &tubes_only);
    let (w, h) = (512, 384);
    let mask: Vec<bool> = (0..w * h)
        .map(|i| brain[i][3] > 0.5 && tubes[i][3] < 0.5)
        .collect();
    let n = mask.iter().filter(|&&b| b).count();
    assert!(n > w * h / 10, "the brain covers {n} pixels");
    let spread = median_local_spread(&luminance8(&full), &mask, w, h, 4);
    eprintln!("median 9x9 local luminance spread over {n} brain pixels: {spread:.2}/255");
    assert!(spread >= 6.0, "{spread:.2}/255");
    // Each bundle is on screen in its own colour: pixels of the full image whose chromaticity
    // is nearest to that bundle's colour (orange, blue, green) and clearly coloured.
    let chroma = |c: [f32; 3]| {
        let s = c[0] + c[1] + c[2];
        [c[0] / s, c[1] / s, c[2] / s]
    };
    // The codes are sRGB; the image is linear light.
    let hex = |h: &str| {
        let v = |k: usize| {
            let c = u8::from_str_radix(&h[1 + 2 * k..3 + 2 * k], 16).unwrap() as f64 / 255.0;
            volume::colormap::srgb_to_linear(c) as f32
        };
        chroma([v(0), v(1), v(2)])
    };
    let want: Vec<[f32; 3]> = s.tubes.iter().map(|t| hex(&t.color)).collect();
    assert_eq!(want.len(), 3);
    let mut counts = [0usize; 3];
    for (i, c) in full.iter().enumerate() {
        if tubes[i][3] < 0.5 || c[0] + c[1] + c[2] < 0.05 {
            continue;
        }
        let q = chroma([c[0], c[1], c[2]]);
        let d: Vec<f32> = want
            .iter()
            .map(|w| (0..3).map(|k| (q[k] - w[k]).powi(2)).sum::<f32>())
            .collect();
        let (k, best) = d
            .iter()
            .enumerate()
            .min_by(|a, b| a.1.total_cmp(b.1))
            .unwrap();
        if *best < 0.01 {
            counts[k] += 1;
        }
    }
    eprintln!("pixels in each bundle's colour: {counts:?}");
    assert!(counts.iter().all(|&n| n > 400), "{counts:?}");
}
