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
//! * **Case groups** (`--cases`, default `accuracy,aniso`): `accuracy` is everything above;
//!   `aniso` is anisotropic LineAO (Köhler et al. 2011, seed 002 §4.2, eq. 10-12; issue 12
//!   item 6), classic LineAO beside `render.lineao.anisotropic = true` with
//!   `alignment = "paper"` and `"invariant"`:
//!   - *roll* ([`crossing_bundles`]): a bundle along x with depth spread over a one-layer bundle
//!     at 60 degrees behind it, flat 2-pixel lines, orthographic from +z, the camera rolled
//!     0 to 90 degrees in 15-degree steps (its `up` turned about the view axis), at `I` = 5, 15
//!     and 25. Pixels are classed by the world point their centre sees, inside a disc about the
//!     centre that keeps every sample on screen at every roll: *parallel* (front-bundle pixels
//!     whose discs cannot reach the crossing bundle: only parallel neighbours occlude them) and
//!     *crossing* (crossing-bundle pixels inside the front bundle's band: only the crossing
//!     lines occlude them, the layer has no depth of its own). Per roll and setting: the mean
//!     occlusion `1 - visibility` in each, their ratios to classic LineAO's at the same roll
//!     and the mean `g_align` (`<dir>/aniso_roll.csv`, [`ROLL_HEADER`]); per setting, the
//!     coefficients of variation (population) across the rolls and the ratios' mean, least and
//!     largest (`<dir>/aniso_summary.csv`, [`SUMMARY_HEADER`]); `<dir>/aniso_roll.svg` (the
//!     ratios against the roll, linear axes, SVG only).
//!   - *flicker* ([`trail_lines`]): the dense bundle's lines with a per-point `time`
//!     (`data/trails.trk`, one unit a point from a per-line phase), drawn as tapered trails
//!     (`back = forward = 8`, the default taper) at `now = 0, 2, .., 14` (8 frames, as
//!     `umbra render --trail-range 0:14:8`); per pair of consecutive frames, at the pixels both
//!     cover with the same surface (depths within the tube radius) and the reference hits in
//!     both: the mean absolute change of the visibility, the mean occlusion, their ratio, the
//!     fraction changing by more than 0.05 and the correlation of the change with the
//!     reference's, for classic, invariant and paper LineAO and the physical ray-traced
//!     reference of the same trails (tubes of the tapered width in four steps, [`trail_pieces`],
//!     `--spp` paths, the same per-pixel seed in every frame) (`<dir>/aniso_flicker.csv`,
//!     [`FLICKER_HEADER`]).
//!
//!   Images `<dir>/images/aniso_*.png`, among them `aniso_roll0_montage.png` and
//!   `aniso_roll30_montage.png` (visibility of classic, paper and invariant at I = 15 side by
//!   side, the two `g_align` channels below) and `aniso_regions_roll0.png` (parallel pixels
//!   dark, crossing pixels light grey). `--quick` runs the same at its size and paths.

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
    /// A small run: of the accuracy group only the isolated lines and the dense bundle, the
    /// anisotropic group with fewer lines; 96 x 96, 16 paths per pixel, one frame.
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
    /// Case groups, comma-separated: `accuracy` (LineAO against the ray-traced references: the
    /// isolated lines, the dense bundle, s_h, the falloff, zoom, borders, the real tracts;
    /// results.csv and its charts) and `aniso` (anisotropic LineAO: camera roll, parallel
    /// against crossing, the intensity I, trail flicker; aniso_*.csv).
    #[arg(long, default_value = "accuracy,aniso", value_name = "LIST")]
    cases: String,
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
        cases: Cases::parse(&a.cases)?,
    };
    if !(16..=2048).contains(&cfg.size) {
        return Err(format!("--size {}: choose 16 to 2048 pixels", cfg.size));
    }
    if cfg.spp == 0 || cfg.frames == 0 {
        return Err("--spp and --frames must be at least 1".into());
    }
    let progress = Stages::new(true);
    let outcome = lineao(&cfg, &|m| progress.stage(m))?;
    drop(progress);
    let rows = &outcome.rows;
    if cfg.cases.accuracy {
        out(format!(
            "{:10} {:9} {:24} {:>9} {:>7} {:>7} {:>7} {:>6} {:>6} {:>6} {:>6}",
            "case",
            "method",
            "setting",
            "ms",
            "rmse",
            "bias",
            "affine",
            "rho",
            "ssim",
            "vis",
            "pixels"
        ))?;
        for r in rows {
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
    }
    if cfg.cases.aniso {
        out(format!(
            "{:12} {:9} {:>4} {:>8} {:>8} {:>8} {:>9} {:>9} {:>9} {:>9}",
            "aniso roll",
            "alignment",
            "I",
            "cv_occ",
            "cv_par",
            "cv_cross",
            "ratio_par",
            "(min-max)",
            "ratio_x",
            "(min-max)"
        ))?;
        for r in &outcome.aniso {
            out(format!(
                "{:12} {:9} {:>4} {:8.4} {:8.4} {:8.4} {:9.3} {:>9} {:9.3} {:>9}",
                r.method,
                r.alignment,
                r.intensity_label(),
                r.cv_occlusion,
                r.cv_parallel,
                r.cv_crossing,
                r.ratio_parallel[0],
                format!("{:.2}-{:.2}", r.ratio_parallel[1], r.ratio_parallel[2]),
                r.ratio_crossing[0],
                format!("{:.2}-{:.2}", r.ratio_crossing[1], r.ratio_crossing[2]),
            ))?;
        }
        out(format!(
            "{:9} {:26} {:>6} {:>7} {:>7} {:>7} {:>7} {:>7} {:>7} {:>7}",
            "flicker",
            "setting",
            "pixels",
            "occ",
            "d_abs",
            "d/occ",
            ">0.05",
            "rms",
            "r_ref",
            "r_model"
        ))?;
        for r in &outcome.flicker {
            out(format!(
                "{:9} {:26} {:6} {:7.4} {:7.4} {:7.3} {:7.3} {:7.4} {:7.3} {:7.3}",
                r.method,
                r.setting,
                r.pixels,
                r.mean_occlusion,
                r.mean_abs_change,
                r.relative_change,
                r.frac_above,
                r.rms_change_denoised,
                r.pearson_reference,
                r.pearson_model
            ))?;
        }
    }
    let mut wrote = vec![];
    if cfg.cases.accuracy {
        wrote.extend(["results.csv", "pareto.svg", "pareto.png"]);
        if !a.quick {
            wrote.extend(["samples.svg", "samples.png", "zoom.csv", "border.csv"]);
        }
    }
    if cfg.cases.aniso {
        wrote.extend([
            "aniso_roll.csv",
            "aniso_summary.csv",
            "aniso_roll.svg",
            "aniso_flicker.csv",
        ]);
    }
    let d = a.output.display();
    eprintln!(
        "wrote {}",
        wrote
            .iter()
            .map(|f| format!("{d}/{f}"))
            .collect::<Vec<_>>()
            .join(", ")
    );
    Ok(())
}

/// The case groups `--cases` selects.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Cases {
    /// LineAO against the ray-traced references (results.csv, its charts, zoom, border).
    pub accuracy: bool,
    /// Anisotropic LineAO: roll, parallel against crossing, I, flicker (aniso_*.csv).
    pub aniso: bool,
}

impl Cases {
    /// `accuracy`, `aniso`, comma-separated (`all` for both).
    pub fn parse(list: &str) -> Result<Cases, String> {
        let mut c = Cases {
            accuracy: false,
            aniso: false,
        };
        for w in list.split(',').map(str::trim).filter(|w| !w.is_empty()) {
            match w {
                "accuracy" => c.accuracy = true,
                "aniso" => c.aniso = true,
                "all" => (c.accuracy, c.aniso) = (true, true),
                _ => {
                    return Err(format!(
                        "--cases {list}: unknown group {w:?} (choose from accuracy, aniso, all)"
                    ))
                }
            }
        }
        if !(c.accuracy || c.aniso) {
            return Err(format!("--cases {list:?}: name at least one group"));
        }
        Ok(c)
    }
}

/// What a run gives: results.csv's rows (the `accuracy` group), and the `aniso` group's
/// summary and flicker rows.
pub struct Outcome {
    pub rows: Vec<Row>,
    pub aniso: Vec<AnisoSummary>,
    pub flicker: Vec<FlickerRow>,
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
    /// The case groups to run.
    pub cases: Cases,
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
        Ok(self.frame_at(extra, &[ch], frames, None)?.0)
    }

    /// [`Geometry::frame`] with every trail drawn at `now` (when given, as `umbra render
    /// --trail-range`): the frame of the first of `chs`, and the others (NaN where `Z` is 0).
    fn frame_at(
        &self,
        extra: &[String],
        chs: &[&str],
        frames: u32,
        now: Option<f64>,
    ) -> Result<(Frame, Vec<Vec<f64>>), String> {
        let s = self.scene(extra)?;
        let (o, view) = self.up.draw_at(
            &s,
            &self.model,
            engine::renderer::DrawOptions {
                frames,
                pass_timings: false,
            },
            now,
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
        let mut vs = vec![];
        for &ch in chs {
            let v = if ch == "Z" { z.clone() } else { get(ch)? };
            vs.push(
                v.iter()
                    .zip(&z)
                    .map(|(&v, &z)| if z > 0.0 { v as f64 } else { f64::NAN })
                    .collect::<Vec<f64>>(),
            );
        }
        if vs.is_empty() {
            return Err("bench lineao: a frame needs a channel".into());
        }
        let vis = vs.remove(0);
        Ok((
            Frame {
                vis,
                z,
                ms: o.timings.total_ms,
                w: view.width as usize,
                h: view.height as usize,
            },
            vs,
        ))
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

/// Runs `umbra bench lineao`: the selected case groups.
pub fn lineao(c: &Config, progress: &dyn Fn(&str)) -> Result<Outcome, String> {
    // The scenes written under `<out>/scenes` name their data by path, and a scene's paths
    // resolve against the scene's folder: a relative output folder must not reach them as is.
    let c = &Config {
        out: std::path::absolute(&c.out).map_err(|e| format!("{}: {e}", c.out.display()))?,
        ..c.clone()
    };
    let n = c.size;
    let mut size = vec![format!("render.width={n}"), format!("render.height={n}")];
    size.extend(c.set.iter().cloned());
    // The overrides are checked on a scene of the bench's kind (lines, LineAO) before anything
    // is written or traced: an unknown key or a value out of range ends the run here.
    spec::parse(
        "[[lines]]\npath = \"lines.tck\"\n[render]\nmethod = \"lineao\"\n",
        "the bench's scenes with --set",
        &c.out,
        &size,
    )?;
    for d in ["data", "scenes", "images"] {
        let d = c.out.join(d);
        std::fs::create_dir_all(&d).map_err(|e| format!("{}: {e}", d.display()))?;
    }
    let gpu = engine::gpu::Gpu::new().map_err(|e| e.to_string())?;
    let rows = if c.cases.accuracy {
        accuracy_cases(c, &gpu, &size, progress)?
    } else {
        vec![]
    };
    let (aniso, flicker) = if c.cases.aniso {
        aniso_cases(c, &gpu, &size, progress)?
    } else {
        (vec![], vec![])
    };
    Ok(Outcome {
        rows,
        aniso,
        flicker,
    })
}

/// The `accuracy` group: the rows of results.csv (also written with the charts and the zoom
/// and border tables).
fn accuracy_cases(
    c: &Config,
    gpu: &engine::gpu::Gpu,
    size: &[String],
    progress: &dyn Fn(&str),
) -> Result<Vec<Row>, String> {
    let data = c.out.join("data");
    let scenes = c.out.join("scenes");
    let images = c.out.join("images");
    let n = c.size;
    let size = size.to_vec();
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
    let iso = Geometry::new(gpu, &isolated_scene, size.clone())?;
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
        let cyl = Geometry::new(gpu, &isolated_scene, over)?;
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
    let bundle = Geometry::new(gpu, &bundle_scene, size.clone())?;
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
        let cyl = Geometry::new(gpu, &bundle_scene, over)?;
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
            gpu,
            &world_scene,
            &size,
            &images,
            seed,
            &mut rows,
            progress,
        )?;
        border_case(
            c,
            gpu,
            &bundle_scene,
            &size,
            &images,
            seed,
            &mut rows,
            progress,
        )?;
        real_cases(c, gpu, &size, &images, seed, &mut rows, progress)?;
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
        crate::commands::demo::trace_carotid(&carotid, &traced)?;
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

// ---------------------------------------------------------------------------------------------
// The `aniso` group: anisotropic LineAO (Köhler et al. 2011, seed 002 §4.2, eq. 10-12).

/// Half the width of the roll case's bundles' bands (world units).
pub const BAND: f32 = 12.0;
/// The angle of the roll case's crossing bundle to x (degrees).
pub const CROSSING_DEG: f32 = 60.0;
/// The roll case's crossing layer lies at this z (the front bundle within `z` in [-4, 4]).
const CROSSING_Z: f32 = -12.0;
/// The roll case's view height (world units) and its camera's distance from the origin.
const ROLL_VIEW: f64 = 80.0;
const EYE_Z: f64 = 200.0;
/// The rolls (degrees) and the intensities `I` (seed 002 Fig. 3) of the roll case.
pub const ROLLS: [f64; 7] = [0.0, 15.0, 30.0, 45.0, 60.0, 75.0, 90.0];
pub const INTENSITIES: [f64; 3] = [5.0, 15.0, 25.0];
/// The flicker case's trail window (time units a side) and its frames' times.
const TRAIL_HALF: f64 = 8.0;
const TRAIL_NOW: (f64, f64, usize) = (0.0, 14.0, 8);

/// The roll case's lines: `front` straight lines along x over [-55, 55] (111 points), evenly
/// spread across `[-BAND, BAND]` in y (each moved by up to 0.3 of the spacing) with z uniform
/// in [-4, 4], each turned by a Gaussian angle of 1.5 degrees; behind them `back` straight
/// lines at `CROSSING_DEG` to x (110 long), spread likewise across the same width, turned
/// likewise, all at `z = -12` (one layer: they do not occlude each other, so what occludes
/// them is the front bundle alone).
pub fn crossing_bundles(front: usize, back: usize) -> tubes::Streamlines {
    let mut rng = SplitMix64(0xA1150);
    let mut sl = tubes::Streamlines::new();
    let jitter = |rng: &mut SplitMix64| 1.5f32.to_radians() * gauss(rng);
    let uniform = |rng: &mut SplitMix64, a: f32| a * (2.0 * rng.next_f64() as f32 - 1.0);
    let spread = |rng: &mut SplitMix64, k: usize, n: usize| {
        -BAND + (k as f32 + 0.5 + uniform(rng, 0.3)) * 2.0 * BAND / n as f32
    };
    for k in 0..front {
        let (y0, z0) = (spread(&mut rng, k, front), uniform(&mut rng, 4.0));
        let j = jitter(&mut rng);
        let d = Vec3::new(j.cos(), j.sin(), 0.0);
        let pts: Vec<Vec3> = (-55..=55)
            .map(|i| Vec3::new(0.0, y0, z0) + d * i as f32)
            .collect();
        sl.push(&pts);
    }
    let a = CROSSING_DEG.to_radians();
    let perp = Vec3::new(-a.sin(), a.cos(), 0.0);
    for k in 0..back {
        let off = spread(&mut rng, k, back);
        let b = a + jitter(&mut rng);
        let d = Vec3::new(b.cos(), b.sin(), 0.0);
        let pts: Vec<Vec3> = (-55..=55)
            .map(|i| perp * off + d * i as f32 + Vec3::new(0.0, 0.0, CROSSING_Z))
            .collect();
        sl.push(&pts);
    }
    sl
}

/// The flicker case's lines: [`dense_bundle`]`(main, cross)` with a per-point attribute
/// `time`: point i of a line at `i + phase`, the phase uniform in `[23 - n, -8]` for a line of
/// n points, so that its trail (`now` in [0, 14], 8 either side) lies within the line.
pub fn trail_lines(main: usize, cross: usize) -> tubes::Streamlines {
    let mut sl = dense_bundle(main, cross);
    let mut rng = SplitMix64(0x7A11);
    let mut times = Vec::with_capacity(sl.points.len());
    for k in 0..sl.len() {
        let n = sl.line(k).len() as f64;
        let phase = (23.0 - n) + rng.next_f64() * (n - 31.0);
        times.extend((0..sl.line(k).len()).map(|i| (i as f64 + phase) as f32));
    }
    sl.point_attributes.push(tubes::Attribute {
        name: "time".into(),
        components: 1,
        values: times,
    });
    sl
}

/// The visible parts of `sl`'s trails at `trail.now` as the renderer draws them (segments cut
/// where their time crosses the window's ends), grouped by width: the full width, and
/// `steps` equal steps of the taper from 1 down to `min_width`, each piece taking the step of
/// the width factor at its middle. Returns (width factor, the pieces of that width).
pub fn trail_pieces(
    sl: &tubes::Streamlines,
    times: &[f32],
    trail: &tubes::lines::Trail,
    steps: usize,
) -> Vec<(f64, tubes::Streamlines)> {
    let steps = steps.max(1);
    let (lo, hi) = (trail.now - trail.back, trail.now + trail.forward);
    let taper = (1.0 - trail.min_width).max(0.0);
    let class = |f: f32| -> usize {
        if f >= 1.0 - 1e-6 || taper <= 0.0 {
            0
        } else {
            1 + (((1.0 - f) / taper * steps as f32) as usize).min(steps - 1)
        }
    };
    let factor = |c: usize| -> f64 {
        if c == 0 {
            1.0
        } else {
            1.0 - (c as f64 - 0.5) / steps as f64 * taper as f64
        }
    };
    let mut out: Vec<tubes::Streamlines> = (0..=steps).map(|_| tubes::Streamlines::new()).collect();
    for k in 0..sl.len() {
        let (a, b) = (sl.offsets[k], sl.offsets[k + 1]);
        let (p, t) = (&sl.points[a..b], &times[a..b]);
        // The run being built: its class and points; it continues while pieces join.
        let mut run: Option<(usize, Vec<Vec3>)> = None;
        let mut flush = |run: &mut Option<(usize, Vec<Vec3>)>| {
            if let Some((c, pts)) = run.take() {
                if pts.len() >= 2 {
                    out[c].push(&pts);
                }
            }
        };
        for i in 0..p.len().saturating_sub(1) {
            let (ta, tb) = (t[i], t[i + 1]);
            if !(ta.is_finite() && tb.is_finite()) {
                flush(&mut run);
                continue;
            }
            let (u0, u1) = if ta == tb {
                if ta >= lo && ta <= hi {
                    (0.0, 1.0)
                } else {
                    (1.0, 0.0)
                }
            } else {
                let (ua, ub) = ((lo - ta) / (tb - ta), (hi - ta) / (tb - ta));
                (ua.min(ub).max(0.0), ua.max(ub).min(1.0))
            };
            if u0 >= u1 {
                flush(&mut run);
                continue;
            }
            let at = |u: f32| p[i] + (p[i + 1] - p[i]) * u;
            let c = class(trail.width_factor(ta + (tb - ta) * 0.5 * (u0 + u1)));
            let joins = u0 == 0.0 && matches!(&run, Some((rc, _)) if *rc == c);
            if !joins {
                flush(&mut run);
                run = Some((c, vec![at(u0)]));
            }
            if let Some((_, pts)) = run.as_mut() {
                pts.push(at(u1));
            }
            if u1 < 1.0 {
                flush(&mut run);
            }
        }
        flush(&mut run);
    }
    out.into_iter()
        .enumerate()
        .filter(|(_, s)| !s.is_empty())
        .map(|(c, s)| (factor(c), s))
        .collect()
}

/// One row of aniso_roll.csv.
#[derive(Clone, Debug)]
pub struct RollRow {
    /// `classic` or `anisotropic`.
    pub method: String,
    /// `-` (classic), `paper` or `invariant`.
    pub alignment: String,
    /// `I` (NaN for classic).
    pub intensity: f64,
    pub roll: f64,
    /// Covered pixels inside the disc, and their mean visibility and occlusion.
    pub pixels: usize,
    pub visibility: f64,
    pub occlusion: f64,
    pub occlusion_parallel: f64,
    pub occlusion_crossing: f64,
    /// Against classic LineAO at the same roll.
    pub ratio_parallel: f64,
    pub ratio_crossing: f64,
    pub g_align_parallel: f64,
    pub g_align_crossing: f64,
    pub parallel_pixels: usize,
    pub crossing_pixels: usize,
    pub ms: f64,
}

/// The header of aniso_roll.csv.
pub const ROLL_HEADER: &str = "method,alignment,intensity,roll_deg,pixels,mean_visibility,occlusion,occlusion_parallel,occlusion_crossing,ratio_parallel,ratio_crossing,g_align_parallel,g_align_crossing,parallel_pixels,crossing_pixels,ms";

/// One row of aniso_summary.csv: a setting across the rolls.
#[derive(Clone, Debug)]
pub struct AnisoSummary {
    pub method: String,
    pub alignment: String,
    pub intensity: f64,
    pub rolls: usize,
    /// Coefficients of variation (population standard deviation over mean) across the rolls:
    /// of the mean visibility, of the mean occlusion over the disc, the parallel and the
    /// crossing region.
    pub cv_visibility: f64,
    pub cv_occlusion: f64,
    pub cv_parallel: f64,
    pub cv_crossing: f64,
    /// Mean, least, largest across the rolls.
    pub ratio_parallel: [f64; 3],
    pub ratio_crossing: [f64; 3],
}

/// The header of aniso_summary.csv.
pub const SUMMARY_HEADER: &str = "method,alignment,intensity,rolls,cv_visibility,cv_occlusion,cv_occlusion_parallel,cv_occlusion_crossing,ratio_parallel_mean,ratio_parallel_min,ratio_parallel_max,ratio_crossing_mean,ratio_crossing_min,ratio_crossing_max";

impl AnisoSummary {
    fn intensity_label(&self) -> String {
        if self.intensity.is_finite() {
            format!("{}", self.intensity)
        } else {
            "-".into()
        }
    }
}

/// One row of aniso_flicker.csv: a method over the trail animation.
#[derive(Clone, Debug)]
pub struct FlickerRow {
    /// `lineao` or `reference`.
    pub method: String,
    pub setting: String,
    pub frames: usize,
    /// The mean count of compared pixels a pair of frames.
    pub pixels: usize,
    /// Over every compared pixel of every pair: the mean occlusion (both frames), the mean
    /// absolute change of the visibility, their ratio, the fraction changing by more than
    /// 0.05, and the Pearson correlation of the change with the physical reference's.
    pub mean_occlusion: f64,
    pub mean_abs_change: f64,
    pub relative_change: f64,
    pub frac_above: f64,
    pub pearson_reference: f64,
    /// The same against the model-matched reference's change.
    pub pearson_model: f64,
    /// The root mean square change; the reference's with its noise taken out,
    /// `sqrt(max(0, mean(Δ²) - mean(se_k² + se_k+1²)))` (LineAO's: the same as `rms_change`,
    /// it has no frame-to-frame noise: its sample pattern is a fixed function of the pixel).
    pub rms_change: f64,
    pub rms_change_denoised: f64,
    /// The mean absolute change two independent estimates of an unchanged pixel would show,
    /// `sqrt(2 / pi) sqrt(se_k² + se_k+1²)` averaged (the reference's noise floor; NaN for
    /// LineAO).
    pub noise_floor: f64,
    /// The reference's mean per-pixel standard error (NaN for LineAO).
    pub ref_stderr: f64,
    /// The mean frame (or trace) time.
    pub ms: f64,
}

/// The header of aniso_flicker.csv.
pub const FLICKER_HEADER: &str = "method,setting,frames,pixels,mean_occlusion,mean_abs_change,relative_change,frac_change_above_0.05,pearson_with_reference_change,pearson_with_model_change,rms_change,rms_change_denoised,noise_floor,ref_stderr,ms";

/// The mean of `v` over the finite values `keep` selects, and how many.
fn masked_mean(v: &[f64], keep: &[bool]) -> (f64, usize) {
    let (s, n) = v
        .iter()
        .zip(keep)
        .filter(|(x, k)| **k && x.is_finite())
        .fold((0.0, 0usize), |(s, n), (x, _)| (s + x, n + 1));
    (if n == 0 { f64::NAN } else { s / n as f64 }, n)
}

/// Population coefficient of variation.
fn cv(v: &[f64]) -> f64 {
    let n = v.len().max(1) as f64;
    let m = v.iter().sum::<f64>() / n;
    (v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / n).sqrt() / m.abs().max(1e-12)
}

/// The `aniso` group: the roll case and the flicker case (their CSVs and the chart).
fn aniso_cases(
    c: &Config,
    gpu: &engine::gpu::Gpu,
    size: &[String],
    progress: &dyn Fn(&str),
) -> Result<(Vec<AnisoSummary>, Vec<FlickerRow>), String> {
    let data = c.out.join("data");
    let scenes = c.out.join("scenes");
    let images = c.out.join("images");
    let write =
        |p: &Path, text: &str| volume::write_atomic(p, text.as_bytes()).map_err(|e| e.to_string());
    // The front lines 4 pixels apart on average, the crossing layer's 3.
    let px = ROLL_VIEW / c.size as f64;
    let count = |gap_px: f64| ((2.0 * BAND as f64 / (gap_px * px)).round() as usize).max(2);
    let (front, back) = (count(4.0), count(3.0));
    tubes::save(&data.join("crossing.tck"), &crossing_bundles(front, back))
        .map_err(|e| e.to_string())?;
    let roll_scene = scenes.join("crossing.toml");
    write(
        &roll_scene,
        &synthetic_scene(&data.join("crossing.tck"), "width = 2.0"),
    )?;
    let rows = roll_case(c, gpu, &roll_scene, size, &images, progress)?;
    let mut csv = Vec::new();
    let _ = writeln!(csv, "{ROLL_HEADER}");
    for r in &rows {
        let _ = writeln!(
            csv,
            "{},{},{},{},{},{:.5},{:.5},{:.5},{:.5},{:.4},{:.4},{:.4},{:.4},{},{},{:.3}",
            r.method,
            r.alignment,
            if r.intensity.is_finite() {
                format!("{}", r.intensity)
            } else {
                "-".into()
            },
            r.roll,
            r.pixels,
            r.visibility,
            r.occlusion,
            r.occlusion_parallel,
            r.occlusion_crossing,
            r.ratio_parallel,
            r.ratio_crossing,
            r.g_align_parallel,
            r.g_align_crossing,
            r.parallel_pixels,
            r.crossing_pixels,
            r.ms
        );
    }
    volume::write_atomic(&c.out.join("aniso_roll.csv"), &csv).map_err(|e| e.to_string())?;
    // Per setting across the rolls.
    let mut keys: Vec<(String, String, f64)> = vec![];
    for r in &rows {
        let k = (r.method.clone(), r.alignment.clone(), r.intensity);
        if !keys
            .iter()
            .any(|q| q.0 == k.0 && q.1 == k.1 && q.2.total_cmp(&k.2).is_eq())
        {
            keys.push(k);
        }
    }
    let mut summary = vec![];
    for (m, al, i) in &keys {
        let of: Vec<&RollRow> = rows
            .iter()
            .filter(|r| &r.method == m && &r.alignment == al && r.intensity.total_cmp(i).is_eq())
            .collect();
        let col = |f: &dyn Fn(&RollRow) -> f64| of.iter().map(|r| f(r)).collect::<Vec<f64>>();
        let stats = |v: Vec<f64>| {
            [
                v.iter().sum::<f64>() / v.len().max(1) as f64,
                v.iter().copied().fold(f64::INFINITY, f64::min),
                v.iter().copied().fold(f64::NEG_INFINITY, f64::max),
            ]
        };
        summary.push(AnisoSummary {
            method: m.clone(),
            alignment: al.clone(),
            intensity: *i,
            rolls: of.len(),
            cv_visibility: cv(&col(&|r| r.visibility)),
            cv_occlusion: cv(&col(&|r| r.occlusion)),
            cv_parallel: cv(&col(&|r| r.occlusion_parallel)),
            cv_crossing: cv(&col(&|r| r.occlusion_crossing)),
            ratio_parallel: stats(col(&|r| r.ratio_parallel)),
            ratio_crossing: stats(col(&|r| r.ratio_crossing)),
        });
    }
    let mut csv = Vec::new();
    let _ = writeln!(csv, "{SUMMARY_HEADER}");
    for s in &summary {
        let _ = writeln!(
            csv,
            "{},{},{},{},{:.5},{:.5},{:.5},{:.5},{:.4},{:.4},{:.4},{:.4},{:.4},{:.4}",
            s.method,
            s.alignment,
            s.intensity_label(),
            s.rolls,
            s.cv_visibility,
            s.cv_occlusion,
            s.cv_parallel,
            s.cv_crossing,
            s.ratio_parallel[0],
            s.ratio_parallel[1],
            s.ratio_parallel[2],
            s.ratio_crossing[0],
            s.ratio_crossing[1],
            s.ratio_crossing[2]
        );
    }
    volume::write_atomic(&c.out.join("aniso_summary.csv"), &csv).map_err(|e| e.to_string())?;
    // The chart: the ratios against the roll.
    volume::write_atomic(&c.out.join("aniso_roll.svg"), roll_svg(&rows).as_bytes())
        .map_err(|e| e.to_string())?;

    // Flicker.
    let (main, cross) = if c.quick { (240, 96) } else { (400, 160) };
    let trails = trail_lines(main, cross);
    let trk = data.join("trails.trk");
    tubes::save(&trk, &trails).map_err(|e| e.to_string())?;
    let trail_scene = scenes.join("trails.toml");
    write(
        &trail_scene,
        &synthetic_scene(
            &trk,
            &format!(
                "width = 2.0\ntime = \"scalar:time\"\ntrail = {{ now = {}, back = {TRAIL_HALF}, forward = {TRAIL_HALF} }}",
                TRAIL_NOW.0
            ),
        ),
    )?;
    let flicker = flicker_case(c, gpu, &trail_scene, size, &images, progress)?;
    let mut csv = Vec::new();
    let _ = writeln!(csv, "{FLICKER_HEADER}");
    for r in &flicker {
        let _ = writeln!(
            csv,
            "{},{},{},{},{:.5},{:.5},{:.4},{:.4},{:.4},{:.4},{:.5},{:.5},{:.5},{:.5},{:.3}",
            r.method,
            r.setting,
            r.frames,
            r.pixels,
            r.mean_occlusion,
            r.mean_abs_change,
            r.relative_change,
            r.frac_above,
            r.pearson_reference,
            r.pearson_model,
            r.rms_change,
            r.rms_change_denoised,
            r.noise_floor,
            r.ref_stderr,
            r.ms
        );
    }
    volume::write_atomic(&c.out.join("aniso_flicker.csv"), &csv).map_err(|e| e.to_string())?;
    Ok((summary, flicker))
}

/// The roll chart, a plain SVG with linear axes (`chart.rs` draws log-log ones): the crossing
/// and parallel ratios against the roll, a line per setting.
fn roll_svg(rows: &[RollRow]) -> String {
    let (w, h, left, right, top, bottom) = (760.0, 460.0, 60.0, 250.0, 40.0, 50.0);
    let (pw, ph) = (w - left - right, h - top - bottom);
    let x = |roll: f64| left + pw * roll / 90.0;
    let y = |v: f64| top + ph * (1.0 - v / 1.1);
    let mut svg = format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{w}\" height=\"{h}\" font-family=\"sans-serif\" font-size=\"12\">\n<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n<text x=\"{}\" y=\"22\" font-size=\"15\" text-anchor=\"middle\">Anisotropic / classic LineAO occlusion against the camera roll</text>\n",
        left + 0.5 * pw
    );
    for k in 0..=6 {
        let r = 15.0 * k as f64;
        svg += &format!(
            "<line x1=\"{0:.1}\" y1=\"{1:.1}\" x2=\"{0:.1}\" y2=\"{2:.1}\" stroke=\"#ddd\"/><text x=\"{0:.1}\" y=\"{3:.1}\" text-anchor=\"middle\">{r}</text>\n",
            x(r),
            top,
            top + ph,
            top + ph + 16.0
        );
    }
    for k in 0..=5 {
        let v = 0.2 * k as f64;
        svg += &format!(
            "<line x1=\"{0:.1}\" y1=\"{1:.1}\" x2=\"{2:.1}\" y2=\"{1:.1}\" stroke=\"#ddd\"/><text x=\"{3:.1}\" y=\"{4:.1}\" text-anchor=\"end\">{v:.1}</text>\n",
            left,
            y(v),
            left + pw,
            left - 6.0,
            y(v) + 4.0
        );
    }
    svg += &format!(
        "<rect x=\"{left}\" y=\"{top}\" width=\"{pw}\" height=\"{ph}\" fill=\"none\" stroke=\"black\"/>\n<text x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"middle\">camera roll (degrees); the bundles cross at 60 degrees</text>\n<text transform=\"translate(16 {:.1}) rotate(-90)\" text-anchor=\"middle\">anisotropic / classic mean occlusion</text>\n",
        left + 0.5 * pw,
        h - 12.0,
        top + 0.5 * ph
    );
    // A0.
    svg += &format!(
        "<line x1=\"{left}\" y1=\"{0:.1}\" x2=\"{1:.1}\" y2=\"{0:.1}\" stroke=\"#888\" stroke-dasharray=\"2 3\"/>\n",
        y(0.1),
        left + pw
    );
    let series: [(&str, &str, f64, &str, &str); 7] = [
        ("crossing", "invariant", 15.0, "#2a9d2a", ""),
        ("crossing", "paper", 5.0, "#5aa0e6", ""),
        ("crossing", "paper", 15.0, "#1f5fbf", ""),
        ("crossing", "paper", 25.0, "#0b2a66", ""),
        ("parallel", "invariant", 15.0, "#2a9d2a", "6 4"),
        ("parallel", "invariant", 25.0, "#8fd18f", "6 4"),
        ("parallel", "paper", 15.0, "#1f5fbf", "6 4"),
    ];
    for (k, (region, al, i, colour, dash)) in series.iter().enumerate() {
        let pts: Vec<(f64, f64)> = rows
            .iter()
            .filter(|r| r.alignment == *al && r.intensity == *i)
            .map(|r| {
                let v = if *region == "crossing" {
                    r.ratio_crossing
                } else {
                    r.ratio_parallel
                };
                (x(r.roll), y(v.clamp(0.0, 1.1)))
            })
            .collect();
        let path: Vec<String> = pts
            .iter()
            .map(|p| format!("{:.1},{:.1}", p.0, p.1))
            .collect();
        svg += &format!(
            "<polyline points=\"{}\" fill=\"none\" stroke=\"{colour}\" stroke-width=\"2\" stroke-dasharray=\"{dash}\"/>\n",
            path.join(" ")
        );
        for p in &pts {
            svg += &format!(
                "<circle cx=\"{:.1}\" cy=\"{:.1}\" r=\"3\" fill=\"{colour}\"/>\n",
                p.0, p.1
            );
        }
        let ly = top + 12.0 + 20.0 * k as f64;
        svg += &format!(
            "<line x1=\"{0:.1}\" y1=\"{1:.1}\" x2=\"{2:.1}\" y2=\"{1:.1}\" stroke=\"{colour}\" stroke-width=\"2\" stroke-dasharray=\"{dash}\"/><text x=\"{3:.1}\" y=\"{4:.1}\">{region}, {al}, I = {i}</text>\n",
            left + pw + 12.0,
            ly,
            left + pw + 40.0,
            left + pw + 46.0,
            ly + 4.0
        );
    }
    let ly = top + 12.0 + 20.0 * series.len() as f64;
    svg += &format!(
        "<line x1=\"{0:.1}\" y1=\"{1:.1}\" x2=\"{2:.1}\" y2=\"{1:.1}\" stroke=\"#888\" stroke-dasharray=\"2 3\"/><text x=\"{3:.1}\" y=\"{4:.1}\">A0 = 0.1</text>\n</svg>\n",
        left + pw + 12.0,
        ly,
        left + pw + 40.0,
        left + pw + 46.0,
        ly + 4.0
    );
    svg
}

/// The LineAO settings of the aniso group: classic, and each alignment at each `I`.
fn aniso_settings(intensities: &[f64]) -> Vec<(String, String, f64, Vec<String>)> {
    let mut v = vec![(
        "classic".to_string(),
        "-".to_string(),
        f64::NAN,
        vec![
            "render.method=\"lineao\"".to_string(),
            "render.lineao.anisotropic=false".to_string(),
        ],
    )];
    for al in ["invariant", "paper"] {
        for &i in intensities {
            v.push((
                "anisotropic".into(),
                al.into(),
                i,
                vec![
                    "render.method=\"lineao\"".into(),
                    "render.lineao.anisotropic=true".into(),
                    format!("render.lineao.alignment=\"{al}\""),
                    format!("render.lineao.intensity={i}"),
                ],
            ));
        }
    }
    v
}

/// The roll case ([`crossing_bundles`]): every setting at every roll.
fn roll_case(
    c: &Config,
    gpu: &engine::gpu::Gpu,
    scene: &Path,
    size: &[String],
    images: &Path,
    progress: &dyn Fn(&str),
) -> Result<Vec<RollRow>, String> {
    let geo = Geometry::new(gpu, scene, size.to_vec())?;
    let settings = aniso_settings(&INTENSITIES);
    let a = (CROSSING_DEG as f64).to_radians();
    let mut rows = vec![];
    for &roll in &ROLLS {
        progress(&format!("aniso: roll {roll}"));
        let r = roll.to_radians();
        let mut view = camera_at(0.0, 0.0, ROLL_VIEW);
        view.push(format!("camera.up=[{}, {}, 0.0]", -r.sin(), r.cos()));
        let (cam, w, h) = geo.view(&view)?;
        let (w, h) = (w as usize, h as usize);
        let (outer, px) = geo.outer_radius(&view)?;
        // Every sample of a pixel within `r_in` of the centre is on screen at every roll.
        let margin = outer + 2.0 * px;
        let r_in = 0.5 * ROLL_VIEW - margin;
        let band = BAND as f64;
        let (mut inside, mut par, mut cross) =
            (vec![false; w * h], vec![false; w * h], vec![false; w * h]);
        let frames: Vec<(Frame, Vec<Vec<f64>>)> = settings
            .iter()
            .map(|(_, _, _, keys)| {
                let mut e = view.clone();
                e.extend(keys.iter().cloned());
                geo.frame_at(
                    &e,
                    &["occlusion.lineao", "occlusion.lineao.g_align"],
                    c.frames,
                    None,
                )
            })
            .collect::<Result<_, _>>()?;
        let z = &frames[0].0.z;
        // The front bundle lies at view depths EYE_Z -+ 4, the crossing layer at EYE_Z + 12:
        // split at EYE_Z + 8.
        let split = EYE_Z - 0.5 * (-4.0 + CROSSING_Z as f64);
        for i in 0..w * h {
            if z[i] <= 0.0 {
                continue;
            }
            let (o, _) = cam.ray((i % w) as f64, (i / w) as f64, w, h);
            let (x, y) = (o.x, o.y);
            if x.hypot(y) > r_in {
                continue;
            }
            inside[i] = true;
            let d_cross = (-a.sin() * x + a.cos() * y).abs();
            let front = (z[i] as f64) < split;
            par[i] = front && d_cross > band + margin;
            cross[i] = !front && y.abs() <= band;
        }
        let mut classic = (f64::NAN, f64::NAN);
        for ((m, al, i, _), (f, extra)) in settings.iter().zip(&frames) {
            let occ: Vec<f64> = f.vis.iter().map(|v| 1.0 - v).collect();
            let (vis, n) = masked_mean(&f.vis, &inside);
            let (op, np) = masked_mean(&occ, &par);
            let (oc, nc) = masked_mean(&occ, &cross);
            if m == "classic" {
                classic = (op, oc);
            }
            let tag = if m == "classic" {
                "classic".to_string()
            } else {
                format!("{al}_I{i}")
            };
            if roll == 0.0 || roll == 30.0 {
                if m == "classic" || *i == 15.0 {
                    write_image(images, &format!("aniso_roll{roll}_{tag}"), &f.vis, w, h)?;
                }
                if m != "classic" && *i == 15.0 {
                    write_image(
                        images,
                        &format!("aniso_roll{roll}_{tag}_g_align"),
                        &extra[0],
                        w,
                        h,
                    )?;
                }
            }
            rows.push(RollRow {
                method: m.clone(),
                alignment: al.clone(),
                intensity: *i,
                roll,
                pixels: n,
                visibility: vis,
                occlusion: 1.0 - vis,
                occlusion_parallel: op,
                occlusion_crossing: oc,
                ratio_parallel: op / classic.0,
                ratio_crossing: oc / classic.1,
                g_align_parallel: masked_mean(&extra[0], &par).0,
                g_align_crossing: masked_mean(&extra[0], &cross).0,
                parallel_pixels: np,
                crossing_pixels: nc,
                ms: f.ms,
            });
        }
        if roll == 0.0 || roll == 30.0 {
            // Classic, paper and invariant (I = 15) side by side, their g_align below.
            let pick = |al: &str| {
                settings
                    .iter()
                    .position(|(_, a, i, _)| a == al && (al == "-" || *i == 15.0))
                    .map(|k| &frames[k])
            };
            let (Some(cl), Some(pa), Some(inv)) = (pick("-"), pick("paper"), pick("invariant"))
            else {
                return Err("bench lineao: a roll setting is missing".into());
            };
            let gap = 4;
            let (mw, mh) = (3 * w + 2 * gap, 2 * h + gap);
            let mut m = vec![f64::NAN; mw * mh];
            let none = vec![f64::NAN; w * h];
            let tiles: [(&[f64], usize, usize); 6] = [
                (&cl.0.vis, 0, 0),
                (&pa.0.vis, 1, 0),
                (&inv.0.vis, 2, 0),
                (&none, 0, 1),
                (&pa.1[0], 1, 1),
                (&inv.1[0], 2, 1),
            ];
            for (v, tx, ty) in tiles {
                for (i, &x) in v.iter().enumerate() {
                    m[tx * (w + gap) + i % w + mw * (ty * (h + gap) + i / w)] = x;
                }
            }
            write_image(images, &format!("aniso_roll{roll}_montage"), &m, mw, mh)?;
        }
        if roll == 0.0 {
            // The regions, for the record: parallel dark grey, crossing light grey.
            let reg: Vec<f64> = (0..w * h)
                .map(|i| {
                    if par[i] {
                        0.25
                    } else if cross[i] {
                        0.6
                    } else if inside[i] {
                        0.9
                    } else {
                        f64::NAN
                    }
                })
                .collect();
            write_image(images, "aniso_regions_roll0", &reg, w, h)?;
        }
    }
    Ok(rows)
}

/// A flicker series: method, setting, its frames' values, the reference kind whose noise it
/// carries (none for LineAO), the index of its time.
type Series<'a> = (String, String, &'a Vec<Vec<f64>>, Option<usize>, usize);

/// The flicker case ([`trail_lines`]): LineAO classic, invariant and paper (I = 15) and the
/// physical reference over the trail animation.
fn flicker_case(
    c: &Config,
    gpu: &engine::gpu::Gpu,
    scene: &Path,
    size: &[String],
    images: &Path,
    progress: &dyn Fn(&str),
) -> Result<Vec<FlickerRow>, String> {
    let geo = Geometry::new(gpu, scene, size.to_vec())?;
    let (t0, t1, nf) = TRAIL_NOW;
    let nows: Vec<f64> = (0..nf)
        .map(|k| t0 + (t1 - t0) * k as f64 / (nf - 1) as f64)
        .collect();
    let settings: Vec<_> = aniso_settings(&[15.0]);
    // Per setting and frame: the visibility and the time.
    let mut vis: Vec<Vec<Vec<f64>>> = vec![vec![]; settings.len()];
    let mut ms = vec![0.0; settings.len() + 1];
    let mut zs: Vec<Vec<f32>> = vec![];
    let (mut w, mut h) = (0, 0);
    for (k, &now) in nows.iter().enumerate() {
        progress(&format!("aniso: trail frame {k} (now {now})"));
        for (si, (m, al, _, keys)) in settings.iter().enumerate() {
            let (f, _) = geo.frame_at(keys, &["occlusion.lineao"], c.frames, Some(now))?;
            if k == 0 {
                let tag = if m == "classic" { m } else { al };
                write_image(images, &format!("aniso_trails_f0_{tag}"), &f.vis, f.w, f.h)?;
            }
            if si == 0 {
                zs.push(f.z.clone());
                (w, h) = (f.w, f.h);
            }
            ms[si] += f.ms / nf as f64;
            vis[si].push(f.vis);
        }
    }
    // The reference of every frame: the trails' visible parts as tubes.
    let s = geo.scene(&[])?;
    let (cam, _, vh) = geo.view(&[])?;
    let l = s
        .lines
        .first()
        .ok_or("bench lineao: the scene has no lines")?;
    let radius = tube_radius(l, &cam, vh)?;
    let sl = tubes::load(&l.path).map_err(|e| e.to_string())?;
    let times: Vec<f32> = sl
        .point_attributes
        .iter()
        .find(|a| a.name == "time")
        .ok_or("bench lineao: the trails have no time")?
        .values
        .clone();
    let spec_trail = l
        .trail
        .as_ref()
        .ok_or("bench lineao: the scene has no trail")?;
    // Per kind (physical, model-matched) and frame: the open fraction and its standard error.
    let mut refs: [Vec<Vec<f64>>; 2] = [vec![], vec![]];
    let mut ses: [Vec<Vec<f64>>; 2] = [vec![], vec![]];
    let mut stderr = [0.0; 2];
    for (k, &now) in nows.iter().enumerate() {
        progress(&format!("aniso: trail reference {k}"));
        let t = Instant::now();
        let trail = tubes::lines::Trail {
            now: now as f32,
            back: spec_trail.back as f32,
            forward: spec_trail.forward as f32,
            start: spec_trail.start as f32,
            min_width: spec_trail.min_width as f32,
        };
        let meshes: Vec<tubes::tube_mesh::TubeMesh> = trail_pieces(&sl, &times, &trail, 3)
            .iter()
            .map(|(f, piece)| {
                let rho = radius * f;
                let mut o = tubes::tube_mesh::TubeOptions::defaults(rho, 12, (0.25 * rho).min(0.1));
                o.color = tubes::tube_mesh::ColorMode::Constant([0.8; 3]);
                tubes::tube_mesh::build(piece, &o).0
            })
            .collect();
        let ts = TubeScene::new(&meshes, &compile::tube_clip(&s));
        // The model-matched point uses the full radius: the taper's narrower tubes put it a
        // little above their surface (open a little more than it should be).
        let px = reference_ao(&ts, &cam, w, h, radius, c.spp, 0x7A11_0AE0);
        ms[settings.len()] += t.elapsed().as_secs_f64() * 1e3 / nf as f64;
        for kind in 0..2 {
            let ao: Vec<f64> = px.iter().map(|p| p[2 * kind]).collect();
            let se_k: Vec<f64> = px.iter().map(|p| p[2 * kind + 1]).collect();
            let hit: Vec<bool> = ao.iter().map(|v| v.is_finite()).collect();
            stderr[kind] += masked_mean(&se_k, &hit).0 / nf as f64;
            if k == 0 {
                let name = ["reference", "reference_model-matched"][kind];
                write_image(images, &format!("aniso_trails_f0_{name}"), &ao, w, h)?;
            }
            refs[kind].push(ao);
            ses[kind].push(se_k);
        }
    }
    // The compared pixels of each pair.
    let pairs: Vec<Vec<usize>> = (0..nf - 1)
        .map(|k| {
            (0..w * h)
                .filter(|&i| {
                    let (za, zb) = (zs[k][i] as f64, zs[k + 1][i] as f64);
                    za > 0.0
                        && zb > 0.0
                        && (za - zb).abs() < radius
                        && (0..2)
                            .all(|r| refs[r][k][i].is_finite() && refs[r][k + 1][i].is_finite())
                })
                .collect()
        })
        .collect();
    let n_px = pairs.iter().map(|p| p.len()).sum::<usize>();
    let deltas = |v: &[Vec<f64>]| -> Vec<f64> {
        pairs
            .iter()
            .enumerate()
            .flat_map(|(k, p)| p.iter().map(move |&i| v[k + 1][i] - v[k][i]))
            .collect()
    };
    let ref_d = deltas(&refs[0]);
    let model_d = deltas(&refs[1]);
    let mut out = vec![];
    let mut all: Vec<Series> = settings
        .iter()
        .zip(&vis)
        .enumerate()
        .map(|(si, ((m, al, i, _), v))| {
            let setting = if m == "classic" {
                "classic".to_string()
            } else {
                format!("anisotropic {al} I={i}")
            };
            ("lineao".to_string(), setting, v, None, si)
        })
        .collect();
    for (kind, name) in ["physical", "model-matched"].iter().enumerate() {
        all.push((
            "reference".into(),
            format!("{name} {} spp", c.spp),
            &refs[kind],
            Some(kind),
            settings.len(),
        ));
    }
    for (m, setting, v, kind, ti) in &all {
        let d = deltas(v);
        let occ: f64 = pairs
            .iter()
            .enumerate()
            .flat_map(|(k, p)| p.iter().map(move |&i| 2.0 - v[k][i] - v[k + 1][i]))
            .sum::<f64>()
            / (2 * n_px.max(1)) as f64;
        let nd = d.len().max(1) as f64;
        let mad = d.iter().map(|x| x.abs()).sum::<f64>() / nd;
        let ms2 = d.iter().map(|x| x * x).sum::<f64>() / nd;
        // The reference's noise: per compared pixel the variance of the difference of two
        // independent estimates.
        let (noise_var, floor) = match kind {
            Some(r) => {
                let var: Vec<f64> = pairs
                    .iter()
                    .enumerate()
                    .flat_map(|(k, p)| {
                        let se = &ses[*r];
                        p.iter()
                            .map(move |&i| se[k][i].powi(2) + se[k + 1][i].powi(2))
                    })
                    .collect();
                (
                    var.iter().sum::<f64>() / nd,
                    var.iter()
                        .map(|v| (2.0 / std::f64::consts::PI * v).sqrt())
                        .sum::<f64>()
                        / nd,
                )
            }
            None => (0.0, f64::NAN),
        };
        out.push(FlickerRow {
            method: m.clone(),
            setting: setting.clone(),
            frames: nf,
            pixels: n_px / pairs.len().max(1),
            mean_occlusion: occ,
            mean_abs_change: mad,
            relative_change: mad / occ.max(1e-12),
            frac_above: d.iter().filter(|x| x.abs() > 0.05).count() as f64 / nd,
            pearson_reference: agreement(&d, &ref_d).pearson,
            pearson_model: agreement(&d, &model_d).pearson,
            rms_change: ms2.sqrt(),
            rms_change_denoised: (ms2 - noise_var).max(0.0).sqrt(),
            noise_floor: floor,
            ref_stderr: kind.map_or(f64::NAN, |r| stderr[r]),
            ms: ms[*ti],
        });
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn trail_pieces_cut_the_window_and_step_the_taper() {
        // One straight line along x, a point a unit, time = x.
        let mut sl = tubes::Streamlines::new();
        let pts: Vec<Vec3> = (0..=10).map(|i| Vec3::new(i as f32, 0.0, 0.0)).collect();
        sl.push(&pts);
        let times: Vec<f32> = (0..=10).map(|i| i as f32).collect();
        let trail = tubes::lines::Trail {
            now: 5.25,
            back: 2.0,
            forward: 2.0,
            start: 0.5,
            min_width: 0.5,
        };
        let pieces = trail_pieces(&sl, &times, &trail, 2);
        let length =
            |s: &tubes::Streamlines| -> f32 { (0..s.len()).map(|k| s.arc_length(k) as f32).sum() };
        // The window [3.25, 7.25] is drawn, cut inside the segments at its ends.
        let total: f32 = pieces.iter().map(|(_, s)| length(s)).sum();
        assert!((total - 4.0).abs() < 1e-5, "{total}");
        let (lo, hi) = pieces
            .iter()
            .flat_map(|(_, s)| s.points.iter())
            .fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), p| {
                (a.min(p.x), b.max(p.x))
            });
        assert!(
            (lo - 3.25).abs() < 1e-5 && (hi - 7.25).abs() < 1e-5,
            "{lo} {hi}"
        );
        // Full width where the segment's middle is within `start` (1 unit) of now: [4, 5] and
        // [5, 6]; the pieces beyond are narrower, never below min_width.
        let full = pieces
            .iter()
            .find(|(f, _)| *f == 1.0)
            .expect("a full-width piece");
        assert!((length(&full.1) - 2.0).abs() < 1e-5, "{}", length(&full.1));
        assert!(pieces.iter().all(|(f, _)| *f >= 0.5 && *f <= 1.0));
        assert!(
            pieces.len() >= 2,
            "{:?}",
            pieces.iter().map(|p| p.0).collect::<Vec<_>>()
        );
        // A window off the line draws nothing.
        let none = trail_pieces(&sl, &times, &tubes::lines::Trail { now: 50.0, ..trail }, 2);
        assert!(none.is_empty());
    }

    #[test]
    fn cases_parse_groups_and_refuse_unknown_ones() {
        let both = Cases {
            accuracy: true,
            aniso: true,
        };
        assert_eq!(Cases::parse("accuracy,aniso").unwrap(), both);
        assert_eq!(Cases::parse("all").unwrap(), both);
        assert_eq!(
            Cases::parse(" aniso ").unwrap(),
            Cases {
                accuracy: false,
                aniso: true
            }
        );
        assert!(Cases::parse("zoom").is_err());
        assert!(Cases::parse("").is_err());
    }

    #[test]
    fn the_crossing_bundles_lie_in_their_bands_and_layers() {
        let sl = crossing_bundles(10, 8);
        assert_eq!(sl.len(), 18);
        let a = CROSSING_DEG.to_radians();
        for k in 0..sl.len() {
            let mid = sl.line(k)[55];
            if k < 10 {
                assert!(mid.y.abs() <= BAND && mid.z.abs() <= 4.0, "{mid}");
            } else {
                let across = -a.sin() * mid.x + a.cos() * mid.y;
                assert!(across.abs() <= BAND + 1e-4 && mid.z == CROSSING_Z, "{mid}");
            }
        }
    }

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
