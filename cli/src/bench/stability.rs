//! `umbra bench stability -o <dir>`: scenes built to make the methods fail, each measured
//! against its Monte Carlo reference by [`accuracy`], with a verdict per row.

use super::accuracy::{accuracy, AccuracyArgs, Row};
use super::sweep::iso_accuracy;
use crate::output::out;
use crate::progress::Stages;
use scene::spec::Method;
use std::io::Write as _;
use std::path::{Path, PathBuf};

/// `umbra bench stability`.
#[derive(clap::Args)]
pub struct Args {
    /// Monte Carlo paths per pixel of the references.
    #[arg(long, default_value_t = 256)]
    reference_spp: u32,
    /// Frames timed per configuration (the median is its time).
    #[arg(long, default_value_t = 1)]
    frames: u32,
    /// Output folder: stability.csv, flicker.csv, scenes/ and one folder per case.
    #[arg(short, long)]
    output: PathBuf,
}

pub fn run(a: Args) -> Result<(), String> {
    let progress = Stages::new(true);
    let rows = stability(&a.output, a.reference_spp, a.frames, &|m| progress.stage(m))?;
    drop(progress);
    for (case, _, r) in &rows {
        out(format!(
            "{case:14} {:5} {:>10}  rmse {:.4}  {}",
            r.method,
            r.values.join(" "),
            r.rmse,
            verdict(r.rmse)
        ))?;
    }
    eprintln!("wrote {}/stability.csv", a.output.display());
    Ok(())
}

/// A stability case: a scene built to make methods fail, its sweeps and the methods run.
struct Case {
    name: &'static str,
    what: &'static str,
    scene: String,
    sweeps: Vec<(String, Vec<String>)>,
    methods: Vec<Method>,
}

/// Verdict on an RMSE against the reference: `ok` below 0.02, `degraded` below 0.05, `fails`.
pub fn verdict(rmse: f64) -> &'static str {
    if rmse < 0.02 {
        "ok"
    } else if rmse < 0.05 {
        "degraded"
    } else {
        "fails"
    }
}

/// Writes a scalar grid over [-10, 10]^3 (n^3 samples) as NRRD.
fn write_grid(path: &Path, n: usize, f: impl Fn(glam::DVec3) -> f64 + Sync) -> Result<(), String> {
    let affine = volume::synthetic::cube_affine([n, n, n], -10.0, 10.0);
    let vol = volume::synthetic::sample_scalar([n, n, n], affine, "v", f);
    volume::nrrd::write(path, &vol, &vol.fields[0], volume::nrrd::WriteEncoding::Raw)
        .map_err(|e| e.to_string())
}

/// `umbra bench stability -o <dir>`: scenes built to make the methods fail - volumes, tubes,
/// and occlusion sweeping on isosurfaces (against Monte Carlo AO, `method` = `sweep`, time =
/// the sweep's) - each measured against its reference; `<dir>/stability.csv` with a verdict per row
/// ([`verdict`]), and `<dir>/flicker.csv`: the occlusion AOV's frame-to-frame change while the
/// camera turns, against the reference's. Returns the rows with their case names.
pub fn stability(
    out: &Path,
    spp: u32,
    frames: u32,
    progress: &dyn Fn(&str),
) -> Result<Vec<(String, String, Row)>, String> {
    if spp == 0 || frames == 0 {
        return Err(format!(
            "--reference-spp {spp} --frames {frames}: each must be at least 1"
        ));
    }
    // The scenes written under `<out>/scenes` name their data by path, and a scene's paths
    // resolve against the scene's folder: a relative output folder must not reach them as is.
    let out = &std::path::absolute(out).map_err(|e| format!("{}: {e}", out.display()))?;
    let sdir = out.join("scenes");
    std::fs::create_dir_all(&sdir).map_err(|e| format!("{}: {e}", sdir.display()))?;
    // A sheet 0.3 units thick (z in [-0.15, 0.15]), a blob, and a block shadowing a floor.
    write_grid(&sdir.join("sheet.nrrd"), 81, |p| {
        (-(p.z / 0.15).powi(8)).exp()
    })?;
    // A sheet one sample thick (value 1 in the plane z = 0, samples 0.5 apart) over a floor
    // of value 0.5: with `peak` below, the sheet's interpolated edges pass the denser 0.5.
    write_grid(&sdir.join("peak.nrrd"), 41, |p| {
        if p.z.abs() < 0.01 {
            1.0
        } else if (-7.01..=-4.99).contains(&p.z) {
            0.5
        } else {
            0.0
        }
    })?;
    write_grid(&sdir.join("blob.nrrd"), 41, |p| {
        (-(p - glam::DVec3::new(1.0, -1.0, 0.5)).length_squared() / 20.0).exp()
    })?;
    write_grid(&sdir.join("shadow.nrrd"), 41, |p| {
        let block = p.x.abs() < 2.5 && p.y.abs() < 2.5 && (4.0..6.0).contains(&p.z);
        let floor = (-7.0..-5.0).contains(&p.z);
        if block || floor {
            1.0
        } else {
            0.0
        }
    })?;
    // Tube bundles along y: sparse (5 tubes 3 units apart) and dense (a 5 x 5 block 1.1 apart).
    let bundle = |name: &str, pts: Vec<(f32, f32)>| -> Result<(), String> {
        let mut sl = tubes::Streamlines::new();
        for (x, z) in pts {
            let line: Vec<glam::Vec3> = (0..=12)
                .map(|i| glam::Vec3::new(x, i as f32 * 1.5 - 9.0, z))
                .collect();
            sl.push(&line);
        }
        tubes::save(&sdir.join(name), &sl).map_err(|e| e.to_string())
    };
    bundle(
        "sparse.tck",
        (0..5).map(|i| (i as f32 * 3.0 - 6.0, 0.0)).collect(),
    )?;
    bundle(
        "dense.tck",
        (0..25)
            .map(|i| ((i % 5) as f32 * 1.1 - 2.2, (i / 5) as f32 * -1.1))
            .collect(),
    )?;
    let tube_scene = |file: &str, camera: &str| {
        format!(
            "background = [1.0, 1.0, 1.0]\n[camera]\n{camera}\n[[tubes]]\npath = \"{}\"\nradius = 0.5\ncolor = \"#d0d0d0\"\n[render]\ntheta = 45.0\nvicinity_distance = 2.0\n",
            sdir.join(file).display()
        )
    };
    let scene = |file: &str, camera: &str, tf: &str| {
        format!(
            "background = [1.0, 1.0, 1.0]\n[camera]\n{camera}\n[volume]\npath = \"{}\"\n[volume.transfer]\n{tf}\n",
            sdir.join(file).display()
        )
    };
    let dense = "points = [{ value = 0.1, color = [0.9, 0.8, 0.7], extinction = 0.0 }, { value = 0.5, color = [0.9, 0.8, 0.7], extinction = 1.5 }]";
    // Extinction peaking at 0.5, between the sheet's value and the empty space's: a feature of
    // the transfer function narrower than a voxel (docs/accuracy.md, "Where light samples a
    // voxel apart fail").
    let peak = "points = [{ value = 0.0, color = [0.9, 0.6, 0.3], extinction = 0.0 }, { value = 0.5, color = [0.9, 0.6, 0.3], extinction = 4.0 }, { value = 1.0, color = [0.9, 0.6, 0.3], extinction = 1.2 }]";
    let soft = "points = [{ value = 0.1, color = [0.8, 0.8, 0.9], extinction = 0.0 }, { value = 1.0, color = [0.8, 0.8, 0.9], extinction = 0.4 }]";
    let s = |v: &[&str]| v.iter().map(|x| x.to_string()).collect::<Vec<_>>();
    use Method::{Combined, Dos, Ea, Vicinity};
    let all = vec![Dos, Ea];
    let cases = vec![
        Case {
            name: "thin-sheet",
            what: "a sheet 0.3 units thick, slices 0.1 to 2 units apart",
            scene: scene("sheet.nrrd", "azimuth = 20.0\nelevation = 40.0", dense),
            sweeps: vec![("slice_distance".into(), s(&["0.1", "0.5", "1.0", "2.0"]))],
            methods: all.clone(),
        },
        Case {
            name: "grazing",
            what: "the same sheet seen almost edge-on (elevation 2 to 20 degrees)",
            scene: scene("sheet.nrrd", "azimuth = 20.0", dense),
            sweeps: vec![("camera.elevation".into(), s(&["2.0", "5.0", "20.0"]))],
            methods: all.clone(),
        },
        Case {
            name: "tf-peak",
            what: "a sheet one voxel thick whose transfer function peaks between its value and 0, light steps of 1 and 8 slices",
            scene: scene("peak.nrrd", "azimuth = 10.0\nelevation = 75.0", peak),
            sweeps: vec![("occlusion_step".into(), s(&["1", "8"]))],
            methods: vec![Dos],
        },
        Case {
            name: "few-slices",
            what: "a soft blob with 4 to 64 slices",
            scene: scene("blob.nrrd", "azimuth = 30.0\nelevation = 20.0", soft),
            sweeps: vec![("slices".into(), s(&["4", "8", "16", "64"]))],
            methods: all.clone(),
        },
        Case {
            name: "cone-extremes",
            what: "a block shadowing a floor, theta 2 to 80 degrees",
            scene: scene("shadow.nrrd", "azimuth = 30.0\nelevation = 50.0", dense),
            sweeps: vec![("cone".into(), s(&["2", "25", "60", "80"]))],
            methods: vec![Dos],
        },
        Case {
            name: "zoom",
            what: "the shadowed floor seen from 1.5 to 6 bounding radii (consistent occlusion?)",
            scene: scene("shadow.nrrd", "azimuth = 30.0\nelevation = 50.0", dense),
            sweeps: vec![("camera.distance".into(), s(&["1.5", "3.0", "6.0"]))],
            methods: vec![Dos],
        },
        Case {
            name: "bundles",
            what: "tubes alone, sparse (3 units apart) or dense (a 5 x 5 block 1.1 apart)",
            scene: tube_scene("sparse.tck", "azimuth = 10.0\nelevation = 60.0"),
            sweeps: vec![(
                "tubes.0.path".into(),
                vec![
                    format!("\"{}\"", sdir.join("sparse.tck").display()),
                    format!("\"{}\"", sdir.join("dense.tck").display()),
                ],
            )],
            methods: vec![Combined, Vicinity, Dos, Ea],
        },
        Case {
            name: "border",
            what: "the dense bundle in the middle of the image or cut by its border",
            scene: tube_scene(
                "dense.tck",
                "projection = \"orthographic\"\nheight = 14.0\neye = [0.0, 0.0, 40.0]\nup = [0.0, 1.0, 0.0]",
            ),
            sweeps: vec![(
                "camera.target".into(),
                s(&["[0.0, 0.0, 0.0]", "[6.0, 0.0, 0.0]"]),
            )],
            methods: vec![Combined, Vicinity],
        },
        Case {
            name: "rotation",
            what: "the camera turning in 0.5-degree steps (frame-to-frame change of the error)",
            scene: scene("shadow.nrrd", "elevation = 50.0", dense),
            sweeps: vec![(
                "camera.azimuth".into(),
                s(&["30.0", "30.5", "31.0", "31.5"]),
            )],
            methods: vec![Dos],
        },
    ];
    let mut all_rows = vec![];
    for c in &cases {
        let path = sdir.join(format!("{}.toml", c.name));
        volume::write_atomic(&path, c.scene.as_bytes()).map_err(|e| e.to_string())?;
        progress(c.name);
        let rows = accuracy(
            &AccuracyArgs {
                scene: path,
                overrides: vec!["render.width=96".into(), "render.height=96".into()],
                sweeps: c.sweeps.clone(),
                methods: c.methods.clone(),
                spp,
                frames,
                out: out.join(c.name),
            },
            &|m| progress(&format!("{}: {m}", c.name)),
        )?
        .rows;
        for mut r in rows {
            // A path as its file name.
            for v in &mut r.values {
                if v.contains('/') {
                    let t = v.trim_matches('"');
                    *v = Path::new(t)
                        .file_name()
                        .map_or(t.to_string(), |n| n.to_string_lossy().to_string());
                }
                *v = v.replace(',', " ");
            }
            all_rows.push((c.name.to_string(), c.what.to_string(), r));
        }
    }
    // Frame-to-frame flicker of the occlusion AOV while the camera turns: the mean change of
    // the volumetric AOV between consecutive steps, against the reference's own change (the
    // scene does move); <out>/flicker.csv.
    let turning: Vec<&Row> = all_rows
        .iter()
        .filter(|r| r.0 == "rotation")
        .map(|r| &r.2)
        .collect();
    let mut flicker = Vec::new();
    let _ = writeln!(flicker, "from,to,aov_change,reference_change,excess");
    for pair in turning.windows(2) {
        let change = |a: &[f64], b: &[f64]| {
            let d: Vec<f64> = a
                .iter()
                .zip(b)
                .filter(|(x, y)| x.is_finite() && y.is_finite())
                .map(|(x, y)| (x - y).abs())
                .collect();
            d.iter().sum::<f64>() / d.len().max(1) as f64
        };
        let g = change(&pair[0].aov_volumetric, &pair[1].aov_volumetric);
        let r = change(&pair[0].ref_volumetric, &pair[1].ref_volumetric);
        let _ = writeln!(
            flicker,
            "{},{},{:.6},{:.6},{:.6}",
            pair[0].values.join(" "),
            pair[1].values.join(" "),
            g,
            r,
            g - r
        );
    }
    volume::write_atomic(&out.join("flicker.csv"), &flicker).map_err(|e| e.to_string())?;
    // Occlusion sweeping's failure modes on isosurfaces: walls at an angle to the grid (the
    // paper's diagonal artifacts) and sharp edges (its glow), against Monte Carlo AO.
    let boxed = |angle: f64, round: f64| {
        let (c, s) = (angle.to_radians().cos(), angle.to_radians().sin());
        move |p: glam::DVec3| {
            let q = glam::DVec3::new(c * p.x + s * p.y, -s * p.x + c * p.y, p.z);
            let d = q.abs() - glam::DVec3::splat(5.0 - round);
            let outside = d.max(glam::DVec3::ZERO).length() + d.max_element().min(0.0) - round;
            -outside
        }
    };
    let iso_cases: [(&str, &str, &str, f64, f64); 5] = [
        (
            "iso-walls",
            "a box's walls at 0, 30 and 45 degrees to the grid",
            "0",
            0.0,
            0.0,
        ),
        ("iso-walls", "", "30", 30.0, 0.0),
        ("iso-walls", "", "45", 45.0, 0.0),
        (
            "iso-edges",
            "a box with sharp or rounded (radius 2) edges",
            "sharp",
            20.0,
            0.0,
        ),
        ("iso-edges", "", "rounded", 20.0, 2.0),
    ];
    for (name, what, setting, angle, round) in iso_cases {
        progress(name);
        let affine = volume::synthetic::cube_affine([48, 48, 48], -10.0, 10.0);
        let vol = volume::synthetic::sample_scalar([48, 48, 48], affine, "v", boxed(angle, round));
        let (ms, r) = iso_accuracy(&vol, spp as usize, 96, 30.0, &[Default::default()])?;
        let (e, se) = r[0];
        all_rows.push((
            name.to_string(),
            what.to_string(),
            Row {
                method: "sweep".into(),
                values: vec![setting.to_string()],
                ms,
                rmse: e,
                max_err: f64::NAN,
                psnr: 10.0 * (1.0 / (e * e).max(1e-20)).log10(),
                ssim: f64::NAN,
                ref_stderr: se,
                rmse_volumetric: f64::NAN,
                rmse_surface: f64::NAN,
                rmse_vicinity: f64::NAN,
                bias: f64::NAN,
                aov_volumetric: vec![],
                ref_volumetric: vec![],
            },
        ));
    }
    let mut csv = Vec::new();
    let _ = writeln!(
        csv,
        "case,method,setting,ms,rmse,max_err,psnr,ssim,ref_stderr,verdict"
    );
    for (name, _, r) in &all_rows {
        let _ = writeln!(
            csv,
            "{name},{},{},{},{}",
            r.method,
            r.values.join(" "),
            r.measured(),
            verdict(r.rmse)
        );
    }
    volume::write_atomic(&out.join("stability.csv"), &csv).map_err(|e| e.to_string())?;
    Ok(all_rows)
}
