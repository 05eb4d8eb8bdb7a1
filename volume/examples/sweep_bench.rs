//! Benchmark of the fast-sweeping precompute (distance + eight octants) on the three-solids
//! scene, for docs/benchmarks.md: `cargo run --release -p volume --example sweep_bench -- 256 5`
//! prints one JSON line per measurement: the compute seconds of `sweep_fields` (median of
//! `repeat` runs; initialisation, distance and octant sweeps, no I/O), the distance alone, and a
//! plain copy of the bytes the method reads and writes (4 bytes in, 12 out per voxel): the
//! memory-bandwidth floor. With `table2` it also runs the paper's Table 2 grid sizes.
use std::time::Instant;
use volume::distance_sweep::{signed_distance, DistanceOptions};
use volume::occlusion_sweep::{sweep_fields, OcclusionOptions};
use volume::synthetic::{sample_solid, three_solids};

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(|a, b| a.total_cmp(b));
    v[v.len() / 2]
}

fn run(dims: [usize; 3], repeat: usize) {
    // The unit cube sampled with dims (non-cubic grids keep isotropic spacing of 1/(n-1) in x).
    let h = 1.0 / (dims[0] - 1) as f64;
    let affine = glam::DMat4::from_scale(glam::DVec3::splat(h));
    let vol = sample_solid(&three_solids(), dims, affine);
    let values = &vol.fields[0].data;
    let sp = [h as f32; 3];
    let opts = DistanceOptions::default();
    let mut both = Vec::new();
    let mut iters = 0;
    for _ in 0..repeat {
        let t = Instant::now();
        let (df, oct) = sweep_fields(values, dims, sp, &opts, &OcclusionOptions::default(), true);
        both.push(t.elapsed().as_secs_f64());
        iters = df.iterations;
        std::hint::black_box(oct);
    }
    let mut dist = Vec::new();
    for _ in 0..repeat {
        let t = Instant::now();
        std::hint::black_box(signed_distance(values, dims, sp, &opts));
        dist.push(t.elapsed().as_secs_f64());
    }
    let n = dims[0] * dims[1] * dims[2];
    let mut copy = Vec::new();
    for _ in 0..repeat {
        let t = Instant::now();
        let d: Vec<f32> = values.clone();
        let mut o: Vec<u8> = vec![0u8; 8 * n];
        o.fill(1);
        std::hint::black_box((d, o));
        copy.push(t.elapsed().as_secs_f64());
    }
    println!(
        "{{\"dims\": {:?}, \"repeat\": {repeat}, \"compute_s\": {:.4}, \"distance_only_s\": {:.4}, \"copy_s\": {:.4}, \"iterations\": {iters}, \"threads\": {}}}",
        dims,
        median(both),
        median(dist),
        median(copy),
        rayon::current_num_threads()
    );
}

fn main() {
    let a: Vec<String> = std::env::args().collect();
    let n: usize = a.get(1).and_then(|s| s.parse().ok()).unwrap_or(256);
    let repeat: usize = a.get(2).and_then(|s| s.parse().ok()).unwrap_or(5);
    run([n; 3], repeat);
    if a.iter().any(|s| s == "table2") {
        for dims in [
            [101, 101, 61],
            [100, 100, 100],
            [150, 150, 150],
            [200, 200, 200],
            [250, 250, 250],
        ] {
            run(dims, repeat);
        }
    }
}
