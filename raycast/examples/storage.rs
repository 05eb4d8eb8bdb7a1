//! What the stored sample type and the layout cost the CPU renderer: a volume rendered in turn
//! from a copy in bricks in its narrow storage (u8/u16 where exact), from a copy in f32 bricks,
//! and from the packed samples where they are (the grid's layout, no copy:
//! `EaVolume::in_place`, what `EaVolume::shared` reads above `COPY_AT_MOST`); medians of
//! frame times and the ratios to the f32 bricks, paired.
//! `cargo run --release -p raycast --example storage -- VOLUME [SIZE] [PAIRS]`
//! (a ramp transfer function over the data's range, transparent below 10% of it, extinction
//! 0.15 per world unit at the top; slices half the smallest spacing apart; the MNI demo view).

use occlusion::camera::Camera;
use occlusion::emission_absorption::{EaView, Transfer};
use std::time::Instant;

fn main() -> Result<(), String> {
    let args: Vec<String> = std::env::args().collect();
    let path = args.get(1).ok_or("usage: storage VOLUME [SIZE] [PAIRS]")?;
    let size: u32 = args
        .get(2)
        .map_or(Ok(512), |s| s.parse())
        .map_err(|_| "SIZE")?;
    let pairs: usize = args
        .get(3)
        .map_or(Ok(7), |s| s.parse())
        .map_err(|_| "PAIRS")?;
    let vol = volume::load(std::path::Path::new(path)).map_err(|e| e.to_string())?;
    let field = vol.select(None).map_err(|e| e.to_string())?;
    let st = field.stats();
    let (lo, hi) = (st.min, st.max);
    let tf = Transfer {
        points: vec![
            (lo + 0.1 * (hi - lo), [0.0; 3], 0.0),
            (hi, [1.0, 0.98, 0.92], 0.15),
        ],
        rows: vec![],
    };
    let narrow = raycast::EaVolume::with_storage(&vol, &field.data, &tf, true)?;
    let wide = raycast::EaVolume::with_storage(&vol, &field.data, &tf, false)?;
    let packed = std::sync::Arc::new(volume::samples::Samples::pack(
        occlusion::emission_absorption::prepare(&field.data),
    ));
    let flat = raycast::EaVolume::in_place(&vol, packed, &tf)?;
    let h = vol.spacing().iter().cloned().fold(f64::INFINITY, f64::min);
    let cam = Camera::orbit(vol.bounds(), 120.0, 15.0, 2.5, Some(30.0));
    let view = EaView::new(&vol, cam, size, size, None, Some(0.5 * h), [1.0; 3])?;
    let time = |ev: &raycast::EaVolume| {
        let t = Instant::now();
        std::hint::black_box(ev.render(&view));
        t.elapsed().as_secs_f64() * 1e3
    };
    time(&narrow);
    time(&wide);
    time(&flat);
    let (mut a, mut b, mut r) = (vec![], vec![], vec![]);
    let (mut c, mut rc) = (vec![], vec![]);
    for _ in 0..pairs {
        let (x, y, z) = (time(&narrow), time(&wide), time(&flat));
        a.push(x);
        b.push(y);
        r.push(x / y);
        c.push(z);
        rc.push(z / y);
    }
    let med = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    println!(
        "{path}: {size}^2, {} slices; {} bricks {:.1} ms, f32 bricks {:.1} ms, {} in place {:.1} \
         ms; paired ratios to f32 bricks {:.3} and {:.3}",
        view.slices,
        narrow.storage(),
        med(&mut a),
        med(&mut b),
        flat.storage(),
        med(&mut c),
        med(&mut r),
        med(&mut rc)
    );
    Ok(())
}
