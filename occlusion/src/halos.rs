//! Everts, Bekker, Roerdink and Isenberg, "Depth-Dependent Halos: Illustrative Rendering of
//! Dense Line Data" (IEEE TVCG 2009; `../shared/seeds/004_64bbe3ebc30d4f15.txt`): the maths
//! of the halos as pure functions, and the paper's index. The notes re-derive it
//! (`../shared/notes/lines-papers.md` §3).
//!
//! | paper | CPU (this module) | GPU | checked by |
//! |---|---|---|---|
//! | eq. 1, view-facing strips (the printed norm is a typo for the unit vector) | - | `shaders/gbuffer.wgsl::line_vertex` (`vs_line`, `vs_line_h`; screen-space offsets of `halo_width` line widths) | `engine/tests/lines_render.rs::strips_are_as_wide_as_asked_in_pixels_and_in_world_units` |
//! | eq. 2, core or rim by the distance from the strip's centre (an edge point is core, [`EDGE_TOLERANCE`]; with MSAA each sample decides, `vs_line_h`) | [`is_rim`] | `gbuffer.wgsl::halo_at` | `the_rim_starts_at_the_core_fraction`, `lines_render.rs::a_haloed_cores_edge_on_pixel_centres_is_drawn_evenly_along_the_line` |
//! | eq. 3, `d_new = d + d_max f(x)`, `f` linear, sqrt or square | [`displacement`], [`rim_depth`] | `halo_at`, `displacement`, `attachment_depth` | `displacements_map_0_1_onto_0_1` |
//! | Appendix A, eq. 4, the visible halo width against the depth gap (two cases' signs corrected) | [`halo_gap`] | - | `halo_gap_follows_the_corrected_appendix`, `engine/tests/lines_render.rs::a_halo_gap_follows_the_corrected_appendix_a` |
//! | §3.4 tapering, `u` non-linear over the end vertices | `tubes::lines::taper_u` | `vs_line` (`taper_t`, the mask on the whole strip) | `lines_render.rs::end_tapers_and_attribute_filters_shape_the_strip` |
//! | §3.4 depth cueing (formula unspecified: the core narrows linearly to `1 - depth_cue` at the far plane) | - | `halo_at` | `lines_render.rs::depth_cueing_narrows_far_cores` |
//! | §3.5 points: a screen-aligned square, circular mask, cone displacement (no CPU quadrupling) | `tubes::lines::LineSet::points`, `tubes::points` | `vs_line` (`points`), `clipped`, `halo_at` (`length(across)`) | `lines_render.rs::points_are_round_discs_of_their_world_size_and_their_halos_are_cones` |
//! | §3.6 attribute filtering with tapered cut ends | `scene::tube_sets::point_values` | `vs_line` (`filter_on`) | `end_tapers_and_attribute_filters_shape_the_strip` |
//! | §3.7 anaglyph stereo (parameters unspecified: off-axis eyes, red = left) | `camera::Camera::stereo_eye`, `stereo::anaglyph` | - (both eyes are whole frames, mixed on the CPU) | `camera::tests::stereo_eyes_converge_on_their_plane_and_show_the_predicted_disparity`, `scene/tests/stereo_render.rs` |
//! | §3.4 1-bit output | `scene::image_io::one_bit` | - | `scene/tests/print_render.rs` |
//! | §4.3 `w_strip` = 4-8 `w_line` (printed inverted) | `render` default `halo.width = 6` | | |
//! | outline rims (seed 002's dark rims, `style = "outline"`; not this paper): black ink, unlit | - | `gbuffer.wgsl::rim_color` (alpha `OUTLINE_ALPHA`), `composite.wgsl` (no highlight below alpha 0.95) | `lines_render.rs::an_outline_rim_is_black_under_the_head_light` |
//!
//! Strips end at their points: a segment's square cap holds the core only, half the core's
//! width beyond the point, and no rim (a rim there hid the next segment of a line bending away
//! in depth; `lines_render.rs::a_haloed_line_bending_away_in_depth_does_not_cut_itself_at_its_joints`).
//!
//! umbra displaces in *linear* view depth, `d_max` a fraction of the camera's clipping range
//! (fitted to the scene, so it is the same fraction of the scene's depth at any zoom), and
//! converts the result for the depth test (`frag_depth`) in every sub-pass alike; the paper
//! displaces the non-linear window depth, where a given `d_max` is a larger distance far away.
//! With a linear depth Appendix A is exact, which makes it a known answer.

/// Eq. 3's `f`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Displacement {
    Linear,
    Sqrt,
    Square,
}

/// `f(x)` for `x` in [0, 1] (clamped).
pub fn displacement(f: Displacement, x: f64) -> f64 {
    let x = x.clamp(0.0, 1.0);
    match f {
        Displacement::Linear => x,
        Displacement::Sqrt => x.sqrt(),
        Displacement::Square => x * x,
    }
}

/// `f^-1(y)` for `y` in [0, 1].
pub fn inverse_displacement(f: Displacement, y: f64) -> f64 {
    let y = y.clamp(0.0, 1.0);
    match f {
        Displacement::Linear => y,
        Displacement::Sqrt => y * y,
        Displacement::Square => y.sqrt(),
    }
}

/// How far (relatively) beyond the core's edge a point must be to be rim: a point on the edge
/// is core, so that the overlapping strips of a line's neighbouring segments, each rounding
/// its own interpolation, agree there (a 3-pixel line on the pixel grid came out dashed).
/// `gbuffer.wgsl::halo_at` uses the same factor.
pub const EDGE_TOLERANCE: f64 = 1e-3;

/// Eq. 2: whether the point `x` across the strip (0 at its centre, 1 at its edge) is in the
/// rim, for a strip `ratio = w_strip / w_line` times as wide as the line (a point within
/// [`EDGE_TOLERANCE`] of the core's edge is core).
pub fn is_rim(x: f64, ratio: f64) -> bool {
    x.abs() > (1.0 + EDGE_TOLERANCE) / ratio
}

/// Eq. 3: the depth of a rim point `x` across the strip of a line at depth `d`.
pub fn rim_depth(d: f64, x: f64, d_max: f64, f: Displacement) -> f64 {
    d + d_max * displacement(f, x.abs())
}

/// Appendix A, corrected: the visible gap on each side of a front line's core where it crosses
/// a line `dz >= 0` behind it (in the depth `d_max` is in), for a line `w_line` wide in a strip
/// `w_strip` wide (any one length unit): the back line is hidden where the rim lies in front of
/// it, `d_max f(x) < dz`, so the gap is
/// `clamp((w_strip / 2) f^-1(min(1, dz / d_max)) - w_line / 2, 0, (w_strip - w_line) / 2)`:
/// 0 up to `dz = d_max f(w_line / w_strip)`, the full rim from `dz = d_max` on. (The paper
/// prints the second and third cases with the opposite sign.) `d_max = 0` gives the full rim for
/// any `dz > 0`.
pub fn halo_gap(dz: f64, w_line: f64, w_strip: f64, d_max: f64, f: Displacement) -> f64 {
    let full = 0.5 * (w_strip - w_line);
    if dz <= 0.0 {
        return 0.0;
    }
    if d_max <= 0.0 {
        return full;
    }
    (0.5 * w_strip * inverse_displacement(f, (dz / d_max).min(1.0)) - 0.5 * w_line).clamp(0.0, full)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn displacements_map_0_1_onto_0_1() {
        for f in [
            Displacement::Linear,
            Displacement::Sqrt,
            Displacement::Square,
        ] {
            assert_eq!(displacement(f, 0.0), 0.0);
            assert_eq!(displacement(f, 1.0), 1.0);
            for x in [0.1, 0.5, 0.9] {
                assert!((inverse_displacement(f, displacement(f, x)) - x).abs() < 1e-12);
            }
        }
        assert!((displacement(Displacement::Sqrt, 0.25) - 0.5).abs() < 1e-12);
        assert!((rim_depth(2.0, -0.5, 0.1, Displacement::Square) - 2.025).abs() < 1e-12);
    }

    #[test]
    fn the_rim_starts_at_the_core_fraction() {
        assert!(!is_rim(0.16, 6.0));
        assert!(is_rim(0.17, 6.0));
        assert!(is_rim(-0.5, 6.0));
        // The edge itself, and rounding about it, is core.
        let edge = 1.0 / 6.0;
        assert!(!is_rim(edge, 6.0) && !is_rim(edge * (1.0 + 1e-6), 6.0));
        assert!(is_rim(edge * (1.0 + 2.0 * EDGE_TOLERANCE), 6.0));
    }

    #[test]
    fn halo_gap_follows_the_corrected_appendix() {
        let (wl, ws, dm) = (2.0, 12.0, 0.01);
        let f = Displacement::Linear;
        // Case 1: no gap up to w_line d_max / w_strip.
        assert_eq!(halo_gap(0.0, wl, ws, dm, f), 0.0);
        assert_eq!(halo_gap(wl * dm / ws, wl, ws, dm, f), 0.0);
        // Case 2: (w_strip dz / d_max - w_line) / 2, positive (the paper prints its negative).
        let dz = 0.005;
        assert!((halo_gap(dz, wl, ws, dm, f) - 0.5 * (ws * dz / dm - wl)).abs() < 1e-12);
        // Case 3: the full rim (w_strip - w_line) / 2 from d_max on.
        assert_eq!(halo_gap(dm, wl, ws, dm, f), 5.0);
        assert_eq!(halo_gap(1.0, wl, ws, dm, f), 5.0);
        // Continuous at the breakpoints; monotone between.
        let mut last = 0.0;
        for k in 0..=100 {
            let g = halo_gap(k as f64 * dm / 100.0, wl, ws, dm, f);
            assert!(g >= last - 1e-12);
            last = g;
        }
        // sqrt pushes the rim back faster (smaller gaps), square slower (larger).
        let (l, s, q) = (
            halo_gap(dz, wl, ws, dm, Displacement::Linear),
            halo_gap(dz, wl, ws, dm, Displacement::Sqrt),
            halo_gap(dz, wl, ws, dm, Displacement::Square),
        );
        assert!(s < l && l < q, "{s} {l} {q}");
        // d_max = 0: every line its full rim.
        assert_eq!(halo_gap(1e-9, wl, ws, 0.0, f), 5.0);
    }
}
