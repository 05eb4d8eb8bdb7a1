//! The statistics behind `tube_mesh::ROUGH_FOURTH` (docs/benchmarks.md): for every cleaned
//! streamline of at least eight points in each file, the fit at `--tolerance` and the line's
//! largest fourth difference `|p[i-2] - 4 p[i-1] + 6 p[i] - 4 p[i+1] + p[i+2]|` in tolerances.
//! Prints per file the fits that shortened their line (and the largest fourth difference among
//! them) and the fits that kept every point (and how many of those exceed 24 tolerances).
//!
//! `cargo run --release -p tubes --example fit_kinks -- TOLERANCE FILE...`

use glam::DVec3;
use tubes::bspline_fit::{clean, fit, FitMethod, FitOptions};

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let Some((tol, files)) = args.split_first() else {
        eprintln!("usage: fit_kinks TOLERANCE FILE...");
        std::process::exit(2);
    };
    let tol: f64 = match tol.parse() {
        Ok(t) if t > 0.0 => t,
        _ => {
            eprintln!("fit_kinks: TOLERANCE '{tol}' is not a positive number");
            std::process::exit(2);
        }
    };
    let o = FitOptions {
        epsilon: tol,
        method: FitMethod::Iterative,
        max_iterations: 100,
    };
    for f in files {
        let s = match tubes::load(std::path::Path::new(f)) {
            Ok(s) => s,
            Err(e) => {
                eprintln!("fit_kinks: {e}");
                std::process::exit(1);
            }
        };
        let (mut short, mut short_max, mut kept, mut kept_over) = (0usize, 0.0f64, 0usize, 0usize);
        for i in 0..s.len() {
            let pts: Vec<DVec3> = s.line(i).iter().map(|p| p.as_dvec3()).collect();
            let (pts, _) = clean(&pts);
            if pts.len() < 8 {
                continue;
            }
            let d4 = pts
                .windows(5)
                .map(|w| (w[0] + w[4] + 6.0 * w[2] - 4.0 * (w[1] + w[3])).length())
                .fold(0.0, f64::max)
                / tol;
            if fit(&pts, &o).curve.control.len() < pts.len() {
                short += 1;
                short_max = short_max.max(d4);
            } else {
                kept += 1;
                kept_over += usize::from(d4 > 24.0);
            }
        }
        println!(
            "{f}: {short} fits shortened their line (largest fourth difference {short_max:.2} \
             tolerances); {kept} kept every point, {kept_over} of them above 24"
        );
    }
}
