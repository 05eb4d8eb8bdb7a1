//! `umbra bench lineao -o <dir> [--quick] [--spp N] [--size N] [--frames N] [--set KEY=VALUE]`:
//! LineAO (Eichelbaum et al. 2013; `occlusion::line_ao`, `engine/src/line_ao.rs`) against
//! ray-traced ambient occlusion of the same lines (issue 6, item 6).
//!
//! * **References** ([`reference_ao`]): the lines as tubes of the proxy radius, meshed by
//!   `tubes::tube_mesh` (12 sides, caps) into `reference_tubes::TubeScene` (its BVH); per pixel
//!   the cosine-weighted hemisphere AO (no distance limit; 1 = open) at the surface the pixel's
//!   centre ray meets - as the G-buffer samples it, so that a pixel is covered or not and its
//!   value is the AO of the one point LineAO shades. *Physical* (R1): about the tube's normal
//!   there. *Model-matched* (R2): at the point of the same tube that faces the viewer, about
//!   the view direction made perpendicular to the tube: the AO of the line LineAO's flat strip
//!   stands for, whatever sub-pixel part of the tube the pixel centre hits. Every camera is
//!   orthographic: a line `w` pixels wide is then exactly a tube of radius `w / 2 x camera
//!   height / image height` world units ([`tube_radius`]).
//! * **Compared**: on the pixels covered in both (the render's `Z > 0` and a reference hit),
//!   the visibility AOV (`occlusion.lineao`, `occlusion.vicinity`, or [`ssao`]'s) against the
//!   physical reference's open fraction: RMSE, bias (mean of estimate - reference), the
//!   affine-calibrated RMSE (after the least-squares `a x + b` of the estimate onto the
//!   reference: LineAO is not a physical model, so its scale is forgiven), Spearman's rank
//!   correlation (ties averaged), SSIM of the two images with the uncovered pixels set to 1 in
//!   both, the frame time (`total_ms`, the median of `--frames`); and Spearman and the
//!   affine-calibrated RMSE against the model-matched reference.
//! * **Methods**: `lineao` (`render.method = "lineao"`, the paper's parameters on flat strips,
//!   `setting = paper`, unless the setting says otherwise); `vicinity` (Schott et al.'s term,
//!   `render.method = "vicinity"`, with `l_vicinity` chosen so that its disc, `l tan theta`, is
//!   LineAO's outermost disc in world units, `setting = matched`, and at the scene default 2,
//!   `setting = default`); `ssao`, the plain screen-space baseline the renderer does not have
//!   ([`ssao`]: Crytek-style depth tests of points in the viewer-side half-ball of the same
//!   world radius, on the CPU from the `Z` AOV of an `illuminated` frame; its `ms` is that
//!   frame's plus the CPU time); and `reference` (the physical one's row: its mean open
//!   fraction, trace time and per-pixel standard error; the model-matched one's: compared with
//!   the physical one, the bound on any method that knows only a line's view-facing normal).
//! * **Cases** (the synthetic lines are written to `<dir>/data`, every scene to
//!   `<dir>/scenes`): `isolated` (five straight lines 10 units apart: they should stay open),
//!   `dense` (a 200-line bundle over an 80-line crossing one; all methods, and LineAO on
//!   pseudo-cylinders, `profile = "cylinder"`), `samples` (`s_h` from 8 to 1024, with
//!   `rmse_converged` against LineAO's own image at `s_h = 1024`), `falloff` (paper against
//!   constant), `zoom` (world-width lines at 1x, 2x, 4x and 8x, the cameras offset so that the
//!   1x pixel centres stay pixel centres; `<dir>/zoom.csv`: each method's visibility at the
//!   world-anchored probes in the 8x view, and its change from 1x), `border` (the bundle
//!   panned off the left edge, guard band 64 or 0: the rows split into the border strip, as
//!   wide as LineAO's outermost disc, and the interior; `<dir>/border.csv`: the same pixels
//!   against a render wider by 32 pixels a side, the screen-space truth, at `s_h` 32 and
//!   1024), and the real tracts `hcp-cst-l`, `hcp-af-r` (HCP1065 bundles,
//!   `bench/scenes/lineao_hcp_*.toml`), `dipy` (`bench/scenes/lineao_dipy.toml`) and `carotid`
//!   (streamlines traced through `datasets/vtk/carotid.vtk` as `umbra demo cfd` does), each
//!   thinned to every k-th streamline so that at most 800 are left. A real case whose data is
//!   missing is skipped with a note. `--quick`: `isolated` and `dense` only, at 96 x 96 with
//!   16 paths per pixel.
//! * **Outputs**: `<dir>/results.csv` ([`CSV_HEADER`]), `<dir>/pareto.svg` and `.png`
//!   (affine-calibrated RMSE against frame time on the dense bundle, the Pareto front marked),
//!   `<dir>/samples.svg` and `.png` (noise and error against `s_h`; not with `--quick`),
//!   `zoom.csv`, `border.csv` (not with `--quick`), and the visibility images
//!   `<dir>/images/<case>_<method>_<setting>.png` (grey, uncovered pixels white).

use super::chart::{write_chart, Plot};
use super::metrics::{agreement, pareto, ssim, Agreement};
use crate::output::out;
use crate::progress::Stages;
use glam::{DVec3, Vec3};
use occlusion::camera::{Camera, Projection};
use occlusion::reference_tubes::TubeScene;
use occlusion::rng::SplitMix64;
use scene::compile::{self, Model, Uploaded};
use scene::spec::{self, Scene};
use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// `umbra bench lineao`.
#[derive(clap::Args)]
pub struct Args {
    /// Two small cases (isolated lines, the dense bundle) at 96 x 96 with 16 paths per pixel.
    #[arg(long)]
    quick: bool,
    /// Hemisphere paths per pixel of the references [default: 128, 16 with --quick].
    #[arg(long)]
    spp: Option<u32>,
    /// Image width and height in pixels [default: 128, 96 with --quick].
    #[arg(long)]
    size: Option<u32>,
    /// Frames timed per configuration (the median is its time) [default: 3, 1 with --quick].
    #[arg(long)]
    frames: Option<u32>,
    /// Override a scene key by its dotted path in every case (repeatable; e.g.
    /// `render.lineao.radius_step=2`).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    set: Vec<String>,
    /// Output folder.
    #[arg(short, long)]
    output: PathBuf,
}

pub fn run(a: Args) -> Result<(), String> {
    let cfg = Config {
        size: a.size.unwrap_or(if a.quick { 96 } else { 128 }),
        spp: a.spp.unwrap_or(if a.quick { 16 } else { 128 }),
        frames: a.frames.unwrap_or(if a.quick { 1 } else { 3 }),
        quick: a.quick,
        set: a.set.clone(),
        out: a.output.clone(),
    };
    if !(16..=2048).contains(&cfg.size) {
        return Err(format!("--size {}: choose 16 to 2048 pixels", cfg.size));
    }
    if cfg.spp == 0 || cfg.frames == 0 {
        return Err("--spp and --frames must be at least 1".into());
    }
    let progress = Stages::new(true);
    let rows = lineao(&cfg, &|m| progress.stage(m))?;
    drop(progress);
    out(format!(
        "{:10} {:9} {:24} {:>9} {:>7} {:>7} {:>7} {:>6} {:>6} {:>6} {:>6}",
        "case", "method", "setting", "ms", "rmse", "bias", "affine", "rho", "ssim", "vis", "pixels"
    ))?;
    for r in &rows {
        out(format!(
            "{:10} {:9} {:24} {:9.1} {:7.4} {:7.4} {:7.4} {:6.3} {:6.3} {:6.3} {:6}",
            r.case,
            r.method,
            r.setting,
            r.ms,
            r.agreement.rmse,
            r.agreement.bias,
            r.agreement.rmse_affine,
            r.agreement.spearman,
            r.ssim,
            r.mean_visibility,
            r.pixels
        ))?;
    }
    if a.quick {
        eprintln!("wrote {0}/results.csv, {0}/pareto.svg", a.output.display());
    } else {
        eprintln!(
            "wrote {0}/results.csv, {0}/pareto.svg, {0}/samples.svg, {0}/zoom.csv, {0}/border.csv",
            a.output.display()
        );
    }
    Ok(())
}

/// What `umbra bench lineao` is asked to do.
#[derive(Clone, Debug)]
pub struct Config {
    pub size: u32,
    pub spp: u32,
    pub frames: u32,
    pub quick: bool,
    /// Scene overrides for every case.
    pub set: Vec<String>,
    pub out: PathBuf,
}

/// One row of results.csv.
#[derive(Clone, Debug)]
pub struct Row {
    pub case: String,
    pub method: String,
    pub setting: String,
    pub ms: f64,
    /// Against the physical reference.
    pub agreement: Agreement,
    /// Against the model-matched reference.
    pub model: Agreement,
    pub ssim: f64,
    /// The method's mean visibility over the compared pixels (the reference's mean open
    /// fraction in its own row).
    pub mean_visibility: f64,
    pub pixels: usize,
    /// The reference's mean per-pixel standard error over the compared pixels.
    pub ref_stderr: f64,
    /// RMSE against LineAO's own image at `s_h = 1024` (the `samples` case; NaN elsewhere).
    pub rmse_converged: f64,
}

/// The header of results.csv.
pub const CSV_HEADER: &str = "case,method,setting,ms,rmse,bias,rmse_affine,spearman,ssim,mean_visibility,pixels,ref_stderr,rmse_converged,spearman_model,rmse_affine_model";

impl Row {
    fn csv(&self) -> String {
        let a = &self.agreement;
        format!(
            "{},{},{},{:.3},{:.6},{:.6},{:.6},{:.5},{:.5},{:.5},{},{:.6},{:.6},{:.5},{:.6}",
            self.case,
            self.method,
            self.setting.replace(',', ";"),
            self.ms,
            a.rmse,
            a.bias,
            a.rmse_affine,
            a.spearman,
            self.ssim,
            self.mean_visibility,
            self.pixels,
            self.ref_stderr,
            self.rmse_converged,
            self.model.spearman,
            self.model.rmse_affine
        )
    }
}

/// The world radius of the tube a line set stands for under `camera` at `height` pixels: half
/// the width for world widths; for pixel widths `w / 2` pixels in world units, exact under an
/// orthographic camera (`w / 2 x view height / image height`), an error under perspective.
pub fn tube_radius(l: &spec::LinesSpec, camera: &Camera, height: u32) -> Result<f64, String> {
    match (l.width_unit, camera.projection) {
        (spec::WidthUnit::World, _) => Ok(0.5 * l.width),
        (spec::WidthUnit::Pixels, Projection::Orthographic { height: view }) => {
            Ok(0.5 * l.width * view / height as f64)
        }
        (spec::WidthUnit::Pixels, Projection::Perspective { .. }) => Err(
            "bench lineao: pixel-width lines are tubes of one radius only under an orthographic camera"
                .into(),
        ),
    }
}

/// The reference of one view: per pixel the open fraction (NaN where the centre ray meets no
/// tube) and its standard error, of the physical reference and of the model-matched one
/// ([`reference_ao`]), and the time it took.
pub struct Reference {
    pub ao: Vec<f64>,
    pub stderr: Vec<f64>,
    pub model: Vec<f64>,
    pub model_stderr: Vec<f64>,
    pub ms: f64,
}

/// One pixel of [`reference_ao`]: the physical AO and its standard error, the model-matched AO
/// and its standard error.
pub type RefPixel = [f64; 4];

/// Hemisphere AO of `scene`'s tubes (of radius `radius`) at the surface each pixel's centre ray
/// meets first, twice, each `spp` cosine-weighted rays counted open when they enter no tube
/// (a ray that only leaves the tube it starts on, through a facet it dipped under, is open:
/// the faceted mesh's self-shadowing, which a round tube does not have):
/// * **physical** (R1): at the hit, about the interpolated normal turned to face the viewer -
///   `reference_tubes::hemisphere_ao`'s integral and sampling without its pixel jitter;
/// * **model-matched** (R2): at the point of the tube that faces the viewer across the tube's
///   axis, `C + radius n_view` with `C = hit - radius n` on the axis and `n_view` the view
///   direction made perpendicular to the tube's tangent (the tangent from the hit triangle's
///   vertex normals, `n x (n_a - n_b)` for its most different pair), about `n_view`: the AO of
///   the line LineAO's flat strip stands for, whatever sub-pixel part of the tube the pixel
///   centre hits (where the tangent is undefined - caps, a tube seen end-on - as R1).
///
/// NaN where the ray meets nothing.
pub fn reference_ao(
    scene: &TubeScene,
    camera: &Camera,
    width: usize,
    height: usize,
    radius: f64,
    spp: u32,
    seed: u64,
) -> Vec<RefPixel> {
    use rayon::prelude::*;
    let hemisphere = |p: DVec3, n: DVec3, rng: &mut SplitMix64| -> (f64, f64) {
        let a = if n.x.abs() < 0.9 { DVec3::X } else { DVec3::Y };
        let t = n.cross(a).normalize();
        let b = n.cross(t);
        let n_paths = spp.max(1);
        let mut open = 0u32;
        for _ in 0..n_paths {
            let (u1, u2) = (rng.next_f64(), rng.next_f64());
            let r = u1.sqrt();
            let phi = std::f64::consts::TAU * u2;
            let dir = t * (r * phi.cos()) + b * (r * phi.sin()) + n * (1.0 - u1).max(0.0).sqrt();
            let blocked = scene
                .hits(p, dir, 0.0, f64::INFINITY)
                .iter()
                .any(|h| scene.surface(h).0.dot(dir) < 0.0);
            if !blocked {
                open += 1;
            }
        }
        let v = open as f64 / n_paths as f64;
        (v, (v * (1.0 - v) / n_paths as f64).sqrt())
    };
    (0..width * height)
        .into_par_iter()
        .map(|i| {
            let (o, d) = camera.ray((i % width) as f64, (i / width) as f64, width, height);
            let Some(hit) = scene.hits(o, d, 0.0, f64::INFINITY).first().copied() else {
                return [f64::NAN; 4];
            };
            let (mut n, _) = scene.surface(&hit);
            if n.dot(d) > 0.0 {
                n = -n;
            }
            let eps = 1e-4 * (1.0 + hit.t.abs());
            let q = o + d * hit.t;
            let mut rng =
                SplitMix64(seed ^ (i as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ 0x1A0A);
            let (v1, s1) = hemisphere(q + n * eps, n, &mut rng);
            // The tangent from the vertex normals' largest difference (around the ring).
            let vn = scene.tris[hit.tri].n;
            let dn = [(0, 1), (1, 2), (0, 2)]
                .iter()
                .map(|&(a, b)| vn[a] - vn[b])
                .max_by(|a, b| a.length_squared().total_cmp(&b.length_squared()))
                .unwrap_or(DVec3::ZERO);
            let tangent = n.cross(dn).normalize_or_zero();
            let view = -d - tangent * (-d).dot(tangent);
            let (v2, s2) = if dn.length() > 1e-6 && tangent != DVec3::ZERO && view.length() > 1e-3 {
                let nv = view.normalize();
                let centre = q - n * radius;
                hemisphere(centre + nv * (radius + eps), nv, &mut rng)
            } else {
                (v1, s1)
            };
            [v1, s1, v2, s2]
        })
        .collect()
}

/// A plain screen-space AO from linear depth alone (the bench's SSAO baseline; Crytek's
/// depth-buffer test, Mittring 2007), for orthographic views: at each pixel with depth
/// `z > 0`, `samples` points uniform in the half-ball of radius `radius` (world units) on the
/// viewer's side of the pixel's surface point, each looked up in `z` at its pixel (nearest;
/// `world_per_px` world units a pixel); a point occludes when the surface there is nearer than
/// the point by more than `bias` and nearer than the pixel by less than `radius` (the range
/// check); background is open; points off screen are left out. Visibility `1 - occluding /
/// on-screen` (1 when none is on screen); NaN where `z` is background. The sample set is
/// drawn per pixel from `seed`. No normals: a flat view-facing surface is open, a tube's
/// flanks see their own tube as an occluder (the artefact of depth-only SSAO).
#[allow(clippy::too_many_arguments)]
pub fn ssao(
    z: &[f32],
    width: usize,
    height: usize,
    world_per_px: f64,
    radius: f64,
    bias: f64,
    samples: u32,
    seed: u64,
) -> Vec<f64> {
    use rayon::prelude::*;
    (0..width * height)
        .into_par_iter()
        .map(|i| {
            let zp = z[i] as f64;
            if zp.is_nan() || zp <= 0.0 {
                return f64::NAN;
            }
            let (x, y) = ((i % width) as f64 + 0.5, (i / width) as f64 + 0.5);
            let mut rng =
                SplitMix64(seed ^ (i as u64).wrapping_mul(0xD1B5_4A32_D192_ED03) ^ 0x55A0);
            let (mut valid, mut occ) = (0u32, 0u32);
            for _ in 0..samples {
                let (u1, u2, u3) = (rng.next_f64(), rng.next_f64(), rng.next_f64());
                // Uniform on the hemisphere towards the eye, radius by the cube root: uniform
                // in the half-ball.
                let c = u1;
                let s = (1.0 - c * c).max(0.0).sqrt();
                let phi = std::f64::consts::TAU * u2;
                let r = radius * u3.cbrt();
                let (ox, oy, oz) = (r * s * phi.cos(), r * s * phi.sin(), r * c);
                let (qx, qy) = (x + ox / world_per_px, y - oy / world_per_px);
                if !(qx >= 0.0 && qy >= 0.0 && qx < width as f64 && qy < height as f64) {
                    continue;
                }
                valid += 1;
                let zb = z[qx as usize + width * qy as usize] as f64;
                let zs = zp - oz;
                if zb > 0.0 && zb < zs - bias && zp - zb < radius {
                    occ += 1;
                }
            }
            if valid == 0 {
                1.0
            } else {
                1.0 - occ as f64 / valid as f64
            }
        })
        .collect()
}

/// A scene's lines loaded once: the scene file, the overrides every frame of it shares, the
/// model and its upload.
struct Geometry<'g> {
    path: PathBuf,
    base: Vec<String>,
    scene: Scene,
    model: Model,
    up: Uploaded<'g>,
}

/// What one frame gives: the visibility (NaN where `Z` is 0), `Z`, the time, the size.
#[derive(Clone)]
struct Frame {
    vis: Vec<f64>,
    z: Vec<f32>,
    ms: f64,
    w: usize,
    h: usize,
}

impl<'g> Geometry<'g> {
    fn new(gpu: &'g engine::gpu::Gpu, path: &Path, base: Vec<String>) -> Result<Self, String> {
        let scene = spec::load(path, &base)?;
        let model = compile::model(&scene).map_err(|e| format!("{}: {e}", path.display()))?;
        let up = compile::upload(gpu, &model)?;
        Ok(Geometry {
            path: path.to_path_buf(),
            base,
            scene,
            model,
            up,
        })
    }

    fn scene(&self, extra: &[String]) -> Result<Scene, String> {
        let mut over = self.base.clone();
        over.extend(extra.iter().cloned());
        spec::load(&self.path, &over)
    }

    /// One frame with `extra` overrides (they must not change the model), its channel `ch`.
    fn frame(&self, extra: &[String], ch: &str, frames: u32) -> Result<Frame, String> {
        let s = self.scene(extra)?;
        let (o, view) = self.up.draw(
            &s,
            &self.model,
            engine::renderer::DrawOptions {
                frames,
                pass_timings: false,
            },
        )?;
        let chans = o.aov_channels();
        let get = |name: &str| {
            chans
                .iter()
                .find(|(n, _)| n == name)
                .map(|(_, v)| v.clone())
                .ok_or_else(|| format!("{}: the frame has no channel {name}", self.path.display()))
        };
        let z = get("Z")?;
        let v = if ch == "Z" { z.clone() } else { get(ch)? };
        Ok(Frame {
            vis: v
                .iter()
                .zip(&z)
                .map(|(&v, &z)| if z > 0.0 { v as f64 } else { f64::NAN })
                .collect(),
            z,
            ms: o.timings.total_ms,
            w: view.width as usize,
            h: view.height as usize,
        })
    }

    /// The camera and size of the scene with `extra` overrides.
    fn view(&self, extra: &[String]) -> Result<(Camera, u32, u32), String> {
        let s = self.scene(extra)?;
        let v = compile::view(&s, &self.model)?;
        Ok((v.camera, v.width, v.height))
    }

    /// The tube meshes of the lines at the radius each set stands for in the view of `extra`.
    fn tubes(&self, extra: &[String]) -> Result<Vec<tubes::tube_mesh::TubeMesh>, String> {
        let (cam, _, h) = self.view(extra)?;
        let mut meshes = vec![];
        for (i, l) in self.scene.lines.iter().enumerate() {
            let rho = tube_radius(l, &cam, h)?;
            let mut sl = tubes::load(&l.path).map_err(|e| format!("lines[{i}]: {e}"))?;
            if let Some(m) = l.transform {
                sl.transform(&scene::tube_sets::transform_matrix(
                    &m,
                    &format!("lines[{i}].transform"),
                )?);
            }
            let mut o = tubes::tube_mesh::TubeOptions::defaults(rho, 12, (0.25 * rho).min(0.1));
            o.color = tubes::tube_mesh::ColorMode::Constant([0.8; 3]);
            meshes.push(tubes::tube_mesh::build(&sl, &o).0);
        }
        Ok(meshes)
    }

    /// The reference of the view of `extra` (both kinds, [`reference_ao`]; the radius of the
    /// first line set for the model-matched one).
    fn reference(&self, extra: &[String], spp: u32, seed: u64) -> Result<Reference, String> {
        let t0 = Instant::now();
        let meshes = self.tubes(extra)?;
        let s = self.scene(extra)?;
        let ts = TubeScene::new(&meshes, &compile::tube_clip(&s));
        let (cam, w, h) = self.view(extra)?;
        let l = s
            .lines
            .first()
            .ok_or("bench lineao: the scene has no lines")?;
        let radius = tube_radius(l, &cam, h)?;
        let px = reference_ao(&ts, &cam, w as usize, h as usize, radius, spp, seed);
        let pick = |k: usize| px.iter().map(|p| p[k]).collect::<Vec<f64>>();
        Ok(Reference {
            ao: pick(0),
            stderr: pick(1),
            model: pick(2),
            model_stderr: pick(3),
            ms: t0.elapsed().as_secs_f64() * 1e3,
        })
    }

    /// LineAO's outermost disc in world units for the view of `extra`, and the world size of
    /// a pixel: `r0 / z + (s_r - 1) radius_step` with `r0 = r0_widths x` the first line set's
    /// width on screen (pixels) or `z x` its world width.
    fn outer_radius(&self, extra: &[String]) -> Result<(f64, f64), String> {
        let s = self.scene(extra)?;
        let (cam, _, h) = self.view(extra)?;
        let Projection::Orthographic { height } = cam.projection else {
            return Err("bench lineao: orthographic cameras only".into());
        };
        let px = height / h as f64;
        let l = s
            .lines
            .first()
            .ok_or("bench lineao: the scene has no lines")?;
        let r0_world = match l.width_unit {
            spec::WidthUnit::Pixels => s.render.lineao.r0 * l.width * px,
            spec::WidthUnit::World => s.render.lineao.r0 * l.width,
        };
        let outer =
            r0_world + (s.render.lineao.levels.max(1) - 1) as f64 * s.render.lineao.radius_step;
        Ok((outer, px))
    }
}

/// Compares `est` with `reference` over the pixels both cover and `region` keeps: against the
/// physical reference, and (`model`) against the model-matched one.
#[allow(clippy::too_many_arguments)]
fn compare(
    case: &str,
    method: &str,
    setting: &str,
    ms: f64,
    est: &[f64],
    reference: &Reference,
    region: Option<&[bool]>,
    w: usize,
    h: usize,
) -> Row {
    let keep: Vec<bool> = (0..est.len())
        .map(|i| {
            est[i].is_finite()
                && reference.ao[i].is_finite()
                && reference.model[i].is_finite()
                && region.is_none_or(|r| r[i])
        })
        .collect();
    let pick =
        |v: &[f64]| -> Vec<f64> { (0..v.len()).filter(|&i| keep[i]).map(|i| v[i]).collect() };
    let (x, y, ym) = (pick(est), pick(&reference.ao), pick(&reference.model));
    let se = pick(&reference.stderr).iter().sum::<f64>() / x.len().max(1) as f64;
    let masked = |v: &[f64]| -> Vec<f64> {
        (0..v.len())
            .map(|i| if keep[i] { v[i] } else { 1.0 })
            .collect()
    };
    let s = if x.is_empty() {
        f64::NAN
    } else {
        ssim(&masked(est), &masked(&reference.ao), w, h)
    };
    Row {
        case: case.into(),
        method: method.into(),
        setting: setting.into(),
        ms,
        agreement: agreement(&x, &y),
        model: agreement(&x, &ym),
        ssim: s,
        mean_visibility: x.iter().sum::<f64>() / x.len().max(1) as f64,
        pixels: x.len(),
        ref_stderr: se,
        rmse_converged: f64::NAN,
    }
}

/// The references' own rows over the pixels they share with `est` (the render's coverage):
/// the physical one (its mean open fraction, standard error and time; nothing to compare) and
/// the model-matched one compared with it (how far LineAO's notion of a line's normal alone
/// is from the physical AO: a bound on any view-normal screen-space method).
fn reference_rows(case: &str, setting: &str, est: &[f64], r: &Reference) -> [Row; 2] {
    let covered: Vec<f64> = (0..est.len())
        .map(|i| {
            if est[i].is_finite() {
                r.ao[i]
            } else {
                f64::NAN
            }
        })
        .collect();
    let mut phys = compare(
        case,
        "reference",
        setting,
        r.ms,
        &covered,
        r,
        None,
        1,
        est.len(),
    );
    let nan = f64::NAN;
    let none = Agreement {
        rmse: nan,
        bias: nan,
        rmse_affine: nan,
        slope: nan,
        offset: nan,
        pearson: nan,
        spearman: nan,
        n: phys.pixels,
    };
    (phys.agreement, phys.model, phys.ssim) = (none, none, nan);
    let model: Vec<f64> = (0..est.len())
        .map(|i| {
            if est[i].is_finite() {
                r.model[i]
            } else {
                f64::NAN
            }
        })
        .collect();
    let setting_m = if setting.is_empty() {
        "model-matched".to_string()
    } else {
        format!("{setting} model-matched")
    };
    let mut m = compare(
        case,
        "reference",
        &setting_m,
        r.ms,
        &model,
        r,
        None,
        1,
        est.len(),
    );
    m.ssim = nan;
    m.ref_stderr = {
        let idx: Vec<usize> = (0..est.len())
            .filter(|&i| model[i].is_finite() && r.ao[i].is_finite())
            .collect();
        idx.iter().map(|&i| r.model_stderr[i]).sum::<f64>() / idx.len().max(1) as f64
    };
    [phys, m]
}

/// A grey image of a visibility (NaN white).
fn write_image(dir: &Path, name: &str, v: &[f64], w: usize, h: usize) -> Result<(), String> {
    std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let px: Vec<[f32; 3]> = v
        .iter()
        .map(|&x| {
            if x.is_finite() {
                [x.clamp(0.0, 1.0) as f32; 3]
            } else {
                [1.0; 3]
            }
        })
        .collect();
    let stem: String = name
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '.' {
                c
            } else {
                '_'
            }
        })
        .collect();
    scene::image_io::write_rgb_png(&dir.join(format!("{stem}.png")), w, h, &px)
}

/// A standard normal deviate (Box-Muller).
fn gauss(rng: &mut SplitMix64) -> f32 {
    let (u1, u2) = (rng.next_f64().max(1e-300), rng.next_f64());
    ((-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()) as f32
}

/// The dense synthetic bundle (world units as mm): `main` lines along x over [-40, 40]
/// (81 points), their (y, z) Gaussian about 0 with spreads 8 and 5, each wavering by 1.5
/// with its own phases; over a crossing bundle of `cross` lines 90 long at 60 degrees to x,
/// 12 units further from a viewer on +z (spread 5 across, 2 in depth).
pub fn dense_bundle(main: usize, cross: usize) -> tubes::Streamlines {
    let mut rng = SplitMix64(0x11AE0);
    let mut sl = tubes::Streamlines::new();
    for _ in 0..main {
        let (y0, z0) = (8.0 * gauss(&mut rng), 5.0 * gauss(&mut rng));
        let p1 = (rng.next_f64() * std::f64::consts::TAU) as f32;
        let p2 = (rng.next_f64() * std::f64::consts::TAU) as f32;
        let pts: Vec<Vec3> = (0..=80)
            .map(|i| {
                let x = i as f32 - 40.0;
                Vec3::new(
                    x,
                    y0 + 1.5 * (x / 12.0 + p1).sin(),
                    z0 + 1.5 * (x / 15.0 + p2).cos(),
                )
            })
            .collect();
        sl.push(&pts);
    }
    let (d, perp) = (
        Vec3::new(0.5, 0.866_025_4, 0.0),
        Vec3::new(-0.866_025_4, 0.5, 0.0),
    );
    for _ in 0..cross {
        let (s0, z0) = (5.0 * gauss(&mut rng), -12.0 + 2.0 * gauss(&mut rng));
        let pts: Vec<Vec3> = (0..=90)
            .map(|i| d * (i as f32 - 45.0) + perp * s0 + Vec3::new(0.0, 0.0, z0))
            .collect();
        sl.push(&pts);
    }
    sl
}

/// Five straight lines along x over [-40, 40], 10 units apart in y, at z = 0.
pub fn isolated_lines() -> tubes::Streamlines {
    let mut sl = tubes::Streamlines::new();
    for k in -2..=2 {
        let pts: Vec<Vec3> = (0..=80)
            .map(|i| Vec3::new(i as f32 - 40.0, 10.0 * k as f32, 0.0))
            .collect();
        sl.push(&pts);
    }
    sl
}

/// Every k-th streamline of `src` so that at most `max` are left, written to `dst` (.tck);
/// returns how many of how many.
fn subsample(src: &Path, max: usize, dst: &Path) -> Result<(usize, usize), String> {
    let sl = tubes::load(src).map_err(|e| format!("{}: {e}", src.display()))?;
    let k = sl.len().div_ceil(max.max(1)).max(1);
    let mut out = tubes::Streamlines::new();
    for i in (0..sl.len()).step_by(k) {
        out.push(sl.line(i));
    }
    tubes::save(dst, &out).map_err(|e| format!("{}: {e}", dst.display()))?;
    Ok((out.len(), sl.len()))
}

/// A scene file of synthetic lines seen from +z by an orthographic camera of view height
/// `view` world units centred on (0, 0).
fn synthetic_scene(tracts: &Path, width: &str) -> String {
    format!(
        "# umbra bench lineao: synthetic lines, orthographic from +z\nbackground = [1.0, 1.0, 1.0]\n[camera]\nprojection = \"orthographic\"\neye = [0.0, 0.0, 200.0]\ntarget = [0.0, 0.0, 0.0]\nup = [0.0, 1.0, 0.0]\nheight = 100.0\n[[lines]]\npath = \"{}\"\ncolor = \"#d0d0d0\"\n{width}\nprofile = \"flat\"\n[render]\nmethod = \"lineao\"\n",
        tracts.display()
    )
}

/// The camera keys of the synthetic scenes' view centred on `(x, y)` with view height `h`.
fn camera_at(x: f64, y: f64, h: f64) -> Vec<String> {
    vec![
        format!("camera.eye=[{x}, {y}, 200.0]"),
        format!("camera.target=[{x}, {y}, 0.0]"),
        format!("camera.height={h}"),
    ]
}

/// The settings the method rows of a case run with.
#[derive(Clone)]
struct Methods<'a> {
    geo: &'a Geometry<'a>,
    case: &'a str,
    view: Vec<String>,
    frames: u32,
    images: PathBuf,
}

impl Methods<'_> {
    fn with_view(&self, extra: &[&str]) -> Vec<String> {
        let mut v = self.view.clone();
        v.extend(extra.iter().map(|s| s.to_string()));
        v
    }

    fn lineao(&self, extra: &[&str]) -> Result<Frame, String> {
        let mut e = vec!["render.method=\"lineao\""];
        e.extend_from_slice(extra);
        self.geo
            .frame(&self.with_view(&e), "occlusion.lineao", self.frames)
    }

    /// Schott's vicinity at `l_vicinity = distance`.
    fn vicinity(&self, distance: f64) -> Result<Frame, String> {
        let d = format!("render.vicinity_distance={distance}");
        self.geo.frame(
            &self.with_view(&[
                "render.method=\"vicinity\"",
                "render.surface_ao=\"vicinity\"",
                &d,
            ]),
            "occlusion.vicinity",
            self.frames,
        )
    }

    /// The CPU SSAO of an illuminated frame's depth, with LineAO's outermost radius.
    fn ssao(&self) -> Result<Frame, String> {
        let mut f = self.geo.frame(
            &self.with_view(&["render.method=\"illuminated\""]),
            "Z",
            self.frames,
        )?;
        let (outer, px) = self.geo.outer_radius(&self.view)?;
        let t0 = Instant::now();
        let v = ssao(&f.z, f.w, f.h, px, outer, 0.02 * outer, 32, 0x55A0);
        f.ms += t0.elapsed().as_secs_f64() * 1e3;
        f.vis = v;
        Ok(f)
    }

    /// The vicinity distance whose disc `l tan theta` is LineAO's outermost disc.
    fn matched_vicinity(&self) -> Result<f64, String> {
        let s = self.geo.scene(&self.view)?;
        let (outer, _) = self.geo.outer_radius(&self.view)?;
        Ok(outer / s.render.theta.to_radians().tan())
    }

    /// The standard rows: LineAO, vicinity matched and default, SSAO, and the reference.
    fn standard(&self, r: &Reference, rows: &mut Vec<Row>) -> Result<(), String> {
        let l = self.lineao(&[])?;
        let l_match = self.matched_vicinity()?;
        let v = self.vicinity(l_match)?;
        let v2 = self.vicinity(2.0)?;
        let s = self.ssao()?;
        for (m, setting, f) in [
            ("lineao", "paper".to_string(), &l),
            ("vicinity", format!("matched l={l_match:.2}"), &v),
            ("vicinity", "default l=2".to_string(), &v2),
            ("ssao", "cpu from Z".to_string(), &s),
        ] {
            rows.push(self.row(m, &setting, f, r, None)?);
        }
        rows.extend(reference_rows(self.case, "", &l.vis, r));
        write_image(
            &self.images,
            &format!("{}_reference_model-matched", self.case),
            &r.model,
            l.w,
            l.h,
        )?;
        write_image(
            &self.images,
            &format!("{}_reference", self.case),
            &r.ao,
            l.w,
            l.h,
        )?;
        Ok(())
    }

    fn row(
        &self,
        method: &str,
        setting: &str,
        f: &Frame,
        r: &Reference,
        region: Option<&[bool]>,
    ) -> Result<Row, String> {
        if region.is_none() {
            write_image(
                &self.images,
                &format!("{}_{method}_{setting}", self.case),
                &f.vis,
                f.w,
                f.h,
            )?;
        }
        Ok(compare(
            self.case, method, setting, f.ms, &f.vis, r, region, f.w, f.h,
        ))
    }
}

/// Runs `umbra bench lineao`: the rows of results.csv (also written with the charts and the
/// zoom and border tables).
pub fn lineao(c: &Config, progress: &dyn Fn(&str)) -> Result<Vec<Row>, String> {
    let data = c.out.join("data");
    let scenes = c.out.join("scenes");
    let images = c.out.join("images");
    for d in [&data, &scenes, &images] {
        std::fs::create_dir_all(d).map_err(|e| format!("{}: {e}", d.display()))?;
    }
    let n = c.size;
    let mut size = vec![format!("render.width={n}"), format!("render.height={n}")];
    size.extend(c.set.iter().cloned());
    let gpu = engine::gpu::Gpu::new().map_err(|e| e.to_string())?;
    let write =
        |p: &Path, text: &str| volume::write_atomic(p, text.as_bytes()).map_err(|e| e.to_string());
    // The synthetic lines and their scenes.
    let (main, cross) = if c.quick { (120, 40) } else { (200, 80) };
    tubes::save(&data.join("bundle.tck"), &dense_bundle(main, cross)).map_err(|e| e.to_string())?;
    tubes::save(&data.join("isolated.tck"), &isolated_lines()).map_err(|e| e.to_string())?;
    let px = 100.0 / n as f64;
    let pixel_width = "width = 2.0".to_string();
    // World width of 2 pixels at 1x: the zoom case's lines keep their world size.
    let world_width = format!("width = {}\nwidth_unit = \"world\"", 2.0 * px);
    let bundle_scene = scenes.join("bundle.toml");
    write(
        &bundle_scene,
        &synthetic_scene(&data.join("bundle.tck"), &pixel_width),
    )?;
    let isolated_scene = scenes.join("isolated.toml");
    write(
        &isolated_scene,
        &synthetic_scene(&data.join("isolated.tck"), &pixel_width),
    )?;
    let world_scene = scenes.join("bundle_world.toml");
    write(
        &world_scene,
        &synthetic_scene(&data.join("bundle.tck"), &world_width),
    )?;
    let mut rows: Vec<Row> = vec![];
    let seed = 0x011A_E0A0;

    // Isolated lines.
    progress("isolated: reference");
    let iso = Geometry::new(&gpu, &isolated_scene, size.clone())?;
    let iso_ref = iso.reference(&[], c.spp, seed)?;
    progress("isolated: methods");
    Methods {
        geo: &iso,
        case: "isolated",
        view: vec![],
        frames: c.frames,
        images: images.clone(),
    }
    .standard(&iso_ref, &mut rows)?;
    drop(iso);
    {
        let mut over = size.clone();
        over.push("lines.0.profile=\"cylinder\"".into());
        let cyl = Geometry::new(&gpu, &isolated_scene, over)?;
        let f = cyl.frame(&[], "occlusion.lineao", c.frames)?;
        rows.push(compare(
            "isolated",
            "lineao",
            "pseudo-cylinder",
            f.ms,
            &f.vis,
            &iso_ref,
            None,
            f.w,
            f.h,
        ));
        write_image(&images, "isolated_lineao_pseudo-cylinder", &f.vis, f.w, f.h)?;
    }

    // The dense bundle: every method, and LineAO on flat ribbons.
    progress("dense: reference");
    let bundle = Geometry::new(&gpu, &bundle_scene, size.clone())?;
    let bundle_ref = bundle.reference(&[], c.spp, seed)?;
    progress("dense: methods");
    let dense = Methods {
        geo: &bundle,
        case: "dense",
        view: vec![],
        frames: c.frames,
        images: images.clone(),
    };
    dense.standard(&bundle_ref, &mut rows)?;
    {
        let mut over = size.clone();
        over.push("lines.0.profile=\"cylinder\"".into());
        let cyl = Geometry::new(&gpu, &bundle_scene, over)?;
        let f = cyl.frame(&[], "occlusion.lineao", c.frames)?;
        rows.push(dense.row("lineao", "pseudo-cylinder", &f, &bundle_ref, None)?);
    }

    // s_h against the reference and against LineAO's own converged image.
    let mut samples_pts = (vec![], vec![]);
    if !c.quick {
        progress("samples");
        let samples = Methods {
            case: "samples",
            ..dense.clone()
        };
        let conv = samples.lineao(&["render.lineao.samples=1024"])?;
        for sh in [8u32, 16, 32, 64, 128, 256, 1024] {
            let f = if sh == 1024 {
                conv.clone()
            } else {
                samples.lineao(&[format!("render.lineao.samples={sh}").as_str()])?
            };
            let mut r = samples.row("lineao", &format!("s_h={sh}"), &f, &bundle_ref, None)?;
            let d: Vec<f64> = (0..f.vis.len())
                .filter(|&i| f.vis[i].is_finite() && conv.vis[i].is_finite())
                .map(|i| (f.vis[i] - conv.vis[i]).powi(2))
                .collect();
            r.rmse_converged = (d.iter().sum::<f64>() / d.len().max(1) as f64).sqrt();
            if sh < 1024 {
                samples_pts.0.push((sh as f64, r.rmse_converged));
            }
            samples_pts.1.push((sh as f64, r.agreement.rmse_affine));
            rows.push(r);
        }

        // Falloff.
        progress("falloff");
        let falloff = Methods {
            case: "falloff",
            ..dense.clone()
        };
        for f in ["paper", "constant"] {
            let fr = falloff.lineao(&[format!("render.lineao.falloff=\"{f}\"").as_str()])?;
            rows.push(falloff.row("lineao", &format!("falloff={f}"), &fr, &bundle_ref, None)?);
        }
    }

    if !c.quick {
        zoom_case(
            c,
            &gpu,
            &world_scene,
            &size,
            &images,
            seed,
            &mut rows,
            progress,
        )?;
        border_case(
            c,
            &gpu,
            &bundle_scene,
            &size,
            &images,
            seed,
            &mut rows,
            progress,
        )?;
        real_cases(c, &gpu, &size, &images, seed, &mut rows, progress)?;
    }
    drop(dense);
    drop(bundle);

    // results.csv
    let mut csv = Vec::new();
    let _ = writeln!(csv, "{CSV_HEADER}");
    for r in &rows {
        let _ = writeln!(csv, "{}", r.csv());
    }
    volume::write_atomic(&c.out.join("results.csv"), &csv).map_err(|e| e.to_string())?;
    // The Pareto chart of the dense bundle's rows (one scene): affine-calibrated error
    // against time, a series per method.
    let on_dense: Vec<&Row> = rows
        .iter()
        .filter(|r| {
            matches!(r.case.as_str(), "dense" | "samples" | "falloff")
                && r.method != "reference"
                && r.agreement.rmse_affine.is_finite()
                && r.ms > 0.0
        })
        .collect();
    let series_of = |r: &Row| match r.case.as_str() {
        "samples" => "lineao, s_h sweep".to_string(),
        "falloff" => format!("lineao, {}", r.setting),
        _ => format!("{} ({})", r.method, r.setting),
    };
    let mut names: Vec<String> = on_dense.iter().map(|r| series_of(r)).collect();
    names.sort();
    names.dedup();
    let pts: Vec<(f64, f64)> = on_dense
        .iter()
        .map(|r| (r.ms, r.agreement.rmse_affine))
        .collect();
    write_chart(
        &c.out,
        "pareto",
        &Plot {
            title: "LineAO against ray-traced AO, dense bundle: error against time".into(),
            x_label: "frame time (ms, median; ssao: CPU pass added)".into(),
            y_label: "affine-calibrated RMSE against the reference".into(),
            series: names
                .iter()
                .map(|nm| {
                    (
                        nm.clone(),
                        on_dense
                            .iter()
                            .filter(|r| series_of(r) == *nm)
                            .map(|r| (r.ms, r.agreement.rmse_affine))
                            .collect(),
                    )
                })
                .collect(),
            line: Some((
                "Pareto front".into(),
                pareto(&pts).into_iter().map(|i| pts[i]).collect(),
            )),
        },
    )?;
    if !samples_pts.0.is_empty() {
        write_chart(
            &c.out,
            "samples",
            &Plot {
                title: "LineAO's s_h on the dense bundle".into(),
                x_label: "s_h (samples of the first disc)".into(),
                y_label: "RMSE".into(),
                series: vec![
                    (
                        "noise: against LineAO at s_h = 1024".into(),
                        samples_pts.0.clone(),
                    ),
                    (
                        "error: affine-calibrated, against the reference".into(),
                        samples_pts.1.clone(),
                    ),
                ],
                line: None,
            },
        )?;
    }
    Ok(rows)
}

/// The zoom case: world-width lines at 1x, 2x, 4x, 8x; rows against each zoom's reference and
/// `<dir>/zoom.csv` at world-anchored probes.
#[allow(clippy::too_many_arguments)]
fn zoom_case(
    c: &Config,
    gpu: &engine::gpu::Gpu,
    scene: &Path,
    size: &[String],
    images: &Path,
    seed: u64,
    rows: &mut Vec<Row>,
    progress: &dyn Fn(&str),
) -> Result<(), String> {
    let n = c.size as usize;
    let geo = Geometry::new(gpu, scene, size.to_vec())?;
    let px = 100.0 / n as f64;
    let zooms = [1usize, 2, 4, 8];
    // Per zoom and method: the visibility; the reference; Z (LineAO's frame).
    let methods = ["lineao", "vicinity", "ssao", "reference"];
    let mut vis: Vec<Vec<Vec<f64>>> = vec![];
    let mut zs: Vec<Vec<f32>> = vec![];
    // The vicinity distance stays the 1x one (a world length: zoom-invariant).
    let mut l_match = None;
    for &k in &zooms {
        progress(&format!("zoom {k}x"));
        // Offset so that the 1x pixel centres are pixel centres at k: a 1x centre at
        // (i + 1/2 - n/2) px lands on k's pixel n/2 + k (i - n/2).
        let off = 0.5 * px * (1.0 - 1.0 / k as f64);
        let view = camera_at(off, -off, 100.0 / k as f64);
        let m = Methods {
            geo: &geo,
            case: "zoom",
            view: view.clone(),
            frames: c.frames,
            images: images.to_path_buf(),
        };
        let l_vic = match l_match {
            Some(l) => l,
            None => {
                let l = m.matched_vicinity()?;
                l_match = Some(l);
                l
            }
        };
        let r = geo.reference(&view, c.spp, seed ^ k as u64)?;
        let la = m.lineao(&[])?;
        let vi = m.vicinity(l_vic)?;
        let ss = m.ssao()?;
        let tag = format!("{k}x");
        rows.push(m.row("lineao", &tag, &la, &r, None)?);
        rows.push(m.row("vicinity", &format!("{tag} l={l_vic:.2}"), &vi, &r, None)?);
        rows.push(m.row("ssao", &tag, &ss, &r, None)?);
        rows.extend(reference_rows("zoom", &tag, &la.vis, &r));
        write_image(images, &format!("zoom_reference_{tag}"), &r.ao, la.w, la.h)?;
        // The alignment the offset promises, checked.
        let (cam1, _, _) = geo.view(&camera_at(0.0, 0.0, 100.0))?;
        let (camk, _, _) = geo.view(&view)?;
        let i = n / 2 - n / 16;
        let (o, d) = cam1.ray(i as f64, i as f64, n, n);
        let (qx, qy, _) = camk
            .to_pixel(o + d * 200.0, n, n)
            .ok_or("zoom: a probe behind the camera")?;
        let want = (n / 2) as f64 - (k * (n / 2 - i)) as f64 + 0.5;
        if (qx - want).abs() > 1e-6 || (qy - want).abs() > 1e-6 {
            return Err(format!(
                "zoom {k}x: the probe lands at ({qx}, {qy}), not the pixel centre {want}"
            ));
        }
        vis.push(vec![la.vis, vi.vis, ss.vis, r.ao]);
        zs.push(la.z);
    }
    // Probes: the 1x pixels of the 8x view's area; valid where every zoom covers them with the
    // same surface (depths within the tube radius) and every method has a value.
    let rho = px;
    let half = n / 16;
    let mut probes: Vec<[usize; 4]> = vec![];
    for y in n / 2 - half..n / 2 + half {
        for x in n / 2 - half..n / 2 + half {
            let idx: Vec<usize> = zooms
                .iter()
                .map(|&k| {
                    let (xk, yk) = (n / 2 + k * x - k * (n / 2), n / 2 + k * y - k * (n / 2));
                    xk + n * yk
                })
                .collect();
            let z1 = zs[0][idx[0]];
            let ok = (0..zooms.len()).all(|zi| {
                let zk = zs[zi][idx[zi]];
                zk > 0.0
                    && ((zk - z1) as f64).abs() < rho
                    && (0..methods.len()).all(|mi| vis[zi][mi][idx[zi]].is_finite())
            });
            if ok {
                probes.push([idx[0], idx[1], idx[2], idx[3]]);
            }
        }
    }
    let mut csv = Vec::new();
    let _ = writeln!(
        csv,
        "method,zoom,probes,mean_visibility,mean_abs_change_from_1x,mean_cv"
    );
    for (mi, m) in methods.iter().enumerate() {
        // Per probe: its coefficient of variation across the zooms.
        let cv: f64 = probes
            .iter()
            .map(|p| {
                let v: Vec<f64> = (0..zooms.len()).map(|zi| vis[zi][mi][p[zi]]).collect();
                let mean = v.iter().sum::<f64>() / v.len() as f64;
                let var = v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / v.len() as f64;
                var.sqrt() / mean.max(1e-9)
            })
            .sum::<f64>()
            / probes.len().max(1) as f64;
        for (zi, k) in zooms.iter().enumerate() {
            let np = probes.len().max(1) as f64;
            let mean = probes.iter().map(|p| vis[zi][mi][p[zi]]).sum::<f64>() / np;
            let change = probes
                .iter()
                .map(|p| (vis[zi][mi][p[zi]] - vis[0][mi][p[0]]).abs())
                .sum::<f64>()
                / np;
            let _ = writeln!(
                csv,
                "{m},{k},{},{mean:.5},{change:.5},{cv:.5}",
                probes.len()
            );
        }
    }
    volume::write_atomic(&c.out.join("zoom.csv"), &csv).map_err(|e| e.to_string())
}

/// The border case: the dense bundle panned so that the left image edge cuts it, with the
/// guard band (64) and without (0); rows per region against the reference, and
/// `<dir>/border.csv` against a render 32 pixels wider a side (the screen-space truth).
#[allow(clippy::too_many_arguments)]
fn border_case(
    c: &Config,
    gpu: &engine::gpu::Gpu,
    scene: &Path,
    size: &[String],
    images: &Path,
    seed: u64,
    rows: &mut Vec<Row>,
    progress: &dyn Fn(&str),
) -> Result<(), String> {
    let n = c.size as usize;
    let pad = 32usize;
    let view = camera_at(25.0, 0.0, 100.0);
    let geo = Geometry::new(gpu, scene, size.to_vec())?;
    let mut wide_view = view.clone();
    wide_view.push(format!("render.width={}", n + 2 * pad));
    progress("border: reference (wide)");
    let wide_ref = geo.reference(&wide_view, c.spp, seed ^ 0xB0)?;
    let crop = |v: &[f64]| -> Vec<f64> {
        (0..n * n)
            .map(|i| v[(i % n) + pad + (n + 2 * pad) * (i / n)])
            .collect()
    };
    let r = Reference {
        ao: crop(&wide_ref.ao),
        stderr: crop(&wide_ref.stderr),
        model: crop(&wide_ref.model),
        model_stderr: crop(&wide_ref.model_stderr),
        ms: wide_ref.ms,
    };
    let m = Methods {
        geo: &geo,
        case: "border",
        view: view.clone(),
        frames: c.frames,
        images: images.to_path_buf(),
    };
    let (outer, px) = geo.outer_radius(&view)?;
    let strip_px = (outer / px).ceil() as usize;
    let strip: Vec<bool> = (0..n * n)
        .map(|i| {
            let (x, y) = (i % n, i / n);
            x.min(y).min(n - 1 - x).min(n - 1 - y) < strip_px
        })
        .collect();
    let interior: Vec<bool> = strip.iter().map(|s| !s).collect();
    progress("border: frames");
    let mut csv = Vec::new();
    let _ = writeln!(
        csv,
        "samples,guard,region,pixels,rmse_vs_wide,bias_vs_wide,max_abs_vs_wide"
    );
    // At the default s_h (the rows against the reference too) and at 1024, where the per-pixel
    // rotation's noise, which differs between the wide and the panned pixel grids, is gone.
    for sh in [32u32, 1024] {
        let samples = format!("render.lineao.samples={sh}");
        let mut wv = wide_view.clone();
        wv.push("render.method=\"lineao\"".into());
        wv.push(samples.clone());
        let wide = geo.frame(&wv, "occlusion.lineao", c.frames)?;
        let truth = crop(&wide.vis);
        for g in [64u32, 0] {
            let f = m.lineao(&[
                format!("render.lineao.guard={g}").as_str(),
                samples.as_str(),
            ])?;
            if sh == 32 {
                write_image(images, &format!("border_lineao_guard{g}"), &f.vis, n, n)?;
            }
            for (name, region) in [("strip", &strip), ("interior", &interior)] {
                if sh == 32 {
                    rows.push(m.row(
                        "lineao",
                        &format!("guard={g} {name} ({strip_px} px)"),
                        &f,
                        &r,
                        Some(region),
                    )?);
                }
                let d: Vec<f64> = (0..n * n)
                    .filter(|&i| region[i] && f.vis[i].is_finite() && truth[i].is_finite())
                    .map(|i| f.vis[i] - truth[i])
                    .collect();
                let k = d.len().max(1) as f64;
                let _ = writeln!(
                    csv,
                    "{sh},{g},{name},{},{:.6},{:.6},{:.6}",
                    d.len(),
                    (d.iter().map(|x| x * x).sum::<f64>() / k).sqrt(),
                    d.iter().sum::<f64>() / k,
                    d.iter().fold(0.0f64, |a, x| a.max(x.abs()))
                );
            }
        }
    }
    write_image(images, "border_reference", &r.ao, n, n)?;
    volume::write_atomic(&c.out.join("border.csv"), &csv).map_err(|e| e.to_string())
}

/// The real tracts: HCP1065 bundles, dipy's tracks300, carotid streamlines; each case whose
/// data is missing is skipped with a note.
#[allow(clippy::too_many_arguments)]
fn real_cases(
    c: &Config,
    gpu: &engine::gpu::Gpu,
    size: &[String],
    images: &Path,
    seed: u64,
    rows: &mut Vec<Row>,
    progress: &dyn Fn(&str),
) -> Result<(), String> {
    let max = 800;
    let data = c.out.join("data");
    let bench_scenes = {
        let built = Path::new(env!("CARGO_MANIFEST_DIR")).join("../bench/scenes");
        if built.join("lineao_dipy.toml").exists() {
            built
        } else {
            PathBuf::from("bench/scenes")
        }
    };
    let mut cases: Vec<(String, PathBuf, Vec<String>)> = vec![];
    for (case, file) in [
        ("hcp-cst-l", "lineao_hcp_cst_l.toml"),
        ("hcp-af-r", "lineao_hcp_af_r.toml"),
        ("dipy", "lineao_dipy.toml"),
    ] {
        let path = bench_scenes.join(file);
        let s = match spec::load(&path, size) {
            Ok(s) => s,
            Err(e) => {
                eprintln!("note: {case} skipped: {e}");
                continue;
            }
        };
        // Every k-th streamline of each set, at most `max` a set.
        let mut over = size.to_vec();
        let mut ok = true;
        for (i, l) in s.lines.iter().enumerate() {
            let dst = data.join(format!("{case}_{i}.tck"));
            match subsample(&l.path, max, &dst) {
                Ok((kept, of)) => {
                    eprintln!("{case}: lines[{i}]: {kept} of {of} streamlines");
                    over.push(format!("lines.{i}.path=\"{}\"", dst.display()));
                }
                Err(e) => {
                    eprintln!("note: {case} skipped: {e}");
                    ok = false;
                }
            }
        }
        if ok {
            cases.push((case.into(), path, over));
        }
    }
    // Carotid streamlines traced as `umbra demo cfd` traces them.
    let carotid = crate::commands::demo::datasets().join("vtk/carotid.vtk");
    if carotid.exists() {
        progress("carotid: tracing");
        let traced = data.join("carotid_traced.tck");
        crate::commands::trace::trace_to_file(&crate::commands::trace::TraceArgs {
            input: carotid,
            output: traced.clone(),
            field: Some("vectors".into()),
            seeds: "plane:z=3:60".into(),
            step: None,
            integrator: tubes::trace::Integrator::Rk4,
            tolerance: 1e-3,
            max_length: None,
            min_speed: 1.0,
            mask: None,
            threshold: 0.2,
            max_angle: 60.0,
            eigen: false,
            one_way: false,
        })?;
        let sub = data.join("carotid.tck");
        let (kept, of) = subsample(&traced, max, &sub)?;
        eprintln!("carotid: {kept} of {of} streamlines");
        let path = c.out.join("scenes/carotid.toml");
        volume::write_atomic(
            &path,
            format!(
                "# umbra bench lineao: carotid streamlines (umbra demo cfd's seeds) as lines\nbackground = [1.0, 1.0, 1.0]\n[camera]\nprojection = \"orthographic\"\nazimuth = 20.0\nelevation = 35.0\n[[lines]]\npath = \"{}\"\ncolor = \"#d0d0d0\"\nwidth = 2.0\nprofile = \"flat\"\n[render]\nmethod = \"lineao\"\n",
                sub.display()
            )
            .as_bytes(),
        )
        .map_err(|e| e.to_string())?;
        cases.push(("carotid".into(), path, size.to_vec()));
    } else {
        eprintln!("note: carotid skipped: {} is missing", carotid.display());
    }
    for (case, path, over) in cases {
        progress(&format!("{case}: reference"));
        let geo = Geometry::new(gpu, &path, over)?;
        let r = geo.reference(&[], c.spp, seed ^ 0xEA1)?;
        progress(&format!("{case}: methods"));
        Methods {
            geo: &geo,
            case: &case,
            view: vec![],
            frames: c.frames,
            images: images.to_path_buf(),
        }
        .standard(&r, rows)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ssao_leaves_a_flat_surface_open_and_darkens_a_pixel_beside_a_near_wall() {
        let (w, h) = (32, 32);
        // A plane at depth 10, and the right half raised to depth 9 (a step nearer the eye).
        let flat = vec![10.0f32; w * h];
        let v = ssao(&flat, w, h, 0.1, 1.0, 0.02, 32, 1);
        assert!(v.iter().all(|&x| x == 1.0));
        let step: Vec<f32> = (0..w * h)
            .map(|i| if i % w >= 16 { 9.5 } else { 10.0 })
            .collect();
        let v = ssao(&step, w, h, 0.1, 1.0, 0.02, 64, 1);
        // Beside the step (one pixel left of it) samples to the right hit the nearer half.
        let beside = v[15 + w * 16];
        let far = v[2 + w * 16];
        assert!(beside < 0.9 && far == 1.0, "{beside} {far}");
        // Background is NaN and never occludes.
        let mut holes = flat.clone();
        holes[5] = 0.0;
        let v = ssao(&holes, w, h, 0.1, 1.0, 0.02, 16, 1);
        assert!(v[5].is_nan() && v[6] == 1.0);
    }

    #[test]
    fn a_pixel_width_line_is_a_tube_of_half_its_width_in_world_units_under_orthographic() {
        // From its serialised form, so that new keys with defaults do not break the test.
        let l: spec::LinesSpec =
            serde_json::from_str(r#"{"path": "a.tck", "width": 2.0}"#).unwrap();
        let b = [DVec3::splat(-1.0), DVec3::splat(1.0)];
        let cam = Camera::look_at(
            DVec3::new(0.0, 0.0, 10.0),
            DVec3::ZERO,
            DVec3::Y,
            Projection::Orthographic { height: 100.0 },
            b,
        )
        .unwrap();
        assert!((tube_radius(&l, &cam, 128).unwrap() - 100.0 / 128.0).abs() < 1e-12);
        let persp = Camera {
            projection: Projection::Perspective { fov_y_deg: 30.0 },
            ..cam
        };
        assert!(tube_radius(&l, &persp, 128).is_err());
        let world = spec::LinesSpec {
            width: 0.6,
            width_unit: spec::WidthUnit::World,
            ..l.clone()
        };
        assert_eq!(tube_radius(&world, &persp, 128).unwrap(), 0.3);
    }

    #[test]
    fn the_reference_of_one_straight_tube_is_open_and_a_tube_between_walls_is_not() {
        let cam = Camera::look_at(
            DVec3::new(0.0, 0.0, 50.0),
            DVec3::ZERO,
            DVec3::Y,
            Projection::Orthographic { height: 8.0 },
            [DVec3::splat(-5.0), DVec3::splat(5.0)],
        )
        .unwrap();
        let one = tubes::tube_mesh::straight_tubes(
            &[[[-5.0, 0.0, 0.0], [5.0, 0.0, 0.0]]],
            0.5,
            8,
            [1.0; 3],
        );
        let ts = TubeScene::new(&[one], &[]);
        let px = reference_ao(&ts, &cam, 16, 16, 0.5, 32, 7);
        let hit: Vec<&RefPixel> = px.iter().filter(|p| p[0].is_finite()).collect();
        assert!(!hit.is_empty(), "the tube is seen");
        assert!(
            hit.iter().all(|p| p[0] == 1.0 && p[2] == 1.0),
            "a lone convex tube is open: {hit:?}"
        );
        assert!(px[0].iter().all(|v| v.is_nan()), "background");
        // The middle tube of three touching ones is occluded at its flanks, less where it
        // faces the viewer (the model-matched point).
        let three = tubes::tube_mesh::straight_tubes(
            &[
                [[-5.0, -1.0, 0.0], [5.0, -1.0, 0.0]],
                [[-5.0, 0.0, 0.0], [5.0, 0.0, 0.0]],
                [[-5.0, 1.0, 0.0], [5.0, 1.0, 0.0]],
            ],
            0.5,
            8,
            [1.0; 3],
        );
        let ts = TubeScene::new(&[three], &[]);
        let px = reference_ao(&ts, &cam, 16, 16, 0.5, 64, 7);
        let hit: Vec<&RefPixel> = px.iter().filter(|p| p[0].is_finite()).collect();
        let mean = |k: usize| hit.iter().map(|p| p[k]).sum::<f64>() / hit.len() as f64;
        assert!(mean(0) < 0.95, "{}", mean(0));
        assert!(mean(2) > mean(0), "{} {}", mean(2), mean(0));
    }
}
