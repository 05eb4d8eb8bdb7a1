//! Synthetic scenes with known answers, for the tests and benchmarks of every later stage.
//!
//! * [`Solid`]: analytic signed-distance solids (sphere, axis-aligned box, torus around z, and
//!   unions). Distances are exact for the primitives; a union's `min` is exact outside and,
//!   because the unions built here are of disjoint solids, inside too (inside one solid the
//!   nearest boundary of the union is that solid's own).
//! * [`validation_scene`]: the occlusion-sweeping paper's validation set-up (its Fig. 3: "a
//!   simple 100 x 100 x 100 dataset" of solids; the figure itself is missing from our copy, so
//!   the layout here is ours): a floor slab with a narrow square pit, a sphere resting on the
//!   floor, a box, and a torus lying on the floor. It has the features the occlusion tests need:
//!   a pit, a flat top, contact creases and an overhang.
//! * [`three_solids`]: a sphere, a torus and a box in the unit cube: the distance-accuracy and
//!   performance scene (`n^3` samples).
//! * [`shepp_logan`]: the 3-D Shepp-Logan head phantom in 16-bit integers (memory benchmarks).
//! * [`VectorField`]s with known streamlines: [`RigidRotation`] (circles), [`AbcFlow`]
//!   (Arnold-Beltrami-Childress, a steady Euler solution with chaotic streamlines) and
//!   [`BurgersVortex`] (a tornado-like exact Navier-Stokes vortex with inflow and updraft).
//! * [`UnsteadyField`]s, sampled into a [`VolumeSeries`] by [`sample_series`]: [`DoubleGyre3d`]
//!   (Shadden et al.'s time-periodic double gyre with a roll in the y-z plane) and
//!   [`LinearRamp`] (a uniform flow whose speed grows linearly in time: exact pathlines).
//!
//! Sampled scalar scenes store `-distance` so that the inside has values >= 0, matching the
//! default `--inside above` of `umbra sweep` at iso 0.

use crate::{Field, ScalarType, Space, Volume, VolumeSeries};
use glam::{DMat4, DVec3, DVec4};

/// An analytic solid with an exact signed distance (negative inside), in world units.
#[derive(Clone, Debug, PartialEq)]
pub enum Solid {
    Sphere {
        center: DVec3,
        radius: f64,
    },
    /// Axis-aligned box with half extents `half`.
    Box {
        center: DVec3,
        half: DVec3,
    },
    /// Torus around the z axis through `center`: ring radius `major`, tube radius `minor`.
    Torus {
        center: DVec3,
        major: f64,
        minor: f64,
    },
    /// Union of disjoint solids.
    Union(Vec<Solid>),
}

impl Solid {
    /// Signed distance from `p` to the surface (negative inside).
    pub fn distance(&self, p: DVec3) -> f64 {
        match self {
            Solid::Sphere { center, radius } => (p - *center).length() - radius,
            Solid::Box { center, half } => {
                let q = (p - *center).abs() - *half;
                q.max(DVec3::ZERO).length() + q.max_element().min(0.0)
            }
            Solid::Torus {
                center,
                major,
                minor,
            } => {
                let d = p - *center;
                let ring = (d.x * d.x + d.y * d.y).sqrt() - major;
                (ring * ring + d.z * d.z).sqrt() - minor
            }
            Solid::Union(parts) => parts
                .iter()
                .map(|s| s.distance(p))
                .fold(f64::INFINITY, f64::min),
        }
    }

    /// Outward unit normal at (or near) the surface, from the analytic gradient.
    pub fn normal(&self, p: DVec3) -> DVec3 {
        let h = 1e-6;
        let g = DVec3::new(
            self.distance(p + DVec3::X * h) - self.distance(p - DVec3::X * h),
            self.distance(p + DVec3::Y * h) - self.distance(p - DVec3::Y * h),
            self.distance(p + DVec3::Z * h) - self.distance(p - DVec3::Z * h),
        );
        g.normalize_or_zero()
    }
}

/// An affine for an `n^3` grid whose voxel centres span `[lo, hi]` in each axis.
pub fn cube_affine(n: [usize; 3], lo: f64, hi: f64) -> DMat4 {
    let s = |k: usize| (hi - lo) / (k.max(2) - 1) as f64;
    DMat4::from_cols(
        DVec4::new(s(n[0]), 0.0, 0.0, 0.0),
        DVec4::new(0.0, s(n[1]), 0.0, 0.0),
        DVec4::new(0.0, 0.0, s(n[2]), 0.0),
        DVec4::new(lo, lo, lo, 1.0),
    )
}

/// World positions of the voxel centres, x fastest.
fn grid_points(dims: [usize; 3], affine: DMat4) -> impl Iterator<Item = DVec3> {
    (0..dims[2]).flat_map(move |k| {
        (0..dims[1]).flat_map(move |j| {
            (0..dims[0])
                .map(move |i| (affine * DVec4::new(i as f64, j as f64, k as f64, 1.0)).truncate())
        })
    })
}

/// A synthetic volume holding one float field.
fn synthetic_volume(
    dims: [usize; 3],
    affine: DMat4,
    name: &str,
    components: usize,
    data: Vec<f32>,
) -> Volume {
    Volume {
        format: "synthetic".into(),
        dims,
        affine,
        space: Space::File,
        fields: vec![Field {
            name: name.into(),
            components,
            stored: ScalarType::F32,
            data,
        }],
        default_field: 0,
        warnings: vec![],
    }
}

/// Samples any scalar function of world position on a grid.
pub fn sample_scalar(
    dims: [usize; 3],
    affine: DMat4,
    name: &str,
    f: impl Fn(DVec3) -> f64 + Sync,
) -> Volume {
    let data = grid_points(dims, affine).map(|p| f(p) as f32).collect();
    synthetic_volume(dims, affine, name, 1, data)
}

/// The renderers' test blob: `exp(-|p - c|^2 / width)` around `c = (1.5, 0, 0.5)` on an
/// anisotropic grid (spacing 1, 0.9, 1.2) whose first sample is at `origin` - off-centre and
/// with an empty margin where the grid is large enough.
pub fn gaussian_blob(dims: [usize; 3], origin: DVec3, width: f64) -> Volume {
    let affine = DMat4::from_cols(
        DVec4::new(1.0, 0.0, 0.0, 0.0),
        DVec4::new(0.0, 0.9, 0.0, 0.0),
        DVec4::new(0.0, 0.0, 1.2, 0.0),
        DVec4::from((origin, 1.0)),
    );
    let c = DVec3::new(1.5, 0.0, 0.5);
    sample_scalar(dims, affine, "blob", |p| {
        (-(p - c).length_squared() / width).exp()
    })
}

/// Samples `-distance` of a solid (inside >= 0, iso level 0).
pub fn sample_solid(solid: &Solid, dims: [usize; 3], affine: DMat4) -> Volume {
    sample_scalar(dims, affine, "neg_distance", |p| -solid.distance(p))
}

/// The distance-accuracy scene: a sphere, a torus and a box in `[0, 1]^3`, disjoint.
pub fn three_solids() -> Solid {
    Solid::Union(vec![
        Solid::Sphere {
            center: DVec3::new(0.3, 0.3, 0.3),
            radius: 0.2,
        },
        Solid::Torus {
            center: DVec3::new(0.68, 0.68, 0.3),
            major: 0.17,
            minor: 0.07,
        },
        Solid::Box {
            center: DVec3::new(0.5, 0.55, 0.75),
            half: DVec3::new(0.3, 0.15, 0.12),
        },
    ])
}

/// The solids of the occlusion validation scene in a `[0, 100]^3` world (one unit per voxel on
/// the default 100^3 grid): the floor slab occupies z in [0, 20] with a 6 x 6 x 14 pit centred
/// at (25, 75); on it stand a sphere (r 16 at (30, 30, 36)), a box (70, 30, 34) of half extents
/// (12, 12, 14) and a torus (70, 72, 27) with radii 16 and 7.
///
/// The pit is cut out of the slab, so the slab is four boxes around it (a union of disjoint
/// solids); the sphere, box and torus rest just above the floor (1 unit gap), so every union is
/// of disjoint solids and [`Solid::distance`] stays exact.
pub fn validation_solid() -> Solid {
    let pit = (25.0, 75.0, 3.0); // centre x, centre y, half width
    let (z0, z1) = (0.0, 20.0);
    let zc = (z0 + z1) / 2.0;
    let zh = (z1 - z0) / 2.0;
    let pit_depth = 14.0;
    let floor_parts = vec![
        // x < pit
        Solid::Box {
            center: DVec3::new((pit.0 - pit.2) / 2.0, 50.0, zc),
            half: DVec3::new((pit.0 - pit.2) / 2.0, 50.0, zh),
        },
        // x > pit
        Solid::Box {
            center: DVec3::new((pit.0 + pit.2 + 100.0) / 2.0, 50.0, zc),
            half: DVec3::new((100.0 - pit.0 - pit.2) / 2.0, 50.0, zh),
        },
        // pit column, y < pit
        Solid::Box {
            center: DVec3::new(pit.0, (pit.1 - pit.2) / 2.0, zc),
            half: DVec3::new(pit.2, (pit.1 - pit.2) / 2.0, zh),
        },
        // pit column, y > pit
        Solid::Box {
            center: DVec3::new(pit.0, (pit.1 + pit.2 + 100.0) / 2.0, zc),
            half: DVec3::new(pit.2, (100.0 - pit.1 - pit.2) / 2.0, zh),
        },
        // pit bottom
        Solid::Box {
            center: DVec3::new(pit.0, pit.1, (z1 - pit_depth + z0) / 2.0),
            half: DVec3::new(pit.2, pit.2, (z1 - pit_depth - z0) / 2.0),
        },
    ];
    let mut parts = floor_parts;
    parts.push(Solid::Sphere {
        center: DVec3::new(30.0, 30.0, 37.0),
        radius: 16.0,
    });
    parts.push(Solid::Box {
        center: DVec3::new(70.0, 30.0, 35.0),
        half: DVec3::new(12.0, 12.0, 14.0),
    });
    parts.push(Solid::Torus {
        center: DVec3::new(70.0, 72.0, 28.0),
        major: 16.0,
        minor: 7.0,
    });
    Solid::Union(parts)
}

/// Key points of the validation scene with known occlusion orderings.
pub mod validation_points {
    use glam::DVec3;
    /// Bottom of the narrow pit (on the pit floor, centred).
    pub const PIT_BOTTOM: DVec3 = DVec3::new(25.0, 75.0, 6.0);
    /// Middle of the box's flat top.
    pub const BOX_TOP: DVec3 = DVec3::new(70.0, 30.0, 49.0);
    /// Top and underside of the sphere.
    pub const SPHERE_TOP: DVec3 = DVec3::new(30.0, 30.0, 53.0);
    pub const SPHERE_BOTTOM_SIDE: DVec3 = DVec3::new(
        30.0,
        30.0 - 16.0 * std::f64::consts::FRAC_1_SQRT_2,
        37.0 - 16.0 * std::f64::consts::FRAC_1_SQRT_2,
    );
}

/// The validation scene sampled on an `n^3` grid spanning `[0, 100]^3` (n = 100 in the paper).
pub fn validation_scene(n: usize) -> Volume {
    let n = n.max(2);
    sample_solid(
        &validation_solid(),
        [n, n, n],
        cube_affine([n, n, n], 0.0, 100.0),
    )
}

/// The modified 3-D Shepp-Logan head phantom (Kak & Slaney's ellipsoids with Toft's
/// contrasts, each rotated about z only) on an `n^3` grid spanning `[-1, 1]^3`, stored as
/// `uint16`: each ellipsoid adds its contrast x 1000 (skull 1000, brain 200, ventricles 0,
/// small lesions 300, 100 where a lesion overlaps a ventricle), plus a deterministic integer
/// noise of -8..=8 on every sample that is not 0 (the ventricles and the empty margin stay
/// exactly 0). Integer samples in 16 bits: the stored-type
/// scene of the renderers' memory benchmarks.
pub fn shepp_logan(n: usize) -> Volume {
    // (contrast, semi-axes a b c, centre x y z, rotation about z in degrees)
    const E: [(f64, [f64; 3], [f64; 3], f64); 10] = [
        (1.0, [0.69, 0.92, 0.81], [0.0, 0.0, 0.0], 0.0),
        (-0.8, [0.6624, 0.874, 0.78], [0.0, -0.0184, 0.0], 0.0),
        (-0.2, [0.11, 0.31, 0.22], [0.22, 0.0, 0.0], -18.0),
        (-0.2, [0.16, 0.41, 0.28], [-0.22, 0.0, 0.0], 18.0),
        (0.1, [0.21, 0.25, 0.41], [0.0, 0.35, -0.15], 0.0),
        (0.1, [0.046, 0.046, 0.05], [0.0, 0.1, 0.25], 0.0),
        (0.1, [0.046, 0.046, 0.05], [0.0, -0.1, 0.25], 0.0),
        (0.1, [0.046, 0.023, 0.05], [-0.08, -0.605, 0.0], 0.0),
        (0.1, [0.023, 0.023, 0.02], [0.0, -0.606, 0.0], 0.0),
        (0.1, [0.023, 0.046, 0.02], [0.06, -0.605, 0.0], 0.0),
    ];
    let n = n.max(2);
    let dims = [n; 3];
    let affine = cube_affine(dims, -1.0, 1.0);
    use rayon::prelude::*;
    let data = (0..n * n * n)
        .into_par_iter()
        .map(|i| {
            let p = (affine
                * DVec4::new(
                    (i % n) as f64,
                    ((i / n) % n) as f64,
                    (i / (n * n)) as f64,
                    1.0,
                ))
            .truncate();
            let mut v = 0.0;
            for (a, s, c, phi) in E {
                let (sn, cs) = phi.to_radians().sin_cos();
                let d = p - DVec3::from(c);
                let q = DVec3::new(cs * d.x + sn * d.y, -sn * d.x + cs * d.y, d.z);
                if (q / DVec3::from(s)).length_squared() <= 1.0 {
                    v += a;
                }
            }
            let v = (v * 1000.0).round().max(0.0);
            if v == 0.0 {
                return 0.0;
            }
            // A 64-bit mix of the index: noise without a random-number crate.
            let mut h = (i as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15);
            h ^= h >> 31;
            h = h.wrapping_mul(0xBF58_476D_1CE4_E5B9);
            h ^= h >> 29;
            (v + (h % 17) as f64 - 8.0).max(0.0) as f32
        })
        .collect();
    let mut vol = synthetic_volume(dims, affine, "density", 1, data);
    vol.fields[0].stored = ScalarType::U16;
    vol
}

/// A steady velocity field with known behaviour.
pub trait VectorField: Sync {
    fn velocity(&self, p: DVec3) -> DVec3;
}

/// Rigid rotation about the axis through `center` along `axis` (unit) with angular speed
/// `omega`: every streamline is a circle around the axis.
#[derive(Clone, Copy, Debug)]
pub struct RigidRotation {
    pub center: DVec3,
    pub axis: DVec3,
    pub omega: f64,
}

impl VectorField for RigidRotation {
    fn velocity(&self, p: DVec3) -> DVec3 {
        self.omega * self.axis.cross(p - self.center)
    }
}

/// Arnold-Beltrami-Childress flow: u = (A sin z + C cos y, B sin x + A cos z, C sin y + B cos x).
/// The classic chaotic parameters are A = sqrt(3), B = sqrt(2), C = 1.
#[derive(Clone, Copy, Debug)]
pub struct AbcFlow {
    pub a: f64,
    pub b: f64,
    pub c: f64,
}

impl Default for AbcFlow {
    fn default() -> Self {
        AbcFlow {
            a: 3f64.sqrt(),
            b: 2f64.sqrt(),
            c: 1.0,
        }
    }
}

impl VectorField for AbcFlow {
    fn velocity(&self, p: DVec3) -> DVec3 {
        DVec3::new(
            self.a * p.z.sin() + self.c * p.y.cos(),
            self.b * p.x.sin() + self.a * p.z.cos(),
            self.c * p.y.sin() + self.b * p.x.cos(),
        )
    }
}

/// Burgers vortex around the z axis through `center`: inflow u_r = -a r / 2, updraft
/// u_z = a (z - z_c), swirl u_theta = gamma / (2 pi r) (1 - exp(-r^2 / r_c^2)) with the core
/// radius r_c = sqrt(4 nu / a) fixed here by `core`. A tornado-like exact solution of the
/// Navier-Stokes equations; streamlines spiral in and up.
#[derive(Clone, Copy, Debug)]
pub struct BurgersVortex {
    pub center: DVec3,
    pub strain: f64,
    pub circulation: f64,
    pub core: f64,
}

impl VectorField for BurgersVortex {
    fn velocity(&self, p: DVec3) -> DVec3 {
        let d = p - self.center;
        let r2 = d.x * d.x + d.y * d.y;
        let r = r2.sqrt();
        let ur = -self.strain * r / 2.0;
        let ut = if r > 1e-12 {
            self.circulation / (2.0 * std::f64::consts::PI * r)
                * (1.0 - (-r2 / (self.core * self.core)).exp())
        } else {
            0.0
        };
        let (c, s) = if r > 1e-12 {
            (d.x / r, d.y / r)
        } else {
            (1.0, 0.0)
        };
        DVec3::new(ur * c - ut * s, ur * s + ut * c, self.strain * d.z)
    }
}

/// The rigid rotation about the z axis (omega 1) sampled on a 41 x 41 x 9 slab over
/// [-1, 1]^2 x [-0.2, 0.2]: a linear field, so trilinear interpolation is exact and a tracer's
/// error on it is the integrator's alone (streamlines are circles about the z axis).
pub fn rotation_slab() -> Volume {
    let mut affine = cube_affine([41, 41, 41], -1.0, 1.0);
    affine.z_axis.z = 0.05;
    affine.w_axis.z = -0.2;
    sample_vector(
        &RigidRotation {
            center: DVec3::ZERO,
            axis: DVec3::Z,
            omega: 1.0,
        },
        [41, 41, 9],
        affine,
        "v",
    )
}

/// End point after arc length `length` of the streamline of `f` from `seed`, by classic RK4 on
/// the analytic field's direction with step `h` (the high-accuracy reference of the tracing
/// tests and of `engine/examples/trace_accuracy.rs`).
pub fn reference_streamline_end(f: &dyn VectorField, seed: DVec3, length: f64, h: f64) -> DVec3 {
    let dir = |p: DVec3| f.velocity(p).normalize();
    let mut p = seed;
    for _ in 0..(length / h).round() as usize {
        let k1 = dir(p);
        let k2 = dir(p + k1 * (h / 2.0));
        let k3 = dir(p + k2 * (h / 2.0));
        let k4 = dir(p + k3 * h);
        p += (k1 + k2 * 2.0 + k3 * 2.0 + k4) * (h / 6.0);
    }
    p
}

/// Samples a vector field on a grid as a 3-component volume.
pub fn sample_vector(
    field: &dyn VectorField,
    dims: [usize; 3],
    affine: DMat4,
    name: &str,
) -> Volume {
    let data = grid_points(dims, affine)
        .flat_map(|p| {
            let v = field.velocity(p);
            [v.x as f32, v.y as f32, v.z as f32]
        })
        .collect();
    synthetic_volume(dims, affine, name, 3, data)
}

/// A time-dependent velocity field.
pub trait UnsteadyField: Sync {
    fn velocity(&self, p: DVec3, t: f64) -> DVec3;
}

/// The double gyre of Shadden, Lekien and Marsden (Physica D 212, 2005), extruded over
/// `0 <= z <= 1` and given a w component by a steady roll in the y-z plane:
///
/// ```text
/// a(t) = eps sin(omega t),  b(t) = 1 - 2 eps sin(omega t),  f(x, t) = a x^2 + b x
/// u = -pi A sin(pi f) cos(pi y)
/// v =  pi A cos(pi f) sin(pi y) (2 a x + b)  +  pi C sin(pi y) cos(pi z)
/// w = -pi C cos(pi y) sin(pi z)
/// ```
///
/// on `[0, 2] x [0, 1] x [0, 1]`. The first terms are the planar double gyre (stream function
/// `A sin(pi f) sin(pi y)`), the `C` terms the roll (stream function `C sin(pi y) sin(pi z)` in
/// the y-z plane); both are divergence-free and tangent to the box's faces, so particles stay
/// inside. Shadden's parameters are `A = 0.1`, `eps = 0.25`, `omega = 2 pi / 10` (period 10);
/// [`Default`] adds `C = 0.05`. With `C = 0` it is the planar double gyre at every z.
#[derive(Clone, Copy, Debug)]
pub struct DoubleGyre3d {
    pub a: f64,
    pub eps: f64,
    pub omega: f64,
    /// Amplitude of the y-z roll.
    pub c: f64,
}

impl Default for DoubleGyre3d {
    fn default() -> Self {
        DoubleGyre3d {
            a: 0.1,
            eps: 0.25,
            omega: 2.0 * std::f64::consts::PI / 10.0,
            c: 0.05,
        }
    }
}

impl DoubleGyre3d {
    /// The time after which the flow repeats, `2 pi / omega`.
    pub fn period(&self) -> f64 {
        2.0 * std::f64::consts::PI / self.omega
    }
}

impl UnsteadyField for DoubleGyre3d {
    fn velocity(&self, p: DVec3, t: f64) -> DVec3 {
        use std::f64::consts::PI;
        let s = (self.omega * t).sin();
        let (a, b) = (self.eps * s, 1.0 - 2.0 * self.eps * s);
        let f = a * p.x * p.x + b * p.x;
        let dfdx = 2.0 * a * p.x + b;
        let (sy, cy) = (PI * p.y).sin_cos();
        let (sz, cz) = (PI * p.z).sin_cos();
        DVec3::new(
            -PI * self.a * (PI * f).sin() * cy,
            PI * self.a * (PI * f).cos() * sy * dfdx + PI * self.c * sy * cz,
            -PI * self.c * cy * sz,
        )
    }
}

/// A uniform flow along `direction` whose speed grows linearly in time: `u = rate t direction`.
/// Its pathlines are known exactly, `x(t) = x0 + rate (t^2 - t0^2) / 2 direction`, and
/// linear interpolation in space and time reproduces it exactly.
#[derive(Clone, Copy, Debug)]
pub struct LinearRamp {
    pub rate: f64,
    pub direction: DVec3,
}

impl UnsteadyField for LinearRamp {
    fn velocity(&self, _p: DVec3, t: f64) -> DVec3 {
        self.rate * t * self.direction
    }
}

/// The affine of the double gyre's grid for `n` samples across y and z: spacing `1 / (n - 1)`,
/// `2 (n - 1) + 1` samples across x, origin 0 (returns the dims too).
pub fn double_gyre_grid(n: usize) -> ([usize; 3], DMat4) {
    let n = n.max(2);
    let h = 1.0 / (n - 1) as f64;
    let dims = [2 * (n - 1) + 1, n, n];
    let affine = DMat4::from_cols(
        DVec4::new(h, 0.0, 0.0, 0.0),
        DVec4::new(0.0, h, 0.0, 0.0),
        DVec4::new(0.0, 0.0, h, 0.0),
        DVec4::new(0.0, 0.0, 0.0, 1.0),
    );
    (dims, affine)
}

/// Samples an unsteady field at `frames` times `t0 + k dt` into a series (periodic when told:
/// then `frames dt` should be the field's period).
#[allow(clippy::too_many_arguments)]
pub fn sample_series(
    field: &dyn UnsteadyField,
    dims: [usize; 3],
    affine: DMat4,
    name: &str,
    frames: usize,
    t0: f64,
    dt: f64,
    periodic: bool,
) -> VolumeSeries {
    let frames = (0..frames.max(1))
        .map(|k| {
            let t = t0 + k as f64 * dt;
            let data = grid_points(dims, affine)
                .flat_map(|p| {
                    let v = field.velocity(p, t);
                    [v.x as f32, v.y as f32, v.z as f32]
                })
                .collect();
            synthetic_volume(dims, affine, name, 3, data)
        })
        .collect();
    VolumeSeries {
        frames,
        t0,
        dt,
        periodic,
        warnings: vec![],
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn primitive_distances_match_closed_forms() {
        let s = Solid::Sphere {
            center: DVec3::ZERO,
            radius: 2.0,
        };
        assert!((s.distance(DVec3::new(5.0, 0.0, 0.0)) - 3.0).abs() < 1e-12);
        assert!((s.distance(DVec3::ZERO) + 2.0).abs() < 1e-12);
        let b = Solid::Box {
            center: DVec3::ZERO,
            half: DVec3::new(1.0, 2.0, 3.0),
        };
        // Outside a corner: Euclidean distance to the corner.
        assert!((b.distance(DVec3::new(4.0, 6.0, 3.0)) - (9.0f64 + 16.0).sqrt()).abs() < 1e-12);
        // Inside: distance to the nearest face.
        assert!((b.distance(DVec3::new(0.5, 0.0, 0.0)) + 0.5).abs() < 1e-12);
        let t = Solid::Torus {
            center: DVec3::ZERO,
            major: 3.0,
            minor: 1.0,
        };
        assert!((t.distance(DVec3::new(3.0, 0.0, 0.0)) + 1.0).abs() < 1e-12);
        assert!((t.distance(DVec3::new(0.0, 0.0, 0.0)) - 2.0).abs() < 1e-12);
        assert!((t.distance(DVec3::new(0.0, 3.0, 2.5)) - 1.5).abs() < 1e-12);
    }

    #[test]
    fn scene_unions_are_disjoint_so_min_is_exact() {
        // For disjoint solids, a point inside one solid is outside all the others, and the
        // other solids are farther than its own boundary: check on a grid of points.
        for solid in [three_solids(), validation_solid()] {
            let Solid::Union(parts) = &solid else {
                panic!()
            };
            // The validation scene lives in [0, 100]^3, the three solids in [0, 1]^3.
            let lo = 0.0;
            let hi = if parts.len() > 3 { 100.0 } else { 1.0 };
            for i in 0..40 {
                for j in 0..40 {
                    for k in 0..40 {
                        let p = DVec3::new(i as f64, j as f64, k as f64) / 39.0 * (hi - lo)
                            + DVec3::splat(lo);
                        let inside: Vec<f64> = parts
                            .iter()
                            .map(|s| s.distance(p))
                            .filter(|&d| d < 0.0)
                            .collect();
                        assert!(inside.len() <= 1, "solids overlap at {p}");
                        if let Some(&d) = inside.first() {
                            for s in parts {
                                let e = s.distance(p);
                                assert!(
                                    e <= 0.0 || e >= -d - 1e-9,
                                    "another solid is nearer than the own boundary at {p}"
                                );
                            }
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn validation_points_lie_on_the_surface() {
        let s = validation_solid();
        use validation_points::*;
        for p in [PIT_BOTTOM, BOX_TOP, SPHERE_TOP, SPHERE_BOTTOM_SIDE] {
            assert!(
                s.distance(p).abs() < 1e-6,
                "{p} is {} from the surface",
                s.distance(p)
            );
        }
    }

    #[test]
    fn rigid_rotation_is_tangent_to_circles() {
        let f = RigidRotation {
            center: DVec3::new(1.0, 2.0, 0.0),
            axis: DVec3::Z,
            omega: 2.0,
        };
        let p = DVec3::new(4.0, 2.0, 5.0);
        let v = f.velocity(p);
        assert!((v - DVec3::new(0.0, 6.0, 0.0)).length() < 1e-12);
        assert!(v.dot(p - f.center).abs() < 1e-12);
    }

    #[test]
    fn abc_flow_is_divergence_free_and_burgers_has_its_strain() {
        let f = AbcFlow::default();
        let h = 1e-5;
        for p in [DVec3::new(0.3, 1.1, 2.0), DVec3::new(4.0, -1.0, 0.5)] {
            let div = (f.velocity(p + DVec3::X * h).x - f.velocity(p - DVec3::X * h).x
                + f.velocity(p + DVec3::Y * h).y
                - f.velocity(p - DVec3::Y * h).y
                + f.velocity(p + DVec3::Z * h).z
                - f.velocity(p - DVec3::Z * h).z)
                / (2.0 * h);
            assert!(div.abs() < 1e-6);
        }
        let b = BurgersVortex {
            center: DVec3::ZERO,
            strain: 0.5,
            circulation: 10.0,
            core: 1.0,
        };
        // Far from the core the swirl is a potential vortex gamma / (2 pi r).
        let v = b.velocity(DVec3::new(10.0, 0.0, 0.0));
        assert!((v.y - 10.0 / (2.0 * std::f64::consts::PI * 10.0)).abs() < 1e-9);
        assert!((v.x + 0.5 * 10.0 / 2.0).abs() < 1e-12);
        // Incompressible: div = -a/2 * 2 + a = 0.
        let p = DVec3::new(0.7, -0.4, 1.3);
        let div = (b.velocity(p + DVec3::X * h).x - b.velocity(p - DVec3::X * h).x
            + b.velocity(p + DVec3::Y * h).y
            - b.velocity(p - DVec3::Y * h).y
            + b.velocity(p + DVec3::Z * h).z
            - b.velocity(p - DVec3::Z * h).z)
            / (2.0 * h);
        assert!(div.abs() < 1e-6);
    }

    #[test]
    fn double_gyre_is_divergence_free_periodic_and_stays_in_its_box() {
        let g = DoubleGyre3d::default();
        assert!((g.period() - 10.0).abs() < 1e-12);
        let h = 1e-5;
        for &(x, y, z, t) in &[
            (0.3, 0.2, 0.7, 0.0),
            (1.4, 0.8, 0.1, 2.5),
            (1.9, 0.5, 0.5, 7.3),
        ] {
            let p = DVec3::new(x, y, z);
            let d = |e: DVec3, c: usize| {
                (g.velocity(p + e * h, t)[c] - g.velocity(p - e * h, t)[c]) / (2.0 * h)
            };
            let div = d(DVec3::X, 0) + d(DVec3::Y, 1) + d(DVec3::Z, 2);
            assert!(div.abs() < 1e-8, "div {div}");
            assert!((g.velocity(p, t) - g.velocity(p, t + 10.0)).length() < 1e-12);
            // Normal components vanish on the faces.
            assert!(g.velocity(DVec3::new(0.0, y, z), t).x.abs() < 1e-12);
            assert!(g.velocity(DVec3::new(2.0, y, z), t).x.abs() < 1e-12);
            assert!(g.velocity(DVec3::new(x, 0.0, z), t).y.abs() < 1e-12);
            assert!(g.velocity(DVec3::new(x, 1.0, z), t).y.abs() < 1e-12);
            assert!(g.velocity(DVec3::new(x, y, 0.0), t).z.abs() < 1e-12);
            assert!(g.velocity(DVec3::new(x, y, 1.0), t).z.abs() < 1e-12);
        }
        // At t = 0 the planar part is the steady double gyre: u = -pi A sin(pi x) cos(pi y).
        let v = g.velocity(DVec3::new(0.5, 0.0, 0.5), 0.0);
        assert!((v.x + std::f64::consts::PI * 0.1).abs() < 1e-12, "{v}");
        let (dims, affine) = double_gyre_grid(5);
        assert_eq!(dims, [9, 5, 5]);
        let s = sample_series(&g, dims, affine, "velocity", 4, 0.0, 2.5, true);
        s.validate().unwrap();
        assert_eq!(s.span(), 10.0);
        assert_eq!(s.frames[0].bounds()[1], DVec3::new(2.0, 1.0, 1.0));
    }

    #[test]
    fn sampled_scene_has_the_right_grid_and_sign() {
        let v = validation_scene(20);
        assert_eq!(v.dims, [20, 20, 20]);
        v.validate().unwrap();
        let f = &v.fields[0];
        // Bottom corner voxel (0,0,0) is inside the floor: value >= 0; top corner outside.
        assert!(f.data[0] >= 0.0);
        assert!(*f.data.last().unwrap() < 0.0);
    }
}
