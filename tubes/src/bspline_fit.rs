//! Streamline approximation by cubic B-splines without wiggles: Schott et al., "Ambient
//! Occlusion Effects for Combined Volumes and Tubular Geometry" (IEEE TVCG), section 4.1,
//! following the iterative fitting of Martin, Cohen and Kirby (2009) that it cites.
//!
//! # The curve
//! Clamped cubic B-splines with uniform interior knots on [0, 1]: `m >= 4` control points,
//! knots `0,0,0,0, 1/(m-3), ..., (m-4)/(m-3), 1,1,1,1`, evaluated by de Boor's algorithm
//! (Cox-de Boor recursion, `BSpline::eval_d_de_boor`); in closed form where the knots allow:
//! the uniform cubic basis on interior spans, and on the first and last three spans of a curve
//! of at least 8 spans the polynomials `edge_basis` derives once from the recursion (test
//! `the_edge_spans_polynomials_match_de_boor`).
//!
//! # Fitting (progressive iterative approximation)
//! Start from Schoenberg's variation-diminishing spline: the samples themselves are the control
//! points (`P^0 = Q`), and sample `i` is paired with the Greville abscissa
//! `xi_i = (u_{i+1} + u_{i+2} + u_{i+3}) / 3` of control point `i`. Then iterate
//! `P_i <- P_i + w (Q_i - C(xi_i))` until the largest `|Q_i - C(xi_i)|` is at most `epsilon`
//! (or an iteration cap). Pairing with the Greville abscissae is what makes the start
//! variation-diminishing (the curve lies in the control polygon's hull and crosses no plane more
//! often than it), and with it the collocation matrix is banded, totally positive and
//! nonsingular, so the iteration converges towards the interpolant; it stops as soon as the
//! samples are within `epsilon`, i.e. it moves the curve only as far towards the samples as the
//! tolerance demands and adds no oscillation of its own. `w = 1` is the classic PIA; we use the
//! weighted PIA's `w = 2 / (1 + lambda_min)` with the smallest eigenvalue of the cubic
//! collocation matrix at the Greville abscissae taken as 2/3 (its interior rows are
//! `(1/6, 2/3, 1/6)`, eigenvalues in `[1/3, 1]`, so `w = 1.5`, safely below the divergence bound
//! `2 / lambda_max = 2`).
//!
//! # Reduction (the paper's data reduction)
//! `gamma_1` is the fit with `n` control points. Curve `gamma_i` takes `m_i = floor(n / 2^(i-1))`
//! samples of `gamma_{i-1}` and is fitted to them as above. The paper samples at uniform
//! parameters; we sample at the Greville abscissae of the new curve instead, which are uniform in
//! the interior but compressed at the clamped ends, so that sample `j` and control point `j`
//! start paired exactly as in Schoenberg's spline. With uniform samples the clamped ends distort
//! the parametrisation and the fit bulges there (measured on a circle of radius 10, 200 samples:
//! 0.0053 against 0.0014 at 50 control points). The halving
//! continues while the largest distance from the *original* samples to the new curve (each
//! sample projected onto the curve by Newton steps from the parameter carried over from the
//! previous level) stays within `epsilon`. The last curve within `epsilon` is kept.
//!
//! # Deviation: bound first, project only where needed
//! The distance `|C(t_i) - Q_i|` to the curve point at a sample's carried parameter `t_i` is an
//! upper bound of the sample's distance to the curve. A halving step is accepted when every
//! bound is within `epsilon`; only samples whose bound exceeds it are projected (Newton on
//! `(C(t) - Q) . C'(t) = 0`, [`BSpline::project`]), and the step is refused as soon as one
//! projected distance exceeds `epsilon` (`within`). The reported largest deviation of the kept
//! curve is exact, by branch and bound (`max_deviation`): project the sample with the largest
//! bound, then only the samples whose bound exceeds the largest distance found so far; no
//! other sample can be farther. The collocation rows of the PIA (span and four basis values at
//! each Greville abscissa) depend only on the number of control points and are cached per
//! thread.
//!
//! # Least squares (for comparison)
//! The same clamped cubic with a given number of control points, fitted to the samples at
//! chord-length parameters by the normal equations (banded, solved by Cholesky). Least squares
//! minimises the squared error and can overshoot between samples: the wiggles of the paper's
//! Fig. 7b and 9. [`wiggle`] measures them as total absolute curvature relative to the polyline's
//! total turning.

use glam::DVec3;

/// A clamped cubic B-spline with uniform interior knots on [0, 1].
#[derive(Clone, Debug, PartialEq)]
pub struct BSpline {
    pub control: Vec<DVec3>,
}

/// The fewest spans for which [`edge_basis`] holds: the first three spans' basis functions
/// then reach no knot of the far end's clamp (in units of a span the knots around spans 0-2
/// are 0, 0, 0, 0, 1, ..., 5, and the last three spans mirror them).
const EDGE_MIN_SPANS: usize = 8;

/// Basis values, `d/du` and `d2/du2` in local coordinate `u` of the four basis functions of span
/// `j` of a clamped uniform cubic spline of `spans` spans, when `j` is one of the first or last
/// three spans and `spans >= EDGE_MIN_SPANS` (else `None`): polynomials in `u` whose
/// coefficients are derived once from Cox-de Boor ([`edge_polynomials`]); the last spans mirror
/// the first ones (`N_{spans + 2 - i}(t) = N_i(1 - t)` on the symmetric knots). Four to five
/// times cheaper than Cox-de Boor, whose divisions dominated the fits' projections.
#[inline]
fn edge_basis(j: usize, spans: usize, u: f64) -> Option<([f64; 4], [f64; 4], [f64; 4])> {
    if spans < EDGE_MIN_SPANS {
        return None;
    }
    let (m, mirror) = if j < 3 {
        (j, false)
    } else if j + 3 >= spans {
        (spans - 1 - j, true)
    } else {
        return None;
    };
    let x = if mirror { 1.0 - u } else { u };
    let poly = &edge_polynomials()[m];
    let mut b = [0.0; 4];
    let mut d = [0.0; 4];
    let mut dd = [0.0; 4];
    for a in 0..4 {
        let [c0, c1, c2, c3] = poly[a];
        b[a] = c0 + x * (c1 + x * (c2 + x * c3));
        d[a] = c1 + x * (2.0 * c2 + x * 3.0 * c3);
        dd[a] = 2.0 * c2 + 6.0 * c3 * x;
    }
    if mirror {
        b.reverse();
        d.reverse();
        dd.reverse();
        // d/du of N(1 - u) is -N'(1 - u).
        d = d.map(|x| -x);
    }
    Some((b, d, dd))
}

/// Per span m = 0, 1, 2 of a clamped uniform cubic spline and per basis function a = 0..3 of
/// the span (control point m + a), the coefficients of `u^0 .. u^3` in the span's local `u`:
/// interpolated through Cox-de Boor's values at u = 0, 1/4, 1/2, 3/4 on a spline of
/// [`EDGE_MIN_SPANS`] spans (exact for cubics, to rounding).
fn edge_polynomials() -> &'static [[[f64; 4]; 4]; 3] {
    static TABLE: std::sync::OnceLock<[[[f64; 4]; 4]; 3]> = std::sync::OnceLock::new();
    TABLE.get_or_init(|| {
        let reference = BSpline::new(vec![DVec3::ZERO; EDGE_MIN_SPANS + 3]);
        let s = EDGE_MIN_SPANS as f64;
        let nodes = [0.0, 0.25, 0.5, 0.75];
        // Lagrange basis polynomials through the nodes, as monomial coefficients.
        let lagrange: Vec<[f64; 4]> = (0..4)
            .map(|q| {
                let mut c = [1.0, 0.0, 0.0, 0.0];
                let mut scale = 1.0;
                for (r, &xr) in nodes.iter().enumerate() {
                    if r == q {
                        continue;
                    }
                    // c *= (u - xr)
                    let mut next = [0.0; 4];
                    for k in 0..3 {
                        next[k + 1] += c[k];
                        next[k] -= xr * c[k];
                    }
                    c = next;
                    scale *= nodes[q] - xr;
                }
                c.map(|x| x / scale)
            })
            .collect();
        let mut table = [[[0.0; 4]; 4]; 3];
        for (m, span) in table.iter_mut().enumerate() {
            for (q, &x) in nodes.iter().enumerate() {
                let (first, n) = reference.basis_de_boor((m as f64 + x) / s);
                debug_assert_eq!(first, m);
                for (a, coeffs) in span.iter_mut().enumerate() {
                    for k in 0..4 {
                        coeffs[k] += n[3][a] * lagrange[q][k];
                    }
                }
            }
        }
        table
    })
}

impl BSpline {
    pub fn new(control: Vec<DVec3>) -> Self {
        assert!(
            control.len() >= 4,
            "a cubic B-spline needs 4 control points"
        );
        BSpline { control }
    }

    /// Number of non-empty knot spans.
    pub fn spans(&self) -> usize {
        self.control.len() - 3
    }

    fn knot(&self, i: isize) -> f64 {
        let s = self.spans() as isize;
        (i - 3).clamp(0, s) as f64 / s as f64
    }

    /// Greville abscissa of control point `i`.
    pub fn greville(&self, i: usize) -> f64 {
        let i = i as isize;
        (self.knot(i + 1) + self.knot(i + 2) + self.knot(i + 3)) / 3.0
    }

    /// Span index and local coordinate of a parameter.
    fn locate(&self, t: f64) -> usize {
        let s = self.spans();
        // Non-negative after the clamp, so truncation is the floor.
        ((t.clamp(0.0, 1.0) * s as f64) as usize).min(s - 1)
    }

    /// Point and first two derivatives at `t` (de Boor with derivatives by differencing the
    /// control points).
    pub fn eval(&self, t: f64) -> DVec3 {
        let t = t.clamp(0.0, 1.0);
        let sp = self.spans();
        let j = self.locate(t);
        if j >= 3 && j + 4 <= sp {
            // Interior span: the uniform cubic basis in closed form (as in `eval_d`).
            let u = t * sp as f64 - j as f64;
            let v = 1.0 - u;
            let (u2, u3) = (u * u, u * u * u);
            let p = &self.control[j..j + 4];
            return p[0] * (v * v * v / 6.0)
                + p[1] * ((3.0 * u3 - 6.0 * u2 + 4.0) / 6.0)
                + p[2] * ((-3.0 * u3 + 3.0 * u2 + 3.0 * u + 1.0) / 6.0)
                + p[3] * (u3 / 6.0);
        }
        if let Some((b, _, _)) = edge_basis(j, sp, t * sp as f64 - j as f64) {
            let p = &self.control[j..j + 4];
            return p[0] * b[0] + p[1] * b[1] + p[2] * b[2] + p[3] * b[3];
        }
        self.eval_d_de_boor(t).0
    }

    /// `(C(t), C'(t), C''(t))`.
    pub fn eval_d(&self, t: f64) -> (DVec3, DVec3, DVec3) {
        let t = t.clamp(0.0, 1.0);
        let sp = self.spans();
        let j = self.locate(t);
        let s = sp as f64;
        let u = t * s - j as f64;
        let basis = if j >= 3 && j + 4 <= sp {
            // Interior span: all knots around it are uniform, so the basis is the uniform cubic
            // B-spline's, in closed form (derivatives scale by the number of spans).
            let (u2, u3) = (u * u, u * u * u);
            let v = 1.0 - u;
            Some((
                [
                    v * v * v / 6.0,
                    (3.0 * u3 - 6.0 * u2 + 4.0) / 6.0,
                    (-3.0 * u3 + 3.0 * u2 + 3.0 * u + 1.0) / 6.0,
                    u3 / 6.0,
                ],
                [
                    -v * v / 2.0,
                    (3.0 * u2 - 4.0 * u) / 2.0,
                    (-3.0 * u2 + 2.0 * u + 1.0) / 2.0,
                    u2 / 2.0,
                ],
                [v, 3.0 * u - 2.0, -3.0 * u + 1.0, u],
            ))
        } else {
            edge_basis(j, sp, u)
        };
        if let Some((b, d, dd)) = basis {
            let p = &self.control[j..j + 4];
            let c = p[0] * b[0] + p[1] * b[1] + p[2] * b[2] + p[3] * b[3];
            let c1 = (p[0] * d[0] + p[1] * d[1] + p[2] * d[2] + p[3] * d[3]) * s;
            let c2 = (p[0] * dd[0] + p[1] * dd[1] + p[2] * dd[2] + p[3] * dd[3]) * (s * s);
            return (c, c1, c2);
        }
        self.eval_d_de_boor(t)
    }

    /// [`BSpline::eval_d`] by Cox-de Boor on the clamped knots (any span, any number of spans).
    fn eval_d_de_boor(&self, t: f64) -> (DVec3, DVec3, DVec3) {
        let (idx, n) = self.basis_de_boor(t);
        let u = |i: usize| self.knot(i as isize);
        let p = &self.control;
        let c =
            p[idx] * n[3][0] + p[idx + 1] * n[3][1] + p[idx + 2] * n[3][2] + p[idx + 3] * n[3][3];
        // Derivatives: the curve's derivative is a quadratic B-spline with control points
        // 3 (P_{i+1} - P_i) / (u_{i+4} - u_{i+1}); evaluate with the degree-2 basis.
        let d1 = |i: usize| {
            let den = u(i + 4) - u(i + 1);
            if den > 0.0 {
                (p[i + 1] - p[i]) * (3.0 / den)
            } else {
                DVec3::ZERO
            }
        };
        let (e0, e1, e2) = (d1(idx), d1(idx + 1), d1(idx + 2));
        let cd = e0 * n[2][0] + e1 * n[2][1] + e2 * n[2][2];
        // Second derivative: linear B-spline of 2 (D_{i+1} - D_i) / (u_{i+4} - u_{i+2}).
        let d2 = |i: usize, a: DVec3, b: DVec3| {
            let den = u(i + 4) - u(i + 2);
            if den > 0.0 {
                (b - a) * (2.0 / den)
            } else {
                DVec3::ZERO
            }
        };
        let cdd = d2(idx, e0, e1) * n[1][0] + d2(idx + 1, e1, e2) * n[1][1];
        (c, cd, cdd)
    }

    /// The first control point of `t`'s span and the Cox-de Boor basis values of degrees 0 to
    /// 3 there (`n[p][a]`: degree p, basis function `first + 3 - p + a`).
    fn basis_de_boor(&self, t: f64) -> (usize, [[f64; 4]; 4]) {
        let k = self.locate(t) + 3; // knot interval [u_k, u_{k+1})
        let u = |i: usize| self.knot(i as isize);
        let mut n = [[0.0f64; 4]; 4];
        n[0][0] = 1.0;
        let mut left = [0.0; 4];
        let mut right = [0.0; 4];
        for p in 1..=3 {
            left[p] = t - u(k + 1 - p);
            right[p] = u(k + p) - t;
            let mut saved = 0.0;
            for r in 0..p {
                let denom = right[r + 1] + left[p - r];
                let temp = if denom != 0.0 {
                    n[p - 1][r] / denom
                } else {
                    0.0
                };
                n[p][r] = saved + right[r + 1] * temp;
                saved = left[p - r] * temp;
            }
            n[p][p] = saved;
        }
        (k - 3, n)
    }

    /// Curvature at `t`.
    pub fn curvature(&self, t: f64) -> f64 {
        let (_, d1, d2) = self.eval_d(t);
        let l = d1.length();
        if l < 1e-300 {
            0.0
        } else {
            d1.cross(d2).length() / (l * l * l)
        }
    }

    /// Closest parameter to `x` near `t0` (Newton on `(C(t) - x) . C'(t) = 0`, steps clamped to
    /// half a span); falls back to `t0` when Newton ends farther away than it started.
    pub fn project(&self, x: DVec3, t0: f64) -> (f64, f64) {
        self.project_until(x, t0, -1.0)
    }

    /// [`Self::project`], stopping at the first iterate whose distance is at most `enough`
    /// (a curve point that near settles whether `x` is within `enough` of the curve).
    pub fn project_until(&self, x: DVec3, t0: f64, enough: f64) -> (f64, f64) {
        let t0 = t0.clamp(0.0, 1.0);
        let max_step = 0.5 / self.spans() as f64;
        let mut t = t0;
        let mut d0 = f64::NAN;
        let mut best = (t0, f64::INFINITY);
        for it in 0..5 {
            let (c, d1, d2) = self.eval_d(t);
            let r = c - x;
            let dist = r.length();
            if it == 0 {
                d0 = dist;
            }
            if dist < best.1 {
                best = (t, dist);
            }
            if dist <= enough {
                break;
            }
            let g = r.dot(d1);
            let h = d1.length_squared() + r.dot(d2);
            if h <= 1e-300 {
                break;
            }
            let nt = (t - (g / h).clamp(-max_step, max_step)).clamp(0.0, 1.0);
            if (nt - t).abs() < 1e-7 * max_step {
                break;
            }
            t = nt;
        }
        let _ = d0;
        best
    }
}

/// Removes NaN points and repeated points (closer than `1e-9` of the local scale); returns the
/// cleaned polyline and the number of dropped points.
pub fn clean(points: &[DVec3]) -> (Vec<DVec3>, usize) {
    let mut out: Vec<DVec3> = Vec::with_capacity(points.len());
    for &p in points {
        if !p.is_finite() {
            continue;
        }
        if let Some(&q) = out.last() {
            if (p - q).length() <= 1e-9 * (1.0 + p.abs().max_element()) {
                continue;
            }
        }
        out.push(p);
    }
    let dropped = points.len() - out.len();
    (out, dropped)
}

/// Points evenly spaced along a polyline's arc length (at least two input points).
pub fn resample_polyline(points: &[DVec3], n: usize) -> Vec<DVec3> {
    let mut cum = vec![0.0];
    for w in points.windows(2) {
        cum.push(cum.last().unwrap() + (w[1] - w[0]).length());
    }
    let total = *cum.last().unwrap();
    (0..n)
        .map(|k| {
            let s = total * k as f64 / (n - 1) as f64;
            let i = cum.partition_point(|&c| c <= s).clamp(1, points.len() - 1);
            let (a, b) = (cum[i - 1], cum[i]);
            let f = if b > a { (s - a) / (b - a) } else { 0.0 };
            points[i - 1].lerp(points[i], f)
        })
        .collect()
}

/// PIA fit of `samples` (at least 4) with as many control points, to within `epsilon`.
///
/// The curve is evaluated at the Greville abscissae through the banded collocation matrix
/// (at most four non-zero basis values per row, computed once), so an iteration costs a few
/// multiply-adds per control point.
pub fn pia(samples: &[DVec3], epsilon: f64, max_iter: usize) -> BSpline {
    let m = samples.len();
    let mut curve = BSpline::new(samples.to_vec());
    let rows = collocation_rows(m);
    let w = 1.5;
    let eps2 = epsilon * epsilon;
    let mut res = vec![DVec3::ZERO; m];
    for _ in 0..max_iter {
        let mut worst = 0.0f64;
        for (i, &(k, b)) in rows.iter().enumerate() {
            let p = &curve.control;
            let c = p[k] * b[0] + p[k + 1] * b[1] + p[k + 2] * b[2] + p[k + 3] * b[3];
            let r = samples[i] - c;
            worst = worst.max(r.length_squared());
            res[i] = r;
        }
        if worst <= eps2 {
            break;
        }
        for (p, r) in curve.control.iter_mut().zip(&res) {
            *p += *r * w;
        }
    }
    curve
}

/// The span and the four basis values at each Greville abscissa of a spline.
type Rows = std::rc::Rc<Vec<(usize, [f64; 4])>>;

thread_local! {
    /// Collocation rows by number of control points: they depend on nothing else (the knots are
    /// uniform and clamped), and polylines of one tractogram mostly share their lengths.
    static ROWS: std::cell::RefCell<std::collections::HashMap<usize, Rows>> = Default::default();
}

/// The span and the four basis values at each Greville abscissa of an `m`-point spline.
fn collocation_rows(m: usize) -> Rows {
    ROWS.with(|cache| {
        let mut cache = cache.borrow_mut();
        if cache.len() > 4096 {
            cache.clear();
        }
        cache
            .entry(m)
            .or_insert_with(|| {
                let curve = BSpline::new(vec![DVec3::ZERO; m]);
                std::rc::Rc::new(
                    (0..m)
                        .map(|i| {
                            let t = curve.greville(i);
                            (curve.locate(t), basis_weights(&curve, t))
                        })
                        .collect(),
                )
            })
            .clone()
    })
}

/// Options of [`fit`].
#[derive(Clone, Copy, Debug)]
pub struct FitOptions {
    pub epsilon: f64,
    pub method: FitMethod,
    pub max_iterations: usize,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FitMethod {
    /// The paper's PIA fit with halving reduction.
    Iterative,
    /// Least squares with the same number of control points the iterative method found.
    LeastSquares,
    /// The samples as control points (Schoenberg's spline), no fitting.
    None,
}

/// A fitted curve and what it cost.
#[derive(Clone, Debug)]
pub struct Fit {
    pub curve: BSpline,
    /// Largest distance from an input sample to the curve.
    pub max_deviation: f64,
    /// Parameter of each input sample's projection.
    pub sample_params: Vec<f64>,
}

/// Largest distance of `points` to `curve`, projecting from the given start parameters; stops
/// as soon as a distance exceeds `limit` (the answer is then just "more than `limit`").
fn deviation(curve: &BSpline, points: &[DVec3], guess: &[f64], limit: f64) -> (f64, Vec<f64>) {
    let mut worst = 0.0f64;
    let mut params = Vec::with_capacity(points.len());
    for (&x, &t0) in points.iter().zip(guess) {
        let (t, d) = curve.project(x, t0);
        worst = worst.max(d);
        params.push(t);
        if worst > limit {
            break;
        }
    }
    (worst, params)
}

/// The largest distance of `points` to `curve`, projecting as few points as possible: the
/// distance to the curve point at the carried parameter bounds a point's distance to the curve
/// from above, so after projecting the point with the largest bound, only points whose bound
/// exceeds the largest projected distance so far can raise the maximum; the rest are not
/// projected (their parameters stay the carried ones). The result is the exact maximum (up to
/// Newton's convergence). Returns the distance and the parameters.
fn max_deviation(curve: &BSpline, points: &[DVec3], guess: &[f64]) -> (f64, Vec<f64>) {
    let mut params = guess.to_vec();
    // Squared bounds: no square root unless a point is projected.
    let bounds: Vec<f64> = points
        .iter()
        .zip(guess)
        .map(|(&x, &t)| (curve.eval(t) - x).length_squared())
        .collect();
    let Some(top) = (0..bounds.len()).max_by(|&a, &b| bounds[a].total_cmp(&bounds[b])) else {
        return (0.0, params);
    };
    let mut best2 = 0.0f64;
    let project = |i: usize, params: &mut Vec<f64>| {
        let (t, d) = curve.project(points[i], guess[i]);
        // Newton never ends farther than it started (it keeps its best iterate).
        let d2 = (d * d).min(bounds[i]);
        if d * d <= bounds[i] {
            params[i] = t;
        }
        d2
    };
    best2 = best2.max(project(top, &mut params));
    for (i, &b) in bounds.iter().enumerate() {
        if i != top && b > best2 {
            best2 = best2.max(project(i, &mut params));
        }
    }
    (best2.sqrt(), params)
}

/// Whether every point is within `limit` of `curve`: the distance to the curve point at the
/// carried parameter is an upper bound of the distance to the curve, so points are projected
/// (Newton) only when that bound exceeds the limit, and only until an iterate is within it
/// (its parameter is carried on; the reported deviation is projected afresh at the end). Returns the largest bound and the
/// parameters, or `None` as soon as a point is farther than `limit`.
fn within(curve: &BSpline, points: &[DVec3], guess: &[f64], limit: f64) -> Option<(f64, Vec<f64>)> {
    let mut worst2 = 0.0f64;
    let mut params = Vec::with_capacity(points.len());
    let limit2 = limit * limit;
    for (&x, &t0) in points.iter().zip(guess) {
        let mut d2 = (curve.eval(t0) - x).length_squared();
        let mut t = t0;
        if d2 > limit2 {
            let (tp, d) = curve.project_until(x, t0, limit);
            if d > limit {
                return None;
            }
            (t, d2) = (tp, d * d);
        }
        worst2 = worst2.max(d2);
        params.push(t);
    }
    Some((worst2.sqrt(), params))
}

/// Fits a cleaned polyline of at least two points.
pub fn fit(points: &[DVec3], opts: &FitOptions) -> Fit {
    assert!(points.len() >= 2);
    // Fewer than four samples: evenly along the polyline (exact for two).
    let base: Vec<DVec3> = if points.len() < 4 {
        resample_polyline(points, 4)
    } else {
        points.to_vec()
    };
    match opts.method {
        FitMethod::None => {
            let curve = BSpline::new(base.clone());
            let guess: Vec<f64> = chord_params(points);
            let (d, p) = deviation(&curve, points, &guess, f64::INFINITY);
            Fit {
                curve,
                max_deviation: d,
                sample_params: p,
            }
        }
        FitMethod::Iterative | FitMethod::LeastSquares => {
            let mut curve = pia(&base, opts.epsilon * 0.2, opts.max_iterations);
            // Parameters of the original samples on gamma_1: the Greville abscissae (or chord
            // length when the polyline was resampled).
            let mut guess: Vec<f64> = if points.len() < 4 {
                chord_params(points)
            } else {
                (0..points.len()).map(|i| curve.greville(i)).collect()
            };
            // Sample i sits at the Greville abscissa i of gamma_1 (to within the PIA tolerance): the
            // projections start there, and are computed once, for the curve that is kept.
            let (mut dev, mut params) = (f64::NAN, guess.clone());
            let mut m = base.len();
            let mut reduced = false;
            while m / 2 >= 4 {
                let m2 = m / 2;
                // Sample the old curve at the new curve's Greville abscissae (see the module doc),
                // so that sample j and control point j start paired, as in Schoenberg's spline.
                let probe = BSpline::new(vec![DVec3::ZERO; m2]);
                let g: Vec<f64> = (0..m2).map(|j| probe.greville(j)).collect();
                let samples: Vec<DVec3> = g.iter().map(|&t| curve.eval(t)).collect();
                let next = pia(&samples, opts.epsilon * 0.2, opts.max_iterations);
                // A point at parameter t of the old curve is sampled at the same parameter of the
                // new one: carry the projections' parameters over unchanged.
                let carried: Vec<f64> = params.clone();
                let Some((d2, p2)) = within(&next, points, &carried, opts.epsilon) else {
                    break;
                };
                curve = next;
                dev = d2;
                params = p2;
                reduced = true;
                guess = carried;
                m = m2;
            }
            let _ = guess;
            // The bounds above are upper bounds: report the true largest distance.
            let _ = (reduced, dev);
            (dev, params) = max_deviation(&curve, points, &params);
            if opts.method == FitMethod::LeastSquares {
                let ls = least_squares(points, curve.control.len());
                let (d, p) = deviation(&ls, points, &chord_params(points), f64::INFINITY);
                return Fit {
                    curve: ls,
                    max_deviation: d,
                    sample_params: p,
                };
            }
            Fit {
                curve,
                max_deviation: dev,
                sample_params: params,
            }
        }
    }
}

/// Chord-length parameters in [0, 1].
pub fn chord_params(points: &[DVec3]) -> Vec<f64> {
    let mut cum = vec![0.0];
    for w in points.windows(2) {
        cum.push(cum.last().unwrap() + (w[1] - w[0]).length());
    }
    let total = cum.last().copied().unwrap_or(0.0).max(1e-300);
    cum.iter().map(|c| c / total).collect()
}

/// Least-squares cubic with `m` control points at chord-length parameters (end points
/// interpolated by the clamped knots' end conditions).
pub fn least_squares(points: &[DVec3], m: usize) -> BSpline {
    let m = m.max(4);
    let t = chord_params(points);
    let basis_curve = BSpline::new(vec![DVec3::ZERO; m]);
    // Normal equations A^T A P = A^T Q with a banded A^T A (bandwidth 4).
    let mut ata = vec![[0.0f64; 4]; m]; // ata[i][d] = (A^T A)[i][i + d]
    let mut atq = vec![DVec3::ZERO; m];
    for (&ti, &q) in t.iter().zip(points) {
        let k = basis_curve.locate(ti);
        let w = basis_weights(&basis_curve, ti);
        for a in 0..4 {
            atq[k + a] += q * w[a];
            for b in a..4 {
                ata[k + a][b - a] += w[a] * w[b];
            }
        }
    }
    // Regularise lightly so spans without samples stay determined.
    for row in ata.iter_mut() {
        row[0] += 1e-12;
    }
    // Banded Cholesky: L with bandwidth 4.
    let mut l = vec![[0.0f64; 4]; m]; // l[i][d] = L[i][i - d]
    for i in 0..m {
        for d in (0..4).rev() {
            if d > i {
                continue;
            }
            let j = i - d;
            let mut sum = if d == 0 { ata[j][0] } else { ata[j][d] };
            for k in 1..4 {
                if k + d < 4 && j >= k {
                    sum -= l[i][d + k] * l[j][k];
                }
            }
            if d == 0 {
                l[i][0] = sum.max(1e-300).sqrt();
            } else {
                l[i][d] = sum / l[j][0];
            }
        }
    }
    // Solve L y = b, L^T x = y.
    let mut y = vec![DVec3::ZERO; m];
    for i in 0..m {
        let mut s = atq[i];
        for d in 1..4 {
            if d <= i {
                s -= y[i - d] * l[i][d];
            }
        }
        y[i] = s / l[i][0];
    }
    let mut x = vec![DVec3::ZERO; m];
    for i in (0..m).rev() {
        let mut s = y[i];
        for d in 1..4 {
            if i + d < m {
                s -= x[i + d] * l[i + d][d];
            }
        }
        x[i] = s / l[i][0];
    }
    BSpline::new(x)
}

/// The four non-zero cubic basis values at `t` (for control points `span .. span + 4`).
fn basis_weights(c: &BSpline, t: f64) -> [f64; 4] {
    let k = c.locate(t);
    let sp = c.spans();
    if k >= 3 && k + 4 <= sp {
        let u = t.clamp(0.0, 1.0) * sp as f64 - k as f64;
        let v = 1.0 - u;
        return [
            v * v * v / 6.0,
            (3.0 * u * u * u - 6.0 * u * u + 4.0) / 6.0,
            (-3.0 * u * u * u + 3.0 * u * u + 3.0 * u + 1.0) / 6.0,
            u * u * u / 6.0,
        ];
    }
    // Evaluate a curve whose control points are unit steps in x, y, z by component: the basis
    // values of the span's four control points (the fourth is the rest of the partition of unity).
    let mut probe = BSpline::new(vec![DVec3::ZERO; c.control.len()]);
    probe.control[k] = DVec3::X;
    probe.control[k + 1] = DVec3::Y;
    probe.control[k + 2] = DVec3::Z;
    let first3 = probe.eval(t);
    [
        first3.x,
        first3.y,
        first3.z,
        1.0 - first3.x - first3.y - first3.z,
    ]
}

/// Wiggle measure: total absolute curvature of the curve (integral of kappa ds, sampled) over
/// the total turning angle of the input polyline. A curve that adds no oscillation stays near 1;
/// overshooting fits exceed it.
pub fn wiggle(curve: &BSpline, polyline: &[DVec3]) -> f64 {
    let turning: f64 = polyline
        .windows(3)
        .map(|w| {
            let (a, b) = (
                (w[1] - w[0]).normalize_or_zero(),
                (w[2] - w[1]).normalize_or_zero(),
            );
            a.dot(b).clamp(-1.0, 1.0).acos()
        })
        .sum();
    let n = 64 * curve.spans();
    let mut total = 0.0;
    for i in 0..n {
        let t = (i as f64 + 0.5) / n as f64;
        let (_, d1, _) = curve.eval_d(t);
        total += curve.curvature(t) * d1.length() / n as f64;
    }
    total / turning.max(1e-12)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn greville_and_endpoints_of_the_clamped_spline() {
        let c = BSpline::new(
            (0..7)
                .map(|i| DVec3::new(i as f64, (i * i) as f64, 0.0))
                .collect(),
        );
        assert_eq!(c.greville(0), 0.0);
        assert_eq!(c.greville(6), 1.0);
        assert!((c.eval(0.0) - c.control[0]).length() < 1e-12);
        assert!((c.eval(1.0) - c.control[6]).length() < 1e-12);
        // Interior uniform rows: C at a knot = (P_{i-1} + 4 P_i + P_{i+1}) / 6.
        let t = c.greville(3);
        let want = (c.control[2] + c.control[3] * 4.0 + c.control[4]) / 6.0;
        assert!((c.eval(t) - want).length() < 1e-12);
        // Derivatives against finite differences.
        for t in [0.1, 0.37, 0.8] {
            let (_, d1, d2) = c.eval_d(t);
            let h = 1e-5;
            let fd1 = (c.eval(t + h) - c.eval(t - h)) / (2.0 * h);
            let fd2 = (c.eval(t + h) - c.eval(t) * 2.0 + c.eval(t - h)) / (h * h);
            assert!((d1 - fd1).length() < 1e-5 * (1.0 + d1.length()));
            assert!((d2 - fd2).length() < 1e-2 * (1.0 + d2.length()));
        }
    }

    /// The edge spans' polynomials (`edge_basis`) give Cox-de Boor's point and derivatives in
    /// the first and last three spans of every spline of 8 spans or more, to rounding; below
    /// 8 spans Cox-de Boor is used as before.
    #[test]
    fn the_edge_spans_polynomials_match_de_boor() {
        for m in [4usize, 7, 8, 9, 11, 16, 37] {
            let c = BSpline::new(
                (0..m)
                    .map(|i| {
                        let x = i as f64;
                        DVec3::new(x + (x * 1.7).sin(), (x * 0.9).cos() * 3.0, (x * x) % 7.0)
                    })
                    .collect(),
            );
            let sp = c.spans();
            assert_eq!(edge_basis(0, sp, 0.5).is_some(), sp >= EDGE_MIN_SPANS);
            for k in 0..=400 {
                let t = k as f64 / 400.0;
                let j = c.locate(t);
                let (p, d1, d2) = c.eval_d(t);
                let (q, e1, e2) = c.eval_d_de_boor(t);
                let scale = 1.0 + q.length() + e1.length() / sp as f64;
                assert!(
                    (p - q).length() < 1e-12 * scale
                        && (d1 - e1).length() < 1e-11 * scale * sp as f64
                        && (d2 - e2).length() < 1e-10 * scale * (sp * sp) as f64,
                    "{m} points, t {t} (span {j}): {p} {d1} {d2} against {q} {e1} {e2}"
                );
                assert!((c.eval(t) - q).length() < 1e-12 * scale, "eval at {t}");
            }
        }
    }

    #[test]
    fn the_closed_form_interior_basis_matches_de_boor() {
        // 20 control points: spans 3..=13 take the closed form; compare with finite differences
        // and with the general recursion's partition of unity at the span borders.
        let c = BSpline::new(
            (0..20)
                .map(|i| DVec3::new(i as f64, ((i * 7) % 5) as f64, (i as f64).sin()))
                .collect(),
        );
        for k in 0..200 {
            let t = k as f64 / 199.0;
            let (_, d1, d2) = c.eval_d(t);
            let h = 1e-6;
            let (a, b) = ((t - h).max(0.0), (t + h).min(1.0));
            let fd1 = (c.eval(b) - c.eval(a)) / (b - a);
            assert!(
                (d1 - fd1).length() < 1e-4 * (1.0 + d1.length()),
                "t {t}: {d1} vs {fd1}"
            );
            let h2 = 1e-4;
            if t > h2 && t < 1.0 - h2 {
                let fd2 = (c.eval(t + h2) - c.eval(t) * 2.0 + c.eval(t - h2)) / (h2 * h2);
                assert!(
                    (d2 - fd2).length() < 1e-2 * (1.0 + d2.length()),
                    "t {t}: {d2} vs {fd2}"
                );
            }
        }
        // Continuity across the border between general and closed-form spans.
        let s = c.spans() as f64;
        for border in [3.0, s - 3.0] {
            let t = border / s;
            assert!((c.eval(t - 1e-12) - c.eval(t + 1e-12)).length() < 1e-9);
        }
    }

    #[test]
    fn a_straight_line_fits_with_four_control_points_exactly() {
        let pts: Vec<DVec3> = (0..50)
            .map(|i| DVec3::new(i as f64 * 0.1, 2.0, -1.0))
            .collect();
        let f = fit(
            &pts,
            &FitOptions {
                epsilon: 1e-3,
                method: FitMethod::Iterative,
                max_iterations: 100,
            },
        );
        assert_eq!(
            f.curve.control.len(),
            6,
            "halving 50 -> 25 -> 12 -> 6 stays exact"
        );
        assert!(f.max_deviation < 1e-6);
    }

    #[test]
    fn a_circle_fits_within_epsilon_and_the_reduction_is_large() {
        let pts: Vec<DVec3> = (0..200)
            .map(|i| {
                let a = i as f64 / 199.0 * 3.0;
                DVec3::new(a.cos() * 10.0, a.sin() * 10.0, 0.0)
            })
            .collect();
        for eps in [0.1, 0.01] {
            let f = fit(
                &pts,
                &FitOptions {
                    epsilon: eps,
                    method: FitMethod::Iterative,
                    max_iterations: 200,
                },
            );
            assert!(f.max_deviation <= eps, "eps {eps}: {}", f.max_deviation);
            assert!(
                f.curve.control.len() <= 50,
                "eps {eps}: {} control points",
                f.curve.control.len()
            );
            // Deviation really is the distance to the circle.
            for i in 0..100 {
                let p = f.curve.eval(i as f64 / 99.0);
                assert!((p.truncate().length() - 10.0).abs() <= eps * 1.5);
            }
        }
    }

    /// `project_until` stops at the first iterate within `enough` (from the start when the start
    /// is), and with a negative `enough` is `project`.
    #[test]
    fn projection_stops_once_the_point_is_near_enough() {
        let c = BSpline::new(
            (0..12)
                .map(|i| {
                    let a = 0.4 * i as f64;
                    DVec3::new(3.0 * a.cos(), 3.0 * a.sin(), 0.3 * a)
                })
                .collect(),
        );
        let x = c.eval(0.37) + DVec3::new(0.0, 0.0, 0.05);
        let full = c.project(x, 0.3);
        assert_eq!(c.project_until(x, 0.3, -1.0), full);
        assert!(
            full.1 <= 0.05 + 1e-9 && (full.0 - 0.37).abs() < 0.02,
            "{full:?}"
        );
        let start = (c.eval(0.3) - x).length();
        assert_eq!(c.project_until(x, 0.3, start), (0.3, start));
        // Between the two: an iterate within `enough`, no farther than the start.
        let (t, d) = c.project_until(x, 0.3, 0.5 * (start + full.1));
        assert!(
            d <= 0.5 * (start + full.1) && d >= full.1 - 1e-12,
            "{t} {d}"
        );
        assert!(((c.eval(t) - x).length() - d).abs() < 1e-12);
    }

    #[test]
    fn reported_deviation_is_the_true_largest_distance() {
        // A helix with a varying pitch (the reduction stops where the tolerance binds) and a
        // straight line sampled unevenly (it reduces to 4 control points, and the carried
        // parameters are far from the projections: bounds well above the true distances).
        let helix: Vec<DVec3> = (0..200)
            .map(|i| {
                let a = i as f64 * 0.05;
                DVec3::new(a.cos() * 3.0, a.sin() * 3.0, 0.1 * a * a)
            })
            .collect();
        let line: Vec<DVec3> = (0..200)
            .map(|i| {
                let a = (i as f64 / 199.0).powi(2) * 10.0;
                DVec3::new(a, 0.5 * a + 1e-3 * (a * 3.0).sin(), -a)
            })
            .collect();
        for (pts, eps) in [
            (&helix, 0.05),
            (&helix, 0.01),
            (&helix, 0.002),
            (&line, 0.01),
        ] {
            let f = fit(
                pts,
                &FitOptions {
                    epsilon: eps,
                    method: FitMethod::Iterative,
                    max_iterations: 200,
                },
            );
            // The true distance of each sample to the curve, by dense sampling then Newton.
            let n = 20_000;
            let truth = pts
                .iter()
                .map(|&x| {
                    let (mut bt, mut bd) = (0.0, f64::INFINITY);
                    for k in 0..=n {
                        let t = k as f64 / n as f64;
                        let d = (f.curve.eval(t) - x).length();
                        if d < bd {
                            (bt, bd) = (t, d);
                        }
                    }
                    f.curve.project(x, bt).1.min(bd)
                })
                .fold(0.0f64, f64::max);
            assert!(f.max_deviation <= eps, "eps {eps}: {}", f.max_deviation);
            assert!(
                (f.max_deviation - truth).abs() <= 1e-6 * eps,
                "eps {eps}: reported {} vs true {truth}",
                f.max_deviation
            );
        }
    }

    #[test]
    fn least_squares_wiggles_more_than_the_iterative_fit_on_noisy_samples() {
        // A noisy straight line: least squares with many control points follows the noise.
        let mut seed = 12345u64;
        let mut rnd = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((seed >> 33) as f64 / (1u64 << 31) as f64) - 0.5
        };
        let pts: Vec<DVec3> = (0..120)
            .map(|i| DVec3::new(i as f64 * 0.1, 0.02 * rnd(), 0.02 * rnd()))
            .collect();
        let opts = FitOptions {
            epsilon: 0.05,
            method: FitMethod::Iterative,
            max_iterations: 200,
        };
        let it = fit(&pts, &opts);
        let ls = least_squares(&pts, 60);
        let (wi, wl) = (wiggle(&it.curve, &pts), wiggle(&ls, &pts));
        assert!(wl > wi, "least squares {wl:.3} vs iterative {wi:.3}");
        assert!(it.max_deviation <= 0.05);
    }
}
