//! The swatch of umbra's colour maps in the README (`docs/images/colormaps.png`): one row of
//! 512 x 28 pixels per map of `volume::colormap::Colormap::ALL`, in that order (grey, viridis,
//! magma, inferno, plasma, cool-warm, hot, red-yellow, blue-lightblue), t from 0 at the left to
//! 1 at the right, 4 white pixels between rows; each pixel is `Colormap::rgb(t)` (linear RGB)
//! written as sRGB, so the PNG shows the maps' own sRGB colours.
//! `cargo run --release -p umbra --example colormap_swatch -- docs/images/colormaps.png`

use volume::colormap::Colormap;

fn main() {
    let out = std::env::args()
        .nth(1)
        .unwrap_or_else(|| "docs/images/colormaps.png".into());
    let (w, row, gap) = (512usize, 28usize, 4usize);
    let h = Colormap::ALL.len() * (row + gap) - gap;
    let mut px = vec![[1.0f32; 3]; w * h];
    for (m, cm) in Colormap::ALL.iter().enumerate() {
        for x in 0..w {
            let c = cm.rgb(x as f64 / (w - 1) as f64).map(|v| v as f32);
            for y in 0..row {
                px[x + w * (m * (row + gap) + y)] = c;
            }
        }
    }
    if let Err(e) = scene::image_io::write_rgb_png(std::path::Path::new(&out), w, h, &px) {
        eprintln!("colormap_swatch: {e}");
        std::process::exit(1);
    }
}
