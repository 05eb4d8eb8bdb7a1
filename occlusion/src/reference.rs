//! The Monte Carlo ground truth of the renderer's volume light model (issue 6), on the CPU
//! (rayon, f64), for the same scene model the GPU renders, so that an error measures the
//! method and not a model mismatch.
//!
//! The model: emission-absorption along the eye ray,
//! `L = int_0^S T(0, s) sigma(s) c(s) O(s) ds + T(0, S) background`, with `sigma` and `c` from the transfer function (extinction per world
//! unit, trilinear samples, NaN and clipped-away samples empty, nothing outside the grid) and
//! `O(s)` the directional occlusion: the mean transmittance, through the volume, over
//! directions distributed uniformly in the cone of half-angle theta around the direction
//! towards the eye (the head light). For the `ea` method `O = 1`. This is the continuous model
//! that Schott et al.'s slices discretise (Algorithms 2-4: the eye buffer is this integral as a
//! Riemann sum over slices, the occlusion buffer this `O` as an incremental blur; eq. 9 the
//! surfaces' shading), with the corrections of issue 5 (extinction per unit length, background
//! last, occlusion inside the tubes' thickness).
//!
//! The estimator is unbiased for this nested integral at a sane cost: delta (Woodcock) tracking
//! (Woodcock et al., "Techniques used in the GEM code for Monte Carlo neutronics calculations in
//! reactors and other systems of complex geometry", 1965) along the eye ray against a global
//! majorant (the transfer function's largest extinction) picks a
//! collision with probability `T sigma ds`; a real collision returns `c(s)` times one ratio-
//! tracking estimate (Novak, Selle and Jarosz, "Residual ratio tracking for estimating
//! attenuation in participating media", ACM TOG 33(6), 2014) of the transmittance along one random cone direction (`prod (1 -
//! sigma / majorant)` over tentative collisions until the ray leaves the grid); escaping the
//! grid returns the background. Each pixel averages `spp` such paths and reports the standard
//! error of its mean (per channel, the largest), so that error bars are honest. Random numbers
//! come from SplitMix64 seeded per pixel: images are reproducible.
//!
//! Tubes (`reference_tubes`): the eye ray ends at the first tube surface, shaded as the GPU
//! shades it (eq. 9 with the head light) with its occlusion estimated the same way as a volume
//! sample's; every transmittance also passes through the tubes with `geometry_extinction` over
//! the length it spends inside them (their real thickness: `geometry_shadow = "inside"`). Each
//! path's eye ray is jittered within its pixel (a box filter, as MSAA and FXAA approximate).
//! The paper's endless-column rule (`geometry_shadow = "column"`) uses a [`ColumnMap`]: the
//! extinction acts wherever a point lies behind the nearest tube surface seen from the eye
//! (the map's grid is several times finer than the image), estimated by delta tracking.

use crate::emission_absorption::{EaView, Transfer};
use crate::rng::SplitMix64;
use glam::{DMat4, DVec3, DVec4};
use rayon::prelude::*;
use volume::Volume;

/// A volume as the reference reads it.
pub struct RefVolume<'a> {
    pub vol: &'a Volume,
    /// As `ea_pass::prepare` returns it (NaN as -3e38).
    pub data: &'a [f32],
    pub tf: &'a Transfer,
}

/// The tubes of a scene, for the reference.
pub struct RefTubes<'a> {
    pub scene: &'a crate::reference_tubes::TubeScene,
    /// Extinction per world unit inside a tube (render.geometry_extinction).
    pub sigma: f64,
    /// ambient, diffuse, specular, shininess (the head light's Phong parameters).
    pub light: [f64; 4],
    /// The paper's endless-column rule instead of the tubes' thickness: the extinction acts
    /// wherever a point lies behind the nearest tube surface seen from the eye.
    pub column: Option<&'a ColumnMap>,
}

/// The nearest tube surface's view depth over a fine grid of the image (`scale` x `scale`
/// rays per pixel, traced against the tube mesh): what "behind a surface" means for the
/// endless-column rule, at a resolution finer than any renderer's pixels.
pub struct ColumnMap {
    camera: crate::camera::Camera,
    width: usize,
    height: usize,
    scale: usize,
    depth: Vec<f64>,
    /// The nearest depth anywhere: no column begins in front of it.
    pub nearest: f64,
}

impl ColumnMap {
    pub fn new(
        scene: &crate::reference_tubes::TubeScene,
        view: &EaView,
        scale: usize,
    ) -> ColumnMap {
        let (w, h) = (view.width as usize * scale, view.height as usize * scale);
        let f = view.camera.forward();
        let eye = view.camera.eye;
        let depth: Vec<f64> = (0..w * h)
            .into_par_iter()
            .map(|i| {
                let (o, d) = view.camera.ray((i % w) as f64, (i / w) as f64, w, h);
                scene
                    .hits(o, d, 0.0, f64::INFINITY)
                    .first()
                    .map_or(f64::INFINITY, |hit| (o + d * hit.t - eye).dot(f))
            })
            .collect();
        let nearest = depth.iter().cloned().fold(f64::INFINITY, f64::min);
        ColumnMap {
            camera: view.camera,
            width: view.width as usize,
            height: view.height as usize,
            scale,
            depth,
            nearest,
        }
    }

    /// Whether `q` lies behind the nearest tube surface along its eye ray.
    pub fn behind(&self, q: DVec3) -> bool {
        let Some((x, y, _)) = self.camera.to_pixel(q, self.width, self.height) else {
            return false;
        };
        let (fx, fy) = (x * self.scale as f64, y * self.scale as f64);
        let (w, h) = (self.width * self.scale, self.height * self.scale);
        if fx < 0.0 || fy < 0.0 || fx >= w as f64 || fy >= h as f64 {
            return false;
        }
        let d = self.depth[fx as usize + w * fy as usize];
        (q - self.camera.eye).dot(self.camera.forward()) >= d
    }
}

/// What to estimate.
#[derive(Clone, Copy, Debug)]
pub struct RefSettings {
    /// Cone half-angle in degrees; `None`: no occlusion (`O = 1`, the `ea` method).
    pub theta_deg: Option<f64>,
    pub spp: u32,
    pub seed: u64,
    /// l_vicinity for the vicinity reference (`None`: not estimated).
    pub vicinity_range: Option<f64>,
}

/// A reference image: linear RGB per pixel (rows top to bottom) and the standard error of
/// each pixel's mean (the largest over the channels).
pub struct RefImage {
    pub width: usize,
    pub height: usize,
    pub rgb: Vec<[f64; 3]>,
    pub stderr: Vec<f64>,
    /// The reference of the volumetric AOV: the mean occlusion at the eye ray's collisions
    /// in the volume (the opacity-weighted mean occlusion along the ray); NaN where none.
    pub volumetric: Vec<f64>,
    /// The reference of the surfaces' occlusion (the combined AOV): the mean cone
    /// transmittance at the first tube surface; NaN where no path reached one.
    pub surface: Vec<f64>,
    /// The reference of the vicinity AOV: the geometry-only part of the same cone visibility at
    /// the first tube surface, counting only tubes within `vicinity_range` (the virtual slice
    /// distance l_vicinity, along the ray); NaN where no path reached a surface or no range
    /// was given.
    pub vicinity: Vec<f64>,
}

struct Medium<'a> {
    v: &'a RefVolume<'a>,
    w2i: DMat4,
    clip: &'a [([f64; 3], f64)],
    majorant: f64,
}

impl Medium<'_> {
    /// Extinction and colour at a world point.
    fn at(&self, p: DVec3) -> (f64, [f64; 3]) {
        if self
            .clip
            .iter()
            .any(|(n, off)| DVec3::from(*n).dot(p) > *off)
        {
            return (0.0, [0.0; 3]);
        }
        let q = (self.w2i * DVec4::from((p, 1.0))).truncate();
        let dims = self.v.vol.dims;
        let Some(v) =
            crate::emission_absorption::sample(self.v.data, dims, q).filter(|&v| v >= -1e30)
        else {
            return (0.0, [0.0; 3]);
        };
        // A 2-D transfer function needs the gradient magnitude, taken as the shader takes it.
        let g = if self.v.tf.rows.is_empty() {
            0.0
        } else {
            crate::emission_absorption::gradient(self.v.data, dims, &self.w2i, q).length()
        };
        let (rgb, sigma) = self.v.tf.eval2(v, g);
        (sigma.max(0.0), rgb)
    }

    /// The ray parameter range `o + t d` spends inside the grid's box.
    fn span(&self, o: DVec3, d: DVec3) -> Option<(f64, f64)> {
        let qo = (self.w2i * DVec4::from((o, 1.0))).truncate();
        let qd = (self.w2i * DVec4::from((d, 0.0))).truncate();
        let dims = self.v.vol.dims;
        let (mut t0, mut t1) = (0.0f64, f64::INFINITY);
        for a in 0..3 {
            let hi = dims[a] as f64 - 1.0;
            if qd[a].abs() < 1e-300 {
                if qo[a] < 0.0 || qo[a] > hi {
                    return None;
                }
                continue;
            }
            let (mut x, mut y) = ((0.0 - qo[a]) / qd[a], (hi - qo[a]) / qd[a]);
            if x > y {
                std::mem::swap(&mut x, &mut y);
            }
            t0 = t0.max(x);
            t1 = t1.min(y);
        }
        (t0 < t1).then_some((t0, t1))
    }

    /// Ratio tracking: an unbiased estimate of the transmittance from `p` along `d` out of the
    /// grid.
    fn transmittance(&self, p: DVec3, d: DVec3, rng: &mut SplitMix64) -> f64 {
        let Some((_, t1)) = self.span(p, d) else {
            return 1.0;
        };
        let mut t = 0.0;
        let mut tr = 1.0;
        loop {
            t -= (1.0 - rng.next_f64()).ln() / self.majorant;
            if t >= t1 {
                return tr;
            }
            let (s, _) = self.at(p + d * t);
            tr *= 1.0 - s / self.majorant;
            if tr < 1e-4 {
                // Russian roulette: unbiased, and bounds the work in dense media.
                if rng.next_f64() < 0.5 {
                    return 0.0;
                }
                tr *= 2.0;
            }
        }
    }
}

/// A direction uniform in the cone of half-angle `theta` around the unit `axis`.
fn cone_direction(axis: DVec3, cos_max: f64, rng: &mut SplitMix64) -> DVec3 {
    let cos_t = 1.0 - rng.next_f64() * (1.0 - cos_max);
    let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
    let phi = std::f64::consts::TAU * rng.next_f64();
    let a = if axis.x.abs() < 0.9 {
        DVec3::X
    } else {
        DVec3::Y
    };
    let u = axis.cross(a).normalize();
    let w = axis.cross(u);
    axis * cos_t + (u * phi.cos() + w * phi.sin()) * sin_t
}

/// Renders the reference of `v` (and the tubes, when given) seen through `view` (its camera,
/// size, clipping planes and background).
pub fn render(v: &RefVolume, tubes: Option<&RefTubes>, view: &EaView, s: &RefSettings) -> RefImage {
    let majorant =
        v.tf.points
            .iter()
            .map(|p| p.2)
            .fold(0.0f64, f64::max)
            .max(1e-12);
    let m = Medium {
        v,
        w2i: v.vol.affine.inverse(),
        clip: &view.clip,
        majorant,
    };
    let (w, h) = (view.width as usize, view.height as usize);
    let cos_max = s.theta_deg.map(|t| t.to_radians().cos());
    let perspective = matches!(
        view.camera.projection,
        crate::camera::Projection::Perspective { .. }
    );
    let bg = view.background;
    let pixels: Vec<([f64; 3], f64, f64, f64, f64)> = (0..w * h)
        .into_par_iter()
        .map(|px| {
            let mut rng =
                SplitMix64(s.seed ^ (px as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ 0xA5A5_5A5A);
            let (mut sum, mut sq) = ([0.0f64; 3], [0.0f64; 3]);
            // (sum, count) of the occlusion at volume collisions and at surfaces.
            let (mut vol_o, mut surf_o) = ((0.0f64, 0u32), (0.0f64, 0u32));
            let mut vic_o = (0.0f64, 0u32);
            let n = s.spp.max(1);
            let occlusion = |p: DVec3, rng: &mut SplitMix64| -> f64 {
                let Some(cm) = cos_max else {
                    return 1.0;
                };
                let axis = if perspective {
                    (view.camera.eye - p).normalize()
                } else {
                    -view.camera.forward()
                };
                let dir = cone_direction(axis, cm, rng);
                let geometry = tubes.map_or(1.0, |t| match t.column {
                    None => (-t.sigma * t.scene.inside_length(p, dir, f64::INFINITY)).exp(),
                    Some(col) => {
                        // Delta tracking against the columns (extinction sigma behind every
                        // surface): absorbed at the first tentative collision in a column.
                        // Towards the light the view depth falls; in front of the nearest
                        // surface no column remains.
                        let f = view.camera.forward();
                        let rate = (-dir.dot(f)).max(1e-3);
                        let reach = ((p - view.camera.eye).dot(f) - col.nearest) / rate;
                        let mut s = 0.0;
                        loop {
                            s -= (1.0 - rng.next_f64()).ln() / t.sigma.max(1e-12);
                            if s >= reach {
                                break 1.0;
                            }
                            if col.behind(p + dir * s) {
                                break 0.0;
                            }
                        }
                    }
                });
                if geometry < 1e-12 {
                    return 0.0;
                }
                geometry * m.transmittance(p, dir, rng)
            };
            for _ in 0..n {
                // A ray through a random point of the pixel.
                let (jx, jy) = (rng.next_f64() - 0.5, rng.next_f64() - 0.5);
                let (o, d) = view
                    .camera
                    .ray((px % w) as f64 + jx, (px / w) as f64 + jy, w, h);
                let surface = tubes.and_then(|t| {
                    t.scene
                        .hits(o, d, 0.0, f64::INFINITY)
                        .first()
                        .map(|hit| (hit.t, t.scene.surface(hit), t))
                });
                let mut value = bg;
                let mut done = false;
                if let Some((t0, t1)) = m.span(o, d) {
                    let t1 = surface.map_or(t1, |x| t1.min(x.0));
                    let mut t = t0;
                    loop {
                        t -= (1.0 - rng.next_f64()).ln() / majorant;
                        if t >= t1 {
                            break;
                        }
                        let p = o + d * t;
                        let (sigma, c) = m.at(p);
                        if rng.next_f64() * majorant < sigma {
                            let occl = occlusion(p, &mut rng);
                            value = c.map(|x| x * occl);
                            vol_o = (vol_o.0 + occl, vol_o.1 + 1);
                            done = true;
                            break;
                        }
                    }
                }
                if !done {
                    if let Some((ts, (mut nrm, albedo), t)) = surface {
                        // The surface, shaded as the GPU does (eq. 9, head light).
                        if nrm.dot(d) > 0.0 {
                            nrm = -nrm;
                        }
                        let p = o + d * ts + nrm * 1e-4 * (1.0 + ts.abs());
                        let occl = occlusion(p, &mut rng);
                        let nl = nrm.dot(-d).max(0.0);
                        let rv = (2.0 * nl * nl - 1.0).max(0.0);
                        let spec = t.light[2] * rv.powf(t.light[3]);
                        value = albedo.map(|a| occl * a * (t.light[0] + t.light[1] * nl) + spec);
                        surf_o = (surf_o.0 + occl, surf_o.1 + 1);
                        if let (Some(range), Some(cm)) = (s.vicinity_range, cos_max) {
                            // One more cone direction: open unless a tube lies within range.
                            let axis = if perspective {
                                (view.camera.eye - p).normalize()
                            } else {
                                -view.camera.forward()
                            };
                            let dir = cone_direction(axis, cm, &mut rng);
                            let open = t.scene.hits(p, dir, 0.0, range).is_empty();
                            vic_o = (vic_o.0 + open as u32 as f64, vic_o.1 + 1);
                        }
                    }
                }
                for k in 0..3 {
                    sum[k] += value[k];
                    sq[k] += value[k] * value[k];
                }
            }
            let nf = n as f64;
            let mean = sum.map(|x| x / nf);
            let se = (0..3)
                .map(|k| ((sq[k] / nf - mean[k] * mean[k]).max(0.0) / nf.max(2.0 - 1.0)).sqrt())
                .fold(0.0, f64::max);
            let avg = |x: (f64, u32)| {
                if x.1 > 0 {
                    x.0 / x.1 as f64
                } else {
                    f64::NAN
                }
            };
            (mean, se, avg(vol_o), avg(surf_o), avg(vic_o))
        })
        .collect();
    RefImage {
        width: w,
        height: h,
        rgb: pixels.iter().map(|p| p.0).collect(),
        stderr: pixels.iter().map(|p| p.1).collect(),
        volumetric: pixels.iter().map(|p| p.2).collect(),
        surface: pixels.iter().map(|p| p.3).collect(),
        vicinity: pixels.iter().map(|p| p.4).collect(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::{Camera, Projection};
    use volume::{Field, ScalarType, Space};

    fn slab() -> Volume {
        // 1 in z in [-5, 5] (the whole grid), a 21^3 grid over [-10, 10]^3.
        let n = 21;
        let affine = DMat4::from_cols(
            DVec4::X,
            DVec4::Y,
            DVec4::Z,
            DVec4::new(-10.0, -10.0, -10.0, 1.0),
        );
        let data = vec![1.0f32; n * n * n];
        Volume::new(
            [n, n, n],
            affine,
            Space::File,
            Field {
                name: "v".into(),
                components: 1,
                stored: ScalarType::F32,
                data,
            },
        )
        .unwrap()
    }

    #[test]
    fn emission_absorption_and_occlusion_match_closed_forms_in_a_uniform_cube() {
        // A uniform white cube of extinction s seen head-on (orthographic, along -z): the
        // E/A image is 1 - exp(-s L) (L = 20) over a black background; with a head light in
        // a cone of half-angle theta, the light at depth x is the cone mean of
        // exp(-s x / cos), so the pixel is int_0^L s e^{-s x} E[e^{-s x / cos}] dx.
        let vol = slab();
        let data = crate::emission_absorption::prepare(&vol.select(None).unwrap().data);
        let s = 0.1;
        let tf = Transfer {
            points: vec![(0.0, [1.0; 3], s), (2.0, [1.0; 3], s)],
            rows: vec![],
        };
        let bounds = vol.bounds();
        let cam = Camera::look_at(
            DVec3::new(0.0, 0.0, 40.0),
            DVec3::ZERO,
            DVec3::Y,
            Projection::Orthographic { height: 16.0 },
            bounds,
        )
        .unwrap();
        let view = EaView::new(&vol, cam, 4, 4, None, None, [0.0; 3]).unwrap();
        let rv = RefVolume {
            vol: &vol,
            data: &data,
            tf: &tf,
        };
        let ea = render(
            &rv,
            None,
            &view,
            &RefSettings {
                theta_deg: None,
                spp: 4000,
                seed: 1,
                vicinity_range: None,
            },
        );
        let want = 1.0 - (-s * 20.0f64).exp();
        for (p, e) in ea.rgb.iter().zip(&ea.stderr) {
            assert!(
                (p[0] - want).abs() < 4.0 * e + 1e-3,
                "{} vs {want} ({e})",
                p[0]
            );
            assert!(*e > 0.0 && *e < 0.02);
        }
        // With the cone: numerical integration of the closed form.
        let theta: f64 = 30.0;
        let cm = theta.to_radians().cos();
        let (nx, nc) = (2000, 400);
        let mut want = 0.0;
        for i in 0..nx {
            let x = (i as f64 + 0.5) / nx as f64 * 20.0;
            let mut light = 0.0;
            for j in 0..nc {
                let c = 1.0 - (j as f64 + 0.5) / nc as f64 * (1.0 - cm);
                // Distance to the cube's top face along a direction at cos c; through a side
                // face when the lateral travel exceeds the 10 units to it (pixel near x=y=0).
                let along = (x / c).min(10.0 / (1.0 - c * c).max(1e-12).sqrt());
                light += (-s * along).exp();
            }
            light /= nc as f64;
            want += s * (-s * x).exp() * light * (20.0 / nx as f64);
        }
        let dos = render(
            &rv,
            None,
            &view,
            &RefSettings {
                theta_deg: Some(theta),
                spp: 4000,
                seed: 2,
                vicinity_range: None,
            },
        );
        // The four central pixels (near the axis; the side-face bound uses 10 units).
        let mean: f64 = dos.rgb.iter().map(|p| p[0]).sum::<f64>() / 16.0;
        let se = dos.stderr.iter().cloned().fold(0.0, f64::max) / 4.0;
        assert!(
            (mean - want).abs() < 4.0 * se + 2e-3,
            "{mean} vs {want} (se {se})"
        );
        assert!(mean < (1.0 - (-s * 20.0f64).exp()) - 0.1);
    }
}
