//! LineAO on whatever adapter this machine has (lavapipe in CI), 128 x 128: an isolated line
//! stays open, the GPU kernel agrees with its CPU twin (`occlusion::line_ao`) pixel for pixel
//! and factor for factor, the guard band changes only the border, degenerate settings give
//! finite values, the AO rises with the bundle's density, tubes are occluded by the lines and
//! tubes in front of them, the paper's shading, and the channels a frame reports.

mod common;
use common::{gpu, top_camera};
use engine::gpu::Gpu;
use engine::method::{LineAoShading, Method, Settings, SurfaceAo};
use engine::renderer::{DrawOptions, Output, Renderer};
use glam::{DVec3, Vec3};
use occlusion::camera::Camera;
use occlusion::emission_absorption::EaView;
use occlusion::line_ao::{line_ao_image, zoom_px, LineAoSettings, LineWidth as AoWidth};
use tubes::lines::{LineSet, LineWidth};
use tubes::tube_mesh::{straight_tubes, ColorMode, TubeMesh};

const W: u32 = 128;
const H: u32 = 128;

fn view(cam: Camera) -> EaView {
    let bounds = [DVec3::splat(-12.0), DVec3::splat(12.0)];
    EaView::span(bounds, 1.0, cam, W, H, None, Some(0.5), [0.0, 0.0, 0.0]).unwrap()
}

fn lines(polylines: &[Vec<[f32; 3]>], width: f64) -> LineSet {
    let mut s = tubes::Streamlines::new();
    for p in polylines {
        let pts: Vec<Vec3> = p.iter().map(|q| Vec3::from(*q)).collect();
        s.push(&pts);
    }
    LineSet::new(
        &s,
        &ColorMode::Constant([1.0; 3]),
        LineWidth::Pixels(width),
        false,
    )
}

fn settings(guard: u32) -> Settings {
    let mut s = Settings {
        method: Method::LineAo,
        fxaa: false,
        msaa: 1,
        ..Default::default()
    };
    s.lineao.guard = guard;
    s
}

fn render(gpu: &Gpu, meshes: &[TubeMesh], sets: &[LineSet], cam: Camera, s: &Settings) -> Output {
    let r = Renderer::new(gpu);
    let scene = r.upload(None, meshes, sets, None).unwrap();
    r.draw(&scene, &view(cam), &[], s, DrawOptions::default())
        .unwrap()
}

fn layer<'a>(o: &'a Output, name: &str) -> &'a [f32] {
    &o.terms
        .iter()
        .find(|(n, _)| *n == name)
        .unwrap_or_else(|| panic!("no layer {name}"))
        .1
}

fn channel<'a>(o: &'a Output, name: &str) -> &'a [f32] {
    &o.term_channels
        .iter()
        .find(|(n, _)| n == name)
        .unwrap_or_else(|| panic!("no channel {name}"))
        .1
}

fn covered(o: &Output) -> Vec<usize> {
    (0..o.aov.len()).filter(|&i| o.aov[i].depth > 0.0).collect()
}

/// The mean of `v` over the pixels `at`.
fn mean(v: &[f32], at: &[usize]) -> f64 {
    at.iter().map(|&i| v[i] as f64).sum::<f64>() / at.len().max(1) as f64
}

/// Horizontal lines at depth `z0` and vertical ones at `z1`, `n` of each, across the view
/// and beyond it.
fn grid(n: usize, z0: f32, z1: f32) -> Vec<Vec<[f32; 3]>> {
    let mut l = vec![];
    for k in 0..n {
        let t = -10.0 + 20.0 * (k as f32 + 0.5) / n as f32;
        l.push(vec![[-20.0, t, z0], [20.0, t, z0]]);
        l.push(vec![[t + 0.3, -20.0, z1], [t + 0.3, 20.0, z1]]);
    }
    l
}

#[test]
fn an_isolated_line_on_an_empty_background_stays_open() {
    let gpu = gpu();
    for perspective in [false, true] {
        let one = lines(&[vec![[-8.0, 0.5, 0.0], [8.0, 0.5, 0.0]]], 2.0);
        let o = render(&gpu, &[], &[one], top_camera(perspective), &settings(64));
        let at = covered(&o);
        assert!(at.len() > 40, "{} pixels", at.len());
        let v = layer(&o, "lineao");
        let worst = at.iter().map(|&i| v[i]).fold(1.0f32, f32::min);
        assert!(worst >= 0.999, "perspective {perspective}: {worst}");
        // Background pixels are open too, and every value is finite.
        assert!(v.iter().all(|x| x.is_finite() && (0.0..=1.0).contains(x)));
        assert_eq!(channel(&o, "occlusion.lineao.v").len(), (W * H) as usize);
        // The cylinder profile (depth bulging towards the eye, normal turning with it) is a
        // convex surface: it does not occlude itself either.
        let mut st = tubes::Streamlines::new();
        st.push(&[Vec3::new(-8.0, 0.5, 0.0), Vec3::new(8.0, 2.5, 0.0)]);
        let cyl = LineSet::new(
            &st,
            &ColorMode::Constant([1.0; 3]),
            LineWidth::Pixels(10.0),
            true,
        );
        let o = render(&gpu, &[], &[cyl], top_camera(perspective), &settings(64));
        let at = covered(&o);
        let m = mean(layer(&o, "lineao"), &at);
        assert!(m > 0.99, "perspective {perspective}: cylinder profile {m}");
    }
}

#[test]
fn the_gpu_kernel_agrees_with_its_cpu_twin() {
    twin_agrees(false);
}

#[test]
fn the_gpu_kernel_agrees_with_its_cpu_twin_anisotropic() {
    twin_agrees(true);
}

fn twin_agrees(anisotropic: bool) {
    let gpu = gpu();
    let cam = top_camera(false);
    // Guard band off: the twin runs on the viewport's own normal-depth map.
    let mut s = settings(0);
    s.lineao.kernel.anisotropic = anisotropic;
    let o = render(&gpu, &[], &[lines(&grid(9, 0.0, 0.6), 2.0)], cam, &s);
    // The twin's input from the frame: orthographic flat lines in planes facing the eye have
    // the normal +z; the depth is the AOV's linear depth, normalised as the pass does.
    let mut nd = occlusion::line_ao::NormalDepth::empty(W, H);
    for y in 0..H {
        for x in 0..W {
            let z = o.aov[(x + W * y) as usize].depth;
            if z > 0.0 {
                let d = occlusion::line_ao::normalised_depth(z, cam.near as f32, cam.far as f32);
                nd.set(x, y, d, [0.0, 0.0, 1.0]);
                // The grid's far lines (z = 0, 40 from the eye) run along x, the near along y.
                let t = if z > 39.7 {
                    glam::Vec2::X
                } else {
                    glam::Vec2::Y
                };
                nd.set_tangent(x, y, t);
            }
        }
    }
    let k = LineAoSettings {
        line_width: AoWidth::Pixels(2.0),
        depth_range: (cam.far - cam.near) as f32,
        ..s.lineao.kernel
    };
    let twin = line_ao_image(
        &nd,
        |x, y| zoom_px(&cam, o.aov[(x + W * y) as usize].depth as f64, H),
        &k,
    );
    let at = covered(&o);
    assert!(at.len() > 2000, "{} pixels", at.len());
    let gpu_v = layer(&o, "lineao");
    type Factor = fn(&occlusion::line_ao::LineAoTerms) -> f32;
    let pairs: [(&str, Factor); 5] = [
        ("visibility", |t| t.visibility()),
        ("v", |t| 1.0 - t.v),
        ("g_depth", |t| t.g_depth),
        ("g_light", |t| t.g_light),
        ("g_align", |t| t.g_align),
    ];
    for (name, factor) in pairs {
        let cpu = |i: usize| factor(&twin[i]);
        let got: &[f32] = if name == "visibility" {
            gpu_v
        } else {
            channel(&o, &format!("occlusion.lineao.{name}"))
        };
        let diffs: Vec<f32> = at.iter().map(|&i| (got[i] - cpu(i)).abs()).collect();
        let mean_diff = diffs.iter().sum::<f32>() / diffs.len() as f32;
        let close = diffs.iter().filter(|d| **d < 1e-3).count() as f64 / diffs.len() as f64;
        assert!(
            mean_diff < 2e-3 && close > 0.98,
            "{name}: mean |GPU - CPU| {mean_diff}, {close} within 1e-3"
        );
    }
    // The crossings occlude: the grid is not open everywhere.
    assert!(mean(gpu_v, &at) < 0.97, "{}", mean(gpu_v, &at));
}

/// `n` parallel lines along `dir` (in the x-y plane) at depth 0 under `n` more at depth 0.8,
/// along `dir` (parallel) or across it (crossing), 1.3 units apart.
fn layers(dir: f32, crossing: bool) -> Vec<Vec<[f32; 3]>> {
    let (c, s) = (dir.to_radians().cos(), dir.to_radians().sin());
    let mut l = vec![];
    for k in -7..=7 {
        let o = k as f32 * 1.3;
        let (a, b) = ([c, s], [-s, c]);
        let line = |d: [f32; 2], n: [f32; 2], off: f32, z: f32| {
            vec![
                [-20.0 * d[0] + off * n[0], -20.0 * d[1] + off * n[1], z],
                [20.0 * d[0] + off * n[0], 20.0 * d[1] + off * n[1], z],
            ]
        };
        l.push(line(a, b, o, 0.0));
        if crossing {
            l.push(line(b, a, o + 0.4, 0.8));
        } else {
            l.push(line(a, b, o + 0.65, 0.8));
        }
    }
    l
}

#[test]
fn anisotropic_lineao_spares_parallel_lines_and_keeps_crossings_and_the_invariant_form_ignores_the_roll(
) {
    let gpu = gpu();
    let cam = top_camera(false);
    // The mean occlusion (1 - visibility) over the far layer's pixels.
    let occ = |dir: f32, crossing: bool, aniso: bool, paper: bool| {
        let mut s = settings(64);
        s.lineao.kernel.anisotropic = aniso;
        if paper {
            s.lineao.kernel.alignment = occlusion::line_ao::Alignment::Paper;
        }
        let o = render(&gpu, &[], &[lines(&layers(dir, crossing), 2.0)], cam, &s);
        let far: Vec<usize> = covered(&o)
            .into_iter()
            .filter(|&i| o.aov[i].depth > 39.7)
            .collect();
        1.0 - mean(layer(&o, "lineao"), &far)
    };
    let (par_c, par_a) = (occ(0.0, false, false, false), occ(0.0, false, true, false));
    let (cross_c, cross_a) = (occ(0.0, true, false, false), occ(0.0, true, true, false));
    assert!(par_c > 0.05 && cross_c > 0.05, "classic {par_c} {cross_c}");
    assert!(
        par_a < 0.3 * par_c,
        "parallel: {par_a} against classic {par_c}"
    );
    assert!(
        (cross_a - cross_c).abs() < 0.15 * cross_c,
        "crossing: {cross_a} against classic {cross_c}"
    );
    // A crossing of +45 and -45 degree lines: the invariant form sees perpendicular lines as
    // the 0/90 crossing does; the paper's |t.x| sees them as parallel.
    let inv45 = occ(45.0, true, true, false);
    let paper45 = occ(45.0, true, true, true);
    eprintln!(
        "occlusion: parallel {par_c:.3} -> {par_a:.3}, crossing {cross_c:.3} -> {cross_a:.3}, \
         +-45 crossing invariant {inv45:.3}, paper {paper45:.3}"
    );
    assert!(
        (inv45 - cross_a).abs() < 0.2 * cross_a,
        "invariant: {inv45} at 45 degrees, {cross_a} at 0"
    );
    assert!(
        paper45 < 0.5 * inv45,
        "paper at 45 degrees: {paper45}, invariant {inv45}"
    );
}

#[test]
fn the_guard_band_changes_only_the_border() {
    let gpu = gpu();
    let cam = top_camera(false);
    let sets = [lines(&grid(16, 0.0, 1.0), 2.0)];
    let plain = render(&gpu, &[], &sets, cam, &settings(0));
    let banded = render(&gpu, &[], &sets, cam, &settings(64));
    let (a, b) = (layer(&plain, "lineao"), layer(&banded, "lineao"));
    // The largest disc: r0 = 3 px, two levels of 1 world unit at 128 / 24 px per unit.
    let reach = (3.0 + 2.0 * 128.0 / 24.0 + 2.0f64).ceil() as u32;
    let (mut inner, mut inner_same, mut border, mut border_differs) = (0, 0, 0, 0);
    for y in 0..H {
        for x in 0..W {
            let i = (x + W * y) as usize;
            if plain.aov[i].depth <= 0.0 || plain.aov[i].depth != banded.aov[i].depth {
                continue;
            }
            let edge = x.min(y).min(W - 1 - x).min(H - 1 - y);
            if edge >= reach {
                inner += 1;
                inner_same += ((a[i] - b[i]).abs() < 1e-5) as u32;
            } else if edge < 4 && a[i].min(b[i]) < 0.999 {
                // Occluded border pixels (the open ones stay open either way).
                border += 1;
                border_differs += ((a[i] - b[i]).abs() > 1e-4) as u32;
            }
        }
    }
    assert!(inner > 1000, "{inner}");
    assert!(
        inner_same as f64 > 0.995 * inner as f64,
        "{inner_same} of {inner} interior pixels equal"
    );
    // At the border the band gives the samples that fell off the screen something to see.
    assert!(
        border >= 8 && border_differs * 2 > border,
        "{border_differs} of {border}"
    );
}

#[test]
fn one_level_and_discs_wholly_off_screen_give_finite_open_values() {
    let gpu = gpu();
    let sets = [lines(&grid(5, 0.0, 1.0), 2.0)];
    let mut one = settings(0);
    one.lineao.kernel.levels = 1;
    let o = render(&gpu, &[], &sets, top_camera(true), &one);
    assert!(layer(&o, "lineao").iter().all(|v| v.is_finite()));
    // r0 of 2000 line widths: even the innermost sample (an eighth of the radius out) lands off
    // the screen (no band).
    let mut far = settings(0);
    far.lineao.kernel.r0_widths = 2000.0;
    far.lineao.kernel.radius_step = 0.0;
    let o = render(&gpu, &[], &sets, top_camera(false), &far);
    for (name, v) in std::iter::once(("lineao".to_string(), layer(&o, "lineao")))
        .chain(o.term_channels.iter().map(|(n, v)| (n.clone(), &v[..])))
    {
        assert!(v.iter().all(|x| *x == 1.0), "{name}");
    }
}

#[test]
fn lineao_darkens_as_the_bundle_gets_denser() {
    let gpu = gpu();
    let mut rng = occlusion::rng::SplitMix64(7);
    let mut means = vec![];
    for n in [4usize, 24, 96] {
        let mut l = vec![];
        for _ in 0..n {
            let y = (rng.next_f64() * 16.0 - 8.0) as f32;
            let z = (rng.next_f64() * 4.0 - 2.0) as f32;
            let tilt = (rng.next_f64() * 2.0 - 1.0) as f32;
            l.push(vec![[-9.0, y - tilt, z], [9.0, y + tilt, z + 0.5 * tilt]]);
        }
        let o = render(
            &gpu,
            &[],
            &[lines(&l, 2.0)],
            top_camera(true),
            &settings(64),
        );
        means.push(mean(layer(&o, "lineao"), &covered(&o)));
    }
    assert!(
        means[0] > means[1] + 0.02 && means[1] > means[2] + 0.02,
        "visibility by density {means:?}"
    );
    assert!(means[0] > 0.9, "{means:?}");
}

#[test]
fn tubes_are_occluded_where_lines_and_tubes_cross_in_front_of_them() {
    let gpu = gpu();
    // A tube along x at z = 0 and, crossing it nearer the eye, a tube along y at z = 1.2.
    let back = straight_tubes(&[[[-9.0, 0.0, 0.0], [9.0, 0.0, 0.0]]], 0.5, 16, [1.0; 3]);
    let front = straight_tubes(&[[[0.0, -9.0, 1.2], [0.0, 9.0, 1.2]]], 0.5, 16, [1.0; 3]);
    let o = render(&gpu, &[back, front], &[], top_camera(false), &settings(64));
    let v = layer(&o, "lineao");
    // The back tube's pixels: near the crossing (within 2 world units) and far from it.
    let px = |x: f64| ((x + 12.0) / 24.0 * W as f64) as u32;
    let (mut near, mut far) = (vec![], vec![]);
    for y in 60..68u32 {
        for x in 0..W {
            let i = (x + W * y) as usize;
            let depth = o.aov[i].depth;
            // The back tube is about 40 units from the eye, the front one 38.8.
            if depth <= 0.0 || depth < 39.4 {
                continue;
            }
            let d = (x as i64 - px(0.0) as i64).abs();
            if (5..11).contains(&d) {
                near.push(i);
            } else if d > 30 && x > px(-8.0) && x < px(8.0) {
                far.push(i);
            }
        }
    }
    assert!(
        near.len() > 20 && far.len() > 100,
        "{} {}",
        near.len(),
        far.len()
    );
    let (vn, vf) = (mean(v, &near), mean(v, &far));
    assert!(vn < vf - 0.1, "beside the crossing {vn}, away from it {vf}");
}

#[test]
fn the_papers_shading_replaces_ambient_and_diffuse_and_combined_folds_partial_and_lineao() {
    let gpu = gpu();
    let mut s = tubes::Streamlines::new();
    s.push(&[Vec3::new(-8.0, 0.0, 0.0), Vec3::new(8.0, 0.0, 0.0)]);
    let cyl = LineSet::new(
        &s,
        &ColorMode::Constant([0.5; 3]),
        LineWidth::Pixels(12.0),
        true,
    );
    let mut phong = settings(64);
    phong.lineao.shading = LineAoShading::Phong;
    let mut paper = phong.clone();
    paper.lineao.shading = LineAoShading::Paper;
    let a = render(
        &gpu,
        &[],
        std::slice::from_ref(&cyl),
        top_camera(false),
        &phong,
    );
    let b = render(
        &gpu,
        &[],
        std::slice::from_ref(&cyl),
        top_camera(false),
        &paper,
    );
    let at = covered(&a);
    let lum = |o: &Output| at.iter().map(|&i| o.image[i][0] as f64).sum::<f64>() / at.len() as f64;
    // An open line: paper = c + specular everywhere; Phong darkens the cylinder's edges.
    assert!(
        lum(&b) > lum(&a) + 0.02,
        "paper {} phong {}",
        lum(&b),
        lum(&a)
    );
    let mut combined = settings(64);
    combined.method = Method::Combined;
    combined.surface_ao = SurfaceAo::LineAo;
    let c = render(&gpu, &[], &[cyl], top_camera(false), &combined);
    let names: Vec<&str> = c.terms.iter().map(|(n, _)| *n).collect();
    assert_eq!(names, ["partial", "lineao"]);
    let aov: Vec<String> = c.aov_channels().into_iter().map(|(n, _)| n).collect();
    for want in [
        "occlusion.lineao",
        "occlusion.lineao.v",
        "occlusion.lineao.g_depth",
        "occlusion.lineao.g_light",
    ] {
        assert!(aov.iter().any(|n| n == want), "{want} not in {aov:?}");
    }
}
