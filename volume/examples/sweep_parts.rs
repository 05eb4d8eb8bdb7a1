//! Times the stages of `umbra sweep`'s computation on a volume file, for docs/benchmarks.md:
//! classification and band, transmittance, the eight octant sweeps (both z groups in parallel),
//! and the closest-point distance (its passes parallel inside, in the samples' buffer as
//! `umbra sweep` does), each alone, fastest of `repeat`.
//! `cargo run --release -p volume --example sweep_parts -- <volume> <iso> [repeat]`
use volume::closest_point::closest_point_distance;
use volume::distance_sweep::{classify_and_initialise_owned, DistanceOptions};
use volume::occlusion_sweep::{sweep_octants, transmittance};

fn main() {
    let a: Vec<String> = std::env::args().collect();
    let vol = volume::load(std::path::Path::new(&a[1])).expect("volume");
    let iso: f32 = a[2].parse().expect("iso");
    let repeat: usize = a.get(3).and_then(|s| s.parse().ok()).unwrap_or(5);
    let sp = vol.spacing();
    let sp = [sp[0] as f32, sp[1] as f32, sp[2] as f32];
    let opts = DistanceOptions {
        iso,
        ..Default::default()
    };
    let mut best = [f64::INFINITY; 4];
    for _ in 0..repeat {
        let values = vol.fields[0].data.clone();
        let t = std::time::Instant::now();
        let init = classify_and_initialise_owned(values, vol.dims, sp, &opts);
        let t1 = t.elapsed().as_secs_f64();
        let tau = transmittance(&init, None);
        let t2 = t.elapsed().as_secs_f64();
        let oct = sweep_octants(&tau, vol.dims);
        let t3 = t.elapsed().as_secs_f64();
        drop((oct, tau));
        let df = closest_point_distance(init);
        let t4 = t.elapsed().as_secs_f64();
        drop(df);
        for (b, x) in best.iter_mut().zip([t1, t2 - t1, t3 - t2, t4 - t3]) {
            *b = b.min(x);
        }
    }
    println!(
        "{{\"dims\": {:?}, \"init_s\": {:.3}, \"tau_s\": {:.3}, \"octants_s\": {:.3}, \"closest_point_s\": {:.3}}}",
        vol.dims, best[0], best[1], best[2], best[3]
    );
}
