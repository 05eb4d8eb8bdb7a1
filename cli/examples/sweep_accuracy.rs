//! Swept ambient occlusion against the Monte Carlo reference on the validation scene:
//! `cargo run --release -p umbra --example sweep_accuracy -- [n] [size] [rays] [outdir]`.
//! Prints one line per configuration (RMSE over surface pixels) and writes the images.
use occlusion::isosurface::{render, rmse, AmbientSource, IsoSurface, OrbitCamera, Shading};
use scene::image_io::write_png;
use volume::distance_sweep::DistanceOptions;
use volume::occlusion_shading::{AmbientModel, AmbientOptions, GeometryTerm, Sky};
use volume::occlusion_sweep::{sweep_fields, OcclusionOptions};
use volume::synthetic::validation_scene;

fn main() {
    let a: Vec<String> = std::env::args().collect();
    let n: usize = a.get(1).and_then(|s| s.parse().ok()).unwrap_or(100);
    let size: usize = a.get(2).and_then(|s| s.parse().ok()).unwrap_or(256);
    let rays: usize = a.get(3).and_then(|s| s.parse().ok()).unwrap_or(256);
    let out = std::path::PathBuf::from(a.get(4).cloned().unwrap_or("/tmp/sweep_accuracy".into()));
    std::fs::create_dir_all(&out).unwrap();
    let vol = validation_scene(n);
    let sp = vol.spacing();
    let values = &vol.fields[0].data;
    let t = std::time::Instant::now();
    let (df, oct) = sweep_fields(
        values,
        vol.dims,
        [sp[0] as f32; 3],
        &DistanceOptions::default(),
        &OcclusionOptions::default(),
        true,
    );
    println!("sweep {:.3} s", t.elapsed().as_secs_f64());
    let oct = oct.unwrap();
    let surf = IsoSurface::new(vol.dims, vol.affine, values, 0.0, true, &df.distance);
    let cam = OrbitCamera {
        width: size,
        height: size,
        azimuth_deg: 35.0,
        elevation_deg: 35.0,
        distance: 1.25,
    };
    let shading = Shading::default();
    for uniform in [false, true] {
        let t = std::time::Instant::now();
        let reference = render(
            &surf,
            vol.bounds(),
            &cam,
            &AmbientSource::Reference { rays, uniform },
            &shading,
        );
        let se: f64 = reference
            .stderr
            .iter()
            .filter(|v| v.is_finite())
            .map(|&v| v as f64)
            .sum::<f64>()
            / reference
                .stderr
                .iter()
                .filter(|v| v.is_finite())
                .count()
                .max(1) as f64;
        println!(
            "reference ({}) {:.2} s, mean per-pixel standard error {:.4}",
            if uniform {
                "uniform sphere"
            } else {
                "cosine hemisphere"
            },
            t.elapsed().as_secs_f64(),
            se
        );
        write_png(
            &out.join(if uniform {
                "reference_uniform.png"
            } else {
                "reference.png"
            }),
            &reference,
        )
        .unwrap();
        let geometry = if uniform {
            GeometryTerm::Constant
        } else {
            GeometryTerm::Cosine
        };
        if !uniform {
            let local = render(
                &surf,
                vol.bounds(),
                &cam,
                &AmbientSource::None,
                &Shading {
                    phong: true,
                    ..Default::default()
                },
            );
            write_png(&out.join("local_phong.png"), &local).unwrap();
            for (name, sky) in [("overcast", Sky::Overcast), ("octant7", Sky::Octant(7))] {
                let model = AmbientModel::new(
                    AmbientOptions {
                        sky,
                        ..Default::default()
                    },
                    &vol.affine,
                );
                let img = render(
                    &surf,
                    vol.bounds(),
                    &cam,
                    &AmbientSource::Swept {
                        octants: &oct,
                        model: &model,
                    },
                    &shading,
                );
                write_png(&out.join(format!("swept_{name}.png")), &img).unwrap();
            }
        }
        for offset in [0.0, 0.5, 1.0, 1.5, 2.0, 3.0] {
            let model = AmbientModel::new(
                AmbientOptions {
                    geometry,
                    sky: Sky::Uniform,
                    gamma: 1.0,
                    offset,
                },
                &vol.affine,
            );
            let img = render(
                &surf,
                vol.bounds(),
                &cam,
                &AmbientSource::Swept {
                    octants: &oct,
                    model: &model,
                },
                &shading,
            );
            let e = rmse(&img, &reference);
            println!("geometry {geometry:?} offset {offset}: RMSE {e:.4}");
            write_png(
                &out.join(format!(
                    "swept_{}_c{}.png",
                    if uniform { "scalar" } else { "cosine" },
                    offset
                )),
                &img,
            )
            .unwrap();
        }
    }
}
