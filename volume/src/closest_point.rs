//! Signed distance to an isosurface by closest points: the default distance of `umbra sweep`,
//! with fast sweeping ([`crate::distance_sweep`]) kept as the paper's method.
//!
//! # Method
//! 1. The band of [`crate::distance_sweep::classify_and_initialise`]: every voxel with a
//!    neighbour on the other side of the surface, with the point `s_b = x_b + o_b` of the local
//!    surface its initial estimate measures to ([`SurfacePoint`]: along the gradient for the
//!    default `gradient` initialisation, so `|o_b|` is the band value fast sweeping starts from).
//! 2. An exact Euclidean feature transform of the band voxels: for every voxel `x` the band
//!    voxel `b(x)` nearest to it on the grid (weighted by the spacings), by three separable
//!    passes (x: nearest band voxel in the row; y and z: the lower envelope of parabolas
//!    `h_a^2 (p - q)^2 + f(q)` of Felzenszwalb and Huttenlocher, "Distance transforms of sampled
//!    functions", Theory of Computing 8, 2012), carrying the band voxel's id.
//! 3. `D(x)`: the distance to `b(x)`'s surface patch (a disk about `s_b`, [`DISK_RADIUS`]),
//!    negative inside; and where that is under [`NEIGHBOUR_REACH`] of the largest spacing, the
//!    least of it and the distances `|x - s_b(y)|` to the surface points of the six neighbours'
//!    winners `b(y)` (a step of vector propagation). A band voxel's nearest band voxel is itself,
//!    so it keeps its initial estimate unless a neighbour's surface point is nearer.
//!
//! # Accuracy (docs/accuracy.md measures it on analytic solids)
//! Every `s_b` lies on the local linear surface, so `D(x)` is a distance to a point near the
//! surface, not a first-order upwind solution: the point-source error of fast sweeping (one to
//! one and a half voxels too far beside convex corners, where the distance field is that of a
//! point) is absent. Its own error is the gap between the nearest band *voxel* and the band
//! voxel with the nearest surface *point*: for a plane at `D` voxels, with the feet of
//! neighbouring band voxels up to half a voxel apart laterally, `sqrt(D^2 + l^2) - D <= l^2 / 2D`
//! with `l <= sqrt(2)/2`, largest just outside the band and falling as `1/D`. Where the band
//! voxel's estimate is poor (thin features sampled by one voxel, noise), so is the distance
//! behind it, as with sweeping.
//!
//! # Near the surface
//! The nearest band voxel on the grid (weighed by the spacings) need not hold the nearest
//! surface point: the points lie up to half a voxel's diagonal from their voxels, so on a noisy
//! or anisotropic surface a voxel's winner can be a band voxel two fine steps away whose point
//! is far, while a band voxel one coarse step away has a near one (the CT head headsq, 3.2 x 3.2
//! x 1.5 mm: 6.07 mm where the nearest surface point is 1.46 mm; near-surface maximum error 3.07
//! voxels, fast sweeping's 1.63). The winners of the six neighbours hold the nearer point there;
//! taking their points (not patches, whose disks reach past a noisy neighbour's surface and bias
//! the distance low: neghip's means 6-12% worse than without the step, a prototype measured in
//! docs/accuracy.md) bounds the error: near-surface maximum 1.60 on headsq, 0.76 against 1.11
//! on neghip (docs/accuracy.md). A voxel whose true distance is within a largest spacing has
//! `D(x)` at most that plus both points' offsets from their voxels (up to half a diagonal
//! each), so the reach is three largest spacings (6 mm, about two, left headsq's maximum at
//! 3.07). Cost: about 5-15% of `umbra sweep`'s compute at 256^3
//! (docs/benchmarks.md).
//!
//! # Cost
//! Three passes over the grid, each `O(N)` whatever the content (no rounds to convergence),
//! each parallel over planes or rows; the band is a small fraction of the voxels.

use crate::distance_sweep::{DistanceField, Initial};
use rayon::prelude::*;

/// Radius of the surface patch around each band voxel's surface point, in voxels of the
/// smallest spacing (see the module doc; chosen by the measurements in docs/accuracy.md).
pub const DISK_RADIUS: f32 = 0.7;

/// No band voxel in this row/column (yet).
const NONE: u32 = u32::MAX;

/// A pointer shared by the threads of the last pass, each writing the rows of its own `j`.
#[derive(Clone, Copy)]
struct SharedOut(*mut u32);
// SAFETY: threads write disjoint elements (see `pass_z`).
unsafe impl Send for SharedOut {}
unsafe impl Sync for SharedOut {}

impl SharedOut {
    /// The pointer (a method, so that closures capture the `Sync` wrapper, not the field).
    fn ptr(self) -> *mut u32 {
        self.0
    }
}

/// A band voxel by id: its x and y on the grid (what the passes weigh).
#[derive(Clone, Copy)]
struct Site {
    x: f32,
    y: f32,
}

/// A band voxel's surface patch: the voxel on the grid, the offset from it to its surface point
/// (world units) and the unit normal there (zero where the offset is). The distance from a voxel
/// is computed from the index difference and the offset, so a band voxel's own distance is its
/// estimate to the last bit, however small (an absolute surface point would round it away).
#[derive(Clone, Copy)]
struct Patch {
    grid: [f32; 3],
    offset: [f32; 3],
    normal: [f32; 3],
}

/// Signed distance by closest points (see the module doc). Band voxels keep their initial
/// estimate; with an empty band every distance is infinite (positive outside, negative inside),
/// as with sweeping.
pub fn closest_point_distance(init: Initial) -> DistanceField {
    let Initial {
        dims,
        spacing,
        inside,
        band,
        nan_count,
        surface,
        scratch,
    } = init;
    let [nx, ny, nz] = dims;
    let n = nx * ny * nz;
    assert!(
        surface.len() < NONE as usize,
        "more band voxels than ids: {}",
        surface.len()
    );
    let plane = nx * ny;
    let (sites, patches): (Vec<Site>, Vec<Patch>) = surface
        .par_iter()
        .map(|s| {
            let g = [s.index % nx, (s.index / nx) % ny, s.index / plane];
            let o = s.offset;
            let len = (o[0] * o[0] + o[1] * o[1] + o[2] * o[2]).sqrt();
            (
                Site {
                    x: g[0] as f32,
                    y: g[1] as f32,
                },
                Patch {
                    grid: g.map(|g| g as f32),
                    offset: o,
                    normal: if len > 0.0 {
                        o.map(|o| o / len)
                    } else {
                        [0.0; 3]
                    },
                },
            )
        })
        .unzip();
    // First band id of each row (ids are in voxel order): a count per row and a prefix sum.
    let mut row_start = vec![0usize; ny * nz + 1];
    for s in &surface {
        row_start[s.index / nx + 1] += 1;
    }
    for r in 0..ny * nz {
        row_start[r + 1] += row_start[r];
    }
    drop(surface);
    // Zeroed pages come free; pass x writes every element.
    // Pass x writes every element: the samples' old buffer serves, else zeroed pages.
    let mut feature = if scratch.len() == n {
        into_u32(scratch)
    } else {
        drop(scratch);
        crate::memory::zeroed(n, 0u32)
    };
    if n == 0 {
        return DistanceField {
            dims,
            distance: Vec::new(),
            iterations: 0,
            converged: true,
            band,
            nan_count,
            rows_processed: 0,
        };
    }
    // Pass x: the nearest band voxel in each row.
    feature.par_chunks_mut(nx).enumerate().for_each(|(r, row)| {
        row.fill(NONE);
        nearest_in_row(row, row_start[r] as u32..row_start[r + 1] as u32, &sites);
    });
    let h2 = spacing.map(|h| h as f64 * h as f64);
    let radius = DISK_RADIUS * spacing.iter().cloned().fold(f32::INFINITY, f32::min);
    // Passes y and z work on blocks of `BLOCK` adjacent columns: each element of a block is
    // gathered from (and returned to) a contiguous run of a grid row, and the envelopes then
    // run down the block's columns inside the cache.
    // Pass y: per plane, the lower envelope down each column.
    feature.par_chunks_mut(plane).for_each_init(
        || (Envelope::new(ny), vec![NONE; ny * BLOCK]),
        |(env, tile), out| {
            for i0 in (0..nx).step_by(BLOCK) {
                let w = BLOCK.min(nx - i0);
                for j in 0..ny {
                    tile[j * BLOCK..j * BLOCK + w]
                        .copy_from_slice(&out[i0 + nx * j..i0 + nx * j + w]);
                }
                for c in 0..w {
                    let i = (i0 + c) as f64;
                    env.f.clear();
                    env.f.extend((0..ny).map(|j| {
                        let b = tile[j * BLOCK + c];
                        if b == NONE {
                            f64::INFINITY
                        } else {
                            let dx = i - sites[b as usize].x as f64;
                            h2[0] * dx * dx
                        }
                    }));
                    env.solve(h2[1]);
                    for j in 0..ny {
                        out[i0 + c + nx * j] = match env.winner[j] {
                            NONE => NONE,
                            q => tile[q as usize * BLOCK + c],
                        };
                    }
                }
            }
        },
    );
    // Pass z: per y, the lower envelope along z; a task reads and writes only the elements of
    // its own y.
    let out = SharedOut(feature.as_mut_ptr());
    let sites = &sites;
    (0..ny).into_par_iter().for_each_init(
        || {
            (
                Envelope::new(nz),
                vec![NONE; nz * BLOCK],
                vec![NONE; nz * BLOCK],
            )
        },
        |(env, tile, win), j| {
            let base = out.ptr();
            for i0 in (0..nx).step_by(BLOCK) {
                let w = BLOCK.min(nx - i0);
                for k in 0..nz {
                    let r = i0 + nx * (j + ny * k);
                    // SAFETY: as below; the run is not being written while read.
                    let run = unsafe { std::slice::from_raw_parts(base.add(r), w) };
                    tile[k * BLOCK..k * BLOCK + w].copy_from_slice(run);
                }
                for c in 0..w {
                    let i = i0 + c;
                    env.f.clear();
                    env.f.extend((0..nz).map(|k| {
                        let b = tile[k * BLOCK + c];
                        if b == NONE {
                            f64::INFINITY
                        } else {
                            let s = &sites[b as usize];
                            let dx = i as f64 - s.x as f64;
                            let dy = j as f64 - s.y as f64;
                            h2[0] * dx * dx + h2[1] * dy * dy
                        }
                    }));
                    env.solve(h2[2]);
                    for k in 0..nz {
                        win[k * BLOCK + c] = match env.winner[k] {
                            NONE => NONE,
                            q => tile[q as usize * BLOCK + c],
                        };
                    }
                }
                for k in 0..nz {
                    let r = i0 + nx * (j + ny * k);
                    // SAFETY: this run of row (j, k) is written by the task of this j alone,
                    // and lies inside the grid.
                    let row = unsafe { std::slice::from_raw_parts_mut(base.add(r), w) };
                    row.copy_from_slice(&win[k * BLOCK..k * BLOCK + w]);
                }
            }
        },
    );
    // The distance to the winner's surface patch, and near the surface the nearest of the six
    // neighbours' winners' surface points, plane by plane in place as `f32` bits. A task owns a
    // run of planes; it keeps the winners of the plane it writes (its rows read each other's)
    // and of the one before as it overwrites them, and reads the plane after from the grid -
    // or, for the plane after its last, from a copy taken before any task wrote (another task
    // owns it).
    let hmax = spacing.iter().cloned().fold(0.0f32, f32::max);
    let ctx = Refine {
        dims,
        spacing,
        radius,
        reach: NEIGHBOUR_REACH * hmax,
        patches: &patches,
    };
    let per_task = nz.div_ceil(4 * rayon::current_num_threads()).max(1);
    // The planes on either side of each boundary between tasks, as they were before any task
    // wrote: `edge[t]` = (the plane before task t's first, the plane after task t's last).
    let copy = |k: usize| feature[k * plane..(k + 1) * plane].to_vec();
    let tasks = nz.div_ceil(per_task);
    let edge: Vec<[Option<Vec<u32>>; 2]> = (0..tasks)
        .map(|t| {
            let (k0, k1) = (t * per_task, ((t + 1) * per_task).min(nz));
            [(k0 > 0).then(|| copy(k0 - 1)), (k1 < nz).then(|| copy(k1))]
        })
        .collect();
    feature
        .par_chunks_mut(per_task * plane)
        .zip(inside.par_chunks(per_task * plane))
        .zip(edge.par_iter())
        .enumerate()
        .for_each_init(
            || (vec![NONE; plane], vec![NONE; plane]),
            |(prev, cur), (t, ((slab, ins), [before, after]))| {
                let planes = slab.len() / plane;
                if let Some(b) = before {
                    prev.copy_from_slice(b);
                }
                for l in 0..planes {
                    let (this, rest) = slab[l * plane..].split_at_mut(plane);
                    let below = (l > 0 || before.is_some()).then_some(prev.as_slice());
                    let above = if l + 1 < planes {
                        Some(&rest[..plane])
                    } else {
                        after.as_deref()
                    };
                    let k = t * per_task + l;
                    ctx.plane(
                        k,
                        this,
                        cur,
                        [below, above],
                        &ins[l * plane..(l + 1) * plane],
                    );
                    std::mem::swap(prev, cur);
                }
            },
        );
    DistanceField {
        dims,
        distance: into_f32(feature),
        iterations: 0,
        converged: true,
        band,
        nan_count,
        rows_processed: 0,
    }
}

/// The buffer reinterpreted as ids (its contents are overwritten).
fn into_u32(v: Vec<f32>) -> Vec<u32> {
    let mut v = std::mem::ManuallyDrop::new(v);
    // SAFETY: as in `into_f32`: same size and alignment, every bit pattern valid.
    unsafe { Vec::from_raw_parts(v.as_mut_ptr() as *mut u32, v.len(), v.capacity()) }
}

/// The buffer reinterpreted: every element holds the bits of an `f32`.
fn into_f32(v: Vec<u32>) -> Vec<f32> {
    let mut v = std::mem::ManuallyDrop::new(v);
    // SAFETY: u32 and f32 have the same size and alignment and every bit pattern is a valid
    // f32; the allocation changes owner, not layout.
    unsafe { Vec::from_raw_parts(v.as_mut_ptr() as *mut f32, v.len(), v.capacity()) }
}

/// Columns per block in the passes along y and z.
const BLOCK: usize = 16;

/// The distance from a point at `d` from a band voxel's surface point to the surface patch
/// there: a disk of radius `radius` about the point, normal to `normal` (a point where the
/// normal is zero).
#[inline(always)]
fn patch_distance(d: [f32; 3], normal: [f32; 3], radius: f32) -> f32 {
    let dn = d[0] * normal[0] + d[1] * normal[1] + d[2] * normal[2];
    let d2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
    if normal == [0.0; 3] {
        return d2.sqrt();
    }
    let lateral = (d2 - dn * dn).max(0.0).sqrt();
    let e = (lateral - radius).max(0.0);
    (dn * dn + e * e).sqrt()
}

/// Voxels nearer the surface than this many of the largest spacing also measure to the surface
/// points of their six neighbours' winners (see the module doc, "Near the surface").
pub const NEIGHBOUR_REACH: f32 = 3.0;

/// What the last pass needs to turn winners into distances.
struct Refine<'a> {
    dims: [usize; 3],
    spacing: [f32; 3],
    /// The patches' radius (world units).
    radius: f32,
    /// Distance (world units) under which the neighbours' winners are tried.
    reach: f32,
    patches: &'a [Patch],
}

impl Refine<'_> {
    /// The vector from band voxel `b`'s surface point to voxel `(i, j, k)`.
    #[inline(always)]
    fn to_voxel(&self, b: u32, i: usize, j: usize, k: usize) -> ([f32; 3], &Patch) {
        let s = &self.patches[b as usize];
        let (g, o, h) = (s.grid, s.offset, self.spacing);
        (
            [
                (i as f32 - g[0]) * h[0] - o[0],
                (j as f32 - g[1]) * h[1] - o[1],
                (k as f32 - g[2]) * h[2] - o[2],
            ],
            s,
        )
    }

    /// Turns row `(j, k)`'s winners (`out`, in place) into their patch distances (as `f32`
    /// bits), keeping the winners in `ids`.
    #[inline(never)]
    fn row(&self, j: usize, k: usize, out: &mut [u32], ids: &mut [u32]) {
        let (jf, kf) = (j as f32, k as f32);
        for (i, (o, id)) in out.iter_mut().zip(ids).enumerate() {
            let b = *o;
            *id = b;
            *o = match b {
                NONE => f32::INFINITY,
                b => {
                    let s = &self.patches[b as usize];
                    let (g, f, h) = (s.grid, s.offset, self.spacing);
                    let d = [
                        (i as f32 - g[0]) * h[0] - f[0],
                        (jf - g[1]) * h[1] - f[1],
                        (kf - g[2]) * h[2] - f[2],
                    ];
                    patch_distance(d, s.normal, self.radius)
                }
            }
            .to_bits();
        }
    }

    /// Turns plane `k`'s winners (`grid`, in place) into signed distances (as `f32` bits),
    /// keeping its winners in `ids` for the plane above; `planes` holds the winners of the
    /// planes below and above (`None` outside the grid). Beyond `reach` a voxel's distance is
    /// its winner's patch distance; nearer, the least of that and the distances to the surface
    /// points (not patches: their disks would reach past a noisy neighbour's surface and bias
    /// the distance low) of the six neighbours' winners.
    fn plane(
        &self,
        k: usize,
        grid: &mut [u32],
        ids: &mut [u32],
        planes: [Option<&[u32]>; 2],
        inside: &[bool],
    ) {
        let [nx, ny, _] = self.dims;
        for j in 0..ny {
            let v0 = j * nx;
            let (out, rest) = grid[v0..].split_at_mut(nx);
            let up = rest.get(..nx);
            // The winners' patch distances (the voxels far from the surface are done).
            self.row(j, k, out, &mut ids[v0..v0 + nx]);
            // Near the surface, the neighbours' winners' surface points.
            for (i, (o, &ins)) in out.iter_mut().zip(&inside[v0..v0 + nx]).enumerate() {
                let mut best = f32::from_bits(*o);
                if best < self.reach {
                    let v = v0 + i;
                    let b0 = ids[v];
                    let candidates = [
                        (i > 0).then(|| ids[v - 1]),
                        (i + 1 < nx).then(|| ids[v + 1]),
                        (j > 0).then(|| ids[v - nx]),
                        up.map(|u| u[i]),
                        planes[0].map(|p| p[v]),
                        planes[1].map(|p| p[v]),
                    ];
                    // Squared distances, one root at the end.
                    let own = best * best;
                    let mut best2 = own;
                    for b in candidates.into_iter().flatten() {
                        if b != b0 && b != NONE {
                            let (d, _) = self.to_voxel(b, i, j, k);
                            best2 = best2.min(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
                        }
                    }
                    if best2 < own {
                        best = best2.sqrt();
                    }
                }
                *o = if ins { -best } else { best }.to_bits();
            }
        }
    }
}

/// Fills `row` with the id of the nearest band voxel among `ids` (in ascending x, positions in
/// `xs`); ties go to the lower x. A row without band voxels stays `NONE`.
fn nearest_in_row(row: &mut [u32], ids: std::ops::Range<u32>, sites: &[Site]) {
    if ids.is_empty() {
        return;
    }
    let mut prev: Option<(u32, usize)> = None;
    for id in ids {
        let x = sites[id as usize].x as usize;
        match prev {
            None => row[..=x].fill(id),
            Some((pid, px)) => {
                // (px, x]: the lower half (ties included) to the previous voxel.
                let mid = (px + x) / 2;
                row[px + 1..=mid].fill(pid);
                row[mid + 1..=x].fill(id);
            }
        }
        prev = Some((id, x));
    }
    let (pid, px) = prev.unwrap();
    row[px + 1..].fill(pid);
}

/// The lower envelope of the parabolas `w (p - q)^2 + f(q)` over a column (Felzenszwalb and
/// Huttenlocher's algorithm), with its buffers.
struct Envelope {
    /// `f(q)`; infinite where the column has no band voxel.
    f: Vec<f64>,
    /// The parabola (position `q`) that is lowest at each `p`, or `NONE`.
    winner: Vec<u32>,
    v: Vec<u32>,
    /// `f(q) + w q^2` of each parabola of `v`.
    g: Vec<f64>,
    /// Where each parabola of `v` starts to be lowest, as (numerator, positive denominator);
    /// the first is minus infinity, (-1, 0).
    z: Vec<(f64, f64)>,
}

impl Envelope {
    fn new(n: usize) -> Self {
        Envelope {
            f: Vec::with_capacity(n),
            winner: vec![NONE; n],
            v: vec![0; n],
            g: vec![0.0; n],
            z: vec![(0.0, 0.0); n],
        }
    }

    /// Fills `winner` for `f` and weight `w` (the squared spacing along the column).
    ///
    /// Division-free: the intersection of parabolas `q > v`,
    /// `s = ((f(q) + w q^2) - (f(v) + w v^2)) / (2 w (q - v))`, is kept as numerator and
    /// (positive) denominator and compared by cross-multiplication.
    fn solve(&mut self, w: f64) {
        let n = self.f.len();
        self.winner.resize(n, NONE);
        self.v.resize(n, 0);
        self.g.resize(n, 0.0);
        self.z.resize(n, (0.0, 0.0));
        let (f, v, g, z) = (
            &self.f[..n],
            &mut self.v[..n],
            &mut self.g[..n],
            &mut self.z[..n],
        );
        let two_w = 2.0 * w;
        // The envelope is v[..len]; z[k] = (numerator, positive denominator) of where parabola
        // v[k] starts to be the lowest, z[0] = (-1, 0) standing for minus infinity.
        let mut len = 0usize;
        for (q, &fq) in f.iter().enumerate() {
            if fq == f64::INFINITY {
                continue;
            }
            let qf = q as f64;
            let gq = fq + w * qf * qf;
            let mut s = (-1.0f64, 0.0f64);
            while len > 0 {
                let k = len - 1;
                let num = gq - g[k];
                let den = two_w * (qf - v[k] as f64);
                let (zn, zd) = z[k];
                // num / den <= zn / zd (den > 0; zd = 0 is minus infinity: never).
                if zd > 0.0 && num * zd <= zn * den {
                    len = k;
                } else {
                    s = (num, den);
                    break;
                }
            }
            v[len] = q as u32;
            g[len] = gq;
            z[len] = s;
            len += 1;
        }
        if len == 0 {
            self.winner.fill(NONE);
            return;
        }
        let mut k = 0;
        let last = len - 1;
        let mut next = if last > 0 { z[1] } else { (1.0, 0.0) };
        for (p, win) in self.winner.iter_mut().enumerate() {
            // z[k + 1] < p.
            while k < last && next.0 < p as f64 * next.1 {
                k += 1;
                next = if k < last { z[k + 1] } else { (1.0, 0.0) };
            }
            *win = v[k];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::distance_sweep::{classify_and_initialise, DistanceOptions};

    /// Brute force: for every voxel, the distances to the surface patches of all the band
    /// voxels nearest to it on the grid (ties: all of them).
    fn brute(init: &Initial) -> Vec<Vec<f32>> {
        let [nx, ny, _] = init.dims;
        let h = init.spacing;
        let pos = |v: usize| {
            [
                (v % nx) as f32 * h[0],
                ((v / nx) % ny) as f32 * h[1],
                (v / (nx * ny)) as f32 * h[2],
            ]
        };
        (0..init.inside.len())
            .map(|v| {
                let p = pos(v);
                let g = |s: &crate::distance_sweep::SurfacePoint| -> f32 {
                    let q = pos(s.index);
                    (0..3).map(|a| (p[a] - q[a]).powi(2)).sum()
                };
                let best = init.surface.iter().map(g).fold(f32::INFINITY, f32::min);
                init.surface
                    .iter()
                    .filter(|s| g(s) <= best * (1.0 + 1e-5))
                    .map(|s| {
                        let q = pos(s.index);
                        let d: [f32; 3] = std::array::from_fn(|a| p[a] - q[a] - s.offset[a]);
                        let normal = s.offset.map(|o| o / s.distance);
                        let normal = if s.distance > 0.0 { normal } else { [0.0; 3] };
                        patch_distance(d, normal, DISK_RADIUS * h[0].min(h[1]).min(h[2]))
                    })
                    .collect()
            })
            .collect()
    }

    fn blob(dims: [usize; 3]) -> Vec<f32> {
        // Two spheres and a slab: several band components, rows without band voxels.
        let mut v = Vec::new();
        for k in 0..dims[2] {
            for j in 0..dims[1] {
                for i in 0..dims[0] {
                    let (x, y, z) = (i as f32, j as f32, k as f32);
                    let a =
                        5.0 - ((x - 6.0).powi(2) + (y - 7.0).powi(2) + (z - 5.0).powi(2)).sqrt();
                    let b =
                        3.2 - ((x - 15.0).powi(2) + (y - 4.0).powi(2) + (z - 9.0).powi(2)).sqrt();
                    let c = 1.3 - (y + 0.4 * x - 16.0).abs();
                    v.push(a.max(b).max(c));
                }
            }
        }
        v
    }

    /// The closest-point distance of a copy of `init` (kept for the checks).
    fn distance_of_a_copy(init: &Initial) -> DistanceField {
        closest_point_distance(Initial {
            surface: init.surface.clone(),
            inside: init.inside.clone(),
            scratch: Vec::new(),
            ..*init
        })
    }

    /// The distance from voxel `v` to band voxel `s`'s surface point.
    fn point_distance(init: &Initial, v: usize, s: &crate::distance_sweep::SurfacePoint) -> f32 {
        let [nx, ny, _] = init.dims;
        let g = |v: usize| [v % nx, (v / nx) % ny, v / (nx * ny)];
        let (p, q) = (g(v), g(s.index));
        (0..3)
            .map(|a| ((p[a] as f32 - q[a] as f32) * init.spacing[a] - s.offset[a]).powi(2))
            .sum::<f32>()
            .sqrt()
    }

    #[test]
    fn the_feature_transform_finds_the_nearest_band_voxel() {
        // Anisotropic spacing, odd sizes: the distance is that to the patch of one of the band
        // voxels nearest on the grid (ties: any of them) or, within the reach, possibly less:
        // then that to the surface point of a band voxel nearest on the grid to one of the six
        // neighbours.
        let dims = [19, 13, 11];
        let v = blob(dims);
        for spacing in [[1.0f32, 1.0, 1.0], [0.7, 1.0, 1.6]] {
            let init = classify_and_initialise(&v, dims, spacing, &DistanceOptions::default());
            assert!(init.band > 100);
            let want = brute(&init);
            let reach = NEIGHBOUR_REACH * spacing.iter().cloned().fold(0.0, f32::max);
            let [nx, ny, nz] = dims;
            let nearest = |v: usize| -> Vec<usize> {
                let g = |v: usize| [v % nx, (v / nx) % ny, v / (nx * ny)];
                let d2 = |s: &crate::distance_sweep::SurfacePoint| -> f32 {
                    let (p, q) = (g(v), g(s.index));
                    (0..3)
                        .map(|a| ((p[a] as f32 - q[a] as f32) * spacing[a]).powi(2))
                        .sum()
                };
                let best = init.surface.iter().map(d2).fold(f32::INFINITY, f32::min);
                (0..init.surface.len())
                    .filter(|&b| d2(&init.surface[b]) <= best * (1.0 + 1e-5))
                    .collect()
            };
            let (mut refined, mut near) = (0, 0);
            let df = distance_of_a_copy(&init);
            for (i, (&got, w)) in df.distance.iter().zip(&want).enumerate() {
                assert_eq!(got.is_sign_negative(), init.inside[i], "sign at {i}");
                let got = got.abs();
                let own = w.iter().any(|&w| (got - w).abs() < 1e-4);
                // The chosen winner's patch distance is one of `w`: at most the largest.
                let (least, most) = w
                    .iter()
                    .fold((f32::INFINITY, 0.0f32), |(a, b), &w| (a.min(w), b.max(w)));
                if least < reach {
                    near += 1;
                }
                if own {
                    continue;
                }
                // Less than the own winner's: within the reach, a neighbour's winner's point.
                assert!(
                    got < most && least < reach + 1e-4,
                    "voxel {i}: {got} is none of {w:?} (reach {reach})"
                );
                let (x, y, z) = (i % nx, (i / nx) % ny, i / (nx * ny));
                let mut neighbours = Vec::new();
                for (c, n, step) in [(x, nx, 1), (y, ny, nx), (z, nz, nx * ny)] {
                    if c > 0 {
                        neighbours.push(i - step);
                    }
                    if c + 1 < n {
                        neighbours.push(i + step);
                    }
                }
                assert!(
                    neighbours.iter().flat_map(|&n| nearest(n)).any(|b| {
                        (point_distance(&init, i, &init.surface[b]) - got).abs() < 1e-4
                    }),
                    "voxel {i}: {got} is no neighbour's winner's point"
                );
                refined += 1;
            }
            // The rule changed some of the voxels it may change, not all.
            assert!(refined > 0 && refined < near, "{refined} of {near}");
        }
    }

    #[test]
    fn near_a_noisy_anisotropic_surface_the_neighbours_winners_bound_the_error() {
        // A bumpy, noisy slab on a grid 2.13 times finer along z than across (as the CT head
        // headsq_64x64x93, 3.2 x 3.2 x 1.5 mm, where a voxel's nearest band voxel on the grid
        // held a surface point 6.07 mm away against 1.46 mm to the nearest). Reference: the
        // distance to the nearest surface point of all the band voxels (brute force), which is
        // what the transform approximates; near the surface (under a voxel of the smallest
        // spacing) the error is bounded.
        let dims = [20, 20, 36];
        let spacing = [3.2f32, 3.2, 1.5];
        let mut v = Vec::new();
        for k in 0..dims[2] {
            for j in 0..dims[1] {
                for i in 0..dims[0] {
                    let (x, y, z) = (i as f32 * 3.2, j as f32 * 3.2, k as f32 * 1.5);
                    let bump =
                        6.0 * (x * 0.21).sin() * (y * 0.17).cos() + 2.5 * (x * 0.9 + y * 0.7).sin();
                    // Sample noise, a hash of the index in [-1, 1].
                    let h = ((i * 73_856_093) ^ (j * 19_349_663) ^ (k * 83_492_791)) % 1000;
                    let noise = h as f32 / 500.0 - 1.0;
                    v.push(z - 27.0 - bump + 2.0 * noise);
                }
            }
        }
        let init = classify_and_initialise(&v, dims, spacing, &DistanceOptions::default());
        let reference: Vec<f32> = (0..v.len())
            .map(|i| {
                init.surface
                    .iter()
                    .map(|s| point_distance(&init, i, s))
                    .fold(f32::INFINITY, f32::min)
            })
            .collect();
        let df = distance_of_a_copy(&init);
        let worst = df
            .distance
            .iter()
            .zip(&reference)
            .filter(|(_, &r)| r < 1.5)
            .map(|(&d, &r)| (d.abs() - r).abs() / 1.5)
            .fold(0.0f32, f32::max);
        // 0.44 voxels; 1.60 with the grid's nearest band voxel alone (reach 0).
        assert!(worst < 0.7, "largest error near the surface {worst} voxels");
    }

    #[test]
    fn a_patch_is_exact_for_its_plane_and_a_point_without_normal() {
        let n = [0.6f32, 0.0, 0.8];
        // Within the radius laterally: the distance to the plane.
        let d = [0.6 * 2.0 + 0.3, 0.1, 0.8 * 2.0 - 0.225]; // 2 along n, (0.3, 0.1, -0.225) across
        assert!((patch_distance(d, n, 0.7) - 2.0).abs() < 1e-5);
        // Beyond it: to the disk's rim.
        let d = [0.0, 3.0, 0.0];
        assert!((patch_distance(d, n, 0.7) - 2.3).abs() < 1e-5);
        // No normal: the distance to the point.
        let d = [3.0, 4.0, 0.0];
        assert!((patch_distance(d, [0.0; 3], 0.7) - 5.0).abs() < 1e-5);
    }

    #[test]
    fn rows_fill_with_the_nearest_voxel() {
        let xs: Vec<Site> = [2.0, 3.0, 9.0].map(|x| Site { x, y: 0.0 }).to_vec();
        let mut row = [NONE; 12];
        nearest_in_row(&mut row, 0..3, &xs);
        assert_eq!(row, [0, 0, 0, 1, 1, 1, 1, 2, 2, 2, 2, 2]);
        let mut empty = [NONE; 4];
        nearest_in_row(&mut empty, 0..0, &xs);
        assert_eq!(empty, [NONE; 4]);
    }

    #[test]
    fn the_envelope_is_the_minimum_of_the_parabolas() {
        let f = [
            f64::INFINITY,
            4.0,
            f64::INFINITY,
            0.5,
            9.0,
            f64::INFINITY,
            0.0,
            30.0,
        ];
        for w in [1.0, 0.3, 2.5] {
            let mut e = Envelope::new(f.len());
            e.f.extend_from_slice(&f);
            e.solve(w);
            for p in 0..f.len() {
                let val = |q: usize| w * (p as f64 - q as f64).powi(2) + f[q];
                let best = (0..f.len()).map(val).fold(f64::INFINITY, f64::min);
                assert!(
                    (val(e.winner[p] as usize) - best).abs() < 1e-12,
                    "w {w} p {p}"
                );
            }
        }
        let mut none = Envelope::new(3);
        none.f.extend_from_slice(&[f64::INFINITY; 3]);
        none.solve(1.0);
        assert_eq!(none.winner, vec![NONE; 3]);
    }
}
