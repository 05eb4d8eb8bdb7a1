//! Streamline tracing: circles of a rigid rotation (radius error against step size), the ABC
//! flow against a high-accuracy integration of the analytic field, and real DTI data.

use glam::DVec3;
use tubes::trace::{trace, GridField, GridScalar, Integrator, TraceOptions};
use volume::synthetic::{
    cube_affine, reference_streamline_end, rotation_slab, sample_vector, AbcFlow,
};

fn opts(integrator: Integrator, step: f64, max_length: f64) -> TraceOptions<'static> {
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

#[test]
fn rigid_rotation_traces_circles_and_rk4_converges_at_fourth_order() {
    let v = rotation_slab();
    let f = GridField::from_volume(&v, None).unwrap();
    let r0 = 0.5;
    let seed = [DVec3::new(r0, 0.0, 0.0)];
    let radius_error = |integ: Integrator, h: f64| {
        let s = trace(&f, &seed, &opts(integ, h, std::f64::consts::TAU * r0));
        s.points
            .iter()
            .map(|p| ((p.x as f64).hypot(p.y as f64) - r0).abs())
            .fold(0.0, f64::max)
    };
    let (rk_coarse, rk_fine) = (
        radius_error(Integrator::Rk4, 0.1),
        radius_error(Integrator::Rk4, 0.05),
    );
    let euler = radius_error(Integrator::Euler, 0.05);
    let rk45 = radius_error(Integrator::Rk45, 0.1);
    eprintln!("radius error over one turn: RK4 h=0.1 {rk_coarse:.2e}, h=0.05 {rk_fine:.2e}; Euler h=0.05 {euler:.2e}; RK45 {rk45:.2e}");
    // The field is linear, so trilinear interpolation is exact and only the integrator errs.
    assert!(rk_fine < 1e-5, "{rk_fine}");
    assert!(
        rk_coarse / rk_fine > 8.0,
        "RK4 should gain about 16x from halving the step: {rk_coarse} / {rk_fine}"
    );
    assert!(euler > 100.0 * rk_fine, "Euler spirals out: {euler}");
    assert!(rk45 < 1e-5);
    // It is a closed curve: the last point is back at the start.
    let s = trace(
        &f,
        &seed,
        &opts(Integrator::Rk4, 0.05, std::f64::consts::TAU * r0),
    );
    let last = s.points.last().unwrap().as_dvec3();
    assert!((last - seed[0]).length() < 5e-3, "{last}");
}

#[test]
fn abc_flow_agrees_with_a_high_accuracy_integration() {
    let n = 64;
    let tau = 2.0 * std::f64::consts::PI;
    let v = sample_vector(
        &AbcFlow::default(),
        [n; 3],
        cube_affine([n; 3], 0.0, tau),
        "v",
    );
    let f = GridField::from_volume(&v, None).unwrap();
    // A seed whose streamline stays inside the (non-periodic) grid for this length.
    let seed = DVec3::new(3.0, 3.2, 3.1);
    let length = 2.5;
    // Reference: RK4 on the analytic field with a tiny step.
    let abc = AbcFlow::default();
    let p = reference_streamline_end(&abc, seed, length, 1e-3);
    let mut errs = Vec::new();
    for integ in [Integrator::Euler, Integrator::Rk4, Integrator::Rk45] {
        let s = trace(&f, &[seed], &opts(integ, 0.05, length));
        let arc: f64 = s
            .points
            .windows(2)
            .map(|w| (w[1].as_dvec3() - w[0].as_dvec3()).length())
            .sum();
        assert!(
            (arc - length).abs() < 0.01,
            "{integ:?}: the line stopped after {arc}"
        );
        let end = s.points.last().unwrap().as_dvec3();
        errs.push((end - p).length());
    }
    eprintln!("ABC end-point error after {length}: Euler {:.2e}, RK4 {:.2e}, RK45 {:.2e} (grid spacing {:.3})", errs[0], errs[1], errs[2], tau / (n - 1) as f64);
    // Trilinear interpolation of the sampled field bounds RK4 and RK45 (about h_grid^2).
    assert!(errs[1] < 0.02 && errs[2] < 0.02, "{errs:?}");
    assert!(errs[0] > errs[1], "{errs:?}");
}

#[test]
fn dti_fibres_run_left_right_through_the_corpus_callosum() {
    let Some(data) =
        test_support::shared_or_skip("dti_fibres_run_left_right_through_the_corpus_callosum")
    else {
        return;
    };
    let v1 = volume::load(&data.join("dti/V1.nii.gz")).unwrap();
    let fa = volume::load(&data.join("dti/FA.nii.gz")).unwrap();
    let f = GridField::from_volume(&v1, None).unwrap();
    let mask = GridScalar::from_volume(&fa).unwrap();
    let o = TraceOptions {
        integrator: Integrator::Rk4,
        step: 0.5,
        tolerance: 1e-3,
        max_length: 80.0,
        min_speed: 1e-6,
        max_angle_deg: 60.0,
        orient: true,
        mask: Some((&mask, 0.2)),
        both_ways: true,
    };
    // Seeds in the mid-sagittal callosal arc (found in the volume tests): where FA > 0.6.
    let seeds: Vec<DVec3> = (-20..=30)
        .step_by(2)
        .flat_map(|y| [-37.0, -35.0, -33.0].map(|z| DVec3::new(-4.4, y as f64, z)))
        .filter(|&p| mask.at(p).is_some_and(|v| v > 0.6))
        .collect();
    assert!(seeds.len() >= 4, "{} seeds", seeds.len());
    let s = trace(&f, &seeds, &o);
    assert!(s.len() >= 4, "{} lines", s.len());
    // Through the midline the traced fibres run left-right: the chord over 5 mm on either side
    // of the seed (the seed is a point of its line) is mostly along x.
    let mut lateral = 0;
    for i in 0..s.len() {
        let l = s.line(i);
        let k = l
            .iter()
            .position(|p| seeds.iter().any(|q| q.as_vec3() == *p))
            .expect("the seed is on its line");
        let (a, b) = (
            l[k.saturating_sub(10)].as_dvec3(),
            l[(k + 10).min(l.len() - 1)].as_dvec3(),
        );
        if (b - a).normalize_or_zero().x.abs() > 0.8 {
            lateral += 1;
        }
    }
    assert!(
        lateral * 4 >= s.len() * 3,
        "{lateral} of {} traced lines run left-right at the midline",
        s.len()
    );
}

/// `max_angle` bounds the line's own turns (between consecutive steps, the seed's joint
/// included), not only the field's directions at the steps' ends: RK4 on the DTI principal
/// eigenvectors made turns of 141 degrees under a limit of 60 (and 84 at seeds, where the two
/// halves meet).
#[test]
fn no_traced_turn_exceeds_max_angle() {
    let Some(data) = test_support::shared_or_skip("no_traced_turn_exceeds_max_angle") else {
        return;
    };
    let v1 = volume::load(&data.join("dti/V1.nii.gz")).unwrap();
    let fa = volume::load(&data.join("dti/FA.nii.gz")).unwrap();
    let f = GridField::from_volume(&v1, None).unwrap();
    let mask = GridScalar::from_volume(&fa).unwrap();
    let b = v1.bounds();
    // Seeds on a regular lattice through the brain, in the mask.
    let seeds: Vec<DVec3> = (0..12)
        .flat_map(|i| (0..12).flat_map(move |j| (0..8).map(move |k| (i, j, k))))
        .map(|(i, j, k)| {
            b[0] + (b[1] - b[0]) * DVec3::new(i as f64 + 0.5, j as f64 + 0.5, k as f64 + 0.5)
                / DVec3::new(12.0, 12.0, 8.0)
        })
        .filter(|&p| mask.at(p).is_some_and(|v| v >= 0.2))
        .collect();
    assert!(seeds.len() > 50, "{} seeds", seeds.len());
    for (integrator, limit) in [
        (Integrator::Rk4, 60.0),
        (Integrator::Rk4, 30.0),
        (Integrator::Euler, 45.0),
    ] {
        let o = TraceOptions {
            integrator,
            step: 1.1,
            tolerance: 1e-3,
            max_length: 200.0,
            min_speed: 1e-6,
            max_angle_deg: limit,
            orient: true,
            mask: Some((&mask, 0.2)),
            both_ways: true,
        };
        let s = trace(&f, &seeds, &o);
        assert!(s.len() > 20, "{} lines", s.len());
        let mut worst = 0.0f64;
        for i in 0..s.len() {
            let l = s.line(i);
            for w in l.windows(3) {
                let (a, b) = ((w[1] - w[0]).as_dvec3(), (w[2] - w[1]).as_dvec3());
                if a.length() > 0.0 && b.length() > 0.0 {
                    worst = worst.max(a.angle_between(b).to_degrees());
                }
            }
        }
        assert!(
            worst <= limit + 0.5,
            "{integrator:?} at {limit}: a turn of {worst} degrees"
        );
    }
}
