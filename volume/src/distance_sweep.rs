//! Signed distance to an isosurface by fast sweeping (Zhao 2005), as used by Singh, Yuksel and
//! House, "Fast Occlusion Sweeping" (ISVC 2009), section 1.1, Table 1 and eq. (1).
//!
//! # Steps
//! 1. **Classification.** `g = (f - iso)` for `--inside above` (the default: values at or above
//!    the iso level are inside) and `g = (iso - f)` for `--inside below`; inside is `g >= 0`.
//!    NaN samples are outside (and counted); infinite samples keep their side. Beyond the grid
//!    is outside too, so an object touching the border is closed half a voxel beyond it.
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
//!
//!    `docs/accuracy.md` and the tests measure all three on analytic solids.
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
            _ => Err(format!(
                "unknown initialisation '{s}' (edge, plane, gradient)"
            )),
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

/// How the distance is carried from the band to the rest of the grid.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub enum DistanceMethod {
    /// The distance to the surface point of the nearest band voxel ([`crate::closest_point`]):
    /// the default, one pass per axis whatever the content.
    #[default]
    ClosestPoint,
    /// Fast sweeping (Zhao 2005), the paper's method: rounds of eight Gauss-Seidel sweeps.
    Sweeping,
}

impl std::str::FromStr for DistanceMethod {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "closest-point" => Ok(DistanceMethod::ClosestPoint),
            "sweeping" => Ok(DistanceMethod::Sweeping),
            _ => Err(format!(
                "unknown distance method '{s}' (closest-point, sweeping)"
            )),
        }
    }
}

/// Options of the distance computation.
#[derive(Clone, Copy, Debug)]
pub struct DistanceOptions {
    pub iso: f32,
    pub inside: Inside,
    pub init: InitMethod,
    /// How the band's distances reach the rest of the grid.
    pub method: DistanceMethod,
    /// Convergence tolerance in voxels (of the smallest spacing).
    pub tolerance: f32,
    /// Upper bound on rounds of eight sweeps.
    pub max_iterations: usize,
}

impl DistanceOptions {
    /// Checks the settings' ranges (a NaN tolerance never converged, running every round),
    /// naming the setting.
    pub fn check(&self) -> std::result::Result<(), String> {
        if !self.iso.is_finite() {
            return Err(format!("iso level {}: must be a finite number", self.iso));
        }
        if !(self.tolerance.is_finite() && self.tolerance > 0.0) {
            return Err(format!(
                "tolerance {} voxels: must be a positive number",
                self.tolerance
            ));
        }
        if self.max_iterations == 0 {
            return Err("max iterations 0: must be at least 1".into());
        }
        Ok(())
    }
}

impl Default for DistanceOptions {
    fn default() -> Self {
        DistanceOptions {
            iso: 0.0,
            inside: Inside::Above,
            init: InitMethod::Gradient,
            method: DistanceMethod::ClosestPoint,
            tolerance: 1e-3,
            max_iterations: 100,
        }
    }
}

/// The result of [`classify_and_initialise`]: what the occlusion sweeps and the distance
/// sweeps both start from.
pub struct Initial {
    pub dims: [usize; 3],
    pub spacing: [f32; 3],
    /// Inside mask per voxel (unpadded, x fastest).
    pub inside: Vec<bool>,
    /// Number of band (initialised) vertices.
    pub band: usize,
    /// Number of NaN samples (treated as outside).
    pub nan_count: usize,
    /// The band: its vertices in voxel order, with their initial distances and surface points.
    pub surface: Vec<SurfacePoint>,
    /// The samples' buffer when the caller gave it up ([`classify_and_initialise_owned`]): the
    /// closest-point distance is computed in it instead of in fresh memory. Empty otherwise.
    pub scratch: Vec<f32>,
}

/// One band vertex and the point of the local surface its initial estimate measures to.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfacePoint {
    /// Unpadded voxel index (x fastest).
    pub index: usize,
    /// The initial distance estimate (world units, unsigned): the length of `offset`.
    pub distance: f32,
    /// From the voxel to its surface point, in world units along the grid's axes; its length
    /// is the voxel's initial distance (`Gradient`: along the gradient; `Plane`: the foot on the
    /// local plane; `Edge`, and wherever an estimate falls back to it: along the axis of the
    /// nearest edge crossing).
    pub offset: [f32; 3],
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
    /// Grid rows swept in all (a full sweep is `ny * nz` rows): the work the locking saved.
    pub rows_processed: usize,
}

#[inline]
fn pidx(dims: [usize; 3], i: usize, j: usize, k: usize) -> usize {
    // Index into the padded grid of unpadded voxel (i, j, k).
    (i + 1) + (dims[0] + 2) * ((j + 1) + (dims[1] + 2) * (k + 1))
}

/// [`classify_and_initialise`] giving up the samples: nothing after the classification reads
/// them, so their buffer becomes the distance's (one fresh allocation and its page faults less,
/// a tenth of a 512^3 sweep on a virtual machine).
pub fn classify_and_initialise_owned(
    values: Vec<f32>,
    dims: [usize; 3],
    spacing: [f32; 3],
    opts: &DistanceOptions,
) -> Initial {
    let mut init = classify_and_initialise(&values, dims, spacing, opts);
    init.scratch = values;
    init
}

/// Classifies samples and initialises the band next to the surface (steps 1 and 2).
pub fn classify_and_initialise(
    values: &[f32],
    dims: [usize; 3],
    spacing: [f32; 3],
    opts: &DistanceOptions,
) -> Initial {
    let [nx, ny, nz] = dims;
    let n = nx * ny * nz;
    assert_eq!(values.len(), n, "values do not match dims");
    let sign = if opts.inside == Inside::Above {
        1.0f32
    } else {
        -1.0
    };
    use rayon::prelude::*;
    // g >= 0 inside; NaN stays NaN (outside).
    let gv = |v: f32| sign * (v - opts.iso);
    let g = values;
    let nan_count = values.par_iter().filter(|v| v.is_nan()).count();
    let mut inside = crate::memory::zeroed(n, false);
    inside
        .par_chunks_mut(1 << 16)
        .zip(values.par_chunks(1 << 16))
        .for_each(|(o, v)| {
            for (o, &v) in o.iter_mut().zip(v) {
                *o = gv(v) >= 0.0; // NaN: outside
            }
        });
    let stride = [1isize, nx as isize, (nx * ny) as isize];
    // Planes are independent.
    let plane = |k: usize| -> Vec<SurfacePoint> {
        let mut surface = Vec::new();
        let mut candidate = vec![false; nx];
        for j in 0..ny {
            // Which voxels of the row have a neighbour on the other side (a cheap pass over the
            // masks, vectorised; most rows have none); inside voxels on the grid's border too.
            let r = nx * (j + ny * k);
            let me_row = &inside[r..r + nx];
            let on_border_yz = j == 0 || j + 1 == ny || k == 0 || k + 1 == nz;
            for (c, &m) in candidate.iter_mut().zip(me_row) {
                *c = m & on_border_yz;
            }
            let neighbours = [
                (j > 0).then(|| r - nx),
                (j + 1 < ny).then(|| r + nx),
                (k > 0).then(|| r - nx * ny),
                (k + 1 < nz).then(|| r + nx * ny),
            ];
            for q in neighbours.into_iter().flatten() {
                for ((c, &m), &o) in candidate.iter_mut().zip(me_row).zip(&inside[q..q + nx]) {
                    *c |= m != o;
                }
            }
            for i in 1..nx {
                let d = me_row[i] != me_row[i - 1];
                candidate[i] |= d;
                candidate[i - 1] |= d;
            }
            candidate[0] |= me_row[0];
            candidate[nx - 1] |= me_row[nx - 1];
            for i in (0..nx).filter(|&i| candidate[i]) {
                let id = r + i;
                let ijk = [i, j, k];
                let me = inside[id];
                let gp = gv(g[id]);
                // Nearest crossing per axis, and on which side (-1 or +1) it lies.
                let mut da = [f32::INFINITY; 3];
                let mut side = [0.0f32; 3];
                let mut any = false;
                for a in 0..3 {
                    for dir in [-1isize, 1] {
                        let c = ijk[a] as isize + dir;
                        if c < 0 || c >= dims[a] as isize {
                            // Beyond the grid is outside: an inside sample on the border has a
                            // crossing half a spacing out (the NaN rule), so objects that touch
                            // the border are closed there.
                            if me {
                                if 0.5 * spacing[a] < da[a] {
                                    da[a] = 0.5 * spacing[a];
                                    side[a] = dir as f32;
                                }
                                any = true;
                            }
                            continue;
                        }
                        let q = (id as isize + dir * stride[a]) as usize;
                        if inside[q] == me {
                            continue;
                        }
                        let gq = gv(g[q]);
                        let t = if gp.is_finite() && gq.is_finite() && gp != gq {
                            (gp / (gp - gq)).clamp(0.0, 1.0)
                        } else {
                            0.5
                        };
                        if t * spacing[a] < da[a] {
                            da[a] = t * spacing[a];
                            side[a] = dir as f32;
                        }
                        any = true;
                    }
                }
                if !any {
                    continue;
                }
                let edge = da[0].min(da[1]).min(da[2]);
                let amin = if da[0] == edge {
                    0
                } else if da[1] == edge {
                    1
                } else {
                    2
                };
                let mut edge_offset = [0.0f32; 3];
                edge_offset[amin] = side[amin] * edge;
                // Offset to the surface point: the edge crossing's unless a method finds a
                // nearer point.
                let mut offset = edge_offset;
                let d = match opts.init {
                    InitMethod::Edge => edge,
                    InitMethod::Plane => {
                        // Axes without a crossing on their incident edges: extrapolate the
                        // crossing with the central slope (it lies beyond the neighbour, so at
                        // least one spacing away).
                        let mut inv2 = 0.0f32;
                        // Foot of the plane through the crossings: offset_a = s_a d^2 / d_a.
                        let mut foot = [0.0f32; 3];
                        for a in 0..3 {
                            let d_a = if da[a].is_finite() {
                                foot[a] = side[a] / da[a];
                                da[a]
                            } else {
                                let c = ijk[a] as isize;
                                let at = |c: isize| -> Option<f32> {
                                    if c < 0 || c >= dims[a] as isize {
                                        return None;
                                    }
                                    let v = gv(g[(id as isize + (c - ijk[a] as isize) * stride[a])
                                        as usize]);
                                    v.is_finite().then_some(v)
                                };
                                let slope = match (at(c - 1), at(c + 1)) {
                                    (Some(l), Some(h)) => (h - l) / (2.0 * spacing[a]),
                                    (None, Some(h)) if gp.is_finite() => (h - gp) / spacing[a],
                                    (Some(l), None) if gp.is_finite() => (gp - l) / spacing[a],
                                    _ => 0.0,
                                };
                                let e = gp.abs() / slope.abs();
                                // The surface lies where g falls to 0: downhill inside
                                // (g > 0), uphill outside.
                                let s_a = if (gp > 0.0) == (slope > 0.0) {
                                    -1.0
                                } else {
                                    1.0
                                };
                                let interior = c > 0 && c + 1 < dims[a] as isize;
                                if e.is_finite() {
                                    let e = if interior { e.max(spacing[a]) } else { e };
                                    if e > 0.0 {
                                        foot[a] = s_a / e;
                                    }
                                    e
                                } else {
                                    f32::INFINITY
                                }
                            };
                            inv2 += if d_a > 0.0 {
                                1.0 / (d_a * d_a)
                            } else {
                                f32::INFINITY
                            };
                        }
                        if inv2.is_infinite() {
                            offset = [0.0; 3];
                            0.0
                        } else {
                            let d = 1.0 / inv2.sqrt();
                            if d < edge {
                                offset = foot.map(|f| f * d * d);
                            }
                            d.min(edge)
                        }
                    }
                    InitMethod::Gradient => {
                        let mut grad2 = 0.0f32;
                        let mut grad = [0.0f32; 3];
                        let mut ok = gp.is_finite();
                        for a in 0..3 {
                            let at = |c: isize| -> Option<f32> {
                                if c < 0 || c >= dims[a] as isize {
                                    return None;
                                }
                                let v =
                                    gv(g[(id as isize + (c - ijk[a] as isize) * stride[a])
                                        as usize]);
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
                            grad[a] = der;
                            grad2 += der * der;
                        }
                        let est = gp.abs() / grad2.sqrt();
                        if ok && est.is_finite() {
                            if est < edge {
                                // Downhill inside (g > 0), uphill outside.
                                let k = if gp > 0.0 { -est } else { est } / grad2.sqrt();
                                offset = grad.map(|g| g * k);
                            }
                            est.min(edge)
                        } else {
                            edge
                        }
                    }
                };
                surface.push(SurfacePoint {
                    index: id,
                    distance: d.max(0.0),
                    offset,
                });
            }
        }
        surface
    };
    let planes: Vec<Vec<SurfacePoint>> = (0..nz).into_par_iter().map(plane).collect();
    let surface: Vec<SurfacePoint> = planes.concat();
    Initial {
        dims,
        spacing,
        inside,
        band: surface.len(),
        nan_count,
        surface,
        scratch: Vec::new(),
    }
}

/// Spacing constants of the update, precomputed once per grid.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Stencil {
    h: [f32; 3],
    w: [f32; 3],
    inv_all: f32,
    sum_w: f32,
    /// All spacings equal: the division-free form of eq. (1) applies.
    iso: bool,
    two_h2: f32,
    three_h2: f32,
}

impl Stencil {
    pub(crate) fn new(h: [f32; 3]) -> Self {
        let w = h.map(|h| 1.0 / (h * h));
        Stencil {
            h,
            w,
            inv_all: 1.0 / (w[0] + w[1] + w[2]),
            sum_w: w[0] + w[1] + w[2],
            iso: h[0] == h[1] && h[1] == h[2],
            two_h2: 2.0 * h[0] * h[0],
            three_h2: 3.0 * h[0] * h[0],
        }
    }
}

/// Solves the upwind update for neighbour values `a` (per axis) (see the module doc).
///
/// The quadratic is solved for `e = d - a_min` with `b_i = a_i - a_min`: the textbook form in
/// `d` cancels catastrophically in `f32` far from the surface (`B^2` and `A C` agree to many
/// digits), and since an update is only accepted when it decreases the value, that rounding
/// noise ratchets values down by about 1e-3 voxel per round and stalls convergence (measured:
/// 19 rounds instead of 3 at 256^3).
///
/// Written without data-dependent branches (sorting by min/max and selects, all three
/// candidates computed): the branchy version spent most of its time in mispredictions.
#[inline(always)]
fn solve(a: [f32; 3], st: &Stencil) -> f32 {
    // Compare-exchange sort of (value, spacing, weight) triples.
    #[inline(always)]
    fn cx(a: &mut [f32; 3], h: &mut [f32; 3], w: &mut [f32; 3], i: usize, j: usize) {
        let sw = a[j] < a[i];
        let (ai, aj) = (fmin(a[i], a[j]), fmax(a[i], a[j]));
        let (hi, hj) = if sw { (h[j], h[i]) } else { (h[i], h[j]) };
        let (wi, wj) = if sw { (w[j], w[i]) } else { (w[i], w[j]) };
        a[i] = ai;
        a[j] = aj;
        h[i] = hi;
        h[j] = hj;
        w[i] = wi;
        w[j] = wj;
    }
    if st.iso {
        // Eq. (1) in shifted variables: no division, two square roots.
        let (mut x, mut y, mut z) = (a[0], a[1], a[2]);
        let (lo, hi) = (fmin(x, y), fmax(x, y));
        x = lo;
        y = hi;
        let (lo, hi) = (fmin(y, z), fmax(y, z));
        y = lo;
        z = hi;
        let (lo, hi) = (fmin(x, y), fmax(x, y));
        x = lo;
        y = hi;
        let b1 = y - x;
        let b2 = z - x;
        let e1 = st.h[0];
        let e2 = 0.5 * (b1 + fmax(st.two_h2 - b1 * b1, 0.0).sqrt());
        let d = b1 - b2;
        let e3 =
            (1.0 / 3.0) * (b1 + b2 + fmax(st.three_h2 - b1 * b1 - b2 * b2 - d * d, 0.0).sqrt());
        let e = if e1 <= b1 {
            e1
        } else if e2 <= b2 {
            e2
        } else {
            e3
        };
        return x + e;
    }
    let (mut a, mut h, mut w) = (a, st.h, st.w);
    cx(&mut a, &mut h, &mut w, 0, 1);
    cx(&mut a, &mut h, &mut w, 1, 2);
    cx(&mut a, &mut h, &mut w, 0, 1);
    let a0 = a[0];
    let b1 = a[1] - a0;
    let b2 = a[2] - a0;
    let e1 = h[0];
    // w0 e^2 + w1 (e - b1)^2 = 1
    let a2 = w[0] + w[1];
    let bb2 = w[1] * b1;
    let cc2 = w[1] * b1 * b1 - 1.0;
    let e2 = (bb2 + fmax(bb2 * bb2 - a2 * cc2, 0.0).sqrt()) / a2;
    // + w2 (e - b2)^2
    let bb3 = bb2 + w[2] * b2;
    let cc3 = cc2 + w[2] * b2 * b2;
    let e3 = (bb3 + fmax(bb3 * bb3 - cc3 * st.sum_w, 0.0).sqrt()) * st.inv_all;
    let e = if e1 <= b1 {
        e1
    } else if e2 <= b2 {
        e2
    } else {
        e3
    };
    a0 + e
}

/// Row bookkeeping for the "locking" optimisation (Bak, McLaughlin and Renzi 2010, at the
/// granularity of grid rows): a value can only decrease when a neighbour decreased since it was
/// last updated, so a row (j, k) is skipped unless it or one of its four neighbouring rows
/// changed after it was last processed. Steps count anti-diagonals (see [`sweep`]); rows on
/// one anti-diagonal share a step, which is all the rule needs, since no two of them are
/// neighbours. The result is identical to processing every row.
struct Rows {
    ny: usize,
    nz: usize,
    last_change: Vec<u32>,
    last_proc: Vec<u32>,
    step: u32,
}

impl Rows {
    fn new(ny: usize, nz: usize) -> Self {
        Rows {
            ny,
            nz,
            last_change: vec![1; ny * nz],
            last_proc: vec![0; ny * nz],
            step: 1,
        }
    }

    #[inline]
    fn needed(&self, j: usize, k: usize) -> bool {
        let r = j + self.ny * k;
        let lp = self.last_proc[r];
        if self.last_change[r] >= lp {
            return true;
        }
        (j > 0 && self.last_change[r - 1] > lp)
            || (j + 1 < self.ny && self.last_change[r + 1] > lp)
            || (k > 0 && self.last_change[r - self.ny] > lp)
            || (k + 1 < self.nz && self.last_change[r + self.ny] > lp)
    }
}

/// The padded grid shared by the threads of one anti-diagonal.
///
/// Rows of one anti-diagonal are updated concurrently: each thread writes only its own rows
/// and reads their y and z neighbours, which lie on the previous and the next anti-diagonal and
/// are not written during this one. Indices stay inside the allocation because every unpadded
/// voxel has its six neighbours in the padded grid.
#[derive(Clone, Copy)]
struct SharedGrid {
    ptr: *mut f32,
    len: usize,
}

// SAFETY: see the type's doc: concurrent writes go to disjoint rows, and no row is read while
// another thread writes it.
unsafe impl Send for SharedGrid {}
unsafe impl Sync for SharedGrid {}

/// A row-addressed view of the padded grid: `nx` voxels per row, `px` floats per padded row,
/// `pxy` per padded plane.
#[derive(Clone, Copy)]
struct RowGeom {
    grid: SharedGrid,
    nx: usize,
    px: usize,
    pxy: usize,
}

impl SharedGrid {
    /// The `nx` values of the row starting at `start` (read-only).
    ///
    /// # Safety
    /// The row lies inside the grid and no thread writes it while the slice lives.
    #[inline(always)]
    unsafe fn row(self, start: usize, nx: usize) -> &'static [f32] {
        debug_assert!(start + nx <= self.len);
        std::slice::from_raw_parts(self.ptr.add(start), nx)
    }

    /// The row starting at `start` with one extra value on each side, writable.
    ///
    /// # Safety
    /// As for [`Self::row`], and no other thread reads or writes the row while it lives.
    #[inline(always)]
    unsafe fn row_mut(self, start: usize, nx: usize) -> &'static mut [f32] {
        debug_assert!(start >= 1 && start + nx < self.len);
        std::slice::from_raw_parts_mut(self.ptr.add(start - 1), nx + 2)
    }
}

/// The y and z neighbour minima of one row, which no update in the row changes, and a copy of
/// the row (the scalar path of [`rows_lockstep`]).
#[inline(always)]
fn neighbour_minima(g: RowGeom, s: usize, ay: &mut [f32], az: &mut [f32], old: &mut [f32]) {
    let RowGeom { grid, nx, px, pxy } = g;
    // SAFETY: the neighbour rows are not written during this step (see `sweep`).
    let (ym, yp, zm, zp, me) = unsafe {
        (
            grid.row(s - px, nx),
            grid.row(s + px, nx),
            grid.row(s - pxy, nx),
            grid.row(s + pxy, nx),
            grid.row(s, nx),
        )
    };
    old.copy_from_slice(me);
    for i in 0..nx {
        ay[i] = fmin(ym[i].abs(), yp[i].abs());
        az[i] = fmin(zm[i].abs(), zp[i].abs());
    }
}

/// The update of one voxel of a row (`row[1..=nx]`, ghosts at both ends).
#[inline(always)]
fn update(row: &mut [f32], i: usize, ay: f32, az: f32, st: &Stencil) {
    let u = row[i + 1];
    let ax = fmin(row[i].abs(), row[i + 2].abs());
    let d = solve([ax, ay, az], st);
    // All neighbours infinite gives NaN, and `fmin(NaN, u)` is `u`; a frozen value (sign bit
    // set) is kept by the select.
    row[i + 1] = if u.is_sign_negative() { u } else { fmin(d, u) };
}

/// The largest decrease from `old` to `new` (vectorised; `inf - inf` is NaN, ignored).
#[inline(always)]
fn largest_decrease(old: &[f32], new: &[f32]) -> f32 {
    old.iter()
        .zip(new)
        .fold(0.0f32, |m, (&o, &n)| fmax(o - n, m))
}

use crate::lanes::{fmax, fmin, F4};

/// [`solve_sorted`] on four lanes.
#[inline(always)]
fn solve_sorted4(ax: F4, lo: F4, hi: F4, st: &Stencil) -> F4 {
    let x = ax.min(lo);
    let m = ax.max(lo);
    let y = m.min(hi);
    let z = m.max(hi);
    let b1 = y.sub(x);
    let b2 = z.sub(x);
    let zero = F4::splat(0.0);
    let e1 = F4::splat(st.h[0]);
    let e2 = F4::splat(0.5).mul(b1.add(F4::splat(st.two_h2).sub(b1.mul(b1)).max(zero).sqrt()));
    let dd = b1.sub(b2);
    let r3 = F4::splat(st.three_h2)
        .sub(b1.mul(b1))
        .sub(b2.mul(b2))
        .sub(dd.mul(dd));
    let e3 = F4::splat(1.0 / 3.0).mul(b1.add(b2).add(r3.max(zero).sqrt()));
    x.add(e1.le_select(b1, e1, e2.le_select(b2, e2, e3)))
}

/// Independent four-lane chains interleaved in [`rows_lockstep`].
const CHAINS: usize = 4;

type Lanes = [[f32; 4]; CHAINS];

/// Buffers of [`rows_lockstep`], reused across calls.
#[derive(Default)]
struct Scratch {
    buf: Vec<f32>,
    t: Vec<Lanes>,
    t_old: Vec<Lanes>,
    l4: Vec<Lanes>,
    h4: Vec<Lanes>,
}

/// Updates up to [`SLAB`] rows in lockstep along x; returns the largest decrease per row.
///
/// Phase 1 gathers the y and z neighbour minima (which no update in these rows changes). On
/// isotropic grids the rows are then transposed into `CHAINS` four-lane vectors (missing rows
/// padded with infinity, which the update leaves alone) and the x recurrences run as
/// `CHAINS` independent vector recurrences interleaved in one loop body: one update is a long
/// chain (a sort, a square root, selects), and only independent chains side by side keep the
/// CPU busy. Anisotropic grids take the scalar update row by row. The change is measured
/// afterwards against a copy.
fn rows_lockstep(
    g: RowGeom,
    starts: &[usize],
    forward: bool,
    st: &Stencil,
    scratch: &mut Scratch,
) -> [f32; SLAB] {
    let RowGeom { grid, nx, px, pxy } = g;
    let n = starts.len();
    assert!((1..=SLAB).contains(&n));
    for &s in starts {
        assert!(
            s > pxy && s + nx + pxy < grid.len,
            "row outside the padded grid"
        );
    }
    let mut change = [0.0f32; SLAB];
    if !st.iso {
        scratch.buf.resize(3 * nx, 0.0);
        let (lo, rest) = scratch.buf.split_at_mut(nx);
        let (hi, old) = rest.split_at_mut(nx);
        for (r, &s) in starts.iter().enumerate() {
            neighbour_minima(g, s, lo, hi, old);
            // SAFETY: each row belongs to this call alone during the step (see `sweep`).
            let row = unsafe { grid.row_mut(s, nx) };
            for ii in 0..nx {
                let i = if forward { ii } else { nx - 1 - ii };
                update(row, i, lo[i], hi[i], st);
            }
            change[r] = largest_decrease(old, &row[1..=nx]);
        }
        return change;
    }
    let inf = [[f32::INFINITY; 4]; CHAINS];
    // t[i] holds voxel i - 1 of every row (ghosts at 0 and nx + 1), row r in lane r % 4 of
    // chain r / 4; rows that are missing stay infinite, which the update leaves alone.
    let Scratch {
        t, t_old, l4, h4, ..
    } = scratch;
    t.clear();
    t.resize(nx + 2, inf);
    l4.clear();
    l4.resize(nx, inf);
    h4.clear();
    h4.resize(nx, inf);
    let mut finite = false;
    for (r, &s) in starts.iter().enumerate() {
        let (c, lane) = (r / 4, r % 4);
        // SAFETY: the neighbour rows and the row itself are not written by anyone else during
        // this step (see `sweep`).
        let (me, ym, yp, zm, zp) = unsafe {
            (
                grid.row(s - 1, nx + 2),
                grid.row(s - px, nx),
                grid.row(s + px, nx),
                grid.row(s - pxy, nx),
                grid.row(s + pxy, nx),
            )
        };
        let mut lo_min = f32::INFINITY;
        for (tv, &v) in t.iter_mut().zip(me) {
            tv[c][lane] = v;
            lo_min = fmin(v.abs(), lo_min);
        }
        for (((((l, h), &a), &b), &cz), &dz) in l4
            .iter_mut()
            .zip(h4.iter_mut())
            .zip(ym)
            .zip(yp)
            .zip(zm)
            .zip(zp)
        {
            let ay = fmin(a.abs(), b.abs());
            let az = fmin(cz.abs(), dz.abs());
            let lo = fmin(ay, az);
            l[c][lane] = lo;
            h[c][lane] = fmax(ay, az);
            lo_min = fmin(lo, lo_min);
        }
        finite |= lo_min < f32::INFINITY;
    }
    if !finite {
        // Every value of these rows and of their y and z neighbours is infinite (upstream of
        // every surface, early in the first round): nothing can change.
        return change;
    }
    t_old.clear();
    t_old.extend_from_slice(t);
    // Forward, the upwind x neighbour of t[i + 1] is t[i] (just updated) and the other one
    // t[i + 2]; backward, the roles swap.
    let first = if forward { 0 } else { nx + 1 };
    let mut prev: [F4; CHAINS] = std::array::from_fn(|c| F4::load(&t[first][c]));
    for ii in 0..nx {
        let (i, other) = if forward {
            (ii, ii + 2)
        } else {
            (nx - 1 - ii, nx - 1 - ii)
        };
        let (l, h) = (&l4[i], &h4[i]);
        let o = t[other];
        let cur = &mut t[i + 1];
        for c in 0..CHAINS {
            let ax = prev[c].abs().min(F4::load(&o[c]).abs());
            let d = solve_sorted4(ax, F4::load(&l[c]), F4::load(&h[c]), st);
            let new = F4::load(&cur[c]).relax(d);
            new.store(&mut cur[c]);
            prev[c] = new;
        }
    }
    // Largest decrease per lane (`inf - inf` is NaN, which `max` passes over).
    let mut acc = [F4::splat(0.0); CHAINS];
    for (a, b) in t_old[1..=nx].iter().zip(&t[1..=nx]) {
        for c in 0..CHAINS {
            acc[c] = F4::load(&a[c]).sub(F4::load(&b[c])).max(acc[c]);
        }
    }
    for (r, &s) in starts.iter().enumerate() {
        let (c, lane) = (r / 4, r % 4);
        let mut v = [0.0f32; 4];
        acc[c].store(&mut v);
        change[r] = v[lane];
        // SAFETY: each row belongs to this call alone during the step (see `sweep`).
        let row = unsafe { grid.row_mut(s, nx) };
        for (dst, tv) in row[1..=nx].iter_mut().zip(&t[1..=nx]) {
            *dst = tv[c][lane];
        }
    }
    change
}

/// Planes per slab of the skewed traversal in [`sweep`].
const SLAB: usize = 4 * CHAINS;

/// One Gauss-Seidel sweep in direction `dir` (signs per axis, Table 1); returns the largest
/// decrease and the number of rows processed.
///
/// Planes are taken in slabs of [`SLAB`] (in sweep order), and a slab is traversed skewed:
/// at step `jj` the rows `(jj - m, kk0 + m)` for `m = 0..SLAB` are updated together, in
/// lockstep along x. Each of these rows needs only its upwind y neighbour (updated at the
/// previous step) and its upwind z neighbour (updated at the previous step, or in the previous
/// slab), and reads its downwind neighbours before they are updated, exactly as in the
/// row-by-row order, so the sweep is the same Gauss-Seidel sweep. The rows of a step are not
/// neighbours of each other, so their x recurrences are independent and overlap in the CPU,
/// while the working set stays a few rows of a few adjacent planes.
fn sweep(
    grid: &mut [f32],
    dims: [usize; 3],
    st: &Stencil,
    dir: [i32; 3],
    rows: &mut Rows,
) -> (f32, usize) {
    let [nx, ny, nz] = dims;
    let px = nx + 2;
    let pxy = px * (ny + 2);
    let forward = dir[0] > 0;
    let geom = RowGeom {
        grid: SharedGrid {
            ptr: grid.as_mut_ptr(),
            len: grid.len(),
        },
        nx,
        px,
        pxy,
    };
    let mut max_change = 0.0f32;
    let mut processed = 0;
    let mut group: Vec<(usize, usize)> = Vec::with_capacity(SLAB);
    let mut starts: Vec<usize> = Vec::with_capacity(SLAB);
    let mut scratch = Scratch::default();
    let mut kk0 = 0;
    while kk0 < nz {
        let slab = SLAB.min(nz - kk0);
        for t in 0..(ny + slab - 1) {
            group.clear();
            for m in 0..slab {
                if t < m || t - m >= ny {
                    continue;
                }
                let (jj, kk) = (t - m, kk0 + m);
                let k = if dir[2] > 0 { kk } else { nz - 1 - kk };
                let j = if dir[1] > 0 { jj } else { ny - 1 - jj };
                if rows.needed(j, k) {
                    group.push((j, k));
                }
            }
            if group.is_empty() {
                continue;
            }
            processed += group.len();
            starts.clear();
            starts.extend(group.iter().map(|&(j, k)| pidx(dims, 0, j, k)));
            let ch = rows_lockstep(geom, &starts, forward, st, &mut scratch);
            for (q, &(j, k)) in group.iter().enumerate() {
                rows.step += 1;
                let r = j + ny * k;
                rows.last_proc[r] = rows.step;
                if ch[q] > 0.0 {
                    rows.last_change[r] = rows.step;
                    max_change = fmax(ch[q], max_change);
                }
            }
        }
        kk0 += slab;
    }
    (max_change, processed)
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

/// The signed distance from the initial band by the method of `opts`.
pub fn distance_from_band(init: Initial, opts: &DistanceOptions) -> DistanceField {
    match opts.method {
        DistanceMethod::ClosestPoint => crate::closest_point::closest_point_distance(init),
        DistanceMethod::Sweeping => sweep_distance(init, opts),
    }
}

/// The padded `(nx+2)(ny+2)(nz+2)` grid the sweeps work on: `+inf` away from the surface, band
/// vertices frozen (sign bit set, magnitude = distance estimate).
fn frozen_band(dims: [usize; 3], surface: &[SurfacePoint]) -> Vec<f32> {
    let [nx, ny, nz] = dims;
    let mut padded = vec![f32::INFINITY; (nx + 2) * (ny + 2) * (nz + 2)];
    for s in surface {
        let (i, j, k) = (s.index % nx, (s.index / nx) % ny, s.index / (nx * ny));
        // Frozen: sign bit set (also for a distance of exactly 0).
        padded[pidx(dims, i, j, k)] = f32::from_bits(s.distance.to_bits() | 0x8000_0000);
    }
    padded
}

/// Sweeps the initial band out to the whole grid and applies the sign (step 3).
pub fn sweep_distance(init: Initial, opts: &DistanceOptions) -> DistanceField {
    let Initial {
        dims,
        spacing,
        inside,
        band,
        nan_count,
        surface,
        scratch,
    } = init;
    drop(scratch);
    let mut padded = frozen_band(dims, &surface);
    drop(surface);
    let hmin = spacing.iter().cloned().fold(f32::INFINITY, f32::min);
    let tol = opts.tolerance * hmin;
    let mut iterations = 0;
    let mut converged = band == 0;
    let mut rows = Rows::new(dims[1], dims[2]);
    let mut rows_processed = 0usize;
    let st = Stencil::new(spacing);
    while !converged && iterations < opts.max_iterations {
        iterations += 1;
        let mut change = 0.0f32;
        for dir in SWEEP_DIRECTIONS {
            let (c, p) = sweep(&mut padded, dims, &st, dir, &mut rows);
            change = change.max(c);
            rows_processed += p;
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
    DistanceField {
        dims,
        distance,
        iterations,
        converged,
        band,
        nan_count,
        rows_processed,
    }
}

/// Classification, initialisation and the distance by `opts.method` in one call.
pub fn signed_distance(
    values: &[f32],
    dims: [usize; 3],
    spacing: [f32; 3],
    opts: &DistanceOptions,
) -> DistanceField {
    distance_from_band(classify_and_initialise(values, dims, spacing, opts), opts)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn isotropic_update_matches_the_papers_eq1() {
        let h = 1.5f32;
        // One neighbour.
        assert_eq!(solve([2.0, 10.0, 10.0], &Stencil::new([h; 3])), 3.5);
        // Two neighbours: s2 = (a1 + a2 + sqrt(2h^2 - (a1 - a2)^2)) / 2.
        let (a1, a2) = (2.0f32, 2.5f32);
        let s2 = (a1 + a2 + (2.0 * h * h - (a1 - a2).powi(2)).sqrt()) / 2.0;
        assert!((solve([a2, a1, 100.0], &Stencil::new([h; 3])) - s2).abs() < 1e-6);
        // Three neighbours.
        let (a1, a2, a3) = (2.0f32, 2.2f32, 2.3f32);
        let s3 = (a1
            + a2
            + a3
            + (3.0 * h * h - (a1 - a2).powi(2) - (a1 - a3).powi(2) - (a2 - a3).powi(2)).sqrt())
            / 3.0;
        assert!((solve([a3, a1, a2], &Stencil::new([h; 3])) - s3).abs() < 1e-6);
    }

    #[test]
    fn anisotropic_update_solves_the_quadratic() {
        let h = [3.2f32, 3.2, 1.5];
        let a = [4.0f32, 4.5, 3.9];
        let d = solve(a, &Stencil::new(h));
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
        let opts = DistanceOptions {
            init: InitMethod::Plane,
            ..Default::default()
        };
        let init = classify_and_initialise(&v, dims, [1.0; 3], &opts);
        let padded = frozen_band(dims, &init.surface);
        for (id, &f) in v.iter().enumerate() {
            let (i, j, k) = (id % 24, (id / 24) % 20, id / 480);
            let p = padded[pidx(dims, i, j, k)];
            // (Inside samples on the border are closed half a voxel out instead.)
            let border = i == 0 || j == 0 || k == 0 || i == 23 || j == 19 || k == 15;
            if p.is_sign_negative() && !border {
                assert!(
                    (p.abs() - f.abs()).abs() < 1e-5,
                    "band value {} vs {}",
                    p.abs(),
                    f.abs()
                );
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
            // Outside only: the inside touches the border, which closes it with more surface.
            if *f < 0.0 && (0..3).all(|a| foot[a] >= 0.0 && foot[a] <= (dims[a] - 1) as f32) {
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
        assert!(compared > 800, "{compared}");
        assert!(max_int < 5e-3, "interior max error {max_int}");
        // Next to the faces a missing upwind neighbour makes the update two-dimensional.
        assert!(
            max_err < 0.5 && sum / (compared as f32) < 0.05,
            "max {max_err}, mean {}",
            sum / compared as f32
        );
    }
}
