//! `umbra bench accuracy <scene.toml> --sweep KEY=V1,V2 ... --methods M1,M2 -o <dir>`: every
//! method at every combination of the swept settings, timed on the GPU and compared with the
//! Monte Carlo ground truth of the same light model (`reference`), written as
//! `<dir>/results.csv` and charted (error against time, one series per method, the Pareto front
//! marked) as `<dir>/pareto.svg` and `<dir>/pareto.png`.
//!
//! * Sweep keys: `slices` (render.slices), `cone` (render.theta, degrees), any other
//!   `render.*` key by its name, or any dotted scene key.
//! * The reference is the directional-occlusion ground truth for each cone angle (the `ea`
//!   method is measured against it too: its error is the occlusion it leaves out), cached as
//!   `<dir>/reference/<hash>.exr` (linear RGB and the per-pixel standard error as channel
//!   `stderr`), the hash over the scene without the settings that do not change the ground
//!   truth, and the samples per pixel.
//! * Metrics on linear colour clamped to [0, 1]: RMSE and largest error over all channels,
//!   PSNR with peak 1, SSIM of the luminance (Gaussian window, sigma 1.5, radius 5; C1 =
//!   0.01^2, C2 = 0.03^2). `ms` is the renderer's `total_ms` (median frame). On the occlusion
//!   AOVs: the RMSE of the volumetric term against the reference's mean occlusion at volume
//!   collisions (pixels with some opacity), and of the combined term against the reference's
//!   mean cone transmittance at the first tube surface (covered surface pixels), and of the
//!   vicinity term against the geometry-only cone visibility within l_vicinity there. A
//!   per-pixel error image per configuration: `<dir>/errors/<method>_<values>.png`
//!   (|colour - reference|, largest channel, 0.25 white).
//! * The reference follows `render.geometry_shadow`: the tubes' real thickness, or the
//!   paper's endless column behind them. Not yet: FLIP; scenes in isosurface mode (refused).

use super::chart::{write_chart, Plot};
use super::metrics::{fnv, metrics, pareto};
use crate::commands::Method as MethodArg;
use crate::output::out;
use crate::progress::Stages;
use occlusion::reference::{self, RefSettings, RefVolume};
use scene::compile;
use scene::image_io::RefImageExr as _;
use scene::spec::{self, Method};
use std::io::Write as _;
use std::path::PathBuf;

/// `umbra bench accuracy`.
#[derive(clap::Args)]
pub struct Args {
    /// Scene file: a volume, tubes or both (the reference traces both; not isosurface mode).
    scene: PathBuf,
    /// KEY=V1,V2,... (repeatable): slices, cone (degrees), a render.* key by name, or a
    /// dotted scene key.
    #[arg(long = "sweep", value_name = "KEY=VALUES", value_parser = parse_sweep)]
    sweeps: Vec<(String, Vec<String>)>,
    /// Methods, comma-separated.
    #[arg(
        long,
        value_enum,
        value_delimiter = ',',
        default_value = "combined,dos,vicinity,ea",
        hide_possible_values = true
    )]
    methods: Vec<MethodArg>,
    /// Monte Carlo paths per pixel of the reference.
    #[arg(long, default_value_t = 256)]
    reference_spp: u32,
    /// Frames timed per configuration (the median is its time).
    #[arg(long, default_value_t = 3)]
    frames: u32,
    /// Override a scene key by its dotted path (repeatable).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    set: Vec<String>,
    /// Output folder.
    #[arg(short, long)]
    output: PathBuf,
}

pub fn run(a: Args) -> Result<(), String> {
    let mut overrides = vec![
        "render.width=128".to_string(),
        "render.height=128".to_string(),
    ];
    overrides.extend(a.set);
    let progress = Stages::new(true);
    let report = accuracy(
        &AccuracyArgs {
            scene: a.scene,
            overrides,
            sweeps: a.sweeps,
            methods: a.methods.into_iter().map(Method::from).collect(),
            spp: a.reference_spp,
            frames: a.frames,
            out: a.output.clone(),
        },
        &|m| progress.stage(m),
    )?;
    drop(progress);
    for r in &report.rows {
        out(format!(
            "{:9} {:>16} {:9.1} ms  rmse {:.5}  psnr {:6.2}  ssim {:.4}  bias {:+.5}",
            r.method,
            r.values.join(" "),
            r.ms,
            r.rmse,
            r.psnr,
            r.ssim,
            r.bias
        ))?;
    }
    eprintln!(
        "references: {} traced, {} from the cache",
        report.references_traced, report.references_cached
    );
    eprintln!(
        "wrote {0}/results.csv, {0}/pareto.svg, {0}/pareto.png",
        a.output.display()
    );
    Ok(())
}

/// What `umbra bench accuracy` is asked to do.
#[derive(Clone, Debug)]
pub struct AccuracyArgs {
    pub scene: PathBuf,
    pub overrides: Vec<String>,
    /// `(key, values)`, in order.
    pub sweeps: Vec<(String, Vec<String>)>,
    pub methods: Vec<Method>,
    pub spp: u32,
    pub frames: u32,
    pub out: PathBuf,
}

/// One row of results.csv.
#[derive(Clone, Debug)]
pub struct Row {
    pub method: String,
    pub values: Vec<String>,
    pub ms: f64,
    pub rmse: f64,
    pub max_err: f64,
    pub psnr: f64,
    pub ssim: f64,
    /// Mean standard error of the reference over the pixels.
    pub ref_stderr: f64,
    /// RMSE of the volumetric-occlusion AOV against the reference's (pixels where both
    /// have volume), and of the combined AOV on surfaces against the reference's surface
    /// occlusion (pixels where both have a tube); NaN where there are none.
    pub rmse_volumetric: f64,
    pub rmse_surface: f64,
    /// RMSE of the vicinity AOV on surfaces against the geometry-only cone visibility within
    /// l_vicinity.
    pub rmse_vicinity: f64,
    /// The signed mean error: colour minus reference, the mean of the channels, over the
    /// pixels where the reference is off the background ([`signed_bias`]); positive where
    /// the renderer is brighter.
    pub bias: f64,
    /// The renderer's volumetric AOV and the reference's (NaN where undefined), for
    /// frame-to-frame comparisons.
    pub aov_volumetric: Vec<f64>,
    pub ref_volumetric: Vec<f64>,
}

/// The mean of `img - reference` (the mean of the three channels) over the pixels where the
/// reference differs from the background `bg` (the channels' absolute differences summing to
/// more than 0.01, as `bench/exr_bias.py` takes them); NaN where there are none. Positive: the
/// image is brighter than the reference.
pub fn signed_bias(img: &[[f64; 3]], reference: &[[f64; 3]], bg: [f64; 3]) -> f64 {
    let (mut sum, mut n) = (0.0, 0usize);
    for (p, q) in img.iter().zip(reference) {
        if (0..3).map(|k| (q[k] - bg[k]).abs()).sum::<f64>() > 0.01 {
            let d = (0..3).map(|k| p[k] - q[k]).sum::<f64>() / 3.0;
            if d.is_finite() {
                sum += d;
                n += 1;
            }
        }
    }
    if n == 0 {
        f64::NAN
    } else {
        sum / n as f64
    }
}

impl Row {
    /// The measured columns shared by results.csv and stability.csv:
    /// `ms,rmse,max_err,psnr,ssim,ref_stderr`.
    pub fn measured(&self) -> String {
        format!(
            "{:.3},{:.6},{:.6},{:.3},{:.5},{:.6}",
            self.ms, self.rmse, self.max_err, self.psnr, self.ssim, self.ref_stderr
        )
    }
}

/// The scene key a sweep key sets.
pub fn sweep_key(k: &str) -> String {
    match k {
        "slices" => "render.slices".into(),
        "cone" | "theta" => "render.theta".into(),
        k if k.contains('.') => k.into(),
        k => format!("render.{k}"),
    }
}

/// Parses `--sweep KEY=V1,V2,...` (`KEY=[..];[..]` when the values are arrays).
pub fn parse_sweep(s: &str) -> Result<(String, Vec<String>), String> {
    let (k, v) = s
        .split_once('=')
        .ok_or_else(|| "expected KEY=V1,V2,...".to_string())?;
    let sep = if v.contains('[') { ';' } else { ',' };
    let vals: Vec<String> = v
        .split(sep)
        .map(|x| x.trim().to_string())
        .filter(|x| !x.is_empty())
        .collect();
    if k.trim().is_empty() || vals.is_empty() {
        return Err("expected KEY=V1,V2,...".into());
    }
    Ok((k.trim().to_string(), vals))
}

/// What `accuracy` measured, and how many references it traced or found in the cache.
#[derive(Clone, Debug, Default)]
pub struct AccuracyReport {
    pub rows: Vec<Row>,
    pub references_traced: usize,
    pub references_cached: usize,
}

/// Runs `umbra bench accuracy`: the rows written to results.csv, and the references traced and
/// found in the cache.
pub fn accuracy(a: &AccuracyArgs, progress: &dyn Fn(&str)) -> Result<AccuracyReport, String> {
    if a.spp == 0 || a.frames == 0 {
        return Err(format!(
            "--reference-spp {} --frames {}: each must be at least 1",
            a.spp, a.frames
        ));
    }
    spec::load(&a.scene, &a.overrides)?;
    // One sweep a key (its aliases counted as the key: `cone` and `theta` are
    // `render.theta`), each value once: a second sweep of a key overrode the first while its
    // rows kept the first's values, and repeated values overwrote their error images.
    for (i, (k, vals)) in a.sweeps.iter().enumerate() {
        if let Some((k2, _)) = a.sweeps[..i]
            .iter()
            .find(|(k2, _)| sweep_key(k2) == sweep_key(k))
        {
            return Err(format!(
                "--sweep {k}: the same key as --sweep {k2} ({}); sweep a key once, with all its values",
                sweep_key(k)
            ));
        }
        if let Some((_, v)) = vals
            .iter()
            .enumerate()
            .find(|(j, v)| vals[..*j].contains(v))
        {
            return Err(format!("--sweep {k}: the value {v} is given twice"));
        }
    }
    let methods = &a.methods;
    // Every combination of the swept values.
    let mut combos: Vec<Vec<String>> = vec![vec![]];
    for (_, vals) in &a.sweeps {
        combos = combos
            .into_iter()
            .flat_map(|c| {
                vals.iter().map(move |v| {
                    let mut c = c.clone();
                    c.push(v.clone());
                    c
                })
            })
            .collect();
    }
    let overrides = |combo: &[String]| {
        let mut over = a.overrides.clone();
        for ((k, _), v) in a.sweeps.iter().zip(combo) {
            over.push(format!("{}={v}", sweep_key(k)));
        }
        over
    };
    // Every combination's scene is checked before anything is written (a swept key that does
    // not exist, a value out of range, what the reference cannot model).
    for combo in &combos {
        let s = spec::load(&a.scene, &overrides(combo))?;
        if s.volume.as_ref().is_some_and(|v| v.iso.is_some()) {
            return Err(format!(
                "{}: the Monte Carlo reference does not model isosurfaces yet",
                a.scene.display()
            ));
        }
        if !(s.lines.is_empty() && s.points.is_empty()) {
            return Err(format!(
                "{}: the Monte Carlo reference does not model [[lines]] or [[points]] yet",
                a.scene.display()
            ));
        }
    }
    std::fs::create_dir_all(a.out.join("reference"))
        .map_err(|e| format!("{}: {e}", a.out.display()))?;
    let gpu = engine::gpu::Gpu::new().map_err(|e| e.to_string())?;
    let mut report = AccuracyReport::default();
    let mut rows = vec![];
    for combo in &combos {
        let over = overrides(combo);
        let s = spec::load(&a.scene, &over)?;
        // Checked above: no isosurface, no line or point sets.
        let m = compile::model(&s).map_err(|e| format!("{}: {e}", a.scene.display()))?;
        // Without a volume the reference sees an empty one (all transparent).
        let empty;
        let (vol, data, tf) = match m.volume.as_ref() {
            Some((v, d, t)) => (v, d.to_f32(), t),
            None => {
                let [lo, hi] = m.bounds;
                let affine = glam::DMat4::from_cols(
                    glam::DVec4::new(hi.x - lo.x, 0.0, 0.0, 0.0),
                    glam::DVec4::new(0.0, hi.y - lo.y, 0.0, 0.0),
                    glam::DVec4::new(0.0, 0.0, hi.z - lo.z, 0.0),
                    lo.extend(1.0),
                );
                let field = volume::Field {
                    name: "empty".into(),
                    components: 1,
                    stored: volume::ScalarType::F32,
                    data: vec![0.0; 8],
                };
                let v = volume::Volume::new([2, 2, 2], affine, volume::Space::File, field)
                    .map_err(|e| e.to_string())?;
                empty = (
                    v,
                    vec![0.0f32; 8],
                    occlusion::emission_absorption::Transfer {
                        points: vec![(0.0, [0.0; 3], 0.0)],
                        rows: vec![],
                    },
                );
                (&empty.0, std::borrow::Cow::Borrowed(&empty.1[..]), &empty.2)
            }
        };
        let view = compile::view(&s, &m)?;
        // The reference for this combination's light model: keyed by what it depends on
        // (the scene but for how a method approximates it) and by the data itself.
        let key = serde_json::to_string(&s.reference_key()).map_err(|e| e.to_string())?;
        let hash = fnv(format!("{key}|data={:016x}|spp={}", m.data_hash(), a.spp).as_bytes());
        let rpath = a.out.join("reference").join(format!("{hash:016x}.exr"));
        let (w, h) = (view.width as usize, view.height as usize);
        let cached = reference::RefImage::read_exr(&rpath).filter(|r| r.rgb.len() == w * h);
        let reference = match cached {
            Some(r) => {
                report.references_cached += 1;
                r
            }
            None => {
                progress(&format!(
                    "reference {} ({w} x {h}, {} spp, cone {} degrees)",
                    rpath.display(),
                    a.spp,
                    s.render.theta
                ));
                let tube_scene =
                    occlusion::reference_tubes::TubeScene::new(&m.meshes, &compile::tube_clip(&s));
                let l = &s.light;
                let column = (s.render.geometry_shadow == spec::GeometryShadow::Column
                    && !tube_scene.is_empty())
                .then(|| reference::ColumnMap::new(&tube_scene, &view, 4));
                let tubes = (!tube_scene.is_empty()).then_some(reference::RefTubes {
                    scene: &tube_scene,
                    sigma: s.render.geometry_extinction,
                    light: [l.ambient, l.diffuse, l.specular, l.shininess],
                    column: column.as_ref(),
                });
                let img = reference::render(
                    &RefVolume {
                        vol,
                        data: &data,
                        tf,
                    },
                    tubes.as_ref(),
                    &view,
                    &RefSettings {
                        theta_deg: Some(s.render.theta),
                        spp: a.spp,
                        seed: hash,
                        vicinity_range: Some(s.render.vicinity_distance),
                    },
                );
                img.write_exr(&rpath)?;
                report.references_traced += 1;
                img
            }
        };
        let reference::RefImage {
            rgb: ref_rgb,
            stderr: ref_se,
            volumetric: ref_vol,
            surface: ref_surf,
            vicinity: ref_vic,
            ..
        } = reference;
        let ref_stderr = ref_se.iter().sum::<f64>() / ref_se.len().max(1) as f64;
        // One upload per combination (its settings may change the data); every method's
        // frames reuse it and the pipelines the device has compiled.
        let up = compile::upload(&gpu, &m)?;
        for &method in methods {
            let mut sm = s.clone();
            sm.render.method = method;
            let name = format!("{method:?}").to_lowercase();
            progress(&format!("{name} {}", combo.join(" ")));
            let opts = engine::renderer::DrawOptions {
                frames: a.frames.max(1),
                pass_timings: false,
            };
            let (out, _) = up.draw(&sm, &m, opts)?;
            let img: Vec<[f64; 3]> = out
                .image
                .iter()
                .map(|p| [p[0] as f64, p[1] as f64, p[2] as f64])
                .collect();
            let [rmse, max_err, psnr, ssim] = metrics(&img, &ref_rgb, w, h);
            let bias = signed_bias(&img, &ref_rgb, view.background);
            // The occlusion AOVs where both the renderer and the reference have a value: the
            // volumetric term where the volume is seen (some opacity), the combined term on
            // surfaces (coverage 1, a tube hit).
            let aov_rmse = |pick: &dyn Fn(usize) -> Option<(f64, f64)>| {
                let (mut se, mut n) = (0.0, 0usize);
                for i in 0..w * h {
                    if let Some((a, b)) = pick(i) {
                        if a.is_finite() && b.is_finite() {
                            se += (a - b) * (a - b);
                            n += 1;
                        }
                    }
                }
                if n == 0 {
                    f64::NAN
                } else {
                    (se / n as f64).sqrt()
                }
            };
            let rmse_volumetric = aov_rmse(&|i| {
                (out.image[i][3] > 0.05 && out.aov[i].depth > 0.0)
                    .then(|| (out.aov[i].volumetric as f64, ref_vol[i]))
            });
            let rmse_surface = aov_rmse(&|i| {
                (out.image[i][3] >= 1.0 && out.aov[i].depth > 0.0 && !ref_surf[i].is_nan())
                    .then(|| (out.aov[i].combined as f64, ref_surf[i]))
            });
            let rmse_vicinity = aov_rmse(&|i| {
                (out.image[i][3] >= 1.0 && out.aov[i].depth > 0.0 && !ref_vic[i].is_nan())
                    .then(|| (out.aov[i].vicinity as f64, ref_vic[i]))
            });
            // The per-pixel error image of this configuration: |colour - reference|, the
            // largest channel, linear, as 8-bit grey scaled so that 0.25 is white.
            let errs: Vec<[f32; 3]> = img
                .iter()
                .zip(&ref_rgb)
                .map(|(p, q)| {
                    let e = (0..3)
                        .map(|k| (p[k].clamp(0.0, 1.0) - q[k].clamp(0.0, 1.0)).abs())
                        .fold(0.0, f64::max);
                    [(e * 4.0).min(1.0) as f32; 3]
                })
                .collect();
            let stem = std::iter::once(name.clone())
                .chain(combo.iter().map(|v| {
                    v.chars()
                        .map(|c| {
                            if c.is_ascii_alphanumeric() || c == '.' {
                                c
                            } else {
                                '_'
                            }
                        })
                        .collect()
                }))
                .collect::<Vec<String>>()
                .join("_");
            std::fs::create_dir_all(a.out.join("errors")).map_err(|e| e.to_string())?;
            scene::image_io::write_rgb_png(
                &a.out.join("errors").join(format!("{stem}.png")),
                w,
                h,
                &errs,
            )?;
            rows.push(Row {
                method: name,
                values: combo.clone(),
                ms: out.timings.total_ms,
                rmse,
                max_err,
                psnr,
                ssim,
                ref_stderr,
                rmse_volumetric,
                rmse_surface,
                rmse_vicinity,
                bias,
                aov_volumetric: (0..w * h)
                    .map(|i| {
                        if out.image[i][3] > 0.05 {
                            out.aov[i].volumetric as f64
                        } else {
                            f64::NAN
                        }
                    })
                    .collect(),
                ref_volumetric: ref_vol.clone(),
            });
        }
    }
    // results.csv
    let mut csv = Vec::new();
    let keys: Vec<&str> = a.sweeps.iter().map(|(k, _)| k.as_str()).collect();
    let _ = writeln!(
        csv,
        "method{}{},ms,rmse,max_err,psnr,ssim,ref_stderr,rmse_volumetric,rmse_surface,rmse_vicinity,bias",
        if keys.is_empty() { "" } else { "," },
        keys.join(",")
    );
    let quote = |v: &String| {
        if v.contains(',') {
            format!("\"{v}\"")
        } else {
            v.clone()
        }
    };
    for r in &rows {
        let _ = writeln!(
            csv,
            "{}{}{},{},{:.6},{:.6},{:.6},{:.6}",
            r.method,
            if r.values.is_empty() { "" } else { "," },
            r.values.iter().map(quote).collect::<Vec<_>>().join(","),
            r.measured(),
            r.rmse_volumetric,
            r.rmse_surface,
            r.rmse_vicinity,
            r.bias
        );
    }
    volume::write_atomic(&a.out.join("results.csv"), &csv).map_err(|e| e.to_string())?;
    // The chart: a series per method and non-numeric swept value (e.g. "dos cone").
    let series = |r: &Row| {
        std::iter::once(r.method.clone())
            .chain(
                r.values
                    .iter()
                    .filter(|v| v.parse::<f64>().is_err())
                    .cloned(),
            )
            .collect::<Vec<_>>()
            .join(" ")
    };
    let mut names: Vec<String> = rows.iter().map(series).collect();
    names.sort();
    names.dedup();
    let pts: Vec<(f64, f64)> = rows.iter().map(|r| (r.ms, r.rmse)).collect();
    write_chart(
        &a.out,
        "pareto",
        &Plot {
            title: format!(
                "{}: error against time",
                a.scene.file_name().unwrap_or_default().to_string_lossy()
            ),
            x_label: "frame time (ms, median)".into(),
            y_label: "RMSE against the Monte Carlo reference".into(),
            series: names
                .iter()
                .map(|n| {
                    let p = rows
                        .iter()
                        .filter(|r| series(r) == *n)
                        .map(|r| (r.ms, r.rmse))
                        .collect();
                    (n.clone(), p)
                })
                .collect(),
            line: Some((
                "Pareto front".into(),
                pareto(&pts).into_iter().map(|i| pts[i]).collect(),
            )),
        },
    )?;
    report.rows = rows;
    Ok(report)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sweeps_parse_and_name_their_keys() {
        assert_eq!(
            parse_sweep("slices=64,128").unwrap(),
            ("slices".into(), vec!["64".into(), "128".into()])
        );
        assert!(parse_sweep("slices").is_err() && parse_sweep("=1").is_err());
        assert_eq!(
            parse_sweep("camera.target=[0, 0, 0];[7,0,0]").unwrap().1,
            vec!["[0, 0, 0]".to_string(), "[7,0,0]".to_string()]
        );
        assert_eq!(sweep_key("cone"), "render.theta");
        assert_eq!(sweep_key("slices"), "render.slices");
        assert_eq!(sweep_key("occlusion_cell"), "render.occlusion_cell");
        assert_eq!(sweep_key("light.ambient"), "light.ambient");
    }
}
