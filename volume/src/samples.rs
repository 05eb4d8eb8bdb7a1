//! A scalar field's samples as the renderers hold them, on the CPU and on the GPU alike: `f32`,
//! or integers in 16 or 8 bits above an offset when every sample is an integer within 65,536
//! (or 256) of the smallest one - the stored type of most scanner and CT volumes, read back
//! exactly. One layout for both sides: the samples packed in 32-bit words, sample `l` of a
//! 16-bit volume in bits `16 (l % 2)..` of word `l / 2` (8-bit: bits `8 (l % 4)..` of word
//! `l / 4`), which is the little-endian byte order of a `u16` (`u8`) array, so the CPU reads
//! the words as `&[u16]` (`&[u8]`) and the GPU upload is the words themselves, no copy.
//!
//! [`Samples::pack`] narrows a `Vec<f32>` in place (the words reuse its allocation, which is
//! then shrunk): a 16-bit volume never needs more than its `f32` size while it is packed, and
//! half of it after.

use std::borrow::Cow;

#[cfg(target_endian = "big")]
compile_error!("volume::samples packs samples in little-endian words");

/// How a field's samples are packed in 32-bit words: `f32`, or integers in 16 or 8 bits plus an
/// offset (value = integer + offset).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Packing {
    F32,
    U16 { offset: f32 },
    U8 { offset: f32 },
}

impl Packing {
    /// The packing `data` allows (NaN, infinite, fractional or out-of-range samples, or
    /// integers beyond 2^24: f32).
    pub fn of(data: &[f32]) -> Packing {
        if data.is_empty() {
            return Packing::F32;
        }
        let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
        for &v in data {
            // Integers exactly representable in f32 only.
            if !(v.abs() < 16_777_216.0 && v == v.trunc()) {
                return Packing::F32;
            }
            lo = lo.min(v);
            hi = hi.max(v);
        }
        match hi - lo {
            r if r < 256.0 => Packing::U8 { offset: lo },
            r if r < 65_536.0 => Packing::U16 { offset: lo },
            _ => Packing::F32,
        }
    }

    /// Samples a 32-bit word holds.
    pub fn per_word(self) -> usize {
        match self {
            Packing::F32 => 1,
            Packing::U16 { .. } => 2,
            Packing::U8 { .. } => 4,
        }
    }

    /// The shaders' code for the packing: 0 f32, 1 two u16, 2 four u8.
    pub fn code(self) -> u32 {
        match self {
            Packing::F32 => 0,
            Packing::U16 { .. } => 1,
            Packing::U8 { .. } => 2,
        }
    }

    /// What is added to a packed integer to give its value (0 for f32).
    pub fn offset(self) -> f32 {
        match self {
            Packing::F32 => 0.0,
            Packing::U16 { offset } | Packing::U8 { offset } => offset,
        }
    }
}

/// A stored sample type the renderers read: `u8`, `u16` or `f32`.
pub trait Sample: Copy + Send + Sync + 'static {
    /// The sample as a float (before any offset).
    fn value(self) -> f32;
}

impl Sample for u8 {
    #[inline(always)]
    fn value(self) -> f32 {
        self as f32
    }
}

impl Sample for u16 {
    #[inline(always)]
    fn value(self) -> f32 {
        self as f32
    }
}

impl Sample for f32 {
    #[inline(always)]
    fn value(self) -> f32 {
        self
    }
}

/// The samples as a typed slice (x fastest, exactly [`Samples::len`] of them) and the offset
/// added to each: what a CPU loop is monomorphized over.
#[derive(Clone, Copy, Debug)]
pub enum View<'a> {
    F32(&'a [f32]),
    U16(&'a [u16], f32),
    U8(&'a [u8], f32),
}

/// A scalar field's samples, packed as [`Packing`] says.
#[derive(Clone, Debug, PartialEq)]
pub struct Samples {
    words: Vec<u32>,
    len: usize,
    packing: Packing,
}

impl Samples {
    /// `data` packed in the narrowest [`Packing`] it allows, in place: the words reuse the
    /// vector's allocation and are shrunk to their length (no second copy of the volume).
    pub fn pack(data: Vec<f32>) -> Samples {
        let packing = Packing::of(&data);
        Samples::pack_as(data, packing)
    }

    /// `data` kept as `f32`.
    pub fn f32(data: Vec<f32>) -> Samples {
        Samples::pack_as(data, Packing::F32)
    }

    /// `data` packed as `packing`, in place; `packing` must hold every sample (as
    /// [`Packing::of`] decides, or any packing whose range covers the samples).
    pub fn pack_as(data: Vec<f32>, packing: Packing) -> Samples {
        let len = data.len();
        let mut words: Vec<u32> = bytemuck::allocation::cast_vec(data);
        let o = packing.offset();
        match packing {
            Packing::F32 => {}
            Packing::U16 { .. } => {
                // Sample i's f32 occupies halves 2i and 2i + 1; its u16 goes to half i <= 2i,
                // whose f32 was read at step i / 2 <= i: ascending order never overwrites a
                // sample not yet read.
                let h: &mut [u16] = bytemuck::cast_slice_mut(&mut words);
                for i in 0..len {
                    let v = f32::from_bits(h[2 * i] as u32 | (h[2 * i + 1] as u32) << 16);
                    h[i] = (v - o) as u16;
                }
                if len % 2 == 1 {
                    h[len] = 0;
                }
                words.truncate(len.div_ceil(2));
            }
            Packing::U8 { .. } => {
                let b: &mut [u8] = bytemuck::cast_slice_mut(&mut words);
                for i in 0..len {
                    let v = f32::from_bits(u32::from_le_bytes([
                        b[4 * i],
                        b[4 * i + 1],
                        b[4 * i + 2],
                        b[4 * i + 3],
                    ]));
                    b[i] = (v - o) as u8;
                }
                for x in &mut b[len..len.next_multiple_of(4)] {
                    *x = 0;
                }
                words.truncate(len.div_ceil(4));
            }
        }
        words.shrink_to_fit();
        Samples {
            words,
            len,
            packing,
        }
    }

    /// `len` samples of `packing` written by `fill` into zeroed words, seen as the packing's
    /// type `T` (`f32`, `u16` or `u8`: sample `i` at element `i`). For copies made straight in
    /// a narrow type, without an `f32` copy of them first.
    ///
    /// # Panics
    /// If `T` is not the packing's width (4, 2 or 1 bytes).
    pub fn from_fill<T: bytemuck::Pod>(
        len: usize,
        packing: Packing,
        fill: impl FnOnce(&mut [T]),
    ) -> Samples {
        assert_eq!(
            std::mem::size_of::<T>() * packing.per_word(),
            4,
            "samples of {packing:?} are not {} bytes",
            std::mem::size_of::<T>()
        );
        let mut words = vec![0u32; len.div_ceil(packing.per_word())];
        fill(&mut bytemuck::cast_slice_mut::<u32, T>(&mut words)[..len]);
        Samples {
            words,
            len,
            packing,
        }
    }

    /// 8 or 16-bit integer samples as a file stores them (`ty`; `big_endian` or little), in
    /// that type: `uint8`/`uint16` as they are, `int8`/`int16` above -128/-32,768 (their sign
    /// bit flipped). `Ok(None)` for other types; an error when the memory cannot be had.
    pub fn from_stored(
        bytes: &[u8],
        ty: crate::ScalarType,
        big_endian: bool,
    ) -> Result<Option<Samples>, std::collections::TryReserveError> {
        use crate::ScalarType as T;
        let (packing, size) = match ty {
            T::U8 => (Packing::U8 { offset: 0.0 }, 1),
            T::I8 => (Packing::U8 { offset: -128.0 }, 1),
            T::U16 => (Packing::U16 { offset: 0.0 }, 2),
            T::I16 => (Packing::U16 { offset: -32_768.0 }, 2),
            _ => return Ok(None),
        };
        let len = bytes.len() / size;
        let n = len.div_ceil(packing.per_word());
        let mut words: Vec<u32> = Vec::new();
        words.try_reserve_exact(n)?;
        // Huge pages before the first touch: a ray's samples in the grid's layout lie a plane
        // apart (512 KiB at 512^2 x 16 bits), one 4 KiB page each without them.
        crate::memory::advise_huge(words.spare_capacity_mut());
        words.resize(n, 0);
        let out: &mut [u8] = bytemuck::cast_slice_mut(&mut words);
        let bytes = &bytes[..len * size];
        out[..bytes.len()].copy_from_slice(bytes);
        let out = &mut out[..bytes.len()];
        match (ty, big_endian) {
            (T::U8, _) => {}
            (T::I8, _) => out.iter_mut().for_each(|b| *b ^= 0x80),
            (T::U16, false) => {}
            (T::U16, true) => out.chunks_exact_mut(2).for_each(|c| c.swap(0, 1)),
            (T::I16, false) => out.chunks_exact_mut(2).for_each(|c| c[1] ^= 0x80),
            (T::I16, true) => out.chunks_exact_mut(2).for_each(|c| {
                c.swap(0, 1);
                c[1] ^= 0x80;
            }),
            _ => unreachable!("8 and 16-bit types only"),
        }
        Ok(Some(Samples {
            words,
            len,
            packing,
        }))
    }

    /// The values as a vector of `f32` (the words themselves when they are `f32`).
    pub fn into_f32(self) -> Vec<f32> {
        match self.packing {
            Packing::F32 => bytemuck::allocation::cast_vec(self.words),
            _ => self.values().collect(),
        }
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.len
    }

    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    pub fn packing(&self) -> Packing {
        self.packing
    }

    /// The packed words (what the GPU binds; unused bits of the last word are 0).
    pub fn words(&self) -> &[u32] {
        &self.words
    }

    /// Bytes the samples occupy.
    pub fn bytes(&self) -> usize {
        self.words.len() * 4
    }

    /// The samples as a typed slice and offset.
    pub fn view(&self) -> View<'_> {
        let o = self.packing.offset();
        match self.packing {
            Packing::F32 => View::F32(bytemuck::cast_slice(&self.words)),
            Packing::U16 { .. } => View::U16(
                &bytemuck::cast_slice::<u32, u16>(&self.words)[..self.len],
                o,
            ),
            Packing::U8 { .. } => {
                View::U8(&bytemuck::cast_slice::<u32, u8>(&self.words)[..self.len], o)
            }
        }
    }

    /// Sample `i`'s value.
    #[inline]
    pub fn get(&self, i: usize) -> f32 {
        match self.view() {
            View::F32(d) => d[i],
            View::U16(d, o) => d[i] as f32 + o,
            View::U8(d, o) => d[i] as f32 + o,
        }
    }

    /// The values in order.
    pub fn values(&self) -> Values<'_> {
        match self.view() {
            View::F32(d) => Values::F32(d.iter()),
            View::U16(d, o) => Values::U16(d.iter(), o),
            View::U8(d, o) => Values::U8(d.iter(), o),
        }
    }

    /// Finite minimum and maximum and the count of NaN or infinite samples.
    pub fn stats(&self) -> crate::FieldStats {
        fn of<T: Sample>(d: &[T], o: f32) -> crate::FieldStats {
            let (mut lo, mut hi, mut bad) = (f32::INFINITY, f32::NEG_INFINITY, 0usize);
            for &v in d {
                let v = v.value();
                if v.is_finite() {
                    lo = lo.min(v);
                    hi = hi.max(v);
                } else {
                    bad += 1;
                }
            }
            let (min, max) = match lo <= hi {
                true => (lo as f64 + o as f64, hi as f64 + o as f64),
                false => (f64::NAN, f64::NAN),
            };
            crate::FieldStats {
                min,
                max,
                nonfinite: bad,
            }
        }
        match self.view() {
            View::F32(d) => of(d, 0.0),
            View::U16(d, o) => of(d, o),
            View::U8(d, o) => of(d, o),
        }
    }

    /// The values as `f32` (borrowed when they are stored so, else converted).
    pub fn to_f32(&self) -> Cow<'_, [f32]> {
        match self.view() {
            View::F32(d) => Cow::Borrowed(d),
            _ => Cow::Owned(self.values().collect()),
        }
    }
}

impl From<Vec<f32>> for Samples {
    /// [`Samples::pack`].
    fn from(data: Vec<f32>) -> Samples {
        Samples::pack(data)
    }
}

/// The iterator of [`Samples::values`].
pub enum Values<'a> {
    F32(std::slice::Iter<'a, f32>),
    U16(std::slice::Iter<'a, u16>, f32),
    U8(std::slice::Iter<'a, u8>, f32),
}

impl Iterator for Values<'_> {
    type Item = f32;

    #[inline]
    fn next(&mut self) -> Option<f32> {
        match self {
            Values::F32(i) => i.next().copied(),
            Values::U16(i, o) => i.next().map(|&v| v as f32 + *o),
            Values::U8(i, o) => i.next().map(|&v| v as f32 + *o),
        }
    }

    fn size_hint(&self) -> (usize, Option<usize>) {
        match self {
            Values::F32(i) => i.size_hint(),
            Values::U16(i, _) => i.size_hint(),
            Values::U8(i, _) => i.size_hint(),
        }
    }
}

impl ExactSizeIterator for Values<'_> {}

#[cfg(test)]
mod tests {
    use super::*;

    /// The shader's `voxel`, on the CPU: sample `l` of the packed words.
    fn unpack(p: Packing, words: &[u32], l: usize) -> f32 {
        match p {
            Packing::F32 => f32::from_bits(words[l]),
            Packing::U16 { offset } => ((words[l / 2] >> (16 * (l % 2))) & 0xFFFF) as f32 + offset,
            Packing::U8 { offset } => ((words[l / 4] >> (8 * (l % 4))) & 0xFF) as f32 + offset,
        }
    }

    #[test]
    fn integer_volumes_pack_into_8_or_16_bits_and_read_back_exactly() {
        let u8s: Vec<f32> = (0..1001).map(|i| (i * 37 % 256) as f32 - 40.0).collect();
        let u16s: Vec<f32> = (0..1001)
            .map(|i| (i * 977 % 65_536) as f32 + 1000.0)
            .collect();
        let floats: Vec<f32> = (0..1001).map(|i| i as f32 * 0.5).collect();
        let wide: Vec<f32> = vec![0.0, 65_536.0];
        let gaps: Vec<f32> = vec![1.0, -3e38, 2.0];
        assert_eq!(Packing::of(&u8s), Packing::U8 { offset: -40.0 });
        assert_eq!(Packing::of(&u16s), Packing::U16 { offset: 1000.0 });
        assert_eq!(Packing::of(&floats), Packing::F32);
        assert_eq!(Packing::of(&wide), Packing::F32);
        assert_eq!(
            Packing::of(&gaps),
            Packing::F32,
            "the NaN stand-in stays f32"
        );
        assert_eq!(
            Packing::of(&[2.0e7, 2.0e7 + 2.0]),
            Packing::F32,
            "beyond 2^24"
        );
        // Every length modulo 4, so the last word's padding is exercised.
        for data in [&u8s, &u16s, &floats] {
            for cut in [0, 1, 2, 3] {
                let data = &data[..data.len() - cut];
                let p = Packing::of(data);
                let s = Samples::pack(data.to_vec());
                assert_eq!(s.packing(), p);
                assert_eq!(s.len(), data.len());
                assert_eq!(s.words().len(), data.len().div_ceil(p.per_word()));
                assert_eq!(s.bytes(), 4 * data.len().div_ceil(p.per_word()));
                for (l, &v) in data.iter().enumerate() {
                    assert_eq!(unpack(p, s.words(), l), v, "{p:?} sample {l}");
                    assert_eq!(s.get(l), v, "{p:?} sample {l}");
                }
                assert_eq!(s.values().collect::<Vec<_>>(), data);
                assert_eq!(&*s.to_f32(), data);
                assert_eq!(s.clone().into_f32(), data);
                // The padding is zero: equal data hash equally.
                let last = *s.words().last().unwrap_or(&0);
                let used = (data.len() % p.per_word()) as u32 * (32 / p.per_word() as u32);
                if used > 0 {
                    assert_eq!(last >> used, 0, "{p:?} padding");
                }
            }
        }
    }

    #[test]
    fn stored_integers_are_read_in_their_type_with_either_byte_order() {
        use crate::ScalarType as T;
        let values: Vec<i32> = vec![-32768, -1000, -1, 0, 1, 255, 32767];
        for big in [false, true] {
            let i16s: Vec<u8> = values
                .iter()
                .flat_map(|&v| match big {
                    true => (v as i16).to_be_bytes(),
                    false => (v as i16).to_le_bytes(),
                })
                .collect();
            let s = Samples::from_stored(&i16s, T::I16, big).unwrap().unwrap();
            assert_eq!(s.packing(), Packing::U16 { offset: -32768.0 });
            let want: Vec<f32> = values.iter().map(|&v| v as f32).collect();
            assert_eq!(s.values().collect::<Vec<_>>(), want, "int16 big {big}");
            let u16s: Vec<u8> = [0u16, 1, 258, 65535]
                .iter()
                .flat_map(|&v| match big {
                    true => v.to_be_bytes(),
                    false => v.to_le_bytes(),
                })
                .collect();
            let s = Samples::from_stored(&u16s, T::U16, big).unwrap().unwrap();
            assert_eq!(s.values().collect::<Vec<_>>(), [0.0, 1.0, 258.0, 65535.0]);
        }
        let i8s: Vec<u8> = [-128i8, -1, 0, 127, 5].iter().map(|&v| v as u8).collect();
        let s = Samples::from_stored(&i8s, T::I8, false).unwrap().unwrap();
        assert_eq!(
            s.values().collect::<Vec<_>>(),
            [-128.0, -1.0, 0.0, 127.0, 5.0]
        );
        assert_eq!(s.words().len(), 2);
        assert_eq!(s.words()[1] >> 8, 0, "zero padding");
        let s = Samples::from_stored(&[7, 200, 3], T::U8, true)
            .unwrap()
            .unwrap();
        assert_eq!(s.values().collect::<Vec<_>>(), [7.0, 200.0, 3.0]);
        assert!(Samples::from_stored(&[0; 8], T::F32, false)
            .unwrap()
            .is_none());
        assert!(Samples::from_stored(&[0; 8], T::U32, false)
            .unwrap()
            .is_none());
    }
}
