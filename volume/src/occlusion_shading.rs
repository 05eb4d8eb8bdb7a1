//! Shading with the octant visibility fields: the integrated geometry term `G_s(N)` of eq. (5),
//! the ambient estimate `A(P, N) = sum_s V_s(P) G_s(N)` of eq. (4), and the paper's variants
//! (scalar AO without the geometry term, octant subsets, gamma, the subsurface geometry term
//! `g = |N . w|`), Singh, Yuksel and House, "Fast Occlusion Sweeping" (ISVC 2009).
//!
//! # `G_s(N)` in closed form
//! `G_s(N) = int_{Omega_s} max(N . w, 0) dw` over the octant `Omega_s` of the unit sphere whose
//! directions have the signs of the sky of sweep `s` (`-sigma_s`, see
//! [`crate::occlusion_sweep`]). The octant is the spherical triangle with vertices
//! `-sx e_x, -sy e_y, -sz e_z`. Clipping it by the great circle `N . w = 0` (arcs are split where
//! `N . ((1 - t) a + t b) = 0`) leaves a spherical polygon `P` in the hemisphere of `N`, and by
//! Lambert's formula for the projected solid angle of a polygon,
//! `int_P N . w dw = 1/2 sum_edges theta_e (N . n_e)`, with `theta_e` the arc angle of an edge and
//! `n_e` the unit normal of its great circle (`v_i x v_i+1`, normalised), oriented so the sum is
//! positive. The eight values add up to `pi` for every unit `N` (tested, with numerical
//! integration of each octant).
//!
//! # Normalisation
//! `A` is divided by the largest value `sum_s w_s G_s(N)` takes over unit normals for the chosen
//! octant weights `w_s`, so an unoccluded point facing the sky gets 1: `pi` for the uniform sky
//! and for `overcast` (the four octants whose sky lies above), `(pi / 4) sqrt(3)` for one octant.
//! Without the geometry term `A = sum_s w_s V_s / sum_s w_s`. With the subsurface term
//! `|N . w|` the octant integral is `G_s(N) + G_s(-N)` and the uniform maximum is `2 pi`.
//! Gamma is applied last: `A^(1 / gamma)`.
//!
//! # Frames
//! The octants are defined in index space, so `N` (a world normal) is taken into the index
//! frame first: `N_index = R^T N` with `R` the affine's unit axis vectors (exact for affines
//! without shear, which covers every format we read in practice).

use crate::distance_sweep::SWEEP_DIRECTIONS;
use crate::occlusion_sweep::{sky_direction_world, OctantFields};
use glam::{DMat3, DMat4, DVec3};

/// The geometry term of eq. (2).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GeometryTerm {
    /// `max(N . w, 0)`: ambient occlusion (eq. 4-5).
    Cosine,
    /// None: scalar AO, the mean octant visibility.
    Constant,
    /// `|N . w|`: the subsurface variant of section 4.2.
    Absolute,
}

/// Which octants light the scene.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Sky {
    Uniform,
    /// The four octants whose sky lies above (world +z, superior for RAS data).
    Overcast,
    /// One octant, numbered 1..=8 in Table 1 order: a low-frequency shadow.
    Octant(usize),
}

impl std::str::FromStr for Sky {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "uniform" => Ok(Sky::Uniform),
            "overcast" => Ok(Sky::Overcast),
            _ => {
                let n: usize = s
                    .strip_prefix("octant:")
                    .and_then(|n| n.parse().ok())
                    .filter(|n| (1..=8).contains(n))
                    .ok_or_else(|| format!("unknown sky '{s}' (uniform, overcast, octant:1..8)"))?;
                Ok(Sky::Octant(n))
            }
        }
    }
}

impl std::str::FromStr for GeometryTerm {
    type Err = String;
    /// `cosine`, `none` (or `constant`) and `abs`, as `umbra iso --geometry` names them.
    fn from_str(s: &str) -> Result<Self, String> {
        match s.trim() {
            "cosine" => Ok(GeometryTerm::Cosine),
            "none" | "constant" => Ok(GeometryTerm::Constant),
            "abs" => Ok(GeometryTerm::Absolute),
            other => Err(format!("'{other}' is not cosine, none or abs")),
        }
    }
}

/// Shading options of the swept ambient term.
#[derive(Clone, Copy, Debug)]
pub struct AmbientOptions {
    pub geometry: GeometryTerm,
    pub sky: Sky,
    pub gamma: f64,
    /// Flat-face correction: look `V` up at `P + c h_min N` instead of `P` (`c = 0` is the
    /// paper). See docs/accuracy.md for what it does against the Monte Carlo reference.
    pub offset: f64,
}

impl Default for AmbientOptions {
    fn default() -> Self {
        AmbientOptions {
            geometry: GeometryTerm::Cosine,
            sky: Sky::Uniform,
            gamma: 1.0,
            offset: DEFAULT_OFFSET,
        }
    }
}

/// Default flat-face correction `c` (chosen from the measurements in docs/accuracy.md).
pub const DEFAULT_OFFSET: f64 = 1.5;

/// `G_s(N)` for sweep `s` (0-based, Table 1 order) and a unit normal in the index frame.
pub fn geometry_term(s: usize, n: DVec3) -> f64 {
    let d = SWEEP_DIRECTIONS[s];
    let verts = [
        DVec3::X * -(d[0] as f64),
        DVec3::Y * -(d[1] as f64),
        DVec3::Z * -(d[2] as f64),
    ];
    projected_solid_angle(&verts, n)
}

/// `int_P max(N . w, 0) dw` for a spherical polygon `P` given by unit vertices (convex, less
/// than a hemisphere).
pub fn projected_solid_angle(verts: &[DVec3], n: DVec3) -> f64 {
    // Clip against N . w >= 0.
    let mut poly: Vec<DVec3> = Vec::with_capacity(verts.len() + 2);
    for i in 0..verts.len() {
        let a = verts[i];
        let b = verts[(i + 1) % verts.len()];
        let (da, db) = (n.dot(a), n.dot(b));
        if da >= 0.0 {
            poly.push(a);
        }
        if (da >= 0.0) != (db >= 0.0) {
            let t = da / (da - db);
            poly.push((a + (b - a) * t).normalize());
        }
    }
    if poly.len() < 3 {
        return 0.0;
    }
    let mut sum = 0.0;
    for i in 0..poly.len() {
        let a = poly[i];
        let b = poly[(i + 1) % poly.len()];
        let c = a.cross(b);
        let len = c.length();
        if len < 1e-15 {
            continue;
        }
        let theta = a.dot(b).clamp(-1.0, 1.0).acos();
        sum += theta * n.dot(c / len);
    }
    (0.5 * sum).abs()
}

/// The ambient model for one grid: octant weights, geometry term, normalisation, frames.
#[derive(Clone, Debug)]
pub struct AmbientModel {
    pub options: AmbientOptions,
    weights: [f64; 8],
    norm: f64,
    /// World normal to index frame (`R^T`).
    to_index: DMat3,
}

impl AmbientModel {
    pub fn new(options: AmbientOptions, affine: &DMat4) -> Self {
        let m = DMat3::from_mat4(*affine);
        let r = DMat3::from_cols(
            m.x_axis.normalize_or_zero(),
            m.y_axis.normalize_or_zero(),
            m.z_axis.normalize_or_zero(),
        );
        let weights = octant_weights(options.sky, affine);
        let mut model = AmbientModel {
            options,
            weights,
            norm: 1.0,
            to_index: r.transpose(),
        };
        model.norm = match options.geometry {
            GeometryTerm::Constant => weights.iter().sum(),
            _ => {
                // Largest unnormalised value over unit normals: octant centres, axes and a
                // Fibonacci sphere, refined around the best.
                let mut cands: Vec<DVec3> = fibonacci_sphere(2000);
                for d in SWEEP_DIRECTIONS {
                    cands.push(-DVec3::new(d[0] as f64, d[1] as f64, d[2] as f64).normalize());
                }
                cands.extend([
                    DVec3::X,
                    DVec3::Y,
                    DVec3::Z,
                    -DVec3::X,
                    -DVec3::Y,
                    -DVec3::Z,
                ]);
                let raw = |n: DVec3| model.raw_index(&[1.0; 8], n);
                let mut best = cands
                    .iter()
                    .copied()
                    .max_by(|a, b| raw(*a).total_cmp(&raw(*b)))
                    .unwrap();
                let mut step = 0.05;
                for _ in 0..60 {
                    let mut improved = false;
                    for dir in [
                        DVec3::X,
                        DVec3::Y,
                        DVec3::Z,
                        -DVec3::X,
                        -DVec3::Y,
                        -DVec3::Z,
                    ] {
                        let c = (best + dir * step).normalize();
                        if raw(c) > raw(best) {
                            best = c;
                            improved = true;
                        }
                    }
                    if !improved {
                        step *= 0.5;
                    }
                }
                raw(best)
            }
        };
        model
    }

    /// Unnormalised `sum_s w_s V_s G_s(N)` for a unit index-frame normal.
    fn raw_index(&self, v: &[f64; 8], n: DVec3) -> f64 {
        (0..8)
            .filter(|&s| self.weights[s] > 0.0)
            .map(|s| {
                let g = match self.options.geometry {
                    GeometryTerm::Cosine => geometry_term(s, n),
                    GeometryTerm::Absolute => geometry_term(s, n) + geometry_term(s, -n),
                    GeometryTerm::Constant => 1.0,
                };
                self.weights[s] * v[s] * g
            })
            .sum()
    }

    /// `A(P, N)` from the eight visibilities at `P` and the world normal `N`, normalised and
    /// gamma-corrected.
    pub fn ambient(&self, v: &[f64; 8], n_world: DVec3) -> f64 {
        let n = (self.to_index * n_world).normalize_or_zero();
        let a = (self.raw_index(v, n) / self.norm).clamp(0.0, 1.0);
        if self.options.gamma != 1.0 {
            a.powf(1.0 / self.options.gamma)
        } else {
            a
        }
    }

    pub fn weights(&self) -> [f64; 8] {
        self.weights
    }

    /// The normalisation of `ambient` (its largest unnormalised value over unit normals).
    pub fn norm(&self) -> f64 {
        self.norm
    }

    /// The rotation taking world normals to the index frame (`R^T`), as `ambient` applies it.
    pub fn to_index(&self) -> DMat3 {
        self.to_index
    }
}

/// Octant weights for a sky.
pub fn octant_weights(sky: Sky, affine: &DMat4) -> [f64; 8] {
    match sky {
        Sky::Uniform => [1.0; 8],
        Sky::Octant(n) => {
            let mut w = [0.0; 8];
            w[n - 1] = 1.0;
            w
        }
        Sky::Overcast => {
            let mut order: Vec<usize> = (0..8).collect();
            order.sort_by(|&a, &b| {
                sky_direction_world(b, affine)
                    .z
                    .total_cmp(&sky_direction_world(a, affine).z)
            });
            let mut w = [0.0; 8];
            for &s in &order[..4] {
                w[s] = 1.0;
            }
            w
        }
    }
}

fn fibonacci_sphere(n: usize) -> Vec<DVec3> {
    let ga = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    (0..n)
        .map(|i| {
            let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
            let r = (1.0 - z * z).sqrt();
            let phi = ga * i as f64;
            DVec3::new(r * phi.cos(), r * phi.sin(), z)
        })
        .collect()
}

/// Trilinear interpolation of the eight octant visibilities at a fractional index position.
///
/// Beyond the grid the sweeps assume open sky, and an object touching the border is closed half
/// a voxel beyond it, so a lookup slightly outside such a surface lands outside the grid. There
/// an octant whose sky points away from the grid across every face the point is beyond sees the
/// open sky (`V = 1`); the others look back into the grid and take the value at the nearest
/// grid sample.
pub fn sample_octants(f: &OctantFields, p: DVec3) -> [f64; 8] {
    let [nx, ny, nz] = f.dims;
    let n = [nx, ny, nz];
    let (x0, y0, z0) = (p.x.floor(), p.y.floor(), p.z.floor());
    let (fx, fy, fz) = (p.x - x0, p.y - y0, p.z - z0);
    let mut v = [0.0; 8];
    for (dk, wz) in [(0.0, 1.0 - fz), (1.0, fz)] {
        for (dj, wy) in [(0.0, 1.0 - fy), (1.0, fy)] {
            for (di, wx) in [(0.0, 1.0 - fx), (1.0, fx)] {
                let w = wx * wy * wz;
                if w == 0.0 {
                    continue;
                }
                let c = [x0 + di, y0 + dj, z0 + dk];
                // -1 beyond the low face, +1 beyond the high face, 0 inside, per axis.
                let side: [i32; 3] = std::array::from_fn(|a| {
                    if c[a] < 0.0 {
                        -1
                    } else if c[a] > (n[a] - 1) as f64 {
                        1
                    } else {
                        0
                    }
                });
                let q: [usize; 3] =
                    std::array::from_fn(|a| c[a].clamp(0.0, (n[a] - 1) as f64) as usize);
                let id = q[0] + nx * (q[1] + ny * q[2]);
                for (s, vs) in v.iter_mut().enumerate() {
                    let sigma = SWEEP_DIRECTIONS[s];
                    // The sky of sweep s is -sigma: open across a face when it points outwards.
                    let open = side.iter().any(|&sd| sd != 0)
                        && (0..3).all(|a| side[a] == 0 || -sigma[a] == side[a]);
                    *vs += w * if open {
                        1.0
                    } else {
                        f.octants[s][id] as f64 / 255.0
                    };
                }
            }
        }
    }
    v
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Midpoint-rule integration of max(N . w, 0) over the octant of sweep s.
    fn numeric(s: usize, n: DVec3) -> f64 {
        let d = SWEEP_DIRECTIONS[s];
        let sign = DVec3::new(-(d[0] as f64), -(d[1] as f64), -(d[2] as f64));
        let m = 400;
        let mut sum = 0.0;
        // Parametrise the octant by polar angle theta in [0, pi/2] from the z axis and
        // azimuth phi in [0, pi/2], then apply the signs.
        for a in 0..m {
            let th = (a as f64 + 0.5) / m as f64 * std::f64::consts::FRAC_PI_2;
            for b in 0..m {
                let ph = (b as f64 + 0.5) / m as f64 * std::f64::consts::FRAC_PI_2;
                let w = DVec3::new(th.sin() * ph.cos(), th.sin() * ph.sin(), th.cos()) * sign;
                sum += n.dot(w).max(0.0) * th.sin();
            }
        }
        sum * (std::f64::consts::FRAC_PI_2 / m as f64).powi(2)
    }

    #[test]
    fn closed_form_matches_numerical_integration() {
        let normals = [
            DVec3::Z,
            DVec3::new(0.3, -0.5, 0.81).normalize(),
            DVec3::new(-1.0, 1.0, 0.2).normalize(),
            DVec3::new(0.0, 1.0, -1.0).normalize(),
        ];
        for n in normals {
            let mut total = 0.0;
            for s in 0..8 {
                let g = geometry_term(s, n);
                let q = numeric(s, n);
                assert!((g - q).abs() < 2e-4, "s {s}, n {n}: closed {g} numeric {q}");
                total += g;
            }
            assert!((total - std::f64::consts::PI).abs() < 1e-9, "sum {total}");
        }
        // N at an octant's centre: the whole octant is lit, G = N . (pi/4)(1,1,1) signs.
        let c = DVec3::splat(-1.0).normalize();
        assert!((geometry_term(0, c) - std::f64::consts::PI / 4.0 * 3f64.sqrt()).abs() < 1e-12);
    }

    #[test]
    fn unoccluded_points_get_one_and_presets_have_their_octants() {
        let id = DMat4::IDENTITY;
        for geometry in [
            GeometryTerm::Cosine,
            GeometryTerm::Constant,
            GeometryTerm::Absolute,
        ] {
            let m = AmbientModel::new(
                AmbientOptions {
                    geometry,
                    sky: Sky::Uniform,
                    gamma: 1.0,
                    offset: 0.0,
                },
                &id,
            );
            for n in [DVec3::Z, DVec3::new(0.2, 0.5, -0.8).normalize()] {
                assert!((m.ambient(&[1.0; 8], n) - 1.0).abs() < 1e-9, "{geometry:?}");
            }
        }
        // Overcast on an identity affine: the skies with +z, i.e. sweeps with sigma_z = -1.
        let w = octant_weights(Sky::Overcast, &id);
        assert_eq!(w, [0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 1.0]);
        let m = AmbientModel::new(
            AmbientOptions {
                sky: Sky::Overcast,
                offset: 0.0,
                ..Default::default()
            },
            &id,
        );
        assert!((m.ambient(&[1.0; 8], DVec3::Z) - 1.0).abs() < 1e-6);
        assert!(m.ambient(&[1.0; 8], -DVec3::Z) < 1e-9);
        // With a flipped z axis (index +z is world -z) the overcast octants flip.
        let flipped = DMat4::from_scale(DVec3::new(1.0, 1.0, -1.0));
        assert_eq!(
            octant_weights(Sky::Overcast, &flipped),
            [1.0, 1.0, 1.0, 1.0, 0.0, 0.0, 0.0, 0.0]
        );
        // Gamma brightens.
        let g = AmbientModel::new(
            AmbientOptions {
                gamma: 2.0,
                offset: 0.0,
                ..Default::default()
            },
            &id,
        );
        assert!((g.ambient(&[0.25; 8], DVec3::Z) - 0.5).abs() < 1e-9);
        assert_eq!("octant:3".parse::<Sky>(), Ok(Sky::Octant(3)));
        assert!("octant:9".parse::<Sky>().is_err());
    }
}
