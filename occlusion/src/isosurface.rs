//! CPU isosurface renderer: the reference for the GPU ray marcher and the ground truth of the
//! occlusion-sweeping paper's Fig. 3 and 4 (Singh, Yuksel and House, ISVC 2009, section 3).
//!
//! * **Surface.** Rays are marched in world units `t`; positions are tracked in index space
//!   (`p_i = A^-1 (o + t d)`), so anisotropic and flipped grids need nothing special. Steps come
//!   from the swept distance field (trilinear), shortened by one smallest spacing because the
//!   first-order field can overestimate by about a voxel near edges, and never shorter than
//!   0.3 voxel; a hit is where the trilinear interpolant of the classified samples
//!   (`g = f - iso`, or `iso - f` for `--inside below`) turns non-negative, refined by bisection.
//!   So the surface is the input's own trilinear isosurface, not the distance field's. Beyond
//!   the grid is outside, as for the sweeps: an object touching the border closes half a voxel
//!   beyond it.
//! * **Normal.** The gradient of the distance field (central differences of the trilinear
//!   interpolant, half a voxel apart), taken to world space by `A^-T`.
//! * **Swept ambient.** `A(P, N)` of [`volume::occlusion_shading::AmbientModel`] with the eight
//!   visibilities interpolated trilinearly at `P + c h_min N` (the flat-face correction `c`).
//! * **Monte Carlo reference.** From `P + 0.5 h_min N`, `N` rays cosine-weighted about `N`
//!   (hemisphere ambient occlusion, the reference with the geometry term), or uniform over the
//!   sphere (`--uniform`: mean visibility, the reference for scalar AO without the geometry
//!   term), each traced against the same trilinear isosurface; leaving the grid is open sky,
//!   as for the sweeps. The estimate is the visible fraction, with its standard error.
//! * **Camera.** Orbits the world centre of the volume's bounds: azimuth 0 looks along +y,
//!   azimuth 90 along +x, elevation 90 looks down from +z; the distance is in multiples of the
//!   bounding-sphere radius and the vertical field of view just fits that sphere.

use crate::rng::SplitMix64;
use glam::{DMat3, DMat4, DVec3, DVec4};
use rayon::prelude::*;
use volume::occlusion_shading::{sample_octants, AmbientModel};
use volume::occlusion_sweep::OctantFields;

/// The isosurface of a scalar grid with its distance field.
pub struct IsoSurface<'a> {
    pub dims: [usize; 3],
    pub affine: DMat4,
    inv: DMat4,
    inv3: DMat3,
    /// Classified samples: inside where `g >= 0`; NaN counts as outside.
    pub g: Vec<f32>,
    pub sdf: &'a [f32],
    pub h_min: f64,
}

impl<'a> IsoSurface<'a> {
    pub fn new(
        dims: [usize; 3],
        affine: DMat4,
        values: &[f32],
        iso: f32,
        inside_above: bool,
        sdf: &'a [f32],
    ) -> Self {
        let s = if inside_above { 1.0 } else { -1.0 };
        let g = values
            .iter()
            .map(|&v| if v.is_nan() { -1.0 } else { s * (v - iso) })
            .collect();
        let inv = affine.inverse();
        let m = DMat3::from_mat4(affine);
        let h_min = m
            .x_axis
            .length()
            .min(m.y_axis.length())
            .min(m.z_axis.length());
        IsoSurface {
            dims,
            affine,
            inv,
            inv3: DMat3::from_mat4(inv),
            g,
            sdf,
            h_min,
        }
    }

    /// The classified field with the space beyond the grid outside: a virtual sample one voxel
    /// out mirrors the border sample's magnitude with negative sign, so an object touching the
    /// border closes half a voxel beyond it, where the distance sweep puts it.
    fn g_at(&self, p: DVec3) -> f64 {
        let [nx, ny, nz] = self.dims;
        let (x0, y0, z0) = (p.x.floor(), p.y.floor(), p.z.floor());
        let (fx, fy, fz) = (p.x - x0, p.y - y0, p.z - z0);
        let sample = |i: f64, j: f64, k: f64| -> f64 {
            let inside = i >= 0.0
                && j >= 0.0
                && k >= 0.0
                && i <= (nx - 1) as f64
                && j <= (ny - 1) as f64
                && k <= (nz - 1) as f64;
            let (ci, cj, ck) = (
                i.clamp(0.0, (nx - 1) as f64) as usize,
                j.clamp(0.0, (ny - 1) as f64) as usize,
                k.clamp(0.0, (nz - 1) as f64) as usize,
            );
            let v = self.g[ci + nx * (cj + ny * ck)] as f64;
            if inside {
                v
            } else {
                -v.abs().max(1e-6)
            }
        };
        let l = |a: f64, b: f64, t: f64| a + (b - a) * t;
        l(
            l(
                l(sample(x0, y0, z0), sample(x0 + 1.0, y0, z0), fx),
                l(sample(x0, y0 + 1.0, z0), sample(x0 + 1.0, y0 + 1.0, z0), fx),
                fy,
            ),
            l(
                l(sample(x0, y0, z0 + 1.0), sample(x0 + 1.0, y0, z0 + 1.0), fx),
                l(
                    sample(x0, y0 + 1.0, z0 + 1.0),
                    sample(x0 + 1.0, y0 + 1.0, z0 + 1.0),
                    fx,
                ),
                fy,
            ),
            fz,
        )
    }

    fn trilinear(&self, data: &[f32], p: DVec3) -> f64 {
        let [nx, ny, nz] = self.dims;
        let c = |v: f64, n: usize| v.clamp(0.0, (n - 1) as f64);
        let (x, y, z) = (c(p.x, nx), c(p.y, ny), c(p.z, nz));
        let (i0, j0, k0) = (x.floor() as usize, y.floor() as usize, z.floor() as usize);
        let (i1, j1, k1) = (
            (i0 + 1).min(nx - 1),
            (j0 + 1).min(ny - 1),
            (k0 + 1).min(nz - 1),
        );
        let (fx, fy, fz) = (x - i0 as f64, y - j0 as f64, z - k0 as f64);
        let at = |i: usize, j: usize, k: usize| data[i + nx * (j + ny * k)] as f64;
        let l = |a: f64, b: f64, t: f64| a + (b - a) * t;
        l(
            l(
                l(at(i0, j0, k0), at(i1, j0, k0), fx),
                l(at(i0, j1, k0), at(i1, j1, k0), fx),
                fy,
            ),
            l(
                l(at(i0, j0, k1), at(i1, j0, k1), fx),
                l(at(i0, j1, k1), at(i1, j1, k1), fx),
                fy,
            ),
            fz,
        )
    }

    /// Index position of a world point.
    pub fn to_index(&self, w: DVec3) -> DVec3 {
        (self.inv * DVec4::from((w, 1.0))).truncate()
    }

    /// Signed distance (world units) at a world point.
    pub fn distance(&self, w: DVec3) -> f64 {
        self.trilinear(self.sdf, self.to_index(w))
    }

    /// Outward world normal at a world point. On the closure beyond the grid (an object
    /// touching the border is closed half a voxel outside it) the distance field, clamped at the
    /// border, has no gradient across the face - only rounding noise - so the normal there is
    /// the face's own (the sum of the faces' normals at an edge or corner).
    pub fn normal(&self, w: DVec3) -> DVec3 {
        let p = self.to_index(w);
        let side = DVec3::from_array(std::array::from_fn(|a| {
            if p[a] < 0.0 {
                -1.0
            } else if p[a] > (self.dims[a] - 1) as f64 {
                1.0
            } else {
                0.0
            }
        }));
        if side != DVec3::ZERO {
            return (self.inv3.transpose() * side).normalize_or_zero();
        }
        let e = 0.5;
        let grad_i = DVec3::new(
            self.trilinear(self.sdf, p + DVec3::X * e) - self.trilinear(self.sdf, p - DVec3::X * e),
            self.trilinear(self.sdf, p + DVec3::Y * e) - self.trilinear(self.sdf, p - DVec3::Y * e),
            self.trilinear(self.sdf, p + DVec3::Z * e) - self.trilinear(self.sdf, p - DVec3::Z * e),
        );
        (self.inv3.transpose() * grad_i).normalize_or_zero()
    }

    /// First hit of the ray `o + t d` (`d` unit, world) with `t` in `[t_min, t_max]`.
    pub fn trace(&self, o: DVec3, d: DVec3, t_min: f64, t_max: f64) -> Option<f64> {
        let oi = self.to_index(o);
        let di = self.inv3 * d;
        // Slab test against the grid box grown by one voxel (objects touching the border close
        // half a voxel beyond it) in index space.
        let (mut t0, mut t1) = (t_min, t_max);
        for a in 0..3 {
            let (lo, hi) = (-1.0, self.dims[a] as f64);
            if di[a].abs() < 1e-300 {
                if oi[a] < lo || oi[a] > hi {
                    return None;
                }
                continue;
            }
            let (mut ta, mut tb) = ((lo - oi[a]) / di[a], (hi - oi[a]) / di[a]);
            if ta > tb {
                std::mem::swap(&mut ta, &mut tb);
            }
            t0 = t0.max(ta);
            t1 = t1.min(tb);
        }
        if t0 > t1 {
            return None;
        }
        let gi = |t: f64| self.g_at(oi + di * t);
        let mut t = t0;
        let mut prev = t;
        if gi(t) >= 0.0 {
            return Some(t);
        }
        let min_step = 0.3 * self.h_min;
        while t < t1 {
            let dist = self.trilinear(self.sdf, oi + di * t);
            let step = (dist - self.h_min).max(min_step);
            prev = t;
            t = (t + step).min(t1);
            if gi(t) >= 0.0 {
                let (mut a, mut b) = (prev, t);
                for _ in 0..20 {
                    let m = 0.5 * (a + b);
                    if gi(m) >= 0.0 {
                        b = m;
                    } else {
                        a = m;
                    }
                }
                return Some(b);
            }
            if t >= t1 {
                break;
            }
        }
        let _ = prev;
        None
    }

    /// Monte Carlo visibility at a surface point: the fraction of `n` rays (cosine-weighted about
    /// `normal`, or uniform over the sphere) that leave the grid, and its standard error.
    pub fn reference_ao(
        &self,
        p: DVec3,
        normal: DVec3,
        n: usize,
        uniform: bool,
        seed: u64,
    ) -> (f64, f64) {
        let mut rng = SplitMix64(seed);
        let start = p + normal * (0.5 * self.h_min);
        let (t, b) = basis(normal);
        let mut visible = 0usize;
        for _ in 0..n {
            let (u1, u2) = (rng.next_f64(), rng.next_f64());
            let dir = if uniform {
                let z = 1.0 - 2.0 * u1;
                let r = (1.0 - z * z).max(0.0).sqrt();
                let phi = 2.0 * std::f64::consts::PI * u2;
                DVec3::new(r * phi.cos(), r * phi.sin(), z)
            } else {
                let r = u1.sqrt();
                let phi = 2.0 * std::f64::consts::PI * u2;
                let local = DVec3::new(r * phi.cos(), r * phi.sin(), (1.0 - u1).max(0.0).sqrt());
                t * local.x + b * local.y + normal * local.z
            };
            if self.trace(start, dir, 0.0, f64::INFINITY).is_none() {
                visible += 1;
            }
        }
        let a = visible as f64 / n as f64;
        (a, (a * (1.0 - a) / n as f64).sqrt())
    }
}

fn basis(n: DVec3) -> (DVec3, DVec3) {
    let a = if n.x.abs() < 0.9 { DVec3::X } else { DVec3::Y };
    let t = n.cross(a).normalize();
    (t, n.cross(t))
}

/// The orbit camera of `umbra iso`.
#[derive(Clone, Copy, Debug)]
pub struct OrbitCamera {
    pub width: usize,
    pub height: usize,
    pub azimuth_deg: f64,
    pub elevation_deg: f64,
    /// Distance in multiples of the bounding-sphere radius (> 1).
    pub distance: f64,
}

impl Default for OrbitCamera {
    fn default() -> Self {
        OrbitCamera {
            width: 512,
            height: 512,
            azimuth_deg: 30.0,
            elevation_deg: 30.0,
            distance: 3.0,
        }
    }
}

struct Rays {
    eye: DVec3,
    forward: DVec3,
    right: DVec3,
    up: DVec3,
    tan_half: f64,
    aspect: f64,
}

impl OrbitCamera {
    fn rays(&self, bounds: [DVec3; 2]) -> Rays {
        let centre = (bounds[0] + bounds[1]) * 0.5;
        let radius = ((bounds[1] - bounds[0]) * 0.5).length().max(1e-9);
        let (az, el) = (
            self.azimuth_deg.to_radians(),
            self.elevation_deg.to_radians(),
        );
        let forward = DVec3::new(az.sin() * el.cos(), az.cos() * el.cos(), -el.sin()).normalize();
        let k = self.distance.max(1.01);
        let eye = centre - forward * (k * radius);
        let world_up = if forward.cross(DVec3::Z).length() < 1e-6 {
            DVec3::Y
        } else {
            DVec3::Z
        };
        let right = forward.cross(world_up).normalize();
        let up = right.cross(forward);
        let tan_half = (1.0 / k).asin().tan() * 1.05;
        Rays {
            eye,
            forward,
            right,
            up,
            tan_half,
            aspect: self.width as f64 / self.height.max(1) as f64,
        }
    }
}

impl Rays {
    fn dir(&self, x: f64, y: f64, w: usize, h: usize) -> DVec3 {
        let sx = (2.0 * (x + 0.5) / w as f64 - 1.0) * self.tan_half * self.aspect;
        let sy = (1.0 - 2.0 * (y + 0.5) / h as f64) * self.tan_half;
        (self.forward + self.right * sx + self.up * sy).normalize()
    }
}

/// How surface points are shaded.
pub enum AmbientSource<'a> {
    /// No occlusion (local illumination only): `A = 1`.
    None,
    /// The swept octant fields.
    Swept {
        octants: &'a OctantFields,
        model: &'a AmbientModel,
    },
    /// Monte Carlo: rays per pixel, uniform sphere instead of cosine-weighted hemisphere.
    Reference { rays: usize, uniform: bool },
}

/// A rendered image: per pixel the ambient term (NaN where the ray missed), its Monte Carlo
/// standard error (0 for other sources), and the shaded colour (linear, in [0, 1]).
pub struct IsoImage {
    pub width: usize,
    pub height: usize,
    pub ambient: Vec<f32>,
    pub stderr: Vec<f32>,
    pub color: Vec<[f32; 3]>,
}

/// Shading of `umbra iso`: the ambient term alone (grey), or with a Phong head light.
#[derive(Clone, Copy, Debug)]
pub struct Shading {
    pub phong: bool,
    pub background: [f32; 3],
}

impl Default for Shading {
    fn default() -> Self {
        Shading {
            phong: false,
            background: [1.0, 1.0, 1.0],
        }
    }
}

/// The ambient term at a surface point (world position and outward normal).
pub fn ambient_at(
    surface: &IsoSurface,
    source: &AmbientSource,
    p: DVec3,
    n: DVec3,
    seed: u64,
) -> (f64, f64) {
    match source {
        AmbientSource::None => (1.0, 0.0),
        AmbientSource::Swept { octants, model } => {
            let q = p + n * (model.options.offset * surface.h_min);
            (
                model.ambient(&sample_octants(octants, surface.to_index(q)), n),
                0.0,
            )
        }
        AmbientSource::Reference { rays, uniform } => {
            surface.reference_ao(p, n, *rays, *uniform, seed)
        }
    }
}

/// Renders the isosurface seen by `camera`.
pub fn render(
    surface: &IsoSurface,
    bounds: [DVec3; 2],
    camera: &OrbitCamera,
    source: &AmbientSource,
    shading: &Shading,
) -> IsoImage {
    let (w, h) = (camera.width.max(1), camera.height.max(1));
    let rays = camera.rays(bounds);
    let pixels: Vec<(f32, f32, [f32; 3])> = (0..w * h)
        .into_par_iter()
        .map(|px| {
            let (x, y) = ((px % w) as f64, (px / w) as f64);
            let d = rays.dir(x, y, w, h);
            let Some(t) = surface.trace(rays.eye, d, 0.0, f64::INFINITY) else {
                return (f32::NAN, 0.0, shading.background);
            };
            let p = rays.eye + d * t;
            let mut n = surface.normal(p);
            if n == DVec3::ZERO {
                // Degenerate gradient (a corner of the closed border): face the viewer.
                n = -d;
            }
            if n.dot(d) > 0.0 {
                n = -n;
            }
            let seed = (px as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ 0x5DEE_CE66;
            let (a, se) = ambient_at(surface, source, p, n, seed);
            let c = if shading.phong {
                let l = -d;
                let diff = n.dot(l).max(0.0);
                let hv = (l - d).normalize_or_zero();
                let spec = n.dot(hv).max(0.0).powf(40.0);
                (0.55 * a + 0.35 * diff * a.sqrt() + 0.25 * spec).min(1.0)
            } else {
                a
            };
            (a as f32, se as f32, [c as f32; 3])
        })
        .collect();
    IsoImage {
        width: w,
        height: h,
        ambient: pixels.iter().map(|p| p.0).collect(),
        stderr: pixels.iter().map(|p| p.1).collect(),
        color: pixels.iter().map(|p| p.2).collect(),
    }
}

/// Root-mean-square difference of two ambient images over pixels where both hit.
pub fn rmse(a: &IsoImage, b: &IsoImage) -> f64 {
    let (mut s, mut n) = (0.0, 0usize);
    for (x, y) in a.ambient.iter().zip(&b.ambient) {
        if x.is_finite() && y.is_finite() {
            s += ((x - y) as f64).powi(2);
            n += 1;
        }
    }
    if n == 0 {
        f64::NAN
    } else {
        (s / n as f64).sqrt()
    }
}
