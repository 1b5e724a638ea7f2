//! Compact keys: a canonical simplex packed into a few 64-bit words (the set of such keys is
//! [`KeySet`](super::KeySet)).

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
        if s.ambient_dim() != self.d || s.dim() != self.l {
            return Err(Error::InvalidSimplex(format!(
                "codec for {}-simplices of R^{}, got a {}-simplex of R^{}",
                self.l,
                self.d,
                s.dim(),
                s.ambient_dim()
            )));
        }
        self.encode_vertex(s.base(), out)?;
        let mut w = BitWriter {
            out: &mut out[..self.words],
            pos: self.d * self.coord_bits as usize,
        };
        if self.part_bits > 0 {
            let mut index = [0u8; 64];
            for (p, &mask) in s.parts().iter().enumerate() {
                let mut m = mask;
                while m != 0 {
                    index[m.trailing_zeros() as usize] = p as u8;
                    m &= m - 1;
                }
            }
            for &p in &index[..self.d] {
                w.put(p as u64, self.part_bits);
            }
        }
        Ok(())
    }

    /// Unpacks a key written by [`KeyCodec::encode`] (no heap allocation).
    pub fn decode(&self, key: &[u64]) -> Simplex {
        let mut s = Simplex::vertex(&[0; MAX_DIM][..self.d]).expect("the codec's d is valid");
        self.decode_into(key, &mut s);
        s
    }

    /// Unpacks a key into `out`, reusing its storage (no validation: keys come from
    /// [`KeyCodec::encode`]).
    pub fn decode_into(&self, key: &[u64], out: &mut Simplex) {
        let bias = 1i64 << (self.coord_bits - 1);
        let mut r = BitReader { words: key, pos: 0 };
        let (v0, parts) = out.reset(self.d, self.l + 1);
        for c in v0.iter_mut() {
            *c = (r.get(self.coord_bits) as i64 - bias) as i32;
        }
        parts.fill(0);
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
            let c = v[..self.d]
                .iter()
                .find(|&&c| (c as i64 + bias) as u64 >> bits != 0)
                .expect("a coordinate spilled");
            return Err(Error::KeyOverflow {
                value: *c as i64,
                bits,
            });
        }
        Ok(())
    }

    /// Unpacks a vertex written by [`KeyCodec::encode_vertex`] into `out` (d coordinates).
    pub fn decode_vertex(&self, key: &[u64], out: &mut [i32]) {
        let bias = 1i64 << (self.coord_bits - 1);
        let mut r = BitReader { words: key, pos: 0 };
        for c in out.iter_mut().take(self.d) {
            *c = (r.get(self.coord_bits) as i64 - bias) as i32;
        }
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
