//! The viewer's drafts while orbiting, without a window: the worker's session draws N drafts
//! of a scene at a view size, turning 2 degrees a draft, and prints each draft's time, its
//! geometry share and slice budget (what the panel shows) and the pooled GPU objects (shader
//! modules, layouts, pipelines, scratch buffers) it had to make, then a full image's time.
//!   cargo run --release -p umbra-viewer --example drafts -- SCENE [N] [WIDTH HEIGHT]
//! docs/benchmarks.md ("Interactive viewer") quotes it.

use umbra_viewer::worker::{Level, Request, Session};

fn main() -> Result<(), String> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let path = args
        .first()
        .ok_or("usage: drafts SCENE [N] [WIDTH HEIGHT]")?;
    let n: usize = args
        .get(1)
        .map_or(Ok(30), |a| a.parse())
        .map_err(|e| format!("N: {e}"))?;
    let w: u32 = args
        .get(2)
        .map_or(Ok(900), |a| a.parse())
        .map_err(|e| format!("WIDTH: {e}"))?;
    let h: u32 = args
        .get(3)
        .map_or(Ok(600), |a| a.parse())
        .map_err(|e| format!("HEIGHT: {e}"))?;
    let mut s = scene::spec::load(std::path::Path::new(path), &[])?;
    s.render.width = w;
    s.render.height = h;
    let t = std::time::Instant::now();
    let m = scene::compile::model(&s).map_err(|e| format!("{path}: {e}"))?;
    let mut session = Session::new(m, &s)?;
    println!("model and upload: {:.1} s", t.elapsed().as_secs_f64());
    let az0 = s.camera.azimuth;
    for i in 0..n {
        s.camera.azimuth = az0 + 2.0 * i as f64;
        let t = std::time::Instant::now();
        let made = session.gpu().pool_made();
        let img = session.frame(&Request {
            id: i as u64,
            scene: s.clone(),
            level: Level::Draft,
            save: None,
            pass_timings: false,
        })?;
        println!(
            "draft {i:3}: {:7.1} ms frame ({}), {:7.1} ms call, {} pooled objects made, {} x {}; {}",
            img.total_ms,
            img.passes
                .iter()
                .map(|(p, ms)| format!("{p} {ms:.1}"))
                .collect::<Vec<_>>()
                .join(", "),
            t.elapsed().as_secs_f64() * 1e3,
            session.gpu().pool_made() - made,
            img.size[0],
            img.size[1],
            img.notes.last().map_or("", String::as_str)
        );
    }
    let img = session.frame(&Request {
        id: n as u64,
        scene: s.clone(),
        level: Level::Full,
        save: None,
        pass_timings: false,
    })?;
    println!(
        "full: {:.1} ms, {} x {}",
        img.total_ms, img.size[0], img.size[1]
    );
    Ok(())
}
