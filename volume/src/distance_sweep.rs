//! Signed distance to an isosurface by fast sweeping (Zhao 2005), as used by Singh, Yuksel and
//! House, "Fast Occlusion Sweeping" (ISVC 2009), section 1.1, Table 1 and eq. (1).
//!
//! # Steps
//! 1. **Classification.** `g = (f - iso)` for `--inside above` (the default: values at or above
//!    the iso level are inside) and `g = (iso - f)` for `--inside below`; inside is `g >= 0`.
//!    NaN samples are outside (and counted); infinite samples keep their side.
//! 2. **Initialisation** (the paper's "open vertices"): every grid vertex with a neighbour (of
//!    its six) on the other side gets a distance estimate from its own sample data and is frozen.
//!    For each axis the nearest crossing along the two incident edges lies at
//!    `d_a = t h_a` with `t = g_p / (g_p - g_q)` (linear interpolation; `t = 1/2` when a sample is
//!    not finite). Three estimates are offered ([`InitMethod`]):
//!    * `Edge`: `min_a d_a` -- the paper's linear interpolation along edges;
//!    * `Plane`: the distance to the local linear surface through the crossings,
//!      `(sum_a d_a^-2)^-1/2`, where an axis without a crossing on its two edges gets
//!      `d_a = max(|g_p| / |slope_a|, h_a)` from the central slope (the crossing lies beyond the
//!      neighbour). Exact for a planar surface; never larger than `Edge`;
//!    * `Gradient`: `|g_p| / |grad g|` with central differences (one-sided at borders and next to
//!      non-finite samples), capped by `Edge`.
//!    `docs/accuracy.md` and the tests measure all three on analytic solids; `Plane` is the
//!    default because it is the most accurate there.
//! 3. **Sweeps.** Eight Gauss-Seidel sweeps in the orders of Table 1 (x fastest), repeated until
//!    the largest change in one round of eight is below `tolerance` (in voxels of the smallest
//!    spacing). Each vertex's new value solves the Godunov upwind discretisation of
//!    `|grad d| = 1`: with `a_x = min(d(P - e_x), d(P + e_x))` (and likewise for y and z; in sweep
//!    `s` the smaller of the two is the Table 1 neighbour once the sweep has passed it) sorted
//!    ascending, take the largest root of `sum_i ((d - a_i) / h_i)^2 = 1` over the growing set of
//!    neighbours, adding the next one while the solution exceeds it. For `h_x = h_y = h_z = h`
//!    this is the intended eq. (1) (the printed one is garbled):
//!    `s1 = a1 + h` if `s1 <= a2`; else `s2 = (a1 + a2 + sqrt(2h^2 - (a1 - a2)^2)) / 2` if
//!    `s2 <= a3`; else `s3 = (a1 + a2 + a3 + sqrt(3h^2 - (a1-a2)^2 - (a1-a3)^2 - (a2-a3)^2)) / 3`.
//!    The general root: with `w_i = h_i^-2`, `A = sum w_i`, `B = sum w_i a_i`,
//!    `C = sum w_i a_i^2 - 1`, `d = (B + sqrt(B^2 - A C)) / A`.
//!    The unsigned distance is swept; the sign comes from the classification at the end.
//!    Distances are in world units (the lengths of the affine's axis vectors; the grid is treated
//!    as orthogonal, which holds for every affine without shear).
//!
//! # Implementation
//! The grid is padded by one ghost layer of `+inf` on every side (no bounds checks in the inner
//! loop), and frozen vertices are stored with their sign bit set, so one `f32` array holds
//! values and the frozen mask (neighbours are read through `abs`).

/// How initial distances next to the surface are estimated (see the module doc).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum InitMethod {
    Edge,
    Plane,
    Gradient,
}

impl std::str::FromStr for InitMethod {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "edge" => Ok(InitMethod::Edge),
            "plane" => Ok(InitMethod::Plane),
            "gradient" => Ok(InitMethod::Gradient),
            _ => Err(format!("unknown initialisation '{s}' (edge, plane, gradient)")),
        }
    }
}

/// Which side of the iso level is inside (negative distance).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Inside {
    /// Values >= iso are inside (the default).
    Above,
    /// Values <= iso are inside.
    Below,
}

/// Options of the distance computation.
#[derive(Clone, Copy, Debug)]
pub struct DistanceOptions {
    pub iso: f32,
    pub inside: Inside,
    pub init: InitMethod,
    /// Convergence tolerance in voxels (of the smallest spacing).
    pub tolerance: f32,
    /// Upper bound on rounds of eight sweeps.
    pub max_iterations: usize,
}

impl Default for DistanceOptions {
    fn default() -> Self {
        DistanceOptions { iso: 0.0, inside: Inside::Above, init: InitMethod::Plane, tolerance: 1e-3, max_iterations: 100 }
    }
}

/// The result of [`classify_and_initialise`]: what the occlusion sweeps and the distance
/// sweeps both start from.
pub struct Initial {
    pub dims: [usize; 3],
    pub spacing: [f32; 3],
    /// Padded `(nx+2)(ny+2)(nz+2)` grid: `+inf` away from the surface, band vertices frozen
    /// (sign bit set, magnitude = distance estimate).
    pub padded: Vec<f32>,
    /// Inside mask per voxel (unpadded, x fastest).
    pub inside: Vec<bool>,
    /// Number of band (initialised) vertices.
    pub band: usize,
    /// Number of NaN samples (treated as outside).
    pub nan_count: usize,
}

/// Result of the distance computation.
pub struct DistanceField {
    pub dims: [usize; 3],
    /// Signed distance in world units, negative inside, x fastest.
    pub distance: Vec<f32>,
    /// Rounds of eight sweeps until the largest change fell below the tolerance.
    pub iterations: usize,
    pub converged: bool,
    pub band: usize,
    pub nan_count: usize,
}

#[inline]
fn pidx(dims: [usize; 3], i: usize, j: usize, k: usize) -> usize {
    // Index into the padded grid of unpadded voxel (i, j, k).
    (i + 1) + (dims[0] + 2) * ((j + 1) + (dims[1] + 2) * (k + 1))
}

/// Classifies samples and initialises the band next to the surface (steps 1 and 2).
pub fn classify_and_initialise(values: &[f32], dims: [usize; 3], spacing: [f32; 3], opts: &DistanceOptions) -> Initial {
    let [nx, ny, nz] = dims;
    let n = nx * ny * nz;
    assert_eq!(values.len(), n, "values do not match dims");
    let sign = if opts.inside == Inside::Above { 1.0f32 } else { -1.0 };
    let g: Vec<f32> = values.iter().map(|&v| if v.is_nan() { f32::NAN } else { sign * (v - opts.iso) }).collect();
    let nan_count = values.iter().filter(|v| v.is_nan()).count();
    let inside: Vec<bool> = g.iter().map(|&x| x >= 0.0).collect(); // NaN compares false: outside
    let (px, py, pz) = (nx + 2, ny + 2, nz + 2);
    let mut padded = vec![f32::INFINITY; px * py * pz];
    let stride = [1isize, nx as isize, (nx * ny) as isize];
    let mut band = 0;
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                let id = i + nx * (j + ny * k);
                let ijk = [i, j, k];
                let me = inside[id];
                let gp = g[id];
                // Nearest crossing per axis.
                let mut da = [f32::INFINITY; 3];
                let mut any = false;
                for a in 0..3 {
                    for dir in [-1isize, 1] {
                        let c = ijk[a] as isize + dir;
                        if c < 0 || c >= dims[a] as isize {
                            continue;
                        }
                        let q = (id as isize + dir * stride[a]) as usize;
                        if inside[q] == me {
                            continue;
                        }
                        let gq = g[q];
                        let t = if gp.is_finite() && gq.is_finite() && gp != gq { (gp / (gp - gq)).clamp(0.0, 1.0) } else { 0.5 };
                        da[a] = da[a].min(t * spacing[a]);
                        any = true;
                    }
                }
                if !any {
                    continue;
                }
                band += 1;
                let edge = da[0].min(da[1]).min(da[2]);
                let d = match opts.init {
                    InitMethod::Edge => edge,
                    InitMethod::Plane => {
                        // Axes without a crossing on their incident edges: extrapolate the
                        // crossing with the central slope (it lies beyond the neighbour, so at
                        // least one spacing away).
                        let mut inv2 = 0.0f32;
                        for a in 0..3 {
                            let d_a = if da[a].is_finite() {
                                da[a]
                            } else {
                                let c = ijk[a] as isize;
                                let at = |c: isize| -> Option<f32> {
                                    if c < 0 || c >= dims[a] as isize {
                                        return None;
                                    }
                                    let v = g[(id as isize + (c - ijk[a] as isize) * stride[a]) as usize];
                                    v.is_finite().then_some(v)
                                };
                                let slope = match (at(c - 1), at(c + 1)) {
                                    (Some(l), Some(h)) => (h - l) / (2.0 * spacing[a]),
                                    (None, Some(h)) if gp.is_finite() => (h - gp) / spacing[a],
                                    (Some(l), None) if gp.is_finite() => (gp - l) / spacing[a],
                                    _ => 0.0,
                                };
                                let e = gp.abs() / slope.abs();
                                let interior = c > 0 && c + 1 < dims[a] as isize;
                                if e.is_finite() {
                                    if interior {
                                        e.max(spacing[a])
                                    } else {
                                        e
                                    }
                                } else {
                                    f32::INFINITY
                                }
                            };
                            inv2 += if d_a > 0.0 { 1.0 / (d_a * d_a) } else { f32::INFINITY };
                        }
                        if inv2.is_infinite() {
                            0.0
                        } else {
                            (1.0 / inv2.sqrt()).min(edge)
                        }
                    }
                    InitMethod::Gradient => {
                        let mut grad2 = 0.0f32;
                        let mut ok = gp.is_finite();
                        for a in 0..3 {
                            let at = |c: isize| -> Option<f32> {
                                if c < 0 || c >= dims[a] as isize {
                                    return None;
                                }
                                let v = g[(id as isize + (c - ijk[a] as isize) * stride[a]) as usize];
                                v.is_finite().then_some(v)
                            };
                            let c = ijk[a] as isize;
                            let (lo, hi) = (at(c - 1), at(c + 1));
                            let der = match (lo, hi) {
                                (Some(l), Some(h)) => (h - l) / (2.0 * spacing[a]),
                                (None, Some(h)) => (h - gp) / spacing[a],
                                (Some(l), None) => (gp - l) / spacing[a],
                                (None, None) => 0.0,
                            };
                            ok &= der.is_finite();
                            grad2 += der * der;
                        }
                        let est = gp.abs() / grad2.sqrt();
                        if ok && est.is_finite() {
                            est.min(edge)
                        } else {
                            edge
                        }
                    }
                };
                // Frozen: sign bit set (also for a distance of exactly 0).
                padded[pidx(dims, i, j, k)] = f32::from_bits(d.max(0.0).to_bits() | 0x8000_0000);
            }
        }
    }
    Initial { dims, spacing, padded, inside, band, nan_count }
}

/// Solves the upwind update for sorted neighbour values (see the module doc).
#[inline(always)]
fn solve(mut a: [f32; 3], mut h: [f32; 3]) -> f32 {
    // Sort ascending by value, carrying spacings.
    if a[1] < a[0] {
        a.swap(0, 1);
        h.swap(0, 1);
    }
    if a[2] < a[1] {
        a.swap(1, 2);
        h.swap(1, 2);
        if a[1] < a[0] {
            a.swap(0, 1);
            h.swap(0, 1);
        }
    }
    let d1 = a[0] + h[0];
    if d1 <= a[1] {
        return d1;
    }
    let (w0, w1) = (1.0 / (h[0] * h[0]), 1.0 / (h[1] * h[1]));
    let aa = w0 + w1;
    let bb = w0 * a[0] + w1 * a[1];
    let cc = w0 * a[0] * a[0] + w1 * a[1] * a[1] - 1.0;
    let disc = bb * bb - aa * cc;
    let d2 = if disc >= 0.0 { (bb + disc.sqrt()) / aa } else { d1 };
    if d2 <= a[2] {
        return d2;
    }
    let w2 = 1.0 / (h[2] * h[2]);
    let aa = aa + w2;
    let bb = bb + w2 * a[2];
    let cc = cc + w2 * a[2] * a[2];
    let disc = bb * bb - aa * cc;
    if disc >= 0.0 {
        (bb + disc.sqrt()) / aa
    } else {
        d2
    }
}

/// One Gauss-Seidel sweep in direction `dir` (signs per axis, Table 1); returns the largest
/// decrease.
fn sweep(grid: &mut [f32], dims: [usize; 3], spacing: [f32; 3], dir: [i32; 3]) -> f32 {
    let [nx, ny, nz] = dims;
    let px = nx + 2;
    let pxy = px * (ny + 2);
    let mut max_change = 0.0f32;
    let ks: Box<dyn Iterator<Item = usize>> = if dir[2] > 0 { Box::new(0..nz) } else { Box::new((0..nz).rev()) };
    for k in ks {
        let js: Box<dyn Iterator<Item = usize>> = if dir[1] > 0 { Box::new(0..ny) } else { Box::new((0..ny).rev()) };
        for j in js {
            let row = pidx(dims, 0, j, k);
            let mut run = |i: usize| {
                let id = row + i;
                let u = grid[id];
                if u.is_sign_negative() {
                    return;
                }
                let ax = grid[id - 1].abs().min(grid[id + 1].abs());
                let ay = grid[id - px].abs().min(grid[id + px].abs());
                let az = grid[id - pxy].abs().min(grid[id + pxy].abs());
                if ax.min(ay).min(az) == f32::INFINITY {
                    return;
                }
                let d = solve([ax, ay, az], spacing);
                if d < u {
                    let change = if u.is_finite() { u - d } else { f32::INFINITY };
                    max_change = max_change.max(change);
                    grid[id] = d;
                }
            };
            if dir[0] > 0 {
                (0..nx).for_each(&mut run);
            } else {
                (0..nx).rev().for_each(&mut run);
            }
        }
    }
    max_change
}

/// Table 1's sweep directions in order.
pub const SWEEP_DIRECTIONS: [[i32; 3]; 8] = [
    [1, 1, 1],
    [-1, 1, 1],
    [1, -1, 1],
    [-1, -1, 1],
    [1, 1, -1],
    [-1, 1, -1],
    [1, -1, -1],
    [-1, -1, -1],
];

/// Sweeps the initial band out to the whole grid and applies the sign (step 3).
pub fn sweep_distance(init: Initial, opts: &DistanceOptions) -> DistanceField {
    let Initial { dims, spacing, mut padded, inside, band, nan_count } = init;
    let hmin = spacing.iter().cloned().fold(f32::INFINITY, f32::min);
    let tol = opts.tolerance * hmin;
    let mut iterations = 0;
    let mut converged = band == 0;
    while !converged && iterations < opts.max_iterations {
        iterations += 1;
        let mut change = 0.0f32;
        for dir in SWEEP_DIRECTIONS {
            change = change.max(sweep(&mut padded, dims, spacing, dir));
        }
        converged = change < tol;
    }
    let [nx, ny, nz] = dims;
    let mut distance = Vec::with_capacity(nx * ny * nz);
    for k in 0..nz {
        for j in 0..ny {
            let row = pidx(dims, 0, j, k);
            for i in 0..nx {
                let d = padded[row + i].abs();
                distance.push(if inside[i + nx * (j + ny * k)] { -d } else { d });
            }
        }
    }
    DistanceField { dims, distance, iterations, converged, band, nan_count }
}

/// Classification, initialisation and sweeps in one call.
pub fn signed_distance(values: &[f32], dims: [usize; 3], spacing: [f32; 3], opts: &DistanceOptions) -> DistanceField {
    sweep_distance(classify_and_initialise(values, dims, spacing, opts), opts)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn isotropic_update_matches_the_papers_eq1() {
        let h = 1.5f32;
        // One neighbour.
        assert_eq!(solve([2.0, 10.0, 10.0], [h; 3]), 3.5);
        // Two neighbours: s2 = (a1 + a2 + sqrt(2h^2 - (a1 - a2)^2)) / 2.
        let (a1, a2) = (2.0f32, 2.5f32);
        let s2 = (a1 + a2 + (2.0 * h * h - (a1 - a2).powi(2)).sqrt()) / 2.0;
        assert!((solve([a2, a1, 100.0], [h; 3]) - s2).abs() < 1e-6);
        // Three neighbours.
        let (a1, a2, a3) = (2.0f32, 2.2f32, 2.3f32);
        let s3 = (a1 + a2 + a3 + (3.0 * h * h - (a1 - a2).powi(2) - (a1 - a3).powi(2) - (a2 - a3).powi(2)).sqrt()) / 3.0;
        assert!((solve([a3, a1, a2], [h; 3]) - s3).abs() < 1e-6);
    }

    #[test]
    fn anisotropic_update_solves_the_quadratic() {
        let h = [3.2f32, 3.2, 1.5];
        let a = [4.0f32, 4.5, 3.9];
        let d = solve(a, h);
        let r: f32 = (0..3).map(|i| ((d - a[i]) / h[i]).powi(2)).sum();
        assert!((r - 1.0).abs() < 1e-5, "residual {r}");
        assert!(d > 4.5);
    }

    #[test]
    fn a_plane_is_exact_with_plane_initialisation() {
        // f = n . x - c, a plane at an oblique angle: every method of the sweep reproduces
        // |n . x - c| up to the first-order scheme's error; the plane init is exact at the band.
        let dims = [24, 20, 16];
        let n = [0.48f32, 0.6, 0.64]; // unit
        let c = 9.0;
        let mut v = Vec::new();
        for k in 0..dims[2] {
            for j in 0..dims[1] {
                for i in 0..dims[0] {
                    v.push(n[0] * i as f32 + n[1] * j as f32 + n[2] * k as f32 - c);
                }
            }
        }
        let opts = DistanceOptions { init: InitMethod::Plane, ..Default::default() };
        let init = classify_and_initialise(&v, dims, [1.0; 3], &opts);
        for (id, &f) in v.iter().enumerate() {
            let (i, j, k) = (id % 24, (id / 24) % 20, id / 480);
            let p = init.padded[pidx(dims, i, j, k)];
            if p.is_sign_negative() {
                assert!((p.abs() - f.abs()).abs() < 1e-5, "band value {} vs {}", p.abs(), f.abs());
            }
        }
        let df = sweep_distance(init, &opts);
        assert!(df.converged);
        // Inside is f >= 0: distance is -f there. The sweep measures the distance to the part of
        // the surface inside the grid, so compare where the perpendicular foot lies inside it.
        let (mut max_err, mut max_int, mut sum) = (0.0f32, 0.0f32, 0.0f32);
        let mut compared = 0;
        for (id, (f, d)) in v.iter().zip(&df.distance).enumerate() {
            let p = [(id % 24) as f32, ((id / 24) % 20) as f32, (id / 480) as f32];
            let foot: Vec<f32> = (0..3).map(|a| p[a] - f * n[a]).collect();
            if (0..3).all(|a| foot[a] >= 0.0 && foot[a] <= (dims[a] - 1) as f32) {
                let e = (d + f).abs();
                max_err = max_err.max(e);
                sum += e;
                compared += 1;
                // Away from the grid faces all three upwind neighbours exist, and there the
                // first-order update is exact for a plane (farther out, the faces' 2-D updates
                // enter the domain of dependence).
                if f.abs() < 2.5 && (0..3).all(|a| p[a] >= 3.0 && p[a] <= (dims[a] - 4) as f32) {
                    max_int = max_int.max(e);
                }
            }
        }
        assert!(compared > 3000, "{compared}");
        assert!(max_int < 5e-3, "interior max error {max_int}");
        // Next to the faces a missing upwind neighbour makes the update two-dimensional.
        assert!(max_err < 0.5 && sum / (compared as f32) < 0.05, "max {max_err}, mean {}", sum / compared as f32);
    }
}
