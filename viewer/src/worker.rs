//! The render worker: a thread that owns the GPU and the uploaded scene, draws the latest
//! requested state of the scene and hands the image back, so that the window never waits for
//! a frame. Requests that arrive while a frame is drawn are coalesced: only the newest is drawn
//! next.

use engine::renderer::DrawOptions;
use scene::compile::{upload, Model};
use scene::spec::Scene;
use std::sync::mpsc::{channel, Receiver, Sender};

/// How much of the scene a frame draws: a draft while the user drags (a quarter of the
/// resolution, `ea`, at most [`DRAFT_SLICES`] slices, no MSAA or FXAA), the full scene when
/// the view rests.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Level {
    Draft,
    Full,
}

/// Slices a draft draws at most.
pub const DRAFT_SLICES: u32 = 128;

/// The scene a frame of `level` draws for scene state `s`.
pub fn at_level(s: &Scene, level: Level) -> Scene {
    let mut d = s.clone();
    if level == Level::Draft {
        d.render.width = (s.render.width / 4).max(16);
        d.render.height = (s.render.height / 4).max(16);
        d.render.method = engine::method::Method::Ea;
        d.render.slices = Some(s.render.slices.unwrap_or(DRAFT_SLICES).min(DRAFT_SLICES));
        d.render.slice_distance = None;
        d.render.msaa = 1;
        d.render.fxaa = false;
        d.render.stereo = scene::spec::Stereo::None;
    }
    d
}

/// A frame to draw, and where to write it (a screenshot: PNG, or EXR with `aov` the AOV
/// channels, as `umbra render` writes them).
pub struct Request {
    pub id: u64,
    pub scene: Scene,
    pub level: Level,
    pub save: Option<(std::path::PathBuf, bool)>,
}

/// A drawn frame: 8-bit sRGB RGBA (rows top to bottom), what it took and what the renderer
/// noted.
pub struct Image {
    pub id: u64,
    pub level: Level,
    pub size: [usize; 2],
    pub rgba: Vec<u8>,
    pub total_ms: f64,
    pub passes: Vec<(String, f64)>,
    pub notes: Vec<String>,
    pub device: String,
    /// The screenshot the request asked for: its path, or why it was not written.
    pub saved: Option<Result<std::path::PathBuf, String>>,
}

/// Draws `s` (the scene state, any level already applied) with the uploaded model into an
/// [`Image`]: the same frame `umbra render` writes as PNG for that scene.
pub fn draw(up: &scene::compile::Uploaded, m: &Model, req: &Request) -> Result<Image, String> {
    let s = at_level(&req.scene, req.level);
    let (out, v) = up.draw(
        &s,
        m,
        DrawOptions {
            frames: 1,
            pass_timings: true,
        },
    )?;
    let saved = req.save.as_ref().map(|(path, aov)| {
        let exr = path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("exr"));
        scene::render::write_image(path, exr, *aov && exr, s.render.bits, &out, &v)
            .map(|()| path.clone())
    });
    let rgba = out
        .image
        .iter()
        .flat_map(|p| {
            [
                scene::image_io::srgb8(p[0]),
                scene::image_io::srgb8(p[1]),
                scene::image_io::srgb8(p[2]),
                255,
            ]
        })
        .collect();
    Ok(Image {
        id: req.id,
        level: req.level,
        size: [s.render.width as usize, s.render.height as usize],
        rgba,
        total_ms: out.timings.total_ms,
        passes: out.timings.passes.into_iter().collect(),
        notes: out.notes,
        device: up.renderer.gpu().report().name,
        saved,
    })
}

/// The worker's ends: requests in, images (or an error naming what failed) out.
pub struct Worker {
    pub requests: Sender<Request>,
    pub images: Receiver<Result<Image, String>>,
}

/// Starts the worker for model `m`; `wake` is called after each image (the window repaints).
pub fn start(m: Model, wake: impl Fn() + Send + 'static) -> Worker {
    let (req_tx, req_rx) = channel::<Request>();
    let (img_tx, img_rx) = channel();
    std::thread::Builder::new()
        .name("umbra render".into())
        .spawn(move || {
            let gpu = match engine::gpu::Gpu::new() {
                Ok(g) => g,
                Err(e) => {
                    let _ = img_tx.send(Err(format!("no GPU adapter for the renderer: {e}")));
                    wake();
                    return;
                }
            };
            let up = match upload(&gpu, &m) {
                Ok(u) => u,
                Err(e) => {
                    let _ = img_tx.send(Err(e));
                    wake();
                    return;
                }
            };
            while let Ok(mut req) = req_rx.recv() {
                while let Ok(newer) = req_rx.try_recv() {
                    req = newer;
                }
                if img_tx.send(draw(&up, &m, &req)).is_err() {
                    break;
                }
                wake();
            }
        })
        .expect("spawning the render thread");
    Worker {
        requests: req_tx,
        images: img_rx,
    }
}
