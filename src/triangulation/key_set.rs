//! The one set of simplex and vertex keys: fixed-width keys of u64 words kept in insertion
//! order in a flat arena, indexed by a hash table of u32 positions (about `8 * words + 5..10`
//! bytes per key, no allocation per key).
//!
//! The width is known at run time ([`KeySet<usize>`], the public default) or at compile time
//! ([`KeySet<Words<W>>`], which the tracing loop uses: the comparisons and the hash of a key
//! unroll). Both hash a key the same way, so one seed and one overflow guard serve both.

use foldhash::fast::FixedState;
use hashbrown::hash_table::Entry;
use hashbrown::HashTable;
use std::hash::BuildHasher;

use crate::error::{Error, Result};

/// The number of u64 words in a key: a `usize` known at run time, or [`Words`] at compile
/// time.
pub trait Width: Copy + std::fmt::Debug {
    /// Words per key.
    fn words(self) -> usize;
}

impl Width for usize {
    #[inline]
    fn words(self) -> usize {
        self
    }
}

/// A key width of `W` words, known at compile time.
#[derive(Clone, Copy, Debug, Default)]
pub struct Words<const W: usize>;

impl<const W: usize> Width for Words<W> {
    #[inline]
    fn words(self) -> usize {
        W
    }
}

/// A set of fixed-width keys in insertion order: a flat arena of u64 words indexed by a hash
/// table of u32 positions, about `8 * words + 5..10` bytes per key. The width is a `usize`
/// (the default) or [`Words<W>`], known at compile time, which unrolls the comparisons.
#[derive(Clone, Debug)]
pub struct KeySet<N: Width = usize> {
    width: N,
    /// Most keys it may hold: 2^32, the positions its table stores (lowered in tests).
    max_keys: usize,
    arena: Vec<u64>,
    table: HashTable<u32>,
    hasher: FixedState,
}

const SEED: u64 = 0x1503_e5a1;

impl KeySet<usize> {
    /// An empty set of keys of `words` words.
    pub fn new(words: usize) -> Self {
        KeySet::with_width(words)
    }
}

impl<const W: usize> KeySet<Words<W>> {
    /// An empty set of keys of `W` words.
    pub fn fixed() -> Self {
        KeySet::with_width(Words)
    }

    /// The key at insertion index `i`, as an array.
    #[inline]
    pub fn key(&self, i: usize) -> &[u64; W] {
        self.get(i).try_into().expect("W words")
    }
}

impl<N: Width> KeySet<N> {
    fn with_width(width: N) -> Self {
        assert!(width.words() > 0, "keys of no words");
        KeySet {
            width,
            max_keys: 1 << 32,
            arena: Vec::new(),
            table: HashTable::new(),
            hasher: FixedState::with_seed(SEED),
        }
    }

    /// Words per key.
    #[inline]
    pub fn words(&self) -> usize {
        self.width.words()
    }

    /// Number of keys.
    #[inline]
    pub fn len(&self) -> usize {
        self.arena.len() / self.words()
    }

    /// Whether the set is empty.
    #[inline]
    pub fn is_empty(&self) -> bool {
        self.arena.is_empty()
    }

    /// The key at insertion index `i`.
    #[inline]
    pub fn get(&self, i: usize) -> &[u64] {
        let w = self.words();
        &self.arena[i * w..(i + 1) * w]
    }

    /// The insertion index of `key`, if present.
    #[inline]
    pub fn find(&self, key: &[u64]) -> Option<usize> {
        let h = self.hasher.hash_one(key);
        let (arena, w) = (&self.arena, self.words());
        self.table
            .find(h, |&i| &arena[i as usize * w..(i as usize + 1) * w] == key)
            .map(|&i| i as usize)
    }

    /// Inserts `key`; returns its index and whether it was new. An error, and the set
    /// unchanged, when a new key would need an index past u32 (2^32 keys held already).
    #[inline]
    pub fn insert(&mut self, key: &[u64]) -> Result<(usize, bool)> {
        debug_assert_eq!(key.len(), self.words());
        let h = self.hasher.hash_one(key);
        let w = self.words();
        let i = self.len();
        let fits = self.position(i);
        let KeySet {
            arena,
            table,
            hasher,
            ..
        } = self;
        let entry = table.entry(
            h,
            |&i| &arena[i as usize * w..(i as usize + 1) * w] == key,
            |&i| hasher.hash_one(&arena[i as usize * w..(i as usize + 1) * w]),
        );
        match entry {
            Entry::Occupied(e) => Ok((*e.get() as usize, false)),
            Entry::Vacant(e) => {
                e.insert(fits?);
                arena.extend_from_slice(key);
                Ok((i, true))
            }
        }
    }

    /// Inserts `key`, known not to be in the set (one probe less than [`KeySet::insert`]);
    /// returns its index.
    #[inline]
    pub fn insert_new(&mut self, key: &[u64]) -> Result<usize> {
        debug_assert_eq!(key.len(), self.words());
        debug_assert!(self.find(key).is_none());
        let i = self.len();
        let pos = self.position(i)?;
        let h = self.hasher.hash_one(key);
        let (arena, w, hasher) = (&self.arena, self.words(), &self.hasher);
        self.table.insert_unique(h, pos, |&j| {
            hasher.hash_one(&arena[j as usize * w..(j as usize + 1) * w])
        });
        self.arena.extend_from_slice(key);
        Ok(i)
    }

    /// The table position of the key at index `i`, or the overflow error.
    #[inline]
    fn position(&self, i: usize) -> Result<u32> {
        u32::try_from(i)
            .ok()
            .filter(|_| i < self.max_keys)
            .ok_or_else(|| Error::Trace(format!("more than {} keys", self.max_keys)))
    }

    /// Reserves room for `additional` more keys.
    pub fn reserve(&mut self, additional: usize) {
        let w = self.words();
        self.arena.reserve(additional * w);
        let (arena, hasher) = (&self.arena, &self.hasher);
        self.table.reserve(additional, |&i| {
            hasher.hash_one(&arena[i as usize * w..(i as usize + 1) * w])
        });
    }

    /// Keys in insertion order.
    pub fn iter(&self) -> impl Iterator<Item = &[u64]> {
        self.arena.chunks_exact(self.words())
    }

    /// Bytes held by the arena and the table.
    pub fn memory_bytes(&self) -> usize {
        self.arena.capacity() * 8 + self.table.allocation_size()
    }

    /// Bytes that inserting `extra` more keys may allocate on top of
    /// [`KeySet::memory_bytes`] (the arena and the table grow by doubling, the old table live
    /// while the new one fills).
    pub fn growth_bytes(&self, extra: usize) -> usize {
        let (len, w) = (self.len() + extra, self.words());
        let mut grow = 0;
        if len * w > self.arena.capacity() {
            grow += (len * w).max(2 * self.arena.capacity()) * 8;
        }
        if len > self.table.capacity() {
            let ratio = len
                .div_ceil(self.table.capacity().max(1))
                .next_power_of_two();
            // A bucket: its u32 and a control byte, at 7/8 load.
            grow += (self.table.allocation_size().max(len * 5 * 8 / 7)) * ratio.max(2);
        }
        grow
    }

    /// The arena: the keys one after another, in insertion order.
    pub fn into_words(self) -> Vec<u64> {
        self.arena
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_key_set_refuses_a_key_past_its_last_index() {
        let mut set = KeySet::new(2);
        set.max_keys = 3;
        for i in 0..3u64 {
            assert_eq!(set.insert(&[i, 7]).unwrap(), (i as usize, true));
        }
        // Known keys are still found; a new one is refused and leaves the set as it was.
        assert_eq!(set.insert(&[1, 7]).unwrap(), (1, false));
        for e in [
            set.insert(&[9, 9]).unwrap_err(),
            set.insert_new(&[9, 9]).unwrap_err(),
        ] {
            assert!(e.to_string().contains("more than 3 keys"), "{e}");
        }
        assert_eq!(set.len(), 3);
        assert_eq!(set.find(&[9, 9]), None);
        assert_eq!(set.find(&[2, 7]), Some(2));
    }

    #[test]
    fn both_widths_hash_alike_and_keep_insertion_order() {
        let mut fixed = KeySet::<Words<3>>::fixed();
        let mut dynamic = KeySet::new(3);
        for i in 0..1000u64 {
            let key = [i * 7919 % 1000, i, u64::MAX - i];
            assert_eq!(fixed.insert_new(&key).unwrap(), i as usize);
            assert_eq!(dynamic.insert(&key).unwrap(), (i as usize, true));
        }
        for i in (0..1000).rev() {
            let key = *fixed.key(i);
            assert_eq!(fixed.find(&key), Some(i));
            assert_eq!(dynamic.find(&key), Some(i));
            assert_eq!(
                fixed.hasher.hash_one(key),
                dynamic.hasher.hash_one(dynamic.get(i))
            );
        }
        assert_eq!(fixed.find(&[1, 2, 3]), None);
        assert_eq!(
            fixed.into_words(),
            dynamic.iter().flatten().copied().collect::<Vec<_>>()
        );
    }
}
