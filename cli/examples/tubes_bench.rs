//! Stream-tube benchmark of docs/benchmarks.md: 10,000 smooth random polylines of 200 points in
//! a 100^3 box (deterministic), the whole pipeline (fit + reduce + RMF + mesh, `compute` of
//! `umbra tubes`, no I/O) at radius 0.2, 8 sides, tolerance 0.02, median of `repeat` runs.
//! `cargo run --release -p umbra --example tubes_bench -- [lines] [repeat] [out.tck] [kind]`
//! writes the polylines to `out.tck` for the VTK peer (bench/peers_tubes.py). `kind`: `smooth`
//! (default, the lines above) or `noisy-helix`: helices of radius 3 and pitch 4 (200 points,
//! 0.5 apart along the helix, about 4.3 turns), randomly placed and oriented in the box, every
//! point moved by uniform noise of +-0.1 per coordinate (5x the tolerance).
use glam::DVec3;
use std::time::Instant;
use tubes::bspline_fit::{FitMethod, FitOptions};
use tubes::tube_mesh::{build, ColorMode, FrameMethod, RadiusMode, TubeOptions};
use tubes::Streamlines;

/// Uniform numbers in [0, 1) by xorshift64 (deterministic, no dependency).
fn uniform(mut seed: u64) -> impl FnMut() -> f64 {
    move || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        (seed >> 11) as f64 / (1u64 << 53) as f64
    }
}

fn polylines(n: usize, points: usize) -> Streamlines {
    let mut rnd = uniform(0x2545F4914F6CDD1Du64);
    let mut s = Streamlines::new();
    for _ in 0..n {
        let mut p = DVec3::new(
            10.0 + 80.0 * rnd(),
            10.0 + 80.0 * rnd(),
            10.0 + 80.0 * rnd(),
        );
        let mut d = DVec3::new(rnd() - 0.5, rnd() - 0.5, rnd() - 0.5).normalize();
        let mut line = Vec::with_capacity(points);
        // Smooth: the turning rate (an angular velocity) drifts slowly, so curvature varies
        // smoothly along the line (radius of curvature mostly 5 to 50).
        let mut w = DVec3::ZERO;
        for _ in 0..points {
            line.push(p.as_vec3());
            w = w * 0.97 + DVec3::new(rnd() - 0.5, rnd() - 0.5, rnd() - 0.5) * 0.02;
            d = (d + w.cross(d)).normalize();
            // Near the walls, steer gently back towards the centre (no reflections: a kink
            // would be a corner for every method).
            let centre = DVec3::splat(50.0) - p;
            if p.min_element() < 15.0 || p.max_element() > 85.0 {
                d = (d + centre.normalize() * 0.03).normalize();
            }
            p += d * 0.5;
        }
        s.push(&line);
    }
    s
}

fn noisy_helices(n: usize, points: usize) -> Streamlines {
    let mut rnd = uniform(0x9E3779B97F4A7C15u64);
    let (radius, pitch, step, noise) = (3.0, 4.0, 0.5, 0.1);
    // Arc length per turn, and so the angle per step.
    let turn = ((2.0 * std::f64::consts::PI * radius).powi(2) + pitch * pitch).sqrt();
    let dphi = 2.0 * std::f64::consts::PI * step / turn;
    let mut s = Streamlines::new();
    for _ in 0..n {
        let centre = DVec3::new(
            20.0 + 60.0 * rnd(),
            20.0 + 60.0 * rnd(),
            20.0 + 60.0 * rnd(),
        );
        let axis = DVec3::new(rnd() - 0.5, rnd() - 0.5, rnd() - 0.5).normalize();
        let u = axis.any_orthonormal_vector();
        let v = axis.cross(u);
        let phase = 2.0 * std::f64::consts::PI * rnd();
        let line: Vec<glam::Vec3> = (0..points)
            .map(|i| {
                let phi = phase + dphi * i as f64;
                let p = centre
                    + (u * phi.cos() + v * phi.sin()) * radius
                    + axis * (pitch * (phi - phase) / (2.0 * std::f64::consts::PI) - 8.0);
                let jitter = DVec3::new(rnd() - 0.5, rnd() - 0.5, rnd() - 0.5) * (2.0 * noise);
                (p + jitter).as_vec3()
            })
            .collect();
        s.push(&line);
    }
    s
}

fn main() {
    let a: Vec<String> = std::env::args().collect();
    let n: usize = a.get(1).and_then(|s| s.parse().ok()).unwrap_or(10_000);
    let repeat: usize = a.get(2).and_then(|s| s.parse().ok()).unwrap_or(3);
    let s = match a.get(4).map(String::as_str) {
        None | Some("smooth") => polylines(n, 200),
        Some("noisy-helix") => noisy_helices(n, 200),
        Some(k) => panic!("unknown kind {k} (smooth, noisy-helix)"),
    };
    if let Some(out) = a.get(3).filter(|o| *o != "-") {
        tubes::save(std::path::Path::new(out), &s).unwrap();
    }
    let opts = TubeOptions {
        radius: 0.2,
        sides: 8,
        per_span: 1,
        chordal: None,
        max_turn_deg: 15.0,
        frame: FrameMethod::Rmf,
        radius_mode: RadiusMode::Local,
        fit: FitOptions {
            epsilon: 0.02,
            method: FitMethod::Iterative,
            max_iterations: 100,
        },
        caps: false,
        color: ColorMode::Direction,
    };
    let mut times = Vec::new();
    let mut last = None;
    for _ in 0..repeat {
        let t = Instant::now();
        let (mesh, st) = build(&s, &opts);
        times.push(t.elapsed().as_secs_f64());
        last = Some((mesh.positions.len(), st));
    }
    times.sort_by(|a, b| a.total_cmp(b));
    if std::env::var("FIT_ONLY").is_ok() {
        use rayon::prelude::*;
        let t = Instant::now();
        let total: usize = (0..s.len())
            .into_par_iter()
            .map(|i| {
                let pts: Vec<DVec3> = s.line(i).iter().map(|p| p.as_dvec3()).collect();
                tubes::bspline_fit::fit(&pts, &opts.fit).curve.control.len()
            })
            .sum();
        eprintln!(
            "fit only: {:.3} s ({total} control points)",
            t.elapsed().as_secs_f64()
        );
    }
    let (verts, st) = last.unwrap();
    println!(
        "{{\"lines\": {n}, \"points\": {}, \"compute_s\": {:.3}, \"triangles\": {}, \"vertices\": {verts}, \"control_points\": {}, \"max_deviation\": {:.5}, \"max_twist_deg\": {:.3}, \"min_section_ratio\": {:.4}, \"radius_clamps\": {}, \"splits\": {}, \"polyline_pieces\": {}, \"threads\": {}}}",
        st.points_in,
        times[times.len() / 2],
        st.triangles,
        st.control_points,
        st.max_deviation,
        st.max_twist_deg,
        st.min_section_ratio,
        st.radius_clamps,
        st.splits,
        st.polyline_pieces,
        rayon::current_num_threads()
    );
}
