//! Pathlines through time-varying vector fields on regular grids.
//!
//! A pathline is the path of a massless particle, `dx/dt = v(x, t)`, integrated in time (a
//! streamline, [`crate::trace`], follows one instant's field by arc length). The field
//! `v(x, t)` of a [`VolumeSeries`] is trilinear in space within each frame and linear in time
//! between the two frames around `t` ([`VolumeSeries::bracket`]: periodic series wrap around,
//! others hold their first and last frames beyond their ends). A steady field (one frame) gives
//! the streamlines' curves, traced in time.
//!
//! The step is a time step `h` (negative backward): RK4
//! `k1 = v(x, t)`, `k2 = v(x + h/2 k1, t + h/2)`, `k3 = v(x + h/2 k2, t + h/2)`,
//! `k4 = v(x + h k3, t + h)`, `x' = x + h/6 (k1 + 2 k2 + 2 k3 + k4)`; or Euler `x' = x + h k1`.
//! From every seed `(x0, t0)` the pathline runs forward to `t0 + duration` and, with
//! `both_ways`, backward to `t0 - duration`; it stops earlier where a stage leaves the grid or
//! meets a non-finite sample, where the speed at a new point is at most `min_speed`, where the
//! velocity turns by more than `max_angle` degrees from one point to the next, where a mask
//! falls below its threshold, or at the first point past `max_length` of arc length (of the
//! whole line: forward first, backward for what is left). Points
//! carry `time` (the particle's time) and `speed` (`|v(x, t)|`) as in [`crate::trace`].

use crate::trace::{
    lines_within, step_limit_warnings, timed_lines, GridField, GridScalar, Sample, Stopped,
    MAX_STEPS,
};
use crate::Streamlines;
use glam::DVec3;
use rayon::prelude::*;
use volume::VolumeSeries;

/// A time-varying 3-component field: one [`GridField`] per frame of a series.
pub struct SeriesField<'a> {
    series: &'a VolumeSeries,
    frames: Vec<GridField<'a>>,
}

impl<'a> SeriesField<'a> {
    /// The first 3-component field of every frame (or the named one).
    pub fn from_series(
        s: &'a VolumeSeries,
        field: Option<&volume::FieldSelector>,
    ) -> Result<Self, String> {
        s.validate().map_err(|e| e.to_string())?;
        let frames = s
            .frames
            .iter()
            .map(|v| GridField::from_volume(v, field))
            .collect::<Result<Vec<_>, _>>()?;
        Ok(SeriesField { series: s, frames })
    }

    /// The series the field samples.
    pub fn series(&self) -> &VolumeSeries {
        self.series
    }

    /// The field at world point `p` and time `t`, `None` outside the grid or next to
    /// non-finite samples.
    pub fn at(&self, p: DVec3, t: f64) -> Option<DVec3> {
        let b = self.series.bracket(t);
        if b.w == 0.0 || b.k0 == b.k1 {
            return self.frames[b.k0].at(p);
        }
        if b.w == 1.0 {
            return self.frames[b.k1].at(p);
        }
        let a = self.frames[b.k0].at(p)?;
        let c = self.frames[b.k1].at(p)?;
        Some(a * (1.0 - b.w) + c * b.w)
    }

    /// World bounding box of the grid.
    pub fn bounds(&self) -> [DVec3; 2] {
        self.frames[0].bounds()
    }

    /// The smallest voxel spacing.
    pub fn min_spacing(&self) -> f64 {
        self.frames[0].min_spacing()
    }

    /// The largest finite speed of any sample of any frame (0 when there is none).
    pub fn max_speed(&self) -> f64 {
        self.frames
            .par_iter()
            .map(GridField::max_speed)
            .reduce(|| 0.0, f64::max)
    }
}

/// The pathline integrators.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PathIntegrator {
    Euler,
    Rk4,
}

/// Options of [`pathlines`].
pub struct PathlineOptions<'a> {
    pub integrator: PathIntegrator,
    /// Time step (positive; the field's time unit).
    pub time_step: f64,
    /// How long to follow each particle each way (may be infinite; `max_length` and a cap of a
    /// million steps still hold).
    pub duration: f64,
    pub max_length: f64,
    pub min_speed: f64,
    pub max_angle_deg: f64,
    pub mask: Option<(&'a GridScalar<'a>, f64)>,
    /// Also trace backward in time from each seed.
    pub both_ways: bool,
}

/// Follows one particle from `(x0, t0)` in time direction `sign` (1 or -1) up to the first
/// point past `max_length` of arc length; returns the points after the seed with their times
/// and speeds, the arc length followed, and whether [`crate::trace::MAX_STEPS`] stopped it.
fn trace_one(
    f: &SeriesField,
    x0: DVec3,
    t0: f64,
    v0: DVec3,
    sign: f64,
    max_length: f64,
    o: &PathlineOptions,
) -> (Vec<(DVec3, f64, f64)>, f64, bool) {
    let mut out = Vec::new();
    if max_length <= 0.0 {
        return (out, 0.0, false);
    }
    let (mut x, mut t, mut v) = (x0, t0, v0);
    let mut elapsed = 0.0;
    let mut length = 0.0;
    let cos_max = o.max_angle_deg.to_radians().cos();
    let steps = (o.duration / o.time_step).ceil();
    let max_steps = if steps.is_finite() {
        (steps as usize).min(MAX_STEPS)
    } else {
        MAX_STEPS
    };
    for _ in 0..max_steps {
        let h = o.time_step.min(o.duration - elapsed);
        if h <= o.time_step * 1e-9 {
            break;
        }
        let hs = sign * h;
        let q = match o.integrator {
            PathIntegrator::Euler => x + v * hs,
            PathIntegrator::Rk4 => {
                let k1 = v;
                let Some(k2) = f.at(x + k1 * (hs / 2.0), t + hs / 2.0) else {
                    break;
                };
                let Some(k3) = f.at(x + k2 * (hs / 2.0), t + hs / 2.0) else {
                    break;
                };
                let Some(k4) = f.at(x + k3 * hs, t + hs) else {
                    break;
                };
                x + (k1 + k2 * 2.0 + k3 * 2.0 + k4) * (hs / 6.0)
            }
        };
        // The new time as seed time plus the elapsed time: no drift from summing steps.
        elapsed += h;
        let tq = if elapsed >= o.duration {
            t0 + sign * o.duration
        } else {
            t0 + sign * elapsed
        };
        let Some(vq) = f.at(q, tq) else {
            break;
        };
        let speed = vq.length();
        if !speed.is_finite() || speed <= o.min_speed {
            break;
        }
        if vq.dot(v) < cos_max * speed * v.length() {
            break;
        }
        if let Some((mask, thr)) = o.mask {
            match mask.at(q) {
                Some(m) if m >= thr => {}
                _ => break,
            }
        }
        length += (q - x).length();
        out.push((q, tq, speed));
        x = q;
        t = tq;
        v = vq;
        if length >= max_length {
            break;
        }
    }
    // Every step taken, and neither the duration nor the length reached: the limit stopped it.
    let capped = out.len() == MAX_STEPS && elapsed < o.duration && length < max_length;
    (out, length, capped)
}

/// Traces a pathline from every seed `(position, time)`, in parallel, with the point attributes
/// `time` and `speed`. Seeds outside the field, below the minimum speed or outside the mask give
/// no line; nor do lines of a single point.
pub fn pathlines(f: &SeriesField, seeds: &[(DVec3, f64)], o: &PathlineOptions) -> Streamlines {
    match pathlines_within(f, seeds, o, usize::MAX) {
        Ok(s) => s,
        Err(Stopped { lines, .. }) => *lines,
    }
}

/// As [`pathlines`], stopping once the lines hold more than `max_points` points
/// ([`crate::trace::trace_at_within`]).
pub fn pathlines_within(
    f: &SeriesField,
    seeds: &[(DVec3, f64)],
    o: &PathlineOptions,
    max_points: usize,
) -> Result<Streamlines, Stopped> {
    let (lines, stopped) = lines_within(seeds, max_points, |s, t0| {
        if let Some((mask, thr)) = o.mask {
            if mask.at(s).is_none_or(|v| v < thr) {
                return None;
            }
        }
        let v = f.at(s, t0)?;
        let s0 = v.length();
        if !s0.is_finite() || s0 <= o.min_speed {
            return None;
        }
        // `max_length` bounds the whole line: backward goes as far as forward left.
        let (fwd, len, cap_f) = trace_one(f, s, t0, v, 1.0, o.max_length, o);
        let (mut line, cap_b): (Vec<Sample>, bool) = if o.both_ways {
            let (mut back, _, cap) = trace_one(f, s, t0, v, -1.0, o.max_length - len, o);
            back.reverse();
            (back, cap)
        } else {
            (Vec::new(), false)
        };
        line.push((s, t0, s0));
        line.extend(fwd);
        (line.len() >= 2).then_some((line, cap_f || cap_b))
    });
    let capped = lines.iter().filter(|l| l.1).count();
    let n = lines.len();
    let mut s = timed_lines(lines.into_iter().map(|l| l.0).collect());
    s.format = "pathlines".into();
    s.warnings = step_limit_warnings(seeds.len(), n, capped);
    match stopped {
        Some(points) => Err(Stopped {
            points,
            lines: Box::new(s),
        }),
        None => Ok(s),
    }
}
