//! Image files: 8-bit sRGB PNG, linear float EXR with the renderer's AOV channels, and the
//! Monte Carlo reference's EXR (one reader and one writer). Every file is written to a
//! temporary file in its folder and renamed into place.

use occlusion::reference::RefImage;
use std::path::Path;

/// Encodes linear [0, 1] values as 8-bit sRGB.
pub fn srgb8(v: f32) -> u8 {
    let v = v.clamp(0.0, 1.0);
    let s = if v <= 0.003_130_8 {
        12.92 * v
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    };
    (s * 255.0 + 0.5) as u8
}

/// Writes the colour of an image as an 8-bit sRGB PNG through a temporary file.
pub fn write_png(
    path: &std::path::Path,
    img: &occlusion::isosurface::IsoImage,
) -> Result<(), String> {
    write_rgb_png(path, img.width, img.height, &img.color)
}

/// The two-valued (print) form of a linear colour: white (255) where its sRGB-encoded
/// luminance `Y = 0.2126 R + 0.7152 G + 0.0722 B` is at least half, else black (0).
pub fn one_bit(c: [f32; 3]) -> u8 {
    let y = 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2];
    if srgb8(y) >= 128 {
        255
    } else {
        0
    }
}

/// Writes linear RGB pixels as a greyscale PNG with exactly two values, 0 and 255 ([`one_bit`]),
/// through a temporary file.
pub fn write_bw_png(
    path: &std::path::Path,
    width: usize,
    height: usize,
    color: &[[f32; 3]],
) -> Result<(), String> {
    check_pixels(path, width, height, color.len())?;
    let buf = image::GrayImage::from_fn(width as u32, height as u32, |x, y| {
        image::Luma([one_bit(color[x as usize + width * y as usize])])
    });
    write_encoded(path, image::DynamicImage::ImageLuma8(buf))
}

/// An error unless `n` pixels fill a `width x height` image.
fn check_pixels(path: &Path, width: usize, height: usize, n: usize) -> Result<(), String> {
    if n != width * height {
        return Err(format!(
            "{}: {n} pixels for a {width} x {height} image",
            path.display()
        ));
    }
    Ok(())
}

/// Encodes `img` as PNG and writes it through a temporary file.
fn write_encoded(path: &Path, img: image::DynamicImage) -> Result<(), String> {
    let mut bytes = Vec::new();
    img.write_to(
        &mut std::io::Cursor::new(&mut bytes),
        image::ImageFormat::Png,
    )
    .map_err(|e| format!("{}: encoding PNG: {e}", path.display()))?;
    volume::write_atomic(path, &bytes).map_err(|e| e.to_string())
}

/// Writes linear RGB pixels (rows top to bottom) as an 8-bit sRGB PNG through a temporary file.
pub fn write_rgb_png(
    path: &std::path::Path,
    width: usize,
    height: usize,
    color: &[[f32; 3]],
) -> Result<(), String> {
    check_pixels(path, width, height, color.len())?;
    let mut buf = image::RgbImage::new(width as u32, height as u32);
    for (i, c) in color.iter().enumerate() {
        buf.put_pixel(
            (i % width) as u32,
            (i / width) as u32,
            image::Rgb([srgb8(c[0]), srgb8(c[1]), srgb8(c[2])]),
        );
    }
    write_encoded(path, image::DynamicImage::ImageRgb8(buf))
}

/// Writes linear RGBA as EXR (channels R, G, B, A) with any further named channels (the
/// renderer's AOVs, `engine::renderer::Output::aov_channels`), through a temporary file renamed
/// into place. Colours are light, never negative: a resolve's rounding below 0 (-0.003 was
/// seen at an MSAA silhouette) is written as 0, as the PNG's quantisation does.
pub fn write_exr(
    path: &Path,
    w: usize,
    h: usize,
    image: &[[f32; 4]],
    channels: &[(String, Vec<f32>)],
) -> Result<(), String> {
    use exr::prelude::*;
    let ch = |name: &str, v: Vec<f32>| AnyChannel::new(name, FlatSamples::F32(v));
    let mut list: SmallVec<[AnyChannel<FlatSamples>; 4]> = SmallVec::new();
    for (k, n) in ["R", "G", "B", "A"].iter().enumerate() {
        list.push(ch(n, image.iter().map(|p| p[k].max(0.0)).collect()));
    }
    for (n, v) in channels {
        if v.len() != w * h {
            return Err(format!(
                "{}: channel {n} has {} values for {w} x {h} pixels",
                path.display(),
                v.len()
            ));
        }
        list.push(ch(n, v.clone()));
    }
    let img = Image::from_encoded_channels((w, h), deterministic(), AnyChannels::sort(list));
    let mut bytes = std::io::Cursor::new(Vec::new());
    img.write()
        .to_buffered(&mut bytes)
        .map_err(|e| format!("{}: encoding EXR: {e}", path.display()))?;
    volume::write_atomic(path, bytes.get_ref()).map_err(|e| e.to_string())?;
    Ok(())
}

/// exr's fast lossless encoding (RLE in 64 x 64 tiles) with the tiles written in increasing
/// order: compressed in parallel, they are put in order before writing, so the same image
/// gives the same bytes every time (in any order, readers agree, but files would not compare
/// equal byte for byte).
fn deterministic() -> exr::prelude::Encoding {
    exr::prelude::Encoding {
        line_order: exr::prelude::LineOrder::Increasing,
        ..exr::prelude::Encoding::FAST_LOSSLESS
    }
}

/// An EXR's first layer: its size and every channel by name, as 32-bit floats (what
/// [`write_exr`] and [`RefImage::write_exr`] write; the tests read images back through it).
pub type ExrChannels = ((usize, usize), Vec<(String, Vec<f32>)>);

/// Reads [`ExrChannels`] from `path`; an error naming the file when it is no readable EXR.
pub fn read_exr_channels(path: &Path) -> Result<ExrChannels, String> {
    let img = exr::prelude::read_first_flat_layer_from_file(path)
        .map_err(|e| format!("{}: reading EXR: {e}", path.display()))?;
    let size = img.layer_data.size;
    let channels = img
        .layer_data
        .channel_data
        .list
        .iter()
        .map(|c| (c.name.to_string(), c.sample_data.values_as_f32().collect()))
        .collect();
    Ok(((size.0, size.1), channels))
}

/// The channel `name` of [`ExrChannels`], if there is one.
pub fn exr_channel<'a>(channels: &'a ExrChannels, name: &str) -> Option<&'a [f32]> {
    channels
        .1
        .iter()
        .find(|(n, _)| n == name)
        .map(|(_, v)| v.as_slice())
}

/// The EXR channels of a cached reference, in [`RefImage`]'s field order after R, G, B.
const REF_CHANNELS: [&str; 4] = [
    "stderr",
    "occlusion.volumetric",
    "occlusion.surface",
    "occlusion.vicinity",
];

/// A Monte Carlo reference image in one EXR: every field of [`RefImage`] a channel.
pub trait RefImageExr: Sized {
    fn write_exr(&self, path: &std::path::Path) -> Result<(), String>;
    fn read_exr(path: &std::path::Path) -> Option<Self>;
}

impl RefImageExr for RefImage {
    /// Writes every field as a 32-bit float channel (R, G, B, then [`REF_CHANNELS`]) of one
    /// EXR, atomically.
    fn write_exr(&self, path: &std::path::Path) -> Result<(), String> {
        use exr::prelude::*;
        let ch = |name: &str, v: Vec<f32>| AnyChannel::new(name, FlatSamples::F32(v));
        let f32s = |v: &[f64]| v.iter().map(|&x| x as f32).collect::<Vec<f32>>();
        let mut list: SmallVec<[AnyChannel<FlatSamples>; 4]> = SmallVec::new();
        for (k, n) in ["R", "G", "B"].iter().enumerate() {
            list.push(ch(n, self.rgb.iter().map(|p| p[k] as f32).collect()));
        }
        let planes = [
            &self.stderr,
            &self.volumetric,
            &self.surface,
            &self.vicinity,
        ];
        for (name, plane) in REF_CHANNELS.iter().zip(planes) {
            list.push(ch(name, f32s(plane)));
        }
        let img = Image::from_encoded_channels(
            (self.width, self.height),
            deterministic(),
            AnyChannels::sort(list),
        );
        let mut bytes = std::io::Cursor::new(Vec::new());
        img.write()
            .to_buffered(&mut bytes)
            .map_err(|e| format!("{}: encoding EXR: {e}", path.display()))?;
        volume::write_atomic(path, bytes.get_ref()).map_err(|e| e.to_string())
    }

    /// Reads what [`RefImage::write_exr`] wrote; `None` when the file is absent, unreadable or
    /// lacks a channel.
    fn read_exr(path: &std::path::Path) -> Option<RefImage> {
        let img = read_exr_channels(path).ok()?;
        let size = img.0;
        let chan = |name: &str| -> Option<Vec<f64>> {
            exr_channel(&img, name).map(|v| v.iter().map(|&x| x as f64).collect())
        };
        let (r, g, b) = (chan("R")?, chan("G")?, chan("B")?);
        let [stderr, volumetric, surface, vicinity] = [
            chan(REF_CHANNELS[0])?,
            chan(REF_CHANNELS[1])?,
            chan(REF_CHANNELS[2])?,
            chan(REF_CHANNELS[3])?,
        ];
        Some(RefImage {
            width: size.0,
            height: size.1,
            rgb: (0..r.len()).map(|i| [r[i], g[i], b[i]]).collect(),
            stderr,
            volumetric,
            surface,
            vicinity,
        })
    }
}

/// The median over the pixels in `mask` of the standard deviation of `values` in the
/// `(2 half + 1)^2` window around each, over the window's pixels that are in `mask` too (so
/// edges against what the mask leaves out do not count); NaN when the mask is empty. With
/// `values` the 8-bit luminance of an image, the local contrast figure of `docs/gallery.md`.
pub fn median_local_spread(values: &[f32], mask: &[bool], w: usize, h: usize, half: usize) -> f64 {
    let mut spreads: Vec<f64> = (0..w * h)
        .filter(|&i| mask[i])
        .map(|i| {
            let (x, y) = (i % w, i / w);
            let (mut n, mut s, mut s2) = (0.0f64, 0.0f64, 0.0f64);
            for yy in y.saturating_sub(half)..(y + half + 1).min(h) {
                for xx in x.saturating_sub(half)..(x + half + 1).min(w) {
                    let j = yy * w + xx;
                    if mask[j] {
                        let v = values[j] as f64;
                        n += 1.0;
                        s += v;
                        s2 += v * v;
                    }
                }
            }
            let m = s / n;
            (s2 / n - m * m).max(0.0).sqrt()
        })
        .collect();
    if spreads.is_empty() {
        return f64::NAN;
    }
    let k = spreads.len() / 2;
    spreads.select_nth_unstable_by(k, f64::total_cmp);
    spreads[k]
}

/// The 8-bit luminance (Rec. 709 weights of the sRGB-encoded channels) of linear RGBA pixels.
pub fn luminance8(image: &[[f32; 4]]) -> Vec<f32> {
    image
        .iter()
        .map(|c| {
            0.2126 * srgb8(c[0]) as f32 + 0.7152 * srgb8(c[1]) as f32 + 0.0722 * srgb8(c[2]) as f32
        })
        .collect()
}

#[cfg(test)]
mod spread_tests {
    use super::*;

    #[test]
    fn the_local_spread_of_a_checkerboard_and_of_a_flat_image() {
        let (w, h) = (40, 30);
        let flat = vec![100.0f32; w * h];
        let all = vec![true; w * h];
        assert_eq!(median_local_spread(&flat, &all, w, h, 4), 0.0);
        // Alternating 0 / 20 columns: a spread of 10 wherever the window is even-sized in x
        // ... about 10 everywhere.
        let cols: Vec<f32> = (0..w * h)
            .map(|i| if i % 2 == 0 { 0.0 } else { 20.0 })
            .collect();
        let m = median_local_spread(&cols, &all, w, h, 4);
        assert!((m - 10.0).abs() < 0.2, "{m}");
        // Masked-out pixels do not count: only the 20s left, no spread.
        let odd: Vec<bool> = (0..w * h).map(|i| i % 2 == 1).collect();
        assert_eq!(median_local_spread(&cols, &odd, w, h, 4), 0.0);
        assert!(median_local_spread(&cols, &vec![false; w * h], w, h, 4).is_nan());
    }
}

#[cfg(test)]
mod exr_tests {
    use super::*;

    /// Negative colours are written as 0 (a resolve's rounding), the rest as given, alpha and
    /// the AOV channels untouched.
    #[test]
    fn an_exr_holds_no_negative_colour() {
        let d = tempfile::tempdir().unwrap();
        let p = d.path().join("x.exr");
        let image = [[-0.0032f32, 0.5, 2.0, 1.0], [0.25, -1.0, 0.0, 0.5]];
        let aov = vec![("occlusion.combined".to_string(), vec![0.75f32, 1.0])];
        write_exr(&p, 2, 1, &image, &aov).unwrap();
        let img = read_exr_channels(&p).unwrap();
        let chan = |name: &str| exr_channel(&img, name).unwrap().to_vec();
        assert_eq!(chan("R"), [0.0, 0.25]);
        assert_eq!(chan("G"), [0.5, 0.0]);
        assert_eq!(chan("B"), [2.0, 0.0]);
        assert_eq!(chan("A"), [1.0, 0.5]);
        assert_eq!(chan("occlusion.combined"), [0.75, 1.0]);
    }

    /// The same image gives the same bytes: tiles compressed in parallel are written in order
    /// (in completion order, five runs of a render gave five different files).
    #[test]
    fn an_exr_is_the_same_bytes_every_time() {
        let d = tempfile::tempdir().unwrap();
        let (w, h) = (512, 384);
        let image: Vec<[f32; 4]> = (0..w * h)
            .map(|i| {
                let v = ((i * 7919) % 1000) as f32 / 1000.0;
                [v, 1.0 - v, (i % w) as f32 / w as f32, 1.0]
            })
            .collect();
        let aov = vec![(
            "depth".to_string(),
            image.iter().map(|p| p[0] * 3.0).collect(),
        )];
        let bytes = |k: usize| {
            let p = d.path().join(format!("{k}.exr"));
            write_exr(&p, w, h, &image, &aov).unwrap();
            std::fs::read(&p).unwrap()
        };
        let first = bytes(0);
        for k in 1..8 {
            assert!(bytes(k) == first, "write {k} differs from the first");
        }
    }
}
