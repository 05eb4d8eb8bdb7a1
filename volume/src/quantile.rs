//! Exact quantiles of a field's values in bounded memory: the robust range that
//! `volume.transfer.range = "robust"` ramps a preset over (FSL's `fslstats -r`, the 2nd and
//! 98th percentiles, which NiiVue and MRIcroGL show a volume over by default).
//!
//! A quantile `q` of `n` values sorted as `x_0 <= .. <= x_{n-1}` is `x_k + f (x_{k+1} - x_k)`
//! with `k + f = q (n - 1)` (numpy's default, "linear"). The values of the ranks `k` are found
//! by radix selection on the floats' order-preserving bit patterns ([`key`]): one pass counts
//! the values by the upper 16 bits of their keys, which names the bucket holding each rank and
//! the rank within it; a second pass counts the values of those buckets (at most four) by the
//! lower 16 bits. Two passes over the values, 65,536 counters each, whatever the field's size;
//! 8 and 16-bit samples take one count of their stored integers ([`of_samples`]).

/// A float's bits made to sort as the float does (negative ones reversed below the positive).
#[inline(always)]
fn key(v: f32) -> u32 {
    // Without a branch: negative floats have every bit flipped, the others the sign bit.
    let b = v.to_bits();
    b ^ (((b as i32) >> 31) as u32 | 0x8000_0000)
}

/// The float of a [`key`].
fn unkey(k: u32) -> f32 {
    f32::from_bits(match k >> 31 {
        1 => k & 0x7fff_ffff,
        _ => !k,
    })
}

/// The quantiles `qs` (each in [0, 1]) of the values `values()` yields (called twice; both
/// calls must yield the same values, all finite). NaN for each when there are none.
pub fn quantiles<I: Iterator<Item = f32>>(values: impl Fn() -> I, qs: &[f64]) -> Vec<f64> {
    select(
        qs,
        || {
            let mut upper = vec![0usize; 1 << 16];
            for v in values() {
                upper[(key(v) >> 16) as usize] += 1;
            }
            upper
        },
        |buckets| {
            let mut lower = vec![vec![0usize; 1 << 16]; buckets.len()];
            for v in values() {
                count_lower(&mut lower, buckets, v);
            }
            lower
        },
    )
}

/// [`quantiles`] of the values of `d` that `keep` keeps, both passes on rayon's threads.
fn quantiles_par(d: &[f32], qs: &[f64], keep: impl Fn(f32) -> bool + Sync) -> Vec<f64> {
    use rayon::prelude::*;
    const CHUNK: usize = 1 << 18;
    let add = |mut a: Vec<usize>, b: Vec<usize>| {
        a.iter_mut().zip(b).for_each(|(x, y)| *x += y);
        a
    };
    select(
        qs,
        || {
            d.par_chunks(CHUNK)
                .fold(
                    || vec![0usize; 1 << 16],
                    |mut upper, c| {
                        for &v in c.iter().filter(|&&v| keep(v)) {
                            upper[(key(v) >> 16) as usize] += 1;
                        }
                        upper
                    },
                )
                .reduce(|| vec![0usize; 1 << 16], add)
        },
        |buckets| {
            d.par_chunks(CHUNK)
                .fold(
                    || vec![vec![0usize; 1 << 16]; buckets.len()],
                    |mut lower, c| {
                        for &v in c.iter().filter(|&&v| keep(v)) {
                            count_lower(&mut lower, buckets, v);
                        }
                        lower
                    },
                )
                .reduce(
                    || vec![vec![0usize; 1 << 16]; buckets.len()],
                    |a, b| a.into_iter().zip(b).map(|(x, y)| add(x, y)).collect(),
                )
        },
    )
}

/// Counts `v` by the lower 16 bits of its key where its upper 16 bits are one of `buckets`.
#[inline]
fn count_lower(lower: &mut [Vec<usize>], buckets: &[usize], v: f32) {
    let k = key(v);
    if let Some(i) = buckets.iter().position(|&b| b == (k >> 16) as usize) {
        lower[i][(k & 0xffff) as usize] += 1;
    }
}

/// The radix selection of [`quantiles`]: `upper()` counts the values by the upper 16 bits of
/// their keys, `lower(buckets)` by the lower 16 bits within each of `buckets`.
fn select(
    qs: &[f64],
    upper: impl FnOnce() -> Vec<usize>,
    lower: impl FnOnce(&[usize]) -> Vec<Vec<usize>>,
) -> Vec<f64> {
    let upper = upper();
    let n: usize = upper.iter().sum();
    if n == 0 {
        return vec![f64::NAN; qs.len()];
    }
    // Each quantile's ranks k and k + 1, and the bucket and the rank within it of each.
    let at: Vec<(usize, f64)> = qs
        .iter()
        .map(|&q| {
            let at = q.clamp(0.0, 1.0) * (n - 1) as f64;
            let k = (at.floor() as usize).min(n - 1);
            (k, at - k as f64)
        })
        .collect();
    let mut ranks: Vec<usize> = at
        .iter()
        .flat_map(|&(k, _)| [k, (k + 1).min(n - 1)])
        .collect();
    ranks.sort_unstable();
    ranks.dedup();
    let mut found: Vec<(usize, usize, usize)> = Vec::with_capacity(ranks.len());
    let (mut bucket, mut below) = (0usize, 0usize);
    for &r in &ranks {
        while below + upper[bucket] <= r {
            below += upper[bucket];
            bucket += 1;
        }
        found.push((r, bucket, r - below));
    }
    let mut buckets: Vec<usize> = found.iter().map(|f| f.1).collect();
    buckets.dedup();
    let lower = lower(&buckets);
    let value_of = |r: usize| {
        let &(_, b, mut within) = found.iter().find(|f| f.0 == r).expect("a rank found");
        let counts = &lower[buckets.iter().position(|&x| x == b).expect("its bucket")];
        let mut low = 0;
        while within >= counts[low] {
            within -= counts[low];
            low += 1;
        }
        unkey(((b as u32) << 16) | low as u32) as f64
    };
    at.iter()
        .map(|&(k, f)| {
            let a = value_of(k);
            if f == 0.0 || k + 1 == n {
                a
            } else {
                a + f * (value_of(k + 1) - a)
            }
        })
        .collect()
}

/// [`quantiles`] of the samples `keep` keeps (it must refuse NaN and infinities): 8 and 16-bit
/// samples by one count of each stored integer (exact, `keep` asked once per integer), `f32`
/// ones by radix selection ([`quantiles`]).
pub fn of_samples(
    s: &crate::samples::Samples,
    qs: &[f64],
    keep: impl Fn(f32) -> bool + Sync,
) -> Vec<f64> {
    use crate::samples::View;
    fn counted<T: Copy + Into<usize>>(d: &[T], codes: usize) -> Vec<usize> {
        let mut count = vec![0usize; codes];
        for &v in d {
            count[v.into()] += 1;
        }
        count
    }
    let (count, o) = match s.view() {
        View::F32(d) => return quantiles_par(d, qs, keep),
        View::U16(d, o) => (counted(d, 1 << 16), o),
        View::U8(d, o) => (counted(d, 1 << 8), o),
    };
    let count: Vec<usize> = count
        .iter()
        .enumerate()
        .map(|(c, &n)| if n > 0 && keep(c as f32 + o) { n } else { 0 })
        .collect();
    let n: usize = count.iter().sum();
    if n == 0 {
        return vec![f64::NAN; qs.len()];
    }
    // The value of rank k: the first integer whose cumulative count passes k.
    let rank = |k: usize| {
        let mut below = 0;
        for (c, &m) in count.iter().enumerate() {
            below += m;
            if below > k {
                return (c as f32 + o) as f64;
            }
        }
        unreachable!("rank {k} of {n}")
    };
    qs.iter()
        .map(|&q| {
            let at = q.clamp(0.0, 1.0) * (n - 1) as f64;
            let k = (at.floor() as usize).min(n - 1);
            let (f, a) = (at - k as f64, rank(k));
            if f == 0.0 || k + 1 == n {
                a
            } else {
                a + f * (rank(k + 1) - a)
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// numpy's "linear" quantile of `v` by sorting.
    fn sorted_quantile(v: &[f32], q: f64) -> f64 {
        let mut s = v.to_vec();
        s.sort_by(f32::total_cmp);
        let at = q * (s.len() - 1) as f64;
        let k = at.floor() as usize;
        let f = at - k as f64;
        if k + 1 >= s.len() {
            s[k] as f64
        } else {
            s[k] as f64 + f * (s[k + 1] as f64 - s[k] as f64)
        }
    }

    /// The keys sort as the floats do, over random bit patterns (every sign, exponent,
    /// subnormals, both zeros and the infinities), and give the floats back.
    #[test]
    fn keys_sort_as_their_floats() {
        let mut seed = 0x1234_5678_9abc_def1u64;
        let mut v: Vec<f32> = (0..200_000)
            .map(|_| {
                seed ^= seed << 13;
                seed ^= seed >> 7;
                seed ^= seed << 17;
                f32::from_bits((seed >> 32) as u32)
            })
            .filter(|x| !x.is_nan())
            .chain([
                0.0,
                -0.0,
                f32::MIN_POSITIVE,
                -1e-45,
                f32::INFINITY,
                f32::NEG_INFINITY,
            ])
            .collect();
        for &x in &v {
            assert_eq!(unkey(key(x)).to_bits(), x.to_bits());
        }
        v.sort_by_key(|&x| key(x));
        assert!(v.windows(2).all(|w| w[0] <= w[1]));
    }

    /// Against sorting, exactly: a few values, a field of outliers (the case the robust range
    /// is for), ties, a constant field, values that share their upper 16 bits, and the ends.
    #[test]
    fn quantiles_are_those_of_the_sorted_values() {
        let mut seed = 0x9e37_79b9_7f4a_7c15u64;
        let mut rnd = || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        let small: Vec<f32> = (0..1000).map(|_| rnd() as f32).collect();
        let mut outliers: Vec<f32> = (0..400_000).map(|_| (rnd() * 2.0 - 1.0) as f32).collect();
        outliers[17] = 1e11;
        outliers[99] = -2e10;
        let ties: Vec<f32> = (0..300_000).map(|i| (i % 7) as f32).collect();
        let constant = vec![3.5f32; 200_000];
        let fine: Vec<f32> = (0..300_000).map(|_| 1.0 + (rnd() * 1e-6) as f32).collect();
        let qs = [0.0, 0.02, 0.25, 0.5, 0.98, 0.999, 1.0];
        for (name, v) in [
            ("small", &small),
            ("outliers", &outliers),
            ("ties", &ties),
            ("constant", &constant),
            ("fine", &fine),
        ] {
            let got = quantiles(|| v.iter().copied(), &qs);
            for (q, g) in qs.iter().zip(&got) {
                let want = sorted_quantile(v, *q);
                assert!(
                    (g - want).abs() <= 1e-12 * want.abs().max(1.0),
                    "{name} q {q}: {g} against {want}"
                );
            }
        }
        assert!(quantiles(std::iter::empty, &[0.5])[0].is_nan());
        // Packed in 8 and 16 bits (with an offset) and as f32 with NaN, through `of_samples`,
        // the same; `keep` leaves values out.
        let ints: Vec<f32> = (0..50_000)
            .map(|_| (rnd() * 200.0).floor() as f32 - 7.0)
            .collect();
        let wide: Vec<f32> = (0..50_000)
            .map(|_| (rnd() * 60_000.0).floor() as f32 + 3.0)
            .collect();
        let (mut ints, mut wide, mut gaps) = (ints, wide, small.clone());
        (ints[0], wide[0], gaps[3]) = (-7.0, 3.0, f32::NAN);
        for (v, packing) in [
            (&ints, crate::samples::Packing::U8 { offset: -7.0 }),
            (&wide, crate::samples::Packing::U16 { offset: 3.0 }),
            (&gaps, crate::samples::Packing::F32),
        ] {
            let s = crate::samples::Samples::pack(v.clone());
            assert_eq!(s.packing(), packing);
            let kept: Vec<f32> = v
                .iter()
                .copied()
                .filter(|x| x.is_finite() && *x != 50.0)
                .collect();
            let got = of_samples(&s, &qs, |x| x.is_finite() && x != 50.0);
            for (q, g) in qs.iter().zip(&got) {
                let want = sorted_quantile(&kept, *q);
                assert!(
                    (g - want).abs() <= 1e-9 * want.abs().max(1.0),
                    "{packing:?} q {q}: {g} {want}"
                );
            }
        }
        assert_eq!(
            quantiles(|| [2.0f32].into_iter(), &[0.0, 0.5, 1.0]),
            [2.0; 3]
        );
    }
}
