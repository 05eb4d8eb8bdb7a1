//! Eight-octant occlusion fields by occlusion sweeping: Singh, Yuksel and House, "Fast Occlusion
//! Sweeping" (ISVC 2009), section 2, eq. (6)-(8), Table 1.
//!
//! # The recurrences
//! For sweep `s` with direction `sigma = (sx, sy, sz)` (Table 1, see
//! [`crate::distance_sweep::SWEEP_DIRECTIONS`]) the octant visibility is eq. (6):
//!
//! `V_s(P) = 1/3 [V_s(P - sx e_x) tau(P - sx e_x) + V_s(P - sy e_y) tau(P - sy e_y)
//!                + V_s(P - sz e_z) tau(P - sz e_z)]`
//!
//! with the transmittance of eq. (7), `tau = clamp(D / h + 1/2, 0, 1)` from the signed distance
//! `D` (negative inside). Outside the grid is open sky: `V = 1` and `tau = 1` there.
//!
//! # What had to be pinned down
//! * **Which sky.** `V_s(P)` is built from the neighbours on the side the sweep comes from, so it
//!   is the visibility of the sky octant *opposite* the sweep direction: light arriving from
//!   directions `w` with `sign(w_a) = -sigma_a` in index space (sweep 1, (+,+,+), sees the
//!   (-,-,-) sky). In world terms that octant is spanned by `-sigma_a` times the affine's unit
//!   axis vectors; for an axis flipped by the affine (as the x axis of many NIfTI files) the
//!   world sign flips too ([`sky_direction_world`]).
//! * **Which h in eq. (7).** The smallest spacing `h_min`. `tau` is a voxel's transmittance, the
//!   outside fraction along a path through it; on anisotropic grids the thinnest extent is the
//!   one through which the surface can pass within half a voxel.
//! * **Concurrency with the distance sweeps.** With `h = h_min`, `tau` depends only on the
//!   initialised values: a vertex outside the initial band has all six neighbours on its own
//!   side, and every value the distance sweep can give it is at least the three-neighbour
//!   solution from neighbours at distance 0, `(sum_a h_a^-2)^(-1/2) >= h_min / sqrt(3) >
//!   h_min / 2`, so there `tau` is exactly 0 (inside) or 1 (outside) whatever the sweeps do,
//!   and in the band the values are frozen at their initial estimates. The octant sweeps therefore
//!   read nothing that the distance sweeps write, and [`sweep_fields`] runs both at once. `tau`
//!   is defined by this rule (the classification off the band, the band's estimates on it)
//!   whichever distance method runs: closest points can give a voxel off the band a distance
//!   below `h_min / 2` where the surface passes it diagonally, and `tau` stays 0 or 1 there.
//! * **Eq. (8).** As printed, `tau_trans = 1 - (1 - tau)^alpha` makes a voxel *more* opaque as
//!   `alpha` falls (and keeps the interior, `tau = 0`, opaque for every `alpha`), the opposite
//!   of the text ("decreasing alpha values permit more light to penetrate"). The reading that
//!   matches the text, with `alpha` an opacity in [0, 1], is `tau_trans = 1 - alpha (1 - tau)`:
//!   `alpha = 1` is eq. (7), `alpha = 0` transparent, and light decays inside the object as
//!   `(1 - alpha)^n` over `n` voxels. That is what [`OcclusionOptions::subsurface_alpha`] applies.
//!
//! # Storage and speed
//! Octants are stored as `u8` (`round(255 V)`, quantisation error at most 1/510), 8 bytes per
//! voxel; `tau` is quantised the same way for the sweeps. Each octant is swept plane by plane
//! keeping only the previous plane (in `f32`, so quantisation does not accumulate). The four
//! octants that share a z direction run in one pass as the four lanes of one vector: each lane
//! sweeps its octant in coordinates mirrored so that all four go forwards, so one four-wide add
//! and multiply per voxel serve all four (see `sweep_z_group`); the two passes run in parallel.
//! `tau` comes from the classification and the band alone ([`transmittance`]), so the octants
//! need nothing from the distance computation and run beside it ([`sweep_fields`]).

use crate::distance_sweep::{
    classify_and_initialise, distance_from_band, DistanceField, DistanceOptions, Initial,
    SWEEP_DIRECTIONS,
};
use crate::lanes::F4;
use glam::{DMat4, DVec3};

/// Options of the occlusion sweeps.
#[derive(Clone, Copy, Debug, Default)]
pub struct OcclusionOptions {
    /// Subsurface variant (eq. 8 as derived in the module doc): per-voxel opacity in [0, 1].
    pub subsurface_alpha: Option<f32>,
}

impl OcclusionOptions {
    /// Checks the subsurface opacity: a number in [0, 1] (2 was clamped in silence, NaN made
    /// every voxel opaque).
    pub fn check(&self) -> std::result::Result<(), String> {
        match self.subsurface_alpha {
            Some(a) if !(0.0..=1.0).contains(&a) => Err(format!(
                "subsurface opacity {a}: must be a number from 0 to 1"
            )),
            _ => Ok(()),
        }
    }
}

/// The eight octant visibility fields, `round(255 V)`, in Table 1 order, each x fastest.
#[derive(Clone, Debug, PartialEq)]
pub struct OctantFields {
    pub dims: [usize; 3],
    pub octants: [Vec<u8>; 8],
}

impl OctantFields {
    /// Visibility of octant `s` at voxel `idx`, in [0, 1].
    #[inline]
    pub fn v(&self, s: usize, idx: usize) -> f32 {
        self.octants[s][idx] as f32 * (1.0 / 255.0)
    }
}

/// Quantised transmittance per voxel (`round(255 tau)`, eq. 7 with `h = h_min`, or eq. 8 as
/// derived when `alpha` is given), from the initialisation alone (see the module doc).
pub fn transmittance(init: &Initial, alpha: Option<f32>) -> Vec<u8> {
    use rayon::prelude::*;
    let h = init.spacing.iter().cloned().fold(f32::INFINITY, f32::min);
    let quantise = |t: f32| -> u8 {
        let t = match alpha {
            Some(a) => 1.0 - a.clamp(0.0, 1.0) * (1.0 - t),
            None => t,
        };
        (t * 255.0 + 0.5) as u8
    };
    let (t_in, t_out) = (quantise(0.0), quantise(1.0));
    let mut tau = crate::memory::zeroed(init.inside.len(), 0u8);
    tau.par_chunks_mut(1 << 16)
        .zip(init.inside.par_chunks(1 << 16))
        .for_each(|(t, i)| {
            for (t, &i) in t.iter_mut().zip(i) {
                *t = if i { t_in } else { t_out };
            }
        });
    // Band: frozen estimate, signed by the classification.
    for s in &init.surface {
        let d = if init.inside[s.index] {
            -s.distance
        } else {
            s.distance
        };
        tau[s.index] = quantise((d / h + 0.5).clamp(0.0, 1.0));
    }
    tau
}

/// A clipping plane: its normal and offset, keeping `normal . p <= offset` (world units).
pub type ClipPlane = ([f64; 3], f64);

/// Opens the transmittance `tau` (quantised, as [`transmittance`] gives it) of an isosurface's
/// solid to the half-spaces clipping planes remove (each plane keeps `normal . p <= offset`,
/// world units; `affine` maps voxel indices to world): a voxel takes the larger of its own
/// transmittance and the plane's, by eq. (7)'s rule from the distance past the plane,
/// `clamp(d / h + 1/2, 0, 1)` with `h` the smallest spacing. The octants swept from it
/// ([`sweep_octants`]) describe the cut solid: a cavity the cut opens sees the sky through the
/// opening, where the uncut fields (the sky shut out by the removed wall) left it black.
/// `false`, `tau` untouched, where no plane comes within half a voxel of a voxel centre (the
/// uncut fields hold).
pub fn open_cut(tau: &mut [u8], dims: [usize; 3], affine: &DMat4, planes: &[ClipPlane]) -> bool {
    use rayon::prelude::*;
    let [nx, ny, nz] = dims;
    assert_eq!(tau.len(), nx * ny * nz);
    let axes = [affine.x_axis, affine.y_axis, affine.z_axis].map(|a| a.truncate());
    let h = axes
        .iter()
        .map(|a| a.length())
        .fold(f64::INFINITY, f64::min);
    // Per plane, the signed distance past it (world units) at voxel (0, 0, 0) and its steps
    // along the three axes: affine in the index.
    let planes: Vec<(f64, [f64; 3])> = planes
        .iter()
        .filter_map(|(n, off)| {
            let n = DVec3::from(*n);
            let len = n.length();
            (len > 0.0 && len.is_finite()).then(|| {
                let n = n / len;
                let o = affine.w_axis.truncate();
                (n.dot(o) - off / len, axes.map(|a| n.dot(a)))
            })
        })
        .collect();
    let past = |i: usize, j: usize, k: usize| {
        planes
            .iter()
            .map(|(d0, s)| d0 + s[0] * i as f64 + s[1] * j as f64 + s[2] * k as f64)
            .fold(f64::NEG_INFINITY, f64::max)
    };
    // Nothing within half a voxel of a plane: the largest of affine functions is convex, its
    // maximum over the grid at a corner.
    let reach = (0..8)
        .map(|c| {
            let at = |b: usize, n: usize| if c & b != 0 { n.saturating_sub(1) } else { 0 };
            past(at(1, nx), at(2, ny), at(4, nz))
        })
        .fold(f64::NEG_INFINITY, f64::max);
    if planes.is_empty() || nx == 0 || reach.is_nan() || reach <= -0.5 * h {
        return false;
    }
    tau.par_chunks_mut(nx).enumerate().for_each(|(row, t)| {
        let (j, k) = (row % ny, row / ny);
        for (i, t) in t.iter_mut().enumerate() {
            let open = (past(i, j, k) / h + 0.5).clamp(0.0, 1.0);
            *t = (*t).max((open * 255.0 + 0.5) as u8);
        }
    });
    true
}

/// Quantised transmittance from a signed distance field (world units, negative inside) alone,
/// for octant fields swept again from a distance file: eq. (7) with `h` the smallest spacing,
/// eq. (8) as derived with `alpha` (a NaN distance open). Equal to [`transmittance`] but
/// where closest points put a voxel off the band within half a voxel of the surface (the
/// module doc): there it is fractional, not 0 or 1.
pub fn transmittance_from_distance(
    distance: &[f32],
    spacing: [f64; 3],
    alpha: Option<f32>,
) -> Vec<u8> {
    use rayon::prelude::*;
    let h = spacing.iter().cloned().fold(f64::INFINITY, f64::min) as f32;
    let mut tau = crate::memory::zeroed(distance.len(), 0u8);
    tau.par_chunks_mut(1 << 16)
        .zip(distance.par_chunks(1 << 16))
        .for_each(|(t, d)| {
            for (t, &d) in t.iter_mut().zip(d) {
                let x = if d.is_nan() {
                    1.0
                } else {
                    (d / h + 0.5).clamp(0.0, 1.0)
                };
                let x = match alpha {
                    Some(a) => 1.0 - a.clamp(0.0, 1.0) * (1.0 - x),
                    None => x,
                };
                *t = (x * 255.0 + 0.5) as u8;
            }
        });
    tau
}

/// Sweeps the four octants with z direction `sz` (+1 or -1) in one pass, one octant per lane.
///
/// Each octant is swept in its own coordinates, mirrored in x and y so that all four go
/// forwards: lane `o` at sweep position `(i, j)` is the voxel `(i_o, j_o)` with
/// `i_o = i` or `nx - 1 - i` by the octant's x direction (likewise y). The recurrence is then the
/// same for the four lanes, one four-wide add and multiply per voxel, and only the transmittance
/// reads and the quantised writes go to the mirrored places.
fn sweep_z_group(tau: &[u8], dims: [usize; 3], sz: i32) -> [(usize, Vec<u8>); 4] {
    let [nx, ny, nz] = dims;
    let plane = nx * ny;
    // The four octants (Table 1 index, sx, sy) of this z direction.
    let members: Vec<(usize, i32, i32)> = SWEEP_DIRECTIONS
        .iter()
        .enumerate()
        .filter(|(_, d)| d[2] == sz)
        .map(|(s, d)| (s, d[0], d[1]))
        .collect();
    assert_eq!(members.len(), 4);
    let mut out: Vec<Vec<u8>> = (0..4)
        .map(|_| crate::memory::zeroed(nx * ny * nz, 0u8))
        .collect();
    // tau / 3 per quantised value: W = V tau with V = (W_x + W_y + W_z) / 3, so the x
    // recurrence is W_x' = (W_x + (W_y + W_z)) tau / 3, one add and one multiply long.
    const TAU3: [f32; 256] = {
        let mut t = [0.0f32; 256];
        let mut i = 0;
        while i < 256 {
            t[i] = i as f32 / (255.0 * 3.0);
            i += 1;
        }
        t
    };
    // W = V tau of the previous plane and of the current plane, in sweep coordinates, four
    // lanes; the sky (1) before the first plane and the first row.
    let mut prev = vec![[1.0f32; 4]; plane];
    let mut cur = vec![[1.0f32; 4]; plane];
    let sky = vec![[1.0f32; 4]; nx];
    // Per lane: the first x of a row and the step along it.
    let x0: [isize; 4] =
        std::array::from_fn(|o| if members[o].1 > 0 { 0 } else { nx as isize - 1 });
    let dx: [isize; 4] = std::array::from_fn(|o| if members[o].1 > 0 { 1 } else { -1 });
    let quarter = F4::splat(255.0 / 3.0);
    let half = F4::splat(0.5);
    for kk in 0..nz {
        let k = if sz > 0 { kk } else { nz - 1 - kk };
        for j in 0..ny {
            // The voxel row of each lane.
            let rows: [usize; 4] = std::array::from_fn(|o| {
                let jo = if members[o].2 > 0 { j } else { ny - 1 - j };
                k * plane + jo * nx
            });
            let (before, rest) = cur.split_at_mut(j * nx);
            let row = &mut rest[..nx];
            let yrow: &[[f32; 4]] = if j > 0 { &before[(j - 1) * nx..] } else { &sky };
            let prow = &prev[j * nx..(j + 1) * nx];
            let tp: [*const u8; 4] = std::array::from_fn(|o| tau[rows[o]..rows[o] + nx].as_ptr());
            let op: [*mut u8; 4] = {
                let mut it = out.iter_mut().zip(rows);
                std::array::from_fn(|_| {
                    let (v, r) = it.next().unwrap();
                    v[r..r + nx].as_mut_ptr()
                })
            };
            let mut wx = F4::splat(1.0);
            for (i, ((c, y), p)) in row.iter_mut().zip(&yrow[..nx]).zip(prow).enumerate() {
                let at: [isize; 4] = std::array::from_fn(|o| x0[o] + dx[o] * i as isize);
                // SAFETY: 0 <= at[o] < nx, and each pointer addresses a row of nx elements
                // (sliced above); the four output rows belong to four different vectors.
                let t = unsafe {
                    F4::load(&[
                        TAU3[*tp[0].offset(at[0]) as usize],
                        TAU3[*tp[1].offset(at[1]) as usize],
                        TAU3[*tp[2].offset(at[2]) as usize],
                        TAU3[*tp[3].offset(at[3]) as usize],
                    ])
                };
                let s = wx.add(F4::load(y).add(F4::load(p)));
                wx = s.mul(t);
                wx.store(c);
                let mut v = [0.0f32; 4];
                s.mul(quarter).add(half).store(&mut v);
                for o in 0..4 {
                    // SAFETY: as above.
                    unsafe { *op[o].offset(at[o]) = v[o] as u8 };
                }
            }
        }
        std::mem::swap(&mut prev, &mut cur);
    }
    let mut it = members.iter().zip(out);
    std::array::from_fn(|_| {
        let ((s, _, _), v) = it.next().unwrap();
        (*s, v)
    })
}

/// The eight octant fields from quantised transmittance (both z groups in parallel).
pub fn sweep_octants(tau: &[u8], dims: [usize; 3]) -> OctantFields {
    assert_eq!(tau.len(), dims[0] * dims[1] * dims[2]);
    let (up, down) = rayon::join(
        || sweep_z_group(tau, dims, 1),
        || sweep_z_group(tau, dims, -1),
    );
    let mut octants: [Vec<u8>; 8] = Default::default();
    for (s, v) in up.into_iter().chain(down) {
        octants[s] = v;
    }
    OctantFields { dims, octants }
}

/// Signed distance and octant fields of one isosurface, computed together: the transmittance
/// comes from the initialisation, so the distance sweeps and the octant sweeps run at once.
pub fn sweep_fields(
    values: &[f32],
    dims: [usize; 3],
    spacing: [f32; 3],
    dopts: &DistanceOptions,
    oopts: &OcclusionOptions,
    octants: bool,
) -> (DistanceField, Option<OctantFields>) {
    let init = classify_and_initialise(values, dims, spacing, dopts);
    fields_from_band(init, dopts, oopts, octants)
}

/// [`sweep_fields`] from the classification and band, so that a caller can free the samples
/// before the fields are allocated (nothing after [`classify_and_initialise`] reads them).
pub fn fields_from_band(
    init: Initial,
    dopts: &DistanceOptions,
    oopts: &OcclusionOptions,
    octants: bool,
) -> (DistanceField, Option<OctantFields>) {
    fields_from_band_cut(init, dopts, oopts, octants, None)
}

/// [`fields_from_band`] with the octants swept for the solid cut by clipping planes
/// (`cut`: the grid's index-to-world affine and the planes, [`open_cut`]).
pub fn fields_from_band_cut(
    init: Initial,
    dopts: &DistanceOptions,
    oopts: &OcclusionOptions,
    octants: bool,
    cut: Option<(&DMat4, &[ClipPlane])>,
) -> (DistanceField, Option<OctantFields>) {
    if !octants {
        return (distance_from_band(init, dopts), None);
    }
    let dims = init.dims;
    let mut tau = transmittance(&init, oopts.subsurface_alpha);
    if let Some((affine, planes)) = cut {
        open_cut(&mut tau, dims, affine, planes);
    }
    let (df, oct) = rayon::join(
        || distance_from_band(init, dopts),
        || sweep_octants(&tau, dims),
    );
    (df, Some(oct))
}

/// World direction (unit) of the centre of the sky octant that sweep `s` sees: `-sigma` in index
/// space, through the affine's unit axis vectors.
pub fn sky_direction_world(s: usize, affine: &DMat4) -> DVec3 {
    let d = SWEEP_DIRECTIONS[s];
    let axes = [
        affine.x_axis.truncate(),
        affine.y_axis.truncate(),
        affine.z_axis.truncate(),
    ];
    let w: DVec3 = (0..3)
        .map(|a| axes[a].normalize_or_zero() * -(d[a] as f64))
        .sum();
    w.normalize_or_zero()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A hollow ball (a shell from radius 6 to 10 about the centre of a 33^3 grid) cut in
    /// half by the plane x = 16 (keeping x <= 16): the cavity, black inside the uncut shell,
    /// sees the sky through the cut on the side it faces and not on the other.
    #[test]
    fn a_cut_opens_the_cavity_it_crosses_to_the_sky_on_its_side() {
        let n = 33;
        let dims = [n; 3];
        let c = 16.0;
        let mut sdf = vec![0f32; n * n * n];
        for k in 0..n {
            for j in 0..n {
                for i in 0..n {
                    let r =
                        ((i as f64 - c).powi(2) + (j as f64 - c).powi(2) + (k as f64 - c).powi(2))
                            .sqrt();
                    sdf[i + n * (j + n * k)] = (r - 10.0).max(6.0 - r) as f32;
                }
            }
        }
        let affine = DMat4::IDENTITY;
        let solid = transmittance_from_distance(&sdf, [1.0; 3], None);
        let uncut = sweep_octants(&solid, dims);
        let cut_by = |planes: &[([f64; 3], f64)]| {
            let mut tau = solid.clone();
            open_cut(&mut tau, dims, &affine, planes).then_some(tau)
        };
        // A plane past the grid cuts nothing.
        assert!(cut_by(&[([1.0, 0.0, 0.0], 40.0)]).is_none());
        // Within the grid but past the shell (x = 28): the transmittance is the uncut one.
        assert_eq!(cut_by(&[([2.0, 0.0, 0.0], 56.0)]).unwrap(), solid);
        let tau = cut_by(&[([2.0, 0.0, 0.0], 32.0)]).unwrap();
        // Past the plane, open; the plane's own voxels half open; the shell before it solid.
        assert_eq!(tau[30 + n * (16 + n * 16)], 255);
        assert_eq!(tau[16 + n * (16 + n * 24)], 128);
        assert_eq!(tau[8 + n * (16 + n * 16)], 0);
        // With a subsurface opacity the solid lets light in, the removed half-space all of it.
        let soft = transmittance_from_distance(&sdf, [1.0; 3], Some(0.5));
        assert_eq!((soft[8 + n * (16 + n * 16)], soft[16]), (128, 255));
        let cut = sweep_octants(&tau, dims);
        // In the cavity, four voxels in front of the cut.
        let p = 12 + n * (16 + n * 16);
        let sky_x = |s: usize| -crate::distance_sweep::SWEEP_DIRECTIONS[s][0];
        for s in 0..8 {
            assert!(uncut.v(s, p) < 0.02, "octant {s} uncut: {}", uncut.v(s, p));
            if sky_x(s) > 0 {
                assert!(
                    cut.v(s, p) > 0.2,
                    "octant {s} towards the cut: {}",
                    cut.v(s, p)
                );
            } else {
                assert!(
                    cut.v(s, p) < 0.02,
                    "octant {s} away from the cut: {}",
                    cut.v(s, p)
                );
            }
        }
    }

    fn sweep_scalar(values: &[f32], dims: [usize; 3]) -> OctantFields {
        let opts = DistanceOptions::default();
        let init = classify_and_initialise(values, dims, [1.0; 3], &opts);
        let tau = transmittance(&init, None);
        sweep_octants(&tau, dims)
    }

    /// Straightforward eq. (6) with boundary = sky, for comparison with the lockstep sweep.
    fn reference(tau: &[u8], dims: [usize; 3], s: usize) -> Vec<f32> {
        let [nx, ny, nz] = dims;
        let d = SWEEP_DIRECTIONS[s];
        let mut v = vec![0.0f32; nx * ny * nz];
        let idx = |i: usize, j: usize, k: usize| i + nx * (j + ny * k);
        let order = |n: usize, sgn: i32| -> Vec<usize> {
            if sgn > 0 {
                (0..n).collect()
            } else {
                (0..n).rev().collect()
            }
        };
        for &k in &order(nz, d[2]) {
            for &j in &order(ny, d[1]) {
                for &i in &order(nx, d[0]) {
                    let w = |ii: isize, jj: isize, kk: isize| -> f32 {
                        if ii < 0
                            || jj < 0
                            || kk < 0
                            || ii >= nx as isize
                            || jj >= ny as isize
                            || kk >= nz as isize
                        {
                            1.0
                        } else {
                            let q = idx(ii as usize, jj as usize, kk as usize);
                            v[q] * tau[q] as f32 / 255.0
                        }
                    };
                    let (ii, jj, kk) = (i as isize, j as isize, k as isize);
                    v[idx(i, j, k)] = (w(ii - d[0] as isize, jj, kk)
                        + w(ii, jj - d[1] as isize, kk)
                        + w(ii, jj, kk - d[2] as isize))
                        / 3.0;
                }
            }
        }
        v
    }

    #[test]
    fn lockstep_sweep_equals_the_plain_recurrence() {
        let dims = [9, 7, 6];
        let values: Vec<f32> = (0..9 * 7 * 6)
            .map(|i| ((i * 7919) % 23) as f32 - 11.0)
            .collect();
        let init = classify_and_initialise(&values, dims, [1.0; 3], &DistanceOptions::default());
        let tau = transmittance(&init, None);
        let f = sweep_octants(&tau, dims);
        for s in 0..8 {
            let r = reference(&tau, dims, s);
            for (a, b) in f.octants[s].iter().zip(&r) {
                assert!(
                    (*a as f32 / 255.0 - b).abs() <= 0.5 / 255.0 + 1e-6,
                    "octant {s}: {a} vs {b}"
                );
            }
        }
    }

    #[test]
    fn empty_grid_is_open_sky_and_a_slab_shadows_the_octants_below() {
        // Nothing inside: every octant sees the sky everywhere.
        let dims = [6, 5, 4];
        let f = sweep_scalar(&vec![-1.0; 120], dims);
        assert!(f.octants.iter().all(|o| o.iter().all(|&v| v == 255)));
        // A slab: inside (value >= 0) for k <= 3, surface at k = 3.5.
        let dims = [20, 20, 10];
        let values: Vec<f32> = (0..4000).map(|i| 3.5 - (i / 400) as f32).collect();
        let f = sweep_scalar(&values, dims);
        // Layer k = 5, 1.5 above the surface: octants whose sky is above (sweeps 5..8, z
        // direction -1) see the open sky.
        let idx = |i: usize, j: usize, k: usize| i + 20 * (j + 20 * k);
        for s in 4..8 {
            assert!(
                f.v(s, idx(10, 10, 5)) > 0.99,
                "octant {s}: {}",
                f.v(s, idx(10, 10, 5))
            );
        }
        // Octants whose sky is below see the slab: dark just above it.
        for s in 0..4 {
            assert!(
                f.v(s, idx(10, 10, 5)) < 0.6,
                "octant {s}: {}",
                f.v(s, idx(10, 10, 5))
            );
        }
    }

    #[test]
    fn surface_layer_of_a_flat_top_settles_at_one_half() {
        // Surface exactly through a voxel layer (tau = 0.5 there): the fixed point of
        // V = (2 V t + 1) / 3 with t = 1/2 is V = 1/2 for the upper octants: the paper's
        // "darkened flat surfaces".
        let dims = [40, 40, 12];
        let values: Vec<f32> = (0..40 * 40 * 12).map(|i| 5.0 - (i / 1600) as f32).collect();
        let f = sweep_scalar(&values, dims);
        let v = f.v(7, 20 + 40 * (20 + 40 * 5));
        assert!((v - 0.5).abs() < 0.02, "{v}");
    }

    #[test]
    fn subsurface_transmittance_follows_the_derived_eq8() {
        // A solid ball in a 24^3 grid.
        let dims = [24, 24, 24];
        let values: Vec<f32> = (0..24 * 24 * 24)
            .map(|i| {
                let (x, y, z) = (
                    (i % 24) as f32 - 11.5,
                    ((i / 24) % 24) as f32 - 11.5,
                    (i / 576) as f32 - 11.5,
                );
                6.0 - (x * x + y * y + z * z).sqrt()
            })
            .collect();
        let init = classify_and_initialise(&values, dims, [1.0; 3], &DistanceOptions::default());
        let plain = sweep_octants(&transmittance(&init, None), dims);
        // alpha = 1 is eq. (7).
        assert_eq!(sweep_octants(&transmittance(&init, Some(1.0)), dims), plain);
        // alpha = 0: fully transparent, every octant sees the sky everywhere.
        let clear = sweep_octants(&transmittance(&init, Some(0.0)), dims);
        assert!(clear.octants.iter().all(|o| o.iter().all(|&v| v == 255)));
        // In between, light reaches the far side of the ball: the shadowed side brightens.
        let half = sweep_octants(&transmittance(&init, Some(0.5)), dims);
        let behind = 12 + 24 * (12 + 24 * 20); // above the ball, in the shadow of sweeps 1..4
        assert!(
            half.octants[0][behind] > plain.octants[0][behind],
            "{} vs {}",
            half.octants[0][behind],
            plain.octants[0][behind]
        );
        assert!(half.octants[0][behind] < 255);
    }

    #[test]
    fn sky_directions_follow_the_affine() {
        let id = DMat4::IDENTITY;
        assert!((sky_direction_world(0, &id) - DVec3::splat(-1.0).normalize()).length() < 1e-12);
        // A flipped x axis flips the world x of every sky.
        let flip = DMat4::from_scale(DVec3::new(-2.0, 1.0, 1.0));
        let a = sky_direction_world(0, &flip);
        assert!(a.x > 0.0 && a.y < 0.0 && a.z < 0.0);
    }
}
