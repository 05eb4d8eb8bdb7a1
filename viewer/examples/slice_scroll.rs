//! Scrolling a slice in the viewer, without a window: the worker's session draws a scene,
//! then N drafts and N full images with the first slice moved a 300th of its span further
//! each (the slices planned again on the modelled grid; with a slab, the full images model
//! the scene anew), and last a full image with a slab added to the first slice (the scene
//! modelled anew: what moving a slice cost before slices were planned on their own). Prints
//! each step's time and whether the model was made anew.
//!   cargo run --release -p umbra-viewer --example slice_scroll -- SCENE [N] [WIDTH HEIGHT]
//! docs/benchmarks.md ("Interactive viewer") quotes it.

use umbra_viewer::worker::{Level, Request, Session};

fn main() -> Result<(), String> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let path = args
        .first()
        .ok_or("usage: slice_scroll SCENE [N] [WIDTH HEIGHT]")?;
    let arg = |i: usize, d: u32, what: &str| {
        args.get(i)
            .map_or(Ok(d), |a| a.parse())
            .map_err(|e| format!("{what}: {e}"))
    };
    let (n, w, h) = (
        arg(1, 10, "N")?,
        arg(2, 900, "WIDTH")?,
        arg(3, 600, "HEIGHT")?,
    );
    let mut s = scene::spec::load(std::path::Path::new(path), &[])?;
    if s.slices.is_empty() {
        return Err(format!("{path}: no [[slices]] to scroll"));
    }
    s.render.width = w;
    s.render.height = h;
    let t = std::time::Instant::now();
    let m = scene::compile::model(&s).map_err(|e| format!("{path}: {e}"))?;
    let grid = umbra_viewer::objects::SliceGrid::of(&m).ok_or("no slice grid")?;
    let mut session = Session::new(m, &s)?;
    println!("model and upload: {:.2} s", t.elapsed().as_secs_f64());
    let (z0, [lo, hi]) = grid.position(&s.slices[0]);
    let step = (hi - lo) / 300.0;
    let mut id = 0;
    let mut frame = |s: &scene::spec::Scene, level: Level| {
        id += 1;
        let t = std::time::Instant::now();
        let img = session.frame(&Request {
            id,
            scene: s.clone(),
            level,
            save: None,
            pass_timings: false,
        })?;
        Ok::<_, String>((t.elapsed().as_secs_f64() * 1e3, img.rebuilt.is_some()))
    };
    let (ms, _) = frame(&s, Level::Full)?;
    println!("first full image: {ms:.0} ms");
    for level in [Level::Draft, Level::Full] {
        let mut times = vec![];
        for i in 1..=n {
            s.slices[0].position = Some((z0 + i as f64 * step).min(hi));
            let (ms, rebuilt) = frame(&s, level)?;
            times.push(ms);
            println!(
                "{level:?} {i}: slice at {:.2}: {ms:.0} ms (model anew: {rebuilt})",
                z0 + i as f64 * step
            );
        }
        times.sort_by(f64::total_cmp);
        println!(
            "{level:?}: median {:.0} ms over {n}",
            times[times.len() / 2]
        );
    }
    // The scene modelled anew: a (huge) slab on the first slice crops the geometry, if any.
    s.slices[0].slab = Some(1e9);
    let (ms, rebuilt) = frame(&s, Level::Full)?;
    println!("full image, the scene modelled anew: {ms:.0} ms (model anew: {rebuilt})");
    Ok(())
}
