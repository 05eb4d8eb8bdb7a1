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

use crate::reference::{self, RefSettings, RefVolume};
use crate::render_cmd;
use crate::scene::{self, Method};
use std::io::Write as _;
use std::path::{Path, PathBuf};

/// What `umbra bench accuracy` is asked to do.
#[derive(Clone, Debug)]
pub struct AccuracyArgs {
    pub scene: PathBuf,
    pub overrides: Vec<String>,
    /// `(key, values)`, in order.
    pub sweeps: Vec<(String, Vec<String>)>,
    pub methods: Vec<String>,
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
    /// The renderer's volumetric AOV and the reference's (NaN where undefined), for
    /// frame-to-frame comparisons.
    pub aov_volumetric: Vec<f64>,
    pub ref_volumetric: Vec<f64>,
}

impl Row {
    /// The measured columns shared by results.csv and stability.csv:
    /// `ms,rmse,max_err,psnr,ssim,ref_stderr`.
    fn measured(&self) -> String {
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

/// Parses `KEY=V1,V2,...` (`KEY=[..];[..]` when the values are arrays).
pub fn parse_sweep(s: &str) -> Result<(String, Vec<String>), String> {
    let (k, v) = s
        .split_once('=')
        .ok_or_else(|| format!("--sweep {s}: expected KEY=V1,V2,..."))?;
    let sep = if v.contains('[') { ';' } else { ',' };
    let vals: Vec<String> = v
        .split(sep)
        .map(|x| x.trim().to_string())
        .filter(|x| !x.is_empty())
        .collect();
    if k.trim().is_empty() || vals.is_empty() {
        return Err(format!("--sweep {s}: expected KEY=V1,V2,..."));
    }
    Ok((k.trim().to_string(), vals))
}

/// FNV-1a, 64 bits: the reference cache's key.
fn fnv(bytes: &[u8]) -> u64 {
    let mut h = 0xcbf2_9ce4_8422_2325u64;
    for b in bytes {
        h ^= *b as u64;
        h = h.wrapping_mul(0x0100_0000_01b3);
    }
    h
}

/// Luminance of linear RGB.
fn luma(c: [f64; 3]) -> f64 {
    0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]
}

/// Mean SSIM of two single-channel images (Gaussian window sigma 1.5, radius 5).
pub fn ssim(a: &[f64], b: &[f64], w: usize, h: usize) -> f64 {
    let r = 5i64;
    let g: Vec<f64> = (-r..=r).map(|i| (-(i * i) as f64 / 4.5).exp()).collect();
    // One 1-D pass of the normalised window along x (stride 1, length w) or y (stride w,
    // length h), the window cut at the border.
    let pass = |x: &[f64], along_x: bool| -> Vec<f64> {
        let mut out = vec![0.0; w * h];
        for y in 0..h {
            for xx in 0..w {
                let (pos, len) = if along_x { (xx, w) } else { (y, h) };
                let (mut s, mut n) = (0.0, 0.0);
                for (k, gk) in g.iter().enumerate() {
                    let i = pos as i64 + k as i64 - r;
                    if i >= 0 && i < len as i64 {
                        let idx = if along_x {
                            i as usize + w * y
                        } else {
                            xx + w * i as usize
                        };
                        s += gk * x[idx];
                        n += gk;
                    }
                }
                out[xx + w * y] = s / n;
            }
        }
        out
    };
    let blur = |x: &[f64]| pass(&pass(x, true), false);
    let prod = |x: &[f64], y: &[f64]| x.iter().zip(y).map(|(p, q)| p * q).collect::<Vec<_>>();
    let (ma, mb) = (blur(a), blur(b));
    let (saa, sbb, sab) = (blur(&prod(a, a)), blur(&prod(b, b)), blur(&prod(a, b)));
    let (c1, c2) = (1e-4, 9e-4);
    let mut total = 0.0;
    for i in 0..w * h {
        let (va, vb) = (saa[i] - ma[i] * ma[i], sbb[i] - mb[i] * mb[i]);
        let cov = sab[i] - ma[i] * mb[i];
        total += ((2.0 * ma[i] * mb[i] + c1) * (2.0 * cov + c2))
            / ((ma[i] * ma[i] + mb[i] * mb[i] + c1) * (va + vb + c2));
    }
    total / (w * h) as f64
}

/// RMSE, largest error, PSNR and SSIM of `img` against `reference` (linear, clamped to [0, 1]).
pub fn metrics(img: &[[f64; 3]], reference: &[[f64; 3]], w: usize, h: usize) -> [f64; 4] {
    let c = |v: f64| v.clamp(0.0, 1.0);
    let (mut se, mut mx) = (0.0, 0.0f64);
    for (p, q) in img.iter().zip(reference) {
        for k in 0..3 {
            let d = c(p[k]) - c(q[k]);
            se += d * d;
            mx = mx.max(d.abs());
        }
    }
    let mse = se / (3 * img.len()).max(1) as f64;
    let la: Vec<f64> = img.iter().map(|p| luma(p.map(c))).collect();
    let lb: Vec<f64> = reference.iter().map(|p| luma(p.map(c))).collect();
    [
        mse.sqrt(),
        mx,
        10.0 * (1.0 / mse.max(1e-20)).log10(),
        ssim(&la, &lb, w, h),
    ]
}

/// The Pareto front of (ms, rmse) points: indices of the points no other is at least as good
/// on both and better on one, by increasing time.
pub fn pareto(points: &[(f64, f64)]) -> Vec<usize> {
    let mut idx: Vec<usize> = (0..points.len()).collect();
    idx.sort_by(|&a, &b| {
        points[a]
            .0
            .total_cmp(&points[b].0)
            .then(points[a].1.total_cmp(&points[b].1))
    });
    let mut front = vec![];
    let mut best = f64::INFINITY;
    for i in idx {
        if points[i].1 < best {
            best = points[i].1;
            front.push(i);
        }
    }
    front
}

const FONT: &[u8] = include_bytes!("../assets/DejaVuSans.ttf");

/// A log-log scatter chart: named point series and an optional line (e.g. a Pareto front).
pub struct Plot {
    pub title: String,
    pub x_label: String,
    pub y_label: String,
    pub series: Vec<(String, Vec<(f64, f64)>)>,
    pub line: Option<(String, Vec<(f64, f64)>)>,
}

fn draw<DB: plotters::prelude::DrawingBackend>(
    root: plotters::prelude::DrawingArea<DB, plotters::coord::Shift>,
    p: &Plot,
) -> Result<(), String>
where
    DB::ErrorType: 'static,
{
    use plotters::prelude::*;
    let err = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
    root.fill(&WHITE).map_err(err)?;
    let all = p.series.iter().flat_map(|s| s.1.iter());
    let (x0, x1, y0, y1) = all.fold(
        (f64::INFINITY, 0.0f64, f64::INFINITY, 0.0f64),
        |(a, b, c, d), q| (a.min(q.0), b.max(q.0), c.min(q.1), d.max(q.1)),
    );
    if !(x0.is_finite() && y0.is_finite()) {
        return Err("nothing to chart".into());
    }
    let (x0, x1) = ((x0 * 0.8).max(1e-9), (x1 * 1.25).max(x0 * 2.0));
    let (y0, y1) = ((y0 * 0.8).max(1e-9), (y1 * 1.25).max(y0 * 2.0));
    let mut c = ChartBuilder::on(&root)
        .caption(&p.title, ("sans-serif", 18))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d((x0..x1).log_scale(), (y0..y1).log_scale())
        .map_err(err)?;
    c.configure_mesh()
        .x_desc(p.x_label.as_str())
        .y_desc(p.y_label.as_str())
        .draw()
        .map_err(err)?;
    for (i, (name, pts)) in p.series.iter().enumerate() {
        let col = Palette99::pick(i).to_rgba();
        c.draw_series(pts.iter().map(|q| Circle::new(*q, 4, col.filled())))
            .map_err(err)?
            .label(name.clone())
            .legend(move |(x, y)| Circle::new((x, y), 4, col.filled()));
    }
    if let Some((name, pts)) = &p.line {
        c.draw_series(LineSeries::new(pts.clone(), BLACK.stroke_width(1)))
            .map_err(err)?
            .label(name.clone())
            .legend(|(x, y)| PathElement::new(vec![(x - 8, y), (x + 8, y)], BLACK));
    }
    c.configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()
        .map_err(err)?;
    root.present().map_err(err)?;
    Ok(())
}

/// Writes `p` as `<dir>/<stem>.svg` and `<dir>/<stem>.png` (800 x 560).
pub fn write_chart(dir: &Path, stem: &str, p: &Plot) -> Result<(), String> {
    plotters::style::register_font("sans-serif", plotters::style::FontStyle::Normal, FONT)
        .map_err(|_| "the chart font does not load".to_string())?;
    let mut text = String::new();
    {
        let root = plotters::prelude::SVGBackend::with_string(&mut text, (800, 560));
        draw(
            plotters::prelude::IntoDrawingArea::into_drawing_area(root),
            p,
        )?;
    }
    volume::write_atomic(&dir.join(format!("{stem}.svg")), text.as_bytes())
        .map_err(|e| e.to_string())?;
    let mut px = vec![0u8; 800 * 560 * 3];
    {
        let root = plotters::prelude::BitMapBackend::with_buffer(&mut px, (800, 560));
        draw(
            plotters::prelude::IntoDrawingArea::into_drawing_area(root),
            p,
        )?;
    }
    let png: image::RgbImage = image::RgbImage::from_raw(800, 560, px).ok_or("chart buffer")?;
    let mut bytes = Vec::new();
    png.write_to(
        &mut std::io::Cursor::new(&mut bytes),
        image::ImageFormat::Png,
    )
    .map_err(|e| e.to_string())?;
    volume::write_atomic(&dir.join(format!("{stem}.png")), &bytes).map_err(|e| e.to_string())
}

/// Runs `umbra bench accuracy`; returns the rows written.
/// What `accuracy` measured, and how many references it traced or found in the cache.
#[derive(Clone, Debug, Default)]
pub struct AccuracyReport {
    pub rows: Vec<Row>,
    pub references_traced: usize,
    pub references_cached: usize,
}

pub fn accuracy(a: &AccuracyArgs, progress: &dyn Fn(&str)) -> Result<AccuracyReport, String> {
    scene::load(&a.scene, &a.overrides)?;
    let methods: Vec<Method> = a
        .methods
        .iter()
        .map(|m| {
            serde_json::from_value(serde_json::Value::String(m.clone())).map_err(|_| {
                format!("--methods: '{m}' is not combined, dos, vicinity, ea or phong")
            })
        })
        .collect::<Result<_, _>>()?;
    std::fs::create_dir_all(a.out.join("reference"))
        .map_err(|e| format!("{}: {e}", a.out.display()))?;
    let gpu = crate::gpu::Gpu::new().map_err(|e| e.to_string())?;
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
    let mut report = AccuracyReport::default();
    let mut rows = vec![];
    for combo in &combos {
        let mut over = a.overrides.clone();
        for ((k, _), v) in a.sweeps.iter().zip(combo) {
            over.push(format!("{}={v}", sweep_key(k)));
        }
        let s = scene::load(&a.scene, &over)?;
        let m = render_cmd::model(&s).map_err(|e| format!("{}: {e}", a.scene.display()))?;
        if m.iso.is_some() {
            return Err(format!(
                "{}: the Monte Carlo reference does not model isosurfaces yet",
                a.scene.display()
            ));
        }
        // Without a volume the reference sees an empty one (all transparent).
        let empty;
        let (vol, data, tf) = match m.volume.as_ref() {
            Some((v, d, t)) => (v, d, t),
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
                    crate::ea_pass::Transfer {
                        points: vec![(0.0, [0.0; 3], 0.0)],
                        rows: vec![],
                    },
                );
                (&empty.0, &empty.1, &empty.2)
            }
        };
        let view = render_cmd::view(&s, &m)?;
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
                    crate::reference_tubes::TubeScene::new(&m.meshes, &render_cmd::tube_clip(&s));
                let l = &s.light;
                let column = (s.render.geometry_shadow == scene::GeometryShadow::Column
                    && !tube_scene.is_empty())
                .then(|| reference::ColumnMap::new(&tube_scene, &view, 4));
                let tubes = (!tube_scene.is_empty()).then_some(reference::RefTubes {
                    scene: &tube_scene,
                    sigma: s.render.geometry_extinction,
                    light: [l.ambient, l.diffuse, l.specular, l.shininess],
                    column: column.as_ref(),
                });
                let img = reference::render(
                    &RefVolume { vol, data, tf },
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
        let up = render_cmd::upload(&gpu, &m)?;
        for &method in &methods {
            let mut sm = s.clone();
            sm.render.method = method;
            let name = format!("{method:?}").to_lowercase();
            progress(&format!("{name} {}", combo.join(" ")));
            let opts = crate::renderer::DrawOptions {
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
            crate::iso_reference::write_rgb_png(
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
        "method{}{},ms,rmse,max_err,psnr,ssim,ref_stderr,rmse_volumetric,rmse_surface,rmse_vicinity",
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
            "{}{}{},{},{:.6},{:.6},{:.6}",
            r.method,
            if r.values.is_empty() { "" } else { "," },
            r.values.iter().map(quote).collect::<Vec<_>>().join(","),
            r.measured(),
            r.rmse_volumetric,
            r.rmse_surface,
            r.rmse_vicinity
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

/// A stability case: a scene built to make methods fail, its sweeps and the methods run.
struct Case {
    name: &'static str,
    what: &'static str,
    scene: String,
    sweeps: Vec<(String, Vec<String>)>,
    methods: Vec<String>,
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
    let sdir = out.join("scenes");
    std::fs::create_dir_all(&sdir).map_err(|e| format!("{}: {e}", sdir.display()))?;
    // A sheet 0.3 units thick (z in [-0.15, 0.15]), a blob, and a block shadowing a floor.
    write_grid(&sdir.join("sheet.nrrd"), 81, |p| {
        (-(p.z / 0.15).powi(8)).exp()
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
    let soft = "points = [{ value = 0.1, color = [0.8, 0.8, 0.9], extinction = 0.0 }, { value = 1.0, color = [0.8, 0.8, 0.9], extinction = 0.4 }]";
    let s = |v: &[&str]| v.iter().map(|x| x.to_string()).collect::<Vec<_>>();
    let all = s(&["dos", "ea"]);
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
            methods: s(&["dos"]),
        },
        Case {
            name: "zoom",
            what: "the shadowed floor seen from 1.5 to 6 bounding radii (consistent occlusion?)",
            scene: scene("shadow.nrrd", "azimuth = 30.0\nelevation = 50.0", dense),
            sweeps: vec![("camera.distance".into(), s(&["1.5", "3.0", "6.0"]))],
            methods: s(&["dos"]),
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
            methods: s(&["combined", "vicinity", "dos", "ea"]),
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
            methods: s(&["combined", "vicinity"]),
        },
        Case {
            name: "rotation",
            what: "the camera turning in 0.5-degree steps (frame-to-frame change of the error)",
            scene: scene("shadow.nrrd", "elevation = 50.0", dense),
            sweeps: vec![(
                "camera.azimuth".into(),
                s(&["30.0", "30.5", "31.0", "31.5"]),
            )],
            methods: s(&["dos"]),
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_pareto_front_keeps_what_nothing_beats() {
        let p = [(1.0, 5.0), (2.0, 3.0), (3.0, 4.0), (4.0, 1.0), (2.0, 6.0)];
        assert_eq!(pareto(&p), vec![0, 1, 3]);
    }

    #[test]
    fn metrics_of_an_image_against_itself_and_a_shifted_one() {
        let (w, h) = (24, 20);
        let a: Vec<[f64; 3]> = (0..w * h)
            .map(|i| [((i % w) as f64 / w as f64); 3])
            .collect();
        let [rmse, mx, psnr, s] = metrics(&a, &a, w, h);
        assert_eq!((rmse, mx), (0.0, 0.0));
        assert!(psnr > 150.0 && (s - 1.0).abs() < 1e-9);
        let b: Vec<[f64; 3]> = a.iter().map(|p| p.map(|v| v + 0.1)).collect();
        let [rmse, mx, psnr, s] = metrics(&b, &a, w, h);
        assert!(
            (rmse - 0.1).abs() < 0.01 && (mx - 0.1).abs() < 1e-9,
            "{rmse} {mx}"
        );
        assert!((psnr - 20.0).abs() < 1.0, "{psnr}");
        assert!(s < 1.0 && s > 0.5, "{s}");
    }

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

/// One tolerance of `bench tubes`.
#[derive(Clone, Debug)]
pub struct TubesRow {
    pub tolerance: f64,
    pub control_points: usize,
    pub triangles: usize,
    pub max_deviation: f64,
    /// Median meshing time.
    pub ms: f64,
}

/// `umbra bench tubes <tractogram> --tolerances T1,T2 -o <dir>`: the stream tubes' cost
/// against their accuracy: for each fitting tolerance, the control points, triangles, the
/// exact largest deviation of the B-splines from the streamlines, and the meshing time
/// (median of `runs`); `<dir>/tubes.csv` and the chart `<dir>/tubes.svg|png` (deviation against
/// triangles).
pub fn tubes(
    input: &Path,
    tolerances: &[f64],
    radius: f64,
    runs: usize,
    out: &Path,
) -> Result<Vec<TubesRow>, String> {
    std::fs::create_dir_all(out).map_err(|e| format!("{}: {e}", out.display()))?;
    let s = tubes::load(input).map_err(|e| e.to_string())?;
    let mut rows = vec![];
    for &tol in tolerances {
        if !(tol > 0.0 && tol.is_finite()) {
            return Err(format!("--tolerances: {tol} is not positive"));
        }
        let args = crate::tubes_cmd::TubesArgs::defaults(radius, 8, tol, "direction");
        let mut times = vec![];
        let mut stats = None;
        for _ in 0..runs.max(1) {
            let t = std::time::Instant::now();
            let (_, st) = crate::tubes_cmd::build_mesh(&s, &args)?;
            times.push(t.elapsed().as_secs_f64() * 1e3);
            stats = Some(st);
        }
        times.sort_by(f64::total_cmp);
        let st = stats.unwrap();
        rows.push(TubesRow {
            tolerance: tol,
            control_points: st.control_points,
            triangles: st.triangles,
            max_deviation: st.max_deviation,
            ms: times[times.len() / 2],
        });
    }
    let mut csv = Vec::new();
    let _ = writeln!(csv, "tolerance,control_points,triangles,max_deviation,ms");
    for r in &rows {
        let _ = writeln!(
            csv,
            "{},{},{},{:.6},{:.2}",
            r.tolerance, r.control_points, r.triangles, r.max_deviation, r.ms
        );
    }
    volume::write_atomic(&out.join("tubes.csv"), &csv).map_err(|e| e.to_string())?;
    write_chart(
        out,
        "tubes",
        &Plot {
            title: format!(
                "{}: deviation against triangles",
                input.file_name().unwrap_or_default().to_string_lossy()
            ),
            x_label: "triangles".into(),
            y_label: "largest deviation from the streamlines (world units)".into(),
            series: vec![(
                "B-spline tubes, tolerance swept".into(),
                rows.iter()
                    .map(|r| (r.triangles as f64, r.max_deviation.max(1e-9)))
                    .collect(),
            )],
            line: None,
        },
    )?;
    Ok(rows)
}

/// Occlusion sweeping on the isosurface 0 of `vol` (inside where positive) with each of the
/// ambient options `opts` against Monte Carlo AO (`spp` rays per pixel: cosine-weighted, or
/// uniform over the sphere for scalar AO without the geometry term; each reference traced
/// once) on a `size x size` image from azimuth `azimuth`, elevation 35, distance 1.6: the
/// sweep's milliseconds, and per option the RMSE of the ambient term and the reference's mean
/// standard error.
pub fn iso_accuracy(
    vol: &volume::Volume,
    spp: usize,
    size: usize,
    azimuth: f64,
    opts: &[volume::occlusion_shading::AmbientOptions],
) -> Result<(f64, Vec<(f64, f64)>), String> {
    use crate::iso_reference::{render, rmse, AmbientSource, IsoSurface, OrbitCamera, Shading};
    use volume::occlusion_shading::{AmbientModel, GeometryTerm};
    let values = vol.select(None).map_err(|e| e.to_string())?.data;
    let sp = vol.spacing();
    let dopts = volume::distance_sweep::DistanceOptions {
        iso: 0.0,
        inside: volume::distance_sweep::Inside::Above,
        ..Default::default()
    };
    let t = std::time::Instant::now();
    let (df, oct) = volume::occlusion_sweep::sweep_fields(
        &values,
        vol.dims,
        [sp[0] as f32, sp[1] as f32, sp[2] as f32],
        &dopts,
        &volume::occlusion_sweep::OcclusionOptions {
            subsurface_alpha: None,
        },
        true,
    );
    let ms = t.elapsed().as_secs_f64() * 1e3;
    let oct = oct.ok_or("octant fields missing")?;
    let surface = IsoSurface::new(vol.dims, vol.affine, &values, 0.0, true, &df.distance);
    let cam = OrbitCamera {
        width: size,
        height: size,
        azimuth_deg: azimuth,
        elevation_deg: 35.0,
        distance: 1.6,
    };
    let shading = Shading::default();
    // The references, cosine-weighted and uniform, as the options need them.
    let mut refs: [Option<(crate::iso_reference::IsoImage, f64)>; 2] = [None, None];
    let mut out = vec![];
    for o in opts {
        let uniform = o.geometry == GeometryTerm::Constant;
        if refs[uniform as usize].is_none() {
            let reference = render(
                &surface,
                vol.bounds(),
                &cam,
                &AmbientSource::Reference { rays: spp, uniform },
                &shading,
            );
            let hits: Vec<f64> = reference
                .stderr
                .iter()
                .zip(&reference.ambient)
                .filter(|(_, a)| a.is_finite())
                .map(|(s, _)| *s as f64)
                .collect();
            let se = hits.iter().sum::<f64>() / hits.len().max(1) as f64;
            refs[uniform as usize] = Some((reference, se));
        }
        let (reference, se) = refs[uniform as usize].as_ref().unwrap();
        let model = AmbientModel::new(*o, &vol.affine);
        let swept = render(
            &surface,
            vol.bounds(),
            &cam,
            &AmbientSource::Swept {
                octants: &oct,
                model: &model,
            },
            &shading,
        );
        out.push((rmse(&swept, reference), *se));
    }
    Ok((ms, out))
}

/// One configuration of `bench sweep`.
#[derive(Clone, Debug)]
pub struct SweepRow {
    pub n: usize,
    pub offset: f64,
    /// `cosine` (with the geometry term) or `constant` (scalar AO).
    pub geometry: String,
    pub ms: f64,
    pub rmse: f64,
    pub reference_stderr: f64,
}

/// `umbra bench sweep -o <dir>`: occlusion sweeping against Monte Carlo ambient occlusion on
/// the sweeping paper's validation scene at several grid sizes: sweep time (distance and eight
/// octants), and the RMSE of the swept ambient term against hemisphere AO traced on the same
/// isosurface (`spp` cosine-weighted rays per pixel, its standard error reported), on a
/// `size x size` image; `<dir>/sweep.csv` and `<dir>/sweep.svg|png` (error against time).
pub fn sweep(
    sizes: &[usize],
    offsets: &[f64],
    geometries: &[volume::occlusion_shading::GeometryTerm],
    spp: usize,
    size: usize,
    out: &Path,
) -> Result<Vec<SweepRow>, String> {
    if let Some(o) = offsets.iter().find(|o| !(o.is_finite() && **o >= 0.0)) {
        return Err(format!("--offsets: {o} is not a finite number >= 0"));
    }
    if spp == 0 || !(8..=2048).contains(&size) {
        return Err(format!(
            "--spp {spp} --size {size}: at least one ray per pixel, an image of 8 to 2048 pixels"
        ));
    }
    std::fs::create_dir_all(out).map_err(|e| format!("{}: {e}", out.display()))?;
    let mut rows = vec![];
    for &n in sizes {
        if !(8..=512).contains(&n) {
            return Err(format!("--sizes: {n} is not in 8..512"));
        }
        let vol = volume::synthetic::validation_scene(n);
        let opts: Vec<volume::occlusion_shading::AmbientOptions> = geometries
            .iter()
            .flat_map(|&geometry| {
                offsets
                    .iter()
                    .map(move |&offset| volume::occlusion_shading::AmbientOptions {
                        geometry,
                        offset,
                        ..Default::default()
                    })
            })
            .collect();
        let (ms, results) = iso_accuracy(&vol, spp, size, 35.0, &opts)?;
        for (o, (rmse, se)) in opts.iter().zip(results) {
            rows.push(SweepRow {
                n,
                offset: o.offset,
                geometry: format!("{:?}", o.geometry).to_lowercase(),
                ms,
                rmse,
                reference_stderr: se,
            });
        }
    }
    let mut csv = Vec::new();
    let _ = writeln!(csv, "n,offset,geometry,sweep_ms,rmse,reference_stderr");
    for r in &rows {
        let _ = writeln!(
            csv,
            "{},{},{},{:.2},{:.6},{:.6}",
            r.n, r.offset, r.geometry, r.ms, r.rmse, r.reference_stderr
        );
    }
    volume::write_atomic(&out.join("sweep.csv"), &csv).map_err(|e| e.to_string())?;
    write_chart(
        out,
        "sweep",
        &Plot {
            title: "occlusion sweeping: error against time (validation scene)".into(),
            x_label: "sweep time (ms; distance and eight octants)".into(),
            y_label: "RMSE of the ambient term against Monte Carlo AO".into(),
            series: {
                let name = |r: &SweepRow| format!("{}, offset {}", r.geometry, r.offset);
                let mut names: Vec<String> = rows.iter().map(name).collect();
                names.sort();
                names.dedup();
                names
                    .into_iter()
                    .map(|nm| {
                        let pts = rows
                            .iter()
                            .filter(|r| name(r) == nm)
                            .map(|r| (r.ms.max(1e-3), r.rmse.max(1e-9)))
                            .collect();
                        (nm, pts)
                    })
                    .collect()
            },
            line: None,
        },
    )?;
    Ok(rows)
}

/// `umbra bench ao <scene.toml> --spp N -o <dir>`: the tubes' hemisphere ambient occlusion
/// (`reference_tubes::hemisphere_ao`) seen by the scene's camera, for the cross-check against
/// an independent renderer (`bench/mitsuba_ao.py`): writes `<dir>/ao.exr` (channels `Y`, the
/// mean, and `stderr`), the tubes as one world-space mesh `<dir>/tubes.ply`, and
/// `<dir>/camera.json` (eye, target, up, vertical field of view, width, height). Perspective
/// cameras only; the volume is left out.
pub fn ao(
    scene_path: &Path,
    overrides: &[String],
    spp: u32,
    max_distance: Option<f64>,
    out: &Path,
) -> Result<f64, String> {
    if max_distance.is_some_and(|d| !(d > 0.0 && d.is_finite())) {
        return Err("--max-distance: must be a positive number".into());
    }
    std::fs::create_dir_all(out).map_err(|e| format!("{}: {e}", out.display()))?;
    let mut s = scene::load(scene_path, overrides)?;
    s.volume = None;
    let m = render_cmd::model(&s).map_err(|e| format!("{}: {e}", scene_path.display()))?;
    if m.meshes.is_empty() {
        return Err(format!(
            "{}: bench ao needs [[tubes]]",
            scene_path.display()
        ));
    }
    let v = render_cmd::view(&s, &m)?;
    let crate::camera::Projection::Perspective { fov_y_deg } = v.camera.projection else {
        return Err("bench ao: the cross-check needs a perspective camera".into());
    };
    let ts = crate::reference_tubes::TubeScene::new(&m.meshes, &render_cmd::tube_clip(&s));
    let (w, h) = (v.width as usize, v.height as usize);
    let (mean, se) =
        crate::reference_tubes::hemisphere_ao(&ts, &v.camera, w, h, spp, 0x5eed, max_distance);
    {
        use exr::prelude::*;
        let ch = |name: &str, x: &[f64]| {
            AnyChannel::new(
                name,
                FlatSamples::F32(x.iter().map(|&v| v as f32).collect()),
            )
        };
        let mut list: SmallVec<[AnyChannel<FlatSamples>; 4]> = SmallVec::new();
        list.push(ch("Y", &mean));
        list.push(ch("stderr", &se));
        let img = Image::from_channels((w, h), AnyChannels::sort(list));
        let mut bytes = std::io::Cursor::new(Vec::new());
        img.write()
            .to_buffered(&mut bytes)
            .map_err(|e| format!("ao.exr: {e}"))?;
        volume::write_atomic(&out.join("ao.exr"), bytes.get_ref()).map_err(|e| e.to_string())?;
    }
    // One mesh in world coordinates (origin zero).
    let mut all = tubes::tube_mesh::TubeMesh::default();
    for mesh in &m.meshes {
        let base = all.positions.len() as u32;
        all.positions.extend(
            mesh.positions
                .iter()
                .map(|p| (mesh.origin + p.as_dvec3()).as_vec3()),
        );
        all.normals.extend(&mesh.normals);
        all.colors.extend(&mesh.colors);
        all.indices.extend(mesh.indices.iter().map(|i| i + base));
    }
    tubes::mesh_io::write(&out.join("tubes.ply"), &all).map_err(|e| e.to_string())?;
    let c = &v.camera;
    let cam = serde_json::json!({
        "eye": [c.eye.x, c.eye.y, c.eye.z],
        "target": [c.target.x, c.target.y, c.target.z],
        "up": [c.up.x, c.up.y, c.up.z],
        "fov_y": fov_y_deg,
        "width": w,
        "height": h,
        "spp": spp,
    });
    volume::write_atomic(&out.join("camera.json"), cam.to_string().as_bytes())
        .map_err(|e| e.to_string())?;
    Ok(mean.iter().sum::<f64>() / mean.len().max(1) as f64)
}
