//! Image metrics of the benchmarks: RMSE, largest error, PSNR and SSIM against a reference,
//! the agreement of a per-pixel estimate with a reference over chosen pixels (RMSE, bias,
//! affine-calibrated RMSE, Pearson and Spearman correlation: [`agreement`]), the Pareto front
//! of (time, error) points, and the reference cache's key (FNV-1a, from `scene::hash`).

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

/// The ranks of `x` from 1 (smallest) to `x.len()`, ties sharing the mean of the ranks they
/// span (`[1, 2, 2, 3]` ranks as `[1, 2.5, 2.5, 4]`); NaN sorts last, as the largest.
pub fn ranks(x: &[f64]) -> Vec<f64> {
    let mut idx: Vec<usize> = (0..x.len()).collect();
    idx.sort_by(|&a, &b| x[a].total_cmp(&x[b]));
    let mut out = vec![0.0; x.len()];
    let mut i = 0;
    while i < idx.len() {
        let mut j = i + 1;
        while j < idx.len() && x[idx[j]] == x[idx[i]] {
            j += 1;
        }
        // Ranks i + 1 ..= j share their mean.
        let r = (i + 1 + j) as f64 / 2.0;
        for &k in &idx[i..j] {
            out[k] = r;
        }
        i = j;
    }
    out
}

/// Pearson's correlation of `x` and `y` (equal lengths); NaN when either is constant or there
/// are fewer than two values.
pub fn pearson(x: &[f64], y: &[f64]) -> f64 {
    let n = x.len().min(y.len());
    if n < 2 {
        return f64::NAN;
    }
    let (mx, my) = (
        x[..n].iter().sum::<f64>() / n as f64,
        y[..n].iter().sum::<f64>() / n as f64,
    );
    let (mut sxy, mut sxx, mut syy) = (0.0, 0.0, 0.0);
    for (a, b) in x[..n].iter().zip(&y[..n]) {
        sxy += (a - mx) * (b - my);
        sxx += (a - mx) * (a - mx);
        syy += (b - my) * (b - my);
    }
    if sxx <= 0.0 || syy <= 0.0 {
        return f64::NAN;
    }
    sxy / (sxx * syy).sqrt()
}

/// Spearman's rank correlation: Pearson's of the ranks ([`ranks`], ties averaged). 1 for any
/// increasing map of `x` onto `y`, -1 for a decreasing one.
pub fn spearman(x: &[f64], y: &[f64]) -> f64 {
    pearson(&ranks(x), &ranks(y))
}

/// The least-squares affine map of `x` onto `y`, `(a, b)` minimising `sum (a x + b - y)^2`;
/// `(0, mean y)` when `x` is constant.
pub fn affine_fit(x: &[f64], y: &[f64]) -> (f64, f64) {
    let n = x.len().min(y.len());
    if n == 0 {
        return (f64::NAN, f64::NAN);
    }
    let (mx, my) = (
        x[..n].iter().sum::<f64>() / n as f64,
        y[..n].iter().sum::<f64>() / n as f64,
    );
    let (mut sxy, mut sxx) = (0.0, 0.0);
    for (a, b) in x[..n].iter().zip(&y[..n]) {
        sxy += (a - mx) * (b - my);
        sxx += (a - mx) * (a - mx);
    }
    if sxx <= 0.0 {
        return (0.0, my);
    }
    let a = sxy / sxx;
    (a, my - a * mx)
}

/// How a per-pixel estimate `x` agrees with a reference `y` over the same pixels.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Agreement {
    /// `sqrt(mean (x - y)^2)`.
    pub rmse: f64,
    /// `mean (x - y)`: positive where the estimate is brighter (more open) than the reference.
    pub bias: f64,
    /// The RMSE after the best affine map of `x` onto `y` ([`affine_fit`]): what is left when
    /// scale and offset are forgiven (for models that are not physical, as screen-space AO).
    pub rmse_affine: f64,
    /// That map, `y ~ slope x + offset`.
    pub slope: f64,
    pub offset: f64,
    pub pearson: f64,
    pub spearman: f64,
    /// How many pixels.
    pub n: usize,
}

/// The [`Agreement`] of `x` with `y` (equal lengths; every value finite); NaN throughout when
/// they are empty.
pub fn agreement(x: &[f64], y: &[f64]) -> Agreement {
    let n = x.len().min(y.len());
    let mean = |f: &dyn Fn(usize) -> f64| (0..n).map(f).sum::<f64>() / n as f64;
    let (slope, offset) = affine_fit(&x[..n], &y[..n]);
    Agreement {
        rmse: mean(&|i| (x[i] - y[i]).powi(2)).sqrt(),
        bias: mean(&|i| x[i] - y[i]),
        rmse_affine: mean(&|i| (slope * x[i] + offset - y[i]).powi(2)).sqrt(),
        slope,
        offset,
        pearson: pearson(&x[..n], &y[..n]),
        spearman: spearman(&x[..n], &y[..n]),
        n,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranks_average_ties() {
        assert_eq!(ranks(&[1.0, 2.0, 2.0, 3.0]), vec![1.0, 2.5, 2.5, 4.0]);
        assert_eq!(ranks(&[0.3, 0.1, 0.2]), vec![3.0, 1.0, 2.0]);
        assert_eq!(ranks(&[5.0; 4]), vec![2.5; 4]);
        assert!(ranks(&[]).is_empty());
    }

    #[test]
    fn spearman_is_one_for_monotone_maps_and_minus_one_for_reversals() {
        let x: Vec<f64> = (0..50)
            .map(|i| (i as f64 * 0.37).sin() + i as f64 * 0.1)
            .collect();
        let up: Vec<f64> = x.iter().map(|v| (3.0 * v).exp()).collect();
        let down: Vec<f64> = x.iter().map(|v| -v * v * v).collect();
        assert!((spearman(&x, &up) - 1.0).abs() < 1e-12);
        assert!((spearman(&x, &down) + 1.0).abs() < 1e-12);
        // Pearson is below 1 for the non-linear map, Spearman is not.
        assert!(pearson(&x, &up) < 0.99);
        // A known answer with ties: x = [1, 2, 2, 3], y = [1, 3, 2, 4] ranks [1, 2.5, 2.5, 4]
        // and [1, 3, 2, 4]: rho = 4.5 / sqrt(4.5 * 5) = 0.948683...
        let r = spearman(&[1.0, 2.0, 2.0, 3.0], &[1.0, 3.0, 2.0, 4.0]);
        assert!((r - 4.5 / (4.5f64 * 5.0).sqrt()).abs() < 1e-12, "{r}");
        assert!(spearman(&[1.0, 1.0, 1.0], &[1.0, 2.0, 3.0]).is_nan());
    }

    #[test]
    fn pearson_of_a_known_pair() {
        // x = [1, 2, 3, 4], y = [2, 1, 4, 3]: cov 0.8 / sqrt(1.25 * 1.25) = 0.6.
        let r = pearson(&[1.0, 2.0, 3.0, 4.0], &[2.0, 1.0, 4.0, 3.0]);
        assert!((r - 0.6).abs() < 1e-12, "{r}");
    }

    #[test]
    fn the_affine_rmse_of_an_exact_affine_map_is_zero() {
        let x: Vec<f64> = (0..20).map(|i| (i as f64).sqrt()).collect();
        let y: Vec<f64> = x.iter().map(|v| 0.4 * v - 0.25).collect();
        let a = agreement(&x, &y);
        assert!(a.rmse_affine < 1e-12, "{a:?}");
        assert!((a.slope - 0.4).abs() < 1e-12 && (a.offset + 0.25).abs() < 1e-12);
        assert!((a.spearman - 1.0).abs() < 1e-12 && (a.pearson - 1.0).abs() < 1e-12);
        // Raw RMSE and bias of a constant shift.
        let z: Vec<f64> = x.iter().map(|v| v + 0.1).collect();
        let b = agreement(&z, &x);
        assert!((b.rmse - 0.1).abs() < 1e-12 && (b.bias - 0.1).abs() < 1e-12);
        assert!(b.rmse_affine < 1e-12);
        // A constant estimate: the best map is the reference's mean, its RMSE the spread.
        let c = agreement(&[0.5; 4], &[0.0, 1.0, 0.0, 1.0]);
        assert_eq!((c.slope, c.offset), (0.0, 0.5));
        assert!((c.rmse_affine - 0.5).abs() < 1e-12 && c.spearman.is_nan());
        assert_eq!(c.n, 4);
        assert!(agreement(&[], &[]).rmse.is_nan());
    }

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
