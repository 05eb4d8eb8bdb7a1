//! The window driven through its widgets (egui_kittest, no X server): a drag on the view
//! orbits, the method menu changes the method, a setting and the transfer function's preset
//! change the scene, and the screenshot button writes what `umbra render` draws of the shown
//! state (so the new transfer function reached the renderer).

mod common;

use eframe::egui;
use egui_kittest::kittest::Queryable;
use egui_kittest::Harness;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::{Duration, Instant};
use umbra_viewer::app::App;
use umbra_viewer::worker::Level;

/// The transfer-function editor a test window gets.
enum WithEditor {
    No,
    OneD,
    /// With the value x gradient histogram (checked not empty).
    TwoD,
}

/// The window on the scene file `path`, `size` points, its worker started as `umbra view`
/// starts it, with the editor `editor` asks for (64 value bins, 128 x 64 for the 2-D one).
fn window(path: &std::path::Path, size: [f32; 2], editor: WithEditor) -> Harness<'static, App> {
    window_with(path, size, editor, None)
}

/// [`window`], with `full` counting the full images shown when given.
fn window_with(
    path: &std::path::Path,
    size: [f32; 2],
    editor: WithEditor,
    full: Option<Arc<std::sync::atomic::AtomicUsize>>,
) -> Harness<'static, App> {
    let s = scene::spec::load(path, &[]).unwrap();
    let m = scene::compile::model(&s).unwrap();
    let bounds = m.bounds;
    let range = umbra_viewer::worker::data_range(&m);
    let one_d = || {
        umbra_viewer::transfer::Editor::new(range, umbra_viewer::worker::histogram(&m, range, 64))
    };
    let editor = match editor {
        WithEditor::No => None,
        WithEditor::OneD => Some(one_d()),
        WithEditor::TwoD => {
            let h2 = umbra_viewer::worker::histogram2d(&m, range, 128, 64);
            assert!(h2.gmax > 0.0 && h2.counts.iter().sum::<u64>() > 100_000);
            Some(one_d().with_2d(h2))
        }
    };
    let grid = umbra_viewer::objects::SliceGrid::of(&m);
    let ras = m.is_ras();
    let worker = umbra_viewer::worker::start(m, &s, || {});
    let quit = Arc::new(AtomicBool::new(false));
    let mut app = App::new(s, bounds, worker, quit, None)
        .with_slice_grid(grid)
        .with_ras(ras);
    if let Some(e) = editor {
        app = app.with_editor(e);
    }
    if let Some(count) = full {
        app = app.with_events(Box::new(move |e| {
            if let umbra_viewer::ViewEvent::Image {
                level: Level::Full, ..
            } = e
            {
                count.fetch_add(1, std::sync::atomic::Ordering::SeqCst);
            }
        }));
    }
    Harness::builder()
        .with_size(egui::vec2(size[0], size[1]))
        .build_ui_state(|ui, app: &mut App| app.show_ui(ui), app)
}

/// [`window`], counting the full images shown in `full`.
fn window_counting(
    path: &std::path::Path,
    size: [f32; 2],
    editor: WithEditor,
) -> (Harness<'static, App>, Arc<std::sync::atomic::AtomicUsize>) {
    let n = Arc::new(std::sync::atomic::AtomicUsize::new(0));
    (window_with(path, size, editor, Some(n.clone())), n)
}

#[test]
fn a_drag_orbits_the_menu_sets_the_method_and_the_screenshot_is_the_headless_image() {
    let dir = tempfile::tempdir().unwrap();
    let path = test_support::headsq_scene(
        dir.path(),
        "background = [1.0, 1.0, 1.0]\n",
        "bone",
        "method = \"ea\"\nfxaa = false\n",
    );
    let (mut h, full) = window_counting(&path, [900.0, 800.0], WithEditor::OneD);
    h.run_steps(3);
    // `ea` sweeps no light: the panel names no light volume.
    let t = Instant::now();
    while h.state().shown_level().is_none() && t.elapsed() < Duration::from_secs(60) {
        std::thread::sleep(Duration::from_millis(50));
        h.run_steps(1);
    }
    assert!(h.query_by_label_contains("cells of").is_none());
    let az0 = h.state().orbit.azimuth;
    // A drag of 100 points to the right over the view turns the azimuth by -40 degrees.
    h.drag_at(egui::pos2(450.0, 200.0));
    h.run_steps(1);
    h.hover_at(egui::pos2(500.0, 200.0));
    h.run_steps(1);
    h.hover_at(egui::pos2(550.0, 200.0));
    h.run_steps(1);
    h.drop_at(egui::pos2(550.0, 200.0));
    h.run_steps(2);
    let az = h.state().orbit.azimuth;
    assert!((az - (az0 - 40.0)).abs() < 1.0, "azimuth {az0} -> {az}");
    // One notch of the wheel over the view (a line of scrolling, spread by egui over frames)
    // zooms in by one step of 1.1, as `+` does.
    h.hover_at(egui::pos2(450.0, 300.0));
    h.run_steps(1);
    let d0 = h.state().orbit.distance;
    h.event(egui::Event::MouseWheel {
        unit: egui::MouseWheelUnit::Line,
        delta: egui::vec2(0.0, 1.0),
        phase: egui::TouchPhase::Move,
        source: egui::MouseWheelSource::Wheel,
        modifiers: Default::default(),
    });
    h.run_steps(40);
    let d = h.state().orbit.distance;
    assert!((d0 / d - 1.1).abs() < 0.002, "distance {d0} -> {d}");
    // The method menu (its button shows the current method) and its entry.
    h.get_by_label("method").click();
    h.run_steps(2);
    h.get_by_label("dos").click();
    h.run_steps(2);
    assert_eq!(h.state().scene.render.method, engine::method::Method::Dos);
    // The settings panel: open "render", switch FXAA off... it is off; turn it on and back.
    h.get_by_label("render").click();
    h.run_steps(2);
    h.get_by_label("fxaa").click();
    h.run_steps(2);
    assert!(h.state().scene.render.fxaa);
    h.get_by_label("fxaa").click();
    h.run_steps(2);
    assert!(!h.state().scene.render.fxaa);
    // Closed again, so that the save buttons are on screen.
    h.get_by_label("render").click();
    h.run_steps(2);
    // The transfer-function editor's preset menu: bone -> fire (the worker uploads it).
    h.get_by_label("volume.transfer").click();
    h.run_steps(2);
    h.get_by_label("fire").click();
    h.run_steps(2);
    let tf = &h.state().scene.volume.as_ref().unwrap().transfer;
    assert_eq!(tf.preset, "fire");
    assert!(tf.points.is_empty());
    // Its range menu: the ramp over the data's robust range (the screenshot below is compared
    // with the headless renderer's image of it).
    h.get_by_label("volume.transfer.range").click();
    h.run_steps(2);
    h.get_by_label("robust").click();
    h.run_steps(2);
    let tf = &h.state().scene.volume.as_ref().unwrap().transfer;
    assert_eq!(tf.range, scene::spec::TransferRange::Named("robust".into()));
    // Wait for the full image of this state, then take the screenshot.
    let t = Instant::now();
    while h.state().shown_level() != Some(Level::Full) && t.elapsed() < Duration::from_secs(60) {
        std::thread::sleep(Duration::from_millis(50));
        h.run_steps(1);
    }
    assert_eq!(h.state().shown_level(), Some(Level::Full));
    // `dos` sweeps the light volume, and the panel says which (as `umbra render` does).
    let light = h.get_by_label_contains("cells of");
    let text = format!("{light:?}");
    assert!(
        text.contains("light ") && text.contains("steps of"),
        "{text}"
    );
    let prefix = dir.path().join("shot");
    h.state_mut().set_prefix(prefix.to_str().unwrap());
    let shown = full.load(std::sync::atomic::Ordering::SeqCst);
    h.get_by_label("screenshot .png").click();
    h.run_steps(1);
    let png = dir.path().join("shot.png");
    let t = Instant::now();
    while h.state().message().is_none() && t.elapsed() < Duration::from_secs(60) {
        std::thread::sleep(Duration::from_millis(50));
        h.run_steps(1);
    }
    assert!(
        h.state().message().is_some_and(|m| m.starts_with("wrote")),
        "{:?}",
        h.state().message()
    );
    // The screenshot's render is no image of the interaction: the frame log's count of full
    // images stays (it grew by one a screenshot).
    assert_eq!(full.load(std::sync::atomic::Ordering::SeqCst), shown);
    // The same state through the headless renderer.
    let state = h.state().state();
    let m = scene::compile::model(&state).unwrap();
    let gpu = engine::gpu::Gpu::new().unwrap();
    let (out, v) = scene::compile::render_scene(&gpu, &state, &m, 1).unwrap();
    let img = image::open(&png).unwrap().to_rgb8();
    assert_eq!(img.dimensions(), (v.width, v.height));
    let diff = common::png_difference(&img, &out.image);
    assert!(
        diff <= 1.0,
        "screenshot and headless render differ by {diff} levels"
    );
}

/// The file dialog lists folders and the files the viewer can open (not others), opening a
/// tractogram adds it as `[[lines]]`, and its rotation widgets turn it about the camera's target.
#[test]
fn the_file_dialog_opens_a_tractogram_and_its_rotation_turns_it_about_the_pivot() {
    let dir = tempfile::tempdir().unwrap();
    let path = test_support::headsq_scene(dir.path(), "", "bone", "method = \"ea\"\n");
    let files = dir.path().join("files");
    std::fs::create_dir(&files).unwrap();
    std::fs::create_dir(files.join("sub")).unwrap();
    std::fs::copy(
        test_support::fixtures().join("tracts/dipy/tracks300.trk"),
        files.join("tracks300.trk"),
    )
    .unwrap();
    std::fs::write(files.join("notes.txt"), "not data").unwrap();
    let mut h = window(&path, [900.0, 800.0], WithEditor::No);
    h.run_steps(2);
    h.get_by_label("objects").click_accesskit();
    h.run_steps(2);
    h.state_mut().set_open_field(files.to_str().unwrap());
    h.get_by_label("browse…").click_accesskit();
    h.run_steps(3);
    assert!(h.state().browsing());
    assert!(h.query_by_label("sub/").is_some(), "folders are listed");
    assert!(
        h.query_by_label("notes.txt").is_none(),
        "other files are not"
    );
    h.get_by_label("tracks300.trk").click_accesskit();
    h.run_steps(2);
    h.get_by_label("open file").click_accesskit();
    h.run_steps(3);
    assert!(!h.state().browsing());
    assert_eq!(h.state().scene.lines.len(), 1);
    assert!(
        h.state().message().is_some_and(|m| m.contains("lines[0]")),
        "{:?}",
        h.state().message()
    );
    assert_eq!(h.state().scene.lines[0].transform, None);
    // 30 steps of 1 degree about z, then 10 about x: a pose turned about the camera's target.
    let rotate = h
        .get_all_by_label("  lines[0] rotate °")
        .collect::<Vec<_>>();
    assert_eq!(rotate.len(), 3, "x, y, z");
    for _ in 0..30 {
        rotate[2].increment_accesskit();
    }
    drop(rotate);
    h.run_steps(2);
    let rotate = h
        .get_all_by_label("  lines[0] rotate °")
        .collect::<Vec<_>>();
    for _ in 0..10 {
        rotate[0].increment_accesskit();
    }
    drop(rotate);
    h.run_steps(2);
    let m = h.state().scene.lines[0].transform.expect("a transform");
    let pose = umbra_viewer::transform::decompose(&m).expect("a pose");
    assert!(
        (pose.angles[0] - 10.0).abs() < 1e-6
            && pose.angles[1].abs() < 1e-6
            && (pose.angles[2] - 30.0).abs() < 1e-6,
        "{:?}",
        pose.angles
    );
    let p = h.state().orbit.target;
    let moved = [0, 1, 2]
        .map(|r| m[r * 4] * p.x + m[r * 4 + 1] * p.y + m[r * 4 + 2] * p.z + m[r * 4 + 3] - p[r]);
    assert!(
        moved.iter().all(|d| d.abs() < 1e-9),
        "the target moved by {moved:?}"
    );
}

/// The value x gradient tab: a 1-D function made 2-D, a row added by a click on the
/// histogram, a row dragged up, and the renderer drawing the result.
#[test]
fn the_value_gradient_tab_adds_and_moves_rows_over_the_histogram() {
    let dir = tempfile::tempdir().unwrap();
    let path = test_support::headsq_scene(dir.path(), "", "bone", "method = \"ea\"\n");
    let mut h = window(&path, [900.0, 900.0], WithEditor::TwoD);
    h.run_steps(2);
    h.get_by_label("value × gradient").click_accesskit();
    h.run_steps(2);
    h.get_by_label("make 2-D").click_accesskit();
    h.run_steps(2);
    let tf = |h: &Harness<App>| h.state().scene.volume.as_ref().unwrap().transfer.clone();
    let rows0 = umbra_viewer::transfer::rows(&tf(&h));
    assert_eq!(rows0.len(), 2);
    // A click at the plot's middle (between the rows' handles) adds a row there.
    let plot = h.get_by_label("value x gradient plot").rect();
    h.get_by_label("value x gradient plot").click();
    h.run_steps(2);
    let rows1 = umbra_viewer::transfer::rows(&tf(&h));
    assert_eq!(rows1.len(), 3, "{rows1:?}");
    let added = *rows1.iter().find(|g| !rows0.contains(g)).unwrap();
    // Its first handle sits at the left edge (the lowest value): drag it 30 points up.
    let at = egui::pos2(plot.left() + 1.0, plot.center().y);
    h.drag_at(at);
    h.run_steps(1);
    for dy in [10.0, 20.0, 30.0] {
        h.hover_at(at - egui::vec2(0.0, dy));
        h.run_steps(1);
    }
    h.drop_at(at - egui::vec2(0.0, 30.0));
    h.run_steps(2);
    let rows2 = umbra_viewer::transfer::rows(&tf(&h));
    assert_eq!(rows2.len(), 3);
    // The points' rows (gradient, value, colour, extinction, remove) stay within the panel,
    // as wide as the plot: wrapped, not cut off at its edge.
    let removes: Vec<egui::Rect> = h.get_all_by_label("x").map(|n| n.rect()).collect();
    assert_eq!(
        removes.len(),
        tf(&h).points.len(),
        "a remove button a point"
    );
    for r in removes {
        assert!(r.right() <= plot.right() + 1.0, "{r:?} beyond {plot:?}");
    }
    // The dragged row went up (to a higher gradient, still below the row above it); the
    // others stayed.
    let moved: Vec<f64> = rows2
        .iter()
        .copied()
        .filter(|g| !rows1.contains(g))
        .collect();
    assert!(
        moved.len() == 1 && moved[0] > added && rows2.len() == 3,
        "{rows1:?} -> {rows2:?}"
    );
    // The worker draws the 2-D function (its full image, no error).
    let t = Instant::now();
    while h.state().shown_level() != Some(Level::Full) && t.elapsed() < Duration::from_secs(60) {
        std::thread::sleep(Duration::from_millis(50));
        h.run_steps(1);
    }
    assert_eq!(h.state().shown_level(), Some(Level::Full));
}

/// The LineAO section edits `[render.lineao]` (here: anisotropic on, its alignment menu appears,
/// the levels slider), and the saved scene carries the keys back through the scene parser.
#[test]
fn the_lineao_section_edits_render_lineao_and_the_saved_scene_keeps_it() {
    let dir = tempfile::tempdir().unwrap();
    let path = test_support::headsq_scene(dir.path(), "", "bone", "method = \"ea\"\n");
    let mut h = window(&path, [900.0, 1400.0], WithEditor::No);
    h.run_steps(2);
    h.get_by_label("LineAO").click_accesskit();
    h.run_steps(2);
    assert!(
        h.query_by_label("alignment").is_none(),
        "shown only when anisotropic"
    );
    h.get_by_label("anisotropic").click_accesskit();
    h.run_steps(2);
    assert!(h.state().scene.render.lineao.anisotropic);
    assert!(h.query_by_label("alignment").is_some());
    h.get_by_role_and_label(egui::accesskit::Role::Slider, "levels (s_r)")
        .increment_accesskit();
    h.run_steps(2);
    let levels = h.state().scene.render.lineao.levels;
    assert_eq!(levels, scene::spec::LineAoSpec::default().levels + 1);
    let prefix = dir.path().join("saved");
    h.state_mut().set_prefix(prefix.to_str().unwrap());
    h.get_by_label("scene .toml").click_accesskit();
    h.run_steps(2);
    let saved = scene::spec::load(&dir.path().join("saved.toml"), &[]).unwrap();
    assert!(saved.render.lineao.anisotropic);
    assert_eq!(saved.render.lineao.levels, levels);
}

#[test]
fn a_paced_window_stops_waiting_for_a_request_the_worker_failed() {
    // A window paced as on a CPU adapter waits (up to the pace) for the image of a request
    // still being drawn; a request the worker answered with an error is done with, so later
    // frames neither wait for it nor lose the error. The worker here is the test: it receives
    // the requests and answers by hand.
    let dir = tempfile::tempdir().unwrap();
    let path = test_support::headsq_scene(dir.path(), "", "bone", "method = \"ea\"\n");
    let s = scene::spec::load(&path, &[]).unwrap();
    let bounds = [glam::DVec3::splat(-1.0), glam::DVec3::splat(1.0)];
    let (req_tx, req_rx) = std::sync::mpsc::channel();
    let (img_tx, img_rx) = std::sync::mpsc::channel();
    let worker = umbra_viewer::worker::Worker {
        requests: req_tx,
        images: img_rx,
    };
    let pace = Duration::from_millis(600);
    let app = App::new(s, bounds, worker, Arc::new(AtomicBool::new(false)), None).paced(pace);
    let mut h = Harness::builder()
        .with_size(egui::vec2(600.0, 400.0))
        .build_ui_state(|ui, app: &mut App| app.show_ui(ui), app);
    // The first frame (the harness's) asked for a draft at the view's size and waited for it
    // (the pace); the next, after the rest, asks for the full image. A frame right after
    // another waits while the request is being drawn.
    h.step();
    let req: umbra_viewer::worker::Request = req_rx.try_iter().last().expect("requests");
    assert_eq!(req.level, Level::Full);
    let t = Instant::now();
    h.step();
    assert!(t.elapsed() >= pace * 9 / 10, "{:?}", t.elapsed());
    img_tx
        .send((req.id, Err("the renderer said no".to_string())))
        .unwrap();
    // The error comes in; nothing is being drawn any more: no frame waits.
    for _ in 0..3 {
        let t = Instant::now();
        h.step();
        assert!(t.elapsed() < pace / 2, "a frame waited {:?}", t.elapsed());
    }
    assert!(h.state().shown_level().is_none());
    assert!(req_rx.try_recv().is_err(), "no request was made again");
}

/// Ctrl + drag over the view moves the chosen clipping plane along its normal (a plane facing
/// the view's right follows a drag to the right by the drag's length in world units), a plain
/// drag still orbits, and a plane added in the panel becomes the one dragged.
#[test]
fn ctrl_drag_moves_the_chosen_clip_plane_along_its_normal() {
    let dir = tempfile::tempdir().unwrap();
    let path = test_support::headsq_scene(
        dir.path(),
        "background = [1.0, 1.0, 1.0]\n[[clip]]\nnormal = [1.0, 0.0, 0.0]\noffset = 100.0\n",
        "bone",
        "method = \"ea\"\nfxaa = false\n",
    );
    let (w, h_points) = (900.0, 800.0);
    let mut h = window(&path, [w, h_points], WithEditor::No);
    h.run_steps(3);
    assert_eq!(
        h.state().clip_drag,
        Some(0),
        "a scene's first plane is the one dragged"
    );
    // Look along +y: the view's right is +x, the plane's normal.
    h.state_mut().orbit.azimuth = 0.0;
    h.state_mut().orbit.elevation = 0.0;
    let o = h.state().orbit;
    let b = scene::compile::model(&h.state().scene).unwrap().bounds;
    let radius = (b[1] - b[0]).length() * 0.5;
    // World units a point at the target's depth, the view as tall as the window.
    let fov = h.state().scene.camera.fov_y.to_radians();
    let per_point = 2.0 * o.distance * radius * (fov * 0.5).tan() / h_points as f64;
    let drag = |h: &mut Harness<'static, App>, m: egui::Modifiers, dx: f32| {
        h.event(egui::Event::ModifiersChanged(m));
        h.run_steps(1);
        h.drag_at(egui::pos2(500.0, 300.0));
        h.run_steps(1);
        for i in 1..=4 {
            h.hover_at(egui::pos2(500.0 + dx * i as f32 / 4.0, 300.0));
            h.run_steps(1);
        }
        h.drop_at(egui::pos2(500.0 + dx, 300.0));
        h.run_steps(1);
        h.event(egui::Event::ModifiersChanged(egui::Modifiers::NONE));
        h.run_steps(1);
    };
    drag(&mut h, egui::Modifiers::CTRL, 100.0);
    let moved = h.state().scene.clip[0].offset - 100.0;
    let want = 100.0 * per_point;
    assert!(
        (moved - want).abs() < 0.03 * want,
        "offset moved {moved}, {want} wanted"
    );
    assert_eq!(
        h.state().orbit,
        o,
        "a ctrl + drag moves the plane, not the camera"
    );
    // The renderer is asked for the moved plane.
    assert_eq!(h.state().state().clip[0].offset, 100.0 + moved);
    // A plain drag orbits and leaves the plane.
    drag(&mut h, egui::Modifiers::NONE, 100.0);
    assert!((h.state().orbit.azimuth - (o.azimuth - 40.0)).abs() < 1.0);
    assert_eq!(h.state().scene.clip[0].offset, 100.0 + moved);
    // Ctrl + shift + drag tilts it: 50 points across turn its normal 20 degrees about the
    // view's up axis, the plane keeping its distance from the camera's target.
    let target = h.state().orbit.target;
    let n0 = glam::DVec3::from(h.state().scene.clip[0].normal);
    let gap = h.state().scene.clip[0].offset - n0.dot(target);
    drag(&mut h, egui::Modifiers::CTRL | egui::Modifiers::SHIFT, 50.0);
    let c = &h.state().scene.clip[0];
    let n1 = glam::DVec3::from(c.normal);
    let turned = n0.angle_between(n1).to_degrees();
    assert!((turned - 20.0).abs() < 0.5, "turned {turned} degrees");
    assert!(
        (c.offset - n1.dot(target) - gap).abs() < 1e-6,
        "as far from the target"
    );
    let tilted = c.clone();
    // A second plane from the panel is the one dragged now; the first stays.
    h.get_by_label("clip planes (1)").click();
    h.run_steps(2);
    h.get_by_label("add clip plane").click();
    h.run_steps(2);
    assert_eq!(h.state().clip_drag, Some(1));
    let before = h.state().scene.clip[1].offset;
    drag(&mut h, egui::Modifiers::CTRL, -60.0);
    assert_eq!(h.state().scene.clip[0], tilted);
    assert!(h.state().scene.clip[1].offset != before);
    // The section stays open as a plane is added; its radio button picks the first again.
    h.get_by_label("clip[0]: ctrl+drag in the view").click();
    h.run_steps(2);
    assert_eq!(h.state().clip_drag, Some(0));
    // Removing a plane before the dragged one keeps dragging that plane (now the first);
    // removing the dragged plane drags none.
    h.get_by_label("clip[1]: ctrl+drag in the view").click();
    h.run_steps(2);
    let second = h.state().scene.clip[1].offset;
    h.query_all_by_label("remove").next().unwrap().click();
    h.run_steps(2);
    assert_eq!(h.state().scene.clip.len(), 1);
    assert_eq!(h.state().scene.clip[0].offset, second);
    assert_eq!(h.state().clip_drag, Some(0));
    h.get_by_label("remove").click();
    h.run_steps(2);
    assert!(h.state().scene.clip.is_empty());
    assert_eq!(h.state().clip_drag, None);
}

/// Steps the window until `done` holds (60 s at most).
fn step_until(h: &mut Harness<'static, App>, mut done: impl FnMut(&App) -> bool) {
    let t = Instant::now();
    while !done(h.state()) && t.elapsed() < Duration::from_secs(60) {
        std::thread::sleep(Duration::from_millis(50));
        h.run_steps(1);
    }
    assert!(done(h.state()), "not within 60 s");
}

/// The method menu's `mip` draws what `umbra render` draws of the saved state (the projection's
/// colour map, not the transfer function the model was made with), and a volume opened from a
/// file the worker cannot read is taken out again: the scene as before, the reader's error
/// shown, and the view drawn anew.
#[test]
fn a_switch_to_mip_is_the_headless_image_and_an_unreadable_volume_is_taken_back() {
    let dir = tempfile::tempdir().unwrap();
    let path = test_support::headsq_scene(dir.path(), "", "fire", "method = \"ea\"\n");
    let (mut h, full) = window_counting(&path, [900.0, 800.0], WithEditor::OneD);
    let seen =
        |n: &Arc<std::sync::atomic::AtomicUsize>| n.load(std::sync::atomic::Ordering::SeqCst);
    h.run_steps(2);
    step_until(&mut h, |a| a.shown_level() == Some(Level::Full));
    // mip from the menu; its full image, then the screenshot of it.
    let before = seen(&full);
    h.get_by_label("method").click();
    h.run_steps(2);
    h.get_by_label("mip").click();
    h.run_steps(2);
    assert_eq!(h.state().scene.render.method, engine::method::Method::Mip);
    let t = Instant::now();
    while seen(&full) == before && t.elapsed() < Duration::from_secs(60) {
        std::thread::sleep(Duration::from_millis(50));
        h.run_steps(1);
    }
    assert!(seen(&full) > before, "no full image after the switch");
    let prefix = dir.path().join("mip");
    h.state_mut().set_prefix(prefix.to_str().unwrap());
    h.get_by_label("screenshot .png").click();
    h.run_steps(1);
    step_until(&mut h, |a| {
        a.message().is_some_and(|m| m.starts_with("wrote"))
    });
    let state = h.state().state();
    let m = scene::compile::model(&state).unwrap();
    let gpu = engine::gpu::Gpu::new().unwrap();
    let (out, _) = scene::compile::render_scene(&gpu, &state, &m, 1).unwrap();
    let img = image::open(dir.path().join("mip.png")).unwrap().to_rgb8();
    let diff = common::png_difference(&img, &out.image);
    assert!(
        diff <= 1.0,
        "mip screenshot and headless render differ by {diff} levels"
    );
    // A volume file cut short: opened (it reads as a volume by its name), not drawable.
    let bad = dir.path().join("cut.nrrd");
    std::fs::write(
        &bad,
        b"NRRD0004\ntype: float\ndimension: 3\nsizes: 8 8 8\nencoding: raw\nendian: little\n\n0123",
    )
    .unwrap();
    let original = h.state().scene.volume.as_ref().unwrap().path.clone();
    let before = seen(&full);
    h.get_by_label("objects").click_accesskit();
    h.run_steps(2);
    h.state_mut().set_open_field(bad.to_str().unwrap());
    h.get_by_label("add").click_accesskit();
    h.run_steps(2);
    step_until(&mut h, |a| {
        a.message().is_some_and(|m| m.contains("not opened"))
    });
    assert_eq!(h.state().scene.volume.as_ref().unwrap().path, original);
    // The view is drawn again.
    let t = Instant::now();
    while seen(&full) == before && t.elapsed() < Duration::from_secs(60) {
        std::thread::sleep(Duration::from_millis(50));
        h.run_steps(1);
    }
    assert!(
        seen(&full) > before,
        "no image after the file was taken back"
    );
    // The reader's error, naming the file, stays shown with the view drawn again.
    let m = h.state().message().unwrap_or_default().to_string();
    assert!(m.contains("not opened") && m.contains("cut.nrrd:"), "{m}");
    assert!(h.query_by_label_contains("cut.nrrd:").is_some(), "{m}");
}

/// The CT head as the grid of `slices` (TOML `[[slices]]` entries), its volume not drawn, 96 x
/// 72 `ea`.
fn slices_scene(dir: &std::path::Path, slices: &str) -> std::path::PathBuf {
    let path = test_support::headsq_scene(
        dir,
        "",
        "bone",
        "method = \"ea\"\nwidth = 96\nheight = 72\n",
    );
    let text = std::fs::read_to_string(&path)
        .unwrap()
        .replace("[volume.transfer]", "render = false\n[volume.transfer]")
        + slices;
    std::fs::write(&path, text).unwrap();
    path
}

/// The objects panel's slice rows: a position moved along the grid, a slice lit and another
/// hidden reach the drawn scene (the hidden one left out of it), and the worker draws them.
#[test]
fn the_objects_panel_moves_lights_and_hides_slices() {
    let dir = tempfile::tempdir().unwrap();
    let path = slices_scene(
        dir.path(),
        "[[slices]]\naxis = \"axial\"\n[[slices]]\naxis = \"coronal\"\n",
    );
    let mut h = window(&path, [900.0, 900.0], WithEditor::No);
    step_until(&mut h, |a| a.shown_level() == Some(Level::Full));
    h.get_by_label("objects").click_accesskit();
    h.run_steps(2);
    let s0 = h.state().scene.clone();
    let m = scene::compile::model(&s0).unwrap();
    let grid = umbra_viewer::objects::SliceGrid::of(&m).unwrap();
    let (z0, [zlo, zhi]) = grid.position(&s0.slices[0]);
    for _ in 0..30 {
        h.get_by_label("  slices[0] position").increment_accesskit();
        h.run_steps(1);
    }
    let z = h.state().scene.slices[0].position.expect("a position");
    // 30 steps of the drag speed, each rounded to the field's two decimals (not to whole
    // millimetres, which would put the slice up to half a millimetre off at every step).
    let step = (zhi - zlo) / 300.0;
    assert!(
        (z - (z0 + 30.0 * step)).abs() < 30.0 * 0.005 + 1e-9 && z <= zhi,
        "{z0} -> {z}, steps of {step}"
    );
    h.get_all_by_label("lit").next().unwrap().click_accesskit();
    h.run_steps(2);
    assert!(h.state().scene.slices[0].lit);
    // The window menu: the robust range, re-planned on the model's grid.
    h.get_by_label("  slices[0] window").click();
    h.run_steps(2);
    h.get_by_label("robust").click();
    h.run_steps(2);
    assert_eq!(
        h.state().scene.slices[0].window,
        Some(scene::spec::Window::Named("robust".into()))
    );
    h.get_by_label("slices[1]").click_accesskit();
    h.run_steps(2);
    let drawn = h.state().state();
    assert_eq!(drawn.slices.len(), 1, "the hidden slice is not drawn");
    assert_eq!(drawn.slices[0].position, Some(z));
    assert_eq!(h.state().scene.slices.len(), 2, "hidden, not removed");
    // The worker draws the new state in full, with no error.
    step_until(&mut h, |a| {
        a.error().is_some()
            || (a.shown_level() == Some(Level::Full) && a.shown_scene() == Some(&a.state()))
    });
    assert!(h.state().error().is_none(), "{:?}", h.state().error());
}

/// A volume opened in place of another, with slices at positions of their own: the one the
/// new grid holds stays, the one it misses goes to its centre (the volume was refused, the
/// slice's plane "does not cut the volume"), and the message says which moved.
#[test]
fn a_new_volume_keeps_the_slices_it_holds_and_centres_the_others() {
    let dir = tempfile::tempdir().unwrap();
    // headsq spans z 0 to 138 mm and y 0 to 201.6 mm; the MNI T1 z -72 to 109, y -126 to 90.
    let path = slices_scene(
        dir.path(),
        "[[slices]]\naxis = \"axial\"\nposition = 130.0\n\
         [[slices]]\naxis = \"coronal\"\nposition = 10.0\n",
    );
    let mut h = window(&path, [900.0, 900.0], WithEditor::No);
    step_until(&mut h, |a| a.shown_level() == Some(Level::Full));
    h.get_by_label("objects").click_accesskit();
    h.run_steps(2);
    let mni = test_support::root().join("datasets/mni/mni_icbm152_t1_tal_nlin_sym_09a.nii.gz");
    h.state_mut().set_open_field(mni.to_str().unwrap());
    h.get_by_label("add").click_accesskit();
    h.run_steps(2);
    step_until(&mut h, |a| {
        a.message().is_some_and(|m| m.contains("moved to"))
            || a.message().is_some_and(|m| m.contains("not opened"))
    });
    let m = h.state().message().unwrap_or_default().to_string();
    assert!(
        m.contains("slices[0] at 130 mm misses it") && !m.contains("slices[1]"),
        "{m}"
    );
    assert_eq!(h.state().scene.volume.as_ref().unwrap().path, mni);
    assert_eq!(h.state().scene.slices[0].position, None);
    assert_eq!(h.state().scene.slices[1].position, Some(10.0));
    // The scene's camera looks at the centre of its bounds: the view follows the new data.
    let m = scene::compile::model(&h.state().state()).unwrap();
    let centre = (m.bounds[0] + m.bounds[1]) * 0.5;
    assert!(
        (h.state().orbit.target - centre).length() < 1e-6,
        "{} against {centre}",
        h.state().orbit.target
    );
    // Drawn in full with the kept position, no error.
    step_until(&mut h, |a| {
        a.error().is_some()
            || (a.shown_level() == Some(Level::Full) && a.shown_scene() == Some(&a.state()))
    });
    assert!(h.state().error().is_none(), "{:?}", h.state().error());
}
