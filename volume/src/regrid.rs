//! Resampling one grid into another's world: an overlay (a statistical map, a label volume)
//! resampled into the voxels of the primary volume it is drawn over.
//!
//! Both grids are given by their index-to-world affines (voxel `(i, j, k, 1)` to world, as
//! [`crate::Volume::affine`]), samples stored x fastest (`i + nx * (j + ny * k)`). A third matrix,
//! `to_src_world`, maps the destination's world into the source file's world (a registration
//! between the two scans; the identity when both files share a world frame). So destination
//! voxel `(i, j, k)` samples the source at the fractional source index
//!
//! ```text
//! q = inverse(src_affine) * to_src_world * dst_affine * (i, j, k, 1)
//! ```
//!
//! with [`Interp::Linear`] (trilinear, for continuous maps) or [`Interp::Nearest`] (for label
//! volumes: only values present in the source come out). Outside the source the result is NaN,
//! which the renderer draws as "no overlay". `tests/fixtures/overlay/make_fixture.py` checks both
//! against scipy's `map_coordinates`.

use glam::{DMat4, DVec3, DVec4};
use rayon::prelude::*;

/// How a destination voxel samples the source grid.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Interp {
    /// Trilinear interpolation of the eight surrounding source voxels; NaN outside the box of
    /// the source's voxel centres, and NaN when a voxel that contributes is NaN.
    Linear,
    /// The source voxel nearest to the point (halves round up); NaN more than half a voxel
    /// outside the source's voxel centres.
    Nearest,
}

/// How far (in source voxels) outside `[0, n - 1]` [`Interp::Linear`] still accepts a point,
/// clamping it onto the edge: rounding in the matrix products must not cut off the border
/// voxels of a grid resampled onto itself.
pub const EDGE_SLACK: f64 = 1e-6;

/// Fractional indices closer than this to an integer are taken as that integer by
/// [`Interp::Linear`], so that a grid resampled onto itself (where rounding leaves `q` a few
/// ulps off the voxel centres) returns its samples exactly and a NaN voxel does not leak into
/// its neighbours through a weight of 1e-16.
pub const SNAP: f64 = 1e-9;

/// Resamples `src` (a `src_dims` grid with index-to-world map `src_affine`) into the
/// `dst_dims` grid with index-to-world map `dst_affine`; `to_src_world` maps the destination's
/// world into the source's world (see the module documentation). Returns the destination's
/// samples, x fastest.
///
/// For destination voxel `(i, j, k)` let `q = inverse(src_affine) * to_src_world *
/// dst_affine * (i, j, k, 1)` and `n` the source's dims:
/// * [`Interp::Linear`]: when every component of `q` lies in `[0, n - 1]` (with
///   [`EDGE_SLACK`], clamped into it; an axis of one voxel accepts only `q` within the slack of
///   0), the trilinear interpolation of the 8 surrounding voxels; a voxel whose weight is not
///   zero and whose value is NaN makes the result NaN. Otherwise NaN.
/// * [`Interp::Nearest`]: when `q` lies in `[-0.5, n - 0.5)` on every axis, the voxel
///   `floor(q + 0.5)`. Otherwise NaN.
///
/// Errors (not panics) when `src.len()` is not the product of `src_dims`, a grid has an empty
/// axis, a matrix has a non-finite entry, a last row other than `(0, 0, 0, 1)` or (nearly)
/// linearly dependent axes, or the destination has more than [`crate::MAX_SAMPLES`] voxels or
/// cannot be allocated (the error gives its size in MiB). The work is split over the
/// destination's z slices with rayon.
pub fn into_grid(
    src: &[f32],
    src_dims: [usize; 3],
    src_affine: DMat4,
    to_src_world: DMat4,
    dst_dims: [usize; 3],
    dst_affine: DMat4,
    interp: Interp,
) -> Result<Vec<f32>, String> {
    let src_count = voxel_count(src_dims, "source")?;
    if src.len() as u64 != src_count {
        return Err(format!(
            "the source grid {} has {src_count} voxels but {} values were given",
            show_dims(src_dims),
            src.len()
        ));
    }
    check_matrix(src_affine, "the source's affine")?;
    check_matrix(to_src_world, "the transform into the source's world")?;
    check_matrix(dst_affine, "the destination's affine")?;
    let dst_count = voxel_count(dst_dims, "destination")?;
    // In f64 for the messages: exact up to 2^53, and no overflow for any dims.
    let voxels = dst_dims.iter().map(|&d| d as f64).product::<f64>();
    let mib = voxels * 4.0 / (1024.0 * 1024.0);
    if dst_count > crate::MAX_SAMPLES {
        return Err(format!(
            "the destination grid {} has {} voxels ({} MiB as f32), more than the {} umbra \
             resamples into",
            show_dims(dst_dims),
            crate::show_number(voxels),
            crate::show_number(mib.round()),
            crate::MAX_SAMPLES
        ));
    }
    let dst_count = usize::try_from(dst_count).map_err(|_| {
        format!(
            "the destination grid {} ({mib:.0} MiB as f32) does not fit this machine's \
             address space",
            show_dims(dst_dims)
        )
    })?;
    let m = src_affine.inverse() * to_src_world * dst_affine;
    if !m.is_finite() {
        return Err(format!(
            "the source's affine cannot be inverted in f64 (index map {m:?})"
        ));
    }

    let mut out: Vec<f32> = Vec::new();
    out.try_reserve_exact(dst_count).map_err(|_| {
        format!(
            "the destination grid {} needs {mib:.1} MiB, which could not be allocated",
            show_dims(dst_dims)
        )
    })?;
    if same_voxels(m, src_dims, dst_dims) {
        // Every destination voxel lands within SNAP of the source voxel of its own index, so
        // either rule returns that voxel's value: the samples as they are (an overlay on the
        // primary volume's own grid, the common case, costs a copy, not a resampling).
        out.extend_from_slice(src);
        return Ok(out);
    }
    out.resize(dst_count, f32::NAN);

    let [nx, ny, _] = dst_dims;
    let grid = Source {
        data: src,
        dims: src_dims,
    };
    out.par_chunks_mut(nx * ny)
        .enumerate()
        .for_each(|(k, slice)| {
            for j in 0..ny {
                for i in 0..nx {
                    let q = m.transform_point3(DVec3::new(i as f64, j as f64, k as f64));
                    slice[i + nx * j] = match interp {
                        Interp::Linear => grid.linear(q),
                        Interp::Nearest => grid.nearest(q),
                    };
                }
            }
        });
    Ok(out)
}

/// Whether index map `m` (destination index to source index) takes every voxel of a grid of
/// `dst` dims to within [`SNAP`] of the same index in a grid of the same dims `src`: the
/// deviation `m p - p` is affine in `p`, so its largest value over the box is at a corner.
fn same_voxels(m: DMat4, src: [usize; 3], dst: [usize; 3]) -> bool {
    src == dst
        && (0..8).all(|c| {
            let p = DVec3::new(
                ((c & 1) * (dst[0] - 1)) as f64,
                ((c >> 1 & 1) * (dst[1] - 1)) as f64,
                ((c >> 2 & 1) * (dst[2] - 1)) as f64,
            );
            (m.transform_point3(p) - p).abs().max_element() < SNAP
        })
}

/// The source grid being sampled.
struct Source<'a> {
    data: &'a [f32],
    dims: [usize; 3],
}

impl Source<'_> {
    fn at(&self, idx: [usize; 3]) -> f32 {
        self.data[idx[0] + self.dims[0] * (idx[1] + self.dims[1] * idx[2])]
    }

    /// Trilinear interpolation at fractional index `q` (see [`into_grid`]).
    fn linear(&self, q: DVec3) -> f32 {
        let q = q.to_array();
        let mut base = [0usize; 3];
        let mut frac = [0f64; 3];
        for a in 0..3 {
            let hi = (self.dims[a] - 1) as f64;
            // Written so that a NaN q fails the test.
            if !(q[a] >= -EDGE_SLACK && q[a] <= hi + EDGE_SLACK) {
                return f32::NAN;
            }
            let mut x = q[a].clamp(0.0, hi);
            // x >= 0: truncation is the floor (and floor(x + 0.5) the rounding), without the
            // calls to libm's floor and round that f64's methods make on baseline x86-64.
            let r = (x + 0.5) as usize as f64;
            if (x - r).abs() < SNAP {
                x = r;
            }
            let i0 = (x as usize).min(self.dims[a].saturating_sub(2));
            base[a] = i0;
            frac[a] = x - i0 as f64;
        }
        let mut sum = 0.0;
        for corner in 0..8 {
            let mut w = 1.0;
            let mut idx = base;
            for a in 0..3 {
                if corner >> a & 1 == 1 {
                    w *= frac[a];
                    idx[a] += 1;
                } else {
                    w *= 1.0 - frac[a];
                }
            }
            // A zero weight skips the voxel (on an axis of one voxel it lies outside the grid).
            if w == 0.0 {
                continue;
            }
            let v = self.at(idx);
            if v.is_nan() {
                return f32::NAN;
            }
            sum += w * v as f64;
        }
        sum as f32
    }

    /// The nearest voxel to fractional index `q` (see [`into_grid`]).
    fn nearest(&self, q: DVec3) -> f32 {
        let q = q.to_array();
        let mut idx = [0usize; 3];
        for a in 0..3 {
            let n = self.dims[a] as f64;
            if !(q[a] >= -0.5 && q[a] < n - 0.5) {
                return f32::NAN;
            }
            // q + 0.5 >= 0 here: truncation is the floor.
            idx[a] = ((q[a] + 0.5) as usize).min(self.dims[a] - 1);
        }
        self.at(idx)
    }
}

fn show_dims(d: [usize; 3]) -> String {
    format!("{} x {} x {}", d[0], d[1], d[2])
}

/// The voxels of a grid (`what`: "source" or "destination"), refusing empty axes; the product
/// saturates at `u64::MAX` (callers compare it with their cap).
fn voxel_count(dims: [usize; 3], what: &str) -> Result<u64, String> {
    if dims.contains(&0) {
        return Err(format!(
            "the {what} grid {} has an empty axis",
            show_dims(dims)
        ));
    }
    Ok(dims
        .iter()
        .try_fold(1u64, |n, &d| n.checked_mul(d as u64))
        .unwrap_or(u64::MAX))
}

/// Checks that `m` (named by `what`) is an invertible affine map.
fn check_matrix(m: DMat4, what: &str) -> Result<(), String> {
    if let Some(v) = m.to_cols_array().iter().find(|v| !v.is_finite()) {
        return Err(format!("{what} has a non-finite entry ({v})"));
    }
    if m.row(3) != DVec4::new(0.0, 0.0, 0.0, 1.0) {
        return Err(format!(
            "{what} has the last row {:?}, not (0, 0, 0, 1): it is not an affine map",
            m.row(3).to_array()
        ));
    }
    if crate::io_util::degenerate_axes(glam::DMat3::from_mat4(m)) {
        return Err(format!(
            "{what} is not invertible: its axes are (nearly) linearly dependent"
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DQuat;

    fn affine(axis: DVec3, degrees: f64, spacing: DVec3, offset: DVec3) -> DMat4 {
        DMat4::from_translation(offset)
            * DMat4::from_quat(DQuat::from_axis_angle(
                axis.normalize(),
                degrees.to_radians(),
            ))
            * DMat4::from_scale(spacing)
    }

    fn world_of(a: DMat4, dims: [usize; 3]) -> Vec<DVec3> {
        let mut out = Vec::new();
        for k in 0..dims[2] {
            for j in 0..dims[1] {
                for i in 0..dims[0] {
                    out.push(a.transform_point3(DVec3::new(i as f64, j as f64, k as f64)));
                }
            }
        }
        out
    }

    fn same(a: &[f32], b: &[f32]) -> bool {
        a.len() == b.len()
            && a.iter()
                .zip(b)
                .all(|(x, y)| x.to_bits() == y.to_bits() || (x.is_nan() && y.is_nan()))
    }

    #[test]
    fn identity_resampling_returns_the_input() {
        let dims = [5, 4, 3];
        let mut data: Vec<f32> = (0..60).map(|v| (v as f32 * 0.37).sin() * 10.0).collect();
        data[17] = f32::NAN;
        data[31] = f32::INFINITY;
        let oblique = affine(
            DVec3::new(0.3, -1.0, 0.5),
            37.0,
            DVec3::new(0.7, 1.3, 2.1),
            DVec3::new(-12.0, 4.5, 80.0),
        );
        for a in [DMat4::IDENTITY, oblique] {
            for interp in [Interp::Linear, Interp::Nearest] {
                let out = into_grid(&data, dims, a, DMat4::IDENTITY, dims, a, interp).unwrap();
                assert!(same(&out, &data), "{interp:?} {a:?}");
            }
        }
    }

    /// A grid moved by a whole voxel is not the same grid: the resampling (not the copy of
    /// the same voxels) snaps onto the neighbours' centres and returns their values exactly,
    /// under an oblique affine whose products leave the indices a few ulps off.
    #[test]
    fn a_whole_voxel_shift_returns_the_neighbours_exactly() {
        let dims = [5, 4, 3];
        let mut data: Vec<f32> = (0..60).map(|v| (v as f32 * 0.37).sin() * 10.0).collect();
        data[17] = f32::NAN;
        let a = affine(
            DVec3::new(0.3, -1.0, 0.5),
            37.0,
            DVec3::new(0.7, 1.3, 2.1),
            DVec3::new(-12.0, 4.5, 80.0),
        );
        // Destination voxel (i, j, k) samples source voxel (i + 1, j, k).
        let shift = DMat4::from_translation(a.x_axis.truncate());
        assert!(!same_voxels(a.inverse() * shift * a, dims, dims));
        for interp in [Interp::Linear, Interp::Nearest] {
            let out = into_grid(&data, dims, a, shift, dims, a, interp).unwrap();
            for k in 0..3 {
                for j in 0..4 {
                    for i in 0..5 {
                        let (o, n) = (out[i + 5 * (j + 4 * k)], i + 1 + 5 * (j + 4 * k));
                        match i {
                            4 => assert!(o.is_nan(), "{interp:?}: past the edge {o}"),
                            _ => assert!(
                                o.to_bits() == data[n].to_bits()
                                    || (o.is_nan() && data[n].is_nan()),
                                "{interp:?} ({i}, {j}, {k}): {o} for {}",
                                data[n]
                            ),
                        }
                    }
                }
            }
        }
        // Rounding-level differences are the same voxels; a millionth of a voxel is not.
        let m = DMat4::from_translation(DVec3::splat(1e-12));
        assert!(same_voxels(m, dims, dims));
        assert!(!same_voxels(
            DMat4::from_translation(DVec3::new(0.0, 1e-6, 0.0)),
            dims,
            dims
        ));
        assert!(!same_voxels(DMat4::IDENTITY, dims, [5, 4, 4]));
    }

    /// A linear function of world position is reproduced by trilinear interpolation on any
    /// grid, wherever the result is finite.
    #[test]
    fn linear_reproduces_linear_functions() {
        let f = |p: DVec3| 0.7 * p.x - 1.3 * p.y + 0.4 * p.z + 5.0;
        let src_dims = [7, 6, 5];
        let src_affine = affine(
            DVec3::new(1.0, 0.2, -0.3),
            25.0,
            DVec3::new(1.5, 0.8, 2.2),
            DVec3::new(3.0, -2.0, 1.0),
        );
        let src: Vec<f32> = world_of(src_affine, src_dims)
            .into_iter()
            .map(|p| f(p) as f32)
            .collect();
        let dst_dims = [13, 11, 9];
        let dst_affine = affine(
            DVec3::new(-0.4, 1.0, 0.6),
            -50.0,
            DVec3::new(0.6, 0.9, 0.75),
            DVec3::new(-1.0, -4.0, -3.0),
        );
        let to_src = affine(
            DVec3::new(0.0, 0.3, 1.0),
            6.0,
            DVec3::ONE,
            DVec3::new(0.5, -0.25, 0.8),
        );
        let out = into_grid(
            &src,
            src_dims,
            src_affine,
            to_src,
            dst_dims,
            dst_affine,
            Interp::Linear,
        )
        .unwrap();
        let to_index = src_affine.inverse() * to_src;
        let (mut inside, mut outside) = (0, 0);
        for (v, p) in out.iter().zip(world_of(dst_affine, dst_dims)) {
            let s = to_src.transform_point3(p);
            let q = to_index.transform_point3(p).to_array();
            let margin = (0..3)
                .map(|a| q[a].min((src_dims[a] - 1) as f64 - q[a]))
                .fold(f64::INFINITY, f64::min);
            if v.is_finite() {
                inside += 1;
                assert!(margin > -1e-6, "finite outside the source: q = {q:?}");
                assert!((*v as f64 - f(s)).abs() < 1e-4, "{v} vs {} at {q:?}", f(s));
            } else {
                outside += 1;
                assert!(v.is_nan());
                assert!(margin < 1e-6, "NaN inside the source: q = {q:?}");
            }
        }
        assert!(
            inside > 100 && outside > 100,
            "{inside} inside, {outside} outside"
        );
    }

    #[test]
    fn nearest_returns_only_source_values() {
        let src_dims = [6, 5, 4];
        let src: Vec<f32> = (0..120).map(|v| (v * 7 + 1) as f32).collect();
        let src_affine = affine(DVec3::Z, 10.0, DVec3::new(1.0, 2.0, 1.5), DVec3::ZERO);
        let dst_dims = [15, 12, 10];
        let dst_affine = affine(
            DVec3::new(1.0, 1.0, 0.0),
            33.0,
            DVec3::splat(0.55),
            DVec3::new(-1.0, 0.5, -0.5),
        );
        let out = into_grid(
            &src,
            src_dims,
            src_affine,
            DMat4::IDENTITY,
            dst_dims,
            dst_affine,
            Interp::Nearest,
        )
        .unwrap();
        let to_index = src_affine.inverse();
        let mut finite = 0;
        for (v, p) in out.iter().zip(world_of(dst_affine, dst_dims)) {
            let q = to_index.transform_point3(p);
            let inside = (0..3).all(|a| q[a] >= -0.5 && q[a] < src_dims[a] as f64 - 0.5);
            if !inside {
                assert!(v.is_nan());
                continue;
            }
            finite += 1;
            let r = (q + 0.5).floor();
            let (i, j, k) = (r.x as usize, r.y as usize, r.z as usize);
            assert_eq!(*v, src[i + 6 * (j + 5 * k)], "q = {q:?}");
            assert!(src.contains(v));
        }
        assert!(finite > 100 && finite < out.len(), "{finite}");
    }

    #[test]
    fn nan_voxels_spread_only_where_they_weigh() {
        let dims = [4, 4, 4];
        let mut src = vec![1.0f32; 64];
        let index = |i: usize, j: usize, k: usize| i + 4 * (j + 4 * k);
        src[index(1, 1, 1)] = f32::NAN;
        // Destination: the source grid shifted by half a voxel in x.
        let shifted = DMat4::from_translation(DVec3::new(0.5, 0.0, 0.0));
        let out = into_grid(
            &src,
            dims,
            DMat4::IDENTITY,
            DMat4::IDENTITY,
            dims,
            shifted,
            Interp::Linear,
        )
        .unwrap();
        let at = |i: usize, j: usize, k: usize| out[i + 4 * (j + 4 * k)];
        assert!(at(0, 1, 1).is_nan() && at(1, 1, 1).is_nan());
        assert_eq!(at(2, 1, 1), 1.0);
        assert_eq!(at(0, 2, 1), 1.0);
        assert!(at(3, 0, 0).is_nan(), "x = 3.5 is outside");
    }

    #[test]
    fn single_voxel_axes() {
        let dims = [3, 3, 1];
        let src: Vec<f32> = (0..9).map(|v| v as f32).collect();
        let at_z = |z: f64, interp| {
            let dst = DMat4::from_translation(DVec3::new(0.0, 0.0, z));
            into_grid(
                &src,
                dims,
                DMat4::IDENTITY,
                DMat4::IDENTITY,
                dims,
                dst,
                interp,
            )
            .unwrap()
        };
        assert_eq!(at_z(0.0, Interp::Linear), src);
        assert_eq!(at_z(1e-9, Interp::Linear), src);
        assert!(at_z(0.1, Interp::Linear).iter().all(|v| v.is_nan()));
        assert_eq!(at_z(0.45, Interp::Nearest), src);
        assert_eq!(at_z(-0.5, Interp::Nearest), src);
        assert!(at_z(0.5, Interp::Nearest).iter().all(|v| v.is_nan()));
    }

    #[test]
    fn bad_input_is_an_error() {
        let id = DMat4::IDENTITY;
        let call =
            |src: &[f32], sd, sa, t, dd, da| into_grid(src, sd, sa, t, dd, da, Interp::Linear);
        let src = vec![0.0; 8];
        let e = call(&src[..7], [2, 2, 2], id, id, [2, 2, 2], id).unwrap_err();
        assert!(e.contains("8 voxels but 7 values"), "{e}");
        let e = call(&[], [0, 2, 2], id, id, [2, 2, 2], id).unwrap_err();
        assert!(e.contains("source grid 0 x 2 x 2 has an empty axis"), "{e}");
        let e = call(&src, [2, 2, 2], id, id, [2, 0, 2], id).unwrap_err();
        assert!(
            e.contains("destination grid 2 x 0 x 2 has an empty axis"),
            "{e}"
        );
        let flat = DMat4::from_scale(DVec3::new(1.0, 1.0, 0.0));
        let e = call(&src, [2, 2, 2], flat, id, [2, 2, 2], id).unwrap_err();
        assert!(e.contains("the source's affine is not invertible"), "{e}");
        let e = call(&src, [2, 2, 2], id, flat, [2, 2, 2], id).unwrap_err();
        assert!(
            e.contains("the transform into the source's world is not invertible"),
            "{e}"
        );
        let e = call(&src, [2, 2, 2], id, id, [2, 2, 2], flat).unwrap_err();
        assert!(
            e.contains("the destination's affine is not invertible"),
            "{e}"
        );
        let mut nan = id;
        nan.w_axis.x = f64::NAN;
        let e = call(&src, [2, 2, 2], nan, id, [2, 2, 2], id).unwrap_err();
        assert!(e.contains("non-finite entry"), "{e}");
        let mut projective = id;
        projective.x_axis.w = 0.5;
        let e = call(&src, [2, 2, 2], id, projective, [2, 2, 2], id).unwrap_err();
        assert!(e.contains("not an affine map"), "{e}");
        let huge = [usize::MAX, usize::MAX, 2];
        let e = call(&src, [2, 2, 2], id, id, huge, id).unwrap_err();
        assert!(e.contains("MiB"), "{e}");
        let e = call(&src, [2, 2, 2], id, id, [1 << 16, 1 << 16, 2], id).unwrap_err();
        assert!(e.contains("8.589934592e9 voxels (32768 MiB as f32)"), "{e}");
    }
}
