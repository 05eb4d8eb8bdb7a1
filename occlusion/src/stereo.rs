//! Anaglyph stereo (Everts et al. 2009 §3.7: "red is the left eye"; their eye separation,
//! convergence and projection are unspecified). The eyes are the off-axis cameras of
//! [`crate::camera::Camera::stereo_eye`]; this module holds the defaults and the colour mix.
//!
//! * Convergence `c`: the view distance of the camera's target (the orbit's centre), so the
//!   data's middle sits on the screen plane; eye separation `e = c / 30`, the photographers'
//!   1/30 rule, which keeps the largest disparity within a few per cent of the image width for
//!   data spanning the near..far range.
//! * Colour: a grey (luminance) anaglyph: red = the left eye's luminance, green = blue = the
//!   right eye's, in linear light (Rec. 709 weights), so each eye sees one full image through
//!   red-cyan glasses whatever the data's colours (a colour anaglyph would drop the cyan
//!   parts of the left image). Alpha is the larger of the two.

use crate::camera::Camera;

/// Eye separation over convergence distance by default.
pub const SEPARATION_RATIO: f64 = 1.0 / 30.0;

/// The default convergence distance: the camera's target along its view direction.
pub fn default_convergence(camera: &Camera) -> f64 {
    (camera.target - camera.eye)
        .dot(camera.forward())
        .max(camera.near)
}

/// The left and right eyes of `camera` for `separation` and `convergence` (both > 0).
pub fn eyes(camera: &Camera, separation: f64, convergence: f64) -> [Camera; 2] {
    [
        camera.stereo_eye(-0.5 * separation, convergence),
        camera.stereo_eye(0.5 * separation, convergence),
    ]
}

/// Linear Rec. 709 luminance.
pub fn luminance(c: [f32; 4]) -> f32 {
    0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]
}

/// One pixel of the grey anaglyph of linear RGBA `left` and `right`.
pub fn anaglyph(left: [f32; 4], right: [f32; 4]) -> [f32; 4] {
    let (l, r) = (luminance(left), luminance(right));
    [l, r, r, left[3].max(right[3])]
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    #[test]
    fn red_is_the_left_eye_and_grey_stays_grey() {
        let white = [1.0, 1.0, 1.0, 1.0];
        let black = [0.0, 0.0, 0.0, 1.0];
        assert_eq!(anaglyph(white, black), [1.0, 0.0, 0.0, 1.0]);
        assert_eq!(anaglyph(black, white), [0.0, 1.0, 1.0, 1.0]);
        let g = [0.4, 0.4, 0.4, 0.5];
        let a = anaglyph(g, g);
        assert!(a.iter().take(3).all(|v| (v - 0.4).abs() < 1e-6) && a[3] == 0.5);
        // Pure red in the right eye is dark there: cyan glasses block it.
        assert!(anaglyph(black, [1.0, 0.0, 0.0, 1.0])[1] < 0.25);
    }

    #[test]
    fn the_default_eyes_straddle_the_camera_and_converge_on_its_target() {
        let b = [DVec3::splat(-1.0), DVec3::splat(1.0)];
        let c = Camera::orbit(b, 30.0, 20.0, 3.0, Some(40.0));
        let conv = default_convergence(&c);
        assert!((conv - (c.target - c.eye).length()).abs() < 1e-9);
        let [l, r] = eyes(&c, conv * SEPARATION_RATIO, conv);
        assert!(((l.eye + r.eye) * 0.5 - c.eye).length() < 1e-12);
        assert!(((r.eye - l.eye).length() - conv / 30.0).abs() < 1e-12);
        // The target projects to the image centre in both eyes.
        for e in [l, r] {
            let (x, y, _) = e.to_pixel(c.target, 200, 100).unwrap();
            assert!(
                (x - 100.0).abs() < 1e-6 && (y - 50.0).abs() < 1e-6,
                "{x} {y}"
            );
        }
    }
}
