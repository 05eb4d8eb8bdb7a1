//! Illuminated lines (Zöckler, Stalling and Hege, "Interactive visualization of 3D-vector
//! fields using illuminated stream lines", IEEE Visualization 1996; the pseudo-tube profile
//! after Mallo, Peikert, Sigg and Sadlo, "Illuminated lines revisited", IEEE Visualization
//! 2005, as MRtrix's pseudotubes draw it): the CPU side of how umbra's line sets are shaded and
//! sized, the twin of `shaders/gbuffer.wgsl::vs_line` and the G-buffer's fragment entries.
//!
//! | paper | CPU (this module) | GPU (`shaders/gbuffer.wgsl`) | checked by |
//! |---|---|---|---|
//! | Zöckler §3: a line has a circle of normals; the one in the plane of the tangent and the view, `N = (T x C) x T` | [`view_facing_normal`] | `vs_line` (`normal`) | unit tests below; `engine/tests/lines_render.rs` (shade 1.3 = ambient + diffuse + specular under the head light, on and off the image centre) |
//! | Mallo §4 / pseudotubes: the normal turned across the width, `N' = N sqrt(1 - u^2) + B u` | [`cylinder_normal`] | `front_values` (`bend`) | unit tests; `lines_render.rs` (bright middle, dark edges) |
//! | the pseudo-tube's depth: nearer by `r sqrt(1 - u^2)` | [`cylinder_depth`] | `surface_depth` (`bulge`) | unit tests; `lines_render.rs` (nearer in the middle) |
//! | the strip's half width on screen (pixels, or a world width projected; at least half a pixel) | [`half_width_px`] | `vs_line` (`hw`) | unit tests; `lines_render.rs` (1, 4, 9 px; 3 world units = 8 px) |
//!
//! What umbra decides: C is the direction to the eye - from the point under perspective, the
//! reverse viewing direction under orthographic projection; where T and C are parallel (a
//! segment along the view ray) the normal is C itself, so no NaN arises. The strip's depth
//! test sees the flat strip; only the G-buffer's linear depth bulges (what the slices and the
//! surface-AO terms read).

use glam::DVec3;

/// The view-facing normal `(T x C) x T` of a line with unit tangent `t` seen from the unit
/// direction `to_eye`; `to_eye` itself where they are parallel.
pub fn view_facing_normal(t: DVec3, to_eye: DVec3) -> DVec3 {
    let s = t.cross(to_eye);
    if s.length_squared() > 1e-12 {
        s.cross(t).normalize()
    } else {
        to_eye
    }
}

/// The side vector `B = T x C` (unit), or zero where `t` and `to_eye` are parallel.
pub fn side_vector(t: DVec3, to_eye: DVec3) -> DVec3 {
    t.cross(to_eye).normalize_or_zero()
}

/// The pseudo-tube normal at `u` in [-1, 1] across the width: `n sqrt(1 - u^2) + b u`.
pub fn cylinder_normal(n: DVec3, b: DVec3, u: f64) -> DVec3 {
    let u = u.clamp(-1.0, 1.0);
    (n * (1.0 - u * u).sqrt() + b * u).normalize()
}

/// The pseudo-tube's linear depth at `u` across the width of a line at depth `z` and world
/// half width `r`: `z - r sqrt(1 - u^2)`.
pub fn cylinder_depth(z: f64, r: f64, u: f64) -> f64 {
    let u = u.clamp(-1.0, 1.0);
    z - r * (1.0 - u * u).sqrt()
}

/// The strip's half width in pixels: `half` pixels, or (`world`) `half` world units at clip
/// w `w` under a projection with `P11` on an image `height` pixels tall
/// (`half 0.5 P11 height / w`); never below half a pixel, so a line stays one pixel wide.
pub fn half_width_px(half: f64, world: bool, p11: f64, height: f64, w: f64) -> f64 {
    let hw = if world {
        half * 0.5 * p11 * height / w.max(1e-6)
    } else {
        half
    };
    hw.max(0.5)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_view_facing_normal_is_perpendicular_to_the_line_and_faces_the_eye() {
        let t = DVec3::new(1.0, 1.0, 0.0).normalize();
        for c in [DVec3::Z, DVec3::new(0.3, -0.2, 1.0).normalize()] {
            let n = view_facing_normal(t, c);
            assert!((n.length() - 1.0).abs() < 1e-12);
            assert!(n.dot(t).abs() < 1e-12, "perpendicular to the tangent");
            assert!(n.dot(c) > 0.0, "towards the eye");
            // In the plane of T and C: no component along T x C.
            assert!(n.dot(t.cross(c)).abs() < 1e-12);
        }
        // A line seen end on: the normal is the direction to the eye, not NaN.
        assert_eq!(view_facing_normal(DVec3::Z, DVec3::Z), DVec3::Z);
        // Perpendicular to the view: the normal is the view direction (full n.l).
        let n = view_facing_normal(DVec3::X, DVec3::Z);
        assert!((n - DVec3::Z).length() < 1e-12);
    }

    #[test]
    fn the_pseudo_tube_turns_its_normal_and_bulges_across_the_width() {
        let (n, b) = (DVec3::Z, side_vector(DVec3::X, DVec3::Z));
        assert!((b.length() - 1.0).abs() < 1e-12 && b.dot(n).abs() < 1e-12);
        assert!((cylinder_normal(n, b, 0.0) - n).length() < 1e-12);
        assert!((cylinder_normal(n, b, 1.0) - b).length() < 1e-12);
        assert!((cylinder_normal(n, b, -1.0) + b).length() < 1e-12);
        // A circle's normal: at u = sin(a) it leans by a.
        let a = 0.5f64;
        assert!((cylinder_normal(n, b, a.sin()).dot(n) - a.cos()).abs() < 1e-12);
        assert_eq!(cylinder_depth(10.0, 0.5, 0.0), 9.5);
        assert_eq!(cylinder_depth(10.0, 0.5, 1.0), 10.0);
        assert_eq!(
            cylinder_depth(10.0, 0.5, 7.0),
            10.0,
            "clamped beyond the edge"
        );
        assert_eq!(side_vector(DVec3::Z, DVec3::Z), DVec3::ZERO);
    }

    #[test]
    fn half_widths_are_pixels_or_projected_world_units_and_at_least_half_a_pixel() {
        assert_eq!(half_width_px(2.0, false, 1.0, 64.0, 40.0), 2.0);
        assert_eq!(half_width_px(0.1, false, 1.0, 64.0, 40.0), 0.5);
        // Orthographic, 24 units over 64 pixels: P11 = 2 / 24, w = 1; 1.5 units = 4 pixels.
        assert!((half_width_px(1.5, true, 2.0 / 24.0, 64.0, 1.0) - 4.0).abs() < 1e-12);
        // Perspective: twice as far, half as wide.
        let near = half_width_px(1.0, true, 3.7, 64.0, 10.0);
        let far = half_width_px(1.0, true, 3.7, 64.0, 20.0);
        assert!((near / far - 2.0).abs() < 1e-12);
        assert!(half_width_px(1.0, true, 3.7, 64.0, -5.0).is_finite());
    }
}
