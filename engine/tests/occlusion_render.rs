//! The occlusion renderer's properties on whatever adapter this machine has (lavapipe in CI),
//! on small synthetic scenes with known answers (issue 5, "How it is checked"): an
//! all-transparent transfer function gives the background; in a uniform medium the partial
//! occlusion of a surface falls with depth as the cone's mean of exp(-sigma depth / cos(phi))
//! (within 0.012; the light's path factor, `occlusion::combined::cone_path_factor`, missing
//! leaves it 0.017 too bright); a tube darkens the volume
//! behind it; a dense volume in front of a tube darkens the tube; a tube in a groove gets more
//! vicinity occlusion than an isolated one; min and product combine as eq. 7 and 8;
//! orthographic and perspective cameras agree; clipping planes remove what they should.

mod common;
use common::{gpu, top_camera};
use engine::gpu::Gpu;
use engine::method::{Combine, Method};
use engine::renderer::{self, Output, Settings};
use engine::slice_pass::{Samples, VolumeInput};
use glam::{DMat4, DVec3, DVec4};
use occlusion::camera::Camera;
use occlusion::emission_absorption::{EaView, Transfer};
use tubes::tube_mesh::TubeMesh;
use volume::{Field, ScalarType, Space, Volume};

const W: u32 = 64;
const H: u32 = 64;

/// A cube [-10, 10]^3 sampled at 1 unit with values f(p).
fn cube(f: impl Fn(DVec3) -> f32) -> Volume {
    let n = 21;
    let affine = DMat4::from_cols(
        DVec4::X,
        DVec4::Y,
        DVec4::Z,
        DVec4::new(-10.0, -10.0, -10.0, 1.0),
    );
    let mut data = Vec::with_capacity(n * n * n);
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                let p = DVec3::new(i as f64 - 10.0, j as f64 - 10.0, k as f64 - 10.0);
                data.push(f(p));
            }
        }
    }
    let field = Field {
        name: "v".into(),
        components: 1,
        stored: ScalarType::F32,
        data,
    };
    Volume::new([n, n, n], affine, Space::File, field).unwrap()
}

/// Constant white with extinction `sigma` per unit for values in [0.5, 2], none below.
fn medium(sigma: f64) -> Transfer {
    Transfer {
        points: vec![
            (0.49, [1.0; 3], 0.0),
            (0.5, [1.0; 3], sigma),
            (2.0, [1.0; 3], sigma),
        ],
        rows: vec![],
    }
}

/// Straight tubes of `radius` through the given end points, grey.
fn tubes(lines: &[[[f32; 3]; 2]], radius: f64) -> TubeMesh {
    tubes::tube_mesh::straight_tubes(lines, radius, 16, [192.0 / 255.0; 3])
}

fn view(cam: Camera) -> EaView {
    let bounds = [DVec3::splat(-12.0), DVec3::splat(12.0)];
    EaView::span(bounds, 1.0, cam, W, H, None, Some(0.25), [1.0, 1.0, 1.0]).unwrap()
}

struct Scene {
    vol: Option<(Volume, Vec<f32>, Transfer)>,
    /// The volume's samples as the renderer takes them.
    packed: Option<Samples>,
    meshes: Vec<TubeMesh>,
    tube_clip: Vec<([f64; 3], f64)>,
}

impl Scene {
    fn new(vol: Option<(Volume, Transfer)>, meshes: Vec<TubeMesh>) -> Scene {
        let vol = vol.map(|(v, t)| {
            let d = occlusion::emission_absorption::prepare(&v.select(None).unwrap().data);
            (v, d, t)
        });
        Scene {
            packed: vol.as_ref().map(|(_, d, _)| Samples::pack(d.clone())),
            vol,
            meshes,
            tube_clip: vec![],
        }
    }

    fn render(&self, gpu: &Gpu, v: &EaView, s: &Settings) -> Output {
        let vi = self
            .vol
            .as_ref()
            .zip(self.packed.as_ref())
            .map(|((vol, _, tf), data)| VolumeInput { vol, data, tf });
        renderer::render(
            gpu,
            vi.as_ref(),
            &self.meshes,
            &self.tube_clip,
            None,
            v,
            s,
            1,
        )
        .unwrap()
    }
}

fn settings(method: Method) -> Settings {
    Settings {
        method,
        fxaa: false,
        ..Default::default()
    }
}

/// Pixel index of a world point.
fn pixel(cam: &Camera, p: [f64; 3]) -> usize {
    let (x, y, _) = cam
        .to_pixel(DVec3::from(p), W as usize, H as usize)
        .unwrap();
    x as usize + W as usize * y as usize
}

/// Mean of `f` over the pixels of the segment a-b (world), sampled at 9 points.
fn mean_along(
    out: &Output,
    cam: &Camera,
    a: [f64; 3],
    b: [f64; 3],
    f: fn(&renderer::Aov) -> f32,
) -> f64 {
    let (a, b) = (DVec3::from(a), DVec3::from(b));
    let vals: Vec<f64> = (0..9)
        .map(|i| {
            let p = a + (b - a) * (i as f64 / 8.0);
            f(&out.aov[pixel(cam, p.into())]) as f64
        })
        .collect();
    vals.iter().sum::<f64>() / vals.len() as f64
}

#[test]
fn an_all_transparent_transfer_function_gives_the_background() {
    let gpu = gpu();
    let vol = cube(|p| (p.x * 0.3).sin() as f32 + 1.0);
    let clear = Transfer {
        points: vec![(0.0, [1.0, 0.0, 0.0], 0.0), (2.0, [0.0, 1.0, 0.0], 0.0)],
        rows: vec![],
    };
    let scene = Scene::new(Some((vol, clear)), vec![]);
    let mut v = view(top_camera(false));
    v.background = [0.2, 0.4, 0.6];
    for m in [
        Method::Combined,
        Method::Dos,
        Method::Vicinity,
        Method::Ea,
        Method::Phong,
    ] {
        let mut s = settings(m);
        s.fxaa = true;
        let out = scene.render(&gpu, &v, &s);
        let worst = out
            .image
            .iter()
            .flat_map(|p| [p[0] - 0.2, p[1] - 0.4, p[2] - 0.6, p[3]])
            .fold(0.0f32, |a, d| a.max(d.abs()));
        assert!(worst < 1e-5, "{m:?}: {worst}");
    }
}

/// Three tubes along x at depths below the top of a uniform medium (z = 10): 4.5, 9.5 and
/// 14.5 units of medium above their tops.
fn depth_scene() -> (Scene, [[f64; 3]; 3]) {
    let vol = cube(|_| 1.0);
    let lines = [
        [[-4.0, -5.0, 5.0], [4.0, -5.0, 5.0]],
        [[-4.0, 0.0, 0.0], [4.0, 0.0, 0.0]],
        [[-4.0, 5.0, -5.0], [4.0, 5.0, -5.0]],
    ];
    let tops = [[0.0, -5.0, 5.5], [0.0, 0.0, 0.5], [0.0, 5.0, -4.5]];
    (
        Scene::new(Some((vol, medium(0.15))), vec![tubes(&lines, 0.5)]),
        tops,
    )
}

#[test]
fn partial_occlusion_in_a_uniform_medium_is_the_transmittance_above_the_surface() {
    let gpu = gpu();
    let (scene, tops) = depth_scene();
    for perspective in [false, true] {
        let cam = top_camera(perspective);
        // A cone of 45 degrees: its light's mean path through a slab is 1.18 slabs, so the
        // light crossing the slabs straight along the ray would miss by 0.035-0.058 here.
        let mut s = settings(Method::Dos);
        s.theta_deg = 45.0;
        let out = scene.render(&gpu, &view(cam), &s);
        let mut last = 1.0;
        for t in tops {
            // Along the tube's top line, away from its ends.
            let got = mean_along(&out, &cam, [-2.0, t[1], t[2]], [2.0, t[1], t[2]], |a| {
                a.partial
            });
            // The light reaching the top through the medium above it (cos ~ 1 at the image
            // centre): the mean over the cone's directions, each a path 1 / cos(phi) times the
            // depth (cos(phi) uniform on [cos(theta), 1]).
            let c = s.theta_deg.to_radians().cos();
            let expect = (0..1000)
                .map(|i| {
                    let cos = 1.0 - (1.0 - c) * (i as f64 + 0.5) / 1000.0;
                    (-0.15 * (10.0 - t[2]) / cos).exp()
                })
                .sum::<f64>()
                / 1000.0;
            eprintln!(
                "perspective {perspective}: z {}: partial {got:.4}, expected {expect:.4}",
                t[2]
            );
            assert!(
                (got - expect).abs() < 0.012,
                "perspective {perspective}: top at z = {}: partial {got}, expected {expect}",
                t[2]
            );
            assert!(got < last, "occlusion must fall with depth");
            last = got;
        }
        // The ea method computes no volumetric occlusion: the terms stay 1.
        let ea = scene.render(&gpu, &view(cam), &settings(Method::Ea));
        let t = tops[2];
        assert_eq!(ea.aov[pixel(&cam, t)].partial, 1.0);
    }
}

#[test]
fn a_tube_darkens_the_volume_behind_it_and_the_column_rule_darkens_more() {
    let gpu = gpu();
    let cam = top_camera(false);
    // A tube above the medium (z = 12 over a medium ending at z = 10), a wide cone.
    let vol = cube(|_| 1.0);
    let above = Scene::new(
        Some((vol.clone(), medium(0.1))),
        vec![tubes(&[[[-6.0, 0.0, 11.5], [6.0, 0.0, 11.5]]], 1.0)],
    );
    let v = view(cam);
    let mut s = settings(Method::Dos);
    s.theta_deg = 60.0;
    let lit = {
        let mut s0 = s.clone();
        s0.geometry_extinction = 0.0;
        above.render(&gpu, &v, &s0)
    };
    let shadowed = above.render(&gpu, &v, &s);
    // Beside the tube's silhouette (radius 1: the edge at y = 1), the volume is darker where
    // the tube's shadow spreads; far away nothing changes.
    let near =
        |o: &Output| mean_along(o, &cam, [-3.0, 1.6, 0.0], [3.0, 1.6, 0.0], |a| a.volumetric);
    let far = |o: &Output| mean_along(o, &cam, [-3.0, 7.0, 0.0], [3.0, 7.0, 0.0], |a| a.volumetric);
    eprintln!(
        "volumetric beside the tube {:.3} (without its extinction {:.3}), far {:.3}",
        near(&shadowed),
        near(&lit),
        far(&shadowed)
    );
    assert!(
        near(&shadowed) < near(&lit) - 0.03,
        "beside the tube: {} with its extinction, {} without",
        near(&shadowed),
        near(&lit)
    );
    assert!((far(&shadowed) - far(&lit)).abs() < 0.01);
    // Inside the medium, the paper's endless column behind the tube shadows more than the
    // tube's real thickness, and never less.
    let inside = Scene::new(
        Some((vol, medium(0.1))),
        vec![tubes(&[[[-6.0, 0.0, 6.0], [6.0, 0.0, 6.0]]], 1.0)],
    );
    let thick = inside.render(&gpu, &v, &s);
    let mut sc = s.clone();
    sc.column = true;
    let column = inside.render(&gpu, &v, &sc);
    let mut most = 0.0f32;
    for (a, b) in thick.aov.iter().zip(&column.aov) {
        assert!(b.volumetric <= a.volumetric + 1e-4);
        most = most.max(a.volumetric - b.volumetric);
    }
    eprintln!("column rule: up to {most:.3} darker");
    assert!(
        most > 0.02,
        "the column rule changed the volume by {most} at most"
    );
}

#[test]
fn a_dense_volume_in_front_of_a_tube_darkens_it() {
    let gpu = gpu();
    let cam = top_camera(false);
    // A dense slab (z in [4, 6]) over the left half (x < 0) of a tube at z = 0.
    let vol = cube(|p| {
        if p.x < 0.0 && (4.0..=6.0).contains(&p.z) {
            1.0
        } else {
            0.0
        }
    });
    let scene = Scene::new(
        Some((vol, medium(1.0))),
        vec![tubes(&[[[-8.0, 0.0, 0.0], [8.0, 0.0, 0.0]]], 0.7)],
    );
    let v = view(cam);
    for m in [Method::Dos, Method::Combined] {
        let out = scene.render(&gpu, &v, &settings(m));
        let left = mean_along(&out, &cam, [-7.0, 0.0, 0.7], [-3.0, 0.0, 0.7], |a| {
            a.partial
        });
        let right = mean_along(&out, &cam, [3.0, 0.0, 0.7], [7.0, 0.0, 0.7], |a| a.partial);
        eprintln!("{m:?}: partial under the slab {left:.3}, beside it {right:.3}");
        assert!(
            left < 0.3 && right > 0.85,
            "{m:?}: left {left}, right {right}"
        );
        // And the shaded tube is darker there (beyond what the slab's own attenuation of the
        // view does: compare with the ea method's image).
        let ea = scene.render(&gpu, &v, &settings(Method::Ea));
        let p = pixel(&cam, [-5.0, 0.0, 0.7]);
        assert!(out.image[p][0] < ea.image[p][0] - 0.02, "{m:?}");
    }
}

/// Tubes along y: two side by side at the top, one in the groove between them, one alone at
/// the groove's depth.
fn groove() -> (Vec<TubeMesh>, [f64; 3], [f64; 3]) {
    let lines = [
        [[-1.2, -6.0, 0.0], [-1.2, 6.0, 0.0]],
        [[1.2, -6.0, 0.0], [1.2, 6.0, 0.0]],
        [[0.0, -6.0, -0.8], [0.0, 6.0, -0.8]],
        [[6.0, -6.0, -0.8], [6.0, 6.0, -0.8]],
    ];
    (vec![tubes(&lines, 0.5)], [0.0, 0.0, -0.3], [6.0, 0.0, -0.3])
}

#[test]
fn a_tube_in_a_groove_gets_more_vicinity_occlusion_than_an_isolated_one() {
    let gpu = gpu();
    let cam = top_camera(false);
    let (meshes, in_groove, alone) = groove();
    let scene = Scene::new(None, meshes);
    let mut s = settings(Method::Vicinity);
    s.theta_deg = 45.0;
    s.vicinity_samples = 64;
    let out = scene.render(&gpu, &view(cam), &s);
    let line = |c: [f64; 3]| {
        mean_along(&out, &cam, [c[0], -4.0, c[2]], [c[0], 4.0, c[2]], |a| {
            a.vicinity
        })
    };
    let (g, a) = (line(in_groove), line(alone));
    eprintln!("vicinity: groove {g:.3}, alone {a:.3}");
    assert!(g < a - 0.1, "groove {g}, alone {a}");
    assert!(a > 0.8, "an isolated tube is mostly open: {a}");
    // Off-screen samples are left out: a tube cut by the image border is as open as one in the
    // middle.
    let edge = mean_along(&out, &cam, [6.0, 11.5, -0.3], [6.0, 11.9, -0.3], |a| {
        a.vicinity
    });
    assert!(
        (edge - a).abs() < 0.1,
        "at the border {edge}, in the middle {a}"
    );
}

#[test]
fn min_and_product_combine_as_equations_7_and_8() {
    let gpu = gpu();
    let cam = top_camera(false);
    let (meshes, in_groove, _) = groove();
    // The groove under a uniform medium, so that both terms are below 1.
    let scene = Scene::new(Some((cube(|_| 1.0), medium(0.05))), meshes);
    let v = view(cam);
    let mut s = settings(Method::Combined);
    s.theta_deg = 45.0;
    let min = scene.render(&gpu, &v, &s);
    s.combine = Combine::Product;
    let product = scene.render(&gpu, &v, &s);
    let mut gap = 0.0f32;
    for (a, b) in min.aov.iter().zip(&product.aov) {
        assert!((a.combined - a.partial.min(a.vicinity)).abs() < 1e-6);
        assert!((b.combined - b.partial * b.vicinity).abs() < 1e-6);
        assert!(b.combined <= a.combined + 1e-6);
        gap = gap.max(a.combined - b.combined);
    }
    assert!(gap > 0.05, "product and min agree everywhere (gap {gap})");
    // Fig. 6: where the volumetric term dominates, min loses the vicinity term's variation
    // across the groove; the product keeps it.
    let p = pixel(&cam, in_groove);
    let q = pixel(&cam, [1.2, 0.0, 0.5]);
    assert!(
        (product.aov[p].combined - product.aov[q].combined).abs()
            > (min.aov[p].combined - min.aov[q].combined).abs() - 1e-6
    );
}

#[test]
fn the_method_table_decides_the_terms_composite_folds() {
    let gpu = gpu();
    let cam = top_camera(false);
    let (meshes, _, _) = groove();
    let scene = Scene::new(Some((cube(|_| 1.0), medium(0.05))), meshes);
    let v = view(cam);
    let mut s = settings(Method::Combined);
    s.theta_deg = 45.0;
    let combined = scene.render(&gpu, &v, &s);
    let names = |o: &Output| o.terms.iter().map(|t| t.0).collect::<Vec<_>>();
    assert_eq!(names(&combined), ["partial", "vicinity"]);
    // An empty surface-AO slot leaves combined with the partial term only: dos's image.
    s.surface_ao = engine::method::SurfaceAo::None;
    let no_ao = scene.render(&gpu, &v, &s);
    assert_eq!(names(&no_ao), ["partial"]);
    s.method = Method::Dos;
    s.surface_ao = engine::method::SurfaceAo::Vicinity;
    let dos = scene.render(&gpu, &v, &s);
    assert_eq!(names(&dos), ["partial"]);
    assert_eq!(no_ao.image, dos.image);
    assert_ne!(combined.image, dos.image);
    // Terms a method does not run read 1 in the AOVs, and ea folds none.
    s.method = Method::Ea;
    let ea = scene.render(&gpu, &v, &s);
    assert!(ea.terms.is_empty());
    assert!(ea
        .aov
        .iter()
        .all(|a| a.partial == 1.0 && a.vicinity == 1.0 && a.combined == 1.0));
    assert!(dos.aov.iter().all(|a| a.vicinity == 1.0));
    let channels: Vec<String> = dos.aov_channels().into_iter().map(|c| c.0).collect();
    assert_eq!(
        channels,
        [
            "occlusion.volumetric",
            "occlusion.partial",
            "occlusion.vicinity",
            "occlusion.lineao",
            "occlusion.combined",
            "Z"
        ]
    );
}

#[test]
fn clipping_planes_remove_the_volume_and_optionally_the_tubes() {
    let gpu = gpu();
    let cam = top_camera(false);
    let mut scene = Scene::new(
        Some((cube(|_| 1.0), medium(0.3))),
        vec![tubes(&[[[-8.0, 0.0, 11.0], [8.0, 0.0, 11.0]]], 0.5)],
    );
    let mut v = view(cam);
    v.clip = vec![([1.0, 0.0, 0.0], 0.0)]; // keep x <= 0
    let out = scene.render(&gpu, &v, &settings(Method::Ea));
    let right = pixel(&cam, [5.0, 5.0, 0.0]);
    let left = pixel(&cam, [-5.0, 5.0, 0.0]);
    assert!(out.image[right][3] < 1e-6, "volume left at x > 0");
    assert!(out.image[left][3] > 0.9);
    // Volume-only clipping keeps the tube whole; clipping the tubes too cuts it.
    let tube_right = pixel(&cam, [5.0, 0.0, 11.5]);
    assert_eq!(out.image[tube_right][3], 1.0);
    scene.tube_clip = v.clip.clone();
    let cut = scene.render(&gpu, &v, &settings(Method::Ea));
    assert!(cut.image[tube_right][3] < 1e-6);
    assert_eq!(cut.image[pixel(&cam, [-5.0, 0.0, 11.5])][3], 1.0);
}

#[test]
fn the_cone_model_spreads_shadows_independently_of_the_slice_count() {
    let gpu = gpu();
    let cam = top_camera(false);
    // A small dense block (2 x 2 x 1 around (0, 0, 8)) shadows a tube along x 16 units below.
    let vol = cube(|p| {
        if p.x.abs() <= 1.0 && p.y.abs() <= 1.0 && (7.5..=8.5).contains(&p.z) {
            1.0
        } else {
            0.0
        }
    });
    let scene = Scene::new(
        Some((vol, medium(5.0))),
        vec![tubes(&[[[-9.0, 0.0, -8.0], [9.0, 0.0, -8.0]]], 0.5)],
    );
    let profile = |cone: bool, d: f64| -> Vec<f64> {
        let bounds = [DVec3::splat(-12.0), DVec3::splat(12.0)];
        let v = EaView::span(bounds, 1.0, cam, W, H, None, Some(d), [1.0; 3]).unwrap();
        let mut s = settings(Method::Dos);
        s.theta_deg = 20.0;
        s.cone = cone;
        s.occlusion_cell = Some(1);
        let out = scene.render(&gpu, &v, &s);
        (0..=16)
            .map(|i| out.aov[pixel(&cam, [-8.0 + i as f64, 0.0, -7.5])].partial as f64)
            .collect()
    };
    let diff = |a: &[f64], b: &[f64]| {
        a.iter()
            .zip(b)
            .map(|(x, y)| (x - y).abs())
            .fold(0.0, f64::max)
    };
    let (paper_coarse, paper_fine) = (profile(false, 0.5), profile(false, 0.125));
    let (cone_coarse, cone_fine) = (profile(true, 0.5), profile(true, 0.125));
    let (dp, dc) = (
        diff(&paper_coarse, &paper_fine),
        diff(&cone_coarse, &cone_fine),
    );
    eprintln!("paper: {paper_coarse:.2?}\n       {paper_fine:.2?}\ncone:  {cone_coarse:.2?}\n       {cone_fine:.2?}");
    eprintln!("slice-count change: paper {dp:.3}, cone {dc:.3}");
    assert!(dc < 0.06, "the cone model moved by {dc} with 4x the slices");
    assert!(dp > 2.0 * dc, "paper {dp}, cone {dc}");
    // The cone's shadow reaches about L tan(theta) = 15.5 tan(20 deg) = 5.6 units from the
    // block's edge: darker than open at 4 units from the centre, open at 8.
    let at = |x: f64| cone_fine[(x + 8.0) as usize];
    assert!(
        at(0.0) < 0.9 && at(4.0) < 0.99 && at(8.0) > 0.97,
        "{cone_fine:?}"
    );
}

#[test]
fn a_two_dimensional_transfer_function_shows_boundaries_only() {
    let gpu = gpu();
    let cam = top_camera(false);
    // A solid ball (value 1 inside radius 6): a 1-D function makes it a dense blob, a 2-D one
    // with extinction only at high gradient magnitude a shell, seen as a ring.
    let ball = cube(|p| if p.length() < 6.0 { 1.0 } else { 0.0 });
    let one_d = Transfer {
        points: vec![(0.0, [1.0; 3], 0.0), (1.0, [1.0; 3], 0.3)],
        rows: vec![],
    };
    let two_d = Transfer {
        points: vec![
            (0.0, [1.0; 3], 0.0),
            (1.0, [1.0; 3], 0.0),
            (0.0, [1.0; 3], 0.3),
            (1.0, [1.0; 3], 0.3),
        ],
        rows: vec![(0.0, 0), (0.4, 2)],
    };
    let v = view(cam);
    let alpha = |tf: Transfer, at: [f64; 3]| {
        let scene = Scene::new(Some((ball.clone(), tf)), vec![]);
        scene.render(&gpu, &v, &settings(Method::Ea)).image[pixel(&cam, at)][3]
    };
    let (c1, r1) = (
        alpha(one_d.clone(), [0.0; 3]),
        alpha(one_d, [5.2, 0.0, 0.0]),
    );
    let (c2, r2) = (
        alpha(two_d.clone(), [0.0; 3]),
        alpha(two_d, [5.2, 0.0, 0.0]),
    );
    eprintln!("1-D: centre {c1:.3}, rim {r1:.3}; 2-D: centre {c2:.3}, rim {r2:.3}");
    assert!(c1 > r1, "1-D: the centre is the densest");
    assert!(r2 > c2 + 0.1, "2-D: the rim outshines the centre");
    assert!(c2 < c1 - 0.1);
}

#[test]
fn the_gpu_agrees_with_the_monte_carlo_reference_on_tubes_in_a_medium() {
    use occlusion::reference::{self, RefSettings, RefTubes, RefVolume};
    use occlusion::reference_tubes::TubeScene;
    let gpu = gpu();
    let (scene, tops) = depth_scene();
    let cam = top_camera(false);
    let v = view(cam);
    let mut s = settings(Method::Dos);
    s.msaa = 1;
    let out = scene.render(&gpu, &v, &s);
    let (vol, data, tf) = scene.vol.as_ref().unwrap();
    let ts = TubeScene::new(&scene.meshes, &[]);
    let r = reference::render(
        &RefVolume { vol, data, tf },
        Some(&RefTubes {
            scene: &ts,
            sigma: s.geometry_extinction,
            light: s.light,
            column: None,
        }),
        &v,
        &RefSettings {
            theta_deg: Some(s.theta_deg),
            spp: 2048,
            seed: 7,
            vicinity_range: None,
        },
    );
    for t in tops {
        // The tube's top line, where the pixel is all tube (no silhouette).
        let (mut g, mut c, mut se) = (0.0, 0.0, 0.0f64);
        for i in 0..5 {
            let p = pixel(&cam, [-2.0 + i as f64, t[1], t[2]]);
            g += out.image[p][0] as f64 / 5.0;
            c += r.rgb[p][0] / 5.0;
            se = se.max(r.stderr[p]);
        }
        eprintln!(
            "tube top at z {}: gpu {g:.4}, reference {c:.4} (se {se:.4})",
            t[2]
        );
        assert!(
            (g - c).abs() < 0.02 + 3.0 * se,
            "z {}: gpu {g}, reference {c}",
            t[2]
        );
    }
}

#[test]
fn the_reference_follows_the_column_rule_as_the_gpu_does() {
    use occlusion::reference::{self, ColumnMap, RefSettings, RefTubes, RefVolume};
    use occlusion::reference_tubes::TubeScene;
    let gpu = gpu();
    let cam = top_camera(false);
    let scene = Scene::new(
        Some((cube(|_| 1.0), medium(0.1))),
        vec![tubes(&[[[-6.0, 0.0, 6.0], [6.0, 0.0, 6.0]]], 1.0)],
    );
    let v = view(cam);
    let (vol, data, tf) = scene.vol.as_ref().unwrap();
    let ts = TubeScene::new(&scene.meshes, &[]);
    let cm = ColumnMap::new(&ts, &v, 4);
    let mut s = settings(Method::Dos);
    s.theta_deg = 60.0;
    let reference = |column: Option<&ColumnMap>| {
        reference::render(
            &RefVolume { vol, data, tf },
            Some(&RefTubes {
                scene: &ts,
                sigma: s.geometry_extinction,
                light: s.light,
                column,
            }),
            &v,
            &RefSettings {
                theta_deg: Some(60.0),
                spp: 512,
                seed: 3,
                vicinity_range: None,
            },
        )
    };
    let (inside, column) = (reference(None), reference(Some(&cm)));
    // Beside the tube (its silhouette at y = 1), mean volumetric occlusion along a line.
    let line = |img: &reference::RefImage| {
        (0..7)
            .map(|i| img.volumetric[pixel(&cam, [-3.0 + i as f64, 1.8, 0.0])])
            .sum::<f64>()
            / 7.0
    };
    let (ri, rc) = (line(&inside), line(&column));
    let mut sc = s.clone();
    sc.column = true;
    let gi = scene.render(&gpu, &v, &s);
    let gc = scene.render(&gpu, &v, &sc);
    let gline =
        |o: &Output| mean_along(o, &cam, [-3.0, 1.8, 0.0], [3.0, 1.8, 0.0], |a| a.volumetric);
    eprintln!(
        "beside the tube: reference inside {ri:.3}, column {rc:.3}; gpu inside {:.3}, column {:.3}",
        gline(&gi),
        gline(&gc)
    );
    // Both renderers darken the volume more under the column rule.
    assert!(rc < ri - 0.02, "reference: column {rc}, inside {ri}");
    assert!(gline(&gc) < gline(&gi) - 0.02);
}

#[test]
fn a_long_lived_renderer_draws_new_cameras_without_compiling_or_uploading() {
    let gpu = gpu();
    let s = Scene::new(
        Some((cube(|p| (p.length() < 8.0) as u8 as f32), medium(0.2))),
        vec![tubes(&[[[-9.0, 0.0, 4.0], [9.0, 0.0, 4.0]]], 1.0)],
    );
    let (vol, _, tf) = s.vol.as_ref().unwrap();
    let data = s.packed.as_ref().unwrap();
    let r = renderer::Renderer::new(&gpu);
    let scene = r
        .upload(Some(&VolumeInput { vol, data, tf }), &s.meshes, &[], None)
        .unwrap();
    let opts = renderer::DrawOptions::default();
    let cams = [top_camera(true), top_camera(false)];
    let first: Vec<Output> = cams
        .iter()
        .map(|c| {
            r.draw(&scene, &view(*c), &[], &settings(Method::Combined), opts)
                .unwrap()
        })
        .collect();
    let made = gpu.pool_made();
    // Later frames at either camera compile, allocate and upload nothing new, and give the
    // same images as the first ones (nothing left over from the frame before).
    for (c, want) in cams.iter().zip(&first).rev() {
        let again = r
            .draw(&scene, &view(*c), &[], &settings(Method::Combined), opts)
            .unwrap();
        assert_eq!(gpu.pool_made(), made, "a frame made new pooled objects");
        assert_eq!(again.image, want.image);
        assert!(
            again.timings.passes.is_empty(),
            "per-pass timing only when asked"
        );
    }
    // A new transfer function keeps the samples on the GPU and gives the image a fresh
    // upload with that function gives.
    let mut scene = scene;
    let denser = medium(0.6);
    r.set_transfer(
        &mut scene,
        &VolumeInput {
            vol,
            data,
            tf: &denser,
        },
    )
    .unwrap();
    let swapped = r
        .draw(
            &scene,
            &view(cams[0]),
            &[],
            &settings(Method::Combined),
            opts,
        )
        .unwrap();
    let fresh_tf = r
        .upload(
            Some(&VolumeInput {
                vol,
                data,
                tf: &denser,
            }),
            &s.meshes,
            &[],
            None,
        )
        .unwrap();
    let want = r
        .draw(
            &fresh_tf,
            &view(cams[0]),
            &[],
            &settings(Method::Combined),
            opts,
        )
        .unwrap();
    assert_eq!(swapped.image, want.image);
    assert_ne!(swapped.image, first[0].image);
    // The same image as the one-shot path (a new upload).
    let fresh = s.render(&gpu, &view(cams[1]), &settings(Method::Combined));
    assert_eq!(fresh.image, first[1].image);
    // Per-pass times, by GPU timestamps where the adapter has them (not on CPU adapters).
    let names: Vec<&String> = fresh.timings.passes.keys().collect();
    assert_eq!(
        names,
        ["composite", "gbuffer", "light", "march", "vicinity"],
        "the passes of combined without FXAA"
    );
    assert!(fresh
        .timings
        .passes
        .values()
        .all(|ms| ms.is_finite() && *ms >= 0.0));
    let want = if gpu.has_pass_timestamps() {
        renderer::PassClock::Timestamps
    } else {
        renderer::PassClock::Fences
    };
    assert_eq!(fresh.timings.pass_clock, Some(want));
}

#[test]
fn lines_shadow_the_volume_through_their_proxy_radius_and_lineao_folds_with_partial() {
    use engine::method::SurfaceAo;
    use engine::renderer::{DrawOptions, Renderer};
    use tubes::lines::{LineSet, LineWidth};
    let gpu = gpu();
    let cam = top_camera(false);
    let vol = cube(|_| 1.0);
    let data = Samples::pack(occlusion::emission_absorption::prepare(
        &vol.select(None).unwrap().data,
    ));
    let tf = medium(0.1);
    let input = VolumeInput {
        vol: &vol,
        data: &data,
        tf: &tf,
    };
    // A 6-pixel line inside the medium (z = 6).
    let mut st = tubes::Streamlines::new();
    st.push(&[
        glam::Vec3::new(-6.0, 0.0, 6.0),
        glam::Vec3::new(6.0, 0.0, 6.0),
    ]);
    let set = LineSet::new(
        &st,
        &tubes::tube_mesh::ColorMode::Constant([0.75; 3]),
        LineWidth::Pixels(6.0),
        false,
    );
    let mut s = settings(Method::Combined);
    s.theta_deg = 60.0;
    s.surface_ao = SurfaceAo::LineAo;
    let r = Renderer::new(&gpu);
    let render = |proxy: f32| {
        let mut l = set.clone();
        l.proxy_radius = proxy;
        let scene = r.upload(Some(&input), &[], &[l], None).unwrap();
        r.draw(&scene, &view(cam), &[], &s, DrawOptions::default())
            .unwrap()
    };
    let (none, proxy) = (render(0.0), render(1.0));
    let beside =
        |o: &Output| mean_along(o, &cam, [-3.0, 1.8, 0.0], [3.0, 1.8, 0.0], |a| a.volumetric);
    assert!(
        beside(&proxy) < beside(&none) - 0.02,
        "beside the line: {} with a proxy radius of 1, {} without",
        beside(&proxy),
        beside(&none)
    );
    let names: Vec<&str> = proxy.terms.iter().map(|(n, _)| *n).collect();
    assert_eq!(names, ["partial", "lineao"]);
    // The line is in the medium: partial occlusion darkens it (1 - exp(-0.1 x 4) above it).
    let partial = mean_along(&proxy, &cam, [-3.0, 0.0, 6.0], [3.0, 0.0, 6.0], |a| {
        a.partial
    });
    assert!(partial < 0.9, "{partial}");
}

/// Five 6-pixel grey lines across the view at different depths.
fn five_lines() -> tubes::lines::LineSet {
    use tubes::lines::{LineSet, LineWidth};
    let mut st = tubes::Streamlines::new();
    for k in 0..5 {
        let y = k as f32 * 2.0 - 4.0;
        st.push(&[
            glam::Vec3::new(-6.0, y, k as f32),
            glam::Vec3::new(6.0, y + 1.0, 4.0 - k as f32),
        ]);
    }
    LineSet::new(
        &st,
        &tubes::tube_mesh::ColorMode::Constant([0.75; 3]),
        LineWidth::Pixels(6.0),
        false,
    )
}

/// With nothing in the light (no volume, only lines that stand for no tubes: proxy radius 0),
/// `dos` and `combined` sweep no light volume (it would be 1 everywhere): no `light` grid,
/// partial occlusion 1, and the image of a frame that swept one through lines whose proxy
/// radius is a hair's breadth (which cast next to nothing).
#[test]
fn lines_that_cast_no_shadow_alone_sweep_no_light_volume() {
    use engine::renderer::{DrawOptions, Renderer};
    let gpu = gpu();
    let cam = top_camera(false);
    let set = five_lines();
    let r = Renderer::new(&gpu);
    for method in [Method::Dos, Method::Combined] {
        let s = settings(method);
        let render = |proxy: f32| {
            let mut l = set.clone();
            l.proxy_radius = proxy;
            let scene = r.upload(None, &[], &[l], None).unwrap();
            r.draw(&scene, &view(cam), &[], &s, DrawOptions::default())
                .unwrap()
        };
        let (none, hair) = (render(0.0), render(1e-6));
        assert!(none.light.is_none(), "{method:?}: a light volume swept");
        assert!(
            hair.light.is_some(),
            "{method:?}: lines with a proxy radius cast light"
        );
        let covered = none.aov.iter().filter(|a| a.depth > 0.0).count();
        assert!(covered > 200, "{covered} pixels");
        assert!(none.aov.iter().all(|a| a.partial == 1.0));
        let worst = none
            .image
            .iter()
            .zip(&hair.image)
            .map(|(p, q)| (0..3).map(|c| (p[c] - q[c]).abs()).fold(0.0, f32::max))
            .fold(0.0, f32::max);
        assert!(
            worst <= 1.0 / 255.0,
            "{method:?}: a pixel differs by {worst}"
        );
    }
}

/// Without a volume, translucent layers, light or partial term the eye march has nothing to
/// do and its buffers are cleared instead (`SlicePass::record_march`): lines alone under `ea`
/// and `vicinity` draw the image and AOVs of the same lines in a volume that absorbs nothing
/// (which the march walks), also right after a frame whose march left colour in the
/// (pooled) buffers.
#[test]
fn lines_alone_skip_the_march_and_draw_what_an_empty_volume_marched_draws() {
    use engine::renderer::{DrawOptions, Renderer};
    let gpu = gpu();
    let cam = top_camera(false);
    let set = five_lines();
    let vol = cube(|_| 1.0);
    let data = Samples::pack(occlusion::emission_absorption::prepare(
        &vol.select(None).unwrap().data,
    ));
    let (dense, empty) = (medium(0.3), medium(0.0));
    let r = Renderer::new(&gpu);
    for method in [Method::Ea, Method::Vicinity] {
        let s = settings(method);
        let render = |tf: Option<&Transfer>| {
            let input = tf.map(|tf| VolumeInput {
                vol: &vol,
                data: &data,
                tf,
            });
            let scene = r
                .upload(input.as_ref(), &[], std::slice::from_ref(&set), None)
                .unwrap();
            r.draw(&scene, &view(cam), &[], &s, DrawOptions::default())
                .unwrap()
        };
        let lit = render(Some(&dense));
        assert!(lit.image.iter().any(|p| p[3] > 0.5 && p[0] > 0.2));
        let alone = render(None);
        let marched = render(Some(&empty));
        let covered = alone.aov.iter().filter(|a| a.depth > 0.0).count();
        assert!(covered > 200, "{covered} pixels");
        let worst = |f: &dyn Fn(usize) -> f32| (0..alone.image.len()).map(f).fold(0.0, f32::max);
        let image = worst(&|i| {
            (0..4)
                .map(|c| (alone.image[i][c] - marched.image[i][c]).abs())
                .fold(0.0, f32::max)
        });
        let aov = worst(&|i| {
            let (a, b) = (&alone.aov[i], &marched.aov[i]);
            (a.volumetric - b.volumetric)
                .abs()
                .max((a.depth - b.depth).abs())
        });
        assert!(
            image <= 1e-6 && aov <= 1e-6,
            "{method:?}: image differs by {image}, AOVs by {aov}"
        );
    }
}
