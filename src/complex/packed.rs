//! (cofacet key, facet index) pairs packed into one u64 (or u128) that sorts exactly as the
//! pair does, and a parallel sort of distinct integers.
//!
//! A cell's key has room for any vertex of the trace's key box (20 bits a coordinate with no
//! box), so a key of a surface in R^3 takes two words and its pair 24 bytes. Within one
//! complex the coordinates span a few hundred values: a key's fields, each less its least
//! value, and the index, fit one word, and comparing words costs a third of comparing pairs.
//! Keys of three or more words (a 3-manifold in R^6, anything in R^8 and up) often fit 128
//! bits packed.

use std::cmp::Reverse;
use std::collections::binary_heap::{BinaryHeap, PeekMut};
use std::fmt::Debug;
use std::ops::{BitOr, BitOrAssign, Shl, Shr};

use rayon::prelude::*;

use crate::triangulation::{KeyCodec, Simplex, MAX_DIM};

/// An unsigned integer that packed pairs are held in: u64, or u128 where 64 bits are too few.
pub(super) trait Word:
    Copy
    + Ord
    + Default
    + Send
    + Sync
    + Debug
    + Shl<u32, Output = Self>
    + Shr<u32, Output = Self>
    + BitOr<Output = Self>
    + BitOrAssign
{
    const BITS: u32;
    fn from_u64(x: u64) -> Self;
    /// The low 64 bits.
    fn low_u64(self) -> u64;
    fn wrapping_add(self, other: Self) -> Self;
    fn wrapping_sub(self, other: Self) -> Self;
}

macro_rules! word {
    ($t:ty) => {
        impl Word for $t {
            const BITS: u32 = <$t>::BITS;
            #[inline]
            fn from_u64(x: u64) -> Self {
                x as $t
            }
            #[inline]
            fn low_u64(self) -> u64 {
                self as u64
            }
            #[inline]
            fn wrapping_add(self, other: Self) -> Self {
                <$t>::wrapping_add(self, other)
            }
            #[inline]
            fn wrapping_sub(self, other: Self) -> Self {
                <$t>::wrapping_sub(self, other)
            }
        }
    };
}
word!(u64);
word!(u128);

/// A piece of one of a key's fields, as packed: bits `from..from + width` of the field's
/// value, less `low` (at most `span`, `bits` wide), go to bit `at` of the packed integer.
#[derive(Clone, Copy, Debug)]
struct Piece {
    from: u32,
    width: u32,
    low: u64,
    span: u64,
    bits: u32,
    at: u32,
}

/// Packs keys of `W` words of one [`KeyCodec`], whose base vertices lie in a known box,
/// with an index below a known count, into integers `P` (u64 or u128) whose order is the
/// order of the (key, index) pairs.
///
/// Keys of `W` words compare word 0 first: as the integer V whose base-2^64 digits are the
/// words, word 0 the highest, whose bits are the codec's fields (coordinates, then each
/// element's part), a field cut where a word ends becoming two pieces. Packed, the pieces
/// keep their order of significance in V, each less its least value (a coordinate's, when
/// it is one piece): an order-preserving map of each piece, so of V. A packed key is the
/// sum of its fields' packed bits, so the cofacets of a simplex are packed from its own
/// fields ([`Packer::cofacets`]).
#[derive(Clone, Debug)]
pub(super) struct Packer<const W: usize, P = u64> {
    d: usize,
    coord_bits: u32,
    part_bits: u32,
    /// The pieces of coordinate i's field (i < d), then of element e's part field (d + e).
    pieces: Vec<Vec<Piece>>,
    /// The packed bits of element e in part x, at e * 2^part_bits + x.
    parts: Vec<P>,
    index_bits: u32,
}

impl<const W: usize, P: Word> Packer<W, P> {
    /// The packer for keys of `codec` (at most `W` words) whose base vertex coordinates lie
    /// in `[lo, hi]`, with indices below `count`; `None` when they would take more bits than
    /// `P` has.
    pub fn new(codec: &KeyCodec, lo: &[i32], hi: &[i32], count: usize) -> Option<Self> {
        if codec.words() > W {
            return None;
        }
        let (d, bits, part_bits) = (codec.ambient_dim(), codec.coord_bits(), codec.part_bits());
        let bias = 1i64 << (bits - 1);
        // A box the codec cannot encode is left to the unpacked path (which says so).
        let fits = |c: i32| (0..=mask(bits) as i64).contains(&(i64::from(c) + bias));
        if !lo[..d].iter().chain(&hi[..d]).all(|&c| fits(c)) {
            return None;
        }
        // (field, start in the key, width) of every piece, with its least value and span.
        let mut all: Vec<(usize, u32, Piece)> = Vec::new();
        for f in 0..2 * d {
            let (start, width) = if f < d {
                (f as u32 * bits, bits)
            } else {
                (d as u32 * bits + (f - d) as u32 * part_bits, part_bits)
            };
            if width == 0 {
                continue;
            }
            let end = start + width;
            let cut = (start / 64 + 1) * 64;
            let whole = |from, width| Piece {
                from,
                width,
                low: 0,
                span: mask(width),
                bits: 0,
                at: 0,
            };
            // A coordinate's top piece (all of it, unless a word's end cuts it) ranges over
            // the box's values shifted down.
            let narrow = |from: u32, width: u32| {
                let low = (i64::from(lo[f]) + bias) as u64 >> from;
                let top = (i64::from(hi[f]) + bias) as u64 >> from;
                Piece {
                    low,
                    span: top.saturating_sub(low),
                    ..whole(from, width)
                }
            };
            if end > cut {
                // Cut where a word ends: two pieces, the low one kept whole.
                all.push((f, start, whole(0, cut - start)));
                let high = if f < d {
                    narrow(cut - start, end - cut)
                } else {
                    whole(cut - start, end - cut)
                };
                all.push((f, cut, high));
            } else if f < d {
                all.push((f, start, narrow(0, width)));
            } else {
                all.push((f, start, whole(0, width)));
            }
        }
        let index_bits = (usize::BITS - count.saturating_sub(1).leading_zeros()).max(1);
        for (_, _, p) in &mut all {
            p.bits = u64::BITS - p.span.leading_zeros();
        }
        let total: u32 = all.iter().map(|(_, _, p)| p.bits).sum::<u32>() + index_bits;
        if total > P::BITS || index_bits > 32 {
            return None;
        }
        // Least significant (in V) first, placed from just above the index up.
        all.sort_by_key(|&(_, start, _)| (W as u32 - 1 - start / 64) * 64 + start % 64);
        let mut pieces = vec![Vec::new(); 2 * d];
        let mut at = index_bits;
        for (f, _, mut p) in all {
            // A piece of no bits (a coordinate of one value) packs to nothing, at bit 0: no
            // shift by the integer's width.
            p.at = if p.bits == 0 { 0 } else { at };
            at += p.bits;
            pieces[f].push(p);
        }
        let mut packer = Packer {
            d,
            coord_bits: bits,
            part_bits,
            pieces,
            parts: Vec::new(),
            index_bits,
        };
        packer.parts = (0..d)
            .flat_map(|e| (0..1u64 << part_bits).map(move |x| (e, x)))
            .map(|(e, x)| packer.field(d + e, x).expect("a part field is kept whole"))
            .collect();
        Some(packer)
    }

    /// The packed bits of field `f` (coordinate f < d, or element f - d's part) of value
    /// `x`, or `None` when it lies outside the box.
    #[inline]
    fn field(&self, f: usize, x: u64) -> Option<P> {
        let mut out = P::default();
        for p in &self.pieces[f] {
            let y = ((x >> p.from) & mask(p.width)).wrapping_sub(p.low);
            if y > p.span {
                return None;
            }
            out |= P::from_u64(y) << p.at;
        }
        Some(out)
    }

    /// Where field `f` starts in a key read as one integer (bit i is bit i % 64 of word
    /// i / 64), and its width.
    fn place(&self, f: usize) -> (u32, u32) {
        let (d, bits, pb) = (self.d, self.coord_bits, self.part_bits);
        if f < d {
            (f as u32 * bits, bits)
        } else {
            (d as u32 * bits + (f - d) as u32 * pb, pb)
        }
    }

    /// Bits of the packed index.
    pub fn index_bits(&self) -> u32 {
        self.index_bits
    }

    /// The packed pair, or `None` when a field lies outside the box it was made for.
    #[cfg(test)]
    pub fn pack(&self, key: &[u64; W], index: u32) -> Option<P> {
        let word = |i: usize| u128::from(key.get(i).copied().unwrap_or(0));
        let mut out = P::from_u64(u64::from(index));
        for f in 0..self.pieces.len() {
            let (start, width) = self.place(f);
            let (i, off) = ((start / 64) as usize, start % 64);
            let two = word(i) | word(i + 1) << 64;
            out |= self.field(f, (two >> off) as u64 & mask(width))?;
        }
        Some(out)
    }

    /// Writes into `out` the packed pairs (cofacet key, `index`) of every cofacet of `s`
    /// (an l-simplex, keys of (l+1)-simplices), as many as `s.cofacet_count()`, in no
    /// particular order; false when a base vertex lies outside the box.
    ///
    /// Splitting part i into sub and the rest moves the rest and every later part up one
    /// index. Where d goes to the second-to-last part, the rest becomes the first part
    /// (every other element moves up one, the rest's from the last index to 0) and the base
    /// vertex drops one step on the rest's coordinates.
    pub fn cofacets(&self, s: &Simplex, index: u32, out: &mut [P]) -> bool {
        let d = self.d;
        let bias = 1i64 << (self.coord_bits - 1);
        let size = 1usize << self.part_bits;
        let part = |e: usize, x: usize| self.parts[e * size + x];
        // The base's packed bits, and their change where a coordinate drops one step.
        let (mut base, mut down) = (P::default(), [P::default(); MAX_DIM]);
        for (i, &c) in s.base().iter().enumerate() {
            let x = (i64::from(c) + bias) as u64;
            let (Some(a), Some(b)) = (self.field(i, x), self.field(i, x.wrapping_sub(1))) else {
                return false;
            };
            base = base.wrapping_add(a);
            down[i] = b.wrapping_sub(a);
        }
        let parts = s.parts();
        let n = parts.len();
        let (top, below) = (1u64 << d, (1u64 << d) - 1);
        let mut idx = [0usize; MAX_DIM];
        for (q, &m) in parts.iter().enumerate() {
            let mut m = m & below;
            while m != 0 {
                idx[m.trailing_zeros() as usize] = q;
                m &= m - 1;
            }
        }
        let index = P::from_u64(u64::from(index));
        let mut at = 0;
        for (i, &m) in parts.iter().enumerate() {
            if m.count_ones() < 2 {
                continue;
            }
            let (mut split, mut rotated) = (base, base);
            for (e, &q) in idx[..d].iter().enumerate() {
                split = split.wrapping_add(part(e, q + usize::from(q > i)));
                rotated = rotated.wrapping_add(part(e, q + 1));
            }
            let mut sub = (m - 1) & m;
            while sub != 0 {
                let mut rest = m & !sub & below;
                let mut key;
                if i == n - 1 && sub & top != 0 {
                    key = rotated;
                    while rest != 0 {
                        let e = rest.trailing_zeros() as usize;
                        key = key
                            .wrapping_add(down[e])
                            .wrapping_add(part(e, 0))
                            .wrapping_sub(part(e, n));
                        rest &= rest - 1;
                    }
                } else {
                    key = split;
                    while rest != 0 {
                        let e = rest.trailing_zeros() as usize;
                        key = key.wrapping_add(part(e, i + 1)).wrapping_sub(part(e, i));
                        rest &= rest - 1;
                    }
                }
                out[at] = key | index;
                at += 1;
                sub = (sub - 1) & m;
            }
        }
        debug_assert_eq!(at, out.len());
        true
    }

    /// The key of a packed pair.
    #[inline]
    pub fn key(&self, packed: P) -> [u64; W] {
        let mut key = [0u64; W];
        for (f, pieces) in self.pieces.iter().enumerate() {
            let start = self.place(f).0;
            for p in pieces {
                // A piece lies within one word of the key.
                let x = ((packed >> p.at).low_u64() & mask(p.bits)) + p.low;
                let bit = start + p.from;
                key[(bit / 64) as usize] |= x << (bit % 64);
            }
        }
        key
    }

    /// The index of a packed pair.
    #[inline]
    pub fn index(&self, packed: P) -> u32 {
        (packed.low_u64() & mask(self.index_bits)) as u32
    }
}

/// The low `bits` bits set.
#[inline]
fn mask(bits: u32) -> u64 {
    if bits == 0 {
        0
    } else {
        u64::MAX >> (64 - bits)
    }
}

/// Fewest values sorted in parallel: below, one thread sorts them.
const PARALLEL_SORT: usize = 1 << 16;

/// Sorts distinct values on every thread of the pool: each thread sorts a chunk in place,
/// then the sorted chunks are merged into a new vector, cut at sampled splitters into a few
/// buckets a thread, each bucket merged alone. Distinct values have one sorted order, so the
/// result does not depend on the threads.
pub(super) fn par_sort_distinct<T: Copy + Ord + Default + Send + Sync>(mut v: Vec<T>) -> Vec<T> {
    let threads = rayon::current_num_threads();
    if threads == 1 || v.len() < PARALLEL_SORT {
        v.sort_unstable();
        return v;
    }
    let chunk = v.len().div_ceil(threads);
    v.par_chunks_mut(chunk).for_each(|c| c.sort_unstable());
    let buckets = 4 * threads;
    // Splitters: every 32nd of a sorted sample of 32 per bucket.
    let step = (v.len() / (32 * buckets)).max(1);
    let mut sample: Vec<T> = v.iter().step_by(step).copied().collect();
    sample.sort_unstable();
    let splitters: Vec<T> = (1..buckets)
        .map(|b| sample[b * sample.len() / buckets])
        .collect();
    // Each chunk cut at the splitters: pieces[b] holds bucket b's piece of every chunk.
    let mut pieces: Vec<Vec<&[T]>> = vec![Vec::with_capacity(threads); buckets];
    for c in v.chunks(chunk) {
        let mut rest = c;
        for (b, s) in splitters.iter().enumerate() {
            let (piece, tail) = rest.split_at(rest.partition_point(|x| x < s));
            pieces[b].push(piece);
            rest = tail;
        }
        pieces[buckets - 1].push(rest);
    }
    let mut out = vec![T::default(); v.len()];
    let mut slots = Vec::with_capacity(buckets);
    let mut rest = &mut out[..];
    for p in &pieces {
        let (slot, tail) = rest.split_at_mut(p.iter().map(|x| x.len()).sum());
        slots.push(slot);
        rest = tail;
    }
    slots
        .into_par_iter()
        .zip(pieces)
        .for_each(|(slot, p)| merge_all(&p, slot));
    out
}

/// Merges the sorted `runs` into `out` (as long as they are together): two by a plain
/// merge, more through a heap of their heads (no scratch memory either way).
fn merge_all<T: Copy + Ord>(runs: &[&[T]], out: &mut [T]) {
    match runs {
        [] => {}
        [a] => out.copy_from_slice(a),
        [a, b] => merge(a, b, out),
        _ => {
            let mut heads: BinaryHeap<Reverse<(T, usize)>> = runs
                .iter()
                .enumerate()
                .filter_map(|(r, run)| Some(Reverse((*run.first()?, r))))
                .collect();
            let mut at = vec![0; runs.len()];
            for o in out.iter_mut() {
                // The runs are as long as `out` together.
                let Some(mut head) = heads.peek_mut() else {
                    break;
                };
                let Reverse((x, r)) = *head;
                *o = x;
                at[r] += 1;
                match runs[r].get(at[r]) {
                    Some(&next) => *head = Reverse((next, r)),
                    None => drop(PeekMut::pop(head)),
                }
            }
        }
    }
}

/// Merges the sorted `a` and `b` into `out`, without branching on the comparisons.
fn merge<T: Copy + Ord>(a: &[T], b: &[T], out: &mut [T]) {
    debug_assert_eq!(a.len() + b.len(), out.len());
    let (mut i, mut j) = (0, 0);
    let mut o = 0;
    while i < a.len() && j < b.len() {
        let (x, y) = (a[i], b[j]);
        let take_a = x <= y;
        out[o] = if take_a { x } else { y };
        i += usize::from(take_a);
        j += usize::from(!take_a);
        o += 1;
    }
    out[o..o + a.len() - i].copy_from_slice(&a[i..]);
    o += a.len() - i;
    out[o..].copy_from_slice(&b[j..]);
}

#[cfg(test)]
mod tests {
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    use super::*;
    use crate::triangulation::test_support::random_simplex;

    /// Keys of random simplices of `codec` with base vertices in [lo, hi], each with a random
    /// index below `count`.
    fn random_pairs<const W: usize>(
        codec: &KeyCodec,
        lo: &[i32],
        hi: &[i32],
        count: u32,
        n: usize,
        seed: u64,
    ) -> Vec<([u64; W], u32)> {
        let mut rng = seed;
        let mut next = move || {
            rng ^= rng << 13;
            rng ^= rng >> 7;
            rng ^= rng << 17;
            rng
        };
        let (d, l) = (codec.ambient_dim(), codec.simplex_dim());
        (0..n)
            .map(|_| {
                let mut v = [0i32; MAX_DIM];
                for i in 0..d {
                    let span = (hi[i] - lo[i] + 1) as u64;
                    v[i] = lo[i] + (next() % span) as i32;
                }
                // A random ordered partition of 0..=d into l + 1 non-empty parts, d last.
                let mut parts = vec![0u64; l + 1];
                let mut order: Vec<usize> = (0..d).collect();
                for i in (1..d).rev() {
                    order.swap(i, (next() % (i as u64 + 1)) as usize);
                }
                for (p, &e) in order.iter().take(l).enumerate() {
                    parts[p] |= 1 << e;
                }
                for &e in &order[l..] {
                    parts[(next() % (l as u64 + 1)) as usize] |= 1 << e;
                }
                parts[l] |= 1 << d;
                let mut key = [0u64; W];
                codec.encode_masks(&v[..d], &parts, &mut key).unwrap();
                (key, (next() % u64::from(count)) as u32)
            })
            .collect()
    }

    /// Packs pairs of a codec (one to four words, fields cut where a word ends) into `P`s
    /// and checks that the packed values sort as the pairs do and unpack to them.
    fn packs_in_order<const W: usize, P: Word>(d: usize, l: usize, bits: u32, lo: i32, hi: i32) {
        let codec = KeyCodec::new(d, l, bits).unwrap();
        assert!(codec.words() <= W);
        let (los, his) = (vec![lo; d], vec![hi; d]);
        let count = 1000;
        let packer = Packer::<W, P>::new(&codec, &los, &his, count).unwrap();
        let pairs = random_pairs::<W>(&codec, &los, &his, count as u32, 4000, 7 + bits as u64);
        let mut packed: Vec<P> = pairs
            .iter()
            .map(|(k, i)| packer.pack(k, *i).unwrap())
            .collect();
        for (p, (k, i)) in packed.iter().zip(&pairs) {
            assert_eq!((packer.key(*p), packer.index(*p)), (*k, *i));
        }
        let mut want = pairs.clone();
        want.sort_unstable();
        want.dedup();
        packed.sort_unstable();
        packed.dedup();
        let got: Vec<([u64; W], u32)> = packed
            .iter()
            .map(|&p| (packer.key(p), packer.index(p)))
            .collect();
        assert_eq!(got, want, "d {d}, l {l}, bits {bits}");
    }

    #[test]
    fn packed_pairs_sort_as_the_pairs_and_unpack_to_them() {
        // A surface in R^3 with no box: 21-bit coordinates, a part field cut by the word's end.
        packs_in_order::<2, u64>(3, 2, 21, -300, 250);
        packs_in_order::<2, u64>(3, 3, 21, 1 << 19, (1 << 19) + 40);
        // One word; a coordinate cut by the word's end (R^4, 15 bits).
        packs_in_order::<1, u64>(3, 1, 12, -5, 7);
        packs_in_order::<2, u64>(4, 3, 15, -100, 100);
        packs_in_order::<2, u64>(4, 4, 17, -1, 0);
        // Into 128 bits: three words (R^6, coordinates cut where words end), four (R^8).
        packs_in_order::<3, u128>(6, 3, 21, -300, 250);
        packs_in_order::<4, u128>(8, 6, 22, -20, 20);
        packs_in_order::<2, u128>(3, 2, 21, -300, 250);
        assert!(Packer::<3, u64>::new(
            &KeyCodec::new(6, 3, 21).unwrap(),
            &[-300; 6],
            &[250; 6],
            1000
        )
        .is_none());
    }

    #[test]
    fn a_key_outside_its_box_or_too_wide_a_packing_is_refused() {
        let codec = KeyCodec::new(3, 2, 21).unwrap();
        let packer = Packer::<2>::new(&codec, &[-10; 3], &[10; 3], 100).unwrap();
        let mut key = [0u64; 2];
        for (v, ok) in [
            ([-10, 0, 10], true),
            ([-11, 0, 0], false),
            ([0, 11, 0], false),
        ] {
            codec.encode_masks(&v, &[1, 2, 12], &mut key).unwrap();
            assert_eq!(packer.pack(&key, 99).is_some(), ok, "{v:?}");
        }
        // 10 coordinates of 21 bits and 4-bit parts over a range of 2^20: too wide.
        let wide = KeyCodec::new(4, 4, 21).unwrap();
        assert!(Packer::<2>::new(&wide, &[-(1 << 19); 4], &[1 << 19; 4], 1 << 20).is_none());
        // 128 bits: ten coordinates over 2^20 values are too many.
        let ten = KeyCodec::new(10, 9, 21).unwrap();
        assert!(Packer::<4, u128>::new(&ten, &[-(1 << 19); 10], &[1 << 19; 10], 9).is_none());
        assert!(Packer::<4, u128>::new(&ten, &[-3; 10], &[3; 10], 9).is_some());
        assert!(
            Packer::<2>::new(&KeyCodec::new(10, 9, 12).unwrap(), &[0; 10], &[3; 10], 9).is_none()
        );
        // A box the codec cannot encode.
        assert!(Packer::<2>::new(&codec, &[-(1 << 20) - 1, 0, 0], &[0; 3], 9).is_none());
        assert!(Packer::<2>::new(&codec, &[0; 3], &[0, 1 << 20, 0], 9).is_none());
        assert!(Packer::<2>::new(&codec, &[-(1 << 20); 3], &[3 - (1 << 20); 3], 9).is_some());
    }

    #[test]
    fn a_simplexs_cofacets_pack_as_their_keys_do() {
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let mut seen = 0;
        for d in 1..=6 {
            for l in 0..d {
                // 21 bits: a part field cut where a word ends in R^3; 15 and 17: a coordinate.
                for bits in [4u32, 15, 17, 21] {
                    let up = KeyCodec::new(d, l + 1, bits).unwrap();
                    if up.words() > 2 {
                        continue;
                    }
                    let r = (1 << (bits - 2)) - 1;
                    // Bases of r.min(50) steps and one more (the canonical form), and their cofacets.
                    let (lo, hi) = (vec![-r - 2; d], vec![r; d]);
                    let Some(packer) = Packer::<2>::new(&up, &lo, &hi, 1000) else {
                        continue;
                    };
                    for _ in 0..30 {
                        let s = random_simplex(&mut rng, d, l, (r - 2).min(50));
                        let mut want = Vec::new();
                        s.for_each_cofacet(|t| {
                            let mut key = [0u64; 2];
                            up.encode(t, &mut key).unwrap();
                            want.push(packer.pack(&key, 77).unwrap());
                        });
                        let mut got = vec![0; s.cofacet_count() as usize];
                        assert!(
                            packer.cofacets(&s, 77, &mut got),
                            "d {d} l {l} bits {bits} {s:?} {packer:?}"
                        );
                        got.sort_unstable();
                        want.sort_unstable();
                        assert_eq!(got, want, "d {d}, l {l}, bits {bits}: {s:?}");
                        seen += got.len();
                    }
                }
            }
        }
        assert!(seen > 5_000, "{seen}");
        // Into 128 bits: keys of three and four words, in R^6 to R^8.
        let mut seen = 0;
        for (d, l, bits) in [(6, 3, 21), (6, 5, 20), (7, 5, 20), (8, 6, 22), (8, 7, 13)] {
            let up = KeyCodec::new(d, l + 1, bits).unwrap();
            assert!(up.words() > 2 && up.words() <= 4, "{d} {l} {bits}");
            let r = 30;
            let (lo, hi) = (vec![-r - 2; d], vec![r; d]);
            let packer = Packer::<4, u128>::new(&up, &lo, &hi, 1000).unwrap();
            for _ in 0..200 {
                let s = random_simplex(&mut rng, d, l, r - 2);
                let mut want = Vec::new();
                s.for_each_cofacet(|t| {
                    let mut key = [0u64; 4];
                    up.encode(t, &mut key).unwrap();
                    want.push(packer.pack(&key, 77).unwrap());
                    assert_eq!(
                        (
                            packer.key(*want.last().unwrap()),
                            packer.index(*want.last().unwrap())
                        ),
                        (key, 77)
                    );
                });
                let mut got = vec![0u128; s.cofacet_count() as usize];
                assert!(packer.cofacets(&s, 77, &mut got), "d {d} l {l} {s:?}");
                got.sort_unstable();
                want.sort_unstable();
                assert_eq!(got, want, "d {d}, l {l}, bits {bits}: {s:?}");
                seen += got.len();
            }
        }
        assert!(seen > 2_000, "{seen}");
        // A base vertex on the box's lower side: its rotated cofacets leave the box.
        let up = KeyCodec::new(2, 1, 8).unwrap();
        let packer = Packer::<2>::new(&up, &[0, 0], &[5, 5], 10).unwrap();
        let s = Simplex::from_masks(&[0, 2], &[0b111]).unwrap();
        let mut out = vec![0; s.cofacet_count() as usize];
        assert!(!packer.cofacets(&s, 1, &mut out));
        let s = Simplex::from_masks(&[1, 2], &[0b111]).unwrap();
        assert!(packer.cofacets(&s, 1, &mut out));
    }

    #[test]
    fn the_parallel_sort_sorts_distinct_values_on_any_pool() {
        let mut rng = 3u64;
        let mut v: Vec<u64> = (0..300_000)
            .map(|_| {
                rng ^= rng << 13;
                rng ^= rng >> 7;
                rng ^= rng << 17;
                rng >> (rng % 40)
            })
            .collect();
        v.sort_unstable();
        v.dedup();
        let want = v.clone();
        for threads in [1, 2, 3, 8] {
            let mut got = want.clone();
            got.reverse();
            got.rotate_left(12345);
            let got = crate::test_pool(threads).install(|| par_sort_distinct(got));
            assert!(got == want, "{threads} threads");
        }
    }

    #[test]
    fn sorted_runs_of_any_lengths_merge_into_one() {
        let cases: [&[&[u32]]; 5] = [
            &[],
            &[&[], &[]],
            &[&[2, 9], &[]],
            &[&[1, 4, 8], &[2, 3, 10, 11]],
            &[&[], &[1, 4], &[2], &[], &[3, 5, 6], &[0, 7]],
        ];
        for runs in cases {
            let mut want: Vec<u32> = runs.concat();
            want.sort_unstable();
            let mut got = vec![u32::MAX; want.len()];
            merge_all(runs, &mut got);
            assert_eq!(got, want, "{runs:?}");
        }
    }
}
