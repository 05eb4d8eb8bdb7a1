//! Eichelbaum, Hlawitschka and Scheuermann, "LineAO - Improved Three-Dimensional Line
//! Rendering" (IEEE TVCG 2013; `../shared/seeds/000_e36ca5266f3759f7.txt`): the CPU side of
//! the paper - its equation index, the model as umbra implements it where the paper is
//! ambiguous or wrong, the pure functions the GPU pass is to be built on, and the CPU twin of
//! that pass over a plain normal-depth image ([`line_ao`], [`line_ao_image`]). The paper's
//! equations are re-derived in `../shared/notes/lines-papers.md` §1; the parameters and
//! checks are issue 11's item 3.
//!
//! | paper | CPU (this module) | GPU (`engine`, `shaders/`) | checked by |
//! |---|---|---|---|
//! | §3.2 depth `d_l` and normal `n_l`: the ND map and its "Gaussian" pyramid (§3.4: mipmaps) | [`NormalDepth`], [`NormalDepth::pyramid`], [`normalised_depth`] | `shaders/gbuffer.wgsl::fs_nd` (the guard-banded map), `line_ao.wgsl::nd_level0`, `nd_half`, `normalised_depth` | `the_pyramid_halves_with_ceil_and_averages_background_as_far`, `normalised_depth_is_linear_over_near_far_and_keeps_zero_for_background` |
//! | §3.2 zoom `z(P)`: the screen radius of a unit world sphere at P | [`zoom_px`] | `line_ao.wgsl::main` (`zoom_scale / z`) | `zoom_is_the_projected_length_of_one_world_unit` |
//! | eq. 7 samples `s_h / (j + 1)` on level j (ceil: the paper's 59) | [`samples_on_level`] | `main` (`(s_h + j) / (j + 1)`) | `sample_counts_are_32_16_11` |
//! | eq. 7 radii `r0 + j z(P)`; §3.2.3 `r0 = 1.5 x` line width; eq. 16 `r0 = 1.5 z t_s` (tubes) | [`level_radius`], [`LineAoSettings::r0_pixels`], [`LineWidth`] | `main` (the width code of `fs_nd`), `engine::line_ao::guard_pixels` | `radii_follow_eq_7_and_eq_16` |
//! | §3.4 random vectors `R1` (per pixel), `R2` (per sample and level) | [`rotation_angle`], [`pcg_hash`], [`sample_offset`], [`hemisphere_direction`] | `rotation_angle`, `pcg_hash`, `sample_offset`, `hemisphere_direction` | `the_rotation_is_a_fixed_function_of_pixel_and_seed`, `sample_offsets_fill_the_disc_and_differ_between_levels`, `hemisphere_directions_are_unit_and_face_the_normal` |
//! | GPU against CPU, pixel for pixel | | | `engine/tests/line_ao_render.rs::the_gpu_kernel_agrees_with_its_cpu_twin` |
//! | eq. 8 visibility (strict: `Δd > delta_0`; tangent plane, its slope along P's own ray) | [`occludes`], [`plane_rise`], [`pixel_ray`], [`Visibility`] | `main`, `plane_rise`, `ao_pixel_ray` | `an_isolated_line_on_an_empty_background_is_not_occluded`, `an_oblique_plane_in_perspective_does_not_occlude_itself` |
//! | eq. 10-13 `g_depth` (eq. 12 with `Δd_l`), `delta(l) = (1 - l / s_r)^2`, `h(x) = 3x^2 - 2x^3` | [`delta`], [`LineAoSettings::delta`], [`smoothstep_h`], [`g_depth`] | `delta`, `smoothstep`, `g_depth` | `delta_is_1_4_9ths_1_9th_for_three_levels`, `g_depth_follows_eq_12`, `a_pixel_behind_a_uniform_wall_gets_1_minus_h_per_level` |
//! | eq. 14-15 `g_light = 1 - min(1, Σ BRDF(L_s, I_s, n_l(P), ω))` | [`phong_brdf`], [`g_light`] | `phong_brdf`, `main` | `g_light_follows_eq_15_and_a_head_light_of_one_zeroes_it`, `a_pixel_behind_a_uniform_wall_gets_1_minus_h_per_level` |
//! | eq. 4-7, 9: the level averages summed, clamped to [0, 1] | [`line_ao`], [`line_ao_image`], [`LineAoTerms`] | `main` (layer and factor channels) | the wall, `an_isolated_line_on_an_empty_background_is_not_occluded`, `all_samples_off_screen_and_one_level_give_finite_values` |
//! | seed 002 (Köhler et al.) eq. 10-12: the angle map `α = |t.x|`, `g_align = max(A0, min(1, I h(Δ)))`, `g = g_depth g_light g_align`; the roll-invariant doubled-angle form | [`tangent_texel`], [`alignment_difference`], [`g_align`], [`Alignment`], [`NormalDepth::tangent`] | `gbuffer.wgsl::fs_nd` (the tangent target), `line_ao.wgsl::nd_half` (its pyramid), `g_align` | `g_align_follows_eq_11_and_the_invariant_difference_ignores_the_roll`, `a_parallel_bundle_gets_about_the_floor_times_the_classic_ao_and_a_crossing_the_same`, `engine/tests/line_ao_render.rs::anisotropic_lineao_spares_parallel_lines_and_keeps_crossings_and_the_invariant_form_ignores_the_roll` |
//! | §3.2.3 parameters | [`LineAoSettings`] (`Default`, `check`) | `render.lineao.*` keys (`scene::spec::LineAoSpec`), `engine::line_ao::LineAoParams` | `the_defaults_are_the_papers_and_check_names_the_field` |
//!
//! What the paper says, in short: around each line pixel P, `s_r` discs ("hemispheres") of
//! radius `r0 + j z(P)` pixels, `j = 0 .. s_r - 1`, each sampled `s_h / (j + 1)` times on
//! level j of a depth/normal pyramid. A sample occludes when the surface seen there is nearer
//! than P (the depth map read as a height field: only the screen position is looked up), with
//! the weight `g = g_depth g_light`: a smoothstep that falls from 1 at `Δd = delta_0` to 0 at
//! `Δd = delta(j)`, times one minus the light reflected at P towards the sample. The level
//! averages are summed (overlaps darken dense bundles on purpose) and clamped to [0, 1].
//!
//! What umbra decides where the paper is ambiguous or wrong (and why):
//! * **Depth normalisation** (the unit clash I3/G7: eq. 10 claims `Δd ∈ [-1, 1]`, §3.4 stores
//!   `z_clip`, OpenWalnut the non-linear window depth, seed 002 eye millimetres): the depth is the
//!   linear view depth normalised over the camera's clipping range,
//!   `d = (z - near) / (far - near)` ([`normalised_depth`]). umbra fits near and far to the
//!   scene's bounding sphere (`camera::near_far`), so `far - near` is the scene's depth extent
//!   whatever the eye's distance: `Δd` is then in [-1, 1] as eq. 10 says, `delta_0 = 1e-4` and
//!   `delta(l) <= 1` are fractions of the scene's depth, and a dolly or an orbit leaves them
//!   unchanged. Only differences of `d` enter the kernel, except that background averages in
//!   as `d = 1`.
//! * **Background** (G6, G19): umbra's G-buffer stores 0 for "no surface"; here depth 0 or not
//!   finite is background. Read naively, 0 would be the nearest depth and every background
//!   sample an occluder. Background counts as far (`d = 1`) in the pyramid's mean (so single
//!   lines fade on the coarse levels, §3.2.1: "coarse or single lines disappear"), a
//!   background sample never occludes (it is a valid, open sample), and a background pixel is
//!   not evaluated ([`LineAoTerms::OPEN`]): lines cast no drop shadow onto the background.
//! * **Visibility** (G11): eq. 8 with eq. 12 makes every sample with `0 <= Δd < delta_0` a full
//!   occluder - including `Δd = 0`, so a flat line would occlude itself on every sample that
//!   lands on it. Here a sample occludes only when `Δd > delta_0` (OpenWalnut's
//!   `step(delta_0, Δd)`); `g_depth` is continuous there (`1 - h(0) = 1`).
//! * **P's depth on a coarse level** (issue: "level j compared with level j"): the samples read
//!   the pyramid's depth with background as far, as the paper; P itself reads the mean of its
//!   block's *surfaces* ([`NormalDepth::cover`]). With the far-mean for P too, a block that
//!   mixes P's line with background is farther than the all-line block beside it, and an
//!   isolated line occludes itself on the coarse levels (measured on the GPU: visibility down
//!   to 0.955 along a single line under perspective; with the surfaces' mean it is 1).
//! * **Tangent plane** ([`Visibility::Plane`], the default; `render.lineao.visibility`): eq. 8
//!   reads the depth map as a height field, so a line running into the depth is its own
//!   occluder - half its samples along it are nearer than P by more than `delta_0` (1e-4 of the
//!   scene depth is a slope of a few hundredths). Measured on the GPU: four sparse tilted lines
//!   had a mean visibility of 0.75 under eq. 8, against an isolated tube's ray-traced AO of
//!   about 1. Here a sample occludes when its surface is nearer than P's tangent plane at the
//!   sample ([`plane_rise`], between the texels' centres where their depths hold), by more than
//!   `delta_0`; `g_depth` takes that difference. P's normal is the strip's own for lines (the
//!   G-buffer's normal-depth pass writes it; it faces along the view axis, where the lit normal
//!   faces the eye point) and the surface's for tubes, whose convex sides then do not occlude
//!   them either. [`Visibility::Height`] keeps the paper's rule.
//! * **Eq. 12** (typo I1): its third case reads `Δd_l`, not `d_l` (seed 002 eq. 5 prints it so):
//!   `g_depth = 1 - h((Δd - delta_0) / (delta(l) - delta_0))`. `check` requires
//!   `delta_0 < delta(s_r - 1)` so the smoothstep's edges are never reversed (OpenWalnut's last
//!   level, G4).
//! * **Eq. 11** as printed, `(1 - l / s_r)^2`: never 0, and fine at `s_r = 1` (1). The paper's
//!   "s_r needs to be larger than one" holds only for OpenWalnut's `(1 - l / (s_r - 1))^2`
//!   (I5), which divides by zero there and is 0 on the last level.
//! * **Sample counts**: `ceil(s_h / (j + 1))`: 32 + 16 + 11 = the paper's 59 (floor gives 58).
//! * **Sum, not mean** (eq. 7): `LineAO = clamp(Σ_j AO_j, 0, 1)`, no `1 / s_r` (OpenWalnut
//!   divides by it: [`LevelsCombine::Mean`], `render.lineao.levels_combine = "mean"`, which
//!   keeps dense bundles from saturating at 0; measured by `umbra bench lineao`).
//! * **Radii**: `r0` is in pixels: `r0_widths` (1.5, §3.2.3) times the line's width on screen,
//!   which is the width itself for pixel-width lines ([`LineWidth::Pixels`], the paper's lines)
//!   and `z(P) t_s` for tubes and world-width lines ([`LineWidth::World`], eq. 16; `t_s` is
//!   the tube's diameter). The step per level is `radius_step` world units projected,
//!   `j radius_step z(P)`: the paper's literal "one world unit" depends on the data's unit (mm
//!   for brains, m for a CFD grid), so it is a setting, default 1.
//! * **Zoom** `z(P)`: analytic from umbra's camera ([`zoom_px`]), pixels per world unit at P's
//!   view depth, the on-axis size of a small sphere (`0.5 P11 H / z` under perspective,
//!   `H / height` orthographic). The paper's zoom map is the same quantity per pixel.
//! * **Pyramid** (G2): level j halves level j - 1 (ceil, so odd sizes keep their last row and
//!   column) with the 2 x 2 mean - the mipmap filter the paper uses (§3.4) and calls Gaussian.
//!   Depth: the mean over the block's texels inside the image, background counting as 1; a
//!   block of background alone stays background. Normal: the renormalised sum of the covered
//!   texels' normals. P and its samples are compared on the same level j, as the paper says
//!   (OpenWalnut reads P on level 0). Radii stay in level-0 pixels; a sample at level-0 position
//!   q reads the level-j texel `floor(q / 2^j)`, nearest (r32float is not filterable on the
//!   GPU without a feature).
//! * **Sampling** (§3.4, G9): the paper reflects a per-pixel random vector `R1` from a tiled
//!   low-resolution noise texture about a per-sample `R2` read at `(i / s, j / (s_r - 1))` - a
//!   coordinate that wraps the last level onto the first and divides by zero at `s_r = 1`.
//!   Here the offsets of level j are a fixed golden-angle (Vogel) spiral in the unit disc,
//!   uniform in area and evenly spread for any count (32, 16, 11), turned by
//!   `2 pi frac(j phi)` so the levels' directions differ (what `R2`'s level coordinate was
//!   for), and the whole set is rotated per pixel by an angle hashed from (x, y, seed) with a
//!   32-bit PCG hash: no tile (no block artefacts, seed 002 §4.4), only `u32` arithmetic so WGSL
//!   computes the same bits, and a fixed function of the pixel so a frame of an orbit equals a
//!   single render at the same camera. Each offset `o` is lifted to the hemisphere,
//!   `ω = (o, sqrt(1 - |o|^2))` in view space - uniform in the disc lifts to cosine-weighted
//!   (Malley), the weighting eq. 4 otherwise drops - and flipped into the hemisphere of
//!   `n_j(P)`. Only `ω.xy` is used (§3.2.1: no back-projection), scaled by the radius, with
//!   the view's y up turned into the pixels' y down.
//! * **Light** (eq. 14-15, G10): one head light, along the view axis (+z in view space: exact
//!   for orthographic cameras; under perspective the direction to the eye differs from the
//!   axis by the pixel's angle off it). The BRDF is Phong without its ambient term (ambient is
//!   not light reflected from the source): `I_s (k_d max(n.L, 0) + k_s max(R.ω, 0)^p)`,
//!   `R = 2 (n.L) n - L`, with its own intensity `I_s = 0.5` (seed 002; umbra's ambient + diffuse
//!   = 1 passed in as `I_s` would zero the AO of every view-facing line) and umbra's head-light
//!   material `k_d = 0.7`, `k_s = 0.3`, `p = 32`. A view-facing line thus gets
//!   `g_light = 1 - 0.35 - 0.15 max(R.ω, 0)^32`.
//! * **Borders** (§3.4, G1, G3): samples outside the image are left out of their level's
//!   average (the renormalising policy of umbra's vicinity pass); a level with no sample on
//!   screen contributes 0, never 0/0. The paper's guard band is the GPU pass's business: the
//!   twin then runs on the guard-banded buffer.
//! * **Factor channels** (issue 11 item 5, seed 002 Fig. 4): [`LineAoTerms`] also carries the
//!   mean of each factor alone over the on-screen samples - the occlusion `1 - V`, `g_depth`,
//!   `g_light` - averaged (not summed) over the levels, so each lies in [0, 1]; the AO is the
//!   mean of their product per level, not the product of these means.
//!
//! * **Anisotropic LineAO** (seed 002 §4.2): the tangent is taken in pixels (seed 002's NDC
//!   tangents are distorted by the aspect ratio), stored as [`tangent_texel`], and averaged on
//!   the coarse levels over the texels covered by lines only (the paper mipmaps `|t.x|` with the
//!   background as 0, "vertical"). Tubes have no tangent in the map: `g_align` is 1 wherever P or
//!   the sample is not a line. The paper's `α = |t.x|` is kept as [`Alignment::Paper`]; the
//!   default [`Alignment::Invariant`] uses `|sin Δθ|` of the doubled-angle vectors.
//!
//! Shading (`colour (1 - LineAO) + specular`, or seed 002's Phong `(1 - AO)`) belongs to the
//! composite; this module ends at the AO.

use crate::camera::{Camera, Projection};
use glam::{Vec2, Vec3};
use std::f32::consts::TAU;

/// The most levels (`s_r`) [`LineAoSettings::check`] allows: on level 7 a texel covers
/// 128 x 128 pixels, beyond any useful disc, and the per-level terms fit a fixed array.
pub const MAX_LEVELS: usize = 8;

/// The golden angle `pi (3 - sqrt 5)`: consecutive spiral points this far apart in angle never
/// line up, whatever the count.
pub const GOLDEN_ANGLE: f32 = 2.399_963;

/// How wide the lines are, which sets `r0`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LineWidth {
    /// A width on screen in pixels (the paper's lines; `[[lines]] width_unit = "pixels"`).
    Pixels(f32),
    /// A world width (tubes: the diameter `t_s` of eq. 16; world-width lines as seed 002),
    /// projected with `z(P)`.
    World(f32),
}

/// How the depth range of eq. 12 changes with the level.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Falloff {
    /// Eq. 11, `delta(l) = (1 - l / s_r)^2`: outer levels count only near occluders (Fig. 3b).
    #[default]
    Paper,
    /// `delta(l) = 1` on every level: the whole scene depth occludes on each (Fig. 3a).
    Constant,
}

/// How the levels' occlusion adds up (eq. 7).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum LevelsCombine {
    /// Eq. 7: the sum, clamped to [0, 1] (overlaps darken dense bundles on purpose).
    #[default]
    Sum,
    /// Their mean, `1 / s_r` times the sum (OpenWalnut): no level saturates the result.
    Mean,
}

/// What a sample is compared with (eq. 8).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Visibility {
    /// The surface seen at the sample occludes when it is nearer than P's tangent plane there
    /// (by more than `delta_0`): a line or tube does not occlude itself where it runs into the
    /// depth (see the module doc).
    #[default]
    Plane,
    /// The paper's eq. 8: nearer than P itself (the depth map as a height field).
    Height,
}

/// How anisotropic LineAO (Köhler et al., seed 002 §4.2) measures two lines' difference in
/// direction on screen.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Alignment {
    /// `|sin Δθ|` from the doubled-angle tangents `(cos 2θ, sin 2θ)` (whose means are
    /// meaningful: a crossing averages to 0): the same for every camera roll.
    #[default]
    Invariant,
    /// The paper's eq. 10-11: `|α(P) - α(q)|` with `α = |t.x|`, which counts +45 and -45 degree
    /// lines as parallel and changes with the roll.
    Paper,
}

/// LineAO's parameters (§3.2.3 and issue 11 item 3). `Default` is the paper's set.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LineAoSettings {
    /// `s_r`, the number of discs and pyramid levels: 3. At most [`MAX_LEVELS`].
    pub levels: u32,
    /// `s_h`, the samples of the first disc (level j takes `ceil(s_h / (j + 1))`): 32.
    pub samples: u32,
    /// `r0` as a multiple of the line's width on screen: 1.5.
    pub r0_widths: f32,
    /// The width of the lines (or tubes) the pixel belongs to. The GPU pass will read it per
    /// pixel (lines and tubes differ); the CPU twin takes one here. Default 2 pixels, a
    /// placeholder until `[[lines]] width` has its default.
    pub line_width: LineWidth,
    /// The radius added per level, in world units (projected with `z(P)`): 1, the paper's
    /// literal step, which depends on the data's unit.
    pub radius_step: f32,
    /// `delta_0`, the smallest depth difference (normalised depth) that occludes: 1e-4.
    pub delta0: f32,
    /// `I_s` of the head light in eq. 14: 0.5 (seed 002).
    pub light_intensity: f32,
    /// The BRDF's diffuse coefficient `k_d`: 0.7 (umbra's head light).
    pub light_diffuse: f32,
    /// The BRDF's specular coefficient `k_s`: 0.3 (umbra's head light).
    pub light_specular: f32,
    /// The BRDF's Phong exponent `p`: 32 (umbra's head light).
    pub light_shininess: f32,
    /// The seed of the per-pixel rotation (the scene's seed): 0.
    pub seed: u32,
    /// The depth range per level (eq. 11 or constant).
    pub falloff: Falloff,
    /// P's tangent plane or the paper's height field.
    pub visibility: Visibility,
    /// The levels' sum (eq. 7) or mean.
    pub levels_combine: LevelsCombine,
    /// Anisotropic LineAO (seed 002 eq. 10-12): samples on lines running the same way on
    /// screen as P's count less, `g_align` ([`g_align`]).
    pub anisotropic: bool,
    pub alignment: Alignment,
    /// `I` of eq. 11: 15.
    pub intensity: f32,
    /// `A0` of eq. 11, the least `g_align`: 0.1.
    pub floor: f32,
    /// The world length of one unit of normalised depth (the camera's `far - near`): how the
    /// tangent plane's rise, in world units, becomes a normalised depth. Set by the pass from
    /// the camera; 1 by default.
    pub depth_range: f32,
    /// The camera's focal length in pixels of the normal-depth map (perspective: `0.5 P11 H`;
    /// its principal point the map's centre), or 0 for an orthographic camera (the default):
    /// the tangent plane's slope at P follows P's own ray ([`plane_rise`]).
    pub ray_focal: f32,
}

impl Default for LineAoSettings {
    fn default() -> Self {
        LineAoSettings {
            levels: 3,
            samples: 32,
            r0_widths: 1.5,
            line_width: LineWidth::Pixels(2.0),
            radius_step: 1.0,
            delta0: 1e-4,
            light_intensity: 0.5,
            light_diffuse: 0.7,
            light_specular: 0.3,
            light_shininess: 32.0,
            seed: 0,
            falloff: Falloff::Paper,
            visibility: Visibility::Plane,
            levels_combine: LevelsCombine::Sum,
            anisotropic: false,
            alignment: Alignment::Invariant,
            intensity: 15.0,
            floor: 0.1,
            depth_range: 1.0,
            ray_focal: 0.0,
        }
    }
}

use crate::settings::require;
pub use crate::settings::SettingError;

impl LineAoSettings {
    /// The first setting out of range, by its field's name.
    pub fn check(&self) -> Result<(), SettingError> {
        let finite_pos = |v: f32| v.is_finite() && v > 0.0;
        let finite_nonneg = |v: f32| v.is_finite() && v >= 0.0;
        require(
            (1..=MAX_LEVELS as u32).contains(&self.levels),
            "levels",
            || format!("{} is not in 1..={MAX_LEVELS}", self.levels),
        )?;
        require((1..=1024).contains(&self.samples), "samples", || {
            format!("{} is not in 1..=1024", self.samples)
        })?;
        require(finite_pos(self.r0_widths), "r0_widths", || {
            format!("{} is not a positive number", self.r0_widths)
        })?;
        let w = match self.line_width {
            LineWidth::Pixels(w) | LineWidth::World(w) => w,
        };
        require(finite_pos(w), "line_width", || {
            format!("{w} is not a positive width")
        })?;
        require(finite_nonneg(self.radius_step), "radius_step", || {
            format!("{} is not a non-negative number", self.radius_step)
        })?;
        let last = self.delta(self.levels - 1);
        require(
            finite_nonneg(self.delta0) && self.delta0 < last,
            "delta0",
            || {
                format!(
                    "{} must be at least 0 and below delta(s_r - 1) = {last}",
                    self.delta0
                )
            },
        )?;
        require(
            finite_nonneg(self.light_intensity),
            "light_intensity",
            || format!("{} is not a non-negative number", self.light_intensity),
        )?;
        require(finite_nonneg(self.light_diffuse), "light_diffuse", || {
            format!("{} is not a non-negative number", self.light_diffuse)
        })?;
        require(finite_nonneg(self.light_specular), "light_specular", || {
            format!("{} is not a non-negative number", self.light_specular)
        })?;
        require(finite_pos(self.light_shininess), "light_shininess", || {
            format!("{} is not a positive exponent", self.light_shininess)
        })?;
        require(finite_nonneg(self.intensity), "intensity", || {
            format!("{} is not a non-negative number", self.intensity)
        })?;
        require(
            finite_nonneg(self.floor) && self.floor <= 1.0,
            "floor",
            || format!("{} is not in [0, 1]", self.floor),
        )?;
        require(finite_pos(self.depth_range), "depth_range", || {
            format!("{} is not a positive length", self.depth_range)
        })?;
        require(finite_nonneg(self.ray_focal), "ray_focal", || {
            format!("{} is not a focal length in pixels (or 0)", self.ray_focal)
        })?;
        Ok(())
    }

    /// The depth range of level `l`: [`delta`] under [`Falloff::Paper`], 1 under
    /// [`Falloff::Constant`].
    pub fn delta(&self, l: u32) -> f32 {
        match self.falloff {
            Falloff::Paper => delta(l, self.levels),
            Falloff::Constant => 1.0,
        }
    }

    /// `r0` in pixels at zoom `z(P)` (pixels per world unit): `r0_widths` times the line's
    /// width on screen (§3.2.3 for pixel widths, eq. 16 `1.5 z t_s` for world widths).
    pub fn r0_pixels(&self, zoom: f32) -> f32 {
        match self.line_width {
            LineWidth::Pixels(w) => self.r0_widths * w,
            LineWidth::World(t) => self.r0_widths * zoom * t,
        }
    }
}

/// Eq. 7's sample count on level `j`: `ceil(s_h / (j + 1))` (a harmonic series; 32, 16, 11 for
/// `s_h = 32`: the paper's 59 samples, where floor would give 58).
pub fn samples_on_level(s_h: u32, j: u32) -> u32 {
    s_h.div_ceil(j + 1)
}

/// Eq. 7's disc radius of level `j` in pixels: `r0 + j step z(P)`, with `r0` in pixels
/// ([`LineAoSettings::r0_pixels`]), `step` in world units and `zoom = z(P)` in pixels per world
/// unit. The step is projected so that the outer discs cover the same world neighbourhood
/// whatever the zoom (§3.1: "a coherent AO effect when zooming"); `r0` follows the line's
/// width on screen.
pub fn level_radius(r0_px: f32, step_world: f32, zoom: f32, j: u32) -> f32 {
    r0_px + j as f32 * step_world * zoom
}

/// `z(P)` (§3.2): pixels per world unit at view depth `view_depth` (world units along the
/// viewing direction, as umbra's G-buffer stores it) for an image `height` pixels high - the
/// on-axis screen radius of a unit sphere, `0.5 P11 H / z` under perspective and `H / height`
/// orthographic (`Camera::texture_radius` times the height). 0 for a depth that is not in
/// front of a perspective camera.
pub fn zoom_px(camera: &Camera, view_depth: f64, height: u32) -> f32 {
    if matches!(camera.projection, Projection::Perspective { .. })
        && !(view_depth > 0.0 && view_depth.is_finite())
    {
        return 0.0;
    }
    let (_, ty) = camera.texture_radius(1.0, -view_depth, 1.0);
    (ty * height as f64) as f32
}

/// The normalised depth of a linear view depth `z` (world units; 0 or not finite: no surface)
/// for a camera clipping at `near`, `far`: `(z - near) / (far - near)` in [0, 1] for the
/// scene (see the module doc for why this scale). A surface never maps to 0, which marks
/// background: it is kept at least `f32::MIN_POSITIVE`.
pub fn normalised_depth(z: f32, near: f32, far: f32) -> f32 {
    if !(z.is_finite() && z > 0.0) {
        return 0.0;
    }
    ((z - near) / (far - near)).max(f32::MIN_POSITIVE)
}

/// Eq. 11, the depth falloff of level `l` of `s_r`: `(1 - l / s_r)^2` (1, 4/9, 1/9 for three
/// levels; never 0 for `l < s_r`, fine for `s_r = 1`).
pub fn delta(l: u32, s_r: u32) -> f32 {
    let t = 1.0 - l as f32 / s_r.max(1) as f32;
    t * t
}

/// Eq. 13, `h(x) = 3x^2 - 2x^3` on `x` clamped to [0, 1] (WGSL `smoothstep(0, 1, x)`).
pub fn smoothstep_h(x: f32) -> f32 {
    let x = x.clamp(0.0, 1.0);
    x * x * (3.0 - 2.0 * x)
}

/// Eq. 12 (third case with `Δd`, not `d`): the depth weight of a sample `dd = d(P) - d(q)`
/// nearer than P by `dd` on a level of falloff `delta_l`: 1 below `delta0`, 0 beyond `delta_l`,
/// `1 - h((dd - delta0) / (delta_l - delta0))` between - near occluders count fully, far ones
/// fade so a distant bundle does not darken a near one's local structure (Fig. 3). Needs
/// `delta0 < delta_l` (`LineAoSettings::check`).
pub fn g_depth(dd: f32, delta0: f32, delta_l: f32) -> f32 {
    if dd > delta_l {
        0.0
    } else if dd < delta0 {
        1.0
    } else {
        1.0 - smoothstep_h((dd - delta0) / (delta_l - delta0))
    }
}

/// Eq. 8 with the strict threshold: a sample whose surface is nearer than P's by more than
/// `delta0` occludes P; background never does. Eq. 8 itself (`Δd >= 0`, with eq. 12's
/// `g_depth = 1` below `delta0`) would make a flat line occlude itself fully.
pub fn occludes(sample_is_surface: bool, dd: f32, delta0: f32) -> bool {
    sample_is_surface && dd > delta0
}

/// One light's term of eq. 14: the Phong BRDF (no ambient) of a light of intensity
/// `intensity` from unit direction `light` (towards the light), at unit normal `n`, towards
/// unit direction `v` (the sample direction ω): `I (k_d max(n.L, 0) + k_s max(R.v, 0)^p)`,
/// `R = 2 (n.L) n - L`; the specular term only where the light reaches the front (`n.L > 0`).
pub fn phong_brdf(
    light: Vec3,
    intensity: f32,
    n: Vec3,
    v: Vec3,
    diffuse: f32,
    specular: f32,
    shininess: f32,
) -> f32 {
    let nl = n.dot(light);
    if nl <= 0.0 {
        return 0.0;
    }
    let r = 2.0 * nl * n - light;
    intensity * (diffuse * nl + specular * r.dot(v).max(0.0).powf(shininess))
}

/// How far P's tangent plane (unit view-space normal `n`, facing the viewer) rises towards the
/// eye at the screen offset `offset_px` (view axes: x right, y up; pixels), in normalised depth:
/// `-(n.x o.x + n.y o.y) / (zoom max(a, 0.1) depth_range)` with `o` in world units `offset /
/// zoom` and `a = n.z - n.x r.x - n.y r.y`, `r` P's ray at unit depth (the eye looks along -z:
/// the ray is `(r.x, r.y, -1)`; `r = 0` on the axis and for an orthographic camera).
///
/// Derivation: the plane through P = d r_P (d its depth along the axis) holds the points `t
/// r_o` with `t = d a_P / a_o`, `a_o = -n . r_o`; on the screen, `r_o = r_P + o / f` (f the
/// focal length in pixels, `zoom = f / d`), so `a_o = a_P - (n.x o.x + n.y o.y) / f` and, to
/// first order in `o`, the plane's depth is `d - (n.x o.x + n.y o.y) / (zoom a_P)`. The
/// exact depth lies beyond that line (`t` is convex in `o`), so a plane never occludes itself.
/// Dividing by `n.z` instead of `a_P`, as before, is right only on the axis: a slice seen in
/// perspective far off the axis darkened by itself. The nearest a sample's surface may be
/// without occluding is the plane's depth there, `d(P) - rise`. `a` is kept at least 0.1 so a
/// silhouette's plane, nearly along the ray, stays finite; `zoom` not positive gives 0.
pub fn plane_rise(n: Vec3, offset_px: Vec2, zoom: f32, depth_range: f32, ray: Vec2) -> f32 {
    if !(zoom > 0.0 && zoom.is_finite()) {
        return 0.0;
    }
    let a = n.z - n.x * ray.x - n.y * ray.y;
    -(n.x * offset_px.x + n.y * offset_px.y) / (zoom * a.max(0.1) * depth_range)
}

/// P's ray at unit depth for pixel centre `centre` of a `w x h` normal-depth map: `((x - w/2) /
/// f, (h/2 - y) / f)` (view y up) with `f` = `ray_focal`; zero for an orthographic camera
/// (`ray_focal` 0).
pub fn pixel_ray(centre: Vec2, w: f32, h: f32, ray_focal: f32) -> Vec2 {
    if ray_focal > 0.0 && ray_focal.is_finite() {
        Vec2::new(
            (centre.x - 0.5 * w) / ray_focal,
            (0.5 * h - centre.y) / ray_focal,
        )
    } else {
        Vec2::ZERO
    }
}

/// A line's screen tangent as the pyramid stores it: `(cos 2θ, sin 2θ, |t.x|, 1)` for the unit
/// tangent `t = (cos θ, sin θ)` in pixels (view axes; the sign of t does not matter).
pub fn tangent_texel(t: Vec2) -> [f32; 4] {
    let t = t.normalize_or_zero();
    [t.x * t.x - t.y * t.y, 2.0 * t.x * t.y, t.x.abs(), 1.0]
}

/// The difference in screen direction of two tangent texels ([`tangent_texel`], or their
/// pyramid means) that eq. 11's smoothstep takes: [`Alignment::Invariant`]: `|sin Δθ| =
/// sqrt((1 - u_P . u_q) / 2)` of the doubled-angle vectors `u`; [`Alignment::Paper`]:
/// `|α(P) - α(q)|` (eq. 10-11).
pub fn alignment_difference(a: Alignment, p: [f32; 4], q: [f32; 4]) -> f32 {
    match a {
        Alignment::Invariant => ((1.0 - (p[0] * q[0] + p[1] * q[1])) * 0.5).max(0.0).sqrt(),
        Alignment::Paper => (p[2] - q[2]).abs(),
    }
}

/// Eq. 11: `g_align = max(A0, min(1, I h(x)))` for a direction difference `x`
/// ([`alignment_difference`]): `A0` for nearly parallel lines (below `x ≈ 0.048` at `I = 15`,
/// `A0 = 0.1`), 1 beyond `x ≈ 0.158`.
pub fn g_align(x: f32, intensity: f32, floor: f32) -> f32 {
    floor.max((intensity * smoothstep_h(x)).min(1.0))
}

/// Eq. 15: the light weight from the light `reflected` at P towards the sample (eq. 14, the
/// sum of [`phong_brdf`] over the lights): `1 - min(reflected, 1)`, so directly lit parts are
/// darkened less. In [0, 1] for non-negative light.
pub fn g_light(reflected: f32) -> f32 {
    1.0 - reflected.clamp(0.0, 1.0)
}

/// The 32-bit PCG hash (Jarzynski and Olano, "Hash Functions for GPU Rendering", JCGT 2020):
/// a bijection of `u32`, only wrapping `u32` arithmetic, so WGSL gives the same bits.
pub fn pcg_hash(v: u32) -> u32 {
    let state = v.wrapping_mul(747_796_405).wrapping_add(2_891_336_453);
    let word = ((state >> ((state >> 28) + 4)) ^ state).wrapping_mul(277_803_737);
    (word >> 22) ^ word
}

/// The per-pixel rotation of the sample set, in [0, 2 pi]: `2 pi` times the top 24 bits of
/// `pcg(x + pcg(y + pcg(seed)))` over `2^24` (exact in f32). A fixed function of the pixel and
/// the seed - no tiled noise texture, so no visible tiling, and a frame of an orbit equals a
/// single render at the same camera. As each stage is a bijection, horizontal and vertical
/// neighbours always get different hashes.
pub fn rotation_angle(x: u32, y: u32, seed: u32) -> f32 {
    let h = pcg_hash(x.wrapping_add(pcg_hash(y.wrapping_add(pcg_hash(seed)))));
    TAU * ((h >> 8) as f32 * (1.0 / 16_777_216.0))
}

/// The angle by which level `j`'s spiral is turned: `2 pi frac(j phi)` (phi the golden ratio
/// conjugate), so the levels' directions differ and spread evenly (the aim of the paper's
/// level coordinate of `R2`).
pub fn level_angle(j: u32) -> f32 {
    let f = (j as f64 * 0.618_033_988_749_894_9).fract();
    (std::f64::consts::TAU * f) as f32
}

/// Sample `i` of `n` on level `j`, rotated by `rotation`: a point of the unit disc on the
/// golden-angle (Vogel) spiral, radius `sqrt((i + 1/2) / n)` (uniform in area), angle
/// `i GOLDEN_ANGLE + level_angle(j) + rotation`. Deterministic; evenly spread for any `n`.
pub fn sample_offset(i: u32, n: u32, j: u32, rotation: f32) -> Vec2 {
    let r = ((i as f32 + 0.5) / n.max(1) as f32).sqrt();
    let a = i as f32 * GOLDEN_ANGLE + level_angle(j) + rotation;
    Vec2::new(r * a.cos(), r * a.sin())
}

/// The offsets of one level ([`sample_offset`] for `i < ceil(s_h / (j + 1))`).
pub fn level_offsets(s_h: u32, j: u32, rotation: f32) -> Vec<Vec2> {
    let n = samples_on_level(s_h, j);
    (0..n).map(|i| sample_offset(i, n, j, rotation)).collect()
}

/// A disc offset `o` lifted to the unit hemisphere facing the viewer,
/// `(o, sqrt(1 - |o|^2))` (view space: x right, y up, z towards the eye; uniform offsets lift
/// to cosine-weighted directions), then flipped into the hemisphere of the unit normal `n` when
/// it points behind it (normal-oriented sampling: fewer samples where a tilted surface rises
/// towards the eye and would occlude itself).
pub fn hemisphere_direction(o: Vec2, n: Vec3) -> Vec3 {
    let z = (1.0 - o.length_squared()).max(0.0).sqrt();
    let w = Vec3::new(o.x, o.y, z);
    if w.dot(n) < 0.0 {
        -w
    } else {
        w
    }
}

/// A normal-depth image, one level of the pyramid: `depth` normalised ([`normalised_depth`];
/// 0 or not finite: background), `normal` unit, in view space (x right, y up, z towards the
/// eye) and facing the viewer; row-major, y down, `width * height` each.
#[derive(Clone, Debug, PartialEq)]
pub struct NormalDepth {
    pub width: u32,
    pub height: u32,
    pub depth: Vec<f32>,
    pub normal: Vec<[f32; 3]>,
    /// The mean depth of the surfaces alone (background left out; 0 where none): what P's own
    /// depth is on a coarse level (level 0: the depth).
    pub cover: Vec<f32>,
    /// Lines' screen tangents ([`tangent_texel`]; the mean over the lines of a coarse texel,
    /// w = 1 where any), zero where no line is (tubes, background).
    pub tangent: Vec<[f32; 4]>,
}

impl NormalDepth {
    /// All background.
    pub fn empty(width: u32, height: u32) -> NormalDepth {
        let n = width as usize * height as usize;
        NormalDepth {
            width,
            height,
            depth: vec![0.0; n],
            normal: vec![[0.0; 3]; n],
            cover: vec![0.0; n],
            tangent: vec![[0.0; 4]; n],
        }
    }

    /// Gives the surface at (x, y) a line's screen tangent `t` (pixels, view axes).
    pub fn set_tangent(&mut self, x: u32, y: u32, t: Vec2) {
        let i = self.index(x, y);
        self.tangent[i] = tangent_texel(t);
    }

    fn index(&self, x: u32, y: u32) -> usize {
        x as usize + self.width as usize * y as usize
    }

    /// Whether a surface covers texel (x, y).
    pub fn is_surface(&self, x: u32, y: u32) -> bool {
        let d = self.depth[self.index(x, y)];
        d.is_finite() && d > 0.0
    }

    /// The depth with background as far (1): what averages and comparisons see.
    pub fn far_depth(&self, x: u32, y: u32) -> f32 {
        if self.is_surface(x, y) {
            self.depth[self.index(x, y)]
        } else {
            1.0
        }
    }

    /// The unit normal at (x, y); facing the viewer (+z) where it is missing or degenerate.
    pub fn unit_normal(&self, x: u32, y: u32) -> Vec3 {
        let n = Vec3::from(self.normal[self.index(x, y)]);
        if n.is_finite() && n.length_squared() > 1e-12 {
            n.normalize()
        } else {
            Vec3::Z
        }
    }

    /// Sets texel (x, y) to a surface of depth `d` and normal `n`.
    pub fn set(&mut self, x: u32, y: u32, d: f32, n: [f32; 3]) {
        let i = self.index(x, y);
        self.depth[i] = d;
        self.normal[i] = n;
        self.cover[i] = d;
    }

    /// The surfaces' own depth at (x, y) ([`NormalDepth::cover`]), or the far depth where it
    /// has none.
    pub fn surface_depth(&self, x: u32, y: u32) -> f32 {
        let c = self.cover[self.index(x, y)];
        if c.is_finite() && c > 0.0 {
            c
        } else {
            self.far_depth(x, y)
        }
    }

    /// The next coarser level: `ceil(w / 2) x ceil(h / 2)`, each texel the 2 x 2 block below
    /// it (texels outside this image left out): depth the mean with background as 1, or
    /// background where the block has no surface; normal the renormalised sum of the covered
    /// texels' normals.
    pub fn half(&self) -> NormalDepth {
        let (w, h) = (self.width.div_ceil(2), self.height.div_ceil(2));
        let mut out = NormalDepth::empty(w, h);
        for y in 0..h {
            for x in 0..w {
                let (mut sum, mut count, mut covered, mut n) = (0.0f32, 0u32, 0u32, Vec3::ZERO);
                let mut cover = 0.0f32;
                let (mut tan, mut lines) = ([0.0f32; 4], 0u32);
                for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                    let (sx, sy) = (2 * x + dx, 2 * y + dy);
                    if sx >= self.width || sy >= self.height {
                        continue;
                    }
                    count += 1;
                    sum += self.far_depth(sx, sy);
                    if self.is_surface(sx, sy) {
                        covered += 1;
                        n += self.unit_normal(sx, sy);
                        cover += self.surface_depth(sx, sy);
                        let t = self.tangent[self.index(sx, sy)];
                        if t[3] > 0.0 {
                            lines += 1;
                            for k in 0..3 {
                                tan[k] += t[k];
                            }
                        }
                    }
                }
                if covered > 0 {
                    out.set(x, y, sum / count as f32, n.normalize_or_zero().into());
                    let i = out.index(x, y);
                    out.cover[i] = cover / covered as f32;
                    if lines > 0 {
                        let k = 1.0 / lines as f32;
                        out.tangent[i] = [tan[0] * k, tan[1] * k, tan[2] * k, 1.0];
                    }
                }
            }
        }
        out
    }

    /// The pyramid of `levels` levels (at least one), level 0 this image, each next level
    /// [`NormalDepth::half`] of the one before: `d_l`, `n_l` of §3.2 (mipmaps, §3.4).
    pub fn pyramid(&self, levels: u32) -> Vec<NormalDepth> {
        assert_eq!(
            self.depth.len(),
            self.width as usize * self.height as usize,
            "NormalDepth: depth has {} texels for {} x {}",
            self.depth.len(),
            self.width,
            self.height
        );
        assert_eq!(
            self.normal.len(),
            self.depth.len(),
            "NormalDepth: normal and depth differ in length"
        );
        assert_eq!(
            (self.cover.len(), self.tangent.len()),
            (self.depth.len(), self.depth.len()),
            "NormalDepth: cover, tangent and depth differ in length"
        );
        let mut out = vec![self.clone()];
        for _ in 1..levels.max(1) {
            let next = out[out.len() - 1].half();
            out.push(next);
        }
        out
    }
}

/// What the kernel returns for one pixel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LineAoTerms {
    /// LineAO, eq. 7: `clamp(Σ_j AO_j, 0, 1)`; 0 = open (the AOV `occlusion.lineao` is the
    /// visibility `1 - ao`, [`LineAoTerms::visibility`]).
    pub ao: f32,
    /// `AO_j` of each level (eq. 6, the mean over its on-screen samples), before the sum;
    /// 0 beyond `s_r`.
    pub level: [f32; MAX_LEVELS],
    /// The occlusion `1 - V` alone: the fraction of on-screen samples that occlude, averaged
    /// over the levels with samples on screen.
    pub v: f32,
    /// `g_depth` alone, its mean over the on-screen samples, averaged over the levels.
    pub g_depth: f32,
    /// `g_light` alone, likewise.
    pub g_light: f32,
    /// `g_align` alone, likewise (1 unless anisotropic).
    pub g_align: f32,
    /// How many samples of all levels fell on screen.
    pub on_screen: u32,
}

impl LineAoTerms {
    /// A pixel with nothing to occlude it: background pixels, and pixels whose samples all
    /// fall off screen (no occluder, weights 1).
    pub const OPEN: LineAoTerms = LineAoTerms {
        ao: 0.0,
        level: [0.0; MAX_LEVELS],
        v: 0.0,
        g_depth: 1.0,
        g_light: 1.0,
        g_align: 1.0,
        on_screen: 0,
    };

    /// `1 - ao`: 1 = open, as the other `occlusion.*` channels.
    pub fn visibility(&self) -> f32 {
        1.0 - self.ao
    }
}

/// The LineAO kernel (eq. 4-15) at pixel `px` of `levels[0]`, the CPU twin of the GPU pass:
/// `levels` is the pyramid ([`NormalDepth::pyramid`], at least `s.levels` levels), `zoom` is
/// `z(P)` in pixels per world unit ([`zoom_px`]; not finite or negative counts as 0, so the
/// discs collapse to `r0`). For each level j: P's depth and normal on level j, `ceil(s_h /
/// (j + 1))` samples at `P + r_j (ω.x, -ω.y)` (pixel centre `px + 1/2`), off-screen ones left
/// out, each adding `[occludes] g_depth g_light` to the level's mean. `s` should pass
/// [`LineAoSettings::check`].
pub fn line_ao(
    levels: &[NormalDepth],
    px: (u32, u32),
    zoom: f32,
    s: &LineAoSettings,
) -> LineAoTerms {
    let s_r = (s.levels as usize).min(MAX_LEVELS);
    assert!(
        levels.len() >= s_r,
        "line_ao: {s_r} levels wanted, the pyramid has {}",
        levels.len()
    );
    let base = &levels[0];
    assert!(
        px.0 < base.width && px.1 < base.height,
        "line_ao: pixel {px:?} outside {} x {}",
        base.width,
        base.height
    );
    if !base.is_surface(px.0, px.1) {
        return LineAoTerms::OPEN;
    }
    let zoom = if zoom.is_finite() && zoom > 0.0 {
        zoom
    } else {
        0.0
    };
    let r0 = s.r0_pixels(zoom);
    let rotation = rotation_angle(px.0, px.1, s.seed);
    let centre = Vec2::new(px.0 as f32 + 0.5, px.1 as f32 + 0.5);
    let (w, h) = (base.width as f32, base.height as f32);
    let light = Vec3::Z;
    let mut out = LineAoTerms::OPEN;
    let (mut sum, mut v, mut gd, mut gl, mut counted) = (0.0f32, 0.0f32, 0.0f32, 0.0f32, 0u32);
    let mut ga = 0.0f32;
    for (j, lvl) in levels.iter().enumerate().take(s_r) {
        let j = j as u32;
        let (pxj, pyj) = (px.0 >> j, px.1 >> j);
        let d_p = lvl.surface_depth(pxj, pyj);
        let n_p = lvl.unit_normal(pxj, pyj);
        let n = samples_on_level(s.samples, j);
        let r = level_radius(r0, s.radius_step, zoom, j);
        let delta_l = s.delta(j);
        let (mut valid, mut ao, mut lv, mut lgd, mut lgl) = (0u32, 0.0f32, 0.0, 0.0, 0.0);
        let mut lga = 0.0f32;
        let t_p = lvl.tangent[lvl.index(pxj, pyj)];
        for i in 0..n {
            let omega = hemisphere_direction(sample_offset(i, n, j, rotation), n_p);
            let q = centre + r * Vec2::new(omega.x, -omega.y);
            // Written so that a NaN position counts as off screen.
            if !(q.x >= 0.0 && q.y >= 0.0 && q.x < w && q.y < h) {
                continue;
            }
            valid += 1;
            let (qx, qy) = ((q.x as u32) >> j, (q.y as u32) >> j);
            let mut dd = d_p - lvl.far_depth(qx, qy);
            if s.visibility == Visibility::Plane {
                // Between the two texels' centres, where their depths hold (level-0 pixels,
                // view y up).
                let texels = Vec2::new(qx as f32 - pxj as f32, pyj as f32 - qy as f32);
                // The slope along the ray through P's texel's centre (level-0 pixels), where
                // its depth and normal hold.
                let tc = Vec2::new(pxj as f32 + 0.5, pyj as f32 + 0.5) * (1u32 << j) as f32;
                let ray = pixel_ray(tc, w, h, s.ray_focal);
                dd -= plane_rise(n_p, texels * (1u32 << j) as f32, zoom, s.depth_range, ray);
            }
            let occ = if occludes(lvl.is_surface(qx, qy), dd, s.delta0) {
                1.0
            } else {
                0.0
            };
            let g_d = g_depth(dd, s.delta0, delta_l);
            let g_l = g_light(phong_brdf(
                light,
                s.light_intensity,
                n_p,
                omega,
                s.light_diffuse,
                s.light_specular,
                s.light_shininess,
            ));
            // Eq. 11-12, where both P and the sample are lines (tubes have no tangent here).
            let t_q = lvl.tangent[lvl.index(qx, qy)];
            let g_a = if s.anisotropic && t_p[3] > 0.0 && t_q[3] > 0.0 {
                g_align(
                    alignment_difference(s.alignment, t_p, t_q),
                    s.intensity,
                    s.floor,
                )
            } else {
                1.0
            };
            ao += occ * g_d * g_l * g_a;
            lv += occ;
            lgd += g_d;
            lgl += g_l;
            lga += g_a;
        }
        if valid > 0 {
            let k = 1.0 / valid as f32;
            out.level[j as usize] = ao * k;
            sum += ao * k;
            v += lv * k;
            gd += lgd * k;
            gl += lgl * k;
            ga += lga * k;
            counted += 1;
            out.on_screen += valid;
        }
    }
    let total = match s.levels_combine {
        LevelsCombine::Sum => sum,
        LevelsCombine::Mean => sum / s.levels.max(1) as f32,
    };
    out.ao = total.clamp(0.0, 1.0);
    if counted > 0 {
        let k = 1.0 / counted as f32;
        out.v = v * k;
        out.g_depth = gd * k;
        out.g_light = gl * k;
        out.g_align = ga * k;
    }
    out
}

/// [`line_ao`] over every pixel of `base` (row-major), the pyramid built once; `zoom(x, y)`
/// is `z(P)` per pixel (the zoom map, or [`zoom_px`] of the pixel's depth).
pub fn line_ao_image(
    base: &NormalDepth,
    zoom: impl Fn(u32, u32) -> f32 + Sync,
    s: &LineAoSettings,
) -> Vec<LineAoTerms> {
    use rayon::prelude::*;
    let levels = base.pyramid(s.levels);
    (0..base.height)
        .into_par_iter()
        .flat_map_iter(|y| {
            let levels = &levels;
            let zoom = &zoom;
            (0..base.width).map(move |x| line_ao(levels, (x, y), zoom(x, y), s))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    fn h(x: f64) -> f64 {
        3.0 * x * x - 2.0 * x * x * x
    }

    #[test]
    fn sample_counts_are_32_16_11() {
        let n: Vec<u32> = (0..3).map(|j| samples_on_level(32, j)).collect();
        assert_eq!(n, [32, 16, 11]);
        assert_eq!(n.iter().sum::<u32>(), 59, "the paper's 59 samples");
        assert_eq!(samples_on_level(1, 7), 1, "never 0");
        assert_eq!(level_offsets(32, 2, 0.3).len(), 11);
    }

    #[test]
    fn delta_is_1_4_9ths_1_9th_for_three_levels() {
        let d: Vec<f32> = (0..3).map(|l| delta(l, 3)).collect();
        for (got, want) in d.iter().zip([1.0, 4.0 / 9.0, 1.0 / 9.0]) {
            assert!((got - want).abs() < 1e-6, "{d:?}");
        }
        assert_eq!(delta(0, 1), 1.0, "s_r = 1 is fine as printed");
        assert!((delta(7, 8) - 1.0 / 64.0).abs() < 1e-7);
        let constant = LineAoSettings {
            falloff: Falloff::Constant,
            ..Default::default()
        };
        assert_eq!(
            (0..3).map(|l| constant.delta(l)).collect::<Vec<_>>(),
            [1.0; 3]
        );
        assert_eq!(LineAoSettings::default().delta(2), delta(2, 3));
    }

    #[test]
    fn g_depth_follows_eq_12() {
        let (d0, dl) = (1e-4f32, 4.0 / 9.0);
        assert_eq!(g_depth(-0.3, d0, dl), 1.0);
        assert_eq!(g_depth(0.5 * d0, d0, dl), 1.0);
        assert_eq!(g_depth(d0, d0, dl), 1.0, "continuous at delta_0");
        assert_eq!(g_depth(0.45, d0, dl), 0.0);
        assert!(g_depth(dl, d0, dl).abs() < 1e-6, "continuous at delta(l)");
        let x = 0.25f64;
        let dd = d0 as f64 + x * (dl as f64 - d0 as f64);
        assert!((g_depth(dd as f32, d0, dl) as f64 - (1.0 - h(x))).abs() < 1e-6);
        // Monotone non-increasing in the depth gap.
        let g: Vec<f32> = (0..=100)
            .map(|k| g_depth(k as f32 / 200.0, d0, dl))
            .collect();
        assert!(g.windows(2).all(|p| p[1] <= p[0]));
        assert_eq!(smoothstep_h(0.5), 0.5);
        assert_eq!(smoothstep_h(-1.0), 0.0);
        assert_eq!(smoothstep_h(2.0), 1.0);
    }

    #[test]
    fn g_light_follows_eq_15_and_a_head_light_of_one_zeroes_it() {
        let (z, n) = (Vec3::Z, Vec3::Z);
        // Diffuse only: I k_d (n.L); the sample direction does not matter.
        let b = phong_brdf(z, 0.5, n, Vec3::new(0.6, 0.0, 0.8), 0.7, 0.0, 32.0);
        assert!((b - 0.35).abs() < 1e-6);
        assert!((g_light(b) - 0.65).abs() < 1e-6);
        // Specular towards the reflection of the head light (= the light itself).
        let b = phong_brdf(z, 0.5, n, z, 0.7, 0.3, 32.0);
        assert!((b - 0.5).abs() < 1e-6);
        // umbra's ambient + diffuse = 1 as the intensity would leave no occlusion (G10).
        assert_eq!(g_light(phong_brdf(z, 1.0, n, z, 1.0, 0.0, 32.0)), 0.0);
        // Two lights add (eq. 14 is not normalised), clamped by eq. 15.
        assert_eq!(g_light(0.7 + 0.7), 0.0);
        assert_eq!(g_light(0.0), 1.0);
        // A normal facing away from the light reflects nothing.
        assert_eq!(phong_brdf(z, 0.5, -n, z, 0.7, 0.3, 32.0), 0.0);
    }

    #[test]
    fn radii_follow_eq_7_and_eq_16() {
        let s = LineAoSettings {
            line_width: LineWidth::Pixels(2.0),
            ..Default::default()
        };
        assert_eq!(
            s.r0_pixels(10.0),
            3.0,
            "1.5 x the width in pixels, zoom aside"
        );
        let r: Vec<f32> = (0..3)
            .map(|j| level_radius(s.r0_pixels(10.0), s.radius_step, 10.0, j))
            .collect();
        assert_eq!(r, [3.0, 13.0, 23.0], "r0 + j z(P), one world unit a level");
        let tubes = LineAoSettings {
            line_width: LineWidth::World(0.4),
            ..Default::default()
        };
        assert!((tubes.r0_pixels(10.0) - 6.0).abs() < 1e-6, "1.5 z t_s");
        assert!((tubes.r0_pixels(20.0) - 12.0).abs() < 1e-6);
    }

    #[test]
    fn zoom_is_the_projected_length_of_one_world_unit() {
        let bounds = [DVec3::splat(-1.0), DVec3::splat(1.0)];
        for projection in [
            Projection::Orthographic { height: 4.0 },
            Projection::Perspective { fov_y_deg: 50.0 },
        ] {
            let cam = Camera::look_at(
                DVec3::new(0.0, -6.0, 0.0),
                DVec3::ZERO,
                DVec3::Z,
                projection,
                bounds,
            )
            .unwrap();
            let (w, hgt) = (300usize, 200usize);
            // A point at view depth 5.5 near the axis and one world unit above it.
            let p = DVec3::new(0.1, -0.5, 0.05);
            let a = cam.to_pixel(p, w, hgt).unwrap();
            let b = cam.to_pixel(p + DVec3::Z, w, hgt).unwrap();
            let measured = (a.1 - b.1).abs();
            let z = zoom_px(&cam, 5.5, hgt as u32) as f64;
            assert!(
                (z - measured).abs() < 1e-3 * measured,
                "{projection:?}: {z} vs {measured}"
            );
            if let Projection::Orthographic { .. } = projection {
                assert!((z - 50.0).abs() < 1e-4, "H / height = 200 / 4");
            }
        }
        let cam = Camera::look_at(
            DVec3::new(0.0, -6.0, 0.0),
            DVec3::ZERO,
            DVec3::Z,
            Projection::Perspective { fov_y_deg: 50.0 },
            [DVec3::splat(-1.0), DVec3::splat(1.0)],
        )
        .unwrap();
        assert_eq!(zoom_px(&cam, 0.0, 200), 0.0, "no surface, no zoom");
        assert_eq!(zoom_px(&cam, f64::NAN, 200), 0.0);
    }

    #[test]
    fn normalised_depth_is_linear_over_near_far_and_keeps_zero_for_background() {
        assert_eq!(normalised_depth(3.0, 2.0, 6.0), 0.25);
        assert_eq!(normalised_depth(6.0, 2.0, 6.0), 1.0);
        // A depth difference is the world gap over far - near, wherever it lies.
        let gap = normalised_depth(5.0, 2.0, 6.0) - normalised_depth(4.0, 2.0, 6.0);
        assert!((gap - 0.25).abs() < 1e-6);
        assert_eq!(normalised_depth(0.0, 2.0, 6.0), 0.0, "no surface");
        assert_eq!(normalised_depth(f32::NAN, 2.0, 6.0), 0.0);
        assert!(
            normalised_depth(2.0, 2.0, 6.0) > 0.0,
            "a surface on the near plane"
        );
    }

    #[test]
    fn the_rotation_is_a_fixed_function_of_pixel_and_seed() {
        assert_eq!(rotation_angle(17, 5, 3), rotation_angle(17, 5, 3));
        assert_ne!(
            rotation_angle(17, 5, 3),
            rotation_angle(17, 5, 4),
            "the seed"
        );
        let (mut c, mut s) = (0.0f64, 0.0f64);
        for y in 0..64 {
            for x in 0..64 {
                let a = rotation_angle(x, y, 0);
                assert!((0.0..TAU).contains(&a));
                assert_ne!(a, rotation_angle(x + 1, y, 0), "({x}, {y}) and its right");
                assert_ne!(a, rotation_angle(x, y + 1, 0), "({x}, {y}) and below");
                c += (a as f64).cos();
                s += (a as f64).sin();
            }
        }
        // Spread over the circle: 4096 uniform angles leave a mean vector of about 1/64.
        assert!(c.hypot(s) / 4096.0 < 0.05, "{c} {s}");
        // Known bits, so the WGSL port can be checked against them.
        assert_eq!(pcg_hash(0), 129_708_002);
    }

    #[test]
    fn sample_offsets_fill_the_disc_and_differ_between_levels() {
        for j in 0..3 {
            let o = level_offsets(32, j, 0.0);
            assert!(o.iter().all(|p| p.length() < 1.0));
            // Uniform in area: the mean squared radius of (i + 1/2) / n is 1/2.
            let m: f32 = o.iter().map(|p| p.length_squared()).sum::<f32>() / o.len() as f32;
            assert!((m - 0.5).abs() < 1e-5, "{m}");
            // Spread: the centroid is near the centre.
            let c = o.iter().fold(Vec2::ZERO, |a, p| a + *p) / o.len() as f32;
            assert!(c.length() < 0.1, "level {j}: {c}");
        }
        assert_ne!(sample_offset(0, 16, 0, 0.0), sample_offset(0, 16, 1, 0.0));
        // The rotation turns the set rigidly.
        let (a, b) = (sample_offset(5, 32, 1, 0.0), sample_offset(5, 32, 1, 1.0));
        assert!((a.length() - b.length()).abs() < 1e-6);
        assert!((a.angle_to(b) - 1.0).abs() < 1e-5);
    }

    #[test]
    fn hemisphere_directions_are_unit_and_face_the_normal() {
        let n = Vec3::new(0.8, 0.0, 0.6);
        for o in level_offsets(32, 0, 0.7) {
            let w = hemisphere_direction(o, n);
            assert!((w.length() - 1.0).abs() < 1e-5);
            assert!(w.dot(n) >= 0.0);
            assert!(
                (w.truncate().length() - o.length()).abs() < 1e-6,
                "xy keeps the radius"
            );
        }
        // A view-facing normal keeps every offset as it is.
        let o = Vec2::new(-0.3, 0.4);
        assert_eq!(hemisphere_direction(o, Vec3::Z).truncate(), o);
    }

    #[test]
    fn the_pyramid_halves_with_ceil_and_averages_background_as_far() {
        let mut nd = NormalDepth::empty(5, 3);
        // Block (0, 0): three surfaces and one background texel.
        nd.set(0, 0, 0.2, [0.0, 0.0, 1.0]);
        nd.set(1, 0, 0.4, [1.0, 0.0, 0.0]);
        nd.set(0, 1, 0.6, [0.0, 0.0, 1.0]);
        // The odd column: texel (4, 0) alone with (4, 1) in its block.
        nd.set(4, 1, 0.5, [0.0, 1.0, 0.0]);
        let p = nd.pyramid(3);
        assert_eq!(p.len(), 3);
        let sizes: Vec<(u32, u32)> = p.iter().map(|l| (l.width, l.height)).collect();
        assert_eq!(sizes, [(5, 3), (3, 2), (2, 1),]);
        assert_eq!(p[0], nd);
        let l1 = &p[1];
        assert!(
            (l1.depth[0] - (0.2 + 0.4 + 0.6 + 1.0) / 4.0).abs() < 1e-6,
            "background as 1"
        );
        let n = Vec3::from(l1.normal[0]);
        assert!((n - Vec3::new(1.0, 0.0, 2.0).normalize()).length() < 1e-6);
        assert!(
            !l1.is_surface(1, 0),
            "a block of background stays background"
        );
        // (4, 0) and (4, 1) only: the column beyond the image is left out.
        assert!((l1.depth[2] - (1.0 + 0.5) / 2.0).abs() < 1e-6);
        // Row 2 of level 0 alone under row 1 of level 1: background.
        assert!(!l1.is_surface(0, 1));
        // Level 2 from level 1: (0, 0) over level-1 texels (0,0), (1,0), (0,1), (1,1).
        let want = (0.55 + 1.0 + 1.0 + 1.0) / 4.0;
        assert!((p[2].depth[0] - want).abs() < 1e-6);
        assert_eq!(
            NormalDepth::empty(4, 4).pyramid(0).len(),
            1,
            "at least level 0"
        );
        assert!(NormalDepth::empty(4, 4).pyramid(3)[2]
            .depth
            .iter()
            .all(|&d| d == 0.0));
    }

    /// A 128 x 128 wall at depth `wall` with the aligned 4 x 4 block [64, 68)^2 set back by
    /// `gap` (so P = (65, 65) has the same depth on levels 0, 1 and 2), normals view-facing.
    fn pit(wall: f32, gap: f32) -> NormalDepth {
        let mut nd = NormalDepth::empty(128, 128);
        for y in 0..128 {
            for x in 0..128 {
                let back = (64..68).contains(&x) && (64..68).contains(&y);
                nd.set(x, y, if back { wall + gap } else { wall }, [0.0, 0.0, 1.0]);
            }
        }
        nd
    }

    /// Settings whose discs all leave the 4 x 4 pit and stay on a 128^2 image: r0 = 32 px
    /// (the smallest offset, 32 sqrt(1/64) = 4 px, clears the pit's far corner at 2.5 sqrt 2),
    /// then 40 and 48 px at zoom 8.
    fn wide(light_intensity: f32, light_specular: f32) -> LineAoSettings {
        LineAoSettings {
            r0_widths: 1.0,
            line_width: LineWidth::Pixels(32.0),
            light_intensity,
            light_specular,
            ..Default::default()
        }
    }

    #[test]
    fn a_pixel_behind_a_uniform_wall_gets_1_minus_h_per_level() {
        for gap in [0.05f32, 0.1, 0.3, 0.5] {
            let levels = pit(0.3, gap).pyramid(3);
            // No light: g = g_depth alone.
            let t = line_ao(&levels, (65, 65), 8.0, &wide(0.0, 0.0));
            assert_eq!(t.on_screen, 59);
            let mut sum = 0.0;
            for j in 0..3u32 {
                let dl = delta(j, 3) as f64;
                let (d0, dd) = (1e-4f64, gap as f64);
                let want = if dd > dl {
                    0.0
                } else {
                    1.0 - h((dd - d0) / (dl - d0))
                };
                let got = t.level[j as usize] as f64;
                assert!(
                    (got - want).abs() < 1e-4,
                    "gap {gap}, level {j}: {got} vs {want}"
                );
                sum += want;
            }
            assert!(
                (t.ao as f64 - sum.min(1.0)).abs() < 1e-4,
                "gap {gap}: {}",
                t.ao
            );
            assert_eq!(t.v, 1.0, "every sample occludes");
            // Diffuse light only: every weight scales by 1 - I k_d = 0.65.
            let lit = line_ao(&levels, (65, 65), 8.0, &wide(0.5, 0.0));
            for j in 0..3 {
                assert!((lit.level[j] - 0.65 * t.level[j]).abs() < 1e-5);
            }
            assert!((lit.g_light - 0.65).abs() < 1e-6);
        }
        // Gap 0.5: beyond delta(1) and delta(2), so only level 0 counts, at 1 - h(~1/2).
        let t = line_ao(&pit(0.3, 0.5).pyramid(3), (65, 65), 8.0, &wide(0.0, 0.0));
        assert_eq!(&t.level[1..3], &[0.0, 0.0]);
        assert!((t.ao - 0.5).abs() < 1e-3, "{}", t.ao);
        // The wall itself, in front of the pit, is never occluded by it.
        let t = line_ao(&pit(0.3, 0.2).pyramid(3), (20, 20), 8.0, &wide(0.5, 0.3));
        assert_eq!(t.ao, 0.0);
    }

    #[test]
    fn an_isolated_line_on_an_empty_background_is_not_occluded() {
        // One row of depth at y = 64 (a view-facing horizontal line), background elsewhere.
        let mut nd = NormalDepth::empty(128, 128);
        for x in 0..128 {
            nd.set(x, 64, 0.4, [0.0, 0.0, 1.0]);
        }
        let s = LineAoSettings::default();
        let img = line_ao_image(&nd, |_, _| 8.0, &s);
        for (i, t) in img.iter().enumerate() {
            assert_eq!(t.ao, 0.0, "pixel {i}");
            assert!(t.g_depth.is_finite() && t.g_light.is_finite());
        }
        let on_line = img[64 + 128 * 64];
        assert!(on_line.on_screen > 0);
        assert_eq!(on_line.v, 0.0);
        // The same with wide discs and a tilted normal (the flip sends samples sideways).
        let mut tilted = nd.clone();
        for x in 0..128 {
            tilted.set(x, 64, 0.4, [0.0, 0.6, 0.8]);
        }
        let height = LineAoSettings {
            visibility: Visibility::Height,
            ..wide(0.5, 0.3)
        };
        let t = line_ao(&tilted.pyramid(3), (64, 64), 8.0, &height);
        assert_eq!(t.ao, 0.0);
        // A background pixel is not evaluated.
        assert_eq!(img[0], LineAoTerms::OPEN);
    }

    #[test]
    fn a_line_running_into_the_depth_occludes_itself_only_as_a_height_field() {
        // A horizontal line whose depth grows by 0.002 a pixel (in normalised depth, for a
        // depth range of 100 world units and 8 px a world unit: a slope of 1.6 in depth per
        // unit across), with the normal perpendicular to it: (T x C) x T.
        let (zoom, range) = (8.0f32, 100.0f32);
        let slope_world = 0.002 * range * zoom; // depth per world unit along x
        let t = Vec3::new(1.0, 0.0, -slope_world).normalize();
        let n = (t.cross(Vec3::Z)).cross(t).normalize();
        let mut nd = NormalDepth::empty(128, 128);
        for x in 0..128 {
            for y in 63..66 {
                nd.set(x, y, 0.3 + 0.002 * x as f32, n.into());
            }
        }
        let levels = nd.pyramid(3);
        let plane = LineAoSettings {
            depth_range: range,
            ..Default::default()
        };
        let height = LineAoSettings {
            visibility: Visibility::Height,
            ..plane
        };
        let open = line_ao(&levels, (64, 64), zoom, &plane);
        let dark = line_ao(&levels, (64, 64), zoom, &height);
        assert!(open.ao < 0.02, "plane {}", open.ao);
        assert!(dark.ao > 0.1, "height field {}", dark.ao);
        // The rise itself: half a unit of depth over a unit offset along a 45-degree normal.
        let r = plane_rise(
            Vec3::new(-1.0, 0.0, 1.0).normalize(),
            Vec2::new(8.0, 0.0),
            8.0,
            2.0,
            Vec2::ZERO,
        );
        assert!((r - 0.5).abs() < 1e-6, "{r}");
        assert_eq!(
            plane_rise(Vec3::Z, Vec2::new(3.0, 4.0), 0.0, 1.0, Vec2::ZERO),
            0.0
        );
    }

    /// An oblique plane seen in perspective (f = 100 px, a 128 x 128 map: 65 degrees across)
    /// fills the map: its pixels' tangent planes, extrapolated along the rays through their
    /// texels' centres, are never behind the plane's samples, so it is open (the exact depth of
    /// a plane in perspective lies beyond the first-order extrapolation). With the axis' slope
    /// for every pixel (`ray_focal` 0, the formula before) most of it darkens. At a grazing
    /// tilt a few pixels keep some AO: a coarse level's texel takes P's zoom, not its own.
    #[test]
    fn an_oblique_plane_in_perspective_does_not_occlude_itself() {
        let (w, f, near, far) = (128u32, 100.0f32, 1.0f32, 101.0f32);
        let run = |n: Vec3, ray_focal: f32| {
            let n = n.normalize();
            let mut nd = NormalDepth::empty(w, w);
            let mut zoom = vec![0.0f32; (w * w) as usize];
            for y in 0..w {
                for x in 0..w {
                    let c = Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
                    let r = pixel_ray(c, w as f32, w as f32, f);
                    // The plane through (0, 0, -10): depth t = 10 n.z / (n.z - n.x r.x - n.y r.y).
                    let t = 10.0 * n.z / (n.z - n.x * r.x - n.y * r.y);
                    assert!(t > 0.0 && t < far);
                    nd.set(x, y, normalised_depth(t, near, far), n.into());
                    zoom[(x + w * y) as usize] = f / t;
                }
            }
            let s = LineAoSettings {
                depth_range: far - near,
                ray_focal,
                ..Default::default()
            };
            let img = line_ao_image(&nd, |x, y| zoom[(x + w * y) as usize], &s);
            let worst = img.iter().map(|t| t.ao).fold(0.0f32, f32::max);
            let mean = img.iter().map(|t| t.ao).sum::<f32>() / img.len() as f32;
            let dark = img.iter().filter(|t| t.ao > 0.01).count();
            (worst, mean, dark)
        };
        let oblique = Vec3::new(0.5, 0.25, 0.83);
        let (worst, mean_new, _) = run(oblique, f);
        assert!(worst < 1e-3, "the plane occludes itself: AO up to {worst}");
        let (_, mean, dark) = run(oblique, 0.0);
        // What docs/gallery.md quotes (`-- --nocapture`).
        eprintln!(
            "oblique plane: mean AO {mean:.3} with the axis' slope, {mean_new:.5} along the rays"
        );
        assert!(
            mean > 0.3 && dark > 10_000,
            "the axis' slope: mean {mean}, {dark} dark"
        );
        // Grazing (n . ray down to 0.2 in a corner): at most 0.1% of the pixels above 0.01.
        let grazing = Vec3::new(0.6, 0.3, 0.74);
        let (_, mean, dark) = run(grazing, f);
        assert!(
            mean < 1e-3 && dark <= 16,
            "grazing: mean {mean}, {dark} dark"
        );
        let (_, mean_old, _) = run(grazing, 0.0);
        assert!(mean_old > 0.5, "{mean_old}");
    }

    #[test]
    fn g_align_follows_eq_11_and_the_invariant_difference_ignores_the_roll() {
        // I = 15, A0 = 0.1: the floor below x = 0.0479, 1 above x = 0.1576 (notes §2.3).
        assert_eq!(g_align(0.0, 15.0, 0.1), 0.1);
        assert_eq!(g_align(0.047, 15.0, 0.1), 0.1);
        assert!(g_align(0.05, 15.0, 0.1) > 0.1);
        assert!(g_align(0.157, 15.0, 0.1) < 1.0);
        assert_eq!(g_align(0.16, 15.0, 0.1), 1.0);
        let dir = |deg: f32| {
            let a = deg.to_radians();
            tangent_texel(Vec2::new(a.cos(), a.sin()))
        };
        // Invariant: 20 degrees apart is |sin 20| wherever the pair points, and +45 / -45 are
        // perpendicular (1); the paper's |t.x| difference changes with the roll and calls them 0.
        for roll in [0.0f32, 30.0, 45.0, 90.0] {
            let d = alignment_difference(Alignment::Invariant, dir(roll), dir(roll + 20.0));
            assert!((d - 20f32.to_radians().sin()).abs() < 1e-5, "{roll}: {d}");
        }
        let inv = alignment_difference(Alignment::Invariant, dir(45.0), dir(-45.0));
        assert!((inv - 1.0).abs() < 1e-6);
        assert!(alignment_difference(Alignment::Paper, dir(45.0), dir(-45.0)) < 1e-6);
        let flat = alignment_difference(Alignment::Paper, dir(0.0), dir(20.0));
        let steep = alignment_difference(Alignment::Paper, dir(70.0), dir(90.0));
        assert!(
            steep > 4.0 * flat,
            "paper: {flat} horizontal, {steep} vertical"
        );
        // A crossing of +45 and -45 averages to a doubled-angle vector of length 0.
        let mean: Vec<f32> = (0..2)
            .map(|k| 0.5 * (dir(45.0)[k] + dir(-45.0)[k]))
            .collect();
        assert!(mean.iter().all(|v| v.abs() < 1e-6));
    }

    #[test]
    fn a_parallel_bundle_gets_about_the_floor_times_the_classic_ao_and_a_crossing_the_same() {
        // Horizontal lines at depth 0.5 under a second layer 0.01 nearer: parallel (also
        // horizontal) or crossing (vertical), every line one pixel in four.
        let layered = |crossing: bool| {
            let mut nd = NormalDepth::empty(128, 128);
            for y in 0..128 {
                for x in 0..128 {
                    let (near, far) = if crossing {
                        (x % 4 == 0, y % 4 == 2)
                    } else {
                        (y % 4 == 0, y % 4 == 2)
                    };
                    if near {
                        nd.set(x, y, 0.49, [0.0, 0.0, 1.0]);
                        let t = if crossing { Vec2::Y } else { Vec2::X };
                        nd.set_tangent(x, y, t);
                    } else if far {
                        nd.set(x, y, 0.5, [0.0, 0.0, 1.0]);
                        nd.set_tangent(x, y, Vec2::X);
                    }
                }
            }
            nd.pyramid(3)
        };
        let classic = LineAoSettings {
            levels: 1,
            ..Default::default()
        };
        let aniso = LineAoSettings {
            anisotropic: true,
            ..classic
        };
        for crossing in [false, true] {
            let l = layered(crossing);
            let (c, a) = (
                line_ao(&l, (65, 66), 8.0, &classic),
                line_ao(&l, (65, 66), 8.0, &aniso),
            );
            assert!(c.ao > 0.05, "{crossing}: classic {}", c.ao);
            let ratio = a.ao / c.ao;
            if crossing {
                assert!((ratio - 1.0).abs() < 1e-6, "crossing: {ratio}");
            } else {
                assert!((ratio - 0.1).abs() < 1e-6, "parallel: {ratio}");
                // Its mean over all samples: 0.1 on the lines, 1 on the background between.
                assert!(a.g_align > 0.1 && a.g_align < 1.0, "{}", a.g_align);
            }
        }
    }

    #[test]
    fn the_levels_mean_is_their_sum_over_s_r() {
        let levels = pit(0.3, 0.02).pyramid(3);
        let sum = line_ao(&levels, (65, 65), 8.0, &wide(0.0, 0.0));
        let mean = line_ao(
            &levels,
            (65, 65),
            8.0,
            &LineAoSettings {
                levels_combine: LevelsCombine::Mean,
                ..wide(0.0, 0.0)
            },
        );
        let total: f32 = sum.level.iter().sum();
        assert!(total > 0.0);
        assert!((mean.ao - total / 3.0).abs() < 1e-6, "{} {total}", mean.ao);
    }

    #[test]
    fn all_samples_off_screen_and_one_level_give_finite_values() {
        // A 1 x 1 image: every sample of a 15-pixel disc falls outside.
        let mut nd = NormalDepth::empty(1, 1);
        nd.set(0, 0, 0.5, [0.0, 0.0, 1.0]);
        let s = LineAoSettings {
            line_width: LineWidth::Pixels(10.0),
            ..Default::default()
        };
        let t = line_ao(&nd.pyramid(3), (0, 0), 8.0, &s);
        assert_eq!(t.on_screen, 0);
        assert_eq!(t, LineAoTerms::OPEN);
        // s_r = 1: one level, delta = 1, no division by s_r - 1.
        let one = LineAoSettings {
            levels: 1,
            ..wide(0.5, 0.3)
        };
        one.check().unwrap();
        let levels = pit(0.3, 0.1).pyramid(1);
        let t = line_ao(&levels, (65, 65), 8.0, &one);
        assert_eq!(t.on_screen, 32);
        assert!(t.ao.is_finite() && t.ao > 0.0 && t.ao <= 1.0);
        assert!(t.v.is_finite() && t.g_depth.is_finite() && t.g_light.is_finite());
        assert_eq!(&t.level[1..], &[0.0; MAX_LEVELS - 1]);
        // A zoom that is not finite (a point behind the eye) collapses the discs to r0.
        let t = line_ao(
            &pit(0.3, 0.1).pyramid(3),
            (65, 65),
            f32::NAN,
            &wide(0.0, 0.0),
        );
        assert!(t.ao.is_finite() && t.on_screen == 59);
        // Corner pixels of a real image: some samples off screen, the rest renormalised.
        let t = line_ao(&pit(0.3, 0.1).pyramid(3), (0, 0), 8.0, &wide(0.0, 0.0));
        assert!(t.on_screen > 0 && t.on_screen < 59 && t.ao == 0.0);
    }

    #[test]
    fn the_defaults_are_the_papers_and_check_names_the_field() {
        let d = LineAoSettings::default();
        assert_eq!((d.levels, d.samples, d.r0_widths), (3, 32, 1.5));
        assert_eq!(
            (d.delta0, d.light_intensity, d.radius_step),
            (1e-4, 0.5, 1.0)
        );
        d.check().unwrap();
        let bad = |s: LineAoSettings| s.check().unwrap_err().field;
        assert_eq!(bad(LineAoSettings { levels: 0, ..d }), "levels");
        assert_eq!(bad(LineAoSettings { levels: 9, ..d }), "levels");
        assert_eq!(bad(LineAoSettings { samples: 0, ..d }), "samples");
        assert_eq!(
            bad(LineAoSettings {
                r0_widths: 0.0,
                ..d
            }),
            "r0_widths"
        );
        let nan_width = LineAoSettings {
            line_width: LineWidth::World(f32::NAN),
            ..d
        };
        assert_eq!(bad(nan_width), "line_width");
        assert_eq!(
            bad(LineAoSettings {
                radius_step: -1.0,
                ..d
            }),
            "radius_step"
        );
        // delta_0 at or above delta(s_r - 1) = 1/9 would reverse the smoothstep's edges.
        assert_eq!(bad(LineAoSettings { delta0: 0.2, ..d }), "delta0");
        assert_eq!(
            bad(LineAoSettings {
                light_intensity: -0.1,
                ..d
            }),
            "light_intensity"
        );
        assert_eq!(
            bad(LineAoSettings {
                light_shininess: 0.0,
                ..d
            }),
            "light_shininess"
        );
        let e = LineAoSettings { levels: 0, ..d }.check().unwrap_err();
        assert!(e.to_string().starts_with("levels: 0"), "{e}");
    }
}
