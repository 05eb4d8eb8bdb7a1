//! Error against step size for the tracer (`umbra trace`), the chart of docs/accuracy.md.
//!
//! * Rigid rotation on a grid (linear field: trilinear interpolation is exact, so only the
//!   integrator errs): largest distance from the true circle over one turn of radius 0.5.
//! * ABC flow (A = sqrt 3, B = sqrt 2, C = 1) sampled on 32^3, 64^3 and 128^3 grids over
//!   [0, 2 pi]^3: end-point error after arc length 2.5 against RK4 on the analytic field with
//!   step 1e-4 — integration error plus the grid's interpolation error, which sets the floor.
//!
//! RK45 is adaptive: its rows use the tolerance as "step" column and report the mean step taken.
//! Prints CSV (method, case, step, mean_step, error) to stdout.
//! `cargo run --release -p umbra --example trace_accuracy > docs/data/trace_accuracy.csv`
use glam::DVec3;
use tubes::trace::{trace, GridField, Integrator, TraceOptions};
use volume::synthetic::{
    cube_affine, reference_streamline_end, rotation_slab, sample_vector, AbcFlow,
};

fn opts(
    integrator: Integrator,
    step: f64,
    tolerance: f64,
    max_length: f64,
) -> TraceOptions<'static> {
    TraceOptions {
        integrator,
        step,
        tolerance,
        max_length,
        min_speed: 1e-9,
        max_angle_deg: 90.0,
        orient: false,
        mask: None,
        both_ways: false,
    }
}

fn mean_step(s: &tubes::Streamlines) -> f64 {
    let arc: f64 = s
        .points
        .windows(2)
        .map(|w| (w[1].as_dvec3() - w[0].as_dvec3()).length())
        .sum();
    arc / (s.points.len().max(2) - 1) as f64
}

fn main() {
    println!("method,case,step,mean_step,error");
    let steps = [0.2, 0.1, 0.05, 0.025, 0.0125, 0.00625];
    let tols = [1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-7];
    // Rigid rotation.
    let v = rotation_slab();
    let f = GridField::from_volume(&v, None).unwrap();
    let r0 = 0.5;
    let seed = [DVec3::new(r0, 0.0, 0.0)];
    let run = |integ: Integrator, h: f64, tol: f64| {
        let s = trace(&f, &seed, &opts(integ, h, tol, std::f64::consts::TAU * r0));
        let err = s
            .points
            .iter()
            .map(|p| ((p.x as f64).hypot(p.y as f64) - r0).abs())
            .fold(0.0, f64::max);
        (mean_step(&s), err)
    };
    for (name, integ) in [("euler", Integrator::Euler), ("rk4", Integrator::Rk4)] {
        for &h in &steps {
            let (m, e) = run(integ, h, 1e-6);
            println!("{name},rotation,{h},{m:.6},{e:.4e}");
        }
    }
    for &tol in &tols {
        let (m, e) = run(Integrator::Rk45, 0.1, tol);
        println!("rk45,rotation,{tol},{m:.6},{e:.4e}");
    }
    // ABC flow: reference by RK4 on the analytic field.
    let abc = AbcFlow::default();
    let seed = DVec3::new(3.0, 3.2, 3.1);
    let length: f64 = 2.5;
    let p = reference_streamline_end(&abc, seed, length, 1e-4);
    let tau = 2.0 * std::f64::consts::PI;
    for n in [32usize, 64, 128] {
        let v = sample_vector(&abc, [n; 3], cube_affine([n; 3], 0.0, tau), "v");
        let f = GridField::from_volume(&v, None).unwrap();
        let run = |integ: Integrator, h: f64, tol: f64| {
            let s = trace(&f, &[seed], &opts(integ, h, tol, length));
            let end = s.points.last().unwrap().as_dvec3();
            (mean_step(&s), (end - p).length())
        };
        let case = format!("abc{n}");
        for (name, integ) in [("euler", Integrator::Euler), ("rk4", Integrator::Rk4)] {
            for &h in &steps {
                let (m, e) = run(integ, h, 1e-6);
                println!("{name},{case},{h},{m:.6},{e:.4e}");
            }
        }
        for &tol in &tols {
            let (m, e) = run(Integrator::Rk45, 0.1, tol);
            println!("rk45,{case},{tol},{m:.6},{e:.4e}");
        }
    }
}
