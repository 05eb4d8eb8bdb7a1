//! Image metrics of the benchmarks: RMSE, largest error, PSNR and SSIM against a reference,
//! the Pareto front of (time, error) points, and the reference cache's key (FNV-1a, from
//! `scene::hash`).

/// FNV-1a, 64 bits: the reference cache's key.
pub use scene::hash::fnv1a as fnv;

/// Luminance of linear RGB.
fn luma(c: [f64; 3]) -> f64 {
    0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]
}

/// Mean SSIM of two single-channel images (Gaussian window sigma 1.5, radius 5).
pub fn ssim(a: &[f64], b: &[f64], w: usize, h: usize) -> f64 {
    let r = 5i64;
    let g: Vec<f64> = (-r..=r).map(|i| (-(i * i) as f64 / 4.5).exp()).collect();
    // One 1-D pass of the normalised window along x (stride 1, length w) or y (stride w,
    // length h), the window cut at the border.
    let pass = |x: &[f64], along_x: bool| -> Vec<f64> {
        let mut out = vec![0.0; w * h];
        for y in 0..h {
            for xx in 0..w {
                let (pos, len) = if along_x { (xx, w) } else { (y, h) };
                let (mut s, mut n) = (0.0, 0.0);
                for (k, gk) in g.iter().enumerate() {
                    let i = pos as i64 + k as i64 - r;
                    if i >= 0 && i < len as i64 {
                        let idx = if along_x {
                            i as usize + w * y
                        } else {
                            xx + w * i as usize
                        };
                        s += gk * x[idx];
                        n += gk;
                    }
                }
                out[xx + w * y] = s / n;
            }
        }
        out
    };
    let blur = |x: &[f64]| pass(&pass(x, true), false);
    let prod = |x: &[f64], y: &[f64]| x.iter().zip(y).map(|(p, q)| p * q).collect::<Vec<_>>();
    let (ma, mb) = (blur(a), blur(b));
    let (saa, sbb, sab) = (blur(&prod(a, a)), blur(&prod(b, b)), blur(&prod(a, b)));
    let (c1, c2) = (1e-4, 9e-4);
    let mut total = 0.0;
    for i in 0..w * h {
        let (va, vb) = (saa[i] - ma[i] * ma[i], sbb[i] - mb[i] * mb[i]);
        let cov = sab[i] - ma[i] * mb[i];
        total += ((2.0 * ma[i] * mb[i] + c1) * (2.0 * cov + c2))
            / ((ma[i] * ma[i] + mb[i] * mb[i] + c1) * (va + vb + c2));
    }
    total / (w * h) as f64
}

/// RMSE, largest error, PSNR and SSIM of `img` against `reference` (linear, clamped to [0, 1]).
pub fn metrics(img: &[[f64; 3]], reference: &[[f64; 3]], w: usize, h: usize) -> [f64; 4] {
    let c = |v: f64| v.clamp(0.0, 1.0);
    let (mut se, mut mx) = (0.0, 0.0f64);
    for (p, q) in img.iter().zip(reference) {
        for k in 0..3 {
            let d = c(p[k]) - c(q[k]);
            se += d * d;
            mx = mx.max(d.abs());
        }
    }
    let mse = se / (3 * img.len()).max(1) as f64;
    let la: Vec<f64> = img.iter().map(|p| luma(p.map(c))).collect();
    let lb: Vec<f64> = reference.iter().map(|p| luma(p.map(c))).collect();
    [
        mse.sqrt(),
        mx,
        10.0 * (1.0 / mse.max(1e-20)).log10(),
        ssim(&la, &lb, w, h),
    ]
}

/// The Pareto front of (ms, rmse) points: indices of the points no other is at least as good
/// on both and better on one, by increasing time.
pub fn pareto(points: &[(f64, f64)]) -> Vec<usize> {
    let mut idx: Vec<usize> = (0..points.len()).collect();
    idx.sort_by(|&a, &b| {
        points[a]
            .0
            .total_cmp(&points[b].0)
            .then(points[a].1.total_cmp(&points[b].1))
    });
    let mut front = vec![];
    let mut best = f64::INFINITY;
    for i in idx {
        if points[i].1 < best {
            best = points[i].1;
            front.push(i);
        }
    }
    front
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_pareto_front_keeps_what_nothing_beats() {
        let p = [(1.0, 5.0), (2.0, 3.0), (3.0, 4.0), (4.0, 1.0), (2.0, 6.0)];
        assert_eq!(pareto(&p), vec![0, 1, 3]);
    }

    #[test]
    fn metrics_of_an_image_against_itself_and_a_shifted_one() {
        let (w, h) = (24, 20);
        let a: Vec<[f64; 3]> = (0..w * h)
            .map(|i| [((i % w) as f64 / w as f64); 3])
            .collect();
        let [rmse, mx, psnr, s] = metrics(&a, &a, w, h);
        assert_eq!((rmse, mx), (0.0, 0.0));
        assert!(psnr > 150.0 && (s - 1.0).abs() < 1e-9);
        let b: Vec<[f64; 3]> = a.iter().map(|p| p.map(|v| v + 0.1)).collect();
        let [rmse, mx, psnr, s] = metrics(&b, &a, w, h);
        assert!(
            (rmse - 0.1).abs() < 0.01 && (mx - 0.1).abs() < 1e-9,
            "{rmse} {mx}"
        );
        assert!((psnr - 20.0).abs() < 1.0, "{psnr}");
        assert!(s < 1.0 && s > 0.5, "{s}");
    }
}
