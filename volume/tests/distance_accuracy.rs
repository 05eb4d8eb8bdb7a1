//! Accuracy of the fast-sweeping signed distance on analytic solids (sphere, torus and box in
//! the unit cube, `volume::synthetic::three_solids`), in voxels: mean and max absolute error near
//! the surface (|d| < 3 voxels) and everywhere. Bounds are set from measured values with margin;
//! the same numbers are in docs/accuracy.md.

use volume::distance_sweep::{signed_distance, DistanceOptions, InitMethod};
use volume::synthetic::{cube_affine, sample_solid, three_solids, Solid};

pub struct Errors {
    pub near_mean: f64,
    pub near_max: f64,
    pub all_max: f64,
    pub iterations: usize,
}

fn measure(solid: &Solid, n: usize, init: InitMethod, spacing_z: f64) -> Errors {
    let dims = [n, n, ((n as f64) / spacing_z).round() as usize];
    let mut affine = cube_affine([n, n, n], 0.0, 1.0);
    affine.z_axis.z *= spacing_z;
    let vol = sample_solid(solid, dims, affine);
    let sp = vol.spacing();
    let h = sp[0];
    let opts = DistanceOptions {
        init,
        ..Default::default()
    };
    let df = signed_distance(
        &vol.fields[0].data,
        dims,
        [sp[0] as f32, sp[1] as f32, sp[2] as f32],
        &opts,
    );
    assert!(df.converged);
    let (mut nsum, mut ncount, mut nmax, mut amax) = (0.0, 0usize, 0.0f64, 0.0f64);
    for k in 0..dims[2] {
        for j in 0..dims[1] {
            for i in 0..dims[0] {
                let p = vol.index_to_world(glam::DVec3::new(i as f64, j as f64, k as f64));
                let exact = solid.distance(p);
                let got = df.distance[vol.index(i, j, k)] as f64;
                let e = (got - exact).abs() / h;
                amax = amax.max(e);
                if exact.abs() < 3.0 * h {
                    nsum += e;
                    ncount += 1;
                    nmax = nmax.max(e);
                }
            }
        }
    }
    Errors {
        near_mean: nsum / ncount as f64,
        near_max: nmax,
        all_max: amax,
        iterations: df.iterations,
    }
}

#[test]
fn plane_initialisation_beats_the_papers_edge_interpolation() {
    let solid = three_solids();
    let sizes: Vec<usize> = std::env::var("SIZES")
        .map(|s| s.split(',').map(|x| x.parse().unwrap()).collect())
        .unwrap_or(vec![64, 128]);
    for n in sizes {
        let edge = measure(&solid, n, InitMethod::Edge, 1.0);
        let plane = measure(&solid, n, InitMethod::Plane, 1.0);
        let grad = measure(&solid, n, InitMethod::Gradient, 1.0);
        eprintln!(
            "n={n}: edge near mean {:.4} max {:.3} all max {:.3} | plane {:.4} {:.3} {:.3} | gradient {:.4} {:.3} {:.3} | iterations {}",
            edge.near_mean, edge.near_max, edge.all_max, plane.near_mean, plane.near_max, plane.all_max, grad.near_mean, grad.near_max, grad.all_max, plane.iterations
        );
        if std::env::var("NOASSERT").is_ok() {
            continue;
        }
        // Both local estimates beat the paper's edge interpolation clearly near the surface.
        assert!(
            grad.near_mean < 0.6 * edge.near_mean,
            "n={n}: gradient {} vs edge {}",
            grad.near_mean,
            edge.near_mean
        );
        assert!(
            plane.near_mean < 0.75 * edge.near_mean,
            "n={n}: plane {} vs edge {}",
            plane.near_mean,
            edge.near_mean
        );
        // Bounds from the measured values (docs/accuracy.md) with margin. On this scene
        // scikit-fmm order 1 gave, at 128^3, near mean 0.045, near max 1.38, overall max 2.59
        // (bench/peers_sdf.py); the maxima are the first-order scheme's, ours agree with them.
        let (mean, nmax, amax) = if n == 64 {
            (0.06, 1.4, 2.1)
        } else {
            (0.033, 1.45, 2.65)
        };
        assert!(grad.near_mean < mean, "n={n}: near mean {}", grad.near_mean);
        assert!(grad.near_max < nmax, "n={n}: near max {}", grad.near_max);
        assert!(grad.all_max < amax, "n={n}: overall max {}", grad.all_max);
        assert!(
            grad.iterations <= 4,
            "n={n}: {} iterations",
            grad.iterations
        );
    }
}

#[test]
fn anisotropic_spacing_keeps_the_error_small() {
    // z spacing twice x and y (as in CT stacks); errors in voxels of the smallest spacing.
    let solid = three_solids();
    let e = measure(&solid, 64, InitMethod::Gradient, 2.0);
    eprintln!(
        "anisotropic 64x64x32: near mean {:.4} max {:.3} all max {:.3}",
        e.near_mean, e.near_max, e.all_max
    );
    // Measured 0.066 / 1.49 / 2.26 (docs/accuracy.md).
    assert!(
        e.near_mean < 0.09 && e.near_max < 1.7 && e.all_max < 2.5,
        "{} {} {}",
        e.near_mean,
        e.near_max,
        e.all_max
    );
}
