//! `umbra view`: the interactive viewer. A window (eframe on wgpu, Vulkan on Linux, X11)
//! shows the scene drawn by the same renderer as `umbra render` (`scene::compile`, on a
//! worker thread: [`worker`]), a draft while the user drags and the full scene when the view
//! rests; the camera is an orbit about the scene's target ([`controls`]) written back into the
//! scene. It ends with status 0 when its window closes or on SIGINT or SIGTERM.

pub mod app;
pub mod controls;
pub mod objects;
pub mod settings;
pub mod transfer;
pub mod transform;
pub mod worker;

use std::path::PathBuf;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;

/// Called once when the first image is shown, with the renderer's adapter.
pub type OnFirstImage = Box<dyn FnOnce(&str)>;

/// What the window did: a frame of its own painted, or a rendered image shown in it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ViewEvent {
    Frame,
    Image {
        level: worker::Level,
        size: [usize; 2],
        total_ms: f64,
    },
}

/// Called at every [`ViewEvent`] (the command line's frame log).
pub type OnEvent = Box<dyn FnMut(&ViewEvent)>;

/// What `umbra view` was asked for.
pub struct ViewArgs {
    pub scene: PathBuf,
    /// Scene overrides, `KEY=VALUE` (as `umbra render --set`).
    pub overrides: Vec<String>,
    /// The window's inner size in logical points.
    pub window: [f32; 2],
    pub on_first_image: Option<OnFirstImage>,
    pub on_event: Option<OnEvent>,
}

/// Opens the viewer and returns when its window has closed; an error when the scene cannot
/// be read, or no window can be opened (no display), naming what is missing.
pub fn run(a: ViewArgs) -> Result<(), String> {
    // The scene file first (quick): its errors are reported wherever the viewer runs; the
    // model, which may take seconds, once a window can be opened.
    let s = scene::spec::load(&a.scene, &a.overrides)?;
    let display = std::env::var_os("DISPLAY").filter(|d| !d.is_empty());
    if cfg!(target_os = "linux") && display.is_none() {
        return Err(
            "umbra view needs an X display (DISPLAY is not set); on a machine without \
                    one, run it under xvfb-run or use umbra render"
                .into(),
        );
    }
    let m = scene::compile::model(&s).map_err(|e| format!("{}: {e}", a.scene.display()))?;
    let bounds = m.bounds;
    let slice_grid = objects::SliceGrid::of(&m);
    let ras = m.is_ras();
    let range = worker::data_range(&m);
    let editor = worker::editor_of(&m, range);
    let quit = Arc::new(AtomicBool::new(false));
    for sig in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        signal_hook::flag::register(sig, quit.clone())
            .map_err(|e| format!("installing the signal handler: {e}"))?;
    }
    // The window's own wgpu device: Vulkan on Linux (the GL path needs a display EGL may not
    // have under Xvfb), unless the user chose with WGPU_BACKEND.
    if cfg!(target_os = "linux") && std::env::var_os("WGPU_BACKEND").is_none() {
        std::env::set_var("WGPU_BACKEND", "vulkan");
    }
    let options = eframe::NativeOptions {
        viewport: eframe::egui::ViewportBuilder::default()
            .with_title(format!("umbra view - {}", a.scene.display()))
            .with_inner_size(a.window),
        renderer: eframe::Renderer::Wgpu,
        ..Default::default()
    };
    let on_first = a.on_first_image;
    let on_event = a.on_event;
    // A window destroyed by another X client (`xdotool windowclose`) makes winit 0.30 panic on
    // its next request about the window (BadWindow, BadDrawable): that is the window closing,
    // so it ends the viewer with success, without the panic's message.
    let previous = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        if !window_gone(&panic_text(info.payload())) {
            previous(info);
        }
    }));
    let run = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        eframe::run_native(
            "umbra view",
            options,
            Box::new(move |cc| {
                let ctx = cc.egui_ctx.clone();
                watch_quit(quit.clone(), ctx.clone());
                let worker = worker::start(m, &s, move || ctx.request_repaint());
                let mut app = app::App::new(s, bounds, worker, quit, on_first)
                    .with_slice_grid(slice_grid)
                    .with_ras(ras);
                if let Some(e) = editor {
                    app = app.with_editor(e);
                }
                let cpu = cc.wgpu_render_state.as_ref().is_some_and(|r| {
                    r.adapter.get_info().device_type == eframe::wgpu::DeviceType::Cpu
                });
                if cpu {
                    app = app.paced(PACE_CPU);
                }
                if let Some(f) = on_event {
                    app = app.with_events(f);
                }
                Ok(Box::new(app))
            }),
        )
    }));
    let _ = std::panic::take_hook();
    match run {
        Ok(r) => r.map_err(|e| {
            // winit's text can carry its source file's path; say what was tried, then it.
            let e = e.to_string();
            let e = e.rsplit_once(".rs:").map_or(e.as_str(), |(_, rest)| {
                rest.split_once(": ").map_or(rest, |(_, m)| m)
            });
            format!(
                "umbra view could not open its window on the X display {}: {e}",
                display
                    .as_deref()
                    .map_or("(none)".into(), |d| d.to_string_lossy().into_owned())
            )
        }),
        Err(p) if window_gone(&panic_text(&*p)) => Ok(()),
        Err(p) => std::panic::resume_unwind(p),
    }
}

/// The shortest time between window frames without a new image when the window is drawn
/// by a CPU adapter ([`app::App::paced`]).
pub const PACE_CPU: std::time::Duration = std::time::Duration::from_millis(100);

/// Wakes the window once SIGINT or SIGTERM set `quit` (the window draws frames only when
/// something happens; its next frame closes it), polling the flag every 100 ms.
fn watch_quit(quit: Arc<AtomicBool>, ctx: eframe::egui::Context) {
    let _ = std::thread::Builder::new()
        .name("umbra quit".into())
        .spawn(move || loop {
            if quit.load(std::sync::atomic::Ordering::Relaxed) {
                ctx.request_repaint();
            }
            std::thread::sleep(std::time::Duration::from_millis(100));
        });
}

/// A panic's message, where it is text.
fn panic_text(p: &(dyn std::any::Any + Send)) -> String {
    p.downcast_ref::<String>()
        .cloned()
        .or_else(|| p.downcast_ref::<&str>().map(|s| s.to_string()))
        .unwrap_or_default()
}

/// Whether a panic says the X server no longer knows the window (an X11 BadWindow or
/// BadDrawable error, whichever request winit made first).
fn window_gone(text: &str) -> bool {
    text.contains("X11Error")
        && (text.contains("error_kind: Window") || text.contains("error_kind: Drawable"))
}

/// Writes `bytes` to `path` through a temporary file and a rename (`volume::write_atomic`, the
/// writer every output of umbra goes through), the error as text naming the file.
pub fn write_atomic(path: &std::path::Path, bytes: &[u8]) -> Result<(), String> {
    // Its folder made first (like `mkdir -p`), as for every output of umbra.
    volume::check_output(path).map_err(|e| e.to_string())?;
    volume::write_atomic(path, bytes).map_err(|e| e.to_string())
}
