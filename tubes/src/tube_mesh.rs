//! Stream tubes: a circle swept along the fitted B-spline of each streamline (Schott et al.,
//! IEEE TVCG, section 4, steps 2 and 3), with rotation-minimizing frames, a radius kept below
//! the local radius of curvature, and rings placed where the curve needs them.
//!
//! # Frames
//! * Rotation-minimizing frames by the double reflection method (Wang, Juttler, Zheng and Liu,
//!   ACM TOG 27(1), 2008), the default: for ring points `x_i`, unit tangents `t_i` and frame
//!   vector `r_i`, reflect `r_i` and `t_i` in the plane normal to `v1 = x_{i+1} - x_i`
//!   (`r_L`, `t_L`), then reflect `r_L` in the plane normal to `v2 = t_{i+1} - t_L`. Where the
//!   chord `v1` turns more than 30 degrees from `t_i` or `t_{i+1}` (the reflections' premise,
//!   a chord along the curve, fails: a hair-length side step of a rough tract), `r_i` is turned
//!   by the least rotation taking `t_i` to `t_{i+1}` instead (the rotation method, Klok, CAGD
//!   3(3), 1986; Wang et al. §2), which is also what `max_twist_deg` measures against.
//! * Frenet frames with the paper's flip correction (the normal `C'' - (C'' . t) t` is negated
//!   whenever it turns by more than 90 degrees from the previous ring's, and the previous normal
//!   is carried over where the curvature vanishes), for comparison.
//!
//! # Radius
//! The paper keeps the radius below `1 / kappa_max` of the whole curve. The default here reduces
//! it only where needed, `r_i = min(r, 0.9 / kappa_i)` per ring, and counts the rings clamped;
//! `RadiusMode::Global` is the paper's rule. The curvature used is the larger of the curve's and
//! the discrete one between consecutive rings (turn angle over spacing), so that the inner side of
//! a bend cannot fold between two rings either; the radius' slope is limited to `|dr/ds| <= 1`,
//! so that a clamp narrows the tube as a cone instead of a step. Where the radius varies, the vertex normal tilts by
//! `-dr/ds` along the tangent (the swept surface's normal).
//!
//! # Rings
//! `per_span` rings per B-spline span (the paper's uniform tessellation), then intervals are
//! bisected while the tangent turns by more than `max_turn_deg` across them, or, with a chordal
//! tolerance, while the axis' sagitta `L^2 kappa / 8` exceeds it. With a chordal tolerance the
//! number of sides follows too: the smallest `N` with `r (1 - cos(pi / N)) <= tol`.
//!
//! # Exact reversals
//! A streamline whose direction reverses (a turn above 179.9 degrees between consecutive
//! segments) has no tangent there; it is split into two tubes at that sample. Where a fitted
//! curve turns so tightly that even a thousandth of the radius would fold (the apex of a
//! near-reversal), the rings there are left out and the tube is cut as well; both count as
//! splits.

use crate::bspline_fit::{clean, fit, BSpline, FitMethod, FitOptions};
use crate::Streamlines;
use glam::{DVec3, Vec3};
use rayon::prelude::*;
use volume::colormap::Colormap;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FrameMethod {
    Rmf,
    Frenet,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RadiusMode {
    Local,
    Global,
}

/// How vertices are coloured.
#[derive(Clone)]
pub enum ColorMode<'a> {
    /// Absolute unit tangent as RGB (the usual directionally encoded colour).
    Direction,
    Constant([f32; 3]),
    /// A per-point attribute of the streamlines (first component), through a colour map over
    /// its range (`None`: [`colormap`]).
    Scalar(String, Option<Colormap>),
    /// A scalar function of world position (a volume sampled along the tube), with its range,
    /// through a colour map (`None`: [`colormap`]).
    Field(
        &'a (dyn Fn(DVec3) -> f64 + Sync),
        [f64; 2],
        Option<Colormap>,
    ),
}

/// The colour at `t` in [0, 1] of colour map `map` (`None`: [`colormap`]), sRGB-encoded as
/// every colour of a mesh or line set is (8-bit sRGB, as PLY and OBJ files carry them and
/// `#rrggbb` gives them; the renderer decodes them to linear light, `gbuffer.wgsl`).
pub fn map_color(map: Option<Colormap>, t: f64) -> [f32; 3] {
    match map {
        Some(m) => m.srgb(t).map(|c| c as f32),
        None => colormap(t),
    }
}

/// Options of [`build`].
pub struct TubeOptions<'a> {
    pub radius: f64,
    pub sides: usize,
    pub per_span: usize,
    /// Chordal tolerance in world units: sides and ring spacing follow it (error-bounded mode).
    pub chordal: Option<f64>,
    pub max_turn_deg: f64,
    pub frame: FrameMethod,
    pub radius_mode: RadiusMode,
    pub fit: FitOptions,
    pub caps: bool,
    pub color: ColorMode<'a>,
}

impl TubeOptions<'_> {
    /// The largest radius (world units) the mesher takes: beyond it vertices leave `f32`'s
    /// useful range (the same bound as a volume's coordinates).
    pub const MAX_RADIUS: f64 = 1e15;
    /// The smallest chordal tolerance, as a fraction of the radius: below it a ring would need
    /// more than the 256 sides the mesher makes (and spans are bisected to their depth limit,
    /// millions of triangles for a few points).
    pub const MIN_CHORDAL_FRACTION: f64 = 1e-4;

    /// Checks every setting's range (NaN and infinities refused), naming the setting: the one
    /// place the CLI, scene tube sets and benchmarks validate a mesher configuration.
    pub fn check(&self) -> std::result::Result<(), String> {
        let r = self.radius;
        let show = volume::show_number;
        if !(r.is_finite() && r > 0.0 && r <= Self::MAX_RADIUS) {
            return Err(format!(
                "radius {}: must be a positive number up to {:e}",
                show(r),
                Self::MAX_RADIUS
            ));
        }
        if !(3..=256).contains(&self.sides) {
            return Err(format!("sides {}: must be 3 to 256", self.sides));
        }
        if !(1..=64).contains(&self.per_span) {
            return Err(format!("rings per span {}: must be 1 to 64", self.per_span));
        }
        if let Some(c) = self.chordal {
            let min = Self::MIN_CHORDAL_FRACTION * r;
            if !(c.is_finite() && c >= min) {
                return Err(format!(
                    "chordal tolerance {}: must be a number of at least {:e} x the radius \
                     ({} for radius {})",
                    show(c),
                    Self::MIN_CHORDAL_FRACTION,
                    show(min),
                    show(r)
                ));
            }
        }
        let t = self.max_turn_deg;
        if !(t.is_finite() && t > 0.0 && t <= 180.0) {
            return Err(format!("max turn {t} degrees: must be in (0, 180]"));
        }
        let e = self.fit.epsilon;
        if !(e.is_finite() && e > 0.0) {
            return Err(format!("fit tolerance {e}: must be a positive number"));
        }
        Ok(())
    }

    /// The mesher's defaults, as `umbra tubes` and the scene's tube sets have them: iterative
    /// fit to `tolerance` (100 iterations at most), rotation-minimising frames, local radius,
    /// caps, one ring per span and one more per 15 degrees of turn, coloured by direction.
    pub fn defaults(radius: f64, sides: usize, tolerance: f64) -> TubeOptions<'static> {
        TubeOptions {
            radius,
            sides,
            per_span: 1,
            chordal: None,
            max_turn_deg: 15.0,
            frame: FrameMethod::Rmf,
            radius_mode: RadiusMode::Local,
            fit: FitOptions {
                epsilon: tolerance,
                method: crate::bspline_fit::FitMethod::Iterative,
                max_iterations: 100,
            },
            caps: true,
            color: ColorMode::Direction,
        }
    }
}

/// Tubes along straight segments (each sampled at 21 points), meshed with
/// [`TubeOptions::defaults`] at a tolerance of 0.01 in one colour (linear RGB in [0, 1]): the
/// synthetic tube sets of tests and benchmarks.
pub fn straight_tubes(
    lines: &[[[f32; 3]; 2]],
    radius: f64,
    sides: usize,
    rgb: [f32; 3],
) -> TubeMesh {
    let mut s = crate::Streamlines::new();
    for l in lines {
        let (a, b) = (Vec3::from(l[0]), Vec3::from(l[1]));
        let pts: Vec<Vec3> = (0..=20).map(|i| a + (b - a) * (i as f32 / 20.0)).collect();
        s.push(&pts);
    }
    let mut o = TubeOptions::defaults(radius, sides, 0.01);
    o.color = ColorMode::Constant(rgb);
    build(&s, &o).0
}

/// An indexed triangle mesh. Positions are relative to `origin` (kept in f64 so that tubes far
/// from the world origin, 1e6 say, keep their shape in f32).
#[derive(Clone, Debug, Default)]
pub struct TubeMesh {
    pub origin: DVec3,
    pub positions: Vec<Vec3>,
    pub normals: Vec<Vec3>,
    pub colors: Vec<[u8; 3]>,
    pub indices: Vec<u32>,
    /// The tubes' nominal radius, world units (the mesher's `TubeOptions::radius`; 0 when
    /// unknown, as for meshes read from files): LineAO's `r0` of tubes (eq. 16).
    pub radius: f64,
    /// The surface's opacity in [0, 1] (`None`: opaque); below 1 the renderer draws it
    /// translucent.
    pub opacity: Option<f32>,
}

impl TubeMesh {
    pub fn triangles(&self) -> usize {
        self.indices.len() / 3
    }
}

/// What the mesher did (the keys of `umbra tubes --stats-json`).
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct TubeStats {
    pub streamlines_in: usize,
    pub streamlines_out: usize,
    pub points_in: usize,
    pub control_points: usize,
    pub triangles: usize,
    pub max_deviation: f64,
    pub max_twist_deg: f64,
    pub min_section_ratio: f64,
    pub radius_clamps: usize,
    pub splits: usize,
    pub dropped_points: usize,
    pub skipped_streamlines: usize,
    /// Pieces meshed as their polyline (a ring on each point the tolerance cannot let go,
    /// `simplify_polyline`) because the fit could not shorten them within the tolerance.
    pub polyline_pieces: usize,
    /// Points dropped where the line turns by more than 100 degrees next to a segment no
    /// longer than the tolerance (trackers' hooks and side steps, [`drop_kinks`]).
    pub kinks: usize,
}

/// Splits a cleaned polyline where its direction reverses (turn > 179.9 degrees).
pub fn split_reversals(points: &[DVec3]) -> Vec<Vec<DVec3>> {
    reversal_ranges(points)
        .into_iter()
        .map(|(a, b)| points[a..=b].to_vec())
        .collect()
}

/// The pieces of [`split_reversals`] as inclusive index ranges (neighbours share the point at
/// the reversal).
fn reversal_ranges(points: &[DVec3]) -> Vec<(usize, usize)> {
    // a . b < cos(179.9 deg) |a| |b|, squared (the cosine is negative) to avoid square roots.
    let c = (179.9f64).to_radians().cos();
    let mut out = Vec::with_capacity(1);
    let mut start = 0;
    for i in 1..points.len().saturating_sub(1) {
        let (a, b) = (points[i] - points[i - 1], points[i + 1] - points[i]);
        let d = a.dot(b);
        if d < 0.0 && d * d > c * c * a.length_squared() * b.length_squared() {
            out.push((start, i));
            start = i;
        }
    }
    out.push((start, points.len() - 1));
    out
}

fn any_perpendicular(t: DVec3) -> DVec3 {
    let a = if t.x.abs() < 0.9 { DVec3::X } else { DVec3::Y };
    t.cross(a).normalize()
}

/// Rotation-minimizing frame vectors by double reflection (Wang et al. 2008).
///
/// The reflections are orthogonal maps, so the frame vector stays a unit vector normal to the
/// tangent but for rounding; each written vector is re-orthonormalised against its tangent,
/// while the sequence carries the reflected vector as it is and takes the corrected one every
/// [`RMF_RESYNC`] rings, or at once where the reflection left it far from unit length or along
/// the tangent (degenerate steps). Each ring then waits only for the two reflections of the one before, not
/// also for a square root and a division (a ring per point on rough tracts made this chain
/// 12% of a mesh, docs/benchmarks.md); the rounding carried meanwhile is a few ulps.
pub fn rmf(x: &[DVec3], t: &[DVec3]) -> Vec<DVec3> {
    let mut r = Vec::with_capacity(x.len());
    rmf_into(x, t, &mut r);
    r
}

/// [`rmf`] into `r` (cleared first), whose allocation a caller reuses.
fn rmf_into(x: &[DVec3], t: &[DVec3], r: &mut Vec<DVec3>) {
    r.clear();
    let mut carry = any_perpendicular(t[0]);
    r.push(carry);
    for i in 0..x.len() - 1 {
        let v1 = x[i + 1] - x[i];
        let c1 = v1.dot(v1);
        // The double reflection assumes the chord runs along the curve: where it turns more than
        // 30 degrees from the tangent at either end (a hair-length side step of a rough tract,
        // between tangents that hardly differ), its two planes turn the frame by an arbitrary
        // angle about the tangent - 180 degrees on HCP1065's TR_S_R, a tube pinched to its
        // axis. There the frame is carried by the rotation that takes one tangent to the next
        // (the least roll those tangents allow).
        let (a0, a1) = (v1.dot(t[i]), v1.dot(t[i + 1]));
        if !(a0 > 0.0 && a1 > 0.0 && 4.0 * a0 * a0 > 3.0 * c1 && 4.0 * a1 * a1 > 3.0 * c1) {
            let next = rotated(t[i], t[i + 1], carry);
            let fixed = (next - t[i + 1] * next.dot(t[i + 1]))
                .try_normalize()
                .unwrap_or_else(|| any_perpendicular(t[i + 1]));
            r.push(fixed);
            carry = fixed;
            continue;
        }
        let (rl, tl) = if c1 > 1e-300 {
            (
                carry - v1 * (2.0 / c1 * v1.dot(carry)),
                t[i] - v1 * (2.0 / c1 * v1.dot(t[i])),
            )
        } else {
            (carry, t[i])
        };
        let v2 = t[i + 1] - tl;
        let c2 = v2.dot(v2);
        let next = if c2 > 1e-300 {
            rl - v2 * (2.0 / c2 * v2.dot(rl))
        } else {
            rl
        };
        // Re-orthonormalised against the tangent (rounding); the fallback only where the
        // rounding left nothing (not made eagerly: a cross product and a square root a ring).
        let (fixed, fallback) = match (next - t[i + 1] * next.dot(t[i + 1])).try_normalize() {
            Some(f) => (f, false),
            None => (any_perpendicular(t[i + 1]), true),
        };
        r.push(fixed);
        let n2 = next.length_squared();
        carry = if fallback || i % RMF_RESYNC == RMF_RESYNC - 1 || !(0.999..=1.001).contains(&n2) {
            fixed
        } else {
            next
        };
    }
}

/// Rings between the corrections [`rmf`] carries.
const RMF_RESYNC: usize = 16;

/// Frenet normals with the flip correction.
pub fn frenet(curve: &BSpline, params: &[f64], t: &[DVec3]) -> Vec<DVec3> {
    let mut r: Vec<DVec3> = Vec::with_capacity(params.len());
    for (i, &u) in params.iter().enumerate() {
        let (_, _, d2) = curve.eval_d(u);
        let n = d2 - t[i] * d2.dot(t[i]);
        let n = if n.length() > 1e-9 * (1.0 + d2.length()) {
            n.normalize()
        } else if let Some(&p) = r.last() {
            (p - t[i] * p.dot(t[i]))
                .try_normalize()
                .unwrap_or_else(|| any_perpendicular(t[i]))
        } else {
            any_perpendicular(t[i])
        };
        let n = match r.last() {
            Some(&p) if n.dot(p) < 0.0 => -n,
            _ => n,
        };
        r.push(n);
    }
    r
}

/// Angle (degrees) between `r1` and `r0` carried from `t0` to `t1` by the smallest rotation.
pub fn twist_deg(t0: DVec3, t1: DVec3, r0: DVec3, r1: DVec3) -> f64 {
    twist_cos(t0, t1, r0, r1).acos().to_degrees()
}

/// The cosine of [`twist_deg`]'s angle (the largest twist along a tube is the arccosine of the
/// smallest of these, one arccosine per tube).
fn twist_cos(t0: DVec3, t1: DVec3, r0: DVec3, r1: DVec3) -> f64 {
    rotated(t0, t1, r0).dot(r1).clamp(-1.0, 1.0)
}

/// `r0` turned by the rotation that takes the unit tangent `t0` to `t1` about their common
/// normal (the least rotation between them; `r0` as it is where they are parallel).
fn rotated(t0: DVec3, t1: DVec3, r0: DVec3) -> DVec3 {
    let axis = t0.cross(t1);
    let s2 = axis.length_squared();
    let c = t0.dot(t1).clamp(-1.0, 1.0);
    if s2 < 1e-30 {
        r0
    } else {
        // Rodrigues about the unit axis k = axis / s (s = sin of the angle), written with the
        // unnormalised axis: (k x r0) s = axis x r0 and k (k . r0) (1 - c) = axis (axis . r0)
        // (1 - c) / s^2 - no square root.
        r0 * c + axis.cross(r0) + axis * (axis.dot(r0) * (1.0 - c) / s2)
    }
}

/// A curve point with its first two derivatives: `(u, C(u), C'(u), C''(u))`.
type CurvePoint = (f64, DVec3, DVec3, DVec3);

/// Ring parameters along a curve, with the curve evaluated there.
fn ring_params(
    curve: &BSpline,
    per_span: usize,
    max_turn: f64,
    chordal: Option<f64>,
) -> Vec<CurvePoint> {
    let n = curve.spans() * per_span.max(1);
    let at = |u: f64| {
        let (c, d1, d2) = curve.eval_d(u);
        (u, c, d1, d2)
    };
    let tan = |u: f64| curve.eval_d(u).1.normalize_or_zero();
    let mut out = Vec::with_capacity(n + 1);
    let mut pa = at(0.0);
    out.push(pa);
    let cos_max = max_turn.to_radians().cos();
    let (mut stack, mut pieces) = (Vec::new(), Vec::new());
    for i in 0..n {
        let (a0, b0) = (i as f64 / n as f64, (i + 1) as f64 / n as f64);
        let pb = at(b0);
        if chordal.is_none() && pa.2.normalize_or_zero().dot(pb.2.normalize_or_zero()) >= cos_max {
            // The common case: the span is smooth enough as it is.
            out.push(pb);
            pa = pb;
            continue;
        }
        // Bisect [a, b] until it is smooth enough.
        stack.push((a0, b0, 0));
        while let Some((a, b, depth)) = stack.pop() {
            let turn_ok = tan(a).dot(tan(b)) >= cos_max;
            let chord_ok = match chordal {
                Some(tol) => {
                    let len = (curve.eval(b) - curve.eval(a)).length();
                    let k = curve.curvature(0.5 * (a + b));
                    len * len * k / 8.0 <= tol
                }
                None => true,
            };
            if (turn_ok && chord_ok) || depth >= 12 {
                pieces.push(if b == b0 { pb } else { at(b) });
            } else {
                let m = 0.5 * (a + b);
                stack.push((m, b, depth + 1));
                stack.push((a, m, depth + 1));
            }
        }
        // The stack visits left halves first.
        out.append(&mut pieces);
        pa = pb;
    }
    out
}

/// The curvature of a turn between consecutive rings, `acos(c) / ds` for tangents at cosine
/// `c` a spacing `ds` apart, which limits a ring's radius to `0.9 / curvature` (or the inner
/// side of the bend folds between the rings). With `local` radii a turn that cannot limit
/// `radius` gives 0 instead, without the arccosine (most rings of a smooth tube): as
/// `theta <= pi sin(theta / 2) = pi sqrt((1 - c) / 2)`, a turn with `pi^2 (1 - c) / 2 <
/// (0.9 ds / radius)^2` (less a margin for rounding) has `0.9 ds / theta > radius`. A ring's
/// radius is the smallest of its limits, so the radii are the same. A global radius takes the
/// largest curvature, so every turn's is computed there.
fn turn_curvature(c: f64, ds: f64, radius: f64, local: bool) -> f64 {
    let (c, ds) = (c.clamp(-1.0, 1.0), ds.max(1e-300));
    let free = 0.9 * ds / radius;
    if local
        && std::f64::consts::PI * std::f64::consts::PI * 0.5 * (1.0 - c) * (1.0 + 1e-6)
            < free * free
    {
        0.0
    } else {
        c.acos() / ds
    }
}

/// Sides for a chordal tolerance: the smallest `N >= 3` with `r (1 - cos(pi / N)) <= tol`.
pub fn sides_for(radius: f64, tol: f64) -> usize {
    (3..=256)
        .find(|&n| radius * (1.0 - (std::f64::consts::PI / n as f64).cos()) <= tol)
        .unwrap_or(256)
}

/// Colour map for scalars in [0, 1] (a perceptually ordered blue-green-yellow ramp, viridis
/// anchors).
pub fn colormap(v: f64) -> [f32; 3] {
    const A: [[f32; 3]; 5] = [
        [0.267, 0.005, 0.329],
        [0.229, 0.322, 0.546],
        [0.128, 0.567, 0.551],
        [0.369, 0.789, 0.383],
        [0.993, 0.906, 0.144],
    ];
    let v = if v.is_finite() {
        v.clamp(0.0, 1.0)
    } else {
        0.0
    } * 4.0;
    let i = (v.floor() as usize).min(3);
    let f = (v - i as f64) as f32;
    [0, 1, 2].map(|c| A[i][c] + (A[i + 1][c] - A[i][c]) * f)
}

/// The bytes a ring of a tube takes while the mesh is built (every tube's rings are found
/// before the mesh is written): for estimates of the memory a mesh needs.
pub const RING_BYTES: u64 = std::mem::size_of::<Ring>() as u64;

/// One ring of a tube piece: what [`emit`] needs to write its vertices.
#[derive(Clone, Copy, Debug)]
struct Ring {
    /// The centre relative to the mesh origin (not used where `cut`).
    centre: DVec3,
    /// Frame vectors (unit; f32 is ample for directions and halves the memory).
    r: Vec3,
    b: Vec3,
    t: Vec3,
    radius: f64,
    drds: f64,
    color: [u8; 3],
    /// The tube is cut here (no ring).
    cut: bool,
    /// The first ring of a tube piece: no quads join it to the ring before.
    start: bool,
}

/// The tube pieces of one streamline, ready to be written: their rings one after the other
/// and what they need in the output buffers. Vertices are written straight into the mesh by
/// [`emit`], so no per-piece vertex buffers are built and concatenated. One allocation a
/// streamline, not a piece: a random walk of 100 points is split into 58 pieces at its sharp
/// turns (docs/benchmarks.md, "Lines that turn sharply").
struct Rings {
    sides: usize,
    rings: Vec<Ring>,
    /// Runs of kept rings `(first, last)` that get end caps, in order.
    caps: Vec<(usize, usize)>,
    vertices: usize,
    indices: usize,
    /// The pieces appended ([`tube_as`]).
    pieces: usize,
    /// Their statistics together (counts summed, largest deviation and twist).
    stats: TubeStats,
}

impl Rings {
    fn new(sides: usize) -> Rings {
        Rings {
            sides,
            rings: Vec::new(),
            caps: Vec::new(),
            vertices: 0,
            indices: 0,
            pieces: 0,
            stats: TubeStats::default(),
        }
    }
}

/// Writes the vertices and triangles of a tube piece of `sides`-gons through `rings` (with end
/// caps on the runs `caps`) into the given parts of the mesh buffers (exactly `vertices` and
/// `indices` long); `first` is the index of the first vertex. Returns the smallest section
/// ratio: the stored ring polygon's area, projected on the plane normal to its tangent, over
/// the ideal polygon's. `trig` is [`ring_trig`] of `sides` (made here where it is not).
#[allow(clippy::too_many_arguments)]
fn emit(
    sides: usize,
    trig: &[(f64, f64)],
    rings: &[Ring],
    caps: &[(usize, usize)],
    (vertices, indices): (usize, usize),
    first: u32,
    pos: &mut [std::mem::MaybeUninit<Vec3>],
    nor: &mut [std::mem::MaybeUninit<Vec3>],
    col: &mut [std::mem::MaybeUninit<[u8; 3]>],
    idx: &mut [std::mem::MaybeUninit<u32>],
) -> f64 {
    let step = std::f64::consts::TAU / sides as f64;
    let own;
    let trig = if trig.len() == sides {
        trig
    } else {
        own = ring_trig(sides);
        &own[..]
    };
    let ideal = |r: f64| 0.5 * sides as f64 * r * r * step.sin();
    let mut min_ratio = f64::INFINITY;
    let mut v = 0usize;
    let mut k = 0usize;
    let s32 = sides as u32;
    // The first vertex of the ring before, where it was kept.
    let mut before: Option<u32> = None;
    for g in rings {
        if g.cut || g.start {
            before = None;
        }
        if g.cut {
            continue;
        }
        let r1 = first + v as u32;
        let (centre, r, b, t, radius, drds) = (
            g.centre,
            g.r.as_dvec3(),
            g.b.as_dvec3(),
            g.t.as_dvec3(),
            g.radius,
            g.drds,
        );
        for &(ca, sa) in trig {
            let radial = r * ca + b * sa;
            let p = (centre + radial * radius).as_vec3();
            pos[v].write(p);
            // The radial direction is a unit vector; only a changing radius tilts it.
            let n = if drds == 0.0 {
                radial
            } else {
                (radial - t * drds).normalize()
            };
            nor[v].write(n.as_vec3());
            col[v].write(g.color);
            v += 1;
        }
        // Section ratio in the stored precision (a fan about the ring's first vertex).
        let ring = v - sides;
        // SAFETY: the ring's vertices were written just above.
        let at = |j: usize| unsafe { pos[ring + j].assume_init() }.as_dvec3();
        let p0 = at(0);
        let mut area = 0.0;
        let mut prev = at(1) - p0;
        for j in 2..sides {
            let q = at(j) - p0;
            area += 0.5 * prev.cross(q).dot(t);
            prev = q;
        }
        let ratio = if radius > 0.0 {
            area / ideal(radius)
        } else {
            1.0
        };
        min_ratio = min_ratio.min(ratio);
        // The quads between this ring and the one before, counter-clockwise seen from outside.
        if let Some(r0) = before {
            for j in 0..s32 {
                let (a, b) = (r0 + j, r0 + (j + 1) % s32);
                let (c, d) = (r1 + j, r1 + (j + 1) % s32);
                for i in [a, b, d, a, d, c] {
                    idx[k].write(i);
                    k += 1;
                }
            }
        }
        before = Some(r1);
    }
    let mut put = |i: u32, k: &mut usize| {
        idx[*k].write(i);
        *k += 1;
    };
    // The first vertex of a kept ring, counted from the piece's first: the caps' rings come
    // in order, so the kept rings before each are counted on from the last.
    let (mut counted, mut kept_before) = (0usize, 0usize);
    let mut base = |ring: usize| {
        kept_before += rings[counted..ring].iter().filter(|g| !g.cut).count();
        counted = ring;
        kept_before * sides
    };
    for &(first_ring, last_ring) in caps {
        for (ring, dir, flip) in [
            (first_ring, -rings[first_ring].t.as_dvec3(), true),
            (last_ring, rings[last_ring].t.as_dvec3(), false),
        ] {
            let rb = base(ring);
            let centre = first + v as u32;
            pos[v].write(rings[ring].centre.as_vec3());
            nor[v].write(dir.as_vec3());
            col[v].write(rings[ring].color);
            v += 1;
            let rim = first + v as u32;
            for j in 0..sides {
                // SAFETY: vertex rb + j of this piece was written above.
                let p = unsafe { pos[rb + j].assume_init() };
                pos[v].write(p);
                nor[v].write(dir.as_vec3());
                col[v].write(rings[ring].color);
                v += 1;
            }
            for j in 0..s32 {
                let (p, q) = (rim + j, rim + (j + 1) % s32);
                let tri = if flip { [centre, q, p] } else { [centre, p, q] };
                for i in tri {
                    put(i, &mut k);
                }
            }
        }
    }
    assert!(
        v == vertices && k == indices,
        "tube piece wrote {v} vertices and {k} indices, {vertices} and {indices} counted"
    );
    min_ratio
}

/// The cosines and sines of the angles of a ring's `sides` vertices.
fn ring_trig(sides: usize) -> Vec<(f64, f64)> {
    let step = std::f64::consts::TAU / sides as f64;
    (0..sides)
        .map(|j| ((step * j as f64).cos(), (step * j as f64).sin()))
        .collect()
}

fn rgb8(c: [f32; 3]) -> [u8; 3] {
    c.map(|v| (v.clamp(0.0, 1.0) * 255.0 + 0.5) as u8)
}

/// Whether a line is too rough for the fit to shorten. Either more than a quarter of its
/// interior points lie more than twice the tolerance from the midpoint of their neighbours
/// (noise: halving the control points drops every other point, so such a line fails the
/// first halving, measured on noisy helices), or one point's fourth difference
/// `p[i-2] - 4 p[i-1] + 6 p[i] - 4 p[i+1] + p[i+2]` exceeds [`ROUGH_FOURTH`] tolerances (a
/// kink: samples of one cubic have none, so five samples each within the tolerance of one
/// have at most 16; the halved fit is cubic over spans of two samples). The fit halves its
/// control points for the whole line at once, so one such point keeps every point, and the
/// fit would only re-trace the polyline at full cost (a third of a mesh of the HCP1065 CST_L
/// bundle, docs/benchmarks.md). A wrong guess costs triangles, never accuracy.
fn too_rough(points: &[DVec3], tolerance: f64) -> bool {
    let n = points.len();
    if n < 8 {
        return false;
    }
    let lim = (4.0 * tolerance) * (4.0 * tolerance);
    let rough = points
        .windows(3)
        .filter(|w| (w[0] + w[2] - 2.0 * w[1]).length_squared() > lim)
        .count();
    rough * 4 > n - 2 || kinked(points, tolerance)
}

/// Whether a point's fourth difference exceeds [`ROUGH_FOURTH`] tolerances ([`too_rough`]'s
/// kink).
fn kinked(points: &[DVec3], tolerance: f64) -> bool {
    let kink = (ROUGH_FOURTH * tolerance).powi(2);
    points
        .windows(5)
        .any(|w| (w[0] + w[4] + 6.0 * w[2] - 4.0 * (w[1] + w[3])).length_squared() > kink)
}

/// The fourth difference, in tolerances, beyond which [`too_rough`] calls a line a polyline:
/// above the 16 that five samples within the tolerance of one cubic can reach, for fits whose
/// spans fall unevenly among the samples. Measured on whole cleaned lines of at least eight
/// points at tolerance 0.02 (`cargo run --release -p tubes --example fit_kinks -- 0.02 FILE...`,
/// docs/benchmarks.md): the fits that shortened a line stay below 11.7 on DIPY tracks300 and
/// 1.9 on the smooth benchmark lines, and below 1.1 on circles and helices of any radius and
/// sampling (the test below); no HCP1065 CST_L or AF_R line's fit shortens it, and 5,522 of
/// CST_L's 5,577 exceed 24.
const ROUGH_FOURTH: f64 = 24.0;

/// The most points a segment of [`simplify_polyline`] passes over, which bounds its cost to
/// `SIMPLIFY_SPAN` distance tests a point.
const SIMPLIFY_SPAN: usize = 16;

/// The most a segment of [`simplify_polyline`] turns from the one before (unless the
/// polyline itself turns more at a point), degrees: longer segments that turn more twist the
/// frames between rings (DIPY's tracks300 at tolerance 0.1: the largest twist 1.32 degrees with
/// every point, 1.79 with 15 degrees, 1.32 with 10; HCP1065 CST_L at 0.02 keeps 48% of its
/// points with 10 degrees, 46.8% with 15).
const SIMPLIFY_TURN_DEG: f64 = 10.0;

/// The points of a polyline its tube needs within `tolerance`: from the first point, each
/// segment is extended point by point while every point it passes lies within `tolerance` of
/// it, it turns by at most `max_turn_deg` from the segment before and it passes at most
/// [`SIMPLIFY_SPAN`] points, then the next starts where it ends. Returns the
/// kept indices (the first and the last point always) and the largest distance of a dropped
/// point to the segment that replaced it - a bound of its distance to the tube's axis.
/// vtkTubeFilter places a ring at every point; a tractogram's polyline lines often run
/// straighter than their sampling (at tolerance 0.02 this keeps 48% of HCP1065 CST_L's
/// points and 51% of AF_R's, docs/benchmarks.md), and the rings left cost as much as the rest
/// of the meshing.
fn simplify_polyline(points: &[DVec3], tolerance: f64, max_turn_deg: f64) -> (Vec<usize>, f64) {
    let n = points.len();
    let mut keep = Vec::with_capacity(n);
    if n == 0 {
        return (keep, 0.0);
    }
    let tol2 = tolerance * tolerance;
    let cos_turn = max_turn_deg.to_radians().cos();
    let mut worst2 = 0.0f64;
    let mut a = 0;
    // The direction of the last segment (unit), or zero before the first.
    let mut last = DVec3::ZERO;
    keep.push(0);
    while a + 1 < n {
        let (mut b, mut b_worst2) = (a + 1, 0.0f64);
        for c in a + 2..n.min(a + SIMPLIFY_SPAN + 1) {
            let (p, v) = (points[a], points[c] - points[a]);
            let vv = v.length_squared();
            // No longer segment that turns more from the last than the rings of a fit may.
            if last != DVec3::ZERO && last.dot(v) < cos_turn * vv.sqrt() {
                break;
            }
            let mut w2 = 0.0f64;
            for &x in &points[a + 1..c] {
                w2 = w2.max(segment_distance2(x, p, points[c]));
                if w2 > tol2 {
                    break;
                }
            }
            if w2 > tol2 {
                break;
            }
            (b, b_worst2) = (c, w2);
        }
        worst2 = worst2.max(b_worst2);
        keep.push(b);
        last = (points[b] - points[a]).normalize_or_zero();
        a = b;
    }
    (keep, worst2.sqrt())
}

/// The points of a cleaned polyline left once its kinks are dropped, and their largest distance
/// to the polyline through the points left: where the line turns by more than 100 degrees at a
/// point next to a segment no longer than `tolerance`, the point goes, if every point dropped
/// between the kept points around it stays within `tolerance` of the segment that replaces them.
/// Trackers leave such kinks: a hook at a line's end (its first or last step doubling back) and
/// hair-length side steps (HCP1065's 1/32 mm): 1,392 of AF_R's 3,356 lines end in a hook 0.03-0.52
/// mm long (`bench/tract_kinks.py`). A sharp turn keeps a line from being meshed as its polyline (its rings would fold) or
/// splits it there, so at coarse tolerances such lines kept fits with more rings than their
/// polylines needed (0.2 cost more triangles than 0.1 on nine of HCP1065's ten bundles), or were
/// split into pieces a side step long that showed as cracks and slivers (docs/benchmarks.md).
/// First a hook's tip goes where it lies within `tolerance` of the segment before the turn (the
/// hook runs back inside the tube, however long); then a short hook's turn point (the line
/// ends at the hook's tip, within the tolerance of where it turned). At least two points stay.
fn drop_kinks(points: &[DVec3], tolerance: f64) -> (Vec<usize>, f64) {
    let t2 = tolerance * tolerance;
    let mut keep: Vec<usize> = Vec::with_capacity(points.len());
    let mut worst2 = 0.0f64;
    // A hook that runs back along the line (an end turning sharply, its tip within the
    // tolerance of the segment before the turn) loses its tip, however long: the tube covers
    // it (HCP1065's TR_S_R ends in exact reversals up to 0.52 mm long, whose stubs showed
    // through the end caps).
    let (mut lo, mut hi) = (0, points.len());
    while hi - lo >= 3 && sharp(&points[lo..lo + 3]) {
        let w2 = segment_distance2(points[lo], points[lo + 1], points[lo + 2]);
        if w2 > t2 {
            break;
        }
        worst2 = worst2.max(w2);
        lo += 1;
    }
    while hi - lo >= 3 && sharp(&points[hi - 3..hi]) {
        let w2 = segment_distance2(points[hi - 1], points[hi - 3], points[hi - 2]);
        if w2 > t2 {
            break;
        }
        worst2 = worst2.max(w2);
        hi -= 1;
    }
    for (i, &q) in points.iter().enumerate().take(hi).skip(lo) {
        while let [.., ia, ib] = keep[..] {
            let (a, b) = (points[ia], points[ib]);
            if !sharp(&[a, b, q]) || (b - a).length_squared().min((q - b).length_squared()) > t2 {
                break;
            }
            // Every point between a and q, b and those dropped before it, against a-q.
            let w2 = points[ia + 1..i]
                .iter()
                .map(|&x| segment_distance2(x, a, q))
                .fold(0.0f64, f64::max);
            if w2 > t2 {
                break;
            }
            worst2 = worst2.max(w2);
            keep.pop();
        }
        keep.push(i);
    }
    (keep, worst2.sqrt())
}

/// The squared distance from `x` to the segment `a`-`b`.
fn segment_distance2(x: DVec3, a: DVec3, b: DVec3) -> f64 {
    let (v, d) = (b - a, x - a);
    let vv = v.length_squared();
    let u = if vv > 0.0 {
        (d.dot(v) / vv).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (d - v * u).length_squared()
}

/// Whether the polyline turns by more than 100 degrees at the middle point of `w`.
fn sharp(w: &[DVec3]) -> bool {
    // a . b < -0.17 |a| |b|, squared (no square roots): a . b < 0 and (a . b)^2 > 0.17^2
    // |a|^2 |b|^2.
    let (a, b) = (w[1] - w[0], w[2] - w[1]);
    let d = a.dot(b);
    d < 0.0 && d * d > 0.17 * 0.17 * a.length_squared() * b.length_squared()
}

/// Whether the polyline turns by more than 100 degrees at some point.
fn sharp_turn(points: &[DVec3]) -> bool {
    points.windows(3).any(sharp)
}

/// `[a, b]` split at the points where the polyline turns by more than 100 degrees (neighbours
/// share the point of the turn), as [`reversal_ranges`] splits at reversals.
fn sharp_ranges(points: &[DVec3], a: usize, b: usize) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    let mut start = a;
    for i in a + 1..b {
        if sharp(&points[i - 1..=i + 1]) {
            out.push((start, i));
            start = i;
        }
    }
    out.push((start, b));
    out
}

/// The points whose rings a piece meshed as its polyline needs, and the largest deviation of
/// the others from the rings' polyline: those the tolerance lets go are dropped where the
/// colour does not come from them (`simplify_polyline`), unless the rings left would turn
/// sharply at a point and fold there.
fn polyline_rings(points: &[DVec3], o: &TubeOptions) -> (Vec<usize>, f64) {
    let all = || (0..points.len()).collect::<Vec<usize>>();
    match o.color {
        ColorMode::Direction | ColorMode::Constant(_) => {
            let (keep, d) = simplify_polyline(points, o.fit.epsilon, SIMPLIFY_TURN_DEG);
            if keep
                .windows(3)
                .any(|w| sharp(&[points[w[0]], points[w[1]], points[w[2]]]))
            {
                (all(), 0.0)
            } else {
                (keep, d)
            }
        }
        ColorMode::Scalar(..) | ColorMode::Field(..) => (all(), 0.0),
    }
}

/// The rings the parts of `points` between its sharp turns (more than 100 degrees at a point,
/// [`sharp_ranges`]) would need as polylines ([`polyline_rings`]; none of them turns sharply,
/// so their rings do not fold), the points of the turns counted in both parts; `usize::MAX`
/// where a sharp turn is one at the tube's scale too (twice its radius, or four tolerances
/// where longer): the chords that long before and after its point turn by more than 60
/// degrees (a hairpin, whose parts' open ends would show as a notch at its apex where the fit
/// makes a narrowed tip; a hair-length side step of a straight run turns by little at that
/// scale, and two tubes meeting there look as one; a hook at the line's end, shorter than
/// that, leaves a stub about as long as the tube is wide).
fn split_rings(points: &[DVec3], o: &TubeOptions) -> usize {
    // The tube's scale: twice its radius, or four tolerances where they are the longer.
    let scale = (2.0 * o.radius).max(4.0 * o.fit.epsilon);
    let r2 = scale * scale;
    let n = points.len();
    for i in 1..n - 1 {
        if !sharp(&points[i - 1..=i + 1]) {
            continue;
        }
        // (A leg shorter than the scale - a hook at the line's end - leaves a stub about as
        // long as the tube is wide: no apex to show.)
        let p = points[i];
        let back = (0..i)
            .rev()
            .find(|&j| (points[j] - p).length_squared() >= r2);
        let ahead = (i + 1..n).find(|&j| (points[j] - p).length_squared() >= r2);
        if let (Some(back), Some(ahead)) = (back, ahead) {
            let (a, b) = (p - points[back], points[ahead] - p);
            if a.dot(b) < 0.5 * (a.length_squared() * b.length_squared()).sqrt() {
                return usize::MAX;
            }
        }
    }
    sharp_ranges(points, 0, n - 1)
        .into_iter()
        .map(|(a, b)| polyline_rings(&points[a..=b], o).0.len())
        .sum()
}

/// The working arrays of [`tube_as`], one set a thread, reused piece after piece.
#[derive(Default)]
struct Scratch {
    x: Vec<DVec3>,
    t: Vec<DVec3>,
    k: Vec<f64>,
    params: Vec<f64>,
    samples: Vec<f64>,
    frames: Vec<DVec3>,
    seg: Vec<f64>,
    kd: Vec<f64>,
    radii: Vec<f64>,
    cut: Vec<bool>,
    s: Vec<f64>,
    runs: Vec<(usize, usize)>,
}

thread_local! {
    static SCRATCH: std::cell::Cell<Scratch> = Default::default();
}

/// Builds the tube of one cleaned polyline piece and appends it to `out`.
///
/// `false` (nothing appended) where the fit would place more rings than the piece has points (or keep every point)
/// and the piece turns sharply (more than 100 degrees at a point), which keeps it from being
/// meshed as its polyline, or where the fit places more rings than the parts between its sharp
/// turns would as polylines ([`split_rings`]): the caller splits it at its sharp turns and
/// meshes the parts with `between_turns`, each as its polyline where the fit would again place
/// more rings than it has points, whatever its length. So no piece gets more rings than points - vtkTubeFilter's
/// ring per point - unless its fit places fewer (HCP1065 at tolerance 0.02: 4,071 pieces had
/// 94,114 rings more than points, 1.2% more triangles than VTK).
fn tube(
    points: &[DVec3],
    attr: Option<(&[f32], [f64; 2])>,
    o: &TubeOptions,
    origin: DVec3,
    between_turns: bool,
    out: &mut Rings,
) -> bool {
    tube_as(points, attr, o, origin, between_turns, false, out)
}

/// [`tube`], meshed as its polyline without a fit where `rough` (a part between sharp turns
/// of a line [`too_rough`] to fit). The piece is appended to `out` (whose `sides` it takes);
/// `false` (nothing appended) where [`tube`] says so.
fn tube_as(
    points: &[DVec3],
    attr: Option<(&[f32], [f64; 2])>,
    o: &TubeOptions,
    origin: DVec3,
    between_turns: bool,
    rough: bool,
    out: &mut Rings,
) -> bool {
    let mut st = TubeStats {
        min_section_ratio: f64::INFINITY,
        ..Default::default()
    };
    // A line too rough for the fit to shorten (noise above the tolerance) is meshed as the
    // polyline it is, a ring on each point the tolerance cannot let go (vtkTubeFilter puts one
    // on every point): deviation within the tolerance, and no more rings than points, which the fit's refinement of its turning spans would exceed (2.4x
    // vtkTubeFilter's triangles on noisy helices, docs/benchmarks.md). Decided before fitting
    // when the points say so, or after it when the fit kept every point (of a line of at least
    // eight, or of a part between sharp turns), placed more rings than the line has points or
    // missed the tolerance. Never where the line turns sharply at a point (more than 100
    // degrees), whose rings would fold there: rough lines are split at such turns beforehand
    // (`prepare`), and a fitted line that needs its polyline is refused (`false`) for
    // `prepare` to split the same way (see the doc above).
    let rmf_iterative = o.frame == FrameMethod::Rmf && o.fit.method == FitMethod::Iterative;
    let mut polyline =
        rmf_iterative && (rough || too_rough(points, o.fit.epsilon)) && !sharp_turn(points);
    let fitted = (!polyline).then(|| fit(points, &o.fit));
    let mut fit_params = Vec::new();
    // The polyline's rings, where the decision below took them.
    let mut kept: Option<(Vec<usize>, f64)> = None;
    if let Some(f) = &fitted {
        // Meshed as its polyline (deviation 0) where the fit keeps every point (which tells a
        // rough line only from eight points up, or in a part between sharp turns: a cubic
        // needs four control points whatever the line), misses the tolerance (short parts
        // between turns can) or places more rings than points. The rings are placed only
        // where the first two leave the question open or the fit is kept.
        let in_vain = ((points.len() >= 8 || between_turns)
            && f.curve.control.len() >= points.len())
            || f.max_deviation > o.fit.epsilon;
        if !(rmf_iterative && in_vain) {
            fit_params = ring_params(&f.curve, o.per_span, o.max_turn_deg, o.chordal);
        }
        // A curve that passes its points but loops between them (a tangent at a ring more
        // than 60 degrees off the chord to the next ring: four points 0.5, 1, 0.5 apart gave
        // a cubic whose end tangents ran 115 degrees from the line, rings tilted across it and
        // narrowed to 0.006 of the radius by the loop's curvature) is meshed as its polyline.
        let loops = fit_params.windows(2).any(|w| {
            let chord = (w[1].1 - w[0].1).normalize_or_zero();
            chord != DVec3::ZERO
                && (w[0].2.normalize_or_zero().dot(chord) < 0.5
                    || w[1].2.normalize_or_zero().dot(chord) < 0.5)
        });
        let sharp = sharp_turn(points);
        // Against the rings its polyline would place (the points the tolerance cannot let
        // go), not its points: on HCP1065's TR_S_R at tolerance 0.1, lines smooth enough to be
        // fitted took more rings than their polylines, 785,248 triangles against 430,896 at
        // the tighter 0.05, where they were rough enough to be polylines (369,376 since).
        // A line that turns sharply at a point too, where its rings would not (the points the
        // tolerance keeps turn by at most 10 degrees at each: HCP1065's hair-length side steps
        // let go); where they would fold, `polyline_rings` keeps every point, more rings than
        // the fit's, and the fit stays (a smooth hairpin).
        // Where they would fold and the fit still places more rings than the parts between
        // the sharp turns would as polylines, the line is split there instead (`false`: the
        // caller meshes the parts, each fitted or not on its own): at tolerance 0.2 such fits
        // kept nine of HCP1065's ten bundles 6-25% above their triangles at 0.1.
        let mut kept_sharp = false;
        if rmf_iterative && !in_vain && !loops && fit_params.len() <= points.len() {
            let keep = polyline_rings(points, o);
            if fit_params.len() > keep.0.len() {
                kept_sharp = sharp;
                kept = Some(keep);
            } else if sharp && !between_turns && split_rings(points, o) < fit_params.len() {
                return false;
            }
        }
        let as_polyline = in_vain || fit_params.len() > points.len() || loops || kept.is_some();
        if rmf_iterative && as_polyline && sharp && !kept_sharp && !between_turns {
            return false;
        }
        polyline = rmf_iterative && as_polyline && (!sharp || kept_sharp);
        if !polyline && fit_params.is_empty() {
            fit_params = ring_params(&f.curve, o.per_span, o.max_turn_deg, o.chordal);
        }
    }
    let sides = out.sides;
    // The piece's working arrays, reused from the pieces this thread meshed before (a rough
    // line's pieces have a segment or two, and a dozen allocations each had cost them more
    // than their arithmetic: docs/benchmarks.md, "Lines that turn sharply").
    let mut scratch = SCRATCH.take();
    let Scratch {
        x,
        t,
        k,
        params: kept_params,
        samples: poly_samples,
        frames,
        seg,
        kd,
        radii,
        cut,
        s,
        runs,
    } = &mut scratch;
    for v in [&mut *x, &mut *t, &mut *frames] {
        v.clear();
    }
    for v in [
        &mut *k,
        &mut *kept_params,
        &mut *poly_samples,
        &mut *seg,
        &mut *kd,
        &mut *radii,
        &mut *s,
    ] {
        v.clear();
    }
    cut.clear();
    runs.clear();
    // The curve, and the parameters of the input points on it where it was fitted (a
    // polyline's are its ring numbers, `params` below).
    let (curve, fit_samples): (Option<&BSpline>, Option<&[f64]>) = if polyline {
        st.polyline_pieces = 1;
        // The points whose rings the tube needs: those the tolerance lets go are dropped
        // where the colour does not come from them (`simplify_polyline`), unless the rings
        // left would turn sharply at a point and fold there.
        let (keep, deviation) = kept.take().unwrap_or_else(|| polyline_rings(points, o));
        st.control_points = keep.len();
        st.max_deviation = deviation;
        let n = keep.len();
        for (m, &i) in keep.iter().enumerate() {
            let d = points[keep[(m + 1).min(n - 1)]] - points[keep[m.saturating_sub(1)]];
            x.push(points[i]);
            t.push(d.normalize_or(if let Some(&q) = t.last() { q } else { DVec3::X }));
            // The turn between rings is weighed by `kd` below.
            k.push(0.0);
            // A ring's parameter is its point's number, as the samples' below.
            kept_params.push(i as f64);
        }
        poly_samples.extend((0..points.len()).map(|i| i as f64));
        (None, Some(&poly_samples[..]))
    } else {
        let f = fitted.as_ref().expect("fitted");
        st.control_points = f.curve.control.len();
        st.max_deviation = f.max_deviation;
        // Rings closer than 1e-4 radius to the previous one (where the fitted curve all but
        // stops, at the apex of a near-reversal) would give zero-area quads: skip them, but
        // keep the last ring. (Of the piece's length where that is shorter: a tube wider than
        // its line is long keeps its rings; at a radius of 1e6 a straight line of 49 mm had
        // lost all but one.)
        let length: f64 = points.windows(2).map(|w| (w[1] - w[0]).length()).sum();
        let too_close = 1e-4 * o.radius.min(length);
        for (pi, &(u, c, d1, d2)) in fit_params.iter().enumerate() {
            if let Some(&prev) = x.last() {
                if (c - prev).length() < too_close {
                    if pi + 1 < fit_params.len() {
                        continue;
                    }
                    x.pop();
                    t.pop();
                    k.pop();
                    kept_params.pop();
                }
            }
            kept_params.push(u);
            x.push(c);
            t.push(d1.normalize_or(if let Some(&p) = t.last() { p } else { DVec3::X }));
            let l = d1.length();
            k.push(if l > 1e-300 {
                d1.cross(d2).length() / (l * l * l)
            } else {
                0.0
            });
        }
        (Some(&f.curve), Some(&f.sample_params[..]))
    };
    let params = &kept_params[..];
    let sample_params = fit_samples.unwrap_or(params);
    match o.frame {
        FrameMethod::Rmf => rmf_into(x, t, frames),
        FrameMethod::Frenet => {
            *frames = frenet(curve.expect("Frenet frames come with a fit"), params, t)
        }
    };
    // The ring spacing, once (also the arc length's steps below).
    seg.extend(x.windows(2).map(|w| (w[1] - w[0]).length()));
    // Discrete curvature between consecutive rings (turn over spacing): a ring may not be wider
    // than this allows either, or the inner side of the bend folds between two rings.
    let local = o.radius_mode == RadiusMode::Local;
    kd.extend((0..seg.len()).map(|i| turn_curvature(t[i].dot(t[i + 1]), seg[i], o.radius, local)));
    // The curvature each ring's radius allows, then the radius.
    radii.extend((0..x.len()).map(|i| {
        let a = if i > 0 { kd[i - 1] } else { 0.0 };
        let b = kd.get(i).copied().unwrap_or(0.0);
        k[i].max(a).max(b)
    }));
    let kmax = radii.iter().cloned().fold(0.0, f64::max);
    for r in radii.iter_mut() {
        let limit = match o.radius_mode {
            RadiusMode::Local => 0.9 / r.max(1e-300),
            RadiusMode::Global => 0.9 / kmax.max(1e-300),
        };
        *r = o.radius.min(limit);
    }
    // Where even 1/1000 of the radius would fold (the apex of a near-reversal, whose fitted
    // curve turns within a hair's breadth), the tube is cut instead: rings there are left out
    // and the pieces on either side end there (with caps when asked for).
    let floor = 1e-3 * o.radius;
    cut.extend(radii.iter().map(|&r| r < floor));
    // Arc length for dr/ds.
    s.push(0.0);
    for &d in seg.iter() {
        s.push(s.last().unwrap() + d);
    }
    // Limit the radius' slope to |dr/ds| <= 1: a clamp then narrows the tube as a cone of at
    // most 45 degrees instead of a step, which keeps the quads next to it facing outwards.
    for i in 1..radii.len() {
        radii[i] = radii[i].min(radii[i - 1] + (s[i] - s[i - 1]));
    }
    for i in (0..radii.len().saturating_sub(1)).rev() {
        radii[i] = radii[i].min(radii[i + 1] + (s[i + 1] - s[i]));
    }
    st.radius_clamps = radii.iter().filter(|&&r| r < o.radius).count();
    let n = x.len();
    // Scalar colour along the curve: interpolate the attribute at ring parameters.
    let attr_at = |u: f64| -> f64 {
        let Some((vals, _)) = attr else { return 0.0 };
        let p = sample_params;
        let j = p.partition_point(|&q| q < u).min(p.len() - 1);
        if j == 0 {
            vals[0] as f64
        } else {
            let (a, b) = (p[j - 1], p[j]);
            let w = if b > a { (u - a) / (b - a) } else { 0.0 };
            let (va, vb) = (vals[j - 1] as f64, vals[j] as f64);
            // A NaN (or infinite) value holds no value: it colours its own point's ring only
            // (the map's lowest colour), not the rings between it and its neighbours, which
            // take the neighbour's value (it darkened about a ring spacing either side).
            match (va.is_finite(), vb.is_finite()) {
                (true, true) => va * (1.0 - w) + vb * w,
                (true, false) if w < 1.0 => va,
                (false, true) if w > 0.0 => vb,
                _ if w >= 1.0 => vb,
                _ => va,
            }
        }
    };
    let r0 = out.rings.len();
    out.rings.reserve(n);
    let mut min_twist_cos = 1.0f64;
    for i in 0..n {
        let r_vec = frames[i];
        let drds = if n > 1 {
            let (a, b) = (i.saturating_sub(1), (i + 1).min(n - 1));
            if s[b] > s[a] {
                (radii[b] - radii[a]) / (s[b] - s[a])
            } else {
                0.0
            }
        } else {
            0.0
        };
        let color = match &o.color {
            ColorMode::Direction => [
                t[i].x.abs() as f32,
                t[i].y.abs() as f32,
                t[i].z.abs() as f32,
            ],
            ColorMode::Constant(c) => *c,
            ColorMode::Scalar(_, map) => {
                let [lo, hi] = attr.map(|a| a.1).unwrap_or([0.0, 1.0]);
                map_color(*map, (attr_at(params[i]) - lo) / (hi - lo).max(1e-300))
            }
            ColorMode::Field(func, [lo, hi], map) => {
                map_color(*map, (func(x[i]) - lo) / (hi - lo).max(1e-300))
            }
        };
        out.rings.push(Ring {
            centre: x[i] - origin,
            r: r_vec.as_vec3(),
            b: t[i].cross(r_vec).as_vec3(),
            t: t[i].as_vec3(),
            radius: radii[i],
            drds,
            color: rgb8(color),
            cut: cut[i],
            start: i == 0,
        });
        if i > 0 && !cut[i] && !cut[i - 1] {
            min_twist_cos = min_twist_cos.min(twist_cos(t[i - 1], t[i], frames[i - 1], frames[i]));
        }
    }
    st.max_twist_deg = min_twist_cos.acos().to_degrees();
    // Runs of rings between cuts: one tube piece each.
    let mut i = 0;
    while i < n {
        if cut[i] {
            i += 1;
            continue;
        }
        let start = i;
        while i + 1 < n && !cut[i + 1] {
            i += 1;
        }
        runs.push((start, i));
        i += 1;
    }
    st.splits += runs.len().saturating_sub(1);
    let kept = cut.iter().filter(|&&c| !c).count();
    let quads: usize = runs.iter().map(|&(a, b)| b - a).sum();
    let caps = if o.caps {
        let c0 = out.caps.len();
        out.caps.extend(
            runs.iter()
                .filter(|&&(a, b)| a != b)
                .map(|&(a, b)| (r0 + a, r0 + b)),
        );
        out.caps.len() - c0
    } else {
        0
    };
    let (vertices, indices) = (
        kept * sides + caps * 2 * (sides + 1),
        quads * sides * 6 + caps * 2 * sides * 3,
    );
    st.triangles = indices / 3;
    out.vertices += vertices;
    out.indices += indices;
    out.pieces += 1;
    let all = &mut out.stats;
    all.control_points += st.control_points;
    all.triangles += st.triangles;
    all.max_deviation = all.max_deviation.max(st.max_deviation);
    all.max_twist_deg = all.max_twist_deg.max(st.max_twist_deg);
    all.radius_clamps += st.radius_clamps;
    all.splits += st.splits;
    all.polyline_pieces += st.polyline_pieces;
    SCRATCH.set(scratch);
    true
}

/// The sides of the tubes' polygons.
fn ring_sides(o: &TubeOptions) -> usize {
    match o.chordal {
        Some(tol) => sides_for(o.radius, tol),
        None => o.sides.max(3),
    }
}

/// Builds the tube mesh of all streamlines (in parallel) and its statistics.
pub fn build(s: &Streamlines, o: &TubeOptions) -> (TubeMesh, TubeStats) {
    prepare(s, o).emit(o)
}

/// [`build`] taking the streamlines: their points are freed once every tube's rings are
/// known, before the mesh buffers are allocated, so the points and the mesh are never held
/// together (the peak is the rings and the mesh).
pub fn build_owned(s: Streamlines, o: &TubeOptions) -> (TubeMesh, TubeStats) {
    let p = prepare(&s, o);
    drop(s);
    p.emit(o)
}

/// Every tube piece's rings, by blocks of streamlines, and the statistics so far: what
/// [`Prepared::emit`] writes.
struct Prepared {
    origin: DVec3,
    blocks: Vec<Block>,
    stats: TubeStats,
}

/// Streamlines whose rings make one [`Block`]: about ten rings of 80 bytes a streamline, so a
/// whole block is one allocation of some 50 MB, which the allocator maps on its own (glibc's
/// mmap threshold is at most 32 MB) and gives back to the system as soon as the block has been
/// written into the mesh: the rings and the mesh are never all resident together.
const BLOCK_STREAMLINES: usize = 1 << 16;

/// Streamlines meshed in parallel at once, within a block.
const BATCH_STREAMLINES: usize = 1 << 12;

/// The rings of the tube pieces of a block of streamlines, in one allocation, and each piece's
/// part of them.
struct Block {
    rings: Vec<Ring>,
    caps: Vec<(usize, usize)>,
    pieces: Vec<Piece>,
}

/// A tube piece in its [`Block`]: its polygons' sides, the ranges of its rings and caps, and
/// what it writes.
struct Piece {
    sides: usize,
    rings: std::ops::Range<usize>,
    caps: std::ops::Range<usize>,
    vertices: usize,
    indices: usize,
}

impl Block {
    /// Appends a batch's pieces: their rings are copied into the block's allocation by the
    /// workers, each piece into its own part (copied on the calling thread, with the first
    /// touches of the block's fresh pages, they had been a third of the preparation of the
    /// HCP1065 bundles, the other core idle), and the pieces' own buffers are freed by the
    /// workers too.
    fn append(&mut self, batch: Vec<Rings>) {
        let add: usize = batch.iter().map(|p| p.rings.len()).sum();
        let r0 = self.rings.len();
        self.rings.reserve(add);
        let mut spare = &mut self.rings.spare_capacity_mut()[..add];
        let mut at = r0;
        let mut jobs = Vec::with_capacity(batch.len());
        for p in batch {
            let (part, rest) = std::mem::take(&mut spare).split_at_mut(p.rings.len());
            spare = rest;
            let c0 = self.caps.len();
            self.caps.extend_from_slice(&p.caps);
            self.pieces.push(Piece {
                sides: p.sides,
                rings: at..at + p.rings.len(),
                caps: c0..self.caps.len(),
                vertices: p.vertices,
                indices: p.indices,
            });
            at += p.rings.len();
            jobs.push((part, p.rings));
        }
        jobs.into_par_iter()
            .with_min_len(16)
            .for_each(|(part, rings)| {
                for (d, r) in part.iter_mut().zip(rings) {
                    d.write(r);
                }
            });
        // SAFETY: the parts cover the `add` reserved elements after `r0` exactly (split by
        // the pieces' ring counts), and every element of every part was written above.
        unsafe { self.rings.set_len(r0 + add) };
    }
}

/// The first half of [`build`]: cleans, splits and fits every streamline (in parallel) into
/// the rings of its tube pieces.
fn prepare(s: &Streamlines, o: &TubeOptions) -> Prepared {
    let origin = s
        .bounds()
        .map(|[lo, hi]| ((lo + hi) * 0.5).as_dvec3())
        .unwrap_or(DVec3::ZERO);
    let scalar = match &o.color {
        ColorMode::Scalar(name, _) => s.point_attributes.iter().find(|a| &a.name == name),
        _ => None,
    };
    let range = scalar.map(|a| {
        let v = a
            .values
            .iter()
            .step_by(a.components)
            .filter(|v| v.is_finite());
        let (lo, hi) = v.fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &x| {
            (l.min(x as f64), h.max(x as f64))
        });
        [lo, hi]
    });
    let piece_of = |i: usize| {
        let mut st = TubeStats {
            streamlines_in: 1,
            points_in: s.line(i).len(),
            min_section_ratio: f64::INFINITY,
            ..Default::default()
        };
        let line = s.line(i);
        let vals: Option<Vec<f32>> = scalar.map(|a| {
            (s.offsets[i]..s.offsets[i + 1])
                .map(|p| a.values[p * a.components])
                .collect()
        });
        // Clean as `clean` does, keeping attribute values aligned with the kept points.
        let mut pts: Vec<DVec3> = Vec::with_capacity(line.len());
        let mut kept_vals = Vec::new();
        for (j, p) in line.iter().enumerate() {
            let p = p.as_dvec3();
            let dup = pts
                .last()
                .is_some_and(|q: &DVec3| (p - *q).length() <= 1e-9 * (1.0 + p.abs().max_element()));
            if p.is_finite() && !dup {
                pts.push(p);
                if let Some(v) = &vals {
                    kept_vals.push(v[j]);
                }
            }
        }
        debug_assert_eq!(
            pts,
            clean(&line.iter().map(|p| p.as_dvec3()).collect::<Vec<_>>()).0
        );
        st.dropped_points = line.len() - pts.len();
        let (keep, dev) = drop_kinks(&pts, o.fit.epsilon);
        if keep.len() < pts.len() {
            st.kinks = pts.len() - keep.len();
            st.max_deviation = dev;
            pts = keep.iter().map(|&k| pts[k]).collect();
            if vals.is_some() {
                kept_vals = keep.iter().map(|&k| kept_vals[k]).collect();
            }
        }
        if pts.len() < 2 {
            st.skipped_streamlines = 1;
            return (Rings::new(0), st);
        }
        // (first, last, whether the part is of a line too rough to fit)
        let mut parts: Vec<(usize, usize, bool)> = reversal_ranges(&pts)
            .into_iter()
            .map(|(a, b)| (a, b, false))
            .collect();
        // A line that will be meshed as its polyline is also split where it turns sharply
        // (its rings would fold there; the fit's refinement is what a smooth line gets), and
        // its parts are meshed as polylines too, however short (parts under eight points, which
        // `too_rough` does not judge, were fitted one by one: on 20,000 lines of 1 mm steps
        // jittered by 0.3 mm, 60,000 fits that gave no fewer rings and took 47% of the
        // meshing time; docs/benchmarks.md).
        let polyline_eligible = o.frame == FrameMethod::Rmf && o.fit.method == FitMethod::Iterative;
        if polyline_eligible {
            parts = parts
                .into_iter()
                .flat_map(|(a, b, _)| {
                    if too_rough(&pts[a..=b], o.fit.epsilon) {
                        sharp_ranges(&pts, a, b)
                            .into_iter()
                            .map(|(c, d)| (c, d, true))
                            .collect()
                    } else {
                        vec![(a, b, false)]
                    }
                })
                .collect();
        }
        st.splits = parts.len() - 1;
        let mut out = Rings::new(ring_sides(o));
        for &(a, b, rough) in &parts {
            if b == a {
                continue;
            }
            let av = vals.as_ref().map(|_| &kept_vals[a..=b]);
            // A rough part lies between sharp turns: meshed as its polyline, unfitted.
            if tube_as(
                &pts[a..=b],
                av.zip(range),
                o,
                origin,
                rough,
                rough,
                &mut out,
            ) {
                continue;
            }
            // More rings than points from the fit, and a sharp turn: the parts between the
            // turns (sharing the points of the turns), none of which turns sharply.
            let turns = sharp_ranges(&pts, a, b);
            st.splits += turns.len() - 1;
            for (c, d) in turns {
                if d == c {
                    continue;
                }
                let av = vals.as_ref().map(|_| &kept_vals[c..=d]);
                tube(&pts[c..=d], av.zip(range), o, origin, true, &mut out);
            }
        }
        (out, st)
    };
    let mut stats = TubeStats {
        min_section_ratio: f64::INFINITY,
        ..Default::default()
    };
    let mut blocks = Vec::new();
    for start in (0..s.len()).step_by(BLOCK_STREAMLINES) {
        let end = (start + BLOCK_STREAMLINES).min(s.len());
        let mut block = Block {
            rings: Vec::new(),
            caps: Vec::new(),
            pieces: Vec::new(),
        };
        // The pieces of a block are made a batch at a time: each piece's own buffers (freed
        // once copied into the block) stay a few MB, not a block's worth, in the allocator's
        // heap (which keeps what it held).
        for batch in (start..end).step_by(BATCH_STREAMLINES) {
            let pieces: Vec<(Rings, TubeStats)> = (batch..(batch + BATCH_STREAMLINES).min(end))
                .into_par_iter()
                .map(piece_of)
                .collect();
            let mut batch_pieces = Vec::new();
            for (parts, st) in pieces {
                stats.streamlines_in += st.streamlines_in;
                stats.points_in += st.points_in;
                stats.dropped_points += st.dropped_points;
                stats.kinks += st.kinks;
                stats.max_deviation = stats.max_deviation.max(st.max_deviation);
                stats.skipped_streamlines += st.skipped_streamlines;
                stats.splits += st.splits;
                // (One `Rings` a streamline, holding its pieces, or none.)
                if let Some(p) = Some(parts).filter(|p| p.pieces > 0) {
                    stats.streamlines_out += p.pieces + p.stats.splits;
                    stats.control_points += p.stats.control_points;
                    stats.triangles += p.stats.triangles;
                    stats.max_deviation = stats.max_deviation.max(p.stats.max_deviation);
                    stats.max_twist_deg = stats.max_twist_deg.max(p.stats.max_twist_deg);
                    stats.radius_clamps += p.stats.radius_clamps;
                    stats.splits += p.stats.splits;
                    stats.polyline_pieces += p.stats.polyline_pieces;
                    batch_pieces.push(p);
                }
            }
            block.append(batch_pieces);
        }
        blocks.push(block);
    }
    Prepared {
        origin,
        blocks,
        stats,
    }
}

impl Prepared {
    /// The second half of [`build`]: the mesh buffers, allocated once, every piece written
    /// straight into them.
    fn emit(self, o: &TubeOptions) -> (TubeMesh, TubeStats) {
        let Prepared {
            origin,
            blocks,
            mut stats,
        } = self;
        let mut mesh = TubeMesh {
            origin,
            radius: o.radius,
            ..Default::default()
        };
        // Write every piece straight into the mesh buffers, in parallel: each piece gets its own
        // disjoint parts of the (uninitialised) buffers, found by prefix sums of its counts;
        // block by block, each block's rings freed once written.
        let nv: usize = blocks
            .iter()
            .flat_map(|b| &b.pieces)
            .map(|p| p.vertices)
            .sum();
        let ni: usize = blocks
            .iter()
            .flat_map(|b| &b.pieces)
            .map(|p| p.indices)
            .sum();
        assert!(
            nv <= u32::MAX as usize,
            "{nv} vertices do not fit 32-bit indices"
        );
        let mut positions: Vec<Vec3> = Vec::with_capacity(nv);
        let mut normals: Vec<Vec3> = Vec::with_capacity(nv);
        let mut colors: Vec<[u8; 3]> = Vec::with_capacity(nv);
        let mut indices: Vec<u32> = Vec::with_capacity(ni);
        volume::memory::advise_huge(positions.spare_capacity_mut());
        volume::memory::advise_huge(normals.spare_capacity_mut());
        volume::memory::advise_huge(colors.spare_capacity_mut());
        volume::memory::advise_huge(indices.spare_capacity_mut());
        stats.min_section_ratio = f64::INFINITY;
        {
            let (mut pos, mut nor, mut col, mut idx) = (
                &mut positions.spare_capacity_mut()[..nv],
                &mut normals.spare_capacity_mut()[..nv],
                &mut colors.spare_capacity_mut()[..nv],
                &mut indices.spare_capacity_mut()[..ni],
            );
            let mut first = 0u32;
            for block in blocks {
                let (v, i) = block.counts();
                let (a, rest) = std::mem::take(&mut pos).split_at_mut(v);
                pos = rest;
                let (b, rest) = std::mem::take(&mut nor).split_at_mut(v);
                nor = rest;
                let (c, rest) = std::mem::take(&mut col).split_at_mut(v);
                col = rest;
                let (d, rest) = std::mem::take(&mut idx).split_at_mut(i);
                idx = rest;
                let ratio = block.emit_into(&block.pieces, first, a, b, c, d);
                stats.min_section_ratio = stats.min_section_ratio.min(ratio);
                first += v as u32;
            }
        }
        // SAFETY: the pieces cover 0..nv and 0..ni exactly (the slices above are split by their
        // counts), and `emit` writes every element of its slices (it asserts its counts).
        unsafe {
            positions.set_len(nv);
            normals.set_len(nv);
            colors.set_len(nv);
            indices.set_len(ni);
        }
        mesh.positions = positions;
        mesh.normals = normals;
        mesh.colors = colors;
        mesh.indices = indices;
        if !stats.min_section_ratio.is_finite() {
            stats.min_section_ratio = 1.0;
        }
        (mesh, stats)
    }
}

impl Block {
    /// The vertices and indices the block's pieces write.
    fn counts(&self) -> (usize, usize) {
        self.pieces
            .iter()
            .fold((0, 0), |(v, i), p| (v + p.vertices, i + p.indices))
    }

    /// Writes `pieces` (the block's, or a run of them) into `pos`, `nor`, `col` (their
    /// vertices) and `idx` (their indices, vertex numbers from `first`), exactly as long as
    /// their counts, the pieces in parallel; the smallest section ratio.
    fn emit_into(
        &self,
        pieces: &[Piece],
        mut first: u32,
        mut pos: &mut [std::mem::MaybeUninit<Vec3>],
        mut nor: &mut [std::mem::MaybeUninit<Vec3>],
        mut col: &mut [std::mem::MaybeUninit<[u8; 3]>],
        mut idx: &mut [std::mem::MaybeUninit<u32>],
    ) -> f64 {
        let mut jobs = Vec::with_capacity(pieces.len());
        for p in pieces {
            let (a, rest) = std::mem::take(&mut pos).split_at_mut(p.vertices);
            pos = rest;
            let (b, rest) = std::mem::take(&mut nor).split_at_mut(p.vertices);
            nor = rest;
            let (c, rest) = std::mem::take(&mut col).split_at_mut(p.vertices);
            col = rest;
            let (d, rest) = std::mem::take(&mut idx).split_at_mut(p.indices);
            idx = rest;
            jobs.push((p, first, a, b, c, d));
            first += p.vertices as u32;
        }
        let trig = ring_trig(pieces.first().map_or(3, |p| p.sides));
        jobs.into_par_iter()
            .map(|(p, first, a, b, c, d)| {
                emit(
                    p.sides,
                    &trig,
                    &self.rings[p.rings.clone()],
                    &self.caps[p.caps.clone()],
                    (p.vertices, p.indices),
                    first,
                    a,
                    b,
                    c,
                    d,
                )
            })
            .reduce(|| f64::INFINITY, f64::min)
    }
}

/// A block's pieces in runs `(first, end, vertices, indices)` of at most `part_vertices`
/// vertices (one piece at least, however large), in order.
fn mesh_parts(pieces: &[Piece], part_vertices: usize) -> Vec<(usize, usize, usize, usize)> {
    let mut out = Vec::new();
    let mut at = 0;
    while at < pieces.len() {
        let (mut end, mut v, mut i) = (at, 0usize, 0usize);
        while end < pieces.len() && (end == at || v + pieces[end].vertices <= part_vertices) {
            v += pieces[end].vertices;
            i += pieces[end].indices;
            end += 1;
        }
        out.push((at, end, v, i));
        at = end;
    }
    out
}

/// Vertices of a part [`build_streamed`] hands its sink at once (pieces are not split, so a
/// part of a single huge tube may be larger): 128 K vertices, 3.5 MB, and their 256 K
/// triangles' indices, 3 MB - a part stays in the caches from its meshing to its writing (1 M
/// vertices took 5% longer to mesh, docs/benchmarks.md).
pub const PART_VERTICES: usize = 1 << 17;

/// The smallest part [`build_streamed`] cuts a small mesh into (32 K vertices, 0.9 MB).
pub const MIN_PART_VERTICES: usize = 1 << 15;

/// Vertices a part of a mesh of `vertices` vertices: [`PART_VERTICES`], but a quarter of a
/// mesh smaller than four such parts, and never below [`MIN_PART_VERTICES`]. A small mesh is
/// meshed into memory the process has never touched, whose first touches (page faults and the
/// kernel's clearing) then cost as much as the meshing: DIPY's tracks300 (115 K vertices)
/// took 4.4-8.1 ms of compute in one part and 3.6-6.6 ms in four (docs/benchmarks.md).
/// Larger meshes keep the large parts: parts of 32 K vertices made the HCP1065 CST_L
/// bundle's mesh 1.15x slower (fork-joins and writes per part).
pub fn part_vertices_for(vertices: usize) -> usize {
    (vertices / 4).clamp(MIN_PART_VERTICES, PART_VERTICES)
}

/// A part of a mesh that [`build_streamed`] hands its sink: the vertices and triangles of a
/// run of tube pieces, the indices numbering the whole mesh's vertices.
pub struct MeshPart<'a> {
    /// The part's first vertex and first index in the whole mesh.
    pub first_vertex: usize,
    pub first_index: usize,
    pub positions: &'a [Vec3],
    pub normals: &'a [Vec3],
    pub colors: &'a [[u8; 3]],
    pub indices: &'a [u32],
}

/// Where [`build_streamed`] sends a mesh: its origin and size first (with the statistics of
/// the fit: a sink may refuse an empty mesh before anything is written), then its parts in
/// order.
pub trait MeshSink {
    fn begin(
        &mut self,
        origin: DVec3,
        vertices: usize,
        indices: usize,
        stats: &TubeStats,
    ) -> crate::Result<()>;
    fn part(&mut self, part: &MeshPart<'_>) -> crate::Result<()>;
}

/// [`build_owned`] without the mesh held whole: every tube's rings are found first (the
/// points then freed), the mesh's size goes to `sink`, then runs of tubes of at most
/// [`PART_VERTICES`] vertices are meshed into buffers reused from run to run and handed to
/// `sink`. The peak is the rings and one run's mesh instead of the whole mesh, and fresh
/// memory is touched for one run instead of for every triangle (first touches of fresh pages
/// were a third of a whole-mesh build's profile on 10^5 streamlines). The parts, put
/// together, are [`build_owned`]'s mesh. Returns the statistics and the vertex count.
pub fn build_streamed(
    s: Streamlines,
    o: &TubeOptions,
    sink: &mut dyn MeshSink,
) -> crate::Result<(TubeStats, usize)> {
    build_streamed_by(s, o, sink, part_vertices_for)
}

/// [`build_streamed`] in parts of at most `part_vertices(the mesh's vertices)` vertices (tests
/// cut small meshes into many parts).
pub(crate) fn build_streamed_by(
    s: Streamlines,
    o: &TubeOptions,
    sink: &mut dyn MeshSink,
    part_vertices: fn(usize) -> usize,
) -> crate::Result<(TubeStats, usize)> {
    let Prepared {
        origin,
        blocks,
        mut stats,
    } = prepare(&s, o);
    drop(s);
    let (nv, ni) = blocks.iter().fold((0, 0), |(v, i), b| {
        let (bv, bi) = b.counts();
        (v + bv, i + bi)
    });
    if nv > u32::MAX as usize {
        return Err(crate::TubesError::Invalid(format!(
            "{nv} vertices do not fit 32-bit indices: mesh fewer streamlines"
        )));
    }
    sink.begin(origin, nv, ni, &stats)?;
    stats.min_section_ratio = f64::INFINITY;
    let part_vertices = part_vertices(nv);
    let (mut positions, mut normals, mut colors, mut indices) = (
        Vec::<Vec3>::new(),
        Vec::<Vec3>::new(),
        Vec::<[u8; 3]>::new(),
        Vec::<u32>::new(),
    );
    // The buffers once, at the largest part's size: reserved part by part, a part larger
    // than the one before grew them by `realloc`, which copied the previous part's contents
    // (already sent) - 17% of a single-threaded mesh of the HCP1065 CST_L bundle
    // (docs/benchmarks.md).
    let parts: Vec<Vec<(usize, usize, usize, usize)>> = blocks
        .iter()
        .map(|b| mesh_parts(&b.pieces, part_vertices))
        .collect();
    let (most_v, most_i) = parts
        .iter()
        .flatten()
        .fold((0, 0), |(a, b), p| (a.max(p.2), b.max(p.3)));
    positions.reserve_exact(most_v);
    normals.reserve_exact(most_v);
    colors.reserve_exact(most_v);
    indices.reserve_exact(most_i);
    let (mut first_vertex, mut first_index) = (0usize, 0usize);
    for (block, parts) in blocks.into_iter().zip(parts) {
        for (at, end, v, i) in parts {
            positions.clear();
            normals.clear();
            colors.clear();
            indices.clear();
            let ratio = block.emit_into(
                &block.pieces[at..end],
                first_vertex as u32,
                &mut positions.spare_capacity_mut()[..v],
                &mut normals.spare_capacity_mut()[..v],
                &mut colors.spare_capacity_mut()[..v],
                &mut indices.spare_capacity_mut()[..i],
            );
            // SAFETY: `emit_into` writes every element of the slices it is given (each
            // piece's `emit` asserts its counts, and the slices are the run's counts).
            unsafe {
                positions.set_len(v);
                normals.set_len(v);
                colors.set_len(v);
                indices.set_len(i);
            }
            stats.min_section_ratio = stats.min_section_ratio.min(ratio);
            sink.part(&MeshPart {
                first_vertex,
                first_index,
                positions: &positions,
                normals: &normals,
                colors: &colors,
                indices: &indices,
            })?;
            first_vertex += v;
            first_index += i;
        }
    }
    if !stats.min_section_ratio.is_finite() {
        stats.min_section_ratio = 1.0;
    }
    Ok((stats, nv))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A straight piece whose fitted curve all but stops at its ends (four points 0.5, 1.0,
    /// 0.5 apart between two hair-length reversals of an HCP1065 CST_L streamline) keeps the
    /// full radius: the analytic curvature there is the parameterisation's, not a turn (its
    /// rings were 0.006 of the radius, a thread in the render).
    #[test]
    fn a_straight_piece_keeps_its_radius_where_its_curve_slows() {
        let pts = [
            [-80.59375, -104.4375, 5.78125],
            [-80.75, -104.125, 6.15625],
            [-81.09375, -103.5, 6.84375],
            [-81.25, -103.1875, 7.21875],
        ];
        let mut s = Streamlines::new();
        s.push(&pts.map(|p| Vec3::new(p[0], p[1], p[2])));
        let mut o = TubeOptions::defaults(0.5, 8, 0.02);
        o.caps = false;
        let (mesh, st) = build(&s, &o);
        assert_eq!(st.radius_clamps, 0, "{st:?}");
        // Every vertex half a unit from the line (nearly straight: within 0.03).
        let (a, b) = (
            DVec3::from(pts[0].map(|v| v as f64)),
            DVec3::from(pts[3].map(|v| v as f64)),
        );
        let axis = (b - a).normalize();
        for p in &mesh.positions {
            let q = p.as_dvec3() + mesh.origin - a;
            let r = (q - axis * q.dot(axis)).length();
            assert!((r - 0.5).abs() < 0.03, "a vertex {r} from the line");
        }
    }

    /// The kink rule of [`too_rough`] and its premise: one point of a straight line or a helix
    /// moved off it by 4.5 to 20 tolerances (fourth difference 27 to 120 tolerances) keeps
    /// every point in the fit, and the rule sees it; smooth circles and helices whose fit
    /// shortens them are never called kinked (tolerance 0.02, as `umbra tubes`' default).
    #[test]
    fn a_kink_that_keeps_every_point_in_the_fit_is_rough_and_smooth_fits_are_not() {
        let tol = 0.02;
        let o = FitOptions {
            epsilon: tol,
            method: FitMethod::Iterative,
            max_iterations: 100,
        };
        let helix = |r: f64, pitch: f64, step: f64, n: usize| -> Vec<DVec3> {
            let k = step / (r * r + (pitch / std::f64::consts::TAU).powi(2)).sqrt();
            (0..n)
                .map(|i| {
                    let a = k * i as f64;
                    DVec3::new(r * a.cos(), r * a.sin(), pitch * a / std::f64::consts::TAU)
                })
                .collect()
        };
        let straight: Vec<DVec3> = (0..60)
            .map(|i| DVec3::new(0.5 * i as f64, 0.0, 0.0))
            .collect();
        for base in [straight, helix(10.0, 4.0, 0.5, 60)] {
            assert!(!too_rough(&base, tol));
            let fb = fit(&base, &o);
            assert!(
                fb.curve.control.len() < base.len(),
                "{} {}",
                fb.curve.control.len(),
                fb.max_deviation
            );
            for h in [4.5, 6.0, 10.0, 20.0] {
                for at in [3, 30, 56] {
                    let mut line = base.clone();
                    line[at] += DVec3::new(0.0, 0.6, 0.8) * (h * tol);
                    let f = fit(&line, &o);
                    assert_eq!(f.curve.control.len(), line.len(), "kink {h} at {at}");
                    assert!(too_rough(&line, tol), "kink {h} at {at}");
                }
            }
        }
        // Circles and helices from 0.3 to 70 in radius sampled 0.05 to 1.5 apart: the fourth
        // differences of those the fit shortens stay below 1.1 tolerances.
        let mut shortened = 0;
        for ri in 0..40 {
            for si in 0..30 {
                for pitch in [0.0, 4.0] {
                    let (r, step) = (0.3 * 1.15f64.powi(ri), 0.05 * 1.12f64.powi(si));
                    let line = helix(r, pitch, step, 80);
                    if fit(&line, &o).curve.control.len() < line.len() {
                        shortened += 1;
                        assert!(!kinked(&line, tol), "r {r} step {step} pitch {pitch}");
                    }
                }
            }
        }
        assert!(shortened >= 500, "{shortened} smooth lines shortened");
    }

    /// Small meshes are cut into four parts of at least [`MIN_PART_VERTICES`], large ones into
    /// parts of [`PART_VERTICES`].
    #[test]
    fn parts_follow_the_size_of_the_mesh() {
        assert_eq!(part_vertices_for(0), MIN_PART_VERTICES);
        // DIPY's tracks300 at radius 0.2, 8 sides: 115,304 vertices, four parts.
        assert_eq!(part_vertices_for(115_304), MIN_PART_VERTICES);
        assert_eq!(115_304usize.div_ceil(part_vertices_for(115_304)), 4);
        assert_eq!(part_vertices_for(400_000), 100_000);
        assert_eq!(part_vertices_for(4 * PART_VERTICES), PART_VERTICES);
        assert_eq!(part_vertices_for(usize::MAX), PART_VERTICES);
    }

    /// [`rmf`] as it was before the carried corrections: every step's vector corrected before
    /// the next reflection.
    fn rmf_corrected_each_step(x: &[DVec3], t: &[DVec3]) -> Vec<DVec3> {
        let mut r = vec![any_perpendicular(t[0])];
        for i in 0..x.len() - 1 {
            let v1 = x[i + 1] - x[i];
            let c1 = v1.dot(v1);
            let ri = r[i];
            let (a0, a1) = (v1.dot(t[i]), v1.dot(t[i + 1]));
            if !(a0 > 0.0 && a1 > 0.0 && 4.0 * a0 * a0 > 3.0 * c1 && 4.0 * a1 * a1 > 3.0 * c1) {
                let next = rotated(t[i], t[i + 1], ri);
                r.push(
                    (next - t[i + 1] * next.dot(t[i + 1]))
                        .try_normalize()
                        .unwrap_or_else(|| any_perpendicular(t[i + 1])),
                );
                continue;
            }
            let (rl, tl) = if c1 > 1e-300 {
                (
                    ri - v1 * (2.0 / c1 * v1.dot(ri)),
                    t[i] - v1 * (2.0 / c1 * v1.dot(t[i])),
                )
            } else {
                (ri, t[i])
            };
            let v2 = t[i + 1] - tl;
            let c2 = v2.dot(v2);
            let next = if c2 > 1e-300 {
                rl - v2 * (2.0 / c2 * v2.dot(rl))
            } else {
                rl
            };
            r.push(
                (next - t[i + 1] * next.dot(t[i + 1]))
                    .try_normalize()
                    .unwrap_or_else(|| any_perpendicular(t[i + 1])),
            );
        }
        r
    }

    /// The frames with the corrections carried every [`RMF_RESYNC`] rings are the frames
    /// corrected at every ring, to 1e-12, on a rough random walk of 50,000 points (a ring at
    /// every point, as on TrackVis tracts) with hairpins and a straight run; each is a unit
    /// vector normal to its tangent.
    #[test]
    fn carried_corrections_keep_the_frames_of_corrections_at_every_ring() {
        let mut seed = 0x2545_f491_4f6c_dd1du64;
        let mut rnd = || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let mut x = vec![DVec3::ZERO];
        let mut d = DVec3::new(1.0, 0.2, 0.1).normalize();
        for i in 1..50_000 {
            d = if i % 5_000 == 0 {
                -d
            } else if (20_000..21_000).contains(&i) {
                d
            } else {
                (d + 0.6 * DVec3::new(rnd(), rnd(), rnd())).normalize()
            };
            x.push(x[i - 1] + d * 0.0625);
        }
        let n = x.len();
        let t: Vec<DVec3> = (0..n)
            .map(|i| (x[(i + 1).min(n - 1)] - x[i.saturating_sub(1)]).normalize_or(DVec3::X))
            .collect();
        // Tangents a little off unit length (rounded to f32): the reflections no longer map
        // one tangent onto the next exactly, and what the carried vector loses is bounded by
        // the corrections it takes every RMF_RESYNC rings.
        let t32: Vec<DVec3> = t
            .iter()
            .map(|v| (v.as_vec3() * 1.000001).as_dvec3())
            .collect();
        let (fast, each) = (rmf(&x, &t32), rmf_corrected_each_step(&x, &t32));
        let worst = (0..n)
            .map(|i| (fast[i] - each[i]).length())
            .fold(0.0, f64::max);
        // Measured: 8.9e-14, and 1.2e-12 without the corrections carried.
        assert!(worst < 4e-13, "{worst:e} with tangents off unit length");
        let (fast, each) = (rmf(&x, &t), rmf_corrected_each_step(&x, &t));
        for i in 0..n {
            assert!((fast[i] - each[i]).length() < 1e-12, "ring {i}");
            assert!((fast[i].length() - 1.0).abs() < 1e-12, "ring {i}");
            assert!(fast[i].dot(t[i]).abs() < 1e-12, "ring {i}");
        }
    }

    #[test]
    fn a_turn_left_out_of_the_curvature_never_limits_the_radius() {
        // Over turns from 0 to 180 degrees and spacings around the radius: the radius limit
        // with the skipped arccosines equals the one with every arccosine (0.9 / curvature,
        // capped at the radius), and turns are skipped where they cannot limit it.
        let radius: f64 = 0.5;
        let mut skipped = 0;
        for ti in 0..=2000 {
            let theta = std::f64::consts::PI * ti as f64 / 2000.0;
            for ds in [1e-3, 0.01, 0.05, 0.1, 0.3, 0.5, 1.0, 2.0] {
                let c = theta.cos();
                let full = radius.min(0.9 / (c.clamp(-1.0, 1.0).acos() / ds).max(1e-300));
                let k = turn_curvature(c, ds, radius, true);
                skipped += usize::from(k == 0.0 && theta > 0.0);
                assert_eq!(
                    radius.min(0.9 / k.max(1e-300)),
                    full,
                    "turn {theta} rad over {ds}"
                );
                // A global radius gets every curvature.
                assert_eq!(turn_curvature(c, ds, radius, false), c.acos() / ds);
            }
        }
        assert!(skipped > 2000, "{skipped} turns skipped");
    }

    /// A hair-length step a little backwards between two points of a straight run (HCP1065's
    /// TR_S_R, streamline 1027, points 92-101 as stored at 1/32 mm): the tangents on either
    /// side hardly differ, the chord between them is 98 degrees from both. The double
    /// reflection there turned the frame by 180 degrees about the tangent (a tube pinched to
    /// its axis, `max_twist_deg` 179); carried by the tangents' rotation it does not roll.
    #[test]
    fn a_hair_length_side_step_does_not_roll_the_tube() {
        let p = [
            [-48.9062, -117.75, 82.3125],
            [-49.0625, -118.0938, 82.6562],
            [-49.2188, -118.4375, 82.9688],
            [-49.375, -118.7812, 83.3125],
            [-49.5312, -119.125, 83.6562],
            [-49.5625, -119.1562, 83.5938],
            [-49.7188, -119.5, 83.875],
            [-49.9062, -119.875, 84.1875],
            [-50.0938, -120.25, 84.4688],
            [-50.2812, -120.625, 84.75],
        ];
        let mut s = Streamlines::new();
        s.push(&p.map(|q| glam::Vec3::from_array(q.map(|v| v as f32))));
        let o = TubeOptions::defaults(0.5, 8, 0.05);
        let (mesh, st) = build(&s, &o);
        assert!(!mesh.indices.is_empty());
        assert!(st.max_twist_deg < 5.0, "{} degrees", st.max_twist_deg);
        // The frames themselves: no ring's frame vector turns by more than the tangents do
        // (here a few degrees) from the one before.
        let x: Vec<DVec3> = p.iter().map(|q| DVec3::from_array(*q)).collect();
        let n = x.len();
        let t: Vec<DVec3> = (0..n)
            .map(|i| (x[(i + 1).min(n - 1)] - x[i.saturating_sub(1)]).normalize())
            .collect();
        let r = rmf(&x, &t);
        for i in 1..n {
            let roll = twist_cos(t[i - 1], t[i], r[i - 1], r[i])
                .acos()
                .to_degrees();
            assert!(roll < 1.0, "ring {i}: {roll} degrees");
        }
    }
}
