//! `umbra render`: a scene file rendered on the GPU (`scene::render`) to PNG or EXR: one image,
//! a turntable (`--orbit N`) or a camera path (`--camera-path FILE`), with a one-line report
//! (or `--json`) and optional timings.

use crate::output::{out, out_json_pretty};
use crate::progress::Frames;
use scene::render::{Cameras, RenderArgs, RenderReport};
use std::path::PathBuf;

#[derive(clap::Args)]
pub struct Args {
    /// Scene file (see `umbra scene` and the README).
    scene: PathBuf,
    /// Output image: .png (8-bit sRGB) or .exr (linear float RGBA).
    #[arg(short, long)]
    output: PathBuf,
    /// Image width (render.width).
    #[arg(long)]
    width: Option<u32>,
    /// Image height (render.height).
    #[arg(long)]
    height: Option<u32>,
    /// A render method (render.method): combined, dos, vicinity, ea, phong, illuminated,
    /// lineao.
    #[arg(long, value_enum, hide_possible_values = true)]
    method: Option<super::Method>,
    /// Render each image this many times, every pass re-run (total_ms is the median);
    /// more than 1 also times each pass.
    #[arg(long, default_value_t = 1)]
    frames: u32,
    /// Write the timings (total_ms, passes, each frame's) as JSON to this file; also times
    /// each pass.
    #[arg(long)]
    timings_json: Option<PathBuf>,
    /// Render a turntable of N frames: frame k at camera.azimuth + k 360/N (a look-at
    /// camera turns its eye about the target around up). The output name's run of #
    /// becomes k, zero-padded.
    #[arg(long, value_name = "N", conflicts_with = "camera_path")]
    orbit: Option<u32>,
    /// Render the keyframed cameras of this TOML file (see the README, "Turntables and
    /// camera paths"); the output name needs a run of # as with --orbit.
    #[arg(long, value_name = "FILE")]
    camera_path: Option<PathBuf>,
    /// Add the AOV channels to the EXR: volumetric, partial, vicinity, lineao (with its
    /// factors .v, .g_depth, .g_light where it ran) and combined occlusion, linear depth (Z).
    #[arg(long)]
    aov: bool,
    /// Animate the lines' trails ([[lines]] trail): N frames with the trails' time `now` from
    /// T0 to T1 (inclusive), in one process; with --orbit (the same N) or --camera-path (as
    /// many frames) the camera moves too. The output name needs a run of # as with --orbit.
    #[arg(long, value_name = "T0:T1:N")]
    trail_range: Option<String>,
    /// Override a scene key by its dotted path (repeatable).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    set: Vec<String>,
    /// Print the report as JSON.
    #[arg(long)]
    json: bool,
}

pub fn run(a: Args) -> Result<(), String> {
    let cameras = match (a.orbit, a.camera_path) {
        (Some(n), _) => Cameras::Orbit(n),
        (None, Some(p)) => Cameras::Path(p),
        (None, None) => Cameras::Single,
    };
    let trail_range = a
        .trail_range
        .as_deref()
        .map(scene::render::TrailRange::parse)
        .transpose()?;
    let sequence = cameras != Cameras::Single || trail_range.is_some();
    let progress = Frames::new();
    let r = scene::render::run(
        &RenderArgs {
            scene: a.scene,
            output: a.output.clone(),
            overrides: size_method_overrides(a.width, a.height, a.method, a.set),
            frames: a.frames,
            aov: a.aov,
            pass_timings: a.timings_json.is_some() || a.frames > 1,
            cameras,
            trail_range,
        },
        &mut |f, n| {
            if sequence {
                progress.frame(f.index, n, &f.path, f.total_ms);
            }
        },
    )?;
    drop(progress);
    for n in &r.notes {
        eprintln!("note: {n}");
    }
    if let Some(t) = a.timings_json {
        let text = serde_json::to_string_pretty(&timings(&r)).map_err(|e| e.to_string())?;
        volume::write_atomic(&t, text.as_bytes()).map_err(|e| e.to_string())?;
    }
    if a.json {
        out_json_pretty(&r)?;
    } else {
        out(summary(&r))?;
    }
    match (r.sequence.first(), r.sequence.last()) {
        (Some(first), Some(last)) => eprintln!(
            "wrote {} frames ({} ... {})",
            r.sequence.len(),
            first.path.display(),
            last.path.display()
        ),
        _ => eprintln!("wrote {}", a.output.display()),
    }
    Ok(())
}

/// What `--timings-json` writes.
fn timings(r: &RenderReport) -> serde_json::Value {
    serde_json::json!({
        "total_ms": r.total_ms,
        "passes": r.passes,
        "pass_clock": r.pass_clock,
        "frames_ms": r.frames_ms,
        "method": r.method,
        "width": r.width,
        "height": r.height,
        "slices": r.slices,
        "triangles": r.triangles,
        "adapter": r.adapter,
        "setup_seconds": r.setup_seconds,
        "seconds": r.seconds,
        "sequence": r.sequence.iter().map(|f| serde_json::json!({
            "index": f.index,
            "path": f.path,
            "total_ms": f.total_ms,
            "frames_ms": f.frames_ms,
            "passes": f.passes,
            "slices": f.slices,
        })).collect::<Vec<_>>(),
    })
}

/// `--width`, `--height`, `--method` as scene overrides, before the `--set` ones.
pub fn size_method_overrides(
    width: Option<u32>,
    height: Option<u32>,
    method: Option<super::Method>,
    set: Vec<String>,
) -> Vec<String> {
    let mut o = vec![];
    if let Some(w) = width {
        o.push(format!("render.width={w}"));
    }
    if let Some(h) = height {
        o.push(format!("render.height={h}"));
    }
    if let Some(m) = method {
        o.push(format!("render.method=\"{}\"", m.name()));
    }
    o.extend(set);
    o
}

/// One line about a render.
pub fn summary(r: &RenderReport) -> String {
    // Per-pass times only when they were measured (--timings-json, --frames above 1).
    let passes = if r.passes.is_empty() {
        String::new()
    } else {
        let list: Vec<String> = r
            .passes
            .iter()
            .map(|(k, v)| format!("{k} {v:.1}"))
            .collect();
        format!(" ({})", list.join(", "))
    };
    format!(
        "{}: {} x {}, {} slices {:.4} apart, {} triangles, on {}: {:.1} ms per frame{passes}, {:.2} s in all",
        r.method,
        r.width,
        r.height,
        r.slices,
        r.slice_distance,
        r.triangles,
        r.adapter,
        r.total_ms,
        r.seconds
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn size_and_method_flags_come_before_the_set_overrides() {
        let o = size_method_overrides(
            Some(64),
            None,
            Some(super::super::Method(scene::spec::Method::Dos)),
            vec!["render.width=32".into()],
        );
        assert_eq!(
            o,
            [
                "render.width=64",
                "render.method=\"dos\"",
                "render.width=32"
            ]
        );
    }
}
