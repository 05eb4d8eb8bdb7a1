//! Integration time and speed on traced lines, and pathlines through time-varying fields:
//! known answers (a uniform field, a flow whose speed grows linearly in time), pathlines of a
//! steady field against its streamlines, the double gyre against an integration of its
//! formula, periodic and clamped time axes, and the attributes through .trk and .trx.

use glam::{DMat4, DVec3, DVec4, Vec3};
use tubes::pathline::{pathlines, PathIntegrator, PathlineOptions, SeriesField};
use tubes::trace::{trace_at, GridField, Integrator, TraceOptions};
use tubes::Streamlines;
use volume::synthetic::{
    cube_affine, double_gyre_grid, sample_series, sample_vector, DoubleGyre3d, LinearRamp,
    UnsteadyField, VectorField,
};
use volume::{Volume, VolumeSeries};

struct Linear(fn(DVec3) -> DVec3);

impl VectorField for Linear {
    fn velocity(&self, p: DVec3) -> DVec3 {
        (self.0)(p)
    }
}

impl UnsteadyField for Linear {
    fn velocity(&self, p: DVec3, _t: f64) -> DVec3 {
        (self.0)(p)
    }
}

fn cube(f: fn(DVec3) -> DVec3, n: usize) -> Volume {
    let dims = [n; 3];
    sample_vector(&Linear(f), dims, cube_affine(dims, -1.0, 1.0), "v")
}

fn stream_opts(integrator: Integrator, step: f64, max_length: f64) -> TraceOptions<'static> {
    TraceOptions {
        integrator,
        step,
        tolerance: 1e-6,
        max_length,
        min_speed: 1e-9,
        max_angle_deg: 90.0,
        orient: false,
        mask: None,
        both_ways: false,
    }
}

fn path_opts(time_step: f64, duration: f64) -> PathlineOptions<'static> {
    PathlineOptions {
        integrator: PathIntegrator::Rk4,
        time_step,
        duration,
        max_length: f64::INFINITY,
        min_speed: 1e-9,
        max_angle_deg: 90.0,
        mask: None,
        both_ways: false,
    }
}

fn attr<'a>(s: &'a Streamlines, name: &str) -> &'a [f32] {
    &s.point_attributes
        .iter()
        .find(|a| a.name == name)
        .unwrap_or_else(|| panic!("no '{name}' attribute"))
        .values
}

/// Distance from `p` to the polyline `line`, and the time there (linear along the segment).
fn nearest(p: Vec3, line: &[Vec3], time: &[f32]) -> (f64, f64) {
    let p = p.as_dvec3();
    let mut best = (f64::INFINITY, 0.0);
    for k in 0..line.len() - 1 {
        let (a, b) = (line[k].as_dvec3(), line[k + 1].as_dvec3());
        let ab = b - a;
        let u = ((p - a).dot(ab) / ab.length_squared()).clamp(0.0, 1.0);
        let d = (a + ab * u - p).length();
        if d < best.0 {
            best = (
                d,
                time[k] as f64 + u * (time[k + 1] as f64 - time[k] as f64),
            );
        }
    }
    best
}

#[test]
fn a_uniform_field_gives_its_speed_and_time_as_distance_over_speed() {
    let v = 0.4;
    let vol = cube(|_| DVec3::new(0.4 * 0.6, 0.4 * 0.8, 0.0), 5);
    let f = GridField::from_volume(&vol, None).unwrap();
    for integ in [Integrator::Euler, Integrator::Rk4, Integrator::Rk45] {
        // Long enough for both halves to reach the grid's edge (the bound is the whole line's).
        let mut o = stream_opts(integ, 0.05, 3.0);
        o.both_ways = true;
        let s = trace_at(&f, &[(DVec3::new(-0.2, -0.3, 0.1), 2.5)], &o);
        assert_eq!(s.len(), 1);
        let (time, speed) = (attr(&s, "time"), attr(&s, "speed"));
        assert_eq!(time.len(), s.points.len());
        assert!(s.points.len() > 20, "{integ:?}: {} points", s.points.len());
        for &sp in speed {
            assert!((sp as f64 - v).abs() < 1e-6, "{integ:?}: speed {sp}");
        }
        for k in 1..s.points.len() {
            let d = (s.points[k] - s.points[k - 1]).length() as f64;
            let dt = (time[k] - time[k - 1]) as f64;
            assert!(
                (dt - d / v).abs() < 2e-6,
                "{integ:?}: dt {dt} for {d} / {v}"
            );
        }
        // The seed keeps its time; time grows along the line, the backward half (traced against
        // the field) before it.
        let seed = s
            .points
            .iter()
            .position(|p| (*p - Vec3::new(-0.2, -0.3, 0.1)).length() < 1e-6)
            .unwrap();
        assert_eq!(time[seed], 2.5);
        assert!(seed > 0 && time[0] < 2.5);
    }
}

#[test]
fn pathlines_of_a_steady_field_are_its_streamlines() {
    // A linear spiral (exact under trilinear interpolation) whose speed changes along its
    // lines; a 4-D steady volume and a series of three equal frames.
    let spiral = |p: DVec3| DVec3::new(-p.y - 0.2 * p.x, p.x - 0.2 * p.y, 0.25);
    let vol = cube(spiral, 11);
    let f = GridField::from_volume(&vol, None).unwrap();
    let seeds = [
        (DVec3::new(0.6, 0.0, -0.8), 0.0),
        (DVec3::new(-0.3, 0.5, -0.5), 1.5),
    ];
    let stream = trace_at(&f, &seeds, &stream_opts(Integrator::Rk4, 0.001, 2.0));
    let steady = VolumeSeries::steady(vol.clone());
    let equal = VolumeSeries::new(vec![vol.clone(), vol.clone(), vol], 0.0, 0.5, false).unwrap();
    for series in [&steady, &equal] {
        let sf = SeriesField::from_series(series, None).unwrap();
        // Stop short of the streamline's end time so that every point has a partner.
        let duration = 0.95
            * (0..2)
                .map(|i| {
                    let t = &attr(&stream, "time")[stream.offsets[i]..stream.offsets[i + 1]];
                    t[t.len() - 1] as f64 - t[0] as f64
                })
                .fold(f64::INFINITY, f64::min);
        let path = pathlines(&sf, &seeds, &path_opts(0.002, duration));
        assert_eq!(path.len(), 2);
        let mut worst = (0.0f64, 0.0f64);
        for i in 0..2 {
            let line = stream.line(i);
            let st = &attr(&stream, "time")[stream.offsets[i]..stream.offsets[i + 1]];
            let pt = &attr(&path, "time")[path.offsets[i]..path.offsets[i + 1]];
            let ps = &attr(&path, "speed")[path.offsets[i]..path.offsets[i + 1]];
            for (k, p) in path.line(i).iter().enumerate() {
                let (d, t) = nearest(*p, line, st);
                worst.0 = worst.0.max(d);
                worst.1 = worst.1.max((t - pt[k] as f64).abs());
                let exact = spiral(p.as_dvec3()).length();
                assert!((ps[k] as f64 - exact).abs() < 1e-5);
            }
        }
        eprintln!(
            "steady field, {} frame(s): pathline points within {:.2e} of the streamlines, \
             times within {:.2e}",
            series.len(),
            worst.0,
            worst.1
        );
        assert!(
            worst.0 < 1e-5 && worst.1 < 1e-5,
            "{} frames: distance {:.2e}, time {:.2e}",
            series.len(),
            worst.0,
            worst.1
        );
    }
}

#[test]
fn a_flow_whose_speed_grows_linearly_in_time_has_exact_pathlines() {
    // u = (a t, 0, 0): x(t) = x0 + a (t^2 - t0^2) / 2. Linear in space and time, so the
    // interpolated field is the formula, and RK4 integrates a linear function of t exactly.
    let a = 0.05;
    let dims = [21, 3, 3];
    let mut affine = cube_affine(dims, 0.0, 10.0);
    affine.y_axis.y = 0.5;
    affine.z_axis.z = 0.5;
    let ramp = LinearRamp {
        rate: a,
        direction: DVec3::X,
    };
    // Frames at t = 0, 0.5, ..., 8.
    let series = sample_series(&ramp, dims, affine, "v", 17, 0.0, 0.5, false);
    let f = SeriesField::from_series(&series, None).unwrap();
    let seeds: Vec<(DVec3, f64)> = [(1.0, 0.7), (0.5, 2.0), (2.0, 3.3)]
        .iter()
        .map(|&(x, t)| (DVec3::new(x, 0.4, 0.6), t))
        .collect();
    let mut o = path_opts(0.07, 4.0);
    o.both_ways = true;
    let s = pathlines(&f, &seeds, &o);
    assert_eq!(s.len(), 3);
    let mut worst = 0.0f64;
    for (i, &(x0, t0)) in seeds.iter().enumerate() {
        let t = &attr(&s, "time")[s.offsets[i]..s.offsets[i + 1]];
        let v = &attr(&s, "speed")[s.offsets[i]..s.offsets[i + 1]];
        for (k, p) in s.line(i).iter().enumerate() {
            let tk = t[k] as f64;
            let x = x0.x + a * (tk * tk - t0 * t0) / 2.0;
            worst = worst.max((p.x as f64 - x).abs());
            assert!((p.y - 0.4).abs() < 1e-6 && (p.z - 0.6).abs() < 1e-6);
            assert!(
                (v[k] as f64 - a * tk.abs()).abs() < 1e-6,
                "speed {} at {tk}",
                v[k]
            );
        }
        // Forward to t0 + 4 (the last point is there exactly); backward until t = 0, where the
        // speed is zero and the line stops, or to t0 - 4.
        assert!((t[t.len() - 1] as f64 - (t0 + 4.0)).abs() < 1e-6);
        assert!(t[0] as f64 >= (t0 - 4.0).max(0.0) - 1e-6);
    }
    assert!(worst < 1e-5, "largest error {worst:.2e}");
}

#[test]
fn time_axes_wrap_when_periodic_and_hold_their_ends_when_not() {
    // u = (0.1 sin(2 pi t / 4), 0, 0) in 8 frames over its period 4.
    struct Swing;
    impl UnsteadyField for Swing {
        fn velocity(&self, _p: DVec3, t: f64) -> DVec3 {
            DVec3::new(0.1 * (std::f64::consts::TAU * t / 4.0).sin(), 0.0, 0.0)
        }
    }
    let dims = [11, 2, 2];
    let affine = cube_affine(dims, 0.0, 1.0);
    let periodic = sample_series(&Swing, dims, affine, "v", 8, 0.0, 0.5, true);
    let f = SeriesField::from_series(&periodic, None).unwrap();
    let o = path_opts(0.05, 3.0);
    let seed = DVec3::new(0.5, 0.5, 0.5);
    let s = pathlines(&f, &[(seed, 0.3), (seed, 0.3 + 4.0), (seed, 0.3 - 8.0)], &o);
    assert_eq!(s.len(), 3);
    for i in 1..3 {
        for (p, q) in s.line(0).iter().zip(s.line(i)) {
            assert!((*p - *q).length() < 1e-6, "{p} {q}");
        }
    }
    // The wrap interpolates from the last frame (t = 3.5) to frame 0 (t = 4): at t = 3.75 the
    // field is the mean of the two.
    let v = |t: f64| f.at(seed, t).unwrap().x;
    let mid = 0.5 * (Swing.velocity(seed, 3.5).x + Swing.velocity(seed, 0.0).x);
    assert!((v(3.75) - mid).abs() < 1e-7);
    // Clamped: beyond the last frame (t = 3.5) the field is the last frame's.
    let clamped = VolumeSeries {
        periodic: false,
        ..periodic.clone()
    };
    let g = SeriesField::from_series(&clamped, None).unwrap();
    let last = Swing.velocity(seed, 3.5).x;
    assert!((g.at(seed, 3.75).unwrap().x - last).abs() < 1e-7);
    assert!((g.at(seed, 100.0).unwrap().x - last).abs() < 1e-7);
    assert!((g.at(seed, -5.0).unwrap().x - Swing.velocity(seed, 0.0).x).abs() < 1e-7);
}

/// RK4 on the double gyre's formula with a small step: the reference pathline point at
/// `t0 + duration`.
fn gyre_reference(g: &DoubleGyre3d, x0: DVec3, t0: f64, duration: f64) -> DVec3 {
    let h = 1e-3;
    let n = (duration / h).round() as usize;
    let (mut x, mut t) = (x0, t0);
    for _ in 0..n {
        let k1 = g.velocity(x, t);
        let k2 = g.velocity(x + k1 * (h / 2.0), t + h / 2.0);
        let k3 = g.velocity(x + k2 * (h / 2.0), t + h / 2.0);
        let k4 = g.velocity(x + k3 * h, t + h);
        x += (k1 + k2 * 2.0 + k3 * 2.0 + k4) * (h / 6.0);
        t += h;
    }
    x
}

#[test]
fn double_gyre_pathlines_converge_to_the_formula() {
    let g = DoubleGyre3d::default();
    let seeds: Vec<(DVec3, f64)> = vec![
        (DVec3::new(0.4, 0.3, 0.3), 0.0),
        (DVec3::new(1.5, 0.6, 0.7), 2.0),
        (DVec3::new(0.8, 0.7, 0.5), 6.5),
        (DVec3::new(1.2, 0.2, 0.4), 9.0),
    ];
    let duration = 5.0;
    let errors: Vec<f64> = [(17usize, 20usize), (33, 40)]
        .iter()
        .map(|&(n, frames)| {
            let (dims, affine) = double_gyre_grid(n);
            let series = sample_series(
                &g,
                dims,
                affine,
                "velocity",
                frames,
                0.0,
                g.period() / frames as f64,
                true,
            );
            let f = SeriesField::from_series(&series, None).unwrap();
            let s = pathlines(&f, &seeds, &path_opts(0.01, duration));
            assert_eq!(s.len(), seeds.len());
            seeds
                .iter()
                .enumerate()
                .map(|(i, &(x0, t0))| {
                    let end = s.line(i)[s.line(i).len() - 1].as_dvec3();
                    (end - gyre_reference(&g, x0, t0, duration)).length()
                })
                .fold(0.0, f64::max)
        })
        .collect();
    eprintln!(
        "double gyre, 5 time units: largest end-point error {:.2e} (17 samples, 20 frames), \
         {:.2e} (33 samples, 40 frames)",
        errors[0], errors[1]
    );
    assert!(errors[1] < 5e-3, "{errors:?}");
    assert!(errors[1] < 0.5 * errors[0], "no convergence: {errors:?}");
}

#[test]
fn time_and_speed_survive_trk_and_trx() {
    let vol = cube(|p| DVec3::new(-p.y, p.x, 0.1), 9);
    let f = GridField::from_volume(&vol, None).unwrap();
    let mut s = trace_at(
        &f,
        &[
            (DVec3::new(0.5, 0.0, 0.0), 1.25),
            (DVec3::new(0.2, 0.1, 0.3), 0.0),
        ],
        &stream_opts(Integrator::Rk4, 0.05, 1.0),
    );
    s.format = String::new();
    let dir = tempfile::tempdir().unwrap();
    for name in ["t.trk", "t.trx", "t.trk.gz"] {
        let p = dir.path().join(name);
        tubes::save(&p, &s).unwrap();
        let r = tubes::load(&p).unwrap();
        assert_eq!(r.offsets, s.offsets, "{name}");
        for a in ["time", "speed"] {
            let (x, y) = (attr(&r, a), attr(&s, a));
            assert_eq!(x, y, "{name}: {a}");
        }
        for (p, q) in r.points.iter().zip(&s.points) {
            assert!((*p - *q).length() < 1e-5, "{name}");
        }
    }
    // A .trx keeps the reference grid of a tractogram that has one.
    let mut t = s.clone();
    t.reference = Some(tubes::ReferenceSpace {
        dims: [9, 9, 9],
        voxel_sizes: [0.25; 3],
        vox_to_ras: DMat4::from_cols(
            DVec4::new(0.25, 0.0, 0.0, 0.0),
            DVec4::new(0.0, 0.25, 0.0, 0.0),
            DVec4::new(0.0, 0.0, 0.25, 0.0),
            DVec4::new(-1.0, -1.0, -1.0, 1.0),
        ),
        voxel_order: *b"RAS",
    });
    let p = dir.path().join("ref.trx");
    tubes::save(&p, &t).unwrap();
    let r = tubes::load(&p).unwrap();
    assert_eq!(r.reference, t.reference);
    assert_eq!(r.points, t.points);
    // A name TRX cannot hold is an error naming it.
    t.point_attributes[0].name = "a/b".into();
    let e = tubes::save(&dir.path().join("bad.trx"), &t)
        .unwrap_err()
        .to_string();
    assert!(e.contains("'a/b'"), "{e}");
}

/// `max_length` bounds a line traced both ways as a whole, forward first and backward for
/// what is left - streamlines and pathlines alike.
#[test]
fn the_length_bound_holds_for_the_whole_line_traced_both_ways() {
    let vol = cube(|_| DVec3::new(1.0, 0.0, 0.0), 5);
    let f = GridField::from_volume(&vol, None).unwrap();
    let series = VolumeSeries::steady(vol.clone());
    let sf = SeriesField::from_series(&series, None).unwrap();
    let seed = DVec3::new(0.1, 0.0, 0.0);
    let arc = |s: &Streamlines| -> (f64, f64, f64) {
        let p: Vec<DVec3> = s.points.iter().map(|p| p.as_dvec3()).collect();
        let len = p.windows(2).map(|w| (w[1] - w[0]).length()).sum();
        let min = p.iter().map(|q| q.x).fold(f64::INFINITY, f64::min);
        let max = p.iter().map(|q| q.x).fold(f64::NEG_INFINITY, f64::max);
        (len, min, max)
    };
    // (bound, expected length, lowest x, highest x): forward takes all of a short bound; a long
    // one reaches the grid's edge at x = 1 and leaves the rest to the backward half.
    for (bound, len, lo, hi) in [(0.6, 0.6, 0.1, 0.7), (1.5, 1.5, -0.5, 1.0)] {
        let mut o = stream_opts(Integrator::Rk4, 0.05, bound);
        o.both_ways = true;
        let s = trace_at(&f, &[(seed, 0.0)], &o);
        let (l, a, b) = arc(&s);
        assert!(
            (l - len).abs() < 1e-6 && (a - lo).abs() < 1e-6 && (b - hi).abs() < 1e-6,
            "streamline, bound {bound}: length {l}, x in [{a}, {b}]"
        );
        let mut p = path_opts(0.05, f64::INFINITY);
        p.max_length = bound;
        p.both_ways = true;
        let s = pathlines(&sf, &[(seed, 0.0)], &p);
        let (l, a, b) = arc(&s);
        // Pathlines stop at the first point past the bound: within a step of it.
        assert!(
            l >= len - 1e-6 && l < len + 0.05 + 1e-6 && a > lo - 0.05 - 1e-6 && b <= hi + 1e-6,
            "pathline, bound {bound}: length {l}, x in [{a}, {b}]"
        );
    }
}

/// A line that reaches `max_length` in many steps ends on its last full step: no step of a
/// rounding's length repeats the end point (2,000 steps of 0.1 summed to 199.99999999999, and a
/// last step of 1e-11 made a zero-length segment), one way or both.
#[test]
fn a_line_ending_at_its_length_bound_has_no_zero_length_last_segment() {
    // A rotation about z (trilinear: exact), circles of radius 0.5 round and round.
    let vol = cube(|p| DVec3::new(-p.y, p.x, 0.0), 9);
    let f = GridField::from_volume(&vol, None).unwrap();
    for both in [false, true] {
        // Steps of 0.1 over 200: 2,000 steps summing to 200 - 7e-12.
        let mut o = stream_opts(Integrator::Rk4, 0.1, 200.0);
        o.both_ways = both;
        let s = trace_at(&f, &[(DVec3::new(0.5, 0.0, 0.0), 0.0)], &o);
        let p: Vec<DVec3> = s.points.iter().map(|p| p.as_dvec3()).collect();
        let shortest = p
            .windows(2)
            .map(|w| (w[1] - w[0]).length())
            .fold(f64::INFINITY, f64::min);
        assert!(shortest > 1e-2, "both ways {both}: a segment of {shortest}");
        let len: f64 = p.windows(2).map(|w| (w[1] - w[0]).length()).sum();
        // (Chords of arcs of 0.1 on a circle of radius 0.5: 0.17% shorter than the arc.)
        assert!(
            (len - 199.67).abs() < 0.01,
            "both ways {both}: length {len}"
        );
    }
}

/// A line the step limit cuts, and seeds that give no line, are counted in the output's
/// warnings (they had been dropped or cut silently); a line that ends by its own bounds is
/// not counted.
#[test]
fn lines_cut_by_the_step_limit_and_seeds_without_lines_are_counted() {
    let vol = cube(|_| DVec3::new(1.0, 0.0, 0.0), 5);
    let f = GridField::from_volume(&vol, None).unwrap();
    let series = VolumeSeries::steady(vol.clone());
    let sf = SeriesField::from_series(&series, None).unwrap();
    let (inside, outside) = ((DVec3::ZERO, 0.0), (DVec3::splat(5.0), 0.0));
    // Streamlines: a step so small that the limit comes before the grid's edge (1e-7 x 10^6 =
    // 0.1 of arc), then a step that reaches the edge.
    let s = trace_at(
        &f,
        &[inside, outside],
        &stream_opts(Integrator::Rk4, 1e-7, 10.0),
    );
    assert_eq!(s.len(), 1);
    assert_eq!(s.points.len(), tubes::trace::MAX_STEPS + 1);
    assert!(
        s.warnings
            .iter()
            .any(|w| w.starts_with("1 of 1 lines stopped at the limit of 1000000 steps")),
        "{:?}",
        s.warnings
    );
    assert!(
        s.warnings
            .iter()
            .any(|w| w.starts_with("1 of 2 seeds gave no line")),
        "{:?}",
        s.warnings
    );
    let s = trace_at(&f, &[inside], &stream_opts(Integrator::Rk4, 0.05, 10.0));
    assert!(s.warnings.is_empty(), "{:?}", s.warnings);
    // Pathlines: a time step whose 10^6 steps end before the duration, then one that does not.
    let s = pathlines(&sf, &[inside], &path_opts(1e-7, 1.0));
    assert_eq!(s.points.len(), tubes::trace::MAX_STEPS + 1);
    assert!(
        s.warnings
            .iter()
            .any(|w| w.starts_with("1 of 1 lines stopped at the limit")),
        "{:?}",
        s.warnings
    );
    let s = pathlines(&sf, &[inside, outside], &path_opts(0.05, 0.5));
    assert_eq!(s.warnings, ["1 of 2 seeds gave no line (outside the grid or the mask, at most the minimum speed, or stopped before their first step)"]);
}

/// A trace given a point budget stops once its lines pass it (the seeds after that give no
/// line) and says how many points it held; under the budget it is the unlimited trace, for
/// streamlines and pathlines alike.
#[test]
fn traces_past_their_point_budget_stop_and_say_so() {
    let spiral = |p: DVec3| DVec3::new(-p.y - 0.2 * p.x, p.x - 0.2 * p.y, 0.25);
    let vol = cube(spiral, 11);
    let f = GridField::from_volume(&vol, None).unwrap();
    let seeds: Vec<(DVec3, f64)> = (0..200)
        .map(|i| {
            let a = i as f64 * 0.1;
            (DVec3::new(0.5 * a.cos(), 0.5 * a.sin(), -0.9), 0.0)
        })
        .collect();
    let o = stream_opts(Integrator::Rk4, 0.01, 1.0);
    let all = trace_at(&f, &seeds, &o);
    let n = all.points.len();
    assert!(
        all.len() == 200 && n > 10_000,
        "{} lines, {n} points",
        all.len()
    );
    let same = tubes::trace::trace_at_within(&f, &seeds, &o, n).unwrap();
    assert_eq!(same.points, all.points);
    let e = tubes::trace::trace_at_within(&f, &seeds, &o, n / 10).unwrap_err();
    assert!(
        e.points > n / 10 && e.lines.len() < 200,
        "{} points",
        e.points
    );
    let series = VolumeSeries::steady(vol);
    let sf = SeriesField::from_series(&series, None).unwrap();
    let p = path_opts(0.01, 1.0);
    let all = pathlines(&sf, &seeds, &p);
    let n = all.points.len();
    let e = tubes::pathline::pathlines_within(&sf, &seeds, &p, n / 10).unwrap_err();
    assert!(
        e.points > n / 10 && e.lines.len() < all.len(),
        "{} points",
        e.points
    );
}
