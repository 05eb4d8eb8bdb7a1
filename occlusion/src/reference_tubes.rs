//! The tubes in the Monte Carlo reference (issue 6): their triangle mesh (the one the GPU
//! rasterises) in a bounding volume hierarchy (the `bvh` crate) for the eye ray's first
//! surface and for the length a light ray spends inside tubes, so that the tubes' extinction
//! over their real thickness (`render.geometry_shadow = "inside"`) can enter the reference's
//! transmittance. Inside and outside are told by the interpolated vertex normal at each hit
//! (outward on the mesher's tubes), as the G-buffer does, not by the winding.

use bvh::aabb::{Aabb, Bounded};
use bvh::bounding_hierarchy::BHShape;
use bvh::bvh::Bvh;
use glam::DVec3;
use nalgebra::{Point3, Vector3};
use tubes::tube_mesh::TubeMesh;

/// A world-space triangle with vertex normals and colours.
#[derive(Clone, Debug)]
pub struct Triangle {
    pub p: [DVec3; 3],
    pub n: [DVec3; 3],
    pub c: [[f64; 3]; 3],
    node: usize,
}

impl Bounded<f64, 3> for Triangle {
    fn aabb(&self) -> Aabb<f64, 3> {
        let lo = self.p[0].min(self.p[1]).min(self.p[2]) - DVec3::splat(1e-9);
        let hi = self.p[0].max(self.p[1]).max(self.p[2]) + DVec3::splat(1e-9);
        Aabb::with_bounds(Point3::new(lo.x, lo.y, lo.z), Point3::new(hi.x, hi.y, hi.z))
    }
}

impl BHShape<f64, 3> for Triangle {
    fn set_bh_node_index(&mut self, i: usize) {
        self.node = i;
    }
    fn bh_node_index(&self) -> usize {
        self.node
    }
}

/// A ray's hit: parameter, barycentrics, triangle.
#[derive(Clone, Copy, Debug)]
pub struct Hit {
    pub t: f64,
    pub u: f64,
    pub v: f64,
    pub tri: usize,
}

/// The tubes of a scene for ray queries.
pub struct TubeScene {
    pub tris: Vec<Triangle>,
    bvh: Bvh<f64, 3>,
    /// Clipping planes that cut the tubes (`normal . p > offset` is removed).
    clip: Vec<([f64; 3], f64)>,
}

impl TubeScene {
    pub fn new(meshes: &[TubeMesh], clip: &[([f64; 3], f64)]) -> TubeScene {
        let mut tris = vec![];
        for m in meshes {
            let col = |i: usize| {
                m.colors
                    .get(i)
                    // 8-bit sRGB, decoded to linear light as the G-buffer decodes it.
                    .map_or([200.0 / 255.0; 3], |c| c.map(|v| v as f64 / 255.0))
                    .map(volume::colormap::srgb_to_linear)
            };
            for t in m.indices.chunks_exact(3) {
                let i = [t[0] as usize, t[1] as usize, t[2] as usize];
                tris.push(Triangle {
                    p: i.map(|k| m.origin + m.positions[k].as_dvec3()),
                    n: i.map(|k| m.normals.get(k).map_or(DVec3::Z, |n| n.as_dvec3())),
                    c: i.map(col),
                    node: 0,
                });
            }
        }
        let bvh = if tris.is_empty() {
            Bvh { nodes: vec![] }
        } else {
            Bvh::build(&mut tris)
        };
        TubeScene {
            tris,
            bvh,
            clip: clip.to_vec(),
        }
    }

    pub fn is_empty(&self) -> bool {
        self.tris.is_empty()
    }

    /// Every hit of `o + t d` with `t` in `(t_min, t_max)`, nearest first (Moller-Trumbore in
    /// f64), leaving out hits on the removed side of a clipping plane; hits at the same `t` (an
    /// edge shared by two triangles) count once.
    pub fn hits(&self, o: DVec3, d: DVec3, t_min: f64, t_max: f64) -> Vec<Hit> {
        if self.tris.is_empty() {
            return vec![];
        }
        let ray = bvh::ray::Ray::new(Point3::new(o.x, o.y, o.z), Vector3::new(d.x, d.y, d.z));
        let mut out = vec![];
        for tri in self.bvh.traverse(&ray, &self.tris) {
            let [a, b, c] = tri.p;
            let (e1, e2) = (b - a, c - a);
            let pv = d.cross(e2);
            let det = e1.dot(pv);
            if det.abs() < 1e-18 {
                continue;
            }
            let inv = 1.0 / det;
            let tv = o - a;
            let u = tv.dot(pv) * inv;
            if !(0.0..=1.0).contains(&u) {
                continue;
            }
            let qv = tv.cross(e1);
            let v = d.dot(qv) * inv;
            if v < 0.0 || u + v > 1.0 {
                continue;
            }
            let t = e2.dot(qv) * inv;
            if t <= t_min || t >= t_max {
                continue;
            }
            let p = o + d * t;
            if self
                .clip
                .iter()
                .any(|(n, off)| DVec3::from(*n).dot(p) > *off)
            {
                continue;
            }
            // The triangle's index in `tris` from its address.
            let idx = (tri as *const Triangle as usize - self.tris.as_ptr() as usize)
                / std::mem::size_of::<Triangle>();
            out.push(Hit { t, u, v, tri: idx });
        }
        out.sort_by(|x, y| x.t.total_cmp(&y.t));
        // A ray through an edge or vertex hits the triangles sharing it at the same t: once.
        out.dedup_by(|b, a| (b.t - a.t).abs() <= 1e-9 * a.t.abs().max(1.0));
        out
    }

    /// The interpolated normal (unit) and colour at a hit.
    pub fn surface(&self, h: &Hit) -> (DVec3, [f64; 3]) {
        let t = &self.tris[h.tri];
        let w = [1.0 - h.u - h.v, h.u, h.v];
        let n = (t.n[0] * w[0] + t.n[1] * w[1] + t.n[2] * w[2]).normalize_or_zero();
        let c = [0, 1, 2].map(|k| t.c[0][k] * w[0] + t.c[1][k] * w[1] + t.c[2][k] * w[2]);
        (n, c)
    }

    /// The length of `o + t d`, `t` in `(0, t_max)`, inside tubes: from each hit entering a
    /// tube (normal against the ray) to the next hit leaving one (from 0 when the first hit
    /// leaves).
    pub fn inside_length(&self, o: DVec3, d: DVec3, t_max: f64) -> f64 {
        let mut len = 0.0;
        let mut entered: Option<f64> = None;
        let mut first = true;
        for h in self.hits(o, d, 0.0, t_max) {
            let (n, _) = self.surface(&h);
            let entering = n.dot(d) < 0.0;
            if entering {
                if entered.is_none() {
                    entered = Some(h.t);
                }
            } else {
                match entered.take() {
                    Some(t0) => len += h.t - t0,
                    None if first => len += h.t,
                    None => {}
                }
            }
            first = false;
        }
        if let Some(t0) = entered {
            if t_max.is_finite() {
                len += t_max - t0;
            }
        }
        len
    }
}

/// Hemisphere ambient occlusion of the tubes seen by `camera` (issue 6): per path a ray through
/// a random point of the pixel (box filter) and, where it meets a tube, one cosine-weighted
/// ray about the surface normal (facing the viewer) that counts as open when it meets no tube;
/// a pixel that misses every tube sees open sky (1). This is what a path tracer computes for a
/// white diffuse surface under a constant white environment with one bounce (Mitsuba's `path`
/// integrator with `max_depth` 2), the cross-check of `bench/mitsuba_ao.py`. With
/// `max_distance` only tubes that near occlude (the usual AO falloff radius). Returns the mean
/// per pixel (rows top to bottom) and its standard error.
#[allow(clippy::too_many_arguments)]
pub fn hemisphere_ao(
    scene: &TubeScene,
    camera: &crate::camera::Camera,
    width: usize,
    height: usize,
    spp: u32,
    seed: u64,
    max_distance: Option<f64>,
) -> (Vec<f64>, Vec<f64>) {
    use rayon::prelude::*;
    let px: Vec<(f64, f64)> = (0..width * height)
        .into_par_iter()
        .map(|i| {
            let mut rng = crate::rng::SplitMix64(
                seed ^ (i as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ 0x0A0A,
            );
            let n = spp.max(1);
            let (mut sum, mut sq) = (0.0, 0.0);
            for _ in 0..n {
                let (jx, jy) = (rng.next_f64() - 0.5, rng.next_f64() - 0.5);
                let (o, d) = camera.ray(
                    (i % width) as f64 + jx,
                    (i / width) as f64 + jy,
                    width,
                    height,
                );
                let v = match scene.hits(o, d, 0.0, f64::INFINITY).first() {
                    None => 1.0,
                    Some(h) => {
                        let (mut nrm, _) = scene.surface(h);
                        if nrm.dot(d) > 0.0 {
                            nrm = -nrm;
                        }
                        let p = o + d * h.t + nrm * 1e-4 * (1.0 + h.t.abs());
                        let (u1, u2) = (rng.next_f64(), rng.next_f64());
                        let r = u1.sqrt();
                        let phi = std::f64::consts::TAU * u2;
                        let a = if nrm.x.abs() < 0.9 {
                            DVec3::X
                        } else {
                            DVec3::Y
                        };
                        let t = nrm.cross(a).normalize();
                        let b = nrm.cross(t);
                        let dir = t * (r * phi.cos())
                            + b * (r * phi.sin())
                            + nrm * (1.0 - u1).max(0.0).sqrt();
                        let reach = max_distance.unwrap_or(f64::INFINITY);
                        if scene.hits(p, dir, 0.0, reach).is_empty() {
                            1.0
                        } else {
                            0.0
                        }
                    }
                };
                sum += v;
                sq += v * v;
            }
            let nf = n as f64;
            let mean = sum / nf;
            (mean, ((sq / nf - mean * mean).max(0.0) / nf).sqrt())
        })
        .collect();
    (
        px.iter().map(|p| p.0).collect(),
        px.iter().map(|p| p.1).collect(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A closed tube of radius r along x from -5 to 5 (caps on).
    fn tube(r: f64) -> TubeMesh {
        tubes::tube_mesh::straight_tubes(
            &[[[-5.0, 0.0, 0.0], [5.0, 0.0, 0.0]]],
            r,
            64,
            [1.0, 0.0, 0.0],
        )
    }

    #[test]
    fn rays_find_the_surface_and_the_chord_through_a_tube() {
        let sc = TubeScene::new(&[tube(1.0)], &[]);
        // Straight down through the axis: the top at z = 1, a chord of 2.
        let o = DVec3::new(0.3, 0.0, 10.0);
        let d = -DVec3::Z;
        let h = sc.hits(o, d, 0.0, f64::INFINITY);
        assert_eq!(h.len(), 2);
        assert!((h[0].t - 9.0).abs() < 2e-3, "{}", h[0].t);
        let (n, c) = sc.surface(&h[0]);
        assert!(n.dot(DVec3::Z) > 0.99 && (c[0] - 1.0).abs() < 1e-9);
        assert!((sc.inside_length(o, d, f64::INFINITY) - 2.0).abs() < 4e-3);
        // Off axis by 0.6: chord 2 sqrt(1 - 0.36) = 1.6; missing it: 0; from inside: 1 + 0.
        let o2 = DVec3::new(0.3, 0.6, 10.0);
        assert!((sc.inside_length(o2, d, f64::INFINITY) - 1.6).abs() < 0.01);
        assert_eq!(
            sc.inside_length(DVec3::new(0.0, 3.0, 10.0), d, f64::INFINITY),
            0.0
        );
        assert!((sc.inside_length(DVec3::new(0.0, 0.0, 0.0), d, f64::INFINITY) - 1.0).abs() < 4e-3);
        // A clipping plane removing x > 0 removes the hits there.
        let cut = TubeScene::new(&[tube(1.0)], &[([1.0, 0.0, 0.0], 0.0)]);
        assert!(cut.hits(o, d, 0.0, f64::INFINITY).is_empty());
        assert_eq!(
            cut.hits(DVec3::new(-0.3, 0.0, 10.0), d, 0.0, f64::INFINITY)
                .len(),
            2
        );
    }
}
