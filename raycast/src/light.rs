//! The volumetric occlusion buffer on the CPU: Schott et al.'s Algorithm 3 (ComputeDOS) as
//! `occlusion::combined` states it and `shaders/slice_pass.wgsl::light` computes it, for the
//! `dos` and `combined` methods of volume-only scenes on machines without a GPU.
//!
//! The light volume holds `O_k`, the light reaching step k (`LightSettings::step` slices deep,
//! `occlusion::combined::light_view`), which the eye reads at the step's front and carries
//! along its own ray (`occlusion::combined::light_in_slab`); behind clipping planes also the
//! light reaching each of the step's parts a voxel deep ([`store_parts`]: the eye's reads
//! after its first take each cell at the pixel's distance behind the planes, between parts,
//! [`LightVolume::front`]). The step's volume samples are
//! a voxel apart whatever it stores (`occlusion::combined::light_samples`: the volume sampled
//! at each part's middle, the light attenuated part by part). Storing only the fronts where
//! there are no planes keeps the volume a quarter of the size at the default step (the GPU's
//! stores every part: its tubes' coverage is in them). The volume lives on cells of `s x s`
//! pixels: step by step (each blurs the light leaving the previous one, so the steps
//! are a sequence; the rows of a slice are shared by the threads, [`sweep_slices`]), each cell's
//! `O_k` gathered from `L_{k-1} = O_{k-1} T_{k-1}` of its neighbours with the slice's blur
//! (`occlusion::combined::blur_rows`: the 3x3 stencil up to two cells, else `n x n` bilinear
//! taps on the disk), then `T_k` through the volume along the cell's centre ray, the whole
//! slab - each of its parts clipped by the clipping planes on its own - (occlusion does not
//! stop at the eye's opacity; it stops where the light arriving is below
//! `occlusion::combined::DARK`, which passes on unattenuated: [`EaVolume::sweep_until_dark`]).
//! The cone-following model carries the shadow's age as a second channel, as the shader does.
//!
//! Unlike the GPU's light volume (cells x slices, slice-major), the CPU's is cell-major in
//! blocks of [`KB`] slices: a ray reads the light of consecutive slices of the same four
//! cells, so one cache line serves [`KB`] of its samples, while the sweep writes one line per
//! cell every [`KB`] slices.

use crate::{EaVolume, Ray, Voxel, SKIP};
use occlusion::camera::Camera;
use occlusion::combined::{blur_rows, blur_taps, light_view, step_theta, BlurRow};
use occlusion::emission_absorption::EaView;
use rayon::prelude::*;

/// How the light volume is computed: `render.occlusion_cell` (as chosen by
/// `occlusion::combined::light_grid`), `render.occlusion_step` (eye slices per step of the
/// light, a power of two: `occlusion::combined::light_step`), `render.occlusion_model =
/// "cone"`, `render.theta` (degrees) and `render.blur_samples`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightSettings {
    pub cell: u32,
    pub step: u32,
    pub cone: bool,
    pub theta_deg: f64,
    pub blur_samples: u32,
}

/// Slices per block of a cell's light (16 f32: one cache line).
pub(crate) const KB: usize = 16;

/// `O` per cell and stored slice (see the module's layout): `slices` stored slices, each
/// `step` eye slices deep (a power of two: a part of a sweep step), each the light reaching
/// its slab's front. The eye reads the light reaching the front of the light step its sample
/// lies in ([`LightVolume::front`]: stored slice `parts s` for step `s`, `eye_step` eye slices
/// deep) and attenuates it along its own ray through the step
/// (`occlusion::combined::light_in_slab`, with the light's path factor `path` and
/// `inv_1f = 1 / (1 + path)`).
pub(crate) struct LightVolume {
    pub cells: [usize; 2],
    pub cell: usize,
    pub slices: usize,
    pub step: usize,
    /// Stored slices a light step (its parts), and the step's eye slices as a shift
    /// (`step parts = 1 << eye_step_shift`).
    pub parts: usize,
    pub eye_step_shift: u32,
    /// The light's path factor (`occlusion::combined::cone_path_factor`) and `1 / (1 + path)`.
    pub path: f32,
    pub inv_1f: f32,
    o: Vec<f32>,
}

impl LightVolume {
    /// No light (the unlit march's placeholder; never read).
    pub(crate) fn empty() -> LightVolume {
        LightVolume {
            cells: [1, 1],
            cell: 1,
            slices: 1,
            step: 1,
            parts: 1,
            eye_step_shift: 0,
            path: 1.0,
            inv_1f: 0.5,
            o: vec![1.0; KB],
        }
    }

    /// The light volume's values (the layout above), for the gathers of `lanes`.
    #[cfg(target_arch = "x86_64")]
    pub(crate) fn values(&self) -> &[f32] {
        &self.o
    }

    /// The light reaching the front of the light step eye slice `k` lies in, at a pixel, `O`
    /// of the step: bilinear over the four cells of `f` (offsets and fractions from
    /// [`LightVolume::footprint`]), at stored slice `parts (k >> eye_step_shift)`. Behind
    /// clipping planes each cell `i` is read with its shift ([`LightVolume::clip_shifts`]: the
    /// same distance behind the planes as the pixel), between stored slices: on the ray's
    /// `first` read, where it enters the medium at the cut (its first sample in its cut's
    /// slice), at the cell's own cut (read at `k + shift_i`, where the ray's first sample
    /// begins, up to a slice in front of the cut, a cell whose cut lay just past a step's front
    /// took the step before's light: faint lines a step apart on a cut face); a first read
    /// deeper (the ray meets the medium past its cut: at the grid's side, say) at
    /// the front of the step its own slice `k + shift_i` lies in (at `k + shift_i` itself the
    /// cells' own attenuation there showed on the grid's sides); later at the pixel's step's
    /// front plus `shift_i` (the stored parts there hold the cell's own attenuation). Read at the
    /// pixel's step's front from the start, the cells would lie further in front of their cuts
    /// the further the pixel's cut lies behind its step's front: a line a step on a cut face
    /// tilted to the slices. The eye carries the light along its own ray through the step
    /// (`occlusion::combined::light_in_slab`).
    pub(crate) fn front(&self, f: &Footprint, k: u32, first: bool) -> f32 {
        let v = if f.shifted {
            let (m, e) = (self.step as f32, (1u32 << self.eye_step_shift) as f32);
            let kf = ((k >> self.eye_step_shift) << self.eye_step_shift) as f32;
            // The ray's first sample is its cut's slice: it enters the medium at the cut.
            let at_cut = first && (k as f32) < f.entry + 1.0;
            [0, 1, 2, 3].map(|i| {
                let x = if at_cut {
                    (k as f32 + f.shift[i]).max(f.start[i])
                } else if first {
                    ((k as f32 + f.shift[i]) / e).floor() * e
                } else {
                    kf + f.shift[i]
                };
                self.cell_from(f.cells[i], x / m, f.start[i] / m)
            })
        } else {
            let s = ((k >> self.eye_step_shift) as usize * self.parts) as f32;
            [0, 1, 2, 3].map(|i| self.cell_at(f.cells[i], s))
        };
        let lerp = |a: f32, b: f32, t: f32| a + (b - a) * t;
        lerp(lerp(v[0], v[1], f.f[0]), lerp(v[2], v[3], f.f[0]), f.f[1])
    }

    /// Cell `c`'s (an offset `cell KB`) light at stored slice `kf`, as `light_step_at` in the
    /// shader: `O_{-1} = 1` before step 0, the last beyond it (read at whole stored slices).
    fn cell_at(&self, c: u32, kf: f32) -> f32 {
        self.cell_from(c, kf, f32::NEG_INFINITY)
    }

    /// [`LightVolume::cell_at`] for a cell whose ray enters the medium at stored slice `from`
    /// (behind clipping planes: its cut; `-inf` none): within the stored slice `from` lies in,
    /// the light is constant up to `from` and geometric from there to the next stored slice,
    /// `a (b / a)^t` ([`geometric`]: exact for a medium uniform between them; linear, its chord
    /// lay above the light's exponential decay - RMSE against the Monte Carlo reference 1-5%
    /// higher on the cut HeadMRVolume, docs/accuracy.md), `light_step_from` in the shader.
    /// Linear between stored slices without a cut (geometric there too gained 1-3% more and
    /// cost the clipped frames' march 7-20%: a logarithm and an exponential at every read). Nothing before the cut absorbs, so the change
    /// between the two stored slices - the cell's own attenuation, and at a step's front the
    /// blur - happens past it; linear over the whole stored slice, a read just past the cut
    /// took part of the change of the medium a stored slice deeper, and where the eye's ray
    /// entered just in front of a step's front its read at that front (a cell a fraction of a
    /// slice past its cut) fell below its neighbours' first reads: a dark seam a step on a cut
    /// face (docs/accuracy.md, "Seams on cut faces"). Equal to `cell_at` wherever `from` is
    /// at or before the stored slice below `kf`.
    fn cell_from(&self, c: u32, kf: f32, from: f32) -> f32 {
        if kf <= -1.0 {
            return 1.0;
        }
        let n = self.cells[0] * self.cells[1];
        let at = |k: usize| {
            let k = k.min(self.slices - 1);
            self.o[(k / KB) * n * KB + c as usize + k % KB]
        };
        if kf < 0.0 {
            return 1.0 + (at(0) - 1.0) * (kf + 1.0);
        }
        let fl = kf.floor();
        let k0 = fl as usize;
        // Where the medium begins within the stored slice, and the fraction past it.
        let s = from.max(fl);
        let t = if s >= kf {
            0.0
        } else {
            (kf - s) / (fl + 1.0 - s)
        };
        let (a, b) = (at(k0), at(k0.saturating_add(1)));
        if s > fl {
            geometric(a, b, t)
        } else {
            a + (b - a) * t
        }
    }

    /// Where each cell's centre ray enters the depths the clipping planes keep
    /// ([`occlusion::emission_absorption::clip_entry`]), cell by cell in raster order, for
    /// [`LightVolume::clip_shifts`]: once a frame, not four times a pixel. `ray` gives a pixel
    /// position's ray.
    pub(crate) fn clip_entries(
        &self,
        v: &EaView,
        ray: impl Fn([f64; 2]) -> (glam::DVec3, glam::DVec3) + Sync,
    ) -> Vec<Option<f64>> {
        let s = self.cell as f64;
        let cw = self.cells[0];
        (0..cw * self.cells[1])
            .into_par_iter()
            .map(|c| {
                let (x, y) = (c % cw, c / cw);
                let (o, d) = ray([(x as f64 + 0.5) * s, (y as f64 + 0.5) * s]);
                occlusion::emission_absorption::clip_entry(v, o, d)
            })
            .collect()
    }

    /// Sets `f`'s shifts for a pixel behind clipping planes (`cell_shifts` in the shader): a
    /// cut face tilted to the slices meets a cell's rays in different slabs, and read at equal
    /// depth a cell whose cut is a slab nearer has absorbed a slab more (a band per slice on
    /// the face); each cell is read instead at the same distance behind the planes as the
    /// pixel, `(entry_cell - entry_pixel) / dz` slices further. `entry` is the pixel's
    /// [`occlusion::emission_absorption::clip_entry`], `entries` the cells'
    /// ([`LightVolume::clip_entries`]).
    pub(crate) fn clip_shifts(
        &self,
        f: &mut Footprint,
        px: [f64; 2],
        v: &EaView,
        entry: Option<f64>,
        entries: &[Option<f64>],
    ) {
        let s = self.cell as f64;
        let c = [px[0] / s - 0.5, px[1] / s - 0.5];
        let b = c.map(|x| x.floor());
        let hi = [self.cells[0] as i64 - 1, self.cells[1] as i64 - 1];
        for (i, (dx, dy)) in [(0, 0), (1, 0), (0, 1), (1, 1)].into_iter().enumerate() {
            let x = (b[0] as i64 + dx).clamp(0, hi[0]) as usize;
            let y = (b[1] as i64 + dy).clamp(0, hi[1]) as usize;
            (f.shift[i], f.start[i]) = match (entry, entries[x + self.cells[0] * y]) {
                (Some(a), Some(b)) => (((b - a) / v.dz) as f32, ((b - v.z0) / v.dz) as f32),
                _ => (0.0, f32::NEG_INFINITY),
            };
        }
        f.entry = entry.map_or(f32::NEG_INFINITY, |a| ((a - v.z0) / v.dz) as f32);
        f.shifted = true;
    }

    /// The four cells around pixel position `px` (centres at half-integers of cells, clamped
    /// at the border) and the bilinear fractions, as `light_bilinear` in the shader. Inlined into
    /// the march's setup, compiled for AVX2 where the CPU has it (its `floor` an instruction,
    /// not a call into libm).
    #[inline(always)]
    pub(crate) fn footprint(&self, px: [f64; 2]) -> Footprint {
        let s = self.cell as f64;
        let c = [px[0] / s - 0.5, px[1] / s - 0.5];
        let b = c.map(|x| x.floor());
        let hi = [self.cells[0] as i64 - 1, self.cells[1] as i64 - 1];
        let at = |dx: i64, dy: i64| {
            let x = (b[0] as i64 + dx).clamp(0, hi[0]) as usize;
            let y = (b[1] as i64 + dy).clamp(0, hi[1]) as usize;
            ((x + self.cells[0] * y) * KB) as u32
        };
        Footprint {
            cells: [at(0, 0), at(1, 0), at(0, 1), at(1, 1)],
            f: [(c[0] - b[0]) as f32, (c[1] - b[1]) as f32],
            shift: [0.0; 4],
            start: [f32::NEG_INFINITY; 4],
            entry: f32::NEG_INFINITY,
            shifted: false,
        }
    }
}

/// Behind clipping planes, where a ray reaches the front of its next light step: the light it
/// carries on and the factor each of its samples in the step multiplies it by (besides its
/// own attenuation), so that the light it carries reaches the front read (`front`) over the
/// step instead of jumping there: `(front / carried)^(1 / e)`, `e` the step's eye slices
/// (`1 << eye_step_shift`), the ratio within [1e-3, 1e3], by `eye_step_shift` square roots
/// (correctly rounded, so the lanes give the same bits; a logarithm and an exponential cost
/// the clipped march 6-13%). The front holds the light the cells' coarser samples and the step's blur
/// give; carried along the eye's own finer samples the light differs from it a little, and a
/// ray entering a cut face at a grazing angle crosses a front in the bright medium under the
/// face: each jump showed as a line a step apart (the HeadMRVolume cut in half seen at azimuth
/// 200: its face's ripple 1.47x `ea`'s, 1.30x since; docs/accuracy.md, "Seams on cut
/// faces"). Where the carried light is below 1e-20 it takes the front at once.
#[inline(always)]
pub(crate) fn front_gain(carried: f32, front: f32, eye_step_shift: u32) -> (f32, f32) {
    if carried.is_nan() || carried <= 1e-20 {
        return (front, 1.0);
    }
    let mut g = (front / carried).clamp(GAIN_RANGE[0], GAIN_RANGE[1]);
    for _ in 0..eye_step_shift {
        g = g.sqrt();
    }
    (carried, g)
}

/// The range of [`front_gain`]'s ratio.
pub(crate) const GAIN_RANGE: [f32; 2] = [1e-3, 1e3];

/// `a (b / a)^t` for lights `a`, `b` and `t` in [0, 1): the larger of the two times
/// `exp(-u ln(larger / smaller))`, `u` the fraction from the larger's end, by [`ln_at_least_1`]
/// and [`exp_neg_fast`] (so that the lanes' `lanes::geometric` gives the same bits: libm's
/// `powf` has no vector twin); `a` at `t = 0`, and linear where either is below 1e-20 (no
/// ratio to take) or the two lie within 1% of each other.
#[inline(always)]
pub(crate) fn geometric(a: f32, b: f32, t: f32) -> f32 {
    let (hi, lo, u) = if a >= b { (a, b, t) } else { (b, a, 1.0 - t) };
    if t == 0.0 {
        a
    } else if lo > 1e-20 && hi - lo > 0.01 * hi {
        hi * exp_neg_fast(u * ln_at_least_1(hi / lo))
    } else {
        // Within 1% of each other the chord is within 1.3e-5 of the curve.
        a + (b - a) * t
    }
}

/// `ln r` for `r >= 1` (finite): the exponent's bits times `ln 2`, and the mantissa's `f` in
/// [1, 2) by the series of `2 atanh((f - 1) / (f + 1))` to its fifth term (error below 2e-6).
#[inline(always)]
pub(crate) fn ln_at_least_1(r: f32) -> f32 {
    let bits = r.to_bits();
    let e = ((bits >> 23) as i32 - 127) as f32;
    let f = f32::from_bits((bits & 0x007f_ffff) | 0x3f80_0000);
    let s = (f - 1.0) / (f + 1.0);
    let s2 = s * s;
    let p = s * (LN_C[0] + s2 * (LN_C[1] + s2 * (LN_C[2] + s2 * (LN_C[3] + s2 * LN_C[4]))));
    e * std::f32::consts::LN_2 + p
}

/// The series' coefficients `2 / (2k + 1)`.
pub(crate) const LN_C: [f32; 5] = [2.0, 2.0 / 3.0, 2.0 / 5.0, 2.0 / 7.0, 2.0 / 9.0];

/// `exp(-x)` for `x >= 0` (0 past 87, and for NaN): `2^-n` by the exponent's bits, `n` the
/// whole part of `x log2(e)`, times the Taylor series of `exp(-z)` to `z^7`, `z` the rest
/// times `ln 2` (in [0, 0.7): relative error below 1e-5, most of it the rounding of
/// `x log2(e)` where `x` is large).
#[inline(always)]
pub(crate) fn exp_neg_fast(x: f32) -> f32 {
    if x.is_nan() || x >= 87.0 {
        return 0.0;
    }
    let y = x * std::f32::consts::LOG2_E;
    let n = y.floor();
    let z = (y - n) * std::f32::consts::LN_2;
    let c = &EXP_C;
    let p = 1.0
        + z * (c[0] + z * (c[1] + z * (c[2] + z * (c[3] + z * (c[4] + z * (c[5] + z * c[6]))))));
    p * f32::from_bits(((127 - n as i32) as u32) << 23)
}

/// The Taylor coefficients of `exp(-z)` from `z` to `z^7`.
pub(crate) const EXP_C: [f32; 7] = [
    -1.0,
    0.5,
    -1.0 / 6.0,
    1.0 / 24.0,
    -1.0 / 120.0,
    1.0 / 720.0,
    -1.0 / 5040.0,
];

/// Where a pixel reads the light volume: four cells (as offsets `cell KB` into a block of
/// slices) and the bilinear fractions (x, y).
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Footprint {
    pub cells: [u32; 4],
    pub f: [f32; 2],
    /// Slices each cell is read further than the pixel's (behind clipping planes).
    pub shift: [f32; 4],
    /// Where each cell's ray enters the medium at the cut, in eye slices (`-inf`: no cut).
    pub start: [f32; 4],
    /// Where the pixel's ray enters it (`-inf`: no cut): the lanes read a cell's `start` only
    /// within a stored slice of it.
    pub entry: f32,
    pub shifted: bool,
}

/// A cell's light leaving a slice: `L` and, for the cone model, the shadow-weighted age
/// `(1 - O) (D + d)` of the arriving shadow.
type Leave = [f32; 2];

impl EaVolume {
    /// A cell's ray `o + s d` through the light's view `v` in steps of `samples` parts: as
    /// [`EaVolume::start`], but where a step's middle lies behind the ray's origin (a camera
    /// inside the grid) its last parts may not, so the ray starts a step earlier, its parts
    /// behind the origin unsampled ([`EaVolume::optical_depth`]).
    #[inline(always)]
    pub(crate) fn light_start(
        &self,
        v: &EaView,
        o: glam::DVec3,
        d: glam::DVec3,
        samples: u32,
    ) -> Ray {
        let mut r = self.start(v, o, d);
        if samples > 1 && r.k > 0 && r.k <= r.k1 {
            r.k -= 1;
        }
        r
    }

    /// The ray of the cell centred at pixel position `px` ([`EaVolume::light_start`]).
    #[inline(always)]
    fn light_ray(&self, v: &EaView, inv: &glam::DMat4, px: [f64; 2], samples: u32) -> Ray {
        let (o, d) = crate::pixel_ray(inv, v, px);
        self.light_start(v, o, d, samples)
    }

    /// [`EaVolume::light_ray`] compiled for AVX2 and FMA (the ray's `floor` and `ceil` are
    /// instructions there, calls into libm otherwise; the arithmetic is the same).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn light_ray_fma(
        &self,
        v: &EaView,
        inv: &glam::DMat4,
        px: [f64; 2],
        samples: u32,
    ) -> Ray {
        self.light_ray(v, inv, px, samples)
    }

    /// Keeps `lv`'s values for the next frame's sweep (see `EaVolume::light_store`).
    pub(crate) fn keep_light(&self, lv: LightVolume) {
        *self.light_store.lock().unwrap_or_else(|e| e.into_inner()) = lv.o;
    }

    /// The light volume of view `v`: slice after slice, every cell's `O_k` from the previous
    /// slice's light, then the light leaving through the slab.
    pub(crate) fn sweep<T: Voxel>(
        &self,
        v: &EaView,
        data: &[T],
        s: &LightSettings,
        inv: glam::DMat4,
    ) -> LightVolume {
        self.sweep_until_dark(v, data, s, inv, occlusion::combined::DARK)
    }

    /// [`EaVolume::sweep`] with cells whose arriving light is below `dark` left unsampled
    /// (`occlusion::combined::DARK`; 0: every cell sampled).
    pub(crate) fn sweep_until_dark<T: Voxel>(
        &self,
        v: &EaView,
        data: &[T],
        s: &LightSettings,
        inv: glam::DMat4,
        dark: f32,
    ) -> LightVolume {
        // A step of `s.step` eye slices (`occlusion::combined::light_step`): the sweep runs in
        // the light's own view, the eye reads it at its steps' fronts (`LightVolume::front`).
        // (A power of two: a step's parts share a block of `KB` stored slices.)
        let step = occlusion::combined::light_step(Some(s.step), v, false) as usize;
        // Samples a voxel apart whatever the step, and the light stored at each: a step
        // blurs once and attenuates part by part (`occlusion::combined::light_samples`).
        let samples = occlusion::combined::light_samples(v, step as u32) as usize;
        // The light volume stores each step's front, which the eye reads and carries along its
        // own ray (`LightVolume::front`); behind clipping planes each part's too, for the
        // cells read at the pixel's distance behind the planes.
        let kept = if v.clip.is_empty() { 1 } else { samples };
        let coarse;
        let v = if step > 1 {
            coarse = light_view(v, step as u32);
            &coarse
        } else {
            v
        };
        let theta_deg = step_theta(s.theta_deg, step as u32, s.cone);
        // The light crosses each slab along the cone's directions, not along the ray.
        let path = occlusion::combined::cone_path_factor(s.theta_deg) as f32;
        let cell = s.cell.max(1) as usize;
        let (w, h) = (v.width as usize, v.height as usize);
        let cells = [w.div_ceil(cell), h.div_ceil(cell)];
        let n = cells[0] * cells[1];
        let slices = v.slices.max(1) as usize;
        // Stored slices: `kept` a step, each `step / kept` eye slices deep.
        let stored = slices * kept;
        // The last frame's values, each block reset to 1 at its first slice (below).
        let mut o =
            std::mem::take(&mut *self.light_store.lock().unwrap_or_else(|e| e.into_inner()));
        let len = n * stored.div_ceil(KB) * KB;
        if o.capacity() > 2 * len {
            // Not a much larger frame's memory held for a small one.
            o = Vec::new();
        }
        o.truncate(len);
        o.resize(len, 1.0);
        let mut lv = LightVolume {
            cells,
            cell,
            slices: stored,
            step: step / kept,
            parts: kept,
            eye_step_shift: step.trailing_zeros(),
            path,
            inv_1f: 1.0 / (1.0 + path),
            o,
        };
        // The cells' centre rays, as the pixels' (a continuous pixel position).
        #[cfg(target_arch = "x86_64")]
        let fma = is_x86_feature_detected!("avx2") && is_x86_feature_detected!("fma");
        // Behind clipping planes, the slabs wholly inside each ray's kept depths are sampled
        // as without planes (`EaVolume::clip_slabs`, as the eye's).
        let planes = !v.clip.is_empty() && self.clip_slabs;
        let rays: Vec<Ray> = (0..n)
            .into_par_iter()
            .map(|c| {
                let px = [
                    ((c % cells[0]) as f64 + 0.5) * cell as f64,
                    ((c / cells[0]) as f64 + 0.5) * cell as f64,
                ];
                #[cfg(target_arch = "x86_64")]
                let mut r = if fma {
                    // SAFETY: the CPU has AVX2 and FMA (checked above).
                    unsafe { self.light_ray_fma(v, &inv, px, samples as u32) }
                } else {
                    self.light_ray(v, &inv, px, samples as u32)
                };
                #[cfg(not(target_arch = "x86_64"))]
                let mut r = self.light_ray(v, &inv, px, samples as u32);
                if planes {
                    self.clip_slabs(v, &mut r);
                }
                r
            })
            .collect();
        // Per cell, the steps whose samples may lie in an occupied block: the others are
        // sampled never (their optical depth is 0 for certain).
        let steps_occupied = self.steps_occupied(v, cells, cell, slices);
        let occ = steps_occupied.as_ref().map(|(o, g)| (&o[..], *g));
        let blur = blur_rows(v, cell as u32, theta_deg);
        debug_assert_eq!(blur.len(), v.slices as usize, "one blur row per slice");
        let taps = blur_taps(s.blur_samples.clamp(1, 9));
        // The cone model's tap sets, n = blur_samples..=9.
        let cone_taps: Vec<Vec<[f64; 2]>> = (0..=9).map(blur_taps).collect();
        // Per slice, the light leaving each cell: slice k reads `leave[k % 2]` (the previous
        // slice's) and writes `leave[(k + 1) % 2]`.
        let mut leave: [Vec<Leave>; 2] = [vec![[1.0, 0.0]; n], vec![[1.0, 0.0]; n]];
        // Per row of cells, the span of cells whose light leaving the previous slice is not
        // 1 (lo > hi: none); elsewhere the blur reads ones and gives 1 without reading. Read
        // and written as `leave`.
        let mut dirty: [Vec<(i32, i32)>; 2] = [
            vec![(i32::MAX, i32::MIN); cells[1]],
            vec![(i32::MAX, i32::MIN); cells[1]],
        ];
        // Per row, the cells the blur of a dirty cell may reach in the slice about to run.
        let mut reach: Vec<(i32, i32)> = vec![(i32::MAX, i32::MIN); cells[1]];
        // Per cell, the next slice whose sample may not be transparent.
        let mut next_k: Vec<u32> = match occ {
            Some((o, g)) => o.iter().map(|&m| next_occupied(m, g, 0)).collect(),
            None => vec![0; n],
        };
        let d = v.dz as f32;
        let threads = rayon::current_num_threads();
        let rows_per_job = (cells[1] / (4 * threads)).max(1);
        let jobs = cells[1].div_ceil(rows_per_job);
        #[cfg(target_arch = "x86_64")]
        let fma = is_x86_feature_detected!("avx2") && is_x86_feature_detected!("fma");
        // SAFETY: the CPU has AVX2 and FMA (checked).
        #[cfg(target_arch = "x86_64")]
        let splat =
            (fma && if planes {
                self.lanes_apply_planes(v, data, None)
            } else {
                self.lanes_apply(v, data, None)
            } && crate::lanes::gathers::<T>())
            .then(|| unsafe { crate::lanes::Splat::new(self) });
        let taps_n = s.blur_samples.clamp(1, 9) as usize;
        // The rows of job `j` of slice `k` (`shared`: the buffers above, written in disjoint
        // rows by the jobs of one slice, read by the next slice's).
        let run = |shared: &Shared, k: usize, j: usize| {
            let row = blur[k];
            let first = j * rows_per_job;
            let rows = rows_per_job.min(cells[1] - first);
            let (c0, len) = (first * cells[0], rows * cells[0]);
            // The job's rows' reach in slice k, from the dirty spans of the light they read
            // (rows up to `reach_rows(row)` away: jobs `sweep_slices` has finished slice k - 1
            // of).
            // The rows of the slice before that the job reads (all of them for the cone
            // model, whose jobs wait for every job).
            let reach_r = reach_rows(&row);
            let (p0, p1) = if s.cone {
                (0, cells[1])
            } else {
                let r = reach_r as usize;
                (first.saturating_sub(r), (first + rows + r).min(cells[1]))
            };
            {
                // SAFETY: rows p0..p1 of `dirty[k % 2]` were written by slice k - 1's jobs
                // of these rows and their neighbours, finished; only this job writes its rows
                // of `reach`.
                let (dirty, reach) = unsafe {
                    (
                        std::slice::from_raw_parts(shared.dirty[k % 2].add(p0), p1 - p0),
                        std::slice::from_raw_parts_mut(shared.reach.add(first), rows),
                    )
                };
                for (y, r) in (first as i32..).zip(reach.iter_mut()) {
                    let (mut lo, mut hi) = (i32::MAX, i32::MIN);
                    for yy in (y - reach_r).max(0)..=(y + reach_r).min(cells[1] as i32 - 1) {
                        let (a, b) = dirty[yy as usize - p0];
                        if a <= b {
                            lo = lo.min(a - reach_r);
                            hi = hi.max(b + reach_r);
                        }
                    }
                    *r = (lo, hi);
                }
            }
            // SAFETY: job j of slice k writes its rows `first..first + rows` of the slice's
            // outputs and reads its inputs (`leave[k % 2]`, `dirty[k % 2]`) in the rows of the
            // jobs within `reach_jobs`: `sweep_slices` runs it after their slice k - 1 and
            // before their slice k + 1 (which overwrites `leave[k % 2]`).
            let (prev, reach, out, o, nk, dn) = unsafe {
                (
                    std::slice::from_raw_parts(
                        shared.leave[k % 2].add(p0 * cells[0]),
                        (p1 - p0) * cells[0],
                    ),
                    std::slice::from_raw_parts(shared.reach.add(first), rows),
                    std::slice::from_raw_parts_mut(shared.leave[(k + 1) % 2].add(c0), len),
                    std::slice::from_raw_parts_mut(
                        shared.o.add(((k * kept / KB) * n + c0) * KB),
                        len * KB,
                    ),
                    std::slice::from_raw_parts_mut(shared.next_k.add(c0), len),
                    std::slice::from_raw_parts_mut(shared.dirty[(k + 1) % 2].add(first), rows),
                )
            };
            let job = Sweep {
                prev,
                prev_row0: p0,
                reach,
                rays: &rays,
                cells,
                row,
                w32: row.w.map(|r| r.map(|x| x as f32)),
                taps: &taps,
                cone_taps: &cone_taps,
                cone: s.cone,
                min_taps: taps_n,
                d,
                k,
                samples: samples as u32,
                kept: kept as u32,
                path,
                dark,
                planes,
                occ,
                #[cfg(target_arch = "x86_64")]
                splat: splat.as_ref(),
            };
            let rows = Rows {
                first,
                out,
                o,
                nk,
                dn,
            };
            #[cfg(target_arch = "x86_64")]
            if fma {
                // SAFETY: the CPU has AVX2 and FMA (checked above).
                unsafe { job.rows_fma(self, v, data, rows) };
                return;
            }
            job.rows(self, v, data, rows);
        };
        // The jobs a job's slice reads of the slice before on each side: the rows its blur and
        // its reach read (`reach_rows`); the cone model's taps widen with the shadow's age,
        // so it waits for every job.
        let reach_jobs = if s.cone {
            jobs
        } else {
            let r = blur.iter().map(reach_rows).max().unwrap_or(1) as usize;
            r.div_ceil(rows_per_job)
        };
        let [l0, l1] = &mut leave;
        let [d0, d1] = &mut dirty;
        let shared = Shared {
            leave: [l0.as_mut_ptr(), l1.as_mut_ptr()],
            dirty: [d0.as_mut_ptr(), d1.as_mut_ptr()],
            reach: reach.as_mut_ptr(),
            next_k: next_k.as_mut_ptr(),
            o: lv.o.as_mut_ptr(),
        };
        sweep_slices(
            &shared,
            blur.len().min(slices),
            jobs,
            reach_jobs,
            threads,
            &run,
        );
        lv
    }
}

/// The sweep's buffers, shared by its threads (see `run` in [`EaVolume::sweep`]).
struct Shared {
    leave: [*mut Leave; 2],
    dirty: [*mut (i32, i32); 2],
    reach: *mut (i32, i32),
    next_k: *mut u32,
    o: *mut f32,
}

// SAFETY: the threads write disjoint rows of the buffers, and `sweep_slices` orders a job's
// slice after the slice before of the jobs whose rows it reads, and before their next.
unsafe impl Sync for Shared {}

/// The first step from `from` in a group of `mask` (bit `j`: steps `j g .. (j + 1) g`), or
/// `u32::MAX` where none is left.
#[inline(always)]
fn next_occupied(mask: u64, g: u32, from: u32) -> u32 {
    let j = from / g;
    if from == u32::MAX || j >= 64 {
        return u32::MAX;
    }
    match mask & (u64::MAX << j) {
        0 => u32::MAX,
        m => from.max(m.trailing_zeros() * g),
    }
}

impl EaVolume {
    /// Per light cell, the groups of `g` steps of view `v` (a step a slice of it, `slices` in
    /// all, bit `j` of a cell's mask: steps `j g .. (j + 1) g`, `g` the fewest that fit 64
    /// groups) whose samples on the cell's centre ray may lie in an occupied skip block: each
    /// occupied block's box (index space, a hundredth of a voxel wider each way for the rays'
    /// rounding) projected to the cells whose centres its corners' bounding rectangle holds,
    /// over the steps its corners' depths span (depth is linear, so the extremes are corners';
    /// a block reaching behind the eye covers every cell). The rest are empty for certain:
    /// hydrogen's light took 19 times more samples in empty blocks than in occupied ones,
    /// stepping over them a block at a time. `None` where nine blocks in ten are occupied
    /// (little to gain; headsq's 51% gained 4-16% of its light pass, neghip's 14% at 128^2).
    pub(crate) fn steps_occupied(
        &self,
        v: &EaView,
        cells: [usize; 2],
        cell: usize,
        slices: usize,
    ) -> Option<(Vec<u64>, u32)> {
        let occupied = &self.occupied_blocks;
        if !self.step_mask || slices == 0 || 10 * occupied.len() > 9 * self.occupied.len() {
            return None;
        }
        let g = slices.div_ceil(64).max(1) as u32;
        let vp = v
            .camera
            .view_projection(v.width as f64 / v.height.max(1) as f64);
        let to_world = self.world_to_index.inverse();
        // Clip coordinates and depth are affine in the index: a block's corners are its first
        // corner's plus eight fixed offsets.
        let clip_of = vp * to_world;
        let (eye, f) = (v.camera.eye, v.camera.forward());
        let depth_of = |q: glam::DVec4| ((to_world * q).truncate() - eye).dot(f);
        let eps = 0.01;
        let axis = |a: usize| {
            let mut q = glam::DVec4::ZERO;
            q[a] = 1.0;
            q
        };
        let (cx, cy, cz) = (clip_of * axis(0), clip_of * axis(1), clip_of * axis(2));
        let (w, h) = (v.width as f64, v.height as f64);
        // Blocks merged `m` to a side (occupied where one of theirs is) while one projects to
        // fewer than three cells at the grid's middle: fewer boxes to project (the MNI T1's
        // 33,525 occupied blocks took 2.5 ms at 128^2), the mask hardly wider at the cells'
        // resolution.
        let mid = glam::DVec4::from((self.hi.map(|x| x as f64 * 0.5).into(), 1.0));
        let at = |q: glam::DVec4| {
            Camera::clip_to_pixel(clip_of * q, w, h).map(|(x, y)| glam::DVec2::new(x, y))
        };
        let across = (0..3)
            .filter_map(|a| Some((at(mid + axis(a) * SKIP as f64)? - at(mid)?).length()))
            .fold(0.0f64, f64::max)
            / cell as f64;
        let mut m = 1usize;
        while m < 8 && (m as f64) * across < 3.0 {
            m *= 2;
        }
        let coarse: Vec<u32>;
        let (occupied, [bx, by, _]) = if m == 1 {
            (occupied, self.blocks)
        } else {
            let cb = self.blocks.map(|b| b.div_ceil(m));
            let mut any = vec![false; cb[0] * cb[1] * cb[2]];
            let [bx, by, _] = self.blocks;
            for &b in occupied {
                let b = b as usize;
                let (x, y, z) = (b % bx / m, b / bx % by / m, b / (bx * by) / m);
                any[x + cb[0] * (y + cb[1] * z)] = true;
            }
            coarse = (0..any.len() as u32).filter(|&b| any[b as usize]).collect();
            (&coarse, cb)
        };
        let side = (m * SKIP) as f64 + 2.0 * eps;
        let origin = glam::DVec4::new(-eps, -eps, -eps, 1.0);
        let (c0, d0) = (clip_of * origin, depth_of(origin));
        let (dx, dy, dz) = (
            depth_of(axis(0) + origin) - d0,
            depth_of(axis(1) + origin) - d0,
            depth_of(axis(2) + origin) - d0,
        );
        let corners: [(glam::DVec4, f64); 8] = std::array::from_fn(|c| {
            let t = [c & 1, c & 2, c & 4].map(|b| if b == 0 { 0.0 } else { side });
            (
                cx * t[0] + cy * t[1] + cz * t[2],
                dx * t[0] + dy * t[1] + dz * t[2],
            )
        });
        let (cw, ch) = (cells[0] as i64, cells[1] as i64);
        let n = cells[0] * cells[1];
        let block = (m * SKIP) as f64;
        // Blocks split between the threads, each into a mask of its own, OR-ed at the end.
        let chunk = occupied
            .len()
            .div_ceil(4 * rayon::current_num_threads())
            .max(256);
        let out = occupied
            .par_chunks(chunk)
            .map(|bs| {
                let mut out = vec![0u64; n];
                for &b in bs {
                    let b = b as usize;
                    let bi = [b % bx, (b / bx) % by, b / (bx * by)].map(|x| x as f64 * block);
                    let base = c0 + cx * bi[0] + cy * bi[1] + cz * bi[2];
                    let dbase = d0 + dx * bi[0] + dy * bi[1] + dz * bi[2];
                    let mut px = [f64::INFINITY, f64::NEG_INFINITY];
                    let mut py = px;
                    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
                    let mut behind = false;
                    for (oc, od) in &corners {
                        let k = base + *oc;
                        let d = dbase + od;
                        (lo, hi) = (lo.min(d), hi.max(d));
                        let Some((x, y)) = Camera::clip_to_pixel(k, w, h) else {
                            behind = true;
                            continue;
                        };
                        px = [px[0].min(x), px[1].max(x)];
                        py = [py[0].min(y), py[1].max(y)];
                    }
                    let (k0, k1) = ((lo - v.z0) / v.dz, (hi - v.z0) / v.dz);
                    if !(k1 >= 0.0 && k0 < slices as f64) {
                        continue;
                    }
                    let k0 = k0.floor().max(0.0) as u32;
                    let k1 = k1.floor().min(slices as f64 - 1.0) as u32;
                    let bits = (u64::MAX >> (63 - k1 / g)) & (u64::MAX << (k0 / g));
                    // The cells whose centres ((i + 1/2) cell) the rectangle holds.
                    let span = |p: [f64; 2], n: i64| -> (i64, i64) {
                        if behind || !(p[0].is_finite() && p[1].is_finite()) {
                            return (0, n - 1);
                        }
                        let a = (p[0] / cell as f64 - 0.5).ceil().max(0.0);
                        let b = (p[1] / cell as f64 - 0.5).floor().min((n - 1) as f64);
                        (a as i64, b as i64)
                    };
                    let ((x0, x1), (y0, y1)) = (span(px, cw), span(py, ch));
                    if x0 > x1 {
                        continue;
                    }
                    for y in y0..=y1 {
                        let row = &mut out[(y * cw) as usize..][..cw as usize];
                        for m in &mut row[x0 as usize..=x1 as usize] {
                            *m |= bits;
                        }
                    }
                }
                out
            })
            .reduce_with(|mut a, b| {
                a.iter_mut().zip(&b).for_each(|(a, b)| *a |= b);
                a
            })
            .unwrap_or_else(|| vec![0u64; n]);
        Some((out, g))
    }
}

/// Cells further than a slice's blur reaches from every dirty cell gather 1: the rows (and
/// cells) it reaches, from the row's blur (1 for the 3x3 stencil).
fn reach_rows(row: &BlurRow) -> i32 {
    if row.wide {
        row.rpx[0].max(row.rpx[1]).ceil() as i32 + 1
    } else {
        1
    }
}

/// Runs `jobs` jobs of each of `slices` slices (`run(shared, k, j)`), job j's slice k after
/// slice k - 1 of the jobs within `reach` of it (j - reach ..= j + reach) and before their
/// slice k + 1 - a wavefront, not a barrier: a slice has a few jobs of a few microseconds
/// each, and a thread need not wait for the whole slice to finish before taking the next
/// slice's jobs whose neighbours are done. The threads that join (the caller and up to
/// `threads - 1` helpers in rayon's pool) claim jobs themselves, half of them scanning from
/// the first job and half from the last, each taking the first job it may run, so that a
/// thread keeps to the same rows (and their cache lines) slice after slice while the two
/// meet wherever the work splits evenly. Nothing waits for a helper that has not started (one
/// thread alone can run every job), so the sweep cannot deadlock inside the pool.
fn sweep_slices<S: Sync>(
    shared: &S,
    slices: usize,
    jobs: usize,
    reach: usize,
    threads: usize,
    run: &(impl Fn(&S, usize, usize) + Sync),
) {
    use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
    if slices == 0 || jobs == 0 {
        return;
    }
    let hands = threads.clamp(1, jobs);
    // Per job: slices claimed, and slices finished (release: the slice's writes).
    let claimed: Vec<AtomicUsize> = (0..jobs).map(|_| AtomicUsize::new(0)).collect();
    let done: Vec<AtomicUsize> = (0..jobs).map(|_| AtomicUsize::new(0)).collect();
    // Jobs with every slice finished.
    let complete = AtomicUsize::new(0);
    // Set when a job panicked: the others stop (rayon then passes the panic on).
    let failed = AtomicBool::new(false);
    struct Failed<'a>(&'a AtomicBool);
    impl Drop for Failed<'_> {
        fn drop(&mut self) {
            if std::thread::panicking() {
                self.0.store(true, Ordering::Relaxed);
            }
        }
    }
    // Job j's next slice, where it may run now: its own last one finished and its
    // neighbours' slice before it too (acquire: their writes).
    let next = |j: usize| -> Option<usize> {
        let k = claimed[j].load(Ordering::Acquire);
        if k >= slices || done[j].load(Ordering::Acquire) != k {
            return None;
        }
        let (lo, hi) = (j.saturating_sub(reach), (j + reach).min(jobs - 1));
        (lo..=hi)
            .all(|i| done[i].load(Ordering::Acquire) >= k)
            .then_some(k)
    };
    let work = |t: usize| {
        let backwards = t % 2 == 1;
        let mut spins = 0u32;
        loop {
            if failed.load(Ordering::Relaxed) || complete.load(Ordering::Acquire) == jobs {
                return;
            }
            let found = (0..jobs)
                .map(|i| if backwards { jobs - 1 - i } else { i })
                .find_map(|j| next(j).map(|k| (k, j)));
            let Some((k, j)) = found else {
                if spins < 4096 {
                    std::hint::spin_loop();
                    spins += 1;
                } else {
                    std::thread::yield_now();
                }
                continue;
            };
            if claimed[j]
                .compare_exchange(k, k + 1, Ordering::AcqRel, Ordering::Relaxed)
                .is_err()
            {
                // Another thread took it first: look again.
                continue;
            }
            spins = 0;
            let guard = Failed(&failed);
            run(shared, k, j);
            drop(guard);
            done[j].store(k + 1, Ordering::Release);
            if k + 1 == slices {
                complete.fetch_add(1, Ordering::AcqRel);
            }
        }
    };
    rayon::scope(|scope| {
        for t in 1..hands {
            let work = &work;
            scope.spawn(move |_| work(t));
        }
        work(0);
    });
}

/// Rows of cells of one slice, from row `first`: their light leaving (`out`), their `O` in
/// the light volume's block (`o`), their next slices to sample (`nk`) and their dirty spans
/// (`dn`).
struct Rows<'a> {
    first: usize,
    out: &'a mut [Leave],
    o: &'a mut [f32],
    nk: &'a mut [u32],
    dn: &'a mut [(i32, i32)],
}

/// One slice of the sweep: what every cell's gather reads.
struct Sweep<'a> {
    prev: &'a [Leave],
    /// The row of the light volume where `prev` begins (the rows the job reads).
    prev_row0: usize,
    /// Per row of the job (from `Rows::first`), the cells the blur of a dirty cell may
    /// reach (outside: clear).
    reach: &'a [(i32, i32)],
    /// The cells' centre rays.
    rays: &'a [Ray],
    cells: [usize; 2],
    row: BlurRow,
    /// The row's 3x3 stencil in f32.
    w32: [[f32; 3]; 3],
    taps: &'a [[f64; 2]],
    cone_taps: &'a [Vec<[f64; 2]>],
    cone: bool,
    min_taps: usize,
    d: f32,
    k: usize,
    /// Volume samples per step (`occlusion::combined::light_samples`).
    samples: u32,
    /// Stored slices per step: its front, and behind clipping planes each part's
    /// (`samples`).
    kept: u32,
    /// The light's extinction factor: its mean path through a slab over the cone's directions
    /// (`occlusion::combined::cone_path_factor` of the scene's own cone angle).
    path: f32,
    /// Arriving light below which a cell takes no samples (`occlusion::combined::DARK`).
    dark: f32,
    /// Clipping planes, the rays' slabs behind them found (`Ray::inner`): the lanes take
    /// only those (the others are cut part by part by `EaVolume::optical_depth`).
    planes: bool,
    /// Per cell, the groups of steps whose samples may lie in an occupied block, and the
    /// steps a group ([`EaVolume::steps_occupied`]; `None`: all of them).
    occ: Option<(&'a [u64], u32)>,
    /// Where the optical depths are taken eight cells at a time (`crate::lanes`): the CPU has
    /// AVX2 and FMA and `EaVolume::lanes_apply` holds.
    #[cfg(target_arch = "x86_64")]
    splat: Option<&'a crate::lanes::Splat<'a>>,
}

impl Sweep<'_> {
    /// [`Sweep::rows`] compiled for AVX2 and FMA.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn rows_fma<T: Voxel>(&self, ev: &EaVolume, v: &EaView, data: &[T], r: Rows<'_>) {
        self.rows(ev, v, data, r)
    }

    /// Slice `k` of rows `r`: each cell's `O_k` (1 where nothing dirty reaches it), stored
    /// where not 1 at the step's first stored slice and, attenuated part by part, at its
    /// others, and the light leaving it through its slab.
    #[inline(always)]
    fn rows<T: Voxel>(&self, ev: &EaVolume, v: &EaView, data: &[T], r: Rows<'_>) {
        let Rows {
            first,
            out,
            o,
            nk,
            dn,
        } = r;
        let cw = self.cells[0];
        let (k, d) = (self.k, self.d);
        let kk = k as u32;
        let c0 = first * cw;
        // The step's stored slices: `parts` of them from `j0` of the block (`KB` is a
        // multiple of the power of two `parts`).
        let parts = self.kept as usize;
        let j0 = (k * parts) % KB;
        if j0 == 0 {
            // A new block of slices: its values left from the last frame are reset to 1.
            o.fill(1.0);
        }
        let mut occ_row: Vec<f32> = Vec::new();
        // Cells of a row whose optical depth the lanes take (`lanes`).
        #[cfg(target_arch = "x86_64")]
        let (lanes, mut need) = (self.splat, Vec::<u32>::with_capacity(cw));
        for (ry, ((out, nk), dn)) in out
            .chunks_mut(cw)
            .zip(nk.chunks_mut(cw))
            .zip(dn.iter_mut())
            .enumerate()
        {
            let y = first + ry;
            let (rlo, rhi) = self.reach[ry];
            // The paper's blur over the row's reachable span at once (the 3x3 stencil,
            // vectorised); the cone model and wide blurs per cell.
            let span_lo = rlo.max(0) as usize;
            let span_hi = rhi.min(cw as i32 - 1);
            let spanned = span_hi >= span_lo as i32;
            let stencil = !self.cone && !self.row.wide;
            let by_row = stencil && spanned;
            if by_row {
                occ_row.clear();
                occ_row.resize(cw, 0.0);
                self.stencil_row(y, span_lo, span_hi as usize, &mut occ_row);
            }
            // The paper's blur with the lanes: the loop below's values, in loops over the row
            // instead of branches per cell (a row the blur does not reach too: its light
            // arrives at 1); the due cells' samples below, as the loop's.
            #[cfg(target_arch = "x86_64")]
            let rowwise = stencil && lanes.is_some();
            #[cfg(not(target_arch = "x86_64"))]
            let rowwise = false;
            let (mut lo, mut hi) = (i32::MAX, i32::MIN);
            #[cfg(target_arch = "x86_64")]
            if rowwise {
                // Outside the span the light arriving is 1 (the block holds 1 already:
                // nothing to store) and leaves so unless sampled below.
                out.fill([1.0, 0.0]);
                if spanned {
                    let (s0, s1) = (span_lo, span_hi as usize);
                    occ_row[..s0].fill(1.0);
                    occ_row[s1 + 1..].fill(1.0);
                    let orow = &mut o[ry * cw * KB..][..cw * KB];
                    for ((o, &occl), leave) in orow[s0 * KB..(s1 + 1) * KB]
                        .chunks_exact_mut(KB)
                        .zip(&occ_row[s0..=s1])
                        .zip(&mut out[s0..=s1])
                    {
                        o[j0..j0 + parts].fill(occl);
                        *leave = [occl, (1.0 - occl) * d];
                    }
                    // The span's cells not left at 1 (the sampled ones are added below).
                    let lit = |l: &Leave| *l != [1.0, 0.0];
                    if let Some(a) = out[s0..=s1].iter().position(lit) {
                        lo = (s0 + a) as i32;
                        hi = (s0 + out[s0..=s1].iter().rposition(lit).unwrap_or(a)) as i32;
                    }
                }
                // The cells whose sample is due: its optical depth, eight cells at a time.
                need.clear();
                // SAFETY: `lanes` is set only where the CPU has AVX2.
                unsafe { crate::lanes::due(nk, kk, &mut need) };
                if spanned {
                    // Light below `dark` passes on unattenuated (`occlusion::combined::DARK`).
                    need.retain(|&x| occ_row[x as usize] >= self.dark);
                }
                if self.planes {
                    // Behind clipping planes the lanes take the slabs of the cells' `inner`;
                    // the others' parts are cut one by one here (as the loop below does).
                    let row0 = c0 + ry * cw;
                    let orow = &mut o[ry * cw * KB..][..cw * KB];
                    need.retain(|&x| {
                        let x = x as usize;
                        let r = &self.rays[row0 + x];
                        if r.inner_has(kk) {
                            return true;
                        }
                        let (tau, after) = ev.optical_depth(v, data, r, kk, self.samples);
                        let tau = tau.map(|t| t * self.path);
                        nk[x] = self.next_due(row0 + x, after);
                        store_parts(&mut orow[x * KB + j0..x * KB + j0 + parts], ev, &tau);
                        out[x][0] *= ev.exp_neg(tau.iter().sum());
                        if out[x] != [1.0, 0.0] {
                            lo = lo.min(x as i32);
                            hi = hi.max(x as i32);
                        }
                        false
                    });
                }
            }
            let cells_here = if rowwise { 0 } else { cw };
            for (x, (leave, nk)) in out
                .iter_mut()
                .zip(nk.iter_mut())
                .enumerate()
                .take(cells_here)
            {
                let clear = (x as i32) < rlo || (x as i32) > rhi;
                if clear && kk < *nk {
                    // Light 1 arrives (the volume holds 1 already) and leaves.
                    *leave = [1.0, 0.0];
                    continue;
                }
                let c = c0 + ry * cw + x;
                let (occl, age) = if clear {
                    (1.0, 0.0)
                } else if by_row {
                    (occ_row[x], 0.0)
                } else {
                    self.gather(c)
                };
                let slots = (c - c0) * KB + j0;
                o[slots..slots + parts].fill(occl);
                // Light below `dark` is not sampled: it passes on unattenuated.
                let due = kk >= *nk && occl >= self.dark;
                #[cfg(target_arch = "x86_64")]
                if due && lanes.is_some() && (!self.planes || self.rays[c].inner_has(kk)) {
                    // The sample's optical depth is taken below, eight cells at a time.
                    need.push(x as u32);
                    *leave = [occl, (1.0 - occl) * (age + d)];
                    continue;
                }
                let tau = if due {
                    let (tau, after) = ev.optical_depth(v, data, &self.rays[c], kk, self.samples);
                    let tau = tau.map(|t| t * self.path);
                    *nk = self.next_due(c, after);
                    store_parts(&mut o[slots..slots + parts], ev, &tau);
                    tau.iter().sum()
                } else {
                    0.0
                };
                *leave = [occl * ev.exp_neg(tau), (1.0 - occl) * (age + d)];
                if leave[0] != 1.0 || leave[1] != 0.0 {
                    lo = lo.min(x as i32);
                    hi = hi.max(x as i32);
                }
            }
            #[cfg(target_arch = "x86_64")]
            if let Some(splat) = lanes {
                let orow = &mut o[ry * cw * KB..][..cw * KB];
                self.sample_due(
                    ev,
                    splat,
                    data,
                    c0 + ry * cw,
                    &need,
                    nk,
                    out,
                    orow,
                    j0,
                    |x, leave| {
                        if leave[0] != 1.0 || leave[1] != 0.0 {
                            lo = lo.min(x as i32);
                            hi = hi.max(x as i32);
                        }
                    },
                );
                need.clear();
            }
            *dn = (lo, hi);
        }
    }

    /// The optical depths of the row's cells `need` whose sample is due (the row's first cell
    /// is `row0`), eight at a time (`crate::lanes`): each cell's next slice to sample in `nk`,
    /// the step's stored slices past its first (`orow`, the row's cells' blocks, from slot
    /// `j0`) attenuated part by part, its light leaving in `out` times `exp(-tau)`, then
    /// `done(x, leave)`.
    #[cfg(target_arch = "x86_64")]
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn sample_due<T: Voxel>(
        &self,
        ev: &EaVolume,
        splat: &crate::lanes::Splat<'_>,
        data: &[T],
        row0: usize,
        need: &[u32],
        nk: &mut [u32],
        out: &mut [Leave],
        orow: &mut [f32],
        j0: usize,
        mut done: impl FnMut(usize, &Leave),
    ) {
        let parts = self.kept as usize;
        for xs in need.chunks(crate::lanes::LANES) {
            let mut cells = [0u32; crate::lanes::LANES];
            for (c, &x) in cells.iter_mut().zip(xs) {
                *c = (row0 + x as usize) as u32;
            }
            // SAFETY: `splat` is set only where the CPU has AVX2 and FMA and
            // `EaVolume::lanes_apply` holds for the view and the samples; the cells index the
            // rays.
            let (tau, next) = unsafe {
                crate::lanes::optical_depths_of(
                    splat,
                    data,
                    self.rays,
                    &cells[..xs.len()],
                    self.k as u32,
                    self.samples,
                )
            };
            for (i, &x) in xs.iter().enumerate() {
                let x = x as usize;
                // (A step over empty blocks past `Ray::inner`'s end steps over cut slabs whose
                // parts lie before the empty cube's far side too: nothing is missed.)
                nk[x] = self.next_due(row0 + x, next[i]);
                let t: crate::Parts = std::array::from_fn(|p| tau[p][i] * self.path);
                let slots = x * KB + j0;
                store_parts(&mut orow[slots..slots + parts], ev, &t);
                out[x][0] *= ev.exp_neg(t.iter().sum());
                done(x, &out[x]);
            }
        }
    }

    /// The first step from `next` (what the cell's samples found: the steps their empty
    /// blocks let it skip) whose samples may lie in an occupied block.
    #[inline(always)]
    fn next_due(&self, c: usize, next: u32) -> u32 {
        match self.occ {
            Some((o, g)) => next_occupied(o[c], g, next),
            None => next,
        }
    }

    /// The previous slice's light leaving cell `(x, y)`, clamped to the border.
    #[inline(always)]
    fn texel(&self, x: i64, y: i64) -> Leave {
        let x = x.clamp(0, self.cells[0] as i64 - 1) as usize;
        let y = y.clamp(0, self.cells[1] as i64 - 1) as usize;
        self.prev[x + self.cells[0] * (y - self.prev_row0)]
    }

    /// Bilinear read at a continuous cell position (centres at half-integers).
    fn bilinear(&self, t: [f64; 2]) -> Leave {
        let s = [t[0] - 0.5, t[1] - 0.5];
        let b = s.map(|x| x.floor());
        let f = [(s[0] - b[0]) as f32, (s[1] - b[1]) as f32];
        let (x, y) = (b[0] as i64, b[1] as i64);
        let mix = |a: Leave, b: Leave, t: f32| [a[0] + (b[0] - a[0]) * t, a[1] + (b[1] - a[1]) * t];
        let a = mix(self.texel(x, y), self.texel(x + 1, y), f[0]);
        let c = mix(self.texel(x, y + 1), self.texel(x + 1, y + 1), f[0]);
        mix(a, c, f[1])
    }

    /// The mean of `taps` scaled by the radius `r` (cells) around cell `(x, y)`'s centre.
    fn taps(&self, taps: &[[f64; 2]], x: i64, y: i64, r: [f64; 2]) -> Leave {
        let c = [x as f64 + 0.5, y as f64 + 0.5];
        let mut sum = [0.0f32; 2];
        for t in taps {
            let l = self.bilinear([c[0] + t[0] * r[0], c[1] + t[1] * r[1]]);
            sum = [sum[0] + l[0], sum[1] + l[1]];
        }
        let n = taps.len() as f32;
        [sum[0] / n, sum[1] / n]
    }

    /// The 3x3 stencil `kx (x) ky` (rows y = -1, 0, 1).
    #[inline(always)]
    fn stencil(&self, w: &[[f32; 3]; 3], x: i64, y: i64) -> Leave {
        let mut sum = [0.0f32; 2];
        for (j, row) in w.iter().enumerate() {
            for (i, wt) in row.iter().enumerate() {
                let l = self.texel(x + i as i64 - 1, y + j as i64 - 1);
                sum = [sum[0] + wt * l[0], sum[1] + wt * l[1]];
            }
        }
        sum
    }

    /// The paper's 3x3 stencil over cells `lo..=hi` of row `y` (borders clamped), into
    /// `out` (zeros): the same sums as [`Sweep::stencil`], a row at a time.
    fn stencil_row(&self, y: usize, lo: usize, hi: usize, out: &mut [f32]) {
        let [cw, ch] = self.cells;
        let rows = [y.saturating_sub(1), y, (y + 1).min(ch - 1)];
        for (j, &ry) in rows.iter().enumerate() {
            let p = &self.prev[(ry - self.prev_row0) * cw..][..cw];
            let [a, b, c] = self.w32[j];
            let at = |x: usize| {
                a * p[x.saturating_sub(1)][0] + b * p[x][0] + c * p[(x + 1).min(cw - 1)][0]
            };
            // Interior cells without clamping (the loop the compiler vectorises).
            let (i0, i1) = (lo.max(1), hi.min(cw.saturating_sub(2)));
            for (x, o) in out.iter_mut().enumerate().take(i0.min(hi + 1)).skip(lo) {
                *o += at(x);
            }
            if i0 <= i1 {
                for (o, w3) in out[i0..=i1].iter_mut().zip(p[i0 - 1..=i1 + 1].windows(3)) {
                    *o += a * w3[0][0] + b * w3[1][0] + c * w3[2][0];
                }
            }
            let tail = (i1 + 1).max(i0);
            for (x, o) in out.iter_mut().enumerate().take(hi + 1).skip(tail) {
                *o += at(x);
            }
        }
    }

    /// `O_k` of cell `c` and (cone model) the mean age of the shadow arriving there.
    fn gather(&self, c: usize) -> (f32, f32) {
        if self.k == 0 {
            return (1.0, 0.0);
        }
        let (x, y) = ((c % self.cells[0]) as i64, (c / self.cells[0]) as i64);
        if !self.cone {
            let occl = if self.row.wide {
                self.taps(self.taps, x, y, self.row.rpx)[0]
            } else {
                self.stencil(&self.w32, x, y)[0]
            };
            return (occl, 0.0);
        }
        // The step that makes an occluder's shadow at distance D reach the cone's variance
        // at D + d: the paper's radius times sqrt(1 + 2 D / d) (occlusion::combined).
        let own = self.texel(x, y);
        let d0 = own[1] / (1.0 - own[0]).max(1e-6);
        let g = (1.0 + 2.0 * d0.max(0.0) / self.d).sqrt() as f64;
        let rc = [self.row.rpx[0] * g, self.row.rpx[1] * g];
        let sum = if rc[0].max(rc[1]) <= 2.0 {
            let k = |r: f64| {
                let v = (r * r * 0.25) as f32;
                [0.5 * v, 1.0 - v, 0.5 * v]
            };
            let (kx, ky) = (k(rc[0]), k(rc[1]));
            let w = ky.map(|b| kx.map(|a| a * b));
            self.stencil(&w, x, y)
        } else {
            let n = (rc[0].max(rc[1]).ceil() as usize).clamp(self.min_taps, 9);
            self.taps(&self.cone_taps[n], x, y, rc)
        };
        (sum[0], sum[1] / (1.0 - sum[0]).max(1e-6))
    }
}

/// A step's stored slices past its first (`slots[0]` holds `O_k`): slice `i` the light
/// arriving at the step's part `i`, `O_k exp(-(tau_0 + ... + tau_{i-1}))` - the steps a part
/// deep attenuate so, and the step blurs only at its first.
#[inline(always)]
fn store_parts(slots: &mut [f32], ev: &EaVolume, tau: &crate::Parts) {
    let occl = slots[0];
    let mut acc = 0.0;
    for (i, s) in slots.iter_mut().enumerate().skip(1) {
        acc += tau[i - 1];
        *s = occl * ev.exp_neg(acc);
    }
}

#[cfg(test)]
mod tests {
    /// The geometric read's logarithm and exponential against f64's, and the read against
    /// `a (b / a)^t`: the logarithm within 2e-6 relative, the exponential within 1e-5 (its
    /// argument's rounding, at `x` near 80), the read within 3e-6.
    #[test]
    fn the_geometric_read_follows_the_exponential() {
        let mut worst = [0f64; 3];
        for i in 0..2000 {
            let r = 1.0 + (i as f32) * 0.37 + (i as f32).powi(3) * 1e-3;
            let e = (ln_at_least_1(r) as f64 - (r as f64).ln()).abs() / (r as f64).ln().max(1e-3);
            worst[0] = worst[0].max(e);
            let x = i as f32 * 0.04;
            let e = (exp_neg_fast(x) as f64 - (-x as f64).exp()).abs() / (-x as f64).exp();
            worst[1] = worst[1].max(e);
        }
        for (a, b) in [
            (1.0f32, 0.3f32),
            (0.3, 1.0),
            (0.9, 0.001),
            (1e-4, 0.5),
            (0.7, 0.7),
        ] {
            for k in 0..20 {
                let t = k as f32 / 20.0;
                let want = a as f64 * (b as f64 / a as f64).powf(t as f64);
                worst[2] = worst[2].max((geometric(a, b, t) as f64 - want).abs() / want);
            }
        }
        assert!(
            worst[0] < 2e-6 && worst[1] < 1e-5 && worst[2] < 3e-6,
            "{worst:?}"
        );
        // The ends, and no ratio to take.
        assert_eq!(geometric(0.4, 0.9, 0.0), 0.4);
        assert_eq!(geometric(0.0, 0.5, 0.5), 0.25);
        assert_eq!(exp_neg_fast(f32::NAN), 0.0);
        assert_eq!(exp_neg_fast(100.0), 0.0);
    }

    use super::{
        exp_neg_fast, geometric, ln_at_least_1, next_occupied, sweep_slices, LightSettings,
    };
    use crate::{EaVolume, View};
    use glam::{DVec3, DVec4};
    use occlusion::camera::Camera;
    use occlusion::emission_absorption::{EaView, Transfer};
    use rayon::prelude::*;
    use std::sync::atomic::{AtomicU64, Ordering};

    #[test]
    fn next_occupied_finds_the_first_step_of_a_set_group() {
        // Groups of 3 steps: bits 1 and 4 (steps 3-5 and 12-14).
        let m = (1u64 << 1) | (1u64 << 4);
        assert_eq!(next_occupied(m, 3, 0), 3);
        assert_eq!(next_occupied(m, 3, 4), 4);
        assert_eq!(next_occupied(m, 3, 6), 12);
        assert_eq!(next_occupied(m, 3, 14), 14);
        assert_eq!(next_occupied(m, 3, 15), u32::MAX);
        assert_eq!(next_occupied(u64::MAX, 1, 63), 63);
        assert_eq!(next_occupied(u64::MAX, 1, 64), u32::MAX);
        assert_eq!(next_occupied(0, 1, 0), u32::MAX);
        assert_eq!(next_occupied(m, 3, u32::MAX), u32::MAX);
    }

    /// The light sweep's step mask (`EaVolume::steps_occupied`) holds every step in which a
    /// cell's centre ray takes a sample in an occupied block - checked sample by sample on
    /// the rays the sweep casts, in perspective, orthographic and from inside the grid, for
    /// steps of 1 and 8 slices, cells of 1 to 3 pixels and blocks merged or not - and the
    /// light volume is the one swept without it, bit for bit.
    #[test]
    fn the_step_mask_holds_every_occupied_sample_and_changes_no_light() {
        // Two small blobs in a larger grid: most blocks empty.
        let dims = [52, 44, 40];
        let affine = glam::DMat4::from_cols(
            DVec4::new(1.0, 0.0, 0.0, 0.0),
            DVec4::new(0.0, 0.9, 0.0, 0.0),
            DVec4::new(0.0, 0.0, 1.2, 0.0),
            DVec4::new(-20.0, -18.0, -16.0, 1.0),
        );
        let (a, b) = (DVec3::new(-8.0, -6.0, -4.0), DVec3::new(12.0, 8.0, 14.0));
        let vol = volume::synthetic::sample_scalar(dims, affine, "blobs", |p| {
            (-(p - a).length_squared() / 12.0).exp() + (-(p - b).length_squared() / 20.0).exp()
        });
        let data = vol.select(None).unwrap().data;
        let tf = Transfer {
            points: vec![(0.4, [1.0; 3], 0.0), (1.0, [1.0, 0.8, 0.6], 1.5)],
            rows: vec![],
        };
        let mut ev = EaVolume::new(&vol, &data, &tf).unwrap();
        let occupied = ev.occupied_blocks.len();
        assert!(
            4 * occupied < ev.occupied.len(),
            "{occupied} blocks occupied"
        );
        let bounds = vol.bounds();
        let c = 0.5 * (bounds[0] + bounds[1]);
        let cameras = [
            Camera::orbit(bounds, 40.0, 25.0, 2.5, Some(40.0)),
            Camera::orbit(bounds, 200.0, -60.0, 4.0, Some(25.0)),
            Camera::orbit(bounds, 110.0, 10.0, 3.0, None),
            Camera {
                eye: c,
                target: c + DVec3::new(0.6, -0.3, 0.5),
                near: 0.5,
                ..Camera::orbit(bounds, 40.0, 25.0, 2.5, Some(60.0))
            },
        ];
        let View::F32(d) = ev.data.view() else {
            panic!("f32 samples expected")
        };
        let d = d.to_vec();
        let (mut checked, mut masked) = (0usize, 0usize);
        for (ci, cam) in cameras.iter().enumerate() {
            for (size, cell, step) in [(40u32, 1u32, 1u32), (64, 2, 8), (96, 3, 8), (24, 2, 1)] {
                let view = EaView::new(&vol, *cam, size, size, None, None, [1.0; 3]).unwrap();
                let inv = view.camera.view_projection(1.0).inverse();
                let step = occlusion::combined::light_step(Some(step), &view, false);
                let samples = occlusion::combined::light_samples(&view, step);
                let coarse = occlusion::combined::light_view(&view, step);
                let cells = [
                    (size as usize).div_ceil(cell as usize),
                    (size as usize).div_ceil(cell as usize),
                ];
                let slices = coarse.slices as usize;
                let (mask, g) = ev
                    .steps_occupied(&coarse, cells, cell as usize, slices)
                    .expect("a sparse volume has a mask");
                for cy in 0..cells[1] {
                    for cx in 0..cells[0] {
                        let px = [
                            (cx as f64 + 0.5) * cell as f64,
                            (cy as f64 + 0.5) * cell as f64,
                        ];
                        let r = ev.light_ray(&coarse, &inv, px, samples);
                        let m = mask[cx + cells[0] * cy];
                        masked += (m == 0) as usize;
                        for k in r.k..=r.k1.min(slices as u32 - 1) {
                            for i in 0..samples {
                                let at = k as f32 + crate::sub_offset(i, samples);
                                let q: [f32; 3] = std::array::from_fn(|a| r.qa[a] + at * r.dq[a]);
                                if !q.iter().zip(ev.hi).all(|(&x, h)| x >= 0.0 && x <= h) {
                                    continue;
                                }
                                let (_, block, _) = ev.cell(q);
                                if ev.occupied[block] {
                                    checked += 1;
                                    assert!(
                                        m >> (k / g) & 1 == 1,
                                        "camera {ci}, {size}^2, cell {cell}, step {step}: cell \
                                         ({cx}, {cy}) samples an occupied block at step {k} \
                                         outside its mask {m:b} (groups of {g})"
                                    );
                                }
                            }
                        }
                    }
                }
                let light = LightSettings {
                    cell,
                    step,
                    cone: false,
                    theta_deg: 30.0,
                    blur_samples: 3,
                };
                // The lanes' sweep and the scalar one.
                for lanes in [true, false] {
                    ev.lanes = lanes;
                    ev.step_mask = false;
                    let without = ev.sweep(&view, &d, &light, inv).values().to_vec();
                    ev.step_mask = true;
                    let with = ev.sweep(&view, &d, &light, inv).values().to_vec();
                    assert!(
                        with == without,
                        "camera {ci}, {size}^2, lanes {lanes}: the light changed"
                    );
                }
            }
        }
        // The check saw occupied samples, and the mask left cells out.
        assert!(
            checked > 5_000 && masked > 1000,
            "{checked} samples, {masked} cells masked"
        );
    }

    /// A sequence of slices, each job reading the values of the jobs within `reach` of it in
    /// the previous slice: any job run early, late or twice changes the result.
    fn sequence(slices: usize, jobs: usize, reach: usize, threads: usize) -> Vec<u64> {
        // Each job must run exactly once.
        let runs: Vec<AtomicU64> = (0..slices * jobs).map(|_| AtomicU64::new(0)).collect();
        let vals: [Vec<AtomicU64>; 2] = [
            (0..jobs).map(|j| AtomicU64::new(j as u64 + 1)).collect(),
            (0..jobs).map(|_| AtomicU64::new(0)).collect(),
        ];
        // Relaxed on purpose: the sweep's own ordering must make the reads see the writes.
        let run = |v: &[Vec<AtomicU64>; 2], k: usize, j: usize| {
            runs[k * jobs + j].fetch_add(1, Ordering::Relaxed);
            let prev = &v[k % 2];
            let (lo, hi) = (j.saturating_sub(reach), (j + reach).min(jobs - 1));
            let x: u64 = (lo..=hi)
                .map(|i| (i.abs_diff(j) as u64 + 2) * prev[i].load(Ordering::Relaxed))
                .sum();
            v[(k + 1) % 2][j].store(x % 1_000_003 + k as u64, Ordering::Relaxed);
        };
        sweep_slices(&vals, slices, jobs, reach, threads, &run);
        assert!(runs.iter().all(|r| r.load(Ordering::Relaxed) == 1));
        vals[slices % 2]
            .iter()
            .map(|x| x.load(Ordering::Relaxed))
            .collect()
    }

    #[test]
    fn slices_run_in_order_on_any_number_of_threads() {
        // In a pool of 8 workers, so that 3 and 8 threads do run at once.
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(8)
            .build()
            .unwrap();
        // Neighbours one job away (the 3x3 stencil), two (a wide blur) and every job (the
        // cone model).
        for reach in [1, 2, 13] {
            let want = sequence(300, 13, reach, 1);
            for threads in [2, 3, 8] {
                let got = pool.install(|| sequence(300, 13, reach, threads));
                assert_eq!(got, want, "{threads} threads, reach {reach}");
            }
        }
        let want = sequence(300, 13, 1, 1);
        assert!(want.iter().all(|&v| v > 0));
        // Sweeps at once from inside rayon's pool (frames drawn in parallel): no deadlock,
        // the same values.
        let got: Vec<_> = (0..6)
            .into_par_iter()
            .map(|_| sequence(300, 13, 1, 2))
            .collect();
        assert!(got.iter().all(|g| *g == want));
        // No slices: the values stay.
        assert_eq!(sequence(0, 13, 1, 2), (1..=13).collect::<Vec<u64>>());
        assert_eq!(sequence(5, 1, 1, 2), sequence(5, 1, 1, 1));
    }

    #[test]
    fn a_job_that_panics_ends_the_sweep_with_its_panic() {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(4)
            .build()
            .unwrap();
        for (threads, bad_job) in [(2, 0), (2, 12), (4, 5)] {
            let r = pool.install(|| {
                std::panic::catch_unwind(|| {
                    sweep_slices(&(), 100, 13, 1, threads, &|_, k, j| {
                        assert!(!(k == 7 && j == bad_job), "job {j} of slice {k}")
                    })
                })
            });
            let payload = r.expect_err("the job's panic");
            let text = payload
                .downcast_ref::<String>()
                .cloned()
                .unwrap_or_default();
            assert_eq!(
                text,
                format!("job {bad_job} of slice 7"),
                "{threads} threads"
            );
        }
    }
}
