//! `umbra bench curves <scene.toml> -o <dir>`: how the renderer's cost grows with its work, in
//! one process (one load, one upload): frame time against image size, slice count and line
//! segment count, for each method and device asked for.

use super::chart::{write_chart, Plot};
use crate::commands::list_item;
use crate::output::out;
use engine::renderer::DrawOptions;
use scene::spec;
use std::io::Write as _;
use std::path::PathBuf;

/// `umbra bench curves`.
#[derive(clap::Args)]
pub struct Args {
    /// Scene file (its camera, data and settings; the swept keys are overridden).
    scene: PathBuf,
    /// Square image sizes (pixels per side).
    #[arg(long, value_delimiter = ',', value_parser = list_item::<u32>, default_value = "128,256,512,1024,2048")]
    sizes: Vec<u32>,
    /// Slice counts, at the size `--slice-size`.
    #[arg(long, value_delimiter = ',', value_parser = list_item::<u32>)]
    slices: Vec<u32>,
    #[arg(long, default_value_t = 512)]
    slice_size: u32,
    /// Fractions of each line set's segments (the first segments kept), at `--slice-size`.
    #[arg(long, value_delimiter = ',', value_parser = list_item::<f64>)]
    segments: Vec<f64>,
    /// Methods (render.method).
    #[arg(long, value_delimiter = ',', default_value = "ea,combined")]
    methods: Vec<String>,
    /// Devices (render.device): gpu, cpu (the CPU renderer draws only what it can; other
    /// cases are left out with a note).
    #[arg(long, value_delimiter = ',', default_value = "gpu")]
    devices: Vec<String>,
    /// Frames per point (the median is reported).
    #[arg(long, default_value_t = 3)]
    frames: u32,
    /// Scene key overrides for every case.
    #[arg(long = "set")]
    overrides: Vec<String>,
    #[arg(short, long)]
    output: PathBuf,
}

/// Draws scene `s` of the uploaded model `m` and records the point of `curve`, or a note
/// saying why it could not be drawn.
fn measure(
    up: &scene::compile::Uploaded,
    s: &spec::Scene,
    m: &scene::compile::Model,
    opts: DrawOptions,
    (curve, method, device): (&'static str, &str, &str),
    rows: &mut Vec<Row>,
    notes: &mut Vec<String>,
) {
    let segments = m.lines.iter().map(|l| l.segments.len() as u64).sum();
    match up.draw(s, m, opts) {
        Ok((o, v)) => rows.push(Row {
            curve,
            method: method.into(),
            device: device.into(),
            width: v.width,
            slices: v.slices,
            segments,
            ms: o.timings.total_ms,
        }),
        Err(e) => notes.push(format!(
            "{method} on {device}, {curve} curve, {} x {}: {e}",
            s.render.width, s.render.height
        )),
    }
}

/// One measured point.
struct Row {
    curve: &'static str,
    method: String,
    device: String,
    width: u32,
    slices: u32,
    segments: u64,
    ms: f64,
}

pub fn run(a: Args) -> Result<(), String> {
    if a.frames == 0 {
        return Err("--frames: must be at least 1".into());
    }
    let base = spec::load(&a.scene, &a.overrides)?;
    let opts = DrawOptions {
        frames: a.frames,
        pass_timings: false,
    };
    let mut rows: Vec<Row> = vec![];
    let mut notes: Vec<String> = vec![];
    let cases: Vec<(String, String)> = a
        .methods
        .iter()
        .flat_map(|m| a.devices.iter().map(move |d| (m.clone(), d.clone())))
        .collect();
    // The scene for one case at one size and slice count.
    let with = |method: &str, device: &str, size: u32, slices: Option<u32>| {
        let sets = vec![
            format!("render.method=\"{method}\""),
            format!("render.device=\"{device}\""),
            format!("render.width={size}"),
            format!("render.height={size}"),
        ];
        let all: Vec<String> = a.overrides.iter().cloned().chain(sets).collect();
        let mut s = spec::load(&a.scene, &all)?;
        if let Some(n) = slices {
            // A slice count replaces whatever slice distance the scene or --set gives.
            s.render.slices = Some(n);
            s.render.slice_distance = None;
        }
        Ok::<_, String>(s)
    };
    // Every case's scene, and the segment fractions, are checked before anything is written.
    if let Some(n) = a.slices.iter().find(|&&n| !(1..=16384).contains(&n)) {
        return Err(format!("--slices: {n} is not within 1..16384"));
    }
    for (method, device) in &cases {
        for &size in &a.sizes {
            with(method, device, size, None)?;
        }
        for &n in &a.slices {
            with(method, device, a.slice_size, Some(n))
                .map_err(|e| format!("--slice-size {}: {e}", a.slice_size))?;
        }
    }
    if let Some(f) = a.segments.iter().find(|&&f| !(f > 0.0 && f <= 1.0)) {
        return Err(format!("--segments: {f} is not in (0, 1]"));
    }
    if !a.segments.is_empty() && base.lines.is_empty() && base.points.is_empty() {
        return Err(format!(
            "{}: --segments needs [[lines]] or [[points]]",
            a.scene.display()
        ));
    }
    let made = !a.output.exists();
    std::fs::create_dir_all(&a.output).map_err(|e| format!("{}: {e}", a.output.display()))?;
    let mut m = scene::compile::model(&base).map_err(|e| format!("{}: {e}", a.scene.display()))?;
    let gpu = engine::gpu::Gpu::new().map_err(|e| e.to_string())?;
    {
        let up = scene::compile::upload(&gpu, &m)?;
        for (method, device) in &cases {
            // One frame first, not timed: a case's first frame compiles its pipelines and
            // fills the pools (with --frames 1 the first point of a curve took 1,124 ms where
            // its frames take 10).
            let first = a.sizes.first().copied().unwrap_or(a.slice_size);
            let _ = up.draw(
                &with(method, device, first, None)?,
                &m,
                DrawOptions {
                    frames: 1,
                    pass_timings: false,
                },
            );
            let case = |curve| (curve, method.as_str(), device.as_str());
            for &size in &a.sizes {
                let s = with(method, device, size, None)?;
                measure(&up, &s, &m, opts, case("size"), &mut rows, &mut notes);
            }
            for &n in &a.slices {
                let s = with(method, device, a.slice_size, Some(n))?;
                measure(&up, &s, &m, opts, case("slices"), &mut rows, &mut notes);
            }
        }
    }
    if !a.segments.is_empty() {
        let full: Vec<Vec<u32>> = m.lines.iter().map(|l| l.segments.clone()).collect();
        if full.iter().all(|s| s.is_empty()) {
            return Err(format!(
                "{}: --segments needs [[lines]] or [[points]]",
                a.scene.display()
            ));
        }
        for &f in &a.segments {
            if !(f > 0.0 && f <= 1.0) {
                return Err(format!("--segments: {f} is not in (0, 1]"));
            }
            for (l, s) in m.lines.iter_mut().zip(&full) {
                l.segments = s[..((s.len() as f64 * f).round() as usize).max(1)].to_vec();
            }
            let up = scene::compile::upload(&gpu, &m)?;
            for (method, device) in &cases {
                let s = with(method, device, a.slice_size, None)?;
                let case = ("segments", method.as_str(), device.as_str());
                measure(&up, &s, &m, opts, case, &mut rows, &mut notes);
            }
        }
    }
    if rows.is_empty() {
        // Nothing measured (every case left out): no empty table, no charts to announce, and
        // the folder this run made (still empty) removed.
        if made {
            let _ = std::fs::remove_dir(&a.output);
        }
        return Err(format!(
            "{}: no case could be measured: {}",
            a.scene.display(),
            notes.join("; ")
        ));
    }
    let mut csv = Vec::new();
    let _ = writeln!(csv, "curve,method,device,width,height,slices,segments,ms");
    for r in &rows {
        let _ = writeln!(
            csv,
            "{},{},{},{},{},{},{},{:.2}",
            r.curve, r.method, r.device, r.width, r.width, r.slices, r.segments, r.ms
        );
        out(format!(
            "{:8} {:12} {:4} {:5}^2 {:5} slices {:9} segments {:10.1} ms",
            r.curve, r.method, r.device, r.width, r.slices, r.segments, r.ms
        ))?;
    }
    volume::write_atomic(&a.output.join("curves.csv"), &csv).map_err(|e| e.to_string())?;
    for (curve, x_label, x) in [
        (
            "size",
            "pixels",
            (|r: &Row| r.width as f64 * r.width as f64) as fn(&Row) -> f64,
        ),
        ("slices", "slices", |r: &Row| r.slices as f64),
        ("segments", "line segments", |r: &Row| r.segments as f64),
    ] {
        let series: Vec<(String, Vec<(f64, f64)>)> = cases
            .iter()
            .map(|(method, device)| {
                (
                    format!("{method} ({device})"),
                    rows.iter()
                        .filter(|r| r.curve == curve && &r.method == method && &r.device == device)
                        .map(|r| (x(r), r.ms))
                        .collect::<Vec<_>>(),
                )
            })
            .filter(|(_, p)| !p.is_empty())
            .collect();
        if series.is_empty() {
            continue;
        }
        write_chart(
            &a.output,
            &format!("curve_{curve}"),
            &Plot {
                title: format!(
                    "{}: frame time against {x_label}",
                    a.scene.file_name().unwrap_or_default().to_string_lossy()
                ),
                x_label: x_label.into(),
                y_label: "frame time (ms, median)".into(),
                series,
                line: None,
            },
        )?;
    }
    for n in &notes {
        eprintln!("note: {n}");
    }
    eprintln!(
        "wrote {0}/curves.csv and {0}/curve_*.svg|png",
        a.output.display()
    );
    Ok(())
}
