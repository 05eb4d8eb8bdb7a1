//! Line sets in the G-buffer on whatever adapter this machine has (lavapipe in CI): strips of
//! the asked width in pixels and in world units, watertight joints, no NaN for degenerate
//! segments, clip planes, the view-facing normal of illuminated lines and the cylinder
//! profile, and lines beside tubes in one depth test.

mod common;
use common::{gpu, top_camera};
use engine::gpu::Gpu;
use engine::method::{Method, Settings};
use engine::renderer::{DrawOptions, Output, Renderer};
use glam::{DVec3, Vec3};
use occlusion::camera::Camera;
use occlusion::emission_absorption::EaView;
use tubes::lines::{LineSet, LineWidth};
use tubes::tube_mesh::ColorMode;

const W: u32 = 64;
const H: u32 = 64;

fn view(cam: Camera) -> EaView {
    let bounds = [DVec3::splat(-12.0), DVec3::splat(12.0)];
    EaView::span(bounds, 1.0, cam, W, H, None, Some(0.5), [0.0, 0.0, 0.0]).unwrap()
}

fn lines(polylines: &[Vec<[f32; 3]>], width: LineWidth, cylinder: bool) -> LineSet {
    let mut s = tubes::Streamlines::new();
    for p in polylines {
        let pts: Vec<Vec3> = p.iter().map(|q| Vec3::from(*q)).collect();
        s.push(&pts);
    }
    LineSet::new(&s, &ColorMode::Constant([1.0; 3]), width, cylinder)
}

fn settings() -> Settings {
    Settings {
        method: Method::Illuminated,
        fxaa: false,
        msaa: 1,
        ..Default::default()
    }
}

fn render(gpu: &Gpu, sets: &[LineSet], cam: Camera, clip: &[([f64; 3], f64)]) -> Output {
    let r = Renderer::new(gpu);
    let scene = r.upload(None, &[], sets, None).unwrap();
    r.draw(
        &scene,
        &view(cam),
        clip,
        &settings(),
        DrawOptions::default(),
    )
    .unwrap()
}

/// Covered pixels (a surface: linear depth above 0) in column `x`.
fn column_coverage(o: &Output, x: usize) -> usize {
    (0..H as usize)
        .filter(|&y| o.aov[x + W as usize * y].depth > 0.0)
        .count()
}

#[test]
fn strips_are_as_wide_as_asked_in_pixels_and_in_world_units() {
    let gpu = gpu();
    // A horizontal line through y = 0 (the boundary between pixel rows 31 and 32).
    let line = vec![[-20.0, 0.0, 0.0], [20.0, 0.0, 0.0]];
    for (w, want) in [(1.0, 1), (4.0, 4), (9.0, 9)] {
        let o = render(
            &gpu,
            &[lines(
                std::slice::from_ref(&line),
                LineWidth::Pixels(w),
                false,
            )],
            top_camera(false),
            &[],
        );
        let got = column_coverage(&o, 20);
        assert!((got as i64 - want as i64).abs() <= 1, "{w} px: {got} rows");
    }
    // 3 world units at 8/3 pixels a unit: 8 pixels, under both projections' scale.
    let o = render(
        &gpu,
        &[lines(
            std::slice::from_ref(&line),
            LineWidth::World(3.0),
            false,
        )],
        top_camera(false),
        &[],
    );
    let got = column_coverage(&o, 20);
    assert!((7..=9).contains(&got), "world width: {got} rows");
    // Under perspective a world width thins with distance, a pixel width does not.
    let near = vec![[-20.0, -4.0, 8.0], [20.0, -4.0, 8.0]];
    let far = vec![[-20.0, 4.0, -8.0], [20.0, 4.0, -8.0]];
    let o = render(
        &gpu,
        &[lines(
            &[near.clone(), far.clone()],
            LineWidth::World(2.0),
            false,
        )],
        top_camera(true),
        &[],
    );
    let rows: Vec<usize> = (0..H as usize)
        .filter(|&y| o.aov[20 + W as usize * y].depth > 0.0)
        .collect();
    let (top, bottom): (Vec<usize>, Vec<usize>) = rows.iter().partition(|&&y| y < H as usize / 2);
    assert!(
        bottom.len() > top.len(),
        "near {} rows, far {}",
        bottom.len(),
        top.len()
    );
    let o = render(
        &gpu,
        &[lines(&[near, far], LineWidth::Pixels(4.0), false)],
        top_camera(true),
        &[],
    );
    let covered = column_coverage(&o, 20);
    assert!(
        (6..=10).contains(&covered),
        "two 4-pixel lines: {covered} rows"
    );
}

#[test]
fn joints_are_watertight_and_degenerate_segments_give_no_nan() {
    let gpu = gpu();
    // A zigzag with sharp turns, a repeated point, and a segment along the view ray.
    let zigzag = vec![
        [-10.0, -8.0, 0.0],
        [-6.0, 8.0, 0.0],
        [-2.0, -8.0, 0.0],
        [-2.0, -8.0, 0.0],
        [2.0, 8.0, 0.0],
        [2.0, 8.0, 6.0],
        [6.0, -8.0, 6.0],
        [10.0, 8.0, 6.0],
    ];
    let set = lines(std::slice::from_ref(&zigzag), LineWidth::Pixels(3.0), false);
    let cam = top_camera(false);
    let o = render(&gpu, std::slice::from_ref(&set), cam, &[]);
    assert!(o.image.iter().flatten().all(|v| v.is_finite()));
    assert!(o.aov.iter().all(|a| a.depth.is_finite()));
    // Every point along every segment, and around every joint, is covered.
    for seg in zigzag.windows(2) {
        let (a, b) = (
            DVec3::from(seg[0].map(f64::from)),
            DVec3::from(seg[1].map(f64::from)),
        );
        for k in 0..=40 {
            let p = a + (b - a) * (k as f64 / 40.0);
            let (x, y, _) = cam.to_pixel(p, W as usize, H as usize).unwrap();
            let i = x as usize + W as usize * y as usize;
            assert!(o.aov[i].depth > 0.0, "a gap at {p} (pixel {x}, {y})");
        }
    }
    // The segment along the view ray still covers its pixel.
    let (x, y, _) = cam
        .to_pixel(DVec3::new(2.0, 8.0, 3.0), W as usize, H as usize)
        .unwrap();
    assert!(o.aov[x as usize + W as usize * y as usize].depth > 0.0);
}

#[test]
fn illuminated_lines_face_the_eye_and_cylinders_turn_away_at_their_edges() {
    let gpu = gpu();
    let line = vec![[-20.0, 0.0, 0.0], [20.0, 0.0, 0.0]];
    let flat = render(
        &gpu,
        &[lines(
            std::slice::from_ref(&line),
            LineWidth::Pixels(9.0),
            false,
        )],
        top_camera(false),
        &[],
    );
    // White under the head light with the view-facing normal: ambient + diffuse + specular
    // = 0.3 + 0.7 + 0.3, the same across the width.
    let at = |o: &Output, y: usize| o.image[20 + W as usize * y][0];
    for y in 28..=35 {
        assert!(
            (at(&flat, y) - 1.3).abs() < 1e-3,
            "row {y}: {}",
            at(&flat, y)
        );
    }
    let cyl = render(
        &gpu,
        &[lines(&[line], LineWidth::Pixels(9.0), true)],
        top_camera(false),
        &[],
    );
    // The pseudo-tube: bright in the middle, darker at the edges, and nearer in the middle.
    let rows: Vec<usize> = (0..H as usize)
        .filter(|&y| cyl.aov[20 + W as usize * y].depth > 0.0)
        .collect();
    let (edge, mid) = (rows[0], rows[rows.len() / 2]);
    assert!(
        at(&cyl, mid) > at(&cyl, edge) + 0.1,
        "{} vs {}",
        at(&cyl, mid),
        at(&cyl, edge)
    );
    let depth = |y: usize| cyl.aov[20 + W as usize * y].depth;
    assert!(
        depth(mid) < depth(edge),
        "{} vs {}",
        depth(mid),
        depth(edge)
    );
    assert!(cyl.image.iter().flatten().all(|v| v.is_finite()));
}

#[test]
fn clip_planes_cut_lines_and_lines_share_the_depth_test_with_tubes() {
    let gpu = gpu();
    let line = vec![[-20.0, 0.0, 2.0], [20.0, 0.0, 2.0]];
    let set = lines(&[line], LineWidth::Pixels(3.0), false);
    let cam = top_camera(false);
    // Keep x <= 0.
    let o = render(
        &gpu,
        std::slice::from_ref(&set),
        cam,
        &[([1.0, 0.0, 0.0], 0.0)],
    );
    assert!(column_coverage(&o, 10) >= 2);
    assert_eq!(column_coverage(&o, 54), 0);
    // A tube above the line (nearer the eye) hides it where they cross; the line, nearer than a
    // tube below it, shows.
    let above = tubes::tube_mesh::straight_tubes(
        &[[[0.0, -20.0, 6.0], [0.0, 20.0, 6.0]]],
        1.0,
        16,
        [1.0, 0.0, 0.0],
    );
    let below = tubes::tube_mesh::straight_tubes(
        &[[[-20.0, 0.0, -6.0], [20.0, 0.0, -6.0]]],
        3.0,
        16,
        [0.0, 0.0, 1.0],
    );
    let r = Renderer::new(&gpu);
    let scene = r
        .upload(None, &[above, below], std::slice::from_ref(&set), None)
        .unwrap();
    let o = r
        .draw(&scene, &view(cam), &[], &settings(), DrawOptions::default())
        .unwrap();
    let px = |p: [f64; 3]| {
        let (x, y, _) = cam
            .to_pixel(DVec3::from(p), W as usize, H as usize)
            .unwrap();
        o.image[x as usize + W as usize * y as usize]
    };
    let crossing = px([0.0, 0.0, 2.0]);
    assert!(
        crossing[0] > crossing[1] && crossing[0] > crossing[2],
        "the red tube: {crossing:?}"
    );
    let beside = px([8.0, 0.0, 2.0]);
    assert!(
        beside[1] > 0.5 && beside[2] > 0.5,
        "the white line over the blue tube: {beside:?}"
    );
    assert_eq!(o.triangles, scene.triangles());
}

#[test]
fn lines_off_centre_and_lines_through_the_eye_plane_are_drawn_right() {
    let gpu = gpu();
    // Orthographic: the eye is a direction, so a line off the image centre faces it as fully
    // as one through the centre (same shade, 1.3).
    let off = vec![[-20.0, 8.0, 0.0], [20.0, 8.0, 0.0]];
    let cam = top_camera(false);
    let o = render(
        &gpu,
        &[lines(
            std::slice::from_ref(&off),
            LineWidth::Pixels(5.0),
            false,
        )],
        cam,
        &[],
    );
    let (x, y, _) = cam
        .to_pixel(DVec3::new(-9.0, 8.0, 0.0), W as usize, H as usize)
        .unwrap();
    let v = o.image[x as usize + W as usize * y as usize][0];
    assert!((v - 1.3).abs() < 1e-3, "{v}");
    // Perspective, a world-width line from behind the eye to in front of it: cut at the
    // near side, not widened into a wedge over the image.
    let through = vec![[3.0, 0.0, 90.0], [3.0, 0.0, -10.0]];
    let o = render(
        &gpu,
        &[lines(&[through], LineWidth::World(0.5), false)],
        top_camera(true),
        &[],
    );
    assert!(o.image.iter().flatten().all(|v| v.is_finite()));
    let covered = o.aov.iter().filter(|a| a.depth > 0.0).count();
    assert!(
        covered > 0 && covered < (W * H / 4) as usize,
        "{covered} of {} pixels",
        W * H
    );
}

#[test]
fn trails_keep_only_their_time_window_and_taper_towards_its_ends() {
    let gpu = gpu();
    // A line along x from -10 to 10 whose time is x + 10 (a point every quarter unit), 8
    // pixels wide; the trail at time 10 (x = 0) reaching 6 back (x = -6) and 3 forward (x = 3).
    let pts: Vec<[f32; 3]> = (0..=80)
        .map(|k| [k as f32 * 0.25 - 10.0, 0.0, 0.0])
        .collect();
    let mut set = lines(&[pts], LineWidth::Pixels(8.0), false);
    set.times = (0..=80).map(|k| k as f32 * 0.25).collect();
    let trail = tubes::lines::Trail {
        now: 10.0,
        back: 6.0,
        forward: 3.0,
        start: 1.0 / 3.0,
        min_width: 0.25,
    };
    set.trail = Some(trail);
    let o = render(&gpu, std::slice::from_ref(&set), top_camera(false), &[]);
    // Pixel column of world x (64 pixels over 24 units).
    let col = |x: f64| ((x + 12.0) / 24.0 * W as f64) as usize;
    let rows = |x: f64| column_coverage(&o, col(x)) as f64;
    // Within 2 rows: the line is centred between two rows, so its coverage grows two rows at a
    // time, and a trail's caps reach half a segment (a third of a pixel here) beyond a point.
    let near = |x: f64, want: f64| {
        let got = rows(x);
        assert!(
            (got - want).abs() <= 2.0,
            "x = {x}: {got} rows, want {want}"
        );
    };
    near(0.0, 8.0);
    near(-1.5, 8.0);
    // 4.5 back: u = 0.75, factor 1 - 0.75 (0.75 - 1/3) / (2/3) = 0.531.
    near(-4.5, 8.0 * trail.width_factor(5.5) as f64);
    near(2.5, 8.0 * trail.width_factor(12.5) as f64);
    near(-5.75, 8.0 * trail.width_factor(4.25) as f64);
    assert!(rows(-5.5) < 0.6 * rows(0.0), "{} {}", rows(-5.5), rows(0.0));
    for x in [-8.5, -7.5, 4.5, 6.0, 9.0] {
        assert_eq!(rows(x), 0.0, "x = {x} is outside the trail");
    }
    // Another time moves the trail: drawn at 16 (x = 6, from x = 0 to 9), x = -1 is then
    // outside it.
    let mut s = settings();
    s.trail_now = Some(16.0);
    let r = Renderer::new(&gpu);
    let scene = r.upload(None, &[], &[set], None).unwrap();
    let moved = r
        .draw(
            &scene,
            &view(top_camera(false)),
            &[],
            &s,
            DrawOptions::default(),
        )
        .unwrap();
    assert!(column_coverage(&moved, col(6.0)) >= 7);
    assert!(column_coverage(&moved, col(-1.0)) == 0);
}

fn coloured(polylines: &[Vec<[f32; 3]>], width: f64, rgb: [f32; 3]) -> LineSet {
    let mut s = tubes::Streamlines::new();
    for p in polylines {
        let pts: Vec<Vec3> = p.iter().map(|q| Vec3::from(*q)).collect();
        s.push(&pts);
    }
    LineSet::new(
        &s,
        &ColorMode::Constant(rgb),
        LineWidth::Pixels(width),
        false,
    )
}

fn halo(d_max: f32, f: tubes::lines::Displacement, uniform: bool) -> tubes::lines::Halo {
    tubes::lines::Halo {
        uniform,
        outline: false,
        width: 6.0,
        d_max,
        displacement: f,
        depth_cue: 0.0,
    }
}

#[test]
fn a_halo_gap_follows_the_corrected_appendix_a() {
    use occlusion::halos::{halo_gap, Displacement as D};
    use tubes::lines::Displacement;
    let gpu = gpu();
    let cam = top_camera(false);
    // d_max of 4 world units of linear depth.
    let d_max = (4.0 / (cam.far - cam.near)) as f32;
    // A 4-pixel blue line along x (strip 24 pixels) in front of a red one along y, dz behind.
    let gap_at = |dz: f32, f: Displacement, uniform: bool| {
        let mut front = coloured(
            &[vec![[-20.0, 0.0, 2.0], [20.0, 0.0, 2.0]]],
            4.0,
            [0.0, 0.0, 1.0],
        );
        front.halo = Some(halo(d_max, f, uniform));
        let back = coloured(
            &[vec![[0.2, -20.0, 2.0 - dz], [0.2, 20.0, 2.0 - dz]]],
            2.0,
            [1.0, 0.0, 0.0],
        );
        let o = render(&gpu, &[front, back], cam, &[]);
        let x = ((0.2 + 12.0) / 24.0 * W as f64) as usize;
        let px = |y: usize| o.image[x + W as usize * y];
        // Lit by the head light (with white specular): blue where blue leads, black where dark.
        let blue: Vec<usize> = (0..H as usize)
            .filter(|&y| px(y)[2] > px(y)[0] + 0.1)
            .collect();
        let (top, bottom) = (blue[0], *blue.last().unwrap());
        let black = |y: usize| px(y)[0] + px(y)[2] < 0.1;
        if std::env::var("HALO_DEBUG").is_ok() {
            eprintln!(
                "dz {dz}: {:?}",
                (0..H as usize)
                    .map(|y| format!("{:.2},{:.2}", px(y)[0], px(y)[2]))
                    .collect::<Vec<_>>()
            );
        }
        let up = (0..top).rev().take_while(|&y| black(y)).count();
        let down = (bottom + 1..H as usize).take_while(|&y| black(y)).count();
        (up + down) as f64 / 2.0
    };
    for (f, d) in [
        (Displacement::Linear, D::Linear),
        (Displacement::Sqrt, D::Sqrt),
        (Displacement::Square, D::Square),
    ] {
        for dz in [0.5f32, 1.5, 2.5, 6.0] {
            let want = halo_gap(dz as f64, 4.0, 24.0, 4.0, d);
            let got = gap_at(dz, f, false);
            assert!(
                (got - want).abs() <= 1.0,
                "{f:?}, dz {dz}: a gap of {got} pixels, the appendix says {want}"
            );
        }
    }
    // Uniform halos: the full rim (10 pixels a side) even for a line just behind.
    let got = gap_at(0.3, Displacement::Linear, true);
    assert!((got - 10.0).abs() <= 1.0, "uniform: {got}");
}

#[test]
fn parallel_lines_at_one_depth_do_not_cut_each_other_and_1_bit_print_has_two_values() {
    let gpu = gpu();
    let cam = top_camera(false);
    let d_max = (4.0 / (cam.far - cam.near)) as f32;
    let line = |y: f32, rgb| {
        let mut l = coloured(&[vec![[-20.0, y, 0.0], [20.0, y, 0.0]]], 4.0, rgb);
        l.halo = Some(halo(d_max, tubes::lines::Displacement::Linear, false));
        l
    };
    let count = |o: &Output| o.image.iter().filter(|c| c[0] > c[2] + 0.1).count();
    let alone = render(&gpu, &[line(2.5, [1.0, 0.0, 0.0])], cam, &[]);
    let both = render(
        &gpu,
        &[line(0.0, [0.0, 0.0, 1.0]), line(2.5, [1.0, 0.0, 0.0])],
        cam,
        &[],
    );
    let (a, b) = (count(&alone), count(&both));
    assert!(
        a > 100 && (a as i64 - b as i64).abs() <= W as i64 / 8,
        "{a} alone, {b} beside"
    );
    // A gap halo covers nothing: its rim shows the background in alpha too (coverage as the
    // line's without a halo), so that an EXR composites over another background cleanly.
    let mut plain = line(2.5, [1.0, 0.0, 0.0]);
    plain.halo = None;
    let bare = render(&gpu, &[plain], cam, &[]);
    let covered = |o: &Output| o.image.iter().filter(|c| c[3] > 0.5).count();
    let (h, p) = (covered(&alone), covered(&bare));
    assert!(
        p > 100 && (h as i64 - p as i64).abs() <= W as i64 / 8,
        "{h} pixels covered with the halo, {p} without"
    );
    // The two-valued print form.
    let v: std::collections::BTreeSet<u8> = both
        .image
        .iter()
        .map(|c| scene_one_bit([c[0], c[1], c[2]]))
        .collect();
    assert_eq!(v.len(), 2);
}

/// `scene::image_io::one_bit` (the engine's tests do not depend on the scene crate).
fn scene_one_bit(c: [f32; 3]) -> u8 {
    let y = 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2];
    if y >= 0.214 {
        255
    } else {
        0
    }
}

#[test]
fn end_tapers_and_attribute_filters_shape_the_strip() {
    let gpu = gpu();
    // A line along x from -10 to 10, a point every half unit, 8 pixels wide.
    let pts: Vec<[f32; 3]> = (0..=40)
        .map(|k| [k as f32 * 0.5 - 10.0, 0.0, 0.0])
        .collect();
    let col = |x: f64| ((x + 12.0) / 24.0 * W as f64) as usize;
    let mut tapered = lines(std::slice::from_ref(&pts), LineWidth::Pixels(8.0), false);
    tapered.taper_u = tubes::lines::taper_u(41, 2, 0.2);
    tapered.taper_t = 0.2;
    let o = render(&gpu, &[tapered], top_camera(false), &[]);
    let rows = |o: &Output, x: f64| column_coverage(o, col(x));
    // Full width inside; narrowing over the last two vertices (one unit) to the ends.
    assert!(
        rows(&o, 0.0) >= 7 && rows(&o, -8.0) >= 7,
        "{}",
        rows(&o, 0.0)
    );
    for x in [-9.6, 9.6] {
        assert!(rows(&o, x) <= 6, "near the end: {}", rows(&o, x));
    }
    for x in [-9.9, 9.9] {
        assert!(rows(&o, x) <= 4, "at the end: {}", rows(&o, x));
    }
    // A filter on an attribute equal to x: only x >= 0 is drawn, its cut end narrowing over
    // 2 units of the attribute.
    let mut filtered = lines(&[pts], LineWidth::Pixels(8.0), false);
    filtered.filter = (0..=40).map(|k| k as f32 * 0.5 - 10.0).collect();
    filtered.filter_min = 0.0;
    filtered.filter_taper = 2.0;
    let o = render(&gpu, &[filtered], top_camera(false), &[]);
    assert_eq!(rows(&o, -1.0), 0, "below the threshold");
    assert!(rows(&o, 0.2) <= 4, "the cut end: {}", rows(&o, 0.2));
    assert!(rows(&o, 4.0) >= 7, "beyond the taper: {}", rows(&o, 4.0));
}

/// A point cloud of `points` as discs `diameter` world units across.
fn cloud(points: &[[f32; 3]], diameter: f64, rgb: [f32; 3]) -> LineSet {
    let mut s = tubes::Streamlines::new();
    let pts: Vec<Vec3> = points.iter().map(|q| Vec3::from(*q)).collect();
    s.push(&pts);
    LineSet::points(&s, &ColorMode::Constant(rgb), LineWidth::World(diameter))
}

#[test]
fn points_are_round_discs_of_their_world_size_and_their_halos_are_cones() {
    use occlusion::halos::{halo_gap, Displacement as D};
    let gpu = gpu();
    let cam = top_camera(false);
    // 24 world units over 64 pixels: a 6-pixel disc is 2.25 units across. The pixel column 32
    // has its centre at x = 0.1875.
    let (px, c) = (24.0 / W as f64, 0.1875f32);
    let o = render(
        &gpu,
        &[cloud(&[[c, 0.0, 0.0]], 6.0 * px, [1.0; 3])],
        cam,
        &[],
    );
    let covered: Vec<(usize, usize)> = (0..(W * H) as usize)
        .filter(|&i| o.aov[i].depth > 0.0)
        .map(|i| (i % W as usize, i / W as usize))
        .collect();
    // Area pi r^2 = 28.3 pixels (a square would be 36); as wide as tall (to the pixel: the
    // centre is on a pixel centre across, between two down); x - y spans 2 sqrt(2) r over a
    // disc, twice the width 2 r over a square.
    let area = covered.len() as f64;
    assert!((area - 28.27).abs() <= 5.0, "disc area {area}");
    let span = |f: &dyn Fn(&(usize, usize)) -> i64| {
        let v: Vec<i64> = covered.iter().map(f).collect();
        v.iter().max().unwrap() - v.iter().min().unwrap() + 1
    };
    let (w, h) = (span(&|p| p.0 as i64), span(&|p| p.1 as i64));
    let diag = span(&|p| p.0 as i64 - p.1 as i64);
    assert!((5..=7).contains(&w) && (w - h).abs() <= 1, "{w} x {h}");
    assert!(
        (diag as f64) <= 1.6 * h as f64,
        "x - y spans {diag}, the height {h}"
    );
    // Unhaloed, the disc is a sphere's impostor: its depth bulges towards the eye by up to
    // the radius at the centre.
    let centre = o.aov[32 + W as usize * 32].depth;
    let edge = o.aov[30 + W as usize * 32].depth;
    assert!(
        centre < edge && (edge - centre) < 1.2 * 3.0 * px as f32,
        "{centre} {edge}"
    );
    // A haloed point (4 pixels, halo disc 24) in front of a line through its centre, dz
    // behind: the gap along the line follows the corrected Appendix A radially (a cone).
    let d_max = (4.0 / (cam.far - cam.near)) as f32;
    for (f, d) in [
        (tubes::lines::Displacement::Linear, D::Linear),
        (tubes::lines::Displacement::Sqrt, D::Sqrt),
    ] {
        for dz in [1.5f32, 2.5, 6.0] {
            let mut front = cloud(&[[c, 0.0, 2.0]], 4.0 * px, [0.0, 0.0, 1.0]);
            front.halo = Some(halo(d_max, f, false));
            let back = coloured(
                &[vec![[c, -20.0, 2.0 - dz], [c, 20.0, 2.0 - dz]]],
                2.0,
                [1.0, 0.0, 0.0],
            );
            let o = render(&gpu, &[front, back], cam, &[]);
            let pxl = |y: usize| o.image[32 + W as usize * y];
            let red = |y: usize| pxl(y)[0] > pxl(y)[2] + 0.1;
            let blue: Vec<usize> = (0..H as usize)
                .filter(|&y| pxl(y)[2] > pxl(y)[0] + 0.1)
                .collect();
            let (top, bottom) = (blue[0], *blue.last().unwrap());
            let up = (0..top).rev().take_while(|&y| !red(y)).count();
            let down = (bottom + 1..H as usize).take_while(|&y| !red(y)).count();
            let got = (up + down) as f64 / 2.0;
            let want = halo_gap(dz as f64, 4.0, 24.0, 4.0, d);
            assert!(
                (got - want).abs() <= 1.0,
                "{f:?}, dz {dz}: a gap of {got} pixels, the appendix says {want}"
            );
        }
    }
}

#[test]
fn a_haloed_line_bending_away_in_depth_does_not_cut_itself_at_its_joints() {
    // A wiggle of 41 points receding 45 degrees (each segment starts deeper than the last
    // ends, bending by up to 25 degrees): square caps that carried the halo hid each next
    // segment's start (seen in the gallery); now the caps hold the core only, so the haloed
    // core covers what the plain line covers.
    let gpu = gpu();
    let cam = top_camera(false);
    let pts: Vec<[f32; 3]> = (0..=40)
        .map(|k| {
            let x = -10.0 + 0.5 * k as f32;
            [x, 2.0 * (0.8 * x).sin(), -x]
        })
        .collect();
    let covered = |halo: Option<tubes::lines::Halo>| {
        let mut l = coloured(std::slice::from_ref(&pts), 3.0, [0.0, 0.0, 1.0]);
        l.halo = halo;
        let o = render(&gpu, &[l], cam, &[]);
        o.aov.iter().filter(|a| a.depth > 0.0).count()
    };
    let plain = covered(None);
    for uniform in [true, false] {
        let d_max = (4.0 / (cam.far - cam.near)) as f32;
        let haloed = covered(Some(halo(
            d_max,
            tubes::lines::Displacement::Linear,
            uniform,
        )));
        assert!(
            (haloed as f64 - plain as f64).abs() <= 0.1 * plain as f64,
            "uniform {uniform}: {haloed} core pixels haloed, {plain} plain"
        );
    }
}

#[test]
fn a_haloed_cores_edge_on_pixel_centres_is_drawn_evenly_along_the_line() {
    // A new user's straight 3-pixel line of 4-pixel segments, seen from above its middle and
    // centred on a row boundary: the core's edges run through the centres of rows 30 and 33.
    // Decided once per pixel, rounding made each pixel there core or rim by whichever of the
    // overlapping strips drew it (the line came out dashed, its rim's background through the
    // core); now an edge sample is core, and a multisampled G-buffer decides sample by sample:
    // every column of the line's middle covers the same, and with 4 samples the line's width.
    let gpu = gpu();
    let pts: Vec<[f32; 3]> = (0..13)
        .map(|k| [k as f32 * 10.0 / 12.0, 0.0, 0.0])
        .collect();
    let bounds = [DVec3::new(0.0, -1.0, -1.0), DVec3::new(10.0, 1.0, 1.0)];
    let cam = Camera::look_at(
        DVec3::new(5.0, 0.0, 20.0),
        DVec3::new(5.0, 0.0, 0.0),
        DVec3::Y,
        occlusion::camera::Projection::Perspective { fov_y_deg: 35.0 },
        bounds,
    )
    .unwrap();
    let r = Renderer::new(&gpu);
    for msaa in [1, 4] {
        for uniform in [true, false] {
            let mut l = coloured(std::slice::from_ref(&pts), 3.0, [0.0, 0.0, 1.0]);
            l.halo = Some(tubes::lines::Halo {
                d_max: 0.01,
                ..halo(0.0, tubes::lines::Displacement::Linear, uniform)
            });
            let scene = r.upload(None, &[], &[l], None).unwrap();
            let set = Settings { msaa, ..settings() };
            let o = r
                .draw(&scene, &view(cam), &[], &set, DrawOptions::default())
                .unwrap();
            // The line's coverage (alpha: a gap halo covers nothing) in each column of its
            // middle (the ends' caps left out); its shade varies along it under the head light.
            let cover: Vec<f32> = (12..52)
                .map(|x| (26..38).map(|y| o.image[x + W as usize * y][3]).sum())
                .collect();
            let (lo, hi) = cover
                .iter()
                .fold((f32::MAX, f32::MIN), |(a, b), &v| (a.min(v), b.max(v)));
            assert!(
                lo > 2.0 && hi - lo < 0.05,
                "msaa {msaa}, uniform {uniform}: columns cover {lo} to {hi} pixels"
            );
            // Sample by sample, the 3-pixel core covers 3 pixels a column (half of each edge
            // row); decided per pixel it covered 4.
            if msaa == 4 {
                assert!(
                    (lo - 3.0).abs() < 0.05,
                    "msaa 4, uniform {uniform}: {lo} pixels"
                );
            }
        }
    }
}

#[test]
fn fxaa_leaves_multisampled_lines_their_ink() {
    // A lone 2-pixel line across the view at a shallow angle: its edges are smoothed by the
    // G-buffer's 4 samples, and FXAA over them took a quarter of its ink (drawn as beads).
    // FXAA now leaves pixels that surfaces' samples cover and their neighbours: the line's
    // pixels are as without it, and it is smeared no wider.
    let gpu = gpu();
    let cam = top_camera(false);
    let l = coloured(
        &[vec![[-11.0, -3.0, 0.0], [11.0, 2.0, 0.0]]],
        2.0,
        [0.0, 0.0, 1.0],
    );
    let r = Renderer::new(&gpu);
    let scene = r.upload(None, &[], &[l], None).unwrap();
    let draw = |fxaa: bool| {
        let set = Settings {
            msaa: 4,
            fxaa,
            ..settings()
        };
        r.draw(&scene, &view(cam), &[], &set, DrawOptions::default())
            .unwrap()
    };
    let (on, off) = (draw(true), draw(false));
    let covered: Vec<usize> = (0..off.image.len())
        .filter(|&i| off.image[i][3] > 0.0)
        .collect();
    assert!(covered.len() > 2 * W as usize, "{} pixels", covered.len());
    for &i in &covered {
        assert_eq!(on.image[i], off.image[i], "pixel {i}");
    }
    let alpha = |o: &Output| o.image.iter().map(|p| p[3]).sum::<f32>();
    let (a, b) = (alpha(&on), alpha(&off));
    assert!(
        (a - b).abs() <= 0.01 * b,
        "coverage {a} with FXAA, {b} without"
    );
}

#[test]
fn depth_cueing_narrows_far_cores() {
    // Two haloed 4-pixel lines along x, one near the near plane and one near the far plane
    // (orthographic: the same width on screen without cueing). With depth_cue = 0.75 the
    // core narrows linearly with depth to a quarter at the far plane.
    let gpu = gpu();
    let cam = top_camera(false);
    let rows_of = |cue: f32| {
        let line = |y: f32, z: f32| {
            let mut l = coloured(&[vec![[-10.0, y, z], [10.0, y, z]]], 8.0, [0.0, 0.0, 1.0]);
            let mut h = halo(0.0, tubes::lines::Displacement::Linear, true);
            h.width = 2.0;
            h.depth_cue = cue;
            l.halo = Some(h);
            l
        };
        let o = render(&gpu, &[line(5.0, 11.0), line(-5.0, -11.0)], cam, &[]);
        // Core rows (a surface in the depth AOV) in column 32 above and below the centre.
        let rows = |ys: std::ops::Range<usize>| {
            ys.filter(|&y| o.aov[32 + W as usize * y].depth > 0.0)
                .count()
        };
        (rows(0..32), rows(32..64))
    };
    let (near, far) = rows_of(0.0);
    assert!(
        near >= 3 && (near as i64 - far as i64).abs() <= 1,
        "{near} {far}"
    );
    let (near_c, far_c) = rows_of(0.75);
    // t = (z - near) / (far - near): about 0.04 and 0.96 here.
    let t = |z: f64| ((cam.eye.z - z) - cam.near) / (cam.far - cam.near);
    let want = |z: f64| near as f64 * (1.0 - 0.75 * t(z));
    assert!(
        (near_c as f64 - want(11.0)).abs() <= 1.0,
        "near {near_c} want {}",
        want(11.0)
    );
    assert!(
        (far_c as f64 - want(-11.0)).abs() <= 1.0,
        "far {far_c} want {}",
        want(-11.0)
    );
    assert!(far_c + 2 <= near_c, "{near_c} {far_c}");
}

/// `lines` lines of `points` points through the origin, line `i` along the direction at
/// `i turn` radians in the x-y plane over [-10, 10], waving in z as
/// `amp sin(0.3 u + phase + i turn)` at the distance `u` along it.
fn wavy_fan(lines: usize, points: usize, turn: f32, amp: f32, phase: f32) -> tubes::Streamlines {
    let mut s = tubes::Streamlines::new();
    for i in 0..lines {
        let a = i as f32 * turn;
        let pts: Vec<Vec3> = (0..points)
            .map(|k| {
                let u = k as f32 / (points - 1) as f32 * 20.0 - 10.0;
                Vec3::new(u * a.cos(), u * a.sin(), amp * (0.3 * u + phase + a).sin())
            })
            .collect();
        s.push(&pts);
    }
    s
}

/// A line set larger than a storage binding is cut into parts (the binding limit lowered here
/// so that a small set is cut into many): the parts draw the same image as the whole, with
/// per-point colours, tapers, filters and times sliced with their points, and point clouds
/// likewise.
#[test]
fn a_set_cut_into_parts_draws_the_image_of_the_whole() {
    let gpu = gpu();
    let s = wavy_fan(40, 31, 0.157, 3.0, 3.0);
    let n = s.points.len();
    let mut set = LineSet::new(&s, &ColorMode::Direction, LineWidth::Pixels(3.0), true);
    set.taper_u = (0..s.len())
        .flat_map(|k| tubes::lines::taper_u(s.line(k).len(), 3, 0.2))
        .collect();
    set.taper_t = 0.2;
    set.filter = (0..n).map(|k| (k % 31) as f32).collect();
    set.filter_min = 2.0;
    set.filter_taper = 1.0;
    let cloud = LineSet::points(&s, &ColorMode::Direction, LineWidth::World(0.4));
    for set in [set, cloud] {
        let r = Renderer::new(&gpu);
        let cam = top_camera(true);
        let whole = r
            .upload(None, &[], std::slice::from_ref(&set), None)
            .unwrap();
        assert_eq!(whole.line_parts(), 1);
        let a = r
            .draw(&whole, &view(cam), &[], &settings(), DrawOptions::default())
            .unwrap();
        // 100 points a part (12 bytes each): the 1240 points in 13 parts.
        gpu.limit_bindings(Some(1200));
        let cut = r.upload(None, &[], std::slice::from_ref(&set), None);
        gpu.limit_bindings(None);
        let cut = cut.unwrap();
        assert_eq!(cut.line_parts(), 13);
        assert_eq!(cut.triangles(), whole.triangles());
        let b = r
            .draw(&cut, &view(cam), &[], &settings(), DrawOptions::default())
            .unwrap();
        // Uploaded part by part while the set's points are freed: the same parts, the same
        // image, and nothing left of the points on the CPU.
        let mut freed = set.clone();
        let mut fr = r.upload(None, &[], &[], None).unwrap();
        gpu.limit_bindings(Some(1200));
        let got = r.upload_lines_freeing(&mut fr, std::slice::from_mut(&mut freed));
        gpu.limit_bindings(None);
        got.unwrap();
        assert_eq!(fr.line_parts(), 13);
        assert!(freed.positions.is_empty() && freed.segments.is_empty() && freed.filter.is_empty());
        let c = r
            .draw(&fr, &view(cam), &[], &settings(), DrawOptions::default())
            .unwrap();
        assert!(
            c.image == b.image,
            "points: {}: freeing changed the image",
            set.points
        );
        let covered = a.aov.iter().filter(|p| p.depth > 0.0).count();
        assert!(covered > 300, "the set covers {covered} pixels");
        let diff: f64 = a
            .image
            .iter()
            .zip(&b.image)
            .map(|(p, q)| (0..3).map(|c| (p[c] - q[c]).abs() as f64).sum::<f64>() / 3.0)
            .sum::<f64>()
            / a.image.len() as f64;
        let changed = a.image.iter().zip(&b.image).filter(|(p, q)| p != q).count();
        assert!(
            diff <= 0.1 / 255.0 && changed <= covered / 50,
            "points: {}: mean difference {:.5}/255, {changed} pixels changed",
            set.points,
            diff * 255.0
        );
    }
}

/// On a CPU adapter large draws are submitted in batches (lavapipe queues a submission's
/// triangles, about 550 bytes each): batches of 50 triangles - tubes and lines cut anywhere,
/// a segment's two triangles included - draw the image of one submission, with LineAO's
/// normal-depth pass and 4x MSAA (its extra depth pass) batched too.
#[test]
fn batched_submissions_draw_the_image_of_one() {
    let gpu = gpu();
    let s = wavy_fan(12, 21, 0.5, 2.0, 0.0);
    let set = LineSet::new(&s, &ColorMode::Direction, LineWidth::Pixels(3.0), true);
    let tube = tubes::tube_mesh::straight_tubes(
        &[
            [[0.0, -20.0, 4.0], [0.0, 20.0, 4.0]],
            [[-20.0, 3.0, -3.0], [20.0, 3.0, -3.0]],
        ],
        1.5,
        16,
        [1.0, 0.3, 0.2],
    );
    let r = Renderer::new(&gpu);
    let scene = r
        .upload(
            None,
            std::slice::from_ref(&tube),
            std::slice::from_ref(&set),
            None,
        )
        .unwrap();
    let cam = top_camera(true);
    for method in [Method::Illuminated, Method::LineAo] {
        let s = Settings {
            method,
            msaa: 4,
            ..settings()
        };
        let draw = |batch: Option<u64>| {
            gpu.set_batch_triangles(batch);
            let o = r.draw(&scene, &view(cam), &[], &s, DrawOptions::default());
            gpu.set_batch_triangles(None);
            o.unwrap()
        };
        let one = draw(None);
        let cut = draw(Some(50));
        assert!(
            scene.triangles() > 10 * 50,
            "{} triangles",
            scene.triangles()
        );
        let covered = one.aov.iter().filter(|p| p.depth > 0.0).count();
        assert!(covered > 500, "{method:?}: {covered} pixels");
        let worst = one
            .image
            .iter()
            .zip(&cut.image)
            .map(|(p, q)| (0..4).map(|c| (p[c] - q[c]).abs()).fold(0.0, f32::max))
            .fold(0.0, f32::max);
        assert!(worst <= 1e-6, "{method:?}: a pixel differs by {worst}");
    }
}

/// Sets added to an uploaded scene (`Renderer::upload_lines_freeing`) are numbered after every
/// set the scene has, also when its last set has no segments (and so no part on the GPU): a
/// share listing each set's segments (`Renderer::upload_shares`, the viewer's drafts) draws
/// what the scene draws. Numbered from the last part instead, the added set took the empty
/// set's number and the share left it out.
#[test]
fn sets_added_after_an_empty_set_keep_their_number() {
    let gpu = gpu();
    let r = Renderer::new(&gpu);
    let first = LineSet::new(
        &wavy_fan(12, 31, 0.157, 3.0, 3.0),
        &ColorMode::Direction,
        LineWidth::Pixels(3.0),
        true,
    );
    let mut empty = first.clone();
    empty.segments.clear();
    let mut added = LineSet::new(
        &wavy_fan(12, 31, 0.4, 1.0, 0.5),
        &ColorMode::Direction,
        LineWidth::Pixels(3.0),
        true,
    );
    let lists = vec![first.segments.clone(), vec![], added.segments.clone()];
    let mut scene = r.upload(None, &[], &[first, empty], None).unwrap();
    assert_eq!(scene.line_parts(), 1);
    r.upload_lines_freeing(&mut scene, std::slice::from_mut(&mut added))
        .unwrap();
    assert_eq!(scene.line_parts(), 2);
    let share = r.upload_shares(&scene, &[], &lists).unwrap();
    assert_eq!(share.triangles(), scene.triangles());
    let cam = top_camera(true);
    let whole = r
        .draw(&scene, &view(cam), &[], &settings(), DrawOptions::default())
        .unwrap();
    let shared = r
        .draw(&share, &view(cam), &[], &settings(), DrawOptions::default())
        .unwrap();
    let covered = whole.aov.iter().filter(|p| p.depth > 0.0).count();
    assert!(covered > 300, "the sets cover {covered} pixels");
    assert!(whole.image == shared.image, "the share draws another image");
}

/// An outline halo's rim is black ink, whatever the head light's specular term (it was grey,
/// 149 of 255, with the default light): the rim pixels beside a white line stay dark.
#[test]
fn an_outline_rim_is_black_under_the_head_light() {
    let gpu = gpu();
    let cam = top_camera(false);
    let d_max = (4.0 / (cam.far - cam.near)) as f32;
    let mut l = coloured(
        &[vec![[-20.0, 0.0, 2.0], [20.0, 0.0, 2.0]]],
        4.0,
        [1.0, 1.0, 1.0],
    );
    l.halo = Some(tubes::lines::Halo {
        outline: true,
        ..halo(d_max, tubes::lines::Displacement::Linear, true)
    });
    let o = render(&gpu, &[l], cam, &[]);
    let x = W as usize / 2;
    let px = |y: usize| o.image[x + W as usize * y];
    // Down the middle column: the line's pixels (lit white) between two rims.
    let lit: Vec<usize> = (0..H as usize).filter(|&y| px(y)[0] > 0.5).collect();
    let (top, bottom) = (lit[0], *lit.last().unwrap());
    let rim: Vec<f32> = (top.saturating_sub(8)..top)
        .chain(bottom + 1..(bottom + 9).min(H as usize))
        .map(|y| px(y)[0].max(px(y)[1]).max(px(y)[2]))
        .collect();
    let dark = rim.iter().filter(|&&v| v < 0.02).count();
    assert!(dark >= 12, "rim values {rim:?}");
}
