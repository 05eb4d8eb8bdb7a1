//! Maximum and minimum intensity projections (MIP, MinIP) of a volume: the context volume of
//! seed 002 (drawn behind pathlines in light grey), as the render methods `mip` and `minip`.
//!
//! A pixel's ray samples the field at the middle of each slice's slab interval kept by the
//! clipping planes (the sample positions of [`emission_absorption::reference`], over the whole
//! ray: surfaces do not stop it), keeps the largest (or smallest) value, and shows it through
//! the volume's transfer function: colour `rgb(v)` with opacity `min(extinction(v), 1)`,
//! premultiplied, over the background. Samples next to a NaN voxel are skipped. The renderer
//! draws it only where no surface is nearest, so tubes and lines stand in front of it and
//! their occlusion terms are those of the method without a volume.
//!
//! | step | CPU (this module) | WGSL (`shaders/slice_pass.wgsl`) | test |
//! |---|---|---|---|
//! | extreme value along the ray | [`extreme`] | `projection` | `engine/tests/projection_render.rs` |
//! | colour and opacity | [`shade`] | `projection` (its end) | the same |

use crate::emission_absorption::{sample, slab_interval, EaView, Transfer};
use glam::{DMat4, DVec3, DVec4};

/// Which value the projection keeps.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Extremum {
    Max,
    Min,
}

/// The extreme value along the ray `o + s d` (unit `d`) through `v`'s slices, of `data` (as
/// [`crate::emission_absorption::prepare`] returns it) on a grid of `dims` with
/// `world_to_index`; `None` when the ray takes no sample.
pub fn extreme(
    data: &[f32],
    dims: [usize; 3],
    world_to_index: &DMat4,
    v: &EaView,
    o: DVec3,
    d: DVec3,
    which: Extremum,
) -> Option<f64> {
    let f = v.camera.forward();
    let cosine = d.dot(f);
    let o_depth = (o - v.camera.eye).dot(f);
    let mut best: Option<f64> = None;
    for k in 0..v.slices {
        let (lo, hi) = slab_interval(v, o, d, k);
        if hi <= lo {
            continue;
        }
        let s = (0.5 * (lo + hi) - o_depth) / cosine;
        if s < 0.0 {
            continue;
        }
        let q = (*world_to_index * DVec4::from((o + d * s, 1.0))).truncate();
        let Some(x) = sample(data, dims, q).filter(|&x| x >= -1e30) else {
            continue;
        };
        best = Some(match (best, which) {
            (None, _) => x,
            (Some(b), Extremum::Max) => b.max(x),
            (Some(b), Extremum::Min) => b.min(x),
        });
    }
    best
}

/// The projection's premultiplied colour and opacity for value `x` (none: transparent).
pub fn shade(tf: &Transfer, x: Option<f64>) -> [f64; 4] {
    match x {
        None => [0.0; 4],
        Some(x) => {
            let (rgb, sigma) = tf.eval(x);
            let a = sigma.clamp(0.0, 1.0);
            [rgb[0] * a, rgb[1] * a, rgb[2] * a, a]
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::{Camera, Projection};

    fn view(slices: u32) -> EaView {
        let camera = Camera {
            eye: DVec3::new(1.5, 1.5, 10.0),
            target: DVec3::new(1.5, 1.5, 0.0),
            up: DVec3::Y,
            projection: Projection::Orthographic { height: 4.0 },
            near: 0.1,
            far: 100.0,
            skew: 0.0,
        };
        EaView {
            camera,
            width: 4,
            height: 4,
            z0: 5.0,
            dz: 10.0 / slices as f64,
            slices,
            background: [0.0; 3],
            clip: vec![],
            voxel: 0.0,
        }
    }

    #[test]
    fn the_extreme_of_a_ray_along_z_is_the_column_extreme() {
        // 4 x 4 x 4 grid, value = 10 k + i: along z (the view axis) the max is at k = 3.
        let dims = [4, 4, 4];
        let data: Vec<f32> = (0..64)
            .map(|n| (10 * (n / 16) + n % 4) as f32 * if n % 16 == 5 { -1.0 } else { 1.0 })
            .collect();
        let v = view(400);
        let o = DVec3::new(2.0, 1.0, 9.0);
        let d = DVec3::new(0.0, 0.0, -1.0);
        let mx = extreme(&data, dims, &DMat4::IDENTITY, &v, o, d, Extremum::Max).unwrap();
        let mn = extreme(&data, dims, &DMat4::IDENTITY, &v, o, d, Extremum::Min).unwrap();
        // Samples at slab middles come within dz / 2 of the ends k = 0 and k = 3.
        assert!((mx - 32.0).abs() <= 10.0 * 0.0125 + 1e-9, "{mx}");
        assert!((mn - 2.0).abs() <= 10.0 * 0.0125 + 1e-9, "{mn}");
        // A ray that misses the grid takes no sample and shades transparent.
        let miss = extreme(
            &data,
            dims,
            &DMat4::IDENTITY,
            &v,
            DVec3::new(9.0, 9.0, 9.0),
            d,
            Extremum::Max,
        );
        assert_eq!(miss, None);
        let tf = Transfer::ramp(0.0, 32.0, [1.0, 1.0, 1.0], 0.5);
        assert_eq!(shade(&tf, None), [0.0; 4]);
        let s = shade(&tf, Some(32.0));
        assert!((s[3] - 0.5).abs() < 1e-12 && (s[0] - 0.5).abs() < 1e-12);
    }
}
