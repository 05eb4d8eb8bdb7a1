//! The window: the latest image of the scene in the centre, the controls beside it, mouse
//! and keys changing the scene state, which goes to the worker as a draft while the user
//! interacts and as the full scene once the view rests.

use crate::controls::{Orbit, StandardView};
use crate::worker::{Image, Level, Request, Worker};
use eframe::egui;
use glam::DVec3;
use scene::spec::Scene;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// How long the view must rest before the full image is asked for.
pub const REST: Duration = Duration::from_millis(250);

pub struct App {
    /// The scene as the user has made it (camera, method, size follow the window).
    pub scene: Scene,
    pub orbit: Orbit,
    initial: Orbit,
    bounds: [DVec3; 2],
    worker: Worker,
    texture: Option<egui::TextureHandle>,
    shown: Option<ImageInfo>,
    error: Option<String>,
    next_id: u64,
    /// The newest request and whether its full image is still to be asked for.
    asked: Option<(u64, Level)>,
    full_pending: bool,
    last_input: Instant,
    quit: Arc<AtomicBool>,
    /// Where the save section writes: a path without its extension.
    prefix: String,
    /// The transfer-function editor (scenes with a volume).
    editor: Option<crate::transfer::Editor>,
    /// The scenes of the requests not yet drawn, by id (a drawn image knows its camera).
    shown_scenes: std::collections::BTreeMap<u64, Scene>,
    /// Objects left out of the drawn scene, and the "open" field.
    hidden: crate::objects::Hidden,
    /// The grid the scene's slices cut (from the model; none without slices).
    slice_grid: Option<crate::objects::SliceGrid>,
    /// Whether the scene is in RAS+ (the triad's labels: R/A/S, else +X/+Y/+Z).
    ras: bool,
    open_path: String,
    /// The file dialog ("browse").
    browser: crate::objects::Browser,
    /// Camera keys recorded for a camera path.
    keys: Vec<Orbit>,
    /// The last save's or open's outcome.
    message: Option<String>,
    /// Files opened whose first image is still to come: the objects before them, to put back
    /// if the worker cannot read them (the view would otherwise stay on the last image), and
    /// the first request that holds them.
    pending_open: Option<PendingOpen>,
    /// Ask again at the next frame (the objects were put back).
    reask: bool,
    /// Called once with the first image shown (the command line reports it).
    on_first_image: Option<crate::OnFirstImage>,
    /// Told of every window frame and shown image.
    on_event: Option<crate::OnEvent>,
    /// Whether full images time each pass (drawing them twice on lavapipe).
    time_passes: bool,
    /// The shortest time between window frames that show no new image (see [`App::paced`]),
    /// and when the last frame began.
    pace: Option<Duration>,
    last_frame: Instant,
    /// The clipping plane (an index of `scene.clip`) that ctrl + drag over the view moves,
    /// outlined over the view.
    pub clip_drag: Option<usize>,
}

/// Files opened and not yet drawn (see [`App::open_file`]).
struct PendingOpen {
    paths: Vec<std::path::PathBuf>,
    before: crate::objects::Objects,
    /// The first request made with them.
    id: Option<u64>,
    /// Slices' positions (index, position) taken out for a second try after an opened volume
    /// could not be drawn: a position the old grid held may miss the new one. Each goes back
    /// where the new grid holds it once drawn; the others stay at its centre.
    set_aside: Option<Vec<(usize, f64)>>,
    /// The last request sent before that second try: its failures and those of the requests
    /// before it are the one being tried again.
    retried_after: Option<u64>,
}

/// What the shown image was.
struct ImageInfo {
    level: Level,
    size: [usize; 2],
    depth: Vec<f32>,
    /// The scene the image shows (for picking).
    scene: Scene,
    total_ms: f64,
    passes: Vec<(String, f64)>,
    light: Option<engine::renderer::LightGrid>,
    notes: Vec<String>,
    device: String,
}

impl App {
    pub fn new(
        scene: Scene,
        bounds: [DVec3; 2],
        worker: Worker,
        quit: Arc<AtomicBool>,
        on_first_image: Option<crate::OnFirstImage>,
    ) -> App {
        let orbit = Orbit::of(&scene.camera, bounds);
        let clip_drag = (!scene.clip.is_empty()).then_some(0);
        App {
            clip_drag,
            scene,
            orbit,
            initial: orbit,
            bounds,
            worker,
            texture: None,
            shown: None,
            error: None,
            next_id: 0,
            asked: None,
            full_pending: true,
            last_input: Instant::now() - REST,
            quit,
            prefix: "umbra_view".into(),
            editor: None,
            hidden: Default::default(),
            slice_grid: None,
            ras: true,
            shown_scenes: Default::default(),
            open_path: String::new(),
            browser: Default::default(),
            keys: vec![],
            message: None,
            pending_open: None,
            reask: false,
            on_first_image,
            pace: None,
            last_frame: Instant::now(),
            on_event: None,
            time_passes: false,
        }
    }

    /// With `f` told of every window frame and every image shown.
    pub fn with_events(mut self, f: crate::OnEvent) -> App {
        self.on_event = Some(f);
        self
    }

    /// Window frames that show no new image at most every `interval`: a frame waits (up to
    /// the rest of `interval` since the last one) for the worker's next image. For windows
    /// drawn by a CPU adapter, where a window frame takes as much of the machine as a draft
    /// (egui's layers on llvmpipe: about 100 ns a pixel, 55 ms of CPU at 900 x 600): eframe
    /// draws a frame for every input event, and unpaced frames took the cores the drafts
    /// need (docs/benchmarks.md, "Interactive viewer").
    pub fn paced(mut self, interval: Duration) -> App {
        self.pace = Some(interval);
        self
    }

    /// With the transfer-function editor over the volume's data.
    pub fn with_editor(mut self, editor: crate::transfer::Editor) -> App {
        self.editor = Some(editor);
        self
    }

    /// Whether the scene is in RAS+ (`scene::compile::Model::is_ras` of its model).
    pub fn with_ras(mut self, ras: bool) -> App {
        self.ras = ras;
        self
    }

    /// The grid the scene's slices cut (the objects panel's position fields span it).
    pub fn with_slice_grid(mut self, grid: Option<crate::objects::SliceGrid>) -> App {
        self.slice_grid = grid;
        self
    }

    /// The level of the image on screen (none yet: `None`).
    pub fn shown_level(&self) -> Option<Level> {
        self.shown.as_ref().map(|i| i.level)
    }

    /// The objects panel's "open" field (the file dialog starts in its folder).
    pub fn set_open_field(&mut self, path: &str) {
        self.open_path = path.into();
    }

    /// Whether the file dialog is open.
    pub fn browsing(&self) -> bool {
        self.browser.is_open()
    }

    /// The scene of the image on screen (none yet: `None`).
    pub fn shown_scene(&self) -> Option<&Scene> {
        self.shown.as_ref().map(|i| &i.scene)
    }

    /// The last frame's error, as the view shows it.
    pub fn error(&self) -> Option<&str> {
        self.error.as_deref()
    }

    /// The last save's outcome, as the panel shows it.
    pub fn message(&self) -> Option<&str> {
        self.message.as_deref()
    }

    /// Where the save section writes (a path without extension).
    pub fn set_prefix(&mut self, prefix: &str) {
        self.prefix = prefix.to_string();
    }

    /// The scene as shown: the user's scene with the orbit as its camera and the view's size.
    pub fn state(&self) -> Scene {
        let mut s = self.hidden.apply(&self.scene);
        self.orbit.apply(&mut s.camera);
        s
    }

    /// Sends the current state at `level` (with a screenshot to write).
    fn ask_saving(&mut self, level: Level, save: Option<(std::path::PathBuf, bool)>) {
        self.next_id += 1;
        let scene = self.state();
        self.shown_scenes.insert(self.next_id, scene.clone());
        if let Some(p) = &mut self.pending_open {
            p.id.get_or_insert(self.next_id);
        }
        let _ = self.worker.requests.send(Request {
            id: self.next_id,
            scene,
            level,
            save,
            pass_timings: self.time_passes,
        });
        self.asked = Some((self.next_id, level));
    }

    fn ask(&mut self, level: Level) {
        self.ask_saving(level, None);
    }

    /// The files of the "save" section: `<prefix>.png`, `.exr`, `.toml`, `_path.toml`.
    fn file(&self, suffix: &str) -> std::path::PathBuf {
        std::path::PathBuf::from(format!("{}{suffix}", self.prefix))
    }

    /// Writes the shown scene as TOML that `umbra render` reproduces.
    fn save_scene(&mut self) {
        let path = self.file(".toml");
        // Saving over the scene file the viewer opened is the user's choice (an editor's
        // "save"); the data files it read stay protected (`volume::check_not_read`).
        volume::forget_input(&path);
        self.message = Some(
            scene::spec::to_toml(&self.state())
                .and_then(|t| crate::write_atomic(&path, t.as_bytes()))
                .map(|()| format!("wrote {}", path.display()))
                .unwrap_or_else(|e| format!("the scene was not saved: {e}")),
        );
    }

    /// Writes the camera keys so far as a camera path (`umbra render --camera-path`).
    fn save_path(&mut self) {
        let path = self.file("_path.toml");
        self.message = Some(
            crate::controls::camera_path(&self.keys, self.bounds, self.orbit.target)
                .and_then(|t| crate::write_atomic(&path, t.as_bytes()))
                .map(|()| format!("wrote {} ({} keys)", path.display(), self.keys.len()))
                .unwrap_or_else(|e| format!("the camera path was not saved: {e}")),
        );
    }

    /// Adds the file at `path` to the scene (as `objects::open`); whether it did. Until the
    /// first image with it comes, the objects before it are kept: a file the worker cannot
    /// read is taken out again, with the reader's error.
    fn open_file(&mut self, path: &std::path::Path) -> bool {
        let before = crate::objects::Objects::of(&self.scene, &self.hidden);
        match crate::objects::open(&mut self.scene, path) {
            Ok(m) => {
                self.message = Some(m);
                match &mut self.pending_open {
                    // Opened while another is still to be drawn: both go back if either fails.
                    Some(p) => p.paths.push(path.into()),
                    None => {
                        self.pending_open = Some(PendingOpen {
                            paths: vec![path.into()],
                            before,
                            id: None,
                            set_aside: None,
                            retried_after: None,
                        })
                    }
                }
                true
            }
            Err(e) => {
                self.message = Some(e);
                false
            }
        }
    }

    /// Takes the slices' own positions out of the scene for a second try of `p` (a volume
    /// opened: the positions may miss its grid), keeping them in `p`; whether it did (not
    /// twice, not without a volume among the files or a slice with a position).
    fn slices_set_aside(&mut self, p: &mut PendingOpen) -> bool {
        let volume = p.paths.iter().any(|f| {
            matches!(
                crate::objects::classify(f),
                Ok(crate::objects::Kind::Volume)
            )
        });
        if p.set_aside.is_some() || !volume {
            return false;
        }
        let aside: Vec<(usize, f64)> = (self.scene.slices.iter_mut().enumerate())
            .filter_map(|(i, sl)| sl.position.take().map(|x| (i, x)))
            .collect();
        if aside.is_empty() {
            return false;
        }
        p.set_aside = Some(aside);
        p.id = None;
        p.retried_after = Some(self.next_id);
        true
    }

    /// Puts slices' positions `aside` back where the grid now drawn (of the volume among
    /// `paths`) holds them; those it does not stay at its centre, and the message says which.
    fn put_back(&mut self, paths: &[std::path::PathBuf], aside: &[(usize, f64)]) {
        let names: Vec<String> = paths.iter().map(|p| p.display().to_string()).collect();
        let Some(grid) = self.slice_grid.clone() else {
            // No slice drawn (all hidden): nothing to check the positions against; they go
            // back as they were (a slice shown later that misses the grid says so).
            for &(i, x) in aside {
                if let Some(sl) = self
                    .scene
                    .slices
                    .get_mut(i)
                    .filter(|s| s.position.is_none())
                {
                    sl.position = Some(x);
                }
            }
            self.message = Some(format!(
                "opened {}; the slices' positions are kept as they were",
                names.join(", ")
            ));
            return;
        };
        let unit = if grid.ras { "mm" } else { "units" };
        let mut moved = vec![];
        for &(i, x) in aside {
            let Some(sl) = self.scene.slices.get_mut(i) else {
                continue;
            };
            // Moved by the user since: theirs.
            if sl.position.is_some() {
                continue;
            }
            let (_, [lo, hi]) = grid.position(sl);
            if (lo..=hi).contains(&x) {
                sl.position = Some(x);
                self.reask = true;
            } else {
                moved.push(format!(
                    "slices[{i}] at {x} {unit} misses it (it spans {lo:.3} to {hi:.3} along the slice's normal)"
                ));
            }
        }
        self.message = Some(match moved.is_empty() {
            true => format!("opened {}", names.join(", ")),
            false => format!(
                "opened {}; moved to the new volume's centre: {}",
                names.join(", "),
                moved.join("; ")
            ),
        });
    }

    /// The state changed by the user: a draft now, the full image when the view rests.
    fn changed(&mut self) {
        self.last_input = Instant::now();
        self.full_pending = true;
        self.ask(Level::Draft);
    }

    /// Takes the worker's finished images, waiting up to `wait` for one when none is there;
    /// whether one came.
    fn receive(&mut self, ctx: &egui::Context, wait: Duration) -> bool {
        let mut next = match wait.is_zero() {
            true => self.worker.images.try_recv().ok(),
            false => self.worker.images.recv_timeout(wait).ok(),
        };
        let got = next.is_some();
        while let Some((id, r)) = next.take() {
            next = self.worker.images.try_recv().ok();
            match r {
                Err(e) => {
                    // That request is done with: frames stop waiting for it.
                    self.shown_scenes.retain(|k, _| *k > id);
                    // Sent before an opened volume was tried again, with the slices' positions
                    // set aside since: the failure being tried again, not a new one.
                    if self
                        .pending_open
                        .as_ref()
                        .and_then(|p| p.retried_after)
                        .is_some_and(|r| id <= r)
                    {
                        continue;
                    }
                    let mut opened = self
                        .pending_open
                        .take_if(|p| p.id.is_some_and(|first| id >= first));
                    // A volume opened in place of another, with slices at positions of their
                    // own: tried again with them at the new volume's centre.
                    let retried = opened.as_mut().is_some_and(|p| self.slices_set_aside(p));
                    if retried {
                        self.message =
                            Some(format!("{e}; trying the slices at the new volume's centre"));
                        self.pending_open = opened.take();
                        self.reask = true;
                    }
                    match opened {
                        None if retried => {}
                        // A file just opened could not be drawn: the objects as they were,
                        // drawn again, and the reason.
                        Some(p) => {
                            p.before.restore(&mut self.scene, &mut self.hidden);
                            let names: Vec<String> =
                                p.paths.iter().map(|p| p.display().to_string()).collect();
                            // In the message, which stays when the view is drawn again.
                            self.message = Some(format!(
                                "{} not opened (the scene is as before): {e}",
                                names.join(", ")
                            ));
                            self.reask = true;
                        }
                        None => self.error = Some(e),
                    }
                }
                Ok(img) => {
                    let opened = self
                        .pending_open
                        .take_if(|p| p.id.is_some_and(|first| img.id >= first));
                    self.show(ctx, img);
                    if let Some(p) = opened {
                        if let Some(aside) = &p.set_aside {
                            self.put_back(&p.paths, aside);
                        }
                    }
                }
            }
        }
        got
    }

    fn show(&mut self, ctx: &egui::Context, img: Image) {
        let color = egui::ColorImage::from_rgba_unmultiplied(img.size, &img.rgba);
        match &mut self.texture {
            Some(t) => t.set(color, egui::TextureOptions::LINEAR),
            None => {
                self.texture =
                    Some(ctx.load_texture("umbra frame", color, egui::TextureOptions::LINEAR))
            }
        }
        self.error = None;
        if let Some(r) = &img.rebuilt {
            if r.bounds != self.bounds && self.scene.camera.target.is_none() {
                // New data (a volume replaced, a tractogram added) with the scene's camera on
                // its centre: the view and `Home` follow the new centre, unless the user moved
                // the target (a pan, a picked pivot).
                let centre = |b: [DVec3; 2]| (b[0] + b[1]) * 0.5;
                if (self.orbit.target - centre(self.bounds)).length()
                    <= 1e-9 * (1.0 + centre(self.bounds).length())
                {
                    self.orbit.target = centre(r.bounds);
                }
                self.initial = Orbit::of(&self.scene.camera, r.bounds);
            }
            self.bounds = r.bounds;
            self.slice_grid = r.slice_grid.clone();
            self.ras = r.ras;
            match &mut self.editor {
                // The same volume's data (other objects changed): the editor keeps its tab
                // and scale, with the histograms of the rebuilt model.
                Some(e) if r.volume && e.range == r.range => {
                    e.histogram = r.histogram.clone();
                    e.robust = r.robust;
                    e.set_2d(r.histogram2d.clone());
                }
                _ => {
                    self.editor = r.volume.then(|| {
                        crate::transfer::Editor::new(r.range, r.histogram.clone())
                            .with_robust(r.robust)
                            .with_2d(r.histogram2d.clone())
                    })
                }
            }
        }
        match &img.saved {
            Some(Ok(p)) => self.message = Some(format!("wrote {}", p.display())),
            Some(Err(e)) => self.message = Some(format!("the screenshot was not written: {e}")),
            None => {}
        }
        if let Some(f) = self.on_first_image.take() {
            f(&img.device);
        }
        // (A screenshot's render is shown too, but it is no frame of the interaction: not
        // logged, or the frame log's counts of the view's images grew by one a screenshot.)
        if let (Some(f), None) = (&mut self.on_event, &img.saved) {
            f(&crate::ViewEvent::Image {
                level: img.level,
                size: img.size,
                total_ms: img.total_ms,
            });
        }
        let scene = self
            .shown_scenes
            .remove(&img.id)
            .unwrap_or_else(|| self.state());
        self.shown_scenes.retain(|id, _| *id > img.id);
        self.shown = Some(ImageInfo {
            level: img.level,
            size: img.size,
            depth: img.depth,
            scene,
            total_ms: img.total_ms,
            passes: img.passes,
            light: img.light,
            notes: img.notes,
            device: img.device,
        });
    }

    /// Mouse over the view and keys: orbit (left drag, arrows), the chosen clipping plane
    /// moved (ctrl + left drag) or tilted (ctrl + shift + left drag), pan (right or middle drag, shift+arrows), zoom (wheel, +/-),
    /// standard views (L R A P S I), reset (Home or 0), projection (O). Returns whether
    /// anything changed.
    fn input(&mut self, ui: &egui::Ui, response: &egui::Response) -> bool {
        let before = self.orbit;
        let mut clip_moved = false;
        let d = response.drag_delta();
        let ctrl = ui.input(|i| i.modifiers.ctrl || i.modifiers.command);
        let clip = self.clip_drag.filter(|&c| c < self.scene.clip.len());
        if response.dragged_by(egui::PointerButton::Primary) {
            let shift = ui.input(|i| i.modifiers.shift);
            match clip {
                Some(c) if ctrl && shift => {
                    let p = &mut self.scene.clip[c];
                    let (n, offset) = self.orbit.clip_tilt(
                        DVec3::from(p.normal),
                        p.offset,
                        d.x as f64,
                        d.y as f64,
                        self.orbit.target,
                    );
                    (p.normal, p.offset) = (n.to_array(), offset);
                    clip_moved = d != egui::Vec2::ZERO;
                }
                Some(c) if ctrl => {
                    let per_point = self.world_per_point(response.rect.height() as f64);
                    let p = &mut self.scene.clip[c];
                    let n = DVec3::from(p.normal);
                    p.offset += self.orbit.clip_drag(n, d.x as f64, d.y as f64, per_point);
                    clip_moved = d != egui::Vec2::ZERO;
                }
                _ => self.orbit = self.orbit.drag(d.x as f64, d.y as f64),
            }
        } else if response.dragged_by(egui::PointerButton::Secondary)
            || response.dragged_by(egui::PointerButton::Middle)
        {
            let per_px = self.world_per_point(response.rect.height() as f64);
            self.orbit = self.orbit.pan(d.x as f64 * per_px, d.y as f64 * per_px);
        }
        if response.double_clicked() {
            if let Some(p) = response.interact_pointer_pos() {
                self.pick(response.rect, p);
            }
        }
        if response.hovered() {
            // One line of scrolling (a wheel's notch) is one zoom step, as a key press is; egui
            // hands lines over as `line_scroll_speed` points, spread over a few frames.
            let scroll = ui.input(|i| i.smooth_scroll_delta.y) as f64;
            if scroll != 0.0 {
                let line = ui.ctx().options(|o| o.input_options.line_scroll_speed) as f64;
                self.orbit = self.orbit.zoom(scroll / line.max(1.0));
            }
        }
        let keys: Vec<(egui::Key, egui::Modifiers)> = ui.input(|i| {
            i.events
                .iter()
                .filter_map(|e| match e {
                    egui::Event::Key {
                        key,
                        pressed: true,
                        modifiers,
                        ..
                    } => Some((*key, *modifiers)),
                    _ => None,
                })
                .collect()
        });
        let focus_free = !ui.ctx().egui_wants_keyboard_input();
        for (key, m) in keys.into_iter().filter(|_| focus_free) {
            use egui::Key;
            let step = crate::controls::KEY_STEP;
            let pan = self.world_per_point(response.rect.height() as f64) * 20.0;
            self.orbit = match key {
                Key::ArrowLeft if m.shift => self.orbit.pan(-pan, 0.0),
                Key::ArrowRight if m.shift => self.orbit.pan(pan, 0.0),
                Key::ArrowUp if m.shift => self.orbit.pan(0.0, -pan),
                Key::ArrowDown if m.shift => self.orbit.pan(0.0, pan),
                Key::ArrowLeft => self
                    .orbit
                    .drag(-step / crate::controls::DEGREES_PER_PIXEL, 0.0),
                Key::ArrowRight => self
                    .orbit
                    .drag(step / crate::controls::DEGREES_PER_PIXEL, 0.0),
                Key::ArrowUp => self
                    .orbit
                    .drag(0.0, -step / crate::controls::DEGREES_PER_PIXEL),
                Key::ArrowDown => self
                    .orbit
                    .drag(0.0, step / crate::controls::DEGREES_PER_PIXEL),
                Key::Plus | Key::Equals => self.orbit.zoom(1.0),
                Key::Minus => self.orbit.zoom(-1.0),
                Key::L => self.orbit.standard(StandardView::Left),
                Key::R => self.orbit.standard(StandardView::Right),
                Key::A => self.orbit.standard(StandardView::Anterior),
                Key::P => self.orbit.standard(StandardView::Posterior),
                Key::S => self.orbit.standard(StandardView::Superior),
                Key::I => self.orbit.standard(StandardView::Inferior),
                Key::Home | Key::Num0 => self.initial,
                Key::O => crate::controls::Orbit {
                    orthographic: !self.orbit.orthographic,
                    ..self.orbit
                },
                _ => self.orbit,
            };
        }
        self.orbit != before || clip_moved
    }

    /// The outline of the clipping plane that ctrl + drag moves, where it cuts the scene's
    /// bounds, over the view (`rect`) as the shown camera projects it.
    fn clip_outline(&self, painter: &egui::Painter, rect: egui::Rect) {
        let Some(c) = self.clip_drag.and_then(|c| self.scene.clip.get(c)) else {
            return;
        };
        let pts = crate::controls::plane_outline(DVec3::from(c.normal), c.offset, self.bounds);
        let Ok(cam) = scene::compile::camera(&self.state(), self.bounds) else {
            return;
        };
        let (w, h) = (rect.width() as usize, rect.height() as usize);
        let screen: Option<Vec<egui::Pos2>> = pts
            .iter()
            .map(|p| {
                let (x, y, _) = cam.to_pixel(*p, w.max(1), h.max(1))?;
                Some(egui::pos2(rect.left() + x as f32, rect.top() + y as f32))
            })
            .collect();
        if let Some(screen) = screen.filter(|s| s.len() >= 3) {
            let stroke = egui::Stroke::new(1.5, egui::Color32::from_rgb(250, 200, 40));
            painter.add(egui::Shape::closed_line(screen, stroke));
        }
    }

    /// Double click: the orbit turns about the point the image shows under the pointer (its
    /// depth AOV), the eye staying put; nothing where the image shows only background.
    fn pick(&mut self, rect: egui::Rect, p: egui::Pos2) {
        let Some(i) = &self.shown else { return };
        let [w, h] = i.size;
        let u = ((p.x - rect.left()) / rect.width()).clamp(0.0, 0.999_999) as f64;
        let v = ((p.y - rect.top()) / rect.height()).clamp(0.0, 0.999_999) as f64;
        let (px, py) = ((u * w as f64) as usize, (v * h as f64) as usize);
        let depth = i.depth.get(px + w * py).copied().unwrap_or(0.0) as f64;
        if depth <= 0.0 {
            self.message = Some("nothing to pivot about there".into());
            return;
        }
        let Ok(cam) = scene::compile::camera(&i.scene, self.bounds) else {
            return;
        };
        let (o, d) = cam.ray(px as f64 + 0.5, py as f64 + 0.5, w, h);
        let f = cam.forward();
        let t = (depth - (o - cam.eye).dot(f)) / d.dot(f).max(1e-12);
        let point = o + d * t;
        self.orbit = self.orbit.pivot(cam.eye, point, self.bounds);
        self.message = Some(format!(
            "pivot at ({:.1}, {:.1}, {:.1})",
            point.x, point.y, point.z
        ));
        self.changed();
    }

    /// The orientation triad in the view's lower left corner (the upper left where the scene
    /// draws a scale bar there, `annotate.scale_bar`): the world axes as the camera sees them,
    /// labelled R, A, S at their positive ends (L, P, I at the others) in RAS+, else +X, +Y,
    /// +Z (-X, -Y, -Z), as `umbra render`'s orientation labels.
    fn triad(&self, painter: &egui::Painter, rect: egui::Rect) {
        let f = self.orbit.forward();
        let right = f.cross(DVec3::Z).try_normalize().unwrap_or(DVec3::X);
        let up = right.cross(f);
        let y = match self.scene.annotate.scale_bar.is_some() {
            true => rect.top() + 40.0,
            false => rect.bottom() - 40.0,
        };
        let c = egui::pos2(rect.left() + 40.0, y);
        let len = 28.0;
        for (i, (axis, color)) in [
            (DVec3::X, egui::Color32::from_rgb(220, 70, 70)),
            (DVec3::Y, egui::Color32::from_rgb(70, 200, 70)),
            (DVec3::Z, egui::Color32::from_rgb(80, 120, 240)),
        ]
        .into_iter()
        .enumerate()
        {
            let pos = scene::annotate::axis_label(i, true, self.ras);
            let neg = scene::annotate::axis_label(i, false, self.ras);
            let s = egui::vec2(axis.dot(right) as f32, -axis.dot(up) as f32);
            painter.line_segment([c, c + s * len], egui::Stroke::new(2.0, color));
            let font = egui::FontId::proportional(12.0);
            painter.text(
                c + s * (len + 8.0),
                egui::Align2::CENTER_CENTER,
                pos,
                font.clone(),
                color,
            );
            painter.text(
                c - s * (len * 0.6 + 6.0),
                egui::Align2::CENTER_CENTER,
                neg,
                font,
                color.gamma_multiply(0.5),
            );
        }
    }

    /// World units per logical point at the target's depth (a perspective camera's view
    /// height there, or the orthographic view's height).
    fn world_per_point(&self, view_height_points: f64) -> f64 {
        let radius = (self.bounds[1] - self.bounds[0]).length() * 0.5;
        let depth = self.orbit.distance * radius;
        let h = match self.orbit.orthographic {
            true => self.orbit.ortho_height,
            false => 2.0 * depth * (self.scene.camera.fov_y.to_radians() * 0.5).tan(),
        };
        h / view_height_points.max(1.0)
    }

    fn panel(&mut self, ui: &mut egui::Ui) -> bool {
        let mut changed = false;
        ui.heading("umbra");
        let current = self.scene.render.method;
        egui::ComboBox::from_label("method")
            .selected_text(current.desc().name)
            .show_ui(ui, |ui| {
                // Every row of the method table (`engine::method::METHODS`).
                for d in engine::method::METHODS {
                    if ui
                        .selectable_label(current == d.method, d.name)
                        .on_hover_text(d.summary)
                        .clicked()
                    {
                        self.scene.render.method = d.method;
                        changed = true;
                    }
                }
            });
        let mut ortho = self.orbit.orthographic;
        if ui.checkbox(&mut ortho, "orthographic (O)").changed() {
            self.orbit.orthographic = ortho;
            changed = true;
        }
        ui.horizontal_wrapped(|ui| {
            for (label, v) in [
                ("L", StandardView::Left),
                ("R", StandardView::Right),
                ("A", StandardView::Anterior),
                ("P", StandardView::Posterior),
                ("S", StandardView::Superior),
                ("I", StandardView::Inferior),
            ] {
                if ui.button(label).clicked() {
                    self.orbit = self.orbit.standard(v);
                    changed = true;
                }
            }
            if ui.button("reset").clicked() {
                self.orbit = self.initial;
                changed = true;
            }
        });
        if let (Some(e), Some(v)) = (&mut self.editor, &mut self.scene.volume) {
            if v.iso.is_none() {
                egui::CollapsingHeader::new("transfer function")
                    .default_open(true)
                    .show(ui, |ui| changed |= e.ui(ui, &mut v.transfer));
            }
        }
        let mut browse = false;
        let mut to_open = None;
        let pivot = self.orbit.target.to_array();
        egui::CollapsingHeader::new("objects")
            .default_open(false)
            .show(ui, |ui| {
                changed |= crate::objects::panel(
                    ui,
                    &mut self.scene,
                    &mut self.hidden,
                    &mut self.open_path,
                    &mut to_open,
                    crate::objects::Place {
                        pivot,
                        grid: self.slice_grid.as_ref(),
                    },
                    &mut browse,
                )
            });
        if let Some(p) = to_open {
            changed |= self.open_file(&p);
        }
        if browse {
            self.browser
                .open(std::path::Path::new(self.open_path.trim()));
        }
        let centre = ((self.bounds[0] + self.bounds[1]) * 0.5).to_array();
        changed |= crate::settings::panel(ui, &mut self.scene, centre, &mut self.clip_drag);
        ui.separator();
        // The zoom as the saved scene holds it: the distance, or an orthographic view's height.
        let zoom = match self.orbit.orthographic {
            true => format!(
                "height {}",
                scene::annotate::format_number(self.orbit.ortho_height)
            ),
            false => format!("distance {:.2}", self.orbit.distance),
        };
        ui.label(format!(
            "azimuth {:.1}°, elevation {:.1}°, {zoom}",
            self.orbit.azimuth, self.orbit.elevation
        ));
        if let Some(i) = &self.shown {
            let level = match i.level {
                Level::Draft => "draft",
                Level::Full => "full",
            };
            ui.label(format!(
                "{level} image {} x {}: {:.0} ms",
                i.size[0], i.size[1], i.total_ms
            ));
            for (p, ms) in &i.passes {
                ui.label(format!("  {p} {ms:.1} ms"));
            }
            if let Some(l) = &i.light {
                ui.label(l.to_string());
            }
            if ui
                .checkbox(&mut self.time_passes, "time each pass")
                .on_hover_text(
                    "the full image's passes timed one by one: on adapters without timestamp \
                     queries (lavapipe) the renderer draws the image a second time",
                )
                .changed()
                && self.time_passes
            {
                self.full_pending = true;
            }
            ui.label(format!("on {}", i.device));
            for n in &i.notes {
                ui.add(egui::Label::new(egui::RichText::new(n).small()).wrap());
            }
        } else {
            ui.label("rendering the first image ...");
        }
        if let Some(e) = &self.error {
            ui.add(egui::Label::new(egui::RichText::new(e).color(egui::Color32::RED)).wrap());
        }
        ui.separator();
        ui.horizontal(|ui| {
            let label = ui.label("save as");
            ui.add(
                egui::TextEdit::singleline(&mut self.prefix).desired_width(ui.available_width()),
            )
            .labelled_by(label.id);
        });
        ui.horizontal_wrapped(|ui| {
            if ui.button("screenshot .png").clicked() {
                let p = self.file(".png");
                self.ask_saving(Level::Full, Some((p, false)));
            }
            if ui.button(".exr with AOVs").clicked() {
                let p = self.file(".exr");
                self.ask_saving(Level::Full, Some((p, true)));
            }
            if ui.button("scene .toml").clicked() {
                self.save_scene();
            }
        });
        ui.horizontal_wrapped(|ui| {
            if ui.button("add camera key").clicked() {
                self.keys.push(self.orbit);
            }
            if ui
                .add_enabled(self.keys.len() >= 2, egui::Button::new("save camera path"))
                .clicked()
            {
                self.save_path();
            }
            ui.label(format!("{} keys", self.keys.len()));
        });
        if let Some(m) = &self.message {
            ui.add(egui::Label::new(m.as_str()).wrap());
        }
        ui.separator();
        ui.label(
            "drag: orbit · right drag: pan · wheel: zoom\nctrl+drag: move the chosen clip plane, +shift: tilt it\n\
             arrows, shift+arrows, +/-\nL R A P S I: standard views · O: projection · Home: \
             reset",
        );
        changed
    }
}

impl eframe::App for App {
    fn ui(&mut self, ui: &mut egui::Ui, _frame: &mut eframe::Frame) {
        self.show_ui(ui);
    }
}

impl App {
    /// The window's contents, a frame of them (what eframe calls; tests call it directly).
    pub fn show_ui(&mut self, ui: &mut egui::Ui) {
        let ctx = ui.ctx().clone();
        if self.quit.load(Ordering::Relaxed) {
            ctx.send_viewport_cmd(egui::ViewportCommand::Close);
        }
        let start = Instant::now();
        let fresh = self.receive(&ctx, Duration::ZERO);
        let mut changed = false;
        // Files dropped on the window or chosen in the file dialog join the scene.
        let mut dropped: Vec<std::path::PathBuf> = ctx.input(|i| {
            i.raw
                .dropped_files
                .iter()
                .map(|f| f.path().to_path_buf())
                .collect()
        });
        dropped.extend(self.browser.show(&ctx));
        for p in dropped {
            changed |= self.open_file(&p);
        }
        changed |= std::mem::take(&mut self.reask);
        // The panel keeps to at most 360 points and 45% of the window (its sections, opened,
        // would otherwise widen it and squeeze the view); the user may drag its edge.
        let widest = (0.45 * ui.available_width()).clamp(160.0, 360.0);
        egui::Panel::left("controls")
            .default_size(280.0_f32.min(widest))
            .max_size(widest)
            .show(ui, |ui| {
                egui::ScrollArea::vertical().show(ui, |ui| changed |= self.panel(ui));
            });
        // No fill under the view (the image covers it): on a CPU adapter every layer of the
        // window's pixels costs as much as the image, about 25 ms a frame at 900 x 600.
        egui::CentralPanel::default()
            .frame(egui::Frame::NONE)
            .show(ui, |ui| {
                // The view on whole physical pixels, the render's size: a panel edge at a
                // fraction of a pixel shifted and resampled the image (a new user's capture
                // differed from `umbra render` on every edge, by up to 215 levels, with the
                // transfer-function editor open).
                let ppp = ctx.pixels_per_point();
                let (rect, (w, h)) = pixel_rect(ui.available_rect_before_wrap(), ppp);
                let response = ui.allocate_rect(rect, egui::Sense::click_and_drag());
                if let Some(t) = &self.texture {
                    ui.painter().image(
                        t.id(),
                        rect,
                        egui::Rect::from_min_max(egui::pos2(0.0, 0.0), egui::pos2(1.0, 1.0)),
                        egui::Color32::WHITE,
                    );
                }
                self.triad(ui.painter(), rect);
                self.clip_outline(ui.painter(), rect);
                // The render follows the view's size in physical pixels.
                if (w, h) != (self.scene.render.width, self.scene.render.height) {
                    self.scene.render.width = w;
                    self.scene.render.height = h;
                    changed = true;
                }
                changed |= self.input(ui, &response);
            });
        if changed {
            self.changed();
        } else if self.full_pending && self.last_input.elapsed() >= REST {
            self.full_pending = false;
            self.ask(Level::Full);
        }
        // A frame only when something waits: the rest timer here, new images through the
        // worker's wake, the quit flag through its watcher (lib.rs), input through eframe. On
        // a CPU adapter a window frame costs about 140 ns a pixel (egui's shader on llvmpipe:
        // 76 ms at 900 x 600), so ticking while idle took CPU from the renders.
        if self.full_pending {
            ctx.request_repaint_after(REST.saturating_sub(self.last_input.elapsed()));
        }
        // Paced (a CPU adapter): the request of this frame's input is on its way; a frame
        // without a new image waits for the one being drawn (up to the pace since the last
        // frame) and is drawn with it, so that the window and the worker take turns on the
        // cores rather than slowing each other (each spreads its work over all of them).
        let drawing = !self.shown_scenes.is_empty();
        if let (Some(pace), false, true) = (self.pace, fresh, drawing) {
            let since = self.last_frame.min(start).elapsed();
            self.receive(&ctx, pace.saturating_sub(since));
        }
        self.last_frame = start;
        if let Some(f) = &mut self.on_event {
            f(&crate::ViewEvent::Frame);
        }
    }
}

/// The largest rectangle within `rect` whose edges lie on physical pixels (`ppp` of them a
/// point), and its size in pixels (at least 16 each way): where the view is drawn, one image
/// pixel on one window pixel.
fn pixel_rect(rect: egui::Rect, ppp: f32) -> (egui::Rect, (u32, u32)) {
    let min = egui::pos2((rect.min.x * ppp).ceil(), (rect.min.y * ppp).ceil());
    let max = egui::pos2((rect.max.x * ppp).floor(), (rect.max.y * ppp).floor());
    let (w, h) = (
        ((max.x - min.x).max(0.0) as u32).max(16),
        ((max.y - min.y).max(0.0) as u32).max(16),
    );
    let min = egui::pos2(min.x / ppp, min.y / ppp);
    (
        egui::Rect::from_min_size(min, egui::vec2(w as f32 / ppp, h as f32 / ppp)),
        (w, h),
    )
}

#[cfg(test)]
mod pixel_rect_tests {
    use super::pixel_rect;
    use eframe::egui;

    /// The view's edges fall on whole pixels and its size is the render's, whatever fraction
    /// of a pixel the panel leaves (a panel 307.4 points wide, scales 1, 1.25 and 2).
    #[test]
    fn the_view_lies_on_whole_pixels() {
        for ppp in [1.0f32, 1.25, 2.0] {
            let rect = egui::Rect::from_min_max(egui::pos2(307.4, 0.3), egui::pos2(1100.0, 720.9));
            let (r, (w, h)) = pixel_rect(rect, ppp);
            for v in [r.min.x, r.min.y, r.max.x, r.max.y] {
                let px = v * ppp;
                assert!(
                    (px - px.round()).abs() < 1e-3,
                    "{ppp}: an edge at pixel {px}"
                );
            }
            assert!(((r.width() * ppp) - w as f32).abs() < 1e-3, "{ppp}: {w}");
            assert!(((r.height() * ppp) - h as f32).abs() < 1e-3, "{ppp}: {h}");
            assert!(rect.contains_rect(r), "{ppp}: {r:?} outside {rect:?}");
            assert!(w as f32 >= rect.width() * ppp - 2.0, "{ppp}: {w} pixels");
        }
    }
}
