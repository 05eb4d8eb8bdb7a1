//! Four lanes of `f32` for the sweeps' inner loops: SSE registers on x86-64 (SSE2 is part of
//! the x86-64 baseline, so no run-time detection is needed), plain arrays elsewhere. `min` and
//! `max` follow `minps`/`maxps`: the second operand wins when either is NaN.

#[cfg(target_arch = "x86_64")]
mod imp {
    use std::arch::x86_64::*;

    #[derive(Clone, Copy)]
    #[repr(transparent)]
    pub struct F4(pub __m128);

    impl Default for F4 {
        #[inline(always)]
        fn default() -> F4 {
            F4::splat(0.0)
        }
    }

    // SAFETY (all blocks below): SSE and SSE2 are enabled on every x86-64 target; loads and
    // stores go through references to `[f32; 4]`.
    impl F4 {
        #[inline(always)]
        pub fn splat(v: f32) -> F4 {
            unsafe { F4(_mm_set1_ps(v)) }
        }
        #[inline(always)]
        pub fn load(a: &[f32; 4]) -> F4 {
            unsafe { F4(_mm_loadu_ps(a.as_ptr())) }
        }
        #[inline(always)]
        pub fn store(self, a: &mut [f32; 4]) {
            unsafe { _mm_storeu_ps(a.as_mut_ptr(), self.0) }
        }
        #[inline(always)]
        pub fn min(self, o: F4) -> F4 {
            unsafe { F4(_mm_min_ps(self.0, o.0)) }
        }
        #[inline(always)]
        pub fn max(self, o: F4) -> F4 {
            unsafe { F4(_mm_max_ps(self.0, o.0)) }
        }
        #[inline(always)]
        pub fn abs(self) -> F4 {
            unsafe { F4(_mm_andnot_ps(_mm_set1_ps(-0.0), self.0)) }
        }
        #[inline(always)]
        pub fn sqrt(self) -> F4 {
            unsafe { F4(_mm_sqrt_ps(self.0)) }
        }
        #[inline(always)]
        pub fn add(self, o: F4) -> F4 {
            unsafe { F4(_mm_add_ps(self.0, o.0)) }
        }
        #[inline(always)]
        pub fn sub(self, o: F4) -> F4 {
            unsafe { F4(_mm_sub_ps(self.0, o.0)) }
        }
        #[inline(always)]
        pub fn mul(self, o: F4) -> F4 {
            unsafe { F4(_mm_mul_ps(self.0, o.0)) }
        }
        /// `if self <= t { a } else { b }` per lane.
        #[inline(always)]
        pub fn le_select(self, t: F4, a: F4, b: F4) -> F4 {
            unsafe {
                let m = _mm_cmple_ps(self.0, t.0);
                F4(_mm_or_ps(_mm_and_ps(m, a.0), _mm_andnot_ps(m, b.0)))
            }
        }
        /// Keeps `self` where its sign bit is set (frozen), else `min(d, self)`.
        #[inline(always)]
        pub fn relax(self, d: F4) -> F4 {
            unsafe {
                let frozen = _mm_castsi128_ps(_mm_srai_epi32(_mm_castps_si128(self.0), 31));
                let m = _mm_min_ps(d.0, self.0);
                F4(_mm_or_ps(
                    _mm_and_ps(frozen, self.0),
                    _mm_andnot_ps(frozen, m),
                ))
            }
        }
    }
}

#[cfg(not(target_arch = "x86_64"))]
mod imp {
    use super::{fmax, fmin};

    #[derive(Clone, Copy, Default)]
    pub struct F4(pub [f32; 4]);

    impl F4 {
        #[inline(always)]
        fn map2(self, o: F4, f: impl Fn(f32, f32) -> f32) -> F4 {
            F4([
                f(self.0[0], o.0[0]),
                f(self.0[1], o.0[1]),
                f(self.0[2], o.0[2]),
                f(self.0[3], o.0[3]),
            ])
        }
        pub fn splat(v: f32) -> F4 {
            F4([v; 4])
        }
        pub fn load(a: &[f32; 4]) -> F4 {
            F4(*a)
        }
        pub fn store(self, a: &mut [f32; 4]) {
            *a = self.0
        }
        pub fn min(self, o: F4) -> F4 {
            self.map2(o, fmin)
        }
        pub fn max(self, o: F4) -> F4 {
            self.map2(o, fmax)
        }
        pub fn abs(self) -> F4 {
            F4(self.0.map(f32::abs))
        }
        pub fn sqrt(self) -> F4 {
            F4(self.0.map(f32::sqrt))
        }
        pub fn add(self, o: F4) -> F4 {
            self.map2(o, |a, b| a + b)
        }
        pub fn sub(self, o: F4) -> F4 {
            self.map2(o, |a, b| a - b)
        }
        pub fn mul(self, o: F4) -> F4 {
            self.map2(o, |a, b| a * b)
        }
        pub fn le_select(self, t: F4, a: F4, b: F4) -> F4 {
            F4([0, 1, 2, 3].map(|k| if self.0[k] <= t.0[k] { a.0[k] } else { b.0[k] }))
        }
        pub fn relax(self, d: F4) -> F4 {
            F4([0, 1, 2, 3].map(|k| {
                if self.0[k].is_sign_negative() {
                    self.0[k]
                } else {
                    fmin(d.0[k], self.0[k])
                }
            }))
        }
    }
}

pub use imp::F4;

/// `min` as one `minss`: returns `b` when either is NaN (as `minps` does per lane).
#[inline(always)]
pub fn fmin(a: f32, b: f32) -> f32 {
    if a < b {
        a
    } else {
        b
    }
}

/// `max` as one `maxss`: returns `b` when either is NaN.
#[inline(always)]
pub fn fmax(a: f32, b: f32) -> f32 {
    if a > b {
        a
    } else {
        b
    }
}
