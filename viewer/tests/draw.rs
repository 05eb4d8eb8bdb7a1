//! The viewer draws what `umbra render` draws: its orbit written into the scene gives the image
//! of the scene with those camera keys, and a draft is the cheap image it says it is.

mod common;

use umbra_viewer::controls::Orbit;
use umbra_viewer::worker::{draw, Level, Request};

fn headsq_scene(dir: &std::path::Path) -> std::path::PathBuf {
    test_support::headsq_scene(
        dir,
        "background = [1.0, 1.0, 1.0]\n[camera]\nazimuth = 30.0\nelevation = 20.0\n",
        "bone",
        "method = \"combined\"\nwidth = 96\nheight = 72\nfxaa = false\n",
    )
}

/// A frame of `scene` at `level` (no screenshot).
fn frame(
    up: &scene::compile::Uploaded,
    m: &scene::compile::Model,
    scene: &scene::spec::Scene,
    level: Level,
) -> umbra_viewer::worker::Image {
    let req = Request {
        id: 0,
        scene: scene.clone(),
        level,
        save: None,
        pass_timings: false,
    };
    draw(up, m, &req).unwrap()
}

/// Values of two images of one size that differ by more than 8 levels.
fn changed(a: &[u8], b: &[u8]) -> usize {
    a.iter().zip(b).filter(|(x, y)| x.abs_diff(**y) > 8).count()
}

/// The headsq scene, its model, a GPU context (leaked: one per test) and the upload.
fn setup(
    dir: &std::path::Path,
) -> (
    std::path::PathBuf,
    scene::spec::Scene,
    scene::compile::Model,
    &'static engine::gpu::Gpu,
    scene::compile::Uploaded<'static>,
) {
    let path = headsq_scene(dir);
    let s = scene::spec::load(&path, &[]).unwrap();
    let m = scene::compile::model(&s).unwrap();
    let gpu: &'static engine::gpu::Gpu = Box::leak(Box::new(engine::gpu::Gpu::new().unwrap()));
    let up = scene::compile::upload(gpu, &m).unwrap();
    (path, s, m, gpu, up)
}

#[test]
fn the_orbit_draws_the_scene_with_those_camera_keys_and_drafts_are_cheap() {
    let dir = tempfile::tempdir().unwrap();
    let (path, s, m, gpu, up) = setup(dir.path());
    // A drag of 100 points right and 20 down: azimuth 30 - 40, elevation 20 + 8.
    let orbit = Orbit::of(&s.camera, m.bounds).drag(100.0, 20.0);
    let mut state = s.clone();
    orbit.apply(&mut state.camera);
    let full = frame(&up, &m, &state, Level::Full);
    assert_eq!(full.size, [96, 72]);
    // The same camera by its scene keys, through the headless renderer.
    let keyed = scene::spec::load(
        &path,
        &[
            "camera.azimuth=-10.0".into(),
            "camera.elevation=28.0".into(),
        ],
    )
    .unwrap();
    let (out, _) = scene::compile::render_scene(gpu, &keyed, &m, 1).unwrap();
    let png: Vec<u8> = out
        .image
        .iter()
        .flat_map(|p| [0, 1, 2].map(|c| scene::image_io::srgb8(p[c])))
        .collect();
    let rgb: Vec<u8> = full
        .rgba
        .chunks(4)
        .flat_map(|p| [p[0], p[1], p[2]])
        .collect();
    let diff = png
        .iter()
        .zip(&rgb)
        .map(|(a, b)| (*a as f64 - *b as f64).abs())
        .sum::<f64>()
        / png.len() as f64;
    assert!(
        diff <= 1.0,
        "the viewer's image differs by {diff} levels in mean"
    );
    // The head is in the picture, not only the background.
    assert!(rgb.iter().filter(|&&v| v < 200).count() > rgb.len() / 20);
    // Another view gives another image (the orbit is not ignored).
    let mut other = s.clone();
    orbit.drag(200.0, 0.0).apply(&mut other.camera);
    let turned = frame(&up, &m, &other, Level::Full);
    let moved = changed(&turned.rgba, &full.rgba);
    assert!(moved > full.rgba.len() / 50, "{moved} values changed");
    // A pan moves the picture (the renderer orbits the moved target).
    let mut panned = s.clone();
    orbit.pan(20.0, 0.0).apply(&mut panned.camera);
    let shifted = frame(&up, &m, &panned, Level::Full);
    let moved = changed(&shifted.rgba, &full.rgba);
    assert!(moved > full.rgba.len() / 50, "a pan changed {moved} values");
    // The draft: a quarter of the size, drawn by ea.
    let draft = frame(&up, &m, &state, Level::Draft);
    assert_eq!(draft.size, [24, 18]);
    assert_eq!(draft.rgba.len(), 24 * 18 * 4);
    // Passes are timed only for a full image that asks for it (drafts never: on lavapipe the
    // timing draws every pass again); the image is the same.
    assert!(full.passes.is_empty() && draft.passes.is_empty());
    let timed = |level| {
        draw(
            &up,
            &m,
            &Request {
                id: 1,
                scene: state.clone(),
                level,
                save: None,
                pass_timings: true,
            },
        )
        .unwrap()
    };
    let t = timed(Level::Full);
    assert!(!t.passes.is_empty(), "{:?}", t.passes);
    assert_eq!(t.rgba, full.rgba);
    assert!(timed(Level::Draft).passes.is_empty());
}

#[test]
fn a_screenshot_is_what_umbra_render_draws_of_the_saved_scene() {
    let dir = tempfile::tempdir().unwrap();
    let (_, s, m, gpu, up) = setup(dir.path());
    let mut state = s.clone();
    Orbit::of(&s.camera, m.bounds)
        .drag(-60.0, 30.0)
        .pan(4.0, -2.0)
        .apply(&mut state.camera);
    state.render.method = engine::method::Method::Dos;
    // With a title and the volume's colour bar, drawn over the image as `umbra render` draws
    // them (the viewer left them out).
    state.annotate.title = Some("headsq".into());
    state.annotate.colorbar = Some("volume".into());
    let m = scene::compile::model(&state).unwrap();
    // The screenshot, through the worker's draw.
    let shot = dir.path().join("out/shot.png");
    let img = draw(
        &up,
        &m,
        &Request {
            id: 1,
            scene: state.clone(),
            level: Level::Full,
            save: Some((shot.clone(), false)),
            pass_timings: false,
        },
    )
    .unwrap();
    assert_eq!(img.saved.as_ref().unwrap().as_ref().unwrap(), &shot);
    // The scene saved elsewhere, loaded back and rendered headless.
    let saved = dir.path().join("elsewhere/state.toml");
    std::fs::create_dir_all(saved.parent().unwrap()).unwrap();
    umbra_viewer::write_atomic(&saved, scene::spec::to_toml(&state).unwrap().as_bytes()).unwrap();
    let back = scene::spec::load(&saved, &[]).unwrap();
    assert_eq!(back.render.method, engine::method::Method::Dos);
    let (out, _) = scene::compile::render_scene(gpu, &back, &m, 1).unwrap();
    let png = image::open(&shot).unwrap().to_rgb8();
    assert_eq!(png.dimensions(), (96, 72));
    // The frame without its annotations differs where they are drawn (the title's and the
    // bar's rows) ...
    let diff = common::png_difference(&png, &out.image);
    assert!(diff > 0.5, "no annotations in the screenshot ({diff})");
    // ... and `umbra render` of the saved scene writes the screenshot's image.
    let rendered = dir.path().join("elsewhere/render.png");
    scene::render::run(
        &scene::render::RenderArgs {
            scene: saved.clone(),
            output: rendered.clone(),
            frames: 1,
            ..Default::default()
        },
        &mut |_| {},
    )
    .unwrap();
    let r = image::open(&rendered).unwrap().to_rgb8();
    let mean = png
        .as_raw()
        .iter()
        .zip(r.as_raw())
        .map(|(a, b)| a.abs_diff(*b) as f64)
        .sum::<f64>()
        / png.as_raw().len() as f64;
    assert!(
        mean <= 1.0,
        "screenshot and umbra render differ by {mean} levels in mean"
    );
    // An unwritable screenshot (its folder is a file) is reported, not a crash.
    std::fs::write(dir.path().join("blocker"), b"a file").unwrap();
    let bad = draw(
        &up,
        &m,
        &Request {
            id: 2,
            scene: state,
            level: Level::Full,
            save: Some((dir.path().join("blocker/x.png"), false)),
            pass_timings: false,
        },
    )
    .unwrap();
    let err = bad.saved.unwrap().unwrap_err();
    assert!(err.contains("blocker"), "{err}");
}

#[test]
fn the_session_rebuilds_for_opened_files_and_survives_bad_settings() {
    let dir = tempfile::tempdir().unwrap();
    let path = headsq_scene(dir.path());
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .unwrap();
    let s = scene::spec::load(&path, &[]).unwrap();
    let m = scene::compile::model(&s).unwrap();
    let volume_bounds = m.bounds;
    let mut session = umbra_viewer::worker::Session::new(m, &s).unwrap();
    let frame = |session: &mut umbra_viewer::worker::Session, scene: &scene::spec::Scene| {
        session.frame(&Request {
            id: 0,
            scene: scene.clone(),
            level: Level::Full,
            save: None,
            pass_timings: false,
        })
    };
    let first = frame(&mut session, &s).unwrap();
    assert!(first.rebuilt.is_none(), "the same scene needs no new model");
    // A tractogram opened into the scene: a new model with the lines, bounds grown.
    let mut with_lines = s.clone();
    let msg = umbra_viewer::objects::open(
        &mut with_lines,
        &root.join("datasets/tracts/AF_R_demo.trk.gz"),
    )
    .unwrap();
    assert!(msg.contains("lines[0]"), "{msg}");
    let img = frame(&mut session, &with_lines).unwrap();
    let r = img.rebuilt.expect("a new model");
    assert!(r.volume);
    assert_eq!(session.model().lines.len(), 1);
    let grown = (0..3).any(|a| {
        r.bounds[0][a] < volume_bounds[0][a] - 1e-6 || r.bounds[1][a] > volume_bounds[1][a] + 1e-6
    });
    assert!(grown, "{:?} within {:?}", r.bounds, volume_bounds);
    // A transfer function the renderer refuses is an error naming the key, and the session
    // draws the next good frame.
    let mut bad = with_lines.clone();
    bad.volume.as_mut().unwrap().transfer.preset = "nope".into();
    let e = frame(&mut session, &bad).err().unwrap();
    assert!(e.contains("volume.transfer.preset"), "{e}");
    let again = frame(&mut session, &with_lines).unwrap();
    assert_eq!(again.size, [96, 72]);
    // The lines hidden: the model without them.
    let hidden = umbra_viewer::objects::Hidden {
        lines: vec![true],
        ..Default::default()
    };
    let img = frame(&mut session, &hidden.apply(&with_lines)).unwrap();
    assert!(session.model().lines.is_empty());
    // The same volume: the ranges and histograms kept from the rebuild before are the model's.
    let kept = img.rebuilt.expect("a new model");
    let m = session.model();
    let range = umbra_viewer::worker::data_range(m);
    assert_eq!((kept.range, kept.robust), (r.range, r.robust));
    assert_eq!(kept.range, range);
    assert_eq!(kept.robust, umbra_viewer::worker::robust_range(m, range));
    assert_eq!(
        kept.histogram,
        umbra_viewer::worker::histogram(m, range, 128)
    );
    assert_eq!(
        kept.histogram2d,
        umbra_viewer::worker::histogram2d(m, range, 128, 64)
    );
    // Another volume opened: its own ranges and histogram, not those kept.
    let mut other = hidden.apply(&with_lines);
    umbra_viewer::objects::open(
        &mut other,
        &root.join("datasets/mni/mni_icbm152_wm_tal_nlin_sym_09a.nii.gz"),
    )
    .unwrap();
    let fresh = frame(&mut session, &other).unwrap().rebuilt.unwrap();
    let m = session.model();
    let range = umbra_viewer::worker::data_range(m);
    assert!(
        fresh.range != kept.range && fresh.range == range,
        "{:?}",
        fresh.range
    );
    assert_eq!(fresh.robust, umbra_viewer::worker::robust_range(m, range));
    assert_eq!(
        fresh.histogram,
        umbra_viewer::worker::histogram(m, range, 128)
    );
}

/// A draft's share of the geometry is drawn from the full upload's volume and points with only
/// its segment list uploaded (`Uploaded::with_shares`): its frames equal those of the same
/// share uploaded whole, with its own copy of the volume and of the points.
#[test]
fn a_share_of_the_lines_drawn_with_the_shared_volume_equals_its_own_upload() {
    let dir = tempfile::tempdir().unwrap();
    // Streamlines across the head (headsq spans about 0..205 x 0..205 x 0..140 mm).
    let mut sl = tubes::Streamlines::new();
    for i in 0..40 {
        let y = 20.0 + 4.0 * i as f32;
        let pts: Vec<glam::Vec3> = (0..60)
            .map(|k| glam::Vec3::new(3.5 * k as f32, y, 40.0 + 0.5 * i as f32))
            .collect();
        sl.push(&pts);
    }
    let tck = dir.path().join("lines.tck");
    tubes::tck::write(&tck, &sl).unwrap();
    let path = test_support::headsq_scene(
        dir.path(),
        "",
        "bone",
        &format!(
            "method = \"combined\"\nwidth = 64\nheight = 48\n[[lines]]\npath = \"{}\"\ncolor = \"#ff0000\"\nwidth = 2.0\n[[tubes]]\npath = \"{}\"\nradius = 1.5\ncolor = \"#0000ff\"\ntransform = [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 30.0, 0.0, 0.0, 0.0, 1.0]\n",
            tck.display(),
            tck.display()
        ),
    );
    // The lowered bindings below halve the volume too.
    let s = scene::spec::load(&path, &["volume.downsample=true".into()]).unwrap();
    let m = scene::compile::model(&s).unwrap();
    let gpu: &'static engine::gpu::Gpu = Box::leak(Box::new(engine::gpu::Gpu::new().unwrap()));
    // Every other segment and every other triangle.
    let mut share = m.lines.clone();
    share[0].segments = share[0].segments.iter().step_by(2).copied().collect();
    let tris: Vec<u32> = m.meshes[0]
        .indices
        .chunks(3)
        .step_by(2)
        .flatten()
        .copied()
        .collect();
    let mut own = scene::compile::model(&s).unwrap();
    own.lines = share.clone();
    own.meshes[0].indices = tris.clone();
    // The set in one part, and cut into eight (storage bindings of 4 KiB: 341 points a part).
    for (limit, parts) in [(None, 1), (Some(4096), 8)] {
        gpu.limit_bindings(limit);
        let up = scene::compile::upload(gpu, &m).unwrap();
        assert_eq!(up.scene.line_parts(), parts);
        let own_up = scene::compile::upload(gpu, &own).unwrap();
        let shared_up = up
            .with_shares(std::slice::from_ref(&tris), &[share[0].segments.clone()])
            .unwrap();
        let a = frame(&shared_up, &own, &s, Level::Full);
        let b = frame(&own_up, &own, &s, Level::Full);
        gpu.limit_bindings(None);
        assert_eq!(
            a.rgba, b.rgba,
            "{parts} parts: the shared volume and points draw as their own copies"
        );
    }
    let up = scene::compile::upload(gpu, &m).unwrap();
    let a = frame(
        &up.with_shares(std::slice::from_ref(&tris), &[share[0].segments.clone()])
            .unwrap(),
        &own,
        &s,
        Level::Full,
    );
    // A share list for a set the upload does not have, or none for one it has: an error.
    assert!(up.with_shares(&[], &[]).is_err());
    // And the share is not the whole: the full lines draw another image.
    let full = frame(&up, &m, &s, Level::Full);
    assert!(
        changed(&full.rgba, &a.rgba) > 0,
        "half the segments look the same"
    );
    assert!(
        a.rgba.chunks(4).any(|p| p[0] > 150 && p[1] < 80),
        "red lines are drawn"
    );
    assert!(
        a.rgba.chunks(4).any(|p| p[2] > 150 && p[0] < 80),
        "blue tubes are drawn"
    );
}

/// An isosurface's octant fields are swept for the scene's cut: a clipping plane moved, the
/// drafts keep the octants of the cut before (no new model while it is dragged), the image at
/// rest has its own cut's, those `umbra render` sweeps for it.
#[test]
fn a_moved_clipping_plane_resweeps_the_isosurface_at_rest() {
    let dir = tempfile::tempdir().unwrap();
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .unwrap();
    let scene_at = |offset: f64| {
        let text = format!(
            "[volume]\npath = \"{}\"\n[volume.iso]\nvalue = 1000.0\n\
             [[clip]]\nnormal = [1.0, 0.0, 0.0]\noffset = {offset}\n\
             [render]\nwidth = 32\nheight = 24\nfxaa = false\n",
            root.join("datasets/vtk/headsq_64x64x93.nhdr").display()
        );
        scene::spec::parse(&text, "iso.toml", dir.path(), &[]).unwrap()
    };
    let (a, b) = (scene_at(100.0), scene_at(120.0));
    let mut session =
        umbra_viewer::worker::Session::new(scene::compile::model(&a).unwrap(), &a).unwrap();
    let req = |scene: &scene::spec::Scene, level: Level| Request {
        id: 0,
        scene: scene.clone(),
        level,
        save: None,
        pass_timings: false,
    };
    let octants = |m: &scene::compile::Model| m.iso.as_ref().unwrap().octants.clone();
    let (cut_a, cut_b) = (
        octants(&scene::compile::model(&a).unwrap()),
        octants(&scene::compile::model(&b).unwrap()),
    );
    assert_ne!(
        cut_a, cut_b,
        "the two cuts open different voxels to the sky"
    );
    assert!(session
        .frame(&req(&a, Level::Full))
        .unwrap()
        .rebuilt
        .is_none());
    let draft = session.frame(&req(&b, Level::Draft)).unwrap();
    assert!(
        draft.rebuilt.is_none(),
        "a draft keeps the model of the cut before"
    );
    assert!(octants(session.model()) == cut_a);
    let full = session.frame(&req(&b, Level::Full)).unwrap();
    assert!(
        full.rebuilt.is_some(),
        "the image at rest is swept for its cut"
    );
    assert!(octants(session.model()) == cut_b);
}

#[test]
fn slices_moved_hidden_or_restyled_are_replanned_without_a_new_model() {
    let dir = tempfile::tempdir().unwrap();
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .unwrap();
    // Two slices of headsq (not drawn as a volume); `extra` adds keys to the sagittal one.
    let scene_with = |axial: &str, sagittal: &str| {
        let text = format!(
            "[camera]\nazimuth = 30.0\nelevation = 35.0\n\
             [volume]\npath = \"{}\"\nrender = false\n\
             [[slices]]\naxis = \"axial\"\n{axial}\n\
             [[slices]]\naxis = \"sagittal\"\n{sagittal}\n\
             [render]\nmethod = \"ea\"\nwidth = 64\nheight = 48\nfxaa = false\n",
            root.join("datasets/vtk/headsq_64x64x93.nhdr").display()
        );
        scene::spec::parse(&text, "slices.toml", dir.path(), &[]).unwrap()
    };
    let a = scene_with("", "");
    let m = scene::compile::model(&a).unwrap();
    let grid = umbra_viewer::objects::SliceGrid::of(&m).unwrap();
    let (z0, [zlo, zhi]) = grid.position(&a.slices[0]);
    assert!(zlo < z0 && z0 < zhi, "{zlo} {z0} {zhi}");
    let mut session = umbra_viewer::worker::Session::new(m, &a).unwrap();
    let req = |scene: &scene::spec::Scene| Request {
        id: 0,
        scene: scene.clone(),
        level: Level::Full,
        save: None,
        pass_timings: false,
    };
    // What a fresh model and upload of the scene draw.
    let gpu = session.gpu();
    let fresh = |s: &scene::spec::Scene| {
        let m = scene::compile::model(s).unwrap();
        let up = scene::compile::upload(gpu, &m).unwrap();
        frame(&up, &m, s, Level::Full).rgba
    };
    let first = session.frame(&req(&a)).unwrap();
    let worst = |x: &[u8], y: &[u8]| x.iter().zip(y).map(|(p, q)| p.abs_diff(*q)).max().unwrap();
    let moved = scene_with(&format!("position = {}", z0 + 0.3 * (zhi - z0)), "");
    let lit = scene_with("lit = true\nopacity = 0.5", "");
    let mut one = a.clone();
    one.slices.remove(1);
    for (what, s) in [
        ("moved", &moved),
        ("lit, translucent", &lit),
        ("one hidden", &one),
    ] {
        let img = session.frame(&req(s)).unwrap();
        assert!(img.rebuilt.is_none(), "{what}: the model is kept");
        assert_eq!(
            session.model().planes.as_ref().unwrap().planes.len(),
            s.slices.len()
        );
        let want = fresh(s);
        assert!(
            worst(&img.rgba, &want) <= 1,
            "{what}: differs from a fresh upload by {}",
            worst(&img.rgba, &want)
        );
        assert!(
            changed(&img.rgba, &first.rgba) > 50,
            "{what}: the image changed ({} values)",
            changed(&img.rgba, &first.rgba)
        );
    }
    // A slice off the grid is refused, naming the key; the session draws on.
    let off = scene_with(&format!("position = {}", zhi + 10.0), "");
    let Err(err) = session.frame(&req(&off)) else {
        panic!("a slice off the grid was drawn");
    };
    assert!(err.contains("slices[0].position"), "{err}");
    let back = session.frame(&req(&a)).unwrap();
    assert!(worst(&back.rgba, &first.rgba) <= 1);
    // A slab crops the geometry: moving a slice that has one makes the model anew for the
    // image at rest; the drafts of the drag keep the old crop, the slice itself moved.
    let slab = scene_with("slab = 20.0", "");
    assert!(session.frame(&req(&slab)).unwrap().rebuilt.is_some());
    let slab_moved = scene_with(&format!("slab = 20.0\nposition = {}", z0 + 5.0), "");
    let draft = session
        .frame(&Request {
            level: Level::Draft,
            ..req(&slab_moved)
        })
        .unwrap();
    assert!(draft.rebuilt.is_none(), "a draft keeps the model");
    let z = |m: &scene::compile::Model| m.planes.as_ref().unwrap().planes[0].polygon.origin;
    assert!(
        (z(session.model())[2] - (z0 + 5.0)).abs() < 1e-6,
        "the slice moved in the draft: {:?}",
        z(session.model())
    );
    assert!(session.frame(&req(&slab_moved)).unwrap().rebuilt.is_some());
}

/// The viewer's image carries the notes `umbra render` prints: the model's (a slab that keeps
/// none of a tractogram's points), not only the frame's.
#[test]
fn a_frame_carries_the_models_notes() {
    let dir = tempfile::tempdir().unwrap();
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .unwrap();
    let mut st = tubes::Streamlines::new();
    st.push(&[
        glam::Vec3::new(0.0, 0.0, 500.0),
        glam::Vec3::new(10.0, 0.0, 500.0),
    ]);
    let tck = dir.path().join("far.tck");
    tubes::save(&tck, &st).unwrap();
    let text = format!(
        "[volume]\npath = \"{}\"\nrender = false\n\
         [[slices]]\naxis = \"axial\"\nslab = 2.0\n\
         [[lines]]\npath = \"{}\"\n\
         [[tubes]]\npath = \"{}\"\n\
         [render]\nmethod = \"ea\"\nwidth = 32\nheight = 24\n",
        root.join("datasets/vtk/headsq_64x64x93.nhdr").display(),
        tck.display(),
        tck.display()
    );
    let s = scene::spec::parse(&text, "far.toml", dir.path(), &[]).unwrap();
    let m = scene::compile::model(&s).unwrap();
    let mut session = umbra_viewer::worker::Session::new(m, &s).unwrap();
    for level in [Level::Full, Level::Draft] {
        let img = session
            .frame(&Request {
                id: 1,
                scene: s.clone(),
                level,
                save: None,
                pass_timings: false,
            })
            .unwrap();
        for what in ["lines", "tubes"] {
            assert!(
                img.notes.iter().any(|n| {
                    n.starts_with(&format!("{what}[0]: the slices' slabs keep 0 of 2 points"))
                }),
                "{level:?}: {:?}",
                img.notes
            );
        }
        // The slab says why nothing is drawn; no second note blames the data.
        assert!(
            !img.notes.iter().any(|n| n.contains("no tube to draw")),
            "{:?}",
            img.notes
        );
    }
}

/// A new transfer function: drafts only upload it, the full image models the scene anew, so
/// that the slices a narrow feature asks for and the notes are the ones `umbra render` takes
/// for that scene (they stayed the first function's: the viewer under-sampled the scene it
/// saved).
#[test]
fn a_new_transfer_function_at_rest_is_modelled_as_umbra_render_models_it() {
    let dir = tempfile::tempdir().unwrap();
    let path = headsq_scene(dir.path());
    let s = scene::spec::load(&path, &[]).unwrap();
    let m = scene::compile::model(&s).unwrap();
    let (lo, hi) = (m.volume.as_ref().unwrap().1.stats().min, {
        m.volume.as_ref().unwrap().1.stats().max
    });
    let mut session = umbra_viewer::worker::Session::new(m, &s).unwrap();
    // A spike a hundredth of the range wide: a feature narrower than the data's change per
    // voxel, which shortens the default slice distance.
    let mut state = s.clone();
    let mid = 0.5 * (lo + hi);
    let w = 0.01 * (hi - lo);
    let point = |value: f64, extinction: f64| scene::spec::TfPoint {
        value,
        color: scene::spec::Color::Rgb([1.0, 0.9, 0.8]),
        extinction,
        gradient: None,
    };
    let tf = &mut state.volume.as_mut().unwrap().transfer;
    tf.preset = String::new();
    tf.points = vec![
        point(lo, 0.0),
        point(mid - w, 0.0),
        point(mid, 2.0),
        point(mid + w, 0.0),
        point(hi, 0.0),
    ];
    let want = scene::compile::model(&state).unwrap();
    assert!(
        want.spacing < session.model().spacing,
        "the spike asks for shorter slices"
    );
    let mut frame = |level: Level| {
        session
            .frame(&Request {
                id: 0,
                scene: state.clone(),
                level,
                save: None,
                pass_timings: false,
            })
            .unwrap()
    };
    let draft = frame(Level::Draft);
    assert!(draft.rebuilt.is_none(), "a draft only uploads the function");
    let full = frame(Level::Full);
    assert!(
        full.rebuilt.is_some(),
        "the full image models the scene anew"
    );
    assert_eq!(session.model().spacing, want.spacing);
    for n in &want.notes {
        assert!(full.notes.contains(n), "{n:?} not in {:?}", full.notes);
    }
    // A function that asks for the same slices (a colour changed) keeps the model: a new one
    // reads every file again.
    state.volume.as_mut().unwrap().transfer.points[2].color =
        scene::spec::Color::Rgb([0.2, 0.9, 0.3]);
    let full = session
        .frame(&Request {
            id: 0,
            scene: state.clone(),
            level: Level::Full,
            save: None,
            pass_timings: false,
        })
        .unwrap();
    assert!(full.rebuilt.is_none(), "the same slices need no new model");
    assert_eq!(session.model().spacing, want.spacing);
}
