//! Compact keys: a canonical simplex packed into a few 64-bit words (the set of such keys is
//! [`KeySet`](super::KeySet)).

use std::ops::{BitOr, Shl, Shr};

use super::simplex::{check_dim, Simplex, MAX_DIM};
use crate::error::{Error, Result};

/// Packs canonical l-simplices of R^d into `words()` u64 words: each base coordinate biased
/// into `coord_bits` bits, then the part index of elements 1..d (d+1 is always in the last
/// part) in ceil(log2(l+1)) bits each.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct KeyCodec {
    d: usize,
    l: usize,
    coord_bits: u32,
    part_bits: u32,
    words: usize,
}

impl KeyCodec {
    /// A codec for l-simplices of R^d with `coord_bits` (2..=32) bits per base coordinate.
    pub fn new(d: usize, l: usize, coord_bits: u32) -> Result<Self> {
        check_dim(d)?;
        if l > d {
            return Err(Error::InvalidSimplex(format!("no {l}-simplices in R^{d}")));
        }
        if !(2..=32).contains(&coord_bits) {
            return Err(Error::InvalidSimplex(format!(
                "coord_bits = {coord_bits}: must be 2 to 32"
            )));
        }
        let part_bits = usize::BITS - l.leading_zeros();
        let bits = d * coord_bits as usize + d * part_bits as usize;
        Ok(KeyCodec {
            d,
            l,
            coord_bits,
            part_bits,
            words: bits.div_ceil(64).max(1),
        })
    }

    /// Number of u64 words per key.
    #[inline]
    pub fn words(&self) -> usize {
        self.words
    }

    /// Packs `s` into `out[..words()]`; fails if a coordinate does not fit `coord_bits`.
    #[inline]
    pub fn encode(&self, s: &Simplex, out: &mut [u64]) -> Result<()> {
        self.check_simplex(s)?;
        self.encode_masks(s.base(), s.parts(), out)
    }

    /// [`KeyCodec::encode`] of the simplex with base `v0` and ordered partition `parts`
    /// (masks of elements 0..=d, element d in the last part), given as they are, without
    /// building the simplex: for the crate's callers that hold a valid partition already
    /// (nothing is checked but the coordinates' range).
    #[inline]
    pub(crate) fn encode_masks(&self, v0: &[i32], parts: &[u64], out: &mut [u64]) -> Result<()> {
        debug_assert_eq!(parts.len(), self.l + 1);
        self.encode_vertex(v0, out)?;
        // Element e's part index goes at bit base + e * part_bits; encode_vertex left those
        // bits clear, so part 0 writes nothing and element d (always in the last part) is
        // not written.
        let base = self.d * self.coord_bits as usize;
        let out = &mut out[..self.words];
        let below_d = (1u64 << self.d) - 1;
        for (p, &mask) in parts.iter().enumerate().skip(1) {
            let mut m = mask & below_d;
            while m != 0 {
                let e = m.trailing_zeros() as usize;
                let mut w = BitWriter {
                    out: &mut *out,
                    pos: base + e * self.part_bits as usize,
                };
                w.put(p as u64, self.part_bits);
                m &= m - 1;
            }
        }
        Ok(())
    }

    /// Unpacks a key written by [`KeyCodec::encode`] (no heap allocation).
    pub fn decode(&self, key: &[u64]) -> Simplex {
        let mut s = self.scratch();
        self.decode_into(key, &mut s);
        s
    }

    /// A simplex of this codec's R^d to decode into with [`KeyCodec::decode_into`]: one per
    /// thread, reused, saves building a new simplex per key.
    pub fn scratch(&self) -> Simplex {
        Simplex::vertex(&[0; MAX_DIM][..self.d]).expect("the codec's d is valid")
    }

    /// Unpacks a key into `out`, reusing its storage (no validation: keys come from
    /// [`KeyCodec::encode`]).
    pub fn decode_into(&self, key: &[u64], out: &mut Simplex) {
        let bias = 1i64 << (self.coord_bits - 1);
        let mut r = BitReader { words: key, pos: 0 };
        let (v0, parts) = out.reset_clear(self.d, self.l + 1);
        for c in v0.iter_mut() {
            *c = (r.get(self.coord_bits) as i64 - bias) as i32;
        }
        parts[self.l] |= 1 << self.d;
        for e in 0..self.d {
            let p = if self.part_bits > 0 {
                r.get(self.part_bits) as usize
            } else {
                0
            };
            parts[p] |= 1 << e;
        }
    }

    /// Bits per base coordinate.
    pub fn coord_bits(&self) -> u32 {
        self.coord_bits
    }

    /// Ambient dimension d.
    pub fn ambient_dim(&self) -> usize {
        self.d
    }

    /// Bits of each element's part index (elements 0..d; element d is always in the last
    /// part and not written).
    pub(crate) fn part_bits(&self) -> u32 {
        self.part_bits
    }

    /// Dimension l of the simplices it packs.
    pub fn simplex_dim(&self) -> usize {
        self.l
    }

    /// Packs a lattice vertex (d coordinates, `coord_bits` each) into `out[..words()]`: the
    /// same layout as the base-vertex field of a key.
    pub fn encode_vertex(&self, v: &[i32], out: &mut [u64]) -> Result<()> {
        let out = &mut out[..self.words];
        out.fill(0);
        let bits = self.coord_bits;
        let bias = 1i64 << (bits - 1);
        // One test for all coordinates: a biased value out of range has a bit at or above
        // `bits` (a negative one has them all).
        let mut spill = 0u64;
        // The word being filled, its index, and the bits used in it.
        let (mut acc, mut w, mut pos) = (0u64, 0usize, 0u32);
        for &c in &v[..self.d] {
            let x = (c as i64 + bias) as u64;
            spill |= x >> bits;
            let x = x & ((1u64 << bits) - 1);
            acc |= x << pos;
            pos += bits;
            if pos >= 64 {
                out[w] = acc;
                w += 1;
                pos -= 64;
                // The bits of x that did not fit (none when it ended the word exactly).
                acc = if pos == 0 { 0 } else { x >> (bits - pos) };
            }
        }
        if pos > 0 {
            out[w] = acc;
        }
        if spill != 0 {
            return Err(self.overflow(v));
        }
        Ok(())
    }

    /// The error for a vertex with a coordinate that does not fit `coord_bits`.
    #[cold]
    fn overflow(&self, v: &[i32]) -> Error {
        let bits = self.coord_bits;
        let bias = 1i64 << (bits - 1);
        let c = v[..self.d]
            .iter()
            .find(|&&c| (c as i64 + bias) as u64 >> bits != 0)
            .expect("a coordinate spilled");
        Error::KeyOverflow {
            value: *c as i64,
            bits,
        }
    }

    /// Unpacks a vertex written by [`KeyCodec::encode_vertex`] into `out` (d coordinates).
    pub fn decode_vertex(&self, key: &[u64], out: &mut [i32]) {
        let bias = 1i64 << (self.coord_bits - 1);
        let mut r = BitReader { words: key, pos: 0 };
        for c in out.iter_mut().take(self.d) {
            *c = (r.get(self.coord_bits) as i64 - bias) as i32;
        }
    }

    // Keys of a width known at compile time (the tracing loop's): those of one word are
    // packed and unpacked in a u64, those of two in a u128, bit for bit the layout above;
    // wider ones take the general path.

    /// [`KeyCodec::encode`] into a key of `W` words (`W` = [`KeyCodec::words`]).
    #[inline]
    pub(crate) fn encode_w<const W: usize>(&self, s: &Simplex, out: &mut [u64; W]) -> Result<()> {
        if W > 2 {
            return self.encode(s, out);
        }
        debug_assert_eq!(self.words, W);
        self.check_simplex(s)?;
        self.encode_masks_w(s.base(), s.parts(), out)
    }

    /// [`KeyCodec::encode_masks`] into a key of `W` words (`W` = [`KeyCodec::words`]).
    #[inline]
    pub(crate) fn encode_masks_w<const W: usize>(
        &self,
        v0: &[i32],
        parts: &[u64],
        out: &mut [u64; W],
    ) -> Result<()> {
        if W > 2 {
            return self.encode_masks(v0, parts, out);
        }
        debug_assert_eq!((parts.len(), self.words), (self.l + 1, W));
        *out = if W == 1 {
            split_words(u128::from(self.pack_masks::<u64>(v0, parts)?))
        } else {
            split_words(self.pack_masks::<u128>(v0, parts)?)
        };
        Ok(())
    }

    /// A key of at most two words packed in `A`: the base vertex `v0`, then the part index
    /// of each element but d of the partition `parts`.
    #[inline]
    fn pack_masks<A: Packed>(&self, v0: &[i32], parts: &[u64]) -> Result<A> {
        let mut acc = self.pack_vertex::<A>(v0)?;
        let base = self.d as u32 * self.coord_bits;
        let below_d = (1u64 << self.d) - 1;
        for (p, &mask) in parts.iter().enumerate().skip(1) {
            let mut m = mask & below_d;
            while m != 0 {
                acc = acc | A::from(p as u64) << (base + m.trailing_zeros() * self.part_bits);
                m &= m - 1;
            }
        }
        Ok(acc)
    }

    /// [`KeyCodec::encode_vertex`] into a key of `W` words (`W` = [`KeyCodec::words`]).
    #[inline]
    pub(crate) fn encode_vertex_w<const W: usize>(
        &self,
        v: &[i32],
        out: &mut [u64; W],
    ) -> Result<()> {
        if W > 2 {
            return self.encode_vertex(v, out);
        }
        debug_assert_eq!(self.words, W);
        *out = if W == 1 {
            split_words(u128::from(self.pack_vertex::<u64>(v)?))
        } else {
            split_words(self.pack_vertex::<u128>(v)?)
        };
        Ok(())
    }

    /// [`KeyCodec::decode_into`] of a key of `W` words (`W` = [`KeyCodec::words`]).
    #[inline]
    pub(crate) fn decode_into_w<const W: usize>(&self, key: &[u64; W], out: &mut Simplex) {
        if W > 2 {
            return self.decode_into(key, out);
        }
        debug_assert_eq!(self.words, W);
        if W == 1 {
            self.unpack_simplex(key[0], out);
        } else {
            self.unpack_simplex(join_words(key), out);
        }
    }

    /// [`KeyCodec::decode_into`] of a key of at most two words packed in `acc`.
    #[inline]
    fn unpack_simplex<A: Packed>(&self, acc: A, out: &mut Simplex) {
        let (bits, pbits) = (self.coord_bits, self.part_bits);
        let (v0, parts) = out.reset_clear(self.d, self.l + 1);
        unpack_vertex(acc, bits, v0);
        parts[self.l] |= 1 << self.d;
        if pbits == 0 {
            parts[0] |= (1 << self.d) - 1;
            return;
        }
        let (base, low) = (self.d as u32 * bits, (1u64 << pbits) - 1);
        for e in 0..self.d {
            let p = ((acc >> (base + e as u32 * pbits)).low() & low) as usize;
            parts[p] |= 1 << e;
        }
    }

    /// [`KeyCodec::decode_vertex`] of a key of `W` words (`W` = [`KeyCodec::words`]).
    #[inline]
    pub(crate) fn decode_vertex_w<const W: usize>(&self, key: &[u64; W], out: &mut [i32]) {
        if W > 2 {
            return self.decode_vertex(key, out);
        }
        debug_assert_eq!(self.words, W);
        let out = &mut out[..self.d];
        if W == 1 {
            unpack_vertex(key[0], self.coord_bits, out);
        } else {
            unpack_vertex(join_words(key), self.coord_bits, out);
        }
    }

    /// The base-vertex field of a key of at most two words, packed in `A`, or the overflow
    /// error.
    #[inline]
    fn pack_vertex<A: Packed>(&self, v: &[i32]) -> Result<A> {
        let bits = self.coord_bits;
        let bias = 1i64 << (bits - 1);
        let low = (1u64 << bits) - 1;
        // One test for all coordinates, as in `encode_vertex`.
        let (mut acc, mut spill, mut pos) = (A::default(), 0u64, 0u32);
        for &c in &v[..self.d] {
            let x = (c as i64 + bias) as u64;
            spill |= x >> bits;
            acc = acc | A::from(x & low) << pos;
            pos += bits;
        }
        if spill != 0 {
            return Err(self.overflow(v));
        }
        Ok(acc)
    }

    /// The error for a simplex of another dimension than the codec's.
    #[inline]
    fn check_simplex(&self, s: &Simplex) -> Result<()> {
        if s.ambient_dim() != self.d || s.dim() != self.l {
            return Err(Error::InvalidSimplex(format!(
                "codec for {}-simplices of R^{}, got a {}-simplex of R^{}",
                self.l,
                self.d,
                s.dim(),
                s.ambient_dim()
            )));
        }
        Ok(())
    }
}

/// The low `W` (at most two) words of `acc`, the first word least significant.
#[inline]
fn split_words<const W: usize>(acc: u128) -> [u64; W] {
    let mut out = [0u64; W];
    for (i, o) in out.iter_mut().enumerate().take(2) {
        *o = (acc >> (64 * i)) as u64;
    }
    out
}

/// The first (at most two) words of `key` as one integer, the first least significant.
#[inline]
fn join_words<const W: usize>(key: &[u64; W]) -> u128 {
    key.iter()
        .take(2)
        .enumerate()
        .fold(0, |a, (i, &w)| a | u128::from(w) << (64 * i))
}

/// The base coordinates (`out.len()` of them, `bits` each, biased) of a packed key.
#[inline]
fn unpack_vertex<A: Packed>(acc: A, bits: u32, out: &mut [i32]) {
    let bias = 1i64 << (bits - 1);
    let low = (1u64 << bits) - 1;
    for (i, c) in out.iter_mut().enumerate() {
        *c = (((acc >> (i as u32 * bits)).low() & low) as i64 - bias) as i32;
    }
}

/// The integer a key of at most two words is packed in: `u64` for one word, whose shifts
/// are single instructions, `u128` for two. Shifts stay below the key's bits.
trait Packed:
    Copy
    + Default
    + From<u64>
    + BitOr<Output = Self>
    + Shl<u32, Output = Self>
    + Shr<u32, Output = Self>
{
    /// The low 64 bits.
    fn low(self) -> u64;
}

impl Packed for u64 {
    #[inline]
    fn low(self) -> u64 {
        self
    }
}

impl Packed for u128 {
    #[inline]
    fn low(self) -> u64 {
        self as u64
    }
}

struct BitWriter<'a> {
    out: &'a mut [u64],
    pos: usize,
}

impl BitWriter<'_> {
    #[inline]
    fn put(&mut self, v: u64, bits: u32) {
        let (w, off) = (self.pos / 64, (self.pos % 64) as u32);
        self.out[w] |= v << off;
        if off + bits > 64 {
            self.out[w + 1] |= v >> (64 - off);
        }
        self.pos += bits as usize;
    }
}

struct BitReader<'a> {
    words: &'a [u64],
    pos: usize,
}

impl BitReader<'_> {
    #[inline]
    fn get(&mut self, bits: u32) -> u64 {
        let (w, off) = (self.pos / 64, (self.pos % 64) as u32);
        let mut v = self.words[w] >> off;
        if off + bits > 64 {
            v |= self.words[w + 1] << (64 - off);
        }
        self.pos += bits as usize;
        if bits == 64 {
            v
        } else {
            v & ((1u64 << bits) - 1)
        }
    }
}

#[cfg(test)]
mod tests {
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    use super::super::test_support::{random_partition, random_simplex};
    use super::*;

    /// Bits needed to write the part indices 0..=l, counted the slow way.
    fn part_bits(l: usize) -> usize {
        (0..).find(|&b| (1usize << b) > l).unwrap()
    }

    #[test]
    fn a_key_has_the_words_its_fields_need() {
        for d in 1..=MAX_DIM {
            for l in 0..=d {
                for bits in [2u32, 5, 16, 31, 32] {
                    let c = KeyCodec::new(d, l, bits).unwrap();
                    let need = d * bits as usize + d * part_bits(l);
                    assert_eq!(
                        c.words(),
                        need.div_ceil(64).max(1),
                        "d={d} l={l} bits={bits}"
                    );
                    assert_eq!(
                        (c.ambient_dim(), c.simplex_dim(), c.coord_bits()),
                        (d, l, bits)
                    );
                    assert_eq!(c.part_bits() as usize, part_bits(l), "d={d} l={l}");
                }
            }
        }
        assert_eq!(KeyCodec::new(3, 0, 21).unwrap().words(), 1);
        assert_eq!(KeyCodec::new(3, 1, 21).unwrap().words(), 2);
        assert_eq!(KeyCodec::new(3, 3, 2).unwrap().words(), 1);
    }

    #[test]
    fn bad_codecs_and_simplices_are_errors() {
        assert!(KeyCodec::new(0, 0, 8).is_err());
        assert!(KeyCodec::new(MAX_DIM + 1, 0, 8).is_err());
        assert!(KeyCodec::new(3, 4, 8).is_err());
        assert!(KeyCodec::new(3, 3, 1).is_err());
        assert!(KeyCodec::new(3, 3, 33).is_err());
        assert!(KeyCodec::new(3, 3, 2).is_ok() && KeyCodec::new(3, 3, 32).is_ok());
        let c = KeyCodec::new(3, 1, 8).unwrap();
        let mut out = [0u64; 4];
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let other_l = random_simplex(&mut rng, 3, 2, 3);
        let other_d = random_simplex(&mut rng, 4, 1, 3);
        assert!(matches!(
            c.encode(&other_l, &mut out),
            Err(Error::InvalidSimplex(_))
        ));
        assert!(matches!(
            c.encode(&other_d, &mut out),
            Err(Error::InvalidSimplex(_))
        ));
    }

    #[test]
    fn every_simplex_comes_back_from_its_key() {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let mut back = Simplex::vertex(&[0; 5]).unwrap();
        for round in 0..3000 {
            let d = 1 + round % MAX_DIM.min(if round % 3 == 0 { MAX_DIM } else { 9 });
            let l = rng.random_range(0..=d);
            let bits = [2u32, 3, 7, 13, 21, 31, 32][round % 7];
            let half = 1i64 << (bits - 1);
            let r = (half - 1).min(i32::MAX as i64 - 1) as i32;
            // A canonical partition (d+1 in the last part), so that the base stays as drawn.
            let mut parts = random_partition(&mut rng, d, l);
            let last = parts.iter().position(|p| p >> d & 1 == 1).unwrap();
            parts.rotate_left(last + 1);
            // Base coordinates over the whole range, its two ends included.
            let base: Vec<i32> = (0..d)
                .map(|_| match rng.random_range(0..4) {
                    0 => (-half) as i32,
                    1 => (half - 1) as i32,
                    _ => rng.random_range(-r..=r),
                })
                .collect();
            let s = Simplex::from_masks(&base, &parts).unwrap();
            assert_eq!(s.base(), &base[..]);
            let c = KeyCodec::new(d, l, bits).unwrap();
            // A buffer full of ones: encode must clear what it does not write.
            let mut key = vec![u64::MAX; c.words()];
            c.encode(&s, &mut key).unwrap();
            assert_eq!(c.decode(&key), s, "d={d} l={l} bits={bits}");
            c.decode_into(&key, &mut back);
            assert_eq!(back, s);
            let mut clean = vec![0u64; c.words()];
            c.encode(&s, &mut clean).unwrap();
            assert_eq!(key, clean, "the key depends on the buffer's old contents");
            // The base field of a key is the vertex's own encoding.
            let mut v = vec![u64::MAX; c.words()];
            c.encode_vertex(s.base(), &mut v).unwrap();
            let field = d * bits as usize;
            for (i, (a, b)) in key.iter().zip(&v).enumerate() {
                let keep = field.saturating_sub(64 * i).min(64);
                let mask = if keep == 64 {
                    u64::MAX
                } else {
                    (1u64 << keep) - 1
                };
                assert_eq!(a & mask, b & mask, "word {i}");
                assert_eq!(b & !mask, 0, "encode_vertex wrote past its field");
            }
            let mut w = vec![0i32; d];
            c.decode_vertex(&v, &mut w);
            assert_eq!(w, s.base());
        }
    }

    /// The fixed-width paths against the general ones on a codec of `W` words: the same
    /// key, simplex, vertex and error.
    fn fixed_width_case<const W: usize>(c: &KeyCodec, s: &Simplex, back: &mut Simplex) {
        assert_eq!(c.words(), W);
        let mut general = [0u64; W];
        let mut fixed = [u64::MAX; W];
        let at = c.encode(s, &mut general);
        let at_w = c.encode_w(s, &mut fixed);
        assert_eq!(at.is_ok(), at_w.is_ok());
        if let (Err(a), Err(b)) = (&at, &at_w) {
            assert_eq!(a.to_string(), b.to_string());
            return;
        }
        assert_eq!(fixed, general, "encode_w: {s:?}");
        let mut masks = [u64::MAX; W];
        c.encode_masks_w(s.base(), s.parts(), &mut masks).unwrap();
        assert_eq!(masks, general, "encode_masks_w");
        c.decode_into_w(&fixed, back);
        assert_eq!(back, s, "decode_into_w");
        let mut v = [0u64; W];
        let mut v_w = [u64::MAX; W];
        c.encode_vertex(s.base(), &mut v).unwrap();
        c.encode_vertex_w(s.base(), &mut v_w).unwrap();
        assert_eq!(v_w, v, "encode_vertex_w");
        let mut x = vec![0i32; s.ambient_dim()];
        c.decode_vertex_w(&v_w, &mut x);
        assert_eq!(x, s.base(), "decode_vertex_w");
    }

    #[test]
    fn fixed_width_keys_are_the_general_keys() {
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let mut back = Simplex::vertex(&[0; 3]).unwrap();
        // Cases per width, and three-word keys whose base vertex alone passes 128 bits.
        let (mut seen, mut wide_vertex) = ([0usize; 4], 0);
        for round in 0..20_000 {
            let d = 1 + round % MAX_DIM.min(12);
            let l = rng.random_range(0..=d);
            // Drawn, not cycled beside d: a cycle of 8 beside one of 12 never pairs d = 5
            // with 31 or 32 bits, the three-word keys whose vertex needs the third word.
            let bits = [2u32, 3, 5, 8, 13, 21, 31, 32][rng.random_range(0..8)];
            let c = KeyCodec::new(d, l, bits).unwrap();
            if c.words() > 3 {
                continue;
            }
            wide_vertex += usize::from(d as u32 * bits > 128);
            // Mostly in range, at times beyond it (the overflow error).
            let half = 1i64 << (bits - 1);
            let reach = if round % 5 == 0 { 2 * half } else { half - 1 };
            let reach = reach.min(i32::MAX as i64) as i32;
            let s = random_simplex(&mut rng, d, l, reach);
            match c.words() {
                1 => fixed_width_case::<1>(&c, &s, &mut back),
                2 => fixed_width_case::<2>(&c, &s, &mut back),
                _ => fixed_width_case::<3>(&c, &s, &mut back),
            }
            seen[c.words()] += 1;
        }
        assert!(
            seen[1..].iter().all(|&n| n > 500) && wide_vertex > 50,
            "cases per width: {seen:?}, vertices past 128 bits: {wide_vertex}"
        );
    }

    #[test]
    fn different_simplices_have_different_keys() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        for (d, l, bits) in [(3, 1, 4), (3, 2, 3), (5, 3, 2), (2, 2, 2), (4, 0, 3)] {
            let c = KeyCodec::new(d, l, bits).unwrap();
            let mut seen = std::collections::HashMap::new();
            for _ in 0..400 {
                let s = random_simplex(&mut rng, d, l, 1);
                let mut key = vec![0u64; c.words()];
                if c.encode(&s, &mut key).is_err() {
                    continue;
                }
                if let Some(t) = seen.insert(key, s.clone()) {
                    assert_eq!(t, s, "two simplices share a key");
                }
            }
            assert!(seen.len() > 20, "d={d} l={l}: {} keys", seen.len());
        }
    }

    #[test]
    fn a_coordinate_out_of_range_is_reported_with_its_value() {
        for bits in [2u32, 8, 31, 32] {
            let half = 1i64 << (bits - 1);
            let c = KeyCodec::new(3, 0, bits).unwrap();
            let mut out = [0u64; 2];
            for (bad, at) in [(half, 1), (-half - 1, 2), (half, 0)] {
                if bad > i32::MAX as i64 || bad < i32::MIN as i64 {
                    continue;
                }
                let mut v = [(half - 1) as i32, (-half) as i32, 0];
                v[at] = bad as i32;
                match c.encode_vertex(&v, &mut out) {
                    Err(Error::KeyOverflow { value, bits: b }) => {
                        assert_eq!((value, b), (bad, bits));
                    }
                    other => panic!("bits={bits} {v:?}: {other:?}"),
                }
                let s = Simplex::vertex(&v).unwrap();
                assert!(matches!(
                    c.encode(&s, &mut out),
                    Err(Error::KeyOverflow { .. })
                ));
            }
            let ok = [(half - 1) as i32, (-half) as i32, 0];
            c.encode_vertex(&ok, &mut out).unwrap();
        }
    }

    #[test]
    fn fields_that_straddle_words_come_back() {
        // 3 coordinates of 31 bits: the third starts at bit 62 and ends in the second word;
        // part indices of 6 bits (l = 40) straddle too.
        let mut bw = [0u64; 3];
        let mut w = BitWriter {
            out: &mut bw,
            pos: 0,
        };
        let vals = [
            (5u64, 3u32),
            (0x7fff_ffff, 31),
            (0x1234_5678, 31),
            (0x2a, 6),
            (1, 1),
        ];
        for &(v, b) in &vals {
            w.put(v, b);
        }
        assert_eq!(w.pos, 72);
        let mut r = BitReader { words: &bw, pos: 0 };
        for &(v, b) in &vals {
            assert_eq!(r.get(b), v);
        }
        let full = [u64::MAX, 0];
        assert_eq!(
            BitReader {
                words: &full,
                pos: 0
            }
            .get(64),
            u64::MAX
        );
    }
}
