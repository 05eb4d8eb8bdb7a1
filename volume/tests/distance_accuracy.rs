//! Accuracy of the fast-sweeping signed distance on analytic solids (sphere, torus and box in
//! the unit cube, `volume::synthetic::three_solids`), in voxels: mean and max absolute error near
//! the surface (|d| < 3 voxels) and everywhere. Bounds are set from measured values with margin;
//! the same numbers are in docs/accuracy.md.

use volume::distance_sweep::{signed_distance, DistanceMethod, DistanceOptions, InitMethod};
use volume::synthetic::{cube_affine, sample_solid, three_solids, Solid};

/// Grid sizes to measure: `SIZES=64,128,256` in the environment, else 64 and 128.
fn sizes() -> Vec<usize> {
    std::env::var("SIZES")
        .map(|s| {
            s.split(',')
                .map(|x| x.parse().expect("SIZES: comma-separated integers"))
                .collect()
        })
        .unwrap_or(vec![64, 128])
}

pub struct Errors {
    pub near_mean: f64,
    pub near_max: f64,
    pub all_max: f64,
    pub iterations: usize,
}

impl Errors {
    /// Prints the three errors of `what` and asserts each below its bound (voxels).
    fn assert_below(&self, what: &str, near_mean: f64, near_max: f64, all_max: f64) {
        eprintln!(
            "{what}: near mean {:.4} max {:.3} all max {:.3}",
            self.near_mean, self.near_max, self.all_max
        );
        assert!(
            self.near_mean < near_mean && self.near_max < near_max && self.all_max < all_max,
            "{what}: near mean {}, near max {}, overall max {}",
            self.near_mean,
            self.near_max,
            self.all_max
        );
    }
}

fn measure(
    solid: &Solid,
    n: usize,
    init: InitMethod,
    method: DistanceMethod,
    spacing_z: f64,
) -> Errors {
    let dims = [n, n, ((n as f64) / spacing_z).round() as usize];
    let mut affine = cube_affine([n, n, n], 0.0, 1.0);
    affine.z_axis.z *= spacing_z;
    let vol = sample_solid(solid, dims, affine);
    let sp = vol.spacing();
    let h = sp[0];
    let opts = DistanceOptions {
        init,
        method,
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
                if e > amax && std::env::var("WHERE").is_ok() {
                    eprintln!(
                        "max {e:.3} at {i} {j} {k} exact {:.2} got {:.2}",
                        exact / h,
                        got / h
                    );
                }
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
    for n in sizes() {
        let sw = DistanceMethod::Sweeping;
        let edge = measure(&solid, n, InitMethod::Edge, sw, 1.0);
        let plane = measure(&solid, n, InitMethod::Plane, sw, 1.0);
        let grad = measure(&solid, n, InitMethod::Gradient, sw, 1.0);
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
    let e = measure(
        &solid,
        64,
        InitMethod::Gradient,
        DistanceMethod::Sweeping,
        2.0,
    );
    // Measured 0.066 / 1.49 / 2.26 (docs/accuracy.md).
    e.assert_below("anisotropic 64x64x32", 0.09, 1.7, 2.5);
}

/// The default distance, closest points of the band (`volume::closest_point`), on the same
/// scene: near the surface as accurate as sweeping or better, and without the first-order
/// scheme's point-source error at the box's corners (the maxima). Measured (docs/accuracy.md):
/// near mean / near max / overall max 0.015 / 0.71 / 0.88 at 64^3, 0.009 / 0.79 / 1.54 at 128^3,
/// against sweeping's 0.052 / 1.27 / 1.95 and 0.028 / 1.37 / 2.58.
#[test]
fn closest_points_have_no_point_source_error() {
    let solid = three_solids();
    for n in sizes() {
        let cp = measure(
            &solid,
            n,
            InitMethod::Gradient,
            DistanceMethod::ClosestPoint,
            1.0,
        );
        let sw = measure(
            &solid,
            n,
            InitMethod::Gradient,
            DistanceMethod::Sweeping,
            1.0,
        );
        let edge = measure(
            &solid,
            n,
            InitMethod::Edge,
            DistanceMethod::ClosestPoint,
            1.0,
        );
        let aniso = measure(
            &solid,
            n,
            InitMethod::Gradient,
            DistanceMethod::ClosestPoint,
            2.0,
        );
        let aniso_sw = measure(
            &solid,
            n,
            InitMethod::Gradient,
            DistanceMethod::Sweeping,
            2.0,
        );
        eprintln!(
            "n={n}: closest point near mean {:.4} max {:.3} all max {:.3} | sweeping {:.4} {:.3} {:.3} | closest point, edge init {:.4} {:.3} {:.3} | anisotropic (z 2x) {:.4} {:.3} {:.3}, sweeping {:.4} {:.3} {:.3}",
            cp.near_mean, cp.near_max, cp.all_max, sw.near_mean, sw.near_max, sw.all_max,
            edge.near_mean, edge.near_max, edge.all_max, aniso.near_mean, aniso.near_max, aniso.all_max,
            aniso_sw.near_mean, aniso_sw.near_max, aniso_sw.all_max
        );
        if std::env::var("NOASSERT").is_ok() {
            continue;
        }
        assert_eq!(cp.iterations, 0);
        // Near the surface at least as good as sweeping (with margin for the largest size's
        // 8% in docs/accuracy.md), the maxima clearly below it.
        assert!(
            cp.near_mean < 1.1 * sw.near_mean,
            "n={n}: near mean {} vs sweeping {}",
            cp.near_mean,
            sw.near_mean
        );
        assert!(
            cp.near_max < 0.7 * sw.near_max,
            "n={n}: near max {} vs {}",
            cp.near_max,
            sw.near_max
        );
        assert!(
            cp.all_max < 0.7 * sw.all_max,
            "n={n}: overall max {} vs {}",
            cp.all_max,
            sw.all_max
        );
        // Bounds from the measured values with margin.
        let (mean, nmax, amax) = if n == 64 {
            (0.02, 0.8, 1.0)
        } else {
            (0.012, 0.9, 1.7)
        };
        assert!(cp.near_mean < mean, "n={n}: near mean {}", cp.near_mean);
        assert!(cp.near_max < nmax, "n={n}: near max {}", cp.near_max);
        assert!(cp.all_max < amax, "n={n}: overall max {}", cp.all_max);
        // The surface patch is what makes the near field accurate: the paper's edge estimate
        // (no gradient normal) is several times worse.
        assert!(
            edge.near_mean > 3.0 * cp.near_mean,
            "edge {} vs {}",
            edge.near_mean,
            cp.near_mean
        );
        // Anisotropic spacing (z twice x and y), in voxels of the smallest spacing: near the
        // surface and overall better than sweeping; the near maximum grows with the coarse axis
        // (a band voxel's surface point can lie up to a z spacing from it): measured 1.79 near
        // and 2.67 overall at 128 x 128 x 64, against sweeping's 1.60 and 3.16.
        assert!(
            aniso.near_mean < aniso_sw.near_mean && aniso.near_mean < 0.03,
            "anisotropic near mean {} vs sweeping {}",
            aniso.near_mean,
            aniso_sw.near_mean
        );
        assert!(
            aniso.all_max < aniso_sw.all_max && aniso.near_max < 2.0,
            "anisotropic maxima {} {} vs sweeping's overall {}",
            aniso.near_max,
            aniso.all_max,
            aniso_sw.all_max
        );
    }
}

/// Issue 18: at 512^3 the default distance stays within the 256^3 errors (docs/accuracy.md:
/// near mean 0.0057, near max 0.85, overall max 1.51 voxels at 256^3; measured 0.0037, 0.28 and
/// 1.22 at 512^3).
#[test]
fn a_512_grid_stays_within_the_256_bounds() {
    let cp = measure(
        &three_solids(),
        512,
        InitMethod::Gradient,
        DistanceMethod::ClosestPoint,
        1.0,
    );
    cp.assert_below("512^3, closest points", 0.0057, 0.85, 1.51);
}
