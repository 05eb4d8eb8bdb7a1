//! Times the distance and octant sweeps on the three-solids scene:
//! `cargo run --release -p volume --example sweep_timing -- 256`.
use volume::distance_sweep::{classify_and_initialise, sweep_distance, DistanceOptions};
use volume::occlusion_sweep::{sweep_fields, OcclusionOptions};
use volume::synthetic::{cube_affine, sample_solid, three_solids};

fn main() {
    let n: usize = std::env::args()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(128);
    let vol = sample_solid(&three_solids(), [n; 3], cube_affine([n; 3], 0.0, 1.0));
    let h = vol.spacing()[0] as f32;
    let opts = DistanceOptions::default();
    let t = std::time::Instant::now();
    let init = classify_and_initialise(&vol.fields[0].data, [n; 3], [h; 3], &opts);
    let t_init = t.elapsed();
    let df = sweep_distance(init, &opts);
    let t_all = t.elapsed();
    println!(
        "n={n}: distance only: init {:.3} s, total {:.3} s, iterations {}, rows {} ({:.1} full sweeps)",
        t_init.as_secs_f64(),
        t_all.as_secs_f64(),
        df.iterations,
        df.rows_processed,
        df.rows_processed as f64 / (n * n) as f64
    );
    for _ in 0..3 {
        let t = std::time::Instant::now();
        let (df, oct) = sweep_fields(
            &vol.fields[0].data,
            [n; 3],
            [h; 3],
            &opts,
            &OcclusionOptions::default(),
            true,
        );
        println!(
            "n={n}: distance + 8 octants: {:.3} s ({} iterations, {} octants)",
            t.elapsed().as_secs_f64(),
            df.iterations,
            oct.unwrap().octants.len()
        );
    }
}
