//! What the viewer's tests share.

/// The mean absolute difference, in 8-bit sRGB levels, between a PNG's pixels and a linear
/// RGBA image of the same size as `umbra render` writes it.
pub fn png_difference(png: &image::RgbImage, linear: &[[f32; 4]]) -> f64 {
    png.as_raw()
        .chunks(3)
        .zip(linear)
        .map(|(p, q)| {
            (0..3)
                .map(|c| (p[c] as f64 - scene::image_io::srgb8(q[c]) as f64).abs())
                .sum::<f64>()
        })
        .sum::<f64>()
        / (3.0 * linear.len() as f64)
}
