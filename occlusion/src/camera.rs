//! The camera and its conventions, derived once here and tested (the renderer's passes, the CPU
//! references and the vicinity radius all go through this module).
//!
//! * World: right-handed; `up` is a hint, re-orthogonalised against the viewing direction.
//! * View space: right-handed, the camera looks down -z (`view_z < 0` in front of it).
//! * Clip and NDC as wgpu expects: x right and y up in [-1, 1], depth z in [0, 1] (0 on the near
//!   plane, 1 on the far plane). Perspective: `z_clip = r z_view + r n`, `w_clip = -z_view`
//!   with `r = f / (n - f)`; orthographic: `z_ndc = (z_view + n) / (n - f)`.
//! * Textures and pixels: x right, y **down**, pixel centres at half-integers, so pixel
//!   `(px, py)` of a `w x h` image has NDC `x = 2 (px + 0.5) / w - 1`,
//!   `y = 1 - 2 (py + 0.5) / h`.
//! * Orbit: azimuth 0 looks along +y, azimuth 90 along +x, elevation 90 looks down from +z (the
//!   convention of `umbra iso`'s camera, `iso_reference::OrbitCamera`); the distance is in
//!   multiples of the bounding-sphere radius.
//! * Near and far planes follow the scene: the bounding sphere seen from the eye, with the near
//!   plane clamped to a small fraction of the far one so depth precision stays usable.
//! * Vicinity occlusion's sampling radius in texture space: Schott et al. (IEEE TVCG), section
//!   3.2.5, eq. 4-5 give `R_c = T P (r, r, z, 1)` and `R_t = (x_t, y_t) / w_t`. As printed, the
//!   scale-and-bias matrix `T` also adds its 0.5 offset, so the result is a texture position,
//!   not a radius. Derivation of the radius: a view-space offset `(r, r)` at depth `z` moves clip
//!   x by `P00 r` and y by `P11 r`; under perspective `w = -z = |z|`, so NDC moves by
//!   `P00 r / |z|`, and texture coordinates (NDC scaled by 0.5) by
//!   `R_t = 0.5 (P00, P11) r / |z|`; under orthographic projection `w = 1` and
//!   `R_t = 0.5 (P00, P11) r`. `P` is the projection matrix; texture units span [0, 1] across
//!   the image ([`Camera::texture_radius`], tested against the projected size).
//! * Stereo (Everts et al. §3.7 leaves it unspecified): two off-axis eyes, no toe-in (it
//!   gives vertical parallax). Eye `k` sits `o_k = -e/2` (left) or `+e/2` (right) along the
//!   camera's right axis and looks parallel to the centre camera; its frustum is sheared so
//!   that the convergence plane, at view distance `c`, projects where the centre camera puts
//!   it: `x_eye = x_view - (o_k / c) z_view` before the projection, i.e. `P[2][0] =
//!   -P00 o_k / c` ([`Camera::skew`] = `o_k / c`). Under perspective this is the usual
//!   asymmetric frustum (near-plane shift `o_k n / c`); under orthographic projection it is
//!   the parallel analogue, an oblique projection with the same shear. A point at view
//!   distance `d` then lands `P00 e (1/c - 1/d)` apart in NDC between the eyes (perspective;
//!   `P00 e (d - c) / c` orthographic): zero on the convergence plane, positive (right eye
//!   to the right, behind the screen) beyond it ([`Camera::stereo_eye`], tested).

use glam::{DMat4, DVec3, DVec4};

/// How view space maps to clip space.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Projection {
    /// Vertical field of view in degrees (0, 180).
    Perspective { fov_y_deg: f64 },
    /// Height of the view volume in world units.
    Orthographic { height: f64 },
}

/// A camera with its clipping range.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    pub eye: DVec3,
    pub target: DVec3,
    pub up: DVec3,
    pub projection: Projection,
    pub near: f64,
    pub far: f64,
    /// Off-axis shear of a stereo eye (module doc): view-space x is offset by
    /// `-skew * z_view` before the projection; 0 for a mono camera.
    pub skew: f64,
}

/// Near and far distances that enclose the sphere around `bounds` seen from `eye` along `dir`
/// (unit); the near plane is at least `far / 1e4` away.
pub fn near_far(bounds: [DVec3; 2], eye: DVec3, dir: DVec3) -> (f64, f64) {
    let centre = (bounds[0] + bounds[1]) * 0.5;
    let radius = ((bounds[1] - bounds[0]) * 0.5).length().max(1e-9);
    let d = (centre - eye).dot(dir);
    let far = (d + radius * 1.01).max(radius * 1e-3);
    let near = (d - radius * 1.01).max(far * 1e-4);
    (near, far)
}

impl Camera {
    /// A camera looking from `eye` at `target`, its clipping range fitted to `bounds`.
    /// Errors when the eye is on the target or `up` is parallel to the viewing direction.
    pub fn look_at(
        eye: DVec3,
        target: DVec3,
        up: DVec3,
        projection: Projection,
        bounds: [DVec3; 2],
    ) -> Result<Camera, String> {
        let dir = target - eye;
        if dir.length().is_nan() || dir.length() <= 1e-12 || !eye.is_finite() || !target.is_finite()
        {
            return Err(format!(
                "camera: eye {eye} and target {target} must differ and be finite"
            ));
        }
        let dir = dir.normalize();
        if dir.cross(up).length() < 1e-9 * up.length().max(1e-300) || !up.is_finite() {
            return Err(format!(
                "camera: up {up} is zero or parallel to the viewing direction"
            ));
        }
        match projection {
            Projection::Perspective { fov_y_deg } if !(fov_y_deg > 0.0 && fov_y_deg < 180.0) => {
                return Err(format!(
                    "camera: field of view {fov_y_deg} degrees is not in (0, 180)"
                ))
            }
            Projection::Orthographic { height } if !(height > 0.0 && height.is_finite()) => {
                return Err(format!(
                    "camera: orthographic height {height} is not positive"
                ))
            }
            _ => {}
        }
        let (near, far) = near_far(bounds, eye, dir);
        Ok(Camera {
            eye,
            target,
            up,
            projection,
            near,
            far,
            skew: 0.0,
        })
    }

    /// Orbits the centre of `bounds` (see the module doc for the angles); `distance` is in
    /// bounding-sphere radii (at least 1.01). The perspective field of view is `fov_y_deg`;
    /// an orthographic camera gets a view height that fits the sphere.
    pub fn orbit(
        bounds: [DVec3; 2],
        azimuth_deg: f64,
        elevation_deg: f64,
        distance: f64,
        perspective_fov_y_deg: Option<f64>,
    ) -> Camera {
        let centre = (bounds[0] + bounds[1]) * 0.5;
        let radius = ((bounds[1] - bounds[0]) * 0.5).length().max(1e-9);
        let (az, el) = (azimuth_deg.to_radians(), elevation_deg.to_radians());
        let forward = DVec3::new(az.sin() * el.cos(), az.cos() * el.cos(), -el.sin()).normalize();
        let k = distance.max(1.01);
        let eye = centre - forward * (k * radius);
        let up = if forward.cross(DVec3::Z).length() < 1e-6 {
            DVec3::Y
        } else {
            DVec3::Z
        };
        let projection = match perspective_fov_y_deg {
            Some(f) => Projection::Perspective {
                fov_y_deg: f.clamp(1e-3, 179.0),
            },
            None => Projection::Orthographic {
                height: 2.1 * radius,
            },
        };
        let (near, far) = near_far(bounds, eye, forward);
        Camera {
            eye,
            target: centre,
            up,
            projection,
            near,
            far,
            skew: 0.0,
        }
    }

    /// The stereo eye `offset` world units along the camera's right axis (negative: the left
    /// eye), converging at view distance `convergence` (> 0): eye and target moved by the
    /// offset, the frustum sheared (module doc). Near and far stay.
    pub fn stereo_eye(&self, offset: f64, convergence: f64) -> Camera {
        let right = self.forward().cross(self.up).normalize();
        Camera {
            eye: self.eye + right * offset,
            target: self.target + right * offset,
            skew: self.skew + offset / convergence.max(1e-12),
            ..*self
        }
    }

    /// Unit viewing direction.
    pub fn forward(&self) -> DVec3 {
        (self.target - self.eye).normalize()
    }

    /// World to view space (right-handed, looking down -z): rows `s`, `u`, `-f` with
    /// `f` the viewing direction, `s = f x up`, `u = s x f`.
    pub fn view(&self) -> DMat4 {
        let f = self.forward();
        let s = f.cross(self.up).normalize();
        let u = s.cross(f);
        DMat4::from_cols(
            DVec4::new(s.x, u.x, -f.x, 0.0),
            DVec4::new(s.y, u.y, -f.y, 0.0),
            DVec4::new(s.z, u.z, -f.z, 0.0),
            DVec4::new(-s.dot(self.eye), -u.dot(self.eye), f.dot(self.eye), 1.0),
        )
    }

    /// View to clip space for an image of `aspect` = width / height (wgpu depth range).
    pub fn projection_matrix(&self, aspect: f64) -> DMat4 {
        let (n, f) = (self.near, self.far);
        // Depth z_ndc = 0 at view z = -near and 1 at -far.
        let r = f / (n - f);
        match self.projection {
            Projection::Perspective { fov_y_deg } => {
                let h = 1.0 / (0.5 * fov_y_deg.to_radians()).tan();
                DMat4::from_cols(
                    DVec4::new(h / aspect, 0.0, 0.0, 0.0),
                    DVec4::new(0.0, h, 0.0, 0.0),
                    DVec4::new(-h / aspect * self.skew, 0.0, r, -1.0),
                    DVec4::new(0.0, 0.0, r * n, 0.0),
                )
            }
            Projection::Orthographic { height } => {
                let q = 1.0 / (n - f);
                let p00 = 2.0 / (height * aspect);
                DMat4::from_cols(
                    DVec4::new(p00, 0.0, 0.0, 0.0),
                    DVec4::new(0.0, 2.0 / height, 0.0, 0.0),
                    DVec4::new(-p00 * self.skew, 0.0, q, 0.0),
                    DVec4::new(0.0, 0.0, q * n, 1.0),
                )
            }
        }
    }

    /// World to clip space.
    pub fn view_projection(&self, aspect: f64) -> DMat4 {
        self.projection_matrix(aspect) * self.view()
    }

    /// Pixel coordinates (x right, y down, continuous: pixel centres at half-integers) and
    /// depth in [0, 1] of a world point, or `None` behind the eye.
    pub fn to_pixel(&self, p: DVec3, width: usize, height: usize) -> Option<(f64, f64, f64)> {
        let aspect = width as f64 / height.max(1) as f64;
        let c = self.view_projection(aspect) * DVec4::from((p, 1.0));
        let (x, y) = Camera::clip_to_pixel(c, width as f64, height as f64)?;
        Some((x, y, c.z / c.w))
    }

    /// Pixel coordinates, as [`Camera::to_pixel`] gives them, of a point in clip space (for a
    /// caller that has its clip coordinates already), or `None` behind the eye (`w <= 0`, or
    /// not a number).
    pub fn clip_to_pixel(c: DVec4, width: f64, height: f64) -> Option<(f64, f64)> {
        if c.w.is_nan() || c.w <= 0.0 {
            return None;
        }
        Some((
            (c.x / c.w + 1.0) * 0.5 * width,
            (1.0 - c.y / c.w) * 0.5 * height,
        ))
    }

    /// The ray through the centre of pixel `(px, py)`: origin (on the near plane) and unit
    /// direction, consistent with [`Camera::to_pixel`].
    pub fn ray(&self, px: f64, py: f64, width: usize, height: usize) -> (DVec3, DVec3) {
        let aspect = width as f64 / height.max(1) as f64;
        let inv = self.view_projection(aspect).inverse();
        let x = 2.0 * (px + 0.5) / width as f64 - 1.0;
        let y = 1.0 - 2.0 * (py + 0.5) / height as f64;
        let un = |z: f64| {
            let v = inv * DVec4::new(x, y, z, 1.0);
            v.truncate() / v.w
        };
        let (a, b) = (un(0.0), un(1.0));
        (a, (b - a).normalize())
    }

    /// Texture-space radius (x, y; texture units span [0, 1] across the image) of a world
    /// radius `r` at view-space depth `view_z` (negative in front of the camera).
    pub fn texture_radius(&self, r: f64, view_z: f64, aspect: f64) -> (f64, f64) {
        let p = self.projection_matrix(aspect);
        let (p00, p11) = (p.x_axis.x, p.y_axis.y);
        match self.projection {
            Projection::Perspective { .. } => {
                let z = view_z.abs().max(1e-12);
                (0.5 * p00 * r / z, 0.5 * p11 * r / z)
            }
            Projection::Orthographic { .. } => (0.5 * p00 * r, 0.5 * p11 * r),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn bounds() -> [DVec3; 2] {
        [DVec3::new(-1.0, -2.0, -0.5), DVec3::new(3.0, 2.0, 1.5)]
    }

    fn cameras() -> Vec<Camera> {
        let b = bounds();
        vec![
            Camera::orbit(b, 30.0, 20.0, 3.0, Some(40.0)),
            Camera::orbit(b, -120.0, 60.0, 2.0, None),
            Camera::orbit(b, 0.0, 90.0, 4.0, Some(25.0)),
            Camera::look_at(
                DVec3::new(10.0, -3.0, 2.0),
                DVec3::new(1.0, 0.0, 0.5),
                DVec3::Z,
                Projection::Perspective { fov_y_deg: 60.0 },
                b,
            )
            .unwrap(),
        ]
    }

    #[test]
    fn the_target_is_the_image_centre_and_world_up_is_pixel_up() {
        for c in cameras() {
            let (w, h) = (640, 480);
            let (x, y, z) = c.to_pixel(c.target, w, h).unwrap();
            assert!(
                (x - 320.0).abs() < 1e-6 && (y - 240.0).abs() < 1e-6,
                "{x} {y}"
            );
            assert!(z > 0.0 && z < 1.0);
            // A point above the target (along the camera's up) lands above: smaller y.
            let right = c.forward().cross(c.up).normalize();
            let up = right.cross(c.forward());
            let (_, y_up, _) = c.to_pixel(c.target + up * 0.1, w, h).unwrap();
            assert!(y_up < y, "{y_up} vs {y}");
            let (x_r, _, _) = c.to_pixel(c.target + right * 0.1, w, h).unwrap();
            assert!(x_r > x);
        }
    }

    #[test]
    fn rays_and_projection_agree_and_depth_spans_near_to_far() {
        for c in cameras() {
            let (w, h) = (200, 100);
            for (px, py) in [(0.0, 0.0), (199.0, 0.0), (57.0, 83.0), (100.0, 50.0)] {
                let (o, d) = c.ray(px, py, w, h);
                for t in [0.0, 0.5, 3.0] {
                    let (x, y, _) = c.to_pixel(o + d * t, w, h).unwrap();
                    assert!((x - (px + 0.5)).abs() < 1e-6 && (y - (py + 0.5)).abs() < 1e-6);
                }
            }
            let f = c.forward();
            let (_, _, zn) = c.to_pixel(c.eye + f * c.near, w, h).unwrap();
            let (_, _, zf) = c.to_pixel(c.eye + f * c.far, w, h).unwrap();
            assert!(zn.abs() < 1e-9 && (zf - 1.0).abs() < 1e-9, "{zn} {zf}");
            // Every corner of the bounds lies between the planes.
            let b = bounds();
            for i in 0..8 {
                let p = DVec3::new(
                    if i & 1 == 0 { b[0].x } else { b[1].x },
                    if i & 2 == 0 { b[0].y } else { b[1].y },
                    if i & 4 == 0 { b[0].z } else { b[1].z },
                );
                let (_, _, z) = c.to_pixel(p, w, h).unwrap();
                assert!((0.0..=1.0).contains(&z), "corner {p}: depth {z}");
            }
        }
    }

    #[test]
    fn texture_radius_matches_the_projected_size() {
        for c in cameras() {
            let (w, h) = (400, 300);
            let aspect = w as f64 / h as f64;
            let right = c.forward().cross(c.up).normalize();
            let up = right.cross(c.forward());
            for t in [0.3, 0.6] {
                let p = c.eye + c.forward() * (c.near + t * (c.far - c.near));
                let r = 0.01 * (c.far - c.near);
                let view_z = (c.view() * DVec4::from((p, 1.0))).z;
                let (rx, ry) = c.texture_radius(r, view_z, aspect);
                let (x0, y0, _) = c.to_pixel(p, w, h).unwrap();
                let (x1, _, _) = c.to_pixel(p + right * r, w, h).unwrap();
                let (_, y1, _) = c.to_pixel(p + up * r, w, h).unwrap();
                // Small radii: the projected offset over the image size (texture units).
                assert!(((x1 - x0) / w as f64 - rx).abs() < 1e-3 * rx, "{c:?}");
                assert!(((y0 - y1) / h as f64 - ry).abs() < 1e-3 * ry);
            }
        }
    }

    #[test]
    fn stereo_eyes_converge_on_their_plane_and_show_the_predicted_disparity() {
        for c in cameras() {
            let (w, h) = (400, 300);
            let aspect = w as f64 / h as f64;
            let conv = 0.5 * (c.near + c.far);
            let e = 0.05 * conv;
            let (l, r) = (c.stereo_eye(-0.5 * e, conv), c.stereo_eye(0.5 * e, conv));
            let p00 = c.projection_matrix(aspect).x_axis.x;
            let f = c.forward();
            let right = f.cross(c.up).normalize();
            let up = right.cross(f);
            for d in [0.6 * conv, conv, 1.3 * conv] {
                // A point off the axis at view distance d.
                let p = c.eye + f * d + right * (0.03 * conv) + up * (0.02 * conv);
                let (xl, yl, zl) = l.to_pixel(p, w, h).unwrap();
                let (xr, yr, zr) = r.to_pixel(p, w, h).unwrap();
                // No vertical parallax, the same depth in both eyes.
                assert!((yl - yr).abs() < 1e-6 && (zl - zr).abs() < 1e-9);
                let want_ndc = match c.projection {
                    Projection::Perspective { .. } => p00 * e * (1.0 / conv - 1.0 / d),
                    Projection::Orthographic { .. } => p00 * e * (d - conv) / conv,
                };
                let got_ndc = (xr - xl) / (0.5 * w as f64);
                assert!(
                    (got_ndc - want_ndc).abs() < 1e-9,
                    "{c:?} d {d}: {got_ndc} vs {want_ndc}"
                );
                // On the convergence plane both eyes see it where the centre camera does.
                if d == conv {
                    let (x, y, _) = c.to_pixel(p, w, h).unwrap();
                    assert!((x - xl).abs() < 1e-6 && (y - yl).abs() < 1e-6);
                }
            }
            // Rays and projection still agree for a sheared eye.
            let (o, dir) = r.ray(37.0, 211.0, w, h);
            let (x, y, _) = r.to_pixel(o + dir * conv, w, h).unwrap();
            assert!((x - 37.5).abs() < 1e-6 && (y - 211.5).abs() < 1e-6);
        }
    }

    #[test]
    fn bad_cameras_are_refused() {
        let b = bounds();
        let p = Projection::Perspective { fov_y_deg: 45.0 };
        assert!(Camera::look_at(DVec3::ONE, DVec3::ONE, DVec3::Z, p, b).is_err());
        assert!(Camera::look_at(DVec3::ZERO, DVec3::Z, DVec3::Z, p, b).is_err());
        assert!(Camera::look_at(
            DVec3::ZERO,
            DVec3::X,
            DVec3::Z,
            Projection::Perspective { fov_y_deg: 180.0 },
            b
        )
        .is_err());
        assert!(Camera::look_at(
            DVec3::ZERO,
            DVec3::X,
            DVec3::Z,
            Projection::Orthographic { height: 0.0 },
            b
        )
        .is_err());
        assert!(Camera::look_at(DVec3::NAN, DVec3::X, DVec3::Z, p, b).is_err());
    }
}
