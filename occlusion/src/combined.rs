//! Schott, Martin, Grosset, Brownlee, Höllt, Brown, Smith and Hansen, "Combined Surface and
//! Volumetric Occlusion Shading" (PacificVis 2012; `../shared/seeds`): the CPU side of the
//! paper - its equation index, the model as umbra implements it, and the pure functions the
//! GPU passes are built on.
//!
//! | paper | CPU (this crate; the CPU renderer `raycast`) | GPU (`engine`, `shaders/`) | checked by |
//! |---|---|---|---|
//! | §3.2.1 G-buffer | - | `gbuffer.rs`, `gbuffer.wgsl` | `engine/tests/occlusion_render.rs` |
//! | Alg. 2 eye buffer, E/A | `emission_absorption::reference`; `raycast::EaVolume::render_frame` (eight rays at a time: `raycast::lanes::march`; behind clipping planes `raycast::EaVolume::clip_slabs`, `march_clipped`) | `slice_pass.wgsl::march` (empty bricks stepped over: `empty_slabs`) | `engine/tests/ea_render.rs` (`empty_bricks_are_stepped_over_without_missing_a_sample`), `raycast` tests (`clipped_frames_march_in_lanes_as_the_scalar_march_bit_for_bit`, `slabs_behind_the_planes_are_sampled_as_without_them`) |
//! | Alg. 3 occlusion buffer (ComputeDOS) | [`blur_stencil`], [`blur_rows`], [`blur_taps`], [`light_grid`], [`DARK`], [`data_cell`], [`light_step`], [`data_step`], [`voxel_step`], [`light_samples`], [`light_slices`], [`light_view`], [`step_theta`], `reference::render`; `raycast::light` (the sweep, volume-only: `EaVolume::sweep`, `light_start`, `store_parts`; a step's parts by `raycast::EaVolume::optical_depth`) | `slice_pass.wgsl::light` (parts and their stores), `light_step_front` and `composite_eye` (along the eye's ray), `light_front` (the surfaces'), `light_step_at` | unit tests below (`the_light_in_a_slab_is_exact_however_the_slabs_cut_the_medium`), `raycast` `a_sample_takes_the_light_at_its_own_depth` and `a_dense_surface_shows_the_same_light_wherever_it_lies_between_the_slices`, `occlusion_render.rs`, `cli/tests/ea_cli.rs` (CPU sweep against the GPU pass; a sheet over a dense floor, a tube over a sheet, a camera inside the head), `raycast` `a_deep_light_step_takes_the_samples_of_the_steps_a_voxel_deep` |
//! | Alg. 2 eye buffer, the light a volume sample receives (not in the paper: `O` read once a light step at its front and carried along the eye's own ray, weighted by the eye within each slab) | [`light_in_slab`]; `raycast::EaVolume::advance`, `raycast::lanes::Packet::composite` (`front`, `front_shifted`), `raycast::light::LightVolume::front` | `slice_pass.wgsl::composite_eye`, `light_step_front`, `light_shifted` (`Params::light_read`) | unit test below (`the_light_in_a_slab_is_exact_however_the_slabs_cut_the_medium`), `raycast` `a_sample_takes_the_light_at_its_own_depth` (steps 1, 2, 8) and `a_dense_surface_shows_the_same_light_wherever_it_lies_between_the_slices`, `cli/tests/render_cli.rs` (`a_tilted_cut_face_shows_no_band_per_slice_on_either_device`), `cli/tests/ea_cli.rs` (devices alike) |
//! | Alg. 2 behind clipping planes, each light cell read at the pixel's distance behind the planes (not in the paper: constant up to the cell's cut, then geometric `a (b / a)^t` to the next stored slice, exact for a uniform medium) | `raycast::light::LightVolume::clip_shifts`, `LightVolume::cell_from`, `raycast::light::geometric` (`ln_at_least_1`, `exp_neg_fast`); `raycast::lanes::Packet::front_shifted`, `lanes::geometric` (the same bits) | `slice_pass.wgsl::cell_shifts`, `light_shifted`, `light_step_from` | `raycast` `the_geometric_read_follows_the_exponential`, `clipped_frames_march_in_lanes_as_the_scalar_march_bit_for_bit`; `cli/tests/render_cli.rs` (`a_tilted_cut_face_shows_no_band_per_slice_on_either_device`) |
//! | Alg. 2 behind clipping planes, the light a ray carries brought to each front it reads over the step, not at once (not in the paper: the front holds the cells' coarser samples and the step's blur, and a ray crossing a front under a cut face at a grazing angle showed the jump as a line) | `raycast::light::front_gain` (`GAIN_RANGE`); `raycast::EaVolume::advance`, `raycast::lanes::Packet::composite` (the same bits) | `slice_pass.wgsl::front_gain`, `composite_eye` (`lgain`) | `raycast` `clipped_frames_march_in_lanes_as_the_scalar_march_bit_for_bit`; `engine` `the_march_brings_the_carried_light_to_each_front_as_the_cpu`; `cli/tests/render_cli.rs` (`a_cut_face_shows_no_line_per_light_step_on_either_device`, `a_tilted_cut_face_shows_no_band_per_slice_on_either_device`) |
//! | Alg. 3, the light's attenuation through a slab (not in the paper: along the cone) | [`cone_path_factor`]; `raycast::light` (`Sweep::path`) | `Params::light_path` in `slice_pass.wgsl::light` | unit test below (`the_cone_path_factor_is_the_mean_path_through_a_slab`), `raycast` `a_sample_takes_the_light_at_its_own_depth` (45 degrees), `occlusion_render.rs` (partial occlusion in a uniform medium), `cli/tests/ea_cli.rs` (devices alike) |
//! | Alg. 4, eq. 1-3 partial occlusion | `reference::render` (surface AOV) | `slice_pass.wgsl::march` | `occlusion_render.rs` (the cone's mean of exp(-sigma z / cos phi)) |
//! | Alg. 5, eq. 4-6 vicinity | [`poisson_disk`], `camera::texture_radius` | `vicinity.wgsl` | `occlusion_render.rs` (groove) |
//! | Alg. 6, eq. 7-10 compositing | - | `composite.wgsl` | `occlusion_render.rs` (eq. 7, 8) |
//! | the light model's ground truth | `reference::render`, `reference_tubes` | - | `cli/tests/render_cli.rs` (bench accuracy) |
//! | §4.1 stream tubes | `tubes::bspline_fit`, `tubes::tube_mesh` | - | `tubes/tests` |
//!
//! The model (the intended maths where the paper's pseudo-code errs):
//! * Slice k is the plane at view depth `z_k = z0 + (k + 1/2) d`, standing for the slab
//!   `[z0 + k d, z0 + (k + 1) d]`. The transfer function gives extinction sigma per world
//!   unit; a slab's opacity along a ray is `1 - exp(-sigma d / cos phi)`.
//! * The light is the head light: a cone of half-angle theta around the direction towards the
//!   eye. `O_k(x)`, the light arriving at slice k at x (`O_0 = 1`), is gathered from the light
//!   leaving slice k - 1, `L_{k-1} = O_{k-1} exp(-f sigma d / cos phi)` (the paper:
//!   `O_{k-1} (1 - alpha_{k-1})`, the slab crossed along the ray; the light crosses it along
//!   the cone's directions, on average `f` = [`cone_path_factor`] times as far: 1.05 at
//!   25 degrees, 1.18 at 45), averaged over the disk the
//!   cone cuts from slice k - 1: radius `d tan(theta)` in world units, projected as
//!   `0.5 (P00, P11) r / z_{k-1}` in texture units (orthographic: without the division; see
//!   `camera::texture_radius`), sampled with `n x n` taps (`blur_samples`) mapped
//!   concentrically onto the disk, bilinear ([`blur_stencil`]). This is the paper's incremental
//!   blur ("ComputeDOS", after Schott et al. 2009): each slice blurs the previous one.
//! * Behind clipping planes (not in the paper): a pixel reads each of its four light cells at
//!   the same distance behind the planes as its own slice, slice `k + (a_cell - a_pixel) / d`
//!   with `a` the view depth where the planes let a ray in
//!   ([`crate::emission_absorption::clip_entry`]): its first read (where it enters the medium
//!   at the cut) at the front of the light step that shifted slice lies in, its later reads
//!   at its own step's front plus the shift, interpolated between stored slices. Read at
//!   equal depth, a cut face tilted to the slices shows a band per slice, because neighbouring
//!   cells meet the plane in different slabs (`slice_pass.wgsl::cell_shifts`,
//!   `light_shifted`; `raycast::light::LightVolume::clip_shifts` with the cells' entries once a
//!   frame, `clip_entries`, read by `LightVolume::front` and, eight rays at a time,
//!   `raycast::lanes::Packet::front_shifted`; `cli/tests/render_cli.rs`, a tilted cut face;
//!   `raycast` `clipped_frames_march_in_lanes_as_the_scalar_march_bit_for_bit`).
//! * Geometry into volume (Alg. 3): where slice k lies inside a tube (`front <= z_k <= back`),
//!   the tube's extinction `geometry_extinction` adds to the volume's for the light leaving
//!   the slice. The paper, with the front depth only, replaces the opacity of every sample
//!   behind a surface (an endless shadow column; its test `f_depth < geom_depth` is a typo for
//!   "behind") - kept as `geometry_shadow = "column"`.
//! * Eye buffer (Alg. 2): volume colour `c alpha O` composited front to back (`dos`,
//!   `combined`; `ea` and `vicinity` leave `O` out, `phong` shades `c` with the gradient), the
//!   sampling distance clipped where the ray meets the nearest surface of the G-buffer. `O` is
//!   the light reaching slab k along the eye's own ray, weighted by the eye within the slab
//!   ([`light_in_slab`]: the light volume read at each light step's front, then attenuated by
//!   the ray's own samples). The paper takes `O_k`, the light half a slab in front of the
//!   sample, which has passed half a slab less of the medium: against the Monte Carlo
//!   reference that left `combined` 0.031 brighter in mean over the MNI T1's volume; the
//!   light at the sample's depth had 1.4-35% less RMSE on every scene measured, and carried
//!   along the eye's ray a further 0.3-67% (docs/accuracy.md, "The light at the sample's
//!   depth", "The light along the eye's ray").
//! * Partial occlusion (Alg. 4, eq. 1-3): a surface at depth `z_s` between `z_{k-1}` and `z_k`
//!   receives `lerp(O_{k-1}, O_k, (z_s - z_{k-1}) / d)` - as the paper has it, half a slab in
//!   front of the surface: at the surface's own depth the light past the slab it lies in is
//!   the light the tube itself attenuated where that slab's middle is inside it (a tube would
//!   shadow its own top; `engine/tests/occlusion_render.rs` checks the transmittance above a
//!   surface in a uniform medium, within 0.012). Algorithm 1's order of updates with
//!   Algorithm 3's buffer swap reverses these weights if copied literally.
//!
//! The cone-following model (`render.occlusion_model = "cone"`; issue 5 item 5). The paper's
//! incremental blur is a random walk: a blur of radius `r` (uniform disk, variance `r^2 / 4`
//! per axis) per slice spreads a shadow after a distance `L` to a standard deviation of
//! `tan(theta) sqrt(L d) / 2`, where the cone it models puts it on a disk of radius
//! `L tan(theta)` (deviation `L tan(theta) / 2`); the result depends on the slice count and
//! never reaches the cone. Here each cell also carries the shadow-weighted age `D` of its
//! shadow (how far behind its occluders it lies; the buffers hold `L` and `(1 - L) D`), and
//! the step's radius is chosen so the variances add up to the cone's:
//! `r^2 = tan^2(theta) ((D + d)^2 - D^2)`, i.e. `r = d tan(theta) sqrt(1 + 2 D / d)` - the
//! paper's radius at `D = 0`; after `n` steps from a point occluder the variance is
//! `(n d tan(theta))^2 / 4`, the cone's at `L = n d`, whatever `d` is. Ages mix linearly where
//! shadows of different occluders overlap (an approximation), and the taps (`n x n`, at least
//! `blur_samples`, up to 9 per axis) grow with the radius in cells.
//!
//! Departure from the paper, for speed (issue 5, "beat the paper's design"): the occlusion
//! buffer lives on cells of `s x s` pixels (`render.occlusion_cell`; by default [`light_grid`]:
//! 2 pixels, or as many as the data's smallest voxel covers on screen, [`data_cell`]), in steps
//! of `m` slices (`render.occlusion_step`; by default [`light_step`]: where the volume alone
//! casts the light four voxels deep, [`data_step`], sampled and stored a voxel apart,
//! [`light_samples`]; else one slice), one dispatch per step (the
//! `light` entry; the dispatch is the barrier the blur needs), and stores every step's `O` -
//! and the light reaching each of its parts - in a light volume (cells x stored slices). A
//! step is the paper's slice in the light's own view ([`light_view`]: slabs `m d` deep) with
//! the blur's angle of [`step_theta`]; the eye reads each step's `O` at its front and carries
//! it along its own ray ([`light_in_slab`]; where tubes, lines or planes cast light, each
//! stored part's). The eye buffer is then one dispatch (`march`): all
//! slices of a pixel in one invocation, with `O` read bilinearly from the light volume, rays
//! clipped to the grid's box and to the surface, empty 8^3 bricks skipped (exact, see
//! `ea_pass::occupancy`), early termination at opacity `OPAQUE` (1 - 1/128; the rest of the ray taken as the mean of what it
//! showed, `emission_absorption::end_opaque`) - none of which the
//! slice-by-slice eye buffer can do. A cell's transmittance through the tubes is the mean over
//! its pixels (coverage), its volume sample the one on its centre ray. A surface reads its
//! partial occlusion at the nearest surface depth of the cells around it, so that a tube does
//! not shadow itself through the cell it shares with its own silhouette; occluders nearer than
//! that within a cell are left to the vicinity term. With `s = 1` the light is the paper's
//! per-pixel buffer (the tubes exactly as in the model above).

use crate::emission_absorption::EaView;
use crate::rng::SplitMix64;

/// The light volume's grid, `(cell, step)`: the cell edge in pixels - the scene's
/// `render.occlusion_cell`, or from [`data_cell`] (2 pixels, more where the data's voxels
/// cover more), doubled (up to 64) while the light volume (`cells x steps x samples` f32:
/// the light stored at each part of a step, [`light_samples`]) exceeds
/// `limit` bytes (at most 1 GiB) - and the eye slices per step on that cell
/// ([`light_step`]: the scene's `render.occlusion_step`, 1 where tubes, lines or planes cast
/// light (`geometry`), else [`data_step`]). The GPU pass passes its adapter's storage binding
/// limit; the CPU renderer the same, so that both choose the same grid.
pub fn light_grid(
    cell: Option<u32>,
    step: Option<u32>,
    geometry: bool,
    v: &EaView,
    limit: u64,
) -> (u32, u32) {
    if let Some(c) = cell {
        let c = c.max(1);
        return (c, light_step(step, v, geometry));
    }
    let budget = limit.min(1 << 30);
    let mut c = data_cell(v);
    loop {
        let m = light_step(step, v, geometry);
        let cells = v.width.div_ceil(c) as u64 * v.height.div_ceil(c) as u64;
        let stored = light_slices(v, m) as u64;
        if c >= 64 || cells * stored * 4 <= budget {
            return (c, m);
        }
        c *= 2;
    }
}

/// The smallest cell worth sweeping for the data: 2 pixels, or the largest power of two up to
/// 64 that the smallest voxel spacing (`v.voxel`) covers on screen at the middle of the slab.
/// The light is a blur of the data's opacity, which varies within a voxel only by
/// interpolation, so cells finer than a voxel's image add cost and little light: cells of 4
/// pixels instead of 2 changed `combined` by 0.22-0.44 levels of 255 in mean over the volume's
/// pixels on three 48-68^3 volumes at 512^2, where a voxel covers 4-5 pixels, and halved the
/// light pass (docs/benchmarks.md).
pub fn data_cell(v: &EaView) -> u32 {
    let Some(px) = voxel_px(v) else {
        return 2;
    };
    let mut c = 2u32;
    while c < 64 && (2 * c) as f64 <= px {
        c *= 2;
    }
    c
}

/// The smallest voxel spacing (`v.voxel`) on screen in pixels at the middle of the slab (the
/// smaller of the two axes); None where the view or the spacing is degenerate.
fn voxel_px(v: &EaView) -> Option<f64> {
    if !(v.voxel > 0.0 && v.width > 0 && v.height > 0) {
        return None;
    }
    let z = v.z0 + 0.5 * v.dz * v.slices as f64;
    let (tx, ty) = v
        .camera
        .texture_radius(v.voxel, -z, v.width as f64 / v.height as f64);
    let px = (tx * v.width as f64).min(ty * v.height as f64);
    (px.is_finite() && px > 0.0).then_some(px)
}

/// The most eye slices one step of the light volume spans (`render.occlusion_step`).
pub const MAX_LIGHT_STEP: u32 = 8;

/// Eye slices per step of the light volume: the scene's `render.occlusion_step` (a power of
/// two up to [`MAX_LIGHT_STEP`]), or [`data_step`] where the light passes through the volume
/// alone, else 1 (the paper's light, a step per slice: a tube thinner than a coarser step
/// could fall between its samples).
pub fn light_step(step: Option<u32>, v: &EaView, geometry: bool) -> u32 {
    match step {
        // A power of two (the CPU renderer's lanes divide by a shift).
        Some(m) => 1 << m.clamp(1, MAX_LIGHT_STEP).ilog2(),
        None if geometry => 1,
        None => data_step(v),
    }
}

/// The deepest step of the light volume [`data_step`] takes, in voxels (of the smallest
/// spacing).
pub const MAX_STEP_VOXELS: f64 = 4.0;

/// The step of the light volume where the volume alone casts the light: the largest power of
/// two `m` up to [`MAX_LIGHT_STEP`] with `m d` within [`MAX_STEP_VOXELS`] voxels (of the
/// smallest spacing, `v.voxel`); 1 where the spacing is unknown.
///
/// Whatever the step, the light samples the data a voxel apart ([`light_samples`]): the light
/// leaving a step is attenuated as by steps a voxel deep, blurred once a step (the paper's
/// blur with the angle of [`step_theta`]), and the eye carries the light from each step's
/// front along its own ray ([`light_in_slab`]). While the eye read the light stored a voxel
/// apart (until 2026-12-07), steps of two, four and eight slices at the default slice distance
/// (one to four voxels) gave the same RMSE against the Monte Carlo reference to 3e-5 on the
/// MNI T1 (128-512^2) and headsq (512^2), while the sweep's cost falls with the steps (the
/// blur, the bookkeeping and the threads meeting between steps; docs/accuracy.md "The light's
/// steps and samples").
pub fn data_step(v: &EaView) -> u32 {
    if !(v.voxel > 0.0 && v.dz > 0.0) {
        return 1;
    }
    steps_within(v, v.voxel * MAX_STEP_VOXELS)
}

/// The largest power of two `m` up to [`MAX_LIGHT_STEP`] with `m d` within `depth` (1 at
/// least).
fn steps_within(v: &EaView, depth: f64) -> u32 {
    let mut m = 1u32;
    while m < MAX_LIGHT_STEP && (2 * m) as f64 * v.dz <= depth * (1.0 + 1e-9) {
        m *= 2;
    }
    m
}

/// Eye slices a voxel deep (the smallest spacing): the largest power of two up to
/// [`MAX_LIGHT_STEP`] whose slices fit in it, 1 where the spacing is unknown.
pub fn voxel_step(v: &EaView) -> u32 {
    if !(v.voxel > 0.0 && v.dz > 0.0) {
        return 1;
    }
    steps_within(v, v.voxel)
}

/// Volume samples a step of `step` eye slices takes: as many as keep them a voxel apart
/// (`step / voxel_step`, 1 at least), at the middles of equal parts of the step's slab; the
/// light reaching each part is stored where the eye reads the parts (on the GPU, for the
/// tubes' coverage and the surfaces; on the CPU behind clipping planes; else only the step's
/// front). A step deeper than a voxel then attenuates the light it passes on as the steps a
/// voxel deep would (the same samples): only its blur is coarser. A sheet thinner than the
/// step cannot fall between its samples, and a dense medium's light decays within the step as
/// it does (`umbra bench stability`'s thin sheet, `cli/tests/ea_cli.rs`'s sheet over a
/// floor).
pub fn light_samples(v: &EaView, step: u32) -> u32 {
    (step / voxel_step(v)).max(1)
}

/// The light a volume sample receives, along the eye's own ray (not in the paper): within a
/// light step the light reaching the step's front (`O`, bilinear over the light cells) is
/// carried along the pixel's ray, attenuated by the ray's own samples `f` times (the cone's
/// path factor, [`cone_path_factor`]), and each sample's share is weighted by the eye's
/// attenuation within its slab. For a slab of optical depth `tau` along the ray and the light
/// `run` reaching its front, returns `(lo, leave)`: the slab's light-weighted opacity
/// `int_0^1 tau exp(-tau s) run exp(-f tau s) ds = run (1 - exp(-(1 + f) tau)) / (1 + f)` (the
/// sample adds `c lo` of its colour, where unlit it adds `c (1 - exp(-tau))`; its light is
/// `lo / (1 - exp(-tau))`), and the light leaving it, `run exp(-f tau)`.
///
/// The paper reads `O_k` itself for slab `k` (Alg. 2): half a slab in front of the sample, a
/// light too bright by about `sigma d / 2` of itself (docs/accuracy.md, "The light at the
/// sample's depth"). Both values here are exact for a medium uniform within each slab, so the
/// light a surface shows does not
/// depend on where it lies between the slices or the light's stored slices: the light read
/// linearly between stored slices a voxel apart (what umbra did until 2026-12-07) drew a hatch
/// on dense surfaces cut at a slant (docs/accuracy.md, "A hatch on dense surfaces"), and its
/// chord lay above the light's exponential decay. A slab too dense to see through shows
/// `run / (1 + f)` of the light reaching it (about half: the eye sees into it as far as the
/// light reaches), where the light at the slab's middle would go to 0 and the chord to
/// `run / 2`. The blur, within a step, is left to the steps' fronts (the light volume's
/// cells); the cells' own samples serve the next front. Against the Monte Carlo reference the
/// RMSE fell 0.3-67% on the scenes of docs/accuracy.md, most on dense media ("The light along
/// the eye's ray").
/// `raycast::EaVolume::advance` (and `raycast::lanes`) and `slice_pass.wgsl::composite_eye`
/// compute it in f32, incrementally.
pub fn light_in_slab(run: f64, tau: f64, path: f64) -> (f64, f64) {
    let f = path.max(0.0);
    let tau = tau.max(0.0);
    (
        run * -(-(1.0 + f) * tau).exp_m1() / (1.0 + f),
        run * (-f * tau).exp(),
    )
}

/// The slices a light volume of steps of `step` eye slices stores: [`light_samples`] a step,
/// for as many steps as cover the eye's slices ([`light_view`]).
pub fn light_slices(v: &EaView, step: u32) -> u32 {
    v.slices.div_ceil(step.max(1)) * light_samples(v, step.max(1))
}

/// The view the light volume is swept in for a step of `step` slices: the same front, slabs
/// `step d` deep, as many as cover the eye's slices. Each step stores the light reaching its
/// [`light_samples`] parts (`p`): the front of eye slab `j step` has exactly the light of
/// step `j` (both have passed through the same depth), which the eye reads there and carries
/// along its own ray through the step ([`light_in_slab`]); the parts are read by the eye where
/// tubes, lines or planes cast light and behind clipping planes, and by the surfaces.
pub fn light_view(v: &EaView, step: u32) -> EaView {
    let m = step.max(1);
    EaView {
        dz: v.dz * m as f64,
        slices: v.slices.div_ceil(m),
        ..v.clone()
    }
}

/// The cone half-angle a step of `step` slices blurs with, so that the paper's model spreads a
/// shadow as far as it does a slice at a time: its blur is a random walk (variance
/// `(d tan(theta))^2 / 4` a step), so `step` slices add up to one step of `d step` with
/// `tan(theta) / sqrt(step)`. The cone-following model (`cone`) depends on the distance alone
/// and keeps theta.
pub fn step_theta(theta_deg: f64, step: u32, cone: bool) -> f64 {
    if cone || step <= 1 {
        return theta_deg;
    }
    (theta_deg.to_radians().tan() / (step as f64).sqrt())
        .atan()
        .to_degrees()
}

/// The light below which the occlusion buffer stops attenuating: a cell whose arriving light
/// `O_k` is below `DARK` (of the unoccluded light, 1) takes no samples of its slab and passes
/// `O_k` on unchanged, to its stored parts and as the light leaving it (`raycast::light`,
/// `slice_pass.wgsl::light`, where the tubes' coverage is skipped too). Deep in a dense
/// volume cells are that dark long before the far side: the MNI T1's CPU light pass is 16-49%
/// faster at 128-512^2 (docs/benchmarks.md, "Dark light is not swept").
///
/// What it may change, for the paper's blur: let `L'`, `O'` be the light with the skip and
/// `L`, `O` without, and `0 <= L' - L <= e` leaving step k - 1. The blur's weights are
/// non-negative and sum to 1, so `0 <= O'_k - O_k <= e`; a lit cell leaves
/// `(O' - O) exp(-tau)`, within the same bound; a dark cell leaves `O'_k` against
/// `O_k exp(-tau)`, between `O'_k - O_k >= 0` and `O'_k < DARK`. From `e = 0` at the first
/// step: every light in the buffer is at least the full sweep's and less than `DARK` above it,
/// and an eye sample's colour `c alpha O` at most `c alpha DARK` above: a pixel's channel less
/// than `DARK` (a quarter of a level of 255; colours at most 1, and up to the f32 rounding of
/// weights that sum to 1 only to within it). The cone model's blur widens with the shadow's
/// age, which the skip changes too: there the bound is measured (`raycast`
/// `light_below_dark_passes_on_within_dark_of_the_full_sweep`), not derived. On the MNI T1 and
/// headsq at 128-1024^2 the 8-bit images are identical with and without the skip.
pub const DARK: f32 = 1.0 / 1024.0;

/// How much longer the head light's path through a slab is, on average over its cone, than the
/// slab's depth along the ray: the mean of `1 / cos(phi)` over directions uniform in solid
/// angle within the cone of half-angle theta (`cos(phi)` uniform on `[cos(theta), 1]`),
/// `-ln(cos(theta)) / (1 - cos(theta))` - 1.0077 at 10 degrees, 1.0500 at 25, 1.1833 at 45,
/// 1.4917 at 65, 2.1186 at 80 (to second order `1 + theta^2 / 4`).
///
/// The paper's occlusion buffer (Alg. 3) attenuates the light leaving a slab by the slab's
/// opacity along the ray, `exp(-sigma d)`, and spreads it over the cone's disk by the blur: its
/// light reaches the slab from the cone's directions, but crosses it as if straight along the
/// ray. A direction at `phi` from the ray crosses a slab `d` deep over `d / cos(phi)`; the
/// model the renderer approximates (the Monte Carlo reference: the mean transmittance over the
/// cone's directions, `occlusion::reference`) therefore sees a uniform medium `z` deep as
/// `E[exp(-sigma z / cos(phi))]`, which `exp(-sigma z f)` with this `f` matches to first order
/// in `sigma z` and, by Jensen's inequality, from below: to second order it is darker by
/// `Var(1 / cos(phi)) (sigma z)^2 / 2` of itself (0.00044 (sigma z)^2 at 25 degrees). The light's
/// extinction - the volume's and the tubes' - is taken times this factor, and times
/// `1 / cos(psi)` for a ray `psi` off the view axis (each slab's depth along the ray): the
/// product is exact on the axis and an approximation off it (for a cone of 45 degrees about a
/// ray 20 degrees off the axis the mean path is 1.299 slabs, the product 1.259; within the
/// fields of view of 20-40 degrees scenes use, the rays stay within 10-20 degrees of it)
/// (`raycast::light`, `slice_pass.wgsl::light`). Against the reference it cut
/// `combined`'s RMSE on every scene measured, by 1-13% at 25 degrees and 12-50% at 45-65
/// (docs/accuracy.md, "The light's path through a slab").
pub fn cone_path_factor(theta_deg: f64) -> f64 {
    let t = theta_deg.to_radians();
    if t.is_nan() || t <= 0.0 {
        return 1.0;
    }
    if t >= std::f64::consts::FRAC_PI_2 {
        // Directions along the slab (the settings allow theta in (0, 90) degrees only).
        return f64::INFINITY;
    }
    // 1 - cos(theta) = 2 sin^2(theta / 2), without the cancellation at small angles.
    let one_minus_cos = 2.0 * (0.5 * t).sin().powi(2);
    if one_minus_cos < 1e-12 {
        return 1.0 + 0.5 * one_minus_cos;
    }
    -(-one_minus_cos).ln_1p() / one_minus_cos
}

/// One slice's blur (the paper's model; the cone model scales `rpx` per cell): the radius in
/// cells `rpx` (x, y) and, up to two cells, the 3x3 stencil of [`blur_stencil`] (`wide`
/// false); beyond, `n x n` bilinear taps on the disk.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BlurRow {
    pub wide: bool,
    pub rpx: [f64; 2],
    pub w: [[f64; 3]; 3],
}

/// Every slice's blur for view `v` on cells of `cell` pixels and the cone's half-angle
/// `theta_deg`: slice k gathers from slice k - 1, so its radius is the cone's disk
/// `d tan(theta)` at depth `z_{k-1} = z0 + (k - 1/2) d` projected to cells
/// (`0.5 (P00 w, P11 h) r / (z s)`; orthographic: without the division). Row 0 (no previous
/// slice) is computed the same way and unused.
pub fn blur_rows(v: &EaView, cell: u32, theta_deg: f64) -> Vec<BlurRow> {
    let aspect = v.width as f64 / v.height.max(1) as f64;
    let proj = v.camera.projection_matrix(aspect);
    let persp = matches!(
        v.camera.projection,
        crate::camera::Projection::Perspective { .. }
    );
    let r = v.dz * theta_deg.to_radians().tan();
    (0..v.slices)
        .map(|k| {
            let z = (v.z0 + (k as f64 - 0.5) * v.dz).max(1e-9);
            let scale = if persp { 0.5 * r / z } else { 0.5 * r } / cell.max(1) as f64;
            let rpx = [
                scale * proj.x_axis.x * v.width as f64,
                scale * proj.y_axis.y * v.height as f64,
            ];
            let (wide, w) = blur_stencil(rpx);
            BlurRow { wide, rpx, w }
        })
        .collect()
}

/// Concentric map of `[-1, 1]^2` onto the unit disk (Shirley and Chiu): where the `n x n`
/// blur taps of a wide blur fall (`shaders/slice_pass.wgsl::concentric`).
pub fn concentric(a: [f64; 2]) -> [f64; 2] {
    if a[0] == 0.0 && a[1] == 0.0 {
        return [0.0; 2];
    }
    let q = std::f64::consts::FRAC_PI_4;
    if a[0].abs() > a[1].abs() {
        let t = q * a[1] / a[0];
        return [a[0] * t.cos(), a[0] * t.sin()];
    }
    let t = std::f64::consts::FRAC_PI_2 - q * a[0] / a[1];
    [a[1] * t.cos(), a[1] * t.sin()]
}

/// The `n x n` tap positions of a wide blur on the unit disk, in the shader's order (`i` over
/// x outer, `j` over y inner); one tap at the centre for `n = 1`.
pub fn blur_taps(n: u32) -> Vec<[f64; 2]> {
    let mut out = Vec::with_capacity((n * n) as usize);
    for i in 0..n {
        for j in 0..n {
            let g = if n > 1 {
                let u = |x: u32| (x as f64 + 0.5) / n as f64 * 2.0 - 1.0;
                [u(i), u(j)]
            } else {
                [0.0; 2]
            };
            out.push(concentric(g));
        }
    }
    out
}

/// The occlusion blur of one slice, a uniform disk of radius `rpx` cells (x, y). On a grid a
/// sub-cell blur cannot be sampled with bilinear taps without adding the interpolation's own
/// diffusion (a tap at offset `o` spreads variance `|o| (1 - |o|)`, linear in `o`, where the
/// disk adds `r^2 / 4`): repeated every slice, that diffusion would dominate and make the
/// spread depend on the cell size instead of the cone. Up to a radius of two cells the blur
/// is therefore the 3x3 stencil with the disk's variance per axis, `v = r^2 / 4`: the outer
/// product of `[v/2, 1 - v, v/2]` in x and y (rows y = -1, 0, 1), returned with `false`; the
/// same for every cell of the slice. Beyond, `true`: the shader takes `n x n` bilinear taps
/// mapped concentrically onto the disk (`n` = `blur_samples`).
pub fn blur_stencil(rpx: [f64; 2]) -> (bool, [[f64; 3]; 3]) {
    let mut w = [[0.0; 3]; 3];
    if rpx[0] > 2.0 || rpx[1] > 2.0 {
        return (true, w);
    }
    let k = |r: f64| {
        let v = r * r / 4.0;
        [v / 2.0, 1.0 - v, v / 2.0]
    };
    let (kx, ky) = (k(rpx[0]), k(rpx[1]));
    for (y, row) in w.iter_mut().enumerate() {
        for (x, c) in row.iter_mut().enumerate() {
            *c = ky[y] * kx[x];
        }
    }
    (false, w)
}

/// `n` points in the unit disk by Mitchell's best-candidate algorithm (a Poisson-disk-like
/// blue-noise set; deterministic): each point is the best of `10 i + 1` uniform candidates,
/// the one furthest from the points so far.
pub fn poisson_disk(n: usize) -> Vec<[f32; 2]> {
    let mut rng = SplitMix64(0x5eed_d15c);
    let mut pts: Vec<[f64; 2]> = Vec::with_capacity(n);
    let mut uniform = || {
        let r = rng.next_f64().sqrt();
        let a = std::f64::consts::TAU * rng.next_f64();
        [r * a.cos(), r * a.sin()]
    };
    for i in 0..n {
        let mut best = ([0.0; 2], -1.0);
        for _ in 0..(10 * i + 1) {
            let c = uniform();
            let d = pts
                .iter()
                .map(|p| (p[0] - c[0]).powi(2) + (p[1] - c[1]).powi(2))
                .fold(f64::INFINITY, f64::min);
            if d > best.1 {
                best = (c, d);
            }
        }
        pts.push(best.0);
    }
    pts.iter().map(|p| [p[0] as f32, p[1] as f32]).collect()
}

#[cfg(test)]
mod tests {
    #[test]
    fn the_light_in_a_slab_is_exact_however_the_slabs_cut_the_medium() {
        // A uniform medium (sigma 0.4 a unit, 6 units deep) cut into n slabs: the slabs' lit
        // opacities add up to the continuous model's int sigma exp(-sigma z) exp(-f sigma z) dz
        // for every n (one slab or 200), and the light leaving the last is exp(-f sigma L).
        // The light at each slab's middle (the midpoint rule) or the chord between the slabs'
        // fronts depends on n (one slab: off by more than 3%).
        let (sigma, l, f) = (0.4f64, 6.0f64, cone_path_factor(45.0));
        let exact = (1.0 - (-(1.0 + f) * sigma * l).exp()) / (1.0 + f);
        for n in [1usize, 2, 3, 7, 50, 200] {
            let tau = sigma * l / n as f64;
            let (mut run, mut sum, mut mid, mut chord) = (1.0, 0.0, 0.0, 0.0);
            for k in 0..n {
                let (lo, leave) = light_in_slab(run, tau, f);
                let a = 1.0 - (-tau).exp();
                let eye = (-tau * k as f64).exp();
                sum += eye * lo;
                mid += eye * a * run * (-0.5 * f * tau).exp();
                chord += eye * a * 0.5 * (run + leave);
                run = leave;
            }
            assert!(
                (sum - exact).abs() < 1e-12,
                "{n} slabs: {sum} against {exact}"
            );
            assert!((run - (-f * sigma * l).exp()).abs() < 1e-12);
            if n == 1 {
                assert!((mid - exact).abs() > 0.03 * exact, "{n}: midpoint {mid}");
                assert!((chord - exact).abs() > 0.03 * exact, "{n}: chord {chord}");
            }
        }
        // A slab too dense to see through shows 1 / (1 + f) of the light reaching it, and
        // passes none on; a transparent one adds nothing and passes all.
        let (lo, leave) = light_in_slab(0.8, 1e3, f);
        assert!((lo - 0.8 / (1.0 + f)).abs() < 1e-12 && leave == 0.0);
        assert_eq!(light_in_slab(0.8, 0.0, f), (0.0, 0.8));
        // A thin slab: its opacity tau times the light.
        let (lo, _) = light_in_slab(0.8, 1e-6, f);
        assert!((lo / (0.8 * 1e-6) - 1.0).abs() < 1e-5);
    }

    use super::*;

    #[test]
    fn the_cone_path_factor_is_the_mean_path_through_a_slab() {
        // Against the mean of 1 / cos(phi) over the cone by the midpoint rule in cos(phi)
        // (uniform in solid angle), and against Monte Carlo of the transmittance of a uniform
        // medium: exp(-sigma z f) matches E[exp(-sigma z / cos(phi))] to first order, below it.
        for theta in [1e-6, 0.5, 10.0, 25.0, 45.0, 65.0, 80.0] {
            let f = cone_path_factor(theta);
            let c = theta.to_radians().cos();
            let n = 20000;
            let mean = (0..n)
                .map(|i| 1.0 / (1.0 - (1.0 - c) * (i as f64 + 0.5) / n as f64))
                .sum::<f64>()
                / n as f64;
            assert!(
                (f - mean).abs() < 1e-6 * mean,
                "{theta}: {f} against {mean}"
            );
            for tau in [0.01, 0.5, 2.0] {
                let cone = (0..n)
                    .map(|i| (-tau / (1.0 - (1.0 - c) * (i as f64 + 0.5) / n as f64)).exp())
                    .sum::<f64>()
                    / n as f64;
                let ours = (-tau * f).exp();
                assert!(ours <= cone + 1e-12, "{theta}, {tau}: {ours} above {cone}");
                // The paper's exp(-tau) is further from the cone than ours wherever the cone is wide enough to tell.
                if theta >= 10.0 {
                    assert!(cone - ours < (-tau).exp() - cone, "{theta}, {tau}");
                }
            }
        }
        assert!((cone_path_factor(25.0) - 1.0499945).abs() < 1e-6);
        assert!((cone_path_factor(45.0) - 1.1832763).abs() < 1e-6);
        assert_eq!(cone_path_factor(0.0), 1.0);
        assert_eq!(cone_path_factor(f64::NAN), 1.0);
        assert_eq!(cone_path_factor(90.0), f64::INFINITY);
    }

    /// The data's cell is the largest power of two a voxel covers on screen (2 to 64): an
    /// orthographic view 100 units high at 400 pixels draws a unit voxel 4 pixels wide.
    #[test]
    fn light_cells_follow_the_voxels_on_screen() {
        use crate::camera::{Camera, Projection};
        use glam::DVec3;
        let view = |voxel: f64, height: f64, w: u32, h: u32| EaView {
            camera: Camera {
                eye: DVec3::new(0.0, 0.0, 100.0),
                target: DVec3::ZERO,
                up: DVec3::Y,
                projection: Projection::Orthographic { height },
                near: 1.0,
                far: 200.0,
                skew: 0.0,
            },
            width: w,
            height: h,
            z0: 50.0,
            dz: 1.0,
            slices: 100,
            background: [0.0; 3],
            clip: vec![],
            voxel,
        };
        for (voxel, height, w, h, want) in [
            (1.0, 100.0, 400, 400, 4),
            (1.0, 100.0, 399, 399, 2),
            (1.0, 100.0, 800, 400, 4),
            (0.3, 100.0, 400, 400, 2),
            (0.0, 100.0, 400, 400, 2),
            (f64::NAN, 100.0, 400, 400, 2),
            (50.0, 100.0, 1024, 1024, 64),
            (3.0, 100.0, 400, 400, 8),
        ] {
            let v = view(voxel, height, w, h);
            assert_eq!(data_cell(&v), want, "voxel {voxel} at {w} x {h}");
        }
        // The scene's own cell wins; the budget still doubles the data's.
        let v = view(1.0, 100.0, 400, 400);
        assert_eq!(light_grid(Some(1), None, false, &v, 1 << 30), (1, 4));
        assert_eq!(light_grid(None, None, false, &v, 1 << 30), (4, 4));
        // The light is stored a voxel (a slice) apart: 100^2 cells x 100 slices of f32 at 4
        // px (4 MB); at 8 px 50^2 x 100 (1 MB).
        assert_eq!(light_grid(None, None, false, &v, 1_000_000), (8, 4));
        assert_eq!(light_grid(None, Some(1), false, &v, 1_000_000), (8, 1));
        // The budget counts the stored slices, not the eye's: at half a voxel apart a step
        // of eight slices stores four, 100^2 x ceil(100 / 8) x 4 (2.08 MB) at 4 px, which
        // fits 2.1 MB; with tubes in the light (a step a slice, 4 MB) the cells double.
        let mut v = view(1.0, 100.0, 400, 400);
        v.dz = 0.5;
        assert_eq!(light_grid(None, None, false, &v, 2_100_000), (4, 8));
        assert_eq!(light_grid(None, None, true, &v, 2_100_000), (8, 1));
        // Without a voxel size: 2 px cells a slice deep, doubled to fit (at most 64 px).
        let v = view(0.0, 100.0, 512, 512);
        assert_eq!(light_grid(None, None, false, &v, 1 << 30), (2, 1));
        assert_eq!(light_grid(None, None, false, &v, 20 << 20), (4, 1));
        assert_eq!(light_grid(None, None, false, &v, 0), (64, 1));
        assert_eq!(light_grid(None, Some(4), false, &v, 1 << 30), (2, 4));
    }

    #[test]
    fn the_light_steps_four_voxels_deep_where_the_volume_alone_casts_it() {
        use crate::camera::Camera;
        use glam::DVec3;
        let view = |voxel: f64, dz: f64, slices: u32| EaView {
            camera: Camera::orbit([DVec3::ZERO, DVec3::ONE], 0.0, 0.0, 2.0, None),
            width: 64,
            height: 64,
            z0: 3.0,
            dz,
            slices,
            background: [0.0; 3],
            clip: vec![],
            voxel,
        };
        // Half a voxel apart (the default slice distance): steps of eight slices, four
        // voxels deep.
        let v = view(1.0, 0.5, 101);
        assert_eq!(data_step(&v), 8);
        // Finer slices at most 8 a step; coarser ones fewer, as many as fit in four voxels.
        assert_eq!(data_step(&view(1.0, 0.25, 101)), 8);
        assert_eq!(data_step(&view(1.0, 0.01, 101)), 8);
        assert_eq!(data_step(&view(1.0, 0.6, 101)), 4);
        assert_eq!(data_step(&view(1.0, 1.0, 101)), 4);
        assert_eq!(data_step(&view(1.0, 1.5, 101)), 2);
        assert_eq!(data_step(&view(1.0, 2.5, 101)), 1);
        assert_eq!(data_step(&view(1.0, 4.5, 101)), 1);
        for bad in [0.0, f64::NAN, -1.0] {
            assert_eq!(data_step(&view(bad, 0.5, 101)), 1);
        }
        // The scene's step wins; tubes keep the paper's step.
        assert_eq!(light_step(None, &v, false), 8);
        assert_eq!(light_step(None, &v, true), 1);
        assert_eq!(light_step(Some(4), &v, true), 4);
        assert_eq!(light_step(Some(0), &v, false), 1);
        assert_eq!(light_step(Some(3), &v, false), 2);
        assert_eq!(light_step(Some(100), &v, false), 8);
        assert_eq!(light_step(Some(1), &v, false), 1);
        // Samples stay a voxel apart whatever the step.
        assert_eq!(voxel_step(&v), 2);
        assert_eq!(voxel_step(&view(1.0, 0.25, 101)), 4);
        assert_eq!(voxel_step(&view(f64::NAN, 0.25, 101)), 1);
        for (step, want) in [(1, 1), (2, 1), (4, 2), (8, 4)] {
            assert_eq!(light_samples(&v, step), want, "step {step}");
        }
        assert_eq!(light_samples(&view(1.0, 0.25, 101), 8), 2);
        assert_eq!(light_samples(&view(1.0, 1.5, 101), 4), 4);
        assert_eq!(light_samples(&view(0.0, 0.5, 101), 4), 4);
        // The light's view: the same front, slabs a step deep covering every eye slice.
        let l = light_view(&v, 2);
        assert_eq!((l.z0, l.dz, l.slices), (3.0, 1.0, 51));
        assert!(l.z0 + l.dz * l.slices as f64 >= v.z0 + v.dz * v.slices as f64);
        assert_eq!(light_view(&v, 1).slices, 101);
        // The paper's blur: `step` slices of variance (d tan)^2 / 4 each make one step of
        // (step d tan')^2 / 4; the cone model keeps its angle.
        for m in [2u32, 4] {
            let t = step_theta(25.0, m, false).to_radians().tan();
            let t0 = 25f64.to_radians().tan();
            assert!(((m as f64 * t).powi(2) - m as f64 * t0 * t0).abs() < 1e-12);
            assert_eq!(step_theta(25.0, m, true), 25.0);
        }
        assert_eq!(step_theta(25.0, 1, false), 25.0);
    }

    #[test]
    fn the_blur_stencil_has_the_disks_variance_and_sums_to_one() {
        for r in [0.0, 0.3, 1.0, 1.9] {
            let (wide, w) = blur_stencil([r, 0.5 * r]);
            assert!(!wide);
            let sum: f64 = w.iter().flatten().sum();
            assert!((sum - 1.0).abs() < 1e-12);
            // Second moments: x^2 weights against r^2 / 4 (a uniform disk's, per axis).
            let vx: f64 = (0..3)
                .map(|y| {
                    (0..3)
                        .map(|x| w[y][x] * ((x as f64) - 1.0).powi(2))
                        .sum::<f64>()
                })
                .sum();
            let vy: f64 = (0..3)
                .map(|y| {
                    (0..3)
                        .map(|x| w[y][x] * ((y as f64) - 1.0).powi(2))
                        .sum::<f64>()
                })
                .sum();
            assert!((vx - r * r / 4.0).abs() < 1e-12, "{r}: {vx}");
            assert!((vy - r * r / 16.0).abs() < 1e-12, "{r}: {vy}");
            assert!(w.iter().flatten().all(|&v| v >= 0.0));
        }
        assert!(
            blur_stencil([2.5, 0.1]).0,
            "beyond two cells the shader takes taps"
        );
    }

    #[test]
    fn the_concentric_taps_cover_the_disk_evenly() {
        // The map is area-preserving: n x n taps on equal-area cells of the square land on
        // equal-area cells of the disk, so their mean is the centre and their second moment
        // per axis approaches the uniform disk's 1/4.
        let t = blur_taps(9);
        assert_eq!(t.len(), 81);
        assert!(t.iter().all(|p| p[0].hypot(p[1]) <= 1.0 + 1e-12));
        let mean = t.iter().fold([0.0; 2], |a, p| [a[0] + p[0], a[1] + p[1]]);
        assert!(mean[0].abs() < 1e-9 && mean[1].abs() < 1e-9);
        let m2 = t.iter().map(|p| p[0] * p[0]).sum::<f64>() / 81.0;
        assert!((m2 - 0.25).abs() < 0.02, "{m2}");
        assert_eq!(blur_taps(1), vec![[0.0, 0.0]]);
        // The corners of the square go to the circle, the edges' midpoints too.
        let c = concentric([1.0, 1.0]);
        assert!((c[0].hypot(c[1]) - 1.0).abs() < 1e-12);
        assert!((concentric([0.0, -1.0])[1] + 1.0).abs() < 1e-12);
    }

    #[test]
    fn poisson_disk_points_are_in_the_disk_and_spread() {
        let p = poisson_disk(64);
        assert_eq!(p.len(), 64);
        assert!(p.iter().all(|q| q[0] * q[0] + q[1] * q[1] <= 1.0));
        let mut dmin = f32::INFINITY;
        for i in 0..p.len() {
            for j in 0..i {
                dmin = dmin.min(((p[i][0] - p[j][0]).powi(2) + (p[i][1] - p[j][1]).powi(2)).sqrt());
            }
        }
        // Uniform random points would have pairs far closer; a Poisson-disk set of 64 points
        // in the unit disk keeps them about 0.2 apart (ideal hexagonal packing: 0.24).
        assert!(dmin > 0.1, "closest pair {dmin}");
        // The centroid is near the centre.
        let c = p
            .iter()
            .fold([0.0f32; 2], |a, q| [a[0] + q[0], a[1] + q[1]]);
        assert!((c[0] / 64.0).abs() < 0.1 && (c[1] / 64.0).abs() < 0.1);
    }
}
