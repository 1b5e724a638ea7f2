//! (cofacet key, facet index) pairs packed into one u64 that sorts exactly as the pair does,
//! and a parallel sort of distinct u64s.
//!
//! A cell's key has room for any vertex of the trace's key box (20 bits a coordinate with no
//! box), so a key of a surface in R^3 takes two words and its pair 24 bytes. Within one
//! complex the coordinates span a few hundred values: a key's fields, each less its least
//! value, and the index, fit one word, and comparing words costs a third of comparing pairs.

use rayon::prelude::*;

use crate::triangulation::KeyCodec;

/// A bit field of a key read as one integer (see [`Packer`]).
#[derive(Clone, Copy, Debug)]
struct Field {
    /// Where it starts in that integer, and its width.
    at: u32,
    width: u32,
    /// Its least value (subtracted), the most the rest may be, and the bits it takes.
    low: u64,
    span: u64,
    bits: u32,
}

/// Packs keys of `W` <= 2 words of one [`KeyCodec`], whose base vertices lie in a known box,
/// with an index below a known count, into u64s whose order is the order of the (key,
/// index) pairs.
///
/// Keys of `W` words compare word 0 first: as the integer V = word 0 * 2^64 + word 1, whose
/// bits are the codec's fields (coordinates, then each element's part), a field cut where a
/// word ends becoming two. Packed, the fields keep their order of significance in V, each
/// less its least value: an order-preserving map of each field, so of V.
#[derive(Clone, Debug)]
pub(super) struct Packer<const W: usize> {
    /// Most significant first.
    fields: Vec<Field>,
    index_bits: u32,
}

impl<const W: usize> Packer<W> {
    /// The packer for keys of `codec` (at most `W` words) whose base vertex coordinates lie
    /// in `[lo, hi]`, with indices below `count`; `None` when they would take more than 64
    /// bits (or `W` > 2).
    pub fn new(codec: &KeyCodec, lo: &[i32], hi: &[i32], count: usize) -> Option<Self> {
        if W > 2 || codec.words() > W {
            return None;
        }
        let (d, bits, part_bits) = (codec.ambient_dim(), codec.coord_bits(), codec.part_bits());
        let bias = 1i64 << (bits - 1);
        // (start in the codec's bit stream, width, least value when known).
        let mut stream: Vec<(u32, u32, Option<u64>)> = (0..d)
            .map(|i| {
                let low = (i64::from(lo[i]) + bias).max(0) as u64;
                (i as u32 * bits, bits, Some(low))
            })
            .collect();
        stream.extend((0..d).map(|e| (d as u32 * bits + e as u32 * part_bits, part_bits, None)));
        let mut fields = Vec::new();
        for (i, (start, width, low)) in stream.into_iter().enumerate() {
            if width == 0 {
                continue;
            }
            let end = start + width;
            if start / 64 != (end - 1) / 64 {
                // Cut where a word ends: two fields, each kept whole.
                let cut = (start / 64 + 1) * 64;
                fields.push(Self::raw(start, cut - start));
                fields.push(Self::raw(cut, end - cut));
            } else if let Some(low) = low {
                let top = (i64::from(hi[i]) + bias).max(0) as u64;
                let span = top.saturating_sub(low);
                fields.push(Field {
                    at: Self::position(start),
                    width,
                    low,
                    span,
                    bits: u64::BITS - span.leading_zeros(),
                });
            } else {
                fields.push(Self::raw(start, width));
            }
        }
        fields.sort_by_key(|f| std::cmp::Reverse(f.at));
        let index_bits = (usize::BITS - count.saturating_sub(1).leading_zeros()).max(1);
        let total: u32 = fields.iter().map(|f| f.bits).sum::<u32>() + index_bits;
        (total <= 64 && index_bits <= 32).then_some(Packer { fields, index_bits })
    }

    /// A field kept whole, at `start` in the codec's bit stream.
    fn raw(start: u32, width: u32) -> Field {
        Field {
            at: Self::position(start),
            width,
            low: 0,
            span: mask(width),
            bits: width,
        }
    }

    /// Where bit `s` of the codec's stream (word s / 64, bit s % 64) sits in V.
    fn position(s: u32) -> u32 {
        (W as u32 - 1 - s / 64) * 64 + s % 64
    }

    /// Bits of the packed index.
    pub fn index_bits(&self) -> u32 {
        self.index_bits
    }

    /// The packed pair, or `None` when a field lies outside the box it was made for.
    #[inline]
    pub fn pack(&self, key: &[u64; W], index: u32) -> Option<u64> {
        let v = join(key);
        let mut acc = 0u64;
        for f in &self.fields {
            let x = ((v >> f.at) as u64 & mask(f.width)).wrapping_sub(f.low);
            if x > f.span {
                return None;
            }
            acc = (acc << f.bits) | x;
        }
        Some((acc << self.index_bits) | u64::from(index))
    }

    /// The key of a packed pair.
    #[inline]
    pub fn key(&self, packed: u64) -> [u64; W] {
        let mut acc = packed >> self.index_bits;
        let mut v = 0u128;
        for f in self.fields.iter().rev() {
            let x = acc & mask(f.bits);
            acc >>= f.bits;
            v |= u128::from(x + f.low) << f.at;
        }
        split(v)
    }

    /// The index of a packed pair.
    #[inline]
    pub fn index(&self, packed: u64) -> u32 {
        (packed & mask(self.index_bits)) as u32
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

/// A key of `W` <= 2 words as the integer that orders it (word 0 the more significant).
#[inline]
fn join<const W: usize>(key: &[u64; W]) -> u128 {
    key.iter().fold(0u128, |v, &w| (v << 64) | u128::from(w))
}

/// The inverse of [`join`].
#[inline]
fn split<const W: usize>(v: u128) -> [u64; W] {
    std::array::from_fn(|i| (v >> (64 * (W - 1 - i))) as u64)
}

/// Fewest values sorted in parallel: below, one thread sorts them.
const PARALLEL_SORT: usize = 1 << 16;

/// Sorts distinct values on every thread of the pool: cut at sampled splitters into a few
/// buckets a thread, each bucket sorted alone. Distinct values have one sorted order, so the
/// result does not depend on the threads.
pub(super) fn par_sort_distinct(v: &mut [u64]) {
    let threads = rayon::current_num_threads();
    if threads == 1 || v.len() < PARALLEL_SORT {
        v.sort_unstable();
        return;
    }
    let buckets = 4 * threads;
    // Splitters: every 32nd of a sorted sample of 32 per bucket.
    let step = (v.len() / (32 * buckets)).max(1);
    let mut sample: Vec<u64> = v.iter().step_by(step).copied().collect();
    sample.sort_unstable();
    let splitters: Vec<u64> = (1..buckets)
        .map(|b| sample[b * sample.len() / buckets])
        .collect();
    let bucket = |x: u64| splitters.partition_point(|&s| s <= x);
    // Each chunk puts its values in bucket order in a copy, counting each bucket's.
    let chunk = v.len().div_ceil(threads);
    let mut copy = vec![0u64; v.len()];
    let counts: Vec<Vec<usize>> = v
        .par_chunks(chunk)
        .zip(copy.par_chunks_mut(chunk))
        .map(|(src, dst)| {
            let mut count = vec![0usize; buckets];
            for &x in src {
                count[bucket(x)] += 1;
            }
            let mut at: Vec<usize> = count
                .iter()
                .scan(0, |s, &c| {
                    let a = *s;
                    *s += c;
                    Some(a)
                })
                .collect();
            for &x in src {
                let b = bucket(x);
                dst[at[b]] = x;
                at[b] += 1;
            }
            count
        })
        .collect();
    // Bucket b's slot in `v`: the chunks' pieces of bucket b, one after the other.
    let mut slots = Vec::with_capacity(buckets);
    let mut rest = &mut v[..];
    for b in 0..buckets {
        let len = counts.iter().map(|c| c[b]).sum();
        let (slot, tail) = rest.split_at_mut(len);
        slots.push(slot);
        rest = tail;
    }
    slots.into_par_iter().enumerate().for_each(|(b, slot)| {
        let mut at = 0;
        for (c, count) in counts.iter().enumerate() {
            let start = c * chunk + count[..b].iter().sum::<usize>();
            slot[at..at + count[b]].copy_from_slice(&copy[start..start + count[b]]);
            at += count[b];
        }
        slot.sort_unstable();
    });
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::triangulation::MAX_DIM;

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

    /// Packs pairs of several codecs (one and two words, fields cut where a word ends) and
    /// checks that the packed values sort as the pairs do and unpack to them.
    fn packs_in_order<const W: usize>(d: usize, l: usize, bits: u32, lo: i32, hi: i32) {
        let codec = KeyCodec::new(d, l, bits).unwrap();
        assert!(codec.words() <= W);
        let (los, his) = (vec![lo; d], vec![hi; d]);
        let count = 1000;
        let packer = Packer::<W>::new(&codec, &los, &his, count).unwrap();
        let pairs = random_pairs::<W>(&codec, &los, &his, count as u32, 4000, 7 + bits as u64);
        let mut packed: Vec<u64> = pairs
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
        packs_in_order::<2>(3, 2, 21, -300, 250);
        packs_in_order::<2>(3, 3, 21, 1 << 19, (1 << 19) + 40);
        // One word; a coordinate cut by the word's end (R^4, 15 bits).
        packs_in_order::<1>(3, 1, 12, -5, 7);
        packs_in_order::<2>(4, 3, 15, -100, 100);
        packs_in_order::<2>(4, 4, 17, -1, 0);
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
        assert!(
            Packer::<2>::new(&KeyCodec::new(10, 9, 12).unwrap(), &[0; 10], &[3; 10], 9).is_none()
        );
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
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            pool.install(|| par_sort_distinct(&mut got));
            assert!(got == want, "{threads} threads");
        }
    }
}
