//! Emission-absorption volume rendering through view-aligned slices: the model of the `ea`
//! baseline of issue 5 - the transfer function, where the slices are ([`EaView`]), empty-space
//! bricks ([`occupancy`]) - and its f64 CPU twin [`reference()`], which the tests compare the
//! GPU's `ea` method (`slice_pass`, entry `march` of `shaders/slice_pass.wgsl`) with on
//! lavapipe.
//!
//! Paper: Schott et al., "Ambient Occlusion Effects for Combined Volumes and Tubular Geometry"
//! (IEEE TVCG), section 3.2: the view-aligned slice traversal of Algorithm 1 and the eye-buffer
//! update of Algorithm 2 (section 3.2.2) with the occlusion factor set to 1 - i.e. without the
//! volumetric occlusion buffer (Algorithm 3), partial occlusion (Algorithm 4), vicinity
//! occlusion (Algorithm 5) and the geometry depth test, which later passes add. Two departures,
//! as issue 5 asks: the transfer function gives extinction per world unit, not opacity per
//! slice (opacity `1 - exp(-sigma l)` for the ray's length `l` between slices), and the
//! background is composited last instead of initialising the eye buffer with it (Algorithm 1's
//! ONE_MINUS_DST_ALPHA blending would add it instead of attenuating it).
//!
//! Slices are planes perpendicular to the viewing direction at distances
//! `z0 + (k + 1/2) dz` from the eye, spanning the volume's bounding box. A pixel's ray meets
//! slice k at one point; the field is sampled there (trilinear, outside the grid: nothing),
//! mapped through a piecewise-linear transfer function to a colour and an extinction sigma per
//! world unit, and composited front to back with `alpha = 1 - exp(-sigma dz / cos phi)`, where
//! `dz / cos phi` is the ray's length between two planes (phi: the angle between the ray and the
//! viewing direction). Opacity per unit length makes the image independent of the slice count
//! (up to the Riemann sum's error, tested). The background is composited last, under the
//! volume (front-to-back "under" blending; issue 5 notes that Algorithm 1's initialisation with
//! the background adds it instead). The default slice distance is half the smallest voxel
//! spacing (two samples per voxel along the view, the Nyquist rate of trilinear data).
//! Each ray only visits the slices where it is inside the grid's box, and empty space is
//! skipped per brick of 8^3 cells whose value range the transfer function maps to zero
//! extinction ([`occupancy`]); both are exact, and the CPU twin, which does neither, checks it.
//! A third departure, for speed, on every path: rays end once their opacity passes
//! [`OPAQUE`] (1 - 1/128, about where VTK's fixed-point ray caster ends them; the paper's
//! Algorithm 2 takes every slice). Where Algorithm 2's eye-buffer update is implemented:
//! [`reference()`] here (f64), `march` in `shaders/slice_pass.wgsl` (GPU), and on the CPU
//! `raycast::EaVolume::advance` (a ray at a time) and `raycast/src/lanes.rs` (eight rays at a
//! time, bit for bit the former); tests: `the_cpu_renderer_matches_the_f64_twin` and
//! `eight_lanes_march_as_the_scalar_march_bit_for_bit_lit_or_not` (raycast), the GPU's in
//! `engine/tests/ea_render.rs`.

use crate::camera::Camera;
use glam::{DMat4, DVec3, DVec4};
use volume::Volume;

/// A piecewise-linear transfer function: `(value, rgb, extinction)` points, values
/// non-decreasing; constant beyond the ends.
///
/// 2-D (over value and gradient magnitude, Schott et al.'s Algorithm 2): `rows` lists, by
/// increasing gradient magnitude, each row's gradient and the index of its first point in
/// `points` (a row runs to the next row's first point); each row is a 1-D function of value,
/// and between two rows the result is interpolated linearly in the gradient magnitude
/// (constant beyond the first and last rows). Empty `rows`: 1-D.
#[derive(Clone, Debug, PartialEq)]
pub struct Transfer {
    pub points: Vec<(f64, [f64; 3], f64)>,
    pub rows: Vec<(f64, usize)>,
}

/// A 1-D piecewise-linear function's colour and extinction at `v`.
fn eval_points(p: &[(f64, [f64; 3], f64)], v: f64) -> ([f64; 3], f64) {
    if p.is_empty() {
        return ([0.0; 3], 0.0);
    }
    if v <= p[0].0 {
        return (p[0].1, p[0].2);
    }
    for i in 1..p.len() {
        if v <= p[i].0 {
            let (a, b) = (&p[i - 1], &p[i]);
            let t = if b.0 > a.0 {
                (v - a.0) / (b.0 - a.0)
            } else {
                0.0
            };
            let c = [0, 1, 2].map(|k| a.1[k] + (b.1[k] - a.1[k]) * t);
            return (c, a.2 + (b.2 - a.2) * t);
        }
    }
    let l = p.last().unwrap();
    (l.1, l.2)
}

impl Transfer {
    /// Whether the extinction is zero for every value in `[lo, hi]` (piecewise linear: the
    /// largest value on an interval is at its ends or at a point inside it).
    /// For a 2-D function: whether every row is (the rows bound the interpolation).
    pub fn transparent_over(&self, lo: f64, hi: f64) -> bool {
        self.row_slices().into_iter().all(|p| {
            let inside = p.iter().filter(|q| q.0 > lo && q.0 < hi).map(|q| q.2);
            let m = inside
                .chain([eval_points(p, lo).1, eval_points(p, hi).1])
                .fold(0.0f64, f64::max);
            m <= 0.0
        })
    }

    /// The rows' points (one slice, all points, for a 1-D function).
    pub fn row_slices(&self) -> Vec<&[(f64, [f64; 3], f64)]> {
        if self.rows.is_empty() {
            return vec![&self.points];
        }
        (0..self.rows.len())
            .map(|r| {
                let end = self.rows.get(r + 1).map_or(self.points.len(), |x| x.1);
                &self.points[self.rows[r].1..end]
            })
            .collect()
    }

    /// Colour and extinction at value `v` and gradient magnitude `g` (`g` is ignored by a 1-D
    /// function).
    pub fn eval2(&self, v: f64, g: f64) -> ([f64; 3], f64) {
        let rows = self.row_slices();
        if self.rows.is_empty() {
            return eval_points(rows[0], v);
        }
        let r = &self.rows;
        if g <= r[0].0 {
            return eval_points(rows[0], v);
        }
        for j in 1..r.len() {
            if g <= r[j].0 {
                let t = if r[j].0 > r[j - 1].0 {
                    (g - r[j - 1].0) / (r[j].0 - r[j - 1].0)
                } else {
                    0.0
                };
                let (a, b) = (eval_points(rows[j - 1], v), eval_points(rows[j], v));
                let c = [0, 1, 2].map(|k| a.0[k] + (b.0[k] - a.0[k]) * t);
                return (c, a.1 + (b.1 - a.1) * t);
            }
        }
        eval_points(rows[r.len() - 1], v)
    }

    /// A ramp from transparent black at `lo` to `colour` with `extinction` at `hi`.
    pub fn ramp(lo: f64, hi: f64, colour: [f64; 3], extinction: f64) -> Transfer {
        Transfer {
            points: vec![(lo, [0.0; 3], 0.0), (hi.max(lo), colour, extinction)],
            rows: vec![],
        }
    }

    /// Colour and extinction at `v` (a 2-D function's lowest-gradient row).
    pub fn eval(&self, v: f64) -> ([f64; 3], f64) {
        eval_points(self.row_slices()[0], v)
    }
}

/// Where the slices are and what the image is.
#[derive(Clone, Debug)]
pub struct EaView {
    pub camera: Camera,
    pub width: u32,
    pub height: u32,
    /// Distance of the slab's front from the eye along the viewing direction, and the slice
    /// spacing; `slices` slices.
    pub z0: f64,
    pub dz: f64,
    pub slices: u32,
    pub background: [f64; 3],
    /// Clipping planes `(normal, offset)`: samples with `normal . p > offset` are removed
    /// (at most [`MAX_CLIP`]).
    pub clip: Vec<([f64; 3], f64)>,
    /// The sampling spacing the data ask for, world units: twice the default slice distance
    /// (`span`'s `spacing`) - the smallest voxel spacing, or less where a scene's transfer
    /// function has features narrower than the data's value change per voxel
    /// (`scene::compile::slice_distance`); 0 where unknown. The light volume's cells need not be
    /// finer on screen (`crate::combined::data_cell`), nor its parts in depth
    /// (`crate::combined::voxel_step`).
    pub voxel: f64,
}

/// The most slices a view has (a bound on the work per pixel).
pub const MAX_SLICES: u32 = 16384;

/// The most clipping planes a view has.
pub const MAX_CLIP: usize = 8;

/// Early ray termination: a ray ends once its opacity passes this, with less than 1/128 of
/// the light behind left to see (the GPU pass `shaders/slice_pass.wgsl` and the CPU renderer
/// end at the same opacity). VTK's fixed-point ray caster ends where the remaining opacity
/// falls below 255/32768 (`VTKKWRCHelper_CompositeColorAndCheckEarlyTermination`), about the
/// same. What is left out changes a pixel by at most 1/128 of the difference between the
/// volume behind and what stands in for it ([`end_opaque`]: the mean of what the ray showed,
/// no longer the background): measured against ending at 0.999 (the earlier threshold, with
/// the background behind), 0.07-0.12 levels of 255 in mean and at most 2 on the MNI T1 and
/// headsq at 512^2, for a fifth less time (docs/benchmarks.md).
pub const OPAQUE: f32 = 1.0 - 1.0 / 128.0;

/// A ray ended at [`OPAQUE`]: the rest of it taken as the mean of what it showed so far - its
/// premultiplied colour over its opacity, at opacity 1 - instead of the background behind it.
/// What the ray leaves unseen (at most 1/128 of the light) lies behind an opaque medium, where
/// more of the medium, not the background, is what the rest of the ray would meet. Letting the
/// background show through it (as VTK's ray casters do) made opaque pixels up to 1/128 of
/// (background - volume) too bright on a white background: against the Monte Carlo
/// reference, which follows every ray to its end, +0.0069 in mean over the MNI T1's volume for
/// `combined` with a cone of 1 degree, whose light deep in the head is near 0, and +0.0022 for
/// `ea` (docs/accuracy.md, "The end of an opaque ray"). The GPU pass (`slice_pass.wgsl`) and
/// the CPU renderer end their rays the same way.
pub fn end_opaque<const N: usize>(c: [f64; N], a: f64) -> ([f64; N], f64) {
    if a > 0.0 {
        (c.map(|x| x / a), 1.0)
    } else {
        (c, a)
    }
}

impl EaView {
    /// Slices spanning `vol`'s bounding box seen by `camera`: `slices`, or `slice_distance`
    /// apart, or (neither given) half the smallest voxel spacing apart; at most
    /// [`MAX_SLICES`] (an error names the setting that asks for more).
    pub fn new(
        vol: &Volume,
        camera: Camera,
        width: u32,
        height: u32,
        slices: Option<u32>,
        slice_distance: Option<f64>,
        background: [f64; 3],
    ) -> Result<EaView, String> {
        let sp = vol.spacing();
        let spacing = sp.iter().cloned().fold(f64::INFINITY, f64::min);
        EaView::span(
            vol.bounds(),
            spacing,
            camera,
            width,
            height,
            slices,
            slice_distance,
            background,
        )
    }

    /// Slices spanning the box `bounds` (the volume's and the tubes' together) seen by
    /// `camera`; the default slice distance is half `spacing` (the smallest voxel spacing).
    #[allow(clippy::too_many_arguments)]
    pub fn span(
        bounds: [DVec3; 2],
        spacing: f64,
        camera: Camera,
        width: u32,
        height: u32,
        slices: Option<u32>,
        slice_distance: Option<f64>,
        background: [f64; 3],
    ) -> Result<EaView, String> {
        let [lo, hi] = bounds;
        let f = camera.forward();
        let (mut zmin, mut zmax) = (f64::INFINITY, f64::NEG_INFINITY);
        for i in 0..8 {
            let p = DVec3::new(
                if i & 1 == 0 { lo.x } else { hi.x },
                if i & 2 == 0 { lo.y } else { hi.y },
                if i & 4 == 0 { lo.z } else { hi.z },
            );
            let z = (p - camera.eye).dot(f);
            zmin = zmin.min(z);
            zmax = zmax.max(z);
        }
        let zmin = zmin.max(0.0);
        let depth = (zmax - zmin).max(1e-9);
        let count = |d: f64| (depth / d).ceil().max(1.0);
        let (n, what) = match (slices, slice_distance) {
            (Some(n), _) => (n as f64, "render.slices"),
            (None, Some(d)) => (count(d), "render.slice_distance"),
            (None, None) => (
                count(0.5 * spacing),
                "the default slice distance (half the smallest voxel spacing)",
            ),
        };
        if !(n >= 1.0 && n <= MAX_SLICES as f64) {
            return Err(format!(
                "{what} gives {n} slices through a slab {depth:.4} deep; 1 to {MAX_SLICES} are allowed"
            ));
        }
        let n = n as u32;
        let dz = depth / n as f64;
        Ok(EaView {
            camera,
            width,
            height,
            z0: zmin,
            dz,
            slices: n,
            background,
            clip: vec![],
            voxel: spacing,
        })
    }
}

fn world_to_index(vol: &Volume) -> DMat4 {
    vol.affine.inverse()
}

/// Trilinear sample of `data` (x fastest) at index-space `q`, `None` outside the grid. With
/// data as [`prepare`] returns it, a sample next to a NaN voxel comes out below -1e30 (the
/// shader's rule for a gap).
pub fn sample(data: &[f32], dims: [usize; 3], q: DVec3) -> Option<f64> {
    let hi = DVec3::new(
        dims[0] as f64 - 1.0,
        dims[1] as f64 - 1.0,
        dims[2] as f64 - 1.0,
    );
    if q.cmplt(DVec3::ZERO).any() || q.cmpgt(hi).any() {
        return None;
    }
    let b = [0, 1, 2].map(|a| (q[a].floor() as usize).min(dims[a].max(2) - 2));
    let f = q - DVec3::new(b[0] as f64, b[1] as f64, b[2] as f64);
    let at = |i: usize, j: usize, k: usize| {
        data[(b[0] + i).min(dims[0] - 1)
            + dims[0] * ((b[1] + j).min(dims[1] - 1) + dims[1] * (b[2] + k).min(dims[2] - 1))]
            as f64
    };
    let l = |a: f64, b: f64, t: f64| a + (b - a) * t;
    let x00 = l(at(0, 0, 0), at(1, 0, 0), f.x);
    let x10 = l(at(0, 1, 0), at(1, 1, 0), f.x);
    let x01 = l(at(0, 0, 1), at(1, 0, 1), f.x);
    let x11 = l(at(0, 1, 1), at(1, 1, 1), f.x);
    Some(l(l(x00, x10, f.y), l(x01, x11, f.y), f.z))
}

/// The world-space gradient at index-space `q` as the shader takes it for Phong shading and
/// 2-D transfer functions: central differences one voxel apart (one-sided at the border),
/// halved, taken to world space by the transpose of `world_to_index`'s 3x3.
pub fn gradient(data: &[f32], dims: [usize; 3], world_to_index: &DMat4, q: DVec3) -> DVec3 {
    let hi = DVec3::new(
        dims[0] as f64 - 1.0,
        dims[1] as f64 - 1.0,
        dims[2] as f64 - 1.0,
    );
    let at = |p: DVec3| sample(data, dims, p.clamp(DVec3::ZERO, hi)).unwrap_or(0.0);
    let d = |e: DVec3| at((q + e).min(hi)) - at((q - e).max(DVec3::ZERO));
    let gq = 0.5 * DVec3::new(d(DVec3::X), d(DVec3::Y), d(DVec3::Z));
    glam::DMat3::from_mat4(*world_to_index).transpose() * gq
}

/// The field as the pass reads it: NaN and infinite samples (no data, e.g. outside a
/// resampled CFD mesh) become -3e38, which the pass skips together with every sample it
/// touches through interpolation.
pub fn prepare(data: &[f32]) -> Vec<f32> {
    prepare_owned(data.to_vec())
}

/// [`prepare`] in place (no second copy of a large volume).
pub fn prepare_owned(mut data: Vec<f32>) -> Vec<f32> {
    for v in &mut data {
        if !v.is_finite() {
            *v = -3e38;
        }
    }
    data
}

/// The depth interval of slice `k`'s slab that the ray `o + s d` keeps behind the clipping
/// planes (`normal . p <= offset`); empty when `b <= a`. The renderer samples the volume at
/// its middle, over its length: cut faces then have no slice steps.
pub fn slab_interval(v: &EaView, o: DVec3, d: DVec3, k: u32) -> (f64, f64) {
    let a = v.z0 + k as f64 * v.dz;
    clip_interval(v, o, d, a, a + v.dz)
}

/// The part of the depth interval `[a, b]` that the ray `o + s d` keeps behind the view's
/// clipping planes ([`slab_interval`] for any interval: a part of a slab).
pub fn clip_interval(v: &EaView, o: DVec3, d: DVec3, a: f64, b: f64) -> (f64, f64) {
    let f = v.camera.forward();
    let cosine = d.dot(f);
    let o_depth = (o - v.camera.eye).dot(f);
    let (mut a, mut b) = (a, b);
    for (n, off) in &v.clip {
        let n = DVec3::from(*n);
        let g1 = n.dot(d) / cosine;
        let g0 = n.dot(o) - off - g1 * o_depth;
        if g1.abs() < 1e-12 {
            if g0 > 0.0 {
                b = a;
            }
        } else if g1 > 0.0 {
            b = b.min(-g0 / g1);
        } else {
            a = a.max(-g0 / g1);
        }
    }
    (a, b)
}

/// The view depth where the clipping planes let the ray `o + s d` in (the largest entry over
/// the planes it crosses front to back), `None` when it crosses none that way (the shader's
/// `clip_entry`, -1 there).
pub fn clip_entry(v: &EaView, o: DVec3, d: DVec3) -> Option<f64> {
    let f = v.camera.forward();
    let cosine = d.dot(f);
    let o_depth = (o - v.camera.eye).dot(f);
    let mut a: Option<f64> = None;
    for (n, off) in &v.clip {
        let n = DVec3::from(*n);
        let g1 = n.dot(d) / cosine;
        let g0 = n.dot(o) - off - g1 * o_depth;
        if g1 < -1e-12 {
            let e = -g0 / g1;
            a = Some(a.map_or(e, |x| x.max(e)));
        }
    }
    a.filter(|&x| x >= 0.0)
}

/// The CPU twin of the shader, in f64: RGBA per pixel (rows top to bottom), alpha the
/// volume's opacity. `data` as [`prepare`] returns it.
pub fn reference(data: &[f32], vol: &Volume, tf: &Transfer, v: &EaView) -> Vec<[f64; 4]> {
    reference_with_layers(data, vol, tf, v, |_, _| vec![])
}

/// A translucent surface's fragment on a pixel's ray: linear view depth, lit colour
/// (straight) and opacity.
pub type Layer = (f64, [f64; 3], f64);

/// [`reference`] with translucent layers (the G-buffer's peeled layers, `layers(x, y)` in
/// increasing depth) composited where the ray reaches them, as the march pass does: a slab a
/// layer lies in is split at its depth, each part sampled at its middle over its length, and
/// the layer composited between them by its opacity; layers behind the volume come last.
/// Alpha is the coverage of volume and layers.
pub fn reference_with_layers(
    data: &[f32],
    vol: &Volume,
    tf: &Transfer,
    v: &EaView,
    layers: impl Fn(usize, usize) -> Vec<Layer>,
) -> Vec<[f64; 4]> {
    reference_blended(data, vol, tf, v, layers, |_| ([0.0; 3], 0.0))
}

/// [`reference_with_layers`] with a colour blended into every volume sample (an overlay,
/// `overlays[].volume_blend`): `blend(p)` gives the colour at world point `p` and its weight
/// (coverage times opacity); the sample's colour becomes `mix(colour, blend, weight)`, its
/// extinction unchanged.
pub fn reference_blended(
    data: &[f32],
    vol: &Volume,
    tf: &Transfer,
    v: &EaView,
    layers: impl Fn(usize, usize) -> Vec<Layer>,
    blend: impl Fn(DVec3) -> ([f64; 3], f64),
) -> Vec<[f64; 4]> {
    let w2i = world_to_index(vol);
    let f = v.camera.forward();
    let (w, h) = (v.width as usize, v.height as usize);
    let mut out = vec![[0.0; 4]; w * h];
    for y in 0..h {
        for x in 0..w {
            let (o, d) = v.camera.ray(x as f64, y as f64, w, h);
            let cosine = d.dot(f);
            let o_depth = (o - v.camera.eye).dot(f);
            let (mut c, mut a) = ([0.0f64; 3], 0.0f64);
            let ls = layers(x, y);
            let mut next = 0;
            // The volume over depths [lo, hi], sampled at the middle.
            let part = |lo: f64, hi: f64, c: &mut [f64; 3], a: &mut f64| {
                let s = (0.5 * (lo + hi) - o_depth) / cosine;
                if hi <= lo || s < 0.0 {
                    return;
                }
                let seg = (hi - lo) / cosine;
                let p = o + d * s;
                let q = (w2i * DVec4::from((p, 1.0))).truncate();
                let Some(val) = sample(data, vol.dims, q).filter(|&v| v >= -1e30) else {
                    return;
                };
                let g = if tf.rows.is_empty() {
                    0.0
                } else {
                    gradient(data, vol.dims, &w2i, q).length()
                };
                let (rgb, sigma) = tf.eval2(val, g);
                let al = 1.0 - (-sigma.max(0.0) * seg).exp();
                if al <= 0.0 {
                    return;
                }
                let (bc, bw) = blend(p);
                for i in 0..3 {
                    c[i] += (1.0 - *a) * al * (rgb[i] + (bc[i] - rgb[i]) * bw);
                }
                *a += (1.0 - *a) * al;
            };
            let layer = |l: &Layer, c: &mut [f64; 3], a: &mut f64| {
                for (ci, li) in c.iter_mut().zip(l.1) {
                    *ci += (1.0 - *a) * l.2 * li;
                }
                *a += (1.0 - *a) * l.2;
            };
            for k in 0..v.slices {
                let (lo, hi) = slab_interval(v, o, d, k);
                if hi <= lo {
                    continue;
                }
                let mut from = lo;
                while next < ls.len() && ls[next].0 <= hi {
                    part(from, ls[next].0, &mut c, &mut a);
                    layer(&ls[next], &mut c, &mut a);
                    from = from.max(ls[next].0);
                    next += 1;
                }
                part(from, hi, &mut c, &mut a);
                if a > OPAQUE as f64 {
                    (c, a) = end_opaque(c, a);
                    break;
                }
            }
            for l in &ls[next..] {
                layer(l, &mut c, &mut a);
            }
            let bg = v.background;
            out[x + w * y] = [
                c[0] + (1.0 - a) * bg[0],
                c[1] + (1.0 - a) * bg[1],
                c[2] + (1.0 - a) * bg[2],
                a,
            ];
        }
    }
    out
}

/// Edge of an empty-space brick, in voxels.
pub const BRICK: usize = 8;

/// Bricks per axis and, per brick, whether any value its voxels span (the brick's cells,
/// voxels `b B ..= b B + B`) has extinction; data as [`prepare`] returns it.
pub fn occupancy(data: &[f32], dims: [usize; 3], tf: &Transfer) -> ([usize; 3], Vec<u32>) {
    occupancy_of(data, 0.0, dims, tf, BRICK)
}

/// [`occupancy`] of packed samples (in their stored type: no `f32` copy).
pub fn occupancy_packed(
    data: &volume::samples::Samples,
    dims: [usize; 3],
    tf: &Transfer,
    brick: usize,
) -> ([usize; 3], Vec<u32>) {
    use volume::samples::View;
    match data.view() {
        View::F32(d) => occupancy_of(d, 0.0, dims, tf, brick),
        View::U16(d, o) => occupancy_of(d, o, dims, tf, brick),
        View::U8(d, o) => occupancy_of(d, o, dims, tf, brick),
    }
}

/// [`occupancy`] for bricks of `brick^3` cells (the CPU renderer skips finer bricks than the
/// GPU pass reads), of samples `data` plus `offset` in any stored type.
pub fn occupancy_of<T: volume::samples::Sample>(
    data: &[T],
    offset: f32,
    dims: [usize; 3],
    tf: &Transfer,
    brick: usize,
) -> ([usize; 3], Vec<u32>) {
    use rayon::prelude::*;
    let b_ = brick.max(1);
    let nb = dims.map(|d| d.saturating_sub(1).max(1).div_ceil(b_));
    let r = |b: usize, a: usize| b * b_..=((b + 1) * b_).min(dims[a] - 1);
    let occ: Vec<u32> = (0..nb[0] * nb[1] * nb[2])
        .into_par_iter()
        .map(|n| {
            let (bx, by, bz) = (n % nb[0], (n / nb[0]) % nb[1], n / (nb[0] * nb[1]));
            let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
            for k in r(bz, 2) {
                for j in r(by, 1) {
                    let row = dims[0] * (j + dims[1] * k);
                    for &v in &data[row + bx * b_..=row + ((bx + 1) * b_).min(dims[0] - 1)] {
                        let v = v.value();
                        if v >= -1e30 {
                            lo = lo.min(v);
                            hi = hi.max(v);
                        }
                    }
                }
            }
            let (lo, hi) = (lo as f64 + offset as f64, hi as f64 + offset as f64);
            (lo <= hi && !tf.transparent_over(lo, hi)) as u32
        })
        .collect();
    (nb, occ)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn transfer_functions_interpolate_and_clamp() {
        let t = Transfer {
            points: vec![
                (0.0, [0.0; 3], 0.0),
                (1.0, [1.0, 0.5, 0.0], 2.0),
                (3.0, [0.0, 0.0, 1.0], 0.0),
            ],
            rows: vec![],
        };
        assert_eq!(t.eval(-5.0), ([0.0; 3], 0.0));
        assert_eq!(t.eval(0.5), ([0.5, 0.25, 0.0], 1.0));
        assert_eq!(t.eval(2.0), ([0.5, 0.25, 0.5], 1.0));
        assert_eq!(t.eval(9.0), ([0.0, 0.0, 1.0], 0.0));
    }

    #[test]
    fn two_dimensional_transfer_functions_interpolate_between_gradient_rows() {
        // Row g = 0: transparent; row g = 10: extinction 2 above value 1.
        let t = Transfer {
            points: vec![
                (0.0, [0.0; 3], 0.0),
                (1.0, [0.0; 3], 0.0),
                (0.0, [1.0; 3], 0.0),
                (1.0, [1.0; 3], 2.0),
            ],
            rows: vec![(0.0, 0), (10.0, 2)],
        };
        assert_eq!(t.eval2(1.0, 0.0), ([0.0; 3], 0.0));
        assert_eq!(t.eval2(1.0, 10.0), ([1.0; 3], 2.0));
        assert_eq!(t.eval2(1.0, 99.0), ([1.0; 3], 2.0));
        assert_eq!(t.eval2(1.0, 2.5), ([0.25; 3], 0.5));
        assert_eq!(t.eval2(0.5, 5.0).1, 0.5);
        // Empty space: transparent only where every row is.
        assert!(t.transparent_over(-1.0, 0.0));
        assert!(!t.transparent_over(0.5, 0.6));
    }

    #[test]
    fn empty_bricks_are_exactly_the_transparent_ones() {
        // A spike of extinction at 0.5 only.
        let t = Transfer {
            points: vec![
                (0.4, [1.0; 3], 0.0),
                (0.5, [1.0; 3], 2.0),
                (0.6, [1.0; 3], 0.0),
            ],
            rows: vec![],
        };
        assert!(t.transparent_over(-1.0, 0.4));
        assert!(t.transparent_over(0.6, 9.0));
        assert!(!t.transparent_over(0.3, 0.7)); // the spike lies inside
        assert!(!t.transparent_over(0.45, 0.46));
        // A ramp x / 32 (exact in f32): only bricks whose values reach (0.4, 0.6) are used.
        let dims = [41, 3, 3];
        let data: Vec<f32> = (0..dims[0] * dims[1] * dims[2])
            .map(|n| (n % dims[0]) as f32 / 32.0)
            .collect();
        let (nb, occ) = occupancy(&data, dims, &t);
        assert_eq!(nb, [5, 1, 1]);
        // Bricks cover x in [0, 8], [8, 16], ...: values [0, .25], [.25, .5], [.5, .75], ...
        assert_eq!(occ, vec![0, 1, 1, 0, 0]);
        // NaN voxels (prepared) do not widen a brick's range.
        let mut d2 = data.clone();
        d2[3] = f32::NAN;
        assert_eq!(occupancy(&prepare(&d2), dims, &t).1, vec![0, 1, 1, 0, 0]);
    }
}
