//! Streamline tracing through vector fields on regular grids.
//!
//! Streamlines are integrated by arc length, `dx/ds = v(x) / |v(x)|`, so the step `h` is a
//! distance in world units whatever the field's speed:
//! * Euler: `x + h d(x)` (first order; for comparison with the paper, whose streamlines are
//!   Euler-integrated);
//! * RK4: the classic fourth-order Runge-Kutta step;
//! * RK45: Dormand-Prince 5(4) with step control (`h` is the initial and largest step; the local
//!   error estimate is kept below `tolerance`).
//!
//! The field is sampled trilinearly in index space (the volume's inverse affine), components
//! being world directions (the volume readers convert them). Eigenvector fields have no sign:
//! with `orient`, every sample is flipped to agree with the previous direction of travel (and
//! within an RK stage with the stage's reference direction). Tracing stops at the grid's edge,
//! after `max_length` of the whole line (forward first, backward for what is left), where the
//! speed falls below `min_speed`, where a mask's trilinear value
//! falls below its threshold (an FA mask), where the direction turns by more than `max_angle`
//! degrees in one step, or where a step's chord is under a tenth of the step (the line went back
//! on itself, at a stagnation point). From every seed the line is traced both ways and joined. For an
//! eigenvector field the eight corner samples are oriented along the direction of travel before
//! they are interpolated (neighbouring eigenvectors of opposite sign would otherwise cancel).
//!
//! Every point carries two attributes: `speed`, the field's magnitude `|v(x)|` there, and
//! `time`, the integration time `t = t_seed + ∫ ds / |v|` along the line, integrated with the
//! same stages as the position (RK4: `h/6 (1/s1 + 2/s2 + 2/s3 + 1/s4)` with the stages'
//! speeds; Euler: `h / s1`; RK45: the fifth-order weights), negative of that before the seed, so
//! time grows along each line in the direction of the field. The seed's time is 0 for
//! [`trace`] and the given one for [`trace_at`]. In a uniform field of speed `v` a step of
//! length `h` adds exactly `h / v`. For an eigenvector field (no sign) the time is the
//! integration time along the arbitrary direction of travel. Pathlines through time-varying
//! fields are [`crate::pathline`]'s.

use crate::{Attribute, Streamlines};
use glam::{DMat3, DMat4, DVec3, DVec4, Vec3};
use rayon::prelude::*;
use volume::Volume;

/// A 3-component field on a regular grid, with trilinear interpolation.
pub struct GridField<'a> {
    dims: [usize; 3],
    data: &'a [f32],
    inv: DMat4,
    pub affine: DMat4,
}

/// A scalar on a regular grid (a stopping mask), with trilinear interpolation.
pub struct GridScalar<'a> {
    dims: [usize; 3],
    data: &'a [f32],
    inv: DMat4,
}

fn trilinear<const C: usize>(dims: [usize; 3], data: &[f32], p: DVec3) -> Option<[f64; C]> {
    trilinear_with::<C>(dims, data, p, None)
}

/// Trilinear interpolation; with `align`, each corner's 3-vector is first flipped to agree with
/// it (eigenvector fields: interpolating opposite signs would cancel the direction).
fn trilinear_with<const C: usize>(
    dims: [usize; 3],
    data: &[f32],
    p: DVec3,
    align: Option<DVec3>,
) -> Option<[f64; C]> {
    let [nx, ny, nz] = dims;
    let lim = |v: f64, n: usize| v >= -1e-9 && v <= (n - 1) as f64 + 1e-9;
    if !(lim(p.x, nx) && lim(p.y, ny) && lim(p.z, nz)) {
        return None;
    }
    let c = |v: f64, n: usize| v.clamp(0.0, (n - 1) as f64);
    let (x, y, z) = (c(p.x, nx), c(p.y, ny), c(p.z, nz));
    let (i0, j0, k0) = (x as usize, y as usize, z as usize);
    let (i1, j1, k1) = (
        (i0 + 1).min(nx - 1),
        (j0 + 1).min(ny - 1),
        (k0 + 1).min(nz - 1),
    );
    let (fx, fy, fz) = (x - i0 as f64, y - j0 as f64, z - k0 as f64);
    let mut out = [0.0; C];
    for (ii, wx) in [(i0, 1.0 - fx), (i1, fx)] {
        for (jj, wy) in [(j0, 1.0 - fy), (j1, fy)] {
            for (kk, wz) in [(k0, 1.0 - fz), (k1, fz)] {
                let w = wx * wy * wz;
                if w == 0.0 {
                    continue;
                }
                let id = (ii + nx * (jj + ny * kk)) * C;
                let mut sign = 1.0;
                if let (Some(a), 3) = (align, C) {
                    let dot = a.x * data[id] as f64
                        + a.y * data[id + 1] as f64
                        + a.z * data[id + 2] as f64;
                    if dot < 0.0 {
                        sign = -1.0;
                    }
                }
                for (c, o) in out.iter_mut().enumerate() {
                    let v = data[id + c];
                    if !v.is_finite() {
                        return None;
                    }
                    *o += w * sign * v as f64;
                }
            }
        }
    }
    Some(out)
}

impl<'a> GridField<'a> {
    /// The first 3-component field of a volume (or the named one).
    pub fn from_volume(
        v: &'a Volume,
        field: Option<&volume::FieldSelector>,
    ) -> Result<Self, String> {
        let f = match field {
            None => v.fields.iter().find(|f| f.components == 3).ok_or_else(|| {
                format!(
                    "no 3-component field (fields: {})",
                    v.field_names().join(", ")
                )
            })?,
            Some(sel) => {
                let f = v
                    .fields
                    .iter()
                    .find(|f| f.name == sel.name)
                    .ok_or_else(|| {
                        format!(
                            "field {}: no such field (fields: {})",
                            sel.name,
                            v.field_names().join(", ")
                        )
                    })?;
                if f.components != 3 {
                    return Err(format!(
                        "field {}: has {} components, tracing needs 3",
                        sel.name, f.components
                    ));
                }
                f
            }
        };
        Ok(GridField {
            dims: v.dims,
            data: &f.data,
            inv: v.affine.inverse(),
            affine: v.affine,
        })
    }

    /// The field at a world point, `None` outside the grid or next to non-finite samples.
    pub fn at(&self, p: DVec3) -> Option<DVec3> {
        let q = (self.inv * DVec4::from((p, 1.0))).truncate();
        trilinear::<3>(self.dims, self.data, q).map(|v| DVec3::new(v[0], v[1], v[2]))
    }

    /// The field at a world point with every corner sample oriented along `reference` first.
    pub fn at_oriented(&self, p: DVec3, reference: DVec3) -> Option<DVec3> {
        let q = (self.inv * DVec4::from((p, 1.0))).truncate();
        trilinear_with::<3>(self.dims, self.data, q, Some(reference))
            .map(|v| DVec3::new(v[0], v[1], v[2]))
    }

    /// World bounding box of the grid.
    pub fn bounds(&self) -> [DVec3; 2] {
        volume::grid_bounds(self.dims, self.affine)
    }

    /// The largest finite magnitude of any sample (0 when there is none).
    pub fn max_speed(&self) -> f64 {
        self.data
            .chunks_exact(3)
            .map(|c| DVec3::new(c[0] as f64, c[1] as f64, c[2] as f64).length())
            .filter(|s| s.is_finite())
            .fold(0.0, f64::max)
    }

    /// The smallest voxel spacing (a natural default step is a fraction of it).
    pub fn min_spacing(&self) -> f64 {
        let m = DMat3::from_mat4(self.affine);
        m.x_axis
            .length()
            .min(m.y_axis.length())
            .min(m.z_axis.length())
    }
}

impl<'a> GridScalar<'a> {
    pub fn from_volume(v: &'a Volume) -> Result<Self, String> {
        let f = v.default();
        if f.components != 1 {
            return Err(format!(
                "the mask must be a scalar volume; its field '{}' has {} components",
                f.name, f.components
            ));
        }
        Ok(GridScalar {
            dims: v.dims,
            data: &f.data,
            inv: v.affine.inverse(),
        })
    }

    pub fn at(&self, p: DVec3) -> Option<f64> {
        let q = (self.inv * DVec4::from((p, 1.0))).truncate();
        trilinear::<1>(self.dims, self.data, q).map(|v| v[0])
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Integrator {
    Euler,
    Rk4,
    Rk45,
}

/// Options of [`trace`].
pub struct TraceOptions<'a> {
    pub integrator: Integrator,
    /// Step (world units); for RK45 the initial and largest step.
    pub step: f64,
    /// RK45 local error bound (world units).
    pub tolerance: f64,
    pub max_length: f64,
    pub min_speed: f64,
    pub max_angle_deg: f64,
    /// Eigenvector field: flip samples to agree with the direction of travel.
    pub orient: bool,
    pub mask: Option<(&'a GridScalar<'a>, f64)>,
    /// Trace both ways from each seed.
    pub both_ways: bool,
}

impl TraceOptions<'_> {
    /// Checks every setting's range, NaN and infinities refused, naming the setting (a NaN
    /// tolerance or length gave 0 streamlines, a NaN speed or angle turned a stop test off):
    /// the one place the CLI and scenes validate a tracer configuration.
    pub fn check(&self) -> std::result::Result<(), String> {
        let positive = |v: f64, what: &str| {
            if v.is_finite() && v > 0.0 {
                Ok(())
            } else {
                Err(format!("{what} {v}: must be a positive number"))
            }
        };
        positive(self.step, "step")?;
        positive(self.tolerance, "tolerance")?;
        positive(self.max_length, "max length")?;
        if !(self.min_speed.is_finite() && self.min_speed >= 0.0) {
            return Err(format!(
                "min speed {}: must be a number of at least 0",
                self.min_speed
            ));
        }
        let a = self.max_angle_deg;
        if !(a.is_finite() && a > 0.0 && a <= 180.0) {
            return Err(format!("max angle {a} degrees: must be in (0, 180]"));
        }
        if let Some((_, t)) = self.mask {
            if !t.is_finite() {
                return Err(format!("mask threshold {t}: must be a finite number"));
            }
        }
        Ok(())
    }
}

/// The unit direction of travel at `p` and the speed there: an eigenvector field's direction
/// oriented along `reference`, any other field's times `sign` (-1 traces backward).
fn direction(
    f: &GridField,
    p: DVec3,
    reference: DVec3,
    sign: f64,
    o: &TraceOptions,
) -> Option<(DVec3, f64)> {
    let v = if o.orient {
        f.at_oriented(p, reference)?
    } else {
        f.at(p)?
    };
    let speed = v.length();
    if speed.is_nan() || speed <= o.min_speed || !speed.is_finite() {
        return None;
    }
    let d = v / speed;
    Some((
        if o.orient {
            if d.dot(reference) < 0.0 {
                -d
            } else {
                d
            }
        } else {
            d * sign
        },
        speed,
    ))
}

/// One integration step.
struct Step {
    /// The new point.
    q: DVec3,
    /// The direction of travel there.
    dir: DVec3,
    /// The arc length taken (RK45 may shrink the step).
    h: f64,
    /// The time it took, `∫ ds / |v|` by the integrator's own weights.
    dt: f64,
    /// The field's speed at `q`.
    speed: f64,
}

/// One step from `p` with unit direction of travel `dir` and speed `speed` there (`sign` as
/// [`direction`]'s).
fn step(
    f: &GridField,
    p: DVec3,
    (dir, speed): (DVec3, f64),
    h: f64,
    sign: f64,
    o: &TraceOptions,
) -> Option<Step> {
    let dirf = |q: DVec3, r: DVec3| direction(f, q, r, sign, o);
    match o.integrator {
        Integrator::Euler => {
            let q = p + dir * h;
            let (nd, ns) = dirf(q, dir)?;
            Some(Step {
                q,
                dir: nd,
                h,
                dt: h / speed,
                speed: ns,
            })
        }
        Integrator::Rk4 => {
            let (k1, s1) = (dir, speed);
            let (k2, s2) = dirf(p + k1 * (h / 2.0), k1)?;
            let (k3, s3) = dirf(p + k2 * (h / 2.0), k2)?;
            let (k4, s4) = dirf(p + k3 * h, k3)?;
            let q = p + (k1 + k2 * 2.0 + k3 * 2.0 + k4) * (h / 6.0);
            let (nd, ns) = dirf(q, dir)?;
            Some(Step {
                q,
                dir: nd,
                h,
                dt: (1.0 / s1 + 2.0 / s2 + 2.0 / s3 + 1.0 / s4) * (h / 6.0),
                speed: ns,
            })
        }
        Integrator::Rk45 => {
            // Dormand-Prince 5(4).
            let mut h = h;
            for _ in 0..30 {
                let (k1, s1) = (dir, speed);
                let (k2, _) = dirf(p + k1 * (h / 5.0), k1)?;
                let (k3, s3) = dirf(p + (k1 * (3.0 / 40.0) + k2 * (9.0 / 40.0)) * h, k1)?;
                let (k4, s4) = dirf(
                    p + (k1 * (44.0 / 45.0) - k2 * (56.0 / 15.0) + k3 * (32.0 / 9.0)) * h,
                    k1,
                )?;
                let (k5, s5) = dirf(
                    p + (k1 * (19372.0 / 6561.0) - k2 * (25360.0 / 2187.0)
                        + k3 * (64448.0 / 6561.0)
                        - k4 * (212.0 / 729.0))
                        * h,
                    k1,
                )?;
                let (k6, s6) = dirf(
                    p + (k1 * (9017.0 / 3168.0) - k2 * (355.0 / 33.0)
                        + k3 * (46732.0 / 5247.0)
                        + k4 * (49.0 / 176.0)
                        - k5 * (5103.0 / 18656.0))
                        * h,
                    k1,
                )?;
                let q5 = p
                    + (k1 * (35.0 / 384.0) + k3 * (500.0 / 1113.0) + k4 * (125.0 / 192.0)
                        - k5 * (2187.0 / 6784.0)
                        + k6 * (11.0 / 84.0))
                        * h;
                let (k7, s7) = dirf(q5, k1)?;
                let q4 = p
                    + (k1 * (5179.0 / 57600.0) + k3 * (7571.0 / 16695.0) + k4 * (393.0 / 640.0)
                        - k5 * (92097.0 / 339200.0)
                        + k6 * (187.0 / 2100.0)
                        + k7 * (1.0 / 40.0))
                        * h;
                let err = (q5 - q4).length();
                if err <= o.tolerance || h <= o.step * 1e-3 {
                    let dt = (35.0 / 384.0 / s1 + 500.0 / 1113.0 / s3 + 125.0 / 192.0 / s4
                        - 2187.0 / 6784.0 / s5
                        + 11.0 / 84.0 / s6)
                        * h;
                    return Some(Step {
                        q: q5,
                        dir: k7,
                        h,
                        dt,
                        speed: s7,
                    });
                }
                h *= (0.9 * (o.tolerance / err).powf(0.2)).clamp(0.1, 0.9);
            }
            None
        }
    }
}

/// A traced point: position, integration time since the seed, speed.
pub(crate) type Sample = (DVec3, f64, f64);

/// The most steps a line is traced each way from its seed (streamlines and pathlines): a
/// bound on the work and the memory of one line; a line it cuts is counted in the output's
/// warnings (`step_limit_warnings`).
pub const MAX_STEPS: usize = 1_000_000;

/// The warnings of a tracing run: lines cut at [`MAX_STEPS`] and seeds that gave no line
/// (when some did: a run where none did says so itself).
pub(crate) fn step_limit_warnings(seeds: usize, lines: usize, capped: usize) -> Vec<String> {
    let mut w = Vec::new();
    if capped > 0 {
        w.push(format!(
            "{capped} of {lines} lines stopped at the limit of {MAX_STEPS} steps each way from \
             the seed, before their length or duration: the step is small for them"
        ));
    }
    if lines > 0 && lines < seeds {
        w.push(format!(
            "{} of {seeds} seeds gave no line (outside the grid or the mask, at most the \
             minimum speed, or stopped before their first step)",
            seeds - lines
        ));
    }
    w
}

/// Traces one way from `seed` (speed `s0`; the first step turns at most `max_angle` from
/// `start_chord`, else from the direction) along `sign d0` (`d0` the field's direction there,
/// `sign` 1 forward, -1 backward) for at most `max_length` of arc length; returns the points
/// after the seed with their integration times since the seed (positive) and speeds, the arc
/// length traced, and whether [`MAX_STEPS`] stopped it.
fn trace_one(
    f: &GridField,
    (seed, s0): (DVec3, f64),
    d0: DVec3,
    sign: f64,
    max_length: f64,
    o: &TraceOptions,
    start_chord: Option<DVec3>,
) -> (Vec<Sample>, f64, bool) {
    let mut out = Vec::new();
    let (mut p, mut dir, mut speed) = (seed, d0 * sign, s0);
    let mut length = 0.0;
    let mut time = 0.0;
    let cos_max = o.max_angle_deg.to_radians().cos();
    // The direction the first step may not turn from: the other half's first step seen from
    // the seed (the line's turn there), else the field's direction.
    let mut last_chord = start_chord.unwrap_or(dir.normalize_or_zero());
    // The length is reached within a millionth of a step: the steps' sum rounds (2,000 steps
    // of 0.1 came to 199.99999999999 of 200, and a last step of 1e-11 repeated the end point).
    let slack = 1e-6 * o.step;
    if max_length <= slack {
        return (out, 0.0, false);
    }
    let max_steps = ((max_length / (o.step * 1e-3)).ceil() as usize).min(MAX_STEPS);
    for _ in 0..max_steps {
        let Some(Step {
            q,
            dir: ndir,
            h,
            dt,
            speed: nspeed,
        }) = step(f, p, (dir, speed), o.step.min(max_length - length), sign, o)
        else {
            break;
        };
        if ndir.dot(dir) < cos_max {
            break;
        }
        // The line's own turn: the step's chord against the last one (the direction at the
        // seed for the first). A higher-order step can bend more than its end directions say
        // (RK4 on an eigenvector field made turns of 141 degrees under a limit of 60).
        let chord = (q - p).normalize_or_zero();
        if chord.dot(last_chord) < cos_max {
            break;
        }
        if let Some((mask, thr)) = o.mask {
            match mask.at(q) {
                Some(v) if v >= thr => {}
                _ => break,
            }
        }
        // Arc length is the integration variable: count the step. A step whose chord is a tenth
        // of it went back on itself (a stagnation point or recirculation): stop there.
        if (q - p).length() < 0.1 * h {
            break;
        }
        length += h;
        time += dt;
        out.push((q, time, nspeed));
        last_chord = chord;
        p = q;
        dir = ndir;
        speed = nspeed;
        if length >= max_length - slack {
            break;
        }
    }
    // Every step taken and the length still short: the limit stopped the line.
    let capped = out.len() == MAX_STEPS && length < max_length - slack;
    (out, length, capped)
}

/// Traces a streamline through every seed (both ways unless told otherwise), in parallel, with
/// the seeds at time 0 (see [`trace_at`]).
pub fn trace(f: &GridField, seeds: &[DVec3], o: &TraceOptions) -> Streamlines {
    let timed: Vec<(DVec3, f64)> = seeds.iter().map(|&s| (s, 0.0)).collect();
    trace_at(f, &timed, o)
}

/// Traces a streamline through every seed `(position, time)` (both ways unless told
/// otherwise), in parallel, with the point attributes `time` and `speed` (module doc). Seeds
/// outside the field, below the minimum speed or outside the mask give no line.
pub fn trace_at(f: &GridField, seeds: &[(DVec3, f64)], o: &TraceOptions) -> Streamlines {
    match trace_at_within(f, seeds, o, usize::MAX) {
        Ok(s) => s,
        Err(Stopped { lines, .. }) => *lines,
    }
}

/// Lines that would hold more points than a caller allowed: traced until they did, the seeds
/// after that skipped.
#[derive(Clone, Debug)]
pub struct Stopped {
    /// The points traced when the tracing stopped.
    pub points: usize,
    /// The lines traced by then.
    pub lines: Box<Streamlines>,
}

/// Traces one line per seed in parallel with `line`, keeping those of two points or more, until
/// they hold more than `max_points` points; then the seeds not yet begun give none and the
/// result says how many points there were.
pub(crate) fn lines_within(
    seeds: &[(DVec3, f64)],
    max_points: usize,
    line: impl Fn(DVec3, f64) -> Option<(Vec<Sample>, bool)> + Sync,
) -> (Vec<(Vec<Sample>, bool)>, Option<usize>) {
    let points = std::sync::atomic::AtomicUsize::new(0);
    let over = |n: usize| n > max_points;
    let lines: Vec<(Vec<Sample>, bool)> = seeds
        .par_iter()
        .filter_map(|&(s, t0)| {
            if over(points.load(std::sync::atomic::Ordering::Relaxed)) {
                return None;
            }
            let l = line(s, t0)?;
            points.fetch_add(l.0.len(), std::sync::atomic::Ordering::Relaxed);
            Some(l)
        })
        .collect();
    let n = points.into_inner();
    (lines, over(n).then_some(n))
}

/// As [`trace_at`], stopping once the lines hold more than `max_points` points (a request that
/// would not fit in memory: each point takes about 60-80 bytes while traced).
pub fn trace_at_within(
    f: &GridField,
    seeds: &[(DVec3, f64)],
    o: &TraceOptions,
    max_points: usize,
) -> Result<Streamlines, Stopped> {
    let (lines, stopped) = lines_within(seeds, max_points, |s, t0| {
        if let Some((mask, thr)) = o.mask {
            if mask.at(s).is_none_or(|v| v < thr) {
                return None;
            }
        }
        let v = f.at(s)?;
        if v.length().is_nan() || v.length() <= o.min_speed {
            return None;
        }
        let s0 = v.length();
        let d = v / s0;
        // `max_length` bounds the whole line: backward goes as far as forward left.
        let (fwd, len, cap_f) = trace_one(f, (s, s0), d, 1.0, o.max_length, o, None);
        let (mut line, cap_b): (Vec<Sample>, bool) = if o.both_ways {
            let joint = fwd.first().map(|q| -(q.0 - s).normalize_or_zero());
            let (mut back, _, cap) = trace_one(f, (s, s0), d, -1.0, o.max_length - len, o, joint);
            back.reverse();
            (
                back.into_iter().map(|(p, t, v)| (p, t0 - t, v)).collect(),
                cap,
            )
        } else {
            (Vec::new(), false)
        };
        line.push((s, t0, s0));
        line.extend(fwd.into_iter().map(|(p, t, v)| (p, t0 + t, v)));
        (line.len() >= 2).then_some((line, cap_f || cap_b))
    });
    let capped = lines.iter().filter(|l| l.1).count();
    let n = lines.len();
    let mut out = timed_lines(lines.into_iter().map(|l| l.0).collect());
    out.warnings = step_limit_warnings(seeds.len(), n, capped);
    match stopped {
        Some(points) => Err(Stopped {
            points,
            lines: Box::new(out),
        }),
        None => Ok(out),
    }
}

/// Streamlines from lines of `(position, time, speed)`, with the point attributes `time` and
/// `speed`.
pub(crate) fn timed_lines(lines: Vec<Vec<Sample>>) -> Streamlines {
    let mut s = Streamlines::new();
    let n: usize = lines.iter().map(Vec::len).sum();
    let (mut time, mut speed) = (Vec::with_capacity(n), Vec::with_capacity(n));
    for l in lines {
        s.push(&l.iter().map(|p| p.0.as_vec3()).collect::<Vec<Vec3>>());
        time.extend(l.iter().map(|p| p.1 as f32));
        speed.extend(l.iter().map(|p| p.2 as f32));
    }
    s.point_attributes = vec![
        Attribute {
            name: "time".into(),
            components: 1,
            values: time,
        },
        Attribute {
            name: "speed".into(),
            components: 1,
            values: speed,
        },
    ];
    s.format = "traced".into();
    s
}

/// Seeds on a regular `n x n x n` lattice strictly inside `bounds`.
pub fn grid_seeds(bounds: [DVec3; 2], n: usize) -> Vec<DVec3> {
    let n = n.max(1);
    let mut out = Vec::with_capacity(n * n * n);
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                let f = DVec3::new(
                    (i as f64 + 0.5) / n as f64,
                    (j as f64 + 0.5) / n as f64,
                    (k as f64 + 0.5) / n as f64,
                );
                out.push(bounds[0] + (bounds[1] - bounds[0]) * f);
            }
        }
    }
    out
}

/// `n` times uniformly at random in `[lo, hi)` (deterministic for a given `seed`, and not the
/// sequence [`random_seeds`] draws for the same `seed`).
pub fn random_times(lo: f64, hi: f64, n: usize, seed: u64) -> Vec<f64> {
    let mut s = seed ^ 0xD1B5_4A32_D192_ED03;
    if s == 0 {
        s = 1;
    }
    let mut next = move || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        (s >> 11) as f64 / (1u64 << 53) as f64
    };
    (0..n).map(|_| lo + (hi - lo) * next()).collect()
}

/// `n` seeds uniformly at random in `bounds` (deterministic for a given `seed`).
pub fn random_seeds(bounds: [DVec3; 2], n: usize, seed: u64) -> Vec<DVec3> {
    let mut s = seed ^ 0x9E37_79B9_7F4A_7C15;
    let mut next = move || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        (s >> 11) as f64 / (1u64 << 53) as f64
    };
    (0..n)
        .map(|_| bounds[0] + (bounds[1] - bounds[0]) * DVec3::new(next(), next(), next()))
        .collect()
}
