//! `umbra view`: the interactive viewer (`umbra-viewer`) on a scene file.

use std::path::PathBuf;

/// Open a scene in a window: drag to orbit, right-drag to pan, wheel to zoom, ctrl+drag to
/// move the clip plane chosen in the panel (outlined in yellow) along its normal and
/// ctrl+shift+drag to tilt it about the camera's target; arrows
/// (orbit) and shift+arrows (pan), + and - (zoom), L R A P S I (standard views of RAS data:
/// from the left, right, front, back, top, bottom), O (orthographic/perspective), Home or 0
/// (reset). A draft (a quarter of the resolution, ea, at most 128 slices, fewer slices and
/// less geometry when drafts run slower than 60 ms) while you interact, the scene's full
/// image when the view rests. Closes with the window, Ctrl+C or
/// SIGTERM (status 0). Needs an X display (DISPLAY; xvfb-run works).
#[derive(clap::Args)]
pub struct Args {
    /// Scene file (see `umbra scene` and the README).
    scene: PathBuf,
    /// The window's inner width, logical pixels (200 to 16384).
    #[arg(long, default_value_t = 1100.0, value_parser = window_side)]
    width: f32,
    /// The window's inner height, logical pixels (200 to 16384).
    #[arg(long, default_value_t = 720.0, value_parser = window_side)]
    height: f32,
    /// Override a scene key by its dotted path (repeatable).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    set: Vec<String>,
    /// Write a CSV line for every window frame and every image shown to this file:
    /// seconds (since the start), event (frame or image), level (draft or full), width,
    /// height, total_ms (the image's render time); a benchmark's record of interaction.
    #[arg(long, value_name = "FILE")]
    frame_log: Option<PathBuf>,
}

/// A window side: a finite number of logical pixels in [200, 16384].
fn window_side(s: &str) -> Result<f32, String> {
    match s.trim().parse::<f32>() {
        Ok(v) if (200.0..=16384.0).contains(&v) => Ok(v),
        _ => Err(format!("'{s}' is not a number of pixels in 200..16384")),
    }
}

/// The frame log's writer: the file checked now (its folder made, writable, not the scene),
/// created with its header at the window's first event - a viewer that fails before its window
/// shows (a bad scene, no display) writes nothing - then a line per event (each written whole).
fn frame_log(
    path: &std::path::Path,
    scene: &std::path::Path,
    started: std::time::Instant,
) -> Result<umbra_viewer::OnEvent, String> {
    use std::io::Write;
    volume::check_output(path).map_err(|e| format!("--frame-log: {e}"))?;
    volume::check_not_input(&[Some(scene)], &[Some(path)])
        .map_err(|e| format!("--frame-log: {e}"))?;
    let path = path.to_path_buf();
    let mut out: Option<std::io::LineWriter<std::fs::File>> = None;
    let mut failed = false;
    Ok(Box::new(move |e: &umbra_viewer::ViewEvent| {
        let t = started.elapsed().as_secs_f64();
        if out.is_none() && !failed {
            // The scene's data are read by now: the log may not replace one of them.
            let created = volume::check_not_read(&[Some(&path)])
                .map_err(std::io::Error::other)
                .and_then(|()| std::fs::File::create(&path));
            match created.map(std::io::LineWriter::new) {
                Ok(mut f) => {
                    let _ = writeln!(f, "seconds,event,level,width,height,total_ms");
                    out = Some(f);
                }
                Err(err) => {
                    failed = true;
                    eprintln!("umbra view: warning: --frame-log {}: {err}", path.display());
                }
            }
        }
        let Some(out) = out.as_mut() else { return };
        // A full disk ends the log, not the viewer.
        let _ = match e {
            umbra_viewer::ViewEvent::Frame => writeln!(out, "{t:.4},frame,,,,"),
            umbra_viewer::ViewEvent::Image {
                level,
                size,
                total_ms,
            } => {
                let level = match level {
                    umbra_viewer::worker::Level::Draft => "draft",
                    umbra_viewer::worker::Level::Full => "full",
                };
                writeln!(
                    out,
                    "{t:.4},image,{level},{},{},{total_ms:.2}",
                    size[0], size[1]
                )
            }
        };
    }))
}

pub fn run(a: Args) -> Result<(), String> {
    let started = std::time::Instant::now();
    let on_event = a
        .frame_log
        .as_deref()
        .map(|p| frame_log(p, &a.scene, started))
        .transpose()?;
    umbra_viewer::run(umbra_viewer::ViewArgs {
        on_event,
        scene: a.scene,
        overrides: a.set,
        window: [a.width, a.height],
        on_first_image: Some(Box::new(move |device: &str| {
            eprintln!(
                "umbra view: first image after {:.1} s (renderer on {device})",
                started.elapsed().as_secs_f64()
            )
        })),
    })
}
