//! FXAA on the final image (T. Lottes, "FXAA", NVIDIA white paper 2009; the compact variant of
//! FXAA 3.11 for consoles) as a compute pass over the linear RGBA buffer. Shader:
//! `shaders/fxaa.wgsl`. Luma is `sqrt` of the Rec. 601 weights of linear colour (close to the
//! display encoding FXAA expects); pixels whose 2x2-diagonal luma range is below
//! `max(1/32, max/8)` are copied; elsewhere the edge direction from the diagonal luma
//! differences picks two or four bilinear taps along the edge, the wider blend rejected when
//! it leaves the local luma range. Pixels composite marks as wholly on an unlit slice are
//! left as they are: a slice's colours are its colour map's, and FXAA would blur the anatomy's
//! own edges (up to 80 of 255 levels on the MNI T1 seen head-on: README, `render.fxaa`). Pixels
//! where a multisampled G-buffer had a surface's sample, and their eight neighbours, are left too:
//! the samples smoothed those edges, and FXAA over them took a quarter of a thin line's ink.

use crate::gpu::{Gpu, Slot};
use crate::prelude::with_prelude;

const SHADER: &str = include_str!("../../shaders/fxaa.wgsl");

/// The pass's uniform. Keep in sync with `struct Params` in `shaders/fxaa.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct FxaaParams {
    pub width: u32,
    pub height: u32,
    pub pad: [u32; 2],
}

pub struct FxaaPass {
    pipe: wgpu::ComputePipeline,
    bind: wgpu::BindGroup,
    pub output: wgpu::Buffer,
    size: (u32, u32),
}

impl FxaaPass {
    /// The pass over `input` (linear RGBA, `width x height`), leaving as they are the pixels
    /// whose `keep` entry (a vec4 per pixel, composite's AOVs) has w above 0.5, and the four
    /// neighbours of those whose w is above 1.5 (multisampled surfaces: `fxaa_cpu` is the
    /// pass where nothing is kept).
    pub fn new(
        gpu: &Gpu,
        width: u32,
        height: u32,
        input: &wgpu::Buffer,
        keep: &wgpu::Buffer,
    ) -> FxaaPass {
        let module = gpu.shader("fxaa.wgsl", &with_prelude(SHADER));
        let layout = gpu.layout(
            "fxaa",
            wgpu::ShaderStages::COMPUTE,
            &[Slot::Uniform, Slot::Storage, Slot::StorageRw, Slot::Storage],
        );
        let pl = gpu.pipeline_layout("fxaa", &[&layout]);
        let pipe = gpu.compute_pipeline_with(&module, "main", &pl, "fxaa");
        let params = FxaaParams {
            width,
            height,
            pad: [0; 2],
        };
        let params = gpu.buffer(
            "fxaa params",
            bytemuck::bytes_of(&params),
            wgpu::BufferUsages::UNIFORM,
        );
        let output = gpu.scratch(
            "fxaa image",
            width as u64 * height as u64 * 16,
            wgpu::BufferUsages::COPY_SRC,
        );
        let bind = gpu.bind(
            "fxaa",
            &layout,
            &[
                params.as_entire_binding(),
                input.as_entire_binding(),
                output.as_entire_binding(),
                keep.as_entire_binding(),
            ],
        );
        FxaaPass {
            pipe,
            bind,
            output,
            size: (width, height),
        }
    }

    pub fn record(&self, enc: &mut wgpu::CommandEncoder) {
        crate::gpu::dispatch_image(enc, &self.pipe, &self.bind, self.size);
    }
}

/// The pass on the CPU, for frames the native CPU renderer draws: `shaders/fxaa.wgsl`'s
/// arithmetic in f32 on a `width x height` linear RGBA image (rows from the top), rows on
/// rayon's threads. Tested against the pass (`the_cpu_twin_matches_the_pass`).
pub fn fxaa_cpu(src: &[[f32; 4]], width: u32, height: u32) -> Vec<[f32; 4]> {
    use rayon::prelude::*;
    let (w, h) = (width as usize, height as usize);
    assert_eq!(src.len(), w * h, "fxaa_cpu: the image is width x height");
    let mut dst = vec![[0.0f32; 4]; src.len()];
    if w == 0 || h == 0 {
        return dst;
    }
    let texel = |x: i64, y: i64| -> [f32; 4] {
        let x = x.clamp(0, w as i64 - 1) as usize;
        let y = y.clamp(0, h as i64 - 1) as usize;
        src[x + w * y]
    };
    let mix = |a: [f32; 4], b: [f32; 4], t: f32| std::array::from_fn(|i| a[i] + (b[i] - a[i]) * t);
    // Bilinear fetch at a continuous pixel position (texel centres at half-integers).
    let fetch = |t: [f32; 2]| -> [f32; 4] {
        let s = [t[0] - 0.5, t[1] - 0.5];
        let b = s.map(f32::floor);
        let f = [s[0] - b[0], s[1] - b[1]];
        let (x, y) = (b[0] as i64, b[1] as i64);
        let a = mix(texel(x, y), texel(x + 1, y), f[0]);
        let c = mix(texel(x, y + 1), texel(x + 1, y + 1), f[0]);
        mix(a, c, f[1])
    };
    let luma = |c: [f32; 4]| (c[0] * 0.299 + c[1] * 0.587 + c[2] * 0.114).max(0.0).sqrt();
    // The luma of the bilinear fetch at each pixel corner (x, y integers: the mean of the four
    // pixels around it, as `fetch` computes it), once per corner rather than four times.
    let cw = w + 1;
    let mut corners = vec![0.0f32; cw * (h + 1)];
    corners.par_chunks_mut(cw).enumerate().for_each(|(y, row)| {
        for (x, l) in row.iter_mut().enumerate() {
            *l = luma(fetch([x as f32, y as f32]));
        }
    });
    dst.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
        for (x, out) in row.iter_mut().enumerate() {
            let centre = [x as f32 + 0.5, y as f32 + 0.5];
            let at = |dx: f32, dy: f32| [centre[0] + dx, centre[1] + dy];
            let m = src[x + w * y];
            let l_m = luma(m);
            let (l_nw, l_ne) = (corners[x + cw * y], corners[x + 1 + cw * y]);
            let (l_sw, l_se) = (corners[x + cw * (y + 1)], corners[x + 1 + cw * (y + 1)]);
            let l_min = l_m.min(l_nw.min(l_ne).min(l_sw.min(l_se)));
            let l_max = l_m.max(l_nw.max(l_ne).max(l_sw.max(l_se)));
            // Low contrast: no edge (FXAA's edge threshold 1/8, minimum 1/32).
            if l_max - l_min < (1.0f32 / 32.0).max(l_max / 8.0) {
                *out = m;
                continue;
            }
            // Edge direction from the diagonal luma differences (pixel y down).
            let dir = [
                -((l_nw + l_ne) - (l_sw + l_se)),
                (l_nw + l_sw) - (l_ne + l_se),
            ];
            let reduce = ((l_nw + l_ne + l_sw + l_se) * 0.25 * (1.0 / 8.0)).max(1.0 / 128.0);
            let rcp = 1.0 / (dir[0].abs().min(dir[1].abs()) + reduce);
            let dir = dir.map(|d| (d * rcp).clamp(-8.0, 8.0));
            let along = |s: f32| at(dir[0] * s, dir[1] * s);
            // WGSL folds `1.0 / 3.0 - 0.5` in abstract (f64) precision, then rounds to f32.
            const THIRD: f32 = (1.0f64 / 3.0 - 0.5) as f32;
            const TWO_THIRDS: f32 = (2.0f64 / 3.0 - 0.5) as f32;
            let (p, q) = (fetch(along(THIRD)), fetch(along(TWO_THIRDS)));
            let a: [f32; 4] = std::array::from_fn(|i| 0.5 * (p[i] + q[i]));
            let (p, q) = (fetch(along(-0.5)), fetch(along(0.5)));
            let b: [f32; 4] = std::array::from_fn(|i| a[i] * 0.5 + 0.25 * (p[i] + q[i]));
            let l_b = luma(b);
            // Colour and alpha (coverage) blended alike: an image composited over black stays
            // premultiplied (colour spread into the background brings its coverage along).
            *out = if l_b < l_min || l_b > l_max { a } else { b };
        }
    });
    dst
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A test image: a hard diagonal edge, a thin bright line, noise (a hash per pixel) in
    /// one quadrant and a ramp with faint noise, alpha varying.
    fn image(w: u32, h: u32) -> Vec<[f32; 4]> {
        (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as f32, (i / w) as f32);
                let hash = ((i.wrapping_mul(2_654_435_761) >> 16) % 1000) as f32 / 1000.0;
                let c = if x < w as f32 / 2.0 && y < h as f32 / 2.0 {
                    [hash, hash * 0.5, 1.0 - hash]
                } else if (x - 2.0 * y).abs() < 1.0 || x > 0.7 * y + 10.0 {
                    [0.9, 0.8, 0.7]
                } else {
                    // Faint noise on the ramp, below FXAA's contrast threshold.
                    [x / w as f32 * 0.2 + 0.01 * hash, 0.1, 0.05]
                };
                [c[0], c[1], c[2], 0.5 + 0.5 * (y / h as f32)]
            })
            .collect()
    }

    #[test]
    fn the_cpu_twin_matches_the_pass() {
        let Ok(g) = Gpu::new() else {
            eprintln!("skipped: no GPU adapter");
            return;
        };
        let (w, h) = (61, 47);
        let img = image(w, h);
        let input = g.buffer(
            "fxaa input",
            bytemuck::cast_slice(&img),
            wgpu::BufferUsages::STORAGE,
        );
        let keep = g.zeroed(
            "fxaa keep",
            w as u64 * h as u64 * 16,
            wgpu::BufferUsages::empty(),
        );
        let pass = FxaaPass::new(&g, w, h, &input, &keep);
        let (_, back) = g.output_buffers("fxaa test", w as u64 * h as u64 * 16);
        let mut enc = g.device.create_command_encoder(&Default::default());
        pass.record(&mut enc);
        enc.copy_buffer_to_buffer(&pass.output, 0, &back, 0, w as u64 * h as u64 * 16);
        g.queue.submit([enc.finish()]);
        let bytes = g.read_buffer(&back).unwrap();
        let gpu: &[[f32; 4]] = bytemuck::cast_slice(&bytes);
        let cpu = fxaa_cpu(&img, w, h);
        let changed = cpu.iter().zip(&img).filter(|(a, b)| a != b).count();
        assert!(changed > 200, "the image has edges FXAA smooths: {changed}");
        let worst = cpu
            .iter()
            .zip(gpu)
            .flat_map(|(a, b)| a.iter().zip(b).map(|(x, y)| (x - y).abs()))
            .fold(0.0f32, f32::max);
        assert!(worst < 1e-4, "CPU twin against the pass: {worst}");
    }

    /// Flat and low-contrast images pass unchanged; a hard edge is blended, colour and alpha
    /// within the range of its two sides.
    #[test]
    fn fxaa_blends_edges_only() {
        let flat = vec![[0.3, 0.4, 0.5, 0.7]; 12 * 9];
        assert_eq!(fxaa_cpu(&flat, 12, 9), flat);
        let faint: Vec<[f32; 4]> = (0..100)
            .map(|i| [0.5 + 0.01 * (i % 2) as f32, 0.5, 0.5, 1.0])
            .collect();
        assert_eq!(fxaa_cpu(&faint, 10, 10), faint);
        let (w, h) = (80usize, 60usize);
        let img = image(w as u32, h as u32);
        let out = fxaa_cpu(&img, w as u32, h as u32);
        // A pixel's result mixes bilinear fetches at most 4 pixels along the edge (the
        // direction is clamped to 8, the taps reach half of it), so it reads pixels within 5.
        let near = |i: usize| {
            let (x, y) = ((i % w) as i64, (i / w) as i64);
            (-5i64..=5)
                .flat_map(move |dy| (-5i64..=5).map(move |dx| (x + dx, y + dy)))
                .filter(|&(x, y)| x >= 0 && y >= 0 && x < w as i64 && y < h as i64)
                .map(|(x, y)| x as usize + w * y as usize)
        };
        let noisy = |i: usize| i % w < w / 2 && i / w < h / 2;
        let ramp = |i: usize| !noisy(i) && img[i][1] == 0.1;
        let (mut flat, mut blended) = (0, 0);
        for (i, (a, b)) in out.iter().zip(&img).enumerate() {
            if near(i).all(ramp) {
                // The ramp's contrast is below the threshold: unchanged.
                assert_eq!(a, b, "ramp pixel {i}");
                flat += 1;
            } else if !near(i).any(noisy) {
                // The edge between ramp and bright: blended within the range of its sides.
                for c in 0..4 {
                    let lo = near(i).map(|j| img[j][c]).fold(f32::INFINITY, f32::min);
                    let hi = near(i).map(|j| img[j][c]).fold(f32::NEG_INFINITY, f32::max);
                    assert!(a[c] >= lo - 1e-6 && a[c] <= hi + 1e-6, "{i}: {a:?}");
                }
                blended += (a != b) as usize;
            }
        }
        assert!(flat > 100 && blended > 50, "{flat} flat, {blended} blended");
        assert!(fxaa_cpu(&[], 0, 0).is_empty());
    }

    /// An image composited over black (colour = straight colour x alpha) stays so: FXAA
    /// spreading colour into the background spreads its coverage with it (an EXR's RGB stays
    /// premultiplied; the colour alone had left coloured pixels of alpha 0).
    #[test]
    fn an_image_over_black_stays_premultiplied() {
        let (w, h) = (40usize, 30usize);
        let k = [0.9f32, 0.5, 0.2];
        let img: Vec<[f32; 4]> = (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as f32, (i / w) as f32);
                // A disc, a line and a hard diagonal.
                let a = if (x - 12.0).hypot(y - 14.0) < 7.0 || (x - y - 8.0).abs() < 0.6 {
                    1.0
                } else if x + y > 55.0 {
                    0.6
                } else {
                    0.0
                };
                [k[0] * a, k[1] * a, k[2] * a, a]
            })
            .collect();
        let out = fxaa_cpu(&img, w as u32, h as u32);
        let changed = out.iter().zip(&img).filter(|(a, b)| a != b).count();
        assert!(changed > 20, "{changed} pixels smoothed");
        for (i, p) in out.iter().enumerate() {
            for c in 0..3 {
                assert!((p[c] - k[c] * p[3]).abs() < 1e-5, "pixel {i}: {p:?}");
            }
        }
    }

    #[test]
    fn the_uniform_matches_its_wgsl_struct() {
        crate::prelude::assert_layout!(
            super::SHADER,
            "Params",
            super::FxaaParams { width, height, pad }
        );
    }
}
