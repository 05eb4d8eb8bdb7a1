//! Line sets: streamlines drawn as lines (screen-facing strips the renderer builds on the GPU
//! from the points), the cheap path for 10^5-10^6 streamlines. The model holds each point once
//! (f32 position relative to an f64 origin, an RGBA8 colour) and one index per segment: 20
//! bytes a point, with no vertex duplicated on the CPU.

use crate::tube_mesh::{map_color, ColorMode};
use crate::Streamlines;
use glam::{DVec3, Vec3};

/// How wide a line set's lines are drawn.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LineWidth {
    /// Constant on screen (LineAO's lines), at least one pixel.
    Pixels(f64),
    /// Constant in the world (shrinks with distance), at least one pixel.
    World(f64),
}

/// Lines as the renderer draws them.
#[derive(Clone, Debug, PartialEq)]
pub struct LineSet {
    /// The points' origin (their positions are f32 relative to it, for precision far from the
    /// world origin).
    pub origin: DVec3,
    pub positions: Vec<Vec3>,
    /// RGBA8 per point (alpha 255).
    pub colors: Vec<[u8; 4]>,
    /// The first point of each segment (a segment joins points `i` and `i + 1` of one line).
    pub segments: Vec<u32>,
    pub width: LineWidth,
    /// Shade and depth across the width as a cylinder (pseudo-tubes) instead of a flat strip.
    pub cylinder: bool,
    /// The world radius the lines stand for where they shadow the volume (0: they cast none).
    pub proxy_radius: f32,
    /// A time per point (empty: none), for trails.
    pub times: Vec<f32>,
    /// The tapered trail drawn of each line around a time (needs `times`).
    pub trail: Option<Trail>,
    /// Depth-dependent halos (Everts et al. 2009).
    pub halo: Option<Halo>,
    /// End tapers (seed 004 §3.4): each point's `u` along its line ([`taper_u`]; empty: none)
    /// and the taper's extent `t` in u.
    pub taper_u: Vec<f32>,
    pub taper_t: f32,
    /// An attribute filter (seed 004 §3.6): a value per point (empty: none); only where it is
    /// at least `min` is drawn, the cut ends narrowing to a point over `taper` of it.
    pub filter: Vec<f32>,
    pub filter_min: f32,
    pub filter_taper: f32,
    /// A point cloud (Everts et al. §3.5): each entry of `segments` is a point drawn as a disc
    /// of diameter `width` facing the viewer (see [`LineSet::points`]).
    pub points: bool,
}

/// Seed 004 §3.4's non-linear `u` along a line of `n` points: the first `vertices` points map
/// evenly onto `[0, t]`, the last `vertices` onto `[1 - t, 1]`, those between evenly onto
/// `[t, 1 - t]`, so the taper spans the same vertices whatever the line's length; a line too
/// short for both (`n - 1 < 2 vertices`) gets `u` even over [0, 1]. The width mask is then
/// `clamp(min(u, 1 - u) / t, 0, 1)`.
pub fn taper_u(n: usize, vertices: usize, t: f32) -> Vec<f32> {
    if n < 2 {
        return vec![0.5; n];
    }
    let last = n - 1;
    let v = vertices.max(1);
    (0..n)
        .map(|k| {
            if last < 2 * v {
                k as f32 / last as f32
            } else if k <= v {
                t * k as f32 / v as f32
            } else if k >= last - v {
                1.0 - t * (last - k) as f32 / v as f32
            } else {
                t + (1.0 - 2.0 * t) * (k - v) as f32 / (last - 2 * v) as f32
            }
        })
        .collect()
}

/// How a halo's rim is pushed back in depth (eq. 3's `f`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Displacement {
    Linear,
    Sqrt,
    Square,
}

/// Depth-dependent halos (Everts et al. 2009, §3.3): each line drawn as a strip `width` times
/// the line's width, its centre the line and the rest its halo, whose depth is pushed back by
/// `d_max f(x)` (x from the strip's centre, 1 at its edge; `d_max` a fraction of the camera's
/// clipping range) so that it hides lines behind it but not lines beside it at about its depth.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Halo {
    /// No displacement: every line gets its full rim (seed 004 Fig. 2c).
    pub uniform: bool,
    /// Dark rims that belong to the line (seed 002), instead of gaps (seed 004).
    pub outline: bool,
    /// The strip's width over the line's, > 1.
    pub width: f32,
    pub d_max: f32,
    pub displacement: Displacement,
    /// The core narrows with depth to `1 - depth_cue` of itself at the far plane.
    pub depth_cue: f32,
}

/// A tapered trail (Köhler et al. 2011, §4.1): of each line only the part whose time lies in
/// `[now - back, now + forward]` is drawn, full width from the particle (`now`) out to the
/// fraction `start` of the way to either end of the window, then narrowing linearly to
/// `min_width` times the width at the ends (times in the attribute's units).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Trail {
    pub now: f32,
    pub back: f32,
    pub forward: f32,
    pub start: f32,
    pub min_width: f32,
}

impl Trail {
    /// The width factor at time `t`: 1 within `start` of the particle, falling linearly to
    /// `min_width` at the window's ends; 0 outside the window (not drawn). NaN gives 0.
    pub fn width_factor(&self, t: f32) -> f32 {
        let (d, span) = if t >= self.now {
            (t - self.now, self.forward)
        } else {
            (self.now - t, self.back)
        };
        // Outside the window, or a NaN time.
        if d.is_nan() || d > span {
            return 0.0;
        }
        let u = if span > 0.0 { d / span } else { 0.0 };
        if u <= self.start {
            1.0
        } else {
            1.0 + (self.min_width - 1.0) * (u - self.start) / (1.0 - self.start)
        }
    }
}

fn rgba(c: [f32; 3]) -> [u8; 4] {
    let b = |v: f32| (v.clamp(0.0, 1.0) * 255.0 + 0.5) as u8;
    [b(c[0]), b(c[1]), b(c[2]), 255]
}

impl LineSet {
    /// The lines of `s` coloured by `color` (direction: the absolute unit tangent by central
    /// differences; a per-point attribute through the colour map over its finite range; a
    /// field of world position; a constant). Lines of one point have no segment; a segment
    /// between two equal points is kept (the renderer gives it a pixel, without NaN).
    pub fn new(s: &Streamlines, color: &ColorMode, width: LineWidth, cylinder: bool) -> LineSet {
        let (origin, colors, segments) = Self::colors_and_segments(s, color);
        let positions = s
            .points
            .iter()
            .map(|p| (p.as_dvec3() - origin).as_vec3())
            .collect();
        Self::with(origin, positions, colors, segments, width, cylinder)
    }

    /// [`LineSet::new`] taking the streamlines: their points become the positions in place
    /// (20 bytes a point at the peak instead of 32: a whole-brain tractogram is not copied).
    pub fn from_streamlines(
        s: Streamlines,
        color: &ColorMode,
        width: LineWidth,
        cylinder: bool,
    ) -> LineSet {
        let (origin, colors, segments) = Self::colors_and_segments(&s, color);
        let mut positions = s.points;
        for p in &mut positions {
            *p = (p.as_dvec3() - origin).as_vec3();
        }
        Self::with(origin, positions, colors, segments, width, cylinder)
    }

    fn with(
        origin: DVec3,
        positions: Vec<Vec3>,
        colors: Vec<[u8; 4]>,
        segments: Vec<u32>,
        width: LineWidth,
        cylinder: bool,
    ) -> LineSet {
        LineSet {
            origin,
            positions,
            colors,
            segments,
            width,
            cylinder,
            proxy_radius: 0.0,
            times: vec![],
            trail: None,
            halo: None,
            taper_u: vec![],
            taper_t: 0.0,
            filter: vec![],
            filter_min: 0.0,
            filter_taper: 0.0,
            points: false,
        }
    }

    /// The set's origin (the centre of the points' bounds), a colour per point and the
    /// segments.
    fn colors_and_segments(s: &Streamlines, color: &ColorMode) -> (DVec3, Vec<[u8; 4]>, Vec<u32>) {
        let origin = s
            .bounds()
            .map(|[lo, hi]| ((lo + hi) * 0.5).as_dvec3())
            .unwrap_or(DVec3::ZERO);
        let scalar = match color {
            ColorMode::Scalar(name, _) => s.point_attributes.iter().find(|a| &a.name == name),
            _ => None,
        };
        let range = scalar.map(|a| {
            a.values
                .iter()
                .step_by(a.components.max(1))
                .filter(|v| v.is_finite())
                .fold([f64::INFINITY, f64::NEG_INFINITY], |[l, h], &x| {
                    [l.min(x as f64), h.max(x as f64)]
                })
        });
        let mut colors = Vec::with_capacity(s.points.len());
        let mut segments = Vec::with_capacity(s.points.len());
        for i in 0..s.len() {
            let first = s.offsets[i];
            let line = s.line(i);
            for (k, p) in line.iter().enumerate() {
                let world = p.as_dvec3();
                let c = match color {
                    ColorMode::Direction => {
                        let a = line[k.saturating_sub(1)];
                        let b = line[(k + 1).min(line.len() - 1)];
                        let t = (b - a).normalize_or_zero();
                        [t.x.abs(), t.y.abs(), t.z.abs()]
                    }
                    ColorMode::Constant(c) => *c,
                    ColorMode::Scalar(_, map) => {
                        let [lo, hi] = range.unwrap_or([0.0, 1.0]);
                        let v = scalar
                            .map(|a| a.values[(first + k) * a.components] as f64)
                            .unwrap_or(0.0);
                        map_color(*map, (v - lo) / (hi - lo).max(1e-300))
                    }
                    ColorMode::Field(f, [lo, hi], map) => {
                        map_color(*map, (f(world) - lo) / (hi - lo).max(1e-300))
                    }
                };
                colors.push(rgba(c));
                // A segment with a non-finite end is left out (the line breaks there).
                if k + 1 < line.len() && line[k].is_finite() && line[k + 1].is_finite() {
                    segments.push((first + k) as u32);
                }
            }
        }
        (origin, colors, segments)
    }

    /// Every point of `s` as a disc of diameter `width` (a point cloud: the lines' order and
    /// lengths do not matter; a line of one point is drawn too).
    pub fn points(s: &Streamlines, color: &ColorMode, width: LineWidth) -> LineSet {
        let mut set = LineSet::new(s, color, width, false);
        set.segments = (0..set.positions.len() as u32)
            .filter(|&i| s.points[i as usize].is_finite())
            .collect();
        set.points = true;
        set
    }

    /// World bounds of the points.
    pub fn bounds(&self) -> Option<[DVec3; 2]> {
        crate::finite_bounds(&self.positions)
            .map(|[lo, hi]| [self.origin + lo.as_dvec3(), self.origin + hi.as_dvec3()])
    }

    /// World bounds of what is drawn: the points' bounds grown by half the drawn width -
    /// the halo's strip where there is one - when the width is in world units (a disc or a
    /// line at the edge is inside the box whole); a width in pixels has no world extent.
    pub fn drawn_bounds(&self) -> Option<[DVec3; 2]> {
        let [lo, hi] = self.bounds()?;
        let r = match self.width {
            LineWidth::World(w) if w.is_finite() => {
                0.5 * w * self.halo.as_ref().map_or(1.0, |h| h.width.max(1.0) as f64)
            }
            _ => 0.0,
        };
        Some([lo - DVec3::splat(r), hi + DVec3::splat(r)])
    }

    /// Bytes the renderer keeps for the set: a position, a colour and a segment index per point.
    pub fn gpu_bytes(&self) -> usize {
        self.positions.len() * 16 + self.segments.len() * 4
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn two_lines() -> Streamlines {
        let mut s = Streamlines::new();
        s.push(&[Vec3::ZERO, Vec3::X, Vec3::new(2.0, 0.0, 0.0)]);
        s.push(&[Vec3::new(0.0, 5.0, 0.0)]);
        s.push(&[Vec3::Y, Vec3::Y, Vec3::new(0.0, 1.0, 3.0)]);
        s
    }

    #[test]
    fn drawn_bounds_hold_whole_discs_and_halos_in_world_units_only() {
        let white = ColorMode::Constant([1.0; 3]);
        let mut p = LineSet::points(&two_lines(), &white, LineWidth::World(0.5));
        let [lo, hi] = p.bounds().unwrap();
        assert_eq!([lo, hi], [DVec3::ZERO, DVec3::new(2.0, 5.0, 3.0)]);
        let [dlo, dhi] = p.drawn_bounds().unwrap();
        assert_eq!([dlo, dhi], [lo - 0.25, hi + 0.25]);
        p.halo = Some(Halo {
            uniform: false,
            outline: false,
            width: 4.0,
            d_max: 0.01,
            displacement: Displacement::Linear,
            depth_cue: 0.0,
        });
        assert_eq!(p.drawn_bounds().unwrap(), [lo - 1.0, hi + 1.0]);
        let px = LineSet::new(&two_lines(), &white, LineWidth::Pixels(3.0), false);
        assert_eq!(px.drawn_bounds(), px.bounds());
    }

    #[test]
    fn segments_join_the_points_of_each_line_only() {
        let l = LineSet::new(
            &two_lines(),
            &ColorMode::Direction,
            LineWidth::Pixels(2.0),
            false,
        );
        assert_eq!(l.positions.len(), 7);
        // Line 0: segments from points 0 and 1; line 1 (one point): none; line 2: 4 and 5.
        assert_eq!(l.segments, vec![0, 1, 4, 5]);
        // Direction colour: along x for line 0, along z at the end of line 2; the repeated
        // point's tangent is taken across it, never NaN.
        assert_eq!(l.colors[1], [255, 0, 0, 255]);
        assert_eq!(l.colors[6], [0, 0, 255, 255]);
        assert!(l.colors.iter().all(|c| c[3] == 255));
        // Positions are relative to the centre of the bounds, and come back exactly.
        let [lo, hi] = l.bounds().unwrap();
        assert_eq!(lo, DVec3::ZERO);
        assert_eq!(hi, DVec3::new(2.0, 5.0, 3.0));
        assert!(l.gpu_bytes() <= 40 * l.positions.len());
    }

    #[test]
    fn scalar_colours_span_the_attribute_range() {
        let mut s = two_lines();
        s.point_attributes.push(crate::Attribute {
            name: "fa".into(),
            components: 1,
            values: vec![0.0, 0.5, 1.0, 0.0, f32::NAN, 0.25, 1.0],
        });
        let l = LineSet::new(
            &s,
            &ColorMode::Scalar("fa".into(), None),
            LineWidth::World(0.1),
            true,
        );
        let want = |v: f64| rgba(crate::tube_mesh::colormap(v));
        assert_eq!(l.colors[0], want(0.0));
        assert_eq!(l.colors[2], want(1.0));
        assert_eq!(l.colors[1], want(0.5));
        // A NaN value takes the colour map's NaN colour (its low end), not a panic.
        assert_eq!(l.colors[4], want(f64::NAN));
        // A named map: its colours at the same positions.
        let magma = volume::colormap::Colormap::Magma;
        let l = LineSet::new(
            &s,
            &ColorMode::Scalar("fa".into(), Some(magma)),
            LineWidth::World(0.1),
            true,
        );
        // sRGB, as every colour of a line set is stored (the renderer decodes them).
        let want = |v: f64| rgba(magma.srgb(v).map(|c| c as f32));
        assert_eq!(l.colors[0], want(0.0));
        assert_eq!(l.colors[1], want(0.5));
        assert_eq!(l.colors[5], want(0.25));
        assert_ne!(l.colors[1], rgba(crate::tube_mesh::colormap(0.5)));
    }
}

#[cfg(test)]
mod trail_tests {
    use super::{taper_u, Trail};

    #[test]
    fn taper_u_spans_the_end_vertices_whatever_the_length() {
        let u = taper_u(11, 2, 0.2);
        assert_eq!(u[0], 0.0);
        assert!((u[1] - 0.1).abs() < 1e-6 && (u[2] - 0.2).abs() < 1e-6);
        assert!((u[8] - 0.8).abs() < 1e-6 && u[10] == 1.0);
        assert!(u.windows(2).all(|w| w[1] > w[0]));
        // A short line: even over [0, 1].
        assert_eq!(taper_u(3, 2, 0.2), vec![0.0, 0.5, 1.0]);
        assert_eq!(taper_u(1, 2, 0.2), vec![0.5]);
    }

    #[test]
    fn the_trail_is_full_width_near_the_particle_and_tapers_to_min_width_at_its_ends() {
        let t = Trail {
            now: 5.0,
            back: 3.0,
            forward: 1.0,
            start: 1.0 / 3.0,
            min_width: 0.25,
        };
        assert_eq!(t.width_factor(5.0), 1.0);
        assert_eq!(t.width_factor(4.0), 1.0); // a third of the way back
        assert!((t.width_factor(2.0) - 0.25).abs() < 1e-6); // the back end
        assert!((t.width_factor(6.0) - 0.25).abs() < 1e-6); // the front end
                                                            // Halfway between the third and the end: halfway between 1 and 0.25.
        assert!((t.width_factor(5.0 + 2.0 / 3.0) - 0.625).abs() < 1e-5);
        assert_eq!(t.width_factor(1.9), 0.0);
        assert_eq!(t.width_factor(6.1), 0.0);
        assert_eq!(t.width_factor(f32::NAN), 0.0);
    }
}
