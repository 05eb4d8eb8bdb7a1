//! The `ea` march - unlit, or lit by the light volume of `dos`/`combined` - and the
//! projections' with eight rays in the lanes of AVX2 registers.
//!
//! [`EaVolume::advance`] takes one sample of one ray at a time: about 20 cycles a sample
//! (`perf annotate` on headsq: the trilinear sample, the transfer function's walk, the
//! exponential's table, the compositing), each step a chain of dependent scalar operations.
//! Here eight rays of a packet take their next sample together, every operation on eight
//! lanes, the cell's corners, the skip reach, the exponential's table and the light read by
//! gathers (masked, so lanes that are done, outside the grid or in an empty block read
//! nothing). Values that sit side by side in memory come in pairs, one gather element each
//! (a cell's corners along x, [`Gather::gather_pair`]; a light cell's two stored slices where
//! both are in one block of [`KB`]): half the gathered elements, the same values.
//! Each lane does exactly what [`EaVolume::advance`] does for its ray, in the same
//! order and with the same operations (no fused multiply-adds where the scalar march has
//! none), so the image is the scalar march's bit for bit (tested): a lane outside the grid
//! steps one slice, a lane in an empty block steps past the cube of empty blocks around it
//! ([`crate::Ray::past_block`]), a lane in an occupied block samples and composites.
//!
//! The light volume's sweep takes its cells' optical depths the same way, eight cells at a
//! time ([`optical_depths`], the same per-slice step), and the projections their extremes
//! ([`march_extreme`], the same sampling without the transfer function).
//!
//! Used where the scalar march would use the same model without extras: `ea`, the eye
//! march of `dos`/`combined` and the projections `mip`/`minip`, samples in any stored type,
//! bricked or in the grid's layout ([`EaVolume::lanes_apply`]), on CPUs with AVX2 and FMA;
//! behind clipping planes, the slabs of each ray (and light cell) wholly inside the depths
//! the planes keep (`crate::Ray::inner`: `EaVolume::march_clipped`, the light read at each
//! cell's shift, [`Packet::front_shifted`]).

use crate::light::{LightVolume, KB};
use crate::{EaVolume, Ray, APRON, EXP_N, EXP_SCALE, SKIP};
use occlusion::emission_absorption::{EaView, BRICK, OPAQUE};
use std::arch::x86_64::*;

/// Lanes a register holds.
pub(crate) const LANES: usize = 8;

/// A stored sample type the lanes gather, as `f32` (exactly `volume::samples::Sample::value`).
pub(crate) trait Gather: Copy {
    /// The samples at `idx` (lanes whose sign bit of `mask` is set; 0 elsewhere) of `data`.
    ///
    /// # Safety
    /// AVX2 is available; the masked lanes' indices lie in `data`, which holds at least four
    /// samples.
    unsafe fn gather(data: &[Self], idx: __m256i, mask: __m256) -> __m256;

    /// Whether [`Gather::gather_pair`] takes its indices and mask in [`pair_order`].
    const PAIR_ORDER: bool;

    /// The samples at `idx` and `idx + 1` (as [`Gather::gather`] of each), one gather element a
    /// pair: `idx` and `mask` in [`pair_order`] where [`Gather::PAIR_ORDER`], else in lane
    /// order; the results in lane order.
    ///
    /// # Safety
    /// As [`Gather::gather`]'s, for the masked lanes' `idx` and `idx + 1`.
    unsafe fn gather_pair(data: &[Self], idx: __m256i, mask: __m256) -> (__m256, __m256);
}

/// The lane order the pair gathers take indices in: lanes 0, 1, 4, 5 by the first gather of
/// four 64-bit pairs, 2, 3, 6, 7 by the second, so that one shuffle within each half of a
/// register puts the pairs' values back in lane order (`_mm256_permutevar8x32_epi32` with
/// this puts a vector in it; the permutation is its own inverse).
#[inline(always)]
pub(crate) unsafe fn pair_order() -> __m256i {
    // SAFETY: AVX (callers are compiled for AVX2).
    unsafe { _mm256_setr_epi32(0, 1, 4, 5, 2, 3, 6, 7) }
}

/// The two 32-bit values of each lane pair gathered as 64-bit words at `idx` (in
/// [`pair_order`], in units of 4 bytes from `base`), masked by `mask` (also in pair order):
/// the first and second of each pair, in lane order.
///
/// # Safety
/// AVX2; the masked lanes' 8 bytes lie in the buffer at `base`.
#[inline(always)]
unsafe fn gather_pairs_32(base: *const u8, idx: __m256i, mask: __m256) -> (__m256, __m256) {
    // SAFETY: the caller's.
    unsafe {
        let m = _mm256_castps_si256(mask);
        let m_lo = _mm256_castsi256_pd(_mm256_cvtepi32_epi64(_mm256_castsi256_si128(m)));
        let m_hi = _mm256_castsi256_pd(_mm256_cvtepi32_epi64(_mm256_extracti128_si256::<1>(m)));
        let base = base as *const f64;
        let lo = _mm256_castpd_ps(_mm256_mask_i32gather_pd::<4>(
            _mm256_setzero_pd(),
            base,
            _mm256_castsi256_si128(idx),
            m_lo,
        ));
        let hi = _mm256_castpd_ps(_mm256_mask_i32gather_pd::<4>(
            _mm256_setzero_pd(),
            base,
            _mm256_extracti128_si256::<1>(idx),
            m_hi,
        ));
        // lo: the pairs of lanes 0, 1 | 4, 5; hi: of 2, 3 | 6, 7.
        (
            _mm256_shuffle_ps::<0b10_00_10_00>(lo, hi),
            _mm256_shuffle_ps::<0b11_01_11_01>(lo, hi),
        )
    }
}

impl Gather for f32 {
    const PAIR_ORDER: bool = true;

    #[inline(always)]
    unsafe fn gather(data: &[f32], idx: __m256i, mask: __m256) -> __m256 {
        // SAFETY: the caller's.
        unsafe { _mm256_mask_i32gather_ps::<4>(_mm256_setzero_ps(), data.as_ptr(), idx, mask) }
    }

    #[inline(always)]
    unsafe fn gather_pair(data: &[f32], idx: __m256i, mask: __m256) -> (__m256, __m256) {
        // SAFETY: the caller's: both samples of each masked lane lie in `data`.
        unsafe { gather_pairs_32(data.as_ptr() as *const u8, idx, mask) }
    }
}

/// Narrow samples of `BYTES` bytes, gathered as the 32-bit word that ends with the sample (or
/// starts at the buffer's first byte), shifted down and masked: the word never leaves the
/// buffer, so nothing past its end is read.
#[inline(always)]
unsafe fn gather_narrow<const BYTES: i32>(base: *const u8, idx: __m256i, mask: __m256) -> __m256 {
    // SAFETY: the caller's: the masked lanes' samples lie in a buffer of at least four bytes.
    unsafe {
        let at = _mm256_mullo_epi32(idx, _mm256_set1_epi32(BYTES));
        let start = _mm256_max_epi32(
            _mm256_sub_epi32(at, _mm256_set1_epi32(4 - BYTES)),
            _mm256_setzero_si256(),
        );
        let word = _mm256_mask_i32gather_epi32::<1>(
            _mm256_setzero_si256(),
            base as *const i32,
            start,
            _mm256_castps_si256(mask),
        );
        // Little-endian: the sample starts (at - start) bytes into the word.
        let shift = _mm256_slli_epi32::<3>(_mm256_sub_epi32(at, start));
        let v = _mm256_and_si256(
            _mm256_srlv_epi32(word, shift),
            _mm256_set1_epi32(((1i64 << (8 * BYTES)) - 1) as i32),
        );
        _mm256_cvtepi32_ps(v)
    }
}

impl Gather for u16 {
    const PAIR_ORDER: bool = false;

    #[inline(always)]
    unsafe fn gather(data: &[u16], idx: __m256i, mask: __m256) -> __m256 {
        // SAFETY: the caller's (at least four samples: eight bytes).
        unsafe { gather_narrow::<2>(data.as_ptr() as *const u8, idx, mask) }
    }

    /// Both samples in the one 32-bit word they fill.
    #[inline(always)]
    unsafe fn gather_pair(data: &[u16], idx: __m256i, mask: __m256) -> (__m256, __m256) {
        // SAFETY: the caller's: the word's four bytes are the two samples, both in `data`.
        unsafe {
            let word = _mm256_mask_i32gather_epi32::<2>(
                _mm256_setzero_si256(),
                data.as_ptr() as *const i32,
                idx,
                _mm256_castps_si256(mask),
            );
            // Little-endian: the first sample in the low half.
            (
                _mm256_cvtepi32_ps(_mm256_and_si256(word, _mm256_set1_epi32(0xffff))),
                _mm256_cvtepi32_ps(_mm256_srli_epi32::<16>(word)),
            )
        }
    }
}

impl Gather for u8 {
    const PAIR_ORDER: bool = false;

    #[inline(always)]
    unsafe fn gather(data: &[u8], idx: __m256i, mask: __m256) -> __m256 {
        // SAFETY: the caller's (at least four samples: four bytes).
        unsafe { gather_narrow::<1>(data.as_ptr(), idx, mask) }
    }

    /// Both samples in the 32-bit word that ends with the second (or starts at the buffer's
    /// first byte), as [`gather_narrow`] takes one.
    #[inline(always)]
    unsafe fn gather_pair(data: &[u8], idx: __m256i, mask: __m256) -> (__m256, __m256) {
        // SAFETY: the caller's: the word lies in `data` (at least four bytes, the second
        // sample in it).
        unsafe {
            let start = _mm256_max_epi32(
                _mm256_sub_epi32(idx, _mm256_set1_epi32(2)),
                _mm256_setzero_si256(),
            );
            let word = _mm256_mask_i32gather_epi32::<1>(
                _mm256_setzero_si256(),
                data.as_ptr() as *const i32,
                start,
                _mm256_castps_si256(mask),
            );
            let shift = _mm256_slli_epi32::<3>(_mm256_sub_epi32(idx, start));
            let v = _mm256_srlv_epi32(word, shift);
            let byte = _mm256_set1_epi32(0xff);
            (
                _mm256_cvtepi32_ps(_mm256_and_si256(v, byte)),
                _mm256_cvtepi32_ps(_mm256_and_si256(_mm256_srli_epi32::<8>(v), byte)),
            )
        }
    }
}

/// The volume's constants splatted into registers (made once per band of rows or per sweep
/// job, not per packet): the grid, its skip blocks and bricks, the corners' offsets, the
/// transfer function.
pub(crate) struct Splat<'v> {
    vol: &'v EaVolume,
    hi: [__m256; 3],
    last_cell: [__m256i; 3],
    blocks: [__m256i; 3],
    bricks: Option<[__m256i; 3]>,
    grid: [__m256i; 3],
    corners: [i32; 8],
    /// Each even corner's next is one sample further (x has two samples): the pairs come in
    /// one gather each.
    pairs: bool,
    offset: __m256,
    tf: Vec<(__m256, [__m256; 3], __m256)>,
    slopes: Vec<(__m256, [__m256; 3], __m256)>,
}

/// What one slice gives eight rays ([`Splat::step`]): which lanes are inside the grid, in an
/// empty skip block (and the slices to step past it) or sampled (not a gap), and the sample's
/// colour and extinction.
struct Step {
    is_empty: __m256i,
    steps: __m256i,
    sampled: __m256,
    rgb: [__m256; 3],
    sigma: __m256,
}

/// What [`Splat::sample`] finds: the empty lanes and their slices to skip (as [`Step`]), the
/// occupied lanes, and the trilinear sample without the samples' offset (`any`: of some lane).
struct Found {
    is_empty: __m256i,
    steps: __m256i,
    occupied: __m256,
    raw: __m256,
    any: bool,
}

// (Macros, not closures, so that every intrinsic is compiled with the calling function's
// target features.)
macro_rules! lerp {
    ($a:expr, $b:expr, $t:expr) => {{
        let (a, b) = ($a, $b);
        _mm256_add_ps(a, _mm256_mul_ps(_mm256_sub_ps(b, a), $t))
    }};
}

/// `light::geometric` eight lanes at a time: the same operations in the same order (its
/// `ln_at_least_1` and `exp_neg_fast`), so the same bits as the scalar march.
///
/// # Safety
/// The CPU has AVX2 (called from functions compiled for it).
#[inline(always)]
unsafe fn geometric(a: __m256, b: __m256, t: __m256) -> __m256 {
    use crate::light::{EXP_C, LN_C};
    use std::f32::consts::{LN_2, LOG2_E};
    // SAFETY: the caller's; arithmetic on registers only.
    unsafe {
        let ps = |x: f32| _mm256_set1_ps(x);
        let pi = |x: i32| _mm256_set1_epi32(x);
        let one = ps(1.0);
        let a_ge = _mm256_cmp_ps::<_CMP_GE_OQ>(a, b);
        let hi = _mm256_blendv_ps(b, a, a_ge);
        let lo = _mm256_blendv_ps(a, b, a_ge);
        let u = _mm256_blendv_ps(_mm256_sub_ps(one, t), t, a_ge);
        let lin = lerp!(a, b, t);
        let at0 = _mm256_cmp_ps::<_CMP_EQ_OQ>(t, _mm256_setzero_ps());
        let need = _mm256_and_ps(
            _mm256_cmp_ps::<_CMP_GT_OQ>(lo, ps(1e-20)),
            _mm256_cmp_ps::<_CMP_GT_OQ>(_mm256_sub_ps(hi, lo), _mm256_mul_ps(ps(0.01), hi)),
        );
        if _mm256_movemask_ps(need) == 0 {
            return _mm256_blendv_ps(lin, a, at0);
        }
        // ln(hi / lo): the exponent's bits, and the series on the mantissa.
        let bits = _mm256_castps_si256(_mm256_div_ps(hi, lo));
        let e = _mm256_cvtepi32_ps(_mm256_sub_epi32(_mm256_srli_epi32::<23>(bits), pi(127)));
        let f = _mm256_castsi256_ps(_mm256_or_si256(
            _mm256_and_si256(bits, pi(0x007f_ffff)),
            pi(0x3f80_0000),
        ));
        let s = _mm256_div_ps(_mm256_sub_ps(f, one), _mm256_add_ps(f, one));
        let s2 = _mm256_mul_ps(s, s);
        let mut p = ps(LN_C[4]);
        for c in LN_C[..4].iter().rev() {
            p = _mm256_add_ps(ps(*c), _mm256_mul_ps(s2, p));
        }
        let ln = _mm256_add_ps(_mm256_mul_ps(e, ps(LN_2)), _mm256_mul_ps(s, p));
        // exp(-u ln): 2^-n by the exponent's bits times the series on the rest.
        let x = _mm256_mul_ps(u, ln);
        let ok = _mm256_cmp_ps::<_CMP_LT_OQ>(x, ps(87.0));
        let y = _mm256_mul_ps(x, ps(LOG2_E));
        let n = _mm256_floor_ps(y);
        let z = _mm256_mul_ps(_mm256_sub_ps(y, n), ps(LN_2));
        let mut q = ps(EXP_C[6]);
        for c in EXP_C[..6].iter().rev() {
            q = _mm256_add_ps(ps(*c), _mm256_mul_ps(z, q));
        }
        let q = _mm256_add_ps(one, _mm256_mul_ps(z, q));
        let scale = _mm256_castsi256_ps(_mm256_slli_epi32::<23>(_mm256_sub_epi32(
            pi(127),
            _mm256_cvttps_epi32(n),
        )));
        let g = _mm256_mul_ps(hi, _mm256_and_ps(_mm256_mul_ps(q, scale), ok));
        _mm256_blendv_ps(_mm256_blendv_ps(lin, g, need), a, at0)
    }
}

impl<'v> Splat<'v> {
    /// # Safety
    /// The CPU has AVX2 and FMA.
    #[target_feature(enable = "avx2,fma")]
    pub(crate) unsafe fn new(vol: &'v EaVolume) -> Splat<'v> {
        let ps = |x: f32| _mm256_set1_ps(x);
        let pi = |x: i32| _mm256_set1_epi32(x);
        Splat {
            vol,
            hi: vol.hi.map(ps),
            last_cell: vol.dims.map(|n| pi((n.max(2) - 2) as i32)),
            blocks: vol.blocks.map(|n| pi(n as i32)),
            bricks: vol.bricks.map(|b| b.map(|n| pi(n as i32))),
            grid: vol.dims.map(|n| pi(n as i32)),
            // The corners' offsets from a cell's first: in a brick of APRON^3 samples, or in
            // the grid's layout (`EaVolume::corner`, as `EaVolume::corners`).
            corners: match vol.bricks {
                Some(_) => {
                    let (sy, sz) = (APRON as i32, (APRON * APRON) as i32);
                    [0, 1, sy, sy + 1, sz, sz + 1, sz + sy, sz + sy + 1]
                }
                None => vol.corner.map(|o| o as i32),
            },
            pairs: match vol.bricks {
                Some(_) => true,
                None => (0..4).all(|i| vol.corner[2 * i + 1] == vol.corner[2 * i] + 1),
            },
            offset: ps(vol.offset),
            tf: vol
                .tf
                .iter()
                .map(|p| (ps(p.0), p.1.map(ps), ps(p.2)))
                .collect(),
            slopes: vol
                .slopes
                .iter()
                .map(|s| (ps(s.0), s.1.map(ps), ps(s.2)))
                .collect(),
        }
    }

    /// Slice samples `q` (index space) of the `active` lanes, as `EaVolume::advance` and
    /// `EaVolume::optical_depth` take them: outside the grid nothing; in an empty skip block
    /// the slices past the empty cube of blocks around it (`Ray::past_block`, at least 1,
    /// capped far beyond any slice count); else the trilinear sample, without the samples'
    /// offset - in occupied blocks, and in empty ones too `WITH_EMPTY` (a projection's ray
    /// ends at a sample there, unless a gap) - ([`Found`]).
    ///
    /// # Safety
    /// As [`march`]'s; called only from functions compiled for AVX2 and FMA (inlined into
    /// them, so its intrinsics are compiled with their features).
    #[inline(always)]
    unsafe fn sample<T: Gather, const WITH_EMPTY: bool>(
        &self,
        data: &[T],
        q: [__m256; 3],
        dq: [__m256; 3],
        active: __m256i,
    ) -> Found {
        // SAFETY: the caller's; masked lanes read nothing.
        unsafe {
            let vol = self.vol;
            let zero = _mm256_setzero_ps();
            let (one, onei) = (_mm256_set1_ps(1.0), _mm256_set1_epi32(1));
            // Inside the grid: 0 <= q <= hi on every axis (false for NaN).
            let mut inside = _mm256_castsi256_ps(active);
            for (&qa, &hi) in q.iter().zip(&self.hi) {
                let ge = _mm256_cmp_ps::<_CMP_GE_OQ>(qa, zero);
                let le = _mm256_cmp_ps::<_CMP_LE_OQ>(qa, hi);
                inside = _mm256_and_ps(inside, _mm256_and_ps(ge, le));
            }
            let inside_i = _mm256_castps_si256(inside);
            // The cell (truncation floors the non-negative positions), its skip block.
            let cell: [__m256i; 3] = std::array::from_fn(|a| {
                _mm256_min_epi32(_mm256_cvttps_epi32(q[a]), self.last_cell[a])
            });
            let skip_shift = _mm_cvtsi32_si128(SKIP.trailing_zeros() as i32);
            let b: [__m256i; 3] = std::array::from_fn(|a| _mm256_srl_epi32(cell[a], skip_shift));
            let block = _mm256_add_epi32(
                b[0],
                _mm256_mullo_epi32(
                    self.blocks[0],
                    _mm256_add_epi32(b[1], _mm256_mullo_epi32(self.blocks[1], b[2])),
                ),
            );
            let d = _mm256_mask_i32gather_epi32::<4>(
                _mm256_setzero_si256(),
                vol.reach32.as_ptr(),
                block,
                inside_i,
            );
            let is_empty =
                _mm256_andnot_si256(_mm256_cmpeq_epi32(d, _mm256_setzero_si256()), inside_i);
            let occupied = _mm256_andnot_si256(is_empty, inside_i);
            // Empty lanes: the slices to the first past the empty cube of blocks around them
            // (the other lanes' counts are never read: none where no lane is empty).
            let mut steps = _mm256_set1_ps((1 << 20) as f32);
            let skip = _mm256_set1_epi32(SKIP as i32);
            // (Not where a sample in an empty block ends the ray: `WITH_EMPTY`.)
            let any_empty = !WITH_EMPTY && _mm256_testz_si256(is_empty, is_empty) == 0;
            for a in (0..3).filter(|_| any_empty) {
                let dqa = dq[a];
                let moving = _mm256_cmp_ps::<_CMP_GE_OQ>(
                    _mm256_andnot_ps(_mm256_set1_ps(-0.0), dqa),
                    _mm256_set1_ps(1e-12),
                );
                let up = _mm256_cmp_ps::<_CMP_GT_OQ>(dqa, zero);
                let far = _mm256_mullo_epi32(_mm256_add_epi32(b[a], d), skip);
                let near = _mm256_mullo_epi32(
                    _mm256_max_epi32(
                        _mm256_sub_epi32(_mm256_add_epi32(b[a], onei), d),
                        _mm256_setzero_si256(),
                    ),
                    skip,
                );
                let edge = _mm256_cvtepi32_ps(_mm256_castps_si256(_mm256_blendv_ps(
                    _mm256_castsi256_ps(near),
                    _mm256_castsi256_ps(far),
                    up,
                )));
                let n = _mm256_max_ps(_mm256_div_ps(_mm256_sub_ps(edge, q[a]), dqa), zero);
                let n = _mm256_add_ps(
                    _mm256_round_ps::<{ _MM_FROUND_TO_ZERO | _MM_FROUND_NO_EXC }>(n),
                    one,
                );
                steps = _mm256_blendv_ps(steps, _mm256_min_ps(steps, n), moving);
            }
            let steps = _mm256_max_epi32(_mm256_cvttps_epi32(steps), onei);
            let occ_ps = _mm256_castsi256_ps(occupied);
            let mask = if WITH_EMPTY { inside } else { occ_ps };
            if _mm256_testz_ps(mask, mask) != 0 {
                // No lane samples: nothing to gather.
                return Found {
                    is_empty,
                    steps,
                    occupied: zero,
                    raw: zero,
                    any: false,
                };
            }
            // The lanes of `mask`: the trilinear sample.
            let f: [__m256; 3] =
                std::array::from_fn(|a| _mm256_sub_ps(q[a], _mm256_cvtepi32_ps(cell[a])));
            // The cell's first corner: in its brick, or in the grid's own layout.
            let base = if let Some(bricks) = self.bricks {
                let brick_shift = _mm_cvtsi32_si128(BRICK.trailing_zeros() as i32);
                let brick_mask = _mm256_set1_epi32(BRICK as i32 - 1);
                let apron = _mm256_set1_epi32(APRON as i32);
                let bc: [__m256i; 3] =
                    std::array::from_fn(|a| _mm256_srl_epi32(cell[a], brick_shift));
                let lc: [__m256i; 3] =
                    std::array::from_fn(|a| _mm256_and_si256(cell[a], brick_mask));
                let brick = _mm256_add_epi32(
                    bc[0],
                    _mm256_mullo_epi32(
                        bricks[0],
                        _mm256_add_epi32(bc[1], _mm256_mullo_epi32(bricks[1], bc[2])),
                    ),
                );
                let local = _mm256_add_epi32(
                    lc[0],
                    _mm256_mullo_epi32(
                        apron,
                        _mm256_add_epi32(lc[1], _mm256_mullo_epi32(apron, lc[2])),
                    ),
                );
                _mm256_add_epi32(
                    _mm256_mullo_epi32(brick, _mm256_set1_epi32(APRON.pow(3) as i32)),
                    local,
                )
            } else {
                _mm256_add_epi32(
                    cell[0],
                    _mm256_mullo_epi32(
                        self.grid[0],
                        _mm256_add_epi32(cell[1], _mm256_mullo_epi32(self.grid[1], cell[2])),
                    ),
                )
            };
            let corners = self.corners;
            macro_rules! corner {
                ($o:expr) => {
                    T::gather(data, _mm256_add_epi32(base, _mm256_set1_epi32($o)), mask)
                };
            }
            let (x00, x10, x01, x11) = if self.pairs {
                // Each pair of corners along x in one gather ([`Gather::gather_pair`]).
                let (base, occ) = if T::PAIR_ORDER {
                    let order = pair_order();
                    (
                        _mm256_permutevar8x32_epi32(base, order),
                        _mm256_permutevar8x32_ps(mask, order),
                    )
                } else {
                    (base, mask)
                };
                macro_rules! pair {
                    ($o:expr) => {{
                        let (a, b) = T::gather_pair(
                            data,
                            _mm256_add_epi32(base, _mm256_set1_epi32($o)),
                            occ,
                        );
                        lerp!(a, b, f[0])
                    }};
                }
                (
                    pair!(corners[0]),
                    pair!(corners[2]),
                    pair!(corners[4]),
                    pair!(corners[6]),
                )
            } else {
                (
                    lerp!(corner!(corners[0]), corner!(corners[1]), f[0]),
                    lerp!(corner!(corners[2]), corner!(corners[3]), f[0]),
                    lerp!(corner!(corners[4]), corner!(corners[5]), f[0]),
                    lerp!(corner!(corners[6]), corner!(corners[7]), f[0]),
                )
            };
            Found {
                is_empty,
                steps,
                occupied: occ_ps,
                raw: lerp!(lerp!(x00, x10, f[1]), lerp!(x01, x11, f[1]), f[2]),
                any: true,
            }
        }
    }

    /// [`Splat::sample`] in occupied blocks through the transfer function (a gap below -1e30
    /// is not sampled).
    ///
    /// # Safety
    /// As [`Splat::sample`]'s.
    #[inline(always)]
    unsafe fn step<T: Gather>(
        &self,
        data: &[T],
        q: [__m256; 3],
        dq: [__m256; 3],
        active: __m256i,
    ) -> Step {
        // SAFETY: the caller's; masked lanes read nothing.
        unsafe {
            let zero = _mm256_setzero_ps();
            let Found {
                is_empty,
                steps,
                occupied: occ_ps,
                raw,
                any,
                ..
            } = self.sample::<T, false>(data, q, dq, active);
            if !any {
                return Step {
                    is_empty,
                    steps,
                    sampled: zero,
                    rgb: [zero; 3],
                    sigma: zero,
                };
            }
            let val = _mm256_add_ps(raw, self.offset);

            // Gaps (below -1e30) are not sampled.
            let sampled = _mm256_andnot_ps(
                _mm256_cmp_ps::<_CMP_LT_OQ>(val, _mm256_set1_ps(-1e30)),
                occ_ps,
            );
            // The transfer function: the last point by default (beyond it, and for NaN), the
            // first at or below its value, else the segment whose end is the first point at
            // or above the sample.
            let (tf, slopes) = (&self.tf, &self.slopes);
            let last = tf[tf.len() - 1];
            let (mut rgb, mut sigma) = (last.1, last.2);
            for i in (1..tf.len()).rev() {
                let (a, (inv, dc, de)) = (tf[i - 1], slopes[i]);
                let m = _mm256_and_ps(
                    _mm256_cmp_ps::<_CMP_GT_OQ>(val, a.0),
                    _mm256_cmp_ps::<_CMP_LE_OQ>(val, tf[i].0),
                );
                let t = _mm256_mul_ps(_mm256_sub_ps(val, a.0), inv);
                for ch in 0..3 {
                    rgb[ch] = _mm256_blendv_ps(
                        rgb[ch],
                        _mm256_add_ps(a.1[ch], _mm256_mul_ps(dc[ch], t)),
                        m,
                    );
                }
                sigma = _mm256_blendv_ps(sigma, _mm256_add_ps(a.2, _mm256_mul_ps(de, t)), m);
            }
            let first = tf[0];
            let m = _mm256_cmp_ps::<_CMP_LE_OQ>(val, first.0);
            for (x, f) in rgb.iter_mut().zip(first.1) {
                *x = _mm256_blendv_ps(*x, f, m);
            }
            sigma = _mm256_blendv_ps(sigma, first.2, m);
            Step {
                is_empty,
                steps,
                sampled,
                rgb,
                sigma,
            }
        }
    }
}

/// The rays' parameters, a lane each (missing lanes: rays already done, k > k1).
struct RayLanes {
    qa: [__m256; 3],
    dq: [__m256; 3],
    seg: __m256,
    k: __m256i,
    k1: __m256i,
    front: __m256,
}

impl RayLanes {
    /// # Safety
    /// The CPU has AVX2 (called from functions compiled for it).
    #[inline(always)]
    unsafe fn load<'r>(rays: impl Iterator<Item = &'r Ray>) -> RayLanes {
        let (mut qa, mut dq) = ([[0f32; LANES]; 3], [[0f32; LANES]; 3]);
        let (mut seg, mut k, mut k1) = ([0f32; LANES], [1i32; LANES], [0i32; LANES]);
        let mut front = [0f32; LANES];
        for (i, r) in rays.take(LANES).enumerate() {
            for a in 0..3 {
                qa[a][i] = r.qa[a];
                dq[a][i] = r.dq[a];
            }
            seg[i] = r.seg;
            front[i] = r.front;
            // Slices are at most `MAX_SLICES` (16,384, checked by `lanes_apply`): they fit.
            (k[i], k1[i]) = (r.k.min(1 << 30) as i32, r.k1.min(1 << 30) as i32);
        }
        // SAFETY: loads from local arrays of eight elements.
        unsafe {
            let load = |x: &[f32; LANES]| _mm256_loadu_ps(x.as_ptr());
            RayLanes {
                qa: qa.map(|x| load(&x)),
                dq: dq.map(|x| load(&x)),
                seg: load(&seg),
                k: _mm256_loadu_si256(k.as_ptr() as *const __m256i),
                k1: _mm256_loadu_si256(k1.as_ptr() as *const __m256i),
                front: load(&front),
            }
        }
    }

    /// Slice `k`'s samples, `q = qa + k dq` (as the scalar march: a product, then a sum).
    #[inline(always)]
    unsafe fn at(&self, k: __m256i) -> [__m256; 3] {
        let kf = _mm256_cvtepi32_ps(k);
        std::array::from_fn(|a| _mm256_add_ps(self.qa[a], _mm256_mul_ps(kf, self.dq[a])))
    }
}

/// Marches `rays` (at most [`LANES`]) to their ends as [`EaVolume::advance`] does for an
/// unclipped `ea` frame of the samples `data` (lit by `lv` when `LIT`), leaving in each ray
/// what the scalar march leaves (colour, opacity, the volumetric sums and the half-opacity
/// depth).
///
/// # Safety
/// The CPU has AVX2 and FMA; [`EaVolume::lanes_apply`] holds for `v`, `data` (the volume's
/// samples in its layout: at least four, fewer than 2^31) and, when `LIT`, `lv` (the light
/// volume swept for `v`, fewer than 2^31 values); `splat` is the volume's; the rays come from
/// [`EaVolume::start`] for `v` (the stored slices they read are clamped to the light volume's
/// last, `Marching::last`), their light footprints from
/// [`LightVolume::footprint`] (shifted behind clipping planes: `LightVolume::clip_shifts`;
/// then the rays' slices `k..=k1` lie in their `inner`, `EaVolume::march_clipped`).
#[target_feature(enable = "avx2,fma")]
pub(crate) unsafe fn march<T: Gather, const LIT: bool>(
    splat: &Splat<'_>,
    data: &[T],
    v: &EaView,
    lv: &LightVolume,
    rays: &mut [(usize, Ray)],
) {
    // SAFETY: the caller's (above); the gathers read only lanes whose indices lie in `data`,
    // `reach32`, the exponential's table and the light volume (masked lanes read nothing).
    unsafe {
        debug_assert!(rays.len() <= LANES);
        let m = Marching::new(splat, lv);
        let mut p = Packet::load::<LIT>(rays);
        loop {
            let active = p.active();
            if _mm256_movemask_epi8(active) == 0 {
                break;
            }
            p.advance::<T, LIT>(&m, data, active);
        }
        p.store(rays, v);
    }
}

/// What a [`march`] reads besides its packet: the volume's constants and the light volume's.
struct Marching<'s, 'v> {
    splat: &'s Splat<'v>,
    light: *const f32,
    slab: __m256i,
    kb_shift: __m128i,
    kb_mask: __m256i,
    inv_step: __m256,
    /// A stored slice's eye slices and one more (`Packet::front_shifted`'s reach of a cut).
    cut_reach: __m256,
    last: __m256i,
    order: __m256i,
    /// Light steps: eye slices as a shift, stored slices a step, the path factor `f` and
    /// `1 / (1 + f)`.
    eye_step_shift: __m128i,
    /// The same shift as a count (`light::front_gain`'s square roots).
    eye_shift: u32,
    parts: __m256i,
    path: __m256,
    inv_1f: __m256,
}

impl<'s, 'v> Marching<'s, 'v> {
    /// # Safety
    /// The CPU has AVX2 (called from functions compiled for it).
    #[inline(always)]
    unsafe fn new(splat: &'s Splat<'v>, lv: &LightVolume) -> Self {
        // SAFETY: the caller's.
        unsafe {
            const { assert!(KB.is_power_of_two()) };
            // Stored light slices of `lv.step` eye slices (a power of two).
            debug_assert!(lv.step.is_power_of_two());
            let pi = |x: i32| _mm256_set1_epi32(x);
            Marching {
                splat,
                light: lv.values().as_ptr(),
                slab: pi((lv.cells[0] * lv.cells[1] * KB) as i32),
                kb_shift: _mm_cvtsi32_si128(KB.trailing_zeros() as i32),
                kb_mask: pi(KB as i32 - 1),
                inv_step: _mm256_set1_ps(1.0 / lv.step as f32),
                cut_reach: _mm256_set1_ps(lv.step as f32 + 1.0),
                last: pi(lv.slices as i32 - 1),
                order: pair_order(),
                eye_step_shift: _mm_cvtsi32_si128(lv.eye_step_shift as i32),
                eye_shift: lv.eye_step_shift,
                parts: pi(lv.parts as i32),
                path: _mm256_set1_ps(lv.path),
                inv_1f: _mm256_set1_ps(lv.inv_1f),
            }
        }
    }
}

/// The eight rays of [`march`] (missing lanes: done from the start) and what they have
/// gathered.
struct Packet {
    r: RayLanes,
    /// Lit: each ray's four light cells (offsets into a block of slices) and fractions.
    cells: [__m256i; 4],
    frac: [__m256; 2],
    /// Behind clipping planes: each cell read this many slices further than the ray's slice
    /// (`Footprint::shift`; `LightVolume::front`), for every ray of the packet, and where each
    /// cell's ray enters the medium (`Footprint::start`) and where the ray does
    /// (`Footprint::entry`).
    shift: Option<([__m256; 4], [__m256; 4], __m256)>,
    kv: __m256i,
    k1v: __m256i,
    /// Lit: the light step each ray last read (`Ray::lstep`) and the light reaching its next
    /// sample (`Ray::lrun`).
    lstep: __m256i,
    lrun: __m256,
    /// Behind clipping planes, the factor each sample brings the light towards the last front
    /// read (`Ray::lgain`, `light::front_gain`).
    lgain: __m256,
    c: [__m256; 3],
    alpha: __m256,
    acc: __m256,
    weights: __m256,
    half_k: __m256i,
}

/// `exp(-x)` from the volume's table in the `mask` lanes, as `EaVolume::exp_neg` (1 at or
/// below 0 and for NaN, 0 beyond the table; masked lanes read nothing).
///
/// # Safety
/// As [`march`]'s.
#[inline(always)]
unsafe fn exp_neg(m: &Marching<'_, '_>, x: __m256, mask: __m256) -> __m256 {
    // SAFETY: the caller's; masked lanes read nothing.
    unsafe {
        let ps = |x: f32| _mm256_set1_ps(x);
        let (zero, one) = (_mm256_setzero_ps(), ps(1.0));
        let t = _mm256_mul_ps(x, ps(EXP_SCALE));
        let inner = _mm256_and_ps(
            mask,
            _mm256_and_ps(
                _mm256_cmp_ps::<_CMP_GT_OQ>(t, zero),
                _mm256_cmp_ps::<_CMP_LT_OQ>(t, ps(EXP_N as f32)),
            ),
        );
        let ti = _mm256_cvttps_epi32(_mm256_and_ps(t, inner));
        let tf_ = _mm256_sub_ps(t, _mm256_cvtepi32_ps(ti));
        // The table's neighbours `ti` and `ti + 1` in one gather element each.
        let (e0, e1) = gather_pairs_32(
            m.splat.vol.exp_table.as_ptr() as *const u8,
            _mm256_permutevar8x32_epi32(ti, m.order),
            _mm256_permutevar8x32_ps(inner, m.order),
        );
        _mm256_blendv_ps(
            // Outside the table: 1 at or below 0 (and NaN), 0 beyond its end.
            _mm256_blendv_ps(zero, one, _mm256_cmp_ps::<_CMP_NGT_UQ>(t, zero)),
            _mm256_add_ps(e0, _mm256_mul_ps(_mm256_sub_ps(e1, e0), tf_)),
            inner,
        )
    }
}

impl Packet {
    /// # Safety
    /// The CPU has AVX2 (called from functions compiled for it); at most [`LANES`] rays.
    #[inline(always)]
    unsafe fn load<const LIT: bool>(rays: &[(usize, Ray)]) -> Packet {
        // SAFETY: the caller's; loads from local arrays of eight elements.
        unsafe {
            debug_assert!(rays.len() <= LANES);
            let r = RayLanes::load(rays.iter().map(|(_, r)| r));
            let (mut cells, mut frac) = ([[0i32; LANES]; 4], [[0f32; LANES]; 2]);
            let mut shift = [[0f32; LANES]; 4];
            let mut start = [[f32::NEG_INFINITY; LANES]; 4];
            let mut entry = [f32::NEG_INFINITY; LANES];
            let mut shifted = false;
            let (mut lstep, mut lrun, mut lgain) = ([-1i32; LANES], [1f32; LANES], [1f32; LANES]);
            if LIT {
                for (i, (_, r)) in rays.iter().enumerate() {
                    for (j, c) in r.light.cells.iter().enumerate() {
                        cells[j][i] = *c as i32;
                        shift[j][i] = r.light.shift[j];
                        start[j][i] = r.light.start[j];
                    }
                    entry[i] = r.light.entry;
                    frac[0][i] = r.light.f[0];
                    frac[1][i] = r.light.f[1];
                    shifted |= r.light.shifted;
                    // (`u32::MAX`, none yet, is -1: no step of fewer than 2^30 slices.)
                    lstep[i] = r.lstep as i32;
                    lrun[i] = r.lrun;
                    lgain[i] = r.lgain;
                }
            }
            let cells = cells.map(|c| _mm256_loadu_si256(c.as_ptr() as *const __m256i));
            let zero = _mm256_setzero_ps();
            let p = Packet {
                cells,
                shift: shifted.then(|| {
                    (
                        shift.map(|x| _mm256_loadu_ps(x.as_ptr())),
                        start.map(|x| _mm256_loadu_ps(x.as_ptr())),
                        _mm256_loadu_ps(entry.as_ptr()),
                    )
                }),
                frac: frac.map(|f| _mm256_loadu_ps(f.as_ptr())),
                kv: r.k,
                k1v: r.k1,
                lstep: _mm256_loadu_si256(lstep.as_ptr() as *const __m256i),
                lrun: _mm256_loadu_ps(lrun.as_ptr()),
                lgain: _mm256_loadu_ps(lgain.as_ptr()),
                r,
                c: [zero; 3],
                alpha: zero,
                acc: zero,
                weights: zero,
                half_k: _mm256_set1_epi32(-1),
            };
            // What the rays have gathered before (a clipped frame's cut slabs in front).
            let mut got = [[0f32; LANES]; 6];
            for (i, (_, r)) in rays.iter().enumerate() {
                for (g, x) in got
                    .iter_mut()
                    .zip([r.c[0], r.c[1], r.c[2], r.alpha, r.acc[0], r.acc[1]])
                {
                    g[i] = x;
                }
            }
            let got = got.map(|g| _mm256_loadu_ps(g.as_ptr()));
            Packet {
                c: [got[0], got[1], got[2]],
                alpha: got[3],
                acc: got[4],
                weights: got[5],
                ..p
            }
        }
    }

    /// The lanes still marching: k <= k1 (both below 2^30).
    #[inline(always)]
    unsafe fn active(&self) -> __m256i {
        // SAFETY: called from functions compiled for AVX2.
        unsafe { _mm256_cmpgt_epi32(_mm256_add_epi32(self.k1v, _mm256_set1_epi32(1)), self.kv) }
    }

    /// One slice of the `active` lanes, as [`EaVolume::advance`] takes it.
    ///
    /// # Safety
    /// As [`march`]'s.
    #[inline(always)]
    unsafe fn advance<T: Gather, const LIT: bool>(
        &mut self,
        m: &Marching<'_, '_>,
        data: &[T],
        active: __m256i,
    ) {
        // SAFETY: the caller's; masked lanes read nothing.
        unsafe {
            let zero = _mm256_setzero_ps();
            let onei = _mm256_set1_epi32(1);
            let (r, kv) = (&self.r, self.kv);
            let Step {
                is_empty,
                steps,
                sampled,
                rgb,
                sigma,
            } = m.splat.step(data, r.at(kv), r.dq, active);
            let lit = _mm256_and_ps(sampled, _mm256_cmp_ps::<_CMP_NLE_UQ>(sigma, zero));
            // A packet none of whose samples absorbs composites nothing (and reads no light).
            let opaque = if _mm256_movemask_ps(lit) != 0 {
                self.composite::<LIT>(m, lit, sigma, rgb, kv)
            } else {
                zero
            };
            // Next slices: one for lanes outside the grid or sampled, past the empty cube for
            // empty ones; rays that became opaque end (k = 1 > k1 = 0).
            let step = _mm256_blendv_epi8(_mm256_and_si256(active, onei), steps, is_empty);
            let kv = _mm256_add_epi32(kv, step);
            let done = _mm256_castps_si256(opaque);
            self.kv = _mm256_blendv_epi8(kv, onei, done);
            self.k1v = _mm256_blendv_epi8(self.k1v, _mm256_setzero_si256(), done);
        }
    }

    /// Composites the samples of the `lit` lanes (colour `rgb`, extinction `sigma`) at slice
    /// `kv`, as [`EaVolume::advance`] does; the lanes that became opaque.
    ///
    /// # Safety
    /// As [`march`]'s.
    #[inline(always)]
    unsafe fn composite<const LIT: bool>(
        &mut self,
        m: &Marching<'_, '_>,
        lit: __m256,
        sigma: __m256,
        rgb: [__m256; 3],
        kv: __m256i,
    ) -> __m256 {
        // SAFETY: the caller's; masked lanes read nothing.
        unsafe {
            let ps = |x: f32| _mm256_set1_ps(x);
            let one = ps(1.0);
            let half = ps(0.5);
            let r = &self.r;
            // 1 - exp(-sigma len), the exponential from its table (`EaVolume::exp_neg`).
            let e = exp_neg(m, _mm256_mul_ps(sigma, r.seg), lit);
            let al = _mm256_sub_ps(one, e);
            let wgt = _mm256_mul_ps(_mm256_sub_ps(one, self.alpha), al);
            // The light along the ray's own path through its light step
            // (`occlusion::combined::light_in_slab`, as `EaVolume::advance`): the step's front
            // from the light volume where the ray enters a step, then attenuated by its
            // samples; this sample's light weighted by the eye's attenuation within its slab
            // (`lw`, for `wgt` unlit).
            let lw = if LIT {
                let st = _mm256_srl_epi32(kv, m.eye_step_shift);
                let stale =
                    _mm256_andnot_ps(_mm256_castsi256_ps(_mm256_cmpeq_epi32(st, self.lstep)), lit);
                if _mm256_movemask_ps(stale) != 0 {
                    match &self.shift {
                        None => {
                            let front = self.front(m, stale, st);
                            self.lrun = _mm256_blendv_ps(self.lrun, front, stale);
                        }
                        Some((shift, start, entry)) => {
                            let front = self.front_shifted(m, stale, shift, start, *entry);
                            // A ray's first read, or a light carried below 1e-20, takes the
                            // front; the others approach it over the step
                            // (`light::front_gain`, to the bit).
                            let first = _mm256_castsi256_ps(_mm256_cmpeq_epi32(
                                self.lstep,
                                _mm256_set1_epi32(-1),
                            ));
                            let dark =
                                _mm256_cmp_ps::<_CMP_NGT_UQ>(self.lrun, _mm256_set1_ps(1e-20));
                            let reset = _mm256_and_ps(stale, _mm256_or_ps(first, dark));
                            let toward = _mm256_andnot_ps(reset, stale);
                            let [lo, hi] = crate::light::GAIN_RANGE;
                            let ratio = _mm256_min_ps(
                                _mm256_max_ps(_mm256_div_ps(front, self.lrun), _mm256_set1_ps(lo)),
                                _mm256_set1_ps(hi),
                            );
                            let mut g = ratio;
                            for _ in 0..m.eye_shift {
                                g = _mm256_sqrt_ps(g);
                            }
                            self.lgain = _mm256_blendv_ps(self.lgain, one, reset);
                            self.lgain = _mm256_blendv_ps(self.lgain, g, toward);
                            self.lrun = _mm256_blendv_ps(self.lrun, front, reset);
                        }
                    }
                    self.lstep = _mm256_blendv_epi8(self.lstep, st, _mm256_castps_si256(stale));
                }
                let ef = exp_neg(m, _mm256_mul_ps(m.path, _mm256_mul_ps(sigma, r.seg)), lit);
                let lo = _mm256_mul_ps(
                    self.lrun,
                    _mm256_mul_ps(_mm256_sub_ps(one, _mm256_mul_ps(e, ef)), m.inv_1f),
                );
                self.lrun = _mm256_blendv_ps(
                    self.lrun,
                    _mm256_mul_ps(self.lrun, _mm256_mul_ps(ef, self.lgain)),
                    lit,
                );
                _mm256_mul_ps(_mm256_sub_ps(one, self.alpha), lo)
            } else {
                wgt
            };
            let c = &mut self.c;
            for ch in 0..3 {
                let x = _mm256_mul_ps(lw, rgb[ch]);
                c[ch] = _mm256_blendv_ps(c[ch], _mm256_add_ps(c[ch], x), lit);
            }
            let before = self.alpha;
            let alpha = _mm256_blendv_ps(before, _mm256_add_ps(before, wgt), lit);
            self.alpha = alpha;
            self.acc = _mm256_blendv_ps(self.acc, _mm256_add_ps(self.acc, lw), lit);
            self.weights = _mm256_blendv_ps(self.weights, _mm256_add_ps(self.weights, wgt), lit);
            let crossed = _mm256_and_ps(
                lit,
                _mm256_and_ps(
                    _mm256_cmp_ps::<_CMP_GE_OQ>(alpha, half),
                    _mm256_cmp_ps::<_CMP_LT_OQ>(before, half),
                ),
            );
            self.half_k = _mm256_castps_si256(_mm256_blendv_ps(
                _mm256_castsi256_ps(self.half_k),
                _mm256_castsi256_ps(kv),
                crossed,
            ));
            _mm256_and_ps(lit, _mm256_cmp_ps::<_CMP_GT_OQ>(alpha, ps(OPAQUE)))
        }
    }

    /// The light reaching the front of light step `st` of the `lit` lanes
    /// (`LightVolume::front`): bilinear over the ray's four cells at stored slice `st parts`.
    ///
    /// # Safety
    /// As [`march`]'s.
    #[inline(always)]
    unsafe fn front(&self, m: &Marching<'_, '_>, lit: __m256, st: __m256i) -> __m256 {
        // SAFETY: the caller's; masked lanes read nothing.
        unsafe {
            let ks = _mm256_min_epi32(_mm256_mullo_epi32(st, m.parts), m.last);
            // The block and slot of stored slice `ks` in the light volume's layout.
            let at = _mm256_add_epi32(
                _mm256_mullo_epi32(_mm256_srl_epi32(ks, m.kb_shift), m.slab),
                _mm256_and_si256(ks, m.kb_mask),
            );
            let zero = _mm256_setzero_ps();
            // (A macro, not a closure: closures are compiled without AVX2.)
            macro_rules! cell {
                ($j:expr) => {
                    _mm256_mask_i32gather_ps::<4>(
                        zero,
                        m.light,
                        _mm256_add_epi32(at, self.cells[$j]),
                        lit,
                    )
                };
            }
            let v = [cell!(0), cell!(1), cell!(2), cell!(3)];
            let x0 = lerp!(v[0], v[1], self.frac[0]);
            let x1 = lerp!(v[2], v[3], self.frac[0]);
            lerp!(x0, x1, self.frac[1])
        }
    }

    /// [`Packet::front`] behind clipping planes (`LightVolume::front`): each of the four cells
    /// at its own fractional stored slice `pos / step` - `pos` on a ray's first read (`lstep`
    /// none yet) the cell's cut where the ray's first sample is its cut's slice (else the
    /// front of the light step `k + shift` lies in), else the front of the
    /// lanes' own step plus `shift` (`k` the lanes' slices; a product by `1 / step`, a power of
    /// two: the quotient's bits) - 1 at or before -1, towards the first stored slice between -1
    /// and 0, else constant up to the cell's cut and geometric from there to the next stored
    /// slice (clamped to the last), as `LightVolume::cell_from`.
    ///
    /// # Safety
    /// As [`march`]'s.
    #[inline(always)]
    unsafe fn front_shifted(
        &self,
        m: &Marching<'_, '_>,
        lit: __m256,
        shift: &[__m256; 4],
        start: &[__m256; 4],
        entry: __m256,
    ) -> __m256 {
        // SAFETY: the caller's; masked lanes read nothing.
        unsafe {
            let (zero, one) = (_mm256_setzero_ps(), _mm256_set1_ps(1.0));
            let onei = _mm256_set1_epi32(1);
            let last_f = _mm256_cvtepi32_ps(m.last);
            let kf = _mm256_cvtepi32_ps(_mm256_sll_epi32(
                _mm256_srl_epi32(self.kv, m.eye_step_shift),
                m.eye_step_shift,
            ));
            let kr = _mm256_cvtepi32_ps(self.kv);
            let first = _mm256_castsi256_ps(_mm256_cmpeq_epi32(self.lstep, _mm256_set1_epi32(-1)));
            let eye = _mm256_cvtepi32_ps(_mm256_sll_epi32(_mm256_set1_epi32(1), m.eye_step_shift));
            // The ray's first sample is its cut's slice: it enters the medium at the cut.
            let at_cut = _mm256_cmp_ps::<_CMP_LT_OQ>(kr, _mm256_add_ps(entry, one));
            // A cell's cut lies in the stored slice read only where the ray's own cut lies
            // less than a stored slice (one eye slice more for the rounding) in front of its
            // step's front, or on its first read (at the cut or past it): elsewhere `LightVolume::cell_from`'s quotient is `x - fl` to the
            // bit, without the cuts or the division (done for every read, they cost 5% of the
            // march of a clipped frame).
            let near = _mm256_movemask_ps(_mm256_and_ps(
                lit,
                _mm256_or_ps(
                    _mm256_cmp_ps::<_CMP_LT_OQ>(_mm256_sub_ps(kf, entry), m.cut_reach),
                    first,
                ),
            )) != 0;
            let mut v = [zero; 4];
            for (j, v) in v.iter_mut().enumerate() {
                let ks = _mm256_add_ps(kr, shift[j]);
                let own = _mm256_blendv_ps(
                    _mm256_mul_ps(_mm256_floor_ps(_mm256_div_ps(ks, eye)), eye),
                    _mm256_max_ps(ks, start[j]),
                    at_cut,
                );
                let pos = _mm256_blendv_ps(_mm256_add_ps(kf, shift[j]), own, first);
                let x = _mm256_mul_ps(pos, m.inv_step);
                let fl = _mm256_floor_ps(x);
                // The stored slice below (0 before the first; clamped in f32 first, so that no
                // conversion overflows), and the next.
                let k0 = _mm256_cvttps_epi32(_mm256_min_ps(_mm256_max_ps(fl, zero), last_f));
                let k1 = _mm256_min_epi32(_mm256_add_epi32(k0, onei), m.last);
                // (A macro, not a closure: closures are compiled without AVX2.)
                macro_rules! at {
                    ($ks:expr) => {
                        _mm256_add_epi32(
                            _mm256_mullo_epi32(_mm256_srl_epi32($ks, m.kb_shift), m.slab),
                            _mm256_and_si256($ks, m.kb_mask),
                        )
                    };
                }
                let a0 = _mm256_add_epi32(at!(k0), self.cells[j]);
                // Neighbours in memory unless k0 is the last of its block or of the volume
                // (`KB` slices a block): then one 64-bit element a pair.
                let split = _mm256_or_si256(
                    _mm256_cmpeq_epi32(_mm256_and_si256(k0, m.kb_mask), m.kb_mask),
                    _mm256_cmpgt_epi32(_mm256_add_epi32(k0, onei), m.last),
                );
                let (a, b) = if _mm256_testz_si256(split, _mm256_castps_si256(lit)) != 0 {
                    gather_pairs_32(
                        m.light as *const u8,
                        _mm256_permutevar8x32_epi32(a0, m.order),
                        _mm256_permutevar8x32_ps(lit, m.order),
                    )
                } else {
                    (
                        _mm256_mask_i32gather_ps::<4>(zero, m.light, a0, lit),
                        _mm256_mask_i32gather_ps::<4>(
                            zero,
                            m.light,
                            _mm256_add_epi32(at!(k1), self.cells[j]),
                            lit,
                        ),
                    )
                };
                // Constant up to where the cell's ray enters the medium within the stored
                // slice, linear from there (`LightVolume::cell_from`).
                // Linear between stored slices; geometric from a cut within the stored slice
                // (`LightVolume::cell_from`).
                let inside = if !near {
                    lerp!(a, b, _mm256_sub_ps(x, fl))
                } else {
                    let s = _mm256_max_ps(_mm256_mul_ps(start[j], m.inv_step), fl);
                    let t = _mm256_div_ps(
                        _mm256_sub_ps(x, s),
                        _mm256_sub_ps(_mm256_add_ps(fl, one), s),
                    );
                    let t = _mm256_blendv_ps(t, zero, _mm256_cmp_ps::<_CMP_GE_OQ>(s, x));
                    let cut = _mm256_and_ps(lit, _mm256_cmp_ps::<_CMP_GT_OQ>(s, fl));
                    if _mm256_movemask_ps(cut) == 0 {
                        lerp!(a, b, t)
                    } else {
                        _mm256_blendv_ps(lerp!(a, b, t), geometric(a, b, t), cut)
                    }
                };
                // Between -1 and 0: from 1 towards the first stored slice (`a` there).
                let before = _mm256_add_ps(
                    one,
                    _mm256_mul_ps(_mm256_sub_ps(a, one), _mm256_add_ps(x, one)),
                );
                let val = _mm256_blendv_ps(inside, before, _mm256_cmp_ps::<_CMP_LT_OQ>(x, zero));
                *v = _mm256_blendv_ps(
                    val,
                    one,
                    _mm256_cmp_ps::<_CMP_LE_OQ>(x, _mm256_set1_ps(-1.0)),
                );
            }
            let x0 = lerp!(v[0], v[1], self.frac[0]);
            let x1 = lerp!(v[2], v[3], self.frac[0]);
            lerp!(x0, x1, self.frac[1])
        }
    }

    /// Leaves in each ray what the scalar march leaves (colour, opacity, the volumetric sums
    /// and the half-opacity depth).
    ///
    /// # Safety
    /// Called from functions compiled for AVX2.
    #[inline(always)]
    unsafe fn store(&self, rays: &mut [(usize, Ray)], v: &EaView) {
        // SAFETY: stores to local arrays of eight elements.
        unsafe {
            let store = |x: __m256| {
                let mut o = [0f32; LANES];
                _mm256_storeu_ps(o.as_mut_ptr(), x);
                o
            };
            let (c, alpha, acc, weights) = (
                self.c.map(store),
                store(self.alpha),
                store(self.acc),
                store(self.weights),
            );
            let (mut hk, mut k, mut k1) = ([0i32; LANES], [0i32; LANES], [0i32; LANES]);
            _mm256_storeu_si256(hk.as_mut_ptr() as *mut __m256i, self.half_k);
            _mm256_storeu_si256(k.as_mut_ptr() as *mut __m256i, self.kv);
            _mm256_storeu_si256(k1.as_mut_ptr() as *mut __m256i, self.k1v);
            let (mut lstep, mut lrun, mut lgain) = ([0i32; LANES], [0f32; LANES], [0f32; LANES]);
            _mm256_storeu_si256(lstep.as_mut_ptr() as *mut __m256i, self.lstep);
            _mm256_storeu_ps(lrun.as_mut_ptr(), self.lrun);
            _mm256_storeu_ps(lgain.as_mut_ptr(), self.lgain);
            for (i, (_, r)) in rays.iter_mut().enumerate() {
                (r.lstep, r.lrun, r.lgain) = (lstep[i] as u32, lrun[i], lgain[i]);
                // Done (k > k1), or ended early (k = 1, k1 = 0).
                (r.k, r.k1) = (k[i] as u32, k1[i] as u32);
                r.c = [c[0][i], c[1][i], c[2][i]];
                r.alpha = alpha[i];
                r.acc = [acc[i], weights[i]];
                if hk[i] >= 0 {
                    r.half = (v.z0 + (hk[i] as f64 + 0.5) * v.dz) as f32;
                }
            }
        }
    }
}

/// Marches `rays` (at most [`LANES`]) to their ends as [`EaVolume::advance`] does for an
/// unclipped projection (`MODE` 1: the largest sample, 2: the smallest) of the samples `data`,
/// leaving in each ray its extreme (`m`, `found`) as the scalar march does. `ends`: the
/// transparent side of empty blocks is the extreme's, so a sample there (not a gap) ends the
/// ray transparent; else empty blocks are stepped over.
///
/// # Safety
/// As [`march`]'s (without a light volume).
#[target_feature(enable = "avx2,fma")]
pub(crate) unsafe fn march_extreme<T: Gather, const MODE: u8>(
    splat: &Splat<'_>,
    data: &[T],
    rays: &mut [(usize, Ray)],
    ends: bool,
) {
    // SAFETY: the caller's; masked lanes read nothing; loads and stores of local arrays of
    // eight elements.
    unsafe {
        debug_assert!(rays.len() <= LANES);
        let r = RayLanes::load(rays.iter().map(|(_, r)| r));
        let (mut kv, mut k1v) = (r.k, r.k1);
        let (mut m0, mut f0) = ([0f32; LANES], [0i32; LANES]);
        for (i, (_, ray)) in rays.iter().enumerate() {
            m0[i] = ray.m;
            f0[i] = if ray.found { -1 } else { 0 };
        }
        let mut m = _mm256_loadu_ps(m0.as_ptr());
        let mut found = _mm256_castsi256_ps(_mm256_loadu_si256(f0.as_ptr() as *const __m256i));
        let (zeroi, onei) = (_mm256_setzero_si256(), _mm256_set1_epi32(1));
        let all = _mm256_castsi256_ps(_mm256_set1_epi32(-1));
        let gap = _mm256_set1_ps(-1e30);
        loop {
            let active = _mm256_cmpgt_epi32(_mm256_add_epi32(k1v, onei), kv);
            if _mm256_movemask_epi8(active) == 0 {
                break;
            }
            let q = r.at(kv);
            let s = if ends {
                splat.sample::<T, true>(data, q, r.dq, active)
            } else {
                splat.sample::<T, false>(data, q, r.dq, active)
            };
            // An occupied lane's sample, unless a gap: the extreme so far.
            let val = _mm256_add_ps(s.raw, splat.offset);
            let ok = _mm256_andnot_ps(_mm256_cmp_ps::<_CMP_LT_OQ>(val, gap), s.occupied);
            let better = if MODE == 1 {
                _mm256_cmp_ps::<_CMP_GT_OQ>(val, m)
            } else {
                _mm256_cmp_ps::<_CMP_LT_OQ>(val, m)
            };
            let take = _mm256_and_ps(ok, _mm256_or_ps(_mm256_xor_ps(found, all), better));
            m = _mm256_blendv_ps(m, val, take);
            found = _mm256_or_ps(found, take);
            let one = _mm256_and_si256(active, onei);
            if ends {
                // A sample in an empty block (not a gap: compared without the offset, as the
                // scalar march) ends the ray transparent (k = 1 > k1 = 0).
                let end = _mm256_and_si256(
                    s.is_empty,
                    _mm256_castps_si256(_mm256_cmp_ps::<_CMP_GE_OQ>(s.raw, gap)),
                );
                found = _mm256_andnot_ps(_mm256_castsi256_ps(end), found);
                kv = _mm256_blendv_epi8(_mm256_add_epi32(kv, one), onei, end);
                k1v = _mm256_blendv_epi8(k1v, zeroi, end);
            } else {
                kv = _mm256_add_epi32(kv, _mm256_blendv_epi8(one, s.steps, s.is_empty));
            }
        }
        _mm256_storeu_ps(m0.as_mut_ptr(), m);
        _mm256_storeu_si256(f0.as_mut_ptr() as *mut __m256i, _mm256_castps_si256(found));
        let (mut k, mut k1) = ([0i32; LANES], [0i32; LANES]);
        _mm256_storeu_si256(k.as_mut_ptr() as *mut __m256i, kv);
        _mm256_storeu_si256(k1.as_mut_ptr() as *mut __m256i, k1v);
        // What the scalar march leaves: the extreme, and the ray done (k > k1).
        for (i, (_, ray)) in rays.iter_mut().enumerate() {
            ray.m = m0[i];
            ray.found = f0[i] != 0;
            (ray.k, ray.k1) = (k[i] as u32, k1[i] as u32);
        }
    }
}

/// The optical depths of slice `k` along the rays of cells `cells` (at most [`LANES`]) of
/// `rays`, as [`EaVolume::optical_depth`] gives them for an unclipped view with `n` samples a
/// slab: each part's `sigma len / n` (0 outside the grid, in an empty skip block, at a gap;
/// indexed part, then lane), and the next slice whose depth may not be 0 (the ray's first slice before it; past
/// the empty cubes of blocks of all its samples; `u32`'s maximum past its last slice).
///
/// # Safety
/// As [`march`]'s for `splat` and `data`; `cells` index `rays`, which come from
/// [`EaVolume::start`] for the view.
#[target_feature(enable = "avx2,fma")]
pub(crate) unsafe fn optical_depths<T: Gather>(
    splat: &Splat<'_>,
    data: &[T],
    rays: &[Ray],
    cells: &[u32],
    k: u32,
    n: u32,
) -> ([[f32; LANES]; crate::MAX_PARTS], [u32; LANES]) {
    // SAFETY: the caller's; masked lanes read nothing.
    unsafe {
        debug_assert!(cells.len() <= LANES);
        let r = RayLanes::load(cells.iter().map(|&c| &rays[c as usize]));
        let kv = _mm256_set1_epi32(k.min(1 << 30) as i32);
        // Before the ray's first slice, past its last (missing lanes: k1 = 0 < k1 + 1 = k0).
        let before = _mm256_cmpgt_epi32(r.k, kv);
        let after = _mm256_cmpgt_epi32(kv, r.k1);
        let active = _mm256_andnot_si256(_mm256_or_si256(before, after), _mm256_set1_epi32(-1));
        let zero = _mm256_setzero_ps();
        let onei = _mm256_set1_epi32(1);
        let n = n.clamp(1, crate::MAX_PARTS as u32);
        // `n` samples at the middles of equal parts of the slab, as `EaVolume::optical_depth`
        // takes them: each part's optical depth; the slices to skip only where every sample
        // is in an empty block (the fewest of theirs), else 1.
        let (seg, kf) = (
            _mm256_div_ps(r.seg, _mm256_set1_ps(n as f32)),
            _mm256_cvtepi32_ps(kv),
        );
        let mut t = [[0f32; LANES]; crate::MAX_PARTS];
        let mut all_empty = _mm256_set1_epi32(-1);
        let mut steps = _mm256_set1_epi32(i32::MAX);
        // Lanes whose first sample's empty cube of blocks holds all of the slab's samples.
        let mut whole = _mm256_setzero_si256();
        for (i, t) in t.iter_mut().enumerate().take(n as usize) {
            let at = _mm256_add_ps(kf, _mm256_set1_ps(crate::sub_offset(i as u32, n)));
            let q = std::array::from_fn(|a| _mm256_add_ps(r.qa[a], _mm256_mul_ps(at, r.dq[a])));
            // A part behind the ray's origin (a camera inside the grid) is not sampled.
            let ahead = _mm256_castps_si256(_mm256_cmp_ps::<_CMP_GE_OQ>(at, r.front));
            let live = _mm256_andnot_si256(whole, _mm256_and_si256(active, ahead));
            let st = splat.step(data, q, r.dq, live);
            let tau = _mm256_and_ps(
                st.sampled,
                _mm256_mul_ps(_mm256_max_ps(st.sigma, zero), seg),
            );
            _mm256_storeu_ps(t.as_mut_ptr(), tau);
            all_empty = _mm256_and_si256(all_empty, _mm256_or_si256(st.is_empty, whole));
            steps = _mm256_min_epi32(
                steps,
                _mm256_blendv_epi8(st.steps, _mm256_set1_epi32(i32::MAX), whole),
            );
            if i == 0 && n > 1 {
                // The slab's samples lie less than a slice beyond its first: where the first's
                // empty cube reaches a slice or more further (`steps` >= 2), they all lie in
                // it, and the last leaves it no sooner than `steps - 1` slices on (the next
                // slice to sample; hydrogen's light at 128^2 took 83,997 lane samples, 105,560
                // before: docs/benchmarks.md, "The light's steps masked by the occupied
                // blocks"; images identical).
                whole = _mm256_and_si256(st.is_empty, _mm256_cmpgt_epi32(st.steps, onei));
                steps = _mm256_blendv_epi8(steps, _mm256_sub_epi32(st.steps, onei), whole);
                let rest = _mm256_andnot_si256(whole, active);
                if _mm256_testz_si256(rest, rest) != 0 {
                    break;
                }
            }
        }
        let next = _mm256_add_epi32(kv, _mm256_blendv_epi8(onei, steps, all_empty));
        let next = _mm256_blendv_epi8(next, r.k, before);
        let next = _mm256_blendv_epi8(next, _mm256_set1_epi32(-1), after);
        let mut m = [0u32; LANES];
        _mm256_storeu_si256(m.as_mut_ptr() as *mut __m256i, next);
        (t, m)
    }
}

/// Appends to `out` the indices `x` of `next` (from 0) with `next[x] <= k`: the cells whose
/// sample is due at slice `k`, eight compares at a time.
///
/// # Safety
/// The CPU has AVX2.
#[target_feature(enable = "avx2")]
pub(crate) unsafe fn due(next: &[u32], k: u32, out: &mut Vec<u32>) {
    let kv = _mm256_set1_epi32(k as i32);
    let mut chunks = next.chunks_exact(LANES);
    let mut x0 = 0u32;
    for c in &mut chunks {
        // SAFETY: eight u32 of the chunk; unsigned `n <= k` as `min(n, k) == n`.
        let mut bits = unsafe {
            let n = _mm256_loadu_si256(c.as_ptr() as *const __m256i);
            let le = _mm256_cmpeq_epi32(_mm256_min_epu32(n, kv), n);
            _mm256_movemask_ps(_mm256_castsi256_ps(le)) as u32
        };
        while bits != 0 {
            out.push(x0 + bits.trailing_zeros());
            bits &= bits - 1;
        }
        x0 += LANES as u32;
    }
    for (i, &n) in chunks.remainder().iter().enumerate() {
        if n <= k {
            out.push(x0 + i as u32);
        }
    }
}

/// Whether the lanes gather samples stored as `T` (`f32`, `u16`, `u8`).
pub(crate) fn gathers<T: 'static>() -> bool {
    use std::any::TypeId;
    [TypeId::of::<f32>(), TypeId::of::<u16>(), TypeId::of::<u8>()].contains(&TypeId::of::<T>())
}

/// `$body` with `$d` the slice `$data` of `$t`s retyped to its stored type (one the lanes
/// gather, [`gathers`]) and `$g` naming that type; `$other` for any other type.
macro_rules! by_stored_type {
    ($t:ty, $data:expr, $d:ident: $g:ident => $body:expr, else $other:expr) => {{
        use std::any::TypeId;
        let data = $data;
        macro_rules! with {
            ($s:ty) => {{
                type $g = $s;
                // SAFETY: the element type is $s (compared below): the same slice, retyped.
                let $d: &[$g] =
                    unsafe { std::slice::from_raw_parts(data.as_ptr() as *const $g, data.len()) };
                $body
            }};
        }
        let t = TypeId::of::<$t>();
        if t == TypeId::of::<f32>() {
            with!(f32)
        } else if t == TypeId::of::<u16>() {
            with!(u16)
        } else if t == TypeId::of::<u8>() {
            with!(u8)
        } else {
            $other
        }
    }};
}
pub(crate) use by_stored_type;

/// [`optical_depths`] over `data` retyped to its stored type (one of [`gathers`]).
///
/// # Safety
/// As [`optical_depths`]'s, and `gathers::<T>()`.
#[inline(always)]
pub(crate) unsafe fn optical_depths_of<T: 'static>(
    splat: &Splat<'_>,
    data: &[T],
    rays: &[Ray],
    cells: &[u32],
    k: u32,
    n: u32,
) -> ([[f32; LANES]; crate::MAX_PARTS], [u32; LANES]) {
    by_stored_type!(T, data, d: G => {
        // SAFETY: the caller's.
        unsafe { optical_depths::<G>(splat, d, rays, cells, k, n) }
    }, else unreachable!("samples the lanes do not gather"))
}
