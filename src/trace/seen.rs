//! A filter over the vertex cache's keys, one bit per slot of a hash: a key whose bit is
//! clear is not cached. A level's new vertices are nearly all uncached (the sphere at edge
//! 0.01: 257 of 435,535 were), so most skip their lookup in the whole cache, whose tables
//! outgrow a core's cache, for one bit of a bitset of 2 to 4 bytes per cached key.

use std::hash::BuildHasher;

use foldhash::fast::FixedState;

use super::table::{Key, Table};

/// Bits per cached key, at least: about one key in 16 not cached finds its bit set.
const BITS_PER_KEY: usize = 16;
/// Fewest bits.
const MIN_BITS: usize = 1 << 16;

/// The keys of a vertex cache, as bits set.
pub(crate) struct SeenVertices<const W: usize> {
    bits: Vec<u64>,
    hasher: FixedState,
    /// The cache's keys before this index have been taken up.
    synced: usize,
}

impl<const W: usize> SeenVertices<W> {
    pub fn new() -> Self {
        SeenVertices {
            bits: vec![0; MIN_BITS / 64],
            hasher: FixedState::with_seed(0x2545_f491_4f6c_dd1d),
            synced: 0,
        }
    }

    #[inline]
    fn slot(&self, key: &Key<W>) -> usize {
        // The bits are a power of two.
        (self.hasher.hash_one(key) as usize) & (self.bits.len() * 64 - 1)
    }

    /// Whether `key` may be in the cache as of the last [`SeenVertices::sync`]: false only
    /// for a key that is not.
    #[inline]
    pub fn may_hold(&self, key: &Key<W>) -> bool {
        let s = self.slot(key);
        (self.bits[s / 64] >> (s % 64)) & 1 == 1
    }

    /// Takes up the keys cached since the last call; all of them again when the bits grow
    /// (to [`BITS_PER_KEY`] per key).
    pub fn sync(&mut self, verts: &Table<W>) {
        let want = (verts.len() * BITS_PER_KEY)
            .next_power_of_two()
            .max(MIN_BITS);
        let from = if want > self.bits.len() * 64 {
            self.bits = vec![0; want / 64];
            0
        } else {
            self.synced
        };
        for i in from..verts.len() {
            let s = self.slot(verts.key(i));
            self.bits[s / 64] |= 1 << (s % 64);
        }
        self.synced = verts.len();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_cached_key_may_be_held_and_most_others_not() {
        let mut verts: Table<1> = Table::fixed();
        let mut seen = SeenVertices::new();
        // Grown in steps, past several sizes of the bits.
        for step in 0..40u64 {
            let keys: Vec<u64> = (step * 10_000..(step + 1) * 10_000)
                .map(|i| i * 3)
                .collect();
            verts.insert_new_batch(&keys).unwrap();
            seen.sync(&verts);
            assert!(
                (0..verts.len()).all(|i| seen.may_hold(verts.key(i))),
                "a cached key missed after step {step}"
            );
        }
        // Keys never cached: 1 mod 3.
        let others = (0..100_000u64)
            .filter(|&i| seen.may_hold(&[i * 3 + 1]))
            .count();
        assert!(
            others < 10_000,
            "{others} of 100,000 uncached keys may be held"
        );
    }
}
